//! A simulated CiA 402 servo drive on CANopen: frames in ([`Drive::receive`]), frames out
//! ([`Drive::take_output`]), simulated time passed in ([`Drive::advance`]).
//!
//! # CANopen (CiA 301)
//!
//! - **NMT.** Power-up (and NMT reset node / reset communication) sends the boot-up
//!   message (one byte 0x00 on 0x700 + node) and enters Pre-operational. NMT commands
//!   (two bytes on 0x000: specifier, node or 0 for all) move it: 0x01 Operational, 0x02
//!   Stopped, 0x80 Pre-operational, 0x81 reset node (the profile's objects too), 0x82 reset
//!   communication (1017h and the PDO objects). SDO, SYNC and EMCY work in Pre-operational
//!   and Operational, PDOs only in Operational; Stopped leaves NMT and heartbeat.
//! - **Heartbeat.** Every 1017h milliseconds (0: off), the NMT state byte on 0x700 + node
//!   (0x04 Stopped, 0x05 Operational, 0x7F Pre-operational); writing 1017h restarts the
//!   period.
//! - **Identity** (1018h, which CiA 301 makes mandatory): vendor-ID 0 (a simulator has
//!   none of CiA's), product code 402, revision 1.0, serial number the node-ID.
//! - **SDO server**, expedited only, on 0x600 + node, answering on 0x580 + node. Frames
//!   of other than 8 bytes are ignored (CiA 301 gives SDO frames 8). Aborts: 0x06020000
//!   unknown object, 0x06090011 unknown sub-index, 0x06010002 read-only, 0x06070012 /
//!   0x06070013 size indicated too long / too short, 0x06090030 a value out of range,
//!   0x05040001 any service but expedited download and upload (the sim has no object
//!   longer than four bytes, so segmented transfers are never needed).
//! - **PDOs**, the four of each predefined direction (1400h–1403h, 1600h–1603h,
//!   1800h–1803h, 1A00h–1A03h), 11-bit COB-IDs only. Power-on mapping: RPDO1 = 6040h,
//!   607Ah and TPDO1 = 6041h, 6064h, both transmission type 1, the others invalid and
//!   empty. RPDOs can carry 6040h, 6060h, 607Ah and 60C1h sub-index 1; TPDOs 6041h, 6061h
//!   and 6064h. Mapping follows CiA 301's procedure, and the aborts CANopenNode gives for
//!   breaking it: changing a mapping while the PDO is valid, or an entry while sub-index 0
//!   is not 0, 0x06010000; an object that cannot be mapped (or with another bit length)
//!   0x06040041; more than 8 entries or 64 bits 0x06040042; making a PDO valid with no
//!   mapping, changing a valid PDO's COB-ID, a 29-bit COB-ID, transmission types 241–253
//!   0x06090030.
//!
//!   RPDOs of transmission type 0–240 are applied at the next SYNC (the last one received
//!   wins), 254–255 at once. TPDOs of type 1–240 go every n-th SYNC, 0 at a SYNC when their
//!   data changed, 254–255 whenever their data changed. An RPDO shorter than its mapping
//!   is dropped with EMCY 0x8210 (CiA 301: PDO not processed due to length error).
//!
//! # The drive (CiA 402)
//!
//! - The power state machine of 6040h/6041h with all its transitions, 0–16 (0, 1 at
//!   power-up and reset node, 13, 14 on a fault, the rest by controlword); "switch
//!   on + enable operation" (0x0F) from Ready to switch on does 3 and 4 at once, as the
//!   profile allows. Fault reset acts on the rising edge of controlword bit 7; with bit 7
//!   high no other command acts. Quick stop stops at once and stays in Quick stop active
//!   (quick stop option code 6) until disable voltage (12) or enable operation (16).
//!   Not ready to switch on and Fault reaction active pass instantly.
//! - Statusword: the state's bits, bit 4 (voltage enabled: mains are always on), bit 9
//!   (remote), bit 12 while the mode's set-points are followed (in cyclic synchronous
//!   position mode with operation enabled: the drive follows the target; in interpolated
//!   position mode, "ip mode active": operation enabled and controlword bit 4, "enable ip
//!   mode", set), bit 13 after a following error.
//! - Modes (6060h, shown in 6061h): 0 (none), 7 (interpolated position) and 8 (cyclic
//!   synchronous position); others abort 0x06090030.
//! - Interpolated position mode's data record (60C1h): sub-index 0 the number of entries,
//!   1 (UNSIGNED8, read-only); sub-index 1 the position set-point (INTEGER32), the one
//!   entry linear interpolation needs, the position actual value at power-up and reset
//!   node, as 607Ah. Only synchronous operation is modelled: one set-point a SYNC, no
//!   buffer (60C4h) and no other sub-mode (60C0h) in the dictionary; with one control
//!   cycle a SYNC the drive's linear interpolation between two set-points is the step from
//!   one to the next.
//! - Interpolation time period (60C2h): sub-index 1 the value (UNSIGNED8), 2 the index
//!   (INTEGER8), the period being value × 10^index s; 1 ms at power-up. The master writes
//!   its SYNC period here, and a bus locked to SYNC ([`super::Bus::lock_clock_to_sync`])
//!   runs one period a cycle. A value of 0 (no cycle at all) and an index outside −6…0
//!   (below a microsecond, above the unit) abort 0x06090030: CiA 402 leaves the range to
//!   the device, and a drive's control cycle is neither zero nor finer than 1 µs.
//! - Each SYNC is one control cycle: synchronous RPDOs are applied, then the actual
//!   position (6064h) moves towards the mode's set-point by at most
//!   [`DriveConfig::max_step`] counts, then the following error is checked, then the
//!   synchronous TPDOs are sent, so they show the cycle's result. The set-point is the
//!   target position (607Ah) in CSP with operation enabled, 60C1h sub-index 1 in
//!   interpolated position mode while ip mode is active; otherwise (ip mode inactive, no
//!   mode, any other state) the drive holds where it is and checks nothing.
//! - Following error: |set-point − 6064h| beyond 6065h after a cycle (6066h, the time-out,
//!   is taken as 0) faults the drive with EMCY 0x8611, error register 0x01 (generic).
//!   6065h = FFFFFFFFh switches the check off, as CiA 402 says. The fault reset sends EMCY
//!   0x0000. The drive does not move its set-point to its position on enable (or, in
//!   interpolated position mode, when ip mode becomes active): a master that enables with
//!   a stale one sees the jump, or the fault.
//! - Positions count modulo 2³², as a drive's do with its position range limit (607Bh) at
//!   INTEGER32's full range: the way to a target and the following error are the wrapping
//!   difference, so a rotary axis can turn past ±2³¹ counts (a whirling job's C does).
//! - Software position limits ([`DriveConfig::software_limits`], 607Dh's values; the
//!   object itself is not in the dictionary): a set-point outside them, when a cycle would
//!   move towards it, faults the drive with EMCY 0x8612 before it moves.
//! - [`Drive::external_fault`]: a fault from outside CANopen (a machine's safety chain).
//!
//! # Layout
//!
//! This file holds the drive itself: its configuration, its state, the frames' dispatch
//! and the SYNC cycle (set-point, step, following error, limits). Each CiA 301 service
//! or CiA 402 automaton the cycle relies on has its own file: `nmt` (NMT and heartbeat),
//! `dictionary` (the object dictionary and SDO server), `pdo` (PDO objects, mapping and
//! traffic) and `power` (the power state machine, statusword and faults).

