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
mod tests {
    use super::*;

    fn opened() -> SlcanAdapter {
        let mut adapter = SlcanAdapter::new();
        adapter.receive(b"S6\rO\r");
        assert_eq!(adapter.take_output(), b"\r\r");
        adapter
    }

    #[test]
    fn setup_follows_the_channel_state() {
        let mut adapter = SlcanAdapter::new();
        // O before a bit rate; C while closed; S9 does not exist.
        adapter.receive(b"O\rC\rS9\r");
        assert_eq!(adapter.take_output(), b"\x07\x07\x07");
        adapter.receive(b"S4\r");
        assert_eq!(adapter.bitrate(), Some(125_000));
        adapter.receive(b"O\r");
        assert!(adapter.is_open());
        // No bit rate change and no second open while open.
        adapter.receive(b"S8\rO\r");
        assert_eq!(adapter.take_output(), b"\r\r\x07\x07");
        assert_eq!(adapter.bitrate(), Some(125_000));
        adapter.receive(b"C\r");
        assert!(!adapter.is_open());
        adapter.receive(b"S8\r");
        assert_eq!(adapter.bitrate(), Some(1_000_000));
        assert_eq!(adapter.take_output(), b"\r\r");
    }

    #[test]
    fn every_bitrate_code_is_lawicels() {
        let rates = [
            10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
        ];
        for (code, rate) in rates.into_iter().enumerate() {
            let mut adapter = SlcanAdapter::new();
            adapter.receive(format!("S{code}\r").as_bytes());
            assert_eq!(adapter.bitrate(), Some(rate));
        }
    }

    #[test]
    fn transmits_go_to_the_bus_and_are_acknowledged() {
        let mut adapter = opened();
        adapter.receive(b"t34580123456789ABCDEF\rt4560\rT1234567820123\rr0023\rR1FFFFFFF0\r");
        assert_eq!(adapter.take_output(), b"z\rz\rZ\rz\rZ\r");
        let frames = adapter.take_transmitted();
        assert_eq!(
            frames[0],
            Frame::data(0x345, &[0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF])
        );
        assert_eq!(frames[1], Frame::data(0x456, &[]));
        assert_eq!(
            frames[2],
            Frame {
                id: 0x1234_5678,
                extended: true,
                remote: false,
                dlc: 2,
                data: vec![0x01, 0x23]
            }
        );
        assert_eq!(
            frames[3],
            Frame {
                id: 2,
                extended: false,
                remote: true,
                dlc: 3,
                data: vec![]
            }
        );
        assert!(frames[4].remote && frames[4].extended && frames[4].id == 0x1FFF_FFFF);
        // Lower-case hex is taken too.
        adapter.receive(b"t7ff1ab\r");
        assert_eq!(adapter.take_transmitted(), [Frame::data(0x7FF, &[0xAB])]);
    }

    #[test]
    fn malformed_transmits_are_refused() {
        let mut adapter = opened();
        for bad in [
            "t12",         // no DLC
            "t12G0",       // bad id digit
            "t8000",       // id beyond 11 bits
            "T200000000",  // id beyond 29 bits
            "t1239",       // DLC 9
            "t1232AA",     // data shorter than DLC
            "t1231AABB",   // data longer than DLC
            "t1231AX",     // bad data digit
            "r12310",      // a remote request with data
            "t123\u{e9}0", // not ASCII
        ] {
            adapter.receive(format!("{bad}\r").as_bytes());
            assert_eq!(adapter.take_output(), b"\x07", "{bad}");
        }
        assert!(adapter.take_transmitted().is_empty());
        // And every transmit while closed.
        let mut closed = SlcanAdapter::new();
        closed.receive(b"S6\rt1230\r");
        assert_eq!(closed.take_output(), b"\r\x07");
    }

    #[test]
    fn unknown_empty_and_overlong_commands_get_bel() {
        let mut adapter = opened();
        adapter.receive(b"\rX\rZ2\r");
        assert_eq!(adapter.take_output(), b"\x07\x07\x07");
        let mut long = vec![b'T'; LONGEST_COMMAND + 5];
        long.extend_from_slice(b"\rt1230\r");
        adapter.receive(&long);
        assert_eq!(adapter.take_output(), b"\x07z\r");
        // The longest legal command still fits.
        adapter.receive(b"T1FFFFFFF80011223344556677\r");
        assert_eq!(adapter.take_output(), b"Z\r");
    }

    #[test]
    fn commands_split_anywhere_act_the_same() {
        let stream = b"S6\rO\rt1232AABB\rC\r";
        for cut in 0..stream.len() {
            let mut adapter = SlcanAdapter::new();
            adapter.receive(&stream[..cut]);
            adapter.receive(&stream[cut..]);
            assert_eq!(adapter.take_output(), b"\r\rz\r\r", "cut at {cut}");
            assert_eq!(
                adapter.take_transmitted(),
                [Frame::data(0x123, &[0xAA, 0xBB])]
            );
        }
    }

    #[test]
    fn bus_frames_reach_the_host_only_while_open() {
        let mut adapter = SlcanAdapter::new();
        adapter.deliver(&Frame::data(0x701, &[0x00]));
        assert!(adapter.take_output().is_empty());
        adapter.receive(b"S8\rO\r");
        adapter.take_output();
        adapter.deliver(&Frame::data(0x701, &[0x00]));
        adapter.deliver(&Frame {
            id: 0x1234,
            extended: true,
            remote: false,
            dlc: 1,
            data: vec![0xFE],
        });
        adapter.deliver(&Frame {
            id: 0x701,
            extended: false,
            remote: true,
            dlc: 1,
            data: vec![],
        });
        // Impossible frames are not written.
        adapter.deliver(&Frame::data(0x800, &[]));
        adapter.deliver(&Frame::data(0x100, &[0; 9]));
        assert_eq!(adapter.take_output(), b"t701100\rT000012341FE\rr7011\r");
    }

    #[test]
    fn timestamps_are_milliseconds_wrapping_each_minute() {
        let mut adapter = opened();
        adapter.receive(b"Z1\r");
        adapter.take_output();
        adapter.advance(Duration::from_millis(59_999));
        adapter.deliver(&Frame::data(0x181, &[]));
        adapter.advance(Duration::from_millis(2));
        adapter.deliver(&Frame::data(0x181, &[]));
        assert_eq!(adapter.take_output(), b"t1810EA5F\rt18100001\r");
        adapter.receive(b"Z0\r");
        adapter.deliver(&Frame::data(0x181, &[]));
        assert_eq!(adapter.take_output(), b"\rt1810\r");
    }
}
