//! The register bank: `docs/modbus.md`'s holding registers in front of a [`Controller`].
//!
//! [`Bank::request`] answers function codes 03, 06 and 16 (anything else 01) with the
//! registers or an exception; [`Bank::advance`] lets simulated time pass for the
//! controller and the watchdog. Between the two, the bank moves segments from the ring
//! into the controller:
//!
//! - **Publishing.** A HEAD write is checked before anything changes: the value, the
//!   state, the room in the ring, then each newly published slot in order (CRC,
//!   sequence number, content). The first failure raises its alarm (101, 102, 103), the
//!   write is answered 04 and HEAD stays. Published slots are read-only to the bridge: a
//!   write that would change one is answered 06, a write that leaves it as it is (a
//!   re-sent copy) is accepted.
//! - **Taking.** While `RUN` is set and no alarm or stop is under way, the slot at TAIL
//!   becomes its G-code line and goes to [`Controller::receive`]. One line at a time:
//!   when the controller answers it `ok` (a motion once it is in the planner, a spindle
//!   change, dwell or program end once done), TAIL moves past the slot and the next one
//!   goes. So the planner's look-ahead stays full, and the RX buffer never holds more
//!   than one line. The line's N word is the sequence number modulo 10⁷ (grbl's largest
//!   line number is 10 000 000); the lines rely on the power-up modes (mm, absolute,
//!   radius), which nothing sent changes, and a G1 always says G93 or G94.
//! - **Executed.** `EXECUTED_SEQ` follows the controller's execution record: a motion
//!   when its [`Event::Executed`] block completes, anything else when it is answered, and
//!   everything taken once the controller is idle with an empty planner (a move to where
//!   the machine already is leaves no block).
//! - **Alarms.** The controller's own alarms (2, 3, 64) are passed through as they
//!   happen; it has already stopped. The bank's (101–105) stop the machine as grbl stops
//!   for a soft limit: a feed hold, and once at rest a soft reset that purges the
//!   controller's queue. The ring is frozen until `RESET_ALARM` (a soft reset and `$X`,
//!   then a flush).
//! - **Watchdog.** Armed while `RUN` is set and `END` clear; [`Bank::advance`] stops the
//!   controller's clock at the deadline to raise alarm 104 on time.
//!
//! What the controller prints is dropped (a Modbus controller has no text channel); its
//! [`Event`]s are kept for [`Bank::take_events`].

use std::collections::VecDeque;

use crate::controller::{Controller, Event};
use crate::error::{ConfigError, TimeError};
use crate::report::MachineState;

use super::{crc16, Exception, Request, Response, WordOrder};

// Addresses (docs/modbus.md, "Address map"). Each number of the map is written once, here;
// the tests check them against tests/data/modbus-golden.json.
const MAGIC_0: u16 = 0;
const MAGIC_1: u16 = 1;
const MAP_VERSION: u16 = 2;
const SLOT_COUNT: u16 = 3;
const SLOT_SIZE: u16 = 4;
const WORD_ORDER: u16 = 5;
const MAX_SEGMENT_RATE: u16 = 6;
const WATCHDOG_TIMEOUT: u16 = 7;
/// The first status register: registers `STATE..CONTROL` are [`Bank::status`]'s.
const STATE: u16 = 16;
const ALARM_CODE: u16 = 17;
const ALARM_SEQ: u16 = 18;
const ALARM_DETAIL: u16 = 20;
const TAIL: u16 = 21;
const EXECUTED_SEQ: u16 = 22;
const POS_X: u16 = 24;
const POS_Z: u16 = 26;
const POS_C: u16 = 28;
const CONTROL: u16 = 32;
const HEAD: u16 = 33;
const WATCHDOG: u16 = 34;
/// `FEED_OVERRIDE`, percent of the programmed feed, 10–200.
const FEED_OVERRIDE: u16 = 40;
/// The range `FEED_OVERRIDE` takes.
const FEED_OVERRIDE_RANGE: std::ops::RangeInclusive<u16> = 10..=200;
const RING: u16 = 256;
/// Registers in the status block, `STATE..CONTROL`.
const STATUS_LEN: usize = (CONTROL - STATE) as usize;

