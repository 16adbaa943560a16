//! A planned program streamed to a Modbus controller (`docs/modbus.md`): the sans-I/O
//! [`RingWriter`] driven over tokio-modbus, Modbus TCP or RTU.
//!
//! tokio-modbus's client has no timeout of its own, so every call gets one. After a timeout
//! (or a broken connection) the context is dropped and a new connection made, with a
//! backoff: a late answer on the old connection would otherwise be read as the answer to the
//! next request. The writer then re-sends the same request, which the map makes idempotent,
//! so a lost answer neither repeats nor skips a segment. A serial line is one wire however
//! often the port is reopened: its input is cleared on opening, and an answer that is not
//! the request's but the one before it's (a late answer, or one the line delivered twice)
//! is taken for a lost answer in the same way, not for a wrong one. Exception answers go to
//! the writer, which names them; a full ring is the writer's back-pressure (it waits on `TAIL`).
//!
//! The writer's clock is the wall clock times [`ModbusOptions::clock_scale`]: 1 for a
//! machine, the simulator's time scale in a dry run, so that status polls and watchdog
//! writes keep their meaning in the controller's time.
//!
//! # Ends
//!
//! A run that logged its start logs its end, whatever ends it, with the reason: done, an
//! alarm, the writer's failure, the caller's stop or abort, a stall
//! ([`ModbusOptions::stall_timeout`]), a controller that cannot be reached (at the start,
//! or once the reconnections after a lost connection run out), an answer the map does not
//! allow. The caller's stop and a stall are the writer's stop ([`RingWriter::stop`]): the
//! controller held where it stands, `RUN` cleared. So is a log that can no longer be
//! written: the controller is held first, then the run ends with the log's error. A run
//! that did not complete says where to resume ([`ModbusOutcome::resume_move`]); an error
//! once the controller was reached carries it too ([`ModbusError::Interrupted`]).

use super::control::{Command, Commands};
use super::progress::{MoveLines, Progress, ProgressFn, Unit};
use crate::log::{self, ExecLog, LogError};
use crate::post::modbus::Segment;
use crate::protocol::modbus::map::{reg, UNIT_ID};
use crate::protocol::modbus::{
    Exception, Request, Response, RingWriter, WriterError, WriterEvent, WriterOptions,
};
use std::net::SocketAddr;
use std::time::Duration;
use thiserror::Error;
use tokio::time::Instant;
use tokio_modbus::client::{Client, Context};
use tokio_modbus::{ExceptionCode, Slave};
use tokio_serial::SerialPortBuilderExt;

/// Where the controller is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ModbusLink {
    /// Modbus TCP.
    Tcp(SocketAddr),
    /// Modbus RTU on a serial line (8N1).
    Rtu {
        /// The port (a device or a pseudo-terminal).
        path: String,
        /// Baud rate.
        baud: u32,
    },
}

impl ModbusLink {
    /// `modbus-tcp` or `modbus-rtu`, as the log and the CLI name transports.
    pub fn transport(&self) -> &'static str {
        match self {
            ModbusLink::Tcp(_) => "modbus-tcp",
            ModbusLink::Rtu { .. } => "modbus-rtu",
        }
    }
}

impl std::fmt::Display for ModbusLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ModbusLink::Tcp(addr) => write!(f, "Modbus TCP {addr}"),
            ModbusLink::Rtu { path, baud } => write!(f, "Modbus RTU {path} at {baud} baud"),
        }
    }
}

