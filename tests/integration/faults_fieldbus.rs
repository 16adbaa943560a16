//! Faults on the fieldbus transports, end to end against `whirl-sim` in its own process:
//! another client holding the Modbus controller, the simulator killed mid-stream, the
//! caller's stop over Modbus and CAN, a log that can no longer be written, and a Modbus
//! controller found held (a resume) or running (another program) at the start.
//!
//! Each checks what the rules of `docs/modbus.md` and `docs/canopen.md` promise from the
//! side that did not do it: the controller's registers read by a client of the test's own
//! (tokio-modbus), the simulator's record of what it executed, the drives' power states in
//! its log, and the bridge's log and exit.

use std::ffi::OsStr;
use std::io::Read;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use tokio_modbus::client::{Context, Reader, Writer};
use tokio_modbus::Slave;
use whirl::config::machine::MachineProfile;
use whirl::log::{Event, ExecLog, Record};
use whirl::post::modbus::segment_moves;
use whirl::program::reentry;
use whirl::protocol::canopen::session::StopReason;
use whirl::transport::modbus::ModbusLink;
use whirl::transport::{control, stream, Link, Outcome, Posted, RunOptions, TransportKind};

use crate::util::{self, Sim};

// docs/modbus.md's registers and values, written here from the document.
const STATUS: u16 = 16;
const STATUS_LEN: u16 = 19;
const CONTROL: u16 = 32;
const RUN: u16 = 1;
const HOLD: u16 = 2;
const RUNNING: u16 = 1;
const HELD: u16 = 2;

/// `whirl-sim --can-slcan` at `link` with `profile`'s drives, logging to `log`.
fn can_sim(link: &Path, profile: &Path, log: &Path) -> Sim {
    Sim::serving(
        OsStr::new("--can-slcan"),
        link,
        &[
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--idle-exit"),
            OsStr::new("30"),
            OsStr::new("--log"),
            log.as_os_str(),
        ],
    )
}

/// A program of `n` feeds of 5 mm in X and back at 3000 mm/min (0.1 s each), then M2.
fn back_and_forth(n: usize) -> String {
    let mut text = "G21 G90 G94\nG0 X0 Z0 C0\n".to_owned();
    for _ in 0..n {
        text.push_str("G1 X5 F3000\nG1 X0 F3000\n");
    }
    text + "M2\n"
}

async fn client(address: SocketAddr) -> Context {
    tokio_modbus::client::tcp::connect_slave(address, Slave(1))
        .await
        .expect("a client connects")
}

/// `STATE`, `EXECUTED_SEQ` (high word first, the simulator's order) and `CONTROL`.
async fn status(ctx: &mut Context) -> (u16, u32, u16) {
    let r = ctx
        .read_holding_registers(STATUS, STATUS_LEN)
        .await
        .expect("the link")
        .expect("no exception");
    let executed = (u32::from(r[6]) << 16) | u32::from(r[7]);
    (r[0], executed, r[usize::from(CONTROL - STATUS)])
}

