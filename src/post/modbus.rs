//! The planned program as segments of the Modbus register map (`docs/modbus.md`): each
//! move in the map's units, the positions absolute machine positions in one continuous
//! frame. How a segment fills a slot's registers is the protocol's
//! ([`crate::protocol::modbus::map`]).

use thiserror::Error;

use crate::program::{Move, Program};

/// X and Z units per millimetre (0.1 µm).
pub const LINEAR_UNITS_PER_MM: f64 = 1e4;
/// C units per degree (10⁻⁴ °).
pub const ANGULAR_UNITS_PER_DEG: f64 = 1e4;

/// One segment of the register map (`docs/modbus.md`), in its units: X and Z in 0.1 µm
/// ([`LINEAR_UNITS_PER_MM`]), C in 10⁻⁴ ° ([`ANGULAR_UNITS_PER_DEG`]), absolute machine
/// positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Segment {
    /// A linked C/X/Z move that takes `duration_us` (G93 G1).
    Linked {
        /// Target X, 0.1 µm (radius).
        x: i32,
        /// Target Z, 0.1 µm.
        z: i32,
        /// Target C, 10⁻⁴ °.
        c: i64,
        /// Duration, µs, at least 1.
        duration_us: u32,
    },
    /// A rapid (G0); `None` axes do not move.
    Rapid {
        /// Target X, 0.1 µm.
        x: Option<i32>,
        /// Target Z, 0.1 µm.
        z: Option<i32>,
        /// Target C, 10⁻⁴ °.
        c: Option<i64>,
    },
    /// A feed move in units per minute (G94 G1); `None` axes do not move.
    Feed {
        /// Target X, 0.1 µm.
        x: Option<i32>,
        /// Target Z, 0.1 µm.
        z: Option<i32>,
        /// Target C, 10⁻⁴ °.
        c: Option<i64>,
        /// Feed, 0.001 mm/min (0.001 deg/min for C alone), at least 1.
        feed: u32,
    },
    /// A dwell (G4).
    Dwell {
        /// How long, µs.
        duration_us: u32,
    },
    /// The whirling ring on, clockwise (M3 S).
    SpindleOn {
        /// Speed, 0.001 rev/min.
        rpm: u32,
    },
    /// The whirling ring off (M5).
    SpindleOff,
    /// Program end (M2).
    ProgramEnd,
}

/// Why a program cannot be carried as segments, or its segments by a controller.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SegmentError {
    /// A move the map cannot carry.
    #[error("move {index} ({what}): {reason}")]
    Move {
        /// Its index in [`Program::moves`].
        index: usize,
        /// What kind of move.
        what: &'static str,
        /// Why.
        reason: String,
    },
    /// A linked move shorter than the controller can execute at its programmed duration.
    #[error(
        "segment {index} lasts {duration_us} µs; the controller \
         executes at most {rate} segments/s, so at least {min_us} µs"
    )]
    TooShort {
        /// Its index in the segment list.
        index: usize,
        /// Its duration, µs.
        duration_us: u32,
        /// `MAX_SEGMENT_RATE`.
        rate: u16,
        /// The shortest duration that rate allows, µs.
        min_us: u32,
    },
}

/// The program's moves as segments, in order, with a [`Segment::ProgramEnd`] after the
/// last (the program leaves the end to its posts, as the G-code writer writes M2).
/// Comments are dropped: nothing on the controller reads them.
///
/// Refused, naming the move: a value that is not finite or does not fit its field; a
/// linked move or feed that rounds to zero.
pub fn segments(program: &Program) -> Result<Vec<Segment>, SegmentError> {
    let mut out = Vec::with_capacity(program.moves.len() + 1);
    for (index, action) in carried(program) {
        let refuse = |what: &'static str, reason: String| SegmentError::Move {
            index,
            what,
            reason,
        };
        let linear = |what: &'static str, mm: f64| {
            linear_units(mm).ok_or_else(|| {
                refuse(
                    what,
                    format!("{mm} mm is not finite or beyond ±214 748.3647 mm (i32 of 0.1 µm)"),
                )
            })
        };
        let angular = |what: &'static str, deg: f64| {
            angular_units(deg).ok_or_else(|| {
                refuse(
                    what,
                    format!("{deg}° is not finite or beyond an i64 of 10⁻⁴ °"),
                )
            })
        };
        let segment = match *action {
            Move::Comment(_) => unreachable!("comments are not carried"),
            Move::Rapid { x, z, c } => Segment::Rapid {
                x: x.map(|v| linear("rapid", v)).transpose()?,
                z: z.map(|v| linear("rapid", v)).transpose()?,
                c: c.map(|v| angular("rapid", v)).transpose()?,
            },
            Move::Feed { x, z, c, feed } => Segment::Feed {
                x: x.map(|v| linear("feed move", v)).transpose()?,
                z: z.map(|v| linear("feed move", v)).transpose()?,
                c: c.map(|v| angular("feed move", v)).transpose()?,
                feed: thousandths(feed).filter(|&f| f > 0).ok_or_else(|| {
                    refuse(
                        "feed move",
                        format!("feed {feed} is not between 0.001 and 4 294 967.295 per minute"),
                    )
                })?,
            },
            Move::Linked { x, z, c, minutes } => Segment::Linked {
                x: linear("linked move", x)?,
                z: linear("linked move", z)?,
                c: angular("linked move", c)?,
                duration_us: micros(minutes * 60.0).filter(|&d| d > 0).ok_or_else(|| {
                    refuse(
                        "linked move",
                        format!(
                            "{minutes} min is not between 1 µs and 4 294.967295 s \
                                 (u32 of µs)"
                        ),
                    )
                })?,
            },
            Move::SpindleOn { rpm } => Segment::SpindleOn {
                rpm: thousandths(rpm).ok_or_else(|| {
                    refuse(
                        "spindle on",
                        format!("{rpm} rpm is not between 0 and 4 294 967.295 rpm"),
                    )
                })?,
            },
            Move::SpindleOff => Segment::SpindleOff,
        };
        out.push(segment);
    }
    out.push(Segment::ProgramEnd);
    Ok(out)
}

