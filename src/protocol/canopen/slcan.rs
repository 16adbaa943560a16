//! The Lawicel ASCII protocol ("slcan"), host side: the commands a host writes to a
//! serial CAN adapter (CANUSB, CAN232, CANable, USBtin) and a decoder for what the adapter
//! writes back. Values in, bytes out, and bytes in, values out; the serial port is the
//! transport's.
//!
//! # The protocol
//!
//! Following Lawicel's CANUSB manual (the EasySYNC USB2-F-7x01 guide, §4.1, describes the
//! same commands): every command is ASCII ending in CR (0x0D). The adapter answers CR
//! for success and BEL (0x07) for an error, except that a transmit answers `z` CR
//! (standard identifier, `t` and `r`) or `Z` CR (extended, `T` and `R`).
//!
//! | command | meaning |
//! | --- | --- |
//! | `S0`…`S8` | bit rate 10, 20, 50, 100, 125, 250, 500, 800 kbit/s, 1 Mbit/s; channel closed |
//! | `O` / `C` | open / close the channel (`O` only after a bit rate was set) |
//! | `tiiildd…` | transmit: 3 hex digits of 11-bit id, DLC digit, 2 hex digits a byte |
//! | `Tiiiiiiiildd…` | the same with 8 hex digits of 29-bit id |
//! | `riiil` / `Riiiiiiiil` | remote request with the DLC asked for, no data |
//! | `Z0` / `Z1` | received frames without / with a timestamp |
//!
//! Frames received from the bus arrive in the transmit syntax, each ending in CR, followed
//! by four hex digits of milliseconds when timestamps are on (Lawicel counts 0–0xEA5F and
//! wraps each minute).
//!
//! # Why the decoder is lenient where it is
//!
//! - The timestamp is recognised by the line's length, not by remembering `Z1`: Lawicel
//!   keeps that setting in the adapter's EEPROM across power cycles, so a host cannot know
//!   it from what it sent. A frame line is exactly its DLC's length, or that plus four.
//! - Hex digits of either case are read: the manual writes upper case, some firmware
//!   writes lower.
//! - A plain CR is [`Received::Ok`] whatever it answers: some firmware (CANable's
//!   slcan build) acknowledges transmits with CR instead of `z` CR. Pairing answers with
//!   commands is the caller's business, since only it knows what it sent.
//! - A BEL ends whatever partial line precedes it: an adapter sends BEL on its own, so bytes
//!   before it are a broken line (reported) and the BEL still counts as the error reply.
//! - A line with no CR after [`MAX_LINE`] bytes is reported once and skipped up to the next
//!   CR, so one lost CR costs one line, not the rest of the session.

use std::fmt;

use thiserror::Error;

use super::frame::{CanFrame, CanId, FrameError};

/// CR, the end of every command and reply line.
pub const CR: u8 = b'\r';
/// BEL, the adapter's error reply.
pub const BEL: u8 = 0x07;
/// The longest line an adapter sends: `T`, 8 id digits, DLC, 16 data digits, 4 timestamp
/// digits.
pub const MAX_LINE: usize = 30;

/// The standard bit rates `S0`–`S8` select.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Bitrate {
    /// `S0`: 10 kbit/s.
    K10,
    /// `S1`: 20 kbit/s.
    K20,
    /// `S2`: 50 kbit/s.
    K50,
    /// `S3`: 100 kbit/s.
    K100,
    /// `S4`: 125 kbit/s.
    K125,
    /// `S5`: 250 kbit/s.
    K250,
    /// `S6`: 500 kbit/s.
    K500,
    /// `S7`: 800 kbit/s.
    K800,
    /// `S8`: 1 Mbit/s.
    M1,
}

impl Bitrate {
    /// All of them, in `S` order.
    pub const ALL: [Bitrate; 9] = [
        Bitrate::K10,
        Bitrate::K20,
        Bitrate::K50,
        Bitrate::K100,
        Bitrate::K125,
        Bitrate::K250,
        Bitrate::K500,
        Bitrate::K800,
        Bitrate::M1,
    ];

    /// The digit after `S`.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// Bits per second.
    pub fn bits_per_second(self) -> u32 {
        [
            10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ][self as usize]
    }

    /// The `S` rate for this many bits per second, if there is one (other rates need the
    /// adapter's bit-timing registers, `s`, which differ between adapters).
    pub fn from_bits_per_second(bps: u32) -> Option<Bitrate> {
        Bitrate::ALL
            .into_iter()
            .find(|rate| rate.bits_per_second() == bps)
    }
}

