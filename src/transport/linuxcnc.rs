//! A program run on LinuxCNC through `linuxcncrsh` ([`crate::protocol::linuxcnc`]): the
//! file written where LinuxCNC can open it, one TCP session, the clock, the log.
//!
//! LinuxCNC runs the program itself, so there is nothing to stream: the bridge writes the
//! posted text to a new file in the profile's `program_dir`, has LinuxCNC open and run it,
//! and polls it until it stops. Every poll is logged (`status`, with LinuxCNC's line), so
//! the log says where the machine went and when; LinuxCNC's errors are logged in its words.
//!
//! The link matters less than on a serial line: LinuxCNC has the whole program, so a lost
//! session does not starve the machine. It does take the bridge's hold away: the run ends
//! in an error that says so, and the operator holds or stops the machine at LinuxCNC's own
//! console. A stop of the bridge (Ctrl-C, a signal) holds the machine (`set pause`) first,
//! and leaves the program open and held in LinuxCNC: it is resumed (or aborted) there,
//! where LinuxCNC still has its place in the program, so `--resume-at` is not needed and
//! not taken (see [`crate::transport::StreamError::ResumeOnLinuxcnc`]).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use thiserror::Error;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use super::control::{Command, Commands};
use super::progress::{Progress, ProgressFn, Unit};
use crate::config::connection::LinuxcncSettings;
use crate::log::{Event, ExecLog, LogError};
use crate::protocol::linuxcnc::{self, Ending, Session, SessionConfig, Status};

/// How a LinuxCNC run goes.
pub struct LinuxcncOptions {
    /// The program's name, for the log.
    pub program: String,
    /// Where the program ends: X (radius), Z, C. See [`SessionConfig::end_position`].
    pub end_position: Option<[f64; 3]>,
    /// Time between status polls.
    pub poll_interval: Duration,
    /// Hold and stop when LinuxCNC's line and position stay the same this long while it
    /// runs (not while held); `None` waits.
    pub stall_timeout: Option<Duration>,
    /// Told how far the run is.
    pub on_progress: Option<ProgressFn>,
    /// The caller's hold, resume, stop and abort.
    pub commands: Option<Commands>,
}

impl Default for LinuxcncOptions {
    fn default() -> Self {
        LinuxcncOptions {
            program: "program".into(),
            end_position: None,
            poll_interval: Duration::from_millis(100),
            stall_timeout: None,
            on_progress: None,
            commands: None,
        }
    }
}

/// What a LinuxCNC run did.
#[derive(Debug, Clone, PartialEq)]
pub struct LinuxcncOutcome {
    /// How it ended.
    pub ending: Ending,
    /// Program lines.
    pub lines_total: usize,
    /// The furthest line LinuxCNC reported executing (1-based).
    pub furthest_line: u64,
    /// Status polls.
    pub polls: usize,
    /// Errors LinuxCNC reported, in its words.
    pub errors: Vec<String>,
    /// The file LinuxCNC ran.
    pub file: PathBuf,
    /// From the connection to the end.
    pub wall_time: Duration,
}

impl LinuxcncOutcome {
    /// LinuxCNC ran the program to its end.
    pub fn completed(&self) -> bool {
        self.ending == Ending::Completed
    }

    /// Why the run did not complete, in words.
    pub fn stop(&self) -> Option<String> {
        Some(match &self.ending {
            Ending::Completed => return None,
            Ending::Refused(why) => format!("nothing ran: {why}"),
            Ending::Failed { error, line } => {
                format!("LinuxCNC stopped the program at line {line}: {error}")
            }
            Ending::Aborted { reason, line } => {
                format!("the program stopped at line {line}: {reason}")
            }
            Ending::Held { reason, line } => format!(
                "{reason}: LinuxCNC holds the machine at line {line} with the program open \
                 (resume or abort it at LinuxCNC's console)"
            ),
            Ending::Silent { request, line } => format!(
                "linuxcncrsh stopped answering (`{request}`) at line {line}; LinuxCNC may still \
                 be running the program: hold or stop it at its console"
            ),
        })
    }
}

