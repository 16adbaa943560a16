//! Tests of the three-drive bus, kept apart from it for length: the executed path, travel
//! limits and the guard, the pulled cable, the clock locked to SYNC and the event log.

use super::*;
use crate::canopen::PowerState;
use crate::guard::Measured;
use crate::machine::Machine;

const MS: Duration = Duration::from_millis(1);

fn machine() -> Machine {
    crate::machine::test_machines::sim_default()
}

/// 10 000 counts a mm, 1000 a degree, a 4 ms cycle, at the origin.
fn config() -> BusConfig {
    BusConfig::for_machine(
        &machine(),
        [10_000.0, 10_000.0, 1000.0],
        4 * MS,
        Position::default(),
    )
}

/// An slcan transmit command.
fn t(id: u16, data: &[u8]) -> String {
    let mut text = format!("t{id:03X}{}", data.len());
    for byte in data {
        text.push_str(&format!("{byte:02X}"));
    }
    text.push('\r');
    text
}

fn host(bus: &mut Bus, text: &str) -> String {
    bus.receive(text.as_bytes());
    String::from_utf8(bus.take_output()).unwrap()
}

fn rpdo(node: u16, word: u16, target: i32) -> String {
    let mut data = word.to_le_bytes().to_vec();
    data.extend_from_slice(&target.to_le_bytes());
    t(0x200 + node, &data)
}

/// One cycle: RPDO1 to each node with `targets`, then SYNC, `dt` after the last.
fn cycle(bus: &mut Bus, word: u16, targets: [i32; 3], dt: Duration) -> String {
    bus.advance(dt);
    let mut text: String = (0..3)
        .map(|k| rpdo(k as u16 + 1, word, targets[k]))
        .collect();
    text.push_str(&t(0x080, &[]));
    host(bus, &text)
}

/// Channel open, nodes started, CSP, walked to Operation enabled at their positions.
fn enabled(config: BusConfig) -> Bus {
    let start: [i32; 3] = std::array::from_fn(|k| config.drives[k].position);
    let mut bus = Bus::new(config).unwrap();
    assert_eq!(host(&mut bus, "S8\rO\r"), "\r\r");
    host(&mut bus, &t(0x000, &[0x01, 0x00]));
    for node in 1..=3 {
        host(
            &mut bus,
            &t(0x600 + node, &[0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]),
        );
    }
    for word in [0x06, 0x07, 0x0F] {
        cycle(&mut bus, word, start, 4 * MS);
    }
    assert!(bus
        .drives()
        .iter()
        .all(|d| d.power_state() == PowerState::OperationEnabled));
    bus.take_events();
    bus
}

fn executed(events: &[BusEvent]) -> Vec<&ExecutedBlock> {
    events
        .iter()
        .filter_map(|e| match e {
            BusEvent::Executed(block) => Some(block),
            _ => None,
        })
        .collect()
}

#[test]
fn for_machine_sets_speed_travel_and_start() {
    let config = BusConfig::for_machine(
        &machine(),
        [10_000.0, 10_000.0, 1000.0],
        4 * MS,
        Position::from_array([10.0, -2.5, 700_000.0]),
    );
    let [x, z, c] = &config.drives;
    // 50 mm/s for 4 ms at 10 000 counts a mm: 2000 counts, plus one of rounding;
    // C 1200 deg/s: 4800 + 1.
    assert_eq!((x.max_step, z.max_step, c.max_step), (2001, 2001, 4801));
    assert_eq!(x.software_limits, Some((-50_000, 1_600_000)));
    assert_eq!(z.software_limits, Some((-3_000_000, 3_000_000)));
    assert_eq!(c.software_limits, None);
    assert_eq!((x.node, z.node, c.node), (1, 2, 3));
    assert_eq!((x.position, z.position), (100_000, -25_000));
    // 7·10⁸ counts fit; the drive holds any start's low 32 bits.
    assert_eq!(c.position, 700_000_000);
    assert_eq!(x.heartbeat_ms, 0);
}

