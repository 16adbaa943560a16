//! Streaming a G-code program to a grbl/grblHAL controller over a serial line.
//!
//! [`stream`] runs a [`Streamer`] against any byte stream: it writes what
//! [`Streamer::transmit`] hands out, feeds what it reads to [`Streamer::receive`], tells
//! [`Streamer::poll`] the time at the poll interval, and writes every event to the
//! executed-path log. It decides nothing about the protocol (what to send, which answer
//! belongs to which line, when the stream has stopped): those are the streamer's, tested
//! without I/O. [`stream_port`] opens a serial port with tokio-serial and calls it; taking a
//! generic stream is what lets the tests (and the dry run) use an in-memory pipe or a
//! pseudo-terminal and still run exactly the code a machine gets.
//!
//! # When the run ends
//!
//! - **Completed**: the streamer's [`Event::Done`] only says every line was acknowledged;
//!   up to a planner's worth of moves may still be queued. The run goes on polling until a
//!   status report says `Idle` with every planner block free (the planner size from `$I`,
//!   else the most free blocks ever reported), so "completed" means the motion finished.
//!   A controller that reports no `Bf:` field gets two consecutive `Idle` reports instead
//!   (grbl can answer one `?` as `Idle` just before starting a freshly planned cycle).
//!   Without polling ([`StreamerConfig::poll_interval`] `None`) or with
//!   [`StreamOptions::wait_for_idle`] off, the run completes at `Done`.
//! - **Stopped**: an `error:N`, an alarm or a reset ([`Event::Stopped`]); the outcome
//!   carries the reason and the streamer's [`ResumePoint`]. This is a result, not an
//!   error: the controller is in a known state and the caller decides what next.
//! - **Timed out**: with [`StreamOptions::no_progress_timeout`], a controller that says
//!   nothing new for that long (no answer, no change of state or position) gets a feed hold
//!   (`!`, which stops motion without losing position, unlike a reset) and the run reports.
//!   A hold (the caller's, or the controller in `Hold`, `Door` or `Tool`) is not a stall:
//!   the clock restarts while it lasts.
//! - **Failed**: a read or write error, or the controller closing the stream, is a
//!   [`SerialError`] naming the port: nothing is known about what ran after that.
//!
//! Every run is logged between [`log::Event::Start`] and [`log::Event::End`]
//! (also when it fails, as far as the log can still be written), with times in seconds
//! since the start.

use std::fmt;
use std::future::pending;
use std::time::Duration;

use thiserror::Error;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, WriteHalf};
use tokio::time::{interval_at, sleep_until, Instant, Interval, MissedTickBehavior};
use tokio_serial::SerialPortBuilderExt;
use tracing::Instrument;

use super::control::{Command, Commands};
use super::progress::{Progress, ProgressFn, Unit};
use super::run::{check_program, PreflightError};
use crate::config::machine::MachineProfile;
use crate::log::{self, ExecLog, LogError};
use crate::protocol::grbl::{
    self, Event, LineRef, MachineState, ResumePoint, Status, StopReason, Streamer, StreamerConfig,
};

/// The transport's name in [`log::Event::Start`].
pub const TRANSPORT: &str = "serial";

/// How long the last bytes of a run (a feed hold, a soft reset) may take to go out before
/// the link is declared dead: they are a few bytes, so anything longer means it is stuck.
const FINAL_WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// Bytes read at once: a serial link delivers far less between two reads.
const READ_CHUNK: usize = 1024;

/// Where X, Z and C sit in a status report's position vector, which lists the
/// controller's configured axes in its own order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusAxes {
    /// Index of X.
    pub x: usize,
    /// Index of Z.
    pub z: usize,
    /// Index of C; `None` for a controller without one (C is then logged as 0).
    pub c: Option<usize>,
}

/// An XYZC grblHAL build (whirl-sim's): `MPos:x,y,z,c`, Y present and unused.
impl Default for StatusAxes {
    fn default() -> StatusAxes {
        StatusAxes {
            x: 0,
            z: 2,
            c: Some(3),
        }
    }
}

/// How [`stream`] runs.
pub struct StreamOptions {
    /// The port's name, for errors and the log (the device path for [`stream_port`]).
    pub port_name: String,
    /// What is streamed (the program file or job), for [`log::Event::Start`].
    pub program: String,
    /// The protocol's settings: receive buffer, `$I`, banner, poll interval, start line.
    pub streamer: StreamerConfig,
    /// Resume the program at this line (0-based) behind a preamble that restores its modes
    /// ([`Streamer::resume_from`]); `None` streams from [`StreamerConfig::start_line`].
    pub resume_at: Option<usize>,
    /// The link's baud rate, for [`StreamOutcome::link_utilization`].
    pub baud: Option<u32>,
    /// Stop with a feed hold when the controller says nothing new for this long; `None`
    /// waits forever. Off by default: a long dwell reports nothing new either, and stopping a
    /// job that is cutting is worse than waiting, so the caller chooses.
    pub no_progress_timeout: Option<Duration>,
    /// After every line is acknowledged, wait for the motion to finish (see the module
    /// docs). On by default.
    pub wait_for_idle: bool,
    /// Where X, Z and C are in status reports.
    pub axes: StatusAxes,
    /// Check the program against this machine's travel and speeds before the first byte
    /// goes out ([`check_program`]); `None`: the caller has checked it.
    pub machine: Option<MachineProfile>,
    /// Planned seconds of each program line, for the progress ETA.
    pub line_durations: Option<Vec<f64>>,
    /// The caller's hold, resume and abort while streaming: a feed hold, a cycle start
    /// and a soft reset, each a real-time byte sent at once, ahead of any line.
    pub commands: Option<Commands>,
    /// Told how far the run is whenever something happened (no more often than the
    /// controller talks). Keep it quick: it runs on the streaming task.
    pub on_progress: Option<ProgressFn>,
}

impl Default for StreamOptions {
    fn default() -> StreamOptions {
        StreamOptions {
            port_name: String::from("serial port"),
            program: String::new(),
            streamer: StreamerConfig::default(),
            resume_at: None,
            baud: None,
            no_progress_timeout: None,
            wait_for_idle: true,
            axes: StatusAxes::default(),
            machine: None,
            line_durations: None,
            commands: None,
            on_progress: None,
        }
    }
}

