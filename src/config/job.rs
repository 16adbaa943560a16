//! The job file: the groove, the tool and the cut, as a process engineer writes them.
//!
//! TOML, read with serde; unknown keys are errors (a misspelt key must not be silently
//! ignored on a machine). Lengths in mm, angles in degrees, speeds in rpm. See
//! `examples/*/job.toml` for complete jobs.

use crate::geometry::linkage::{Ring, Whirling};
use crate::geometry::profile::drawing::{self, DrawingError};
use crate::geometry::profile::points::{self, PointsError, Section};
use crate::geometry::profile::standard::designation::{self, Designation, DesignationError};
use crate::geometry::profile::standard::{
    AcmeGeneralPurpose, BallArc, BallScrew, IsoTrapezoidal, LoadFlank, Raceway, StandardError,
    StandardProfile, Worm, WormFlank,
};
use crate::geometry::profile::{Material, Profile};
use serde::Deserialize;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

#[cfg(test)]
mod forms_tests;
#[cfg(test)]
mod tests;

/// A job, read and checked: the job file's values, and the groove's profile built from its
/// points (read relative to the job file) or its standard. Everything the planner needs,
/// as values: planning reads no file.
#[derive(Debug, Clone)]
pub struct Job {
    /// The helical groove.
    pub groove: Groove,
    /// The whirling tool.
    pub tool: Tool,
    /// Cutting parameters.
    pub cut: Cut,
    /// The groove's transverse profile, validated.
    pub profile: Profile,
    /// The standard form the profile was built from, where the job names one: its
    /// dimensions and source are what `whirl profile` shows.
    pub form: Option<StandardProfile>,
}

/// The job file as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct JobText {
    groove: GrooveFile,
    tool: Tool,
    cut: CutFile,
}

/// The job file with its groove's lead, starts and hand settled (given, or fixed by the
/// profile's designation).
#[derive(Debug, Clone)]
struct JobFile {
    groove: Groove,
    tool: Tool,
    cut: CutFile,
    /// The profile's designation, read.
    designation: Option<Designation>,
}

/// `[groove]` as written: lead, starts and hand may be left to a `[groove.profile]
/// designation` that fixes them (`Tr 40x14 P7 LH`: lead 14 mm, 2 starts, left hand).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct GrooveFile {
    lead: Option<f64>,
    starts: Option<u32>,
    hand: Option<Hand>,
    z_start: f64,
    length: f64,
    internal: Option<bool>,
    profile: ProfileSpec,
}

/// Right- or left-hand helix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Hand {
    /// p > 0.
    Right,
    /// p < 0.
    Left,
}

/// `[groove]`.
#[derive(Debug, Clone)]
pub struct Groove {
    /// Lead, mm (axial advance of one groove per turn).
    pub lead: f64,
    /// Number of starts (grooves side by side).
    pub starts: u32,
    /// Helix hand.
    pub hand: Hand,
    /// The groove is fully formed from `z_start` …
    pub z_start: f64,
    /// … to `z_start + length`, mm.
    pub length: f64,
    /// An internal groove (a nut's thread, the material outside): `true`; absent or `false`,
    /// an external one (a screw). A nut is cut by a bore head (`tool.whirling = "bore"`).
    pub internal: Option<bool>,
    /// Its cross-section.
    pub profile: ProfileSpec,
}

/// Which section sampled points describe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SectionSpec {
    /// `x, y` in the plane z = 0.
    Transverse,
    /// `rho, z` in the axial half-plane.
    Axial,
}

/// The standard families a job can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StandardKind {
    /// ISO 2904 metric trapezoidal.
    Trapezoidal,
    /// ASME B1.5 general-purpose Acme.
    Acme,
    /// Circular-arc ball-screw groove.
    BallArc,
    /// Ball screw raceway, gothic arch or circular arc (`raceway`).
    BallScrew,
    /// Cylindrical worm, DIN 3975-1 flank form ZA, ZN, ZI or ZK (`flank`).
    Worm,
}

impl StandardKind {
    /// The `[groove.profile]` keys that give this form its dimensions (see
    /// [`ProfileSpec`]); any other form's key beside it is refused.
    fn keys(self) -> &'static [&'static str] {
        match self {
            StandardKind::Trapezoidal => &["major_diameter", "root_radius", "crest_clearance"],
            StandardKind::Acme => &["major_diameter", "root_radius"],
            StandardKind::BallArc => &[
                "ball_diameter",
                "groove_radius",
                "pitch_diameter",
                "outer_diameter",
            ],
            StandardKind::BallScrew => &[
                "raceway",
                "ball_diameter",
                "conformity",
                "contact_angle_deg",
                "pitch_diameter",
                "outer_diameter",
                "relief_radius",
            ],
            StandardKind::Worm => &[
                "flank",
                "module",
                "diameter_quotient",
                "pressure_angle_deg",
                "bottom_clearance",
                "root_radius",
                "wheel_diameter",
            ],
        }
    }

    /// The name a job gives it (`standard = "ball-arc"`).
    pub fn name(self) -> &'static str {
        match self {
            StandardKind::Trapezoidal => "trapezoidal",
            StandardKind::Acme => "acme",
            StandardKind::BallArc => "ball-arc",
            StandardKind::BallScrew => "ball-screw",
            StandardKind::Worm => "worm",
        }
    }
}

