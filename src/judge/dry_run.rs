//! `whirl dry-run`: a planned job run on the simulated controller before it goes near
//! metal, through the same transport code a machine gets.
//!
//! [`dry_run`] is the one entry, for every transport the simulator serves: the grblHAL
//! controller behind a real pseudo-terminal (serial), its Modbus register bank over TCP or
//! RTU, or three CiA 402 drives behind an slcan adapter. The simulator runs in this process;
//! the program goes through the same checks, protocol and log as on a machine, and the
//! caller holds, resumes and aborts it with the same [`Commands`]. The simulator's Δ guard
//! ([`crate::judge::guard`]) measures what it executes and stops it (`ALARM:64`) as soon as
//! the profile error exceeds Δ; every move it executes is written to the same log as the
//! transport's events. Its clock runs as fast as the host allows unless a time scale is
//! given, so a job of hours dry-runs in seconds.
//!
//! [`preflight`] settles every refusal (the machine's limits, a transport the simulator
//! does not serve, drives the profile does not describe) before anything is opened, so a
//! caller can check before it opens a log; [`dry_run`] checks again.

use crate::config::connection::{DriveSettings, SettingError};
use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::geometry::linkage::Ring;
use crate::judge::cycles::{self, MergedGuard};
use crate::judge::guard::DeltaGuard;
use crate::judge::simulator;
use crate::judge::verify::CheckError;
use crate::log::{self, ExecLog, LogError};
use crate::post::modbus::{segment_moves, SegmentError};
use crate::post::setpoints::SampleConfig;
use crate::protocol::canopen::session::SessionConfig;
use crate::protocol::canopen::slcan::Bitrate;
use crate::protocol::grbl::codes::alarm_message;
use crate::transport::link::can_bus;
use crate::transport::run::Pickup;
use crate::transport::serial::{
    link_utilization, stream_port, Ending, SerialError, StreamOptions, StreamOutcome,
};
use crate::transport::{Commands, LinkError, Posted, PreflightError, ProgressFn, TransportKind};
use serde::Serialize;
use std::time::{Duration, Instant};
use tokio_serial::SerialPort;
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions, Event, Measured, MoveKind};

/// Simulated seconds per step when the clock runs as fast as it can: fine enough for the
/// 5 Hz status polls and the emulated link (at 115 200 baud, 58 bytes a step).
const FAST_STEP_S: f64 = 0.005;

/// How a dry run runs.
pub struct DryRunOptions {
    /// How the program goes to the simulator: G-code over a serial line, segments through
    /// the Modbus register map over TCP or RTU, or set-points to CAN drives through slcan.
    pub transport: TransportKind,
    /// Simulated seconds per wall second; `None`: as fast as the host allows (for Modbus,
    /// [`MODBUS_TIME_SCALE`]). Over CAN the drives boot at real time whatever it is, and
    /// the cycle then runs in lockstep at no more than this scale
    /// ([`crate::transport::can::CanOptions::pace`]).
    pub time_scale: Option<f64>,
    /// The link's baud rate, emulated in simulated time.
    pub baud: u32,
    /// The simulated controller's receive buffer, bytes.
    pub rx_size: usize,
    /// Give up (with a feed hold) after this long without progress, wall time.
    pub stall_timeout: Duration,
    /// Told how far the run is, as it goes.
    pub progress: Option<ProgressFn>,
    /// The caller's hold, resume and abort.
    pub commands: Option<Commands>,
}

impl Default for DryRunOptions {
    fn default() -> DryRunOptions {
        DryRunOptions {
            transport: TransportKind::Serial,
            time_scale: None,
            baud: 115_200,
            rx_size: 1024,
            stall_timeout: Duration::from_secs(30),
            progress: None,
            commands: None,
        }
    }
}

/// An alarm the simulator raised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alarm {
    /// `ALARM:N`.
    pub code: u16,
    /// grbl's meaning of it.
    pub message: String,
    /// What the Δ guard found, for `ALARM:64`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub detail: Option<String>,
}

