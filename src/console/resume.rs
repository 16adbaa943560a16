//! A stopped dry run resumed on the simulator, as `whirl stream --resume-at` resumes a
//! machine: the simulated controller powers up where the stopped run left the machine,
//! and the library's run ([`crate::transport::stream`]) re-enters along the groove at the
//! resume line (X clear, C and Z to the line's start on the helix, the spindle on, a plunge
//! in X, the program's modes restored) and streams the rest over a pseudo-terminal.
//!
//! The simulator here has no Δ guard: a guard judges a whole program, and this is the rest
//! of one. The console measures the cut of the stopped run and the resume together
//! ([`super::groove::measure`]).

use crate::config::machine::MachineProfile;
use crate::judge::simulator;
use crate::log::{self, ExecLog};
use crate::transport::{self, Commands, Link, Outcome, Posted, ProgressFn, RunOptions};
use std::time::{Duration, Instant};
use tokio_serial::SerialPort;
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions, Event, MoveKind, Position};

/// Why a resume could not be carried out (a resume that stops again is an [`Outcome`]).
#[derive(Debug, thiserror::Error)]
pub enum ResumeError {
    /// The simulated controller cannot be built for the machine.
    #[error("the simulated controller: {0}")]
    Controller(whirl_sim::ConfigError),
    /// No pseudo-terminal, or the simulator stopped serving.
    #[error("the simulator: {0}")]
    Simulator(std::io::Error),
    /// The run.
    #[error(transparent)]
    Stream(#[from] transport::StreamError),
}

/// How the resume runs.
pub struct ResumeOptions {
    /// The program line (0-based) to resume at.
    pub line: usize,
    /// Where the stopped run left the machine: X, Z (mm), C (degrees).
    pub start: [f64; 3],
    /// Simulated seconds per wall second.
    pub time_scale: f64,
    /// The link's baud rate, emulated.
    pub baud: u32,
    /// Told how far the run is.
    pub progress: Option<ProgressFn>,
}

/// Resumes `posted` on `machine`'s simulated controller over a serial line; every move
/// the simulator executes is logged to `log` (the console's, in memory) beside the run's
/// own events.
pub async fn resume_serial(
    machine: &MachineProfile,
    posted: &Posted,
    options: ResumeOptions,
    commands: Commands,
    log: &mut ExecLog,
) -> Result<Outcome, ResumeError> {
    let mut controller = Controller::new(
        &simulator::machine(machine),
        ControllerOptions {
            start: Position::from_array(options.start),
            ..ControllerOptions::default()
        },
    )
    .map_err(ResumeError::Controller)?;
    controller.take_output();
    let (master, slave) = tokio_serial::SerialStream::pair().map_err(|e| {
        ResumeError::Simulator(std::io::Error::other(format!("no pseudo-terminal: {e}")))
    })?;
    let port = slave
        .name()
        .ok_or_else(|| ResumeError::Simulator(std::io::Error::other("the pty has no name")))?;
    let started = Instant::now();
    let mut sim_log = log.clone();
    let served = serve(
        master,
        &mut controller,
        ServeOptions {
            time_scale: Some(options.time_scale),
            baud: Some(options.baud),
            ..ServeOptions::default()
        },
        |event| {
            if let Event::Executed(block) = event {
                // The console's logs are in memory, which takes every event.
                let _ = sim_log.write(
                    started.elapsed().as_secs_f64(),
                    log::Event::Executed {
                        line: block.n.map(|n| n as usize),
                        times: [block.start_time, block.end_time],
                        from: block.from.to_array(),
                        to: block.to.to_array(),
                        rapid: block.kind == MoveKind::Rapid,
                    },
                );
            }
        },
    );
    let link = Link::Serial {
        port,
        baud: options.baud,
    };
    let run = RunOptions {
        stall_timeout: Some(Duration::from_secs(30)),
        resume_at: Some(options.line),
        unlock: false,
        progress: options.progress,
    };
    let streamed = transport::stream(&link, posted, machine, run, commands, log);
    tokio::pin!(served, streamed);
    let outcome = tokio::select! {
        outcome = &mut streamed => outcome.map_err(ResumeError::from),
        ended = &mut served => Err(ResumeError::Simulator(ended.err().unwrap_or_else(|| {
            std::io::Error::other("the simulator stopped serving")
        }))),
    };
    drop(slave);
    outcome
}
