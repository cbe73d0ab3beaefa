//! End-to-end training: the CI synthetic scene trained from scratch,
//! resumed, with corrupt checkpoints, and on every backend.

use std::path::Path;

use burn::tensor::Device;
use tests::{ci_scene, scratch_dir, serial, tiny_config, wgpu_enabled};
use train::checkpoint::{Checkpoint, list_checkpoints};
use train::{BackendKind, SessionOptions, TrainError};

fn session(backend: BackendKind) -> SessionOptions {
    SessionOptions {
        backend,
        final_render: false,
        ..Default::default()
    }
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn training_beats_initialisation_and_writes_a_complete_run() {
    let _guard = serial();
    let scene = ci_scene();
    let dir = scratch_dir();
    let mut config = tiny_config(scene, 300);
    config.logging.checkpoint_every = 150;
    let opts = SessionOptions {
        final_render: true,
        ..session(BackendKind::Flex)
    };
    let out = train::train_new(scene, config, 4, dir.path(), &opts).unwrap();
    let s = &out.summary;
    println!("summary: {s:?}");
    let init_psnr = s.initial_psnr.unwrap();
    let init_cos = s.initial_feature_cosine.unwrap();
    assert_eq!(s.iterations, 300);
    assert!(
        s.heldout_psnr > init_psnr + 4.0,
        "held-out PSNR {} vs {init_psnr} at initialisation",
        s.heldout_psnr
    );
    let cos = s.heldout_feature_cosine.unwrap();
    assert!(
        cos > init_cos + 0.1 && cos > 0.5,
        "feature cosine {cos} vs {init_cos}"
    );
    assert!(s.heldout_depth_mae.unwrap() < 1.0);
    assert!(s.rays_per_second > 0.0 && s.peak_memory_bytes.unwrap() > 0);

    // The run directory holds what evaluation needs.
    let run = eval::run::RunDir::new(dir.path());
    let summary = read_json(&run.summary());
    for key in [
        "iterations",
        "heldout_psnr",
        "heldout_depth_mae",
        "heldout_feature_cosine",
        "wall_seconds",
        "rays_per_second",
        "peak_memory_bytes",
    ] {
        assert!(
            summary[key].is_number(),
            "summary.json: {key} = {}",
            summary[key]
        );
    }
    let split = read_json(&run.split());
    assert_eq!(split["heldout"], serde_json::json!([0, 4, 8, 12, 16]));
    let loaded = eval::run::load_run(dir.path(), &Device::flex()).unwrap();
    assert_eq!(loaded.split.heldout, vec![0, 4, 8, 12, 16]);
    for name in [
        "frame000004_rgb.png",
        "frame000004_depth.png",
        "frame000004_feature.png",
    ] {
        assert!(run.renders().join(name).exists(), "missing renders/{name}");
    }
    let metrics = std::fs::read_to_string(run.metrics()).unwrap();
    let evals = metrics
        .lines()
        .filter(|l| l.contains("\"event\":\"eval\""))
        .count();
    assert_eq!(evals, 3, "evaluations at 0, 100, 200");
    let ckpts: Vec<usize> = list_checkpoints(&run.checkpoints())
        .unwrap()
        .iter()
        .map(|c| c.0)
        .collect();
    assert_eq!(ckpts, vec![150, 300]);
}

#[test]
fn resumed_run_matches_the_uninterrupted_one_and_corruption_is_reported() {
    let _guard = serial();
    let scene = ci_scene();
    let n = 20;
    let whole = scratch_dir();
    let mut config = tiny_config(scene, 2 * n);
    config.logging.eval_every = 0;
    config.logging.checkpoint_every = n;
    let a = train::train_new(
        scene,
        config.clone(),
        4,
        whole.path(),
        &session(BackendKind::Flex),
    )
    .unwrap();

    let parts = scratch_dir();
    let first = SessionOptions {
        stop_at: Some(n),
        ..session(BackendKind::Flex)
    };
    let half = train::train_new(scene, config, 4, parts.path(), &first).unwrap();
    assert_eq!(half.summary.iterations, n);
    let b = train::resume(parts.path(), None, &session(BackendKind::Flex)).unwrap();
    assert_eq!(b.summary.iterations, 2 * n);

    // Same batches, same jitter, same Adam state: the same weights.
    let ck = |dir: &Path| {
        let (_, p) = list_checkpoints(&dir.join("checkpoints"))
            .unwrap()
            .pop()
            .unwrap();
        Checkpoint::read(&p).unwrap()
    };
    let (ca, cb) = (ck(whole.path()), ck(parts.path()));
    assert_eq!(ca.state.iteration, cb.state.iteration);
    assert_eq!(ca.state.rays_processed, cb.state.rays_processed);
    let wa = weights(whole.path());
    let wb = weights(parts.path());
    assert_eq!(wa.len(), wb.len());
    let max_diff = wa
        .iter()
        .zip(&wb)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(max_diff < 1e-4, "weights differ by up to {max_diff}");
    assert!(
        (a.summary.heldout_psnr - b.summary.heldout_psnr).abs() < 0.05,
        "{} vs {}",
        a.summary.heldout_psnr,
        b.summary.heldout_psnr
    );

    // Damage the newest checkpoint: resuming names it; the older one is intact.
    let all = list_checkpoints(&parts.path().join("checkpoints")).unwrap();
    let (_, newest) = all.last().unwrap().clone();
    let (_, older) = all[all.len() - 2].clone();
    let bytes = std::fs::read(&newest).unwrap();
    for damaged in [bytes[..bytes.len() / 2].to_vec(), vec![0x42u8; 4096]] {
        std::fs::write(&newest, &damaged).unwrap();
        let err =
            train::resume(parts.path(), Some(3 * n), &session(BackendKind::Flex)).unwrap_err();
        assert!(matches!(err, TrainError::Checkpoint { .. }), "{err}");
        assert!(
            err.to_string().contains(&newest.display().to_string()),
            "{err}"
        );
    }
    assert_eq!(Checkpoint::read(&older).unwrap().state.iteration, n);
}

/// All weights of the run in `dir`, flattened.
fn weights(dir: &Path) -> Vec<f32> {
    use burn::module::{Module, ModuleVisitor, Param};
    use burn::tensor::Tensor;
    struct Collect(Vec<f32>);
    impl ModuleVisitor for Collect {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0
                .extend(p.val().into_data().try_to_vec::<f32>().unwrap());
        }
    }
    let run = eval::run::load_run(dir, &Device::flex()).unwrap();
    let mut c = Collect(Vec::new());
    run.model.visit(&mut c);
    c.0
}

