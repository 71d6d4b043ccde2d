//! The demo's progress on stderr: a line per step, and a bar or spinner on the long ones
//! (indicatif draws them only on a terminal). `--quiet` shows nothing but the notes.

use std::sync::Mutex;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// Where the demo says how far it is.
#[derive(Debug)]
pub struct Progress {
    quiet: bool,
    /// The bar or spinner of the long work under way.
    long: Mutex<Option<ProgressBar>>,
}

impl Progress {
    /// Progress on stderr, or none.
    pub fn new(quiet: bool) -> Self {
        Progress { quiet, long: Mutex::new(None) }
    }

    fn long(&self) -> std::sync::MutexGuard<'_, Option<ProgressBar>> {
        self.long.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

impl dash2sim_sim::demo::Progress for Progress {
    fn step(&self, n: u32, of: u32, text: &str) {
        if !self.quiet {
            eprintln!("[{n}/{of}] {text}");
        }
    }

    fn begin(&self, len: Option<u64>, text: &str) {
        if self.quiet {
            return;
        }
        let bar = match len {
            Some(len) => {
                let style =
                    ProgressStyle::with_template(&format!("      {{bar:40}} {{pos}}/{{len}} {text} ({{elapsed}})"))
                        .unwrap_or_else(|_| ProgressStyle::default_bar());
                ProgressBar::new(len).with_style(style)
            }
            None => {
                let spinner = ProgressBar::new_spinner().with_message(text.to_owned());
                spinner.enable_steady_tick(Duration::from_millis(120));
                spinner
            }
        };
        if let Some(old) = self.long().replace(bar) {
            old.finish_and_clear();
        }
    }

    fn at(&self, position: u64) {
        if let Some(bar) = self.long().as_ref() {
            bar.set_position(position);
        }
    }

    fn end(&self) {
        if let Some(bar) = self.long().take() {
            bar.finish_and_clear();
        }
    }

    fn note(&self, text: &str) {
        eprintln!("dash2sim demo: {text}");
    }
}
