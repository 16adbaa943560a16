//! The executed-path log: what was sent, what the controller answered, where the machine was,
//! and what it executed, as JSON lines, so that a run can be audited and replayed.
//!
//! One event per line, each written with a single `write` to a file opened for appending and
//! never truncated: a crash loses at most the event being written, and a torn last line is
//! reported, not fatal, when the log is read. Times are seconds since the run started. The
//! format is the same for every transport.

use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// One logged event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A run begins.
    Start {
        /// The program file or job that was run.
        program: String,
        /// Its number of lines.
        lines: usize,
        /// How it was sent (serial, modbus-tcp, …).
        transport: String,
    },
    /// A program line went out (1-based program line).
    Sent {
        /// Program line.
        line: usize,
        /// Its text.
        text: String,
    },
    /// The controller accepted a line.
    Ack {
        /// Program line.
        line: usize,
    },
    /// The controller refused a line.
    Error {
        /// Program line.
        line: usize,
        /// The controller's error code.
        code: u32,
        /// What it means.
        message: String,
    },
    /// A status report.
    Status {
        /// Controller state (Idle, Run, Hold:0, Alarm, …).
        state: String,
        /// Machine position X, Z (mm) and C (degrees).
        pos: [f64; 3],
        /// Free planner blocks, if reported.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        blocks_free: Option<u32>,
        /// Free RX bytes, if reported.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        rx_free: Option<u32>,
        /// The line number being executed, if reported.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        line: Option<u64>,
    },
    /// The controller raised an alarm.
    Alarm {
        /// Alarm code.
        code: u32,
        /// What it means.
        message: String,
    },
    /// A message from the controller or the bridge.
    Message {
        /// The text.
        text: String,
    },
    /// A straight move the controller executed (from its own execution record, so only
    /// from a simulated controller).
    Executed {
        /// Program line: the N word of the line that queued it (whirl numbers every line of
        /// a grblHAL program with its file line); `None` for a line without one.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        line: Option<usize>,
        /// Start and end time, s.
        times: [f64; 2],
        /// X, Z (mm), C (degrees) at the start.
        from: [f64; 3],
        /// At the end.
        to: [f64; 3],
        /// A rapid (G0): positioning, not cutting.
        #[serde(skip_serializing_if = "std::ops::Not::not", default)]
        rapid: bool,
    },
    /// The run ended.
    End {
        /// Whether every line was executed.
        completed: bool,
        /// Why it stopped, if it did not complete.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        reason: Option<String>,
    },
}

/// An event with its time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// Seconds since the run started.
    pub t: f64,
    /// What happened.
    #[serde(flatten)]
    pub event: Event,
}

/// Why a log could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file could not be opened or written.
    #[error("executed-path log {path}: {error}")]
    Io {
        /// The log.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A line that is not an event (other than a torn last line).
    #[error("executed-path log {path} line {line}: not a log event: {error}")]
    Parse {
        /// The log.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// Why.
        error: serde_json::Error,
    },
}

/// Where a run's events go: an append-only file, memory, or nowhere. Clones write to the
/// same place, a whole event at a time, so the streamer and an in-process simulator can log
/// side by side.
#[derive(Debug, Clone)]
pub struct ExecLog {
    sink: Sink,
}

#[derive(Debug, Clone)]
enum Sink {
    /// One line an event, appended and flushed.
    File {
        file: Arc<Mutex<File>>,
        path: PathBuf,
    },
    /// Kept for the caller ([`ExecLog::records`]).
    Memory(Arc<Mutex<Vec<Record>>>),
    /// Dropped (a dry run without a log).
    Discard,
}

impl ExecLog {
    /// Open `path` for appending (created if missing; what is there is kept).
    pub fn append(path: &Path) -> Result<ExecLog, LogError> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|error| LogError::Io {
                path: path.to_owned(),
                error,
            })?;
        Ok(ExecLog {
            sink: Sink::File {
                file: Arc::new(Mutex::new(file)),
                path: path.to_owned(),
            },
        })
    }

    /// A log kept in memory, for a front end that shows a run as it goes, or a test.
    pub fn memory() -> ExecLog {
        ExecLog {
            sink: Sink::Memory(Arc::default()),
        }
    }

    /// A log that keeps nothing, for a run the caller asked no log of.
    pub fn discard() -> ExecLog {
        ExecLog {
            sink: Sink::Discard,
        }
    }

    /// The events a memory log holds so far, in order (none for a file or a discarding
    /// log: read a file back with [`read`]).
    pub fn records(&self) -> Vec<Record> {
        match &self.sink {
            Sink::Memory(records) => lock(records).clone(),
            Sink::File { .. } | Sink::Discard => Vec::new(),
        }
    }

    /// Append one event: to a file, one line written in one call and flushed to the OS.
    pub fn write(&mut self, t: f64, event: Event) -> Result<(), LogError> {
        match &self.sink {
            Sink::File { file, path } => {
                let mut line = serde_json::to_string(&Record { t, event })
                    .expect("log events always serialise");
                line.push('\n');
                let mut file = lock(file);
                file.write_all(line.as_bytes())
                    .and_then(|()| file.flush())
                    .map_err(|error| LogError::Io {
                        path: path.clone(),
                        error,
                    })
            }
            Sink::Memory(records) => {
                lock(records).push(Record { t, event });
                Ok(())
            }
            Sink::Discard => Ok(()),
        }
    }
}

