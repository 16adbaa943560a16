//! Signals while a run streams: the first SIGINT (Ctrl-C), SIGTERM or SIGHUP stops the
//! machine (a hold, and the run ends once it stands, saying where to resume); a second
//! SIGINT aborts (a soft reset, a quick stop). Without this the process would die at the
//! first signal and leave the controller cutting what it had received.
//!
//! The handlers are installed before the first byte goes out ([`Interrupts::install`]), so
//! no signal can arrive unhandled once streaming has begun.

use std::io::Write;

use tokio::signal::unix::{signal, Signal, SignalKind};
use whirl::transport::Control;

/// The signals a run answers, installed.
pub struct Interrupts {
    interrupt: Signal,
    terminate: Signal,
    hangup: Signal,
}

impl Interrupts {
    /// Installs the handlers; call inside the runtime (its I/O driver delivers them).
    pub fn install() -> std::io::Result<Interrupts> {
        Ok(Interrupts {
            interrupt: signal(SignalKind::interrupt())?,
            terminate: signal(SignalKind::terminate())?,
            hangup: signal(SignalKind::hangup())?,
        })
    }

    /// Presses `control`'s buttons as the signals come, until the run has ended.
    pub async fn watch(mut self, control: Control) {
        let mut stopping = false;
        loop {
            let (name, aborts) = tokio::select! {
                _ = self.interrupt.recv() => ("SIGINT", true),
                _ = self.terminate.recv() => ("SIGTERM", false),
                _ = self.hangup.recv() => ("SIGHUP", false),
            };
            let (pressed, said) = match (stopping, aborts) {
                (false, _) => (
                    control.stop(name),
                    format!("{name}: holding the machine; Ctrl-C again aborts (soft reset)"),
                ),
                (true, true) => (control.abort(), format!("{name} again: aborting")),
                (true, false) => continue,
            };
            if !pressed {
                return;
            }
            stopping = true;
            // After a hangup there may be no terminal to say it on; the log has it.
            let _ = writeln!(std::io::stderr(), "whirl: {said}");
        }
    }
}
