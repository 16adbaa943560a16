//! The bridge's CANopen master for three CiA 402 drives (X, Z, C), as a state machine over
//! frames and time: [`Session::receive`] takes the bus's frames, [`Session::poll`] is told
//! the time and returns the frames to send, [`Session::events`] says what happened. No
//! port, no clock: the transport moves the frames and calls `poll` at least once a cycle.
//!
//! # Phases
//!
//! 1. **Boot-up.** Wait [`SessionConfig::boot_wait`] for every node's boot-up message. A
//!    node that booted before the bridge listened (before the adapter's channel opened)
//!    never sends another, so the missing ones get NMT reset communication, which makes
//!    them boot again, and one more wait; a node still silent stops the job.
//! 2. **Configuration**, by expedited SDO, the three nodes in parallel, each node's writes
//!    in order: device type 1000h read (CiA 402 is 0192h in its low word: anything else is
//!    not a drive this master knows how to run), producer heartbeat 1017h, modes of
//!    operation 6060h = 8 (cyclic synchronous position) or 7 (interpolated position; see
//!    [`SessionConfig::operation`]), following error window 6065h, interpolation time
//!    period 60C2h (the cycle, which the drives lock to), then RPDO1 = controlword 6040h +
//!    the mode's set-point (target position 607Ah, or in interpolated position mode the
//!    interpolation data record's first entry, 60C1h sub-index 1) and TPDO1 = statusword
//!    6041h + position actual 6064h, both every SYNC, by CiA 301's mapping procedure
//!    ([`cia301::pdo_mapping`]). Heartbeat supervision of a node starts when its 1017h
//!    write is confirmed.
//! 3. **Start and enable.** NMT start to each node, and the cycle starts: every period,
//!    each drive's RPDO1 and then one SYNC. The first SYNC only asks for the TPDOs; from
//!    each drive's first TPDO on, its target is its actual position (CiA 402: in CSP a
//!    drive follows 607Ah the moment it is enabled, in interpolated position mode 60C1h
//!    the moment ip mode is active), which must be within
//!    [`SessionConfig::start_tolerance`] of the set-points' start, and the controlword
//!    walks it to Operation enabled with a [`PowerSequencer`], one transition a cycle:
//!    0x06, 0x07, 0x0F. In interpolated position mode one step follows: once a drive
//!    shows Operation enabled, its controlword also sets bit 4, enable ip mode (0x1F).
//! 4. **Run.** Once all three show Operation enabled and follow their targets (statusword
//!    bit 12: in CSP "drive follows the command value", in interpolated position mode "ip
//!    mode active"), each cycle carries the next set-point's three targets, then the SYNC
//!    that makes the drives take them together. In interpolated position mode a drive
//!    whose bit 12 drops while it runs stops the job ([`StopReason::IpModeInactive`]): it
//!    no longer takes its set-points. Spindle [`Mark`](crate::post::setpoints::Mark)s are
//!    reported as [`Event::Spindle`] when due.
//! 5. **Settle and disable.** After the last set-point the final targets are held until
//!    every actual position is within [`SessionConfig::settle_window`], then the drives
//!    are walked to Switch on disabled, and the cycle ends.
//!
//! # Stopping
//!
//! A lost heartbeat, an emergency message, a drive leaving Operation enabled or NMT
//! Operational, an SDO failure, a timeout of any phase, or [`Session::stop`] stops the
//! job: [`Event::Stopped`] says why, once (the first reason wins). If the cycle was
//! running, it goes on for the stop: each drive in Operation enabled is sent quick stop
//! (0x02), held there until its position stands still, then disable voltage (0x00)
//! (neither with bit 4: in interpolated position mode ip mode ends with the first),
//! until every drive still heard from shows Switch on disabled or Fault in a TPDO received
//! after the stop, or [`SessionConfig::disable_timeout`] passes; [`Event::Halted`] then
//! names the drives not confirmed. Faults are not reset: a faulted drive stays faulted for
//! someone to look at.
//!
//! # The cycle
//!
//! Set-points are computed before the first SYNC ([`crate::post::setpoints`]), so a cycle only
//! reads the next one and the cycle never waits for the planner. `poll` sends exactly one
//! SYNC when the cycle's time has come, however often it is called. A poll later than
//! a whole period still sends one cycle (never a burst to catch up, which would hand the
//! drives set-points faster than the path allows), reports [`Event::Late`], and the
//! schedule restarts from then: the path slows down, it does not jump.

use std::collections::VecDeque;
use std::time::Duration;

use thiserror::Error;

use super::cia301::{
    self, cob, decode_emcy, decode_heartbeat, Cob, Emergency, MapEntry, NmtCommand, NmtState,
    NodeId, PdoConfig, PdoDirection, PdoNumber, SdoClient, SdoDone, SdoError, SdoWrite, EVERY_SYNC,
};
use super::cia402::{
    interpolation_time_period, object, Command, Mode, PowerSequencer, PowerState, Statusword,
    Target, ENABLE_IP_MODE,
};
use super::frame::{CanFrame, CanId};
use crate::config::connection::{DriveMode, DriveSettings, SettingError};
use crate::config::machine::Axis;
use crate::post::setpoints::{to_wire, unwrap_near, SetPoints};

/// How the session runs the bus.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SessionConfig {
    /// The drives of X, Z and C, in that order; distinct.
    pub nodes: [NodeId; 3],
    /// How long to wait for boot-up messages, before and after NMT reset communication.
    pub boot_wait: Duration,
    /// How long an SDO transfer may take.
    pub sdo_timeout: Duration,
    /// The producer heartbeat time written to every drive (1017h), ms; not 0.
    pub heartbeat_ms: u16,
    /// A node not heard from for this long is lost: the consumer heartbeat time, which
    /// must exceed the producer's period (by a margin for the bus's latency and the
    /// transport's polling).
    pub heartbeat_timeout: Duration,
    /// Following error window written to every drive (6065h), counts.
    pub following_error_window: u32,
    /// How far a drive may stand from the set-points' start when it is enabled, counts.
    pub start_tolerance: u32,
    /// How long the walk to Operation enabled may take.
    pub enable_timeout: Duration,
    /// How close every actual position must come to the final target, counts.
    pub settle_window: u32,
    /// How long settling may take.
    pub settle_timeout: Duration,
    /// How long disabling may take, after the job and after a stop.
    pub disable_timeout: Duration,
    /// The drives' mode of operation: how the set-points reach them.
    pub operation: Operation,
}

/// The CiA 402 modes of operation the session runs the drives in: either takes one
/// position set-point a SYNC, in its own object, and shows it follows them in statusword
/// bit 12.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum Operation {
    /// Cyclic synchronous position (6060h = 8): the set-point is the target position
    /// 607Ah, followed from Operation enabled on.
    #[default]
    CyclicSynchronousPosition,
    /// Interpolated position (6060h = 7): the set-point is 60C1h sub-index 1, followed
    /// once the controlword's bit 4 (enable ip mode) has made ip mode active.
    InterpolatedPosition,
}

impl Operation {
    /// The mode, as 6060h takes it.
    pub fn mode(self) -> Mode {
        match self {
            Operation::CyclicSynchronousPosition => Mode::CyclicSynchronousPosition,
            Operation::InterpolatedPosition => Mode::InterpolatedPosition,
        }
    }

    /// The object that carries the set-point, (index, sub-index), INTEGER32.
    pub fn set_point_object(self) -> (u16, u8) {
        match self {
            Operation::CyclicSynchronousPosition => (object::TARGET_POSITION, 0),
            Operation::InterpolatedPosition => (object::INTERPOLATION_DATA, 1),
        }
    }

    /// The controlword bits beyond the state machine's command that the mode needs while
    /// the drive is in Operation enabled: enable ip mode in interpolated position mode.
    fn running_bits(self) -> u16 {
        match self {
            Operation::CyclicSynchronousPosition => 0,
            Operation::InterpolatedPosition => ENABLE_IP_MODE,
        }
    }

    /// Whether a drive showing `statusword` takes its set-points: Operation enabled, and
    /// bit 12 (CSP's "drive follows the command value", interpolated position's "ip mode
    /// active").
    fn follows(self, statusword: u16) -> bool {
        let word = Statusword(statusword);
        word.state() == Ok(PowerState::OperationEnabled)
            && match self {
                Operation::CyclicSynchronousPosition => word.following_target(),
                Operation::InterpolatedPosition => word.ip_mode_active(),
            }
    }
}

impl std::fmt::Display for Operation {
    /// The mode's name and number, for the log.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = match self {
            Operation::CyclicSynchronousPosition => "cyclic synchronous position",
            Operation::InterpolatedPosition => "interpolated position",
        };
        write!(f, "{name} (mode {})", self.mode().value())
    }
}

impl Default for SessionConfig {
    /// Nodes 1, 2, 3; a 50 ms heartbeat supervised at 150 ms; a second for each phase.
    fn default() -> Self {
        let node = |id| NodeId::new(id).expect("1-3 are node ids");
        SessionConfig {
            nodes: [node(1), node(2), node(3)],
            boot_wait: Duration::from_millis(500),
            sdo_timeout: Duration::from_millis(100),
            heartbeat_ms: 50,
            heartbeat_timeout: Duration::from_millis(150),
            following_error_window: 10_000,
            start_tolerance: 0,
            enable_timeout: Duration::from_secs(1),
            settle_window: 10,
            settle_timeout: Duration::from_secs(1),
            disable_timeout: Duration::from_secs(1),
            operation: Operation::CyclicSynchronousPosition,
        }
    }
}

impl SessionConfig {
    /// The session for a profile's drives: their nodes, heartbeat, following error window
    /// and mode, every other setting at [`SessionConfig::default`]. An error, naming the
    /// key, for settings [`DriveSettings::validate`] refuses.
    pub fn for_drives(drives: &DriveSettings) -> Result<SessionConfig, SettingError> {
        drives.validate()?;
        let mut nodes = SessionConfig::default().nodes;
        for (node, &id) in nodes.iter_mut().zip(&drives.nodes) {
            *node = NodeId::new(id).map_err(|e| SettingError {
                key: "connection.drives.nodes".into(),
                problem: e.to_string(),
            })?;
        }
        Ok(SessionConfig {
            nodes,
            heartbeat_ms: drives.heartbeat_ms,
            heartbeat_timeout: drives.heartbeat_timeout(),
            following_error_window: drives.following_error_window,
            operation: drives.mode.into(),
            ..SessionConfig::default()
        })
    }
}