/// How a program is streamed over Modbus.
pub struct ModbusOptions {
    /// The ring writer's settings (first sequence number, poll interval, retries, the
    /// stop's wait for the stand).
    pub writer: WriterOptions,
    /// Longest wait for one answer, wall time.
    pub timeout: Duration,
    /// First wait before reconnecting; it doubles up to [`ModbusOptions::max_backoff`].
    pub backoff: Duration,
    /// Longest wait before reconnecting.
    pub max_backoff: Duration,
    /// Connection attempts in a row before giving up.
    pub max_reconnects: u32,
    /// The writer's clock in wall seconds per second (see the module docs).
    pub clock_scale: f64,
    /// Hold and stop when the controller shows nothing new for this long, wall time (a hold
    /// another client or the controller made counts; the caller's own does not); `None`
    /// waits. See [`crate::protocol::modbus`], "Stalls".
    pub stall_timeout: Option<Duration>,
    /// Which move of the program each segment comes from
    /// ([`segment_moves`](crate::post::modbus::segment_moves)), so that
    /// [`ModbusOutcome::resume_move`] names a move; empty, the segments are the program and
    /// it counts segments.
    pub segment_moves: Vec<usize>,
    /// The program line of each move, so that a run that does not complete fills in
    /// [`ModbusOutcome::resume_line`] and logs it ([`log::Event::ResumeAt`]) just before its
    /// End, as the serial transport does; `None`: the caller knows no lines, and neither is
    /// done.
    pub lines: Option<MoveLines>,
    /// What is streamed, for the log.
    pub program: String,
    /// The controller's unit id (slave address); the map's is 1.
    pub unit: u8,
    /// The caller's hold, resume, stop and abort: the map's `HOLD`, `RESUME` and `ABORT`
    /// edges, written ahead of any slot; a stop is [`RingWriter::stop`].
    pub commands: Option<Commands>,
    /// Told how far the run is at every published segment and status read.
    pub on_progress: Option<ProgressFn>,
}

impl std::fmt::Debug for ModbusOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModbusOptions")
            .field("writer", &self.writer)
            .field("timeout", &self.timeout)
            .field("backoff", &self.backoff)
            .field("max_backoff", &self.max_backoff)
            .field("max_reconnects", &self.max_reconnects)
            .field("clock_scale", &self.clock_scale)
            .field("stall_timeout", &self.stall_timeout)
            .field("segment_moves", &self.segment_moves.len())
            .field("lines", &self.lines.is_some())
            .field("program", &self.program)
            .field("unit", &self.unit)
            .field("commands", &self.commands.is_some())
            .field("on_progress", &self.on_progress.is_some())
            .finish()
    }
}

impl Default for ModbusOptions {
    fn default() -> ModbusOptions {
        ModbusOptions {
            writer: WriterOptions::default(),
            timeout: Duration::from_millis(500),
            backoff: Duration::from_millis(50),
            max_backoff: Duration::from_secs(2),
            max_reconnects: 8,
            clock_scale: 1.0,
            stall_timeout: None,
            segment_moves: Vec::new(),
            lines: None,
            program: String::new(),
            unit: UNIT_ID,
            commands: None,
            on_progress: None,
        }
    }
}

/// What a stream did.
#[derive(Debug, Clone, PartialEq)]
pub struct ModbusOutcome {
    /// Every segment executed and the controller reads done.
    pub completed: bool,
    /// The caller aborted: the controller stopped and flushed its ring.
    pub aborted: bool,
    /// The run stopped with the controller held on the path (the caller's stop, or a
    /// stall), and why, in words.
    pub stopped: Option<String>,
    /// Segments in the program.
    pub segments: usize,
    /// Segments published to the ring.
    pub published: usize,
    /// The controller's alarm, if that ended the stream.
    pub alarm: Option<crate::protocol::modbus::map::AlarmReport>,
    /// Why the stream could not go on, if it could not.
    pub failure: Option<WriterError>,
    /// Where a run that did not complete resumes: the index in the program (see
    /// [`ModbusOptions::segment_moves`]) of the move of the first segment the controller
    /// did not report executed (`EXECUTED_SEQ`); `None` when completed.
    pub resume_move: Option<usize>,
    /// The program line (0-based) of `resume_move`, where the caller gave the moves' lines
    /// ([`ModbusOptions::lines`]).
    pub resume_line: Option<usize>,
    /// Calls that got no answer in time.
    pub timeouts: u32,
    /// New connections made after the first.
    pub reconnects: u32,
    /// From the first request to the end.
    pub wall_time: Duration,
    /// Bit times the requests and answers would take on an RTU line (8N1), the 3.5
    /// characters of silence that end each frame included ([`rtu_bits`]); for Modbus TCP
    /// what the same exchanges would cost on a serial line.
    pub rtu_bits: u64,
}

