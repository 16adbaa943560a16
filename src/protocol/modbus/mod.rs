//! Modbus: the planned path streamed to a controller as segments through the ring of
//! holding registers that `docs/modbus.md` defines, as sans-I/O values and a state
//! machine. No socket, no serial port, no clock: a later transport (tokio-modbus over TCP
//! or RTU) carries the [`Request`]s and brings back the answers.
//!
//! - [`map`]: the register map as values: addresses, control bits, alarm codes, the word
//!   order of 32- and 64-bit values, the slots that carry [`Segment`]s (sequence
//!   number, CRC), the identification and status blocks decoded.
//! - [`RingWriter`]: one program streamed through the ring: what to request next, what
//!   the answers mean.
//!
//! The simulated controller's side (`whirl_sim::modbus`) is written apart from this one,
//! from the same document, so that a misreading shared by both cannot pass; the two meet
//! in `tests/integration/modbus_map.rs`.
//!
//! # The stream
//!
//! [`RingWriter::poll`] is told the time and gives the next request, or none while it
//! waits; [`RingWriter::response`] takes the answer (or the exception),
//! [`RingWriter::timeout`] says none came. One request is outstanding at a time, as on a
//! Modbus RTU line. The writer reads the identification block, checks the controller is
//! idle, flushes the ring (`ABORT`), fills it, sets `RUN`, keeps it full as `TAIL` moves,
//! feeds the watchdog, sets `END` after the last segment and waits for the state to
//! read done ([`WriterEvent::Done`]).
//!
//! **Back-pressure.** The writer writes a slot only while the ring has room by the last
//! `TAIL` it read: (`HEAD` + 1) mod N ≠ `TAIL`. `TAIL` only moves forward between flushes,
//! so a stale value can only under-state the room. While the ring is full it writes
//! nothing but the watchdog and reads the status every poll interval.
//!
//! **Sequence numbers** are `first_sequence` plus the segment's index, wrapping past
//! 4 294 967 295 to 1. A segment's slot is written, then published by the `HEAD` write;
//! the writer moves on to the next segment only when that `HEAD` write is answered, so
//! no number is skipped, and none is published twice.
//!
//! **Re-sending.** After a timeout the same request is sent again, unchanged, and every
//! request is idempotent: the slot is not yet published when it is re-written (the
//! controller does not look at it, and the same registers land again); `HEAD` is written
//! as an absolute index, so a second copy publishes nothing more; the control word's
//! commands are edges, so the same value twice is one command; the watchdog counts only
//! changes. A re-sent slot write that the controller receives after it was published is
//! accepted because it changes nothing. So a lost answer never repeats or skips a segment.
//!
//! **Alarms.** An alarm in the status ends the stream with [`WriterEvent::Alarm`]; so does
//! an exception 04 (the controller refused a slot at the `HEAD` write), once the status
//! read after it says which alarm. Other exceptions, malformed answers, repeated timeouts
//! and a ring flushed under the stream end it with [`WriterEvent::Failed`].
//!
//! **Starting on a held controller.** A run that stopped leaves the controller held on the
//! path (below). The next run (a resume, re-entering along the groove) flushes that ring
//! with the same `ABORT` every start writes, which the map allows in any state, and
//! streams. A controller that is running (another program) or in alarm is refused before
//! anything is written.
//!
//! **Stopping.** [`RingWriter::stop`] ends the stream with the machine held where it is,
//! for an interrupted bridge: no more slots or `HEAD` writes, a `HOLD` edge (the bit
//! written 0 first, so that it rises whatever another client left in `CONTROL`), status
//! reads until the state is held or idle and the position reads the same twice (held also
//! covers the slowing down), then `CONTROL` = 0: `RUN` cleared, so the controller takes
//! nothing more and its watchdog, disarmed, raises no alarm once the bridge is gone
//! ([`WriterEvent::Stopped`]). The wait for the stand has its limit,
//! [`WriterOptions::stand_timeout`]; past it the stream fails ([`WriterError::NotHeld`])
//! with `RUN` left set, so that the watchdog stops the machine once the bridge stops
//! feeding it. Done instead (everything had been published and executed) is
//! [`WriterEvent::Done`]: nothing is left to resume.
//!
//! **Stalls.** With [`WriterOptions::stall_timeout`], a controller that shows nothing new
//! for that long (no segment published, and `STATE`, `TAIL`, `EXECUTED_SEQ` and the
//! position as they were) is stopped as above, after [`WriterEvent::Stalled`]. A hold
//! another client or the controller made counts toward it; the caller's own
//! [`RingWriter::hold`] does not, until its [`RingWriter::resume`].
//!
//! **Where the controller is.** [`RingWriter::executed`] counts the segments the
//! controller reports executed (`EXECUTED_SEQ` since the start's flush), and
//! [`RingWriter::taken`] those it has taken into its motion queue (`TAIL`), which may have
//! run in part: a stopped run resumes at the first segment not executed.

