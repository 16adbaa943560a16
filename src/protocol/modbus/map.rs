//! The register map of `docs/modbus.md` as values: addresses, bits and codes, the word
//! order of multi-register values, segments and their slots (sequence number and
//! CRC-16/MODBUS), and the identification and status blocks decoded.
//!
//! Nothing here talks to a controller; [`super::RingWriter`] decides what to write when.
//! Every number below is the document's; the tests check the encodings against values
//! worked out by hand from it.

use std::fmt;
use std::time::Duration;

use thiserror::Error;

use crate::post::modbus::{Segment, ANGULAR_UNITS_PER_DEG, LINEAR_UNITS_PER_MM};

/// The controller's Modbus unit id.
pub const UNIT_ID: u8 = 1;
/// `MAGIC_0`, `MAGIC_1`: ASCII "WHRL", two characters a register, high byte first.
pub const MAGIC: [u16; 2] = [0x5748, 0x524C];
/// The map version this module implements.
pub const MAP_VERSION: u16 = 1;
/// Registers per slot.
pub const SLOT_SIZE: u16 = 16;
/// Fewest slots a ring may have (one is always kept empty).
pub const MIN_SLOTS: u16 = 2;
/// Most slots a ring may have.
pub const MAX_SLOTS: u16 = 64;
/// Most registers one FC03 may read (Modbus application protocol, 6.3).
pub const MAX_READ: u16 = 125;
/// Most registers one FC16 may write (Modbus application protocol, 6.12).
pub const MAX_WRITE: u16 = 123;

/// Holding-register addresses, 0-based as on the wire.
pub mod reg {
    /// `MAGIC_0`, `MAGIC_1`.
    pub const MAGIC: u16 = 0;
    /// `MAP_VERSION`.
    pub const MAP_VERSION: u16 = 2;
    /// `SLOT_COUNT`: N.
    pub const SLOT_COUNT: u16 = 3;
    /// `SLOT_SIZE`.
    pub const SLOT_SIZE: u16 = 4;
    /// `WORD_ORDER`: 0 high word first, 1 low word first.
    pub const WORD_ORDER: u16 = 5;
    /// `MAX_SEGMENT_RATE`, segments per second.
    pub const MAX_SEGMENT_RATE: u16 = 6;
    /// `WATCHDOG_TIMEOUT`, ms.
    pub const WATCHDOG_TIMEOUT: u16 = 7;
    /// Registers in the identification block (0–7).
    pub const IDENT_LEN: u16 = 8;

    /// `STATE`, the first status register.
    pub const STATE: u16 = 16;
    /// `ALARM_CODE`.
    pub const ALARM_CODE: u16 = 17;
    /// `ALARM_SEQ`, u32.
    pub const ALARM_SEQ: u16 = 18;
    /// `ALARM_DETAIL`.
    pub const ALARM_DETAIL: u16 = 20;
    /// `TAIL`.
    pub const TAIL: u16 = 21;
    /// `EXECUTED_SEQ`, u32.
    pub const EXECUTED_SEQ: u16 = 22;
    /// `POS_X`, i32, 0.1 µm.
    pub const POS_X: u16 = 24;
    /// `POS_Z`, i32, 0.1 µm.
    pub const POS_Z: u16 = 26;
    /// `POS_C`, i64, 10⁻⁴ °.
    pub const POS_C: u16 = 28;
    /// `CONTROL`, the control word.
    pub const CONTROL: u16 = 32;
    /// `HEAD`.
    pub const HEAD: u16 = 33;
    /// `WATCHDOG`.
    pub const WATCHDOG: u16 = 34;
    /// `FEED_OVERRIDE`, percent of the programmed feed, 10–200 (not in the status block
    /// read: the bridge writes it, and the echo confirms it).
    pub const FEED_OVERRIDE: u16 = 40;
    /// Registers in the status and control blocks read together (16–34).
    pub const STATUS_LEN: u16 = 19;

    /// Slot 0; slot i is at `RING + 16·i`.
    pub const RING: u16 = 256;
}

/// Bits of the control word.
pub mod control {
    /// Level: take slots while set.
    pub const RUN: u16 = 1 << 0;
    /// Rising edge: feed hold.
    pub const HOLD: u16 = 1 << 1;
    /// Rising edge: cycle start after a hold.
    pub const RESUME: u16 = 1 << 2;
    /// Rising edge: clear the alarm and flush the ring.
    pub const RESET_ALARM: u16 = 1 << 3;
    /// Rising edge: stop and flush the ring.
    pub const ABORT: u16 = 1 << 4;
    /// Level: end of stream, no more slots will come.
    pub const END: u16 = 1 << 5;
}

