//! A stopped dry run resumed on the simulator, as `whirl stream --resume-at` resumes a
//! machine: the simulated controller (or drives) power up where the stopped run left the
//! machine, and the run re-enters along the groove at the resume line (X clear, C and Z to
//! the line's start on the helix, the spindle on, a plunge in X;
//! [`crate::program::reentry`]) and runs the rest, over the transport the stopped run used:
//!
//! - serial: the library's run ([`crate::transport::stream`]) over a pseudo-terminal, the
//!   program's modes restored by its preamble;
//! - Modbus TCP or RTU: the re-entry and the rest as segments through the register map, the
//!   bridge's clock at the console's time scale, as a Modbus dry run runs;
//! - CAN through slcan: the re-entry and the rest as set-points to the simulated drives,
//!   in lockstep with their SYNC clock, as a CAN dry run runs (a machine's drives run on the
//!   wall clock, which [`crate::transport::stream`] keeps to).
//!
//! A fieldbus resume that stops again says where to resume in program lines, as
//! [`crate::transport::stream`] does. The simulator here has no Δ guard: a guard judges a
//! whole program, and this is the rest of one. The console measures the cut of the stopped
//! run and the resume together ([`super::groove::measure`]).

use crate::config::machine::MachineProfile;
use crate::judge::{cycles, simulator};
use crate::log::{self, ExecLog};
use crate::program::Move;

