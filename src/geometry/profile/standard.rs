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
use std::f64::consts::{FRAC_PI_2, PI};

/// Millimetres per inch (exact by definition), for the inch-based Acme rules.
pub const MM_PER_INCH: f64 = 25.4;

/// Tolerance (mm) when comparing a pitch with the boundaries of a standard's pitch classes, so
/// that a pitch such as 10 tpi = 2.54 mm, computed in floating point, falls in its class.
const PITCH_CLASS_EPS: f64 = 1e-9;

/// Relative tolerance within which a root radius equal to the largest that fits (a full-radius
/// root, no root flat left) is taken as exactly that largest value, whether it lies slightly
/// above or below it.
const FULL_RADIUS_REL_EPS: f64 = 1e-9;

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

/// The symmetric trapezoidal groove shared by the ISO trapezoidal and Acme forms.
///
/// Both standards fix the flanks by the same two facts: the thread is `P/2` thick at the pitch
/// line, which lies `P/4` below the crest (basic height `P/2`, pitch diameter `d − P/2`), and
/// each flank makes the half-angle `beta` with the radial direction. The groove half-width at
/// radius `rho` is therefore `P/4 + (rho − (R − P/4))·tan(beta)`, R = d/2, and every flat
/// (crest, root) follows from it. The extra depth below the basic root (ISO's `a_c`, Acme's
/// minor-diameter allowance) extends the flanks, narrowing the root flat by `2·extra·tan(beta)`.
///
/// The root corners are either sharp (`root_radius == 0`) or rounded by fillets tangent to
/// the flank and the root flat; the crest corners are sharp.
fn trapezoid_pieces(
    pitch: f64,
    crest_rho: f64,
    depth: f64,
    half_angle: f64,
    root_radius: f64,
) -> Result<Vec<AxialPiece>, StandardError> {
    let root_rho = crest_rho - depth;
    if root_rho <= 0.0 {
        return Err(StandardError::MinorDiameterNotPositive {
            major: 2.0 * crest_rho,
            depth,
            minor: 2.0 * root_rho,
        });
    }
    let tan_b = half_angle.tan();
    let quarter = 0.25 * pitch;
    // Groove half-widths at the crest and at the root.
    let crest_half = quarter + quarter * tan_b;
    let root_half = quarter + (quarter - depth) * tan_b;
    if root_half <= 0.0 {
        return Err(StandardError::FlanksCross {
            pitch,
            depth,
            root_flat: 2.0 * root_half,
        });
    }

    // A fillet tangent to a flank and to the root flat turns the tangent by
    // `turn = 90° − beta`; its tangent points lie `r·tan(turn/2)` from the sharp corner. Two
    // fillets share the root flat, so `r·tan(turn/2) <= root_half`. (The flank, at least
    // `depth/cos(beta) > P/2 > root_half` long for these forms, never limits first.)
    let turn = FRAC_PI_2 - half_angle;
    let setback_per_radius = (0.5 * turn).tan();
    let max_radius = root_half / setback_per_radius;
    if root_radius > max_radius * (1.0 + FULL_RADIUS_REL_EPS) {
        return Err(StandardError::RootRadiusTooLarge {
            radius: root_radius,
            max: max_radius,
        });
    }

    let crest_start = DVec2::new(crest_rho, -0.5 * pitch);
    let crest_left = DVec2::new(crest_rho, -crest_half);
    let crest_right = DVec2::new(crest_rho, crest_half);
    let crest_end = DVec2::new(crest_rho, 0.5 * pitch);

    let mut pieces = Vec::with_capacity(7);
    pieces.push(AxialPiece::Line {
        from: crest_start,
        to: crest_left,
    });

    if root_radius == 0.0 {
        // Sharp root corners: ISO and Acme allow them (a radius is permitted, not required),
        // though a real insert always leaves its own nose radius there.
        let root_left = DVec2::new(root_rho, -root_half);
        let root_right = DVec2::new(root_rho, root_half);
        pieces.push(AxialPiece::Line {
            from: crest_left,
            to: root_left,
        });
        pieces.push(AxialPiece::Line {
            from: root_left,
            to: root_right,
        });
        pieces.push(AxialPiece::Line {
            from: root_right,
            to: crest_right,
        });
    } else if root_radius >= max_radius * (1.0 - FULL_RADIUS_REL_EPS) {
        // Full-radius root (within rounding of the largest radius, so that no sliver of root
        // flat is left): the two fillets meet at z = 0 and form one arc, centred on the groove
        // axis, tangent to both flanks.
        let arc = AxialPiece::Arc {
            centre: DVec2::new(root_rho + max_radius, 0.0),
            radius: max_radius,
            start: -(FRAC_PI_2 + half_angle),
            end: -(PI + FRAC_PI_2 - half_angle),
        };
        pieces.push(AxialPiece::Line {
            from: crest_left,
            to: arc.start(),
        });
        pieces.push(arc);
        pieces.push(AxialPiece::Line {
            from: arc.end(),
            to: crest_right,
        });
    } else {
        let r = root_radius;
        let setback = r * setback_per_radius;
        // Centres lie in the groove, r above the root flat and r from the flank. Both fillets
        // turn clockwise (flank direction → +z → flank direction).
        let left = AxialPiece::Arc {
            centre: DVec2::new(root_rho + r, -root_half + setback),
            radius: r,
            start: -(FRAC_PI_2 + half_angle),
            end: -PI,
        };
        let right = AxialPiece::Arc {
            centre: DVec2::new(root_rho + r, root_half - setback),
            radius: r,
            start: PI,
            end: FRAC_PI_2 + half_angle,
        };
        pieces.push(AxialPiece::Line {
            from: crest_left,
            to: left.start(),
        });
        pieces.push(left);
        pieces.push(AxialPiece::Line {
            from: left.end(),
            to: right.start(),
        });
        pieces.push(right);
        pieces.push(AxialPiece::Line {
            from: right.end(),
            to: crest_right,
        });
    }

    pieces.push(AxialPiece::Line {
        from: crest_right,
        to: crest_end,
    });
    Ok(pieces)
}

