//! How a [`Streamer`](super::Streamer) runs ([`StreamerConfig`] and its defaults) and why
//! it refuses to be built ([`StreamerError`], from the check every line to be sent passes
//! first).

use std::time::Duration;

use thiserror::Error;

use super::events::LineRef;
use super::realtime;
use crate::protocol::grbl::resume::ResumeError;

/// Receive buffer size assumed until `$I` says otherwise: grbl 1.1 on an AVR.
pub const DEFAULT_RX_SIZE: usize = 128;

/// Status poll interval: grbl's interface document recommends at most 5 Hz.
pub const DEFAULT_POLL_INTERVAL: Duration = Duration::from_millis(200);

/// How a [`Streamer`](super::Streamer) runs.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamerConfig {
    /// The controller's serial receive buffer, bytes, until `[OPT:…]` reports it; the
    /// streamer keeps the unanswered bytes at or below one less than this.
    pub rx_size: usize,
    /// Send `$I` first and adopt the receive buffer size of its `[OPT:…]` line.
    pub query_build_info: bool,
    /// Send nothing, not even `?`, before the controller's banner: for a board that resets
    /// when its port opens and must not see a byte while booting. One that booted before
    /// the port opened prints no banner, so this waits for ever there;
    /// [`StreamerConfig::check_state`] copes with both.
    pub wait_for_banner: bool,
    /// Status report interval for [`Streamer::poll`](super::Streamer::poll); `None` never
    /// polls, and then no status report says when the motion is done
    /// ([`Event::MotionDone`](super::Event::MotionDone)).
    pub poll_interval: Option<Duration>,
    /// First program line to send (0-based). [`Streamer::new`](super::Streamer::new) sends
    /// from here as the lines are, without restoring modes;
    /// [`Streamer::resume_from`](super::Streamer::resume_from) sets it and adds the preamble
    /// that does.
    pub start_line: usize,
    /// Used by [`Streamer::resume_from`](super::Streamer::resume_from): a dwell after
    /// restarting the spindle, seconds (0: none).
    pub spin_up_dwell_s: f64,
    /// Connect first: ask the controller's state (`?`, again at every poll while no answer
    /// comes, and after every banner) and send no line before a status report says it is
    /// up; then act on the state it reports: idle goes on;
    /// held (a stop left it so) gets a soft reset, which keeps the position of a machine
    /// at rest, then goes on; in alarm stops, unless [`StreamerConfig::unlock`]; anything
    /// else (running, jogging, homing) stops. See [the streamer's docs](super#connecting-the-state-before-the-first-line).
    pub check_state: bool,
    /// With [`StreamerConfig::check_state`]: a controller in alarm is unlocked with `$X`
    /// (the operator has said the machine is fit to go on).
    pub unlock: bool,
}

impl Default for StreamerConfig {
    fn default() -> StreamerConfig {
        StreamerConfig {
            rx_size: DEFAULT_RX_SIZE,
            query_build_info: true,
            wait_for_banner: false,
            poll_interval: Some(DEFAULT_POLL_INTERVAL),
            start_line: 0,
            spin_up_dwell_s: 0.0,
            check_state: false,
            unlock: false,
        }
    }
}

/// Why a [`Streamer`](super::Streamer) could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StreamerError {
    /// A byte the controller would act on outside the line, or that would split it: a line
    /// end, a real-time command byte (`?` `!` `~` 0x18, or any byte above 0x7F, which
    /// grbl and grblHAL read as real-time overrides), or DEL (a backspace to grblHAL).
    #[error("{line}, byte {column}: {byte:#04x} cannot be streamed inside a line (line end, real-time command or DEL)")]
    ForbiddenByte {
        /// The line.
        line: LineRef,
        /// 1-based byte position.
        column: usize,
        /// The byte.
        byte: u8,
    },
    /// A line that does not fit the receive buffer even alone.
    #[error("{line} is {bytes} bytes with its line end, over the receive buffer's {budget}")]
    LineTooLong {
        /// The line.
        line: LineRef,
        /// Its length with `\n`.
        bytes: usize,
        /// The most the buffer takes.
        budget: usize,
    },
    /// The start line is past the program.
    #[error("start line index {start} is past the program's {len} lines")]
    StartBeyondEnd {
        /// The requested start.
        start: usize,
        /// Program lines.
        len: usize,
    },
    /// A receive buffer too small to hold any line.
    #[error("receive buffer of {0} bytes is too small (at least 2)")]
    RxTooSmall(usize),
    /// The resume preamble could not be built.
    #[error(transparent)]
    Resume(#[from] ResumeError),
}

/// Checks that `text` can be streamed as one line within `budget` bytes.
pub(super) fn check_line(line: LineRef, text: &str, budget: usize) -> Result<(), StreamerError> {
    if let Some((i, &byte)) = text.as_bytes().iter().enumerate().find(|(_, &b)| {
        matches!(
            b,
            b'\n' | b'\r' | realtime::STATUS | realtime::FEED_HOLD | realtime::CYCLE_START
        ) || b == realtime::SOFT_RESET
            || b >= 0x7f
    }) {
        return Err(StreamerError::ForbiddenByte {
            line,
            column: i + 1,
            byte,
        });
    }
    let bytes = text.len() + 1;
    if bytes > budget {
        return Err(StreamerError::LineTooLong {
            line,
            bytes,
            budget,
        });
    }
    Ok(())
}
