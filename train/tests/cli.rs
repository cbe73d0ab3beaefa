//! The `train` binary on bad options and on run directories that must not
//! lose work: every refusal names the flag or the file, nothing panics, and
//! nothing already written is replaced. A finished run ends by printing the
//! exact command to run next.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
mod common;

use common::{TINY, assert_refused, s, text, train};

fn tiny_config(dir: &Path) -> PathBuf {
    let p = dir.join("tiny.json");
    std::fs::write(&p, TINY).expect("write config");
    p
}

/// A Nice-SLAM scene of `n` frames of 40x30 pixels, without feature maps.
fn replica_dir(dir: &Path, n: usize) -> PathBuf {
    let root = dir.join("room");
    let results = root.join("results");
    std::fs::create_dir_all(&results).expect("mkdir");
    std::fs::write(
        root.join("cam_params.json"),
        r#"{"camera": {"w": 40, "h": 30, "fx": 30.0, "fy": 30.0, "cx": 19.5, "cy": 14.5, "scale": 1000.0}}"#,
    )
    .expect("write");
    let mut traj = String::new();
    for i in 0..n {
        image::RgbImage::from_fn(40, 30, |x, y| {
            image::Rgb([(x * 6) as u8, (y * 8) as u8, 90])
        })
        .save(results.join(format!("frame{i:06}.png")))
        .expect("png");
        image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_pixel(40, 30, image::Luma([2000]))
            .save(results.join(format!("depth{i:06}.png")))
            .expect("png");
        traj += &format!("1 0 0 {} 0 1 0 0 0 0 1 0 0 0 0 1\n", 0.05 * i as f64);
    }
    std::fs::write(root.join("traj.txt"), traj).expect("write");
    root
}

/// `train` on the room of `replica_dir` (every other frame held out) with
/// the tiny configuration, for `iters` iterations into `out`, with `extra`
/// flags.
fn train_tiny_room(room: &Path, config: &Path, iters: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "--dataset",
        "replica",
        "--data",
        s(room),
        "--holdout-every",
        "2",
        "--config",
        s(config),
        "--iters",
        iters,
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    train(&args)
}

#[test]
fn out_of_range_numbers_are_refused_by_flag() {
    for (args, flag) in [
        (&["--iters", "0"][..], "--iters 0"),
        (&["--time-budget", "0"], "--time-budget 0"),
        (&["--time-budget", "-5"], "--time-budget -5"),
        (&["--time-budget", "NaN"], "--time-budget NaN"),
        (&["--holdout-every", "0"], "--holdout-every 0"),
        (&["--holdout-every", "1"], "--holdout-every 1"),
        (&["--box-margin", "-0.1"], "--box-margin -0.1"),
        (&["--box-margin", "NaN"], "--box-margin NaN"),
        (&["--box-margin", "inf"], "--box-margin inf"),
        (&["--box-margin", "10.5"], "--box-margin 10.5"),
    ] {
        assert_refused(args, &[flag]);
    }
}

#[test]
fn scene_flags_that_would_be_ignored_are_refused() {
    assert_refused(
        &["--dataset", "synthetic", "--data", "/some/room"],
        &["--data", "--dataset synthetic"],
    );
    assert_refused(&["--features", "/some/feats"], &["--features", "synthetic"]);
    assert_refused(&["--box-margin", "0.5"], &["--box-margin", "synthetic"]);
    // --data alone detects the format, so a missing directory is named.
    assert_refused(&["--data", "/some/room"], &["/some/room", "not found"]);
}

/// `--backend` and `--device` are the flags of every `eval` subcommand and
/// the measurement programs: a backend this build does not know is listed
/// against the ones it does, and `--device` takes a wgpu adapter index only.
#[test]
fn bad_backend_and_device_values_are_refused_by_flag() {
    assert_refused(
        &["--backend", "cuda"],
        &["'cuda'", "--backend", "flex", "ndarray", "wgpu"],
    );
    assert_refused(&["--device", "gpu0"], &["--device", "adapter index"]);
    assert_refused(&["--device", "ndarray"], &["--backend ndarray"]);
    assert_refused(&["--device", "0"], &["--device", "--backend wgpu"]);
    let help = String::from_utf8_lossy(&train(&["--help"]).stdout).into_owned();
    for flag in [
        "--backend <BACKEND>",
        "--device <INDEX>",
        "the discrete GPU",
    ] {
        assert!(help.contains(flag), "{flag:?} not in the help");
    }
}

