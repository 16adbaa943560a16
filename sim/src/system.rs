//! `$` system commands: which one a line is (grbl's `system_execute_line`).
//!
//! The controller decides what each does in which state; this module only reads the line,
//! with spaces removed and letters upper-cased as grblHAL does.

/// A `$` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystemCommand {
    /// `$`, `$HLP`: the help line.
    Help,
    /// `$$`: all settings.
    Settings,
    /// `$n`: one setting.
    Setting(u16),
    /// `$n=value`: write a setting (the simulator's settings come from the machine
    /// profile and are read-only).
    SetSetting,
    /// `$G`: parser state.
    ParserState,
    /// `$#`: offsets and stored positions.
    Parameters,
    /// `$I`: build info.
    BuildInfo,
    /// `$N`: start-up lines (always empty here).
    StartupLines,
    /// `$C`: check-mode toggle.
    CheckMode,
    /// `$X`: alarm unlock.
    Unlock,
    /// `$H` and its single-axis forms: homing (the simulated machine has no switches).
    Home,
    /// Anything else (`$J=`, `$SLP`, `$RST=`, `$I=…`, `$N0=…`, unknown letters).
    Unsupported,
}

impl SystemCommand {
    /// Reads a line that starts with `$`.
    pub fn parse(line: &str) -> SystemCommand {
        let text: String = line
            .chars()
            .filter(|c| *c != ' ')
            .map(|c| c.to_ascii_uppercase())
            .collect();
        let rest = text.strip_prefix('$').unwrap_or(&text);
        match rest {
            "" | "HLP" | "HELP" => SystemCommand::Help,
            "$" => SystemCommand::Settings,
            "G" => SystemCommand::ParserState,
            "#" => SystemCommand::Parameters,
            "I" => SystemCommand::BuildInfo,
            "N" => SystemCommand::StartupLines,
            "C" => SystemCommand::CheckMode,
            "X" => SystemCommand::Unlock,
            _ if rest.starts_with('H') && rest.len() <= 2 => SystemCommand::Home,
            _ => {
                let (number, value) = match rest.split_once('=') {
                    Some((n, _)) => (n, true),
                    None => (rest, false),
                };
                match (number.parse::<u16>(), value) {
                    (Ok(_), true) if number.bytes().all(|b| b.is_ascii_digit()) => {
                        SystemCommand::SetSetting
                    }
                    (Ok(n), false) if number.bytes().all(|b| b.is_ascii_digit()) => {
                        SystemCommand::Setting(n)
                    }
                    _ => SystemCommand::Unsupported,
                }
            }
        }
    }

    /// Whether grblHAL runs it during a critical alarm (before the reset it demands);
    /// the others answer `error:79`. Reports are allowed, anything that changes state not.
    pub fn allowed_during_critical(self) -> bool {
        matches!(
            self,
            SystemCommand::Help
                | SystemCommand::Settings
                | SystemCommand::Setting(_)
                | SystemCommand::ParserState
                | SystemCommand::Parameters
                | SystemCommand::BuildInfo
                | SystemCommand::StartupLines
        )
    }
}

#[cfg(test)]
mod tests {
    use super::SystemCommand::{self, *};

    #[test]
    fn reads_commands() {
        let cases = [
            ("$", Help),
            ("$$", Settings),
            ("$ c ", CheckMode),
            ("$x", Unlock),
            ("$H", Home),
            ("$HZ", Home),
            ("$I", BuildInfo),
            ("$110", Setting(110)),
            ("$110=500", SetSetting),
            ("$J=G91 X1 F100", Unsupported),
            ("$SLP", Unsupported),
            ("$I=hello", Unsupported),
            ("$-1", Unsupported),
            ("$99999", Unsupported),
        ];
        for (line, expected) in cases {
            assert_eq!(SystemCommand::parse(line), expected, "{line}");
        }
        assert!(!Unlock.allowed_during_critical() && Settings.allowed_during_critical());
    }
}
