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

// Addresses (docs/modbus.md, "Address map").
const STATUS: u16 = 16;
const CONTROL: u16 = 32;
const HEAD: u16 = 33;
const WATCHDOG: u16 = 34;
const RING: u16 = 256;
const SLOT: u16 = 16;

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
        let kind = slot[2] & 0x00FF;
        let flags = slot[2] >> 8;
        if slot[3] != 0 || slot[14] != 0 || flags & !0b111 != 0 {
            return None;
        }
        let x = order.value(&slot[4..6]) as u32 as i32;
        let z = order.value(&slot[6..8]) as u32 as i32;
        let c = order.value(&slot[8..12]) as i64;
        let param = order.value(&slot[12..14]) as u32;
        let values = [i64::from(x), i64::from(z), c];
        let mut axes = [None; 3];
        for (k, axis) in axes.iter_mut().enumerate() {
            if flags & (1 << k) != 0 {
                *axis = Some(values[k]);
            } else if values[k] != 0 {
                return None;
            }
        }
        let no_axes = flags == 0;
        let segment = match kind {
            1 if flags == 0b111 && param >= 1 => Segment::Linked {
                xzc: values,
                micros: param,
            },
            2 if param == 0 => Segment::Rapid { axes },
            3 if param >= 1 => Segment::Feed { axes, milli: param },
            4 if no_axes => Segment::Dwell { micros: param },
            5 if no_axes => Segment::SpindleOn { milli: param },
            6 if no_axes && param == 0 => Segment::SpindleOff,
            7 if no_axes && param == 0 => Segment::ProgramEnd,
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
            axes.iter()
                .zip(['X', 'Z', 'C'])
                .filter_map(|(v, letter)| v.map(|v| format!(" {letter}{}", decimal(v, 4))))
                .collect()
        };
        match self {
            Segment::Linked { xzc, micros } => {
                // F = 1 / minutes = 60 000 000 / µs, to 10⁻⁶.
                let f =
                    (60_000_000u128 * 1_000_000 + u128::from(*micros) / 2) / u128::from(*micros);
                format!(
                    "N{n} G93 G1{} F{}",
                    words(&xzc.map(Some)),
                    decimal(f as i64, 6)
                )
            }
            Segment::Rapid { axes } => format!("N{n} G0{}", words(axes)),
            Segment::Feed { axes, milli } => {
                format!(
                    "N{n} G94 G1{} F{}",
                    words(axes),
                    decimal(i64::from(*milli), 3)
                )
            }
            Segment::Dwell { micros } => format!("N{n} G4 P{}", decimal(i64::from(*micros), 6)),
            Segment::SpindleOn { milli } => format!("N{n} M3 S{}", decimal(i64::from(*milli), 3)),
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
        if !(2..=64).contains(&options.slots) {
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
        if count == 0 || count > 125 {
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
    fn register(&self, address: u16, status: &[u16; 16]) -> Option<u16> {
        let o = &self.options;
        Some(match address {
            0 => 0x5748,
            1 => 0x524C,
            2 => 1,
            3 => o.slots,
            4 => SLOT,
            5 => match o.word_order {
                WordOrder::HighFirst => 0,
                WordOrder::LowFirst => 1,
            },
            6 => o.max_segment_rate,
            7 => o.watchdog_timeout_ms,
            STATUS..CONTROL => status[usize::from(address - STATUS)],
            CONTROL => self.control,
            HEAD => self.head,
            WATCHDOG => self.watchdog,
            a if self.in_ring(a) => self.ring[usize::from(a - RING)],
            _ => return None,
        })
    }

    /// Registers 16–31.
    fn status(&self) -> [u16; 16] {
        let order = self.options.word_order;
        let alarm = self.alarm.unwrap_or(Alarm {
            code: 0,
            sequence: 0,
            detail: 0,
        });
        let position = self.controller.position();
        let linear = |mm: f64| u64::from((mm * 1e4).round() as i32 as u32);
        let mut r = [0u16; 16];
        r[0] = self.state();
        r[1] = alarm.code;
        r[2..4].copy_from_slice(&order.place::<2>(u64::from(alarm.sequence)));
        r[4] = alarm.detail;
        r[5] = self.tail;
        r[6..8].copy_from_slice(&order.place::<2>(u64::from(self.executed)));
        r[8..10].copy_from_slice(&order.place::<2>(linear(position.x)));
        r[10..12].copy_from_slice(&order.place::<2>(linear(position.z)));
        r[12..16].copy_from_slice(&order.place::<4>((position.c * 1e4).round() as i64 as u64));
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
        if values.is_empty() || values.len() > 123 {
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
            let bytes: Vec<u8> = slot[..15].iter().flat_map(|r| r.to_be_bytes()).collect();
            if crc16(&bytes) != slot[15] {
                return Err(self.refuse(ALARM_CRC, expected));
            }
            let sequence = order.value(&slot[0..2]) as u32;
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
mod tests {
    use super::*;
    use crate::error::{Alarm as GrblAlarm, GrblError};
    use crate::guard::{Breach, Guard, Measured};
    use crate::machine::{Axis, Machine, Number};
    use crate::record::ExecutedBlock;
    use crate::ControllerOptions;

    /// X 0–100 mm, Z ±200 mm at 3000 mm/min and 500 mm/s², C unlimited at 72 000 °/min
    /// and 7200 °/s², 64-bit numbers.
    fn machine() -> Machine {
        let linear = |min, max| Axis {
            min: Some(min),
            max: Some(max),
            max_rate: 3000.0,
            accel: 500.0,
        };
        Machine {
            x: linear(0.0, 100.0),
            z: linear(-200.0, 200.0),
            c: Axis {
                min: None,
                max: None,
                max_rate: 72_000.0,
                accel: 7200.0,
            },
            number: Number::F64,
            max_line_length: 256,
            spindle_rpm: None,
        }
    }

    fn bank_on(machine: &Machine, options: BankOptions) -> Bank {
        let controller = Controller::new(machine, ControllerOptions::default()).unwrap();
        Bank::new(controller, options).unwrap()
    }

    fn bank(slots: u16) -> Bank {
        bank_on(
            &machine(),
            BankOptions {
                slots,
                ..BankOptions::default()
            },
        )
    }

    /// A slot as docs/modbus.md lays it out, written here word by word: SEQ, KIND, 0,
    /// X (i32), Z (i32), C (i64), PARAM, 0, CRC over registers 0–14 high byte first.
    fn slot(sequence: u32, kind: u16, xzc: [i64; 3], param: u32, low_first: bool) -> [u16; 16] {
        let words = |value: u64, n: usize| -> Vec<u16> {
            let mut w: Vec<u16> = (0..n).rev().map(|k| (value >> (16 * k)) as u16).collect();
            if low_first {
                w.reverse();
            }
            w
        };
        let mut r = Vec::new();
        r.extend(words(u64::from(sequence), 2));
        r.extend([kind, 0]);
        r.extend(words(u64::from(xzc[0] as i32 as u32), 2));
        r.extend(words(u64::from(xzc[1] as i32 as u32), 2));
        r.extend(words(xzc[2] as u64, 4));
        r.extend(words(u64::from(param), 2));
        r.push(0);
        let bytes: Vec<u8> = r.iter().flat_map(|w| [(w >> 8) as u8, *w as u8]).collect();
        r.push(crc16(&bytes));
        r.try_into().unwrap()
    }

    /// A linked move (kind 1, flags X Z C = 0x0701), mm, mm, degrees, seconds.
    fn linked(sequence: u32, x: f64, z: f64, c: f64, seconds: f64) -> [u16; 16] {
        let units = |v: f64| (v * 1e4).round() as i64;
        let micros = (seconds * 1e6).round() as u32;
        slot(
            sequence,
            0x0701,
            [units(x), units(z), units(c)],
            micros,
            false,
        )
    }

    fn read(bank: &mut Bank, address: u16, count: u16) -> Result<Vec<u16>, Exception> {
        match bank.request(&Request::ReadHolding { address, count })? {
            Response::ReadHolding(values) => Ok(values),
            other => panic!("a read answered {other:?}"),
        }
    }

    fn reg(bank: &mut Bank, address: u16) -> u16 {
        read(bank, address, 1).unwrap()[0]
    }

    fn write(bank: &mut Bank, address: u16, value: u16) -> Result<Response, Exception> {
        bank.request(&Request::WriteSingle { address, value })
    }

    fn write_slot(bank: &mut Bank, index: u16, values: &[u16]) -> Result<Response, Exception> {
        bank.request(&Request::WriteMultiple {
            address: 256 + 16 * index,
            values: values.to_vec(),
        })
    }

    /// Writes `slots` from HEAD on, then moves HEAD past them; the HEAD write's answer.
    fn publish(bank: &mut Bank, slots: &[[u16; 16]]) -> Result<Response, Exception> {
        let n = reg(bank, 3);
        let mut head = reg(bank, 33);
        for s in slots {
            write_slot(bank, head, s).unwrap();
            head = (head + 1) % n;
        }
        write(bank, 33, head)
    }

    /// STATE, ALARM_CODE, ALARM_SEQ (high word first), ALARM_DETAIL.
    fn alarm(bank: &mut Bank) -> (u16, u16, u32, u16) {
        let r = read(bank, 16, 5).unwrap();
        (r[0], r[1], (u32::from(r[2]) << 16) | u32::from(r[3]), r[4])
    }

    /// (TAIL, HEAD, EXECUTED_SEQ).
    fn ring(bank: &mut Bank) -> (u16, u16, u32) {
        let r = read(bank, 21, 3).unwrap();
        (
            r[0],
            reg(bank, 33),
            (u32::from(r[1]) << 16) | u32::from(r[2]),
        )
    }

    fn lines(events: &[Event]) -> Vec<(String, Option<GrblError>)> {
        events
            .iter()
            .filter_map(|e| match e {
                Event::Line { text, error, .. } => Some((text.clone(), *error)),
                _ => None,
            })
            .collect()
    }

    fn executed(events: &[Event]) -> Vec<u32> {
        events
            .iter()
            .filter_map(|e| match e {
                Event::Executed(b) if b.completed => b.n,
                _ => None,
            })
            .collect()
    }

    /// Advances in 10 ms steps until `done` or `seconds` have passed; the events.
    fn run(bank: &mut Bank, seconds: f64, done: impl Fn(&mut Bank) -> bool) -> Vec<Event> {
        let mut events = bank.take_events();
        let mut t = 0.0;
        while t < seconds && !done(bank) {
            bank.advance(0.01).unwrap();
            events.extend(bank.take_events());
            t += 0.01;
        }
        events
    }

    fn state(bank: &mut Bank) -> u16 {
        reg(bank, 16)
    }

    #[test]
    fn identification_block() {
        let mut b = bank(4);
        assert_eq!(
            read(&mut b, 0, 8),
            Ok(vec![0x5748, 0x524C, 1, 4, 16, 0, 1000, 1000])
        );
        // "WHRL".
        assert_eq!([0x57, 0x48, 0x52, 0x4C], *b"WHRL");
        let mut low = bank_on(
            &machine(),
            BankOptions {
                word_order: WordOrder::LowFirst,
                max_segment_rate: 250,
                watchdog_timeout_ms: 200,
                ..BankOptions::default()
            },
        );
        assert_eq!(read(&mut low, 3, 5), Ok(vec![32, 16, 1, 250, 200]));
        // Power-up: idle, no alarm, empty ring, nothing executed, at the origin.
        assert_eq!(read(&mut b, 16, 19), Ok(vec![0; 19]));
    }

    #[test]
    fn slots_run_as_the_g_code_they_stand_for() {
        let mut b = bank(8);
        let units = |v: f64| (v * 1e4).round() as i64;
        let slots = [
            // Rapid X10 Z0 C0 (flags X Z C).
            slot(1, 0x0702, [units(10.0), 0, 0], 0, false),
            // Spindle on at 2500.5 rpm.
            slot(2, 5, [0; 3], 2_500_500, false),
            // Feed X alone to 9.5 mm at 100 mm/min.
            slot(3, 0x0103, [units(9.5), 0, 0], 100_000, false),
            // Linked to X 9.5, Z 1, C 360 in 0.5 s: F = 1 / (0.5 / 60) = 120.
            linked(4, 9.5, 1.0, 360.0, 0.5),
            // Dwell 0.25 s, spindle off, program end.
            slot(5, 4, [0; 3], 250_000, false),
            slot(6, 6, [0; 3], 0, false),
            slot(7, 7, [0; 3], 0, false),
        ];
        assert!(publish(&mut b, &slots).is_ok());
        // RUN clear: published, waiting.
        assert_eq!(ring(&mut b), (0, 7, 0));
        assert_eq!(state(&mut b), 0);
        write(&mut b, 32, 1 | 32).unwrap();
        assert_eq!(state(&mut b), 1);
        let events = run(&mut b, 30.0, |b| state(b) == 4);
        let expected = [
            "N1 G0 X10 Z0 C0",
            "N2 M3 S2500.5",
            "N3 G94 G1 X9.5 F100",
            "N4 G93 G1 X9.5 Z1 C360 F120",
            "N5 G4 P0.25",
            "N6 M5",
            "N7 M2",
        ];
        let got = lines(&events);
        assert_eq!(
            got,
            expected.map(|t| (t.to_owned(), None)).to_vec(),
            "every slot one line, answered ok"
        );
        assert_eq!(executed(&events), vec![1, 3, 4]);
        // Done: TAIL caught up with HEAD, everything executed, at X 9.5, Z 1, C 360
        // (95 000 = 0x00017318, 10 000, 3 600 000 = 0x0036EE80).
        assert_eq!(ring(&mut b), (7, 7, 7));
        assert_eq!(
            read(&mut b, 24, 8),
            Ok(vec![0x0001, 0x7318, 0, 10_000, 0, 0, 0x0036, 0xEE80])
        );
    }

    #[test]
    fn c_near_700_000_degrees() {
        for low_first in [false, true] {
            let mut b = bank_on(
                &machine(),
                BankOptions {
                    word_order: if low_first {
                        WordOrder::LowFirst
                    } else {
                        WordOrder::HighFirst
                    },
                    ..BankOptions::default()
                },
            );
            // A rapid of C alone (flag C, 0x0402) to 700 000.1234° = 7 000 001 234 units.
            let s = slot(1, 0x0402, [0, 0, 7_000_001_234], 0, low_first);
            assert!(publish(&mut b, &[s]).is_ok());
            write(&mut b, 32, 1 | 32).unwrap();
            let events = run(&mut b, 1000.0, |b| state(b) == 4);
            // The line carries every digit; grblHAL's read_float keeps 9 significant ones,
            // so the controller goes to 700 000.123° = 7 000 001 230 units; 7 000 001 230 −
            // 2³² = 2 705 033 934 = 0xA13B·65 536 + 0x8ACE: 0x0000 0x0001 0xA13B 0x8ACE.
            assert_eq!(lines(&events)[0].0, "N1 G0 C700000.1234");
            let c = read(&mut b, 28, 4).unwrap();
            let high = [0x0000, 0x0001, 0xA13B, 0x8ACE];
            if low_first {
                assert_eq!(c, high.iter().rev().copied().collect::<Vec<_>>());
            } else {
                assert_eq!(c, high);
            }
        }
    }

    #[test]
    fn the_ring_fills_empties_and_wraps() {
        let mut b = bank(4);
        let moves: Vec<[u16; 16]> = (1..=6)
            .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.1))
            .collect();
        // Empty: HEAD = TAIL = 0. Three slots fill a ring of four.
        assert_eq!(ring(&mut b), (0, 0, 0));
        assert!(publish(&mut b, &moves[0..3]).is_ok());
        assert_eq!(ring(&mut b), (0, 3, 0));
        // Full ((3 + 1) mod 4 = TAIL 0): a fourth is refused, 03, and HEAD stays.
        write_slot(&mut b, 3, &moves[3]).unwrap();
        assert_eq!(write(&mut b, 33, 0), Err(Exception::IllegalDataValue));
        // Backwards is as far beyond the free slots.
        assert_eq!(write(&mut b, 33, 1), Err(Exception::IllegalDataValue));
        // The same value again publishes nothing and is answered.
        assert!(write(&mut b, 33, 3).is_ok());
        assert_eq!(ring(&mut b), (0, 3, 0));
        // RUN: the planner takes all three at once, TAIL catches up: empty again.
        write(&mut b, 32, 1).unwrap();
        assert_eq!(ring(&mut b).0, 3);
        // Three more go to slots 3, 0, 1: HEAD wraps to 2.
        assert!(publish(&mut b, &moves[3..6]).is_ok());
        assert_eq!(ring(&mut b).1, 2);
        write(&mut b, 32, 1 | 32).unwrap();
        let events = run(&mut b, 30.0, |b| state(b) == 4);
        assert_eq!(executed(&events), vec![1, 2, 3, 4, 5, 6]);
        assert_eq!(ring(&mut b), (2, 2, 6));
    }

    #[test]
    fn executed_trails_tail() {
        let mut b = bank(8);
        let moves: Vec<[u16; 16]> = (1..=3)
            .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.5))
            .collect();
        publish(&mut b, &moves).unwrap();
        write(&mut b, 32, 1 | 32).unwrap();
        // Taken into the planner at once, executed over 1.5 s and more.
        assert_eq!(ring(&mut b), (3, 3, 0));
        b.advance(0.25).unwrap();
        assert_eq!(ring(&mut b), (3, 3, 0));
        assert_eq!(state(&mut b), 1);
        run(&mut b, 10.0, |b| state(b) == 4);
        assert_eq!(ring(&mut b), (3, 3, 3));
    }

    #[test]
    fn a_slot_written_twice_runs_once() {
        let mut b = bank(4);
        let s = linked(1, 5.0, 1.0, 90.0, 0.2);
        // Written, its answer "lost", written again: the same slot.
        assert!(write_slot(&mut b, 0, &s).is_ok());
        assert!(write_slot(&mut b, 0, &s).is_ok());
        assert!(write(&mut b, 33, 1).is_ok());
        // A copy arriving after publication changes nothing and is accepted, as is HEAD
        // written again; a write that would change the published slot is refused, 06.
        assert!(write_slot(&mut b, 0, &s).is_ok());
        assert!(write(&mut b, 256 + 4, s[4]).is_ok());
        assert!(write(&mut b, 33, 1).is_ok());
        let mut other = s;
        other[5] ^= 1;
        assert_eq!(
            write_slot(&mut b, 0, &other),
            Err(Exception::ServerDeviceBusy)
        );
        assert_eq!(
            write(&mut b, 256 + 5, other[5]),
            Err(Exception::ServerDeviceBusy)
        );
        // A refused FC16 writes nothing, not even its part in the free slot 1 after it.
        let mut spanning = s[8..].to_vec();
        spanning[0] ^= 1;
        spanning.extend([7; 4]);
        assert_eq!(
            b.request(&Request::WriteMultiple {
                address: 256 + 8,
                values: spanning
            }),
            Err(Exception::ServerDeviceBusy)
        );
        assert_eq!(read(&mut b, 256 + 16, 4), Ok(vec![0; 4]));
        write(&mut b, 32, 1 | 32).unwrap();
        let events = run(&mut b, 10.0, |b| state(b) == 4);
        assert_eq!(executed(&events), vec![1]);
        assert_eq!(lines(&events).len(), 1);
        assert_eq!(ring(&mut b), (1, 1, 1));
    }

    #[test]
    fn a_bad_crc_raises_alarm_101() {
        let mut b = bank(4);
        let mut s = linked(1, 5.0, 0.0, 0.0, 0.1);
        s[15] ^= 1;
        // First after a flush: no sequence number expected yet, ALARM_SEQ 0.
        assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
        assert_eq!(alarm(&mut b), (3, 101, 0, 0));
        assert_eq!(ring(&mut b), (0, 0, 0));
        // With 1 published, a bad slot 2 names sequence 2.
        let mut b = bank(4);
        publish(&mut b, &[linked(1, 5.0, 0.0, 0.0, 0.1)]).unwrap();
        let mut s = linked(2, 5.0, 1.0, 0.0, 0.1);
        s[6] ^= 0x0100;
        assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
        assert_eq!(alarm(&mut b), (3, 101, 2, 0));
        // An all-zero slot (never written) fails the CRC too.
        let mut b = bank(4);
        assert_eq!(write(&mut b, 33, 1), Err(Exception::ServerDeviceFailure));
        assert_eq!(alarm(&mut b).1, 101);
        // In alarm, HEAD cannot move (04) but may be written as it is.
        assert_eq!(write(&mut b, 33, 2), Err(Exception::ServerDeviceFailure));
        assert!(write(&mut b, 33, 0).is_ok());
    }

    #[test]
    fn sequence_numbers_out_of_order_raise_alarm_102() {
        let case = |sequences: &[u32]| {
            let mut b = bank(8);
            let slots: Vec<[u16; 16]> = sequences
                .iter()
                .map(|&s| linked(s, 5.0, 0.0, 0.0, 0.1))
                .collect();
            let (good, last) = slots.split_at(slots.len() - 1);
            if !good.is_empty() {
                publish(&mut b, good).unwrap();
            }
            assert_eq!(publish(&mut b, last), Err(Exception::ServerDeviceFailure));
            (alarm(&mut b), reg(&mut b, 33))
        };
        // Skipped: 2 expected after 1.
        assert_eq!(case(&[1, 3]), ((3, 102, 2, 0), 1));
        // Repeated.
        assert_eq!(case(&[1, 1]), ((3, 102, 2, 0), 1));
        // 0 is never a sequence number.
        assert_eq!(case(&[0]), ((3, 102, 0, 0), 0));
        // Wrapping: after 4 294 967 295 comes 1, not 0.
        assert_eq!(case(&[u32::MAX, 0]), ((3, 102, 1, 0), 1));
        let mut b = bank(8);
        let wrap = [
            linked(u32::MAX, 5.0, 0.0, 0.0, 0.1),
            linked(1, 5.0, 1.0, 0.0, 0.1),
        ];
        assert!(publish(&mut b, &wrap).is_ok());
        // Two slots in one HEAD write, the second bad: neither is published.
        let mut b = bank(8);
        write_slot(&mut b, 0, &linked(1, 5.0, 0.0, 0.0, 0.1)).unwrap();
        write_slot(&mut b, 1, &linked(3, 5.0, 0.0, 0.0, 0.1)).unwrap();
        assert_eq!(write(&mut b, 33, 2), Err(Exception::ServerDeviceFailure));
        assert_eq!(ring(&mut b), (0, 0, 0));
        assert_eq!(alarm(&mut b), (3, 102, 2, 0));
    }

    #[test]
    fn invalid_segments_raise_alarm_103() {
        let bad = [
            // Unknown kind.
            slot(1, 9, [0; 3], 0, false),
            slot(1, 0, [0; 3], 0, false),
            // A linked move without its C flag, or lasting 0 µs.
            slot(1, 0x0301, [1, 1, 0], 1000, false),
            slot(1, 0x0701, [1, 1, 1], 0, false),
            // A rapid with a PARAM; an axis holding a value without its flag.
            slot(1, 0x0102, [1, 0, 0], 5, false),
            slot(1, 0x0102, [1, 5, 0], 0, false),
            // A feed of 0.
            slot(1, 0x0103, [1, 0, 0], 0, false),
            // A dwell, spindle off or program end with axes or a PARAM.
            slot(1, 0x0104, [1, 0, 0], 0, false),
            slot(1, 0x0105, [1, 0, 0], 10, false),
            slot(1, 6, [0; 3], 1, false),
            slot(1, 7, [0; 3], 1, false),
            // A flag bit the map does not define.
            slot(1, 0x0802, [0; 3], 0, false),
        ];
        for s in bad {
            let mut b = bank(4);
            assert_eq!(
                publish(&mut b, &[s]),
                Err(Exception::ServerDeviceFailure),
                "{s:04x?}"
            );
            assert_eq!(alarm(&mut b), (3, 103, 1, 0), "{s:04x?}");
        }
        // The reserved registers 3 and 14 must be 0 (the CRC recomputed to match).
        for reserved in [3, 14] {
            let mut s = slot(1, 6, [0; 3], 0, false);
            s[reserved] = 1;
            let bytes: Vec<u8> = s[..15].iter().flat_map(|w| w.to_be_bytes()).collect();
            s[15] = crc16(&bytes);
            let mut b = bank(4);
            assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
            assert_eq!(alarm(&mut b).1, 103);
        }
    }

    #[test]
    fn exception_codes_for_every_bad_request() {
        let mut b = bank(4);
        let request = |b: &mut Bank, r: Request| b.request(&r).err();
        let read_req = |address, count| Request::ReadHolding { address, count };
        let multi = |address, n: usize| Request::WriteMultiple {
            address,
            values: vec![0; n],
        };
        use Exception::*;
        let cases = [
            // 01: not 03, 06 or 16.
            (Request::Other { function: 4 }, IllegalFunction),
            // 03: Modbus's quantities.
            (read_req(0, 0), IllegalDataValue),
            (read_req(0, 126), IllegalDataValue),
            (multi(256, 0), IllegalDataValue),
            (multi(256, 124), IllegalDataValue),
            // 02: unmapped registers, alone or inside a range.
            (read_req(8, 1), IllegalDataAddress),
            (read_req(0, 9), IllegalDataAddress),
            (read_req(30, 6), IllegalDataAddress),
            (read_req(255, 2), IllegalDataAddress),
            (read_req(256 + 64, 1), IllegalDataAddress),
            (read_req(65535, 2), IllegalDataAddress),
            // 02: read-only and unmapped registers written.
            (
                Request::WriteSingle {
                    address: 0,
                    value: 1,
                },
                IllegalDataAddress,
            ),
            (
                Request::WriteSingle {
                    address: 21,
                    value: 1,
                },
                IllegalDataAddress,
            ),
            (
                Request::WriteSingle {
                    address: 100,
                    value: 1,
                },
                IllegalDataAddress,
            ),
            (
                Request::WriteSingle {
                    address: 320,
                    value: 1,
                },
                IllegalDataAddress,
            ),
            // 02: FC16 on the control registers, the identification, past the ring.
            (multi(32, 1), IllegalDataAddress),
            (multi(33, 1), IllegalDataAddress),
            (multi(0, 2), IllegalDataAddress),
            (multi(256 + 63, 2), IllegalDataAddress),
            (multi(65535, 2), IllegalDataAddress),
            // 03: a reserved control bit, HEAD ≥ N.
            (
                Request::WriteSingle {
                    address: 32,
                    value: 0x40,
                },
                IllegalDataValue,
            ),
            (
                Request::WriteSingle {
                    address: 33,
                    value: 4,
                },
                IllegalDataValue,
            ),
        ];
        for (r, exception) in cases {
            assert_eq!(request(&mut b, r.clone()), Some(exception), "{r:?}");
        }
        // The good ones: status and control in one read, a whole ring, a slot by FC16.
        assert_eq!(read(&mut b, 16, 19).map(|v| v.len()), Ok(19));
        assert_eq!(read(&mut b, 256, 64).map(|v| v.len()), Ok(64));
        assert_eq!(
            b.request(&multi(256 + 48, 16)),
            Ok(Response::WriteMultiple {
                address: 304,
                count: 16
            })
        );
        assert_eq!(
            write(&mut b, 34, 7),
            Ok(Response::WriteSingle {
                address: 34,
                value: 7
            })
        );
        assert_eq!(reg(&mut b, 34), 7);
        // Nothing refused changed anything.
        assert_eq!(read(&mut b, 16, 18), Ok(vec![0; 18]));
    }

    #[test]
    fn the_watchdog_faults_when_not_fed() {
        let mut b = bank(4);
        // Not armed with RUN clear.
        b.advance(5.0).unwrap();
        assert_eq!(state(&mut b), 0);
        // RUN arms it (timer from now, t = 5). 0.999 s later: fine; fed; fine again 0.999 s
        // after that.
        write(&mut b, 32, 1).unwrap();
        b.advance(0.999).unwrap();
        assert_eq!(state(&mut b), 0);
        write(&mut b, 34, 1).unwrap();
        b.advance(0.999).unwrap();
        assert_eq!(state(&mut b), 0);
        // The same value again is not a change: 1 s after the last change, alarm 104.
        write(&mut b, 34, 1).unwrap();
        b.advance(0.0005).unwrap();
        assert_eq!(state(&mut b), 0);
        b.advance(0.001).unwrap();
        assert_eq!(alarm(&mut b), (3, 104, 0, 0));
        // RESET_ALARM with RUN still set arms it afresh, from the reset on.
        b.advance(3.0).unwrap();
        write(&mut b, 32, 1 | 8).unwrap();
        b.advance(0.9).unwrap();
        assert_eq!(alarm(&mut b), (0, 0, 0, 0));
        b.advance(0.2).unwrap();
        assert_eq!(alarm(&mut b).1, 104);
        // With END set it is off: the controller has every segment.
        let mut b = bank(4);
        write(&mut b, 32, 1 | 32).unwrap();
        b.advance(10.0).unwrap();
        assert_eq!(state(&mut b), 4);
        // Clearing END arms it afresh.
        write(&mut b, 32, 1).unwrap();
        b.advance(0.9).unwrap();
        assert_eq!(state(&mut b), 0);
        b.advance(0.2).unwrap();
        assert_eq!(alarm(&mut b).1, 104);
    }

    #[test]
    fn a_watchdog_stop_while_moving_holds_then_resets() {
        let mut b = bank(4);
        publish(&mut b, &[linked(1, 50.0, 0.0, 0.0, 5.0)]).unwrap();
        write(&mut b, 32, 1).unwrap();
        b.advance(1.0).unwrap();
        // Alarm at 1 s: a feed hold, not yet at rest, so RESET_ALARM must wait (06).
        assert_eq!(alarm(&mut b).1, 104);
        assert_eq!(
            b.controller().state(),
            MachineState::Hold { complete: false }
        );
        assert_eq!(write(&mut b, 32, 1 | 8), Err(Exception::ServerDeviceBusy));
        let events = run(&mut b, 2.0, |b| {
            b.controller().state() == MachineState::Idle
        });
        // Stopped short of X 50, then reset: the move was cut short, never completed.
        assert!(events.iter().any(|e| matches!(e, Event::Reset { .. })));
        assert!(executed(&events).is_empty());
        let x = b.controller().position().x;
        assert!(x > 0.0 && x < 50.0, "{x}");
        // At rest: RESET_ALARM clears it and flushes; any sequence number may start.
        assert!(write(&mut b, 32, 1 | 32 | 8).is_ok());
        assert_eq!(alarm(&mut b), (4, 0, 0, 0));
        assert_eq!(ring(&mut b), (0, 0, 0));
        assert!(publish(&mut b, &[linked(500, 50.0, 0.0, 0.0, 1.0)]).is_ok());
        let events = run(&mut b, 10.0, |b| state(b) == 4);
        assert_eq!(executed(&events), vec![500]);
    }

    #[test]
    fn a_line_queued_during_an_alarm_stop_is_not_taken() {
        // 45 linked moves of 1 mm along Z in 0.2 s each (5 mm/s; at 500 mm/s² the first
        // starts 0.005 s late, v/2a, and the rest follow at full speed), so block k ends at
        // 0.2·k + 0.005 s. The planner takes 35 lines at once and a line waits for room;
        // blocks 1–4 make room for lines 36–39 by 0.805 s.
        let mut b = bank_on(
            &machine(),
            BankOptions {
                slots: 64,
                watchdog_timeout_ms: 1003,
                ..BankOptions::default()
            },
        );
        let moves: Vec<[u16; 16]> = (1..=45)
            .map(|k| linked(k, 0.0, f64::from(k), 0.0, 0.2))
            .collect();
        publish(&mut b, &moves).unwrap();
        write(&mut b, 32, 1).unwrap();
        // The watchdog stops it at 1.003 s, 0.01 mm before block 5 ends: the hold needs
        // 0.025 mm (v²/2a), so block 5 completes while slowing and line 40 finds room.
        // It is queued only to be purged by the reset: TAIL stays after line 39.
        let events = run(&mut b, 2.0, |b| {
            b.controller().state() == MachineState::Idle && alarm(b).1 == 104
        });
        assert_eq!(executed(&events), vec![1, 2, 3, 4, 5]);
        assert_eq!(ring(&mut b).0, 39);
        assert_eq!(alarm(&mut b), (3, 104, 0, 0));
    }

    #[test]
    fn a_target_beyond_the_travel_is_alarm_2() {
        let mut b = bank(4);
        let slots = [
            linked(1, 50.0, 0.0, 0.0, 0.5),
            // X 150: outside 0–100.
            linked(2, 150.0, 0.0, 0.0, 0.5),
        ];
        publish(&mut b, &slots).unwrap();
        write(&mut b, 32, 1 | 32).unwrap();
        let events = run(&mut b, 5.0, |b| state(b) == 3);
        // grbl's soft limit: ALARM:2, the line answered error:15; the segment it refused
        // is 2, and TAIL stays on it.
        assert!(events.iter().any(|e| matches!(
            e,
            Event::Alarm {
                alarm: GrblAlarm::SoftLimit,
                ..
            }
        )));
        assert_eq!(alarm(&mut b), (3, 2, 2, 15));
        assert_eq!(ring(&mut b).0, 1);
        // RESET_ALARM (the machine is at rest): idle, flushed.
        write(&mut b, 32, 1 | 32 | 8).unwrap();
        assert_eq!(alarm(&mut b), (4, 0, 0, 0));
        assert_eq!(ring(&mut b), (0, 0, 0));
        assert_eq!(b.controller().state(), MachineState::Idle);
    }

    #[test]
    fn a_line_the_controller_refuses_is_alarm_105() {
        // A controller whose lines hold 16 characters: the linked line is longer, so
        // grbl answers error:11.
        let mut m = machine();
        m.max_line_length = 16;
        let mut b = bank_on(&m, BankOptions::default());
        publish(&mut b, &[linked(1, 5.0, 0.0, 0.0, 0.1)]).unwrap();
        write(&mut b, 32, 1).unwrap();
        assert_eq!(alarm(&mut b), (3, 105, 1, 11));
    }

    /// A guard that finds every block beyond Δ.
    #[derive(Debug)]
    struct Strict;

    impl Guard for Strict {
        fn executed(&mut self, _: &ExecutedBlock) -> Result<(), Breach> {
            Err(Breach {
                message: "beyond Δ".into(),
            })
        }
        fn program_end(&mut self) -> Result<(), Breach> {
            Ok(())
        }
        fn measured(&self) -> Measured {
            Measured::default()
        }
    }

    #[test]
    fn the_delta_guard_stops_a_slot_stream_with_alarm_64() {
        let mut controller = Controller::new(&machine(), ControllerOptions::default()).unwrap();
        controller.set_guard(Box::new(Strict));
        let mut b = Bank::new(controller, BankOptions::default()).unwrap();
        let moves: Vec<[u16; 16]> = (1..=3)
            .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.2))
            .collect();
        publish(&mut b, &moves).unwrap();
        write(&mut b, 32, 1 | 32).unwrap();
        run(&mut b, 5.0, |b| state(b) == 3);
        assert_eq!(alarm(&mut b).1, 64);
        // Nothing more is taken.
        b.advance(1.0).unwrap();
        assert_eq!(alarm(&mut b).1, 64);
    }

    #[test]
    fn hold_and_resume() {
        let mut b = bank(4);
        publish(&mut b, &[linked(1, 50.0, 0.0, 0.0, 2.0)]).unwrap();
        write(&mut b, 32, 1 | 32).unwrap();
        b.advance(0.5).unwrap();
        assert_eq!(state(&mut b), 1);
        write(&mut b, 32, 1 | 32 | 2).unwrap();
        b.advance(1.0).unwrap();
        assert_eq!(state(&mut b), 2);
        assert_eq!(
            b.controller().state(),
            MachineState::Hold { complete: true }
        );
        // Writing the same word again is no new edge; RESUME is.
        write(&mut b, 32, 1 | 32 | 2).unwrap();
        write(&mut b, 32, 1 | 32 | 4).unwrap();
        assert_eq!(state(&mut b), 1);
        let events = run(&mut b, 10.0, |b| state(b) == 4);
        assert_eq!(executed(&events), vec![1]);
    }

    #[test]
    fn abort_stops_and_flushes() {
        let mut b = bank(4);
        publish(
            &mut b,
            &[
                linked(1, 50.0, 0.0, 0.0, 2.0),
                linked(2, 60.0, 0.0, 0.0, 1.0),
            ],
        )
        .unwrap();
        write(&mut b, 32, 1).unwrap();
        b.advance(0.5).unwrap();
        assert!(write(&mut b, 32, 1 | 16).is_ok());
        // Coming to rest: held, and HEAD cannot move until then (06).
        assert_eq!(state(&mut b), 2);
        write_slot(&mut b, 2, &linked(3, 5.0, 0.0, 0.0, 0.1)).unwrap();
        assert_eq!(write(&mut b, 33, 3), Err(Exception::ServerDeviceBusy));
        run(&mut b, 2.0, |b| state(b) != 2);
        assert_eq!(state(&mut b), 0);
        assert_eq!(ring(&mut b), (0, 0, 0));
        assert_eq!(b.controller().state(), MachineState::Idle);
        // At rest, an abort is complete when answered. Then a new stream, any number.
        write(&mut b, 32, 1).unwrap();
        assert!(write(&mut b, 32, 1 | 16).is_ok());
        assert_eq!(state(&mut b), 0);
        assert!(publish(&mut b, &[linked(77, 5.0, 0.0, 0.0, 0.1)]).is_ok());
        write(&mut b, 32, 1 | 32).unwrap();
        let events = run(&mut b, 5.0, |b| state(b) == 4);
        assert_eq!(executed(&events), vec![77]);
    }

    #[test]
    fn options_and_time_are_checked() {
        let controller = || Controller::new(&machine(), ControllerOptions::default()).unwrap();
        for (options, name) in [
            (
                BankOptions {
                    slots: 1,
                    ..BankOptions::default()
                },
                "slots",
            ),
            (
                BankOptions {
                    slots: 65,
                    ..BankOptions::default()
                },
                "slots",
            ),
            (
                BankOptions {
                    watchdog_timeout_ms: 0,
                    ..BankOptions::default()
                },
                "watchdog_timeout_ms",
            ),
            (
                BankOptions {
                    max_segment_rate: 0,
                    ..BankOptions::default()
                },
                "max_segment_rate",
            ),
        ] {
            assert!(matches!(
                Bank::new(controller(), options),
                Err(ConfigError::Option { name: n, .. }) if n == name
            ));
        }
        let mut b = bank(4);
        assert_eq!(b.advance(-1.0), Err(TimeError(-1.0)));
        assert!(b.advance(f64::NAN).is_err());
    }

    #[test]
    fn numbers_are_written_exactly() {
        assert_eq!(decimal(125_000, 4), "12.5");
        assert_eq!(decimal(-5, 4), "-0.0005");
        assert_eq!(decimal(0, 4), "0");
        assert_eq!(decimal(-30_000, 4), "-3");
        assert_eq!(decimal(i64::MIN, 4), "-922337203685477.5808");
        // 7 µs: F = 60 000 000 / 7 = 8 571 428.571429 (to 10⁻⁶).
        let s = Segment::Linked {
            xzc: [0; 3],
            micros: 7,
        };
        assert_eq!(s.line(3), "N3 G93 G1 X0 Z0 C0 F8571428.571429");
    }
}
