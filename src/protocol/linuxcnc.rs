//! A program run on LinuxCNC through `linuxcncrsh`, LinuxCNC's remote shell: a line
//! protocol over TCP (LinuxCNC's manual, "linuxcncrsh"; `src/emc/usr_intf/emcrsh.cc`).
//!
//! LinuxCNC is not streamed to: it opens a G-code file and runs it itself, reading ahead
//! and planning its own motion. So the bridge's part is a session: log in, check (and, only
//! where the profile allows, bring about) that the machine is out of E-stop and on, switch
//! to auto mode, open the program, run it, and then poll what it does (program state, the
//! line it is executing, the position, errors) until it stops, passing on the operator's
//! hold, resume and abort. [`Session`] is that session as a state machine: bytes in, bytes
//! out, the transport's clock given with each call.
//!
//! What the server does, as found on LinuxCNC 2.9 (and what this module relies on):
//!
//! - a command is one line, `hello`, `get` or `set` and words separated by spaces;
//!   answers end in `\r\n` (`set` acknowledgements in `\n\r`), and an unknown `set`
//!   sends an empty line before its `NAK`: empty lines are skipped;
//! - echo is on until `set echo off`, which is echoed itself; an echo is the command's own
//!   text, and is skipped;
//! - `get NAME` answers `NAME value…`, or `GET NAME NAK`; with `set verbose on`, `set NAME`
//!   answers `SET NAME ACK` or `SET NAME NAK` (without it, nothing), and `hello` answers
//!   `HELLO ACK …` or `HELLO NAK`;
//! - `set` commands other than `echo`, `verbose` and `enable` need `set enable <password>`
//!   first;
//! - `get error` gives the oldest error LinuxCNC's task reported and forgets it, or
//!   `ERROR OK`: so a `NAK`, a file that will not open and a program line the interpreter
//!   refuses are all read there, in LinuxCNC's words;
//! - `get program_status` is `IDLE`, `RUNNING` or `PAUSED`; `get program_line` the line
//!   motion is executing (the interpreter reads ahead of it); `get abs_act_pos` six
//!   numbers, X Y Z A B C in machine units.
//!
//! One request is in flight at a time (the server answers in order and a session is
//! single-threaded), each with a deadline: a `linuxcncrsh` session that stops answering is a
//! known LinuxCNC failure, and the run must not wait on it for ever.

use std::collections::VecDeque;
use std::time::Duration;

/// How a session runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionConfig {
    /// `hello`'s password (`linuxcncrsh --connectpw`).
    pub connect_password: String,
    /// `set enable`'s password (`linuxcncrsh --enablepw`).
    pub enable_password: String,
    /// Whether the session may take the machine out of E-stop and switch it on.
    pub power_on: bool,
    /// The program's path, as LinuxCNC's host sees it.
    pub program: String,
    /// Time between status polls while the program runs.
    pub poll_interval: Duration,
    /// Longest wait for one answer.
    pub answer_timeout: Duration,
    /// Where the program leaves the machine, X (radius), Z, C: a program that goes idle
    /// without an error anywhere else was stopped outside the bridge (an abort at the
    /// machine), not completed. `None`: not checked.
    pub end_position: Option<[f64; 3]>,
}

/// How far from the program's end position, in machine units, LinuxCNC may stand and the
/// program still count as run to its end: LinuxCNC reaches its targets to well under a
/// micrometre (its positions are doubles); the status reports six decimals.
const END_TOLERANCE: f64 = 1e-4;

impl SessionConfig {
    /// A session for `program` with linuxcncrsh's default passwords, 100 ms polls and 2 s
    /// answers; the machine is not switched on.
    pub fn new(program: impl Into<String>) -> SessionConfig {
        SessionConfig {
            connect_password: "EMC".into(),
            enable_password: "EMCTOO".into(),
            power_on: false,
            program: program.into(),
            poll_interval: Duration::from_millis(100),
            answer_timeout: Duration::from_secs(2),
            end_position: None,
        }
    }
}

/// LinuxCNC's program state (`get program_status`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgramState {
    /// No program running.
    Idle,
    /// Running.
    Running,
    /// Held (feed hold, `set pause`, M0).
    Paused,
}

