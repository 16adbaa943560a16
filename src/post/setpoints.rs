//! The planned path as cyclic synchronous position set-points: a [`Program`] sampled at a
//! fixed cycle period into one (X, Z, C) target a cycle, in drive counts.
//!
//! In CSP mode (CiA 402, mode 8) the drives interpolate nothing: each SYNC they take the
//! target position the master sent in the cycle before and close their loops on it (in
//! interpolated position mode, 7, the same set-points go in 60C1h). So
//! the master is the interpolator, and the three drives stay coordinated only if all three
//! targets of a cycle are the same instant of the same straight move. [`sample`] computes
//! every cycle's targets before the first SYNC, so the cyclic phase only reads an array
//! and never waits for a planner.
//!
//! # Timing
//!
//! Each motion is a straight move in X, Z and C (the program's moves are straight in
//! joint space, as G-code's are), run at constant speed for the time the program's one
//! timing rule gives it ([`MoveTime`]): a linked move its `minutes`, a feed move its length
//! over the feed (shared between linear and rotary axes by the controller's rule, as the
//! limit check reads it), a rapid as fast as its slowest axis allows.
//!
//! Any of them is lengthened, if need be, so that no axis exceeds its max rate (grbl's
//! planner does the same, `limit_value_by_axis_maximum`): the path stays the same, only
//! slower ([`SampledMove::slowed`]). Acceleration is not limited: the drives see the planned
//! velocity steps at every junction.
//!
//! Each move then takes a whole number of cycles: its time is rounded up to the next
//! whole cycle (a move shorter than a cycle takes one). So every junction of the planned
//! polyline is a set-point, and the drives, which go straight from one set-point to the
//! next, follow the polyline itself rather than chords cut across its corners. (Sampled
//! at fixed times instead, a cycle straddling a junction of turn θ cuts it by up to
//! v·T·θ/4, on top of the polyline's own error and outside the planner's budget.) The
//! job runs at most a cycle a move slower; a slower pass changes the groove only through
//! the insert cusp, which shrinks with the workpiece's speed.
//!
//! The moves follow each other without gaps, and the set-point of cycle *k* (1-based) is
//! the path's position at time *k*·T. The last cycle is the path's end.
//!
//! # Counts and their width
//!
//! A position is `round(value × counts per unit)`; moves run between these rounded ends,
//! and a set-point is its move's start plus the rounded fraction of the move's difference,
//! so every set-point lies within half a count (per axis) of its straight segment, and a
//! move's last set-point is exactly its end.
//!
//! Counts are `i64`. A whirling job turns C for hours: 700 000° at 10 000 counts a degree
//! (a 22-bit encoder on a 1:1 spindle has 11 650) is 7·10⁹ counts, beyond INTEGER32's
//! 2.1·10⁹. f64 holds integers exactly up to 2⁵³, so counts up to ±2⁵³ (over 10⁹ turns at
//! that resolution) are computed exactly and refused beyond.
//!
//! Target position 607Ah is INTEGER32 on the bus, so [`to_wire`] sends a position's low
//! 32 bits: a CiA 402 drive with its position range limit (607Bh) at INTEGER32's full
//! range counts modulo 2³², and so follows a C that wraps, as long as one cycle's step
//! is below 2³¹ counts. [`unwrap_near`] reads a drive's 32-bit position back as the i64
//! nearest a known one. X and Z are linear axes: their counts must fit INTEGER32 and are
//! refused otherwise.
//!
//! # Spindle moves
//!
//! The whirling ring's spindle is not one of the three drives. With
//! [`SampleConfig::spin_up`] given, M3 and M5 become [`Mark`]s at the cycle where they
//! fall, for the caller who runs the spindle, and the motion holds still for the spin-up
//! time after M3; without it they are refused, naming the move, rather than a cut being
//! run with the ring standing still.

use std::time::Duration;

use thiserror::Error;

use crate::config::connection::DriveSettings;
use crate::config::machine::Axis;
use crate::config::machine::{Dialect, MachineProfile};
use crate::program::timing::MoveTime;
use crate::program::{Move, Position, Program};

/// The largest count magnitude computed exactly: 2⁵³, where f64 stops holding every
/// integer.
pub const MAX_COUNTS: i64 = 1 << 53;

