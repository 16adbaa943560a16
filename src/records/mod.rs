//! Run records: every `plan`, `dry-run`, `stream` and console (`serve`) run in a real
//! database, so that a shop can say months later which program cut which part, on which
//! machine, with which alarms and resumes.
//!
//! The executed-path log ([`crate::log`]) stays the raw record of a run; the database
//! indexes the runs: what went in (the job and machine files' contents and hashes, the
//! program's hash, the plan report), how each ended (outcome, reason, alarms, the stop and
//! where it resumes, a dry run's measured error) and where its log is. A record is opened
//! `running` before anything is sent and closed with the outcome; one its process never
//! closed (killed outright) is closed on the next opening of the database, from what its
//! log says ([`Store::close_orphans`], [`process`], [`from_log`]).
//!
//! - [`store`]: the records a run uses: SQLite (one file, the default) or PostgreSQL (a
//!   shop's server, written by many bridges at once), and PostgreSQL's spool.
//! - [`database`]: one database through the same code and the same SQL for both,
//!   migrations embedded in the binary.
//! - [`spool`]: the runs a shop's PostgreSQL could not take, kept on the host and uploaded
//!   once it answers.
//! - [`uid`]: a run's key, the same in every database it is written to.
//! - [`process`]: whose a running record is and whether that process still runs.
//! - [`from_log`]: what a run's log says of it.
//! - [`ending`]: how a run ended, from a stream's outcome, a dry run's report, its log.
//! - [`time`]: the records' UTC times.
//!
//! The store's calls are async, for a server that records the runs it starts while it
//! serves pages; the command line drives them from a runtime of its own. `docs/records.md`
//! has the schema, the default place and the interruption rule.

pub mod database;
pub mod ending;
pub mod from_log;
pub mod process;
pub mod spool;
pub mod store;
pub mod time;
pub mod uid;

use std::path::PathBuf;

use serde::Serialize;
use sha2::{Digest, Sha256};

/// The one hash of the files a run reads, the one a program's provenance holds.
pub use crate::config::provenance::sha256_hex;
use crate::config::provenance::{hex, Provenance};
pub use process::Process;
pub use spool::Uploaded;
pub use store::{Finished, Kept, Place, RecordError, Recorded, Store};
pub use time::Timestamp;
pub use uid::Uid;

/// A record's number in its database, from 1.
pub type RunId = i64;

/// What kind of run a record is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// `whirl plan`: a program written.
    Plan,
    /// `whirl dry-run`: a job run on a simulated controller.
    DryRun,
    /// `whirl stream`: a program sent to a machine.
    Stream,
    /// A run started from `whirl serve`'s console.
    Serve,
}

/// How a run ended, or that it has not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// Its process is at it (or was killed and no one has opened the database since).
    Running,
    /// Every line run (a dry run: every line run, whatever it measured).
    Completed,
    /// Stopped short by the machine, the operator or a guard: an alarm, a hold that ended
    /// the run, a signal; it says where to resume.
    Stopped,
    /// It could not be carried out: an error of the bridge, the link or the input.
    Failed,
    /// Its process ended without closing the record (killed, crashed, the host down).
    Interrupted,
}

/// What happened to a run as it went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoteKind {
    /// The controller raised an alarm (its code in [`Note::code`]).
    Alarm,
    /// A feed hold.
    Hold,
    /// A resume from a hold.
    Resume,
    /// The run stopped: [`Note::line`] is where it resumes.
    Stop,
    /// The controller ran at a new feed override ([`Note::code`]: percent): faster than
    /// planned coarsens the insert cusp, so the record says every value a part was cut at.
    FeedOverride,
}

