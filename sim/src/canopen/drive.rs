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

use std::time::Duration;

use serde::{Serialize, Serializer};
use thiserror::Error;

use super::Frame;

/// SDO abort codes the server gives (CiA 301).
mod abort {
    pub const COMMAND: u32 = 0x0504_0001;
    pub const UNSUPPORTED: u32 = 0x0601_0000;
    pub const READ_ONLY: u32 = 0x0601_0002;
    pub const NO_OBJECT: u32 = 0x0602_0000;
    pub const CANNOT_MAP: u32 = 0x0604_0041;
    pub const MAP_TOO_LONG: u32 = 0x0604_0042;
    pub const TOO_LONG: u32 = 0x0607_0012;
    pub const TOO_SHORT: u32 = 0x0607_0013;
    pub const NO_SUB: u32 = 0x0609_0011;
    pub const INVALID: u32 = 0x0609_0030;
}

/// 1000h: CiA 402 (0x0192) in the low word, servo drive (0x02) above it.
pub const DEVICE_TYPE: u32 = 0x0002_0192;
/// EMCY code of a following error (CiA 402).
pub const EMCY_FOLLOWING_ERROR: u16 = 0x8611;
/// EMCY code of an RPDO shorter than its mapping (CiA 301).
pub const EMCY_PDO_LENGTH: u16 = 0x8210;
/// EMCY code of a target outside the software position limits: CiA 402's "reference
/// limit" of the positioning controller.
pub const EMCY_POSITION_LIMIT: u16 = 0x8612;
/// 60C2h at power-up: value 1, index −3, one millisecond.
const INTERPOLATION_POWER_ON: (u8, i8) = (1, -3);
/// The interpolation time indices the drive takes: 1 µs to 1 s units.
const INTERPOLATION_INDICES: std::ops::RangeInclusive<i8> = -6..=0;
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

/// The NMT states a drive can be in after boot-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum NmtState {
    /// Heartbeat byte 0x7F.
    PreOperational,
    /// 0x05.
    Operational,
    /// 0x04.
    Stopped,
}

impl NmtState {
    fn heartbeat(self) -> u8 {
        match self {
            NmtState::PreOperational => 0x7F,
            NmtState::Operational => 0x05,
            NmtState::Stopped => 0x04,
        }
    }
}

/// CiA 402 power drive system states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PowerState {
    /// Statusword `x0xx 0000`.
    NotReadyToSwitchOn,
    /// `x1xx 0000`.
    SwitchOnDisabled,
    /// `x01x 0001`.
    ReadyToSwitchOn,
    /// `x01x 0011`.
    SwitchedOn,
    /// `x01x 0111`.
    OperationEnabled,
    /// `x00x 0111`.
    QuickStopActive,
    /// `x0xx 1111`.
    FaultReactionActive,
    /// `x0xx 1000`.
    Fault,
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

/// One PDO's communication and mapping objects, and its traffic state.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Pdo {
    cob_id: u32,
    transmission: u8,
    count: u8,
    map: [u32; 8],
    /// SYNCs since the last transmission (TPDO types 1–240).
    syncs: u8,
    /// The data last sent (TPDO), to send on change.
    last_sent: Option<Vec<u8>>,
    /// Received data waiting for SYNC (synchronous RPDO).
    received: Option<Vec<u8>>,
}

impl Pdo {
    fn new(cob_id: u32, transmission: u8, map: &[u32]) -> Pdo {
        let mut entries = [0; 8];
        entries[..map.len()].copy_from_slice(map);
        Pdo {
            cob_id,
            transmission,
            count: map.len() as u8,
            map: entries,
            syncs: 0,
            last_sent: None,
            received: None,
        }
    }

    fn valid(&self) -> bool {
        self.cob_id & 0x8000_0000 == 0
    }

    fn can_id(&self) -> u16 {
        (self.cob_id & 0x7FF) as u16
    }

    fn entries(&self) -> impl Iterator<Item = (u16, u8, usize)> + '_ {
        self.map[..usize::from(self.count)].iter().map(|raw| {
            (
                (raw >> 16) as u16,
                (raw >> 8) as u8,
                (raw & 0xFF) as usize / 8,
            )
        })
    }
}

/// An object dictionary entry as the SDO server sees it.
struct Entry {
    size: usize,
    writable: bool,
    value: u32,
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

    /// A fault from outside the CANopen interface (a machine's safety chain, a
    /// supervisor): the drive goes through Fault reaction active to Fault and sends EMCY
    /// `code`, as for a fault of its own. Nothing happens in Fault (the first fault
    /// stands).
    pub fn external_fault(&mut self, code: u16) {
        if self.power != PowerState::Fault {
            self.fault(code);
        }
    }

