//! whirl's streamer (`whirl::transport::stream`) against the simulated grblHAL controller
//! over a real pseudo-terminal: the same code path `whirl stream --port` takes to a machine.
//!
//! The simulator is served on one end of a terminal pair, on its own thread and runtime (as
//! the `whirl-sim` binary runs in its own process); the streamer opens the other end by
//! path. Every assertion is a fact of grbl's protocol (character counting, one answer per
//! line, the sticky error, soft limits, feed hold) checked against the simulator's own log
//! of what it answered and executed, which shares no code with the streamer. Programs carry
//! an N word equal to their 1-based line number on every line, so an executed block's N
//! names the program line that queued it.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::sync::oneshot;
use tokio_serial::{SerialPort, SerialPortBuilderExt};
use whirl::config::machine::MachineProfile;
use whirl::log::{self, ExecLog};
use whirl::protocol::grbl::{LineRef, ResumeBasis, StopReason, StreamerConfig};
use whirl::transport::control;
use whirl::transport::serial::{stream, Ending, StreamOptions, StreamOutcome};
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{
    Alarm, Controller, ControllerOptions, Event, ExecutedBlock, GrblError, MachineState,
};

/// The rate the terminal is opened at, as `whirl stream` opens a port; a pseudo-terminal
/// carries bytes at whatever rate, so only the simulator's `baud` could limit it (unset here).
const BAUD: u32 = 115_200;

/// Bound on one stream, and on each wait for the simulator: every run here takes a fraction
/// of it, so reaching it means a hang, reported as a failure rather than blocking the suite.
const LIMIT: Duration = Duration::from_secs(20);

/// The simulator as fast as the host allows: simulated time owes nothing to the wall clock,
/// so a long program costs only the link's round trips.
fn fast() -> ServeOptions {
    ServeOptions {
        time_scale: None,
        baud: None,
        ..ServeOptions::default()
    }
}

/// The simulator at 20 times real time: a few seconds of simulated motion pass in a fraction
/// of a second, slowly enough for status reports and the caller's commands to land mid-program.
fn scaled() -> ServeOptions {
    ServeOptions {
        time_scale: Some(20.0),
        baud: None,
        ..ServeOptions::default()
    }
}

/// The built-in simulated machine (`machine-profiles/sim.toml`), the controller's travel.
fn profile() -> MachineProfile {
    MachineProfile::builtin_sim().expect("the built-in sim profile")
}

/// The simulator's own log: every event it emitted, in order, shared with the test while it
/// grows so a test can wait for something to happen on the machine rather than for a time.
#[derive(Clone, Default)]
struct SimLog(Arc<(Mutex<Vec<Event>>, Condvar)>);

impl SimLog {
    fn push(&self, event: &Event) {
        let (events, grew) = &*self.0;
        events.lock().unwrap().push(event.clone());
        grew.notify_all();
    }

    fn events(&self) -> Vec<Event> {
        self.0 .0.lock().unwrap().clone()
    }

    /// Blocks until `holds` is true of the events so far; fails the test after [`LIMIT`].
    fn wait_for(&self, what: &str, holds: impl Fn(&[Event]) -> bool) {
        let (events, grew) = &*self.0;
        let guard = events.lock().unwrap();
        let (_guard, wait) = grew
            .wait_timeout_while(guard, LIMIT, |events| !holds(events))
            .unwrap();
        assert!(!wait.timed_out(), "the simulator never showed {what}");
    }
}

/// A simulated controller on a pseudo-terminal, and one executed-path log that every stream
/// sent to it appends to (as successive `whirl stream` runs with `--log` do).
struct Link {
    /// The terminal's device, for the streamer to open.
    path: String,
    log: SimLog,
    /// Stops serving; the simulator holds its end open, so it never sees the link close.
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
    dir: tempfile::TempDir,
}

