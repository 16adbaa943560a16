//! What the session reports: [`Event`]s in order, the [`StopReason`] of a stop, each
//! drive's [`DriveStatus`], and [`emcy_meaning`] for the emergency codes drives send.

use std::time::Duration;

use thiserror::Error;

use crate::config::machine::Axis;
use crate::protocol::canopen::cia301::{Emergency, NmtState, NodeId, SdoError};
use crate::protocol::canopen::cia402::PowerState;

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
        /// [`SessionConfig::start_tolerance`](super::SessionConfig::start_tolerance).
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
        /// [`SessionConfig::enable_timeout`](super::SessionConfig::enable_timeout).
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
        /// [`SessionConfig::settle_window`](super::SessionConfig::settle_window).
        window: u32,
        /// [`SessionConfig::settle_timeout`](super::SessionConfig::settle_timeout).
        timeout: Duration,
    },
    /// A drive not in Switch on disabled in time after the job.
    #[error("node {node} ({axis}) not disabled within {timeout:?} after the job")]
    NotDisabled {
        /// The node.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// [`SessionConfig::disable_timeout`](super::SessionConfig::disable_timeout).
        timeout: Duration,
    },
    /// [`Session::stop`](super::Session::stop).
    #[error("stop requested")]
    Requested,
    /// The caller stopped the job ([`Session::stop_held`](super::Session::stop_held)): an
    /// interrupted bridge, a stop button.
    #[error("interrupted ({why}): the path held to a stand, then the drives disabled")]
    Interrupted {
        /// Why, in the caller's words.
        why: String,
    },
    /// The set-points moved on and no drive reported anything new for
    /// [`SessionConfig::stall_timeout`](super::SessionConfig::stall_timeout).
    #[error(
        "nothing new from the drives for {} s: the path held to a stand, then the drives \
         disabled",
        .waited.as_secs_f64()
    )]
    Stalled {
        /// The stall timeout.
        waited: Duration,
    },
    /// A gentle stop's drives did not stand at the held targets in time: quick stop.
    #[error(
        "node {node} ({axis}) did not stand within {window} counts of its held target \
         within {waited:?} of the stop: quick stop"
    )]
    NoStand {
        /// The first drive not standing.
        node: NodeId,
        /// Its axis.
        axis: Axis,
        /// [`SessionConfig::settle_window`](super::SessionConfig::settle_window).
        window: u32,
        /// How long the session waited: the hold ramp and the settle timeout.
        waited: Duration,
    },
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
    /// The caller's hold has brought the path to a stand: the drives hold their targets on
    /// the path.
    Held {
        /// Set-points passed.
        sent: usize,
    },
    /// The caller's resume has brought the path back to speed.
    Resumed,
    /// The set-points' clock has reached the feed override asked: the path runs at this
    /// percent of the programmed feed.
    FeedOverride {
        /// Percent.
        percent: u16,
    },
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
            Event::Held { sent } => write!(
                f,
                "held after {sent} set-points: the drives stand on the path"
            ),
            Event::Resumed => write!(f, "resumed: the set-points run at speed again"),
            Event::FeedOverride { percent } => write!(
                f,
                "feed override {percent} %: the set-points run at {percent} % of the \
                 programmed feed"
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
    /// Its last position actual value, counts (unwrapped: see
    /// [`unwrap_near`](crate::post::setpoints::unwrap_near)).
    pub actual: Option<i64>,
    /// The last target sent, counts.
    pub target: Option<i64>,
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
