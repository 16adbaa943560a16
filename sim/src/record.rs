//! The executed-motion record: what the simulated machine actually did, block by block,
//! precisely enough to replay it.
//!
//! Each [`ExecutedBlock`] is one straight move from [`ExecutedBlock::from`] towards
//! [`ExecutedBlock::target`]; the machine stops at [`ExecutedBlock::to`], which is the target
//! unless the block was cut short (soft reset, soft-limit stop). Along the way the distance
//! travelled is piecewise quadratic in time, one [`Phase`] of constant acceleration after
//! another (a feed hold shows as a phase at speed zero), so
//! [`ExecutedBlock::position_at`] gives the machine position at any time of the block
//! exactly, and a consumer (the executed-path log, the Δ guard's sweep) can rebuild both
//! the path (the straight segments `from → to`, in order) and its timing.

use serde::{Deserialize, Serialize};

/// A machine position: X the ring-centre offset from the spindle axis as a radius (mm),
/// Z axial (mm), C the workpiece turn (degrees). Machine coordinates (grbl's `MPos`): no
/// G92 offset, so C keeps counting whole turns across rebasing.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Position {
    /// X, mm (radius).
    pub x: f64,
    /// Z, mm.
    pub z: f64,
    /// C, degrees.
    pub c: f64,
}

impl Position {
    /// From `[x, z, c]`.
    pub fn from_array([x, z, c]: [f64; 3]) -> Position {
        Position { x, z, c }
    }

    /// As `[x, z, c]` (the order of `whirl::log::Event::Executed`).
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.z, self.c]
    }
}

/// How the block's speed was programmed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MoveKind {
    /// G0.
    Rapid,
    /// G1 at a feed rate (G94).
    Feed,
    /// G1 in inverse time (G93).
    InverseTime,
    /// A jog (`$J=`), the operator's move rather than the program's.
    Jog,
}

/// A stretch of constant acceleration along a block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Phase {
    /// When it starts, simulated seconds.
    pub start: f64,
    /// Distance already travelled along the block at its start, path units (the Euclidean
    /// length over X, Z in mm and C in degrees, grbl's "millimeters" of a block).
    pub distance: f64,
    /// Path speed at its start, units/s.
    pub speed: f64,
    /// Path acceleration during it, units/s² (negative when slowing).
    pub accel: f64,
}

/// One executed straight move.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExecutedBlock {
    /// The line that queued it: its 1-based ordinal among all lines the controller has
    /// taken from the serial stream since it was created (empty and `$` lines count;
    /// lines a soft reset discarded unread do not).
    pub line: u64,
    /// The line's N word, if it had one (the robust key for a sender's program line).
    pub n: Option<u32>,
    /// Rapid, feed or inverse time.
    pub kind: MoveKind,
    /// Where the block started.
    pub from: Position,
    /// Where it was going.
    pub target: Position,
    /// Where it ended: `target` if [`Self::completed`].
    pub to: Position,
    /// When it started moving, simulated seconds.
    pub start_time: f64,
    /// When it ended.
    pub end_time: f64,
    /// It reached its target (false: cut short by a soft reset or a soft-limit stop).
    pub completed: bool,
    /// The acceleration phases, in time order; the first starts at `start_time`.
    pub phases: Vec<Phase>,
}

impl ExecutedBlock {
    /// The block's planned length, path units.
    pub fn length(&self) -> f64 {
        let (a, b) = (self.from.to_array(), self.target.to_array());
        a.iter()
            .zip(b)
            .map(|(p, q)| (q - p) * (q - p))
            .sum::<f64>()
            .sqrt()
    }

    /// Distance travelled along the block at time `t` (clamped to the block's time span).
    pub fn distance_at(&self, t: f64) -> f64 {
        let t = t.clamp(self.start_time, self.end_time);
        let Some(phase) = self.phases.iter().rev().find(|p| p.start <= t) else {
            return 0.0;
        };
        let dt = t - phase.start;
        (phase.distance + phase.speed * dt + 0.5 * phase.accel * dt * dt).clamp(0.0, self.length())
    }

    /// The machine position at time `t` (clamped to the block's time span).
    pub fn position_at(&self, t: f64) -> Position {
        if t >= self.end_time {
            return self.to;
        }
        let length = self.length();
        if length == 0.0 {
            return self.from;
        }
        let f = self.distance_at(t) / length;
        let (a, b) = (self.from.to_array(), self.target.to_array());
        Position::from_array([0, 1, 2].map(|i| a[i] + (b[i] - a[i]) * f))
    }

    /// Path speed at time `t`, units/s.
    pub fn speed_at(&self, t: f64) -> f64 {
        let t = t.clamp(self.start_time, self.end_time);
        self.phases
            .iter()
            .rev()
            .find(|p| p.start <= t)
            .map_or(0.0, |p| (p.speed + p.accel * (t - p.start)).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replays_a_trapezoid() {
        // 10 units: accelerate at 2 for 1 s (1 unit), cruise at 2 for 4 s (8 units),
        // decelerate for 1 s (1 unit).
        let block = ExecutedBlock {
            line: 1,
            n: None,
            kind: MoveKind::Feed,
            from: Position::default(),
            target: Position::from_array([6.0, 8.0, 0.0]),
            to: Position::from_array([6.0, 8.0, 0.0]),
            start_time: 1.0,
            end_time: 7.0,
            completed: true,
            phases: vec![
                Phase {
                    start: 1.0,
                    distance: 0.0,
                    speed: 0.0,
                    accel: 2.0,
                },
                Phase {
                    start: 2.0,
                    distance: 1.0,
                    speed: 2.0,
                    accel: 0.0,
                },
                Phase {
                    start: 6.0,
                    distance: 9.0,
                    speed: 2.0,
                    accel: -2.0,
                },
            ],
        };
        assert_eq!(block.length(), 10.0);
        assert_eq!(block.distance_at(4.0), 5.0);
        assert_eq!(
            block.position_at(4.0),
            Position::from_array([3.0, 4.0, 0.0])
        );
        assert_eq!(block.position_at(0.0), Position::default());
        assert_eq!(block.position_at(9.0), block.to);
        assert_eq!(block.speed_at(6.5), 1.0);
    }
}