/// Bit times of one exchange on an RTU line at 10 bits a character (8N1, as the transport
/// opens the port): the request's frame and, if one came, the answer's, each its unit
/// address, PDU and CRC-16 plus the 3.5 characters of silence that end an RTU frame
/// (Modbus over Serial Line, 2.5.1.1).
pub fn rtu_bits(request: &Request, answer: Option<&Result<Response, Exception>>) -> u64 {
    let asked = match request {
        Request::ReadHolding { .. } | Request::WriteSingle { .. } => 5,
        Request::WriteMultiple { values, .. } => 6 + 2 * values.len() as u64,
    };
    let answered = match (answer, request) {
        (None, _) => None,
        (Some(Err(_)), _) => Some(2),
        (Some(Ok(_)), Request::ReadHolding { count, .. }) => Some(2 + 2 * u64::from(*count)),
        (Some(Ok(_)), _) => Some(5),
    };
    // Address 1 byte and CRC 2 around the PDU, then 3.5 characters of silence.
    let frame = |pdu: u64| (pdu + 3) * 10 + 35;
    frame(asked) + answered.map_or(0, frame)
}

/// Why a stream could not be carried out (an alarm, a stop or a writer failure is an
/// outcome).
#[derive(Debug, Error)]
pub enum ModbusError {
    /// The controller could not be reached, `attempts` times in a row.
    #[error("cannot reach {link} ({attempts} attempts): {error}")]
    Connect {
        /// Where.
        link: String,
        /// How often it was tried.
        attempts: u32,
        /// The last failure.
        error: std::io::Error,
    },
    /// The program cannot be streamed (a segment rate or a first sequence the map refuses).
    #[error(transparent)]
    Writer(#[from] WriterError),
    /// An exception code the map never uses.
    #[error("{request}: exception code {code:#04x}, which docs/modbus.md does not use")]
    UnknownException {
        /// What was asked.
        request: Request,
        /// The code.
        code: u8,
    },
    /// An answer of another function than the request's (a late answer on a serial line,
    /// a confused gateway).
    #[error("{request}: answered {answer}")]
    Mismatch {
        /// What was asked.
        request: Request,
        /// The answer.
        answer: String,
    },
    /// The executed-path log. Once the stream has begun, the controller was stopped
    /// (held, see [`RingWriter::stop`]) before the run ended with this.
    #[error(transparent)]
    Log(#[from] LogError),
    /// Any of the above once the stream had begun, with where to resume.
    #[error("{error}")]
    Interrupted {
        /// What ended it.
        error: Box<ModbusError>,
        /// As [`ModbusOutcome::resume_move`]: the controller's last report before it.
        resume_move: usize,
    },
}

impl ModbusError {
    /// Where to resume a stream that failed after it began.
    pub fn resume_move(&self) -> Option<usize> {
        match self {
            ModbusError::Interrupted { resume_move, .. } => Some(*resume_move),
            _ => None,
        }
    }
}

/// Streams `segments` to the controller at `link`, logging to `log`. Every run that
/// logged its start logs its end, whatever ends it, with the reason.
pub async fn stream_modbus(
    link: &ModbusLink,
    segments: Vec<Segment>,
    mut options: ModbusOptions,
    log: &mut ExecLog,
) -> Result<ModbusOutcome, ModbusError> {
    let total = segments.len();
    let progress = Told::new(
        &segments,
        options.writer.first_sequence,
        options.on_progress.take(),
    );
    // The stall in the writer's clock, as everything it times.
    let writer_options = WriterOptions {
        stall_timeout: options
            .stall_timeout
            .map(|limit| limit.mul_f64(options.clock_scale)),
        ..options.writer.clone()
    };
    let writer = RingWriter::new(segments, writer_options)?;
    log.write(
        0.0,
        log::Event::Start {
            program: options.program.clone(),
            lines: total,
            transport: link.transport().to_owned(),
        },
    )?;
    let mut run = Run {
        writer,
        log: Logger { log, failed: None },
        start: Instant::now(),
        commands: options.commands.take(),
        progress,
        stall_timeout: options.stall_timeout,
        stop_asked: None,
        outcome: ModbusOutcome {
            completed: false,
            aborted: false,
            stopped: None,
            segments: total,
            published: 0,
            alarm: None,
            failure: None,
            resume_move: None,
            resume_line: None,
            timeouts: 0,
            reconnects: 0,
            wall_time: Duration::ZERO,
            rtu_bits: 0,
        },
    };
    let mut connected = false;
    let result = run.stream(link, &options, &mut connected).await;
    run.outcome.wall_time = run.start.elapsed();
    let resume = {
        let executed = run.writer.executed();
        options
            .segment_moves
            .get(executed)
            .copied()
            .unwrap_or(executed)
    };
    let t = run.t();
    let failed = run.log.failed.take();
    let (completed, reason) = match (&result, &failed) {
        (Err(error), _) => (false, Some(error.to_string())),
        (Ok(()), Some(error)) => (false, Some(error.to_string())),
        (Ok(()), None) => (run.outcome.completed, run.outcome.reason()),
    };
    // A run that never reached the controller has nothing to resume.
    if !completed && (connected || result.is_ok()) {
        run.outcome.resume_move = Some(resume);
        run.outcome.resume_line = options.lines.as_ref().map(|lines| lines.line_of(resume));
        if let Some(line) = run.outcome.resume_line {
            // Best effort, as the End: what ended the run is what the caller hears.
            let _ = run.log.log.write(
                t,
                log::Event::ResumeAt {
                    line: line + 1,
                    possibly_run_to: None,
                },
            );
        }
    }
    // After a failed write the End may not land either; the failure is what the caller
    // hears.
    let ended = run.log.log.write(t, log::Event::End { completed, reason });
    let error = match (result, failed) {
        (Err(error), _) => Some(error),
        (Ok(()), Some(error)) => Some(ModbusError::Log(error)),
        (Ok(()), None) => {
            ended?;
            None
        }
    };
    match error {
        None => Ok(run.outcome),
        Some(error) if connected => Err(ModbusError::Interrupted {
            error: Box::new(error),
            resume_move: resume,
        }),
        Some(error) => Err(error),
    }
}

/// The executed-path log of a run: the first write that fails is kept, for the run to stop
/// the controller and then end with it; nothing more is written after it.
struct Logger<'a> {
    log: &'a mut ExecLog,
    failed: Option<LogError>,
}

impl Logger<'_> {
    fn write(&mut self, t: f64, event: log::Event) {
        if self.failed.is_none() {
            if let Err(error) = self.log.write(t, event) {
                self.failed = Some(error);
            }
        }
    }
}

