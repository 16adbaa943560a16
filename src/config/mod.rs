//! Configuration: what the user gives, read and checked.
//!
//! - [`job`]: the job file: the groove (with its profile points read and validated), the
//!   tool and the cut.
//! - [`machine`]: a machine profile: the controller's dialect and number type, travel,
//!   rates and the spindle.
//! - [`connection`]: a profile's `[connection]`: how the bridge reaches the machine.
//! - [`eds`]: a CANopen drive's electronic data sheet (CiA 306), which a CAN connection's
//!   drives are checked against.
//! - [`telemetry`]: a profile's `[telemetry]`: the MQTT broker a bridge reports to, the
//!   OPC UA server it serves, or both.
//! - [`opcua`]: the OPC UA server's address, security and login, checked.
//! - [`provenance`]: what a program was planned from (the files' hashes, Δ, the angle and
//!   the feed), as its header says it.

pub mod connection;
pub mod eds;
pub mod job;
pub mod machine;
pub mod opcua;
pub mod provenance;
pub mod telemetry;
#[cfg(test)]
pub(crate) mod testing;
