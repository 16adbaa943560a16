//! A planned program run on three CiA 402 drives over CAN: the sans-I/O [`Session`] driven
//! through an slcan adapter on a serial line (tokio-serial) or a socketcan interface
//! (socketcan's tokio socket).
//!
//! # The run
//!
//! 1. Open the link: for slcan, close the channel (an adapter left open by an earlier run
//!    refuses a new bit rate), set the bit rate, open it; each command must be answered
//!    with CR, not BEL.
//! 2. Read each drive's position actual value (6064h) by expedited SDO. CSP set-points
//!    begin where the drives stand ([`crate::post::setpoints`]), so the program is
//!    sampled from there, with [`CanOptions::sample`]'s cycle, scales and rates.
//! 3. Run the [`Session`]: its frames out, the bus's frames in, its events to the log,
//!    until it has finished or stopped. Nothing else decides anything here.
//!
//! # Clocks
//!
//! [`CanClock::Wall`] is a machine's: the session is polled every millisecond of wall time
//! and sends each cycle's RPDOs and SYNC when the period has passed (tokio's timer has a
//! millisecond's grain, so a cycle's SYNC can be up to that late; the session reports a
//! whole period late as [`Event::Late`] and slows the path rather than jump).
//!
//! [`CanClock::SyncLocked`] is for the simulator's drives, which lock their clock to the
//! master's SYNC as CSP drives lock their control cycle to it (`whirl_sim::canopen`): time
//! runs on the wall until the first SYNC, and from then on each cycle is one period of
//! the session's time, begun as soon as the adapter has acknowledged the frames of all
//! but the last eight cycles. A job of hours then runs as fast as the link and the
//! simulator go, with both ends agreeing on every cycle. It needs the adapter's
//! acknowledgements, so slcan only. [`CanOptions::pace`] holds such a run to a time scale
//! (a console's dry run that an operator watches, holds and stops): a cycle begins no
//! sooner than its session time over the scale, in wall time, after the first SYNC.
//!
//! Every frame is sent as the session gives it; the log gets the session's events (boot-up,
//! configuration, enable, spindle marks, emergencies, the stop and its reason), not the
//! cycles, which the simulator's execution record logs as moves.
//!
//! # Ends
//!
//! A run that logged its start logs its end, whatever ends it, with the reason. The caller's
//! stop ([`control::Command::Stop`]), like a log that can no longer be written, is the
//! session's gentle stop ([`Session::stop_held`]): the path held to a stand, then the drives
//! disabled; so is a stall, with the session's stall timeout set. A run that did not
//! complete says where to resume
//! ([`CanOutcome::resume_move`], from [`Session::resume_move`]); an error once the session
//! ran carries it too ([`CanError::Interrupted`]).

use super::control::{self, Commands};
use super::progress::{MoveLines, Progress, ProgressFn, Unit};
use crate::log::{self, ExecLog, LogError};
use crate::post::setpoints::{sample, SampleConfig, SampleError, SetPoints};
use crate::program::{Position, Program};
use crate::protocol::canopen::cia301::{NodeId, SdoClient, SdoDone};
use crate::protocol::canopen::cia402::object;
use crate::protocol::canopen::session::{Event, Phase, Session, SessionConfig, StopReason};
use crate::protocol::canopen::slcan::{Bitrate, Command, Decoder, Received};
use crate::protocol::canopen::{CanFrame, CanId};
use futures_util::FutureExt;
use std::collections::VecDeque;
use std::time::Duration;
use thiserror::Error;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::time::Instant;
use tokio_serial::SerialPortBuilderExt;

/// Where the drives are.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CanLink {
    /// An slcan (Lawicel) adapter on a serial line.
    Slcan {
        /// Its port (a device or a pseudo-terminal).
        path: String,
        /// The serial line's baud rate (a USB adapter ignores it).
        baud: u32,
        /// The CAN bus's bit rate.
        bitrate: Bitrate,
    },
    /// A socketcan interface (`can0`), set up and brought up by the system.
    SocketCan {
        /// The interface's name.
        interface: String,
    },
}

impl CanLink {
    /// `can-slcan` or `can`, as the log and the CLI name transports.
    pub fn transport(&self) -> &'static str {
        match self {
            CanLink::Slcan { .. } => "can-slcan",
            CanLink::SocketCan { .. } => "can",
        }
    }
}

impl std::fmt::Display for CanLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CanLink::Slcan {
                path,
                baud,
                bitrate,
            } => write!(
                f,
                "slcan adapter {path} ({baud} baud, CAN at {} kbit/s)",
                bitrate.bits_per_second() / 1000
            ),
            CanLink::SocketCan { interface } => write!(f, "socketcan {interface}"),
        }
    }
}

