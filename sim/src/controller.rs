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
use crate::report::{self, Flags, GcSnapshot, MachineState, StatusSnapshot, Tracker, Units};
use crate::settings::{self, report_bits, Initial, Settings};
use crate::system::SystemCommand;

/// The longest build string `$I=` stores (grblHAL's `stored_line_t` holds
/// `MAX_STORED_LINE_LENGTH` = 70 bytes with its terminator; `system.c` refuses a string of
/// 69 or more, `error:3`).
const MAX_BUILD_INFO: usize = 68;

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
    /// Wait for the queue to empty before a G92 or G54–G59 change takes effect, as
    /// grblHAL does by default (`$10` bit 8, "Buffer sync on WCO change", in its default
    /// `$10=511`; `$I` shows `W` when off).
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
    /// The soft limits of X, Z, C (the profile's, then as `$130`–`$133` set them).
    travel: [(Option<f64>, Option<f64>); 3],
    /// The profile's travel, which `$130`–`$133` are measured from.
    profile_travel: [(Option<f64>, Option<f64>); 3],
    settings: Settings,
    /// The build info string `$I` shows (`$I=` sets it).
    build_info: String,
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
    /// Flood coolant as executed.
    coolant: bool,
    /// A jog (`$J=`) is queued or running: the state is `Jog`.
    jogging: bool,
    feed_override: u8,
    rapid_override: u8,
    spindle_override: u8,
    /// What the next status report shows of its optional fields.
    tracker: Tracker,
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
        let span = |min: Option<f64>, max: Option<f64>| match (min, max) {
            (Some(a), Some(b)) => (b - a).max(0.0),
            _ => 0.0,
        };
        // Y, which never moves, shows X's rate and acceleration and no travel.
        let settings = Settings::new(&Initial {
            junction_deviation: options.junction_deviation,
            spindle: machine
                .spindle_rpm
                .map_or((1000.0, 0.0), |(min, max)| (max, min)),
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
                span(axes.c.min, axes.c.max),
            ],
            planner_blocks: options.planner_blocks,
            sync_on_offset_change: options.sync_on_offset_change,
        });
        let numbers = Numbers(machine.number);
        let start = options.start.to_array().map(|v| numbers.hold(v));
        let travel = [
            (axes.x.min, axes.x.max),
            (axes.z.min, axes.z.max),
            (axes.c.min, axes.c.max),
        ];
        let mut controller = Controller {
            dialect: dialect(numbers, &settings),
            travel,
            profile_travel: travel,
            now: 0.0,
            rx: RxBuffer::new(options.rx_buffer_size),
            assembler: LineAssembler::new(machine.max_line_length),
            output: report::banner(),
            events: Vec::new(),
            parser: ParserState::new(start, [0.0; 3]),
            motion: Motion::new(dynamics(&settings), options.planner_blocks, start),
            settings,
            build_info: String::new(),
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
            coolant: false,
            jogging: false,
            feed_override: 100,
            rapid_override: 100,
            spindle_override: 100,
            tracker: Tracker::after_reset(),
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

    /// The feed override now, percent.
    pub fn feed_override(&self) -> u8 {
        self.feed_override
    }

    /// Sets the feed override to `percent` at once, as a front end with an override
    /// register does (the Modbus bank's `FEED_OVERRIDE`), held within 10–200 % as grbl holds
    /// its real-time steps; the G-code front end takes 0x90–0x94 instead.
    pub fn set_feed_override(&mut self, percent: u8) {
        let percent = percent.clamp(OVERRIDE_MIN, OVERRIDE_MAX);
        self.set_overrides(percent, self.rapid_override);
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
        } else if self.jogging && self.motion.is_running() {
            // A hold during a jog is its cancel: grblHAL's state stays `Jog` while it slows.
            MachineState::Jog
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
            Realtime::CompleteStatusReport => {
                self.tracker.add(Flags::everything());
                let report = self.status_report();
                self.output.push_str(&report);
            }
            Realtime::JogCancel => self.jog_cancel(),
            Realtime::ParserStateReport => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
            }
            Realtime::FeedHold => {
                // Not during a jog: grblHAL's `state_set` refuses a hold from `Jog`
                // (`state_machine.c`); 0x85 is the way to stop one.
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
                if next != self.spindle_override {
                    self.tracker.add(Flags {
                        overrides: true,
                        ..Flags::default()
                    });
                }
                self.spindle_override = next;
            }
        }
        self.note_state();
    }

    fn set_overrides(&mut self, feed: u8, rapid: u8) {
        if (feed, rapid) != (self.feed_override, self.rapid_override) {
            self.feed_override = feed;
            self.rapid_override = rapid;
            self.tracker.add(Flags {
                overrides: true,
                ..Flags::default()
            });
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
        self.jogging = false;
        self.rx.clear();
        self.assembler.clear();
        self.last_error = None;
        // grblHAL keeps G92 across a reset (stored in NVS) unless `$384=1`; changes made in
        // check mode are dropped with it.
        let g92 = self.check_mode.take().unwrap_or(self.parser.g92);
        let g92 = if self.settings.g92_volatile() {
            [0.0; 3]
        } else {
            g92
        };
        self.parser = ParserState::new(self.motion.position(), g92);
        self.critical = false;
        self.spindle.on = false;
        self.coolant = false;
        self.spindle_override = 100;
        self.set_overrides(100, 100);
        self.tracker = Tracker::after_reset();
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

    fn units(&self) -> Units {
        Units {
            diameter: self.parser.diameter,
            inches: self.settings.report_inches(),
            c_rotary: self.settings.c_rotary(),
        }
    }

    fn status_report(&mut self) -> String {
        let state = self.state();
        // The executing block's N, else the parser's last (grblHAL's `Ln:` falls back on
        // `gc_state.line_number`, `report.c`).
        let line = match self.motion.head_tag() {
            Some(tag) => tag.n.unwrap_or(0),
            None => self.parser.line_number,
        };
        let spindle_rpm = self.spindle.rpm * f64::from(self.spindle_override) / 100.0;
        let snapshot = StatusSnapshot {
            state,
            alarm: self.alarm,
            position: self.motion.position(),
            offset: self.parser.g92,
            coord_system: self.parser.coord_system,
            units: self.units(),
            mask: self.settings.report_mask(),
            lathe: self.settings.lathe_mode(),
            homing_axes: self.settings.homing_axes(),
            blocks_free: self.blocks_free(),
            rx_free: self.rx.free(),
            line: Some(line).filter(|&n| n > 0),
            feed: self.motion.speed() * 60.0,
            spindle: (self.spindle.on, self.spindle.ccw, spindle_rpm),
            coolant: self.coolant,
            overrides: [
                self.feed_override,
                self.rapid_override,
                self.spindle_override,
            ],
        };
        report::status(&snapshot, &mut self.tracker)
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
            g92: p.g92 != [0.0; 3],
            lathe: self.settings.lathe_mode(),
            diameter: p.diameter,
            plane: p.plane,
            inches: p.inches,
            incremental: p.incremental,
            inverse_time: p.inverse_time,
            retract_r: p.retract_r,
            spindle: match (p.spindle.on, p.spindle.ccw) {
                (false, _) => 5,
                (true, false) => 3,
                (true, true) => 4,
            },
            coolant: p.coolant,
            feed: p.feed,
            rpm: p.spindle.rpm,
            units: self.units(),
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

    /// Runs a `$` command; returns its result (`None` while a jog waits for planner room:
    /// it is answered when queued) and whether a soft reset follows the answer. States and
    /// errors as grblHAL's `system.c` has them for each command.
    fn system(
        &mut self,
        command: SystemCommand,
        tag: Tag,
    ) -> (Option<Result<(), GrblError>>, bool) {
        if self.critical && !command.allowed_during_critical() {
            return (Some(Err(GrblError::NotAllowedCriticalEvent)), false);
        }
        let state = self.state();
        // Idle, or in alarm or check mode: where grblHAL reads and writes settings and
        // prints `$I` and `$N`.
        let settled = matches!(
            state,
            MachineState::Idle | MachineState::Alarm | MachineState::Check
        );
        let needs = |ok: bool| {
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
            SystemCommand::HelpTopics => {
                self.output.push_str(&help_topics());
                Ok(())
            }
            SystemCommand::Settings => needs(!matches!(
                state,
                MachineState::Run | MachineState::Hold { .. }
            ))
            .map(|()| self.output.push_str(&report::settings(&self.settings))),
            SystemCommand::Setting(id) => needs(settled).and_then(|()| {
                let value = self.settings.text(id).ok_or(GrblError::SettingDisabled)?;
                self.output
                    .push_str(&format!("${id}={value}{}", report::EOL));
                Ok(())
            }),
            SystemCommand::SetSetting(id, value) => needs(settled)
                .and_then(|()| self.settings.store(id, &value))
                .map(|()| self.settings_changed(id)),
            SystemCommand::ParserState => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
                // `$G` asks for the homed state in the next report (`system.c`).
                self.tracker.add(Flags {
                    homed: true,
                    ..Flags::default()
                });
                Ok(())
            }
            SystemCommand::Parameters => {
                let text = report::parameters(self.parser.g92, self.units());
                self.output.push_str(&text);
                Ok(())
            }
            SystemCommand::BuildInfo => needs(settled).map(|()| {
                let text = report::build_info(&report::BuildInfo {
                    build: &self.build_info,
                    blocks: self.options.planner_blocks,
                    rx_size: self.options.rx_buffer_size,
                    sync_on_offset_change: self.dialect.sync_on_offset_change,
                    legacy_realtime: self.settings.legacy_realtime(),
                    homing: self.settings.homing_enabled(),
                    lathe: self.settings.lathe_mode(),
                });
                self.output.push_str(&text);
            }),
            SystemCommand::SetBuildInfo(text) => needs(settled).and_then(|()| {
                if text.len() > MAX_BUILD_INFO {
                    return Err(GrblError::InvalidStatement);
                }
                self.build_info = text;
                Ok(())
            }),
            SystemCommand::StartupLines => needs(settled).map(|()| {
                self.output
                    .push_str(&format!("$N0={0}$N1={0}", report::EOL));
            }),
            SystemCommand::Home => needs(matches!(state, MachineState::Idle | MachineState::Alarm))
                .and(Err(GrblError::HomingDisabled)),
            SystemCommand::Unlock => {
                if self.alarm.take().is_some() {
                    self.output.push_str(&report::message("Caution: Unlocked"));
                }
                Ok(())
            }
            SystemCommand::CheckMode => {
                if self.check_mode.is_some() && state == MachineState::Check {
                    self.output.push_str(&report::message("Disabled"));
                    return (Some(Ok(())), true);
                }
                needs(state == MachineState::Idle).map(|()| {
                    self.check_mode = Some(self.parser.g92);
                    self.output.push_str(&report::message("Enabled"));
                })
            }
            SystemCommand::Jog(gcode) => {
                return match self.jog(&gcode, tag) {
                    Ok(true) => (Some(Ok(())), false),
                    Ok(false) => (None, false),
                    Err(error) => (Some(Err(error)), false),
                };
            }
            SystemCommand::AlarmCodes => {
                self.output.push_str(&report::alarm_codes());
                Ok(())
            }
            SystemCommand::ErrorCodes => {
                self.output.push_str(&report::error_codes());
                Ok(())
            }
            SystemCommand::SettingGroups => {
                self.output.push_str(&settings::groups());
                Ok(())
            }
            SystemCommand::SettingDetails => {
                self.output.push_str(&settings::details());
                Ok(())
            }
            SystemCommand::SettingDescription(id) => {
                // grblHAL (`output_setting_description`) prints the description of a setting
                // it has and nothing for another; the simulator has no descriptions to give
                // and prints what grblHAL prints for a setting without one.
                let mut at = 0;
                match interpreter::read_float(id.as_bytes(), &mut at) {
                    None => Err(GrblError::BadNumberFormat),
                    Some(id) if id.fract() != 0.0 => Err(GrblError::InvalidStatement),
                    Some(id) => {
                        let id = id.clamp(0.0, f64::from(u16::MAX)) as u16;
                        if self.settings.text(id).is_some() {
                            self.output
                                .push_str(&format!("[SETTINGDESCR:{id}|]{}", report::EOL));
                        }
                        Ok(())
                    }
                }
            }
            SystemCommand::Unsupported => Err(GrblError::InvalidStatement),
        };
        (Some(result), false)
    }

    /// A jog, `$J=` with `gcode` (grblHAL's `jog` in `system.c`, then `gc_execute_block`
    /// and `mc_jog_execute` in `motion_control.c`): only idle or jogging (`error:8`); a
    /// target beyond the soft limits is refused, `error:15` and no alarm, or with `$40=1`
    /// cut to them. `Ok(true)`: queued; `Ok(false)`: waiting for planner room (the line is
    /// then executed like a G1 and answered once queued).
    fn jog(&mut self, gcode: &str, tag: Tag) -> Result<bool, GrblError> {
        if !matches!(self.state(), MachineState::Idle | MachineState::Jog) {
            return Err(GrblError::IdleError);
        }
        let mut jog = interpreter::jog(gcode, &self.parser, self.dialect)?;
        if self.settings.soft_limits() {
            let limits = self.limits();
            let target = &mut jog.request.target;
            if self.settings.jog_soft_limited() {
                for (t, (min, max)) in target.iter_mut().zip(limits) {
                    *t = t.clamp(min, max);
                }
            } else if self.outside_travel(*target) {
                return Err(GrblError::TravelExceeded);
            }
        }
        self.parser.position = jog.request.target;
        let tag = Tag { n: jog.n, ..tag };
        self.exec = Some(Exec {
            tag,
            text: String::new(),
            steps: VecDeque::from([Step::Motion(jog.request)]),
            dwell: None,
            soft_limit: false,
        });
        self.jogging = self.jogging || self.state() == MachineState::Idle;
        if self.run_exec_quietly() {
            return Ok(true);
        }
        Ok(false)
    }

    /// Runs the line just made the executing one without answering it; `true` if it is
    /// done (its steps all taken), `false` if it waits.
    fn run_exec_quietly(&mut self) -> bool {
        let Some(mut exec) = self.exec.take() else {
            return true;
        };
        while let Some(Step::Motion(request)) = exec.steps.front().copied() {
            if self.motion.blocks_free() == 0 {
                self.exec = Some(exec);
                return false;
            }
            self.motion.push(request, exec.tag);
            exec.steps.pop_front();
        }
        true
    }

    /// Jog cancel (0x85, grblHAL's `CMD_JOG_CANCEL`): the RX buffer and the line being
    /// read are dropped unanswered and the sticky error cleared, whatever the state; a jog
    /// slows to a stop and its queue is dropped, and the parser takes the position the
    /// machine stopped at. A jog line already waiting for planner room is not in the
    /// buffer: as in grblHAL's `mc_line`, it is queued once the cancel has emptied the
    /// planner, and starts a new jog.
    fn jog_cancel(&mut self) {
        self.rx.clear();
        self.assembler.clear();
        self.last_error = None;
        if self.state() == MachineState::Jog {
            self.motion.cancel(self.now);
            self.collect_executed();
            self.pump();
        }
    }

    /// The soft limits as numbers (±∞ where an axis has none).
    fn limits(&self) -> [(f64, f64); 3] {
        let num = self.dialect.numbers;
        self.travel.map(|(min, max)| {
            (
                min.map_or(f64::NEG_INFINITY, |m| num.hold(m)),
                max.map_or(f64::INFINITY, |m| num.hold(m)),
            )
        })
    }

    /// A setting was written: what it changes beyond its value.
    fn settings_changed(&mut self, id: u16) {
        match id {
            10 | 32 | 376 => {
                self.dialect = dialect(self.dialect.numbers, &self.settings);
                if !self.settings.lathe_mode() {
                    // `set_mode`: leaving lathe mode ends diameter mode.
                    self.parser.diameter = false;
                }
            }
            11 | 110..=123 => self.motion.set_dynamics(dynamics(&self.settings)),
            // `set_report_inches` refreshes the WCO (`system_flag_wco_change`).
            13 => self.tracker.add(Flags {
                wco: true,
                ..Flags::default()
            }),
            130..=133 => {
                let lengths = self.settings.travel();
                for (i, length) in lengths.into_iter().enumerate() {
                    self.travel[i] = travel(self.profile_travel[i], length);
                }
            }
            _ => {}
        }
    }

    /// Whether all queued motion is done and the machine stands still (grbl's
    /// `protocol_buffer_synchronize` condition).
    fn synced(&self) -> bool {
        self.motion.is_empty() && !self.motion.is_running()
    }

    /// Whether soft limits are on (`$20`) and `target` is beyond them.
    fn outside_travel(&self, target: [f64; 3]) -> bool {
        // Limits compared in the controller's number type, as grbl compares its floats.
        self.settings.soft_limits()
            && target
                .iter()
                .zip(self.limits())
                .any(|(&t, (min, max))| t < min || t > max)
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

/// How lines are read, from the number type and the settings.
fn dialect(numbers: Numbers, settings: &Settings) -> Dialect {
    Dialect {
        numbers,
        sync_on_offset_change: settings.report_mask() & report_bits::SYNC_ON_WCO_CHANGE != 0,
        lathe: settings.lathe_mode(),
        c_rotary: settings.c_rotary(),
    }
}

/// The planner's dynamics from `$11`, `$110`–`$113` and `$120`–`$123`.
fn dynamics(settings: &Settings) -> Dynamics {
    Dynamics {
        max_rate: settings.max_rate().map(|r| r / 60.0),
        accel: settings.accel(),
        junction_deviation: settings.junction_deviation(),
    }
}

/// An axis' soft limits after `$13n` = `length`: the profile's, which `$$` shows as their
/// span, kept while the span is; else from the profile's minimum over `length`; an axis
/// the profile leaves unlimited gets grblHAL's own travel, `[−length, 0]`
/// (`settings.axis[].max_travel` is stored negative), and none for a length of 0.
fn travel(profile: (Option<f64>, Option<f64>), length: f64) -> (Option<f64>, Option<f64>) {
    match profile {
        // To within the 3 decimals `$$` shows: a span written back as read changes nothing.
        (Some(min), Some(max)) if (max - min - length).abs() < 5e-4 => profile,
        (Some(min), Some(_)) => (Some(min), Some(min + length)),
        _ if length == 0.0 => (None, None),
        _ => (Some(-length), Some(0.0)),
    }
}

/// `$HELP` (`report_help` without a topic): the topics, then the setting groups' names in
/// order.
fn help_topics() -> String {
    let eol = report::EOL;
    let mut groups: Vec<&str> = settings::GROUPS
        .iter()
        .filter(|(id, ..)| *id != 0)
        .map(|(_, _, name)| *name)
        .collect();
    groups.sort_unstable();
    let mut out = format!("Help topics:{eol} Commands{eol} Settings{eol}");
    for name in groups {
        out.push_str(&format!(" {name}{eol}"));
    }
    out
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