/// `raceway` of a ball screw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RacewaySpec {
    /// Two arcs, the ball touching each at the contact angle.
    GothicArch,
    /// One arc.
    CircularArc,
}

/// `flank` of a worm: DIN 3975-1's letters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum WormFlankSpec {
    /// Straight in the axial section.
    ZA,
    /// Straight in the normal section.
    ZN,
    /// Involute helicoid.
    ZI,
    /// Generated by a double-cone wheel (`wheel_diameter`).
    ZK,
}

/// `[groove.profile]`: either sampled points or a standard with its dimensions.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Section of the points (default transverse).
    pub section: Option<SectionSpec>,
    /// CSV file of points, relative to the job file.
    pub points: Option<PathBuf>,
    /// The points are half a period: mirror them about the last point.
    pub mirror: Option<bool>,
    /// Measured points: how far each may lie from the true curve, mm (a CMM's or an
    /// optical projector's stated uncertainty). The profile is fitted within it, its
    /// scatter smoothed away; without it, within the points' own rounding (half their last
    /// decimal). See `geometry::profile::smoothing`.
    pub fit_tolerance: Option<f64>,
    /// A standard profile instead of points.
    pub standard: Option<StandardKind>,
    /// A standard thread by its designation, as a drawing writes it (`Tr 40x7`,
    /// `1/2-10 ACME-2G`), instead of points or `standard`: the form comes from the standard's
    /// tables, and the lead, starts and hand from the designation.
    pub designation: Option<String>,
    /// A CAD drawing (DXF) of the section instead of points, relative to the job file.
    pub dxf: Option<PathBuf>,
    /// The drawing's layer that holds the profile (default: every layer).
    pub layer: Option<String>,
    /// The drawing's units (`"mm"`, `"in"`, `"um"`…), overriding its `$INSUNITS`; needed
    /// when it has none.
    pub units: Option<String>,
    /// Trapezoidal, Acme: major diameter d, mm.
    pub major_diameter: Option<f64>,
    /// Trapezoidal, Acme: root fillet radius, mm.
    pub root_radius: Option<f64>,
    /// Trapezoidal: crest clearance a_c override, mm.
    pub crest_clearance: Option<f64>,
    /// Ball-arc: ball diameter D_w, mm.
    pub ball_diameter: Option<f64>,
    /// Ball-arc: groove radius r_g, mm.
    pub groove_radius: Option<f64>,
    /// Ball-arc: ball-centre (pitch-circle) diameter d_0, mm.
    pub pitch_diameter: Option<f64>,
    /// Ball-arc: shaft outer diameter, mm.
    pub outer_diameter: Option<f64>,
    /// Ball screw: `"gothic-arch"` or `"circular-arc"`.
    pub raceway: Option<RacewaySpec>,
    /// Ball screw: conformity r_g / D_w (0.52 to 0.56 in the catalogues).
    pub conformity: Option<f64>,
    /// Ball screw, gothic arch: contact angle, degrees (default 45).
    pub contact_angle_deg: Option<f64>,
    /// Ball screw, gothic arch: radius of the relief arc rounding the bottom, mm.
    pub relief_radius: Option<f64>,
    /// Worm: flank form `"ZA"`, `"ZN"`, `"ZI"` or `"ZK"`.
    pub flank: Option<WormFlankSpec>,
    /// Worm: axial module m, mm.
    pub module: Option<f64>,
    /// Worm: diameter quotient q = d1 / m.
    pub diameter_quotient: Option<f64>,
    /// Worm: pressure angle α, degrees (default 20), in the section the flank form names.
    pub pressure_angle_deg: Option<f64>,
    /// Worm: bottom clearance factor c* (default 0.2).
    pub bottom_clearance: Option<f64>,
    /// Worm, ZK: the generating double-cone wheel's diameter d0, mm.
    pub wheel_diameter: Option<f64>,
    /// Buttress (S): the side of the groove its 3° load flank lies on, `"+z"` (DIN 513's
    /// drawing, the default) or `"-z"`.
    pub load_flank: Option<LoadFlankSpec>,
}

/// `[groove.profile] load_flank`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum LoadFlankSpec {
    /// The groove's +z side.
    #[serde(rename = "+z")]
    PlusZ,
    /// The groove's −z side.
    #[serde(rename = "-z")]
    MinusZ,
}

