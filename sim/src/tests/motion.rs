//! Motion in simulated time: limits, inverse time, feed hold, syncs, overrides, and the
//! executed record.

use super::*;
use crate::MachineState;

/// sim.toml's limits in units/s and units/s²: X, Z, C.
const MAX_RATE: [f64; 3] = [50.0, 50.0, 1200.0];
const ACCEL: [f64; 3] = [500.0, 500.0, 7200.0];

/// The path speed and acceleration grbl allows along `delta` (the most every axis allows).
fn path_limits(delta: [f64; 3]) -> (f64, f64, f64) {
    let length = delta.iter().map(|d| d * d).sum::<f64>().sqrt();
    let (mut rate, mut accel) = (f64::INFINITY, f64::INFINITY);
    for i in 0..3 {
        let u = (delta[i] / length).abs();
        if u > 0.0 {
            rate = rate.min(MAX_RATE[i] / u);
            accel = accel.min(ACCEL[i] / u);
        }
    }
    (length, rate, accel)
}

fn duration(block: &ExecutedBlock) -> f64 {
    block.end_time - block.start_time
}

#[test]
fn rapids_respect_every_axis_max_rate() {
    // A long rapid takes at least distance / max rate on every axis; from rest to rest
    // it takes exactly L/v + v/a with grbl's path limits.
    for (line, delta) in [
        ("G0 X150", [150.0_f64, 0.0, 0.0]),
        ("G0 Z-250", [0.0, -250.0, 0.0]),
        ("G0 C3600", [0.0, 0.0, 3600.0]),
        ("G0 X100 Z-100 C1800", [100.0, -100.0, 1800.0]),
    ] {
        let mut sim = new_sim();
        send(&mut sim, &format!("{line}\n"));
        run_until_idle(&mut sim, 0.05, 100.0);
        let block = executed(&sim.take_events()).remove(0);
        let slowest_axis = (0..3)
            .map(|i| delta[i].abs() / MAX_RATE[i])
            .fold(0.0, f64::max);
        assert!(duration(&block) >= slowest_axis, "{line}");
        let (length, v, a) = path_limits(delta);
        let expected = length / v + v / a;
        assert!(
            (duration(&block) - expected).abs() < 1e-9,
            "{line}: {}",
            duration(&block)
        );
    }
}

#[test]
fn no_axis_exceeds_its_rate_or_acceleration() {
    // A program with corners, reversals, C moves and feeds: every recorded phase keeps
    // each axis within its limits.
    let mut sim = new_sim();
    let program = "G0 X20 Z5 C0\nG1 X30 F2000\nG1 Z-5 C720 F9000\nG0 X0\nG93 G1 X10 Z0 C1080 F30\n\
                   G1 X10.5 Z0.2 C1090 F600\nG1 X10 Z0.4 C1100 F600\nG94 G0 Z-10\n";
    send(&mut sim, program);
    run_until_idle(&mut sim, 0.01, 100.0);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 8);
    for block in &blocks {
        let (from, to) = (block.from.to_array(), block.target.to_array());
        let delta = [0, 1, 2].map(|i| to[i] - from[i]);
        let length = block.length();
        for phase in &block.phases {
            let end_speed = block.speed_at(
                block
                    .phases
                    .iter()
                    .find(|p| p.start > phase.start)
                    .map_or(block.end_time, |p| p.start),
            );
            for i in 0..3 {
                let u = (delta[i] / length).abs();
                let top = phase.speed.max(end_speed) * u;
                assert!(
                    top <= MAX_RATE[i] * (1.0 + 1e-9),
                    "axis {i} at {top}: {block:?}"
                );
                assert!(
                    phase.accel.abs() * u <= ACCEL[i] * (1.0 + 1e-9),
                    "axis {i} accel: {block:?}"
                );
            }
        }
    }
}

