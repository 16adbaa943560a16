//! A program checked against a machine: travel, speeds and the ring spindle's range,
//! before anything is sent or written.

use thiserror::Error;

use super::timing::feed_speeds;
use super::{Move, Position, Program};
use crate::config::machine::{Axis, MachineProfile};

/// An end of an axis' travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bound {
    /// The lower end (`min`).
    Min,
    /// The upper end (`max`).
    Max,
}

impl Bound {
    fn side(self) -> &'static str {
        match self {
            Bound::Min => "below",
            Bound::Max => "above",
        }
    }
}

impl std::fmt::Display for Bound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Bound::Min => "min",
            Bound::Max => "max",
        })
    }
}

/// Relative slack on speed limits, so a move planned exactly at the limit is not
/// refused for the last bit of floating-point rounding.
const RATE_SLACK: f64 = 1e-9;

/// A program that asks more of the machine than its profile allows.
///
/// `index` is the move's index in [`Program::moves`] (0-based), not a line of a G-code
/// file; the message leaves it out, so that the caller can say where in its own terms (a
/// file line, see [`LimitError::index`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LimitError {
    /// A position outside the axis' travel.
    #[error(
        "{axis} position {value} {unit} is \
         {side} the machine's {bound} {limit} {unit} (axes.{key}.{bound})",
        unit = .axis.unit(),
        key = .axis.letter().to_ascii_lowercase(),
        side = .bound.side()
    )]
    Travel {
        /// Move index.
        index: usize,
        /// The axis.
        axis: Axis,
        /// The position (C unrebased).
        value: f64,
        /// Which end of the travel.
        bound: Bound,
        /// The limit.
        limit: f64,
    },
    /// An axis moving faster than its max rate.
    #[error(
        "{axis} speed {speed:.1} {unit}/min \
         exceeds the machine's max_rate {limit} {unit}/min (axes.{key})",
        unit = .axis.unit(),
        key = .axis.letter().to_ascii_lowercase()
    )]
    Speed {
        /// Move index.
        index: usize,
        /// The axis.
        axis: Axis,
        /// The axis speed the block asks for, per minute.
        speed: f64,
        /// The axis' max rate.
        limit: f64,
    },
    /// A feed or linked move of an axis the program has not positioned: where it starts,
    /// and so how fast it moves, is unknown.
    #[error(
        "moves {axis} at feed before any \
         block positioned {axis}, so its speed cannot be checked (position it with a rapid first)"
    )]
    Unpositioned {
        /// Move index.
        index: usize,
        /// The axis.
        axis: Axis,
    },
    /// A ring speed outside the spindle's range.
    #[error(
        "spindle speed {rpm} rpm is outside \
         the machine's range {min}..={max} rpm (spindle)"
    )]
    SpindleSpeed {
        /// Move index.
        index: usize,
        /// The speed asked for.
        rpm: f64,
        /// Lowest speed.
        min: f64,
        /// Highest speed.
        max: f64,
    },
    /// A value no machine can execute (not finite, zero or negative time or feed).
    #[error("{problem}")]
    InvalidMove {
        /// Move index.
        index: usize,
        /// What is wrong.
        problem: String,
    },
}

impl LimitError {
    /// The move (index into [`Program::moves`]) that asks too much.
    pub fn index(&self) -> usize {
        match self {
            LimitError::Travel { index, .. }
            | LimitError::Speed { index, .. }
            | LimitError::Unpositioned { index, .. }
            | LimitError::SpindleSpeed { index, .. }
            | LimitError::InvalidMove { index, .. } => *index,
        }
    }
}

