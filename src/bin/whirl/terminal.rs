//! A progress bar on a terminal, fed by a run's progress.

use whirl::transport::{Progress, ProgressFn};

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
