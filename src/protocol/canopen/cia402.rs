//! CiA 402 (IEC 61800-7-201, the drive profile) for a master: the power drive system's
//! state machine as seen through the statusword (6041h) and driven through the controlword
//! (6040h), the modes of operation, and the objects the bridge uses.
//!
//! # The state machine
//!
//! A drive reports its state in statusword bits 0–3, 5 and 6 (ready to switch on, switched
//! on, operation enabled, fault, quick stop (active low), switch on disabled); each state
//! is a pattern over some of those bits, the rest being don't-care:
//!
//! | state | pattern (bits 6…0) | mask |
//! | --- | --- | --- |
//! | Not ready to switch on | `0xx 0000` | 0x4F = 0x00 |
//! | Switch on disabled | `1xx 0000` | 0x4F = 0x40 |
//! | Ready to switch on | `01x 0001` | 0x6F = 0x21 |
//! | Switched on | `01x 0011` | 0x6F = 0x23 |
//! | Operation enabled | `01x 0111` | 0x6F = 0x27 |
//! | Quick stop active | `00x 0111` | 0x6F = 0x07 |
//! | Fault reaction active | `0xx 1111` | 0x4F = 0x0F |
//! | Fault | `0xx 1000` | 0x4F = 0x08 |
//!
//! The master moves it with controlword commands over bits 0–3 and 7 (switch on, enable
//! voltage, quick stop (active low), enable operation, fault reset): shutdown 0x06
//! (transitions 2, 6, 8), switch on 0x07 (3), enable operation 0x0F (4, 16), disable
//! operation 0x07 (5), disable voltage 0x00 (7, 9, 10, 12), quick stop 0x02 (7, 10, 11),
//! and fault reset, which acts on the *rising edge* of bit 7 (15).
//!
//! [`next_controlword`] is the one step towards a target from a state; [`PowerSequencer`]
//! adds the one thing a stateless step cannot know: whether bit 7 was already high, so a
//! fault reset must first drop it to make an edge.
//!
//! It climbs one transition a command (2, then 3, then 4) and checks the statusword
//! between, although 0x0F from Ready to switch on is allowed to do 3 and 4 at once: that
//! shortcut would enable a drive whose Switched on state never showed, and a step that
//! does not happen is then a state the master sees rather than a guess. From Quick stop
//! active it disables voltage (12) rather than re-enabling (16), which only drives with
//! quick stop option codes 5–8 allow.
//!
//! In cyclic synchronous position mode the drive follows 607Ah the moment operation is
//! enabled: the master must write the actual position (6064h) as target before enabling,
//! or the drive jumps (or trips its following-error window). Statusword bit 12 then says
//! the drive follows it ([`Statusword::following_target`]).
//!
//! In interpolated position mode (7) the set-point is the interpolation data record's
//! first entry, 60C1h sub-index 1, and Operation enabled is not enough: the master also
//! sets controlword bit 4, "enable ip mode" ([`ENABLE_IP_MODE`]), and the drive takes
//! set-points only while its statusword shows bit 12, "ip mode active"
//! ([`Statusword::ip_mode_active`]). Bit 4 is no part of the state machine's commands
//! (above, bits 0–3 and 7), so 0x1F is enable operation with ip mode enabled; any command
//! without it (quick stop 0x02, disable voltage 0x00) ends ip mode too.

use thiserror::Error;