/// Checks that the program stays within the machine's travel and speeds.
///
/// Travel: every position a motion reaches, for X and Z always and for C when its travel
/// is limited. Moves are straight in X, Z and C, so checking the ends checks the whole
/// move. Speed: a [`Move::Linked`] moves each axis at |Δ|/minutes; a [`Move::Feed`]
/// shares its feed between the axes by the dialect's rule ([`feed_speeds`]); rapids run at
/// the machine's own rates and are not checked. Acceleration is not checked. The
/// program's start position is taken as unknown: a feed or linked move of an axis no
/// earlier move positioned is an error. Ring speeds are checked when the profile has a
/// `[spindle]`.
///
/// Returns the first violation.
pub fn check_limits(program: &Program, profile: &MachineProfile) -> Result<(), LimitError> {
    for step in program.steps(Position::UNKNOWN) {
        let index = step.index;
        let invalid = |problem: String| LimitError::InvalidMove { index, problem };
        match *step.action {
            Move::SpindleOn { rpm } => {
                if let Some(spindle) = &profile.spindle {
                    if !(spindle.min_rpm..=spindle.max_rpm).contains(&rpm) {
                        return Err(LimitError::SpindleSpeed {
                            index,
                            rpm,
                            min: spindle.min_rpm,
                            max: spindle.max_rpm,
                        });
                    }
                }
                continue;
            }
            Move::Linked { minutes, .. } if !(minutes.is_finite() && minutes > 0.0) => {
                return Err(invalid(format!(
                    "move time {minutes} min is not above zero"
                )));
            }
            Move::Feed { feed, .. } if !(feed.is_finite() && feed > 0.0) => {
                return Err(invalid(format!("feed {feed} is not above zero")));
            }
            _ => {}
        }
        let Some(target) = step.action.target() else {
            continue;
        };
        // Travel of the axes this move moves.
        for axis in Axis::ALL {
            let (Some(_), Some(value)) = (target.get(axis), step.to.get(axis)) else {
                continue;
            };
            if !value.is_finite() {
                return Err(invalid(format!("{axis} target {value} is not finite")));
            }
            let (min, max) = profile.travel(axis);
            if let Some(limit) = min.filter(|&min| value < min) {
                return Err(LimitError::Travel {
                    index,
                    axis,
                    value,
                    bound: Bound::Min,
                    limit,
                });
            }
            if let Some(limit) = max.filter(|&max| value > max) {
                return Err(LimitError::Travel {
                    index,
                    axis,
                    value,
                    bound: Bound::Max,
                    limit,
                });
            }
        }
        // Speeds of feed and linked moves.
        let speeds = match *step.action {
            Move::Linked { minutes, .. } => {
                let delta = axis_deltas(&step.from, &step.to, &target, index)?;
                delta.map(|d| d.abs() / minutes)
            }
            Move::Feed { feed, .. } => {
                let delta = axis_deltas(&step.from, &step.to, &target, index)?;
                feed_speeds(profile.dialect, delta, feed)
            }
            _ => continue,
        };
        for (axis, speed) in Axis::ALL.into_iter().zip(speeds) {
            let limit = profile.max_rate(axis);
            if speed > limit * (1.0 + RATE_SLACK) {
                return Err(LimitError::Speed {
                    index,
                    axis,
                    speed,
                    limit,
                });
            }
        }
    }
    Ok(())
}