/// How the session's time runs; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CanClock {
    /// The wall clock: a machine's drives.
    Wall,
    /// One period a cycle once the cycle runs, for drives whose clock is the SYNC (the
    /// simulator's).
    SyncLocked,
}

/// How [`stream_can`] runs.
pub struct CanOptions {
    /// The master's settings: nodes, heartbeat, windows, timeouts.
    pub session: SessionConfig,
    /// The cycle, the drives' scales and the axes' rates for sampling.
    pub sample: SampleConfig,
    /// The session's clock.
    pub clock: CanClock,
    /// With [`CanClock::SyncLocked`]: at most this many session seconds a wall second once
    /// the cycle runs (finite, above zero); `None`: as fast as the link and the drives go.
    /// The wall clock is real time, and ignores it.
    pub pace: Option<f64>,
    /// Longest wait, wall time, for the adapter to answer a command and for a drive to
    /// answer the position read.
    pub answer_timeout: Duration,
    /// What is run, for the log.
    pub program: String,
    /// Told how far the run is: once a second of the session's time, held or not, and at
    /// its end.
    pub on_progress: Option<ProgressFn>,
    /// The caller's hold, resume, stop and abort: the set-points slowed along the path to
    /// a stand and brought back up to speed, the same stand then the drives disabled, or a
    /// quick stop.
    pub commands: Option<Commands>,
    /// The program line of each move of the program run: a run that does not complete
    /// logs the line to resume at (1-based, as `--resume-at` takes it) just before its
    /// `end`, in the order every transport logs them. `None`: the caller knows no lines,
    /// and the log gets no `resume_at`.
    pub lines: Option<MoveLines>,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub struct CanOutcome {
    /// Every set-point was sent, the drives settled on the last and were disabled.
    pub completed: bool,
    /// Why the session stopped, if it did.
    pub stop: Option<StopReason>,
    /// Drives whose disabling was not confirmed after a stop.
    pub unconfirmed: Vec<NodeId>,
    /// Where a run that did not complete resumes: the index in the program of the first
    /// move the drives are not known to have run to its end ([`Session::resume_move`]);
    /// `None` when completed.
    pub resume_move: Option<usize>,
    /// The program line (0-based) of `resume_move`, where the caller gave the moves' lines
    /// ([`CanOptions::lines`]).
    pub resume_line: Option<usize>,
    /// Set-points sent.
    pub sent: usize,
    /// Set-points of the program.
    pub setpoints: usize,
    /// Cycles whose SYNC went out a whole period late.
    pub late_cycles: usize,
    /// Where the drives stood, X, Z (mm), C (degrees).
    pub start: [f64; 3],
    /// Bytes written to the port (slcan) or frames × 16 bytes (socketcan).
    pub bytes_written: u64,
    /// Bit times of the frames sent and received during the session, without stuff
    /// bits ([`CanFrame::bits`]).
    pub bus_bits: u64,
    /// The session's time from its start to its end: wall time, or with a SYNC-locked
    /// clock the cycles' time.
    pub session_time: Duration,
}

impl CanOutcome {
    /// The share of the bus's bit times the session's frames took, at `bitrate` bits/s.
    pub fn bus_load(&self, bitrate: u32) -> f64 {
        let time = self.session_time.as_secs_f64();
        if time > 0.0 {
            self.bus_bits as f64 / (f64::from(bitrate) * time)
        } else {
            0.0
        }
    }
}

/// Why a CAN run could not be carried out. A run the session stopped is not an error: it
/// is in the outcome.
#[derive(Debug, Error)]
pub enum CanError {
    /// The port or interface could not be opened.
    #[error("cannot open {link}: {error}")]
    Open {
        /// The link.
        link: String,
        /// Why.
        error: std::io::Error,
    },
    /// Reading or writing failed.
    #[error("{link}: {error}")]
    Io {
        /// The link.
        link: String,
        /// Why.
        error: std::io::Error,
    },
    /// The slcan adapter answered a command with BEL.
    #[error("the slcan adapter refused {command}")]
    Refused {
        /// The command, as sent.
        command: String,
    },
    /// Nothing answered in time.
    #[error("{what}: no answer within {waited:?}")]
    Silent {
        /// What was waited for.
        what: String,
        /// How long.
        waited: Duration,
    },
    /// A drive's position could not be read before the run.
    #[error("reading node {node}'s position actual value (6064h): {reason}")]
    Position {
        /// The node.
        node: NodeId,
        /// Why.
        reason: String,
    },
    /// The program cannot be sampled into set-points.
    #[error("set-points: {0}")]
    Sample(SampleError),
    /// The session's configuration.
    #[error(transparent)]
    Session(#[from] crate::protocol::canopen::session::SessionError),
    /// A SYNC-locked clock needs the adapter's acknowledgements.
    #[error("a SYNC-locked clock needs an slcan adapter's acknowledgements; {0} has none")]
    Lockstep(String),
    /// A pace that is no time scale.
    #[error(
        "a SYNC-locked clock's pace of {0} session seconds a wall second: it must be finite \
         and above zero"
    )]
    Pace(f64),
    /// The executed-path log. Once the session ran, the drives were stopped (the gentle
    /// stop, [`Session::stop_held`]) before the run ended with this.
    #[error(transparent)]
    Log(#[from] LogError),
    /// Any of the above once the session had begun, with where to resume.
    #[error("{error}")]
    Interrupted {
        /// What ended it.
        error: Box<CanError>,
        /// As [`CanOutcome::resume_move`].
        resume_move: usize,
    },
}

impl CanError {
    /// Where to resume a run that failed after the session began.
    pub fn resume_move(&self) -> Option<usize> {
        match self {
            CanError::Interrupted { resume_move, .. } => Some(*resume_move),
            _ => None,
        }
    }
}

/// What came off the link.
enum Incoming {
    /// A frame from the bus.
    Frame(CanFrame),
    /// The adapter took a command.
    Ack,
    /// The adapter refused a command.
    Refused,
}

/// An open link.
enum Port {
    Slcan {
        stream: tokio_serial::SerialStream,
        decoder: Decoder,
        buffer: Vec<u8>,
    },
    Socket(socketcan::tokio::CanSocket),
}

impl Port {
    async fn open(link: &CanLink, timeout: Duration) -> Result<Port, CanError> {
        let name = link.to_string();
        match link {
            CanLink::Slcan {
                path,
                baud,
                bitrate,
            } => {
                let stream = tokio_serial::new(path, *baud)
                    .open_native_async()
                    .map_err(|e| CanError::Open {
                        link: name.clone(),
                        error: e.into(),
                    })?;
                let mut port = Port::Slcan {
                    stream,
                    decoder: Decoder::new(),
                    buffer: vec![0; 4096],
                };
                // Close first: an adapter left open refuses `S`; a closed one refuses the
                // close, which is fine.
                port.write(&name, &Command::Close.encode()).await?;
                port.answer(&name, timeout).await?;
                for command in [Command::SetBitrate(*bitrate), Command::Open] {
                    let bytes = command.encode();
                    port.write(&name, &bytes).await?;
                    if !port.answer(&name, timeout).await? {
                        return Err(CanError::Refused {
                            command: String::from_utf8_lossy(&bytes).trim_end().to_owned(),
                        });
                    }
                }
                Ok(port)
            }
            CanLink::SocketCan { interface } => socketcan::tokio::CanSocket::open(interface)
                .map(Port::Socket)
                .map_err(|error| CanError::Open { link: name, error }),
        }
    }