/// A stream under way.
struct Run<'a> {
    writer: RingWriter,
    log: Logger<'a>,
    start: Instant,
    commands: Option<Commands>,
    progress: Told,
    /// [`ModbusOptions::stall_timeout`], for the words of a stall.
    stall_timeout: Option<Duration>,
    /// Why the writer was asked to stop, if it was: the outcome's words once it has.
    stop_asked: Option<String>,
    outcome: ModbusOutcome,
}

impl Run<'_> {
    /// Seconds since the run started, for the log.
    fn t(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Stops the writer (see [`RingWriter::stop`]) for `why`, unless a stop is under way.
    fn stop(&mut self, why: String) {
        if self.stop_asked.is_none() {
            self.stop_asked = Some(why);
            self.writer.stop();
        }
    }

    /// Drives the writer over the link until it has finished. `connected` is set once the
    /// first connection is made: from then on the controller may have moved.
    async fn stream(
        &mut self,
        link: &ModbusLink,
        options: &ModbusOptions,
        connected: &mut bool,
    ) -> Result<(), ModbusError> {
        // `None` once the writer has given up on a request: no new connection is made for it.
        let mut ctx = Some(connect(link, options).await?);
        *connected = true;
        // The request sent before the one outstanding: a late answer answers it.
        let mut previous: Option<Request> = None;
        while !self.writer.is_finished() {
            if let Some(error) = &self.log.failed {
                // The log is gone: the controller is held before the run ends with it.
                self.stop(format!("the log cannot be written ({error})"));
            }
            self.obey();
            let now = self.start.elapsed().mul_f64(options.clock_scale);
            match self.writer.poll(now) {
                Some(request) => {
                    let Some(conn) = ctx.as_mut() else {
                        break;
                    };
                    let answer = tokio::time::timeout(options.timeout, call(conn, &request)).await;
                    self.outcome.rtu_bits += rtu_bits(
                        &request,
                        match &answer {
                            Ok(Ok(answer)) => Some(answer),
                            _ => None,
                        },
                    );
                    let late = match &answer {
                        Ok(Ok(Ok(response))) if !request.is_answered_by(response) => previous
                            .as_ref()
                            .filter(|before| before.is_answered_by(response))
                            .map(|before| {
                                format!(
                                    "answered {response:?}, the answer to {before}, late on \
                                     the line"
                                )
                            }),
                        _ => None,
                    };
                    previous = Some(request.clone());
                    let lost = match answer {
                        _ if late.is_some() => late,
                        Ok(Ok(answer)) => {
                            self.writer.response(answer);
                            None
                        }
                        Ok(Err(Failure::Exception(code))) => {
                            return Err(ModbusError::UnknownException { request, code });
                        }
                        Ok(Err(Failure::Mismatch(answer))) => {
                            return Err(ModbusError::Mismatch { request, answer });
                        }
                        Ok(Err(Failure::Link(error))) => Some(error.to_string()),
                        Err(_) => Some(format!(
                            "no answer within {} ms",
                            options.timeout.as_millis()
                        )),
                    };
                    if let Some(why) = lost {
                        self.outcome.timeouts += 1;
                        let text = format!("{request}: {why}; reconnecting");
                        self.log.write(self.t(), log::Event::Message { text });
                        // The old connection goes: a late answer on it would be read as the
                        // answer to the next request.
                        ctx = None;
                        self.writer.timeout();
                        if !self.writer.is_finished() {
                            self.outcome.reconnects += 1;
                            ctx = Some(connect(link, options).await?);
                        }
                    }
                }
                None => {
                    // Nothing to send until the writer's next poll: a short wall-time wait.
                    let wait = options
                        .writer
                        .poll_interval
                        .div_f64(options.clock_scale.max(1.0));
                    tokio::time::sleep(
                        wait.clamp(Duration::from_micros(200), Duration::from_millis(20)),
                    )
                    .await;
                }
            }
            self.report();
        }
        self.report();
        Ok(())
    }

    /// The caller's commands that have come, to the writer and the log.
    fn obey(&mut self) {
        while let Some(command) = self.commands.as_mut().and_then(Commands::try_next) {
            let text = match command {
                Command::Hold => {
                    self.writer.hold();
                    "feed hold requested".to_owned()
                }
                Command::Resume => {
                    self.writer.resume();
                    "resume requested".to_owned()
                }
                Command::Stop { reason } => {
                    self.stop(format!(
                        "the stream was stopped ({reason}): the controller holds on the path"
                    ));
                    format!("stop requested ({reason}): HOLD, then RUN cleared once it stands")
                }
                Command::Abort => {
                    self.writer.abort();
                    "abort requested".to_owned()
                }
            };
            self.log.write(self.t(), log::Event::Message { text });
        }
        if let Some(percent) = self.commands.as_mut().and_then(Commands::try_feed_override) {
            self.writer.feed_override(percent);
            self.log.write(
                self.t(),
                log::Event::FeedOverride {
                    percent,
                    state: log::FeedOverrideState::Asked,
                },
            );
        }
    }

    /// The writer's events to the log, the caller's display and the outcome.
    fn report(&mut self) {
        while let Some(event) = self.writer.next_event() {
            let time = self.t();
            match event {
                WriterEvent::Identified(_) => {}
                WriterEvent::Published { sequence, slot } => {
                    self.outcome.published += 1;
                    self.progress
                        .published(self.outcome.published, self.start.elapsed());
                    self.log.write(
                        time,
                        log::Event::Sent {
                            line: sequence as usize,
                            text: format!("segment {sequence} in slot {slot}"),
                        },
                    );
                }
                WriterEvent::Status(s) => {
                    self.progress.status(&s, self.start.elapsed());
                    self.log.write(
                        time,
                        log::Event::Status {
                            state: format!("{:?}", s.state),
                            pos: s.position(),
                            blocks_free: None,
                            rx_free: None,
                            line: Some(u64::from(s.executed)),
                        },
                    );
                }
                WriterEvent::Alarm(alarm) => {
                    self.outcome.alarm = Some(alarm);
                    self.log.write(
                        time,
                        log::Event::Alarm {
                            code: u32::from(alarm.code.code()),
                            message: alarm.to_string(),
                        },
                    );
                }
                WriterEvent::Stalled { waited } => {
                    // The writer counts in its clock: the caller's limit is in wall time.
                    let seconds = self.stall_timeout.unwrap_or(waited).as_secs_f64();
                    let why = format!("nothing new from the controller for {seconds} s");
                    self.log.write(
                        time,
                        log::Event::Message {
                            text: format!("{why}: holding"),
                        },
                    );
                    self.stop(format!("{why}: held"));
                }
                WriterEvent::Done => self.outcome.completed = true,
                WriterEvent::Aborted => self.outcome.aborted = true,
                WriterEvent::Stopped => self.outcome.stopped = self.stop_asked.clone(),
                WriterEvent::Failed(error) => self.outcome.failure = Some(error),
                WriterEvent::FeedOverride(percent) => self.log.write(
                    time,
                    log::Event::FeedOverride {
                        percent,
                        state: log::FeedOverrideState::Running,
                    },
                ),
                WriterEvent::FeedOverrideRefused { percent, exception } => {
                    let why = match exception {
                        Exception::IllegalDataAddress => format!(
                            "the controller's register map has no FEED_OVERRIDE register \
                             ({}): set the override on its panel",
                            reg::FEED_OVERRIDE
                        ),
                        other => format!("FEED_OVERRIDE was refused: {other}"),
                    };
                    self.log.write(
                        time,
                        log::Event::Message {
                            text: format!("feed override {percent} % not taken: {why}"),
                        },
                    );
                    self.log.write(
                        time,
                        log::Event::FeedOverride {
                            percent,
                            state: log::FeedOverrideState::NotTaken,
                        },
                    );
                }
            }
        }
    }
}

