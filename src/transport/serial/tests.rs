//! The serial transport's tests: a model controller ([`Fake`] plus time, status reports
//! and scripted failures) over an in-memory pipe in paused time, and one run over a real
//! pseudo-terminal pair.

use super::*;
use crate::log::Record;
use crate::protocol::grbl::fake::Fake;
use crate::protocol::grbl::response::parse_status;
use crate::protocol::grbl::ResumeBasis;
use std::sync::{Arc, Mutex};
use tokio::io::DuplexStream;

/// How the model controller behaves beyond grbl's protocol (which [`Fake`] speaks).
#[derive(Debug, Clone, Default)]
struct Script {
    /// Each line "executes" this long before its answer; zero answers at once.
    line_time: Duration,
    /// Status reports that still say `Run` after the last line is answered (the planner
    /// finishing its moves).
    run_reports_after: usize,
    /// Stop answering lines once this many have executed (a hung controller).
    hang_after: Option<usize>,
    /// Close the connection once this many lines have executed.
    close_after: Option<usize>,
    /// Never answer a status request (`?`).
    no_status: bool,
}

/// The controller's side of the link: `Fake` for the protocol, plus time per line, a
/// status report that moves (X = lines executed, Z = X / 2, C = 10 X) and says `Run`
/// while lines are queued, and the script's failures. Ends when the host closes the
/// stream, and hands back the model for inspection.
async fn controller<S: AsyncRead + AsyncWrite + Unpin>(
    mut io: S,
    mut fake: Fake,
    script: Script,
) -> Fake {
    let mut buffer = [0u8; 512];
    let mut run_reports = 0usize;
    let mut next_line_at: Option<Instant> = None;
    loop {
        let hung = hung_now(&fake, &script) || held(&fake);
        tokio::select! {
            read = io.read(&mut buffer) => {
                let n = match read {
                    Ok(0) | Err(_) => break,
                    Ok(n) => n,
                };
                let bytes: Vec<u8> = buffer[..n]
                    .iter()
                    .copied()
                    .filter(|&b| !(script.no_status && b == b'?'))
                    .collect();
                let bytes = &bytes[..];
                let running = fake.buffered() > 0 || run_reports > 0;
                if bytes.contains(&b'?') && fake.buffered() == 0 && run_reports > 0 {
                    run_reports -= 1;
                }
                let done = fake.executed.len() as f64;
                let state = match (held(&fake), running) {
                    (true, _) => "Hold:0",
                    (false, true) => "Run",
                    (false, false) => "Idle",
                };
                fake.status = format!(
                    "<{}|MPos:{:.3},0.000,{:.3},{:.3}|Bf:{},{}|FS:0,0>",
                    state,
                    done,
                    done / 2.0,
                    done * 10.0,
                    if running { 30 } else { 35 },
                    1023 - fake.buffered(),
                );
                fake.write(bytes);
                if script.line_time.is_zero() {
                    while !hung_now(&fake, &script) && !held(&fake) && fake.process() {
                        run_reports = script.run_reports_after;
                    }
                } else if next_line_at.is_none() && fake.buffered() > 0 {
                    next_line_at = Some(Instant::now() + script.line_time);
                }
            }
            () = wait_until(next_line_at), if !hung => {
                next_line_at = None;
                if fake.process() {
                    run_reports = script.run_reports_after;
                    if fake.buffered() > 0 {
                        next_line_at = Some(Instant::now() + script.line_time);
                    }
                }
            }
        }
        let output = fake.take_output();
        if !output.is_empty() && io.write_all(&output).await.is_err() {
            break;
        }
        if script.close_after.is_some_and(|n| fake.executed.len() >= n) {
            break;
        }
    }
    fake
}

fn hung_now(fake: &Fake, script: &Script) -> bool {
    script.hang_after.is_some_and(|n| fake.executed.len() >= n)
}

/// A feed hold (`!`) not yet followed by a cycle start (`~`): nothing executes.
fn held(fake: &Fake) -> bool {
    fake.realtime
        .iter()
        .rev()
        .find(|&&b| b == b'!' || b == b'~')
        == Some(&b'!')
}

/// `n` lines of `G1 X<i> F100`.
fn moves(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("G1 X{i} F100")).collect()
}

