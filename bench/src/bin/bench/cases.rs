//! The benchmark's cases: one training-step timing each, with inference
//! on the trained model, and the rays and grid they use.

use std::time::Instant;

use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};
use model::geometry::NormalizedRay;
use model::{
    FeatureHeadConfig, FeatureMode, MipMlpConfig, OccupancyConfig, OccupancyGrid, OpenNerf,
    OpenNerfConfig, ProposalConfig, RenderRequest, Termination,
};
use train::batch::{BatchTensors, FeatureTargets};
use train::config::LossConfig;
use train::config::{fast_field, fast_proposal};
use train::step::{StepRates, train_step_from_deferred};

use crate::Size;

/// The cases `--cases` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CaseName {
    /// Composited hidden activations with the top-k head.
    Composited,
    /// The per-sample head (the plain formulation, JAX's).
    Plain,
    /// Composited + top-k behind the occupancy grid.
    Grid,
    /// Composited + top-k with the proposal sampler (two rounds of 64
    /// samples of the proposal MLP, then the MLP's samples).
    Proposal,
    /// The fast field (`train --field-model fast`'s) in place of the MLP,
    /// composited + top-k, the coarse and the fine level.
    Fast,
    /// The fast field with its hash-grid proposal networks (`train
    /// --field-model fast`'s on a room: rounds of 64 and 32).
    FastProposal,
}

/// Rays of the bench: `n` rays through the box from a plane in front of it.
pub fn rays(n: usize, seed: u64) -> Vec<NormalizedRay> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as f64 / (1u64 << 31) as f64) as f32
    };
    let v: Vec<NormalizedRay> = (0..n)
        .map(|_| NormalizedRay {
            origin: [next() * 2.0 - 1.0, next() * 2.0 - 1.0, -2.5],
            direction: [next() - 0.5, next() - 0.5, 1.0],
            radius: 0.003,
            near: 0.2,
            far: 4.5,
        })
        .collect();
    v
}

/// A grid holding a ball of radius 1.2 at the centre of the box (an object
/// in empty space, as in the Blender scenes).
pub fn object_grid() -> OccupancyGrid {
    // One sample a cell, no early updates and no dilation (a training run's
    // grid is more conservative): a fixed ball, the same case in every run.
    let config = OccupancyConfig::new()
        .with_early_updates(0)
        .with_dilation(0);
    let mut grid = OccupancyGrid::new(&config);
    let density: Vec<f32> = grid
        .sample_points(0)
        .iter()
        .map(|p| {
            let r2: f32 = p.iter().map(|v| v * v).sum();
            if r2 < 1.44 { 100.0 } else { 0.0 }
        })
        .collect();
    grid.update(&density);
    grid
}

/// One case: a feature path, the head's top-k, with or without the grid.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    pub label: &'static str,
    pub path: FeatureMode,
    pub top_k: usize,
    pub with_grid: bool,
    /// The proposal sampler instead of the coarse and the fine level.
    pub proposal: bool,
    /// The fast field in place of the Mip-NeRF MLP.
    pub fast: bool,
}

impl Case {
    /// The field's configuration in this case: `mlp`, or the fast field
    /// `train` builds; its proposal sampler as `train` builds it.
    pub fn config(&self, mlp: &MipMlpConfig, size: crate::Size) -> OpenNerfConfig {
        let proposal = match (self.proposal, self.fast) {
            (false, _) => None,
            (true, false) => Some(ProposalConfig::new()),
            (true, true) => Some(fast_proposal()),
        };
        OpenNerfConfig::new(FeatureHeadConfig::new(size.feature_dim).with_width(size.head_width))
            .with_mlp(mlp.clone())
            .with_fast(self.fast.then(fast_field))
            .with_num_samples(size.samples)
            .with_head_top_k((self.top_k > 0).then_some(self.top_k))
            .with_proposal(proposal)
    }
}

/// What one case measured.
#[derive(Debug, Clone, Copy)]
pub struct Timing {
    /// Mean seconds of a timed step.
    pub secs: f64,
    /// Rays rendered per step (fewer than drawn behind the grid).
    pub rendered: usize,
    /// Rendering the trained model (no autodiff, the same feature path, the
    /// grid when the case has one, as `eval render` does).
    pub infer: Inference,
}

/// Inference speed of one model, with and without early ray termination.
#[derive(Debug, Clone, Copy)]
pub struct Inference {
    /// Rays per second with the default termination (what every render uses).
    pub rays_per_s: f64,
    /// Rays per second evaluating every sample.
    pub all_samples_rays_per_s: f64,
    /// Share of the samples evaluated with termination.
    pub samples_share: f64,
}

/// What every case of one backend shares.
pub struct Setup<'a> {
    /// The autodiff device.
    pub ad: &'a Device,
    pub size: Size,
    pub mlp: &'a MipMlpConfig,
    /// The Mip-NeRF field with its density fitted to the ball.
    pub fitted: &'a OpenNerf,
    /// The fast field fitted likewise, when a fast case is asked for.
    pub fitted_fast: Option<&'a OpenNerf>,
    pub grid: &'a OccupancyGrid,
    /// Timed steps.
    pub steps: usize,
    /// Samples between two termination checks.
    pub segment: usize,
}