impl From<DriveMode> for Operation {
    /// The mode a profile's `connection.drives.mode` names.
    fn from(mode: DriveMode) -> Operation {
        match mode {
            DriveMode::Csp => Operation::CyclicSynchronousPosition,
            DriveMode::Ip => Operation::InterpolatedPosition,
        }
    }
}

/// A session that cannot be made.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SessionError {
    /// A configuration value out of range.
    #[error("CAN session: {name}: {reason}")]
    Config {
        /// The field.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
}

/// Where the session is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for boot-up messages.
    Booting,
    /// Writing the drives' objects by SDO.
    Configuring,
    /// NMT started; walking the drives to Operation enabled.
    Enabling,
    /// Sending set-points.
    Running,
    /// Holding the final targets until the drives get there.
    Settling,
    /// Walking the drives to Switch on disabled after the job.
    Disabling,
    /// The job ran to its end and the drives are disabled.
    Finished,
    /// Quick-stopping and disabling the drives after a stop.
    Stopping,
    /// Stopped; see [`Event::Stopped`].
    Stopped,
}

/// Why the job stopped. Each names the node and its axis.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum StopReason {
    /// No boot-up message, even after NMT reset communication.
    #[error("node {node} ({axis}) sent no boot-up message, even after NMT reset communication")]
    NoBootUp {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
    },
    /// A boot-up message after configuration: the node reset and lost its objects.
    #[error(
        "node {node} ({axis}) booted again during the job: it reset and lost its configuration"
    )]
    Rebooted {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
    },
    /// No heartbeat within the consumer time.
    #[error("node {node} ({axis}) heartbeat lost: none for {timeout:?} (cable, power or a crashed drive)")]
    HeartbeatLost {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The consumer heartbeat time.
        timeout: Duration,
    },
    /// A heartbeat showing a state other than Operational while the cycle runs.
    #[error("node {node} ({axis}) left NMT Operational: its heartbeat shows {state:?}")]
    NotOperational {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The state its heartbeat shows.
        state: NmtState,
    },
    /// An emergency message announcing an error.
    #[error("node {node} ({axis}) emergency 0x{code:04X}: {meaning}")]
    Emergency {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The error code.
        code: u16,
        /// What the code means (CiA 301 / CiA 402), or its class.
        meaning: &'static str,
    },
    /// A statusword showing Fault or Fault reaction active while running, with no
    /// emergency message before it.
    #[error("node {node} ({axis}) faulted (statusword 0x{statusword:04X})")]
    Fault {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The statusword.
        statusword: u16,
    },
    /// A statusword showing another state than Operation enabled while running.
    #[error("node {node} ({axis}) left Operation enabled: {state:?}")]
    LeftOperation {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The state it shows.
        state: PowerState,
    },
    /// In interpolated position mode, a statusword showing Operation enabled without ip
    /// mode active (bit 12) while running: the drive ignores its set-points.
    #[error(
        "node {node} ({axis}) left interpolated position mode: statusword 0x{statusword:04X} \
         shows ip mode inactive (bit 12), its set-points ignored"
    )]
    IpModeInactive {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The statusword.
        statusword: u16,
    },
    /// A statusword matching no CiA 402 state.
    #[error("node {node} ({axis}): statusword 0x{statusword:04X} matches no CiA 402 state")]
    Statusword {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The statusword.
        statusword: u16,
    },
    /// A TPDO1 too short for its mapping.
    #[error("node {node} ({axis}): TPDO1 of {len} bytes, its mapping (6041h, 6064h) has 6")]
    Tpdo {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The bytes it had.
        len: usize,
    },
    /// An SDO transfer failed (the error names the node).
    #[error("configuration failed: {0}")]
    Sdo(SdoError),
    /// A device type that is not CiA 402.
    #[error(
        "node {node} ({axis}) is not a CiA 402 drive: device type 0x{device_type:08X} (1000h)"
    )]
    DeviceType {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// 1000h.
        device_type: u32,
    },
    /// A drive standing too far from where the set-points start.
    #[error(
        "node {node} ({axis}) stands at {actual} counts, the path starts at {start}: more than \
         the {tolerance} counts allowed"
    )]
    StartMismatch {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// Its position, counts.
        actual: i64,
        /// The set-points' start, counts.
        start: i64,
        /// [`SessionConfig::start_tolerance`].
        tolerance: u32,
    },
    /// A drive not in Operation enabled in time.
    #[error("node {node} ({axis}) not in Operation enabled after {timeout:?}: {state}")]
    EnableTimeout {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// The state it showed last.
        state: String,
        /// [`SessionConfig::enable_timeout`].
        timeout: Duration,
    },
    /// A drive not at its final target in time.
    #[error(
        "node {node} ({axis}) at {actual} counts did not settle within {window} counts of \
         {target} in {timeout:?}"
    )]
    NotSettled {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// Its last position, counts.
        actual: i64,
        /// The final target, counts.
        target: i64,
        /// [`SessionConfig::settle_window`].
        window: u32,
        /// [`SessionConfig::settle_timeout`].
        timeout: Duration,
    },
    /// A drive not in Switch on disabled in time after the job.
    #[error("node {node} ({axis}) not disabled within {timeout:?} after the job")]
    NotDisabled {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// [`SessionConfig::disable_timeout`].
        timeout: Duration,
    },
    /// [`Session::stop`].
    #[error("stop requested")]
    Requested,
}

/// What happened, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A node's boot-up message.
    BootUp {
        /// The node.
        node: NodeId,
    },
    /// NMT reset communication was sent to the nodes that had not booted.
    ResetCommunication {
        /// Those nodes.
        nodes: Vec<NodeId>,
    },
    /// A node's objects are written.
    Configured {
        /// The node.
        node: NodeId,
    },
    /// NMT start was sent; the cycle runs.
    Started,
    /// Every drive follows its target: the set-points start with the next SYNC.
    Enabled {
        /// SYNCs sent so far: set-point k (0-based) goes with SYNC number `syncs + k + 1`.
        syncs: u64,
    },
    /// A spindle command is due (the ring is not on this bus: the caller runs it).
    Spindle {
        /// The block.
        block: usize,
        /// `Some(rpm)`: M3; `None`: M5.
        rpm: Option<f64>,
    },
    /// `poll` came a whole period or more after the cycle was due (the transport's
    /// problem, made visible); the path was slowed by as much.
    Late {
        /// The SYNC sent late (1-based).
        sync: u64,
        /// How late.
        late_by: Duration,
    },
    /// An emergency message from one of the drives (error resets included).
    Emergency(Emergency),
    /// Every drive is at its final target.
    Settled,
    /// The job ran to its end; the drives are disabled.
    Finished,
    /// The job stopped, and why.
    Stopped {
        /// Why.
        reason: StopReason,
    },
    /// The stop is complete: the cycle has ended.
    Halted {
        /// Drives not seen in Switch on disabled or Fault (lost, or not in time).
        unconfirmed: Vec<NodeId>,
    },
}

impl std::fmt::Display for Event {
    /// A line for the log.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let list = |nodes: &[NodeId]| {
            nodes
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        };
        match self {
            Event::BootUp { node } => write!(f, "node {node} booted"),
            Event::ResetCommunication { nodes } => write!(
                f,
                "NMT reset communication to node(s) {} (no boot-up heard)",
                list(nodes)
            ),
            Event::Configured { node } => write!(f, "node {node} configured"),
            Event::Started => write!(f, "NMT start; the cycle runs"),
            Event::Enabled { syncs } => write!(
                f,
                "every drive follows its target after {syncs} SYNCs; the set-points start"
            ),
            Event::Spindle {
                block,
                rpm: Some(rpm),
            } => write!(
                f,
                "block {block}: ring spindle on at {rpm} rpm (the ring is not on this bus: \
                 it must be running now)"
            ),
            Event::Spindle { block, rpm: None } => {
                write!(f, "block {block}: ring spindle off (it may stop now)")
            }
            Event::Late { sync, late_by } => write!(
                f,
                "SYNC {sync} went out {late_by:?} late; the path slowed by as much"
            ),
            Event::Emergency(emcy) => write!(
                f,
                "node {} emergency 0x{:04X} ({}), error register 0x{:02X}",
                emcy.node,
                emcy.code,
                emcy_meaning(emcy),
                emcy.register
            ),
            Event::Settled => write!(f, "every drive at its final target"),
            Event::Finished => write!(f, "finished; the drives are disabled"),
            Event::Stopped { reason } => write!(f, "stopped: {reason}"),
            Event::Halted { unconfirmed } if unconfirmed.is_empty() => {
                write!(f, "halted; every drive confirmed disabled or faulted")
            }
            Event::Halted { unconfirmed } => write!(
                f,
                "halted; node(s) {} not confirmed disabled",
                list(unconfirmed)
            ),
        }
    }
}

/// A drive as the session last saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveStatus {
    /// Its node.
    pub node: NodeId,
    /// Its last statusword.
    pub statusword: Option<u16>,
    /// Its last position actual value, counts (unwrapped: see [`unwrap_near`]).
    pub actual: Option<i64>,
    /// The last target sent, counts.
    pub target: Option<i64>,
}

/// One configuration step of a node.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Op {
    /// Read 1000h and check it is CiA 402.
    CheckDeviceType,
    /// Write an object.
    Write(SdoWrite),
}

/// The session's view of one drive.
#[derive(Debug, Clone)]
struct Drive {
    axis: Axis,
    sdo: SdoClient,
    ops: VecDeque<Op>,
    booted: bool,
    /// Heartbeat supervision: lost if not heard from by then.
    heartbeat_due: Option<Duration>,
    lost: bool,
    statusword: Option<u16>,
    actual: Option<i64>,
    /// The last TPDO showed the same position as the one before.
    still: bool,
    /// A TPDO arrived since the stop or the disable began.
    fresh: bool,
    target: Option<i64>,
    sequencer: PowerSequencer,
}

impl Drive {
    fn state(&self) -> Option<PowerState> {
        self.statusword
            .and_then(|w| PowerState::from_statusword(w).ok())
    }
}

