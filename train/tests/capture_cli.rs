//! Real captures through the `train` binary: a small COLMAP text model
//! trains, and each kind of broken capture stops with an error naming the
//! file and the problem, before the run directory is created.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::{json, s, train, train_tiny};

const IMAGES: usize = 4;

/// The text model of a small rig walked around an object: one PINHOLE
/// camera (40x30), four images 3 units from the origin looking at it from
/// 0.5 rad apart about the y axis (world-to-camera: that rotation, then 3
/// along +z), 30 points around the origin.
fn model_text() -> [String; 3] {
    let cameras = "# Camera list\n1 PINHOLE 40 30 38 38 20 15\n".to_string();
    let mut images = "# Image list\n".to_string();
    for i in 0..IMAGES {
        let half = 0.25 * i as f64;
        images += &format!(
            "{} {:.9} 0 {:.9} 0 0 0 3 1 img{i}.png\n\n",
            i + 1,
            half.cos(),
            half.sin()
        );
    }
    let mut points = "# 3D point list\n".to_string();
    for i in 0..30 {
        let t = i as f64 / 30.0;
        points += &format!(
            "{} {:.4} {:.4} {:.4} 200 120 40 0.5 1 0\n",
            i + 1,
            (9.0 * t).sin() * 0.5,
            (5.0 * t).cos() * 0.4,
            t - 0.5
        );
    }
    [cameras, images, points]
}

/// A COLMAP directory with the rig's images and `text` as its model.
fn capture(root: &Path, text: &[String; 3]) -> PathBuf {
    let dir = root.join("capture");
    let sparse = dir.join("sparse").join("0");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    for (name, body) in ["cameras.txt", "images.txt", "points3D.txt"]
        .iter()
        .zip(text)
    {
        std::fs::write(sparse.join(name), body).expect("write model");
    }
    let images = dir.join("images");
    std::fs::create_dir_all(&images).expect("mkdir");
    for i in 0..IMAGES {
        image::RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(x * 6) as u8, (y * 8) as u8, 90])
        })
        .save(images.join(format!("img{i}.png")))
        .expect("png");
    }
    dir
}

/// Trains two iterations on `data` into `out` with the tiny model.
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
    let out = tmp.join("run");
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
fn a_colmap_text_model_trains_and_records_its_frame() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = capture(tmp.path(), &model_text());
    let out = tmp.path().join("run");
    let o = run(tmp.path(), &data, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("is a colmap scene"), "{err}");
    assert!(err.contains("--frame colmap"), "{err}");
    // Auto: the unbounded field with appearance codes, each said so.
    assert!(
        err.contains("field: unbounded (auto: a photographed object walked around"),
        "{err}"
    );
    assert!(
        err.contains("appearance: a learned appearance code per photograph")
            && err.contains("(auto: a photographed object walked around: appearance codes"),
        "{err}"
    );
    // With the box field asked for, the capture's other settings stay:
    // one flag changes one setting.
    let boxed = tmp.path().join("boxed");
    let o = run(tmp.path(), &data, &boxed, &["--field", "box"]);
    let box_err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{box_err}");
    assert!(
        box_err.contains("field: box (--field box)")
            && box_err.contains(
                "appearance: a learned appearance code per photograph (held-out and novel \
                 views: the zero code) (auto: a photographed object walked around"
            ),
        "{box_err}"
    );
    let meta: datasets::SceneMeta =
        serde_json::from_slice(&std::fs::read(out.join("scene.json")).expect("scene.json"))
            .expect("scene.json parses");
    let world = meta.world.expect("capture frame recorded");
    assert_eq!(world.name, "colmap");
    // The recorded map takes the first camera's centre, (0, 0, -3) in
    // COLMAP's frame, to where the rebuilt scene has it.
    let scene = datasets::load_scene(&meta.source).expect("scene rebuilds");
    let c = world.to_scene.apply_point([0.0, 0.0, -3.0]);
    let got = scene.frames[0].camera.pose.center();
    assert!(
        (0..3).all(|i| (c[i] - got[i]).abs() < 1e-9),
        "{c:?} vs {got:?}"
    );
}

