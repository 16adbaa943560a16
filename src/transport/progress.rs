//! How far a run is, for a display: one snapshot type for every transport.

use std::time::Duration;

/// What a [`Progress`] counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// Program lines acknowledged by a grbl-family controller.
    Lines,
    /// Segments published to a controller through the Modbus register map.
    Segments,
    /// Set-points sent to CiA 402 drives, one a cycle.
    SetPoints,
}

impl Unit {
    /// The unit's name in words, plural: `lines`, `segments`, `set-points`.
    pub fn name(self) -> &'static str {
        match self {
            Unit::Lines => "lines",
            Unit::Segments => "segments",
            Unit::SetPoints => "set-points",
        }
    }
}

/// A run's progress, handed to a [`ProgressFn`] whenever something happened. Plain values,
/// so a terminal or a web page can show them as it likes.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// What `done` and `total` count.
    pub unit: Unit,
    /// Done so far (acknowledged, published or sent), counting those an earlier run did
    /// before a resume.
    pub done: usize,
    /// In the whole program.
    pub total: usize,
    /// The program line executing now (0-based), where the controller says.
    pub line: Option<usize>,
    /// Since the run started.
    pub elapsed: Duration,
    /// Time left, where it can be told: from the planned move times, or the rate so far.
    pub left: Option<Duration>,
    /// The controller's state in its own words (`Run`, `Hold`, `Idle`), where it reports
    /// one.
    pub state: Option<String>,
    /// X, Z (mm) and C (degrees) in machine coordinates, as last reported.
    pub position: Option<[f64; 3]>,
    /// Everything is sent; the machine is finishing the last moves.
    pub finishing: bool,
}

impl Progress {
    /// `done / total`, 0 to 1 (1 for an empty program).
    pub fn fraction(&self) -> f64 {
        if self.total == 0 {
            1.0
        } else {
            self.done as f64 / self.total as f64
        }
    }
}

/// A progress callback. It runs on the streaming task: keep it quick.
pub type ProgressFn = Box<dyn FnMut(&Progress) + Send>;

/// The program line each move of a fieldbus run is, so that the run can say the line a move
/// it stopped at resumes from: a Modbus segment or a CANopen set-point knows its move, and
/// only the posted program knows the move's line.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MoveLines {
    /// The program line (0-based) of each move, in the order the run has them.
    lines: Vec<usize>,
    /// One past the program's last line: where a run that ran every move would resume.
    end: usize,
}

impl MoveLines {
    /// `lines`, the line (0-based) of each move; `end`, the program's line count.
    pub fn new(lines: Vec<usize>, end: usize) -> MoveLines {
        MoveLines { lines, end }
    }

    /// The program line (0-based) of move `index`; past the last move, the line after the
    /// program's last.
    pub fn line_of(&self, index: usize) -> usize {
        self.lines.get(index).copied().unwrap_or(self.end)
    }
}