/// Object indices (and the CiA 301 objects the drive setup uses).
pub mod object {
    /// 1000h device type (CiA 402 drives: 0192h in the low 16 bits).
    pub const DEVICE_TYPE: u16 = 0x1000;
    /// 1001h error register.
    pub const ERROR_REGISTER: u16 = 0x1001;
    /// 1016h consumer heartbeat time (sub-indices 1…: node id << 16 | ms).
    pub const CONSUMER_HEARTBEAT: u16 = 0x1016;
    /// 1017h producer heartbeat time, ms (UNSIGNED16; 0 = off).
    pub const PRODUCER_HEARTBEAT: u16 = 0x1017;
    /// 6040h controlword (UNSIGNED16).
    pub const CONTROLWORD: u16 = 0x6040;
    /// 6041h statusword (UNSIGNED16, read-only).
    pub const STATUSWORD: u16 = 0x6041;
    /// 6060h modes of operation (INTEGER8).
    pub const MODES_OF_OPERATION: u16 = 0x6060;
    /// 6061h modes of operation display (INTEGER8, read-only).
    pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
    /// 6064h position actual value (INTEGER32, read-only).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// 6065h following error window (UNSIGNED32; FFFFFFFFh switches the check off).
    pub const FOLLOWING_ERROR_WINDOW: u16 = 0x6065;
    /// 607Ah target position (INTEGER32).
    pub const TARGET_POSITION: u16 = 0x607A;
    /// 60C1h interpolation data record (sub-index 1: the position set-point in
    /// interpolated position mode).
    pub const INTERPOLATION_DATA: u16 = 0x60C1;
    /// 60C2h interpolation time period: sub 1 the value (UNSIGNED8), sub 2 the index
    /// (INTEGER8), the period being value × 10^index s. Drives in cyclic synchronous
    /// modes take it as the SYNC period they lock their cycle to.
    pub const INTERPOLATION_TIME_PERIOD: u16 = 0x60C2;
}

/// A cycle period as 60C2h holds it, (value, index) with period = value × 10^index s, or
/// `None` if that cannot be exact (value at most 255, index from −6: a whole number of
/// microseconds whose significant digits fit 255).
pub fn interpolation_time_period(period: std::time::Duration) -> Option<(u8, i8)> {
    let mut value = period.as_micros();
    if value == 0 || !period.subsec_nanos().is_multiple_of(1000) {
        return None;
    }
    let mut index = -6i8;
    while value > 255 {
        if !value.is_multiple_of(10) || index == 0 {
            return None;
        }
        value /= 10;
        index += 1;
    }
    Some((value as u8, index))
}

/// CiA 402's emergency code for a following error.
pub const EMCY_FOLLOWING_ERROR: u16 = 0x8611;

/// A statusword that matches none of the states' patterns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[error("statusword 0x{0:04X} matches no CiA 402 state")]
pub struct UnknownStatusword(pub u16);

/// The power drive system's states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PowerState {
    /// Initialising; no command is accepted (leaves automatically, transition 1).
    NotReadyToSwitchOn,
    /// Initialised, power stage off.
    SwitchOnDisabled,
    /// Ready; high voltage may be applied.
    ReadyToSwitchOn,
    /// Power stage on, drive function disabled.
    SwitchedOn,
    /// The drive follows its set-points.
    OperationEnabled,
    /// Stopping or stopped on the quick stop ramp.
    QuickStopActive,
    /// Reacting to a fault (leaves automatically to Fault, transition 14).
    FaultReactionActive,
    /// Faulted; power stage off.
    Fault,
}

impl PowerState {
    /// Decodes statusword bits 0–3, 5, 6 with the standard masks.
    pub fn from_statusword(word: u16) -> Result<PowerState, UnknownStatusword> {
        Ok(match (word & 0x4F, word & 0x6F) {
            (0x00, _) => PowerState::NotReadyToSwitchOn,
            (0x40, _) => PowerState::SwitchOnDisabled,
            (0x0F, _) => PowerState::FaultReactionActive,
            (0x08, _) => PowerState::Fault,
            (_, 0x21) => PowerState::ReadyToSwitchOn,
            (_, 0x23) => PowerState::SwitchedOn,
            (_, 0x27) => PowerState::OperationEnabled,
            (_, 0x07) => PowerState::QuickStopActive,
            _ => return Err(UnknownStatusword(word)),
        })
    }
}

/// The statusword's other bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Statusword(pub u16);

impl Statusword {
    /// The state (bits 0–3, 5, 6).
    pub fn state(self) -> Result<PowerState, UnknownStatusword> {
        PowerState::from_statusword(self.0)
    }

    fn bit(self, n: u8) -> bool {
        self.0 & (1 << n) != 0
    }

    /// Bit 4: high voltage is applied.
    pub fn voltage_enabled(self) -> bool {
        self.bit(4)
    }

