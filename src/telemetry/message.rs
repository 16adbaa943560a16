//! What a bridge publishes, topic by topic, as JSON (`docs/shop.md` has the schema with
//! examples). Under `PREFIX/MACHINE/`:
//!
//! | topic | payload | QoS | retained |
//! |---|---|---|---|
//! | `status` | [`Status`]: the bridge online (its birth) or offline (its last will, or its goodbye) | 1 | yes |
//! | `state` | [`State`]: the machine now (idle, running, held, alarm), its run and its last ending | 1 | yes |
//! | `event` | [`Event`]: a run's start and end, a hold, a resume, an alarm, a refused line, an override | 1 | no |
//! | `progress` | [`Progress`]: line, percent, time left, position, at a bounded rate | 0 | no |
//! | `command` | [`Command`], *to* the bridge: the shop overview's Hold | 1 | no |
//!
//! Every `state` and `event` carries the bridge's `session` (new at each start of a
//! bridge) and a `seq` counting from 1 in it: a reader that sees a `seq` twice has seen a
//! redelivery (QoS 1 is at least once), and one that skips a number knows it missed one.
//! The types read back what they write, so that a reader in Rust (the shop overview) and
//! the tests use them too.

use serde::{Deserialize, Serialize};

/// The topic of [`Status`], under `PREFIX/MACHINE/`.
pub const STATUS: &str = "status";
/// The topic of [`State`].
pub const STATE: &str = "state";
/// The topic of [`Event`].
pub const EVENT: &str = "event";
/// The topic of [`Progress`].
pub const PROGRESS: &str = "progress";
/// The topic of [`Command`], which the bridge reads.
pub const COMMAND: &str = "command";

/// A command to a bridge: the only one is a Hold, from the shop overview. The bridge takes
/// it only with its console's own token (`whirl serve --token`), which the overview, given
/// the shop's token, carries.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Command {
    /// `hold`.
    pub command: String,
    /// The token it carries.
    pub token: String,
    /// Who asked, for the run's notes (the overview's client).
    pub by: String,
}

/// The bridge: online or not, and who it is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Whether the bridge is connected.
    pub online: bool,
    /// The machine profile's name, as a person reads it.
    pub machine: String,
    /// The host the bridge runs on.
    pub bridge: String,
    /// The bridge's process id.
    pub pid: u32,
    /// This start of the bridge: a random word, new each time.
    pub session: String,
    /// whirl's version.
    pub version: String,
    /// When this session came online (UTC, RFC 3339).
    pub since: String,
    /// The keep-alive, s: the broker says a silent bridge is offline after 1.5 times it.
    pub keepalive_s: u64,
    /// The bridge's console, if it serves one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub console: Option<String>,
    /// Why it is offline: "the bridge stopped", or the last will's "connection lost".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// What the machine is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Machine {
    /// No run.
    Idle,
    /// A run is under way.
    Running,
    /// A run is held (a feed hold, a door, a pause): it resumes where it stands.
    Held,
    /// The controller is in alarm.
    Alarm,
}

/// A run, as its start says it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Run {
    /// `dry-run`, `stream` or `serve`.
    pub kind: String,
    /// The run's number in the record store, if it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record: Option<i64>,
    /// The job file, if the run was planned from one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub job: Option<String>,
    /// The program (its file, or the job it was planned from).
    pub program: String,
    /// Its lines.
    pub lines: usize,
    /// How it goes to the machine (`serial`, `modbus-tcp`, `linuxcnc`, …).
    pub transport: String,
    /// The program's SHA-256, if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub program_sha256: Option<String>,
    /// What the program was planned from (its provenance header: the job's and the
    /// machine's hashes, Δ, the angle, the feed), if known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<serde_json::Value>,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ending {
    /// Every line ran.
    pub completed: bool,
    /// Why it stopped short.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The line (1-based) it resumes at.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resume_at: Option<usize>,
    /// Lines from `resume_at` to this one may already have run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub possibly_run_to: Option<usize>,
}

/// An alarm, in the controller's code and in words.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    /// The controller's code.
    pub code: u32,
    /// What it means.
    pub text: String,
}

/// The machine now (retained: a reader that subscribes later gets it at once).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// The bridge's session.
    pub session: String,
    /// The number of this message in the session.
    pub seq: u64,
    /// When (UTC, RFC 3339).
    pub time: String,
    /// What the machine does.
    pub state: Machine,
    /// The run under way, or the last one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run: Option<Run>,
    /// The active alarm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alarm: Option<Alarm>,
    /// The feed override, percent, once one was reported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_override: Option<u16>,
    /// How the last run ended (while idle).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last: Option<Ending>,
}

/// Something that happened to a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// The bridge's session.
    pub session: String,
    /// The number of this message in the session.
    pub seq: u64,
    /// When (UTC, RFC 3339).
    pub time: String,
    /// What.
    #[serde(flatten)]
    pub what: What,
}

/// What an [`Event`] is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum What {
    /// A run started.
    Start {
        /// The run.
        run: Run,
    },
    /// The run was held.
    Hold {
        /// The controller's word for it (`Hold:0`, `Held`, `PAUSED`, `Door:1`).
        controller: String,
        /// The program line executing, if known (1-based).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        line: Option<usize>,
    },
    /// It runs again.
    Resume {
        /// The controller's word for it.
        controller: String,
        /// The program line executing, if known (1-based).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        line: Option<usize>,
    },
    /// The controller raised an alarm.
    Alarm {
        /// It.
        #[serde(flatten)]
        alarm: Alarm,
    },
    /// The controller refused a line.
    Error {
        /// The line (1-based).
        line: usize,
        /// Its code.
        code: u32,
        /// What it means.
        text: String,
    },
    /// The feed override runs at a new value.
    FeedOverride {
        /// Percent of the programmed feed.
        percent: u16,
    },
    /// The run ended.
    End {
        /// How.
        #[serde(flatten)]
        ending: Ending,
    },
}

/// X, Z (mm, machine coordinates; X a radius) and C (degrees).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Position {
    /// X, mm.
    pub x: f64,
    /// Z, mm.
    pub z: f64,
    /// C, degrees.
    pub c: f64,
}

/// Where a run is (QoS 0: the next one replaces a lost one).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// When (UTC, RFC 3339).
    pub time: String,
    /// What `done` and `total` count: `lines`, `segments` or `set-points`.
    pub unit: String,
    /// Done so far.
    pub done: usize,
    /// In the whole program.
    pub total: usize,
    /// `done / total`, percent.
    pub percent: f64,
    /// The program line executing, if the controller says (1-based).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line: Option<usize>,
    /// Since the run started, s.
    pub elapsed_s: f64,
    /// Time left, s, where it can be told.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left_s: Option<f64>,
    /// Where the machine is, as last reported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<Position>,
    /// The controller's state in its own word, where it reports one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<String>,
}
