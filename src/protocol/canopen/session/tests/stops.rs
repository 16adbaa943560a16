//! What stops a job: missing boot-ups, lost heartbeats, emergencies, reboots, NMT and
//! statusword states out of line, short TPDOs, a drive away from the start, phases that
//! time out, and an operator's stop; then the quick stop and disable that follow.

use super::*;
use crate::protocol::canopen::cia301::Emergency;

#[test]
fn an_ip_drive_leaving_ip_mode_while_running_stops_the_job() {
    let mut bench = Bench::with(Operation::InterpolatedPosition);
    bench.run_until(|s| s.progress().0 == 10);
    // One TPDO of node 3 shows Operation enabled without ip mode active.
    let mut once = true;
    bench.tamper = Some(Box::new(move |f: CanFrame| {
        if f.id().raw() == 0x183 && once {
            once = false;
            let mut data = f.data().to_vec();
            data[..2].copy_from_slice(&0x0237u16.to_le_bytes());
            return Some(std(0x183, &data));
        }
        Some(f)
    }));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::IpModeInactive {
            node: node(3),
            axis: Axis::C,
            statusword: 0x0237
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 3 (C) left interpolated position mode: statusword 0x0237 shows ip mode \
         inactive (bit 12), its set-points ignored"
    );
    assert!(bench.session.progress().0 < 12);
    // Quick stop, then disable voltage: neither with bit 4.
    let cycles = bench.cycles();
    let stop = cycles
        .iter()
        .position(|c| c.1[0].is_some_and(|r| r.0 == 0x02))
        .unwrap();
    assert!(cycles[stop..]
        .iter()
        .all(|c| c.1.iter().flatten().all(|r| r.0 & 0x10 == 0)));
    assert_eq!(bench.halted(), Some(&vec![]));
    assert!(bench
        .drives
        .iter()
        .all(|d| d.power_state() == SimPower::SwitchOnDisabled));
}

#[test]
fn a_silent_node_stops_the_job_before_it_starts() {
    let mut bench = Bench::plain();
    bench.pulled = Some(1);
    for id in [0x701, 0x703] {
        bench.session.receive(&std(id, &[0x00]), Duration::ZERO);
    }
    bench.run_to_end();
    // Nodes 1 and 3 announced themselves; node 2 is reset at 51 ms, given up at 101.
    assert_eq!(
        bench.events[2],
        Event::ResetCommunication {
            nodes: vec![node(2)]
        }
    );
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::NoBootUp {
            node: node(2),
            axis: Axis::Z
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 2 (Z) sent no boot-up message, even after NMT reset communication"
    );
    assert_eq!(bench.now, 101 * MS);
    assert_eq!(bench.halted(), Some(&vec![]));
    assert!(bench.sent.iter().all(|(_, f)| f.id().raw() == 0x000));
}

#[test]
fn a_lost_heartbeat_stops_every_drive_and_names_the_node() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.progress().0 == 20);
    let pulled_at = bench.now;
    bench.pulled = Some(2);
    bench.run_to_end();
    let reason = bench.stopped().unwrap().clone();
    assert_eq!(
        reason,
        StopReason::HeartbeatLost {
            node: node(3),
            axis: Axis::C,
            timeout: 30 * MS
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 3 (C) heartbeat lost: none for 30ms (cable, power or a crashed drive)"
    );
    // Heard last at most one 10 ms period before the pull: stopped within 40 ms.
    let stopped_at = bench
        .cycles()
        .iter()
        .find(|c| c.1[0].is_some_and(|r| r.0 == 0x02))
        .unwrap()
        .0;
    assert!(
        stopped_at > pulled_at && stopped_at <= pulled_at + 41 * MS,
        "{stopped_at:?}"
    );
    // Quick stop to all (C never hears it), standstill, disable voltage; X and Z end
    // in Switch on disabled, C unconfirmed.
    // (A simulated drive stops dead: the first TPDO after the quick stop shows it
    // still.)
    let words: Vec<Option<u16>> = bench
        .cycles()
        .iter()
        .rev()
        .take(3)
        .map(|c| c.1[0].map(|r| r.0))
        .collect();
    assert_eq!(words, [Some(0x00), Some(0x02), Some(0x0F)]);
    assert_eq!(bench.drives[0].power_state(), SimPower::SwitchOnDisabled);
    assert_eq!(bench.drives[1].power_state(), SimPower::SwitchOnDisabled);
    assert_eq!(bench.halted(), Some(&vec![node(3)]));
    assert_eq!(bench.session.phase(), Phase::Stopped);
}

#[test]
fn a_malformed_heartbeat_keeps_nobody_alive() {
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| {
        Some(if f.id().raw() == 0x702 && f.data() == [0x05] {
            std(0x702, &[0x05, 0x00])
        } else {
            f
        })
    }));
    bench.run_to_end();
    assert!(matches!(
        bench.stopped(),
        Some(StopReason::HeartbeatLost { axis: Axis::Z, .. })
    ));
}

