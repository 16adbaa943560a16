//! The ISO general purpose metric thread (M): ISO 68-1's basic profile, the external thread
//! with ISO 965-1's rounded root, and the internal thread on the basic profile; read from
//! `M20`, `M20x1.5`, `M20x1.5-6g`, `M20 LH` against ISO 262's selected sizes.

use super::designation::{Designation, DesignationError};
use super::reading::{left_hand, list, number, refuse};
use super::trapezoid::trapezoid_pieces;
use super::{mirror_rho, positive, AxialPiece, StandardError, StandardProfile};

/// ISO metric thread (ISO 68-1, ISO 965-1), dimensions in mm.
///
/// ISO 68-1's basic profile: flank angle 60°, fundamental triangle height `H = √3/2·P`, crest
/// of the external thread (and root of the internal) truncated `H/8` from the triangle's
/// apex, so the flank runs `5H/8` from the major diameter `d` to the basic minor diameter
/// `D1 = d − 2·5H/8 = d − 1.0825·P`; pitch diameter `d2 = d − 2·3H/8 = d − 0.6495·P` (the
/// thread `P/2` thick there); crest flat `P/8`, basic root flat `P/4`.
///
/// The external thread's root (ISO 965-1, the root contour every tolerance class must clear):
/// rounded, minor diameter `d3 = d1 − H/6 = d − 1.22687·P`. The arc tangent to both flanks
/// that reaches `d3` has radius `H/6 = 0.1443·P`, above ISO 965-1's minimum `0.125·P`: whirl
/// cuts that full-radius root. The internal thread is cut on the basic profile: bore at `D1`,
/// root flat `P/8` at `D = d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsoMetric {
    major_diameter: f64,
}

impl IsoMetric {
    /// Flank half-angle: 30°, i.e. 60° included.
    pub const FLANK_HALF_ANGLE_DEG: f64 = 30.0;

    /// A metric thread of nominal (major) diameter `d` (mm).
    pub fn new(major_diameter: f64) -> Result<Self, StandardError> {
        Ok(Self {
            major_diameter: positive("major diameter d", major_diameter)?,
        })
    }

    /// Nominal (major) diameter d (mm).
    pub fn major_diameter(&self) -> f64 {
        self.major_diameter
    }

    /// Height of the fundamental triangle, `H = √3/2·P` (mm).
    pub fn fundamental_height(pitch: f64) -> f64 {
        0.5 * 3f64.sqrt() * pitch
    }

    /// Pitch diameter `d2 = D2 = d − 3H/4` (mm).
    pub fn pitch_diameter(&self, pitch: f64) -> f64 {
        self.major_diameter - 0.75 * Self::fundamental_height(pitch)
    }

    /// Depth of the external thread to its rounded root, `17H/24` (mm).
    pub fn thread_height(&self, pitch: f64) -> f64 {
        17.0 / 24.0 * Self::fundamental_height(pitch)
    }

    /// Root radius of the external thread, `H/6` (mm).
    pub fn root_radius(pitch: f64) -> f64 {
        Self::fundamental_height(pitch) / 6.0
    }

    /// The external thread's axial section of one pitch.
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        trapezoid_pieces(
            pitch,
            0.5 * self.major_diameter,
            0.75 * Self::fundamental_height(pitch),
            self.thread_height(pitch),
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            Self::root_radius(pitch),
        )
    }

    /// The internal thread's axial section of one pitch (the internal convention of
    /// [`StandardProfile::internal_pieces`]): the basic profile from the bore at `D1` to the
    /// root flat at `D`. Built as the screw-like section it mirrors: crest `H/4` outside the
    /// pitch line, `5H/8` deep, reflected about the pitch line.
    pub fn internal_pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        let h = Self::fundamental_height(pitch);
        let about = 0.5 * self.pitch_diameter(pitch);
        let pieces = trapezoid_pieces(
            pitch,
            about + 0.25 * h,
            0.5 * h,
            0.625 * h,
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            0.0,
        )?;
        Ok(pieces.into_iter().map(|p| mirror_rho(p, about)).collect())
    }
}

