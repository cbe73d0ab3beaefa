//! The PyTorch baseline: `scripts/bench_vlm_torch.py` run in the same process tree.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, ensure};

use super::{Args, Row};

/// The PyTorch script: `--torch-script`, else the first that exists of
/// `scripts/bench_vlm_torch.py` under the current directory and in the
/// source tree this binary was built from.
fn torch_script(args: &Args) -> Result<PathBuf> {
    let candidates = match &args.torch_script {
        Some(p) => vec![p.clone()],
        None => vec![
            PathBuf::from("scripts/bench_vlm_torch.py"),
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/bench_vlm_torch.py"),
        ],
    };
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .with_context(|| {
            let tried: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
            format!(
                "the PyTorch script is not at {} (set --torch-script)",
                tried.join(" or ")
            )
        })
}

/// Runs the PyTorch baseline and returns its JSON line.
pub(crate) fn run_pytorch(python: &Path, args: &Args) -> Result<serde_json::Value> {
    let script = torch_script(args)?;
    eprintln!(
        "pytorch: {} {} (progress on stderr)",
        python.display(),
        script.display()
    );
    let output = Command::new(python)
        .arg(&script)
        .args(["--width", &args.width.to_string()])
        .args(["--height", &args.height.to_string()])
        .args(["--short-side", &args.short_side.to_string()])
        .args(["--frames", &args.frames.to_string()])
        .args(["--batch", &args.batch.to_string()])
        .args(["--dense", args.dense.name()])
        .stderr(Stdio::inherit())
        .output()
        .with_context(|| format!("cannot run {}", python.display()))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    ensure!(
        output.status.success(),
        "{} {} failed ({}); stdout: {}",
        python.display(),
        script.display(),
        output.status,
        stdout.trim()
    );
    let line = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .context("the PyTorch script printed nothing on stdout")?;
    serde_json::from_str(line)
        .with_context(|| format!("the PyTorch script's last line is not JSON: {line}"))
}

/// The PyTorch measurement as a row.
pub(crate) fn pytorch_row(v: &serde_json::Value, flops: f64) -> Result<Row> {
    let num = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_f64)
            .with_context(|| format!("the PyTorch JSON has no number {k:?}"))
    };
    let secs = num("seconds_per_frame")?;
    ensure!(secs > 0.0, "the PyTorch JSON reports {secs} s per frame");
    let grid = v
        .get("grid")
        .and_then(|g| g.as_array())
        .and_then(|g| Some((g.first()?.as_u64()? as usize, g.get(1)?.as_u64()? as usize)))
        .context("the PyTorch JSON has no grid [rows, cols]")?;
    let per_frame = v
        .get("per_frame")
        .and_then(|p| p.as_array())
        .map(|p| p.iter().filter_map(serde_json::Value::as_f64).collect())
        .unwrap_or_default();
    Ok(Row {
        implementation: format!(
            "pytorch {}",
            v.get("torch").and_then(|t| t.as_str()).unwrap_or("?")
        ),
        threads: num("threads")? as usize,
        windows: num("windows")? as usize,
        grid,
        seconds_per_frame: secs,
        frames_per_s: 1.0 / secs,
        gflop_per_frame: flops / 1e9,
        gflop_per_s: flops / secs / 1e9,
        ratio_to_pytorch: Some(1.0),
        gemm_seconds_per_frame: None,
        cores_busy: v
            .get("cpu_seconds_per_frame")
            .and_then(serde_json::Value::as_f64)
            .map(|cpu| cpu / secs),
        per_frame,
    })
}
