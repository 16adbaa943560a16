//! Streaming a program to a grbl/grblHAL controller by character counting, as a sans-I/O
//! state machine: [`Streamer::receive`] takes the bytes read from the controller,
//! [`Streamer::transmit`] gives the bytes to write, [`Streamer::poll`] is told the time,
//! and [`Streamer::next_event`] says what happened. No clock, no port, no task: the
//! transport drives it, and the tests drive it with a model controller.
//!
//! # Character counting
//!
//! grbl's interface document ("Streaming Protocol: Character-Counting") describes the
//! method: the controller answers every line it receives with exactly one `ok` or
//! `error:N`, in order, so the host knows which lines still sit in the controller's serial
//! receive buffer: the unanswered ones. The host sends a whole line only while the bytes
//! of all unanswered lines (each with its `\n`) plus the new one fit in that buffer, and
//! never splits a line. This keeps the buffer full, and the planner fed, without ever
//! overflowing it.
//!
//! The budget is the buffer size less one byte: grbl's and grblHAL's receive buffers are
//! ring buffers that keep one slot empty, so a 128-byte buffer holds 127. The size is 128
//! (grbl on an AVR) until `$I` reports another: its `[OPT:codes,blocks,rx_bytes]` line
//! gives it (grblHAL: typically 1024), and the streamer asks before the first program
//! line unless told not to ([`StreamerConfig::query_build_info`]).
//!
//! Real-time bytes (`?` status, `!` feed hold, `~` cycle start, 0x18 soft reset) are taken
//! off the serial stream by the controller's receive interrupt and never enter the buffer,
//! so they are not counted and go out at once, ahead of any line.
//!
//! Lines are sent with `\n` only: grbl 1.1 answers `\r` and `\n` each as a line end, so
//! `\r\n` would draw two answers for one line and break the pairing.
//!
//! # Pairing
//!
//! Each `ok`/`error` answers the oldest unanswered line, whichever line that is (a
//! program line, a preamble line, `$I`, the error-clearing empty line), so the pairing
//! can never slip: no line is removed from the in-flight queue but by its answer, or all
//! at once by a controller reset (its banner), which discards the receive buffer. Push
//! messages (status reports, `[MSG:…]`, `ALARM:N`, startup-line results `>…:ok`) answer
//! nothing and are never counted.
//!
//! # Errors
//!
//! On the first `error:N` the streamer stops sending program lines. The lines already in
//! the receive buffer cannot be recalled, and the controller will read them:
//!
//! - grblHAL (default build) keeps the error *sticky*: until it reads an empty line, a
//!   successful `$` command or a soft reset, it answers every further G-code line with the
//!   same `error:N` and executes none. Those answers are reported as
//!   [`Event::Rejected`], consequences of the failure rather than new failures.
//! - grbl 1.1 has no sticky error and executes whatever valid lines follow (its document
//!   calls this out as the method's reservation). Their `ok`s are reported as
//!   [`Event::Acked`] and listed in [`ResumePoint::executed_after_failure`], because
//!   resuming at the failed line would run them twice.
//!
//! To leave the controller in a known state the streamer then sends one empty line: it
//! clears grblHAL's sticky error (otherwise the operator's next command, or a resumed
//! stream, would be refused with the old error), and grbl answers it with a plain `ok`.
//! Because the controller reads lines in order, the empty line takes effect only after
//! every in-flight line has been answered, which is what waiting for those answers and
//! then sending it would do, one round trip sooner. When its `ok` arrives the stream is
//! [`Event::Stopped`] with [`StopReason::Error`].
//!
//! # Alarms and resets
//!
//! `ALARM:N` stops the stream at once: grbl stops motion and discards its planned moves,
//! and locks out G-code, so lines still in the buffer come back as `error:9` (reported as
//! [`Event::Rejected`]). A banner after the stream has begun means the controller reset
//! (power, a reset button, the streamer's own [`Streamer::soft_reset`]): its receive
//! buffer and planner are gone, the unanswered lines are reported as
//! [`Event::Discarded`], and the stream stops with [`Event::Reset`].
//!
//! # Resuming
//!
//! An `ok` means "parsed and queued", not "executed": up to a planner's worth of
//! acknowledged lines (16 on grbl, 35 or more on grblHAL) may still be waiting to run.
//! [`Streamer::resume_point`] therefore says where to resume and how it knows:
//!
//! - after an error, with no reset since: the failed line. The controller refused it and
//!   executed every line before it (once it is idle again);
//! - after an alarm or a reset, which discard the planned moves: the first line *not known
//!   to have executed*. The streamer knows a line executed from status reports: `Ln:n`
//!   (grbl reports the N number of the block executing; the program must carry N words)
//!   proves every line before that block done; an `Idle` report with every planner block
//!   free (`Bf:`) proves every line acknowledged before it done. Lines acknowledged but not
//!   proven executed are returned as [`ResumePoint::possibly_executed`]: resuming at the
//!   returned line never skips a line, and runs those twice unless the caller rules them
//!   out (for instance by comparing the machine position with where they end).
//!
//! [`Streamer::resume_from`] then streams the program from that line behind a preamble
//! that restores its modes ([`super::resume`]).

use std::collections::VecDeque;
use std::fmt;
use std::ops::Range;
use std::time::Duration;

use thiserror::Error;

use super::codes::{alarm_message, error_message};
use super::response::{parse_response, BuildOptions, LineBuffer, Response, Status};
use super::resume::{resume_preamble, ResumeError};

/// Receive buffer size assumed until `$I` says otherwise: grbl 1.1 on an AVR.
pub const DEFAULT_RX_SIZE: usize = 128;

/// Status poll interval: grbl's interface document recommends at most 5 Hz.
pub const DEFAULT_POLL_INTERVAL: Duration = Duration::from_millis(200);

/// Real-time command bytes (grbl 1.1 "Real-time commands").
pub mod realtime {
    /// `?`: request a status report.
    pub const STATUS: u8 = b'?';
    /// `!`: feed hold.
    pub const FEED_HOLD: u8 = b'!';
    /// `~`: cycle start / resume.
    pub const CYCLE_START: u8 = b'~';
    /// Ctrl-X: soft reset.
    pub const SOFT_RESET: u8 = 0x18;
}

/// How a [`Streamer`] runs.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamerConfig {
    /// The controller's serial receive buffer, bytes, until `[OPT:…]` reports it; the
    /// streamer keeps the unanswered bytes at or below one less than this.
    pub rx_size: usize,
    /// Send `$I` first and adopt the receive buffer size of its `[OPT:…]` line.
    pub query_build_info: bool,
    /// Send no line before the controller's banner (for boards that reset when the port
    /// opens, such as an Arduino running grbl, which would drop lines sent while booting).
    pub wait_for_banner: bool,
    /// Status report interval for [`Streamer::poll`]; `None` never polls.
    pub poll_interval: Option<Duration>,
    /// First program line to send (0-based). [`Streamer::new`] sends from here as the
    /// lines are, without restoring modes; [`Streamer::resume_from`] sets it and adds the
    /// preamble that does.
    pub start_line: usize,
    /// Used by [`Streamer::resume_from`]: a dwell after restarting the spindle, seconds
    /// (0: none).
    pub spin_up_dwell_s: f64,
}

impl Default for StreamerConfig {
    fn default() -> StreamerConfig {
        StreamerConfig {
            rx_size: DEFAULT_RX_SIZE,
            query_build_info: true,
            wait_for_banner: false,
            poll_interval: Some(DEFAULT_POLL_INTERVAL),
            start_line: 0,
            spin_up_dwell_s: 0.0,
        }
    }
}

/// A line the streamer adds to the program's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Aux {
    /// `$I`, asking the receive buffer size.
    BuildInfo,
    /// Line `n` (0-based) of the resume preamble.
    Preamble(usize),
    /// The empty line that clears grblHAL's sticky error.
    ClearError,
}

/// Any line the streamer sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LineRef {
    /// Program line at this 0-based index.
    Program(usize),
    /// A line of the streamer's own.
    Aux(Aux),
}

/// Program lines display 1-based, as editors and controllers' error reports count them.
impl fmt::Display for LineRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LineRef::Program(index) => write!(f, "program line {}", index + 1),
            LineRef::Aux(Aux::BuildInfo) => write!(f, "the $I query"),
            LineRef::Aux(Aux::Preamble(index)) => write!(f, "resume preamble line {}", index + 1),
            LineRef::Aux(Aux::ClearError) => write!(f, "the error-clearing empty line"),
        }
    }
}

/// Why the stream stopped.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StopReason {
    /// The controller refused a line.
    #[error("{line} was refused: error:{code} ({})", error_message(*.code))]
    Error {
        /// The line.
        line: LineRef,
        /// grbl's error code.
        code: u16,
    },
    /// A line longer than the receive buffer (after `$I` reported a smaller one than
    /// configured): it can never be sent whole.
    #[error("{line} is {bytes} bytes with its line end, over the receive buffer's {budget}")]
    LineTooLong {
        /// The line.
        line: LineRef,
        /// Its length with `\n`.
        bytes: usize,
        /// The most the buffer takes.
        budget: usize,
    },
    /// `ALARM:N`.
    #[error("ALARM:{code} ({})", alarm_message(*.code))]
    Alarm {
        /// grbl's alarm code.
        code: u16,
    },
    /// The controller reset (a banner arrived mid-stream).
    #[error("the controller reset")]
    ControllerReset,
    /// [`Streamer::soft_reset`] was called.
    #[error("soft reset requested")]
    SoftReset,
}

