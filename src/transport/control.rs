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
//! A feed override ([`Control::feed_override`]) is not a button but a value: the latest
//! asked is the one that counts, so it travels apart from the commands (a run reads both
//! through [`Commands::next_request`]). It is refused above the run's cap
//! ([`crate::plan::overrides::FeedCap`]: the insert cusp within its share of Δ, and the
//! controller's range), before anything is sent:
//!
//! | | grbl / grblHAL | Modbus register map | CiA 402 drives |
//! |---|---|---|---|
//! | feed override | real-time bytes 0x90–0x94, one step at a time, each read back from `Ov:` | `FEED_OVERRIDE` register (40) | the bridge's own set-point clock runs at the override |
//!
//! A stop is what an interrupted bridge does (Ctrl-C, a signal, a console's stop button):
//! the machine is brought to a stand along the path and left there, nothing queued is lost
//! from the record, and the run ends saying where to resume. An abort is the second press:
//! stop now, whatever it costs.
use super::link::TransportKind;
use crate::plan::overrides::{self, FeedCap, OverrideError, OverrideRange};
use crate::plan::Report;
use std::sync::{Arc, Mutex, PoisonError};
use tokio::sync::{mpsc, watch};

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

/// What a run is asked: a command, or a new feed override.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// A button.
    Command(Command),
    /// Run at this feed override, percent (already checked against the run's cap).
    FeedOverride(u16),
}

/// Why a feed override was not asked of the run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeedOverrideError {
    /// Over the cap or under the controller's range.
    #[error(transparent)]
    Refused(#[from] OverrideError),
    /// The run's cap is not known (nobody told this control what was planned), so no
    /// override can be checked against Δ.
    #[error(
        "no feed override without the planned program's cap: the insert cusp's share of Δ is \
         not known for this run"
    )]
    NoCap,
    /// The run has ended.
    #[error("the run has ended")]
    Ended,
    /// A transport whose controller takes its feed override from its own panel.
    #[error(
        "whirl sets no feed override on {transport}: LinuxCNC takes it from its own panel \
         (halui); the insert cusp's cap is {cap} %"
    )]
    Unsupported {
        /// The transport's name.
        transport: &'static str,
        /// The cap the operator should keep to there, percent.
        cap: u16,
    },
}

/// The feed override range `kind` takes; `None` where whirl sets none (LinuxCNC).
pub fn override_range(kind: TransportKind) -> Option<OverrideRange> {
    match kind {
        TransportKind::Serial => Some(overrides::GRBL),
        TransportKind::ModbusTcp | TransportKind::ModbusRtu => Some(overrides::MODBUS),
        TransportKind::CanSlcan | TransportKind::Can => Some(overrides::CANOPEN),
        TransportKind::Linuxcnc => None,
    }
}

/// The feed override cap of a program planned as `report` says, streamed over `kind`;
/// refused where whirl sets no override (naming the cap to keep to on the machine's panel).
pub fn feed_cap(report: &Report, kind: TransportKind) -> Result<FeedCap, FeedOverrideError> {
    match override_range(kind) {
        Some(range) => Ok(FeedCap::of(report, range)),
        None => Err(FeedOverrideError::Unsupported {
            transport: kind.name(),
            cap: FeedCap::of(report, overrides::GRBL).max_percent,
        }),
    }
}

/// The feed override of one run: its cap and the value asked.
#[derive(Debug)]
struct Feed {
    cap: Mutex<Option<FeedCap>>,
    asked: watch::Sender<Option<u16>>,
}

/// The sending half: presses the buttons of one run.
#[derive(Debug, Clone)]
pub struct Control(mpsc::UnboundedSender<Command>, Arc<Feed>);

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

    /// Sets the run's feed override cap, from its plan; overrides are refused until then.
    pub fn set_feed_cap(&self, cap: FeedCap) {
        *self.1.cap.lock().unwrap_or_else(PoisonError::into_inner) = Some(cap);
    }

    /// The run's feed override cap, if set.
    pub fn feed_cap(&self) -> Option<FeedCap> {
        self.1
            .cap
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The feed override last asked, percent (100 if none was).
    pub fn feed_override_asked(&self) -> u16 {
        self.1.asked.borrow().unwrap_or(100)
    }

    /// Asks the run to go on at `percent` of the programmed feed; refused above the cap
    /// (naming it and why) or below the controller's range, and then nothing is asked.
    /// Asked before the run starts, it is the run's first override.
    pub fn feed_override(&self, percent: u16) -> Result<u16, FeedOverrideError> {
        let cap = self.feed_cap().ok_or(FeedOverrideError::NoCap)?;
        let percent = cap.check(percent)?;
        if self.0.is_closed() {
            return Err(FeedOverrideError::Ended);
        }
        self.1.asked.send_replace(Some(percent));
        Ok(percent)
    }

    /// Steps the feed override by `by` percent from the value last asked, held within the
    /// cap and the controller's range (a key pressed once too often): the value asked, and
    /// why it was held if it was.
    pub fn step_feed_override(&self, by: i32) -> Result<(u16, Option<String>), FeedOverrideError> {
        let cap = self.feed_cap().ok_or(FeedOverrideError::NoCap)?;
        let (percent, held) = cap.clamp(i32::from(self.feed_override_asked()).saturating_add(by));
        self.feed_override(percent).map(|p| (p, held))
    }
}

