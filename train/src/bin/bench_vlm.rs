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
//! `cargo run -p train --release --bin bench-vlm -- [--frames N] [--python PATH]`
//! (`scripts/bench-vlm.sh` makes a PyTorch venv and passes `--python`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{Context, Result, bail, ensure};
use burn::tensor::{Device, Distribution, Tensor};
use clap::Parser;
use clip::vision::{DenseOptions, VisionModel};
use model::clip::{ClipVisionConfig, DenseVariant};
use serde::Serialize;
use train::backend::{BackendKind, device, vulkan_available};

/// Benchmark options.
#[derive(Debug, Parser)]
#[command(
    name = "bench-vlm",
    about = "Dense CLIP (ViT-B/16, NACLIP) feature extraction speed per backend, against PyTorch"
)]
struct Args {
    /// Backends to time, comma-separated (flex, ndarray, wgpu). wgpu needs a
    /// Vulkan driver (a GPU, or lavapipe on the CPU: slow, for checking only).
    #[arg(long, alias = "backends", value_enum, value_delimiter = ',',
          default_values_t = [BackendKind::Flex, BackendKind::Ndarray])]
    backend: Vec<BackendKind>,
    /// wgpu only: the index of the discrete GPU (default: wgpu's default adapter).
    #[arg(long)]
    device: Option<usize>,
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
    #[arg(long, default_value = "naclip", value_parser = parse_variant)]
    dense: DenseVariant,
    /// Seed of the frame's content and of the random weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A Python interpreter with torch and transformers: runs the PyTorch
    /// baseline (`--torch-script`) with the same sizes in this run.
    #[arg(long)]
    python: Option<PathBuf>,
    /// The PyTorch baseline script run by `--python`.
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/bench_vlm_torch.py"))]
    torch_script: PathBuf,
    /// Skip timing the tower's matrix products alone (the "GEMM s" column).
    #[arg(long)]
    no_gemm: bool,
    /// Directory for bench_vlm.csv and bench_vlm.json (created if missing).
    #[arg(long, default_value = "runs/bench-vlm")]
    out: PathBuf,
}

fn parse_variant(s: &str) -> Result<DenseVariant, String> {
    s.parse()
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

/// Matrix-product FLOPs (2 per multiply-add) of one window through the
/// tower: patch embedding, every block (q, k, v and output projections,
/// the two attention products, the MLP), the last block as `variant` runs
/// it (no MLP; NACLIP and ClearCLIP project two of q/k/v plus the output,
/// MaskCLIP only v and the output, without attention), and the projection
/// of the patch tokens. Element-wise work (norms, softmax, GELU) is not
/// counted.
fn window_flops(c: &ClipVisionConfig, variant: DenseVariant) -> f64 {
    let g = (c.image_size / c.patch_size) as f64;
    let patches = g * g;
    let t = patches + 1.0;
    let w = c.width as f64;
    let mlp = c.mlp_width as f64;
    let attention = 2.0 * 2.0 * t * t * w;
    let block = 2.0 * t * (4.0 * w * w + 2.0 * w * mlp) + attention;
    let last = match variant {
        DenseVariant::Naclip | DenseVariant::Clearclip => 2.0 * t * 3.0 * w * w + attention,
        DenseVariant::Maskclip => 2.0 * t * 2.0 * w * w,
    };
    let embed = 2.0 * patches * (3.0 * (c.patch_size * c.patch_size) as f64) * w;
    let projection = 2.0 * patches * w * c.embed_dim as f64;
    embed + (c.layers as f64 - 1.0) * block + last + projection
}

/// The CPU's model name from `/proc/cpuinfo` ("unknown" elsewhere).
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

fn logical_cpus() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// `height x width x 3` random values `k / 255` (`k` a seeded uint8), HWC.
fn random_frame(height: usize, width: usize, seed: u64) -> Vec<f32> {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..height * width * 3)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 56) as u8) as f32 / 255.0
        })
        .collect()
}