impl fmt::Debug for StreamOptions {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("StreamOptions")
            .field("port_name", &self.port_name)
            .field("program", &self.program)
            .field("streamer", &self.streamer)
            .field("resume_at", &self.resume_at)
            .field("baud", &self.baud)
            .field("no_progress_timeout", &self.no_progress_timeout)
            .field("wait_for_idle", &self.wait_for_idle)
            .field("axes", &self.axes)
            .field("machine", &self.machine.as_ref().map(|m| &m.name))
            .field(
                "line_durations",
                &self.line_durations.as_ref().map(Vec::len),
            )
            .field("commands", &self.commands.is_some())
            .field("on_progress", &self.on_progress.is_some())
            .finish()
    }
}

/// How a run ended (when it did not fail; see [`SerialError`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// Every line acknowledged and, unless told not to wait, the motion finished.
    Completed,
    /// The streamer stopped: an error, an alarm, a reset.
    Stopped(StopReason),
    /// Nothing new from the controller for this long; a feed hold was sent.
    TimedOut {
        /// The configured timeout.
        after: Duration,
    },
}

impl fmt::Display for Ending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ending::Completed => write!(f, "completed"),
            Ending::Stopped(reason) => write!(f, "stopped: {reason}"),
            Ending::TimedOut { after } => write!(
                f,
                "nothing new from the controller for {:.0} s: feed hold sent",
                after.as_secs_f64()
            ),
        }
    }
}

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamOutcome {
    /// How it ended.
    pub ending: Ending,
    /// The program line (0-based) the controller refused, if that is why it stopped.
    pub failed_line: Option<usize>,
    /// Where to resume, after a stop ([`Streamer::resume_point`]); `None` when completed
    /// or timed out (a held controller has not discarded anything: the caller can resume
    /// the motion with `~`, or reset and then knows nothing more than the acks).
    pub resume: Option<ResumePoint>,
    /// Program lines.
    pub lines_total: usize,
    /// Program lines sent in this run.
    pub lines_sent: usize,
    /// Program lines acknowledged `ok` in this run.
    pub lines_acked: usize,
    /// From the first byte to the end.
    pub wall_time: Duration,
    /// When the last line was acknowledged, if it was.
    pub all_acked_at: Option<Duration>,
    /// Bytes written to the port (lines and real-time bytes).
    pub bytes_written: u64,
    /// Bytes read from the port.
    pub bytes_read: u64,
    /// The link's baud rate, if known.
    pub baud: Option<u32>,
    /// Bytes written × 10 bits / (baud × wall time): how busy the link was, 0 to 1 (a
    /// measurement, so it can come out a hair above 1). `None` without a baud rate.
    pub link_utilization: Option<f64>,
    /// The same over the streaming phase only (up to the last acknowledgement, so
    /// without the wait for the last moves): the figure that shows whether character
    /// counting keeps the link busy.
    pub streaming_utilization: Option<f64>,
    /// Alarm codes raised, in order.
    pub alarms: Vec<u16>,
    /// The last status report.
    pub last_status: Option<Status>,
}

impl StreamOutcome {
    /// Every line acknowledged and the motion finished.
    pub fn completed(&self) -> bool {
        self.ending == Ending::Completed
    }
}

