//! Captures at a phone's own size through the `train` binary, on Record3D
//! exports written here from the built-in synthetic scene: a video's
//! default stride, the sharpest frame of each window, the training size
//! chosen for large images (recorded, so the scene is rebuilt at it), and
//! a capture too large for the memory limit refused before any image is
//! decoded; bad values of the new flags are refused naming the flag.

use std::path::{Path, PathBuf};

mod common;

use common::{assert_refused, s, text, train_tiny};
use datasets::writer::{Record3dExport, sharp_frames, write_record3d};
use datasets::{SceneMeta, SceneSource};

/// A Record3D export of `frames` frames at `size` into `root/name`.
fn export(
    root: &Path,
    name: &str,
    frames: usize,
    size: (u32, u32),
    fps: f64,
    blur: Option<usize>,
) -> PathBuf {
    let scene = datasets::load_scene(&SceneSource::Synthetic {
        seed: 0,
        size: "ci".into(),
        pca: None,
    })
    .expect("the synthetic scene");
    let dir = root.join(name);
    write_record3d(
        &scene,
        &dir,
        &Record3dExport {
            frames,
            size,
            fps,
            blur_window: blur,
            ..Record3dExport::default()
        },
    )
    .expect("write the export");
    dir
}

/// Trains one iteration of the tiny model on `data` into `run` with
/// `extra` flags; returns stderr, asserting success.
fn one_iteration(root: &Path, data: &Path, run: &Path, extra: &[&str]) -> String {
    let out = train_tiny(root, data, run, "1", extra);
    let (_, err) = text(&out);
    assert!(out.status.success(), "{extra:?}: {err}");
    err
}

/// The scene a run recorded.
fn recorded(run: &Path) -> SceneMeta {
    let text = std::fs::read_to_string(run.join("scene.json")).expect("scene.json");
    serde_json::from_str(&text).expect("scene.json parses")
}

#[test]
fn a_record3d_video_keeps_about_three_frames_a_second_by_default() {
    let tmp = tempfile::tempdir().expect("tmp");
    // 80 frames at 12 fps: every 4th keeps 3 a second, 20 frames.
    let data = export(tmp.path(), "video", 80, (64, 48), 12.0, None);
    let run = tmp.path().join("run");
    let err = one_iteration(tmp.path(), &data, &run, &[]);
    assert!(
        err.contains(
            "frames: every 4th of the 80 frames (20 kept, 3.0 a second of the 12 fps video"
        ),
        "{err}"
    );
    let meta = recorded(&run);
    let SceneSource::Disk { loader, .. } = meta.source else {
        panic!("a disk scene");
    };
    assert_eq!(loader.selection().stride, 4);
    // --stride 1 keeps every frame, and nothing is said about a default.
    let all = tmp.path().join("all");
    let err = one_iteration(tmp.path(), &data, &all, &["--stride", "1"]);
    assert!(!err.contains("auto: a Record3D video"), "{err}");
    let split = std::fs::read_to_string(all.join("split.json")).expect("split.json");
    let split: serde_json::Value = serde_json::from_str(&split).expect("split parses");
    let count = |k: &str| split[k].as_array().map_or(0, Vec::len);
    assert_eq!(count("train") + count("heldout"), 80, "{split}");
    // A short video keeps at least 20 frames: 30 frames at 12 fps, every
    // one of them.
    let short = export(tmp.path(), "short", 30, (64, 48), 12.0, None);
    let run = tmp.path().join("short-run");
    let err = one_iteration(tmp.path(), &short, &run, &[]);
    assert!(!err.contains("auto: about"), "{err}");
    let SceneSource::Disk { loader, .. } = recorded(&run).source else {
        panic!("a disk scene");
    };
    assert_eq!(loader.selection().stride, 1);
    // 50 frames at 60 fps: every 2nd, not every 20th.
    let brief = export(tmp.path(), "brief", 50, (64, 48), 60.0, None);
    let run = tmp.path().join("brief-run");
    let err = one_iteration(tmp.path(), &brief, &run, &[]);
    assert!(err.contains("every 2nd of the 50 frames (25 kept"), "{err}");
}

