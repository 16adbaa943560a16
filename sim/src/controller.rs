//! The simulated controller: bytes in, bytes out, simulated time advanced by the caller.
//!
//! [`Controller`] is grblHAL's main loop and real-time handling reduced to values. Bytes
//! given to [`Controller::receive`] pass the real-time filter (acted on at once) or go to
//! the RX buffer; the main loop takes lines from the buffer only while it is not blocked
//! executing the previous one (a motion waiting for planner room, a sync, a dwell), which
//! is what makes a sender's character counting matter. Processing a line takes no
//! simulated time; motion takes exactly the time its kinematics need, and only
//! [`Controller::advance`] moves the clock. There is no I/O, no wall clock and no
//! randomness: the same calls give the same bytes and events.

use std::collections::VecDeque;

use crate::machine::Machine;
use serde::{Deserialize, Serialize};

use crate::error::{Alarm, ConfigError, GrblError, TimeError};
use crate::guard::{Breach, Guard};
use crate::interpreter::{
    self, Dialect, MotionMode, Numbers, ParserState, Spindle, Step, SyncAction,
};
use crate::motion::{Dynamics, Hold, Motion, Tag};
use crate::protocol::{classify, ByteClass, LineAssembler, Realtime, RxBuffer};
use crate::record::{ExecutedBlock, Position};
use crate::report::{self, GcSnapshot, MachineState, Settings, StatusSnapshot};
use crate::system::SystemCommand;

/// Feed and spindle overrides stay within 10–200 % (grbl's `config.h` defaults).
const OVERRIDE_MIN: u8 = 10;
/// See [`OVERRIDE_MIN`].
const OVERRIDE_MAX: u8 = 200;

/// How the simulated controller is built (what differs between grblHAL builds and boards).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerOptions {
    /// RX buffer size in bytes, as `$I` reports it; the ring holds one byte less, as
    /// grblHAL's drivers do. grblHAL: 1024; grbl on an AVR: 128.
    pub rx_buffer_size: usize,
    /// Planner blocks (`$398`; grblHAL's long-time default 35).
    pub planner_blocks: usize,
    /// Junction deviation `$11`, mm (grbl's default 0.010).
    pub junction_deviation: f64,
    /// Wait for the queue to empty before a G92 or G54–G59 change takes effect, as grbl
    /// does by default (`FORCE_BUFFER_SYNC_DURING_WCO_CHANGE`; `$I` shows `W` when off).
    pub sync_on_offset_change: bool,
    /// Where the machine is at power-up (machine coordinates).
    pub start: Position,
}

impl Default for ControllerOptions {
    fn default() -> Self {
        ControllerOptions {
            rx_buffer_size: 1024,
            planner_blocks: 35,
            junction_deviation: 0.01,
            sync_on_offset_change: true,
            start: Position::default(),
        }
    }
}

/// Something that happened, for the executed-path log and for tests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A line was answered (`ok` or `error:N`).
    Line {
        /// Simulated time, s.
        time: f64,
        /// The line's ordinal (see [`ExecutedBlock::line`]).
        line: u64,
        /// Its N word, if it had one and it could be read.
        n: Option<u32>,
        /// The line as stored (leading spaces removed).
        text: String,
        /// The error it was answered with; `None` for `ok`.
        error: Option<GrblError>,
    },
    /// A block was executed (or cut short).
    Executed(ExecutedBlock),
    /// An alarm was raised.
    Alarm {
        /// Simulated time, s.
        time: f64,
        /// Which.
        alarm: Alarm,
        /// What the Δ guard found, for [`Alarm::ProfileError`].
        #[serde(default, skip_serializing_if = "Option::is_none")]
        breach: Option<Breach>,
    },
    /// Bytes arrived while the RX buffer was full and were dropped: the sender broke
    /// character counting. The damaged line is answered `error:11`.
    RxOverflow {
        /// Simulated time, s.
        time: f64,
        /// Bytes dropped in this `receive` call.
        dropped: usize,
    },
    /// A soft reset (0x18, or leaving check mode).
    Reset {
        /// Simulated time, s.
        time: f64,
    },
    /// The state the status report would show changed.
    State {
        /// Simulated time, s.
        time: f64,
        /// The new state.
        state: MachineState,
    },
}

