//! `--vlm`: the scene's feature maps made in process by a CLIP model's
//! vision tower (dense NACLIP / ClearCLIP / MaskCLIP features over sliding
//! windows), cached as `.npy` with a stamp so that a resumed or repeated run
//! reuses them, and its class embeddings by the same model's text tower.

use std::path::PathBuf;
use std::sync::Arc;

use clip::vision::{DenseOptions, Vlm};
use datasets::features::PcaSetting;
use datasets::text::TextEmbeddings;
use datasets::{Scene, SceneSource, VlmSource};

use crate::backend::{BackendKind, device};
use crate::error::TrainError;

/// How `--vlm` runs.
#[derive(Debug, Clone)]
pub struct VlmRequest {
    /// The CLIP model directory.
    pub model: PathBuf,
    /// Dense variant and short side.
    pub options: DenseOptions,
    /// Where the maps go.
    pub features: PathBuf,
    /// Compression of the maps.
    pub pca: PcaSetting,
    /// Backend the model runs on.
    pub backend: BackendKind,
    /// Its device index.
    pub device_index: Option<usize>,
}

fn flag_error(request: &VlmRequest, e: impl std::fmt::Display) -> TrainError {
    TrainError::Config(format!("--vlm {}: {e}", request.model.display()))
}

/// Loads `base`, makes (or reuses) its maps with the model and returns the
/// scene with them, its source recording how to rebuild it.
pub fn prepare(base: &SceneSource, request: &VlmRequest) -> Result<Scene, TrainError> {
    let device = device(request.backend, request.device_index);
    let vlm = Vlm::load(&request.model, &device).map_err(|e| flag_error(request, e))?;
    for note in vlm.notes() {
        eprintln!("note: {note}");
    }
    let Vlm { vision, text } = vlm;
    let vision = Arc::new(vision);
    let mut scene = datasets::load_scene(base)?;
    let dir = &request.features;
    field_ops::vlm_maps::ensure_maps(&scene, &vision, &request.options, dir)?;
    // Absolute, so that the run is rebuilt from any working directory.
    let dir = &std::fs::canonicalize(dir).map_err(|e| TrainError::io(dir, e))?;
    if let Some(classes) = &scene.classes {
        let rows = text
            .embed(&classes.names)
            .map_err(|e| flag_error(request, e))?;
        let embedded = TextEmbeddings {
            names: classes.names.clone(),
            dim: text.dim(),
            data: rows.concat(),
        };
        embedded.save(&dir.join("classes.npy"), &dir.join("classes.txt"))?;
    }
    let model =
        std::fs::canonicalize(&request.model).map_err(|e| TrainError::io(&request.model, e))?;
    let source = SceneSource::WithFeatures {
        base: Box::new(base.clone()),
        features: dir.to_path_buf(),
        pca: request.pca,
        vlm: Some(VlmSource {
            model,
            dense: request.options.variant,
            short_side: vision.short_side(&request.options),
        }),
    };
    datasets::overlay_features(&mut scene, dir, request.pca, None)?;
    scene.source = source;
    Ok(scene)
}