/// Crest clearance `a_c` (mm) of the ISO metric trapezoidal thread for a pitch (mm).
///
/// ISO 2901 (design profiles) and ISO 2904 (basic dimensions) give `a_c` by pitch: 0.15 mm for
/// P = 1.5, 0.25 mm for P = 2 to 5, 0.5 mm for P = 6 to 12 and 1 mm for P = 14 to 44 mm
/// (the series of the standard runs from 1.5 to 44 mm). A pitch between two listed ranges
/// takes the larger clearance, i.e. the rule `P ≤ 1.5 → 0.15; P ≤ 5 → 0.25; P ≤ 12 → 0.5;
/// otherwise 1`, as the standard's table is usually encoded. A pitch below 1.5 mm or above
/// 44 mm is outside the standard: [`StandardError::PitchOutsideStandard`] (give the clearance
/// explicitly to [`IsoTrapezoidal::new`] for such a pitch).
///
/// Sources consulted: ISO 2901:2016 clause 6 (design profiles: `h3 = H4 = 0.5P + a_c`,
/// `d3 = d − 2h3`, `R1max = 0.5 a_c`, `R2max = a_c`), the ISO 2904 clearance-by-pitch rule as
/// encoded by public ISO 2904 calculators (e.g. eng-calculations.com, "ISO 2904 basic
/// dimensions"), and reproductions of ISO 2904's table of basic dimensions (e.g. roymech.org,
/// "Trapezoidal", after ISO 2904 / DIN 103-4), whose minor diameters agree with it.
pub fn iso2904_crest_clearance(pitch: f64) -> Result<f64, StandardError> {
    const MIN: f64 = 1.5;
    const MAX: f64 = 44.0;
    let p = positive("pitch", pitch)?;
    if !(MIN - PITCH_CLASS_EPS..=MAX + PITCH_CLASS_EPS).contains(&p) {
        return Err(StandardError::PitchOutsideStandard {
            pitch: p,
            min: MIN,
            max: MAX,
        });
    }
    Ok(if p <= 1.5 + PITCH_CLASS_EPS {
        0.15
    } else if p <= 5.0 + PITCH_CLASS_EPS {
        0.25
    } else if p <= 12.0 + PITCH_CLASS_EPS {
        0.5
    } else {
        1.0
    })
}

/// ISO metric trapezoidal thread (Tr, ISO 2901 / ISO 2904), external thread, design profile.
///
/// Geometry (ISO 2901 design profile): flank half-angle 15° (30° included), overlap height
/// `H1 = 0.5·P`, thread height `h3 = H1 + a_c`, minor diameter `d3 = d − 2·h3`, pitch diameter
/// `d2 = d − H1`. The crest flat, `P/2·(1 − tan 15°)` (ISO's "0.366 P"), follows from the flanks
/// and the thread thickness `P/2` at the pitch line; the root flat is that basic flat narrowed
/// by the extra depth: `P/2·(1 − tan 15°) − 2·a_c·tan 15°`.
///
/// The crest corners are left sharp. The root corners get fillets of `root_radius`; 0 (the
/// default) gives sharp concave root corners, which the standard allows but which a cutting
/// insert never leaves exactly (it leaves its nose radius). Note on naming: ISO 2901/2904 call
/// the radius on the *root* corners `R2` (maximum `a_c`) and the radius on the external
/// thread's *crest* corners `R1` (maximum `0.5·a_c`). This type checks only that the root
/// radius fits geometrically ([`StandardError::RootRadiusTooLarge`]); whether it stays within
/// the standard's maximum is the caller's choice ([`Self::iso_max_root_radius`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsoTrapezoidal {
    major_diameter: f64,
    root_radius: f64,
    crest_clearance: Option<f64>,
}

impl IsoTrapezoidal {
    /// Flank half-angle: 15°, i.e. 30° included.
    pub const FLANK_HALF_ANGLE_DEG: f64 = 15.0;

    /// A trapezoidal thread of major (nominal) diameter `d` (mm), with an optional root fillet
    /// radius (mm, default 0: sharp root corners) and an optional crest clearance `a_c` (mm)
    /// that replaces the standard's value (0 gives the basic profile; use it also for pitches
    /// outside ISO 2904's range).
    pub fn new(
        major_diameter: f64,
        root_radius: Option<f64>,
        crest_clearance: Option<f64>,
    ) -> Result<Self, StandardError> {
        let major_diameter = positive("major diameter d", major_diameter)?;
        let root_radius = non_negative("root radius", root_radius.unwrap_or(0.0))?;
        let crest_clearance = crest_clearance
            .map(|a| non_negative("crest clearance a_c", a))
            .transpose()?;
        Ok(Self {
            major_diameter,
            root_radius,
            crest_clearance,
        })
    }

    /// Major (nominal) diameter d (mm).
    pub fn major_diameter(&self) -> f64 {
        self.major_diameter
    }

    /// Root fillet radius (mm); 0 means sharp root corners.
    pub fn root_radius(&self) -> f64 {
        self.root_radius
    }

    /// Crest clearance `a_c` (mm) used at this pitch: the override if one was given, else
    /// ISO 2904's value ([`iso2904_crest_clearance`]).
    pub fn crest_clearance(&self, pitch: f64) -> Result<f64, StandardError> {
        let pitch = positive("pitch", pitch)?;
        match self.crest_clearance {
            Some(a_c) => Ok(a_c),
            None => iso2904_crest_clearance(pitch),
        }
    }

    /// Thread height of the external thread, `h3 = 0.5·P + a_c` (mm).
    pub fn thread_height(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(0.5 * pitch + self.crest_clearance(pitch)?)
    }

    /// Minor diameter of the external thread, `d3 = d − 2·h3` (mm).
    pub fn minor_diameter(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(self.major_diameter - 2.0 * self.thread_height(pitch)?)
    }

    /// Largest root radius ISO 2901 allows on the design profile, `R2max = a_c` (mm).
    pub fn iso_max_root_radius(&self, pitch: f64) -> Result<f64, StandardError> {
        self.crest_clearance(pitch)
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let depth = self.thread_height(pitch)?;
        trapezoid_pieces(
            pitch,
            0.5 * self.major_diameter,
            depth,
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            self.root_radius,
        )
    }
}

