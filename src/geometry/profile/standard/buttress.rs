//! The buttress thread (Sägengewinde) of DIN 513-1: a 3° load flank and a 30° clearance
//! flank, the external thread's root one arc tangent to both; read from `S 48x8`,
//! `S 48x16 P8 LH`, `S 48x8-7h`.

use super::designation::{Designation, DesignationError};
use super::reading::{lead_screw_size, refuse, starts, LeadScrewSize};
use super::{mirror_z, positive, AxialPiece, StandardError, StandardProfile};
use glam::DVec2;

/// DIN 513-1 buttress thread, external (the screw), dimensions in mm.
///
/// DIN 513-1's profile, every dimension a multiple of the pitch P: load flank at 3° and
/// clearance flank at 30° to the radial line; thread overlap `H1 = 0.75·P`, so the pitch
/// diameter is `d2 = d − H1`; the screw's thread height `h3 = H1 + a_c = 0.86777·P` with the
/// crest clearance `a_c = 0.11777·P`, minor diameter `d3 = d − 2·h3 = d − 1.73554·P`; the
/// screw's crest flat `e = 0.26384·P` at `d`; its root one arc of radius
/// `R = 0.12427·P` tangent to both flanks (which is what sets `h3`: the flanks, `P − e`
/// apart at `d`, would meet `(P − e) / (tan 3° + tan 30°) = 1.16896·P` below it, and the arc
/// stands `R·(cos 13.5° / sin 16.5° − 1) = 0.30119·P` above that point).
///
/// Which side of the groove the 3° (load) flank lies on is the drawing's to say
/// ([`LoadFlank`]): DIN 513 draws it on the right, +z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Buttress {
    major_diameter: f64,
    load_flank: LoadFlank,
}

/// The side of the groove, along the screw's axis, that the 3° load flank lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LoadFlank {
    /// The groove's +z side (DIN 513's drawing: the load flank on the right).
    #[default]
    PlusZ,
    /// The groove's −z side.
    MinusZ,
}

impl Buttress {
    /// The load flank's angle to the radial line, degrees.
    pub const LOAD_FLANK_DEG: f64 = 3.0;
    /// The clearance flank's angle to the radial line, degrees.
    pub const CLEARANCE_FLANK_DEG: f64 = 30.0;
    /// Thread overlap `H1` per unit pitch.
    pub const OVERLAP: f64 = 0.75;
    /// Crest clearance `a_c` per unit pitch.
    pub const CREST_CLEARANCE: f64 = 0.11777;
    /// The screw's thread height `h3` per unit pitch.
    pub const THREAD_HEIGHT: f64 = 0.86777;
    /// The screw's crest flat `e` per unit pitch.
    pub const CREST_FLAT: f64 = 0.26384;
    /// The screw's root radius `R` per unit pitch.
    pub const ROOT_RADIUS: f64 = 0.12427;

    /// A buttress screw of nominal (major) diameter `d` (mm).
    pub fn new(major_diameter: f64) -> Result<Self, StandardError> {
        Ok(Self {
            major_diameter: positive("major diameter d", major_diameter)?,
            load_flank: LoadFlank::default(),
        })
    }

    /// The same thread with its load flank on `side`.
    pub fn with_load_flank(self, side: LoadFlank) -> Buttress {
        Buttress {
            load_flank: side,
            ..self
        }
    }

    /// Nominal (major) diameter d (mm).
    pub fn major_diameter(&self) -> f64 {
        self.major_diameter
    }

