//! How the bridge reaches a machine: the `[connection]` table of a machine profile.
//!
//! A profile says what a machine can do ([`crate::config::machine`]); its optional `[connection]`
//! says where the controller is and how to talk to it, so that a shop's profile carries
//! "this lathe's PLC is at 192.168.0.10:502" or "these drives hang off a CANable on
//! /dev/ttyACM0 at 1 Mbit/s, 4 ms cycle". A profile without it leaves the choice to the
//! caller (the command line's flags).
//!
//! The table is a [`Connection`], one kind per transport, chosen by its `transport` key:
//!
//! | `transport` | reaches | settings |
//! | --- | --- | --- |
//! | `serial` | a grbl/grblHAL controller, G-code by character counting | [`SerialSettings`] |
//! | `modbus-tcp` | a controller serving `docs/modbus.md` over Modbus TCP | [`ModbusTcpSettings`] |
//! | `modbus-rtu` | the same over Modbus RTU (a serial line, 8N1) | [`ModbusRtuSettings`] |
//! | `can-slcan` | three CiA 402 drives through a serial (slcan) CAN adapter | [`SlcanSettings`] |
//! | `can` | the same on a SocketCAN interface | [`SocketCanSettings`] |
//!
//! The CAN kinds share their drives' settings, a nested `[connection.drives]` table
//! ([`DriveSettings`]). Every table denies unknown keys (a key of another transport
//! included), most keys have defaults, and [`Connection::validate`] checks the values,
//! naming the key and what it must be; a profile's loading runs it, so
//! [`MachineProfile::load`](crate::config::machine::MachineProfile::load) refuses a bad
//! `[connection]` with the key (`connection.drives.cycle_us`).
//!
//! ```
//! use whirl::config::connection::Connection;
//!
//! let connection: Connection = toml::from_str(
//!     r#"
//!     transport = "can-slcan"
//!     port = "/dev/ttyACM0"
//!     [drives]
//!     counts_per_mm = [10000.0, 10000.0]
//!     counts_per_degree = 2912.711111111111
//!     "#,
//! )
//! .unwrap();
//! assert_eq!(connection.transport_name(), "can-slcan");
//! let drives = connection.drives().unwrap();
//! assert_eq!(drives.period(), std::time::Duration::from_millis(4));
//! assert_eq!(drives.nodes, [1, 2, 3]);
//! ```

use std::net::SocketAddr;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::config::machine::MachineProfile;
use crate::post::gcode::writer::Dialect;
use crate::post::setpoints::SampleConfig;
use crate::protocol::canopen::cia301::NodeId;
use crate::protocol::canopen::session::{Operation, SessionConfig};
use crate::protocol::canopen::slcan::Bitrate;

/// How the bridge reaches the machine, by transport.
///
/// Serialized as a table tagged by `transport` (serde's internally tagged form). Its
/// [`Deserialize`] reads the same form through a [`toml::Table`] rather than serde's
/// derived buffering, only so that a value of the wrong type or length names its key
/// (`connection.drives.counts_per_mm: invalid length 1, expected an array of length 2`):
/// the derived code loses the key, and toml then points only at `[connection]`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "transport", rename_all = "kebab-case")]
pub enum Connection {
    /// `serial`: G-code streamed to a grbl/grblHAL controller.
    Serial(SerialSettings),
    /// `modbus-tcp`: segments through the register map of `docs/modbus.md`, Modbus TCP.
    ModbusTcp(ModbusTcpSettings),
    /// `modbus-rtu`: the same over Modbus RTU.
    ModbusRtu(ModbusRtuSettings),
    /// `can-slcan`: CiA 402 drives through a serial CAN adapter (Lawicel slcan).
    CanSlcan(SlcanSettings),
    /// `can`: CiA 402 drives on a SocketCAN interface.
    Can(SocketCanSettings),
}

/// `transport = "serial"`: a grbl/grblHAL controller on a serial line.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSettings {
    /// The port: a device (`/dev/ttyACM0`, `COM3`) or a pseudo-terminal.
    pub port: String,
    /// Baud rate (ignored by USB CDC ports, which most grblHAL boards are); above zero.
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// The controller's serial receive buffer, bytes, if known (grbl on an AVR: 128,
    /// grblHAL: typically 1024); absent: the streamer asks the controller (`$I`). It must
    /// hold the longest line the profile allows with its line end, with the ring buffer's
    /// empty slot: `max_line_length` + 2.
    #[serde(default)]
    pub rx_buffer: Option<usize>,
}

/// `transport = "modbus-tcp"`: a controller serving the register map over TCP.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusTcpSettings {
    /// `host:port`: an IP address (`192.168.0.10:502`, `[fe80::1]:502`) or a host name
    /// (`plc-3.local:502`), which the transport resolves.
    pub address: String,
    /// Modbus unit id (`docs/modbus.md` serves unit 1; a gateway in front of serial
    /// devices routes by it).
    #[serde(default = "default_unit")]
    pub unit: u8,
    /// Longest wait for one answer, ms; 1 to 60 000.
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u32,
}

/// `transport = "modbus-rtu"`: a controller serving the register map on a serial line.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusRtuSettings {
    /// The port (an RS-485 adapter's device).
    pub port: String,
    /// Baud rate, one of [`MODBUS_RTU_BAUDS`] (8N1).
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// Modbus unit id of the controller, 1 to 247 (0 is broadcast, which no one answers).
    #[serde(default = "default_unit")]
    pub unit: u8,
    /// Longest wait for one answer, ms; 1 to 60 000.
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u32,
}

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
    /// The CAN bit rate, bit/s: one that slcan's `S0`–`S8` select ([`Bitrate`]).
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