impl ModbusOutcome {
    /// Why the run did not complete, for the log's End; `None` if it did.
    fn reason(&self) -> Option<String> {
        if self.completed {
            return None;
        }
        Some(
            self.alarm
                .map(|a| a.to_string())
                .or_else(|| self.failure.as_ref().map(ToString::to_string))
                .or_else(|| self.stopped.clone())
                .unwrap_or_else(|| {
                    if self.aborted {
                        "aborted: the controller stopped and flushed its ring".to_owned()
                    } else {
                        "the stream ended before the controller read done".to_owned()
                    }
                }),
        )
    }
}

/// The caller's progress display: what it was last told, and the planned time of the
/// segments still to run.
struct Told {
    report: Option<ProgressFn>,
    progress: Progress,
    first_sequence: u32,
    /// `left[i]`: the planned time of the linked segments from segment `i` on, µs.
    left: Vec<u64>,
}

impl Told {
    fn new(segments: &[Segment], first_sequence: u32, report: Option<ProgressFn>) -> Told {
        let mut left = vec![0u64; segments.len() + 1];
        for (i, segment) in segments.iter().enumerate().rev() {
            let own = match *segment {
                Segment::Linked { duration_us, .. } => u64::from(duration_us),
                _ => 0,
            };
            left[i] = left[i + 1] + own;
        }
        Told {
            progress: Progress {
                unit: Unit::Segments,
                done: 0,
                total: segments.len(),
                line: None,
                elapsed: Duration::ZERO,
                left: Some(Duration::from_micros(left[0])),
                state: None,
                position: None,
                finishing: false,
            },
            report,
            first_sequence,
            left,
        }
    }