/// What `whirl dry-run --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct DryRunReport {
    /// The job (or program) that was run.
    pub job: String,
    /// Every line acknowledged and executed, no alarm, and the whole groove measured
    /// within Δ.
    pub within_delta: bool,
    /// The stream completed (every line acknowledged, the motion finished).
    pub completed: bool,
    /// Program lines.
    pub lines: usize,
    /// Program lines acknowledged `ok`.
    pub lines_acked: usize,
    /// How the stream ended, when it did not complete.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop: Option<String>,
    /// Where a run that did not complete resumes: the program line (1-based) of the first
    /// move not known to have run, as `whirl stream --resume-at` takes it; also in the log.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resume_at: Option<usize>,
    /// Simulated time from the first move's start to the last one's end, s: what the job
    /// takes on the machine, stops for a slow sender included. (Before and after, the
    /// simulator's clock runs on while the streamer opens the port and confirms the machine
    /// idle, which takes it wall time, not machine time.)
    pub machine_time_s: f64,
    /// Wall time of the dry run, s.
    pub wall_time_s: f64,
    /// The link's baud rate.
    pub baud: u32,
    /// Bytes sent × 10 bits over what the link carries until the last line is answered
    /// (simulated time): how busy the real link will be, 0 to 1.
    pub link_utilization: f64,
    /// The larger of the measured overcut and undercut, mm.
    pub max_error_mm: f64,
    /// Largest overcut the simulator measured, mm.
    pub max_overcut_mm: f64,
    /// Largest undercut the simulator measured, mm.
    pub max_undercut_mm: f64,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Target points measured.
    pub points_measured: usize,
    /// Target points of the groove.
    pub points: usize,
    /// Alarms the simulator raised, in order.
    pub alarms: Vec<Alarm>,
}

/// Why a dry run could not be carried out (a run that stops or exceeds Δ is not an error:
/// it is in the report).
#[derive(Debug, thiserror::Error)]
pub enum DryRunError {
    /// The job's groove cannot be measured.
    #[error("the simulator's Δ guard: {0}")]
    Guard(CheckError),
    /// The simulated controller cannot be built for the machine.
    #[error("the simulated controller: {0}")]
    Controller(whirl_sim::ConfigError),
    /// No pseudo-terminal.
    #[error("cannot open a pseudo-terminal for the simulator: {0}")]
    Pty(tokio_serial::Error),
    /// The program asks more of the machine than it has, or cannot be read (checked
    /// before anything runs).
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    /// The serial transport.
    #[error(transparent)]
    Stream(#[from] SerialError),
    /// The simulator stopped serving mid-run.
    #[error("the simulator stopped mid-run: {0}")]
    Simulator(std::io::Error),
    /// The executed-path log.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The program cannot go through the Modbus register map.
    #[error(transparent)]
    Segments(#[from] SegmentError),
    /// The Modbus transport.
    #[error(transparent)]
    ModbusStream(#[from] crate::transport::modbus::ModbusError),
    /// The profile's CAN drives or adapter, as a link.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The drives' settings make no session.
    #[error(transparent)]
    Settings(#[from] SettingError),
    /// The simulated drives cannot be built for the machine.
    #[error("the simulated drives: {0}")]
    Drives(whirl_sim::canopen::BusError),
    /// The CAN transport.
    #[error(transparent)]
    CanStream(#[from] crate::transport::can::CanError),
    /// LinuxCNC is a controller, not a way to the built-in simulator.
    #[error(
        "the built-in simulator is a grblHAL controller and does not run LinuxCNC's \
         transport: dry-run with --controller linuxcnc"
    )]
    LinuxcncTransport,
    /// A transport the simulator does not serve.
    #[error(
        "the simulated drives are reached through an slcan adapter, not a socketcan \
         interface: dry-run with --transport can-slcan"
    )]
    Socketcan,
}

/// What the simulator side collects while it serves.
struct SimSide {
    log: ExecLog,
    started: Instant,
    /// Simulated time of the last line answered.
    last_answer: f64,
    /// Simulated times the first executed move started and the last one ended.
    motion: Option<(f64, f64)>,
    alarms: Vec<Alarm>,
    log_error: Option<LogError>,
}

/// The simulated controller for `machine`, `guard` watching it, and the number of target
/// points the guard will measure.
fn guarded_controller(
    guard: DeltaGuard,
    machine: &MachineProfile,
    options: ControllerOptions,
) -> Result<(Controller, usize), DryRunError> {
    let points = guard.points();
    let mut controller =
        Controller::new(&simulator::machine(machine), options).map_err(DryRunError::Controller)?;
    controller.set_guard(Box::new(guard));
    Ok((controller, points))
}

/// How a run ended, in the terms of either transport.
struct RunEnd {
    completed: bool,
    lines: usize,
    acked: usize,
    stop: Option<String>,
    /// The program line (1-based) to resume at.
    resume_at: Option<usize>,
    link_utilization: f64,
}

impl SimSide {
    fn new(log: &ExecLog) -> SimSide {
        SimSide {
            log: log.clone(),
            started: Instant::now(),
            last_answer: 0.0,
            motion: None,
            alarms: Vec::new(),
            log_error: None,
        }
    }