#[test]
fn each_sync_is_an_executed_straight_move() {
    let mut bus = enabled(config());
    // 12 ms since the last SYNC (at 12 ms): X 1000 counts (0.1 mm), C 4000 (4°).
    let answer = cycle(&mut bus, 0x0F, [1000, 0, 4000], 12 * MS);
    // Each drive's TPDO1: statusword 0x1237, its position.
    assert!(answer.starts_with("z\rz\rz\rz\rt1816371"), "{answer}");
    let events = bus.take_events();
    let blocks = executed(&events);
    assert_eq!(blocks.len(), 1);
    let block = blocks[0];
    assert_eq!(block.line, 4, "the fourth SYNC");
    assert_eq!(block.n, None);
    assert_eq!(block.kind, MoveKind::InverseTime);
    assert_eq!(block.from, Position::default());
    assert_eq!(block.to, Position::from_array([0.1, 0.0, 4.0]));
    assert_eq!(block.target, block.to);
    assert!(block.completed);
    assert_eq!((block.start_time, block.end_time), (0.012, 0.024));
    // Constant speed over the cycle: half way at half time.
    let middle = block.position_at(0.018);
    assert!((middle.c - 2.0).abs() < 1e-9 && (middle.x - 0.05).abs() < 1e-12);
    // A target beyond one cycle's reach (2001 counts): the block shows where the drive
    // got, not completed, and the next one goes on from there.
    cycle(&mut bus, 0x0F, [6000, 0, 4000], 4 * MS);
    cycle(&mut bus, 0x0F, [6000, 0, 4000], 4 * MS);
    let events = bus.take_events();
    let blocks = executed(&events);
    assert_eq!(blocks[0].to.x, 0.3001);
    assert_eq!(blocks[0].target.x, 0.6);
    assert!(!blocks[0].completed);
    assert_eq!(blocks[1].from, blocks[0].to);
    assert_eq!(blocks[1].to.x, 0.5002);
    assert_eq!(blocks[1].line, 6);
}

#[test]
fn c_counts_on_past_the_32_bit_range() {
    let mut config = config();
    config.drives[2].position = i32::MAX - 1000;
    let mut bus = enabled(config);
    let start = f64::from(i32::MAX - 1000) / 1000.0;
    // 3000 counts on, past i32::MAX: the drive's counter wraps, the path does not.
    let targets = [0, 0, (i32::MAX - 1000).wrapping_add(3000)];
    assert!(targets[2] < 0);
    cycle(&mut bus, 0x0F, targets, 4 * MS);
    let events = bus.take_events();
    let block = executed(&events)[0];
    assert_eq!(block.from.c, start);
    assert!((block.to.c - (start + 3.0)).abs() < 1e-9, "{}", block.to.c);
    assert!(block.completed);
}

#[test]
fn a_target_beyond_the_travel_faults_that_drive_and_stops_the_others() {
    let mut bus = enabled(config());
    // X to 160.0001 mm, one count past its travel (and within one cycle's reach).
    let answer = cycle(&mut bus, 0x0F, [1_600_001, 0, 0], 4 * MS);
    assert_eq!(bus.drives()[0].position(), 0, "it did not move");
    for drive in bus.drives() {
        assert_eq!(drive.power_state(), PowerState::Fault);
    }
    // The cause first, then the chain: EMCY 8612h from node 1, 9000h from 2 and 3.
    let emcy: Vec<&str> = answer
        .split('\r')
        .filter(|line| line.starts_with("t08"))
        .collect();
    assert_eq!(
        emcy,
        [
            "t08181286010000000000",
            "t08280090010000000000",
            "t08380090010000000000"
        ]
    );
    let faults: Vec<(u8, u16)> = bus
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            BusEvent::Drive {
                node,
                event: DriveEvent::Fault { code, .. },
            } => Some((node, code)),
            _ => None,
        })
        .collect();
    assert_eq!(faults, [(1, 0x8612), (2, 0x9000), (3, 0x9000)]);
    // Up to the end of the travel is fine.
    let near_the_end = BusConfig::for_machine(
        &machine(),
        [10_000.0, 10_000.0, 1000.0],
        4 * MS,
        Position::from_array([159.9, 0.0, 0.0]),
    );
    let mut bus = enabled(near_the_end);
    cycle(&mut bus, 0x0F, [1_600_000, 0, 0], 4 * MS);
    assert_eq!(bus.drives()[0].power_state(), PowerState::OperationEnabled);
    assert_eq!(bus.drives()[0].position(), 1_600_000);
}

