//! Acme and Stub Acme threads by designation: `1/2-10 ACME-2G`, `3/4-6 STUB ACME`,
//! `2.875-0.4P-0.8L-ACME-2G-LH`, read against the ASME series of diameters and pitches.

use super::designation::{Designation, DesignationError};
use super::reading::{left_hand, number, refuse, size_inches, starts};
use super::{AcmeGeneralPurpose, StandardProfile, StubAcme, MM_PER_INCH};

/// The preferred diameter–pitch combinations of the Acme thread series: nominal size (as the
/// standard writes it), size in inches, threads per inch. ASME B1.5-1997 (general purpose
/// Acme) and ASME/ANSI B1.8-1988 (R2021) (Stub Acme) recommend the same 23 combinations.
///
/// Source: B1.8's table of Stub Acme basic dimensions, as reproduced by torqbolt.com "Stub
/// Acme 29 degree threads" (1/4-16 to 5-2, with h = 0.3P and flat 0.4224P columns), and the
/// list of "preferred diameters and associated pitches ... recommended in the ASME standard"
/// of amesweb.info's Acme and Stub Acme calculators.
pub const SERIES: &[(&str, f64, f64)] = &[
    ("1/4", 0.25, 16.0),
    ("5/16", 0.3125, 14.0),
    ("3/8", 0.375, 12.0),
    ("7/16", 0.4375, 12.0),
    ("1/2", 0.5, 10.0),
    ("5/8", 0.625, 8.0),
    ("3/4", 0.75, 6.0),
    ("7/8", 0.875, 6.0),
    ("1", 1.0, 5.0),
    ("1 1/8", 1.125, 5.0),
    ("1 1/4", 1.25, 5.0),
    ("1 3/8", 1.375, 4.0),
    ("1 1/2", 1.5, 4.0),
    ("1 3/4", 1.75, 4.0),
    ("2", 2.0, 4.0),
    ("2 1/4", 2.25, 3.0),
    ("2 1/2", 2.5, 3.0),
    ("2 3/4", 2.75, 3.0),
    ("3", 3.0, 2.0),
    ("3 1/2", 3.5, 2.0),
    ("4", 4.0, 2.0),
    ("4 1/2", 4.5, 2.0),
    ("5", 5.0, 2.0),
];

/// Classes of fit: B1.5's general purpose classes; B1.8 establishes 2G only for Stub Acme.
const ACME_CLASSES: &[&str] = &["2G", "3G", "4G"];
const STUB_CLASSES: &[&str] = &["2G"];

/// Reads `size-tpi ACME[-class][-LH]`, `size-tpi STUB ACME`, and the multi-start form
/// `size-pitchP-leadL-ACME-class`. The size is a fraction (`1/2`, `1 1/2`, `1-1/2`) or a
/// decimal (`0.500`) in inches. `None` when the text names no Acme thread.
pub fn read(text: &str) -> Option<Result<Designation, DesignationError>> {
    let upper = text.to_ascii_uppercase();
    let (at, keyword, stub) = match upper.find("STUB ACME") {
        Some(at) => (at, "STUB ACME", true),
        None => (upper.find("ACME")?, "ACME", false),
    };
    let head = text[..at].trim().trim_end_matches('-').trim();
    let tail = &upper[at + keyword.len()..];
    Some(read_parts(head, tail, stub).map_err(|why| refuse(text, why)))
}

/// The size and pitch before the keyword, the class and hand after it.
fn read_parts(head: &str, tail: &str, stub: bool) -> Result<Designation, String> {
    let words: Vec<&str> = tail
        .split(|c: char| c == '-' || c.is_whitespace())
        .filter(|w| !w.is_empty())
        .collect();
    let (standard, classes) = if stub {
        ("ASME B1.8 (Stub Acme)", STUB_CLASSES)
    } else {
        ("ASME B1.5", ACME_CLASSES)
    };
    let words = words.concat();
    let (rest, left) = left_hand(&words)?;
    let class = match rest {
        "" => None,
        c if classes.contains(&c) => Some(c.to_string()),
        c => {
            return Err(format!(
                "`{c}` is not a class of {standard}, which has {}",
                classes.join(", ")
            ))
        }
    };

    let parts: Vec<&str> = head.split('-').map(str::trim).collect();
    let n = parts.len();
    let (size, pitch, lead) =
        if n >= 3 && parts[n - 1].ends_with('L') && parts[n - 2].ends_with('P') {
            let pitch = number(parts[n - 2].trim_end_matches('P'), "pitch (in)")?;
            let lead = number(parts[n - 1].trim_end_matches('L'), "lead (in)")?;
            (parts[..n - 2].join(" "), pitch, lead)
        } else if n >= 2 {
            let tpi = number(parts[n - 1], "threads per inch")?;
            (parts[..n - 1].join(" "), 1.0 / tpi, 1.0 / tpi)
        } else {
            return Err("write size-threads per inch, as in `1/2-10 ACME-2G`".into());
        };
    let inches = size_inches(&size)?;
    let Some((name, _, tpi)) = SERIES.iter().find(|(_, s, _)| (s - inches).abs() < 1e-6) else {
        return Err(format!(
            "{standard}'s series has no size {size} in; its sizes run {}",
            SERIES
                .iter()
                .map(|(name, ..)| *name)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    };
    if (pitch * tpi - 1.0).abs() > 1e-6 {
        return Err(format!(
            "{standard}'s series gives size {name} in {tpi} threads per inch (pitch {} in), not \
             {} threads per inch",
            1.0 / tpi,
            1.0 / pitch
        ));
    }
    let starts = starts(lead, pitch, "in")?;
    let d = inches * MM_PER_INCH;
    let form = if stub {
        StandardProfile::StubAcme(StubAcme::new(d, None).map_err(|e| e.to_string())?)
    } else {
        StandardProfile::Acme(AcmeGeneralPurpose::new(d, None).map_err(|e| e.to_string())?)
    };
    Ok(Designation {
        form,
        lead: Some(lead * MM_PER_INCH),
        starts: Some(starts),
        left_hand: left,
        class,
        row: format!("{standard} series: {name} in, {tpi} threads per inch"),
    })
}

#[cfg(test)]
mod tests;
