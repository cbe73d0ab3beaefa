//! Stopping a run from outside without losing its work: a signal sets a
//! flag, the training loop sees it before its next step, writes a
//! checkpoint at the iteration it reached and returns
//! [`TrainError::Interrupted`](crate::TrainError::Interrupted). The binary
//! then exits with [`EXIT_INTERRUPTED`], the code a batch scheduler's job
//! script requeues on; `--resume` continues bit-identically, since every
//! random draw of iteration `i` is seeded from `(seed, i)`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Exit code of a run stopped by a signal after writing its checkpoint
/// (`EX_TEMPFAIL` of `sysexits.h`: try again later).
pub const EXIT_INTERRUPTED: u8 = 75;

/// Exit code of a second Ctrl-C, which stops at once without a checkpoint
/// (128 + SIGINT, as a shell reports it).
pub const EXIT_FORCED: i32 = 130;

/// A request to stop, shared between the signal handlers and the loop.
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// A flag nobody has raised.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the run to stop before its next step.
    pub fn request(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// A flag raised by SIGTERM (Slurm's preemption, requeue and time-limit
    /// signal, `kill`), SIGINT (Ctrl-C) and SIGHUP (a closed terminal).
    /// Repeated SIGTERMs are one request (Slurm signals both the job script
    /// and its children); a second Ctrl-C exits at once with
    /// [`EXIT_FORCED`].
    pub fn on_signals() -> std::io::Result<Self> {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let flag = Self::new();
        // Registered before the flag-setting handler, so it sees the flag
        // as the previous Ctrl-C (or SIGTERM) left it.
        signal_hook::flag::register_conditional_shutdown(SIGINT, EXIT_FORCED, flag.0.clone())?;
        for signal in [SIGTERM, SIGINT, SIGHUP] {
            signal_hook::flag::register(signal, flag.0.clone())?;
        }
        Ok(flag)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flag_is_shared_by_its_clones() {
        let flag = StopFlag::new();
        let seen = flag.clone();
        assert!(!seen.requested());
        flag.request();
        assert!(seen.requested());
    }
}
