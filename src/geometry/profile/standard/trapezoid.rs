//! The symmetric trapezoidal family: the ISO metric trapezoidal thread (ISO 2901 / ISO 2904),
//! the general purpose Acme thread (ASME B1.5) and the Stub Acme thread (ASME B1.8), all built
//! on one trapezoidal groove with optional root fillets. Conventions as in the parent module.

use super::{non_negative, positive, AxialPiece, StandardError};
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

/// The symmetric trapezoidal groove shared by the ISO trapezoidal and Acme forms.
///
/// The three standards fix the flanks by the same two facts: the thread is `P/2` thick at the
/// pitch line, which lies half the basic height `h` below the crest (ISO and Acme: `h = P/2`,
/// pitch diameter `d − P/2`; Stub Acme: `h = 0.3·P`, pitch diameter `d − 0.3·P`), and each
/// flank makes the half-angle `beta` with the radial direction. The groove half-width at
/// radius `rho` is therefore `P/4 + (rho − (R − h/2))·tan(beta)`, R = d/2, and every flat
/// (crest, root) follows from it. The extra depth below the basic root (ISO's `a_c`, Acme's
/// minor-diameter allowance) extends the flanks, narrowing the root flat by `2·extra·tan(beta)`.
///
/// The root corners are either sharp (`root_radius == 0`) or rounded by fillets tangent to
/// the flank and the root flat; the crest corners are sharp.
pub(super) fn trapezoid_pieces(
    pitch: f64,
    crest_rho: f64,
    basic_height: f64,
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
    let half_basic = 0.5 * basic_height;
    let crest_half = quarter + half_basic * tan_b;
    let root_half = quarter + (half_basic - depth) * tan_b;
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
    // `depth/cos(beta) > 0.3·P > P/4 > root_half` long for these forms, never limits first.)
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

    /// The same thread with root fillets of `radius` (mm): a designation fixes the form but
    /// not the radius, which ISO 2901 leaves to the maker up to `R2max`.
    pub fn with_root_radius(self, radius: f64) -> Result<Self, StandardError> {
        Self::new(self.major_diameter, Some(radius), self.crest_clearance)
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
            0.5 * pitch,
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

    /// The same thread with root fillets of `radius` (mm): a designation fixes the form but
    /// not the radius.
    pub fn with_root_radius(self, radius: f64) -> Result<Self, StandardError> {
        Self::new(self.major_diameter, Some(radius))
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
            0.5 * pitch,
            depth,
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            self.root_radius,
        )
    }
}

/// Stub Acme thread (ASME/ANSI B1.8-1988, reaffirmed 2021), external thread, all dimensions in
/// mm: the Acme thread's 29° flanks on a shallow basic height for coarse pitches where the
/// wall is thin.
///
/// Geometry (B1.8 basic dimensions): flank half-angle 14.5°, basic height `h = 0.3·P`, basic
/// thickness `P/2` at the pitch diameter `d − 0.3·P`, basic minor diameter `d − 0.6·P`, basic
/// flat at crest and root `P/2 − 2·0.15·P·tan 14.5° = 0.4224·P` (the standard's column
/// "basic width of flat, 0.4224P"). B1.8 establishes one class, 2G, whose fit "corresponds to
/// the Class 2G General Purpose Acme thread": the screw's minor diameter takes the same
/// minor-diameter allowance as B1.5 ([`asme_b1_5_minor_diameter_allowance`]), so the total
/// depth is `0.3·P + allowance/2` and the root flat `0.4224·P − allowance·tan 14.5°`. Root
/// fillets and crest corners as [`AcmeGeneralPurpose`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StubAcme {
    major_diameter: f64,
    root_radius: f64,
}

impl StubAcme {
    /// Flank half-angle: 14.5°, i.e. 29° included (as Acme).
    pub const FLANK_HALF_ANGLE_DEG: f64 = 14.5;
    /// Basic thread height as a share of the pitch: `h = 0.3·P`.
    pub const BASIC_HEIGHT_PER_PITCH: f64 = 0.3;

    /// A Stub Acme screw of major diameter `d` (mm) with an optional root fillet radius (mm,
    /// default 0: sharp root corners).
    pub fn new(major_diameter: f64, root_radius: Option<f64>) -> Result<Self, StandardError> {
        let major_diameter = positive("major diameter d", major_diameter)?;
        let root_radius = non_negative("root radius", root_radius.unwrap_or(0.0))?;
        Ok(Self {
            major_diameter,
            root_radius,
        })
    }

    /// The same thread with root fillets of `radius` (mm).
    pub fn with_root_radius(self, radius: f64) -> Result<Self, StandardError> {
        Self::new(self.major_diameter, Some(radius))
    }

    /// Major diameter d (mm).
    pub fn major_diameter(&self) -> f64 {
        self.major_diameter
    }

    /// Root fillet radius (mm); 0 means sharp root corners.
    pub fn root_radius(&self) -> f64 {
        self.root_radius
    }

    /// Basic thread height `h = 0.3·P` (mm).
    pub fn basic_height(&self, pitch: f64) -> f64 {
        Self::BASIC_HEIGHT_PER_PITCH * pitch
    }

    /// Total thread depth of the screw, `0.3·P + allowance/2` (mm).
    pub fn thread_height(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(self.basic_height(pitch) + 0.5 * asme_b1_5_minor_diameter_allowance(pitch)?)
    }

    /// Minor diameter of the screw, `d − 0.6·P − allowance` (mm).
    pub fn minor_diameter(&self, pitch: f64) -> Result<f64, StandardError> {
        Ok(self.major_diameter - 2.0 * self.thread_height(pitch)?)
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let depth = self.thread_height(pitch)?;
        trapezoid_pieces(
            pitch,
            0.5 * self.major_diameter,
            self.basic_height(pitch),
            depth,
            Self::FLANK_HALF_ANGLE_DEG.to_radians(),
            self.root_radius,
        )
    }
}
