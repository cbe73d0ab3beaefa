//! What the `train` binary's command-line tests share: a small model, the
//! binary run with arguments, and a refusal checked for its words.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// A small model, so that a real run of a few iterations takes seconds.
pub const TINY: &str = r#"{
  "model": {"mlp": {"width": 16, "depth": 2, "skip_layer": 1, "max_deg": 4},
            "num_samples": 4, "head": {"width": 8, "layers": 1}},
  "sampler": {"rays_per_batch": 32, "border_margin": 2},
  "logging": {"checkpoint_every": 2, "eval_every": 0, "eval_pixels": 64}
}"#;

/// The JSON file at `path` (a run's `config.json`, `summary.json`, ...).
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read")).expect("json")
}

/// Runs the `train` binary with `args`.
pub fn train(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_train"))
        .args(args)
        .output()
        .expect("the train binary runs")
}

/// Trains `iters` iterations of the tiny model ([`TINY`], written into
/// `dir`) on `data` into `out`, without the final render, with `extra`
/// flags.
pub fn train_tiny(dir: &Path, data: &Path, out: &Path, iters: &str, extra: &[&str]) -> Output {
    let config = dir.join("tiny.json");
    std::fs::write(&config, TINY).expect("config");
    let mut args = vec![
        "--data",
        s(data),
        "--config",
        s(&config),
        "--iters",
        iters,
        "--no-final-render",
        "--quiet",
        "--out",
        s(out),
    ];
    args.extend_from_slice(extra);
    train(&args)
}

/// What a run printed: (stdout, stderr).
pub fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A path as a `&str` argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Asserts a clean refusal (non-zero exit, no panic) mentioning every
/// `words`; returns what it printed on stderr.
pub fn assert_refused(args: &[&str], words: &[&str]) -> String {
    let out = train(args);
    let (_, err) = text(&out);
    assert!(!out.status.success(), "{args:?} succeeded: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for w in words {
        assert!(err.contains(w), "{args:?}: {w:?} not in {err:?}");
    }
    // Shown with `--nocapture`: the message a user gets for this input.
    eprintln!("refused {args:?}:\n{}", err.trim_end());
    err
}

/// Writes `json` to `dir/name` and asserts that a run with it as its
/// `--config` is refused cleanly, naming every `words` and the file, and
/// writes no run directory. Returns what it printed on stderr.
pub fn assert_config_refused(dir: &Path, name: &str, json: &str, words: &[&str]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, json).expect("write the configuration");
    let run = dir.join(format!("{name}-run"));
    let err = assert_refused(
        &[
            "--config",
            s(&path),
            "--iters",
            "2",
            "--quiet",
            "--out",
            s(&run),
        ],
        &[words, &[name]].concat(),
    );
    assert!(!run.exists(), "nothing is written for a refused {name}");
    err
}

/// Trains 2 iterations of the model `config` describes on the synthetic
/// room into `run` with `extra` flags (the configuration written into
/// `dir`); returns what `train` printed, asserting it succeeded.
pub fn tiny_run(dir: &Path, run: &Path, config: &str, extra: &[&str]) -> String {
    let path = dir.join("config.json");
    std::fs::write(&path, config).expect("write config");
    let args = [
        &[
            "--config",
            s(&path),
            "--iters",
            "2",
            "--quiet",
            "--no-final-render",
            "--out",
            s(run),
        ][..],
        extra,
    ]
    .concat();
    let out = train(&args);
    let (_, err) = text(&out);
    assert!(out.status.success(), "{args:?}: {err}");
    err
}

pub mod steps;
