//! `eval uncertainty`: the uncertainty map of a run's training feature maps,
//! its correlation with the error of the fused features, a scatter plot and
//! a point cloud coloured by uncertainty. The flags and the run are checked
//! here, the map is measured in `measure` and written in `outputs`.

mod measure;
mod outputs;

use std::path::{Path, PathBuf};

use datasets::Scene;
use datasets::points::IGNORE_LABEL;
use field_ops::OpsError;
use field_ops::json::read_json;
use field_ops::run_dir::{RunDir, Split};
use field_ops::uncertainty::UncertaintyMap;
use field_ops::uncertainty::coarse::coarse_points;
use model::geometry::Vec3;
use serde::Serialize;

use super::proposals::ProposalRequest;
use crate::segment::EvalPoints;
use crate::similarity::ClassScorer;

/// Arguments of `uncertainty`.
#[derive(Debug, Clone, clap::Args)]
pub struct UncertaintyArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// Principal directions of the feature space the covariances are kept in.
    #[arg(long, default_value_t = 16)]
    pub k: usize,
    /// Added to the covariance's diagonal before its log-determinant.
    #[arg(long, default_value_t = 1e-6, allow_negative_numbers = true)]
    pub eps: f64,
    /// Pseudo-observations of the pooled covariance each point's covariance
    /// is shrunk towards (0: the plain sample covariance, which is
    /// rank-deficient for points seen by fewer than k+1 views).
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    pub prior_weight: f64,
    /// Uncertainty of each point's mean feature (covariance / views) instead
    /// of a single view's.
    #[arg(long)]
    pub of_mean: bool,
    /// How the uncertainty becomes each point's chance to be a proposed
    /// camera's target: `minmax-logdet` (log-determinant rescaled to
    /// [0, 1]), `det-over-max` (generalized variance over its largest
    /// value, the paper's draw) or `rank:T` (rank quantile to the power 1/T:
    /// about T/(1+T) of the points become candidates). Every normalisation's
    /// draw is reported in `uncertainty.json` (`target_draws`) either way.
    #[arg(long, default_value_t = field_ops::novel::NovelViewConfig::default().normalisation)]
    pub normalisation: field_ops::uncertainty::Normalisation,
    /// Voxel size (metres) the point cloud is thinned to (0 keeps every point).
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub voxel: f64,
    /// Most memory (GiB) the per-point statistics may take: each point of
    /// the thinned cloud keeps k + k^2 f64 of covariance and about 12 bytes
    /// per feature channel. A --k or --voxel that needs more is refused
    /// (with what it would need) instead of exhausting the machine's memory.
    #[arg(long, default_value_t = 4.0, allow_negative_numbers = true)]
    pub max_memory: f64,
    /// Novel cameras to propose at uncertain points (0: none). Needs the
    /// run's weights, to keep cameras out of matter and their targets in view.
    #[arg(long, default_value_t = 8)]
    pub views: usize,
    /// Seed of the target draw and the position noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output directory [default: `uncertainty/` in the run directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Compute backend and device (of the proposals' field checks and previews).
    #[command(flatten)]
    pub compute: field_ops::backend::BackendArgs,
    /// Frame of the written points.
    #[command(flatten)]
    pub frame: field_ops::frame::FrameArgs,
}

/// What `uncertainty.json` records.
#[derive(Debug, Clone, Serialize)]
pub struct UncertaintySummary {
    /// Points of the (thinned) cloud.
    pub points: usize,
    /// Points seen by at least one training view.
    pub seen: usize,
    /// Points seen at least twice (with a covariance).
    pub seen_twice: usize,
    /// Subspace dimension and diagonal regulariser.
    pub k: usize,
    /// Diagonal regulariser.
    pub eps: f64,
    /// Smallest, median and largest `log det` over the points seen twice.
    pub log_det_min: f64,
    /// Median `log det`.
    pub log_det_median: f64,
    /// Largest `log det`.
    pub log_det_max: f64,
    /// Pearson r of `log det` and the feature error over labelled points
    /// seen twice (`None` without labels and class embeddings).
    pub pearson_r: Option<f64>,
    /// Points the correlation is computed on.
    pub correlated_points: usize,
    /// Points seen twice whose covariance could not be factorised: they are
    /// given the largest `log det` (a larger `--eps` avoids this).
    pub failed_factorisations: usize,
    /// The normalisation of `--normalisation`.
    pub normalisation: String,
    /// Where 24 targets land under each normalisation (same map, same seed).
    pub target_draws: Vec<super::targets::TargetDraw>,
}