impl DriveMode {
    /// The values a profile spells.
    pub const NAMES: [&'static str; 2] = ["csp", "ip"];

    /// The session's mode of operation.
    pub fn operation(self) -> Operation {
        match self {
            DriveMode::Csp => Operation::CyclicSynchronousPosition,
            DriveMode::Ip => Operation::InterpolatedPosition,
        }
    }
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

/// The baud rates a `modbus-rtu` connection takes: the standard rates of RS-485 Modbus
/// devices (19 200 is the Modbus serial line specification's default).
pub const MODBUS_RTU_BAUDS: [u32; 9] = [
    1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200, 230_400,
];

/// The shortest SYNC cycle a connection takes, µs.
pub const MIN_CYCLE_US: u32 = 250;
/// The longest SYNC cycle a connection takes, µs.
pub const MAX_CYCLE_US: u32 = 100_000;
/// The longest answer timeout or spin-up hold, ms: anything longer is taken for a unit
/// mistake.
pub const MAX_WAIT_MS: u32 = 60_000;

fn default_baud() -> u32 {
    115_200
}
fn default_unit() -> u8 {
    1
}
fn default_timeout_ms() -> u32 {
    500
}
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

/// A connection setting out of range: its key, as a profile spells it
/// (`connection.drives.cycle_us`), and what it must be.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{key}: {problem}")]
pub struct SettingError {
    /// The key, e.g. `connection.drives.cycle_us`.
    pub key: String,
    /// What is wrong.
    pub problem: String,
}

/// A [`SettingError`] for `key` relative to `[connection]`.
fn invalid(key: &str, problem: impl Into<String>) -> SettingError {
    SettingError {
        key: format!("connection.{key}"),
        problem: problem.into(),
    }
}

/// The `transport` values, in [`Connection`]'s order.
pub const TRANSPORTS: [&str; 5] = ["serial", "modbus-tcp", "modbus-rtu", "can-slcan", "can"];

impl<'de> Deserialize<'de> for Connection {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let mut table = toml::Table::deserialize(deserializer)?;
        let transport = match table.remove("transport") {
            Some(toml::Value::String(transport)) => transport,
            Some(other) => {
                return Err(D::Error::custom(format!(
                    "connection.transport: {other} must be a string, one of {}",
                    quoted(&TRANSPORTS)
                )))
            }
            None => {
                return Err(D::Error::custom(format!(
                    "connection: missing field `transport` (one of {})",
                    quoted(&TRANSPORTS)
                )))
            }
        };
        /// The variant's settings from the rest of the table; an error names the key.
        fn settings<T: serde::de::DeserializeOwned, E: Error>(
            table: toml::Table,
            transport: &str,
        ) -> Result<T, E> {
            table.try_into().map_err(|e: toml::de::Error| {
                let message = e.message();
                // Without a span, toml's error reads "message\nin `a.b`\n".
                let keys = e
                    .to_string()
                    .strip_prefix(message)
                    .and_then(|rest| rest.trim().strip_prefix("in `"))
                    .and_then(|rest| rest.strip_suffix('`'))
                    .map(str::to_owned);
                match keys {
                    Some(keys) => E::custom(format!("connection.{keys}: {message}")),
                    None => E::custom(format!(
                        "connection: {message} (transport = \"{transport}\")"
                    )),
                }
            })
        }
        match transport.as_str() {
            "serial" => settings(table, &transport).map(Connection::Serial),
            "modbus-tcp" => settings(table, &transport).map(Connection::ModbusTcp),
            "modbus-rtu" => settings(table, &transport).map(Connection::ModbusRtu),
            "can-slcan" => settings(table, &transport).map(Connection::CanSlcan),
            "can" => settings(table, &transport).map(Connection::Can),
            other => Err(D::Error::custom(format!(
                "connection.transport: unknown transport `{other}`, expected one of {}",
                quoted(&TRANSPORTS)
            ))),
        }
    }
}

fn quoted(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

impl Connection {
    /// The transport's name as the profile, the log and the command line spell it:
    /// `serial`, `modbus-tcp`, `modbus-rtu`, `can-slcan` or `can`.
    pub fn transport_name(&self) -> &'static str {
        match self {
            Connection::Serial(_) => "serial",
            Connection::ModbusTcp(_) => "modbus-tcp",
            Connection::ModbusRtu(_) => "modbus-rtu",
            Connection::CanSlcan(_) => "can-slcan",
            Connection::Can(_) => "can",
        }
    }

    /// The drives' settings of a CAN connection.
    pub fn drives(&self) -> Option<&DriveSettings> {
        match self {
            Connection::CanSlcan(slcan) => Some(&slcan.drives),
            Connection::Can(can) => Some(&can.drives),
            _ => None,
        }
    }

    /// Checks every value, and those that depend on the machine against `machine`: a
    /// serial connection streams grbl's protocol, so it needs a grblHAL dialect, and its
    /// receive buffer must hold the profile's longest line; the drives' counts must hold
    /// X's and Z's travel in INTEGER32 (what the drives' target position 607Ah is).
    ///
    /// Returns the first value out of range.
    pub fn validate(&self, machine: &MachineProfile) -> Result<(), SettingError> {
        match self {
            Connection::Serial(serial) => {
                if machine.dialect != Dialect::GrblHal {
                    return Err(invalid(
                        "transport",
                        format!(
                            "\"serial\" streams G-code by grbl's character counting, which \
                             only a grblHAL controller speaks (dialect is {:?})",
                            machine.dialect
                        ),
                    ));
                }
                port("port", &serial.port)?;
                baud("baud", serial.baud)?;
                if let Some(bytes) = serial.rx_buffer {
                    let needed = machine.max_line_length + 2;
                    if bytes < needed {
                        return Err(invalid(
                            "rx_buffer",
                            format!(
                                "{bytes} bytes cannot hold a line of max_line_length ({}) \
                                 characters and its line end; it must be at least {needed}",
                                machine.max_line_length
                            ),
                        ));
                    }
                }
                Ok(())
            }
            Connection::ModbusTcp(tcp) => {
                host_port("address", &tcp.address)?;
                timeout("timeout_ms", tcp.timeout_ms)
            }
            Connection::ModbusRtu(rtu) => {
                port("port", &rtu.port)?;
                if !MODBUS_RTU_BAUDS.contains(&rtu.baud) {
                    return Err(invalid(
                        "baud",
                        format!(
                            "{} is not a standard Modbus RTU rate (one of {})",
                            rtu.baud,
                            list(&MODBUS_RTU_BAUDS)
                        ),
                    ));
                }
                if !(1..=247).contains(&rtu.unit) {
                    return Err(invalid(
                        "unit",
                        format!(
                            "{} must be a Modbus RTU unit id, 1 to 247 (0 is broadcast)",
                            rtu.unit
                        ),
                    ));
                }
                timeout("timeout_ms", rtu.timeout_ms)
            }
            Connection::CanSlcan(slcan) => {
                port("port", &slcan.port)?;
                baud("baud", slcan.baud)?;
                slcan.slcan_bitrate()?;
                slcan.drives.validate(machine)
            }
            Connection::Can(can) => {
                let name = &can.interface;
                if name.is_empty()
                    || name.len() > 15
                    || name.chars().any(|c| c.is_whitespace() || c == '/')
                {
                    return Err(invalid(
                        "interface",
                        format!(
                            "{name:?} must be a network interface name (`can0`): 1 to 15 \
                             characters, no white space or `/`"
                        ),
                    ));
                }
                can.drives.validate(machine)
            }
        }
    }
}

fn port(key: &str, port: &str) -> Result<(), SettingError> {
    if port.trim().is_empty() {
        Err(invalid(
            key,
            "must name a serial device (`/dev/ttyACM0`, `COM3`)",
        ))
    } else {
        Ok(())
    }
}

fn baud(key: &str, baud: u32) -> Result<(), SettingError> {
    if baud == 0 {
        Err(invalid(key, "0 must be a baud rate above zero"))
    } else {
        Ok(())
    }
}

fn timeout(key: &str, ms: u32) -> Result<(), SettingError> {
    if (1..=MAX_WAIT_MS).contains(&ms) {
        Ok(())
    } else {
        Err(invalid(
            key,
            format!("{ms} ms must be 1 to {MAX_WAIT_MS} ms"),
        ))
    }
}

/// `host:port` with a port 1 to 65 535, an IPv6 address in brackets.
fn host_port(key: &str, address: &str) -> Result<(), SettingError> {
    let bad = |why: &str| {
        invalid(
            key,
            format!("{address:?} must be host:port (`192.168.0.10:502`, `plc.local:502`): {why}"),
        )
    };
    let (host, port) = address.rsplit_once(':').ok_or_else(|| bad("no port"))?;
    match port.parse::<u16>() {
        Ok(p) if p > 0 && !port.starts_with('+') => {}
        _ => return Err(bad("the port must be 1 to 65535")),
    }
    let host = match host.strip_prefix('[') {
        Some(inner) => {
            let inner = inner
                .strip_suffix(']')
                .ok_or_else(|| bad("an IPv6 address needs its closing `]`"))?;
            inner
                .parse::<std::net::Ipv6Addr>()
                .map_err(|_| bad("not an IPv6 address in the brackets"))?;
            return Ok(());
        }
        None => host,
    };
    if host.is_empty() {
        return Err(bad("no host"));
    }
    if host.contains(':') {
        return Err(bad("an IPv6 address goes in brackets, `[fe80::1]:502`"));
    }
    if host
        .chars()
        .any(|c| !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '_'))
    {
        return Err(bad("the host is not an IP address or a host name"));
    }
    Ok(())
}

