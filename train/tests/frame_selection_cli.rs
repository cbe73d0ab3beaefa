//! `--stride` and `--max-frames` through the `train` binary, on a small
//! capture of every format on disk: the run keeps the frames they select
//! (counted in its `split.json`) and records them in its `scene.json`; bad
//! values are refused naming the flag.

use std::path::{Path, PathBuf};

mod common;

use common::{TINY, assert_refused, s, text, train};

/// Frames of every capture written here (40x30 pixels each).
const FRAMES: usize = 8;

fn png(path: &Path, i: usize) {
    image::RgbImage::from_fn(40, 30, |x, y| {
        image::Rgb([(x * 6) as u8, (y * 8) as u8, (20 * i) as u8])
    })
    .save(path)
    .expect("png");
}

fn depth_png(path: &Path, (w, h): (u32, u32), value: u16) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(w, h, image::Luma([value]))
        .save(path)
        .expect("depth png");
}

/// Nice-SLAM Replica: cameras stepping along x, 2 m from a wall.
fn replica(root: &Path) -> PathBuf {
    let dir = root.join("replica");
    let results = dir.join("results");
    std::fs::create_dir_all(&results).expect("mkdir");
    std::fs::write(
        dir.join("cam_params.json"),
        r#"{"camera": {"w": 40, "h": 30, "fx": 30.0, "fy": 30.0, "cx": 19.5, "cy": 14.5, "scale": 1000.0}}"#,
    )
    .expect("cam_params");
    let mut traj = String::new();
    for i in 0..FRAMES {
        png(&results.join(format!("frame{i:06}.png")), i);
        depth_png(&results.join(format!("depth{i:06}.png")), (40, 30), 2000);
        traj += &format!("1 0 0 {} 0 1 0 0 0 0 1 0 0 0 0 1\n", 0.05 * i as f64);
    }
    std::fs::write(dir.join("traj.txt"), traj).expect("traj");
    dir
}

/// Blender: cameras on a circle 4 m around the origin, looking at it.
fn blender(root: &Path) -> PathBuf {
    let dir = root.join("blender");
    std::fs::create_dir_all(dir.join("train")).expect("mkdir");
    let frames: Vec<serde_json::Value> = (0..FRAMES)
        .map(|i| {
            png(&dir.join(format!("train/r_{i}.png")), i);
            let a = i as f64 * std::f64::consts::TAU / FRAMES as f64;
            let p = [4.0 * a.cos(), 4.0 * a.sin(), 1.0];
            let n = p.iter().map(|v| v * v).sum::<f64>().sqrt();
            let back = p.map(|v| v / n);
            // right = up x back with up = z, normalised; up' = back x right.
            let r = [-back[1], back[0], 0.0];
            let rn = (r[0] * r[0] + r[1] * r[1]).sqrt();
            let r = r.map(|v| v / rn);
            let u = [
                back[1] * r[2] - back[2] * r[1],
                back[2] * r[0] - back[0] * r[2],
                back[0] * r[1] - back[1] * r[0],
            ];
            let m: Vec<Vec<f64>> = (0..3)
                .map(|k| vec![r[k], u[k], back[k], p[k]])
                .chain([vec![0.0, 0.0, 0.0, 1.0]])
                .collect();
            serde_json::json!({"file_path": format!("./train/r_{i}"), "transform_matrix": m})
        })
        .collect();
    let json = serde_json::json!({"camera_angle_x": 0.69, "frames": frames});
    std::fs::write(dir.join("transforms.json"), json.to_string()).expect("transforms");
    dir
}

