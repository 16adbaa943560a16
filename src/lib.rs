//! whirl: a machine-controller bridge for thread-whirling lathes.
//!
//! A ring of inserts spins fast around a slowly turning workpiece; with standard (round-nose)
//! inserts the machine must link C (workpiece turn), X (ring-centre offset) and Z (axial feed)
//! so that the ring envelops the groove's profile. This crate plans that linkage from the
//! groove and the tool, chooses as few segments as keep the profile error within the allowable
//! error Δ, and writes the program for the machine's controller.
//!
//! The model, frames and sign conventions are those of `docs/kinematics.md`.
//!
//! # Data flow, and where each stage lives
//!
//! ```text
//! config      job.toml (+ profile points) and machine profile, read and checked
//!   → plan    linkage table X(ψ) → interference → error budget → nodes → path
//!   → program the neutral planned path: moves in one continuous frame
//!   → post    G-code text | Modbus segments | CANopen set-points
//!   → protocol  sans-I/O grbl streamer | Modbus ring writer | CANopen master
//!   → transport async edges: serial, Modbus TCP/RTU, CAN (slcan, socketcan)
//!   → log     the executed-path log
//! judge       verify, the simulator's Δ guard, dry runs: measures what was cut
//! ```
//!
//! Each stage is a folder named after it. Below them all, [`geometry`] holds the
//! mathematics (profile curves, the linkage, numerics). Every stage but the transports
//! is plain synchronous code of values; [`plan::plan`] runs the planner's steps in order
//! and refuses, with the place and the cause, before anything is written.
//!
//! # Modules, in the order they may import each other
//!
//! - [`geometry`]: profiles, the linkage of `docs/kinematics.md`, root finding, minimising.
//! - [`config`]: the job, machine profiles and their `[connection]`.
//! - [`program`]: the neutral planned path.
//! - [`post`]: the program in a controller's form.
//! - [`plan`]: job + machine → a checked program and its report.
//! - [`protocol`]: sans-I/O controller protocols.
//! - [`log`]: the executed-path log (JSON lines) and its summary.
//! - [`transport`]: the async edges that move a protocol's bytes.
//! - [`judge`]: the swept-volume measurement, the simulator and dry runs.
//! - [`records`]: every run recorded in a database (SQLite or PostgreSQL).
//! - [`telemetry`]: the machine's live state published on the shop's MQTT broker.
//! - [`opcua`]: the machine served to the shop's MES as OPC UA for Machine Tools.
//! - [`console`]: `whirl serve`, the operator's web console.
//! - [`papers`]: the founding papers' geometry reproduced, outside the data flow: it checks
//!   the measurement engine's methods and backs `whirl sweep`.
//!
//! `docs/architecture.md` draws the layers and says what each may import.
//!
//! # Example
//!
//! ```
//! use std::f64::consts::{PI, TAU};
//! use glam::DVec2;
//! use whirl::geometry::linkage::{Linkage, Ring, Whirling};
//! use whirl::geometry::profile::ProfilePoint;
//!
//! // A root point of a groove (normal radial): kinematics.md's check values say the ring
//! // centre sits at X = R − (ρ + r) with C = π − φ, whatever the installation angle.
//! let linkage = Linkage {
//!     p: 60.0 / TAU,
//!     ring: Ring {
//!         whirling: Whirling::Internal,
//!         radius: 50.0,
//!         nose: 1.0,
//!         installation: 20f64.to_radians(),
//!         edge_half_angle: PI / 2.0,
//!     },
//! };
//! let root = ProfilePoint { u: 0.0, pos: DVec2::new(25.0, 0.0), tangent: DVec2::Y };
//! let contact = linkage.solve(&root).unwrap();
//! assert!((contact.pose.x - 24.0).abs() < 1e-9);
//! assert!((contact.pose.c - PI).abs() < 1e-9);
//! ```

pub mod config;
pub mod console;
pub mod geometry;
pub mod judge;
pub mod log;
pub mod opcua;
pub mod papers;
pub mod plan;
pub mod post;
pub mod program;
pub mod protocol;
pub mod records;
pub mod telemetry;
pub mod transport;
