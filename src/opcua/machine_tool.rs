//! One machine tool as OPC 40501-1 (OPC UA for Machine Tools) shows it, followed from the
//! telemetry tracker's messages: the tracker's message in, the values of the machine's
//! nodes and the alerts to raise out. No server and no clock, so that every rule of the
//! mapping is tested on values ([`crate::opcua::nodes`] writes them into the server).
//!
//! | tracker | 40501-1 |
//! |---|---|
//! | the machine idle, running, held, in alarm | `OperationMode`, the `Stacklight`'s lamps, the channel's `ChannelState`, the program's and the job's `State` |
//! | a feed override | the channel's `FeedOverride` |
//! | a run's start | the `ActiveProgram`'s `Name` and the job's `Identifier` (a new job when it names another) |
//! | a run's end | the job's `RunsCompleted` (a run that completed counts) |
//! | an alarm | an `AlertType` event, its `ErrorCode` the controller's code and its `Message` its words; cleared when the next run starts |
//! | progress | whirl's `Line` and `Percent` beside the `ActiveProgram` (40501-1 has no place for them) |

use crate::telemetry::message::{Alarm, Ending, Machine, What};
use crate::telemetry::tracker::Out;

/// `MachineOperationMode` (OPC 40501-1, 12.5): the values whirl uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum OperationMode {
    /// The machine runs programs automatically: whirl drives it.
    Automatic = 1,
    /// A run is held (a feed hold, a door): the operator intervenes.
    AutoWithManualIntervention = 3,
}

/// `ChannelState` (OPC 40501-1, 12): the NC channel's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum ChannelState {
    /// A command executes: a run is under way.
    Active = 0,
    /// Execution is interrupted and can go on: a run held, or stopped by an alarm.
    Interrupted = 1,
    /// No command is active: idle.
    Reset = 2,
}

/// `SignalColor` (OPC 10000-200, 5.3.3): the colours of whirl's lamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum SignalColor {
    /// An alarm.
    Red = 1,
    /// Running.
    Green = 2,
    /// Held.
    Yellow = 4,
}

/// The stacklight's lamps, top to bottom (their `NumberInList`).
pub const LAMPS: [SignalColor; 3] = [SignalColor::Red, SignalColor::Yellow, SignalColor::Green];

/// The states of 40501-1's `ProductionStateMachineType`, which a program's and a job's
/// `State` are in; `CurrentState` is the name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProductionState {
    /// Not started yet.
    Initializing,
    /// Executing.
    Running,
    /// Paused: it can go on.
    Interrupted,
    /// Finished as planned.
    Ended,
    /// Stopped short.
    Aborted,
}

impl ProductionState {
    /// The state's name, as `CurrentState` says it.
    pub fn name(self) -> &'static str {
        match self {
            ProductionState::Initializing => "Initializing",
            ProductionState::Running => "Running",
            ProductionState::Interrupted => "Interrupted",
            ProductionState::Ended => "Ended",
            ProductionState::Aborted => "Aborted",
        }
    }
}

/// The values of one machine's variable nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Values {
    /// `Monitoring/MachineTool/OperationMode`.
    pub operation_mode: OperationMode,
    /// Each of [`LAMPS`] on or off (`SignalOn`).
    pub lamps: [bool; 3],
    /// The channel's `ChannelState`.
    pub channel_state: ChannelState,
    /// The channel's `FeedOverride`, percent: 100 until the controller reports another.
    pub feed_override: f64,
    /// `Production/ActiveProgram/Name`: the program of the run under way or the last.
    pub program: String,
    /// Its `State`.
    pub program_state: ProductionState,
    /// The job's `Identifier`: the job file the runs are planned from (or their program).
    pub job: String,
    /// The job's `State`.
    pub job_state: ProductionState,
    /// The job's `RunsCompleted`: its runs that completed.
    pub runs_completed: u32,
    /// The program line executing (1-based), where the controller says.
    pub line: Option<u32>,
    /// How far the run is, percent.
    pub percent: f64,
}

/// An `AlertType` event (OPC 40501-1, 9.1): an alarm raised or cleared.
#[derive(Debug, Clone, PartialEq)]
pub struct Alert {
    /// `ErrorCode`: the controller's code.
    pub error_code: String,
    /// `Message`: what it means.
    pub message: String,
    /// `ActiveState`: raised (true) or cleared.
    pub active: bool,
}

impl Alert {
    /// OPC UA's severity, 1 to 1000: an alarm stops the run, the highest band.
    pub const SEVERITY: u16 = 900;
}

/// A machine tool's values, followed message by message.
#[derive(Debug, Clone)]
pub struct MachineTool {
    values: Values,
    /// The alarm raised and not yet cleared.
    alarm: Option<Alarm>,
}

impl Default for MachineTool {
    fn default() -> Self {
        MachineTool::new()
    }
}

