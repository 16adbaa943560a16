//! The executed-path log's tests.

use super::*;

fn sample() -> Vec<(f64, Event)> {
    vec![
        (
            0.0,
            Event::Start {
                program: "p.nc".into(),
                lines: 2,
                transport: "serial".into(),
            },
        ),
        (
            0.1,
            Event::Sent {
                line: 1,
                text: "G1 X1 F100".into(),
            },
        ),
        (0.2, Event::Ack { line: 1 }),
        (
            0.3,
            Event::Status {
                state: "Run".into(),
                pos: [0.5, 0.0, 0.0],
                blocks_free: Some(34),
                rx_free: Some(1000),
                line: None,
            },
        ),
        (
            0.9,
            Event::Executed {
                line: Some(1),
                times: [0.2, 0.8],
                from: [0.0; 3],
                to: [1.0, 0.0, 0.0],
                rapid: false,
            },
        ),
        (
            1.0,
            Event::End {
                completed: true,
                reason: None,
            },
        ),
    ]
}

#[test]
fn events_round_trip_one_per_line_and_appending_keeps_what_was_there() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    for (t, e) in sample() {
        ExecLog::append(&path).unwrap().write(t, e).unwrap();
    }
    let mut log = ExecLog::append(&path).unwrap();
    log.write(
        2.0,
        Event::Message {
            text: "again".into(),
        },
    )
    .unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().count(), sample().len() + 1);
    assert!(text.lines().all(|l| l.starts_with("{\"t\":")));
    let read = read(&path).unwrap();
    assert!(!read.torn_tail);
    assert!(read.skipped.is_empty());
    let back: Vec<(f64, Event)> = read.records.into_iter().map(|r| (r.t, r.event)).collect();
    assert_eq!(&back[..sample().len()], &sample()[..]);
}

#[test]
fn a_memory_log_keeps_every_event_in_order_for_every_clone() {
    let mut log = ExecLog::memory();
    let mut clone = log.clone();
    for (i, (t, e)) in sample().into_iter().enumerate() {
        if i % 2 == 0 {
            log.write(t, e).unwrap();
        } else {
            clone.write(t, e).unwrap();
        }
    }
    let kept: Vec<(f64, Event)> = log.records().into_iter().map(|r| (r.t, r.event)).collect();
    assert_eq!(kept, sample());
    assert_eq!(clone.records().len(), sample().len());
    // A reader following the run takes what is new since its last look.
    let n = sample().len();
    assert_eq!(clone.records_from(n - 1).len(), 1);
    assert_eq!(clone.records_from(n - 1)[0].event, sample()[n - 1].1);
    assert!(clone.records_from(n).is_empty());
    assert!(clone.records_from(n + 5).is_empty());
    // Nothing is kept by the others.
    let mut discard = ExecLog::discard();
    discard.write(0.0, sample()[0].1.clone()).unwrap();
    assert!(discard.records().is_empty());
}

#[test]
fn clones_from_two_threads_write_whole_events_to_one_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    let log = ExecLog::append(&path).unwrap();
    std::thread::scope(|scope| {
        for k in 0..2 {
            let mut log = log.clone();
            scope.spawn(move || {
                for i in 0..500 {
                    let text = format!("writer {k} event {i} {}", "x".repeat(200));
                    log.write(f64::from(i), Event::Message { text }).unwrap();
                }
            });
        }
    });
    let read = read(&path).unwrap();
    assert_eq!(read.records.len(), 1000);
    assert!(!read.torn_tail);
}

/// Writes `events` to `path` through [`ExecLog::append`], as one run does.
fn run_into(path: &Path, events: Vec<(f64, Event)>) {
    let mut log = ExecLog::append(path).unwrap();
    for (t, e) in events {
        log.write(t, e).unwrap();
    }
}

/// Appends `bytes` as they are: a write that broke off.
fn tear(path: &Path, bytes: &[u8]) {
    let mut f = OpenOptions::new().append(true).open(path).unwrap();
    f.write_all(bytes).unwrap();
}

/// A torn write: an ack that broke off.
const TORN: &[u8] = b"{\"t\":1.1,\"event\":\"ac";