/// Segment kinds, the low byte of a slot's `KIND` register.
pub mod kind {
    /// A linked C/X/Z move in inverse time.
    pub const LINKED: u16 = 1;
    /// A rapid.
    pub const RAPID: u16 = 2;
    /// A feed move in units per minute.
    pub const FEED: u16 = 3;
    /// A dwell.
    pub const DWELL: u16 = 4;
    /// Spindle (the whirling ring) on, clockwise.
    pub const SPINDLE_ON: u16 = 5;
    /// Spindle off.
    pub const SPINDLE_OFF: u16 = 6;
    /// Program end.
    pub const PROGRAM_END: u16 = 7;
}

/// Axis flags, the high byte of a slot's `KIND` register: the axis moves to the target
/// given.
pub mod flag {
    /// X moves.
    pub const X: u16 = 1 << 8;
    /// Z moves.
    pub const Z: u16 = 1 << 9;
    /// C moves.
    pub const C: u16 = 1 << 10;
}

/// The registers of a slot, as offsets from its first. The two not named (3 and 14) are
/// reserved and hold 0.
pub mod offset {
    /// `SEQ`, u32: the sequence number.
    pub const SEQ: usize = 0;
    /// `KIND`: the segment kind in the low byte, the axis flags in the high byte.
    pub const KIND: usize = 2;
    /// `X`, i32.
    pub const X: usize = 4;
    /// `Z`, i32.
    pub const Z: usize = 6;
    /// `C`, i64.
    pub const C: usize = 8;
    /// `PARAM`, u32: duration, feed, dwell or spindle speed, by kind.
    pub const PARAM: usize = 12;
    /// `CRC`: CRC-16/MODBUS of the registers before it.
    pub const CRC: usize = 15;
}

/// Why registers could not be encoded or decoded, or a program carried.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MapError {
    /// A register of the identification or status block holds a value this map does not
    /// allow.
    #[error("register {register} holds {value:#06x}: {reason}")]
    Register {
        /// Its address.
        register: u16,
        /// What it held.
        value: u16,
        /// What was expected.
        reason: &'static str,
    },
    /// A block decoded from the wrong number of registers.
    #[error("{what}: expected {expected} registers, got {got}")]
    Length {
        /// Which block.
        what: &'static str,
        /// Registers it has.
        expected: usize,
        /// Registers given.
        got: usize,
    },
}

/// How a 32- or 64-bit value is spread over consecutive registers. The discriminants are
/// the `WORD_ORDER` register's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u16)]
pub enum WordOrder {
    /// Most significant word at the lowest address (register value 0, the default).
    #[default]
    HighFirst = 0,
    /// Least significant word at the lowest address (register value 1).
    LowFirst = 1,
}

impl WordOrder {
    /// From the `WORD_ORDER` register.
    pub fn from_register(value: u16) -> Result<WordOrder, MapError> {
        [WordOrder::HighFirst, WordOrder::LowFirst]
            .into_iter()
            .find(|order| order.register() == value)
            .ok_or(MapError::Register {
                register: reg::WORD_ORDER,
                value,
                reason: "word order must be 0 (high word first) or 1 (low word first)",
            })
    }

    /// The `WORD_ORDER` register's value.
    pub fn register(self) -> u16 {
        self as u16
    }

    /// `value` as two registers, in address order.
    pub fn u32_words(self, value: u32) -> [u16; 2] {
        let words = [(value >> 16) as u16, value as u16];
        self.arrange(words)
    }

    /// Two registers, in address order, as a u32.
    pub fn u32_from(self, words: [u16; 2]) -> u32 {
        let [high, low] = self.arrange(words);
        (u32::from(high) << 16) | u32::from(low)
    }

    /// `value` as four registers, in address order.
    pub fn i64_words(self, value: i64) -> [u16; 4] {
        let v = value as u64;
        let words = [
            (v >> 48) as u16,
            (v >> 32) as u16,
            (v >> 16) as u16,
            v as u16,
        ];
        self.arrange(words)
    }

    /// Four registers, in address order, as an i64.
    pub fn i64_from(self, words: [u16; 4]) -> i64 {
        let [a, b, c, d] = self.arrange(words);
        ((u64::from(a) << 48) | (u64::from(b) << 32) | (u64::from(c) << 16) | u64::from(d)) as i64
    }

