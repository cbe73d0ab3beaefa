//! The uncertainty map on the synthetic CI scene: its invariants, the eps
//! floor where every view agrees, more uncertainty where views disagree, and
//! `eval uncertainty` end to end (files written, bad flags refused).

mod common;

use std::process::Command;

use datasets::scene::Scene;
use datasets::synthetic::{SceneSize, generate};
use eval::commands::uncertainty::feature_errors;
use field_ops::uncertainty::{UncertaintyOptions, uncertainty_map, voxel_downsample};
use half::f16;

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
fn the_map_is_finite_normalised_maximal_where_unseen_and_the_prior_where_seen_once() {
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
    // Never seen: the largest value. Seen once: no scatter, so the shrunk
    // covariance is the pooled prior itself, the same value for all of them.
    let once: Vec<f64> = (0..pts.len())
        .filter(|&i| map.counts[i] == 1)
        .map(|i| map.log_det[i])
        .collect();
    assert!(!once.is_empty(), "no point seen once");
    assert!(
        once.iter().all(|u| (u - once[0]).abs() < 1e-9 && *u < max),
        "{once:?}"
    );
    for (c, u) in map.counts.iter().zip(&map.log_det) {
        if *c == 0 {
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
    // The colours the frames saw each point with are the surface's own:
    // the frames are renders of it, and the scene's points carry its
    // shaded colour (up to the pixel the point rounds to).
    let all = scene.points.as_ref().expect("points");
    let truth = all.colors.as_ref().expect("point colours");
    let mut diffs = Vec::new();
    for (j, &i) in voxel_downsample(&all.positions, 0.05).iter().enumerate() {
        assert_eq!(map.mean_colors[j].is_some(), map.counts[j] > 0);
        if let Some(c) = map.mean_colors[j] {
            let d = (0..3)
                .map(|k| (c[k] - truth[i][k] as f32 / 255.0).abs())
                .fold(0f32, f32::max);
            diffs.push(d);
        }
    }
    diffs.sort_by(f32::total_cmp);
    let median = diffs[diffs.len() / 2];
    assert!(median < 0.05, "median colour difference {median}");
}

/// A tiny untrained field on the CI scene and a 9 x 9 camera looking at the
/// room's middle, whose principal point is a pixel centre.
fn probe_setup() -> (model::OpenNerf, Scene, model::geometry::Camera) {
    let scene = ci_scene();
    let dim = scene.features.as_ref().expect("features").dim();
    let model = common::tiny_config(dim).init(&burn::tensor::Device::flex());
    let k = model::geometry::Intrinsics {
        width: 9,
        height: 9,
        fx: 8.0,
        fy: 8.0,
        cx: 4.0,
        cy: 4.0,
        distortion: model::geometry::Distortion::NONE,
    };
    let b = scene.scene_box;
    let mid: [f64; 3] = std::array::from_fn(|i| 0.5 * (b.min[i] + b.max[i]));
    let eye = [mid[0] + 0.4, mid[1] - 0.3, mid[2] + 0.1];
    let pose = model::geometry::look_at(eye, mid, [0.0, 0.0, 1.0]).expect("pose");
    (
        model,
        scene,
        model::geometry::Camera {
            intrinsics: k,
            pose,
        },
    )
}

#[test]
fn the_probe_renders_the_target_as_the_full_render_does_and_rejects_a_wrong_colour() {
    use field_ops::novel::guided::{FieldProbe, ProposalOptions, color_error};
    let (model, scene, cam) = probe_setup();
    let device = burn::tensor::Device::flex();
    let probe = FieldProbe {
        model: &model,
        scene_box: &scene.scene_box,
        device: &device,
        samples: 16,
        background: Some([0.2, 0.4, 0.6]),
    };
    let centre = probe.centre_color(&cam);
    let settings = field_ops::render::ViewSettings::new(Some([0.2, 0.4, 0.6]), 64);
    let view = field_ops::render::render_view(&model, &cam, &scene.scene_box, &settings)
        .expect("never cancelled without an observer");
    // The 3 x 3 patch around pixel (4, 4) of the full render.
    let mut want = [0.0f64; 3];
    for y in 3..=5 {
        for x in 3..=5 {
            let o = 3 * (y * 9 + x);
            (0..3).for_each(|c| want[c] += view.rgb[o + c] as f64 / 9.0);
        }
    }
    for c in 0..3 {
        assert!((centre[c] - want[c]).abs() < 1e-5, "{centre:?} vs {want:?}");
    }
    // Only the colour decides here: density and transmittance never reject.
    let mid = cam.pose.center();
    let target = std::array::from_fn(|i| mid[i] + 0.3 * cam.pose.forward()[i]);
    let opts = ProposalOptions {
        max_density: f64::INFINITY,
        min_transmittance: 0.0,
        max_color_error: 0.01,
        ..ProposalOptions::default()
    };
    let seen = centre.map(|v| v as f32);
    let ok = probe
        .accept(&cam, target, Some(seen), &opts)
        .expect("faithful render accepted");
    assert!(ok.color_error.expect("checked") < 1e-6);
    let off = [seen[0], seen[1] + 0.05, seen[2] - 0.04];
    assert!(probe.accept(&cam, target, Some(off), &opts).is_none());
    let e = color_error(centre, off);
    assert!(
        (e - ((0.05f64.powi(2) + 0.04f64.powi(2)) / 3.0).sqrt()).abs() < 1e-6,
        "{e}"
    );
    // Without an observed colour it is not measured; with no limit (the
    // default) it is measured and never rejects.
    let unchecked = probe.accept(&cam, target, None, &opts).expect("accepted");
    assert_eq!(unchecked.color_error, None);
    let measured = probe
        .accept(
            &cam,
            target,
            Some(off),
            &ProposalOptions {
                max_color_error: f64::INFINITY,
                ..opts
            },
        )
        .expect("no limit");
    assert!((measured.color_error.expect("measured") - e).abs() < 1e-12);
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

fn eval(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

#[test]
fn the_command_writes_its_files_and_refuses_bad_flags() {
    let tmp = tempfile::tempdir().expect("tmp");
    common::write_tiny_run(tmp.path());
    // An empty field rejects no camera: exactly the views asked for.
    common::make_field_empty(tmp.path());
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
    assert_eq!(frames.len(), 3, "{views}");
    for (i, f) in frames.iter().enumerate() {
        let u = f["uncertainty"].as_f64().expect("u");
        assert!(u > 0.0 && u <= 1.0, "a certain point became a target: {u}");
        // Nothing in the way: the target is seen through empty space.
        assert!(f["transmittance"].as_f64().expect("t") > 0.99, "{f}");
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

/// Runs `eval uncertainty` on `run` with `args` and returns its stderr,
/// checking that it failed without a panic.
fn refused(run: &str, args: &[&str]) -> String {
    let mut all = vec!["uncertainty", "--run", run];
    all.extend_from_slice(args);
    let out = eval(&all);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success() && !err.contains("panicked"),
        "{args:?}: {err}"
    );
    err
}

#[test]
fn a_split_outside_the_scene_or_without_training_frames_is_refused_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    common::write_tiny_run(tmp.path());
    let run = tmp.path().to_str().expect("utf-8");
    let split = tmp.path().join("split.json");
    std::fs::write(&split, r#"{"train": [1, 2, 4000], "heldout": [0]}"#).expect("write");
    let err = refused(run, &["--views", "0"]);
    assert!(err.contains("split.json") && err.contains("4000"), "{err}");
    // No training frames: refused before any file is written.
    std::fs::write(&split, r#"{"train": [], "heldout": [0]}"#).expect("write");
    let err = refused(run, &["--views", "2"]);
    assert!(
        err.contains("split.json") && err.contains("no training frames"),
        "{err}"
    );
    assert!(!tmp.path().join("uncertainty").exists());
}

#[test]
fn sizes_that_would_exhaust_memory_are_refused_with_what_they_need() {
    let tmp = tempfile::tempdir().expect("tmp");
    common::write_tiny_run(tmp.path());
    let run = tmp.path().to_str().expect("utf-8");
    // The full cloud against a cap of about 1 kB: refused, the need named.
    for args in [
        &["--voxel", "0", "--max-memory", "0.000001"][..],
        &["--k", "100000", "--max-memory", "0.000001"],
    ] {
        let err = refused(run, args);
        assert!(
            err.contains("would need") && err.contains("GiB") && err.contains("--max-memory"),
            "{args:?}: {err}"
        );
    }
    for bad in ["0", "-1", "NaN"] {
        let err = refused(run, &["--max-memory", bad]);
        assert!(err.contains("--max-memory"), "{bad}: {err}");
    }
    assert!(!tmp.path().join("uncertainty").exists());
}

#[test]
fn covariances_that_cannot_be_factorised_are_counted_and_reported() {
    let tmp = tempfile::tempdir().expect("tmp");
    common::write_tiny_run(tmp.path());
    let run = tmp.path().to_str().expect("utf-8");
    let summary = |args: &[&str]| {
        let mut all = vec!["uncertainty", "--run", run, "--views", "0"];
        all.extend_from_slice(args);
        let out = eval(&all);
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(out.status.success(), "{err}");
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(tmp.path().join("uncertainty/uncertainty.json"))
                .expect("summary"),
        )
        .expect("json");
        (json, err)
    };
    let (plain, err) = summary(&[]);
    assert_eq!(plain["failed_factorisations"], 0, "{plain}");
    assert!(!err.contains("could not be factorised"), "{err}");
    // The plain sample covariance of points seen by a few views is rank
    // deficient; with an eps far below rounding the factorisation fails.
    let (tiny, err) = summary(&["--prior-weight", "0", "--eps", "1e-300"]);
    let failed = tiny["failed_factorisations"].as_u64().expect("count");
    assert!(failed > 0, "{tiny}");
    assert!(failed <= tiny["seen_twice"].as_u64().expect("seen twice"));
    assert!(
        err.contains(&format!("{failed} of the")) && err.contains("could not be factorised"),
        "{err}"
    );
}