fn list(values: &[u32]) -> String {
    values
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

impl ModbusTcpSettings {
    /// The address as a socket address, if its host is an IP address (a host name is
    /// for the transport to resolve).
    pub fn socket_addr(&self) -> Option<SocketAddr> {
        self.address.parse().ok()
    }

    /// The answer timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(u64::from(self.timeout_ms))
    }
}

impl ModbusRtuSettings {
    /// The answer timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(u64::from(self.timeout_ms))
    }
}

impl SlcanSettings {
    /// The `S` rate of [`SlcanSettings::bitrate`]; an error, naming `connection.bitrate`,
    /// for a rate slcan's `S0`–`S8` do not select.
    pub fn slcan_bitrate(&self) -> Result<Bitrate, SettingError> {
        Bitrate::from_bits_per_second(self.bitrate).ok_or_else(|| {
            invalid(
                "bitrate",
                format!(
                    "{} bit/s is not one of slcan's S0-S8 rates ({} bit/s)",
                    self.bitrate,
                    list(&Bitrate::ALL.map(Bitrate::bits_per_second))
                ),
            )
        })
    }
}

impl DriveSettings {
    /// The SYNC cycle period.
    pub fn period(&self) -> Duration {
        Duration::from_micros(u64::from(self.cycle_us))
    }

