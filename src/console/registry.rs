//! The console's runs: one slot per machine, what the page shows of each, and the buttons.
//!
//! A run lives here, not in a browser: the page subscribes to changes ([`Registry::subscribe`])
//! and reads the views ([`Registry::views`]), so a closed page neither stops nor orphans a
//! run, and a page opened later shows it. A machine holds one run at a time: a second is
//! refused while the first has not ended.

use crate::log::Record;
use crate::plan::overrides::FeedCap;
use crate::transport::control::FeedOverrideError;
use crate::transport::{Command, Control};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};
use tokio::sync::watch;

/// What a run is doing, for the page.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Streaming.
    Running,
    /// Over: completed, stopped or failed (see [`RunView::outcome`]).
    Ended,
}

/// Where a stopped run goes on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ResumePoint {
    /// The program line (1-based) to resume at.
    pub line: usize,
    /// Lines from `line` up to this one may already have run; re-entering along the
    /// groove cuts them again harmlessly.
    pub possibly_run_to: Option<usize>,
}

/// One run as the page shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunView {
    /// Counts up with every run the console starts.
    pub id: u64,
    /// The machine (its profile's name).
    pub machine: String,
    /// The job, relative to the jobs folder.
    pub job: String,
    /// How it goes to the simulator (`serial`, `modbus-tcp`, …).
    pub transport: String,
    /// Simulated seconds per wall second.
    pub time_scale: f64,
    /// The line this run resumed at (1-based), if it is a resume.
    pub resumed_at: Option<usize>,
    /// Running or ended.
    pub phase: Phase,
    /// The controller's state in its words (`Run`, `Hold:0`, `Idle`).
    pub state: Option<String>,
    /// What `done` and `total` count (`lines`, `segments`, `set-points`).
    pub unit: String,
    /// Done so far.
    pub done: usize,
    /// In the program.
    pub total: usize,
    /// The program line executing (1-based).
    pub line: Option<usize>,
    /// Seconds since the run started (wall).
    pub elapsed_s: f64,
    /// Seconds left, where known.
    pub left_s: Option<f64>,
    /// X, Z (mm), C (degrees).
    pub position: Option<[f64; 3]>,
    /// The link's use so far, 0 to 1, where it can be told.
    pub link_use: Option<f64>,
    /// Alarms, in words.
    pub alarms: Vec<String>,
    /// The controller's and the bridge's messages, in words (the latest
    /// [`MESSAGES_KEPT`]).
    pub messages: Vec<String>,
    /// How it ended, in words.
    pub outcome: Option<String>,
    /// Every line ran.
    pub completed: bool,
    /// Where to resume, after a stop.
    pub resume: Option<ResumePoint>,
    /// The cut measured against the groove at the end: the larger of overcut and
    /// undercut, mm, and Δ.
    pub measured: Option<Measured>,
    /// Executed moves logged so far (the groove picture changes when this does).
    pub executed: usize,
    /// The run's number in the run records, if it is recorded there (a record kept in the
    /// spool has its number when uploaded).
    pub record: Option<i64>,
    /// Its record is kept in the spool: the shop's database could not be reached.
    pub spooled: bool,
    /// Its record, for the notes the console's buttons add to it.
    #[serde(skip)]
    pub recorded: Option<crate::records::Recorded>,
    /// The feed override: what may be asked, what was, and what the controller runs at;
    /// `None` for a run that takes none.
    pub feed: Option<FeedView>,
    /// The program's lines around the one executing (1-based number and text), so the
    /// operator sees where in the program the machine is and what comes next.
    pub around: Vec<(usize, String)>,
    /// The ring's speed the program asks (its `S` word), rpm.
    pub ring_rpm: Option<f64>,
    /// When the run started, UTC (RFC 3339).
    pub started_at: String,
    /// Who started it: the client's address and, if it logged in, its session's first
    /// digits (as the records note who pressed what).
    pub started_by: String,
    /// What its program was planned from.
    pub provenance: Option<ProvenanceView>,
}

