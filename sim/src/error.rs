//! The controller's numbered answers (`error:N`, `ALARM:N`) and the simulator's own errors.
//!
//! The numbers are grbl's (`doc/markdown/interface.md` of gnea/grbl, "Grbl Response
//! Messages" and "Alarm Message"), which grblHAL keeps (`errors.h`, `alarms.h` of
//! grblHAL/core) and extends; 52, 53 and 79 are grblHAL's. [`GrblError`] and [`Alarm`] hold
//! only the codes the simulator can produce; [`ERROR_CODES`] and [`ALARM_CODES`] are
//! grblHAL's whole tables, as `$EE` and `$EA` list them.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A refused line: the `N` of `error:N`, with grbl's description as the message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Error, Serialize, Deserialize)]
pub enum GrblError {
    /// 1: a word did not start with a letter.
    #[error("G-code words consist of a letter and a value. Letter was not found.")]
    ExpectedCommandLetter,
    /// 2: a letter without a valid number after it.
    #[error("Missing the expected G-code word value or numeric value format is not valid.")]
    BadNumberFormat,
    /// 3: a `$` command the controller does not know (or, here, does not support).
    #[error("'$' system command was not recognized or supported.")]
    InvalidStatement,
    /// 4: a negative F, N, P or S.
    #[error("Negative value received for an expected positive value.")]
    NegativeValue,
    /// 5: `$H` on a machine without homing.
    #[error("Homing cycle failure. Homing is not configured via settings.")]
    HomingDisabled,
    /// 8: a `$` command that needs the machine idle.
    #[error("'$' command cannot be used unless controller state is IDLE. Ensures smooth operation during a job.")]
    IdleError,
    /// 9: G-code while in alarm or jogging.
    #[error("G-code commands are locked out during alarm or jog state.")]
    SystemGcLock,
    /// 10: soft limits (`$20`) or limited jogs (`$40`) without homing (`$22`).
    #[error("Soft limits cannot be enabled without homing also enabled.")]
    SoftLimitError,
    /// 11: a line longer than the line buffer (or, in the simulator, damaged by an RX overflow).
    #[error("Max characters per line exceeded. Received command line was not executed.")]
    Overflow,
    /// 15: a target outside the machine's travel (a jog's, as grblHAL uses it; in the
    /// simulator also the line that trips a soft limit).
    #[error("Jog target exceeds machine travel. Jog command has been ignored.")]
    TravelExceeded,
    /// 16: a `$J=` line with a G-code other than G20/G21, G90/G91 and G53, or any M code.
    #[error("Jog command has no '=' or contains prohibited g-code.")]
    InvalidJogCommand,
    /// 17: laser mode (`$32=1`) on a spindle that cannot be a laser.
    #[error("Laser mode requires PWM output.")]
    SettingDisabledLaser,
    /// 19: a rate or acceleration of 0 (the simulator's own use: grblHAL takes it).
    #[error("Non positive value")]
    NonPositiveValue,
    /// 20: a G or M code, or a word letter, outside the supported set.
    #[error("Unsupported or invalid g-code command found in block.")]
    UnsupportedCommand,
    /// 21: two codes of one modal group in a line.
    #[error("More than one g-code command from same modal group found in block.")]
    ModalGroupViolation,
    /// 22: a feed move with no feed rate (G94 without F so far, G93 without F on the line).
    #[error("Feed rate has not yet been set or is undefined.")]
    UndefinedFeedRate,
    /// 23: a code with a fraction where it needs a whole number (G1.5, M3.1).
    #[error("G-code command in block requires an integer value.")]
    CommandValueNotInteger,
    /// 24: two commands that both want the axis words (G0 and G1, G92 and G1).
    #[error("More than one g-code command that requires axis words found in block.")]
    AxisCommandConflict,
    /// 25: a word letter given twice.
    #[error("Repeated g-code word found in block.")]
    WordRepeated,
    /// 26: G92 without an axis word.
    #[error("No axis words found in block for g-code command or current modal state which requires them.")]
    NoAxisWords,
    /// 27: an N word above 10 000 000.
    #[error("Line number value is invalid.")]
    InvalidLineNumber,
    /// 28: G4 without P.
    #[error("G-code command is missing a required value word.")]
    ValueWordMissing,
    /// 30: G53 with a motion mode other than G0 or G1.
    #[error("G53 only allowed with G0 and G1 motion modes.")]
    G53InvalidMotionMode,
    /// 31: axis words with motion cancelled (G80).
    #[error("Axis words found in block when no command or current modal state uses them.")]
    AxisWordsExist,
    /// 33: a target the controller cannot represent (not finite in its number type).
    #[error("Motion command target is invalid.")]
    InvalidTarget,
    /// 36: a value word no command on the line uses (P without G4).
    #[error("Unused value words found in block.")]
    UnusedWords,
    /// 39 (grblHAL): a macro call (G65, G66) whose P names no macro.
    #[error("Value out of range.")]
    ValueOutOfRange,
    /// 52 (grblHAL): a setting value outside its range or format.
    #[error("Setting value is out of range.")]
    SettingValueOutOfRange,
    /// 53 (grblHAL): a setting number the controller does not have.
    #[error("Setting is not available, possibly due to limited driver support.")]
    SettingDisabled,
    /// 79 (grblHAL): a command refused until the critical alarm is cleared by a reset.
    #[error("Not allowed while critical event is active.")]
    NotAllowedCriticalEvent,
}

