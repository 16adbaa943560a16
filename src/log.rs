//! The executed-path log: what was sent, what the controller answered, where the machine was,
//! and what it executed, as JSON lines, so that a run can be audited and replayed.
//!
//! One event per line, each written with a single `write` to a file opened for appending and
//! never truncated or rewritten: a crash or a full disk loses at most the event being
//! written. The next run to open the log closes such a torn line off with a newline before
//! its first event, so the torn bytes stay, on a line of their own, and the new run starts
//! clean. The reader skips a torn or unreadable line wherever it is and says which it
//! skipped and why. Times are seconds since the run started. The format is the same for
//! every transport.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::{Read as _, Seek, SeekFrom, Write};
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
    /// The feed override: asked of the controller, or reported running (every value it
    /// goes through, so that a run can be audited for the insert cusp it left), or asked
    /// and not reached.
    FeedOverride {
        /// Percent of the programmed feed.
        percent: u16,
        /// What happened to it.
        state: FeedOverrideState,
    },
    /// Where a run that did not complete resumes (beside its End: just before it on a
    /// serial line, just after it on the fieldbus transports): the first program line
    /// (1-based) not known to have executed, and the last one that may have.
    ResumeAt {
        /// The line to resume at (`whirl stream --resume-at`).
        line: usize,
        /// Lines from `line` up to this one may already have run (a resume re-enters along
        /// the groove, so running them again is harmless); `None` if none did.
        #[serde(skip_serializing_if = "Option::is_none", default)]
        possibly_run_to: Option<usize>,
    },
}

/// What a logged feed override is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedOverrideState {
    /// The bridge asked the controller for it (checked against the run's cap).
    Asked,
    /// The controller runs at it (grbl's `Ov:`, the Modbus register read back, the
    /// bridge's own set-point clock on CANopen).
    Running,
    /// Asked and not reached: the controller does not report it, or did not take it.
    NotTaken,
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
    /// The file could not be opened, read or written.
    #[error("executed-path log {path}: {error}")]
    Io {
        /// The log.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The path is a device, a pipe or a socket. Such a "file" has no end to look for a
    /// torn line at, and what is written to it is not kept (`/dev/full` reads as endless
    /// zeros, a pipe's reader may be gone): it keeps no log, so it is refused before a run.
    #[error(
        "executed-path log {path}: it is {kind}, not a regular file; a log must be a file \
         that keeps every run's events: name one"
    )]
    NotAFile {
        /// The log.
        path: PathBuf,
        /// What it is instead, in words ("a character device").
        kind: &'static str,
    },
}

/// Where a run's events go: an append-only file, memory, or nowhere. Clones write to the
/// same place, a whole event at a time, so the streamer and an in-process simulator can log
/// side by side.
#[derive(Debug, Clone)]
pub struct ExecLog {
    sink: Sink,
    tap: Option<Tap>,
}

/// Who else sees each event as it is written (live telemetry): called on the writing
/// task with every event, so it must only hand the event on, never wait.
#[derive(Clone)]
pub struct Tap(Arc<dyn Fn(&Record) + Send + Sync>);

impl Tap {
    /// A tap calling `see` with every event.
    pub fn new(see: impl Fn(&Record) + Send + Sync + 'static) -> Tap {
        Tap(Arc::new(see))
    }
}

