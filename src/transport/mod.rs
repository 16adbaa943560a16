//! The async edges: where a sans-I/O protocol ([`crate::protocol::grbl`]) meets a port, a task
//! and a clock.
//!
//! A transport moves bytes and tells the time, and nothing else: every decision about what
//! to send, how the answers pair with the lines and when the stream has stopped is the
//! protocol's, so the rules stay testable byte for byte and the same code drives a real
//! controller and the simulator. What a transport adds is the run around the protocol: the
//! executed-path log ([`crate::log`]), the caller's feed hold / resume / reset, a
//! progress report, a watchdog for a silent controller, and the link's measured use.
//!
//! - [`serial`]: a G-code program streamed to a grbl/grblHAL controller over a serial line
//!   (tokio-serial), or over any byte stream ([`serial::stream`]), so tests and the dry run
//!   can use an in-memory pipe or a pseudo-terminal.
//! - [`modbus`]: segments through the register map of `docs/modbus.md`, over tokio-modbus
//!   TCP or RTU.
//! - [`can`]: set-points to three CiA 402 drives, through an slcan adapter on a serial line
//!   or a socketcan interface.

pub mod can;
pub mod modbus;
pub mod serial;

pub use serial::{
    check_program, link_utilization, stream, stream_port, Command, Ending, PreflightError,
    ProgressFn, StatusAxes, StreamError, StreamOptions, StreamOutcome, StreamProgress,
};