    fn published(&mut self, published: usize, elapsed: Duration) {
        self.progress.done = published;
        self.progress.finishing = published == self.progress.total;
        self.tell(elapsed);
    }

    /// A status read: the state, the position, and the time left after the segment the
    /// controller reports executing.
    fn status(&mut self, status: &crate::protocol::modbus::map::Status, elapsed: Duration) {
        self.progress.state = Some(format!("{:?}", status.state));
        self.progress.position = Some(status.position());
        if status.executed != 0 {
            let index = status.executed.wrapping_sub(self.first_sequence) as usize;
            if let Some(&left) = self.left.get(index + 1) {
                self.progress.left = Some(Duration::from_micros(left));
            }
        }
        self.tell(elapsed);
    }

    fn tell(&mut self, elapsed: Duration) {
        if let Some(report) = self.report.as_mut() {
            self.progress.elapsed = elapsed;
            report(&self.progress);
        }
    }
}

/// Why a call brought no answer the writer can take.
enum Failure {
    /// The link: no connection, a broken one, a garbled frame.
    Link(tokio_modbus::Error),
    /// An exception code outside the map's.
    Exception(u8),
    /// An answer of another function than the request's.
    Mismatch(String),
}

/// Connects to `link`, retrying with a doubling backoff up to `options.max_reconnects`
/// attempts.
async fn connect(link: &ModbusLink, options: &ModbusOptions) -> Result<Context, ModbusError> {
    let mut wait = options.backoff;
    let mut attempt = 0;
    loop {
        attempt += 1;
        let tried = tokio::time::timeout(options.timeout, open(link, options.unit)).await;
        let error = match tried {
            Ok(Ok(ctx)) => return Ok(ctx),
            Ok(Err(error)) => error,
            Err(_) => std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("no connection within {} ms", options.timeout.as_millis()),
            ),
        };
        if attempt >= options.max_reconnects.max(1) {
            return Err(ModbusError::Connect {
                link: link.to_string(),
                attempts: attempt,
                error,
            });
        }
        tokio::time::sleep(wait).await;
        wait = (wait * 2).min(options.max_backoff);
    }
}