    /// Bit 7: a warning (the drive still runs).
    pub fn warning(self) -> bool {
        self.bit(7)
    }

    /// Bit 9: the controlword is processed (remote control).
    pub fn remote(self) -> bool {
        self.bit(9)
    }

    /// Bit 10: target reached (mode-specific).
    pub fn target_reached(self) -> bool {
        self.bit(10)
    }

    /// Bit 11: an internal limit is active.
    pub fn internal_limit(self) -> bool {
        self.bit(11)
    }

    /// Bit 12 in cyclic synchronous position mode: the drive follows the target position
    /// (0: the target is ignored).
    pub fn following_target(self) -> bool {
        self.bit(12)
    }

    /// Bit 12 in interpolated position mode: ip mode active, the drive takes the
    /// set-points of 60C1h (0: inactive, they are ignored).
    pub fn ip_mode_active(self) -> bool {
        self.bit(12)
    }

    /// Bit 13 in the position modes: following error.
    pub fn following_error(self) -> bool {
        self.bit(13)
    }
}

/// Controlword commands (bits 0–3 and 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Command {
    /// 0x06: transitions 2, 6, 8 (→ Ready to switch on).
    Shutdown,
    /// 0x07: transition 3 (→ Switched on).
    SwitchOn,
    /// 0x0F: transitions 4, 16 (→ Operation enabled).
    EnableOperation,
    /// 0x07: transition 5 (Operation enabled → Switched on).
    DisableOperation,
    /// 0x00: transitions 7, 9, 10, 12 (→ Switch on disabled).
    DisableVoltage,
    /// 0x02: transitions 7, 10, 11 (Operation enabled → Quick stop active).
    QuickStop,
    /// 0x80: transition 15 (Fault → Switch on disabled) on the rising edge of bit 7.
    FaultReset,
}

impl Command {
    /// The controlword.
    pub fn word(self) -> u16 {
        match self {
            Command::Shutdown => 0x06,
            Command::SwitchOn | Command::DisableOperation => 0x07,
            Command::EnableOperation => 0x0F,
            Command::DisableVoltage => 0x00,
            Command::QuickStop => 0x02,
            Command::FaultReset => 0x80,
        }
    }
}

/// Bit 7 of the controlword: fault reset.
pub const FAULT_RESET_BIT: u16 = 0x80;

/// Bit 4 of the controlword in interpolated position mode: enable ip mode (0: inactive).
pub const ENABLE_IP_MODE: u16 = 0x10;

/// States a master can hold a drive in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Target {
    /// Power stage off.
    SwitchOnDisabled,
    /// Ready, power stage off.
    ReadyToSwitchOn,
    /// Power stage on, not following set-points.
    SwitchedOn,
    /// Following set-points.
    OperationEnabled,
}

impl Target {
    /// The command that holds (or, from above, reaches) this state.
    fn hold(self) -> Command {
        match self {
            Target::SwitchOnDisabled => Command::DisableVoltage,
            Target::ReadyToSwitchOn => Command::Shutdown,
            Target::SwitchedOn => Command::SwitchOn,
            Target::OperationEnabled => Command::EnableOperation,
        }
    }

    /// Position on the ladder Switch on disabled → Operation enabled.
    fn rung(self) -> u8 {
        self as u8
    }
}

/// The controlword to send to a drive in `state` that should reach (or stay in) `target`:
/// one transition's command, the target's own command once there, fault reset (0x80) in
/// Fault, disable voltage (0x00) in Quick stop active and while the drive is in a state it
/// leaves by itself. Bit 7 must have been low before for the fault reset to act; see
/// [`PowerSequencer`].
pub fn next_controlword(state: PowerState, target: Target) -> u16 {
    let rung = match state {
        PowerState::Fault => return Command::FaultReset.word(),
        PowerState::NotReadyToSwitchOn
        | PowerState::FaultReactionActive
        | PowerState::QuickStopActive => return Command::DisableVoltage.word(),
        PowerState::SwitchOnDisabled => Target::SwitchOnDisabled,
        PowerState::ReadyToSwitchOn => Target::ReadyToSwitchOn,
        PowerState::SwitchedOn => Target::SwitchedOn,
        PowerState::OperationEnabled => Target::OperationEnabled,
    };
    let ladder = [
        Target::SwitchOnDisabled,
        Target::ReadyToSwitchOn,
        Target::SwitchedOn,
        Target::OperationEnabled,
    ];
    // Up one rung at a time; down (5, 6, 7, 8, 9, 10) in one transition.
    let step = if rung.rung() < target.rung() {
        ladder[usize::from(rung.rung()) + 1]
    } else {
        target
    };
    step.hold().word()
}

