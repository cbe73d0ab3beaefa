//! Rays drawn from the pixels that have a depth target
//! ([`super::SamplerConfig::depth_rays`]): sparse depth, a few hundred
//! pixels an image, is otherwise almost never drawn.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{RayBatch, SamplerConfig, batch_at, interior};
use crate::scene::Scene;

/// The interior pixels of `frames` that may be targets and have a depth
/// target (`(frame, x, y)`, frame by frame, row-major): what
/// [`SamplerConfig::depth_rays`] draws from.
pub fn depth_pixels(scene: &Scene, frames: &[usize], margin: u32) -> Vec<(usize, u32, u32)> {
    let mut out = Vec::new();
    for &fi in frames {
        let Some(frame) = scene.frames.get(fi) else {
            continue;
        };
        let Some(depth) = frame.depth.as_ref() else {
            continue;
        };
        if (depth.width, depth.height) != (frame.rgb.width, frame.rgb.height) {
            continue;
        }
        let ((x0, x1), (y0, y1)) = interior(margin, frame.rgb.width, frame.rgb.height);
        for y in y0..y1 {
            for x in x0..x1 {
                if depth.get(x, y) > 0.0 && frame.is_target_pixel(x, y) {
                    out.push((fi, x, y));
                }
            }
        }
    }
    out
}

/// Batch number `index` of `count` pixels drawn uniformly from `pixels`
/// ([`depth_pixels`] of `frames`), a pure function of `seed` and `index`;
/// empty when `pixels` is.
pub fn sample_listed(
    config: &SamplerConfig,
    seed: u64,
    scene: &Scene,
    frames: &[usize],
    pixels: &[(usize, u32, u32)],
    count: usize,
    index: u64,
) -> RayBatch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let picks: Vec<(usize, u32, u32)> = if pixels.is_empty() {
        Vec::new()
    } else {
        (0..count)
            .map(|_| pixels[rng.random_range(0..pixels.len())])
            .collect()
    };
    batch_at(config, scene, frames, &picks)
}