impl Link {
    /// Powers up a controller for the built-in sim machine with `controller` options and
    /// serves it on a new pseudo-terminal with `serving`.
    fn start(controller: ControllerOptions, serving: ServeOptions) -> Link {
        let log = SimLog::default();
        let sim_log = log.clone();
        let (path_tx, path_rx) = std::sync::mpsc::channel();
        let (stop, stop_rx) = oneshot::channel();
        let thread = std::thread::spawn(move || {
            // tokio-serial streams belong to the runtime that made them: the terminal pair is
            // made, and served, here.
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("a runtime");
            runtime.block_on(async move {
                let (master, slave) =
                    tokio_serial::SerialStream::pair().expect("a pseudo-terminal");
                path_tx
                    .send(slave.name().expect("the terminal's device"))
                    .expect("the test waits for the path");
                let machine = whirl::judge::simulator::machine(&profile());
                let mut sim = Controller::new(&machine, controller).expect("a controller");
                // As whirl-sim does: the board booted before the host opened the port.
                sim.take_output();
                tokio::select! {
                    served = serve(master, &mut sim, serving, |e| sim_log.push(e)) => {
                        served.expect("the simulator serves");
                    }
                    _ = stop_rx => {}
                }
                // Held open until here, so the terminal outlives every stream.
                drop(slave);
            });
        });
        let path = path_rx.recv().expect("the simulator's terminal");
        Link {
            path,
            log,
            stop: Some(stop),
            thread: Some(thread),
            dir: tempfile::tempdir().expect("a temporary directory"),
        }
    }

    fn log_path(&self) -> PathBuf {
        self.dir.path().join("exec.jsonl")
    }

    /// Streams `lines` with `options`, opening the terminal by path as `whirl stream --port`
    /// does, in a runtime on the calling thread; a second call reopens it, as a second run
    /// (a resume) would.
    fn stream(&self, lines: &[String], options: StreamOptions) -> StreamOutcome {
        let mut log = ExecLog::append(&self.log_path()).expect("the executed-path log");
        let options = StreamOptions {
            port_name: self.path.clone(),
            program: "link test".to_owned(),
            ..options
        };
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("a runtime");
        runtime.block_on(async {
            let port = tokio_serial::new(&self.path, BAUD)
                .open_native_async()
                .expect("the terminal opens");
            tokio::time::timeout(LIMIT, stream(port, lines.to_vec(), options, &mut log))
                .await
                .expect("the stream ends")
                .expect("the stream runs")
        })
    }

    /// The simulator's log so far.
    fn events(&self) -> Vec<Event> {
        self.log.events()
    }

    /// The streamer's executed-path log, every run so far.
    fn streamer_log(&self) -> Vec<log::Event> {
        log::read(&self.log_path())
            .expect("the executed-path log reads back")
            .records
            .into_iter()
            .map(|r| r.event)
            .collect()
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        // The simulator may have stopped already if its link failed; the join says so.
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let served = thread.join();
            if !std::thread::panicking() {
                served.expect("the simulator thread ends cleanly");
            }
        }
    }
}

/// `moves` G1 moves inside the sim machine's travel at `feed` mm/min, each line numbered
/// with its 1-based line number: modes, a rapid that places X and Z (the machine check wants
/// every moved axis placed first), then moves that advance Z by `step` mm and zig-zag X by
/// 1 mm. Every move has a length, so every line from the second on queues exactly one block
/// (grbl drops zero-length moves).
fn program(moves: usize, step: f64, feed: f64) -> Vec<String> {
    let mut lines = vec!["N1 G21 G90 G94".to_owned(), "N2 G0 X10 Z0".to_owned()];
    for i in 1..=moves {
        let n = lines.len() + 1;
        let x = 10 + i % 2;
        let z = i as f64 * step;
        lines.push(format!("N{n} G1 X{x} Z{z:.3} F{feed}"));
    }
    lines
}

/// The N word of program line `index` (0-based) in [`program`] and [`mixed_program`].
fn n_of(index: usize) -> u32 {
    u32::try_from(index + 1).expect("a short program")
}

/// The blocks the simulator executed, in order.
fn executed(events: &[Event]) -> impl Iterator<Item = &ExecutedBlock> {
    events.iter().filter_map(|e| match e {
        Event::Executed(block) => Some(block),
        _ => None,
    })
}

/// How many blocks each N word executed; a block without one counts under `None`.
fn executions_per_line(events: &[Event]) -> BTreeMap<Option<u32>, usize> {
    let mut counts = BTreeMap::new();
    for block in executed(events) {
        *counts.entry(block.n).or_default() += 1;
    }
    counts
}

/// Asserts that every line from the second of a [`program`] of `len` lines executed exactly
/// once, and nothing else did.
fn assert_each_move_executed_once(events: &[Event], len: usize) {
    let expected: BTreeMap<Option<u32>, usize> = (1..len).map(|i| (Some(n_of(i)), 1)).collect();
    let counts = executions_per_line(events);
    let wrong: Vec<_> = expected
        .keys()
        .chain(counts.keys())
        .filter(|n| expected.get(n) != counts.get(n))
        .map(|n| (*n, counts.get(n).copied().unwrap_or(0)))
        .collect();
    assert!(wrong.is_empty(), "(N, times executed) off: {wrong:?}");
}

