//! Dense CLIP feature extraction speed: a ViT-B/16 tower with random weights
//! of the real size turns one frame (random seeded content, 640x360 by
//! default) into a NACLIP dense map (short side resized to 336, 224-px
//! windows every 112 px, run in batches, averaged), timed on each backend,
//! and optionally the same extraction in PyTorch (`scripts/bench_vlm_torch.py`,
//! run by `--python`) in the same run. Prints seconds per frame, frames/s,
//! the throughput ratio to PyTorch, GFLOP per frame and GFLOP/s, and the time
//! of the tower's matrix products alone (the same shapes, nothing else), and
//! writes `bench_vlm.csv` and `bench_vlm.json` under `--out`.
//!
//! `cargo run -p bench --release --bin bench-vlm -- [--frames N] [--python PATH]`
//! (`scripts/bench-vlm.sh` makes a PyTorch venv and passes `--python`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, ensure};
use clap::Parser;
use clip::vision::DenseOptions;
use clip::{ClipVisionConfig, DenseVariant};
use serde::Serialize;
mod breakdown;
mod cpu;
mod pytorch;
mod timing;

use cpu::{cpu_model, logical_cpus};
use field_ops::backend::BackendListArgs;
use pytorch::{pytorch_row, run_pytorch};
use timing::{BackendTiming, random_frame, time_backend, window_flops};

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Benchmark options.
#[derive(Debug, Parser)]
#[command(
    name = "bench-vlm",
    about = "Dense CLIP (ViT-B/16, NACLIP) feature extraction speed per backend, against PyTorch"
)]
struct Args {
    /// Backends to time (`--backend`, comma-separated) and wgpu's adapter
    /// (`--device`).
    #[command(flatten)]
    compute: BackendListArgs,
    /// Timed frames per implementation, after one untimed warm-up frame.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..))]
    frames: u64,
    /// Frame width in pixels (random uint8 RGB content, seeded).
    #[arg(long, default_value_t = 640, value_parser = clap::value_parser!(u64).range(16..=8192))]
    width: u64,
    /// Frame height in pixels.
    #[arg(long, default_value_t = 360, value_parser = clap::value_parser!(u64).range(16..=8192))]
    height: u64,
    /// Short side after resizing, in pixels (at least the model's 224-px input).
    #[arg(long, default_value_t = 336, value_parser = clap::value_parser!(u64).range(224..=8192))]
    short_side: u64,
    /// Windows run together in one forward pass (the last batch holds the rest).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(1..=1024))]
    batch: u64,
    /// The last block's dense variant: naclip, clearclip or maskclip.
    #[arg(long, default_value_t = DenseVariant::Naclip,
          value_parser = field_ops::vlm_maps::dense_variant_parser())]
    dense: DenseVariant,
    /// Seed of the frame's content and of the random weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A Python interpreter with torch and transformers: runs the PyTorch
    /// baseline (`--torch-script`) with the same sizes in this run.
    #[arg(long)]
    python: Option<PathBuf>,
    /// The PyTorch baseline script run by `--python` [default:
    /// scripts/bench_vlm_torch.py under the current directory, else in the
    /// source tree this binary was built from].
    #[arg(long)]
    torch_script: Option<PathBuf>,
    /// Skip timing the tower's matrix products alone (the "GEMM s" column).
    #[arg(long)]
    no_gemm: bool,
    /// Also print where a frame's time goes: its stages (resize, tower,
    /// averaging) and each operation of one block timed alone at the
    /// frame's batch shape, with the cores each kept busy.
    #[arg(long)]
    breakdown: bool,
    /// Directory for bench_vlm.csv and bench_vlm.json (created if missing).
    #[arg(long, default_value = "runs/bench-vlm")]
    out: PathBuf,
}

/// The frame and window geometry shared by every implementation.
#[derive(Debug, Clone, Serialize)]
struct Geometry {
    width: usize,
    height: usize,
    short_side: usize,
    resized: (usize, usize),
    grid: (usize, usize),
    windows: usize,
    batch: usize,
    dense: String,
}

/// One implementation's measurement.
#[derive(Debug, Clone, Serialize)]
struct Row {
    implementation: String,
    threads: usize,
    windows: usize,
    grid: (usize, usize),
    seconds_per_frame: f64,
    frames_per_s: f64,
    gflop_per_frame: f64,
    gflop_per_s: f64,
    /// Throughput against PyTorch (ours / PyTorch frames per second).
    ratio_to_pytorch: Option<f64>,
    /// Seconds per frame of the tower's matrix products alone.
    gemm_seconds_per_frame: Option<f64>,
    /// Process CPU seconds (all threads) over wall seconds while timing:
    /// the cores kept busy on average.
    cores_busy: Option<f64>,
    per_frame: Vec<f64>,
}

