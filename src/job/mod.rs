//! Jobs: the library's whole tasks, shared by the command line (`cli`) and the Python
//! package (`python/`), so neither holds logic of its own. A job takes checked inputs,
//! reports through a [`progress::Progress`] (bars and stderr lines on the command line,
//! callbacks in Python) and can be stopped through it.

pub mod adaptive;
pub mod progress;
pub mod render;
pub mod system;

pub use adaptive::{AdaptiveRequest, Goal};
pub use progress::{Cancelled, Progress, Silent, Stage};
pub use render::{render, RenderJob, RenderReport};