/// `--short-side` is spelt as in `eval extract`; the former
/// `--vlm-short-side` still works (and is left out of the help), and a
/// `--dense` that is no variant is listed against the variants.
#[test]
fn short_side_is_named_as_in_eval_extract_and_the_old_name_still_works() {
    let tmp = tempfile::tempdir().expect("tmp");
    let model = tmp.path().join("no-such-model");
    let out = tmp.path().join("run");
    for flag in ["--short-side", "--vlm-short-side"] {
        let err = assert_refused(
            &["--vlm", s(&model), flag, "448", "--out", s(&out)],
            &["no-such-model"],
        );
        assert!(!err.contains("unexpected argument"), "{flag}: {err}");
        // Without --vlm the flag means nothing, under either name.
        assert_refused(&[flag, "448"], &["--vlm"]);
    }
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    assert_refused(
        &["--vlm", s(&model), "--dense", "naclipp"],
        &["'naclipp'", "--dense", "naclip", "clearclip", "maskclip"],
    );
    let help = String::from_utf8_lossy(&train(&["--help"]).stdout).into_owned();
    assert!(help.contains("--short-side <SHORT_SIDE>"), "{help}");
    assert!(!help.contains("--vlm-short-side"), "{help}");
}

/// `--dataset auto` (the default with --data) names the format it chose
/// and why; a directory of no known format is refused with what each
/// format needs, and nothing is written.
#[test]
fn the_format_of_a_data_directory_is_detected() {
    let tmp = tempfile::tempdir().expect("tmp");
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    let out = tmp.path().join("run");
    assert_refused(
        &["--data", s(&empty), "--out", s(&out)],
        &[
            "empty",
            "no scene format",
            "transforms.json",
            "sparse/0/",
            "poses_bounds.npy",
        ],
    );
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    let room = replica_dir(tmp.path(), 3);
    let config = tiny_config(tmp.path());
    let run = train(&[
        "--data",
        s(&room),
        "--config",
        s(&config),
        "--iters",
        "2",
        "--holdout-every",
        "3",
        "--no-final-render",
        "--quiet",
        "--out",
        s(&out),
    ]);
    let (_, err) = text(&run);
    assert!(run.status.success(), "{err}");
    assert!(
        err.contains("is a replica scene (it holds traj.txt and results/)"),
        "{err}"
    );
    let scene: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("scene.json")).expect("scene.json"))
            .expect("json");
    assert_eq!(scene["source"]["format"], "replica", "{scene}");
}

