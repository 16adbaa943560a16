//! The run of a program, for every transport: a posted program streamed to the machine a
//! [`Link`] names, with the caller's hand on it ([`Commands`]) and its progress
//! ([`ProgressFn`]), every event in the executed-path log.
//!
//! Nothing is opened before the program has passed the machine's limits ([`Posted::check`]),
//! so a refused program leaves the machine untouched whatever the transport.

use std::time::Duration;

use thiserror::Error;

use super::can::{stream_can, CanClock, CanError, CanOptions, CanOutcome};
use super::control::Commands;
use super::link::Link;
use super::linuxcnc::{run_linuxcnc, LinuxcncError, LinuxcncOptions, LinuxcncOutcome};
use super::modbus::{stream_modbus, ModbusError, ModbusOptions, ModbusOutcome};
use super::progress::{MoveLines, ProgressFn};
use super::serial::{self, stream_port, SerialError, StreamOptions, StreamOutcome};
use crate::config::connection::SettingError;
use crate::config::machine::MachineProfile;
use crate::log::ExecLog;
use crate::post::gcode::parse::{read_program_with_lines, ParseError};
use crate::post::modbus::{segment_moves, segments, SegmentError};
use crate::post::setpoints::SampleConfig;
use crate::program::limits::{check_limits, LimitError};
use crate::program::reentry::{approach, ReentryError};
use crate::program::timing::move_seconds;
use crate::program::{Move, Program};
use crate::protocol::canopen::session::{SessionConfig, StopReason};
use crate::protocol::grbl::{ResumePoint, StreamerConfig};
use crate::protocol::modbus::WriterOptions;

/// A program as it goes to a machine: the G-code written for it, line by line (what a
/// grbl-family controller is sent), and the moves those lines say, each with its file
/// line (what a PLC or the drives are sent). Every transport so executes the same numbers,
/// the ones written.
#[derive(Debug, Clone, PartialEq)]
pub struct Posted {
    /// What the program is (its file, or the job it was planned from), for the log.
    pub name: String,
    /// The text's lines, without line ends.
    pub lines: Vec<String>,
    /// The moves the lines say.
    pub program: Program,
    /// The file line (1-based) of each move.
    pub move_lines: Vec<usize>,
}

impl Posted {
    /// Reads `text` (G-code written for `machine`, whose profile says how X is read) as the
    /// program called `name`.
    pub fn read(
        name: impl Into<String>,
        text: &str,
        machine: &MachineProfile,
    ) -> Result<Posted, ParseError> {
        let (program, move_lines) = read_program_with_lines(text, machine.x_diameter())?;
        Ok(Posted {
            name: name.into(),
            lines: text.lines().map(str::to_owned).collect(),
            program,
            move_lines,
        })
    }

    /// The first move said on `line` (0-based) or after it: where a resume at that line
    /// picks the program up.
    pub fn first_move_at(&self, line: usize) -> usize {
        self.move_lines.partition_point(|&l| l < line + 1)
    }

    /// Checks the program against `machine`'s travel, speeds and spindle, naming the file
    /// line of the first move that asks too much.
    pub fn check(&self, machine: &MachineProfile) -> Result<(), PreflightError> {
        check_limits(&self.program, machine).map_err(|error| PreflightError::Limits {
            line: self.move_lines[error.index()],
            error,
        })
    }
}

/// Why a program failed the check before streaming.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PreflightError {
    /// The program could not be read.
    #[error("the program cannot be read: {0}")]
    Parse(ParseError),
    /// The program asks more than the machine allows.
    #[error("line {line}: the program exceeds the machine's limits: {error}")]
    Limits {
        /// The program line (1-based) of the move that does.
        line: usize,
        /// What it asks.
        error: LimitError,
    },
}

/// Checks program text against a machine's travel and speed limits, as it will be
/// streamed: read as one program ([`Posted::read`]), then [`Posted::check`].
pub fn check_program(lines: &[String], machine: &MachineProfile) -> Result<(), PreflightError> {
    Posted::read("", &lines.join("\n"), machine)
        .map_err(PreflightError::Parse)?
        .check(machine)
}

/// How a stream runs, whatever the transport.
#[derive(Default)]
pub struct RunOptions {
    /// Hold and stop when the controller says nothing new for this long (a hold the
    /// controller or another client made counts; the caller's own does not); `None` waits.
    pub stall_timeout: Option<Duration>,
    /// Resume the program at this line (0-based): inside the cut, the ring re-enters along
    /// the groove first ([`crate::program::reentry`]); on a serial line a preamble restores
    /// the program's modes.
    pub resume_at: Option<usize>,
    /// A grbl-family controller found in alarm before the first line is unlocked (`$X`)
    /// instead of refused: the operator has checked the machine.
    pub unlock: bool,
    /// Told how far the run is, as it goes.
    pub progress: Option<ProgressFn>,
}