/// The line being executed: the main loop is blocked on it until its steps are done.
#[derive(Debug, Clone)]
struct Exec {
    tag: Tag,
    text: String,
    steps: VecDeque<Step>,
    /// Seconds of dwell left, once the dwell has started.
    dwell: Option<f64>,
    /// The line's target is outside the travel; waiting for the machine to stop.
    soft_limit: bool,
}

/// A simulated grblHAL controller for an XZC whirling lathe (see the crate docs).
#[derive(Debug)]
pub struct Controller {
    options: ControllerOptions,
    dialect: Dialect,
    travel: [(Option<f64>, Option<f64>); 3],
    settings: Settings,
    now: f64,
    rx: RxBuffer,
    assembler: LineAssembler,
    output: String,
    events: Vec<Event>,
    parser: ParserState,
    motion: Motion,
    alarm: Option<Alarm>,
    /// A critical alarm is active: only a soft reset clears it.
    critical: bool,
    /// In check mode, with the G92 offsets from before it (restored when it ends).
    check_mode: Option<[f64; 3]>,
    /// grblHAL's `gc_state.last_error`: G-code lines repeat it until cleared.
    last_error: Option<GrblError>,
    lines_taken: u64,
    exec: Option<Exec>,
    /// The spindle as executed (the parser's runs ahead).
    spindle: Spindle,
    feed_override: u8,
    rapid_override: u8,
    spindle_override: u8,
    wco_counter: u8,
    wco_changed: bool,
    ov_counter: u8,
    ov_changed: bool,
    last_state: MachineState,
    /// The Δ guard, if one watches the motion.
    guard: Option<Box<dyn Guard>>,
}

