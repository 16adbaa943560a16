//! The fault matrix on a serial line (docs/faults.md): a real `whirl stream` process
//! streaming to a real `whirl-sim` on a pseudo-terminal, interrupted by signals, an external
//! reset, a log that cannot be written and a simulator that dies; each run checked from the
//! simulator's own log (what the machine did, with the wall clock) and the bridge's.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde_json::Value;

use crate::util::{self, Sim};

/// The double-start example's planned program, its simulator serving on a pseudo-terminal as
/// fast as the host allows with the Δ guard watching the job, and the logs.
struct Bench {
    _dir: tempfile::TempDir,
    program: PathBuf,
    link: PathBuf,
    sim_log: PathBuf,
    log: PathBuf,
    sim: Option<Sim>,
}

impl Bench {
    fn new() -> Bench {
        Bench::with(None, &[OsStr::new("--time-scale"), OsStr::new("0")])
    }

    /// The double-start example, its groove `length` mm long if given (as issue 21's
    /// short job), planned and served by a simulator started with `sim_args`.
    fn with(length: Option<f64>, sim_args: &[&OsStr]) -> Bench {
        let dir = tempfile::tempdir().unwrap();
        let example = util::example("double-start");
        let job = match length {
            None => example,
            Some(length) => {
                let folder = example.parent().unwrap();
                std::fs::copy(folder.join("profile.csv"), dir.path().join("profile.csv")).unwrap();
                let text = std::fs::read_to_string(&example).unwrap();
                let at = text.find("length = ").expect("the groove's length");
                let end = at + text[at..].find('#').unwrap();
                let text = format!("{}length = {length} {}", &text[..at], &text[end..]);
                let job = dir.path().join("job.toml");
                std::fs::write(&job, text).unwrap();
                job
            }
        };
        let program = dir.path().join("job.nc");
        let o = util::whirl(&[
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            program.as_os_str(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let link = dir.path().join("grbl");
        let sim_log = dir.path().join("sim.jsonl");
        let args = [
            sim_args,
            &[
                OsStr::new("--job"),
                job.as_os_str(),
                OsStr::new("--log"),
                sim_log.as_os_str(),
            ],
        ]
        .concat();
        let sim = Sim::serving(OsStr::new("--pty"), &link, &args);
        let log = dir.path().join("exec.jsonl");
        Bench {
            _dir: dir,
            program,
            link,
            sim_log,
            log,
            sim: Some(sim),
        }
    }

    /// `whirl stream` of the program to the simulator, with `args`, started.
    fn stream(&self, args: &[&OsStr]) -> Child {
        self.stream_with(Command::new(env!("CARGO_BIN_EXE_whirl")), args)
    }

    fn stream_with(&self, mut command: Command, args: &[&OsStr]) -> Child {
        command
            // Its records beside its log: a run under a file size limit cannot grow the
            // tests' shared database.
            .env("WHIRL_DB", self.log.with_file_name("runs.sqlite"))
            .args([OsStr::new("stream"), self.program.as_os_str()])
            .args([OsStr::new("--port"), self.link.as_os_str()])
            .args([OsStr::new("--log"), self.log.as_os_str()])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("whirl starts")
    }

    /// Waits until the simulator has executed `blocks` moves of this run: the cut is on.
    fn wait_cutting(&self, blocks: usize) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while self.sim_events("executed").len() < blocks {
            assert!(Instant::now() < deadline, "the simulator executed nothing");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The simulator's events of a kind, in order.
    fn sim_events(&self, kind: &str) -> Vec<Value> {
        read_events(&self.sim_log)
            .into_iter()
            .filter(|e| e["event"] == kind)
            .collect()
    }

    /// The program's lines.
    fn lines(&self) -> Vec<String> {
        std::fs::read_to_string(&self.program)
            .unwrap()
            .lines()
            .map(str::to_owned)
            .collect()
    }
}

/// Every event of a JSON-lines log.
fn read_events(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// Sends `signal` (a name `kill` knows) to `child`, returning the wall clock just before.
fn signal(child: &Child, signal: &str) -> f64 {
    let at = wall();
    let status = Command::new("kill")
        .args([format!("-{signal}"), child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    at
}

fn wall() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// Waits for `child` to exit, at most a minute.
fn finish(mut child: Child) -> Output {
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("whirl did not exit");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// The line `--resume-at N` names in `stderr`.
fn resume_line(stderr: &str) -> usize {
    let at = stderr
        .find("--resume-at ")
        .unwrap_or_else(|| panic!("no resume point in: {stderr}"));
    stderr[at + 12..]
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// The simulator's state events as (wall clock, state).
fn states(bench: &Bench) -> Vec<(f64, Value)> {
    bench
        .sim_events("state")
        .into_iter()
        .map(|e| (e["wall_s"].as_f64().unwrap(), e["state"].clone()))
        .collect()
}

fn is_hold(state: &Value) -> bool {
    state.get("Hold").is_some()
}

fn held_complete(state: &Value) -> bool {
    state["Hold"]["complete"] == true
}

/// The bridge's log of its last run ends with where to resume and an End naming `why`.
fn assert_log_ends_with_resume(bench: &Bench, line: usize, why: &str) {
    let events = read_events(&bench.log);
    let n = events.len();
    assert!(n >= 2);
    assert_eq!(
        events[n - 2]["event"],
        "resume_at",
        "{:?}",
        &events[n - 2..]
    );
    assert_eq!(events[n - 2]["line"], line);
    assert_eq!(events[n - 1]["event"], "end");
    assert_eq!(events[n - 1]["completed"], false);
    let reason = events[n - 1]["reason"].as_str().unwrap();
    assert!(reason.contains(why), "{reason}");
}

/// X, Z, C of the program's moves as its text leaves them after each line (absolute G90
/// words, as whirl's post writes them), indexed by the line's N number.
fn ends_by_line(lines: &[String]) -> Vec<[f64; 3]> {
    let mut at = [f64::NAN; 3];
    let mut ends = vec![at];
    for line in lines {
        // A comment (the title, the provenance header) holds no words.
        let words = line.split('(').next().unwrap_or_default();
        for word in words.split_whitespace() {
            let (axis, value) = word.split_at(1);
            let slot = match axis {
                "X" => 0,
                "Z" => 1,
                "C" => 2,
                _ => continue,
            };
            at[slot] = value.parse().unwrap();
        }
        ends.push(at);
    }
    ends
}

/// The resumed run, from the simulator's log after `after` events: it completed without
/// an alarm (the Δ guard found the groove within Δ), and every program line it executed
/// began where the line before it ends in the program: re-entered along the groove, no
/// line run as a jump from somewhere else. Before the first of them only the approach
/// runs: X out to the clear position, C and Z there, X back in alone.
fn assert_resumed_along_the_groove(bench: &Bench, after: usize, from_line: usize) {
    let events = read_events(&bench.sim_log);
    let run = &events[after..];
    let alarms: Vec<&Value> = run.iter().filter(|e| e["event"] == "alarm").collect();
    assert!(alarms.is_empty(), "{alarms:?}");
    let ends = ends_by_line(&bench.lines());
    let executed: Vec<&Value> = run.iter().filter(|e| e["event"] == "executed").collect();
    let first = executed
        .iter()
        .position(|e| e["n"].is_u64())
        .expect("program lines executed");
    // Nothing before the resume line runs again (a line without motion executes nothing).
    assert!(
        executed[first]["n"].as_u64().unwrap() as usize >= from_line,
        "{}",
        executed[first]
    );
    let xyz = |p: &Value| {
        [
            p["x"].as_f64().unwrap(),
            p["z"].as_f64().unwrap(),
            p["c"].as_f64().unwrap(),
        ]
    };
    // The approach: only X moves off the clear position (0 for this internal whirling).
    for e in &executed[..first] {
        let (from, to) = (xyz(&e["from"]), xyz(&e["to"]));
        if from[1] != to[1] || from[2] != to[2] {
            assert!(from[0].abs() < 1e-6 && to[0].abs() < 1e-6, "{e}");
        }
    }
    // C is held as a 32-bit float by the machine: 0.008° apart near 80 000°.
    let tolerance = [1e-3, 1e-3, 0.02];
    for e in &executed[first..] {
        let Some(n) = e["n"].as_u64() else { continue };
        let start = ends[n as usize - 1];
        let from = xyz(&e["from"]);
        for k in 0..3 {
            if start[k].is_finite() {
                assert!(
                    (from[k] - start[k]).abs() <= tolerance[k],
                    "line {n} began at {from:?}, not where line {} ends, {start:?}",
                    n - 1
                );
            }
        }
    }
    // The run goes on to the program's last move (the lead-out's retract).
    let last_move = bench
        .lines()
        .iter()
        .rposition(|l| l.contains(" X") || l.contains(" Z") || l.contains(" C"))
        .unwrap();
    let last = executed.last().unwrap();
    assert_eq!(last["completed"], true);
    assert_eq!(last["n"].as_u64().unwrap() as usize, last_move + 1);
}

#[test]
fn ctrl_c_holds_the_machine_within_100_ms_and_the_resume_re_enters_along_the_groove() {
    let mut bench = Bench::new();
    let child = bench.stream(&[]);
    bench.wait_cutting(2000);
    let at = signal(&child, "INT");
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(stderr.contains("interrupted (SIGINT)"), "{stderr}");
    // The feed hold reached the simulator within 100 ms of the signal, and the machine
    // stands held.
    let states = states(&bench);
    let (hold_at, _) = states
        .iter()
        .find(|(t, s)| *t >= at && is_hold(s))
        .expect("the simulator held");
    assert!(
        hold_at - at < 0.1,
        "held {:.3} s after the signal",
        hold_at - at
    );
    assert!(held_complete(&states.last().unwrap().1), "{states:?}");
    let line = resume_line(&stderr);
    assert_log_ends_with_resume(&bench, line, "SIGINT");
    // Resuming there completes the job along the groove.
    let after = read_events(&bench.sim_log).len();
    let resumed = bench.stream(&[OsStr::new("--resume-at"), OsStr::new(&line.to_string())]);
    let o = finish(resumed);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_resumed_along_the_groove(&bench, after, line);
    drop(bench.sim.take());
}

#[test]
fn sigterm_and_sighup_hold_the_machine_too() {
    for name in ["TERM", "HUP"] {
        let bench = Bench::new();
        let child = bench.stream(&[]);
        bench.wait_cutting(500);
        let at = signal(&child, name);
        let o = finish(child);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "SIG{name}: {stderr}");
        let states = states(&bench);
        assert!(
            states.iter().any(|(t, s)| *t >= at && is_hold(s)),
            "SIG{name}: {states:?}"
        );
        assert!(held_complete(&states.last().unwrap().1), "SIG{name}");
        assert_log_ends_with_resume(&bench, resume_line(&stderr), &format!("SIG{name}"));
    }
}

#[test]
fn a_second_ctrl_c_aborts_with_a_soft_reset() {
    let bench = Bench::new();
    let child = bench.stream(&[]);
    bench.wait_cutting(500);
    signal(&child, "INT");
    std::thread::sleep(Duration::from_millis(5));
    signal(&child, "INT");
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(stderr.contains("SIGINT again: aborting"), "{stderr}");
    // The simulator was reset: its Reset event follows the hold.
    assert!(!bench.sim_events("reset").is_empty(), "{stderr}");
}

#[test]
fn after_an_external_reset_the_resume_unlocks_an_alarm_and_re_enters_along_the_groove() {
    let bench = Bench::new();
    let child = bench.stream(&[]);
    bench.wait_cutting(2000);
    // Someone at the machine resets it mid-cut: a soft reset byte on the same line.
    let mut port = std::fs::OpenOptions::new()
        .write(true)
        .open(&bench.link)
        .unwrap();
    std::io::Write::write_all(&mut port, &[0x18]).unwrap();
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    let line = resume_line(&stderr);
    let resume_at = line.to_string();
    let resume = [OsStr::new("--resume-at"), OsStr::new(&resume_at)];
    // grbl raises ALARM:3 for a reset in motion only. One that finds the machine standing
    // (on a loaded host the simulator may have run dry waiting for its sender) leaves no
    // alarm, and the resume needs no unlock; the simulator's log says which it was.
    let unlock = if bench.sim_events("alarm").is_empty() {
        assert!(
            stderr.contains("the stream stopped: the controller reset"),
            "{stderr}"
        );
        &[][..]
    } else {
        assert!(stderr.contains("the stream stopped: ALARM:3"), "{stderr}");
        // The controller is still in alarm: the resume says so and offers the unlock.
        let o = finish(bench.stream(&resume));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert!(
            stderr.contains("in alarm") && stderr.contains("--unlock"),
            "{stderr}"
        );
        &[OsStr::new("--unlock")][..]
    };
    // What the resume sends, from here on in the simulator's log.
    let after = read_events(&bench.sim_log).len();
    let o = finish(bench.stream(&[&resume[..], unlock].concat()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_resumed_along_the_groove(&bench, after, line);
}

#[test]
fn a_log_that_cannot_be_written_holds_the_machine_and_says_where_to_resume() {
    let bench = Bench::new();
    // The log may grow to 64 KiB (a file size limit, as a full disk would stop it), well
    // into the cut; SIGXFSZ ignored, so the write fails instead of killing the process.
    let mut command = Command::new("sh");
    command.args([
        OsStr::new("-c"),
        OsStr::new("trap '' XFSZ; ulimit -f 128; exec \"$0\" \"$@\""),
        OsStr::new(env!("CARGO_BIN_EXE_whirl")),
    ]);
    let o = finish(bench.stream_with(command, &[]));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains(&bench.log.display().to_string()),
        "{stderr}"
    );
    // The bridge left once the machine stood held, and said where to resume.
    let states = states(&bench);
    assert!(
        states.last().is_some_and(|(_, s)| held_complete(s)),
        "the machine was not held: {states:?}"
    );
    resume_line(&stderr);
}

#[test]
fn a_simulator_that_dies_mid_stream_ends_the_run_with_a_resume_point() {
    let mut bench = Bench::new();
    let child = bench.stream(&[]);
    bench.wait_cutting(500);
    drop(bench.sim.take());
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains(&bench.link.display().to_string()),
        "{stderr}"
    );
    let line = resume_line(&stderr);
    let events = read_events(&bench.log);
    let n = events.len();
    assert_eq!(events[n - 2]["event"], "resume_at");
    assert_eq!(events[n - 2]["line"], line);
    assert_eq!(events[n - 1]["event"], "end");
}

#[test]
fn no_link_use_figure_is_given_for_a_pseudo_terminal() {
    // A simulator on a pseudo-terminal takes bytes at the speed of memory, whatever the
    // 115 200 baud the port is opened at: a share of that rate (83 % seen from a 1×
    // simulator, above 100 % from a fast one) would measure nothing of a link. Here 20
    // moves of 0.5 mm at 600 mm/min take a second of motion at 1×, in which the lines'
    // bytes would fill a few per cent of a real 115 200-baud line.
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = Sim::serving(
        OsStr::new("--pty"),
        &link,
        &[OsStr::new("--time-scale"), OsStr::new("1")],
    );
    let mut text = String::from("G21 G90 G94\nG0 X10 Z0 C0\n");
    for k in 1..=20 {
        text.push_str(&format!("G1 Z{:.1} F600\n", f64::from(k) * 0.5));
    }
    text.push_str("M2\n");
    let program = util::write(dir.path(), "p.nc", &text);
    let log = dir.path().join("exec.jsonl");
    // Written by hand: it carries no provenance.
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
        OsStr::new("--no-provenance-check"),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("23 of 23 lines acknowledged"), "{stdout}");
    assert!(!stdout.contains("% busy"), "{stdout}");
}

#[test]
fn a_resume_behind_a_link_that_stops_at_a_full_buffer_survives_its_own_plunge() {
    // Issue 21, case 9: a link that delivers no byte, real-time ones included, to a nearly
    // full receive buffer (grblHAL's own simulator reads its UART only while more than 100
    // bytes are free, `mcu.c`: `--rx-backpressure 100`), the short job. The resume's radial
    // plunge at the program's plunge feed takes seconds, during which the planner is full
    // and no line is read: a bridge that fills the buffer to the last byte (all but the
    // line the controller waits on, a few dozen bytes) gets no status report for the
    // whole plunge, and its watchdog gave up on it. At 10 times real time and a 2 s stall
    // timeout the plunge (30 s of the machine's time) outlasts the timeout whatever the
    // host's speed (a slower host only lengthens it in wall time).
    let mut bench = Bench::with(
        Some(1.0),
        &[
            OsStr::new("--time-scale"),
            OsStr::new("10"),
            OsStr::new("--rx-backpressure"),
            OsStr::new("100"),
        ],
    );
    let stall = [OsStr::new("--stall-timeout"), OsStr::new("2")];
    let child = bench.stream(&stall);
    bench.wait_cutting(150);
    signal(&child, "INT");
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("interrupted (SIGINT)"), "{stderr}");
    let line = resume_line(&stderr);
    let after = read_events(&bench.sim_log).len();
    let at = line.to_string();
    let resume = [&stall[..], &[OsStr::new("--resume-at"), OsStr::new(&at)]].concat();
    let o = finish(bench.stream(&resume));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_resumed_along_the_groove(&bench, after, line);
    drop(bench.sim.take());
}

#[test]
fn a_stall_holds_and_says_where_to_resume() {
    // Issue 21, case 4: the simulator frozen (SIGSTOP) for 5 s under a 2 s stall timeout,
    // once the bridge's reports show the cut past the lead-in's plunge (a line planned at
    // 30 s, which the watchdog would rightly allow its time while it may be running).
    let mut bench = Bench::with(None, &[OsStr::new("--time-scale"), OsStr::new("10")]);
    let sim_pid = bench.sim.as_ref().unwrap().0.id().to_string();
    let child = bench.stream(&[OsStr::new("--stall-timeout"), OsStr::new("2")]);
    let deadline = Instant::now() + Duration::from_secs(60);
    while !read_events(&bench.log)
        .iter()
        .any(|e| e["event"] == "status" && e["line"].as_u64().is_some_and(|n| n > 50))
    {
        assert!(Instant::now() < deadline, "no report of the cut");
        std::thread::sleep(Duration::from_millis(20));
    }
    let kill = |sig: &str| {
        assert!(Command::new("kill")
            .args([sig, &sim_pid])
            .status()
            .unwrap()
            .success());
    };
    kill("-STOP");
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut child = child;
    while Instant::now() < deadline && child.try_wait().unwrap().is_none() {
        std::thread::sleep(Duration::from_millis(20));
    }
    kill("-CONT");
    let o = finish(child);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("the stream stalled: nothing new from the controller for 2 s"),
        "{stderr}"
    );
    let line = resume_line(&stderr);
    assert_log_ends_with_resume(&bench, line, "stalled");
    drop(bench.sim.take());
}

#[test]
fn a_momentary_idle_between_starved_moves_does_not_end_a_stop() {
    // Issue 21, case 10: a controller starved between moves reports Idle for a moment
    // while lines are still on their way to it. At 300 baud a line takes a second of the
    // machine's time to arrive and a groove move a fraction of one, so the machine stands
    // idle between most moves, and the lines and status requests in flight queue for
    // seconds on the link: a `?` sent before the Ctrl-C is answered after it, often Idle.
    // A bridge that takes that for a machine at rest leaves while the lines behind it run.
    let bench = Bench::with(
        Some(1.0),
        &[
            OsStr::new("--time-scale"),
            OsStr::new("10"),
            OsStr::new("--baud"),
            OsStr::new("300"),
        ],
    );
    let child = bench.stream(&[]);
    bench.wait_cutting(40);
    signal(&child, "INT");
    let o = finish(child);
    let left = wall();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("interrupted (SIGINT)"), "{stderr}");
    resume_line(&stderr);
    // The machine stood when the bridge left, and nothing ran after: the link's backlog
    // (at most a receive buffer, 1023 bytes, 34 s of the machine's time, 3.4 s of wall time
    // at 10 times real time) would have arrived well within the 6 s waited here.
    std::thread::sleep(Duration::from_secs(6));
    let moved_after: Vec<(f64, Value)> = states(&bench)
        .into_iter()
        .filter(|(t, s)| *t > left && *s == "Run")
        .collect();
    assert!(moved_after.is_empty(), "{moved_after:?}");
    let executed_after = bench
        .sim_events("executed")
        .into_iter()
        .filter(|e| e["wall_s"].as_f64().unwrap() > left)
        .count();
    assert_eq!(executed_after, 0);
}