async fn open(link: &ModbusLink, unit: u8) -> std::io::Result<Context> {
    match link {
        ModbusLink::Tcp(addr) => tokio_modbus::client::tcp::connect_slave(*addr, Slave(unit)).await,
        ModbusLink::Rtu { path, baud } => {
            let port = tokio_serial::new(path, *baud)
                .open_native_async()
                .map_err(std::io::Error::other)?;
            // What the line delivered before, late answers included, is no answer to what
            // this connection will ask.
            tokio_serial::SerialPort::clear(&port, tokio_serial::ClearBuffer::Input)
                .map_err(std::io::Error::other)?;
            Ok(tokio_modbus::client::rtu::attach_slave(port, Slave(unit)))
        }
    }
}

/// One request over `ctx`, its answer as the writer reads answers.
///
/// The answer is passed on as it came: the registers read, the address and value an FC06
/// echoes, the address and count an FC16 confirms, and the writer checks each against its
/// request. tokio-modbus's `Reader` and `Writer` calls would not do: they return no echo
/// and check echoes and counts only with debug assertions (a panic in a debug build,
/// nothing in a release one), so an answer meant for another request (a late one on a
/// serial line, a confused gateway's) would crash the bridge or be taken for this one's.
async fn call(
    ctx: &mut Context,
    request: &Request,
) -> Result<Result<Response, Exception>, Failure> {
    let wire = match request {
        Request::ReadHolding { address, count } => {
            tokio_modbus::Request::ReadHoldingRegisters(*address, *count)
        }
        Request::WriteSingle { address, value } => {
            tokio_modbus::Request::WriteSingleRegister(*address, *value)
        }
        Request::WriteMultiple { address, values } => {
            tokio_modbus::Request::WriteMultipleRegisters(*address, values.into())
        }
    };
    match ctx.call(wire).await {
        Ok(Ok(tokio_modbus::Response::ReadHoldingRegisters(values))) => {
            Ok(Ok(Response::ReadHolding(values)))
        }
        Ok(Ok(tokio_modbus::Response::WriteSingleRegister(address, value))) => {
            Ok(Ok(Response::WriteSingle { address, value }))
        }
        Ok(Ok(tokio_modbus::Response::WriteMultipleRegisters(address, count))) => {
            Ok(Ok(Response::WriteMultiple { address, count }))
        }
        // tokio-modbus refuses an answer whose function code is not the request's.
        Ok(Ok(other)) => Err(Failure::Mismatch(format!("{other:?}"))),
        Ok(Err(code)) => exception(code)
            .map(Err)
            .ok_or(Failure::Exception(code.into())),
        Err(error) => Err(Failure::Link(error)),
    }
}

