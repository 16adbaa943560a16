//! Machine profiles: what a whirling lathe and its controller can do, and checks of a
//! [`Program`] against it.
//!
//! A profile is a TOML file (`machine-profiles/*.toml`, `sim.toml` the default). Every
//! table denies unknown keys, so a misspelt limit is an error instead of a silently
//! ignored one, and loading validates the values; errors name the file and the key.
//!
//! Positions and rates are in the machine frame of `kinematics.md`: X is the ring-centre
//! offset from the spindle axis (a radius, mm) even when the controller's X words are
//! diameters (`x_mode = "diameter"` only changes how the post writes X), Z is axial (mm),
//! C is the workpiece turn (degrees).
//!
//! An optional `[connection]` table says how the bridge reaches the machine (a serial
//! port, a PLC's Modbus address, CAN drives and their scales); see [`crate::config::connection`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::config::connection::Connection;
use crate::post::gcode::writer::{Dialect, PostSettings, MIN_LINE_LENGTH};
use crate::program::{Axis, Block, Pose, Program};

/// How the controller holds coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NumberType {
    /// 32-bit floats (grbl family): about 7 significant digits of the *machine* position,
    /// which G92 cannot win back, so C's resolution at its largest value is a cost in the
    /// planner's error budget.
    F32,
    /// 64-bit floats (LinuxCNC).
    F64,
}

impl NumberType {
    /// The gap between adjacent representable numbers at `value`: the resolution the
    /// controller has there (at C = 180 000° an f32 resolves 0.015625°). Infinite for a
    /// value the type cannot hold. The planner counts half of it in its rounding share.
    pub fn spacing_at(self, value: f64) -> f64 {
        match self {
            NumberType::F32 => {
                let v = value.abs() as f32;
                let next = f32::from_bits(v.to_bits() + 1);
                if v.is_finite() && next.is_finite() {
                    f64::from(next) - f64::from(v)
                } else {
                    f64::INFINITY
                }
            }
            NumberType::F64 => {
                let v = value.abs();
                let next = f64::from_bits(v.to_bits() + 1);
                if v.is_finite() && next.is_finite() {
                    next - v
                } else {
                    f64::INFINITY
                }
            }
        }
    }
}

/// What the controller's X words mean.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum XMode {
    /// X words are the ring-centre offset itself (kinematics.md).
    Radius,
    /// X words are twice the offset (lathe diameter mode, G7), as many LinuxCNC lathes
    /// are set up.
    Diameter,
}

/// A linear axis (X or Z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearAxis {
    /// Lowest reachable position, mm (program frame; X as a radius).
    pub min: f64,
    /// Highest reachable position, mm.
    pub max: f64,
    /// Highest axis speed, mm/min (the controller's max rate, also its rapid rate).
    pub max_rate: f64,
    /// Axis acceleration, mm/s² (for the simulator and the planner's junction model).
    pub accel: f64,
}

/// The rotary axis C (the workpiece).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotaryAxis {
    /// Lowest allowed position, degrees; absent: unlimited (a rotary axis usually is).
    #[serde(default)]
    pub min: Option<f64>,
    /// Highest allowed position, degrees; absent: unlimited.
    #[serde(default)]
    pub max: Option<f64>,
    /// Highest axis speed, deg/min (360 000 deg/min = 1000 rpm of the workpiece).
    pub max_rate: f64,
    /// Axis acceleration, deg/s².
    pub accel: f64,
}

/// The three axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axes {
    /// Ring-centre offset.
    pub x: LinearAxis,
    /// Axial position.
    pub z: LinearAxis,
    /// Workpiece turn.
    pub c: RotaryAxis,
}

/// The whirling ring's spindle (M3 S…).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spindle {
    /// Slowest speed the ring drive holds, rpm.
    pub min_rpm: f64,
    /// Fastest speed of the ring (drive and insert limit), rpm.
    pub max_rpm: f64,
}

/// A whirling machine and its controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineProfile {
    /// Human-readable name, shown in logs and program headers.
    pub name: String,
    /// Controller language.
    pub dialect: Dialect,
    /// How the controller holds coordinates; with `f32`, C's resolution at its largest
    /// value is counted in the error budget.
    pub number: NumberType,
    /// What the controller's X words mean.
    pub x_mode: XMode,
    /// Longest G-code line the controller takes, characters without the line end
    /// (grblHAL: 256, LinuxCNC: 255); at least 32.
    pub max_line_length: usize,
    /// LinuxCNC path-blending tolerance (`G64 P`), mm: the controller's share of the
    /// error budget Δ. Absent: exact path (`G61`). Must be absent for grblHAL.
    #[serde(default)]
    pub blend_tolerance_mm: Option<f64>,
    /// The ring spindle's speed range; absent: speeds are not checked.
    #[serde(default)]
    pub spindle: Option<Spindle>,
    /// Axis travel and dynamics.
    pub axes: Axes,
    /// How the bridge reaches this machine (`[connection]`, see [`crate::config::connection`]);
    /// absent: the caller says (the command line's flags).
    #[serde(default)]
    pub connection: Option<Connection>,
}

/// Why a profile could not be loaded.
#[derive(Debug, Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("cannot read machine profile {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML is malformed or does not fit the schema (toml's message names the key
    /// and the line).
    #[error("machine profile {origin}: {source}")]
    Toml {
        /// The file (or what the text came from).
        origin: String,
        /// The TOML error.
        source: toml::de::Error,
    },
    /// A value is out of range.
    #[error("machine profile {origin}: {key}: {problem}")]
    Invalid {
        /// The file (or what the text came from).
        origin: String,
        /// The key, e.g. `axes.x.max_rate`.
        key: String,
        /// What is wrong.
        problem: String,
    },
}