/// The master; see the module docs.
#[derive(Debug, Clone)]
pub struct Session {
    config: SessionConfig,
    setpoints: SetPoints,
    phase: Phase,
    /// The current phase's deadline (boot wait, timeouts).
    deadline: Option<Duration>,
    reset_sent: bool,
    drives: [Drive; 3],
    next_sync: Duration,
    syncs: u64,
    /// Set-points sent.
    sent: usize,
    next_mark: usize,
    outbox: Vec<CanFrame>,
    events: Vec<Event>,
}

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).expect("CANopen frames are 11-bit and at most 8 bytes")
}

/// What an emergency code means: CiA 301's and CiA 402's words for the codes drives send
/// about the bus and the position loop, the code's class otherwise.
pub fn emcy_meaning(emcy: &Emergency) -> &'static str {
    match emcy.code {
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard error or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8611 => "following error",
        0x8612 => "reference limit (position limit)",
        0x9000 => "external error",
        _ => emcy.class(),
    }
}

impl Session {
    /// A session that will run `setpoints` on the drives `config` names.
    pub fn new(config: SessionConfig, setpoints: SetPoints) -> Result<Session, SessionError> {
        let invalid = |name, reason: String| Err(SessionError::Config { name, reason });
        let [x, z, c] = config.nodes;
        if x == z || z == c || x == c {
            return invalid("nodes", format!("{x}, {z}, {c} are not three nodes"));
        }
        if config.heartbeat_ms == 0 {
            return invalid("heartbeat_ms", "0 switches the heartbeat off".into());
        }
        let period = Duration::from_millis(config.heartbeat_ms.into());
        if config.heartbeat_timeout <= period {
            return invalid(
                "heartbeat_timeout",
                format!(
                    "{:?} is not longer than the producer's {period:?}",
                    config.heartbeat_timeout
                ),
            );
        }
        let Some(cycle) = interpolation_time_period(setpoints.period) else {
            return invalid(
                "setpoints.period",
                format!(
                    "{:?} is not a cycle 60C2h holds (value ≤ 255 × 10^index s, whole µs)",
                    setpoints.period
                ),
            );
        };
        let drives = std::array::from_fn(|k| {
            let node = config.nodes[k];
            Drive {
                axis: Axis::ALL[k],
                sdo: SdoClient::new(node, config.sdo_timeout),
                ops: configuration(node, &config, cycle),
                booted: false,
                heartbeat_due: None,
                lost: false,
                statusword: None,
                actual: None,
                still: false,
                fresh: false,
                target: None,
                sequencer: PowerSequencer::new(Target::OperationEnabled),
            }
        });
        Ok(Session {
            config,
            setpoints,
            phase: Phase::Booting,
            deadline: None,
            reset_sent: false,
            drives,
            next_sync: Duration::ZERO,
            syncs: 0,
            sent: 0,
            next_mark: 0,
            outbox: Vec::new(),
            events: Vec::new(),
        })
    }

    /// Where the session is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Set-points sent, and their number.
    pub fn progress(&self) -> (usize, usize) {
        (self.sent, self.setpoints.points.len())
    }

    /// The drives as last seen, X, Z, C.
    pub fn drives(&self) -> [DriveStatus; 3] {
        std::array::from_fn(|k| {
            let d = &self.drives[k];
            DriveStatus {
                node: self.config.nodes[k],
                statusword: d.statusword,
                actual: d.actual,
                target: d.target,
            }
        })
    }

    /// What happened since the last call.
    pub fn events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Stops the job (an operator's abort): as any stop, see the module docs.
    pub fn stop(&mut self, now: Duration) {
        self.halt(StopReason::Requested, now);
    }

    /// Which of the three a node is.
    fn slot(&self, node: NodeId) -> Option<usize> {
        self.config.nodes.iter().position(|n| *n == node)
    }

    fn reason_for(&self, k: usize) -> (NodeId, Axis) {
        (self.config.nodes[k], self.drives[k].axis)
    }

    /// Whether the cycle runs.
    fn cyclic(&self) -> bool {
        matches!(
            self.phase,
            Phase::Enabling | Phase::Running | Phase::Settling | Phase::Disabling | Phase::Stopping
        )
    }

    /// Stops the job for `reason` (the first reason stands).
    fn halt(&mut self, reason: StopReason, now: Duration) {
        if matches!(
            self.phase,
            Phase::Stopping | Phase::Stopped | Phase::Finished
        ) {
            return;
        }
        self.events.push(Event::Stopped { reason });
        if self.cyclic() {
            self.phase = Phase::Stopping;
            self.deadline = Some(now + self.config.disable_timeout);
            self.drives.iter_mut().for_each(|d| d.fresh = false);
        } else {
            // Nothing was enabled: there is nothing to stop.
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted {
                unconfirmed: Vec::new(),
            });
        }
    }

    /// A frame from the bus, received at `now`.
    pub fn receive(&mut self, frame: &CanFrame, now: Duration) {
        let CanId::Standard(id) = frame.id() else {
            return;
        };
        if frame.is_remote() {
            return;
        }
        let cob = Cob::classify(id);
        let (node, k) = match cob {
            Cob::Heartbeat(node)
            | Cob::Emcy(node)
            | Cob::SdoResponse(node)
            | Cob::Tpdo(_, node) => match self.slot(node) {
                Some(k) => (node, k),
                None => return,
            },
            _ => return,
        };
        match cob {
            Cob::Heartbeat(_) => self.heartbeat(k, frame, now),
            Cob::Emcy(_) => {
                let Ok(emcy) = decode_emcy(frame) else {
                    return;
                };
                self.events.push(Event::Emergency(emcy));
                if !emcy.is_reset() {
                    let axis = self.drives[k].axis;
                    let reason = StopReason::Emergency {
                        node,
                        axis,
                        code: emcy.code,
                        meaning: emcy_meaning(&emcy),
                    };
                    self.halt(reason, now);
                }
            }
            Cob::SdoResponse(_) => {
                let done = self.drives[k].sdo.receive(frame);
                while let Some(frame) = self.drives[k].sdo.transmit() {
                    self.outbox.push(frame);
                }
                match done {
                    Some(Ok(done)) => self.configured(k, done, now),
                    Some(Err(error)) => self.halt(StopReason::Sdo(error), now),
                    None => {}
                }
            }
            Cob::Tpdo(pdo, _) if pdo.get() == 1 => self.tpdo(k, frame.data(), now),
            _ => {}
        }
    }

    fn heartbeat(&mut self, k: usize, frame: &CanFrame, now: Duration) {
        // A malformed heartbeat is not one: it does not keep the node alive.
        let Ok(beat) = decode_heartbeat(frame) else {
            return;
        };
        let (node, axis) = self.reason_for(k);
        if beat.state == NmtState::BootUp {
            if self.phase == Phase::Booting {
                if !self.drives[k].booted {
                    self.drives[k].booted = true;
                    self.events.push(Event::BootUp { node });
                }
            } else {
                self.halt(StopReason::Rebooted { node, axis }, now);
            }
            return;
        }
        let drive = &mut self.drives[k];
        if drive.heartbeat_due.is_some() {
            drive.heartbeat_due = Some(now + self.config.heartbeat_timeout);
        }
        let running = matches!(
            self.phase,
            Phase::Running | Phase::Settling | Phase::Disabling
        );
        if running && beat.state != NmtState::Operational {
            let reason = StopReason::NotOperational {
                node,
                axis,
                state: beat.state,
            };
            self.halt(reason, now);
        }
    }

    /// An SDO transfer of drive `k` succeeded.
    fn configured(&mut self, k: usize, done: SdoDone, now: Duration) {
        let (node, axis) = self.reason_for(k);
        match done {
            SdoDone::Uploaded { index, data, .. } if index == object::DEVICE_TYPE => {
                let mut bytes = [0; 4];
                bytes[..data.len()].copy_from_slice(&data);
                let device_type = u32::from_le_bytes(bytes);
                if device_type & 0xFFFF != 0x0192 {
                    let reason = StopReason::DeviceType {
                        node,
                        axis,
                        device_type,
                    };
                    self.halt(reason, now);
                }
            }
            SdoDone::Downloaded { index, .. } if index == object::PRODUCER_HEARTBEAT => {
                // The drive restarts its period on this write: supervise from now.
                self.drives[k].heartbeat_due = Some(now + self.config.heartbeat_timeout);
            }
            _ => {}
        }
        if self.phase == Phase::Configuring
            && self.drives[k].ops.is_empty()
            && !self.drives[k].sdo.is_busy()
        {
            self.events.push(Event::Configured { node });
        }
    }

    fn tpdo(&mut self, k: usize, data: &[u8], now: Duration) {
        let (node, axis) = self.reason_for(k);
        if data.len() < 6 {
            let len = data.len();
            return self.halt(StopReason::Tpdo { node, axis, len }, now);
        }
        let statusword = u16::from_le_bytes([data[0], data[1]]);
        let wire = i32::from_le_bytes([data[2], data[3], data[4], data[5]]);
        let start = self.setpoints.start[k];
        let drive = &mut self.drives[k];
        let near = drive.target.or(drive.actual).unwrap_or(start);
        let actual = unwrap_near(wire, near);
        drive.still = drive.actual == Some(actual);
        drive.actual = Some(actual);
        drive.statusword = Some(statusword);
        drive.fresh = true;
        let state = match PowerState::from_statusword(statusword) {
            Ok(state) => state,
            Err(_) if self.phase == Phase::Stopping => return,
            Err(_) => {
                return self.halt(
                    StopReason::Statusword {
                        node,
                        axis,
                        statusword,
                    },
                    now,
                )
            }
        };
        match self.phase {
            Phase::Enabling if drive.target.is_none() => {
                let tolerance = self.config.start_tolerance;
                if actual.abs_diff(start) > u64::from(tolerance) {
                    let reason = StopReason::StartMismatch {
                        node,
                        axis,
                        actual,
                        start,
                        tolerance,
                    };
                    return self.halt(reason, now);
                }
                drive.target = Some(actual);
            }
            Phase::Running | Phase::Settling => match state {
                PowerState::OperationEnabled
                    if self.config.operation == Operation::InterpolatedPosition
                        && !Statusword(statusword).ip_mode_active() =>
                {
                    self.halt(
                        StopReason::IpModeInactive {
                            node,
                            axis,
                            statusword,
                        },
                        now,
                    );
                }
                PowerState::OperationEnabled => {}
                PowerState::Fault | PowerState::FaultReactionActive => {
                    self.halt(
                        StopReason::Fault {
                            node,
                            axis,
                            statusword,
                        },
                        now,
                    );
                }
                state => self.halt(StopReason::LeftOperation { node, axis, state }, now),
            },
            _ => {}
        }
    }