pub mod map;

use std::collections::VecDeque;
use std::fmt;
use std::time::Duration;

use thiserror::Error;

use crate::post::modbus::{check_rate, Segment, SegmentError};

use map::{control, reg, AlarmReport, Identification, MapError, State, Status, SLOT_SIZE};

/// A request to the controller: function codes 03, 06 and 16, unit id [`map::UNIT_ID`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// FC03, read holding registers.
    ReadHolding {
        /// First register.
        address: u16,
        /// How many.
        count: u16,
    },
    /// FC06, write single register.
    WriteSingle {
        /// The register.
        address: u16,
        /// Its new value.
        value: u16,
    },
    /// FC16, write multiple registers.
    WriteMultiple {
        /// First register.
        address: u16,
        /// The values, in address order.
        values: Vec<u16>,
    },
}

impl Request {
    /// Whether `response` can be this request's answer: a read's as many registers as it
    /// asked for, an FC06's echo of its address and value, an FC16's address and count. (A
    /// read cannot tell its answer from another read's of the same length: Modbus RTU
    /// carries no transaction number.)
    pub fn is_answered_by(&self, response: &Response) -> bool {
        match (self, response) {
            (Request::ReadHolding { count, .. }, Response::ReadHolding(values)) => {
                values.len() == usize::from(*count)
            }
            (
                Request::WriteSingle { address, value },
                Response::WriteSingle {
                    address: a,
                    value: v,
                },
            ) => a == address && v == value,
            (
                Request::WriteMultiple { address, values },
                Response::WriteMultiple { address: a, count },
            ) => a == address && usize::from(*count) == values.len(),
            _ => false,
        }
    }
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Request::ReadHolding { address, count } => {
                write!(f, "FC03 read {count} registers at {address}")
            }
            Request::WriteSingle { address, value } => {
                write!(f, "FC06 write {value:#06x} to register {address}")
            }
            Request::WriteMultiple { address, values } => {
                write!(f, "FC16 write {} registers at {address}", values.len())
            }
        }
    }
}

/// A normal answer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// FC03: the registers read.
    ReadHolding(Vec<u16>),
    /// FC06: the request echoed.
    WriteSingle {
        /// The register.
        address: u16,
        /// The value written.
        value: u16,
    },
    /// FC16: the first register and how many were written.
    WriteMultiple {
        /// First register.
        address: u16,
        /// How many.
        count: u16,
    },
}

/// An exception answer (the Modbus application protocol's exception codes the map uses).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum Exception {
    /// 01: the function code is not served.
    #[error("exception 01 (illegal function)")]
    IllegalFunction,
    /// 02: a register of the request is not mapped or not writable.
    #[error("exception 02 (illegal data address)")]
    IllegalDataAddress,
    /// 03: a quantity or a value the map does not allow.
    #[error("exception 03 (illegal data value)")]
    IllegalDataValue,
    /// 04: the controller could not do it: a refused slot, or an alarm.
    #[error("exception 04 (server device failure)")]
    ServerDeviceFailure,
    /// 06: not now; retry later.
    #[error("exception 06 (server device busy)")]
    ServerDeviceBusy,
}