/// The events alone, without their times.
fn events(records: &[Record]) -> Vec<&Event> {
    records.iter().map(|r| &r.event).collect()
}

#[test]
fn a_run_appended_after_a_torn_line_reads_back_whole_with_the_torn_line_reported() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    run_into(&path, sample());
    tear(&path, TORN);
    run_into(&path, sample());
    let r = read(&path).unwrap();
    let twice: Vec<Event> = sample()
        .into_iter()
        .chain(sample())
        .map(|(_, e)| e)
        .collect();
    assert_eq!(events(&r.records), twice.iter().collect::<Vec<_>>());
    assert_eq!(r.skipped.len(), 1, "{:?}", r.skipped);
    assert_eq!(r.skipped[0].line, sample().len() + 1);
    assert!(r.skipped[0].reason.starts_with("torn"), "{:?}", r.skipped);
    assert!(!r.torn_tail, "the torn line is no longer the last");
    let s = Summary::of(&r);
    assert_eq!((s.runs, s.sent, s.executed, s.skipped), (2, 2, 2, 1));
    assert_eq!(s.skipped_lines, r.skipped);
    assert!(s.executed_twice.is_empty());
}

#[test]
fn appending_to_a_torn_file_closes_the_torn_line_off_first_and_keeps_its_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    let event = |t: f64| Event::Message {
        text: format!("at {t}"),
    };
    let line = |t: f64| serde_json::to_string(&Record { t, event: event(t) }).unwrap() + "\n";
    // A new file and one that ends with its newline get nothing but the event.
    run_into(&path, vec![(0.0, event(0.0))]);
    run_into(&path, vec![(1.0, event(1.0))]);
    let mut expected = line(0.0) + &line(1.0);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
    // A torn one gets the newline that closes the torn line off, then the event.
    tear(&path, TORN);
    ExecLog::append(&path).unwrap();
    expected += std::str::from_utf8(TORN).unwrap();
    expected += "\n";
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        expected,
        "on opening"
    );
    run_into(&path, vec![(2.0, event(2.0))]);
    expected += &line(2.0);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
    // A torn line that happens to be a whole event but for its newline is closed off too.
    let whole = line(3.0);
    tear(&path, whole.trim_end().as_bytes());
    run_into(&path, vec![(4.0, event(4.0))]);
    expected += &whole;
    expected += &line(4.0);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
    let r = read(&path).unwrap();
    assert_eq!(r.records.len(), 5);
    assert_eq!(r.skipped.len(), 1);
}

#[test]
fn torn_and_bad_lines_anywhere_are_skipped_and_reported_not_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("exec.jsonl");
    let mut bytes = Vec::new();
    bytes.extend_from_slice(b"{\"t\":0,\"event\":\"ack\",\"line\":1}\n");
    bytes.extend_from_slice(TORN);
    bytes.extend_from_slice(b"\n{\"t\":2,\"event\":\"ack\",\"line\":2}\n");
    bytes.extend_from_slice(b"not json\n\n");
    bytes.extend_from_slice(b"{\"t\":3,\"event\":\"launch\"}\n");
    bytes.extend_from_slice(b"{\"t\":4,\"event\":\"message\",\"text\":\"\xff\xfe\"}\n");
    bytes.extend_from_slice(b"{\"t\":5,\"event\":\"ack\",\"line\":3}\n");
    bytes.extend_from_slice(TORN);
    std::fs::write(&path, &bytes).unwrap();
    let r = read(&path).unwrap();
    let acked: Vec<&Event> = events(&r.records);
    assert_eq!(
        acked,
        [1, 2, 3]
            .map(|line| Event::Ack { line })
            .iter()
            .collect::<Vec<_>>()
    );
    let skipped: Vec<usize> = r.skipped.iter().map(|s| s.line).collect();
    assert_eq!(skipped, [2, 4, 6, 7, 9], "{:?}", r.skipped);
    assert!(r.skipped[0].reason.starts_with("torn"), "{:?}", r.skipped);
    assert!(
        r.skipped[1].reason.starts_with("not a log event"),
        "{:?}",
        r.skipped
    );
    assert!(r.skipped[2].reason.contains("launch"), "{:?}", r.skipped);
    assert!(r.skipped[4].reason.starts_with("torn"), "{:?}", r.skipped);
    assert!(r.torn_tail);
    // Only a log that cannot be read at all is an error.
    let missing = read(&dir.path().join("missing.jsonl")).unwrap_err();
    assert!(matches!(missing, LogError::Io { .. }), "{missing}");
}

