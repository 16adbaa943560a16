//! The ISO metric trapezoidal thread by designation: `Tr 40x7`, `Tr 40 x 14 P7 LH`,
//! `Tr 40x7-7H`, read against ISO 2902's table of diameters and pitches.

use super::designation::{Designation, DesignationError};
use super::reading::{lead_screw_size, list, refuse, starts, LeadScrewSize};
use super::{IsoTrapezoidal, StandardProfile};

/// ISO 2902's diameter–pitch combinations (ISO metric trapezoidal screw threads, general
/// plan), as ISO 2904:2020 Table 1 lists them with their basic dimensions: nominal diameter
/// d (mm) and the pitches (mm) the standard has for it, coarse to fine.
///
/// Source: ISO 2902 / DIN 103-1 "diameters and pitch combinations", as reproduced in
/// F-M-S (www.f-m-s.dk) "ISO Trapezoidal screw threads Tr", sheet 3.11 2007/1, page 1
/// (columns coarse, normal, fine for d = 8 to 300 mm); the Tr 40 row (10, 7, 3) agrees with
/// ISO 2904:2020 Table 1.
pub const DIAMETERS_AND_PITCHES: &[(f64, &[f64])] = &[
    (8.0, &[1.5]),
    (9.0, &[2.0, 1.5]),
    (10.0, &[2.0, 1.5]),
    (11.0, &[3.0, 2.0]),
    (12.0, &[3.0, 2.0]),
    (14.0, &[3.0, 2.0]),
    (16.0, &[4.0, 2.0]),
    (18.0, &[4.0, 2.0]),
    (20.0, &[4.0, 2.0]),
    (22.0, &[8.0, 5.0, 3.0]),
    (24.0, &[8.0, 5.0, 3.0]),
    (26.0, &[8.0, 5.0, 3.0]),
    (28.0, &[8.0, 5.0, 3.0]),
    (30.0, &[10.0, 6.0, 3.0]),
    (32.0, &[10.0, 6.0, 3.0]),
    (34.0, &[10.0, 6.0, 3.0]),
    (36.0, &[10.0, 6.0, 3.0]),
    (38.0, &[10.0, 7.0, 3.0]),
    (40.0, &[10.0, 7.0, 3.0]),
    (42.0, &[10.0, 7.0, 3.0]),
    (44.0, &[12.0, 7.0, 3.0]),
    (46.0, &[12.0, 8.0, 3.0]),
    (48.0, &[12.0, 8.0, 3.0]),
    (50.0, &[12.0, 8.0, 3.0]),
    (52.0, &[12.0, 8.0, 3.0]),
    (55.0, &[14.0, 9.0, 3.0]),
    (60.0, &[14.0, 9.0, 3.0]),
    (65.0, &[16.0, 10.0, 4.0]),
    (70.0, &[16.0, 10.0, 4.0]),
    (75.0, &[16.0, 10.0, 4.0]),
    (80.0, &[16.0, 10.0, 4.0]),
    (85.0, &[18.0, 12.0, 4.0]),
    (90.0, &[18.0, 12.0, 4.0]),
    (95.0, &[18.0, 12.0, 4.0]),
    (100.0, &[20.0, 12.0, 4.0]),
    (105.0, &[20.0, 12.0, 4.0]),
    (110.0, &[20.0, 12.0, 4.0]),
    (115.0, &[22.0, 14.0, 6.0]),
    (120.0, &[22.0, 14.0, 6.0]),
    (125.0, &[22.0, 14.0, 6.0]),
    (130.0, &[22.0, 14.0, 6.0]),
    (135.0, &[24.0, 14.0, 6.0]),
    (140.0, &[24.0, 14.0, 6.0]),
    (145.0, &[24.0, 14.0, 6.0]),
    (150.0, &[24.0, 16.0, 6.0]),
    (155.0, &[24.0, 16.0, 6.0]),
    (160.0, &[28.0, 16.0, 6.0]),
    (165.0, &[28.0, 16.0, 6.0]),
    (170.0, &[28.0, 16.0, 6.0]),
    (175.0, &[28.0, 16.0, 8.0]),
    (180.0, &[28.0, 18.0, 8.0]),
    (185.0, &[32.0, 18.0, 8.0]),
    (190.0, &[32.0, 18.0, 8.0]),
    (195.0, &[32.0, 18.0, 8.0]),
    (200.0, &[32.0, 18.0, 8.0]),
    (210.0, &[36.0, 20.0, 8.0]),
    (220.0, &[36.0, 20.0, 8.0]),
    (230.0, &[36.0, 20.0, 8.0]),
    (240.0, &[36.0, 22.0, 8.0]),
    (250.0, &[40.0, 22.0, 12.0]),
    (260.0, &[40.0, 22.0, 12.0]),
    (270.0, &[40.0, 24.0, 12.0]),
    (280.0, &[40.0, 24.0, 12.0]),
    (290.0, &[44.0, 24.0, 12.0]),
    (300.0, &[44.0, 24.0, 12.0]),
];

