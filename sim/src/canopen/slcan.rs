//! A Lawicel-protocol (slcan) USB-CAN adapter, as the host sees it over its serial port.
//!
//! Modelled on Lawicel's CANUSB manual (and the EasySYNC USB2-F-7x01 guide, which
//! documents the same command set): a command is ASCII up to CR; the adapter answers CR
//! for success and BEL (0x07) for failure, and a transmit with `z` CR (`t`, `r`) or `Z` CR
//! (`T`, `R`).
//!
//! - `S0`–`S8` set the bit rate, only while the channel is closed.
//! - `O` opens the channel, only when closed and after a bit rate was set; `C` closes it,
//!   only when open.
//! - `t`/`T`/`r`/`R` transmit, only while open; the line must be exactly as long as its
//!   DLC says, with hex digits (either case) and an identifier within its width.
//! - `Z0`/`Z1` switch the timestamp on received frames (in either channel state, as the
//!   EasySYNC guide describes).
//! - Anything else, an empty line included, is answered BEL, as is a line longer than the
//!   longest command (BEL once, then the rest up to CR is dropped).
//!
//! Frames from the bus reach the host only while the channel is open, written in the
//! transmit syntax with upper-case hex and, with `Z1`, four hex digits of milliseconds
//! that wrap at 60000 (0xEA5F is the last). The adapter does not hear its own
//! transmissions, as a CAN controller does not.

use std::time::Duration;

use super::Frame;

/// The longest command: `T`, 8 id digits, DLC, 16 data digits.
const LONGEST_COMMAND: usize = 26;

/// The adapter: bytes from the host in, bytes to the host out, frames to and from the bus.
#[derive(Debug, Clone, Default)]
pub struct SlcanAdapter {
    /// The `S` code set, if any.
    bitrate: Option<u8>,
    open: bool,
    timestamps: bool,
    command: Vec<u8>,
    /// Dropping an overlong command up to its CR.
    dropping: bool,
    to_host: Vec<u8>,
    to_bus: Vec<Frame>,
    clock: Duration,
}

impl SlcanAdapter {
    /// Powered up: channel closed, no bit rate, timestamps off.
    pub fn new() -> SlcanAdapter {
        SlcanAdapter::default()
    }

    /// Whether the channel is open.
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// The bit rate set with `S`, in bits per second.
    pub fn bitrate(&self) -> Option<u32> {
        const RATES: [u32; 9] = [
            10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ];
        self.bitrate.map(|code| RATES[usize::from(code)])
    }

    /// Lets simulated time pass (the timestamp counter).
    pub fn advance(&mut self, dt: Duration) {
        self.clock += dt;
    }

    /// Bytes from the host.
    pub fn receive(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            if byte == b'\r' {
                if !std::mem::take(&mut self.dropping) {
                    let command = std::mem::take(&mut self.command);
                    self.execute(&command);
                }
            } else if !self.dropping {
                self.command.push(byte);
                if self.command.len() > LONGEST_COMMAND {
                    self.command.clear();
                    self.dropping = true;
                    self.to_host.push(0x07);
                }
            }
        }
    }

    fn execute(&mut self, command: &[u8]) {
        let reply: &[u8] = match command {
            [b'S', digit @ b'0'..=b'8'] if !self.open => {
                self.bitrate = Some(digit - b'0');
                b"\r"
            }
            [b'O'] if !self.open && self.bitrate.is_some() => {
                self.open = true;
                b"\r"
            }
            [b'C'] if self.open => {
                self.open = false;
                b"\r"
            }
            [b'Z', flag @ (b'0' | b'1')] => {
                self.timestamps = *flag == b'1';
                b"\r"
            }
            [kind @ (b't' | b'T' | b'r' | b'R'), rest @ ..] if self.open => {
                match parse_transmit(*kind, rest) {
                    Some(frame) => {
                        self.to_bus.push(frame);
                        if kind.is_ascii_lowercase() {
                            b"z\r"
                        } else {
                            b"Z\r"
                        }
                    }
                    None => b"\x07",
                }
            }
            _ => b"\x07",
        };
        self.to_host.extend_from_slice(reply);
    }

    /// Bytes for the host since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.to_host)
    }

    /// Frames the host put on the bus since the last call.
    pub fn take_transmitted(&mut self) -> Vec<Frame> {
        std::mem::take(&mut self.to_bus)
    }

    /// A frame on the bus: written to the host if the channel is open. Frames that could
    /// not be on a bus (more than 8 bytes, an identifier too wide) are not written.
    pub fn deliver(&mut self, frame: &Frame) {
        let max_id = if frame.extended { 0x1FFF_FFFF } else { 0x7FF };
        if !self.open || frame.id > max_id || frame.dlc > 8 || frame.data.len() > 8 {
            return;
        }
        let mut line = match (frame.extended, frame.remote) {
            (false, false) => format!("t{:03X}", frame.id),
            (false, true) => format!("r{:03X}", frame.id),
            (true, false) => format!("T{:08X}", frame.id),
            (true, true) => format!("R{:08X}", frame.id),
        };
        if frame.remote {
            line.push_str(&frame.dlc.to_string());
        } else {
            line.push_str(&frame.data.len().to_string());
            for byte in &frame.data {
                line.push_str(&format!("{byte:02X}"));
            }
        }
        if self.timestamps {
            line.push_str(&format!("{:04X}", self.clock.as_millis() % 60_000));
        }
        line.push('\r');
        self.to_host.extend_from_slice(line.as_bytes());
    }
}

/// The frame a transmit command describes (after its letter), or `None` if the command
/// is malformed.
fn parse_transmit(kind: u8, rest: &[u8]) -> Option<Frame> {
    let extended = kind.is_ascii_uppercase();
    let remote = kind.eq_ignore_ascii_case(&b'r');
    let id_len = if extended { 8 } else { 3 };
    let text = std::str::from_utf8(rest).ok()?;
    let id_text = text.get(..id_len)?;
    if !id_text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let id = u32::from_str_radix(id_text, 16).ok()?;
    if id > if extended { 0x1FFF_FFFF } else { 0x7FF } {
        return None;
    }
    let dlc = text.get(id_len..id_len + 1)?.parse::<u8>().ok()?;
    if dlc > 8 {
        return None;
    }
    let payload = &text[id_len + 1..];
    let data_len = if remote { 0 } else { 2 * usize::from(dlc) };
    if payload.len() != data_len || !payload.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let data = (0..data_len / 2)
        .map(|k| u8::from_str_radix(&payload[2 * k..2 * k + 2], 16))
        .collect::<Result<Vec<u8>, _>>()
        .ok()?;
    Some(Frame {
        id,
        extended,
        remote,
        dlc,
        data,
    })
}

#[cfg(test)]
mod tests;