use std::time::Duration;

use serde::{Serialize, Serializer};
use thiserror::Error;

use super::Frame;

mod dictionary;
mod nmt;
mod pdo;
mod power;
#[cfg(test)]
mod tests;

pub use dictionary::DEVICE_TYPE;
pub use nmt::NmtState;
pub use pdo::EMCY_PDO_LENGTH;
pub use power::PowerState;

use pdo::{default_pdos, Pdo};

/// EMCY code of a following error (CiA 402).
pub const EMCY_FOLLOWING_ERROR: u16 = 0x8611;
/// EMCY code of a target outside the software position limits: CiA 402's "reference
/// limit" of the positioning controller.
pub const EMCY_POSITION_LIMIT: u16 = 0x8612;
/// 60C2h at power-up: value 1, index −3, one millisecond.
const INTERPOLATION_POWER_ON: (u8, i8) = (1, -3);
/// 6060h: interpolated position mode.
const MODE_IP: i8 = 7;
/// 6060h: cyclic synchronous position mode.
const MODE_CSP: i8 = 8;
/// Controlword bit 4 in interpolated position mode: enable ip mode.
const ENABLE_IP_MODE: u16 = 1 << 4;

/// How a drive is built.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DriveConfig {
    /// CANopen node id, 1–127.
    pub node: u8,
    /// The most the position moves in one SYNC cycle, counts (the axis's speed limit).
    pub max_step: u32,
    /// Position actual value at power-up, counts.
    pub position: i32,
    /// Power-on value of 1017h, ms.
    pub heartbeat_ms: u16,
    /// Power-on value of 6065h, counts.
    pub following_error_window: u32,
    /// Software position limits (min, max), counts; `None`: unlimited, as a rotary axis
    /// is.
    pub software_limits: Option<(i32, i32)>,
}

