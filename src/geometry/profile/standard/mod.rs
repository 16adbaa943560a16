//! Standard thread and groove profiles as exact axial sections.
//!
//! Thread standards draw a groove in the *axial section*: the half-plane through the screw axis.
//! This module turns the defining dimensions of three standard families into the exact
//! axial-section curve of one axial pitch of an **external** thread (a screw shaft), made of
//! straight lines and circular arcs ([`AxialPiece`]). The planner feeds that curve to the
//! groove model of `docs/kinematics.md` ("axial-section input": the point (ρ, z) of
//! the half-plane φ = 0 is the transverse point at radius ρ and polar angle φ = −z / p).
//!
//! # Families
//!
//! - [`IsoTrapezoidal`]: ISO metric trapezoidal thread (Tr), ISO 2901 / ISO 2904, 30° included
//!   flank angle, external thread on its design profile (crest clearance `a_c` added below the
//!   basic root, flanks extended into it).
//! - [`AcmeGeneralPurpose`]: general purpose Acme thread, ASME B1.5, 29° included angle,
//!   external thread with the standard's minor-diameter allowance added below the basic root.
//! - [`BallArc`]: single circular-arc ("ball-arc") ball-screw groove with zero contact angle.
//!
//! [`StandardProfile`] wraps the three so a job can carry any of them.
//!
//! # Conventions
//!
//! - Points are `DVec2::new(rho, z)`: `rho` is the radius from the screw axis, `z` the axial
//!   position, both in mm. Angles of arcs are in radians, measured in the (ρ, z) plane from
//!   the +ρ axis towards +z.
//! - One period covers z ∈ [−P/2, +P/2], where P is the **axial pitch** (lead / starts), which
//!   the caller passes to `pieces`. The groove (the cut, the root) is centred at z = 0; the
//!   crest (the uncut outer diameter) lies at both ends of the period.
//! - The pieces are ordered by increasing z and are continuous: each piece starts exactly
//!   where the previous one ended (shared endpoints are copied, not recomputed). The first
//!   starts at (d/2, −P/2) and the last ends at (d/2, +P/2), so the curve repeats by
//!   translation by P along z. Along the curve z never decreases.
//! - Signed curvature is the rate of turn of the unit tangent: positive when the tangent turns
//!   from +ρ towards +z (counter-clockwise in the (ρ, z) plane). With the traversal above, the
//!   concave corners at the bottom of a groove (root fillets, the ball-arc) have negative
//!   curvature.
//! - The crest corners are sharp in every family here: a whirling ring cuts the groove, the
//!   outer diameter is turned beforehand, so the crest corner is whatever the blank leaves.
//! - Every dimension is validated; bad input returns a [`StandardError`] naming the dimension
//!   and the reason, never a panic or a NaN curve.

use glam::DVec2;

mod ball_arc;
pub mod designation;
mod trapezoid;

pub use ball_arc::BallArc;
pub use trapezoid::{
    asme_b1_5_minor_diameter_allowance, iso2904_crest_clearance, AcmeGeneralPurpose,
    IsoTrapezoidal, MM_PER_INCH,
};

