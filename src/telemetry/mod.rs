//! Live telemetry: each bridge publishes its machine's state on the shop's MQTT broker, so
//! that the office, the next machine and the shop overview see which machines cut, which
//! are held, which alarmed, and how far each run is (`docs/shop.md`).
//!
//! Telemetry is never in the control loop. The run hands its log events (through the
//! log's tap) and its progress to a thread of telemetry's own without waiting; the thread
//! follows the machine's state ([`tracker`]), keeps what must be delivered in order while
//! the broker is away ([`outbox`]) and talks to the broker ([`mqtt`]). A broker that is
//! down, slow or refuses the login is said once and waited for; no line, segment or
//! set-point waits for it.
//!
//! - [`message`]: the topics and their JSON payloads.
//! - [`tracker`]: the machine's state from a run's log events and progress (sans-I/O).
//! - [`outbox`]: the queue, its order, acknowledgements and reconnections (sans-I/O).
//! - [`mqtt`]: the thread and its MQTT connection (if `[telemetry]` names a broker), and
//!   the [`Observer`] that also reads the tracker's messages (the OPC UA server's feed).

pub mod message;
pub mod mqtt;
pub mod outbox;
pub mod tracker;

pub use mqtt::{Closed, Handle, Observer, StartError, Telemetry};
pub use tracker::RunContext;
