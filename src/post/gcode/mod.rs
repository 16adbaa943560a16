//! G-code: number formatting, the dialect writers and a parser.
//!
//! The planner produces a [`Program`](crate::program::Program) in the machine frame of
//! `docs/kinematics.md` (X the ring-centre offset as a radius in mm, Z axial in mm, C the
//! workpiece turn in degrees), with no dialect in it. [`write()`] turns it into text for
//! one controller dialect ([`Dialect`](crate::config::machine::Dialect)) under [`PostSettings`]
//! (decimals from the error budget via [`decimals_for`], X as radius or diameter, line
//! length, blending). [`read_program`] reads such text (and what grbl senders commonly
//! send) back into a program, so `read_program(write(p)) ≈ p` within the written
//! decimals; a simulator or a checker reads programs the same way.
//!
//! - [`format`](mod@format): numbers with just enough decimals, no trailing zeros, no `-0`.
//! - [`writer`]: the writers.
//! - [`parse`](mod@parse): the reader.
//! - [`header`]: the provenance header at the top of a program, written and read.

pub mod format;
pub mod header;
pub mod parse;
pub mod writer;

pub use format::{decimals_for, FormatError};
pub use parse::{parse, read_program, to_program, ParseError, ParseErrorKind, ParsedLine};
pub use writer::{write, PostError, PostSettings};