#[test]
fn inverse_time_moves_take_the_commanded_time() {
    // G93 F60 on a linked X/Z/C move: one second of cruise, plus the ramp v/a that a start
    // and a stop from rest add (half of it at each end).
    // The moves start from rest: the positioning rapid is finished before they are sent
    // (otherwise they would enter through the corner at its junction speed).
    let mut sim = new_sim();
    send(&mut sim, "G0 X10 Z0 C0\n");
    run_until_idle(&mut sim, 0.01, 100.0);
    sim.take_events();
    send(&mut sim, "G93 G1 X10 Z1 C90 F60\n");
    run_until_idle(&mut sim, 0.01, 100.0);
    let block = executed(&sim.take_events()).remove(0);
    let (length, limit, a) = path_limits([0.0, 1.0, 90.0]);
    let v = length * 60.0 / 60.0;
    assert!(v < limit);
    assert!(
        (duration(&block) - (1.0 + v / a)).abs() < 1e-9,
        "{}",
        duration(&block)
    );

    // Ten collinear G93 blocks of 0.1 s run without stopping between them: 1 s in all.
    let mut sim = new_sim();
    send(&mut sim, "G0 X10 Z0 C0\n");
    run_until_idle(&mut sim, 0.01, 100.0);
    sim.take_events();
    let mut program = String::from("G93\n");
    for i in 1..=10 {
        program.push_str(&format!("G1 Z{:.1} C{} F600\n", 0.1 * f64::from(i), 36 * i));
    }
    send(&mut sim, &program);
    run_until_idle(&mut sim, 0.01, 100.0);
    let moves = executed(&sim.take_events());
    assert_eq!(moves.len(), 10);
    let (length, _, a) = path_limits([0.0, 0.1, 36.0]);
    let v = length * 600.0 / 60.0;
    let total = moves[9].end_time - moves[0].start_time;
    assert!((total - (1.0 + v / a)).abs() < 1e-9, "{total}");

    // Faster than the axes allow: the axis limit wins (grbl clamps to the max rate).
    let mut sim = new_sim();
    send(&mut sim, "G93 G1 X100 F6000\n");
    run_until_idle(&mut sim, 0.01, 100.0);
    let block = executed(&sim.take_events()).remove(0);
    assert!((duration(&block) - (100.0 / 50.0 + 50.0 / 500.0)).abs() < 1e-9);
}

#[test]
fn feed_hold_stops_motion_and_cycle_start_resumes() {
    let mut sim = new_sim();
    send(&mut sim, "G1 X100 F3000\n");
    // At 0.5 s: 2.5 mm of ramp plus 0.4 s at 50 mm/s = 22.5 mm.
    run(&mut sim, 0.5, 0.01);
    assert!((sim.position().x - 22.5).abs() < 1e-9);
    sim.receive(b"!");
    assert_eq!(sim.state(), MachineState::Hold { complete: false });
    // It stops after v²/2a = 2.5 mm, in v/a = 0.1 s.
    run(&mut sim, 0.2, 0.01);
    assert_eq!(sim.state(), MachineState::Hold { complete: true });
    let held = sim.position();
    assert!((held.x - 25.0).abs() < 1e-9);
    run(&mut sim, 2.0, 0.1);
    assert_eq!(sim.position(), held, "position stays constant while held");
    assert!(send(&mut sim, "?")[0].starts_with("<Hold:0|MPos:25.000,"));
    let resumed_at = sim.now();
    sim.receive(b"~");
    assert_eq!(sim.state(), MachineState::Run);
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().x, 100.0);
    let block = executed(&sim.take_events()).remove(0);
    assert!(block.completed);
    // The remaining 75 mm from rest to rest: 75/50 + 0.1 = 1.6 s.
    assert!((block.end_time - resumed_at - 1.6).abs() < 1e-9);
    // Replay: standing at 25 mm throughout the hold.
    assert!((block.position_at(resumed_at - 1.0).x - 25.0).abs() < 1e-9);
}

#[test]
fn offset_changes_and_spindle_changes_wait_for_motion() {
    // grbl syncs the planner before G92 and spindle changes: their `ok` comes only when
    // the machine has stopped.
    let mut sim = new_sim();
    let out = send(&mut sim, "G1 X10 F600\nG92 C0\n");
    assert_eq!(responses(&out), ["ok"]);
    run(&mut sim, 0.5, 0.01);
    assert!(output(&mut sim).is_empty());
    run(&mut sim, 0.6, 0.01);
    assert_eq!(responses(&output(&mut sim)), ["ok"]);
    let out = send(&mut sim, "G1 X0\nM3 S1000\n");
    assert_eq!(responses(&out), ["ok"]);
    run(&mut sim, 1.1, 0.01);
    assert_eq!(responses(&output(&mut sim)), ["ok"]);
    // With the sync turned off, G92 is answered at once.
    let mut sim = sim_with(ControllerOptions {
        sync_on_offset_change: false,
        ..ControllerOptions::default()
    });
    assert_eq!(
        responses(&send(&mut sim, "G1 X10 F600\nG92 C0\n")),
        ["ok", "ok"]
    );
    run_until_idle(&mut sim, 0.01, 10.0);
    let out = send(&mut sim, "$I\n");
    assert!(out.iter().any(|l| l.starts_with("[OPT:VNLW,")), "{out:?}");
}

