//! Outputs in a capture's own world frame (`--frame colmap`) and points
//! without ground truth (a capture's sparse cloud), through the `eval`
//! binary on an untrained tiny run whose `scene.json` records a capture
//! frame.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use datasets::points::{PointCloud, read_ply, write_ply};
use model::geometry::{Similarity, Vec3};

/// COLMAP frame -> scene frame of the test run.
fn to_scene() -> Similarity {
    let (c, s) = (0.8f64, 0.6f64);
    Similarity {
        rotation: [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        scale: 0.25,
        translation: [0.4, -0.3, 1.1],
    }
}

/// The tiny run with `world` recorded in its `scene.json`, and the class
/// embeddings of its scene as `.npy` + names.
fn run_with_world(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let run = dir.join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    common::write_tiny_run(&run);
    let path = run.join("scene.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).expect("scene.json")).expect("json");
    meta["world"] = serde_json::json!({ "name": "colmap", "to_scene": to_scene() });
    std::fs::write(&path, meta.to_string()).expect("write");
    let scene =
        datasets::synthetic::generate(0, datasets::synthetic::SceneSize::Ci).expect("scene");
    let (npy, names) = (dir.join("classes.npy"), dir.join("classes.txt"));
    scene
        .classes
        .as_ref()
        .expect("classes")
        .save(&npy, &names)
        .expect("save classes");
    (run, npy, names)
}

fn eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn refused(out: &Output, words: &[&str]) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !err.contains("panicked"), "{err}");
    for w in words {
        assert!(err.contains(w), "{w:?} not in {err}");
    }
}

fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

/// Points in the scene's frame spread over the synthetic room.
fn scene_points() -> Vec<Vec3> {
    (0..40)
        .map(|i| {
            let t = i as f64 / 40.0;
            [-1.5 + 3.0 * t, 0.8 * (7.0 * t).sin(), 0.3 + t]
        })
        .collect()
}

fn write_points(path: &Path, positions: Vec<Vec3>) {
    let cloud = PointCloud {
        positions,
        colors: None,
        labels: None,
    };
    write_ply(path, &cloud, &[]).expect("ply");
}

#[test]
fn unlabelled_points_are_segmented_in_the_capture_frame() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (run, npy, names) = run_with_world(tmp.path());
    let s = |p: &Path| p.display().to_string();
    let in_scene = scene_points();
    let in_colmap: Vec<Vec3> = in_scene
        .iter()
        .map(|&p| to_scene().inverse().apply_point(p))
        .collect();
    let (ply_scene, ply_colmap) = (tmp.path().join("scene.ply"), tmp.path().join("colmap.ply"));
    write_points(&ply_scene, in_scene.clone());
    write_points(&ply_colmap, in_colmap.clone());
    let segment = |ply: &Path, frame: &str, out: &Path| {
        eval(&[
            "segment",
            "--run",
            &s(&run),
            "--points",
            &s(ply),
            "--embeddings",
            &s(&npy),
            "--names",
            &s(&names),
            "--frame",
            frame,
            "--out",
            &s(out),
            "--max-views",
            "2",
            "--render-scale",
            "0.5",
            "--mode",
            "project",
        ])
    };
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let stdout = ok(&segment(&ply_colmap, "colmap", &a));
    assert!(stdout.contains("no ground-truth labels"), "{stdout}");
    ok(&segment(&ply_scene, "scene", &b));
    // No scores and no error cloud without ground truth.
    for dir in [&a, &b] {
        assert!(!dir.join("segmentation.json").exists());
        assert!(!dir.join("segmentation_project_error.ply").exists());
    }
    let pa = read_ply(&a.join("segmentation_project_pred.ply")).expect("pred a");
    let pb = read_ply(&b.join("segmentation_project_pred.ply")).expect("pred b");
    // The same points, given in either frame, get the same classes, and each
    // output is written in the frame its input was given in.
    assert_eq!(pa.labels, pb.labels);
    // ... and that says something: which points the views see (the others
    // get no class, -1) depends on where they are, so points read in the
    // wrong frame are classed differently.
    let labels = pa.labels.as_ref().expect("labels");
    let distinct: std::collections::BTreeSet<i64> = labels.iter().copied().collect();
    assert!(
        distinct.len() >= 2,
        "one class for every point: {distinct:?}"
    );
    ok(&segment(&ply_colmap, "scene", &tmp.path().join("wrong")));
    let wrong = read_ply(&tmp.path().join("wrong/segmentation_project_pred.ply")).expect("wrong");
    assert_ne!(wrong.labels, pa.labels, "the frame changes nothing");
    for i in 0..in_scene.len() {
        assert!(
            close(pa.positions[i], in_colmap[i], 1e-5),
            "{i}: {:?}",
            pa.positions[i]
        );
        assert!(close(pb.positions[i], in_scene[i], 1e-5), "{i}");
    }
    // Scores need ground truth; another frame's name is refused.
    refused(
        &eval(&[
            "segment",
            "--run",
            &s(&run),
            "--points",
            &s(&ply_scene),
            "--embeddings",
            &s(&npy),
            "--names",
            &s(&names),
            "--compare",
        ]),
        &["--compare", "no labels"],
    );
    refused(
        &eval(&["segment", "--run", &s(&run), "--frame", "nerfstudio"]),
        &["--frame nerfstudio", "`colmap`"],
    );
    // Without --embeddings the scene's own classes are used: the same ones.
    let c = tmp.path().join("c");
    ok(&eval(&[
        "segment",
        "--run",
        &s(&run),
        "--points",
        &s(&ply_scene),
        "--out",
        &s(&c),
        "--max-views",
        "2",
        "--render-scale",
        "0.5",
        "--mode",
        "project",
    ]));
    let pc = read_ply(&c.join("segmentation_project_pred.ply")).expect("pred c");
    assert_eq!(pc.labels, pb.labels);
}

#[test]
fn render_writes_camera_poses_in_the_chosen_frame() {
    let tmp = tempfile::tempdir().expect("tmp");
    let (run, _, _) = run_with_world(tmp.path());
    let s = |p: &Path| p.display().to_string();
    let poses = |frame: &str| -> Vec<[[f64; 4]; 4]> {
        let out = tmp.path().join(frame);
        ok(&eval(&[
            "render",
            "--run",
            &s(&run),
            "--out",
            &s(&out),
            "--frame",
            frame,
            "--width",
            "8",
        ]));
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("cameras.json")).expect("cameras"))
                .expect("json");
        assert_eq!(v["frame"], frame);
        v["cameras"]
            .as_array()
            .expect("list")
            .iter()
            .map(|c| serde_json::from_value(c["camera_to_world"].clone()).expect("matrix"))
            .collect()
    };
    let (scene, colmap) = (poses("scene"), poses("colmap"));
    assert!(!scene.is_empty());
    assert_eq!(scene.len(), colmap.len());
    let back = to_scene().inverse();
    for (a, b) in scene.iter().zip(&colmap) {
        let centre = back.apply_point([a[0][3], a[1][3], a[2][3]]);
        assert!(close(centre, [b[0][3], b[1][3], b[2][3]], 1e-9));
        // Viewing direction rotated, not scaled.
        let fwd = back
            .apply_vector([a[0][2], a[1][2], a[2][2]])
            .map(|x| x / back.scale);
        assert!(close(fwd, [b[0][2], b[1][2], b[2][2]], 1e-9));
    }
}