#[test]
fn unknown_config_keys_are_named_with_the_file() {
    let tmp = tempfile::tempdir().expect("tmp");
    let p = tmp.path().join("typo.json");
    std::fs::write(&p, r#"{"model": {"mlp": {"widht": 64}}, "sed": 3}"#).expect("write");
    assert_refused(
        &["--config", s(&p)],
        &["typo.json", "model.mlp.widht", "sed"],
    );
}

#[test]
fn a_stride_that_leaves_one_frame_has_nothing_to_hold_out() {
    let tmp = tempfile::tempdir().expect("tmp");
    let room = replica_dir(tmp.path(), 2);
    let out = tmp.path().join("run");
    assert_refused(
        &[
            "--dataset",
            "replica",
            "--data",
            s(&room),
            "--stride",
            "2",
            "--out",
            s(&out),
        ],
        &[
            "--holdout-every 8",
            "1 frame",
            "none of them would be held out",
        ],
    );
    assert!(!out.exists(), "a refused run left a directory behind");
}

#[test]
fn a_finished_run_without_checkpoints_is_not_overwritten() {
    let tmp = tempfile::tempdir().expect("tmp");
    let out = tmp.path().join("finished");
    std::fs::create_dir_all(&out).expect("mkdir");
    std::fs::write(out.join("model.bpk"), b"trained weights").expect("write");
    std::fs::write(out.join("summary.json"), b"{\"iterations\": 1000}").expect("write");
    assert_refused(
        &["--out", s(&out), "--iters", "2"],
        &["finished", "already holds a run", "model.bpk"],
    );
    assert_eq!(
        std::fs::read(out.join("model.bpk")).expect("read"),
        b"trained weights"
    );
    assert_eq!(
        std::fs::read(out.join("summary.json")).expect("read"),
        b"{\"iterations\": 1000}"
    );
}

#[test]
fn training_without_features_warns_that_segmentation_is_impossible() {
    let tmp = tempfile::tempdir().expect("tmp");
    let room = replica_dir(tmp.path(), 3);
    let config = tiny_config(tmp.path());
    let out = tmp.path().join("run");
    let r = train_tiny_room(&room, &config, "2", &out, &[]);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(stderr.contains("without --features"), "{stderr}");
    assert!(stderr.contains("eval segment"), "{stderr}");
    // No segment or query suggestion for a run without features.
    assert!(
        stdout.contains(&format!(
            "cargo run -p eval --release -- render --run {}",
            out.display()
        )),
        "{stdout}"
    );
    assert!(!stdout.contains("-- segment"), "{stdout}");
    // The viewer shows any run (points from rendered depth without a cloud).
    assert!(
        stdout.contains(&format!(
            "cargo run -p eval --release -- view --run {}",
            out.display()
        )),
        "{stdout}"
    );
}

/// `--box-margin` reaches the loader: the box of a scene on disk grows by
/// the margin's fraction of the region's largest side on every side, and
/// the run's `scene.json` keeps it (a resume rebuilds the same box).
#[test]
fn box_margin_grows_the_scene_box_by_its_fraction() {
    let tmp = tempfile::tempdir().expect("tmp");
    let room = replica_dir(tmp.path(), 3);
    let config = tiny_config(tmp.path());
    let scene_box = |margin: Option<&str>| {
        let out = tmp
            .path()
            .join(format!("run-{}", margin.unwrap_or("default")));
        let mut extra = vec!["--no-final-render"];
        if let Some(m) = margin {
            extra.extend(["--box-margin", m]);
        }
        let r = train_tiny_room(&room, &config, "1", &out, &extra);
        assert!(r.status.success(), "{}", text(&r).1);
        let meta: datasets::SceneMeta =
            serde_json::from_slice(&std::fs::read(out.join("scene.json")).expect("scene.json"))
                .expect("scene.json parses");
        let b = meta.scene_box;
        let rebuilt = datasets::load_scene(&meta.source)
            .expect("scene rebuilds")
            .scene_box;
        assert_eq!(rebuilt, b, "scene.json rebuilds another box");
        [0, 1, 2].map(|k| b.max[k] - b.min[k])
    };
    let default = scene_box(None);
    let wide = scene_box(Some("0.5"));
    // Sides are the region's plus twice the margin times its largest side.
    let d = datasets::replica::ReplicaOptions::default().box_margin;
    let largest = default.iter().fold(0.0f64, |a, &b| a.max(b)) / (1.0 + 2.0 * d);
    for k in 0..3 {
        let grown = wide[k] - default[k];
        assert!(
            (grown - 2.0 * (0.5 - d) * largest).abs() < 1e-9 * largest.max(1.0),
            "axis {k}: {default:?} -> {wide:?}"
        );
    }
}

/// A new run, resumed with bad options (nothing rewritten), with a damaged
/// newest checkpoint (falls back to the older one) and with the temporary
/// file of a killed checkpoint write (removed).
#[test]
fn resume_checks_before_writing_and_survives_a_damaged_checkpoint() {
    let tmp = tempfile::tempdir().expect("tmp");
    let config = tiny_config(tmp.path());
    let run = tmp.path().join("run");
    let r = train(&[
        "--config",
        s(&config),
        "--iters",
        "4",
        "--out",
        s(&run),
        "--quiet",
    ]);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    // Captured output gets plain progress lines, and the run ends with the
    // exact next command.
    assert!(stderr.contains("iteration 4/4:"), "{stderr}");
    assert!(
        stdout.contains(&format!(
            "cargo run -p eval --release -- segment --run {}",
            run.display()
        )),
        "{stdout}"
    );

    let config_json = std::fs::read(run.join("config.json")).expect("config.json");
    assert_refused(&["--resume", s(&run), "--iters", "0"], &["--iters 0"]);
    assert_refused(
        &["--resume", s(&run), "--iters", "3"],
        &["--iters 3", "4 iterations"],
    );
    assert_refused(
        &["--resume", s(&run), "--width", "8"],
        &["--width", "--resume"],
    );
    assert_refused(
        &["--resume", s(&run), "--occupancy-grid"],
        &["--occupancy-grid", "--resume"],
    );
    assert_refused(
        &["--resume", s(&run), "--box-margin", "0.5"],
        &["--box-margin", "--resume"],
    );
    assert_refused(
        &["--resume", s(&run), "--sparse-depth", "off"],
        &["--sparse-depth", "--resume"],
    );
    assert_eq!(
        std::fs::read(run.join("config.json")).expect("config.json"),
        config_json,
        "a refused resume rewrote config.json"
    );

    let ckpts = run.join("checkpoints");
    let newest = ckpts.join("ckpt-00000004.onck");
    assert!(ckpts.join("ckpt-00000002.onck").exists() && newest.exists());
    let bytes = std::fs::read(&newest).expect("read");
    std::fs::write(&newest, &bytes[..bytes.len() / 2]).expect("truncate");
    let stale = ckpts.join(".ckpt-00000006.onck.tmp-4000000000");
    std::fs::write(&stale, b"half written").expect("write");

    let r = train(&["--resume", s(&run), "--iters", "6", "--quiet"]);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(stderr.contains("ckpt-00000004.onck"), "{stderr}");
    assert!(stderr.contains("resuming from the older"), "{stderr}");
    assert!(stdout.contains("done: 6 iterations"), "{stdout}");
    assert!(!stale.exists(), "the stale temporary file is still there");
    assert!(ckpts.join("ckpt-00000004.onck.damaged").exists());
    assert!(ckpts.join("ckpt-00000006.onck").exists());
}

#[test]
fn occupancy_grid_flags_and_settings_are_checked_and_a_grid_run_saves_its_grid() {
    for (args, words) in [
        (
            &["--occupancy-grid", "--grid-resolution", "1"][..],
            &["--grid-resolution 1", "2..=256"][..],
        ),
        (
            &["--occupancy-grid", "--grid-resolution", "100000"],
            &["--grid-resolution 100000"],
        ),
        (&["--occupancy-grid", "--grid-resolution", "-3"], &["-3"]),
        (
            &["--grid-resolution", "16"],
            &["--grid-resolution 16", "--occupancy-grid"],
        ),
        (&["--head-top-k", "-1"], &["-1"]),
        (&["--head-top-k", "many"], &["many"]),
    ] {
        assert_refused(args, words);
    }
    let tmp = tempfile::tempdir().expect("tmp");
    for (patch, words) in [
        (
            r#"{"occupancy": {"enabled": true, "decay": 2.0}}"#,
            &["occupancy.decay 2"][..],
        ),
        (
            r#"{"occupancy": {"resolution": 0}}"#,
            &["occupancy.resolution 0"],
        ),
        (
            r#"{"occupancy": {"update_every": 0}}"#,
            &["occupancy.update_every 0"],
        ),
        (
            r#"{"occupancy": {"min_opacity": 1.0}}"#,
            &["occupancy.min_opacity 1"],
        ),
        (
            r#"{"occupancy": {"resolutoin": 8}}"#,
            &["occupancy.resolutoin"],
        ),
    ] {
        let p = tmp.path().join("bad.json");
        std::fs::write(&p, patch).expect("write");
        assert_refused(&["--config", s(&p), "--iters", "2", "--quiet"], words);
    }
    let config = tiny_config(tmp.path());
    let run = tmp.path().join("grid-run");
    let r = train(&[
        "--config",
        s(&config),
        "--iters",
        "4",
        "--occupancy-grid",
        "--grid-resolution",
        "8",
        "--out",
        s(&run),
        "--quiet",
    ]);
    let (stdout, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(stdout.contains("model.bpk, occupancy.bin"), "{stdout}");
    let grid = std::fs::read(run.join("occupancy.bin")).expect("occupancy.bin");
    // Magic, resolution and updates (u64), decay and min opacity (f32),
    // early samples, early updates and dilation (u32), then 8^3 densities.
    assert_eq!(grid.len(), 8 + 16 + 8 + 12 + 4 * 8 * 8 * 8, "an 8^3 grid");
    let config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).expect("config"))
            .expect("json");
    assert_eq!(config["occupancy"]["enabled"], true);
    assert_eq!(config["occupancy"]["resolution"], 8);
}