use crate::transport::can::{stream_can, CanClock, CanLink, CanOptions};
use crate::transport::link::can_bus;
use crate::transport::modbus::{stream_modbus, ModbusLink, ModbusOptions};
use crate::transport::run::Pickup;
use crate::transport::{
    self, Commands, Link, Outcome, Posted, ProgressFn, RunOptions, StreamError, TransportKind,
};
use std::sync::{Arc, Mutex};
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
    /// The simulated drives cannot be built for the machine.
    #[error("the simulated drives: {0}")]
    Drives(String),
    /// A transport the console does not resume on.
    #[error(
        "the console resumes dry runs over serial, Modbus TCP or RTU and CAN (slcan), not {0}"
    )]
    Transport(&'static str),
    /// The run.
    #[error(transparent)]
    Stream(#[from] StreamError),
}

impl ResumeError {
    /// The run's own error, if the run got that far, else `None`.
    pub fn stream(&self) -> Option<&StreamError> {
        match self {
            ResumeError::Stream(error) => Some(error),
            _ => None,
        }
    }
}

/// Resumes `posted` on `machine`'s simulator over `transport` (see the module docs); every
/// move the simulator executes is logged to `log` beside the run's own events.
pub async fn resume(
    machine: &MachineProfile,
    posted: &Posted,
    transport: TransportKind,
    options: ResumeOptions,
    commands: Commands,
    log: &mut ExecLog,
) -> Result<Outcome, ResumeError> {
    match transport {
        TransportKind::Serial => resume_serial(machine, posted, options, commands, log).await,
        TransportKind::ModbusTcp => {
            resume_modbus(machine, posted, false, options, commands, log).await
        }
        TransportKind::ModbusRtu => {
            resume_modbus(machine, posted, true, options, commands, log).await
        }
        TransportKind::CanSlcan => resume_can(machine, posted, options, commands, log).await,
        other => Err(ResumeError::Transport(other.name())),
    }
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

/// A resume on the simulated controller over a serial line, through the library's run.
async fn resume_serial(
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
                executed(&mut sim_log, started, block);
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
    let outcome = until_streamed(served, streamed).await;
    drop(slave);
    outcome
}

/// An executed move of the simulator, into the console's log.
fn executed(log: &mut ExecLog, started: Instant, block: &whirl_sim::ExecutedBlock) {
    // The console's logs are in memory, which takes every event.
    let _ = log.write(
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

/// The simulated controller's watchdog in a console resume, ms of its time: the longest
/// the map holds, as in a Modbus dry run (a busy host must not trip it at a high scale).
const WATCHDOG_MS: u16 = u16::MAX;

/// A resume through the Modbus register map, over TCP on a loopback port or RTU on a
/// pseudo-terminal, the bridge's clock at the time scale of the simulator's.
async fn resume_modbus(
    machine: &MachineProfile,
    posted: &Posted,
    rtu: bool,
    options: ResumeOptions,
    commands: Commands,
    log: &mut ExecLog,
) -> Result<Outcome, ResumeError> {
    use whirl_sim::modbus::serve::{serve_rtu, serve_tcp, ClockOptions};
    use whirl_sim::modbus::{Bank, BankOptions};

    let pickup = Pickup::resuming(posted, options.line)?;
    let segments = crate::post::modbus::segments(&pickup.program).map_err(StreamError::from)?;
    let controller = Controller::new(
        &simulator::machine(machine),
        ControllerOptions {
            start: Position::from_array(options.start),
            ..ControllerOptions::default()
        },
    )
    .map_err(ResumeError::Controller)?;
    let bank = Bank::new(
        controller,
        BankOptions {
            watchdog_timeout_ms: WATCHDOG_MS,
            ..BankOptions::default()
        },
    )
    .map_err(ResumeError::Controller)?;
    let bank = Arc::new(Mutex::new(bank));
    let clock = ClockOptions {
        time_scale: options.time_scale,
        max_step: Some(crate::judge::dry_run::SIM_MAX_STEP),
        ..ClockOptions::default()
    };
    let started = Instant::now();
    let mut sim_log = log.clone();
    let on_event = |event: &Event| {
        if let Event::Executed(block) = event {
            executed(&mut sim_log, started, block);
        }
    };
    let stream_options = ModbusOptions {
        clock_scale: options.time_scale,
        segment_moves: crate::post::modbus::segment_moves(&pickup.program),
        lines: Some(pickup.lines.clone()),
        program: posted.name.clone(),
        on_progress: options.progress,
        commands: Some(commands),
        ..ModbusOptions::default()
    };
    let mut slave = None;
    #[allow(clippy::type_complexity)]
    let (served, link): (
        std::pin::Pin<Box<dyn std::future::Future<Output = std::io::Result<()>> + '_>>,
        ModbusLink,
    ) = if rtu {
        let (master, pty) = tokio_serial::SerialStream::pair().map_err(|e| {
            ResumeError::Simulator(std::io::Error::other(format!("no pseudo-terminal: {e}")))
        })?;
        let path = pty
            .name()
            .ok_or_else(|| ResumeError::Simulator(std::io::Error::other("the pty has no name")))?;
        slave = Some(pty);
        (
            Box::pin(serve_rtu(master, Arc::clone(&bank), clock, on_event)),
            ModbusLink::Rtu {
                path,
                baud: options.baud,
            },
        )
    } else {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .map_err(ResumeError::Simulator)?;
        let address = listener.local_addr().map_err(ResumeError::Simulator)?;
        (
            Box::pin(serve_tcp(listener, Arc::clone(&bank), clock, on_event)),
            ModbusLink::Tcp(address),
        )
    };
    let streamed = async {
        let outcome = stream_modbus(&link, segments, stream_options, log)
            .await
            .map_err(|error| pickup.interrupted(error.resume_move(), error))?;
        Ok::<_, StreamError>(Outcome::Modbus(outcome))
    };
    let result = until_streamed(served, streamed).await;
    drop(slave);
    result
}

/// A resume on the simulated CiA 402 drives behind an slcan adapter on a pseudo-terminal,
/// the set-points in lockstep with the drives' SYNC clock.
async fn resume_can(
    machine: &MachineProfile,
    posted: &Posted,
    options: ResumeOptions,
    commands: Commands,
    log: &mut ExecLog,
) -> Result<Outcome, ResumeError> {
    use crate::post::setpoints::SampleConfig;
    use crate::protocol::canopen::session::SessionConfig;
    use whirl_sim::canopen::serve::{serve_slcan, ServeOptions};
    use whirl_sim::canopen::{Bus, BusConfig, BusEvent};

    let pickup = Pickup::resuming(posted, options.line)?;
    let (drives, bitrate) = can_bus(machine).map_err(|e| ResumeError::Drives(e.to_string()))?;
    let mut session = SessionConfig {
        hold_ramp: machine.stop_time(),
        ..SessionConfig::for_drives(&drives).map_err(StreamError::from)?
    };
    // Before the first SYNC both ends run on one host's wall clock (see the CAN dry run).
    session.sdo_timeout = session.sdo_timeout.max(Duration::from_secs(1));
    session.heartbeat_timeout = session.heartbeat_timeout.max(Duration::from_secs(1));
    let counts_per_unit = drives.counts_per_unit();
    let bus = Bus::new(BusConfig::for_machine(
        &simulator::machine(machine),
        counts_per_unit,
        drives.period(),
        Position::from_array(options.start),
    ))
    .map_err(|e| ResumeError::Drives(e.to_string()))?;
    let bus = Arc::new(Mutex::new(bus));
    let (master, slave) = tokio_serial::SerialStream::pair().map_err(|e| {
        ResumeError::Simulator(std::io::Error::other(format!("no pseudo-terminal: {e}")))
    })?;
    let path = slave
        .name()
        .ok_or_else(|| ResumeError::Simulator(std::io::Error::other("the pty has no name")))?;
    let link = CanLink::Slcan {
        path,
        baud: options.baud,
        bitrate,
    };
    let can_options = CanOptions {
        session,
        sample: SampleConfig::for_drives(machine, &drives),
        clock: CanClock::SyncLocked,
        pace: Some(options.time_scale),
        answer_timeout: Duration::from_secs(5),
        program: posted.name.clone(),
        on_progress: options.progress,
        commands: Some(commands),
        lines: Some(pickup.lines.clone()),
    };
    let serve_options = ServeOptions {
        // The boot-up at real time, as the drives' and the master's timeouts are set for
        // it; the cycle then runs on the master's SYNC.
        time_scale: 1.0,
        sync_hold: Duration::from_secs(5),
        ..ServeOptions::default()
    };
    let started = Instant::now();
    let mut sim_log = log.clone();
    let mut merger = cycles::Merger::new(counts_per_unit);
    let positioning = Positioning::of(&pickup, counts_per_unit[0]);
    let stretch = |log: &mut ExecLog, s: cycles::Stretch| {
        let mut block = s.block();
        if positioning.is(&s) {
            block.kind = MoveKind::Rapid;
        }
        executed(log, started, &block)
    };
    let served = serve_slcan(master, Arc::clone(&bus), serve_options, |event| {
        if let BusEvent::Executed(block) = event {
            if let Some(s) = merger.push(block) {
                stretch(&mut sim_log, s);
            }
        }
    });
    let streamed = async {
        let outcome = stream_can(&link, &pickup.program, can_options, log)
            .await
            .map_err(|error| pickup.interrupted(error.resume_move(), error))?;
        Ok::<_, StreamError>(Outcome::Can(outcome))
    };
    let result = until_streamed(served, streamed).await;
    drop(slave);
    if let Some(s) = merger.finish() {
        stretch(log, s);
    }
    // The master logged where to resume before its End.
    result
}

/// Which of a CAN resume's stretches are positioning: those with the ring at the program's
/// clear X from end to end. A CiA 402 drive knows no rapids, so the drives' record does
/// not say; but the re-entry's own premise is that the ring at the clear X cuts nothing
/// ([`crate::program::reentry`]), and there it turns C back to the resume line's start (the
/// drives may have stood past it), which is no cut. Logged as rapids, they are left out of
/// the measured cut as a G-code resume's `G0` is.
struct Positioning {
    /// The program's clear X, if the resume re-enters from it.
    clear: Option<f64>,
    /// A count of X, mm: how near the clear X the drives stand there.
    tolerance: f64,
}

impl Positioning {
    /// For the resume `pickup` on drives with `x_counts` counts a mm.
    fn of(pickup: &Pickup, x_counts: f64) -> Positioning {
        let clear = match pickup.approach().first() {
            Some(Move::Rapid { x: Some(x), .. }) => Some(*x),
            _ => None,
        };
        Positioning {
            clear,
            // A count, and a hair for the floating point of the units (as the merger's).
            tolerance: 1.000_001 / x_counts,
        }
    }

    fn is(&self, stretch: &cycles::Stretch) -> bool {
        self.clear.is_some_and(|x| {
            (stretch.from[0] - x).abs() <= self.tolerance
                && (stretch.to[0] - x).abs() <= self.tolerance
        })
    }
}

/// Runs the simulator's side until the bridge's has finished and gives the bridge's
/// result; the simulator ending first is an error.
async fn until_streamed(
    served: impl std::future::Future<Output = std::io::Result<()>>,
    streamed: impl std::future::Future<Output = Result<Outcome, impl Into<ResumeError>>>,
) -> Result<Outcome, ResumeError> {
    tokio::pin!(served, streamed);
    tokio::select! {
        outcome = &mut streamed => outcome.map_err(Into::into),
        ended = &mut served => Err(ResumeError::Simulator(ended.err().unwrap_or_else(|| {
            std::io::Error::other("the simulator stopped serving")
        }))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lead-in (clear X 0, C, Z, spindle, plunge to X 18), three linked moves along a helix
    /// of lead 10 mm, lead-out; the lines as a post writes them.
    const PROGRAM: &str = "G90 G21\nG0 X0\nG0 C0\nG0 Z0\nM3 S2500\nG1 X18 F50\n\
                           G93 G1 X18.1 Z2.5 C90 F100\nG1 X18.2 Z5 C180 F100\n\
                           G1 X18.3 Z7.5 C270 F100\nG94 G0 X0\nM5\nM2\n";

    fn stretch(from: [f64; 3], to: [f64; 3]) -> cycles::Stretch {
        cycles::Stretch {
            times: [0.0, 1.0],
            from,
            to,
            cycles: 250,
            line: 1,
        }
    }

    #[test]
    fn a_can_resume_positions_at_the_clear_x_and_cuts_everywhere_else() {
        let machine = MachineProfile::builtin_sim().unwrap();
        let posted = Posted::read("p.nc", PROGRAM, &machine).unwrap();
        // Resumed at the second linked move (line 8, 0-based 7): the drives stood past its
        // start, at C 200°, and the approach turns C back there with the ring clear.
        let pickup = Pickup::resuming(&posted, 7).unwrap();
        let positioning = Positioning::of(&pickup, 10_000.0);
        assert_eq!(positioning.clear, Some(0.0));
        assert!(positioning.is(&stretch([0.0, 5.5, 200.0], [0.0, 2.5, 90.0])));
        // Within a count of the clear X, still there.
        assert!(positioning.is(&stretch([0.00009, 5.5, 200.0], [-0.00009, 2.5, 90.0])));
        // Out of the groove to the clear X, in at the plunge, and the cut: not positioning.
        assert!(!positioning.is(&stretch([18.2, 5.5, 200.0], [0.0, 5.5, 200.0])));
        assert!(!positioning.is(&stretch([0.0, 2.5, 90.0], [18.1, 2.5, 90.0])));
        assert!(!positioning.is(&stretch([18.1, 2.5, 90.0], [18.2, 5.0, 180.0])));
        // Two counts off the clear X is somewhere else.
        assert!(!positioning.is(&stretch([0.0002, 5.5, 200.0], [0.0002, 2.5, 90.0])));
        // Resumed at the program's first move (line 2, 0-based 1), the program itself
        // positions: no approach, so nothing is judged positioning by the clear X.
        let first = Positioning::of(&Pickup::resuming(&posted, 1).unwrap(), 10_000.0);
        assert_eq!(first.clear, None);
        assert!(!first.is(&stretch([0.0, 0.0, 0.0], [0.0, 0.0, 90.0])));
    }
}
