//! Geometry: the groove, the ring and the numerics they need, as pure mathematics.
//!
//! Nothing here knows a file, a machine or a controller: values in, values out.
//!
//! - [`profile`]: one period of the groove's transverse section, from sampled points (a
//!   periodic spline) or a standard's exact axial section.
//! - [`linkage`]: the contact conditions of `docs/kinematics.md`, one profile point → one
//!   machine pose (X, C, Z) and its phase ψ.
//! - [`brent`]: the bracketing root finder the linkage uses; [`minimise`]: the 1D
//!   minimiser the sweeps use.

pub mod brent;
pub mod linkage;
pub mod minimise;
pub mod profile;
