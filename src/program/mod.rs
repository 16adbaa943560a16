//! The neutral planned path: what the planner produces, and what every post, the limit
//! check, the timing and the judge consume.
//!
//! A [`Program`] is a list of [`Move`]s in the machine frame of `docs/kinematics.md`, in
//! one continuous frame and with no dialect in it: X is the ring-centre offset from the
//! spindle axis (a radius, mm), Z the axial position (mm), C the workpiece turn (degrees,
//! counting whole turns, however many). How a move is spelled for a controller (G-code's
//! G93 or G94, X as radius or diameter, decimals; Modbus segments; CANopen set-points) is
//! the posts' business ([`crate::post`]). G-code's renaming of C (G92) exists only in
//! G-code: the reader undoes it ([`crate::post::gcode::parse()`]), and the planner never
//! writes it.
//!
//! - [`limits`]: a program checked against a machine's travel, speeds and spindle.
//! - [`timing`]: how long each move takes, and the program's cycle time.

pub mod blending;
pub mod limits;
pub mod reentry;
pub mod timing;

use crate::config::machine::Axis;

/// One move of a whirling program in the machine frame of `docs/kinematics.md`:
/// X the ring-centre offset (mm, a radius), Z axial (mm), C the workpiece turn (degrees).
#[derive(Debug, Clone, PartialEq)]
pub enum Move {
    /// A note for the operator, where it stands in the program; it moves nothing.
    /// Writers sanitize it for their dialect.
    Comment(String),
    /// Rapid positioning (G0): each axis at its max rate; `None` axes do not move.
    Rapid {
        /// Target X, mm (radius).
        x: Option<f64>,
        /// Target Z, mm.
        z: Option<f64>,
        /// Target C, degrees.
        c: Option<f64>,
    },
    /// A move at a feed rate (G94): plunge and retract moves; feed in mm/min.
    ///
    /// When X or Z moves, the feed is along the X/Z path; when C moves alone, it is in
    /// deg/min. A feed that turns C together with X or Z is shared between them by the
    /// controller's rule ([`timing::feed_speeds`]); the planner never writes one.
    Feed {
        /// Target X, mm (radius).
        x: Option<f64>,
        /// Target Z, mm.
        z: Option<f64>,
        /// Target C, degrees.
        c: Option<f64>,
        /// Feed rate, mm/min (deg/min for a move of C alone).
        feed: f64,
    },
    /// A linked C/X/Z move that takes `minutes` (G93, inverse time): the cutting moves.
    Linked {
        /// Target X, mm (radius).
        x: f64,
        /// Target Z, mm.
        z: f64,
        /// Target C, degrees.
        c: f64,
        /// Duration of the move, minutes.
        minutes: f64,
    },
    /// Whirling-ring spindle on (`M3 S<rpm>`).
    SpindleOn {
        /// Ring speed, revolutions per minute.
        rpm: f64,
    },
    /// Whirling-ring spindle off (M5).
    SpindleOff,
}

impl Move {
    /// The target of a motion, with `None` for axes it leaves alone; `None` for moves that
    /// do not move the machine.
    pub fn target(&self) -> Option<Position> {
        match *self {
            Move::Rapid { x, z, c } | Move::Feed { x, z, c, .. } => Some(Position { x, z, c }),
            Move::Linked { x, z, c, .. } => Some(Position::known(x, z, c)),
            Move::Comment(_) | Move::SpindleOn { .. } | Move::SpindleOff => None,
        }
    }
}

/// A machine position, axis by axis; `None` where it is not known (before the program
/// has positioned that axis, when the start was not given).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Position {
    /// X, mm (radius).
    pub x: Option<f64>,
    /// Z, mm.
    pub z: Option<f64>,
    /// C, degrees.
    pub c: Option<f64>,
}

impl Position {
    /// Nothing known: where a program starts when the caller does not know the machine's
    /// position.
    pub const UNKNOWN: Position = Position {
        x: None,
        z: None,
        c: None,
    };

    /// A fully known position.
    pub fn known(x: f64, z: f64, c: f64) -> Position {
        Position {
            x: Some(x),
            z: Some(z),
            c: Some(c),
        }
    }