/// What a run's program was planned from, as the page shows it beside the run: the
/// program, the job and machine profile files by their hashes, and the plan's Δ, angle
/// and feed, so that an operator sees which planning is cutting.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProvenanceView {
    /// The program's name.
    pub program: String,
    /// SHA-256 of its lines, each ended by a newline (as the records hash it).
    pub program_sha256: String,
    /// The job file, relative to the jobs folder.
    pub job: String,
    /// SHA-256 of the job file's bytes as read.
    pub job_sha256: String,
    /// The machine profile's name.
    pub machine: String,
    /// SHA-256 of the machine profile file, where it is a file the console read.
    pub machine_sha256: Option<String>,
    /// The allowable error Δ planned for, mm.
    pub delta_mm: f64,
    /// The installation angle planned at, degrees.
    pub installation_angle_deg: f64,
    /// The axial feed planned at, mm per workpiece revolution.
    pub axial_feed_mm: f64,
}

/// How many program lines the page shows before and after the one executing.
pub const AROUND: usize = 2;

/// The lines of `program` (its text, line by line) from [`AROUND`] before `line` (1-based)
/// to [`AROUND`] after it, numbered.
pub fn around(program: &[String], line: usize) -> Vec<(usize, String)> {
    let first = line.saturating_sub(AROUND).max(1);
    let last = (line + AROUND).min(program.len());
    (first..=last)
        .map(|n| (n, program[n - 1].clone()))
        .collect()
}

/// A run's feed override, for the page.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedView {
    /// The overrides offered and why the fastest is where it is (the insert cusp within
    /// its share of Δ, or the controller's range).
    pub cap: FeedCap,
    /// The override last asked, percent (100 until one is).
    pub asked: u16,
    /// The override the controller reports running at, percent (grbl's `Ov:`, the Modbus
    /// register read back, the CANopen bridge's set-point clock); `None` until it reports
    /// one.
    pub running: Option<u16>,
}

/// A feed override the page asks for: a value, or a step from the value last asked (the
/// keys of `whirl stream`: held at the cap or the controller's slowest, saying why).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedAsk {
    /// This percent of the programmed feed.
    Percent(u16),
    /// This many percent more (less, if negative) than the value last asked.
    Step(i32),
}

/// The measured error of what a run (and the runs it resumed) cut.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Measured {
    /// Largest overcut, mm.
    pub max_overcut_mm: f64,
    /// Largest undercut, mm.
    pub max_undercut_mm: f64,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Both within Δ.
    pub within_delta: bool,
}

/// How many messages a view keeps.
pub const MESSAGES_KEPT: usize = 50;

impl RunView {
    /// A run about to start.
    pub fn new(machine: &str, job: &str, transport: &str, time_scale: f64) -> RunView {
        RunView {
            id: 0,
            machine: machine.to_owned(),
            job: job.to_owned(),
            transport: transport.to_owned(),
            time_scale,
            resumed_at: None,
            phase: Phase::Running,
            state: None,
            unit: "lines".to_owned(),
            done: 0,
            total: 0,
            line: None,
            elapsed_s: 0.0,
            left_s: None,
            position: None,
            link_use: None,
            alarms: Vec::new(),
            messages: Vec::new(),
            outcome: None,
            completed: false,
            resume: None,
            measured: None,
            executed: 0,
            record: None,
            spooled: false,
            recorded: None,
            feed: None,
            around: Vec::new(),
            ring_rpm: None,
            started_at: crate::records::Timestamp::now().to_text(),
            started_by: String::new(),
            provenance: None,
        }
    }

    /// Adds a message, dropping the oldest beyond [`MESSAGES_KEPT`].
    pub fn message(&mut self, text: String) {
        self.messages.push(text);
        let over = self.messages.len().saturating_sub(MESSAGES_KEPT);
        self.messages.drain(..over);
    }
}

/// What a run keeps for its resume (the runner's own type, opaque here).
pub type Inputs = Arc<dyn std::any::Any + Send + Sync>;

struct Slot {
    view: RunView,
    /// The buttons, while the run runs.
    control: Option<Control>,
    /// The executed moves of this run and the runs it resumed (the groove so far).
    cut: Arc<Mutex<Vec<Record>>>,
    /// The run's inputs, for a resume.
    inputs: Option<Inputs>,
}

/// Why a run was not started or a button not pressed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RunError {
    /// The machine runs already.
    #[error("machine \"{machine}\" is busy: run {id} ({job}) is still running")]
    Busy {
        /// The machine.
        machine: String,
        /// The running run.
        id: u64,
        /// Its job.
        job: String,
    },
    /// No run to press the button of.
    #[error("machine \"{0}\" has no run going")]
    NotRunning(String),
}

