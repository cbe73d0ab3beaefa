//! A training step reads nothing back to the host: every combination of
//! field (box, unbounded), sampler (coarse and fine level, proposal
//! rounds), hash encoding, occupancy grid, and appearance codes with sparse
//! depth, with the Mip-NeRF MLP or the fast field (and its hash-grid
//! proposal networks), takes its step without a read on a GPU backend (wgpu, here on a
//! CPU Vulkan driver), and on the CPU backends reads only for the work they
//! do on the host by design (the hash encoding's corners, the proposal
//! rounds' resampling: `model::host_work`). Every backend's step measures
//! what flex's does, and moves the weights alike.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::AdamConfig;
use burn::tensor::{Device, Tensor, TensorData};
use model::geometry::NormalizedRay;
use model::host_work::{ReadReason, read_backs};
use model::{
    AppearanceCodesConfig, FastFieldConfig, FeatureHeadConfig, GridUse, HashGridConfig,
    MipMlpConfig, OccupancyConfig, OccupancyGrid, OpenNerf, OpenNerfConfig, ProposalConfig,
    UnboundedConfig,
};
use train::batch::{BatchTensors, FeatureTargets};
use train::config::LossConfig;
use train::step::{StepRates, StepRender, StepReport, train_step_deferred};

const FEATURES: usize = 4;
const RAYS: usize = 6;

/// One combination of the field's parts.
#[derive(Debug, Clone, Copy)]
struct Parts {
    unbounded: bool,
    proposal: bool,
    hash: bool,
    grid: bool,
    /// Appearance codes for two photographs, and depth targets on half the
    /// rays (sparse depth).
    extras: bool,
    /// The fast field in place of the MLP (its own hash grid; the proposal
    /// networks on a hash grid too).
    fast: bool,
}

impl Parts {
    fn all() -> Vec<Parts> {
        let mip = (0..32).map(|i| Parts {
            unbounded: i & 1 != 0,
            proposal: i & 2 != 0,
            hash: i & 4 != 0,
            grid: i & 8 != 0,
            extras: i & 16 != 0,
            fast: false,
        });
        // The fast field has no second grid: its combinations with the
        // extras on.
        let fast = (0..8).map(|i| Parts {
            unbounded: i & 1 != 0,
            proposal: i & 2 != 0,
            hash: false,
            grid: i & 4 != 0,
            extras: true,
            fast: true,
        });
        mip.chain(fast).collect()
    }

    fn config(&self) -> OpenNerfConfig {
        let mut c = OpenNerfConfig::new(FeatureHeadConfig::new(FEATURES).with_width(8))
            .with_mlp(
                MipMlpConfig::new()
                    .with_width(16)
                    .with_depth(2)
                    .with_skip_layer(1)
                    .with_max_deg(4),
            )
            .with_num_samples(8);
        if self.unbounded {
            c = c.with_unbounded(Some(UnboundedConfig::new(2.0)));
        }
        let small_grid = HashGridConfig::new()
            .with_levels(4)
            .with_log2_table(8)
            .with_max_resolution(64);
        if self.proposal {
            c = c.with_proposal(Some(
                ProposalConfig::new()
                    .with_samples(vec![16, 8])
                    .with_depth(1)
                    .with_width(8)
                    .with_max_deg(4)
                    .with_hash(self.fast.then(|| small_grid.clone().with_levels(2))),
            ));
        }
        if self.fast {
            c = c.with_fast(Some(
                FastFieldConfig::new()
                    .with_grid(small_grid.clone())
                    .with_density_width(8)
                    .with_color_width(8),
            ));
        }
        if self.hash {
            c = c.with_hash(Some(
                HashGridConfig::new()
                    .with_levels(4)
                    .with_log2_table(8)
                    .with_max_resolution(64),
            ));
        }
        if self.extras {
            c = c.with_appearance(Some(AppearanceCodesConfig::new(2).with_dim(4)));
        }
        c
    }

    /// The field on flex from a fixed seed, behind a grid of 2 x 2 x 2
    /// cells whose half at x > 0 is occupied when the combination has one.
    fn field(&self) -> OpenNerf {
        let flex = Device::flex().autodiff();
        flex.seed(21);
        let model = self.config().init(&flex);
        // Parameters are made when first read: read them here, so that a
        // fork to another device carries these values, not new draws.
        weights(&model);
        if !self.grid {
            return model;
        }
        let mut grid = OccupancyGrid::new(
            &OccupancyConfig::new()
                .with_resolution(2)
                .with_early_updates(0),
        );
        let density: Vec<f32> = (0..8)
            .map(|c| if c % 2 == 1 { 100.0 } else { 0.0 })
            .collect();
        grid.update(&density);
        model.with_occupancy(Some(grid))
    }
}

fn rays() -> Vec<NormalizedRay> {
    (0..RAYS)
        .map(|i| {
            let x = -1.25 + 0.5 * i as f32;
            NormalizedRay {
                origin: [x, 0.3, -2.0],
                direction: [0.05, 0.05, 1.0],
                radius: 0.01,
                near: 0.5,
                far: 3.5,
            }
        })
        .collect()
}

