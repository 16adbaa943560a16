//! What a command shows: its results on standard output ([`say!`]), errors on standard
//! error ([`error`]), and a progress bar on a terminal, fed by a run's progress.
//!
//! A reader that goes away (`whirl dry-run JOB | head -1`, a closed pipe) ends the printing
//! quietly: whatever is left to print is dropped, no error is said, and the command goes on
//! to its end, so its exit code is the work's (0 if it succeeded, 2 beyond Δ, 1 if it
//! failed). A classic Unix filter dies of SIGPIPE instead, a status that would hide whether
//! a dry run was within Δ. Any other failure to write to standard output (a full disk) is
//! an error.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use whirl::transport::{Progress, ProgressFn};

/// Standard output's reader has gone: nothing more is printed.
static STDOUT_GONE: AtomicBool = AtomicBool::new(false);

/// Prints a line of results on standard output, as `println!` does, but a closed pipe ends
/// the printing quietly instead of panicking (see the module's docs); gives an error for any
/// other failure to write.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::terminal::say_line(format_args!($($arg)*))
    };
}
pub(crate) use say;

/// [`say!`]'s line.
pub(crate) fn say_line(line: std::fmt::Arguments) -> anyhow::Result<()> {
    if STDOUT_GONE.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
            STDOUT_GONE.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(anyhow::Error::new(e).context("cannot write to standard output")),
    }
}

/// Prints `error: …` on standard error; if standard error cannot take it, there is nowhere
/// left to say so.
pub(crate) fn error(e: &anyhow::Error) {
    let _ = writeln!(std::io::stderr(), "error: {e:#}");
}

/// Prints `warning: …` on standard error (there is nowhere to say it if that is closed).
pub(crate) fn warn(text: &str) {
    let _ = writeln!(std::io::stderr(), "warning: {text}");
}

/// A progress bar with the time left on a terminal (stderr).
pub(crate) struct Bar(indicatif::ProgressBar);

impl Bar {
    /// The run's progress callback, drawing this bar.
    pub(crate) fn callback(&self) -> ProgressFn {
        let bar = self.0.clone();
        Box::new(move |p: &Progress| {
            bar.set_length(p.total as u64);
            bar.set_position(p.done as u64);
            let state = p.state.as_deref().unwrap_or_default();
            let left = p.left.map_or(String::new(), |d| {
                format!(", {} left", indicatif::HumanDuration(d))
            });
            let tail = if p.finishing {
                ", waiting for the last moves"
            } else {
                ""
            };
            bar.set_message(format!("{} {state}{left}{tail}", p.unit.name()));
        })
    }

    /// Clears the bar.
    pub(crate) fn finish(self) {
        self.0.finish_and_clear();
    }
}

/// `Some` only when stderr is a terminal: logs and pipes get no bar.
pub(crate) fn progress_bar() -> Option<Bar> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} {elapsed} {msg}")
            .expect("a valid template"),
    );
    Some(Bar(bar))
}