/// A guard that breaches once X passes `max_x` mm, and at program end if `end_breach`;
/// its measure counts the blocks it saw.
#[derive(Debug)]
struct Fence {
    max_x: f64,
    end_breach: bool,
    seen: usize,
}

impl Guard for Fence {
    fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach> {
        self.seen += 1;
        if block.to.x > self.max_x {
            return Err(Breach {
                message: format!("X {} beyond {}", block.to.x, self.max_x),
            });
        }
        Ok(())
    }

    fn program_end(&mut self) -> Result<(), Breach> {
        if self.end_breach {
            return Err(Breach {
                message: "left open".into(),
            });
        }
        Ok(())
    }

    fn measured(&self) -> Measured {
        Measured {
            points: self.seen,
            ..Measured::default()
        }
    }
}

#[test]
fn a_guard_breach_faults_every_drive() {
    let mut bus = enabled(config());
    bus.set_guard(Box::new(Fence {
        max_x: 0.15,
        end_breach: true,
        seen: 0,
    }));
    cycle(&mut bus, 0x0F, [1000, 0, 0], 4 * MS);
    assert!(bus
        .drives()
        .iter()
        .all(|d| d.power_state() == PowerState::OperationEnabled));
    let answer = cycle(&mut bus, 0x0F, [2000, 0, 0], 4 * MS);
    // EMCY FF64h from all three, after the cycle's TPDOs.
    for node in 1..=3 {
        assert!(
            answer.contains(&format!("t08{node}864FF010000000000")),
            "{answer}"
        );
    }
    let events = bus.take_events();
    assert!(events.contains(&BusEvent::Breach {
        time: 0.02,
        breach: Breach {
            message: "X 0.2 beyond 0.15".into()
        }
    }));
    assert!(bus
        .drives()
        .iter()
        .all(|d| d.power_state() == PowerState::Fault));
    // The guard sees nothing more, and program end does not ask it again.
    cycle(&mut bus, 0x0F, [2000, 0, 0], 4 * MS);
    assert_eq!(bus.guard().unwrap().measured().points, 2);
    assert_eq!(bus.program_end(), Ok(()));
}

#[test]
fn program_end_settles_the_guard() {
    let mut bus = enabled(config());
    assert_eq!(bus.program_end(), Ok(()), "no guard, nothing to settle");
    bus.set_guard(Box::new(Fence {
        max_x: 1.0,
        end_breach: false,
        seen: 0,
    }));
    assert_eq!(bus.program_end(), Ok(()));
    bus.set_guard(Box::new(Fence {
        max_x: 1.0,
        end_breach: true,
        seen: 0,
    }));
    let breach = Breach {
        message: "left open".into(),
    };
    assert_eq!(bus.program_end(), Err(breach));
    assert!(bus
        .drives()
        .iter()
        .all(|d| d.power_state() == PowerState::Fault));
    assert!(String::from_utf8(bus.take_output())
        .unwrap()
        .contains("t081864FF010000000000"));
}