/// A command from the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `Sn`: the bit rate (only while the channel is closed).
    SetBitrate(Bitrate),
    /// `O`: open the channel.
    Open,
    /// `C`: close the channel.
    Close,
    /// `Z0` / `Z1`: timestamps on received frames.
    Timestamps(bool),
    /// `t`, `T`, `r` or `R`: put a frame on the bus.
    Transmit(CanFrame),
}

impl Command {
    /// The bytes to write, CR included.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(MAX_LINE);
        match self {
            Command::SetBitrate(rate) => {
                out.push(b'S');
                out.push(b'0' + rate.code());
            }
            Command::Open => out.push(b'O'),
            Command::Close => out.push(b'C'),
            Command::Timestamps(on) => out.extend_from_slice(if *on { b"Z1" } else { b"Z0" }),
            Command::Transmit(frame) => write_frame(&mut out, frame),
        }
        out.push(CR);
        out
    }
}

/// `tiiil…`, `Tiiiiiiiil…`, `riiil`, `Riiiiiiiil` for a frame, without the CR.
fn write_frame(out: &mut Vec<u8>, frame: &CanFrame) {
    let (letter, id) = match (frame.id(), frame.is_remote()) {
        (CanId::Standard(id), false) => (b't', format!("{id:03X}")),
        (CanId::Standard(id), true) => (b'r', format!("{id:03X}")),
        (CanId::Extended(id), false) => (b'T', format!("{id:08X}")),
        (CanId::Extended(id), true) => (b'R', format!("{id:08X}")),
    };
    out.push(letter);
    out.extend_from_slice(id.as_bytes());
    out.push(b'0' + frame.dlc());
    for byte in frame.data() {
        out.extend_from_slice(format!("{byte:02X}").as_bytes());
    }
}

/// Something the adapter said.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Received {
    /// CR: the last command succeeded.
    Ok,
    /// BEL: the last command failed.
    Error,
    /// `z` CR or `Z` CR: a frame was queued for transmission.
    Transmitted {
        /// `Z`: it had an extended identifier.
        extended: bool,
    },
    /// A frame from the bus.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// Milliseconds, when the adapter's timestamps are on.
        timestamp_ms: Option<u16>,
    },
}

/// A line the decoder could not read. `line` is the line as received, escaped.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SlcanError {
    /// A line starting with a letter the adapter does not send.
    #[error("unknown reply {line:?}")]
    Unknown {
        /// The line.
        line: String,
    },
    /// A frame line too short to hold its identifier and DLC.
    #[error("truncated frame line {line:?}")]
    Truncated {
        /// The line.
        line: String,
    },
    /// A byte that should be a hex digit.
    #[error("{line:?}: byte {byte:?} at column {column} is not a hex digit")]
    Hex {
        /// The line.
        line: String,
        /// 0-based position in the line.
        column: usize,
        /// The byte, escaped.
        byte: String,
    },
    /// A DLC digit other than 0–8.
    #[error("{line:?}: DLC {byte:?} is not 0-8")]
    Dlc {
        /// The line.
        line: String,
        /// The byte, escaped.
        byte: String,
    },
    /// A frame line of the wrong length for its DLC.
    #[error("{line:?}: {found} characters, its DLC makes {expected} (or {} with a timestamp)", expected + 4)]
    Length {
        /// The line.
        line: String,
        /// Characters the DLC implies, without timestamp.
        expected: usize,
        /// Characters received.
        found: usize,
    },
    /// An identifier out of its width's range (`t800`, `T20000000`).
    #[error("{line:?}: {error}")]
    Id {
        /// The line.
        line: String,
        /// What is wrong with it.
        error: FrameError,
    },
    /// Bytes before a BEL that do not end in CR: a broken line.
    #[error("unterminated line {line:?} before BEL")]
    Unterminated {
        /// The bytes.
        line: String,
    },
    /// No CR within [`MAX_LINE`] bytes; the rest up to the next CR is skipped.
    #[error("line {start:?}… longer than {MAX_LINE} bytes without CR")]
    TooLong {
        /// The line's first bytes.
        start: String,
    },
}

fn escape(bytes: &[u8]) -> String {
    bytes.escape_ascii().to_string()
}

