//! Appearance codes in training steps: the same rays seen in two
//! photographs that agree on half of the rays and differ on the other half
//! (a window lit in one and not the other), a change no gain and offset of
//! the whole photograph makes. Without codes no field does better than the
//! mean of the two on the differing half, an error floor known in closed
//! form; with codes the steps fit both, and the zero code every other view
//! renders with lies between the two photographs.

mod common;

use burn::module::Module;
use burn::tensor::Device;
use common::steps::{fit, small_field};
use model::geometry::NormalizedRay;
use model::{AppearanceCodesConfig, RenderRequest};
use train::step::StepRates;

const RAYS: usize = 16;
const STEPS: usize = 1000;

/// The colour of ray `i` in photograph `p`: the second lights the rays of
/// the upper half.
fn colour(i: usize, p: usize) -> [f32; 3] {
    let t = i as f32 / (RAYS - 1) as f32;
    let base = [0.2 + 0.3 * t, 0.5 - 0.2 * t, 0.3];
    if p == 1 && i >= RAYS / 2 {
        base.map(|c| c + 0.4)
    } else {
        base
    }
}

fn ray(i: usize) -> NormalizedRay {
    NormalizedRay {
        origin: [0.3 * i as f32 / RAYS as f32 - 0.15, 0.0, -2.0],
        direction: [0.0, 0.0, 1.0],
        radius: 0.005,
        near: 0.5,
        far: 3.5,
    }
}

/// Trains a small field on both photographs; returns the mean colour error
/// of the last 50 steps and the colours rendered with the zero code.
fn train(codes: bool) -> (f64, Vec<f32>) {
    let device = Device::flex().autodiff();
    device.seed(7);
    let mut config = small_field();
    config.appearance = codes.then(|| AppearanceCodesConfig::new(2).with_dim(4));
    let model = config.init(&device);
    let rays: Vec<NormalizedRay> = (0..2 * RAYS).map(|i| ray(i % RAYS)).collect();
    let rgb: Vec<f32> = (0..2 * RAYS)
        .flat_map(|i| colour(i % RAYS, i / RAYS))
        .collect();
    let frames = (0..2 * RAYS).map(|i| i / RAYS).collect();
    let rates = StepRates {
        base: 1e-2,
        head: 1e-2,
        pose: 1e-2,
    };
    let (tail, model) = fit(model, &device, rays, frames, rgb, rates, STEPS);
    // Any render but a training photograph's: the zero code.
    let plain: Vec<NormalizedRay> = (0..RAYS).map(ray).collect();
    let out = model.valid().render(
        &RenderRequest::train(&plain)
            .with_randomized(false)
            .with_features(model::FeatureMode::None),
    );
    let zero_code = out
        .fine
        .rgb
        .into_data()
        .try_into_vec_as::<f32>()
        .expect("f32");
    (tail, zero_code)
}

#[test]
fn each_photograph_gets_its_code_and_the_zero_code_renders_between_them() {
    // Rendering the mean of the two on the lit half leaves 0.2^2 per
    // channel there, on half of all rays.
    let floor = 0.5 * 0.2f64.powi(2);
    let (plain, _) = train(false);
    assert!(
        plain > 0.9 * floor,
        "without codes: {plain} below the floor {floor}"
    );
    let (coded, zero) = train(true);
    assert!(coded < 0.1 * floor, "with codes: {coded}, floor {floor}");
    // Where the photographs agree the zero code renders what both saw;
    // where they differ, a colour between the two (the penalty pulls the
    // codes to zero from both sides).
    for i in 0..RAYS {
        for c in 0..3 {
            let (a, b, z) = (colour(i, 0)[c], colour(i, 1)[c], zero[3 * i + c]);
            let (lo, hi) = (a.min(b) - 0.05, a.max(b) + 0.05);
            assert!(
                z > lo && z < hi,
                "ray {i} channel {c}: zero code renders {z}, photographs {a} and {b}"
            );
        }
    }
}
