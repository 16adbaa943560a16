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

/// Machines for the crate's tests.
#[cfg(test)]
pub(crate) mod test_machines {
    use super::{Axis, Machine, Number};

    /// whirl-sim's default machine: X −5…160 mm, Z ±300 mm at 3000 mm/min and 500 mm/s²,
    /// C unlimited at 72 000 °/min and 7200 °/s², 32-bit numbers.
    pub(crate) fn sim_default() -> Machine {
        let linear = |min, max| Axis {
            min: Some(min),
            max: Some(max),
            max_rate: 3000.0,
            accel: 500.0,
        };
        Machine {
            x: linear(-5.0, 160.0),
            z: linear(-300.0, 300.0),
            c: Axis {
                min: None,
                max: None,
                max_rate: 72_000.0,
                accel: 7200.0,
            },
            number: Number::F32,
            max_line_length: 256,
            spindle_rpm: None,
        }
    }
}
