//! A console run from request to end: every refusal settled before anything starts
//! (machine, path, job, plan, the machine's limits, the lock, the run's record), then the
//! dry run (or the stream to the machine, or a resume of either) on a thread of its own, its
//! progress and log read into the [`Registry`] as it goes, and its record closed with how
//! it ended.
//!
//! A run gets its own thread and single-threaded runtime: the simulator runs as fast as its
//! time scale lets it and must not slow the server, and the run must outlive any page.

use super::groove;
use super::lock::{self, LockError, MachineLock};
use super::paths::{JobDir, PathError};
use super::record::{self, Records};
use super::registry::{around, Inputs, ProvenanceView, Registry, ResumePoint, RunError, RunView};
use super::resume::{self, ResumeError, ResumeOptions};
use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::config::provenance::{self, Provenance, Source};
use crate::geometry::linkage::Ring;
use crate::judge::dry_run::{self, DryRunOptions};
use crate::judge::svg::Plot;
use crate::log::{Event, ExecLog, FeedOverrideState, Record};
use crate::plan::overrides::FeedCap;
use crate::records::{
    Ending, FileSnapshot, Finished, Kept, NoteKind, Outcome, ProgramId, Recorded, RunProvenance,
    Store, Timestamp,
};
use crate::telemetry::{self, RunContext};
use crate::transport::control::override_range;
use crate::transport::{
    self, Commands, Link, Posted, Progress, ProgressFn, RunOptions, TransportKind,
};
use std::collections::BTreeMap;
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The emulated link's baud rate in a console dry run.
const BAUD: u32 = 115_200;

/// How often a run's log is read into its view, at most.
const LOG_READ_EVERY: Duration = Duration::from_millis(250);

/// The slowest and fastest time scales a console run takes: from a tenth of real time
/// (to watch a cut closely) to as fast as a dry run of hours should go in a minute.
pub const TIME_SCALES: (f64, f64) = (0.1, 1000.0);

/// One `whirl serve`: its machines, its jobs folder and its runs.
pub struct Console {
    /// The machines, by profile name.
    pub machines: BTreeMap<String, MachineProfile>,
    /// Where the jobs are.
    pub jobs: JobDir,
    /// The runs.
    pub registry: Registry,
    /// Where the runs are recorded; `None`: unrecorded (`--allow-unrecorded`).
    pub records: Option<Records>,
    /// The machine profiles' files as read, by machine name, for the records.
    pub machine_files: BTreeMap<String, FileSnapshot>,
    /// Where each machine's live state is published (`[telemetry]`, `--mqtt`), by machine
    /// name; a machine without one publishes nothing.
    pub telemetry: BTreeMap<String, telemetry::Handle>,
    /// Where the machine locks are.
    lock_dir: PathBuf,
    /// This process, as a lock names it.
    holder: String,
}

/// A run the page asks for.
#[derive(Debug, Clone, serde::Deserialize)]
pub struct RunRequest {
    /// The machine's name.
    pub machine: String,
    /// The job, relative to the jobs folder.
    pub job: String,
    /// A dry run's transport: `serial`, `modbus-tcp`, `modbus-rtu` or `can-slcan`.
    #[serde(default)]
    pub transport: String,
    /// A dry run's simulated seconds per wall second.
    #[serde(default = "real_time")]
    pub time_scale: f64,
    /// Stream to the machine over its profile's `[connection]` instead of dry-running.
    #[serde(default)]
    pub stream: bool,
    /// Who asks: the client's address and session, as the HTTP edge tells it (never
    /// read from the request's body); the run's lock and view name it.
    #[serde(skip)]
    pub client: String,
}

fn real_time() -> f64 {
    1.0
}