/// Minor-diameter allowance (mm, on the diameter) of a general purpose Acme external thread.
///
/// ASME B1.5 (general purpose series, all classes 2G/3G/4G) makes the screw's minor diameter
/// `D − P − allowance`, i.e. the total thread depth `0.5·P + allowance/2`, with an allowance
/// of 0.020 in for 10 threads per inch and coarser (P ≥ 0.1 in = 2.54 mm) and 0.010 in for
/// finer pitches. Sources consulted: the ASME B1.5 table "Acme thread form, basic
/// dimensions" as reproduced in manufacturers' data sheets (total depth of thread, all screws:
/// 0.0362 in at 16 tpi = 0.5P + 0.005, 0.0600 in at 10 tpi = 0.5P + 0.010; root flat of screw
/// 0.3707P − 0.259 × allowance), and published 2G screw limits (e.g. 1/2-10: minor diameter
/// max 0.3800 in = 0.5 − 0.1 − 0.020; 3/8-12: 0.2817 in = 0.375 − 1/12 − 0.010). The flat
/// formulas are those of ASME B1.5 §2 as quoted by amesweb.info ("ACME thread profile
/// formulas"); the limits are from a manufacturer's 2G table (dependableacme.com, "internal
/// and external thread dimensions"). The standard's own text (§2.5, "Allowance (minimum
/// clearance) at major and minor diameters") was not available to read here.
pub fn asme_b1_5_minor_diameter_allowance(pitch: f64) -> Result<f64, StandardError> {
    let p = positive("pitch", pitch)?;
    Ok(if p >= 0.1 * MM_PER_INCH - PITCH_CLASS_EPS {
        0.020 * MM_PER_INCH
    } else {
        0.010 * MM_PER_INCH
    })
}

/// General purpose Acme thread (ASME B1.5), external thread, all dimensions in mm.
///
/// Geometry: flank half-angle 14.5° (29° included), basic height `0.5·P`, basic thickness `P/2`
/// at the pitch diameter `d − 0.5·P`, total depth `0.5·P + allowance/2` with the minor-diameter
/// allowance of [`asme_b1_5_minor_diameter_allowance`]. The crest flat is
/// `P/2·(1 − tan 14.5°)` (the standard's "0.3707 P"); the root flat is narrowed by the
/// allowance: `P/2·(1 − tan 14.5°) − allowance·tan 14.5°` (the standard's
/// "0.3707 P − 0.259 × allowance").
///
/// This is the maximum-material basic form: the class-dependent pitch-diameter allowance and
/// tolerances of the 2G/3G/4G classes are not applied (they thin the thread, they do not move
/// the root). The crest corners are sharp; the root corners get fillets of `root_radius`
/// (default 0: sharp, allowed). Only the geometric fit of the radius is checked here.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AcmeGeneralPurpose {
    major_diameter: f64,
    root_radius: f64,
}

impl AcmeGeneralPurpose {
    /// Flank half-angle: 14.5°, i.e. 29° included.
    pub const FLANK_HALF_ANGLE_DEG: f64 = 14.5;

    /// An Acme screw of major diameter `d` (mm) with an optional root fillet radius (mm,
    /// default 0: sharp root corners).
    pub fn new(major_diameter: f64, root_radius: Option<f64>) -> Result<Self, StandardError> {
        let major_diameter = positive("major diameter d", major_diameter)?;
        let root_radius = non_negative("root radius", root_radius.unwrap_or(0.0))?;
        Ok(Self {
            major_diameter,
            root_radius,
        })
    }

    /// Major diameter d (mm).
    pub fn major_diameter(&self) -> f64 {
        self.major_diameter
    }

    /// Root fillet radius (mm); 0 means sharp root corners.
    pub fn root_radius(&self) -> f64 {
        self.root_radius
    }

    /// Total thread depth of the screw, `0.5·P + allowance/2` (mm).
    pub fn thread_height(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(0.5 * pitch + 0.5 * asme_b1_5_minor_diameter_allowance(pitch)?)
    }

    /// Minor diameter of the screw, `d − P − allowance` (mm).
    pub fn minor_diameter(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(self.major_diameter - 2.0 * self.thread_height(pitch)?)
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let depth = self.thread_height(pitch)?;
        trapezoid_pieces(
            pitch,
            0.5 * self.major_diameter,
            depth,
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            self.root_radius,
        )
    }
}

/// Single circular-arc ball-screw groove ("ball-arc"), zero contact angle.
///
/// The groove is one arc of radius `r_g > D_w/2` (conformity `r_g/D_w`, typically 0.52 to
/// 0.56), placed so that the ball, centred on the ball-centre (pitch-circle) diameter `d_0`,
/// touches it at the groove bottom: groove bottom at `rho = d_0/2 − D_w/2`, arc centre at
/// `rho = d_0/2 − D_w/2 + r_g`, `z = 0`. The arc runs up to the outer diameter `d`; between
/// grooves the crest is the outer diameter, a line at `rho = d/2`. The corners where the arc
/// meets the outer diameter are sharp.
///
/// The outer diameter must lie above the groove bottom and below the arc centre (else the
/// flanks would overhang); the pitch must leave a crest between grooves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallArc {
    ball_diameter: f64,
    groove_radius: f64,
    pitch_circle_diameter: f64,
    outer_diameter: f64,
}

impl BallArc {
    /// A ball-arc groove for balls of diameter `D_w`, groove radius `r_g`, ball-centre diameter
    /// `d_0` and shaft outer diameter `d`, all in mm.
    pub fn new(
        ball_diameter: f64,
        groove_radius: f64,
        pitch_circle_diameter: f64,
        outer_diameter: f64,
    ) -> Result<Self, StandardError> {
        let ball_diameter = positive("ball diameter D_w", ball_diameter)?;
        let groove_radius = positive("groove radius r_g", groove_radius)?;
        let pitch_circle_diameter = positive("ball-centre diameter d_0", pitch_circle_diameter)?;
        let outer_diameter = positive("outer diameter d", outer_diameter)?;
        if groove_radius <= 0.5 * ball_diameter {
            return Err(StandardError::GrooveRadiusTooSmall {
                groove_radius,
                ball_radius: 0.5 * ball_diameter,
            });
        }
        if pitch_circle_diameter <= ball_diameter {
            return Err(StandardError::GrooveBottomNotAboveAxis {
                pitch_circle_diameter,
                ball_diameter,
            });
        }
        let groove = Self {
            ball_diameter,
            groove_radius,
            pitch_circle_diameter,
            outer_diameter,
        };
        let bottom = groove.groove_bottom_radius();
        let centre = groove.arc_centre().x;
        let outer = 0.5 * outer_diameter;
        if outer <= bottom {
            return Err(StandardError::OuterDiameterNotAboveGrooveBottom {
                outer: outer_diameter,
                bottom: 2.0 * bottom,
            });
        }
        if outer >= centre {
            return Err(StandardError::GrooveOverhangs {
                outer: outer_diameter,
                centre: 2.0 * centre,
            });
        }
        Ok(groove)
    }

    /// Ball diameter D_w (mm).
    pub fn ball_diameter(&self) -> f64 {
        self.ball_diameter
    }

    /// Groove radius r_g (mm).
    pub fn groove_radius(&self) -> f64 {
        self.groove_radius
    }

