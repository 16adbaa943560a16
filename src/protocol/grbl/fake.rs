//! A model controller for the streamer's tests, written from grbl's documented protocol
//! (interface document; grblHAL's `protocol.c` for the sticky error): a receive buffer of
//! fixed capacity that is really enforced, one `ok`/`error:N` per line in order, `$I`
//! with `[VER:]`/`[OPT:]`, real-time bytes taken off the stream before the buffer, and
//! optionally grblHAL's sticky error (after `error:N`, every G-code line gets the same
//! error until an empty line, a successful `$` command or a soft reset).

use std::collections::VecDeque;

pub(crate) struct Fake {
    /// Bytes the receive buffer holds (a ring buffer of N holds N − 1).
    pub capacity: usize,
    rx: VecDeque<u8>,
    /// A byte arrived with the buffer full.
    pub overflowed: bool,
    /// The fullest the buffer has been.
    pub max_fill: usize,
    pub sticky: bool,
    last_error: u16,
    /// Lines refused with a code, by exact text.
    pub fail: Vec<(String, u16)>,
    /// The body of `[OPT:…]`, if `$I` is supported.
    pub opt: Option<String>,
    /// G-code lines executed (answered `ok`), in order; empty lines and `$` excluded.
    pub executed: Vec<String>,
    /// Real-time bytes seen, in order.
    pub realtime: Vec<u8>,
    /// What `?` answers.
    pub status: String,
    out: Vec<u8>,
}

impl Fake {
    /// grblHAL: sticky errors, `$I` reporting `rx_size`.
    pub fn grblhal(rx_size: usize) -> Fake {
        Fake {
            capacity: rx_size - 1,
            rx: VecDeque::new(),
            overflowed: false,
            max_fill: 0,
            sticky: true,
            last_error: 0,
            fail: Vec::new(),
            opt: Some(format!("VNMSL,35,{rx_size},4,0")),
            executed: Vec::new(),
            realtime: Vec::new(),
            status: "<Idle|MPos:0.000,0.000,0.000,0.000|Bf:35,1023|FS:0,0>".into(),
            out: Vec::new(),
        }
    }

    /// grbl 1.1: no sticky error.
    pub fn grbl(rx_size: usize) -> Fake {
        Fake {
            sticky: false,
            opt: Some(format!("V,15,{rx_size}")),
            ..Fake::grblhal(rx_size)
        }
    }

    /// Bytes from the host.
    pub fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            match byte {
                b'?' => {
                    self.realtime.push(byte);
                    let status = format!("{}\r\n", self.status);
                    self.out.extend_from_slice(status.as_bytes());
                }
                b'!' | b'~' => self.realtime.push(byte),
                0x18 => {
                    self.realtime.push(byte);
                    self.rx.clear();
                    self.last_error = 0;
                    self.out
                        .extend_from_slice(b"GrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
                }
                _ if self.rx.len() >= self.capacity => self.overflowed = true,
                _ => {
                    self.rx.push_back(byte);
                    self.max_fill = self.max_fill.max(self.rx.len());
                }
            }
        }
    }

    /// Bytes in the receive buffer.
    pub fn buffered(&self) -> usize {
        self.rx.len()
    }

    /// Reads and answers one line, if a whole one is buffered.
    pub fn process(&mut self) -> bool {
        let Some(end) = self.rx.iter().position(|&b| b == b'\n') else {
            return false;
        };
        let bytes: Vec<u8> = self.rx.drain(..=end).collect();
        let line = String::from_utf8_lossy(&bytes[..end]).trim().to_owned();
        let answer = if line.is_empty() {
            self.last_error = 0;
            0
        } else if line == "$I" {
            self.out.extend_from_slice(b"[VER:1.1f.20250102:]\r\n");
            if let Some(opt) = &self.opt {
                self.out
                    .extend_from_slice(format!("[OPT:{opt}]\r\n").as_bytes());
            }
            self.last_error = 0;
            0
        } else if self.sticky && self.last_error != 0 {
            self.last_error
        } else if let Some(&(_, code)) = self.fail.iter().find(|(text, _)| *text == line) {
            self.last_error = code;
            code
        } else {
            self.executed.push(line);
            0
        };
        let response = match answer {
            0 => "ok\r\n".to_owned(),
            code => format!("error:{code}\r\n"),
        };
        self.out.extend_from_slice(response.as_bytes());
        true
    }

    /// Answers every whole line buffered.
    pub fn process_all(&mut self) {
        while self.process() {}
    }

    /// What the controller has written since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }
}
