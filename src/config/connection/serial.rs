//! `transport = "serial"`: G-code to a grbl/grblHAL controller on a serial line.

use serde::{Deserialize, Serialize};

use super::{baud, default_baud, port, SettingError};

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

impl SerialSettings {
    /// Checks the port and the baud rate; the receive buffer against the profile's line
    /// length is the machine profile's check.
    pub(super) fn validate(&self) -> Result<(), SettingError> {
        port("port", &self.port)?;
        baud("baud", self.baud)
    }
}