/// Why a run failed. Stops the protocol defines (errors, alarms, resets) are not failures:
/// they end in a [`StreamOutcome`].
#[derive(Debug, Error)]
pub enum SerialError {
    /// The port could not be opened.
    #[error("cannot open {port}: {source}")]
    Open {
        /// The port.
        port: String,
        /// Why.
        source: tokio_serial::Error,
    },
    /// Reading or writing failed.
    #[error("{port}: {source}")]
    Io {
        /// The port.
        port: String,
        /// Why.
        source: std::io::Error,
    },
    /// The controller's end closed the stream.
    #[error("{port}: the connection was closed (end of file) mid-stream")]
    Eof {
        /// The port.
        port: String,
    },
    /// The program cannot be streamed as it is (a forbidden byte, a line too long).
    #[error("the program cannot be streamed: {0}")]
    Program(#[from] grbl::StreamerError),
    /// The program failed the machine check; nothing was sent.
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    /// The executed-path log could not be written.
    #[error("executed-path log: {0}")]
    Log(#[from] LogError),
}

/// How busy a serial link was: `bytes` × 10 bits (8N1: a start bit, eight data bits, a
/// stop bit) over what `baud` could carry in `time`. `None` for a zero baud rate or time.
pub fn link_utilization(bytes: u64, baud: u32, time: Duration) -> Option<f64> {
    let capacity = f64::from(baud) * time.as_secs_f64();
    (capacity > 0.0).then(|| bytes as f64 * 10.0 / capacity)
}

/// Opens the serial port at `path` (8N1, no flow control, as grbl expects) and streams
/// `lines` over it with [`stream`]. The machine check, if asked for, runs before the port
/// is opened: opening resets some boards (an Arduino running grbl), so a program that
/// will be refused should not even do that. `options.port_name` becomes `path` and
/// `options.baud` defaults to `baud`.
pub async fn stream_port(
    path: &str,
    baud: u32,
    lines: Vec<String>,
    mut options: StreamOptions,
    log: &mut ExecLog,
) -> Result<StreamOutcome, SerialError> {
    if let Some(machine) = options.machine.take() {
        check_program(&lines, &machine)?;
    }
    let port = tokio_serial::new(path, baud)
        .open_native_async()
        .map_err(|source| SerialError::Open {
            port: path.to_owned(),
            source,
        })?;
    options.port_name = path.to_owned();
    options.baud.get_or_insert(baud);
    stream(port, lines, options, log).await
}

/// Streams `lines` (without line ends) to a grbl/grblHAL controller on `port`, logging to
/// `log`; see the module docs for when it ends. Nothing is written before the program
/// passes the streamer's checks (and the machine check, with [`StreamOptions::machine`]).
pub async fn stream<P: AsyncRead + AsyncWrite + Unpin>(
    port: P,
    lines: Vec<String>,
    mut options: StreamOptions,
    log: &mut ExecLog,
) -> Result<StreamOutcome, SerialError> {
    if let Some(machine) = &options.machine {
        check_program(&lines, machine)?;
    }
    let config = options.streamer.clone();
    let poll_interval = config.poll_interval;
    let streamer = match options.resume_at {
        Some(index) => Streamer::resume_from(lines.clone(), index, config)?,
        None => Streamer::new(lines.clone(), config)?,
    };
    let span = tracing::debug_span!("stream", port = %options.port_name, lines = lines.len());
    let run = Run {
        wait_for_idle: options.wait_for_idle && poll_interval.is_some(),
        timeout: options.no_progress_timeout,
        axes: options.axes,
        durations: options.line_durations.take(),
        on_progress: options.on_progress.take(),
        baud: options.baud,
        port: options.port_name.clone(),
        program: options.program.clone(),
        lines,
        streamer,
        log,
        start: Instant::now(),
        sent: 0,
        acked: 0,
        bytes_written: 0,
        bytes_read: 0,
        all_acked_at: None,
        bytes_at_all_acked: 0,
        motion_done: false,
        stopped: None,
        alarms: Vec::new(),
        wco: None,
        last_status: None,
        max_blocks_free: None,
        idle_reports: 0,
        held_by_caller: false,
        held_by_controller: false,
    };
    run.run(port, poll_interval, options.commands.take())
        .instrument(span)
        .await
}

/// One run's state around the streamer: counters, what the log needs, when to stop.
struct Run<'a> {
    port: String,
    program: String,
    lines: Vec<String>,
    streamer: Streamer,
    log: &'a mut ExecLog,
    start: Instant,
    wait_for_idle: bool,
    timeout: Option<Duration>,
    axes: StatusAxes,
    durations: Option<Vec<f64>>,
    on_progress: Option<ProgressFn>,
    baud: Option<u32>,
    sent: usize,
    acked: usize,
    bytes_written: u64,
    bytes_read: u64,
    all_acked_at: Option<Duration>,
    bytes_at_all_acked: u64,
    /// Every line acknowledged and the controller idle with an empty planner.
    motion_done: bool,
    stopped: Option<StopReason>,
    alarms: Vec<u16>,
    /// The last work coordinate offset seen, in the order the reports came.
    wco: Option<Vec<f64>>,
    last_status: Option<Status>,
    max_blocks_free: Option<u32>,
    /// Consecutive `Idle` reports since every line was acknowledged.
    idle_reports: u32,
    held_by_caller: bool,
    held_by_controller: bool,
}

impl Run<'_> {
    fn now(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    fn write_log(&mut self, event: log::Event) -> Result<(), LogError> {
        let t = self.now();
        self.log.write(t, event)
    }

    fn io_error(&self, source: std::io::Error) -> SerialError {
        SerialError::Io {
            port: self.port.clone(),
            source,
        }
    }

    async fn run<P: AsyncRead + AsyncWrite + Unpin>(
        mut self,
        port: P,
        poll_interval: Option<Duration>,
        commands: Option<Commands>,
    ) -> Result<StreamOutcome, SerialError> {
        self.start = Instant::now();
        self.write_log(log::Event::Start {
            program: self.program.clone(),
            lines: self.lines.len(),
            transport: TRANSPORT.to_owned(),
        })?;
        tracing::debug!(program = %self.program, "stream started");
        match self.drive(port, poll_interval, commands).await {
            Ok(ending) => {
                let reason = match &ending {
                    Ending::Completed => None,
                    Ending::Stopped(reason) => Some(reason.to_string()),
                    Ending::TimedOut { after } => Some(format!(
                        "no progress for {} s: feed hold sent",
                        after.as_secs_f64()
                    )),
                };
                tracing::debug!(?ending, "stream ended");
                self.write_log(log::Event::End {
                    completed: ending == Ending::Completed,
                    reason,
                })?;
                Ok(self.outcome(ending))
            }
            Err(error) => {
                tracing::warn!(%error, "stream failed");
                // Best effort: the log may be what failed.
                let _ = self.write_log(log::Event::End {
                    completed: false,
                    reason: Some(error.to_string()),
                });
                Err(error)
            }
        }
    }

    /// The loop: bytes out, bytes in, the poll clock, the caller's commands, the watchdog.
    async fn drive<P: AsyncRead + AsyncWrite + Unpin>(
        &mut self,
        port: P,
        poll_interval: Option<Duration>,
        mut commands: Option<Commands>,
    ) -> Result<Ending, SerialError> {
        let (mut reader, mut writer) = tokio::io::split(port);
        let mut out: Vec<u8> = Vec::new();
        let mut buffer = vec![0u8; READ_CHUNK];
        // Ticks on a fixed grid from the start, and the streamer is told the grid time, so
        // a late wake-up never makes a poll look early and get skipped.
        let mut ticker = poll_interval.map(|period| {
            let mut ticker = interval_at(self.start, period);
            ticker.set_missed_tick_behavior(MissedTickBehavior::Skip);
            ticker
        });
        let mut last_progress = Instant::now();
        loop {
            if let Some(bytes) = self.streamer.transmit() {
                out.extend_from_slice(&bytes);
            }
            let progressed = self.drain_events()?;
            if progressed || self.held_by_caller || self.held_by_controller {
                last_progress = Instant::now();
            }
            if let Some(ending) = self.ending() {
                // What is queued still goes out: real-time bytes queued with the stop (a soft
                // reset's 0x18), and the rest of a line cut off mid-write, which would
                // otherwise sit in the controller's buffer and merge with the next command.
                self.write_final(&mut writer, &mut out).await?;
                return Ok(ending);
            }
            let deadline = self.timeout.map(|timeout| last_progress + timeout);
            tokio::select! {
                written = writer.write(&out), if !out.is_empty() => {
                    let n = written.map_err(|e| self.io_error(e))?;
                    if n == 0 {
                        return Err(self.io_error(std::io::ErrorKind::WriteZero.into()));
                    }
                    out.drain(..n);
                    self.bytes_written += n as u64;
                }
                read = reader.read(&mut buffer) => {
                    let n = read.map_err(|e| self.io_error(e))?;
                    if n == 0 {
                        return Err(SerialError::Eof { port: self.port.clone() });
                    }
                    self.bytes_read += n as u64;
                    self.streamer.receive(&buffer[..n]);
                }
                at = next_tick(&mut ticker) => {
                    self.streamer.poll(at.duration_since(self.start));
                }
                command = next_command(&mut commands) => self.command(command)?,
                () = wait_until(deadline) => {
                    let after = self.timeout.unwrap_or_default();
                    tracing::warn!(seconds = after.as_secs_f64(), "no progress: feed hold");
                    self.streamer.feed_hold();
                    if let Some(bytes) = self.streamer.transmit() {
                        out.extend_from_slice(&bytes);
                    }
                    self.drain_events()?;
                    self.write_final(&mut writer, &mut out).await?;
                    return Ok(Ending::TimedOut { after });
                }
            }
        }
    }

    /// Writes what is left, within [`FINAL_WRITE_TIMEOUT`].
    async fn write_final<W: AsyncWrite>(
        &mut self,
        writer: &mut WriteHalf<W>,
        out: &mut Vec<u8>,
    ) -> Result<(), SerialError> {
        if out.is_empty() {
            return Ok(());
        }
        match tokio::time::timeout(FINAL_WRITE_TIMEOUT, writer.write_all(out)).await {
            Ok(Ok(())) => {
                self.bytes_written += out.len() as u64;
                out.clear();
                Ok(())
            }
            Ok(Err(e)) => Err(self.io_error(e)),
            Err(_) => Err(self.io_error(std::io::ErrorKind::TimedOut.into())),
        }
    }

    fn command(&mut self, command: Command) -> Result<(), SerialError> {
        tracing::debug!(?command, "caller command");
        let text = match command {
            Command::Hold => {
                self.streamer.feed_hold();
                self.held_by_caller = true;
                "feed hold requested"
            }
            Command::Resume => {
                self.streamer.resume();
                self.held_by_caller = false;
                "resume requested"
            }
            Command::Abort => {
                self.streamer.soft_reset();
                "soft reset requested"
            }
        };
        self.write_log(log::Event::Message {
            text: text.to_owned(),
        })?;
        Ok(())
    }

    /// How the run ends now, if it does.
    fn ending(&self) -> Option<Ending> {
        if let Some(reason) = &self.stopped {
            return Some(Ending::Stopped(reason.clone()));
        }
        let done = self.all_acked_at.is_some() && (self.motion_done || !self.wait_for_idle);
        done.then_some(Ending::Completed)
    }

    /// Logs the streamer's events; `true` if any showed the controller doing something.
    fn drain_events(&mut self) -> Result<bool, LogError> {
        let mut any = false;
        let mut progressed = false;
        while let Some(event) = self.streamer.next_event() {
            any = true;
            progressed |= self.handle(event)?;
        }
        if any {
            self.report_progress();
        }
        Ok(progressed)
    }

    /// Logs one event; `true` if it shows the controller doing something.
    fn handle(&mut self, event: Event) -> Result<bool, LogError> {
        let log = match event {
            Event::Sent { index, line_no } => {
                self.sent += 1;
                let text = self.lines.get(index).cloned().unwrap_or_default();
                tracing::debug!(line = index + 1, ?line_no, %text, "sent");
                self.write_log(log::Event::Sent {
                    line: index + 1,
                    text,
                })?;
                return Ok(false);
            }
            Event::AuxSent { line, text } => {
                tracing::debug!(?line, %text, "sent (streamer's own line)");
                return Ok(false);
            }
            Event::Acked { index } => {
                self.acked += 1;
                tracing::debug!(line = index + 1, "ok");
                log::Event::Ack { line: index + 1 }
            }
            Event::Error {
                index,
                line,
                code,
                message,
            } => {
                tracing::debug!(line = index + 1, %line, code, message, "error");
                log::Event::Error {
                    line: index + 1,
                    code: u32::from(code),
                    message: message.to_owned(),
                }
            }
            Event::Rejected { index, code } => {
                tracing::debug!(line = index + 1, code, "rejected after the stop");
                log::Event::Message {
                    text: format!(
                        "line {} not executed: refused with error:{code} after the stop",
                        index + 1
                    ),
                }
            }
            Event::Discarded { index } => {
                tracing::debug!(line = index + 1, "discarded by the reset");
                log::Event::Message {
                    text: format!(
                        "line {} not executed: discarded unanswered by the reset",
                        index + 1
                    ),
                }
            }
            Event::AuxAnswered { line, error } => {
                tracing::debug!(?line, ?error, "answer to the streamer's own line");
                match error {
                    None => return Ok(true),
                    Some(code) => log::Event::Message {
                        text: format!(
                            "{} was refused: error:{code} ({})",
                            LineRef::Aux(line),
                            grbl::error_message(code)
                        ),
                    },
                }
            }
            Event::Alarm { code, message } => {
                tracing::debug!(code, message, "alarm");
                self.alarms.push(code);
                log::Event::Alarm {
                    code: u32::from(code),
                    message: message.to_owned(),
                }
            }
            Event::Status(status) => return self.on_status(status),
            Event::Message(text) => {
                tracing::debug!(%text, "controller message");
                log::Event::Message { text }
            }
            Event::Feedback(text) => {
                tracing::debug!(%text, "controller feedback");
                return Ok(true);
            }
            Event::Options(options) => {
                tracing::debug!(?options, "build options");
                return Ok(true);
            }
            Event::RxSize { bytes } => {
                tracing::debug!(bytes, "receive buffer size");
                log::Event::Message {
                    text: format!("controller receive buffer: {bytes} bytes"),
                }
            }
            Event::Banner(text) => {
                tracing::debug!(%text, "banner");
                log::Event::Message {
                    text: format!("controller: {text}"),
                }
            }
            Event::Reset => {
                tracing::debug!("controller reset");
                log::Event::Message {
                    text: "the controller reset".to_owned(),
                }
            }
            Event::Stopped { reason } => {
                tracing::debug!(%reason, "stream stopped");
                self.stopped = Some(reason);
                return Ok(true);
            }
            Event::Done => {
                tracing::debug!("every line acknowledged");
                self.all_acked_at = Some(self.start.elapsed());
                self.bytes_at_all_acked = self.bytes_written;
                return Ok(true);
            }
            Event::Unrecognized(text) => {
                tracing::debug!(%text, "unrecognised controller output");
                log::Event::Message {
                    text: format!("unrecognised controller output: {text}"),
                }
            }
        };
        self.write_log(log)?;
        Ok(true)
    }

    /// Logs a status report and watches it for the end of motion; `true` if the state or
    /// the position changed.
    fn on_status(&mut self, status: Status) -> Result<bool, LogError> {
        if let Some(wco) = &status.wco {
            self.wco = Some(wco.clone());
        }
        if let Some(free) = status.buffer.map(|b| b.planner_blocks_free) {
            self.max_blocks_free = Some(self.max_blocks_free.map_or(free, |m| m.max(free)));
        }
        self.held_by_controller = matches!(
            status.state,
            MachineState::Hold | MachineState::Door | MachineState::Tool
        );
        let position = self.position(&status);
        let changed = self.last_status.as_ref().is_none_or(|last| {
            last.state != status.state
                || last.substate != status.substate
                || self.position(last) != position
        });
        if self.all_acked_at.is_some() {
            if status.state == MachineState::Idle {
                self.idle_reports += 1;
            } else {
                self.idle_reports = 0;
            }
            let blocks = self.streamer.planner_blocks().or(self.max_blocks_free);
            self.motion_done |= match (status.buffer, blocks) {
                (Some(_), Some(blocks)) => status.planner_empty(blocks),
                _ => self.idle_reports >= 2,
            };
        }
        let state = state_name(&status);
        tracing::debug!(%state, ?position, line = ?status.line, "status");
        let event = match position {
            Some(pos) => log::Event::Status {
                state,
                pos,
                blocks_free: status.buffer.map(|b| b.planner_blocks_free),
                rx_free: status.buffer.map(|b| b.rx_bytes_free),
                line: status.line.map(u64::from),
            },
            None => log::Event::Message {
                text: format!("status {state} without a machine position"),
            },
        };
        self.last_status = Some(status);
        self.write_log(event)?;
        Ok(changed)
    }

    /// X, Z, C in machine coordinates: `MPos`, or `WPos` plus the last `WCO`.
    fn position(&self, status: &Status) -> Option<[f64; 3]> {
        let wco = status.wco.as_deref().or(self.wco.as_deref());
        machine_xzc(status, wco, self.axes)
    }

    fn report_progress(&mut self) {
        let Some(callback) = self.on_progress.as_mut() else {
            return;
        };
        let progress = self.streamer.progress();
        let elapsed = self.start.elapsed();
        let eta = match &self.durations {
            Some(durations) => progress
                .eta_seconds(durations)
                .and_then(|s| Duration::try_from_secs_f64(s).ok()),
            None if self.acked > 0 => {
                let left = progress.total.saturating_sub(progress.acked) as f64;
                Duration::try_from_secs_f64(elapsed.as_secs_f64() * left / self.acked as f64).ok()
            }
            None => None,
        };
        let snapshot = Progress {
            unit: Unit::Lines,
            done: progress.acked,
            total: progress.total,
            line: progress.executing,
            elapsed,
            left: eta,
            state: self.last_status.as_ref().map(state_name),
            position: self
                .last_status
                .as_ref()
                .and_then(|s| machine_xzc(s, s.wco.as_deref().or(self.wco.as_deref()), self.axes)),
            finishing: self.all_acked_at.is_some(),
        };
        callback(&snapshot);
    }

    fn outcome(&self, ending: Ending) -> StreamOutcome {
        let wall_time = self.start.elapsed();
        let failed_line = match &ending {
            Ending::Stopped(StopReason::Error {
                line: LineRef::Program(index),
                ..
            }) => Some(*index),
            _ => None,
        };
        let (streaming_time, streaming_bytes) = match self.all_acked_at {
            Some(at) => (at, self.bytes_at_all_acked),
            None => (wall_time, self.bytes_written),
        };
        StreamOutcome {
            failed_line,
            resume: self.streamer.resume_point(),
            lines_total: self.lines.len(),
            lines_sent: self.sent,
            lines_acked: self.acked,
            wall_time,
            all_acked_at: self.all_acked_at,
            bytes_written: self.bytes_written,
            bytes_read: self.bytes_read,
            baud: self.baud,
            link_utilization: self
                .baud
                .and_then(|baud| link_utilization(self.bytes_written, baud, wall_time)),
            streaming_utilization: self
                .baud
                .and_then(|baud| link_utilization(streaming_bytes, baud, streaming_time)),
            alarms: self.alarms.clone(),
            last_status: self.last_status.clone(),
            ending,
        }
    }
}

/// X, Z, C of a status report in machine coordinates (`MPos`, or `WPos` + `wco`).
fn machine_xzc(status: &Status, wco: Option<&[f64]>, axes: StatusAxes) -> Option<[f64; 3]> {
    let position = status.machine_position(wco)?;
    let x = *position.get(axes.x)?;
    let z = *position.get(axes.z)?;
    let c = match axes.c {
        Some(index) => *position.get(index)?,
        None => 0.0,
    };
    Some([x, z, c])
}

/// The state as grbl writes it: `Idle`, `Hold:0`, `Door:1`.
fn state_name(status: &Status) -> String {
    let name = match &status.state {
        MachineState::Other(name) => name.clone(),
        state => format!("{state:?}"),
    };
    match status.substate {
        Some(sub) => format!("{name}:{sub}"),
        None => name,
    }
}

/// The next poll tick, or never without polling.
async fn next_tick(ticker: &mut Option<Interval>) -> Instant {
    match ticker {
        Some(ticker) => ticker.tick().await,
        None => pending().await,
    }
}

/// The caller's next command, or never without any.
async fn next_command(commands: &mut Option<Commands>) -> Command {
    match commands {
        Some(commands) => commands.next().await,
        None => pending().await,
    }
}

/// Waits until `deadline`, or forever without one.
async fn wait_until(deadline: Option<Instant>) {
    match deadline {
        Some(deadline) => sleep_until(deadline).await,
        None => pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Record;
    use crate::protocol::grbl::fake::Fake;
    use crate::protocol::grbl::response::parse_status;
    use crate::protocol::grbl::ResumeBasis;
    use std::sync::{Arc, Mutex};
    use tokio::io::DuplexStream;

    /// How the model controller behaves beyond grbl's protocol (which [`Fake`] speaks).
    #[derive(Debug, Clone, Default)]
    struct Script {
        /// Each line "executes" this long before its answer; zero answers at once.
        line_time: Duration,
        /// Status reports that still say `Run` after the last line is answered (the planner
        /// finishing its moves).
        run_reports_after: usize,
        /// Stop answering lines once this many have executed (a hung controller).
        hang_after: Option<usize>,
        /// Close the connection once this many lines have executed.
        close_after: Option<usize>,
    }

    /// The controller's side of the link: `Fake` for the protocol, plus time per line, a
    /// status report that moves (X = lines executed, Z = X / 2, C = 10 X) and says `Run`
    /// while lines are queued, and the script's failures. Ends when the host closes the
    /// stream, and hands back the model for inspection.
    async fn controller<S: AsyncRead + AsyncWrite + Unpin>(
        mut io: S,
        mut fake: Fake,
        script: Script,
    ) -> Fake {
        let mut buffer = [0u8; 512];
        let mut run_reports = 0usize;
        let mut next_line_at: Option<Instant> = None;
        loop {
            let hung = hung_now(&fake, &script) || held(&fake);
            tokio::select! {
                read = io.read(&mut buffer) => {
                    let n = match read {
                        Ok(0) | Err(_) => break,
                        Ok(n) => n,
                    };
                    let bytes = &buffer[..n];
                    let running = fake.buffered() > 0 || run_reports > 0;
                    if bytes.contains(&b'?') && fake.buffered() == 0 && run_reports > 0 {
                        run_reports -= 1;
                    }
                    let done = fake.executed.len() as f64;
                    let state = match (held(&fake), running) {
                        (true, _) => "Hold:0",
                        (false, true) => "Run",
                        (false, false) => "Idle",
                    };
                    fake.status = format!(
                        "<{}|MPos:{:.3},0.000,{:.3},{:.3}|Bf:{},{}|FS:0,0>",
                        state,
                        done,
                        done / 2.0,
                        done * 10.0,
                        if running { 30 } else { 35 },
                        1023 - fake.buffered(),
                    );
                    fake.write(bytes);
                    if script.line_time.is_zero() {
                        while !hung_now(&fake, &script) && !held(&fake) && fake.process() {
                            run_reports = script.run_reports_after;
                        }
                    } else if next_line_at.is_none() && fake.buffered() > 0 {
                        next_line_at = Some(Instant::now() + script.line_time);
                    }
                }
                () = wait_until(next_line_at), if !hung => {
                    next_line_at = None;
                    if fake.process() {
                        run_reports = script.run_reports_after;
                        if fake.buffered() > 0 {
                            next_line_at = Some(Instant::now() + script.line_time);
                        }
                    }
                }
            }
            let output = fake.take_output();
            if !output.is_empty() && io.write_all(&output).await.is_err() {
                break;
            }
            if script.close_after.is_some_and(|n| fake.executed.len() >= n) {
                break;
            }
        }
        fake
    }

    fn hung_now(fake: &Fake, script: &Script) -> bool {
        script.hang_after.is_some_and(|n| fake.executed.len() >= n)
    }

    /// A feed hold (`!`) not yet followed by a cycle start (`~`): nothing executes.
    fn held(fake: &Fake) -> bool {
        fake.realtime
            .iter()
            .rev()
            .find(|&&b| b == b'!' || b == b'~')
            == Some(&b'!')
    }

    /// `n` lines of `G1 X<i> F100`.
    fn moves(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("G1 X{i} F100")).collect()
    }

    fn options() -> StreamOptions {
        StreamOptions {
            port_name: "/dev/ttyTEST".to_owned(),
            program: "test.nc".to_owned(),
            ..StreamOptions::default()
        }
    }

    struct Run {
        result: Result<StreamOutcome, SerialError>,
        fake: Fake,
        records: Vec<Record>,
    }

    /// Streams `lines` to the model controller over an in-memory pipe, logging to a
    /// temporary file, and reads the log back.
    async fn run(lines: Vec<String>, options: StreamOptions, fake: Fake, script: Script) -> Run {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("exec.jsonl");
        let mut log = ExecLog::append(&path).unwrap();
        let (host, device): (DuplexStream, DuplexStream) = tokio::io::duplex(4096);
        let controller = tokio::spawn(controller(device, fake, script));
        let result = stream(host, lines, options, &mut log).await;
        let fake = controller.await.unwrap();
        let read = log::read(&path).unwrap();
        assert!(!read.torn_tail);
        Run {
            result,
            fake,
            records: read.records,
        }
    }

    fn events(records: &[Record]) -> Vec<&log::Event> {
        records.iter().map(|r| &r.event).collect()
    }

    fn sent_lines(records: &[Record]) -> Vec<usize> {
        records
            .iter()
            .filter_map(|r| match &r.event {
                log::Event::Sent { line, .. } => Some(*line),
                _ => None,
            })
            .collect()
    }

    fn acked_lines(records: &[Record]) -> Vec<usize> {
        records
            .iter()
            .filter_map(|r| match &r.event {
                log::Event::Ack { line } => Some(*line),
                _ => None,
            })
            .collect()
    }

    fn statuses(records: &[Record]) -> Vec<(f64, String, [f64; 3])> {
        records
            .iter()
            .filter_map(|r| match &r.event {
                log::Event::Status { state, pos, .. } => Some((r.t, state.clone(), *pos)),
                _ => None,
            })
            .collect()
    }

    fn assert_start_and_end(records: &[Record], completed: bool) {
        let events = events(records);
        assert!(
            matches!(events.first(), Some(log::Event::Start { transport, .. }) if transport == TRANSPORT),
            "{events:?}"
        );
        assert!(
            matches!(events.last(), Some(log::Event::End { completed: c, .. }) if *c == completed),
            "{events:?}"
        );
        let times: Vec<f64> = records.iter().map(|r| r.t).collect();
        assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    }

    #[tokio::test(start_paused = true)]
    async fn the_whole_program_is_acked_and_logged_in_order() {
        let lines = moves(60);
        let run = run(lines.clone(), options(), Fake::grbl(128), Script::default()).await;
        let outcome = run.result.unwrap();
        assert!(outcome.completed(), "{outcome:?}");
        assert_eq!(
            (outcome.lines_total, outcome.lines_sent, outcome.lines_acked),
            (60, 60, 60)
        );
        assert!(outcome.resume.is_none());
        assert!(outcome.bytes_written > lines.iter().map(|l| l.len() as u64 + 1).sum());
        assert!(outcome.link_utilization.is_none(), "no baud given");
        assert_eq!(run.fake.executed, lines);
        assert!(!run.fake.overflowed);
        assert!(run.fake.max_fill <= 127);

        assert_start_and_end(&run.records, true);
        let events = events(&run.records);
        assert!(matches!(
            events.first(),
            Some(log::Event::Start { lines: 60, program, .. }) if program == "test.nc"
        ));
        assert_eq!(sent_lines(&run.records), (1..=60).collect::<Vec<_>>());
        assert_eq!(acked_lines(&run.records), (1..=60).collect::<Vec<_>>());
        for (k, text) in lines.iter().enumerate() {
            let line = k + 1;
            let sent = events.iter().position(
                |e| matches!(e, log::Event::Sent { line: l, text: t } if *l == line && t == text),
            );
            let acked = events
                .iter()
                .position(|e| matches!(e, log::Event::Ack { line: l } if *l == line));
            assert!(sent.unwrap() < acked.unwrap(), "line {line}");
        }
        assert!(!events.iter().any(|e| matches!(e, log::Event::Error { .. })));
    }

    #[tokio::test(start_paused = true)]
    async fn an_error_mid_stream_stops_cleanly_with_the_failed_line_and_resume_point() {
        let lines = moves(20);
        let mut fake = Fake::grblhal(1024);
        fake.fail = vec![(lines[7].clone(), 33)];
        let script = Script {
            line_time: Duration::from_millis(10),
            ..Script::default()
        };
        let run = run(lines.clone(), options(), fake, script).await;
        let outcome = run.result.unwrap();
        assert_eq!(
            outcome.ending,
            Ending::Stopped(StopReason::Error {
                line: LineRef::Program(7),
                code: 33
            })
        );
        assert_eq!(outcome.failed_line, Some(7));
        let resume = outcome.resume.unwrap();
        assert_eq!(resume.line_index, 7);
        assert_eq!(resume.basis, ResumeBasis::FailedLine);
        assert!(resume.executed_after_failure.is_empty());
        assert_eq!(outcome.lines_acked, 7);
        // grblHAL's sticky error: nothing after the failed line ran.
        assert_eq!(run.fake.executed, lines[..7]);

        assert_start_and_end(&run.records, false);
        let events = events(&run.records);
        assert!(events.iter().any(|e| matches!(
            e,
            log::Event::Error { line: 8, code: 33, message } if !message.is_empty()
        )));
        assert!(acked_lines(&run.records).iter().all(|&l| l <= 7));
        let Some(log::Event::End {
            reason: Some(reason),
            ..
        }) = events.last()
        else {
            panic!("no reason: {events:?}");
        };
        assert!(
            reason.contains("program line 8") && reason.contains("error:33"),
            "{reason}"
        );
    }

    #[tokio::test(start_paused = true)]
    async fn status_polls_run_at_5_hz_of_paused_time() {
        let lines = moves(20);
        let script = Script {
            line_time: Duration::from_millis(100),
            ..Script::default()
        };
        let options = StreamOptions {
            baud: Some(115_200),
            ..options()
        };
        let run = run(lines, options, Fake::grblhal(1024), script).await;
        let outcome = run.result.unwrap();
        assert!(outcome.completed(), "{outcome:?}");
        let wall = outcome.wall_time.as_secs_f64();
        // 21 lines ($I and the program) at 100 ms each.
        assert!((2.1..2.6).contains(&wall), "{wall}");

        let statuses = statuses(&run.records);
        let times: Vec<f64> = statuses.iter().map(|s| s.0).collect();
        for pair in times.windows(2) {
            let gap = pair[1] - pair[0];
            assert!((0.19..0.21).contains(&gap), "{times:?}");
        }
        let expected = wall / 0.2;
        assert!(
            (statuses.len() as f64 - expected).abs() <= 1.5,
            "{} reports in {wall} s",
            statuses.len()
        );
        // Positions come through X, Z, C from MPos (X Y Z C).
        let last = statuses.last().unwrap();
        assert_eq!(last.1, "Idle");
        assert_eq!(last.2, [20.0, 10.0, 200.0]);
        assert!(statuses.windows(2).all(|w| w[0].2[0] <= w[1].2[0]));

        let expected_use = outcome.bytes_written as f64 * 10.0 / (115_200.0 * wall);
        let measured = outcome.link_utilization.unwrap();
        assert!((measured - expected_use).abs() < 1e-9, "{measured}");
        assert!(outcome.streaming_utilization.is_some());
    }

    #[tokio::test(start_paused = true)]
    async fn completion_waits_until_the_motion_has_finished() {
        let lines = moves(10);
        let script = Script {
            run_reports_after: 3,
            ..Script::default()
        };
        let run = run(lines, options(), Fake::grblhal(1024), script).await;
        let outcome = run.result.unwrap();
        assert!(outcome.completed(), "{outcome:?}");
        let acked_at = outcome.all_acked_at.unwrap();
        assert!(outcome.wall_time >= acked_at + Duration::from_millis(600));

        let events = events(&run.records);
        let last_ack = events
            .iter()
            .rposition(|e| matches!(e, log::Event::Ack { .. }))
            .unwrap();
        let after: Vec<&str> = events[last_ack..]
            .iter()
            .filter_map(|e| match e {
                log::Event::Status { state, .. } => Some(state.as_str()),
                _ => None,
            })
            .collect();
        assert_eq!(after.last(), Some(&"Idle"), "{after:?}");
        assert!(
            after.iter().filter(|s| **s == "Run").count() >= 3,
            "{after:?}"
        );
        assert_start_and_end(&run.records, true);
    }

    #[tokio::test(start_paused = true)]
    async fn eof_from_the_controller_is_an_error_naming_the_port() {
        let script = Script {
            line_time: Duration::from_millis(10),
            close_after: Some(5),
            ..Script::default()
        };
        let run = run(moves(20), options(), Fake::grblhal(1024), script).await;
        let error = run.result.unwrap_err();
        assert!(
            matches!(&error, SerialError::Eof { port } if port == "/dev/ttyTEST"),
            "{error:?}"
        );
        assert!(error.to_string().contains("/dev/ttyTEST"), "{error}");
        assert_start_and_end(&run.records, false);
        assert!(matches!(
            run.records.last().map(|r| &r.event),
            Some(log::Event::End { reason: Some(reason), .. }) if reason.contains("/dev/ttyTEST")
        ));
    }

    #[tokio::test(start_paused = true)]
    async fn a_silent_controller_times_out_with_a_feed_hold() {
        let script = Script {
            hang_after: Some(3),
            ..Script::default()
        };
        let options = StreamOptions {
            no_progress_timeout: Some(Duration::from_secs(5)),
            ..options()
        };
        let run = run(moves(10), options, Fake::grblhal(1024), script).await;
        let outcome = run.result.unwrap();
        assert_eq!(
            outcome.ending,
            Ending::TimedOut {
                after: Duration::from_secs(5)
            }
        );
        assert_eq!(outcome.lines_acked, 3);
        assert!(outcome.resume.is_none());
        let wall = outcome.wall_time.as_secs_f64();
        assert!((5.0..5.5).contains(&wall), "{wall}");
        assert_eq!(run.fake.realtime.last(), Some(&b'!'));
        assert_start_and_end(&run.records, false);
        assert!(matches!(
            run.records.last().map(|r| &r.event),
            Some(log::Event::End { reason: Some(reason), .. }) if reason.contains("no progress")
        ));
    }

    #[tokio::test(start_paused = true)]
    async fn the_caller_holds_resumes_and_resets() {
        let (control, receiver) = crate::transport::control();
        let script = Script {
            line_time: Duration::from_millis(100),
            ..Script::default()
        };
        let options = StreamOptions {
            commands: Some(receiver),
            // A hold is not a stall, even one longer than the watchdog.
            no_progress_timeout: Some(Duration::from_millis(300)),
            ..options()
        };
        let caller = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(500)).await;
            assert!(control.hold());
            tokio::time::sleep(Duration::from_millis(500)).await;
            assert!(control.resume());
            tokio::time::sleep(Duration::from_millis(500)).await;
            assert!(control.abort());
        });
        let run = run(moves(40), options, Fake::grblhal(1024), script).await;
        caller.await.unwrap();
        let outcome = run.result.unwrap();
        assert_eq!(outcome.ending, Ending::Stopped(StopReason::SoftReset));
        let resume = outcome.resume.unwrap();
        assert!(resume.line_index <= outcome.lines_acked);
        let commands: Vec<u8> = run
            .fake
            .realtime
            .iter()
            .copied()
            .filter(|&b| b != b'?')
            .collect();
        assert_eq!(commands, [b'!', b'~', 0x18]);
        let messages: Vec<&str> = run
            .records
            .iter()
            .filter_map(|r| match &r.event {
                log::Event::Message { text } if text.ends_with("requested") => Some(text.as_str()),
                _ => None,
            })
            .collect();
        assert!(
            statuses(&run.records).iter().any(|s| s.1 == "Hold:0"),
            "the controller held"
        );
        assert_eq!(
            messages,
            [
                "feed hold requested",
                "resume requested",
                "soft reset requested"
            ]
        );
        assert_start_and_end(&run.records, false);
    }

    #[tokio::test(start_paused = true)]
    async fn the_machine_check_refuses_a_program_before_any_byte() {
        let machine = MachineProfile::builtin_sim().unwrap();
        let lines = vec![
            "G21 G90 G94".to_owned(),
            "G0 X0 Z0 C0".to_owned(),
            "G0 X1000".to_owned(),
        ];
        let options = StreamOptions {
            machine: Some(machine),
            ..options()
        };
        let run = run(lines, options, Fake::grblhal(1024), Script::default()).await;
        let error = run.result.unwrap_err();
        // The third line goes to X1000, past the travel: the error names that line.
        assert!(
            matches!(
                error,
                SerialError::Preflight(PreflightError::Limits { line: 3, .. })
            ),
            "{error:?}"
        );
        assert!(error.to_string().starts_with("line 3: "), "{error}");
        assert!(run.fake.realtime.is_empty());
        assert_eq!(run.fake.max_fill, 0);
        assert!(run.records.is_empty(), "nothing ran, nothing logged");
    }

    #[tokio::test(start_paused = true)]
    async fn progress_reports_reach_the_end() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&seen);
        let options = StreamOptions {
            on_progress: Some(Box::new(move |p: &Progress| {
                sink.lock().unwrap().push(p.clone());
            })),
            ..options()
        };
        let script = Script {
            line_time: Duration::from_millis(50),
            ..Script::default()
        };
        let run = run(moves(12), options, Fake::grblhal(1024), script).await;
        assert!(run.result.unwrap().completed());
        let seen = seen.lock().unwrap();
        let last = seen.last().unwrap();
        assert_eq!((last.unit, last.done, last.total), (Unit::Lines, 12, 12));
        assert!(last.finishing);
        assert_eq!(last.fraction(), 1.0);
        assert_eq!(last.position, Some([12.0, 6.0, 120.0]));
        assert!(seen.windows(2).all(|w| w[0].done <= w[1].done));
        assert!(seen
            .iter()
            .any(|p| p.left.is_some_and(|left| left > Duration::ZERO)));
    }

    #[test]
    fn status_positions_are_machine_x_z_c() {
        let axes = StatusAxes::default();
        let mpos = parse_status("Run|MPos:1.000,0.000,2.000,3.000|Bf:30,1000").unwrap();
        assert_eq!(machine_xzc(&mpos, None, axes), Some([1.0, 2.0, 3.0]));
        // WPos needs the work offset: WPos + WCO = MPos.
        let wpos = parse_status("Hold:0|WPos:1.000,0.000,2.000,3.000").unwrap();
        assert_eq!(machine_xzc(&wpos, None, axes), None);
        let wco = [10.0, 0.0, 20.0, 30.0];
        assert_eq!(
            machine_xzc(&wpos, Some(&wco), axes),
            Some([11.0, 22.0, 33.0])
        );
        assert_eq!(state_name(&wpos), "Hold:0");
        // A controller without C.
        let xyz = parse_status("Idle|MPos:1,0,2").unwrap();
        let no_c = StatusAxes { c: None, ..axes };
        assert_eq!(machine_xzc(&xyz, None, no_c), Some([1.0, 2.0, 0.0]));
        assert_eq!(machine_xzc(&xyz, None, axes), None);
    }

    #[test]
    fn link_utilization_is_bits_over_capacity() {
        assert_eq!(
            link_utilization(11_520, 115_200, Duration::from_secs(1)),
            Some(1.0)
        );
        assert_eq!(
            link_utilization(5_760, 115_200, Duration::from_secs(1)),
            Some(0.5)
        );
        assert_eq!(link_utilization(100, 115_200, Duration::ZERO), None);
        assert_eq!(link_utilization(100, 0, Duration::from_secs(1)), None);
    }

    /// The real serial path: a pseudo-terminal pair opened by tokio-serial, in real time.
    #[tokio::test]
    async fn streams_over_a_pseudo_terminal_pair() {
        let (host, device) = tokio_serial::SerialStream::pair().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("exec.jsonl");
        let mut log = ExecLog::append(&path).unwrap();
        let lines = moves(50);
        let controller = tokio::spawn(controller(device, Fake::grbl(128), Script::default()));
        let options = StreamOptions {
            port_name: "pty".to_owned(),
            baud: Some(115_200),
            streamer: StreamerConfig {
                poll_interval: Some(Duration::from_millis(20)),
                ..StreamerConfig::default()
            },
            no_progress_timeout: Some(Duration::from_secs(5)),
            ..StreamOptions::default()
        };
        let outcome = tokio::time::timeout(
            Duration::from_secs(20),
            stream(host, lines.clone(), options, &mut log),
        )
        .await
        .unwrap()
        .unwrap();
        assert!(outcome.completed(), "{outcome:?}");
        assert_eq!(outcome.lines_acked, 50);
        let fake = controller.await.unwrap();
        assert_eq!(fake.executed, lines);
        assert!(!fake.overflowed);
        let records = log::read(&path).unwrap().records;
        assert_eq!(acked_lines(&records), (1..=50).collect::<Vec<_>>());
        assert_start_and_end(&records, true);
    }
}