    /// Frames to put on the bus since the last call.
    pub fn take_output(&mut self) -> Vec<Frame> {
        std::mem::take(&mut self.output)
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<DriveEvent> {
        std::mem::take(&mut self.events)
    }

    /// Lets `dt` pass: heartbeats fall due.
    pub fn advance(&mut self, dt: Duration) {
        let end = self.now + dt;
        while let Some(due) = self.next_heartbeat.filter(|due| *due <= end) {
            self.now = due;
            self.send(0x700, &[self.nmt.heartbeat()]);
            self.next_heartbeat = Some(due + Duration::from_millis(self.heartbeat_ms.into()));
        }
        self.now = end;
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

    /// Statusword 6041h.
    pub fn statusword(&self) -> u16 {
        let state = match self.power {
            PowerState::NotReadyToSwitchOn => 0x00,
            PowerState::SwitchOnDisabled => 0x40,
            PowerState::ReadyToSwitchOn => 0x21,
            PowerState::SwitchedOn => 0x23,
            PowerState::OperationEnabled => 0x27,
            PowerState::QuickStopActive => 0x07,
            PowerState::FaultReactionActive => 0x0F,
            PowerState::Fault => 0x08,
        };
        let mut word = state | 1 << 4 | 1 << 9;
        if self.following() {
            word |= 1 << 12;
        }
        if self.following_error {
            word |= 1 << 13;
        }
        word
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

    fn set_nmt(&mut self, state: NmtState) {
        if state == self.nmt {
            return;
        }
        if self.nmt == NmtState::Operational {
            self.rpdo.iter_mut().for_each(|pdo| pdo.received = None);
        }
        if state == NmtState::Operational {
            for pdo in &mut self.tpdo {
                pdo.last_sent = None;
                pdo.syncs = 0;
            }
        }
        self.nmt = state;
        self.events.push(DriveEvent::Nmt {
            time: self.now,
            state,
        });
    }

    fn set_power(&mut self, state: PowerState) {
        if state != self.power {
            self.power = state;
            self.events.push(DriveEvent::Power {
                time: self.now,
                state,
            });
        }
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

    /// Communication objects to power-on values, boot-up, Pre-operational.
    fn reset_communication(&mut self) {
        (self.rpdo, self.tpdo) = default_pdos(self.config.node);
        self.heartbeat_ms = self.config.heartbeat_ms;
        self.restart_heartbeat();
        self.send(0x700, &[0x00]);
        self.nmt = NmtState::PreOperational;
        self.events.push(DriveEvent::Nmt {
            time: self.now,
            state: NmtState::PreOperational,
        });
    }

    fn restart_heartbeat(&mut self) {
        self.next_heartbeat = (self.heartbeat_ms > 0)
            .then(|| self.now + Duration::from_millis(self.heartbeat_ms.into()));
    }

    fn nmt_command(&mut self, data: &[u8]) {
        let [specifier, node] = data else { return };
        if *node != 0 && *node != self.config.node {
            return;
        }
        match specifier {
            0x01 => self.set_nmt(NmtState::Operational),
            0x02 => self.set_nmt(NmtState::Stopped),
            0x80 => self.set_nmt(NmtState::PreOperational),
            0x81 => {
                self.reset_application();
                self.reset_communication();
            }
            0x82 => self.reset_communication(),
            _ => {}
        }
    }

    fn emcy(&mut self, code: u16) {
        if self.nmt != NmtState::Stopped {
            let [lo, hi] = code.to_le_bytes();
            self.send(0x080, &[lo, hi, self.error_register, 0, 0, 0, 0, 0]);
        }
    }

    fn fault(&mut self, code: u16) {
        self.set_power(PowerState::FaultReactionActive);
        self.set_power(PowerState::Fault);
        self.error_register |= 0x01;
        self.events.push(DriveEvent::Fault {
            time: self.now,
            code,
        });
        self.emcy(code);
    }

    /// A controlword written (by SDO or RPDO).
    fn command(&mut self, word: u16) {
        let rising_reset = word & 0x80 != 0 && self.controlword & 0x80 == 0;
        self.controlword = word;
        if self.power == PowerState::Fault {
            if rising_reset {
                self.following_error = false;
                self.error_register = 0;
                self.set_power(PowerState::SwitchOnDisabled);
                self.emcy(0x0000);
            }
            return;
        }
        if word & 0x80 != 0 {
            return;
        }
        self.set_power(next_power_state(self.power, word));
    }

    fn sync(&mut self, data: &[u8]) {
        // SYNC carries nothing, or a one-byte counter.
        if data.len() > 1 || self.nmt == NmtState::Stopped {
            return;
        }
        if self.nmt == NmtState::Operational {
            for k in 0..4 {
                let pdo = &mut self.rpdo[k];
                if pdo.valid() && pdo.transmission <= 240 {
                    if let Some(data) = pdo.received.take() {
                        self.apply_rpdo(k, &data);
                    }
                }
            }
        }
        if let Some(set_point) = self.active_set_point() {
            self.control_cycle(set_point);
        }
        if self.nmt == NmtState::Operational {
            for k in 0..4 {
                let pdo = &mut self.tpdo[k];
                if !pdo.valid() || pdo.transmission > 240 {
                    continue;
                }
                if pdo.transmission == 0 {
                    self.send_tpdo(k, true);
                } else {
                    pdo.syncs += 1;
                    if pdo.syncs >= pdo.transmission {
                        pdo.syncs = 0;
                        self.send_tpdo(k, false);
                    }
                }
            }
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

    /// Event-driven TPDOs (types 254, 255) whose data changed.
    fn send_changed_tpdos(&mut self) {
        if self.nmt != NmtState::Operational {
            return;
        }
        for k in 0..4 {
            if self.tpdo[k].valid() && self.tpdo[k].transmission >= 254 {
                self.send_tpdo(k, true);
            }
        }
    }

    /// Sends TPDO `k` (only if its data changed, with `on_change`).
    fn send_tpdo(&mut self, k: usize, on_change: bool) {
        let entries: Vec<_> = self.tpdo[k].entries().collect();
        let mut data = Vec::with_capacity(8);
        for (index, sub, bytes) in entries {
            let value = self.entry(index, sub).map_or(0, |entry| entry.value);
            data.extend_from_slice(&value.to_le_bytes()[..bytes]);
        }
        let pdo = &mut self.tpdo[k];
        if on_change && pdo.last_sent.as_ref() == Some(&data) {
            return;
        }
        let frame = Frame::data(pdo.can_id(), &data);
        pdo.last_sent = Some(data);
        self.output.push(frame);
    }

    fn rpdo_frame(&mut self, id: u16, data: &[u8]) {
        if self.nmt != NmtState::Operational {
            return;
        }
        let Some(k) = self.rpdo.iter().position(|p| p.valid() && p.can_id() == id) else {
            return;
        };
        let length: usize = self.rpdo[k].entries().map(|(_, _, bytes)| bytes).sum();
        if data.len() < length {
            self.emcy(EMCY_PDO_LENGTH);
            return;
        }
        if self.rpdo[k].transmission <= 240 {
            self.rpdo[k].received = Some(data[..length].to_vec());
        } else {
            self.apply_rpdo(k, &data[..length]);
        }
    }

    fn apply_rpdo(&mut self, k: usize, data: &[u8]) {
        let entries: Vec<_> = self.rpdo[k].entries().collect();
        let mut at = 0;
        for (index, sub, bytes) in entries {
            let mut value = [0; 4];
            value[..bytes].copy_from_slice(&data[at..at + bytes]);
            at += bytes;
            // Mapped objects are writable; a value out of range (a mode the drive does
            // not have) is dropped, as a write of it by SDO would be refused.
            let _ = self.write(index, sub, u32::from_le_bytes(value));
        }
    }

    fn sdo_request(&mut self, data: &[u8]) {
        if self.nmt == NmtState::Stopped || data.len() != 8 {
            return;
        }
        let index = u16::from_le_bytes([data[1], data[2]]);
        let sub = data[3];
        let answer = match data[0] >> 5 {
            1 => self.sdo_download(data[0], index, sub, &data[4..]),
            2 => self.sdo_upload(index, sub),
            4 => return, // the client aborted: nothing to answer
            _ => Err(abort::COMMAND),
        };
        let [lo, hi] = index.to_le_bytes();
        let reply = match answer {
            Ok((command, value)) => [command, lo, hi, sub, value[0], value[1], value[2], value[3]],
            Err(code) => {
                let c = code.to_le_bytes();
                [0x80, lo, hi, sub, c[0], c[1], c[2], c[3]]
            }
        };
        self.send(0x580, &reply);
    }

    fn sdo_download(
        &mut self,
        command: u8,
        index: u16,
        sub: u8,
        payload: &[u8],
    ) -> Result<(u8, [u8; 4]), u32> {
        if command & 0b10 == 0 {
            return Err(abort::COMMAND);
        }
        let entry = self.entry(index, sub)?;
        if !entry.writable {
            return Err(abort::READ_ONLY);
        }
        if command & 0b01 != 0 {
            let given = 4 - usize::from((command >> 2) & 0b11);
            if given > entry.size {
                return Err(abort::TOO_LONG);
            }
            if given < entry.size {
                return Err(abort::TOO_SHORT);
            }
        }
        let mut value = [0; 4];
        value[..entry.size].copy_from_slice(&payload[..entry.size]);
        self.write(index, sub, u32::from_le_bytes(value))?;
        Ok((0x60, [0; 4]))
    }

    fn sdo_upload(&self, index: u16, sub: u8) -> Result<(u8, [u8; 4]), u32> {
        let entry = self.entry(index, sub)?;
        let command = 0x43 | ((4 - entry.size as u8) << 2);
        let mut value = entry.value.to_le_bytes();
        value[entry.size..].fill(0);
        Ok((command, value))
    }

    /// The object dictionary.
    fn entry(&self, index: u16, sub: u8) -> Result<Entry, u32> {
        let var = |size, writable, value| {
            if sub == 0 {
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            } else {
                Err(abort::NO_SUB)
            }
        };
        match index {
            0x1000 => var(4, false, DEVICE_TYPE),
            0x1001 => var(1, false, self.error_register.into()),
            0x1017 => var(2, true, self.heartbeat_ms.into()),
            0x6040 => var(2, true, self.controlword.into()),
            0x6041 => var(2, false, self.statusword().into()),
            0x6060 => var(1, true, u32::from(self.mode as u8)),
            0x6061 => var(1, false, u32::from(self.mode as u8)),
            0x6064 => var(4, false, self.actual as u32),
            0x6065 => var(4, true, self.window),
            0x607A => var(4, true, self.target as u32),
            0x60C1 => {
                let (size, writable, value) = match sub {
                    0 => (1, false, 1),
                    1 => (4, true, self.interpolation_data as u32),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            }
            0x60C2 => {
                let (value, index) = self.interpolation;
                let (writable, value) = match sub {
                    0 => (false, 2),
                    1 => (true, value.into()),
                    2 => (true, u32::from(index as u8)),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size: 1,
                    writable,
                    value,
                })
            }
            0x1400..=0x1403 | 0x1800..=0x1803 => {
                let pdo = self.pdo(index);
                let (size, writable, value) = match sub {
                    0 => (1, false, 2),
                    1 => (4, true, pdo.cob_id),
                    2 => (1, true, pdo.transmission.into()),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            }
            0x1600..=0x1603 | 0x1A00..=0x1A03 => {
                let pdo = self.pdo(index);
                match sub {
                    0 => Ok(Entry {
                        size: 1,
                        writable: true,
                        value: pdo.count.into(),
                    }),
                    1..=8 => Ok(Entry {
                        size: 4,
                        writable: true,
                        value: pdo.map[usize::from(sub) - 1],
                    }),
                    _ => Err(abort::NO_SUB),
                }
            }
            _ => Err(abort::NO_OBJECT),
        }
    }

    /// The PDO behind a communication or mapping index (1400h…1A03h).
    fn pdo(&self, index: u16) -> &Pdo {
        let k = usize::from(index & 0x3);
        if index < 0x1800 {
            &self.rpdo[k]
        } else {
            &self.tpdo[k]
        }
    }

    fn pdo_mut(&mut self, index: u16) -> &mut Pdo {
        let k = usize::from(index & 0x3);
        if index < 0x1800 {
            &mut self.rpdo[k]
        } else {
            &mut self.tpdo[k]
        }
    }

    /// Writes a writable object (its existence and size already checked).
    fn write(&mut self, index: u16, sub: u8, value: u32) -> Result<(), u32> {
        match index {
            0x1017 => {
                self.heartbeat_ms = value as u16;
                self.restart_heartbeat();
            }
            0x6040 => self.command(value as u16),
            0x6060 => match value as u8 as i8 {
                mode @ (0 | MODE_IP | MODE_CSP) => self.mode = mode,
                _ => return Err(abort::INVALID),
            },
            0x6065 => self.window = value,
            0x607A => self.target = value as i32,
            // Sub-index 0 is read-only: only sub-index 1 gets here.
            0x60C1 => self.interpolation_data = value as i32,
            0x60C2 => self.write_interpolation(sub, value as u8)?,
            0x1400..=0x1403 | 0x1800..=0x1803 => self.write_communication(index, sub, value)?,
            0x1600..=0x1603 | 0x1A00..=0x1A03 => self.write_mapping(index, sub, value)?,
            _ => return Err(abort::READ_ONLY),
        }
        Ok(())
    }

    /// 60C2h sub-index 1 (value) or 2 (index); see the module docs for what is refused.
    fn write_interpolation(&mut self, sub: u8, byte: u8) -> Result<(), u32> {
        if sub == 1 {
            if byte == 0 {
                return Err(abort::INVALID);
            }
            self.interpolation.0 = byte;
        } else {
            let index = byte as i8;
            if !INTERPOLATION_INDICES.contains(&index) {
                return Err(abort::INVALID);
            }
            self.interpolation.1 = index;
        }
        Ok(())
    }

    fn write_communication(&mut self, index: u16, sub: u8, value: u32) -> Result<(), u32> {
        let pdo = self.pdo_mut(index);
        if sub == 2 {
            let kind = value as u8;
            if (241..=253).contains(&kind) {
                return Err(abort::INVALID);
            }
            pdo.transmission = kind;
            return Ok(());
        }
        // Sub-index 1, the COB-ID: bits 11–29 must be 0 (11-bit identifiers only).
        let valid = value & 0x8000_0000 == 0;
        let id = value & 0x7FF;
        if value & 0x3FFF_F800 != 0 {
            return Err(abort::INVALID);
        }
        if valid && (pdo.count == 0 || id == 0 || (pdo.valid() && id != u32::from(pdo.can_id()))) {
            return Err(abort::INVALID);
        }
        pdo.cob_id = value;
        pdo.syncs = 0;
        pdo.last_sent = None;
        pdo.received = None;
        Ok(())
    }

    fn write_mapping(&mut self, index: u16, sub: u8, value: u32) -> Result<(), u32> {
        let receive = index < 0x1800;
        let pdo = self.pdo_mut(index);
        if pdo.valid() || (sub != 0 && pdo.count != 0) {
            return Err(abort::UNSUPPORTED);
        }
        if sub != 0 {
            if !mappable(receive, value) {
                return Err(abort::CANNOT_MAP);
            }
            pdo.map[usize::from(sub) - 1] = value;
            return Ok(());
        }
        let count = value as u8;
        if count > 8 {
            return Err(abort::MAP_TOO_LONG);
        }
        let entries = &pdo.map[..usize::from(count)];
        if !entries.iter().all(|raw| mappable(receive, *raw)) {
            return Err(abort::CANNOT_MAP);
        }
        if entries.iter().map(|raw| raw & 0xFF).sum::<u32>() > 64 {
            return Err(abort::MAP_TOO_LONG);
        }
        pdo.count = count;
        Ok(())
    }
}

/// The objects a PDO can carry, as mapping values (index, sub-index, bit length).
fn mappable(receive: bool, raw: u32) -> bool {
    const RECEIVE: [u32; 4] = [0x6040_0010, 0x607A_0020, 0x6060_0008, 0x60C1_0120];
    const TRANSMIT: [u32; 3] = [0x6041_0010, 0x6064_0020, 0x6061_0008];
    if receive {
        RECEIVE.contains(&raw)
    } else {
        TRANSMIT.contains(&raw)
    }
}

/// Power-on PDOs: RPDO1 = controlword + target, TPDO1 = statusword + actual position,
/// both every SYNC; the rest invalid on their predefined identifiers.
fn default_pdos(node: u8) -> ([Pdo; 4], [Pdo; 4]) {
    let node = u32::from(node);
    let invalid = |base: u32| Pdo::new(0x8000_0000 | (base + node), 0xFF, &[]);
    let rpdo = [
        Pdo::new(0x200 + node, 1, &[0x6040_0010, 0x607A_0020]),
        invalid(0x300),
        invalid(0x400),
        invalid(0x500),
    ];
    // TPDOs without remote request (COB-ID bit 30): the sim answers none.
    let tpdo = [
        Pdo::new(0x4000_0000 | (0x180 + node), 1, &[0x6041_0010, 0x6064_0020]),
        invalid(0x4000_0280),
        invalid(0x4000_0380),
        invalid(0x4000_0480),
    ];
    (rpdo, tpdo)
}

/// CiA 402's transitions caused by a controlword with bit 7 low.
fn next_power_state(state: PowerState, word: u16) -> PowerState {
    use PowerState::*;
    let bits = word & 0x0F;
    let disable_voltage = bits & 0b0010 == 0;
    let quick_stop = !disable_voltage && bits & 0b0100 == 0;
    let shutdown = bits & 0b0111 == 0b0110;
    let switch_on = bits == 0b0111;
    let enable = bits == 0b1111;
    match state {
        SwitchOnDisabled if shutdown => ReadyToSwitchOn,
        ReadyToSwitchOn if switch_on => SwitchedOn,
        ReadyToSwitchOn if enable => OperationEnabled,
        SwitchedOn if enable => OperationEnabled,
        ReadyToSwitchOn | SwitchedOn if disable_voltage || quick_stop => SwitchOnDisabled,
        SwitchedOn | OperationEnabled if shutdown => ReadyToSwitchOn,
        OperationEnabled if switch_on => SwitchedOn,
        OperationEnabled if disable_voltage => SwitchOnDisabled,
        OperationEnabled if quick_stop => QuickStopActive,
        QuickStopActive if disable_voltage => SwitchOnDisabled,
        QuickStopActive if enable => OperationEnabled,
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn booted(config: DriveConfig) -> Drive {
        let mut drive = Drive::new(config).unwrap();
        drive.take_output();
        drive.take_events();
        drive
    }

    /// Node 1, started (Operational), output drained.
    fn operational() -> Drive {
        let mut drive = booted(DriveConfig::new(1));
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        drive.take_output();
        drive
    }

    /// Sends an SDO request to node 1 and returns the 8 answer bytes, if any.
    fn sdo(drive: &mut Drive, request: [u8; 8]) -> Option<Vec<u8>> {
        drive.receive(&Frame::data(0x601, &request));
        let answers: Vec<Frame> = drive
            .take_output()
            .into_iter()
            .filter(|f| f.id == 0x581)
            .collect();
        assert!(answers.len() <= 1);
        answers.into_iter().next().map(|f| f.data)
    }

    /// Expedited download of `size` bytes of `value`; `Err(abort code)` on abort.
    fn write(drive: &mut Drive, index: u16, sub: u8, value: u32, size: u8) -> Result<(), u32> {
        let [lo, hi] = index.to_le_bytes();
        let v = value.to_le_bytes();
        let command = 0x23 | ((4 - size) << 2);
        let answer = sdo(drive, [command, lo, hi, sub, v[0], v[1], v[2], v[3]]).unwrap();
        match answer[0] {
            0x60 => {
                assert_eq!(answer, [0x60, lo, hi, sub, 0, 0, 0, 0]);
                Ok(())
            }
            0x80 => Err(u32::from_le_bytes([
                answer[4], answer[5], answer[6], answer[7],
            ])),
            other => panic!("answer {other:02X}"),
        }
    }

    /// Expedited upload: (command byte, value) or `Err(abort code)`.
    fn read(drive: &mut Drive, index: u16, sub: u8) -> Result<(u8, u32), u32> {
        let [lo, hi] = index.to_le_bytes();
        let answer = sdo(drive, [0x40, lo, hi, sub, 0, 0, 0, 0]).unwrap();
        let value = u32::from_le_bytes([answer[4], answer[5], answer[6], answer[7]]);
        if answer[0] == 0x80 {
            Err(value)
        } else {
            Ok((answer[0], value))
        }
    }

    fn sync(drive: &mut Drive) -> Vec<Frame> {
        drive.receive(&Frame::data(0x080, &[]));
        drive.take_output()
    }

    /// RPDO1 with controlword and target, as mapped at power-up.
    fn rpdo1(drive: &mut Drive, controlword: u16, target: i32) {
        let mut data = controlword.to_le_bytes().to_vec();
        data.extend_from_slice(&target.to_le_bytes());
        drive.receive(&Frame::data(0x201, &data));
    }

    /// Walks to Operation enabled in CSP through RPDO1 on SYNC.
    fn enabled() -> Drive {
        let mut drive = operational();
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        for word in [0x06, 0x07, 0x0F] {
            rpdo1(&mut drive, word, 0);
            sync(&mut drive);
        }
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        drive
    }

    /// Node 1 in interpolated position mode with RPDO1 remapped to controlword and
    /// 60C1h sub-index 1 (CiA 301's procedure), started; output drained.
    fn interpolating(config: DriveConfig) -> Drive {
        let mut drive = booted(config);
        write(&mut drive, 0x6060, 0, 7, 1).unwrap();
        write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
        write(&mut drive, 0x1600, 0, 0, 1).unwrap();
        write(&mut drive, 0x1600, 1, 0x6040_0010, 4).unwrap();
        write(&mut drive, 0x1600, 2, 0x60C1_0120, 4).unwrap();
        write(&mut drive, 0x1600, 0, 2, 1).unwrap();
        write(&mut drive, 0x1400, 1, 0x0000_0201, 4).unwrap();
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        drive.take_output();
        drive
    }

    /// The (set-point, actual) of each control cycle since the last call.
    fn cycles(drive: &mut Drive) -> Vec<(i32, i32)> {
        drive
            .take_events()
            .into_iter()
            .filter_map(|e| match e {
                DriveEvent::Cycle { target, actual, .. } => Some((target, actual)),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn power_up_sends_boot_up_and_waits_pre_operational() {
        let mut drive = Drive::new(DriveConfig::new(3)).unwrap();
        // CiA 301: boot-up is one byte 0x00 on 0x700 + node.
        assert_eq!(drive.take_output(), [Frame::data(0x703, &[0x00])]);
        assert_eq!(drive.nmt_state(), NmtState::PreOperational);
        // CiA 402: Not ready to switch on and on to Switch on disabled by itself.
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
        assert_eq!(drive.statusword(), 0x0250);
        assert_eq!(
            drive.take_events(),
            [
                DriveEvent::Power {
                    time: Duration::ZERO,
                    state: PowerState::SwitchOnDisabled
                },
                DriveEvent::Nmt {
                    time: Duration::ZERO,
                    state: NmtState::PreOperational
                },
            ]
        );
        assert_eq!(
            Drive::new(DriveConfig::new(0)).unwrap_err(),
            DriveConfigError::NodeId(0)
        );
        assert!(Drive::new(DriveConfig::new(128)).is_err());
        assert!(Drive::new(DriveConfig::new(127)).is_ok());
    }

    #[test]
    fn nmt_commands_move_the_node() {
        let mut drive = booted(DriveConfig::new(2));
        // For another node, the wrong length, an unknown specifier: nothing.
        for data in [
            &[0x01, 0x03][..],
            &[0x01],
            &[0x01, 0x02, 0x00],
            &[0x03, 0x02],
        ] {
            drive.receive(&Frame::data(0x000, data));
            assert_eq!(drive.nmt_state(), NmtState::PreOperational);
        }
        drive.receive(&Frame::data(0x000, &[0x01, 0x02]));
        assert_eq!(drive.nmt_state(), NmtState::Operational);
        drive.receive(&Frame::data(0x000, &[0x02, 0x00])); // all nodes
        assert_eq!(drive.nmt_state(), NmtState::Stopped);
        drive.receive(&Frame::data(0x000, &[0x80, 0x02]));
        assert_eq!(drive.nmt_state(), NmtState::PreOperational);
        drive.receive(&Frame::data(0x000, &[0x01, 0x00]));
        assert_eq!(drive.nmt_state(), NmtState::Operational);
        // Reset communication: boot-up again, Pre-operational.
        drive.take_output();
        drive.receive(&Frame::data(0x000, &[0x82, 0x02]));
        assert_eq!(drive.take_output(), [Frame::data(0x702, &[0x00])]);
        assert_eq!(drive.nmt_state(), NmtState::PreOperational);
    }

    #[test]
    fn resets_restore_their_objects() {
        let mut drive = booted(DriveConfig::new(1));
        write(&mut drive, 0x1017, 0, 100, 2).unwrap();
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        write(&mut drive, 0x6040, 0, 0x06, 2).unwrap();
        write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
        // Reset communication: 1017h and the PDOs, not the profile's objects.
        drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
        drive.take_output();
        assert_eq!(read(&mut drive, 0x1017, 0), Ok((0x4B, 0)));
        assert_eq!(read(&mut drive, 0x1800, 1), Ok((0x43, 0x4000_0181)));
        assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 8)));
        assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
        // Reset node: the profile's objects too.
        drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
        assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x00])]);
        assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 0)));
        assert_eq!(read(&mut drive, 0x6040, 0), Ok((0x4B, 0)));
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    }

    #[test]
    fn heartbeats_follow_1017h() {
        let mut drive = booted(DriveConfig::new(1));
        drive.advance(Duration::from_secs(10));
        assert!(drive.take_output().is_empty(), "1017h = 0: no heartbeat");
        write(&mut drive, 0x1017, 0, 100, 2).unwrap();
        drive.advance(250 * MS);
        // At 10.1 s and 10.2 s, the Pre-operational byte 0x7F.
        assert_eq!(drive.take_output(), vec![Frame::data(0x701, &[0x7F]); 2]);
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        drive.take_output();
        drive.advance(50 * MS);
        assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x05])]);
        drive.receive(&Frame::data(0x000, &[0x02, 0x01]));
        drive.advance(100 * MS);
        assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x04])]);
        assert_eq!(drive.now(), Duration::from_millis(10_400));
        // A configured power-on period starts at boot-up.
        let mut beating = booted(DriveConfig {
            heartbeat_ms: 20,
            ..DriveConfig::new(4)
        });
        beating.advance(19 * MS);
        assert!(beating.take_output().is_empty());
        beating.advance(MS);
        assert_eq!(beating.take_output(), [Frame::data(0x704, &[0x7F])]);
    }

    #[test]
    fn stopped_serves_no_sdo_and_no_sync() {
        let mut drive = operational();
        drive.receive(&Frame::data(0x000, &[0x02, 0x01]));
        assert_eq!(sdo(&mut drive, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]), None);
        assert!(sync(&mut drive).is_empty());
    }

    #[test]
    fn uploads_answer_with_the_objects_size() {
        let mut drive = booted(DriveConfig {
            position: -5,
            ..DriveConfig::new(1)
        });
        // n = 4 − size in bits 3–2: 0x43 four bytes, 0x4B two, 0x4F one.
        assert_eq!(read(&mut drive, 0x1000, 0), Ok((0x43, 0x0002_0192)));
        assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0)));
        assert_eq!(read(&mut drive, 0x6041, 0), Ok((0x4B, 0x0250)));
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 0)));
        assert_eq!(read(&mut drive, 0x6064, 0), Ok((0x43, -5i32 as u32)));
        assert_eq!(read(&mut drive, 0x607A, 0), Ok((0x43, -5i32 as u32)));
        assert_eq!(read(&mut drive, 0x6065, 0), Ok((0x43, 10_000)));
        assert_eq!(read(&mut drive, 0x1400, 0), Ok((0x4F, 2)));
        assert_eq!(read(&mut drive, 0x1400, 1), Ok((0x43, 0x201)));
        assert_eq!(read(&mut drive, 0x1401, 1), Ok((0x43, 0x8000_0301)));
        assert_eq!(read(&mut drive, 0x1800, 2), Ok((0x4F, 1)));
        assert_eq!(read(&mut drive, 0x1600, 0), Ok((0x4F, 2)));
        assert_eq!(read(&mut drive, 0x1600, 2), Ok((0x43, 0x607A_0020)));
        assert_eq!(read(&mut drive, 0x1A00, 1), Ok((0x43, 0x6041_0010)));
        assert_eq!(read(&mut drive, 0x1A03, 0), Ok((0x4F, 0)));
    }

    #[test]
    fn sdo_aborts_carry_cia_301_codes() {
        let mut drive = booted(DriveConfig::new(1));
        assert_eq!(read(&mut drive, 0x2000, 0), Err(0x0602_0000));
        assert_eq!(read(&mut drive, 0x1404, 1), Err(0x0602_0000));
        assert_eq!(read(&mut drive, 0x6041, 1), Err(0x0609_0011));
        assert_eq!(read(&mut drive, 0x1800, 3), Err(0x0609_0011));
        assert_eq!(read(&mut drive, 0x1A00, 9), Err(0x0609_0011));
        assert_eq!(write(&mut drive, 0x6041, 0, 0, 2), Err(0x0601_0002));
        assert_eq!(write(&mut drive, 0x1000, 0, 0, 4), Err(0x0601_0002));
        assert_eq!(write(&mut drive, 0x1800, 0, 5, 1), Err(0x0601_0002));
        assert_eq!(write(&mut drive, 0x607A, 0, 0, 2), Err(0x0607_0013));
        assert_eq!(write(&mut drive, 0x6040, 0, 6, 4), Err(0x0607_0012));
        assert_eq!(write(&mut drive, 0x6060, 0, 1, 1), Err(0x0609_0030));
        assert_eq!(write(&mut drive, 0x6060, 0, 0xFF, 1), Err(0x0609_0030));
        // A segmented download (e = 0) and the segment services are not served.
        let segmented = [0x21, 0x7A, 0x60, 0, 4, 0, 0, 0];
        let upload_segment = [0x60, 0x7A, 0x60, 0, 0, 0, 0, 0];
        for request in [segmented, upload_segment] {
            assert_eq!(
                sdo(&mut drive, request),
                Some(vec![0x80, 0x7A, 0x60, 0, 0x01, 0x00, 0x04, 0x05])
            );
        }
        // A client's abort gets no answer; neither does a frame that is not 8 bytes.
        assert_eq!(sdo(&mut drive, [0x80, 0x7A, 0x60, 0, 0, 0, 0, 0x08]), None);
        drive.receive(&Frame::data(0x601, &[0x40, 0x41, 0x60, 0]));
        assert!(drive.take_output().is_empty());
    }

    #[test]
    fn a_download_without_size_takes_the_objects_bytes() {
        let mut drive = booted(DriveConfig::new(1));
        // e = 1, s = 0: "unspecified number of bytes"; 607Ah takes all four.
        let answer = sdo(&mut drive, [0x22, 0x7A, 0x60, 0, 0x10, 0x27, 0, 0]);
        assert_eq!(answer, Some(vec![0x60, 0x7A, 0x60, 0, 0, 0, 0, 0]));
        assert_eq!(drive.target(), 10_000);
        // 6060h takes one: the bytes after it do not matter.
        sdo(&mut drive, [0x22, 0x60, 0x60, 0, 8, 0xAA, 0xBB, 0xCC]);
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 8)));
    }

    #[test]
    fn the_interpolation_period_is_60c2h_value_times_ten_to_the_index() {
        let mut drive = booted(DriveConfig::new(1));
        // Sub-index 0 holds the highest sub-index, 2; power-up 1 × 10⁻³ s. One byte each:
        // command 0x4F; the index −3 as INTEGER8 is FDh.
        assert_eq!(read(&mut drive, 0x60C2, 0), Ok((0x4F, 2)));
        assert_eq!(read(&mut drive, 0x60C2, 1), Ok((0x4F, 1)));
        assert_eq!(read(&mut drive, 0x60C2, 2), Ok((0x4F, 0xFD)));
        assert_eq!(drive.interpolation_period(), MS);
        let cases = [
            (4, -3, Duration::from_millis(4)),
            (25, -4, Duration::from_micros(2500)),
            (1, -6, Duration::from_micros(1)),
            (255, 0, Duration::from_secs(255)),
        ];
        for (value, index, period) in cases {
            write(&mut drive, 0x60C2, 1, value, 1).unwrap();
            write(&mut drive, 0x60C2, 2, u32::from(index as u8), 1).unwrap();
            assert_eq!(drive.interpolation_period(), period, "{value} × 10^{index}");
            assert_eq!(read(&mut drive, 0x60C2, 1), Ok((0x4F, value)));
            assert_eq!(
                read(&mut drive, 0x60C2, 2),
                Ok((0x4F, u32::from(index as u8)))
            );
        }
    }

    #[test]
    fn impossible_interpolation_periods_are_refused() {
        let mut drive = booted(DriveConfig::new(1));
        write(&mut drive, 0x60C2, 1, 4, 1).unwrap();
        assert_eq!(write(&mut drive, 0x60C2, 0, 3, 1), Err(0x0601_0002));
        assert_eq!(read(&mut drive, 0x60C2, 3), Err(0x0609_0011));
        assert_eq!(write(&mut drive, 0x60C2, 3, 0, 1), Err(0x0609_0011));
        // Both are one byte.
        assert_eq!(write(&mut drive, 0x60C2, 1, 4, 2), Err(0x0607_0012));
        assert_eq!(write(&mut drive, 0x60C2, 2, 0xFD, 4), Err(0x0607_0012));
        // No period at all, or units above a second or below a microsecond.
        assert_eq!(write(&mut drive, 0x60C2, 1, 0, 1), Err(0x0609_0030));
        for index in [1i8, 63, -7, -128] {
            let byte = u32::from(index as u8);
            assert_eq!(write(&mut drive, 0x60C2, 2, byte, 1), Err(0x0609_0030));
        }
        assert_eq!(drive.interpolation_period(), Duration::from_millis(4));
    }

    #[test]
    fn reset_node_restores_the_interpolation_period() {
        let mut drive = booted(DriveConfig::new(1));
        write(&mut drive, 0x60C2, 1, 4, 1).unwrap();
        // A profile object (6000h–9FFFh): reset communication keeps it, reset node does
        // not.
        drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
        assert_eq!(drive.interpolation_period(), Duration::from_millis(4));
        drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
        assert_eq!(drive.interpolation_period(), MS);
    }

    #[test]
    fn the_power_state_machine_follows_the_controlword() {
        use PowerState::*;
        let mut drive = booted(DriveConfig::new(1));
        let mut step = |word: u32, expected: PowerState, statusword: u16| {
            write(&mut drive, 0x6040, 0, word, 2).unwrap();
            assert_eq!(drive.power_state(), expected, "after {word:02X}");
            assert_eq!(drive.statusword(), statusword, "after {word:02X}");
        };
        step(0x07, SwitchOnDisabled, 0x0250); // switch on is not transition 2
        step(0x06, ReadyToSwitchOn, 0x0231); // 2
        step(0x07, SwitchedOn, 0x0233); // 3
        step(0x0F, OperationEnabled, 0x0237); // 4 (no mode: bit 12 clear)
        step(0x07, SwitchedOn, 0x0233); // 5
        step(0x06, ReadyToSwitchOn, 0x0231); // 6
        step(0x00, SwitchOnDisabled, 0x0250); // 7
        step(0x06, ReadyToSwitchOn, 0x0231);
        step(0x0F, OperationEnabled, 0x0237); // 3 + 4
        step(0x06, ReadyToSwitchOn, 0x0231); // 8
        step(0x0F, OperationEnabled, 0x0237);
        step(0x00, SwitchOnDisabled, 0x0250); // 9
        step(0x06, ReadyToSwitchOn, 0x0231);
        step(0x07, SwitchedOn, 0x0233);
        step(0x02, SwitchOnDisabled, 0x0250); // 10
        step(0x06, ReadyToSwitchOn, 0x0231);
        step(0x0F, OperationEnabled, 0x0237);
        step(0x02, QuickStopActive, 0x0217); // 11
        step(0x06, QuickStopActive, 0x0217); // shutdown does not leave it
        step(0x0F, OperationEnabled, 0x0237); // 16
        step(0x0B, QuickStopActive, 0x0217); // quick stop with enable operation set
        step(0x00, SwitchOnDisabled, 0x0250); // 12
        step(0x86, SwitchOnDisabled, 0x0250); // bit 7 high: no command acts
    }

    #[test]
    fn rpdo1_is_applied_at_sync_and_tpdo1_answers() {
        let mut drive = enabled();
        // Received between SYNCs, applied only at the next one; the last one wins.
        rpdo1(&mut drive, 0x0F, 300);
        rpdo1(&mut drive, 0x0F, 400);
        assert_eq!(drive.target(), 0);
        let frames = sync(&mut drive);
        assert_eq!(drive.target(), 400);
        assert_eq!(drive.position(), 400);
        // TPDO1: statusword 0x1237 (bit 12: following the target), position 400.
        assert_eq!(
            frames,
            [Frame::data(0x181, &[0x37, 0x12, 0x90, 0x01, 0, 0])]
        );
        // At most max_step (1000) counts a cycle.
        rpdo1(&mut drive, 0x0F, -2000);
        sync(&mut drive);
        assert_eq!(drive.position(), -600);
        sync(&mut drive);
        assert_eq!(drive.position(), -1600);
        let cycles: Vec<_> = drive
            .take_events()
            .into_iter()
            .filter_map(|e| match e {
                DriveEvent::Cycle { target, actual, .. } => Some((target, actual)),
                _ => None,
            })
            .collect();
        assert_eq!(
            cycles[cycles.len() - 3..],
            [(400, 400), (-2000, -600), (-2000, -1600)]
        );
    }

    #[test]
    fn pdos_only_run_in_operational() {
        let mut drive = booted(DriveConfig::new(1));
        rpdo1(&mut drive, 0x06, 0);
        assert!(sync(&mut drive).is_empty(), "no TPDO in Pre-operational");
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
        // An RPDO received in Operational but not applied is dropped on leaving it.
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        rpdo1(&mut drive, 0x06, 0);
        drive.receive(&Frame::data(0x000, &[0x80, 0x01]));
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        sync(&mut drive);
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
        // SYNC with a counter byte is a SYNC; with more it is not.
        assert_eq!(drive.take_output().len(), 0);
        drive.receive(&Frame::data(0x080, &[7]));
        assert_eq!(drive.take_output().len(), 1);
        drive.receive(&Frame::data(0x080, &[7, 7]));
        assert!(drive.take_output().is_empty());
    }

    #[test]
    fn a_short_rpdo_is_dropped_with_emcy_8210() {
        let mut drive = operational();
        drive.receive(&Frame::data(0x201, &[0x06, 0x00, 0x00]));
        assert_eq!(
            drive.take_output(),
            [Frame::data(0x081, &[0x10, 0x82, 0, 0, 0, 0, 0, 0])]
        );
        sync(&mut drive);
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
        // Extra bytes are ignored.
        drive.receive(&Frame::data(0x201, &[0x06, 0, 0, 0, 0, 0, 0xFF, 0xFF]));
        sync(&mut drive);
        assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
    }

    #[test]
    fn a_following_error_faults_with_emcy_8611_until_reset() {
        let mut drive = booted(DriveConfig {
            max_step: 10,
            following_error_window: 100,
            ..DriveConfig::new(1)
        });
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        for word in [0x06, 0x07, 0x0F] {
            rpdo1(&mut drive, word, 0);
            sync(&mut drive);
        }
        // 110 counts away: after one 10-count cycle 100 remain, within the window; then
        // 500 away: 480 remain.
        rpdo1(&mut drive, 0x0F, 110);
        sync(&mut drive);
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        rpdo1(&mut drive, 0x0F, 500);
        let frames = sync(&mut drive);
        assert_eq!(drive.position(), 20);
        // EMCY 8611h with error register bit 0, then TPDO1 showing Fault (x0xx 1000) with
        // bit 13, following error.
        assert_eq!(
            frames,
            [
                Frame::data(0x081, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
                Frame::data(0x181, &[0x18, 0x22, 20, 0, 0, 0]),
            ]
        );
        assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0x01)));
        assert!(drive.take_events().contains(&DriveEvent::Fault {
            time: Duration::ZERO,
            code: 0x8611
        }));
        // The fault holds: nothing moves, enable does nothing.
        rpdo1(&mut drive, 0x0F, 500);
        sync(&mut drive);
        assert_eq!(
            (drive.power_state(), drive.position()),
            (PowerState::Fault, 20)
        );
        // Fault reset on the rising edge of bit 7: EMCY 0000h, Switch on disabled.
        rpdo1(&mut drive, 0x80, 20);
        let frames = sync(&mut drive);
        assert_eq!(frames[0], Frame::data(0x081, &[0; 8]));
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
        assert_eq!(drive.statusword(), 0x0250);
        assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0)));
    }

    #[test]
    fn fault_reset_needs_an_edge() {
        let mut drive = enabled();
        write(&mut drive, 0x6065, 0, 0, 4).unwrap();
        write(&mut drive, 0x6040, 0, 0x80, 2).unwrap(); // bit 7 high before the fault
        rpdo1(&mut drive, 0x80, 5000);
        sync(&mut drive);
        // 0x80 did not count as a command: the drive kept running, 1000 counts a cycle,
        // and faulted with a window of 0.
        assert_eq!(drive.power_state(), PowerState::Fault);
        write(&mut drive, 0x6040, 0, 0x80, 2).unwrap();
        assert_eq!(drive.power_state(), PowerState::Fault, "no edge");
        write(&mut drive, 0x6040, 0, 0x00, 2).unwrap();
        write(&mut drive, 0x6040, 0, 0x80, 2).unwrap();
        assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    }

    #[test]
    fn positions_wrap_modulo_2_pow_32() {
        let mut drive = booted(DriveConfig {
            position: i32::MAX - 500,
            ..DriveConfig::new(1)
        });
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        for word in [0x06, 0x07, 0x0F] {
            rpdo1(&mut drive, word, i32::MAX - 500);
            sync(&mut drive);
        }
        // 1000 counts on from i32::MAX − 500: past the top, to i32::MIN + 499, in one
        // cycle, within the window.
        rpdo1(&mut drive, 0x0F, i32::MIN + 499);
        let frames = sync(&mut drive);
        assert_eq!(drive.position(), i32::MIN + 499);
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        let mut tpdo = vec![0x37, 0x12];
        tpdo.extend_from_slice(&(i32::MIN + 499).to_le_bytes());
        assert_eq!(frames, [Frame::data(0x181, &tpdo)]);
        // Back the other way, and a following error measured across the wrap too.
        rpdo1(&mut drive, 0x0F, i32::MAX - 20_000);
        sync(&mut drive);
        assert_eq!(drive.position(), i32::MAX - 500);
        assert_eq!(drive.power_state(), PowerState::Fault);
        assert!(drive.take_events().contains(&DriveEvent::Fault {
            time: Duration::ZERO,
            code: EMCY_FOLLOWING_ERROR
        }));
    }

    #[test]
    fn a_target_beyond_the_software_limits_faults_before_moving() {
        let mut drive = booted(DriveConfig {
            software_limits: Some((-100, 5000)),
            ..DriveConfig::new(2)
        });
        drive.receive(&Frame::data(0x000, &[0x01, 0x02]));
        drive.receive(&Frame::data(0x602, &[0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]));
        let rpdo = |drive: &mut Drive, word: u16, target: i32| {
            let mut data = word.to_le_bytes().to_vec();
            data.extend_from_slice(&target.to_le_bytes());
            drive.receive(&Frame::data(0x202, &data));
            drive.receive(&Frame::data(0x080, &[]));
            drive.take_output()
        };
        for word in [0x06, 0x07, 0x0F] {
            rpdo(&mut drive, word, 0);
        }
        // Up to the limit is fine; one count past it faults, with no motion, EMCY 8612h.
        rpdo(&mut drive, 0x0F, 5000);
        assert_eq!(drive.position(), 1000);
        let frames = rpdo(&mut drive, 0x0F, 5001);
        assert_eq!(drive.position(), 1000);
        assert_eq!(drive.power_state(), PowerState::Fault);
        assert_eq!(
            frames[0],
            Frame::data(0x082, &[0x12, 0x86, 0x01, 0, 0, 0, 0, 0])
        );
        // Reset, and a target below the limit does the same.
        rpdo(&mut drive, 0x80, 1000);
        for word in [0x06, 0x07, 0x0F] {
            rpdo(&mut drive, word, 1000);
        }
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        rpdo(&mut drive, 0x0F, -101);
        assert_eq!(
            (drive.power_state(), drive.position()),
            (PowerState::Fault, 1000)
        );
    }

    #[test]
    fn an_external_fault_sends_its_code_once() {
        let mut drive = enabled();
        drive.external_fault(0xFF64);
        assert_eq!(drive.power_state(), PowerState::Fault);
        assert_eq!(
            drive.take_output(),
            [Frame::data(0x081, &[0x64, 0xFF, 0x01, 0, 0, 0, 0, 0])]
        );
        // A second one while in Fault: the first stands, nothing is sent.
        drive.external_fault(0x9000);
        assert!(drive.take_output().is_empty());
        assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0x01)));
    }

    #[test]
    fn window_ffffffff_switches_the_check_off() {
        let mut drive = booted(DriveConfig {
            max_step: 1,
            ..DriveConfig::new(1)
        });
        drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
        write(&mut drive, 0x6065, 0, u32::MAX, 4).unwrap();
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        for word in [0x06, 0x07, 0x0F] {
            rpdo1(&mut drive, word, 0);
            sync(&mut drive);
        }
        rpdo1(&mut drive, 0x0F, i32::MAX);
        sync(&mut drive);
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        assert_eq!(drive.position(), 1);
    }

    #[test]
    fn remapping_follows_the_procedure() {
        let mut drive = operational();
        let w = |drive: &mut Drive, index, sub, value, size| write(drive, index, sub, value, size);
        // Mapping while the PDO is valid: refused.
        assert_eq!(w(&mut drive, 0x1A00, 0, 0, 1), Err(0x0601_0000));
        assert_eq!(w(&mut drive, 0x1A00, 1, 0x6064_0020, 4), Err(0x0601_0000));
        // Destroy, transmission type 2, clear, map position only, count, create.
        w(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
        w(&mut drive, 0x1800, 2, 2, 1).unwrap();
        // An entry while sub-index 0 is not 0: refused.
        assert_eq!(w(&mut drive, 0x1A00, 1, 0x6064_0020, 4), Err(0x0601_0000));
        w(&mut drive, 0x1A00, 0, 0, 1).unwrap();
        // Enabling with nothing mapped: refused.
        assert_eq!(w(&mut drive, 0x1800, 1, 0x4000_0181, 4), Err(0x0609_0030));
        w(&mut drive, 0x1A00, 1, 0x6064_0020, 4).unwrap();
        w(&mut drive, 0x1A00, 0, 1, 1).unwrap();
        w(&mut drive, 0x1800, 1, 0x4000_0181, 4).unwrap();
        // Type 2: every second SYNC, four bytes of position.
        assert!(sync(&mut drive).is_empty());
        assert_eq!(sync(&mut drive), [Frame::data(0x181, &[0, 0, 0, 0])]);
        assert!(sync(&mut drive).is_empty());
        // A valid PDO's identifier cannot change.
        assert_eq!(w(&mut drive, 0x1800, 1, 0x4000_0191, 4), Err(0x0609_0030));
    }

    #[test]
    fn impossible_mappings_are_refused() {
        let mut drive = operational();
        write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
        write(&mut drive, 0x1600, 0, 0, 1).unwrap();
        let cases = [
            (1, 0x6041_0010, 0x0604_0041), // a TPDO object in an RPDO
            (1, 0x6065_0020, 0x0604_0041), // not mappable at all
            (1, 0x607A_0010, 0x0604_0041), // wrong length
            (0, 9, 0x0604_0042),           // nine entries
            (0, 3, 0x0604_0041),           // counting an entry never written
        ];
        for (sub, value, code) in cases {
            let size = if sub == 0 { 1 } else { 4 };
            assert_eq!(write(&mut drive, 0x1600, sub, value, size), Err(code));
        }
        // Three entries of 80 bits in all.
        for (sub, value) in [(1, 0x607A_0020), (2, 0x607A_0020), (3, 0x6040_0010)] {
            write(&mut drive, 0x1600, sub, value, 4).unwrap();
        }
        assert_eq!(write(&mut drive, 0x1600, 0, 3, 1), Err(0x0604_0042));
        write(&mut drive, 0x1600, 0, 2, 1).unwrap();
        // COB-IDs: 29-bit (bit 29), bits 11–28, identifier 0; transmission types.
        for cob in [0x2000_0201, 0x0000_0A01, 0x0000_0000] {
            assert_eq!(write(&mut drive, 0x1400, 1, cob, 4), Err(0x0609_0030));
        }
        for kind in [241, 252, 253] {
            assert_eq!(write(&mut drive, 0x1400, 2, kind, 1), Err(0x0609_0030));
        }
        for kind in [0, 240, 254, 255] {
            assert_eq!(write(&mut drive, 0x1400, 2, kind, 1), Ok(()));
        }
    }

    #[test]
    fn asynchronous_pdos_act_on_change() {
        let mut drive = operational();
        // RPDO1 asynchronous (255): applied on receipt, no SYNC needed.
        write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
        write(&mut drive, 0x1400, 2, 255, 1).unwrap();
        write(&mut drive, 0x1400, 1, 0x0000_0201, 4).unwrap();
        rpdo1(&mut drive, 0x06, 0);
        assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
        // TPDO1 event-driven (255): sent when the statusword changes, not on SYNC.
        write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
        write(&mut drive, 0x1800, 2, 255, 1).unwrap();
        drive.take_output();
        drive.receive(&Frame::data(
            0x601,
            &[0x23, 0x00, 0x18, 1, 0x81, 0x01, 0, 0x40],
        ));
        let out = drive.take_output();
        assert_eq!(out[1], Frame::data(0x181, &[0x31, 0x02, 0, 0, 0, 0]));
        assert!(sync(&mut drive).is_empty());
        rpdo1(&mut drive, 0x07, 0);
        assert_eq!(
            drive.take_output(),
            [Frame::data(0x181, &[0x33, 0x02, 0, 0, 0, 0])]
        );
        // Acyclic synchronous (0): at a SYNC, only if changed.
        write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
        write(&mut drive, 0x1800, 2, 0, 1).unwrap();
        write(&mut drive, 0x1800, 1, 0x4000_0181, 4).unwrap();
        assert_eq!(sync(&mut drive).len(), 1);
        assert!(sync(&mut drive).is_empty());
        rpdo1(&mut drive, 0x06, 0);
        assert_eq!(sync(&mut drive).len(), 1);
    }

    #[test]
    fn frames_that_are_not_canopens_are_ignored() {
        let mut drive = operational();
        let request = vec![0x40, 0x41, 0x60, 0, 0, 0, 0, 0];
        let odd = [
            Frame {
                extended: true,
                ..Frame::data(0x601, &request)
            },
            Frame {
                remote: true,
                data: vec![],
                ..Frame::data(0x601, &request)
            },
            Frame {
                id: 0x1601,
                ..Frame::data(0x601, &request)
            },
            Frame::data(0x601, &[0; 9]),
            Frame::data(0x602, &request),
        ];
        for frame in odd {
            drive.receive(&frame);
            assert!(drive.take_output().is_empty(), "{frame:?}");
        }
    }
    #[test]
    fn interpolated_position_mode_7_is_accepted_and_displayed() {
        let mut drive = booted(DriveConfig::new(1));
        // CiA 402: 6060h = 7 selects interpolated position mode; 6061h shows it.
        write(&mut drive, 0x6060, 0, 7, 1).unwrap();
        assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 7)));
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 7)));
        // Profile position, homing, the cyclic synchronous velocity and torque modes are
        // not the sim's: refused, and the mode stays.
        for mode in [1, 6, 9, 10] {
            assert_eq!(write(&mut drive, 0x6060, 0, mode, 1), Err(0x0609_0030));
        }
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 7)));
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 8)));
        // Reset node: no mode.
        drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
        assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 0)));
    }

    #[test]
    fn the_interpolation_data_record_60c1h_is_read_and_written_by_sdo() {
        let mut drive = booted(DriveConfig {
            position: -7,
            ..DriveConfig::new(1)
        });
        // Sub-index 0: one entry (the position set-point of linear interpolation), one
        // byte, read-only; sub-index 1: INTEGER32, the position actual value at power-up.
        assert_eq!(read(&mut drive, 0x60C1, 0), Ok((0x4F, 1)));
        assert_eq!(write(&mut drive, 0x60C1, 0, 2, 1), Err(0x0601_0002));
        assert_eq!(read(&mut drive, 0x60C1, 1), Ok((0x43, -7i32 as u32)));
        assert_eq!(drive.interpolation_data(), -7);
        write(&mut drive, 0x60C1, 1, -123_456i32 as u32, 4).unwrap();
        assert_eq!(read(&mut drive, 0x60C1, 1), Ok((0x43, -123_456i32 as u32)));
        assert_eq!(drive.interpolation_data(), -123_456);
        // Four bytes, no more, no fewer; no sub-index 2.
        assert_eq!(write(&mut drive, 0x60C1, 1, 5, 2), Err(0x0607_0013));
        assert_eq!(write(&mut drive, 0x60C1, 1, 5, 1), Err(0x0607_0013));
        assert_eq!(write(&mut drive, 0x60C1, 0, 1, 4), Err(0x0601_0002));
        assert_eq!(read(&mut drive, 0x60C1, 2), Err(0x0609_0011));
        assert_eq!(write(&mut drive, 0x60C1, 2, 0, 4), Err(0x0609_0011));
        assert_eq!(drive.interpolation_data(), -123_456);
        // 607Ah is another object: untouched.
        assert_eq!(drive.target(), -7);
        // The mode's set-point: 607Ah outside interpolated position mode, 60C1h in it.
        assert_eq!(drive.set_point(), -7);
        write(&mut drive, 0x6060, 0, 7, 1).unwrap();
        assert_eq!(drive.set_point(), -123_456);
        // A profile object: reset communication keeps it, reset node restores it.
        drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
        assert_eq!(drive.interpolation_data(), -123_456);
        drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
        assert_eq!(drive.interpolation_data(), -7);
    }

    #[test]
    fn interpolation_data_maps_into_rpdos_only() {
        let mut drive = operational();
        write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
        write(&mut drive, 0x1600, 0, 0, 1).unwrap();
        // Sub-index 0 (the count) and another length are not the set-point.
        assert_eq!(
            write(&mut drive, 0x1600, 1, 0x60C1_0020, 4),
            Err(0x0604_0041)
        );
        assert_eq!(
            write(&mut drive, 0x1600, 1, 0x60C1_0008, 4),
            Err(0x0604_0041)
        );
        assert_eq!(
            write(&mut drive, 0x1600, 1, 0x60C1_0110, 4),
            Err(0x0604_0041)
        );
        assert_eq!(
            write(&mut drive, 0x1600, 1, 0x60C1_0220, 4),
            Err(0x0604_0041)
        );
        write(&mut drive, 0x1600, 1, 0x60C1_0120, 4).unwrap();
        assert_eq!(read(&mut drive, 0x1600, 1), Ok((0x43, 0x60C1_0120)));
        // The master's input, not the drive's output: no TPDO carries it.
        write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
        write(&mut drive, 0x1A00, 0, 0, 1).unwrap();
        assert_eq!(
            write(&mut drive, 0x1A00, 1, 0x60C1_0120, 4),
            Err(0x0604_0041)
        );
    }

    #[test]
    fn ip_mode_is_active_only_with_bit_4_in_operation_enabled() {
        use PowerState::*;
        let mut drive = booted(DriveConfig::new(1));
        write(&mut drive, 0x6060, 0, 7, 1).unwrap();
        let mut step = |word: u32, expected: PowerState, statusword: u16| {
            write(&mut drive, 0x6040, 0, word, 2).unwrap();
            assert_eq!(drive.power_state(), expected, "after {word:02X}");
            assert_eq!(drive.statusword(), statusword, "after {word:02X}");
        };
        // Bit 4 does not take part in the state machine's commands, and below Operation
        // enabled it activates nothing.
        step(0x16, ReadyToSwitchOn, 0x0231);
        step(0x17, SwitchedOn, 0x0233);
        // Operation enabled without bit 4: ip mode inactive (statusword bit 12 clear).
        step(0x0F, OperationEnabled, 0x0237);
        // With bit 4: ip mode active (bit 12).
        step(0x1F, OperationEnabled, 0x1237);
        // Bit 4 cleared: inactive again, still Operation enabled.
        step(0x0F, OperationEnabled, 0x0237);
        step(0x1F, OperationEnabled, 0x1237);
        // Leaving Operation enabled ends it, whatever bit 4 says.
        step(0x17, SwitchedOn, 0x0233);
        step(0x1F, OperationEnabled, 0x1237);
        step(0x12, QuickStopActive, 0x0217);
        step(0x10, SwitchOnDisabled, 0x0250);
        // In CSP bit 12 does not wait for bit 4.
        write(&mut drive, 0x6060, 0, 8, 1).unwrap();
        for word in [0x06, 0x07] {
            write(&mut drive, 0x6040, 0, word, 2).unwrap();
        }
        write(&mut drive, 0x6040, 0, 0x0F, 2).unwrap();
        assert_eq!(drive.statusword(), 0x1237);
        // Nor in no mode does bit 4 make it.
        write(&mut drive, 0x6060, 0, 0, 1).unwrap();
        write(&mut drive, 0x6040, 0, 0x1F, 2).unwrap();
        assert_eq!(drive.statusword(), 0x0237);
    }

    /// RPDO1 as [`interpolating`] maps it: controlword, 60C1h sub-index 1.
    fn ip_rpdo(drive: &mut Drive, controlword: u16, set_point: i32) -> Vec<Frame> {
        rpdo1(drive, controlword, set_point);
        sync(drive)
    }

    #[test]
    fn set_points_move_the_drive_only_while_ip_mode_is_active() {
        let mut drive = interpolating(DriveConfig::new(1));
        for word in [0x06, 0x07, 0x0F] {
            ip_rpdo(&mut drive, word, 0);
        }
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        // Enabled but ip mode inactive: the set-point is taken into 60C1h, not followed.
        let frames = ip_rpdo(&mut drive, 0x0F, 500);
        assert_eq!(drive.interpolation_data(), 500);
        assert_eq!(drive.position(), 0);
        assert_eq!(frames, [Frame::data(0x181, &[0x37, 0x02, 0, 0, 0, 0])]);
        assert!(cycles(&mut drive).is_empty());
        // Bit 4: ip mode active, and the same SYNC's set-point is followed.
        let frames = ip_rpdo(&mut drive, 0x1F, 500);
        assert_eq!(drive.position(), 500);
        assert_eq!(
            frames,
            [Frame::data(0x181, &[0x37, 0x12, 0xF4, 0x01, 0, 0])]
        );
        // One set-point a SYNC, at most max_step (1000) counts a cycle, as in CSP.
        ip_rpdo(&mut drive, 0x1F, 3000);
        assert_eq!(drive.position(), 1500);
        ip_rpdo(&mut drive, 0x1F, 3000);
        assert_eq!(drive.position(), 2500);
        // Bit 4 cleared: the drive holds where it is, the new set-point ignored.
        let frames = ip_rpdo(&mut drive, 0x0F, -4000);
        assert_eq!(drive.position(), 2500);
        assert_eq!(frames[0].data[..2], [0x37, 0x02]);
        assert_eq!(cycles(&mut drive), [(500, 500), (3000, 1500), (3000, 2500)]);
        // 607Ah played no part.
        assert_eq!(drive.target(), 0);
        assert_eq!(drive.set_point(), -4000);
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    }

    #[test]
    fn ip_set_points_meet_the_following_error_window_and_the_software_limits() {
        let mut drive = interpolating(DriveConfig {
            max_step: 10,
            following_error_window: 100,
            software_limits: Some((-100, 5000)),
            ..DriveConfig::new(1)
        });
        for word in [0x06, 0x07, 0x0F, 0x1F] {
            ip_rpdo(&mut drive, word, 0);
        }
        // 110 away: 100 remain after the cycle, in the window; 500 away: 480 remain.
        ip_rpdo(&mut drive, 0x1F, 110);
        assert_eq!(drive.power_state(), PowerState::OperationEnabled);
        let frames = ip_rpdo(&mut drive, 0x1F, 500);
        assert_eq!(drive.position(), 20);
        assert_eq!(
            frames,
            [
                Frame::data(0x081, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
                Frame::data(0x181, &[0x18, 0x22, 20, 0, 0, 0]),
            ]
        );
        // Reset, enable again from where it stands, and a set-point past the limit faults
        // before it moves, with EMCY 8612h.
        ip_rpdo(&mut drive, 0x80, 20);
        for word in [0x06, 0x07, 0x0F, 0x1F] {
            ip_rpdo(&mut drive, word, 20);
        }
        assert_eq!(drive.statusword(), 0x1237);
        let frames = ip_rpdo(&mut drive, 0x1F, -101);
        assert_eq!(
            (drive.power_state(), drive.position()),
            (PowerState::Fault, 20)
        );
        assert_eq!(
            frames[0],
            Frame::data(0x081, &[0x12, 0x86, 0x01, 0, 0, 0, 0, 0])
        );
    }
}