/// Times `steps` steps (after one untimed warm-up step) of `case`.
pub fn time_case(setup: &Setup<'_>, case: Case) -> Timing {
    let Setup {
        ad,
        size,
        mlp,
        fitted,
        fitted_fast,
        grid,
        steps,
        segment,
    } = *setup;
    ad.seed(0);
    let mut model = case.config(mlp, size).init(ad);
    if case.fast {
        model.fast = fitted_fast.and_then(|f| f.fast.clone());
        assert!(model.fast.is_some(), "a fast case has its fitted field");
    } else {
        model.mlp = fitted.mlp.clone();
    }
    if case.with_grid {
        model = model.with_occupancy(Some(grid.clone()));
    }
    // The training's optimiser: Adam in one pass a parameter on flex.
    let mut optim = model::FusedAdamConfig::new().init();
    let n = size.rays;
    let host_rays = rays(n, 1);
    let batch_of = |r: &[NormalizedRay]| {
        let m = r.len();
        let target =
            |c: usize| Tensor::<2>::from_data(TensorData::new(vec![0.5f32; m * c], [m, c]), ad);
        BatchTensors {
            rays: r.to_vec(),
            frames: vec![0; m],
            rgb: target(3),
            rgb_weight: None,
            depth: None,
            feature: Some(FeatureTargets::dense(target(size.feature_dim))),
        }
    };
    let mut rendered = n;
    let rates = StepRates {
        base: 1e-4,
        head: 1e-4,
        pose: 1e-4,
    };
    // The steps read nothing back (as in training); the time of steps
    // 1..=steps runs to the read of the last one's values, which waits for
    // a GPU's queue to drain.
    let mut timed = None;
    let mut last = None;
    for step in 0..=steps {
        if step == 1 {
            crate::profile::enable();
            timed = Some(Instant::now());
        }
        // The grid case's model clips the host rays every step, as
        // training does.
        let batch = batch_of(&host_rays);
        let out = model.render(&RenderRequest::train(&batch.rays).with_features(case.path));
        rendered = out.clip.map_or(n, |c| c.kept);
        let (next, values) = train_step_from_deferred(
            model,
            &mut optim,
            out,
            &batch,
            None,
            &LossConfig::default(),
            rates,
        );
        model = next;
        if step == 0 {
            assert!(
                values.read().finite(),
                "benchmark warm-up step was not finite"
            );
        } else {
            last = Some(values);
        }
    }
    let finite = last.is_none_or(|v| v.read().finite());
    let total = timed.map_or(0.0, |t| t.elapsed().as_secs_f64());
    assert!(finite, "benchmark step produced a non-finite loss");
    crate::profile::disable();
    Timing {
        secs: total / steps.max(1) as f64,
        rendered,
        infer: inference(&model, case, grid, n, segment),
    }
}

/// Rendering `4 n` fresh rays with `model` in chunks of 4096 on the device
/// without autodiff (after one warm-up chunk), with the default early
/// termination and with every sample evaluated.
fn inference(
    model: &model::OpenNerf,
    case: Case,
    grid: &OccupancyGrid,
    n: usize,
    segment: usize,
) -> Inference {
    let valid = model.valid();
    let valid = if case.with_grid {
        valid.with_occupancy(Some(grid.clone()))
    } else {
        valid
    };
    let mode = case.path;
    let many = rays(4 * n, 2);
    let render = |rays: &[NormalizedRay], termination: Termination| {
        let request = RenderRequest::inference(rays)
            .with_features(mode)
            .with_termination(termination);
        valid
            .render(&request)
            .expect("never cancelled without an observer")
    };
    let time = |termination: Termination| {
        let _ = render(&rays(256, 3), termination);
        let start = Instant::now();
        let out = render(&many, termination);
        let secs = start.elapsed().as_secs_f64();
        (many.len() as f64 / secs, out.samples_evaluated)
    };
    let (all_samples_rays_per_s, all) = time(Termination::off());
    let (rays_per_s, evaluated) = time(Termination {
        segment,
        ..Termination::default()
    });
    Inference {
        rays_per_s,
        all_samples_rays_per_s,
        samples_share: evaluated as f64 / all.max(1) as f64,
    }
}

/// The Burn cases, in the order printed, with their names.
pub fn cases(top_k: usize) -> [(CaseName, Case); 6] {
    [
        (
            CaseName::Composited,
            Case {
                label: "composited + top-k",
                path: FeatureMode::Composited,
                top_k,
                with_grid: false,
                proposal: false,
                fast: false,
            },
        ),
        (
            CaseName::Plain,
            Case {
                label: "per-sample (plain)",
                path: FeatureMode::PerSample,
                top_k: 0,
                with_grid: false,
                proposal: false,
                fast: false,
            },
        ),
        (
            CaseName::Grid,
            Case {
                label: "composited + grid",
                path: FeatureMode::Composited,
                top_k,
                with_grid: true,
                proposal: false,
                fast: false,
            },
        ),
        (
            CaseName::Proposal,
            Case {
                label: "composited + proposal",
                path: FeatureMode::Composited,
                top_k,
                with_grid: false,
                proposal: true,
                fast: false,
            },
        ),
        (
            CaseName::Fast,
            Case {
                label: "fast field, composited",
                path: FeatureMode::Composited,
                top_k,
                with_grid: false,
                proposal: false,
                fast: true,
            },
        ),
        (
            CaseName::FastProposal,
            Case {
                label: "fast field + proposal",
                path: FeatureMode::Composited,
                top_k,
                with_grid: false,
                proposal: true,
                fast: true,
            },
        ),
    ]
}
