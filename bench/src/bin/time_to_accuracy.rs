//! Time to accuracy with and without empty-space skipping, in one run: the
//! same scene, configuration, seed and iteration count are trained twice
//! (plain, then with `--occupancy-grid`), one after the other on this
//! machine; the held-out PSNR of the periodic evaluations gives the seconds
//! each needs to reach every target.
//!
//! `cargo run -p bench --release --bin time_to_accuracy -- [--data DIR] [--iters N]`
//!
//! Writes `time_to_accuracy.{csv,json,png}` into `--out`; a run already
//! finished there (its `summary.json` present) is reused, so a killed
//! benchmark continues where it stopped.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Parser;
use field_ops::backend::BackendArgs;
use field_ops::json::read_json;
use plotters::prelude::*;
use serde::Serialize;
use serde_json::json;
use train::summary::Summary;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Options.
#[derive(Debug, Parser)]
#[command(
    name = "time_to_accuracy",
    about = "Seconds to reach held-out PSNR targets with and without the occupancy grid"
)]
struct Args {
    /// Blender/nerfstudio scene directory.
    #[arg(long, default_value = "../shared/data/lego_train")]
    data: PathBuf,
    /// Divide the image size by N (8: lego at 100x100).
    #[arg(long, default_value_t = 8)]
    downscale: u32,
    /// Iterations of each run (the same schedule for both).
    #[arg(long, default_value_t = 2000)]
    iters: usize,
    /// Held-out evaluation every N iterations (the time resolution).
    #[arg(long, default_value_t = 50)]
    eval_every: usize,
    /// Held-out PSNR targets in dB.
    #[arg(long, value_delimiter = ',', default_values_t = [24.0, 26.0])]
    targets: Vec<f64>,
    /// Cells per axis of the grid.
    #[arg(long, default_value_t = 32)]
    grid_resolution: usize,
    /// Output directory (one run directory per variant inside).
    #[arg(long, default_value = "runs/time-to-accuracy")]
    out: PathBuf,
    /// Compute backend and device of both runs.
    #[command(flatten)]
    compute: BackendArgs,
}

/// Seconds of the first evaluation at `target` or above.
fn first_reaching(curve: &[(f64, f64)], target: f64) -> Option<f64> {
    curve.iter().find(|p| p.1 >= target).map(|p| p.0)
}

/// Seconds of the first evaluation where the mean of it and the two before
/// it is at `target` or above (one lucky evaluation does not count).
fn sustained_reaching(curve: &[(f64, f64)], target: f64) -> Option<f64> {
    curve
        .windows(3)
        .find(|w| w.iter().map(|p| p.1).sum::<f64>() / 3.0 >= target)
        .map(|w| w[2].0)
}

