//! The weights of the loss terms: the `losses` section of a run's
//! `config.json`.

use serde::{Deserialize, Serialize};

/// Weights of the loss terms (README, "How the feature field is trained").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LossConfig {
    /// Weight of the open-set cosine loss.
    pub lambda_open: f32,
    /// Weight of the depth Huber loss (0 = off).
    pub lambda_depth: f32,
    /// Weight of the coarse level's colour and depth terms.
    pub coarse_weight: f32,
    /// Huber threshold in metres.
    pub huber_delta: f32,
    /// With the proposal sampler, how far past its target an interval's
    /// midpoint counts in the depth loss, in multiples of the target
    /// (`model::capped_depth`; at least 1). The sampler pins each round's
    /// last post at the ray's far end: uncapped, an unbounded ray's last
    /// interval made the step diverge. Higher pulls the far weight in
    /// harder. The coarse and fine levels' depth is never capped.
    pub depth_cap: f32,
    /// Weight of the interlevel loss that trains the proposal sampler
    /// (Mip-NeRF 360: 1).
    pub interlevel_weight: f32,
    /// Weight of the compositing weight that lies away from each ray's depth
    /// target (`model::depth_window`; 0: off), beside the expected depth's
    /// Huber loss: the weight at the surface rather than spread around it.
    pub depth_window_weight: f32,
    /// Half-width of that window, as a fraction of the target depth.
    pub depth_window_width: f32,
    /// Weight of the distortion loss on the fine level, in `s`
    /// (Mip-NeRF 360: 0.01).
    pub distortion_weight: f32,
    /// Weight of the distortion loss on the box field's fine level, in `t`
    /// mapped linearly onto `[0, 1]` from the first to the last post of
    /// each ray (0: off). It gathers each ray's weight into a short
    /// interval, against the fog a field fits few views with.
    pub box_distortion_weight: f32,
    /// Weight of the penalty on the learned exposure corrections' squares
    /// (see `model::exposure`), which holds the field at the photographs'
    /// common exposure.
    pub exposure_penalty: f32,
    /// Weight of the penalty on the learned pose corrections' squares
    /// (see `model::pose`: rotation in radians, shift in normalised units),
    /// which holds the cameras near their given poses.
    pub pose_penalty: f32,
    /// Weight of the penalty on the appearance codes' squares (see
    /// `model::appearance`), which keeps the zero code, the one every
    /// render uses, at the photographs' common appearance.
    pub appearance_penalty: f32,
    /// Weight of the depth smoothness of patches rendered from viewpoints
    /// between the training cameras (RegNeRF's geometry regulariser; 0:
    /// off, no patches are rendered).
    pub unseen_depth_weight: f32,
    /// Patches a step renders for it, each from its own viewpoint.
    pub unseen_patches: usize,
    /// Rays along each side of a patch.
    pub unseen_patch_side: usize,
    /// Pixels between neighbouring rays of a patch.
    pub unseen_patch_stride: usize,
}

impl Default for LossConfig {
    fn default() -> Self {
        Self {
            lambda_open: 1.0,
            lambda_depth: 0.1,
            coarse_weight: 0.1,
            huber_delta: 0.2,
            depth_cap: 2.0,
            interlevel_weight: 1.0,
            depth_window_weight: 0.0,
            depth_window_width: 0.05,
            distortion_weight: 0.01,
            box_distortion_weight: 0.0,
            exposure_penalty: 1e-3,
            pose_penalty: 1e-2,
            appearance_penalty: 1e-3,
            unseen_depth_weight: 0.0,
            unseen_patches: 4,
            unseen_patch_side: 8,
            unseen_patch_stride: 4,
        }
    }
}