#[test]
fn dwell_pause_and_program_end() {
    let mut sim = new_sim();
    let out = send(&mut sim, "G4 P0.5\n");
    assert!(responses(&out).is_empty());
    run(&mut sim, 0.4, 0.1);
    assert!(output(&mut sim).is_empty());
    run(&mut sim, 0.2, 0.1);
    assert_eq!(responses(&output(&mut sim)), ["ok"]);
    // M0: pause after the move, resume with cycle start.
    send(&mut sim, "G1 X5 F600\nM0\nG1 X10\n");
    run(&mut sim, 1.0, 0.01);
    assert_eq!(sim.state(), MachineState::Hold { complete: true });
    assert_eq!(sim.position().x, 5.0);
    sim.receive(b"~");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().x, 10.0);
    output(&mut sim);
    let out = send(&mut sim, "M2\n");
    assert_eq!(out, ["[MSG:Pgm End]", "ok"]);
    // M2 leaves G1 as the motion mode.
    assert!(send(&mut sim, "$G\n")[0].starts_with("[GC:G1 "));
}

#[test]
fn feed_override_speeds_up_feeds_not_rapids() {
    let mut sim = new_sim();
    // +10 % ten times: 200 %, the maximum.
    sim.receive(&[0x91; 12]);
    send(&mut sim, "G1 X20 F600\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    let block = executed(&sim.take_events()).remove(0);
    // 20 mm at 20 mm/s from rest to rest: 1 s + 20/500.
    assert!((duration(&block) - 1.04).abs() < 1e-9);
    let report = send(&mut sim, "?").remove(0);
    assert!(report.contains("|Ov:200,100,100"), "{report}");
    // A rapid is not affected by the feed override; 0x97 sets rapids to 25 %.
    sim.receive(&[0x97]);
    send(&mut sim, "G0 X0\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    let block = executed(&sim.take_events()).remove(0);
    assert!((duration(&block) - (20.0 / 12.5 + 12.5 / 500.0)).abs() < 1e-9);
}

#[test]
fn executed_record_replays_the_program_path() {
    let mut sim = new_sim();
    let lines = zigzag(40);
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    send(&mut sim, &text);
    run_until_idle(&mut sim, 0.013, 100.0);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 41);
    for pair in blocks.windows(2) {
        // The path is continuous and so is time: streamed at once, nothing waits.
        assert_eq!(pair[0].to, pair[1].from);
        assert!((pair[0].end_time - pair[1].start_time).abs() < 1e-12);
        // Replaying at the boundary gives the same point from both sides.
        let t = pair[0].end_time;
        let (a, b) = (pair[0].position_at(t), pair[1].position_at(t));
        assert!((a.x - b.x).abs() < 1e-9 && (a.z - b.z).abs() < 1e-9);
    }
    // Each block carries its line's N; the last ends at the last target.
    assert_eq!(blocks[1].n, Some(1));
    assert_eq!(blocks[40].n, Some(40));
    assert!((blocks[40].to.z - 8.0).abs() < 1e-9);
    // Mid-block, the replayed point lies on the straight segment.
    let b = &blocks[20];
    let p = b.position_at((b.start_time + b.end_time) / 2.0);
    let f = (p.z - b.from.z) / (b.target.z - b.from.z);
    assert!((p.x - (b.from.x + f * (b.target.x - b.from.x))).abs() < 1e-9);
}

#[test]
fn f32_controller_rounds_targets_like_grbl() {
    // sim.toml says f32: C10.0001 is held as the nearest f32.
    let mut sim = new_sim();
    send(&mut sim, "G0 C10.0001\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().c, f64::from(10.0001_f32));
}