impl GrblError {
    /// The number the controller prints after `error:`.
    pub fn code(self) -> u8 {
        match self {
            GrblError::ExpectedCommandLetter => 1,
            GrblError::BadNumberFormat => 2,
            GrblError::InvalidStatement => 3,
            GrblError::NegativeValue => 4,
            GrblError::HomingDisabled => 5,
            GrblError::IdleError => 8,
            GrblError::SystemGcLock => 9,
            GrblError::SoftLimitError => 10,
            GrblError::Overflow => 11,
            GrblError::TravelExceeded => 15,
            GrblError::InvalidJogCommand => 16,
            GrblError::SettingDisabledLaser => 17,
            GrblError::NonPositiveValue => 19,
            GrblError::UnsupportedCommand => 20,
            GrblError::ModalGroupViolation => 21,
            GrblError::UndefinedFeedRate => 22,
            GrblError::CommandValueNotInteger => 23,
            GrblError::AxisCommandConflict => 24,
            GrblError::WordRepeated => 25,
            GrblError::NoAxisWords => 26,
            GrblError::InvalidLineNumber => 27,
            GrblError::ValueWordMissing => 28,
            GrblError::G53InvalidMotionMode => 30,
            GrblError::AxisWordsExist => 31,
            GrblError::InvalidTarget => 33,
            GrblError::UnusedWords => 36,
            GrblError::ValueOutOfRange => 39,
            GrblError::SettingValueOutOfRange => 52,
            GrblError::SettingDisabled => 53,
            GrblError::NotAllowedCriticalEvent => 79,
        }
    }
}

/// An alarm: the `N` of `ALARM:N`. The machine is locked (G-code answers `error:9`) until
/// `$X`; a critical alarm also needs a soft reset first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Error, Serialize, Deserialize)]
pub enum Alarm {
    /// 2: a motion target outside the travel (soft limit). Position is kept.
    #[error("G-code motion target exceeds machine travel. Machine position safely retained.")]
    SoftLimit,
    /// 3: soft reset while moving. grbl cannot vouch for the position (the simulator can).
    #[error("Reset while in motion. Position may be lost.")]
    AbortCycle,
    /// 64 (whirl-sim's own): the Δ guard measured the executed motion beyond the allowable
    /// profile error. Critical: the motion stopped dead, as at a hard limit.
    #[error("Profile error beyond the allowable error. Motion stopped.")]
    ProfileError,
}

impl Alarm {
    /// The number the controller prints after `ALARM:`.
    pub fn code(self) -> u8 {
        match self {
            Alarm::SoftLimit => 2,
            Alarm::AbortCycle => 3,
            Alarm::ProfileError => 64,
        }
    }

