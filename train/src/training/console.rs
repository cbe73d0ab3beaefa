//! What a session shows and how it is timed: the session's clock, the rays
//! per second between log lines, the held-out figures and training steps
//! as console lines, and the occupancy grid's figures of a log line.

use std::time::Instant;

use indicatif::ProgressBar;
use model::{ClipStats, OccupancyGrid};

use crate::accuracy::EvalMetrics;
use crate::metrics_log::GridLine;
use crate::progress::say;
use crate::step::StepReport;

/// The clock of a session: seconds since it started, and training
/// wall-clock seconds (those of the earlier sessions of a resumed run
/// included).
#[derive(Debug, Clone, Copy)]
pub(super) struct Clock {
    start: Instant,
    before: f64,
}

impl Clock {
    /// Starts the clock of a session that follows `before` seconds of
    /// earlier ones.
    pub(super) fn start(before: f64) -> Self {
        Self {
            start: Instant::now(),
            before,
        }
    }

    /// Seconds of this session.
    pub(super) fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Seconds of all sessions.
    pub(super) fn wall(&self) -> f64 {
        self.before + self.elapsed()
    }
}

/// Rays trained on since the previous log line, and since when.
#[derive(Debug, Clone, Copy)]
pub(super) struct RayRate {
    since: Instant,
    rays: u64,
}

impl RayRate {
    /// Starts counting now.
    pub(super) fn start() -> Self {
        Self {
            since: Instant::now(),
            rays: 0,
        }
    }

    /// Counts the rays of a step.
    pub(super) fn add(&mut self, rays: u64) {
        self.rays += rays;
    }

    /// Rays per second since the count started; starts it anew.
    pub(super) fn take(&mut self) -> f64 {
        let secs = self.since.elapsed().as_secs_f64().max(1e-9);
        let rate = self.rays as f64 / secs;
        *self = Self::start();
        rate
    }
}

/// One line of held-out figures for the log.
pub(super) fn describe(label: &str, m: &EvalMetrics) -> String {
    format!(
        "{label} psnr {:.2} dB{}{}{}",
        m.psnr,
        m.ssim.map(|s| format!(", ssim {s:.3}")).unwrap_or_default(),
        m.depth_mae
            .map(|d| format!(", depth mae {d:.3} m"))
            .unwrap_or_default(),
        m.feature_cosine
            .map(|c| format!(", feature cosine {c:.3}"))
            .unwrap_or_default()
    )
}

/// Shows the losses of the step that completed iteration `i` of `end`: as
/// the bar's message, or without a visible bar (`--quiet`, or stderr not a
/// terminal) as a plain line.
pub(super) fn show_step(
    bar: &ProgressBar,
    i: usize,
    end: usize,
    report: &StepReport,
    rays_per_second: f64,
) {
    let line = format!(
        "loss {:.4} rgb {:.5} open {:.4} depth {:.4} psnr {:.2} {:.0} rays/s",
        report.loss,
        report.rgb_mse,
        report.open,
        report.depth,
        report.psnr(),
        rays_per_second
    );
    if bar.is_hidden() {
        say(bar, format!("iteration {i}/{end}: {line}"));
    } else {
        bar.set_message(line);
    }
}

/// The grid's figures of a log line from what clipping did since the last.
pub(super) fn grid_line(grid: &OccupancyGrid, skipping: &ClipStats) -> GridLine {
    let drawn = skipping.drawn.max(1) as f64;
    GridLine {
        occupied_cells: grid.occupied_fraction(),
        rays_rendered: skipping.kept as f64 / drawn,
        ray_length_sampled: skipping.span_sum / drawn,
    }
}
