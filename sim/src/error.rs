//! The controller's numbered answers (`error:N`, `ALARM:N`) and the simulator's own errors.
//!
//! The numbers are grbl's (`doc/markdown/interface.md` of gnea/grbl, "Grbl Response
//! Messages" and "Alarm Message"), which grblHAL keeps (`errors.h`, `alarms.h` of
//! grblHAL/core) and extends; 79 is a grblHAL extension. Only the codes the simulator can
//! produce are listed, so a sender's error table is a superset of this one.

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
    #[error("'$' command cannot be used unless controller state is IDLE.")]
    IdleError,
    /// 9: G-code while in alarm.
    #[error("G-code commands are locked out during alarm or jog state.")]
    SystemGcLock,
    /// 11: a line longer than the line buffer (or, in the simulator, damaged by an RX overflow).
    #[error("Max characters per line exceeded. Received command line was not executed.")]
    Overflow,
    /// 15: a target outside the machine's travel.
    #[error("Target exceeds machine travel. Command ignored.")]
    TravelExceeded,
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
    /// 31: axis words with motion cancelled (G80).
    #[error("Axis words found in block when no command or current modal state uses them.")]
    AxisWordsExist,
    /// 33: a target the controller cannot represent (not finite in its number type).
    #[error("Motion command target is invalid.")]
    InvalidTarget,
    /// 36: a value word no command on the line uses (P without G4).
    #[error("Unused value words found in block.")]
    UnusedWords,
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
            GrblError::Overflow => 11,
            GrblError::TravelExceeded => 15,
            GrblError::UnsupportedCommand => 20,
            GrblError::ModalGroupViolation => 21,
            GrblError::UndefinedFeedRate => 22,
            GrblError::CommandValueNotInteger => 23,
            GrblError::AxisCommandConflict => 24,
            GrblError::WordRepeated => 25,
            GrblError::NoAxisWords => 26,
            GrblError::InvalidLineNumber => 27,
            GrblError::ValueWordMissing => 28,
            GrblError::AxisWordsExist => 31,
            GrblError::InvalidTarget => 33,
            GrblError::UnusedWords => 36,
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