impl MachineProfile {
    /// Loads and validates a profile file.
    pub fn load(path: &Path) -> Result<MachineProfile, ProfileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Read {
            path: path.to_owned(),
            source,
        })?;
        MachineProfile::from_toml(&text, &path.display().to_string())
    }

    /// The default profile, `machine-profiles/sim.toml`, built into the binary so the
    /// simulator setup works without the profile files at hand.
    pub fn builtin_sim() -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml(
            include_str!("../../machine-profiles/sim.toml"),
            "machine-profiles/sim.toml (built in)",
        )
    }

    /// Parses and validates a profile; `origin` names the text's source in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<MachineProfile, ProfileError> {
        let profile: MachineProfile =
            toml::from_str(text).map_err(|source| ProfileError::Toml {
                origin: origin.to_owned(),
                source,
            })?;
        profile
            .validate()
            .map_err(|(key, problem)| ProfileError::Invalid {
                origin: origin.to_owned(),
                key,
                problem,
            })?;
        Ok(profile)
    }

    /// The first out-of-range value, as (key, problem).
    fn validate(&self) -> Result<(), (String, String)> {
        fn positive(key: &str, value: f64) -> Result<(), (String, String)> {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err((
                    key.to_owned(),
                    format!("{value} must be a finite number above zero"),
                ))
            }
        }
        fn range(key: &str, min: Option<f64>, max: Option<f64>) -> Result<(), (String, String)> {
            for (end, value) in [("min", min), ("max", max)] {
                if let Some(value) = value.filter(|v| !v.is_finite()) {
                    return Err((
                        format!("{key}.{end}"),
                        format!("{value} is not a finite number"),
                    ));
                }
            }
            match (min, max) {
                (Some(min), Some(max)) if min >= max => Err((
                    format!("{key}.min"),
                    format!("{min} must be below {key}.max ({max})"),
                )),
                _ => Ok(()),
            }
        }
        if self.name.trim().is_empty() {
            return Err(("name".into(), "must not be empty".into()));
        }
        if self.max_line_length < MIN_LINE_LENGTH {
            return Err((
                "max_line_length".into(),
                format!(
                    "{} is below the minimum of {MIN_LINE_LENGTH}",
                    self.max_line_length
                ),
            ));
        }
        if let Some(tolerance) = self.blend_tolerance_mm {
            if self.dialect == Dialect::GrblHal {
                return Err((
                    "blend_tolerance_mm".into(),
                    "grblHAL does not blend paths; leave it out".into(),
                ));
            }
            positive("blend_tolerance_mm", tolerance)?;
        }
        if let Some(spindle) = &self.spindle {
            positive("spindle.min_rpm", spindle.min_rpm)?;
            positive("spindle.max_rpm", spindle.max_rpm)?;
            if spindle.min_rpm > spindle.max_rpm {
                return Err((
                    "spindle.min_rpm".into(),
                    format!(
                        "{} must not exceed spindle.max_rpm ({})",
                        spindle.min_rpm, spindle.max_rpm
                    ),
                ));
            }
        }
        for (key, axis) in [("axes.x", &self.axes.x), ("axes.z", &self.axes.z)] {
            range(key, Some(axis.min), Some(axis.max))?;
            positive(&format!("{key}.max_rate"), axis.max_rate)?;
            positive(&format!("{key}.accel"), axis.accel)?;
        }
        let c = &self.axes.c;
        range("axes.c", c.min, c.max)?;
        positive("axes.c.max_rate", c.max_rate)?;
        positive("axes.c.accel", c.accel)?;
        if let Some(connection) = &self.connection {
            connection.validate(self).map_err(|e| (e.key, e.problem))?;
        }
        Ok(())
    }

    /// The post settings of this machine, with decimals the planner chose from its
    /// error budget (see [`crate::post::gcode::format::decimals_for`]).
    pub fn post_settings(&self, linear_decimals: u32, angular_decimals: u32) -> PostSettings {
        PostSettings {
            dialect: self.dialect,
            linear_decimals,
            angular_decimals,
            x_diameter: self.x_diameter(),
            blend_tolerance_mm: self.blend_tolerance_mm,
            max_line_length: self.max_line_length,
        }
    }

    /// Whether the controller's X words are diameters (the post writes 2·X).
    pub fn x_diameter(&self) -> bool {
        self.x_mode == XMode::Diameter
    }

    /// The travel limits of an axis (`None` where unlimited).
    pub fn travel(&self, axis: Axis) -> (Option<f64>, Option<f64>) {
        match axis {
            Axis::X => (Some(self.axes.x.min), Some(self.axes.x.max)),
            Axis::Z => (Some(self.axes.z.min), Some(self.axes.z.max)),
            Axis::C => (self.axes.c.min, self.axes.c.max),
        }
    }

    /// The highest speed of an axis: mm/min for X and Z, deg/min for C.
    pub fn max_rate(&self, axis: Axis) -> f64 {
        match axis {
            Axis::X => self.axes.x.max_rate,
            Axis::Z => self.axes.z.max_rate,
            Axis::C => self.axes.c.max_rate,
        }
    }
}

/// An end of an axis' travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// The lower end (`min`).
    Min,
    /// The upper end (`max`).
    Max,
}

impl Bound {
    fn side(self) -> &'static str {
        match self {
            Bound::Min => "below",
            Bound::Max => "above",
        }
    }
}