impl ProfileSpec {
    /// The keys that give a standard form its dimensions, each with whether the job sets it:
    /// what points, a drawing or a designation must not be given beside.
    fn form_keys(&self) -> [(&'static str, bool); 18] {
        [
            ("major_diameter", self.major_diameter.is_some()),
            ("root_radius", self.root_radius.is_some()),
            ("crest_clearance", self.crest_clearance.is_some()),
            ("ball_diameter", self.ball_diameter.is_some()),
            ("groove_radius", self.groove_radius.is_some()),
            ("pitch_diameter", self.pitch_diameter.is_some()),
            ("outer_diameter", self.outer_diameter.is_some()),
            ("raceway", self.raceway.is_some()),
            ("conformity", self.conformity.is_some()),
            ("contact_angle_deg", self.contact_angle_deg.is_some()),
            ("relief_radius", self.relief_radius.is_some()),
            ("flank", self.flank.is_some()),
            ("module", self.module.is_some()),
            ("diameter_quotient", self.diameter_quotient.is_some()),
            ("pressure_angle_deg", self.pressure_angle_deg.is_some()),
            ("bottom_clearance", self.bottom_clearance.is_some()),
            ("wheel_diameter", self.wheel_diameter.is_some()),
            ("load_flank", self.load_flank.is_some()),
        ]
    }
}

/// `[tool]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tool {
    /// Internal (ring round the work), external (disk beside it) or bore (a head inside a
    /// nut's bore).
    pub whirling: Whirling,
    /// R: ring centre to insert nose centre, mm.
    pub ring_radius: f64,
    /// r: insert nose radius, mm.
    pub nose_radius: f64,
    /// Number of inserts on the ring.
    pub inserts: u32,
    /// δ, degrees; omitted: `plan` takes the angle with the largest margin in the window
    /// of angles at which the ring fits the groove (`crate::plan::angles`).
    pub installation_angle_deg: Option<f64>,
    /// The insert's cutting-edge arc, degrees (default 180: a full-radius nose cuts ±90°).
    pub edge_arc_deg: Option<f64>,
    /// The largest chip thickness the insert takes, mm (its maker's figure); absent: chips
    /// are not checked. The fastest feed keeps below it (`crate::plan::feed`).
    pub max_chip_thickness: Option<f64>,
}

/// `[cut]`, read and checked.
#[derive(Debug, Clone)]
pub struct Cut {
    /// Allowable profile error Δ, mm.
    pub delta: f64,
    /// Axial feed of the unit per workpiece revolution, mm: the job's, or, while
    /// [`Cut::auto_feed`] is set, where the search for the fastest feed starts (the job's
    /// number under `whirl plan --fastest`, else [`AUTO_FEED_START`] of the axial pitch).
    /// The planner resolves an auto job itself (`crate::plan::feed::fastest`); whatever
    /// measures one measures it at the feed its program was planned at.
    pub axial_feed: f64,
    /// `axial_feed = "auto"` (or `whirl plan --fastest`): plan at the largest feed that Δ
    /// and the machine allow, not at `axial_feed`.
    pub auto_feed: bool,
    /// Workpiece speed, rpm.
    pub workpiece_rpm: f64,
    /// Ring speed, rpm.
    pub ring_rpm: f64,
    /// Feed of the radial plunge and of other G94 moves, mm/min (default 50).
    pub plunge_feed: Option<f64>,
}

/// Where the search for the fastest feed starts when the job gives none, as a share of the
/// axial pitch (lead / starts): a feed well inside the range every example plans at.
pub const AUTO_FEED_START: f64 = 0.01;

/// `[cut]` as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CutFile {
    delta: f64,
    axial_feed: AxialFeed,
    workpiece_rpm: f64,
    ring_rpm: f64,
    plunge_feed: Option<f64>,
}

impl CutFile {
    /// The cut, its feed resolved to a number: the job's, or for `"auto"` where the search
    /// starts, [`AUTO_FEED_START`] of `groove`'s axial pitch.
    fn resolve(self, groove: &Groove) -> Cut {
        let (axial_feed, auto_feed) = match self.axial_feed {
            AxialFeed::Mm(feed) => (feed, false),
            AxialFeed::Auto => (
                AUTO_FEED_START * groove.lead / f64::from(groove.starts),
                true,
            ),
        };
        Cut {
            delta: self.delta,
            axial_feed,
            auto_feed,
            workpiece_rpm: self.workpiece_rpm,
            ring_rpm: self.ring_rpm,
            plunge_feed: self.plunge_feed,
        }
    }
}

/// `cut.axial_feed`: mm per workpiece revolution, or `"auto"`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum AxialFeed {
    /// A feed, mm per workpiece revolution: finite, above zero.
    Mm(f64),
    /// The fastest feed Δ and the machine allow.
    Auto,
}

