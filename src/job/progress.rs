//! How a job reports while it works, and how it is stopped. The command line shows
//! progress bars and prints notes to stderr (`cli::progress`); the Python package calls
//! back into Python and stops on Ctrl-C. A job's results never depend on the reporter.

/// The stages a job reports, each a count of paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The adaptive pilot (its samples are not in the bundle).
    Pilot,
    /// The render whose samples the bundle keeps.
    Render,
}

impl Stage {
    pub fn name(self) -> &'static str {
        match self {
            Stage::Pilot => "pilot",
            Stage::Render => "render",
        }
    }
}

/// Receives a job's progress. Called from worker threads (hence `Sync`); every method
/// must be cheap.
pub trait Progress: Sync {
    /// `stage` starts; `total` paths will be traced.
    fn start(&self, stage: Stage, total: u64);
    /// `n` more paths of the current stage are done.
    fn advance(&self, n: u64);
    /// The current stage's running estimate, e.g. "RMSE so far 1.2e-3".
    fn status(&self, _text: &str) {}
    /// The current stage is over.
    fn finish(&self) {}
    /// A line for the user: what is about to be done, what was chosen, warnings.
    fn note(&self, line: &str);
    /// True once the caller wants the job stopped. A render checks it after each row:
    /// the job then ends with [`Cancelled`] and writes nothing.
    fn cancelled(&self) -> bool {
        false
    }
}

/// Reports nothing, never stops.
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _: Stage, _: u64) {}
    fn advance(&self, _: u64) {}
    fn note(&self, _: &str) {}
}

/// A job stopped because its [`Progress`] asked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("interrupted: the render was stopped before it finished; nothing was written")]
pub struct Cancelled;
