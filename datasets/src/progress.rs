//! A progress bar on stderr for the long parts of loading a capture
//! (decoding hundreds of images), drawn only when stderr is a terminal
//! and the work has more than a few steps.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use crate::error::DatasetError;

/// `f` of every item, computed in parallel and returned in order, with a
/// bar of `what` while it runs. On failure the error of the first failing
/// item in order is returned, whichever thread found an error first, so a
/// bad capture always names the same file.
pub fn par_map<T: Sync, R: Send>(
    items: &[T],
    what: &str,
    f: impl Fn(&T) -> Result<R, DatasetError> + Sync,
) -> Result<Vec<R>, DatasetError> {
    let bar = Progress::new(items.len(), what);
    let out: Vec<Result<R, DatasetError>> = items
        .par_iter()
        .map(|item| {
            let r = f(item);
            bar.tick();
            r
        })
        .collect();
    bar.finish();
    out.into_iter().collect()
}

/// Fewer steps than this draw no bar.
const MIN_STEPS: usize = 16;

/// A bar of `total` steps, shared by the threads that do them.
pub struct Progress(Option<ProgressBar>);

impl Progress {
    /// A bar for `total` steps of `what` (none for fewer than
    /// sixteen).
    pub fn new(total: usize, what: &str) -> Self {
        if total < MIN_STEPS {
            return Self(None);
        }
        let bar = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template(
            "{msg} {bar:30} {pos}/{len} [{elapsed_precise}, {eta} left]",
        ) {
            bar.set_style(style);
        }
        bar.set_message(what.to_string());
        Self(Some(bar))
    }

    /// One step done.
    pub fn tick(&self) {
        if let Some(bar) = &self.0 {
            bar.inc(1);
        }
    }

    /// All done: the bar is cleared.
    pub fn finish(&self) {
        if let Some(bar) = &self.0 {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use std::time::Duration;

    #[test]
    fn the_first_failing_item_in_order_is_the_error() {
        let items: Vec<usize> = (0..64).collect();
        let out = par_map(&items, "test", |&i| {
            if i == 3 {
                // The first failure in order is the slowest to be found.
                std::thread::sleep(Duration::from_millis(50));
            }
            if i % 4 == 3 {
                Err(DatasetError::invalid(PathBuf::from(format!("{i}")), "bad"))
            } else {
                Ok(i * 2)
            }
        });
        let msg = out.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(msg.starts_with("3:"), "{msg}");
        let ok = par_map(&items, "test", |&i| Ok::<_, DatasetError>(i * 2));
        assert_eq!(ok.ok(), Some(items.iter().map(|i| i * 2).collect()));
    }
}
