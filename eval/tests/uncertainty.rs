//! The uncertainty map on the synthetic CI scene: its invariants, the eps
//! floor where every view agrees, more uncertainty where views disagree, and
//! `eval uncertainty` end to end (files written, bad flags refused).

use std::path::Path;
use std::process::Command;

use burn::module::Module;
use burn::tensor::Device;
use datasets::SceneMeta;
use datasets::scene::Scene;
use datasets::synthetic::{SceneSize, generate};
use eval::uncertainty::report::feature_errors;
use eval::uncertainty::{UncertaintyOptions, uncertainty_map, voxel_downsample};
use half::f16;
use model::{FeatureHeadConfig, MipMlpConfig, OpenNerfConfig};

fn ci_scene() -> Scene {
    generate(0, SceneSize::Ci).expect("CI scene")
}

fn cloud(scene: &Scene) -> Vec<[f64; 3]> {
    let all = &scene.points.as_ref().expect("points").positions;
    voxel_downsample(all, 0.05)
        .iter()
        .map(|&i| all[i])
        .collect()
}

#[test]
fn the_map_is_finite_normalised_and_maximal_where_seen_less_than_twice() {
    let scene = ci_scene();
    let frames: Vec<usize> = (0..scene.frames.len()).collect();
    let pts = cloud(&scene);
    let map = uncertainty_map(
        &scene,
        &frames,
        &pts,
        &UncertaintyOptions::default(),
        |_, _| {},
    )
    .expect("map");
    let twice = map.counts.iter().filter(|&&c| c >= 2).count();
    assert!(
        twice > pts.len() / 4,
        "{twice} of {} points seen twice",
        pts.len()
    );
    assert!(map.log_det.iter().all(|u| u.is_finite()));
    assert!(map.normalised.iter().all(|u| (0.0..=1.0).contains(u)));
    let max = map
        .log_det
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    for (c, u) in map.counts.iter().zip(&map.log_det) {
        if *c < 2 {
            assert_eq!(*u, max);
        }
    }
    // The error of the mean feature against the point's class: a cosine
    // distance, defined wherever a labelled point was seen.
    let mut points = eval::segment::EvalPoints::from_scene(&scene).expect("labelled");
    let keep = voxel_downsample(&points.positions, 0.05);
    points.positions = keep.iter().map(|&i| points.positions[i]).collect();
    points.labels = keep.iter().map(|&i| points.labels[i]).collect();
    let pca = scene.features.as_ref().and_then(|f| f.pca.as_ref());
    let errors = feature_errors(&map, &points, pca).expect("errors");
    let finite: Vec<f64> = errors.iter().copied().filter(|e| e.is_finite()).collect();
    assert!(finite.len() > pts.len() / 4);
    assert!(finite.iter().all(|e| (0.0..=2.0).contains(e)));
}

/// Overwrites every target pixel of every map with `f(frame)`.
fn set_maps(scene: &mut Scene, f: impl Fn(usize) -> Vec<f16>) {
    let set = scene.features.as_mut().expect("features");
    let dim = set.dim();
    for (i, map) in set.maps.iter_mut().enumerate() {
        let value = f(i);
        for px in map.data.chunks_mut(dim) {
            px.copy_from_slice(&value);
        }
    }
}

#[test]
fn agreeing_views_give_the_eps_floor_and_disagreeing_views_more() {
    let mut scene = ci_scene();
    let dim = scene.features.as_ref().expect("features").dim();
    let frames: Vec<usize> = (0..scene.frames.len()).collect();
    let pts = cloud(&scene);
    let opts = UncertaintyOptions::default();
    set_maps(&mut scene, |_| vec![f16::from_f32(0.25); dim]);
    let same = uncertainty_map(&scene, &frames, &pts, &opts, |_, _| {}).expect("map");
    let floor = opts.k.min(dim) as f64 * opts.eps.ln();
    for (c, u) in same.counts.iter().zip(&same.log_det) {
        if *c >= 2 {
            assert!((u - floor).abs() < 1e-6, "{u} vs {floor}");
        }
    }
    // Every frame sees a different constant: each point's samples spread.
    set_maps(&mut scene, |i| {
        (0..dim)
            .map(|j| f16::from_f32(0.5 * (i as f32 * 1.3 + j as f32 * 0.7).sin()))
            .collect()
    });
    let spread = uncertainty_map(&scene, &frames, &pts, &opts, |_, _| {}).expect("map");
    for ((c, u), s) in spread.counts.iter().zip(&spread.log_det).zip(&same.log_det) {
        if *c >= 2 {
            assert!(u > s, "{u} not above the agreeing {s}");
        }
    }
}