/// How a [`RingWriter`] streams.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WriterOptions {
    /// The first segment's sequence number (not 0). After the flush the writer starts
    /// with, the controller accepts any.
    pub first_sequence: u32,
    /// How often the status is read while streaming.
    pub poll_interval: Duration,
    /// How many times a request is re-sent after timeouts before the stream fails.
    pub max_retries: u32,
    /// Stop (see the module docs) when the controller shows nothing new for this long;
    /// `None` waits.
    pub stall_timeout: Option<Duration>,
    /// How long a stop waits for the status to read held or idle after it began: the
    /// machine's time to stop from full speed, and a margin.
    pub stand_timeout: Duration,
}

impl Default for WriterOptions {
    fn default() -> WriterOptions {
        WriterOptions {
            first_sequence: 1,
            poll_interval: Duration::from_millis(50),
            max_retries: 3,
            stall_timeout: None,
            stand_timeout: Duration::from_secs(10),
        }
    }
}

/// Something that happened in the stream.
#[derive(Debug, Clone, PartialEq)]
pub enum WriterEvent {
    /// The identification block was read and accepted.
    Identified(Identification),
    /// A segment was published: its slot written and `HEAD` moved past it.
    Published {
        /// Its sequence number.
        sequence: u32,
        /// The slot it went to.
        slot: u16,
    },
    /// A status read.
    Status(Status),
    /// The controller is in alarm; the stream is over.
    Alarm(AlarmReport),
    /// Every segment executed; the stream is over.
    Done,
    /// The caller's abort was written: the controller stops and flushes its ring; the
    /// stream is over.
    Aborted,
    /// The controller showed nothing new for [`WriterOptions::stall_timeout`]: the writer
    /// stops the stream.
    Stalled {
        /// How long nothing changed.
        waited: Duration,
    },
    /// A stop is complete: the controller reads held or idle, `RUN` is cleared; the stream
    /// is over.
    Stopped,
    /// The stream cannot go on.
    Failed(WriterError),
    /// `FEED_OVERRIDE` was written and echoed: the controller runs at this percent of the
    /// programmed feed.
    FeedOverride(u16),
    /// The controller refused the `FEED_OVERRIDE` write: exception 02, a map without the
    /// register, or another exception. The stream goes on at the override it had.
    FeedOverrideRefused {
        /// The percent asked.
        percent: u16,
        /// The answer.
        exception: Exception,
    },
}

/// Why a stream failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WriterError {
    /// The first sequence number was 0, which the map never uses.
    #[error("the first sequence number must not be 0")]
    ZeroSequence,
    /// The identification or status block.
    #[error(transparent)]
    Map(#[from] MapError),
    /// The program against the controller's segment rate.
    #[error(transparent)]
    Segments(#[from] SegmentError),
    /// The controller was not idle, held or done when the stream began; nothing was
    /// written.
    #[error(
        "the controller is {}, not idle, held or done; nothing was written",
        not_ready(.0)
    )]
    NotReady(Status),
    /// A stop's `HOLD` edge was written, but the status did not read held or idle in time.
    #[error(
        "the controller did not stand within {waited:?} of the stop's HOLD edge (state \
         {state:?}); RUN is left set, so that its watchdog stops it once the bridge is gone"
    )]
    NotHeld {
        /// How long the writer waited.
        waited: Duration,
        /// The state it read last.
        state: State,
    },
    /// The controller answered with an exception.
    #[error("{request}: {exception}")]
    Exception {
        /// What was asked.
        request: Request,
        /// The answer.
        exception: Exception,
    },
    /// An answer that does not fit the request.
    #[error("{request}: answered {response:?}")]
    BadResponse {
        /// What was asked.
        request: Request,
        /// The answer.
        response: Response,
    },
    /// An answer or a timeout with no request outstanding (a caller's bug).
    #[error("{0} with no request outstanding")]
    Unexpected(&'static str),
    /// No answer to a request sent `attempts` times.
    #[error("{request}: no answer after {attempts} attempts")]
    NoAnswer {
        /// What was asked.
        request: Request,
        /// How often it was sent.
        attempts: u32,
    },
    /// `HEAD` does not read what the writer wrote: someone flushed the ring.
    #[error(
        "the ring was flushed under the stream: HEAD reads {read}, the writer wrote {written}"
    )]
    RingReset {
        /// What the writer wrote.
        written: u16,
        /// What it reads.
        read: u16,
    },
}