/// The report written to bench_vlm.json.
#[derive(Debug, Serialize)]
struct Report {
    cpu: String,
    logical_cpus: usize,
    model: &'static str,
    geometry: Geometry,
    frames: u64,
    gflop_per_frame: f64,
    rows: Vec<Row>,
    /// The PyTorch script's own JSON line, as printed.
    pytorch: Option<serde_json::Value>,
}

/// Writes `bench_vlm.csv` (one row per implementation) and
/// `bench_vlm.json` (the whole report) under `dir`.
fn write_outputs(dir: &Path, report: &Report) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let g = &report.geometry;
    let mut csv = String::from(
        "implementation,threads,cpu,width,height,short_side,batch,dense,windows,grid_rows,\
         grid_cols,gflop_per_frame,seconds_per_frame,frames_per_s,gflop_per_s,\
         ratio_to_pytorch,gemm_seconds_per_frame,cores_busy,per_frame\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    for r in &report.rows {
        let per: Vec<String> = r.per_frame.iter().map(|s| format!("{s:.6}")).collect();
        // Writing to a String cannot fail.
        let _ = writeln!(
            csv,
            "{},{},\"{}\",{},{},{},{},{},{},{},{},{:.3},{:.6},{:.6},{:.3},{},{},{},{}",
            r.implementation,
            r.threads,
            report.cpu.replace('"', "'"),
            g.width,
            g.height,
            g.short_side,
            g.batch,
            g.dense,
            r.windows,
            r.grid.0,
            r.grid.1,
            r.gflop_per_frame,
            r.seconds_per_frame,
            r.frames_per_s,
            r.gflop_per_s,
            opt(r.ratio_to_pytorch),
            opt(r.gemm_seconds_per_frame),
            opt(r.cores_busy),
            per.join(";")
        );
    }
    let csv_path = dir.join("bench_vlm.csv");
    std::fs::write(&csv_path, csv)
        .with_context(|| format!("cannot write {}", csv_path.display()))?;
    let json_path = dir.join("bench_vlm.json");
    let json = serde_json::to_string_pretty(report).context("cannot serialise the report")?;
    std::fs::write(&json_path, json + "\n")
        .with_context(|| format!("cannot write {}", json_path.display()))?;
    Ok(())
}

/// The table and its header lines.
#[allow(clippy::too_many_arguments)]
fn print_table(
    geometry: &Geometry,
    args: &Args,
    flops: f64,
    per_window: f64,
    cpu: &str,
    threads: usize,
    rows: &[Row],
) {
    let (w, h) = (args.width, args.height);
    println!(
        "ViT-B/16 (random weights), {} dense, {}x{} frame -> short side {} -> {}x{} \
         (grid {}x{}), {} windows of 224 px in batches of {}; {} timed frames",
        geometry.dense,
        w,
        h,
        geometry.short_side,
        geometry.resized.1,
        geometry.resized.0,
        geometry.grid.1,
        geometry.grid.0,
        geometry.windows,
        geometry.batch,
        args.frames
    );
    println!(
        "{:.1} GFLOP per frame ({:.2} per window, matrix products); CPU: {cpu}, {threads} logical CPUs",
        flops / 1e9,
        per_window / 1e9
    );
    println!(
        "{:<26} {:>7} {:>6} {:>9} {:>9} {:>9} {:>10} {:>8}",
        "implementation",
        "threads",
        "busy",
        "s/frame",
        "frames/s",
        "GFLOP/s",
        "vs PyTorch",
        "GEMM s"
    );
    for r in rows {
        println!(
            "{:<26} {:>7} {:>6} {:>9.3} {:>9.3} {:>9.1} {:>10} {:>8}",
            r.implementation,
            r.threads,
            r.cores_busy.map_or("-".into(), |x| format!("{x:.2}")),
            r.seconds_per_frame,
            r.frames_per_s,
            r.gflop_per_s,
            r.ratio_to_pytorch
                .map_or("-".into(), |x| format!("{x:.2}x")),
            r.gemm_seconds_per_frame
                .map_or("-".into(), |x| format!("{x:.3}"))
        );
    }
    println!(
        "busy: CPU seconds / wall seconds while timing (cores kept busy); vs PyTorch: \
         throughput ratio (ours / PyTorch frames per second); GEMM s: the tower's matrix \
         products alone, same shapes, per frame"
    );
}