impl std::fmt::Debug for Tap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Tap")
    }
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
    /// Open `path` for appending (created if missing; what is there is kept). If its last
    /// line is torn (no newline at the end: a crash or a full disk mid-write), a newline is
    /// appended first to close it off, so this run's events start on a line of their own:
    /// only the last byte is read, however long the log. A path that is not a regular file
    /// is refused ([`LogError::NotAFile`]), looked at before it is opened (opening a named
    /// pipe may wait for its reader) and again once open (it may have been replaced).
    pub fn append(path: &Path) -> Result<ExecLog, LogError> {
        let io = |error| LogError::Io {
            path: path.to_owned(),
            error,
        };
        match std::fs::metadata(path) {
            Ok(meta) => regular(path, &meta)?,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(error) => return Err(io(error)),
        }
        let mut file = OpenOptions::new()
            .create(true)
            .read(true)
            .append(true)
            .open(path)
            .map_err(io)?;
        regular(path, &file.metadata().map_err(io)?)?;
        close_torn_line(&mut file).map_err(io)?;
        Ok(ExecLog {
            sink: Sink::File {
                file: Arc::new(Mutex::new(file)),
                path: path.to_owned(),
            },
            tap: None,
        })
    }

    /// A log kept in memory, for a front end that shows a run as it goes, or a test.
    pub fn memory() -> ExecLog {
        ExecLog {
            sink: Sink::Memory(Arc::default()),
            tap: None,
        }
    }

    /// A log that keeps nothing, for a run the caller asked no log of.
    pub fn discard() -> ExecLog {
        ExecLog {
            sink: Sink::Discard,
            tap: None,
        }
    }

    /// This log, with `tap` shown every event written from now on (by it and its clones
    /// made after).
    pub fn tapped(mut self, tap: Tap) -> ExecLog {
        self.tap = Some(tap);
        self
    }

    /// The events a memory log holds so far, in order (none for a file or a discarding
    /// log: read a file back with [`read`]).
    pub fn records(&self) -> Vec<Record> {
        self.records_from(0)
    }

    /// The events a memory log holds from the `from`-th on (none past its end): what is new
    /// to a reader that follows a run, copied without the rest, which a long run's reader
    /// would otherwise copy again at every look while the run waits on the lock.
    pub fn records_from(&self, from: usize) -> Vec<Record> {
        match &self.sink {
            Sink::Memory(records) => lock(records).get(from..).unwrap_or_default().to_vec(),
            Sink::File { .. } | Sink::Discard => Vec::new(),
        }
    }

    /// Append one event: shown to the tap, if any, then to a file, one line written in one
    /// call and flushed to the OS.
    pub fn write(&mut self, t: f64, event: Event) -> Result<(), LogError> {
        let record = Record { t, event };
        if let Some(tap) = &self.tap {
            (tap.0)(&record);
        }
        match &self.sink {
            Sink::File { file, path } => {
                let mut line = serde_json::to_string(&record).expect("log events always serialise");
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
                lock(records).push(record);
                Ok(())
            }
            Sink::Discard => Ok(()),
        }
    }
}

/// `Ok` for a regular file (links followed), else [`LogError::NotAFile`] naming what it is.
pub(crate) fn regular(path: &Path, meta: &std::fs::Metadata) -> Result<(), LogError> {
    if meta.is_file() {
        return Ok(());
    }
    Err(LogError::NotAFile {
        path: path.to_owned(),
        kind: special_kind(&meta.file_type()),
    })
}

/// What a file that is not a regular file is, in the words of a refusal.
pub fn special_kind(kind: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_dir() {
        "a directory"
    } else if kind.is_char_device() {
        "a character device"
    } else if kind.is_block_device() {
        "a block device"
    } else if kind.is_fifo() {
        "a named pipe"
    } else if kind.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// Append the newline a torn last line lacks; nothing for an empty file or one that ends
/// with a newline. Only ever appends.
fn close_torn_line(file: &mut File) -> std::io::Result<()> {
    if file.metadata()?.len() == 0 {
        return Ok(());
    }
    let mut last = [0u8];
    file.seek(SeekFrom::End(-1))?;
    file.read_exact(&mut last)?;
    if last != [b'\n'] {
        file.write_all(b"\n")?;
        file.flush()?;
    }
    Ok(())
}

/// A writer that panicked mid-event left at most a torn line in a file (which [`read`]
/// skips) or a whole record in memory: either way the log is still usable.
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A log as read back: its events, and the lines that were not events.
#[derive(Debug, Clone, PartialEq)]
pub struct Read {
    /// Every event read, in order.
    pub records: Vec<Record>,
    /// The last line had no newline and was not an event (a crash mid-write that no run has
    /// appended after yet); it is among `skipped`.
    pub torn_tail: bool,
    /// The lines left out, in order: torn writes and anything else that is not an event.
    pub skipped: Vec<Skipped>,
}

/// A line of a log that [`read`] left out.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Skipped {
    /// 1-based line of the file.
    pub line: usize,
    /// Why, in a few words: torn (the event breaks off), or not a log event and the
    /// parser's complaint.
    pub reason: String,
}

/// Read a log. A line that is not an event (a torn write, wherever it is, or anything else)
/// is skipped and listed in [`Read::skipped`]; only a file that cannot be read at all, or
/// that is not a regular file ([`LogError::NotAFile`]: a device may never end), is an
/// error. Blank lines are passed over.
pub fn read(path: &Path) -> Result<Read, LogError> {
    let io = |error| LogError::Io {
        path: path.to_owned(),
        error,
    };
    // Looked at before it is opened: opening a named pipe waits for a writer.
    regular(path, &std::fs::metadata(path).map_err(io)?)?;
    let mut file = File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes).map_err(io)?;
    Ok(parse(&bytes))
}

