//! Link use: how busy a sender keeps a real 115 200-baud serial line, whirl's streamer beside
//! an independent character-counting client.
//!
//! whirl-sim is served on a real pseudo-terminal at time scale 1, where its emulated link is
//! the real line from both ends ([`ServeOptions::baud`]): the sender's bytes reach the
//! controller no faster than 115 200 baud allows in wall time, and the controller's answers
//! and status reports come back no faster either, each direction on its own as on a full
//! duplex line. Two senders stream the same program to it, each to a fresh simulator:
//!
//! - `whirl_stream`: `whirl::transport::serial::stream_port` on the terminal's other end,
//!   opened by path as `whirl stream --port` opens it: the state check (`?`) and `$I`
//!   before the first line, then 5 Hz status polls;
//! - `grbl_stream_py`: `tests/clients/grbl_stream.py`, grbl's character counting written
//!   from the protocol's published description in Python with pyserial; it shares no code
//!   with whirl's streamer, and sends no polls.
//!
//! Each sample prints the sender's link use: the bytes it wrote × 10 bits (8N1) over the
//! baud rate, the least time those bytes can take on the line, divided by the wall time
//! from its first byte to the last line's answer. The floor makes 100 % the most any
//! sender can reach, so each figure is checked to be at most 1 (the simulator's pacing
//! holds). whirl's run also prints the figure from its first program line on, counting
//! the program's bytes only: like for like with the client, whose first byte is its first
//! line, because whirl first asks the machine's state and its receive buffer (`?` and
//! `$I`, two round trips the client does without: it neither checks the machine nor asks,
//! it is told `--rx`). The requirement: `whirl stream` keeps the link at least 95 % busy,
//! and at least as busy as the independent client. The run time divan shows is the whole
//! stream, the motion after the last answer included.
//!
//! # Why the link, not the motion, binds
//!
//! The program is [`MOVES`] moves of [`STEP_MM`] along Z at 50 mm/s. A line is 8 or 9 bytes
//! (`G1Z12.34` and its newline), 0.7–0.8 ms on the line, while its move would last 0.2 ms
//! at the feed: the machine could run lines faster than the link brings them, so it runs
//! at the speed they arrive, R ≈ 1 300 lines a second, v = R·L ≈ 13 mm/s. Collinear moves
//! have no junction to slow for; the speed is bounded by stopping within the queued moves,
//! v = √(2·a·n·L), so the planner needs only about n = v² / (2·a·L) ≈ 17 of its 35 blocks
//! at 500 mm/s². It never fills, so the controller takes every line from its receive
//! buffer as soon as the line is in, answers at once, and a sender that keeps its window
//! full keeps the link busy: only the link and the sender set the pace. (Moves long enough
//! to outlast their lines' link time would fill the planner and bind on motion, the case
//! of a whirling program, whose moves last tens of milliseconds: it shows nothing of the
//! link.) Each sample prints the fewest free planner blocks the controller's status
//! reports showed during whirl's run: never none.
//!
//! About 44 kB at 11 520 bytes a second, each run lasts about 4 s: long enough that the
//! timer's grain does not count, and the whole bench (12 runs) about a minute.
//!
//! Run with `cargo bench --bench stream`; docs/streaming.md quotes the figures.

use std::path::Path;
use std::process::Command;
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use divan::Bencher;
use tokio::sync::oneshot;
use tokio_serial::SerialPort;
use whirl::config::machine::MachineProfile;
use whirl::log::{self, ExecLog};
use whirl::transport::check_program;
use whirl::transport::serial::{stream_port, StreamOptions, StreamOutcome};
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions, Event};

fn main() {
    divan::main();
}

/// The link rate, bits per second, on both sides.
const BAUD: u32 = 115_200;

/// Program moves: about 44 kB, 3.8 s of link time.
const MOVES: usize = 5000;

/// Each move's length, mm (see the module docs for why the link binds).
const STEP_MM: f64 = 0.01;

/// Units, absolute distances, the feed, a start at the origin (where the simulator powers
/// up, so it does not move; the machine check wants every axis placed), then [`MOVES`] short
/// G1 lines along Z from 0 to 50 mm, inside the sim machine's travel. Written without
/// spaces, as the independent client would send them (it strips whitespace, as grbl's
/// `stream.py` does), so both senders write the same program bytes.
fn program() -> Vec<String> {
    let mut lines = vec![
        "G21G90G94".to_owned(),
        "F3000".to_owned(),
        "G0X0Z0C0".to_owned(),
    ];
    lines.extend((1..=MOVES).map(|k| format!("G1Z{:.2}", k as f64 * STEP_MM)));
    lines
}

/// What the simulator saw: the run must have been clean for its figure to count.
#[derive(Debug, Default)]
struct SimReport {
    executed: usize,
    overflows: usize,
    alarms: usize,
}