    /// Waits for the adapter's answer to a command: true for CR, false for BEL.
    async fn answer(&mut self, name: &str, timeout: Duration) -> Result<bool, CanError> {
        let deadline = Instant::now() + timeout;
        loop {
            let incoming = tokio::time::timeout_at(deadline, self.read(name))
                .await
                .map_err(|_| CanError::Silent {
                    what: format!("{name}, answering a command"),
                    waited: timeout,
                })??;
            for item in incoming {
                match item {
                    Incoming::Ack => return Ok(true),
                    Incoming::Refused => return Ok(false),
                    Incoming::Frame(_) => {}
                }
            }
        }
    }

    async fn write(&mut self, name: &str, bytes: &[u8]) -> Result<(), CanError> {
        let Port::Slcan { stream, .. } = self else {
            unreachable!("only slcan writes bytes");
        };
        stream.write_all(bytes).await.map_err(|error| CanError::Io {
            link: name.to_owned(),
            error,
        })
    }

    /// Sends `frames`, in one write on slcan; returns the bytes written.
    async fn send(&mut self, name: &str, frames: &[CanFrame]) -> Result<u64, CanError> {
        match self {
            Port::Slcan { .. } => {
                let bytes: Vec<u8> = frames
                    .iter()
                    .flat_map(|f| Command::Transmit(*f).encode())
                    .collect();
                self.write(name, &bytes).await?;
                Ok(bytes.len() as u64)
            }
            Port::Socket(socket) => {
                for frame in frames {
                    socket
                        .write_frame(to_socketcan(frame))
                        .await
                        .map_err(|error| CanError::Io {
                            link: name.to_owned(),
                            error,
                        })?;
                }
                Ok(16 * frames.len() as u64)
            }
        }
    }

