//! `eval view`: bad flags refused through the real binary, the server
//! started and stopped, and the page driven in a real (headless) browser.
//!
//! The browser test needs Chromium and the `playwright-core` npm package;
//! it is ignored in a plain `cargo test` and `.ci/run` installs both and
//! runs it (see the README's "Tests").

mod common;

use common::{get, printed_until_closed, start_view};

use std::path::{Path, PathBuf};
use std::process::Command;

fn eval_bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eval"))
}

fn tiny_run() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("temp dir");
    common::write_tiny_run(dir.path());
    dir
}

#[test]
fn view_refuses_bad_flags_and_runs_that_do_not_exist() {
    let run = tiny_run();
    let r = run.path().to_str().expect("utf-8");
    let missing = run.path().join("nothing");
    let m = missing.to_str().expect("utf-8");
    for (args, words) in [
        (vec!["--run", m], vec!["nothing", "config.json"]),
        (
            vec!["--run", r, "--host", "localhost:80"],
            vec!["--host", "not an IP address"],
        ),
        (
            vec!["--run", r, "--max-points", "0"],
            vec!["--max-points 0"],
        ),
        (vec!["--run", r, "--seconds", "-1"], vec!["--seconds -1"]),
        (vec!["--run", r, "--radius", "-0.5"], vec!["--radius -0.5"]),
        (
            vec!["--run", r, "--max-render-side", "8"],
            vec!["--max-render-side 8"],
        ),
        (
            vec!["--run", r, "--text-model", m],
            vec!["--text-model", "not a directory"],
        ),
        (vec!["--run", r, "--port", "70000"], vec!["--port", "70000"]),
        (vec!["--run", r, "--classes", "chair"], vec!["--text-model"]),
    ] {
        let out = eval_bin()
            .arg("view")
            .args(&args)
            .output()
            .expect("eval runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        for w in words {
            assert!(err.contains(w), "{args:?}: {w:?} not in {err}");
        }
    }
    // The port is taken: a clear error, not a panic.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = taken.local_addr().expect("addr").port().to_string();
    let out = eval_bin()
        .args(["view", "--run", r, "--port", &port, "--seconds", "5"])
        .output()
        .expect("eval runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("cannot serve on"),
        "{err}"
    );
}

#[test]
fn view_serves_the_run_prints_the_ssh_line_and_stops_after_its_seconds() {
    let run = tiny_run();
    let (mut child, url, rx) = start_view(run.path(), "8");
    let summary = get(&url, "/api/summary");
    assert!(summary.starts_with("HTTP/1.1 200"), "{summary}");
    assert!(
        summary.contains("\"point_source\":\"labelled cloud\""),
        "{summary}"
    );
    let status = child.wait().expect("eval view exits");
    assert!(status.success());
    let printed = printed_until_closed(&rx);
    assert!(
        printed.iter().any(|l| l.contains("ssh -N -L")),
        "{printed:?}"
    );
    assert!(
        printed.iter().any(|l| l.contains("viewer stopped")),
        "{printed:?}"
    );
}

#[test]
fn ctrl_c_stops_the_viewer_cleanly() {
    let run = tiny_run();
    let (mut child, url, rx) = start_view(run.path(), "600");
    assert!(get(&url, "/api/classes").starts_with("HTTP/1.1 200"));
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    let status = child.wait().expect("eval view exits");
    assert!(status.success(), "{status:?}");
    let printed = printed_until_closed(&rx);
    assert!(
        printed.iter().any(|l| l.contains("viewer stopped")),
        "{printed:?}"
    );
}

/// Where the browser test finds its tools: Chromium and `node` with
/// `playwright-core` on `NODE_PATH` (`.ci/run` sets `OPENNERF_NODE_PATH`).
fn browser_tools() -> Result<(PathBuf, String), String> {
    let chromium = PathBuf::from(std::env::var("CHROMIUM").unwrap_or("/usr/bin/chromium".into()));
    if !chromium.is_file() {
        return Err(format!("no Chromium at {}", chromium.display()));
    }
    let node_path = std::env::var("OPENNERF_NODE_PATH")
        .map_err(|_| "OPENNERF_NODE_PATH (the node_modules holding playwright-core) is not set")?;
    if !Path::new(&node_path).join("playwright-core").is_dir() {
        return Err(format!("no playwright-core in {node_path}"));
    }
    Ok((chromium, node_path))
}