/// Why a LinuxCNC run failed before or outside LinuxCNC's own say.
#[derive(Debug, Error)]
pub enum LinuxcncError {
    /// The program file could not be written.
    #[error("cannot write the program for LinuxCNC to {path}: {error}")]
    Program {
        /// Where.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// No session with `linuxcncrsh`.
    #[error("cannot connect to linuxcncrsh at {address}: {error}")]
    Connect {
        /// Where.
        address: String,
        /// Why.
        error: std::io::Error,
    },
    /// The session broke.
    #[error(
        "the session with linuxcncrsh broke at line {line}: {error}; LinuxCNC may still be \
         running the program: hold or stop it at its console"
    )]
    Link {
        /// The line last reported.
        line: u64,
        /// Why.
        error: std::io::Error,
    },
    /// The executed-path log.
    #[error(transparent)]
    Log(#[from] LogError),
}

/// A new file in `dir` for `lines`, never one that exists: `whirl-<pid>-<n>.ngc`.
fn write_program(dir: &Path, lines: &[String]) -> Result<PathBuf, LinuxcncError> {
    let pid = std::process::id();
    let mut n = 0u32;
    loop {
        let path = dir.join(format!("whirl-{pid}-{n}.ngc"));
        let created = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path);
        match created {
            Ok(mut file) => {
                let mut text = lines.join("\n");
                text.push('\n');
                file.write_all(text.as_bytes())
                    .and_then(|()| file.sync_all())
                    .map_err(|error| LinuxcncError::Program {
                        path: path.clone(),
                        error,
                    })?;
                return Ok(path);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 10_000 => n += 1,
            Err(error) => return Err(LinuxcncError::Program { path, error }),
        }
    }
}

/// Runs `lines` on the LinuxCNC at `settings.address`; see the module docs.
pub async fn run_linuxcnc(
    settings: &LinuxcncSettings,
    lines: &[String],
    options: LinuxcncOptions,
    log: &mut ExecLog,
) -> Result<LinuxcncOutcome, LinuxcncError> {
    run_linuxcnc_unended(settings, lines, options, log)
        .await?
        .end(log)
}

/// As [`run_linuxcnc`], but the run's End is left to the caller, who may log more of the
/// run first: a dry run's sampler reports the path a servo period behind LinuxCNC's last
/// status, and its last stretches belong before the End. An error here leaves no run
/// open: it came before the run's Start, or the log itself failed.
pub async fn run_linuxcnc_unended(
    settings: &LinuxcncSettings,
    lines: &[String],
    options: LinuxcncOptions,
    log: &mut ExecLog,
) -> Result<Unended, LinuxcncError> {
    let dir = settings
        .program_dir
        .as_ref()
        .map_or_else(std::env::temp_dir, PathBuf::from);
    let file = write_program(&dir, lines)?;
    let unended = session(settings, lines.len(), &file, options, log).await?;
    // LinuxCNC has read what it ran (it reads ahead, and holds the file open while it
    // runs); the copy is the bridge's own and goes once the run is over.
    if unended.completed() {
        let _ = std::fs::remove_file(&file);
    }
    Ok(unended)
}

/// A LinuxCNC run that is over, its Start logged and its End not yet.
#[must_use = "a run's End is logged by `end`"]
pub struct Unended {
    started: Instant,
    result: Result<LinuxcncOutcome, LinuxcncError>,
}

impl Unended {
    /// Whether LinuxCNC ran the program to its end.
    pub fn completed(&self) -> bool {
        self.result.as_ref().is_ok_and(LinuxcncOutcome::completed)
    }

    /// Logs the run's End and gives its outcome.
    pub fn end(self, log: &mut ExecLog) -> Result<LinuxcncOutcome, LinuxcncError> {
        let (completed, reason) = match &self.result {
            Ok(outcome) => (outcome.completed(), outcome.stop()),
            Err(error) => (false, Some(error.to_string())),
        };
        log.write(
            self.started.elapsed().as_secs_f64(),
            Event::End { completed, reason },
        )?;
        self.result
    }
}

