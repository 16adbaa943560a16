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
mod tests;