impl ProgramState {
    /// As LinuxCNC names it.
    pub fn name(self) -> &'static str {
        match self {
            ProgramState::Idle => "IDLE",
            ProgramState::Running => "RUNNING",
            ProgramState::Paused => "PAUSED",
        }
    }
}

/// One status poll's findings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// The program's state.
    pub state: ProgramState,
    /// The program line motion is executing (1-based file line; 0 before the first).
    pub line: u64,
    /// Machine position: X, Z (machine units) and C (degrees).
    pub position: [f64; 3],
}

/// What happened, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// LinuxCNC started running the program.
    Running,
    /// A status poll completed.
    Status(Status),
    /// An error LinuxCNC reported, in its words.
    Error(String),
    /// The session ended; see [`Session::ending`].
    Ended,
}

/// Why a session ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// LinuxCNC ran the program to its end, without an error.
    Completed,
    /// Nothing was run: the server, the machine or the program is not fit to start
    /// (a wrong password, E-stop, a file LinuxCNC cannot open); in words.
    Refused(String),
    /// LinuxCNC stopped the program with an error, in its words, at the line motion had
    /// reached.
    Failed {
        /// LinuxCNC's error.
        error: String,
        /// The line executing when it stopped (1-based; 0 if none had).
        line: u64,
    },
    /// The program was aborted: by the operator through the bridge, or outside it (the
    /// reason says which), at the line motion had reached.
    Aborted {
        /// Why.
        reason: String,
        /// The line executing when it stopped.
        line: u64,
    },
    /// The bridge stopped: the machine is held (`set pause`) at `line`, and LinuxCNC still
    /// has the program open, to resume or abort at the machine.
    Held {
        /// Why.
        reason: String,
        /// The line executing when it held.
        line: u64,
    },
    /// `linuxcncrsh` did not answer a request in time.
    Silent {
        /// The request.
        request: String,
        /// The line last reported.
        line: u64,
    },
}

/// The operator's commands.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// Feed hold (`set pause`).
    Hold,
    /// Resume after a hold (`set resume`).
    Resume,
    /// Abort the program (`set abort`): LinuxCNC stops and forgets it.
    Abort,
    /// Hold the machine and end the session (an interrupted bridge).
    Stop(String),
}

/// What a request is for: its answer's keyword and what the session does with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    Hello,
    EchoOff,
    Verbose,
    Enable,
    GetEstop,
    EstopOff,
    GetMachine,
    MachineOn,
    ModeAuto,
    Open,
    OpenError,
    Run,
    Status,
    Line,
    Position,
    Error,
    Pause,
    Resume,
    Abort,
    /// `get error` after a `NAK`, for LinuxCNC's reason.
    NakReason(Nak),
}

/// Which `set` a `NAK` answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Nak {
    EstopOff,
    MachineOn,
    ModeAuto,
    Open,
    Run,
    Control,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Logging in and checking the machine.
    Preparing,
    /// The program runs (or is held); polling.
    Running,
    /// Over.
    Ended,
}

/// A program run on LinuxCNC; see the module docs.
#[derive(Debug)]
pub struct Session {
    config: SessionConfig,
    phase: Phase,
    /// Requests to send, in order.
    queue: VecDeque<(Step, String)>,
    /// The request in flight, its text and its deadline.
    in_flight: Option<(Step, String, Duration)>,
    /// When the next status poll is due.
    next_poll: Duration,
    /// The status being gathered by the current poll.
    poll: Status,
    last: Status,
    /// The program has been seen running (or held).
    seen_running: bool,
    /// The first error LinuxCNC reported while running.
    error: Option<String>,
    /// Why the bridge ends the run, once it has asked LinuxCNC to abort or hold.
    ending_requested: Option<Ending>,
    input: Vec<u8>,
    events: VecDeque<Event>,
    ending: Option<Ending>,
}

