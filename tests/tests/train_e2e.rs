//! End-to-end training: the CI synthetic scene trained from scratch,
//! resumed, with corrupt checkpoints, and on every backend.

use std::path::Path;

use burn::tensor::Device;
use tests::{
    ci_scene, max_abs_diff, run_weights as weights, scratch_dir, serial, tiny_config, wgpu_enabled,
};
use train::checkpoint::{Checkpoint, list_checkpoints};
use train::metrics_log::MetricsEvent;
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
    let init = s.initial_interior.unwrap();
    let (init_psnr, init_cos) = (init.psnr, init.feature_cosine.unwrap());
    let h = &s.heldout_interior;
    assert_eq!(s.iterations, 300);
    assert!(
        h.psnr > init_psnr + 4.0,
        "held-out PSNR {} vs {init_psnr} at initialisation",
        h.psnr
    );
    let cos = h.feature_cosine.unwrap();
    assert!(
        cos > init_cos + 0.1 && cos > 0.5,
        "feature cosine {cos} vs {init_cos}"
    );
    assert!(h.depth_mae.unwrap() < 1.0);
    assert!(s.rays_per_second > 0.0 && s.peak_memory_bytes.unwrap() > 0);
    // Interior and whole-view figures are reported apart, each over its own
    // pixels: the interior ones leave the scaled border margin out.
    let whole = s.heldout_whole.unwrap();
    assert!(whole.pixels > h.pixels && h.pixels > 0);
    assert!(whole.psnr.is_finite());

    // The run directory holds what evaluation needs.
    let run = field_ops::run_dir::RunDir::new(dir.path());
    let summary = read_json(&run.summary());
    for key in [
        "iterations",
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
    for part in ["heldout_interior", "heldout_whole"] {
        for key in ["psnr", "ssim", "depth_mae", "feature_cosine", "pixels"] {
            assert!(
                summary[part][key].is_number(),
                "summary.json: {part}.{key} = {}",
                summary[part][key]
            );
        }
    }
    // The training curve is drawn from the same log (the numbers it shows
    // are parsed back by train::curve, tested there).
    let curve = image::open(dir.path().join("training_curve.png")).expect("training_curve.png");
    assert_eq!((curve.width(), curve.height()), (900, 800));
    let log = std::fs::read_to_string(run.metrics()).unwrap();
    let curves = train::curve::parse(&log);
    assert_eq!(curves.heldout_psnr.last().map(|p| p.1), Some(h.psnr));
    assert!(curves.batch_psnr.len() >= 2);
    let events = train::metrics_log::parse(&log);
    assert_eq!(events.len(), log.lines().count(), "every line is an event");
    let Some(MetricsEvent::Final(last)) = events.last() else {
        panic!("the log ends with {:?}", events.last());
    };
    assert_eq!(last.interior, *h);
    assert_eq!(last.whole, Some(whole));
    // SSIM of the views in full, in the summary and the log alike, and per
    // view: the interior and whole figures are the means over the views.
    let ssim = h.ssim.expect("held-out SSIM");
    assert!(ssim > 0.0 && ssim <= 1.0, "{ssim}");
    assert!(log.contains("\"ssim_interior\":") && log.contains("\"ssim_whole\":"));
    assert_eq!(s.heldout_views.len(), s.heldout_frames.len());
    let mean = |f: fn(&train::view_eval::ViewFigures) -> Option<f64>| {
        s.heldout_views.iter().filter_map(f).sum::<f64>() / s.heldout_views.len() as f64
    };
    assert!((mean(|v| v.ssim_interior) - ssim).abs() < 1e-12);
    assert!((mean(|v| v.ssim_whole) - whole.ssim.unwrap()).abs() < 1e-12);
    for v in &s.heldout_views {
        assert!(
            v.psnr_interior.is_finite() && v.psnr_whole.is_finite(),
            "{v:?}"
        );
        // Each view's strip (photograph, render, error, depth) and pictures.
        let strip = image::open(run.renders().join(format!("{}_strip.png", v.name))).unwrap();
        let rgb = image::open(run.renders().join(format!("{}_rgb.png", v.name))).unwrap();
        assert_eq!(
            (strip.width(), strip.height()),
            (4 * rgb.width(), rgb.height())
        );
        for file in ["opacity.png", "depth.png", "depth.json"] {
            assert!(
                run.renders().join(format!("{}_{file}", v.name)).exists(),
                "{file}"
            );
        }
    }
    let views = summary["heldout_views"]
        .as_array()
        .expect("per-view figures");
    assert_eq!(views.len(), s.heldout_views.len());
    let sheet = image::open(run.renders().join("heldout.png")).expect("contact sheet");
    assert!(
        sheet.height() >= 120 * views.len() as u32,
        "{}",
        sheet.height()
    );
    // On disk, every held-out figure names the pixels it was measured on.
    let last: serde_json::Value = serde_json::from_str(log.lines().last().unwrap()).unwrap();
    assert_eq!(last["event"], "final");
    assert!(last["psnr_interior"].is_number() && last["psnr_whole"].is_number());
    assert!(last.get("psnr").is_none(), "unqualified PSNR in {last}");
    let split = read_json(&run.split());
    assert_eq!(split["heldout"], serde_json::json!([0, 4, 8, 12, 16]));
    let loaded = field_ops::run_dir::load_run(dir.path(), &Device::flex()).unwrap();
    assert_eq!(loaded.split.heldout, vec![0, 4, 8, 12, 16]);
    for name in [
        "frame000004_rgb.png",
        "frame000004_depth.png",
        "frame000004_feature.png",
    ] {
        assert!(run.renders().join(name).exists(), "missing renders/{name}");
    }
    let evals = events
        .iter()
        .filter(|e| matches!(e, MetricsEvent::Eval(_)))
        .count();
    assert_eq!(evals, 3, "evaluations at 0, 100, 200");
    let ckpts: Vec<usize> = list_checkpoints(&run.checkpoints())
        .unwrap()
        .iter()
        .map(|c| c.0)
        .collect();
    assert_eq!(ckpts, vec![150, 300]);
}