fn batch(parts: &Parts, device: &Device) -> BatchTensors {
    let n = RAYS;
    let t = |v: Vec<f32>, c: usize| Tensor::<2>::from_data(TensorData::new(v, [n, c]), device);
    let rgb: Vec<f32> = (0..n * 3)
        .map(|i| 0.1 + 0.8 * ((i * 7) % 11) as f32 / 11.0)
        .collect();
    let feature: Vec<f32> = (0..n * FEATURES)
        .map(|i| ((i * 5) % 7) as f32 / 7.0 - 0.4)
        .collect();
    let depth = parts.extras.then(|| {
        let d: Vec<f32> = (0..n)
            .map(|i| {
                if i % 2 == 0 {
                    1.5 + 0.1 * i as f32
                } else {
                    0.0
                }
            })
            .collect();
        let w: Vec<f32> = (0..n).map(|i| if i % 2 == 0 { 1.0 } else { 0.0 }).collect();
        (t(d, 1), t(w, 1))
    });
    BatchTensors {
        rays: rays(),
        frames: (0..n).map(|i| i % 2).collect(),
        rgb: t(rgb, 3),
        rgb_weight: None,
        depth,
        feature: Some(FeatureTargets::dense(t(feature, FEATURES))),
    }
}

/// Every float parameter's values, in visiting order.
fn weights(m: &OpenNerf) -> Vec<Vec<f32>> {
    struct All(Vec<Vec<f32>>);
    impl ModuleVisitor for All {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0
                .push(p.val().into_data().try_into_vec_as::<f32>().expect("f32"));
        }
    }
    let mut all = All(Vec::new());
    m.visit(&mut all);
    all.0
}

/// One deferred step of `parts` on `device`, returning the reads it made
/// (by reason), what it measured, and the weights after it.
fn step(parts: &Parts, device: &Device) -> (Vec<(ReadReason, u64)>, StepReport, Vec<Vec<f32>>) {
    let model = parts.field().fork(device);
    let batch = batch(parts, device);
    let mut optim = AdamConfig::new().init();
    let render = StepRender {
        background: None,
        grid: GridUse::Model,
        progress: 0.5,
        jitter: false,
    };
    let cfg = LossConfig {
        lambda_depth: 0.1,
        ..LossConfig::default()
    };
    let rates = StepRates {
        base: 1e-3,
        head: 1e-3,
        pose: 1e-3,
    };
    let before = read_backs();
    let (model, values) = train_step_deferred(model, &mut optim, &batch, None, render, &cfg, rates);
    let reads = read_backs().since(&before).nonzero();
    (reads, values.read(), weights(&model))
}

fn devices() -> Vec<(&'static str, Device)> {
    #[allow(deprecated)]
    let mut v = vec![
        ("flex", Device::flex().autodiff()),
        ("ndarray", Device::ndarray().autodiff()),
    ];
    if train::backend::vulkan_available() {
        // CUBECL_AUTOTUNE_LEVEL=minimal keeps the shader compilation short.
        v.push((
            "wgpu",
            Device::wgpu(burn::tensor::DeviceKind::Cpu).autodiff(),
        ));
    } else {
        eprintln!("skipping wgpu: no Vulkan driver");
    }
    v
}

fn close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-4 + 1e-3 * b.abs(),
        "{what}: {a} against flex's {b}"
    );
}

#[test]
fn a_training_step_reads_nothing_back_for_every_combination() {
    let devices = devices();
    for parts in Parts::all() {
        let (flex_reads, flex, flex_weights) = step(&parts, &devices[0].1);
        assert!(flex.finite(), "{parts:?}: flex's step is finite: {flex:?}");
        for (name, device) in &devices {
            let (reads, report, after) = if *name == "flex" {
                (flex_reads.clone(), flex, flex_weights.clone())
            } else {
                step(&parts, device)
            };
            let what = format!("{name} {parts:?}");
            if *name == "wgpu" {
                assert!(reads.is_empty(), "{what}: read back {reads:?}");
            } else {
                for (reason, count) in &reads {
                    assert!(
                        reason.is_cpu_form(),
                        "{what}: read back {count} for {reason:?}"
                    );
                }
                let hash_reads = reads.iter().any(|r| r.0 == ReadReason::HashCorners);
                let round_reads = reads.iter().any(|r| r.0 == ReadReason::ProposalRound);
                assert_eq!(
                    hash_reads,
                    parts.hash || parts.fast,
                    "{what}: hash corners on the host"
                );
                assert_eq!(round_reads, parts.proposal, "{what}: rounds on the host");
                let fine_reads = reads.iter().any(|r| r.0 == ReadReason::FineResample);
                assert_eq!(
                    fine_reads, !parts.proposal,
                    "{what}: the fine level's resampling on the host"
                );
            }
            close(report.loss, flex.loss, &format!("{what}: loss"));
            close(report.rgb_mse, flex.rgb_mse, &format!("{what}: colour"));
            close(report.depth, flex.depth, &format!("{what}: depth"));
            close(report.open, flex.open, &format!("{what}: open-set"));
            close(report.grad_l1, flex.grad_l1, &format!("{what}: gradient"));
            assert_eq!(parts.extras, report.depth > 0.0, "{what}: depth term");
            assert_eq!(after.len(), flex_weights.len(), "{what}: parameters");
            for (k, (a, b)) in after.iter().zip(&flex_weights).enumerate() {
                for (x, y) in a.iter().zip(b) {
                    assert!(
                        (x - y).abs() <= 1e-4 + 1e-3 * y.abs(),
                        "{what}: parameter {k} after the step: {x} against flex's {y}"
                    );
                }
            }
        }
    }
}
