//! The report of `scripts/bench-scale.sh`: each stage's wall time and peak
//! resident memory (the `stages.json` that `train` and `eval` append to) for
//! each scene size, next to what grows between the sizes (frames x pixels,
//! feature-map pixels, feature dimension), so one table shows which stage
//! runs out of time or memory first as the scene approaches the paper's.
//!
//! `scale_report --dir runs/scale --sizes bench,paper` reads
//! `DIR/SIZE/{stages,scene}.json` and writes `DIR/scale.{csv,md,png}`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Parser;
use datasets::synthetic::SceneSize;
use field_ops::stages::{STAGES_FILE, StageRecord, read_records};

mod plot;

/// Options.
#[derive(Debug, Parser)]
#[command(
    name = "scale_report",
    about = "Tables and a plot of each stage's seconds and peak memory per scene size"
)]
struct Args {
    /// Directory holding one run directory per size.
    #[arg(long)]
    dir: PathBuf,
    /// The sizes (run directory names), in the order of the columns.
    #[arg(long, value_delimiter = ',', required = true)]
    sizes: Vec<String>,
}

/// Stages in pipeline order; others follow in the order first seen.
const STAGE_ORDER: [&str; 7] = [
    "scene",
    "sampler",
    "training",
    "novel views",
    "final render",
    "eval segment",
    "eval uncertainty",
];

/// A stage's figures at one size: seconds summed over its records (the
/// sampler is built again when novel views join), the largest peak.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cell {
    /// Wall seconds.
    pub seconds: f64,
    /// Peak resident memory, MiB.
    pub peak_mb: Option<f64>,
}

/// What one size's scene holds.
#[derive(Debug, Clone, Default)]
struct Scale {
    frames: Option<usize>,
    image_pixels: Option<u64>,
    map_pixels: Option<u64>,
    dim: Option<u64>,
    components: Option<u64>,
}

/// One size's run.
struct SizeRun {
    name: String,
    scale: Scale,
    stages: BTreeMap<String, Cell>,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let mut runs = Vec::new();
    for name in &args.sizes {
        runs.push(read_run(&args.dir, name)?);
    }
    let stages = stage_rows(&runs);
    let csv = csv_text(&runs, &stages);
    let md = markdown(&runs, &stages);
    let write = |file: &str, text: &str| {
        let path = args.dir.join(file);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
    };
    write("scale.csv", &csv)?;
    write("scale.md", &md)?;
    print!("{md}");
    let png = args.dir.join("scale.png");
    let columns: Vec<(String, Vec<Cell>)> = runs
        .iter()
        .map(|r| {
            let cells = stages
                .iter()
                .map(|s| r.stages.get(s).copied().unwrap_or_default())
                .collect();
            (r.name.clone(), cells)
        })
        .collect();
    // The numbers are in the tables: a missing font costs the picture only.
    match plot::draw(&png, &stages, &columns) {
        Ok(()) => println!(
            "wrote {}, {} and {}",
            args.dir.join("scale.csv").display(),
            args.dir.join("scale.md").display(),
            png.display()
        ),
        Err(e) => eprintln!("warning: {e}"),
    }
    Ok(())
}

/// Reads `DIR/NAME/stages.json` and `scene.json`.
fn read_run(dir: &Path, name: &str) -> Result<SizeRun> {
    let run = dir.join(name);
    let path = run.join(STAGES_FILE);
    if !path.exists() {
        bail!("{}: missing (was the size run?)", path.display());
    }
    let records: Vec<StageRecord> = read_records(&path)?;
    let mut stages: BTreeMap<String, Cell> = BTreeMap::new();
    for r in records {
        let cell = stages.entry(r.stage).or_default();
        cell.seconds += r.seconds;
        cell.peak_mb = match (cell.peak_mb, r.peak_mb) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
    }
    let scene: serde_json::Value = field_ops::json::read_json(&run.join("scene.json"))?;
    Ok(SizeRun {
        name: name.to_string(),
        scale: scale_of(&scene),
        stages,
    })
}

