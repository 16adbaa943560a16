//! The caller's hand on a running stream: hold, resume, stop and abort, the same for every
//! transport.
//!
//! [`control`] makes a pair: a [`Control`] for whoever presses the buttons (a terminal's
//! Ctrl-C handler, a web console, a test), cheap to clone and usable from any task or
//! thread, and the [`Commands`] the run reads. Each transport says a command in its own
//! terms:
//!
//! | command | grbl / grblHAL | Modbus register map | CiA 402 drives |
//! |---|---|---|---|
//! | [`Command::Hold`] | feed hold `!` | `HOLD` edge | set-points slowed along the path to a stand |
//! | [`Command::Resume`] | cycle start `~` | `RESUME` edge | set-points brought back up to speed |
//! | [`Command::Stop`] | feed hold `!`, then the run ends once the controller reports `Hold:0` or `Idle` | `HOLD` edge, then the run ends once the status reads held or idle | set-points slowed to a stand, then the drives disabled |
//! | [`Command::Abort`] | soft reset 0x18 | `ABORT` edge | quick stop |
//!
//! A stop is what an interrupted bridge does (Ctrl-C, a signal, a console's stop button):
//! the machine is brought to a stand along the path and left there, nothing queued is lost
//! from the record, and the run ends saying where to resume. An abort is the second press:
//! stop now, whatever it costs.
use tokio::sync::mpsc;

/// What the caller can ask of a running stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// Stop along the path and hold the position; the run goes on, held.
    Hold,
    /// Go on after a hold.
    Resume,
    /// Hold, wait until the machine stands, and end the run there, saying where to resume;
    /// `reason` (a signal's name, a button) goes into the log and the outcome.
    Stop {
        /// Why, in a few words.
        reason: &'static str,
    },
    /// Stop now and drop what is queued; the run ends, saying where to resume.
    Abort,
}

/// The sending half: presses the buttons of one run.
#[derive(Debug, Clone)]
pub struct Control(mpsc::UnboundedSender<Command>);

impl Control {
    /// Asks the run to hold; `false` if the run has already ended.
    pub fn hold(&self) -> bool {
        self.send(Command::Hold)
    }

    /// Asks the run to resume after a hold; `false` if the run has already ended.
    pub fn resume(&self) -> bool {
        self.send(Command::Resume)
    }

    /// Asks the run to hold and end once the machine stands; `false` if the run has
    /// already ended.
    pub fn stop(&self, reason: &'static str) -> bool {
        self.send(Command::Stop { reason })
    }

    /// Asks the run to abort; `false` if the run has already ended.
    pub fn abort(&self) -> bool {
        self.send(Command::Abort)
    }

    /// Sends `command`; `false` if the run has already ended.
    pub fn send(&self, command: Command) -> bool {
        self.0.send(command).is_ok()
    }
}

/// The receiving half, read by the run. Once every [`Control`] is gone no command can
/// come, and the run goes on unattended.
#[derive(Debug)]
pub struct Commands(mpsc::UnboundedReceiver<Command>);

impl Commands {
    /// The next command; waits forever once no [`Control`] is left (so a `select!` on it
    /// never ends a run by itself).
    pub async fn next(&mut self) -> Command {
        match self.0.recv().await {
            Some(command) => command,
            None => std::future::pending().await,
        }
    }

    /// A command that has arrived, if any, without waiting.
    pub fn try_next(&mut self) -> Option<Command> {
        self.0.try_recv().ok()
    }
}

/// A new pair: the [`Control`] for the caller, the [`Commands`] for the run.
pub fn control() -> (Control, Commands) {
    let (sender, receiver) = mpsc::unbounded_channel();
    (Control(sender), Commands(receiver))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn commands_arrive_in_order_and_a_run_without_controls_waits() {
        let (control, mut commands) = control();
        let other = control.clone();
        assert!(control.hold());
        assert!(other.resume());
        assert!(other.stop("SIGINT"));
        assert!(control.abort());
        assert_eq!(commands.next().await, Command::Hold);
        assert_eq!(commands.try_next(), Some(Command::Resume));
        assert_eq!(
            commands.try_next(),
            Some(Command::Stop { reason: "SIGINT" })
        );
        assert_eq!(commands.next().await, Command::Abort);
        assert_eq!(commands.try_next(), None);
        drop((control, other));
        // No control left: nothing comes, and waiting does not end.
        let waited =
            tokio::time::timeout(std::time::Duration::from_millis(20), commands.next()).await;
        assert!(waited.is_err());
        // A run that ended refuses the buttons.
        let (control, commands) = super::control();
        drop(commands);
        assert!(!control.hold());
    }
}
