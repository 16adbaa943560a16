//! The run records on the command line: `whirl runs list|show`, and the [`Recorder`] that
//! records the runs of `plan`, `dry-run` and `stream` (docs/records.md).
//!
//! A run's record is opened, `running`, once its inputs are read and checked and before
//! anything is sent or written, and closed with its outcome when the command ends. The
//! rule when the database fails:
//!
//! - it cannot be opened, or the record cannot be made: the run does not start (nothing is
//!   sent, nothing written), and the error says so; `--allow-unrecorded` runs it all the
//!   same, with a warning, its log its only record. A run must not start unrecorded
//!   without the operator knowing.
//! - the record cannot be closed (the database went away mid-run): a warning, and the run
//!   ends as it would have. A machine already cutting never stops because an index is
//!   down; the log keeps the run, and the next whirl that opens the database closes the
//!   record from the log.
//!
//! A shop's PostgreSQL that cannot be reached is neither: the run is recorded in the
//! spool on the host, with a warning that says so, and uploaded by the next whirl that
//! opens the records and reaches the server (docs/records.md#the-spool).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use clap::Subcommand;
use whirl::config::machine::MachineProfile;
use whirl::judge::dry_run::DryRunReport;
use whirl::plan::Plan;
use whirl::records::from_log::read_run;
use whirl::records::{
    Ending, FileSnapshot, Filter, Finished, Kept, Kind, LogPlace, NewRun, Outcome, Place, Process,
    ProgramId, Recorded, Run, RunId, RunMode, RunProvenance, RunSummary, Store, Timestamp,
    Uploaded,
};
use whirl::transport::{self, Link, Posted, StreamError};

use crate::args::{Cli, Command, Controller};
use crate::terminal::say;

