//! Every `eval` command on a run of an unbounded field with the proposal
//! sampler (the synthetic outdoor scene): it loads, renders the scene's
//! views and a camera path, segments, answers a query, maps uncertainty and
//! serves the viewer.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

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

    // The viewer serves the run's summary and points, then stops.
    let mut child = Command::new(env!("CARGO_BIN_EXE_eval"))
        .args(["view", "--run", &r, "--port", "0", "--seconds", "6"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("eval view starts");
    let stdout = child.stdout.take().expect("stdout");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let url = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(180))
            .expect("eval view prints its address");
        if let Some(url) = line.strip_prefix("viewer at ") {
            break url.trim().to_string();
        }
    };
    for api in ["/api/summary", "/api/points", "/api/cameras"] {
        let addr = url.trim_start_matches("http://").trim_end_matches('/');
        let mut s = TcpStream::connect(addr).expect("connect");
        write!(
            s,
            "GET {api} HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n"
        )
        .expect("send");
        let mut reply = Vec::new();
        s.read_to_end(&mut reply).expect("read");
        let head = String::from_utf8_lossy(&reply[..reply.len().min(200)]).into_owned();
        assert!(head.starts_with("HTTP/1.1 200"), "{api}: {head}");
    }
    assert!(child.wait().expect("eval view exits").success());
    // Everything it printed after the address, to its end.
    while rx.recv_timeout(Duration::from_secs(30)).is_ok() {}
}
