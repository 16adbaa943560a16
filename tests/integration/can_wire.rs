//! whirl's CAN transport end to end over a real pseudo-terminal: [`stream_can`] opens the
//! pty's slave end as an slcan adapter, [`serve_slcan`] serves the simulator's three CiA 402
//! drives on its master end, and the test keeps a handle on the [`SharedBus`] to act on the
//! machine while the job runs (pull a cable, fault a drive). Where `can_session.rs` checks
//! the session in one thread on simulated time, these check what the transport adds: the
//! serial line, the adapter's answers, the SYNC-locked clock and its window of cycles in
//! flight, and how a stop reaches the outcome.
//!
//! The drives are set as `machine-profiles/canopen-drives.toml` says (4 ms cycle, 50 ms
//! heartbeat), the heartbeat supervised at 1 s rather than the profile's 150 ms (see
//! [`options`]); the program is the double-start example planned for that machine, cut to
//! its first 200 blocks and its lead-out, so each run takes seconds.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use crate::util;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::SerialPort;
use whirl::config::connection::{DriveMode, DriveSettings};
use whirl::config::machine::Axis;
use whirl::config::machine::MachineProfile;
use whirl::log::{self, ExecLog};
use whirl::post::setpoints::{sample, SampleConfig, SetPoints};
use whirl::program::{Move, Position, Program};
use whirl::protocol::canopen::cia301::NodeId;
use whirl::protocol::canopen::session::{SessionConfig, StopReason};
use whirl::protocol::canopen::slcan::Bitrate;
use whirl::transport::can::{stream_can, CanClock, CanError, CanLink, CanOptions, CanOutcome};
use whirl::transport::{Progress, Unit};
use whirl_sim::canopen::serve::{serve_slcan, ServeOptions, SharedBus};
use whirl_sim::canopen::{Bus, BusConfig, BusEvent, DriveEvent, NmtState, PowerState};
use whirl_sim::{ExecutedBlock, Position as SimPosition};

/// Cycles a SYNC-locked run may have sent and not yet had acknowledged: the transport's
/// "all but the last eight cycles" (src/transport/can.rs, module docs). The drives'
/// answers reach the session up to this many cycles after the SYNC that made them.
const LOCKSTEP_WINDOW: u64 = 8;

/// The longest a whole run may take here before the test gives up on it.
const RUN_LIMIT: Duration = Duration::from_secs(60);

/// The CAN drives' machine, as whirl loads it.
fn profile() -> MachineProfile {
    MachineProfile::load(&util::root().join("machine-profiles/canopen-drives.toml"))
        .expect("the CAN drives' profile loads")
}

/// Its `[connection.drives]`.
fn drive_settings(profile: &MachineProfile) -> DriveSettings {
    profile
        .connection
        .as_ref()
        .and_then(|c| c.drives())
        .cloned()
        .expect("the profile's connection has drives")
}

/// The shortened double-start job ([`util::short_double_start`]) for `profile`.
fn program(profile: &MachineProfile) -> Program {
    util::short_double_start(profile)
}

/// A program of a few cycles: a rapid of 0.1 mm on X and back.
fn tiny_program() -> Program {
    Program {
        moves: vec![
            Move::Rapid {
                x: Some(0.1),
                z: None,
                c: None,
            },
            Move::Rapid {
                x: Some(0.0),
                z: None,
                c: None,
            },
        ],
    }
}

/// The simulator's drives for `profile` at the origin, at the drives' cycle and scales.
fn bus(profile: &MachineProfile, drives: &DriveSettings) -> SharedBus {
    let config = BusConfig::for_machine(
        &whirl::judge::simulator::machine(profile),
        drives.counts_per_unit(),
        drives.period(),
        SimPosition::default(),
    );
    Arc::new(Mutex::new(Bus::new(config).expect("the bus builds")))
}

/// The bus, whoever panicked holding it.
fn lock(bus: &SharedBus) -> MutexGuard<'_, Bus> {
    bus.lock().unwrap_or_else(|p| p.into_inner())
}