    /// The report of a run named `name` that ended so, with what the guard `measured` of
    /// its `points`.
    fn report(
        self,
        name: &str,
        measured: Measured,
        points: usize,
        ending: RunEnd,
        baud: u32,
    ) -> Result<DryRunReport, DryRunError> {
        if let Some(error) = self.log_error {
            return Err(error.into());
        }
        let within_delta = ending.completed
            && self.alarms.is_empty()
            && measured.points == points
            && measured.max_error_mm() <= measured.delta_mm;
        Ok(DryRunReport {
            job: name.to_owned(),
            within_delta,
            completed: ending.completed,
            lines: ending.lines,
            lines_acked: ending.acked,
            stop: ending.stop,
            resume_at: ending.resume_at,
            machine_time_s: self.motion.map_or(0.0, |(start, end)| end - start),
            wall_time_s: self.started.elapsed().as_secs_f64(),
            baud,
            link_utilization: ending.link_utilization,
            max_error_mm: measured.max_error_mm(),
            max_overcut_mm: measured.max_overcut_mm,
            max_undercut_mm: measured.max_undercut_mm,
            delta_mm: measured.delta_mm,
            points_measured: measured.points,
            points,
            alarms: self.alarms,
        })
    }

    fn on_event(&mut self, event: &Event) {
        match event {
            Event::Line { time, .. } => self.last_answer = *time,
            Event::Executed(block) => self.executed(
                block.n.map(|n| n as usize),
                [block.start_time, block.end_time],
                [block.from.to_array(), block.to.to_array()],
                block.kind == MoveKind::Rapid,
            ),
            Event::Alarm { alarm, breach, .. } => {
                let code = u16::from(alarm.code());
                self.alarms.push(Alarm {
                    code,
                    message: alarm_message(code).to_owned(),
                    detail: breach.as_ref().map(|b| b.message.clone()),
                });
                if let Some(b) = breach {
                    self.message(format!("simulator: {}", b.message));
                }
            }
            Event::RxOverflow { dropped, .. } => self.message(format!(
                "simulator: RX buffer overflow, {dropped} bytes dropped"
            )),
            Event::Reset { .. } | Event::State { .. } => {}
        }
    }

    /// The simulated drives' cycles, merged into a move.
    fn stretch(&mut self, stretch: cycles::Stretch) {
        self.executed(None, stretch.times, [stretch.from, stretch.to], false);
    }

    /// The Δ guard stopped the simulated drives: reported as grbl's ALARM:64 is.
    fn breach(&mut self, breach: &whirl_sim::Breach) {
        self.alarms.push(Alarm {
            code: 64,
            message: alarm_message(64).to_owned(),
            detail: Some(breach.message.clone()),
        });
        self.message(format!("simulator: {}", breach.message));
    }

