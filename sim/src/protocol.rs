//! The serial side of the controller: which bytes are real-time commands, the RX buffer
//! that holds the rest, and the assembly of stored bytes into lines.
//!
//! This follows grblHAL's split (`protocol.c` of grblHAL/core): the serial interrupt picks
//! real-time bytes off the stream before they reach the buffer
//! (`protocol_enqueue_realtime_command`), and the main loop reads the buffer one byte at a
//! time into a line buffer, only while it is not blocked executing the previous line.

use std::collections::VecDeque;

/// Commands that act the moment their byte arrives, never stored and never answered with
/// `ok` (grbl `doc/markdown/realtime_cmds.md`, grblHAL `grbl.h`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realtime {
    /// 0x18 (ctrl-X): soft reset.
    Reset,
    /// `?`, 0x80 or 0x05: status report.
    StatusReport,
    /// 0x87: the complete status report, every optional field in it (grblHAL's
    /// `CMD_STATUS_REPORT_ALL`, `protocol.c`).
    CompleteStatusReport,
    /// 0x85: jog cancel. grblHAL empties the RX buffer (the line being read too) and, if
    /// jogging, stops the jog (`CMD_JOG_CANCEL` in `protocol.c`).
    JogCancel,
    /// `~` or 0x81: cycle start / resume.
    CycleStart,
    /// `!` or 0x82: feed hold.
    FeedHold,
    /// 0x83: parser state report (`[GC:…]`).
    ParserStateReport,
    /// 0x90–0x94: feed override reset, +10 %, −10 %, +1 %, −1 %.
    FeedOverride(OverrideStep),
    /// 0x95–0x97: rapid override 100 %, 50 %, 25 %.
    RapidOverride(u8),
    /// 0x99–0x9D: spindle override reset, +10 %, −10 %, +1 %, −1 %.
    SpindleOverride(OverrideStep),
}

/// One step of a feed or spindle override.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverrideStep {
    /// Back to 100 %.
    Reset,
    /// Add this many percent (negative: subtract).
    By(i8),
}

impl OverrideStep {
    /// The new percentage, within `min..=max`.
    pub fn apply(self, current: u8, min: u8, max: u8) -> u8 {
        let next = match self {
            OverrideStep::Reset => 100,
            OverrideStep::By(delta) => i16::from(current) + i16::from(delta),
        };
        // The clamp keeps the value within 10..=200, so the narrowing cannot lose anything.
        next.clamp(i16::from(min), i16::from(max)) as u8
    }
}

/// What the serial interrupt does with one byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ByteClass {
    /// A real-time command: acted on now, not stored.
    Realtime(Realtime),
    /// A byte of a line (printable ASCII, `\n`, `\r`): stored in the RX buffer.
    Stored,
    /// Thrown away unseen: other control characters, DEL, and top-bit-set bytes with no
    /// real-time meaning (grblHAL drops them in the interrupt).
    Dropped,
}

/// Classifies a received byte the way grblHAL's interrupt does with `$39=1` (legacy
/// real-time characters enabled, the default), so `?`, `!` and `~` are real-time even
/// inside comments and `$` lines.
pub fn classify(byte: u8) -> ByteClass {
    use ByteClass::{Dropped, Realtime as Rt, Stored};
    match byte {
        b'\n' | b'\r' => Stored,
        0x18 => Rt(Realtime::Reset),
        b'?' | 0x80 | 0x05 => Rt(Realtime::StatusReport),
        0x87 => Rt(Realtime::CompleteStatusReport),
        0x85 => Rt(Realtime::JogCancel),
        b'~' | 0x81 => Rt(Realtime::CycleStart),
        b'!' | 0x82 => Rt(Realtime::FeedHold),
        0x83 => Rt(Realtime::ParserStateReport),
        0x90 => Rt(Realtime::FeedOverride(OverrideStep::Reset)),
        0x91 => Rt(Realtime::FeedOverride(OverrideStep::By(10))),
        0x92 => Rt(Realtime::FeedOverride(OverrideStep::By(-10))),
        0x93 => Rt(Realtime::FeedOverride(OverrideStep::By(1))),
        0x94 => Rt(Realtime::FeedOverride(OverrideStep::By(-1))),
        0x95 => Rt(Realtime::RapidOverride(100)),
        0x96 => Rt(Realtime::RapidOverride(50)),
        0x97 => Rt(Realtime::RapidOverride(25)),
        0x99 => Rt(Realtime::SpindleOverride(OverrideStep::Reset)),
        0x9A => Rt(Realtime::SpindleOverride(OverrideStep::By(10))),
        0x9B => Rt(Realtime::SpindleOverride(OverrideStep::By(-10))),
        0x9C => Rt(Realtime::SpindleOverride(OverrideStep::By(1))),
        0x9D => Rt(Realtime::SpindleOverride(OverrideStep::By(-1))),
        0x20..=0x7E => Stored,
        _ => Dropped,
    }
}

