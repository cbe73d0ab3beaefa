//! The step tests' shared set-up: a small field and the loop that fits it
//! to a few photographs' rays with real training steps.

use burn::optim::AdamConfig;
use burn::tensor::{Device, Tensor, TensorData};
use model::geometry::NormalizedRay;
use model::{FeatureHeadConfig, GridUse, MipMlpConfig, OpenNerf, OpenNerfConfig};
use train::batch::BatchTensors;
use train::config::LossConfig;
use train::step::{StepRates, StepRender, train_step};

/// A 2 x 32 trunk with IPE degrees 0..4 and 8 samples a level.
pub fn small_field() -> OpenNerfConfig {
    OpenNerfConfig::new(FeatureHeadConfig::new(4).with_width(8))
        .with_mlp(
            MipMlpConfig::new()
                .with_width(32)
                .with_depth(2)
                .with_skip_layer(1)
                .with_max_deg(4),
        )
        .with_num_samples(8)
}

/// Fits `model` to `rays` (ray `i` from photograph `frames[i]`, colour
/// `rgb[3i..3i+3]`) with `steps` training steps of Adam at `rates`, colour
/// loss only, asserting every step applied; returns the mean colour error
/// of the last 50 steps and the model.
pub fn fit(
    mut model: OpenNerf,
    device: &Device,
    rays: Vec<NormalizedRay>,
    frames: Vec<usize>,
    rgb: Vec<f32>,
    rates: StepRates,
    steps: usize,
) -> (f64, OpenNerf) {
    let n = rays.len();
    let batch = BatchTensors {
        rays,
        frames,
        rgb: Tensor::from_data(TensorData::new(rgb, [n, 3]), device),
        rgb_weight: None,
        depth: None,
        feature: None,
    };
    let render = StepRender {
        background: None,
        grid: GridUse::Model,
        progress: 1.0,
        jitter: true,
    };
    let cfg = LossConfig {
        lambda_open: 0.0,
        lambda_depth: 0.0,
        ..LossConfig::default()
    };
    let mut optim = AdamConfig::new().init();
    let mut tail = Vec::new();
    for step in 0..steps {
        let (next, report) = train_step(model, &mut optim, &batch, render, &cfg, rates);
        model = next;
        assert!(report.applied, "step {step} was not applied");
        if step + 50 >= steps {
            tail.push(report.rgb_mse);
        }
    }
    (tail.iter().sum::<f64>() / tail.len() as f64, model)
}