#[test]
fn broken_colmap_models_are_refused_by_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let edit = |part: usize, from: &str, to: &str| {
        let mut text = model_text();
        assert!(text[part].contains(from), "{from:?}");
        text[part] = text[part].replacen(from, to, 1);
        let root = tmp.path().join(format!("case-{part}-{}", to.len()));
        capture(&root, &text)
    };
    let data = edit(1, " 1 img2.png", " 9 img2.png");
    assert_refused(
        tmp.path(),
        &data,
        &[],
        &["images.txt", "img2.png", "camera 9"],
    );
    let data = edit(
        0,
        "PINHOLE 40 30 38 38 20 15",
        "OPENCV_FISHEYE 40 30 38 38 20 15 0 0 0 0",
    );
    assert_refused(
        tmp.path(),
        &data,
        &[],
        &["cameras.txt", "OPENCV_FISHEYE", "image_undistorter"],
    );
    let mut text = model_text();
    text[2] = text[2]
        .lines()
        .map(|l| match l.starts_with("4 ") {
            true => "4 NaN 0.1 0.1 200 120 40 0.5 1 0",
            false => l,
        })
        .collect::<Vec<_>>()
        .join("\n");
    let data = capture(&tmp.path().join("nan"), &text);
    assert_refused(tmp.path(), &data, &[], &["points3D.txt", "point 4"]);
    let data = capture(&tmp.path().join("missing"), &model_text());
    std::fs::remove_file(data.join("images").join("img3.png")).expect("rm");
    assert_refused(tmp.path(), &data, &[], &["img3.png", "not found"]);
    // Dense depth asked for, one map of the wrong aspect ratio.
    let data = capture(&tmp.path().join("depth"), &model_text());
    let maps = data.join("stereo").join("depth_maps");
    std::fs::create_dir_all(&maps).expect("mkdir");
    for i in 0..IMAGES {
        let (w, h) = if i == 1 { (30, 40) } else { (40, 30) };
        let mut bytes = format!("{w}&{h}&1&").into_bytes();
        (0..w * h).for_each(|_| bytes.extend_from_slice(&2.5f32.to_le_bytes()));
        std::fs::write(maps.join(format!("img{i}.png.geometric.bin")), bytes).expect("map");
    }
    assert_refused(
        tmp.path(),
        &data,
        &["--colmap-depth"],
        &["img1.png.geometric.bin", "aspect ratio"],
    );
}

/// COLMAP's binary model of a real capture, cut short.
#[test]
fn a_truncated_binary_model_is_refused() {
    // Skipped only on a machine without the shared data at all.
    let Some(statue) = datasets::shared_dataset("colmap_statue") else {
        return;
    };
    let tmp = tempfile::tempdir().expect("tmp");
    let data = tmp.path().join("statue");
    let sparse = data.join("sparse");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    for name in ["cameras.bin", "images.bin", "points3D.bin"] {
        let bytes = std::fs::read(statue.join("sparse").join(name)).expect("read");
        let keep = if name == "images.bin" {
            bytes.len() / 2
        } else {
            bytes.len()
        };
        std::fs::write(sparse.join(name), &bytes[..keep]).expect("write");
    }
    std::fs::create_dir_all(data.join("images")).expect("mkdir");
    assert_refused(tmp.path(), &data, &[], &["images.bin", "truncated"]);
}

/// A ScanNet export of four 40x30 frames with depth at 20x15 (the same
/// view), frame 2's pose lost (`-inf`, as ScanNet writes it).
fn scannet(root: &Path) -> PathBuf {
    let dir = root.join("scannet");
    for sub in ["color", "depth", "pose", "intrinsic"] {
        std::fs::create_dir_all(dir.join(sub)).expect("mkdir");
    }
    let k = |f: f64, cx: f64, cy: f64| format!("{f} 0 {cx} 0\n0 {f} {cy} 0\n0 0 1 0\n0 0 0 1\n");
    std::fs::write(
        dir.join("intrinsic/intrinsic_color.txt"),
        k(38.0, 19.5, 14.5),
    )
    .expect("k");
    std::fs::write(
        dir.join("intrinsic/intrinsic_depth.txt"),
        k(19.0, 9.75, 7.25),
    )
    .expect("k");
    for i in 0..4 {
        image::RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(x * 6) as u8, (y * 8) as u8, 90])
        })
        .save(dir.join(format!("color/{i}.png")))
        .expect("png");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(20, 15, image::Luma([1500]))
            .save(dir.join(format!("depth/{i}.png")))
            .expect("png");
        let pose = if i == 2 {
            "-inf -inf -inf -inf\n".repeat(4)
        } else {
            format!("1 0 0 {}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", 0.1 * i as f64)
        };
        std::fs::write(dir.join(format!("pose/{i}.txt")), pose).expect("pose");
    }
    dir
}