#[test]
fn an_emergency_stops_the_job_with_its_code_and_meaning() {
    // C's drive moves 50 counts a cycle where the path asks 200: it falls behind by
    // 150 a cycle and trips its 1000-count window.
    let mut drives = [1, 2, 3].map(DriveConfig::new);
    drives[2].max_step = 50;
    let mut bench = Bench::new(
        setpoints(Position::known(0.0, 0.0, 0.0)),
        config(),
        drives,
        false,
    );
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::Emergency {
            node: node(3),
            axis: Axis::C,
            code: 0x8611,
            meaning: "following error"
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 3 (C) emergency 0x8611: following error"
    );
    assert!(bench
        .events
        .iter()
        .any(|e| matches!(e, Event::Emergency(m) if m.code == 0x8611)));
    // The faulted drive stays faulted; the others are quick-stopped and disabled.
    assert_eq!(bench.drives[2].power_state(), SimPower::Fault);
    assert_eq!(bench.drives[0].power_state(), SimPower::SwitchOnDisabled);
    assert_eq!(bench.drives[1].power_state(), SimPower::SwitchOnDisabled);
    assert_eq!(bench.halted(), Some(&vec![]));
    let last = bench.cycles().last().unwrap().1;
    assert_eq!(last[2], None, "no word for a faulted drive");
}

#[test]
fn an_error_reset_emergency_is_only_reported() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Running);
    bench.session.receive(&std(0x081, &[0; 8]), bench.now);
    bench.step(MS);
    assert_eq!(bench.session.phase(), Phase::Running);
    assert!(bench
        .events
        .iter()
        .any(|e| matches!(e, Event::Emergency(m) if m.is_reset())));
}

#[test]
fn a_reboot_during_the_job_stops_it() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Running);
    // Someone resets node 1's communication: it boots again with its default objects.
    bench.drives[0].receive(&Frame::data(0x000, &[0x82, 1]));
    bench.step(MS);
    assert_eq!(
        bench.stopped(),
        Some(&StopReason::Rebooted {
            node: node(1),
            axis: Axis::X
        })
    );
}

#[test]
fn a_node_leaving_operational_stops_the_job() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Running);
    // NMT stop for node 2 from elsewhere: its heartbeat says Stopped, its PDOs cease.
    bench.drives[1].receive(&Frame::data(0x000, &[0x02, 2]));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::NotOperational {
            node: node(2),
            axis: Axis::Z,
            state: NmtState::Stopped
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 2 (Z) left NMT Operational: its heartbeat shows Stopped"
    );
    // It no longer answers: it cannot be confirmed disabled.
    assert_eq!(bench.halted(), Some(&vec![node(2)]));
}

#[test]
fn statuswords_out_of_line_stop_the_job() {
    let cases = [
        (
            1,
            0x0218,
            StopReason::Fault {
                node: node(1),
                axis: Axis::X,
                statusword: 0x0218,
            },
        ),
        (
            3,
            0x1217,
            StopReason::LeftOperation {
                node: node(3),
                axis: Axis::C,
                state: PowerState::QuickStopActive,
            },
        ),
        (
            2,
            0x0048,
            StopReason::Statusword {
                node: node(2),
                axis: Axis::Z,
                statusword: 0x0048,
            },
        ),
    ];
    for (id, word, expected) in cases {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.progress().0 == 10);
        bench.tamper = Some(statusword(id, word));
        bench.run_to_end();
        assert_eq!(bench.stopped(), Some(&expected));
        assert!(bench.session.progress().0 < 20);
    }
    assert_eq!(
        StopReason::Fault {
            node: node(1),
            axis: Axis::X,
            statusword: 0x0218
        }
        .to_string(),
        "node 1 (X) faulted (statusword 0x0218)"
    );
}

#[test]
fn a_short_tpdo_stops_the_job() {
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| {
        Some(if f.id().raw() == 0x181 {
            std(0x181, &f.data()[..3])
        } else {
            f
        })
    }));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::Tpdo {
            node: node(1),
            axis: Axis::X,
            len: 3
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 1 (X): TPDO1 of 3 bytes, its mapping (6041h, 6064h) has 6"
    );
    // Stopped while enabling: nothing was running, the others confirm at once.
    assert_eq!(bench.halted(), Some(&vec![node(1)]));
}