/// What happened; see [`Streamer::next_event`].
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// Program line `index` (0-based) was handed to [`Streamer::transmit`]; `line_no` is its
    /// N word, if it has one.
    Sent {
        /// 0-based program index.
        index: usize,
        /// The line's N number.
        line_no: Option<u32>,
    },
    /// Program line `index` was answered `ok`.
    Acked {
        /// 0-based program index.
        index: usize,
    },
    /// Program line `index` failed: the controller refused it, and executed nothing of it.
    Error {
        /// 0-based program index.
        index: usize,
        /// The line as sent.
        line: String,
        /// grbl's error code.
        code: u16,
        /// What the code means.
        message: &'static str,
    },
    /// Program line `index` was refused as a consequence of an earlier failure or stop
    /// (grblHAL's sticky error repeating the failure's code, or `error:9` after an alarm),
    /// not as a failure of its own. It was not executed.
    Rejected {
        /// 0-based program index.
        index: usize,
        /// The code the controller answered.
        code: u16,
    },
    /// Program line `index` was sent but discarded unanswered by a controller reset; it
    /// was not executed.
    Discarded {
        /// 0-based program index.
        index: usize,
    },
    /// A line of the streamer's own was sent.
    AuxSent {
        /// Which.
        line: Aux,
        /// Its text, without the line end.
        text: String,
    },
    /// A line of the streamer's own was answered: `None` for `ok`, else the error code.
    AuxAnswered {
        /// Which.
        line: Aux,
        /// The error code, if refused.
        error: Option<u16>,
    },
    /// `ALARM:N`.
    Alarm {
        /// grbl's alarm code.
        code: u16,
        /// What it means.
        message: &'static str,
    },
    /// A status report.
    Status(Status),
    /// A `[MSG:…]` message.
    Message(String),
    /// Other feedback (`[VER:…]`, `[GC:…]`, `>…:ok` startup lines, `$x=val` settings), as
    /// received.
    Feedback(String),
    /// `$I`'s `[OPT:…]` line.
    Options(BuildOptions),
    /// The receive buffer size the streamer now counts against, from `[OPT:…]`.
    RxSize {
        /// Bytes.
        bytes: usize,
    },
    /// The controller's banner before the stream began (power-up, port open).
    Banner(String),
    /// The controller reset mid-stream: its buffers are gone.
    Reset,
    /// The stream stopped early; nothing more will be sent but real-time bytes.
    Stopped {
        /// Why.
        reason: StopReason,
    },
    /// Every program line was answered `ok`. The controller may still be executing the
    /// last planned moves: poll until the status says `Idle`.
    Done,
    /// An `ok`/`error` with no line waiting for it, or output that is none of grbl's
    /// message kinds, as received.
    Unrecognized(String),
}

/// Progress through the program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Program lines acknowledged, counting the lines before the start line (they ran in
    /// an earlier stream).
    pub acked: usize,
    /// The line executing now, if a status report's `Ln:` said so.
    pub executing: Option<usize>,
    /// Program lines.
    pub total: usize,
}

impl Progress {
    /// `acked / total` (1 for an empty program).
    pub fn fraction(&self) -> f64 {
        if self.total == 0 {
            1.0
        } else {
            self.acked as f64 / self.total as f64
        }
    }

    /// Seconds left, from `durations[i]` = planned seconds of program line `i`: the sum over
    /// the lines from the executing one (if known) or the first unacknowledged one on.
    /// Without `Ln:` the estimate is short by what the planner still holds (a few moves);
    /// with it, long by at most the executing line's elapsed part. `None` if `durations`
    /// does not have one entry per program line.
    pub fn eta_seconds(&self, durations: &[f64]) -> Option<f64> {
        if durations.len() != self.total {
            return None;
        }
        let from = self.executing.unwrap_or(self.acked).min(self.total);
        Some(durations[from..].iter().sum())
    }
}

/// How [`ResumePoint::line_index`] is known.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResumeBasis {
    /// The line the controller refused (nothing reset since): it and no later line ran,
    /// apart from [`ResumePoint::executed_after_failure`].
    FailedLine,
    /// A line of the resume preamble failed, so no program line of this stream ran.
    FailedPreamble,
    /// The line was never sent ([`StopReason::LineTooLong`]).
    NotSent,
    /// A status report's `Ln:` showed this line executing when last seen; the lines
    /// before it are done.
    ExecutingLine {
        /// Its N number.
        line_no: u32,
    },
    /// An `Idle` report with an empty planner showed every line before it done.
    PlannerEmpty,
    /// Nothing proves any line of this stream executed: the start line.
    StreamStart,
}

/// Where to resume after a stop; see the module docs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ResumePoint {
    /// The program line to resume at (0-based): the first not known to have executed.
    pub line_index: usize,
    /// How that is known.
    pub basis: ResumeBasis,
    /// Lines from `line_index` on that were acknowledged and may or may not have executed
    /// before the planner was discarded; empty when the resume point is exact.
    pub possibly_executed: Range<usize>,
    /// Lines after a failed one that a non-sticky controller (grbl 1.1) executed anyway.
    pub executed_after_failure: Vec<usize>,
}

/// Why a [`Streamer`] could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StreamerError {
    /// A byte the controller would act on outside the line, or that would split it: a line
    /// end, a real-time command byte (`?` `!` `~` 0x18, or any byte above 0x7F, which
    /// grbl and grblHAL read as real-time overrides), or DEL (a backspace to grblHAL).
    #[error("{line}, byte {column}: {byte:#04x} cannot be streamed inside a line (line end, real-time command or DEL)")]
    ForbiddenByte {
        /// The line.
        line: LineRef,
        /// 1-based byte position.
        column: usize,
        /// The byte.
        byte: u8,
    },
    /// A line that does not fit the receive buffer even alone.
    #[error("{line} is {bytes} bytes with its line end, over the receive buffer's {budget}")]
    LineTooLong {
        /// The line.
        line: LineRef,
        /// Its length with `\n`.
        bytes: usize,
        /// The most the buffer takes.
        budget: usize,
    },
    /// The start line is past the program.
    #[error("start line index {start} is past the program's {len} lines")]
    StartBeyondEnd {
        /// The requested start.
        start: usize,
        /// Program lines.
        len: usize,
    },
    /// A receive buffer too small to hold any line.
    #[error("receive buffer of {0} bytes is too small (at least 2)")]
    RxTooSmall(usize),
    /// The resume preamble could not be built.
    #[error(transparent)]
    Resume(#[from] ResumeError),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Waiting for the banner before sending anything.
    AwaitBanner,
    /// `$I` queued or in flight; no other line goes out until it is answered.
    Query,
    /// Sending the preamble and the program.
    Streaming,
    /// A stop is pending: nothing new but the clearing line goes out; waiting for answers.
    Draining,
    /// Stopped early.
    Stopped,
    /// Every line acknowledged.
    Done,
}

#[derive(Debug, Clone, Copy)]
struct InFlight {
    line: LineRef,
    bytes: usize,
}

/// The streaming state machine; see the module docs.
///
/// A transport drives it in a loop, in any order and at any rate, because every call only
/// updates state and queues output:
///
/// ```text
/// loop {
///     streamer.poll(elapsed());                     // maybe queues `?`
///     if let Some(bytes) = streamer.transmit() {    // real-time bytes, then whole lines
///         port.write_all(&bytes)?;
///     }
///     let n = port.read(&mut buffer) /* with a short timeout */;
///     streamer.receive(&buffer[..n]);
///     for event in streamer.events() { log(event) }
///     if streamer.is_finished() { break }           // Done or Stopped
/// }
/// ```
///
/// After [`Event::Done`], keep polling until the status says `Idle` if the machine must
/// finish its planned moves first; after [`Event::Stopped`], [`Streamer::resume_point`]
/// says where to go on.
#[derive(Debug, Clone)]
pub struct Streamer {
    lines: Vec<String>,
    line_nos: Vec<Option<u32>>,
    preamble: Vec<String>,
    config: StreamerConfig,
    rx_size: usize,
    planner_blocks: Option<u32>,
    phase: Phase,
    /// Lines of the streamer's own waiting to go out, ahead of the preamble and program.
    aux_queue: VecDeque<Aux>,
    next_preamble: usize,
    next_line: usize,
    in_flight: VecDeque<InFlight>,
    in_flight_bytes: usize,
    realtime: Vec<u8>,
    input: LineBuffer,
    events: VecDeque<Event>,
    /// A line has been handed out: a banner now means a reset.
    lines_sent: bool,
    reset_requested: bool,
    /// Why the stream will stop once drained.
    pending: Option<StopReason>,
    stop_reason: Option<StopReason>,
    /// The first failed line and its code.
    failure: Option<(LineRef, u16)>,
    executed_after_failure: Vec<usize>,
    /// Program lines answered `ok` (in this stream) plus the start line.
    acked: usize,
    /// One past the last program line answered `ok`.
    ok_end: usize,
    /// Lines before this one are known to have executed.
    known_executed: usize,
    known_basis: ResumeBasis,
    executing: Option<usize>,
    /// An alarm or reset discarded the planner: acks no longer imply execution.
    planner_flushed: bool,
    max_blocks_free: Option<u32>,
    last_poll: Option<Duration>,
    last_status: Option<Status>,
    last_wco: Option<Vec<f64>>,
}

