//! The command line's [`Progress`]: a bar on stderr per stage (the render's shows the
//! adaptive error estimate beside it), notes printed to stderr between bars.

use crate::job::progress::{Progress, Stage};
use indicatif::{ProgressBar, ProgressStyle};
use std::sync::{PoisonError, RwLock};

/// Progress bars on stderr (none when `quiet`); the notes are printed either way.
pub struct Bars {
    bar: RwLock<ProgressBar>,
    quiet: bool,
}

impl Bars {
    pub fn new(quiet: bool) -> Self {
        Bars {
            bar: RwLock::new(ProgressBar::hidden()),
            quiet,
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: Stage, total: u64) {
        let template = match stage {
            Stage::Pilot => "pilot {bar:34} {percent:>3}% {human_pos}/{human_len} paths, ETA {eta}",
            Stage::Render => {
                "{bar:34} {percent:>3}% {human_pos}/{human_len} paths, {per_sec}, ETA {eta} {msg}"
            }
        };
        let bar = if self.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(total)
        };
        bar.set_style(ProgressStyle::with_template(template).expect("valid template"));
        *self.bar.write().unwrap_or_else(PoisonError::into_inner) = bar;
    }

    fn advance(&self, n: u64) {
        self.bar
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .inc(n);
    }

    fn status(&self, text: &str) {
        self.bar
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .set_message(text.to_string());
    }

    fn finish(&self) {
        self.bar
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .finish_and_clear();
    }

    fn note(&self, line: &str) {
        eprintln!("{line}");
    }
}
