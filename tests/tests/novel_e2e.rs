//! End-to-end novel views on the CI scene: views rendered part-way through
//! training are recorded in the run directory, a run stopped before or after
//! they were added resumes to the same weights, and evaluation rebuilds the
//! augmented scene.

use burn::tensor::Device;
use field_ops::novel::{NovelMode, NovelViewConfig};
use field_ops::run_dir::{RunDir, Split, load_run_scene};
use tests::{
    ci_scene, flex_session as session, run_weights as weights, scratch_dir, serial, tiny_config,
};
use train::TrainConfig;

fn config(mode: NovelMode) -> TrainConfig {
    let scene = ci_scene();
    let mut c = tiny_config(scene, 90);
    c.logging.eval_every = 0;
    c.logging.checkpoint_every = 30;
    c.novel = NovelViewConfig {
        views: 3,
        after: Some(45),
        mode,
        voxel: 0.2,
        ..NovelViewConfig::default()
    };
    c
}

#[test]
fn novel_views_are_recorded_resumed_bit_identically_and_evaluated() {
    let _guard = serial();
    let scene = ci_scene();
    let n = scene.frames.len();
    let whole = scratch_dir();
    let cfg = config(NovelMode::Guided);
    let a = train::train_new(scene, cfg.clone(), 4, whole.path(), &session(None)).unwrap();
    assert_eq!(a.summary.iterations, 90);

    // The record: three views at iteration 45, each with colour, masked
    // depth at the configured weight and compressed features.
    let run = RunDir::new(whole.path());
    let record = datasets::novel_record::read_record(&run.novel())
        .unwrap()
        .expect("views.json");
    assert_eq!((record.mode.as_str(), record.added_at), ("guided", 45));
    assert_eq!(record.views.len(), 3, "{record:?}");
    let dim = scene.features.as_ref().unwrap().dim();
    let views = datasets::novel_record::load_views(&run.novel(), &record, dim).unwrap();
    // A field this young is opaque enough in some views only: the depth is
    // kept there (within the scene) and masked to 0 elsewhere.
    let diagonal = {
        let b = &scene.scene_box;
        (0..3)
            .map(|a| (b.max[a] - b.min[a]).powi(2))
            .sum::<f64>()
            .sqrt() as f32
    };
    let mut trusted = 0usize;
    for (frame, map) in &views {
        assert_eq!(frame.depth_weight, cfg.novel.depth_weight);
        let depth = frame.depth.as_ref().unwrap();
        assert!(
            depth
                .to_f32()
                .iter()
                .all(|d| d.is_finite() && (0.0..=diagonal).contains(d)),
            "{}",
            frame.name
        );
        trusted += depth.to_f32().iter().filter(|d| **d > 0.0).count();
        assert_eq!(map.dim, dim);
        let e = record.views.iter().find(|e| e.name == frame.name).unwrap();
        let t = e.target.expect("guided views have targets");
        let p = frame.camera.project(t).expect("the target is in front");
        assert!((p.u - frame.camera.intrinsics.cx).abs() < 1e-6);
    }
    assert!(trusted > 0, "no view kept any rendered depth");
    let metrics = std::fs::read_to_string(run.metrics()).unwrap();
    assert!(
        metrics.contains("\"event\":\"novel_views\""),
        "the addition is logged"
    );

    // Stopped after the views were added (checkpoint 60), or before them
    // (checkpoint 30, the views are then made by the resumed session):
    // both resume to the weights of the uninterrupted run.
    for stop in [60, 30] {
        let parts = scratch_dir();
        train::train_new(scene, cfg.clone(), 4, parts.path(), &session(Some(stop))).unwrap();
        assert_eq!(
            RunDir::new(parts.path())
                .novel()
                .join("views.json")
                .exists(),
            stop > 45
        );
        let b = train::resume(parts.path(), None, &session(None)).unwrap();
        assert_eq!(b.summary.iterations, 90);
        assert!(
            weights(whole.path()) == weights(parts.path()),
            "stopped at {stop}: the resumed weights differ"
        );
        let again = datasets::novel_record::read_record(&RunDir::new(parts.path()).novel())
            .unwrap()
            .unwrap();
        assert_eq!(again, record, "stopped at {stop}");
    }

    // Evaluation rebuilds the augmented scene: the views are training frames.
    let meta: datasets::SceneMeta =
        serde_json::from_str(&std::fs::read_to_string(run.scene()).unwrap()).unwrap();
    let mut split: Split =
        serde_json::from_str(&std::fs::read_to_string(run.split()).unwrap()).unwrap();
    let base_train = split.train.len();
    let rebuilt = load_run_scene(&run, &meta, &mut split).unwrap();
    assert_eq!(rebuilt.frames.len(), n + 3);
    assert_eq!(split.train.len(), base_train + 3);
    assert_eq!(&split.train[base_train..], &[n, n + 1, n + 2]);
    let ctx = eval::commands::common::Context::load(whole.path(), &Device::flex()).unwrap();
    assert_eq!(ctx.scene.as_ref().unwrap().frames.len(), n + 3);
    assert!(ctx.run.split.train.contains(&(n + 2)));
    drop(ctx);
    #[derive(clap::Parser)]
    struct Segment {
        #[command(flatten)]
        args: eval::commands::segment::SegmentArgs,
    }
    let seg = scratch_dir();
    let out = seg.path().join("segmentation.json");
    let args = <Segment as clap::Parser>::try_parse_from([
        "segment".as_ref(),
        "--run".as_ref(),
        whole.path().as_os_str(),
        "--max-views".as_ref(),
        "2".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ])
    .unwrap()
    .args;
    let scores = eval::commands::segment::segment_command(&args)
        .unwrap()
        .expect("labelled points are scored");
    assert!(scores.all.miou.is_some_and(f64::is_finite), "{scores:?}");
    assert!(out.exists());
}