#[test]
fn a_drive_away_from_the_paths_start_is_not_enabled() {
    let mut drives = [1, 2, 3].map(DriveConfig::new);
    drives[1].position = 500;
    let tolerant = SessionConfig {
        start_tolerance: 100,
        ..config()
    };
    let mut bench = Bench::new(
        setpoints(Position::known(0.0, 0.0, 0.0)),
        tolerant.clone(),
        drives.clone(),
        false,
    );
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::StartMismatch {
            node: node(2),
            axis: Axis::Z,
            actual: 500,
            start: 0,
            tolerance: 100
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 2 (Z) stands at 500 counts, the path starts at 0: more than the 100 counts allowed"
    );
    assert!(
        bench.cycles().iter().all(|c| c.1[1].is_none()),
        "node 2 never commanded"
    );
    // Within the tolerance it runs, from where it stands.
    let lenient = SessionConfig {
        start_tolerance: 500,
        ..tolerant
    };
    let mut bench = Bench::new(
        setpoints(Position::known(0.0, 0.0, 0.0)),
        lenient,
        drives,
        false,
    );
    bench.run_to_end();
    assert_eq!(bench.session.phase(), Phase::Finished);
    assert_eq!(bench.cycles()[1].1[1], Some((0x06, 500)));
}

#[test]
fn phases_that_do_not_end_time_out() {
    // Node 2 seems to stay in Switch on disabled.
    let mut bench = Bench::plain();
    bench.tamper = Some(statusword(2, 0x0250));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        reason.to_string(),
        "node 2 (Z) not in Operation enabled after 100ms: SwitchOnDisabled (statusword 0x0250)"
    );
    // Node 3 sends no TPDO at all.
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| (f.id().raw() != 0x183).then_some(f)));
    bench.run_to_end();
    assert!(matches!(
        bench.stopped(),
        Some(StopReason::EnableTimeout { node: n, state, .. }) if *n == node(3) && state == "no TPDO seen"
    ));
    // Node 1 cannot follow the last jump of the path (its window switched off).
    let mut sp = setpoints(Position::known(0.0, 0.0, 0.0));
    sp.points.last_mut().unwrap()[0] = 1_000_000;
    let unbounded = SessionConfig {
        following_error_window: u32::MAX,
        ..config()
    };
    let mut bench = Bench::new(sp, unbounded, [1, 2, 3].map(DriveConfig::new), false);
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert!(
        matches!(reason, StopReason::NotSettled { node: n, target: 1_000_000, .. } if *n == node(1))
    );
    assert!(reason.to_string().starts_with("node 1 (X) at "));
    assert!(reason
        .to_string()
        .ends_with("did not settle within 0 counts of 1000000 in 100ms"));
    // Node 1 seems to stay enabled after the job.
    let mut bench = Bench::plain();
    bench.run_until(|s| s.progress().0 == s.progress().1);
    bench.tamper = Some(statusword(1, 0x1237));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        reason.to_string(),
        "node 1 (X) not disabled within 100ms after the job"
    );
    assert_eq!(bench.halted(), Some(&vec![node(1)]));
}

#[test]
fn a_requested_stop_is_a_stop_and_the_first_reason_stands() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.progress().0 == 5);
    bench.session.stop(bench.now);
    bench.session.stop(bench.now);
    bench.run_to_end();
    let stops = bench
        .events
        .iter()
        .filter(|e| matches!(e, Event::Stopped { .. }))
        .count();
    assert_eq!(stops, 1);
    assert_eq!(bench.stopped(), Some(&StopReason::Requested));
    assert_eq!(StopReason::Requested.to_string(), "stop requested");
    assert_eq!(bench.halted(), Some(&vec![]));
    assert!(bench
        .drives
        .iter()
        .all(|d| d.power_state() == SimPower::SwitchOnDisabled));
    // Before anything runs, a stop ends the session at once.
    let mut bench = Bench::plain();
    bench.session.stop(Duration::ZERO);
    assert_eq!(bench.session.phase(), Phase::Stopped);
    assert_eq!(
        bench.session.events(),
        [
            Event::Stopped {
                reason: StopReason::Requested
            },
            Event::Halted {
                unconfirmed: vec![]
            }
        ]
    );
    assert!(bench.session.poll(MS).is_empty());
}

#[test]
fn emergency_codes_are_named() {
    let emcy = |code| Emergency {
        node: node(1),
        code,
        register: 1,
        manufacturer: [0; 5],
    };
    assert_eq!(emcy_meaning(&emcy(0x8611)), "following error");
    assert_eq!(
        emcy_meaning(&emcy(0x8612)),
        "reference limit (position limit)"
    );
    assert_eq!(
        emcy_meaning(&emcy(0x8130)),
        "life guard error or heartbeat error"
    );
    assert_eq!(
        emcy_meaning(&emcy(0x8210)),
        "PDO not processed due to length error"
    );
    assert_eq!(emcy_meaning(&emcy(0x9000)), "external error");
    assert_eq!(emcy_meaning(&emcy(0x8110)), "CAN overrun (objects lost)");
    assert_eq!(emcy_meaning(&emcy(0x8120)), "CAN in error passive mode");
    assert_eq!(emcy_meaning(&emcy(0x8140)), "recovered from bus off");
    assert_eq!(emcy_meaning(&emcy(0x8220)), "PDO length exceeded");
    // Others by their class (a manufacturer's code, a temperature).
    assert_eq!(emcy_meaning(&emcy(0xFF64)), "device specific");
    assert_eq!(emcy_meaning(&emcy(0x4210)), "temperature");
}