/// A refused start's state, in words.
fn not_ready(status: &Status) -> String {
    match (status.state, status.alarm) {
        (_, Some(alarm)) => format!("in {alarm}"),
        (State::Running, None) => "running (another program is under way)".into(),
        (state, None) => format!("{state:?}"),
    }
}

/// What a request is for, to read its answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Purpose {
    Identify,
    Inspect,
    Status,
    Control(u16),
    Slot,
    Head(u16),
    Watchdog,
    FeedOverride(u16),
}

/// When the outstanding request goes (again).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Send {
    /// Sent; waiting for its answer.
    Sent,
    /// At the next poll (after a timeout).
    Again,
    /// Not before this time (after exception 06).
    NotBefore(Duration),
}

#[derive(Debug, Clone)]
struct Outstanding {
    request: Request,
    purpose: Purpose,
    attempts: u32,
    send: Send,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Identify,
    Inspect,
    ClearControl,
    Abort,
    Stream,
    /// A stop under way (see the module docs), begun at `since`.
    Stopping {
        since: Duration,
    },
    Finished,
}

/// What the writer compares between status reads to tell that the controller did
/// something: its state, `TAIL`, `EXECUTED_SEQ` and position.
type Seen = (State, u16, u32, i32, i32, i64);

fn seen(status: &Status) -> Seen {
    (
        status.state,
        status.tail,
        status.executed,
        status.x,
        status.z,
        status.c,
    )
}

/// One program streamed through the ring (see the module docs).
#[derive(Debug, Clone)]
pub struct RingWriter {
    segments: Vec<Segment>,
    options: WriterOptions,
    phase: Phase,
    ident: Option<Identification>,
    outstanding: Option<Outstanding>,
    now: Duration,
    /// Segments published.
    published: usize,
    /// The next segment's slot is written, its `HEAD` write not yet answered.
    staged: bool,
    head: u16,
    /// `TAIL` as last read.
    tail: u16,
    /// `RUN` written.
    run: bool,
    /// `END` written.
    end: bool,
    /// An exception 04 came; the next status read says why.
    refused: Option<Request>,
    /// `EXECUTED_SEQ` as last read since the start's flush.
    executed: u32,
    /// The caller's hold is on (no resume since): the stall clock does not run.
    caller_held: bool,
    /// When the controller last showed something new, and what it showed.
    progressed: Duration,
    last_seen: Option<Seen>,
    /// A stop's `CONTROL` = 0 write, once the controller stands, is under way.
    standing: bool,
    /// The caller's commands, as control words still to write: each edge followed by the
    /// levels alone, so that the next command is a new edge.
    commands: VecDeque<u16>,
    /// A feed override asked and not yet written.
    feed_override: Option<u16>,
    next_status: Duration,
    next_watchdog: Duration,
    watchdog: u16,
    events: VecDeque<WriterEvent>,
}

impl RingWriter {
    /// A writer for `segments` (see [`segments`](crate::post::modbus::segments)), not started: the first
    /// [`RingWriter::poll`] starts it.
    pub fn new(segments: Vec<Segment>, options: WriterOptions) -> Result<RingWriter, WriterError> {
        if options.first_sequence == 0 {
            return Err(WriterError::ZeroSequence);
        }
        Ok(RingWriter {
            segments,
            options,
            phase: Phase::Identify,
            ident: None,
            outstanding: None,
            now: Duration::ZERO,
            published: 0,
            staged: false,
            head: 0,
            tail: 0,
            run: false,
            end: false,
            refused: None,
            executed: 0,
            caller_held: false,
            progressed: Duration::ZERO,
            last_seen: None,
            standing: false,
            commands: VecDeque::new(),
            feed_override: None,
            next_status: Duration::ZERO,
            next_watchdog: Duration::ZERO,
            watchdog: 0,
            events: VecDeque::new(),
        })
    }

