//! Machine profiles: what a whirling lathe and its controller can do, and the machine's axes
//! and controller dialect that programs are checked and written against.
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
use crate::config::telemetry::TelemetrySettings;
use std::fmt;

mod block_rate;
pub use block_rate::{
    BlockRate, Family, GRBLHAL_SEGMENTS_AHEAD, GRBLHAL_TICKS_PER_SECOND,
    LINUXCNC_MIN_SEGMENT_CYCLES, LINUXCNC_TRAJ_PERIOD_S, PLC_SCAN_S,
};

/// A machine axis of the whirling lathe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Ring-centre offset from the spindle axis, mm (a radius).
    X,
    /// Axial position of the whirling unit, mm.
    Z,
    /// Workpiece turn, degrees.
    C,
}

impl Axis {
    /// The three axes in the order G-code words are written: X, Z, C.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Z, Axis::C];

    /// The G-code letter of the axis.
    pub fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Z => 'Z',
            Axis::C => 'C',
        }
    }

    /// The unit of the axis' positions: `"mm"` for X and Z, `"deg"` for C.
    pub fn unit(self) -> &'static str {
        match self {
            Axis::X | Axis::Z => "mm",
            Axis::C => "deg",
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.letter())
    }
}

/// The controller language a program is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dialect {
    /// grblHAL (grbl family): f32 coordinates, no path blending, 256-character lines.
    GrblHal,
    /// LinuxCNC (rs274ngc): f64 coordinates, path blending with `G64 P… Q…`.
    LinuxCnc,
}

impl Dialect {
    /// How many digits of a number the controller reads; grblHAL's `read_float` keeps
    /// the first nine significant digits and silently drops the rest. Every digit written
    /// counts here, leading zeros too, which errs on the safe side.
    pub fn max_number_digits(self) -> Option<usize> {
        match self {
            Dialect::GrblHal => Some(9),
            Dialect::LinuxCnc => None,
        }
    }
}

/// The shortest line limit a profile may give: every fixed line a writer writes (preamble,
/// spindle) fits, and a comment still carries a useful amount of text per line.
pub const MIN_LINE_LENGTH: usize = 32;

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
    /// Linked moves a second the controller sustains at their programmed durations; absent:
    /// its family's default ([`MachineProfile::block_rate`]). The fastest feed keeps every
    /// linked move at least its inverse long.
    #[serde(default)]
    pub max_block_rate: Option<f64>,
    /// The ring spindle's speed range; absent: speeds are not checked.
    #[serde(default)]
    pub spindle: Option<Spindle>,
    /// Axis travel and dynamics.
    pub axes: Axes,
    /// How the bridge reaches this machine (`[connection]`, see [`crate::config::connection`]);
    /// absent: the caller says (the command line's flags).
    #[serde(default)]
    pub connection: Option<Connection>,
    /// Where the bridge publishes the machine's live state (`[telemetry]`, see
    /// [`crate::config::telemetry`]); absent: nowhere, unless the command line says.
    #[serde(default)]
    pub telemetry: Option<TelemetrySettings>,
}