/// A run directory with an untrained tiny field on the CI scene.
fn run_dir(dir: &Path) {
    let scene = ci_scene();
    let features = scene.features.as_ref().expect("features");
    let config = OpenNerfConfig::new(
        FeatureHeadConfig::new(features.dim())
            .with_width(8)
            .with_layers(1),
    )
    .with_mlp(
        MipMlpConfig::new()
            .with_width(16)
            .with_depth(2)
            .with_skip_layer(1)
            .with_max_deg(4),
    )
    .with_num_samples(4);
    let bytes = config
        .init(&Device::flex())
        .into_record()
        .into_bytes()
        .expect("serialise");
    std::fs::write(dir.join("model.bpk"), bytes.to_vec()).expect("weights");
    let cfg = serde_json::json!({ "model": config });
    std::fs::write(dir.join("config.json"), cfg.to_string()).expect("config");
    let meta = SceneMeta {
        source: scene.source.clone(),
        scene_box: scene.scene_box,
        background: scene.background,
        pca: features.pca.clone(),
        feature_dim: Some(features.full_dim),
    };
    std::fs::write(
        dir.join("scene.json"),
        serde_json::to_string(&meta).expect("meta"),
    )
    .expect("write");
    let n = scene.frames.len();
    let split = serde_json::json!({ "train": (1..n).collect::<Vec<_>>(), "heldout": [0] });
    std::fs::write(dir.join("split.json"), split.to_string()).expect("write");
}

fn eval(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

#[test]
fn the_command_writes_its_files_and_refuses_bad_flags() {
    let tmp = tempfile::tempdir().expect("tmp");
    run_dir(tmp.path());
    let run = tmp.path().to_str().expect("utf-8");
    let out = eval(&["uncertainty", "--run", run, "--views", "3"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("Pearson r"), "{stdout}");
    let dir = tmp.path().join("uncertainty");
    let views: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("novel_views.json")).expect("cameras file"),
    )
    .expect("json");
    let frames = views["frames"].as_array().expect("frames");
    assert!(frames.len() <= 3);
    for (i, f) in frames.iter().enumerate() {
        let u = f["uncertainty"].as_f64().expect("u");
        assert!((0.0..=1.0).contains(&u));
        assert!(f["transmittance"].as_f64().expect("t") >= 0.5);
        assert!(dir.join(format!("previews/novel_{i:03}_rgb.png")).is_file());
    }
    for name in ["uncertainty.json", "uncertainty.csv", "uncertainty.ply"] {
        assert!(dir.join(name).is_file(), "{name} missing: {stdout}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("uncertainty.json")).expect("read"))
            .expect("json");
    let r = summary["pearson_r"].as_f64().expect("r");
    assert!((-1.0..=1.0).contains(&r));
    let csv = std::fs::read_to_string(dir.join("uncertainty.csv")).expect("csv");
    assert_eq!(
        csv.lines().count(),
        summary["points"].as_u64().expect("n") as usize + 1
    );
    for (flag, value) in [
        ("--k", "0"),
        ("--eps", "NaN"),
        ("--eps", "-1"),
        ("--voxel", "-0.1"),
    ] {
        let out = eval(&["uncertainty", "--run", run, flag, value]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && !err.contains("panicked"),
            "{flag} {value}: {err}"
        );
        assert!(err.contains(flag), "{flag} {value}: {err}");
    }
}