    /// Words most significant first ↔ address order: the identity or a reversal, which
    /// is its own inverse.
    fn arrange<const N: usize>(self, mut words: [u16; N]) -> [u16; N] {
        if self == WordOrder::LowFirst {
            words.reverse();
        }
        words
    }
}

/// CRC-16/MODBUS lookup table (reflected polynomial 0xA001), built at compile time.
const CRC_TABLE: [u16; 256] = {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xA001
            } else {
                crc >> 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
};

/// CRC-16/MODBUS of `bytes`: initial value 0xFFFF, reflected, no final XOR.
pub fn crc16(bytes: &[u8]) -> u16 {
    bytes.iter().fold(0xFFFF, |crc, &b| {
        (crc >> 8) ^ CRC_TABLE[usize::from((crc ^ u16::from(b)) as u8)]
    })
}

/// The CRC of a slot: over registers 0–14, each high byte first.
pub fn slot_crc(registers: &[u16]) -> u16 {
    let bytes: Vec<u8> = registers.iter().flat_map(|r| r.to_be_bytes()).collect();
    crc16(&bytes)
}

impl Segment {
    /// The slot carrying this segment as sequence number `sequence`, in address order,
    /// with its CRC.
    pub fn encode(&self, sequence: u32, order: WordOrder) -> [u16; SLOT_SIZE as usize] {
        let (kind, x, z, c, param) = match *self {
            Segment::Linked {
                x,
                z,
                c,
                duration_us,
            } => (
                kind::LINKED | flag::X | flag::Z | flag::C,
                Some(x),
                Some(z),
                Some(c),
                duration_us,
            ),
            Segment::Rapid { x, z, c } => (kind::RAPID | flags(x, z, c), x, z, c, 0),
            Segment::Feed { x, z, c, feed } => (kind::FEED | flags(x, z, c), x, z, c, feed),
            Segment::Dwell { duration_us } => (kind::DWELL, None, None, None, duration_us),
            Segment::SpindleOn { rpm } => (kind::SPINDLE_ON, None, None, None, rpm),
            Segment::SpindleOff => (kind::SPINDLE_OFF, None, None, None, 0),
            Segment::ProgramEnd => (kind::PROGRAM_END, None, None, None, 0),
        };
        let mut slot = [0u16; SLOT_SIZE as usize];
        let mut put = |at: usize, words: &[u16]| slot[at..at + words.len()].copy_from_slice(words);
        put(offset::SEQ, &order.u32_words(sequence));
        put(offset::KIND, &[kind]);
        put(offset::X, &order.u32_words(x.unwrap_or(0) as u32));
        put(offset::Z, &order.u32_words(z.unwrap_or(0) as u32));
        put(offset::C, &order.i64_words(c.unwrap_or(0)));
        put(offset::PARAM, &order.u32_words(param));
        slot[offset::CRC] = slot_crc(&slot[..offset::CRC]);
        slot
    }
}

/// The axis flags of the axes given.
fn flags(x: Option<i32>, z: Option<i32>, c: Option<i64>) -> u16 {
    let mut f = 0;
    if x.is_some() {
        f |= flag::X;
    }
    if z.is_some() {
        f |= flag::Z;
    }
    if c.is_some() {
        f |= flag::C;
    }
    f
}

/// The next sequence number after `sequence`: one more, from 4 294 967 295 back to 1
/// (0 is never used).
pub fn next_sequence(sequence: u32) -> u32 {
    sequence.checked_add(1).unwrap_or(1)
}

/// The identification block (registers 0–7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identification {
    /// N, slots in the ring.
    pub slots: u16,
    /// How the controller orders the words of 32- and 64-bit values.
    pub word_order: WordOrder,
    /// Most segments per second the controller executes at their programmed duration.
    pub max_segment_rate: u16,
    /// The watchdog's timeout.
    pub watchdog_timeout: Duration,
}