    /// What arrives next (at least one item, unless a read brought only part of a line).
    async fn read(&mut self, name: &str) -> Result<Vec<Incoming>, CanError> {
        let io = |error| CanError::Io {
            link: name.to_owned(),
            error,
        };
        match self {
            Port::Slcan {
                stream,
                decoder,
                buffer,
            } => {
                let n = stream.read(buffer).await.map_err(io)?;
                if n == 0 {
                    return Err(io(std::io::ErrorKind::UnexpectedEof.into()));
                }
                let mut out = Vec::new();
                for item in decoder.feed(&buffer[..n]) {
                    match item {
                        Ok(Received::Frame { frame, .. }) => out.push(Incoming::Frame(frame)),
                        Ok(Received::Ok | Received::Transmitted { .. }) => out.push(Incoming::Ack),
                        Ok(Received::Error) => out.push(Incoming::Refused),
                        // A line garbled on the serial link: its frame is lost, as on a bus
                        // with errors; the session's supervision covers what that costs.
                        Err(error) => tracing::warn!("{name}: {error}"),
                    }
                }
                Ok(out)
            }
            Port::Socket(socket) => {
                let frame = socket.read_frame().await.map_err(io)?;
                Ok(from_socketcan(&frame)
                    .map(Incoming::Frame)
                    .into_iter()
                    .collect())
            }
        }
    }
}

fn to_socketcan(frame: &CanFrame) -> socketcan::CanFrame {
    use socketcan::{EmbeddedFrame, ExtendedId, Id, StandardId};
    let id = match frame.id() {
        CanId::Standard(raw) => Id::Standard(StandardId::new(raw).expect("an 11-bit id")),
        CanId::Extended(raw) => Id::Extended(ExtendedId::new(raw).expect("a 29-bit id")),
    };
    let built = if frame.is_remote() {
        socketcan::CanFrame::new_remote(id, frame.dlc().into())
    } else {
        socketcan::CanFrame::new(id, frame.data())
    };
    built.expect("a valid CAN 2.0 frame")
}

/// A socketcan frame as a CAN 2.0 frame; error frames are the interface's reports, not
/// frames on the bus.
fn from_socketcan(frame: &socketcan::CanFrame) -> Option<CanFrame> {
    use socketcan::{EmbeddedFrame, Id};
    let id = match frame.id() {
        Id::Standard(id) => CanId::standard(id.as_raw()),
        Id::Extended(id) => CanId::extended(id.as_raw()),
    }
    .ok()?;
    match frame {
        socketcan::CanFrame::Data(_) => CanFrame::new(id, frame.data()).ok(),
        socketcan::CanFrame::Remote(_) => CanFrame::remote(id, frame.dlc() as u8).ok(),
        socketcan::CanFrame::Error(_) => None,
    }
}

/// Reads every drive's position actual value (6064h), in counts, X, Z, C.
async fn positions(
    port: &mut Port,
    name: &str,
    nodes: [NodeId; 3],
    timeout: Duration,
) -> Result<[i64; 3], CanError> {
    let mut counts = [0; 3];
    for (k, node) in nodes.into_iter().enumerate() {
        let failed = |reason: String| CanError::Position { node, reason };
        let mut sdo = SdoClient::new(node, timeout);
        sdo.upload(object::POSITION_ACTUAL, 0, Duration::ZERO)
            .map_err(|e| failed(e.to_string()))?;
        let request: Vec<CanFrame> = std::iter::from_fn(|| sdo.transmit()).collect();
        port.send(name, &request).await?;
        let deadline = Instant::now() + timeout;
        counts[k] = 'answer: loop {
            let incoming = tokio::time::timeout_at(deadline, port.read(name))
                .await
                .map_err(|_| failed(format!("no answer within {timeout:?}")))??;
            for item in incoming {
                let Incoming::Frame(frame) = item else {
                    continue;
                };
                match sdo.receive(&frame) {
                    Some(Ok(SdoDone::Uploaded { data, .. })) if data.len() == 4 => {
                        break 'answer i64::from(i32::from_le_bytes([
                            data[0], data[1], data[2], data[3],
                        ]));
                    }
                    Some(Ok(other)) => return Err(failed(format!("unexpected answer {other:?}"))),
                    Some(Err(error)) => return Err(failed(error.to_string())),
                    None => {}
                }
            }
        };
    }
    Ok(counts)
}

/// The session's time; see the module docs.
struct Clock {
    kind: CanClock,
    started: Instant,
    /// Once locked to the cycle: the session's time now.
    locked: Option<Duration>,
    /// A SYNC-locked clock's time scale ([`CanOptions::pace`]).
    pace: Option<f64>,
    /// The wall instant and the session's time of the first locked cycle: the pace's
    /// origin.
    paced_from: Option<(Instant, Duration)>,
}

