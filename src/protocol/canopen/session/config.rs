//! What configures a session: [`SessionConfig`] (nodes, timeouts, windows), the drives'
//! mode of operation ([`Operation`]), and [`SessionError`] for a configuration the session
//! refuses.

use std::time::Duration;

use thiserror::Error;

use crate::config::connection::{DriveMode, DriveSettings, SettingError};
use crate::protocol::canopen::cia301::NodeId;
use crate::protocol::canopen::cia402::{object, Mode, PowerState, Statusword, ENABLE_IP_MODE};

/// How the session runs the bus.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SessionConfig {
    /// The drives of X, Z and C, in that order; distinct.
    pub nodes: [NodeId; 3],
    /// How long to wait for boot-up messages, before and after NMT reset communication.
    /// CiA 301 sets no time for a reset of communication; a drive's takes milliseconds,
    /// but the master waits on its host's clock, and the default's two seconds (half a
    /// second, as before, was lost to a host busy elsewhere: the job refused for drives
    /// that were there) cost a start nothing it would notice.
    pub boot_wait: Duration,
    /// How long an SDO transfer may take. A drive's firmware answers SDOs beside its
    /// control cycle, and neither CiA 301 nor a drive says how soon; the configuration is
    /// no race, so the default waits a second (100 ms, as before, was lost to a host busy
    /// elsewhere: the job refused for a drive that was there).
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
    /// How long a hold takes to bring the path to a stand, and a resume to bring it back
    /// to speed: at least the time every axis needs to stop from its max rate
    /// ([`MachineProfile::stop_time`](crate::config::machine::MachineProfile::stop_time)).
    pub hold_ramp: Duration,
    /// Stop the job gently ([`Session::stop_held`](super::Session::stop_held)) when the
    /// set-points move on and no drive's TPDO has shown anything new for this long, in the
    /// session's time; `None` waits. See the session's docs, "Stopping".
    pub stall_timeout: Option<Duration>,
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
    pub(super) fn running_bits(self) -> u16 {
        match self {
            Operation::CyclicSynchronousPosition => 0,
            Operation::InterpolatedPosition => ENABLE_IP_MODE,
        }
    }

    /// Whether a drive showing `statusword` takes its set-points: Operation enabled, and
    /// bit 12 (CSP's "drive follows the command value", interpolated position's "ip mode
    /// active").
    pub(super) fn follows(self, statusword: u16) -> bool {
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
            boot_wait: Duration::from_secs(2),
            sdo_timeout: Duration::from_secs(1),
            heartbeat_ms: 50,
            heartbeat_timeout: Duration::from_millis(150),
            following_error_window: 10_000,
            start_tolerance: 0,
            enable_timeout: Duration::from_secs(1),
            settle_window: 10,
            settle_timeout: Duration::from_secs(1),
            disable_timeout: Duration::from_secs(1),
            operation: Operation::CyclicSynchronousPosition,
            hold_ramp: Duration::from_millis(200),
            stall_timeout: None,
        }
    }
}

impl SessionConfig {
    /// The session for a profile's drives: their nodes, heartbeat, following error window
    /// and mode, every other setting at [`SessionConfig::default`]. An error, naming the
    /// key, for settings [`DriveSettings::validate`] refuses, or for data sheets
    /// (`connection.drives.eds`) that lack an object the session uses as it uses it
    /// ([`objects_used`](super::objects_used)).
    pub fn for_drives(drives: &DriveSettings) -> Result<SessionConfig, SettingError> {
        drives.validate()?;
        let mut nodes = SessionConfig::default().nodes;
        for (node, &id) in nodes.iter_mut().zip(&drives.nodes) {
            *node = NodeId::new(id).map_err(|e| SettingError {
                key: "connection.drives.nodes".into(),
                problem: e.to_string(),
            })?;
        }
        super::objects::check_data_sheets(drives)?;
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
