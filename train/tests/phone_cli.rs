//! Phone captures through the `train` binary: a small 3D Scanner App
//! export trains (format detected, frame recorded, mesh as the point
//! cloud), and each kind of broken export stops with an error naming the
//! file and the problem, before the run directory is created.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::train_tiny;

const FRAMES: usize = 4;

/// Frame `i`'s camera-to-world in ARKit's conventions: a camera 1.5 m up,
/// turning about the vertical (y) axis, looking down its -z.
fn pose(i: usize) -> Vec<f64> {
    let a = i as f64 * 0.5;
    let (sn, c) = a.sin_cos();
    vec![
        c,
        0.0,
        sn,
        0.1 * i as f64, //
        0.0,
        1.0,
        0.0,
        1.5, //
        -sn,
        0.0,
        c,
        0.0, //
        0.0,
        0.0,
        0.0,
        1.0,
    ]
}

/// A 3D Scanner App export of four 40x30 frames with 20x15 depth and
/// confidence maps and a textured box mesh.
fn export(root: &Path) -> PathBuf {
    let dir = root.join("scan");
    std::fs::create_dir_all(&dir).expect("mkdir");
    for i in 0..FRAMES {
        let img = image::RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(6 * x) as u8, (8 * y) as u8, (60 * i) as u8])
        });
        img.save(dir.join(format!("frame_{i:05}.jpg")))
            .expect("jpg");
        let json = serde_json::json!({
            "cameraPoseARFrame": pose(i),
            "intrinsics": [36.0, 0.0, 19.5, 0.0, 36.0, 14.5, 0.0, 0.0, 1.0],
        });
        std::fs::write(dir.join(format!("frame_{i:05}.json")), json.to_string()).expect("json");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(20, 15, image::Luma([1800]))
            .save(dir.join(format!("depth_{i:05}.png")))
            .expect("depth");
        image::GrayImage::from_fn(20, 15, |x, _| image::Luma([(x % 3) as u8]))
            .save(dir.join(format!("conf_{i:05}.png")))
            .expect("conf");
    }
    let mut obj = String::from("mtllib textured_output.mtl\nusemtl m\n");
    for (x, y, z) in [
        (-2.0, 0.0, -2.0),
        (2.0, 0.0, -2.0),
        (2.0, 0.0, 2.0),
        (-2.0, 0.0, 2.0),
        (-2.0, 3.0, -2.0),
        (2.0, 3.0, -2.0),
        (2.0, 3.0, 2.0),
        (-2.0, 3.0, 2.0),
    ] {
        obj += &format!("v {x} {y} {z}\nvt {} {}\n", (x + 2.0) / 4.0, y / 3.0);
    }
    for [a, b, c] in [
        [1, 2, 3],
        [1, 3, 4],
        [5, 7, 6],
        [5, 8, 7],
        [1, 5, 6],
        [1, 6, 2],
        [2, 6, 7],
        [2, 7, 3],
        [3, 7, 8],
        [3, 8, 4],
        [4, 8, 5],
        [4, 5, 1],
    ] {
        obj += &format!("f {a}/{a} {b}/{b} {c}/{c}\n");
    }
    std::fs::write(dir.join("textured_output.obj"), obj).expect("obj");
    std::fs::write(
        dir.join("textured_output.mtl"),
        "newmtl m\nmap_Kd textured_output.jpg\n",
    )
    .expect("mtl");
    image::RgbImage::from_pixel(8, 8, image::Rgb([200, 30, 30]))
        .save(dir.join("textured_output.jpg"))
        .expect("texture");
    dir
}

fn run(tmp: &Path, data: &Path, out: &Path, extra: &[&str]) -> Output {
    train_tiny(
        tmp,
        data,
        out,
        "2",
        &[&["--holdout-every", "4"], extra].concat(),
    )
}

/// Asserts a clean refusal naming every `words`, with nothing written.
fn assert_refused(tmp: &Path, data: &Path, extra: &[&str], words: &[&str]) {
    let out = tmp.join("refused");
    let o = run(tmp, data, &out, extra);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "succeeded: {err}");
    assert!(!err.contains("panicked"), "panicked: {err}");
    for w in words {
        assert!(err.contains(w), "{w:?} not in {err:?}");
    }
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    eprintln!("refused:\n{}", err.trim_end());
}

#[test]
fn a_scanner_app_export_trains_with_its_frame_and_mesh() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = export(tmp.path());
    let out = tmp.path().join("run");
    let o = run(tmp.path(), &data, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("is a scanner-app scene"), "{err}");
    // 14 of the 20 columns of the confidence map are below high.
    assert!(err.contains("70.0% of depth pixels below high"), "{err}");
    let meta: datasets::SceneMeta =
        serde_json::from_slice(&std::fs::read(out.join("scene.json")).expect("scene.json"))
            .expect("scene.json parses");
    let world = meta.world.clone().expect("the ARKit frame is recorded");
    assert_eq!(world.name, "arkit");
    // ARKit's y (up) is the scene's z, metric.
    let up = world.to_scene.apply_vector([0.0, 1.0, 0.0]);
    assert!(
        (up[2] - 1.0).abs() < 1e-12 && world.to_scene.scale == 1.0,
        "{up:?}"
    );
    // The run rebuilds in its recorded frame, and is refused in another.
    let dir = field_ops::run_dir::RunDir::new(&out);
    field_ops::run_dir::rebuild_scene(&dir, &meta).expect("the run rebuilds in its frame");
    let mut moved = meta.clone();
    moved.world.as_mut().expect("frame").to_scene =
        model::geometry::yaw_rotation(0.2).compose(&world.to_scene);
    let e = field_ops::run_dir::rebuild_scene(&dir, &moved)
        .err()
        .expect("another frame is refused")
        .to_string();
    assert!(
        e.contains("scene.json") && e.contains("`arkit` frame"),
        "{e}"
    );
    let scene = datasets::load_scene(&meta.source).expect("scene rebuilds");
    let cloud = scene.points.expect("the mesh is the point cloud");
    assert_eq!(cloud.positions.len(), 8);
    assert!(
        cloud
            .colors
            .expect("texture colours")
            .iter()
            .all(|c| c[0] > 150 && c[1] < 80),
        "the texture's red"
    );
    // --min-depth-confidence low keeps every measured pixel.
    let out = tmp.path().join("low");
    let o = run(tmp.path(), &data, &out, &["--min-depth-confidence", "low"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("0.0% of depth pixels below low"), "{err}");
}