    /// The request to send now, if any. `now` is any monotonic time (the writer keeps its
    /// status polls and watchdog writes apart by it).
    pub fn poll(&mut self, now: Duration) -> Option<Request> {
        self.now = now;
        self.check_clocks(now);
        if self.phase == Phase::Finished {
            return None;
        }
        if let Some(o) = &mut self.outstanding {
            let due = match o.send {
                Send::Sent => false,
                Send::Again => true,
                Send::NotBefore(t) => now >= t,
            };
            if !due {
                return None;
            }
            o.send = Send::Sent;
            return Some(o.request.clone());
        }
        let (request, purpose) = self.next_request(now)?;
        self.outstanding = Some(Outstanding {
            request: request.clone(),
            purpose,
            attempts: 1,
            send: Send::Sent,
        });
        Some(request)
    }

    /// The answer to the outstanding request: its response or its exception.
    pub fn response(&mut self, result: Result<Response, Exception>) {
        if self.phase == Phase::Finished {
            return;
        }
        let Some(mut o) = self.outstanding.take() else {
            return self.fail(WriterError::Unexpected("a response"));
        };
        match (result, o.purpose) {
            (Ok(response), _) => self.answered(o, response),
            (Err(Exception::ServerDeviceBusy), _) => {
                o.send = Send::NotBefore(self.now + self.options.poll_interval);
                self.outstanding = Some(o);
            }
            // Not a reason to end the stream: it goes on at the override it had.
            (Err(exception), Purpose::FeedOverride(percent)) => {
                self.events
                    .push_back(WriterEvent::FeedOverrideRefused { percent, exception });
            }
            (Err(Exception::ServerDeviceFailure), _)
                if matches!(self.phase, Phase::Stream | Phase::Stopping { .. }) =>
            {
                // A refused slot (or an alarm): the status says which.
                self.refused = Some(o.request);
            }
            (Err(exception), _) => self.fail(WriterError::Exception {
                request: o.request,
                exception,
            }),
        }
    }

    /// No answer came to the outstanding request: it is sent again, unchanged, at the
    /// next poll, up to [`WriterOptions::max_retries`] times.
    pub fn timeout(&mut self) {
        if self.phase == Phase::Finished {
            return;
        }
        match &mut self.outstanding {
            Some(o) if o.send == Send::Sent => {
                if o.attempts > self.options.max_retries {
                    let (request, attempts) = (o.request.clone(), o.attempts);
                    self.fail(WriterError::NoAnswer { request, attempts });
                } else {
                    o.attempts += 1;
                    o.send = Send::Again;
                }
            }
            _ => self.fail(WriterError::Unexpected("a timeout")),
        }
    }

    /// Feed hold (`HOLD`): the controller stops along the path and holds its position;
    /// slots keep filling the ring. Sent ahead of any slot. The stall clock stops until
    /// [`RingWriter::resume`].
    pub fn hold(&mut self) {
        self.caller_held = true;
        self.command(control::HOLD);
    }

    /// Cycle start after a hold (`RESUME`); the stall clock starts again from now.
    pub fn resume(&mut self) {
        self.caller_held = false;
        self.progressed = self.now;
        self.command(control::RESUME);
    }

    /// Feed override (`FEED_OVERRIDE`, register 40): the controller runs at `percent` of
    /// the programmed feed (10–200; the caller checks the cap). Written once streaming, ahead
    /// of any slot; the echo confirms it ([`WriterEvent::FeedOverride`]); a map without the
    /// register answers exception 02 ([`WriterEvent::FeedOverrideRefused`]) and the stream
    /// goes on. Only the latest value asked is written.
    pub fn feed_override(&mut self, percent: u16) {
        if self.phase != Phase::Finished {
            self.feed_override = Some(percent);
        }
    }

    /// Ends the stream with the machine held where it is (see the module docs): once the
    /// controller stands, [`WriterEvent::Stopped`]. Before streaming began, it ends at
    /// once: nothing was sent that moves the machine.
    pub fn stop(&mut self) {
        match self.phase {
            Phase::Stream => self.begin_stop(),
            Phase::Stopping { .. } | Phase::Finished => {}
            _ => {
                self.events.push_back(WriterEvent::Stopped);
                self.outstanding = None;
                self.phase = Phase::Finished;
            }
        }
    }

    /// Segments the controller reports executed (`EXECUTED_SEQ`), counted from the first.
    pub fn executed(&self) -> usize {
        if self.executed == 0 {
            return 0;
        }
        // Sequence numbers run 1 ..= u32::MAX, so their offsets count modulo u32::MAX.
        let span = u64::from(u32::MAX);
        let offset =
            (u64::from(self.executed) + span - u64::from(self.options.first_sequence)) % span;
        (offset as usize + 1).min(self.published)
    }