/// Mean absolute difference per channel and the fraction of pixels that
/// differ by more than 24 in some channel.
fn difference(a: &image::RgbImage, b: &image::RgbImage) -> (f64, f64) {
    let mut sum = 0.0;
    let mut changed = 0usize;
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d: Vec<i32> = (0..3).map(|k| (p[k] as i32 - q[k] as i32).abs()).collect();
        sum += d.iter().sum::<i32>() as f64;
        changed += usize::from(d.iter().any(|&x| x > 24));
    }
    let n = (a.width() * a.height()) as f64;
    (sum / (3.0 * n), changed as f64 / n)
}

#[test]
#[ignore = "needs Chromium and playwright-core; .ci/run installs them and runs this test"]
fn a_real_browser_shows_the_points_answers_a_class_query_and_renders() {
    let (chromium, node_path) = browser_tools().unwrap_or_else(|e| panic!("{e}"));
    let run = tiny_run();
    let (mut child, url, _rx) = start_view(run.path(), "600");
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("viewer-browser");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).expect("artefacts dir");
    let scene =
        datasets::synthetic::generate(0, datasets::synthetic::SceneSize::Ci).expect("scene");
    let classes = scene.classes.expect("classes").names;
    let driver = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/browser/drive_viewer.cjs");
    let status = Command::new("node")
        .arg(&driver)
        .args(["--url", &url, "--out", out.to_str().expect("utf-8")])
        .args([
            "--class",
            &classes[1],
            "--chromium",
            chromium.to_str().expect("utf-8"),
        ])
        .env("NODE_PATH", &node_path)
        .status();
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        status.expect("node runs").success(),
        "the driver could not run Chromium"
    );
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).expect("result"))
            .expect("result.json is JSON");
    eprintln!("browser result: {result}");
    assert_eq!(result["console_errors"], serde_json::json!([]), "{result}");
    assert_eq!(result["page_errors"], serde_json::json!([]), "{result}");
    assert_eq!(result["legend"], serde_json::json!(classes), "{result}");
    assert_eq!(result["query_ok"], true, "{result}");
    assert_eq!(result["render_ok"], true, "{result}");
    assert!(result["render_width"].as_u64().unwrap_or(0) > 0, "{result}");
    // The depth's range and units are shown under it, the opacity beside it.
    let caption = result["depth_caption"].as_str().unwrap_or("");
    assert!(
        caption.starts_with("depth: ") && caption.contains(" m (red, near) to "),
        "{result}"
    );
    assert_eq!(result["opacity_width"], result["render_width"], "{result}");
    let points = scene.points.expect("cloud").positions.len();
    assert_eq!(result["points"].as_u64(), Some(points as u64), "{result}");

    let load = |name: &str| image::open(out.join(name)).expect(name).to_rgb8();
    let (initial, query) = (load("initial.png"), load("query.png"));
    // Not blank: many colours, and pixels far from the background's.
    let colours: std::collections::HashSet<[u8; 3]> = initial.pixels().map(|p| p.0).collect();
    let background = initial.get_pixel(0, 0).0;
    let drawn = initial
        .pixels()
        .filter(|p| (0..3).any(|k| (p[k] as i32 - background[k] as i32).abs() > 24))
        .count();
    assert!(colours.len() > 50, "{} colours", colours.len());
    assert!(
        drawn * 50 > (initial.width() * initial.height()) as usize,
        "{drawn} drawn pixels"
    );
    // The query recolours part of the cloud (relevancy above the threshold).
    let (mean, changed) = difference(&initial, &query);
    eprintln!(
        "query screenshot: mean change {mean:.2}, {:.1}% of pixels changed",
        100.0 * changed
    );
    assert!(changed > 0.005, "{changed}");
}