macro_rules! words {
    ($type:ty { $($variant:ident = $word:literal),* $(,)? }) => {
        impl $type {
            /// The word the database holds and the command line takes.
            pub fn as_str(self) -> &'static str {
                match self {
                    $(<$type>::$variant => $word,)*
                }
            }

            /// The value a word names, if any.
            pub fn from_word(word: &str) -> Option<$type> {
                match word {
                    $($word => Some(<$type>::$variant),)*
                    _ => None,
                }
            }
        }

        impl std::fmt::Display for $type {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.pad(self.as_str())
            }
        }
    };
}

words!(Kind {
    Plan = "plan",
    DryRun = "dry-run",
    Stream = "stream",
    Serve = "serve",
});
words!(Outcome {
    Running = "running",
    Completed = "completed",
    Stopped = "stopped",
    Failed = "failed",
    Interrupted = "interrupted",
});
words!(NoteKind {
    Alarm = "alarm",
    Hold = "hold",
    Resume = "resume",
    Stop = "stop",
    FeedOverride = "feed-override",
});

/// A file a run read, as it read it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileSnapshot {
    /// Where it was (a built-in profile: its name, "(built in)").
    pub path: String,
    /// SHA-256 of its bytes, lower-case hex.
    pub sha256: String,
    /// Its text.
    pub text: String,
}

impl FileSnapshot {
    /// The file called `path` whose bytes are `bytes` (not UTF-8 ones kept lossily; the
    /// hash is of the bytes).
    pub fn of(path: impl Into<String>, bytes: &[u8]) -> FileSnapshot {
        FileSnapshot {
            path: path.into(),
            sha256: sha256_hex(bytes),
            text: String::from_utf8_lossy(bytes).into_owned(),
        }
    }
}

/// The program a run sent or wrote, by name and hash: the same text cut twice has the
/// same hash, whatever it was called.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProgramId {
    /// The program file, or the job it was planned from.
    pub name: String,
    /// SHA-256 of its text, lower-case hex.
    pub sha256: String,
    /// Its number of lines.
    pub lines: usize,
}

impl ProgramId {
    /// The program `text` called `name`. The hash is of its lines, each ended by a
    /// newline: a program saved with CRLF line ends, or without a newline after its last
    /// line, is the same program.
    pub fn of(name: impl Into<String>, text: &str) -> ProgramId {
        let mut hash = Sha256::new();
        let mut lines = 0;
        for line in text.lines() {
            hash.update(line.as_bytes());
            hash.update(b"\n");
            lines += 1;
        }
        ProgramId {
            name: name.into(),
            sha256: hex(&hash.finalize()),
            lines,
        }
    }
}

/// How a run's program stands to what it was planned from (docs/streaming.md#provenance).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProvenanceCheck {
    /// The run planned the program itself (`plan`, a job streamed or dry-run, the
    /// console): its provenance is right by construction.
    Planned,
    /// The program's header was checked against its job and machine profile: they match.
    Matched,
    /// The check found the program stale, for another machine or without provenance, and
    /// the operator streamed it all the same (`--no-provenance-check`).
    Overridden,
    /// A dry run or verification of a given program against a given job: what did not
    /// match was said, and the program measured against the job all the same.
    Reported,
}

/// A run's provenance, as its record keeps it (JSON in the `provenance` column).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunProvenance {
    /// What the program was planned from: its header, or the plan's own; `None` for a
    /// program without a header that reads.
    pub header: Option<Provenance>,
    /// How it stood to its job and machine profile.
    pub check: ProvenanceCheck,
    /// What the check found, when it did not match.
    pub finding: Option<String>,
}

impl RunProvenance {
    /// A program this run planned, from `header`.
    pub fn planned(header: Provenance) -> RunProvenance {
        RunProvenance {
            header: Some(header),
            check: ProvenanceCheck::Planned,
            finding: None,
        }
    }

    /// The JSON the record holds.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a provenance serialises")
    }
}

/// Where a run's events are in its executed-path log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogPlace {
    /// The log (absolute, so that any later command finds it).
    pub path: PathBuf,
    /// Its length when the run opened it: the run's events begin there.
    pub offset: u64,
}