    /// The position of one axis.
    pub fn get(&self, axis: Axis) -> Option<f64> {
        match axis {
            Axis::X => self.x,
            Axis::Z => self.z,
            Axis::C => self.c,
        }
    }
}

/// A whirling program: its moves in execution order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// The moves, in order. Errors elsewhere name a move by its index here; a program read
    /// from G-code knows the file line of each ([`crate::post::gcode::parse::read_program_with_lines`]).
    pub moves: Vec<Move>,
}

impl Program {
    /// Walks the program move by move, giving each move's start and end position.
    ///
    /// `start` is where the machine is when the program starts ([`Position::UNKNOWN`] when
    /// that is not known: an axis then becomes known at the first move that positions it).
    pub fn steps(&self, start: Position) -> Steps<'_> {
        Steps {
            moves: self.moves.iter().enumerate(),
            position: start,
        }
    }

    /// Where the program leaves the machine, X, Z, C, when every axis is positioned.
    pub fn end_position(&self) -> Option<[f64; 3]> {
        let end = self.steps(Position::UNKNOWN).last()?.to;
        Some([end.x?, end.z?, end.c?])
    }
}

/// One move of a program with the positions it goes between; see [`Program::steps`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step<'a> {
    /// Index of the move in [`Program::moves`].
    pub index: usize,
    /// The move.
    pub action: &'a Move,
    /// Position before the move.
    pub from: Position,
    /// Position after the move (equal to `from` for moves that do not move the machine).
    pub to: Position,
}

/// Iterator over the [`Step`]s of a program; see [`Program::steps`].
#[derive(Debug, Clone)]
pub struct Steps<'a> {
    moves: std::iter::Enumerate<std::slice::Iter<'a, Move>>,
    position: Position,
}

impl<'a> Iterator for Steps<'a> {
    type Item = Step<'a>;

    fn next(&mut self) -> Option<Step<'a>> {
        let (index, action) = self.moves.next()?;
        let from = self.position;
        if let Some(target) = action.target() {
            for (slot, value) in [
                (&mut self.position.x, target.x),
                (&mut self.position.z, target.z),
                (&mut self.position.c, target.c),
            ] {
                if value.is_some() {
                    *slot = value;
                }
            }
        }
        Some(Step {
            index,
            action,
            from,
            to: self.position,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.moves.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_left_out_keep_their_position() {
        let program = Program {
            moves: vec![
                Move::Rapid {
                    x: None,
                    z: Some(5.0),
                    c: None,
                },
                Move::Feed {
                    x: Some(1.0),
                    z: None,
                    c: None,
                    feed: 100.0,
                },
            ],
        };
        let steps: Vec<Step<'_>> = program.steps(Position::known(9.0, 0.0, 45.0)).collect();
        assert_eq!(steps[0].to, Position::known(9.0, 5.0, 45.0));
        assert_eq!(steps[1].to, Position::known(1.0, 5.0, 45.0));
    }

    #[test]
    fn an_unknown_start_becomes_known_axis_by_axis() {
        let program = Program {
            moves: vec![
                Move::Rapid {
                    x: Some(10.0),
                    z: None,
                    c: None,
                },
                Move::SpindleOn { rpm: 3000.0 },
                Move::Linked {
                    x: 10.0,
                    z: 2.0,
                    c: 720.0,
                    minutes: 0.1,
                },
            ],
        };
        let steps: Vec<Step<'_>> = program.steps(Position::UNKNOWN).collect();
        assert_eq!(steps[0].from, Position::UNKNOWN);
        assert_eq!(
            steps[0].to,
            Position {
                x: Some(10.0),
                ..Position::UNKNOWN
            }
        );
        // The spindle moves nothing.
        assert_eq!(steps[1].from, steps[1].to);
        assert_eq!(steps[2].to, Position::known(10.0, 2.0, 720.0));
        assert_eq!(steps[2].index, 2);
    }

    #[test]
    fn non_motion_moves_have_no_target() {
        assert_eq!(Move::SpindleOff.target(), None);
        assert_eq!(Move::Comment("x".into()).target(), None);
        assert_eq!(Move::SpindleOn { rpm: 1.0 }.target(), None);
    }
}