/// The simulator's answers: (N word, line text, error), in the order given.
fn answers(events: &[Event]) -> Vec<(Option<u32>, &str, Option<GrblError>)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Line { n, text, error, .. } => Some((*n, text.as_str(), *error)),
            _ => None,
        })
        .collect()
}

/// The state the simulator last reported changing to.
fn last_state(events: &[Event]) -> Option<MachineState> {
    events.iter().rev().find_map(|e| match e {
        Event::State { state, .. } => Some(*state),
        _ => None,
    })
}

/// The code grbl prints for `error` (`StopReason` carries it as a `u16`).
fn code(error: GrblError) -> u16 {
    u16::from(error.code())
}

#[test]
fn a_move_past_the_travel_trips_alarm_2_and_nothing_after_it_executes() {
    let x_max = profile().axes.x.max;
    // Line 60 targets X past the end of travel. The controller reads it once the moves its
    // 35-block planner could not hold have run, so the machine is moving when it arrives and
    // grbl must stop it under control before the alarm.
    let offending = 59;
    let mut lines = program(70, 2.0, 1200.0);
    lines[offending] = format!("N{} G1 X{}", n_of(offending), x_max + 10.0);
    // Scaled, with frequent status reports, so that the streamer sees lines execute (`Ln:`)
    // and its resume point below has evidence to go on.
    // A planner of 35 blocks (`$398=35`), as the figures above count on.
    let link = Link::start(
        ControllerOptions {
            planner_blocks: 35,
            ..ControllerOptions::default()
        },
        scaled(),
    );
    let outcome = link.stream(
        &lines,
        StreamOptions {
            streamer: StreamerConfig {
                poll_interval: Some(Duration::from_millis(10)),
                ..StreamerConfig::default()
            },
            // No machine check: whirl would refuse this program before sending a byte, and
            // the test is about what the controller does when such a line reaches it.
            machine: None,
            ..StreamOptions::default()
        },
    );
    let alarm = u16::from(Alarm::SoftLimit.code());
    assert_eq!(
        outcome.ending,
        Ending::Stopped(StopReason::Alarm { code: alarm }),
        "{outcome:?}"
    );
    assert!(outcome.alarms.contains(&alarm), "{:?}", outcome.alarms);

    let events = link.events();
    assert!(
        events.iter().any(|e| matches!(
            e,
            Event::Alarm {
                alarm: Alarm::SoftLimit,
                ..
            }
        )),
        "the simulator raised no soft-limit alarm"
    );
    // grbl checks the target before planning the line (`mc_line`), so the offending line
    // queues nothing, and the alarm purges everything after it.
    let bad_n = n_of(offending);
    let late: Vec<_> = executed(&events)
        .filter(|b| b.n.is_none_or(|n| n >= bad_n))
        .map(|b| b.n)
        .collect();
    assert!(late.is_empty(), "executed at or after N{bad_n}: {late:?}");
    // The machine never went past the travel: position is retained inside it.
    let past: Vec<_> = executed(&events)
        .filter(|b| b.to.x > x_max || b.target.x > x_max)
        .collect();
    assert!(past.is_empty(), "beyond X {x_max}: {past:?}");
    // A controlled stop, so the position is retained (ALARM:2's own message): the machine
    // slowed to rest inside the move it was on, cut short, rather than stopping dead.
    let last = executed(&events)
        .last()
        .expect("moves ran before the alarm");
    assert!(!last.completed, "the machine was moving: {last:?}");
    assert!(last.speed_at(last.end_time) < 1e-9, "at rest: {last:?}");
    assert!(
        last.phases.iter().any(|p| p.accel < 0.0),
        "braked to the stop: {last:?}"
    );

    // The streamer's resume point skips nothing: every move before it was carried out to
    // its end, and no line past the ones it lists as possibly executed moved at all.
    let resume = outcome.resume.expect("a resume point after an alarm");
    assert!(
        resume.line_index > 1,
        "no line proven executed, so nothing below is checked: {resume:?}"
    );
    for index in 1..resume.line_index {
        assert!(
            executed(&events).any(|b| b.n == Some(n_of(index)) && b.completed),
            "resume at line {} but N{} did not finish ({resume:?})",
            resume.line_index + 1,
            n_of(index)
        );
    }
    let unlisted = resume.possibly_executed.end.max(resume.line_index);
    let moved: Vec<_> = executed(&events)
        .filter(|b| b.n.is_none_or(|n| n >= n_of(unlisted)))
        .map(|b| b.n)
        .collect();
    assert!(
        moved.is_empty(),
        "executed, not listed: {moved:?} ({resume:?})"
    );
}

