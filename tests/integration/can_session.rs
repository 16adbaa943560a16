//! whirl's CANopen master against the simulator's drives, end to end in one thread: the
//! session's frames through whirl's slcan encoder as bytes into the simulated adapter, the
//! adapter's bytes through whirl's decoder back to the session, simulated time stepped
//! here a millisecond at a time. The two sides share no code, so each checks the other's
//! reading of CiA 301 and CiA 402; the bus records what the drives executed, which is
//! checked against the planned path.

use std::time::Duration;

use crate::util;
use whirl::config::machine::Axis;
use whirl::config::machine::MachineProfile;
use whirl::judge::simulator::machine;
use whirl::post::setpoints::{sample, SampleConfig, SetPoints};
use whirl::program::{Move, Position, Program};
use whirl::protocol::canopen::session::{Event, Phase, Session, SessionConfig, StopReason};
use whirl::protocol::canopen::slcan::{Bitrate, Command, Decoder, Received};
use whirl_sim::canopen::{Bus, BusConfig, BusEvent, PowerState};
use whirl_sim::{ExecutedBlock, Position as SimPosition};

const MS: Duration = Duration::from_millis(1);
/// The SYNC period.
const PERIOD: Duration = Duration::from_millis(4);
/// Drive counts: 0.1 µm on X and Z, a 2²⁰-count encoder on C (not a whole number a
/// degree).
const SCALE: [f64; 3] = [10_000.0, 10_000.0, 1_048_576.0 / 360.0];

/// The first 200 blocks of the double-start example as planned for the simulated machine
/// (lead-in, M3, plunge, linked moves), then its lead-out (the blocks after the last
/// linked move: retract, M5).
fn program() -> Program {
    util::short_double_start(&MachineProfile::builtin_sim().unwrap())
}

fn setpoints(program: &Program) -> SetPoints {
    let profile = MachineProfile::builtin_sim().unwrap();
    let config =
        SampleConfig::for_machine(&profile, PERIOD, SCALE, Some(Duration::from_millis(500)));
    sample(program, Position::known(0.0, 0.0, 0.0), &config).unwrap()
}

fn session_config() -> SessionConfig {
    SessionConfig {
        boot_wait: Duration::from_millis(200),
        following_error_window: 20_000,
        ..SessionConfig::default()
    }
}

/// The session and the simulated bus, wired through the slcan codecs.
struct Rig {
    session: Session,
    bus: Bus,
    decoder: Decoder,
    now: Duration,
    events: Vec<Event>,
    executed: Vec<ExecutedBlock>,
}

impl Rig {
    /// The simulated machine's drives at the origin, `adjust`ed; the adapter opened at
    /// 1 Mbit/s (after the drives booted, so their boot-up messages went unheard).
    fn new(setpoints: SetPoints, adjust: impl FnOnce(&mut BusConfig)) -> Rig {
        let profile = MachineProfile::builtin_sim().unwrap();
        let mut config =
            BusConfig::for_machine(&machine(&profile), SCALE, PERIOD, SimPosition::default());
        adjust(&mut config);
        let mut bus = Bus::new(config).unwrap();
        let mut open = Command::SetBitrate(Bitrate::M1).encode();
        open.extend(Command::Open.encode());
        bus.receive(&open);
        let mut decoder = Decoder::new();
        assert_eq!(
            decoder.feed(&bus.take_output()),
            [Ok(Received::Ok), Ok(Received::Ok)]
        );
        Rig {
            session: Session::new(session_config(), setpoints).unwrap(),
            bus,
            decoder,
            now: Duration::ZERO,
            events: Vec::new(),
            executed: Vec::new(),
        }
    }

    /// The adapter's bytes to the session.
    fn hear(&mut self) {
        for item in self.decoder.feed(&self.bus.take_output()) {
            match item.expect("the adapter's lines decode") {
                Received::Frame { frame, .. } => self.session.receive(&frame, self.now),
                Received::Error => panic!("the adapter refused a command"),
                Received::Ok | Received::Transmitted { .. } => {}
            }
        }
    }

    fn step(&mut self) {
        self.now += MS;
        self.bus.advance(MS);
        self.hear();
        let bytes: Vec<u8> = self
            .session
            .poll(self.now)
            .into_iter()
            .flat_map(|frame| Command::Transmit(frame).encode())
            .collect();
        self.bus.receive(&bytes);
        self.hear();
        self.events.extend(self.session.events());
        for event in self.bus.take_events() {
            if let BusEvent::Executed(block) = event {
                self.executed.push(block);
            }
        }
    }

