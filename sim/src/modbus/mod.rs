//! A Modbus front-end for the simulated controller: the register map of whirl's
//! `docs/modbus.md` (identification, status, control word, a ring of segment slots with
//! a bridge-owned HEAD and a controller-owned TAIL, a watchdog), served by a [`Bank`] as
//! requests in and answers out, sans-I/O like the rest of the crate.
//!
//! This is the controller's side, written from the document apart from the bridge's
//! (whirl's `modbus` module): the two meet end to end in whirl's integration tests, and a
//! misreading shared by both would pass every test of either.
//!
//! The bank executes nothing itself. Each slot, once published and taken, becomes the
//! G-code line it stands for (`N<seq> G93 G1 X… Z… C… F…` for a linked move), handed to
//! the same [`Controller`](crate::Controller) the serial front-end drives, so the motion
//! model, the travel limits (`ALARM:2`), the Δ guard (`ALARM:64`) and the execution record
//! are exactly the G-code front-end's. See [`bank`] for how.
//!
//! A network server (tokio-modbus) would answer each request with
//! [`Bank::request`] and call [`Bank::advance`] as time passes; unit id 1.

pub mod bank;
pub mod serve;

pub use bank::{Bank, BankOptions};

use thiserror::Error;

/// A request, by function code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// 03, read holding registers.
    ReadHolding {
        /// First register.
        address: u16,
        /// How many.
        count: u16,
    },
    /// 06, write single register.
    WriteSingle {
        /// The register.
        address: u16,
        /// The value.
        value: u16,
    },
    /// 16, write multiple registers.
    WriteMultiple {
        /// First register.
        address: u16,
        /// The values, in address order.
        values: Vec<u16>,
    },
    /// Any other function code (answered 01).
    Other {
        /// The function code.
        function: u8,
    },
}

/// A normal answer, as Modbus frames it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// 03: the registers.
    ReadHolding(Vec<u16>),
    /// 06: the request echoed.
    WriteSingle {
        /// The register.
        address: u16,
        /// The value.
        value: u16,
    },
    /// 16: where and how many.
    WriteMultiple {
        /// First register.
        address: u16,
        /// How many were written.
        count: u16,
    },
}

/// An exception answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum Exception {
    /// 01: a function code other than 03, 06, 16.
    #[error("illegal function")]
    IllegalFunction,
    /// 02: a register unmapped, read-only, or (for 16) one of the control registers.
    #[error("illegal data address")]
    IllegalDataAddress,
    /// 03: a quantity out of Modbus's range, or a value the map does not allow.
    #[error("illegal data value")]
    IllegalDataValue,
    /// 04: a slot refused at the HEAD write, or a HEAD advance during an alarm.
    #[error("server device failure")]
    ServerDeviceFailure,
    /// 06: not now (a published slot, an abort or an alarm stop under way).
    #[error("server device busy")]
    ServerDeviceBusy,
}

impl Exception {
    /// The exception code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Exception::IllegalFunction => 0x01,
            Exception::IllegalDataAddress => 0x02,
            Exception::IllegalDataValue => 0x03,
            Exception::ServerDeviceFailure => 0x04,
            Exception::ServerDeviceBusy => 0x06,
        }
    }
}

/// How the bank spreads 32- and 64-bit values over registers (`WORD_ORDER`); the
/// discriminants are the register's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u16)]
pub enum WordOrder {
    /// Most significant word at the lowest address (0).
    #[default]
    HighFirst = 0,
    /// Least significant word at the lowest address (1).
    LowFirst = 1,
}

impl WordOrder {
    /// The `WORD_ORDER` register's value.
    fn register(self) -> u16 {
        self as u16
    }

    /// The words of `value` (`N` of them, the most significant first) in address order.
    fn place<const N: usize>(self, value: u64) -> [u16; N] {
        let mut words = [0u16; N];
        for (k, word) in words.iter_mut().enumerate() {
            let shift = 16 * (N - 1 - k);
            *word = (value >> shift) as u16;
        }
        if self == WordOrder::LowFirst {
            words.reverse();
        }
        words
    }

    /// The value of `words`, given in address order.
    fn value(self, words: &[u16]) -> u64 {
        let fold = |acc: u64, w: &u16| (acc << 16) | u64::from(*w);
        match self {
            WordOrder::HighFirst => words.iter().fold(0, fold),
            WordOrder::LowFirst => words.iter().rev().fold(0, fold),
        }
    }
}

/// CRC-16/MODBUS, bit by bit: register 0xFFFF, each byte XORed into the low end and
/// shifted out to the right eight times, XORing 0xA001 (0x8005 reflected) when a one
/// falls out. No final XOR.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &byte in bytes {
        crc ^= u16::from(byte);
        for _ in 0..8 {
            let carry = crc & 1;
            crc >>= 1;
            if carry == 1 {
                crc ^= 0xA001;
            }
        }
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc16_check_value() {
        // CRC-16/MODBUS's catalogue check value over ASCII "123456789".
        assert_eq!(crc16(b"123456789"), 0x4B37);
        assert_eq!(crc16(&[]), 0xFFFF);
    }

    #[test]
    fn word_orders_place_and_read() {
        assert_eq!(
            WordOrder::HighFirst.place::<2>(0x1234_5678),
            [0x1234, 0x5678]
        );
        assert_eq!(
            WordOrder::LowFirst.place::<2>(0x1234_5678),
            [0x5678, 0x1234]
        );
        assert_eq!(
            WordOrder::LowFirst.place::<4>(0x0102_0304_0506_0708),
            [0x0708, 0x0506, 0x0304, 0x0102]
        );
        assert_eq!(WordOrder::LowFirst.value(&[0x5678, 0x1234]), 0x1234_5678);
        assert_eq!(
            WordOrder::HighFirst.value(&[0x0102, 0x0304, 0x0506, 0x0708]),
            0x0102_0304_0506_0708
        );
    }

    #[test]
    fn exception_codes() {
        let codes = [
            Exception::IllegalFunction,
            Exception::IllegalDataAddress,
            Exception::IllegalDataValue,
            Exception::ServerDeviceFailure,
            Exception::ServerDeviceBusy,
        ]
        .map(Exception::code);
        assert_eq!(codes, [1, 2, 3, 4, 6]);
        assert_eq!(
            Exception::ServerDeviceBusy.to_string(),
            "server device busy"
        );
    }
}