    /// A move the simulator executed: its file line, start and end time, start and end
    /// position, and whether it was a rapid.
    fn executed(
        &mut self,
        line: Option<usize>,
        times: [f64; 2],
        [from, to]: [[f64; 3]; 2],
        rapid: bool,
    ) {
        // Machine time is motion's: from the first move that went somewhere.
        if from != to || self.motion.is_some() {
            let start = self.motion.map_or(times[0], |m| m.0);
            self.motion = Some((start, times[1]));
        }
        self.log(log::Event::Executed {
            line,
            times,
            from,
            to,
            rapid,
        });
    }

    fn message(&mut self, text: String) {
        self.log(log::Event::Message { text });
    }

    fn log(&mut self, event: log::Event) {
        let t = self.started.elapsed().as_secs_f64();
        if let Err(error) = self.log.write(t, event) {
            self.log_error.get_or_insert(error);
        }
    }
}

/// Checks that `posted` can be dry-run on `machine` over `transport`, before anything is
/// opened: the machine's limits, a transport the simulator serves, and for CAN the
/// profile's drives and adapter. Gives the CAN drives and bit rate where they are needed.
pub fn preflight(
    machine: &MachineProfile,
    posted: &Posted,
    transport: TransportKind,
) -> Result<Option<(DriveSettings, Bitrate)>, DryRunError> {
    posted.check(machine)?;
    match transport {
        TransportKind::Can => Err(DryRunError::Socketcan),
        TransportKind::Linuxcnc => Err(DryRunError::LinuxcncTransport),
        // The adapter's port is the simulator's own; the drives are the profile's.
        TransportKind::CanSlcan => Ok(Some(can_bus(machine)?)),
        TransportKind::Serial | TransportKind::ModbusTcp | TransportKind::ModbusRtu => Ok(None),
    }
}

/// Dry-runs `posted` (the program planned for `job` on `machine` with `ring`, or one given
/// for it; a program planned before takes the ring `plan` plans the job with,
/// [`crate::plan::angles::ring`]) on the simulator over `options.transport`, logging to `log`;
/// see the module docs. Its name names it in the log and the report.
pub async fn dry_run(
    job: &Job,
    ring: Ring,
    machine: &MachineProfile,
    posted: &Posted,
    options: DryRunOptions,
    log: &mut ExecLog,
) -> Result<DryRunReport, DryRunError> {
    let can = preflight(machine, posted, options.transport)?;
    let guard = DeltaGuard::new(job, ring, machine).map_err(DryRunError::Guard)?;
    match (options.transport, can) {
        (TransportKind::ModbusTcp, _) => {
            over_modbus(guard, machine, posted, ModbusKind::Tcp, options, log).await
        }
        (TransportKind::ModbusRtu, _) => {
            over_modbus(guard, machine, posted, ModbusKind::Rtu, options, log).await
        }
        (_, Some((drives, bitrate))) => {
            over_can(guard, machine, posted, &drives, bitrate, options, log).await
        }
        _ => over_serial(guard, machine, posted, options, log).await,
    }
}

/// The dry run over a serial line: the controller behind a pseudo-terminal.
async fn over_serial(
    guard: DeltaGuard,
    machine: &MachineProfile,
    posted: &Posted,
    options: DryRunOptions,
    log: &mut ExecLog,
) -> Result<DryRunReport, DryRunError> {
    let program = posted.name.as_str();
    let lines = posted.lines.clone();
    let (mut controller, points) = guarded_controller(
        guard,
        machine,
        ControllerOptions {
            rx_buffer_size: options.rx_size,
            ..ControllerOptions::default()
        },
    )?;
    // Booted long before the port opened, as a board on a USB link is: no banner waiting.
    controller.take_output();
    let (master, slave) = tokio_serial::SerialStream::pair().map_err(DryRunError::Pty)?;
    let device = slave
        .name()
        .ok_or_else(|| DryRunError::Simulator(std::io::Error::other("the pty has no name")))?;
    let mut sim = SimSide::new(log);
    let serve_options = ServeOptions {
        time_scale: options.time_scale,
        fast_step: FAST_STEP_S,
        baud: Some(options.baud),
        ..ServeOptions::default()
    };
    let total = lines.len();
    let stream_options = StreamOptions {
        program: program.to_owned(),
        baud: Some(options.baud),
        no_progress_timeout: Some(options.stall_timeout),
        on_progress: options.progress,
        commands: options.commands,
        ..StreamOptions::default()
    };
    let outcome: StreamOutcome = until_streamed(
        serve(master, &mut controller, serve_options, |e| sim.on_event(e)),
        stream_port(&device, options.baud, lines, stream_options, log),
    )
    .await?;
    drop(slave);
    let completed = outcome.completed();
    let ending = RunEnd {
        completed,
        lines: total,
        acked: outcome.lines_acked,
        stop: match &outcome.ending {
            Ending::Completed => None,
            Ending::Stopped(reason) => Some(reason.to_string()),
            other => Some(other.to_string()),
        },
        resume_at: outcome.resume.as_ref().map(|r| r.line_index + 1),
        link_utilization: link_utilization(
            outcome.bytes_written,
            options.baud,
            Duration::from_secs_f64(sim.last_answer),
        )
        .unwrap_or(0.0),
    };
    sim.report(program, measured(&controller), points, ending, options.baud)
}

/// What the Δ guard of a dry run's controller measured.
fn measured(controller: &Controller) -> Measured {
    controller
        .guard()
        .map(|g| g.measured())
        .expect("a dry run's controller has its guard")
}

/// Runs the simulator's side (`served`) until the bridge's (`streamed`) has finished and
/// gives the bridge's result; the simulator ending first is an error.
async fn until_streamed<T, E: Into<DryRunError>>(
    served: impl std::future::Future<Output = std::io::Result<()>>,
    streamed: impl std::future::Future<Output = Result<T, E>>,
) -> Result<T, DryRunError> {
    tokio::pin!(served, streamed);
    tokio::select! {
        outcome = &mut streamed => outcome.map_err(Into::into),
        ended = &mut served => Err(DryRunError::Simulator(ended.err().unwrap_or_else(|| {
            std::io::Error::other("the simulator stopped serving")
        }))),
    }
}

/// Which Modbus link a Modbus dry run uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ModbusKind {
    /// Modbus TCP on a loopback port.
    Tcp,
    /// Modbus RTU over a pseudo-terminal.
    Rtu,
}

