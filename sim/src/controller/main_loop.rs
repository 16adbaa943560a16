//! The main loop (grblHAL's `protocol_main_loop`): lines taken from the RX buffer while
//! nothing blocks it, parsed and executed step by step (motion as planner room appears,
//! syncs and dwells once the machine stands), each answered once; soft limits, the Δ
//! guard's breaches and the state changes they cause.

use super::{Controller, Event, Exec};
use crate::error::{Alarm, GrblError};
use crate::guard::Breach;
use crate::interpreter::{self, Step, SyncAction};
use crate::motion::Tag;
use crate::report::{self, Flags, MachineState};
use crate::system::SystemCommand;

impl Controller {
    /// Runs the main loop until it blocks or the RX buffer is empty, then starts the cycle
    /// if motion is queued (grbl's auto cycle start).
    pub(super) fn pump(&mut self) {
        loop {
            if self.exec.is_some() {
                if !self.run_exec() {
                    break;
                }
                continue;
            }
            if self.jog_cancelling {
                if self.motion.is_running() {
                    break;
                }
                self.jog_cancelling = false;
            }
            let Some(item) = self.rx.pop() else {
                break;
            };
            if let Some(line) = self.assembler.push(item) {
                self.process_line(line);
            }
        }
        self.motion.start_cycle();
        self.collect_executed();
        self.note_state();
    }

    pub(super) fn process_line(&mut self, line: crate::protocol::Line) {
        self.lines_taken += 1;
        let mut tag = Tag {
            line: self.lines_taken,
            n: None,
        };
        let text = line.text;
        if line.overflow {
            return self.answer(tag, text, Err(GrblError::Overflow));
        }
        if text.is_empty() {
            return self.answer(tag, text, Ok(()));
        }
        if let Some(command) = text.strip_prefix('$').map(|_| SystemCommand::parse(&text)) {
            if let SystemCommand::Jog(gcode) = &command {
                tag.n = interpreter::line_number(gcode);
            }
            let (result, reset) = self.system(command, tag);
            if let Some(result) = result {
                self.answer(tag, text, result);
            } else if let Some(exec) = self.exec.as_mut() {
                // A jog waiting for planner room: answered once queued.
                exec.text = text;
            }
            if reset {
                self.soft_reset();
            }
            return;
        }
        tag.n = interpreter::line_number(&text);
        // G-code is locked out in alarm and while jogging (grblHAL's `protocol.c`).
        if self.alarm.is_some() || self.state() == MachineState::Jog {
            return self.answer(tag, text, Err(GrblError::SystemGcLock));
        }
        if let Some(error) = self.last_error {
            // grblHAL's sticky error: not even parsed.
            return self.answer(tag, text, Err(error));
        }
        let before = self.parser.clone();
        match interpreter::interpret(&text, &mut self.parser, self.dialect) {
            Err(error) => self.answer(tag, text, Err(error)),
            Ok(block) => {
                let p = &self.parser;
                let coord_system = p.coord_system != before.coord_system;
                // Report_LatheXMode also asks for WCO (`report_add_realtime`).
                let diameter_mode = p.diameter != before.diameter;
                self.tracker.add(Flags {
                    wco: p.g92 != before.g92 || coord_system || diameter_mode,
                    coord_system,
                    diameter_mode,
                    ..Flags::default()
                });
                tag.n = block.n;
                self.exec = Some(Exec {
                    tag,
                    text,
                    steps: block.steps.into(),
                    dwell: None,
                    soft_limit: false,
                });
            }
        }
    }

    /// Answers a line: `ok` or `error:N`, the sticky error updated, an event logged.
    pub(super) fn answer(&mut self, tag: Tag, text: String, result: Result<(), GrblError>) {
        self.last_error = result.err();
        self.output.push_str(&report::response(result));
        self.events.push(Event::Line {
            time: self.now,
            line: tag.line,
            n: tag.n,
            text,
            error: result.err(),
        });
    }

    /// The soft limits as numbers (±∞ where an axis has none).
    pub(super) fn limits(&self) -> [(f64, f64); 3] {
        let num = self.dialect.numbers;
        self.travel.map(|(min, max)| {
            (
                min.map_or(f64::NEG_INFINITY, |m| num.hold(m)),
                max.map_or(f64::INFINITY, |m| num.hold(m)),
            )
        })
    }

    /// Whether all queued motion is done and the machine stands still (grbl's
    /// `protocol_buffer_synchronize` condition).
    pub(super) fn synced(&self) -> bool {
        self.motion.is_empty() && !self.motion.is_running()
    }

    /// Whether soft limits are on (`$20`) and `target` is beyond them.
    pub(super) fn outside_travel(&self, target: [f64; 3]) -> bool {
        // Limits compared in the controller's number type, as grbl compares its floats.
        self.settings.soft_limits()
            && target
                .iter()
                .zip(self.limits())
                .any(|(&t, (min, max))| t < min || t > max)
    }

