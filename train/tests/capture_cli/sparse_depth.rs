//! `--sparse-depth`: the sparse points as depth targets under `on` where
//! the model links features to points, left out by `auto`, and refused
//! where they cannot apply.

use super::*;

/// The rig's model with each image's features: the projections of the
/// points it sees (PINHOLE f 38, principal point (20, 15), camera centre
/// (0.2 i, 0, -3) looking along +z).
fn model_with_features() -> [String; 3] {
    let [cameras, _, points] = model_text();
    let mut images = "# Image list\n".to_string();
    for i in 0..IMAGES {
        let cx = 0.2 * i as f64;
        let features: Vec<String> = points
            .lines()
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| {
                let v: Vec<f64> = l
                    .split(' ')
                    .take(4)
                    .map(|x| x.parse().expect("number"))
                    .collect();
                let (u, w) = (
                    38.0 * (v[1] - cx) / (v[3] + 3.0) + 20.0,
                    38.0 * v[2] / (v[3] + 3.0) + 15.0,
                );
                (u > 0.0 && w > 0.0 && u < 40.0 && w < 30.0).then(|| format!("{u} {w} {}", v[0]))
            })
            .collect();
        images += &format!(
            "{} 1 0 0 0 {} 0 3 1 img{i}.png\n{}\n",
            i + 1,
            -cx,
            features.join(" ")
        );
    }
    [cameras, images, points]
}

fn depth_rays(run: &Path) -> u64 {
    let config: serde_json::Value =
        serde_json::from_slice(&std::fs::read(run.join("config.json")).expect("config.json"))
            .expect("json");
    config["sampler"]["depth_rays"]
        .as_u64()
        .expect("depth_rays")
}

/// The scene a run's `scene.json` rebuilds.
fn rebuilt_scene(run: &Path) -> datasets::Scene {
    let meta: datasets::SceneMeta =
        serde_json::from_slice(&std::fs::read(run.join("scene.json")).expect("scene.json"))
            .expect("scene.json parses");
    datasets::load_scene(&meta.source).expect("scene rebuilds")
}

#[test]
fn on_supervises_depth_where_features_see_points_and_auto_leaves_them_out() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = capture(tmp.path(), &model_with_features());
    let out = tmp.path().join("run");
    let o = run(tmp.path(), &data, &out, &["--sparse-depth", "on"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("depth: the sparse points give depth targets at")
            && err.contains("pixels of 4 photographs; 8 of the 32 rays of each batch")
            && err.contains("(--sparse-depth on)"),
        "{err}"
    );
    // A quarter of the tiny configuration's 32 rays.
    assert_eq!(depth_rays(&out), 8);
    // The rebuilt scene has the targets: the run records the choice.
    let scene = rebuilt_scene(&out);
    assert!(scene.frames.iter().all(|f| f.depth.is_some()));
    // A batch of three rays: one of them.
    let small = tmp.path().join("small");
    let o = run(
        tmp.path(),
        &data,
        &small,
        &["--sparse-depth", "on", "--rays", "3"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("1 of the 3 rays of each batch"), "{err}");
    assert_eq!(depth_rays(&small), 1);
    // Auto (the default): no targets, no depth rays, and a line that says
    // why and how to turn them on.
    let auto = tmp.path().join("auto");
    let o = run(tmp.path(), &data, &auto, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("sparse points give depth"), "{err}");
    assert!(
        err.contains("depth: none from the sparse points (auto:")
            && err.contains("--sparse-depth on draws a quarter of each batch"),
        "{err}"
    );
    assert_eq!(depth_rays(&auto), 0);
    let scene = rebuilt_scene(&auto);
    assert!(scene.frames.iter().all(|f| f.depth.is_none()));
    // Off: no targets, no depth rays, no line about them.
    let off = tmp.path().join("off");
    let o = run(tmp.path(), &data, &off, &["--sparse-depth", "off"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("sparse points give depth"), "{err}");
    assert!(!err.contains("depth: none from the sparse points"), "{err}");
    assert_eq!(depth_rays(&off), 0);
    // A model whose images link no feature to a point: auto gives no
    // targets.
    let bare = capture(&tmp.path().join("bare"), &model_text());
    let plain = tmp.path().join("plain");
    let o = run(tmp.path(), &bare, &plain, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("sparse points give depth"), "{err}");
    assert_eq!(depth_rays(&plain), 0);
}

#[test]
fn sparse_depth_on_is_refused_where_it_cannot_apply() {
    let tmp = tempfile::tempdir().expect("tmp");
    let bare = capture(tmp.path(), &model_text());
    assert_refused(
        tmp.path(),
        &bare,
        &["--sparse-depth", "on"],
        &["--sparse-depth on", "observes a sparse point", "points3D"],
    );
    assert_refused(
        tmp.path(),
        &bare,
        &["--sparse-depth", "on", "--colmap-depth"],
        &["--sparse-depth on and --colmap-depth", "choose one"],
    );
    assert_refused(
        tmp.path(),
        &bare,
        &["--sparse-depth", "sometimes"],
        &["--sparse-depth", "auto, off, on"],
    );
}

#[test]
fn sparse_depth_is_refused_for_scenes_without_sparse_points() {
    let tmp = tempfile::tempdir().expect("tmp");
    let replica = tmp.path().join("replica");
    std::fs::create_dir_all(replica.join("results")).expect("mkdir");
    std::fs::write(replica.join("traj.txt"), "").expect("write");
    assert_refused(
        tmp.path(),
        &replica,
        &["--sparse-depth", "on"],
        &["--sparse-depth on is not supported for --dataset replica"],
    );
    common::assert_refused(
        &["--sparse-depth", "on", "--iters", "2"],
        &["--sparse-depth", "applies to a scene on disk"],
    );
}
