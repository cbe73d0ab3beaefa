//! Training a field into a run directory: the start of a new run or of a
//! resumed one, the loop with its periodic logging, evaluations and
//! checkpoints, the schedule's fit to a time budget, the novel views, and
//! the final renders and `summary.json`.

mod budget;
mod console;
mod finish;
mod guard;
mod heldout;
mod live_viewer;
mod novel;
mod session;
mod snapshot;
mod start;
mod stepper;
mod train_loop;
mod unseen;

pub use live_viewer::ViewerSettings;
pub use session::{RunOutcome, SessionOptions};
pub use snapshot::{model_bytes, restore};
pub use start::{resume, train_new, train_new_with_stages};