impl std::fmt::Display for Bound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Bound::Min => "min",
            Bound::Max => "max",
        })
    }
}

/// Relative slack on speed limits, so a move planned exactly at the limit is not
/// refused for the last bit of floating-point rounding.
const RATE_SLACK: f64 = 1e-9;

/// A program that asks more of the machine than its profile allows.
///
/// `block` is an index into [`Program::blocks`] (0-based), not a line of a G-code file;
/// the message leaves it out, so that the caller can say where in its own terms (a file
/// line, see [`LimitError::block`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LimitError {
    /// A position outside the axis' travel.
    #[error(
        "{axis} position {value} {unit} is \
         {side} the machine's {bound} {limit} {unit} (axes.{key}.{bound})",
        unit = .axis.unit(),
        key = .axis.letter().to_ascii_lowercase(),
        side = .bound.side()
    )]
    Travel {
        /// Block index.
        block: usize,
        /// The axis.
        axis: Axis,
        /// The position (C unrebased).
        value: f64,
        /// Which end of the travel.
        bound: Bound,
        /// The limit.
        limit: f64,
    },
    /// An axis moving faster than its max rate.
    #[error(
        "{axis} speed {speed:.1} {unit}/min \
         exceeds the machine's max_rate {limit} {unit}/min (axes.{key})",
        unit = .axis.unit(),
        key = .axis.letter().to_ascii_lowercase()
    )]
    Speed {
        /// Block index.
        block: usize,
        /// The axis.
        axis: Axis,
        /// The axis speed the block asks for, per minute.
        speed: f64,
        /// The axis' max rate.
        limit: f64,
    },
    /// A feed or linked move of an axis the program has not positioned: where it starts,
    /// and so how fast it moves, is unknown.
    #[error(
        "moves {axis} at feed before any \
         block positioned {axis}, so its speed cannot be checked (position it with a rapid first)"
    )]
    Unpositioned {
        /// Block index.
        block: usize,
        /// The axis.
        axis: Axis,
    },
    /// A ring speed outside the spindle's range.
    #[error(
        "spindle speed {rpm} rpm is outside \
         the machine's range {min}..={max} rpm (spindle)"
    )]
    SpindleSpeed {
        /// Block index.
        block: usize,
        /// The speed asked for.
        rpm: f64,
        /// Lowest speed.
        min: f64,
        /// Highest speed.
        max: f64,
    },
    /// A value no machine can execute (not finite, zero or negative time or feed).
    #[error("{problem}")]
    InvalidBlock {
        /// Block index.
        block: usize,
        /// What is wrong.
        problem: String,
    },
}

impl LimitError {
    /// The block (index into [`Program::blocks`]) that asks too much.
    pub fn block(&self) -> usize {
        match self {
            LimitError::Travel { block, .. }
            | LimitError::Speed { block, .. }
            | LimitError::Unpositioned { block, .. }
            | LimitError::SpindleSpeed { block, .. }
            | LimitError::InvalidBlock { block, .. } => *block,
        }
    }
}

/// Axis speeds of a G94 feed move, per minute, under the controller's rule for sharing
/// a feed between linear and rotary axes:
///
/// - LinuxCNC (RS274/NGC): when X or Z moves, F is mm/min along the X/Z path and C
///   follows in the same time; when C moves alone, F is deg/min.
/// - grblHAL (grbl): F is the rate along the Euclidean length of all moving axes, mm and
///   degrees counted alike (grblHAL's optional rotary-axis handling is not assumed).
fn feed_speeds(dialect: Dialect, delta: [f64; 3], feed: f64) -> [f64; 3] {
    let [dx, dz, dc] = delta.map(f64::abs);
    let linear = dx.hypot(dz);
    let length = match dialect {
        Dialect::LinuxCnc if linear > 0.0 => linear,
        _ => linear.hypot(dc),
    };
    if length == 0.0 {
        return [0.0; 3];
    }
    [dx, dz, dc].map(|d| feed * d / length)
}

