//! The learned exposure in training steps: the same rays seen in two
//! photographs, the second at half the brightness of the first. Without
//! exposure no field can do better than render their mean, an error floor
//! known in closed form; with it the steps learn how one photograph's
//! colours map to the other's (halved, per channel) and fit both.

mod common;

use burn::tensor::Device;
use common::steps::{fit, small_field};
use model::ExposureConfig;
use model::geometry::NormalizedRay;
use train::step::StepRates;

const RAYS: usize = 16;
const STEPS: usize = 1000;

/// The colour of ray `i` in the brighter photograph: every channel varies
/// over the rays, so that a gain and an offset can be told apart.
fn colour(i: usize) -> [f32; 3] {
    let t = i as f32 / (RAYS - 1) as f32;
    let u = ((i * 7) % RAYS) as f32 / (RAYS - 1) as f32;
    [0.2 + 0.6 * t, 0.8 - 0.5 * t, 0.3 + 0.4 * u]
}

/// Trains a small field on both photographs; returns the mean colour error
/// of the last 50 steps and the learned corrections (`[2, 6]`, flattened).
fn train(exposure: bool) -> (f64, Option<Vec<f32>>) {
    let device = Device::flex().autodiff();
    device.seed(5);
    let mut config = small_field();
    config.exposure = exposure.then(|| ExposureConfig::new(2));
    let model = config.init(&device);
    let ray = |i: usize| NormalizedRay {
        origin: [0.3 * i as f32 / RAYS as f32 - 0.15, 0.0, -2.0],
        direction: [0.0, 0.0, 1.0],
        radius: 0.005,
        near: 0.5,
        far: 3.5,
    };
    let rays: Vec<NormalizedRay> = (0..2 * RAYS).map(|i| ray(i % RAYS)).collect();
    let rgb: Vec<f32> = (0..2 * RAYS)
        .flat_map(|i| {
            let scale = if i < RAYS { 1.0 } else { 0.5 };
            colour(i % RAYS).map(|c| c * scale)
        })
        .collect();
    let frames = (0..2 * RAYS).map(|i| i / RAYS).collect();
    let rates = StepRates {
        base: 1e-2,
        head: 1e-2,
        pose: 1e-2,
    };
    let (tail, model) = fit(model, &device, rays, frames, rgb, rates, STEPS);
    let corrections = model
        .exposure
        .as_ref()
        .map(|e| e.params.val().try_into_vec_as::<f32>().expect("f32"));
    (tail, corrections)
}

#[test]
fn the_exposure_of_each_photograph_is_learned_and_the_rest_is_fitted() {
    // Rendering the mean of c and c/2 leaves (c/4)^2 per channel.
    let floor = (0..RAYS)
        .flat_map(colour)
        .map(|c| (0.25 * c as f64).powi(2))
        .sum::<f64>()
        / (3 * RAYS) as f64;
    let (plain, none) = train(false);
    assert!(none.is_none());
    assert!(
        plain > 0.9 * floor,
        "without exposure: {plain} below the floor {floor}"
    );
    let (exposed, corrections) = train(true);
    let c = corrections.expect("corrections");
    assert!(
        exposed < 0.1 * floor,
        "with exposure: {exposed}, floor {floor}, corrections {c:?}"
    );
    // The two photographs' corrections map each colour seen in the first to
    // the one the second saw: half of it. (A gain and an offset per
    // photograph leave one degree of freedom that the field absorbs, so the
    // mapping is fixed, not each number; without corrections the mapping
    // is the identity, off by half of each colour.)
    for channel in 0..3 {
        let (g0, b0, g1, b1) = (c[channel], c[3 + channel], c[6 + channel], c[9 + channel]);
        let errors: Vec<f32> = (0..RAYS)
            .map(|i| {
                let x = colour(i)[channel];
                ((x - b0) * (g1 - g0).exp() + b1 - 0.5 * x).abs()
            })
            .collect();
        let mean = errors.iter().sum::<f32>() / RAYS as f32;
        let max = errors.iter().fold(0.0f32, |a, &e| a.max(e));
        assert!(
            mean < 0.02 && max < 0.04,
            "channel {channel}: mapping off by {mean} on average, {max} at most; corrections {c:?}"
        );
    }
}
