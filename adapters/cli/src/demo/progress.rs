//! Progress of the demo on stderr: a line per step, and a bar or spinner on the long ones
//! (indicatif draws them only on a terminal). `--quiet` shows nothing.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// Where the demo says how far it is.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    quiet: bool,
}

impl Progress {
    /// Progress on stderr, or none.
    pub fn new(quiet: bool) -> Self {
        Progress { quiet }
    }

    /// Step `n` of `of` begins.
    pub fn step(&self, n: u32, of: u32, text: &str) {
        if !self.quiet {
            eprintln!("[{n}/{of}] {text}");
        }
    }

    /// A bar of `len` units.
    pub fn bar(&self, len: u64, unit: &str) -> ProgressBar {
        if self.quiet {
            return ProgressBar::hidden();
        }
        let style = ProgressStyle::with_template(&format!("      {{bar:40}} {{pos}}/{{len}} {unit} ({{elapsed}})"))
            .unwrap_or_else(|_| ProgressStyle::default_bar());
        ProgressBar::new(len).with_style(style)
    }

    /// A spinner saying `text`.
    pub fn spinner(&self, text: &str) -> ProgressBar {
        if self.quiet {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new_spinner().with_message(text.to_owned());
        bar.enable_steady_tick(Duration::from_millis(120));
        bar
    }
}