fn exception(code: ExceptionCode) -> Option<Exception> {
    Some(match code {
        ExceptionCode::IllegalFunction => Exception::IllegalFunction,
        ExceptionCode::IllegalDataAddress => Exception::IllegalDataAddress,
        ExceptionCode::IllegalDataValue => Exception::IllegalDataValue,
        ExceptionCode::ServerDeviceFailure => Exception::ServerDeviceFailure,
        ExceptionCode::ServerDeviceBusy => Exception::ServerDeviceBusy,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_rtu_exchange_costs_its_frames_bytes_and_silences() {
        // Modbus over Serial Line: a frame is address + PDU + CRC, 10 bits a character at
        // 8N1, then 3.5 characters of silence (35 bit times).
        let read = Request::ReadHolding {
            address: 0,
            count: 8,
        };
        // Request 1 + 5 + 2 = 8 bytes; answer 1 + (2 + 16) + 2 = 21 bytes.
        let answer: Result<Response, Exception> = Ok(Response::ReadHolding(vec![0; 8]));
        assert_eq!(rtu_bits(&read, Some(&answer)), 80 + 35 + 210 + 35);
        // A slot: FC16 of 16 registers is 1 + (6 + 32) + 2 = 41 bytes, its answer 8.
        let slot = Request::WriteMultiple {
            address: 100,
            values: vec![0; 16],
        };
        let written = Ok(Response::WriteMultiple {
            address: 100,
            count: 16,
        });
        assert_eq!(rtu_bits(&slot, Some(&written)), 410 + 35 + 80 + 35);
        // An exception answer is 1 + 2 + 2 bytes; a lost one costs only the request.
        let refused = Err(Exception::IllegalDataAddress);
        assert_eq!(rtu_bits(&read, Some(&refused)), 115 + 50 + 35);
        assert_eq!(rtu_bits(&read, None), 115);
    }
}
