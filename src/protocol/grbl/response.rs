//! Controller output, one line at a time: bytes → lines ([`LineBuffer`]) → [`Response`]s.
//!
//! grbl 1.1 and grblHAL end every output line with `\r\n`; a line is one of grbl's
//! documented message kinds (grbl's `doc/markdown/interface.md`, "Message Summary"):
//! the two *response messages* `ok` and `error:N`, which answer exactly one line the
//! host sent and are what the character-counting stream pairs, and *push messages*
//! that may come at any time and answer nothing: status reports `<…>`, `ALARM:N`,
//! feedback `[…]`, the welcome banner `Grbl …`, startup-line results `>…:ok` (which
//! carry their `ok` on the same line precisely so that a stream does not count it) and
//! settings `$N=…`.
//!
//! Parsing never fails: a line that is none of the known kinds, or a known kind with a
//! malformed body, becomes [`Response::Other`] (or keeps the malformed field in
//! [`Status::other`]), so garbage on the line can never panic the streamer nor be taken
//! for an `ok`.

use serde::{Deserialize, Serialize};

/// The longest line [`LineBuffer`] keeps, in bytes. grbl's longest outputs (a status
/// report with every field of a six-axis grblHAL, a `[VER:…]` line with its user string)
/// stay far below this; anything longer is line noise, and the bound keeps a
/// controller that never sends a line end from growing the buffer without limit.
pub const MAX_LINE_BYTES: usize = 1024;

/// Splits the bytes read from the controller into lines.
///
/// A line ends at `\n` or `\r`, so `\r\n` (grbl), `\n` and a lone `\r` all work; the
/// empty "line" between `\r` and `\n` is dropped, as are blank lines (grbl never sends
/// one that means anything). A line may arrive split over any number of reads. Bytes past
/// [`MAX_LINE_BYTES`] of one line are dropped; the truncated line is still delivered
/// when its end arrives, and parses as whatever its first bytes say (a truncated status
/// report, for instance, lacks its `>` and becomes [`Response::Other`]). Invalid UTF-8 is
/// replaced, never rejected.
#[derive(Debug, Clone, Default)]
pub struct LineBuffer {
    partial: Vec<u8>,
}

impl LineBuffer {
    /// An empty buffer.
    pub fn new() -> LineBuffer {
        LineBuffer::default()
    }

    /// Adds `bytes` and returns the lines they complete, in order, without line ends.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<String> {
        let mut lines = Vec::new();
        for &byte in bytes {
            if byte == b'\n' || byte == b'\r' {
                if !self.partial.is_empty() {
                    lines.push(String::from_utf8_lossy(&self.partial).into_owned());
                    self.partial.clear();
                }
            } else if self.partial.len() < MAX_LINE_BYTES {
                self.partial.push(byte);
            }
        }
        lines
    }

    /// Bytes of an unfinished line held so far.
    pub fn pending(&self) -> usize {
        self.partial.len()
    }
}

/// One line of controller output, classified.
#[derive(Debug, Clone, PartialEq)]
pub enum Response {
    /// `ok`: the oldest unanswered line was parsed and executed or queued for execution.
    Ok,
    /// `error:N`: the oldest unanswered line was refused and nothing in it was executed.
    /// A non-numeric code (grbl before 1.1 wrote a text) is 0, so the line still answers
    /// its line and the pairing stays right.
    Error(u16),
    /// `ALARM:N`: the controller stopped motion and locked out G-code.
    Alarm(u16),
    /// `<…>`: a real-time status report.
    Status(Status),
    /// `[MSG:…]`: a feedback message, its text.
    Message(String),
    /// `[VER:…]`: build version (from `$I`), the text after `VER:`.
    Version(String),
    /// `[OPT:…]`: build options (from `$I`).
    Options(BuildOptions),
    /// Any other `[…]` feedback (`[GC:…]`, `[HLP:…]`, `[echo:…]`, grblHAL's `[NEWOPT:…]`
    /// …), the text between the brackets.
    Feedback(String),
    /// `Grbl …` or `GrblHAL …`: the welcome banner, printed at power-up and after every
    /// reset, which flushes the controller's buffers.
    Banner(String),
    /// `>…`: the result of a startup line (`>G54:ok`); it answers no line the host sent.
    StartupLine(String),
    /// `$…`: a setting printed by `$$` or `$N`.
    Setting(String),
    /// Anything else, as received.
    Other(String),
}

