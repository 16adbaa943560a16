//! Controller protocols as sans-I/O state machines: values in, values out.
//!
//! A protocol here never touches a port, a socket, a task or a clock. It takes the bytes
//! the transport read and the time the transport saw, and hands back the bytes to write
//! and the events that happened; [`crate`]'s async transports (and the tests, with a
//! model controller) drive it. So every rule of a protocol can be tested byte for byte,
//! and the same code runs against a real machine and the simulator.
//!
//! - [`streamer`]: streaming a G-code program to a grbl/grblHAL controller over a serial line
//!   by character counting ([`Streamer`]), with status polling, feed hold, soft reset,
//!   error and alarm handling, the rule that says when the motion after the last line has
//!   finished, and the bookkeeping that says where to resume.
//! - [`response`]: the controller's output, line by line: `ok`, `error:N`, `ALARM:N`,
//!   status reports, feedback messages, banners.
//! - [`resume`]: the modal state a program is in at a line, and the preamble that restores
//!   it (units, distance and feed modes, the G92 offset of C, the spindle).
//! - [`codes`]: what grbl's and grblHAL's error and alarm codes mean.
//! - [`feed_override`]: the feed override's real-time bytes, one step at a time, read back
//!   from `Ov:`.
//!
//! # Example
//!
//! A two-line program streamed to a controller that answers `ok` to each line:
//!
//! ```
//! use whirl::protocol::grbl::{Event, Streamer, StreamerConfig};
//!
//! let lines = vec!["G21 G90 G94".to_string(), "G1 X1 F100".to_string()];
//! let config = StreamerConfig { query_build_info: false, ..StreamerConfig::default() };
//! let mut streamer = Streamer::new(lines, config).unwrap();
//! // Both lines fit grbl's 128-byte receive buffer: they go out together.
//! assert_eq!(streamer.transmit().unwrap(), b"G21 G90 G94\nG1 X1 F100\n");
//! // The answers may arrive split anywhere.
//! streamer.receive(b"ok\r\no");
//! streamer.receive(b"k\r\n");
//! let events: Vec<Event> = streamer.events().collect();
//! assert!(events.contains(&Event::Acked { index: 1 }));
//! assert_eq!(events.last(), Some(&Event::Done));
//! ```

pub mod codes;
pub mod feed_override;
pub mod response;
pub mod resume;
pub mod streamer;

#[cfg(test)]
pub(crate) mod fake;

pub use codes::{alarm_message, error_message};
pub use response::{parse_response, BuildOptions, LineBuffer, MachineState, Response, Status};
pub use resume::{reentry_preamble, resume_preamble, ModalState, ResumeError};
pub use streamer::{
    Aux, Event, LineRef, Progress, ResumeBasis, ResumePoint, StopReason, Streamer, StreamerConfig,
    StreamerError,
};
