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
//! so they are not counted and go out at once, ahead of any line. Not every link has such
//! an interrupt, though: a USB CDC link, and grblHAL's own simulator (its `mcu.c` reads a
//! byte only while more than 100 bytes of the buffer are free), deliver no byte while the
//! buffer is full, and a `?` or a `!` then waits behind the lines until one is read: a
//! controller in a long move answers nothing and cannot be held. So the streamer keeps an
//! eighth of a grblHAL buffer free while any line is in flight ([`rx_reserve`]: 128 of
//! 1024 bytes; none of an AVR's 128, whose interrupt sees every byte). What it costs: the
//! lines waiting in the buffer behind the planner's blocks come to 895 bytes instead of
//! 1023, at 115 200 baud 78 ms of link time instead of 89 ms, still many times the 17–60
//! ms grblHAL's simulator takes to answer a line, so the link stays as busy.
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
//!
//! # Interrupting
//!
//! [`Streamer::interrupt`] is how a bridge that must go away (a signal, a lost console)
//! leaves the machine: a feed hold, no line sent after it, and the stream stopped with
//! [`StopReason::Interrupted`]. The machine decelerates along the path and holds; the
//! transport keeps polling until [`Streamer::is_standing`] (a report of `Hold:0` or
//! `Alarm` taken after the hold, or `Idle` with nothing left: every line answered, the
//! buffers empty in `Bf:`, and `Idle` in the report before too), so the run ends with the
//! machine at rest and the resume point read from the report that shows it there (`Ln:`
//! of the held block). One `Idle` is no proof: a controller starved between moves reports
//! it for a moment while lines are still on their way, and runs them. A report of `Run`, or
//! such an `Idle`, after the hold means the hold did not take, and it goes out again.
//!
//! # Connecting: the state before the first line
//!
//! With [`StreamerConfig::check_state`] the streamer asks `?` before anything else and
//! sends no line before a status report answers: that report says the controller is up
//! and listening, and what state it is in. A board that resets when its port opens (the
//! DTR line of an Arduino or a USB serial adapter) is in its boot loader for 100 ms to 2 s
//! and drops the bytes sent meanwhile, the first `?` among them; the poll
//! ([`Streamer::poll`]) asks again at every interval until one is answered. Its banner,
//! whenever it comes in this phase, is the boot, not a reset: the streamer asks `?` once
//! more and waits for the answer, since a `?` sent before the banner may have been lost.
//! A banner waiting from before the port opened is the same (the transport clears the
//! port's input on open, but a banner may still be on its way).
//!
//! The answer decides: a controller left held by an interrupted run gets a soft reset (at
//! rest, grbl keeps its position and raises no alarm) and is asked again; one in alarm
//! (locked out: every line would come back `error:9`) stops the stream with
//! [`StopReason::AlarmAtStart`], or with [`StreamerConfig::unlock`] gets `$X` first; one
//! running, jogging or homing stops it with [`StopReason::Busy`]. Nothing but `?` and the
//! reset goes out before the answer.
//!
//! Until the first line of the program (or of a resume preamble) has gone out, a banner is
//! a boot too, a late one (a board whose banner follows its first answer, as some print it
//! when the host opens their USB port): the streamer's own lines in flight (`$I`, `$X`)
//! are taken as lost with the controller's buffer, `$I` is asked again, and with
//! [`StreamerConfig::check_state`] the state is asked again before anything else. Once a
//! program or preamble line has gone out, a banner is a reset and stops the stream (see
//! [above](self#alarms-and-resets)).
//!
//! # When the motion is done
//!
//! [`Event::Done`] says every program line was acknowledged, not that it ran: up to a
//! planner's worth of moves may still be queued. The streamer watches the status reports
//! that follow and reports [`Event::MotionDone`] once one proves the motion finished:
//! `Idle` with every planner block free (`Bf:`), counted against the planner size from
//! `$I`'s `[OPT:…]`, else the most free blocks any report has shown (a report taken while
//! the machine was idle shows them all). A controller that reports no `Bf:` field needs
//! two consecutive `Idle` reports instead: grbl can answer one `?` as `Idle` just before
//! it starts the cycle of blocks it has just planned. Only reports read after the read
//! that brought the last `ok` count, and only while the stream has not stopped. The rule
//! reads status reports, so it needs polling ([`StreamerConfig::poll_interval`]); a
//! transport that must not end before the machine stands waits for it.
//!
//! A held machine ([`Streamer::is_held`]: a [`Streamer::feed_hold`] not yet followed by
//! [`Streamer::resume`], or the last status report saying `Hold`, `Door` or `Tool`) is
//! waiting, not stalled: a transport's no-progress watchdog asks before it gives up.
//!
//! The types the streamer reports and a caller reads ([`Event`] and the rest) are defined
//! next to it, with [`StreamerConfig`] and [`StreamerError`], and re-exported here.

