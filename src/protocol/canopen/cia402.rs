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
    if value == 0 || period.subsec_nanos() % 1000 != 0 {
        return None;
    }
    let mut index = -6i8;
    while value > 255 {
        if value % 10 != 0 || index == 0 {
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
mod tests {
    use super::*;
    use std::time::Duration;
    use PowerState::*;

    #[test]
    fn cycle_periods_are_written_as_60c2h_value_and_power_of_ten() {
        let us = Duration::from_micros;
        // 4 ms = 40 × 10⁻⁴ s; 1 ms = 100 × 10⁻⁵ s; 250 µs as is; 2.5 ms = 250 × 10⁻⁵ s.
        assert_eq!(interpolation_time_period(us(4000)), Some((40, -4)));
        assert_eq!(interpolation_time_period(us(1000)), Some((100, -5)));
        assert_eq!(interpolation_time_period(us(250)), Some((250, -6)));
        assert_eq!(interpolation_time_period(us(2500)), Some((250, -5)));
        assert_eq!(
            interpolation_time_period(Duration::from_secs(100)),
            Some((100, 0))
        );
        // Significant digits beyond 255, sub-microseconds, zero, beyond 255 s: not exact.
        assert_eq!(interpolation_time_period(us(2560)), None);
        assert_eq!(
            interpolation_time_period(Duration::from_nanos(4_000_500)),
            None
        );
        assert_eq!(interpolation_time_period(Duration::ZERO), None);
        assert_eq!(interpolation_time_period(Duration::from_secs(1000)), None);
    }

    #[test]
    fn statuswords_decode_by_the_standard_masks() {
        // Typical words: remote (bit 9) and voltage enabled (bit 4) set, as drives report.
        let table = [
            (0x0000, NotReadyToSwitchOn),
            (0x0250, SwitchOnDisabled),
            (0x0231, ReadyToSwitchOn),
            (0x0233, SwitchedOn),
            (0x1637, OperationEnabled),
            (0x0217, QuickStopActive),
            (0x021F, FaultReactionActive),
            (0x2218, Fault),
            (0x0208, Fault),
        ];
        for (word, state) in table {
            assert_eq!(PowerState::from_statusword(word), Ok(state), "{word:04X}");
        }
        // Don't-care bits do not matter: bit 5 in Switch on disabled and Fault,
        // everything above bit 6.
        assert_eq!(PowerState::from_statusword(0xFFF0), Ok(SwitchOnDisabled));
        assert_eq!(PowerState::from_statusword(0x0028), Ok(Fault));
    }

    #[test]
    fn words_matching_no_pattern_are_refused() {
        // Ready to switch on without quick stop (bit 5); fault with bit 6; bit 1 alone.
        for word in [0x0001, 0x0048, 0x0002, 0x0063] {
            assert_eq!(
                PowerState::from_statusword(word),
                Err(UnknownStatusword(word))
            );
        }
        assert_eq!(
            UnknownStatusword(0x48).to_string(),
            "statusword 0x0048 matches no CiA 402 state"
        );
    }

    #[test]
    fn statusword_bits() {
        let word = Statusword(0x3EB7);
        assert_eq!(word.state(), Ok(OperationEnabled));
        assert!(word.voltage_enabled());
        assert!(word.warning());
        assert!(word.remote());
        assert!(word.target_reached());
        assert!(word.internal_limit());
        assert!(word.following_target());
        assert!(word.following_error());
        let plain = Statusword(0x0027);
        assert!(!plain.voltage_enabled() && !plain.warning() && !plain.remote());
        assert!(!plain.target_reached() && !plain.internal_limit());
        assert!(!plain.following_target() && !plain.following_error());
        // The same bit 12 in interpolated position mode.
        assert!(word.ip_mode_active() && Statusword(0x1237).ip_mode_active());
        assert!(!plain.ip_mode_active());
    }

    #[test]
    fn commands_are_the_profiles_words() {
        assert_eq!(Command::Shutdown.word(), 0x06);
        assert_eq!(Command::SwitchOn.word(), 0x07);
        assert_eq!(Command::EnableOperation.word(), 0x0F);
        assert_eq!(Command::DisableOperation.word(), 0x07);
        assert_eq!(Command::DisableVoltage.word(), 0x00);
        assert_eq!(Command::QuickStop.word(), 0x02);
        assert_eq!(Command::FaultReset.word(), 0x80);
        // Enable ip mode is bit 4, outside every command's bits.
        assert_eq!(ENABLE_IP_MODE, 1 << 4);
        for command in [
            Command::Shutdown,
            Command::SwitchOn,
            Command::EnableOperation,
            Command::DisableVoltage,
            Command::QuickStop,
            Command::FaultReset,
        ] {
            assert_eq!(command.word() & ENABLE_IP_MODE, 0, "{command:?}");
        }
    }

    /// The transitions of CiA 402's state diagram that commands cause, as (from, word, to).
    fn transition(state: PowerState, word: u16) -> PowerState {
        let fault_reset = word & 0x80 != 0;
        let (so, ev, qs, eo) = (word & 1 != 0, word & 2 != 0, word & 4 != 0, word & 8 != 0);
        let shutdown = ev && qs && !so;
        let disable_voltage = !ev;
        let quick_stop = ev && !qs;
        match state {
            Fault if fault_reset => SwitchOnDisabled,
            _ if fault_reset => state,
            SwitchOnDisabled if shutdown => ReadyToSwitchOn,
            ReadyToSwitchOn if so && ev && qs => SwitchedOn,
            ReadyToSwitchOn if disable_voltage || quick_stop => SwitchOnDisabled,
            SwitchedOn if so && ev && qs && eo => OperationEnabled,
            SwitchedOn if shutdown => ReadyToSwitchOn,
            SwitchedOn if disable_voltage || quick_stop => SwitchOnDisabled,
            OperationEnabled if so && ev && qs && !eo => SwitchedOn,
            OperationEnabled if shutdown => ReadyToSwitchOn,
            OperationEnabled if disable_voltage => SwitchOnDisabled,
            OperationEnabled if quick_stop => QuickStopActive,
            QuickStopActive if disable_voltage => SwitchOnDisabled,
            _ => state,
        }
    }

    #[test]
    fn every_state_walks_to_every_target() {
        let targets = [
            (Target::SwitchOnDisabled, SwitchOnDisabled),
            (Target::ReadyToSwitchOn, ReadyToSwitchOn),
            (Target::SwitchedOn, SwitchedOn),
            (Target::OperationEnabled, OperationEnabled),
        ];
        let starts = [
            SwitchOnDisabled,
            ReadyToSwitchOn,
            SwitchedOn,
            OperationEnabled,
            QuickStopActive,
            Fault,
        ];
        for (target, wanted) in targets {
            for start in starts {
                let mut state = start;
                let mut steps = 0;
                while state != wanted {
                    state = transition(state, next_controlword(state, target));
                    steps += 1;
                    assert!(steps <= 5, "{start:?} → {target:?} stuck at {state:?}");
                }
                // Once there, the word holds the state.
                assert_eq!(transition(state, next_controlword(state, target)), wanted);
            }
        }
    }

    #[test]
    fn the_walk_up_is_one_transition_a_command() {
        let target = Target::OperationEnabled;
        assert_eq!(next_controlword(SwitchOnDisabled, target), 0x06); // 2
        assert_eq!(next_controlword(ReadyToSwitchOn, target), 0x07); // 3
        assert_eq!(next_controlword(SwitchedOn, target), 0x0F); // 4
        assert_eq!(next_controlword(OperationEnabled, target), 0x0F);
        assert_eq!(next_controlword(QuickStopActive, target), 0x00); // 12
        assert_eq!(next_controlword(Fault, target), 0x80); // 15
                                                           // States the drive leaves by itself get a harmless word with bit 7 low.
        assert_eq!(next_controlword(NotReadyToSwitchOn, target), 0x00);
        assert_eq!(next_controlword(FaultReactionActive, target), 0x00);
        // Down in one transition each: 5, 8, 9.
        assert_eq!(next_controlword(OperationEnabled, Target::SwitchedOn), 0x07);
        assert_eq!(
            next_controlword(OperationEnabled, Target::ReadyToSwitchOn),
            0x06
        );
        assert_eq!(
            next_controlword(OperationEnabled, Target::SwitchOnDisabled),
            0x00
        );
    }

    #[test]
    fn a_lasting_fault_gets_a_fresh_edge_every_other_word() {
        let mut sequencer = PowerSequencer::new(Target::OperationEnabled);
        let fault = 0x0218;
        let words: Vec<u16> = (0..4)
            .map(|_| sequencer.controlword(fault).unwrap())
            .collect();
        assert_eq!(words, [0x80, 0x00, 0x80, 0x00]);
        // After the reset the walk goes on with bit 7 low.
        assert_eq!(sequencer.controlword(0x0250), Ok(0x06));
        assert!(!sequencer.reached(0x0250));
        assert_eq!(sequencer.controlword(0x0231), Ok(0x07));
        assert_eq!(sequencer.controlword(0x0233), Ok(0x0F));
        assert!(sequencer.reached(0x1237));
        sequencer.set_target(Target::SwitchOnDisabled);
        assert!(!sequencer.reached(0x1237));
        assert_eq!(sequencer.controlword(0x1237), Ok(0x00));
        assert_eq!(
            sequencer.controlword(0x0001),
            Err(UnknownStatusword(0x0001))
        );
    }

    #[test]
    fn a_fault_straight_after_a_reset_word_waits_one_word() {
        // The last word had bit 7 high (a fault reset that did not clear the fault):
        // the next must drop it before another edge can happen.
        let mut sequencer = PowerSequencer::new(Target::SwitchedOn);
        assert_eq!(sequencer.controlword(0x0008), Ok(0x80));
        assert_eq!(sequencer.controlword(0x000F), Ok(0x00)); // fault reaction: wait
        assert_eq!(sequencer.controlword(0x0008), Ok(0x80));
    }

    #[test]
    fn modes_of_operation_values() {
        assert_eq!(Mode::CyclicSynchronousPosition.value(), 8);
        assert_eq!(Mode::InterpolatedPosition.value(), 7);
        assert_eq!(Mode::ProfilePosition.value(), 1);
        assert_eq!(Mode::CyclicSynchronousTorque.value(), 10);
        for value in [1, 2, 3, 4, 6, 7, 8, 9, 10] {
            assert_eq!(Mode::from_value(value).unwrap().value(), value);
        }
        for value in [0, 5, 11, -1] {
            assert_eq!(Mode::from_value(value), None);
        }
    }

    #[test]
    fn object_indices() {
        use object::*;
        assert_eq!((CONTROLWORD, STATUSWORD), (0x6040, 0x6041));
        assert_eq!(
            (MODES_OF_OPERATION, MODES_OF_OPERATION_DISPLAY),
            (0x6060, 0x6061)
        );
        assert_eq!((TARGET_POSITION, POSITION_ACTUAL), (0x607A, 0x6064));
        assert_eq!(
            (FOLLOWING_ERROR_WINDOW, INTERPOLATION_DATA),
            (0x6065, 0x60C1)
        );
        assert_eq!((PRODUCER_HEARTBEAT, CONSUMER_HEARTBEAT), (0x1017, 0x1016));
        assert_eq!((DEVICE_TYPE, ERROR_REGISTER), (0x1000, 0x1001));
        assert_eq!(EMCY_FOLLOWING_ERROR, 0x8611);
    }
}