impl Streamer {
    /// A streamer for `lines` (without line ends), from `config.start_line` on.
    ///
    /// Refuses lines holding bytes that cannot be streamed (see
    /// [`StreamerError::ForbiddenByte`]) or too long for `config.rx_size`, before anything
    /// is sent.
    pub fn new(lines: Vec<String>, config: StreamerConfig) -> Result<Streamer, StreamerError> {
        Streamer::with_preamble(lines, Vec::new(), config)
    }

    /// A streamer that resumes `lines` at `line_index` (0-based): the preamble of
    /// [`resume_preamble`] (modes, G92 offset of C, spindle, as the program had them
    /// before that line), then lines `line_index..`, so that with the right resume point
    /// ([`Streamer::resume_point`]) no line runs twice and none is skipped.
    /// `config.start_line` is replaced by `line_index`.
    pub fn resume_from(
        lines: Vec<String>,
        line_index: usize,
        config: StreamerConfig,
    ) -> Result<Streamer, StreamerError> {
        let preamble = resume_preamble(&lines, line_index, config.spin_up_dwell_s)?;
        let config = StreamerConfig {
            start_line: line_index,
            ..config
        };
        Streamer::with_preamble(lines, preamble, config)
    }

    /// A streamer that sends `preamble` before the program lines from
    /// `config.start_line`; for a preamble of the caller's own (for instance
    /// [`resume_preamble`]'s with a measured `G92` value, see [`super::resume`]).
    pub fn with_preamble(
        lines: Vec<String>,
        preamble: Vec<String>,
        config: StreamerConfig,
    ) -> Result<Streamer, StreamerError> {
        if config.rx_size < 2 {
            return Err(StreamerError::RxTooSmall(config.rx_size));
        }
        let start = config.start_line;
        if start > lines.len() {
            return Err(StreamerError::StartBeyondEnd {
                start,
                len: lines.len(),
            });
        }
        let budget = config.rx_size - 1;
        let preamble_refs = preamble
            .iter()
            .enumerate()
            .map(|(i, text)| (LineRef::Aux(Aux::Preamble(i)), text));
        let program_refs = lines
            .iter()
            .enumerate()
            .skip(start)
            .map(|(i, text)| (LineRef::Program(i), text));
        for (line, text) in preamble_refs.chain(program_refs) {
            check_line(line, text, budget)?;
        }
        let phase = if config.wait_for_banner {
            Phase::AwaitBanner
        } else if config.query_build_info {
            Phase::Query
        } else {
            Phase::Streaming
        };
        let mut aux_queue = VecDeque::new();
        if config.query_build_info {
            aux_queue.push_back(Aux::BuildInfo);
        }
        let mut streamer = Streamer {
            line_nos: lines.iter().map(|l| line_number(l)).collect(),
            lines,
            preamble,
            rx_size: config.rx_size,
            planner_blocks: None,
            phase,
            aux_queue,
            next_preamble: 0,
            next_line: start,
            in_flight: VecDeque::new(),
            in_flight_bytes: 0,
            realtime: Vec::new(),
            input: LineBuffer::new(),
            events: VecDeque::new(),
            lines_sent: false,
            reset_requested: false,
            pending: None,
            stop_reason: None,
            failure: None,
            executed_after_failure: Vec::new(),
            acked: start,
            ok_end: start,
            known_executed: start,
            known_basis: ResumeBasis::StreamStart,
            executing: None,
            planner_flushed: false,
            max_blocks_free: None,
            last_poll: None,
            last_status: None,
            last_wco: None,
            config,
        };
        streamer.advance();
        Ok(streamer)
    }

    /// Takes bytes read from the controller: any amount, split anywhere.
    pub fn receive(&mut self, bytes: &[u8]) {
        for line in self.input.push(bytes) {
            self.on_response(parse_response(&line), line);
        }
        self.advance();
    }

    /// The bytes to write now, if any: pending real-time bytes first, then every whole
    /// line (with `\n`) that fits the receive buffer's free space. The caller must write
    /// all of them, in order.
    pub fn transmit(&mut self) -> Option<Vec<u8>> {
        let mut out = std::mem::take(&mut self.realtime);
        while let Some(line) = self.next_outgoing() {
            let bytes = self.text(line).len() + 1;
            let budget = self.budget();
            if bytes > budget {
                self.halt(StopReason::LineTooLong {
                    line,
                    bytes,
                    budget,
                });
                continue;
            }
            if self.in_flight_bytes + bytes > budget {
                break;
            }
            out.extend_from_slice(self.text(line).as_bytes());
            out.push(b'\n');
            self.mark_sent(line, bytes);
        }
        self.advance();
        (!out.is_empty()).then_some(out)
    }

    /// Tells the streamer the time (any monotonic clock; only differences matter). When a
    /// status report is due, queues `?` for [`Streamer::transmit`] and returns `true`.
    pub fn poll(&mut self, now: Duration) -> bool {
        let Some(interval) = self.config.poll_interval else {
            return false;
        };
        let due = self
            .last_poll
            .is_none_or(|last| now.saturating_sub(last) >= interval);
        if due {
            self.last_poll = Some(now);
            if !self.realtime.contains(&realtime::STATUS) {
                self.realtime.push(realtime::STATUS);
            }
        }
        due
    }

    /// Feed hold (`!`): the controller decelerates to a stop and holds. Streaming goes on
    /// filling the buffer; [`Streamer::resume`] continues the motion.
    pub fn feed_hold(&mut self) {
        self.realtime.push(realtime::FEED_HOLD);
    }

    /// Cycle start (`~`): resume after a feed hold.
    pub fn resume(&mut self) {
        self.realtime.push(realtime::CYCLE_START);
    }

    /// Soft reset (0x18): the controller stops at once (an alarm if it was moving), drops
    /// its buffers and planned moves, and prints its banner. The stream stops now.
    pub fn soft_reset(&mut self) {
        self.realtime.push(realtime::SOFT_RESET);
        self.reset_requested = true;
        self.planner_flushed = true;
        self.stop(StopReason::SoftReset);
    }