#[test]
fn field_and_sampler_flags_are_checked_and_the_choice_is_printed() {
    assert_refused(&["--field", "sphere"], &["sphere", "box", "unbounded"]);
    assert_refused(&["--sampler", "fine"], &["fine", "coarse-fine", "proposal"]);
    // The grid covers the box: refused with an unbounded field, chosen or asked for.
    for args in [
        &["--scene-size", "outdoor", "--occupancy-grid"][..],
        &["--field", "unbounded", "--occupancy-grid"],
    ] {
        assert_refused(args, &["occupancy grid", "unbounded", "--field box"]);
    }
    let tmp = tempfile::tempdir().expect("tmp");
    for (patch, words) in [
        (
            r#"{"model": {"unbounded": {"radius": -1.0}}}"#,
            &["model.unbounded.radius", "-1"][..],
        ),
        (
            r#"{"model": {"unbounded": {"radius": 3.0, "near": 2.0, "far": 1.0}}}"#,
            &["model.unbounded.far", "near"],
        ),
        (
            r#"{"model": {"proposal": {"samples": [64, 0]}}}"#,
            &["model.proposal.samples", "[64, 0]"],
        ),
        (
            r#"{"model": {"proposal": {"anneal_slope": -2.0}}}"#,
            &["model.proposal.anneal_slope", "-2"],
        ),
    ] {
        let p = tmp.path().join("bad.json");
        std::fs::write(&p, patch).expect("write");
        let args = [
            "--config",
            s(&p),
            "--field",
            "unbounded",
            "--sampler",
            "proposal",
        ];
        assert_refused(&[&args[..], &["--iters", "2", "--quiet"]].concat(), words);
    }
    // A file may give only the keys it changes: the radius is then the scene's.
    let p = tmp.path().join("near.json");
    std::fs::write(&p, r#"{"model": {"unbounded": {"near": 0.3}}}"#).expect("write");
    let near_run = tmp.path().join("near-run");
    let r = train(&[
        "--config",
        s(&p),
        "--field",
        "unbounded",
        "--iters",
        "1",
        "--out",
        s(&near_run),
        "--quiet",
        "--scene-size",
        "outdoor",
        "--no-final-render",
    ]);
    let (_, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    let saved: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(near_run.join("config.json")).expect("config"),
    )
    .expect("json");
    assert!((saved["model"]["unbounded"]["near"].as_f64().unwrap_or(0.0) - 0.3).abs() < 1e-6);
    assert!(
        saved["model"]["unbounded"]["radius"]
            .as_f64()
            .unwrap_or(0.0)
            > 3.0
    );
    // Auto on the outdoor scene: contracted, said so; a preset leaves its
    // grid off there.
    let config = tiny_config(tmp.path());
    let run = tmp.path().join("outdoor");
    let r = train(&[
        "--scene-size",
        "outdoor",
        "--config",
        s(&config),
        "--preset",
        "fast",
        "--iters",
        "3",
        "--out",
        s(&run),
        "--quiet",
    ]);
    let (_, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(
        stderr.contains("field: unbounded (auto: an open scene reaching far past its box"),
        "{stderr}"
    );
    assert!(
        stderr.contains("no occupancy grid (the field is unbounded)"),
        "{stderr}"
    );
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).expect("config"))
            .expect("json");
    assert!(
        saved["model"]["unbounded"]["radius"]
            .as_f64()
            .unwrap_or(0.0)
            > 3.0
    );
    assert_eq!(saved["occupancy"]["enabled"], false);
    // Its rays start where they enter the scene box, said so and saved.
    assert!(
        stderr.contains("rays start where they enter the scene box"),
        "{stderr}"
    );
    assert_eq!(saved["model"]["unbounded"]["start_at_box"], true);
    // A file may turn that off; a value that is not a boolean is refused
    // with the file named.
    for (value, ok) in [("false", true), ("\"yes\"", false)] {
        let file = tmp.path().join(format!("start{ok}.json"));
        std::fs::write(
            &file,
            format!("{{\"model\": {{\"unbounded\": {{\"start_at_box\": {value}}}}}}}"),
        )
        .expect("write");
        let run = tmp.path().join(format!("outdoor-start{ok}"));
        let r = train(&[
            "--scene-size",
            "outdoor",
            "--config",
            s(&file),
            "--width",
            "8",
            "--depth",
            "1",
            "--samples",
            "4",
            "--rays",
            "16",
            "--iters",
            "1",
            "--out",
            s(&run),
            "--quiet",
        ]);
        let (_, stderr) = text(&r);
        assert_eq!(r.status.success(), ok, "{value}: {stderr}");
        if ok {
            assert!(stderr.contains("start_at_box false"), "{stderr}");
            let saved: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(run.join("config.json")).expect("config"),
            )
            .expect("json");
            assert_eq!(saved["model"]["unbounded"]["start_at_box"], false);
        } else {
            assert!(stderr.contains(&*file.to_string_lossy()), "{stderr}");
        }
    }
    // The room stays a box.
    let room = tmp.path().join("room");
    let r = train(&[
        "--config",
        s(&config),
        "--iters",
        "1",
        "--out",
        s(&room),
        "--quiet",
    ]);
    let (_, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(
        stderr.contains("field: box (auto: a room stood in"),
        "{stderr}"
    );
}

