//! The fast field's coarse-to-fine ramp: its weights against the formula
//! written out level by level, and a field trained with it against the
//! same field whose finer levels are zeroed in the table (an independent
//! way to switch a level off), its finer levels' rows receiving no
//! gradient at the start, and every level once the ramp is done.

mod common;

use burn::module::Param;
use burn::tensor::{Device, Tensor};
use common::{camera_rays, vec};
use model::level_ramp::{ramp_done, ramp_start_levels, ramp_weights};
use model::{FastFieldConfig, FeatureHeadConfig, HashGridConfig, OpenNerf, RenderRequest};

#[test]
fn a_quarter_of_the_levels_start_and_the_rest_come_in_one_by_one() {
    assert_eq!(
        [1, 4, 5, 8, 16].map(ramp_start_levels),
        [1, 1, 2, 2, 4],
        "a quarter, rounded up"
    );
    assert_eq!(ramp_weights(8, 0.0, 0.5), [1., 1., 0., 0., 0., 0., 0., 0.]);
    // Halfway through the ramp, 2 + 6 / 2 = 5 levels are on.
    assert_eq!(ramp_weights(8, 0.25, 0.5), [1., 1., 1., 1., 1., 0., 0., 0.]);
    // A level comes in linearly: at a = 2 + 6 * 0.55 = 5.3, level 5 is 0.3 in.
    let w = ramp_weights(8, 0.275, 0.5);
    assert!(
        (w[5] - 0.3).abs() < 1e-5 && w[6] == 0.0 && w[4] == 1.0,
        "{w:?}"
    );
    for (progress, until) in [(0.5, 0.5), (0.9, 0.5), (0.0, 0.0), (0.3, -1.0)] {
        assert!(ramp_done(progress, until));
        assert_eq!(ramp_weights(16, progress, until), vec![1.0; 16]);
    }
    assert!(!ramp_done(0.49, 0.5));
}

/// Every level's weight never falls as training goes on, and their sum is
/// the number of levels on, `s + (L - s) p / u`.
#[test]
fn the_weights_grow_with_progress_and_sum_to_the_levels_on() {
    let (levels, until) = (16, 0.4);
    let mut last = ramp_weights(levels, 0.0, until);
    for step in 1..=100 {
        let progress = step as f32 / 200.0;
        let w = ramp_weights(levels, progress, until);
        assert!(w.iter().zip(&last).all(|(now, before)| now >= before));
        let on = (4.0 + 12.0 * (progress / until).min(1.0)) as f64;
        let sum: f64 = w.iter().map(|&x| x as f64).sum();
        assert!(
            (sum - on).abs() < 1e-4,
            "progress {progress}: {sum} vs {on}"
        );
        last = w;
    }
}

fn ramped(until: Option<f32>) -> model::OpenNerfConfig {
    let grid = HashGridConfig::new()
        .with_levels(8)
        .with_log2_table(10)
        .with_base_resolution(4)
        .with_max_resolution(64);
    let fast = FastFieldConfig::new()
        .with_grid(grid)
        .with_density_width(16)
        .with_geo_features(7)
        .with_color_width(16)
        .with_coarse_to_fine(until);
    model::OpenNerfConfig::new(FeatureHeadConfig::new(5).with_width(8))
        .with_fast(Some(fast))
        .with_num_samples(8)
}

/// `m` with the coarse-to-fine ramp of `until` (0: none) and this table:
/// the fields compared below are one field's copies, so that only the
/// table and the ramp tell them apart.
fn with_table(m: &OpenNerf, until: f32, table: &Tensor<2>) -> OpenNerf {
    let mut m = m.clone();
    let fast = m.fast.as_mut().expect("the fast field");
    fast.grid.table = Param::from_tensor(table.clone());
    fast.coarse_to_fine = until;
    m
}

fn colour(m: &OpenNerf, progress: f32) -> Vec<f32> {
    let rays = camera_rays(6, 5);
    let out = m.render(
        &RenderRequest::train(&rays)
            .with_randomized(false)
            .with_progress(progress),
    );
    vec(out.fine.rgb)
}

#[test]
fn at_the_start_the_finer_levels_are_as_if_zero_and_after_the_ramp_all_are_on() {
    let device = Device::flex();
    device.seed(3);
    let table = Tensor::<2>::random(
        [8 << 10, 2],
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        &device,
    );
    let field = ramped(Some(0.5)).init(&device);
    assert_eq!(field.fast.as_ref().map(|f| f.coarse_to_fine), Some(0.5));
    let ramp = with_table(&field, 0.5, &table);
    // The first two levels (a quarter of 8) kept, the rows of the six
    // finer ones zeroed: their trilinear sums are zero.
    let mut rows = vec(table.clone());
    rows[(2 << 10) * 2..].fill(0.0);
    let coarse_only = with_table(
        &field,
        0.0,
        &Tensor::from_data(burn::tensor::TensorData::new(rows, [8 << 10, 2]), &device),
    );
    assert_eq!(colour(&ramp, 0.0), colour(&coarse_only, 0.0));
    let plain = with_table(&field, 0.0, &table);
    assert_eq!(colour(&ramp, 0.5), colour(&plain, 0.5));
    assert_eq!(colour(&ramp, 1.0), colour(&plain, 1.0));
    assert_ne!(colour(&ramp, 0.25), colour(&plain, 0.25));
}

/// At the start, the rows of the levels not yet in get no gradient; the
/// coarse levels' rows do.
#[test]
fn the_levels_not_yet_in_get_no_gradient() {
    let device: Device = Device::flex().autodiff();
    device.seed(8);
    let table = Tensor::<2>::random(
        [8 << 10, 2],
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        &device,
    );
    let m = with_table(&ramped(Some(0.5)).init(&device), 0.5, &table);
    let rays = camera_rays(6, 2);
    let out = m.render(
        &RenderRequest::train(&rays)
            .with_randomized(false)
            .with_progress(0.0),
    );
    let grads = out.fine.rgb.sum().backward();
    let fast = m.fast.as_ref().expect("fast");
    let g = vec(fast.grid.table.val().grad(&grads).expect("a gradient"));
    let split = (2 << 10) * 2;
    assert!(
        g[..split].iter().any(|&x| x != 0.0),
        "the coarse levels learn"
    );
    assert!(
        g[split..].iter().all(|&x| x == 0.0),
        "the finer levels wait"
    );
}
