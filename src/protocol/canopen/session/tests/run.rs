//! Jobs that run: from boot-up to disabled drives in either mode, one set-point a SYNC,
//! late polls, C past the 32-bit range, and frames meant for others.

use super::*;

#[test]
fn a_job_runs_from_boot_up_to_disabled_drives() {
    let mut bench = Bench::plain();
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    // The boot-ups went by unheard: reset communication after the wait, then each
    // node boots, is configured, started, enabled; M3 and M5 in their places.
    let kinds: Vec<String> = bench
        .events
        .iter()
        .map(|e| {
            format!("{e:?}")
                .split([' ', '('])
                .next()
                .unwrap()
                .to_string()
        })
        .collect();
    assert_eq!(
        kinds,
        [
            "ResetCommunication",
            "BootUp",
            "BootUp",
            "BootUp",
            "Configured",
            "Configured",
            "Configured",
            "Started",
            "Enabled",
            "Spindle",
            "Spindle",
            "Settled",
            "Finished"
        ]
    );
    assert_eq!(
        bench.events[0],
        Event::ResetCommunication {
            nodes: vec![node(1), node(2), node(3)]
        }
    );
    // The wait starts at the first poll, 1 ms in.
    assert_eq!(bench.sent[0], (51 * MS, std(0x000, &[0x82, 1])));
    // Every set-point once, in order, three RPDOs then the SYNC that applies them.
    let cycles = bench.cycles();
    let first = bench.enabled_syncs();
    for (k, point) in sp.points.iter().enumerate() {
        let (_, rpdos) = cycles[first + k];
        for axis in 0..3 {
            assert_eq!(
                rpdos[axis],
                Some((0x0F, to_wire(point[axis]))),
                "set-point {k}"
            );
        }
    }
    assert_eq!(bench.session.progress(), (sp.points.len(), sp.points.len()));
    // Polled every millisecond: exactly one SYNC a 2 ms period, from the first to the
    // last.
    for pair in cycles.windows(2) {
        assert_eq!(pair[1].0 - pair[0].0, PERIOD);
    }
    // The drives are where the path ends, and disabled; the session saw them there.
    for (k, drive) in bench.drives.iter().enumerate() {
        assert_eq!(i64::from(drive.position()), sp.end()[k]);
        assert_eq!(drive.power_state(), SimPower::SwitchOnDisabled);
        assert_eq!(bench.session.drives()[k].actual, Some(sp.end()[k]));
    }
    // The walk up was one transition a cycle: 06, 07, 0F, then the set-points.
    let walk: Vec<u16> = cycles[..first]
        .iter()
        .filter_map(|c| c.1[0].map(|r| r.0))
        .collect();
    assert_eq!(walk, [0x06, 0x07, 0x0F]);
    // Nothing more after the end.
    let before = bench.sent.len();
    bench.step(10 * MS);
    assert_eq!(bench.sent.len(), before);
}

#[test]
fn an_ip_job_enables_ip_mode_before_the_set_points() {
    let mut bench = Bench::with(Operation::InterpolatedPosition);
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    assert!(bench.stopped().is_none());
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    let cycles = bench.cycles();
    // SYNC 1 asks for the TPDOs, 2-4 walk to Operation enabled, 5 enables ip mode:
    // the set-points start with SYNC 6.
    let first = bench.enabled_syncs();
    assert_eq!(first, 5);
    for axis in 0..3 {
        let walk: Vec<u16> = cycles[..first]
            .iter()
            .filter_map(|c| c.1[axis].map(|r| r.0))
            .collect();
        assert_eq!(walk, [0x06, 0x07, 0x0F, 0x1F], "node {}", axis + 1);
        // Held where they stand (60C1h = the actual position) meanwhile.
        assert!(cycles[..first]
            .iter()
            .all(|c| c.1[axis].is_none_or(|r| r.1 == 0)));
        // Each TPDO answers a SYNC: Switch on disabled, Ready to switch on, Switched
        // on, Operation enabled with ip mode inactive, then active (bit 12).
        let words = bench.statuswords(axis as u16 + 1);
        let shown: Vec<u16> = words[..5].iter().map(|w| w.1).collect();
        assert_eq!(shown, [0x0250, 0x0231, 0x0233, 0x0237, 0x1237]);
        // Bit 12 came with the SYNC that carried 0x1F, before the first set-point.
        assert_eq!(words[4].0, cycles[first - 1].0);
        assert!(words[4].0 < cycles[first].0);
    }
    // Every set-point once, in order, with enable ip mode.
    for (k, point) in sp.points.iter().enumerate() {
        let (_, rpdos) = cycles[first + k];
        for axis in 0..3 {
            assert_eq!(
                rpdos[axis],
                Some((0x1F, to_wire(point[axis]))),
                "set-point {k}"
            );
        }
    }
    assert_eq!(bench.session.progress(), (sp.points.len(), sp.points.len()));
    // Disabled after settling: bit 4 gone with the disable voltage.
    let last = cycles.last().unwrap().1;
    assert_eq!(last.map(|r| r.unwrap().0), [0x00; 3]);
    for (k, drive) in bench.drives.iter().enumerate() {
        assert_eq!(i64::from(drive.position()), sp.end()[k]);
        assert_eq!(i64::from(drive.interpolation_data()), sp.end()[k]);
        assert_eq!(drive.target(), 0, "607Ah is not the set-point in IP mode");
        assert_eq!(drive.power_state(), SimPower::SwitchOnDisabled);
    }
}