impl Clock {
    fn now(&self) -> Duration {
        self.locked.unwrap_or_else(|| self.started.elapsed())
    }

    /// A SYNC went out at `now`: with a SYNC-locked clock, the next step is a period on.
    /// Gives the wall instant before which that step must not begin, if the clock is paced
    /// ([`CanOptions::pace`]): the session's time since the first locked cycle over the
    /// scale, from the instant that cycle began (so that a cycle late on a busy host is
    /// made up, not carried).
    fn cycle(&mut self, now: Duration, period: Duration, wall: Instant) -> Option<Instant> {
        if self.kind != CanClock::SyncLocked {
            return None;
        }
        let next = now + period;
        self.locked = Some(next);
        let scale = self.pace?;
        let (origin, from) = *self.paced_from.get_or_insert((wall, now));
        Some(origin + (next - from).div_f64(scale))
    }
}

/// Runs `program` on the drives behind `link`; see the module docs.
pub async fn stream_can(
    link: &CanLink,
    program: &Program,
    mut options: CanOptions,
    log: &mut ExecLog,
) -> Result<CanOutcome, CanError> {
    if options.clock == CanClock::SyncLocked && !matches!(link, CanLink::Slcan { .. }) {
        return Err(CanError::Lockstep(link.to_string()));
    }
    if let Some(scale) = options.pace.filter(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(CanError::Pace(scale));
    }
    let name = link.to_string();
    let mut port = Port::open(link, options.answer_timeout).await?;
    let nodes = options.session.nodes;
    let counts = positions(&mut port, &name, nodes, options.answer_timeout).await?;
    let scale = options.sample.counts_per_unit;
    let start: [f64; 3] = std::array::from_fn(|k| counts[k] as f64 / scale[k]);
    let setpoints: SetPoints = sample(
        program,
        Position::known(start[0], start[1], start[2]),
        &options.sample,
    )
    .map_err(CanError::Sample)?;
    let period = setpoints.period;
    let total = setpoints.points.len();
    let mut session = Session::new(options.session.clone(), setpoints)?;
    log.write(
        0.0,
        log::Event::Start {
            program: options.program.clone(),
            lines: total,
            transport: link.transport().to_owned(),
        },
    )?;
    let [x, z, c] = nodes;
    log.write(
        0.0,
        log::Event::Message {
            text: format!(
                "{name}: drives X, Z, C on nodes {x}, {z}, {c} in {}, a {period:?} cycle, \
                 from X {:.4} Z {:.4} C {:.4}",
                options.session.operation, start[0], start[1], start[2]
            ),
        },
    )?;
    let mut run = Run {
        clock: Clock {
            kind: options.clock,
            started: Instant::now(),
            locked: None,
            pace: options.pace,
            paced_from: None,
        },
        outcome: CanOutcome {
            completed: false,
            stop: None,
            unconfirmed: Vec::new(),
            resume_move: None,
            resume_line: None,
            sent: 0,
            setpoints: total,
            late_cycles: 0,
            start,
            bytes_written: 0,
            bus_bits: 0,
            session_time: Duration::ZERO,
        },
        commands: 0,
        acks: 0,
        in_flight: VecDeque::new(),
        log_failed: None,
        caller: options.commands.take(),
        progress: Told {
            started: Instant::now(),
            report: options.on_progress.take(),
            last: None,
            period,
        },
    };
    let result = run
        .drive(&mut port, &name, &mut session, period, &options, log)
        .await;
    let result = match (result, run.log_failed.take()) {
        (Ok(()), Some(error)) => Err(CanError::Log(error)),
        (result, _) => result,
    };
    let reason = match &result {
        Ok(()) => run.outcome.stop.as_ref().map(ToString::to_string),
        Err(error) => Some(error.to_string()),
    };
    run.outcome.completed = result.is_ok() && session.phase() == Phase::Finished;
    run.outcome.sent = session.progress().0;
    run.progress.tell(session.progress(), run.clock.now());
    run.outcome.session_time = run.clock.now();
    let resume_move = session.resume_move();
    if !run.outcome.completed {
        run.outcome.resume_move = Some(resume_move);
    }
    // After a failed write the End may not land either; the failure is what the caller
    // hears. Where to resume goes first, as the serial transport logs it
    // (docs/streaming.md, the log's events).
    if let (false, Some(lines)) = (run.outcome.completed, &options.lines) {
        let line = lines.line_of(resume_move);
        run.outcome.resume_line = Some(line);
        let _ = log.write(
            run.clock.started.elapsed().as_secs_f64(),
            log::Event::ResumeAt {
                line: line + 1,
                possibly_run_to: None,
            },
        );
    }
    let ended = log.write(
        run.clock.started.elapsed().as_secs_f64(),
        log::Event::End {
            completed: run.outcome.completed,
            reason,
        },
    );
    match result {
        Ok(()) => ended.map(|()| run.outcome).map_err(CanError::from),
        Err(error) => Err(CanError::Interrupted {
            error: Box::new(error),
            resume_move,
        }),
    }
}