impl Identification {
    /// Decodes registers 0–7, checking the magic, the version, the slot size and that
    /// every value is one the map allows.
    pub fn decode(registers: &[u16]) -> Result<Identification, MapError> {
        let r = exact::<{ reg::IDENT_LEN as usize }>(registers, "identification block")?;
        let at = |register: u16| r[usize::from(register - reg::MAGIC)];
        let bad = |register: u16, reason| {
            Err(MapError::Register {
                register,
                value: at(register),
                reason,
            })
        };
        let magic_1 = reg::MAGIC + 1;
        if at(reg::MAGIC) != MAGIC[0] {
            return bad(
                reg::MAGIC,
                "not a whirl register map (magic \"WH\" expected)",
            );
        }
        if at(magic_1) != MAGIC[1] {
            return bad(magic_1, "not a whirl register map (magic \"RL\" expected)");
        }
        if at(reg::MAP_VERSION) != MAP_VERSION {
            return bad(reg::MAP_VERSION, "map version 1 expected");
        }
        let slots = at(reg::SLOT_COUNT);
        if !(MIN_SLOTS..=MAX_SLOTS).contains(&slots) {
            return bad(reg::SLOT_COUNT, "slot count must be 2 to 64");
        }
        if at(reg::SLOT_SIZE) != SLOT_SIZE {
            return bad(reg::SLOT_SIZE, "slot size 16 expected");
        }
        let word_order = WordOrder::from_register(at(reg::WORD_ORDER))?;
        let max_segment_rate = at(reg::MAX_SEGMENT_RATE);
        if max_segment_rate == 0 {
            return bad(
                reg::MAX_SEGMENT_RATE,
                "a segment rate of 0 executes nothing",
            );
        }
        let watchdog_ms = at(reg::WATCHDOG_TIMEOUT);
        if watchdog_ms == 0 {
            return bad(
                reg::WATCHDOG_TIMEOUT,
                "a watchdog timeout of 0 ms cannot be met",
            );
        }
        Ok(Identification {
            slots,
            word_order,
            max_segment_rate,
            watchdog_timeout: Duration::from_millis(u64::from(watchdog_ms)),
        })
    }
}

/// The controller's state (`STATE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// 0: nothing to do, or slots waiting with `RUN` clear.
    Idle,
    /// 1: moving, or executing a queued segment.
    Running,
    /// 2: a feed hold (or an abort coming to rest).
    Held,
    /// 3: an alarm is active.
    Alarm,
    /// 4: `END` set, the ring empty and everything executed.
    Done,
}

impl State {
    /// From the `STATE` register.
    pub fn from_register(value: u16) -> Result<State, MapError> {
        Ok(match value {
            0 => State::Idle,
            1 => State::Running,
            2 => State::Held,
            3 => State::Alarm,
            4 => State::Done,
            _ => {
                return Err(MapError::Register {
                    register: reg::STATE,
                    value,
                    reason: "state must be 0 to 4",
                })
            }
        })
    }
}

/// An alarm code (`ALARM_CODE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlarmCode {
    /// 2: a target outside the travel (grbl's `ALARM:2`).
    SoftLimit,
    /// 3: reset while moving (grbl's `ALARM:3`).
    AbortCycle,
    /// 64: the Δ guard measured the cut beyond Δ (whirl-sim's `ALARM:64`).
    ProfileError,
    /// 101: a published slot failed its CRC.
    SlotCrc,
    /// 102: a published slot's sequence number was not the one expected.
    Sequence,
    /// 103: a published slot's content was not a valid segment.
    Segment,
    /// 104: the watchdog was not fed in time.
    Watchdog,
    /// 105: the controller refused a segment.
    Refused,
    /// Another controller alarm, by number.
    Other(u16),
}

impl AlarmCode {
    /// The alarms the map names; their codes are [`AlarmCode::code`]'s.
    const NAMED: [AlarmCode; 8] = [
        AlarmCode::SoftLimit,
        AlarmCode::AbortCycle,
        AlarmCode::ProfileError,
        AlarmCode::SlotCrc,
        AlarmCode::Sequence,
        AlarmCode::Segment,
        AlarmCode::Watchdog,
        AlarmCode::Refused,
    ];

    /// From the `ALARM_CODE` register; `None` for 0 (no alarm).
    pub fn from_register(value: u16) -> Option<AlarmCode> {
        if value == 0 {
            return None;
        }
        let named = AlarmCode::NAMED.into_iter().find(|a| a.code() == value);
        Some(named.unwrap_or(AlarmCode::Other(value)))
    }

    /// The register value.
    pub fn code(self) -> u16 {
        match self {
            AlarmCode::SoftLimit => 2,
            AlarmCode::AbortCycle => 3,
            AlarmCode::ProfileError => 64,
            AlarmCode::SlotCrc => 101,
            AlarmCode::Sequence => 102,
            AlarmCode::Segment => 103,
            AlarmCode::Watchdog => 104,
            AlarmCode::Refused => 105,
            AlarmCode::Other(code) => code,
        }
    }
}

