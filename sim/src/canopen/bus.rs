//! Three CiA 402 drives, X, Z and C, on one CAN bus behind an slcan adapter, as one
//! sans-I/O unit: the host's bytes in ([`Bus::receive`]), simulated time in
//! ([`Bus::advance`]), the adapter's bytes out ([`Bus::take_output`]), and what the machine
//! did as [`BusEvent`]s ([`Bus::take_events`]).
//!
//! # The executed path
//!
//! Each SYNC is one control cycle of all three drives. After the drives have taken it,
//! their positions (6064h, in counts; X and Z per mm, C per degree) become one
//! [`ExecutedBlock`]: a straight move from where the previous SYNC left them (power-up
//! for the first) to where they are now, spanning the time from that SYNC to this one
//! (one interpolation period with the clock locked to SYNC; see [Time](#time)), of kind
//! inverse time (a duration, not a feed), its `line` the SYNC's ordinal (from 1) and
//! no N word. Its `target` is the drives' set-points (607Ah, or 60C1h sub-index 1 in
//! interpolated position mode: [`Drive::set_point`]) and `completed` says whether they
//! got there; a cycle cut short shows one phase at the speed of the distance
//! actually moved. Replayed in order, the blocks are the path the drives followed, at the
//! cycle's resolution.
//!
//! Positions count modulo 2³² in the drives (a whirling job's C passes INTEGER32's range);
//! the bus reads each cycle's step as the wrapping difference from the last, so the
//! executed path counts whole turns on and on, from the drives' power-up positions as
//! INTEGER32 reads them.
//!
//! # Guard and limits
//!
//! [`Bus::set_guard`] gives every executed block to a [`Guard`], as the grbl controller
//! does ([`crate::Controller::set_guard`]). A breach faults all three drives with EMCY
//! [`EMCY_GUARD`] (a manufacturer-specific code; 64 as grbl's ALARM:64) and the guard
//! sees no more blocks.
//!
//! Travel limits are the drives' software position limits
//! ([`DriveConfig::software_limits`], from the machine's travel by
//! [`BusConfig::for_machine`]): a drive given a target outside faults before it moves, with
//! EMCY 0x8612. The machine's enable chain then opens: once that emergency is on the bus,
//! the other drives fault with EMCY [`EMCY_CHAIN`], so a master hears the cause first.
//!
//! [`Bus::pull_cable`] cuts one drive off the bus, the way a pulled connector does: it
//! neither hears nor is heard, its heartbeat included. [`Bus::external_fault`] faults one
//! drive as its own protection would (an over-voltage, a motor too hot), for a master's
//! fault handling to be tried.
//!
//! # Time
//!
//! By default the bus's clock is the caller's: [`Bus::advance`] moves it and a SYNC takes
//! no time, so a cycle spans from the previous SYNC to this one. Real CSP drives lock
//! their control cycle to the master's SYNC instead, and a master that runs faster or
//! slower than the wall clock (a dry run in lockstep) still sees each cycle take one
//! period. [`Bus::lock_clock_to_sync`] does that: each SYNC from the host first lets the
//! drives' interpolation time period (60C2h) pass, heartbeats included, then reaches the
//! drives, and its cycle spans exactly that period, ending at the SYNC. Between SYNCs the
//! caller may still [`Bus::advance`] (a master that stopped sending them leaves the drives
//! standing in wall time); that time shows as a gap in which nothing moves. The period is
//! X's: a master writes all three alike, and if it does not, the bus runs at X's.

use std::time::Duration;

use serde::Serialize;
use thiserror::Error;

use super::drive::{DriveConfigError, EMCY_POSITION_LIMIT};
use super::{Drive, DriveConfig, DriveEvent, Frame, SlcanAdapter};
use crate::guard::{Breach, Guard};
use crate::machine::Machine;
use crate::record::{ExecutedBlock, MoveKind, Phase, Position};

/// EMCY code of a Δ guard breach: manufacturer-specific (FFxxh), 64 as grbl's ALARM:64.
pub const EMCY_GUARD: u16 = 0xFF64;
/// EMCY code of the drives whose enable chain another drive's limit fault opened: CiA
/// 301's "external error".
pub const EMCY_CHAIN: u16 = 0x9000;