// Identification values.
/// `MAGIC_0`, `MAGIC_1`: ASCII "WH", "RL".
const MAGIC: [u16; 2] = [0x5748, 0x524C];
/// `MAP_VERSION`.
const VERSION: u16 = 1;
/// Registers per slot (`SLOT_SIZE`).
const SLOT: u16 = 16;
/// Slots a ring may have.
const SLOTS: std::ops::RangeInclusive<u16> = 2..=64;

// Modbus's own limits: registers one FC03 may read, one FC16 may write.
const MAX_READ: u16 = 125;
const MAX_WRITE: usize = 123;

// A slot's registers, from its first ("Slot layout").
const SLOT_SEQ: usize = 0;
const SLOT_KIND: usize = 2;
const SLOT_X: usize = 4;
const SLOT_Z: usize = 6;
const SLOT_C: usize = 8;
const SLOT_PARAM: usize = 12;
const SLOT_CRC: usize = 15;
/// The reserved registers, which hold 0.
const SLOT_RESERVED: [usize; 2] = [3, 14];

// Segment kinds, the low byte of KIND.
const KIND_MASK: u16 = 0x00FF;
const KIND_LINKED: u16 = 1;
const KIND_RAPID: u16 = 2;
const KIND_FEED: u16 = 3;
const KIND_DWELL: u16 = 4;
const KIND_SPINDLE_ON: u16 = 5;
const KIND_SPINDLE_OFF: u16 = 6;
const KIND_PROGRAM_END: u16 = 7;

// Axis flags, the high byte of KIND, in the order X, Z, C.
const FLAG_X: u16 = 1 << 8;
const FLAG_Z: u16 = 1 << 9;
const FLAG_C: u16 = 1 << 10;
const FLAGS: [u16; 3] = [FLAG_X, FLAG_Z, FLAG_C];

// Units ("Units"), as decimals of the quantity written in G-code.
/// X and Z: 0.1 µm, 10⁻⁴ mm.
const LINEAR_DECIMALS: u32 = 4;
/// C: 10⁻⁴ °.
const ANGULAR_DECIMALS: u32 = 4;
/// Feed (mm/min) and spindle speed (rev/min): thousandths.
const MILLI_DECIMALS: u32 = 3;
/// Durations: µs, 10⁻⁶ s.
const MICRO_DECIMALS: u32 = 6;
/// A linked move's duration, µs, per minute of inverse time.
const MICROS_PER_MINUTE: u128 = 60_000_000;
/// Decimals of a linked move's inverse-time F.
const INVERSE_TIME_DECIMALS: u32 = 6;

// Control word bits.
const RUN: u16 = 1;
const HOLD: u16 = 2;
const RESUME: u16 = 4;
const RESET_ALARM: u16 = 8;
const ABORT: u16 = 16;
const END: u16 = 32;

// States.
const IDLE: u16 = 0;
const RUNNING: u16 = 1;
const HELD: u16 = 2;
const ALARM: u16 = 3;
const DONE: u16 = 4;

// The map's own alarms.
const ALARM_CRC: u16 = 101;
const ALARM_SEQUENCE: u16 = 102;
const ALARM_SEGMENT: u16 = 103;
const ALARM_WATCHDOG: u16 = 104;
const ALARM_REFUSED: u16 = 105;

/// grbl's line numbers go up to 10 000 000; the N word is the sequence number modulo 10⁷.
const LINE_NUMBERS: u32 = 10_000_000;

/// How a [`Bank`] is set up: what a real controller would have as parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BankOptions {
    /// N, slots in the ring, 2–64.
    pub slots: u16,
    /// Word order of 32- and 64-bit values.
    pub word_order: WordOrder,
    /// Watchdog timeout, ms, at least 1.
    pub watchdog_timeout_ms: u16,
    /// `MAX_SEGMENT_RATE`, segments per second, at least 1. Reported, not enforced: the
    /// simulator has no interpolation cycle.
    pub max_segment_rate: u16,
    /// The map has the `FEED_OVERRIDE` register (40); a PLC built before it answers
    /// exception 02 there.
    pub feed_override: bool,
}