    /// The next event, oldest first.
    pub fn next_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// All pending events, oldest first.
    pub fn events(&mut self) -> std::collections::vec_deque::Drain<'_, Event> {
        self.events.drain(..)
    }

    /// Lines acknowledged out of the program.
    pub fn progress(&self) -> Progress {
        Progress {
            acked: self.acked,
            executing: self.executing,
            total: self.lines.len(),
        }
    }

    /// Where to resume, once the stream has stopped early ([`Event::Stopped`]); `None`
    /// before that and after [`Event::Done`]. See the module docs.
    pub fn resume_point(&self) -> Option<ResumePoint> {
        if self.phase != Phase::Stopped {
            return None;
        }
        let exact = |line_index: usize, basis| ResumePoint {
            line_index,
            basis,
            possibly_executed: line_index..line_index,
            executed_after_failure: self.executed_after_failure.clone(),
        };
        if !self.planner_flushed {
            match (self.failure, &self.stop_reason) {
                (Some((LineRef::Program(index), _)), _) => {
                    return Some(exact(index, ResumeBasis::FailedLine));
                }
                (Some((LineRef::Aux(_), _)), _) => {
                    return Some(exact(self.config.start_line, ResumeBasis::FailedPreamble));
                }
                (
                    None,
                    Some(StopReason::LineTooLong {
                        line: LineRef::Program(index),
                        ..
                    }),
                ) => return Some(exact(*index, ResumeBasis::NotSent)),
                (None, Some(StopReason::LineTooLong { .. })) => {
                    return Some(exact(self.config.start_line, ResumeBasis::NotSent));
                }
                _ => {}
            }
        }
        // A failed line never ran, even if lines after it did (grbl 1.1) and an idle
        // report then proved those done.
        let (line_index, basis) = match self.failure {
            Some((LineRef::Program(index), _)) if index < self.known_executed => {
                (index, ResumeBasis::FailedLine)
            }
            _ => (self.known_executed, self.known_basis),
        };
        Some(ResumePoint {
            line_index,
            basis,
            possibly_executed: line_index..self.ok_end.max(line_index),
            executed_after_failure: self.executed_after_failure.clone(),
        })
    }

    /// Why the stream stopped, once it has.
    pub fn stop_reason(&self) -> Option<&StopReason> {
        self.stop_reason.as_ref()
    }

    /// Every line acknowledged ([`Event::Done`]) or the stream stopped.
    pub fn is_finished(&self) -> bool {
        matches!(self.phase, Phase::Done | Phase::Stopped)
    }

    /// The receive buffer size counted against, bytes.
    pub fn rx_size(&self) -> usize {
        self.rx_size
    }

    /// Bytes sent and not yet answered; never above `rx_size() − 1`.
    pub fn in_flight_bytes(&self) -> usize {
        self.in_flight_bytes
    }

    /// Planner blocks, from `[OPT:…]`.
    pub fn planner_blocks(&self) -> Option<u32> {
        self.planner_blocks
    }

    /// The last status report.
    pub fn last_status(&self) -> Option<&Status> {
        self.last_status.as_ref()
    }

    /// The last work coordinate offset reported (grbl sends it only now and then).
    pub fn last_wco(&self) -> Option<&[f64]> {
        self.last_wco.as_deref()
    }

    fn budget(&self) -> usize {
        self.rx_size - 1
    }

    fn text(&self, line: LineRef) -> &str {
        match line {
            LineRef::Program(i) => self.lines.get(i).map_or("", String::as_str),
            LineRef::Aux(Aux::Preamble(i)) => self.preamble.get(i).map_or("", String::as_str),
            LineRef::Aux(Aux::BuildInfo) => "$I",
            LineRef::Aux(Aux::ClearError) => "",
        }
    }

    /// The line that goes out next, if the phase lets one go.
    fn next_outgoing(&self) -> Option<LineRef> {
        let aux = self.aux_queue.front().map(|&aux| LineRef::Aux(aux));
        match self.phase {
            Phase::Query | Phase::Draining => aux,
            Phase::Streaming => aux.or(if self.next_preamble < self.preamble.len() {
                Some(LineRef::Aux(Aux::Preamble(self.next_preamble)))
            } else if self.next_line < self.lines.len() {
                Some(LineRef::Program(self.next_line))
            } else {
                None
            }),
            Phase::AwaitBanner | Phase::Stopped | Phase::Done => None,
        }
    }

    fn mark_sent(&mut self, line: LineRef, bytes: usize) {
        match line {
            LineRef::Program(index) => {
                self.next_line = index + 1;
                let line_no = self.line_nos.get(index).copied().flatten();
                self.events.push_back(Event::Sent { index, line_no });
            }
            LineRef::Aux(aux) => {
                if let Aux::Preamble(i) = aux {
                    self.next_preamble = i + 1;
                } else {
                    self.aux_queue.pop_front();
                }
                let text = self.text(line).to_owned();
                self.events.push_back(Event::AuxSent { line: aux, text });
            }
        }
        self.in_flight.push_back(InFlight { line, bytes });
        self.in_flight_bytes += bytes;
        self.lines_sent = true;
    }

    fn on_response(&mut self, response: Response, raw: String) {
        match response {
            Response::Ok => self.on_answer(None, raw),
            Response::Error(code) => self.on_answer(Some(code), raw),
            Response::Alarm(code) => self.on_alarm(code),
            Response::Status(status) => self.on_status(status),
            Response::Message(text) => self.events.push_back(Event::Message(text)),
            Response::Options(options) => self.on_options(options),
            Response::Version(_)
            | Response::Feedback(_)
            | Response::StartupLine(_)
            | Response::Setting(_) => self.events.push_back(Event::Feedback(raw)),
            Response::Banner(text) => self.on_banner(text),
            Response::Other(_) => self.events.push_back(Event::Unrecognized(raw)),
        }
    }

    fn on_answer(&mut self, error: Option<u16>, raw: String) {
        let Some(entry) = self.in_flight.pop_front() else {
            tracing::warn!(response = %raw, "controller answered a line the streamer did not send");
            self.events.push_back(Event::Unrecognized(raw));
            return;
        };
        self.in_flight_bytes -= entry.bytes;
        match (entry.line, error) {
            (LineRef::Aux(aux), _) => {
                self.events
                    .push_back(Event::AuxAnswered { line: aux, error });
                match (aux, error) {
                    (Aux::BuildInfo, _) if self.phase == Phase::Query => {
                        if error.is_some() {
                            // A failed `$` command sets grblHAL's sticky error too.
                            self.aux_queue.push_front(Aux::ClearError);
                        }
                        self.phase = Phase::Streaming;
                    }
                    (Aux::Preamble(_), Some(code)) => self.fail(entry.line, code),
                    _ => {}
                }
            }
            (LineRef::Program(index), None) => {
                self.events.push_back(Event::Acked { index });
                self.acked += 1;
                self.ok_end = self.ok_end.max(index + 1);
                if self.failure.is_some() {
                    tracing::warn!(
                        line = index + 1,
                        "line executed after an earlier line failed (no sticky error)"
                    );
                    self.executed_after_failure.push(index);
                }
            }
            (LineRef::Program(_), Some(code)) => self.fail(entry.line, code),
        }
    }

    /// A line was refused.
    fn fail(&mut self, line: LineRef, code: u16) {
        let first = match self.phase {
            Phase::Streaming | Phase::Query => true,
            // Draining for a too-long line: this earlier line is the real failure.
            Phase::Draining => self.failure.is_none(),
            Phase::AwaitBanner | Phase::Stopped | Phase::Done => false,
        };
        let consequence = match self.phase {
            // After an alarm or reset, refusals (`error:9`) are its consequence.
            Phase::AwaitBanner | Phase::Stopped | Phase::Done => true,
            _ if first => false,
            // grblHAL's sticky error repeats the failure's code; another code is a failure
            // of the line's own (grbl without a sticky error).
            _ => self.failure.is_some_and(|(_, failed)| failed == code),
        };
        if let LineRef::Program(index) = line {
            if consequence {
                self.events.push_back(Event::Rejected { index, code });
            } else {
                self.events.push_back(Event::Error {
                    index,
                    line: self.text(line).to_owned(),
                    code,
                    message: error_message(code),
                });
            }
        }
        if first {
            tracing::warn!(%line, code, message = error_message(code), "controller refused a line");
            self.failure = Some((line, code));
            self.pending = Some(StopReason::Error { line, code });
            self.phase = Phase::Draining;
            self.aux_queue.clear();
            self.aux_queue.push_back(Aux::ClearError);
        }
    }

    /// Stop sending new lines; stop once the lines in flight are answered.
    fn halt(&mut self, reason: StopReason) {
        if matches!(self.phase, Phase::Streaming | Phase::Query) {
            self.pending = Some(reason);
            self.phase = Phase::Draining;
            self.aux_queue.clear();
        } else if self.phase == Phase::Draining {
            // Not even the clearing line fits: give up on it.
            self.aux_queue.clear();
        }
    }

    /// Stop now.
    fn stop(&mut self, reason: StopReason) {
        let stop = match self.phase {
            Phase::Stopped => false,
            // A reset or alarm after the last ack still matters if moves were pending.
            Phase::Done => self.known_executed < self.lines.len(),
            _ => true,
        };
        if stop {
            self.phase = Phase::Stopped;
            self.pending = None;
            self.aux_queue.clear();
            self.stop_reason = Some(reason.clone());
            self.events.push_back(Event::Stopped { reason });
        }
    }

    fn on_alarm(&mut self, code: u16) {
        tracing::warn!(code, message = alarm_message(code), "controller alarm");
        self.events.push_back(Event::Alarm {
            code,
            message: alarm_message(code),
        });
        // grbl stops motion and discards its planned moves on every alarm.
        self.planner_flushed = true;
        self.stop(StopReason::Alarm { code });
    }

    fn on_banner(&mut self, text: String) {
        if self.phase == Phase::AwaitBanner {
            self.events.push_back(Event::Banner(text));
            self.phase = if self.aux_queue.is_empty() {
                Phase::Streaming
            } else {
                Phase::Query
            };
            return;
        }
        if !self.lines_sent && !self.reset_requested {
            self.events.push_back(Event::Banner(text));
            return;
        }
        tracing::warn!(banner = %text, "controller reset");
        self.events.push_back(Event::Reset);
        for entry in self.in_flight.drain(..) {
            if let LineRef::Program(index) = entry.line {
                self.events.push_back(Event::Discarded { index });
            }
        }
        self.in_flight_bytes = 0;
        self.planner_flushed = true;
        let reason = if std::mem::take(&mut self.reset_requested) {
            StopReason::SoftReset
        } else {
            StopReason::ControllerReset
        };
        self.stop(reason);
    }

    fn on_options(&mut self, options: BuildOptions) {
        if let Some(blocks) = options.blocks {
            self.planner_blocks = Some(blocks);
        }
        // Adopt the size only while `$I` is the one line in flight, so that the bytes
        // already counted never exceed the new budget.
        let asked = self.phase == Phase::Query
            && self
                .in_flight
                .iter()
                .all(|e| e.line == LineRef::Aux(Aux::BuildInfo));
        let rx = options.rx_bytes.map(|rx| rx as usize);
        self.events.push_back(Event::Options(options));
        if let Some(bytes) = rx.filter(|&rx| asked && rx > self.in_flight_bytes + 1) {
            self.rx_size = bytes;
            self.events.push_back(Event::RxSize { bytes });
        }
    }

    fn on_status(&mut self, status: Status) {
        if let Some(free) = status.buffer.map(|b| b.planner_blocks_free) {
            self.max_blocks_free = Some(self.max_blocks_free.map_or(free, |m| m.max(free)));
        }
        if !self.planner_flushed {
            if let Some(line_no) = status.line {
                let sent = self.known_executed..self.next_line.min(self.lines.len());
                if let Some(index) = sent
                    .into_iter()
                    .find(|&i| self.line_nos[i] == Some(line_no))
                {
                    self.executing = Some(index);
                    if index > self.known_executed {
                        self.known_executed = index;
                        self.known_basis = ResumeBasis::ExecutingLine { line_no };
                    }
                }
            }
            // The planner size from `$I`, else the most free blocks ever reported (all of
            // them, in any report taken while the machine was idle).
            let blocks = self.planner_blocks.or(self.max_blocks_free);
            if blocks.is_some_and(|b| status.planner_empty(b)) {
                self.executing = None;
                if self.ok_end > self.known_executed {
                    self.known_executed = self.ok_end;
                    self.known_basis = ResumeBasis::PlannerEmpty;
                }
            }
        }
        if let Some(wco) = &status.wco {
            self.last_wco = Some(wco.clone());
        }
        self.last_status = Some(status.clone());
        self.events.push_back(Event::Status(status));
    }

    /// Moves to Done or Stopped once nothing is left to send or answer.
    fn advance(&mut self) {
        if !self.in_flight.is_empty() || !self.aux_queue.is_empty() {
            return;
        }
        match self.phase {
            Phase::Streaming
                if self.next_preamble >= self.preamble.len()
                    && self.next_line >= self.lines.len() =>
            {
                self.phase = Phase::Done;
                self.events.push_back(Event::Done);
            }
            Phase::Draining => {
                if let Some(reason) = self.pending.take() {
                    self.stop(reason);
                }
            }
            _ => {}
        }
    }
}