/// Simulated seconds per wall second of a Modbus dry run unless told otherwise: the bridge
/// polls and feeds the watchdog in the controller's time (see
/// [`crate::transport::modbus`]), so the clock runs scaled, not as fast as it can.
pub const MODBUS_TIME_SCALE: f64 = 100.0;

/// The simulated controller's watchdog in a dry run, ms of its time: the longest the map
/// holds (65.5 s), so that a bridge task kept waiting behind the simulator's own work does
/// not trip it at the dry run's time scale (a third of a second of wall time at 200×); a
/// host that stops the whole process is not counted at all ([`SIM_MAX_STEP`]). The
/// watchdog itself is tested apart.
const DRY_RUN_WATCHDOG_MS: u16 = u16::MAX;

/// The most wall time one step of an in-process Modbus simulator's clock counts
/// ([`whirl_sim::modbus::serve::ClockOptions::max_step`]): ten of its 2 ms ticks. A longer
/// gap is the host not running the process, in which the bridge did not run either; counted,
/// it would expire the controller's watchdog at a high time scale however well the bridge
/// feeds it, and the dry run's verdict would depend on how busy the host was.
pub const SIM_MAX_STEP: Duration = Duration::from_millis(20);

/// The dry run through the Modbus register map: the simulator's register bank in front of
/// the same simulated controller and Δ guard, served with tokio-modbus over TCP or RTU,
/// and whirl's Modbus transport streaming to it.
async fn over_modbus(
    guard: DeltaGuard,
    machine: &MachineProfile,
    posted: &Posted,
    kind: ModbusKind,
    options: DryRunOptions,
    log: &mut ExecLog,
) -> Result<DryRunReport, DryRunError> {
    let (name, program) = (posted.name.as_str(), &posted.program);
    use crate::transport::modbus::{stream_modbus, ModbusLink, ModbusOptions};
    use whirl_sim::modbus::serve::{serve_rtu, serve_tcp, ClockOptions};
    use whirl_sim::modbus::{Bank, BankOptions};

    let segments = crate::post::modbus::segments(program)?;
    let total = segments.len();
    let moves = Pickup::whole(posted);
    let (controller, points) = guarded_controller(guard, machine, ControllerOptions::default())?;
    let bank = Bank::new(
        controller,
        BankOptions {
            watchdog_timeout_ms: DRY_RUN_WATCHDOG_MS,
            ..BankOptions::default()
        },
    )
    .map_err(DryRunError::Controller)?;
    let bank = std::sync::Arc::new(std::sync::Mutex::new(bank));
    let scale = options.time_scale.unwrap_or(MODBUS_TIME_SCALE);
    let clock = ClockOptions {
        time_scale: scale,
        max_step: Some(SIM_MAX_STEP),
        ..ClockOptions::default()
    };
    let mut sim = SimSide::new(log);
    let stream_options = ModbusOptions {
        clock_scale: scale,
        segment_moves: segment_moves(program),
        lines: Some(moves.lines.clone()),
        program: name.to_owned(),
        on_progress: options.progress,
        commands: options.commands,
        ..ModbusOptions::default()
    };
    let streamed = match kind {
        ModbusKind::Tcp => {
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
                .await
                .map_err(DryRunError::Simulator)?;
            let addr = listener.local_addr().map_err(DryRunError::Simulator)?;
            let link = ModbusLink::Tcp(addr);
            until_streamed(
                serve_tcp(listener, std::sync::Arc::clone(&bank), clock, |e| {
                    sim.on_event(e)
                }),
                stream_modbus(&link, segments, stream_options, log),
            )
            .await
        }
        ModbusKind::Rtu => {
            let (master, slave) = tokio_serial::SerialStream::pair().map_err(DryRunError::Pty)?;
            let device = slave.name().ok_or_else(|| {
                DryRunError::Simulator(std::io::Error::other("the pty has no name"))
            })?;
            let link = ModbusLink::Rtu {
                path: device,
                baud: options.baud,
            };
            let streamed = until_streamed(
                serve_rtu(master, std::sync::Arc::clone(&bank), clock, |e| {
                    sim.on_event(e)
                }),
                stream_modbus(&link, segments, stream_options, log),
            )
            .await;
            drop(slave);
            streamed
        }
    };
    let resume_move = match &streamed {
        Ok(outcome) => outcome.resume_move,
        Err(DryRunError::ModbusStream(error)) => error.resume_move(),
        Err(_) => None,
    };
    // The transport logged it before its End.
    let resume_at = resume_move.map(|at| moves.line_of(at) + 1);
    let outcome = streamed?;
    let bank = bank.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(alarm) = outcome.alarm {
        // An alarm of the map's own (a refused slot, the watchdog) the controller did not
        // raise: the simulator's events have none for it.
        if sim.alarms.is_empty() {
            sim.alarms.push(Alarm {
                code: alarm.code.code(),
                message: alarm.to_string(),
                detail: None,
            });
        }
    }
    let ending = RunEnd {
        completed: outcome.completed,
        lines: total,
        acked: outcome.published,
        stop: outcome
            .alarm
            .map(|a| a.to_string())
            .or_else(|| outcome.failure.as_ref().map(ToString::to_string))
            .or_else(|| outcome.stopped.clone())
            .or_else(|| outcome.aborted.then(|| "aborted".to_owned())),
        resume_at,
        // A TCP link has no byte rate to fill. An RTU line's: the exchanges' bit times
        // over what the line carries in the controller's time.
        link_utilization: match kind {
            ModbusKind::Tcp => 0.0,
            ModbusKind::Rtu => {
                let seconds = outcome.wall_time.as_secs_f64() * scale;
                outcome.rtu_bits as f64 / (f64::from(options.baud) * seconds)
            }
        },
    };
    sim.report(
        name,
        measured(bank.controller()),
        points,
        ending,
        options.baud,
    )
}