/// Checks that the program stays within the machine's travel and speeds.
///
/// Travel: every position a motion block reaches, for X and Z always and for C when its
/// travel is limited (C in the unrebased frame of [`Program::steps`], so G92 does not
/// hide whole turns). Moves are straight in X, Z and C, so checking the ends checks the
/// whole move. Speed: a [`Block::Linked`] moves each axis at |Δ|/minutes; a
/// [`Block::Feed`] shares its feed between the axes by the dialect's rule (LinuxCNC: F
/// along the X/Z path, C following in the same time, so a short X/Z move with a large C
/// turn can run C far faster than F; grblHAL: F along the length of all axes, mm and
/// degrees counted alike); rapids run at the machine's own rates and are not checked. Acceleration is not checked. The program's start position is taken
/// as unknown: a feed or linked move of an axis no earlier block positioned is an
/// error. Ring speeds are checked when the profile has a `[spindle]`.
///
/// Returns the first violation.
pub fn check_limits(program: &Program, profile: &MachineProfile) -> Result<(), LimitError> {
    for step in program.steps(Pose::UNKNOWN) {
        let block = step.index;
        let invalid = |problem: String| LimitError::InvalidBlock { block, problem };
        match *step.block {
            Block::SpindleOn { rpm } => {
                if let Some(spindle) = &profile.spindle {
                    if !(spindle.min_rpm..=spindle.max_rpm).contains(&rpm) {
                        return Err(LimitError::SpindleSpeed {
                            block,
                            rpm,
                            min: spindle.min_rpm,
                            max: spindle.max_rpm,
                        });
                    }
                }
                continue;
            }
            Block::Linked { minutes, .. } if !(minutes.is_finite() && minutes > 0.0) => {
                return Err(invalid(format!(
                    "move time {minutes} min is not above zero"
                )));
            }
            Block::Feed { feed, .. } if !(feed.is_finite() && feed > 0.0) => {
                return Err(invalid(format!("feed {feed} is not above zero")));
            }
            Block::RebaseC { c } if !c.is_finite() => {
                return Err(invalid(format!("G92 C value {c} is not finite")));
            }
            // Nothing to check: G92.1 moves nothing, and `steps` reads the targets after
            // it in the same continuous frame.
            Block::ClearRebase => continue,
            _ => {}
        }
        let Some(target) = step.block.target() else {
            continue;
        };
        // Travel of the axes this block moves.
        for axis in Axis::ALL {
            let (Some(_), Some(value)) = (target.get(axis), step.to.get(axis)) else {
                continue;
            };
            if !value.is_finite() {
                return Err(invalid(format!("{axis} target {value} is not finite")));
            }
            let (min, max) = profile.travel(axis);
            if let Some(limit) = min.filter(|&min| value < min) {
                return Err(LimitError::Travel {
                    block,
                    axis,
                    value,
                    bound: Bound::Min,
                    limit,
                });
            }
            if let Some(limit) = max.filter(|&max| value > max) {
                return Err(LimitError::Travel {
                    block,
                    axis,
                    value,
                    bound: Bound::Max,
                    limit,
                });
            }
        }
        // Speeds of feed and linked moves.
        let speeds = match *step.block {
            Block::Linked { minutes, .. } => {
                let delta = axis_deltas(&step.from, &step.to, &target, block)?;
                delta.map(|d| d.abs() / minutes)
            }
            Block::Feed { feed, .. } => {
                let delta = axis_deltas(&step.from, &step.to, &target, block)?;
                feed_speeds(profile.dialect, delta, feed)
            }
            _ => continue,
        };
        for (axis, speed) in Axis::ALL.into_iter().zip(speeds) {
            let limit = profile.max_rate(axis);
            if speed > limit * (1.0 + RATE_SLACK) {
                return Err(LimitError::Speed {
                    block,
                    axis,
                    speed,
                    limit,
                });
            }
        }
    }
    Ok(())
}

/// Δ per axis of a move (zero for axes the block leaves alone); an axis the block names
/// but that has no known start is [`LimitError::Unpositioned`].
fn axis_deltas(
    from: &Pose,
    to: &Pose,
    target: &Pose,
    block: usize,
) -> Result<[f64; 3], LimitError> {
    let mut delta = [0.0; 3];
    for (slot, axis) in Axis::ALL.into_iter().enumerate() {
        if target.get(axis).is_none() {
            continue;
        }
        match (from.get(axis), to.get(axis)) {
            (Some(a), Some(b)) => delta[slot] = b - a,
            _ => return Err(LimitError::Unpositioned { block, axis }),
        }
    }
    Ok(delta)
}