/// A writer that panicked mid-event left at most a torn line in a file (which [`read`]
/// tolerates) or a whole record in memory: either way the log is still usable.
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A log as read back: its records, and whether the last line was torn (a crash mid-write).
#[derive(Debug, Clone, PartialEq)]
pub struct Read {
    /// Every complete event, in order.
    pub records: Vec<Record>,
    /// The last line was incomplete and was left out.
    pub torn_tail: bool,
}

/// Read a log. A last line without its newline that does not parse is a torn write and is
/// left out; any other bad line is an error naming it.
pub fn read(path: &Path) -> Result<Read, LogError> {
    let text = std::fs::read_to_string(path).map_err(|error| LogError::Io {
        path: path.to_owned(),
        error,
    })?;
    let ends_clean = text.is_empty() || text.ends_with('\n');
    let lines: Vec<&str> = text.lines().collect();
    let mut records = Vec::with_capacity(lines.len());
    let mut torn_tail = false;
    for (i, l) in lines.iter().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Record>(l) {
            Ok(r) => records.push(r),
            Err(_) if i + 1 == lines.len() && !ends_clean => torn_tail = true,
            Err(error) => {
                return Err(LogError::Parse {
                    path: path.to_owned(),
                    line: i + 1,
                    error,
                })
            }
        }
    }
    Ok(Read { records, torn_tail })
}

/// What `whirl log summary` prints.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Runs in the log (Start events).
    pub runs: usize,
    /// Lines sent, acknowledged, refused.
    pub sent: usize,
    /// See `sent`.
    pub acked: usize,
    /// See `sent`.
    pub errors: usize,
    /// Alarms raised.
    pub alarms: usize,
    /// Moves the controller reported executing.
    pub executed: usize,
    /// Program lines executed more than once (a resumed run must have none), as far as
    /// executed moves name their lines.
    pub executed_twice: Vec<usize>,
    /// Seconds from the first to the last event.
    pub duration_s: f64,
    /// How the last run ended.
    pub completed: Option<bool>,
    /// The last line was torn.
    pub torn_tail: bool,
}

impl Summary {
    /// Summarise a log.
    pub fn of(log: &Read) -> Summary {
        let mut s = Summary {
            runs: 0,
            sent: 0,
            acked: 0,
            errors: 0,
            alarms: 0,
            executed: 0,
            executed_twice: Vec::new(),
            duration_s: 0.0,
            completed: None,
            torn_tail: log.torn_tail,
        };
        let mut seen = std::collections::BTreeMap::<usize, usize>::new();
        for r in &log.records {
            match &r.event {
                Event::Start { .. } => s.runs += 1,
                Event::Sent { .. } => s.sent += 1,
                Event::Ack { .. } => s.acked += 1,
                Event::Error { .. } => s.errors += 1,
                Event::Alarm { .. } => s.alarms += 1,
                Event::Executed { line, .. } => {
                    s.executed += 1;
                    if let Some(line) = line {
                        *seen.entry(*line).or_default() += 1;
                    }
                }
                Event::End { completed, .. } => s.completed = Some(*completed),
                Event::Status { .. } | Event::Message { .. } => {}
            }
        }
        s.executed_twice = seen
            .into_iter()
            .filter(|(_, n)| *n > 1)
            .map(|(l, _)| l)
            .collect();
        if let (Some(a), Some(b)) = (log.records.first(), log.records.last()) {
            s.duration_s = b.t - a.t;
        }
        s
    }
}

#[cfg(test)]
mod tests {
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

    #[test]
    fn a_torn_last_line_is_left_out_and_a_bad_middle_line_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("exec.jsonl");
        let mut log = ExecLog::append(&path).unwrap();
        for (t, e) in sample() {
            log.write(t, e).unwrap();
        }
        let mut f = OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(b"{\"t\":1.1,\"event\":\"ac").unwrap();
        let r = read(&path).unwrap();
        assert!(r.torn_tail);
        assert_eq!(r.records.len(), sample().len());
        std::fs::write(&path, "{\"t\":0,\"event\":\"ack\",\"line\":1}\nnot json\n{\"t\":1,\"event\":\"ack\",\"line\":2}\n").unwrap();
        let e = read(&path).unwrap_err();
        assert!(matches!(e, LogError::Parse { line: 2, .. }), "{e}");
    }

    #[test]
    fn the_summary_counts_and_finds_lines_executed_twice() {
        let mut records: Vec<Record> = sample()
            .into_iter()
            .map(|(t, event)| Record { t, event })
            .collect();
        let s = Summary::of(&Read {
            records: records.clone(),
            torn_tail: false,
        });
        assert_eq!(
            (s.runs, s.sent, s.acked, s.errors, s.executed),
            (1, 1, 1, 0, 1)
        );
        assert_eq!(s.completed, Some(true));
        assert!((s.duration_s - 1.0).abs() < 1e-12);
        assert!(s.executed_twice.is_empty());
        records.push(Record {
            t: 1.5,
            event: Event::Executed {
                line: Some(1),
                times: [1.2, 1.4],
                from: [0.0; 3],
                to: [1.0, 0.0, 0.0],
                rapid: false,
            },
        });
        let s = Summary::of(&Read {
            records,
            torn_tail: false,
        });
        assert_eq!(s.executed_twice, vec![1]);
    }
}