/// How the bus is built: the drives, X, Z, C in that order, and their scales.
#[derive(Debug, Clone, PartialEq)]
pub struct BusConfig {
    /// Counts per mm (X, Z) and per degree (C): how the drives' counts read as machine
    /// positions.
    pub counts_per_unit: [f64; 3],
    /// The drives of X, Z and C; distinct nodes.
    pub drives: [DriveConfig; 3],
}

impl BusConfig {
    /// Drives on nodes 1, 2, 3 for `machine` at a cycle of `period`: each moves at most
    /// its axis's max rate a cycle (plus one count of rounding), stops at the axis's
    /// travel (software limits, where the axis has both ends), and starts at `start` (its
    /// low 32 bits of counts, as a drive holds it). The
    /// heartbeat is off and the window 10 000 counts until a master writes 1017h and
    /// 6065h.
    pub fn for_machine(
        machine: &Machine,
        counts_per_unit: [f64; 3],
        period: Duration,
        start: Position,
    ) -> BusConfig {
        let axes = [machine.x, machine.z, machine.c];
        let start = start.to_array();
        let drives = std::array::from_fn(|k| {
            let scale = counts_per_unit[k];
            let counts = |v: f64| v * scale;
            let per_cycle = axes[k].max_rate / 60.0 * period.as_secs_f64() * scale;
            let limits = match (axes[k].min, axes[k].max) {
                // Inward, and within INTEGER32.
                (Some(min), Some(max)) => Some((
                    counts(min).ceil().max(f64::from(i32::MIN)) as i32,
                    counts(max).floor().min(f64::from(i32::MAX)) as i32,
                )),
                _ => None,
            };
            DriveConfig {
                max_step: (per_cycle.ceil() + 1.0).min(f64::from(u32::MAX)) as u32,
                position: counts(start[k]).round() as i64 as i32,
                software_limits: limits,
                ..DriveConfig::new(k as u8 + 1)
            }
        });
        BusConfig {
            counts_per_unit,
            drives,
        }
    }
}

/// A bus that cannot be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BusError {
    /// A drive's configuration.
    #[error(transparent)]
    Drive(#[from] DriveConfigError),
    /// Two drives on one node.
    #[error("two drives on node {0}")]
    Node(u8),
    /// A scale that is not a positive number.
    #[error("counts per unit of axis {axis}: {value} must be finite and above zero")]
    Scale {
        /// X, Z or C.
        axis: char,
        /// The value.
        value: f64,
    },
}

/// What happened on the bus. In a log, `event` names the variant, as in the controller's
/// events; a drive's event carries its own `kind`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum BusEvent {
    /// A SYNC's cycle, as a straight move (see the module docs).
    Executed(ExecutedBlock),
    /// One of the drives' own events (NMT, power state, faults); their control cycles are
    /// the executed blocks.
    Drive {
        /// The drive's node.
        node: u8,
        /// What happened. Flattened, it has no key of its own; the name only keeps serde
        /// from taking the field for a second `event` beside the tag.
        #[serde(flatten, rename = "drive_event")]
        event: DriveEvent,
    },
    /// The guard found the executed motion out of bounds; every drive faulted.
    Breach {
        /// Simulated time, s.
        time: f64,
        /// The guard's verdict.
        breach: Breach,
    },
}

/// The three drives and the adapter; see the module docs.
#[derive(Debug)]
pub struct Bus {
    adapter: SlcanAdapter,
    drives: [Drive; 3],
    nodes: [u8; 3],
    scale: [f64; 3],
    now: Duration,
    pulled: [bool; 3],
    guard: Option<Box<dyn Guard>>,
    breached: bool,
    /// Rounds of routing until the chain opens after a limit fault (its emergency goes on
    /// the bus in the round after the fault); 0: nothing pending.
    chain: u8,
    /// Each SYNC from the host lets the interpolation period pass (see the module docs).
    sync_clock: bool,
    syncs: u64,
    /// Positions (unwrapped counts) and time at the last SYNC.
    positions: [i64; 3],
    last_sync: f64,
    events: Vec<BusEvent>,
}

/// A SYNC: nothing, or a one-byte counter, on 080h.
fn is_sync(frame: &Frame) -> bool {
    frame.id == 0x080 && !frame.extended && !frame.remote && frame.data.len() <= 1
}

/// The i64 nearest `near` whose low 32 bits are `wire`.
fn unwrap_near(wire: i32, near: i64) -> i64 {
    near + i64::from(wire.wrapping_sub(near as i32))
}

