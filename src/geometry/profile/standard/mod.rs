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
//! - [`StubAcme`]: Stub Acme thread, ASME B1.8, 29° included angle, basic height 0.3·P.
//! - [`IsoMetric`]: ISO general purpose metric thread, ISO 68-1 / ISO 965-1, 60°, the
//!   external thread's root rounded to ISO 965-1's `d3`.
//! - [`Unified`]: ASME B1.1 unified inch thread (UNC, UNF, UNEF, UN, UNS), the metric form
//!   on inch sizes.
//! - [`Buttress`]: DIN 513-1 buttress thread, 3° load flank and 30° clearance flank.
//! - [`BallArc`]: single circular-arc ("ball-arc") ball-screw groove with zero contact angle.
//!
//! [`StandardProfile`] wraps them so a job can carry any of them; [`designation`] reads them
//! from a drawing's designation (`Tr 40x7`, `1/2-10 ACME-2G`) with the standards' tables.
//! [`StandardProfile::internal_pieces`] gives the nut's (internal thread's) section of the
//! thread forms.
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
use std::f64::consts::PI;

mod acme_series;
mod arc_fit;
mod ball_arc;
pub mod ball_screw;
mod buttress;
pub mod designation;
mod iso2902;
mod metric;
mod reading;
mod trapezoid;
mod unified;
pub mod worm;

pub use ball_arc::BallArc;
pub use ball_screw::{BallScrew, Raceway};
pub use buttress::{Buttress, LoadFlank};
pub use metric::IsoMetric;
pub use trapezoid::{
    asme_b1_5_minor_diameter_allowance, iso2904_crest_clearance, AcmeGeneralPurpose,
    IsoTrapezoidal, StubAcme, MM_PER_INCH,
};
pub use unified::Unified;
pub use worm::{Worm, WormFlank};

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
    /// The form has no internal (nut) section here.
    #[error("{form} has no internal (nut) form in whirl")]
    NoInternalForm {
        /// The form.
        form: &'static str,
    },
    /// A dimension given for a ball-screw raceway that does not have it (the circular arc
    /// has no contact angle other than 0 and no relief).
    #[error("{name} = {value} belongs to the gothic arch, not to the circular-arc raceway")]
    NotForRaceway {
        /// Which dimension.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The gothic arch's contact angle is not between 0° and 90°.
    #[error(
        "contact angle {degrees}° must lie above 0° and below 90° (the catalogues' gothic arch \
         has 45°)"
    )]
    ContactAngleOutOfRange {
        /// The angle given (degrees).
        degrees: f64,
    },
    /// The ball would touch the gothic arch at or above the shaft's outer diameter.
    #[error(
        "the ball touches the flank on diameter {contact} mm, not below the outer diameter \
         {outer} mm: the contact point would not be on the shaft"
    )]
    ContactAboveOuterDiameter {
        /// Diameter of the contact point (mm).
        contact: f64,
        /// Outer diameter d (mm).
        outer: f64,
    },
    /// The gothic arch's relief reaches the ball's contact points.
    #[error(
        "relief radius {relief} mm reaches the contact points: it must be below the ball's \
         radius {max} mm"
    )]
    ReliefReachesContact {
        /// The relief radius given (mm).
        relief: f64,
        /// The largest below which it must stay (mm).
        max: f64,
    },
    /// A worm's pressure angle is outside the range the flank forms are built for.
    #[error("pressure angle {degrees}° must lie above 0° and below 45° (DIN 3975-1: 20°)")]
    PressureAngleOutOfRange {
        /// The angle given (degrees).
        degrees: f64,
    },
    /// A ZI worm's root lies inside its base cylinder, where no involute is.
    #[error(
        "root diameter {root} mm lies inside the involute's base cylinder, {base} mm: a ZI \
         flank does not reach the root (choose a smaller pressure angle or a larger q)"
    )]
    RootInsideBaseCylinder {
        /// Root diameter d_f1 (mm).
        root: f64,
        /// Base diameter d_b (mm).
        base: f64,
    },
    /// A ZK worm's wheel leaves no flank at some radius between the root and the tip (its
    /// envelope folds or leaves the cone there).
    #[error(
        "a double-cone wheel of diameter {wheel} mm generates no ZK flank at radius {radius} \
         mm: choose another wheel diameter, or a smaller lead angle"
    )]
    NoWheelEnvelope {
        /// The wheel's diameter d0 (mm).
        wheel: f64,
        /// The radius on the worm where the flank fails (mm).
        radius: f64,
    },
    /// A worm's groove is given a pitch other than its axial pitch π·m.
    #[error(
        "axial pitch {pitch} mm is not the module's: a worm of module {module} mm has axial \
         pitch π·m = {axial_pitch} mm (lead = π·m·starts)"
    )]
    PitchNotModule {
        /// The axial pitch given (lead / starts, mm).
        pitch: f64,
        /// Module m (mm).
        module: f64,
        /// π·m (mm).
        axial_pitch: f64,
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
    /// Stub Acme.
    StubAcme(StubAcme),
    /// ISO metric (M).
    IsoMetric(IsoMetric),
    /// Unified inch (UNC, UNF, UNEF, UN, UNS).
    Unified(Unified),
    /// Buttress (S), DIN 513.
    Buttress(Buttress),
    /// Circular-arc ball-screw groove.
    BallArc(BallArc),
    /// Ball screw raceway: gothic arch or circular arc.
    BallScrew(BallScrew),
    /// Cylindrical worm: ZA, ZN, ZI or ZK.
    Worm(Worm),
}