/// How to sample: the cycle, the drives' scales and the axes' speed limits. Arrays are in
/// X, Z, C order ([`Axis::ALL`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SampleConfig {
    /// The cycle period (the SYNC period), non-zero, in whole microseconds as CiA 301's
    /// communication cycle period 1006h holds it.
    pub period: Duration,
    /// Drive counts per mm (X, Z) and per degree (C); positive, not necessarily whole.
    pub counts_per_unit: [f64; 3],
    /// Highest speed of each axis: mm/min (X, Z), deg/min (C), as machine profiles give it.
    pub max_rate: [f64; 3],
    /// How long the motion holds after M3 for the ring to reach its speed; `None` refuses
    /// spindle moves (see the module docs).
    pub spin_up: Option<Duration>,
    /// The rule by which the program's controller shares a feed between linear and rotary
    /// axes ([`feed_speeds`](crate::program::timing::feed_speeds)).
    pub dialect: Dialect,
}

impl SampleConfig {
    /// A configuration with `profile`'s max rates and feed rule.
    pub fn for_machine(
        profile: &MachineProfile,
        period: Duration,
        counts_per_unit: [f64; 3],
        spin_up: Option<Duration>,
    ) -> SampleConfig {
        SampleConfig {
            period,
            counts_per_unit,
            max_rate: Axis::ALL.map(|axis| profile.max_rate(axis)),
            spin_up,
            dialect: profile.dialect,
        }
    }

    /// How to sample a program for a profile's drives on `machine`: their cycle, their
    /// scales, the machine's max rates and their spin-up hold.
    pub fn for_drives(machine: &MachineProfile, drives: &DriveSettings) -> SampleConfig {
        SampleConfig::for_machine(
            machine,
            drives.period(),
            drives.counts_per_unit(),
            Some(drives.spin_up()),
        )
    }

    fn check(&self) -> Result<(), SampleError> {
        let config = |name, value: String, reason| SampleError::Config {
            name,
            value,
            reason,
        };
        if self.period.is_zero() || !self.period.subsec_nanos().is_multiple_of(1000) {
            return Err(config(
                "period",
                format!("{:?}", self.period),
                "must be a non-zero whole number of microseconds",
            ));
        }
        for (name, values) in [
            ("counts_per_unit", self.counts_per_unit),
            ("max_rate", self.max_rate),
        ] {
            if let Some(bad) = values.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
                return Err(config(
                    name,
                    bad.to_string(),
                    "must be finite and above zero",
                ));
            }
        }
        Ok(())
    }
}

/// Why a program cannot be sampled. Moves are named by their index in
/// [`Program::moves`].
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SampleError {
    /// A configuration value out of range.
    #[error("set-point sampling: {name} {value} {reason}")]
    Config {
        /// The field.
        name: &'static str,
        /// Its value.
        value: String,
        /// What it must be.
        reason: &'static str,
    },
    /// The start position is not fully known or not finite.
    #[error("start {axis}: {problem}")]
    Start {
        /// The axis.
        axis: Axis,
        /// What is wrong.
        problem: String,
    },
    /// A spindle move with no spin-up time given: the ring is not on this bus.
    #[error(
        "move {index} (not a file line) switches the ring spindle, which is not one of the \
         CAN drives; give a spin-up time so that the caller runs it, or take it out"
    )]
    Spindle {
        /// Move index.
        index: usize,
    },
    /// A value no move can have (not finite, zero or negative time or feed).
    #[error("move {index} (not a file line): {problem}")]
    InvalidMove {
        /// Move index.
        index: usize,
        /// What is wrong.
        problem: String,
    },
    /// A position beyond what the counts can hold.
    #[error("{}{axis} {value} is {counts:.0} counts, beyond {limit}", at(*.index))]
    Range {
        /// Move index; `None` for the start position.
        index: Option<usize>,
        /// The axis.
        axis: Axis,
        /// The position, mm or degrees.
        value: f64,
        /// Its counts.
        counts: f64,
        /// The limit it passes.
        limit: &'static str,
    },
}

fn at(index: Option<usize>) -> String {
    index.map_or("start ".into(), |i| format!("move {i} (not a file line): "))
}

