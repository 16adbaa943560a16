//! Behaviour of the whole controller, driven as a sender drives it. Expected values come
//! from grbl's protocol documentation and from kinematics worked out by hand (a trapezoid
//! from rest to rest over L at speed v and acceleration a takes L/v + v/a), never from the
//! simulator's own output.

mod alarms;
mod fuzz;
mod grblhal;
mod guard;
mod motion;
mod streaming;

use std::collections::VecDeque;

use crate::machine::{Axis, Machine, Number};

use crate::{Controller, ControllerOptions, Event, ExecutedBlock};

/// The built-in simulated machine: X −5..160 mm and Z −300..300 mm at 3000 mm/min and
/// 500 mm/s², C unlimited at 72 000 deg/min and 7200 deg/s² (`machine-profiles/sim.toml`).
pub(crate) fn profile() -> Machine {
    Machine {
        x: Axis {
            min: Some(-5.0),
            max: Some(160.0),
            max_rate: 3000.0,
            accel: 500.0,
        },
        z: Axis {
            min: Some(-300.0),
            max: Some(300.0),
            max_rate: 3000.0,
            accel: 500.0,
        },
        c: Axis {
            min: None,
            max: None,
            max_rate: 72000.0,
            accel: 7200.0,
        },
        number: Number::F32,
        max_line_length: 256,
        spindle_rpm: Some((100.0, 12000.0)),
    }
}

/// A controller with its banner already read.
pub(crate) fn sim_with(options: ControllerOptions) -> Controller {
    let mut sim = Controller::new(&profile(), options).expect("valid options");
    sim.take_output();
    sim
}

pub(crate) fn new_sim() -> Controller {
    sim_with(ControllerOptions::default())
}

/// A controller with a planner of 35 blocks (`$398=35`, grblHAL's default for years), which
/// the figures of the tests written for it count on.
pub(crate) fn sim_35() -> Controller {
    sim_with(ControllerOptions {
        planner_blocks: 35,
        ..ControllerOptions::default()
    })
}

/// Sends text and returns what the controller printed, as lines.
pub(crate) fn send(sim: &mut Controller, text: &str) -> Vec<String> {
    sim.receive(text.as_bytes());
    output(sim)
}

pub(crate) fn output(sim: &mut Controller) -> Vec<String> {
    let bytes = sim.take_output();
    let text = String::from_utf8(bytes).expect("the controller prints ASCII");
    text.split("\r\n")
        .filter(|l| !l.is_empty())
        .map(str::to_owned)
        .collect()
}

/// The `ok` / `error:N` lines among printed lines.
pub(crate) fn responses(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .filter(|l| *l == "ok" || l.starts_with("error:"))
        .cloned()
        .collect()
}

/// Advances in steps of `dt` for `seconds`.
pub(crate) fn run(sim: &mut Controller, seconds: f64, dt: f64) {
    let steps = (seconds / dt).round() as usize;
    for _ in 0..steps {
        sim.advance(dt).expect("valid step");
    }
}

/// Advances until the controller is idle with nothing left to do (or `limit` seconds).
pub(crate) fn run_until_idle(sim: &mut Controller, dt: f64, limit: f64) {
    let start = sim.now();
    loop {
        sim.advance(dt).expect("valid step");
        let idle = sim.state() == crate::MachineState::Idle
            && sim.blocks_free() == sim.options().planner_blocks;
        if idle || sim.now() - start > limit {
            break;
        }
    }
}

pub(crate) fn executed(events: &[Event]) -> Vec<ExecutedBlock> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Executed(block) => Some(block.clone()),
            _ => None,
        })
        .collect()
}

/// A sender following grbl's character-counting method (gnea/grbl
/// `doc/script/stream.py`): it tracks the length of every line sent and not yet answered,
/// and sends the next line only if the total stays within `budget` bytes.
pub(crate) struct CountingSender {
    lines: Vec<String>,
    next: usize,
    in_flight: VecDeque<usize>,
    budget: usize,
    pending: String,
    pub answers: Vec<String>,
}

impl CountingSender {
    pub(crate) fn new(lines: Vec<String>, budget: usize) -> CountingSender {
        CountingSender {
            lines,
            next: 0,
            in_flight: VecDeque::new(),
            budget,
            pending: String::new(),
            answers: Vec::new(),
        }
    }

    pub(crate) fn done(&self) -> bool {
        self.answers.len() == self.lines.len()
    }

    /// Reads what the controller printed, then sends what fits.
    pub(crate) fn service(&mut self, sim: &mut Controller) {
        self.read(sim);
        while let Some(line) = self.lines.get(self.next) {
            let len = line.len() + 1;
            if self.in_flight.iter().sum::<usize>() + len > self.budget {
                break;
            }
            sim.receive(format!("{line}\n").as_bytes());
            self.in_flight.push_back(len);
            self.next += 1;
        }
    }

    fn read(&mut self, sim: &mut Controller) {
        let bytes = sim.take_output();
        self.pending.push_str(&String::from_utf8_lossy(&bytes));
        while let Some(end) = self.pending.find("\r\n") {
            let line: String = self.pending.drain(..end + 2).take(end).collect();
            if line == "ok" || line.starts_with("error:") {
                self.in_flight.pop_front();
                self.answers.push(line);
            }
        }
    }
}

/// A program of `count` short feed moves zig-zagging in X and Z, like a post's output.
pub(crate) fn zigzag(count: usize) -> Vec<String> {
    let mut lines = vec!["G21 G90 G94".to_owned(), "G0 X10 Z0".to_owned()];
    for i in 0..count {
        let x = if i % 2 == 0 { 10.5 } else { 10.0 };
        lines.push(format!(
            "N{} G1 X{x} Z{:.3} F3000",
            i + 1,
            0.2 * (i + 1) as f64
        ));
    }
    lines
}