impl SimReport {
    fn note(&mut self, event: &Event) {
        match event {
            Event::Executed(_) => self.executed += 1,
            Event::RxOverflow { .. } => self.overflows += 1,
            Event::Alarm { .. } => self.alarms += 1,
            _ => {}
        }
    }

    /// Every move executed, no byte dropped, no alarm.
    fn assert_clean(&self) {
        assert_eq!((self.executed, self.overflows, self.alarms), (MOVES, 0, 0));
    }
}

/// whirl-sim with an `rx`-byte receive buffer on a new pseudo-terminal, on its own thread (as
/// the `whirl-sim` binary runs in its own process, so neither side's work delays the other's
/// reads), at time scale 1 and [`BAUD`].
struct Sim {
    /// The terminal's device, for the sender to open.
    path: String,
    /// Stops serving (the simulator keeps the terminal open, so it never sees it close).
    stop: oneshot::Sender<()>,
    thread: JoinHandle<SimReport>,
}

impl Sim {
    /// Serves at once: the emulated link credits no idle time to later bytes, so it does
    /// not matter how long the sender takes to open the terminal.
    fn start(rx: usize) -> Sim {
        let (path_tx, path_rx) = mpsc::channel();
        let (stop, stop_rx) = oneshot::channel();
        let thread = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("a runtime");
            runtime.block_on(async move {
                let (master, slave) =
                    tokio_serial::SerialStream::pair().expect("a pseudo-terminal");
                path_tx
                    .send(slave.name().expect("the terminal's device"))
                    .expect("the bench waits for the path");
                let profile = MachineProfile::builtin_sim().expect("the built-in profile");
                let options = ControllerOptions {
                    rx_buffer_size: rx,
                    ..ControllerOptions::default()
                };
                let mut controller =
                    Controller::new(&whirl::judge::simulator::machine(&profile), options)
                        .expect("a controller");
                // As whirl-sim does: the board booted before the host opened the port.
                controller.take_output();
                let serve_options = ServeOptions {
                    time_scale: Some(1.0),
                    baud: Some(BAUD),
                    ..ServeOptions::default()
                };
                let mut report = SimReport::default();
                tokio::select! {
                    served = serve(master, &mut controller, serve_options, |e| report.note(e)) => {
                        served.expect("the simulator serves");
                    }
                    _ = stop_rx => {}
                }
                // The slave end stays open until here so the terminal outlives the sender.
                drop(slave);
                report
            })
        });
        let path = path_rx.recv().expect("the simulator's terminal");
        Sim { path, stop, thread }
    }

    /// Stops the simulator and says what it saw.
    fn finish(self) -> SimReport {
        // The simulator may already have finished if something closed the link.
        let _ = self.stop.send(());
        self.thread.join().expect("the simulator thread")
    }
}

/// One sender's run: bytes written up to the last answer, and the wall time from its first
/// byte (or from `since`) to that answer.
struct LinkUse {
    bytes: u64,
    elapsed: Duration,
    since: &'static str,
}

impl LinkUse {
    /// The least time the bytes take on the line: 10 bits each.
    fn floor(&self) -> Duration {
        Duration::from_secs_f64(self.bytes as f64 * 10.0 / f64::from(BAUD))
    }

    /// How busy the link was, 0 to 1.
    fn share(&self) -> f64 {
        self.floor().as_secs_f64() / self.elapsed.as_secs_f64()
    }

    fn print(&self, who: &str, rx: usize, extra: &str) {
        eprintln!(
            "rx {rx:4} {who}: {} bytes, floor {:.4} s, {} to last answer {:.4} s: \
             link {:.2} % busy{extra}",
            self.bytes,
            self.floor().as_secs_f64(),
            self.since,
            self.elapsed.as_secs_f64(),
            100.0 * self.share(),
        );
        // The floor: both senders' clocks start before their first byte is written and
        // stop after the last answer is read, which itself took link time. Above 1, the
        // simulator would have let bytes through faster than the baud rate allows.
        assert!(
            self.share() <= 1.0,
            "faster than the line: {}",
            self.share()
        );
    }
}

/// What whirl's run showed besides its outcome, from its executed-path log.
struct WhirlRun {
    outcome: StreamOutcome,
    /// When the first program line went out, from the run's start: after the state check
    /// (`?` and its report) and `$I` and its answer.
    first_line: Duration,
    /// The fewest free planner blocks a status report showed.
    planner_low: Option<u32>,
}