#[test]
fn feed_hold_then_resume_completes_every_line_once() {
    // 40 moves of about 5 mm at 10 mm/s: 20 s of simulated motion, 1 s of wall time at 20×,
    // slow enough for a hold to land mid-program and fast enough for the test.
    let lines = program(40, 5.0, 600.0);
    let hold_after = n_of(12);
    let link = Link::start(ControllerOptions::default(), scaled());
    let (commands, receiver) = control();
    // The operator: feed hold once the machine is well into the program, cycle start once
    // it has come to rest in the hold, each on what the simulator shows.
    let machine = link.log.clone();
    let operator = std::thread::spawn(move || {
        machine.wait_for(&format!("N{hold_after} executed"), |events| {
            executed(events).any(|b| b.n >= Some(hold_after))
        });
        assert!(commands.hold());
        machine.wait_for("the machine at rest in a feed hold", |events| {
            last_state(events) == Some(MachineState::Hold { complete: true })
        });
        assert!(commands.resume());
    });
    let outcome = link.stream(
        &lines,
        StreamOptions {
            commands: Some(receiver),
            machine: Some(profile()),
            ..StreamOptions::default()
        },
    );
    operator.join().expect("the operator held and resumed");
    assert!(outcome.completed(), "{outcome:?}");
    assert_eq!(outcome.lines_acked, lines.len());

    let events = link.events();
    // grbl's hold: decelerate (Hold:1), stand still (Hold:0), run again after `~`.
    let states: Vec<(f64, MachineState)> = events
        .iter()
        .filter_map(|e| match e {
            Event::State { time, state } => Some((*time, *state)),
            _ => None,
        })
        .collect();
    let held = states
        .iter()
        .position(|s| s.1 == MachineState::Hold { complete: true })
        .expect("the machine came to rest in the hold");
    assert!(held > 0, "{states:?}");
    assert_eq!(
        states[held - 1].1,
        MachineState::Hold { complete: false },
        "decelerating first: {states:?}"
    );
    assert_eq!(states[held + 1].1, MachineState::Run, "{states:?}");
    let (from, to) = (states[held].0, states[held + 1].0);
    assert!(to > from, "the hold lasted no time: {states:?}");
    // Nothing moved while held: no block started, and the block the machine stopped in
    // stood still until the resume.
    let started: Vec<_> = executed(&events)
        .filter(|b| b.start_time > from && b.start_time < to)
        .map(|b| b.n)
        .collect();
    assert!(started.is_empty(), "started while held: {started:?}");
    let spanning: Vec<&ExecutedBlock> = executed(&events)
        .filter(|b| b.start_time <= from && b.end_time >= to)
        .collect();
    assert_eq!(spanning.len(), 1, "one block held mid-way: {spanning:?}");
    assert_eq!(spanning[0].position_at(from), spanning[0].position_at(to));
    assert!(
        spanning[0].completed,
        "the held block finished after the resume"
    );
    assert_each_move_executed_once(&events, lines.len());
}