/// Why a profile could not be loaded.
#[derive(Debug, Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("cannot read machine profile {}: {error}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        error: std::io::Error,
    },
    /// The TOML is malformed or does not fit the schema (toml's message names the key
    /// and the line).
    #[error("machine profile {origin}: {error}")]
    Toml {
        /// The file (or what the text came from).
        origin: String,
        /// The TOML error.
        error: toml::de::Error,
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
    /// Loads and validates a profile file, and reads the drives' data sheets it names
    /// (`connection.drives.eds`, relative to the profile's folder). The telemetry's TLS
    /// files (`telemetry.tls_ca`, …) are found relative to the same folder, and read only
    /// when the telemetry starts ([`TelemetrySettings::tls`]): a bridge's private key may
    /// be readable by the bridge's user alone, and `whirl plan` has no need of it.
    pub fn load(path: &Path) -> Result<MachineProfile, ProfileError> {
        let text = std::fs::read_to_string(path).map_err(|error| ProfileError::Read {
            path: path.to_owned(),
            error,
        })?;
        let folder = path.parent().unwrap_or(Path::new(""));
        MachineProfile::from_toml_in(&text, &path.display().to_string(), folder)
    }

    /// The default profile, `machine-profiles/sim.toml`, built into the binary so the
    /// simulator setup works without the profile files at hand.
    pub fn builtin_sim() -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml(
            include_str!("../../machine-profiles/sim.toml"),
            "machine-profiles/sim.toml (built in)",
        )
    }

    /// `machine-profiles/linuxcnc-lathe.toml`, built in: the machine `whirl dry-run
    /// --controller linuxcnc` simulates unless told another.
    pub fn builtin_linuxcnc() -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml(
            include_str!("../../machine-profiles/linuxcnc-lathe.toml"),
            "machine-profiles/linuxcnc-lathe.toml (built in)",
        )
    }

    /// Parses and validates a profile; `origin` names the text's source in errors. The
    /// drives' data sheets it names (`connection.drives.eds`) are read relative to the
    /// working directory, the text having no folder of its own, and the telemetry's TLS
    /// files are found there.
    pub fn from_toml(text: &str, origin: &str) -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml_in(text, origin, Path::new(""))
    }

    /// [`MachineProfile::from_toml`], the data sheets read relative to `folder`.
    fn from_toml_in(
        text: &str,
        origin: &str,
        folder: &Path,
    ) -> Result<MachineProfile, ProfileError> {
        let mut profile: MachineProfile =
            toml::from_str(text).map_err(|error| ProfileError::Toml {
                origin: origin.to_owned(),
                error,
            })?;
        profile
            .validate()
            .map_err(|(key, problem)| ProfileError::Invalid {
                origin: origin.to_owned(),
                key,
                problem,
            })?;
        profile.telemetry = profile.telemetry.map(|t| t.in_folder(folder));
        if let Some(drives) = profile.connection.as_mut().and_then(Connection::drives_mut) {
            drives
                .read_data_sheets(folder)
                .map_err(|error| ProfileError::Invalid {
                    origin: origin.to_owned(),
                    key: "connection.drives.eds".into(),
                    problem: error.to_string(),
                })?;
        }
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
            connection.validate().map_err(|e| (e.key, e.problem))?;
            self.check_connection(connection)?;
        }
        if let Some(telemetry) = &self.telemetry {
            telemetry
                .validate()
                .map_err(|e| (format!("telemetry.{}", e.key), e.problem))?;
        }
        block_rate::check(self)?;
        Ok(())
    }

    /// Whether `connection` fits this machine: a serial connection streams grbl's
    /// protocol, so it needs a grblHAL dialect, and its receive buffer must hold the
    /// longest line with its line end (and the ring buffer's empty slot); LinuxCNC runs
    /// only LinuxCNC's G-code; CAN drives'
    /// counts must hold X's and Z's travel in INTEGER32 (their target position, 607Ah).
    fn check_connection(&self, connection: &Connection) -> Result<(), (String, String)> {
        let invalid = |key: &str, problem: String| (format!("connection.{key}"), problem);
        if let Connection::Serial(serial) = connection {
            if self.dialect != Dialect::GrblHal {
                return Err(invalid(
                    "transport",
                    format!(
                        "\"serial\" streams G-code by grbl's character counting, which only a \
                         grblHAL controller speaks (dialect is {:?})",
                        self.dialect
                    ),
                ));
            }
            if let Some(bytes) = serial.rx_buffer {
                let needed = self.max_line_length + 2;
                if bytes < needed {
                    return Err(invalid(
                        "rx_buffer",
                        format!(
                            "{bytes} bytes cannot hold a line of max_line_length ({}) \
                             characters and its line end; it must be at least {needed}",
                            self.max_line_length
                        ),
                    ));
                }
            }
        }
        if matches!(connection, Connection::Linuxcnc(_)) && self.dialect != Dialect::LinuxCnc {
            return Err(invalid(
                "transport",
                format!(
                    "\"linuxcnc\" has LinuxCNC run the program, which needs the linuxcnc \
                     dialect (dialect is {:?})",
                    self.dialect
                ),
            ));
        }
        if let Some(drives) = connection.drives() {
            for (slot, (axis, travel)) in [("X", &self.axes.x), ("Z", &self.axes.z)]
                .into_iter()
                .enumerate()
            {
                let reach = travel.min.abs().max(travel.max.abs());
                let counts = reach * drives.counts_per_mm[slot];
                if counts > f64::from(i32::MAX) {
                    return Err(invalid(
                        "drives.counts_per_mm",
                        format!(
                            "{} counts/mm puts {axis}'s travel ({reach} mm, axes.{}) at \
                             {counts:.0} counts, beyond the drives' INTEGER32 target position ({})",
                            drives.counts_per_mm[slot],
                            axis.to_ascii_lowercase(),
                            i32::MAX
                        ),
                    ));
                }
            }
        }
        Ok(())
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

    /// An axis's acceleration: mm/s² for X and Z, deg/s² for C.
    pub fn accel(&self, axis: Axis) -> f64 {
        match axis {
            Axis::X => self.axes.x.accel,
            Axis::Z => self.axes.z.accel,
            Axis::C => self.axes.c.accel,
        }
    }

    /// The time the slowest-stopping axis needs to come to rest from its max rate at its
    /// acceleration: a hold that slows the path over this long asks no axis for more.
    pub fn stop_time(&self) -> std::time::Duration {
        let seconds = Axis::ALL
            .map(|axis| self.max_rate(axis) / 60.0 / self.accel(axis))
            .into_iter()
            .fold(0.0, f64::max);
        std::time::Duration::from_secs_f64(seconds)
    }
}

#[cfg(test)]
pub(crate) mod tests;
