//! Soft limits, soft reset, alarm lock and check mode.

use super::*;
use crate::{Alarm, MachineState};

#[test]
fn soft_limit_stops_alarms_and_nothing_after_runs() {
    let mut sim = new_sim();
    send(&mut sim, "G0 X100\n");
    // At 0.5 s X is at 22.5 mm, moving at 50 mm/s.
    run(&mut sim, 0.5, 0.01);
    // X160 is the travel's end: X200 is beyond it. grbl checks the target when it plans
    // the line: a controlled stop (v²/2a = 2.5 mm), the queue purged, ALARM:2.
    let out = send(&mut sim, "G0 X200\nG0 X20\nG0 Z5\n");
    assert!(responses(&out).is_empty(), "{out:?}");
    run(&mut sim, 0.2, 0.01);
    let out = output(&mut sim);
    assert_eq!(
        out,
        [
            "ALARM:2",
            "[MSG:Reset to continue]",
            "error:15",
            "error:9",
            "error:9"
        ]
    );
    assert_eq!(sim.state(), MachineState::Alarm);
    let events = sim.take_events();
    assert!(events.iter().any(|e| matches!(
        e,
        Event::Alarm {
            alarm: Alarm::SoftLimit,
            ..
        }
    )));
    let blocks = executed(&events);
    assert_eq!(blocks.len(), 1);
    assert!(!blocks[0].completed);
    assert!((blocks[0].to.x - 25.0).abs() < 1e-9);
    // Nothing runs, whatever comes; unlocking needs a reset first (grblHAL error 79).
    run(&mut sim, 5.0, 0.1);
    assert!((sim.position().x - 25.0).abs() < 1e-9);
    assert_eq!(send(&mut sim, "$X\nG0 X20\n"), ["error:79", "error:9"]);
    assert!(send(&mut sim, "?")[0].starts_with("<Alarm|"));
    sim.receive(&[0x18]);
    let out = output(&mut sim);
    assert_eq!(
        out,
        [
            "GrblHAL 1.1f ['$' or '$HELP' for help]",
            "[MSG:'$H'|'$X' to unlock]"
        ]
    );
    assert_eq!(send(&mut sim, "G0 X20\n"), ["error:9"]);
    assert_eq!(send(&mut sim, "$X\n"), ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(send(&mut sim, "G0 X20\n"), ["ok"]);
    run_until_idle(&mut sim, 0.01, 10.0);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 1);
    assert!((blocks[0].from.x - 25.0).abs() < 1e-9);
    assert_eq!(blocks[0].to.x, 20.0);
}

#[test]
fn soft_limit_at_rest_alarms_at_once() {
    let mut sim = new_sim();
    let out = send(&mut sim, "G0 Z-301\nG0 Z1\n");
    assert_eq!(
        out,
        ["ALARM:2", "[MSG:Reset to continue]", "error:15", "error:9"]
    );
    assert!(executed(&sim.take_events()).is_empty());
    // Exactly at the end of travel is inside.
    sim.receive(&[0x18]);
    output(&mut sim);
    send(&mut sim, "$X\n");
    assert_eq!(send(&mut sim, "G0 Z-300 X-5\n"), ["ok"]);
}

#[test]
fn soft_reset_in_motion_alarms_3_and_clears_the_queue() {
    let mut sim = sim_35();
    send(&mut sim, "G1 X50 F600\nG1 X60\nG1 X70\n");
    run(&mut sim, 1.0, 0.01);
    assert_eq!(sim.blocks_free(), 32);
    sim.receive(&[0x18]);
    let out = output(&mut sim);
    // grbl: a reset while moving cannot vouch for the position: ALARM:3, then the banner
    // and the unlock reminder.
    assert_eq!(
        out,
        [
            "ALARM:3",
            "GrblHAL 1.1f ['$' or '$HELP' for help]",
            "[MSG:'$H'|'$X' to unlock]"
        ]
    );
    assert_eq!(sim.blocks_free(), sim.options().planner_blocks);
    let stopped = sim.position();
    run(&mut sim, 2.0, 0.1);
    assert_eq!(sim.position(), stopped);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 1);
    assert!(!blocks[0].completed);
    assert_eq!(send(&mut sim, "G1 X1\n"), ["error:9"]);
    assert_eq!(send(&mut sim, "$X\n"), ["[MSG:Caution: Unlocked]", "ok"]);
    // The parser restarts from where the machine stopped, in its defaults (G0, F unset).
    assert_eq!(send(&mut sim, "G1 X1\n"), ["error:22"]);
}