/// ISO 262's selected sizes (a subset of ISO 261's diameter–pitch combinations): nominal
/// diameter d (mm), its coarse pitch and its fine pitches (mm).
///
/// Source: ISO 262:1998 Table 1 (selected sizes for screws, bolts and nuts), as reproduced in
/// the "ISO metric screw thread, preferred sizes" table of the Wikipedia article (liquisearch
/// copy), columns "ISO 261 pitch, coarse / fine".
pub const SELECTED_SIZES: &[(f64, f64, &[f64])] = &[
    (1.0, 0.25, &[]),
    (1.2, 0.25, &[]),
    (1.4, 0.3, &[]),
    (1.6, 0.35, &[]),
    (1.8, 0.35, &[]),
    (2.0, 0.4, &[]),
    (2.5, 0.45, &[]),
    (3.0, 0.5, &[]),
    (3.5, 0.6, &[]),
    (4.0, 0.7, &[]),
    (5.0, 0.8, &[]),
    (6.0, 1.0, &[]),
    (7.0, 1.0, &[]),
    (8.0, 1.25, &[1.0]),
    (10.0, 1.5, &[1.25, 1.0]),
    (12.0, 1.75, &[1.5, 1.25]),
    (14.0, 2.0, &[1.5]),
    (16.0, 2.0, &[1.5]),
    (18.0, 2.5, &[2.0, 1.5]),
    (20.0, 2.5, &[2.0, 1.5]),
    (22.0, 2.5, &[2.0, 1.5]),
    (24.0, 3.0, &[2.0]),
    (27.0, 3.0, &[2.0]),
    (30.0, 3.5, &[2.0]),
    (33.0, 3.5, &[2.0]),
    (36.0, 4.0, &[3.0]),
    (39.0, 4.0, &[3.0]),
    (42.0, 4.5, &[3.0]),
    (45.0, 4.5, &[3.0]),
    (48.0, 5.0, &[3.0]),
    (52.0, 5.0, &[4.0]),
    (56.0, 5.5, &[4.0]),
    (60.0, 5.5, &[4.0]),
    (64.0, 6.0, &[4.0]),
];

/// Reads `M d` (coarse pitch), `M d x P`, an optional `LH` after the size and an optional
/// ISO 965-1 tolerance class after a dash (`M20x1.5-6g`, `M20-6H`, `M20-5g6g`). `None` when
/// the text is not `M` followed by a number.
pub fn read(text: &str) -> Option<Result<Designation, DesignationError>> {
    let rest = text.strip_prefix('M')?;
    if !rest.trim_start().starts_with(|c: char| c.is_ascii_digit()) {
        return None;
    }
    Some(read_size(rest).map_err(|why| refuse(text, why)))
}

/// The size, pitch, hand and class after `M`.
fn read_size(rest: &str) -> Result<Designation, String> {
    let (body, class) = match rest.split_once('-') {
        Some((body, class)) => (body, Some(tolerance_class(class.trim())?)),
        None => (rest, None),
    };
    let body: String = body
        .chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| if c == '×' || c == 'X' { 'x' } else { c })
        .collect();
    let (body, left_hand) = left_hand(&body)?;
    let (d, pitch) = match body.split_once('x') {
        Some((d, p)) => (number(d, "nominal diameter")?, Some(number(p, "pitch")?)),
        None => (number(body, "nominal diameter")?, None),
    };
    let Some((_, coarse, fine)) = SELECTED_SIZES.iter().find(|(size, ..)| *size == d) else {
        return Err(format!(
            "ISO 262 has no nominal diameter {d} mm among its selected sizes ({} ... {} mm)",
            SELECTED_SIZES[0].0,
            SELECTED_SIZES[SELECTED_SIZES.len() - 1].0
        ));
    };
    let pitch = pitch.unwrap_or(*coarse);
    if pitch != *coarse && !fine.contains(&pitch) {
        return Err(format!(
            "ISO 262 has no pitch {pitch} mm for M{d}, only {} mm",
            list(std::iter::once(*coarse).chain(fine.iter().copied()))
        ));
    }
    Ok(Designation {
        form: StandardProfile::IsoMetric(IsoMetric::new(d).map_err(|e| e.to_string())?),
        lead: Some(pitch),
        starts: Some(1),
        left_hand,
        class,
        row: format!(
            "ISO 262:1998 Table 1, M{d}: coarse {coarse} mm, fine {}",
            list(fine.iter().copied())
        ),
    })
}

/// An ISO 965-1 tolerance class: a pitch-diameter and a crest-diameter tolerance, each a grade
/// (3 to 9) and a position (e, f, g, h for the screw; G, H for the nut), written once when
/// they are the same (`6g`, `5g6g`, `6H`).
fn tolerance_class(class: &str) -> Result<String, String> {
    let bytes = class.as_bytes();
    let part = |p: &[u8]| {
        p.len() == 2
            && (b'3'..=b'9').contains(&p[0])
            && matches!(p[1], b'e' | b'f' | b'g' | b'h' | b'G' | b'H')
    };
    let ok = match bytes.len() {
        2 => part(bytes),
        4 => {
            part(&bytes[..2])
                && part(&bytes[2..])
                && bytes[1].is_ascii_uppercase() == bytes[3].is_ascii_uppercase()
        }
        _ => false,
    };
    if ok {
        Ok(class.to_string())
    } else {
        Err(format!(
            "`{class}` is not an ISO 965-1 tolerance class (grade 3 to 9 and position e, f, g, h \
             for the screw, G, H for the nut: 6g, 5g6g, 6H)"
        ))
    }
}

#[cfg(test)]
mod tests;
