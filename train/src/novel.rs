//! Novel views during training: when they are due, render them with the
//! current field, extract and compress their features, record them in the
//! run directory and append them to the scene; on resume, find them there.
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
    let extractor = field_ops::novel::scene_extractor(scene, novel)?;
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
        device,
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
