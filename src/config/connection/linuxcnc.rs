//! `transport = "linuxcnc"`: a LinuxCNC machine through its `linuxcncrsh` remote shell.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::{invalid, timeout, SettingError};

/// `transport = "linuxcnc"`: LinuxCNC's `linuxcncrsh` server (a line protocol over TCP;
/// LinuxCNC's manual, "linuxcncrsh").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinuxcncSettings {
    /// `host:port` of `linuxcncrsh` (its default port is 5007).
    #[serde(default = "default_address")]
    pub address: String,
    /// The password `hello` gives (`linuxcncrsh --connectpw`, default `EMC`).
    #[serde(default = "default_connect_password")]
    pub connect_password: String,
    /// The password `set enable` gives (`linuxcncrsh --enablepw`, default `EMCTOO`).
    #[serde(default = "default_enable_password")]
    pub enable_password: String,
    /// Whether whirl may take the machine out of E-stop and switch it on. Off by default:
    /// on a real machine that is the operator's act, at the machine; a machine found in
    /// E-stop or off is then refused, and nothing is run.
    #[serde(default)]
    pub power_on: bool,
    /// The folder, as LinuxCNC's host sees it, where whirl writes the program for
    /// LinuxCNC to open (each run a new file, never one that exists). Absent: the system's
    /// temporary folder, which is right when LinuxCNC runs on this host.
    #[serde(default)]
    pub program_dir: Option<String>,
    /// Longest wait for one answer, ms; 1 to 60 000. `linuxcncrsh` answers within a task
    /// cycle, so a silent one is wedged (a known LinuxCNC failure), not slow.
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u32,
}

fn default_address() -> String {
    "127.0.0.1:5007".into()
}
fn default_connect_password() -> String {
    "EMC".into()
}
fn default_enable_password() -> String {
    "EMCTOO".into()
}
fn default_timeout_ms() -> u32 {
    2000
}

impl Default for LinuxcncSettings {
    fn default() -> Self {
        LinuxcncSettings {
            address: default_address(),
            connect_password: default_connect_password(),
            enable_password: default_enable_password(),
            power_on: false,
            program_dir: None,
            timeout_ms: default_timeout_ms(),
        }
    }
}

impl LinuxcncSettings {
    /// The answer timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(u64::from(self.timeout_ms))
    }

    pub(super) fn validate(&self) -> Result<(), SettingError> {
        super::modbus::host_port("address", &self.address)?;
        for (key, password) in [
            ("connect_password", &self.connect_password),
            ("enable_password", &self.enable_password),
        ] {
            // linuxcncrsh splits its commands at white space: a password with a space in
            // it can never be given.
            if password.is_empty()
                || password
                    .chars()
                    .any(|c| c.is_whitespace() || c.is_control())
            {
                return Err(invalid(key, "must be one word, without spaces"));
            }
        }
        if let Some(dir) = &self.program_dir {
            if dir.trim().is_empty() {
                return Err(invalid("program_dir", "must name a folder"));
            }
        }
        timeout("timeout_ms", self.timeout_ms)
    }
}