/// LLFF: forward-facing cameras stepping along x, in `images/`.
fn llff(root: &Path) -> PathBuf {
    let dir = root.join("llff");
    std::fs::create_dir_all(dir.join("images")).expect("mkdir");
    let mut rows = Vec::new();
    for i in 0..FRAMES {
        png(&dir.join(format!("images/view{i:02}.png")), i);
        // Columns [down, right, backwards, t, hwf] of an OpenCV identity.
        rows.extend_from_slice(&[0.0, 1.0, 0.0, 0.1 * i as f32, 30.0]);
        rows.extend_from_slice(&[1.0, 0.0, 0.0, 0.0, 40.0]);
        rows.extend_from_slice(&[0.0, 0.0, -1.0, 0.0, 38.0]);
        rows.extend_from_slice(&[1.0, 5.0]);
    }
    datasets::npy::write_npy_f32(&dir.join("poses_bounds.npy"), &[FRAMES, 17], &rows).expect("npy");
    dir
}

/// COLMAP: a text model of one PINHOLE camera, images stepping along x
/// looking along +z, 30 points around the origin.
fn colmap(root: &Path) -> PathBuf {
    let dir = root.join("colmap");
    let sparse = dir.join("sparse").join("0");
    std::fs::create_dir_all(&sparse).expect("mkdir");
    std::fs::create_dir_all(dir.join("images")).expect("mkdir");
    let mut images = String::new();
    for i in 0..FRAMES {
        png(&dir.join(format!("images/img{i}.png")), i);
        images += &format!("{} 1 0 0 0 {} 0 3 1 img{i}.png\n\n", i + 1, -0.2 * i as f64);
    }
    let mut points = String::new();
    for i in 0..30 {
        let t = i as f64 / 30.0;
        let (x, y) = ((9.0 * t).sin() * 0.5, (5.0 * t).cos() * 0.4);
        points += &format!(
            "{} {x:.4} {y:.4} {:.4} 200 120 40 0.5 1 0\n",
            i + 1,
            t - 0.5
        );
    }
    for (name, body) in [
        ("cameras.txt", "1 PINHOLE 40 30 38 38 20 15\n".to_string()),
        ("images.txt", images),
        ("points3D.txt", points),
    ] {
        std::fs::write(sparse.join(name), body).expect("model");
    }
    dir
}

/// ScanNet: colour at 40x30, depth at 20x15, cameras stepping along x.
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
    for i in 0..FRAMES {
        png(&dir.join(format!("color/{i}.png")), i);
        depth_png(&dir.join(format!("depth/{i}.png")), (20, 15), 1500);
        let pose = format!("1 0 0 {}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", 0.1 * i as f64);
        std::fs::write(dir.join(format!("pose/{i}.txt")), pose).expect("pose");
    }
    dir
}

/// A 3D Scanner App export without a mesh: cameras 1.5 m up turning about
/// the vertical, LiDAR depth at 20x15.
fn scanner_app(root: &Path) -> PathBuf {
    let dir = root.join("scan");
    std::fs::create_dir_all(&dir).expect("mkdir");
    for i in 0..FRAMES {
        png(&dir.join(format!("frame_{i:05}.jpg")), i);
        let (sn, c) = (i as f64 * 0.3).sin_cos();
        let pose = [
            c,
            0.0,
            sn,
            0.1 * i as f64,
            0.0,
            1.0,
            0.0,
            1.5,
            -sn,
            0.0,
            c,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ];
        let json = serde_json::json!({
            "cameraPoseARFrame": pose,
            "intrinsics": [36.0, 0.0, 19.5, 0.0, 36.0, 14.5, 0.0, 0.0, 1.0],
        });
        std::fs::write(dir.join(format!("frame_{i:05}.json")), json.to_string()).expect("json");
        depth_png(&dir.join(format!("depth_{i:05}.png")), (20, 15), 1800);
    }
    dir
}

/// Writes a capture under a directory, returning its path.
type Writer = fn(&Path) -> PathBuf;

/// Every format with its capture writer.
const CAPTURES: [(&str, Writer); 6] = [
    ("replica", replica),
    ("blender", blender),
    ("llff", llff),
    ("colmap", colmap),
    ("scannet", scannet),
    ("scanner-app", scanner_app),
];

