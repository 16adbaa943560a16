//! `transport = "can-slcan"` and `"can"`: three CiA 402 drives (X, Z, C) through a serial
//! CAN adapter or a SocketCAN interface, and their `[connection.drives]` settings.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::{baud, default_baud, invalid, list, port, SettingError, MAX_WAIT_MS};
use crate::config::eds::{Eds, EdsError};

/// `transport = "can-slcan"`: three CiA 402 drives through a serial CAN adapter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlcanSettings {
    /// The adapter's serial device (`/dev/ttyACM0`).
    pub port: String,
    /// The adapter's serial line, baud: irrelevant for USB CDC adapters (CANable,
    /// USBtin), which ignore it, but a CAN232 on a real UART needs it; above zero.
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// The CAN bit rate, bit/s: one that slcan's `S0`–`S8` select ([`CAN_BITRATES`]).
    #[serde(default = "default_bitrate")]
    pub bitrate: u32,
    /// The drives.
    pub drives: DriveSettings,
}

/// `transport = "can"`: three CiA 402 drives on a SocketCAN interface (Linux), its bit
/// rate set up with the interface (`ip link set can0 type can bitrate 1000000`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SocketCanSettings {
    /// The interface (`can0`): 1 to 15 characters, no white space or `/`.
    pub interface: String,
    /// The drives.
    pub drives: DriveSettings,
}

/// The three CiA 402 drives (X, Z, C), in cyclic synchronous position or interpolated
/// position mode: their nodes, the mode, the SYNC cycle, their scales and supervision.
/// `[connection.drives]` of the CAN transports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSettings {
    /// CANopen node ids of the X, Z and C drives: distinct, 1 to 127.
    #[serde(default = "default_nodes")]
    pub nodes: [u8; 3],
    /// The SYNC cycle, whole µs (CiA 301's 1006h holds µs): 250 to 100 000.
    #[serde(default = "default_cycle_us")]
    pub cycle_us: u32,
    /// Drive counts per mm of X and of Z (encoder counts per motor turn × turns per mm);
    /// finite, above zero.
    pub counts_per_mm: [f64; 2],
    /// Drive counts per degree of C; finite, above zero.
    pub counts_per_degree: f64,
    /// The drives' producer heartbeat (1017h), ms; not 0.
    #[serde(default = "default_heartbeat_ms")]
    pub heartbeat_ms: u16,
    /// A drive not heard from for this long is lost, ms: above `heartbeat_ms`; absent:
    /// three heartbeats.
    #[serde(default)]
    pub heartbeat_timeout_ms: Option<u32>,
    /// Following error window written to every drive (6065h), counts: 1 to 4 294 967 294
    /// (4 294 967 295 switches the drive's following-error check off).
    #[serde(default = "default_following_error_window")]
    pub following_error_window: u32,
    /// How long the motion holds after M3 for the ring to reach its speed, ms: 1 to
    /// 60 000.
    #[serde(default = "default_spin_up_ms")]
    pub spin_up_ms: u32,
    /// The drives' mode of operation: `"csp"` (the default) or `"ip"`.
    #[serde(default)]
    pub mode: DriveMode,
    /// The drives' electronic data sheets (CiA 306), which the objects the master uses
    /// are checked against before anything is sent; absent: not checked.
    #[serde(default)]
    pub eds: Option<EdsFiles>,
    /// The data sheets `eds` names, as read by [`DriveSettings::read_data_sheets`] (which
    /// a profile's loading runs), X, Z and C; `None` until then.
    #[serde(skip)]
    pub data_sheets: Option<[Arc<Eds>; 3]>,
}

/// `connection.drives.eds`: one EDS for all three drives (`eds = "drive.eds"`, one model
/// on every axis), or one each, X, Z and C in the order of `nodes` (`eds = ["x.eds",
/// "z.eds", "c.eds"]`, where the axes have drives of different models or sizes). A
/// relative path is relative to the machine profile's folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum EdsFiles {
    /// One file for every drive.
    All(PathBuf),
    /// One file each, X, Z, C.
    Each([PathBuf; 3]),
}