/// What is known of a run when it starts.
#[derive(Debug, Clone, PartialEq)]
pub struct NewRun {
    /// What kind of run.
    pub kind: Kind,
    /// The job file.
    pub job: Option<FileSnapshot>,
    /// The machine profile file.
    pub machine: Option<FileSnapshot>,
    /// The machine profile's name.
    pub machine_name: Option<String>,
    /// The program, if it is known before the run (a stream, a dry run).
    pub program: Option<ProgramId>,
    /// The plan report (JSON), if the job was planned before the run.
    pub plan_report: Option<String>,
    /// How the program goes (serial, modbus-tcp, …).
    pub transport: Option<String>,
    /// Where it goes (a port, an address).
    pub port: Option<String>,
    /// The line (1-based) the run starts at when it resumes an earlier one.
    pub resume_from: Option<usize>,
    /// What its program was planned from, and how that was checked, when known at its start.
    pub provenance: Option<RunProvenance>,
    /// Its executed-path log.
    pub log: Option<LogPlace>,
    /// The process that runs it.
    pub process: Process,
}

impl NewRun {
    /// A run of `kind` by this process, nothing else known yet.
    pub fn new(kind: Kind) -> NewRun {
        NewRun {
            kind,
            job: None,
            machine: None,
            machine_name: None,
            program: None,
            plan_report: None,
            transport: None,
            port: None,
            resume_from: None,
            provenance: None,
            log: None,
            process: Process::current(),
        }
    }
}

/// The profile error a dry run measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Measured {
    /// Largest overcut, mm.
    pub max_overcut_mm: f64,
    /// Largest undercut, mm.
    pub max_undercut_mm: f64,
    /// The allowable error Δ, mm.
    pub delta_mm: f64,
    /// Completed with the whole groove within Δ.
    pub within_delta: bool,
}

/// How a run ended, as its record is closed.
#[derive(Debug, Clone, PartialEq)]
pub struct Ending {
    /// Completed, stopped, failed or interrupted.
    pub outcome: Outcome,
    /// Why, if it did not complete.
    pub reason: Option<String>,
    /// The program, if it was made by the run (a plan).
    pub program: Option<ProgramId>,
    /// The plan report (JSON), if the run planned.
    pub plan_report: Option<String>,
    /// What the program the run planned was planned from (a plan learns it as it ends).
    pub provenance: Option<RunProvenance>,
    /// A dry run's measured error.
    pub measured: Option<Measured>,
    /// Where to resume (1-based line), if it did not complete.
    pub resume_at: Option<usize>,
    /// Lines from `resume_at` up to this one may have run all the same.
    pub possibly_run_to: Option<usize>,
    /// The last line known done.
    pub last_line: Option<usize>,
    /// What happened as it went that is not noted yet (alarms, its stop).
    pub notes: Vec<Note>,
}

impl Ending {
    /// An ending with `outcome` and nothing more known.
    pub fn new(outcome: Outcome) -> Ending {
        Ending {
            outcome,
            reason: None,
            program: None,
            plan_report: None,
            provenance: None,
            measured: None,
            resume_at: None,
            possibly_run_to: None,
            last_line: None,
            notes: Vec::new(),
        }
    }
}

/// One thing that happened to a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Note {
    /// What.
    pub kind: NoteKind,
    /// When it happened; `None`: when the store writes the note (a hold pressed, a run's
    /// end), which is when it happened.
    pub at: Option<String>,
    /// The program line it concerns (1-based): where a stop resumes, where a hold held.
    pub line: Option<usize>,
    /// An alarm's code; a feed override's percent.
    pub code: Option<u32>,
    /// In words.
    pub text: String,
}

impl Note {
    /// A note of `kind` saying `text`, no line, no code.
    pub fn new(kind: NoteKind, text: impl Into<String>) -> Note {
        Note {
            kind,
            at: None,
            line: None,
            code: None,
            text: text.into(),
        }
    }
}

