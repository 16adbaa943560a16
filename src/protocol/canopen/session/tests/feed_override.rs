//! The feed override on the bridge's own set-point clock: it speeds the feed moves up to
//! what the axes' max rates allow and no further, and leaves rapids and the spin-up wait
//! at their own time, as grbl's feed override does.

use super::*;

/// The sampled speed-ups of [`setpoints`]' moves, from its program and max rates: the
/// linked moves turn C 60° in 60 ms, 60 000°/min against C's 72 000, so 1.2; the rapid
/// and the spin-up wait 1.
#[test]
fn a_moves_speed_up_is_what_its_fastest_axis_leaves_and_none_for_rapids_and_waits() {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let speedups: Vec<f64> = sp.moves.iter().map(|m| m.speedup).collect();
    assert_eq!(speedups.len(), 4, "{:?}", sp.moves);
    assert_eq!(speedups[0], 1.0, "the spin-up wait");
    assert!((speedups[1] - 1.2).abs() < 1e-9, "{speedups:?}");
    assert!((speedups[2] - 1.2).abs() < 1e-9, "{speedups:?}");
    assert_eq!(speedups[3], 1.0, "the rapid");
}

/// At 200 %, no cycle moves an axis further than its max rate allows in a cycle (to the
/// count the rounding of a target may add), the linked moves run at C's max rate, and the
/// rapid at the speed it runs at 100 %.
#[test]
fn at_200_percent_no_axis_exceeds_its_max_rate_and_the_rapid_keeps_its_own() {
    let (sp, steps) = steps_at(200);
    // Counts a cycle at each axis's max rate: X and Z 3000 mm/min, C 72 000°/min.
    let period = sp.period.as_secs_f64();
    let most = [3000.0, 3000.0, 72_000.0].map(|rate| rate / 60.0 * period);
    let most: [f64; 3] = std::array::from_fn(|i| most[i] * SCALE[i]);
    for (k, step) in steps.iter().enumerate() {
        for i in 0..3 {
            assert!(
                step[i] as f64 <= most[i] + 1.0,
                "cycle {k}: axis {i} moves {} counts, its max rate {}",
                step[i],
                most[i]
            );
        }
    }
    // C at its max rate on the linked moves (240 counts a 2 ms cycle), which 100 % runs
    // at 200; the rapid's X at its max rate, 100 counts a cycle, as at 100 %.
    let c_most = steps.iter().map(|s| s[2]).max().unwrap();
    assert!((c_most - 240).abs() <= 1, "C's largest step {c_most}");
    let x_back = steps.iter().map(|s| s[0]).max().unwrap();
    assert!((x_back - 100).abs() <= 1, "X's largest step {x_back}");
}

/// At 50 %, the linked moves run at half their speed and the rapid at its own: a feed
/// override slows the feed, not the rapids (grbl's has a rapid override of its own).
#[test]
fn at_50_percent_the_feed_moves_run_at_half_speed_and_the_rapid_at_its_own() {
    let (_, steps) = steps_at(50);
    // C's 200 counts a cycle at 100 % on the linked moves, 100 at half from their first
    // cycle on (the spin-up wait before them keeps its own time, and the clock starts the
    // feed at the override, not ramping down to it); the rapid's X at its max rate, 100
    // counts a cycle, as at 100 %.
    let c: Vec<i64> = steps.iter().map(|s| s[2]).filter(|&c| c > 0).collect();
    assert!(c.iter().all(|&c| c <= 101), "C's steps {c:?}");
    let at_half = c.iter().filter(|&&c| c >= 99).count();
    assert!(at_half + 3 >= c.len(), "C's steps {c:?}");
    let x_back = steps.iter().map(|s| s[0]).max().unwrap();
    assert!((x_back - 100).abs() <= 1, "X's largest step {x_back}");
}

/// [`setpoints`] run to their end at a feed override of `percent`: the set-points, and how
/// far each axis's target moves from one enabled cycle to the next, counts.
fn steps_at(percent: u16) -> (SetPoints, Vec<[i64; 3]>) {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let drives = [1, 2, 3].map(DriveConfig::new);
    let mut bench = Bench::new(sp.clone(), config(), drives, false);
    bench.session.feed_override(percent);
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    let first = bench.enabled_syncs();
    let run: Vec<[i64; 3]> = bench.cycles()[first..]
        .iter()
        .filter_map(|c| {
            let t = c.1.map(|t| t.map(|(_, target)| i64::from(target)));
            Some([t[0]?, t[1]?, t[2]?])
        })
        .collect();
    assert_eq!(*run.last().unwrap(), sp.end());
    let steps = run
        .windows(2)
        .map(|w| std::array::from_fn(|i| (w[1][i] - w[0][i]).abs()))
        .collect();
    (sp, steps)
}