    /// Whether the alarm blocks unlocking until a soft reset (grblHAL's critical events:
    /// hard and soft limits, `[MSG:Reset to continue]`).
    pub fn is_critical(self) -> bool {
        matches!(self, Alarm::SoftLimit | Alarm::ProfileError)
    }
}

/// `$EE`: grblHAL's status codes and their descriptions, as its `errors.c` has them.
pub const ERROR_CODES: [(u8, &str); 67] = [
    (0, ""),
    (1, "G-code words consist of a letter and a value. Letter was not found."),
    (2, "Missing the expected G-code word value or numeric value format is not valid."),
    (3, "'$' system command was not recognized or supported."),
    (4, "Negative value received for an expected positive value."),
    (5, "Homing cycle failure. Homing is not configured via settings."),
    (6, "Step pulse time must be greater or equal to 2 microseconds."),
    (7, "A settings read failed. Auto-restoring affected settings to default values."),
    (8, "'$' command cannot be used unless controller state is IDLE. Ensures smooth operation during a job."),
    (9, "G-code commands are locked out during alarm or jog state."),
    (10, "Soft limits cannot be enabled without homing also enabled."),
    (11, "Max characters per line exceeded. Received command line was not executed."),
    (12, "'$' setting value cause the step rate to exceed the maximum supported."),
    (13, "Safety door detected as opened and door state initiated."),
    (14, "Build info or startup line exceeded line length limit. Line not stored."),
    (15, "Jog target exceeds machine travel. Jog command has been ignored."),
    (16, "Jog command has no '=' or contains prohibited g-code."),
    (17, "Laser mode requires PWM output."),
    (18, "Reset asserted"),
    (19, "Non positive value"),
    (20, "Unsupported or invalid g-code command found in block."),
    (21, "More than one g-code command from same modal group found in block."),
    (22, "Feed rate has not yet been set or is undefined."),
    (23, "G-code command in block requires an integer value."),
    (24, "More than one g-code command that requires axis words found in block."),
    (25, "Repeated g-code word found in block."),
    (26, "No axis words found in block for g-code command or current modal state which requires them."),
    (27, "Line number value is invalid."),
    (28, "G-code command is missing a required value word."),
    (29, "G59.x work coordinate systems are not supported."),
    (30, "G53 only allowed with G0 and G1 motion modes."),
    (31, "Axis words found in block when no command or current modal state uses them."),
    (32, "G2 and G3 arcs require at least one in-plane axis word."),
    (33, "Motion command target is invalid."),
    (34, "Arc radius value is invalid."),
    (35, "G2 and G3 arcs require at least one in-plane offset word."),
    (36, "Unused value words found in block."),
    (37, "G43.1 dynamic tool length offset is not assigned to configured tool length axis."),
    (38, "Tool number greater than max supported value or undefined tool selected."),
    (39, "Value out of range."),
    (40, "G-code command not allowed when tool change is pending."),
    (41, "Spindle not running when motion commanded in CSS or spindle sync mode."),
    (42, "Plane must be ZX for threading."),
    (43, "Max. feed rate exceeded."),
    (44, "RPM out of range."),
    (45, "Only homing is allowed when a limit switch is engaged."),
    (46, "Home machine to continue."),
    (47, "ATC: current tool is not set. Set current tool with M61."),
    (48, "Value word conflict."),
    (49, "Power on self test failed. A hard reset is required."),
    (50, "Emergency stop active."),
    (51, "Motor fault."),
    (52, "Setting value is out of range."),
    (53, "Setting is not available, possibly due to limited driver support."),
    (54, "Retract position is less than drill depth."),
    (55, "Attempt to home two auto squared axes at the same time."),
    (56, "Coordinate system is locked."),
    (57, "Unexpected file demarcation."),
    (58, "Port is not available"),
    (77, "Authentication required."),
    (78, "Access denied."),
    (79, "Not allowed while critical event is active."),
    (84, "Could not open file."),
    (86, "Port is not usable."),
    (87, "Tool in spindle."),
    (88, "No tool in spindle."),
    (253, "User defined error occured."),
];