#[test]
fn soft_reset_when_held_or_idle_keeps_the_machine_unlocked() {
    let mut sim = new_sim();
    send(&mut sim, "G1 X50 F600\n");
    run(&mut sim, 1.0, 0.01);
    sim.receive(b"!");
    run(&mut sim, 0.5, 0.01);
    assert_eq!(sim.state(), MachineState::Hold { complete: true });
    sim.receive(&[0x18]);
    // grbl's realtime_cmds.md: not in motion, position retained, no alarm.
    assert_eq!(output(&mut sim), ["GrblHAL 1.1f ['$' or '$HELP' for help]"]);
    assert_eq!(sim.state(), MachineState::Idle);
    assert_eq!(send(&mut sim, "G0 X0\n"), ["ok"]);
}

#[test]
fn check_mode_executes_nothing() {
    let mut sim = new_sim();
    assert_eq!(send(&mut sim, "$C\n"), ["[MSG:Enabled]", "ok"]);
    assert!(send(&mut sim, "?")[0].starts_with("<Check|"));
    // Lines are checked and answered at once: moves, dwells, syncs.
    let out = send(
        &mut sim,
        "G0 X50\nG1 Z10 F100\nG4 P10\nM3 S1000\nG92 C0\nG2 X1\n\nM2\n",
    );
    assert_eq!(
        responses(&out),
        ["ok", "ok", "ok", "ok", "ok", "error:20", "ok", "ok"]
    );
    assert!(out.contains(&"[MSG:Pgm End]".to_owned()));
    run(&mut sim, 2.0, 0.1);
    assert_eq!(sim.position(), crate::Position::default());
    assert!(executed(&sim.take_events()).is_empty());
    // Leaving check mode resets the controller (grbl restores the parser's defaults).
    let out = send(&mut sim, "$C\n");
    assert_eq!(
        out,
        [
            "[MSG:Disabled]",
            "ok",
            "GrblHAL 1.1f ['$' or '$HELP' for help]"
        ]
    );
    assert_eq!(sim.state(), MachineState::Idle);
    // The parser is back at the machine's position with no G92 left from check mode.
    send(&mut sim, "G91 G0 X1\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().x, 1.0);
    assert!(send(&mut sim, "$#\n").contains(&"[G92:0.000,0.000,0.000,0.000]".to_owned()));
}

#[test]
fn soft_limit_in_check_mode_is_alarm_2() {
    // grblHAL's mc_line checks soft limits before it skips planning in check mode.
    let mut sim = new_sim();
    send(&mut sim, "$C\n");
    assert_eq!(
        send(&mut sim, "G0 X500\n"),
        ["ALARM:2", "[MSG:Reset to continue]", "error:15"]
    );
    assert_eq!(send(&mut sim, "$C\n"), ["error:79"]);
}

#[test]
fn alarm_state_refuses_every_gcode_line() {
    let mut sim = new_sim();
    send(&mut sim, "G0 X500\n");
    sim.receive(&[0x18]);
    output(&mut sim);
    let out = send(&mut sim, "G0 X1\nG2\n(comment)\n\n$G\n");
    // Empty lines and $ commands are still answered normally.
    assert_eq!(
        responses(&out),
        ["error:9", "error:9", "error:9", "ok", "ok"]
    );
}