impl Controller {
    /// A controller for `machine`, powered up: the banner is waiting in the output.
    pub fn new(machine: &Machine, options: ControllerOptions) -> Result<Controller, ConfigError> {
        check_options(&options)?;
        let axes = machine;
        for (key, value) in [
            ("axes.x.max_rate", axes.x.max_rate),
            ("axes.x.accel", axes.x.accel),
            ("axes.z.max_rate", axes.z.max_rate),
            ("axes.z.accel", axes.z.accel),
            ("axes.c.max_rate", axes.c.max_rate),
            ("axes.c.accel", axes.c.accel),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ConfigError::Profile { key, value });
            }
        }
        let dynamics = Dynamics {
            max_rate: [axes.x.max_rate, axes.z.max_rate, axes.c.max_rate].map(|r| r / 60.0),
            accel: [axes.x.accel, axes.z.accel, axes.c.accel],
            junction_deviation: options.junction_deviation,
        };
        let span = |min: Option<f64>, max: Option<f64>| match (min, max) {
            (Some(a), Some(b)) => (b - a).max(0.0),
            _ => 0.0,
        };
        let c_travel = span(axes.c.min, axes.c.max);
        let settings = Settings {
            junction_deviation: options.junction_deviation,
            spindle_max: machine.spindle_rpm.map_or(1000.0, |s| s.1),
            spindle_min: machine.spindle_rpm.map_or(0.0, |s| s.0),
            max_rate: [
                axes.x.max_rate,
                axes.x.max_rate,
                axes.z.max_rate,
                axes.c.max_rate,
            ],
            accel: [axes.x.accel, axes.x.accel, axes.z.accel, axes.c.accel],
            travel: [
                span(axes.x.min, axes.x.max),
                0.0,
                span(axes.z.min, axes.z.max),
                c_travel,
            ],
            planner_blocks: options.planner_blocks,
        };
        let numbers = Numbers(machine.number);
        let start = options.start.to_array().map(|v| numbers.hold(v));
        let mut controller = Controller {
            dialect: Dialect {
                numbers,
                sync_on_offset_change: options.sync_on_offset_change,
            },
            travel: [
                (axes.x.min, axes.x.max),
                (axes.z.min, axes.z.max),
                (axes.c.min, axes.c.max),
            ],
            settings,
            now: 0.0,
            rx: RxBuffer::new(options.rx_buffer_size),
            assembler: LineAssembler::new(machine.max_line_length),
            output: report::banner(),
            events: Vec::new(),
            parser: ParserState::new(start, [0.0; 3]),
            motion: Motion::new(dynamics, options.planner_blocks, start),
            alarm: None,
            critical: false,
            check_mode: None,
            last_error: None,
            lines_taken: 0,
            exec: None,
            spindle: Spindle {
                on: false,
                ccw: false,
                rpm: 0.0,
            },
            feed_override: 100,
            rapid_override: 100,
            spindle_override: 100,
            wco_counter: 0,
            wco_changed: true,
            ov_counter: 1,
            ov_changed: false,
            last_state: MachineState::Idle,
            guard: None,
            options,
        };
        controller.last_state = controller.state();
        Ok(controller)
    }

    /// Bytes from the sender, in order. Real-time commands act at once (their output lands
    /// in the output immediately, between whole lines); the rest fills the RX buffer, and
    /// the main loop takes lines from it as far as it can without simulated time passing.
    pub fn receive(&mut self, bytes: &[u8]) {
        let mut dropped = 0;
        for &byte in bytes {
            match classify(byte) {
                ByteClass::Realtime(command) => self.realtime(command),
                ByteClass::Stored => {
                    if self.rx.push(byte) {
                        self.pump();
                    } else {
                        if dropped == 0 {
                            self.output.push_str(&report::message("RX overflow"));
                        }
                        dropped += 1;
                    }
                }
                ByteClass::Dropped => {}
            }
        }
        if dropped > 0 {
            self.events.push(Event::RxOverflow {
                time: self.now,
                dropped,
            });
        }
        self.note_state();
    }

    /// Lets `dt` seconds of simulated time pass: motion runs, dwells count down, and the
    /// main loop takes more lines as planner room appears, each at the moment it does.
    pub fn advance(&mut self, dt: f64) -> Result<(), TimeError> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(TimeError(dt));
        }
        let mut left = dt;
        let mut stalls = 0;
        while left > 0.0 {
            // A dwell's clock stops during a feed hold, as grbl suspends it.
            let dwelling = self.motion.hold() == Hold::None;
            let dwell = self
                .exec
                .as_ref()
                .and_then(|e| e.dwell)
                .filter(|_| dwelling);
            // The dwell bounds the step so the line is answered when it ends; a run of steps
            // that use no time (which the main loop should never cause) falls back to
            // letting the whole interval pass.
            let limit = match dwell {
                Some(d) if stalls < 4 => left.min(d.max(0.0)),
                _ => left,
            };
            let outcome = self.motion.step(limit, self.now);
            let used = outcome.used.clamp(0.0, left);
            self.now += used;
            left -= used;
            if let Some(exec) = self.exec.as_mut() {
                if let (Some(d), true) = (exec.dwell.as_mut(), dwelling) {
                    *d -= used;
                }
            }
            self.collect_executed();
            self.pump();
            stalls = if used > 0.0 || outcome.event.is_some() {
                0
            } else {
                stalls + 1
            };
        }
        Ok(())
    }

    /// Let `guard` watch every block executed from now on; a breach stops the machine with
    /// `ALARM:64` (see [`crate::guard`]).
    pub fn set_guard(&mut self, guard: Box<dyn Guard>) {
        self.guard = Some(guard);
    }

    /// The guard, to read what it has measured.
    pub fn guard(&self) -> Option<&dyn Guard> {
        self.guard.as_deref()
    }

    /// Everything the controller has printed since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.output).into_bytes()
    }

    /// Every event since the last call, in order.
    pub fn take_events(&mut self) -> Vec<Event> {
        self.collect_executed();
        std::mem::take(&mut self.events)
    }

    /// Simulated time since power-up, s.
    pub fn now(&self) -> f64 {
        self.now
    }

    /// Machine position now.
    pub fn position(&self) -> Position {
        Position::from_array(self.motion.position())
    }

    /// The state the status report shows.
    pub fn state(&self) -> MachineState {
        if self.alarm.is_some() {
            MachineState::Alarm
        } else if self.check_mode.is_some() {
            MachineState::Check
        } else {
            match self.motion.hold() {
                Hold::Decelerating => MachineState::Hold { complete: false },
                Hold::Complete => MachineState::Hold { complete: true },
                Hold::None if self.motion.is_running() => MachineState::Run,
                Hold::None => MachineState::Idle,
            }
        }
    }

    /// RX bytes free (the status report's `Bf:` second number).
    pub fn rx_free(&self) -> usize {
        self.rx.free()
    }

    /// Planner blocks free (the status report's `Bf:` first number).
    pub fn blocks_free(&self) -> usize {
        self.motion.blocks_free()
    }

    /// The options the controller was built with.
    pub fn options(&self) -> &ControllerOptions {
        &self.options
    }

    // ---- real-time commands ----

    fn realtime(&mut self, command: Realtime) {
        match command {
            Realtime::Reset => self.soft_reset(),
            Realtime::StatusReport => {
                let report = self.status_report();
                self.output.push_str(&report);
            }
            Realtime::ParserStateReport => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
            }
            Realtime::FeedHold => {
                if matches!(self.state(), MachineState::Idle | MachineState::Run) {
                    self.motion.feed_hold();
                }
            }
            Realtime::CycleStart => {
                if self.alarm.is_none() && self.motion.resume() {
                    self.pump();
                }
            }
            Realtime::FeedOverride(step) => {
                let next = step.apply(self.feed_override, OVERRIDE_MIN, OVERRIDE_MAX);
                self.set_overrides(next, self.rapid_override);
            }
            Realtime::RapidOverride(percent) => self.set_overrides(self.feed_override, percent),
            Realtime::SpindleOverride(step) => {
                let next = step.apply(self.spindle_override, OVERRIDE_MIN, OVERRIDE_MAX);
                self.ov_changed |= next != self.spindle_override;
                self.spindle_override = next;
            }
        }
        self.note_state();
    }

    fn set_overrides(&mut self, feed: u8, rapid: u8) {
        if (feed, rapid) != (self.feed_override, self.rapid_override) {
            self.feed_override = feed;
            self.rapid_override = rapid;
            self.ov_changed = true;
            self.motion
                .set_overrides(f64::from(feed) / 100.0, f64::from(rapid) / 100.0);
        }
    }

    /// grbl's soft reset: stop dead (an alarm if moving), forget every buffered byte and
    /// queued block, restore the parser's defaults, print the banner.
    fn soft_reset(&mut self) {
        let moving = self.motion.abort(self.now);
        if moving {
            self.raise(Alarm::AbortCycle);
        }
        self.exec = None;
        self.rx.clear();
        self.assembler.clear();
        self.last_error = None;
        // grblHAL keeps G92 across a reset (stored in NVS, `$384=0`); changes made in
        // check mode are dropped with it.
        let g92 = self.check_mode.take().unwrap_or(self.parser.g92);
        self.parser = ParserState::new(self.motion.position(), g92);
        self.critical = false;
        self.spindle.on = false;
        self.spindle_override = 100;
        self.set_overrides(100, 100);
        self.wco_changed = true;
        self.ov_counter = 1;
        self.ov_changed = false;
        self.output.push_str(&report::banner());
        if self.alarm.is_some() {
            self.output
                .push_str(&report::message("'$H'|'$X' to unlock"));
        }
        self.events.push(Event::Reset { time: self.now });
        self.collect_executed();
    }

    fn raise(&mut self, alarm: Alarm) {
        self.raise_with(alarm, None);
    }

    fn raise_with(&mut self, alarm: Alarm, breach: Option<Breach>) {
        self.alarm = Some(alarm);
        self.critical |= alarm.is_critical();
        self.output.push_str(&report::alarm(alarm));
        if let Some(b) = &breach {
            self.output.push_str(&report::message(&b.message));
        }
        if alarm.is_critical() {
            self.output.push_str(&report::message("Reset to continue"));
        }
        self.events.push(Event::Alarm {
            time: self.now,
            alarm,
            breach,
        });
    }

    fn status_report(&mut self) -> String {
        let state = self.state();
        let busy = matches!(state, MachineState::Run | MachineState::Hold { .. });
        let wco = if self.wco_counter > 0 && !self.wco_changed {
            self.wco_counter -= 1;
            None
        } else {
            self.wco_counter = if busy { 29 } else { 9 };
            self.wco_changed = false;
            Some(self.parser.g92)
        };
        let overrides = if self.ov_counter > 0 && !self.ov_changed {
            self.ov_counter -= 1;
            None
        } else {
            self.ov_counter = if busy { 19 } else { 9 };
            self.ov_changed = false;
            Some([
                self.feed_override,
                self.rapid_override,
                self.spindle_override,
            ])
        };
        let spindle_rpm = if self.spindle.on {
            self.spindle.rpm * f64::from(self.spindle_override) / 100.0
        } else {
            0.0
        };
        report::status(&StatusSnapshot {
            state,
            position: self.motion.position(),
            diameter: self.parser.diameter,
            blocks_free: self.blocks_free(),
            rx_free: self.rx.free(),
            line: self.motion.head_tag().and_then(|t| t.n).filter(|&n| n > 0),
            feed: self.motion.speed() * 60.0,
            spindle: spindle_rpm,
            wco,
            overrides,
            accessory: self
                .spindle
                .on
                .then_some(if self.spindle.ccw { 'C' } else { 'S' }),
        })
    }

    fn gc_report(&self) -> String {
        let p = &self.parser;
        report::gc_state(&GcSnapshot {
            motion: match p.motion {
                MotionMode::Rapid => 0,
                MotionMode::Linear => 1,
                MotionMode::Cancelled => 80,
            },
            coord_system: p.coord_system,
            plane: p.plane,
            inches: p.inches,
            incremental: p.incremental,
            inverse_time: p.inverse_time,
            diameter: p.diameter,
            spindle: match (p.spindle.on, p.spindle.ccw) {
                (false, _) => 5,
                (true, false) => 3,
                (true, true) => 4,
            },
            coolant: p.coolant,
            feed: p.feed,
            rpm: p.spindle.rpm,
        })
    }

    // ---- the main loop ----

    /// Runs the main loop until it blocks or the RX buffer is empty, then starts the cycle
    /// if motion is queued (grbl's auto cycle start).
    fn pump(&mut self) {
        loop {
            if self.exec.is_some() {
                if !self.run_exec() {
                    break;
                }
                continue;
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

    fn process_line(&mut self, line: crate::protocol::Line) {
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
        if text.starts_with('$') {
            let (result, reset) = self.system(&text);
            self.answer(tag, text, result);
            if reset {
                self.soft_reset();
            }
            return;
        }
        tag.n = interpreter::line_number(&text);
        if self.alarm.is_some() {
            return self.answer(tag, text, Err(GrblError::SystemGcLock));
        }
        if let Some(error) = self.last_error {
            // grblHAL's sticky error: not even parsed.
            return self.answer(tag, text, Err(error));
        }
        let g92 = self.parser.g92;
        match interpreter::interpret(&text, &mut self.parser, self.dialect) {
            Err(error) => self.answer(tag, text, Err(error)),
            Ok(block) => {
                self.wco_changed |= self.parser.g92 != g92;
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
    fn answer(&mut self, tag: Tag, text: String, result: Result<(), GrblError>) {
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

    /// Runs a `$` command; returns its result and whether a soft reset follows the answer.
    fn system(&mut self, text: &str) -> (Result<(), GrblError>, bool) {
        let command = SystemCommand::parse(text);
        if self.critical && !command.allowed_during_critical() {
            return (Err(GrblError::NotAllowedCriticalEvent), false);
        }
        let state = self.state();
        let idle_or_alarm = matches!(state, MachineState::Idle | MachineState::Alarm);
        let needs_idle = |ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(GrblError::IdleError)
            }
        };
        let result = match command {
            SystemCommand::Help => {
                self.output.push_str(&report::help());
                Ok(())
            }
            SystemCommand::Settings => needs_idle(!matches!(
                state,
                MachineState::Run | MachineState::Hold { .. }
            ))
            .map(|()| self.output.push_str(&report::settings(&self.settings))),
            SystemCommand::Setting(id) => needs_idle(idle_or_alarm).and_then(|()| {
                let value = self.settings.get(id).ok_or(GrblError::InvalidStatement)?;
                self.output
                    .push_str(&format!("${id}={value}{}", report::EOL));
                Ok(())
            }),
            SystemCommand::SetSetting | SystemCommand::Unsupported => {
                needs_idle(idle_or_alarm).and(Err(GrblError::InvalidStatement))
            }
            SystemCommand::ParserState => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
                Ok(())
            }
            SystemCommand::Parameters => needs_idle(idle_or_alarm).map(|()| {
                let text = report::parameters(self.parser.g92, self.parser.diameter);
                self.output.push_str(&text);
            }),
            SystemCommand::BuildInfo => needs_idle(idle_or_alarm).map(|()| {
                let text = report::build_info(
                    self.options.planner_blocks,
                    self.options.rx_buffer_size,
                    self.options.sync_on_offset_change,
                );
                self.output.push_str(&text);
            }),
            SystemCommand::StartupLines => needs_idle(idle_or_alarm).map(|()| {
                self.output
                    .push_str(&format!("$N0={0}$N1={0}", report::EOL));
            }),
            SystemCommand::Home => needs_idle(idle_or_alarm).and(Err(GrblError::HomingDisabled)),
            SystemCommand::Unlock => {
                if self.alarm.take().is_some() {
                    self.output.push_str(&report::message("Caution: Unlocked"));
                }
                Ok(())
            }
            SystemCommand::CheckMode => {
                if self.check_mode.is_some() && state == MachineState::Check {
                    self.output.push_str(&report::message("Disabled"));
                    return (Ok(()), true);
                }
                needs_idle(state == MachineState::Idle).map(|()| {
                    self.check_mode = Some(self.parser.g92);
                    self.output.push_str(&report::message("Enabled"));
                })
            }
        };
        (result, false)
    }

    /// Whether all queued motion is done and the machine stands still (grbl's
    /// `protocol_buffer_synchronize` condition).
    fn synced(&self) -> bool {
        self.motion.is_empty() && !self.motion.is_running()
    }

    fn outside_travel(&self, target: [f64; 3]) -> bool {
        let num = self.dialect.numbers;
        // Limits compared in the controller's number type, as grbl compares its floats.
        target.iter().zip(self.travel).any(|(&t, (min, max))| {
            min.is_some_and(|m| t < num.hold(m)) || max.is_some_and(|m| t > num.hold(m))
        })
    }

    /// Continues the blocked line; `true` once it is answered.
    fn run_exec(&mut self) -> bool {
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

    fn apply(&mut self, action: SyncAction) {
        match action {
            SyncAction::Wait => {}
            SyncAction::Spindle(spindle) => self.spindle = spindle,
            SyncAction::Pause => self.motion.feed_hold(),
            SyncAction::ProgramEnd => {
                if let Some(Err(breach)) = self.guard.as_mut().map(|g| g.program_end()) {
                    self.trip_guard(breach);
                    return;
                }
                self.spindle.on = false;
                self.output.push_str(&report::message("Pgm End"));
            }
        }
    }

    /// A target outside the travel, with the machine at rest: the queue is purged (nothing
    /// after the line runs), `ALARM:2`, and the line is answered `error:15`.
    fn trip_soft_limit(&mut self, exec: Exec) {
        self.motion.abort(self.now);
        self.raise(Alarm::SoftLimit);
        self.answer(exec.tag, exec.text, Err(GrblError::TravelExceeded));
        self.collect_executed();
    }

    /// Moves finished blocks to the events, showing each to the guard first while no alarm
    /// is up (a breach found here stops what is still moving).
    fn collect_executed(&mut self) {
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
    fn trip_guard(&mut self, breach: Breach) {
        self.raise_with(Alarm::ProfileError, Some(breach));
        self.motion.abort(self.now);
        if let Some(exec) = self.exec.take() {
            self.answer(exec.tag, exec.text, Err(GrblError::SystemGcLock));
        }
        self.collect_executed();
    }

    fn note_state(&mut self) {
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

fn check_options(options: &ControllerOptions) -> Result<(), ConfigError> {
    if options.rx_buffer_size < 2 {
        return Err(ConfigError::Option {
            name: "rx_buffer_size",
            value: options.rx_buffer_size.to_string(),
            reason: "must be at least 2 (the ring keeps one byte free)",
        });
    }
    if options.planner_blocks == 0 {
        return Err(ConfigError::Option {
            name: "planner_blocks",
            value: "0".into(),
            reason: "must be at least 1",
        });
    }
    if !(options.junction_deviation.is_finite() && options.junction_deviation >= 0.0) {
        return Err(ConfigError::Option {
            name: "junction_deviation",
            value: options.junction_deviation.to_string(),
            reason: "must be a finite number of mm, zero or more",
        });
    }
    if !options.start.to_array().iter().all(|v| v.is_finite()) {
        return Err(ConfigError::Option {
            name: "start",
            value: format!("{:?}", options.start),
            reason: "must be a finite position",
        });
    }
    Ok(())
}