impl MachineTool {
    /// A machine that has run nothing yet.
    pub fn new() -> MachineTool {
        MachineTool {
            values: Values {
                operation_mode: OperationMode::Automatic,
                lamps: [false; 3],
                channel_state: ChannelState::Reset,
                feed_override: 100.0,
                program: String::new(),
                program_state: ProductionState::Initializing,
                job: String::new(),
                job_state: ProductionState::Initializing,
                runs_completed: 0,
                line: None,
                percent: 0.0,
            },
            alarm: None,
        }
    }

    /// The values now.
    pub fn values(&self) -> &Values {
        &self.values
    }

    /// One of the tracker's messages: the values follow it; the alerts it raises or clears
    /// come back.
    pub fn apply(&mut self, out: &Out) -> Vec<Alert> {
        let mut alerts = Vec::new();
        match out {
            Out::Event(event) => match &event.what {
                What::Start { run } => {
                    let job = run.job.clone().unwrap_or_else(|| run.program.clone());
                    if job != self.values.job {
                        self.values.job = job;
                        self.values.runs_completed = 0;
                    }
                    self.values.program.clone_from(&run.program);
                    self.values.line = None;
                    self.values.percent = 0.0;
                }
                What::End { ending } if ending.completed => {
                    self.values.runs_completed += 1;
                }
                What::Alarm { alarm } => {
                    self.alarm = Some(alarm.clone());
                    alerts.push(Alert {
                        error_code: alarm.code.to_string(),
                        message: alarm.text.clone(),
                        active: true,
                    });
                }
                _ => {}
            },
            Out::State(state) => {
                self.follow(state.state, state.last.as_ref());
                self.values.feed_override = state.feed_override.map_or(100.0, f64::from);
                if state.alarm.is_none() {
                    if let Some(alarm) = self.alarm.take() {
                        alerts.push(Alert {
                            error_code: alarm.code.to_string(),
                            message: alarm.text,
                            active: false,
                        });
                    }
                }
            }
            Out::Progress(progress) => {
                self.values.line = progress.line.and_then(|l| u32::try_from(l).ok());
                self.values.percent = progress.percent;
            }
        }
        alerts
    }