impl<'de> Deserialize<'de> for EdsFiles {
    /// A string or an array of three strings; anything else is refused with both forms
    /// named (the table's reader puts the key, `connection.drives.eds`, in front).
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let refuse = |what: String| {
            serde::de::Error::custom(format!(
                "{what} must be a path (`eds = \"drive.eds\"`, one EDS for all three \
                 drives) or three, X, Z and C (`eds = [\"x.eds\", \"z.eds\", \"c.eds\"]`)"
            ))
        };
        match toml::Value::deserialize(deserializer)? {
            toml::Value::String(path) => Ok(EdsFiles::All(path.into())),
            toml::Value::Array(items) => {
                let paths: Option<Vec<PathBuf>> = items
                    .iter()
                    .map(|item| item.as_str().map(PathBuf::from))
                    .collect();
                match paths.map(<[PathBuf; 3]>::try_from) {
                    Some(Ok(paths)) => Ok(EdsFiles::Each(paths)),
                    _ => Err(refuse(toml::Value::Array(items).to_string())),
                }
            }
            other => Err(refuse(other.to_string())),
        }
    }
}

impl EdsFiles {
    /// The X, Z and C drives' files.
    pub fn paths(&self) -> [&Path; 3] {
        match self {
            EdsFiles::All(path) => [path.as_path(); 3],
            EdsFiles::Each([x, z, c]) => [x.as_path(), z.as_path(), c.as_path()],
        }
    }
}

/// `connection.drives.mode`: how the set-points reach the drives, one a SYNC either way.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DriveMode {
    /// `"csp"`: cyclic synchronous position (CiA 402 mode 8), the target position 607Ah.
    #[default]
    Csp,
    /// `"ip"`: interpolated position (mode 7), 60C1h sub-index 1 with ip mode enabled.
    Ip,
}

impl<'de> Deserialize<'de> for DriveMode {
    /// `"csp"` or `"ip"`; anything else is refused with both named (the table's reader
    /// puts the key, `connection.drives.mode`, in front).
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let value = String::deserialize(deserializer)?;
        match value.as_str() {
            "csp" => Ok(DriveMode::Csp),
            "ip" => Ok(DriveMode::Ip),
            other => Err(serde::de::Error::custom(format!(
                "{other:?} must be \"csp\" (cyclic synchronous position, CiA 402 mode 8) or \
                 \"ip\" (interpolated position, mode 7)"
            ))),
        }
    }
}

impl DriveMode {
    /// The values a profile spells.
    pub const NAMES: [&'static str; 2] = ["csp", "ip"];
}

/// The CAN bit rates an slcan adapter selects with `S0`–`S8`, bit/s: CiA 301's standard
/// rates (the protocol's own table is checked against this one).
pub const CAN_BITRATES: [u32; 9] = [
    10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
];

/// The shortest SYNC cycle a connection takes, µs.
pub const MIN_CYCLE_US: u32 = 250;
/// The longest SYNC cycle a connection takes, µs.
pub const MAX_CYCLE_US: u32 = 100_000;

fn default_bitrate() -> u32 {
    1_000_000
}
fn default_nodes() -> [u8; 3] {
    [1, 2, 3]
}
fn default_cycle_us() -> u32 {
    4000
}
fn default_heartbeat_ms() -> u16 {
    50
}
fn default_following_error_window() -> u32 {
    10_000
}
fn default_spin_up_ms() -> u32 {
    2000
}

impl DriveSettings {
    /// The SYNC cycle period.
    pub fn period(&self) -> Duration {
        Duration::from_micros(u64::from(self.cycle_us))
    }

    /// Drive counts per mm (X, Z) and per degree (C), in [`Axis::ALL`](crate::config::machine::Axis::ALL)
    /// order.
    pub fn counts_per_unit(&self) -> [f64; 3] {
        [
            self.counts_per_mm[0],
            self.counts_per_mm[1],
            self.counts_per_degree,
        ]
    }

    /// The consumer heartbeat time: `heartbeat_timeout_ms`, else three heartbeats.
    pub fn heartbeat_timeout(&self) -> Duration {
        let ms = self
            .heartbeat_timeout_ms
            .unwrap_or(3 * u32::from(self.heartbeat_ms));
        Duration::from_millis(u64::from(ms))
    }

    /// The ring's spin-up hold after M3.
    pub fn spin_up(&self) -> Duration {
        Duration::from_millis(u64::from(self.spin_up_ms))
    }

    /// Reads the data sheets `eds` names, each file once, a relative path from `folder`
    /// (the machine profile's): a file that cannot be read or is not CiA 306's syntax is
    /// refused naming it (and the line). Without `eds` it reads nothing.
    pub fn read_data_sheets(&mut self, folder: &Path) -> Result<(), EdsError> {
        let Some(files) = &self.eds else {
            return Ok(());
        };
        let mut read: Vec<(&Path, Arc<Eds>)> = Vec::new();
        let mut sheets = Vec::with_capacity(3);
        for path in files.paths() {
            let sheet = match read.iter().find(|(p, _)| *p == path) {
                Some((_, sheet)) => Arc::clone(sheet),
                None => {
                    let sheet = Arc::new(Eds::load(&folder.join(path))?);
                    read.push((path, Arc::clone(&sheet)));
                    sheet
                }
            };
            sheets.push(sheet);
        }
        self.data_sheets = Some(sheets.try_into().expect("three drives"));
        Ok(())
    }