/// What a stream did, in its transport's terms.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A G-code program over a serial line.
    Serial(Box<StreamOutcome>),
    /// Segments through the Modbus register map.
    Modbus(ModbusOutcome),
    /// Set-points to CiA 402 drives.
    Can(CanOutcome),
    /// A program LinuxCNC ran.
    Linuxcnc(LinuxcncOutcome),
}

impl Outcome {
    /// Every move executed: the run is over and the machine at the program's end.
    pub fn completed(&self) -> bool {
        match self {
            Outcome::Serial(o) => o.completed(),
            Outcome::Modbus(o) => o.completed,
            Outcome::Can(o) => o.completed,
            Outcome::Linuxcnc(o) => o.completed(),
        }
    }

    /// Where to resume, if the run did not complete and that is known.
    pub fn resume(&self) -> Option<Resume> {
        match self {
            Outcome::Serial(o) => o.resume.as_ref().map(Resume::from),
            Outcome::Modbus(o) => o.resume_line.map(Resume::at),
            Outcome::Can(o) => o.resume_line.map(Resume::at),
            // LinuxCNC keeps its place in the program: a run is resumed at its console.
            Outcome::Linuxcnc(_) => None,
        }
    }

    /// Why the run did not complete, in words; `None` if it did; see [`Outcome::resume`]
    /// for where to go on.
    pub fn stop(&self) -> Option<String> {
        match self {
            _ if self.completed() => None,
            Outcome::Serial(o) => Some(format!("the stream {}", o.ending)),
            Outcome::Modbus(o) => Some(match (o.alarm, &o.failure, &o.stopped) {
                (Some(alarm), _, _) => format!("the controller stopped the stream: {alarm}"),
                (None, Some(failure), _) => format!("the stream failed: {failure}"),
                (None, None, Some(stopped)) => stopped.clone(),
                (None, None, None) if o.aborted => {
                    "the stream was aborted: the controller stopped and flushed its ring".into()
                }
                (None, None, None) => "the stream ended before the controller read done".into(),
            }),
            Outcome::Can(o) => Some(match &o.stop {
                // The bridge's own stops: the caller's, a stall.
                Some(reason @ (StopReason::Interrupted { .. } | StopReason::Stalled { .. })) => {
                    format!("the job stopped: {reason}")
                }
                Some(reason) => format!("the drives stopped the job: {reason}"),
                None => "the job ended before the drives settled".into(),
            }),
            Outcome::Linuxcnc(o) => o.stop(),
        }
    }

    /// One line on what the run did, for a terminal: `name` is the program's, `link`
    /// where it went.
    pub fn summary(&self, name: &str, link: &Link) -> String {
        match self {
            Outcome::Serial(o) => format!(
                "{name}: {} of {} lines acknowledged in {:.1} s{}",
                o.lines_acked,
                o.lines_total,
                o.wall_time.as_secs_f64(),
                o.link_utilization
                    .filter(|_| !link.is_pseudo_terminal())
                    .map_or(String::new(), |u| format!(", link {:.0} % busy", 100.0 * u))
            ),
            Outcome::Modbus(o) => format!(
                "{name}: {} of {} segments published over {link} in {:.1} s ({} timeouts, {} \
                 reconnects)",
                o.published,
                o.segments,
                o.wall_time.as_secs_f64(),
                o.timeouts,
                o.reconnects
            ),
            Outcome::Can(o) => format!(
                "{name}: {} of {} set-points over {link} in {:.1} s; {} late cycles",
                o.sent,
                o.setpoints,
                o.session_time.as_secs_f64(),
                o.late_cycles
            ),
            Outcome::Linuxcnc(o) => format!(
                "{name}: LinuxCNC ran to line {} of {} over {link} in {:.1} s ({} polls)",
                o.furthest_line,
                o.lines_total,
                o.wall_time.as_secs_f64(),
                o.polls
            ),
        }
    }
}

/// Where a run that did not complete goes on, whatever the transport: give `line` to
/// [`RunOptions::resume_at`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Resume {
    /// The first program line (0-based) not known to have executed.
    pub line: usize,
    /// Lines from `line` on that may have executed all the same (the resume re-enters along
    /// the groove, so cutting them again is harmless); empty when none did.
    pub possibly_executed: std::ops::Range<usize>,
}

impl Resume {
    /// At `line`, nothing after it run.
    fn at(line: usize) -> Resume {
        Resume {
            line,
            possibly_executed: line..line,
        }
    }
}