/// The receiving half, read by the run. Once every [`Control`] is gone no command can
/// come, and the run goes on unattended.
#[derive(Debug)]
pub struct Commands(
    mpsc::UnboundedReceiver<Command>,
    watch::Receiver<Option<u16>>,
);

impl Commands {
    /// The next command; waits forever once no [`Control`] is left (so a `select!` on it
    /// never ends a run by itself).
    pub async fn next(&mut self) -> Command {
        next_command(&mut self.0).await
    }

    /// The next command or feed override, commands first; waits forever once no
    /// [`Control`] is left. For a run that honours the feed override.
    pub async fn next_request(&mut self) -> Request {
        tokio::select! {
            biased;
            command = next_command(&mut self.0) => Request::Command(command),
            percent = next_feed_override(&mut self.1) => Request::FeedOverride(percent),
        }
    }

    /// A feed override asked and not yet read, if any, without waiting.
    pub fn try_feed_override(&mut self) -> Option<u16> {
        if self.1.has_changed().unwrap_or(false) {
            *self.1.borrow_and_update()
        } else {
            None
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
    let (asked, feed) = watch::channel(None);
    let feed_state = Feed {
        cap: Mutex::new(None),
        asked,
    };
    (
        Control(sender, Arc::new(feed_state)),
        Commands(receiver, feed),
    )
}

async fn next_command(receiver: &mut mpsc::UnboundedReceiver<Command>) -> Command {
    match receiver.recv().await {
        Some(command) => command,
        None => std::future::pending().await,
    }
}

/// The next feed override asked; waits forever once no [`Control`] is left.
async fn next_feed_override(receiver: &mut watch::Receiver<Option<u16>>) -> u16 {
    loop {
        if receiver.changed().await.is_err() {
            return std::future::pending().await;
        }
        if let Some(percent) = *receiver.borrow_and_update() {
            return percent;
        }
    }
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

    /// Δ = 10 µm, held to 8.5 µm with a 4 µm cusp: capped at 117 % (√(5.5/4) = 1.1726).
    fn cap() -> FeedCap {
        FeedCap::new(0.01, 0.0085, 0.004, crate::plan::overrides::GRBL)
    }

    #[tokio::test]
    async fn a_feed_override_is_checked_against_the_cap_and_the_latest_counts() {
        let (control, mut commands) = control();
        // No cap known: nothing can be checked against Δ.
        assert_eq!(control.feed_override(90), Err(FeedOverrideError::NoCap));
        control.set_feed_cap(cap());
        // Asked before the run reads anything: its first override.
        assert_eq!(control.feed_override(110), Ok(110));
        let above = control.feed_override(118).unwrap_err();
        assert!(above.to_string().contains("117 %"), "{above}");
        assert!(control.feed_override(9).is_err());
        // The refusals asked nothing.
        assert_eq!(control.feed_override_asked(), 110);
        assert!(control.hold());
        // Commands first.
        assert_eq!(
            commands.next_request().await,
            Request::Command(Command::Hold)
        );
        assert_eq!(commands.next_request().await, Request::FeedOverride(110));
        // Two asked before the run looks: only the latest counts.
        control.feed_override(80).unwrap();
        control.feed_override(95).unwrap();
        assert_eq!(commands.try_feed_override(), Some(95));
        assert_eq!(commands.try_feed_override(), None);
        // Keys: +10 from 95, then held at the cap with the reason.
        assert_eq!(control.step_feed_override(10), Ok((105, None)));
        let (held, why) = control.step_feed_override(20).unwrap();
        assert_eq!(held, 117);
        assert!(why.unwrap().contains("insert cusp"));
        assert_eq!(commands.next_request().await, Request::FeedOverride(117));
        // A step as large as a request can ask is held at the cap, not overflowed.
        assert_eq!(control.step_feed_override(i32::MAX).unwrap().0, 117);
        assert_eq!(control.step_feed_override(i32::MIN).unwrap().0, 10);
        // A run that ended refuses it.
        drop(commands);
        assert_eq!(control.feed_override(100), Err(FeedOverrideError::Ended));
    }
}