fn options() -> StreamOptions {
    StreamOptions {
        port_name: "/dev/ttyTEST".to_owned(),
        program: "test.nc".to_owned(),
        ..StreamOptions::default()
    }
}

struct Run {
    result: Result<StreamOutcome, SerialError>,
    fake: Fake,
    records: Vec<Record>,
}

/// Streams `lines` to the model controller over an in-memory pipe, logging to a
/// temporary file, and reads the log back.
async fn run(lines: Vec<String>, options: StreamOptions, fake: Fake, script: Script) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    let mut log = ExecLog::append(&path).unwrap();
    let (host, device): (DuplexStream, DuplexStream) = tokio::io::duplex(4096);
    let controller = tokio::spawn(controller(device, fake, script));
    let result = stream(host, lines, options, &mut log).await;
    let fake = controller.await.unwrap();
    let read = log::read(&path).unwrap();
    assert!(!read.torn_tail);
    Run {
        result,
        fake,
        records: read.records,
    }
}

fn events(records: &[Record]) -> Vec<&log::Event> {
    records.iter().map(|r| &r.event).collect()
}

fn sent_lines(records: &[Record]) -> Vec<usize> {
    records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Sent { line, .. } => Some(*line),
            _ => None,
        })
        .collect()
}

fn acked_lines(records: &[Record]) -> Vec<usize> {
    records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Ack { line } => Some(*line),
            _ => None,
        })
        .collect()
}

fn statuses(records: &[Record]) -> Vec<(f64, String, [f64; 3])> {
    records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Status { state, pos, .. } => Some((r.t, state.clone(), *pos)),
            _ => None,
        })
        .collect()
}

fn assert_start_and_end(records: &[Record], completed: bool) {
    let events = events(records);
    assert!(
        matches!(events.first(), Some(log::Event::Start { transport, .. }) if transport == TRANSPORT),
        "{events:?}"
    );
    assert!(
        matches!(events.last(), Some(log::Event::End { completed: c, .. }) if *c == completed),
        "{events:?}"
    );
    let times: Vec<f64> = records.iter().map(|r| r.t).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
}

#[tokio::test(start_paused = true)]
async fn the_whole_program_is_acked_and_logged_in_order() {
    let lines = moves(60);
    let run = run(lines.clone(), options(), Fake::grbl(128), Script::default()).await;
    let outcome = run.result.unwrap();
    assert!(outcome.completed(), "{outcome:?}");
    assert_eq!(
        (outcome.lines_total, outcome.lines_sent, outcome.lines_acked),
        (60, 60, 60)
    );
    assert!(outcome.resume.is_none());
    assert!(outcome.bytes_written > lines.iter().map(|l| l.len() as u64 + 1).sum());
    assert!(outcome.link_utilization.is_none(), "no baud given");
    assert_eq!(run.fake.executed, lines);
    assert!(!run.fake.overflowed);
    assert!(run.fake.max_fill <= 127);

    assert_start_and_end(&run.records, true);
    let events = events(&run.records);
    assert!(matches!(
        events.first(),
        Some(log::Event::Start { lines: 60, program, .. }) if program == "test.nc"
    ));
    assert_eq!(sent_lines(&run.records), (1..=60).collect::<Vec<_>>());
    assert_eq!(acked_lines(&run.records), (1..=60).collect::<Vec<_>>());
    for (k, text) in lines.iter().enumerate() {
        let line = k + 1;
        let sent = events.iter().position(
            |e| matches!(e, log::Event::Sent { line: l, text: t } if *l == line && t == text),
        );
        let acked = events
            .iter()
            .position(|e| matches!(e, log::Event::Ack { line: l } if *l == line));
        assert!(sent.unwrap() < acked.unwrap(), "line {line}");
    }
    assert!(!events.iter().any(|e| matches!(e, log::Event::Error { .. })));
}

