//! What a run's executed-path log says of it: how it ended, where it resumes, the last
//! line known done, its alarms. The log is the raw record ([`crate::log`]); a record
//! notes where in it the run's events begin (the log's length when the run opened it, as
//! the log is only ever appended to), so one run is read out of a log that holds many,
//! and the log is only ever read.

use std::io::{BufRead, Seek, SeekFrom};
use std::path::Path;

use crate::log::{Ended, Event, FeedOverrideState, Read, Record, Summary};

/// What a log says of one run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LogFacts {
    /// How it ended: `None` if the log holds no events of it at all.
    pub ended: Option<Ended>,
    /// Why it stopped, as its End event says.
    pub reason: Option<String>,
    /// The first program line (1-based) not known to have finished, for a run that did not
    /// complete: the run's own `resume_at` if it logged one, else the block the controller
    /// last reported executing (`Ln:`; every line before it is done) or the line after the
    /// last one it reported executed, whichever is further, else the line the run started
    /// at (nothing known done).
    pub resume_at: Option<usize>,
    /// Lines from `resume_at` up to this one may have run all the same: a controller goes
    /// on with every line it received when its sender dies, so without a logged
    /// `resume_at` this is the last line sent, if it is not before `resume_at`.
    pub possibly_run_to: Option<usize>,
    /// The last program line known done (1-based).
    pub last_line: Option<usize>,
    /// The alarms the controller raised, in order: code and message.
    pub alarms: Vec<(u32, String)>,
    /// The feed overrides the controller reported running, in order: each change from the
    /// planned feed (100 %) on, once, with when it was first reported.
    pub feed_overrides: Vec<FeedChange>,
    /// The time of its last event, seconds after it started.
    pub last_t: Option<f64>,
}

/// A feed override the controller began to run at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedChange {
    /// Percent of the programmed feed.
    pub percent: u16,
    /// When the controller first reported it, seconds after the run started (the log's
    /// time).
    pub t: f64,
}

/// Reads the run whose events begin at byte `offset` of the log at `path` and which
/// started at program line `from_line` (1-based: 1, or the line it resumed at): its events
/// up to the next run's Start (a run appended after it), lines that are not events skipped
/// as [`crate::log::read`] skips them. The log is read a line at a time and no further
/// than that Start, so a long log of many runs costs one run's events; a path that is not
/// a regular file (a device reads without end) is an error of kind `InvalidInput`.
pub fn read_run(path: &Path, offset: u64, from_line: usize) -> std::io::Result<LogFacts> {
    // Looked at before it is opened: opening a named pipe waits for a writer.
    if let Err(refused) = crate::log::regular(path, &std::fs::metadata(path)?) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            refused.to_string(),
        ));
    }
    let mut file = std::fs::File::open(path)?;
    file.seek(SeekFrom::Start(offset))?;
    let mut reader = std::io::BufReader::new(file);
    let mut records: Vec<Record> = Vec::new();
    let mut line = Vec::new();
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line)? == 0 {
            break;
        }
        let Ok(record) = serde_json::from_slice::<Record>(line.trim_ascii_end()) else {
            continue;
        };
        if matches!(record.event, Event::Start { .. }) && !records.is_empty() {
            break;
        }
        records.push(record);
    }
    Ok(LogFacts::of(records, from_line))
}

impl LogFacts {
    /// The facts of one run's events, for a run that started at program line `from_line`
    /// (1-based).
    pub fn of(records: Vec<Record>, from_line: usize) -> LogFacts {
        facts(records, from_line)
    }
}

