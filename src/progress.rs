//! Progress of the long commands on stderr (indicatif): drawn only when stderr is a terminal and
//! the command prints no JSON, so stdout and any captured output are the same with or without it.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::Duration;

/// stderr when `shown`, else nowhere.
fn target(shown: bool) -> ProgressDrawTarget {
    if shown {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    }
}

/// A bar over `len` units, or a spinner with a message, hidden where it must not draw.
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// Whether a command run with `json` (or `--quiet`) may draw on stderr now.
    pub fn wanted(json: bool) -> bool {
        !json && std::io::stderr().is_terminal()
    }

    /// A bar over `len` units (`{pos}/{len}` when `len > 0`); `template` decides the rest.
    pub fn bar(len: u64, template: &str, shown: bool) -> Progress {
        let bar = ProgressBar::with_draw_target(Some(len), target(shown));
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        Progress { bar }
    }

    /// A spinner with a message: for work whose length is not known ahead.
    pub fn spinner(message: &str, shown: bool) -> Progress {
        let bar = ProgressBar::with_draw_target(None, target(shown));
        if let Ok(style) = ProgressStyle::with_template("{spinner} {elapsed:>4} {msg}") {
            bar.set_style(style);
        }
        bar.set_message(message.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        Progress { bar }
    }

    pub fn set_position(&self, pos: u64) {
        self.bar.set_position(pos);
    }

    pub fn set_message(&self, message: impl Into<String>) {
        self.bar.set_message(message.into());
    }

    /// Remove it from the terminal (the command's own output follows).
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
