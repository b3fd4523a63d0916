//! Progress of long commands on a terminal: a spinner with the current step and the
//! elapsed time, drawn on stderr only when it is a terminal (quiet when piped), and
//! cleared when done.

use std::time::Duration;

/// A spinner naming the step a command is at.
pub struct Steps {
    bar: indicatif::ProgressBar,
}

impl Steps {
    /// Starts the spinner (hidden when stderr is not a terminal).
    pub fn new(what: &str) -> Self {
        let bar = indicatif::ProgressBar::new_spinner();
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.set_prefix(what.to_string());
        if !bar.is_hidden() {
            bar.enable_steady_tick(Duration::from_millis(120));
        }
        Steps { bar }
    }

    /// Names the step now running.
    pub fn step(&self, message: &str) {
        self.bar.set_message(message.to_string());
    }

    /// Prints a line on stderr without tearing the spinner.
    pub fn note(&self, line: &str) {
        self.bar.suspend(|| eprintln!("{line}"));
    }

    /// Whether anything is drawn (false when stderr is not a terminal).
    pub fn visible(&self) -> bool {
        !self.bar.is_hidden()
    }
}

impl Drop for Steps {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
