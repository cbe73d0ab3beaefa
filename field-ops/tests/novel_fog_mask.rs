//! Feature-map cells of a novel view whose render is mostly transparent are
//! cleared, and no sampler ever draws them as feature targets (their rays
//! still train colour and depth).

use datasets::balance::{BalanceConfig, BalancedSampler};
use datasets::sampler::{RayBatch, RaySampler, SamplerConfig};
use datasets::synthetic::{SceneSize, generate};
use datasets::{DepthImage, Scene};
use field_ops::novel::extract::mask_fog_cells;

/// The CI scene with frame 0's left half rendered as fog (no trusted depth)
/// and its map cleared there; returns the scene and the cells cleared.
fn fogged_scene() -> (Scene, usize) {
    let mut scene = generate(5, SceneSize::Ci).expect("scene");
    let (w, h) = (scene.frames[0].rgb.width, scene.frames[0].rgb.height);
    let depth = DepthImage {
        width: w,
        height: h,
        data: datasets::DepthData::F32(
            (0..w * h)
                .map(|i| if i % w < w / 2 { 0.0 } else { 1.5 })
                .collect(),
        ),
    };
    let maps = &mut scene.features.as_mut().expect("maps").maps;
    let cleared = mask_fog_cells(&mut maps[0], &depth);
    (scene, cleared)
}

/// Counts rays of frame 0 on each side, asserting that no ray of the fogged
/// half carries a feature target and that every ray of the other half does.
fn check(batch: &RayBatch, width: u32, counts: &mut [usize; 2]) {
    let mask = batch.feature_mask.as_ref().expect("feature mask");
    let dim = batch.feature_dim;
    let features = batch.features.as_ref().expect("features");
    for (i, p) in batch.pixels.iter().enumerate() {
        if p[0] != 0 {
            continue;
        }
        if p[1] < width / 2 {
            assert_eq!(mask[i], 0.0, "fogged pixel {p:?} drawn as a feature target");
            assert!(features[i * dim..(i + 1) * dim].iter().all(|&v| v == 0.0));
            counts[0] += 1;
        } else {
            assert_eq!(mask[i], 1.0, "clear pixel {p:?} lost its target");
            counts[1] += 1;
        }
    }
}

#[test]
fn fog_cells_are_cleared_at_the_map_resolution() {
    let (scene, cleared) = fogged_scene();
    let map = &scene.features.as_ref().expect("maps").maps[0];
    // 96x54 image, 24x13 map: the left 12 columns of cells lie in the fog.
    assert_eq!((map.width, map.height), (24, 13));
    assert_eq!(cleared, 12 * 13);
    for y in 0..map.height {
        for x in 0..map.width {
            let nan = map.pixel(x, y).iter().all(|v| v.is_nan());
            assert_eq!(nan, x < 12, "cell ({x}, {y})");
        }
    }
    // A cell half in the fog keeps its target (at least half its pixels are
    // opaque); one with fewer opaque pixels loses it.
    let mut one = map.clone();
    let depth = |opaque_cols: u32| DepthImage {
        width: 96,
        height: 54,
        data: datasets::DepthData::F32(
            (0..96 * 54)
                .map(|i| if i % 96 < opaque_cols { 1.0 } else { 0.0 })
                .collect(),
        ),
    };
    assert_eq!(mask_fog_cells(&mut one, &depth(96 - 2)), 0);
    assert_eq!(mask_fog_cells(&mut one, &depth(96 - 3)), 13);
}

#[test]
fn no_sampler_draws_a_fogged_cell_as_a_feature_target() {
    let (scene, _) = fogged_scene();
    let width = scene.frames[0].rgb.width;
    let uniform = SamplerConfig {
        feature_balance: 0.0,
        ..SamplerConfig::default()
    };
    let mut plain = RaySampler::new(uniform, 11).with_frames(vec![0, 1]);
    let mut counts = [0usize; 2];
    for _ in 0..40 {
        check(
            &plain.next_batch(&scene).expect("batch"),
            width,
            &mut counts,
        );
    }
    assert!(counts[0] > 500 && counts[1] > 500, "{counts:?}");

    let config = SamplerConfig::default();
    let balance = BalanceConfig::of(&config).expect("balanced by default");
    let balanced = BalancedSampler::new(&scene, &[0, 1], config.border_margin, &balance, 11)
        .expect("sampler")
        .expect("the scene has maps");
    let mut counts = [0usize; 2];
    for i in 0..40 {
        check(&balanced.batch(&config, 11, &scene, i), width, &mut counts);
    }
    // The fogged half still trains colour and depth.
    assert!(counts[0] > 100 && counts[1] > 100, "{counts:?}");
}