    /// Segments the controller has taken from the ring (`TAIL` past them): executed, being
    /// executed, or queued for its motion.
    pub fn taken(&self) -> usize {
        let Some(ident) = self.ident else {
            return 0;
        };
        let n = ident.slots;
        let in_ring = (self.head + n - self.tail) % n;
        self.published - usize::from(in_ring)
    }

    /// The stall's and the stand's clocks, at `now`.
    fn check_clocks(&mut self, now: Duration) {
        match self.phase {
            Phase::Stream if !self.caller_held => {
                let Some(limit) = self.options.stall_timeout else {
                    return;
                };
                let waited = now.saturating_sub(self.progressed);
                if waited >= limit {
                    self.events.push_back(WriterEvent::Stalled { waited });
                    self.begin_stop();
                }
            }
            Phase::Stopping { since } if !self.standing => {
                let waited = now.saturating_sub(since);
                if waited >= self.options.stand_timeout {
                    let state = self.last_seen.map_or(State::Running, |s| s.0);
                    self.fail(WriterError::NotHeld { waited, state });
                }
            }
            _ => {}
        }
    }

    /// Stops publishing and writes the `HOLD` edge: the bit cleared, then set.
    fn begin_stop(&mut self) {
        self.phase = Phase::Stopping { since: self.now };
        // A request waiting to be sent again is dropped: a slot or HEAD the stop no longer
        // publishes, a status or watchdog the stop writes anew, a command the stop
        // supersedes. One awaiting its answer keeps it.
        if self
            .outstanding
            .as_ref()
            .is_some_and(|o| o.send != Send::Sent)
        {
            self.outstanding = None;
        }
        self.commands.clear();
        self.commands.extend([0, control::HOLD]);
    }

    /// Stop and flush the ring (`ABORT`); once the controller has the write, the stream
    /// ends with [`WriterEvent::Aborted`]. Before streaming began, it ends at once: nothing
    /// was sent that moves the machine. During a stop, it goes ahead of what the stop
    /// still had to write.
    pub fn abort(&mut self) {
        if matches!(self.phase, Phase::Stopping { .. }) {
            self.commands.clear();
            self.command(control::ABORT);
        } else if matches!(self.phase, Phase::Stream) {
            self.command(control::ABORT);
        } else if self.phase != Phase::Finished {
            self.events.push_back(WriterEvent::Aborted);
            self.outstanding = None;
            self.phase = Phase::Finished;
        }
    }

    /// Queues `edge` and then the levels alone.
    fn command(&mut self, edge: u16) {
        if self.phase != Phase::Finished {
            self.commands.extend([edge, 0]);
        }
    }

    /// The control word's levels as written.
    fn levels(&self) -> u16 {
        (if self.run { control::RUN } else { 0 }) | (if self.end { control::END } else { 0 })
    }

    /// The next event, oldest first.
    pub fn next_event(&mut self) -> Option<WriterEvent> {
        self.events.pop_front()
    }

    /// The stream is over (done, alarm or failed); nothing more will be requested.
    pub fn is_finished(&self) -> bool {
        self.phase == Phase::Finished
    }

    /// Sequence number of the segment at `index`.
    fn sequence(&self, index: usize) -> u32 {
        let offset = u64::from(self.options.first_sequence) - 1 + index as u64;
        (offset % u64::from(u32::MAX)) as u32 + 1
    }

    fn next_request(&mut self, now: Duration) -> Option<(Request, Purpose)> {
        let read = |address, count| Request::ReadHolding { address, count };
        match self.phase {
            Phase::Identify => Some((read(reg::MAGIC, reg::IDENT_LEN), Purpose::Identify)),
            Phase::Inspect => Some((read(reg::STATE, reg::STATUS_LEN), Purpose::Inspect)),
            Phase::ClearControl => Some(control_write(0)),
            Phase::Abort => Some(control_write(control::ABORT)),
            Phase::Stream => self.stream_request(now),
            Phase::Stopping { .. } => self.stop_request(now),
            Phase::Finished => None,
        }
    }