#[test]
fn a_pulled_cable_silences_a_drive() {
    let mut bus = Bus::new(config()).unwrap();
    host(&mut bus, "S8\rO\r");
    for node in 1..=3 {
        // 1017h = 10 ms.
        host(
            &mut bus,
            &t(0x600 + node, &[0x2B, 0x17, 0x10, 0, 10, 0, 0, 0]),
        );
    }
    bus.advance(10 * MS);
    assert_eq!(
        String::from_utf8(bus.take_output()).unwrap(),
        "t70117F\rt70217F\rt70317F\r"
    );
    assert!(bus.pull_cable(3));
    assert!(!bus.pull_cable(9));
    bus.advance(10 * MS);
    assert_eq!(
        String::from_utf8(bus.take_output()).unwrap(),
        "t70117F\rt70217F\r"
    );
    // Nor does it hear anything: an NMT start leaves it Pre-operational.
    host(&mut bus, &t(0x000, &[0x01, 0x00]));
    assert_eq!(
        bus.drives()[0].nmt_state(),
        crate::canopen::NmtState::Operational
    );
    assert_eq!(
        bus.drives()[2].nmt_state(),
        crate::canopen::NmtState::PreOperational
    );
    assert_eq!(bus.now(), 20 * MS);
}

/// The SDO download of 60C2h on every node: `value` × 10^`index` s.
fn set_period(bus: &mut Bus, value: u8, index: i8) {
    for node in 1..=3 {
        for (sub, byte) in [(1, value), (2, index as u8)] {
            let answer = host(
                bus,
                &t(0x600 + node, &[0x2F, 0xC2, 0x60, sub, byte, 0, 0, 0]),
            );
            let ok = t(0x580 + node, &[0x60, 0xC2, 0x60, sub, 0, 0, 0, 0]);
            assert_eq!(answer, format!("z\r{ok}"));
        }
    }
}

#[test]
fn a_clock_locked_to_sync_runs_one_period_a_cycle() {
    let mut bus = enabled(config());
    set_period(&mut bus, 4, -3);
    bus.lock_clock_to_sync();
    let (t0, syncs) = (bus.now(), bus.syncs());
    let period = 4 * MS;
    // No advance between SYNCs: each SYNC is the time, 1000 counts (0.1 mm) of X each.
    for k in 1..=10 {
        let answer = host(&mut bus, &(rpdo(1, 0x0F, 1000 * k) + &t(0x080, &[])));
        assert!(answer.contains("t181"), "{answer}");
    }
    assert_eq!(bus.now(), t0 + 10 * period);
    assert_eq!(bus.syncs(), syncs + 10);
    let events = bus.take_events();
    let blocks = executed(&events);
    assert_eq!(blocks.len(), 10);
    for (k, block) in (1..).zip(&blocks) {
        assert_eq!(block.start_time, (t0 + (k - 1) * period).as_secs_f64());
        assert_eq!(block.end_time, (t0 + k * period).as_secs_f64());
        assert_eq!(block.to.x, f64::from(1000 * k) / 10_000.0);
    }
    // A master that paused: the drives stood still, and the next cycle still takes one
    // period, ending at the SYNC.
    bus.advance(Duration::from_secs(1));
    host(&mut bus, &(rpdo(1, 0x0F, 11_000) + &t(0x080, &[])));
    let events = bus.take_events();
    let block = executed(&events)[0];
    let end = t0 + 10 * period + Duration::from_secs(1) + period;
    assert_eq!(bus.now(), end);
    assert_eq!(block.start_time, (end - period).as_secs_f64());
    assert_eq!(block.end_time, end.as_secs_f64());
    assert_eq!(block.from.x, 1.0);
    // A drive on another period does not change the bus's: X's rules.
    let answer = host(&mut bus, &t(0x602, &[0x2F, 0xC2, 0x60, 1, 2, 0, 0, 0]));
    assert!(answer.ends_with(&t(0x582, &[0x60, 0xC2, 0x60, 1, 0, 0, 0, 0])));
    host(&mut bus, &t(0x080, &[]));
    assert_eq!(bus.now(), end + period);
}

