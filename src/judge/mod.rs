//! The judge: measures what a program cuts, independently of how it was planned.
//!
//! - [`measure`]: the swept torus over a program's straight-line motion against the
//!   target groove, point by point; [`verify`] runs it on a program's text for a job.
//! - [`simulator`]: the simulated controller (crate `whirl-sim`) as whirl embeds it;
//!   [`guard`] its Δ guard, [`cycles`] the drives' cycles merged into moves.
//! - [`dry_run`]: a planned job run on the simulator through the same transports a
//!   machine gets, its error measured by the guard.
//! - [`plots`]: a run's axes over time and the section it cut, from its log; [`svg`]
//!   draws them.

pub mod cycles;
pub mod dry_run;
pub mod guard;
pub mod linuxcnc;
pub mod measure;
pub mod plots;
pub mod sampled;
pub mod simulator;
pub mod svg;
pub mod verify;