/// The coarse cloud of the uncertainty map (see
/// [`field_ops::uncertainty::coarse::coarse_points`]) and, when it is the
/// scene's labelled cloud with class embeddings, its labels.
fn labelled_coarse_points(
    scene: &Scene,
    train: &[usize],
    voxel: f64,
) -> Result<(Vec<Vec3>, Option<EvalPoints>), OpsError> {
    let cloud = coarse_points(scene, train, voxel)?;
    let labelled = match (&cloud.scene_indices, &scene.classes) {
        (Some(keep), Some(_)) => {
            let mut e = EvalPoints::from_scene(scene)?;
            e.positions = keep.iter().map(|&i| e.positions[i]).collect();
            e.labels = keep.iter().map(|&i| e.labels[i]).collect();
            Some(e)
        }
        _ => None,
    };
    Ok((cloud.positions, labelled))
}

/// Refuses flag values that cannot give a map, before any file is read.
fn check_flags(args: &UncertaintyArgs) -> Result<(), OpsError> {
    if args.k == 0 {
        return Err(OpsError::Invalid("--k must be at least 1".into()));
    }
    if !(args.eps.is_finite() && args.eps > 0.0) {
        return Err(OpsError::Invalid(format!(
            "--eps must be positive and finite, got {}",
            args.eps
        )));
    }
    if !(args.prior_weight.is_finite() && args.prior_weight >= 0.0) {
        return Err(OpsError::Invalid(format!(
            "--prior-weight must be a non-negative number of pseudo-observations, got {}",
            args.prior_weight
        )));
    }
    if !(args.voxel.is_finite() && args.voxel >= 0.0) {
        return Err(OpsError::Invalid(format!(
            "--voxel must be a size in metres (0 keeps every point), got {}",
            args.voxel
        )));
    }
    if !(args.max_memory.is_finite() && args.max_memory > 0.0) {
        return Err(OpsError::Invalid(format!(
            "--max-memory must be a positive number of GiB, got {}",
            args.max_memory
        )));
    }
    args.compute.check().map_err(OpsError::Invalid)
}

/// Runs `eval uncertainty` and returns the files written.
pub fn uncertainty_command(args: &UncertaintyArgs) -> Result<Vec<PathBuf>, OpsError> {
    check_flags(args)?;
    let run = TrainedScene::open(&args.run)?;
    let frame = args.frame.resolve(&run.meta)?;
    let (points, labelled) = labelled_coarse_points(&run.scene, &run.split.train, args.voxel)?;
    check_memory(args, &run.scene, points.len())?;
    let measured = measure::measure(args, &run, &points, labelled.as_ref())?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| run.dir.dir.join("uncertainty"));
    let mut written = outputs::write_outputs(&out, &measured, &frame.points(&points))?;
    print_summary(&measured.summary, args.eps);
    if args.views > 0 {
        written.extend(super::proposals::write_proposals(
            ProposalRequest {
                views: args.views,
                seed: args.seed,
                compute: args.compute,
            },
            &run.dir,
            &run.scene,
            &run.split,
            &points,
            &measured.map,
            &out,
        )?);
    }
    print_correlation(&measured.summary);
    Ok(written)
}

/// A run's scene with its split, which has training views.
struct TrainedScene {
    dir: RunDir,
    meta: datasets::SceneMeta,
    split: Split,
    scene: Scene,
}