/// `whirl runs`.
#[derive(Subcommand)]
pub(crate) enum RunsCommand {
    /// The runs, newest first, as a table (or JSON). Runs whose process is gone without
    /// closing its record are closed first, from their logs.
    List {
        /// Only runs whose job file or program name contains this (any case).
        #[arg(long)]
        job: Option<String>,
        /// Only runs whose machine profile's name or file contains this (any case).
        #[arg(long)]
        machine: Option<String>,
        /// Only runs on a host whose name contains this (any case): a shop's database
        /// holds every bridge's runs.
        #[arg(long)]
        host: Option<String>,
        /// Only runs started at or after this UTC date or time: YYYY-MM-DD,
        /// YYYY-MM-DDTHH:MM or YYYY-MM-DDTHH:MM:SS.
        #[arg(long, value_parser = Timestamp::parse)]
        since: Option<Timestamp>,
        /// Only runs started before this UTC date or time (as --since).
        #[arg(long, value_parser = Timestamp::parse)]
        until: Option<Timestamp>,
        /// Only runs that ended so: running, completed, stopped, failed or interrupted.
        #[arg(long, value_parser = outcome)]
        outcome: Option<Outcome>,
        /// At most this many runs, the newest, 1 to 4294967295.
        #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
        limit: Option<u32>,
        /// JSON (an array of runs) instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// One run's whole record: its inputs and their hashes, the plan report, how it ended,
    /// where it resumes, its alarms and stops, its log.
    Show {
        /// The run's number, as `whirl runs list` gives it.
        id: RunId,
        /// JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// `--outcome`: one of the outcome words.
fn outcome(text: &str) -> Result<Outcome, String> {
    Outcome::from_word(text)
        .ok_or_else(|| "must be running, completed, stopped, failed or interrupted".to_owned())
}

/// A warning on standard error (there is nowhere to say it if that is closed).
fn warn(text: &str) {
    let _ = writeln!(std::io::stderr(), "warning: {text}");
}

/// An open database: the runtime its connections live on, the store.
struct Open {
    runtime: tokio::runtime::Runtime,
    store: Store,
}

/// Opens the records `--db` (or `WHIRL_DB`, or the default) names, and closes the records
/// of this host's runs whose process is gone; `say`: says so on standard error (`whirl
/// runs`, where the records are looked at; a run's own command does not talk of others).
fn open(db: Option<&str>, say: bool) -> Result<Open> {
    let place = Place::resolve(db)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let store = runtime.block_on(Store::open(&place))?;
    match store.uploaded() {
        Some(Ok(uploaded)) if say => say_uploaded(&store, uploaded),
        Some(Ok(_)) | None => {}
        Some(Err(e)) => warn(&format!(
            "{e}: the runs kept in the spool {} stay there until a whirl that opens the \
             records can upload them",
            store
                .spool()
                .map_or(String::new(), |f| f.display().to_string())
        )),
    }
    match runtime.block_on(store.close_orphans(&Process::current())) {
        Ok(closed) if say => {
            for (id, outcome) in closed {
                warn(&format!(
                    "run {id} in {} was left running by a process that is gone: closed as \
                     {outcome} from its log (whirl runs show {id})",
                    store.place()
                ));
            }
        }
        Ok(_) => {}
        Err(e) => warn(&format!("{e}")),
    }
    Ok(Open { runtime, store })
}

/// Says on standard error which runs kept in the spool went to the database.
fn say_uploaded(store: &Store, uploaded: &Uploaded) {
    if uploaded.runs.is_empty() {
        return;
    }
    let runs: Vec<String> = uploaded
        .runs
        .iter()
        .map(|(spooled, id)| format!("{spooled} as run {id}"))
        .collect();
    let _ = writeln!(
        std::io::stderr(),
        "whirl: uploaded the runs kept in the spool {} to {}: {}",
        store
            .spool()
            .map_or(String::new(), |f| f.display().to_string()),
        store.place(),
        runs.join(", ")
    );
}

/// `whirl runs …`.
pub(crate) fn runs(command: RunsCommand, recorder: &Recorder) -> Result<ExitCode> {
    let Open { runtime, store } = open(recorder.db.as_deref(), true)?;
    match command {
        RunsCommand::List {
            job,
            machine,
            host,
            since,
            until,
            outcome,
            limit,
            json,
        } => {
            let filter = Filter {
                job,
                machine,
                since,
                until,
                outcome,
                host,
                limit,
            };
            let runs = runtime.block_on(store.list(&filter))?;
            if json {
                say!("{}", serde_json::to_string_pretty(&runs)?)?;
            } else {
                table(&runs)?;
            }
        }
        RunsCommand::Show { id, json } => {
            let Some(run) = runtime.block_on(store.show(id))? else {
                bail!("{} holds no run {id}", store.place());
            };
            if json {
                say!("{}", serde_json::to_string_pretty(&run)?)?;
            } else {
                show(&run)?;
            }
        }
    }
    runtime.block_on(store.close_connections());
    Ok(ExitCode::SUCCESS)
}

/// How long a run took, from its record's times; a run still running, how long so far.
fn duration(run: &RunSummary) -> String {
    let Some(s) = run.duration_s else {
        return "?".into();
    };
    let took = match s {
        s if s < 60.0 => format!("{s:.1} s"),
        s if s < 3600.0 => format!("{:.0} min {:.0} s", (s / 60.0).floor(), s % 60.0),
        s => format!(
            "{:.0} h {:.0} min",
            (s / 3600.0).floor(),
            (s % 3600.0) / 60.0
        ),
    };
    if run.ended_at.is_none() {
        format!("{took} so far")
    } else {
        took
    }
}

/// Whether a run went to a machine, in a column's words: a plan, a dry run on the
/// simulator, or a stream (with its transport).
fn how(run: &RunSummary) -> String {
    let over = run
        .transport
        .as_deref()
        .map_or(String::new(), |t| format!(" ({t})"));
    match run.mode {
        RunMode::Plan => "plan".into(),
        RunMode::DryRun => format!("dry run{over}"),
        RunMode::Stream => format!("STREAM{over}"),
    }
}

/// The runs as a table, one a line, each column as wide as its widest entry.
fn table(runs: &[RunSummary]) -> Result<()> {
    let mut rows: Vec<[String; 10]> = vec![[
        "ID",
        "KIND",
        "HOW",
        "OUTCOME",
        "STARTED (UTC)",
        "TOOK",
        "RESUME",
        "HOST",
        "MACHINE",
        "JOB OR PROGRAM",
    ]
    .map(str::to_owned)];
    for run in runs {
        rows.push([
            run.id.to_string(),
            run.kind.to_string(),
            how(run),
            run.outcome.to_string(),
            run.started_at.clone(),
            duration(run),
            run.resume_at.map_or("-".into(), |l| l.to_string()),
            run.host.clone(),
            run.machine.clone().unwrap_or_else(|| "-".into()),
            run.job
                .clone()
                .or_else(|| run.program.clone())
                .unwrap_or_else(|| "-".into()),
        ]);
    }
    let widths: Vec<usize> = (0..10)
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    for row in &rows {
        let mut line = String::new();
        for (c, cell) in row.iter().enumerate() {
            let pad = widths[c] - cell.chars().count();
            // Numbers to the right, words to the left; the last column unpadded.
            match c {
                0 | 5 | 6 => line.push_str(&format!("{}{cell}  ", " ".repeat(pad))),
                9 => line.push_str(cell),
                _ => line.push_str(&format!("{cell}{}  ", " ".repeat(pad))),
            }
        }
        say!("{line}")?;
    }
    Ok(())
}

/// One run's record, as text.
fn show(run: &Run) -> Result<()> {
    let s = &run.summary;
    say!("run {}: {}, {}", s.id, s.kind, s.outcome)?;
    say!(
        "started    {} on {} (pid {})",
        s.started_at,
        s.host,
        run.pid
    )?;
    if let Some(uid) = &run.uid {
        say!("key        {uid}")?;
    }
    if let Some(ended) = &s.ended_at {
        say!("ended      {ended} ({})", duration(s))?;
    }
    if let Some(reason) = &s.reason {
        say!("reason     {reason}")?;
    }
    if let Some(job) = &run.job_file {
        say!("job        {} (sha256 {})", job.path, job.sha256)?;
    }
    if let Some(machine) = &run.machine_file {
        say!(
            "machine    {} from {} (sha256 {})",
            s.machine.as_deref().unwrap_or("?"),
            machine.path,
            machine.sha256
        )?;
    }
    if let Some(program) = &run.program_id {
        say!(
            "program    {}: {} lines (sha256 {})",
            program.name,
            program.lines,
            program.sha256
        )?;
    }
    if let Some(transport) = &s.transport {
        say!(
            "transport  {transport}{}",
            run.port
                .as_deref()
                .map_or(String::new(), |p| format!(" to {p}"))
        )?;
    }
    if let Some(m) = &run.measured {
        say!(
            "measured   overcut {:.4} mm, undercut {:.4} mm; Δ {} mm: {}",
            m.max_overcut_mm,
            m.max_undercut_mm,
            m.delta_mm,
            if m.within_delta {
                "within"
            } else {
                "BEYOND or incomplete"
            }
        )?;
    }
    if let Some(from) = run.resume_from {
        say!(
            "resumed    at line {from}{}",
            run.resumes
                .map_or(String::new(), |id| format!(", continuing run {id}"))
        )?;
    }
    if let Some(at) = s.resume_at {
        say!(
            "resume at  line {at}{}",
            run.possibly_run_to.map_or(String::new(), |to| format!(
                " (lines {at} to {to} may already have run)"
            ))
        )?;
    }
    if let Some(line) = run.last_line {
        say!("last done  line {line}")?;
    }
    if let Some(log) = &run.log {
        say!(
            "log        {} (from byte {})",
            log.path.display(),
            log.offset
        )?;
    }
    if let Some(provenance) = &run.provenance {
        say!(
            "provenance {}{}",
            provenance["check"].as_str().unwrap_or("?"),
            provenance["finding"]
                .as_str()
                .map_or(String::new(), |f| format!(": {f}"))
        )?;
        let header = &provenance["header"];
        if !header.is_null() {
            say!(
                "planned    from {} (sha256 {}) for \"{}\" (sha256 {}) by whirl {}",
                header["job"]["path"].as_str().unwrap_or("?"),
                header["job"]["sha256"].as_str().unwrap_or("?"),
                header["machine_name"].as_str().unwrap_or("?"),
                header["machine"]["sha256"].as_str().unwrap_or("?"),
                header["version"].as_str().unwrap_or("?"),
            )?;
        }
    }
    if run.plan_report.is_some() {
        say!(
            "plan       its report is in `whirl runs show {} --json`",
            s.id
        )?;
    }
    for note in &run.notes {
        say!(
            "{}  {}{}{}: {}",
            note.at.as_deref().unwrap_or("?"),
            note.kind,
            note.code.map_or(String::new(), |c| format!(" {c}")),
            note.line.map_or(String::new(), |l| format!(" at line {l}")),
            note.text
        )?;
    }
    Ok(())
}

/// The built-in machine profiles, as a record keeps the profile a run used.
pub(crate) const BUILTIN_SIM: (&str, &str) = (
    "machine-profiles/sim.toml (built in)",
    include_str!("../../../machine-profiles/sim.toml"),
);
pub(crate) const BUILTIN_LINUXCNC: (&str, &str) = (
    "machine-profiles/linuxcnc-lathe.toml (built in)",
    include_str!("../../../machine-profiles/linuxcnc-lathe.toml"),
);

/// What the command line says of a run: the files it reads and its log.
struct Inputs {
    kind: Kind,
    job: Option<PathBuf>,
    machine: Option<PathBuf>,
    builtin_machine: (&'static str, &'static str),
    /// `plan -o`: the program's name.
    output: Option<PathBuf>,
    log: Option<PathBuf>,
    /// How a dry run sends the program.
    transport: Option<&'static str>,
    /// `--resume-at`, 1-based.
    resume_from: Option<usize>,
}

/// Records the run of `plan`, `dry-run` or `stream`: [`Recorder::begin`] opens the record,
/// the command notes what it learns, [`Recorder::finish`] closes it with the command's end.
pub(crate) struct Recorder {
    /// `--db`.
    db: Option<String>,
    allow_unrecorded: bool,
    inputs: Option<Inputs>,
    plan: Option<(String, ProgramId)>,
    /// What the run's program was planned from, and how that was checked.
    provenance: Option<RunProvenance>,
    /// How the run ended, as the command noted it.
    noted: Option<Ending>,
    open: Option<(Open, Recorded, NewRun)>,
    /// When its record opened (about when its log's clock started).
    started: Option<Timestamp>,
}

impl Recorder {
    /// The recorder of the command `cli` runs (which records nothing unless it is a run).
    pub(crate) fn new(cli: &Cli) -> Recorder {
        let inputs = match &cli.command {
            Command::Plan {
                job,
                machine,
                output,
                ..
            } => Some(Inputs {
                kind: Kind::Plan,
                job: Some(job.clone()),
                machine: machine.clone(),
                builtin_machine: BUILTIN_SIM,
                output: Some(output.clone()),
                log: None,
                transport: None,
                resume_from: None,
            }),
            Command::DryRun {
                job,
                machine,
                log,
                transport,
                controller,
                ..
            } => Some(Inputs {
                kind: Kind::DryRun,
                job: Some(job.clone()),
                machine: machine.clone(),
                builtin_machine: match controller {
                    Controller::WhirlSim => BUILTIN_SIM,
                    Controller::Linuxcnc => BUILTIN_LINUXCNC,
                },
                output: None,
                log: log.clone(),
                transport: Some(match controller {
                    Controller::WhirlSim => transport::TransportKind::from(*transport).name(),
                    Controller::Linuxcnc => "linuxcnc",
                }),
                resume_from: None,
            }),
            Command::Stream {
                input,
                machine,
                log,
                resume_at,
                ..
            } => Some(Inputs {
                kind: Kind::Stream,
                job: input
                    .extension()
                    .is_some_and(|e| e == "toml")
                    .then(|| input.clone()),
                machine: machine.clone(),
                builtin_machine: BUILTIN_SIM,
                output: None,
                log: Some(log.clone()),
                transport: None,
                resume_from: *resume_at,
            }),
            _ => None,
        };
        Recorder {
            db: cli.db.clone(),
            allow_unrecorded: cli.allow_unrecorded,
            inputs,
            plan: None,
            provenance: None,
            noted: None,
            started: None,
            open: None,
        }
    }

    /// The SQLite file this run is to be recorded in, and what names it, for the command
    /// to check against its own files before anything is written ([`crate::files`]);
    /// `None` if the command records nothing, or not in a file of this host's (a database
    /// that cannot be named is said by [`Recorder::begin`]).
    pub(crate) fn database(&self) -> Option<(&'static str, PathBuf)> {
        self.inputs.as_ref()?;
        let what = match &self.db {
            Some(_) => "--db",
            None if std::env::var_os(whirl::records::store::ENV).is_some_and(|v| !v.is_empty()) => {
                "WHIRL_DB"
            }
            None => "the default place",
        };
        let place = Place::resolve(self.db.as_deref()).ok()?;
        Some((what, place.file()?.to_owned()))
    }

    /// Opens the run's record, once its inputs are read and checked (`machine` is the
    /// profile loaded), before anything is sent or written: `posted`, the program it
    /// runs, and `link`, where to, when they are known. If the database cannot take it,
    /// the run is refused unless `--allow-unrecorded` was given (see the module's docs).
    /// What live telemetry says of the run beyond its log: its record, its job, its
    /// program's hash and what the program was planned from (after [`Recorder::begin`]).
    pub(crate) fn telemetry_context(&self, kind: &str) -> whirl::telemetry::RunContext {
        let run = self
            .open
            .as_ref()
            .map(|(_, recorded, run)| (recorded.id, run));
        whirl::telemetry::RunContext {
            kind: kind.to_owned(),
            record: run.map(|(id, _)| id),
            job: self
                .inputs
                .as_ref()
                .and_then(|i| i.job.as_ref())
                .map(|job| job.display().to_string()),
            program_sha256: run
                .and_then(|(_, run)| run.program.as_ref())
                .map(|p| p.sha256.clone()),
            provenance: self
                .provenance
                .as_ref()
                .and_then(|p| p.header.as_ref())
                .and_then(|header| serde_json::to_value(header).ok()),
        }
    }

    pub(crate) fn begin(
        &mut self,
        machine: &MachineProfile,
        posted: Option<&Posted>,
        link: Option<&Link>,
    ) -> Result<()> {
        let Some(inputs) = &self.inputs else {
            return Ok(());
        };
        let mut run = NewRun::new(inputs.kind);
        run.job = inputs.job.as_deref().and_then(snapshot);
        run.machine = match &inputs.machine {
            Some(path) => snapshot(path),
            None => Some(FileSnapshot::of(
                inputs.builtin_machine.0,
                inputs.builtin_machine.1.as_bytes(),
            )),
        };
        run.machine_name = Some(machine.name.clone());
        run.program = posted.map(|p| ProgramId::of(p.name.clone(), &p.lines.join("\n")));
        run.plan_report = self.plan.as_ref().map(|(report, _)| report.clone());
        run.transport = link
            .map(|l| l.kind().name())
            .or(inputs.transport)
            .map(str::to_owned);
        run.port = link.map(Link::to_string);
        run.resume_from = inputs.resume_from;
        run.provenance = self.provenance.clone();
        run.log = inputs.log.as_deref().map(|path| LogPlace {
            path: std::path::absolute(path).unwrap_or_else(|_| path.to_owned()),
            offset: std::fs::metadata(path).map_or(0, |m| m.len()),
        });
        self.started = Some(Timestamp::now());
        let opened = open(self.db.as_deref(), false).and_then(|open| {
            let recorded = open.runtime.block_on(open.store.begin(&run))?;
            Ok((open, recorded))
        });
        match opened {
            Ok((open, recorded)) => {
                if let Kept::Spool { file, why } = &recorded.kept {
                    warn(&format!(
                        "{why}: this run is recorded in the spool {} (as its run {}), and \
                         uploaded to {} by the next whirl that opens them and reaches them",
                        file.display(),
                        recorded.id,
                        open.store.place()
                    ));
                }
                self.open = Some((open, recorded, run));
                Ok(())
            }
            Err(e) if self.allow_unrecorded => {
                warn(&format!(
                    "{e:#}: this run is not recorded (--allow-unrecorded){}",
                    inputs.log.as_ref().map_or(String::new(), |l| format!(
                        "; its log {} keeps it",
                        l.display()
                    ))
                ));
                Ok(())
            }
            Err(e) => Err(e.context(
                "the run is not started, since it could not be recorded (nothing was sent or \
                 written); --allow-unrecorded runs it without a record",
            )),
        }
    }

    /// What the run's program was planned from, and how it was checked: kept from the
    /// record's opening if known by then, else when it closes.
    pub(crate) fn provenance(&mut self, provenance: RunProvenance) {
        self.provenance = Some(provenance);
    }

    /// The job was planned: its report, and for `plan` the program it wrote.
    pub(crate) fn planned(&mut self, plan: &Plan) {
        let report = serde_json::to_string(&plan.report).unwrap_or_default();
        let name = self
            .inputs
            .as_ref()
            .and_then(|i| i.output.as_ref())
            .map_or_else(String::new, |o| o.display().to_string());
        self.plan = Some((report, ProgramId::of(name, &plan.text)));
    }

    /// A stream ended (or failed): how, and where it resumes.
    pub(crate) fn streamed(&mut self, result: &Result<transport::Outcome, StreamError>) {
        self.noted = Some(Ending::of_stream(result));
    }

    /// A dry run's report.
    pub(crate) fn dry_ran(&mut self, report: &DryRunReport) {
        self.noted = Some(Ending::of_dry_run(report));
    }

    /// Closes the record with how the command ended (`result`, which is handed back as it
    /// is): a database that cannot take it is said on standard error, and changes nothing
    /// of the command's end.
    pub(crate) fn finish(&mut self, result: Result<ExitCode>) -> Result<ExitCode> {
        let Some((open, recorded, run)) = self.open.take() else {
            return result;
        };
        let id = recorded.id;
        let ending = self.ending(&run, &result);
        let closed = open.runtime.block_on(open.store.finish(&recorded, &ending));
        match closed {
            Ok(Finished {
                kept: Kept::Spool { file, why },
                ..
            }) if recorded.kept == Kept::Database => warn(&format!(
                "{why}: the end of run {id} is kept in the spool {}, and uploaded to {} by the \
                 next whirl that opens them and reaches them",
                file.display(),
                open.store.place()
            )),
            Ok(_) => {}
            Err(e) => {
                warn(&format!(
                    "{e}: run {id} stays open in the records until the next whirl that opens them \
                 closes it {}",
                    run.log.as_ref().map_or(
                        "as interrupted (it keeps no log)".into(),
                        |l| format!("from its log {}", l.path.display())
                    )
                ))
            }
        }
        open.runtime.block_on(open.store.close_connections());
        result
    }

    /// The record's ending: the one the command noted, else its result (an error where
    /// the run had not said it stopped is a failure); the plan; what the log says.
    fn ending(&self, run: &NewRun, result: &Result<ExitCode>) -> Ending {
        let mut ending = self
            .noted
            .clone()
            .unwrap_or_else(|| Ending::new(Outcome::Completed));
        if let Err(error) = result {
            if ending.outcome == Outcome::Completed {
                ending.outcome = Outcome::Failed;
                ending.reason = Some(format!("{error:#}"));
            }
        }
        ending.provenance = self.provenance.clone();
        if let Some((report, program)) = &self.plan {
            ending.plan_report = Some(report.clone());
            if run.kind == Kind::Plan {
                ending.program = Some(program.clone());
            }
        }
        if let Some(log) = &run.log {
            if let Ok(facts) = read_run(&log.path, log.offset, run.resume_from.unwrap_or(1)) {
                // The log's clock starts with the transport, a moment (the link's opening)
                // after the record opened: its notes are timed by the record's start, at
                // worst that moment early, never at the run's end.
                ending.add_log(&facts, self.started);
            }
        }
        ending
    }
}

/// A file as a run read it; `None` if it cannot be read now (the run read it a moment
/// ago; the record goes without its contents rather than stop the run).
fn snapshot(path: &Path) -> Option<FileSnapshot> {
    std::fs::read(path)
        .ok()
        .map(|bytes| FileSnapshot::of(path.display().to_string(), &bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_a_person_says_them() {
        let now = Timestamp::parse("2026-05-01T10:00:40").unwrap();
        let run = |start: &str, end: Option<&str>| RunSummary {
            id: 1,
            kind: Kind::Stream,
            outcome: Outcome::Completed,
            started_at: start.into(),
            ended_at: end.map(Into::into),
            job: None,
            program: None,
            machine: None,
            transport: Some("serial".into()),
            mode: RunMode::Stream,
            host: "lathe-1".into(),
            duration_s: whirl::records::duration_s(start, end, now),
            resume_at: None,
            reason: None,
        };
        let t0 = "2026-05-01T10:00:00.000Z";
        // Still running: how long so far.
        assert_eq!(duration(&run(t0, None)), "40.0 s so far");
        assert_eq!(duration(&run("yesterday", None)), "?");
        assert_eq!(how(&run(t0, None)), "STREAM (serial)");
        assert_eq!(
            duration(&run(t0, Some("2026-05-01T10:00:12.340Z"))),
            "12.3 s"
        );
        assert_eq!(
            duration(&run(t0, Some("2026-05-01T10:27:25.000Z"))),
            "27 min 25 s"
        );
        assert_eq!(
            duration(&run(t0, Some("2026-05-01T12:30:00.000Z"))),
            "2 h 30 min"
        );
        assert_eq!(
            outcome("done").unwrap_err(),
            "must be running, completed, stopped, failed or interrupted"
        );
        assert_eq!(outcome("interrupted"), Ok(Outcome::Interrupted));
    }

    #[test]
    fn the_built_in_profiles_are_the_repositorys() {
        let sim = MachineProfile::from_toml(BUILTIN_SIM.1, BUILTIN_SIM.0).unwrap();
        assert_eq!(sim.name, MachineProfile::builtin_sim().unwrap().name);
        let lathe = MachineProfile::from_toml(BUILTIN_LINUXCNC.1, BUILTIN_LINUXCNC.0).unwrap();
        assert_eq!(lathe.name, MachineProfile::builtin_linuxcnc().unwrap().name);
    }
}
