//! The gentle stop ([`Session::stop_held`]), the stall, and where the drives are known to
//! be ([`Session::resume_move`]): the module docs' "Stopping" and "Where the drives are".

use super::*;

/// The sampled move whose straight stretch holds `point` (within a count on every axis),
/// and whether `point` is its end: the drives standing there have run the moves before it,
/// and this one only if they stand at its end.
fn standing_on(sp: &SetPoints, point: [i64; 3]) -> Option<(usize, bool)> {
    sp.moves.iter().find_map(|m| {
        let longest = (0..3).max_by_key(|&i| (m.to[i] - m.from[i]).abs())?;
        let span = (m.to[longest] - m.from[longest]) as f64;
        let f = if span == 0.0 {
            0.0
        } else {
            (point[longest] - m.from[longest]) as f64 / span
        };
        let on = (0.0..=1.0).contains(&f)
            && (0..3).all(|i| {
                let expected = m.from[i] as f64 + (m.to[i] - m.from[i]) as f64 * f;
                (expected - point[i] as f64).abs() <= 1.0
            });
        (on && span != 0.0).then_some((m.index, point == m.to))
    })
}

fn actuals(session: &Session) -> [i64; 3] {
    session.drives().map(|d| d.actual.expect("a TPDO seen"))
}

/// Controlword 0x02: quick stop (CiA 402).
const QUICK_STOP: u16 = 0x02;

#[test]
fn a_gentle_stop_holds_the_path_then_disables_without_a_quick_stop() {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let config = SessionConfig {
        hold_ramp: 20 * MS,
        ..config()
    };
    let drives = [1, 2, 3].map(DriveConfig::new);
    let mut bench = Bench::new(sp.clone(), config, drives, false);
    bench.run_until(|s| s.progress().0 >= 20);
    let stop_at = bench.cycles().len();
    let why = "SIGINT".to_owned();
    bench
        .session
        .stop_held(StopReason::Interrupted { why: why.clone() }, bench.now);
    // A resume does not undo it.
    bench.session.resume();
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Stopped);
    assert_eq!(bench.stopped(), Some(&StopReason::Interrupted { why }));
    // Stopped (at once), the path held, then every drive confirmed disabled.
    let order: Vec<&str> = bench
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Stopped { .. } => Some("stopped"),
            Event::Held { .. } => Some("held"),
            Event::Halted { .. } => Some("halted"),
            _ => None,
        })
        .collect();
    assert_eq!(order, ["stopped", "held", "halted"]);
    assert_eq!(bench.halted(), Some(&vec![]));
    assert!(bench
        .drives
        .iter()
        .all(|d| d.power_state() == SimPower::SwitchOnDisabled));
    // No quick stop: the drives were walked down as at a job's end.
    let cycles = bench.cycles();
    assert!(cycles[stop_at..]
        .iter()
        .all(|c| c.1.iter().flatten().all(|r| r.0 != QUICK_STOP)));
    // Short of the path's end, where the drives stand says where to resume.
    assert!(bench.session.progress().0 < sp.points.len());
    let stand = actuals(&bench.session);
    let (index, at_end) = standing_on(&sp, stand).expect("the drives stand on the path");
    let expected = if at_end { index + 1 } else { index };
    assert_eq!(
        bench.session.resume_move(),
        expected,
        "standing at {stand:?}"
    );
}

#[test]
fn a_gentle_stop_before_the_set_points_is_a_stop_and_after_them_the_job_finishes() {
    let mut bench = Bench::plain();
    let why = "before".to_owned();
    bench
        .session
        .stop_held(StopReason::Interrupted { why: why.clone() }, Duration::ZERO);
    bench.step(MS);
    assert_eq!(bench.session.phase(), Phase::Stopped);
    assert_eq!(bench.stopped(), Some(&StopReason::Interrupted { why }));
    // Nothing known reached: the program from its first move.
    assert_eq!(bench.session.resume_move(), 0);
    // After the last set-point: the drives settle at the path's end and the job finishes.
    let mut bench = Bench::plain();
    bench.run_until(|s| s.progress().0 == s.progress().1);
    let why = "late".to_owned();
    bench
        .session
        .stop_held(StopReason::Interrupted { why }, bench.now);
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    assert_eq!(bench.stopped(), None);
}

