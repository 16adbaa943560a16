//! The machine's state, followed from a run's log events and progress, and the messages
//! each change makes: plain values in, messages out, no clock and no broker.
//!
//! Every transport writes the same log events (`crate::log`), so one tracker reads them
//! all: `Start` and `End` bound a run, an `Alarm` is an alarm, a refused line an error, a
//! running feed override an override; the controller's own state words (a status report's,
//! or a progress snapshot's) say held or running, in each controller's words: grbl's
//! `Hold:0` and `Door:1`, the register map's `Held`, LinuxCNC's `PAUSED`.

use crate::log::{self, FeedOverrideState, Record};
use crate::telemetry::message::{
    self, Alarm, Ending, Event, Machine, Position, Progress, Run, State, What,
};
use crate::transport;

/// A message the tracker makes, for the outbox.
#[derive(Debug, Clone, PartialEq)]
pub enum Out {
    /// The machine's state changed (QoS 1, retained).
    State(State),
    /// Something happened (QoS 1).
    Event(Event),
    /// Where the run is (QoS 0).
    Progress(Progress),
}

/// What the caller knows of a run before its log's `Start`: what kind it is, its record,
/// its job and what its program was planned from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunContext {
    /// `dry-run`, `stream` or `serve`.
    pub kind: String,
    /// Its number in the record store.
    pub record: Option<i64>,
    /// The job file.
    pub job: Option<String>,
    /// The program's SHA-256.
    pub program_sha256: Option<String>,
    /// Its provenance header, as JSON.
    pub provenance: Option<serde_json::Value>,
}

/// The machine's state and the session's message count.
#[derive(Debug)]
pub struct Tracker {
    session: String,
    seq: u64,
    machine: Machine,
    /// The run under way (`running` true) or the last one.
    run: Option<Run>,
    running: bool,
    context: Option<RunContext>,
    alarm: Option<Alarm>,
    feed_override: Option<u16>,
    last: Option<Ending>,
    /// The shortest time between two progress messages, ms.
    interval_ms: i64,
    /// When the last progress message was made, ms.
    last_progress: Option<i64>,
}

impl Tracker {
    /// A tracker for the bridge's `session`, idle, making progress messages at most every
    /// `interval_s`.
    pub fn new(session: &str, interval_s: f64) -> Tracker {
        Tracker {
            session: session.to_owned(),
            seq: 0,
            machine: Machine::Idle,
            run: None,
            running: false,
            context: None,
            alarm: None,
            feed_override: None,
            last: None,
            interval_ms: (interval_s * 1000.0).round() as i64,
            last_progress: None,
        }
    }

    /// The state now, as a message (numbered: call it when it is to be published).
    pub fn state(&mut self, time: &str) -> State {
        self.seq += 1;
        State {
            session: self.session.clone(),
            seq: self.seq,
            time: time.to_owned(),
            state: self.machine,
            run: self.run.clone(),
            alarm: self.alarm.clone(),
            feed_override: self.feed_override,
            last: self.last.clone().filter(|_| !self.running),
        }
    }

    /// What the next run's `Start` does not say.
    pub fn prepare(&mut self, context: RunContext) {
        self.context = Some(context);
    }