    /// Ball-centre (pitch-circle) diameter d_0 (mm).
    pub fn pitch_circle_diameter(&self) -> f64 {
        self.pitch_circle_diameter
    }

    /// Outer diameter d (mm).
    pub fn outer_diameter(&self) -> f64 {
        self.outer_diameter
    }

    /// Conformity `r_g / D_w`.
    pub fn conformity(&self) -> f64 {
        self.groove_radius / self.ball_diameter
    }

    /// Radius of the groove bottom, `d_0/2 − D_w/2` (mm).
    pub fn groove_bottom_radius(&self) -> f64 {
        0.5 * (self.pitch_circle_diameter - self.ball_diameter)
    }

    /// Centre (rho, z) of the groove arc.
    pub fn arc_centre(&self) -> DVec2 {
        DVec2::new(self.groove_bottom_radius() + self.groove_radius, 0.0)
    }

    /// Groove depth below the outer diameter, `d/2 − (d_0/2 − D_w/2)` (mm).
    pub fn depth(&self) -> f64 {
        0.5 * self.outer_diameter - self.groove_bottom_radius()
    }

    /// Axial width of the groove at the outer diameter (mm).
    pub fn groove_width(&self) -> f64 {
        let below_centre = self.arc_centre().x - 0.5 * self.outer_diameter;
        2.0 * (self.groove_radius * self.groove_radius - below_centre * below_centre).sqrt()
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        let width = self.groove_width();
        if width >= pitch {
            return Err(StandardError::GroovesOverlap { width, pitch });
        }
        let centre = self.arc_centre();
        let outer = 0.5 * self.outer_diameter;
        // Angle between the arc's radius to its end on the outer diameter and the −rho
        // direction; the arc passes through the bottom (angle ±π) clockwise.
        let half_sweep = (0.5 * width).atan2(centre.x - outer);
        let arc = AxialPiece::Arc {
            centre,
            radius: self.groove_radius,
            start: -PI + half_sweep,
            end: -PI - half_sweep,
        };
        Ok(vec![
            AxialPiece::Line {
                from: DVec2::new(outer, -0.5 * pitch),
                to: arc.start(),
            },
            arc,
            AxialPiece::Line {
                from: arc.end(),
                to: DVec2::new(outer, 0.5 * pitch),
            },
        ])
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

impl StandardProfile {
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
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_4;

    const TOL: f64 = 1e-12;

    /// Checks the chain conventions every profile must meet; returns a description of the
    /// first violation.
    fn chain_violation(pieces: &[AxialPiece], pitch: f64, crest_rho: f64) -> Option<String> {
        let first = pieces.first()?;
        let last = pieces.last()?;
        if first.start().distance(DVec2::new(crest_rho, -0.5 * pitch)) > TOL {
            return Some(format!("first piece starts at {}", first.start()));
        }
        if last.end().distance(DVec2::new(crest_rho, 0.5 * pitch)) > TOL {
            return Some(format!("last piece ends at {}", last.end()));
        }
        for (i, w) in pieces.windows(2).enumerate() {
            if w[0].end().distance(w[1].start()) > TOL {
                return Some(format!("gap after piece {i}"));
            }
        }
        let mut last_z = f64::NEG_INFINITY;
        for (i, p) in pieces.iter().enumerate() {
            let len = p.length();
            if len.is_nan() || len <= 0.0 {
                return Some(format!("piece {i} has length {len}"));
            }
            let (p0, _, _) = p.eval(0.0);
            let (p1, _, _) = p.eval(len);
            if p0.distance(p.start()) > TOL || p1.distance(p.end()) > TOL {
                return Some(format!("piece {i}: eval disagrees with start/end"));
            }
            for k in 0..=16 {
                let (pt, tangent, _) = p.eval(len * k as f64 / 16.0);
                if (tangent.length() - 1.0).abs() > 1e-12 {
                    return Some(format!("piece {i}: tangent not unit"));
                }
                if pt.y < last_z - TOL {
                    return Some(format!("piece {i}: z decreases"));
                }
                if pt.x > crest_rho + TOL {
                    return Some(format!("piece {i}: above the crest"));
                }
                last_z = pt.y;
            }
        }
        None
    }

    /// z values where the straight pieces cross the radius `rho` (strictly inside the piece).
    fn crossings(pieces: &[AxialPiece], rho: f64) -> Vec<f64> {
        pieces
            .iter()
            .filter_map(|p| match *p {
                AxialPiece::Line { from, to } if (from.x - rho) * (to.x - rho) < 0.0 => {
                    let t = (rho - from.x) / (to.x - from.x);
                    Some(from.y + t * (to.y - from.y))
                }
                _ => None,
            })
            .collect()
    }

    fn min_rho(pieces: &[AxialPiece]) -> f64 {
        pieces
            .iter()
            .flat_map(|p| {
                let len = p.length();
                (0..=1000).map(move |k| p.eval(len * k as f64 / 1000.0).0.x)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Angle (degrees) between a line piece and the radial direction.
    fn angle_to_radial_deg(from: DVec2, to: DVec2) -> f64 {
        let d = to - from;
        d.y.abs().atan2(d.x.abs()).to_degrees()
    }

    /// The flank lines: neither radial-only nor axial-only.
    fn flanks(pieces: &[AxialPiece]) -> Vec<(DVec2, DVec2)> {
        pieces
            .iter()
            .filter_map(|p| match *p {
                AxialPiece::Line { from, to }
                    if (to.x - from.x).abs() > 1e-9 && (to.y - from.y).abs() > 1e-9 =>
                {
                    Some((from, to))
                }
                _ => None,
            })
            .collect()
    }

    /// Total length of the axial lines at the given radius.
    fn flat_at(pieces: &[AxialPiece], rho: f64) -> f64 {
        pieces
            .iter()
            .filter_map(|p| match *p {
                AxialPiece::Line { from, to }
                    if (from.x - rho).abs() < 1e-9 && (to.x - rho).abs() < 1e-9 =>
                {
                    Some(to.y - from.y)
                }
                _ => None,
            })
            .sum()
    }

    fn assert_close(a: f64, b: f64, tol: f64) {
        assert!((a - b).abs() <= tol, "{a} vs {b} (tol {tol})");
    }

    // ---------- AxialPiece ----------

    #[test]
    fn line_eval_walks_the_segment() {
        let line = AxialPiece::Line {
            from: DVec2::new(1.0, 2.0),
            to: DVec2::new(4.0, 6.0),
        };
        assert_close(line.length(), 5.0, TOL);
        let (p, t, k) = line.eval(2.5);
        assert!(p.distance(DVec2::new(2.5, 4.0)) < TOL);
        assert!(t.distance(DVec2::new(0.6, 0.8)) < TOL);
        assert_eq!(k, 0.0);
        // Clamped beyond the ends.
        assert!(line.eval(-1.0).0.distance(line.start()) < TOL);
        assert!(line.eval(99.0).0.distance(line.end()) < TOL);
    }

    #[test]
    fn malformed_arc_does_not_panic() {
        for radius in [f64::NAN, -1.0, 0.0] {
            let arc = AxialPiece::Arc {
                centre: DVec2::ZERO,
                radius,
                start: 0.0,
                end: 1.0,
            };
            let _ = arc.eval(0.5);
            let _ = arc.eval(f64::NAN);
        }
    }

    #[test]
    fn degenerate_line_does_not_panic() {
        let p = DVec2::new(1.0, 1.0);
        let line = AxialPiece::Line { from: p, to: p };
        let (q, t, k) = line.eval(0.5);
        assert_eq!((q, t, k), (p, DVec2::ZERO, 0.0));
        let (q, _, _) = line.eval(f64::NAN);
        assert!(q.x.is_nan() || q == p);
    }

    #[test]
    fn arc_eval_counter_clockwise_and_clockwise() {
        let c = DVec2::new(10.0, 0.0);
        let ccw = AxialPiece::Arc {
            centre: c,
            radius: 2.0,
            start: 0.0,
            end: FRAC_PI_2,
        };
        assert_close(ccw.length(), PI, TOL);
        assert!(ccw.start().distance(DVec2::new(12.0, 0.0)) < TOL);
        assert!(ccw.end().distance(DVec2::new(10.0, 2.0)) < TOL);
        let (p, t, k) = ccw.eval(0.5 * PI);
        let s2 = 2f64.sqrt();
        assert!(p.distance(c + DVec2::new(s2, s2)) < TOL);
        assert!(t.distance(DVec2::new(-1.0, 1.0) / s2) < TOL);
        assert_close(k, 0.5, TOL);

        let cw = AxialPiece::Arc {
            centre: c,
            radius: 2.0,
            start: FRAC_PI_2,
            end: 0.0,
        };
        let (p, t, k) = cw.eval(0.0);
        assert!(p.distance(DVec2::new(10.0, 2.0)) < TOL);
        assert!(t.distance(DVec2::new(1.0, 0.0)) < TOL);
        assert_close(k, -0.5, TOL);
        assert!(cw.eval(cw.length()).0.distance(cw.end()) < TOL);
    }

    // ---------- ISO trapezoidal ----------

    #[test]
    fn iso_crest_clearance_follows_the_standard_table() {
        assert_eq!(iso2904_crest_clearance(1.5), Ok(0.15));
        for p in [2.0, 3.0, 4.0, 5.0] {
            assert_eq!(iso2904_crest_clearance(p), Ok(0.25), "P = {p}");
        }
        for p in [6.0, 7.0, 8.0, 9.0, 10.0, 12.0] {
            assert_eq!(iso2904_crest_clearance(p), Ok(0.5), "P = {p}");
        }
        for p in [14.0, 16.0, 18.0, 20.0, 24.0, 32.0, 44.0] {
            assert_eq!(iso2904_crest_clearance(p), Ok(1.0), "P = {p}");
        }
    }

    #[test]
    fn iso_pitch_outside_the_standard_needs_an_explicit_clearance() {
        for p in [1.0, 1.49, 44.5, 60.0] {
            assert!(matches!(
                iso2904_crest_clearance(p),
                Err(StandardError::PitchOutsideStandard { .. })
            ));
            let tr = IsoTrapezoidal::new(40.0, None, None).unwrap();
            assert!(matches!(
                tr.pieces(p),
                Err(StandardError::PitchOutsideStandard { .. })
            ));
        }
        let tr = IsoTrapezoidal::new(40.0, None, Some(0.1)).unwrap();
        let pieces = tr.pieces(1.0).unwrap();
        assert_close(min_rho(&pieces), 20.0 - (0.5 + 0.1), 1e-9);
    }

    /// Minor diameters d3 from ISO 2904's table of basic dimensions (as republished, e.g. in
    /// DIN 103-4 tables): Tr 8×1.5 → 6.2, Tr 10×2 → 7.5, Tr 42×3 → 38.5, Tr 42×7 → 34,
    /// Tr 46×8 → 37.
    #[test]
    fn iso_minor_diameter_matches_the_standard_table() {
        for (d, p, d3) in [
            (8.0, 1.5, 6.2),
            (10.0, 2.0, 7.5),
            (42.0, 3.0, 38.5),
            (42.0, 7.0, 34.0),
            (46.0, 8.0, 37.0),
        ] {
            let tr = IsoTrapezoidal::new(d, None, None).unwrap();
            assert_close(tr.minor_diameter(p).unwrap(), d3, 1e-9);
            // The curve itself reaches exactly down to d3/2.
            assert_close(min_rho(&tr.pieces(p).unwrap()), 0.5 * d3, 1e-9);
        }
    }

    #[test]
    fn iso_flanks_make_15_degrees_with_the_radial_direction() {
        for r in [0.0, 0.1, 0.25] {
            let tr = IsoTrapezoidal::new(40.0, Some(r), None).unwrap();
            let pieces = tr.pieces(7.0).unwrap();
            let f = flanks(&pieces);
            assert_eq!(f.len(), 2);
            for (a, b) in f {
                assert_close(angle_to_radial_deg(a, b), 15.0, 1e-9);
            }
        }
    }

    #[test]
    fn iso_width_at_pitch_line_is_half_the_pitch() {
        // Basic profile (a_c = 0) and design profile alike: the thread is P/2 thick on the
        // pitch diameter d2 = d − H1 = d − P/2.
        for a_c in [Some(0.0), None] {
            let (d, p) = (40.0, 7.0);
            let tr = IsoTrapezoidal::new(d, Some(0.3), a_c).unwrap();
            let z = crossings(&tr.pieces(p).unwrap(), 0.5 * (d - 0.5 * p));
            assert_eq!(z.len(), 2);
            assert_close(z[1] - z[0], 0.5 * p, 1e-9);
            assert_close(z[0] + z[1], 0.0, 1e-9);
        }
    }

    #[test]
    fn iso_flats_match_the_basic_profile() {
        let (d, p) = (40.0, 7.0);
        // ISO 2901: the basic profile has flats w = 0.366 P (rounded in the standard), equal
        // at crest and root since tooth and groove are alike.
        let basic = IsoTrapezoidal::new(d, None, Some(0.0)).unwrap();
        let pieces = basic.pieces(p).unwrap();
        let crest = flat_at(&pieces, 0.5 * d);
        let root = flat_at(&pieces, 0.5 * d - 0.5 * p);
        assert_close(crest / p, 0.366, 5e-4);
        assert_close(root, crest, 1e-9);
        // Design profile: same crest, root narrowed by the extra depth a_c on both flanks.
        let design = IsoTrapezoidal::new(d, None, None).unwrap();
        let a_c = 0.5;
        let pieces = design.pieces(p).unwrap();
        assert_close(flat_at(&pieces, 0.5 * d), crest, 1e-9);
        let root_design = flat_at(&pieces, 0.5 * d - 0.5 * p - a_c);
        assert_close(
            root_design,
            root - 2.0 * a_c * 15f64.to_radians().tan(),
            1e-9,
        );
    }

    #[test]
    fn iso_root_fillets_are_tangent_and_keep_the_depth() {
        let (d, p, r) = (40.0, 7.0, 0.5); // r = R2max = a_c
        let tr = IsoTrapezoidal::new(d, Some(r), None).unwrap();
        assert_close(tr.iso_max_root_radius(p).unwrap(), 0.5, 0.0);
        let pieces = tr.pieces(p).unwrap();
        assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
        let arcs: Vec<_> = pieces
            .iter()
            .enumerate()
            .filter(|(_, q)| matches!(q, AxialPiece::Arc { .. }))
            .map(|(i, _)| i)
            .collect();
        assert_eq!(arcs.len(), 2);
        for i in arcs {
            let arc = pieces[i];
            let (_, t_in, k) = arc.eval(0.0);
            let (_, t_out, _) = arc.eval(arc.length());
            let (_, t_prev, _) = pieces[i - 1].eval(pieces[i - 1].length());
            let (_, t_next, _) = pieces[i + 1].eval(0.0);
            assert!(t_in.distance(t_prev) < 1e-12, "not tangent to the flank");
            assert!(t_out.distance(t_next) < 1e-12, "not tangent to the root");
            assert_close(k, -1.0 / r, 1e-12);
        }
        // The fillets round the corners off, the root flat stays at d3/2.
        assert_close(min_rho(&pieces), 0.5 * (d - 2.0 * (0.5 * p + 0.5)), 1e-9);
    }

    #[test]
    fn iso_full_radius_root_is_one_arc_tangent_to_both_flanks() {
        let (d, p) = (40.0, 7.0);
        let b = 15f64.to_radians();
        // Largest radius: tangent to both flanks and to the root line, i.e. the circle
        // inscribed in the root corner pair; the root flat is 2·w_r wide and each tangent point
        // lies r·tan(45° − β/2) from its corner.
        let root_flat = 0.5 * p * (1.0 - b.tan()) - 2.0 * 0.5 * b.tan();
        let r_max = 0.5 * root_flat / (FRAC_PI_4 - 0.5 * b).tan();
        let tr = IsoTrapezoidal::new(d, Some(r_max), None).unwrap();
        let pieces = tr.pieces(p).unwrap();
        assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
        assert_eq!(pieces.len(), 5);
        let arc = pieces[2];
        let (_, t0, _) = arc.eval(0.0);
        let (_, t1, _) = arc.eval(arc.length());
        assert!(t0.distance(pieces[1].eval(0.0).1) < 1e-12);
        assert!(t1.distance(pieces[3].eval(0.0).1) < 1e-12);
        assert_close(min_rho(&pieces), 0.5 * d - (0.5 * p + 0.5), 1e-9);

        let too_big = IsoTrapezoidal::new(d, Some(r_max * 1.001), None).unwrap();
        match too_big.pieces(p) {
            Err(StandardError::RootRadiusTooLarge { max, .. }) => assert_close(max, r_max, 1e-12),
            other => panic!("expected RootRadiusTooLarge, got {other:?}"),
        }
    }

    #[test]
    fn iso_sharp_root_has_only_lines() {
        let tr = IsoTrapezoidal::new(20.0, None, None).unwrap();
        let pieces = tr.pieces(4.0).unwrap();
        assert_eq!(pieces.len(), 5);
        assert!(pieces.iter().all(|p| matches!(p, AxialPiece::Line { .. })));
        assert!(chain_violation(&pieces, 4.0, 10.0).is_none());
    }

    #[test]
    fn iso_rejects_bad_dimensions() {
        for d in [0.0, -10.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                IsoTrapezoidal::new(d, None, None),
                Err(StandardError::NotPositive {
                    name: "major diameter d",
                    ..
                })
            ));
        }
        for r in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                IsoTrapezoidal::new(20.0, Some(r), None),
                Err(StandardError::Negative {
                    name: "root radius",
                    ..
                })
            ));
        }
        for a in [-0.1, f64::NAN] {
            assert!(matches!(
                IsoTrapezoidal::new(20.0, None, Some(a)),
                Err(StandardError::Negative {
                    name: "crest clearance a_c",
                    ..
                })
            ));
        }
        let tr = IsoTrapezoidal::new(20.0, None, None).unwrap();
        for p in [0.0, -2.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                tr.pieces(p),
                Err(StandardError::NotPositive { name: "pitch", .. })
            ));
        }
        for p in [0.0, f64::NAN] {
            assert!(matches!(
                iso2904_crest_clearance(p),
                Err(StandardError::NotPositive { name: "pitch", .. })
            ));
        }
    }

    #[test]
    fn iso_minor_diameter_must_stay_positive() {
        // Tr 2×2: h3 = 1.25, d3 = −0.5.
        let tr = IsoTrapezoidal::new(2.0, None, None).unwrap();
        match tr.pieces(2.0) {
            Err(StandardError::MinorDiameterNotPositive { minor, .. }) => {
                assert_close(minor, -0.5, 1e-12)
            }
            other => panic!("expected MinorDiameterNotPositive, got {other:?}"),
        }
    }

    #[test]
    fn iso_flanks_cross_when_the_clearance_is_too_deep() {
        // Flanks meet where the groove half-width P/4 − (depth − P/4)·tan15° reaches zero.
        let tr = IsoTrapezoidal::new(40.0, None, Some(2.0)).unwrap();
        assert!(matches!(
            tr.pieces(2.0),
            Err(StandardError::FlanksCross { .. })
        ));
    }

    // ---------- Acme ----------

    #[test]
    fn acme_minor_diameters_match_published_2g_limits() {
        // Maximum minor diameter of 2G screws (= basic form) from published ASME B1.5
        // tables, inch: 3/8-12 → 0.2817, 1/2-10 → 0.3800, 5/8-8 → 0.4800, 1-5 → 0.7800,
        // 1-10 → 0.8800.
        for (d_in, tpi, minor_in) in [
            (0.375, 12.0, 0.2817),
            (0.5, 10.0, 0.38),
            (0.625, 8.0, 0.48),
            (1.0, 5.0, 0.78),
            (1.0, 10.0, 0.88),
        ] {
            let p = MM_PER_INCH / tpi;
            let acme = AcmeGeneralPurpose::new(d_in * MM_PER_INCH, None).unwrap();
            let got = 2.0 * min_rho(&acme.pieces(p).unwrap()) / MM_PER_INCH;
            assert_close(got, minor_in, 5.1e-5);
            assert_close(
                acme.minor_diameter(p).unwrap() / MM_PER_INCH,
                minor_in,
                5.1e-5,
            );
        }
    }

    #[test]
    fn acme_depths_and_flats_match_the_basic_dimension_table() {
        // ASME B1.5 "Acme thread form, basic dimensions" (inch): pitch, total depth of thread
        // (all screws), flat at crest of screw (0.3707 P), flat at root of screw.
        for (p_in, depth_in, crest_in, root_in) in [
            (0.0625, 0.0362, 0.0232, 0.0206),
            (0.1, 0.0600, 0.0371, 0.0319),
            (0.25, 0.1350, 0.0927, 0.0875),
        ] {
            let d = 2.0 * MM_PER_INCH;
            let p = p_in * MM_PER_INCH;
            let acme = AcmeGeneralPurpose::new(d, None).unwrap();
            let pieces = acme.pieces(p).unwrap();
            let depth = 0.5 * d - min_rho(&pieces);
            assert_close(depth / MM_PER_INCH, depth_in, 5.1e-5);
            let crest = flat_at(&pieces, 0.5 * d);
            let root = flat_at(&pieces, 0.5 * d - depth);
            assert_close(crest / MM_PER_INCH, crest_in, 5.1e-5);
            assert_close(root / MM_PER_INCH, root_in, 5.1e-5);
        }
    }

    #[test]
    fn acme_flanks_make_14_5_degrees_and_width_is_half_pitch() {
        let (d, p) = (25.4, 5.08);
        let acme = AcmeGeneralPurpose::new(d, Some(0.2)).unwrap();
        let pieces = acme.pieces(p).unwrap();
        assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
        let f = flanks(&pieces);
        assert_eq!(f.len(), 2);
        for (a, b) in f {
            assert_close(angle_to_radial_deg(a, b), 14.5, 1e-9);
        }
        let z = crossings(&pieces, 0.5 * (d - 0.5 * p));
        assert_eq!(z.len(), 2);
        assert_close(z[1] - z[0], 0.5 * p, 1e-9);
    }

    #[test]
    fn acme_allowance_switches_at_ten_threads_per_inch() {
        let coarse = asme_b1_5_minor_diameter_allowance(MM_PER_INCH / 10.0).unwrap();
        let fine = asme_b1_5_minor_diameter_allowance(MM_PER_INCH / 12.0).unwrap();
        assert_close(coarse, 0.508, 1e-12);
        assert_close(fine, 0.254, 1e-12);
    }

    #[test]
    fn acme_rejects_bad_dimensions() {
        for d in [0.0, -1.0, f64::NAN] {
            assert!(matches!(
                AcmeGeneralPurpose::new(d, None),
                Err(StandardError::NotPositive {
                    name: "major diameter d",
                    ..
                })
            ));
        }
        assert!(matches!(
            AcmeGeneralPurpose::new(25.0, Some(-0.01)),
            Err(StandardError::Negative {
                name: "root radius",
                ..
            })
        ));
        let acme = AcmeGeneralPurpose::new(25.0, None).unwrap();
        assert!(matches!(
            acme.pieces(-1.0),
            Err(StandardError::NotPositive { name: "pitch", .. })
        ));
        // Depth 0.5·P + 0.127 on a 1 mm shaft with P = 2 mm: no core left.
        assert!(matches!(
            AcmeGeneralPurpose::new(1.0, None).unwrap().pieces(2.0),
            Err(StandardError::MinorDiameterNotPositive { .. })
        ));
        // P = 0.1 mm: the 0.254 mm allowance alone makes the flanks cross.
        assert!(matches!(
            acme.pieces(0.1),
            Err(StandardError::FlanksCross { .. })
        ));
        assert!(matches!(
            AcmeGeneralPurpose::new(25.0, Some(2.0))
                .unwrap()
                .pieces(5.08),
            Err(StandardError::RootRadiusTooLarge { .. })
        ));
    }

    // ---------- Ball-arc ----------

    fn ball_4010() -> BallArc {
        // 40 mm screw, 10 mm lead, 6.35 mm balls, conformity 0.53.
        BallArc::new(6.35, 0.53 * 6.35, 40.5, 39.5).unwrap()
    }

    #[test]
    fn ball_arc_depth_and_crest() {
        let g = ball_4010();
        let p = 10.0;
        let pieces = g.pieces(p).unwrap();
        assert!(chain_violation(&pieces, p, 0.5 * 39.5).is_none());
        // Depth below the outer diameter: d/2 − (d_0/2 − D_w/2).
        let depth = 0.5 * 39.5 - min_rho(&pieces);
        assert_close(depth, 0.5 * 39.5 - (0.5 * 40.5 - 0.5 * 6.35), 1e-9);
        assert_close(g.depth(), depth, 1e-9);
        // Crest lines lie on the outer diameter, together P minus the groove width.
        let crest = flat_at(&pieces, 0.5 * 39.5);
        assert_close(crest, p - g.groove_width(), 1e-9);
        assert_close(g.conformity(), 0.53, 1e-12);
    }

    #[test]
    fn ball_arc_holds_the_ball_touching_only_at_the_bottom() {
        let g = ball_4010();
        let pieces = g.pieces(10.0).unwrap();
        let arc = pieces[1];
        let AxialPiece::Arc { radius, .. } = arc else {
            panic!("middle piece must be the groove arc");
        };
        assert_close(radius, 0.53 * 6.35, 0.0);
        let ball_centre = DVec2::new(0.5 * 40.5, 0.0);
        let ball_r = 0.5 * 6.35;
        let mut closest = f64::INFINITY;
        for k in 0..=200 {
            let (pt, _, curvature) = arc.eval(arc.length() * k as f64 / 200.0);
            // On the groove circle of radius r_g about the arc centre.
            assert_close(pt.distance(g.arc_centre()), radius, 1e-9);
            assert_close(curvature, -1.0 / radius, 1e-12);
            // Never inside the ball.
            let gap = pt.distance(ball_centre) - ball_r;
            assert!(gap > -1e-9, "groove cuts into the ball: {gap}");
            closest = closest.min(gap);
        }
        // Touches it (at the bottom, k = 100).
        assert_close(closest, 0.0, 1e-9);
        let (bottom, tangent, _) = arc.eval(0.5 * arc.length());
        assert!(bottom.distance(DVec2::new(0.5 * (40.5 - 6.35), 0.0)) < 1e-9);
        assert!(tangent.distance(DVec2::Y) < 1e-9);
        // The arc ends on the outer diameter.
        assert_close(arc.start().x, 0.5 * 39.5, 1e-9);
        assert_close(arc.end().x, 0.5 * 39.5, 1e-9);
    }

    #[test]
    fn ball_arc_rejects_bad_dimensions() {
        let names = [
            "ball diameter D_w",
            "groove radius r_g",
            "ball-centre diameter d_0",
            "outer diameter d",
        ];
        for (i, name) in names.iter().enumerate() {
            for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
                let mut v = [6.35, 3.4, 40.5, 39.5];
                v[i] = bad;
                match BallArc::new(v[0], v[1], v[2], v[3]) {
                    Err(StandardError::NotPositive { name: n, .. }) => assert_eq!(n, *name),
                    other => panic!("{name} = {bad}: {other:?}"),
                }
            }
        }
        assert!(matches!(
            BallArc::new(6.35, 3.175, 40.5, 39.5),
            Err(StandardError::GrooveRadiusTooSmall { .. })
        ));
        assert!(matches!(
            BallArc::new(6.35, 3.4, 6.35, 5.0),
            Err(StandardError::GrooveBottomNotAboveAxis { .. })
        ));
        // Groove bottom diameter 40.5 − 6.35 = 34.15.
        assert!(matches!(
            BallArc::new(6.35, 3.4, 40.5, 34.15),
            Err(StandardError::OuterDiameterNotAboveGrooveBottom { .. })
        ));
        // Arc centre diameter 34.15 + 2·3.4 = 40.95.
        assert!(matches!(
            BallArc::new(6.35, 3.4, 40.5, 41.0),
            Err(StandardError::GrooveOverhangs { .. })
        ));
        let g = ball_4010();
        assert!(matches!(
            g.pieces(g.groove_width()),
            Err(StandardError::GroovesOverlap { .. })
        ));
        assert!(matches!(
            g.pieces(5.0),
            Err(StandardError::GroovesOverlap { .. })
        ));
        assert!(matches!(
            g.pieces(f64::NAN),
            Err(StandardError::NotPositive { name: "pitch", .. })
        ));
    }

    #[test]
    fn standard_profile_dispatches() {
        let profiles = [
            StandardProfile::IsoTrapezoidal(IsoTrapezoidal::new(40.0, Some(0.2), None).unwrap()),
            StandardProfile::Acme(AcmeGeneralPurpose::new(40.0, Some(0.2)).unwrap()),
            StandardProfile::BallArc(ball_4010()),
        ];
        for prof in profiles {
            let pieces = prof.pieces(10.0).unwrap();
            assert!(chain_violation(&pieces, 10.0, 0.5 * prof.outer_diameter()).is_none());
        }
    }

    #[test]
    fn errors_name_the_dimension() {
        let e = IsoTrapezoidal::new(-1.0, None, None).unwrap_err();
        assert!(e.to_string().contains("major diameter d"));
        let e = ball_4010().pieces(1.0).unwrap_err();
        assert!(e.to_string().contains("grooves overlap"));
    }

    // ---------- properties ----------

    proptest! {
        #[test]
        fn iso_chain_is_continuous_and_closed(
            p in 1.5f64..44.0,
            d_extra in 1.0f64..200.0,
            r_frac in 0.0f64..=1.0,
        ) {
            let a_c = iso2904_crest_clearance(p).unwrap();
            let d = 2.0 * (0.5 * p + a_c) + d_extra;
            let b = 15f64.to_radians();
            let root_half = 0.25 * p * (1.0 - b.tan()) - a_c * b.tan();
            let r_max = root_half / (FRAC_PI_4 - 0.5 * b).tan();
            let tr = IsoTrapezoidal::new(d, Some(r_frac * r_max), None).unwrap();
            let pieces = tr.pieces(p).unwrap();
            prop_assert_eq!(chain_violation(&pieces, p, 0.5 * d), None);
            prop_assert!((min_rho(&pieces) - (0.5 * d - 0.5 * p - a_c)).abs() < 1e-9);
        }

        #[test]
        fn acme_chain_is_continuous_and_closed(
            tpi in 1.0f64..16.0,
            d_extra in 1.0f64..150.0,
            r_frac in 0.0f64..=1.0,
        ) {
            let p = MM_PER_INCH / tpi;
            let allowance = asme_b1_5_minor_diameter_allowance(p).unwrap();
            let d = p + allowance + d_extra;
            let b = 14.5f64.to_radians();
            let root_half = 0.25 * p * (1.0 - b.tan()) - 0.5 * allowance * b.tan();
            let r_max = root_half / (FRAC_PI_4 - 0.5 * b).tan();
            let acme = AcmeGeneralPurpose::new(d, Some(r_frac * r_max)).unwrap();
            let pieces = acme.pieces(p).unwrap();
            prop_assert_eq!(chain_violation(&pieces, p, 0.5 * d), None);
        }

        #[test]
        fn ball_arc_chain_is_continuous_and_closed(
            dw in 1.0f64..20.0,
            conformity in 0.505f64..0.6,
            d0_extra in 1.0f64..100.0,
            od_frac in 0.05f64..0.95,
            crest_frac in 0.01f64..1.0,
        ) {
            let rg = conformity * dw;
            let d0 = dw + d0_extra;
            let bottom = 0.5 * (d0 - dw);
            let centre = bottom + rg;
            let outer = bottom + od_frac * (centre - bottom);
            let g = BallArc::new(dw, rg, d0, 2.0 * outer).unwrap();
            let p = g.groove_width() * (1.0 + crest_frac);
            let pieces = g.pieces(p).unwrap();
            prop_assert_eq!(chain_violation(&pieces, p, outer), None);
            prop_assert!((min_rho(&pieces) - bottom).abs() < 1e-9);
        }
    }
}
