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
        if self.period.is_zero() || self.period.subsec_nanos() % 1000 != 0 {
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
            moves.push(SampledMove {
                index,
                from: position,
                to: end,
                start: cycle as f64 * period,
                duration: n as f64 * period,
                slowed,
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
mod tests {
    use super::*;
    use crate::program::Step;

    const MS: Duration = Duration::from_millis(1);

    fn config() -> SampleConfig {
        SampleConfig {
            period: 4 * MS,
            // 0.1 µm, and a 2^20-count encoder on C: not a whole number a degree.
            counts_per_unit: [10_000.0, 10_000.0, 1_048_576.0 / 360.0],
            max_rate: [3000.0, 3000.0, 72_000.0],
            spin_up: Some(Duration::from_millis(500)),
            dialect: Dialect::LinuxCnc,
        }
    }

    fn rapid(x: f64, z: f64, c: f64) -> Move {
        Move::Rapid {
            x: Some(x),
            z: Some(z),
            c: Some(c),
        }
    }

    fn linked(x: f64, z: f64, c: f64, minutes: f64) -> Move {
        Move::Linked { x, z, c, minutes }
    }

    fn program(moves: Vec<Move>) -> Program {
        Program { moves }
    }

    /// The test's own reading of a move's duration: linked moves their minutes, X/Z
    /// feeds length over F, C feeds degrees over F, rapids their slowest axis, M3 the
    /// spin-up, each at least its slowest axis at max rate.
    fn seconds(step: &Step<'_>, config: &SampleConfig) -> f64 {
        let d = Axis::ALL.map(|a| step.to.get(a).unwrap() - step.from.get(a).unwrap());
        let floor = (0..3)
            .map(|i| d[i].abs() * 60.0 / config.max_rate[i])
            .fold(0.0, f64::max);
        match *step.action {
            Move::Linked { minutes, .. } => (minutes * 60.0).max(floor),
            Move::Feed { feed, .. } => ((d[0].hypot(d[1]) + d[2].abs()) * 60.0 / feed).max(floor),
            Move::Rapid { .. } => floor,
            Move::SpindleOn { .. } => config.spin_up.unwrap().as_secs_f64(),
            _ => 0.0,
        }
    }

    /// The same in whole cycles: the next whole cycle up, at least one for any motion.
    fn cycle_seconds(step: &Step<'_>, config: &SampleConfig) -> f64 {
        let period = config.period.as_secs_f64();
        match seconds(step, config) {
            0.0 => 0.0,
            s => ((s / period - 1e-9).ceil()).max(1.0) * period,
        }
    }

    /// A short whirling-like program: rapid in, M3, plunge, linked moves, retract, M5.
    fn job() -> Program {
        program(vec![
            Move::Comment("test".into()),
            rapid(0.0, -13.45, 1.25),
            Move::SpindleOn { rpm: 1500.0 },
            Move::Feed {
                x: Some(2.5),
                z: None,
                c: None,
                feed: 50.0,
            },
            linked(2.6315, -13.4492, 3.8185, 1.0 / 1403.28),
            linked(2.7864, -13.4484, 6.5944, 1.0 / 1296.84),
            linked(2.9671, -13.4476, 9.3269, 1.0 / 1317.5),
            linked(3.0, -13.4, 12.0, 0.0005),
            rapid(0.0, -13.4, 12.0),
            Move::SpindleOff,
        ])
    }

    #[test]
    fn set_points_lie_on_the_straight_segments() {
        let config = config();
        let start = Position::known(0.0, 0.0, 0.0);
        let program = job();
        let sp = sample(&program, start, &config).unwrap();
        let scale = config.counts_per_unit;
        let period = config.period.as_secs_f64();
        // The segments in program units, with their times, from the program itself.
        let mut segments = Vec::new();
        let mut t = 0.0;
        for step in program.steps(start) {
            let from = Axis::ALL.map(|a| step.from.get(a).unwrap());
            let to = Axis::ALL.map(|a| step.to.get(a).unwrap());
            let d = cycle_seconds(&step, &config);
            if d > 0.0 {
                segments.push((from, to, t, t + d));
            }
            t += d;
        }
        // Every junction is a set-point, exactly: the drives turn the polyline's corners
        // rather than cutting across them.
        for &(_, to, _, t1) in &segments {
            let cycle = (t1 / period).round() as usize;
            let exact: [i64; 3] = std::array::from_fn(|i| (to[i] * scale[i]).round() as i64);
            assert_eq!(sp.points[cycle - 1], exact, "the junction at {t1} s");
        }
        for (k, point) in sp.points.iter().enumerate() {
            let time = (k + 1) as f64 * period;
            let &(from, to, t0, t1) = segments
                .iter()
                .find(|s| time < s.3)
                .unwrap_or(segments.last().unwrap());
            let f = ((time - t0) / (t1 - t0)).min(1.0);
            for i in 0..3 {
                let exact = (from[i] + (to[i] - from[i]) * f) * scale[i];
                // Half a count for the ends' rounding, half for the fraction's.
                assert!(
                    (point[i] as f64 - exact).abs() <= 1.0 + 1e-6,
                    "point {k} axis {i}: {} vs {exact}",
                    point[i]
                );
            }
        }
        assert_eq!(sp.end(), [0, -134_000, (12.0 * scale[2]).round() as i64]);
    }

    #[test]
    fn consecutive_set_points_stay_within_max_rate_times_period() {
        let config = config();
        let sp = sample(&job(), Position::known(0.0, 0.0, 0.0), &config).unwrap();
        let period = config.period.as_secs_f64();
        let limit: [f64; 3] =
            std::array::from_fn(|i| config.max_rate[i] / 60.0 * period * config.counts_per_unit[i]);
        let mut previous = sp.start;
        let mut fastest = [0i64; 3];
        for point in &sp.points {
            for i in 0..3 {
                let step = (point[i] - previous[i]).abs();
                // One count of quantization on top of the rate.
                assert!(
                    step as f64 <= limit[i] + 1.0,
                    "axis {i}: {step} > {}",
                    limit[i]
                );
                fastest[i] = fastest[i].max(step);
            }
            previous = *point;
        }
        // The rapids reach the limits, up to whole cycles (2000 counts a 4 ms cycle at
        // 50 mm/s): the retract's 30 000 counts of X are exactly 15 cycles; the rapid in's
        // 134 500 counts of Z need 67.25, so take 68 of 1978.
        assert!(fastest[0] as f64 >= limit[0] - 1.0, "X: {}", fastest[0]);
        assert!((fastest[1] - 134_500 / 68).abs() <= 1, "Z: {}", fastest[1]);
    }

    #[test]
    fn each_move_takes_its_time_rounded_up_to_whole_cycles() {
        for period_ms in [2, 4, 5, 10] {
            let config = SampleConfig {
                period: period_ms * MS,
                ..config()
            };
            let period = config.period.as_secs_f64();
            let start = Position::known(0.0, 0.0, 0.0);
            let sp = sample(&job(), start, &config).unwrap();
            let program = job();
            let steps: Vec<Step<'_>> = program.steps(start).collect();
            let programmed: f64 = steps.iter().map(|s| seconds(s, &config)).sum();
            let whole: f64 = steps.iter().map(|s| cycle_seconds(s, &config)).sum();
            assert!((sp.duration() - whole).abs() < 1e-9);
            assert!((sp.points.len() as f64 * period - whole).abs() < 1e-9);
            // At most a cycle a move slower than programmed.
            assert!(
                whole >= programmed - 1e-9 && whole < programmed + sp.moves.len() as f64 * period,
                "{period_ms} ms: {whole} s for {programmed} s"
            );
            for m in &sp.moves {
                let cycles = m.duration / period;
                assert!((cycles - cycles.round()).abs() < 1e-9 && cycles >= 1.0 - 1e-9);
            }
            // The last set-point is the program's end, exactly.
            let c_end = (12.0 * config.counts_per_unit[2]).round() as i64;
            assert_eq!(sp.end(), [0, -134_000, c_end]);
        }
    }

    #[test]
    fn c_beyond_700_000_degrees_stays_exact() {
        // 10 000 counts a degree: 700 000° is 7·10⁹ counts, beyond INTEGER32.
        let config = SampleConfig {
            counts_per_unit: [10_000.0, 10_000.0, 10_000.0],
            spin_up: None,
            ..config()
        };
        let c0 = 700_000.0;
        let start = Position::known(30.0, 0.0, c0);
        // Two turns in 0.01 min each, the second a thousandth of a degree short.
        let program = program(vec![
            linked(30.0, 0.5, c0 + 360.0, 0.01),
            linked(30.0, 1.0, c0 + 719.999, 0.01),
        ]);
        let sp = sample(&program, start, &config).unwrap();
        assert!(sp.start[2] > i64::from(i32::MAX));
        assert_eq!(sp.start[2], 7_000_000_000);
        assert_eq!(sp.moves[0].to[2], 7_003_600_000);
        assert_eq!(sp.end()[2], 7_007_199_990);
        // 0.6 s a move at 4 ms: 150 cycles each, the move's end exactly on its last one.
        assert_eq!(sp.points.len(), 300);
        assert_eq!(sp.points[149][2], 7_003_600_000);
        // Equal turns give equal steps: 3 600 000 counts in 150 cycles, 24 000 each.
        for k in 0..150 {
            assert_eq!(sp.points[k][2], 7_000_000_000 + 24_000 * (k as i64 + 1));
        }
        // On the wire the low 32 bits: differences survive the wrap, and a drive's 32-bit
        // position reads back as the path's counts.
        let mut previous = sp.start[2];
        for point in &sp.points {
            let wire_step = to_wire(point[2]).wrapping_sub(to_wire(previous));
            assert_eq!(i64::from(wire_step), point[2] - previous);
            assert_eq!(unwrap_near(to_wire(point[2]), previous), point[2]);
            previous = point[2];
        }
        assert_eq!(to_wire(7_000_000_000), 7_000_000_000_i64 as i32);
        assert_eq!(unwrap_near(to_wire(-5), 3), -5);
        assert_eq!(
            unwrap_near(i32::MIN, i64::from(i32::MAX)),
            i64::from(i32::MAX) + 1
        );
    }

    #[test]
    fn a_move_faster_than_an_axis_allows_is_slowed() {
        let config = config();
        // 10 mm of X in 0.1 min is 100 mm/min, fine; 10 mm in 0.001 min is 10 000 mm/min,
        // above 3000: it takes 10 / 50 mm/s = 0.2 s instead of 0.06 s.
        let program = program(vec![
            linked(10.0, 0.0, 0.0, 0.1),
            linked(20.0, 0.0, 0.0, 0.001),
        ]);
        let sp = sample(&program, Position::known(0.0, 0.0, 0.0), &config).unwrap();
        assert!(!sp.moves[0].slowed);
        assert!(sp.moves[1].slowed);
        assert!((sp.moves[0].duration - 6.0).abs() < 1e-9);
        assert!((sp.moves[1].duration - 0.2).abs() < 1e-9);
        assert_eq!(sp.points.len(), 1550);
        for pair in sp.points[1500..].windows(2) {
            assert_eq!(pair[1][0] - pair[0][0], 2000);
        }
    }

    #[test]
    fn feeds_run_along_x_and_z_or_c_alone() {
        let config = SampleConfig {
            spin_up: None,
            ..config()
        };
        let feed =
            |x: Option<f64>, z: Option<f64>, c: Option<f64>, feed| Move::Feed { x, z, c, feed };
        // 3-4-5: 5 mm at 60 mm/min is 5 s; C alone, 90° at 1800 deg/min is 3 s.
        let apart = program(vec![
            feed(Some(3.0), Some(4.0), None, 60.0),
            feed(None, None, Some(90.0), 1800.0),
        ]);
        let sp = sample(&apart, Position::known(0.0, 0.0, 0.0), &config).unwrap();
        assert!((sp.moves[0].duration - 5.0).abs() < 1e-9);
        assert!((sp.moves[1].duration - 3.0).abs() < 1e-9);
        assert_eq!(sp.points.len(), 2000);
        // X 1 mm with C 1° at F100, shared by the controller's rule: LinuxCNC runs F along
        // X (0.6 s), grbl along the length of both (√2 · 0.6 s).
        let mixed = program(vec![feed(Some(1.0), None, Some(1.0), 100.0)]);
        let start = Position::known(0.0, 0.0, 0.0);
        let linuxcnc = sample(&mixed, start, &config).unwrap();
        assert!((linuxcnc.moves[0].duration - 0.6).abs() < 1e-9);
        let grbl = SampleConfig {
            dialect: Dialect::GrblHal,
            ..config
        };
        let grbl = sample(&mixed, start, &grbl).unwrap();
        let expected = (0.6 * 2f64.sqrt() / 0.004).ceil() * 0.004;
        assert!((grbl.moves[0].duration - expected).abs() < 1e-9);
    }

    #[test]
    fn spindle_moves_are_marks_with_a_spin_up_hold_or_refused() {
        let config = config();
        let sp = sample(&job(), Position::known(0.0, 0.0, 0.0), &config).unwrap();
        // The rapid in takes 13.45 mm / 50 mm/s = 0.269 s, 68 cycles of 4 ms (0.272 s):
        // M3 is due once cycle 68 is sent, and the motion holds 500 ms, 125 cycles, from
        // there.
        assert_eq!(
            sp.marks[0],
            Mark {
                index: 2,
                cycle: 68,
                spindle: Some(1500.0)
            }
        );
        let held = sp.points[67];
        assert_eq!(
            held,
            [
                0,
                -134_500,
                (1.25 * config.counts_per_unit[2]).round() as i64
            ]
        );
        let hold_end = 68 + 125;
        assert!(sp.points[67..hold_end].iter().all(|p| *p == held));
        assert_ne!(sp.points[66], held);
        assert_ne!(sp.points[hold_end], held);
        assert_eq!(sp.marks[1].index, 9);
        assert_eq!(sp.marks[1].spindle, None);
        assert_eq!(sp.marks[1].cycle, sp.points.len());
        // No spin-up: the ring is not the bridge's, M3 and M5 are refused by move.
        let refuse = SampleConfig {
            spin_up: None,
            ..config.clone()
        };
        let err = sample(&job(), Position::known(0.0, 0.0, 0.0), &refuse).unwrap_err();
        assert_eq!(err, SampleError::Spindle { index: 2 });
        assert!(err.to_string().starts_with("move 2 (not a file line)"));
        let off = program(vec![Move::SpindleOff]);
        assert_eq!(
            sample(&off, Position::known(0.0, 0.0, 0.0), &refuse),
            Err(SampleError::Spindle { index: 0 })
        );
        // A zero spin-up marks without holding.
        let none = SampleConfig {
            spin_up: Some(Duration::ZERO),
            ..config
        };
        let sp = sample(&job(), Position::known(0.0, 0.0, 0.0), &none).unwrap();
        assert!(sp.moves.iter().all(|m| m.index != 2));
        assert_eq!(sp.marks.len(), 2);
    }

    #[test]
    fn an_unknown_or_broken_start_is_refused() {
        let config = config();
        let err = sample(&job(), Position::UNKNOWN, &config).unwrap_err();
        assert!(matches!(err, SampleError::Start { axis: Axis::X, .. }));
        assert!(err.to_string().starts_with("start X: not known"));
        let partly = Position {
            c: None,
            ..Position::known(0.0, 0.0, 0.0)
        };
        assert!(matches!(
            sample(&job(), partly, &config),
            Err(SampleError::Start { axis: Axis::C, .. })
        ));
        let err = sample(&job(), Position::known(0.0, f64::NAN, 0.0), &config).unwrap_err();
        assert_eq!(err.to_string(), "start Z: NaN is not finite");
        // Outside what a linear axis's INTEGER32 holds: 300 m at 10 000 counts a mm.
        let err = sample(&job(), Position::known(300_000.0, 0.0, 0.0), &config).unwrap_err();
        assert_eq!(
            err,
            SampleError::Range {
                index: None,
                axis: Axis::X,
                value: 300_000.0,
                counts: 3e9,
                limit: "INTEGER32, which a linear axis's target must fit"
            }
        );
        assert_eq!(
            err.to_string(),
            "start X 300000 is 3000000000 counts, beyond INTEGER32, which a linear axis's \
             target must fit"
        );
    }

    #[test]
    fn impossible_moves_are_refused_by_index() {
        let config = config();
        let start = Position::known(0.0, 0.0, 0.0);
        let cases = [
            (
                linked(1.0, 0.0, 0.0, 0.0),
                "move time 0 min is not above zero",
            ),
            (
                linked(1.0, 0.0, 0.0, f64::NAN),
                "move time NaN min is not above zero",
            ),
            (
                Move::Feed {
                    x: Some(1.0),
                    z: None,
                    c: None,
                    feed: -5.0,
                },
                "feed -5 is not above zero",
            ),
            (rapid(f64::INFINITY, 0.0, 0.0), "X target inf is not finite"),
            (
                Move::SpindleOn { rpm: 0.0 },
                "spindle speed 0 rpm is not above zero",
            ),
        ];
        for (case, problem) in cases {
            let program = program(vec![Move::Comment("first".into()), case]);
            assert_eq!(
                sample(&program, start, &config),
                Err(SampleError::InvalidMove {
                    index: 1,
                    problem: problem.into()
                })
            );
        }
        // C beyond 2^53 counts; Z beyond INTEGER32.
        let far = program(vec![rapid(0.0, 0.0, 1e13)]);
        let err = sample(&far, start, &config).unwrap_err();
        assert!(matches!(
            err,
            SampleError::Range {
                index: Some(0),
                axis: Axis::C,
                ..
            }
        ));
        assert!(err.to_string().contains("beyond 2^53"));
        let long = program(vec![rapid(0.0, -250_000.0, 0.0)]);
        assert!(matches!(
            sample(&long, start, &config),
            Err(SampleError::Range {
                index: Some(0),
                axis: Axis::Z,
                ..
            })
        ));
    }

    #[test]
    fn bad_configurations_are_refused() {
        let start = Position::known(0.0, 0.0, 0.0);
        let cases = [
            (
                SampleConfig {
                    period: Duration::ZERO,
                    ..config()
                },
                "set-point sampling: period 0ns must be a non-zero whole number of microseconds",
            ),
            (
                SampleConfig {
                    period: Duration::from_nanos(2_000_500),
                    ..config()
                },
                "set-point sampling: period 2.0005ms must be a non-zero whole number of microseconds",
            ),
            (
                SampleConfig {
                    counts_per_unit: [1.0, 0.0, 1.0],
                    ..config()
                },
                "set-point sampling: counts_per_unit 0 must be finite and above zero",
            ),
            (
                SampleConfig {
                    max_rate: [1.0, 1.0, f64::NAN],
                    ..config()
                },
                "set-point sampling: max_rate NaN must be finite and above zero",
            ),
        ];
        for (config, message) in cases {
            assert_eq!(
                sample(&job(), start, &config).unwrap_err().to_string(),
                message
            );
        }
    }

    #[test]
    fn a_program_without_motion_holds_the_start() {
        let config = config();
        let sp = sample(
            &program(vec![Move::Comment("nothing".into())]),
            Position::known(1.0, 2.0, 3.0),
            &config,
        )
        .unwrap();
        assert!(sp.points.is_empty());
        assert_eq!(sp.end(), sp.start);
        assert_eq!(sp.start[0], 10_000);
        assert_eq!(sp.duration(), 0.0);
    }

    #[test]
    fn for_machine_takes_the_profiles_rates() {
        let profile = MachineProfile::builtin_sim().unwrap();
        let config = SampleConfig::for_machine(&profile, 2 * MS, [1.0; 3], None);
        assert_eq!(config.max_rate, [3000.0, 3000.0, 72_000.0]);
        assert_eq!(config.period, 2 * MS);
    }

    #[test]
    fn for_drives_takes_their_cycle_scales_and_spin_up() {
        let machine = MachineProfile::builtin_sim().unwrap();
        let drives: DriveSettings =
            toml::from_str("counts_per_mm = [10000.0, 20000.0]\ncounts_per_degree = 3000.0")
                .unwrap();
        let config = SampleConfig::for_drives(&machine, &drives);
        assert_eq!(config.period, 4 * MS);
        assert_eq!(config.counts_per_unit, [10_000.0, 20_000.0, 3000.0]);
        assert_eq!(config.max_rate, [3000.0, 3000.0, 72_000.0]);
        assert_eq!(config.spin_up, Some(Duration::from_secs(2)));
    }
}
