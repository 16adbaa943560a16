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
use std::fmt;

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
            connection.validate().map_err(|e| (e.key, e.problem))?;
            self.check_connection(connection)?;
        }
        Ok(())
    }

    /// Whether `connection` fits this machine: a serial connection streams grbl's
    /// protocol, so it needs a grblHAL dialect, and its receive buffer must hold the
    /// longest line with its line end (and the ring buffer's empty slot); CAN drives'
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
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

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
        assert!(linuxcnc.x_diameter());
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
        // The unit the register map serves (docs/modbus.md).
        assert_eq!(tcp.unit, 1);
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
        assert_eq!(slcan.bitrate, 1_000_000);
        let drives = &slcan.drives;
        assert_eq!(drives.nodes, [1, 2, 3]);
        assert_eq!(drives.period(), std::time::Duration::from_millis(4));
        assert_eq!(
            drives.counts_per_unit(),
            [10_000.0, 10_000.0, f64::from(1u32 << 20) / 360.0]
        );
        // The drives' defaults: 50 ms heartbeats, supervised at three, a 10 000-count
        // window, cyclic synchronous position.
        assert_eq!(
            drives.heartbeat_timeout(),
            std::time::Duration::from_millis(150)
        );
        assert_eq!(drives.following_error_window, 10_000);
        assert_eq!(drives.mode, crate::config::connection::DriveMode::Csp);
        assert_eq!(drives.spin_up(), std::time::Duration::from_secs(2));
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
}
