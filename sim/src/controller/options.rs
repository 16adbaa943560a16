//! How a simulated controller is built, and the check of those choices.

use crate::error::ConfigError;
use crate::record::Position;

/// How the simulated controller is built (what differs between grblHAL builds and boards).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerOptions {
    /// RX buffer size in bytes, as `$I` reports it; the ring holds one byte less, as
    /// grblHAL's drivers do. grblHAL: 1024; grbl on an AVR: 128.
    pub rx_buffer_size: usize,
    /// Planner blocks (`$398`; grblHAL's long-time default 35).
    pub planner_blocks: usize,
    /// Junction deviation `$11`, mm (grbl's default 0.010).
    pub junction_deviation: f64,
    /// Wait for the queue to empty before a G92 or G54–G59 change takes effect, as
    /// grblHAL does by default (`$10` bit 8, "Buffer sync on WCO change", in its default
    /// `$10=511`; `$I` shows `W` when off).
    pub sync_on_offset_change: bool,
    /// Where the machine is at power-up (machine coordinates).
    pub start: Position,
}

impl Default for ControllerOptions {
    fn default() -> Self {
        ControllerOptions {
            rx_buffer_size: 1024,
            planner_blocks: 35,
            junction_deviation: 0.01,
            sync_on_offset_change: true,
            start: Position::default(),
        }
    }
}

pub(super) fn check_options(options: &ControllerOptions) -> Result<(), ConfigError> {
    if options.rx_buffer_size < 2 {
        return Err(ConfigError::Option {
            name: "rx_buffer_size",
            value: options.rx_buffer_size.to_string(),
            reason: "must be at least 2 (the ring keeps one byte free)",
        });
    }
    if options.planner_blocks == 0 {
        return Err(ConfigError::Option {
            name: "planner_blocks",
            value: "0".into(),
            reason: "must be at least 1",
        });
    }
    if !(options.junction_deviation.is_finite() && options.junction_deviation >= 0.0) {
        return Err(ConfigError::Option {
            name: "junction_deviation",
            value: options.junction_deviation.to_string(),
            reason: "must be a finite number of mm, zero or more",
        });
    }
    if !options.start.to_array().iter().all(|v| v.is_finite()) {
        return Err(ConfigError::Option {
            name: "start",
            value: format!("{:?}", options.start),
            reason: "must be a finite position",
        });
    }
    Ok(())
}