    /// A log event, written at `time` (UTC text): the messages it makes.
    pub fn record(&mut self, record: &Record, time: &str) -> Vec<Out> {
        let mut out = Vec::new();
        match &record.event {
            log::Event::Start {
                program,
                lines,
                transport,
            } => {
                let context = self.context.take().unwrap_or_default();
                let run = Run {
                    kind: context.kind,
                    record: context.record,
                    job: context.job,
                    program: program.clone(),
                    lines: *lines,
                    transport: transport.clone(),
                    program_sha256: context.program_sha256,
                    provenance: context.provenance,
                };
                self.run = Some(run.clone());
                self.running = true;
                self.machine = Machine::Running;
                self.alarm = None;
                self.feed_override = None;
                self.last = None;
                self.last_progress = None;
                self.event(&mut out, time, What::Start { run });
            }
            log::Event::Status { state, line, .. } => {
                let line = line
                    .and_then(|l| usize::try_from(l).ok())
                    .filter(|&l| l > 0);
                self.controller_says(&mut out, time, state, line);
            }
            log::Event::Alarm { code, message } => {
                let alarm = Alarm {
                    code: *code,
                    text: message.clone(),
                };
                self.alarm = Some(alarm.clone());
                self.machine = Machine::Alarm;
                self.event(&mut out, time, What::Alarm { alarm });
            }
            log::Event::Error {
                line,
                code,
                message,
            } => {
                let what = What::Error {
                    line: *line,
                    code: *code,
                    text: message.clone(),
                };
                self.event(&mut out, time, what);
            }
            log::Event::FeedOverride {
                percent,
                state: FeedOverrideState::Running,
            } if self.feed_override != Some(*percent) => {
                self.feed_override = Some(*percent);
                let what = What::FeedOverride { percent: *percent };
                self.event(&mut out, time, what);
            }
            log::Event::ResumeAt {
                line,
                possibly_run_to,
            } => {
                // Beside the run's End: before it on a serial line, after it on a fieldbus.
                let last = self.last.get_or_insert(Ending {
                    completed: false,
                    reason: None,
                    resume_at: None,
                    possibly_run_to: None,
                });
                last.resume_at = Some(*line);
                last.possibly_run_to = *possibly_run_to;
                if !self.running {
                    self.changed(&mut out, time);
                }
            }
            log::Event::End { completed, reason } if self.running => {
                let ending = Ending {
                    completed: *completed,
                    reason: reason.clone(),
                    resume_at: self.last.as_ref().and_then(|l| l.resume_at),
                    possibly_run_to: self.last.as_ref().and_then(|l| l.possibly_run_to),
                };
                self.running = false;
                self.last = Some(ending.clone());
                if self.machine != Machine::Alarm {
                    self.machine = Machine::Idle;
                }
                self.event(&mut out, time, What::End { ending });
            }
            _ => {}
        }
        out
    }

    /// A progress snapshot at `now_ms` (ms, any clock that only goes forward): a progress
    /// message if the last one is at least the interval old or this is the last, and
    /// whatever the controller's state word changes.
    pub fn progress(&mut self, p: &transport::Progress, now_ms: i64, time: &str) -> Vec<Out> {
        let mut out = Vec::new();
        if !self.running {
            return out;
        }
        if let Some(state) = &p.state {
            let line = p.line.map(|l| l + 1);
            self.controller_says(&mut out, time, state, line);
        }
        let due = self
            .last_progress
            .is_none_or(|last| now_ms - last >= self.interval_ms);
        if due || p.done == p.total {
            self.last_progress = Some(now_ms);
            out.push(Out::Progress(Progress {
                time: time.to_owned(),
                unit: p.unit.name().to_owned(),
                done: p.done,
                total: p.total,
                percent: 100.0 * p.fraction(),
                line: p.line.map(|l| l + 1),
                elapsed_s: p.elapsed.as_secs_f64(),
                left_s: p.left.map(|d| d.as_secs_f64()),
                position: p.position.map(|[x, z, c]| Position { x, z, c }),
                controller: p.state.clone(),
            }));
        }
        out
    }

    /// The controller's state word, during a run: held and running in turn.
    fn controller_says(&mut self, out: &mut Vec<Out>, time: &str, word: &str, line: Option<usize>) {
        if !self.running {
            return;
        }
        let controller = word.to_owned();
        match (self.machine, held_or_running(word)) {
            (Machine::Running, Some(Machine::Held)) => {
                self.machine = Machine::Held;
                self.event(out, time, What::Hold { controller, line });
            }
            (Machine::Held, Some(Machine::Running)) => {
                self.machine = Machine::Running;
                self.event(out, time, What::Resume { controller, line });
            }
            _ => {}
        }
    }

    /// An event, then the state it leaves.
    fn event(&mut self, out: &mut Vec<Out>, time: &str, what: What) {
        self.seq += 1;
        out.push(Out::Event(Event {
            session: self.session.clone(),
            seq: self.seq,
            time: time.to_owned(),
            what,
        }));
        self.changed(out, time);
    }

    fn changed(&mut self, out: &mut Vec<Out>, time: &str) {
        let state = self.state(time);
        out.push(Out::State(state));
    }
}

/// A controller's state word as held or running (`None`: neither, as `Idle` between two
/// lines, or an alarm, which its own event says).
fn held_or_running(word: &str) -> Option<Machine> {
    let word = word.to_ascii_lowercase();
    if ["hold", "held", "paused", "door"]
        .iter()
        .any(|w| word.starts_with(w))
    {
        Some(Machine::Held)
    } else if ["run", "jog"].iter().any(|w| word.starts_with(w)) {
        Some(Machine::Running)
    } else {
        None
    }
}

/// The topic each message goes to, under the machine's root.
pub fn topic(out: &Out) -> &'static str {
    match out {
        Out::State(_) => message::STATE,
        Out::Event(_) => message::EVENT,
        Out::Progress(_) => message::PROGRESS,
    }
}
