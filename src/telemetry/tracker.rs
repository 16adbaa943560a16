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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::progress::Unit;
    use std::time::Duration;

    fn record(event: log::Event) -> Record {
        Record { t: 0.0, event }
    }

    fn start() -> log::Event {
        log::Event::Start {
            program: "job.toml".into(),
            lines: 100,
            transport: "serial".into(),
        }
    }

    fn status(word: &str) -> log::Event {
        log::Event::Status {
            state: word.into(),
            pos: [0.0; 3],
            blocks_free: None,
            rx_free: None,
            line: Some(12),
        }
    }

    fn end(completed: bool) -> log::Event {
        log::Event::End {
            completed,
            reason: (!completed).then(|| "held, then stopped".to_owned()),
        }
    }

    /// What each message says: an event's kind, or the state's machine.
    fn said(out: &[Out]) -> Vec<String> {
        out.iter()
            .map(|o| match o {
                Out::Event(e) => format!("{:?}", e.what)
                    .split([' ', '{'])
                    .next()
                    .unwrap()
                    .to_owned(),
                Out::State(s) => format!("state {:?}", s.state),
                Out::Progress(_) => "progress".to_owned(),
            })
            .collect()
    }

    fn feed(tracker: &mut Tracker, events: Vec<log::Event>) -> Vec<Out> {
        events
            .into_iter()
            .flat_map(|e| tracker.record(&record(e), "t"))
            .collect()
    }

    #[test]
    fn a_run_starts_holds_resumes_and_ends_in_each_controllers_words() {
        for (held, running) in [
            ("Hold:0", "Run"),
            ("Held", "Running"),
            ("PAUSED", "RUNNING"),
            ("Door:1", "Run"),
        ] {
            let mut tracker = Tracker::new("s", 0.5);
            let out = feed(
                &mut tracker,
                vec![
                    start(),
                    status(running),
                    status(held),
                    status(held),
                    status(running),
                    end(true),
                ],
            );
            assert_eq!(
                said(&out),
                [
                    "Start",
                    "state Running",
                    "Hold",
                    "state Held",
                    "Resume",
                    "state Running",
                    "End",
                    "state Idle"
                ],
                "{held} / {running}"
            );
            let Out::State(last) = out.last().unwrap() else {
                panic!()
            };
            assert_eq!(last.last.as_ref().map(|l| l.completed), Some(true));
        }
    }

    #[test]
    fn every_message_is_numbered_once_in_order() {
        let mut tracker = Tracker::new("s", 0.5);
        let first = tracker.state("t");
        let out = feed(
            &mut tracker,
            vec![start(), status("Hold:0"), status("Run"), end(true)],
        );
        let seqs: Vec<u64> = std::iter::once(first.seq)
            .chain(out.iter().map(|o| match o {
                Out::Event(e) => e.seq,
                Out::State(s) => s.seq,
                Out::Progress(_) => unreachable!(),
            }))
            .collect();
        assert_eq!(seqs, (1..=seqs.len() as u64).collect::<Vec<_>>());
    }

    #[test]
    fn an_alarm_is_said_in_words_and_stays_after_the_run() {
        let mut tracker = Tracker::new("s", 0.5);
        let alarm = log::Event::Alarm {
            code: 64,
            message: "Δ guard: overcut".into(),
        };
        let out = feed(&mut tracker, vec![start(), alarm, end(false)]);
        assert_eq!(
            said(&out),
            [
                "Start",
                "state Running",
                "Alarm",
                "state Alarm",
                "End",
                "state Alarm"
            ]
        );
        let Out::State(last) = out.last().unwrap() else {
            panic!()
        };
        assert_eq!(
            last.alarm.as_ref().map(|a| (a.code, a.text.as_str())),
            Some((64, "Δ guard: overcut"))
        );
        // The next run starts clear of it.
        let out = feed(&mut tracker, vec![start()]);
        let Out::State(state) = &out[1] else { panic!() };
        assert_eq!((state.state, state.alarm.clone()), (Machine::Running, None));
    }

    #[test]
    fn where_a_run_resumes_is_said_whether_it_comes_before_or_after_its_end() {
        let resume = log::Event::ResumeAt {
            line: 41,
            possibly_run_to: Some(44),
        };
        // A serial line logs it before the End, a fieldbus after.
        for events in [
            vec![start(), resume.clone(), end(false)],
            vec![start(), end(false), resume.clone()],
        ] {
            let mut tracker = Tracker::new("s", 0.5);
            let out = feed(&mut tracker, events);
            let Out::State(last) = out.last().unwrap() else {
                panic!()
            };
            let ending = last.last.clone().unwrap();
            assert_eq!(
                (ending.resume_at, ending.possibly_run_to),
                (Some(41), Some(44))
            );
            assert!(!ending.completed);
        }
    }

    #[test]
    fn an_override_is_said_when_it_changes_only() {
        let running = |percent| log::Event::FeedOverride {
            percent,
            state: FeedOverrideState::Running,
        };
        let asked = log::Event::FeedOverride {
            percent: 50,
            state: FeedOverrideState::Asked,
        };
        let mut tracker = Tracker::new("s", 0.5);
        let out = feed(
            &mut tracker,
            vec![start(), asked, running(80), running(80), running(100)],
        );
        let percents: Vec<u16> = out
            .iter()
            .filter_map(|o| match o {
                Out::Event(Event {
                    what: What::FeedOverride { percent },
                    ..
                }) => Some(*percent),
                _ => None,
            })
            .collect();
        assert_eq!(percents, [80, 100]);
    }

    #[test]
    fn progress_comes_at_most_once_an_interval_and_always_at_the_end() {
        let mut tracker = Tracker::new("s", 0.5);
        let snapshot = |done| transport::Progress {
            unit: Unit::Lines,
            done,
            total: 100,
            line: Some(done),
            elapsed: Duration::from_millis(10 * done as u64),
            left: None,
            state: Some("Run".into()),
            position: Some([1.0, 2.0, 3.0]),
            finishing: false,
        };
        assert!(
            tracker.progress(&snapshot(1), 0, "t").is_empty(),
            "before the start"
        );
        feed(&mut tracker, vec![start()]);
        // One snapshot every 100 ms for 2 s: one message each 500 ms, and the last.
        let sent: Vec<usize> = (0..=20)
            .flat_map(|i| tracker.progress(&snapshot(i * 5), 100 * i as i64, "t"))
            .map(|o| match o {
                Out::Progress(p) => p.done,
                _ => panic!("a state change from a steady Run"),
            })
            .collect();
        assert_eq!(sent, [0, 25, 50, 75, 100]);
        let mut tracker = Tracker::new("s", 0.5);
        feed(&mut tracker, vec![start()]);
        let out = tracker.progress(&snapshot(99), 0, "t");
        let Out::Progress(p) = &out[0] else { panic!() };
        assert_eq!(
            (p.line, p.percent, p.position.map(|p| p.c)),
            (Some(100), 99.0, Some(3.0))
        );
        assert_eq!(
            tracker.progress(&snapshot(100), 1, "t").len(),
            1,
            "the last comes at once"
        );
    }
}