impl<'de> Deserialize<'de> for AxialFeed {
    /// A positive number or the string `"auto"`; anything else is refused where it stands in
    /// the file (toml adds the line and column).
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = AxialFeed;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a feed in mm per workpiece revolution, or \"auto\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<AxialFeed, E> {
                if v.is_finite() && v > 0.0 {
                    Ok(AxialFeed::Mm(v))
                } else {
                    Err(E::custom(format!(
                        "cut.axial_feed = {}: a feed must be a positive number of mm per \
                         workpiece revolution (or \"auto\" for the fastest feed)",
                        show_number(v)
                    )))
                }
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<AxialFeed, E> {
                self.visit_f64(v as f64)
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<AxialFeed, E> {
                self.visit_f64(v as f64)
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<AxialFeed, E> {
                if v == "auto" {
                    Ok(AxialFeed::Auto)
                } else {
                    Err(E::custom(format!(
                        "cut.axial_feed = {v:?}: give a feed in mm per workpiece revolution \
                         (0.1) or \"auto\" for the fastest feed Δ and the machine allow"
                    )))
                }
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// Why a job could not be read or resolved.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// The file could not be read.
    #[error("cannot read {path}: {error}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// TOML syntax or schema.
    #[error("{path}: {error}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why (with line and column).
        error: Box<toml::de::Error>,
    },
    /// A value out of its range.
    #[error("{key} = {value}: {why}")]
    Invalid {
        /// The TOML key.
        key: &'static str,
        /// Its value.
        value: String,
        /// What is allowed.
        why: String,
    },
    /// The profile table is inconsistent.
    #[error("[groove.profile]: {0}")]
    ProfileSpec(String),
    /// Profile points are wrong.
    #[error("{path}: {error}")]
    Points {
        /// The points file.
        path: PathBuf,
        /// What is wrong and where.
        error: PointsError,
    },
    /// Standard dimensions are wrong.
    #[error("[groove.profile] standard: {0}")]
    Standard(StandardError),
    /// The designation is refused.
    #[error("[groove.profile] designation = {0}")]
    Designation(DesignationError),
    /// A key the job must give (or a designation fix) is missing.
    #[error("{key} is missing: {why}")]
    Missing {
        /// The TOML key.
        key: &'static str,
        /// What fixes it.
        why: &'static str,
    },
    /// A value the job gives disagrees with the one its designation fixes.
    #[error("{key} = {value} disagrees with designation = \"{designation}\", which gives {given}")]
    DisagreesWithDesignation {
        /// The TOML key.
        key: &'static str,
        /// The job's value.
        value: String,
        /// The designation.
        designation: String,
        /// The designation's value.
        given: String,
    },
    /// The drawing gives no profile.
    #[error("{path}: {error}")]
    Drawing {
        /// The drawing file.
        path: PathBuf,
        /// What is wrong and where (boxed: it names entities, and a job's error stays small).
        error: Box<DrawingError>,
    },
}

/// A standard's dimensions, in the words of its own error (printed whole, not as a
/// separate cause).
impl From<StandardError> for JobError {
    fn from(error: StandardError) -> JobError {
        JobError::Standard(error)
    }
}

impl Job {
    /// Read and check a job file, and the profile points it names.
    pub fn load(path: &Path) -> Result<Job, JobError> {
        let text = std::fs::read_to_string(path).map_err(|error| JobError::Read {
            path: path.to_owned(),
            error,
        })?;
        Job::from_toml(&text, path)
    }

    /// Read and check a job from its TOML text; `path` is where the text came from, named in
    /// errors, and its folder is where a profile's points file is read from.
    pub fn from_toml(text: &str, path: &Path) -> Result<Job, JobError> {
        let file: JobText = toml::from_str(text).map_err(|error| JobError::Parse {
            path: path.to_owned(),
            error: Box::new(error),
        })?;
        let file = file.settle()?;
        file.validate()?;
        file.tool_for_the_groove()?;
        let profile = file.profile(path.parent().unwrap_or(Path::new("")))?;
        // Δ against the groove it is for: beyond the depth it bounds nothing. (The planner
        // refuses one finer than the machine's numbers can hold; that needs the machine.)
        let (rho_min, rho_max) = profile.radius_range();
        if let Some(why) = depth_refusal(file.cut.delta, rho_min, rho_max) {
            return Err(JobError::Invalid {
                key: "cut.delta",
                value: show_number(file.cut.delta),
                why,
            });
        }
        if let Some(why) = bore_refusal(&file.tool, rho_min) {
            return Err(JobError::Invalid {
                key: "tool.ring_radius",
                value: show_number(file.tool.ring_radius),
                why,
            });
        }
        // The form whirl profile shows: the designation's, or the standard's dimensions.
        let form = match &file.designation {
            Some(designation) => Some(match file.groove.profile.root_radius {
                Some(radius) => designation.form.with_root_radius(radius)?,
                None => designation.form,
            }),
            None => file
                .groove
                .profile
                .standard
                .map(|kind| file.standard(kind))
                .transpose()?,
        };
        let JobFile {
            groove, tool, cut, ..
        } = file;
        let cut = cut.resolve(&groove);
        Ok(Job {
            groove,
            tool,
            cut,
            profile,
            form,
        })
    }

    /// Lead parameter p = ±lead / 2π (+ right hand).
    pub fn p(&self) -> f64 {
        self.groove.p()
    }

    /// Polar period 2π / starts.
    pub fn period(&self) -> f64 {
        self.groove.period()
    }

    /// The job's ring tilted by `installation` radians, whatever angle the job gives.
    ///
    /// There is no ring of the job alone: one that gives no `installation_angle_deg` is
    /// planned at the angle with the largest margin in its window, which only the planner's
    /// checks find (`crate::plan::angles::ring`, which also gives the ring of a job that
    /// gives its angle), and whatever measures a program of the job must take the ring the
    /// program was planned with (`crate::plan::Plan::ring`).
    pub fn ring_at(&self, installation: f64) -> Ring {
        Ring {
            whirling: self.tool.whirling,
            radius: self.tool.ring_radius,
            nose: self.tool.nose_radius,
            installation,
            edge_half_angle: self.tool.edge_arc_deg.unwrap_or(180.0).to_radians() / 2.0,
        }
    }
}

/// Why Δ = `delta` means nothing for a groove whose radii run from `rho_min` to `rho_max`:
/// above the groove's depth, every groove lies within Δ of a plain cylinder, so nothing is
/// being cut to any tolerance (and at 10³⁰⁸ the program's title line, which states Δ, runs off
/// the controller's line length). `None` when Δ is within the depth.
pub(crate) fn depth_refusal(delta: f64, rho_min: f64, rho_max: f64) -> Option<String> {
    let depth = rho_max - rho_min;
    (delta > depth).then(|| {
        format!(
            "above the groove's depth, {depth:.4} mm (ρ from {rho_min:.4} to {rho_max:.4} mm): \
             an allowable error that large means nothing is cut to any tolerance"
        )
    })
}

/// Why a bore head `tool` does not fit a nut whose bore radius is `bore` (the groove's least
/// radius): centred in the bore its noses reach R + r from the axis all round, and touching
/// one side they reach as far across on the other, so the head fits only when R + r is
/// below the bore radius (kinematics.md, "Internal grooves"). `None` when it fits or the
/// tool is no bore head.
fn bore_refusal(tool: &Tool, bore: f64) -> Option<String> {
    let reach = tool.ring_radius + tool.nose_radius;
    (tool.whirling == Whirling::Bore && reach >= bore).then(|| {
        format!(
            "the bore head does not fit the nut's bore: ring_radius + nose_radius = {} mm \
             reaches the bore radius {:.4} mm (bore diameter {:.4} mm); a head this size \
             would cut the far side of the bore",
            show_figure(reach),
            bore,
            2.0 * bore
        )
    })
}

/// A value for a message: Rust's shortest form, in exponent form outside 10⁻⁶ … 10⁹ (where
/// the plain form spells out hundreds of digits: 1e308, 1e-12).
pub(crate) fn show_number(v: f64) -> String {
    if v != 0.0 && !(1e-6..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// A computed figure for a message: four significant digits, shown as [`show_number`] does.
pub(crate) fn show_figure(v: f64) -> String {
    show_number(format!("{v:.3e}").parse().unwrap_or(v))
}

impl Groove {
    /// Lead parameter p = ±lead / 2π (+ right hand).
    pub fn p(&self) -> f64 {
        let p = self.lead / TAU;
        match self.hand {
            Hand::Right => p,
            Hand::Left => -p,
        }
    }

    /// Polar period 2π / starts.
    pub fn period(&self) -> f64 {
        TAU / f64::from(self.starts)
    }

    /// Which side of the groove's surface the material lies: outside for a nut.
    pub fn material(&self) -> Material {
        if self.internal == Some(true) {
            Material::Outside
        } else {
            Material::Inside
        }
    }
}

impl JobText {
    /// Settles the groove's lead, starts and hand: the job's own, or its designation's; where
    /// both give one they must agree.
    fn settle(self) -> Result<JobFile, JobError> {
        let JobText { groove, tool, cut } = self;
        let text = groove.profile.designation.as_deref();
        let designation = text
            .map(|text| designation::parse(text).map_err(JobError::Designation))
            .transpose()?;
        let text = text.unwrap_or_default();
        let disagree = |key, value: String, given: String| JobError::DisagreesWithDesignation {
            key,
            value,
            designation: text.to_string(),
            given,
        };
        let fixed = designation.as_ref();
        let missing = "give it, or a [groove.profile] designation that fixes it (Tr 40x7)";
        let lead = match (groove.lead, fixed.and_then(|d| d.lead)) {
            (Some(job), Some(given)) if (job - given).abs() > 1e-9 * given => {
                return Err(disagree(
                    "groove.lead",
                    show_number(job),
                    show_number(given),
                ))
            }
            (Some(lead), _) | (None, Some(lead)) => lead,
            (None, None) => {
                return Err(JobError::Missing {
                    key: "groove.lead",
                    why: missing,
                })
            }
        };
        let starts = match (groove.starts, fixed.and_then(|d| d.starts)) {
            (Some(job), Some(given)) if job != given => {
                return Err(disagree(
                    "groove.starts",
                    job.to_string(),
                    given.to_string(),
                ))
            }
            (Some(starts), _) | (None, Some(starts)) => starts,
            (None, None) => {
                return Err(JobError::Missing {
                    key: "groove.starts",
                    why: missing,
                })
            }
        };
        // ISO's capital tolerance class (7H, 6H) names the nut: the groove is internal.
        // (ASME's Acme classes, 2G, name screw and nut alike: the job says which.)
        let nut = fixed.is_some_and(Designation::internal).then_some(true);
        let internal = match (groove.internal, nut) {
            (Some(job), Some(given)) if job != given => {
                return Err(disagree(
                    "groove.internal",
                    job.to_string(),
                    given.to_string(),
                ))
            }
            (job, given) => job.or(given),
        };
        let given_hand = fixed.map(|d| if d.left_hand { Hand::Left } else { Hand::Right });
        let hand = match (groove.hand, given_hand) {
            (Some(job), Some(given)) if job != given => {
                return Err(disagree(
                    "groove.hand",
                    format!("{job:?}").to_lowercase(),
                    format!("{given:?}").to_lowercase(),
                ))
            }
            (Some(hand), _) | (None, Some(hand)) => hand,
            (None, None) => {
                return Err(JobError::Missing {
                    key: "groove.hand",
                    why: "give \"right\" or \"left\", or a [groove.profile] designation \
                          (right hand unless it says LH)",
                })
            }
        };
        Ok(JobFile {
            groove: Groove {
                lead,
                starts,
                hand,
                z_start: groove.z_start,
                length: groove.length,
                internal,
                profile: groove.profile,
            },
            tool,
            cut,
            designation,
        })
    }
}

impl JobFile {
    /// A nut's groove is cut by a bore head and a screw's by a ring or a disk: a job that
    /// pairs them otherwise is refused, naming both keys.
    fn tool_for_the_groove(&self) -> Result<(), JobError> {
        let internal = self.groove.material() == Material::Outside;
        let bore = self.tool.whirling == Whirling::Bore;
        if internal == bore {
            return Ok(());
        }
        Err(JobError::Invalid {
            key: "tool.whirling",
            value: format!("{:?}", self.tool.whirling.name()),
            why: if internal {
                "[groove] internal = true is a nut's groove, cut from inside its bore: only a \
                 bore head (whirling = \"bore\") reaches it; a ring or a disk cuts screws"
                    .into()
            } else {
                "a bore head cuts internal grooves only: set [groove] internal = true for a \
                 nut, or take an internal or external ring for a screw"
                    .into()
            },
        })
    }

    /// Check every value's range, naming the key.
    fn validate(&self) -> Result<(), JobError> {
        let positive = |key: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(JobError::Invalid {
                    key,
                    value: v.to_string(),
                    why: "must be a positive number".into(),
                })
            }
        };
        positive("groove.lead", self.groove.lead)?;
        positive("groove.length", self.groove.length)?;
        if !self.groove.z_start.is_finite() {
            return Err(JobError::Invalid {
                key: "groove.z_start",
                value: self.groove.z_start.to_string(),
                why: "must be a finite number".into(),
            });
        }
        if self.groove.starts == 0 {
            return Err(JobError::Invalid {
                key: "groove.starts",
                value: "0".into(),
                why: "a groove has at least one start".into(),
            });
        }
        positive("tool.ring_radius", self.tool.ring_radius)?;
        positive("tool.nose_radius", self.tool.nose_radius)?;
        if self.tool.nose_radius >= self.tool.ring_radius {
            return Err(JobError::Invalid {
                key: "tool.nose_radius",
                value: self.tool.nose_radius.to_string(),
                why: format!(
                    "must be smaller than ring_radius ({})",
                    self.tool.ring_radius
                ),
            });
        }
        if self.tool.inserts == 0 {
            return Err(JobError::Invalid {
                key: "tool.inserts",
                value: "0".into(),
                why: "the ring carries at least one insert".into(),
            });
        }
        if let Some(d) = self.tool.installation_angle_deg {
            if !(0.0..90.0).contains(&d) {
                return Err(JobError::Invalid {
                    key: "tool.installation_angle_deg",
                    value: d.to_string(),
                    why: "must be at least 0° and below 90°".into(),
                });
            }
        }
        if let Some(a) = self.tool.edge_arc_deg {
            if !(a > 0.0 && a <= 360.0) {
                return Err(JobError::Invalid {
                    key: "tool.edge_arc_deg",
                    value: a.to_string(),
                    why: "must be above 0° and at most 360°".into(),
                });
            }
        }
        if let Some(h) = self.tool.max_chip_thickness {
            positive("tool.max_chip_thickness", h)?;
        }
        positive("cut.delta", self.cut.delta)?;
        positive("cut.workpiece_rpm", self.cut.workpiece_rpm)?;
        positive("cut.ring_rpm", self.cut.ring_rpm)?;
        if let Some(f) = self.cut.plunge_feed {
            positive("cut.plunge_feed", f)?;
        }
        if let Some(t) = self.groove.profile.fit_tolerance {
            positive("groove.profile.fit_tolerance", t)?;
        }
        let pitch = self.groove.lead / f64::from(self.groove.starts);
        match self.cut.axial_feed {
            AxialFeed::Mm(feed) if feed >= pitch => Err(JobError::Invalid {
                key: "cut.axial_feed",
                value: feed.to_string(),
                why: format!("must be well below the axial pitch lead / starts = {pitch} mm"),
            }),
            _ => Ok(()),
        }
    }

    /// The groove's transverse profile, from points (their file relative to `dir`) or a
    /// standard.
    fn profile(&self, dir: &Path) -> Result<Profile, JobError> {
        let spec = &self.groove.profile;
        let standard_keys = spec.form_keys();
        if let Some(designation) = &self.designation {
            return self.designated(designation);
        }
        if let Some(file) = &spec.dxf {
            return self.drawing(dir, file, &standard_keys);
        }
        if spec.layer.is_some() || spec.units.is_some() {
            return Err(JobError::ProfileSpec(
                "layer and units belong to a drawing: give dxf = \"groove.dxf\"".into(),
            ));
        }
        if spec.standard.is_some() && spec.fit_tolerance.is_some() {
            return Err(JobError::ProfileSpec(
                "fit_tolerance belongs to points: a standard's form is exact".into(),
            ));
        }
        match (&spec.points, spec.standard) {
            (Some(_), Some(_)) => Err(JobError::ProfileSpec(
                "give either points or standard, not both".into(),
            )),
            (None, None) => Err(JobError::ProfileSpec(
                "give points = \"file.csv\", designation = \"Tr 40x7\" or standard = \
                 \"trapezoidal\" | \"acme\" | \"ball-arc\" | \"ball-screw\" | \"worm\""
                    .into(),
            )),
            (Some(file), None) => {
                if let Some((key, _)) = standard_keys.iter().find(|(_, set)| *set) {
                    return Err(JobError::ProfileSpec(format!(
                        "{key} belongs to a standard profile, not to points"
                    )));
                }
                let path = dir.join(file);
                let text = std::fs::read_to_string(&path).map_err(|error| JobError::Read {
                    path: path.clone(),
                    error,
                })?;
                let section = match spec.section.unwrap_or(SectionSpec::Transverse) {
                    SectionSpec::Transverse => Section::Transverse,
                    SectionSpec::Axial => Section::Axial,
                };
                let points_err = |error| JobError::Points {
                    path: path.clone(),
                    error,
                };
                let rows = points::read_csv(&text).map_err(points_err)?;
                points::profile_within(
                    &rows,
                    section,
                    spec.mirror.unwrap_or(false),
                    self.groove.p(),
                    self.groove.starts,
                    spec.fit_tolerance,
                )
                .map(|profile| profile.with_material(self.groove.material()))
                .map_err(points_err)
            }
            (None, Some(kind)) => {
                if spec.section == Some(SectionSpec::Transverse) || spec.mirror.is_some() {
                    return Err(JobError::ProfileSpec(
                        "standard profiles are axial sections of a whole pitch: leave out \
                         section = \"transverse\" and mirror"
                            .into(),
                    ));
                }
                self.axial(&self.standard(kind)?)
            }
        }
    }

    /// The profile of a standard thread named by its designation: the form from the
    /// standard's tables, with the job's `root_radius` (which a designation leaves to the
    /// maker) where it gives one; no other dimension may be given beside it.
    fn designated(&self, designation: &Designation) -> Result<Profile, JobError> {
        let spec = &self.groove.profile;
        let others = [
            ("points", spec.points.is_some()),
            ("standard", spec.standard.is_some()),
            ("dxf", spec.dxf.is_some()),
            ("layer", spec.layer.is_some()),
            ("units", spec.units.is_some()),
            ("section", spec.section.is_some()),
            ("mirror", spec.mirror.is_some()),
            ("fit_tolerance", spec.fit_tolerance.is_some()),
        ];
        // A designation leaves the root radius to the maker, and a buttress's load flank to
        // the drawing: every other dimension is its.
        let dimensions = spec
            .form_keys()
            .into_iter()
            .filter(|(key, _)| !["root_radius", "load_flank"].contains(key));
        if let Some((key, _)) = others.into_iter().chain(dimensions).find(|(_, set)| *set) {
            return Err(JobError::ProfileSpec(format!(
                "{key} does not go with designation: the designation fixes the form (only \
                 root_radius may be given beside it)"
            )));
        }
        let form = match spec.root_radius {
            Some(radius) => designation.form.with_root_radius(radius)?,
            None => designation.form,
        };
        let form = match (spec.load_flank, form) {
            (None, form) => form,
            (Some(side), StandardProfile::Buttress(b)) => {
                StandardProfile::Buttress(b.with_load_flank(match side {
                    LoadFlankSpec::PlusZ => LoadFlank::PlusZ,
                    LoadFlankSpec::MinusZ => LoadFlank::MinusZ,
                }))
            }
            (Some(_), _) => {
                return Err(JobError::ProfileSpec(
                    "load_flank belongs to a buttress thread (S 48x8), whose 3° load flank it \
                     places: this designation's form has none"
                        .into(),
                ))
            }
        };
        self.axial(&form)
    }

    /// The profile of a standard `form` over one axial pitch: the screw's section, or its
    /// nut's where the groove is internal.
    fn axial(&self, form: &StandardProfile) -> Result<Profile, JobError> {
        let pitch = self.groove.lead / f64::from(self.groove.starts);
        let material = self.groove.material();
        let pieces = match material {
            Material::Inside => form.pieces(pitch)?,
            Material::Outside => form.internal_pieces(pitch)?,
        };
        Ok(Profile::from_axial_of(
            pieces,
            self.groove.p(),
            self.groove.period(),
            material,
        ))
    }

    /// The profile a drawing (`file`, relative to `dir`) draws.
    fn drawing(
        &self,
        dir: &Path,
        file: &Path,
        standard_keys: &[(&str, bool)],
    ) -> Result<Profile, JobError> {
        let spec = &self.groove.profile;
        let others = [
            ("points", spec.points.is_some()),
            ("standard", spec.standard.is_some()),
            ("mirror", spec.mirror.is_some()),
            ("fit_tolerance", spec.fit_tolerance.is_some()),
        ];
        if let Some((key, _)) = others.iter().chain(standard_keys).find(|(_, set)| *set) {
            return Err(JobError::ProfileSpec(format!(
                "{key} does not go with dxf: a drawing is exact and gives the whole section"
            )));
        }
        let path = dir.join(file);
        let bytes = std::fs::read(&path).map_err(|error| JobError::Read {
            path: path.clone(),
            error,
        })?;
        let drawing_err = |error| JobError::Drawing {
            path: path.clone(),
            error: Box::new(error),
        };
        let units = spec
            .units
            .as_deref()
            .map(drawing::Units::named)
            .transpose()
            .map_err(drawing_err)?;
        let options = drawing::Options {
            layer: spec.layer.clone(),
            units,
            section: match spec.section.unwrap_or(SectionSpec::Transverse) {
                SectionSpec::Transverse => drawing::Section::Transverse,
                SectionSpec::Axial => drawing::Section::Axial,
            },
            p: self.groove.p(),
            starts: self.groove.starts,
            material: self.groove.material(),
        };
        let parsed = drawing::read(&bytes).map_err(drawing_err)?;
        drawing::profile(&parsed, &options).map_err(drawing_err)
    }

    fn standard(&self, kind: StandardKind) -> Result<StandardProfile, JobError> {
        let spec = &self.groove.profile;
        let need = |key: &'static str, v: Option<f64>| {
            v.ok_or_else(|| JobError::ProfileSpec(format!("standard = {kind:?} needs {key}")))
        };
        let own = kind.keys();
        if let Some((key, _)) = spec
            .form_keys()
            .into_iter()
            .find(|(key, set)| *set && !own.contains(key))
        {
            return Err(JobError::ProfileSpec(format!(
                "{key} is not a dimension of standard = {kind:?}"
            )));
        }
        Ok(match kind {
            StandardKind::BallScrew => {
                let raceway = match spec.raceway {
                    Some(RacewaySpec::GothicArch) => Raceway::GothicArch,
                    Some(RacewaySpec::CircularArc) => Raceway::CircularArc,
                    None => {
                        return Err(JobError::ProfileSpec(
                            "standard = \"ball-screw\" needs raceway = \"gothic-arch\" | \
                             \"circular-arc\""
                                .into(),
                        ))
                    }
                };
                StandardProfile::BallScrew(BallScrew::new(
                    raceway,
                    need("ball_diameter", spec.ball_diameter)?,
                    need("conformity", spec.conformity)?,
                    spec.contact_angle_deg,
                    need("pitch_diameter", spec.pitch_diameter)?,
                    need("outer_diameter", spec.outer_diameter)?,
                    spec.relief_radius,
                )?)
            }
            StandardKind::Worm => {
                let flank =
                    match spec.flank {
                        Some(WormFlankSpec::ZA) => WormFlank::ZA,
                        Some(WormFlankSpec::ZN) => WormFlank::ZN,
                        Some(WormFlankSpec::ZI) => WormFlank::ZI,
                        Some(WormFlankSpec::ZK) => WormFlank::ZK {
                            wheel_diameter: need("wheel_diameter", spec.wheel_diameter)?,
                        },
                        None => return Err(JobError::ProfileSpec(
                            "standard = \"worm\" needs flank = \"ZA\" | \"ZN\" | \"ZI\" | \"ZK\""
                                .into(),
                        )),
                    };
                if spec.wheel_diameter.is_some() && spec.flank != Some(WormFlankSpec::ZK) {
                    return Err(JobError::ProfileSpec(
                        "wheel_diameter belongs to a ZK worm (flank = \"ZK\"), whose flank its \
                         wheel generates"
                            .into(),
                    ));
                }
                StandardProfile::Worm(Worm::new(
                    flank,
                    need("module", spec.module)?,
                    self.groove.starts,
                    need("diameter_quotient", spec.diameter_quotient)?,
                    spec.pressure_angle_deg,
                    spec.bottom_clearance,
                    spec.root_radius,
                )?)
            }
            StandardKind::Trapezoidal | StandardKind::Acme => {
                let d = need("major_diameter", spec.major_diameter)?;
                if kind == StandardKind::Trapezoidal {
                    StandardProfile::IsoTrapezoidal(IsoTrapezoidal::new(
                        d,
                        spec.root_radius,
                        spec.crest_clearance,
                    )?)
                } else {
                    StandardProfile::Acme(AcmeGeneralPurpose::new(d, spec.root_radius)?)
                }
            }
            StandardKind::BallArc => StandardProfile::BallArc(BallArc::new(
                need("ball_diameter", spec.ball_diameter)?,
                need("groove_radius", spec.groove_radius)?,
                need("pitch_diameter", spec.pitch_diameter)?,
                need("outer_diameter", spec.outer_diameter)?,
            )?),
        })
    }
}