fn main() -> Result<()> {
    let args = Args::parse();
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    args.compute.check().map_err(anyhow::Error::msg)?;
    ensure!(
        !args.compute.backend.is_empty() || args.python.is_some(),
        "nothing to time: give --backend or --python"
    );
    let (h, w) = (args.height as usize, args.width as usize);
    let options = DenseOptions {
        variant: args.dense,
        short_side: Some(args.short_side as usize),
        batch: args.batch as usize,
    };
    let config = ClipVisionConfig::vit_b_16();
    let per_window = window_flops(&config, args.dense);
    let frame = random_frame(h, w, args.seed);
    let cpu = cpu_model();
    let threads = logical_cpus();

    let pytorch = match &args.python {
        Some(python) => Some(run_pytorch(python, &args).context("the PyTorch baseline")?),
        None => None,
    };

    let mut rows = Vec::new();
    let mut geometry = None;
    for &kind in &args.compute.backend {
        let BackendTiming {
            per_frame: times,
            geometry: geo,
            gemm,
            cores_busy,
        } = time_backend(kind, &args, &frame, &options)
            .with_context(|| format!("timing the {kind} backend"))?;
        let secs = times.iter().sum::<f64>() / times.len().max(1) as f64;
        let flops = per_window * geo.windows as f64;
        rows.push(Row {
            implementation: format!("burn {kind}"),
            threads,
            windows: geo.windows,
            grid: geo.grid,
            seconds_per_frame: secs,
            frames_per_s: 1.0 / secs,
            gflop_per_frame: flops / 1e9,
            gflop_per_s: flops / secs / 1e9,
            ratio_to_pytorch: None,
            gemm_seconds_per_frame: gemm,
            cores_busy,
            per_frame: times,
        });
        geometry = Some(geo);
    }
    let geometry = match geometry {
        Some(g) => g,
        None => {
            // PyTorch alone: the geometry from its JSON.
            let v = pytorch.as_ref().context("no measurement")?;
            let n = |k: &str| v.get(k).and_then(serde_json::Value::as_u64).unwrap_or(0) as usize;
            let row = pytorch_row(v, 0.0)?;
            Geometry {
                width: w,
                height: h,
                short_side: args.short_side as usize,
                resized: (
                    row.grid.0 * config.patch_size,
                    row.grid.1 * config.patch_size,
                ),
                grid: row.grid,
                windows: n("windows"),
                batch: options.batch,
                dense: args.dense.name().into(),
            }
        }
    };
    let flops = per_window * geometry.windows as f64;
    if let Some(v) = &pytorch {
        let row = pytorch_row(v, flops)?;
        if (row.windows, row.grid) != (geometry.windows, geometry.grid) {
            eprintln!(
                "warning: PyTorch ran {} windows over a {:?} grid, Burn {} over {:?}",
                row.windows, row.grid, geometry.windows, geometry.grid
            );
        }
        let fps = row.frames_per_s;
        for r in &mut rows {
            r.ratio_to_pytorch = Some(r.frames_per_s / fps);
        }
        rows.insert(0, row);
    }

    print_table(&geometry, &args, flops, per_window, &cpu, threads, &rows);

    let report = Report {
        cpu,
        logical_cpus: threads,
        model: "CLIP ViT-B/16 (random weights)",
        geometry,
        frames: args.frames,
        gflop_per_frame: flops / 1e9,
        rows,
        pytorch,
    };
    write_outputs(&args.out, &report)?;
    println!("written: {}/bench_vlm.{{csv,json}}", args.out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vit_b_16_costs_about_33_gflop_a_window() {
        let c = ClipVisionConfig::vit_b_16();
        let f = window_flops(&c, DenseVariant::Naclip);
        // 11 full blocks of 197 tokens: 2 * 197 * (4 * 768^2 + 2 * 768 * 3072)
        // + 4 * 197^2 * 768 each.
        let block = 2.0 * 197.0 * (4.0 * 768.0f64.powi(2) + 2.0 * 768.0 * 3072.0)
            + 4.0 * 197.0f64.powi(2) * 768.0;
        assert!(f > 11.0 * block && f < 12.0 * block, "{f}");
        assert!((f / 1e9 - 33.2).abs() < 0.2, "{f}");
        assert!(window_flops(&c, DenseVariant::Maskclip) < f);
    }

    #[test]
    fn frames_are_seeded_bytes() {
        let a = random_frame(4, 5, 1);
        assert_eq!(a.len(), 60);
        assert_eq!(a, random_frame(4, 5, 1));
        assert_ne!(a, random_frame(4, 5, 2));
        assert!(
            a.iter()
                .all(|v| (0.0..=1.0).contains(v) && ((v * 255.0).round() - v * 255.0).abs() < 1e-3)
        );
    }
}