/// Parses one line of controller output (without its line end); never fails.
pub fn parse_response(line: &str) -> Response {
    let line = line.trim();
    if line == "ok" {
        return Response::Ok;
    }
    if let Some(code) = line.strip_prefix("error:") {
        return Response::Error(code.trim().parse().unwrap_or(0));
    }
    if let Some(code) = line.strip_prefix("ALARM:") {
        return Response::Alarm(code.trim().parse().unwrap_or(0));
    }
    if let Some(body) = line.strip_prefix('<').and_then(|l| l.strip_suffix('>')) {
        return match parse_status(body) {
            Some(status) => Response::Status(status),
            None => Response::Other(line.to_owned()),
        };
    }
    if let Some(body) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
        if let Some(text) = body.strip_prefix("MSG:") {
            return Response::Message(text.to_owned());
        }
        if let Some(text) = body.strip_prefix("VER:") {
            return Response::Version(text.to_owned());
        }
        if let Some(text) = body.strip_prefix("OPT:") {
            return Response::Options(BuildOptions::parse(text));
        }
        return Response::Feedback(body.to_owned());
    }
    if line.starts_with("Grbl") {
        return Response::Banner(line.to_owned());
    }
    if line.starts_with('>') {
        return Response::StartupLine(line.to_owned());
    }
    if line.starts_with('$') {
        return Response::Setting(line.to_owned());
    }
    Response::Other(line.to_owned())
}

/// The `[OPT:codes,blocks,rx_bytes,…]` line of `$I`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct BuildOptions {
    /// The option letters (`V` variable spindle, `N` line numbers, …).
    pub codes: String,
    /// Usable planner blocks.
    pub blocks: Option<u32>,
    /// Serial receive buffer size in bytes: the budget of character counting.
    pub rx_bytes: Option<u32>,
    /// Further fields grblHAL appends (axis count, tool table size, …), as written.
    pub extra: Vec<String>,
}

impl BuildOptions {
    /// Parses the text after `OPT:`; a field that is not a number is `None`.
    pub fn parse(text: &str) -> BuildOptions {
        let mut fields = text.split(',');
        let codes = fields.next().unwrap_or_default().to_owned();
        let blocks = fields.next().and_then(|f| f.trim().parse().ok());
        let rx_bytes = fields.next().and_then(|f| f.trim().parse().ok());
        BuildOptions {
            codes,
            blocks,
            rx_bytes,
            extra: fields.map(str::to_owned).collect(),
        }
    }
}

/// The machine state, the first field of a status report.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum MachineState {
    /// Idle: no motion queued or running (see [`Status::planner_empty`] for the caveat).
    Idle,
    /// Running a motion.
    Run,
    /// Feed hold (substate 0: complete, ready to resume; 1: decelerating).
    Hold,
    /// Jogging.
    Jog,
    /// Alarm: G-code locked out until `$X`, `$H` or a reset.
    Alarm,
    /// Safety door.
    Door,
    /// Check mode (`$C`): G-code parsed but not executed.
    Check,
    /// Homing.
    Home,
    /// Sleep.
    Sleep,
    /// grblHAL: waiting for a manual tool change.
    Tool,
    /// A state this parser does not know, as written.
    Other(String),
}

impl MachineState {
    fn parse(name: &str) -> MachineState {
        match name {
            "Idle" => MachineState::Idle,
            "Run" => MachineState::Run,
            "Hold" => MachineState::Hold,
            "Jog" => MachineState::Jog,
            "Alarm" => MachineState::Alarm,
            "Door" => MachineState::Door,
            "Check" => MachineState::Check,
            "Home" => MachineState::Home,
            "Sleep" => MachineState::Sleep,
            "Tool" => MachineState::Tool,
            other => MachineState::Other(other.to_owned()),
        }
    }
}

/// The `Bf:` field: free space in the controller's buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BufferState {
    /// Free planner blocks.
    pub planner_blocks_free: u32,
    /// Free bytes in the serial receive buffer. grbl's documentation warns against
    /// streaming by it (it is stale by the time it arrives); the streamer counts instead.
    pub rx_bytes_free: u32,
}