impl Bus {
    /// Powers the drives up (their boot-up messages go by while the adapter's channel is
    /// still closed, as on a bench where the drives are switched on first).
    pub fn new(config: BusConfig) -> Result<Bus, BusError> {
        for (k, value) in config.counts_per_unit.into_iter().enumerate() {
            if !(value.is_finite() && value > 0.0) {
                let axis = ['X', 'Z', 'C'][k];
                return Err(BusError::Scale { axis, value });
            }
        }
        let nodes = config.drives.each_ref().map(|d| d.node);
        if let Some(k) = (1..3).find(|&k| nodes[..k].contains(&nodes[k])) {
            return Err(BusError::Node(nodes[k]));
        }
        let [x, z, c] = config.drives;
        let drives = [Drive::new(x)?, Drive::new(z)?, Drive::new(c)?];
        let mut bus = Bus {
            adapter: SlcanAdapter::new(),
            positions: drives.each_ref().map(|d| i64::from(d.position())),
            drives,
            nodes,
            scale: config.counts_per_unit,
            now: Duration::ZERO,
            pulled: [false; 3],
            guard: None,
            breached: false,
            chain: 0,
            sync_clock: false,
            syncs: 0,
            last_sync: 0.0,
            events: Vec::new(),
        };
        bus.route();
        Ok(bus)
    }

    /// Let `guard` judge every cycle executed from now on (see the module docs).
    pub fn set_guard(&mut self, guard: Box<dyn Guard>) {
        self.guard = Some(guard);
    }

    /// The guard, to read what it has measured.
    pub fn guard(&self) -> Option<&dyn Guard> {
        self.guard.as_deref()
    }

    /// The job ended: the guard settles what waited for later motion. A breach faults the
    /// drives as in [`Bus::set_guard`]'s case and is returned.
    pub fn program_end(&mut self) -> Result<(), Breach> {
        let Some(guard) = self.guard.as_mut().filter(|_| !self.breached) else {
            return Ok(());
        };
        if let Err(breach) = guard.program_end() {
            self.trip(breach.clone());
            self.route();
            return Err(breach);
        }
        Ok(())
    }

    /// Runs the clock on the host's SYNCs from now on (see the module docs).
    pub fn lock_clock_to_sync(&mut self) {
        self.sync_clock = true;
    }

    /// SYNCs the host has sent since power-up.
    pub fn syncs(&self) -> u64 {
        self.syncs
    }

    /// Cuts the drive on `node` off the bus (a pulled cable): nothing reaches it, nothing
    /// of it reaches anyone. Returns false if no drive is on that node.
    pub fn pull_cable(&mut self, node: u8) -> bool {
        let Some(k) = self.slot(node) else {
            return false;
        };
        self.pulled[k] = true;
        true
    }

    /// Faults the drive on `node` as a fault of its own would: Fault, EMCY `code` on the
    /// bus at once (reaching the host if the channel is open and the cable in). Returns
    /// false if no drive is on that node. A drive already in Fault keeps its first fault.
    pub fn external_fault(&mut self, node: u8, code: u16) -> bool {
        let Some(k) = self.slot(node) else {
            return false;
        };
        self.drives[k].external_fault(code);
        self.collect_drive_events();
        self.route();
        true
    }

    /// Where the drive on `node` is in `drives`.
    fn slot(&self, node: u8) -> Option<usize> {
        self.nodes.iter().position(|n| *n == node)
    }

    /// The drives, X, Z, C.
    pub fn drives(&self) -> &[Drive; 3] {
        &self.drives
    }

    /// Simulated time.
    pub fn now(&self) -> Duration {
        self.now
    }

    /// Bytes from the host, to the adapter; frames it puts on the bus reach the drives at
    /// once.
    pub fn receive(&mut self, bytes: &[u8]) {
        self.adapter.receive(bytes);
        self.route();
    }

    /// Lets `dt` pass: heartbeats fall due (and reach the adapter at the end of `dt`).
    pub fn advance(&mut self, dt: Duration) {
        self.pass(dt);
        self.route();
    }

    /// Lets `dt` pass without moving the frames it produced.
    fn pass(&mut self, dt: Duration) {
        self.now += dt;
        self.adapter.advance(dt);
        for drive in &mut self.drives {
            drive.advance(dt);
        }
    }

