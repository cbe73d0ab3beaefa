//! Novel views during training: when they are due, render them with the
//! current field, extract and compress their features, record them in the
//! run directory and append them to the scene; on resume, find them there;
//! and the iteration at which the sampler starts drawing them.
//!
//! Views join the training frames at the iteration recorded with them, also
//! when a resumed run read them back before reaching it, so that the ray
//! stream of an interrupted run is that of an uninterrupted one.

use std::time::Instant;

use burn::tensor::Device;
use datasets::Scene;
use field_ops::novel::record::{RecordedViews, ViewChoice, append_recorded, write_record};
use field_ops::run_dir::RunDir;
use model::OpenNerf;

use crate::config::TrainConfig;
use crate::error::TrainError;
use crate::metrics_log::NovelViewsLine;

/// The iteration novel views are due at: the configured one, else half the
/// schedule. `None` when no views are configured.
pub fn due_at(config: &TrainConfig) -> Option<usize> {
    config
        .novel
        .enabled()
        .then(|| config.novel.after.unwrap_or(config.schedule.iterations / 2))
}

/// What adding the views cost and gave.
#[derive(Debug, Clone)]
pub struct AddReport {
    /// The views.
    pub added: RecordedViews,
    /// Cameras asked for.
    pub requested: usize,
    /// Seconds spent choosing, rendering and extracting.
    pub seconds: f64,
}

/// Chooses, renders, extracts and records the novel views of iteration
/// `iteration`, then appends them to `scene` as read back from the record
/// (so that a resumed run sees the very same bytes). `progress(done, total)`
/// is called after each rendered view.
#[allow(clippy::too_many_arguments)]
pub fn add_views(
    model: &OpenNerf,
    scene: &mut Scene,
    train: &[usize],
    config: &TrainConfig,
    run: &RunDir,
    iteration: usize,
    device: &Device,
    mut progress: impl FnMut(usize, usize),
) -> Result<AddReport, TrainError> {
    let start = Instant::now();
    let novel = &config.novel;
    let extractor = field_ops::novel::scene_extractor(scene, novel, device)?;
    let cameras = field_ops::novel::choose_cameras(
        novel.mode,
        novel.views,
        model,
        scene,
        train,
        novel,
        config.seed ^ 0x9e37_79b9_7f4a_7c15 ^ iteration as u64,
        device,
    )?;
    let views = field_ops::novel::render_views(
        model,
        &cameras,
        scene,
        extractor.as_ref(),
        novel,
        config.logging.render_chunk,
        &mut progress,
    )?;
    // The record says where the views came from, so that a run whose views
    // were taken from the ground truth is never mistaken for the method's.
    let choice = ViewChoice {
        mode: novel.mode,
        oracle: novel.oracle,
    };
    write_record(&run.novel(), choice, iteration, &views)?;
    let added = append_recorded(scene, &run.novel())?.ok_or_else(|| {
        TrainError::Config(format!(
            "{}: the novel views just written cannot be read back",
            run.novel().display()
        ))
    })?;
    Ok(AddReport {
        added,
        requested: novel.views,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The novel views of a session, and whether its sampler draws them yet.
#[derive(Debug, Clone)]
pub(super) struct SessionViews {
    /// The views, once made or read back.
    pub added: Option<RecordedViews>,
    in_sampler: bool,
}

impl SessionViews {
    /// The views of a session starting at `iteration` (read back from the
    /// run on resume).
    pub(super) fn new(added: Option<RecordedViews>, iteration: usize) -> Self {
        let in_sampler = added.as_ref().is_some_and(|a| iteration >= a.at);
        Self { added, in_sampler }
    }

    /// Whether the views are to be made before iteration `it`.
    pub(super) fn due(&self, config: &TrainConfig, it: usize) -> bool {
        self.added.is_none() && due_at(config).is_some_and(|due| it >= due)
    }

    /// The novel views batch `it` draws from (none before their iteration).
    pub(super) fn novel_frames(&self, it: usize) -> &[usize] {
        self.added
            .as_ref()
            .filter(|a| it >= a.at)
            .map_or(&[], |a| &a.frames)
    }

    /// Whether the views join the sampler's frames at iteration `it` (true
    /// once, at the first iteration that draws them).
    pub(super) fn join(&mut self, it: usize) -> bool {
        let joins = self.joins_at(it);
        self.in_sampler |= joins;
        joins
    }

    /// Whether [`SessionViews::join`] would be true at `it`.
    pub(super) fn joins_at(&self, it: usize) -> bool {
        !self.in_sampler && self.added.as_ref().is_some_and(|a| it >= a.at)
    }
}

/// The console line before the views of iteration `it` are made.
pub(super) fn adding_message(config: &TrainConfig, it: usize) -> String {
    format!(
        "iteration {it}: adding {} novel views ({})",
        config.novel.views, config.novel.mode
    )
}

/// The console line once they are.
pub(super) fn added_message(report: &AddReport, run: &RunDir, it: usize) -> String {
    format!(
        "iteration {it}: {} of {} novel views added in {:.1} s (recorded in {})",
        report.added.frames.len(),
        report.requested,
        report.seconds,
        run.novel().display()
    )
}

/// The log line of the views made at iteration `it`.
pub(super) fn log_line(report: &AddReport, it: usize, wall_seconds: f64) -> NovelViewsLine {
    NovelViewsLine {
        iteration: it,
        mode: report.added.choice.to_string(),
        requested: report.requested,
        added: report.added.frames.len(),
        seconds: report.seconds,
        wall_seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_join_the_sampler_once_from_their_iteration() {
        let added = RecordedViews {
            at: 40,
            frames: vec![20, 21],
            choice: ViewChoice {
                mode: field_ops::novel::NovelMode::Guided,
                oracle: None,
            },
        };
        let mut views = SessionViews::new(Some(added.clone()), 30);
        assert!(views.novel_frames(39).is_empty());
        assert_eq!(views.novel_frames(40), &[20, 21]);
        assert!(!views.join(39));
        assert!(views.join(40));
        assert!(!views.join(41));
        // A session resumed after they joined draws them from its start.
        let mut resumed = SessionViews::new(Some(added), 50);
        assert!(!resumed.join(50));
        assert_eq!(resumed.novel_frames(50), &[20, 21]);
    }
}