/// Trains 2 iterations on the `format` capture `data` with `extra` flags;
/// returns the number of frames the run kept and its scene's options.
fn kept(tmp: &Path, format: &str, data: &Path, extra: &[&str]) -> (usize, serde_json::Value) {
    let config = tmp.join("tiny.json");
    std::fs::write(&config, TINY).expect("config");
    let out = tmp.join(format!("run-{format}-{}", extra.join("-")));
    let mut args = vec![
        "--dataset",
        format,
        "--data",
        s(data),
        "--config",
        s(&config),
    ];
    args.extend_from_slice(&["--iters", "2", "--holdout-every", "4", "--no-final-render"]);
    args.extend_from_slice(&["--quiet", "--out", s(&out)]);
    args.extend_from_slice(extra);
    let run = train(&args);
    let (_, err) = text(&run);
    assert!(run.status.success(), "{format} {extra:?}: {err}");
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(out.join(name)).expect(name)).expect("json")
    };
    let split = read("split.json");
    let count = |k: &str| split[k].as_array().map_or(0, Vec::len);
    let scene = read("scene.json");
    (
        count("train") + count("heldout"),
        scene["source"]["options"].clone(),
    )
}

#[test]
fn stride_and_max_frames_reach_every_format() {
    let tmp = tempfile::tempdir().expect("tmp");
    for (format, write) in CAPTURES {
        let data = write(tmp.path());
        let (n, options) = kept(tmp.path(), format, &data, &["--stride", "2"]);
        assert_eq!(n, FRAMES / 2, "{format} --stride 2");
        assert_eq!(options["stride"], 2, "{format}: {options}");
        assert_eq!(options["max_frames"], serde_json::Value::Null, "{format}");
        let (n, options) = kept(tmp.path(), format, &data, &["--max-frames", "5"]);
        assert_eq!(n, 5, "{format} --max-frames 5");
        assert_eq!(
            (&options["stride"], &options["max_frames"]),
            (&1.into(), &5.into())
        );
        let (n, _) = kept(
            tmp.path(),
            format,
            &data,
            &["--stride", "3", "--max-frames", "2"],
        );
        assert_eq!(n, 2, "{format} --stride 3 --max-frames 2");
    }
}

#[test]
fn bad_strides_and_frame_counts_are_refused_naming_the_flag() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = replica(tmp.path());
    let out = tmp.path().join("run");
    for flag in ["--stride", "--max-frames"] {
        for (value, words) in [
            ("0", &["at least 1"][..]),
            ("-2", &["\"-2\"", "at least 1"][..]),
            ("two", &["\"two\"", "whole number"][..]),
        ] {
            let args = ["--data", s(&data), flag, value, "--out", s(&out)];
            assert_refused(&args, &[&[flag][..], words].concat());
            assert!(
                !out.exists(),
                "{flag} {value}: a refused run wrote its directory"
            );
        }
    }
    // The synthetic scene makes its own frames.
    assert_refused(&["--max-frames", "3"], &["--max-frames", "synthetic"]);
}

/// A resolution is refused where the loader reads pre-sized images, naming
/// what to use instead; Replica resamples.
#[test]
fn resolution_reaches_the_loaders_that_resample() {
    let tmp = tempfile::tempdir().expect("tmp");
    for (format, instead) in [
        ("blender", "--downscale"),
        ("colmap", "--downscale"),
        ("llff", ""),
    ] {
        let data = CAPTURES.iter().find(|c| c.0 == format).expect("format").1(tmp.path());
        let args = [
            "--dataset",
            format,
            "--data",
            s(&data),
            "--resolution",
            "20x15",
        ];
        assert_refused(&args, &["--resolution", format, instead]);
    }
    let data = replica(tmp.path());
    let (n, options) = kept(tmp.path(), "replica", &data, &["--resolution", "20x15"]);
    assert_eq!(
        (n, &options["resolution"]),
        (FRAMES, &serde_json::json!([20, 15]))
    );
}