    fn run_until(&mut self, done: impl Fn(&Session) -> bool) {
        while !done(&self.session) {
            assert!(
                self.now < Duration::from_secs(120),
                "stuck in {:?}",
                self.session.phase()
            );
            self.step();
        }
    }

    fn run_to_end(&mut self) {
        self.run_until(|s| matches!(s.phase(), Phase::Finished | Phase::Stopped));
    }

    fn stopped(&self) -> Option<&StopReason> {
        self.events.iter().find_map(|e| match e {
            Event::Stopped { reason } => Some(reason),
            _ => None,
        })
    }

    fn enabled_syncs(&self) -> usize {
        self.events
            .iter()
            .find_map(|e| match e {
                Event::Enabled { syncs } => Some(*syncs as usize),
                _ => None,
            })
            .expect("the drives were enabled")
    }
}

fn counts(p: SimPosition) -> [i64; 3] {
    let a = p.to_array();
    std::array::from_fn(|k| (a[k] * SCALE[k]).round() as i64)
}

/// The program's straight moves in its continuous frame, mm and degrees (moves that go
/// nowhere left out).
fn segments(program: &Program) -> Vec<([f64; 3], [f64; 3])> {
    program
        .steps(Position::known(0.0, 0.0, 0.0))
        .filter(|s| s.action.target().is_some())
        .map(|s| {
            let at = |p: Position| Axis::ALL.map(|a| p.get(a).unwrap());
            (at(s.from), at(s.to))
        })
        .filter(|(a, b)| a != b)
        .collect()
}

/// Whether `p` lies on the segment a→b within `tolerance` counts on every axis.
fn on_segment(p: [f64; 3], (a, b): ([f64; 3], [f64; 3]), tolerance: f64) -> bool {
    // The fraction along the axis that moves most, in counts; the others must agree.
    let lead = (0..3)
        .max_by(|&i, &j| {
            ((b[i] - a[i]) * SCALE[i])
                .abs()
                .total_cmp(&((b[j] - a[j]) * SCALE[j]).abs())
        })
        .unwrap();
    let f = ((p[lead] - a[lead]) / (b[lead] - a[lead])).clamp(0.0, 1.0);
    (0..3).all(|i| ((p[i] - (a[i] + f * (b[i] - a[i]))) * SCALE[i]).abs() <= tolerance)
}

#[test]
fn a_planned_program_runs_on_three_simulated_drives_set_point_by_set_point() {
    let program = program();
    let sp = setpoints(&program);
    let mut rig = Rig::new(sp.clone(), |_| {});
    rig.run_to_end();
    assert_eq!(rig.session.phase(), Phase::Finished, "{:?}", rig.stopped());
    assert!(!rig
        .events
        .iter()
        .any(|e| matches!(e, Event::Late { .. } | Event::Stopped { .. })));
    // M3 before the plunge (after the lead-in's rapids), M5 after the retract.
    let m3 = program
        .moves
        .iter()
        .position(|b| matches!(b, Move::SpindleOn { .. }))
        .unwrap();
    assert!(matches!(program.moves[m3 + 1], Move::Feed { .. }));
    let spindle: Vec<&Event> = rig
        .events
        .iter()
        .filter(|e| matches!(e, Event::Spindle { .. }))
        .collect();
    assert_eq!(
        spindle,
        [
            &Event::Spindle {
                block: m3,
                rpm: Some(1500.0)
            },
            &Event::Spindle {
                block: program.moves.len() - 1,
                rpm: None
            }
        ]
    );

    // Every set-point executed once, in order, by the SYNC after it was sent: the bus's
    // block k + 1 after enabling has the set-point's targets and got there.
    let first = rig.enabled_syncs();
    let run = &rig.executed[first..first + sp.points.len()];
    for (k, (block, point)) in run.iter().zip(&sp.points).enumerate() {
        assert_eq!(block.line as usize, first + k + 1);
        assert_eq!(counts(block.target), *point, "set-point {k}");
        assert!(block.completed, "set-point {k}");
    }
    for pair in rig.executed.windows(2) {
        assert_eq!(pair[0].to, pair[1].from);
        assert_eq!(pair[1].start_time, pair[0].end_time);
    }
    // X, Z and C kept together: no axis moved more in a cycle than its max rate allows
    // (plus a count of rounding), and the cycles are the SYNC period apart.
    let profile = MachineProfile::builtin_sim().unwrap();
    let reach: [f64; 3] = std::array::from_fn(|k| {
        profile.max_rate(Axis::ALL[k]) / 60.0 * PERIOD.as_secs_f64() * SCALE[k] + 1.0
    });
    for block in &run[1..] {
        assert!((block.end_time - block.start_time - PERIOD.as_secs_f64()).abs() < 1e-9);
        let (a, b) = (counts(block.from), counts(block.to));
        for k in 0..3 {
            assert!(((b[k] - a[k]).abs() as f64) <= reach[k], "{block:?}");
        }
    }

    // The executed path stays on the planned straight moves, in their order, within the
    // drives' quantization: a count on each axis (half for the move's rounded ends, half
    // for the rounded fraction), and up to one more through the fraction, which the check
    // reads off the most-moving axis, itself rounded.
    let planned = segments(&program);
    let mut at = 0;
    for block in &rig.executed {
        let p = block.to.to_array();
        while !on_segment(p, planned[at], 2.0 + 1e-6) {
            at += 1;
            assert!(
                at < planned.len(),
                "{p:?} is on no planned move after the {at}th"
            );
        }
    }
    assert_eq!(at, planned.len() - 1, "the path reached the last move");
    // It ends where the program does, the drives disabled.
    assert_eq!(counts(rig.executed.last().unwrap().to), sp.end());
    assert_eq!(sp.end(), counts(SimPosition::from_array(planned[at].1)));
    for drive in rig.bus.drives() {
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    }
    assert_eq!(rig.session.progress(), (sp.points.len(), sp.points.len()));
}

