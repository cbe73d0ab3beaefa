//! `train --viewer`: the web viewer served from the training process, its
//! field refreshed while training, stopped with the training; its flags
//! refused at bad values.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn train() -> Command {
    Command::new(env!("CARGO_BIN_EXE_train"))
}

/// The JSON body of `GET path`, or `None` when the server is gone.
fn get_json(addr: &str, path: &str) -> Option<serde_json::Value> {
    let mut s = TcpStream::connect(addr).ok()?;
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut raw = String::new();
    s.read_to_string(&mut raw).ok()?;
    let body = raw.split_once("\r\n\r\n")?.1;
    serde_json::from_str(body).ok()
}

#[test]
fn the_viewer_follows_the_training_and_stops_with_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("run");
    let mut child = train()
        .args([
            "--scene-size",
            "ci",
            "--iters",
            "300",
            "--rays",
            "64",
            "--samples",
            "8",
        ])
        .args([
            "--width",
            "32",
            "--depth",
            "2",
            "--no-final-render",
            "--quiet",
        ])
        .args(["--viewer", "--viewer-port", "0", "--viewer-every", "0.2"])
        .arg("--out")
        .arg(&out)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("train starts");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut printed = Vec::new();
    let addr = loop {
        let Ok(line) = rx.recv_timeout(Duration::from_secs(300)) else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("no viewer address in {printed:?}");
        };
        printed.push(line.clone());
        if let Some(url) = line.strip_prefix("viewer at http://") {
            break url.trim_end_matches('/').to_string();
        }
    };
    // Poll while it trains: the version grows, the iteration with it.
    let (mut versions, mut training) = (Vec::new(), false);
    let start = Instant::now();
    while let Some(s) = get_json(&addr, "/api/summary") {
        training |= s["training"] == true;
        let v = s["field_version"].as_u64().unwrap_or(0);
        if versions.last() != Some(&v) {
            versions.push(v);
        }
        if start.elapsed() > Duration::from_secs(300) {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let status = child.wait().expect("train exits");
    // The reader thread may still hold the last lines: read to the end.
    while let Ok(line) = rx.recv_timeout(Duration::from_secs(30)) {
        printed.push(line);
    }
    assert!(status.success(), "{printed:?}");
    assert!(training, "the summary says it is a training process");
    assert!(versions.len() >= 3, "the field was refreshed: {versions:?}");
    assert!(versions.windows(2).all(|w| w[0] < w[1]), "{versions:?}");
    assert!(
        printed
            .iter()
            .any(|l| l.contains("viewer stopped with the training")),
        "{printed:?}"
    );
    assert!(out.join("model.bpk").is_file());
}

#[test]
fn viewer_flags_are_refused_at_bad_values() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("run");
    let o = out.to_str().expect("utf-8");
    for (args, says) in [
        (
            vec!["--viewer", "--viewer-host", "my-laptop"],
            "--viewer-host",
        ),
        (vec!["--viewer", "--viewer-every", "0"], "--viewer-every 0"),
        (
            vec!["--viewer", "--viewer-every", "nan"],
            "--viewer-every NaN",
        ),
        (vec!["--viewer-port", "7008"], "--viewer"),
        (vec!["--viewer", "--viewer-port", "65536"], "65536"),
    ] {
        let run = train()
            .args(&args)
            .args(["--scene-size", "ci", "--iters", "2", "--out", o])
            .output()
            .expect("train runs");
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{args:?} succeeded");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {says:?} not in {err}");
        assert!(!out.exists(), "{args:?} wrote a run");
    }
}
