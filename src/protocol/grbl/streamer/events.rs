//! What a [`Streamer`](super::Streamer) reports and what a caller reads from it: the
//! [`Event`]s in order, the lines they name ([`LineRef`], [`Aux`]), why a stream stopped
//! ([`StopReason`]), how far it is ([`Progress`]) and where to resume ([`ResumePoint`],
//! [`ResumeBasis`]).

use std::fmt;
use std::ops::Range;

use thiserror::Error;

use crate::protocol::grbl::codes::{alarm_message, error_message};
use crate::protocol::grbl::response::{BuildOptions, Status};

/// A line the streamer adds to the program's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Aux {
    /// `$I`, asking the receive buffer size.
    BuildInfo,
    /// Line `n` (0-based) of the resume preamble.
    Preamble(usize),
    /// The empty line that clears grblHAL's sticky error.
    ClearError,
    /// `$X`, unlocking a controller found in alarm before the first line.
    Unlock,
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
            LineRef::Aux(Aux::Unlock) => write!(f, "the unlock $X"),
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
    /// [`Streamer::soft_reset`](super::Streamer::soft_reset) was called.
    #[error("soft reset requested")]
    SoftReset,
    /// [`Streamer::interrupt`](super::Streamer::interrupt) was called: a feed hold, and
    /// no line sent after it.
    #[error("interrupted ({reason}): feed hold sent")]
    Interrupted {
        /// Why, as the caller said it.
        reason: String,
    },
    /// The controller was in alarm before the first line, and unlocking was not asked for.
    #[error(
        "the controller is in alarm and locks out G-code (a reset mid-motion, a limit, or an \
         earlier alarm): check the machine, then run again with --unlock to clear it with $X"
    )]
    AlarmAtStart,
    /// The controller was busy before the first line (running, jogging, homing) or still
    /// held after a reset.
    #[error("the controller is {state} before the first line: nothing was sent")]
    Busy {
        /// The state it reported.
        state: String,
    },
}

/// What happened; see [`Streamer::next_event`](super::Streamer::next_event).
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// Program line `index` (0-based) was handed to
    /// [`Streamer::transmit`](super::Streamer::transmit); `line_no` is its N word, if it has
    /// one.
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
    /// last planned moves: keep polling until [`Event::MotionDone`].
    Done,
    /// After [`Event::Done`], a status report showed the motion finished: `Idle` with
    /// every planner block free, or, from a controller that reports no `Bf:` field, a
    /// second `Idle` report in a row (see [the streamer's docs](super#when-the-motion-is-done)).
    /// Reported once, after the [`Event::Status`] that proved it; it takes status reports,
    /// so never without polling.
    MotionDone,
    /// An `ok`/`error` with no line waiting for it, or output that is none of grbl's
    /// message kinds, as received.
    Unrecognized(String),
    /// A status report's `Ov:` shows a feed override other than the last one seen (or the
    /// first one), percent: the controller runs at it now.
    FeedOverride {
        /// Percent of the programmed feed.
        percent: u16,
    },
    /// A feed override asked ([`Streamer::feed_override`](super::Streamer::feed_override))
    /// was not reached: the controller does not report `Ov:` (`reported` is `None`), or it
    /// did not take the last byte.
    FeedOverrideNotTaken {
        /// Asked, percent.
        asked: u16,
        /// What the controller last reported, percent.
        reported: Option<u16>,
    },
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

/// Where to resume after a stop; see [the streamer's docs](super#resuming).
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
