//! The feed override from the keyboard while a run streams: `+` faster and `-` slower by
//! 10 %, `0` back to 100 %, each press held at the run's cap (the insert cusp within its
//! share of Δ) or the controller's range with a message saying why. Only on a terminal:
//! standard input is put in non-canonical mode without echo for the run (signals still
//! work, so Ctrl-C stops the run as ever), and put back as it was when the run ends.

use std::io::{IsTerminal, Read, Write};

use rustix::termios::{self, LocalModes, OptionalActions, Termios};
use whirl::plan::overrides::FeedCap;
use whirl::transport::control::FeedOverrideError;
use whirl::transport::Control;

/// The step of one press, percent.
const STEP: i32 = 10;

/// Standard input as it was before the run; put back on drop.
pub struct Keys {
    saved: Termios,
}

impl Keys {
    /// Reads the keys for `control` on a thread of their own, if standard input and standard
    /// error are a terminal; `None` otherwise (a pipe, a CI job), and nothing changes.
    pub fn watch(control: Control) -> Option<Keys> {
        let stdin = std::io::stdin();
        if !stdin.is_terminal() || !std::io::stderr().is_terminal() {
            return None;
        }
        let saved = termios::tcgetattr(&stdin).ok()?;
        let mut raw = saved.clone();
        raw.local_modes
            .remove(LocalModes::ICANON | LocalModes::ECHO);
        termios::tcsetattr(&stdin, OptionalActions::Now, &raw).ok()?;
        say("feed override: + and - by 10 %, 0 back to 100 %");
        // The thread blocks on the terminal; it ends with the process.
        std::thread::spawn(move || {
            let mut byte = [0u8; 1];
            while std::io::stdin().read_exact(&mut byte).is_ok() {
                let asked = match byte[0] {
                    b'+' | b'=' => control.step_feed_override(STEP),
                    b'-' | b'_' => control.step_feed_override(-STEP),
                    b'0' => control.feed_override(100).map(|percent| (percent, None)),
                    _ => continue,
                };
                match asked {
                    Ok((percent, held)) => {
                        say(&format!("feed override {percent} % asked"));
                        if let Some(why) = held {
                            say(&why);
                        }
                    }
                    Err(error) => say(&format!("feed override: {error}")),
                }
            }
        });
        Some(Keys { saved })
    }
}

impl Drop for Keys {
    fn drop(&mut self) {
        let _ = termios::tcsetattr(std::io::stdin(), OptionalActions::Now, &self.saved);
    }
}

/// A line on standard error (the progress bar's terminal).
fn say(text: &str) {
    let _ = writeln!(std::io::stderr(), "whirl: {text}");
}

/// The cap of a run and the override it starts at, checked before anything is sent:
/// `cap` is the plan's (`None` for a program given as G-code, which has no plan to take
/// the insert cusp's share of Δ from), `asked` the `--feed-override`.
pub fn start_cap(
    cap: Option<Result<FeedCap, FeedOverrideError>>,
    asked: Option<u16>,
    input: &std::path::Path,
) -> anyhow::Result<Option<FeedCap>> {
    match (cap, asked) {
        (None, Some(percent)) => anyhow::bail!(
            "--feed-override {percent}: {} is a program, not a job: the cap that keeps the \
             insert cusp within its share of Δ comes from planning the job (.toml)",
            input.display()
        ),
        (Some(Err(error)), Some(percent)) => {
            anyhow::bail!("--feed-override {percent}: {error}")
        }
        (Some(Ok(cap)), Some(percent)) => {
            cap.check(percent)
                .map_err(|error| anyhow::anyhow!("--feed-override {percent}: {error}"))?;
            Ok(Some(cap))
        }
        (cap, None) => Ok(cap.and_then(Result::ok)),
    }
}

/// Sets the run's cap and its first override on `control`, and reads the keys if on a
/// terminal.
pub fn arm(control: &Control, cap: Option<FeedCap>, asked: Option<u16>) -> Option<Keys> {
    let cap = cap?;
    control.set_feed_cap(cap);
    if let Some(percent) = asked {
        // Checked against the same cap by start_cap.
        let _ = control.feed_override(percent);
    }
    Keys::watch(control.clone())
}