#[test]
fn a_pulled_cable_stops_the_job_with_the_node_named() {
    let sp = setpoints(&program());
    let mut rig = Rig::new(sp.clone(), |_| {});
    rig.run_until(|s| s.progress().0 == 1000);
    let pulled_at = rig.now;
    assert!(rig.bus.pull_cable(3));
    rig.run_to_end();
    let reason = rig.stopped().expect("stopped");
    assert!(
        matches!(reason, StopReason::HeartbeatLost { node, axis: Axis::C, .. } if node.get() == 3)
    );
    assert!(reason
        .to_string()
        .starts_with("node 3 (C) heartbeat lost: none for 150ms"));
    let stopped_at = rig.now;
    assert!(
        stopped_at - pulled_at < Duration::from_millis(260),
        "{:?}",
        stopped_at - pulled_at
    );
    // X and Z were stopped and disabled; C, unheard, is named unconfirmed.
    assert_eq!(
        rig.events.last(),
        Some(&Event::Halted {
            unconfirmed: vec![rig.session.drives()[2].node]
        })
    );
    for drive in &rig.bus.drives()[..2] {
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    }
    // The job did not run on: far fewer set-points than the path has.
    let (sent, total) = rig.session.progress();
    assert!(sent < 1100 && sent < total);
}

#[test]
fn a_following_error_stops_the_job_with_the_emergency_code_named() {
    // C's drive can turn 300 counts a cycle where the linked moves ask about 700: it
    // falls behind until its 20 000-count window trips.
    let sp = setpoints(&program());
    let mut rig = Rig::new(sp, |config| config.drives[2].max_step = 300);
    rig.run_to_end();
    let reason = rig.stopped().expect("stopped");
    assert!(matches!(
        reason,
        StopReason::Emergency {
            axis: Axis::C,
            code: 0x8611,
            ..
        }
    ));
    assert_eq!(
        reason.to_string(),
        "node 3 (C) emergency 0x8611: following error"
    );
    // The emergency as the bus sent it, error register bit 0.
    assert!(rig
        .events
        .iter()
        .any(|e| matches!(e, Event::Emergency(m) if m.code == 0x8611 && m.register == 1)));
    // C stays faulted for someone to look at; X and Z are disabled.
    let drives = rig.bus.drives();
    assert_eq!(drives[2].power_state(), PowerState::Fault);
    assert_eq!(drives[0].power_state(), PowerState::SwitchOnDisabled);
    assert_eq!(drives[1].power_state(), PowerState::SwitchOnDisabled);
    assert_eq!(
        rig.events.last(),
        Some(&Event::Halted {
            unconfirmed: vec![]
        })
    );
}
