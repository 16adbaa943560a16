//! OPC UA for Machine Tools: each bridge can serve the monitoring part of OPC 40501-1 to
//! the shop's MES (`docs/opcua.md`): the machine's identification, its operation mode and
//! stacklight, its channel's state and feed override, the production job and program with
//! their state and run count, and an alert event for each alarm.
//!
//! Like MQTT telemetry, the server is never in the control loop: it runs on a thread and a
//! runtime of its own, and the run's telemetry thread hands it each tracker message
//! (`crate::telemetry::Observer`) without waiting.
//!
//! - [`machine_tool`]: the 40501-1 values of one machine from the tracker's messages
//!   (sans-I/O).
//! - [`nodes`]: the machines' objects and variables, their BrowseNames and namespaces.
//! - [`alert`]: an alarm as an `AlertType` event.
//! - [`security`]: endpoints, login and the server's certificate.
//! - [`server`]: the thread, the server and the feeds.

pub mod alert;
pub mod machine_tool;
pub mod nodes;
pub mod security;
pub mod server;

pub use nodes::Identity;
pub use server::{Feed, OpcUa, OpcUaError};