/// A real-time status report, `<State|MPos:…|…>`.
///
/// Positions are as the controller reports them (mm, or inches with `$13=1`), one value
/// per configured axis in the controller's order (X Y Z, then A B C on grblHAL builds
/// that have them). grbl sends either `MPos` or `WPos` (setting `$10`) and `WCO` only
/// now and then (every 10–30 reports and when it changes), with `WPos = MPos − WCO`:
/// keep the last `WCO` seen ([`crate::protocol::grbl::Streamer::last_wco`]) and use
/// [`Status::machine_position`] / [`Status::work_position`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// The machine state.
    pub state: MachineState,
    /// The state's substate (`Hold:0`, `Door:1`), if given.
    pub substate: Option<u8>,
    /// `MPos:`, machine position.
    pub mpos: Option<Vec<f64>>,
    /// `WPos:`, work position.
    pub wpos: Option<Vec<f64>>,
    /// `WCO:`, work coordinate offset (coordinate system + G92 + tool length offset).
    pub wco: Option<Vec<f64>>,
    /// `Bf:`, buffer state.
    pub buffer: Option<BufferState>,
    /// `Ln:`, the N number of the block executing now (only for lines that carry one).
    pub line: Option<u32>,
    /// Current feed rate, from `FS:` or `F:`.
    pub feed: Option<f64>,
    /// Current spindle speed, rpm, from `FS:`.
    pub spindle_rpm: Option<f64>,
    /// Fields not parsed here (`Pn:`, `Ov:`, `A:`, …) or malformed, as written.
    pub other: Vec<String>,
}

impl Status {
    /// The machine position: `MPos` if reported, else `WPos + wco`; `None` if neither
    /// can be had or the vectors differ in length.
    pub fn machine_position(&self, wco: Option<&[f64]>) -> Option<Vec<f64>> {
        self.mpos
            .clone()
            .or_else(|| combine(self.wpos.as_deref()?, wco?, 1.0))
    }

    /// The work position: `WPos` if reported, else `MPos − wco`.
    pub fn work_position(&self, wco: Option<&[f64]>) -> Option<Vec<f64>> {
        self.wpos
            .clone()
            .or_else(|| combine(self.mpos.as_deref()?, wco?, -1.0))
    }

    /// The report proves the planner empty: `Idle` with every one of `planner_blocks`
    /// blocks free. `Idle` alone does not: grbl answers a `?` before it starts the cycle
    /// of blocks it has just planned, so a report can say `Idle` with moves still queued.
    pub fn planner_empty(&self, planner_blocks: u32) -> bool {
        self.state == MachineState::Idle
            && self
                .buffer
                .is_some_and(|b| b.planner_blocks_free >= planner_blocks)
    }
}

fn combine(a: &[f64], b: &[f64], sign: f64) -> Option<Vec<f64>> {
    (a.len() == b.len()).then(|| a.iter().zip(b).map(|(a, b)| a + sign * b).collect())
}

/// Parses the body of a status report (between `<` and `>`); `None` only if it is empty.
pub fn parse_status(body: &str) -> Option<Status> {
    let mut fields = body.split('|');
    let first = fields.next().filter(|f| !f.is_empty())?;
    let (name, substate) = match first.split_once(':') {
        Some((name, sub)) => (name, sub.trim().parse().ok()),
        None => (first, None),
    };
    let mut status = Status {
        state: MachineState::parse(name),
        substate,
        mpos: None,
        wpos: None,
        wco: None,
        buffer: None,
        line: None,
        feed: None,
        spindle_rpm: None,
        other: Vec::new(),
    };
    for field in fields {
        let parsed = field
            .split_once(':')
            .and_then(|(key, value)| status.take_field(key, value));
        if parsed.is_none() {
            status.other.push(field.to_owned());
        }
    }
    Some(status)
}

impl Status {
    /// Stores one `key:value` field; `None` if the key is not parsed here or the value
    /// is malformed.
    fn take_field(&mut self, key: &str, value: &str) -> Option<()> {
        match key {
            "MPos" => self.mpos = Some(numbers(value)?),
            "WPos" => self.wpos = Some(numbers(value)?),
            "WCO" => self.wco = Some(numbers(value)?),
            "Bf" => {
                let (blocks, rx) = value.split_once(',')?;
                self.buffer = Some(BufferState {
                    planner_blocks_free: blocks.trim().parse().ok()?,
                    rx_bytes_free: rx.trim().parse().ok()?,
                });
            }
            "Ln" => self.line = Some(value.trim().parse().ok()?),
            "FS" => {
                let values = numbers(value)?;
                self.feed = Some(*values.first()?);
                self.spindle_rpm = values.get(1).copied();
            }
            "F" => self.feed = Some(value.trim().parse().ok()?),
            _ => return None,
        }
        Some(())
    }
}

