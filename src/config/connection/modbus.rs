//! `transport = "modbus-tcp"` and `"modbus-rtu"`: segments through the register map of
//! `docs/modbus.md`, over TCP or a serial line.

use std::net::SocketAddr;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::{default_baud, invalid, list, port, timeout, SettingError};

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

/// The baud rates a `modbus-rtu` connection takes: the standard rates of RS-485 Modbus
/// devices (19 200 is the Modbus serial line specification's default).
pub const MODBUS_RTU_BAUDS: [u32; 9] = [
    1200, 2400, 4800, 9600, 19_200, 38_400, 57_600, 115_200, 230_400,
];

fn default_unit() -> u8 {
    1
}
fn default_timeout_ms() -> u32 {
    500
}

/// `host:port` with a port 1 to 65 535, an IPv6 address in brackets.
pub(super) fn host_port(key: &str, address: &str) -> Result<(), SettingError> {
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

impl ModbusTcpSettings {
    pub(super) fn validate(&self) -> Result<(), SettingError> {
        host_port("address", &self.address)?;
        timeout("timeout_ms", self.timeout_ms)
    }
}

impl ModbusRtuSettings {
    pub(super) fn validate(&self) -> Result<(), SettingError> {
        port("port", &self.port)?;
        if !MODBUS_RTU_BAUDS.contains(&self.baud) {
            return Err(invalid(
                "baud",
                format!(
                    "{} is not a standard Modbus RTU rate (one of {})",
                    self.baud,
                    list(&MODBUS_RTU_BAUDS)
                ),
            ));
        }
        if !(1..=247).contains(&self.unit) {
            return Err(invalid(
                "unit",
                format!(
                    "{} must be a Modbus RTU unit id, 1 to 247 (0 is broadcast)",
                    self.unit
                ),
            ));
        }
        timeout("timeout_ms", self.timeout_ms)
    }
}
