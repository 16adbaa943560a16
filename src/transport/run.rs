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
use super::modbus::{stream_modbus, ModbusError, ModbusOptions, ModbusOutcome};
use super::progress::ProgressFn;
use super::serial::{stream_port, SerialError, StreamOptions, StreamOutcome};
use crate::config::connection::SettingError;
use crate::config::machine::MachineProfile;
use crate::log::ExecLog;
use crate::post::gcode::parse::{read_program_with_lines, ParseError};
use crate::post::modbus::{segments, SegmentError};
use crate::post::setpoints::SampleConfig;
use crate::program::limits::{check_limits, LimitError};
use crate::program::Program;
use crate::protocol::canopen::session::SessionConfig;

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
    /// On a serial line, hold and stop when the controller says nothing new for this long;
    /// `None` waits.
    pub stall_timeout: Option<Duration>,
    /// On a serial line, resume the program at this line (0-based) behind a preamble that
    /// restores its modes.
    pub resume_at: Option<usize>,
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
}

impl Outcome {
    /// Every move executed: the run is over and the machine at the program's end.
    pub fn completed(&self) -> bool {
        match self {
            Outcome::Serial(o) => o.completed(),
            Outcome::Modbus(o) => o.completed,
            Outcome::Can(o) => o.completed,
        }
    }

    /// Why the run did not complete, in words; `None` if it did. Where to resume a
    /// serial run is its [`StreamOutcome::resume`].
    pub fn stop(&self) -> Option<String> {
        match self {
            _ if self.completed() => None,
            Outcome::Serial(o) => Some(format!("the stream {}", o.ending)),
            Outcome::Modbus(o) => Some(match (o.alarm, &o.failure) {
                (Some(alarm), _) => format!("the controller stopped the stream: {alarm}"),
                (None, Some(failure)) => format!("the stream failed: {failure}"),
                (None, None) if o.aborted => {
                    "the stream was aborted: the controller stopped and flushed its ring".into()
                }
                (None, None) => "the stream ended before the controller read done".into(),
            }),
            Outcome::Can(o) => Some(match &o.stop {
                Some(reason) => format!("the drives stopped the job: {reason}"),
                None => "the job ended before the drives settled".into(),
            }),
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
    let name = posted.name.clone();
    Ok(match link {
        Link::Serial { port, baud } => {
            let options = StreamOptions {
                program: name,
                no_progress_timeout: options.stall_timeout,
                resume_at: options.resume_at,
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
            let options = ModbusOptions {
                program: name,
                unit: *unit,
                timeout: *timeout,
                on_progress: options.progress,
                commands: Some(commands),
                ..ModbusOptions::default()
            };
            let segments = segments(&posted.program)?;
            Outcome::Modbus(stream_modbus(link, segments, options, log).await?)
        }
        Link::Can { link, drives } => {
            let options = CanOptions {
                session: SessionConfig {
                    hold_ramp: machine.stop_time(),
                    ..SessionConfig::for_drives(drives)?
                },
                sample: SampleConfig::for_drives(machine, drives),
                clock: CanClock::Wall,
                answer_timeout: Duration::from_secs(1),
                program: name,
                on_progress: options.progress,
                commands: Some(commands),
            };
            Outcome::Can(stream_can(link, &posted.program, options, log).await?)
        }
    })
}
