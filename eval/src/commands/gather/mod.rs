//! `eval gather DIR`: the benchmark table of a directory of runs (a batch
//! directory as `batch` writes it, or any directory whose subdirectories
//! are runs). Every run of the batch is accounted for: those not finished
//! or failed are listed with why, never dropped silently.

mod chart;
mod table;

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use field_ops::batch_dir::{BatchManifest, MANIFEST_FILE, TaskRecord, TaskState};
use field_ops::scores::SegmentationScores;

pub use table::{Row, SceneRow, Stat, scene_rows};

/// Arguments of `eval gather`.
#[derive(Debug, Clone, clap::Args)]
pub struct GatherArgs {
    /// Batch directory (with `batch.json`), or a directory whose
    /// subdirectories are run directories (one scene each).
    pub dir: PathBuf,
    /// Where `benchmark.csv`, `benchmark_runs.csv`, `benchmark.md` and
    /// `benchmark.png` go [default: DIR].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Where one run stands.
#[derive(Debug, Clone, PartialEq)]
pub enum RunStatus {
    /// Trained and segmented: every figure is there.
    Finished,
    /// Trained; its `segmentation.json` is missing (no `eval segment` step),
    /// so it counts for PSNR only.
    NotSegmented,
    /// Failed, with the error its batch task recorded.
    Failed(String),
    /// Started and not finished (stopped, requeued or still running), with
    /// the newest checkpoint's iteration when it has one.
    Unfinished(Option<usize>),
    /// Its directory does not exist yet.
    NotStarted,
    /// Its files could not be read (the error names the file).
    Unreadable(String),
}

impl RunStatus {
    /// A short description for the tables.
    pub fn describe(&self) -> String {
        match self {
            Self::Finished => "finished".into(),
            Self::NotSegmented => "trained, no segmentation.json (PSNR only)".into(),
            Self::Failed(e) => format!("failed: {e}"),
            Self::Unfinished(Some(i)) => format!("unfinished (checkpoint at iteration {i})"),
            Self::Unfinished(None) => "unfinished (no checkpoint yet)".into(),
            Self::NotStarted => "not started".into(),
            Self::Unreadable(e) => format!("unreadable: {e}"),
        }
    }
}

/// One run and its figures.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// Scene it belongs to.
    pub scene: String,
    /// Its directory name.
    pub run: String,
    /// Its seed, when the batch set one.
    pub seed: Option<u64>,
    /// Where it stands.
    pub status: RunStatus,
    /// Iterations trained (from `summary.json`).
    pub iterations: Option<usize>,
    /// Held-out PSNR on interior pixels (from `summary.json`).
    pub psnr: Option<f64>,
    /// Held-out SSIM on interior pixels (from `summary.json`; runs written
    /// before it was recorded, or that did not render their views, have none).
    pub ssim: Option<f64>,
    /// Segmentation scores (from `segmentation.json`).
    pub scores: Option<SegmentationScores>,
}