use std::collections::VecDeque;
use std::time::Duration;

use super::codes::{alarm_message, error_message};
use super::feed_override::{self, Change, FeedOverride};
use super::response::{parse_response, BuildOptions, LineBuffer, MachineState, Response, Status};
use super::resume::resume_preamble;

mod config;
mod events;
#[cfg(test)]
mod tests;

use config::check_line;
pub use config::{StreamerConfig, StreamerError, DEFAULT_POLL_INTERVAL, DEFAULT_RX_SIZE};
pub use events::{Aux, Event, LineRef, Progress, ResumeBasis, ResumePoint, StopReason};

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Waiting for the banner before sending anything.
    AwaitBanner,
    /// `?` sent before the first line; waiting for the state it reports.
    CheckState,
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
/// After [`Event::Done`], keep polling until [`Event::MotionDone`] if the machine must
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
    /// A line of the program or of the resume preamble has been handed out: a banner now
    /// means a reset (before, it is the controller booting).
    started: bool,
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
    /// The most receive-buffer bytes free any report has shown (all of them at rest).
    max_rx_free: u32,
    /// Consecutive `Idle` reports since every line was acknowledged.
    idle_reports: u32,
    /// [`Event::MotionDone`] has been reported.
    motion_done: bool,
    /// [`Streamer::feed_hold`] was called and [`Streamer::resume`] not since.
    hold_requested: bool,
    /// [`Streamer::interrupt`] was called: waiting for a report of the machine at rest.
    interrupted: bool,
    /// A report since [`Streamer::interrupt`] showed the machine at rest.
    standing: bool,
    /// The soft reset of a controller found held before the first line has been sent.
    reset_at_start: bool,
    /// ... and its banner not yet read: reports until then answer a `?` sent before it.
    reset_pending: bool,
    last_poll: Option<Duration>,
    last_status: Option<Status>,
    last_wco: Option<Vec<f64>>,
    /// The feed override asked and what `Ov:` says.
    feed: FeedOverride,
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
            phase: Phase::AwaitBanner,
            aux_queue,
            next_preamble: 0,
            next_line: start,
            in_flight: VecDeque::new(),
            in_flight_bytes: 0,
            realtime: Vec::new(),
            input: LineBuffer::new(),
            events: VecDeque::new(),
            started: false,
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
            max_rx_free: 0,
            idle_reports: 0,
            motion_done: false,
            hold_requested: false,
            interrupted: false,
            standing: false,
            reset_at_start: false,
            reset_pending: false,
            last_poll: None,
            last_status: None,
            last_wco: None,
            feed: FeedOverride::default(),
            config,
        };
        if !streamer.config.wait_for_banner {
            streamer.after_banner();
        }
        streamer.advance();
        Ok(streamer)
    }

    /// The phase once the controller is known to be listening: the state check, or the
    /// streamer's own lines (`$I`), or the program.
    fn after_banner(&mut self) {
        if self.config.check_state {
            self.phase = Phase::CheckState;
            if !self.realtime.contains(&realtime::STATUS) {
                self.realtime.push(realtime::STATUS);
            }
        } else {
            self.begin();
        }
    }

    /// Go on to the streamer's own lines, then the program.
    fn begin(&mut self) {
        self.phase = if self.aux_queue.is_empty() {
            Phase::Streaming
        } else {
            Phase::Query
        };
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
            // The reserve is left free for real-time bytes, except for a line that goes
            // alone (one longer than the budget less the reserve would otherwise never go).
            let reserve = if self.in_flight.is_empty() {
                0
            } else {
                rx_reserve(self.rx_size)
            };
            if self.in_flight_bytes + bytes + reserve > budget {
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
    /// filling the buffer; [`Streamer::resume`] continues the motion, and until then the
    /// machine counts as held ([`Streamer::is_held`]).
    pub fn feed_hold(&mut self) {
        self.realtime.push(realtime::FEED_HOLD);
        self.hold_requested = true;
    }

    /// Cycle start (`~`): resume after a feed hold.
    pub fn resume(&mut self) {
        self.realtime.push(realtime::CYCLE_START);
        self.hold_requested = false;
    }

    /// Feed override: run at `percent` of the programmed feed (grbl takes 10–200; the
    /// caller checks the cap). The real-time bytes go out one at a time, each once a status
    /// report's `Ov:` shows the one before took ([`super::feed_override`]), so it takes
    /// status polling; [`Event::FeedOverride`] says each value reached, and
    /// [`Event::FeedOverrideNotTaken`] that the controller does not report `Ov:` or did
    /// not take a byte.
    pub fn feed_override(&mut self, percent: u16) {
        if let Some(byte) = self.feed.ask(percent) {
            self.realtime.push(byte);
        }
    }

    /// The feed override the controller last reported, percent.
    pub fn reported_feed_override(&self) -> Option<u16> {
        self.feed.reported()
    }

    /// Soft reset (0x18): the controller stops at once (an alarm if it was moving), drops
    /// its buffers and planned moves, and prints its banner. The stream stops now.
    pub fn soft_reset(&mut self) {
        self.realtime.push(realtime::SOFT_RESET);
        self.reset_requested = true;
        self.planner_flushed = true;
        self.stop(StopReason::SoftReset);
    }

    /// Hold and end the stream (see [the module docs](self#interrupting)): a feed hold now,
    /// no line after it, and [`Event::Stopped`] with [`StopReason::Interrupted`]; the
    /// transport then waits for [`Streamer::is_standing`]. After an alarm or a reset the
    /// machine is stopped already, and only the hold goes out.
    pub fn interrupt(&mut self, reason: impl Into<String>) {
        self.feed_hold();
        self.interrupted = true;
        self.standing = false;
        if self.phase != Phase::Stopped {
            self.phase = Phase::Stopped;
            self.pending = None;
            self.aux_queue.clear();
            let reason = StopReason::Interrupted {
                reason: reason.into(),
            };
            self.stop_reason = Some(reason.clone());
            self.events.push_back(Event::Stopped { reason });
        }
    }

    /// After [`Streamer::interrupt`]: a status report since showed the machine at rest
    /// (`Hold:0`, the hold complete; `Alarm`, stopped by the controller; or `Idle` with
    /// nothing left, see [the module docs](self#interrupting)).
    pub fn is_standing(&self) -> bool {
        self.interrupted && self.standing
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
        // Held after an interrupt, in the block the last report names: the lines after it
        // are in the planner, not run; that block may be part done.
        let held_in = self.is_standing()
            && self.executing == Some(line_index)
            && self
                .last_status
                .as_ref()
                .is_some_and(|status| status.state == MachineState::Hold);
        let possibly_end = if held_in {
            line_index + 1
        } else {
            self.ok_end.max(line_index)
        };
        Some(ResumePoint {
            line_index,
            basis,
            possibly_executed: line_index..possibly_end,
            executed_after_failure: self.executed_after_failure.clone(),
        })
    }

    /// Where to resume if the stream ended now, whatever its phase: after a stop,
    /// [`Streamer::resume_point`]; otherwise (the link lost mid-stream: the controller goes
    /// on with every line it has received) the first line not known to have executed, with
    /// every line sent from there on as possibly executed.
    pub fn resume_point_now(&self) -> ResumePoint {
        self.resume_point().unwrap_or_else(|| {
            let line_index = self.known_executed;
            ResumePoint {
                line_index,
                basis: self.known_basis,
                possibly_executed: line_index..self.next_line.max(line_index),
                executed_after_failure: self.executed_after_failure.clone(),
            }
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

    /// The machine is held, so silence from it is no stall: a [`Streamer::feed_hold`] not
    /// yet followed by [`Streamer::resume`], or the last status report says `Hold`, `Door`
    /// or `Tool` (the controller's own hold: a safety door, a tool change).
    pub fn is_held(&self) -> bool {
        self.hold_requested
            || self.last_status.as_ref().is_some_and(|status| {
                matches!(
                    status.state,
                    MachineState::Hold | MachineState::Door | MachineState::Tool
                )
            })
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

    /// Program lines sent and not known to have executed: the lines the controller may
    /// still be working through (see [the module docs](self#resuming)).
    pub fn lines_in_flight(&self) -> std::ops::Range<usize> {
        let end = self.next_line.min(self.lines.len());
        self.known_executed.min(end)..end
    }

    /// The resume preamble has begun to go out and no program line is known to have run
    /// since: the preamble's moves (a re-entry's plunge) may be what the machine is doing.
    pub fn preamble_may_be_running(&self) -> bool {
        self.next_preamble > 0 && self.known_executed <= self.config.start_line
    }

    fn text(&self, line: LineRef) -> &str {
        match line {
            LineRef::Program(i) => self.lines.get(i).map_or("", String::as_str),
            LineRef::Aux(Aux::Preamble(i)) => self.preamble.get(i).map_or("", String::as_str),
            LineRef::Aux(Aux::BuildInfo) => "$I",
            LineRef::Aux(Aux::ClearError) => "",
            LineRef::Aux(Aux::Unlock) => "$X",
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
            Phase::AwaitBanner | Phase::CheckState | Phase::Stopped | Phase::Done => None,
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
        self.started |= matches!(line, LineRef::Program(_) | LineRef::Aux(Aux::Preamble(_)));
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
                    (Aux::Preamble(_) | Aux::Unlock, Some(code)) => self.fail(entry.line, code),
                    (Aux::Unlock, None) if self.phase == Phase::Query => self.begin(),
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
            Phase::AwaitBanner | Phase::CheckState | Phase::Stopped | Phase::Done => false,
        };
        let consequence = match self.phase {
            // After an alarm or reset, refusals (`error:9`) are its consequence.
            Phase::AwaitBanner | Phase::CheckState | Phase::Stopped | Phase::Done => true,
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
            self.after_banner();
            return;
        }
        if self.phase == Phase::CheckState {
            // The answer to the reset of a held controller, or a reset of its own: ask again.
            self.reset_pending = false;
            self.events.push_back(Event::Banner(text));
            if !self.realtime.contains(&realtime::STATUS) {
                self.realtime.push(realtime::STATUS);
            }
            return;
        }
        if !self.started
            && !self.reset_requested
            && matches!(self.phase, Phase::Query | Phase::Streaming)
        {
            self.events.push_back(Event::Banner(text));
            self.boot();
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

    /// A banner before the stream started: the controller booted (see [the module
    /// docs](self#connecting-the-state-before-the-first-line)). Its receive buffer is gone
    /// with the streamer's own lines in it; the boot cleared any sticky error, and whether
    /// `$X` is needed is for the state check to say again.
    fn boot(&mut self) {
        tracing::debug!("controller banner before the first program line: a boot");
        let lost_build_info = self
            .in_flight
            .drain(..)
            .any(|entry| entry.line == LineRef::Aux(Aux::BuildInfo));
        self.in_flight_bytes = 0;
        self.aux_queue.retain(|aux| *aux == Aux::BuildInfo);
        if lost_build_info && self.aux_queue.is_empty() {
            self.aux_queue.push_back(Aux::BuildInfo);
        }
        self.after_banner();
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
        if self.phase == Phase::CheckState && !self.reset_pending {
            self.on_start_state(&status.state);
        }
        if let Some(free) = status.buffer.map(|b| b.rx_bytes_free) {
            self.max_rx_free = self.max_rx_free.max(free);
        }
        if self.interrupted {
            self.standing = match status.state {
                MachineState::Hold => status.substate == Some(0),
                MachineState::Alarm => true,
                MachineState::Idle => self.idle_with_nothing_left(&status),
                _ => false,
            };
            if matches!(status.state, MachineState::Run | MachineState::Idle)
                && !self.standing
                && !self.realtime.contains(&realtime::FEED_HOLD)
            {
                // A hold the controller has not taken (one that came while it stood idle
                // between starved moves) would let the lines in its buffer run: again.
                self.realtime.push(realtime::FEED_HOLD);
            }
        }
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
        let (byte, change) = self.feed.on_report(feed_override::reported(&status.other));
        self.realtime.extend(byte);
        let motion_done = self.motion_finished(&status);
        if let Some(wco) = &status.wco {
            self.last_wco = Some(wco.clone());
        }
        self.last_status = Some(status.clone());
        self.events.push_back(Event::Status(status));
        match change {
            Some(Change::Reported(percent)) => {
                self.events.push_back(Event::FeedOverride { percent });
            }
            Some(Change::NotTaken { asked, reported }) => {
                self.events
                    .push_back(Event::FeedOverrideNotTaken { asked, reported });
            }
            None => {}
        }
        if motion_done {
            self.events.push_back(Event::MotionDone);
        }
    }

    /// An `Idle` report after an interrupt proves the machine stands only with the
    /// controller's own evidence that nothing is left: every line sent answered, the
    /// planner and the receive buffer empty (`Bf:`: every block free, and as many bytes as
    /// the buffer holds or any report showed free), and the report before it `Idle` too. One
    /// `Idle` alone may be a controller starved between two moves, with more lines on their
    /// way to it.
    fn idle_with_nothing_left(&self, status: &Status) -> bool {
        let previous_idle = self
            .last_status
            .as_ref()
            .is_some_and(|last| last.state == MachineState::Idle);
        let blocks = self.planner_blocks.or(self.max_blocks_free);
        let buffers_empty = status.buffer.is_some_and(|b| {
            blocks.is_some_and(|blocks| b.planner_blocks_free >= blocks)
                && b.rx_bytes_free as usize + 1 >= self.rx_size
                && b.rx_bytes_free >= self.max_rx_free
        });
        self.in_flight.is_empty() && buffers_empty && previous_idle
    }

    /// The state reported before the first line; see [the module docs](self#connecting-the-state-before-the-first-line).
    fn on_start_state(&mut self, state: &MachineState) {
        match state {
            MachineState::Idle | MachineState::Check => self.begin(),
            MachineState::Hold if !self.reset_at_start => {
                self.reset_at_start = true;
                self.reset_pending = true;
                self.realtime.push(realtime::SOFT_RESET);
            }
            MachineState::Alarm if self.config.unlock => {
                self.aux_queue.push_front(Aux::Unlock);
                self.begin();
            }
            MachineState::Alarm => self.stop(StopReason::AlarmAtStart),
            other => self.stop(StopReason::Busy {
                state: busy_state(other),
            }),
        }
    }

    /// `status` is the first report since every line was acknowledged that shows the
    /// motion finished; see the module docs.
    fn motion_finished(&mut self, status: &Status) -> bool {
        if self.phase != Phase::Done || self.motion_done {
            return false;
        }
        if status.state == MachineState::Idle {
            self.idle_reports += 1;
        } else {
            self.idle_reports = 0;
        }
        let blocks = self.planner_blocks.or(self.max_blocks_free);
        self.motion_done = match (status.buffer, blocks) {
            (Some(_), Some(blocks)) => status.planner_empty(blocks),
            _ => self.idle_reports >= 2,
        };
        self.motion_done
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

/// Bytes of a receive buffer of `rx_size` the streamer leaves free while lines are in
/// flight, so that real-time bytes get through a link that stops at a full buffer (see
/// [the module docs](self#character-counting)): an eighth of a grblHAL buffer, more than
/// the 100 bytes grblHAL's simulator wants free of its 1024. None of grbl's 128 bytes on an
/// AVR: its receive interrupt takes real-time bytes whatever the buffer holds
/// (`serial.c`), and its buffer has none to spare.
pub fn rx_reserve(rx_size: usize) -> usize {
    if rx_size <= DEFAULT_RX_SIZE {
        0
    } else {
        rx_size / 8
    }
}

/// A busy state in words, for [`StopReason::Busy`].
fn busy_state(state: &MachineState) -> String {
    match state {
        MachineState::Run => "running",
        MachineState::Jog => "jogging",
        MachineState::Home => "homing",
        MachineState::Hold => "still held after a soft reset",
        MachineState::Door => "held by an open safety door",
        MachineState::Sleep => "asleep",
        MachineState::Tool => "waiting for a tool change",
        MachineState::Other(name) => name,
        MachineState::Idle | MachineState::Alarm | MachineState::Check => "ready",
    }
    .to_owned()
}

/// The N number of a line (`N120 G1 …`), if its first word is one.
fn line_number(text: &str) -> Option<u32> {
    let rest = text.trim_start().strip_prefix(['N', 'n'])?.trim_start();
    let digits = rest
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(rest.len());
    rest.get(..digits)?.parse().ok()
}