#[test]
fn set_points_wait_until_every_drive_shows_ip_mode_active() {
    // Node 2 shows ip mode inactive for its first three TPDOs in Operation enabled
    // with bit 4 (a drive slow to take it up): everyone is held at the start meanwhile.
    let mut bench = Bench::with(Operation::InterpolatedPosition);
    let mut held = 3;
    bench.tamper = Some(Box::new(move |f: CanFrame| {
        if f.id().raw() == 0x182 && f.data()[..2] == [0x37, 0x12] && held > 0 {
            held -= 1;
            let mut data = f.data().to_vec();
            data[1] = 0x02;
            return Some(std(0x182, &data));
        }
        Some(f)
    }));
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    let first = bench.enabled_syncs();
    assert_eq!(first, 8);
    let cycles = bench.cycles();
    for axis in 0..3 {
        let walk: Vec<u16> = cycles[..first]
            .iter()
            .filter_map(|c| c.1[axis].map(|r| r.0))
            .collect();
        assert_eq!(walk, [0x06, 0x07, 0x0F, 0x1F, 0x1F, 0x1F, 0x1F]);
    }
    assert!(cycles[..first]
        .iter()
        .all(|c| c.1.iter().flatten().all(|r| r.1 == 0)));
    // The first set-point went out after node 2's first TPDO with bit 12.
    let shown = bench
        .statuswords(2)
        .into_iter()
        .find(|w| w.1 & 0x1000 != 0)
        .unwrap();
    assert_eq!(shown.0, cycles[first - 1].0);
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    assert_eq!(cycles[first].1[1], Some((0x1F, to_wire(sp.points[0][1]))));
    // A drive that never shows it times out, named for what it lacks.
    let mut bench = Bench::with(Operation::InterpolatedPosition);
    bench.tamper = Some(statusword(2, 0x0237));
    bench.run_to_end();
    assert_eq!(bench.session.progress().0, 0);
    assert_eq!(
        bench.stopped().unwrap().to_string(),
        "node 2 (Z) not in Operation enabled after 100ms: OperationEnabled (statusword \
         0x0237) without ip mode active (bit 12)"
    );
}

#[test]
fn every_set_point_is_executed_once_in_either_mode() {
    let sp = setpoints(Position::known(0.0, 0.0, 0.0));
    for operation in [
        Operation::CyclicSynchronousPosition,
        Operation::InterpolatedPosition,
    ] {
        let mut bench = Bench::with(operation);
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished, "{operation}");
        for (k, drive) in bench.drives.iter_mut().enumerate() {
            // The drive's own record of the cycles it followed set-points in.
            let executed: Vec<(i32, i32)> = drive
                .take_events()
                .into_iter()
                .filter_map(|e| match e {
                    SimEvent::Cycle { target, actual, .. } => Some((target, actual)),
                    _ => None,
                })
                .collect();
            // The enabling cycle at the start, then each set-point once, in order,
            // then (if any) the end held while the session saw it settle.
            let mut expected = vec![to_wire(sp.start[k])];
            expected.extend(sp.points.iter().map(|p| to_wire(p[k])));
            assert!(executed.len() >= expected.len(), "{operation}, node {k}");
            let (head, rest) = executed.split_at(expected.len());
            let set_points: Vec<i32> = head.iter().map(|c| c.0).collect();
            assert_eq!(set_points, expected, "{operation}, node {k}");
            assert!(rest.iter().all(|c| c.0 == to_wire(sp.end()[k])));
            // Each cycle ended at its set-point: the drives kept up.
            assert!(executed.iter().all(|(target, actual)| target == actual));
        }
    }
}