#[test]
fn a_run_without_novel_views_writes_no_record_and_bad_settings_are_refused() {
    let _guard = serial();
    let scene = ci_scene();
    let dir = scratch_dir();
    let mut cfg = config(NovelMode::None);
    cfg.schedule.iterations = 20;
    cfg.novel.after = Some(10);
    train::train_new(scene, cfg.clone(), 4, dir.path(), &session(None)).unwrap();
    assert!(!RunDir::new(dir.path()).novel().exists());

    // Due after the schedule's end: refused before anything is written.
    let late = scratch_dir();
    let mut bad = cfg.clone();
    bad.novel.mode = NovelMode::Trajectory;
    bad.novel.after = Some(20);
    let e = train::train_new(scene, bad, 4, late.path(), &session(None)).unwrap_err();
    assert!(e.to_string().contains("--novel-after"), "{e}");
    assert!(!late.path().join("config.json").exists());
}

#[test]
fn trajectory_views_sit_half_way_between_consecutive_training_cameras() {
    use model::geometry::{add_scaled, dot, norm, sub};
    let scene = ci_scene();
    let train: Vec<usize> = (0..scene.frames.len()).filter(|i| i % 4 != 0).collect();
    let up = field_ops::novel::cameras::scene_up(scene, &train);
    let cams = field_ops::novel::cameras::trajectory_cameras(scene, &train, 5, up);
    assert_eq!(cams.len(), 5);
    for c in &cams {
        let p = c.pose.center();
        let between = train.windows(2).any(|w| {
            let (a, b) = (&scene.frames[w[0]].camera, &scene.frames[w[1]].camera);
            let mid = add_scaled(a.pose.center(), 0.5, sub(b.pose.center(), a.pose.center()));
            let f = add_scaled(a.pose.forward(), 1.0, b.pose.forward());
            norm(sub(p, mid)) < 1e-9 && dot(c.pose.forward(), f) / norm(f) > 1.0 - 1e-9
        });
        assert!(between, "{p:?} is not half-way along the path");
        assert!(c.pose.orthonormality_error() < 1e-9);
    }
    // No more views than segments of the path.
    let all = field_ops::novel::cameras::trajectory_cameras(scene, &train, 1000, up);
    assert_eq!(all.len(), train.len() - 1);
    assert!(field_ops::novel::cameras::trajectory_cameras(scene, &train[..1], 3, up).is_empty());
}