/// One whole stream of [`program`] by whirl's streamer; it checks the machine's state and
/// learns the receive buffer's size from `$I` first, as it does with a real controller.
fn whirl_once(rx: usize) -> WhirlRun {
    let sim = Sim::start(rx);
    let dir = tempfile::tempdir().expect("a temporary directory");
    let log_path = dir.path().join("exec.jsonl");
    let mut log = ExecLog::append(&log_path).expect("the log");
    let lines = program();
    // The machine check `whirl stream` makes, done here so it runs before the link starts.
    let profile = MachineProfile::builtin_sim().expect("the built-in profile");
    check_program(&lines, &profile).expect("the program fits the sim machine");
    let options = StreamOptions {
        port_name: sim.path.clone(),
        program: "short lines".to_owned(),
        baud: Some(BAUD),
        no_progress_timeout: Some(Duration::from_secs(10)),
        ..StreamOptions::default()
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    let outcome = runtime
        .block_on(stream_port(&sim.path, BAUD, lines, options, &mut log))
        .expect("the stream runs");
    sim.finish().assert_clean();
    assert!(outcome.completed(), "{outcome:?}");
    let records = log::read(&log_path).expect("the log reads back").records;
    let first_line = records
        .iter()
        .find(|r| matches!(r.event, log::Event::Sent { .. }))
        .map(|r| Duration::from_secs_f64(r.t))
        .expect("a line was sent");
    let planner_low = records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Status { blocks_free, .. } => *blocks_free,
            _ => None,
        })
        .min();
    WhirlRun {
        outcome,
        first_line,
        planner_low,
    }
}

/// The program's bytes on the line, each line with its newline.
fn program_bytes() -> u64 {
    program().iter().map(|l| l.len() as u64 + 1).sum()
}

/// The independent client, `tests/clients/grbl_stream.py`.
fn client_script() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/clients/grbl_stream.py")
}

/// Whether `python3` with pyserial is there to run the independent client.
fn client_runs() -> bool {
    Command::new("python3")
        .args(["-c", "import serial"])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// One whole stream of [`program`] by the independent client, told the receive buffer's
/// size (it does not ask `$I`).
fn client_once(rx: usize) -> LinkUse {
    let sim = Sim::start(rx);
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = dir.path().join("program.nc");
    std::fs::write(&file, program().join("\n") + "\n").expect("the program file");
    let out = Command::new("python3")
        .arg(client_script())
        .arg(&sim.path)
        .arg(&file)
        .args(["--rx", &rx.to_string(), "--baud", &BAUD.to_string()])
        .output()
        .expect("python3 runs the client");
    sim.finish().assert_clean();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the client failed: {stdout}{stderr}");
    let summary = stdout
        .lines()
        .find(|l| l.starts_with("lines="))
        .unwrap_or_else(|| panic!("no summary line: {stdout}{stderr}"));
    let value = |key: &str| -> u64 {
        summary
            .split_whitespace()
            .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {key} in {summary:?}"))
    };
    assert_eq!(value("ok"), program().len() as u64, "{summary}");
    LinkUse {
        bytes: value("bytes"),
        elapsed: Duration::from_micros(value("elapsed_us")),
        since: "first byte",
    }
}

/// whirl's streamer, with grblHAL's 1024-byte receive buffer and an AVR grbl's 128.
#[divan::bench(args = [1024, 128], sample_count = 3, sample_size = 1)]
fn whirl_stream(bencher: Bencher, rx: usize) {
    bencher.bench_local(|| {
        let run = whirl_once(rx);
        let acked = run.outcome.all_acked_at.expect("every line acknowledged");
        // The streamer's own figure is its bytes up to the last answer over the time from
        // its start (just before its first byte) to that answer; it is `None` only above 1,
        // which the check in `print` reports.
        let share = run.outcome.streaming_utilization.unwrap_or(f64::INFINITY);
        let whole = LinkUse {
            bytes: (share * f64::from(BAUD) * acked.as_secs_f64() / 10.0).round() as u64,
            elapsed: acked,
            since: "first byte",
        };
        // Like for like with the client, whose first byte is its first line: from whirl's
        // first program line, counting the program's bytes only (not the `?` polls, so
        // never more than the link carried).
        let streaming = LinkUse {
            bytes: program_bytes(),
            elapsed: acked - run.first_line,
            since: "first program line",
        };
        // A full planner would make the program bind on motion: the figures would then say
        // nothing of the link.
        let blocks = ControllerOptions::default().planner_blocks;
        let low = run
            .planner_low
            .expect("status reports with the planner's free blocks");
        assert!(low > 0, "the planner filled: the program is not link-bound");
        let planner = format!("; planner at least {low} of {blocks} blocks free");
        whole.print("whirl stream", rx, &planner);
        streaming.print(
            "whirl stream",
            rx,
            &format!(
                " (after `?` and `$I` answered: {:.1} ms)",
                run.first_line.as_secs_f64() * 1e3
            ),
        );
        run.outcome
    });
}

/// The independent client, with the same buffers.
#[divan::bench(args = [1024, 128], sample_count = 3, sample_size = 1)]
fn grbl_stream_py(bencher: Bencher, rx: usize) {
    if !client_runs() {
        eprintln!("grbl_stream_py skipped: it needs python3 with pyserial");
        return;
    }
    bencher.bench_local(|| {
        let link = client_once(rx);
        link.print("grbl_stream.py", rx, "");
        link
    });
}