#[test]
fn a_scannet_export_skips_lost_poses_and_refuses_bad_depth() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = scannet(tmp.path());
    let out = tmp.path().join("trained");
    let o = run(tmp.path(), &data, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("is a scannet scene"), "{err}");
    assert!(
        err.contains("skipped 1 frames with invalid poses (pose/2.txt)"),
        "{err}"
    );
    // Depth of another size than its intrinsics describe.
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(20, 20, image::Luma([1500]))
        .save(data.join("depth/1.png"))
        .expect("png");
    assert_refused(tmp.path(), &data, &[], &["depth/1.png"]);
}

/// `--preset` reads where the cameras stand: the rig looks at its points
/// from outside their box (an object: 256 rays a batch, the lego
/// settings, with the grid when the field is the box), the synthetic room's cameras stand inside it (128 rays a
/// batch and more iterations); explicit flags still win over the preset.
#[test]
fn presets_follow_where_the_cameras_stand() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = capture(tmp.path(), &model_text());
    let run = |name: &str, scene: &[&str], extra: &[&str]| -> (String, serde_json::Value) {
        let out = tmp.path().join(name);
        let mut args = scene.to_vec();
        args.extend_from_slice(&["--stop-at", "1", "--no-final-render", "--quiet"]);
        args.extend_from_slice(&["--out", s(&out)]);
        args.extend_from_slice(extra);
        let o = train(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{name}: {err}");
        let config =
            serde_json::from_slice(&std::fs::read(out.join("config.json")).expect("config"))
                .expect("config.json parses");
        (err, config)
    };
    let knobs = |c: &serde_json::Value| {
        (
            c["model"]["num_samples"].as_u64(),
            c["sampler"]["rays_per_batch"].as_u64(),
            c["schedule"]["iterations"].as_u64(),
            c["occupancy"]["enabled"].as_bool(),
        )
    };
    let rig = ["--data", s(&data), "--holdout-every", "4"];
    let (err, c) = run("object", &rig, &["--preset", "fast", "--field", "box"]);
    assert!(
        err.contains("preset fast with the object settings"),
        "{err}"
    );
    assert_eq!(knobs(&c), (Some(16), Some(256), Some(1600), Some(true)));
    // A COLMAP capture's auto field is unbounded: the preset's grid stays
    // off, said so.
    let (err, c) = run("object-auto", &rig, &["--preset", "fast"]);
    assert!(
        err.contains("no occupancy grid (the field is unbounded)"),
        "{err}"
    );
    assert_eq!(knobs(&c), (Some(16), Some(256), Some(1600), Some(false)));
    let room = ["--scene-size", "ci"];
    let (err, c) = run("room", &room, &["--preset", "balanced"]);
    assert!(
        err.contains("preset balanced with the room settings"),
        "{err}"
    );
    assert_eq!(knobs(&c), (Some(24), Some(128), Some(4150), Some(true)));
    let (_, c) = run(
        "flags",
        &room,
        &["--preset", "best", "--rays", "64", "--iters", "9"],
    );
    assert_eq!(knobs(&c), (Some(24), Some(64), Some(9), Some(true)));
}

#[path = "capture_cli/sparse_depth.rs"]
mod sparse_depth;

#[test]
fn the_fast_field_takes_its_own_samples_only_with_its_proposal_networks() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = capture(tmp.path(), &model_text());
    // The tiny sizes without the samples, so that the capture's row sets them.
    let config = tmp.path().join("unsized.json");
    std::fs::write(
        &config,
        r#"{"model": {"head": {"width": 8, "layers": 1}},
            "sampler": {"rays_per_batch": 32, "border_margin": 2},
            "logging": {"checkpoint_every": 2, "eval_every": 0, "eval_pixels": 64}}"#,
    )
    .expect("config");
    let trained = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let args = [
            &[
                "--data",
                s(&data),
                "--config",
                s(&config),
                "--iters",
                "1",
                "--holdout-every",
                "4",
                "--no-final-render",
                "--quiet",
                "--out",
                s(&out),
                "--field-model",
                "fast",
            ][..],
            extra,
        ]
        .concat();
        let o = train(&args);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        let saved = json(&out.join("config.json"));
        (err, saved["model"]["num_samples"].as_u64())
    };
    let (err, samples) = trained("proposal", &[]);
    assert_eq!(samples, Some(24), "{err}");
    assert!(
        err.contains("sampling: 24 samples per ray and level")
            && err.contains("the fast field's proposal networks place 24 samples"),
        "{err}"
    );
    // On its coarse and fine levels it samples as the row says for the
    // Mip-NeRF field (the built-in 48), and says nothing of 24.
    let (err, samples) = trained("coarse-fine", &["--sampler", "coarse-fine"]);
    assert_eq!(samples, Some(48), "{err}");
    assert!(!err.contains("24 samples"), "{err}");
}