    /// Tells the session the time; returns the frames to send now, in order.
    pub fn poll(&mut self, now: Duration) -> Vec<CanFrame> {
        let mut out = std::mem::take(&mut self.outbox);
        self.supervise(now);
        match self.phase {
            Phase::Booting => self.boot(now, &mut out),
            Phase::Configuring => self.configure(now, &mut out),
            _ => {}
        }
        if self.cyclic() && now >= self.next_sync {
            self.cycle(now, &mut out);
        }
        out
    }

    /// Heartbeat consumer: a node not heard from in time is lost.
    fn supervise(&mut self, now: Duration) {
        if matches!(
            self.phase,
            Phase::Finished | Phase::Stopped | Phase::Booting
        ) {
            return;
        }
        for k in 0..3 {
            let drive = &mut self.drives[k];
            if drive.lost || drive.heartbeat_due.is_none_or(|due| now <= due) {
                continue;
            }
            drive.lost = true;
            let (node, axis) = self.reason_for(k);
            let timeout = self.config.heartbeat_timeout;
            self.halt(
                StopReason::HeartbeatLost {
                    node,
                    axis,
                    timeout,
                },
                now,
            );
        }
    }

    fn boot(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        let deadline = *self.deadline.get_or_insert(now + self.config.boot_wait);
        if self.drives.iter().all(|d| d.booted) {
            self.phase = Phase::Configuring;
            self.deadline = None;
            return self.configure(now, out);
        }
        if now < deadline {
            return;
        }
        let missing: Vec<usize> = (0..3).filter(|&k| !self.drives[k].booted).collect();
        if self.reset_sent {
            let (node, axis) = self.reason_for(missing[0]);
            return self.halt(StopReason::NoBootUp { node, axis }, now);
        }
        let nodes: Vec<NodeId> = missing.iter().map(|&k| self.config.nodes[k]).collect();
        for node in &nodes {
            out.push(NmtCommand::ResetCommunication.frame(Some(*node)));
        }
        self.events.push(Event::ResetCommunication { nodes });
        self.reset_sent = true;
        self.deadline = Some(now + self.config.boot_wait);
    }

    fn configure(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        for k in 0..3 {
            if let Some(error) = self.drives[k].sdo.poll(now) {
                out.extend(std::iter::from_fn(|| self.drives[k].sdo.transmit()));
                return self.halt(StopReason::Sdo(error), now);
            }
            let drive = &mut self.drives[k];
            if !drive.sdo.is_busy() {
                let started = match drive.ops.pop_front() {
                    Some(Op::CheckDeviceType) => drive.sdo.upload(object::DEVICE_TYPE, 0, now),
                    Some(Op::Write(w)) => drive.sdo.download(w.index, w.sub, &w.data, now),
                    None => Ok(()),
                };
                // One transfer at a time, of 1-4 bytes: the client cannot refuse these.
                started.expect("an idle client takes an expedited transfer");
            }
            out.extend(std::iter::from_fn(|| self.drives[k].sdo.transmit()));
        }
        if self.phase != Phase::Configuring {
            return;
        }
        if self
            .drives
            .iter()
            .all(|d| d.ops.is_empty() && !d.sdo.is_busy())
        {
            for node in self.config.nodes {
                out.push(NmtCommand::Start.frame(Some(node)));
            }
            self.events.push(Event::Started);
            self.phase = Phase::Enabling;
            self.deadline = Some(now + self.config.enable_timeout);
            self.next_sync = now;
        }
    }

    /// One cycle: RPDOs, then SYNC.
    fn cycle(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        let period = self.setpoints.period;
        let late_by = now - self.next_sync;
        let late = late_by >= period;
        self.next_sync = if late {
            now + period
        } else {
            self.next_sync + period
        };
        let words = match self.phase {
            Phase::Enabling => self.enabling(now),
            Phase::Running => self.running(now),
            Phase::Settling => self.settling(now),
            Phase::Disabling => self.disabling(now),
            Phase::Stopping => self.stopping(now),
            _ => None,
        };
        // A phase may have ended the cycle (or moved on to another that sends).
        let Some(words) = words else {
            return;
        };
        if late {
            self.events.push(Event::Late {
                sync: self.syncs + 1,
                late_by,
            });
        }
        for (k, word) in words.into_iter().enumerate() {
            let (Some(word), Some(target)) = (word, self.drives[k].target) else {
                continue;
            };
            let mut data = word.to_le_bytes().to_vec();
            data.extend_from_slice(&to_wire(target).to_le_bytes());
            let pdo = PdoNumber::new(1).expect("PDO 1");
            out.push(frame(cob::rpdo(pdo, self.config.nodes[k]), &data));
        }
        out.push(cia301::sync_frame());
        self.syncs += 1;
    }

    /// Controlwords of the walk to Operation enabled (and in interpolated position mode
    /// on to ip mode active), or on to running.
    fn enabling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let operation = self.config.operation;
        let following = |d: &Drive| d.statusword.is_some_and(|w| operation.follows(w));
        if self.drives.iter().all(following) {
            self.events.push(Event::Enabled { syncs: self.syncs });
            self.phase = Phase::Running;
            self.deadline = None;
            return self.running(now);
        }
        if self.deadline.is_some_and(|d| now >= d) {
            let k = (0..3).find(|&k| !following(&self.drives[k])).unwrap_or(0);
            let (node, axis) = self.reason_for(k);
            let state = match self.drives[k].statusword {
                None => "no TPDO seen".to_string(),
                Some(w) => match PowerState::from_statusword(w) {
                    Ok(PowerState::OperationEnabled)
                        if operation == Operation::InterpolatedPosition =>
                    {
                        format!(
                            "OperationEnabled (statusword 0x{w:04X}) without ip mode active \
                             (bit 12)"
                        )
                    }
                    Ok(state) => format!("{state:?} (statusword 0x{w:04X})"),
                    Err(e) => e.to_string(),
                },
            };
            let timeout = self.config.enable_timeout;
            self.halt(
                StopReason::EnableTimeout {
                    node,
                    axis,
                    state,
                    timeout,
                },
                now,
            );
            return self.stopping(now);
        }
        let mut words = [None; 3];
        for (k, word) in words.iter_mut().enumerate() {
            let drive = &mut self.drives[k];
            let (Some(statusword), Some(_)) = (drive.statusword, drive.target) else {
                continue;
            };
            // The TPDO was checked when it arrived: a statusword that decodes.
            *word = drive.sequencer.controlword(statusword).ok();
            // Enable ip mode once Operation enabled shows, not before (the sequencer
            // then sends enable operation, 0x0F).
            if drive.state() == Some(PowerState::OperationEnabled) {
                *word = word.map(|w| w | operation.running_bits());
            }
        }
        Some(words)
    }

    /// The spindle marks due once `sent` set-points are out.
    fn due_marks(&mut self) {
        let marks = &self.setpoints.marks;
        while self.next_mark < marks.len() && marks[self.next_mark].cycle <= self.sent {
            let mark = marks[self.next_mark];
            self.events.push(Event::Spindle {
                block: mark.index,
                rpm: mark.spindle,
            });
            self.next_mark += 1;
        }
    }

    fn running(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        self.due_marks();
        let Some(point) = self.setpoints.points.get(self.sent).copied() else {
            self.phase = Phase::Settling;
            self.deadline = Some(now + self.config.settle_timeout);
            return self.settling(now);
        };
        for (drive, target) in self.drives.iter_mut().zip(point) {
            drive.target = Some(target);
        }
        self.sent += 1;
        Some([Some(self.run_word()); 3])
    }

    /// The controlword while the set-points run: enable operation, with enable ip mode
    /// in interpolated position mode.
    fn run_word(&self) -> u16 {
        Command::EnableOperation.word() | self.config.operation.running_bits()
    }

    fn settling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let end = self.setpoints.end();
        let window = u64::from(self.config.settle_window);
        let off = (0..3).find(|&k| {
            self.drives[k]
                .actual
                .is_none_or(|a| a.abs_diff(end[k]) > window)
        });
        let Some(k) = off else {
            self.events.push(Event::Settled);
            self.phase = Phase::Disabling;
            self.deadline = Some(now + self.config.disable_timeout);
            for drive in &mut self.drives {
                drive.sequencer.set_target(Target::SwitchOnDisabled);
                drive.fresh = false;
            }
            return self.disabling(now);
        };
        if self.deadline.is_some_and(|d| now >= d) {
            let (node, axis) = self.reason_for(k);
            let reason = StopReason::NotSettled {
                node,
                axis,
                actual: self.drives[k].actual.unwrap_or(self.setpoints.start[k]),
                target: end[k],
                window: self.config.settle_window,
                timeout: self.config.settle_timeout,
            };
            self.halt(reason, now);
            return self.stopping(now);
        }
        Some([Some(self.run_word()); 3])
    }

    fn disabling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let disabled = |d: &Drive| d.fresh && d.state() == Some(PowerState::SwitchOnDisabled);
        if self.drives.iter().all(disabled) {
            self.events.push(Event::Finished);
            self.phase = Phase::Finished;
            self.deadline = None;
            return None;
        }
        if self.deadline.is_some_and(|d| now >= d) {
            let k = (0..3).find(|&k| !disabled(&self.drives[k])).unwrap_or(0);
            let (node, axis) = self.reason_for(k);
            let timeout = self.config.disable_timeout;
            // Disabling is what a stop does too: there is no more to try.
            self.events.push(Event::Stopped {
                reason: StopReason::NotDisabled {
                    node,
                    axis,
                    timeout,
                },
            });
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted {
                unconfirmed: vec![node],
            });
            return None;
        }
        let mut words = [None; 3];
        for (k, word) in words.iter_mut().enumerate() {
            let drive = &mut self.drives[k];
            *word = drive
                .statusword
                .and_then(|w| drive.sequencer.controlword(w).ok());
        }
        Some(words)
    }

    fn stopping(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let safe = |d: &Drive| {
            d.fresh
                && matches!(
                    d.state(),
                    Some(
                        PowerState::SwitchOnDisabled
                            | PowerState::Fault
                            | PowerState::NotReadyToSwitchOn
                    )
                )
        };
        let done = self.drives.iter().all(|d| d.lost || safe(d));
        if done || self.deadline.is_some_and(|d| now >= d) {
            let unconfirmed = (0..3)
                .filter(|&k| !safe(&self.drives[k]))
                .map(|k| self.config.nodes[k])
                .collect();
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted { unconfirmed });
            return None;
        }
        let words = self.drives.each_ref().map(|d| match d.state() {
            Some(PowerState::OperationEnabled) => Some(Command::QuickStop.word()),
            // Stopping on the quick stop ramp: hold it until the drive stands still.
            Some(PowerState::QuickStopActive) if !(d.fresh && d.still) => {
                Some(Command::QuickStop.word())
            }
            Some(PowerState::Fault | PowerState::FaultReactionActive) | None => None,
            Some(_) => Some(Command::DisableVoltage.word()),
        });
        Some(words)
    }
}