/// Frames, pixels and feature dimension of a run's scene (`scene.json`):
/// the synthetic presets are known by name; `D` and the kept PCA
/// components are read for any scene.
fn scale_of(scene: &serde_json::Value) -> Scale {
    let dim = scene["feature_dim"].as_u64();
    let components = scene["pca"]["k"].as_u64();
    let size = scene["source"]["size"]
        .as_str()
        .and_then(|s| s.parse::<SceneSize>().ok());
    let Some(size) = size else {
        return Scale {
            dim,
            components,
            ..Scale::default()
        };
    };
    let (n, w, h) = size.views();
    let ds = size.feature_downsample();
    let (mw, mh) = ((w / ds).max(1) as u64, (h / ds).max(1) as u64);
    Scale {
        frames: Some(n),
        image_pixels: Some(n as u64 * w as u64 * h as u64),
        map_pixels: Some(n as u64 * mw * mh),
        dim,
        components,
    }
}

/// The stages present at any size, in pipeline order.
fn stage_rows(runs: &[SizeRun]) -> Vec<String> {
    let mut rows: Vec<String> = STAGE_ORDER
        .iter()
        .filter(|s| runs.iter().any(|r| r.stages.contains_key(**s)))
        .map(|s| s.to_string())
        .collect();
    for r in runs {
        for s in r.stages.keys() {
            if !rows.contains(s) {
                rows.push(s.clone());
            }
        }
    }
    rows
}

/// The largest stage peak of a run: the whole pipeline's peak.
fn pipeline_peak(run: &SizeRun) -> Option<f64> {
    run.stages
        .values()
        .filter_map(|c| c.peak_mb)
        .reduce(f64::max)
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(String::new, |v| v.to_string())
}

/// One line per size and stage, then per size the sum of the stages'
/// seconds and the largest peak (the whole pipeline's).
fn csv_text(runs: &[SizeRun], stages: &[String]) -> String {
    let mut out = String::from("size,stage,seconds,peak_mb\n");
    for r in runs {
        for s in stages {
            if let Some(c) = r.stages.get(s) {
                let _ = writeln!(out, "{},{s},{:.3},{}", r.name, c.seconds, opt(c.peak_mb));
            }
        }
        let total: f64 = r.stages.values().map(|c| c.seconds).sum();
        let peak = opt(pipeline_peak(r));
        let _ = writeln!(out, "{},all stages (sum; max),{total:.3},{peak}", r.name);
    }
    out
}

/// A count in millions or thousands, to one decimal.
fn millions(v: Option<u64>) -> String {
    match v {
        None => "-".into(),
        Some(v) if v >= 1_000_000 => format!("{:.1} M", v as f64 / 1e6),
        Some(v) if v >= 1_000 => format!("{:.1} k", v as f64 / 1e3),
        Some(v) => v.to_string(),
    }
}

/// The stage table (rows: stages, columns: sizes) and the scale table.
fn markdown(runs: &[SizeRun], stages: &[String]) -> String {
    let mut out = String::from("Wall seconds / peak resident MiB (VmHWM) of each stage\n\n");
    let header: Vec<&str> = runs.iter().map(|r| r.name.as_str()).collect();
    let _ = writeln!(out, "| stage | {} |", header.join(" | "));
    let _ = writeln!(out, "|---|{}", "---:|".repeat(runs.len()));
    for s in stages {
        let cells: Vec<String> = runs
            .iter()
            .map(|r| match r.stages.get(s) {
                Some(c) => format!(
                    "{:.1} s / {} MB",
                    c.seconds,
                    c.peak_mb.map_or("-".into(), |p| format!("{p:.0}"))
                ),
                None => "-".into(),
            })
            .collect();
        let _ = writeln!(out, "| {s} | {} |", cells.join(" | "));
    }
    let totals: Vec<String> = runs
        .iter()
        .map(|r| {
            let total: f64 = r.stages.values().map(|c| c.seconds).sum();
            let peak = pipeline_peak(r).map_or("-".into(), |p| format!("{p:.0}"));
            format!("**{total:.1} s / {peak} MB**")
        })
        .collect();
    let _ = writeln!(
        out,
        "| all stages (sum of seconds / whole-pipeline peak) | {} |",
        totals.join(" | ")
    );
    out.push_str("\nWhat grows\n\n| size | frames | frames x pixels | map pixels | D | PCA k |\n");
    out.push_str("|---|---:|---:|---:|---:|---:|\n");
    for r in runs {
        let s = &r.scale;
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            r.name,
            s.frames.map_or("-".into(), |n| n.to_string()),
            millions(s.image_pixels),
            millions(s.map_pixels),
            s.dim.map_or("-".into(), |d| d.to_string()),
            s.components.map_or("-".into(), |k| k.to_string()),
        );
    }
    out
}
