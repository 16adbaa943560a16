//! The Δ guard's seat: what the controller does when its guard finds a breach.

use super::*;
use crate::{Alarm, Breach, Guard, MachineState, Measured};

/// A guard that objects to any block ending beyond `x_max`, or to the program's end.
#[derive(Debug)]
struct Fence {
    x_max: f64,
    object_at_end: bool,
    seen: usize,
}

impl Guard for Fence {
    fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach> {
        self.seen += 1;
        if block.to.x > self.x_max {
            return Err(Breach {
                message: format!("X {} beyond {}", block.to.x, self.x_max),
            });
        }
        Ok(())
    }

    fn program_end(&mut self) -> Result<(), Breach> {
        if self.object_at_end {
            return Err(Breach {
                message: String::from("left uncut"),
            });
        }
        Ok(())
    }

    fn measured(&self) -> Measured {
        Measured {
            points: self.seen,
            ..Measured::default()
        }
    }
}

fn fenced(x_max: f64, object_at_end: bool) -> Controller {
    let mut sim = sim_35();
    sim.set_guard(Box::new(Fence {
        x_max,
        object_at_end,
        seen: 0,
    }));
    sim
}

#[test]
fn a_breach_stops_the_motion_drops_the_queue_and_locks_until_reset() {
    let mut sim = fenced(10.0, false);
    // Five 4 mm feeds along X: the third ends at X12, beyond the fence.
    let lines: String = (1..=5).map(|k| format!("G1 X{} F600\n", 4 * k)).collect();
    let out = send(&mut sim, &lines);
    assert_eq!(responses(&out), ["ok"; 5]);
    run(&mut sim, 10.0, 0.01);
    let out = output(&mut sim);
    assert_eq!(
        out,
        [
            "ALARM:64",
            "[MSG:X 12 beyond 10]",
            "[MSG:Reset to continue]"
        ]
    );
    assert_eq!(sim.state(), MachineState::Alarm);
    // Stopped dead where the third block ended (blocks are judged as they finish): the
    // fourth had only just started.
    assert!(sim.position().x < 12.1, "{:?}", sim.position());
    let events = sim.take_events();
    let blocks = executed(&events);
    assert!(blocks.iter().all(|b| b.to.x < 16.0));
    assert!(events.iter().any(|e| matches!(
        e,
        Event::Alarm { alarm: Alarm::ProfileError, breach: Some(b), .. } if b.message == "X 12 beyond 10"
    )));
    // Locked: G-code is refused until a soft reset and $X.
    assert_eq!(responses(&send(&mut sim, "G1 X0\n")), ["error:9"]);
    assert_eq!(responses(&send(&mut sim, "$X\n")), ["error:79"]);
    sim.receive(&[0x18]);
    output(&mut sim);
    assert_eq!(responses(&send(&mut sim, "$X\n")), ["ok"]);
    assert_eq!(responses(&send(&mut sim, "G1 X0 F600\n")), ["ok"]);
}

#[test]
fn the_line_waiting_for_planner_room_is_answered_error_9_on_a_breach() {
    let mut sim = fenced(0.5, false);
    // 40 short moves: 35 fill the planner, the 36th waits for room, unanswered.
    let lines: String = (1..=40).map(|k| format!("G1 X{k} F3000\n")).collect();
    let out = send(&mut sim, &lines);
    assert_eq!(responses(&out), vec!["ok"; 35]);
    run(&mut sim, 5.0, 0.01);
    let out = output(&mut sim);
    assert_eq!(out[0], "ALARM:64");
    // The waiting line, then the four behind it, all locked out; nothing more ran.
    assert_eq!(responses(&out), vec!["error:9"; 5]);
    assert!(sim.position().x < 2.0, "{:?}", sim.position());
}

#[test]
fn a_breach_at_program_end_comes_before_the_end_line_is_answered() {
    let mut sim = fenced(100.0, true);
    let out = send(&mut sim, "G1 X5 F600\nM2\n");
    assert_eq!(responses(&out), ["ok"]);
    run(&mut sim, 5.0, 0.01);
    let out = output(&mut sim);
    assert_eq!(
        out,
        [
            "ALARM:64",
            "[MSG:left uncut]",
            "[MSG:Reset to continue]",
            "error:9"
        ]
    );
    assert_eq!(sim.guard().map(|g| g.measured().points), Some(1));
}

#[test]
fn without_a_breach_the_guard_only_watches() {
    let mut sim = fenced(100.0, false);
    let out = send(&mut sim, "G1 X5 F600\nG1 X6\nM2\n");
    run(&mut sim, 5.0, 0.01);
    let out = [out, output(&mut sim)].concat();
    assert_eq!(responses(&out), ["ok"; 3]);
    assert!(out.contains(&String::from("[MSG:Pgm End]")));
    assert_eq!(sim.guard().map(|g| g.measured().points), Some(2));
}