/// The least time a CAN dry run's master waits for an SDO answer or a heartbeat.
const CAN_HOST_PATIENCE: Duration = Duration::from_secs(1);

/// How long the simulated drives wait for the next SYNC before wall time runs their clock
/// again: far beyond any pause of a busy host, well below the dry run's patience.
const CAN_SYNC_HOLD: Duration = Duration::from_secs(5);

/// Where the simulated drives power up: Z and C at 0, X where the program's first move
/// puts it, which in a planned program is the ring's clear position. The drives'
/// every cycle is judged (a CiA 402 drive knows no rapids), and a ring at X 0 is no place
/// to start from: for external whirling it is concentric with the work, and the way out
/// to the clear position would run its inserts through the blank.
fn clear_start(program: &crate::program::Program) -> whirl_sim::Position {
    use crate::config::machine::Axis;
    use crate::program::Position;
    let x = program
        .steps(Position::known(0.0, 0.0, 0.0))
        .find(|step| step.action.target().is_some())
        .and_then(|step| step.to.get(Axis::X))
        .unwrap_or(0.0);
    whirl_sim::Position::from_array([x, 0.0, 0.0])
}

/// Where a dry run of `program` on `transport` powers the simulated machine up (X, Z, C):
/// the drives' clear start on CAN, the origin for a grbl or a PLC, as the simulator's
/// controller boots. A resume of a dry run stopped before it moved starts there.
pub fn power_up(program: &crate::program::Program, transport: TransportKind) -> [f64; 3] {
    match transport {
        TransportKind::CanSlcan | TransportKind::Can => clear_start(program).to_array(),
        _ => [0.0; 3],
    }
}