/// Walks one drive to a target, one statusword at a time, making fault resets edges.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PowerSequencer {
    target: Target,
    last: u16,
}

impl PowerSequencer {
    /// A sequencer that has sent nothing yet (as if 0x0000 had been sent).
    pub fn new(target: Target) -> PowerSequencer {
        PowerSequencer { target, last: 0 }
    }

    /// Changes the target.
    pub fn set_target(&mut self, target: Target) {
        self.target = target;
    }

    /// Whether the drive in `statusword` is where it should be.
    pub fn reached(&self, statusword: u16) -> bool {
        let state = PowerState::from_statusword(statusword);
        let wanted = match self.target {
            Target::SwitchOnDisabled => PowerState::SwitchOnDisabled,
            Target::ReadyToSwitchOn => PowerState::ReadyToSwitchOn,
            Target::SwitchedOn => PowerState::SwitchedOn,
            Target::OperationEnabled => PowerState::OperationEnabled,
        };
        state == Ok(wanted)
    }

    /// The controlword to send now, given the drive's latest statusword. In Fault it
    /// alternates 0x80 and 0x00 while the fault stays, so every other word is an edge.
    pub fn controlword(&mut self, statusword: u16) -> Result<u16, UnknownStatusword> {
        let state = PowerState::from_statusword(statusword)?;
        let mut word = next_controlword(state, self.target);
        if word & FAULT_RESET_BIT != 0 && self.last & FAULT_RESET_BIT != 0 {
            word &= !FAULT_RESET_BIT;
        }
        self.last = word;
        Ok(word)
    }
}

/// Modes of operation (6060h) and their display (6061h).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// 1: profile position.
    ProfilePosition,
    /// 2: velocity (frequency-converter style).
    Velocity,
    /// 3: profile velocity.
    ProfileVelocity,
    /// 4: profile torque.
    ProfileTorque,
    /// 6: homing.
    Homing,
    /// 7: interpolated position (set-points in 60C1h).
    InterpolatedPosition,
    /// 8: cyclic synchronous position (set-points in 607Ah every SYNC).
    CyclicSynchronousPosition,
    /// 9: cyclic synchronous velocity.
    CyclicSynchronousVelocity,
    /// 10: cyclic synchronous torque.
    CyclicSynchronousTorque,
}

impl Mode {
    /// The INTEGER8 value of 6060h.
    pub fn value(self) -> i8 {
        match self {
            Mode::ProfilePosition => 1,
            Mode::Velocity => 2,
            Mode::ProfileVelocity => 3,
            Mode::ProfileTorque => 4,
            Mode::Homing => 6,
            Mode::InterpolatedPosition => 7,
            Mode::CyclicSynchronousPosition => 8,
            Mode::CyclicSynchronousVelocity => 9,
            Mode::CyclicSynchronousTorque => 10,
        }
    }

    /// The mode a 6061h value shows; `None` for 0 (no mode), reserved and
    /// manufacturer-specific (negative) values.
    pub fn from_value(value: i8) -> Option<Mode> {
        Some(match value {
            1 => Mode::ProfilePosition,
            2 => Mode::Velocity,
            3 => Mode::ProfileVelocity,
            4 => Mode::ProfileTorque,
            6 => Mode::Homing,
            7 => Mode::InterpolatedPosition,
            8 => Mode::CyclicSynchronousPosition,
            9 => Mode::CyclicSynchronousVelocity,
            10 => Mode::CyclicSynchronousTorque,
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests;
