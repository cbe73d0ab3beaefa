//! The JAX peer: `scripts/peer_step_jax.py` (the plain per-sample step in
//! JAX on the CPU) run with the benchmark's sizes, so that the Burn step
//! times come out as ratios to JAX measured on the same machine in one run.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, Result, ensure};

use super::Size;

/// What the JAX script measured.
#[derive(Debug, Clone)]
pub(crate) struct Peer {
    /// JAX version.
    pub version: String,
    /// CPU threads it ran with.
    pub threads: usize,
    /// Mean seconds of a timed step.
    pub secs: f64,
    /// FLOPs of one step, counted as [`Size::step_flops`] counts the per-sample path.
    pub flops: f64,
    /// GFLOP/s of its `[4096, w] x [w, w]` product loop.
    pub matmul: f64,
    /// Peak resident memory of the Python process, MB.
    pub peak_mb: f64,
}

/// The script: `scripts/peer_step_jax.py` under the current directory, else
/// in the source tree this binary was built from.
fn script() -> Result<PathBuf> {
    let candidates = [
        PathBuf::from("scripts/peer_step_jax.py"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/peer_step_jax.py"),
    ];
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .with_context(|| {
            format!(
                "the JAX peer script is not at {} or {}",
                candidates[0].display(),
                candidates[1].display()
            )
        })
}

/// Runs the JAX step with `size` (trunk skip layer `skip`) for `steps` timed
/// steps and parses its JSON line.
pub(crate) fn run(python: &Path, size: Size, skip: usize, steps: usize) -> Result<Peer> {
    let script = script()?;
    let cmd = format!("{} {}", python.display(), script.display());
    eprintln!("jax peer: {cmd} (compiles, then times {steps} steps)");
    let arg = |v: usize| v.to_string();
    let output = Command::new(python)
        .arg(&script)
        .args(["--rays", &arg(size.rays)])
        .args(["--samples", &arg(size.samples)])
        .args(["--width", &arg(size.width)])
        .args(["--depth", &arg(size.depth)])
        .args(["--skip", &arg(skip)])
        .args(["--head-width", &arg(size.head_width)])
        .args(["--feature-dim", &arg(size.feature_dim)])
        .args(["--steps", &arg(steps.max(1))])
        .stdin(Stdio::null())
        .output()
        .with_context(|| format!("cannot run the JAX peer {cmd}"))?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    ensure!(
        output.status.success(),
        "the JAX peer {cmd} failed ({}); its stderr:\n{}",
        output.status,
        stderr.trim_end()
    );
    eprint!("{stderr}");
    let line = stdout
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('{'))
        .with_context(|| {
            format!(
                "the JAX peer {cmd} printed no JSON line on stdout; its stderr:\n{}",
                stderr.trim_end()
            )
        })?;
    let v: serde_json::Value = serde_json::from_str(line)
        .with_context(|| format!("the JAX peer {cmd} printed a line that is not JSON: {line}"))?;
    let num = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_f64)
            .with_context(|| format!("the JSON of the JAX peer {cmd} has no number {k:?}: {line}"))
    };
    let secs = num("seconds_per_step")?;
    ensure!(
        secs > 0.0,
        "the JAX peer {cmd} reports {secs} s per step: {line}"
    );
    Ok(Peer {
        version: v
            .get("jax")
            .and_then(serde_json::Value::as_str)
            .unwrap_or("?")
            .to_string(),
        threads: num("threads")? as usize,
        secs,
        flops: num("gflop_per_step")? * 1e9,
        matmul: num("matmul_gflop_per_s")?,
        peak_mb: num("peak_mb").unwrap_or(0.0),
    })
}
