//! whirl-sim: a simulated whirling-lathe controller that speaks grblHAL's serial protocol.
//!
//! The simulator stands in for the machine in tests and dry runs: a grbl sender streams a
//! program to it exactly as to a real grblHAL XZC lathe and gets the same answers (`ok`,
//! `error:N`, `ALARM:N`, status reports), while the simulator records what it executed so
//! the run can be audited and measured against the allowable error Δ.
//!
//! This crate is the sans-I/O core: [`Controller`] takes bytes ([`Controller::receive`])
//! and simulated time ([`Controller::advance`]) and gives bytes
//! ([`Controller::take_output`]) and [`Event`]s ([`Controller::take_events`]). No clock, no
//! threads, no files: the pseudo-terminal and TCP front-ends, the time scale and the baud
//! rate emulation are the caller's business. `README.md` lists the supported subset and
//! every known difference from grblHAL.
//!
//! # Modules
//!
//! - [`protocol`]: real-time bytes, the RX buffer, line assembly.
//! - [`interpreter`]: G-code lines → modal state and steps, grbl's error numbers.
//! - [`system`]: `$` commands.
//! - [`settings`]: grblHAL's settings (`$$`, `$n=value`).
//! - [`motion`]: grbl's look-ahead planner and an exact executor in simulated time.
//! - [`record`]: the executed-motion record ([`ExecutedBlock`]), replayable.
//! - [`report`]: everything printed (banner, status report, `$$`, `$I`, …).
//! - [`machine`]: what the controller knows of its machine (travel, rates, number type).
//! - [`controller`]: the state machine tying them together.
//! - [`serve`]: the controller served on a byte stream in simulated time (the only async part).
//! - [`guard`]: the Δ guard's seat: a watch on executed blocks that can stop the machine.
//! - [`error`]: the numbered answers and the simulator's own errors.
//! - [`canopen`]: CAN equipment: an slcan adapter and CiA 402 drives on CANopen.
//! - [`modbus`]: the Modbus register map's controller side, slots executed as G-code lines.
//!
//! # Example
//!
//! ```
//! use whirl_sim::{Controller, ControllerOptions, Event, machine::{Axis, Machine, Number}};
//!
//! let linear = Axis { min: Some(-300.0), max: Some(300.0), max_rate: 3000.0, accel: 500.0 };
//! let machine = Machine {
//!     x: linear,
//!     z: linear,
//!     c: Axis { min: None, max: None, max_rate: 72000.0, accel: 7200.0 },
//!     number: Number::F32,
//!     max_line_length: 256,
//!     spindle_rpm: None,
//! };
//! let mut sim = Controller::new(&machine, ControllerOptions::default()).unwrap();
//! sim.take_output(); // the banner
//!
//! // A 30 mm rapid along Z; grbl acknowledges a motion once it is queued.
//! sim.receive(b"N10 G0 Z30\n");
//! assert_eq!(sim.take_output(), b"ok\r\n");
//!
//! // Z runs at 3000 mm/min = 50 mm/s with 500 mm/s²: 0.6 s cruising plus 0.1 s for
//! // the speed ramps, 0.7 s in all.
//! sim.advance(1.0).unwrap();
//! assert_eq!(sim.position().z, 30.0);
//! let executed: Vec<_> = sim
//!     .take_events()
//!     .into_iter()
//!     .filter_map(|e| match e {
//!         Event::Executed(block) => Some(block),
//!         _ => None,
//!     })
//!     .collect();
//! assert_eq!(executed[0].n, Some(10));
//! assert!((executed[0].end_time - executed[0].start_time - 0.7).abs() < 1e-9);
//!
//! sim.receive(b"?");
//! let report = String::from_utf8(sim.take_output()).unwrap();
//! assert!(report.starts_with("<Idle|MPos:0.000,0.000,30.000,0.000|Bf:100,1023|"));
//! ```

pub mod canopen;
pub mod controller;
pub mod error;
pub mod guard;
pub mod interpreter;
pub mod machine;
pub mod modbus;
pub mod motion;
pub mod protocol;
pub mod record;
pub mod report;
pub mod serve;
pub mod settings;
pub mod system;

#[cfg(test)]
mod tests;

pub use controller::{Controller, ControllerOptions, Event};
pub use error::{Alarm, ConfigError, GrblError, TimeError};
pub use guard::{Breach, Guard, Measured};
pub use record::{ExecutedBlock, MoveKind, Phase, Position};
pub use report::MachineState;
