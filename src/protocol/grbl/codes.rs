//! What grbl's numbered `error:N` and `ALARM:N` responses mean.
//!
//! grbl 1.1 reports bare numbers to save flash and publishes their meaning in its
//! documentation (`doc/csv/error_codes_en_US.csv`, `alarm_codes_en_US.csv`); grblHAL
//! keeps grbl's numbers and adds codes above them (its `errors.h` / `alarms.h`). The texts
//! here give each code's documented meaning, short enough for one log line. A code
//! outside the tables (a plugin's own, or a newer firmware's) gets a generic text rather
//! than a failure, because the number itself is what the log must keep.

/// The meaning of grbl's `error:code`; codes 1–38 are grbl 1.1's, the rest grblHAL's.
pub fn error_message(code: u16) -> &'static str {
    match code {
        1 => "G-code word without a letter (expected a command letter)",
        2 => "bad or missing number in a G-code word",
        3 => "'$' system command not recognised or not supported",
        4 => "negative value where a positive one is expected",
        5 => "homing is not enabled in the settings",
        6 => "step pulse time below the minimum",
        7 => "settings read failed; the affected settings were restored to defaults",
        8 => "'$' command refused: the controller is not idle",
        9 => "G-code locked out during alarm or jog state",
        10 => "soft limits need homing to be enabled",
        11 => "line too long for the controller's line buffer; the line was not executed",
        12 => "'$' setting value exceeds the maximum step rate",
        13 => "safety door open",
        14 => "build info or startup line too long; not stored",
        15 => "jog target exceeds machine travel; jog ignored",
        16 => "invalid jog command (no '=' or prohibited G-code)",
        17 => "laser mode needs PWM output",
        18 => "reset asserted",
        19 => "value must be positive",
        20 => "unsupported or invalid G-code command in the block",
        21 => "two G-code commands of the same modal group in the block",
        22 => "feed rate not set or undefined",
        23 => "G-code command needs an integer value",
        24 => "two G-code commands in the block both need the axis words",
        25 => "G-code word repeated in the block",
        26 => "no axis words in the block, but the command or modal state needs them",
        27 => "invalid line number (N word)",
        28 => "G-code command is missing a required value word",
        29 => "G59.x work coordinate systems are not supported",
        30 => "G53 needs G0 or G1 motion mode",
        31 => "axis words in the block that no command or modal state uses",
        32 => "G2/G3 arc without an axis word in the selected plane",
        33 => "invalid motion target",
        34 => "invalid arc radius",
        35 => "G2/G3 arc without an offset word in the selected plane",
        36 => "unused value words in the block",
        37 => "G43.1 dynamic tool length offset on an axis other than the tool length axis",
        38 => "tool number out of range or undefined tool",
        39 => "value out of range",
        40 => "G-code command not allowed while a tool change is pending",
        41 => "spindle not running for a spindle-synchronised or CSS motion",
        42 => "threading needs the ZX plane",
        43 => "maximum feed rate exceeded",
        44 => "spindle speed out of range",
        45 => "only homing is allowed while a limit switch is engaged",
        46 => "homing required",
        47 => "tool change: the current tool is not set",
        48 => "value word conflict",
        49 => "power-on self test failed",
        50 => "emergency stop active",
        51 => "motor fault",
        52 => "setting value out of range",
        53 => "setting not available",
        54 => "retract position below drill depth",
        55 => "cannot home two auto-squared axes at the same time",
        56 => "coordinate system locked",
        57 => "unexpected file demarcation",
        58 => "port not available",
        60 => "SD card mount failed",
        61 => "file read error",
        62 => "failed to open directory",
        63 => "directory not found",
        64 => "SD card not mounted",
        65 => "file system not mounted",
        66 => "file system is read-only",
        70 => "Bluetooth initialisation failed",
        71 => "unknown operation in expression",
        72 => "division by zero in expression",
        73 => "expression argument out of range",
        74 => "invalid expression argument",
        75 => "expression syntax error",
        76 => "expression result is not a finite number",
        77 => "authentication required",
        78 => "access denied",
        79 => "not allowed while a critical event is active",
        80 => "flow statement only allowed in a file macro",
        81 => "unknown flow statement",
        82 => "flow statement stack overflow",
        83 => "out of memory in flow statement",
        84 => "could not open file",
        253 => "user-defined error",
        _ => "unknown error code (not in grbl's or grblHAL's table)",
    }
}

/// The meaning of grbl's `ALARM:code`; codes 1–9 are grbl 1.1's, 10–18 grblHAL's, 64
/// whirl-sim's own.
pub fn alarm_message(code: u16) -> &'static str {
    match code {
        1 => "hard limit triggered; machine position likely lost, re-homing recommended",
        2 => "soft limit: motion target exceeds machine travel; machine position retained",
        3 => "reset while in motion; machine position likely lost, re-homing recommended",
        4 => "probe fail: probe not in the expected initial state",
        5 => "probe fail: no contact within the programmed travel",
        6 => "homing fail: the homing cycle was reset",
        7 => "homing fail: safety door opened during homing",
        8 => "homing fail: pull-off did not clear the limit switch",
        9 => "homing fail: limit switch not found within the search distance",
        10 => "emergency stop asserted",
        11 => "homing required",
        12 => "limit switch engaged",
        13 => "probe protection triggered",
        14 => "spindle at-speed timeout",
        15 => "homing fail: second switch of an auto-squared axis not found",
        16 => "power-on self test failed",
        17 => "motor fault",
        18 => "homing fail: bad configuration",
        64 => "profile error beyond the allowable error Δ (whirl-sim's Δ guard); motion stopped",
        _ => "unknown alarm code (not in grbl's or grblHAL's table)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn documented_codes_have_their_meaning_and_unknown_codes_a_generic_text() {
        assert!(error_message(20).contains("unsupported"));
        assert!(error_message(22).contains("feed rate"));
        assert!(error_message(9).contains("alarm"));
        assert!(error_message(0).starts_with("unknown"));
        assert!(error_message(200).starts_with("unknown"));
        assert!(alarm_message(2).contains("soft limit"));
        assert!(alarm_message(0).starts_with("unknown"));
        // Every code of grbl 1.1's tables is known.
        for code in (1..=17).chain(20..=38) {
            assert!(!error_message(code).starts_with("unknown"), "error {code}");
        }
        for code in 1..=9 {
            assert!(!alarm_message(code).starts_with("unknown"), "alarm {code}");
        }
    }
}