/// Why a feed override was not asked of a run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeedError {
    /// No run going on the machine.
    #[error(transparent)]
    Run(#[from] RunError),
    /// The run refused it: above its cap (naming the cap and why), below the controller's
    /// range, or the run has just ended.
    #[error(transparent)]
    Refused(#[from] FeedOverrideError),
}

/// The console's runs, one slot per machine.
pub struct Registry {
    slots: Mutex<BTreeMap<String, Slot>>,
    /// Bumped on every change; the page's event stream waits on it.
    changes: watch::Sender<u64>,
}

impl Default for Registry {
    fn default() -> Registry {
        Registry {
            slots: Mutex::new(BTreeMap::new()),
            changes: watch::Sender::new(0),
        }
    }
}

impl Registry {
    fn slots(&self) -> MutexGuard<'_, BTreeMap<String, Slot>> {
        self.slots.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn changed(&self) {
        self.changes.send_modify(|n| *n += 1);
    }

    /// Starts a run on `view.machine`, with its buttons, `cut` holding what earlier runs
    /// it resumes cut, `inputs` kept for a resume; refused while the machine's last run
    /// has not ended. Gives the run's id.
    pub fn begin(
        &self,
        mut view: RunView,
        control: Control,
        cut: Vec<Record>,
        inputs: Inputs,
    ) -> Result<u64, RunError> {
        let mut slots = self.slots();
        let last = slots.values().map(|s| s.view.id).max().unwrap_or(0);
        if let Some(slot) = slots.get(&view.machine) {
            if slot.view.phase == Phase::Running {
                return Err(RunError::Busy {
                    machine: view.machine.clone(),
                    id: slot.view.id,
                    job: slot.view.job.clone(),
                });
            }
        }
        view.id = last + 1;
        view.executed = cut.len();
        view.feed = control.feed_cap().map(|cap| FeedView {
            cap,
            asked: control.feed_override_asked(),
            running: None,
        });
        let id = view.id;
        slots.insert(
            view.machine.clone(),
            Slot {
                view,
                control: Some(control),
                cut: Arc::new(Mutex::new(cut)),
                inputs: Some(inputs),
            },
        );
        drop(slots);
        self.changed();
        Ok(id)
    }

    /// Whether `machine`'s last run is still running.
    pub fn busy(&self, machine: &str) -> Option<RunError> {
        let slots = self.slots();
        let slot = slots.get(machine)?;
        (slot.view.phase == Phase::Running).then(|| RunError::Busy {
            machine: machine.to_owned(),
            id: slot.view.id,
            job: slot.view.job.clone(),
        })
    }

    /// Changes run `id`'s view (nothing if the machine has moved on to another run).
    pub fn update(&self, machine: &str, id: u64, change: impl FnOnce(&mut RunView)) {
        let mut slots = self.slots();
        if let Some(slot) = slots.get_mut(machine).filter(|s| s.view.id == id) {
            change(&mut slot.view);
            drop(slots);
            self.changed();
        }
    }

    /// Adds executed moves to what run `id` has cut.
    pub fn cut(&self, machine: &str, id: u64, moves: impl IntoIterator<Item = Record>) {
        let cut = {
            let slots = self.slots();
            match slots.get(machine).filter(|s| s.view.id == id) {
                Some(slot) => Arc::clone(&slot.cut),
                None => return,
            }
        };
        let count = {
            let mut cut = cut.lock().unwrap_or_else(|p| p.into_inner());
            cut.extend(moves);
            cut.len()
        };
        self.update(machine, id, |v| v.executed = count);
    }

    /// Ends run `id`: its buttons go, its view says how it ended.
    pub fn end(&self, machine: &str, id: u64, change: impl FnOnce(&mut RunView)) {
        let mut slots = self.slots();
        if let Some(slot) = slots.get_mut(machine).filter(|s| s.view.id == id) {
            slot.control = None;
            slot.view.phase = Phase::Ended;
            change(&mut slot.view);
            drop(slots);
            self.changed();
        }
    }

    /// Presses a button of `machine`'s run.
    pub fn press(&self, machine: &str, command: Command) -> Result<(), RunError> {
        let slots = self.slots();
        let control = slots
            .get(machine)
            .and_then(|s| s.control.as_ref())
            .ok_or_else(|| RunError::NotRunning(machine.to_owned()))?;
        if control.send(command) {
            Ok(())
        } else {
            Err(RunError::NotRunning(machine.to_owned()))
        }
    }

    /// Asks `machine`'s run for a feed override; gives the percent asked and, for a step
    /// held at the cap or the controller's slowest, why.
    pub fn feed_override(
        &self,
        machine: &str,
        ask: FeedAsk,
    ) -> Result<(u16, Option<String>), FeedError> {
        let mut slots = self.slots();
        let not_running = || RunError::NotRunning(machine.to_owned());
        let slot = slots.get_mut(machine).ok_or_else(not_running)?;
        let control = slot.control.as_ref().ok_or_else(not_running)?;
        let asked = match ask {
            FeedAsk::Percent(percent) => control.feed_override(percent).map(|p| (p, None)),
            FeedAsk::Step(by) => control.step_feed_override(by),
        }?;
        if let Some(feed) = slot.view.feed.as_mut() {
            feed.asked = asked.0;
        }
        drop(slots);
        self.changed();
        Ok(asked)
    }

    /// Every machine's last run, in the machines' order.
    pub fn views(&self) -> Vec<RunView> {
        self.slots().values().map(|s| s.view.clone()).collect()
    }

    /// `machine`'s last run, what it (and the runs it resumed) cut, and its inputs.
    pub fn last(&self, machine: &str) -> Option<(RunView, Vec<Record>, Option<Inputs>)> {
        let slots = self.slots();
        let slot = slots.get(machine)?;
        let cut = slot.cut.lock().unwrap_or_else(|p| p.into_inner()).clone();
        Some((slot.view.clone(), cut, slot.inputs.clone()))
    }

    /// A receiver that sees every change.
    pub fn subscribe(&self) -> watch::Receiver<u64> {
        self.changes.subscribe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lines_around_the_one_executing_are_two_each_side_within_the_program() {
        let program: Vec<String> = (1..=6).map(|n| format!("N{n}")).collect();
        let numbers = |line| -> Vec<usize> { around(&program, line).iter().map(|l| l.0).collect() };
        assert_eq!(numbers(3), [1, 2, 3, 4, 5]);
        assert_eq!(numbers(1), [1, 2, 3]);
        assert_eq!(numbers(6), [4, 5, 6]);
        assert_eq!(around(&program, 4)[2], (4, "N4".to_owned()));
    }
    use crate::transport::control;

    fn view(machine: &str) -> RunView {
        RunView::new(machine, "screw/job.toml", "serial", 1.0)
    }

    #[test]
    fn a_machine_runs_one_run_at_a_time_and_the_next_after_it_ended() {
        let registry = Registry::default();
        let (c1, _commands1) = control();
        let id = registry
            .begin(view("lathe"), c1, Vec::new(), Arc::new(()))
            .unwrap();
        let (c2, _commands2) = control();
        assert_eq!(
            registry.begin(view("lathe"), c2.clone(), Vec::new(), Arc::new(())),
            Err(RunError::Busy {
                machine: "lathe".into(),
                id,
                job: "screw/job.toml".into()
            })
        );
        assert!(registry.busy("lathe").is_some());
        // Another machine is free.
        let (c3, _commands3) = control();
        let other = registry
            .begin(view("mill"), c3, Vec::new(), Arc::new(()))
            .unwrap();
        assert_ne!(other, id);
        registry.end("lathe", id, |v| v.outcome = Some("completed".into()));
        assert!(registry.busy("lathe").is_none());
        let next = registry
            .begin(view("lathe"), c2, Vec::new(), Arc::new(()))
            .unwrap();
        assert!(next > other);
    }

    #[test]
    fn buttons_reach_the_run_while_it_runs_and_are_refused_after() {
        let registry = Registry::default();
        assert_eq!(
            registry.press("lathe", Command::Hold),
            Err(RunError::NotRunning("lathe".into()))
        );
        let (control, mut commands) = control();
        let id = registry
            .begin(view("lathe"), control, Vec::new(), Arc::new(()))
            .unwrap();
        registry.press("lathe", Command::Hold).unwrap();
        registry.press("lathe", Command::Resume).unwrap();
        assert_eq!(commands.try_next(), Some(Command::Hold));
        assert_eq!(commands.try_next(), Some(Command::Resume));
        registry.end("lathe", id, |_| {});
        assert_eq!(
            registry.press("lathe", Command::Hold),
            Err(RunError::NotRunning("lathe".into()))
        );
        // A run whose side has gone refuses too.
        let (control, commands) = crate::transport::control();
        registry
            .begin(view("lathe"), control, Vec::new(), Arc::new(()))
            .unwrap();
        drop(commands);
        assert!(registry
            .press("lathe", Command::Stop { reason: "x" })
            .is_err());
    }

    #[test]
    fn changes_reach_subscribers_and_stale_runs_change_nothing() {
        let registry = Registry::default();
        let mut changes = registry.subscribe();
        let (control, _commands) = control();
        let id = registry
            .begin(view("lathe"), control, Vec::new(), Arc::new(()))
            .unwrap();
        assert!(changes.has_changed().unwrap());
        changes.borrow_and_update();
        registry.update("lathe", id, |v| v.done = 7);
        assert!(changes.has_changed().unwrap());
        changes.borrow_and_update();
        registry.update("lathe", id + 1, |v| v.done = 9);
        assert!(!changes.has_changed().unwrap());
        assert_eq!(registry.views()[0].done, 7);
        let record = Record {
            t: 0.0,
            event: crate::log::Event::Message { text: "x".into() },
        };
        registry.cut("lathe", id, [record.clone(), record]);
        let (last, cut, inputs) = registry.last("lathe").unwrap();
        assert_eq!((last.executed, cut.len()), (2, 2));
        assert!(inputs.is_some());
    }

    /// Δ = 10 µm, held to 8.5 µm with a 4 µm cusp: the cusp may grow to 5.5 µm, at
    /// √(5.5/4) = 117 % of the feed.
    fn cap() -> FeedCap {
        FeedCap::new(0.01, 0.0085, 0.004, crate::plan::overrides::GRBL)
    }

    #[test]
    fn a_feed_override_reaches_the_run_within_its_cap_and_is_refused_above_it() {
        let registry = Registry::default();
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Percent(90)),
            Err(FeedError::Run(RunError::NotRunning("lathe".into())))
        );
        let (control, mut commands) = control();
        control.set_feed_cap(cap());
        let id = registry
            .begin(view("lathe"), control, Vec::new(), Arc::new(()))
            .unwrap();
        let feed = |r: &Registry| r.views()[0].feed.clone().unwrap();
        assert_eq!(feed(&registry).cap.max_percent, 117);
        assert_eq!(
            (feed(&registry).asked, feed(&registry).running),
            (100, None)
        );
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Percent(90)),
            Ok((90, None))
        );
        assert_eq!(commands.try_feed_override(), Some(90));
        assert_eq!(feed(&registry).asked, 90);
        // Above the cap: refused naming it and why, and nothing asked.
        let above = registry
            .feed_override("lathe", FeedAsk::Percent(118))
            .unwrap_err();
        assert!(
            above.to_string().contains("above the cap of 117 %")
                && above.to_string().contains("insert cusp"),
            "{above}"
        );
        assert!(matches!(
            registry.feed_override("lathe", FeedAsk::Percent(9)),
            Err(FeedError::Refused(_))
        ));
        assert_eq!(feed(&registry).asked, 90);
        assert_eq!(commands.try_feed_override(), None);
        // A step past the cap is held there, saying why.
        let (held, why) = registry.feed_override("lathe", FeedAsk::Step(40)).unwrap();
        assert_eq!(held, 117);
        assert!(why.unwrap().contains("held at 117 %"));
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Step(-10)),
            Ok((107, None))
        );
        // The run's side gone: the run has ended.
        drop(commands);
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Percent(100)),
            Err(FeedError::Refused(FeedOverrideError::Ended))
        );
        // Ended in the registry: no run to ask.
        registry.end("lathe", id, |_| {});
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Percent(100)),
            Err(FeedError::Run(RunError::NotRunning("lathe".into())))
        );
        // A run without a cap takes no override, and its view offers none.
        let (control, _commands) = crate::transport::control();
        registry
            .begin(view("lathe"), control, Vec::new(), Arc::new(()))
            .unwrap();
        assert_eq!(registry.views()[0].feed, None);
        assert_eq!(
            registry.feed_override("lathe", FeedAsk::Percent(100)),
            Err(FeedError::Refused(FeedOverrideError::NoCap))
        );
    }

    #[test]
    fn a_view_keeps_the_latest_messages() {
        let mut v = view("lathe");
        for i in 0..MESSAGES_KEPT + 3 {
            v.message(format!("m{i}"));
        }
        assert_eq!(v.messages.len(), MESSAGES_KEPT);
        assert_eq!(v.messages[0], "m3");
    }
}