    /// Continues the blocked line; `true` once it is answered.
    pub(super) fn run_exec(&mut self) -> bool {
        let Some(mut exec) = self.exec.take() else {
            return true;
        };
        let checking = self.check_mode.is_some();
        let finished = loop {
            if exec.soft_limit {
                if self.motion.is_moving() {
                    break false;
                }
                self.trip_soft_limit(exec);
                return true;
            }
            let Some(&step) = exec.steps.front() else {
                break true;
            };
            match step {
                Step::Sync(action) => {
                    if !checking {
                        if !self.synced() {
                            break false;
                        }
                        self.apply(action);
                        if self.critical {
                            // The guard stopped the machine at program end.
                            self.answer(exec.tag, exec.text, Err(GrblError::SystemGcLock));
                            return true;
                        }
                    } else if action == SyncAction::ProgramEnd {
                        self.output.push_str(&report::message("Pgm End"));
                    }
                }
                Step::Dwell(seconds) => {
                    if !checking {
                        if !self.synced() {
                            break false;
                        }
                        match exec.dwell {
                            None => {
                                exec.dwell = Some(seconds);
                                continue;
                            }
                            Some(left) if left > 0.0 => break false,
                            Some(_) => exec.dwell = None,
                        }
                    }
                }
                Step::Motion(request) => {
                    if self.outside_travel(request.target) {
                        // grbl: a controlled stop first, so position is kept; the alarm
                        // once the machine stands still.
                        if self.motion.is_moving() {
                            self.motion.feed_hold();
                        }
                        exec.soft_limit = true;
                        continue;
                    }
                    if !checking {
                        if self.motion.blocks_free() == 0 {
                            break false;
                        }
                        self.motion.push(request, exec.tag);
                    }
                }
            }
            exec.steps.pop_front();
        };
        if finished {
            self.answer(exec.tag, exec.text, Ok(()));
        } else {
            self.exec = Some(exec);
        }
        finished
    }

    pub(super) fn apply(&mut self, action: SyncAction) {
        match action {
            SyncAction::Wait => {}
            SyncAction::Spindle(spindle) => {
                self.spindle = spindle;
                self.tracker.add(Flags {
                    spindle: true,
                    ..Flags::default()
                });
            }
            SyncAction::Coolant(on) => {
                self.coolant = on;
                self.tracker.add(Flags {
                    coolant: true,
                    ..Flags::default()
                });
            }
            SyncAction::Pause => self.motion.feed_hold(),
            SyncAction::ProgramEnd => {
                if let Some(Err(breach)) = self.guard.as_mut().map(|g| g.program_end()) {
                    self.trip_guard(breach);
                    return;
                }
                self.spindle.on = false;
                self.coolant = false;
                // grblHAL's program end refreshes the WCO and reports spindle and coolant
                // (`gcode.c`).
                self.tracker.add(Flags {
                    wco: true,
                    spindle: true,
                    coolant: true,
                    ..Flags::default()
                });
                self.output.push_str(&report::message("Pgm End"));
            }
        }
    }

    /// A target outside the travel, with the machine at rest: the queue is purged (nothing
    /// after the line runs), `ALARM:2`, and the line is answered `error:15`.
    pub(super) fn trip_soft_limit(&mut self, exec: Exec) {
        self.motion.abort(self.now);
        self.raise(Alarm::SoftLimit);
        self.answer(exec.tag, exec.text, Err(GrblError::TravelExceeded));
        self.collect_executed();
    }

    /// Moves finished blocks to the events, showing each to the guard first while no alarm
    /// is up (a breach found here stops what is still moving).
    pub(super) fn collect_executed(&mut self) {
        for block in self.motion.take_done() {
            let verdict = match (&mut self.guard, self.alarm) {
                (Some(guard), None) => guard.executed(&block),
                _ => Ok(()),
            };
            self.events.push(Event::Executed(block));
            if let Err(breach) = verdict {
                self.trip_guard(breach);
            }
        }
    }

    /// The Δ guard found the executed motion beyond Δ: stop dead, as a hard limit does, drop
    /// the queue and the line waiting on it (answered `error:9`), `ALARM:64`.
    pub(super) fn trip_guard(&mut self, breach: Breach) {
        self.raise_with(Alarm::ProfileError, Some(breach));
        self.motion.abort(self.now);
        if let Some(exec) = self.exec.take() {
            self.answer(exec.tag, exec.text, Err(GrblError::SystemGcLock));
        }
        self.collect_executed();
    }

    pub(super) fn note_state(&mut self) {
        if self.jogging && !self.motion.is_running() && self.exec.is_none() {
            // The jog is over (done or cancelled): the parser goes on from where the machine
            // stands (grblHAL syncs `gc_state.position` when jogging ends, `protocol.c`).
            self.jogging = false;
            self.parser.position = self.motion.position();
        }
        let state = self.state();
        if state != self.last_state {
            self.last_state = state;
            self.events.push(Event::State {
                time: self.now,
                state,
            });
        }
    }
}