/// The device for `kind`, refused with a reason where it cannot run here.
fn checked_device(kind: BackendKind, index: Option<usize>) -> Result<Device> {
    field_ops::backend::check_device_flag(kind, index).map_err(anyhow::Error::msg)?;
    if kind == BackendKind::Wgpu && !vulkan_available() {
        bail!(
            "--backend wgpu: no Vulkan driver is installed (no manifest under \
             /usr/share/vulkan/icd.d or /etc/vulkan/icd.d); without one wgpu falls back to \
             OpenGL, which deadlocks on software renderers. Install a GPU driver (or \
             mesa-vulkan-drivers for lavapipe on the CPU), or leave wgpu out of --backend"
        );
    }
    Ok(device(kind, index))
}

/// Seconds per frame of the tower's matrix products alone, at the shapes a
/// frame's batches run them (rows of every batch folded into one 2D
/// product for the linear layers, `[batch, heads]` batched products for
/// attention), with random operands made beforehand.
fn gemm_seconds(
    dev: &Device,
    c: &ClipVisionConfig,
    variant: DenseVariant,
    windows: usize,
    batch: usize,
) -> Result<f64> {
    let g = c.image_size / c.patch_size;
    let t = g * g + 1;
    let (w, mlp, heads) = (c.width, c.mlp_width, c.heads);
    ensure!(
        heads > 0 && w % heads == 0,
        "width {w} is not a multiple of {heads} heads"
    );
    let hd = w / heads;
    let rnd2 = |s: [usize; 2]| Tensor::<2>::random(s, Distribution::Default, dev);
    let rnd4 = |s: [usize; 4]| Tensor::<4>::random(s, Distribution::Default, dev);
    let (sq, up, down) = (rnd2([w, w]), rnd2([w, mlp]), rnd2([mlp, w]));
    let patch_w = rnd2([3 * c.patch_size * c.patch_size, w]);
    let proj = rnd2([w, c.embed_dim]);
    let sizes: Vec<usize> = (0..windows)
        .step_by(batch)
        .map(|s| batch.min(windows - s))
        .collect();
    let mut inputs = Vec::new();
    for &b in &sizes {
        inputs.push((
            rnd2([b * (t - 1), 3 * c.patch_size * c.patch_size]),
            rnd2([b * t, w]),
            rnd2([b * t, mlp]),
            rnd4([b, heads, t, hd]),
            rnd4([b, heads, t, t]),
        ));
    }
    let run = || -> f32 {
        let mut acc = Tensor::<1>::zeros([1], dev);
        for (px, x, hidden, q, a) in &inputs {
            acc = acc + px.clone().matmul(patch_w.clone()).sum();
            for layer in 0..c.layers {
                let last = layer + 1 == c.layers;
                let projections = match (last, variant) {
                    (false, _) => 4,
                    (true, DenseVariant::Maskclip) => 2,
                    (true, _) => 3,
                };
                for _ in 0..projections {
                    acc = acc + x.clone().matmul(sq.clone()).sum();
                }
                if !(last && variant == DenseVariant::Maskclip) {
                    acc = acc + q.clone().matmul(q.clone().swap_dims(2, 3)).sum();
                    acc = acc + a.clone().matmul(q.clone()).sum();
                }
                if !last {
                    acc = acc + x.clone().matmul(up.clone()).sum();
                    acc = acc + hidden.clone().matmul(down.clone()).sum();
                }
            }
            let [rows, _] = x.dims();
            acc = acc
                + x.clone()
                    .slice([0..rows - rows / t, 0..w])
                    .matmul(proj.clone())
                    .sum();
        }
        acc.into_scalar::<f32>()
    };
    let _ = run(); // warm-up
    let start = Instant::now();
    let _ = run();
    Ok(start.elapsed().as_secs_f64())
}