impl Default for BankOptions {
    /// 32 slots (31 segments, about 1.7 s of a whirling pass at 55 ms a segment, on top of
    /// the planner's blocks), high word first, 1 s watchdog, 1000 segments/s (a 1 kHz
    /// interpolation cycle).
    fn default() -> BankOptions {
        BankOptions {
            slots: 32,
            word_order: WordOrder::HighFirst,
            watchdog_timeout_ms: 1000,
            max_segment_rate: 1000,
            feed_override: true,
        }
    }
}

/// A segment as a valid slot describes it, in the map's units (0.1 µm, 10⁻⁴ °, µs,
/// thousandths).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Segment {
    Linked { xzc: [i64; 3], micros: u32 },
    Rapid { axes: [Option<i64>; 3] },
    Feed { axes: [Option<i64>; 3], milli: u32 },
    Dwell { micros: u32 },
    SpindleOn { milli: u32 },
    SpindleOff,
    ProgramEnd,
}

impl Segment {
    /// Reads a slot whose CRC has been checked; `None` if it is not a valid segment.
    fn parse(slot: &[u16], order: WordOrder) -> Option<Segment> {
        let all = FLAG_X | FLAG_Z | FLAG_C;
        let kind = slot[SLOT_KIND] & KIND_MASK;
        let flags = slot[SLOT_KIND] & !KIND_MASK;
        if SLOT_RESERVED.iter().any(|&k| slot[k] != 0) || flags & !all != 0 {
            return None;
        }
        let field = |at: usize, words: usize| order.value(&slot[at..at + words]);
        let x = field(SLOT_X, 2) as u32 as i32;
        let z = field(SLOT_Z, 2) as u32 as i32;
        let c = field(SLOT_C, 4) as i64;
        let param = field(SLOT_PARAM, 2) as u32;
        let values = [i64::from(x), i64::from(z), c];
        let mut axes = [None; 3];
        for (k, axis) in axes.iter_mut().enumerate() {
            if flags & FLAGS[k] != 0 {
                *axis = Some(values[k]);
            } else if values[k] != 0 {
                return None;
            }
        }
        let no_axes = flags == 0;
        let segment = match kind {
            KIND_LINKED if flags == all && param >= 1 => Segment::Linked {
                xzc: values,
                micros: param,
            },
            KIND_RAPID if param == 0 => Segment::Rapid { axes },
            KIND_FEED if param >= 1 => Segment::Feed { axes, milli: param },
            KIND_DWELL if no_axes => Segment::Dwell { micros: param },
            KIND_SPINDLE_ON if no_axes => Segment::SpindleOn { milli: param },
            KIND_SPINDLE_OFF if no_axes && param == 0 => Segment::SpindleOff,
            KIND_PROGRAM_END if no_axes && param == 0 => Segment::ProgramEnd,
            _ => return None,
        };
        Some(segment)
    }

    /// Whether the line queues motion (answered when planned, not when done).
    fn moves(&self) -> bool {
        matches!(
            self,
            Segment::Linked { .. } | Segment::Rapid { .. } | Segment::Feed { .. }
        )
    }