    /// The screw's axial section of one pitch: the crest flat split at both ends, the
    /// clearance flank, the root arc, the load flank (the other way round for
    /// [`LoadFlank::MinusZ`]).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pieces = self.load_on_plus_z(pitch)?;
        Ok(match self.load_flank {
            LoadFlank::PlusZ => pieces,
            LoadFlank::MinusZ => pieces.into_iter().rev().map(mirror_z).collect(),
        })
    }

    /// The section with the load flank on the +z side.
    fn load_on_plus_z(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        let crest = 0.5 * self.major_diameter;
        let depth = Self::THREAD_HEIGHT * pitch;
        if crest - depth <= 0.0 {
            return Err(StandardError::MinorDiameterNotPositive {
                major: self.major_diameter,
                depth,
                minor: self.major_diameter - 2.0 * depth,
            });
        }
        let open = (1.0 - Self::CREST_FLAT) * pitch;
        let left = DVec2::new(crest, -0.5 * open);
        let right = DVec2::new(crest, 0.5 * open);
        let (clearance, load) = (
            Self::CLEARANCE_FLANK_DEG.to_radians(),
            Self::LOAD_FLANK_DEG.to_radians(),
        );
        // Each flank's unit normal into the material: the −z flank leans by the clearance
        // angle, the +z flank by the load angle.
        let n_left = DVec2::new(-clearance.sin(), -clearance.cos());
        let n_right = DVec2::new(-load.sin(), load.cos());
        // The root arc's centre lies R inside the groove from both flank lines.
        let radius = Self::ROOT_RADIUS * pitch;
        let centre = solve(
            [n_left, n_right],
            [n_left.dot(left) - radius, n_right.dot(right) - radius],
        );
        let (t_left, t_right) = (centre + radius * n_left, centre + radius * n_right);
        Ok(vec![
            AxialPiece::Line {
                from: DVec2::new(crest, -0.5 * pitch),
                to: left,
            },
            AxialPiece::Line {
                from: left,
                to: t_left,
            },
            AxialPiece::Arc {
                centre,
                radius,
                start: n_left.y.atan2(n_left.x),
                end: n_right.y.atan2(n_right.x) - std::f64::consts::TAU,
            },
            AxialPiece::Line {
                from: t_right,
                to: right,
            },
            AxialPiece::Line {
                from: right,
                to: DVec2::new(crest, 0.5 * pitch),
            },
        ])
    }
}

/// The point x with `rows[i]·x = rhs[i]` (two lines that cross).
fn solve(rows: [DVec2; 2], rhs: [f64; 2]) -> DVec2 {
    let det = rows[0].perp_dot(rows[1]);
    DVec2::new(
        (rhs[0] * rows[1].y - rhs[1] * rows[0].y) / det,
        (rows[0].x * rhs[1] - rows[1].x * rhs[0]) / det,
    )
}

/// DIN 513-2's tolerance classes of the screw (the nut's, in capitals, name a form whirl
/// does not cut).
pub const TOLERANCE_CLASSES: &[&str] = &["7h", "7e", "8e", "8c"];

/// Reads `S d x P`, `S d x Ph P P` (multi-start), an optional `LH` after the pitch and an
/// optional tolerance class after a dash. `None` when the text is not `S` and a number.
pub fn read(text: &str) -> Option<Result<Designation, DesignationError>> {
    let rest = text.strip_prefix('S')?;
    if !rest.trim_start().starts_with(|c: char| c.is_ascii_digit()) {
        return None;
    }
    Some(read_size(rest).map_err(|why| refuse(text, why)))
}

/// The size, pitch, hand and class after `S`.
fn read_size(rest: &str) -> Result<Designation, String> {
    let (body, class) = match rest.split_once('-') {
        Some((body, class)) => (body, Some(class.trim())),
        None => (rest, None),
    };
    let class = match class {
        None => None,
        Some(c) if TOLERANCE_CLASSES.contains(&c) => Some(c.to_string()),
        Some(c) if c.ends_with(|l: char| l.is_ascii_uppercase()) => {
            return Err(format!(
                "`{c}` is a nut's class, and DIN 513's nut thread is not built in whirl"
            ))
        }
        Some(c) => {
            return Err(format!(
                "`{c}` is not one of DIN 513-2's tolerance classes for the screw ({})",
                TOLERANCE_CLASSES.join(", ")
            ))
        }
    };
    let LeadScrewSize {
        d,
        lead,
        pitch,
        left_hand,
    } = lead_screw_size(body, "S 48x8")?;
    let starts = starts(lead, pitch, "mm")?;
    let form = Buttress::new(d).map_err(|e| e.to_string())?;
    // Refuse here a size whose form cannot be drawn, naming the designation.
    form.pieces(pitch).map_err(|e| e.to_string())?;
    Ok(Designation {
        form: StandardProfile::Buttress(form),
        lead: Some(lead),
        starts: Some(starts),
        left_hand,
        class,
        row: format!("DIN 513-1:1985 profile, d = {d} mm, P = {pitch} mm"),
    })
}

#[cfg(test)]
mod tests;
