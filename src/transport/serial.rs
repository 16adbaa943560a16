//! Streaming a G-code program to a grbl/grblHAL controller over a serial line.
//!
//! [`stream`] runs a [`Streamer`] against any byte stream: it writes what
//! [`Streamer::transmit`] hands out, feeds what it reads to [`Streamer::receive`], tells
//! [`Streamer::poll`] the time at the poll interval, and writes every event to the
//! executed-path log. It decides nothing about the protocol (what to send, which answer
//! belongs to which line, when the stream has stopped, when the motion after the last
//! line has finished, whether the machine is held): those are the streamer's, tested
//! without I/O. What stays here is bytes and time: the port, the poll clock, the caller's
//! commands, the no-progress watchdog, the log. [`stream_port`] opens a serial port with
//! tokio-serial and calls it; taking a generic stream is what lets the tests (and the dry
//! run) use an in-memory pipe or a pseudo-terminal and still run exactly the code a
//! machine gets.
//!
//! # When the run ends
//!
//! - **Completed**: the streamer's [`Event::Done`] only says every line was acknowledged;
//!   up to a planner's worth of moves may still be queued. The run goes on polling until
//!   the streamer's [`Event::MotionDone`], so "completed" means the motion finished.
//!   Which status reports prove that (`Idle` with every planner block free, or two `Idle`
//!   reports in a row from a controller without `Bf:`) is the streamer's rule, sans-I/O
//!   (see [its docs](grbl::streamer#when-the-motion-is-done)).
//!   Without polling ([`StreamerConfig::poll_interval`] `None`) or with
//!   [`StreamOptions::wait_for_idle`] off, the run completes at `Done`.
//! - **Stopped**: an `error:N`, an alarm or a reset ([`Event::Stopped`]); the outcome
//!   carries the reason and the streamer's [`ResumePoint`]. This is a result, not an
//!   error: the controller is in a known state and the caller decides what next.
//! - **Timed out**: with [`StreamOptions::no_progress_timeout`], a controller that says
//!   nothing new for that long (no answer, no change of state or position) beyond the
//!   planned time of the longest move it may be working through (the program lines not
//!   known to have run, [`StreamOptions::line_durations`]; the resume preamble's plunge,
//!   [`StreamOptions::approach_seconds`]) gets a feed hold (`!`, which stops motion without
//!   losing position, unlike a reset) and the run ends saying where to resume, as every
//!   other end does ([`Streamer::resume_point_now`]: the controller may have run any line
//!   sent).
//!   A hold (the caller's, or the controller in `Hold`, `Door` or `Tool`: the streamer's
//!   [`Streamer::is_held`]) is not a stall: the clock restarts while it lasts.
//! - **Interrupted**: the caller's [`Command::Stop`] (a signal, a console's stop button):
//!   the streamer's [`Streamer::interrupt`] sends a feed hold and no line after it, and the
//!   run polls on until a report shows the machine at rest ([`Streamer::is_standing`]), so
//!   the resume point comes from where it stands. The wait is limited (the no-progress
//!   timeout, else [`STAND_TIMEOUT`]); past it the run ends saying so.
//! - **Failed**: a read or write error, or the controller closing the stream, is a
//!   [`SerialError`] naming the port. The controller goes on with what it has received,
//!   so the error carries the first line not known to have executed and the last one it
//!   may run ([`Streamer::resume_point_now`]). An executed-path log that cannot be written
//!   fails the run too, but as a stop does (feed hold, the end once the machine stands,
//!   with where to resume): a run that cannot be recorded must not go on cutting.
//!
//! Every run is logged between [`log::Event::Start`] and [`log::Event::End`]
//! (also when it fails, as far as the log can still be written), with times in seconds
//! since the start; a run that did not complete logs where it resumes
//! ([`log::Event::ResumeAt`]) just before its End.

use std::fmt;
use std::future::pending;
use std::time::Duration;

use thiserror::Error;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, WriteHalf};
use tokio::time::{interval_at, sleep_until, Instant, Interval, MissedTickBehavior};
use tokio_serial::{ClearBuffer, SerialPort, SerialPortBuilderExt};
use tracing::Instrument;