/// Δ per axis of a move (zero for axes the move leaves alone); an axis the move names
/// but that has no known start is [`LimitError::Unpositioned`].
fn axis_deltas(
    from: &Position,
    to: &Position,
    target: &Position,
    index: usize,
) -> Result<[f64; 3], LimitError> {
    let mut delta = [0.0; 3];
    for (slot, axis) in Axis::ALL.into_iter().enumerate() {
        if target.get(axis).is_none() {
            continue;
        }
        match (from.get(axis), to.get(axis)) {
            (Some(a), Some(b)) => delta[slot] = b - a,
            _ => return Err(LimitError::Unpositioned { index, axis }),
        }
    }
    Ok(delta)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::config::machine::{Dialect, Spindle};
    use crate::program::timing::cycle_time_s;

    /// The built-in simulated machine (X −5…160 mm and Z ±300 mm at 3000 mm/min, C
    /// unlimited at 72 000 deg/min) speaking `dialect`, its ring spindle held to 500–6000 rpm.
    pub(crate) fn profile(dialect: Dialect) -> MachineProfile {
        let mut profile = MachineProfile::builtin_sim().expect("the built-in profile");
        profile.dialect = dialect;
        profile.spindle = Some(Spindle {
            min_rpm: 500.0,
            max_rpm: 6000.0,
        });
        profile
    }

    pub(crate) fn rapid(x: f64, z: f64, c: f64) -> Move {
        Move::Rapid {
            x: Some(x),
            z: Some(z),
            c: Some(c),
        }
    }

    pub(crate) fn program(moves: Vec<Move>) -> Program {
        Program { moves }
    }

    #[test]
    fn speeds_over_the_limit_name_block_axis_value_and_limit() {
        let p = profile(Dialect::GrblHal);
        // 10 mm of X in 0.002 min is 5000 mm/min.
        let too_fast = program(vec![
            rapid(10.0, 0.0, 0.0),
            Move::Linked {
                x: 20.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.002,
            },
        ]);
        let error = check_limits(&too_fast, &p).unwrap_err();
        assert_eq!(
            error,
            LimitError::Speed {
                index: 1,
                axis: Axis::X,
                speed: 5000.0,
                limit: 3000.0
            }
        );
        assert_eq!(
            error.to_string(),
            "X speed 5000.0 mm/min exceeds the machine's max_rate 3000 mm/min (axes.x)"
        );
        // C: 180° in 0.002 min is 90 000 deg/min, over 72 000.
        let c_fast = program(vec![
            rapid(10.0, 0.0, 0.0),
            Move::Linked {
                x: 10.0,
                z: 0.0,
                c: 180.0,
                minutes: 0.002,
            },
        ]);
        assert!(matches!(
            check_limits(&c_fast, &p),
            Err(LimitError::Speed { axis: Axis::C, .. })
        ));
        // Exactly at the limit is allowed: 6 mm in 0.002 min = 3000 mm/min.
        let at_limit = program(vec![
            rapid(10.0, 0.0, 0.0),
            Move::Linked {
                x: 16.0,
                z: 0.0,
                c: 0.0,
                minutes: 0.002,
            },
        ]);
        assert_eq!(check_limits(&at_limit, &p), Ok(()));
    }

    #[test]
    fn travel_is_checked_on_every_axis() {
        let mut p = profile(Dialect::GrblHal);
        let prog = program(vec![rapid(170.0, 0.0, 0.0)]);
        assert_eq!(
            check_limits(&prog, &p),
            Err(LimitError::Travel {
                index: 0,
                axis: Axis::X,
                value: 170.0,
                bound: Bound::Max,
                limit: 160.0
            })
        );
        let prog = program(vec![rapid(0.0, -301.0, 0.0)]);
        let error = check_limits(&prog, &p).unwrap_err();
        assert_eq!(error.index(), 0);
        assert_eq!(
            error.to_string(),
            "Z position -301 mm is below the machine's min -300 mm (axes.z.min)"
        );
        // A C axis limited to ±400°: a turn past it is refused, naming the move.
        p.axes.c.min = Some(-400.0);
        p.axes.c.max = Some(400.0);
        let prog = program(vec![
            rapid(10.0, 0.0, 300.0),
            Move::Rapid {
                x: None,
                z: None,
                c: Some(420.0),
            },
        ]);
        assert!(matches!(
            check_limits(&prog, &p),
            Err(LimitError::Travel {
                index: 1,
                axis: Axis::C,
                bound: Bound::Max,
                ..
            })
        ));
    }

    #[test]
    fn feed_moves_share_the_feed_by_the_dialect_rule() {
        // X 3, Z 4 (5 mm) and C 180° at feed F.
        let prog = |feed| {
            program(vec![
                rapid(10.0, 0.0, 0.0),
                Move::Feed {
                    x: Some(13.0),
                    z: Some(4.0),
                    c: Some(180.0),
                    feed,
                },
            ])
        };
        // LinuxCNC: 5 mm at 1500 mm/min take 1/300 min, so C turns at 54 000 deg/min.
        // (The first rapid starts from an unknown position: it adds no time.)
        let linuxcnc = profile(Dialect::LinuxCnc);
        assert_eq!(check_limits(&prog(1500.0), &linuxcnc), Ok(()));
        assert!((cycle_time_s(&prog(1500.0), &linuxcnc) - 60.0 / 300.0).abs() < 1e-12);
        // F2100: C at 75 600 deg/min, over 72 000 (Z at 1680 mm/min is fine).
        assert_eq!(
            check_limits(&prog(2100.0), &linuxcnc),
            Err(LimitError::Speed {
                index: 1,
                axis: Axis::C,
                speed: 2100.0 * 180.0 / 5.0,
                limit: 72000.0
            })
        );
        // grbl: F runs along sqrt(3² + 4² + 180²) "units" of mm and degrees alike, so
        // C gets just under F and the same program is within limits.
        let grbl = profile(Dialect::GrblHal);
        let length = (9.0f64 + 16.0 + 180.0 * 180.0).sqrt();
        assert!((cycle_time_s(&prog(2100.0), &grbl) - length / 2100.0 * 60.0).abs() < 1e-9);
        assert_eq!(check_limits(&prog(2100.0), &grbl), Ok(()));
        // A plunge of X alone at F above the X max rate.
        let plunge = program(vec![
            rapid(10.0, 0.0, 0.0),
            Move::Feed {
                x: Some(5.0),
                z: None,
                c: None,
                feed: 3500.0,
            },
        ]);
        assert!(matches!(
            check_limits(&plunge, &grbl),
            Err(LimitError::Speed {
                index: 1,
                axis: Axis::X,
                ..
            })
        ));
    }

    #[test]
    fn moves_from_unknown_positions_and_bad_values_are_refused() {
        let p = profile(Dialect::GrblHal);
        let unpositioned = program(vec![
            Move::Rapid {
                x: Some(10.0),
                z: Some(0.0),
                c: None,
            },
            Move::Linked {
                x: 10.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.1,
            },
        ]);
        assert_eq!(
            check_limits(&unpositioned, &p),
            Err(LimitError::Unpositioned {
                index: 1,
                axis: Axis::C
            })
        );
        let cases = [
            Move::Linked {
                x: 10.0,
                z: 1.0,
                c: 90.0,
                minutes: 0.0,
            },
            Move::Feed {
                x: Some(1.0),
                z: None,
                c: None,
                feed: f64::NAN,
            },
            Move::Rapid {
                x: Some(f64::INFINITY),
                z: None,
                c: None,
            },
        ];
        for case in cases {
            let prog = program(vec![rapid(10.0, 0.0, 0.0), case]);
            assert!(matches!(
                check_limits(&prog, &p),
                Err(LimitError::InvalidMove { index: 1, .. })
            ));
        }
        let slow_ring = program(vec![Move::SpindleOn { rpm: 100.0 }]);
        assert_eq!(
            check_limits(&slow_ring, &p),
            Err(LimitError::SpindleSpeed {
                index: 0,
                rpm: 100.0,
                min: 500.0,
                max: 6000.0
            })
        );
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_programs_never_panic(
            moves in proptest::collection::vec(
                (0..6u8, proptest::num::f64::ANY, proptest::num::f64::ANY, proptest::num::f64::ANY, proptest::num::f64::ANY),
                0..20,
            ),
        ) {
            let moves = moves.into_iter().map(|(kind, a, b, c, d)| match kind {
                0 => Move::Rapid { x: Some(a), z: Some(b).filter(|_| d > 0.0), c: Some(c) },
                1 => Move::Feed { x: Some(a), z: None, c: Some(c), feed: d },
                2 => Move::Linked { x: a, z: b, c, minutes: d },
                3 => Move::SpindleOn { rpm: a },
                4 => Move::Comment(String::new()),
                _ => Move::SpindleOff,
            }).collect();
            let prog = program(moves);
            for dialect in [Dialect::GrblHal, Dialect::LinuxCnc] {
                let p = profile(dialect);
                let _ = check_limits(&prog, &p);
                let _ = cycle_time_s(&prog, &p);
            }
        }
    }
}