/// Comma-separated numbers; `None` if any is malformed.
fn numbers(text: &str) -> Option<Vec<f64>> {
    text.split(',').map(|v| v.trim().parse().ok()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn responses_and_push_messages_are_told_apart() {
        assert_eq!(parse_response("ok"), Response::Ok);
        assert_eq!(parse_response(" ok "), Response::Ok);
        assert_eq!(parse_response("error:20"), Response::Error(20));
        assert_eq!(parse_response("error: 9"), Response::Error(9));
        // grbl 0.9 wrote a text: still an answer, so pairing stays right.
        assert_eq!(
            parse_response("error: Expected command letter"),
            Response::Error(0)
        );
        assert_eq!(parse_response("ALARM:2"), Response::Alarm(2));
        assert_eq!(
            parse_response("[MSG:Reset to continue]"),
            Response::Message("Reset to continue".into())
        );
        assert_eq!(
            parse_response("[VER:1.1f.20170131:my lathe]"),
            Response::Version("1.1f.20170131:my lathe".into())
        );
        assert_eq!(
            parse_response("[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]"),
            Response::Feedback("GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0".into())
        );
        assert_eq!(
            parse_response("Grbl 1.1h ['$' for help]"),
            Response::Banner("Grbl 1.1h ['$' for help]".into())
        );
        assert_eq!(
            parse_response("GrblHAL 1.1f ['$' or '$HELP' for help]"),
            Response::Banner("GrblHAL 1.1f ['$' or '$HELP' for help]".into())
        );
        // A startup line's ":ok" must not be taken for a response.
        assert_eq!(
            parse_response(">G54G20:ok"),
            Response::StartupLine(">G54G20:ok".into())
        );
        assert_eq!(
            parse_response("$110=500.000"),
            Response::Setting("$110=500.000".into())
        );
        assert_eq!(parse_response("okay"), Response::Other("okay".into()));
        assert_eq!(parse_response("<>"), Response::Other("<>".into()));
    }

    #[test]
    fn build_options_give_planner_blocks_and_rx_size() {
        // grbl 1.1 (documented example) and grblHAL (which appends fields).
        assert_eq!(
            parse_response("[OPT:VL,16,128]"),
            Response::Options(BuildOptions {
                codes: "VL".into(),
                blocks: Some(16),
                rx_bytes: Some(128),
                extra: vec![],
            })
        );
        let Response::Options(hal) = parse_response("[OPT:VNMSL,35,1024,3,0]") else {
            panic!("not options");
        };
        assert_eq!((hal.blocks, hal.rx_bytes), (Some(35), Some(1024)));
        assert_eq!(hal.extra, vec!["3", "0"]);
        let odd = BuildOptions::parse("V");
        assert_eq!((odd.blocks, odd.rx_bytes), (None, None));
    }

    #[test]
    fn status_with_work_coordinate_offset() {
        // The example of grbl's interface document, with WCO as it appears every few reports.
        let Response::Status(s) =
            parse_response("<Idle|MPos:0.000,-10.000,5.000|FS:0,0|WCO:0.000,1.551,5.664>")
        else {
            panic!("not a status report");
        };
        assert_eq!(s.state, MachineState::Idle);
        assert_eq!(s.substate, None);
        assert_eq!(s.mpos, Some(vec![0.0, -10.0, 5.0]));
        assert_eq!(s.wco, Some(vec![0.0, 1.551, 5.664]));
        assert_eq!((s.feed, s.spindle_rpm), (Some(0.0), Some(0.0)));
        assert_eq!((s.line, s.buffer), (None, None));
        // WPos = MPos − WCO.
        let w = s.work_position(s.wco.as_deref()).unwrap();
        assert!((w[1] - (-11.551)).abs() < 1e-12 && (w[2] + 0.664).abs() < 1e-12);
        assert_eq!(s.machine_position(None), s.mpos);
    }

    #[test]
    fn status_without_wco_with_line_number_and_buffer() {
        let Response::Status(s) = parse_response(
            "<Run|WPos:1.5,0,-2.25,90|Bf:12,97|Ln:420|FS:500,3000|Ov:100,100,100|Pn:Z>",
        ) else {
            panic!("not a status report");
        };
        assert_eq!(s.state, MachineState::Run);
        assert_eq!(s.wpos, Some(vec![1.5, 0.0, -2.25, 90.0]));
        assert_eq!((&s.mpos, &s.wco), (&None, &None));
        assert_eq!(
            s.buffer,
            Some(BufferState {
                planner_blocks_free: 12,
                rx_bytes_free: 97
            })
        );
        assert_eq!(s.line, Some(420));
        assert_eq!((s.feed, s.spindle_rpm), (Some(500.0), Some(3000.0)));
        assert_eq!(s.other, vec!["Ov:100,100,100", "Pn:Z"]);
        // Without a WCO the other position is unknown; with one it follows.
        assert_eq!(s.machine_position(None), None);
        assert_eq!(
            s.machine_position(Some(&[1.0, 0.0, 1.0, 0.0])),
            Some(vec![2.5, 0.0, -1.25, 90.0])
        );
        assert_eq!(s.machine_position(Some(&[1.0])), None);
        assert!(!s.planner_empty(15));
    }

    #[test]
    fn status_substates_feed_only_and_malformed_fields() {
        let Response::Status(s) = parse_response("<Hold:0|MPos:1,2,3|F:250|Bf:15,128>") else {
            panic!("not a status report");
        };
        assert_eq!((s.state.clone(), s.substate), (MachineState::Hold, Some(0)));
        assert_eq!((s.feed, s.spindle_rpm), (Some(250.0), None));
        let Response::Status(idle) = parse_response("<Idle|MPos:1,2,3|Bf:15,127>") else {
            panic!("not a status report");
        };
        assert!(idle.planner_empty(15));
        assert!(!idle.planner_empty(16));
        let Response::Status(odd) = parse_response("<Mystery|MPos:1,x,3|Ln:|Bf:3>") else {
            panic!("not a status report");
        };
        assert_eq!(odd.state, MachineState::Other("Mystery".into()));
        assert_eq!(odd.mpos, None);
        assert_eq!(odd.other, vec!["MPos:1,x,3", "Ln:", "Bf:3"]);
    }

    #[test]
    fn lines_split_across_reads_with_either_line_end() {
        let mut buffer = LineBuffer::new();
        assert!(buffer.push(b"o").is_empty());
        assert_eq!(buffer.push(b"k\r"), vec!["ok"]);
        assert_eq!(buffer.push(b"\nok\nerr"), vec!["ok"]);
        assert_eq!(buffer.pending(), 3);
        assert_eq!(buffer.push(b"or:20\r\n\r\n<Idle|MPos:0,0,0>\rok"), {
            vec!["error:20", "<Idle|MPos:0,0,0>"]
        });
        assert_eq!(buffer.push(b"\n"), vec!["ok"]);
    }

    #[test]
    fn a_line_without_end_is_bounded() {
        let mut buffer = LineBuffer::new();
        assert!(buffer.push(&[b'x'; 5000]).is_empty());
        assert_eq!(buffer.pending(), MAX_LINE_BYTES);
        let lines = buffer.push(b"\n");
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].len(), MAX_LINE_BYTES);
        assert_eq!(buffer.push(b"ok\n"), vec!["ok"]);
    }

    proptest! {
        #[test]
        fn any_bytes_parse_without_panicking(
            chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..64), 0..32)
        ) {
            let mut buffer = LineBuffer::new();
            for chunk in &chunks {
                for line in buffer.push(chunk) {
                    prop_assert!(!line.is_empty());
                    prop_assert!(!line.contains(['\r', '\n']));
                    let _ = parse_response(&line);
                }
                prop_assert!(buffer.pending() <= MAX_LINE_BYTES);
            }
        }

        #[test]
        fn status_like_text_parses_without_panicking(body in "[A-Za-z:|,.0-9-]{0,80}") {
            let _ = parse_response(&format!("<{body}>"));
            let _ = parse_response(&format!("[OPT:{body}]"));
        }
    }
}