/// A run in progress.
struct Run {
    clock: Clock,
    outcome: CanOutcome,
    /// slcan commands sent, and acknowledged.
    commands: u64,
    acks: u64,
    /// With a SYNC-locked clock, for each cycle sent and not yet acknowledged: the
    /// commands sent up to its SYNC.
    in_flight: VecDeque<u64>,
    progress: Told,
    /// The first write to the log that failed: the drives are stopped, and the run ends
    /// with it.
    log_failed: Option<LogError>,
    /// The caller's hold, resume, stop and abort.
    caller: Option<Commands>,
}

/// How often the caller's progress display is told, in the session's time.
const PROGRESS_EVERY: Duration = Duration::from_secs(1);

/// The caller's progress display, told every [`PROGRESS_EVERY`] of the session's time: by
/// its time, not by the set-points sent, so that a held run, whose set-points stand, is told
/// too (a console reads the run's log, where the hold's words are, when it is told).
struct Told {
    report: Option<ProgressFn>,
    /// The session's time when it was last told.
    last: Option<Duration>,
    period: Duration,
    started: Instant,
}

impl Told {
    /// Tells the display at the session's time `now`, (sent, total) as
    /// [`Session::progress`] gives them.
    fn tell(&mut self, (sent, total): (usize, usize), now: Duration) {
        if let Some(report) = self.report.as_mut() {
            self.last = Some(now);
            report(&Progress {
                unit: Unit::SetPoints,
                done: sent,
                total,
                line: None,
                elapsed: self.started.elapsed(),
                left: Some(self.period * (total - sent) as u32),
                state: None,
                position: None,
                finishing: sent == total,
            });
        }
    }

    /// Tells it if [`PROGRESS_EVERY`] of the session's time has passed since it was last
    /// told (or it never was).
    fn step(&mut self, progress: (usize, usize), now: Duration) {
        if self.last.is_none_or(|last| now >= last + PROGRESS_EVERY) {
            self.tell(progress, now);
        }
    }
}

/// Cycles a SYNC-locked run may have in flight: sent, not yet acknowledged. The adapter and
/// the simulator take them in order, so a few in flight keep both busy instead of waiting
/// on each other's every turn; the drives' answers reach the session up to this many
/// cycles late (32 ms at 4 ms), well within heartbeat supervision's margin over the
/// heartbeat (100 ms at the defaults).
const LOCKSTEP_WINDOW: usize = 8;