use super::control::{Command, Commands, Request};
use super::progress::{Progress, ProgressFn, Unit};
use super::run::{check_program, PreflightError};
use crate::config::machine::MachineProfile;
use crate::log::{self, ExecLog, LogError};
use crate::program::timing::move_seconds;
use crate::program::{Move, Program};
use crate::protocol::grbl::{
    self, Event, LineRef, MachineState, ResumePoint, Status, StopReason, Streamer, StreamerConfig,
};

/// The transport's name in [`log::Event::Start`].
pub const TRANSPORT: &str = "serial";

/// How long the last bytes of a run (a feed hold, a soft reset) may take to go out before
/// the link is declared dead: they are a few bytes, so anything longer means it is stuck.
const FINAL_WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// The longest wait, after a stop, for a report of the machine at rest when no
/// no-progress timeout is set: a feed hold decelerates a machine within a second or two.
pub const STAND_TIMEOUT: Duration = Duration::from_secs(10);

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
    /// With `resume_at`: the moves that bring the ring back onto the groove at that line
    /// ([`crate::program::reentry::approach`]), written into the resume preamble
    /// ([`grbl::reentry_preamble`]); empty where the program's own moves are the way.
    pub approach: Vec<Move>,
    /// X words of the program are diameters unless it says otherwise (G7/G8): how the
    /// approach writes X.
    pub x_diameter: bool,
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
    /// Planned seconds of each program line ([`line_seconds`]), for the progress ETA and
    /// the no-progress watchdog, which allows the longest line in flight its planned time.
    pub line_durations: Option<Vec<f64>>,
    /// With `approach`: the planned seconds of its longest move (a re-entry's plunge at the
    /// program's plunge feed) or of the preamble's spin-up dwell, which the watchdog allows
    /// while the preamble may still be running.
    pub approach_seconds: f64,
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
            approach: Vec::new(),
            x_diameter: false,
            baud: None,
            no_progress_timeout: None,
            wait_for_idle: true,
            axes: StatusAxes::default(),
            machine: None,
            line_durations: None,
            approach_seconds: 0.0,
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
            .field("approach", &self.approach)
            .field("x_diameter", &self.x_diameter)
            .field("baud", &self.baud)
            .field("no_progress_timeout", &self.no_progress_timeout)
            .field("wait_for_idle", &self.wait_for_idle)
            .field("axes", &self.axes)
            .field("machine", &self.machine.as_ref().map(|m| &m.name))
            .field(
                "line_durations",
                &self.line_durations.as_ref().map(Vec::len),
            )
            .field("approach_seconds", &self.approach_seconds)
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
        /// The planned time of the longest move the controller may have been working
        /// through, which the wait allowed on top of the timeout.
        planned: Duration,
    },
}

impl fmt::Display for Ending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ending::Completed => write!(f, "completed"),
            Ending::Stopped(reason) => write!(f, "stopped: {reason}"),
            Ending::TimedOut { after, planned } => {
                write!(
                    f,
                    "stalled: nothing new from the controller for {:.0} s",
                    after.as_secs_f64()
                )?;
                if !planned.is_zero() {
                    write!(
                        f,
                        " beyond the {:.1} s its longest move in flight is planned to take",
                        planned.as_secs_f64()
                    )?;
                }
                write!(f, ": feed hold sent")
            }
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
    /// Where to resume, after a stop ([`Streamer::resume_point`]) or a stall (the first
    /// line not known to have executed, every line sent from there on possibly run:
    /// [`Streamer::resume_point_now`]); `None` when completed.
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
    #[error("cannot open {port}: {error}")]
    Open {
        /// The port.
        port: String,
        /// Why.
        error: tokio_serial::Error,
    },
    /// Reading or writing failed.
    #[error("{port}: {error}")]
    Io {
        /// The port.
        port: String,
        /// Why.
        error: std::io::Error,
        /// Where to resume, as far as the controller's reports before the failure tell.
        resume: Option<ResumePoint>,
    },
    /// The controller's end closed the stream.
    #[error("{port}: the connection was closed (end of file) mid-stream")]
    Eof {
        /// The port.
        port: String,
        /// Where to resume, as far as the controller's reports before the failure tell.
        resume: Option<ResumePoint>,
    },
    /// The program cannot be streamed as it is (a forbidden byte, a line too long).
    #[error("the program cannot be streamed: {0}")]
    Program(grbl::StreamerError),
    /// The program failed the machine check; nothing was sent.
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    /// The executed-path log could not be written: the machine was held, and the run ended
    /// once it stood (or the wait for that ran out).
    #[error("{error}: the machine was held")]
    Log {
        /// Why the log could not be written.
        error: LogError,
        /// Where to resume, as far as the controller's reports tell.
        resume: Option<ResumePoint>,
    },
}