    /// The G-code line, with N word `n`.
    fn line(&self, n: u32) -> String {
        let words = |axes: &[Option<i64>; 3]| -> String {
            let letters = [
                ('X', LINEAR_DECIMALS),
                ('Z', LINEAR_DECIMALS),
                ('C', ANGULAR_DECIMALS),
            ];
            axes.iter()
                .zip(letters)
                .filter_map(|(v, (letter, decimals))| {
                    v.map(|v| format!(" {letter}{}", decimal(v, decimals)))
                })
                .collect()
        };
        match self {
            Segment::Linked { xzc, micros } => {
                // F = 1 / minutes = 60 000 000 / µs, to 10⁻⁶.
                let scale = 10u128.pow(INVERSE_TIME_DECIMALS);
                let f = (MICROS_PER_MINUTE * scale + u128::from(*micros) / 2) / u128::from(*micros);
                format!(
                    "N{n} G93 G1{} F{}",
                    words(&xzc.map(Some)),
                    decimal(f as i64, INVERSE_TIME_DECIMALS)
                )
            }
            Segment::Rapid { axes } => format!("N{n} G0{}", words(axes)),
            Segment::Feed { axes, milli } => {
                format!(
                    "N{n} G94 G1{} F{}",
                    words(axes),
                    decimal(i64::from(*milli), MILLI_DECIMALS)
                )
            }
            Segment::Dwell { micros } => {
                format!("N{n} G4 P{}", decimal(i64::from(*micros), MICRO_DECIMALS))
            }
            Segment::SpindleOn { milli } => {
                format!("N{n} M3 S{}", decimal(i64::from(*milli), MILLI_DECIMALS))
            }
            Segment::SpindleOff => format!("N{n} M5"),
            Segment::ProgramEnd => format!("N{n} M2"),
        }
    }
}

/// `value` × 10⁻ᵈᵉᶜⁱᵐᵃˡˢ written exactly, without trailing zeros: 125000, 4 → `12.5`.
fn decimal(value: i64, decimals: u32) -> String {
    let scale = 10u64.pow(decimals);
    let magnitude = value.unsigned_abs();
    let (int, frac) = (magnitude / scale, magnitude % scale);
    let sign = if value < 0 { "-" } else { "" };
    if frac == 0 {
        return format!("{sign}{int}");
    }
    let digits = format!("{frac:0width$}", width = decimals as usize);
    format!("{sign}{int}.{}", digits.trim_end_matches('0'))
}

/// An alarm as the status registers show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Alarm {
    code: u16,
    sequence: u32,
    detail: u16,
}

/// The line given to the controller and not yet answered.
#[derive(Debug, Clone)]
struct InFlight {
    sequence: u32,
    moves: bool,
}

/// Why the bank is bringing the machine to rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stop {
    /// A bank alarm: reset the controller once at rest.
    Alarm,
    /// `ABORT`: reset, then flush the ring.
    Abort,
}

/// The holding registers of `docs/modbus.md` in front of a simulated controller (see the
/// module docs).
#[derive(Debug)]
pub struct Bank {
    controller: Controller,
    options: BankOptions,
    ring: Vec<u16>,
    control: u16,
    head: u16,
    tail: u16,
    watchdog: u16,
    /// When the watchdog was last fed or armed, controller time, s.
    watchdog_at: f64,
    /// Published segments from TAIL on, with their sequence numbers.
    queue: VecDeque<(u32, Segment)>,
    /// The last sequence number published; `None` after a flush (any is accepted next).
    last: Option<u32>,
    in_flight: Option<InFlight>,
    /// Motion lines answered `ok`, not yet seen executed: (N word, sequence number).
    accepted: VecDeque<(u32, u32)>,
    executed: u32,
    alarm: Option<Alarm>,
    stopping: Option<Stop>,
    events: Vec<Event>,
}

impl Bank {
    /// The bank in front of `controller`, with an empty ring and the controller's power-up
    /// output dropped.
    pub fn new(mut controller: Controller, options: BankOptions) -> Result<Bank, ConfigError> {
        let bad = |name, value: u16, reason| {
            Err(ConfigError::Option {
                name,
                value: value.to_string(),
                reason,
            })
        };
        if !SLOTS.contains(&options.slots) {
            return bad("slots", options.slots, "must be 2 to 64");
        }
        if options.watchdog_timeout_ms == 0 {
            return bad("watchdog_timeout_ms", 0, "must be at least 1 ms");
        }
        if options.max_segment_rate == 0 {
            return bad("max_segment_rate", 0, "must be at least 1 segment/s");
        }
        controller.take_output();
        let watchdog_at = controller.now();
        Ok(Bank {
            controller,
            ring: vec![0; usize::from(options.slots * SLOT)],
            options,
            control: 0,
            head: 0,
            tail: 0,
            watchdog: 0,
            watchdog_at,
            queue: VecDeque::new(),
            last: None,
            in_flight: None,
            accepted: VecDeque::new(),
            executed: 0,
            alarm: None,
            stopping: None,
            events: Vec::new(),
        })
    }