/// Which runs to list; every field left `None` lets every run through.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Filter {
    /// The job file's path or the program's name contains this (any case).
    pub job: Option<String>,
    /// The machine profile's name or path contains this (any case).
    pub machine: Option<String>,
    /// Started at or after this.
    pub since: Option<Timestamp>,
    /// Started before this.
    pub until: Option<Timestamp>,
    /// Ended so (or still running).
    pub outcome: Option<Outcome>,
    /// Ran on a host whose name contains this (any case).
    pub host: Option<String>,
    /// At most this many, the newest.
    pub limit: Option<u32>,
}

/// Whether a run sent its program to a machine: the history tells a dry run on the
/// simulator from a stream to a real controller at a glance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RunMode {
    /// `whirl plan`: a program written, nothing sent.
    Plan,
    /// On a simulated controller: `whirl dry-run`, or a console run with no port.
    DryRun,
    /// To a machine: `whirl stream`, or a console run that names its port.
    Stream,
}

impl RunMode {
    /// The mode of a run of `kind`, which went to `port` if it names one. A console run
    /// records no port for a dry run (the simulator is its own), one for a stream.
    pub fn of(kind: Kind, port: Option<&str>) -> RunMode {
        match (kind, port) {
            (Kind::Plan, _) => RunMode::Plan,
            (Kind::DryRun, _) | (Kind::Serve, None) => RunMode::DryRun,
            (Kind::Stream, _) | (Kind::Serve, Some(_)) => RunMode::Stream,
        }
    }
}

words!(RunMode {
    Plan = "plan",
    DryRun = "dry-run",
    Stream = "stream",
});

/// A run's duration in seconds: from `started` to `ended`, or to `now` for a run without
/// an end (still running); `None` if a time does not read.
pub fn duration_s(started: &str, ended: Option<&str>, now: Timestamp) -> Option<f64> {
    let start = Timestamp::parse(started).ok()?;
    let end = match ended {
        Some(text) => Timestamp::parse(text).ok()?,
        None => now,
    };
    Some((end.0 - start.0).max(0) as f64 / 1000.0)
}

/// A run as a list shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// Its number.
    pub id: RunId,
    /// What kind of run.
    pub kind: Kind,
    /// How it ended.
    pub outcome: Outcome,
    /// When it started and ended (UTC, RFC 3339).
    pub started_at: String,
    /// See `started_at`.
    pub ended_at: Option<String>,
    /// The host it ran on (a shop's database holds every bridge's runs).
    pub host: String,
    /// The job file.
    pub job: Option<String>,
    /// The program.
    pub program: Option<String>,
    /// The machine profile's name.
    pub machine: Option<String>,
    /// How the program went.
    pub transport: Option<String>,
    /// A plan, a dry run on the simulator or a stream to a machine.
    pub mode: RunMode,
    /// Seconds from its start to its end; for a run still running, to when it was read.
    pub duration_s: Option<f64>,
    /// Where it resumes (1-based line), if it did not complete.
    pub resume_at: Option<usize>,
    /// Why, if it did not complete.
    pub reason: Option<String>,
}

/// A whole record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Run {
    /// What a list shows of it.
    #[serde(flatten)]
    pub summary: RunSummary,
    /// Its key in every database; `None` for a record made before keys were.
    pub uid: Option<Uid>,
    /// The process that ran it.
    pub pid: u32,
    /// The job file as it was.
    pub job_file: Option<FileSnapshot>,
    /// The machine profile file as it was.
    pub machine_file: Option<FileSnapshot>,
    /// The program's name, hash and length.
    pub program_id: Option<ProgramId>,
    /// Where it went.
    pub port: Option<String>,
    /// The plan report.
    pub plan_report: Option<serde_json::Value>,
    /// What its program was planned from, and how that was checked ([`RunProvenance`] as
    /// JSON).
    pub provenance: Option<serde_json::Value>,
    /// A dry run's measured error.
    pub measured: Option<Measured>,
    /// The line it started at, if it resumed an earlier run.
    pub resume_from: Option<usize>,
    /// The run it resumed: the latest earlier run of the same program that did not
    /// complete, the one whose resume point is `resume_from` if there is one.
    pub resumes: Option<RunId>,
    /// Lines from `resume_at` up to this one may have run all the same.
    pub possibly_run_to: Option<usize>,
    /// The last line known done.
    pub last_line: Option<usize>,
    /// Its executed-path log.
    pub log: Option<LogPlace>,
    /// What happened as it went, in order.
    pub notes: Vec<Note>,
}