/// Which move of `program` each of [`segments`]'s segments comes from, in order: its index
/// in [`Program::moves`], and for the [`Segment::ProgramEnd`] after the last,
/// `program.moves.len()` (the program's end). A controller reports progress by segment
/// (`EXECUTED_SEQ`); this says it in the program's moves, where a stopped run resumes.
pub fn segment_moves(program: &Program) -> Vec<usize> {
    carried(program)
        .map(|(index, _)| index)
        .chain([program.moves.len()])
        .collect()
}

/// The moves that become segments, with their indices: all but comments, which nothing on
/// the controller reads.
fn carried(program: &Program) -> impl Iterator<Item = (usize, &Move)> {
    program
        .moves
        .iter()
        .enumerate()
        .filter(|(_, action)| !matches!(action, Move::Comment(_)))
}

/// Millimetres as 0.1 µm, rounded to nearest, if finite and within i32.
fn linear_units(mm: f64) -> Option<i32> {
    let v = (mm * LINEAR_UNITS_PER_MM).round();
    (f64::from(i32::MIN)..=f64::from(i32::MAX))
        .contains(&v)
        .then_some(v as i32)
}

/// Degrees as 10⁻⁴ °, rounded to nearest, if finite and within i64.
fn angular_units(deg: f64) -> Option<i64> {
    let v = (deg * ANGULAR_UNITS_PER_DEG).round();
    // −2⁶³ and 2⁶³ are exact in f64; i64 holds [−2⁶³, 2⁶³).
    (-9_223_372_036_854_775_808.0..9_223_372_036_854_775_808.0)
        .contains(&v)
        .then_some(v as i64)
}

/// A value in thousandths, rounded to nearest, if finite and within u32.
fn thousandths(value: f64) -> Option<u32> {
    let v = (value * 1000.0).round();
    (0.0..=f64::from(u32::MAX)).contains(&v).then_some(v as u32)
}

/// Seconds as µs, rounded to nearest, if finite and within u32.
fn micros(seconds: f64) -> Option<u32> {
    let v = (seconds * 1e6).round();
    (0.0..=f64::from(u32::MAX)).contains(&v).then_some(v as u32)
}