/// Simulated seconds per wall second of a CAN dry run before the cycle runs (boot-up,
/// configuration): real time, as the drives' and the master's timeouts are set for it.
/// Once the cycle runs, the drives' clock is the master's SYNC and the job goes as fast
/// as the link and the simulator allow, or at the dry run's time scale if it has one.
const CAN_BOOT_TIME_SCALE: f64 = 1.0;

/// The dry run on three simulated CiA 402 drives behind an slcan adapter on a
/// pseudo-terminal, set as the profile's `drives` and `bitrate` say: whirl's CANopen
/// master streams the set-points through the adapter in lockstep with the drives' SYNC
/// clock ([`crate::transport::can::CanClock::SyncLocked`]), paced at the time scale if
/// one is given (a watched run: a console's), and the Δ guard judges the
/// cycles the drives executed, merged into the straight stretches they make up
/// ([`crate::judge::cycles`]). The log gets the master's events and the same stretches.
///
/// The report counts set-points as its lines (`lines`, `lines_acked`: sent), and gives the
/// CAN bus's load as `link_utilization`, at the adapter's bit rate, without stuff bits.
async fn over_can(
    guard: DeltaGuard,
    machine: &MachineProfile,
    posted: &Posted,
    drives: &DriveSettings,
    bitrate: Bitrate,
    options: DryRunOptions,
    log: &mut ExecLog,
) -> Result<DryRunReport, DryRunError> {
    use crate::transport::can::{stream_can, CanClock, CanLink, CanOptions};
    use whirl_sim::canopen::serve::{serve_slcan, ServeOptions};
    use whirl_sim::canopen::{Bus, BusConfig, BusEvent};

    let (name, program) = (posted.name.as_str(), &posted.program);
    let time_scale = options.time_scale;
    let mut session = SessionConfig {
        hold_ramp: machine.stop_time(),
        ..SessionConfig::for_drives(drives)?
    };
    // Until the first SYNC the master and the simulated drives both run on the wall clock
    // of one host, which may pause either for longer than a bus ever would: such a pause
    // must not read as a dead drive. From the first SYNC on, heartbeats are exact.
    session.sdo_timeout = session.sdo_timeout.max(CAN_HOST_PATIENCE);
    session.heartbeat_timeout = session.heartbeat_timeout.max(CAN_HOST_PATIENCE);
    let counts_per_unit = drives.counts_per_unit();
    let points = guard.points();
    let mut bus = Bus::new(BusConfig::for_machine(
        &simulator::machine(machine),
        counts_per_unit,
        drives.period(),
        clear_start(program),
    ))
    .map_err(DryRunError::Drives)?;
    bus.set_guard(Box::new(MergedGuard::new(guard, counts_per_unit)));
    let bus = std::sync::Arc::new(std::sync::Mutex::new(bus));
    let (master, slave) = tokio_serial::SerialStream::pair().map_err(DryRunError::Pty)?;
    let device = slave
        .name()
        .ok_or_else(|| DryRunError::Simulator(std::io::Error::other("the pty has no name")))?;
    let link = CanLink::Slcan {
        path: device,
        baud: 115_200,
        bitrate,
    };
    let options = CanOptions {
        session,
        sample: SampleConfig::for_drives(machine, drives),
        clock: CanClock::SyncLocked,
        pace: time_scale,
        answer_timeout: Duration::from_secs(5),
        program: name.to_owned(),
        on_progress: options.progress,
        commands: options.commands,
        lines: Some(Pickup::whole(posted).lines.clone()),
    };
    let serve_options = ServeOptions {
        time_scale: CAN_BOOT_TIME_SCALE,
        // The master in lockstep never pauses the cycle: a wait between SYNCs is the host
        // busy elsewhere, not time the drives should see pass.
        sync_hold: CAN_SYNC_HOLD,
        ..ServeOptions::default()
    };
    let mut sim = SimSide::new(log);
    let mut merger = cycles::Merger::new(counts_per_unit);
    let streamed = until_streamed(
        serve_slcan(
            master,
            std::sync::Arc::clone(&bus),
            serve_options,
            |event| match event {
                BusEvent::Executed(block) => {
                    if let Some(stretch) = merger.push(block) {
                        sim.stretch(stretch);
                    }
                }
                BusEvent::Breach { breach, .. } => sim.breach(breach),
                BusEvent::Drive { node, event } => {
                    sim.message(format!("simulator: node {node}: {event:?}"))
                }
            },
        ),
        stream_can(&link, program, options, log),
    )
    .await;
    drop(slave);
    // The drives' last stretch, logged and judged however the stream ended: a failed run's
    // log, too, ends where the drives stand.
    if let Some(stretch) = merger.finish() {
        sim.stretch(stretch);
    }
    let resume_move = match &streamed {
        Ok(outcome) => outcome.resume_move,
        Err(DryRunError::CanStream(error)) => error.resume_move(),
        Err(_) => None,
    };
    // The master logged it before its End (1-based, as `--resume-at` takes it).
    let resume_at = resume_move.map(|at| Pickup::whole(posted).line_of(at) + 1);
    let outcome = streamed?;
    let mut bus = bus.lock().unwrap_or_else(|p| p.into_inner());
    if outcome.completed {
        // The job's end: the guard settles the points that waited for later motion.
        if let Err(breach) = bus.program_end() {
            sim.breach(&breach);
        }
    }
    let measured = bus
        .guard()
        .map(|g| g.measured())
        .expect("the dry run's bus has its guard");
    let ending = RunEnd {
        completed: outcome.completed,
        lines: outcome.setpoints,
        acked: outcome.sent,
        stop: outcome.stop.as_ref().map(ToString::to_string),
        resume_at,
        link_utilization: outcome.bus_load(bitrate.bits_per_second()),
    };
    sim.report(name, measured, points, ending, bitrate.bits_per_second())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drives_power_up_where_the_first_move_puts_x_and_a_controller_at_its_origin() {
        let machine = MachineProfile::builtin_sim().unwrap();
        let text = "G21\nG90\nG0 X31.5 Z2\nG1 X30 Z0 F100\nM2\n";
        let posted = Posted::read("p", text, &machine).unwrap();
        for can in [TransportKind::CanSlcan, TransportKind::Can] {
            assert_eq!(power_up(&posted.program, can), [31.5, 0.0, 0.0]);
        }
        for other in [
            TransportKind::Serial,
            TransportKind::ModbusTcp,
            TransportKind::ModbusRtu,
        ] {
            assert_eq!(power_up(&posted.program, other), [0.0; 3]);
        }
    }
}