    /// Drive counts per mm (X, Z) and per degree (C), in [`Axis::ALL`](crate::program::Axis::ALL)
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

    /// The node ids, checked (1 to 127); an error, naming `connection.drives.nodes`,
    /// otherwise.
    pub fn node_ids(&self) -> Result<[NodeId; 3], SettingError> {
        let mut ids = [None; 3];
        for (slot, &id) in self.nodes.iter().enumerate() {
            ids[slot] = Some(NodeId::new(id).map_err(|_| {
                invalid(
                    "drives.nodes",
                    format!(
                        "{id} (the {} drive's) must be a CANopen node id, 1 to 127",
                        ["X", "Z", "C"][slot]
                    ),
                )
            })?);
        }
        Ok(ids.map(|id| id.expect("every slot was filled")))
    }

    /// The CANopen session's configuration: these nodes, heartbeat, following error
    /// window and mode, every other setting at [`SessionConfig::default`]. An error for
    /// settings [`DriveSettings::validate`] refuses.
    pub fn session_config(&self) -> Result<SessionConfig, SettingError> {
        self.check()?;
        Ok(SessionConfig {
            nodes: self.node_ids()?,
            heartbeat_ms: self.heartbeat_ms,
            heartbeat_timeout: self.heartbeat_timeout(),
            following_error_window: self.following_error_window,
            operation: self.mode.operation(),
            ..SessionConfig::default()
        })
    }

    /// How to sample a program for these drives on `machine`: this cycle, these scales,
    /// the machine's max rates and this spin-up hold.
    pub fn sample_config(&self, machine: &MachineProfile) -> SampleConfig {
        SampleConfig::for_machine(
            machine,
            self.period(),
            self.counts_per_unit(),
            Some(self.spin_up()),
        )
    }

