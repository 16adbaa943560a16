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
//! | `linuxcnc` | a LinuxCNC machine through `linuxcncrsh`, G-code it opens and runs | [`LinuxcncSettings`] |
//!
//! The CAN kinds share their drives' settings, a nested `[connection.drives]` table
//! ([`DriveSettings`]), whose `eds` names the drives' data sheets ([`EdsFiles`]), read
//! with the profile ([`crate::config::eds`]). Every table denies unknown keys (a key of another transport
//! included), most keys have defaults, and [`Connection::validate`] checks the values,
//! naming the key and what it must be. A profile's loading runs it, and then checks that
//! the connection fits the machine (a serial line needs grblHAL, the drives' counts must
//! hold the travel), so [`MachineProfile::load`](crate::config::machine::MachineProfile::load)
//! refuses a bad `[connection]` with the key (`connection.drives.cycle_us`). This module
//! knows nothing of machines or protocols: the CANopen session and the set-point sampler
//! take these settings as they are.
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
//!
//! One file a transport: [`serial`](SerialSettings), [`modbus`](ModbusTcpSettings) and
//! [`can`](DriveSettings).

mod can;
mod linuxcnc;
mod modbus;
mod serial;

pub use can::{
    DriveMode, DriveSettings, EdsFiles, SlcanSettings, SocketCanSettings, CAN_BITRATES,
    MAX_CYCLE_US, MIN_CYCLE_US,
};
pub use linuxcnc::LinuxcncSettings;
pub use modbus::{ModbusRtuSettings, ModbusTcpSettings, MODBUS_RTU_BAUDS};
pub use serial::SerialSettings;

use serde::{Deserialize, Serialize};
use thiserror::Error;

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
    /// `linuxcnc`: a LinuxCNC machine through `linuxcncrsh`.
    Linuxcnc(LinuxcncSettings),
}

/// The longest answer timeout or spin-up hold, ms: anything longer is taken for a unit
/// mistake.
pub const MAX_WAIT_MS: u32 = 60_000;

fn default_baud() -> u32 {
    115_200
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
pub(super) fn invalid(key: &str, problem: impl Into<String>) -> SettingError {
    SettingError {
        key: format!("connection.{key}"),
        problem: problem.into(),
    }
}

/// The `transport` values, in [`Connection`]'s order.
pub const TRANSPORTS: [&str; 6] = [
    "serial",
    "modbus-tcp",
    "modbus-rtu",
    "can-slcan",
    "can",
    "linuxcnc",
];

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
            "linuxcnc" => settings(table, &transport).map(Connection::Linuxcnc),
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
    /// `serial`, `modbus-tcp`, `modbus-rtu`, `can-slcan`, `can` or `linuxcnc`.
    pub fn transport_name(&self) -> &'static str {
        match self {
            Connection::Serial(_) => "serial",
            Connection::ModbusTcp(_) => "modbus-tcp",
            Connection::ModbusRtu(_) => "modbus-rtu",
            Connection::CanSlcan(_) => "can-slcan",
            Connection::Can(_) => "can",
            Connection::Linuxcnc(_) => "linuxcnc",
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

    /// The drives' settings of a CAN connection, to change.
    pub fn drives_mut(&mut self) -> Option<&mut DriveSettings> {
        match self {
            Connection::CanSlcan(slcan) => Some(&mut slcan.drives),
            Connection::Can(can) => Some(&mut can.drives),
            _ => None,
        }
    }

    /// Checks every value, naming the key; whether the connection fits a machine is the
    /// machine profile's check.
    ///
    /// Returns the first value out of range.
    pub fn validate(&self) -> Result<(), SettingError> {
        match self {
            Connection::Serial(serial) => serial.validate(),
            Connection::ModbusTcp(tcp) => tcp.validate(),
            Connection::ModbusRtu(rtu) => rtu.validate(),
            Connection::CanSlcan(slcan) => slcan.validate(),
            Connection::Can(can) => can.validate(),
            Connection::Linuxcnc(linuxcnc) => linuxcnc.validate(),
        }
    }
}

pub(super) fn port(key: &str, port: &str) -> Result<(), SettingError> {
    if port.trim().is_empty() {
        Err(invalid(
            key,
            "must name a serial device (`/dev/ttyACM0`, `COM3`)",
        ))
    } else {
        Ok(())
    }
}

pub(super) fn baud(key: &str, baud: u32) -> Result<(), SettingError> {
    if baud == 0 {
        Err(invalid(key, "0 must be a baud rate above zero"))
    } else {
        Ok(())
    }
}

pub(super) fn timeout(key: &str, ms: u32) -> Result<(), SettingError> {
    if (1..=MAX_WAIT_MS).contains(&ms) {
        Ok(())
    } else {
        Err(invalid(
            key,
            format!("{ms} ms must be 1 to {MAX_WAIT_MS} ms"),
        ))
    }
}

pub(super) fn list(values: &[u32]) -> String {
    values
        .iter()
        .map(u32::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests;
