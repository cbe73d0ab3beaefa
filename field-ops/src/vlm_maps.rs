//! Feature maps of a scene's frames made by a CLIP vision tower, written as
//! `<frame name>.npy` (f16, `rows x cols x D`) with a stamp saying what made
//! them, so that a later run with the same model, variant, size and frames
//! reuses them instead of extracting again.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clip::vision::{DenseOptions, VisionModel};
use datasets::Scene;
use datasets::extractor::FeatureExtractor;
use datasets::npy::write_npy_f16;
use serde::{Deserialize, Serialize};

use crate::error::OpsError;

/// The value parser of a `--dense` flag (`train --vlm`, `eval extract`,
/// `bench-vlm`): one of the [`DenseVariant`](clip::DenseVariant)
/// names, listed with what each does in `--help` and by clap when a value
/// is not one of them.
pub fn dense_variant_parser() -> impl clap::builder::TypedValueParser<Value = clip::DenseVariant> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    use clip::DenseVariant;
    let help = |v: DenseVariant| match v {
        DenseVariant::Naclip => "key-key attention plus a Gaussian window over the patches",
        DenseVariant::Clearclip => "query-query attention",
        DenseVariant::Maskclip => "each token's value, no attention across tokens",
    };
    PossibleValuesParser::new(DenseVariant::ALL.map(|v| PossibleValue::new(v.name()).help(help(v))))
        .map(|name| {
            DenseVariant::ALL
                .into_iter()
                .find(|v| v.name() == name)
                .expect("clap accepts only the variants' names")
        })
}

/// The stamp written next to the maps.
pub const STAMP: &str = "vlm_features.json";

/// What a directory of maps was made from; maps are reused only when all agree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stamp {
    /// The model directory (canonical path).
    pub model: PathBuf,
    /// SHA-256 of its weights file.
    pub weights_sha256: String,
    /// The dense variant.
    pub dense: clip::DenseVariant,
    /// Short side in pixels.
    pub short_side: usize,
    /// Channels.
    pub dim: usize,
    /// Frame names, in order.
    pub frames: Vec<String>,
}

impl Stamp {
    /// The stamp of `scene`'s maps by `model` with `options`.
    pub fn of(
        scene: &Scene,
        model: &VisionModel,
        options: &DenseOptions,
    ) -> Result<Self, OpsError> {
        let invalid = |e: String| OpsError::Invalid(format!("--vlm {}: {e}", model.dir.display()));
        Ok(Self {
            model: std::fs::canonicalize(&model.dir).map_err(|e| invalid(e.to_string()))?,
            weights_sha256: clip::cache::hash_file(&model.weights)
                .map_err(|e| invalid(e.to_string()))?,
            dense: options.variant,
            short_side: model.short_side(options),
            dim: model.dim(),
            frames: scene.frames.iter().map(|f| f.name.clone()).collect(),
        })
    }

    /// Whether `dir` holds every map this stamp describes, made by it.
    pub fn matches(&self, dir: &Path) -> bool {
        std::fs::read_to_string(dir.join(STAMP))
            .ok()
            .and_then(|t| serde_json::from_str::<Stamp>(&t).ok())
            .is_some_and(|s| &s == self)
            && self
                .frames
                .iter()
                .all(|n| dir.join(format!("{n}.npy")).is_file())
    }
}

/// Makes the maps of every frame of `scene` in `dir` unless `dir` already
/// holds them from the same model and options; returns whether they were
/// reused. Each map is written as it is made; the stamp last.
pub fn ensure_maps(
    scene: &Scene,
    model: &Arc<VisionModel>,
    options: &DenseOptions,
    dir: &Path,
) -> Result<bool, OpsError> {
    let stamp = Stamp::of(scene, model, options)?;
    if stamp.matches(dir) {
        eprintln!(
            "--vlm: reusing the {} feature maps in {}",
            scene.frames.len(),
            dir.display()
        );
        return Ok(true);
    }
    let stamp_path = dir.join(STAMP);
    let _ = std::fs::remove_file(&stamp_path);
    let options = DenseOptions {
        short_side: Some(stamp.short_side),
        ..*options
    };
    if let Some(f) = scene.frames.first() {
        let plan = model
            .plan((f.rgb.height as usize, f.rgb.width as usize), &options)
            .map_err(|e| {
                OpsError::Invalid(format!(
                    "--vlm {}: frame {}: {e}",
                    model.dir.display(),
                    f.name
                ))
            })?;
        eprintln!(
            "--vlm: {} features of {} frames ({} windows each, {}x{} patches, {} dims) into {}",
            options.variant,
            scene.frames.len(),
            plan.origins.len(),
            plan.grid.1,
            plan.grid.0,
            model.dim(),
            dir.display()
        );
    }
    // Created only once the first frame's windows are known to fit.
    std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
    let extractor = clip::ClipExtractor::new(model.clone(), options);
    let bar = crate::progress::progress(scene.frames.len(), "extracting features");
    for frame in &scene.frames {
        let map = extractor
            .extract(&frame.rgb)
            .map_err(|e| OpsError::Invalid(format!("--vlm on frame {}: {e}", frame.name)))?;
        let path = dir.join(format!("{}.npy", frame.name));
        write_npy_f16(
            &path,
            &[map.height as usize, map.width as usize, map.dim],
            &map.data,
        )?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let text =
        serde_json::to_string_pretty(&stamp).map_err(|e| OpsError::Invalid(e.to_string()))?;
    std::fs::write(&stamp_path, text).map_err(|e| OpsError::io(&stamp_path, e))?;
    Ok(false)
}