#[tokio::test(start_paused = true)]
async fn an_error_mid_stream_stops_cleanly_with_the_failed_line_and_resume_point() {
    let lines = moves(20);
    let mut fake = Fake::grblhal(1024);
    fake.fail = vec![(lines[7].clone(), 33)];
    let script = Script {
        line_time: Duration::from_millis(10),
        ..Script::default()
    };
    let run = run(lines.clone(), options(), fake, script).await;
    let outcome = run.result.unwrap();
    assert_eq!(
        outcome.ending,
        Ending::Stopped(StopReason::Error {
            line: LineRef::Program(7),
            code: 33
        })
    );
    assert_eq!(outcome.failed_line, Some(7));
    let resume = outcome.resume.unwrap();
    assert_eq!(resume.line_index, 7);
    assert_eq!(resume.basis, ResumeBasis::FailedLine);
    assert!(resume.executed_after_failure.is_empty());
    assert_eq!(outcome.lines_acked, 7);
    // grblHAL's sticky error: nothing after the failed line ran.
    assert_eq!(run.fake.executed, lines[..7]);

    assert_start_and_end(&run.records, false);
    let events = events(&run.records);
    assert!(events.iter().any(|e| matches!(
        e,
        log::Event::Error { line: 8, code: 33, message } if !message.is_empty()
    )));
    assert!(acked_lines(&run.records).iter().all(|&l| l <= 7));
    let Some(log::Event::End {
        reason: Some(reason),
        ..
    }) = events.last()
    else {
        panic!("no reason: {events:?}");
    };
    assert!(
        reason.contains("program line 8") && reason.contains("error:33"),
        "{reason}"
    );
}

#[tokio::test(start_paused = true)]
async fn status_polls_run_at_5_hz_of_paused_time() {
    let lines = moves(20);
    let script = Script {
        line_time: Duration::from_millis(100),
        ..Script::default()
    };
    let options = StreamOptions {
        baud: Some(115_200),
        ..options()
    };
    let run = run(lines, options, Fake::grblhal(1024), script).await;
    let outcome = run.result.unwrap();
    assert!(outcome.completed(), "{outcome:?}");
    let wall = outcome.wall_time.as_secs_f64();
    // 21 lines ($I and the program) at 100 ms each.
    assert!((2.1..2.6).contains(&wall), "{wall}");

    let statuses = statuses(&run.records);
    let times: Vec<f64> = statuses.iter().map(|s| s.0).collect();
    for pair in times.windows(2) {
        let gap = pair[1] - pair[0];
        assert!((0.19..0.21).contains(&gap), "{times:?}");
    }
    let expected = wall / 0.2;
    assert!(
        (statuses.len() as f64 - expected).abs() <= 1.5,
        "{} reports in {wall} s",
        statuses.len()
    );
    // Positions come through X, Z, C from MPos (X Y Z C).
    let last = statuses.last().unwrap();
    assert_eq!(last.1, "Idle");
    assert_eq!(last.2, [20.0, 10.0, 200.0]);
    assert!(statuses.windows(2).all(|w| w[0].2[0] <= w[1].2[0]));

    let expected_use = outcome.bytes_written as f64 * 10.0 / (115_200.0 * wall);
    let measured = outcome.link_utilization.unwrap();
    assert!((measured - expected_use).abs() < 1e-9, "{measured}");
    assert!(outcome.streaming_utilization.is_some());
}