    fn stream_request(&mut self, now: Duration) -> Option<(Request, Purpose)> {
        let ident = self.ident?;
        let slots = ident.slots;
        let status = (
            Request::ReadHolding {
                address: reg::STATE,
                count: reg::STATUS_LEN,
            },
            Purpose::Status,
        );
        if self.refused.is_some() {
            return Some(status);
        }
        if let Some(edge) = self.commands.pop_front() {
            return Some(control_write(self.levels() | edge));
        }
        if let Some(value) = self.feed_override.take() {
            return Some((
                Request::WriteSingle {
                    address: reg::FEED_OVERRIDE,
                    value,
                },
                Purpose::FeedOverride(value),
            ));
        }
        if self.staged {
            let value = (self.head + 1) % slots;
            return Some((
                Request::WriteSingle {
                    address: reg::HEAD,
                    value,
                },
                Purpose::Head(value),
            ));
        }
        let watchdog_interval = ident.watchdog_timeout / 4;
        if self.run && !self.end && now >= self.next_watchdog {
            self.watchdog = self.watchdog.wrapping_add(1);
            self.next_watchdog = now + watchdog_interval;
            return Some((
                Request::WriteSingle {
                    address: reg::WATCHDOG,
                    value: self.watchdog,
                },
                Purpose::Watchdog,
            ));
        }
        if self.run && now >= self.next_status {
            self.next_status = now + self.options.poll_interval;
            return Some(status);
        }
        let all = self.published == self.segments.len();
        let full = (self.head + 1) % slots == self.tail;
        if !all && !full {
            let sequence = self.sequence(self.published);
            let values = self.segments[self.published]
                .encode(sequence, ident.word_order)
                .to_vec();
            return Some((
                Request::WriteMultiple {
                    address: reg::RING + SLOT_SIZE * self.head,
                    values,
                },
                Purpose::Slot,
            ));
        }
        if !self.run {
            // The ring is filled as far as it goes: start.
            self.next_status = now + self.options.poll_interval;
            self.next_watchdog = now + watchdog_interval;
            let end = if all { control::END } else { 0 };
            return Some(control_write(control::RUN | end));
        }
        if all && !self.end {
            return Some(control_write(control::RUN | control::END));
        }
        None
    }

    /// What a stop writes: its edges, the watchdog (the controller still depends on the
    /// bridge until `RUN` is cleared), status reads, and `CONTROL` = 0 once it stands.
    fn stop_request(&mut self, now: Duration) -> Option<(Request, Purpose)> {
        let ident = self.ident?;
        let status = (
            Request::ReadHolding {
                address: reg::STATE,
                count: reg::STATUS_LEN,
            },
            Purpose::Status,
        );
        if self.refused.is_some() {
            return Some(status);
        }
        if let Some(edge) = self.commands.pop_front() {
            return Some(control_write(self.levels() | edge));
        }
        if self.standing {
            return Some(control_write(0));
        }
        if self.run && !self.end && now >= self.next_watchdog {
            self.watchdog = self.watchdog.wrapping_add(1);
            self.next_watchdog = now + ident.watchdog_timeout / 4;
            return Some((
                Request::WriteSingle {
                    address: reg::WATCHDOG,
                    value: self.watchdog,
                },
                Purpose::Watchdog,
            ));
        }
        if now >= self.next_status {
            self.next_status = now + self.options.poll_interval;
            return Some(status);
        }
        None
    }