#[test]
fn broken_phone_exports_are_refused_naming_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let fresh = |name: &str| {
        let root = tmp.path().join(name);
        export(&root)
    };
    let json = |dir: &Path, i: usize| dir.join(format!("frame_{i:05}.json"));
    // A JSON without its pose.
    let d = fresh("no-pose");
    std::fs::write(
        json(&d, 1),
        r#"{"intrinsics": [36,0,19.5,0,36,14.5,0,0,1]}"#,
    )
    .expect("w");
    assert_refused(
        tmp.path(),
        &d,
        &[],
        &["frame_00001.json", "no `cameraPoseARFrame`"],
    );
    // A pose that is not a rigid transform.
    let d = fresh("skewed");
    let mut p = pose(2);
    p[0] = 2.0;
    let body = serde_json::json!({"cameraPoseARFrame": p,
        "intrinsics": [36.0, 0.0, 19.5, 0.0, 36.0, 14.5, 0.0, 0.0, 1.0]});
    std::fs::write(json(&d, 2), body.to_string()).expect("w");
    assert_refused(tmp.path(), &d, &[], &["frame_00002.json", "rigid"]);
    // Intrinsics of the wrong length.
    let d = fresh("short-k");
    let body =
        serde_json::json!({"cameraPoseARFrame": pose(0), "intrinsics": [36.0, 0.0, 19.5, 0.0]});
    std::fs::write(json(&d, 0), body.to_string()).expect("w");
    assert_refused(
        tmp.path(),
        &d,
        &[],
        &["frame_00000.json", "`intrinsics` has 4 numbers, expected 9"],
    );
    // An OBJ face pointing past the vertex list.
    let d = fresh("bad-face");
    let obj = d.join("textured_output.obj");
    let mut text = std::fs::read_to_string(&obj).expect("obj");
    text += "f 1/1 2/2 40/40\n";
    std::fs::write(&obj, text).expect("w");
    assert_refused(tmp.path(), &d, &[], &["textured_output.obj", "vert"]);
    // Depth of another aspect ratio than the colour image.
    let d = fresh("bad-depth");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(20, 20, image::Luma([1500]))
        .save(d.join("depth_00003.png"))
        .expect("png");
    assert_refused(tmp.path(), &d, &[], &["depth_00003.png", "aspect"]);
    // A confidence map of another size than its depth map.
    let d = fresh("bad-conf");
    image::GrayImage::from_pixel(10, 15, image::Luma([2]))
        .save(d.join("conf_00001.png"))
        .expect("png");
    assert_refused(tmp.path(), &d, &[], &["conf_00001.png", "10x15"]);
    // An empty export directory.
    let d = tmp.path().join("empty");
    std::fs::create_dir_all(&d).expect("mkdir");
    assert_refused(
        tmp.path(),
        &d,
        &[],
        &["no scene format recognised", "scanner-app"],
    );
    assert_refused(
        tmp.path(),
        &d,
        &["--dataset", "scanner-app"],
        &["empty", "the export directory is empty"],
    );
    // Flags at their bad values, and where they do not apply.
    let d = fresh("flags");
    assert_refused(tmp.path(), &d, &["--max-depth", "0"], &["--max-depth 0"]);
    assert_refused(
        tmp.path(),
        &d,
        &["--max-depth", "NaN"],
        &["--max-depth NaN"],
    );
    assert_refused(
        tmp.path(),
        &d,
        &["--min-depth-confidence", "most"],
        &["most"],
    );
    assert_refused(tmp.path(), &d, &["--downscale", "2"], &["--downscale"]);
    let replica = tmp.path().join("replica");
    std::fs::create_dir_all(replica.join("results")).expect("mkdir");
    std::fs::write(replica.join("traj.txt"), "").expect("w");
    assert_refused(
        tmp.path(),
        &replica,
        &["--max-depth", "3"],
        &["--max-depth (phone captures only) is not supported for --dataset replica"],
    );
}

/// A missing texture leaves the cloud without colour, said once; the run
/// still trains.
#[test]
fn a_missing_texture_trains_without_colour_said_once() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = export(tmp.path());
    std::fs::remove_file(data.join("textured_output.jpg")).expect("rm");
    let out = tmp.path().join("run");
    let o = run(tmp.path(), &data, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("textured_output.jpg").count(), 1, "{err}");
    let meta: datasets::SceneMeta =
        serde_json::from_slice(&std::fs::read(out.join("scene.json")).expect("scene.json"))
            .expect("scene.json parses");
    let scene = datasets::load_scene(&meta.source).expect("scene rebuilds");
    assert!(scene.points.expect("cloud").colors.is_none());
}