#[tokio::test(start_paused = true)]
async fn completion_waits_until_the_motion_has_finished() {
    let lines = moves(10);
    let script = Script {
        run_reports_after: 3,
        ..Script::default()
    };
    let run = run(lines, options(), Fake::grblhal(1024), script).await;
    let outcome = run.result.unwrap();
    assert!(outcome.completed(), "{outcome:?}");
    let acked_at = outcome.all_acked_at.unwrap();
    assert!(outcome.wall_time >= acked_at + Duration::from_millis(600));

    let events = events(&run.records);
    let last_ack = events
        .iter()
        .rposition(|e| matches!(e, log::Event::Ack { .. }))
        .unwrap();
    let after: Vec<&str> = events[last_ack..]
        .iter()
        .filter_map(|e| match e {
            log::Event::Status { state, .. } => Some(state.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(after.last(), Some(&"Idle"), "{after:?}");
    assert!(
        after.iter().filter(|s| **s == "Run").count() >= 3,
        "{after:?}"
    );
    assert_start_and_end(&run.records, true);
}

#[tokio::test(start_paused = true)]
async fn eof_from_the_controller_is_an_error_naming_the_port() {
    let script = Script {
        line_time: Duration::from_millis(10),
        close_after: Some(5),
        ..Script::default()
    };
    let run = run(moves(20), options(), Fake::grblhal(1024), script).await;
    let error = run.result.unwrap_err();
    assert!(
        matches!(&error, SerialError::Eof { port, resume: Some(_) } if port == "/dev/ttyTEST"),
        "{error:?}"
    );
    assert!(error.to_string().contains("/dev/ttyTEST"), "{error}");
    assert_start_and_end(&run.records, false);
    assert!(matches!(
        run.records.last().map(|r| &r.event),
        Some(log::Event::End { reason: Some(reason), .. }) if reason.contains("/dev/ttyTEST")
    ));
}

#[tokio::test(start_paused = true)]
async fn a_silent_controller_times_out_with_a_feed_hold_and_a_resume_point() {
    let script = Script {
        hang_after: Some(3),
        ..Script::default()
    };
    let options = StreamOptions {
        no_progress_timeout: Some(Duration::from_secs(5)),
        ..options()
    };
    let run = run(moves(10), options, Fake::grblhal(1024), script).await;
    let outcome = run.result.unwrap();
    assert_eq!(
        outcome.ending,
        Ending::TimedOut {
            after: Duration::from_secs(5),
            planned: Duration::ZERO,
        }
    );
    assert_eq!(outcome.lines_acked, 3);
    let wall = outcome.wall_time.as_secs_f64();
    assert!((5.0..5.5).contains(&wall), "{wall}");
    assert_eq!(run.fake.realtime.last(), Some(&b'!'));
    // A stall ends like every other end: where to resume, in the outcome and the log,
    // never past a line not known to have run.
    let resume = outcome.resume.expect("a resume point");
    assert!(resume.line_index <= 3, "{resume:?}");
    let n = run.records.len();
    assert!(matches!(
        &run.records[n - 2].event,
        log::Event::ResumeAt { line, .. } if *line == resume.line_index + 1
    ));
    assert_start_and_end(&run.records, false);
    assert!(matches!(
        run.records.last().map(|r| &r.event),
        Some(log::Event::End { reason: Some(reason), .. })
            if reason.starts_with("stalled: nothing new from the controller for 5 s")
    ));
}

#[tokio::test(start_paused = true)]
async fn a_long_move_in_flight_is_allowed_its_planned_time_before_a_stall() {
    // The controller falls silent after three lines, with the fourth planned at 8 s in
    // flight: silence is a stall only 5 s past those 8 s.
    let script = Script {
        hang_after: Some(3),
        ..Script::default()
    };
    let mut durations = vec![0.1; 10];
    durations[3] = 8.0;
    let options = StreamOptions {
        no_progress_timeout: Some(Duration::from_secs(5)),
        line_durations: Some(durations),
        ..options()
    };
    let run = run(moves(10), options, Fake::grblhal(1024), script).await;
    let outcome = run.result.unwrap();
    assert_eq!(
        outcome.ending,
        Ending::TimedOut {
            after: Duration::from_secs(5),
            planned: Duration::from_secs(8),
        }
    );
    let wall = outcome.wall_time.as_secs_f64();
    assert!((13.0..13.5).contains(&wall), "{wall}");
    assert!(outcome.ending.to_string().contains("beyond the 8.0 s"));
}

#[tokio::test(start_paused = true)]
async fn a_stop_holds_and_ends_once_the_controller_reports_the_hold_complete() {
    let (control, receiver) = crate::transport::control();
    let script = Script {
        line_time: Duration::from_millis(100),
        ..Script::default()
    };
    let options = StreamOptions {
        commands: Some(receiver),
        ..options()
    };
    let caller = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(control.stop("SIGINT"));
    });
    let run = run(moves(40), options, Fake::grblhal(1024), script).await;
    caller.await.unwrap();
    let outcome = run.result.unwrap();
    assert!(matches!(
        &outcome.ending,
        Ending::Stopped(StopReason::Interrupted { reason }) if reason == "SIGINT"
    ));
    // The hold went out, nothing after it, and the run ended on a report of it complete.
    assert_eq!(
        run.fake
            .realtime
            .iter()
            .filter(|&&b| b != b'?')
            .collect::<Vec<_>>(),
        [&b'!']
    );
    assert_eq!(
        statuses(&run.records).last().map(|s| s.1.as_str()),
        Some("Hold:0")
    );
    let resume = outcome.resume.unwrap();
    assert!(resume.line_index < 40);
    let n = run.records.len();
    assert!(matches!(
        run.records[n - 2].event,
        log::Event::ResumeAt { line, .. } if line == resume.line_index + 1
    ));
    assert_start_and_end(&run.records, false);
}

#[tokio::test(start_paused = true)]
async fn a_stop_without_a_report_of_the_stand_ends_when_the_wait_runs_out_and_says_so() {
    let (control, receiver) = crate::transport::control();
    let script = Script {
        line_time: Duration::from_millis(100),
        no_status: true,
        ..Script::default()
    };
    let options = StreamOptions {
        commands: Some(receiver),
        no_progress_timeout: Some(Duration::from_secs(3)),
        ..options()
    };
    let caller = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(control.stop("SIGTERM"));
    });
    let run = run(moves(40), options, Fake::grblhal(1024), script).await;
    caller.await.unwrap();
    let outcome = run.result.unwrap();
    assert!(matches!(
        outcome.ending,
        Ending::Stopped(StopReason::Interrupted { .. })
    ));
    // The wait is the no-progress timeout, counted from the stop.
    let wall = outcome.wall_time.as_secs_f64();
    assert!((3.5..4.0).contains(&wall), "{wall}");
    assert!(run.records.iter().any(|r| matches!(
        &r.event,
        log::Event::Message { text } if text.contains("did not report the machine at rest")
    )));
    assert_start_and_end(&run.records, false);
}