    fn answered(&mut self, o: Outstanding, response: Response) {
        if !o.request.is_answered_by(&response) {
            return self.fail(WriterError::BadResponse {
                request: o.request,
                response,
            });
        }
        let registers = match response {
            Response::ReadHolding(values) => values,
            _ => Vec::new(),
        };
        match o.purpose {
            Purpose::Identify => self.identified(&registers),
            Purpose::Inspect => match self.decode_status(&registers) {
                Some(status) if matches!(status.state, State::Idle | State::Done | State::Held) => {
                    self.events.push_back(WriterEvent::Status(status));
                    self.phase = Phase::ClearControl;
                }
                Some(status) => self.fail(WriterError::NotReady(status)),
                None => {}
            },
            Purpose::Status => {
                if let Some(status) = self.decode_status(&registers) {
                    self.on_status(status);
                }
            }
            Purpose::Control(value) => match self.phase {
                Phase::ClearControl => self.phase = Phase::Abort,
                Phase::Abort => {
                    // At rest, the flush is complete when the write is answered (moving,
                    // HEAD writes are refused with 06 until it is, and sent again).
                    self.head = 0;
                    self.tail = 0;
                    self.phase = Phase::Stream;
                    self.progressed = self.now;
                }
                _ if value & control::ABORT != 0 => {
                    self.events.push_back(WriterEvent::Aborted);
                    self.phase = Phase::Finished;
                }
                Phase::Stopping { .. } if self.standing => {
                    self.events.push_back(WriterEvent::Stopped);
                    self.phase = Phase::Finished;
                }
                _ => {
                    self.run |= value & control::RUN != 0;
                    self.end |= value & control::END != 0;
                }
            },
            Purpose::Slot => self.staged = true,
            Purpose::Head(value) => {
                self.events.push_back(WriterEvent::Published {
                    sequence: self.sequence(self.published),
                    slot: self.head,
                });
                self.head = value;
                self.staged = false;
                self.published += 1;
                self.progressed = self.now;
            }
            Purpose::Watchdog => {}
            Purpose::FeedOverride(percent) => {
                self.events.push_back(WriterEvent::FeedOverride(percent));
            }
        }
    }

    fn identified(&mut self, registers: &[u16]) {
        let checked = Identification::decode(registers)
            .map_err(WriterError::from)
            .and_then(|ident| {
                check_rate(&self.segments, ident.max_segment_rate)?;
                Ok(ident)
            });
        match checked {
            Ok(ident) => {
                self.ident = Some(ident);
                self.events.push_back(WriterEvent::Identified(ident));
                self.phase = Phase::Inspect;
            }
            Err(e) => self.fail(e),
        }
    }

    /// The status, or `None` after failing the stream on a block that does not decode.
    fn decode_status(&mut self, registers: &[u16]) -> Option<Status> {
        let order = self.ident.map(|i| i.word_order).unwrap_or_default();
        match Status::decode(registers, order) {
            Ok(status) => Some(status),
            Err(e) => {
                self.fail(e.into());
                None
            }
        }
    }

    fn on_status(&mut self, status: Status) {
        self.events.push_back(WriterEvent::Status(status));
        if let Some(alarm) = status.alarm {
            self.events.push_back(WriterEvent::Alarm(alarm));
            self.phase = Phase::Finished;
            return;
        }
        if let Some(request) = self.refused.take() {
            return self.fail(WriterError::Exception {
                request,
                exception: Exception::ServerDeviceFailure,
            });
        }
        if status.head != self.head {
            return self.fail(WriterError::RingReset {
                written: self.head,
                read: status.head,
            });
        }
        self.tail = status.tail;
        self.executed = status.executed;
        let now = seen(&status);
        // Held reads from the edge on, while the machine slows down too: it stands once
        // its position reads the same twice.
        let still = self
            .last_seen
            .is_some_and(|last| (last.3, last.4, last.5) == (now.3, now.4, now.5));
        if self.last_seen != Some(now) {
            self.last_seen = Some(now);
            self.progressed = self.now;
        }
        if self.end && status.state == State::Done {
            self.events.push_back(WriterEvent::Done);
            self.phase = Phase::Finished;
        } else if matches!(self.phase, Phase::Stopping { .. })
            && self.commands.is_empty()
            && still
            && matches!(status.state, State::Held | State::Idle)
        {
            // The edge written and the machine at rest: RUN is cleared next.
            self.standing = true;
        }
    }

    fn fail(&mut self, error: WriterError) {
        self.events.push_back(WriterEvent::Failed(error));
        self.outstanding = None;
        self.phase = Phase::Finished;
    }
}

/// A write of the control word.
fn control_write(value: u16) -> (Request, Purpose) {
    (
        Request::WriteSingle {
            address: reg::CONTROL,
            value,
        },
        Purpose::Control(value),
    )
}

#[cfg(test)]
mod tests;