/// Estimated run time of the program, seconds: linked moves take their `minutes`, feed
/// moves their length over the feed (by the dialect's rule, as in [`check_limits`]),
/// rapids the time of their slowest axis at its max rate.
///
/// A lower bound: acceleration and the slow-down at junctions are ignored, and so is
/// any motion of an axis from the unknown start position to where the program first
/// puts it. Meaningful for programs that pass [`check_limits`].
pub fn cycle_time_s(program: &Program, profile: &MachineProfile) -> f64 {
    let mut minutes = 0.0;
    for step in program.steps(Pose::UNKNOWN) {
        let delta: [f64; 3] = std::array::from_fn(|slot| {
            let axis = Axis::ALL[slot];
            match (step.from.get(axis), step.to.get(axis)) {
                (Some(a), Some(b)) => b - a,
                _ => 0.0,
            }
        });
        minutes += match *step.block {
            Block::Linked { minutes, .. } => minutes,
            Block::Feed { feed, .. } => {
                // Time = distance of any moving axis / its speed.
                let speeds = feed_speeds(profile.dialect, delta, feed);
                (0..3)
                    .find(|&i| speeds[i] > 0.0)
                    .map_or(0.0, |i| delta[i].abs() / speeds[i])
            }
            Block::Rapid { .. } => Axis::ALL
                .into_iter()
                .zip(delta)
                .map(|(axis, d)| d.abs() / profile.max_rate(axis))
                .fold(0.0, f64::max),
            Block::Comment(_)
            | Block::RebaseC { .. }
            | Block::ClearRebase
            | Block::SpindleOn { .. }
            | Block::SpindleOff => 0.0,
        };
    }
    minutes * 60.0
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn profile(dialect: Dialect) -> MachineProfile {
        MachineProfile {
            name: "test".into(),
            dialect,
            number: NumberType::F32,
            x_mode: XMode::Radius,
            max_line_length: 256,
            blend_tolerance_mm: None,
            spindle: Some(Spindle {
                min_rpm: 500.0,
                max_rpm: 6000.0,
            }),
            axes: Axes {
                x: LinearAxis {
                    min: -5.0,
                    max: 160.0,
                    max_rate: 3000.0,
                    accel: 500.0,
                },
                z: LinearAxis {
                    min: -300.0,
                    max: 300.0,
                    max_rate: 3000.0,
                    accel: 500.0,
                },
                c: RotaryAxis {
                    min: None,
                    max: None,
                    max_rate: 72000.0,
                    accel: 7200.0,
                },
            },
            connection: None,
        }
    }

    fn rapid(x: f64, z: f64, c: f64) -> Block {
        Block::Rapid {
            x: Some(x),
            z: Some(z),
            c: Some(c),
        }
    }

    fn program(blocks: Vec<Block>) -> Program {
        Program { blocks }
    }

    #[test]
    fn every_profile_file_loads() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("machine-profiles");
        let mut names = Vec::new();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let profile = MachineProfile::load(&path).unwrap_or_else(|e| panic!("{e}"));
                names.push((
                    path.file_name().unwrap().to_string_lossy().into_owned(),
                    profile,
                ));
            }
        }
        names.sort_by(|a, b| a.0.cmp(&b.0));
        let files: Vec<&str> = names.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            files,
            [
                "canopen-drives.toml",
                "grblhal-lathe.toml",
                "linuxcnc-lathe.toml",
                "modbus-plc.toml",
                "sim.toml"
            ]
        );
        let sim = &names[4].1;
        assert_eq!(sim.dialect, Dialect::GrblHal);
        assert_eq!(sim.number, NumberType::F32);
        assert_eq!(sim.x_mode, XMode::Radius);
        let linuxcnc = &names[2].1;
        assert_eq!(linuxcnc.dialect, Dialect::LinuxCnc);
        assert_eq!(linuxcnc.blend_tolerance_mm, Some(0.001));
        assert_eq!(linuxcnc.x_mode, XMode::Diameter);
        assert!(linuxcnc.post_settings(3, 4).x_diameter);
        assert_eq!(&MachineProfile::builtin_sim().unwrap(), sim);
        // The G-code machines leave the connection to the caller.
        for (_, profile) in names
            .iter()
            .filter(|(n, _)| n.contains("lathe") || n == "sim.toml")
        {
            assert_eq!(profile.connection, None, "{}", profile.name);
        }

        // A PLC on Modbus TCP: segments carry radius X and machine positions, exact.
        let plc = &names[3].1;
        assert_eq!(plc.dialect, Dialect::LinuxCnc);
        assert_eq!(plc.number, NumberType::F64);
        assert_eq!(plc.x_mode, XMode::Radius);
        assert_eq!(plc.blend_tolerance_mm, None);
        let Some(Connection::ModbusTcp(tcp)) = &plc.connection else {
            panic!("{:?}", plc.connection);
        };
        assert_eq!(
            tcp.socket_addr(),
            Some(std::net::SocketAddr::from(([192, 168, 0, 10], 502)))
        );
        assert_eq!(tcp.unit, crate::protocol::modbus::map::UNIT_ID);
        assert_eq!(tcp.timeout(), std::time::Duration::from_millis(500));

        // CiA 402 drives through a CANable: 4 ms, 0.1 µm on X and Z, 2^20 counts a turn of C.
        let drives_profile = &names[0].1;
        assert_eq!(drives_profile.dialect, Dialect::LinuxCnc);
        assert_eq!(drives_profile.number, NumberType::F64);
        assert_eq!(drives_profile.x_mode, XMode::Radius);
        let Some(Connection::CanSlcan(slcan)) = &drives_profile.connection else {
            panic!("{:?}", drives_profile.connection);
        };
        assert_eq!(slcan.port, "/dev/ttyACM0");
        assert_eq!(
            slcan.slcan_bitrate(),
            Ok(crate::protocol::canopen::slcan::Bitrate::M1)
        );
        let drives = &slcan.drives;
        assert_eq!(drives.nodes, [1, 2, 3]);
        assert_eq!(drives.period(), std::time::Duration::from_millis(4));
        assert_eq!(
            drives.counts_per_unit(),
            [10_000.0, 10_000.0, f64::from(1u32 << 20) / 360.0]
        );
        assert_eq!(
            drives.session_config(),
            Ok(crate::protocol::canopen::session::SessionConfig::default())
        );
        assert_eq!(drives.spin_up(), std::time::Duration::from_secs(2));
    }

    /// Every example job plans on the two machines that are not reached by G-code, and
    /// what is planned fits their links: the register map's segments (whose 0.1 µm and
    /// 10⁻⁴° are no coarser than the decimals the planner counted), and the drives' 32-bit
    /// linear counts.
    #[test]
    fn the_examples_plan_on_the_modbus_and_can_machines() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut jobs: Vec<PathBuf> = std::fs::read_dir(root.join("examples"))
            .unwrap()
            .map(|entry| entry.unwrap().path().join("job.toml"))
            .filter(|path| path.exists())
            .collect();
        jobs.sort();
        assert_eq!(jobs.len(), 4, "{jobs:?}");
        let plc = MachineProfile::load(&root.join("machine-profiles/modbus-plc.toml")).unwrap();
        let can = MachineProfile::load(&root.join("machine-profiles/canopen-drives.toml")).unwrap();
        let drives = can
            .connection
            .as_ref()
            .and_then(Connection::drives)
            .unwrap();
        for path in &jobs {
            let job = crate::config::job::Job::load(path).unwrap();
            for machine in [&plc, &can] {
                let plan = crate::plan::plan(&job, machine)
                    .unwrap_or_else(|e| panic!("{} on {}: {e}", path.display(), machine.name));
                let [linear, angular] = plan.report.decimals;
                assert!(linear <= 4 && angular <= 4, "{path:?}: {linear}, {angular}");
                check_limits(&plan.program, machine).unwrap();
                // Modbus: every block fits a segment, and the shortest linked move is within
                // a controller that takes 55 segments a second (the profile's comment).
                let segments = crate::protocol::modbus::map::segments(&plan.program)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                crate::protocol::modbus::map::check_rate(&segments, 55)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                // CAN: X and Z stay in INTEGER32 counts, and every linked move spans at
                // least four cycles.
                for step in plan.program.steps(Pose::UNKNOWN) {
                    for (slot, axis) in [Axis::X, Axis::Z].into_iter().enumerate() {
                        if let Some(value) = step.to.get(axis) {
                            let counts = value * drives.counts_per_mm[slot];
                            assert!(counts.abs() < f64::from(i32::MAX), "{counts}");
                        }
                    }
                    if let Block::Linked { minutes, .. } = *step.block {
                        assert!(minutes * 60.0 >= 4.0 * drives.period().as_secs_f64());
                    }
                }
            }
        }
    }

    #[test]
    fn a_bad_connection_is_refused_naming_its_key() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let text =
            std::fs::read_to_string(root.join("machine-profiles/canopen-drives.toml")).unwrap();
        let bad = text.replacen("cycle_us = 4000", "cycle_us = 100", 1);
        assert_ne!(bad, text);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.toml");
        std::fs::write(&path, bad).unwrap();
        let error = MachineProfile::load(&path).unwrap_err();
        let message = error.to_string();
        assert!(
            matches!(&error, ProfileError::Invalid { key, .. } if key == "connection.drives.cycle_us"),
            "{message}"
        );
        assert!(
            message.contains("bad.toml: connection.drives.cycle_us: 100 µs must be 250 to"),
            "{message}"
        );
        // A key the table does not know is a schema error that names it.
        let unknown = text.replacen("cycle_us = 4000", "cycle_ms = 4", 1);
        let message = MachineProfile::from_toml(&unknown, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("connection.drives: unknown field `cycle_ms`"),
            "{message}"
        );
    }

    const SIM: &str = r#"