#[test]
fn novel_view_flags_are_checked_by_flag() {
    for (args, words) in [
        (
            &["--novel-views", "2", "--novel-depth-weight", "NaN"][..],
            &["--novel-depth-weight NaN"][..],
        ),
        (
            &["--novel-views", "2", "--novel-depth-weight", "-1"],
            &["--novel-depth-weight -1"],
        ),
        (
            &["--novel-views", "2", "--novel-depth-weight", "1.5"],
            &["--novel-depth-weight 1.5", "[0, 1]"],
        ),
        (
            &["--novel-views", "2", "--novel-after", "0"],
            &["--novel-after 0"],
        ),
        (&["--novel-views", "2", "--novel-after", "-3"], &["-3"]),
        (
            &["--novel-views", "2", "--novel-scale", "0"],
            &["--novel-scale 0", "(0, 1]"],
        ),
        (
            &["--novel-views", "2", "--novel-scale", "NaN"],
            &["--novel-scale NaN"],
        ),
        (
            &["--novel-views", "2", "--novel-scale", "-0.5"],
            &["--novel-scale -0.5"],
        ),
        (
            &["--novel-views", "2", "--novel-scale", "1.5"],
            &["--novel-scale 1.5"],
        ),
        (
            &["--novel-views", "2", "--novel-max-color-error", "-0.1"],
            &["--novel-max-color-error -0.1", ">= 0"],
        ),
        (
            &["--novel-views", "2", "--novel-max-color-error", "NaN"],
            &["--novel-max-color-error NaN"],
        ),
        (&["--novel-max-color-error", "0.05"], &["--novel-views"]),
        (&["--novel-oracle", "labels"], &["--novel-views"]),
        (
            &["--novel-views", "2", "--novel-oracle", "perfect"],
            &["perfect", "renders", "labels"],
        ),
        (
            &[
                "--dataset",
                "replica",
                "--data",
                "/nonexistent/room0",
                "--novel-views",
                "2",
                "--novel-oracle",
                "renders",
            ],
            &["--novel-oracle renders", "synthetic"],
        ),
        (&["--novel-views", "-2"], &["-2"]),
        (
            &["--novel-views", "2", "--extractor-command", " "],
            &["--extractor-command"],
        ),
        (&["--novel-after", "5"], &["--novel-views N"]),
        (&["--novel-views-mode", "sideways"], &["sideways", "guided"]),
        (&["--novel-views", "2000"], &["novel.views", "1000"]),
        (
            &["--novel-views", "2", "--novel-after", "50", "--iters", "50"],
            &["iteration 50", "--novel-after"],
        ),
    ] {
        assert_refused(args, words);
    }
}

