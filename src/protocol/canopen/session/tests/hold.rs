//! The caller's hold and resume: the set-points slowed along the path to a stand and back.

use super::*;

/// The straight stretches of the path: the start, then every set-point.
fn path(sp: &SetPoints) -> Vec<[i64; 3]> {
    std::iter::once(sp.start)
        .chain(sp.points.iter().copied())
        .collect()
}

/// Whether `target` lies on one of the path's straight stretches, to a count.
fn on_path(path: &[[i64; 3]], target: [i64; 3]) -> bool {
    path.windows(2).any(|w| {
        let (a, b) = (w[0], w[1]);
        let longest = (0..3).max_by_key(|&i| (b[i] - a[i]).abs()).unwrap();
        let span = (b[longest] - a[longest]) as f64;
        let f = if span == 0.0 {
            0.0
        } else {
            (target[longest] - a[longest]) as f64 / span
        };
        (-1e-9..=1.0 + 1e-9).contains(&f)
            && (0..3).all(|i| {
                let expected = a[i] as f64 + (b[i] - a[i]) as f64 * f;
                (expected - target[i] as f64).abs() <= 1.0
            })
    })
}

#[test]
fn a_hold_slows_the_path_to_a_stand_on_it_and_a_resume_brings_it_back() {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let drives = [1, 2, 3].map(DriveConfig::new);
    // A ramp of ten 2 ms cycles.
    let config = SessionConfig {
        hold_ramp: 20 * MS,
        ..config()
    };
    let mut bench = Bench::new(sp.clone(), config, drives, false);
    bench.run_until(|s| s.progress().0 >= 30);
    let held_at = bench.cycles().len();
    bench.session.hold();
    while !bench.events.iter().any(|e| matches!(e, Event::Held { .. })) {
        assert_eq!(bench.session.phase(), Phase::Running, "{:?}", bench.events);
        bench.step(MS);
    }
    let held_after = bench.cycles().len();
    // Held: ten more cycles (still sending the last set-points) and the targets stand.
    let standing = bench.cycles().len();
    for _ in 0..30 {
        bench.step(MS);
    }
    let cycles = bench.cycles();
    let targets = |c: &Cycle| c.1.map(|t| t.map(|(_, target)| target));
    assert!(
        cycles[standing..]
            .windows(2)
            .all(|w| targets(&w[0]) == targets(&w[1])),
        "the drives stand while held"
    );
    assert!(cycles.len() > standing + 10);
    bench.session.resume();
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    assert!(bench.events.contains(&Event::Resumed));
    let cycles = bench.cycles();
    // Every target of the run lies on the path, and the path's end was reached.
    let path = path(&sp);
    let first = bench.enabled_syncs();
    let run: Vec<[i64; 3]> = cycles[first..]
        .iter()
        .filter_map(|c| {
            let t = targets(c);
            Some([t[0]? as i64, t[1]? as i64, t[2]? as i64])
        })
        .collect();
    for (k, t) in run.iter().enumerate() {
        assert!(on_path(&path, *t), "cycle {k}: {t:?} is off the path");
    }
    assert_eq!(*run.last().unwrap(), sp.end());
    // The stand came within the ramp, and the steps along the path shrank on the way.
    assert!(held_after - held_at <= 12, "{held_at} → {held_after}");
    let steps: Vec<i64> = run
        .windows(2)
        .map(|w| (0..3).map(|i| (w[1][i] - w[0][i]).abs()).max().unwrap())
        .collect();
    let slowing = &steps[held_at - first..held_after - first - 1];
    assert!(
        slowing.windows(2).all(|w| w[1] <= w[0] + 1),
        "the path slows, never speeds up, while holding: {slowing:?}"
    );
    // Every corner of the polyline was a target: the drives turned it, never cut across.
    let period = sp.period.as_secs_f64();
    for m in &sp.moves {
        let end = ((m.start + m.duration) / period).round() as usize;
        let corner = sp.points[end - 1];
        assert!(run.contains(&corner), "the corner {corner:?} was cut");
    }
}

#[test]
fn a_hold_before_the_set_points_start_keeps_the_drives_at_the_start() {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let drives = [1, 2, 3].map(DriveConfig::new);
    let mut bench = Bench::new(sp.clone(), config(), drives, false);
    bench.session.hold();
    bench.run_until(|s| s.phase() == Phase::Running);
    for _ in 0..100 {
        bench.step(MS);
    }
    assert_eq!(bench.session.progress().0, 0);
    let cycles = bench.cycles();
    let last = cycles
        .last()
        .unwrap()
        .1
        .map(|t| t.map(|(_, target)| i64::from(target)));
    assert_eq!(last, sp.start.map(Some));
    bench.session.resume();
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
}
