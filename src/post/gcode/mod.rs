//! G-code: the program model, number formatting, the dialect writers and a parser.
//!
//! The planner produces a [`Program`]: plain [`Block`]s in the machine frame of
//! `kinematics.md` (X the ring-centre offset as a radius in mm, Z axial in mm, C the
//! workpiece turn in degrees), with no dialect in it. [`write()`] turns it into text for
//! one controller ([`Dialect::GrblHal`] or [`Dialect::LinuxCnc`]) under [`PostSettings`]
//! (decimals from the error budget via [`decimals_for`], X as radius or diameter, line
//! length, blending). [`read_program`] reads such text (and what grbl senders commonly
//! send) back into a [`Program`], so `read_program(write(p)) ≈ p` within the written
//! decimals; a simulator or a checker reads programs the same way.
//!
//! - [`program`]: the model, and [`Program::steps`] for walking it in one continuous
//!   frame across G92 rebasing of C.
//! - [`format`](mod@format): numbers with just enough decimals, no trailing zeros, no `-0`.
//! - [`post`]: the writers.
//! - [`parse`](mod@parse): the reader.

pub mod format;
pub mod parse;
pub mod post;
pub mod program;

pub use format::{decimals_for, FormatError};
pub use parse::{parse, read_program, to_program, ParseError, ParseErrorKind, ParsedLine};
pub use post::{write, Dialect, PostError, PostSettings};
pub use program::{Axis, Block, Pose, Program, Step, Steps};