impl From<&ResumePoint> for Resume {
    fn from(point: &ResumePoint) -> Resume {
        Resume {
            line: point.line_index,
            possibly_executed: point.possibly_executed.clone(),
        }
    }
}

/// Why a stream failed. Stops the machine or the controller decides (an alarm, an error,
/// a reset, the caller's abort) are not failures: they end in an [`Outcome`].
#[derive(Debug, Error)]
pub enum StreamError {
    /// The program failed the machine check; nothing was opened.
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    /// A fieldbus transport failed once the run had begun; the controller's (or the
    /// drives') last report says where to resume.
    #[error("{error}")]
    Interrupted {
        /// What ended it.
        error: Box<StreamError>,
        /// Where to resume.
        resume: Resume,
    },
    /// The program cannot be re-entered at the resume line.
    #[error("cannot resume at line {}: {error}", .line + 1)]
    Reentry {
        /// The resume line (0-based).
        line: usize,
        /// Why.
        error: ReentryError,
    },
    /// The program cannot go through the Modbus register map.
    #[error(transparent)]
    Segments(#[from] SegmentError),
    /// The drives' settings make no CANopen session.
    #[error(transparent)]
    Settings(#[from] SettingError),
    /// The serial transport.
    #[error(transparent)]
    Serial(#[from] SerialError),
    /// The Modbus transport.
    #[error(transparent)]
    Modbus(#[from] ModbusError),
    /// The CAN transport.
    #[error(transparent)]
    Can(#[from] CanError),
    /// The LinuxCNC transport.
    #[error(transparent)]
    Linuxcnc(#[from] LinuxcncError),
    /// `--resume-at` on LinuxCNC, which resumes at its own console.
    #[error(
        "LinuxCNC resumes a held or stopped program itself (its run-from-line, at its \
         console), where it keeps its place; whirl does not re-enter a LinuxCNC run at line {}",
        .0 + 1
    )]
    ResumeOnLinuxcnc(usize),
}

impl StreamError {
    /// Where to resume after a failure mid-stream, if the controller's reports before it
    /// tell.
    pub fn resume(&self) -> Option<Resume> {
        match self {
            StreamError::Serial(error) => error.resume().map(Resume::from),
            StreamError::Interrupted { resume, .. } => Some(resume.clone()),
            _ => None,
        }
    }
}

/// What a fieldbus transport runs: the moves of a [`Posted`] program from where a run
/// picks it up, behind the approach that re-enters there, with each move's program line, so
/// that a move the run stops at can be told as a line to resume at.
pub(crate) struct Pickup {
    pub(crate) program: Program,
    /// How many of [`Pickup::program`]'s first moves are the approach.
    approach: usize,
    /// The program line of each move; the approach's is the resume line's.
    pub(crate) lines: MoveLines,
}

impl Pickup {
    /// Where a run resumed at `line` picks `posted` up: the re-entry there, then the rest.
    pub(crate) fn resuming(posted: &Posted, line: usize) -> Result<Pickup, StreamError> {
        let from = posted.first_move_at(line);
        let approach = approach(&posted.program, from)
            .map_err(|error| StreamError::Reentry { line, error })?;
        Ok(Pickup::new(posted, approach, from, Some(line)))
    }

    /// The whole of `posted` from its start, as a dry run sends it.
    pub(crate) fn whole(posted: &Posted) -> Pickup {
        Pickup::new(posted, Vec::new(), 0, None)
    }

    fn new(posted: &Posted, approach: Vec<Move>, from: usize, line: Option<usize>) -> Pickup {
        let lines = std::iter::repeat_n(line.unwrap_or(0), approach.len())
            .chain(posted.move_lines[from..].iter().map(|&l| l - 1))
            .collect();
        let approach_len = approach.len();
        let mut program = Program { moves: approach };
        program
            .moves
            .extend_from_slice(&posted.program.moves[from..]);
        Pickup {
            program,
            approach: approach_len,
            lines: MoveLines::new(lines, posted.lines.len()),
        }
    }

    /// The approach that re-enters where the run picks the program up (empty where the
    /// program's own moves lead there; [`crate::program::reentry::approach`]).
    pub(crate) fn approach(&self) -> &[Move] {
        &self.program.moves[..self.approach]
    }

    /// The program line of move `index` of [`Pickup::program`].
    pub(crate) fn line_of(&self, index: usize) -> usize {
        self.lines.line_of(index)
    }

    /// A transport's `error`, with where to resume if it failed mid-run at `resume_move`.
    pub(crate) fn interrupted(
        &self,
        resume_move: Option<usize>,
        error: impl Into<StreamError>,
    ) -> StreamError {
        match resume_move {
            Some(at) => StreamError::Interrupted {
                resume: Resume::at(self.line_of(at)),
                error: Box::new(error.into()),
            },
            None => error.into(),
        }
    }
}

/// Streams `posted` to the machine at `link`, which `machine` describes: checked against
/// its limits first, then run over the link's transport, the caller's `commands` obeyed,
/// every event logged to `log`.
pub async fn stream(
    link: &Link,
    posted: &Posted,
    machine: &MachineProfile,
    options: RunOptions,
    commands: Commands,
    log: &mut ExecLog,
) -> Result<Outcome, StreamError> {
    posted.check(machine)?;
    if let (Link::Linuxcnc(_), Some(line)) = (link, options.resume_at) {
        return Err(StreamError::ResumeOnLinuxcnc(line));
    }
    let name = posted.name.clone();
    let from = options.resume_at.map(|line| posted.first_move_at(line));
    let approach = match (options.resume_at, from) {
        (Some(line), Some(from)) => {
            approach(&posted.program, from).map_err(|error| StreamError::Reentry { line, error })?
        }
        _ => Vec::new(),
    };
    // Where the fieldbus transports pick the program up.
    let pickup = |approach| Pickup::new(posted, approach, from.unwrap_or(0), options.resume_at);
    async {
        Ok(match link {
            Link::Serial { port, baud } => {
                let streamer = StreamerConfig {
                    check_state: true,
                    unlock: options.unlock,
                    ..StreamerConfig::default()
                };
                // The watchdog allows a move its planned time: the approach's longest move
                // (a plunge at the plunge feed) or the preamble's spin-up dwell.
                let approach_seconds = move_seconds(
                    &Program {
                        moves: approach.clone(),
                    },
                    machine,
                )
                .into_iter()
                .map(|(_, seconds)| seconds)
                .fold(streamer.spin_up_dwell_s, f64::max);
                let options = StreamOptions {
                    program: name,
                    streamer,
                    line_durations: Some(serial::line_seconds(
                        posted.lines.len(),
                        &posted.program,
                        &posted.move_lines,
                        machine,
                    )),
                    approach_seconds,
                    no_progress_timeout: options.stall_timeout,
                    resume_at: options.resume_at,
                    approach,
                    x_diameter: machine.x_diameter(),
                    on_progress: options.progress,
                    commands: Some(commands),
                    ..StreamOptions::default()
                };
                let outcome = stream_port(port, *baud, posted.lines.clone(), options, log).await?;
                Outcome::Serial(Box::new(outcome))
            }
            Link::Modbus {
                link,
                unit,
                timeout,
            } => {
                let moves = pickup(approach);
                let options = ModbusOptions {
                    writer: WriterOptions {
                        // A stop waits for the stand as long as the machine takes to stop from
                        // full speed, and a margin for the status polls and the link.
                        stand_timeout: machine.stop_time() + Duration::from_secs(2),
                        ..WriterOptions::default()
                    },
                    stall_timeout: options.stall_timeout,
                    segment_moves: segment_moves(&moves.program),
                    lines: Some(moves.lines.clone()),
                    program: name,
                    unit: *unit,
                    timeout: *timeout,
                    on_progress: options.progress,
                    commands: Some(commands),
                    ..ModbusOptions::default()
                };
                let segments = segments(&moves.program)?;
                let outcome = stream_modbus(link, segments, options, log)
                    .await
                    .map_err(|error| moves.interrupted(error.resume_move(), error))?;
                Outcome::Modbus(outcome)
            }
            Link::Can { link, drives } => {
                let moves = pickup(approach);
                let options = CanOptions {
                    session: SessionConfig {
                        hold_ramp: machine.stop_time(),
                        stall_timeout: options.stall_timeout,
                        ..SessionConfig::for_drives(drives)?
                    },
                    sample: SampleConfig::for_drives(machine, drives),
                    clock: CanClock::Wall,
                    pace: None,
                    answer_timeout: Duration::from_secs(1),
                    program: name,
                    on_progress: options.progress,
                    commands: Some(commands),
                    lines: Some(moves.lines.clone()),
                };
                let outcome = stream_can(link, &moves.program, options, log)
                    .await
                    .map_err(|error| moves.interrupted(error.resume_move(), error))?;
                Outcome::Can(outcome)
            }
            Link::Linuxcnc(settings) => {
                let options = LinuxcncOptions {
                    program: name,
                    end_position: posted.program.end_position(),
                    stall_timeout: options.stall_timeout,
                    on_progress: options.progress,
                    commands: Some(commands),
                    ..LinuxcncOptions::default()
                };
                Outcome::Linuxcnc(run_linuxcnc(settings, &posted.lines, options, log).await?)
            }
        })
    }
    .await
}