/// Why a run, a plan or a verification was refused.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// No such machine.
    #[error("no machine \"{0}\" in this console (see --machine)")]
    UnknownMachine(String),
    /// The job path.
    #[error(transparent)]
    Path(#[from] PathError),
    /// The job file.
    #[error("{0}")]
    Job(String),
    /// The plan.
    #[error("cannot plan {job}: {error}")]
    Plan {
        /// The job.
        job: String,
        /// Why.
        error: String,
    },
    /// A transport the simulator does not serve, or a program the machine refuses.
    #[error("{0}")]
    Preflight(String),
    /// A time scale out of range.
    #[error("time scale {0} is out of range: {min} to {max}", min = TIME_SCALES.0, max = TIME_SCALES.1)]
    TimeScale(f64),
    /// The machine is busy here, or nothing to press.
    #[error(transparent)]
    Run(#[from] RunError),
    /// Another process runs the machine.
    #[error(transparent)]
    Lock(#[from] LockError),
    /// Nothing to resume.
    #[error("machine \"{0}\" has no stopped run to resume")]
    NothingToResume(String),
    /// The machine's profile says no connection the console can stream over.
    #[error("cannot stream to machine \"{machine}\": {error}")]
    Link {
        /// The machine.
        machine: String,
        /// Why.
        error: String,
    },
    /// The run's record could not be opened: the run is not started.
    #[error("the run is not started, since it could not be recorded (nothing was sent): {0}")]
    Record(String),
    /// The run's thread could not be started.
    #[error("cannot start the run: {0}")]
    Thread(std::io::Error),
}

/// What a run was started from, kept for its resume.
struct RunInputs {
    job_name: String,
    job: Job,
    /// The ring the program was planned with, which its cut is measured with.
    ring: Ring,
    /// The job file as read, for the records.
    job_file: Option<FileSnapshot>,
    /// The plan report (JSON), for the records.
    plan_report: Option<String>,
    /// What the program was planned from, for the records: the console streams only what
    /// it plans, so it is right by construction.
    provenance: Option<RunProvenance>,
    /// The feed overrides the run may take ([`FeedCap`]); `None` on a transport whose
    /// controller takes its override from its own panel.
    feed_cap: Option<FeedCap>,
    posted: Posted,
    transport: TransportKind,
    time_scale: f64,
    /// The machine's own connection, for a stream; `None`: a dry run on the simulator.
    link: Option<Link>,
    /// What the program was planned from, for the page.
    shown: ProvenanceView,
}

/// A machine's lock, for the page: which machine or port it is, and who holds it since
/// when (this console's run, or a `whirl stream` of another terminal), if anyone.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct LockView {
    /// The machine's name.
    pub machine: String,
    /// What the lock is on (the port its profile reaches, else the machine).
    pub what: String,
    /// Who holds it and since when; `None`: free.
    pub held: Option<lock::Holder>,
}

/// The transports a console dry run takes, by their names.
fn transport(name: &str) -> Result<TransportKind, StartError> {
    [
        TransportKind::Serial,
        TransportKind::ModbusTcp,
        TransportKind::ModbusRtu,
        TransportKind::CanSlcan,
    ]
    .into_iter()
    .find(|t| t.name() == name)
    .ok_or_else(|| {
        StartError::Preflight(format!(
            "transport \"{name}\": the simulator serves serial, modbus-tcp, modbus-rtu and \
             can-slcan"
        ))
    })
}

impl Console {
    /// A console of `machines` and the jobs in `jobs`, locking machines in
    /// [`lock::lock_dir`].
    pub fn new(machines: BTreeMap<String, MachineProfile>, jobs: JobDir) -> Console {
        Console {
            machines,
            jobs,
            registry: Registry::default(),
            records: None,
            machine_files: BTreeMap::new(),
            telemetry: BTreeMap::new(),
            lock_dir: lock::lock_dir(),
            holder: lock::this_process(),
        }
    }

    /// Every machine's lock and its holder, if held (see [`lock::holder`]).
    pub fn locks(&self) -> Vec<LockView> {
        self.machines
            .iter()
            .map(|(name, profile)| {
                let what = super::machine_key(profile);
                LockView {
                    machine: name.clone(),
                    held: lock::holder(&self.lock_dir, &what),
                    what,
                }
            })
            .collect()
    }

    fn machine(&self, name: &str) -> Result<&MachineProfile, StartError> {
        self.machines
            .get(name)
            .ok_or_else(|| StartError::UnknownMachine(name.to_owned()))
    }

    /// The job `name` and its program planned for `machine`.
    fn planned(
        &self,
        name: &str,
        machine: &MachineProfile,
    ) -> Result<(Job, crate::plan::Plan), StartError> {
        let path = self.jobs.resolve(name)?;
        let job = Job::load(&path).map_err(|e| StartError::Job(e.to_string()))?;
        self.planned_job(name, job, machine)
    }

    fn planned_job(
        &self,
        name: &str,
        job: Job,
        machine: &MachineProfile,
    ) -> Result<(Job, crate::plan::Plan), StartError> {
        let plan = crate::judge::refine::plan(&job, machine).map_err(|e| StartError::Plan {
            job: name.to_owned(),
            error: e.to_string(),
        })?;
        Ok((job, plan))
    }

    /// What whirl understood of job `name`'s groove, as `whirl profile` prints it: its facts
    /// (a standard form's dimensions first) and the axial section drawn (SVG).
    pub fn profile(&self, name: &str) -> Result<serde_json::Value, StartError> {
        let path = self.jobs.resolve(name)?;
        let job = Job::load(&path).map_err(|e| StartError::Job(e.to_string()))?;
        let view = crate::judge::profile_view::view(&job)
            .map_err(|e| StartError::Job(format!("{name}: {e}")))?;
        Ok(serde_json::json!({
            "job": name,
            "facts": view.facts,
            "svg": view.svg(&format!("{name}: axial section at polar angle 0, one pitch")),
        }))
    }

    /// The plan report of job `name` on machine `machine`, as `whirl plan --report` writes it.
    pub fn plan(&self, name: &str, machine: &str) -> Result<serde_json::Value, StartError> {
        let (_, plan) = self.planned(name, self.machine(machine)?)?;
        Ok(serde_json::to_value(&plan.report).expect("a plan report serialises"))
    }

    /// The planned program of job `name` on `machine` measured against its groove, as
    /// `whirl plan --verify` reports it.
    pub fn verify(&self, name: &str, machine: &str) -> Result<serde_json::Value, StartError> {
        let profile = self.machine(machine)?;
        let (job, plan) = self.planned(name, profile)?;
        let verified = crate::judge::verify::verify(&job, plan.ring, profile, &plan.text, false)
            .map_err(|e| StartError::Plan {
                job: name.to_owned(),
                error: e.to_string(),
            })?;
        Ok(serde_json::to_value(crate::judge::verify::VerifiedReport {
            report: &plan.report,
            verify: &verified,
        })
        .expect("a verified report serialises"))
    }

    /// Starts the dry run (or the stream to the machine) `request` asks for; gives its id.
    pub fn start(self: &Arc<Console>, request: &RunRequest) -> Result<u64, StartError> {
        let machine = self.machine(&request.machine)?;
        let link = if request.stream {
            let link = Link::resolve(machine, None, None, None).map_err(|e| StartError::Link {
                machine: request.machine.clone(),
                error: e.to_string(),
            })?;
            if matches!(link, Link::Linuxcnc(_)) {
                return Err(StartError::Link {
                    machine: request.machine.clone(),
                    error: "the console streams over serial, Modbus and CAN; LinuxCNC is run \
                            with whirl stream"
                        .into(),
                });
            }
            Some(link)
        } else {
            None
        };
        let kind = match &link {
            Some(link) => link.kind(),
            None => transport(&request.transport)?,
        };
        let (low, high) = TIME_SCALES;
        if link.is_none() && !(low..=high).contains(&request.time_scale) {
            return Err(StartError::TimeScale(request.time_scale));
        }
        if let Some(busy) = self.registry.busy(&request.machine) {
            return Err(busy.into());
        }
        let path = self.jobs.resolve(&request.job)?;
        let bytes = std::fs::read(&path)
            .map_err(|e| StartError::Job(format!("cannot read the job {}: {e}", request.job)))?;
        // Planned from the bytes the record keeps, not from a second read of a file that
        // may change in between.
        let text = std::str::from_utf8(&bytes).map_err(|e| {
            StartError::Job(format!("the job {} is not UTF-8 text: {e}", request.job))
        })?;
        let job = Job::from_toml(text, &path).map_err(|e| StartError::Job(e.to_string()))?;
        let (job, plan) = self.planned_job(&request.job, job, machine)?;
        let posted = Posted::read(request.job.as_str(), &plan.text, machine)
            .map_err(|e| StartError::Preflight(format!("{}: {e}", request.job)))?;
        match &link {
            Some(_) => posted
                .check(machine)
                .map_err(|e| StartError::Preflight(e.to_string()))?,
            None => {
                dry_run::preflight(machine, &posted, kind)
                    .map_err(|e| StartError::Preflight(e.to_string()))?;
            }
        }
        let provenance = self
            .machine_files
            .get(&request.machine)
            .map(|file| planned_from(&path, &bytes, machine, file, &plan));
        let shown = shown_provenance(&request.job, &bytes, machine, self, &posted, &plan);
        // The overrides the transport's controller takes, up to the cusp's cap.
        let feed_cap = override_range(kind).map(|range| FeedCap::of(&plan.report, range));
        let inputs = Arc::new(RunInputs {
            job_name: request.job.clone(),
            job,
            ring: plan.ring,
            job_file: Some(FileSnapshot::of(path.display().to_string(), &bytes)),
            plan_report: serde_json::to_string(&plan.report).ok(),
            provenance,
            feed_cap,
            posted,
            transport: kind,
            time_scale: if link.is_some() {
                1.0
            } else {
                request.time_scale
            },
            link,
            shown,
        });
        self.launch(&request.machine, inputs, None, Vec::new(), &request.client)
    }

    /// The groove `machine`'s runs have cut so far, against the target of the job they ran,
    /// measured with the ring it was planned with ([`groove::section`]); `None` before the
    /// ring has turned through the work.
    pub fn cut_section(&self, machine: &str) -> Result<Option<Plot>, StartError> {
        let nothing = || StartError::NothingToResume(machine.to_owned());
        let (_, cut, inputs) = self.registry.last(machine).ok_or_else(nothing)?;
        let inputs = inputs
            .and_then(|i| i.downcast::<RunInputs>().ok())
            .ok_or_else(nothing)?;
        groove::section(&inputs.job, inputs.ring, &cut).map_err(|e| StartError::Plan {
            job: inputs.job_name.clone(),
            error: e.to_string(),
        })
    }

    /// Resumes `machine`'s stopped run where it stopped, as `client` asks; gives the new
    /// run's id.
    pub fn resume(self: &Arc<Console>, machine: &str, client: &str) -> Result<u64, StartError> {
        self.machine(machine)?;
        let nothing = || StartError::NothingToResume(machine.to_owned());
        let (view, cut, inputs) = self.registry.last(machine).ok_or_else(nothing)?;
        if let Some(busy) = self.registry.busy(machine) {
            return Err(busy.into());
        }
        let point = view.resume.ok_or_else(nothing)?;
        let inputs = inputs
            .and_then(|i| i.downcast::<RunInputs>().ok())
            .ok_or_else(nothing)?;
        self.launch(machine, inputs, Some(point.line), cut, client)
    }

    /// Locks the machine, registers the run and starts its thread.
    fn launch(
        self: &Arc<Console>,
        machine: &str,
        inputs: Arc<RunInputs>,
        resume_at: Option<usize>,
        cut: Vec<Record>,
        client: &str,
    ) -> Result<u64, StartError> {
        let profile = self.machine(machine)?;
        let holder = format!(
            "{}, console run of {} started by {client}",
            self.holder, inputs.job_name
        );
        let lock = MachineLock::acquire(&self.lock_dir, &super::machine_key(profile), &holder)?;
        let (control, commands) = transport::control();
        if let Some(cap) = &inputs.feed_cap {
            control.set_feed_cap(cap.clone());
        }
        let transport = match &inputs.link {
            Some(link) => format!("{} to the machine ({link})", inputs.transport.name()),
            None => inputs.transport.name().to_owned(),
        };
        let mut view = RunView::new(machine, &inputs.job_name, &transport, inputs.time_scale);
        view.resumed_at = resume_at;
        view.started_by = client.to_owned();
        view.provenance = Some(inputs.shown.clone());
        view.total = inputs.posted.lines.len();
        view.ring_rpm = inputs.posted.program.moves.iter().find_map(|m| match m {
            crate::program::Move::SpindleOn { rpm } => Some(*rpm),
            _ => None,
        });
        let start = cut.iter().rev().find_map(|r| match &r.event {
            Event::Executed { to, .. } => Some(*to),
            _ => None,
        });
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(StartError::Thread)?;
        // The record, opened before anything is sent; the database's connections live on
        // the run's own runtime.
        let recorded = match &self.records {
            Some(records) => {
                let run = record::new_run(record::Start {
                    job: inputs.job_file.clone(),
                    machine: self.machine_files.get(machine).cloned(),
                    machine_name: machine,
                    posted: &inputs.posted,
                    plan_report: inputs.plan_report.clone(),
                    provenance: inputs.provenance.clone(),
                    transport: inputs.transport.name(),
                    port: inputs.link.as_ref().map(Link::to_string),
                    resume_from: resume_at,
                });
                let (store, id) = runtime
                    .block_on(record::begin(&records.place, &run))
                    .map_err(|e| StartError::Record(e.to_string()))?;
                Some((store, id))
            }
            None => None,
        };
        if let Some((_, recorded)) = &recorded {
            // A record kept in the spool is numbered by the shop's database when uploaded:
            // the page shows no number that is not its number there.
            match &recorded.kept {
                Kept::Database => view.record = Some(recorded.id),
                Kept::Spool { file, why } => {
                    view.spooled = true;
                    view.message(format!(
                        "its record is kept in the spool {} ({why}), and uploaded to the run \
                         records when they answer",
                        file.display()
                    ));
                }
            }
            view.recorded = Some(recorded.clone());
        }
        let erased: Inputs = inputs.clone();
        let id = match self.registry.begin(view, control, cut, erased) {
            Ok(id) => id,
            Err(busy) => {
                if let Some((store, record)) = &recorded {
                    let mut ending = Ending::new(Outcome::Failed);
                    ending.reason = Some(format!("not started: {busy}"));
                    if let Err(e) = runtime.block_on(store.finish(record, &ending)) {
                        tracing::error!(record = record.id, error = %e, "the run's record could not be closed");
                    }
                }
                return Err(busy.into());
            }
        };
        // The run's record closes however its thread ends: a panic in it, or no thread at
        // all, fails the record here rather than leave it running while this console lives
        // (no other whirl closes it: this process is alive).
        let runtime = Arc::new(runtime);
        let record = recorded.clone();
        let broke_off = {
            let console = Arc::clone(self);
            let runtime = Arc::clone(&runtime);
            move |machine: &str, id: u64, why: String| {
                if let Some((store, record)) = &record {
                    if let Err(e) = runtime.block_on(store.finish(record, &failed(&why))) {
                        tracing::error!(record = record.id, error = %e, "the run's record could not be closed");
                    }
                }
                console
                    .registry
                    .end(machine, id, |v| v.outcome = Some(format!("failed: {why}")));
            }
        };
        let console = Arc::clone(self);
        let name = machine.to_owned();
        let thread_runtime = Arc::clone(&runtime);
        let ends = broke_off.clone();
        std::thread::Builder::new()
            .name(format!("console run {id}"))
            .spawn(move || {
                let _lock = lock;
                let run = Run {
                    machine: &name,
                    id,
                    inputs: &inputs,
                    resume_at,
                    start,
                };
                let ran = std::panic::catch_unwind(AssertUnwindSafe(|| {
                    console.run(run, &thread_runtime, recorded, commands)
                }));
                if ran.is_err() {
                    ends(
                        &name,
                        id,
                        "the console's run broke off (see its error output)".into(),
                    );
                }
            })
            .map_err(|error| {
                broke_off(machine, id, format!("not started: {error}"));
                StartError::Thread(error)
            })?;
        Ok(id)
    }

    /// The run itself, on its thread: the dry run, the stream or a resume of either, then
    /// its record closed and its end shown.
    fn run(
        self: &Arc<Console>,
        run: Run<'_>,
        runtime: &tokio::runtime::Runtime,
        recorded: Option<(Store, Recorded)>,
        commands: Commands,
    ) {
        let Run {
            machine,
            id,
            inputs,
            resume_at,
            start,
        } = run;
        let profile = &self.machines[machine];
        let telemetry = self.telemetry.get(machine);
        let log = match telemetry {
            Some(telemetry) => {
                telemetry.prepare(RunContext {
                    kind: "serve".into(),
                    record: recorded.as_ref().map(|(_, recorded)| recorded.id),
                    job: Some(inputs.job_name.clone()),
                    program_sha256: Some(
                        ProgramId::of(inputs.posted.name.clone(), &inputs.posted.lines.join("\n"))
                            .sha256,
                    ),
                    provenance: inputs
                        .provenance
                        .as_ref()
                        .and_then(|p| serde_json::to_value(&p.header).ok()),
                });
                ExecLog::memory().tapped(telemetry.tap())
            }
            None => ExecLog::memory(),
        };
        let reader = Arc::new(Mutex::new(LogReader {
            console: Arc::clone(self),
            machine: machine.to_owned(),
            id,
            log: log.clone(),
            read: 0,
            last: Instant::now(),
            read_at: Timestamp::now(),
            feed_times: Vec::new(),
        }));
        let progress = progress(Arc::clone(&reader), inputs);
        let progress = match telemetry {
            Some(telemetry) => telemetry.progress(Some(progress)),
            None => progress,
        };
        let mut run_log = log.clone();
        let (mut ending, link_use) = match (&inputs.link, resume_at) {
            (None, None) => match runtime.block_on(dry_run::dry_run(
                &inputs.job,
                inputs.ring,
                profile,
                &inputs.posted,
                DryRunOptions {
                    transport: inputs.transport,
                    time_scale: Some(inputs.time_scale),
                    baud: BAUD,
                    progress: Some(progress),
                    commands: Some(commands),
                    ..DryRunOptions::default()
                },
                &mut run_log,
            )) {
                Ok(report) => (Ending::of_dry_run(&report), Some(report.link_utilization)),
                Err(error) => (failed(error), None),
            },
            (None, Some(line)) => {
                let resumed = runtime.block_on(resume::resume(
                    profile,
                    &inputs.posted,
                    inputs.transport,
                    ResumeOptions {
                        line: line - 1,
                        start: start.unwrap_or_else(|| {
                            dry_run::power_up(&inputs.posted.program, inputs.transport)
                        }),
                        time_scale: inputs.time_scale,
                        baud: BAUD,
                        progress: Some(progress),
                    },
                    commands,
                    &mut run_log,
                ));
                let ending = match resumed {
                    Ok(outcome) => Ending::of_stream(&Ok(outcome)),
                    Err(ResumeError::Stream(error)) => Ending::of_stream(&Err(error)),
                    Err(error) => failed(error),
                };
                (ending, None)
            }
            (Some(link), resume_at) => {
                let options = RunOptions {
                    stall_timeout: Some(STALL_TIMEOUT),
                    resume_at: resume_at.map(|line| line - 1),
                    unlock: false,
                    progress: Some(progress),
                };
                let streamed = runtime.block_on(transport::stream(
                    link,
                    &inputs.posted,
                    profile,
                    options,
                    commands,
                    &mut run_log,
                ));
                (Ending::of_stream(&streamed), None)
            }
        };
        let feed_times = {
            let mut reader = reader.lock().unwrap_or_else(|p| p.into_inner());
            reader.read_log();
            std::mem::take(&mut reader.feed_times)
        };
        let (view, cut) = self
            .registry
            .last(machine)
            .map(|(view, cut, _)| (Some(view), cut))
            .unwrap_or_default();
        // A dry run's cut is measured; a machine's is not known to the bridge.
        let measured = inputs
            .link
            .is_none()
            .then(|| groove::measure(&inputs.job, inputs.ring, &cut));
        let resume = view.as_ref().and_then(|v| v.resume.clone());
        record::complete(
            &mut ending,
            &log.records(),
            resume.as_ref(),
            measured.as_ref().and_then(|m| m.as_ref().ok().copied()),
            |t| feed_times.iter().find(|c| c.0 == t).map(|c| c.1),
        );
        // Closed before the page hears the run ended, so that its history shows it so.
        let unclosed = recorded.and_then(|(store, record)| {
            let closed = runtime.block_on(store.finish(&record, &ending));
            runtime.block_on(store.close_connections());
            match closed {
                Ok(Finished { kept: Kept::Spool { file, why }, .. }) if record.kept == Kept::Database => {
                    Some(format!(
                        "the run's record {} could not be closed in the run records ({why}): its end is kept in the spool {}, and uploaded when they answer",
                        record.id,
                        file.display()
                    ))
                }
                Ok(_) => None,
                Err(e) => Some(format!(
                    "the run's record {} could not be closed ({e}); the next whirl serve closes it as interrupted",
                    record.id
                )),
            }
        });
        let completed = ending.outcome == Outcome::Completed;
        self.registry.end(machine, id, |v| {
            v.completed = completed;
            v.link_use = link_use.or(v.link_use);
            v.outcome = Some(match (&ending.outcome, &ending.reason) {
                (Outcome::Completed, _) => "completed".to_owned(),
                (outcome, Some(reason)) => format!("{outcome}: {reason}"),
                (outcome, None) => outcome.to_string(),
            });
            if completed {
                v.resume = None;
            }
            match measured {
                Some(Ok(m)) => v.measured = Some(m),
                Some(Err(error)) => v.message(format!("the cut cannot be measured: {error}")),
                None => {}
            }
            if let Some(text) = unclosed {
                v.message(text);
            }
        });
    }

    /// Notes a hold or a resume pressed on `machine`'s run in its record; the error, if the
    /// records could not take it (the run goes on: a machine never stops for an index).
    pub async fn note_pressed(
        &self,
        machine: &str,
        kind: NoteKind,
        client: &str,
    ) -> Result<(), String> {
        let Some(records) = &self.records else {
            return Ok(());
        };
        let Some(view) = self
            .registry
            .views()
            .into_iter()
            .find(|v| v.machine == machine)
        else {
            return Ok(());
        };
        let Some(recorded) = &view.recorded else {
            return Ok(());
        };
        records
            .store
            .note(recorded, &record::pressed(kind, view.line, client))
            .await
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

/// How long a stream waits for the controller to say something new before it holds and
/// stops, as `whirl dry-run`'s default.
const STALL_TIMEOUT: Duration = Duration::from_secs(30);

/// A run's ending when it could not be carried out.
/// The provenance of `plan`, planned from the job file at `path` whose bytes are `job` for
/// `machine`, its profile file as `file`; the points file the job names read now.
fn planned_from(
    path: &std::path::Path,
    job: &[u8],
    machine: &MachineProfile,
    file: &FileSnapshot,
    plan: &crate::plan::Plan,
) -> RunProvenance {
    let points = std::str::from_utf8(job)
        .ok()
        .and_then(provenance::points_named)
        .and_then(|named| {
            let at = path
                .parent()
                .unwrap_or(std::path::Path::new(""))
                .join(&named);
            std::fs::read(&at)
                .ok()
                .map(|bytes| Source::of(at.display().to_string(), &bytes))
        });
    RunProvenance::planned(Provenance {
        version: env!("CARGO_PKG_VERSION").into(),
        job: Source::of(path.display().to_string(), job),
        points,
        machine_name: machine.name.clone(),
        machine: Source {
            path: file.path.clone(),
            sha256: file.sha256.clone(),
        },
        delta_mm: plan.report.delta_mm,
        installation_angle_deg: plan.report.installation_angle_deg,
        axial_feed_mm: plan.report.axial_feed_mm,
        fastest: false,
    })
}

/// What the page shows of what a run's program was planned from: the job `name` whose
/// bytes are `job`, the machine's profile file as `console` read it, the program and the
/// plan's Δ, angle and feed (the same facts as the record's provenance header).
fn shown_provenance(
    name: &str,
    job: &[u8],
    machine: &MachineProfile,
    console: &Console,
    posted: &Posted,
    plan: &crate::plan::Plan,
) -> ProvenanceView {
    ProvenanceView {
        program: posted.name.clone(),
        program_sha256: ProgramId::of(posted.name.clone(), &posted.lines.join("\n")).sha256,
        job: name.to_owned(),
        job_sha256: crate::records::sha256_hex(job),
        machine: machine.name.clone(),
        machine_sha256: console
            .machine_files
            .get(&machine.name)
            .map(|f| f.sha256.clone()),
        delta_mm: plan.report.delta_mm,
        installation_angle_deg: plan.report.installation_angle_deg,
        axial_feed_mm: plan.report.axial_feed_mm,
    }
}

fn failed(error: impl std::fmt::Display) -> Ending {
    let mut ending = Ending::new(Outcome::Failed);
    ending.reason = Some(error.to_string());
    ending
}

/// Which run a run thread carries out.
struct Run<'a> {
    machine: &'a str,
    id: u64,
    inputs: &'a RunInputs,
    /// The line (1-based) it resumes at.
    resume_at: Option<usize>,
    /// Where the stopped run it resumes left the machine.
    start: Option<[f64; 3]>,
}

/// Reads a run's log into its view as it grows: alarms and messages in words, the resume
/// point, and the executed moves into what the machine has cut.
struct LogReader {
    console: Arc<Console>,
    machine: String,
    id: u64,
    log: ExecLog,
    /// Records read so far.
    read: usize,
    last: Instant,
    /// When the log was last read, by the wall clock.
    read_at: Timestamp,
    /// When each feed override the controller began to run at happened, by the wall clock:
    /// its log time, the wall time it was read at less how long before the last record
    /// read it was logged, never before the read before (a log whose clock is a CAN
    /// session's, scaled, is thus off by at most the time between two reads), and the
    /// percent. The record notes each at this time, not at the run's end.
    feed_times: Vec<(f64, Timestamp, u16)>,
}

impl LogReader {
    fn read_log(&mut self) {
        self.last = Instant::now();
        let (before, now) = (self.read_at, Timestamp::now());
        self.read_at = now;
        let new = self.log.records_from(self.read);
        self.read += new.len();
        let newest = new.last().map_or(0.0, |r| r.t);
        let mut executed = Vec::new();
        let mut words = Vec::new();
        let mut alarms = Vec::new();
        let mut resume = None;
        let mut running = None;
        for record in &new {
            match &record.event {
                // Not taken, the transport says why in a message beside it.
                Event::FeedOverride {
                    percent,
                    state: FeedOverrideState::Running,
                } => {
                    running = Some(*percent);
                    // Each change once, from the planned 100 % on, as the record's notes
                    // are read from the log (grbl reports its override in every status).
                    if self.feed_times.last().map_or(100, |c| c.2) != *percent {
                        let ago = ((newest - record.t).max(0.0) * 1000.0) as i64;
                        let wall = Timestamp((now.0 - ago).max(before.0));
                        self.feed_times.push((record.t, wall, *percent));
                    }
                }

                Event::Executed { .. } => executed.push(record.clone()),
                Event::Alarm { code, message } => alarms.push(format!("ALARM:{code} {message}")),
                Event::Error {
                    line,
                    code,
                    message,
                } => words.push(format!("line {line} refused, error {code}: {message}")),
                Event::Message { text } => words.push(text.clone()),
                Event::ResumeAt {
                    line,
                    possibly_run_to,
                } => {
                    resume = Some(ResumePoint {
                        line: *line,
                        possibly_run_to: *possibly_run_to,
                    })
                }
                Event::End {
                    reason: Some(reason),
                    ..
                } => words.push(format!("the run ended: {reason}")),
                _ => {}
            }
        }
        let registry = &self.console.registry;
        if !executed.is_empty() {
            registry.cut(&self.machine, self.id, executed);
        }
        if !(words.is_empty() && alarms.is_empty() && resume.is_none() && running.is_none()) {
            registry.update(&self.machine, self.id, |v| {
                v.alarms.extend(alarms);
                for text in words {
                    v.message(text);
                }
                if resume.is_some() {
                    v.resume = resume;
                }
                if let (Some(feed), Some(percent)) = (v.feed.as_mut(), running) {
                    feed.running = Some(percent);
                }
            });
        }
    }
}

/// The progress callback of a run: its figures into the view at once, the log at most
/// every [`LOG_READ_EVERY`]; a serial line's use from the bytes of the acknowledged lines
/// over what the link carries in the simulated time so far.
fn progress(reader: Arc<Mutex<LogReader>>, inputs: &RunInputs) -> ProgressFn {
    let serial = inputs.transport == TransportKind::Serial;
    // The machine's line, or the dry run's emulated one.
    let baud = match &inputs.link {
        Some(Link::Serial { baud, .. }) => *baud,
        _ => BAUD,
    };
    let scale = inputs.time_scale;
    // Bytes of the first n lines, each with its newline.
    let bytes: Vec<usize> = std::iter::once(0)
        .chain(inputs.posted.lines.iter().scan(0, |sum, line| {
            *sum += line.len() + 1;
            Some(*sum)
        }))
        .collect();
    let program = Arc::new(inputs.posted.lines.clone());
    Box::new(move |p: &Progress| {
        let mut reader = reader.lock().unwrap_or_else(|p| p.into_inner());
        let simulated = p.elapsed.as_secs_f64() * scale;
        let link = (serial && simulated > 0.0).then(|| {
            let sent = bytes[p.done.min(bytes.len() - 1)] as f64;
            (sent * 10.0 / (f64::from(baud) * simulated)).min(1.0)
        });
        reader
            .console
            .registry
            .update(&reader.machine, reader.id, |v| {
                v.unit = p.unit.name().to_owned();
                v.done = p.done;
                v.total = p.total;
                let line = p.line.map(|l| l + 1);
                if line != v.line {
                    v.around = line.map_or_else(Vec::new, |l| around(&program, l));
                }
                v.line = line;
                v.elapsed_s = p.elapsed.as_secs_f64();
                v.left_s = p.left.map(|l| l.as_secs_f64());
                v.state.clone_from(&p.state);
                v.position = p.position.or(v.position);
                v.link_use = link;
            });
        if reader.last.elapsed() >= LOG_READ_EVERY {
            reader.read_log();
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn console(dir: &std::path::Path) -> Arc<Console> {
        let jobs = dir.join("jobs");
        std::fs::create_dir_all(jobs.join("t")).unwrap();
        std::fs::copy(
            concat!(env!("CARGO_MANIFEST_DIR"), "/examples/trapezoidal/job.toml"),
            jobs.join("t/job.toml"),
        )
        .unwrap();
        std::fs::write(jobs.join("broken.toml"), "[groove]\nlead = \"x\"\n").unwrap();
        let sim = MachineProfile::builtin_sim().unwrap();
        let mut console = Console::new(
            super::super::machines(vec![sim]).unwrap(),
            JobDir::open(&jobs).unwrap(),
        );
        console.lock_dir = dir.join("locks");
        Arc::new(console)
    }

    fn request(machine: &str, job: &str) -> RunRequest {
        RunRequest {
            machine: machine.into(),
            job: job.into(),
            transport: "serial".into(),
            time_scale: 100.0,
            stream: false,
            client: "127.0.0.1:1".into(),
        }
    }

    #[test]
    fn requests_are_refused_before_anything_runs() {
        let dir = tempfile::tempdir().unwrap();
        let console = console(dir.path());
        let sim = console.machines.keys().next().unwrap().clone();
        let refused = |r: RunRequest| console.start(&r).unwrap_err().to_string();
        let mut stream = request(&sim, "t/job.toml");
        stream.stream = true;
        assert!(refused(stream).contains("cannot stream to machine"));
        assert!(refused(request("lathe", "t/job.toml")).contains("no machine \"lathe\""));
        assert!(refused(request(&sim, "../t/job.toml")).contains("steps out of the jobs folder"));
        assert!(refused(request(&sim, "broken.toml")).contains("broken.toml"));
        let mut fast = request(&sim, "t/job.toml");
        fast.time_scale = 1e6;
        assert!(refused(fast).contains("time scale 1000000 is out of range"));
        let mut can = request(&sim, "t/job.toml");
        can.transport = "can".into();
        assert!(refused(can).contains("the simulator serves serial"));
        assert!(console
            .resume(&sim, "test")
            .unwrap_err()
            .to_string()
            .contains("no stopped run to resume"));
        // Nothing ran.
        assert!(console.registry.views().is_empty());
    }

    #[test]
    fn a_machine_another_process_runs_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let console = console(dir.path());
        let sim = console.machines.keys().next().unwrap().clone();
        let key = super::super::machine_key(&console.machines[&sim]);
        let _held =
            MachineLock::acquire(&dir.path().join("locks"), &key, "process 42 (whirl stream)")
                .unwrap();
        let error = console.start(&request(&sim, "t/job.toml")).unwrap_err();
        assert!(
            error.to_string().contains("process 42 (whirl stream)"),
            "{error}"
        );
        assert!(console.registry.views().is_empty());
    }

    #[test]
    fn the_override_the_controller_reports_running_reaches_the_view_and_asked_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let console = console(dir.path());
        let (control, _commands) = transport::control();
        control.set_feed_cap(FeedCap::new(
            0.01,
            0.0085,
            0.004,
            crate::plan::overrides::GRBL,
        ));
        let view = RunView::new("lathe", "t/job.toml", "serial", 1.0);
        let id = console
            .registry
            .begin(view, control, Vec::new(), Arc::new(()))
            .unwrap();
        let log = ExecLog::memory();
        let mut reader = LogReader {
            console: Arc::clone(&console),
            machine: "lathe".into(),
            id,
            log: log.clone(),
            read: 0,
            last: Instant::now(),
            read_at: Timestamp::now(),
            feed_times: Vec::new(),
        };
        let running = |c: &Console| c.registry.views()[0].feed.as_ref().unwrap().running;
        let mut writer = log.clone();
        let mut say = |percent, state| {
            writer
                .write(0.0, Event::FeedOverride { percent, state })
                .unwrap()
        };
        // Asked is not running: the controller has not said so.
        say(80, FeedOverrideState::Asked);
        reader.read_log();
        assert_eq!(running(&console), None);
        // grbl goes 100 → 80 in two bytes (−10 each), reporting each value it runs at; the
        // last report counts.
        say(90, FeedOverrideState::Running);
        say(80, FeedOverrideState::Running);
        reader.read_log();
        assert_eq!(running(&console), Some(80));
        // Not taken: what runs stays what the controller last reported.
        say(70, FeedOverrideState::NotTaken);
        say(80, FeedOverrideState::Running);
        reader.read_log();
        assert_eq!(running(&console), Some(80));
        // Each change the controller ran at is timed once, when it was read, for the
        // record's notes; the same value reported again is no change.
        let percents: Vec<u16> = reader.feed_times.iter().map(|c| c.2).collect();
        assert_eq!(percents, [90, 80]);
        assert!(reader.feed_times.iter().all(|c| c.1 <= Timestamp::now()));
    }

    #[test]
    fn plan_and_verify_report_as_the_command_line_does() {
        let dir = tempfile::tempdir().unwrap();
        let console = console(dir.path());
        let sim = console.machines.keys().next().unwrap().clone();
        let plan = console.plan("t/job.toml", &sim).unwrap();
        assert_eq!(plan["delta_mm"], 0.01);
        assert!(plan["segments"].as_u64().unwrap() > 0);
        assert!(console.plan("../job.toml", &sim).is_err());
    }
}
