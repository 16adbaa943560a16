//! whirl: plan, post and stream thread-whirling programs.
#![allow(missing_docs)]
pub mod brent;
pub mod budget;
pub mod gcode;
pub mod interference;
pub mod job;
pub mod linkage;
pub mod machine;
pub mod path;
pub mod plan;
pub mod profile;
pub mod segment;
pub mod table;
