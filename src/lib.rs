//! whirl: plan, post and stream thread-whirling programs.
#![allow(missing_docs)]
pub mod gcode;
pub mod machine;
pub mod profile;
pub mod brent;
pub mod linkage;