#[test]
fn an_event_an_older_whirl_glued_onto_a_torn_line_is_kept() {
    // Before runs closed a torn line off, the next run's Start went on the torn line.
    let start = serde_json::to_string(&Record {
        t: 0.0,
        event: sample()[0].1.clone(),
    })
    .unwrap();
    let mut bytes = TORN.to_vec();
    bytes.extend_from_slice(start.as_bytes());
    bytes.extend_from_slice(b"\n{\"t\":0.2,\"event\":\"ack\",\"line\":1}\n");
    let r = parse(&bytes);
    assert_eq!(
        events(&r.records),
        [&sample()[0].1, &Event::Ack { line: 1 }]
    );
    assert_eq!(r.skipped.len(), 1);
    assert_eq!(r.skipped[0].line, 1);
    assert!(r.skipped[0].reason.starts_with("torn"), "{:?}", r.skipped);
    // Two whole events on one line (the newline between them lost) are both kept.
    let two = format!("{start}{start}\n");
    let r = parse(two.as_bytes());
    assert_eq!(r.records.len(), 2);
    assert!(r.skipped.is_empty(), "{:?}", r.skipped);
}

/// `events` as records, as [`read`] gives them, with nothing skipped.
fn clean(events: Vec<(f64, Event)>) -> Read {
    Read {
        records: events
            .into_iter()
            .map(|(t, event)| Record { t, event })
            .collect(),
        torn_tail: false,
        skipped: Vec::new(),
    }
}

/// An executed move of program line `line`.
fn executed(t: f64, line: usize) -> (f64, Event) {
    (
        t,
        Event::Executed {
            line: Some(line),
            times: [t - 0.2, t],
            from: [0.0; 3],
            to: [1.0, 0.0, 0.0],
            rapid: false,
        },
    )
}

#[test]
fn the_summary_counts_one_run_and_how_it_ended() {
    let s = Summary::of(&clean(sample()));
    assert_eq!(
        (s.runs, s.sent, s.acked, s.errors, s.alarms, s.executed),
        (1, 1, 1, 0, 0, 1)
    );
    assert_eq!(s.completed, Some(true));
    assert!((s.duration_s - 1.0).abs() < 1e-12);
    assert!(s.executed_twice.is_empty());
    assert_eq!((s.skipped, s.torn_tail), (0, false));
    let run = &s.per_run[0];
    assert_eq!(
        (
            run.program.as_deref(),
            run.lines,
            run.transport.as_deref(),
            run.start_s
        ),
        (Some("p.nc"), Some(2), Some("serial"), Some(0.0))
    );
    assert_eq!((run.sent, run.acked, run.executed), (1, 1, 1));
    assert_eq!((run.ended, run.reason.as_deref()), (Ended::Completed, None));
}

#[test]
fn lines_executed_twice_are_counted_within_a_run_not_across_runs() {
    // The same program run twice, each executing line 1 once.
    let s = Summary::of(&clean(sample().into_iter().chain(sample()).collect()));
    assert_eq!((s.runs, s.sent, s.executed), (2, 2, 2));
    assert!(s.executed_twice.is_empty(), "{:?}", s.executed_twice);
    assert!(s.per_run.iter().all(|run| run.executed_twice.is_empty()));
    assert!((s.duration_s - 2.0).abs() < 1e-12, "{}", s.duration_s);
    // A second run that executes line 1 twice: only that run has it.
    let mut second = sample();
    second.insert(5, executed(0.95, 1));
    let s = Summary::of(&clean(sample().into_iter().chain(second).collect()));
    assert_eq!(s.executed_twice, vec![1]);
    assert!(s.per_run[0].executed_twice.is_empty());
    assert_eq!(s.per_run[1].executed_twice, vec![1]);
    assert_eq!((s.per_run[1].executed, s.executed), (2, 3));
}