impl SerialError {
    /// Where to resume after a failure mid-stream.
    pub fn resume(&self) -> Option<&ResumePoint> {
        match self {
            SerialError::Io { resume, .. }
            | SerialError::Eof { resume, .. }
            | SerialError::Log { resume, .. } => resume.as_ref(),
            _ => None,
        }
    }
}

/// How busy a serial link was, 0 to 1: `bytes` × 10 bits (8N1: a start bit, eight data
/// bits, a stop bit) over what `baud` could carry in `time`. `None` for a zero baud rate or
/// time, and when the bytes went faster than `baud` allows: the link was then no serial
/// line at that rate (a pseudo-terminal ignores the rate; a simulator runs on its own
/// clock), so the ratio measures nothing of it.
pub fn link_utilization(bytes: u64, baud: u32, time: Duration) -> Option<f64> {
    let capacity = f64::from(baud) * time.as_secs_f64();
    Some(bytes as f64 * 10.0 / capacity).filter(|&share| capacity > 0.0 && share <= 1.0)
}

/// Planned seconds of each of `lines` (0-based) from the moves `program` reads them as,
/// `move_lines` giving each move's file line (1-based), on `machine`
/// ([`MoveTime::planned`](crate::program::timing::MoveTime::planned); a line that moves
/// nothing takes 0).
pub fn line_seconds(
    lines: usize,
    program: &Program,
    move_lines: &[usize],
    machine: &MachineProfile,
) -> Vec<f64> {
    let mut seconds = vec![0.0; lines];
    for (step, time) in move_seconds(program, machine) {
        if let Some(slot) = move_lines
            .get(step)
            .and_then(|&line| seconds.get_mut(line.wrapping_sub(1)))
        {
            *slot += time;
        }
    }
    seconds
}

/// Opens the serial port at `path` (8N1, no flow control, as grbl expects) and streams
/// `lines` over it with [`stream`]. The machine check, if asked for, runs before the port
/// is opened: opening resets some boards (an Arduino running grbl), so a program that
/// will be refused should not even do that. What waited in the port's input is cleared
/// once it is open: the output of an earlier session, a banner printed before anyone
/// listened; only what the controller says from now on answers what is sent from now on
/// (the streamer's connect phase, [`StreamerConfig::check_state`], then finds out whether
/// the controller is up). `options.port_name` becomes `path` and `options.baud` defaults
/// to `baud`.
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
        .map_err(|error| SerialError::Open {
            port: path.to_owned(),
            error,
        })?;
    // Best effort: what is left in the input is what the connect phase copes with anyway.
    if let Err(error) = port.clear(ClearBuffer::Input) {
        tracing::warn!(%error, port = path, "cannot clear the port's input");
    }
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
        Some(index) if !options.approach.is_empty() => {
            let preamble = grbl::reentry_preamble(
                &lines,
                index,
                &options.approach,
                options.x_diameter,
                config.spin_up_dwell_s,
            )
            .map_err(|e| SerialError::Program(e.into()))?;
            let config = StreamerConfig {
                start_line: index,
                ..config
            };
            Streamer::with_preamble(lines.clone(), preamble, config)
        }
        Some(index) => Streamer::resume_from(lines.clone(), index, config),
        None => Streamer::new(lines.clone(), config),
    }
    .map_err(SerialError::Program)?;
    let span = tracing::debug_span!("stream", port = %options.port_name, lines = lines.len());
    let run = Run {
        wait_for_idle: options.wait_for_idle && poll_interval.is_some(),
        timeout: options.no_progress_timeout,
        axes: options.axes,
        durations: options.line_durations.take(),
        approach_seconds: options.approach_seconds,
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
        stand_by: None,
        log_failure: None,
        alarms: Vec::new(),
        wco: None,
        last_status: None,
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
    approach_seconds: f64,
    on_progress: Option<ProgressFn>,
    baud: Option<u32>,
    sent: usize,
    acked: usize,
    bytes_written: u64,
    bytes_read: u64,
    all_acked_at: Option<Duration>,
    bytes_at_all_acked: u64,
    /// The streamer's [`Event::MotionDone`]: the motion after the last line finished.
    motion_done: bool,
    stopped: Option<StopReason>,
    /// After a [`Command::Stop`]: the latest a report of the machine at rest may come.
    stand_by: Option<Instant>,
    /// Why the log could not be written, once it could not: nothing more is logged, and the
    /// run stops as for a [`Command::Stop`].
    log_failure: Option<LogError>,
    alarms: Vec<u16>,
    /// The last work coordinate offset seen, in the order the reports came.
    wco: Option<Vec<f64>>,
    last_status: Option<Status>,
}