/// [`read`] of a log's bytes.
fn parse(bytes: &[u8]) -> Read {
    let ends_clean = bytes.is_empty() || bytes.ends_with(b"\n");
    let mut lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    if ends_clean {
        // What follows the last newline: nothing.
        lines.pop();
    }
    let mut read = Read {
        records: Vec::with_capacity(lines.len()),
        torn_tail: false,
        skipped: Vec::new(),
    };
    let count = lines.len();
    for (i, line) in lines.into_iter().enumerate() {
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if line.trim_ascii().is_empty() {
            continue;
        }
        if let Err(reason) = parse_line(line, &mut read.records) {
            read.torn_tail |= i + 1 == count && !ends_clean;
            read.skipped.push(Skipped {
                line: i + 1,
                reason,
            });
        }
    }
    read
}

/// How every event line begins (the writer puts `t` first, and nothing else in an event is
/// an object with a `t`; inside a string the quotes would be escaped).
const EVENT_START: &[u8] = b"{\"t\":";

/// Push the event `line` holds onto `records`, or say why it is not one. A line on which an
/// older whirl appended a run's first event after a torn write (`{"t":1.1,"event":"ac{"t":0,…`)
/// gives up the events that are whole, and still counts as skipped for the torn one.
fn parse_line(line: &[u8], records: &mut Vec<Record>) -> Result<(), String> {
    let error = match serde_json::from_slice::<Record>(line) {
        Ok(record) => {
            records.push(record);
            return Ok(());
        }
        Err(error) => error,
    };
    let mut starts: Vec<usize> = (1..line.len())
        .filter(|&k| line[k..].starts_with(EVENT_START))
        .collect();
    if !starts.is_empty() {
        starts.insert(0, 0);
        let pieces: Vec<Option<Record>> = starts
            .iter()
            .zip(starts.iter().skip(1).chain([&line.len()]))
            .map(|(&a, &b)| serde_json::from_slice(&line[a..b]).ok())
            .collect();
        let whole = pieces.iter().flatten().count();
        if whole > 0 {
            records.extend(pieces.into_iter().flatten());
            return match starts.len() - whole {
                0 => Ok(()),
                torn => Err(format!(
                    "torn: events run together on one line, {torn} broken off, {whole} kept"
                )),
            };
        }
    }
    Err(if error.is_eof() {
        "torn: the event breaks off".to_owned()
    } else {
        format!("not a log event: {error}")
    })
}

/// What `whirl log summary` prints: the totals over the file, then each run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Runs in the log: one for each Start event, and one more for events before the first
    /// Start (whose Start was lost), if there are any.
    pub runs: usize,
    /// Lines sent, acknowledged, refused, over every run.
    pub sent: usize,
    /// See `sent`.
    pub acked: usize,
    /// See `sent`.
    pub errors: usize,
    /// Alarms raised, over every run.
    pub alarms: usize,
    /// Moves the controller reported executing, over every run.
    pub executed: usize,
    /// Program lines that some run executed more than once (a resumed run must have none),
    /// as far as executed moves name their lines; a line that two runs each executed once
    /// is not among them.
    pub executed_twice: Vec<usize>,
    /// Seconds the runs took, added up.
    pub duration_s: f64,
    /// How the last run ended: `None` if it has no End event.
    pub completed: Option<bool>,
    /// The last line was torn (it is among `skipped_lines`).
    pub torn_tail: bool,
    /// How many lines were not events and were left out.
    pub skipped: usize,
    /// Which, and why.
    pub skipped_lines: Vec<Skipped>,
    /// Each run, in the order of the file.
    pub per_run: Vec<RunSummary>,
}

/// One run of a log: from a Start event to the next (or the end of the file).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// The program or job its Start names (`None` for events before the first Start).
    pub program: Option<String>,
    /// Its number of lines, from the Start event.
    pub lines: Option<usize>,
    /// How it was sent (serial, modbus-tcp, …), from the Start event.
    pub transport: Option<String>,
    /// The time of its Start event, s (the log's times count from each run's start).
    pub start_s: Option<f64>,
    /// Seconds from its first to its last event.
    pub duration_s: f64,
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
    /// Program lines this run executed more than once, as far as executed moves name
    /// their lines.
    pub executed_twice: Vec<usize>,
    /// How it ended.
    pub ended: Ended,
    /// Why it stopped, if its End event says.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Where it resumes (1-based program line), if it logged one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resume_at: Option<usize>,
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Ended {
    /// Its End event says every line was executed.
    Completed,
    /// Its End event says it stopped short (see [`RunSummary::reason`]).
    Stopped,
    /// It has no End event: the bridge was killed, crashed or lost the log mid-run.
    Interrupted,
}