    /// The machine's state into the mode, the lamps, the channel and the state machines:
    /// `last` is how the last run ended (absent while one runs, and before the first).
    fn follow(&mut self, machine: Machine, last: Option<&Ending>) {
        let v = &mut self.values;
        v.operation_mode = match machine {
            Machine::Held => OperationMode::AutoWithManualIntervention,
            Machine::Idle | Machine::Running | Machine::Alarm => OperationMode::Automatic,
        };
        let lit = match machine {
            Machine::Idle => None,
            Machine::Running => Some(SignalColor::Green),
            Machine::Held => Some(SignalColor::Yellow),
            Machine::Alarm => Some(SignalColor::Red),
        };
        v.lamps = LAMPS.map(|lamp| Some(lamp) == lit);
        v.channel_state = match machine {
            Machine::Running => ChannelState::Active,
            Machine::Held | Machine::Alarm => ChannelState::Interrupted,
            Machine::Idle => ChannelState::Reset,
        };
        let state = match (machine, last) {
            (_, Some(ending)) if ending.completed => ProductionState::Ended,
            (_, Some(_)) => ProductionState::Aborted,
            (Machine::Running, None) => ProductionState::Running,
            (Machine::Held | Machine::Alarm, None) => ProductionState::Interrupted,
            (Machine::Idle, None) => ProductionState::Initializing,
        };
        v.program_state = state;
        v.job_state = state;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::{self, FeedOverrideState, Record};
    use crate::telemetry::tracker::{RunContext, Tracker};

    fn start(job: &str) -> log::Event {
        log::Event::Start {
            program: format!("{job}.nc"),
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
            line: Some(3),
        }
    }

    fn end(completed: bool) -> log::Event {
        log::Event::End {
            completed,
            reason: None,
        }
    }

    /// The tracker and the machine tool, fed log events as a run writes them.
    struct Bridge {
        tracker: Tracker,
        tool: MachineTool,
        alerts: Vec<Alert>,
    }

    impl Bridge {
        fn new() -> Bridge {
            let mut bridge = Bridge {
                tracker: Tracker::new("s", 0.5),
                tool: MachineTool::new(),
                alerts: Vec::new(),
            };
            let first = Out::State(bridge.tracker.state("t"));
            bridge.alerts.extend(bridge.tool.apply(&first));
            bridge
        }

        fn run(&mut self, job: Option<&str>) {
            self.tracker.prepare(RunContext {
                job: job.map(str::to_owned),
                ..RunContext::default()
            });
        }

        fn feed(&mut self, event: log::Event) -> &Values {
            let record = Record { t: 0.0, event };
            for out in self.tracker.record(&record, "t") {
                self.alerts.extend(self.tool.apply(&out));
            }
            self.tool.values()
        }
    }

    /// What the mode, the lit lamp, the channel and the program's state say.
    fn said(
        v: &Values,
    ) -> (
        OperationMode,
        Vec<SignalColor>,
        ChannelState,
        ProductionState,
    ) {
        let lit = LAMPS
            .iter()
            .zip(v.lamps)
            .filter(|(_, on)| *on)
            .map(|(lamp, _)| *lamp)
            .collect();
        (v.operation_mode, lit, v.channel_state, v.program_state)
    }

    #[test]
    fn each_machine_state_is_said_in_40501s_enumerations() {
        use ChannelState::{Active, Reset};
        use OperationMode::*;
        use ProductionState::{Aborted, Ended, Initializing, Running};
        let mut bridge = Bridge::new();
        assert_eq!(
            said(bridge.tool.values()),
            (Automatic, vec![], Reset, Initializing),
            "before any run"
        );
        assert_eq!(
            said(bridge.feed(start("a"))),
            (Automatic, vec![SignalColor::Green], Active, Running)
        );
        assert_eq!(
            said(bridge.feed(status("Hold:0"))),
            (
                AutoWithManualIntervention,
                vec![SignalColor::Yellow],
                ChannelState::Interrupted,
                ProductionState::Interrupted
            )
        );
        assert_eq!(
            said(bridge.feed(status("Run"))),
            (Automatic, vec![SignalColor::Green], Active, Running)
        );
        assert_eq!(
            said(bridge.feed(end(true))),
            (Automatic, vec![], Reset, Ended)
        );
        bridge.feed(start("a"));
        assert_eq!(said(bridge.feed(end(false))).3, Aborted);
        // The numbers are the specifications' (OPC 40501-1 12, 12.5; OPC 10000-200 5.3.3).
        assert_eq!(
            [
                Active as i32,
                ChannelState::Interrupted as i32,
                Reset as i32
            ],
            [0, 1, 2]
        );
        assert_eq!(
            [Automatic as i32, AutoWithManualIntervention as i32],
            [1, 3]
        );
        assert_eq!(LAMPS.map(|l| l as i32), [1, 4, 2]);
    }

    #[test]
    fn runs_of_one_job_are_counted_and_another_job_counts_afresh() {
        let mut bridge = Bridge::new();
        for (completed, count) in [(true, 1), (false, 1), (true, 2)] {
            bridge.run(Some("jobs/m8.toml"));
            let v = bridge.feed(start("m8"));
            assert_eq!(
                (v.job.as_str(), v.program.as_str(), v.job_state),
                ("jobs/m8.toml", "m8.nc", ProductionState::Running)
            );
            assert_eq!(bridge.feed(end(completed)).runs_completed, count);
        }
        // A program streamed without a job is its own job.
        bridge.run(None);
        let v = bridge.feed(start("tr40"));
        assert_eq!((v.job.as_str(), v.runs_completed), ("tr40.nc", 0));
        assert_eq!(bridge.feed(end(true)).runs_completed, 1);
    }

    #[test]
    fn an_alarm_is_an_alert_with_its_code_and_words_cleared_by_the_next_run() {
        let mut bridge = Bridge::new();
        bridge.feed(start("a"));
        let alarm = log::Event::Alarm {
            code: 64,
            message: "Δ guard: overcut".into(),
        };
        let v = bridge.feed(alarm).clone();
        assert_eq!(
            said(&v),
            (
                OperationMode::Automatic,
                vec![SignalColor::Red],
                ChannelState::Interrupted,
                ProductionState::Interrupted
            )
        );
        let raised = Alert {
            error_code: "64".into(),
            message: "Δ guard: overcut".into(),
            active: true,
        };
        assert_eq!(bridge.alerts, std::slice::from_ref(&raised));
        // The run ends short, the alarm stays on the lamp until the next run clears it.
        let v = bridge.feed(end(false)).clone();
        assert_eq!(
            (v.lamps, v.program_state),
            ([true, false, false], ProductionState::Aborted)
        );
        assert_eq!(bridge.alerts.len(), 1);
        bridge.feed(start("a"));
        assert_eq!(
            bridge.alerts,
            [
                raised.clone(),
                Alert {
                    active: false,
                    ..raised
                }
            ]
        );
    }

    #[test]
    fn the_feed_override_and_the_progress_are_the_channels_and_the_programs() {
        let mut bridge = Bridge::new();
        bridge.feed(start("a"));
        assert_eq!(bridge.tool.values().feed_override, 100.0, "until reported");
        let v = bridge.feed(log::Event::FeedOverride {
            percent: 80,
            state: FeedOverrideState::Running,
        });
        assert_eq!(v.feed_override, 80.0);
        let p = crate::transport::Progress {
            unit: crate::transport::progress::Unit::Lines,
            done: 25,
            total: 100,
            line: Some(24),
            elapsed: std::time::Duration::from_secs(1),
            left: None,
            state: None,
            position: None,
            finishing: false,
        };
        for out in bridge.tracker.progress(&p, 0, "t") {
            bridge.tool.apply(&out);
        }
        let v = bridge.tool.values();
        assert_eq!((v.line, v.percent), (Some(25), 25.0));
        // A new run starts from the programmed feed and the first line.
        let v = bridge.feed(start("a"));
        assert_eq!((v.feed_override, v.line, v.percent), (100.0, None, 0.0));
    }
}
