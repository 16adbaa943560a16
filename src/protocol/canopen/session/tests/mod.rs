//! The session's unit tests, against three simulated drives (`whirl_sim::canopen`) on
//! one bus in simulated time: the fixtures (`Bench` and the set-points it runs) here,
//! the tests by topic in the sibling files.

mod configuration;
mod feed_override;
mod gentle;
mod hold;
mod objects;
mod run;
mod stops;

use super::*;
use crate::post::setpoints::{sample, SampleConfig};
use crate::program::{Move, Position, Program};
use whirl_sim::canopen::{
    Drive as SimDrive, DriveConfig, DriveEvent as SimEvent, Frame, PowerState as SimPower,
};

const MS: Duration = Duration::from_millis(1);
const PERIOD: Duration = Duration::from_millis(2);

fn node(id: u8) -> NodeId {
    NodeId::new(id).unwrap()
}

fn std(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

/// Counts a mm (X, Z) and a degree (C).
const SCALE: [f64; 3] = [1000.0, 1000.0, 100.0];

/// From `start`: M3, two linked moves, a rapid back in X, M5: 170 ms at 2 ms, 85
/// cycles.
fn setpoints(start: Position) -> SetPoints {
    let [x, z, c] = Axis::ALL.map(|a| start.get(a).unwrap());
    let program = Program {
        moves: vec![
            Move::SpindleOn { rpm: 1000.0 },
            Move::Linked {
                x: x + 1.0,
                z: z + 0.5,
                c: c + 60.0,
                minutes: 0.001,
            },
            Move::Linked {
                x: x + 2.0,
                z: z + 1.0,
                c: c + 120.0,
                minutes: 0.001,
            },
            Move::Rapid {
                x: Some(x),
                z: None,
                c: None,
            },
            Move::SpindleOff,
        ],
    };
    let config = SampleConfig {
        period: PERIOD,
        counts_per_unit: SCALE,
        max_rate: [3000.0, 3000.0, 72_000.0],
        spin_up: Some(10 * MS),
        dialect: crate::config::machine::Dialect::LinuxCnc,
    };
    sample(&program, start, &config).unwrap()
}

fn config() -> SessionConfig {
    SessionConfig {
        boot_wait: 50 * MS,
        sdo_timeout: 20 * MS,
        heartbeat_ms: 10,
        heartbeat_timeout: 30 * MS,
        following_error_window: 1000,
        start_tolerance: 0,
        enable_timeout: 100 * MS,
        settle_window: 0,
        settle_timeout: 100 * MS,
        disable_timeout: 100 * MS,
        ..SessionConfig::default()
    }
}

type Tamper = Box<dyn FnMut(CanFrame) -> Option<CanFrame>>;

/// A SYNC's time and the (controlword, target) sent to nodes 1-3 before it.
type Cycle = (Duration, [Option<(u16, i32)>; 3]);

/// The session and three simulated drives on one bus, in simulated time.
struct Bench {
    session: Session,
    drives: Vec<SimDrive>,
    now: Duration,
    /// Applied to every frame from the drives to the session.
    tamper: Option<Tamper>,
    /// A drive cut off the bus (index 0-2).
    pulled: Option<usize>,
    sent: Vec<(Duration, CanFrame)>,
    /// The frames the session received (after tampering).
    received: Vec<(Duration, CanFrame)>,
    events: Vec<Event>,
}

impl Bench {
    /// Drives at 0 (X, Z, C on nodes 1-3) with `configs` applied; their boot-up
    /// messages reach the session if `announced`.
    fn new(
        setpoints: SetPoints,
        config: SessionConfig,
        drives: [DriveConfig; 3],
        announced: bool,
    ) -> Bench {
        let mut bench = Bench {
            session: Session::new(config, setpoints).unwrap(),
            drives: drives.map(|c| SimDrive::new(c).unwrap()).into(),
            now: Duration::ZERO,
            tamper: None,
            pulled: None,
            sent: Vec::new(),
            received: Vec::new(),
            events: Vec::new(),
        };
        if !announced {
            bench.drives.iter_mut().for_each(|d| {
                d.take_output();
            });
        }
        bench.route();
        bench
    }

    fn plain() -> Bench {
        Bench::with(Operation::CyclicSynchronousPosition)
    }

    /// As [`Bench::plain`], the drives run in `operation`.
    fn with(operation: Operation) -> Bench {
        let drives = [1, 2, 3].map(DriveConfig::new);
        let config = SessionConfig {
            operation,
            ..config()
        };
        Bench::new(
            setpoints(Position::known(0.0, 0.0, 0.0)),
            config,
            drives,
            false,
        )
    }

    /// Moves the drives' frames until the bus is quiet.
    fn route(&mut self) {
        loop {
            let mut on_bus = Vec::new();
            for (k, drive) in self.drives.iter_mut().enumerate() {
                let out = drive.take_output();
                if self.pulled != Some(k) {
                    on_bus.extend(out.into_iter().map(|f| (k, f)));
                }
            }
            if on_bus.is_empty() {
                break;
            }
            for (sender, f) in on_bus {
                for (k, drive) in self.drives.iter_mut().enumerate() {
                    if k != sender && self.pulled != Some(k) {
                        drive.receive(&f);
                    }
                }
                let frame = CanFrame::standard(f.id as u16, &f.data).unwrap();
                let frame = match self.tamper.as_mut() {
                    Some(tamper) => tamper(frame),
                    None => Some(frame),
                };
                if let Some(frame) = frame {
                    self.received.push((self.now, frame));
                    self.session.receive(&frame, self.now);
                }
            }
        }
        self.events.extend(self.session.events());
    }

    fn step(&mut self, dt: Duration) {
        self.drives.iter_mut().for_each(|d| d.advance(dt));
        self.now += dt;
        self.route();
        for frame in self.session.poll(self.now) {
            self.sent.push((self.now, frame));
            let f = Frame::data(frame.id().raw() as u16, frame.data());
            for (k, drive) in self.drives.iter_mut().enumerate() {
                if self.pulled != Some(k) {
                    drive.receive(&f);
                }
            }
        }
        self.route();
    }

    fn run_until(&mut self, done: impl Fn(&Session) -> bool) {
        while !done(&self.session) {
            assert!(
                self.now < Duration::from_secs(2),
                "stuck in {:?}",
                self.session.phase()
            );
            self.step(MS);
        }
    }

    fn run_to_end(&mut self) {
        self.run_until(|s| matches!(s.phase(), Phase::Finished | Phase::Stopped));
    }

    /// The stop reason reported, if any.
    fn stopped(&self) -> Option<&StopReason> {
        self.events.iter().find_map(|e| match e {
            Event::Stopped { reason } => Some(reason),
            _ => None,
        })
    }

    fn halted(&self) -> Option<&Vec<NodeId>> {
        self.events.iter().find_map(|e| match e {
            Event::Halted { unconfirmed } => Some(unconfirmed),
            _ => None,
        })
    }

    /// Each SYNC's time with the (controlword, target) sent to nodes 1-3 before it.
    fn cycles(&self) -> Vec<Cycle> {
        let mut cycles = Vec::new();
        let mut current = [None; 3];
        for (time, frame) in &self.sent {
            let id = frame.id().raw();
            if id == 0x080 {
                cycles.push((*time, std::mem::take(&mut current)));
            } else if (0x201..=0x203).contains(&id) {
                let d = frame.data();
                let word = u16::from_le_bytes([d[0], d[1]]);
                let target = i32::from_le_bytes([d[2], d[3], d[4], d[5]]);
                current[id as usize - 0x201] = Some((word, target));
            }
        }
        cycles
    }

    /// The statuswords of node `id`'s TPDO1s, with when the session got them.
    fn statuswords(&self, id: u16) -> Vec<(Duration, u16)> {
        self.received
            .iter()
            .filter(|(_, f)| f.id().raw() == u32::from(0x180 + id))
            .map(|(t, f)| (*t, u16::from_le_bytes([f.data()[0], f.data()[1]])))
            .collect()
    }

    /// The configuration's SDO requests to node 1, in order.
    fn sdo_requests(&self) -> Vec<[u8; 8]> {
        self.sent
            .iter()
            .filter(|(_, f)| f.id().raw() == 0x601)
            .map(|(_, f)| f.data().try_into().unwrap())
            .collect()
    }

    fn enabled_syncs(&self) -> usize {
        self.events
            .iter()
            .find_map(|e| match e {
                Event::Enabled { syncs } => Some(*syncs as usize),
                _ => None,
            })
            .expect("enabled")
    }
}

/// Replaces node `id`'s TPDO1 statusword with `word`.
fn statusword(id: u16, word: u16) -> Tamper {
    Box::new(move |f: CanFrame| {
        if f.id().raw() == u32::from(0x180 + id) {
            let mut data = f.data().to_vec();
            data[..2].copy_from_slice(&word.to_le_bytes());
            return Some(std(f.id().raw() as u16, &data));
        }
        Some(f)
    })
}