#[tokio::test(start_paused = true)]
async fn the_caller_holds_resumes_and_resets() {
    let (control, receiver) = crate::transport::control();
    let script = Script {
        line_time: Duration::from_millis(100),
        ..Script::default()
    };
    let options = StreamOptions {
        commands: Some(receiver),
        // A hold is not a stall, even one longer than the watchdog.
        no_progress_timeout: Some(Duration::from_millis(300)),
        ..options()
    };
    let caller = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(control.hold());
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(control.resume());
        tokio::time::sleep(Duration::from_millis(500)).await;
        assert!(control.abort());
    });
    let run = run(moves(40), options, Fake::grblhal(1024), script).await;
    caller.await.unwrap();
    let outcome = run.result.unwrap();
    assert_eq!(outcome.ending, Ending::Stopped(StopReason::SoftReset));
    let resume = outcome.resume.unwrap();
    assert!(resume.line_index <= outcome.lines_acked);
    let commands: Vec<u8> = run
        .fake
        .realtime
        .iter()
        .copied()
        .filter(|&b| b != b'?')
        .collect();
    assert_eq!(commands, [b'!', b'~', 0x18]);
    let messages: Vec<&str> = run
        .records
        .iter()
        .filter_map(|r| match &r.event {
            log::Event::Message { text } if text.ends_with("requested") => Some(text.as_str()),
            _ => None,
        })
        .collect();
    assert!(
        statuses(&run.records).iter().any(|s| s.1 == "Hold:0"),
        "the controller held"
    );
    assert_eq!(
        messages,
        [
            "feed hold requested",
            "resume requested",
            "soft reset requested"
        ]
    );
    assert_start_and_end(&run.records, false);
}

#[tokio::test(start_paused = true)]
async fn the_machine_check_refuses_a_program_before_any_byte() {
    let machine = MachineProfile::builtin_sim().unwrap();
    let lines = vec![
        "G21 G90 G94".to_owned(),
        "G0 X0 Z0 C0".to_owned(),
        "G0 X1000".to_owned(),
    ];
    let options = StreamOptions {
        machine: Some(machine),
        ..options()
    };
    let run = run(lines, options, Fake::grblhal(1024), Script::default()).await;
    let error = run.result.unwrap_err();
    // The third line goes to X1000, past the travel: the error names that line.
    assert!(
        matches!(
            error,
            SerialError::Preflight(PreflightError::Limits { line: 3, .. })
        ),
        "{error:?}"
    );
    assert!(error.to_string().starts_with("line 3: "), "{error}");
    assert!(run.fake.realtime.is_empty());
    assert_eq!(run.fake.max_fill, 0);
    assert!(run.records.is_empty(), "nothing ran, nothing logged");
}

