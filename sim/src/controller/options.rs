//! How a simulated controller is built, and the check of those choices.

use crate::error::ConfigError;
use crate::record::Position;

/// How the simulated controller is built (what differs between grblHAL builds and boards).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerOptions {
    /// RX buffer size in bytes, as `$I` reports it; the ring holds one byte less, as
    /// grblHAL's drivers do. grblHAL: 1024; grbl on an AVR: 128.
    pub rx_buffer_size: usize,
    /// Planner blocks (`$398`; grblHAL's default is 100, `DEFAULT_PLANNER_BUFFER_BLOCKS` in
    /// its `config.h`; it was 35 for a long time).
    pub planner_blocks: usize,
    /// Junction deviation `$11`, mm (grbl's default 0.010).
    pub junction_deviation: f64,
    /// Wait for the queue to empty before a G92 or G54–G59 change takes effect, as
    /// grblHAL does by default (`$10` bit 8, "Buffer sync on WCO change", in its default
    /// `$10=511`; `$I` shows `W` when off).
    pub sync_on_offset_change: bool,
    /// Where the machine is at power-up (machine coordinates).
    pub start: Position,
    /// What the link does while the RX buffer is (nearly) full. `None`: a receive
    /// interrupt sees every byte the moment it arrives, so real-time bytes act whatever the
    /// buffer holds and a stored byte that finds it full is dropped (grblHAL's UART drivers,
    /// grbl on an AVR). `Some(reserve)`: the link delivers no byte, real-time ones included,
    /// while `reserve` bytes of the buffer or fewer are free; the bytes wait in the link, in
    /// order, until the main loop makes room (grblHAL's Simulator, whose `mcu.c` hands the
    /// UART a byte only while more than 100 are free; a USB CDC link holds the host back
    /// the same way; the firmware of issue 21 stopped at 0 free). A sender that fills the
    /// buffer past the reserve then gets no status report and no feed hold until a line
    /// has been read.
    pub rx_backpressure: Option<usize>,
}

impl Default for ControllerOptions {
    fn default() -> Self {
        ControllerOptions {
            rx_buffer_size: 1024,
            planner_blocks: 100,
            junction_deviation: 0.01,
            sync_on_offset_change: true,
            start: Position::default(),
            rx_backpressure: None,
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
    if let Some(reserve) = options.rx_backpressure {
        if reserve + 1 >= options.rx_buffer_size {
            return Err(ConfigError::Option {
                name: "rx_backpressure",
                value: reserve.to_string(),
                reason: "must leave room in the RX buffer: below its size less one byte",
            });
        }
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