/// `$EA`: grblHAL's alarm codes and their descriptions (`alarms.c`).
pub const ALARM_CODES: [(u8, &str); 23] = [
    (1, "Hard limit has been triggered. Machine position is likely lost due to sudden halt. Re-homing is highly recommended."),
    (2, "Soft limit alarm. G-code motion target exceeds machine travel. Machine position retained. Alarm may be safely unlocked."),
    (3, "Reset/E-stop while in motion. Machine position is likely lost due to sudden halt. Re-homing is highly recommended."),
    (4, "Probe fail. Probe is not in the expected initial state before starting probe cycle when G38.2 and G38.3 is not triggered and G38.4 and G38.5 is triggered."),
    (5, "Probe fail. Probe did not contact the workpiece within the programmed travel for G38.2 and G38.4."),
    (6, "Homing fail. The active homing cycle was reset."),
    (7, "Homing fail. Safety door was opened during homing cycle."),
    (8, "Homing fail. Pull off travel failed to clear limit switch. Try increasing pull-off setting or check wiring."),
    (9, "Homing fail. Could not find limit switch within search distances. Try increasing max travel, decreasing pull-off distance, or check wiring."),
    (10, "EStop asserted. Clear and reset"),
    (11, "Homing required. Execute homing command ($H) to continue."),
    (12, "Limit switch engaged. Clear before continuing."),
    (13, "Probe protection triggered. Clear before continuing."),
    (14, "Spindle at speed timeout. Clear before continuing."),
    (15, "Homing fail. Could not find second limit switch for auto squared axis within search distances. Try increasing max travel, decreasing pull-off distance, or check wiring."),
    (16, "Power on selftest (POS) failed."),
    (17, "Motor fault."),
    (18, "Homing fail. Bad configuration."),
    (19, "Modbus exception. Timeout or message error."),
    (20, "I/O expander communication failed."),
    (21, "Non Volatile Storage (EEPROM) failure."),
    (22, "Buffer overflow."),
    // whirl-sim's own (see [`Alarm::ProfileError`]).
    (64, "Profile error beyond the allowable error. Motion stopped."),
];

/// A controller that cannot be built from the profile and options given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// An option out of its range.
    #[error("controller option {name} = {value}: {reason}")]
    Option {
        /// The option's field name.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// The range it must be in.
        reason: &'static str,
    },
    /// A machine-profile value the simulator cannot run with (the profile's own loader
    /// refuses these too, but its fields are public).
    #[error("machine profile {key} = {value}: must be a finite number above zero")]
    Profile {
        /// The profile key, e.g. `axes.x.max_rate`.
        key: &'static str,
        /// Its value.
        value: f64,
    },
}

/// A time step the simulated clock cannot take.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
#[error("time step {0} s: simulated time only moves forward by a finite, non-negative amount")]
pub struct TimeError(pub f64);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_grbls() {
        // interface.md's table: 1, 2, 3, 9, 11, 20, 21, 22, 24, 33; ALARM 2 and 3.
        assert_eq!(GrblError::ExpectedCommandLetter.code(), 1);
        assert_eq!(GrblError::BadNumberFormat.code(), 2);
        assert_eq!(GrblError::InvalidStatement.code(), 3);
        assert_eq!(GrblError::SystemGcLock.code(), 9);
        assert_eq!(GrblError::Overflow.code(), 11);
        assert_eq!(GrblError::UnsupportedCommand.code(), 20);
        assert_eq!(GrblError::ModalGroupViolation.code(), 21);
        assert_eq!(GrblError::UndefinedFeedRate.code(), 22);
        assert_eq!(GrblError::AxisCommandConflict.code(), 24);
        assert_eq!(GrblError::InvalidTarget.code(), 33);
        assert_eq!(Alarm::SoftLimit.code(), 2);
        assert_eq!(Alarm::AbortCycle.code(), 3);
        assert!(Alarm::SoftLimit.is_critical() && !Alarm::AbortCycle.is_critical());
    }
}
