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
//! # Data flow
//!
//! ```text
//! job.toml + machine profile
//!   → profile        (points + periodic spline, or a standard's axial section; validated)
//!   → table          (the linkage at every profile sample: X(ψ) over one period)
//!   → interference   (no other part of the ring cuts the groove)
//!   → budget         (Δ shared: scallop, cusp, blending, rounding, interpolation)
//!   → segment        (nodes in ψ, each span within its interpolation share)
//!   → path           (lead-in, linked revolutions with axial feed, C rebasing, lead-out)
//!   → gcode          (post-processor for the controller's dialect)
//! ```
//!
//! Every arrow is a plain, synchronous function of values; [`plan::plan`] runs them in order
//! and refuses, with the place and the cause, before anything is written.
//!
//! # Modules
//!
//! - [`job`]: the job file (groove, tool, cut).
//! - [`machine`]: machine profiles: dialect, number type, travel, rates.
//! - [`connection`]: a profile's `[connection]`: how the bridge reaches the machine
//!   (serial, Modbus TCP/RTU, CAN through slcan or SocketCAN, with the drives' settings).
//! - [`profile`]: groove sections ([`profile::points`], [`profile::spline`],
//!   [`profile::standard`]).
//! - [`linkage`]: kinematics.md's node solver, one profile point → one pose; [`brent`] its
//!   root finder, [`minimise`] the 1D minimiser the sweeps use.
//! - [`table`], [`interference`], [`budget`], [`segment`], [`path`]: the planner's steps.
//! - [`gcode`]: the program model, writers and parser.
//! - [`plan`]: all of the above in order, with the report.
//! - [`protocol`]: sans-I/O controller protocols: grbl/grblHAL streaming by character
//!   counting, controller responses, resume preambles.
//! - [`simulator`]: the simulated controller (`whirl-sim`) as whirl embeds it.
//! - [`dry_run`]: a planned job streamed to the in-process simulator over a pseudo-terminal,
//!   its profile error measured by the simulator's Δ guard.
//! - [`exec_log`]: the executed-path log (JSON lines), its summary and plots.
//! - [`can`]: sans-I/O CAN layers for CiA 402 drives: frames, slcan, CANopen, CiA 402.
//! - [`modbus`]: the Modbus register map (`docs/modbus.md`), segments streamed through its ring.
//! - [`transport`]: the async edges that move a protocol's bytes: a program streamed to a
//!   controller over a serial line (tokio, tokio-serial), logged to the executed-path log.
//!
//! # Example
//!
//! ```
//! use std::f64::consts::{PI, TAU};
//! use glam::DVec2;
//! use whirl::linkage::{Linkage, Ring, Whirling};
//! use whirl::profile::ProfilePoint;
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

pub mod brent;
pub mod budget;
pub mod can;
pub mod check;
pub mod connection;
pub mod dry_run;
pub mod exec_log;
pub mod gcode;
pub mod interference;
pub mod job;
pub mod linkage;
pub mod machine;
pub mod minimise;
pub mod modbus;
pub mod path;
pub mod plan;
pub mod profile;
pub mod protocol;
pub mod segment;
pub mod simulator;
pub mod svg;
pub mod sweep;
pub mod table;
pub mod transport;

/// An error and its causes as one line, for the command lines. Errors here carry their
/// cause's text in their own message (so `to_string` alone says everything); a cause whose
/// text is already there is not repeated.
pub fn error_message(error: &(dyn std::error::Error + 'static)) -> String {
    let mut message = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !message.contains(&text) {
            message.push_str(": ");
            message.push_str(&text);
        }
        cause = c.source();
    }
    message
}

#[cfg(test)]
mod tests {
    /// An error whose message carries its cause's text, and one whose message does not.
    #[derive(Debug, thiserror::Error)]
    enum Outer {
        #[error("cannot read the job: {0}")]
        Carries(#[source] std::io::Error),
        #[error("cannot plan")]
        Plain(#[source] std::io::Error),
    }

    #[test]
    fn a_cause_is_said_once() {
        let io = || std::io::Error::other("no such file");
        let carries = Outer::Carries(io());
        assert_eq!(
            super::error_message(&carries),
            "cannot read the job: no such file"
        );
        let plain = Outer::Plain(io());
        assert_eq!(super::error_message(&plain), "cannot plan: no such file");
    }
}

/// Shapes shared by the unit tests.
#[cfg(test)]
pub(crate) mod testing {
    use crate::profile::points::{profile, Row, Section};
    use crate::profile::Profile;
    use std::f64::consts::TAU;

    /// The three-lobe groove ρ(φ) = 30 − 5·cos 3φ of tests/data/linkage-vectors.csv,
    /// 24 points of one period, for lead `lead` (right hand).
    pub fn lobe(lead: f64) -> Profile {
        let rows: Vec<Row> = (0..24)
            .map(|k| {
                let phi = TAU / 3.0 * k as f64 / 24.0;
                let rho = 30.0 - 5.0 * (3.0 * phi).cos();
                Row {
                    line: k + 1,
                    a: rho * phi.cos(),
                    b: rho * phi.sin(),
                }
            })
            .collect();
        profile(&rows, Section::Transverse, false, lead / TAU, 3).expect("a valid profile")
    }
}
