//! Every `eval` command on a run of an unbounded field with the proposal
//! sampler (the synthetic outdoor scene): it loads, renders the scene's
//! views and a camera path, segments, answers a query, maps uncertainty and
//! serves the viewer.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn eval(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(args)
        .output()
        .expect("the eval binary runs")
}

fn succeeds(args: &[&str]) -> String {
    let out = eval(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{args:?}: {err}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn path(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn every_eval_command_runs_on_an_unbounded_run() {
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    std::fs::create_dir_all(&run).expect("mkdir");
    common::write_tiny_unbounded_run(&run);
    let r = path(&run);

    let renders = path(&tmp.path().join("renders"));
    let out = succeeds(&["render", "--run", &r, "--out", &renders]);
    assert!(out.contains("PSNR against the"), "{out}");
    // Proposal rounds of 8 and 8, then 4 samples of the MLP.
    assert!(out.contains("evaluated of 20"), "{out}");
    let rgb = image::open(tmp.path().join("renders/frame000000_rgb.png")).expect("render");
    assert_eq!((rgb.width(), rgb.height()), (80, 60));
    // An unbounded field's depth is shown as disparity (one over metres),
    // near above far.
    let scale: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(tmp.path().join("renders/frame000000_depth.json"))
            .expect("depth scale"),
    )
    .expect("json");
    assert_eq!(scale["quantity"], "disparity", "{scale}");
    assert_eq!(scale["units"], "1/m", "{scale}");
    let (near, far) = (scale["near_m"].as_f64(), scale["far_m"].as_f64());
    assert!(near.zip(far).is_some_and(|(n, f)| n <= f), "{scale}");
    let out = succeeds(&[
        "render",
        "--run",
        &r,
        "--out",
        &renders,
        "--camera-path",
        "3",
    ]);
    assert!(out.contains("path.gif"), "{out}");

    let seg = path(&tmp.path().join("seg"));
    let out = succeeds(&["segment", "--run", &r, "--out", &seg]);
    assert!(out.contains("mIoU"), "{out}");

    let query = path(&tmp.path().join("query"));
    succeeds(&["query", "--run", &r, "--query", "chair", "--out", &query]);
    assert!(std::fs::read_dir(&query).expect("query output").count() > 0);

    let unc = path(&tmp.path().join("uncertainty"));
    succeeds(&["uncertainty", "--run", &r, "--out", &unc]);
    assert!(std::fs::read_dir(&unc).expect("uncertainty output").count() > 0);

    // The viewer serves the run's summary, points and cameras, then stops.
    let (mut child, url, rx) = common::start_view(&run, "6");
    for api in ["/api/summary", "/api/points", "/api/cameras"] {
        let reply = common::get(&url, api);
        assert!(
            reply.starts_with("HTTP/1.1 200"),
            "{api}: {}",
            &reply[..reply.len().min(200)]
        );
    }
    assert!(child.wait().expect("eval view exits").success());
    common::printed_until_closed(&rx);
}