fn train(args: &Args, dir: &Path, config: &Path, grid: bool) -> Result<()> {
    if dir.join("summary.json").exists() {
        eprintln!("{}: finished earlier, reused", dir.display());
        return Ok(());
    }
    if dir.exists() {
        std::fs::remove_dir_all(dir).with_context(|| format!("clearing {}", dir.display()))?;
    }
    let mut argv: Vec<String> = ["train", "--dataset", "blender", "--quiet"]
        .map(String::from)
        .to_vec();
    argv.extend([
        "--data".into(),
        args.data.display().to_string(),
        "--downscale".into(),
        args.downscale.to_string(),
        "--iters".into(),
        args.iters.to_string(),
        "--config".into(),
        config.display().to_string(),
        "--out".into(),
        dir.display().to_string(),
    ]);
    argv.extend(args.compute.to_args());
    if grid {
        argv.extend([
            "--occupancy-grid".into(),
            "--grid-resolution".into(),
            args.grid_resolution.to_string(),
        ]);
    }
    eprintln!("training: {}", argv.join(" "));
    let cli = train::cli::Cli::try_parse_from(&argv)?;
    train::run_cli(&cli, &train::interrupt::StopFlag::new()).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// Seconds one variant needed to reach one target.
#[derive(Debug, Serialize)]
struct Reach {
    psnr: f64,
    first_seconds: Option<f64>,
    sustained_seconds: Option<f64>,
}

/// What one variant measured.
#[derive(Debug, Serialize)]
struct Row {
    variant: String,
    targets: Vec<Reach>,
    final_psnr_interior: f64,
    final_psnr_whole: Option<f64>,
    train_seconds: f64,
    wall_seconds: f64,
    rays_per_second: f64,
    rays_rendered: Option<f64>,
    ray_length_sampled: Option<f64>,
}

/// What the run in `dir` measured, and its held-out curve `(seconds, PSNR)`.
fn measure(variant: &str, dir: &Path, targets: &[f64]) -> Result<(Row, Vec<(f64, f64)>)> {
    let metrics = dir.join("metrics.jsonl");
    let log = std::fs::read_to_string(&metrics)
        .with_context(|| format!("reading {}", metrics.display()))?;
    let curves = train::curve::parse(&log);
    let skipping = curves.mean_skipping();
    let summary: Summary = read_json(&dir.join("summary.json"))?;
    // Training seconds: the clock of the last training line.
    let train_seconds = curves.batch_psnr.last().map_or(f64::NAN, |p| p.0);
    let curve = curves.heldout_psnr;
    let row = Row {
        variant: variant.into(),
        targets: targets
            .iter()
            .map(|&t| Reach {
                psnr: t,
                first_seconds: first_reaching(&curve, t),
                sustained_seconds: sustained_reaching(&curve, t),
            })
            .collect(),
        final_psnr_interior: summary.heldout_interior.psnr,
        final_psnr_whole: summary.heldout_whole.map(|m| m.psnr),
        train_seconds,
        wall_seconds: summary.wall_seconds,
        rays_per_second: summary.rays_per_second,
        rays_rendered: skipping.map(|s| s.0),
        ray_length_sampled: skipping.map(|s| s.1),
    };
    Ok((row, curve))
}

fn main() -> Result<()> {
    let args = Args::parse();
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    args.compute.check().map_err(anyhow::Error::msg)?;
    if !args.data.join("transforms_train.json").exists()
        && !args.data.join("transforms.json").exists()
    {
        bail!(
            "{}: no transforms_train.json or transforms.json (give a Blender scene with --data)",
            args.data.display()
        );
    }
    if args.iters == 0 || args.eval_every == 0 {
        bail!("--iters and --eval-every must be at least 1");
    }
    std::fs::create_dir_all(&args.out)?;
    let config = args.out.join("config-patch.json");
    let patch = json!({"logging": {"eval_every": args.eval_every, "checkpoint_every": 0}});
    std::fs::write(&config, serde_json::to_string_pretty(&patch)?)?;
    let variants = [("plain", false), ("occupancy grid", true)];
    let mut rows = Vec::new();
    let mut curves = Vec::new();
    for (label, grid) in variants {
        let dir = args.out.join(if grid { "grid" } else { "plain" });
        train(&args, &dir, &config, grid)?;
        let (row, curve) = measure(label, &dir, &args.targets)?;
        rows.push(row);
        curves.push((label, curve));
    }
    let mut csv = String::from(
        "variant,target_db,first_seconds,sustained_seconds,final_psnr_interior,final_psnr_whole,\
         train_seconds,wall_seconds,rays_rendered,ray_length_sampled\n",
    );
    let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:.3}"));
    for r in &rows {
        for t in &r.targets {
            csv.push_str(&format!(
                "{},{},{},{},{:.3},{},{:.2},{:.2},{},{}\n",
                r.variant,
                t.psnr,
                opt(t.first_seconds),
                opt(t.sustained_seconds),
                r.final_psnr_interior,
                opt(r.final_psnr_whole),
                r.train_seconds,
                r.wall_seconds,
                opt(r.rays_rendered),
                opt(r.ray_length_sampled),
            ));
        }
    }
    std::fs::write(args.out.join("time_to_accuracy.csv"), &csv)?;
    let report = json!({
        "scene": args.data.display().to_string(),
        "downscale": args.downscale,
        "iterations": args.iters,
        "eval_every": args.eval_every,
        "seconds_measured_on": "held-out views, a fixed sample of interior pixels (the periodic evaluation); \
            first = first evaluation at the target, sustained = first where the mean of three consecutive evaluations is",
        "final_measured_on": "every held-out view rendered in full (interior pixels and every pixel)",
        "variants": rows,
    });
    std::fs::write(
        args.out.join("time_to_accuracy.json"),
        serde_json::to_string_pretty(&report)?,
    )?;
    plot(
        &curves,
        &args.targets,
        &args.out.join("time_to_accuracy.png"),
    )
    .map_err(|e| anyhow::anyhow!(e))?;
    println!(
        "seconds to held-out PSNR (interior pixel sample; first / sustained over 3 evaluations), {} iterations each:",
        args.iters
    );
    for r in &rows {
        let cells: Vec<String> = r
            .targets
            .iter()
            .map(|t| {
                format!(
                    "{} dB: {} / {} s",
                    t.psnr,
                    t.first_seconds.map_or("-".into(), |x| format!("{x:.0}")),
                    t.sustained_seconds
                        .map_or("-".into(), |x| format!("{x:.0}"))
                )
            })
            .collect();
        println!(
            "  {:<15} {}; final {:.2} dB interior, {} whole views; {:.0} s training",
            r.variant,
            cells.join(", "),
            r.final_psnr_interior,
            opt(r.final_psnr_whole),
            r.train_seconds
        );
    }
    println!(
        "written: {}",
        args.out.join("time_to_accuracy.{csv,json,png}").display()
    );
    Ok(())
}

fn plot(curves: &[(&str, Vec<(f64, f64)>)], targets: &[f64], path: &Path) -> Result<(), String> {
    let (w, h) = (800u32, 500u32);
    field_ops::plot::draw_png(path, w, h, |root| {
        let pts = curves.iter().flat_map(|c| c.1.iter());
        let t_max = pts.clone().map(|p| p.0).fold(1.0f64, f64::max) * 1.02;
        let p_max = pts
            .map(|p| p.1)
            .fold(0.0f64, f64::max)
            .max(targets.iter().copied().fold(0.0, f64::max))
            + 1.0;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "held-out views: PSNR of the interior pixel sample against seconds",
                ("sans-serif", 18),
            )
            .margin(12)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..t_max, 8f64..p_max)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("seconds")
            .y_desc("PSNR (dB)")
            .draw()
            .map_err(|e| e.to_string())?;
        for &t in targets {
            chart
                .draw_series(LineSeries::new([(0.0, t), (t_max, t)], BLACK.mix(0.3)))
                .map_err(|e| e.to_string())?;
        }
        for ((label, curve), colour) in curves.iter().zip([BLUE, RED]) {
            chart
                .draw_series(LineSeries::new(
                    curve.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(*label)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(|e| e.to_string())?;
        Ok(())
    })
}
