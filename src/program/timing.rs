//! How long a move takes: the one rule every consumer uses (the planner's cycle time, the
//! CANopen set-points), with the controller's rule for a feed shared between linear and
//! rotary axes.

use super::{Move, Position, Program};
use crate::config::machine::{Axis, Dialect, MachineProfile};

/// Axis speeds of a feed move, per minute, under the controller's rule for sharing a feed
/// between linear and rotary axes:
///
/// - LinuxCNC (RS274/NGC): when X or Z moves, F is mm/min along the X/Z path and C
///   follows in the same time; when C moves alone, F is deg/min.
/// - grblHAL (grbl): F is the rate along the Euclidean length of all moving axes, mm and
///   degrees counted alike (grblHAL's optional rotary-axis handling is not assumed).
///
/// The two agree for every feed that does not turn C together with X or Z.
pub fn feed_speeds(dialect: Dialect, delta: [f64; 3], feed: f64) -> [f64; 3] {
    let [dx, dz, dc] = delta.map(f64::abs);
    let linear = dx.hypot(dz);
    let length = match dialect {
        Dialect::LinuxCnc if linear > 0.0 => linear,
        _ => linear.hypot(dc),
    };
    if length == 0.0 {
        return [0.0; 3];
    }
    [dx, dz, dc].map(|d| feed * d / length)
}

/// How long a motion takes, minutes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoveTime {
    /// The time the program asks for: a linked move's `minutes`, a feed move's distance
    /// over its feed; `None` for a rapid, which runs as fast as the axes allow.
    pub programmed: Option<f64>,
    /// The shortest time the axes' max rates allow: the slowest axis at its max rate.
    pub fastest: f64,
}

impl MoveTime {
    /// The time of `action` moving the axes by `delta` (X mm, Z mm, C degrees), under
    /// `dialect`'s feed rule and the axes' `max_rate` (per minute, X, Z, C); `None` for
    /// moves that do not move the machine. A feed or time that is not above zero is the
    /// caller's to refuse.
    pub fn of(
        action: &Move,
        delta: [f64; 3],
        dialect: Dialect,
        max_rate: [f64; 3],
    ) -> Option<MoveTime> {
        let fastest = (0..3)
            .map(|i| delta[i].abs() / max_rate[i])
            .fold(0.0, f64::max);
        let programmed = match *action {
            Move::Linked { minutes, .. } => Some(minutes),
            Move::Feed { feed, .. } => {
                // Time = distance of any moving axis / its speed.
                let speeds = feed_speeds(dialect, delta, feed);
                Some(
                    (0..3)
                        .find(|&i| speeds[i] > 0.0)
                        .map_or(0.0, |i| delta[i].abs() / speeds[i]),
                )
            }
            Move::Rapid { .. } => None,
            Move::Comment(_) | Move::SpindleOn { .. } | Move::SpindleOff => return None,
        };
        Some(MoveTime {
            programmed,
            fastest,
        })
    }

    /// As the program asks, rapids as fast as the axes allow: the time a controller that
    /// keeps to its limits needs for a program that passes them.
    pub fn planned(self) -> f64 {
        self.programmed.unwrap_or(self.fastest)
    }

    /// As the program asks, but never faster than the axes allow (grbl's planner, and the
    /// set-point sampler, lengthen a move that would exceed a max rate).
    pub fn within_max_rates(self) -> f64 {
        self.programmed
            .map_or(self.fastest, |wanted| wanted.max(self.fastest))
    }
}

/// Estimated run time of the program, seconds: every move's [`MoveTime::planned`].
///
/// A lower bound: acceleration and the slow-down at junctions are ignored, and so is
/// any motion of an axis from the unknown start position to where the program first
/// puts it. Meaningful for programs that pass
/// [`check_limits`](super::limits::check_limits).
pub fn cycle_time_s(program: &Program, profile: &MachineProfile) -> f64 {
    move_seconds(program, profile)
        .into_iter()
        .map(|(_, seconds)| seconds)
        .sum()
}

/// Each move's [`MoveTime::planned`] in seconds, with its index in the program; moves that
/// do not move the machine are left out. The same lower bound as [`cycle_time_s`], move by
/// move: what a stream's watchdog allows a move it may be waiting on.
pub fn move_seconds(program: &Program, profile: &MachineProfile) -> Vec<(usize, f64)> {
    let max_rate = Axis::ALL.map(|axis| profile.max_rate(axis));
    program
        .steps(Position::UNKNOWN)
        .filter_map(|step| {
            let delta: [f64; 3] = std::array::from_fn(|slot| {
                let axis = Axis::ALL[slot];
                match (step.from.get(axis), step.to.get(axis)) {
                    (Some(a), Some(b)) => b - a,
                    _ => 0.0,
                }
            });
            let time = MoveTime::of(step.action, delta, profile.dialect, max_rate)?;
            Some((step.index, time.planned() * 60.0))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::limits::tests::{profile, program, rapid};

    #[test]
    fn cycle_time_adds_linked_feed_and_rapid_times() {
        let p = profile(Dialect::GrblHal);
        let prog = program(vec![
            rapid(10.0, 0.0, 0.0),
            // Z 300 mm at 3000 mm/min: 6 s; C 3600° at 72 000 deg/min: 3 s; slowest wins.
            rapid(10.0, 300.0, 3600.0),
            // 10 mm at 100 mm/min: 6 s.
            Move::Feed {
                x: Some(0.0),
                z: None,
                c: None,
                feed: 100.0,
            },
            Move::Linked {
                x: 0.0,
                z: 301.0,
                c: 3960.0,
                minutes: 0.5,
            },
            Move::SpindleOff,
        ]);
        assert!((cycle_time_s(&prog, &p) - (6.0 + 6.0 + 30.0)).abs() < 1e-9);
    }
}