impl Session {
    /// A session that logs in, prepares the machine and runs `config.program`.
    pub fn new(config: SessionConfig) -> Session {
        let mut session = Session {
            phase: Phase::Preparing,
            queue: VecDeque::new(),
            in_flight: None,
            next_poll: Duration::ZERO,
            poll: Status {
                state: ProgramState::Idle,
                line: 0,
                position: [0.0; 3],
            },
            last: Status {
                state: ProgramState::Idle,
                line: 0,
                position: [0.0; 3],
            },
            seen_running: false,
            error: None,
            ending_requested: None,
            input: Vec::new(),
            events: VecDeque::new(),
            ending: None,
            config,
        };
        let hello = format!("hello {} whirl 1.0", session.config.connect_password);
        let enable = format!("set enable {}", session.config.enable_password);
        session.push(Step::Hello, hello);
        // Verbose first, so that every `set` is answered (`set echo off` included: with
        // verbose off, its only answer would be its echo, if echo was on).
        session.push(Step::Verbose, "set verbose on".into());
        session.push(Step::EchoOff, "set echo off".into());
        session.push(Step::Enable, enable);
        session.push(Step::GetEstop, "get estop".into());
        session
    }

    fn push(&mut self, step: Step, text: String) {
        self.queue.push_back((step, text));
    }

    /// The next request to write, if one is due at `now`: none while one is in flight.
    pub fn transmit(&mut self, now: Duration) -> Option<Vec<u8>> {
        if self.in_flight.is_some() || self.phase == Phase::Ended {
            return None;
        }
        if self.queue.is_empty() && self.phase == Phase::Running && now >= self.next_poll {
            self.next_poll = now + self.config.poll_interval;
            self.push(Step::Status, "get program_status".into());
            self.push(Step::Line, "get program_line".into());
            self.push(Step::Position, "get abs_act_pos".into());
            self.push(Step::Error, "get error".into());
        }
        let (step, text) = self.queue.pop_front()?;
        let bytes = format!("{text}\r\n").into_bytes();
        self.in_flight = Some((step, text, now + self.config.answer_timeout));
        Some(bytes)
    }

    /// When the session next needs the transport's attention without new bytes: an
    /// answer's deadline or the next poll; `None` once it has ended.
    pub fn deadline(&self) -> Option<Duration> {
        match (&self.in_flight, self.phase) {
            (_, Phase::Ended) => None,
            (Some((_, _, deadline)), _) => Some(*deadline),
            (None, _) if !self.queue.is_empty() => Some(Duration::ZERO),
            (None, _) => Some(self.next_poll),
        }
    }

    /// Lets time pass: an answer overdue at `now` ends the session.
    pub fn poll(&mut self, now: Duration) {
        if let Some((_, text, deadline)) = &self.in_flight {
            if now >= *deadline && self.phase != Phase::Ended {
                let request = text.clone();
                self.end(Ending::Silent {
                    request,
                    line: self.last.line,
                });
            }
        }
    }

    /// Bytes from the server.
    pub fn receive(&mut self, bytes: &[u8]) {
        self.input.extend_from_slice(bytes);
        while let Some(end) = self.input.iter().position(|&b| b == b'\n' || b == b'\r') {
            let line: Vec<u8> = self.input.drain(..=end).collect();
            let line = String::from_utf8_lossy(&line[..end]).trim().to_owned();
            if !line.is_empty() {
                self.answer(&line);
            }
        }
    }

    /// The operator's `command`.
    pub fn command(&mut self, command: Command) {
        if self.phase == Phase::Ended {
            return;
        }
        if self.phase == Phase::Preparing {
            // Nothing runs yet: a stop or an abort ends the session before it starts.
            if let Command::Abort | Command::Stop(_) = command {
                let reason = match command {
                    Command::Stop(reason) => reason,
                    _ => "aborted by the operator".into(),
                };
                self.end(Ending::Refused(format!(
                    "{reason} before the program started; nothing ran"
                )));
            }
            return;
        }
        let line = self.last.line;
        match command {
            Command::Hold => self.urgent(Step::Pause, "set pause"),
            Command::Resume => self.urgent(Step::Resume, "set resume"),
            Command::Abort => {
                self.ending_requested = Some(Ending::Aborted {
                    reason: "aborted by the operator".into(),
                    line,
                });
                self.urgent(Step::Abort, "set abort");
            }
            Command::Stop(reason) => {
                self.ending_requested = Some(Ending::Held { reason, line });
                self.urgent(Step::Pause, "set pause");
            }
        }
    }