/// Reads the adapter's output as it arrives, in pieces of any size.
#[derive(Debug, Default, Clone)]
pub struct Decoder {
    line: Vec<u8>,
    /// Skipping an overlong line up to its CR.
    skipping: bool,
}

impl Decoder {
    /// A decoder at a line boundary.
    pub fn new() -> Decoder {
        Decoder::default()
    }

    /// Decodes `bytes`; returns what they completed, in order. A partial line waits for
    /// the next call.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<Result<Received, SlcanError>> {
        let mut out = Vec::new();
        for &byte in bytes {
            match byte {
                CR if self.skipping => self.skipping = false,
                CR => {
                    let line = std::mem::take(&mut self.line);
                    out.push(parse_line(&line));
                }
                BEL => {
                    if !self.line.is_empty() {
                        let line = std::mem::take(&mut self.line);
                        out.push(Err(SlcanError::Unterminated {
                            line: escape(&line),
                        }));
                    }
                    self.skipping = false;
                    out.push(Ok(Received::Error));
                }
                _ if self.skipping => {}
                _ => {
                    self.line.push(byte);
                    if self.line.len() > MAX_LINE {
                        let line = std::mem::take(&mut self.line);
                        out.push(Err(SlcanError::TooLong {
                            start: escape(&line),
                        }));
                        self.skipping = true;
                    }
                }
            }
        }
        out
    }
}

/// One line, CR removed.
fn parse_line(line: &[u8]) -> Result<Received, SlcanError> {
    match line {
        [] => Ok(Received::Ok),
        [b'z'] => Ok(Received::Transmitted { extended: false }),
        [b'Z'] => Ok(Received::Transmitted { extended: true }),
        [b't' | b'T' | b'r' | b'R', ..] => parse_frame(line),
        _ => Err(SlcanError::Unknown { line: escape(line) }),
    }
}

/// Reads hex digits `line[range]` as a number.
fn hex(line: &[u8], range: std::ops::Range<usize>) -> Result<u32, SlcanError> {
    let mut value = 0u32;
    for column in range {
        let byte = line[column];
        let digit = (byte as char).to_digit(16).ok_or_else(|| SlcanError::Hex {
            line: escape(line),
            column,
            byte: escape(&[byte]),
        })?;
        value = value << 4 | digit;
    }
    Ok(value)
}

fn parse_frame(line: &[u8]) -> Result<Received, SlcanError> {
    let extended = line[0].is_ascii_uppercase();
    let remote = matches!(line[0], b'r' | b'R');
    let id_digits = if extended { 8 } else { 3 };
    let dlc_at = 1 + id_digits;
    if line.len() <= dlc_at {
        return Err(SlcanError::Truncated { line: escape(line) });
    }
    let raw = hex(line, 1..dlc_at)?;
    let dlc = match line[dlc_at] {
        digit @ b'0'..=b'8' => digit - b'0',
        byte => {
            return Err(SlcanError::Dlc {
                line: escape(line),
                byte: escape(&[byte]),
            })
        }
    };
    let data_digits = if remote { 0 } else { 2 * usize::from(dlc) };
    let expected = dlc_at + 1 + data_digits;
    let timestamped = match line.len() {
        n if n == expected => false,
        n if n == expected + 4 => true,
        found => {
            return Err(SlcanError::Length {
                line: escape(line),
                expected,
                found,
            })
        }
    };
    let id_error = |error| SlcanError::Id {
        line: escape(line),
        error,
    };
    let id = if extended {
        CanId::extended(raw).map_err(id_error)?
    } else {
        // Three hex digits are at most 0xFFF, so the narrowing is exact.
        CanId::standard(raw as u16).map_err(id_error)?
    };
    let frame = if remote {
        CanFrame::remote(id, dlc)
    } else {
        let mut data = Vec::with_capacity(usize::from(dlc));
        for k in 0..usize::from(dlc) {
            let at = dlc_at + 1 + 2 * k;
            data.push(hex(line, at..at + 2)? as u8);
        }
        CanFrame::new(id, &data)
    }
    // The DLC digit was checked to be 0–8, the only thing the constructors refuse here.
    .expect("DLC within 0-8");
    let timestamp_ms = if timestamped {
        Some(hex(line, expected..expected + 4)? as u16)
    } else {
        None
    };
    Ok(Received::Frame {
        frame,
        timestamp_ms,
    })
}

/// Shown as the adapter would write it, CR as `\r`.
impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&escape(&self.encode()))
    }
}

#[cfg(test)]
mod tests;
