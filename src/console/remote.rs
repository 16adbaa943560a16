//! The shop overview's Hold, as a bridge takes it: a command from the broker
//! ([`crate::telemetry::message::Command`]) holds the machine's run only if it carries this
//! console's own token (`whirl serve --token`, the shop's token, which the overview is
//! given too). A console without a token takes no remote command: it is reachable from
//! its own host alone, and so is its Hold. Every command taken or refused is said on
//! standard error with who sent it; a hold taken is noted in the run's record as the
//! console's own button is.

use std::sync::Arc;

use super::runner::Console;
use super::token::Token;
use crate::records::NoteKind;
use crate::telemetry::message::Command;
use crate::transport;

/// Why a remote command was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    /// Not a command a bridge takes.
    #[error("\"{0}\" is no command a bridge takes (only hold)")]
    Unknown(String),
    /// This console has no token to check it against.
    #[error("this console has no token (--token), so it takes no remote command")]
    NoToken,
    /// The token is not this console's.
    #[error("its token is not this console's")]
    WrongToken,
    /// The machine runs nothing to hold.
    #[error("{0}")]
    NotRunning(String),
}

/// Takes `command` for `machine`: holds its run if the command is a hold with the token.
pub fn take(
    console: &Console,
    token: Option<&Token>,
    machine: &str,
    command: &Command,
) -> Result<(), Refused> {
    if command.command != "hold" {
        return Err(Refused::Unknown(command.command.clone()));
    }
    let token = token.ok_or(Refused::NoToken)?;
    if !token.matches(&command.token) {
        return Err(Refused::WrongToken);
    }
    console
        .registry
        .press(machine, transport::Command::Hold)
        .map_err(|e| Refused::NotRunning(e.to_string()))
}

/// Has every machine's telemetry hand its commands to [`take`]; a hold taken is noted on
/// `runtime` (the records are async), as the console's button notes it.
pub fn take_commands(
    console: &Arc<Console>,
    token: Option<Token>,
    runtime: tokio::runtime::Handle,
) {
    for (machine, telemetry) in &console.telemetry {
        let (console, token, runtime) = (Arc::clone(console), token.clone(), runtime.clone());
        let machine = machine.clone();
        telemetry.on_command(move |command| {
            match take(&console, token.as_ref(), &machine, &command) {
                Ok(()) => {
                    tracing::warn!("{machine}: held by the shop overview ({})", command.by);
                    let (console, machine) = (Arc::clone(&console), machine.clone());
                    let by = format!("the shop overview ({})", command.by);
                    runtime.spawn(async move {
                        let _ = console.note_pressed(&machine, NoteKind::Hold, &by).await;
                    });
                }
                Err(refused) => tracing::warn!(
                    "{machine}: a remote {} from {} refused: {refused}",
                    command.command,
                    command.by
                ),
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::machine::MachineProfile;
    use crate::console::paths::JobDir;

    fn console() -> Console {
        let machine = MachineProfile::builtin_sim().unwrap();
        let jobs = JobDir::open(std::path::Path::new(env!("CARGO_MANIFEST_DIR"))).unwrap();
        Console::new([(machine.name.clone(), machine)].into(), jobs)
    }

    fn command(word: &str, token: &str) -> Command {
        Command {
            command: word.into(),
            token: token.into(),
            by: "127.0.0.1:4711".into(),
        }
    }

    #[test]
    fn a_remote_hold_needs_this_consoles_token_and_a_run() {
        let console = console();
        let machine = console.machines.keys().next().unwrap().clone();
        let token = Token::new("shop-floor-token-0123").unwrap();
        let take = |token: Option<&Token>, c: Command| take(&console, token, &machine, &c);
        assert_eq!(
            take(Some(&token), command("start", "shop-floor-token-0123")),
            Err(Refused::Unknown("start".into()))
        );
        assert_eq!(
            take(None, command("hold", "shop-floor-token-0123")),
            Err(Refused::NoToken)
        );
        assert_eq!(
            take(Some(&token), command("hold", "shop-floor-token-0124")),
            Err(Refused::WrongToken)
        );
        assert!(matches!(
            take(Some(&token), command("hold", "shop-floor-token-0123")),
            Err(Refused::NotRunning(_))
        ));
    }
}