/// Times the Burn extraction on `kind`.
fn time_backend(
    kind: BackendKind,
    args: &Args,
    frame: &[f32],
    options: &DenseOptions,
) -> Result<(Vec<f64>, Geometry, Option<f64>)> {
    let dev = checked_device(kind, args.device)?;
    dev.seed(args.seed);
    let config = ClipVisionConfig::vit_b_16();
    let encoder = config.init(&dev);
    let model = VisionModel::from_encoder(encoder, config.clone(), &dev);
    let (h, w) = (args.height as usize, args.width as usize);
    let plan = model
        .plan((h, w), options)
        .with_context(|| format!("planning the windows of a {w}x{h} frame"))?;
    let geometry = Geometry {
        width: w,
        height: h,
        short_side: args.short_side as usize,
        resized: plan.resized,
        grid: plan.grid,
        windows: plan.origins.len(),
        batch: options.batch,
        dense: options.variant.name().into(),
    };
    let mut times = Vec::new();
    for i in 0..=args.frames {
        let start = Instant::now();
        let map = model
            .dense_map(frame, (h, w), options)
            .with_context(|| format!("{kind}: dense map of frame {i}"))?;
        let secs = start.elapsed().as_secs_f64();
        ensure!(
            (map.rows, map.cols) == plan.grid,
            "{kind}: the map is {}x{}, the plan says {:?}",
            map.rows,
            map.cols,
            plan.grid
        );
        ensure!(
            map.data.iter().all(|v| v.is_finite()),
            "{kind}: the dense map has non-finite values"
        );
        if i == 0 {
            eprintln!("{kind}: warm-up frame {secs:.3} s");
        } else {
            eprintln!("{kind}: frame {i} {secs:.3} s");
            times.push(secs);
        }
    }
    let gemm = if args.no_gemm {
        None
    } else {
        let secs = gemm_seconds(
            &dev,
            &config,
            options.variant,
            geometry.windows,
            options.batch,
        )
        .with_context(|| format!("{kind}: timing the matrix products alone"))?;
        eprintln!("{kind}: matrix products alone {secs:.3} s per frame");
        Some(secs)
    };
    Ok((times, geometry, gemm))
}

/// Runs the PyTorch baseline and returns its JSON line.
fn run_pytorch(python: &Path, args: &Args) -> Result<serde_json::Value> {
    ensure!(
        args.torch_script.is_file(),
        "the PyTorch script {} does not exist (set --torch-script)",
        args.torch_script.display()
    );
    eprintln!(
        "pytorch: {} {} (progress on stderr)",
        python.display(),
        args.torch_script.display()
    );
    let output = Command::new(python)
        .arg(&args.torch_script)
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
        args.torch_script.display(),
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
fn pytorch_row(v: &serde_json::Value, flops: f64) -> Result<Row> {
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
        per_frame,
    })
}

fn write_outputs(dir: &Path, report: &Report) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let g = &report.geometry;
    let mut csv = String::from(
        "implementation,threads,cpu,width,height,short_side,batch,dense,windows,grid_rows,\
         grid_cols,gflop_per_frame,seconds_per_frame,frames_per_s,gflop_per_s,\
         ratio_to_pytorch,gemm_seconds_per_frame,per_frame\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    for r in &report.rows {
        let per: Vec<String> = r.per_frame.iter().map(|s| format!("{s:.6}")).collect();
        // Writing to a String cannot fail.
        let _ = writeln!(
            csv,
            "{},{},\"{}\",{},{},{},{},{},{},{},{},{:.3},{:.6},{:.6},{:.3},{},{},{}",
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

fn main() -> Result<()> {
    let args = Args::parse();
    ensure!(
        !args.backend.is_empty() || args.python.is_some(),
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
    for &kind in &args.backend {
        let (times, geo, gemm) = time_backend(kind, &args, &frame, &options)
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
        "{:<26} {:>7} {:>9} {:>9} {:>9} {:>10} {:>8}",
        "implementation", "threads", "s/frame", "frames/s", "GFLOP/s", "vs PyTorch", "GEMM s"
    );
    for r in &rows {
        println!(
            "{:<26} {:>7} {:>9.3} {:>9.3} {:>9.1} {:>10} {:>8}",
            r.implementation,
            r.threads,
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
        "vs PyTorch: throughput ratio (ours / PyTorch frames per second); GEMM s: the tower's \
         matrix products alone, same shapes, per frame"
    );

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
                .all(|v| (0.0..=1.0).contains(v) && (v * 255.0).fract().abs() < 1e-3)
        );
    }
}