    /// Answers one request.
    pub fn request(&mut self, request: &Request) -> Result<Response, Exception> {
        let answer = match request {
            Request::ReadHolding { address, count } => {
                self.read(*address, *count).map(Response::ReadHolding)
            }
            Request::WriteSingle { address, value } => {
                self.write_single(*address, *value)
                    .map(|()| Response::WriteSingle {
                        address: *address,
                        value: *value,
                    })
            }
            Request::WriteMultiple { address, values } => self
                .write_multiple(*address, values)
                .map(|()| Response::WriteMultiple {
                    address: *address,
                    count: values.len() as u16,
                }),
            Request::Other { .. } => Err(Exception::IllegalFunction),
        };
        self.pump();
        answer
    }

    /// Lets `dt` seconds of simulated time pass: the controller runs, lines are taken,
    /// the watchdog is checked (at its deadline, not after the whole interval).
    pub fn advance(&mut self, dt: f64) -> Result<(), TimeError> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(TimeError(dt));
        }
        let mut left = dt;
        loop {
            let deadline = self.watchdog_deadline();
            if deadline.is_some_and(|d| d - self.controller.now() <= 1e-9) {
                self.raise(ALARM_WATCHDOG, 0, 0);
                self.pump();
                continue;
            }
            if left <= 0.0 {
                return Ok(());
            }
            let step = deadline.map_or(left, |d| (d - self.controller.now()).min(left));
            self.controller.advance(step)?;
            left -= step;
            self.pump();
        }
    }

    /// The controller's events since the last call (lines answered, blocks executed,
    /// alarms), in order.
    pub fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// The controller behind the registers.
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    // ---- reads ----

    fn read(&self, address: u16, count: u16) -> Result<Vec<u16>, Exception> {
        if count == 0 || count > MAX_READ {
            return Err(Exception::IllegalDataValue);
        }
        let status = self.status();
        (u32::from(address)..u32::from(address) + u32::from(count))
            .map(|a| {
                let a = u16::try_from(a).map_err(|_| Exception::IllegalDataAddress)?;
                self.register(a, &status)
                    .ok_or(Exception::IllegalDataAddress)
            })
            .collect()
    }

    /// One register's value; `None` if unmapped.
    fn register(&self, address: u16, status: &[u16; STATUS_LEN]) -> Option<u16> {
        let o = &self.options;
        Some(match address {
            MAGIC_0 => MAGIC[0],
            MAGIC_1 => MAGIC[1],
            MAP_VERSION => VERSION,
            SLOT_COUNT => o.slots,
            SLOT_SIZE => SLOT,
            WORD_ORDER => o.word_order.register(),
            MAX_SEGMENT_RATE => o.max_segment_rate,
            WATCHDOG_TIMEOUT => o.watchdog_timeout_ms,
            STATE..CONTROL => status[usize::from(address - STATE)],
            CONTROL => self.control,
            HEAD => self.head,
            WATCHDOG => self.watchdog,
            FEED_OVERRIDE if o.feed_override => u16::from(self.controller.feed_override()),
            a if self.in_ring(a) => self.ring[usize::from(a - RING)],
            _ => return None,
        })
    }

    /// Registers `STATE..CONTROL` (16–31).
    fn status(&self) -> [u16; STATUS_LEN] {
        let order = self.options.word_order;
        let alarm = self.alarm.unwrap_or(Alarm {
            code: 0,
            sequence: 0,
            detail: 0,
        });
        let position = self.controller.position();
        let units = |value: f64, decimals: u32| (value * 10f64.powi(decimals as i32)).round();
        let linear = |mm: f64| u64::from(units(mm, LINEAR_DECIMALS) as i32 as u32);
        let mut r = [0u16; STATUS_LEN];
        let mut put = |register: u16, words: &[u16]| {
            let at = usize::from(register - STATE);
            r[at..at + words.len()].copy_from_slice(words);
        };
        put(STATE, &[self.state()]);
        put(ALARM_CODE, &[alarm.code]);
        put(ALARM_SEQ, &order.place::<2>(u64::from(alarm.sequence)));
        put(ALARM_DETAIL, &[alarm.detail]);
        put(TAIL, &[self.tail]);
        put(EXECUTED_SEQ, &order.place::<2>(u64::from(self.executed)));
        put(POS_X, &order.place::<2>(linear(position.x)));
        put(POS_Z, &order.place::<2>(linear(position.z)));
        let c = units(position.c, ANGULAR_DECIMALS) as i64 as u64;
        put(POS_C, &order.place::<4>(c));
        r
    }

    fn state(&self) -> u16 {
        let machine = self.controller.state();
        if self.alarm.is_some() || machine == MachineState::Alarm {
            return ALARM;
        }
        match machine {
            MachineState::Hold { .. } => HELD,
            MachineState::Run => RUNNING,
            _ if self.control & RUN != 0 && !self.queue.is_empty() => RUNNING,
            _ if self.control & END != 0 && self.queue.is_empty() => DONE,
            _ => IDLE,
        }
    }

    // ---- writes ----

    fn in_ring(&self, address: u16) -> bool {
        address >= RING && address - RING < self.options.slots * SLOT
    }

    /// Whether slot `slot` is published (between TAIL and HEAD).
    fn published(&self, slot: u16) -> bool {
        let n = self.options.slots;
        (slot + n - self.tail) % n < (self.head + n - self.tail) % n
    }

    /// Ring registers from `address` on: refused 06 if they would change a published slot.
    fn check_ring_write(&self, address: u16, values: &[u16]) -> Result<(), Exception> {
        for (k, &value) in values.iter().enumerate() {
            let offset = address - RING + k as u16;
            if self.published(offset / SLOT) && self.ring[usize::from(offset)] != value {
                return Err(Exception::ServerDeviceBusy);
            }
        }
        Ok(())
    }

    fn write_multiple(&mut self, address: u16, values: &[u16]) -> Result<(), Exception> {
        if values.is_empty() || values.len() > MAX_WRITE {
            return Err(Exception::IllegalDataValue);
        }
        let last = u32::from(address) + values.len() as u32 - 1;
        let writable = |a: u32| u16::try_from(a).is_ok_and(|a| self.in_ring(a));
        if !(writable(u32::from(address)) && writable(last)) {
            return Err(Exception::IllegalDataAddress);
        }
        self.check_ring_write(address, values)?;
        let at = usize::from(address - RING);
        self.ring[at..at + values.len()].copy_from_slice(values);
        Ok(())
    }

    fn write_single(&mut self, address: u16, value: u16) -> Result<(), Exception> {
        match address {
            CONTROL => self.write_control(value),
            HEAD => self.write_head(value),
            WATCHDOG => {
                if value != self.watchdog {
                    self.watchdog = value;
                    self.watchdog_at = self.controller.now();
                }
                Ok(())
            }
            FEED_OVERRIDE if self.options.feed_override => {
                if !FEED_OVERRIDE_RANGE.contains(&value) {
                    return Err(Exception::IllegalDataValue);
                }
                // Within 10..=200: fits a u8.
                self.controller.set_feed_override(value as u8);
                Ok(())
            }
            a if self.in_ring(a) => {
                self.check_ring_write(a, &[value])?;
                self.ring[usize::from(a - RING)] = value;
                Ok(())
            }
            _ => Err(Exception::IllegalDataAddress),
        }
    }

    fn write_control(&mut self, value: u16) -> Result<(), Exception> {
        if value & !(RUN | HOLD | RESUME | RESET_ALARM | ABORT | END) != 0 {
            return Err(Exception::IllegalDataValue);
        }
        let rising = value & !self.control;
        if rising & RESET_ALARM != 0 && self.alarm.is_some() && self.stopping.is_some() {
            return Err(Exception::ServerDeviceBusy);
        }
        let armed = self.armed();
        self.control = value;
        if rising & ABORT != 0 {
            self.stop(Stop::Abort);
        }
        if rising & RESET_ALARM != 0 && self.alarm.is_some() {
            self.controller.receive(&[0x18]);
            self.controller.receive(b"$X\n");
            self.alarm = None;
            self.flush();
        }
        if rising & HOLD != 0 {
            self.controller.receive(b"!");
        }
        if rising & RESUME != 0 && self.alarm.is_none() && self.stopping.is_none() {
            self.controller.receive(b"~");
        }
        // Armed by RUN, by END cleared, or by the alarm cleared: the timer starts now.
        if self.armed() && !armed {
            self.watchdog_at = self.controller.now();
        }
        Ok(())
    }

    fn write_head(&mut self, value: u16) -> Result<(), Exception> {
        let n = self.options.slots;
        if value >= n {
            return Err(Exception::IllegalDataValue);
        }
        if value == self.head {
            return Ok(());
        }
        if self.alarm.is_some() {
            return Err(Exception::ServerDeviceFailure);
        }
        if self.stopping.is_some() {
            return Err(Exception::ServerDeviceBusy);
        }
        let count = (value + n - self.head) % n;
        let free = n - 1 - (self.head + n - self.tail) % n;
        if count > free {
            return Err(Exception::IllegalDataValue);
        }
        let order = self.options.word_order;
        let mut last = self.last;
        let mut accepted = Vec::new();
        for k in 0..count {
            let at = usize::from((self.head + k) % n * SLOT);
            let slot = &self.ring[at..at + usize::from(SLOT)];
            let expected = last.map(|s| s.checked_add(1).unwrap_or(1));
            let bytes: Vec<u8> = slot[..SLOT_CRC]
                .iter()
                .flat_map(|r| r.to_be_bytes())
                .collect();
            if crc16(&bytes) != slot[SLOT_CRC] {
                return Err(self.refuse(ALARM_CRC, expected));
            }
            let sequence = order.value(&slot[SLOT_SEQ..SLOT_SEQ + 2]) as u32;
            if sequence == 0 || expected.is_some_and(|e| e != sequence) {
                return Err(self.refuse(ALARM_SEQUENCE, expected));
            }
            let Some(segment) = Segment::parse(slot, order) else {
                return Err(self.refuse(ALARM_SEGMENT, Some(sequence)));
            };
            accepted.push((sequence, segment));
            last = Some(sequence);
        }
        self.queue.extend(accepted);
        self.last = last;
        self.head = value;
        Ok(())
    }

    /// A slot refused at publication: its alarm, and 04 for the HEAD write.
    fn refuse(&mut self, code: u16, expected: Option<u32>) -> Exception {
        self.raise(code, expected.unwrap_or(0), 0);
        Exception::ServerDeviceFailure
    }

    // ---- the machine ----

    fn armed(&self) -> bool {
        self.control & RUN != 0 && self.control & END == 0 && self.alarm.is_none()
    }

    fn watchdog_deadline(&self) -> Option<f64> {
        self.armed()
            .then(|| self.watchdog_at + f64::from(self.options.watchdog_timeout_ms) / 1000.0)
    }

    fn at_rest(&self) -> bool {
        !matches!(
            self.controller.state(),
            MachineState::Run | MachineState::Hold { complete: false }
        )
    }

    /// A bank alarm (the first one stands): stop the machine, freeze the ring.
    fn raise(&mut self, code: u16, sequence: u32, detail: u16) {
        if self.alarm.is_some() {
            return;
        }
        self.alarm = Some(Alarm {
            code,
            sequence,
            detail,
        });
        self.stop(Stop::Alarm);
    }

    /// A feed hold, and once at rest a soft reset (see [`Bank::pump`]); an abort stop
    /// overrides an alarm stop, since it also flushes.
    fn stop(&mut self, kind: Stop) {
        if !self.at_rest() {
            self.controller.receive(b"!");
        }
        if self.stopping != Some(Stop::Abort) {
            self.stopping = Some(kind);
        }
    }

    /// The machine is at rest: soft reset (the controller's RX, line and queue dropped),
    /// and for an abort, the flush.
    fn finish_stop(&mut self, kind: Stop) {
        self.stopping = None;
        self.controller.receive(&[0x18]);
        self.in_flight = None;
        self.accepted.clear();
        if kind == Stop::Abort {
            self.flush();
        }
    }

    fn flush(&mut self) {
        self.head = 0;
        self.tail = 0;
        self.queue.clear();
        self.last = None;
        self.in_flight = None;
        self.accepted.clear();
        self.executed = 0;
    }

    /// Reads the controller's events, finishes a stop at rest, and gives the controller
    /// lines while it can take them.
    fn pump(&mut self) {
        loop {
            self.collect();
            if let Some(kind) = self.stopping {
                if self.at_rest() {
                    self.finish_stop(kind);
                    continue;
                }
                break;
            }
            if self.alarm.is_some() || self.in_flight.is_some() || self.control & RUN == 0 {
                break;
            }
            let Some(&(sequence, segment)) = self.queue.front() else {
                break;
            };
            let text = segment.line(sequence % LINE_NUMBERS);
            self.controller.receive(format!("{text}\n").as_bytes());
            self.in_flight = Some(InFlight {
                sequence,
                moves: segment.moves(),
            });
        }
        let idle = self.controller.state() == MachineState::Idle
            && self.controller.blocks_free() == self.controller.options().planner_blocks;
        if idle && self.in_flight.is_none() {
            if let Some(&(_, sequence)) = self.accepted.back() {
                self.executed = sequence;
            }
            self.accepted.clear();
        }
        self.controller.take_output();
    }

    fn collect(&mut self) {
        for event in self.controller.take_events() {
            match &event {
                // One line at a time, each answered once and in order: an answer while a
                // slot's line is in flight is its answer (its text may be cut short, as
                // for error:11). The only other line sent, `$X`, follows a reset, with
                // nothing in flight.
                Event::Line { error, .. } if self.in_flight.is_some() => {
                    let line = self.in_flight.take().expect("checked");
                    match error {
                        // Queued during an alarm stop, and about to be purged by its reset:
                        // not taken, TAIL stays on it.
                        None if self.alarm.is_some() => {}
                        None => self.taken(line),
                        Some(e) => self.refused(line.sequence, u16::from(e.code())),
                    }
                }
                Event::Executed(block) if block.completed => {
                    if let Some(n) = block.n {
                        while let Some((k, sequence)) = self.accepted.pop_front() {
                            if k == n {
                                self.executed = sequence;
                                break;
                            }
                        }
                    }
                }
                Event::Alarm { alarm, .. } => {
                    self.alarm.get_or_insert(Alarm {
                        code: u16::from(alarm.code()),
                        sequence: 0,
                        detail: 0,
                    });
                }
                _ => {}
            }
            self.events.push(event);
        }
    }

    /// The controller answered a slot's line `ok`: TAIL moves past it.
    fn taken(&mut self, line: InFlight) {
        self.queue.pop_front();
        self.tail = (self.tail + 1) % self.options.slots;
        if line.moves {
            self.accepted
                .push_back((line.sequence % LINE_NUMBERS, line.sequence));
        } else {
            // Answered once done, after everything before it.
            self.executed = line.sequence;
            self.accepted.clear();
        }
    }

    /// The controller refused a slot's line: the alarm it raised names the segment, or the
    /// bank raises 105.
    fn refused(&mut self, sequence: u32, error: u16) {
        match &mut self.alarm {
            Some(alarm) if alarm.sequence == 0 => {
                alarm.sequence = sequence;
                alarm.detail = error;
            }
            Some(_) => {}
            None => self.raise(ALARM_REFUSED, sequence, error),
        }
    }
}

#[cfg(test)]
mod tests;
