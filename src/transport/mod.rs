//! The async edges: where a sans-I/O protocol ([`crate::protocol`]) meets a port, a task
//! and a clock.
//!
//! A transport moves bytes and tells the time, and nothing else: every decision about what
//! to send, how the answers pair with the requests and when the run has stopped is the
//! protocol's, so the rules stay testable byte for byte and the same code drives a real
//! controller and the simulator. What a transport adds is the run around the protocol: the
//! executed-path log ([`crate::log`]), the caller's hold / resume / abort, a progress
//! report, a watchdog for a silent controller, and the link's measured use.
//!
//! [`stream()`] is the one entry a front end needs: a [`Posted`] program, the [`Link`] a
//! machine profile's `[connection]` names ([`Link::resolve`]), the [`Commands`] half of a
//! [`control()`] pair and a [`ProgressFn`]; it ends in an [`Outcome`]. Below it, one module a
//! transport:
//!
//! - [`serial`]: a G-code program streamed to a grbl/grblHAL controller over a serial line
//!   (tokio-serial), or over any byte stream ([`serial::stream`]), so tests and the dry run
//!   can use an in-memory pipe or a pseudo-terminal.
//! - [`modbus`]: segments through the register map of `docs/modbus.md`, over tokio-modbus
//!   TCP or RTU.
//! - [`can`]: set-points to three CiA 402 drives, through an slcan adapter on a serial line
//!   or a socketcan interface.
//! - [`linuxcnc`]: a G-code program LinuxCNC opens and runs, through `linuxcncrsh`.
//! - [`linuxcnc`]: a G-code program LinuxCNC opens and runs, through `linuxcncrsh`.

pub mod can;
pub mod control;
pub mod link;
pub mod linuxcnc;
pub mod modbus;
pub mod progress;
pub mod run;
pub mod serial;

pub use control::{control, Command, Commands, Control};
pub use link::{Link, LinkError, TransportKind};
pub use progress::{Progress, ProgressFn, Unit};
pub use run::{
    check_program, stream, Outcome, Posted, PreflightError, Resume, RunOptions, StreamError,
};