/// An entry of the RX buffer. Bytes that did not fit are remembered as zero-size marks, so
/// that the line they belonged to can be refused instead of run damaged, and a lost line
/// end still ends a line (each line sent gets exactly one answer, even after an overflow).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RxItem {
    /// A stored byte.
    Byte(u8),
    /// One or more bytes other than line ends were dropped here.
    Lost,
    /// A line end (`\n` or `\r`) was dropped here.
    LostEnd(u8),
}

/// The serial receive buffer: a ring of `size` bytes that, like grblHAL's drivers, keeps
/// one slot empty, so it holds `size − 1` bytes and reports `size − 1 − used` free.
#[derive(Debug, Clone)]
pub struct RxBuffer {
    items: VecDeque<RxItem>,
    used: usize,
    capacity: usize,
}

impl RxBuffer {
    /// A buffer of `size` bytes (the number `$I` reports); it holds `size − 1`.
    pub fn new(size: usize) -> RxBuffer {
        RxBuffer {
            items: VecDeque::new(),
            used: 0,
            capacity: size.saturating_sub(1),
        }
    }

    /// Stores a byte; `false` if the buffer was full and the byte was dropped (an
    /// overflow: the sender did not count characters).
    pub fn push(&mut self, byte: u8) -> bool {
        if self.used < self.capacity {
            self.items.push_back(RxItem::Byte(byte));
            self.used += 1;
            return true;
        }
        let mark = if byte == b'\n' || byte == b'\r' {
            RxItem::LostEnd(byte)
        } else {
            RxItem::Lost
        };
        // Runs of dropped bytes within a line collapse into one mark.
        if !(mark == RxItem::Lost && self.items.back() == Some(&RxItem::Lost)) {
            self.items.push_back(mark);
        }
        false
    }

    /// Takes the oldest entry (the main loop reading the buffer).
    pub fn pop(&mut self) -> Option<RxItem> {
        let item = self.items.pop_front()?;
        if let RxItem::Byte(_) = item {
            self.used -= 1;
        }
        Some(item)
    }

    /// Bytes free, as the status report's `Bf:` shows them.
    pub fn free(&self) -> usize {
        self.capacity - self.used
    }

    /// Bytes stored.
    pub fn used(&self) -> usize {
        self.used
    }

    /// Empties the buffer (soft reset).
    pub fn clear(&mut self) {
        self.items.clear();
        self.used = 0;
    }
}

/// A complete line from the line assembler.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Line {
    /// The stored characters: leading spaces and control characters removed, everything
    /// else as received (comments and case are the interpreter's business).
    pub text: String,
    /// The line lost characters: longer than the line buffer, or bytes dropped by an RX
    /// overflow. Answered `error:11` without being looked at.
    pub overflow: bool,
}

/// Gathers stored bytes into lines, as grblHAL's main loop does (`protocol_main_loop`):
/// `\n` or `\r` ends a line, the second byte of a `\r\n` or `\n\r` pair is ignored,
/// leading spaces are skipped, and characters past the line buffer set the overflow flag.
#[derive(Debug, Clone)]
pub struct LineAssembler {
    text: String,
    overflow: bool,
    last_end: Option<u8>,
    max_len: usize,
}

impl LineAssembler {
    /// An assembler whose line buffer holds `max_len` characters (grblHAL: 256).
    pub fn new(max_len: usize) -> LineAssembler {
        LineAssembler {
            text: String::new(),
            overflow: false,
            last_end: None,
            max_len,
        }
    }

