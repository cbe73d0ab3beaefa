//! End to end: train a tiny field on the CI synthetic scene, then segment
//! its labelled point cloud in every mode and compare with the 2D-feature
//! projection bound and the ground-truth-feature oracle.

use burn::tensor::Device;
use datasets::synthetic::{SceneSize, generate};
use eval::commands::common::PointArgs;
use eval::commands::segment::{SegmentArgs, segment_command};
use eval::metrics::format_table;
use eval::segment::{
    EvalPoints, SegmentMode, SegmentOptions, evaluate, scene_views, segment_oracle,
    segment_with_2d_features, segment_with_field,
};
use field_ops::project::ProjectOptions;
use field_ops::run_dir::load_run;
use train::{SessionOptions, TrainConfig, train_new};

#[test]
fn train_then_segment_in_every_mode() {
    let scene = generate(7, SceneSize::Ci).expect("CI scene");
    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let mut config = TrainConfig::tiny(dim);
    config.schedule.iterations = 300;
    let dir = tempfile::tempdir().expect("temp dir");
    let session = SessionOptions {
        final_render: false,
        ..Default::default()
    };
    train_new(&scene, config, 8, dir.path(), &session).expect("training");

    let device = Device::flex();
    let run = load_run(dir.path(), &device).expect("load run");
    let points = EvalPoints::from_scene(&scene).expect("points");
    // Chance levels: uniform random prediction has expected mAcc 1/C; always
    // predicting the most frequent class gives the majority mIoU.
    let chance = 1.0 / points.names.len() as f64;
    let mut counts = vec![0usize; points.names.len()];
    for &l in &points.labels {
        if let Some(c) = counts.get_mut(l as usize) {
            *c += 1;
        }
    }
    let majority =
        *counts.iter().max().expect("classes") as f64 / counts.iter().sum::<usize>() as f64;
    let present = counts.iter().filter(|&&c| c > 0).count() as f64;
    let majority_miou = majority / present;
    let views = scene_views(&scene, &run.split.train, true).expect("views");
    let mut results = Vec::new();
    for mode in [
        SegmentMode::Sampled,
        SegmentMode::Project,
        SegmentMode::Hybrid,
    ] {
        let opts = SegmentOptions {
            mode,
            ..Default::default()
        };
        let (pred, seen) = segment_with_field(
            &run.model,
            run.meta.pca.as_ref(),
            &points,
            &views,
            &run.meta.scene_box,
            run.meta.background,
            &opts,
            &device,
        )
        .expect("segment");
        assert!(
            seen > points.positions.len() / 2,
            "{mode}: only {seen} points seen"
        );
        results.push((
            mode.to_string(),
            evaluate(&mode.to_string(), &points, &pred),
        ));
    }
    let features = scene.features.as_ref().expect("features");
    let maps: Vec<_> = run.split.train.iter().map(|&i| &features.maps[i]).collect();
    let pred =
        segment_with_2d_features(features, &maps, &points, &views, &ProjectOptions::default())
            .expect("2D bound");
    results.push((
        "2D-feature projection".into(),
        evaluate("2d", &points, &pred),
    ));
    let pred = segment_oracle(&points).expect("oracle");
    results.push((
        "oracle (GT features)".into(),
        evaluate("oracle", &points, &pred),
    ));

    let rows: Vec<(&str, _)> = results.iter().map(|(l, r)| (l.as_str(), r)).collect();
    println!(
        "CI scene, {} points, {} classes; chance mAcc {:.1}, majority-class mIoU {:.1}",
        points.positions.len(),
        points.names.len(),
        100.0 * chance,
        100.0 * majority_miou
    );
    print!("{}", format_table(&rows));

    let miou = |i: usize| results[i].1.all.miou.expect("mIoU");
    let macc = |i: usize| results[i].1.all.macc.expect("mAcc");
    for (label, r) in &results {
        for v in [r.all.miou, r.all.macc].into_iter().flatten() {
            assert!((0.0..=1.0).contains(&v), "{label}: {v}");
        }
    }
    assert!((miou(4) - 1.0).abs() < 1e-12, "oracle mIoU {}", miou(4));
    assert!(
        macc(3) > 3.0 * chance,
        "2D bound mAcc {} not well above chance",
        macc(3)
    );
    assert!(
        miou(3) > 3.0 * majority_miou,
        "2D bound mIoU {} not well above chance",
        miou(3)
    );
    for (label, r) in results.iter().take(3) {
        let (mi, ma) = (r.all.miou.expect("mIoU"), r.all.macc.expect("mAcc"));
        assert!(ma > chance, "{label}: mAcc {ma} not above chance");
        assert!(
            mi > majority_miou,
            "{label}: mIoU {mi} not above the majority class"
        );
    }

    // The command-line path writes the JSON and the coloured point clouds.
    let out = dir.path().join("seg").join("segmentation.json");
    let args = SegmentArgs {
        run: dir.path().to_path_buf(),
        mode: SegmentMode::Hybrid,
        data: PointArgs::default(),
        cameras: "train".into(),
        cam_params: None,
        rendered_depth: false,
        render_scale: 1.0,
        max_views: Some(8),
        radius: 0.01,
        chunk: 4096,
        split: None,
        out: Some(dir.path().join("seg")),
        compute: field_ops::backend::BackendArgs {
            backend: field_ops::backend::BackendKind::Flex,
            device: None,
        },
        compare: true,
        classes: None,
        text_model: None,
        frame: Default::default(),
    };
    let scores = segment_command(&args)
        .expect("segment command")
        .expect("labelled points are scored");
    assert_eq!(scores.mode, "hybrid");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).expect("json")).expect("parse");
    assert_eq!(json["mode"], "hybrid");
    for key in ["all", "head", "common", "tail"] {
        assert!(json[key].is_object(), "{key} missing");
    }
    assert!(
        json["per_class"]
            .as_array()
            .is_some_and(|a| a.len() == points.names.len())
    );
    assert!(dir.path().join("seg/segmentation_hybrid_pred.ply").exists());
    // `--compare`: the three field modes, the 2D-feature bound and the oracle.
    let compare: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("seg/segmentation_compare.json"))
            .expect("compare json"),
    )
    .expect("parse compare");
    let rows = compare.as_array().expect("rows");
    let modes: Vec<&str> = rows.iter().filter_map(|r| r["mode"].as_str()).collect();
    assert_eq!(
        modes,
        [
            "sampled",
            "project",
            "hybrid",
            "2D-feature projection",
            "oracle (GT features)"
        ]
    );
    assert_eq!(rows[4]["all"]["miou"].as_f64(), Some(1.0));
    assert!(
        dir.path()
            .join("seg/segmentation_hybrid_error.ply")
            .exists()
    );
}