/// One straight move as sampled: its ends in counts and its time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampledMove {
    /// The program's move (for a spin-up hold, the M3).
    pub index: usize,
    /// Start, counts.
    pub from: [i64; 3],
    /// End, counts.
    pub to: [i64; 3],
    /// When it starts, seconds from the first cycle's start: a whole number of cycles.
    pub start: f64,
    /// How long it takes, seconds: a whole number of cycles, at least one.
    pub duration: f64,
    /// Lengthened beyond the programmed time so that no axis exceeds its max rate (the
    /// rounding up to whole cycles aside).
    pub slowed: bool,
    /// How much faster a feed override may run it: its duration over the time its fastest
    /// axis takes at that axis's max rate, at least 1. Exactly 1 for a rapid and for the
    /// spindle's spin-up wait, which keep their own time at any override.
    pub speedup: f64,
    /// A feed move, which a feed override scales; a rapid and the spin-up wait (a dwell)
    /// it leaves alone, slower or faster, as grbl's does.
    pub feed: bool,
}

/// A spindle command at its place in the set-points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mark {
    /// The program's move.
    pub index: usize,
    /// Due once this many set-points have been sent: the first set-point at or past the
    /// move's time is the last of them, so the motion before the move has been
    /// commanded to its end.
    pub cycle: usize,
    /// `Some(rpm)`: M3; `None`: M5.
    pub spindle: Option<f64>,
}

/// A program's set-points; see the module docs.
#[derive(Debug, Clone, PartialEq)]
pub struct SetPoints {
    /// The cycle period.
    pub period: Duration,
    /// Where the path starts, counts (the drives' positions before the first cycle).
    pub start: [i64; 3],
    /// `points[k]`: the targets for cycle k + 1, the path's position at (k + 1)·period; the
    /// last is the path's end.
    pub points: Vec<[i64; 3]>,
    /// The straight moves sampled, in order, with their timing.
    pub moves: Vec<SampledMove>,
    /// Spindle commands, in order.
    pub marks: Vec<Mark>,
}

impl SetPoints {
    /// Where the path ends, counts.
    pub fn end(&self) -> [i64; 3] {
        self.points.last().copied().unwrap_or(self.start)
    }

    /// The path's duration, seconds: its cycles.
    pub fn duration(&self) -> f64 {
        self.moves.last().map_or(0.0, |m| m.start + m.duration)
    }
}

/// A position's 32 bits for 607Ah: the low 32 bits of its counts (wrapping; see the
/// module docs).
pub fn to_wire(counts: i64) -> i32 {
    counts as i32
}

/// The i64 position whose low 32 bits are `wire` and which is nearest `near`: a drive's
/// 32-bit position read back in the path's counts, exact while the two are within 2³¹.
pub fn unwrap_near(wire: i32, near: i64) -> i64 {
    near + i64::from(wire.wrapping_sub(to_wire(near)))
}

