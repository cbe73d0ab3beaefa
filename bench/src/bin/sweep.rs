//! The speed/accuracy sweep: trains one scene once per setting (samples
//! per ray, trunk width and depth, rays per batch, the occupancy grid, the
//! time budget, and on feature scenes PCA and the head's top-k), each in
//! its own process so that its peak memory is its own, and writes
//! `sweep.{csv,json}`, `psnr_vs_seconds.png` and `ssim_vs_seconds.png`
//! (plus `miou_vs_seconds.png` on the benchmark synthetic scene) with the
//! Pareto front joined.
//!
//! `cargo run -p bench --release --bin sweep -- --scene lego [--budget S]`
//!
//! A point whose run finished earlier (its `summary.json`, and on the
//! synthetic scene its segmentation, present) is reused: a killed sweep
//! continues where it stopped.

// Flag help is written for `--help`, where `<scene>` is a placeholder.
#![allow(rustdoc::invalid_html_tags)]

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use bench::sweep::{SweepPoint, SweepResult, common_points, feature_points, pareto};
use clap::{Parser, ValueEnum};
use field_ops::backend::BackendArgs;
use field_ops::json::read_json;
use field_ops::scores::SegmentationScores;
use train::summary::Summary;

#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static ALLOCATOR: field_ops::allocator::Jemalloc = field_ops::allocator::Jemalloc;

/// Which scene to sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SweepScene {
    /// Blender lego at 100x100 (`--data`, downscaled 8 times).
    Lego,
    /// The benchmark-sized synthetic room (`--scene-seed`), with 3D segmentation.
    Bench,
}

/// Options.
#[derive(Debug, Parser)]
#[command(
    name = "sweep",
    about = "Speed against accuracy: one training run per setting"
)]
struct Args {
    /// Scene to sweep.
    #[arg(long, value_enum, default_value_t = SweepScene::Lego)]
    scene: SweepScene,
    /// Lego: the Blender scene directory.
    #[arg(long, default_value = "../shared/data/lego_train")]
    data: PathBuf,
    /// Bench: the synthetic scene's seed.
    #[arg(long, default_value_t = 21)]
    scene_seed: u64,
    /// Seconds of training of the central points [default: 60 for lego,
    /// 300 for bench]; the budget points use half and double.
    #[arg(long)]
    budget: Option<f64>,
    /// Run only these points (comma-separated names) [default: all].
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Output directory [default: runs/sweep-<scene>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Compute backend and device of every training run and segmentation.
    #[command(flatten)]
    compute: BackendArgs,
}

fn sibling(name: &str) -> Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let path = exe.with_file_name(name);
    if !path.exists() {
        bail!(
            "{} not found next to {} (build it: cargo build --release -p {name})",
            path.display(),
            exe.display()
        );
    }
    Ok(path)
}

fn run(cmd: &mut Command, what: &str) -> Result<()> {
    let status = cmd.status().with_context(|| format!("starting {what}"))?;
    if !status.success() {
        bail!("{what} failed ({status})");
    }
    Ok(())
}

