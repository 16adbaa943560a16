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
use crate::interpreter::{Dialect, Numbers, ParserState, Spindle, Step};
use crate::motion::{Dynamics, Hold, Motion, Tag};
use crate::protocol::{classify, ByteClass, LineAssembler, RxBuffer};
use crate::record::{ExecutedBlock, Position};
use crate::report::{self, MachineState, Tracker};
use crate::settings::{report_bits, Initial, Settings};

mod main_loop;
mod options;
mod realtime;
mod system;

use options::check_options;
pub use options::ControllerOptions;

/// Feed and spindle overrides stay within 10–200 % (grbl's `config.h` defaults).
const OVERRIDE_MIN: u8 = 10;
/// See [`OVERRIDE_MIN`].
const OVERRIDE_MAX: u8 = 200;

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
    /// Bytes waiting in the link for room in the RX buffer
    /// ([`ControllerOptions::rx_backpressure`]).
    link: VecDeque<u8>,
    /// A jog cancel (0x85) stopping a jog: the main loop reads no line until the machine
    /// stands (grbl's jog-cancel suspend), so the next line finds it idle.
    jog_cancelling: bool,
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
            link: VecDeque::new(),
            jog_cancelling: false,
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
    /// With [`ControllerOptions::rx_backpressure`], bytes that find the buffer at its
    /// reserve wait in the link, real-time ones too, until lines have been read.
    pub fn receive(&mut self, bytes: &[u8]) {
        let mut dropped = 0;
        match self.options.rx_backpressure {
            None => {
                for &byte in bytes {
                    self.take(byte, &mut dropped);
                }
            }
            Some(_) => {
                self.link.extend(bytes);
                self.deliver();
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

    /// One byte through the receive interrupt: a real-time command acts, another is stored
    /// (or, with the buffer full, dropped and counted in `dropped`).
    fn take(&mut self, byte: u8, dropped: &mut usize) {
        match classify(byte) {
            ByteClass::Realtime(command) => self.realtime(command),
            ByteClass::Stored => {
                if self.rx.push(byte) {
                    self.pump();
                } else {
                    if *dropped == 0 {
                        self.output.push_str(&report::message("RX overflow"));
                    }
                    *dropped += 1;
                }
            }
            ByteClass::Dropped => {}
        }
    }

    /// Hands the bytes waiting in the link to the receive interrupt while the RX buffer has
    /// more than the reserve free.
    fn deliver(&mut self) {
        let Some(reserve) = self.options.rx_backpressure else {
            return;
        };
        let mut dropped = 0;
        while self.rx.free() > reserve {
            let Some(byte) = self.link.pop_front() else {
                break;
            };
            self.take(byte, &mut dropped);
        }
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
            self.deliver();
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
