//! The `eval` binary on bad arguments and inputs (an error naming the flag
//! or file, never a panic or a silently wrong result) and on the outputs
//! meant for reading: held-out renders next to the ground truth, camera-path
//! GIFs, relevancy images with one scale, `segment --out DIR`.
//!
//! The run directory is made here without training: an untrained tiny field
//! on the synthetic CI scene loads, renders and segments like a trained one.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use datasets::points::{PointCloud, write_ply};

/// A run directory of an untrained tiny field on the synthetic CI scene
/// (seed 0), made once per test binary; tests copy it when they change it.
fn run_dir() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        common::write_tiny_run(dir.path());
        dir
    })
    .path()
}

fn copy_run(to: &Path) -> PathBuf {
    let dst = to.join("run");
    std::fs::create_dir_all(&dst).expect("mkdir");
    for name in ["model.bpk", "config.json", "scene.json", "split.json"] {
        std::fs::copy(run_dir().join(name), dst.join(name)).expect("copy");
    }
    dst
}

fn eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

/// Asserts the command failed cleanly (no panic) with every `words` in its
/// error output.
fn assert_refused(args: &[&str], words: &[&str]) {
    let out = eval(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for w in words {
        assert!(err.contains(w), "{args:?}: {w:?} not in {err:?}");
    }
    // Shown with `--nocapture`: the message a user gets for this input.
    eprintln!("refused {args:?}:\n{}", err.trim_end());
}

const MISSING: &str = "/nonexistent/run";

#[test]
fn zero_sizes_and_counts_are_refused_by_flag() {
    for (args, flag) in [
        (
            &["render", "--run", MISSING, "--width", "0"][..],
            "--width 0",
        ),
        (&["render", "--run", MISSING, "--height", "0"], "--height 0"),
        (
            &["render", "--run", MISSING, "--max-views", "0"],
            "--max-views 0",
        ),
        (
            &["render", "--run", MISSING, "--camera-path", "0"],
            "--camera-path 0",
        ),
        (
            &["query", "--run", MISSING, "--query", "sofa", "--width", "0"],
            "--width 0",
        ),
        (
            &["segment", "--run", MISSING, "--max-views", "0"],
            "--max-views 0",
        ),
        (
            &["segment", "--run", MISSING, "--render-scale", "0"],
            "--render-scale 0",
        ),
    ] {
        assert_refused(args, &[flag]);
    }
    // 0 views is not "all views": the message says how to get all of them.
    assert_refused(
        &["segment", "--run", MISSING, "--max-views", "0"],
        &["leave the flag out"],
    );
}

#[test]
fn a_termination_outside_0_to_1_is_refused() {
    for value in ["1", "--termination=-0.5", "NaN", "inf"] {
        let args: Vec<&str> = if value.starts_with("--") {
            vec!["render", "--run", MISSING, value]
        } else {
            vec!["render", "--run", MISSING, "--termination", value]
        };
        assert_refused(&args, &["--termination", "[0, 1)"]);
    }
    assert_refused(
        &[
            "query",
            "--run",
            MISSING,
            "--query",
            "sofa",
            "--termination",
            "2",
        ],
        &["--termination 2"],
    );
}

#[test]
fn nan_or_negative_radius_is_refused() {
    for r in ["NaN", "-0.5", "inf"] {
        assert_refused(&["segment", "--run", MISSING, "--radius", r], &["--radius"]);
        assert_refused(
            &["query", "--run", MISSING, "--query", "sofa", "--radius", r],
            &["--radius"],
        );
    }
}

/// Every subcommand takes the same `--backend` and `--device` (`uncertainty`
/// included), refused at a bad value before any file is read.
#[test]
fn every_subcommand_refuses_a_bad_backend_or_device() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("maps");
    let out = out.to_str().expect("utf-8");
    let commands: [&[&str]; 6] = [
        &["segment", "--run", MISSING],
        &["query", "--run", MISSING, "--query", "sofa"],
        &["render", "--run", MISSING],
        &["uncertainty", "--run", MISSING],
        &["view", "--run", MISSING],
        &["extract", "--vlm", MISSING, "--out", out],
    ];
    for command in commands {
        let with = |extra: &[&'static str]| {
            let mut args = command.to_vec();
            args.extend_from_slice(extra);
            args
        };
        assert_refused(
            &with(&["--backend", "cuda"]),
            &["'cuda'", "--backend", "flex", "ndarray", "wgpu"],
        );
        assert_refused(&with(&["--device", "gpu0"]), &["--device", "adapter index"]);
        assert_refused(
            &with(&["--backend", "ndarray", "--device", "1"]),
            &["--device", "the backend is ndarray", "--backend wgpu"],
        );
    }
    assert!(!Path::new(out).exists(), "extract wrote {out}");
}