    /// A control request goes before any poll still queued.
    fn urgent(&mut self, step: Step, text: &str) {
        self.queue.retain(|(s, _)| {
            !matches!(s, Step::Status | Step::Line | Step::Position | Step::Error)
        });
        self.queue.push_front((step, text.into()));
    }

    /// The next event, if any.
    pub fn next_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// Why the session ended, once it has.
    pub fn ending(&self) -> Option<&Ending> {
        self.ending.as_ref()
    }

    /// The last status polled.
    pub fn last_status(&self) -> Status {
        self.last
    }

    fn end(&mut self, ending: Ending) {
        if self.phase == Phase::Ended {
            return;
        }
        self.phase = Phase::Ended;
        self.queue.clear();
        self.in_flight = None;
        self.ending = Some(ending);
        self.events.push_back(Event::Ended);
    }

    fn refuse(&mut self, why: String) {
        self.end(Ending::Refused(why));
    }

    fn answer(&mut self, line: &str) {
        let Some((step, text, _)) = self.in_flight.clone() else {
            return;
        };
        if line == text {
            return; // the server's echo of the request
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let upper: Vec<String> = words.iter().map(|w| w.to_ascii_uppercase()).collect();
        let request: Vec<String> = text
            .split_whitespace()
            .map(str::to_ascii_uppercase)
            .collect();
        let verdict = match (request[0].as_str(), upper.as_slice()) {
            ("HELLO", [h, v, ..]) if h == "HELLO" => Some(v == "ACK"),
            ("SET", [s, name, v]) if s == "SET" && *name == request[1] => Some(v == "ACK"),
            ("GET", [g, name, nak]) if g == "GET" && *name == request[1] && nak == "NAK" => {
                Some(false)
            }
            ("GET", [name, ..]) if *name == request[1] => Some(true),
            _ => None,
        };
        let Some(ack) = verdict else {
            // Not this request's answer: a stray line from the server, skipped.
            return;
        };
        self.in_flight = None;
        let value = words.get(1..).map(|w| w.join(" ")).unwrap_or_default();
        self.step(step, ack, &value);
    }

    fn step(&mut self, step: Step, ack: bool, value: &str) {
        let nak = |session: &mut Session, which: Nak| {
            session
                .queue
                .push_front((Step::NakReason(which), "get error".into()));
        };
        match step {
            Step::Hello if !ack => self.refuse(
                "linuxcncrsh refused the connect password (hello NAK): check \
                 connection.connect_password"
                    .into(),
            ),
            Step::Enable if !ack => self.refuse(
                "linuxcncrsh refused the enable password (set enable NAK): check \
                 connection.enable_password"
                    .into(),
            ),
            Step::Hello | Step::EchoOff | Step::Verbose | Step::Enable => {}
            Step::GetEstop => match (value, self.config.power_on) {
                ("OFF", _) => self.push(Step::GetMachine, "get machine".into()),
                (_, true) => {
                    self.push(Step::EstopOff, "set estop off".into());
                    self.push(Step::GetMachine, "get machine".into());
                }
                (_, false) => self.refuse(
                    "LinuxCNC is in E-stop, and the profile does not let whirl release it \
                     (connection.power_on = false): release it at the machine"
                        .into(),
                ),
            },
            Step::GetMachine => match (value, self.config.power_on) {
                ("ON", _) => self.prepare_program(),
                (_, true) => {
                    self.push(Step::MachineOn, "set machine on".into());
                    self.prepare_program();
                }
                (_, false) => self.refuse(
                    "the LinuxCNC machine is off, and the profile does not let whirl switch it \
                     on (connection.power_on = false): switch it on at the machine"
                        .into(),
                ),
            },
            Step::EstopOff if !ack => nak(self, Nak::EstopOff),
            Step::MachineOn if !ack => nak(self, Nak::MachineOn),
            Step::ModeAuto if !ack => nak(self, Nak::ModeAuto),
            Step::Open if !ack => nak(self, Nak::Open),
            Step::Run if !ack => nak(self, Nak::Run),
            Step::Pause | Step::Resume | Step::Abort if !ack => nak(self, Nak::Control),
            Step::EstopOff | Step::MachineOn | Step::ModeAuto | Step::Open => {}
            Step::OpenError => {
                if value == "OK" {
                    self.push(Step::Run, "set run".into());
                } else {
                    self.refuse(format!("LinuxCNC cannot open the program: {value}"));
                }
            }
            Step::Run => {
                self.phase = Phase::Running;
                self.events.push_back(Event::Running);
            }
            Step::Status => {
                self.poll.state = match value {
                    "RUNNING" => ProgramState::Running,
                    "PAUSED" => ProgramState::Paused,
                    _ => ProgramState::Idle,
                };
            }
            Step::Line => self.poll.line = value.parse().unwrap_or(self.poll.line),
            Step::Position => {
                let numbers: Vec<f64> = value
                    .split_whitespace()
                    .filter_map(|w| w.parse().ok())
                    .collect();
                if let [x, _, z, _, _, c, ..] = numbers[..] {
                    self.poll.position = [x, z, c];
                }
            }
            Step::Error => {
                if value != "OK" {
                    self.error.get_or_insert_with(|| value.to_owned());
                    self.events.push_back(Event::Error(value.to_owned()));
                }
                self.polled();
            }
            Step::Pause | Step::Resume => {
                if let Some(held @ Ending::Held { .. }) = self.ending_requested.clone() {
                    self.end(held);
                }
            }
            Step::Abort => {}
            Step::NakReason(which) => self.nak_reason(which, value),
        }
    }

    /// Mode, program, its open error: then run.
    fn prepare_program(&mut self) {
        let open = format!("set open {}", self.config.program);
        self.push(Step::ModeAuto, "set mode auto".into());
        self.push(Step::Open, open);
        self.push(Step::OpenError, "get error".into());
    }

    fn nak_reason(&mut self, which: Nak, error: &str) {
        let words = if error == "OK" {
            "LinuxCNC gave no reason".to_owned()
        } else {
            format!("LinuxCNC: {error}")
        };
        match which {
            Nak::EstopOff => self.refuse(format!("LinuxCNC would not leave E-stop ({words})")),
            Nak::MachineOn => self.refuse(format!("LinuxCNC would not switch on ({words})")),
            Nak::ModeAuto => self.refuse(format!("LinuxCNC would not go to auto mode ({words})")),
            Nak::Open => self.refuse(format!("LinuxCNC would not open the program ({words})")),
            Nak::Run => self.refuse(format!("LinuxCNC would not run the program ({words})")),
            Nak::Control => {
                let line = self.last.line;
                self.end(Ending::Failed {
                    error: format!("LinuxCNC refused the operator's command ({words})"),
                    line,
                });
            }
        }
    }

    /// A poll is complete: report it, and end the run once LinuxCNC is idle again.
    fn polled(&mut self) {
        let status = self.poll;
        self.last = status;
        self.events.push_back(Event::Status(status));
        if status.state != ProgramState::Idle {
            self.seen_running = true;
            return;
        }
        // `set run` is acknowledged before the task switches state: an idle program that
        // was never seen running, with no error and no line, has not started yet.
        if !self.seen_running && self.error.is_none() && status.line == 0 {
            return;
        }
        let ending = match (self.ending_requested.take(), self.error.take()) {
            (Some(requested), _) => requested,
            (None, Some(error)) => Ending::Failed {
                error,
                line: status.line,
            },
            (None, None) => match self.config.end_position {
                Some(end)
                    if (0..3).any(|k| (status.position[k] - end[k]).abs() > END_TOLERANCE) =>
                {
                    Ending::Aborted {
                        reason: format!(
                            "LinuxCNC went idle at X {:.4} Z {:.4} C {:.4}, not at the program's \
                             end (X {:.4} Z {:.4} C {:.4}), with no error: it was stopped outside \
                             whirl",
                            status.position[0],
                            status.position[1],
                            status.position[2],
                            end[0],
                            end[1],
                            end[2]
                        ),
                        line: status.line,
                    }
                }
                _ => Ending::Completed,
            },
        };
        self.end(ending);
    }
}

#[cfg(test)]
mod tests;