#[test]
fn novel_views_need_feature_maps_and_an_extractor_and_resume_keeps_them() {
    let tmp = tempfile::tempdir().expect("tmp");
    let room = replica_dir(tmp.path(), 3);
    let out = tmp.path().join("run");
    // A scene without feature maps has nothing to re-extract.
    assert_refused(
        &[
            "--dataset",
            "replica",
            "--data",
            s(&room),
            "--holdout-every",
            "2",
            "--novel-views",
            "2",
            "--out",
            s(&out),
        ],
        &["no feature maps", "novel views"],
    );
    assert!(!out.join("config.json").exists());
    // Resuming keeps the run's own novel-view settings.
    let config = tiny_config(tmp.path());
    let run = tmp.path().join("synthetic");
    let r = train(&[
        "--config",
        s(&config),
        "--iters",
        "4",
        "--stop-at",
        "2",
        "--out",
        s(&run),
        "--quiet",
    ]);
    assert!(r.status.success(), "{}", text(&r).1);
    assert_refused(
        &["--resume", s(&run), "--novel-views", "3"],
        &["--novel-views", "--resume"],
    );
    assert_refused(
        &["--resume", s(&run), "--novel-oracle", "labels"],
        &["--novel-oracle", "--resume"],
    );
}

/// A scene on disk with feature maps: the novel views go through the
/// command extractor, are recorded, and a damaged record is reported by
/// file on resume.
#[test]
fn a_scene_on_disk_adds_views_through_the_command_extractor() {
    let tmp = tempfile::tempdir().expect("tmp");
    let room = replica_dir(tmp.path(), 4);
    // Feature maps of 10x8 pixels, 4 channels, for each frame.
    let feats = tmp.path().join("features");
    std::fs::create_dir_all(&feats).expect("mkdir");
    // A path with spaces: the command is split as a shell would split it.
    let script_dir = tmp.path().join("my extractor");
    std::fs::create_dir_all(&script_dir).expect("mkdir");
    let script = script_dir.join("extract.py");
    std::fs::write(
        &script,
        r#"import sys, os, struct
def write(path, h, w, d):
    hdr = "{'descr': '<f4', 'fortran_order': False, 'shape': (%d, %d, %d), }" % (h, w, d)
    hdr += " " * (63 - (10 + len(hdr)) % 64) + "\n"
    with open(path, "wb") as f:
        f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(hdr)) + hdr.encode())
        for i in range(h * w):
            f.write(struct.pack("<4f", 1.0, 0.5 * (i % 3), 0.25, 0.0))