/// The facts of one run's events.
fn facts(records: Vec<Record>, from_line: usize) -> LogFacts {
    let mut facts = LogFacts::default();
    let (mut reported, mut executed, mut sent) = (None, None, None);
    for record in &records {
        match &record.event {
            Event::Status {
                line: Some(line), ..
            } => reported = usize::try_from(*line).ok().filter(|&l| l > 0),
            Event::Executed {
                line: Some(line), ..
            } => executed = Some(executed.map_or(*line, |e: usize| e.max(*line))),
            Event::Sent { line, .. } => sent = Some(sent.map_or(*line, |s: usize| s.max(*line))),
            Event::Alarm { code, message } => facts.alarms.push((*code, message.clone())),
            // Changes from the planned feed (100 %) on.
            Event::FeedOverride {
                percent,
                state: FeedOverrideState::Running,
            } if facts.feed_overrides.last().map_or(100, |c| c.percent) != *percent => {
                facts.feed_overrides.push(FeedChange {
                    percent: *percent,
                    t: record.t,
                })
            }
            _ => {}
        }
    }
    // A line the controller reports executing: every line before it is done. A line it
    // reports executed: done itself.
    facts.last_t = records.last().map(|r| r.t);
    let known_done = [reported.map(|l| l - 1), executed]
        .into_iter()
        .flatten()
        .max();
    facts.last_line = known_done.filter(|&l| l > 0);
    let read = Read {
        records,
        torn_tail: false,
        skipped: Vec::new(),
    };
    let summary = Summary::of(&read);
    let Some(run) = summary.per_run.into_iter().next() else {
        return facts;
    };
    facts.ended = Some(run.ended);
    facts.reason = run.reason;
    let logged = read.records.iter().rev().find_map(|r| match r.event {
        Event::ResumeAt {
            line,
            possibly_run_to,
        } => Some((line, possibly_run_to)),
        _ => None,
    });
    match logged {
        Some((line, possibly_run_to)) => {
            facts.resume_at = Some(line);
            facts.possibly_run_to = possibly_run_to;
        }
        None if run.ended != Ended::Completed => {
            let resume_at = known_done.map_or(from_line, |l| (l + 1).max(from_line));
            facts.resume_at = Some(resume_at);
            facts.possibly_run_to = sent.filter(|&s| s >= resume_at);
        }
        None => {}
    }
    facts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::ExecLog;

    fn status(line: u64) -> Event {
        Event::Status {
            state: "Run".into(),
            pos: [0.0; 3],
            blocks_free: None,
            rx_free: None,
            line: Some(line),
        }
    }

    fn sent(line: usize) -> Event {
        Event::Sent {
            line,
            text: format!("N{line} G1 X1"),
        }
    }

    fn start() -> Event {
        Event::Start {
            program: "p.nc".into(),
            lines: 100,
            transport: "serial".into(),
        }
    }

    /// A log file holding `before` (another run's events), then `run`; the offset where
    /// `run` begins.
    fn log_with(dir: &Path, before: Vec<Event>, run: Vec<Event>) -> (std::path::PathBuf, u64) {
        let path = dir.join("exec.jsonl");
        let mut log = ExecLog::append(&path).unwrap();
        for e in before {
            log.write(0.0, e).unwrap();
        }
        let offset = std::fs::metadata(&path).unwrap().len();
        for e in run {
            log.write(1.0, e).unwrap();
        }
        (path, offset)
    }

    #[test]
    fn a_log_that_is_a_device_is_not_read() {
        // /dev/zero has no end: reading it for a run's events would never stop.
        let error = read_run(Path::new("/dev/zero"), 0, 1).unwrap_err();
        assert_eq!(error.kind(), std::io::ErrorKind::InvalidInput);
        assert!(error.to_string().contains("a character device"), "{error}");
    }

    #[test]
    fn a_killed_run_resumes_at_the_block_last_reported_executing() {
        let dir = tempfile::tempdir().unwrap();
        // The earlier run completed; ours sent lines 1 to 40, the controller last said it
        // was executing line 31, and then the log stops: no End.
        let earlier = vec![
            start(),
            sent(1),
            Event::End {
                completed: true,
                reason: None,
            },
        ];
        let mut ours = vec![start()];
        ours.extend((1..=40).map(sent));
        ours.extend([status(12), status(31)]);
        let (path, offset) = log_with(dir.path(), earlier, ours);
        let facts = read_run(&path, offset, 1).unwrap();
        assert_eq!(facts.ended, Some(Ended::Interrupted));
        assert_eq!(facts.resume_at, Some(31));
        assert_eq!(facts.last_line, Some(30));
        // The controller may have gone on with everything it had received.
        assert_eq!(facts.possibly_run_to, Some(40));
        // The earlier run, read from the start, is its own and completed.
        let first = read_run(&path, 0, 1).unwrap();
        assert_eq!(first.ended, Some(Ended::Completed));
        assert_eq!(first.resume_at, None);
    }

    #[test]
    fn a_logged_resume_point_and_end_are_taken_as_the_run_said() {
        let dir = tempfile::tempdir().unwrap();
        let run = vec![
            start(),
            sent(1),
            sent(2),
            status(2),
            Event::Alarm {
                code: 64,
                message: "beyond Δ".into(),
            },
            Event::ResumeAt {
                line: 2,
                possibly_run_to: None,
            },
            Event::End {
                completed: false,
                reason: Some("ALARM:64".into()),
            },
            // A later run appended to the same log is not this one's.
            start(),
            sent(1),
        ];
        let (path, offset) = log_with(dir.path(), vec![], run);
        let facts = read_run(&path, offset, 1).unwrap();
        assert_eq!(facts.ended, Some(Ended::Stopped));
        assert_eq!(facts.reason.as_deref(), Some("ALARM:64"));
        assert_eq!((facts.resume_at, facts.possibly_run_to), (Some(2), None));
        assert_eq!(facts.alarms, vec![(64, "beyond Δ".to_owned())]);
    }

    #[test]
    fn the_feed_overrides_the_controller_ran_at_are_read_as_they_change_not_those_only_asked() {
        let dir = tempfile::tempdir().unwrap();
        let feed = |percent, state| Event::FeedOverride { percent, state };
        let run = vec![
            start(),
            // The controller's first report: the planned feed, no change.
            feed(100, FeedOverrideState::Running),
            feed(150, FeedOverrideState::Asked),
            feed(150, FeedOverrideState::Running),
            // grbl reports its override in every status: the same value again.
            feed(150, FeedOverrideState::Running),
            feed(190, FeedOverrideState::Asked),
            feed(190, FeedOverrideState::NotTaken),
            feed(90, FeedOverrideState::Running),
        ];
        let (path, offset) = log_with(dir.path(), vec![], run);
        let facts = read_run(&path, offset, 1).unwrap();
        let percents: Vec<u16> = facts.feed_overrides.iter().map(|c| c.percent).collect();
        assert_eq!(percents, [150, 90]);
    }

    #[test]
    fn executed_moves_prove_their_lines_done_and_torn_lines_are_passed_over() {
        let dir = tempfile::tempdir().unwrap();
        let executed = |line| Event::Executed {
            line: Some(line),
            times: [0.0, 0.1],
            from: [0.0; 3],
            to: [0.0; 3],
            rapid: false,
        };
        let (path, offset) = log_with(
            dir.path(),
            vec![],
            vec![start(), sent(1), sent(2), sent(3), executed(1), executed(2)],
        );
        // A torn write at the end, as a kill mid-event leaves.
        std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .and_then(|mut f| std::io::Write::write_all(&mut f, b"{\"t\":1.2,\"ev"))
            .unwrap();
        let facts = read_run(&path, offset, 1).unwrap();
        assert_eq!(facts.ended, Some(Ended::Interrupted));
        assert_eq!((facts.last_line, facts.resume_at), (Some(2), Some(3)));
        // Line 3 was sent: it may have run, part or whole.
        assert_eq!(facts.possibly_run_to, Some(3));
    }

    #[test]
    fn a_run_with_nothing_known_done_resumes_where_it_started_and_a_missing_log_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let (path, offset) = log_with(dir.path(), vec![], vec![start(), sent(7), sent(8)]);
        // It had resumed at line 7 and nothing is known done since.
        let facts = read_run(&path, offset, 7).unwrap();
        assert_eq!((facts.resume_at, facts.last_line), (Some(7), None));
        assert_eq!(facts.possibly_run_to, Some(8));
        // Past the end: nothing of the run is in the log.
        let nothing = read_run(&path, offset + 10_000, 1).unwrap();
        assert_eq!(nothing.ended, None);
        assert!(read_run(&dir.path().join("missing.jsonl"), 0, 1).is_err());
    }
}
