//! Whether a COLMAP capture's sparse points supervise the field's depth
//! (`--sparse-depth`, see `datasets::colmap::sparse_depth`): under `on`, a
//! quarter of each batch is drawn from them; `auto` leaves them out, as
//! measured on real captures (docs/measurements/real-capture-defaults.md).

use datasets::options::LoaderOptions;
use datasets::{Scene, SceneSource};

use super::args::SparseDepthArg;
use crate::config::TrainConfig;
use crate::error::TrainError;

/// The share of each batch drawn from the pixels with a sparse depth
/// target: 64 of 256 rays, the measured setting (docs/measurements/unbounded.md).
pub const SPARSE_DEPTH_SHARE: usize = 4;

/// Why `auto` leaves the sparse points out.
pub const AUTO_OFF_WHY: &str = "auto: at 600 s they lifted one of the two COLMAP captures \
     measured and lowered the other (docs/measurements/real-capture-defaults.md)";

/// Whether the loader makes sparse depth targets: a COLMAP capture under
/// `on` (`auto` and `off` leave them out). Errors for `on` with
/// `--colmap-depth`.
pub fn loader_flag(arg: Option<SparseDepthArg>, colmap_depth: bool) -> Result<bool, TrainError> {
    match arg.unwrap_or_default() {
        SparseDepthArg::On if colmap_depth => Err(TrainError::Config(
            "--sparse-depth on and --colmap-depth both give depth targets; choose one".into(),
        )),
        SparseDepthArg::On => Ok(true),
        SparseDepthArg::Auto | SparseDepthArg::Off => Ok(false),
    }
}

/// The pixels with a sparse depth target in a loaded scene, and the
/// photographs they are in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SparseDepthChoice {
    /// Pixels with a target, over every frame.
    pub pixels: usize,
    /// Frames with at least one.
    pub frames: usize,
    /// Rays of each batch drawn from those pixels.
    pub rays: usize,
    /// Rays of each batch.
    pub batch: usize,
}

impl SparseDepthChoice {
    /// The one-line message `train` prints.
    pub fn message(&self) -> String {
        format!(
            "depth: the sparse points give depth targets at {} pixels of {} photographs; {} of \
             the {} rays of each batch are drawn from those of the training photographs \
             (sampler.depth_rays) (--sparse-depth on)",
            self.pixels, self.frames, self.rays, self.batch
        )
    }
}

/// What the loaded `scene` gives to batches of `rays`: `None` when its
/// loader made no sparse depth (another format, `auto`, `off`, dense depth).
/// `depth_rays` of them are drawn from the targets when given (a
/// `--config` file's), else a quarter ([`SPARSE_DEPTH_SHARE`], at least
/// one when the batch has two rays or more). Errors
/// for `on` when no image observes a point (an empty `points3D`).
pub fn choose(
    arg: Option<SparseDepthArg>,
    scene: &Scene,
    rays: usize,
    depth_rays: usize,
) -> Result<Option<SparseDepthChoice>, TrainError> {
    let sparse = matches!(
        scene.source.base(),
        SceneSource::Disk { loader: LoaderOptions::Colmap(o), .. } if o.sparse_depth && !o.depth
    );
    if !sparse {
        return Ok(None);
    }
    let counts: Vec<usize> = scene
        .frames
        .iter()
        .filter_map(|f| f.depth.as_ref())
        .map(|d| (0..d.len()).filter(|&i| d.value(i) > 0.0).count())
        .filter(|&n| n > 0)
        .collect();
    if counts.is_empty() {
        return if arg == Some(SparseDepthArg::On) {
            Err(TrainError::Config(format!(
                "--sparse-depth on: no image of {} observes a sparse point (its points3D is \
                 empty or no feature is linked to a point); leave --sparse-depth out",
                scene.name
            )))
        } else {
            Ok(None)
        };
    }
    // At least one, and one ray of each batch left to draw from every
    // pixel (none of a batch of one).
    let batch = rays;
    let rays = if depth_rays > 0 {
        depth_rays
    } else {
        (batch / SPARSE_DEPTH_SHARE)
            .max(1)
            .min(batch.saturating_sub(1))
    };
    Ok(Some(SparseDepthChoice {
        pixels: counts.iter().sum(),
        frames: counts.len(),
        rays,
        batch,
    }))
}

/// Draws part of each batch of `config` from the sparse depth targets
/// when `scene` has them (see [`choose`]), and returns the line that says
/// so; under `auto`, on a COLMAP capture without dense depth, the line
/// that says they are left out.
pub fn apply(
    arg: Option<SparseDepthArg>,
    scene: &Scene,
    config: &mut TrainConfig,
) -> Result<Option<String>, TrainError> {
    let sampler = &mut config.sampler;
    if let Some(s) = choose(arg, scene, sampler.rays_per_batch, sampler.depth_rays)? {
        sampler.depth_rays = s.rays;
        return Ok(Some(s.message()));
    }
    let colmap_without_depth = matches!(
        scene.source.base(),
        SceneSource::Disk { loader: LoaderOptions::Colmap(o), .. } if !o.depth
    );
    let auto = matches!(arg, None | Some(SparseDepthArg::Auto));
    Ok((auto && colmap_without_depth).then(|| {
        format!(
            "depth: none from the sparse points ({AUTO_OFF_WHY}; --sparse-depth on draws a \
             quarter of each batch from them)"
        )
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_with_dense_depth_is_refused_and_auto_yields_to_it() {
        assert!(loader_flag(Some(SparseDepthArg::On), true).is_err());
        assert_eq!(
            loader_flag(Some(SparseDepthArg::On), false).ok(),
            Some(true)
        );
        assert_eq!(loader_flag(None, false).ok(), Some(false));
        assert_eq!(
            loader_flag(Some(SparseDepthArg::Auto), false).ok(),
            Some(false)
        );
        assert_eq!(
            loader_flag(Some(SparseDepthArg::Auto), true).ok(),
            Some(false)
        );
        assert_eq!(
            loader_flag(Some(SparseDepthArg::Off), false).ok(),
            Some(false)
        );
    }
}