/// Samples `program` from `start` (every axis known: the drives' actual position) at
/// `config`'s cycle; see the module docs.
pub fn sample(
    program: &Program,
    start: Position,
    config: &SampleConfig,
) -> Result<SetPoints, SampleError> {
    config.check()?;
    let mut start_units = [0.0; 3];
    for (slot, axis) in Axis::ALL.into_iter().enumerate() {
        start_units[slot] = match start.get(axis) {
            None => {
                return Err(SampleError::Start {
                    axis,
                    problem: "not known: CSP set-points begin at the drives' actual positions, \
                              so every axis's start must be given"
                        .into(),
                })
            }
            Some(v) if !v.is_finite() => {
                return Err(SampleError::Start {
                    axis,
                    problem: format!("{v} is not finite"),
                })
            }
            Some(v) => v,
        };
    }
    let start_counts = counts(config, None, start_units)?;
    let mut moves = Vec::new();
    let mut marks = Vec::new();
    let period = config.period.as_secs_f64();
    // Whole cycles a move of `seconds` takes; a hair over a whole number is rounding.
    let cycles_of = |seconds: f64| ((seconds / period - 1e-9).ceil() as usize).max(1);
    // Cycles so far, and each move's first cycle and number of cycles.
    let mut cycle = 0;
    let mut spans: Vec<(usize, usize)> = Vec::new();
    let mut position = start_counts;
    for step in program.steps(start) {
        let index = step.index;
        let invalid = |problem: String| SampleError::InvalidMove { index, problem };
        match *step.action {
            Move::Comment(_) => continue,
            Move::SpindleOn { rpm } => {
                let spin_up = config.spin_up.ok_or(SampleError::Spindle { index })?;
                if !(rpm.is_finite() && rpm > 0.0) {
                    return Err(invalid(format!(
                        "spindle speed {rpm} rpm is not above zero"
                    )));
                }
                marks.push((index, cycle, Some(rpm)));
                if !spin_up.is_zero() {
                    let n = cycles_of(spin_up.as_secs_f64());
                    moves.push(SampledMove {
                        index,
                        from: position,
                        to: position,
                        start: cycle as f64 * period,
                        duration: n as f64 * period,
                        slowed: false,
                        speedup: 1.0,
                        feed: false,
                    });
                    spans.push((cycle, n));
                    cycle += n;
                }
                continue;
            }
            Move::SpindleOff => {
                config.spin_up.ok_or(SampleError::Spindle { index })?;
                marks.push((index, cycle, None));
                continue;
            }
            Move::Feed { feed, .. } if !(feed.is_finite() && feed > 0.0) => {
                return Err(invalid(format!("feed {feed} is not above zero")));
            }
            Move::Linked { minutes, .. } if !(minutes.is_finite() && minutes > 0.0) => {
                return Err(invalid(format!(
                    "move time {minutes} min is not above zero"
                )));
            }
            Move::Rapid { .. } | Move::Feed { .. } | Move::Linked { .. } => {}
        }
        // A known start keeps every axis known through `steps`.
        let units = |pose: Position| Axis::ALL.map(|a| pose.get(a).expect("a known start"));
        let (from, to) = (units(step.from), units(step.to));
        if let Some(slot) = (0..3).find(|&i| !to[i].is_finite()) {
            let axis = Axis::ALL[slot];
            return Err(invalid(format!("{axis} target {} is not finite", to[slot])));
        }
        let delta: [f64; 3] = std::array::from_fn(|i| to[i] - from[i]);
        let time = MoveTime::of(step.action, delta, config.dialect, config.max_rate)
            .expect("every motion has a time");
        let duration = time.within_max_rates() * 60.0;
        let slowed = time
            .programmed
            .is_some_and(|wanted| time.fastest > wanted * (1.0 + 1e-9));
        let end = counts(config, Some(index), to)?;
        if duration > 0.0 {
            let n = cycles_of(duration);
            let speedup = match step.action {
                Move::Rapid { .. } => 1.0,
                _ => (n as f64 * period / (time.fastest * 60.0)).max(1.0),
            };
            moves.push(SampledMove {
                index,
                from: position,
                to: end,
                start: cycle as f64 * period,
                duration: n as f64 * period,
                slowed,
                speedup,
                feed: !matches!(step.action, Move::Rapid { .. }),
            });
            spans.push((cycle, n));
            cycle += n;
        }
        position = end;
    }
    let mut points = Vec::with_capacity(cycle);
    for (m, &(first, n)) in moves.iter().zip(&spans) {
        for k in 1..=n {
            let f = k as f64 / n as f64;
            points.push(std::array::from_fn(|i| {
                m.from[i] + ((m.to[i] - m.from[i]) as f64 * f).round() as i64
            }));
        }
        debug_assert_eq!(points.len(), first + n);
    }
    let marks = marks
        .into_iter()
        .map(|(index, cycle, spindle)| Mark {
            index,
            cycle,
            spindle,
        })
        .collect();
    Ok(SetPoints {
        period: config.period,
        start: start_counts,
        points,
        moves,
        marks,
    })
}

/// A position's counts, range-checked.
fn counts(
    config: &SampleConfig,
    index: Option<usize>,
    units: [f64; 3],
) -> Result<[i64; 3], SampleError> {
    let mut out = [0; 3];
    for (slot, axis) in Axis::ALL.into_iter().enumerate() {
        let counts = (units[slot] * config.counts_per_unit[slot]).round();
        let limit = match axis {
            Axis::X | Axis::Z if counts.abs() > f64::from(i32::MAX) => {
                Some("INTEGER32, which a linear axis's target must fit")
            }
            _ if counts.abs() > MAX_COUNTS as f64 => Some("2^53, the exactly computed range"),
            _ => None,
        };
        if let Some(limit) = limit {
            return Err(SampleError::Range {
                index,
                axis,
                value: units[slot],
                counts,
                limit,
            });
        }
        out[slot] = counts as i64;
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