/// Trains (and on the bench scene segments) one point, unless done before.
fn measure(args: &Args, p: &SweepPoint, out: &Path) -> Result<SweepResult> {
    let dir = out.join(&p.name);
    let seg = dir.join("segmentation.json");
    let bench = args.scene == SweepScene::Bench;
    if !dir.join("summary.json").exists() {
        if dir.exists() {
            std::fs::remove_dir_all(&dir)?;
        }
        let mut cmd = Command::new(sibling("train")?);
        match args.scene {
            SweepScene::Lego => cmd
                .args(["--dataset", "blender", "--downscale", "8", "--data"])
                .arg(&args.data),
            // The full render of the room's 25 held-out views takes as
            // long as the training itself on two cores; the held-out
            // figures come from the final evaluation on a pixel sample.
            SweepScene::Bench => cmd
                .args(["--scene-size", "bench", "--no-final-render", "--scene-seed"])
                .arg(args.scene_seed.to_string()),
        };
        cmd.args(args.compute.to_args())
            .args(["--quiet", "--time-budget"])
            .arg(p.budget.to_string())
            .arg("--out")
            .arg(&dir)
            .args(&p.flags);
        eprintln!(
            "== {} ({} s): train {}",
            p.name,
            p.budget,
            p.flags.join(" ")
        );
        run(&mut cmd, &format!("training {}", p.name))?;
    }
    if bench && !seg.exists() {
        let mut cmd = Command::new(sibling("eval")?);
        cmd.args(["segment", "--run"])
            .arg(&dir)
            .args(args.compute.to_args())
            .args(["--max-views", "20", "--render-scale", "0.5"]);
        run(&mut cmd, &format!("segmenting {}", p.name))?;
    }
    let s: Summary = read_json(&dir.join("summary.json"))?;
    let (miou, miou_tail) = if bench {
        let v: SegmentationScores = read_json(&seg)?;
        let pct = |x: f64| 100.0 * x;
        (v.all.miou.map(pct), v.tail.and_then(|t| t.miou).map(pct))
    } else {
        (None, None)
    };
    // Training seconds: the clock of the last training line of the log.
    let metrics = dir.join("metrics.jsonl");
    let log = std::fs::read_to_string(&metrics)
        .with_context(|| format!("reading {}", metrics.display()))?;
    let train_seconds = train::curve::parse(&log)
        .batch_psnr
        .last()
        .map_or(f64::NAN, |p| p.0);
    Ok(SweepResult {
        point: p.clone(),
        train_seconds,
        wall_seconds: s.wall_seconds,
        iterations: s.iterations,
        rays_per_second: s.rays_per_second,
        peak_memory_bytes: s.peak_memory_bytes,
        psnr_interior: s.heldout_interior.psnr,
        psnr_whole: s.heldout_whole.map(|m| m.psnr),
        ssim_interior: s.heldout_interior.ssim,
        depth_mae: s.heldout_interior.depth_mae,
        miou,
        miou_tail,
    })
}

fn main() -> Result<()> {
    let args = Args::parse();
    // Subnormals flushed to zero: docs/measurements/cpu-step.md.
    field_ops::subnormals::flush_to_zero();
    args.compute.check().map_err(anyhow::Error::msg)?;
    let (budget, points) = match args.scene {
        SweepScene::Lego => {
            let b = args.budget.unwrap_or(60.0);
            (b, common_points(b))
        }
        SweepScene::Bench => {
            let b = args.budget.unwrap_or(300.0);
            (b, feature_points(b))
        }
    };
    if !(budget.is_finite() && budget > 0.0) {
        bail!("--budget {budget}: give a positive number of seconds");
    }
    if args.scene == SweepScene::Lego && !args.data.join("transforms_train.json").exists() {
        bail!(
            "{}: no transforms_train.json (give the lego scene with --data)",
            args.data.display()
        );
    }
    for name in &args.only {
        if !points.iter().any(|p| &p.name == name) {
            let all: Vec<&str> = points.iter().map(|p| p.name.as_str()).collect();
            bail!("--only {name}: no such point (points: {})", all.join(", "));
        }
    }
    let scene = match args.scene {
        SweepScene::Lego => "lego",
        SweepScene::Bench => "bench",
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("runs/sweep-{scene}")));
    std::fs::create_dir_all(&out)?;
    let mut results = Vec::new();
    for p in points
        .iter()
        .filter(|p| args.only.is_empty() || args.only.contains(&p.name))
    {
        results.push(measure(&args, p, &out)?);
    }
    bench::sweep::write_report(&results, &out).map_err(|e| anyhow::anyhow!(e))?;
    let front = pareto(
        &results
            .iter()
            .map(|r| (r.train_seconds, r.psnr_interior))
            .collect::<Vec<_>>(),
    );
    println!(
        "{:<20} {:>8} {:>7} {:>9} {:>8} {:>9} {:>8}",
        "point", "train s", "iters", "rays/s", "peak MB", "PSNR int", "mIoU"
    );
    for (i, r) in results.iter().enumerate() {
        println!(
            "{:<20} {:>8.0} {:>7} {:>9.0} {:>8.0} {:>9.2} {:>8}{}",
            r.point.name,
            r.train_seconds,
            r.iterations,
            r.rays_per_second,
            r.peak_memory_bytes.unwrap_or(0) as f64 / 1e6,
            r.psnr_interior,
            r.miou.map_or("-".into(), |m| format!("{m:.1}")),
            if front.contains(&i) { "  (Pareto)" } else { "" }
        );
    }
    println!(
        "written: {}/sweep.{{csv,json}} and the PNG plots",
        out.display()
    );
    Ok(())
}