impl Run {
    async fn drive(
        &mut self,
        port: &mut Port,
        name: &str,
        session: &mut Session,
        period: Duration,
        options: &CanOptions,
        log: &mut ExecLog,
    ) -> Result<(), CanError> {
        let slcan = matches!(port, Port::Slcan { .. });
        let mut tick = tokio::time::interval(Duration::from_millis(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        loop {
            let now = self.clock.now();
            self.obey(session, now, log);
            if let Some(error) = &self.log_failed {
                // The log is gone: the drives are brought to a stand and disabled before
                // the run ends with it (once: the session keeps the first stop).
                let why = format!("the log cannot be written ({error})");
                session.stop_held(StopReason::Interrupted { why }, now);
            }
            let frames = session.poll(now);
            if !frames.is_empty() {
                self.outcome.bytes_written += port.send(name, &frames).await?;
                self.outcome.bus_bits += frames.iter().map(|f| u64::from(f.bits())).sum::<u64>();
                if slcan {
                    self.commands += frames.len() as u64;
                }
            }
            let synced = frames.iter().any(is_sync);
            self.report(session, log);
            self.progress.step(session.progress(), now);
            if matches!(session.phase(), Phase::Finished | Phase::Stopped) {
                return Ok(());
            }
            if synced && self.clock.kind == CanClock::SyncLocked {
                // Lockstep: the next cycle is a period on, once no more than the window
                // of cycles is unacknowledged (the drives' answers come with the
                // acknowledgements).
                self.in_flight.push_back(self.commands);
                self.settle(port, name, session, now, options.answer_timeout)
                    .await?;
                if let Some(due) = self.clock.cycle(now, period, Instant::now()) {
                    tokio::time::sleep_until(due).await;
                }
                continue;
            }
            // What the port holds first: after the host kept this task waiting, the
            // answers and heartbeats that came meanwhile are taken before the time that
            // passed is told to the session, which would otherwise time them out.
            tokio::select! {
                biased;
                incoming = port.read(name) => {
                    let incoming = incoming?;
                    let now = self.clock.now();
                    self.take(incoming, session, now)?;
                }
                _ = tick.tick() => self.catch_up(port, name, session).await?,
            }
        }
    }

    /// Woken by time alone, and before that time is told to the session: the rest of the
    /// host gets a turn (the I/O driver, and drives simulated in this process, which a
    /// stalled host stopped as it stopped this task), then what the port holds by then is
    /// taken. A host that stood still for a boot-up's or an SDO answer's wait would
    /// otherwise time out a drive whose answer came in that very stall.
    async fn catch_up(
        &mut self,
        port: &mut Port,
        name: &str,
        session: &mut Session,
    ) -> Result<(), CanError> {
        tokio::task::yield_now().await;
        while let Some(incoming) = port.read(name).now_or_never() {
            let now = self.clock.now();
            self.take(incoming?, session, now)?;
        }
        Ok(())
    }

    /// Writes `event` to the log unless a write has failed (the first failure is kept).
    fn write(&mut self, log: &mut ExecLog, event: log::Event) {
        if self.log_failed.is_none() {
            let t = self.clock.started.elapsed().as_secs_f64();
            if let Err(error) = log.write(t, event) {
                self.log_failed = Some(error);
            }
        }
    }

    /// The caller's commands that have come: a hold slows the set-points along the path
    /// to a stand, a resume brings them back up to speed, a stop holds then disables the
    /// drives, an abort is a quick stop.
    fn obey(&mut self, session: &mut Session, now: Duration, log: &mut ExecLog) {
        while let Some(command) = self.caller.as_mut().and_then(Commands::try_next) {
            let text = match command {
                control::Command::Hold => {
                    session.hold();
                    "hold requested".to_owned()
                }
                control::Command::Resume => {
                    session.resume();
                    "resume requested".to_owned()
                }
                control::Command::Stop { reason } => {
                    let why = reason.to_owned();
                    session.stop_held(StopReason::Interrupted { why }, now);
                    format!(
                        "stop requested ({reason}): the path held to a stand, then the drives \
                         disabled"
                    )
                }
                control::Command::Abort => {
                    session.stop(now);
                    "abort requested: quick stop".to_owned()
                }
            };
            self.write(log, log::Event::Message { text });
        }
        if let Some(percent) = self.caller.as_mut().and_then(Commands::try_feed_override) {
            session.feed_override(percent);
            let event = log::Event::FeedOverride {
                percent,
                state: log::FeedOverrideState::Asked,
            };
            self.write(log, event);
        }
    }

    /// Reads until at most [`LOCKSTEP_WINDOW`] cycles are unacknowledged.
    async fn settle(
        &mut self,
        port: &mut Port,
        name: &str,
        session: &mut Session,
        now: Duration,
        timeout: Duration,
    ) -> Result<(), CanError> {
        let deadline = Instant::now() + timeout;
        loop {
            while self.in_flight.front().is_some_and(|&c| self.acks >= c) {
                self.in_flight.pop_front();
            }
            if self.in_flight.len() <= LOCKSTEP_WINDOW {
                return Ok(());
            }
            let incoming = tokio::time::timeout_at(deadline, port.read(name))
                .await
                .map_err(|_| CanError::Silent {
                    what: format!("{name}, acknowledging a cycle's frames"),
                    waited: timeout,
                })??;
            self.take(incoming, session, now)?;
        }
    }

    fn take(
        &mut self,
        incoming: Vec<Incoming>,
        session: &mut Session,
        now: Duration,
    ) -> Result<(), CanError> {
        for item in incoming {
            match item {
                Incoming::Frame(frame) => {
                    self.outcome.bus_bits += u64::from(frame.bits());
                    session.receive(&frame, now);
                }
                Incoming::Ack => self.acks += 1,
                Incoming::Refused => {
                    return Err(CanError::Refused {
                        command: "a frame (its transmit buffer is full or the bus is off)".into(),
                    })
                }
            }
        }
        Ok(())
    }

    /// The session's events to the log and the outcome.
    fn report(&mut self, session: &mut Session, log: &mut ExecLog) {
        for event in session.events() {
            match &event {
                Event::Late { .. } => {
                    self.outcome.late_cycles += 1;
                    // The first tells; the count is in the outcome.
                    if self.outcome.late_cycles > 1 {
                        continue;
                    }
                }
                Event::Stopped { reason } => {
                    self.outcome.stop.get_or_insert_with(|| reason.clone());
                }
                Event::Halted { unconfirmed } => self.outcome.unconfirmed = unconfirmed.clone(),
                Event::FeedOverride { percent } => {
                    let event = log::Event::FeedOverride {
                        percent: *percent,
                        state: log::FeedOverrideState::Running,
                    };
                    self.write(log, event);
                }
                _ => {}
            }
            let text = event.to_string();
            self.write(log, log::Event::Message { text });
        }
    }
}

fn is_sync(frame: &CanFrame) -> bool {
    frame.id() == CanId::Standard(0x080) && !frame.is_remote()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::machine::MachineProfile;
    use std::sync::{Arc, Mutex};

    /// What a display was told, (done, total) each time.
    type Heard = Arc<Mutex<Vec<(usize, usize)>>>;

    /// A display that keeps what it is told.
    fn display() -> (ProgressFn, Heard) {
        let told = Arc::new(Mutex::new(Vec::new()));
        let keep = Arc::clone(&told);
        let report: ProgressFn = Box::new(move |p: &Progress| {
            keep.lock().unwrap().push((p.done, p.total));
        });
        (report, told)
    }

    #[test]
    fn a_held_run_is_told_once_a_second_of_session_time_though_its_set_points_stand() {
        let (report, told) = display();
        let mut progress = Told {
            report: Some(report),
            last: None,
            period: Duration::from_millis(4),
            started: Instant::now(),
        };
        let s = Duration::from_secs_f64;
        // The first step tells where the run starts.
        progress.step((0, 1000), s(0.0));
        // 250 set-points in a second at 4 ms; none told within the second.
        progress.step((125, 1000), s(0.5));
        progress.step((250, 1000), s(1.0));
        // Held: the set-points stand, the session's time runs on.
        progress.step((250, 1000), s(1.5));
        progress.step((250, 1000), s(2.0));
        progress.step((250, 1000), s(3.0));
        assert_eq!(
            *told.lock().unwrap(),
            [(0, 1000), (250, 1000), (250, 1000), (250, 1000)]
        );
    }

    #[test]
    fn a_paced_clock_begins_each_cycle_at_its_session_time_over_the_scale() {
        let period = Duration::from_millis(4);
        let clock = |kind, pace| Clock {
            kind,
            started: Instant::now(),
            locked: None,
            pace,
            paced_from: None,
        };
        let wall = Instant::now();
        // The cycle starts after 2 s of boot on the wall: at 50 times real time a 4 ms
        // cycle lasts 80 µs of wall time, counted from the first cycle's start.
        let boot = Duration::from_secs(2);
        let mut paced = clock(CanClock::SyncLocked, Some(50.0));
        let first = paced.cycle(boot, period, wall);
        assert_eq!(first, Some(wall + Duration::from_micros(80)));
        assert_eq!(paced.now(), boot + period);
        // A cycle begun late (the host busy) is due where the pace puts it, not later.
        let late = wall + Duration::from_millis(10);
        let second = paced.cycle(paced.now(), period, late);
        assert_eq!(second, Some(wall + Duration::from_micros(160)));
        // Unpaced: the next cycle is a period on in the session's time, at once.
        let mut free = clock(CanClock::SyncLocked, None);
        assert_eq!(free.cycle(boot, period, wall), None);
        assert_eq!(free.now(), boot + period);
        // The wall clock is real time: neither locked nor paced.
        let mut real = clock(CanClock::Wall, Some(50.0));
        assert_eq!(real.cycle(boot, period, wall), None);
        assert_eq!(real.locked, None);
    }

    #[tokio::test]
    async fn a_pace_that_is_no_time_scale_is_refused_before_anything_is_opened() {
        let machine = MachineProfile::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/machine-profiles/canopen-drives.toml"
        )))
        .unwrap();
        let (drives, bitrate) = crate::transport::link::can_bus(&machine).unwrap();
        // Never opened: the pace is refused first.
        let link = CanLink::Slcan {
            path: "no-adapter-here".into(),
            baud: 115_200,
            bitrate,
        };
        for pace in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let options = CanOptions {
                session: SessionConfig::for_drives(&drives).unwrap(),
                sample: SampleConfig::for_drives(&machine, &drives),
                clock: CanClock::SyncLocked,
                pace: Some(pace),
                answer_timeout: Duration::from_secs(1),
                program: "p".into(),
                on_progress: None,
                commands: None,
                lines: None,
            };
            let error = stream_can(
                &link,
                &Program { moves: Vec::new() },
                options,
                &mut ExecLog::discard(),
            )
            .await
            .unwrap_err();
            assert!(matches!(error, CanError::Pace(_)), "{pace}: {error}");
            assert!(error.to_string().contains("finite and above zero"));
        }
    }
}
