//! A training step with unseen patches behind an occupancy grid: the grid
//! drops batch rays that cross no occupied cell, but every patch ray is
//! rendered, so the regulariser the step adds is the depth smoothness of
//! whole patches.

use burn::optim::AdamConfig;
use burn::tensor::{Device, Tensor, TensorData};
use model::geometry::NormalizedRay;
use model::{
    FeatureMode, GridUse, OccupancyConfig, OccupancyGrid, OpenNerf, RenderRequest, depth_smoothness,
};
use train::TrainConfig;
use train::batch::BatchTensors;
use train::config::LossConfig;
use train::step::{StepRates, StepRender, UnseenPatches, train_step_regularised};

/// A small field behind a grid of 2 x 2 x 2 cells whose half at x > 0 is
/// occupied.
fn field_behind_half_grid(device: &Device) -> OpenNerf {
    device.seed(5);
    let model = TrainConfig::tiny(4).model.init(device);
    let config = OccupancyConfig::new()
        .with_resolution(2)
        .with_early_updates(0);
    let mut grid = OccupancyGrid::new(&config);
    // Cell (i, j, k) is index (k * 2 + j) * 2 + i: occupied where i = 1.
    let density: Vec<f32> = (0..8)
        .map(|c| if c % 2 == 1 { 100.0 } else { 0.0 })
        .collect();
    grid.update(&density);
    model.with_occupancy(Some(grid))
}

fn ray(x: f32) -> NormalizedRay {
    NormalizedRay {
        origin: [x, 0.3, -2.0],
        direction: [0.0, 0.05, 1.0],
        radius: 0.01,
        near: 0.5,
        far: 3.5,
    }
}

fn batch(device: &Device) -> BatchTensors {
    let xs = [-1.5, -0.5, 0.5, 1.0, 1.5, 2.0];
    let n = xs.len();
    BatchTensors {
        rays: xs.iter().map(|&x| ray(x)).collect(),
        frames: vec![0; n],
        rgb: Tensor::from_data(TensorData::new(vec![0.5f32; n * 3], [n, 3]), device),
        rgb_weight: None,
        depth: None,
        feature: None,
    }
}

#[test]
fn patches_behind_a_grid_stay_whole() {
    let device = Device::flex().autodiff();
    let model = field_behind_half_grid(&device);
    // Two patches of 2 x 2; the first ray of the first lies in the free half.
    let patches = UnseenPatches {
        rays: [-1.0, 0.6, 0.8, 1.0, 0.4, 0.7, 1.1, 1.3]
            .iter()
            .map(|&x| ray(x))
            .collect(),
        side: 2,
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
        unseen_depth_weight: 1.0,
        ..LossConfig::default()
    };
    let rates = StepRates {
        base: 1e-3,
        head: 1e-3,
        pose: 1e-3,
    };
    let step = |unseen: Option<&UnseenPatches>| {
        let mut optim = AdamConfig::new().init();
        device.seed(9);
        let (_, report) = train_step_regularised(
            model.clone(),
            &mut optim,
            &batch(&device),
            unseen,
            render,
            &cfg,
            rates,
        );
        assert!(report.applied, "the step applies");
        let clip = report.clip.expect("the grid clipped the batch");
        assert!(
            clip.kept < clip.drawn,
            "the grid drops batch rays: {clip:?}"
        );
        report.loss
    };
    // The first render after the field is built draws differently from
    // the same seed; every compared render comes after it.
    let _ = step(None);
    let without = step(None);
    let added = step(Some(&patches)) - without;
    // The same draws: the batch first, then every patch ray, none dropped.
    device.seed(9);
    let _ = model.render(
        &RenderRequest::train(&batch(&device).rays)
            .with_features(FeatureMode::None)
            .with_grid(GridUse::Model),
    );
    let whole = model.render(
        &RenderRequest::train(&patches.rays)
            .with_features(FeatureMode::None)
            .with_grid(GridUse::KeepEmpty),
    );
    assert!(whole.kept.is_none(), "every patch ray rendered");
    let want: f32 = depth_smoothness(whole.fine.depth, 2)
        .into_data()
        .try_to_vec::<f32>()
        .expect("f32")[0];
    assert!(want > 0.0, "the patches' depth is not flat: {want}");
    assert!(
        (added as f32 - want).abs() <= 1e-5 + 1e-3 * want,
        "the step added {added}, the whole patches' smoothness is {want}"
    );
}