    /// Checks every value, naming the key; whether the counts hold the machine's travel
    /// is the machine profile's check.
    pub fn validate(&self) -> Result<(), SettingError> {
        for (slot, &id) in self.nodes.iter().enumerate() {
            if !(1..=127).contains(&id) {
                return Err(invalid(
                    "drives.nodes",
                    format!(
                        "{id} (the {} drive's) must be a CANopen node id, 1 to 127",
                        ["X", "Z", "C"][slot]
                    ),
                ));
            }
        }
        for i in 0..3 {
            for j in i + 1..3 {
                if self.nodes[i] == self.nodes[j] {
                    return Err(invalid(
                        "drives.nodes",
                        format!(
                            "{:?}: the X, Z and C drives must have distinct node ids \
                             (node {} appears twice)",
                            self.nodes, self.nodes[i]
                        ),
                    ));
                }
            }
        }
        if !(MIN_CYCLE_US..=MAX_CYCLE_US).contains(&self.cycle_us) {
            return Err(invalid(
                "drives.cycle_us",
                format!(
                    "{} µs must be {MIN_CYCLE_US} to {MAX_CYCLE_US} µs (whole µs)",
                    self.cycle_us
                ),
            ));
        }
        for (slot, axis) in ["X", "Z"].into_iter().enumerate() {
            let value = self.counts_per_mm[slot];
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(
                    "drives.counts_per_mm",
                    format!("{value} ({axis}) must be a finite number above zero"),
                ));
            }
        }
        let value = self.counts_per_degree;
        if !(value.is_finite() && value > 0.0) {
            return Err(invalid(
                "drives.counts_per_degree",
                format!("{value} must be a finite number above zero"),
            ));
        }
        if self.heartbeat_ms == 0 {
            return Err(invalid(
                "drives.heartbeat_ms",
                "0 must be above zero (0 switches the drives' heartbeat off, and a lost \
                 drive would go unnoticed)",
            ));
        }
        if let Some(timeout) = self.heartbeat_timeout_ms {
            if timeout <= u32::from(self.heartbeat_ms) {
                return Err(invalid(
                    "drives.heartbeat_timeout_ms",
                    format!(
                        "{timeout} ms must exceed drives.heartbeat_ms ({} ms), by a margin \
                         for the bus's latency",
                        self.heartbeat_ms
                    ),
                ));
            }
        }
        if self.following_error_window == 0 || self.following_error_window == u32::MAX {
            return Err(invalid(
                "drives.following_error_window",
                format!(
                    "{} counts must be 1 to {} (0 trips at once, {} switches the check off)",
                    self.following_error_window,
                    u32::MAX - 1,
                    u32::MAX
                ),
            ));
        }
        if !(1..=MAX_WAIT_MS).contains(&self.spin_up_ms) {
            return Err(invalid(
                "drives.spin_up_ms",
                format!(
                    "{} ms must be 1 to {MAX_WAIT_MS} ms: the ring needs time to reach its \
                     speed before the cut",
                    self.spin_up_ms
                ),
            ));
        }
        Ok(())
    }
}

impl SlcanSettings {
    pub(super) fn validate(&self) -> Result<(), SettingError> {
        port("port", &self.port)?;
        baud("baud", self.baud)?;
        if !CAN_BITRATES.contains(&self.bitrate) {
            return Err(invalid(
                "bitrate",
                format!(
                    "{} bit/s is not one of slcan's S0-S8 rates ({} bit/s)",
                    self.bitrate,
                    list(&CAN_BITRATES)
                ),
            ));
        }
        self.drives.validate()
    }
}

impl SocketCanSettings {
    pub(super) fn validate(&self) -> Result<(), SettingError> {
        let name = &self.interface;
        if name.is_empty() || name.len() > 15 || name.chars().any(|c| c.is_whitespace() || c == '/')
        {
            return Err(invalid(
                "interface",
                format!(
                    "{name:?} must be a network interface name (`can0`): 1 to 15 \
                     characters, no white space or `/`"
                ),
            ));
        }
        self.drives.validate()
    }
}