/// Checks that `text` can be streamed as one line within `budget` bytes.
fn check_line(line: LineRef, text: &str, budget: usize) -> Result<(), StreamerError> {
    if let Some((i, &byte)) = text.as_bytes().iter().enumerate().find(|(_, &b)| {
        matches!(
            b,
            b'\n' | b'\r' | realtime::STATUS | realtime::FEED_HOLD | realtime::CYCLE_START
        ) || b == realtime::SOFT_RESET
            || b >= 0x7f
    }) {
        return Err(StreamerError::ForbiddenByte {
            line,
            column: i + 1,
            byte,
        });
    }
    let bytes = text.len() + 1;
    if bytes > budget {
        return Err(StreamerError::LineTooLong {
            line,
            bytes,
            budget,
        });
    }
    Ok(())
}

/// The N number of a line (`N120 G1 …`), if its first word is one.
fn line_number(text: &str) -> Option<u32> {
    let rest = text.trim_start().strip_prefix(['N', 'n'])?.trim_start();
    let digits = rest
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(rest.len());
    rest.get(..digits)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::grbl::fake::Fake;
    use proptest::prelude::*;

    fn program(lines: &[&str]) -> Vec<String> {
        lines.iter().map(|l| l.to_string()).collect()
    }

    /// `n` lines of `G1 X<i> F100`, each about a dozen bytes.
    fn moves(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("G1 X{i} F100")).collect()
    }

    fn no_query() -> StreamerConfig {
        StreamerConfig {
            query_build_info: false,
            ..StreamerConfig::default()
        }
    }

    /// Runs streamer and controller against each other until the stream finishes or
    /// nothing moves; checks the buffer invariants on the way.
    fn drive(streamer: &mut Streamer, fake: &mut Fake) {
        for _ in 0..10_000 {
            let sent = streamer.transmit();
            if let Some(bytes) = &sent {
                fake.write(bytes);
            }
            assert!(!fake.overflowed, "receive buffer overflowed");
            assert!(streamer.in_flight_bytes() < streamer.rx_size());
            fake.process_all();
            let output = fake.take_output();
            streamer.receive(&output);
            if streamer.is_finished() && sent.is_none() && output.is_empty() {
                return;
            }
        }
        panic!("stream did not finish");
    }

    fn sent_indices(events: &[Event]) -> Vec<usize> {
        events
            .iter()
            .filter_map(|e| match e {
                Event::Sent { index, .. } => Some(*index),
                _ => None,
            })
            .collect()
    }

    fn acked_indices(events: &[Event]) -> Vec<usize> {
        events
            .iter()
            .filter_map(|e| match e {
                Event::Acked { index } => Some(*index),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_program_streams_to_done_in_order() {
        let lines = moves(40);
        let mut streamer = Streamer::new(lines.clone(), StreamerConfig::default()).unwrap();
        let mut fake = Fake::grblhal(128);
        drive(&mut streamer, &mut fake);
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(fake.executed, lines);
        assert_eq!(sent_indices(&events), (0..40).collect::<Vec<_>>());
        assert_eq!(acked_indices(&events), (0..40).collect::<Vec<_>>());
        assert_eq!(events.last(), Some(&Event::Done));
        assert_eq!(events.iter().filter(|e| **e == Event::Done).count(), 1);
        assert_eq!(streamer.progress().acked, 40);
        assert_eq!(streamer.resume_point(), None);
        // The buffer was kept full: 127 bytes hold 9 lines of 12–13 bytes.
        assert!(fake.max_fill > 100, "{}", fake.max_fill);
    }

    #[test]
    fn whole_lines_only_up_to_the_budget() {
        // 4 lines of 40 bytes with `\n`: three fit 127 bytes, the fourth waits for an ok.
        let line = "G1 X1.2345 Z-0.5678 C123.4567 F1234.567".to_string();
        assert_eq!(line.len() + 1, 40);
        let mut streamer = Streamer::new(vec![line.clone(); 4], no_query()).unwrap();
        let first = streamer.transmit().unwrap();
        assert_eq!(first.len(), 120);
        assert_eq!(streamer.in_flight_bytes(), 120);
        assert_eq!(streamer.transmit(), None);
        streamer.receive(b"ok\r\n");
        assert_eq!(
            streamer.transmit().unwrap(),
            format!("{line}\n").into_bytes()
        );
        assert_eq!(streamer.in_flight_bytes(), 120);
    }

    #[test]
    fn answers_pair_in_order_in_bursts_split_reads_and_between_push_messages() {
        let lines = moves(6);
        let mut streamer = Streamer::new(lines, no_query()).unwrap();
        streamer.transmit().unwrap();
        // Two oks in one read, one split over three reads, push messages in between that
        // answer nothing (a startup line's `:ok` included).
        streamer.receive(b"ok\r\nok\r\n<Run|MPos:1,0,0|FS:100,0>\r\no");
        streamer.receive(b"k");
        streamer.receive(b"\r\n[MSG:Pgm End]\r\n>G54:ok\r\nok\nok\r");
        streamer.receive(b"\n");
        assert_eq!(streamer.in_flight_bytes(), 11);
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(acked_indices(&events), vec![0, 1, 2, 3, 4]);
        assert!(events.contains(&Event::Message("Pgm End".into())));
        assert!(events.contains(&Event::Feedback(">G54:ok".into())));
        streamer.receive(b"ok\r\n");
        assert_eq!(streamer.next_event(), Some(Event::Acked { index: 5 }));
        assert_eq!(streamer.next_event(), Some(Event::Done));
        // An answer with nothing in flight is reported, not paired.
        streamer.receive(b"ok\r\n");
        assert_eq!(
            streamer.next_event(),
            Some(Event::Unrecognized("ok".into()))
        );
    }

    #[test]
    fn an_error_stops_sending_reports_the_line_and_clears_the_sticky_error() {
        let mut lines = moves(30);
        lines[5] = "G1 X5 Q1 F100".into();
        let mut fake = Fake::grblhal(128);
        fake.fail.push((lines[5].clone(), 20));
        let mut streamer = Streamer::new(lines.clone(), no_query()).unwrap();
        // One burst: the lines that fit go out, the controller answers them all.
        fake.write(&streamer.transmit().unwrap());
        let in_flight = sent_indices(&streamer.events().collect::<Vec<_>>());
        assert!(in_flight.len() > 7, "{in_flight:?}");
        fake.process_all();
        streamer.receive(&fake.take_output());
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(acked_indices(&events), vec![0, 1, 2, 3, 4]);
        assert!(events.contains(&Event::Error {
            index: 5,
            line: lines[5].clone(),
            code: 20,
            message: error_message(20),
        }));
        // The lines behind it got the sticky error: consequences, not failures.
        let rejected: Vec<usize> = events
            .iter()
            .filter_map(|e| match e {
                Event::Rejected { index, code: 20 } => Some(*index),
                _ => None,
            })
            .collect();
        assert_eq!(rejected, (6..in_flight.len()).collect::<Vec<_>>());
        assert_eq!(
            events
                .iter()
                .filter(|e| matches!(e, Event::Error { .. }))
                .count(),
            1
        );
        assert!(!streamer.is_finished());
        // Then exactly one empty line goes out, and no program line.
        let clear = streamer.transmit().unwrap();
        assert_eq!(clear, b"\n");
        assert_eq!(streamer.transmit(), None);
        fake.write(&clear);
        drive(&mut streamer, &mut fake);
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(
            events,
            vec![
                Event::AuxSent {
                    line: Aux::ClearError,
                    text: String::new()
                },
                Event::AuxAnswered {
                    line: Aux::ClearError,
                    error: None
                },
                Event::Stopped {
                    reason: StopReason::Error {
                        line: LineRef::Program(5),
                        code: 20
                    }
                },
            ]
        );
        assert_eq!(fake.executed, lines[..5]);
        // The controller is clear: a next line would run.
        fake.write(b"G0 X0\n");
        fake.process_all();
        assert_eq!(fake.take_output(), b"ok\r\n");
        let point = streamer.resume_point().unwrap();
        assert_eq!(
            point,
            ResumePoint {
                line_index: 5,
                basis: ResumeBasis::FailedLine,
                possibly_executed: 5..5,
                executed_after_failure: vec![],
            }
        );
        assert!(streamer
            .stop_reason()
            .unwrap()
            .to_string()
            .contains("program line 6"));
    }

    #[test]
    fn without_a_sticky_error_later_lines_run_and_a_new_code_is_a_new_failure() {
        let mut lines = moves(12);
        lines[3] = "G1 X3 Q1 F100".into();
        lines[5] = "G1 X5 F0".into();
        let mut fake = Fake::grbl(128);
        fake.fail.push((lines[3].clone(), 20));
        fake.fail.push((lines[5].clone(), 22));
        let mut streamer = Streamer::new(lines.clone(), no_query()).unwrap();
        drive(&mut streamer, &mut fake);
        let events: Vec<Event> = streamer.events().collect();
        let failed: Vec<(usize, u16)> = events
            .iter()
            .filter_map(|e| match e {
                Event::Error { index, code, .. } => Some((*index, *code)),
                _ => None,
            })
            .collect();
        assert_eq!(failed, vec![(3, 20), (5, 22)]);
        let point = streamer.resume_point().unwrap();
        assert_eq!(point.line_index, 3);
        assert_eq!(point.basis, ResumeBasis::FailedLine);
        // grbl ran the valid lines that were already in its buffer.
        let after = point.executed_after_failure;
        assert!(after.starts_with(&[4, 6]), "{after:?}");
        assert!(after.iter().all(|&i| fake.executed.contains(&lines[i])));
        assert!(!fake.executed.contains(&lines[3]));
        assert_eq!(
            streamer.stop_reason(),
            Some(&StopReason::Error {
                line: LineRef::Program(3),
                code: 20
            })
        );
    }

    #[test]
    fn an_alarm_stops_the_stream_and_later_refusals_are_its_consequence() {
        let mut streamer = Streamer::new(moves(30), no_query()).unwrap();
        let first = sent_count(&mut streamer);
        streamer.receive(b"ok\r\nok\r\nALARM:2\r\n[MSG:Reset to continue]\r\n");
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(
            events,
            vec![
                Event::Acked { index: 0 },
                Event::Acked { index: 1 },
                Event::Alarm {
                    code: 2,
                    message: alarm_message(2)
                },
                Event::Stopped {
                    reason: StopReason::Alarm { code: 2 }
                },
                Event::Message("Reset to continue".into()),
            ]
        );
        // Nothing but real-time bytes goes out any more, whatever room there is.
        streamer.receive(b"error:9\r\n");
        assert_eq!(
            streamer.next_event(),
            Some(Event::Rejected { index: 2, code: 9 })
        );
        assert_eq!(streamer.transmit(), None);
        streamer.feed_hold();
        assert_eq!(streamer.transmit().unwrap(), b"!");
        // The reset that follows discards the rest, without a second stop.
        streamer.receive(b"Grbl 1.1h ['$' for help]\r\n");
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(events[0], Event::Reset);
        assert_eq!(
            events[1..],
            (3..first)
                .map(|index| Event::Discarded { index })
                .collect::<Vec<_>>()
        );
        assert_eq!(streamer.in_flight_bytes(), 0);
        // Nothing proves a line executed: resume at the start; 0 and 1 may have run.
        let point = streamer.resume_point().unwrap();
        assert_eq!(point.line_index, 0);
        assert_eq!(point.basis, ResumeBasis::StreamStart);
        assert_eq!(point.possibly_executed, 0..2);
    }

    /// Transmits once and returns how many program lines went out.
    fn sent_count(streamer: &mut Streamer) -> usize {
        streamer.transmit().unwrap();
        sent_indices(&streamer.events().collect::<Vec<_>>()).len()
    }

    #[test]
    fn a_banner_mid_stream_is_a_reset() {
        let mut streamer = Streamer::new(moves(20), no_query()).unwrap();
        let sent = sent_count(&mut streamer);
        streamer.receive(b"ok\r\n\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n");
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(events[0], Event::Acked { index: 0 });
        assert_eq!(events[1], Event::Reset);
        let discarded: Vec<usize> = events
            .iter()
            .filter_map(|e| match e {
                Event::Discarded { index } => Some(*index),
                _ => None,
            })
            .collect();
        assert_eq!(discarded, (1..sent).collect::<Vec<_>>());
        assert!(events.contains(&Event::Stopped {
            reason: StopReason::ControllerReset
        }));
        assert_eq!(streamer.transmit(), None);
        assert_eq!(streamer.resume_point().unwrap().possibly_executed, 0..1);
    }

    #[test]
    fn a_banner_before_the_stream_is_no_reset_and_can_gate_it() {
        let config = StreamerConfig {
            wait_for_banner: true,
            ..StreamerConfig::default()
        };
        let mut streamer = Streamer::new(moves(3), config).unwrap();
        assert_eq!(streamer.transmit(), None);
        // Real-time bytes are not held back.
        assert!(streamer.poll(Duration::ZERO));
        assert_eq!(streamer.transmit().unwrap(), b"?");
        streamer.receive(b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
        assert_eq!(
            streamer.next_event(),
            Some(Event::Banner(
                "GrblHAL 1.1f ['$' or '$HELP' for help]".into()
            ))
        );
        assert_eq!(streamer.transmit().unwrap(), b"$I\n");

        // Without waiting, a banner before any line is informational too.
        let mut streamer = Streamer::new(moves(3), no_query()).unwrap();
        streamer.receive(b"Grbl 1.1h ['$' for help]\r\n");
        assert!(matches!(streamer.next_event(), Some(Event::Banner(_))));
        assert!(streamer.transmit().is_some());
    }

    #[test]
    fn the_rx_size_of_build_info_is_adopted() {
        let lines: Vec<String> = (0..60)
            .map(|i| format!("G1 X{i:03} Z-1.000 C{i:03}.5 F100"))
            .collect();
        let mut fake = Fake::grblhal(1024);
        let mut streamer = Streamer::new(lines.clone(), StreamerConfig::default()).unwrap();
        // `$I` alone first: the program waits for the size.
        assert_eq!(streamer.transmit().unwrap(), b"$I\n");
        assert_eq!(streamer.transmit(), None);
        fake.write(b"$I\n");
        fake.process_all();
        streamer.receive(&fake.take_output());
        let events: Vec<Event> = streamer.events().collect();
        assert!(events.contains(&Event::RxSize { bytes: 1024 }));
        assert!(events.contains(&Event::Feedback("[VER:1.1f.20250102:]".into())));
        assert_eq!(streamer.rx_size(), 1024);
        assert_eq!(streamer.planner_blocks(), Some(35));
        let burst = streamer.transmit().unwrap();
        assert!(burst.len() > 900 && burst.len() <= 1023, "{}", burst.len());
        fake.write(&burst);
        drive(&mut streamer, &mut fake);
        assert_eq!(fake.executed, lines);
        assert!(fake.max_fill > 900);

        // An OPT line without a size, or grbl without `$I`, keeps the default.
        let mut fake = Fake::grbl(128);
        fake.opt = None;
        let mut streamer = Streamer::new(moves(5), StreamerConfig::default()).unwrap();
        drive(&mut streamer, &mut fake);
        assert_eq!(streamer.rx_size(), 128);
        assert_eq!(fake.executed, moves(5));
    }

    #[test]
    fn a_failed_build_info_query_clears_the_sticky_error_and_streams() {
        let mut fake = Fake::grblhal(128);
        fake.opt = None;
        let mut streamer = Streamer::new(moves(3), StreamerConfig::default()).unwrap();
        streamer.transmit().unwrap();
        streamer.receive(b"error:3\r\n");
        assert_eq!(
            streamer.events().next_back(),
            Some(Event::AuxAnswered {
                line: Aux::BuildInfo,
                error: Some(3)
            })
        );
        let out = streamer.transmit().unwrap();
        assert_eq!(out, b"\nG1 X0 F100\nG1 X1 F100\nG1 X2 F100\n");
        fake.write(&out);
        drive(&mut streamer, &mut fake);
        assert_eq!(streamer.events().next_back(), Some(Event::Done));
        assert_eq!(fake.executed, moves(3));
    }

    #[test]
    fn a_reported_buffer_too_small_for_a_line_stops_before_it() {
        let mut streamer = Streamer::new(
            program(&["G0 X0", "G1 X1.2345 Z2.3456 F100", "G0 X0"]),
            StreamerConfig::default(),
        )
        .unwrap();
        streamer.transmit().unwrap();
        streamer.receive(b"[OPT:V,15,16]\r\nok\r\n");
        assert_eq!(streamer.transmit().unwrap(), b"G0 X0\n");
        streamer.receive(b"ok\r\n");
        let stopped = streamer.events().next_back();
        assert_eq!(
            stopped,
            Some(Event::Stopped {
                reason: StopReason::LineTooLong {
                    line: LineRef::Program(1),
                    bytes: 24,
                    budget: 15
                }
            })
        );
        let point = streamer.resume_point().unwrap();
        assert_eq!((point.line_index, point.basis), (1, ResumeBasis::NotSent));
    }

    #[test]
    fn status_reports_are_parsed_and_the_wco_kept() {
        let mut streamer = Streamer::new(moves(1), no_query()).unwrap();
        streamer.receive(
            b"<Idle|MPos:1.000,0.000,-2.000,90.000|FS:0,0|WCO:0.000,0.000,1.000,45.000>\r\n",
        );
        streamer.receive(b"<Run|MPos:2.000,0.000,-2.000,90.000|Bf:30,1000|FS:100,3000>\r\n");
        let events: Vec<Event> = streamer.events().collect();
        let Event::Status(first) = &events[0] else {
            panic!("{events:?}");
        };
        assert_eq!(first.wco, Some(vec![0.0, 0.0, 1.0, 45.0]));
        let Event::Status(second) = &events[1] else {
            panic!("{events:?}");
        };
        assert_eq!(second.wco, None);
        assert_eq!(streamer.last_wco(), Some(&[0.0, 0.0, 1.0, 45.0][..]));
        let work = second.work_position(streamer.last_wco()).unwrap();
        assert_eq!(work, vec![2.0, 0.0, -3.0, 45.0]);
        assert_eq!(streamer.last_status(), Some(second));
    }

    #[test]
    fn real_time_bytes_bypass_the_count() {
        let mut streamer = Streamer::new(moves(30), no_query()).unwrap();
        streamer.transmit().unwrap();
        let full = streamer.in_flight_bytes();
        assert!(full > 114, "{full}");
        assert_eq!(streamer.transmit(), None);
        streamer.feed_hold();
        assert!(streamer.poll(Duration::from_secs(1)));
        streamer.resume();
        assert_eq!(streamer.transmit().unwrap(), b"!?~");
        assert_eq!(streamer.in_flight_bytes(), full);
        // They go ahead of lines that go out in the same call.
        streamer.feed_hold();
        streamer.receive(b"ok\r\n");
        let out = streamer.transmit().unwrap();
        assert_eq!(out[0], b'!');
        assert_eq!(&out[1..], b"G1 X11 F100\n");
        // A soft reset stops the stream at once.
        streamer.soft_reset();
        assert_eq!(streamer.transmit().unwrap(), [realtime::SOFT_RESET]);
        assert!(streamer.events().any(|e| e
            == Event::Stopped {
                reason: StopReason::SoftReset
            }));
        streamer.receive(b"ok\r\n");
        assert_eq!(streamer.transmit(), None);
        // Its banner is the expected reset: in-flight lines are discarded.
        streamer.receive(b"GrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
        let events: Vec<Event> = streamer.events().collect();
        assert_eq!(events[1], Event::Reset);
        assert!(matches!(events[2], Event::Discarded { index: 2 }));
        assert_eq!(streamer.in_flight_bytes(), 0);
        assert_eq!(streamer.stop_reason(), Some(&StopReason::SoftReset));
    }

    #[test]
    fn polls_at_the_configured_interval() {
        let ms = Duration::from_millis;
        let mut streamer = Streamer::new(Vec::new(), no_query()).unwrap();
        assert!(streamer.poll(ms(1000)));
        assert!(!streamer.poll(ms(1100)));
        assert!(!streamer.poll(ms(1199)));
        assert!(streamer.poll(ms(1200)));
        assert!(!streamer.poll(ms(1350)));
        assert!(streamer.poll(ms(1400)));
        // Due twice before a transmit: one `?` (grbl ignores a second before it reports).
        assert!(streamer.poll(ms(1600)));
        assert_eq!(streamer.transmit().unwrap(), b"?");
        // A clock that goes back is not due, and does not panic.
        assert!(!streamer.poll(ms(10)));
        let mut quiet = Streamer::new(
            Vec::new(),
            StreamerConfig {
                poll_interval: None,
                ..no_query()
            },
        )
        .unwrap();
        assert!(!quiet.poll(ms(0)));
        assert_eq!(quiet.transmit(), None);
        assert_eq!(quiet.next_event(), Some(Event::Done));
    }

    const POSTED: &str = "\
G21 G90 G94
M3 S3000
G0 X20 Z5 C0
G93 G1 Z-0.5 C90 F100
G1 Z-1 C180 F100
G92 C0
G1 Z-1.5 C90 F100
G1 Z-2 C180 F100
G92 C0
G1 Z-2.5 C90 F100
G1 Z-3 C180 F100
G94
G0 X30
M5
M2";

    #[test]
    fn resume_streams_the_preamble_then_the_line() {
        let lines: Vec<String> = POSTED.lines().map(str::to_owned).collect();
        let mut streamer = Streamer::resume_from(lines.clone(), 7, no_query()).unwrap();
        let out = String::from_utf8(streamer.transmit().unwrap()).unwrap();
        let expected: String = ["G21 G92 C90", "G21 G90 G93", "M3 S3000"]
            .iter()
            .chain(
                lines[7..]
                    .iter()
                    .map(String::as_str)
                    .collect::<Vec<_>>()
                    .iter(),
            )
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(out, expected);
        let events: Vec<Event> = streamer.events().collect();
        assert!(matches!(
            events[0],
            Event::AuxSent {
                line: Aux::Preamble(0),
                ..
            }
        ));
        assert_eq!(sent_indices(&events), (7..lines.len()).collect::<Vec<_>>());
        assert_eq!(streamer.progress().acked, 7);
        // Nothing resumes past the end, or with unreadable history.
        assert!(matches!(
            Streamer::resume_from(lines.clone(), 99, no_query()),
            Err(StreamerError::Resume(ResumeError::BeyondEnd { .. }))
        ));
    }

    #[test]
    fn error_then_resume_runs_every_line_exactly_once() {
        let good: Vec<String> = POSTED.lines().map(str::to_owned).collect();
        let mut bad = good.clone();
        bad[7] = "G1 Z-2 C180 F100 Q1".into();
        let mut fake = Fake::grblhal(128);
        fake.fail.push((bad[7].clone(), 20));
        let mut first = Streamer::new(bad, StreamerConfig::default()).unwrap();
        drive(&mut first, &mut fake);
        let point = first.resume_point().unwrap();
        assert_eq!(point.line_index, 7);
        assert_eq!(point.possibly_executed, 7..7);
        let mut second =
            Streamer::resume_from(good.clone(), point.line_index, StreamerConfig::default())
                .unwrap();
        drive(&mut second, &mut fake);
        assert_eq!(second.events().next_back(), Some(Event::Done));
        // Every program line ran exactly once, in order, the preamble between the streams.
        let preamble = ["G21 G92 C90", "G21 G90 G93", "M3 S3000"].map(String::from);
        let expected: Vec<String> = good[..7]
            .iter()
            .chain(&preamble)
            .chain(&good[7..])
            .cloned()
            .collect();
        assert_eq!(fake.executed, expected);
    }

    #[test]
    fn after_an_alarm_line_numbers_say_where_execution_was() {
        let lines: Vec<String> = (0..20)
            .map(|i| format!("N{} G1 X{i} F100", 10 * (i + 1)))
            .collect();
        let wide = StreamerConfig {
            rx_size: 1024,
            ..no_query()
        };
        let mut streamer = Streamer::new(lines.clone(), wide).unwrap();
        let sent = sent_count(&mut streamer);
        streamer.receive(&b"ok\r\n".repeat(8));
        // N40 is index 3: lines 0–2 are done, 3 was executing.
        streamer.receive(b"<Run|MPos:3.5,0,0|Bf:10,60|Ln:40|FS:100,0>\r\n");
        assert_eq!(streamer.progress().executing, Some(3));
        streamer.receive(b"ALARM:1\r\n");
        let point = streamer.resume_point().unwrap();
        assert_eq!(point.line_index, 3);
        assert_eq!(point.basis, ResumeBasis::ExecutingLine { line_no: 40 });
        assert_eq!(point.possibly_executed, 3..8);
        assert!(sent > 8);
        // Sent events carry the N numbers.
        let mut again = Streamer::new(lines, no_query()).unwrap();
        again.transmit();
        assert_eq!(
            again.next_event(),
            Some(Event::Sent {
                index: 0,
                line_no: Some(10)
            })
        );
    }

    #[test]
    fn after_an_alarm_an_empty_planner_proves_lines_done() {
        let mut streamer = Streamer::new(moves(20), no_query()).unwrap();
        streamer.transmit();
        streamer.receive(&b"ok\r\n".repeat(5));
        // Idle alone proves nothing: grbl may not have started the cycle yet.
        streamer.receive(b"<Idle|MPos:0,0,0|FS:0,0>\r\n");
        streamer.receive(b"<Idle|MPos:0,0,0|Bf:14,100|FS:0,0>\r\n");
        assert_eq!(streamer.resume_point(), None);
        // With every block free (15 is the most seen, so the planner size) it does.
        streamer.receive(b"<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
        streamer.receive(&b"ok\r\n".repeat(3));
        streamer.receive(b"<Run|MPos:0,0,0|Bf:13,60|FS:100,0>\r\nALARM:3\r\n");
        // After the alarm nothing more is proven, even by an idle report.
        streamer.receive(b"<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
        let point = streamer.resume_point().unwrap();
        assert_eq!(point.line_index, 5);
        assert_eq!(point.basis, ResumeBasis::PlannerEmpty);
        assert_eq!(point.possibly_executed, 5..8);
    }

    #[test]
    fn progress_and_eta() {
        let mut streamer = Streamer::new(moves(4), no_query()).unwrap();
        streamer.transmit();
        streamer.receive(b"ok\r\n");
        let progress = streamer.progress();
        assert_eq!((progress.acked, progress.total), (1, 4));
        assert_eq!(progress.fraction(), 0.25);
        assert_eq!(progress.eta_seconds(&[1.0, 2.0, 3.0, 4.0]), Some(9.0));
        assert_eq!(progress.eta_seconds(&[1.0]), None);
        let executing = Progress {
            executing: Some(3),
            ..progress
        };
        assert_eq!(executing.eta_seconds(&[1.0, 2.0, 3.0, 4.0]), Some(4.0));
        let empty = Progress {
            acked: 0,
            executing: None,
            total: 0,
        };
        assert_eq!((empty.fraction(), empty.eta_seconds(&[])), (1.0, Some(0.0)));
    }

    #[test]
    fn unstreamable_programs_are_refused_before_anything_is_sent() {
        let refused = |lines: &[&str], config: StreamerConfig| {
            Streamer::new(program(lines), config).unwrap_err()
        };
        assert_eq!(
            refused(&["G0 X0", "G1 X1 (why?)"], no_query()),
            StreamerError::ForbiddenByte {
                line: LineRef::Program(1),
                column: 11,
                byte: b'?'
            }
        );
        assert!(matches!(
            refused(&["G0 X0\r"], no_query()),
            StreamerError::ForbiddenByte { byte: b'\r', .. }
        ));
        assert!(matches!(
            refused(&["(é)"], no_query()),
            StreamerError::ForbiddenByte { byte: 0xc3, .. }
        ));
        let long = "G1 X1".repeat(30);
        assert!(matches!(
            Streamer::new(vec![long.clone()], no_query()).unwrap_err(),
            StreamerError::LineTooLong {
                bytes: 151,
                budget: 127,
                ..
            }
        ));
        let wide = StreamerConfig {
            rx_size: 1024,
            ..no_query()
        };
        assert!(Streamer::new(vec![long], wide).is_ok());
        assert_eq!(
            refused(
                &["G0 X0"],
                StreamerConfig {
                    start_line: 2,
                    ..no_query()
                }
            ),
            StreamerError::StartBeyondEnd { start: 2, len: 1 }
        );
        assert_eq!(
            refused(
                &["G0 X0"],
                StreamerConfig {
                    rx_size: 1,
                    ..no_query()
                }
            ),
            StreamerError::RxTooSmall(1)
        );
        // Lines before the start line are not sent, so not checked.
        let config = StreamerConfig {
            start_line: 1,
            ..no_query()
        };
        let mut streamer = Streamer::new(program(&["?", "G0 X0"]), config).unwrap();
        assert_eq!(streamer.transmit().unwrap(), b"G0 X0\n");
    }

    #[test]
    fn a_preamble_line_that_fails_stops_before_the_program() {
        let preamble = program(&["G21 G92 C0"]);
        let mut fake = Fake::grblhal(128);
        fake.fail.push(("G21 G92 C0".into(), 9));
        let mut streamer = Streamer::with_preamble(moves(3), preamble, no_query()).unwrap();
        drive(&mut streamer, &mut fake);
        assert!(fake.executed.is_empty());
        assert_eq!(
            streamer.stop_reason(),
            Some(&StopReason::Error {
                line: LineRef::Aux(Aux::Preamble(0)),
                code: 9
            })
        );
        let point = streamer.resume_point().unwrap();
        assert_eq!(
            (point.line_index, point.basis),
            (0, ResumeBasis::FailedPreamble)
        );
        let rejected = streamer
            .events()
            .filter(|e| matches!(e, Event::Rejected { code: 9, .. }))
            .count();
        assert_eq!(rejected, 3);
    }

    #[test]
    fn an_empty_program_or_start_at_the_end_is_done_at_once() {
        let mut streamer = Streamer::new(Vec::new(), no_query()).unwrap();
        assert_eq!(streamer.next_event(), Some(Event::Done));
        assert_eq!(streamer.transmit(), None);
        let config = StreamerConfig {
            start_line: 2,
            ..StreamerConfig::default()
        };
        let mut fake = Fake::grblhal(128);
        let mut streamer = Streamer::new(moves(2), config).unwrap();
        drive(&mut streamer, &mut fake);
        assert_eq!(streamer.events().next_back(), Some(Event::Done));
        assert!(fake.executed.is_empty());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Character counting never lets the unanswered bytes exceed the receive buffer,
        /// whatever the line lengths and however the answers are timed and split.
        #[test]
        fn unanswered_bytes_never_exceed_the_receive_buffer(
            lengths in proptest::collection::vec(0usize..=120, 1..80),
            rx_size in prop_oneof![Just(128usize), Just(200), Just(1024)],
            query in any::<bool>(),
            steps in proptest::collection::vec((0u8..3, 1usize..40), 0..600),
        ) {
            let lines: Vec<String> = lengths
                .iter()
                .enumerate()
                .map(|(i, &n)| format!("{i}{}", "A".repeat(n)).chars().take(n.max(1)).collect())
                .collect();
            let config = StreamerConfig {
                query_build_info: query,
                // Without `$I` the streamer must be told the size.
                rx_size: if query { DEFAULT_RX_SIZE } else { rx_size },
                ..StreamerConfig::default()
            };
            let mut streamer = Streamer::new(lines.clone(), config).unwrap();
            let mut fake = Fake::grbl(rx_size);
            let mut wire: VecDeque<u8> = VecDeque::new();
            let mut events = Vec::new();
            let mut step = |action: u8, amount: usize, streamer: &mut Streamer, fake: &mut Fake| {
                match action {
                    0 => {
                        if let Some(bytes) = streamer.transmit() {
                            fake.write(&bytes);
                        }
                    }
                    1 => {
                        for _ in 0..amount % 4 + 1 {
                            fake.process();
                        }
                    }
                    _ => {
                        wire.extend(fake.take_output());
                        let n = amount.min(wire.len());
                        let chunk: Vec<u8> = wire.drain(..n).collect();
                        streamer.receive(&chunk);
                    }
                }
            };
            for &(action, amount) in &steps {
                step(action, amount, &mut streamer, &mut fake);
                prop_assert!(!fake.overflowed);
                prop_assert!(fake.buffered() < rx_size);
                prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
                prop_assert!(streamer.rx_size() <= rx_size);
                events.extend(streamer.events());
            }
            for _ in 0..10_000 {
                if streamer.is_finished() {
                    break;
                }
                for action in 0..3 {
                    step(action, usize::MAX, &mut streamer, &mut fake);
                    prop_assert!(!fake.overflowed);
                    prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
                }
                events.extend(streamer.events());
            }
            prop_assert_eq!(&fake.executed, &lines);
            let all: Vec<usize> = (0..lines.len()).collect();
            prop_assert_eq!(sent_indices(&events), all.clone());
            prop_assert_eq!(acked_indices(&events), all);
            prop_assert_eq!(events.last(), Some(&Event::Done));
        }

        /// Any bytes from the controller, in any chunks, between transmits: no panic, the
        /// count stays within the buffer, and only sent lines are ever answered.
        #[test]
        fn any_controller_output_is_survived(
            chunks in proptest::collection::vec(
                prop_oneof![
                    proptest::collection::vec(any::<u8>(), 0..24),
                    prop_oneof![
                        Just(b"ok\r\n".to_vec()),
                        Just(b"error:20\r\n".to_vec()),
                        Just(b"error:9\n".to_vec()),
                        Just(b"ALARM:2\r\n".to_vec()),
                        Just(b"Grbl 1.1h ['$' for help]\r\n".to_vec()),
                        Just(b"<Idle|MPos:0,0,0|Bf:15,127|Ln:3>\r\n".to_vec()),
                        Just(b"[OPT:V,15,64]\r\n".to_vec()),
                        Just(b"[OPT:V,15,0]\r\n".to_vec()),
                        Just(b"\r".to_vec()),
                    ],
                ],
                0..60,
            ),
            commands in proptest::collection::vec(0u8..8, 0..60),
        ) {
            let lines: Vec<String> = (0..30).map(|i| format!("N{i} G1 X{i} F100")).collect();
            let mut streamer = Streamer::new(lines, StreamerConfig::default()).unwrap();
            let mut sent = std::collections::HashSet::new();
            for (i, chunk) in chunks.iter().enumerate() {
                match commands.get(i) {
                    Some(0) => streamer.feed_hold(),
                    Some(1) => streamer.resume(),
                    Some(2) => streamer.soft_reset(),
                    Some(3) => {
                        streamer.poll(Duration::from_millis(i as u64 * 100));
                    }
                    _ => {}
                }
                let _ = streamer.transmit();
                streamer.receive(chunk);
                prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
                for event in streamer.events() {
                    match event {
                        Event::Sent { index, .. } => {
                            sent.insert(index);
                        }
                        Event::Acked { index }
                        | Event::Error { index, .. }
                        | Event::Rejected { index, .. }
                        | Event::Discarded { index } => prop_assert!(sent.contains(&index)),
                        _ => {}
                    }
                }
                let _ = streamer.resume_point();
                let _ = streamer.progress();
            }
        }
    }
}