    /// Feeds one RX entry; returns the line it completes, if any.
    pub fn push(&mut self, item: RxItem) -> Option<Line> {
        match item {
            RxItem::Byte(byte @ (b'\n' | b'\r')) => self.end(byte, false),
            RxItem::LostEnd(byte) => self.end(byte, true),
            RxItem::Lost => {
                self.overflow = true;
                None
            }
            RxItem::Byte(byte) => {
                // Only printable ASCII reaches the buffer (see `classify`); a leading
                // space is skipped like grblHAL's leading whitespace.
                if byte == b' ' && self.text.is_empty() {
                    return None;
                }
                if self.text.len() >= self.max_len {
                    self.overflow = true;
                } else {
                    self.text.push(char::from(byte));
                }
                None
            }
        }
    }

    fn end(&mut self, byte: u8, lost: bool) -> Option<Line> {
        let pair_half = self.text.is_empty()
            && !self.overflow
            && self.last_end.is_some_and(|last| last != byte);
        if pair_half {
            // The second half of CR LF (or LF CR) is not a second, empty line.
            self.last_end = None;
            return None;
        }
        self.last_end = Some(byte);
        let line = Line {
            text: std::mem::take(&mut self.text),
            overflow: self.overflow || lost,
        };
        self.overflow = false;
        Some(line)
    }

    /// Forgets the partial line (soft reset).
    pub fn clear(&mut self) {
        self.text.clear();
        self.overflow = false;
        self.last_end = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(bytes: &[u8], max_len: usize) -> Vec<Line> {
        let mut assembler = LineAssembler::new(max_len);
        bytes
            .iter()
            .filter_map(|&b| assembler.push(RxItem::Byte(b)))
            .collect()
    }

    #[test]
    fn line_ends_and_pairs() {
        // grblHAL: \n or \r end a line; CR LF and LF CR are one end; CR CR is two.
        let texts = |bytes: &[u8]| -> Vec<String> {
            lines(bytes, 256).into_iter().map(|l| l.text).collect()
        };
        assert_eq!(texts(b"G0 X1\nG0 X2\r"), ["G0 X1", "G0 X2"]);
        assert_eq!(texts(b"A\r\nB\n\rC\r\n"), ["A", "B", "C"]);
        assert_eq!(texts(b"\r\n\r\n"), ["", ""]);
        assert_eq!(texts(b"\r\r"), ["", ""]);
        assert_eq!(texts(b"   G1 X1 \n"), ["G1 X1 "]);
    }

    #[test]
    fn long_lines_overflow() {
        let ok = lines(&[b"G".as_slice(), &[b'0'; 255], b"\n"].concat(), 256);
        assert!(!ok[0].overflow);
        let long = lines(&[b"G".as_slice(), &[b'0'; 256], b"\nX\n"].concat(), 256);
        assert!(long[0].overflow);
        assert_eq!(long[0].text.len(), 256);
        // The flag does not leak into the next line.
        assert!(!long[1].overflow);
    }

    #[test]
    fn realtime_bytes_are_never_stored() {
        for byte in [
            b'?', b'!', b'~', 0x18, 0x80, 0x81, 0x82, 0x85, 0x90, 0x9E, 0xFF,
        ] {
            assert_ne!(classify(byte), ByteClass::Stored, "{byte:#x}");
        }
        assert_eq!(classify(b'\t'), ByteClass::Dropped);
        assert_eq!(classify(0x7F), ByteClass::Dropped);
        assert_eq!(classify(b'G'), ByteClass::Stored);
        assert_eq!(
            classify(0x91),
            ByteClass::Realtime(Realtime::FeedOverride(OverrideStep::By(10)))
        );
    }

    #[test]
    fn ring_keeps_one_slot_free_and_marks_losses() {
        let mut rx = RxBuffer::new(4);
        assert_eq!(rx.free(), 3);
        assert!(rx.push(b'A') && rx.push(b'B') && rx.push(b'C'));
        assert!(!rx.push(b'D'));
        assert!(!rx.push(b'E'));
        assert!(!rx.push(b'\n'));
        assert_eq!(rx.free(), 0);
        let mut assembler = LineAssembler::new(256);
        let mut out = Vec::new();
        while let Some(item) = rx.pop() {
            out.extend(assembler.push(item));
        }
        assert_eq!(
            out,
            [Line {
                text: "ABC".into(),
                overflow: true
            }]
        );
        assert_eq!(rx.free(), 3);
    }

    #[test]
    fn overrides_clamp() {
        assert_eq!(OverrideStep::By(10).apply(195, 10, 200), 200);
        assert_eq!(OverrideStep::By(-10).apply(15, 10, 200), 10);
        assert_eq!(OverrideStep::Reset.apply(40, 10, 200), 100);
    }
}