/// A run of `2 n` iterations trained whole, and the same run stopped after
/// `n` and resumed from its checkpoint: their directories and outcomes
/// (whole, first half, resumed).
struct Halves {
    whole: tempfile::TempDir,
    parts: tempfile::TempDir,
    a: train::RunOutcome,
    half: train::RunOutcome,
    b: train::RunOutcome,
}

fn whole_and_resumed(config: train::config::TrainConfig, n: usize) -> Halves {
    let scene = ci_scene();
    let whole = scratch_dir();
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
    let b = train::resume(parts.path(), None, &session(BackendKind::Flex)).unwrap();
    Halves {
        whole,
        parts,
        a,
        half,
        b,
    }
}

/// The fast field (with its hash-grid proposal sampler) resumed halfway
/// ends with the weights of the uninterrupted run: its tables, MLPs and
/// their Adam state are all in the checkpoint.
#[test]
fn a_resumed_fast_field_run_matches_the_uninterrupted_one() {
    let _guard = serial();
    let scene = ci_scene();
    let n = 10;
    let mut config = tiny_config(scene, 2 * n);
    config.logging.eval_every = 0;
    config.logging.checkpoint_every = n;
    let grid = model::HashGridConfig::new()
        .with_levels(4)
        .with_log2_table(10)
        .with_max_resolution(64);
    config.model.fast = Some(model::FastFieldConfig::new().with_grid(grid.clone()));
    config.model.proposal = Some(
        model::ProposalConfig::new()
            .with_samples(vec![8])
            .with_depth(1)
            .with_width(8)
            .with_hash(Some(grid.with_levels(2))),
    );
    let Halves {
        whole, parts, b, ..
    } = whole_and_resumed(config, n);
    assert_eq!(b.summary.iterations, 2 * n);
    let (wa, wb) = (weights(whole.path()), weights(parts.path()));
    assert_eq!(wa.len(), wb.len());
    let max_diff = max_abs_diff(&wa, &wb);
    assert!(max_diff < 1e-4, "weights differ by up to {max_diff}");
    // The run's weights are the fast field's: its tables are among them.
    let device = Device::flex();
    let loaded = field_ops::run_dir::load_run(parts.path(), &device).unwrap();
    let fast = loaded.model.fast.as_ref().expect("the fast field");
    assert_eq!(fast.grid.table.val().dims(), [4 << 10, 2]);
    assert!(loaded.model.mlp.is_none());
}