/// One dimension of a standard form as `whirl profile` and the console's job page list it:
/// what the shop checks the drawing against.
#[derive(Debug, Clone, PartialEq)]
pub struct Dimension {
    /// What it is, in the standard's words and symbol ("thread height h3").
    pub name: &'static str,
    /// Its value in `unit`.
    pub value: f64,
    /// `"mm"`, `"°"`, or empty for a ratio or a count.
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
            StandardProfile::StubAcme(_) => "ASME/ANSI B1.8-1988 (R2021) Stub Acme",
            StandardProfile::IsoMetric(_) => "ISO 68-1:1998 basic profile, ISO 965-1:2013 root",
            StandardProfile::Unified(_) => {
                "ASME B1.1-2019 unified inch thread (ISO 68-1's basic profile), UNR root"
            }
            StandardProfile::Buttress(_) => "DIN 513-1:1985 buttress thread profile",
            StandardProfile::BallArc(_) => "circular-arc ball-screw raceway (catalogue data)",
            StandardProfile::BallScrew(b) => match b.raceway() {
                Raceway::GothicArch => {
                    "ball screw, gothic-arch raceway (ISO 3408-1; THK, HIWIN, NSK catalogues)"
                }
                Raceway::CircularArc => {
                    "ball screw, circular-arc raceway (ISO 3408-1; THK, HIWIN, NSK catalogues)"
                }
            },
            StandardProfile::Worm(_) => "cylindrical worm, DIN 3975-1:2017 / ISO 10828:2015",
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
                Dimension::mm(
                    "crest width",
                    crest_width(pitch, 0.5 * pitch, IsoTrapezoidal::FLANK_HALF_ANGLE_DEG),
                ),
                Dimension::mm(
                    "root width",
                    root_width(
                        pitch,
                        0.5 * pitch,
                        t.thread_height(pitch)?,
                        IsoTrapezoidal::FLANK_HALF_ANGLE_DEG,
                    ),
                ),
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
                Dimension::mm(
                    "crest width",
                    crest_width(pitch, 0.5 * pitch, AcmeGeneralPurpose::FLANK_HALF_ANGLE_DEG),
                ),
                Dimension::mm(
                    "root width",
                    root_width(
                        pitch,
                        0.5 * pitch,
                        a.thread_height(pitch)?,
                        AcmeGeneralPurpose::FLANK_HALF_ANGLE_DEG,
                    ),
                ),
                Dimension::mm("root radius", a.root_radius()),
            ],
            StandardProfile::StubAcme(a) => vec![
                Dimension::mm("major diameter", a.major_diameter()),
                Dimension::mm("pitch diameter", a.major_diameter() - a.basic_height(pitch)),
                Dimension::mm("minor diameter", a.minor_diameter(pitch)?),
                Dimension::mm("basic thread height h", a.basic_height(pitch)),
                Dimension::mm("thread height", a.thread_height(pitch)?),
                Dimension::deg("flank angle", 2.0 * StubAcme::FLANK_HALF_ANGLE_DEG),
                Dimension::mm(
                    "crest width",
                    crest_width(pitch, a.basic_height(pitch), StubAcme::FLANK_HALF_ANGLE_DEG),
                ),
                Dimension::mm(
                    "root width",
                    root_width(
                        pitch,
                        a.basic_height(pitch),
                        a.thread_height(pitch)?,
                        StubAcme::FLANK_HALF_ANGLE_DEG,
                    ),
                ),
                Dimension::mm("root radius", a.root_radius()),
            ],
            StandardProfile::IsoMetric(m) | StandardProfile::Unified(Unified { metric: m, .. }) => {
                vec![
                    Dimension::mm("major diameter d", m.major_diameter()),
                    Dimension::mm("pitch diameter d2", m.pitch_diameter(pitch)),
                    Dimension::mm(
                        "minor diameter d3",
                        m.major_diameter() - 2.0 * m.thread_height(pitch),
                    ),
                    Dimension::mm(
                        "fundamental triangle height H",
                        IsoMetric::fundamental_height(pitch),
                    ),
                    Dimension::mm("thread height h3", m.thread_height(pitch)),
                    Dimension::deg("flank angle", 2.0 * IsoMetric::FLANK_HALF_ANGLE_DEG),
                    Dimension::mm(
                        "crest width",
                        crest_width(pitch, 0.75 * IsoMetric::fundamental_height(pitch), 30.0),
                    ),
                    Dimension::mm("root radius R", IsoMetric::root_radius(pitch)),
                ]
            }
            StandardProfile::Buttress(b) => {
                let d = b.major_diameter();
                vec![
                    Dimension::mm("major diameter d", d),
                    Dimension::mm("pitch diameter d2", d - Buttress::OVERLAP * pitch),
                    Dimension::mm(
                        "minor diameter d3",
                        d - 2.0 * Buttress::THREAD_HEIGHT * pitch,
                    ),
                    Dimension::mm("thread overlap H1", Buttress::OVERLAP * pitch),
                    Dimension::mm("thread height h3", Buttress::THREAD_HEIGHT * pitch),
                    Dimension::mm("crest clearance a_c", Buttress::CREST_CLEARANCE * pitch),
                    Dimension::deg("load flank", Buttress::LOAD_FLANK_DEG),
                    Dimension::deg("clearance flank", Buttress::CLEARANCE_FLANK_DEG),
                    Dimension::mm("crest width e", Buttress::CREST_FLAT * pitch),
                    Dimension::mm("root radius R", Buttress::ROOT_RADIUS * pitch),
                ]
            }
            StandardProfile::BallArc(b) => vec![
                Dimension::mm("outer diameter", b.outer_diameter()),
                Dimension::mm("ball diameter D_w", b.ball_diameter()),
                Dimension::mm("ball-centre diameter d_0", b.pitch_circle_diameter()),
                Dimension::mm("groove radius r_g", b.groove_radius()),
                Dimension::mm("groove depth", b.depth()),
                Dimension::mm("groove width", b.groove_width()),
            ],
            StandardProfile::BallScrew(b) => {
                let mut rows = vec![
                    Dimension::mm("outer diameter d", b.outer_diameter()),
                    Dimension::mm("ball diameter D_w", b.ball_diameter()),
                    Dimension::mm("ball-centre diameter d_0", b.pitch_circle_diameter()),
                    Dimension::mm("raceway radius r_g", b.groove_radius()),
                    Dimension {
                        name: "conformity r_g/D_w",
                        value: b.conformity(),
                        unit: "",
                    },
                    Dimension::deg("contact angle", b.contact_angle().to_degrees()),
                    Dimension::mm("groove depth", b.depth()),
                    Dimension::mm("groove width", b.groove_width()),
                ];
                if let Some(r) = b.relief_radius() {
                    rows.push(Dimension::mm("relief radius r_r", r));
                }
                rows
            }
            StandardProfile::Worm(w) => {
                let mut rows = vec![
                    Dimension::mm("axial module m", w.module()),
                    Dimension {
                        name: "starts z1",
                        value: f64::from(w.starts()),
                        unit: "",
                    },
                    Dimension::mm("axial pitch p_x", w.axial_pitch()),
                    Dimension::mm("lead p_z", w.lead()),
                    Dimension::mm("reference diameter d1", w.reference_diameter()),
                    Dimension::mm("tip diameter d_a1", w.tip_diameter()),
                    Dimension::mm("root diameter d_f1", w.root_diameter()),
                    Dimension::deg("lead angle γ", w.lead_angle().to_degrees()),
                    Dimension::deg("pressure angle α", w.pressure_angle().to_degrees()),
                    Dimension::deg(
                        "axial pressure angle α_x",
                        w.axial_pressure_angle().to_degrees(),
                    ),
                    Dimension::mm("axial tooth thickness s_x1", 0.5 * w.axial_pitch()),
                    Dimension::mm("root radius ρ_f", w.root_radius()),
                ];
                if let Some(wheel) = w.wheel() {
                    rows.push(Dimension::mm("wheel diameter d0", wheel.diameter()));
                    rows.push(Dimension::mm("wheel thickness at d0", wheel.thickness()));
                }
                rows
            }
        })
    }

    /// Outer (major) diameter of the shaft (mm): the crest radius is half of it.
    pub fn outer_diameter(&self) -> f64 {
        match self {
            StandardProfile::IsoTrapezoidal(t) => t.major_diameter(),
            StandardProfile::Acme(a) => a.major_diameter(),
            StandardProfile::StubAcme(a) => a.major_diameter(),
            StandardProfile::IsoMetric(m) => m.major_diameter(),
            StandardProfile::Unified(u) => u.metric().major_diameter(),
            StandardProfile::Buttress(b) => b.major_diameter(),
            StandardProfile::BallArc(b) => b.outer_diameter(),
            StandardProfile::BallScrew(b) => b.outer_diameter(),
            StandardProfile::Worm(w) => w.tip_diameter(),
        }
    }

    /// The axial section of one pitch of the wrapped profile.
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        match self {
            StandardProfile::IsoTrapezoidal(t) => t.pieces(pitch),
            StandardProfile::Acme(a) => a.pieces(pitch),
            StandardProfile::StubAcme(a) => a.pieces(pitch),
            StandardProfile::IsoMetric(m) => m.pieces(pitch),
            StandardProfile::Unified(u) => u.metric().pieces(pitch),
            StandardProfile::Buttress(b) => b.pieces(pitch),
            StandardProfile::BallArc(b) => b.pieces(pitch),
            StandardProfile::BallScrew(b) => b.pieces(pitch),
            StandardProfile::Worm(w) => w.pieces(pitch),
        }
    }

    /// The same form with root fillets of `radius` (mm), for a job that names the form by its
    /// designation and the radius its insert leaves. Only the thread forms have root fillets.
    pub fn with_root_radius(self, radius: f64) -> Result<StandardProfile, StandardError> {
        Ok(match self {
            StandardProfile::IsoTrapezoidal(t) => {
                StandardProfile::IsoTrapezoidal(t.with_root_radius(radius)?)
            }
            StandardProfile::Acme(a) => StandardProfile::Acme(a.with_root_radius(radius)?),
            StandardProfile::StubAcme(a) => StandardProfile::StubAcme(a.with_root_radius(radius)?),
            StandardProfile::Worm(w) => StandardProfile::Worm(Worm::new(
                w.flank(),
                w.module(),
                w.starts(),
                w.quotient(),
                Some(w.pressure_angle().to_degrees()),
                Some(w.bottom_clearance()),
                Some(radius),
            )?),
            StandardProfile::IsoMetric(_)
            | StandardProfile::Unified(_)
            | StandardProfile::Buttress(_)
            | StandardProfile::BallArc(_)
            | StandardProfile::BallScrew(_) => {
                return Err(StandardError::Negative {
                    name: "root radius (this form's root is the standard's own)",
                    value: radius,
                })
            }
        })
    }

    /// Radius of the basic pitch line (mm): where the thread and the groove are both `P/2`
    /// wide. The screw and its nut share it (ISO 2904: `D2 = d2`; ASME B1.5, B1.8: the basic
    /// pitch diameter is common to both).
    fn pitch_line_radius(&self, pitch: f64) -> Result<f64, StandardError> {
        let d = self.outer_diameter();
        match self {
            StandardProfile::IsoTrapezoidal(_) | StandardProfile::Acme(_) => {
                Ok(0.5 * (d - 0.5 * pitch))
            }
            StandardProfile::StubAcme(a) => Ok(0.5 * (d - a.basic_height(pitch))),
            StandardProfile::IsoMetric(m) | StandardProfile::Unified(Unified { metric: m, .. }) => {
                Ok(0.5 * m.pitch_diameter(pitch))
            }
            StandardProfile::Buttress(_) => Err(StandardError::NoInternalForm {
                form: "DIN 513's buttress nut",
            }),
            StandardProfile::BallArc(_) | StandardProfile::BallScrew(_) => {
                Err(StandardError::NoInternalForm {
                    form: "a ball-screw raceway",
                })
            }
            StandardProfile::Worm(_) => Err(StandardError::NoInternalForm {
                form: "a worm (its mate is a worm wheel)",
            }),
        }
    }

    /// The axial section of one pitch of the **internal** thread (the nut) that mates with
    /// this screw, on the standard's design profile.
    ///
    /// Convention for an internal section: one period z ∈ [−P/2, P/2], the groove centred at
    /// z = 0 running *outward* from the bore, ρ increasing into the groove; the bore (the nut's
    /// crest, minor diameter D1) at both ends at ρ = D1/2. The three thread standards give the
    /// nut the screw's clearances mirrored about the common pitch line (ISO 2904:
    /// `D1 = d − P`, `D4 = d + 2·a_c`, `H4 = h3`, `D2 = d2`; ASME B1.5 and B1.8: nut minor
    /// diameter `d − 2h`, major diameter `d + allowance`), so the nut's section is the
    /// screw's reflected in ρ about the pitch line, root fillets included (ISO 2901's `R2`
    /// applies to the root corners of both).
    /// The metric thread is the exception: ISO 68-1's nut is the basic profile, its root at
    /// `D = d`, not the screw's rounded root mirrored ([`IsoMetric::internal_pieces`]).
    pub fn internal_pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        if let StandardProfile::IsoMetric(m) | StandardProfile::Unified(Unified { metric: m, .. }) =
            self
        {
            return m.internal_pieces(pitch);
        }
        let about = self.pitch_line_radius(pitch)?;
        Ok(self
            .pieces(pitch)?
            .into_iter()
            .map(|piece| mirror_rho(piece, about))
            .collect())
    }

    /// The nut's dimensions at this axial pitch (mm), as the standard names them (ISO 2904's
    /// `D1`, `D2`, `D4`, `H4`).
    pub fn internal_dimensions(&self, pitch: f64) -> Result<Vec<Dimension>, StandardError> {
        let about = self.pitch_line_radius(pitch)?;
        let d = self.outer_diameter();
        let (depth, names) = match self {
            StandardProfile::IsoTrapezoidal(t) => (
                t.thread_height(pitch)?,
                [
                    "major diameter D4",
                    "pitch diameter D2",
                    "minor diameter D1",
                    "thread height H4",
                ],
            ),
            StandardProfile::Acme(a) => (
                a.thread_height(pitch)?,
                [
                    "major diameter",
                    "pitch diameter",
                    "minor diameter",
                    "thread height",
                ],
            ),
            StandardProfile::StubAcme(a) => (
                a.thread_height(pitch)?,
                [
                    "major diameter",
                    "pitch diameter",
                    "minor diameter",
                    "thread height",
                ],
            ),
            StandardProfile::IsoMetric(m) | StandardProfile::Unified(Unified { metric: m, .. }) => {
                let h1 = 0.625 * IsoMetric::fundamental_height(pitch);
                return Ok(vec![
                    Dimension::mm("major diameter D", d),
                    Dimension::mm("pitch diameter D2", m.pitch_diameter(pitch)),
                    Dimension::mm("minor diameter D1", d - 2.0 * h1),
                    Dimension::mm("thread height H1", h1),
                ]);
            }
            StandardProfile::Buttress(_)
            | StandardProfile::BallArc(_)
            | StandardProfile::BallScrew(_)
            | StandardProfile::Worm(_) => unreachable!("pitch_line_radius refused it"),
        };
        let minor = 2.0 * (2.0 * about - 0.5 * d);
        Ok(vec![
            Dimension::mm(names[0], minor + 2.0 * depth),
            Dimension::mm(names[1], 2.0 * about),
            Dimension::mm(names[2], minor),
            Dimension::mm(names[3], depth),
        ])
    }
}

