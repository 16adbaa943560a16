//! What the simulated controller knows of its machine: travel, speed and acceleration per axis,
//! the number type it holds coordinates in, its line length and its spindle's range.
//!
//! The simulator's own description rather than whirl's machine profile: the simulator is a
//! controller model that judges what whirl sends, so it shares no code with the sender
//! (whirl converts its profiles into this when it embeds the simulator).

/// One axis: travel (none for an unlimited rotary axis), max rate in units per minute
/// (mm or degrees), acceleration in units per second².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Axis {
    /// Lowest position, if limited.
    pub min: Option<f64>,
    /// Highest position, if limited.
    pub max: Option<f64>,
    /// Units per minute.
    pub max_rate: f64,
    /// Units per second².
    pub accel: f64,
}

/// How the controller holds coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Number {
    /// 32-bit floats, as the grbl family does.
    F32,
    /// 64-bit floats.
    F64,
}

/// The simulated machine: X, Z, C axes and the controller's limits.
#[derive(Debug, Clone, PartialEq)]
pub struct Machine {
    /// Ring-centre offset, mm.
    pub x: Axis,
    /// Axial, mm.
    pub z: Axis,
    /// Workpiece turn, degrees.
    pub c: Axis,
    /// Coordinate number type.
    pub number: Number,
    /// Longest line accepted, characters.
    pub max_line_length: usize,
    /// Spindle speed range (min, max), rpm, if known.
    pub spindle_rpm: Option<(f64, f64)>,
}