/// A node's configuration steps, in order (see the module docs).
fn configuration(node: NodeId, config: &SessionConfig, cycle: (u8, i8)) -> VecDeque<Op> {
    let mut ops = VecDeque::from([
        Op::CheckDeviceType,
        Op::Write(SdoWrite::u16(
            object::PRODUCER_HEARTBEAT,
            0,
            config.heartbeat_ms,
        )),
        Op::Write(SdoWrite::u8(
            object::MODES_OF_OPERATION,
            0,
            config.operation.mode().value() as u8,
        )),
        Op::Write(SdoWrite::u32(
            object::FOLLOWING_ERROR_WINDOW,
            0,
            config.following_error_window,
        )),
        Op::Write(SdoWrite::u8(object::INTERPOLATION_TIME_PERIOD, 1, cycle.0)),
        Op::Write(SdoWrite::u8(
            object::INTERPOLATION_TIME_PERIOD,
            2,
            cycle.1 as u8,
        )),
    ]);
    let pdo = PdoNumber::new(1).expect("PDO 1");
    let entry = |index, bits| MapEntry {
        index,
        sub: 0,
        bits,
    };
    let (set_point, sub) = config.operation.set_point_object();
    let mappings = [
        PdoConfig {
            direction: PdoDirection::Receive,
            number: pdo,
            transmission: EVERY_SYNC,
            entries: vec![
                entry(object::CONTROLWORD, 16),
                MapEntry {
                    index: set_point,
                    sub,
                    bits: 32,
                },
            ],
        },
        PdoConfig {
            direction: PdoDirection::Transmit,
            number: pdo,
            transmission: EVERY_SYNC,
            entries: vec![
                entry(object::STATUSWORD, 16),
                entry(object::POSITION_ACTUAL, 32),
            ],
        },
    ];
    for mapping in &mappings {
        let writes = cia301::pdo_mapping(node, mapping).expect("48 bits, valid entries");
        ops.extend(writes.into_iter().map(Op::Write));
    }
    ops
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::post::setpoints::{sample, SampleConfig};
    use crate::program::{Move, Pose, Program};
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
    fn setpoints(start: Pose) -> SetPoints {
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
            Bench::new(setpoints(Pose::known(0.0, 0.0, 0.0)), config, drives, false)
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

    /// A profile's `[connection.drives]`: counts for the sampler, the rest defaults.
    fn drives(more: &str) -> DriveSettings {
        toml::from_str(&format!(
            "counts_per_mm = [10000.0, 10000.0]\ncounts_per_degree = 2912.7\n{more}"
        ))
        .unwrap()
    }

    #[test]
    fn a_profiles_drives_make_the_session() {
        // The session's own defaults are a profile's: nodes 1-3, a 50 ms heartbeat
        // supervised at 150 ms, a 10 000-count window, cyclic synchronous position.
        assert_eq!(
            SessionConfig::for_drives(&drives("")),
            Ok(SessionConfig::default())
        );
        let config = SessionConfig::for_drives(&drives(
            "nodes = [10, 20, 30]\nheartbeat_ms = 20\nheartbeat_timeout_ms = 70\n\
             following_error_window = 2500",
        ))
        .unwrap();
        assert_eq!(config.nodes.map(NodeId::get), [10, 20, 30]);
        assert_eq!(config.heartbeat_ms, 20);
        assert_eq!(config.heartbeat_timeout, Duration::from_millis(70));
        assert_eq!(config.following_error_window, 2500);
        assert_eq!(
            SessionConfig {
                nodes: SessionConfig::default().nodes,
                heartbeat_ms: 50,
                heartbeat_timeout: Duration::from_millis(150),
                following_error_window: 10_000,
                ..config
            },
            SessionConfig::default()
        );
        // Interpolated position, everything else alike.
        assert_eq!(
            SessionConfig::for_drives(&drives("mode = \"ip\"")),
            Ok(SessionConfig {
                operation: Operation::InterpolatedPosition,
                ..SessionConfig::default()
            })
        );
        // Settings the profile refuses make no session, naming the key.
        for (more, key) in [
            ("nodes = [1, 0, 3]", "connection.drives.nodes"),
            ("nodes = [4, 4, 5]", "connection.drives.nodes"),
            ("heartbeat_ms = 0", "connection.drives.heartbeat_ms"),
            ("cycle_us = 0", "connection.drives.cycle_us"),
        ] {
            assert_eq!(
                SessionConfig::for_drives(&drives(more)).unwrap_err().key,
                key
            );
        }
    }

    #[test]
    fn a_job_runs_from_boot_up_to_disabled_drives() {
        let mut bench = Bench::plain();
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        let sp = setpoints(Pose::known(0.0, 0.0, 0.0));
        // The boot-ups went by unheard: reset communication after the wait, then each
        // node boots, is configured, started, enabled; M3 and M5 in their places.
        let kinds: Vec<String> = bench
            .events
            .iter()
            .map(|e| {
                format!("{e:?}")
                    .split([' ', '('])
                    .next()
                    .unwrap()
                    .to_string()
            })
            .collect();
        assert_eq!(
            kinds,
            [
                "ResetCommunication",
                "BootUp",
                "BootUp",
                "BootUp",
                "Configured",
                "Configured",
                "Configured",
                "Started",
                "Enabled",
                "Spindle",
                "Spindle",
                "Settled",
                "Finished"
            ]
        );
        assert_eq!(
            bench.events[0],
            Event::ResetCommunication {
                nodes: vec![node(1), node(2), node(3)]
            }
        );
        // The wait starts at the first poll, 1 ms in.
        assert_eq!(bench.sent[0], (51 * MS, std(0x000, &[0x82, 1])));
        // Every set-point once, in order, three RPDOs then the SYNC that applies them.
        let cycles = bench.cycles();
        let first = bench.enabled_syncs();
        for (k, point) in sp.points.iter().enumerate() {
            let (_, rpdos) = cycles[first + k];
            for axis in 0..3 {
                assert_eq!(
                    rpdos[axis],
                    Some((0x0F, to_wire(point[axis]))),
                    "set-point {k}"
                );
            }
        }
        assert_eq!(bench.session.progress(), (sp.points.len(), sp.points.len()));
        // Polled every millisecond: exactly one SYNC a 2 ms period, from the first to the
        // last.
        for pair in cycles.windows(2) {
            assert_eq!(pair[1].0 - pair[0].0, PERIOD);
        }
        // The drives are where the path ends, and disabled; the session saw them there.
        for (k, drive) in bench.drives.iter().enumerate() {
            assert_eq!(i64::from(drive.position()), sp.end()[k]);
            assert_eq!(drive.power_state(), SimPower::SwitchOnDisabled);
            assert_eq!(bench.session.drives()[k].actual, Some(sp.end()[k]));
        }
        // The walk up was one transition a cycle: 06, 07, 0F, then the set-points.
        let walk: Vec<u16> = cycles[..first]
            .iter()
            .filter_map(|c| c.1[0].map(|r| r.0))
            .collect();
        assert_eq!(walk, [0x06, 0x07, 0x0F]);
        // Nothing more after the end.
        let before = bench.sent.len();
        bench.step(10 * MS);
        assert_eq!(bench.sent.len(), before);
    }

    #[test]
    fn the_configuration_is_written_by_sdo_in_order() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Enabling);
        let requests: Vec<[u8; 8]> = bench
            .sent
            .iter()
            .filter(|(_, f)| f.id().raw() == 0x601)
            .map(|(_, f)| f.data().try_into().unwrap())
            .collect();
        let header = |r: &[u8; 8]| (r[0], u16::from_le_bytes([r[1], r[2]]), r[3]);
        let value = |r: &[u8; 8]| u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
        assert_eq!(header(&requests[0]), (0x40, 0x1000, 0));
        assert_eq!(
            (header(&requests[1]), value(&requests[1])),
            ((0x2B, 0x1017, 0), 10)
        );
        assert_eq!(
            (header(&requests[2]), value(&requests[2])),
            ((0x2F, 0x6060, 0), 8)
        );
        assert_eq!(
            (header(&requests[3]), value(&requests[3])),
            ((0x23, 0x6065, 0), 1000)
        );
        // 60C2h: the 2 ms cycle as 200 × 10⁻⁵ s, each sub-index one byte.
        assert_eq!(
            (header(&requests[4]), value(&requests[4])),
            ((0x2F, 0x60C2, 1), 200)
        );
        assert_eq!(
            (header(&requests[5]), value(&requests[5])),
            ((0x2F, 0x60C2, 2), (-5i8) as u8 as u32)
        );
        // RPDO1: invalid, type 1, clear, 6040h/16, 607Ah/32, two entries, valid.
        let rpdo: Vec<(u16, u8, u32)> = requests[6..13]
            .iter()
            .map(|r| (header(r).1, r[3], value(r)))
            .collect();
        assert_eq!(
            rpdo,
            [
                (0x1400, 1, 0x8000_0201),
                (0x1400, 2, 1),
                (0x1600, 0, 0),
                (0x1600, 1, 0x6040_0010),
                (0x1600, 2, 0x607A_0020),
                (0x1600, 0, 2),
                (0x1400, 1, 0x0000_0201),
            ]
        );
        assert_eq!(value(&requests[19]), 0x4000_0181);
        assert_eq!(requests.len(), 20);
        // NMT start to each node after the last answer, and the first SYNC with it.
        let tail: Vec<CanFrame> = bench.sent.iter().rev().take(4).rev().map(|s| s.1).collect();
        assert_eq!(
            tail,
            [
                std(0x000, &[0x01, 1]),
                std(0x000, &[0x01, 2]),
                std(0x000, &[0x01, 3]),
                std(0x080, &[])
            ]
        );
    }

    #[test]
    fn operations_name_their_mode_and_set_point() {
        let csp = Operation::CyclicSynchronousPosition;
        let ip = Operation::InterpolatedPosition;
        assert_eq!(Operation::default(), csp);
        assert_eq!(SessionConfig::default().operation, csp);
        assert_eq!((csp.mode().value(), ip.mode().value()), (8, 7));
        assert_eq!(csp.set_point_object(), (0x607A, 0));
        assert_eq!(ip.set_point_object(), (0x60C1, 1));
        assert_eq!(csp.to_string(), "cyclic synchronous position (mode 8)");
        assert_eq!(ip.to_string(), "interpolated position (mode 7)");
        // Both take Operation enabled with bit 12; only IP asks for bit 4 to get it.
        for operation in [csp, ip] {
            assert!(operation.follows(0x1237));
            assert!(!operation.follows(0x0237));
            assert!(!operation.follows(0x1233));
        }
        assert_eq!((csp.running_bits(), ip.running_bits()), (0, 0x10));
    }

    #[test]
    fn the_ip_configuration_is_written_by_sdo_in_order() {
        let mut csp = Bench::plain();
        csp.run_until(|s| s.phase() == Phase::Enabling);
        let mut ip = Bench::with(Operation::InterpolatedPosition);
        ip.run_until(|s| s.phase() == Phase::Enabling);
        let (csp, ip) = (csp.sdo_requests(), ip.sdo_requests());
        assert_eq!(ip.len(), 20);
        // 6060h = 7, interpolated position: one byte (0x2F).
        assert_eq!(ip[2], [0x2F, 0x60, 0x60, 0, 7, 0, 0, 0]);
        assert_eq!(csp[2], [0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]);
        // 60C2h as in CSP: the 2 ms cycle, 200 × 10⁻⁵ s.
        assert_eq!(ip[4], [0x2F, 0xC2, 0x60, 1, 200, 0, 0, 0]);
        assert_eq!(ip[5], [0x2F, 0xC2, 0x60, 2, (-5i8) as u8, 0, 0, 0]);
        // RPDO1: invalid, type 1, clear, 6040h/16, 60C1h sub-index 1/32, two entries,
        // valid.
        let value = |r: &[u8; 8]| u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
        let rpdo: Vec<(u16, u8, u32)> = ip[6..13]
            .iter()
            .map(|r| (u16::from_le_bytes([r[1], r[2]]), r[3], value(r)))
            .collect();
        assert_eq!(
            rpdo,
            [
                (0x1400, 1, 0x8000_0201),
                (0x1400, 2, 1),
                (0x1600, 0, 0),
                (0x1600, 1, 0x6040_0010),
                (0x1600, 2, 0x60C1_0120),
                (0x1600, 0, 2),
                (0x1400, 1, 0x0000_0201),
            ]
        );
        assert_eq!(value(&csp[10]), 0x607A_0020);
        // The rest as CSP writes it: device type, heartbeat, window, period, TPDO1.
        for k in (0..20).filter(|k| ![2, 10].contains(k)) {
            assert_eq!(ip[k], csp[k], "request {k}");
        }
    }

    #[test]
    fn an_ip_job_enables_ip_mode_before_the_set_points() {
        let mut bench = Bench::with(Operation::InterpolatedPosition);
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        assert!(bench.stopped().is_none());
        let sp = setpoints(Pose::known(0.0, 0.0, 0.0));
        let cycles = bench.cycles();
        // SYNC 1 asks for the TPDOs, 2-4 walk to Operation enabled, 5 enables ip mode:
        // the set-points start with SYNC 6.
        let first = bench.enabled_syncs();
        assert_eq!(first, 5);
        for axis in 0..3 {
            let walk: Vec<u16> = cycles[..first]
                .iter()
                .filter_map(|c| c.1[axis].map(|r| r.0))
                .collect();
            assert_eq!(walk, [0x06, 0x07, 0x0F, 0x1F], "node {}", axis + 1);
            // Held where they stand (60C1h = the actual position) meanwhile.
            assert!(cycles[..first]
                .iter()
                .all(|c| c.1[axis].is_none_or(|r| r.1 == 0)));
            // Each TPDO answers a SYNC: Switch on disabled, Ready to switch on, Switched
            // on, Operation enabled with ip mode inactive, then active (bit 12).
            let words = bench.statuswords(axis as u16 + 1);
            let shown: Vec<u16> = words[..5].iter().map(|w| w.1).collect();
            assert_eq!(shown, [0x0250, 0x0231, 0x0233, 0x0237, 0x1237]);
            // Bit 12 came with the SYNC that carried 0x1F, before the first set-point.
            assert_eq!(words[4].0, cycles[first - 1].0);
            assert!(words[4].0 < cycles[first].0);
        }
        // Every set-point once, in order, with enable ip mode.
        for (k, point) in sp.points.iter().enumerate() {
            let (_, rpdos) = cycles[first + k];
            for axis in 0..3 {
                assert_eq!(
                    rpdos[axis],
                    Some((0x1F, to_wire(point[axis]))),
                    "set-point {k}"
                );
            }
        }
        assert_eq!(bench.session.progress(), (sp.points.len(), sp.points.len()));
        // Disabled after settling: bit 4 gone with the disable voltage.
        let last = cycles.last().unwrap().1;
        assert_eq!(last.map(|r| r.unwrap().0), [0x00; 3]);
        for (k, drive) in bench.drives.iter().enumerate() {
            assert_eq!(i64::from(drive.position()), sp.end()[k]);
            assert_eq!(i64::from(drive.interpolation_data()), sp.end()[k]);
            assert_eq!(drive.target(), 0, "607Ah is not the set-point in IP mode");
            assert_eq!(drive.power_state(), SimPower::SwitchOnDisabled);
        }
    }

    #[test]
    fn set_points_wait_until_every_drive_shows_ip_mode_active() {
        // Node 2 shows ip mode inactive for its first three TPDOs in Operation enabled
        // with bit 4 (a drive slow to take it up): everyone is held at the start meanwhile.
        let mut bench = Bench::with(Operation::InterpolatedPosition);
        let mut held = 3;
        bench.tamper = Some(Box::new(move |f: CanFrame| {
            if f.id().raw() == 0x182 && f.data()[..2] == [0x37, 0x12] && held > 0 {
                held -= 1;
                let mut data = f.data().to_vec();
                data[1] = 0x02;
                return Some(std(0x182, &data));
            }
            Some(f)
        }));
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        let first = bench.enabled_syncs();
        assert_eq!(first, 8);
        let cycles = bench.cycles();
        for axis in 0..3 {
            let walk: Vec<u16> = cycles[..first]
                .iter()
                .filter_map(|c| c.1[axis].map(|r| r.0))
                .collect();
            assert_eq!(walk, [0x06, 0x07, 0x0F, 0x1F, 0x1F, 0x1F, 0x1F]);
        }
        assert!(cycles[..first]
            .iter()
            .all(|c| c.1.iter().flatten().all(|r| r.1 == 0)));
        // The first set-point went out after node 2's first TPDO with bit 12.
        let shown = bench
            .statuswords(2)
            .into_iter()
            .find(|w| w.1 & 0x1000 != 0)
            .unwrap();
        assert_eq!(shown.0, cycles[first - 1].0);
        let sp = setpoints(Pose::known(0.0, 0.0, 0.0));
        assert_eq!(cycles[first].1[1], Some((0x1F, to_wire(sp.points[0][1]))));
        // A drive that never shows it times out, named for what it lacks.
        let mut bench = Bench::with(Operation::InterpolatedPosition);
        bench.tamper = Some(statusword(2, 0x0237));
        bench.run_to_end();
        assert_eq!(bench.session.progress().0, 0);
        assert_eq!(
            bench.stopped().unwrap().to_string(),
            "node 2 (Z) not in Operation enabled after 100ms: OperationEnabled (statusword \
             0x0237) without ip mode active (bit 12)"
        );
    }

    #[test]
    fn an_ip_drive_leaving_ip_mode_while_running_stops_the_job() {
        let mut bench = Bench::with(Operation::InterpolatedPosition);
        bench.run_until(|s| s.progress().0 == 10);
        // One TPDO of node 3 shows Operation enabled without ip mode active.
        let mut once = true;
        bench.tamper = Some(Box::new(move |f: CanFrame| {
            if f.id().raw() == 0x183 && once {
                once = false;
                let mut data = f.data().to_vec();
                data[..2].copy_from_slice(&0x0237u16.to_le_bytes());
                return Some(std(0x183, &data));
            }
            Some(f)
        }));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::IpModeInactive {
                node: node(3),
                axis: Axis::C,
                statusword: 0x0237
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 3 (C) left interpolated position mode: statusword 0x0237 shows ip mode \
             inactive (bit 12), its set-points ignored"
        );
        assert!(bench.session.progress().0 < 12);
        // Quick stop, then disable voltage: neither with bit 4.
        let cycles = bench.cycles();
        let stop = cycles
            .iter()
            .position(|c| c.1[0].is_some_and(|r| r.0 == 0x02))
            .unwrap();
        assert!(cycles[stop..]
            .iter()
            .all(|c| c.1.iter().flatten().all(|r| r.0 & 0x10 == 0)));
        assert_eq!(bench.halted(), Some(&vec![]));
        assert!(bench
            .drives
            .iter()
            .all(|d| d.power_state() == SimPower::SwitchOnDisabled));
    }

    #[test]
    fn every_set_point_is_executed_once_in_either_mode() {
        let sp = setpoints(Pose::known(0.0, 0.0, 0.0));
        for operation in [
            Operation::CyclicSynchronousPosition,
            Operation::InterpolatedPosition,
        ] {
            let mut bench = Bench::with(operation);
            bench.run_to_end();
            assert_eq!(bench.session.phase(), Phase::Finished, "{operation}");
            for (k, drive) in bench.drives.iter_mut().enumerate() {
                // The drive's own record of the cycles it followed set-points in.
                let executed: Vec<(i32, i32)> = drive
                    .take_events()
                    .into_iter()
                    .filter_map(|e| match e {
                        SimEvent::Cycle { target, actual, .. } => Some((target, actual)),
                        _ => None,
                    })
                    .collect();
                // The enabling cycle at the start, then each set-point once, in order,
                // then (if any) the end held while the session saw it settle.
                let mut expected = vec![to_wire(sp.start[k])];
                expected.extend(sp.points.iter().map(|p| to_wire(p[k])));
                assert!(executed.len() >= expected.len(), "{operation}, node {k}");
                let (head, rest) = executed.split_at(expected.len());
                let set_points: Vec<i32> = head.iter().map(|c| c.0).collect();
                assert_eq!(set_points, expected, "{operation}, node {k}");
                assert!(rest.iter().all(|c| c.0 == to_wire(sp.end()[k])));
                // Each cycle ended at its set-point: the drives kept up.
                assert!(executed.iter().all(|(target, actual)| target == actual));
            }
        }
    }

    #[test]
    fn announced_drives_need_no_reset() {
        let drives = [1, 2, 3].map(DriveConfig::new);
        let mut bench = Bench::new(
            setpoints(Pose::known(0.0, 0.0, 0.0)),
            config(),
            drives,
            true,
        );
        bench.run_until(|s| s.phase() == Phase::Configuring);
        assert_eq!(bench.now, MS);
        assert!(bench
            .events
            .iter()
            .all(|e| !matches!(e, Event::ResetCommunication { .. })));
        assert_eq!(
            bench.events[..3],
            [1, 2, 3].map(|n| Event::BootUp { node: node(n) })
        );
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
    }

    #[test]
    fn a_silent_node_stops_the_job_before_it_starts() {
        let mut bench = Bench::plain();
        bench.pulled = Some(1);
        for id in [0x701, 0x703] {
            bench.session.receive(&std(id, &[0x00]), Duration::ZERO);
        }
        bench.run_to_end();
        // Nodes 1 and 3 announced themselves; node 2 is reset at 51 ms, given up at 101.
        assert_eq!(
            bench.events[2],
            Event::ResetCommunication {
                nodes: vec![node(2)]
            }
        );
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::NoBootUp {
                node: node(2),
                axis: Axis::Z
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 2 (Z) sent no boot-up message, even after NMT reset communication"
        );
        assert_eq!(bench.now, 101 * MS);
        assert_eq!(bench.halted(), Some(&vec![]));
        assert!(bench.sent.iter().all(|(_, f)| f.id().raw() == 0x000));
    }

    #[test]
    fn a_lost_heartbeat_stops_every_drive_and_names_the_node() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.progress().0 == 20);
        let pulled_at = bench.now;
        bench.pulled = Some(2);
        bench.run_to_end();
        let reason = bench.stopped().unwrap().clone();
        assert_eq!(
            reason,
            StopReason::HeartbeatLost {
                node: node(3),
                axis: Axis::C,
                timeout: 30 * MS
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 3 (C) heartbeat lost: none for 30ms (cable, power or a crashed drive)"
        );
        // Heard last at most one 10 ms period before the pull: stopped within 40 ms.
        let stopped_at = bench
            .cycles()
            .iter()
            .find(|c| c.1[0].is_some_and(|r| r.0 == 0x02))
            .unwrap()
            .0;
        assert!(
            stopped_at > pulled_at && stopped_at <= pulled_at + 41 * MS,
            "{stopped_at:?}"
        );
        // Quick stop to all (C never hears it), standstill, disable voltage; X and Z end
        // in Switch on disabled, C unconfirmed.
        // (A simulated drive stops dead: the first TPDO after the quick stop shows it
        // still.)
        let words: Vec<Option<u16>> = bench
            .cycles()
            .iter()
            .rev()
            .take(3)
            .map(|c| c.1[0].map(|r| r.0))
            .collect();
        assert_eq!(words, [Some(0x00), Some(0x02), Some(0x0F)]);
        assert_eq!(bench.drives[0].power_state(), SimPower::SwitchOnDisabled);
        assert_eq!(bench.drives[1].power_state(), SimPower::SwitchOnDisabled);
        assert_eq!(bench.halted(), Some(&vec![node(3)]));
        assert_eq!(bench.session.phase(), Phase::Stopped);
    }

    #[test]
    fn a_malformed_heartbeat_keeps_nobody_alive() {
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| {
            Some(if f.id().raw() == 0x702 && f.data() == [0x05] {
                std(0x702, &[0x05, 0x00])
            } else {
                f
            })
        }));
        bench.run_to_end();
        assert!(matches!(
            bench.stopped(),
            Some(StopReason::HeartbeatLost { axis: Axis::Z, .. })
        ));
    }

    #[test]
    fn an_emergency_stops_the_job_with_its_code_and_meaning() {
        // C's drive moves 50 counts a cycle where the path asks 200: it falls behind by
        // 150 a cycle and trips its 1000-count window.
        let mut drives = [1, 2, 3].map(DriveConfig::new);
        drives[2].max_step = 50;
        let mut bench = Bench::new(
            setpoints(Pose::known(0.0, 0.0, 0.0)),
            config(),
            drives,
            false,
        );
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::Emergency {
                node: node(3),
                axis: Axis::C,
                code: 0x8611,
                meaning: "following error"
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 3 (C) emergency 0x8611: following error"
        );
        assert!(bench
            .events
            .iter()
            .any(|e| matches!(e, Event::Emergency(m) if m.code == 0x8611)));
        // The faulted drive stays faulted; the others are quick-stopped and disabled.
        assert_eq!(bench.drives[2].power_state(), SimPower::Fault);
        assert_eq!(bench.drives[0].power_state(), SimPower::SwitchOnDisabled);
        assert_eq!(bench.drives[1].power_state(), SimPower::SwitchOnDisabled);
        assert_eq!(bench.halted(), Some(&vec![]));
        let last = bench.cycles().last().unwrap().1;
        assert_eq!(last[2], None, "no word for a faulted drive");
    }

    #[test]
    fn an_error_reset_emergency_is_only_reported() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Running);
        bench.session.receive(&std(0x081, &[0; 8]), bench.now);
        bench.step(MS);
        assert_eq!(bench.session.phase(), Phase::Running);
        assert!(bench
            .events
            .iter()
            .any(|e| matches!(e, Event::Emergency(m) if m.is_reset())));
    }

    #[test]
    fn a_late_poll_is_reported_and_sends_one_cycle() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Running);
        let syncs = bench.cycles().len();
        let due = bench.cycles().last().unwrap().0 + PERIOD;
        // 1 ms late: jitter, no report, the schedule keeps its phase.
        bench.step(due + MS - bench.now);
        assert_eq!(bench.cycles().len(), syncs + 1);
        assert!(bench
            .events
            .iter()
            .all(|e| !matches!(e, Event::Late { .. })));
        bench.step(MS);
        assert_eq!(
            bench.cycles().len(),
            syncs + 2,
            "the next one at its own time"
        );
        // 7 ms without a poll: one cycle, not four, and a report.
        let due = bench.cycles().last().unwrap().0 + PERIOD;
        bench.step(7 * MS);
        assert_eq!(bench.cycles().len(), syncs + 3);
        let late_by = bench.now - due;
        assert_eq!(
            bench.events.last(),
            Some(&Event::Late {
                sync: syncs as u64 + 3,
                late_by
            })
        );
        // The schedule restarts from the late poll, and every set-point still goes out
        // once: the path is slowed, not cut.
        let restart = bench.now;
        bench.step(MS);
        assert_eq!(bench.cycles().len(), syncs + 3);
        bench.step(MS);
        assert_eq!(bench.cycles().last().unwrap().0, restart + PERIOD);
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        let (sent, total) = bench.session.progress();
        assert_eq!(sent, total);
    }

    #[test]
    fn a_reboot_during_the_job_stops_it() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Running);
        // Someone resets node 1's communication: it boots again with its default objects.
        bench.drives[0].receive(&Frame::data(0x000, &[0x82, 1]));
        bench.step(MS);
        assert_eq!(
            bench.stopped(),
            Some(&StopReason::Rebooted {
                node: node(1),
                axis: Axis::X
            })
        );
    }

    #[test]
    fn a_node_leaving_operational_stops_the_job() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Running);
        // NMT stop for node 2 from elsewhere: its heartbeat says Stopped, its PDOs cease.
        bench.drives[1].receive(&Frame::data(0x000, &[0x02, 2]));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::NotOperational {
                node: node(2),
                axis: Axis::Z,
                state: NmtState::Stopped
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 2 (Z) left NMT Operational: its heartbeat shows Stopped"
        );
        // It no longer answers: it cannot be confirmed disabled.
        assert_eq!(bench.halted(), Some(&vec![node(2)]));
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

    #[test]
    fn statuswords_out_of_line_stop_the_job() {
        let cases = [
            (
                1,
                0x0218,
                StopReason::Fault {
                    node: node(1),
                    axis: Axis::X,
                    statusword: 0x0218,
                },
            ),
            (
                3,
                0x1217,
                StopReason::LeftOperation {
                    node: node(3),
                    axis: Axis::C,
                    state: PowerState::QuickStopActive,
                },
            ),
            (
                2,
                0x0048,
                StopReason::Statusword {
                    node: node(2),
                    axis: Axis::Z,
                    statusword: 0x0048,
                },
            ),
        ];
        for (id, word, expected) in cases {
            let mut bench = Bench::plain();
            bench.run_until(|s| s.progress().0 == 10);
            bench.tamper = Some(statusword(id, word));
            bench.run_to_end();
            assert_eq!(bench.stopped(), Some(&expected));
            assert!(bench.session.progress().0 < 20);
        }
        assert_eq!(
            StopReason::Fault {
                node: node(1),
                axis: Axis::X,
                statusword: 0x0218
            }
            .to_string(),
            "node 1 (X) faulted (statusword 0x0218)"
        );
    }

    #[test]
    fn a_short_tpdo_stops_the_job() {
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| {
            Some(if f.id().raw() == 0x181 {
                std(0x181, &f.data()[..3])
            } else {
                f
            })
        }));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::Tpdo {
                node: node(1),
                axis: Axis::X,
                len: 3
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 1 (X): TPDO1 of 3 bytes, its mapping (6041h, 6064h) has 6"
        );
        // Stopped while enabling: nothing was running, the others confirm at once.
        assert_eq!(bench.halted(), Some(&vec![node(1)]));
    }

    #[test]
    fn configuration_failures_stop_before_anything_moves() {
        // A device that is not CiA 402 (0191h).
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| {
            Some(
                if f.id().raw() == 0x581 && f.data()[..4] == [0x43, 0x00, 0x10, 0x00] {
                    std(0x581, &[0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x02, 0x00])
                } else {
                    f
                },
            )
        }));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::DeviceType {
                node: node(1),
                axis: Axis::X,
                device_type: 0x0002_0191
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 1 (X) is not a CiA 402 drive: device type 0x00020191 (1000h)"
        );
        assert_eq!(bench.halted(), Some(&vec![]));
        assert!(bench.sent.iter().all(|(_, f)| f.id().raw() != 0x080));
        // A server abort: node 2 refuses 6060h.
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| {
            Some(if f.id().raw() == 0x582 && f.data()[1..3] == [0x60, 0x60] {
                std(0x582, &[0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06])
            } else {
                f
            })
        }));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            reason.to_string(),
            "configuration failed: node 2 aborted SDO 6060h/00h: 0x06090030 (Invalid value for \
             parameter (download only))"
        );
        // No answer from node 3's SDO server: a timeout, and the client's abort.
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| (f.id().raw() != 0x583).then_some(f)));
        bench.run_to_end();
        assert!(matches!(
            bench.stopped(),
            Some(StopReason::Sdo(SdoError::Timeout { index: 0x1000, .. }))
        ));
        let abort = bench.sent.last().unwrap().1;
        assert_eq!(
            abort,
            std(0x603, &[0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05])
        );
    }

    #[test]
    fn a_drive_away_from_the_paths_start_is_not_enabled() {
        let mut drives = [1, 2, 3].map(DriveConfig::new);
        drives[1].position = 500;
        let tolerant = SessionConfig {
            start_tolerance: 100,
            ..config()
        };
        let mut bench = Bench::new(
            setpoints(Pose::known(0.0, 0.0, 0.0)),
            tolerant.clone(),
            drives.clone(),
            false,
        );
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            *reason,
            StopReason::StartMismatch {
                node: node(2),
                axis: Axis::Z,
                actual: 500,
                start: 0,
                tolerance: 100
            }
        );
        assert_eq!(
            reason.to_string(),
            "node 2 (Z) stands at 500 counts, the path starts at 0: more than the 100 counts allowed"
        );
        assert!(
            bench.cycles().iter().all(|c| c.1[1].is_none()),
            "node 2 never commanded"
        );
        // Within the tolerance it runs, from where it stands.
        let lenient = SessionConfig {
            start_tolerance: 500,
            ..tolerant
        };
        let mut bench = Bench::new(
            setpoints(Pose::known(0.0, 0.0, 0.0)),
            lenient,
            drives,
            false,
        );
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        assert_eq!(bench.cycles()[1].1[1], Some((0x06, 500)));
    }

    #[test]
    fn phases_that_do_not_end_time_out() {
        // Node 2 seems to stay in Switch on disabled.
        let mut bench = Bench::plain();
        bench.tamper = Some(statusword(2, 0x0250));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            reason.to_string(),
            "node 2 (Z) not in Operation enabled after 100ms: SwitchOnDisabled (statusword 0x0250)"
        );
        // Node 3 sends no TPDO at all.
        let mut bench = Bench::plain();
        bench.tamper = Some(Box::new(|f: CanFrame| (f.id().raw() != 0x183).then_some(f)));
        bench.run_to_end();
        assert!(matches!(
            bench.stopped(),
            Some(StopReason::EnableTimeout { node: n, state, .. }) if *n == node(3) && state == "no TPDO seen"
        ));
        // Node 1 cannot follow the last jump of the path (its window switched off).
        let mut sp = setpoints(Pose::known(0.0, 0.0, 0.0));
        sp.points.last_mut().unwrap()[0] = 1_000_000;
        let unbounded = SessionConfig {
            following_error_window: u32::MAX,
            ..config()
        };
        let mut bench = Bench::new(sp, unbounded, [1, 2, 3].map(DriveConfig::new), false);
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert!(
            matches!(reason, StopReason::NotSettled { node: n, target: 1_000_000, .. } if *n == node(1))
        );
        assert!(reason.to_string().starts_with("node 1 (X) at "));
        assert!(reason
            .to_string()
            .ends_with("did not settle within 0 counts of 1000000 in 100ms"));
        // Node 1 seems to stay enabled after the job.
        let mut bench = Bench::plain();
        bench.run_until(|s| s.progress().0 == s.progress().1);
        bench.tamper = Some(statusword(1, 0x1237));
        bench.run_to_end();
        let reason = bench.stopped().unwrap();
        assert_eq!(
            reason.to_string(),
            "node 1 (X) not disabled within 100ms after the job"
        );
        assert_eq!(bench.halted(), Some(&vec![node(1)]));
    }

    #[test]
    fn a_requested_stop_is_a_stop_and_the_first_reason_stands() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.progress().0 == 5);
        bench.session.stop(bench.now);
        bench.session.stop(bench.now);
        bench.run_to_end();
        let stops = bench
            .events
            .iter()
            .filter(|e| matches!(e, Event::Stopped { .. }))
            .count();
        assert_eq!(stops, 1);
        assert_eq!(bench.stopped(), Some(&StopReason::Requested));
        assert_eq!(StopReason::Requested.to_string(), "stop requested");
        assert_eq!(bench.halted(), Some(&vec![]));
        assert!(bench
            .drives
            .iter()
            .all(|d| d.power_state() == SimPower::SwitchOnDisabled));
        // Before anything runs, a stop ends the session at once.
        let mut bench = Bench::plain();
        bench.session.stop(Duration::ZERO);
        assert_eq!(bench.session.phase(), Phase::Stopped);
        assert_eq!(
            bench.session.events(),
            [
                Event::Stopped {
                    reason: StopReason::Requested
                },
                Event::Halted {
                    unconfirmed: vec![]
                }
            ]
        );
        assert!(bench.session.poll(MS).is_empty());
    }

    #[test]
    fn c_past_the_32_bit_range_runs_and_reads_back_unwrapped() {
        // C starts 1000 counts below INTEGER32's top and turns 12 000 counts on.
        let c0 = (f64::from(i32::MAX) - 1000.0) / SCALE[2];
        let sp = setpoints(Pose::known(0.0, 0.0, c0));
        assert!(sp.end()[2] > i64::from(i32::MAX));
        let mut drives = [1, 2, 3].map(DriveConfig::new);
        drives[2].position = to_wire(sp.start[2]);
        let mut bench = Bench::new(sp.clone(), config(), drives, false);
        bench.run_to_end();
        assert_eq!(bench.session.phase(), Phase::Finished);
        assert_eq!(bench.drives[2].position(), to_wire(sp.end()[2]));
        assert!(
            bench.drives[2].position() < 0,
            "the drive's counter wrapped"
        );
        assert_eq!(bench.session.drives()[2].actual, Some(sp.end()[2]));
    }

    #[test]
    fn frames_for_others_are_ignored() {
        let mut bench = Bench::plain();
        bench.run_until(|s| s.phase() == Phase::Running);
        let ext = CanFrame::new(CanId::Extended(0x181), &[0x18, 0x02, 0, 0, 0, 0]).unwrap();
        let rtr = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
        for frame in [
            std(0x709, &[0x00]),
            std(0x089, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
            std(0x181 + 0x100, &[0x18, 0x02, 0, 0, 0, 0]),
            std(0x601, &[0x40, 0, 0, 0, 0, 0, 0, 0]),
            std(0x081, &[0x11]),
            ext,
            rtr,
        ] {
            bench.session.receive(&frame, bench.now);
        }
        bench.step(MS);
        assert_eq!(bench.session.phase(), Phase::Running);
        assert!(bench.stopped().is_none());
    }

    #[test]
    fn emergency_codes_are_named() {
        let emcy = |code| Emergency {
            node: node(1),
            code,
            register: 1,
            manufacturer: [0; 5],
        };
        assert_eq!(emcy_meaning(&emcy(0x8611)), "following error");
        assert_eq!(
            emcy_meaning(&emcy(0x8612)),
            "reference limit (position limit)"
        );
        assert_eq!(
            emcy_meaning(&emcy(0x8130)),
            "life guard error or heartbeat error"
        );
        assert_eq!(
            emcy_meaning(&emcy(0x8210)),
            "PDO not processed due to length error"
        );
        assert_eq!(emcy_meaning(&emcy(0x9000)), "external error");
        assert_eq!(emcy_meaning(&emcy(0x8110)), "CAN overrun (objects lost)");
        assert_eq!(emcy_meaning(&emcy(0x8120)), "CAN in error passive mode");
        assert_eq!(emcy_meaning(&emcy(0x8140)), "recovered from bus off");
        assert_eq!(emcy_meaning(&emcy(0x8220)), "PDO length exceeded");
        // Others by their class (a manufacturer's code, a temperature).
        assert_eq!(emcy_meaning(&emcy(0xFF64)), "device specific");
        assert_eq!(emcy_meaning(&emcy(0x4210)), "temperature");
    }

    #[test]
    fn impossible_configurations_are_refused() {
        let sp = || setpoints(Pose::known(0.0, 0.0, 0.0));
        let cases = [
            (
                SessionConfig {
                    nodes: [node(1), node(2), node(1)],
                    ..config()
                },
                "CAN session: nodes: 1, 2, 1 are not three nodes",
            ),
            (
                SessionConfig {
                    heartbeat_ms: 0,
                    ..config()
                },
                "CAN session: heartbeat_ms: 0 switches the heartbeat off",
            ),
            (
                SessionConfig {
                    heartbeat_timeout: 10 * MS,
                    ..config()
                },
                "CAN session: heartbeat_timeout: 10ms is not longer than the producer's 10ms",
            ),
        ];
        for (config, message) in cases {
            assert_eq!(Session::new(config, sp()).unwrap_err().to_string(), message);
        }
        // 60C2h holds a cycle as at most 255 × 10^index s, whole microseconds.
        for (period, shown) in [
            (Duration::ZERO, "0ns"),
            (Duration::from_micros(2561), "2.561ms"),
        ] {
            let mut odd = sp();
            odd.period = period;
            assert_eq!(
                Session::new(config(), odd).unwrap_err().to_string(),
                format!(
                    "CAN session: setpoints.period: {shown} is not a cycle 60C2h holds \
                     (value ≤ 255 × 10^index s, whole µs)"
                )
            );
        }
    }
}