#[test]
fn an_error_mid_stream_stops_cleanly_and_resume_from_line_executes_every_line_once() {
    let failing = 119;
    let fixed = program(200, 0.5, 3000.0);
    let mut broken = fixed.clone();
    // Q is no word grbl knows: `error:20`, and the line does nothing.
    broken[failing].push_str(" Q5");
    let link = Link::start(ControllerOptions::default(), fast());
    let first = link.stream(
        &broken,
        StreamOptions {
            // No machine check: whirl's own reader refuses Q before a byte is sent, and the
            // test is about the controller refusing it mid-stream.
            machine: None,
            ..StreamOptions::default()
        },
    );
    assert_eq!(
        first.ending,
        Ending::Stopped(StopReason::Error {
            line: LineRef::Program(failing),
            code: code(GrblError::UnsupportedCommand),
        }),
        "{first:?}"
    );
    assert_eq!(first.failed_line, Some(failing));
    let resume = first.resume.clone().expect("a resume point after an error");
    assert_eq!(
        (resume.line_index, resume.basis),
        (failing, ResumeBasis::FailedLine)
    );
    assert!(resume.possibly_executed.is_empty(), "{resume:?}");
    assert!(resume.executed_after_failure.is_empty(), "{resume:?}");

    // An error stop keeps the planner: the moves before the failed line finish. Once the
    // machine is idle (the condition `whirl::protocol::grbl::resume` gives for resuming at the
    // failed line) nothing at or after it has run.
    let failing_n = n_of(failing);
    link.log
        .wait_for("the moves before the failed line done", |events| {
            executed(events).any(|b| b.n == Some(failing_n - 1))
                && last_state(events) == Some(MachineState::Idle)
        });
    let events = link.events();
    let late: Vec<_> = executed(&events)
        .filter(|b| b.n.is_none_or(|n| n >= failing_n))
        .map(|b| b.n)
        .collect();
    assert!(
        late.is_empty(),
        "executed at or after N{failing_n}: {late:?}"
    );
    // grblHAL's sticky error: the lines already in the buffer came back with the same code,
    // and the streamer took them as consequences, not failures: its log names one error.
    let refused_after = answers(&events)
        .iter()
        .filter(|a| a.0 > Some(failing_n) && a.2 == Some(GrblError::UnsupportedCommand))
        .count();
    assert!(
        refused_after > 0,
        "no line after the failed one was in flight"
    );
    let errors: Vec<usize> = link
        .streamer_log()
        .iter()
        .filter_map(|e| match e {
            log::Event::Error { line, .. } => Some(*line),
            _ => None,
        })
        .collect();
    assert_eq!(errors, [failing + 1]);

    // The line fixed, the same program resumed at the failed line on the same controller.
    let second = link.stream(
        &fixed,
        StreamOptions {
            resume_at: first.failed_line,
            machine: Some(profile()),
            ..StreamOptions::default()
        },
    );
    assert!(second.completed(), "{second:?}");
    assert_eq!(second.lines_acked, fixed.len() - failing);
    assert_each_move_executed_once(&link.events(), fixed.len());
}

#[test]
fn grblhal_sticky_error_answers_later_lines_with_the_same_error_until_cleared() {
    let failing = 19;
    let mut lines = program(40, 0.5, 3000.0);
    lines[failing].push_str(" Q5");
    let link = Link::start(ControllerOptions::default(), fast());
    let first = link.stream(
        &lines,
        StreamOptions {
            // No machine check: whirl's own reader refuses Q before a byte is sent.
            machine: None,
            ..StreamOptions::default()
        },
    );
    assert_eq!(first.failed_line, Some(failing), "{first:?}");
    // The next run starts with G-code, not `$I`: a `$` command sets its own result and so
    // clears the sticky error itself, which would hide whether the empty line did.
    let next = vec![
        "N1001 G0 X10 Z0".to_owned(),
        "N1002 G1 X12 Z-1 F600".to_owned(),
    ];
    let second = link.stream(
        &next,
        StreamOptions {
            streamer: StreamerConfig {
                query_build_info: false,
                ..StreamerConfig::default()
            },
            machine: Some(profile()),
            ..StreamOptions::default()
        },
    );
    assert!(second.completed(), "{second:?}");

    let events = link.events();
    let answers = answers(&events);
    let failing_n = n_of(failing);
    let at = answers
        .iter()
        .position(|a| a.0 == Some(failing_n))
        .expect("the failing line answered");
    let error = answers[at].2.expect("the failing line refused");
    let after = &answers[at + 1..];
    let cleared = after
        .iter()
        .position(|a| a.1.is_empty())
        .expect("the streamer's empty line reached the controller");
    let (sticky, rest) = after.split_at(cleared);
    // Every line after the failed one that was already sent got the same error, unparsed;
    // the streamer's log says which lines it had sent after the failing one.
    assert!(
        !sticky.is_empty(),
        "no line after the failed one was in flight"
    );
    assert!(sticky.iter().all(|a| a.2 == Some(error)), "{sticky:?}");
    let refused: Vec<Option<u32>> = sticky.iter().map(|a| a.0).collect();
    let sent_after: Vec<Option<u32>> = link
        .streamer_log()
        .iter()
        .filter_map(|e| match e {
            log::Event::Sent { line, .. } if *line > failing + 1 && *line <= lines.len() => {
                Some(Some(n_of(*line - 1)))
            }
            _ => None,
        })
        .collect();
    assert_eq!(refused, sent_after);
    // The empty line cleared it: it and the next run's G-code lines were accepted, and ran.
    assert!(
        rest.iter().all(|a| a.2.is_none()),
        "refused after the clear: {rest:?}"
    );
    let next_answered: Vec<Option<u32>> = rest[1..].iter().map(|a| a.0).collect();
    assert_eq!(next_answered, [Some(1001), Some(1002)]);
    let ran: Vec<Option<u32>> = executed(&events)
        .map(|b| b.n)
        .filter(|n| *n >= Some(failing_n))
        .collect();
    assert_eq!(
        ran,
        [Some(1001), Some(1002)],
        "nothing of the refused lines ran"
    );
}