async fn session(
    settings: &LinuxcncSettings,
    lines_total: usize,
    file: &Path,
    mut options: LinuxcncOptions,
    log: &mut ExecLog,
) -> Result<Unended, LinuxcncError> {
    let started = Instant::now();
    let timeout = settings.timeout();
    let mut socket = tokio::time::timeout(timeout, TcpStream::connect(&settings.address))
        .await
        .unwrap_or_else(|_| Err(std::io::Error::from(std::io::ErrorKind::TimedOut)))
        .map_err(|error| LinuxcncError::Connect {
            address: settings.address.clone(),
            error,
        })?;
    let mut session = Session::new(SessionConfig {
        connect_password: settings.connect_password.clone(),
        enable_password: settings.enable_password.clone(),
        power_on: settings.power_on,
        program: file.display().to_string(),
        poll_interval: options.poll_interval,
        answer_timeout: timeout,
        end_position: options.end_position,
    });
    let t = |started: Instant| started.elapsed().as_secs_f64();
    log.write(
        t(started),
        Event::Start {
            program: options.program.clone(),
            lines: lines_total,
            transport: "linuxcnc".into(),
        },
    )?;
    let mut outcome = LinuxcncOutcome {
        ending: Ending::Completed,
        lines_total,
        furthest_line: 0,
        polls: 0,
        errors: Vec::new(),
        file: file.to_owned(),
        wall_time: Duration::ZERO,
    };
    let mut buf = [0u8; 4096];
    let mut commands = options.commands.take();
    let mut last_change: Option<(Status, Instant)> = None;
    let mut held = false;
    let result = loop {
        let now = started.elapsed();
        session.poll(now);
        if let Some(bytes) = session.transmit(now) {
            if let Err(error) = socket.write_all(&bytes).await {
                break Err(LinuxcncError::Link {
                    line: session.last_status().line,
                    error,
                });
            }
        }
        while let Some(event) = session.next_event() {
            match event {
                linuxcnc::Event::Running => log.write(
                    t(started),
                    Event::Message {
                        text: format!("LinuxCNC runs {}", file.display()),
                    },
                )?,
                linuxcnc::Event::Status(status) => {
                    outcome.polls += 1;
                    outcome.furthest_line = outcome.furthest_line.max(status.line);
                    log.write(
                        t(started),
                        Event::Status {
                            state: status.state.name().into(),
                            pos: status.position,
                            blocks_free: None,
                            rx_free: None,
                            line: Some(status.line),
                        },
                    )?;
                    if let Some(report) = options.on_progress.as_mut() {
                        report(&Progress {
                            unit: Unit::Lines,
                            done: status.line as usize,
                            total: lines_total,
                            line: Some((status.line as usize).saturating_sub(1)),
                            elapsed: started.elapsed(),
                            left: None,
                            state: Some(status.state.name().into()),
                            position: Some(status.position),
                            finishing: false,
                        });
                    }
                    held = status.state == linuxcnc::ProgramState::Paused;
                    let moved = last_change.is_none_or(|(last, _)| {
                        last.line != status.line || last.position != status.position
                    });
                    if moved || held {
                        last_change = Some((status, Instant::now()));
                    }
                }
                linuxcnc::Event::Error(text) => {
                    log.write(
                        t(started),
                        Event::Message {
                            text: format!("LinuxCNC: {text}"),
                        },
                    )?;
                    outcome.errors.push(text);
                }
                linuxcnc::Event::Ended => {}
            }
        }
        if let Some(ending) = session.ending() {
            outcome.ending = ending.clone();
            break Ok(());
        }
        if let (Some(limit), Some((_, since))) = (options.stall_timeout, last_change) {
            if !held && since.elapsed() >= limit {
                session.command(linuxcnc::Command::Stop(format!(
                    "LinuxCNC made no progress for {:.0} s",
                    limit.as_secs_f64()
                )));
                last_change = None;
                continue;
            }
        }
        let wait = session.deadline().map_or(Duration::from_millis(100), |d| {
            d.saturating_sub(started.elapsed())
        });
        tokio::select! {
            read = socket.read(&mut buf) => match read {
                Ok(0) => break Err(LinuxcncError::Link {
                    line: session.last_status().line,
                    error: std::io::ErrorKind::UnexpectedEof.into(),
                }),
                Ok(n) => session.receive(&buf[..n]),
                Err(error) => break Err(LinuxcncError::Link {
                    line: session.last_status().line,
                    error,
                }),
            },
            command = next_command(&mut commands) => session.command(match command {
                Command::Hold => linuxcnc::Command::Hold,
                Command::Resume => linuxcnc::Command::Resume,
                Command::Abort => linuxcnc::Command::Abort,
                Command::Stop { reason } => linuxcnc::Command::Stop(reason.to_owned()),
            }),
            () = tokio::time::sleep(wait) => {}
        }
    };
    outcome.wall_time = started.elapsed();
    Ok(Unended {
        started,
        result: result.map(|()| outcome),
    })
}

/// The caller's next command; never, without a caller.
async fn next_command(commands: &mut Option<Commands>) -> Command {
    match commands {
        Some(commands) => commands.next().await,
        None => std::future::pending().await,
    }
}
