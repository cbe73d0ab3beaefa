//! What the batch tests share: the binaries, scene lists of tiny synthetic
//! runs, and the comparison of two runs' summaries.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `batch` binary.
pub fn batch_exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_batch"))
}

/// The `eval` binary, next to `batch` in the target directory (built by
/// `cargo test --workspace`, or `cargo build -p eval`).
pub fn eval_exe() -> PathBuf {
    let exe = batch_exe().with_file_name(format!("eval{}", std::env::consts::EXE_SUFFIX));
    assert!(
        exe.is_file(),
        "{} is not built: run the tests with --workspace, or `cargo build --release -p eval` first",
        exe.display()
    );
    exe
}

/// Runs `batch` with `args`.
pub fn batch(args: &[&str]) -> Output {
    Command::new(batch_exe())
        .args(args)
        .output()
        .expect("running batch")
}

/// Flags of a run that trains in seconds.
pub const TINY: &str = r#"["--quiet", "--no-final-render", "--width", "32", "--samples", "8"]"#;

/// Writes `text` as `dir/name` and returns its path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `summary.json` of `run` without the fields that measure time or memory.
pub fn non_timing_summary(run: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(run.join("summary.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let map = v.as_object_mut().unwrap();
    for k in [
        "wall_seconds",
        "rays_per_second",
        "render_rays_per_second",
        "peak_memory_bytes",
    ] {
        assert!(map.remove(k).is_some(), "summary.json without {k}");
    }
    v
}

/// Both outputs as text, for failure messages.
pub fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The newest logged training iteration of `run` (0 before the first).
pub fn logged_iteration(run: &Path) -> usize {
    std::fs::read_to_string(run.join("metrics.jsonl"))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["event"] == "train")
        .filter_map(|v| v["iteration"].as_u64())
        .max()
        .unwrap_or(0) as usize
}

/// Runs `eval gather dir` and returns the `benchmark.md` it wrote.
pub fn gather(dir: &Path) -> String {
    let o = Command::new(eval_exe())
        .args(["gather", dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    std::fs::read_to_string(dir.join("benchmark.md")).unwrap()
}