impl DriveConfig {
    /// Node `node` with 1000 counts a cycle, at 0, no heartbeat, a 10000-count window, no
    /// software limits.
    pub fn new(node: u8) -> DriveConfig {
        DriveConfig {
            node,
            max_step: 1000,
            position: 0,
            heartbeat_ms: 0,
            following_error_window: 10_000,
            software_limits: None,
        }
    }
}

/// A configuration that cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum DriveConfigError {
    /// Node ids are 1–127.
    #[error("node id {0} is not 1-127")]
    NodeId(u8),
}

/// What happened in the drive, for logs and tests. In a log, `kind` names the variant
/// and times are seconds, as in the controller's events.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum DriveEvent {
    /// The NMT state changed (boot-up included).
    Nmt {
        /// Simulated time.
        #[serde(serialize_with = "seconds")]
        time: Duration,
        /// The new state.
        state: NmtState,
    },
    /// The power state changed.
    Power {
        /// Simulated time.
        #[serde(serialize_with = "seconds")]
        time: Duration,
        /// The new state.
        state: PowerState,
    },
    /// A fault, with its EMCY code.
    Fault {
        /// Simulated time.
        #[serde(serialize_with = "seconds")]
        time: Duration,
        /// The EMCY error code.
        code: u16,
    },
    /// A control cycle (SYNC) following set-points: in cyclic synchronous position mode
    /// with operation enabled, or in interpolated position mode with ip mode active.
    Cycle {
        /// Simulated time.
        #[serde(serialize_with = "seconds")]
        time: Duration,
        /// The set-point: 607Ah (CSP) or 60C1h sub-index 1 (interpolated position).
        target: i32,
        /// 6064h after the cycle.
        actual: i32,
    },
}

/// A time as seconds, the unit of every time in the simulator's logs.
fn seconds<S: Serializer>(time: &Duration, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_f64(time.as_secs_f64())
}

/// A CiA 402 drive on a CANopen bus.
#[derive(Debug, Clone)]
pub struct Drive {
    config: DriveConfig,
    now: Duration,
    nmt: NmtState,
    heartbeat_ms: u16,
    next_heartbeat: Option<Duration>,
    power: PowerState,
    controlword: u16,
    mode: i8,
    target: i32,
    /// 60C1h sub-index 1.
    interpolation_data: i32,
    actual: i32,
    window: u32,
    following_error: bool,
    error_register: u8,
    /// 60C2h: (value, index).
    interpolation: (u8, i8),
    rpdo: [Pdo; 4],
    tpdo: [Pdo; 4],
    output: Vec<Frame>,
    events: Vec<DriveEvent>,
}

impl Drive {
    /// Powers the drive up: the boot-up message waits in the output.
    pub fn new(config: DriveConfig) -> Result<Drive, DriveConfigError> {
        if !(1..=127).contains(&config.node) {
            return Err(DriveConfigError::NodeId(config.node));
        }
        let (rpdo, tpdo) = default_pdos(config.node);
        let mut drive = Drive {
            now: Duration::ZERO,
            nmt: NmtState::PreOperational,
            heartbeat_ms: config.heartbeat_ms,
            next_heartbeat: None,
            power: PowerState::NotReadyToSwitchOn,
            controlword: 0,
            mode: 0,
            target: config.position,
            interpolation_data: config.position,
            actual: config.position,
            window: config.following_error_window,
            following_error: false,
            error_register: 0,
            interpolation: INTERPOLATION_POWER_ON,
            rpdo,
            tpdo,
            output: Vec::new(),
            events: Vec::new(),
            config,
        };
        drive.reset_application();
        drive.reset_communication();
        Ok(drive)
    }

