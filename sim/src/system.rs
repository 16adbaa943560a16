//! `$` system commands: which one a line is (grblHAL's `system_execute_line`, `system.c`).
//!
//! The controller decides what each does in which state; this module only reads the line
//! as grblHAL does: up to the first `=`, spaces are removed and letters upper-cased; the
//! rest is kept as sent. A line that names no command is a setting (`$n`, `$n=value`) if
//! it starts with a whole number of zero or more, else `error:3`.

/// A `$` command.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SystemCommand {
    /// `$`: the help line.
    Help,
    /// `$HELP`: the help topics.
    HelpTopics,
    /// `$$`: all settings.
    Settings,
    /// `$n`: one setting.
    Setting(u16),
    /// `$n=value`: write a setting; the text after `=`.
    SetSetting(u16, String),
    /// `$G`: parser state.
    ParserState,
    /// `$#`: offsets and stored positions.
    Parameters,
    /// `$I`: build info.
    BuildInfo,
    /// `$I=text`: set the build info string.
    SetBuildInfo(String),
    /// `$N`: start-up lines (always empty here).
    StartupLines,
    /// `$C`: check-mode toggle.
    CheckMode,
    /// `$X`: alarm unlock.
    Unlock,
    /// `$H` and its single-axis forms: homing (the simulated machine has no switches).
    Home,
    /// `$J=…`: a jog; the G-code after `=`.
    Jog(String),
    /// `$EA`: alarm codes.
    AlarmCodes,
    /// `$EE`: error codes.
    ErrorCodes,
    /// `$EG`: setting groups.
    SettingGroups,
    /// `$ES`: setting details.
    SettingDetails,
    /// `$SED=n`: a setting's description.
    SettingDescription(String),
    /// A command grblHAL has that the simulator does not (`$SLP`, `$RST=`, `$N0=`, `$HELP
    /// topic`, …), or none at all: `error:3`.
    Unsupported,
}

impl SystemCommand {
    /// Reads a line that starts with `$`.
    pub fn parse(line: &str) -> SystemCommand {
        let rest = line.strip_prefix('$').unwrap_or(line);
        let (name, args) = match rest.split_once('=') {
            Some((name, args)) => (name, Some(args.to_owned())),
            None => (rest, None),
        };
        let name: String = name
            .chars()
            .filter(|c| *c != ' ')
            .map(|c| c.to_ascii_uppercase())
            .collect();
        if name.starts_with("HELP") {
            // `$HELP` alone lists the topics; a topic's own help is not reproduced.
            return if name == "HELP" && args.is_none() {
                SystemCommand::HelpTopics
            } else {
                SystemCommand::Unsupported
            };
        }
        match (name.as_str(), args) {
            ("", None) => SystemCommand::Help,
            ("$", None) => SystemCommand::Settings,
            ("G", None) => SystemCommand::ParserState,
            ("#", None) => SystemCommand::Parameters,
            ("I", None) => SystemCommand::BuildInfo,
            ("I", Some(text)) => SystemCommand::SetBuildInfo(text),
            ("N", None) => SystemCommand::StartupLines,
            ("C", None) => SystemCommand::CheckMode,
            ("X", _) => SystemCommand::Unlock,
            ("J", Some(text)) => SystemCommand::Jog(text),
            ("EA", None) => SystemCommand::AlarmCodes,
            ("EE", None) => SystemCommand::ErrorCodes,
            ("EG", None) => SystemCommand::SettingGroups,
            ("ES", None) => SystemCommand::SettingDetails,
            ("SED", Some(text)) => SystemCommand::SettingDescription(text),
            ("H" | "HX" | "HY" | "HZ" | "HC", _) => SystemCommand::Home,
            (name, args) => match (setting_number(name), args) {
                (Some(id), None) => SystemCommand::Setting(id),
                (Some(id), Some(value)) => SystemCommand::SetSetting(id, value),
                (None, _) => SystemCommand::Unsupported,
            },
        }
    }

    /// Whether grblHAL runs it during a critical alarm, before the reset it demands (its
    /// command table's `allow_blocking`; settings are read and written by the fallback
    /// that no flag blocks); the others answer `error:79`.
    pub fn allowed_during_critical(&self) -> bool {
        !matches!(
            self,
            SystemCommand::CheckMode
                | SystemCommand::Unlock
                | SystemCommand::Home
                | SystemCommand::Jog(_)
        )
    }
}

/// A setting's number as grblHAL's fallback reads it (`read_float` of the name, at least
/// 0 and whole), if it is one.
fn setting_number(name: &str) -> Option<u16> {
    let mut at = 0;
    let value = crate::interpreter::read_float(name.as_bytes(), &mut at)?;
    (value >= 0.0 && value.fract() == 0.0).then(|| value.min(f64::from(u16::MAX)) as u16)
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
            ("$I=my lathe", SetBuildInfo("my lathe".into())),
            ("$110", Setting(110)),
            ("$110=500", SetSetting(110, "500".into())),
            ("$1 10 = 5", SetSetting(110, " 5".into())),
            ("$J=G91 x1 F100", Jog("G91 x1 F100".into())),
            ("$j=X1", Jog("X1".into())),
            ("$HELP", HelpTopics),
            ("$ES", SettingDetails),
            ("$SED=110", SettingDescription("110".into())),
            // Not grblHAL's commands, or not the simulator's.
            ("$HLP", Unsupported),
            ("$HELP Commands", Unsupported),
            ("$J", Unsupported),
            ("$SLP", Unsupported),
            ("$N0=G21", Unsupported),
            ("$-1", Unsupported),
            ("$1.5", Unsupported),
        ];
        for (line, expected) in cases {
            assert_eq!(SystemCommand::parse(line), expected, "{line}");
        }
        assert!(!Unlock.allowed_during_critical() && Settings.allowed_during_critical());
        assert!(SetSetting(10, "0".into()).allowed_during_critical());
    }
}