#[test]
fn each_run_says_how_it_ended_and_the_last_one_says_for_the_file() {
    let end = |completed: bool, reason: Option<&str>| {
        (
            1.0,
            Event::End {
                completed,
                reason: reason.map(str::to_owned),
            },
        )
    };
    let run = |last: Option<(f64, Event)>| {
        let mut events = sample();
        events.pop();
        events.extend(last);
        events
    };
    let stopped = run(Some(end(false, Some("alarm 64: beyond delta"))));
    let log: Vec<(f64, Event)> = [run(Some(end(true, None))), stopped.clone(), run(None)].concat();
    let s = Summary::of(&clean(log));
    assert_eq!(s.completed, None, "the last run has no End");
    let ended: Vec<(Ended, Option<&str>)> = s
        .per_run
        .iter()
        .map(|run| (run.ended, run.reason.as_deref()))
        .collect();
    assert_eq!(
        ended,
        [
            (Ended::Completed, None),
            (Ended::Stopped, Some("alarm 64: beyond delta")),
            (Ended::Interrupted, None)
        ]
    );
    assert_eq!((s.runs, s.sent, s.acked, s.executed), (3, 3, 3, 3));
    let s = Summary::of(&clean(stopped));
    assert_eq!(s.completed, Some(false));
    // Events whose Start was lost make a run of their own, with no program.
    let s = Summary::of(&clean(sample()[1..].to_vec()));
    assert_eq!(s.runs, 1);
    assert_eq!(
        (s.per_run[0].program.as_ref(), s.per_run[0].sent),
        (None, 1)
    );
    assert_eq!(s.completed, Some(true));
}

#[test]
fn the_summary_prints_its_totals_skipped_lines_and_runs_as_json() {
    let mut log = clean(sample());
    log.skipped.push(Skipped {
        line: 7,
        reason: "torn: the event breaks off".into(),
    });
    log.torn_tail = true;
    let json = serde_json::to_value(Summary::of(&log)).unwrap();
    for key in [
        "runs",
        "sent",
        "acked",
        "errors",
        "alarms",
        "executed",
        "executed_twice",
        "duration_s",
        "completed",
        "torn_tail",
    ] {
        assert!(json.get(key).is_some(), "{key}: {json:#}");
    }
    assert_eq!(json["skipped"], 1);
    assert_eq!(
        json["skipped_lines"],
        serde_json::json!([{"line": 7, "reason": "torn: the event breaks off"}])
    );
    let run = &json["per_run"][0];
    assert_eq!(run["program"], "p.nc");
    assert_eq!(run["transport"], "serial");
    assert_eq!(run["ended"], "completed");
    assert!(run.get("reason").is_none(), "{run:#}");
}

/// A named pipe made by `mkfifo`, in `dir`.
fn fifo(dir: &Path) -> PathBuf {
    let path = dir.join("pipe");
    let made = std::process::Command::new("mkfifo").arg(&path).status();
    assert!(made.unwrap().success(), "mkfifo");
    path
}

#[test]
fn a_path_that_is_not_a_regular_file_is_refused_as_a_log_naming_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let socket = dir.path().join("sock");
    let _listening = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    // /dev/full and /dev/zero read as endless zeros: a reader that looked for the end of
    // either would never stop. A named pipe's open would wait for its other end.
    for (path, kind) in [
        (PathBuf::from("/dev/full"), "a character device"),
        (PathBuf::from("/dev/zero"), "a character device"),
        (fifo(dir.path()), "a named pipe"),
        (socket, "a socket"),
        (dir.path().to_owned(), "a directory"),
    ] {
        match ExecLog::append(&path) {
            Err(LogError::NotAFile {
                path: named,
                kind: said,
            }) => {
                assert_eq!((named, said), (path.clone(), kind));
            }
            other => panic!("{}: {other:?}", path.display()),
        }
        assert!(
            matches!(read(&path), Err(LogError::NotAFile { kind: said, .. }) if said == kind),
            "{}",
            path.display()
        );
    }
}