impl Summary {
    /// Summarise a log, run by run.
    pub fn of(log: &Read) -> Summary {
        let mut runs: Vec<Tally> = Vec::new();
        for r in &log.records {
            match (&r.event, runs.last_mut()) {
                (Event::Start { .. }, _) | (_, None) => runs.push(Tally::new(r)),
                (_, Some(run)) => run.add(r),
            }
        }
        let per_run: Vec<RunSummary> = runs.into_iter().map(Tally::finish).collect();
        let total = |count: fn(&RunSummary) -> usize| per_run.iter().map(count).sum();
        let mut executed_twice: Vec<usize> = per_run
            .iter()
            .flat_map(|run| run.executed_twice.iter().copied())
            .collect();
        executed_twice.sort_unstable();
        executed_twice.dedup();
        Summary {
            runs: per_run.len(),
            sent: total(|run| run.sent),
            acked: total(|run| run.acked),
            errors: total(|run| run.errors),
            alarms: total(|run| run.alarms),
            executed: total(|run| run.executed),
            executed_twice,
            duration_s: per_run.iter().map(|run| run.duration_s).sum(),
            completed: per_run.last().and_then(|run| match run.ended {
                Ended::Completed => Some(true),
                Ended::Stopped => Some(false),
                Ended::Interrupted => None,
            }),
            torn_tail: log.torn_tail,
            skipped: log.skipped.len(),
            skipped_lines: log.skipped.clone(),
            per_run,
        }
    }
}

/// A run being summarised.
struct Tally {
    run: RunSummary,
    /// How many moves executed each program line.
    seen: BTreeMap<usize, usize>,
    /// The times of its first and last events.
    first_t: f64,
    last_t: f64,
}

impl Tally {
    /// A run that begins with `first` (its Start event, or the first event of a log that
    /// lost its Start).
    fn new(first: &Record) -> Tally {
        let (program, lines, transport, start_s) = match &first.event {
            Event::Start {
                program,
                lines,
                transport,
            } => (
                Some(program.clone()),
                Some(*lines),
                Some(transport.clone()),
                Some(first.t),
            ),
            _ => (None, None, None, None),
        };
        let mut tally = Tally {
            run: RunSummary {
                program,
                lines,
                transport,
                start_s,
                duration_s: 0.0,
                sent: 0,
                acked: 0,
                errors: 0,
                alarms: 0,
                executed: 0,
                executed_twice: Vec::new(),
                ended: Ended::Interrupted,
                reason: None,
                resume_at: None,
            },
            seen: BTreeMap::new(),
            first_t: first.t,
            last_t: first.t,
        };
        tally.add(first);
        tally
    }

    fn add(&mut self, r: &Record) {
        let run = &mut self.run;
        self.last_t = r.t;
        match &r.event {
            Event::Sent { .. } => run.sent += 1,
            Event::Ack { .. } => run.acked += 1,
            Event::Error { .. } => run.errors += 1,
            Event::Alarm { .. } => run.alarms += 1,
            Event::Executed { line, .. } => {
                run.executed += 1;
                if let Some(line) = line {
                    *self.seen.entry(*line).or_default() += 1;
                }
            }
            Event::End { completed, reason } => {
                run.ended = if *completed {
                    Ended::Completed
                } else {
                    Ended::Stopped
                };
                run.reason.clone_from(reason);
            }
            Event::ResumeAt { line, .. } => run.resume_at = Some(*line),
            Event::Start { .. }
            | Event::Status { .. }
            | Event::Message { .. }
            | Event::FeedOverride { .. } => {}
        }
    }

    fn finish(self) -> RunSummary {
        RunSummary {
            duration_s: self.last_t - self.first_t,
            executed_twice: self
                .seen
                .into_iter()
                .filter(|&(_, n)| n > 1)
                .map(|(line, _)| line)
                .collect(),
            ..self.run
        }
    }
}

#[cfg(test)]
mod tests;