/// How the bridge runs the drives: the profile's settings, the SYNC-locked clock.
fn options(profile: &MachineProfile, drives: &DriveSettings) -> CanOptions {
    CanOptions {
        session: SessionConfig {
            // Boot-up and configuration run on the wall clock, the simulator and the
            // bridge on one busy test machine: an SDO answer may wait for a scheduler
            // slice far longer than on a bus. Everything after runs on the SYNC's clock.
            sdo_timeout: Duration::from_secs(1),
            // So is the heartbeat's supervision until the cycle runs: the drives' heartbeats
            // come from a task of this process, which a busy host may leave unrun for longer
            // than the profile's 150 ms (a cable "pulled" during configuration). After that
            // it counts SYNC cycles: 1 s is 250 of them.
            heartbeat_timeout: Duration::from_secs(1),
            ..SessionConfig::for_drives(drives).expect("the profile's drive settings")
        },
        sample: SampleConfig::for_drives(profile, drives),
        clock: CanClock::SyncLocked,
        pace: None,
        answer_timeout: Duration::from_secs(5),
        program: "double-start (short)".to_owned(),
        on_progress: None,
        commands: None,
        lines: None,
    }
}

/// An slcan link on the pty slave `path`, CAN at 1 Mbit/s.
fn slcan(path: String) -> CanLink {
    CanLink::Slcan {
        path,
        baud: 115_200,
        bitrate: Bitrate::M1,
    }
}

/// A pseudo-terminal pair and its slave's name.
fn pty() -> (
    tokio_serial::SerialStream,
    tokio_serial::SerialStream,
    String,
) {
    let (master, slave) = tokio_serial::SerialStream::pair().expect("a pseudo-terminal");
    let name = slave.name().expect("the pty's slave has a name");
    (master, slave, name)
}

/// Streams `program` with `options` to `bus`, served on a pseudo-terminal, every bus event
/// to `on_event`; the bridge's result once it has finished (the simulator ending first
/// fails the test).
async fn run_on_wire(
    bus: &SharedBus,
    program: &Program,
    options: CanOptions,
    log: &mut ExecLog,
    on_event: impl FnMut(&BusEvent),
) -> Result<CanOutcome, CanError> {
    let (master, slave, path) = pty();
    let link = slcan(path);
    let served = serve_slcan(master, Arc::clone(bus), ServeOptions::default(), on_event);
    let streamed = stream_can(&link, program, options, log);
    tokio::pin!(served, streamed);
    let result = tokio::time::timeout(RUN_LIMIT, async {
        tokio::select! {
            outcome = &mut streamed => outcome,
            ended = &mut served => panic!("the simulator stopped serving first: {ended:?}"),
        }
    })
    .await
    .unwrap_or_else(|_| panic!("the run took longer than {RUN_LIMIT:?}"));
    // Held open until the bridge was done, so that the master end never saw the slave
    // closed (EIO) while the bridge opened it or between its reads.
    drop(slave);
    result
}

/// What the bus showed while serving.
#[derive(Debug, Default)]
struct Seen {
    /// Every executed cycle, in order.
    executed: Vec<ExecutedBlock>,
    /// Power states the drives entered: (node, state, the SYNC whose frames it came with,
    /// 1-based: the one after the last executed cycle).
    power: Vec<(u8, PowerState, u64)>,
    /// NMT states the drives entered: (node, state, simulated time), for a run that ends
    /// early to say which side lost what.
    nmt: Vec<(u8, NmtState, Duration)>,
}

impl Seen {
    fn record(&mut self, event: &BusEvent) {
        match event {
            BusEvent::Executed(block) => self.executed.push(block.clone()),
            BusEvent::Drive {
                node,
                event: DriveEvent::Power { state, .. },
            } => {
                let sync = self.executed.last().map_or(0, |b| b.line) + 1;
                self.power.push((*node, *state, sync));
            }
            BusEvent::Drive {
                node,
                event: DriveEvent::Nmt { state, time },
            } => self.nmt.push((*node, *state, *time)),
            _ => {}
        }
    }

    /// The first SYNC that found `node` in `state`.
    fn entered(&self, node: u8, state: PowerState) -> Option<u64> {
        self.power
            .iter()
            .find(|(n, s, _)| *n == node && *s == state)
            .map(|(_, _, sync)| *sync)
    }
}