/// Crest flat width (mm) of a symmetric trapezoidal thread of basic height `h` whose flanks
/// make `half_angle_deg` with the radial: the thread is `P/2` thick `h/2` below the crest, so
/// `P/2 − h·tan(half angle)` at the crest (ISO 2904's 0.366·P, B1.5's 0.3707·P, B1.8's
/// 0.4224·P).
fn crest_width(pitch: f64, h: f64, half_angle_deg: f64) -> f64 {
    0.5 * pitch - h * half_angle_deg.to_radians().tan()
}

/// Root flat width (mm) of the same thread cut `depth` deep: the groove is `P/2` wide at the
/// pitch line and narrows by `2·tan(half angle)` per mm of depth below it.
fn root_width(pitch: f64, h: f64, depth: f64, half_angle_deg: f64) -> f64 {
    0.5 * pitch - (2.0 * depth - h) * half_angle_deg.to_radians().tan()
}

/// A piece reflected in z about z = 0 and traversed the other way, so that a section
/// reflected piece by piece, in reverse order, still runs towards +z: a point's angle θ
/// about an arc's centre becomes −θ.
pub(super) fn mirror_z(piece: AxialPiece) -> AxialPiece {
    let flip = |p: DVec2| DVec2::new(p.x, -p.y);
    match piece {
        AxialPiece::Line { from, to } => AxialPiece::Line {
            from: flip(to),
            to: flip(from),
        },
        AxialPiece::Arc {
            centre,
            radius,
            start,
            end,
        } => AxialPiece::Arc {
            centre: flip(centre),
            radius,
            start: -end,
            end: -start,
        },
    }
}

/// A piece reflected in ρ about the cylinder ρ = `about`, keeping its direction of travel in
/// z: a point's angle θ about an arc's centre becomes π − θ.
fn mirror_rho(piece: AxialPiece, about: f64) -> AxialPiece {
    let flip = |p: DVec2| DVec2::new(2.0 * about - p.x, p.y);
    match piece {
        AxialPiece::Line { from, to } => AxialPiece::Line {
            from: flip(from),
            to: flip(to),
        },
        AxialPiece::Arc {
            centre,
            radius,
            start,
            end,
        } => AxialPiece::Arc {
            centre: flip(centre),
            radius,
            start: PI - start,
            end: PI - end,
        },
    }
}

#[cfg(test)]
mod tests;
