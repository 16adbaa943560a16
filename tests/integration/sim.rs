//! whirl's posts against the simulated controller (whirl-sim), through its public API: the
//! program text the planner writes runs line by line, every line acknowledged, and the
//! controller's own execution record ends where the program says.

use crate::util;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::simulator::machine;
use whirl::program::Position;
use whirl_sim::{Controller, ControllerOptions, Event};

#[test]
fn a_planned_program_runs_on_the_simulator_line_by_line_and_ends_where_it_says() {
    let profile = MachineProfile::builtin_sim().unwrap();
    let job = Job::load(&util::example("trapezoidal")).unwrap();
    let plan = whirl::plan::plan(&job, &profile).unwrap();
    // The first 400 lines: lead-in, a few hundred linked moves.
    let lines: Vec<&str> = plan.text.lines().take(400).collect();
    let mut sim = Controller::new(&machine(&profile), ControllerOptions::default()).unwrap();
    sim.take_output();
    // grbl's character counting against the 1024-byte buffer (1023 usable).
    let (mut next, mut in_flight, mut answers) = (0, std::collections::VecDeque::new(), Vec::new());
    let mut executed = Vec::new();
    let mut pending = String::new();
    while answers.len() < lines.len() {
        while next < lines.len() && in_flight.iter().sum::<usize>() + lines[next].len() < 1023 {
            sim.receive(format!("{}\n", lines[next]).as_bytes());
            in_flight.push_back(lines[next].len() + 1);
            next += 1;
        }
        sim.advance(0.01).unwrap();
        pending.push_str(&String::from_utf8_lossy(&sim.take_output()));
        while let Some(end) = pending.find('\n') {
            let line = pending[..end].trim().to_owned();
            pending.drain(..=end);
            if line == "ok" || line.starts_with("error:") {
                in_flight.pop_front();
                answers.push(line);
            }
        }
        for e in sim.take_events() {
            if let Event::Executed(b) = e {
                executed.push(b);
            }
        }
        assert!(sim.now() < 3600.0, "the stream stalled");
    }
    assert!(
        answers.iter().all(|a| a == "ok"),
        "{:?}",
        answers.iter().find(|a| *a != "ok")
    );
    // Where the program says the machine ends, in its continuous frame.
    let program = whirl::post::gcode::parse::read_program(&lines.join("\n"), false).unwrap();
    let end = program
        .steps(Position::UNKNOWN)
        .filter_map(|s| s.action.target().map(|_| s.to))
        .last()
        .unwrap();
    for _ in 0..100_000 {
        if sim.take_events().is_empty()
            && sim.blocks_free() == ControllerOptions::default().planner_blocks
        {
            break;
        }
        sim.advance(0.01).unwrap();
    }
    let at = sim.position();
    assert!((at.x - end.x.unwrap()).abs() < 1e-3 && (at.z - end.z.unwrap()).abs() < 1e-3);
    assert!(
        (at.c - end.c.unwrap()).abs() < 1e-2,
        "C {} vs {}",
        at.c,
        end.c.unwrap()
    );
    assert!(!executed.is_empty());
}