/// Runs `future` to its end on a runtime of its own: the store's tests are synchronous.
#[cfg(test)]
pub(crate) fn block_on<F: std::future::Future>(future: F) -> F::Output {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(future)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_words_read_back_as_what_they_name() {
        for kind in [Kind::Plan, Kind::DryRun, Kind::Stream, Kind::Serve] {
            assert_eq!(Kind::from_word(kind.as_str()), Some(kind));
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.as_str());
        }
        for outcome in [
            Outcome::Running,
            Outcome::Completed,
            Outcome::Stopped,
            Outcome::Failed,
            Outcome::Interrupted,
        ] {
            assert_eq!(Outcome::from_word(outcome.as_str()), Some(outcome));
            assert_eq!(serde_json::to_value(outcome).unwrap(), outcome.as_str());
        }
        for kind in [
            NoteKind::Alarm,
            NoteKind::Hold,
            NoteKind::Resume,
            NoteKind::Stop,
            NoteKind::FeedOverride,
        ] {
            assert_eq!(NoteKind::from_word(kind.as_str()), Some(kind));
        }
        assert_eq!(Outcome::from_word("done"), None);
    }

    #[test]
    fn a_console_run_is_a_dry_run_without_a_port_and_a_stream_with_one() {
        assert_eq!(RunMode::of(Kind::Serve, None), RunMode::DryRun);
        assert_eq!(
            RunMode::of(Kind::Serve, Some("/dev/ttyUSB0")),
            RunMode::Stream
        );
        assert_eq!(RunMode::of(Kind::DryRun, None), RunMode::DryRun);
        assert_eq!(RunMode::of(Kind::Stream, Some("x")), RunMode::Stream);
        assert_eq!(RunMode::of(Kind::Plan, None), RunMode::Plan);
        assert_eq!(serde_json::to_value(RunMode::DryRun).unwrap(), "dry-run");
    }

    #[test]
    fn a_duration_runs_from_start_to_end_or_to_now_while_running() {
        let start = "2026-05-01T10:00:00.000Z";
        let now = Timestamp::parse("2026-05-01T10:01:00").unwrap();
        assert_eq!(
            duration_s(start, Some("2026-05-01T10:00:12.340Z"), now),
            Some(12.34)
        );
        assert_eq!(duration_s(start, None, now), Some(60.0));
        assert_eq!(duration_s("yesterday", None, now), None);
    }

    #[test]
    fn hashes_are_sha_256_of_the_bytes() {
        // FIPS 180-2's test vector "abc".
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let program = ProgramId::of("p.nc", "G0 X1\nG1 Z2\n");
        assert_eq!(program.lines, 2);
        assert_eq!(program.sha256, sha256_hex(b"G0 X1\nG1 Z2\n"));
        // Line ends are not the program.
        assert_eq!(
            ProgramId::of("q.nc", "G0 X1\r\nG1 Z2").sha256,
            program.sha256
        );
        assert_ne!(
            ProgramId::of("p.nc", "G0 X1\nG1 Z3\n").sha256,
            program.sha256
        );
        let file = FileSnapshot::of("job.toml", b"a = 1\n");
        assert_eq!((file.text.as_str(), file.sha256.len()), ("a = 1\n", 64));
    }
}