/// Why a standard profile's dimensions are rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StandardError {
    /// A dimension that must be a finite number above zero is not.
    #[error("{name} must be a finite number greater than zero, got {value}")]
    NotPositive {
        /// Which dimension.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A dimension that may be zero but not negative (a radius, a clearance) is negative or
    /// not finite.
    #[error("{name} must be a finite number not below zero, got {value}")]
    Negative {
        /// Which dimension.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// ISO 2904 gives no crest clearance `a_c` for this pitch.
    #[error(
        "pitch {pitch} mm lies outside ISO 2904's pitch range {min}..={max} mm, which gives no \
         crest clearance a_c for it; give the crest clearance explicitly"
    )]
    PitchOutsideStandard {
        /// The pitch given (mm).
        pitch: f64,
        /// Smallest pitch of the standard (mm).
        min: f64,
        /// Largest pitch of the standard (mm).
        max: f64,
    },
    /// The thread is deeper than the major radius: the minor diameter would be zero or less.
    #[error(
        "minor diameter would be {minor} mm: major diameter {major} mm is too small for a \
         thread depth of {depth} mm"
    )]
    MinorDiameterNotPositive {
        /// Major (outer) diameter (mm).
        major: f64,
        /// Thread depth from the major diameter (mm).
        depth: f64,
        /// The resulting minor diameter (mm).
        minor: f64,
    },
    /// The two flanks of a groove meet above the root: the pitch is too small for the depth.
    #[error(
        "flanks cross: pitch {pitch} mm is too small for a thread depth of {depth} mm (the root \
         flat would be {root_flat} mm wide)"
    )]
    FlanksCross {
        /// Axial pitch (mm).
        pitch: f64,
        /// Thread depth (mm).
        depth: f64,
        /// The (non-positive) root flat width it would give (mm).
        root_flat: f64,
    },
    /// The root radius is larger than the root fillets can be, tangent to both flanks, on the
    /// available root flat.
    #[error(
        "root radius {radius} mm is too large: at most {max} mm fits the root flat (a \
         full-radius root)"
    )]
    RootRadiusTooLarge {
        /// The root radius given (mm).
        radius: f64,
        /// The largest root radius that fits (mm).
        max: f64,
    },
    /// The ball-arc groove radius does not exceed the ball radius, so the ball would not touch
    /// the groove at its bottom only.
    #[error(
        "groove radius r_g = {groove_radius} mm must exceed the ball radius D_w/2 = \
         {ball_radius} mm (typical conformity r_g/D_w is 0.52 to 0.56)"
    )]
    GrooveRadiusTooSmall {
        /// Groove radius r_g (mm).
        groove_radius: f64,
        /// Ball radius D_w/2 (mm).
        ball_radius: f64,
    },
    /// The ball-centre (pitch-circle) diameter does not exceed the ball diameter: the groove
    /// bottom would be at or below the screw axis.
    #[error(
        "pitch-circle diameter d_0 = {pitch_circle_diameter} mm must exceed the ball diameter \
         D_w = {ball_diameter} mm, or the groove bottom is at or below the axis"
    )]
    GrooveBottomNotAboveAxis {
        /// Ball-centre diameter d_0 (mm).
        pitch_circle_diameter: f64,
        /// Ball diameter D_w (mm).
        ball_diameter: f64,
    },
    /// The outer diameter is not above the groove bottom: the ball would sit entirely above
    /// the shaft, there is no groove to cut.
    #[error(
        "outer diameter {outer} mm is not above the groove bottom diameter {bottom} mm: the \
         ball would sit above the outer diameter"
    )]
    OuterDiameterNotAboveGrooveBottom {
        /// Outer diameter d (mm).
        outer: f64,
        /// Groove bottom diameter d_0 − D_w (mm).
        bottom: f64,
    },
    /// The outer diameter reaches the widest point of the groove circle (its centre height), so
    /// the groove flanks would overhang (undercut) and the axial section would not be a
    /// function of z.
    #[error(
        "outer diameter {outer} mm reaches the groove arc's centre diameter {centre} mm: the \
         groove flanks would overhang"
    )]
    GrooveOverhangs {
        /// Outer diameter d (mm).
        outer: f64,
        /// Diameter of the groove arc's centre (mm).
        centre: f64,
    },
    /// The groove is at least as wide as the pitch at the outer diameter: neighbouring grooves
    /// overlap and no crest is left.
    #[error(
        "grooves overlap: the groove is {width} mm wide at the outer diameter, not less than \
         the pitch {pitch} mm"
    )]
    GroovesOverlap {
        /// Groove width at the outer diameter (mm).
        width: f64,
        /// Axial pitch (mm).
        pitch: f64,
    },
}

/// Checks that `value` is finite and above zero.
fn positive(name: &'static str, value: f64) -> Result<f64, StandardError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(StandardError::NotPositive { name, value })
    }
}

/// Checks that `value` is finite and not below zero.
fn non_negative(name: &'static str, value: f64) -> Result<f64, StandardError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(StandardError::Negative { name, value })
    }
}

/// One piece of an axial section, traversed from its start to its end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxialPiece {
    /// Straight segment from `from` to `to`.
    Line {
        /// Start point (rho, z).
        from: DVec2,
        /// End point (rho, z).
        to: DVec2,
    },
    /// Circular arc: centre, radius, start and end angle (radians, measured in the (rho, z)
    /// plane from the +rho axis towards +z); traversed from `start` to `end` (end < start:
    /// clockwise).
    Arc {
        /// Centre (rho, z).
        centre: DVec2,
        /// Radius (mm), above zero.
        radius: f64,
        /// Angle of the start point (radians).
        start: f64,
        /// Angle of the end point (radians).
        end: f64,
    },
}

impl AxialPiece {
    /// The point where the piece starts.
    pub fn start(&self) -> DVec2 {
        match *self {
            AxialPiece::Line { from, .. } => from,
            AxialPiece::Arc {
                centre,
                radius,
                start,
                ..
            } => centre + radius * DVec2::from_angle(start),
        }
    }

    /// The point where the piece ends.
    pub fn end(&self) -> DVec2 {
        match *self {
            AxialPiece::Line { to, .. } => to,
            AxialPiece::Arc {
                centre,
                radius,
                end,
                ..
            } => centre + radius * DVec2::from_angle(end),
        }
    }

    /// Arc length of the piece (mm).
    pub fn length(&self) -> f64 {
        match *self {
            AxialPiece::Line { from, to } => from.distance(to),
            AxialPiece::Arc {
                radius, start, end, ..
            } => radius * (end - start).abs(),
        }
    }