#[tokio::test(start_paused = true)]
async fn progress_reports_reach_the_end() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&seen);
    let options = StreamOptions {
        on_progress: Some(Box::new(move |p: &Progress| {
            sink.lock().unwrap().push(p.clone());
        })),
        ..options()
    };
    let script = Script {
        line_time: Duration::from_millis(50),
        ..Script::default()
    };
    let run = run(moves(12), options, Fake::grblhal(1024), script).await;
    assert!(run.result.unwrap().completed());
    let seen = seen.lock().unwrap();
    let last = seen.last().unwrap();
    assert_eq!((last.unit, last.done, last.total), (Unit::Lines, 12, 12));
    assert!(last.finishing);
    assert_eq!(last.fraction(), 1.0);
    assert_eq!(last.position, Some([12.0, 6.0, 120.0]));
    assert!(seen.windows(2).all(|w| w[0].done <= w[1].done));
    assert!(seen
        .iter()
        .any(|p| p.left.is_some_and(|left| left > Duration::ZERO)));
}

#[test]
fn status_positions_are_machine_x_z_c() {
    let axes = StatusAxes::default();
    let mpos = parse_status("Run|MPos:1.000,0.000,2.000,3.000|Bf:30,1000").unwrap();
    assert_eq!(machine_xzc(&mpos, None, axes), Some([1.0, 2.0, 3.0]));
    // WPos needs the work offset: WPos + WCO = MPos.
    let wpos = parse_status("Hold:0|WPos:1.000,0.000,2.000,3.000").unwrap();
    assert_eq!(machine_xzc(&wpos, None, axes), None);
    let wco = [10.0, 0.0, 20.0, 30.0];
    assert_eq!(
        machine_xzc(&wpos, Some(&wco), axes),
        Some([11.0, 22.0, 33.0])
    );
    assert_eq!(state_name(&wpos), "Hold:0");
    // A controller without C.
    let xyz = parse_status("Idle|MPos:1,0,2").unwrap();
    let no_c = StatusAxes { c: None, ..axes };
    assert_eq!(machine_xzc(&xyz, None, no_c), Some([1.0, 2.0, 0.0]));
    assert_eq!(machine_xzc(&xyz, None, axes), None);
}

#[test]
fn link_utilization_is_bits_over_capacity() {
    assert_eq!(
        link_utilization(11_520, 115_200, Duration::from_secs(1)),
        Some(1.0)
    );
    assert_eq!(
        link_utilization(5_760, 115_200, Duration::from_secs(1)),
        Some(0.5)
    );
    assert_eq!(link_utilization(100, 115_200, Duration::ZERO), None);
    assert_eq!(link_utilization(100, 0, Duration::from_secs(1)), None);
    // More bits than the rate carries: no serial line at that rate, so no figure.
    assert_eq!(
        link_utilization(11_521, 115_200, Duration::from_secs(1)),
        None
    );
}

/// The real serial path: a pseudo-terminal pair opened by tokio-serial, in real time.
#[tokio::test]
async fn streams_over_a_pseudo_terminal_pair() {
    let (host, device) = tokio_serial::SerialStream::pair().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    let mut log = ExecLog::append(&path).unwrap();
    let lines = moves(50);
    let controller = tokio::spawn(controller(device, Fake::grbl(128), Script::default()));
    let options = StreamOptions {
        port_name: "pty".to_owned(),
        baud: Some(115_200),
        streamer: StreamerConfig {
            poll_interval: Some(Duration::from_millis(20)),
            ..StreamerConfig::default()
        },
        no_progress_timeout: Some(Duration::from_secs(5)),
        ..StreamOptions::default()
    };
    let outcome = tokio::time::timeout(
        Duration::from_secs(20),
        stream(host, lines.clone(), options, &mut log),
    )
    .await
    .unwrap()
    .unwrap();
    assert!(outcome.completed(), "{outcome:?}");
    assert_eq!(outcome.lines_acked, 50);
    let fake = controller.await.unwrap();
    assert_eq!(fake.executed, lines);
    assert!(!fake.overflowed);
    let records = log::read(&path).unwrap().records;
    assert_eq!(acked_lines(&records), (1..=50).collect::<Vec<_>>());
    assert_start_and_end(&records, true);
}