name = "sim"
dialect = "grblhal"
number = "f32"
x_mode = "radius"
max_line_length = 256
[axes.x]
min = -5.0
max = 160.0
max_rate = 3000.0
accel = 500.0
[axes.z]
min = -300.0
max = 300.0
max_rate = 3000.0
accel = 500.0
[axes.c]
max_rate = 72000.0
accel = 7200.0
"#;

    /// The key and problem of a profile `text` that parses but does not validate.
    pub(crate) fn invalid(text: &str) -> (String, String) {
        match MachineProfile::from_toml(text, "test.toml") {
            Err(ProfileError::Invalid {
                origin,
                key,
                problem,
            }) => {
                assert_eq!(origin, "test.toml");
                (key, problem)
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn values_are_validated_and_errors_name_the_key() {
        assert!(MachineProfile::from_toml(SIM, "sim").is_ok());
        let cases = [
            ("min = -5.0", "min = 170.0", "axes.x.min"),
            ("max = 300.0", "max = -300.0", "axes.z.min"),
            (
                "max_rate = 3000.0\naccel = 500.0\n[axes.z]",
                "max_rate = 0.0\naccel = 500.0\n[axes.z]",
                "axes.x.max_rate",
            ),
            ("accel = 7200.0", "accel = -1.0", "axes.c.accel"),
            ("max_rate = 72000.0", "max_rate = inf", "axes.c.max_rate"),
            (
                "max_line_length = 256",
                "max_line_length = 31",
                "max_line_length",
            ),
            (
                "accel = 7200.0",
                "accel = 7200.0\nmin = 10.0\nmax = -10.0",
                "axes.c.min",
            ),
            ("accel = 7200.0", "accel = 7200.0\nmin = nan", "axes.c.min"),
            (
                "max_line_length = 256",
                "max_line_length = 256\nblend_tolerance_mm = 0.001",
                "blend_tolerance_mm",
            ),
            ("name = \"sim\"", "name = \" \"", "name"),
            (
                "max_line_length = 256",
                "max_line_length = 256\n[spindle]\nmin_rpm = 600.0\nmax_rpm = 500.0",
                "spindle.min_rpm",
            ),
            (
                "max_line_length = 256",
                "max_line_length = 256\n[spindle]\nmin_rpm = 0.0\nmax_rpm = 500.0",
                "spindle.min_rpm",
            ),
        ];
        for (from, to, key) in cases {
            let text = SIM.replacen(from, to, 1);
            assert_ne!(text, SIM);
            let (found, problem) = invalid(&text);
            assert_eq!(found, key, "{problem}");
        }
        let linuxcnc = SIM.replace("\"grblhal\"", "\"linuxcnc\"").replace(
            "max_line_length = 256",
            "max_line_length = 256\nblend_tolerance_mm = 0.0",
        );
        assert_eq!(invalid(&linuxcnc).0, "blend_tolerance_mm");
    }

    #[test]
    fn schema_errors_name_the_file_and_the_key() {
        for (text, key) in [
            (
                SIM.replace("accel = 500.0", "accel = 500.0\nacel = 1.0"),
                "acel",
            ),
            (
                SIM.replace("dialect = \"grblhal\"", "dialect = \"mach3\""),
                "mach3",
            ),
            (SIM.replace("number = \"f32\"\n", ""), "number"),
            (
                SIM.replace("x_mode = \"radius\"", "x_mode = \"radial\""),
                "radial",
            ),
            (
                SIM.replace(
                    "max_line_length = 256",
                    "max_line_length = 256\nc_rebase_turns = 5",
                ),
                "c_rebase_turns",
            ),
        ] {
            let error = MachineProfile::from_toml(&text, "machine-profiles/x.toml").unwrap_err();
            let message = error.to_string();
            assert!(matches!(error, ProfileError::Toml { .. }));
            assert!(
                message.starts_with("machine profile machine-profiles/x.toml: "),
                "{message}"
            );
            assert!(message.contains(key), "{message}");
        }
        let missing = Path::new("/nonexistent/profile.toml");
        let error = MachineProfile::load(missing).unwrap_err();
        assert!(error.to_string().contains("/nonexistent/profile.toml"));
    }

    #[test]
    fn f32_spacing_matches_ieee754() {
        // 2^17 ≤ 180 000 < 2^18: the gap is 2^(17-23) = 2^-6.
        assert_eq!(NumberType::F32.spacing_at(180_000.0), 0.015625);
        assert_eq!(NumberType::F32.spacing_at(-1.0), f64::from(f32::EPSILON));
        assert_eq!(NumberType::F64.spacing_at(1.0), f64::EPSILON);
        assert_eq!(NumberType::F32.spacing_at(1e39), f64::INFINITY);
        assert_eq!(NumberType::F64.spacing_at(f64::NAN), f64::INFINITY);
    }

    #[test]
    fn speeds_over_the_limit_name_block_axis_value_and_limit() {
        let p = profile(Dialect::GrblHal);
        // 10 mm of X in 0.002 min is 5000 mm/min.
        let too_fast = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Linked {
                x: 20.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.002,
            },
        ]);
        let error = check_limits(&too_fast, &p).unwrap_err();
        assert_eq!(
            error,
            LimitError::Speed {
                block: 1,
                axis: Axis::X,
                speed: 5000.0,
                limit: 3000.0
            }
        );
        assert_eq!(
            error.to_string(),
            "X speed 5000.0 mm/min exceeds the machine's max_rate 3000 mm/min (axes.x)"
        );
        // C: 180° in 0.002 min is 90 000 deg/min, over 72 000.
        let c_fast = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Linked {
                x: 10.0,
                z: 0.0,
                c: 180.0,
                minutes: 0.002,
            },
        ]);
        assert!(matches!(
            check_limits(&c_fast, &p),
            Err(LimitError::Speed { axis: Axis::C, .. })
        ));
        // Exactly at the limit is allowed: 6 mm in 0.002 min = 3000 mm/min.
        let at_limit = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Linked {
                x: 16.0,
                z: 0.0,
                c: 0.0,
                minutes: 0.002,
            },
        ]);
        assert_eq!(check_limits(&at_limit, &p), Ok(()));
    }

    #[test]
    fn c_speed_is_checked_across_rebasing() {
        // G92 renames 720° as 0°; the move to 60° in the new frame is 60°, not -660°.
        let p = profile(Dialect::GrblHal);
        let prog = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Linked {
                x: 10.0,
                z: 1.0,
                c: 720.0,
                minutes: 0.011,
            },
            Block::RebaseC { c: 0.0 },
            Block::Linked {
                x: 10.0,
                z: 1.1,
                c: 60.0,
                minutes: 0.001,
            },
        ]);
        assert_eq!(check_limits(&prog, &p), Ok(()));
    }

    #[test]
    fn limits_and_cycle_time_read_c_unrebased_after_a_clear() {
        // 720° renamed as 0°, G92.1: the controller reads 720° again, so the move to 780°
        // is 60° in 0.001 min (60 000 deg/min, under 72 000), not 780°.
        let mut p = profile(Dialect::GrblHal);
        let prog = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Linked {
                x: 10.0,
                z: 1.0,
                c: 720.0,
                minutes: 0.011,
            },
            Block::RebaseC { c: 0.0 },
            Block::ClearRebase,
            Block::Linked {
                x: 10.0,
                z: 1.1,
                c: 780.0,
                minutes: 0.001,
            },
        ]);
        assert_eq!(check_limits(&prog, &p), Ok(()));
        assert!((cycle_time_s(&prog, &p) - 0.012 * 60.0).abs() < 1e-9);
        // Travel is checked in the same frame: 780° is over a limit of 750°.
        p.axes.c.max = Some(750.0);
        assert_eq!(
            check_limits(&prog, &p),
            Err(LimitError::Travel {
                block: 4,
                axis: Axis::C,
                value: 780.0,
                bound: Bound::Max,
                limit: 750.0
            })
        );
    }

    #[test]
    fn travel_is_checked_with_unrebased_c() {
        let mut p = profile(Dialect::GrblHal);
        let prog = program(vec![rapid(170.0, 0.0, 0.0)]);
        assert_eq!(
            check_limits(&prog, &p),
            Err(LimitError::Travel {
                block: 0,
                axis: Axis::X,
                value: 170.0,
                bound: Bound::Max,
                limit: 160.0
            })
        );
        let prog = program(vec![rapid(0.0, -301.0, 0.0)]);
        let error = check_limits(&prog, &p).unwrap_err();
        assert_eq!(error.block(), 0);
        assert_eq!(
            error.to_string(),
            "Z position -301 mm is below the machine's min -300 mm (axes.z.min)"
        );
        // A C axis limited to ±400°: two turns renamed to 0 are still 720° unrebased.
        p.axes.c.min = Some(-400.0);
        p.axes.c.max = Some(400.0);
        let prog = program(vec![
            rapid(10.0, 0.0, 300.0),
            Block::RebaseC { c: 0.0 },
            Block::Rapid {
                x: None,
                z: None,
                c: Some(200.0),
            },
        ]);
        assert!(matches!(
            check_limits(&prog, &p),
            Err(LimitError::Travel {
                block: 2,
                axis: Axis::C,
                bound: Bound::Max,
                ..
            })
        ));
    }

    #[test]
    fn feed_moves_share_the_feed_by_the_dialect_rule() {
        // X 3, Z 4 (5 mm) and C 180° at feed F.
        let prog = |feed| {
            program(vec![
                rapid(10.0, 0.0, 0.0),
                Block::Feed {
                    x: Some(13.0),
                    z: Some(4.0),
                    c: Some(180.0),
                    feed,
                },
            ])
        };
        // LinuxCNC: 5 mm at 1500 mm/min take 1/300 min, so C turns at 54 000 deg/min.
        // (The first rapid starts from an unknown position: it adds no time.)
        let linuxcnc = profile(Dialect::LinuxCnc);
        assert_eq!(check_limits(&prog(1500.0), &linuxcnc), Ok(()));
        assert!((cycle_time_s(&prog(1500.0), &linuxcnc) - 60.0 / 300.0).abs() < 1e-12);
        // F2100: C at 75 600 deg/min, over 72 000 (Z at 1680 mm/min is fine).
        assert_eq!(
            check_limits(&prog(2100.0), &linuxcnc),
            Err(LimitError::Speed {
                block: 1,
                axis: Axis::C,
                speed: 2100.0 * 180.0 / 5.0,
                limit: 72000.0
            })
        );
        // grbl: F runs along sqrt(3² + 4² + 180²) "units" of mm and degrees alike, so
        // C gets just under F and the same program is within limits.
        let grbl = profile(Dialect::GrblHal);
        let length = (9.0f64 + 16.0 + 180.0 * 180.0).sqrt();
        assert!((cycle_time_s(&prog(2100.0), &grbl) - length / 2100.0 * 60.0).abs() < 1e-9);
        assert_eq!(check_limits(&prog(2100.0), &grbl), Ok(()));
        // A plunge of X alone at F above the X max rate.
        let plunge = program(vec![
            rapid(10.0, 0.0, 0.0),
            Block::Feed {
                x: Some(5.0),
                z: None,
                c: None,
                feed: 3500.0,
            },
        ]);
        assert!(matches!(
            check_limits(&plunge, &grbl),
            Err(LimitError::Speed {
                block: 1,
                axis: Axis::X,
                ..
            })
        ));
    }

    #[test]
    fn moves_from_unknown_positions_and_bad_values_are_refused() {
        let p = profile(Dialect::GrblHal);
        let unpositioned = program(vec![
            Block::Rapid {
                x: Some(10.0),
                z: Some(0.0),
                c: None,
            },
            Block::Linked {
                x: 10.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.1,
            },
        ]);
        assert_eq!(
            check_limits(&unpositioned, &p),
            Err(LimitError::Unpositioned {
                block: 1,
                axis: Axis::C
            })
        );
        let cases = [
            Block::Linked {
                x: 10.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.0,
            },
            Block::Feed {
                x: Some(1.0),
                z: None,
                c: None,
                feed: f64::NAN,
            },
            Block::Rapid {
                x: Some(f64::INFINITY),
                z: None,
                c: None,
            },
            Block::RebaseC { c: f64::NAN },
        ];
        for block in cases {
            let prog = program(vec![rapid(10.0, 0.0, 0.0), block]);
            assert!(matches!(
                check_limits(&prog, &p),
                Err(LimitError::InvalidBlock { block: 1, .. })
            ));
        }
        let slow_ring = program(vec![Block::SpindleOn { rpm: 100.0 }]);
        assert_eq!(
            check_limits(&slow_ring, &p),
            Err(LimitError::SpindleSpeed {
                block: 0,
                rpm: 100.0,
                min: 500.0,
                max: 6000.0
            })
        );
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_programs_never_panic(
            blocks in proptest::collection::vec(
                (0..7u8, proptest::num::f64::ANY, proptest::num::f64::ANY, proptest::num::f64::ANY, proptest::num::f64::ANY),
                0..20,
            ),
        ) {
            let blocks = blocks.into_iter().map(|(kind, a, b, c, d)| match kind {
                0 => Block::Rapid { x: Some(a), z: Some(b).filter(|_| d > 0.0), c: Some(c) },
                1 => Block::Feed { x: Some(a), z: None, c: Some(c), feed: d },
                2 => Block::Linked { x: a, z: b, c, minutes: d },
                3 => Block::RebaseC { c: a },
                4 => Block::SpindleOn { rpm: a },
                5 => Block::ClearRebase,
                _ => Block::SpindleOff,
            }).collect();
            let prog = program(blocks);
            for dialect in [Dialect::GrblHal, Dialect::LinuxCnc] {
                let p = profile(dialect);
                let _ = check_limits(&prog, &p);
                let _ = cycle_time_s(&prog, &p);
            }
        }
    }

    #[test]
    fn cycle_time_adds_linked_feed_and_rapid_times() {
        let p = profile(Dialect::GrblHal);
        let prog = program(vec![
            rapid(10.0, 0.0, 0.0),
            // Z 300 mm at 3000 mm/min: 6 s; C 3600° at 72 000 deg/min: 3 s; slowest wins.
            rapid(10.0, 300.0, 3600.0),
            // 10 mm at 100 mm/min: 6 s.
            Block::Feed {
                x: Some(0.0),
                z: None,
                c: None,
                feed: 100.0,
            },
            Block::Linked {
                x: 0.0,
                z: 301.0,
                c: 3960.0,
                minutes: 0.5,
            },
            Block::SpindleOff,
        ]);
        assert!((cycle_time_s(&prog, &p) - (6.0 + 6.0 + 30.0)).abs() < 1e-9);
    }
}