/// `segment --mode` and `extract --dense` take a fixed set of values:
/// another is refused with the set.
#[test]
fn a_mode_or_dense_variant_outside_its_set_is_listed_against_it() {
    assert_refused(
        &["segment", "--run", MISSING, "--mode", "projected"],
        &["'projected'", "--mode", "sampled", "project", "hybrid"],
    );
    assert_refused(
        &[
            "extract", "--vlm", MISSING, "--out", MISSING, "--dense", "clip",
        ],
        &["'clip'", "--dense", "naclip", "clearclip", "maskclip"],
    );
    let help = eval(&["segment", "--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(help.contains("[default: hybrid]"), "{help}");
    // Every mode explains itself where `--mode` is described.
    assert!(help.contains("no view sees"), "{help}");
}

#[test]
fn device_means_an_adapter_index_as_in_train() {
    assert_refused(
        &["render", "--run", MISSING, "--device", "ndarray"],
        &["--backend ndarray"],
    );
    assert_refused(
        &["render", "--run", MISSING, "--device", "0"],
        &["--device", "--backend wgpu"],
    );
}

#[test]
fn query_embedding_of_the_wrong_dimension_is_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    let q = tmp.path().join("q7.npy");
    datasets::npy::write_npy_f32(&q, &[7], &[0.1; 7]).expect("npy");
    let run = run_dir().display().to_string();
    assert_refused(
        &[
            "query",
            "--run",
            &run,
            "--query-npy",
            q.to_str().expect("utf-8"),
        ],
        &["q7.npy", "7 values", "features have"],
    );
}

#[test]
fn split_with_a_frame_outside_the_scene_names_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = copy_run(tmp.path());
    std::fs::write(
        run.join("split.json"),
        r#"{"train": [1], "heldout": [999]}"#,
    )
    .expect("write");
    let r = run.display().to_string();
    assert_refused(
        &["render", "--run", &r, "--cameras", "heldout"],
        &["split.json", "frame 999"],
    );
}

#[test]
fn point_labels_outside_the_classes_are_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    let ply = tmp.path().join("labels_out_of_range.ply");
    let cloud = PointCloud {
        positions: vec![[0.0, 0.0, 0.0], [0.1, 0.2, 0.3]],
        colors: None,
        labels: Some(vec![1000, 2000]),
    };
    write_ply(&ply, &cloud, &[]).expect("ply");
    let run = run_dir().display().to_string();
    assert_refused(
        &[
            "segment",
            "--run",
            &run,
            "--points",
            ply.to_str().expect("utf-8"),
        ],
        &["labels_out_of_range.ply", "outside the"],
    );
}

#[test]
fn render_writes_strips_a_contact_sheet_readable_depth_and_a_path_gif() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("renders");
    let run = run_dir().display().to_string();
    let o = out.display().to_string();
    let r = eval(&["render", "--run", &run, "--out", &o]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    // Scene frames are scored against their images.
    assert!(stdout.contains("PSNR against the"), "{stdout}");
    assert!(stdout.contains("SSIM"), "{stdout}");
    assert!(stdout.contains("samples a ray evaluated"), "{stdout}");
    // photograph | render | error | depth, at the render's size.
    let strip = image::open(out.join("frame000000_strip.png")).expect("strip");
    let rgb = image::open(out.join("frame000000_rgb.png")).expect("render");
    assert_eq!(strip.width(), 4 * rgb.width());
    assert_eq!(strip.height(), rgb.height());
    let opacity = image::open(out.join("frame000000_opacity.png")).expect("opacity");
    assert_eq!(opacity.width(), rgb.width());
    let sheet = image::open(out.join("heldout.png")).expect("contact sheet");
    assert_eq!(sheet.height() % 120, 0, "{}", sheet.height() % 120);
    // The depth image's scale: a box field's depth in metres.
    let scale: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("frame000000_depth.json")).expect("depth scale"),
    )
    .expect("json");
    assert_eq!(
        (scale["quantity"].as_str(), scale["units"].as_str()),
        (Some("depth"), Some("m"))
    );
    assert!(scale["lo"].as_f64() <= scale["hi"].as_f64(), "{scale}");
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("render_metrics.json")).expect("render metrics"),
    )
    .expect("json");
    let views = metrics["views"].as_array().expect("views");
    assert!(!views.is_empty(), "{metrics}");
    for v in views {
        let s = v["ssim"].as_f64().expect("ssim");
        assert!((-1.0..=1.0).contains(&s), "{v}");
        assert!(v["photograph_resized_from"].is_null(), "{v}");
    }

    // At another size than the photographs, they are resized to the renders.
    let small = tmp.path().join("small");
    let o2 = small.display().to_string();
    let r = eval(&["render", "--run", &run, "--out", &o2, "--width", "40"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        stdout.contains("photographs resized to the renders"),
        "{stdout}"
    );
    let strip = image::open(small.join("frame000000_strip.png")).expect("strip");
    assert_eq!(strip.width(), 160);
    let metrics: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(small.join("render_metrics.json")).expect("render metrics"),
    )
    .expect("json");
    assert_eq!(
        metrics["views"][0]["photograph_resized_from"],
        serde_json::json!([rgb.width(), rgb.height()])
    );

    let r = eval(&["render", "--run", &run, "--out", &o, "--camera-path", "4"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("path.gif"), "{stdout}");
    use image::AnimationDecoder;
    // Colour, and depth on one scale over the path.
    for name in ["path.gif", "path_depth.gif"] {
        let gif = std::fs::File::open(out.join(name)).expect("gif");
        let frames =
            image::codecs::gif::GifDecoder::new(std::io::BufReader::new(gif)).expect("decode");
        assert_eq!(frames.into_frames().count(), 4, "{name}");
    }
    assert!(out.join("path_depth.json").exists());
}