#[test]
fn announced_drives_need_no_reset() {
    let drives = [1, 2, 3].map(DriveConfig::new);
    let mut bench = Bench::new(
        setpoints(Position::known(0.0, 0.0, 0.0)),
        config(),
        drives,
        true,
    );
    bench.run_until(|s| s.phase() == Phase::Configuring);
    assert_eq!(bench.now, MS);
    assert!(bench
        .events
        .iter()
        .all(|e| !matches!(e, Event::ResetCommunication { .. })));
    assert_eq!(
        bench.events[..3],
        [1, 2, 3].map(|n| Event::BootUp { node: node(n) })
    );
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
}

#[test]
fn a_late_poll_is_reported_and_sends_one_cycle() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Running);
    let syncs = bench.cycles().len();
    let due = bench.cycles().last().unwrap().0 + PERIOD;
    // 1 ms late: jitter, no report, the schedule keeps its phase.
    bench.step(due + MS - bench.now);
    assert_eq!(bench.cycles().len(), syncs + 1);
    assert!(bench
        .events
        .iter()
        .all(|e| !matches!(e, Event::Late { .. })));
    bench.step(MS);
    assert_eq!(
        bench.cycles().len(),
        syncs + 2,
        "the next one at its own time"
    );
    // 7 ms without a poll: one cycle, not four, and a report.
    let due = bench.cycles().last().unwrap().0 + PERIOD;
    bench.step(7 * MS);
    assert_eq!(bench.cycles().len(), syncs + 3);
    let late_by = bench.now - due;
    assert_eq!(
        bench.events.last(),
        Some(&Event::Late {
            sync: syncs as u64 + 3,
            late_by
        })
    );
    // The schedule restarts from the late poll, and every set-point still goes out
    // once: the path is slowed, not cut.
    let restart = bench.now;
    bench.step(MS);
    assert_eq!(bench.cycles().len(), syncs + 3);
    bench.step(MS);
    assert_eq!(bench.cycles().last().unwrap().0, restart + PERIOD);
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    let (sent, total) = bench.session.progress();
    assert_eq!(sent, total);
}

#[test]
fn c_past_the_32_bit_range_runs_and_reads_back_unwrapped() {
    // C starts 1000 counts below INTEGER32's top and turns 12 000 counts on.
    let c0 = (f64::from(i32::MAX) - 1000.0) / SCALE[2];
    let sp = setpoints(Position::known(0.0, 0.0, c0));
    assert!(sp.end()[2] > i64::from(i32::MAX));
    let mut drives = [1, 2, 3].map(DriveConfig::new);
    drives[2].position = to_wire(sp.start[2]);
    let mut bench = Bench::new(sp.clone(), config(), drives, false);
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    assert_eq!(bench.drives[2].position(), to_wire(sp.end()[2]));
    assert!(
        bench.drives[2].position() < 0,
        "the drive's counter wrapped"
    );
    assert_eq!(bench.session.drives()[2].actual, Some(sp.end()[2]));
}

#[test]
fn frames_for_others_are_ignored() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Running);
    let ext = CanFrame::new(CanId::Extended(0x181), &[0x18, 0x02, 0, 0, 0, 0]).unwrap();
    let rtr = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
    for frame in [
        std(0x709, &[0x00]),
        std(0x089, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
        std(0x181 + 0x100, &[0x18, 0x02, 0, 0, 0, 0]),
        std(0x601, &[0x40, 0, 0, 0, 0, 0, 0, 0]),
        std(0x081, &[0x11]),
        ext,
        rtr,
    ] {
        bench.session.receive(&frame, bench.now);
    }
    bench.step(MS);
    assert_eq!(bench.session.phase(), Phase::Running);
    assert!(bench.stopped().is_none());
}
