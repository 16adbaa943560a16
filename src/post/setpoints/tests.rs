//! The set-point sampler: timing, counts, spindle marks, refusals by move.

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
    let feed = |x: Option<f64>, z: Option<f64>, c: Option<f64>, feed| Move::Feed { x, z, c, feed };
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
        toml::from_str("counts_per_mm = [10000.0, 20000.0]\ncounts_per_degree = 3000.0").unwrap();
    let config = SampleConfig::for_drives(&machine, &drives);
    assert_eq!(config.period, 4 * MS);
    assert_eq!(config.counts_per_unit, [10_000.0, 20_000.0, 3000.0]);
    assert_eq!(config.max_rate, [3000.0, 3000.0, 72_000.0]);
    assert_eq!(config.spin_up, Some(Duration::from_secs(2)));
}