#[test]
fn drives_that_do_not_stand_after_a_gentle_stop_get_the_quick_stop() {
    let config = SessionConfig {
        hold_ramp: 20 * MS,
        ..config()
    };
    let drives = [1, 2, 3].map(DriveConfig::new);
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let mut bench = Bench::new(sp, config.clone(), drives, false);
    bench.run_until(|s| s.progress().0 >= 20);
    // Node 1's reports are frozen where it was: it never reads at its held target.
    let frozen = bench.session.drives()[0].actual.unwrap() as i32 - 1000;
    bench.tamper = Some(Box::new(move |f: CanFrame| {
        if f.id().raw() == 0x181 {
            let mut data = f.data().to_vec();
            data[2..6].copy_from_slice(&frozen.to_le_bytes());
            return Some(std(0x181, &data));
        }
        Some(f)
    }));
    let stop_at = bench.now;
    let why = "SIGTERM".to_owned();
    bench
        .session
        .stop_held(StopReason::Interrupted { why }, bench.now);
    bench.run_to_end();
    let reasons: Vec<&StopReason> = bench
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Stopped { reason } => Some(reason),
            _ => None,
        })
        .collect();
    let waited = config.hold_ramp + config.settle_timeout;
    assert_eq!(
        reasons[1],
        &StopReason::NoStand {
            node: node(1),
            axis: Axis::X,
            window: config.settle_window,
            waited
        }
    );
    // The quick stop came at the limit (the hold ramp and the settle timeout), not before.
    let quick = bench
        .cycles()
        .into_iter()
        .find(|c| c.0 > stop_at && c.1[0].is_some_and(|r| r.0 == QUICK_STOP))
        .expect("a quick stop");
    assert!(quick.0 >= stop_at + waited, "{:?}", quick.0);
    assert!(quick.0 <= stop_at + waited + 2 * PERIOD, "{:?}", quick.0);
}

#[test]
fn drives_that_report_nothing_new_while_the_path_moves_are_a_stall() {
    let limit = 20 * MS;
    let config = SessionConfig {
        hold_ramp: 20 * MS,
        stall_timeout: Some(limit),
        ..config()
    };
    let drives = [1, 2, 3].map(DriveConfig::new);
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let mut bench = Bench::new(sp, config, drives, false);
    bench.run_until(|s| s.progress().0 >= 20);
    // Every TPDO repeats what it said last: the set-points move on, the reports do not.
    let mut last: std::collections::HashMap<u32, Vec<u8>> = Default::default();
    bench.tamper = Some(Box::new(move |f: CanFrame| {
        let id = f.id().raw();
        if (0x181..=0x183).contains(&id) {
            let data = last.entry(id).or_insert_with(|| f.data().to_vec()).clone();
            return Some(std(id as u16, &data));
        }
        Some(f)
    }));
    bench.run_to_end();
    assert_eq!(
        bench.stopped(),
        Some(&StopReason::Stalled { waited: limit })
    );
    assert_eq!(
        bench.stopped().unwrap().to_string(),
        "nothing new from the drives for 0.02 s: the path held to a stand, then the drives \
         disabled"
    );
}

#[test]
fn the_callers_hold_and_a_spin_up_are_no_stall() {
    // The spin-up holds the set-points for 10 ms, five cycles; the stall limit is four.
    let config = SessionConfig {
        hold_ramp: 20 * MS,
        stall_timeout: Some(4 * PERIOD),
        ..config()
    };
    let drives = [1, 2, 3].map(DriveConfig::new);
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let mut bench = Bench::new(sp, config, drives, false);
    bench.run_until(|s| s.progress().0 >= 20);
    bench.session.hold();
    for _ in 0..100 {
        bench.step(MS);
    }
    bench.session.resume();
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished, "{:?}", bench.events);
    assert_eq!(bench.stopped(), None);
}