    /// The NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.nmt
    }

    /// The power state.
    pub fn power_state(&self) -> PowerState {
        self.power
    }

    /// Position actual value (6064h), counts.
    pub fn position(&self) -> i32 {
        self.actual
    }

    /// Target position (607Ah), counts.
    pub fn target(&self) -> i32 {
        self.target
    }

    /// Interpolated position mode's set-point (60C1h sub-index 1), counts.
    pub fn interpolation_data(&self) -> i32 {
        self.interpolation_data
    }

    /// The set-point object of the drive's mode of operation, counts: 60C1h sub-index 1 in
    /// interpolated position mode, the target position (607Ah) otherwise.
    pub fn set_point(&self) -> i32 {
        if self.mode == MODE_IP {
            self.interpolation_data
        } else {
            self.target
        }
    }

    /// Simulated time.
    pub fn now(&self) -> Duration {
        self.now
    }

    /// The interpolation time period (60C2h): value × 10^index seconds, the master's SYNC
    /// period as it told the drive.
    pub fn interpolation_period(&self) -> Duration {
        let (value, index) = self.interpolation;
        // −6 ≤ index ≤ 0: a whole number of nanoseconds.
        let nanos_per_unit = 10u64.pow((9 + i32::from(index)) as u32);
        Duration::from_nanos(u64::from(value) * nanos_per_unit)
    }

    /// Frames to put on the bus since the last call.
    pub fn take_output(&mut self) -> Vec<Frame> {
        std::mem::take(&mut self.output)
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<DriveEvent> {
        std::mem::take(&mut self.events)
    }

    /// A frame from the bus. Extended, remote and over-long frames are not CANopen's
    /// business here and are ignored, as are frames for other nodes.
    pub fn receive(&mut self, frame: &Frame) {
        if frame.extended || frame.remote || frame.id > 0x7FF || frame.data.len() > 8 {
            return;
        }
        let id = frame.id as u16;
        let sdo = 0x600 + u16::from(self.config.node);
        match id {
            0x000 => self.nmt_command(&frame.data),
            0x080 => self.sync(&frame.data),
            _ if id == sdo => self.sdo_request(&frame.data),
            _ => self.rpdo_frame(id, &frame.data),
        }
        self.send_changed_tpdos();
    }

    /// The set-point a control cycle steers to: 607Ah in CSP with operation enabled,
    /// 60C1h sub-index 1 in interpolated position mode with ip mode active (operation
    /// enabled and controlword bit 4), none otherwise.
    fn active_set_point(&self) -> Option<i32> {
        if self.power != PowerState::OperationEnabled {
            return None;
        }
        match self.mode {
            MODE_CSP => Some(self.target),
            MODE_IP if self.controlword & ENABLE_IP_MODE != 0 => Some(self.interpolation_data),
            _ => None,
        }
    }

    /// Statusword bit 12: CSP's "drive follows the command value", interpolated position
    /// mode's "ip mode active".
    fn following(&self) -> bool {
        self.active_set_point().is_some()
    }

    fn send(&mut self, function: u16, data: &[u8]) {
        self.output
            .push(Frame::data(function + u16::from(self.config.node), data));
    }

    /// NMT reset node's application part: the profile's objects to power-on values.
    fn reset_application(&mut self) {
        self.set_power(PowerState::NotReadyToSwitchOn);
        self.controlword = 0;
        self.mode = 0;
        self.target = self.actual;
        self.interpolation_data = self.actual;
        self.window = self.config.following_error_window;
        self.following_error = false;
        self.error_register = 0;
        self.interpolation = INTERPOLATION_POWER_ON;
        self.set_power(PowerState::SwitchOnDisabled);
    }

    fn emcy(&mut self, code: u16) {
        if self.nmt != NmtState::Stopped {
            let [lo, hi] = code.to_le_bytes();
            self.send(0x080, &[lo, hi, self.error_register, 0, 0, 0, 0, 0]);
        }
    }

    /// A SYNC: the synchronous RPDOs, then one control cycle, then the synchronous TPDOs.
    fn sync(&mut self, data: &[u8]) {
        // SYNC carries nothing, or a one-byte counter.
        if data.len() > 1 || self.nmt == NmtState::Stopped {
            return;
        }
        if self.nmt == NmtState::Operational {
            self.apply_synchronous_rpdos();
        }
        if let Some(set_point) = self.active_set_point() {
            self.control_cycle(set_point);
        }
        if self.nmt == NmtState::Operational {
            self.send_synchronous_tpdos();
        }
    }

    /// One control cycle towards `set_point`: the software limits, the step, the
    /// following error.
    fn control_cycle(&mut self, set_point: i32) {
        let outside = |(min, max): (i32, i32)| !(min..=max).contains(&set_point);
        let moving = set_point != self.actual;
        if moving && self.config.software_limits.is_some_and(outside) {
            self.fault(EMCY_POSITION_LIMIT);
            return;
        }
        // Modulo 2^32: the shorter way round, as the drive's position counter wraps.
        let step = i64::from(self.config.max_step);
        let gap = i64::from(set_point.wrapping_sub(self.actual));
        self.actual = self.actual.wrapping_add(gap.clamp(-step, step) as i32);
        self.events.push(DriveEvent::Cycle {
            time: self.now,
            target: set_point,
            actual: self.actual,
        });
        let error = i64::from(set_point.wrapping_sub(self.actual)).unsigned_abs();
        if self.window != u32::MAX && error > u64::from(self.window) {
            self.following_error = true;
            self.fault(EMCY_FOLLOWING_ERROR);
        }
    }
}