/// The log's record of the session's Enabled event: SYNCs sent before the first
/// set-point (set-point k, 0-based, goes with SYNC `syncs + k + 1`).
fn enabled_syncs(log: &log::Read) -> u64 {
    log.records
        .iter()
        .find_map(|r| match &r.event {
            log::Event::Message { text } => text
                .strip_prefix("every drive follows its target after ")?
                .split(' ')
                .next()?
                .parse()
                .ok(),
            _ => None,
        })
        .expect("the log has the session's Enabled event")
}

/// A log file in `dir`, and how to read it back.
fn log_in(dir: &tempfile::TempDir) -> (ExecLog, std::path::PathBuf) {
    let path = dir.path().join("exec.jsonl");
    (ExecLog::append(&path).unwrap(), path)
}

fn node(id: u8) -> NodeId {
    NodeId::new(id).unwrap()
}

/// `position` in drive counts, rounded.
fn counts(position: SimPosition, scale: [f64; 3]) -> [i64; 3] {
    let a = position.to_array();
    std::array::from_fn(|k| (a[k] * scale[k]).round() as i64)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_short_job_runs_over_the_wire_and_every_set_point_executes_once() {
    every_set_point_executes_once(DriveMode::Csp).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn in_interpolated_position_mode_every_set_point_executes_once_too() {
    every_set_point_executes_once(DriveMode::Ip).await;
}

/// A short job over the wire with the drives in `mode`: every set-point executed once, in
/// order, each cycle one period, the drives disabled at the path's end.
async fn every_set_point_executes_once(mode: DriveMode) {
    let profile = profile();
    let drives = DriveSettings {
        mode,
        ..drive_settings(&profile)
    };
    let program = program(&profile);
    let expected: SetPoints = sample(
        &program,
        Position::known(0.0, 0.0, 0.0),
        &SampleConfig::for_drives(&profile, &drives),
    )
    .unwrap();
    let bus = bus(&profile, &drives);
    let dir = tempfile::tempdir().unwrap();
    let (mut log, log_path) = log_in(&dir);
    let mut seen = Seen::default();
    let began = Instant::now();
    let told = Arc::new(Mutex::new(Vec::new()));
    let options = CanOptions {
        on_progress: Some(Box::new({
            let told = Arc::clone(&told);
            move |p: &Progress| told.lock().unwrap().push(p.clone())
        })),
        ..options(&profile, &drives)
    };
    let outcome = run_on_wire(&bus, &program, options, &mut log, |e| seen.record(e))
        .await
        .expect("the run is carried out");
    eprintln!(
        "{} set-points over the wire in {:?}",
        outcome.setpoints,
        began.elapsed()
    );

    assert!(outcome.completed, "{:?}", outcome.stop);
    assert_eq!(outcome.stop, None);
    // Progress was told once a second of the session's time (250 cycles of 4 ms), whether
    // the set-points moved or not (the boot-up tells none sent), in order, with the machine
    // time the rest takes, and last at the end. Once the set-points run, one a cycle at
    // 100 %, a second between two tells is 250 of them.
    let told = told.lock().unwrap();
    let period = drives.period();
    assert!(told.len() >= outcome.setpoints / 250, "{}", told.len());
    let last = told.len() - 1;
    for (k, pair) in told.windows(2).enumerate() {
        let step = pair[1].done - pair[0].done;
        if pair[0].done > 0 && k + 1 < last {
            assert_eq!(step, 250, "tells {k} and {}", k + 1);
        } else {
            assert!(step <= 250, "tells {k} and {}: {step}", k + 1);
        }
    }
    for p in told.iter() {
        assert_eq!(p.total, outcome.setpoints);
        assert_eq!(p.unit, Unit::SetPoints);
        assert_eq!(p.left, Some(period * (p.total - p.done) as u32));
    }
    assert_eq!(
        told.last().map(|p| (p.done, p.left)),
        Some((outcome.setpoints, Some(Duration::ZERO)))
    );
    assert!(outcome.unconfirmed.is_empty());
    assert_eq!(outcome.sent, outcome.setpoints);
    assert_eq!(outcome.setpoints, expected.points.len());
    assert_eq!(outcome.start, [0.0; 3], "the drives stood at the origin");
    // With the clock locked to SYNC no cycle can be late: each is one period of the
    // session's time.
    assert_eq!(outcome.late_cycles, 0);

    // Every set-point executed once, in order, by the SYNC after it was sent (Event::Enabled):
    // the bus's cycle `first + k + 1` has set-point k's targets.
    let read = log::read(&log_path).unwrap();
    let first = enabled_syncs(&read);
    let scale = drives.counts_per_unit();
    let executed = &seen.executed;
    let total = expected.points.len();
    assert!(
        executed.len() as u64 > first + total as u64,
        "{} cycles executed for {total} set-points after {first} SYNCs",
        executed.len()
    );
    for (k, point) in expected.points.iter().enumerate() {
        let block = &executed[first as usize + k];
        assert_eq!(block.line, first + k as u64 + 1);
        let target = counts(block.target, scale);
        for axis in 0..3 {
            assert!(
                target[axis].abs_diff(point[axis]) <= 1,
                "set-point {k}: executed target {target:?}, set-point {point:?}"
            );
        }
    }
    // Before the set-points the drives were held where they stood; after them, on the
    // path's end until they were disabled: no cycle carried any other target.
    for block in &executed[..first as usize] {
        assert_eq!(counts(block.target, scale), expected.start, "{block:?}");
    }
    for block in &executed[first as usize + total..] {
        let target = counts(block.target, scale);
        assert!((0..3).all(|k| target[k].abs_diff(expected.end()[k]) <= 1));
    }
    // Every cycle, the SYNC-locked drives' and the session's, spans exactly the period.
    let period = drives.period().as_secs_f64();
    for block in executed {
        let span = block.end_time - block.start_time;
        assert!(
            (span - period).abs() < 1e-9,
            "cycle {}: {span} s",
            block.line
        );
    }
    // The job ended where the program does, every drive disabled (Switch on disabled).
    assert_eq!(counts(executed.last().unwrap().to, scale), expected.end());
    for drive in lock(&bus).drives() {
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    }
}

/// What a run that was acted on gave.
struct Acted {
    outcome: CanOutcome,
    seen: Seen,
    log: log::Read,
    bus: SharedBus,
    /// SYNCs the bus had taken when the test acted: the server hands the bus a read's
    /// bytes whole, and a read may carry several cycles, so this may be a few past `at`.
    at_sync: u64,
}

/// Runs the job, calling `act` on the bus once the cycle `at` has executed (the drives
/// then well into the set-points: the spin-up hold alone is 500 cycles).
async fn run_and_act_at(at: u64, act: impl FnOnce(&mut Bus)) -> Acted {
    let profile = profile();
    let drives = drive_settings(&profile);
    let program = program(&profile);
    let bus = bus(&profile, &drives);
    let dir = tempfile::tempdir().unwrap();
    let (mut log, log_path) = log_in(&dir);
    let mut seen = Seen::default();
    let mut act = Some(act);
    let mut at_sync = None;
    let handle = Arc::clone(&bus);
    let began = Instant::now();
    let outcome = run_on_wire(
        &bus,
        &program,
        options(&profile, &drives),
        &mut log,
        |event| {
            seen.record(event);
            if matches!(event, BusEvent::Executed(b) if b.line == at) {
                // serve_slcan calls this with the bus unlocked.
                let mut bus = lock(&handle);
                at_sync = Some(bus.syncs());
                (act.take().expect("once"))(&mut bus);
            }
        },
    )
    .await
    .expect("a stopped run is an outcome, not an error");
    eprintln!("stopped after {:?}: {:?}", began.elapsed(), outcome.stop);
    let at_sync = at_sync.unwrap_or_else(|| {
        panic!(
            "the job ended before cycle {at}: {:?}; the drives' NMT states (node, state, \
             bus time): {:?}; the bridge's log: {:?}",
            outcome.stop,
            seen.nmt,
            std::fs::read_to_string(&log_path)
        )
    });
    Acted {
        outcome,
        seen,
        log: log::read(&log_path).unwrap(),
        bus,
        at_sync,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pulled_cable_stops_the_job_with_heartbeat_lost_naming_the_node() {
    let profile = profile();
    let drives = drive_settings(&profile);
    let Acted {
        outcome,
        seen,
        log,
        bus,
        at_sync: pulled_at,
    } = run_and_act_at(700, |bus| assert!(bus.pull_cable(2))).await;

    assert!(!outcome.completed);
    let timeout = options(&profile, &drives).session.heartbeat_timeout;
    assert_eq!(
        outcome.stop,
        Some(StopReason::HeartbeatLost {
            node: node(2),
            axis: Axis::Z,
            timeout
        })
    );
    let text = outcome.stop.as_ref().unwrap().to_string();
    assert!(
        text.starts_with("node 2 (Z) heartbeat lost: none for 1s"),
        "{text}"
    );
    // Z, unheard since, is the one drive not confirmed disabled.
    assert_eq!(outcome.unconfirmed, [node(2)]);

    // The session went on cycling for the stop: X and C were sent quick stop, held until
    // they stood, then disable voltage, and show Switch on disabled (CiA 402: Operation
    // enabled → Quick stop active → Switch on disabled).
    let stop_sync = seen
        .entered(1, PowerState::QuickStopActive)
        .expect("X was quick-stopped");
    assert_eq!(
        seen.entered(3, PowerState::QuickStopActive),
        Some(stop_sync)
    );
    {
        let bus = lock(&bus);
        let [x, _, c] = bus.drives();
        assert_eq!(x.power_state(), PowerState::SwitchOnDisabled);
        assert_eq!(c.power_state(), PowerState::SwitchOnDisabled);
    }

    // The consumer (CiA 301) declares the node lost once nothing was heard for the
    // consumer time: not before its last heartbeat (at most one producer period before the
    // pull) is that old, and no later than that plus the cycles the drives' answers lag
    // in lockstep and a cycle's rounding each way.
    let period = drives.period();
    let cycles = |d: Duration| d.as_secs_f64() / period.as_secs_f64();
    let heartbeat = Duration::from_millis(drives.heartbeat_ms.into());
    let after = stop_sync - pulled_at;
    eprintln!("cable pulled after SYNC {pulled_at}, quick stop with SYNC {stop_sync}");
    let earliest = cycles(timeout - heartbeat) - 1.0;
    let latest = cycles(timeout) + (LOCKSTEP_WINDOW + 2) as f64;
    assert!(
        (after as f64) >= earliest && (after as f64) <= latest,
        "stopped {after} cycles after the pull: expected {earliest}..={latest}"
    );

    // No set-point went out with the stop or after it: the session sent exactly those
    // due before the stop's SYNC, and from that SYNC on every drive was held on the last
    // set-point it had.
    let first = enabled_syncs(&log);
    assert_eq!(outcome.sent as u64, stop_sync - 1 - first);
    assert!(outcome.sent < outcome.setpoints);
    let executed = &seen.executed;
    let last_setpoint = executed[(stop_sync - 2) as usize].target;
    assert_eq!(executed[(stop_sync - 2) as usize].line, stop_sync - 1);
    for block in &executed[(stop_sync - 1) as usize..] {
        assert_eq!(block.target, last_setpoint, "cycle {}", block.line);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drive_fault_emcy_stops_the_job_and_says_why() {
    let Acted {
        outcome,
        seen,
        log,
        bus,
        at_sync: faulted_at,
    } = run_and_act_at(700, |bus| assert!(bus.external_fault(3, 0x8611))).await;

    assert!(!outcome.completed);
    assert_eq!(
        outcome.stop,
        Some(StopReason::Emergency {
            node: node(3),
            axis: Axis::C,
            code: 0x8611,
            meaning: "following error"
        })
    );
    assert_eq!(
        outcome.stop.as_ref().unwrap().to_string(),
        "node 3 (C) emergency 0x8611: following error"
    );
    // The emergency in the log as the session reported it, and the run's end with why.
    let messages: Vec<&str> = log
        .records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Message { text } => Some(text.as_str()),
            _ => None,
        })
        .collect();
    assert!(
        messages
            .iter()
            .any(|m| m.starts_with("node 3 emergency 0x8611 (following error)")),
        "{messages:?}"
    );
    assert!(log.records.iter().any(|r| matches!(
        &r.event,
        log::Event::End { completed: false, reason: Some(reason) }
            if reason.contains("0x8611") && reason.contains("following error")
    )));

    // The EMCY goes out at once, ahead of the acknowledgements of the cycles after the
    // fault. Having those of the cycles before it, the session may have sent the lockstep
    // window of cycles beyond the fault and one more before it waits for the next
    // acknowledgement and hears the EMCY; it quick-stops X and Z with its next cycle.
    let stop_sync = seen
        .entered(1, PowerState::QuickStopActive)
        .expect("X was quick-stopped");
    assert_eq!(
        seen.entered(2, PowerState::QuickStopActive),
        Some(stop_sync)
    );
    let after = stop_sync - faulted_at;
    eprintln!("fault after SYNC {faulted_at}, quick stop with SYNC {stop_sync}");
    assert!(
        (1..=LOCKSTEP_WINDOW + 2).contains(&after),
        "stopped {after} cycles after the fault"
    );
    let first = enabled_syncs(&log);
    assert_eq!(outcome.sent as u64, stop_sync - 1 - first);

    // C stays faulted for someone to look at (faults are not reset); X and Z are disabled;
    // all three confirmed.
    {
        let bus = lock(&bus);
        let [x, z, c] = bus.drives();
        assert_eq!(c.power_state(), PowerState::Fault);
        assert_eq!(x.power_state(), PowerState::SwitchOnDisabled);
        assert_eq!(z.power_state(), PowerState::SwitchOnDisabled);
    }
    assert!(outcome.unconfirmed.is_empty(), "{:?}", outcome.unconfirmed);
}

/// An slcan adapter on `port` that takes every command but the bit rate (`S…`), which it
/// refuses with BEL, as one does that is open; returns the commands it got.
async fn refusing_adapter(mut port: tokio_serial::SerialStream) -> Vec<String> {
    let mut heard = Vec::new();
    let mut line = Vec::new();
    let mut buf = [0u8; 256];
    loop {
        let n = match port.read(&mut buf).await {
            Ok(0) | Err(_) => return heard,
            Ok(n) => n,
        };
        for &byte in &buf[..n] {
            if byte != b'\r' {
                line.push(byte);
                continue;
            }
            let command = String::from_utf8_lossy(&line).into_owned();
            line.clear();
            let answer: &[u8] = if command.starts_with('S') {
                b"\x07"
            } else {
                b"\r"
            };
            heard.push(command);
            if port.write_all(answer).await.is_err() {
                return heard;
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_adapter_refusing_the_bit_rate_is_a_clear_error() {
    let profile = profile();
    let drives = drive_settings(&profile);
    let (master, slave, path) = pty();
    let adapter = tokio::spawn(refusing_adapter(master));
    let link = slcan(path);
    let error = tokio::time::timeout(
        Duration::from_secs(10),
        stream_can(
            &link,
            &tiny_program(),
            options(&profile, &drives),
            &mut ExecLog::discard(),
        ),
    )
    .await
    .expect("the bridge gives up at once")
    .expect_err("a refused bit rate is an error");
    assert!(
        matches!(&error, CanError::Refused { command } if command == "S8"),
        "{error:?}"
    );
    assert_eq!(error.to_string(), "the slcan adapter refused S8");
    drop(slave);
    adapter.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_silent_port_is_a_clear_error_naming_what_was_awaited() {
    let profile = profile();
    let drives = drive_settings(&profile);
    // The master end held open and never read: nothing answers.
    let (master, slave, path) = pty();
    let link = slcan(path.clone());
    let answer_timeout = Duration::from_millis(300);
    let options = CanOptions {
        answer_timeout,
        ..options(&profile, &drives)
    };
    let began = Instant::now();
    let error = tokio::time::timeout(
        Duration::from_secs(10),
        stream_can(&link, &tiny_program(), options, &mut ExecLog::discard()),
    )
    .await
    .expect("the bridge gives up after its answer timeout")
    .expect_err("a silent adapter is an error");
    let waited_wall = began.elapsed();
    match &error {
        CanError::Silent { what, waited } => {
            assert_eq!(*waited, answer_timeout);
            assert!(what.contains(&path), "{what}");
            assert!(what.contains("answering a command"), "{what}");
        }
        other => panic!("expected Silent, got {other:?}"),
    }
    assert_eq!(
        error.to_string(),
        format!(
            "slcan adapter {path} (115200 baud, CAN at 1000 kbit/s), answering a command: no \
             answer within 300ms"
        )
    );
    // It waited for the first command's answer (the close), then gave up: a timer never
    // fires early, and how much later a busy host lets it fire is no verdict (the outer
    // 10 s says it gave up at all).
    assert!(waited_wall >= answer_timeout, "{waited_wall:?}");
    drop((master, slave));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_adapter_left_open_by_an_earlier_run_is_closed_and_reopened() {
    let profile = profile();
    let drives = drive_settings(&profile);
    let bus = bus(&profile, &drives);
    {
        // An earlier run opened the channel and went away: a new bit rate is refused
        // while it is open (BEL), as a real adapter does.
        let mut bus = lock(&bus);
        bus.receive(b"S8\rO\r");
        assert_eq!(bus.take_output(), b"\r\r");
        bus.receive(b"S8\r");
        assert_eq!(bus.take_output(), b"\x07");
    }
    let outcome = run_on_wire(
        &bus,
        &tiny_program(),
        options(&profile, &drives),
        &mut ExecLog::discard(),
        |_| {},
    )
    .await
    .expect("the bridge closes the channel before setting the bit rate");
    assert!(outcome.completed, "{:?}", outcome.stop);
    assert_eq!(outcome.sent, outcome.setpoints);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn lockstep_over_socketcan_is_refused() {
    let profile = profile();
    let drives = drive_settings(&profile);
    // No such interface: the refusal must come before any attempt to open it.
    let link = CanLink::SocketCan {
        interface: "whirlnone0".to_owned(),
    };
    let error = stream_can(
        &link,
        &tiny_program(),
        options(&profile, &drives),
        &mut ExecLog::discard(),
    )
    .await
    .expect_err("a SYNC-locked clock needs an slcan adapter");
    assert!(
        matches!(&error, CanError::Lockstep(name) if name == "socketcan whirlnone0"),
        "{error:?}"
    );
    assert_eq!(
        error.to_string(),
        "a SYNC-locked clock needs an slcan adapter's acknowledgements; socketcan whirlnone0 \
         has none"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn socketcan_runs_where_an_interface_exists() {
    let Some(interface) = ["vcan0", "can0"]
        .into_iter()
        .find(|name| std::path::Path::new("/sys/class/net").join(name).exists())
    else {
        eprintln!("skipped: no CAN interface (this kernel has no CAN support)");
        return;
    };
    let operstate = std::fs::read_to_string(format!("/sys/class/net/{interface}/operstate"))
        .unwrap_or_default();
    if !matches!(operstate.trim(), "up" | "unknown") {
        eprintln!(
            "skipped: {interface} is {} (ip link set {interface} up)",
            operstate.trim()
        );
        return;
    }
    let profile = profile();
    let drives = drive_settings(&profile);
    let link = CanLink::SocketCan {
        interface: interface.to_owned(),
    };
    let answer_timeout = Duration::from_millis(300);
    let options = CanOptions {
        clock: CanClock::Wall,
        answer_timeout,
        ..options(&profile, &drives)
    };
    let error = tokio::time::timeout(
        Duration::from_secs(10),
        stream_can(&link, &tiny_program(), options, &mut ExecLog::discard()),
    )
    .await
    .expect("the position read times out")
    .expect_err("no drives answer on this bus");
    // It opened the interface and asked X's drive (node 1) for its position first.
    assert!(
        matches!(&error, CanError::Position { node, reason }
            if node.get() == 1 && reason.contains("no answer within 300ms")),
        "{error:?}"
    );
}