/// `count` numbered lines of three lengths, as a planned program mixes them: after the
/// modes, a rapid placing every axis and a first feed move setting G1 and F, a bare modal
/// move `N… Z…` (a dozen bytes), a full `G1 X… Z…` (about 25) and, every seventh line, a
/// long one with C, F and a comment (about 70), which a 128-byte buffer must still take
/// whole. Z advances on every line, so every move has a length.
fn mixed_program(count: usize) -> Vec<String> {
    let mut lines = vec![
        "N1 G21 G90 G94".to_owned(),
        "N2 G0 X10 Z0 C0".to_owned(),
        "N3 G1 Z0.1 F3000".to_owned(),
    ];
    while lines.len() < count {
        let i = lines.len();
        let n = n_of(i);
        let z = i as f64 * 0.05;
        lines.push(match i % 7 {
            0 => format!(
                "N{n} G1 X{:.4} Z{z:.4} C{:.3} F3000 (long line, as a post writes)",
                10.0 + (i % 3) as f64 * 0.5,
                i as f64 * 0.25
            ),
            1 | 4 => format!("N{n} G1 X{:.3} Z{z:.3}", 10.0 + (i % 5) as f64 * 0.2),
            _ => format!("N{n} Z{z:.3}"),
        });
    }
    lines
}

#[test]
fn character_counting_never_overflows_at_128_and_1024_bytes() {
    let lines = mixed_program(2400);
    assert!(lines.iter().any(|l| l.len() >= 70));
    for rx in [128, 1024] {
        let link = Link::start(
            ControllerOptions {
                rx_buffer_size: rx,
                ..ControllerOptions::default()
            },
            fast(),
        );
        // The default streamer configuration asks `$I` for the buffer size.
        let outcome = link.stream(
            &lines,
            StreamOptions {
                machine: Some(profile()),
                ..StreamOptions::default()
            },
        );
        assert!(outcome.completed(), "rx {rx}: {outcome:?}");
        assert_eq!(outcome.lines_acked, lines.len(), "rx {rx}");
        let learned = format!("controller receive buffer: {rx} bytes");
        assert!(
            link.streamer_log()
                .iter()
                .any(|e| matches!(e, log::Event::Message { text } if *text == learned)),
            "rx {rx}: the streamer did not learn the size from $I"
        );

        let events = link.events();
        let overflows = events
            .iter()
            .filter(|e| matches!(e, Event::RxOverflow { .. }))
            .count();
        assert_eq!(overflows, 0, "rx {rx}");
        // One answer per line, each `ok`: the controller read every line whole.
        let answers = answers(&events);
        let refused: Vec<_> = answers.iter().filter(|a| a.2.is_some()).collect();
        assert!(refused.is_empty(), "rx {rx}: {refused:?}");
        let mut per_line: BTreeMap<Option<u32>, usize> = BTreeMap::new();
        for a in &answers {
            *per_line.entry(a.0).or_default() += 1;
        }
        for index in 0..lines.len() {
            assert_eq!(
                per_line.get(&Some(n_of(index))),
                Some(&1),
                "rx {rx}: N{} answered",
                n_of(index)
            );
        }
        assert_each_move_executed_once(&events, lines.len());
    }

    // The check is live: a streamer told the buffer is 1024 bytes, without asking, overruns
    // a 128-byte controller, and the simulator reports it.
    let link = Link::start(
        ControllerOptions {
            rx_buffer_size: 128,
            ..ControllerOptions::default()
        },
        fast(),
    );
    let outcome = link.stream(
        &lines,
        StreamOptions {
            streamer: StreamerConfig {
                query_build_info: false,
                rx_size: 1024,
                ..StreamerConfig::default()
            },
            machine: Some(profile()),
            ..StreamOptions::default()
        },
    );
    assert!(!outcome.completed(), "{outcome:?}");
    assert!(
        link.events()
            .iter()
            .any(|e| matches!(e, Event::RxOverflow { .. })),
        "no overflow reported: the check above could not fail"
    );
}
