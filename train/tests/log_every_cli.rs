//! `--log-every` through the `train` binary: it sets how often a
//! `metrics.jsonl` line is written (and the steps' values read back), and
//! refuses 0 on the command line and in a `--config` file.

mod common;

use common::{assert_config_refused, assert_refused, s, train};

#[test]
fn log_every_sets_the_training_lines_and_refuses_zero() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("run");
    let run = train(&[
        "--iters",
        "12",
        "--log-every",
        "4",
        "--no-final-render",
        "--quiet",
        "--out",
        s(&out),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let config: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["logging"]["log_every"], 4);
    let lines: Vec<u64> = std::fs::read_to_string(out.join("metrics.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["event"] == "train")
        .map(|v| v["iteration"].as_u64().unwrap())
        .collect();
    assert_eq!(lines, vec![4, 8, 12]);

    assert_refused(&["--log-every", "0", "--iters", "2"], &["--log-every", "0"]);
    assert_refused(&["--log-every", "x", "--iters", "2"], &["--log-every"]);
    assert_config_refused(
        dir.path(),
        "log-zero.json",
        r#"{"logging": {"log_every": 0}}"#,
        &["logging.log_every", "at least 1"],
    );
}