#[test]
fn segment_out_is_a_directory_and_every_file_is_listed() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("seg");
    let run = run_dir().display().to_string();
    let o = out.display().to_string();
    let r = eval(&[
        "segment",
        "--run",
        &run,
        "--out",
        &o,
        "--max-views",
        "2",
        "--render-scale",
        "0.5",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    for name in [
        "segmentation.json",
        "segmentation_hybrid_pred.ply",
        "segmentation_hybrid_error.ply",
    ] {
        assert!(out.join(name).exists(), "{name} not written");
        assert!(
            stdout.contains(&format!("wrote {}", out.join(name).display())),
            "{stdout}"
        );
    }
    // An existing file is not a directory to write into.
    let file = out.join("segmentation.json").display().to_string();
    assert_refused(
        &["segment", "--run", &run, "--out", &file],
        &["--out", "directory"],
    );
}

#[test]
fn relevancy_images_share_one_scale_and_carry_a_colour_bar() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("q");
    let run = run_dir().display().to_string();
    let o = out.display().to_string();
    let r = eval(&[
        "query",
        "--run",
        &run,
        "--query",
        "sofa",
        "--cameras",
        "all",
        "--max-views",
        "3",
        "--out",
        &o,
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("relevancy scale over 3 views"), "{stdout}");
    let written: Vec<PathBuf> = std::fs::read_dir(&out)
        .expect("out dir")
        .map(|e| e.expect("entry").path())
        .collect();
    assert_eq!(written.len(), 3, "{written:?}");
    for p in &written {
        let img = image::open(p).expect("png");
        // Wider than the 96-pixel view: the colour bar and its labels.
        assert!(img.width() > 96, "{}: {}", p.display(), img.width());
    }
}

#[test]
fn gather_refuses_what_holds_no_runs_and_names_unreadable_files() {
    assert_refused(&["gather", MISSING], &[MISSING, "not a directory"]);
    let empty = tempfile::tempdir().unwrap();
    let dir = empty.path().to_str().unwrap();
    assert_refused(&["gather", dir], &[dir, "no runs here"]);
    // A run whose summary.json is garbage is listed as unreadable, not
    // dropped.
    let run = empty.path().join("broken");
    std::fs::create_dir(&run).unwrap();
    std::fs::write(run.join("config.json"), "{}").unwrap();
    std::fs::write(run.join("summary.json"), "not json").unwrap();
    let out = eval(&["gather", dir]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(empty.path().join("benchmark.md")).unwrap();
    assert!(md.contains("0 of 1 runs finished."), "{md}");
    assert!(md.contains("- broken (broken): unreadable: "), "{md}");
    assert!(md.contains("summary.json: invalid JSON"), "{md}");
    // A damaged batch.json is an error naming it.
    std::fs::write(empty.path().join("batch.json"), "[").unwrap();
    assert_refused(&["gather", dir], &["batch.json", "invalid JSON"]);
}