impl Run<'_> {
    fn now(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Logs `event`. A log that cannot be written stops the run as a [`Command::Stop`]
    /// would (feed hold, then the end once the machine stands): the controller is not left
    /// executing what nobody records.
    fn write_log(&mut self, event: log::Event) {
        if self.log_failure.is_some() {
            return;
        }
        let t = self.now();
        if let Err(error) = self.log.write(t, event) {
            tracing::warn!(%error, "the log cannot be written: feed hold");
            self.log_failure = Some(error);
            self.stop("the executed-path log cannot be written");
        }
    }

    fn io_error(&self, error: std::io::Error) -> SerialError {
        SerialError::Io {
            port: self.port.clone(),
            error,
            resume: Some(self.streamer.resume_point_now()),
        }
    }

    /// Where a run that ended so resumes: after a stop, the streamer's resume point; after
    /// a stall, where it would be if the run ended now (the controller, held but not known
    /// to stand, may have run any line sent); none after a completed run.
    fn resume(&self, ending: &Ending) -> Option<ResumePoint> {
        match ending {
            Ending::Completed => None,
            Ending::Stopped(_) => self.streamer.resume_point(),
            Ending::TimedOut { .. } => Some(self.streamer.resume_point_now()),
        }
    }

    /// The longest a controller working through what it was sent may rightly say nothing
    /// new: the planned time of the longest program line not known to have run, or, while
    /// the resume preamble may still be running, of its longest move or dwell. A 33 s
    /// plunge is not a stall.
    fn planned_in_flight(&self) -> Duration {
        let lines = self.durations.as_ref().map_or(0.0, |durations| {
            self.streamer
                .lines_in_flight()
                .filter_map(|i| durations.get(i).copied())
                .fold(0.0, f64::max)
        });
        let preamble = if self.streamer.preamble_may_be_running() {
            self.approach_seconds
        } else {
            0.0
        };
        Duration::try_from_secs_f64(lines.max(preamble)).unwrap_or_default()
    }

    /// Logs where a run that did not complete resumes, if it is known.
    fn log_resume(&mut self, resume: Option<&ResumePoint>) {
        let Some(resume) = resume else {
            return;
        };
        let possibly = &resume.possibly_executed;
        self.write_log(log::Event::ResumeAt {
            line: resume.line_index + 1,
            possibly_run_to: (!possibly.is_empty()).then_some(possibly.end),
        })
    }

    async fn run<P: AsyncRead + AsyncWrite + Unpin>(
        mut self,
        port: P,
        poll_interval: Option<Duration>,
        commands: Option<Commands>,
    ) -> Result<StreamOutcome, SerialError> {
        self.start = Instant::now();
        // Nothing is sent before the run's Start is in the log.
        let start = log::Event::Start {
            program: self.program.clone(),
            lines: self.lines.len(),
            transport: TRANSPORT.to_owned(),
        };
        self.log
            .write(0.0, start)
            .map_err(|error| SerialError::Log {
                error,
                resume: None,
            })?;
        tracing::debug!(program = %self.program, "stream started");
        let (mut reader, mut writer) = tokio::io::split(port);
        let mut out: Vec<u8> = Vec::new();
        let driven = self
            .exchange(&mut reader, &mut writer, &mut out, poll_interval, commands)
            .await;
        match driven {
            Ok(ending) => {
                let reason = match &ending {
                    Ending::Completed => None,
                    Ending::Stopped(reason) => Some(reason.to_string()),
                    Ending::TimedOut { .. } => Some(ending.to_string()),
                };
                tracing::debug!(?ending, "stream ended");
                self.log_resume(self.resume(&ending).as_ref());
                self.write_log(log::Event::End {
                    completed: ending == Ending::Completed,
                    reason,
                });
                match self.log_failure.take() {
                    Some(error) => Err(SerialError::Log {
                        error,
                        resume: self.resume(&ending),
                    }),
                    None => Ok(self.outcome(ending)),
                }
            }
            Err(error) => {
                tracing::warn!(%error, "stream failed");
                self.log_resume(error.resume());
                self.write_log(log::Event::End {
                    completed: false,
                    reason: Some(error.to_string()),
                });
                Err(error)
            }
        }
    }

    /// The loop: bytes out, bytes in, the poll clock, the caller's commands, the watchdog.
    async fn exchange<P: AsyncRead + AsyncWrite + Unpin>(
        &mut self,
        reader: &mut tokio::io::ReadHalf<P>,
        writer: &mut WriteHalf<P>,
        out: &mut Vec<u8>,
        poll_interval: Option<Duration>,
        mut commands: Option<Commands>,
    ) -> Result<Ending, SerialError> {
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
            let progressed = self.drain_events();
            if progressed || self.streamer.is_held() {
                last_progress = Instant::now();
            }
            if let Some(ending) = self.ending() {
                // What is queued still goes out: real-time bytes queued with the stop (a soft
                // reset's 0x18), and the rest of a line cut off mid-write, which would
                // otherwise sit in the controller's buffer and merge with the next command.
                self.write_final(writer, out).await?;
                return Ok(ending);
            }
            let planned = self.planned_in_flight();
            let deadline = self.stand_by.or(self
                .timeout
                .map(|timeout| last_progress + timeout + planned));
            tokio::select! {
                written = writer.write(out), if !out.is_empty() => {
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
                        return Err(SerialError::Eof {
                            port: self.port.clone(),
                            resume: Some(self.streamer.resume_point_now()),
                        });
                    }
                    self.bytes_read += n as u64;
                    self.streamer.receive(&buffer[..n]);
                }
                at = next_tick(&mut ticker) => {
                    self.streamer.poll(at.duration_since(self.start));
                }
                request = next_request(&mut commands) => match request {
                    Request::Command(command) => self.command(command),
                    Request::FeedOverride(percent) => self.feed_override(percent),
                },
                () = wait_until(deadline) => {
                    if self.stand_by.take().is_some() {
                        // The wait after a stop ran out: the run ends at the top of the loop.
                        tracing::warn!("no report of the machine at rest after the stop");
                        self.write_log(log::Event::Message {
                            text: "the controller did not report the machine at rest after \
                                   the feed hold: check it stands before resuming"
                                .to_owned(),
                        });
                        continue;
                    }
                    let after = self.timeout.unwrap_or_default();
                    tracing::warn!(
                        seconds = after.as_secs_f64(),
                        planned = planned.as_secs_f64(),
                        "no progress: feed hold"
                    );
                    self.streamer.feed_hold();
                    if let Some(bytes) = self.streamer.transmit() {
                        out.extend_from_slice(&bytes);
                    }
                    self.drain_events();
                    self.write_final(writer, out).await?;
                    return Ok(Ending::TimedOut { after, planned });
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

    fn command(&mut self, command: Command) {
        tracing::debug!(?command, "caller command");
        let text = match command {
            Command::Hold => {
                self.streamer.feed_hold();
                "feed hold requested"
            }
            Command::Resume => {
                self.streamer.resume();
                "resume requested"
            }
            Command::Stop { reason } => {
                self.stop(reason);
                "stop requested: feed hold, then the run ends once the machine stands"
            }
            Command::Abort => {
                self.streamer.soft_reset();
                "soft reset requested"
            }
        };
        self.write_log(log::Event::Message {
            text: text.to_owned(),
        });
    }

    /// The caller's feed override (checked against the cap by the [`Control`](super::Control)):
    /// the real-time bytes go out one at a time as `Ov:` confirms each.
    fn feed_override(&mut self, percent: u16) {
        tracing::debug!(percent, "feed override asked");
        self.streamer.feed_override(percent);
        self.write_log(log::Event::FeedOverride {
            percent,
            state: log::FeedOverrideState::Asked,
        });
    }

    /// Feed hold; the run ends once the machine stands, or when the wait for that runs out.
    fn stop(&mut self, reason: impl Into<String>) {
        self.streamer.interrupt(reason);
        let wait = self.timeout.unwrap_or(STAND_TIMEOUT);
        self.stand_by.get_or_insert(Instant::now() + wait);
    }

    /// How the run ends now, if it does.
    fn ending(&self) -> Option<Ending> {
        if let Some(reason) = &self.stopped {
            // An interrupted run ends once the machine stands (or the wait for it ran out).
            let waiting = matches!(reason, StopReason::Interrupted { .. })
                && self.stand_by.is_some()
                && !self.streamer.is_standing();
            return (!waiting).then(|| Ending::Stopped(reason.clone()));
        }
        let done = self.all_acked_at.is_some() && (self.motion_done || !self.wait_for_idle);
        done.then_some(Ending::Completed)
    }

    /// Logs the streamer's events; `true` if any showed the controller doing something.
    fn drain_events(&mut self) -> bool {
        let mut any = false;
        let mut progressed = false;
        while let Some(event) = self.streamer.next_event() {
            any = true;
            progressed |= self.handle(event);
        }
        if any {
            self.report_progress();
        }
        progressed
    }

    /// Logs one event; `true` if it shows the controller doing something.
    fn handle(&mut self, event: Event) -> bool {
        let log = match event {
            Event::Sent { index, line_no } => {
                self.sent += 1;
                let text = self.lines.get(index).cloned().unwrap_or_default();
                tracing::debug!(line = index + 1, ?line_no, %text, "sent");
                self.write_log(log::Event::Sent {
                    line: index + 1,
                    text,
                });
                return false;
            }
            Event::AuxSent { line, text } => {
                tracing::debug!(?line, %text, "sent (streamer's own line)");
                return false;
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
                    None => return true,
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
                return true;
            }
            Event::Options(options) => {
                tracing::debug!(?options, "build options");
                return true;
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
                return true;
            }
            Event::Done => {
                tracing::debug!("every line acknowledged");
                self.all_acked_at = Some(self.start.elapsed());
                self.bytes_at_all_acked = self.bytes_written;
                return true;
            }
            Event::FeedOverride { percent } => {
                tracing::debug!(percent, "feed override reported");
                log::Event::FeedOverride {
                    percent,
                    state: log::FeedOverrideState::Running,
                }
            }
            Event::FeedOverrideNotTaken { asked, reported } => {
                tracing::warn!(asked, ?reported, "feed override not taken");
                self.write_log(log::Event::Message {
                    text: match reported {
                        None => format!(
                            "feed override {asked} % not confirmed: the controller reports no \
                             Ov: field, so whirl cannot tell the feed it runs at; set it on the \
                             controller's panel"
                        ),
                        Some(at) => format!(
                            "feed override {asked} % not reached: the controller stays at {at} %"
                        ),
                    },
                });
                log::Event::FeedOverride {
                    percent: asked,
                    state: log::FeedOverrideState::NotTaken,
                }
            }
            Event::MotionDone => {
                // Nothing new from the controller: the status report before it said so.
                tracing::debug!("motion finished");
                self.motion_done = true;
                return false;
            }
            Event::Unrecognized(text) => {
                tracing::debug!(%text, "unrecognised controller output");
                log::Event::Message {
                    text: format!("unrecognised controller output: {text}"),
                }
            }
        };
        self.write_log(log);
        true
    }

    /// Logs a status report; `true` if the state or the position changed.
    fn on_status(&mut self, status: Status) -> bool {
        if let Some(wco) = &status.wco {
            self.wco = Some(wco.clone());
        }
        let position = self.position(&status);
        let changed = self.last_status.as_ref().is_none_or(|last| {
            last.state != status.state
                || last.substate != status.substate
                || self.position(last) != position
        });
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
        self.write_log(event);
        changed
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
            resume: self.resume(&ending),
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

/// The caller's next command or feed override, or never without any.
async fn next_request(commands: &mut Option<Commands>) -> Request {
    match commands {
        Some(commands) => commands.next_request().await,
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
mod tests;