#[test]
fn heartbeats_fall_due_in_sync_time() {
    let mut bus = Bus::new(config()).unwrap();
    host(&mut bus, "S8\rO\r");
    // 1017h = 50 ms, a 4 ms period: a heartbeat every 12.5 SYNCs.
    for node in 1..=3 {
        host(
            &mut bus,
            &t(0x600 + node, &[0x2B, 0x17, 0x10, 0, 50, 0, 0, 0]),
        );
    }
    set_period(&mut bus, 4, -3);
    bus.lock_clock_to_sync();
    let mut heard = String::new();
    for _ in 0..100 {
        heard += &host(&mut bus, &t(0x080, &[]));
    }
    // 400 ms: due at 50, 100, …, 400 ms, eight each, Pre-operational (7Fh).
    assert_eq!(bus.now(), 400 * MS);
    for node in 1..=3 {
        let beat = t(0x700 + node, &[0x7F]);
        assert_eq!(heard.matches(&beat).count(), 8, "node {node}: {heard}");
    }
}

#[test]
fn an_external_fault_faults_one_drive_with_its_emcy() {
    let mut bus = enabled(config());
    // CiA 402's DC link over-voltage, 3210h, on Z: EMCY on 082h with error register
    // bit 0 (generic), at once.
    assert!(bus.external_fault(2, 0x3210));
    assert_eq!(
        String::from_utf8(bus.take_output()).unwrap(),
        t(0x082, &[0x10, 0x32, 0x01, 0, 0, 0, 0, 0])
    );
    let states = bus.drives().each_ref().map(|d| d.power_state());
    use PowerState::{Fault, OperationEnabled};
    assert_eq!(states, [OperationEnabled, Fault, OperationEnabled]);
    assert!(bus.take_events().contains(&BusEvent::Drive {
        node: 2,
        event: DriveEvent::Fault {
            time: bus.now(),
            code: 0x3210
        }
    }));
    // No drive there; a drive off the bus faults unheard.
    assert!(!bus.external_fault(9, 0x3210));
    assert!(bus.pull_cable(3));
    assert!(bus.external_fault(3, 0x3210));
    assert_eq!(bus.drives()[2].power_state(), Fault);
    assert!(bus.take_output().is_empty());
}

#[test]
fn events_log_as_json_with_seconds() {
    let fault = BusEvent::Drive {
        node: 2,
        event: DriveEvent::Fault {
            time: 1500 * MS,
            code: 0x3210,
        },
    };
    assert_eq!(
        serde_json::to_string(&fault).unwrap(),
        r#"{"event":"drive","node":2,"kind":"fault","time":1.5,"code":12816}"#
    );
    let power = BusEvent::Drive {
        node: 1,
        event: DriveEvent::Power {
            time: Duration::ZERO,
            state: PowerState::SwitchOnDisabled,
        },
    };
    assert_eq!(
        serde_json::to_string(&power).unwrap(),
        r#"{"event":"drive","node":1,"kind":"power","time":0.0,"state":"SwitchOnDisabled"}"#
    );
    let breach = BusEvent::Breach {
        time: 0.25,
        breach: Breach {
            message: "off".into(),
        },
    };
    assert_eq!(
        serde_json::to_string(&breach).unwrap(),
        r#"{"event":"breach","time":0.25,"breach":{"message":"off"}}"#
    );
    let mut bus = enabled(config());
    cycle(&mut bus, 0x0F, [1000, 0, 0], 4 * MS);
    let events = bus.take_events();
    let json = serde_json::to_value(executed(&events)[0]).unwrap();
    let logged = serde_json::to_value(&events[events.len() - 1]).unwrap();
    assert_eq!(logged["event"], "executed");
    assert_eq!(logged["to"], json["to"]);
}

#[test]
fn impossible_buses_are_refused() {
    let mut zero = config();
    zero.counts_per_unit[2] = 0.0;
    let err = Bus::new(zero).unwrap_err();
    assert_eq!(
        err,
        BusError::Scale {
            axis: 'C',
            value: 0.0
        }
    );
    assert_eq!(
        err.to_string(),
        "counts per unit of axis C: 0 must be finite and above zero"
    );
    let mut twice = config();
    twice.drives[2].node = 1;
    assert_eq!(
        Bus::new(twice).unwrap_err().to_string(),
        "two drives on node 1"
    );
    let mut none = config();
    none.drives[0].node = 0;
    assert_eq!(
        Bus::new(none).unwrap_err(),
        BusError::Drive(DriveConfigError::NodeId(0))
    );
}
