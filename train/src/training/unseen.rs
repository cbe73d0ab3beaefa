//! The patches a step renders from viewpoints between the training
//! cameras, for the unseen depth smoothness (`--unseen-depth`).

use datasets::Scene;
use datasets::unseen::{PatchLayout, unseen_patch_rays};

use crate::batch::iteration_seed;
use crate::config::TrainConfig;
use crate::step::UnseenPatches;

/// The patches of iteration `it` of a run seeded with `seed`, drawn
/// between the cameras `train` (indices into `scene.frames`), when the
/// unseen depth smoothness is on; `None` when its weight is 0. The same
/// iteration draws the same patches, so a resumed run renders what the
/// uninterrupted one would have.
pub(super) fn patches(
    scene: &Scene,
    train: &[usize],
    config: &TrainConfig,
    seed: u64,
    it: usize,
) -> Option<UnseenPatches> {
    let losses = &config.losses;
    if losses.unseen_depth_weight <= 0.0 {
        return None;
    }
    let layout = PatchLayout {
        patches: losses.unseen_patches,
        side: losses.unseen_patch_side,
        stride: losses.unseen_patch_stride,
    };
    let rays = unseen_patch_rays(
        scene,
        train,
        layout,
        config.sampler.min_near,
        iteration_seed(seed ^ 0x3c6e_f372_fe94_f82b, it),
    );
    Some(UnseenPatches {
        rays,
        side: layout.side,
    })
}