/// A short run on `backend` improves the held-out colour and features over
/// initialisation (`rays` per batch, `samples` per level).
fn short_run_improves(
    backend: BackendKind,
    iterations: usize,
    rays: usize,
    samples: usize,
    min_psnr_gain: f64,
    min_cosine_gain: f64,
) {
    let _guard = serial();
    let scene = ci_scene();
    let dir = scratch_dir();
    let mut config = tiny_config(scene, iterations);
    config.sampler.rays_per_batch = rays;
    config.model.num_samples = samples;
    config.schedule.warmup_iters = iterations / 10;
    config.logging.eval_every = 0;
    config.logging.checkpoint_every = 0;
    config.logging.eval_pixels = rays;
    let out = train::train_new(scene, config, 4, dir.path(), &session(backend)).unwrap();
    let s = out.summary;
    println!("{backend}: {s:?}");
    assert_eq!(s.iterations, iterations);
    assert_eq!(s.skipped_steps, 0);
    let (psnr0, cos0) = (s.initial_psnr.unwrap(), s.initial_feature_cosine.unwrap());
    assert!(
        s.heldout_psnr > psnr0 + min_psnr_gain,
        "{backend}: PSNR {} vs {psnr0} at initialisation",
        s.heldout_psnr
    );
    let cos = s.heldout_feature_cosine.unwrap();
    assert!(
        cos > cos0 + min_cosine_gain,
        "{backend}: feature cosine {cos} vs {cos0} at initialisation"
    );
}

#[test]
fn ndarray_backend_trains() {
    short_run_improves(BackendKind::Ndarray, 100, 256, 32, 1.0, 0.3);
}

#[test]
fn wgpu_backend_trains_when_a_vulkan_driver_is_present() {
    if !wgpu_enabled() {
        println!(
            "skipped: no Vulkan driver (install mesa-vulkan-drivers or set OPENNERF_TEST_WGPU=1)"
        );
        return;
    }
    // A software Vulkan driver runs at a few GFLOP/s: a handful of small steps.
    short_run_improves(BackendKind::Wgpu, 12, 64, 8, 0.0, 0.2);
}

#[test]
fn diverging_training_stops_after_bounded_non_finite_steps() {
    let _guard = serial();
    let scene = ci_scene();
    let dir = scratch_dir();
    let mut config = tiny_config(scene, 50);
    // A learning rate of 1e30 blows the weights up in one step, after which
    // every loss is non-finite.
    config.schedule.lr_init = 1e30;
    config.schedule.lr_final = 1e30;
    config.schedule.warmup_iters = 0;
    config.sampler.rays_per_batch = 32;
    config.logging.eval_pixels = 32;
    config.logging.checkpoint_every = 1;
    config.logging.max_nonfinite_steps = 3;
    let err =
        train::train_new(scene, config, 4, dir.path(), &session(BackendKind::Flex)).unwrap_err();
    let TrainError::Diverged {
        count,
        iteration,
        last_checkpoint,
    } = &err
    else {
        panic!("expected a divergence error, got {err}");
    };
    assert_eq!(*count, 3);
    assert!(*iteration < 10, "stopped at {iteration}");
    assert!(err.to_string().contains("non-finite"), "{err}");
    let skipped = std::fs::read_to_string(dir.path().join("metrics.jsonl"))
        .unwrap()
        .lines()
        .filter(|l| l.contains("\"event\":\"nonfinite\""))
        .count();
    assert_eq!(skipped, 3);
    // Skipped steps never reach the weights: the checkpoints stay readable.
    if let Some(path) = last_checkpoint {
        let ck = Checkpoint::read(path).unwrap();
        assert!(ck.state.iteration <= *iteration);
    }
    assert!(!dir.path().join("model.bpk").exists());
}
