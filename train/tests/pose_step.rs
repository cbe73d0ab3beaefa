//! Pose refinement in training steps: two photographs of one pattern, the
//! second given with its camera shifted sideways. Without refinement no
//! field fits both (the same colour is asked at two places, an error floor
//! known in closed form); with it the steps learn the shift between the
//! two cameras and fit both.

mod common;

use burn::tensor::Device;
use common::steps::{fit, small_field};
use model::PoseCorrectionConfig;
use model::geometry::NormalizedRay;
use train::step::StepRates;

const RAYS: usize = 16;
const STEPS: usize = 800;
/// The second camera's error: its rays are given this far along x from
/// where they were taken.
const SHIFT: f32 = 0.1;
/// The pattern's slope along x, per channel.
const SLOPE: [f32; 3] = [2.0, -1.5, 1.0];

fn x(i: usize) -> f32 {
    0.3 * i as f32 / (RAYS - 1) as f32 - 0.15
}

/// The colour seen along x (a ramp per channel, which a shift changes
/// everywhere by `SLOPE * shift`).
fn colour(x: f32) -> [f32; 3] {
    [0.5 + SLOPE[0] * x, 0.5 + SLOPE[1] * x, 0.5 + SLOPE[2] * x]
}

/// Trains a small field on both photographs; returns the mean colour error
/// of the last 50 steps and the learned corrections (`[2, 6]`, flattened).
fn train(refine: bool) -> (f64, Option<Vec<f32>>) {
    let device = Device::flex().autodiff();
    device.seed(6);
    let mut config = small_field();
    config.pose = refine.then(|| PoseCorrectionConfig::new(2));
    let model = config.init(&device);
    let ray = |x: f32| NormalizedRay {
        origin: [x, 0.0, -2.0],
        direction: [0.0, 0.0, 1.0],
        radius: 0.005,
        near: 0.5,
        far: 3.5,
    };
    // Photograph 0 as taken; photograph 1's rays given SHIFT off.
    let rays: Vec<NormalizedRay> = (0..2 * RAYS)
        .map(|i| ray(x(i % RAYS) + if i < RAYS { 0.0 } else { SHIFT }))
        .collect();
    let rgb: Vec<f32> = (0..2 * RAYS).flat_map(|i| colour(x(i % RAYS))).collect();
    let frames = (0..2 * RAYS).map(|i| i / RAYS).collect();
    let rates = StepRates {
        base: 1e-2,
        head: 1e-2,
        pose: 3e-3,
    };
    let (tail, model) = fit(model, &device, rays, frames, rgb, rates, STEPS);
    let corrections = model
        .pose
        .as_ref()
        .map(|p| p.params.val().try_into_vec_as::<f32>().expect("f32"));
    (tail, corrections)
}

#[test]
fn the_shift_between_two_cameras_is_learned_and_both_are_fitted() {
    // Where the two photographs overlap, one place is asked for two colours
    // SLOPE * SHIFT apart: the best field renders their mean, leaving
    // (SLOPE * SHIFT / 2)^2 per channel on every overlapping ray.
    let overlap = (0..RAYS).filter(|&i| x(i) + SHIFT <= x(RAYS - 1)).count();
    let floor = SLOPE
        .iter()
        .map(|s| ((s * SHIFT / 2.0) as f64).powi(2))
        .sum::<f64>()
        / 3.0
        * (2 * overlap) as f64
        / (2 * RAYS) as f64;
    let (plain, none) = train(false);
    assert!(none.is_none());
    assert!(
        plain > 0.5 * floor,
        "without refinement: {plain}, below half the floor {floor}"
    );
    let (refined, corrections) = train(true);
    let c = corrections.expect("corrections");
    assert!(
        refined < 0.1 * floor,
        "with refinement: {refined}, floor {floor}, corrections {c:?}"
    );
    // The second camera's rays move back by the shift relative to the
    // first's at some depth along them: a shift of the camera and a turn of
    // its rays trade off against where the field puts the pattern, so the
    // displacement between the corrected rays, `dt + dw_y t` along x at
    // parameter `t`, must reach -SHIFT within the rays' range (only the
    // difference of the two photographs' corrections is fixed by them).
    let (w0, t0, w1, t1) = (&c[0..3], &c[3..6], &c[6..9], &c[9..12]);
    let along_x = |t: f32| (t1[0] - t0[0]) + (w1[1] - w0[1]) * t;
    let reaches = (0..=30)
        .map(|k| 0.5 + 0.1 * k as f32)
        .any(|t| (along_x(t) + SHIFT).abs() < 0.1 * SHIFT);
    assert!(
        reaches,
        "displacement {} at the near bound, {} at the far bound, want {}; corrections {c:?}",
        along_x(0.5),
        along_x(3.5),
        -SHIFT
    );
    // Nothing asks for a move along y.
    assert!((t1[1] - t0[1]).abs() < 0.3 * SHIFT, "{c:?}");
}