    /// Bytes for the host since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        self.adapter.take_output()
    }

    /// Events since the last call, in order.
    pub fn take_events(&mut self) -> Vec<BusEvent> {
        std::mem::take(&mut self.events)
    }

    /// Moves frames until the bus is quiet: the host's first, then the drives' in node
    /// order, each to everyone but its sender (and nothing to or from a pulled drive).
    fn route(&mut self) {
        loop {
            let mut on_bus: Vec<(Option<usize>, Frame)> = self
                .adapter
                .take_transmitted()
                .into_iter()
                .map(|f| (None, f))
                .collect();
            for k in 0..3 {
                let out = self.drives[k].take_output();
                if !self.pulled[k] {
                    on_bus.extend(out.into_iter().map(|f| (Some(k), f)));
                }
            }
            if on_bus.is_empty() {
                return;
            }
            for (sender, frame) in on_bus {
                let sync = sender.is_none() && is_sync(&frame);
                let cycle_start = sync.then(|| self.sync_arrives());
                if sender.is_some() {
                    self.adapter.deliver(&frame);
                }
                for k in 0..3 {
                    if sender != Some(k) && !self.pulled[k] {
                        self.drives[k].receive(&frame);
                    }
                }
                self.collect_drive_events();
                if let Some(start) = cycle_start {
                    self.cycle(start);
                }
            }
            if self.chain > 0 {
                self.chain -= 1;
                if self.chain == 0 {
                    // The limit fault's emergency is on the bus now: open the chain.
                    for drive in &mut self.drives {
                        drive.external_fault(EMCY_CHAIN);
                    }
                    self.collect_drive_events();
                }
            }
        }
    }

    fn collect_drive_events(&mut self) {
        for k in 0..3 {
            for event in self.drives[k].take_events() {
                match event {
                    DriveEvent::Cycle { .. } => continue,
                    DriveEvent::Fault {
                        code: EMCY_POSITION_LIMIT,
                        ..
                    } => self.chain = 2,
                    _ => {}
                }
                self.events.push(BusEvent::Drive {
                    node: self.nodes[k],
                    event,
                });
            }
        }
    }

    /// A SYNC from the host is about to reach the drives: with the clock locked, X's
    /// interpolation period passes first. Returns when the cycle it starts began, s.
    fn sync_arrives(&mut self) -> f64 {
        if !self.sync_clock {
            return self.last_sync;
        }
        let period = self.drives[0].interpolation_period();
        self.pass(period);
        (self.now - period).as_secs_f64()
    }

    fn units(&self, counts: [i64; 3]) -> Position {
        Position::from_array(std::array::from_fn(|k| counts[k] as f64 / self.scale[k]))
    }

    /// A SYNC went by, its cycle begun at `start`: the cycle as an executed block, shown to
    /// the guard.
    fn cycle(&mut self, start: f64) {
        self.syncs += 1;
        let actual: [i64; 3] =
            std::array::from_fn(|k| unwrap_near(self.drives[k].position(), self.positions[k]));
        let target: [i64; 3] =
            std::array::from_fn(|k| unwrap_near(self.drives[k].set_point(), actual[k]));
        let now = self.now.as_secs_f64();
        let (from, to) = (self.units(self.positions), self.units(actual));
        let moved = (0..3)
            .map(|k| (to.to_array()[k] - from.to_array()[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        let span = now - start;
        let block = ExecutedBlock {
            line: self.syncs,
            n: None,
            kind: MoveKind::InverseTime,
            from,
            target: self.units(target),
            to,
            start_time: start,
            end_time: now,
            completed: target == actual,
            phases: vec![Phase {
                start,
                distance: 0.0,
                speed: if span > 0.0 { moved / span } else { 0.0 },
                accel: 0.0,
            }],
        };
        self.positions = actual;
        self.last_sync = now;
        let verdict = match (&mut self.guard, self.breached) {
            (Some(guard), false) => guard.executed(&block),
            _ => Ok(()),
        };
        self.events.push(BusEvent::Executed(block));
        if let Err(breach) = verdict {
            self.trip(breach);
        }
    }

    /// A breach: every drive faults with [`EMCY_GUARD`]; the guard is done.
    fn trip(&mut self, breach: Breach) {
        self.breached = true;
        self.events.push(BusEvent::Breach {
            time: self.now.as_secs_f64(),
            breach,
        });
        for drive in &mut self.drives {
            drive.external_fault(EMCY_GUARD);
        }
        self.collect_drive_events();
    }
}

#[cfg(test)]
mod tests {
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
}