/// Waits until the controller reports `segments` executed.
async fn executed_at_least(ctx: &mut Context, segments: u32) {
    let since = Instant::now();
    while status(ctx).await.1 < segments {
        assert!(
            since.elapsed() < Duration::from_secs(30),
            "the stream never got going"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// The JSON events of a log file (the bridge's or the simulator's); torn lines skipped.
fn events(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// The bridge log's last `end` event: (completed, reason).
fn ended(log: &Path) -> Option<(bool, String)> {
    events(log).iter().rev().find_map(|e| {
        (e["event"] == "end").then(|| {
            (
                e["completed"].as_bool().unwrap(),
                e["reason"].as_str().unwrap_or("").to_owned(),
            )
        })
    })
}

/// The highest sequence number among the segments the Modbus simulator completed.
fn last_completed_segment(sim_log: &Path) -> u64 {
    events(sim_log)
        .iter()
        .filter(|e| e["event"] == "executed" && e["completed"] == true)
        .filter_map(|e| e["n"].as_u64())
        .max()
        .unwrap_or(0)
}

/// Waits for `child` at most `limit`; its status, or it is killed and `None`.
fn wait_for(child: &mut Child, limit: Duration) -> Option<ExitStatus> {
    let since = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status);
        }
        if since.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn stderr_of(child: &mut Child) -> String {
    let mut text = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut text)
        .unwrap();
    text
}

/// `whirl stream PROGRAM --transport modbus-tcp --port ADDRESS --log LOG EXTRA…`, started.
fn whirl_stream_modbus(program: &Path, address: SocketAddr, log: &Path, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", util::records_db())
        .args([
            OsStr::new("stream"),
            program.as_os_str(),
            // Written here, not planned: it carries no provenance.
            OsStr::new("--no-provenance-check"),
            OsStr::new("--transport"),
            OsStr::new("modbus-tcp"),
            OsStr::new("--port"),
            OsStr::new(&address.to_string()),
            OsStr::new("--log"),
            log.as_os_str(),
        ])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("whirl starts")
}

#[test]
fn another_clients_hold_over_modbus_is_a_stall_that_ends_the_run_held() {
    let dir = tempfile::tempdir().unwrap();
    let (_sim, address) = util::modbus_tcp_sim(&dir.path().join("sim.jsonl"));
    let program = util::write(dir.path(), "long.nc", &back_and_forth(100));
    let log = dir.path().join("exec.jsonl");
    let stall = Duration::from_secs(2);
    let mut whirl = whirl_stream_modbus(&program, address, &log, &["--stall-timeout", "2"]);
    let rt = tokio::runtime::Runtime::new().unwrap();
    let mut other = rt.block_on(client(address));
    // Mid-stream, another client sets HOLD in CONTROL: a rising edge, a feed hold.
    let held_at = rt.block_on(async {
        executed_at_least(&mut other, 5).await;
        let (_, _, control) = status(&mut other).await;
        other
            .write_single_register(CONTROL, control | HOLD)
            .await
            .unwrap()
            .unwrap();
        Instant::now()
    });
    // The bridge gives up a stall timeout after the controller last changed (the hold's
    // slowing down), holds, and ends; a few seconds' margin for the stand and the exit.
    let exit = wait_for(&mut whirl, stall + Duration::from_secs(6))
        .expect("the bridge gave up within the stall timeout and a margin");
    let took = held_at.elapsed();
    assert!(took >= stall, "{took:?}");
    assert!(!exit.success());
    let stderr = stderr_of(&mut whirl);
    assert!(
        stderr.contains("nothing new from the controller for 2 s: held"),
        "{stderr}"
    );
    let (completed, reason) = ended(&log).expect("the log has an end");
    assert!(!completed);
    assert!(
        reason.contains("nothing new from the controller"),
        "{reason}"
    );
    // The controller is left held, RUN cleared: it takes nothing more, and its watchdog,
    // disarmed, raises no alarm now that the bridge is gone.
    let (state, _, control) = rt.block_on(status(&mut other));
    assert_eq!(state, HELD);
    assert_eq!(control & RUN, 0);
}

#[test]
fn a_killed_modbus_simulator_ends_the_run_with_an_end_that_names_the_link() {
    let dir = tempfile::tempdir().unwrap();
    let (mut sim, address) = util::modbus_tcp_sim(&dir.path().join("sim.jsonl"));
    let program = util::write(dir.path(), "long.nc", &back_and_forth(100));
    let log = dir.path().join("exec.jsonl");
    let mut whirl = whirl_stream_modbus(&program, address, &log, &[]);
    let since = Instant::now();
    while events(&log).iter().filter(|e| e["event"] == "sent").count() < 10 {
        assert!(
            since.elapsed() < Duration::from_secs(30),
            "the stream never got going"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    sim.0.kill().unwrap();
    sim.0.wait().unwrap();
    // The bridge's reconnection attempts (eight, backing off to 2 s) run out in seconds.
    let exit = wait_for(&mut whirl, Duration::from_secs(30)).expect("the bridge gave up");
    assert!(!exit.success());
    let stderr = stderr_of(&mut whirl);
    assert!(
        stderr.contains(&format!("cannot reach Modbus TCP {address}")),
        "{stderr}"
    );
    let (completed, reason) = ended(&log).expect("the log has an end");
    assert!(!completed);
    assert!(
        reason.contains(&format!("cannot reach Modbus TCP {address}")),
        "{reason}"
    );
}

#[test]
fn a_modbus_controller_that_cannot_be_reached_gets_an_end_in_the_log() {
    let dir = tempfile::tempdir().unwrap();
    // A port nobody listens on: bound, then closed.
    let address = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    let program = util::write(dir.path(), "short.nc", &back_and_forth(1));
    let log = dir.path().join("exec.jsonl");
    let mut whirl = whirl_stream_modbus(&program, address, &log, &[]);
    let exit = wait_for(&mut whirl, Duration::from_secs(30)).expect("the bridge gave up");
    assert!(!exit.success());
    let (completed, reason) = ended(&log).expect("the log has an end");
    assert!(!completed);
    assert!(reason.contains("cannot reach"), "{reason}");
}

/// The simulated machine's profile, as whirl-sim serves it by default.
fn sim_machine() -> MachineProfile {
    MachineProfile::load(&util::root().join("machine-profiles/sim.toml")).unwrap()
}

fn modbus_link(address: SocketAddr) -> Link {
    Link::Modbus {
        link: ModbusLink::Tcp(address),
        unit: 1,
        timeout: Duration::from_millis(500),
    }
}

/// `program` posted as it stands (re-entered programs have no text of their own).
fn posted(name: &str, program: whirl::program::Program) -> Posted {
    let move_lines = (1..=program.moves.len()).collect();
    Posted {
        name: name.to_owned(),
        lines: Vec::new(),
        program,
        move_lines,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_over_modbus_holds_the_controller_and_the_next_run_starts_from_held() {
    let dir = tempfile::tempdir().unwrap();
    let sim_log = dir.path().join("sim.jsonl");
    let (_sim, address) = util::modbus_tcp_sim(&sim_log);
    let machine = sim_machine();
    let first = Posted::read("long.nc", &back_and_forth(30), &machine).unwrap();
    let link = modbus_link(address);
    let (operator, commands) = control::control();
    let log = ExecLog::memory();
    let mut watcher = client(address).await;
    // The stream's future is not Send (it borrows the caller's progress callback), so it
    // runs on this task, beside the operator's.
    let mut writer = log.clone();
    let (outcome, ()) = tokio::join!(
        stream(
            &link,
            &first,
            &machine,
            RunOptions::default(),
            commands,
            &mut writer,
        ),
        async {
            executed_at_least(&mut watcher, 5).await;
            assert!(operator.stop("the test's stop"));
        }
    );
    let outcome = outcome.expect("a stop is an outcome");
    let Outcome::Modbus(o) = &outcome else {
        panic!("{outcome:?}");
    };
    assert!(!o.completed);
    let stopped = o.stopped.as_deref().unwrap_or_default();
    assert!(stopped.contains("the test's stop"), "{o:?}");
    assert_eq!(outcome.stop().as_deref(), Some(stopped));
    // Held, RUN cleared.
    let (state, executed, control_word) = status(&mut watcher).await;
    assert_eq!(state, HELD);
    assert_eq!(control_word & RUN, 0);
    // The resume point is the move of the first segment the controller did not complete,
    // by its own record: segment S (0-based) has sequence number S + 1.
    let last = last_completed_segment(&sim_log);
    assert_eq!(u64::from(executed), last);
    let moves = segment_moves(&first.program);
    let resume = o.resume_move.expect("a resume point");
    assert_eq!(resume, moves[last as usize]);
    assert!(resume > 0 && resume < first.program.moves.len());
    // The run ends with the program line to resume at, then its End, in the serial
    // transport's order: the line is the resume move's (1-based).
    let records = log.records();
    let n = records.len();
    assert!(
        matches!(records[n - 2].event, Event::ResumeAt { line, .. } if line == first.move_lines[resume]),
        "{:?}",
        &records[n - 2..]
    );
    assert!(
        matches!(&records[n - 1].event, Event::End { completed: false, reason: Some(r) } if r.contains("the test's stop")),
        "{:?}",
        &records[n - 2..]
    );
    // The next run re-enters along the path on the held controller: its ring flushed, it
    // runs to the end.
    let resumed = posted(
        "resumed",
        reentry::resumed(&first.program, resume).expect("a re-entry"),
    );
    let (_keep, commands) = control::control();
    // Meanwhile a third run finds it running another program: refused, nothing written.
    let mut writer = log.clone();
    let (finished, ()) = tokio::join!(
        stream(
            &link,
            &resumed,
            &machine,
            RunOptions::default(),
            commands,
            &mut writer,
        ),
        async {
            let since = Instant::now();
            while status(&mut watcher).await.0 != RUNNING {
                assert!(
                    since.elapsed() < Duration::from_secs(30),
                    "the resumed run never ran"
                );
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
            let (_third_control, third_commands) = control::control();
            let third = stream(
                &link,
                &first,
                &machine,
                RunOptions::default(),
                third_commands,
                &mut ExecLog::discard(),
            )
            .await
            .expect("a refusal is an outcome");
            let refused = third.stop().expect("refused");
            assert!(
                refused.contains("running (another program is under way)")
                    && refused.contains("nothing was written"),
                "{refused}"
            );
        }
    );
    let finished = finished.expect("the resumed run");
    assert!(finished.completed(), "{finished:?}");
}

fn can_machine() -> (PathBuf, MachineProfile) {
    let path = util::root().join("machine-profiles/canopen-drives.toml");
    let machine = MachineProfile::load(&path).unwrap();
    (path, machine)
}

/// The CAN drives' profile written to `dir`, its heartbeat watched for a second rather than
/// 150 ms. The drives and the bridge run in two processes on the wall clock, on a host
/// whose two cores other builds keep busy: the scheduler may leave either without a core
/// for longer than a bus ever goes silent (with both cores loaded, a heartbeat of 50 ms
/// was seen missing for more than 150 ms), and these tests are about stops and resumes,
/// not supervision. A second is twenty heartbeats; a lost heartbeat is tested on the
/// drives' own clock (`can_wire.rs`, `can_session.rs`).
fn patient_can_machine(dir: &Path) -> (PathBuf, MachineProfile) {
    let (path, _) = can_machine();
    let watched = "heartbeat_timeout_ms = 150";
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.contains(watched),
        "the example profile's heartbeat timeout"
    );
    let path = util::write(
        dir,
        "drives.toml",
        &text.replace(watched, "heartbeat_timeout_ms = 1000"),
    );
    let machine = MachineProfile::load(&path).unwrap();
    (path, machine)
}

/// The drives' power states in the CAN simulator's log, in order, for `node`.
fn power_states(sim_log: &Path, node: u64) -> Vec<String> {
    events(sim_log)
        .iter()
        .filter(|e| e["event"] == "drive" && e["kind"] == "power" && e["node"] == node)
        .map(|e| e["state"].as_str().unwrap().to_owned())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stop_over_can_holds_the_path_then_disables_the_drives_gently() {
    let dir = tempfile::tempdir().unwrap();
    let slcan = dir.path().join("slcan");
    let sim_log = dir.path().join("sim.jsonl");
    let (profile, machine) = patient_can_machine(dir.path());
    let _sim = can_sim(&slcan, &profile, &sim_log);
    // 20 mm of Z at 600 mm/min: two seconds.
    let text = "G21 G90 G94\nG0 X1 Z0 C0\nG1 Z-20 F600\nG0 X0\n";
    let posted = Posted::read("z.nc", text, &machine).unwrap();
    let cut = posted
        .move_lines
        .iter()
        .position(|&line| line == 3)
        .expect("the Z move");
    let link = Link::resolve(
        &machine,
        Some(TransportKind::CanSlcan),
        Some(slcan.to_str().unwrap().to_owned()),
        None,
    )
    .unwrap();
    let (operator, commands) = control::control();
    let log = ExecLog::memory();
    let started = |records: &[Record]| {
        records.iter().any(|r| {
            matches!(&r.event, Event::Message { text } if text.contains("the set-points start"))
        })
    };
    let mut writer = log.clone();
    let (outcome, ()) = tokio::join!(
        stream(
            &link,
            &posted,
            &machine,
            RunOptions::default(),
            commands,
            &mut writer,
        ),
        async {
            let since = Instant::now();
            let mut follow = util::Follow::new(&log);
            while !started(follow.look()) {
                assert!(
                    since.elapsed() < Duration::from_secs(30),
                    "the job never started"
                );
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
            tokio::time::sleep(Duration::from_millis(700)).await;
            assert!(operator.stop("the test's stop"));
        }
    );
    let outcome = outcome.expect("a stop is an outcome");
    let Outcome::Can(o) = &outcome else {
        panic!("{outcome:?}");
    };
    assert!(!o.completed);
    assert_eq!(
        o.stop,
        Some(StopReason::Interrupted {
            why: "the test's stop".into()
        })
    );
    assert!(o.unconfirmed.is_empty(), "{o:?}");
    // The drives stood inside the Z move: it is where to resume.
    assert_eq!(o.resume_move, Some(cut));
    let stood = events(&sim_log)
        .iter()
        .rev()
        .find(|e| e["event"] == "executed")
        .map(|e| e["to"]["z"].as_f64().unwrap())
        .unwrap();
    assert!(stood < 0.0 && stood > -20.0, "{stood}");
    // Each drive went from Operation enabled to Switch on disabled, never through quick
    // stop active.
    for node in 1..=3 {
        let states = power_states(&sim_log, node);
        assert!(!states.iter().any(|s| s == "QuickStopActive"), "{states:?}");
        assert_eq!(states.last().map(String::as_str), Some("SwitchOnDisabled"));
        assert!(states.iter().any(|s| s == "OperationEnabled"), "{states:?}");
    }
    let records = log.records();
    assert!(records.iter().any(|r| matches!(&r.event, Event::Message { text } if text.contains("every drive confirmed disabled"))));
    // Where to resume, then the End, as the serial transport logs them (docs/streaming.md):
    // the line of the Z move.
    let n = records.len();
    assert!(
        matches!(records[n - 2].event, Event::ResumeAt { line: 3, .. }),
        "{:?}",
        &records[n - 2..]
    );
    assert!(matches!(
        &records[n - 1].event,
        Event::End {
            completed: false,
            reason: Some(_)
        }
    ));
}

/// `whirl ARGS…` run by bash with the files it writes limited to `kib` KiB and SIGXFSZ
/// ignored (as a full disk would: the write fails with EFBIG instead of killing it).
fn whirl_with_file_limit(kib: u64, args: &[&OsStr]) -> Child {
    Command::new("bash")
        .arg("-c")
        .arg(format!("ulimit -f {kib}; trap '' XFSZ; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_whirl"))
        // Its records beside its log (the last argument): the tests' shared database is
        // longer than the file size limit.
        .env(
            "WHIRL_DB",
            Path::new(args[args.len() - 1]).with_file_name("runs.sqlite"),
        )
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bash runs whirl")
}

/// A log already `kib` KiB less `room` bytes long: earlier runs' lines.
fn nearly_full_log(path: &Path, kib: u64, room: usize) {
    let line = "{\"t\":0.0,\"event\":\"message\",\"text\":\"an earlier run\"}\n";
    let size = kib as usize * 1024 - room;
    let mut text = line.repeat(size / line.len());
    text.push_str(&" ".repeat(size - text.len() - 1));
    text.push('\n');
    std::fs::write(path, text).unwrap();
}

#[test]
fn a_log_that_fails_mid_stream_over_modbus_holds_the_controller_first() {
    let dir = tempfile::tempdir().unwrap();
    let (_sim, address) = util::modbus_tcp_sim(&dir.path().join("sim.jsonl"));
    let program = util::write(dir.path(), "long.nc", &back_and_forth(100));
    let log = dir.path().join("exec.jsonl");
    // Room for the start, the ring's first fill and a few seconds of status reads and
    // segments.
    nearly_full_log(&log, 64, 16 * 1024);
    let mut whirl = whirl_with_file_limit(
        64,
        &[
            OsStr::new("stream"),
            program.as_os_str(),
            // Written here, not planned: it carries no provenance.
            OsStr::new("--no-provenance-check"),
            OsStr::new("--transport"),
            OsStr::new("modbus-tcp"),
            OsStr::new("--port"),
            OsStr::new(&address.to_string()),
            OsStr::new("--log"),
            log.as_os_str(),
        ],
    );
    let exit = wait_for(&mut whirl, Duration::from_secs(30)).expect("the bridge ended");
    assert!(!exit.success());
    let stderr = stderr_of(&mut whirl);
    assert!(stderr.contains("executed-path log"), "{stderr}");
    // The stream had begun, and the controller was held and left with RUN cleared before
    // the bridge went: a program of 20 s was not run to its end.
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (state, executed, control) =
        rt.block_on(async { status(&mut client(address).await).await });
    assert_eq!(state, HELD);
    assert_eq!(control & RUN, 0);
    assert!(executed > 0 && executed < 200, "{executed}");
    assert_eq!(std::fs::metadata(&log).unwrap().len(), 64 * 1024);
}

#[test]
fn a_log_that_fails_mid_job_over_can_disables_the_drives_first() {
    let dir = tempfile::tempdir().unwrap();
    let slcan = dir.path().join("slcan");
    let sim_log = dir.path().join("sim.jsonl");
    // The ring's spindle is switched on and off between short Z moves: each switch is an
    // event in the bridge's log, so the log keeps growing through the job.
    let (profile, _) = patient_can_machine(dir.path());
    let text = std::fs::read_to_string(&profile)
        .unwrap()
        .replace("spin_up_ms = 2000", "spin_up_ms = 1");
    let profile = util::write(dir.path(), "drives.toml", &text);
    let _sim = can_sim(&slcan, &profile, &sim_log);
    let mut program = "G21 G90 G94\nG0 X1 Z0 C0\n".to_owned();
    for _ in 0..60 {
        program.push_str("M3 S1000\nG1 Z-0.5 F600\nM5\nG1 Z0 F600\n");
    }
    let program = util::write(dir.path(), "spindle.nc", &program);
    let log = dir.path().join("exec.jsonl");
    // Room for the start, the boot-up and about twenty switches.
    nearly_full_log(&log, 64, 3000);
    let mut whirl = whirl_with_file_limit(
        64,
        &[
            OsStr::new("stream"),
            program.as_os_str(),
            // Written here, not planned: it carries no provenance.
            OsStr::new("--no-provenance-check"),
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--port"),
            slcan.as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
        ],
    );
    let exit = wait_for(&mut whirl, Duration::from_secs(60)).expect("the bridge ended");
    assert!(!exit.success());
    let stderr = stderr_of(&mut whirl);
    assert!(stderr.contains("executed-path log"), "{stderr}");
    // The job had begun; the drives were walked to Switch on disabled, not quick-stopped,
    // well before the program's end (60 round trips of 0.1 s).
    for node in 1..=3 {
        let states = power_states(&sim_log, node);
        assert!(states.iter().any(|s| s == "OperationEnabled"), "{states:?}");
        assert!(!states.iter().any(|s| s == "QuickStopActive"), "{states:?}");
        assert_eq!(states.last().map(String::as_str), Some("SwitchOnDisabled"));
    }
    // Each move of 0.5 mm at 600 mm/min is 50 ms, 13 cycles of 4 ms: the program is over
    // 1 500 cycles; the drives ran far fewer.
    let cycles = events(&sim_log)
        .iter()
        .filter(|e| e["event"] == "executed")
        .count();
    assert!(cycles < 1000, "{cycles}");
}

/// The double-start example cut to 1 mm of groove, written to `dir` with its profile points,
/// turned at 60 rpm with the ring at 4000 rpm (its rating) and fed 0.2 mm a turn, so that
/// it runs in under a minute of real time; the insert cusp and the scallop grow with it,
/// and the planner still holds the whole error within Δ (it refuses a job it cannot).
fn short_fast_double_start(dir: &Path) -> PathBuf {
    let example = util::example("double-start");
    std::fs::copy(
        example.with_file_name("profile.csv"),
        dir.join("profile.csv"),
    )
    .unwrap();
    let mut text = std::fs::read_to_string(&example).unwrap();
    for (from, to) in [
        ("length = 24.0 ", "length = 1.0 "),
        ("workpiece_rpm = 10.0", "workpiece_rpm = 60.0"),
        ("ring_rpm = 1500.0", "ring_rpm = 4000.0"),
        ("axial_feed = 0.1 ", "axial_feed = 0.2 "),
    ] {
        assert!(text.contains(from), "the example's {from}");
        text = text.replace(from, to);
    }
    util::write(dir, "job.toml", &text)
}

/// `whirl stream PROGRAM` to the CAN drives at `slcan` on `profile`, logging to `log`, with
/// `extra` arguments; started, its output piped.
fn whirl_stream_can(
    program: &Path,
    profile: &Path,
    slcan: &Path,
    log: &Path,
    extra: &[&str],
) -> Child {
    Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", log.with_file_name("runs.sqlite"))
        .arg("stream")
        .arg(program)
        .arg("--machine")
        .arg(profile)
        .args(["--transport", "can-slcan", "--port"])
        .arg(slcan)
        .arg("--log")
        .arg(log)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("whirl starts")
}

/// The simulator's executed cycles in its log, in order.
fn executed_cycles(sim_log: &Path) -> Vec<whirl_sim::ExecutedBlock> {
    events(sim_log)
        .into_iter()
        .filter(|e| e["event"] == "executed")
        .map(|e| serde_json::from_value(e).expect("an executed block"))
        .collect()
}

/// Issue 21, case 2: a `whirl stream` to CiA 402 drives interrupted by SIGINT mid-cut, then
/// resumed with `--resume-at` at the line it printed, at real time, `whirl-sim` judging
/// every cycle with the job's Δ guard. The re-entry turns C back to the resume line's start
/// with X at the clear position (0 for this internal ring, which then stays 60·cos δ −
/// 1.2 mm from the axis, clear of the 34 mm crest): a move that cuts nothing, which the
/// guard took for a cut turning C both ways (EMCY 0xFF64) before it knew a ring clear of
/// the work. Both runs together must cut the whole groove within Δ.
#[test]
fn a_can_stop_then_resume_re_enters_and_the_guard_measures_the_groove_within_delta() {
    let dir = tempfile::tempdir().unwrap();
    let (profile, _) = patient_can_machine(dir.path());
    let job = short_fast_double_start(dir.path());
    let program = dir.path().join("job.nc");
    let o = util::whirl(&[
        OsStr::new("plan"),
        job.as_os_str(),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("-o"),
        program.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let slcan = dir.path().join("slcan");
    let sim_log = dir.path().join("sim.jsonl");
    let _sim = Sim::serving(
        OsStr::new("--can-slcan"),
        &slcan,
        &[
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--job"),
            job.as_os_str(),
            OsStr::new("--idle-exit"),
            OsStr::new("60"),
            OsStr::new("--log"),
            sim_log.as_os_str(),
        ],
    );
    let log = dir.path().join("exec.jsonl");
    let mut first = whirl_stream_can(&program, &profile, &slcan, &log, &[]);
    // In the cut (X past 20 mm: the ring's tips inside the crest's 34 mm, and C turning)
    // for two seconds of the drives' cycles (4 ms each), then the signal.
    let since = Instant::now();
    loop {
        let cutting = events(&sim_log)
            .iter()
            .filter(|e| {
                e["event"] == "executed"
                    && e["to"]["x"].as_f64().unwrap() > 20.0
                    && e["to"]["c"].as_f64() != e["from"]["c"].as_f64()
            })
            .count();
        if cutting >= 500 {
            break;
        }
        assert!(
            first.try_wait().unwrap().is_none(),
            "the run ended before the cut: {}",
            stderr_of(&mut first)
        );
        // The lead-in's plunge alone takes 30 s (25 mm at 50 mm/min).
        assert!(since.elapsed() < Duration::from_secs(90), "no cut");
        std::thread::sleep(Duration::from_millis(50));
    }
    let kill = Command::new("kill")
        .args(["-INT", &first.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let exit = wait_for(&mut first, Duration::from_secs(30)).expect("the bridge stopped");
    let stderr = stderr_of(&mut first);
    assert!(!exit.success(), "{stderr}");
    assert!(stderr.contains("interrupted (SIGINT)"), "{stderr}");
    let at = stderr
        .find("--resume-at ")
        .unwrap_or_else(|| panic!("no resume point in: {stderr}"));
    let line: usize = stderr[at + 12..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap();
    // The log ends with where to resume, then the End, as serial's does.
    let logged = events(&log);
    let n = logged.len();
    assert_eq!(
        logged[n - 2]["event"],
        "resume_at",
        "{:?}",
        &logged[n - 2..]
    );
    assert_eq!(logged[n - 2]["line"], line);
    assert_eq!(logged[n - 1]["event"], "end");
    assert_eq!(logged[n - 1]["completed"], false);
    let stopped = executed_cycles(&sim_log).len();

    let line_arg = line.to_string();
    let mut resumed = whirl_stream_can(
        &program,
        &profile,
        &slcan,
        &log,
        &["--resume-at", &line_arg],
    );
    let exit = wait_for(&mut resumed, Duration::from_secs(180)).expect("the resume ended");
    let stderr = stderr_of(&mut resumed);
    assert!(exit.success(), "{stderr}");
    let breaches: Vec<_> = events(&sim_log)
        .into_iter()
        .filter(|e| e["event"] == "breach")
        .collect();
    assert!(breaches.is_empty(), "{breaches:?}");

    // The case itself: the re-entry turned C back against the cut's turn, with X at the
    // clear 0 all the while.
    let cycles = executed_cycles(&sim_log);
    let turn: f64 = cycles[..stopped]
        .iter()
        .filter(|b| b.to.x > 20.0)
        .map(|b| b.to.c - b.from.c)
        .sum();
    let back: Vec<_> = cycles[stopped..]
        .iter()
        .filter(|b| (b.to.c - b.from.c) * turn < 0.0)
        .collect();
    assert!(!back.is_empty(), "the re-entry never turned C back");
    assert!(
        back.iter()
            .all(|b| b.from.x.abs() < 1e-9 && b.to.x.abs() < 1e-9),
        "C turned back off the clear X"
    );
    // Every cycle of both runs, judged as the simulator's guard judged them, and then the
    // job's end: the whole groove measured, within Δ.
    let job = whirl::config::job::Job::load(&job).unwrap();
    let machine = MachineProfile::load(&profile).unwrap();
    let (ring, _) = whirl::plan::angles::ring(&job).unwrap();
    let guard = whirl::judge::guard::DeltaGuard::new(&job, ring, &machine).unwrap();
    let points = guard.points();
    let counts = machine
        .connection
        .as_ref()
        .and_then(|c| c.drives())
        .unwrap()
        .counts_per_unit();
    let mut guard = whirl::judge::cycles::MergedGuard::new(guard, counts);
    for block in &cycles {
        whirl_sim::Guard::executed(&mut guard, block).expect("within Δ");
    }
    whirl_sim::Guard::program_end(&mut guard).expect("within Δ");
    let measured = whirl_sim::Guard::measured(&guard);
    assert_eq!(measured.points, points);
    assert!(measured.max_error_mm() <= job.cut.delta, "{measured:?}");
    eprintln!("both runs measured: {measured:?}");
}