/// ISO 2903's recommended tolerance classes: the external thread's (tolerance position in
/// small letters) and the internal thread's (capitals).
pub const TOLERANCE_CLASSES: &[&str] = &["7e", "8e", "8c", "9c", "7H", "8H", "9H"];

/// Reads `Tr d x P`, `Tr d x Ph P P` (multi-start: lead Ph, pitch P, also written
/// `Tr 40x14(P7)`), an optional `LH` after the pitch and an optional tolerance class after a
/// dash (`Tr 40x7-7e`, ISO 2903's form) or a space. `None` when the text does not start
/// with `Tr`.
pub fn read(text: &str) -> Option<Result<Designation, DesignationError>> {
    let rest = text.strip_prefix("Tr")?;
    if rest.starts_with(|c: char| c.is_alphabetic()) {
        return None;
    }
    Some(read_size(rest).map_err(|why| refuse(text, why)))
}

/// The size, pitch, hand and class after `Tr`.
fn read_size(rest: &str) -> Result<Designation, String> {
    let (body, class) = split_class(rest)?;
    let LeadScrewSize {
        d,
        lead,
        pitch,
        left_hand,
    } = lead_screw_size(body, "Tr 40x7")?;
    let Some((_, table)) = DIAMETERS_AND_PITCHES.iter().find(|(size, _)| *size == d) else {
        return Err(format!(
            "ISO 2902 has no nominal diameter {d} mm; its diameters near it are {}",
            list(neighbours(d))
        ));
    };
    if !table.contains(&pitch) {
        return Err(format!(
            "ISO 2902 has no pitch {pitch} mm for d = {d} mm, only {} mm (for another pitch, \
             give standard = \"trapezoidal\" with its dimensions)",
            list(table.iter().copied())
        ));
    }
    let starts = starts(lead, pitch, "mm")?;
    let form = IsoTrapezoidal::new(d, None, None).map_err(|e| e.to_string())?;
    Ok(Designation {
        form: StandardProfile::IsoTrapezoidal(form),
        lead: Some(lead),
        starts: Some(starts),
        left_hand,
        class,
        row: format!(
            "ISO 2902 / ISO 2904:2020 Table 1, d = {d} mm: pitches {} mm",
            list(table.iter().copied())
        ),
    })
}

/// Splits the tolerance class off the end: after a dash (`40x7-7e`), or as the last word when
/// it has the form of one, a digit and a letter (`40x7 7e`). A class not among ISO 2903's is refused.
fn split_class(rest: &str) -> Result<(&str, Option<String>), String> {
    let (body, class) = match rest.split_once('-') {
        Some((body, class)) => (body, class.trim()),
        None => match rest.trim_end().rsplit_once(char::is_whitespace) {
            Some((body, last))
                if last.len() == 2
                    && last.starts_with(|c: char| c.is_ascii_digit())
                    && last.ends_with(|c: char| c.is_ascii_alphabetic()) =>
            {
                (body, last)
            }
            _ => return Ok((rest, None)),
        },
    };
    if TOLERANCE_CLASSES.contains(&class) {
        Ok((body, Some(class.to_string())))
    } else {
        Err(format!(
            "`{class}` is not one of ISO 2903's tolerance classes ({}; capitals for the nut)",
            TOLERANCE_CLASSES.join(", ")
        ))
    }
}

/// The table's diameters either side of `d`.
fn neighbours(d: f64) -> Vec<f64> {
    let sizes: Vec<f64> = DIAMETERS_AND_PITCHES.iter().map(|(s, _)| *s).collect();
    let above = sizes.iter().position(|s| *s > d).unwrap_or(sizes.len());
    sizes[above.saturating_sub(1)..(above + 1).min(sizes.len())].to_vec()
}

#[cfg(test)]
mod tests;
