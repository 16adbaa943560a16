//! The judge: measures what a program cuts, independently of how it was planned.
//!
//! - [`measure`]: the swept torus over a program's straight-line motion against the
//!   target groove, point by point; [`verify`] runs it on a program's text for a job.
//! - [`simulator`]: the simulated controller (crate `whirl-sim`) as whirl embeds it;
//!   [`guard`] its Δ guard, [`cycles`] the drives' cycles merged into moves.
//! - [`dry_run`]: a planned job run on the simulator through the same transports a
//!   machine gets, its error measured by the guard.
//! - [`fastest`]: the fastest feed whose planned program the engine measures within Δ.
//! - [`plots`]: a run's axes over time and the section it cut, from its log; [`svg`]
//!   draws them.
//! - [`profile_view`]: what whirl understood of a job's groove, and its axial section
//!   drawn (`whirl profile`, the console's job page).
//! - [`refine`]: `whirl plan`'s nodes: planned, measured by the engine on a stretch of the
//!   program, planned again.
//! - [`section`]: a measured section of a cut part, read in its stated frame, and each
//!   point's deviation from the target; [`fit`] the tool the part was really cut with, and
//!   the job that cuts the target with it (`whirl measure`).

pub mod cycles;
pub mod dry_run;
pub mod fastest;
pub mod fit;
pub mod guard;
pub mod linuxcnc;
pub mod measure;
pub mod plots;
pub mod profile_view;
pub mod refine;
pub mod sampled;
pub mod section;
pub mod simulator;
pub mod svg;
pub mod verify;