if sys.argv[1] == "--maps":
    for i in range(int(sys.argv[3])):
        write(os.path.join(sys.argv[2], "frame%06d.npy" % i), 8, 10, 4)
else:
    for name in os.listdir(sys.argv[1]):
        write(os.path.join(sys.argv[2], name[:-4] + ".npy"), 8, 10, 4)
"#,
    )
    .expect("write script");
    // Python plays the external extractor; CI has it (the layout check is
    // a Python script), so its absence fails rather than skips.
    let python = ["python3", "python"]
        .into_iter()
        .find(|p| Command::new(p).arg("--version").output().is_ok())
        .expect("python3 (or python) on PATH, to play the external extractor");
    let made = Command::new(python)
        .arg(&script)
        .args(["--maps", s(&feats), "4"])
        .status()
        .expect("python runs");
    assert!(made.success());
    let config = tiny_config(tmp.path());
    let out = tmp.path().join("run");
    let base = [
        "--dataset",
        "replica",
        "--data",
        s(&room),
        "--features",
        s(&feats),
        "--pca",
        "off",
        "--holdout-every",
        "2",
        "--config",
        s(&config),
        "--iters",
        "6",
        "--novel-views",
        "2",
        "--novel-after",
        "3",
        "--novel-views-mode",
        "trajectory",
        "--out",
        s(&out),
        "--quiet",
    ];
    // Without the extractor that made the maps there is nothing to run.
    assert_refused(&base, &["--extractor-command"]);
    let command = format!("{python} '{}'", s(&script));
    let mut args = base.to_vec();
    args.extend(["--extractor-command", &command, "--stop-at", "4"]);
    let r = train(&args);
    let (_, stderr) = text(&r);
    assert!(r.status.success(), "{stderr}");
    assert!(stderr.contains("novel views added"), "{stderr}");
    let novel = out.join("novel");
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(novel.join("views.json")).expect("index"))
            .expect("json");
    assert_eq!(record["mode"], "trajectory");
    assert_eq!(record["added_at"], 3);
    let views = record["views"].as_array().expect("views");
    // Two training frames (0 and 2 are held out): one segment between them.
    assert_eq!(views.len(), 1, "{record}");
    // A truncated feature map is named on resume, and nothing is trained.
    let f = novel.join(views[0]["features"].as_str().expect("name"));
    let bytes = std::fs::read(&f).expect("read");
    std::fs::write(&f, &bytes[..bytes.len() / 2]).expect("truncate");
    assert_refused(&["--resume", s(&out)], &["novel_000_features.npy"]);
    std::fs::write(&f, &bytes).expect("restore");
    let r = train(&["--resume", s(&out), "--quiet"]);
    assert!(r.status.success(), "{}", text(&r).1);
    assert!(text(&r).0.contains("done: 6 iterations"));
}