impl fmt::Display for AlarmCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            AlarmCode::SoftLimit => "target outside the travel",
            AlarmCode::AbortCycle => "reset while moving",
            AlarmCode::ProfileError => "profile error beyond Δ",
            AlarmCode::SlotCrc => "slot CRC",
            AlarmCode::Sequence => "sequence number out of order",
            AlarmCode::Segment => "invalid segment",
            AlarmCode::Watchdog => "watchdog",
            AlarmCode::Refused => "segment refused by the controller",
            AlarmCode::Other(_) => "controller alarm",
        };
        write!(f, "alarm {} ({text})", self.code())
    }
}

/// An active alarm with what it concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlarmReport {
    /// Which.
    pub code: AlarmCode,
    /// `ALARM_SEQ`: the segment it refused, 0 if none.
    pub sequence: u32,
    /// `ALARM_DETAIL`: the controller's error number for a refused segment, else 0.
    pub detail: u16,
}

impl fmt::Display for AlarmReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.code)?;
        if self.sequence != 0 {
            write!(f, " at segment {}", self.sequence)?;
        }
        if self.detail != 0 {
            write!(f, ", controller error {}", self.detail)?;
        }
        Ok(())
    }
}

/// The status and control blocks (registers 16–34), as one read returns them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status {
    /// `STATE`.
    pub state: State,
    /// The active alarm, if `ALARM_CODE` is not 0.
    pub alarm: Option<AlarmReport>,
    /// `TAIL`.
    pub tail: u16,
    /// `EXECUTED_SEQ`.
    pub executed: u32,
    /// `POS_X`, 0.1 µm.
    pub x: i32,
    /// `POS_Z`, 0.1 µm.
    pub z: i32,
    /// `POS_C`, 10⁻⁴ °.
    pub c: i64,
    /// `CONTROL` as last written.
    pub control: u16,
    /// `HEAD`.
    pub head: u16,
    /// `WATCHDOG` as last written.
    pub watchdog: u16,
}

impl Status {
    /// Decodes registers 16–34 with the controller's word order.
    pub fn decode(registers: &[u16], order: WordOrder) -> Result<Status, MapError> {
        let r = exact::<{ reg::STATUS_LEN as usize }>(registers, "status block")?;
        let at = |register: u16| usize::from(register - reg::STATE);
        let u32_at = |register: u16| order.u32_from([r[at(register)], r[at(register) + 1]]);
        let i = at(reg::POS_C);
        let state = State::from_register(r[at(reg::STATE)])?;
        let code = r[at(reg::ALARM_CODE)];
        let alarm = AlarmCode::from_register(code).map(|code| AlarmReport {
            code,
            sequence: u32_at(reg::ALARM_SEQ),
            detail: r[at(reg::ALARM_DETAIL)],
        });
        if (state == State::Alarm) != alarm.is_some() {
            return Err(MapError::Register {
                register: reg::ALARM_CODE,
                value: code,
                reason: "an alarm code goes with state 3 (alarm), and only with it",
            });
        }
        Ok(Status {
            state,
            alarm,
            tail: r[at(reg::TAIL)],
            executed: u32_at(reg::EXECUTED_SEQ),
            x: u32_at(reg::POS_X) as i32,
            z: u32_at(reg::POS_Z) as i32,
            c: order.i64_from([r[i], r[i + 1], r[i + 2], r[i + 3]]),
            control: r[at(reg::CONTROL)],
            head: r[at(reg::HEAD)],
            watchdog: r[at(reg::WATCHDOG)],
        })
    }

    /// The machine position, mm (X as a radius), mm, degrees.
    pub fn position(&self) -> [f64; 3] {
        [
            f64::from(self.x) / LINEAR_UNITS_PER_MM,
            f64::from(self.z) / LINEAR_UNITS_PER_MM,
            self.c as f64 / ANGULAR_UNITS_PER_DEG,
        ]
    }
}

/// `registers` as an array of exactly `N`.
fn exact<const N: usize>(registers: &[u16], what: &'static str) -> Result<[u16; N], MapError> {
    registers.try_into().map_err(|_| MapError::Length {
        what,
        expected: N,
        got: registers.len(),
    })
}

#[cfg(test)]
mod tests;