#[test]
fn resumed_run_matches_the_uninterrupted_one_and_corruption_is_reported() {
    let _guard = serial();
    let scene = ci_scene();
    let n = 20;
    let mut config = tiny_config(scene, 2 * n);
    config.logging.eval_every = 0;
    config.logging.checkpoint_every = n;
    let Halves {
        whole,
        parts,
        a,
        half,
        b,
    } = whole_and_resumed(config, n);
    assert_eq!(half.summary.iterations, n);
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
    let max_diff = max_abs_diff(&wa, &wb);
    assert!(max_diff < 1e-4, "weights differ by up to {max_diff}");
    assert!(
        (a.summary.heldout_interior.psnr - b.summary.heldout_interior.psnr).abs() < 0.05,
        "{} vs {}",
        a.summary.heldout_interior.psnr,
        b.summary.heldout_interior.psnr
    );

    // Damage every checkpoint: resuming reports the newest by name. (With an
    // intact older one it resumes from that instead: train/tests/cli.rs.)
    let all = list_checkpoints(&parts.path().join("checkpoints")).unwrap();
    let (_, newest) = all.last().unwrap().clone();
    let bytes = std::fs::read(&newest).unwrap();
    for damaged in [bytes[..bytes.len() / 2].to_vec(), vec![0x42u8; 4096]] {
        for (_, path) in &all {
            std::fs::write(path, &damaged).unwrap();
        }
        let err =
            train::resume(parts.path(), Some(3 * n), &session(BackendKind::Flex)).unwrap_err();
        assert!(matches!(err, TrainError::Checkpoint { .. }), "{err}");
        assert!(
            err.to_string().contains(&newest.display().to_string()),
            "{err}"
        );
    }
    // Nothing was renamed or removed by the failed attempts.
    assert_eq!(
        list_checkpoints(&parts.path().join("checkpoints")).unwrap(),
        all
    );
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
    let init = s.initial_interior.unwrap();
    let (psnr0, cos0) = (init.psnr, init.feature_cosine.unwrap());
    let h = s.heldout_interior;
    assert!(
        h.psnr > psnr0 + min_psnr_gain,
        "{backend}: PSNR {} vs {psnr0} at initialisation",
        h.psnr
    );
    let cos = h.feature_cosine.unwrap();
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
    if !field_ops::backend::WGPU_BUILT {
        println!("skipped: built without the wgpu feature");
        return;
    }
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
    let skipped = train::metrics_log::read(&dir.path().join("metrics.jsonl"))
        .unwrap()
        .iter()
        .filter(|e| matches!(e, MetricsEvent::Nonfinite(_)))
        .count();
    assert_eq!(skipped, 3);
    // Skipped steps never reach the weights: the checkpoints stay readable.
    // One is written every iteration, so the first (finite) step left one.
    let path = last_checkpoint
        .as_ref()
        .expect("a checkpoint written before the divergence");
    let ck = Checkpoint::read(path).unwrap();
    assert!(ck.state.iteration <= *iteration);
    assert!(!dir.path().join("model.bpk").exists());
}