    /// Checks every value, and that X's and Z's travel on `machine` fits INTEGER32 counts
    /// (the drives' target position, 607Ah).
    pub fn validate(&self, machine: &MachineProfile) -> Result<(), SettingError> {
        self.check()?;
        for (slot, (axis, travel)) in [("X", &machine.axes.x), ("Z", &machine.axes.z)]
            .into_iter()
            .enumerate()
        {
            let reach = travel.min.abs().max(travel.max.abs());
            let counts = reach * self.counts_per_mm[slot];
            if counts > f64::from(i32::MAX) {
                return Err(invalid(
                    "drives.counts_per_mm",
                    format!(
                        "{} counts/mm puts {axis}'s travel ({reach} mm, axes.{}) at {counts:.0} \
                         counts, beyond the drives' INTEGER32 target position ({})",
                        self.counts_per_mm[slot],
                        axis.to_ascii_lowercase(),
                        i32::MAX
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The checks that need no machine.
    fn check(&self) -> Result<(), SettingError> {
        self.node_ids()?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::machine::ProfileError;

    /// The built-in simulated machine (grblHAL, max_line_length 256, X −5…160, Z ±300)
    /// with `connection` as its `[connection]` table (its `[drives]` tables as
    /// `[connection.drives]`).
    fn profile_text(connection: &str) -> String {
        format!(
            "{}\n[connection]\n{}\n",
            include_str!("../../machine-profiles/sim.toml"),
            connection.replace("[drives", "[connection.drives")
        )
    }

    fn load(connection: &str) -> Result<MachineProfile, ProfileError> {
        MachineProfile::from_toml(&profile_text(connection), "test.toml")
    }

    /// The key and problem of a connection that parses but does not validate.
    fn refused(connection: &str) -> (String, String) {
        crate::config::machine::tests::invalid(&profile_text(connection))
    }

    /// The message of a connection that does not parse.
    fn unparsed(connection: &str) -> String {
        match load(connection) {
            Err(error @ ProfileError::Toml { .. }) => error.to_string(),
            other => panic!("{connection}\n=> {other:?}"),
        }
    }

    const SLCAN: &str = r#"
transport = "can-slcan"
port = "/dev/ttyACM0"
[drives]
counts_per_mm = [10000.0, 10000.0]
counts_per_degree = 2912.711111111111
"#;

    const SOCKETCAN: &str = r#"
transport = "can"
interface = "can0"
[drives]
counts_per_mm = [10000.0, 10000.0]
counts_per_degree = 2912.711111111111
"#;

    #[test]
    fn minimal_tables_take_the_defaults() {
        let serial: Connection = toml::from_str("transport = \"serial\"\nport = \"COM3\"").unwrap();
        assert_eq!(
            serial,
            Connection::Serial(SerialSettings {
                port: "COM3".into(),
                baud: 115_200,
                rx_buffer: None,
            })
        );
        let tcp: Connection =
            toml::from_str("transport = \"modbus-tcp\"\naddress = \"192.168.0.10:502\"").unwrap();
        assert_eq!(
            tcp,
            Connection::ModbusTcp(ModbusTcpSettings {
                address: "192.168.0.10:502".into(),
                unit: 1,
                timeout_ms: 500,
            })
        );
        let rtu: Connection =
            toml::from_str("transport = \"modbus-rtu\"\nport = \"/dev/ttyUSB0\"").unwrap();
        assert_eq!(
            rtu,
            Connection::ModbusRtu(ModbusRtuSettings {
                port: "/dev/ttyUSB0".into(),
                baud: 115_200,
                unit: 1,
                timeout_ms: 500,
            })
        );
        let drives = DriveSettings {
            nodes: [1, 2, 3],
            cycle_us: 4000,
            counts_per_mm: [10_000.0, 10_000.0],
            counts_per_degree: 1_048_576.0 / 360.0,
            heartbeat_ms: 50,
            heartbeat_timeout_ms: None,
            following_error_window: 10_000,
            spin_up_ms: 2000,
            mode: DriveMode::Csp,
        };
        let slcan: Connection = toml::from_str(SLCAN).unwrap();
        assert_eq!(
            slcan,
            Connection::CanSlcan(SlcanSettings {
                port: "/dev/ttyACM0".into(),
                baud: 115_200,
                bitrate: 1_000_000,
                drives: drives.clone(),
            })
        );
        let can: Connection = toml::from_str(SOCKETCAN).unwrap();
        assert_eq!(
            can,
            Connection::Can(SocketCanSettings {
                interface: "can0".into(),
                drives,
            })
        );
        for (connection, name) in [
            (serial, "serial"),
            (tcp, "modbus-tcp"),
            (rtu, "modbus-rtu"),
            (slcan, "can-slcan"),
            (can, "can"),
        ] {
            assert_eq!(connection.transport_name(), name);
            assert!(TRANSPORTS.contains(&name));
            assert_eq!(
                connection.drives().is_some(),
                name.starts_with("can"),
                "{name}"
            );
            // And each loads as a profile's [connection].
            let text = toml::to_string(&connection).unwrap();
            let profile = load(&text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
            assert_eq!(profile.connection, Some(connection));
        }
    }

    #[test]
    fn every_transport_round_trips_through_toml() {
        let texts = [
            "transport = \"serial\"\nport = \"/dev/ttyACM0\"\nbaud = 250000\nrx_buffer = 1024\n",
            "transport = \"modbus-tcp\"\naddress = \"[fe80::1]:1502\"\nunit = 255\ntimeout_ms = 250\n",
            "transport = \"modbus-rtu\"\nport = \"/dev/ttyUSB0\"\nbaud = 19200\nunit = 7\n\
             timeout_ms = 1000\n",
            "transport = \"can-slcan\"\nport = \"COM4\"\nbaud = 921600\nbitrate = 500000\n\
             [drives]\nnodes = [5, 6, 7]\ncycle_us = 2000\ncounts_per_mm = [8192.0, 4096.5]\n\
             counts_per_degree = 100.0\nheartbeat_ms = 20\nheartbeat_timeout_ms = 100\n\
             following_error_window = 5000\nspin_up_ms = 3000\n",
            "transport = \"can\"\ninterface = \"vcan0\"\n[drives]\ncounts_per_mm = [1.5, 2.5]\n\
             counts_per_degree = 2912.711111111111\n",
        ];
        for text in texts {
            let connection: Connection =
                toml::from_str(text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
            let written = toml::to_string(&connection).unwrap();
            assert!(
                written.starts_with(&format!(
                    "transport = \"{}\"\n",
                    connection.transport_name()
                )),
                "{written}"
            );
            let again: Connection =
                toml::from_str(&written).unwrap_or_else(|e| panic!("{written}\n=> {e}"));
            assert_eq!(again, connection, "{written}");
            // Every value given was read, none left at its default.
            for line in text.lines().filter(|l| l.contains(" = ")) {
                let key = line.split(" = ").next().unwrap();
                assert!(written.contains(&format!("{key} = ")), "{key}: {written}");
            }
            // And in a profile, through MachineProfile's own round trip.
            let profile = load(text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
            let profile_text = toml::to_string(&profile).unwrap();
            let reloaded = MachineProfile::from_toml(&profile_text, "written").unwrap();
            assert_eq!(reloaded, profile);
        }
    }

    #[test]
    fn unknown_keys_are_refused_with_the_tag_and_in_drives() {
        // The tag itself is no unknown key to the transport's settings (it is taken off
        // before they read the rest), but a key of another transport is.
        let cases = [
            (
                "transport = \"serial\"\nport = \"a\"\nbaudrate = 9600",
                "baudrate",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"10.0.0.1:502\"\nport = \"/dev/ttyS0\"",
                "`port`",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"/dev/ttyS0\"\naddress = \"10.0.0.1:502\"",
                "`address`",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"/dev/ttyS0\"\nparity = \"even\"",
                "parity",
            ),
            (&format!("{SLCAN}\n[drives.extra]\na = 1"), "extra"),
            (
                &SLCAN.replace("\nport =", "\ninterface = \"can0\"\nport ="),
                "`interface`",
            ),
            (
                &SOCKETCAN.replace("[drives]", "bitrate = 500000\n[drives]"),
                "`bitrate`",
            ),
            (&format!("{SOCKETCAN}cycle_ms = 4"), "cycle_ms"),
        ];
        for (text, key) in cases {
            let message = unparsed(text);
            assert!(message.contains("unknown field"), "{message}");
            assert!(message.contains(key), "{message}");
            assert!(message.contains("connection"), "{message}");
            assert!(toml::from_str::<Connection>(text).is_err());
        }
        let message = unparsed(&format!("{SOCKETCAN}cycle_ms = 4"));
        assert!(
            message.starts_with("machine profile test.toml: "),
            "{message}"
        );
        assert!(
            message.contains("connection.drives: unknown field `cycle_ms`"),
            "{message}"
        );
    }

    #[test]
    fn missing_or_mistyped_keys_are_refused_naming_the_key() {
        let cases = [
            (
                "port = \"/dev/ttyACM0\"",
                "connection: missing field `transport`",
            ),
            ("transport = \"serial\"", "missing field `port`"),
            (
                "transport = \"modbus-tcp\"\nunit = 1",
                "missing field `address`",
            ),
            ("transport = \"modbus-rtu\"", "missing field `port`"),
            (
                "transport = \"can-slcan\"\nport = \"a\"",
                "missing field `drives`",
            ),
            (
                &SLCAN.replace("port = \"/dev/ttyACM0\"\n", ""),
                "missing field `port`",
            ),
            (
                &SOCKETCAN.replace("interface = \"can0\"\n", ""),
                "missing field `interface`",
            ),
            (
                &SOCKETCAN.replace("counts_per_mm = [10000.0, 10000.0]\n", ""),
                "connection.drives: missing field `counts_per_mm`",
            ),
            (
                &SOCKETCAN.replace("counts_per_degree = 2912.711111111111\n", ""),
                "connection.drives: missing field `counts_per_degree`",
            ),
            (
                "transport = \"modbus\"\nport = \"a\"",
                "connection.transport: unknown transport `modbus`, expected one of `serial`",
            ),
            (
                "transport = 3\nport = \"a\"",
                "connection.transport: 3 must be a string",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 300",
                "connection.unit: invalid value: integer `300`, expected u8",
            ),
            (
                "transport = \"serial\"\nport = \"a\"\nbaud = \"fast\"",
                "connection.baud: invalid type: string \"fast\"",
            ),
            (
                &SOCKETCAN.replace("[10000.0, 10000.0]", "[10000.0]"),
                "connection.drives.counts_per_mm: invalid length 1",
            ),
            (
                &format!("{SOCKETCAN}nodes = [1, 2, 3, 4]"),
                "connection.drives.nodes: invalid length 4",
            ),
            (
                &format!("{SOCKETCAN}heartbeat_ms = 70000"),
                "connection.drives.heartbeat_ms: invalid value: integer `70000`",
            ),
        ];
        for (text, expected) in cases {
            let message = unparsed(text);
            assert!(message.contains(expected), "{expected}\n{message}");
        }
    }

    #[test]
    fn values_are_validated_and_errors_name_the_key() {
        let slcan_with = |key: &str| format!("{SLCAN}{key}\n");
        let can_with = |key: &str| format!("{SOCKETCAN}{key}\n");
        let cases: Vec<(String, &str, &str)> = vec![
            // serial
            (
                "transport = \"serial\"\nport = \" \"".into(),
                "connection.port",
                "serial device",
            ),
            (
                "transport = \"serial\"\nport = \"a\"\nbaud = 0".into(),
                "connection.baud",
                "above zero",
            ),
            (
                "transport = \"serial\"\nport = \"a\"\nrx_buffer = 128".into(),
                "connection.rx_buffer",
                "at least 258",
            ),
            // modbus-tcp
            (
                "transport = \"modbus-tcp\"\naddress = \"192.168.0.10\"".into(),
                "connection.address",
                "no port",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"192.168.0.10:0\"".into(),
                "connection.address",
                "1 to 65535",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"192.168.0.10:70000\"".into(),
                "connection.address",
                "1 to 65535",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \":502\"".into(),
                "connection.address",
                "no host",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"fe80::1:502\"".into(),
                "connection.address",
                "in brackets",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"[fe80::1:502\"".into(),
                "connection.address",
                "closing",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"[fe80::zz]:502\"".into(),
                "connection.address",
                "IPv6",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"plc 3:502\"".into(),
                "connection.address",
                "host name",
            ),
            (
                "transport = \"modbus-tcp\"\naddress = \"10.0.0.1:502\"\ntimeout_ms = 0".into(),
                "connection.timeout_ms",
                "1 to 60000",
            ),
            // modbus-rtu
            (
                "transport = \"modbus-rtu\"\nport = \"\"".into(),
                "connection.port",
                "serial device",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"a\"\nbaud = 100000".into(),
                "connection.baud",
                "19200",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 0".into(),
                "connection.unit",
                "1 to 247",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 248".into(),
                "connection.unit",
                "1 to 247",
            ),
            (
                "transport = \"modbus-rtu\"\nport = \"a\"\ntimeout_ms = 60001".into(),
                "connection.timeout_ms",
                "1 to 60000",
            ),
            // can-slcan
            (
                SLCAN.replace("\"/dev/ttyACM0\"", "\"\""),
                "connection.port",
                "serial device",
            ),
            (
                SLCAN.replace("[drives]", "baud = 0\n[drives]"),
                "connection.baud",
                "above zero",
            ),
            (
                SLCAN.replace("[drives]", "bitrate = 300000\n[drives]"),
                "connection.bitrate",
                "S0-S8",
            ),
            // can
            (
                SOCKETCAN.replace("\"can0\"", "\"\""),
                "connection.interface",
                "1 to 15",
            ),
            (
                SOCKETCAN.replace("\"can0\"", "\"can0 \""),
                "connection.interface",
                "white space",
            ),
            (
                SOCKETCAN.replace("\"can0\"", "\"a-very-long-can-name\""),
                "connection.interface",
                "1 to 15",
            ),
            (
                SOCKETCAN.replace("\"can0\"", "\"/dev/can0\""),
                "connection.interface",
                "`/`",
            ),
            // drives, through either CAN transport
            (
                slcan_with("nodes = [0, 2, 3]"),
                "connection.drives.nodes",
                "1 to 127",
            ),
            (
                can_with("nodes = [1, 2, 128]"),
                "connection.drives.nodes",
                "C drive's",
            ),
            (
                can_with("nodes = [1, 2, 1]"),
                "connection.drives.nodes",
                "distinct",
            ),
            (
                slcan_with("cycle_us = 249"),
                "connection.drives.cycle_us",
                "250 to 100000",
            ),
            (
                can_with("cycle_us = 100001"),
                "connection.drives.cycle_us",
                "250 to 100000",
            ),
            (
                SLCAN.replace("[10000.0, 10000.0]", "[10000.0, 0.0]"),
                "connection.drives.counts_per_mm",
                "(Z) must be a finite number above zero",
            ),
            (
                SOCKETCAN.replace("[10000.0, 10000.0]", "[-1.0, 10000.0]"),
                "connection.drives.counts_per_mm",
                "(X)",
            ),
            (
                SOCKETCAN.replace("[10000.0, 10000.0]", "[inf, 10000.0]"),
                "connection.drives.counts_per_mm",
                "finite",
            ),
            (
                SOCKETCAN.replace("2912.711111111111", "nan"),
                "connection.drives.counts_per_degree",
                "finite",
            ),
            (
                SLCAN.replace("2912.711111111111", "0.0"),
                "connection.drives.counts_per_degree",
                "above zero",
            ),
            (
                can_with("heartbeat_ms = 0"),
                "connection.drives.heartbeat_ms",
                "above zero",
            ),
            (
                can_with("heartbeat_ms = 100\nheartbeat_timeout_ms = 100"),
                "connection.drives.heartbeat_timeout_ms",
                "exceed drives.heartbeat_ms (100 ms)",
            ),
            (
                slcan_with("heartbeat_timeout_ms = 40"),
                "connection.drives.heartbeat_timeout_ms",
                "exceed",
            ),
            (
                can_with("following_error_window = 0"),
                "connection.drives.following_error_window",
                "trips at once",
            ),
            (
                can_with("following_error_window = 4294967295"),
                "connection.drives.following_error_window",
                "switches the check off",
            ),
            (
                slcan_with("spin_up_ms = 0"),
                "connection.drives.spin_up_ms",
                "1 to 60000",
            ),
            (
                can_with("spin_up_ms = 60001"),
                "connection.drives.spin_up_ms",
                "1 to 60000",
            ),
            // sim.toml's Z reaches 300 mm: 300 × 10⁷ counts is beyond INTEGER32.
            (
                SOCKETCAN.replace("[10000.0, 10000.0]", "[10000.0, 10000000.0]"),
                "connection.drives.counts_per_mm",
                "Z's travel (300 mm, axes.z)",
            ),
        ];
        for (text, key, problem_part) in cases {
            let (found, problem) = refused(&text);
            assert_eq!(found, key, "{text}\n{problem}");
            assert!(
                problem.contains(problem_part),
                "{problem_part:?} not in {problem:?}"
            );
            let message = load(&text).unwrap_err().to_string();
            assert!(
                message.starts_with(&format!("machine profile test.toml: {key}: ")),
                "{message}"
            );
        }
        // A serial connection needs grbl's streaming protocol: not LinuxCNC.
        let linuxcnc = profile_text("transport = \"serial\"\nport = \"a\"")
            .replace("dialect = \"grblhal\"", "dialect = \"linuxcnc\"");
        match MachineProfile::from_toml(&linuxcnc, "test.toml") {
            Err(ProfileError::Invalid { key, problem, .. }) => {
                assert_eq!(key, "connection.transport");
                assert!(problem.contains("grblHAL"), "{problem}");
            }
            other => panic!("{other:?}"),
        }
        // The edges that are allowed.
        for text in [
            "transport = \"serial\"\nport = \"a\"\nrx_buffer = 258".to_owned(),
            "transport = \"modbus-tcp\"\naddress = \"plc-3.local:502\"\ntimeout_ms = 60000"
                .to_owned(),
            "transport = \"modbus-tcp\"\naddress = \"[::1]:65535\"\nunit = 0".to_owned(),
            "transport = \"modbus-rtu\"\nport = \"a\"\nbaud = 1200\nunit = 247".to_owned(),
            SLCAN.replace("[drives]", "bitrate = 10000\n[drives]"),
            can_with("nodes = [127, 1, 64]\ncycle_us = 250"),
            can_with("cycle_us = 100000\nheartbeat_ms = 1\nheartbeat_timeout_ms = 2"),
            can_with("following_error_window = 4294967294\nspin_up_ms = 60000"),
            SOCKETCAN.replace("\"can0\"", "\"can_fifteen_chr\""),
        ] {
            load(&text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
        }
    }

    #[test]
    fn drive_settings_convert_to_the_session_and_the_sampler() {
        let Connection::CanSlcan(slcan) = toml::from_str(SLCAN).unwrap() else {
            panic!("can-slcan");
        };
        assert_eq!(slcan.slcan_bitrate(), Ok(Bitrate::M1));
        let drives = &slcan.drives;
        assert_eq!(drives.period(), Duration::from_micros(4000));
        assert_eq!(
            drives.counts_per_unit(),
            [10_000.0, 10_000.0, 1_048_576.0 / 360.0]
        );
        assert_eq!(drives.heartbeat_timeout(), Duration::from_millis(150));
        assert_eq!(drives.spin_up(), Duration::from_secs(2));
        // The session's own defaults are this default: nodes 1-3, 50 ms heartbeat
        // supervised at 150 ms, a 10 000-count window.
        assert_eq!(drives.session_config(), Ok(SessionConfig::default()));

        let mut other = drives.clone();
        other.nodes = [10, 20, 30];
        other.heartbeat_ms = 20;
        other.heartbeat_timeout_ms = Some(70);
        other.following_error_window = 2500;
        let config = other.session_config().unwrap();
        assert_eq!(config.nodes.map(NodeId::get), [10, 20, 30]);
        assert_eq!(config.heartbeat_ms, 20);
        assert_eq!(config.heartbeat_timeout, Duration::from_millis(70));
        assert_eq!(config.following_error_window, 2500);
        assert_eq!(
            SessionConfig {
                nodes: SessionConfig::default().nodes,
                heartbeat_ms: 50,
                heartbeat_timeout: Duration::from_millis(150),
                following_error_window: 10_000,
                ..config
            },
            SessionConfig::default()
        );
        other.heartbeat_timeout_ms = None;
        assert_eq!(other.heartbeat_timeout(), Duration::from_millis(60));

        // Settings validation refuses make no session.
        for (change, key) in [
            (
                (|d: &mut DriveSettings| d.nodes = [1, 0, 3]) as fn(&mut DriveSettings),
                "connection.drives.nodes",
            ),
            (|d| d.nodes = [4, 4, 5], "connection.drives.nodes"),
            (|d| d.heartbeat_ms = 0, "connection.drives.heartbeat_ms"),
            (|d| d.cycle_us = 0, "connection.drives.cycle_us"),
        ] {
            let mut bad = drives.clone();
            change(&mut bad);
            assert_eq!(bad.session_config().unwrap_err().key, key);
        }

        let machine = MachineProfile::builtin_sim().unwrap();
        let sample = drives.sample_config(&machine);
        assert_eq!(sample.period, Duration::from_millis(4));
        assert_eq!(sample.counts_per_unit, drives.counts_per_unit());
        assert_eq!(sample.max_rate, [3000.0, 3000.0, 72_000.0]);
        assert_eq!(sample.spin_up, Some(Duration::from_secs(2)));

        let mut rate = slcan.clone();
        rate.bitrate = 125_000;
        assert_eq!(rate.slcan_bitrate(), Ok(Bitrate::K125));
        rate.bitrate = 1_000;
        assert_eq!(rate.slcan_bitrate().unwrap_err().key, "connection.bitrate");
    }

    #[test]
    fn the_drives_mode_selects_the_sessions_operation() {
        // Absent: cyclic synchronous position, as before the key existed.
        let drives = |text: &str| {
            let connection: Connection = toml::from_str(text).unwrap();
            connection.drives().unwrap().clone()
        };
        let csp = drives(SLCAN);
        assert_eq!(csp.mode, DriveMode::Csp);
        assert_eq!(
            csp.session_config().unwrap().operation,
            Operation::CyclicSynchronousPosition
        );
        assert_eq!(drives(&format!("{SLCAN}mode = \"csp\"\n")), csp);
        // "ip": interpolated position, everything else alike.
        let text = format!("{SOCKETCAN}mode = \"ip\"\n");
        let ip = drives(&text);
        assert_eq!(ip.mode, DriveMode::Ip);
        assert_eq!(
            ip.session_config().unwrap(),
            SessionConfig {
                operation: Operation::InterpolatedPosition,
                ..csp.session_config().unwrap()
            }
        );
        assert_eq!(
            DriveMode::NAMES.map(|n| format!("{n:?}")),
            ["\"csp\"", "\"ip\""]
        );
        // Written back as the profile spells it, and loaded in a profile.
        let connection: Connection = toml::from_str(&text).unwrap();
        let written = toml::to_string(&connection).unwrap();
        assert!(written.contains("mode = \"ip\""), "{written}");
        let profile = load(&text).unwrap();
        assert_eq!(profile.connection, Some(connection));
        // Anything else is refused, naming the key and the two values.
        for (value, shown) in [("\"pp\"", "\"pp\""), ("\"IP\"", "\"IP\""), ("7", "")] {
            let message = unparsed(&format!("{SLCAN}mode = {value}\n"));
            assert!(
                message.contains("connection.drives.mode: "),
                "{value}: {message}"
            );
            if !shown.is_empty() {
                assert!(
                    message.contains(&format!(
                        "{shown} must be \"csp\" (cyclic synchronous position, CiA 402 \
                         mode 8) or \"ip\" (interpolated position, mode 7)"
                    )),
                    "{message}"
                );
            }
        }
    }

    #[test]
    fn modbus_settings_give_the_address_and_timeout() {
        let tcp = ModbusTcpSettings {
            address: "192.168.0.10:502".into(),
            unit: 1,
            timeout_ms: 250,
        };
        assert_eq!(
            tcp.socket_addr(),
            Some(SocketAddr::from(([192, 168, 0, 10], 502)))
        );
        assert_eq!(tcp.timeout(), Duration::from_millis(250));
        let v6 = ModbusTcpSettings {
            address: "[::1]:1502".into(),
            ..tcp.clone()
        };
        assert_eq!(
            v6.socket_addr(),
            Some(SocketAddr::from((std::net::Ipv6Addr::LOCALHOST, 1502)))
        );
        // A host name is valid, but for the transport to resolve.
        let named = ModbusTcpSettings {
            address: "plc-3.local:502".into(),
            ..tcp
        };
        assert_eq!(named.socket_addr(), None);
        let rtu = ModbusRtuSettings {
            port: "/dev/ttyUSB0".into(),
            baud: 19_200,
            unit: 1,
            timeout_ms: 1000,
        };
        assert_eq!(rtu.timeout(), Duration::from_secs(1));
    }
}