/// Runs `eval gather`; returns the files written.
pub fn gather_command(args: &GatherArgs) -> anyhow::Result<Vec<PathBuf>> {
    let runs = collect(&args.dir)?;
    let out = args.out.clone().unwrap_or_else(|| args.dir.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let scenes = scene_rows(&runs);
    let markdown = table::markdown(&scenes, &runs);
    print!("{markdown}");
    let written = [
        (out.join("benchmark.csv"), table::scenes_csv(&scenes)),
        (out.join("benchmark_runs.csv"), table::runs_csv(&runs)),
        (out.join("benchmark.md"), markdown),
    ];
    let mut paths = Vec::new();
    for (path, text) in written {
        field_ops::files::write_atomic(&path, text.as_bytes())?;
        paths.push(path);
    }
    let png = out.join("benchmark.png");
    match chart::draw(&scenes, &png) {
        Ok(true) => paths.push(png),
        Ok(false) => eprintln!("no run is segmented yet: benchmark.png not drawn"),
        // The numbers are in the CSV: a missing font costs the picture only.
        Err(e) => eprintln!("warning: {e}"),
    }
    Ok(paths)
}

/// The runs of `dir`: the batch's list when it has one, else every
/// subdirectory holding a run's `config.json` (its name is its scene).
pub fn collect(dir: &Path) -> anyhow::Result<Vec<RunResult>> {
    if !dir.is_dir() {
        bail!("{}: not a directory", dir.display());
    }
    if dir.join(MANIFEST_FILE).exists() {
        let manifest = BatchManifest::read(dir)?;
        return Ok(manifest
            .tasks
            .iter()
            .map(|t| read_run(&dir.join(&t.run), &t.scene, &t.run, t.seed))
            .collect());
    }
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("config.json").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    if names.is_empty() {
        bail!(
            "{}: no runs here (no {MANIFEST_FILE}, and no subdirectory with a config.json)",
            dir.display()
        );
    }
    Ok(names
        .iter()
        .map(|n| read_run(&dir.join(n), n, n, None))
        .collect())
}

/// One run's status and figures.
fn read_run(path: &Path, scene: &str, run: &str, seed: Option<u64>) -> RunResult {
    let mut result = RunResult {
        scene: scene.to_string(),
        run: run.to_string(),
        seed,
        status: RunStatus::NotStarted,
        iterations: None,
        psnr: None,
        ssim: None,
        scores: None,
    };
    if !path.is_dir() {
        return result;
    }
    let record = match TaskRecord::read(path) {
        Ok(r) => r,
        Err(e) => {
            result.status = RunStatus::Unreadable(e.to_string());
            return result;
        }
    };
    let summary = path.join("summary.json");
    let segmentation = path.join("segmentation.json");
    let failed = record
        .as_ref()
        .filter(|r| r.state == TaskState::Failed)
        .map(|r| {
            r.error
                .clone()
                .unwrap_or_else(|| "no error recorded".into())
        });
    let running = record
        .as_ref()
        .is_some_and(|r| r.state == TaskState::Running);
    result.status = if !summary.exists() {
        match failed {
            Some(e) => RunStatus::Failed(e),
            None => RunStatus::Unfinished(newest_checkpoint(path)),
        }
    } else {
        match read_figures(&summary, &segmentation, &mut result) {
            Err(e) => RunStatus::Unreadable(e),
            // Trained, but its eval steps failed or have not all run.
            Ok(()) if failed.is_some() => RunStatus::Failed(failed.unwrap_or_default()),
            Ok(()) if running => RunStatus::Unfinished(result.iterations),
            Ok(()) if result.scores.is_none() => RunStatus::NotSegmented,
            Ok(()) => RunStatus::Finished,
        }
    };
    result
}

/// Reads PSNR, SSIM and iterations from `summary.json`, and the scores from
/// `segmentation.json` when it exists.
fn read_figures(summary: &Path, segmentation: &Path, out: &mut RunResult) -> Result<(), String> {
    let s: serde_json::Value = field_ops::json::read_json(summary).map_err(|e| e.to_string())?;
    out.iterations = s["iterations"].as_u64().map(|i| i as usize);
    out.psnr = s["heldout_interior"]["psnr"].as_f64();
    out.ssim = s["heldout_interior"]["ssim"].as_f64();
    if out.psnr.is_none() {
        return Err(format!("{}: no heldout_interior.psnr", summary.display()));
    }
    if segmentation.exists() {
        out.scores = Some(field_ops::json::read_json(segmentation).map_err(|e| e.to_string())?);
    }
    Ok(())
}

/// The iteration of the newest checkpoint file of run `path`.
fn newest_checkpoint(path: &Path) -> Option<usize> {
    std::fs::read_dir(path.join("checkpoints"))
        .ok()?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.strip_prefix("ckpt-")?
                .strip_suffix(".onck")?
                .parse::<usize>()
                .ok()
        })
        .max()
}