/// Checks that every linked move lasts at least 1 / `max_rate` s: a shorter one would
/// run slower than planned on a controller that executes at most `max_rate` segments a
/// second. Names the first that does not.
pub fn check_rate(segments: &[Segment], max_rate: u16) -> Result<(), SegmentError> {
    let min_us = 1_000_000u32.div_ceil(u32::from(max_rate.max(1)));
    for (index, segment) in segments.iter().enumerate() {
        if let Segment::Linked { duration_us, .. } = *segment {
            if duration_us < min_us {
                return Err(SegmentError::TooShort {
                    index,
                    duration_us,
                    rate: max_rate,
                    min_us,
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_program_becomes_segments_in_order() {
        let program = Program {
            moves: vec![
                Move::Comment("groove".into()),
                Move::Rapid {
                    x: Some(30.0),
                    z: None,
                    c: Some(0.0),
                },
                Move::SpindleOn { rpm: 2500.5 },
                Move::Feed {
                    x: Some(24.0001),
                    z: None,
                    c: None,
                    feed: 100.0,
                },
                Move::Linked {
                    x: 24.0,
                    z: 0.5,
                    c: 360.0,
                    minutes: 0.5 / 60.0,
                },
                Move::SpindleOff,
            ],
        };
        assert_eq!(
            segments(&program).unwrap(),
            vec![
                Segment::Rapid {
                    x: Some(300_000),
                    z: None,
                    c: Some(0)
                },
                Segment::SpindleOn { rpm: 2_500_500 },
                Segment::Feed {
                    x: Some(240_001),
                    z: None,
                    c: None,
                    feed: 100_000
                },
                Segment::Linked {
                    x: 240_000,
                    z: 5_000,
                    c: 3_600_000,
                    duration_us: 500_000
                },
                Segment::SpindleOff,
                Segment::ProgramEnd,
            ]
        );
    }

    #[test]
    fn each_segment_names_the_move_it_comes_from() {
        let program = Program {
            moves: vec![
                Move::Comment("lead-in".into()),
                Move::SpindleOn { rpm: 2500.0 },
                Move::Comment("cut".into()),
                Move::Comment("still the cut".into()),
                Move::Linked {
                    x: 24.0,
                    z: 0.5,
                    c: 360.0,
                    minutes: 0.01,
                },
                Move::SpindleOff,
            ],
        };
        let moves = segment_moves(&program);
        // One per segment: the comments carry none, and the program end is past the last
        // move.
        assert_eq!(moves.len(), segments(&program).unwrap().len());
        assert_eq!(moves, vec![1, 4, 5, 6]);
        assert_eq!(segment_moves(&Program { moves: vec![] }), vec![0]);
    }

    #[test]
    fn moves_the_map_cannot_carry_are_named() {
        let refused = |action: Move| {
            let program = Program {
                moves: vec![Move::Comment("x".into()), action],
            };
            match segments(&program) {
                Err(SegmentError::Move { index, what, .. }) => (index, what),
                other => panic!("expected a refusal, got {other:?}"),
            }
        };
        let linked = |x: f64, c: f64, minutes: f64| Move::Linked {
            x,
            z: 0.0,
            c,
            minutes,
        };
        assert_eq!(refused(linked(f64::NAN, 0.0, 1.0)).1, "linked move");
        // i32 of 0.1 µm ends at 214 748.3647 mm.
        assert_eq!(refused(linked(214_748.4, 0.0, 1.0)).0, 1);
        assert_eq!(refused(linked(0.0, f64::INFINITY, 1.0)).0, 1);
        assert_eq!(refused(linked(0.0, 1e16, 1.0)).0, 1);
        // Half a µs rounds to zero; 72 min is beyond u32 µs (71.58 min).
        assert_eq!(refused(linked(0.0, 0.0, 0.4e-6 / 60.0)).0, 1);
        assert_eq!(refused(linked(0.0, 0.0, 72.0)).0, 1);
        let rapid = Move::Rapid {
            x: None,
            z: Some(-1e9),
            c: None,
        };
        assert_eq!(refused(rapid).1, "rapid");
        let rapid_c = Move::Rapid {
            x: None,
            z: None,
            c: Some(f64::NAN),
        };
        assert_eq!(refused(rapid_c).1, "rapid");
        let feed = |x: f64, feed: f64| Move::Feed {
            x: Some(x),
            z: None,
            c: None,
            feed,
        };
        assert_eq!(refused(feed(1.0, 0.0)).1, "feed move");
        assert_eq!(refused(feed(1.0, 5e6)).1, "feed move");
        assert_eq!(refused(feed(f64::NAN, 1.0)).1, "feed move");
        let feed_c = Move::Feed {
            x: None,
            z: None,
            c: Some(1e300),
            feed: 1.0,
        };
        assert_eq!(refused(feed_c).1, "feed move");
        assert_eq!(refused(Move::SpindleOn { rpm: -1.0 }).1, "spindle on");
        // The message names the move.
        let err = segments(&Program {
            moves: vec![Move::SpindleOn { rpm: -1.0 }],
        })
        .unwrap_err();
        assert!(
            err.to_string().starts_with("move 0 (spindle on): "),
            "{err}"
        );
    }

    #[test]
    fn rate_check_names_the_short_segment() {
        let linked = |duration_us| Segment::Linked {
            x: 0,
            z: 0,
            c: 0,
            duration_us,
        };
        // 1000 segments/s: 1 ms each at least.
        let segs = [Segment::SpindleOff, linked(1000), linked(999)];
        assert_eq!(check_rate(&segs[..2], 1000), Ok(()));
        assert_eq!(
            check_rate(&segs, 1000),
            Err(SegmentError::TooShort {
                index: 2,
                duration_us: 999,
                rate: 1000,
                min_us: 1000
            })
        );
        // 3 segments/s: ⌈333 333.3⌉ µs.
        assert!(matches!(
            check_rate(&[linked(333_333)], 3),
            Err(SegmentError::TooShort {
                min_us: 333_334,
                ..
            })
        ));
    }
}