impl TrainedScene {
    /// Loads the scene of the run in `run`, refusing one without training
    /// frames.
    fn open(run: &Path) -> Result<TrainedScene, OpsError> {
        let dir = RunDir::new(run);
        let meta: datasets::SceneMeta = read_json(&dir.scene())?;
        let mut split: Split = read_json(&dir.split())?;
        let scene = field_ops::run_dir::load_run_scene(&dir, &meta, &mut split)?;
        // Without training views every point is unseen: nothing to measure,
        // and no camera to take novel cameras' intrinsics from.
        if split.train.is_empty() {
            return Err(OpsError::Invalid(format!(
                "{}: the run has no training frames; the uncertainty map is made of the \
                 training views' feature maps",
                dir.split().display()
            )));
        }
        Ok(TrainedScene {
            dir,
            meta,
            split,
            scene,
        })
    }
}

/// The uncertainty map of `points` and what is measured on it.
struct Measured {
    map: UncertaintyMap,
    /// The feature error of each point, with labels and class embeddings.
    errors: Option<Vec<f64>>,
    summary: UncertaintySummary,
}

/// Prints the map's figures, where targets land under each normalisation,
/// and a warning when covariances could not be factorised (which names
/// `eps`, the `--eps` in use).
fn print_summary(summary: &UncertaintySummary, eps: f64) {
    println!(
        "{} points, {} seen by a training view, {} seen twice; log det (k = {}) from {:.1} to {:.1}, median {:.1}",
        summary.points,
        summary.seen,
        summary.seen_twice,
        summary.k,
        summary.log_det_min,
        summary.log_det_max,
        summary.log_det_median
    );
    println!(
        "where {} targets land, by normalisation:",
        super::targets::REPORT_TARGETS
    );
    for line in super::targets::describe(&summary.target_draws) {
        println!("  {line}");
    }
    if summary.failed_factorisations > 0 {
        eprintln!(
            "warning: the covariance of {} of the {} points seen twice could not be factorised \
             (Cholesky failed); they are given the largest uncertainty. A larger --eps (now {}) \
             avoids this",
            summary.failed_factorisations, summary.seen_twice, eps
        );
    }
}

/// Prints the correlation of uncertainty and feature error, or why there
/// is none.
fn print_correlation(summary: &UncertaintySummary) {
    match summary.pearson_r {
        Some(r) => println!(
            "Pearson r between uncertainty and feature error: {r:.3} over {} labelled points seen twice",
            summary.correlated_points
        ),
        None => {
            println!("no labelled points with class embeddings: the error correlation is skipped")
        }
    }
}

/// Refuses a map whose per-point statistics would take more than
/// `--max-memory` (see [`field_ops::uncertainty::memory_needed`]).
fn check_memory(args: &UncertaintyArgs, scene: &Scene, points: usize) -> Result<(), OpsError> {
    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let needed = field_ops::uncertainty::memory_needed(points, args.k, dim);
    let gib = |b: f64| b / (1u64 << 30) as f64;
    if gib(needed as f64) > args.max_memory {
        return Err(OpsError::Invalid(format!(
            "--k {} and --voxel {} would need {:.2} GiB for the statistics of {points} points \
             ({dim} feature channels), more than --max-memory {} GiB: use a smaller --k, a \
             larger --voxel, or raise --max-memory if the machine has the memory",
            args.k,
            args.voxel,
            gib(needed as f64),
            args.max_memory
        )));
    }
    Ok(())
}

/// `1 - cos(mean feature, class embedding of the point's label)` per point;
/// NaN where the point is unlabelled or unseen.
pub fn feature_errors(
    map: &UncertaintyMap,
    points: &EvalPoints,
    pca: Option<&datasets::features::PcaBasis>,
) -> Result<Vec<f64>, OpsError> {
    let scorer = ClassScorer::new(&points.embeddings, points.dim, pca)?;
    let mut cos = vec![0.0; scorer.classes];
    Ok(map
        .mean_features
        .iter()
        .zip(&points.labels)
        .map(|(m, &l)| match m {
            Some(f) if l != IGNORE_LABEL && (l as usize) < scorer.classes => {
                scorer.cosines(f, &mut cos);
                1.0 - cos[l as usize]
            }
            _ => f64::NAN,
        })
        .collect())
}