    /// Point, unit tangent (direction of travel) and signed curvature at arc length s from the
    /// start.
    ///
    /// `s` is clamped to `[0, length]`, so the point always lies on the piece. The curvature is
    /// positive when the tangent turns from +rho towards +z (counter-clockwise), i.e. `+1/r`
    /// for an arc with `end > start`, `−1/r` for `end < start`, and 0 for a line. A line of
    /// zero length has a zero tangent (there is no direction to report).
    pub fn eval(&self, s: f64) -> (DVec2, DVec2, f64) {
        // max/min rather than clamp: clamp panics on a NaN bound, and a hand-built piece may
        // have a NaN or negative radius.
        let s = s.max(0.0).min(self.length());
        match *self {
            AxialPiece::Line { from, to } => {
                let tangent = (to - from).normalize_or_zero();
                (from + tangent * s, tangent, 0.0)
            }
            AxialPiece::Arc {
                centre,
                radius,
                start,
                end,
            } => {
                // Direction of travel in angle: +1 counter-clockwise, −1 clockwise.
                let sense = if end >= start { 1.0 } else { -1.0 };
                let angle = start + sense * s / radius;
                let radial = DVec2::from_angle(angle);
                let tangent = sense * radial.perp();
                (centre + radius * radial, tangent, sense / radius)
            }
        }
    }
}

/// Any of the standard families, for jobs that name one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StandardProfile {
    /// ISO metric trapezoidal (Tr).
    IsoTrapezoidal(IsoTrapezoidal),
    /// General purpose Acme.
    Acme(AcmeGeneralPurpose),
    /// Circular-arc ball-screw groove.
    BallArc(BallArc),
}

/// One dimension of a standard form as `whirl profile` and the console's job page list it:
/// what the shop checks the drawing against.
#[derive(Debug, Clone, PartialEq)]
pub struct Dimension {
    /// What it is, in the standard's words and symbol ("thread height h3").
    pub name: &'static str,
    /// Its value in `unit`.
    pub value: f64,
    /// `"mm"` or `"°"`.
    pub unit: &'static str,
}

impl Dimension {
    /// A length, mm.
    pub fn mm(name: &'static str, value: f64) -> Dimension {
        Dimension {
            name,
            value,
            unit: "mm",
        }
    }

    /// An angle, degrees.
    pub fn deg(name: &'static str, value: f64) -> Dimension {
        Dimension {
            name,
            value,
            unit: "°",
        }
    }
}

impl StandardProfile {
    /// The standard (and edition, table) the form's rules come from.
    pub fn source(&self) -> &'static str {
        match self {
            StandardProfile::IsoTrapezoidal(_) => "ISO 2901:2016 basic profile, ISO 2904:2020 a_c",
            StandardProfile::Acme(_) => "ASME B1.5-1997 general purpose Acme",
            StandardProfile::BallArc(_) => "circular-arc ball-screw raceway (catalogue data)",
        }
    }

    /// The form's dimensions at this axial pitch (mm): depth, flank angles, radii,
    /// diameters, as the standard names them.
    pub fn dimensions(&self, pitch: f64) -> Result<Vec<Dimension>, StandardError> {
        Ok(match self {
            StandardProfile::IsoTrapezoidal(t) => vec![
                Dimension::mm("major diameter d", t.major_diameter()),
                Dimension::mm("pitch diameter d2", t.major_diameter() - 0.5 * pitch),
                Dimension::mm("minor diameter d3", t.minor_diameter(pitch)?),
                Dimension::mm("thread height h3", t.thread_height(pitch)?),
                Dimension::mm("crest clearance a_c", t.crest_clearance(pitch)?),
                Dimension::deg("flank angle", 2.0 * IsoTrapezoidal::FLANK_HALF_ANGLE_DEG),
                Dimension::mm("root radius", t.root_radius()),
            ],
            StandardProfile::Acme(a) => vec![
                Dimension::mm("major diameter", a.major_diameter()),
                Dimension::mm("pitch diameter", a.major_diameter() - 0.5 * pitch),
                Dimension::mm("minor diameter", a.minor_diameter(pitch)?),
                Dimension::mm("thread height", a.thread_height(pitch)?),
                Dimension::deg(
                    "flank angle",
                    2.0 * AcmeGeneralPurpose::FLANK_HALF_ANGLE_DEG,
                ),
                Dimension::mm("root radius", a.root_radius()),
            ],
            StandardProfile::BallArc(b) => vec![
                Dimension::mm("outer diameter", b.outer_diameter()),
                Dimension::mm("ball diameter D_w", b.ball_diameter()),
                Dimension::mm("ball-centre diameter d_0", b.pitch_circle_diameter()),
                Dimension::mm("groove radius r_g", b.groove_radius()),
                Dimension::mm("groove depth", b.depth()),
                Dimension::mm("groove width", b.groove_width()),
            ],
        })
    }

    /// Outer (major) diameter of the shaft (mm): the crest radius is half of it.
    pub fn outer_diameter(&self) -> f64 {
        match self {
            StandardProfile::IsoTrapezoidal(t) => t.major_diameter(),
            StandardProfile::Acme(a) => a.major_diameter(),
            StandardProfile::BallArc(b) => b.outer_diameter(),
        }
    }

    /// The axial section of one pitch of the wrapped profile.
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        match self {
            StandardProfile::IsoTrapezoidal(t) => t.pieces(pitch),
            StandardProfile::Acme(a) => a.pieces(pitch),
            StandardProfile::BallArc(b) => b.pieces(pitch),
        }
    }
}

#[cfg(test)]
mod tests;