#[test]
fn sharpest_of_keeps_the_sharp_frame_of_each_window() {
    let tmp = tempfile::tempdir().expect("tmp");
    // One sharp frame in each window of 4, at a moving offset.
    let data = export(tmp.path(), "blurry", 24, (160, 120), 60.0, Some(4));
    let mut loader = datasets::LoaderOptions::Record3d(datasets::PhoneOptions::default());
    loader.selection_mut().sharpest_of = Some(4);
    let scene = datasets::load_disk(&data, &loader).expect("load");
    let names: Vec<&str> = scene.frames.iter().map(|f| f.name.as_str()).collect();
    let want: Vec<String> = sharp_frames(24, 4)
        .into_iter()
        .map(|j| format!("frame_{j:05}"))
        .collect();
    assert_eq!(names, want);
    assert_eq!(want.len(), 6);
    // The same through the command line, which says how it chose.
    let run = tmp.path().join("run");
    let err = one_iteration(tmp.path(), &data, &run, &["--sharpest-of", "4"]);
    assert!(
        err.contains(
            "kept the sharpest frame of each 4 (6 of 24, by the variance of the Laplacian)"
        ),
        "{err}"
    );
    let SceneSource::Disk { loader, .. } = recorded(&run).source else {
        panic!("a disk scene");
    };
    assert_eq!(loader.selection().sharpest_of, Some(4));
    assert_eq!(
        loader.selection().stride,
        1,
        "no default stride with --sharpest-of"
    );
}

#[test]
fn phone_sized_frames_train_at_960_and_the_size_is_recorded() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = export(tmp.path(), "large", 6, (1920, 1440), 60.0, None);
    let run = tmp.path().join("run");
    let err = one_iteration(tmp.path(), &data, &run, &["--stride", "1"]);
    assert!(
        err.contains("training resolution 960x720 of the images' 1920x1440"),
        "{err}"
    );
    let meta = recorded(&run);
    let SceneSource::Disk { loader, .. } = &meta.source else {
        panic!("a disk scene");
    };
    assert_eq!(loader.selection().resolution, Some((960, 720)));
    // Rebuilt from scene.json (as eval does), the frames have that size.
    let rebuilt = datasets::load_scene(&meta.source).expect("rebuild");
    assert_eq!(rebuilt.frames.len(), 6);
    assert!(
        rebuilt
            .frames
            .iter()
            .all(|f| (f.rgb.width, f.rgb.height) == (960, 720))
    );
    // Colour is kept as bytes: a quarter of the memory of floats.
    assert_eq!(rebuilt.frames[0].rgb.memory_bytes(), 960 * 720 * 3);
    // A size asked for is taken as it is.
    let asked = tmp.path().join("asked");
    let err = one_iteration(
        tmp.path(),
        &data,
        &asked,
        &["--stride", "1", "--resolution", "320x240"],
    );
    assert!(!err.contains("training resolution"), "{err}");
    let SceneSource::Disk { loader, .. } = recorded(&asked).source else {
        panic!("a disk scene");
    };
    assert_eq!(loader.selection().resolution, Some((320, 240)));
}

#[test]
fn a_capture_over_the_memory_limit_is_refused_before_loading() {
    let tmp = tempfile::tempdir().expect("tmp");
    let data = export(tmp.path(), "large", 6, (1920, 1440), 60.0, None);
    let run = tmp.path().join("run");
    // Every frame at full size, under a limit they do not fit in.
    let over = [
        "--stride",
        "1",
        "--resolution",
        "1920x1440",
        "--max-memory",
        "760M",
    ];
    let err = assert_refused(
        &[&["--data", s(&data), "--out", s(&run)], &over[..]].concat(),
        &[
            "6 frames at 1920x1440 would need about",
            "more than the 0.80 GB allowed (--max-memory)",
            "--resolution",
            "--max-memory with more memory",
        ],
    );
    assert!(err.contains(s(&data)), "{err}");
    assert!(!run.join("model.bpk").exists());
    // The number of frames it names fits under the same limit.
    let fits = err
        .split("--max-frames ")
        .nth(1)
        .and_then(|t| t.split(';').next())
        .expect("a number of frames that fits");
    let fitted = tmp.path().join("fitted");
    one_iteration(
        tmp.path(),
        &data,
        &fitted,
        &[&over[..], &["--max-frames", fits]].concat(),
    );
    for (args, words) in [
        (vec!["--max-memory", "0"], vec!["--max-memory", "positive"]),
        (vec!["--max-memory", "12X"], vec!["--max-memory", "unit"]),
        (vec!["--max-memory", "lots"], vec!["--max-memory", "8G"]),
        (
            vec!["--sharpest-of", "0"],
            vec!["--sharpest-of", "at least 1"],
        ),
        (
            vec!["--sharpest-of", "3", "--stride", "2"],
            vec!["--sharpest-of", "--stride"],
        ),
    ] {
        let mut all = vec!["--data", s(&data), "--out", s(&run)];
        all.extend(args);
        assert_refused(&all, &words);
    }
}
