//! `eval uncertainty`: the uncertainty map of a run's training feature maps,
//! its correlation with the error of the fused features, a scatter plot and
//! a point cloud coloured by uncertainty.

use std::io::Write;
use std::path::{Path, PathBuf};

use datasets::Scene;
use datasets::points::{PointCloud, write_ply};
use model::geometry::Vec3;
use serde::Serialize;

use field_ops::colormap::{to_u8, turbo};
use field_ops::uncertainty::coarse::coarse_points;

use super::proposals::ProposalRequest;
use crate::segment::EvalPoints;
use crate::similarity::ClassScorer;
use datasets::points::IGNORE_LABEL;
use field_ops::OpsError;
use field_ops::json::{read_json, write_json};
use field_ops::project::ProjectOptions;
use field_ops::run_dir::{RunDir, Split};
use field_ops::uncertainty::scatter::scatter;
use field_ops::uncertainty::{UncertaintyMap, UncertaintyOptions, pearson, uncertainty_map};

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
    let dir = RunDir::new(&args.run);
    let meta: datasets::SceneMeta = read_json(&dir.scene())?;
    let mut split: Split = read_json(&dir.split())?;
    let scene = field_ops::run_dir::load_run_scene(&dir, &meta, &mut split)?;
    // Without training views every point is unseen: nothing to measure, and
    // no camera to take novel cameras' intrinsics from.
    if split.train.is_empty() {
        return Err(OpsError::Invalid(format!(
            "{}: the run has no training frames; the uncertainty map is made of the training \
             views' feature maps",
            dir.split().display()
        )));
    }
    let frame = args.frame.resolve(&meta)?;
    let (points, labelled) = labelled_coarse_points(&scene, &split.train, args.voxel)?;
    check_memory(args, &scene, points.len())?;
    let opts = UncertaintyOptions {
        k: args.k,
        eps: args.eps,
        prior_weight: args.prior_weight,
        of_mean: args.of_mean,
        normalisation: args.normalisation,
        project: ProjectOptions::default(),
    };
    let bar = field_ops::progress::progress(split.train.len(), "projecting feature maps");
    let map = uncertainty_map(&scene, &split.train, &points, &opts, |d, _| {
        bar.set_position(d as u64)
    })?;
    bar.finish_and_clear();
    let errors = match (&labelled, scene.features.as_ref()) {
        (Some(l), Some(set)) => Some(feature_errors(&map, l, set.pca.as_ref())?),
        _ => None,
    };
    let mut summary = summarise(&map, errors.as_deref(), &opts);
    summary.target_draws = super::targets::draws_by_normalisation(
        &map,
        &points,
        labelled.as_ref(),
        args.normalisation,
        args.seed,
    );
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| dir.dir.join("uncertainty"));
    std::fs::create_dir_all(&out).map_err(|e| OpsError::io(&out, e))?;
    let mut written = Vec::new();
    let json = out.join("uncertainty.json");
    write_json(&json, &summary)?;
    written.push(json);
    let csv = out.join("uncertainty.csv");
    let written_points = frame.points(&points);
    write_csv(&csv, &written_points, &map, errors.as_deref())?;
    written.push(csv);
    let ply = out.join("uncertainty.ply");
    write_uncertainty_ply(&ply, &written_points, &map)?;
    written.push(ply);
    if let Some(e) = &errors {
        let png = out.join("uncertainty_scatter.png");
        // The numbers are in the CSV: a missing font costs the picture only.
        match scatter(&png, &map, e, summary.pearson_r) {
            Ok(()) => written.push(png),
            Err(e) => eprintln!("warning: {e}"),
        }
    }
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
            summary.failed_factorisations, summary.seen_twice, args.eps
        );
    }
    if args.views > 0 {
        written.extend(super::proposals::write_proposals(
            ProposalRequest {
                views: args.views,
                seed: args.seed,
                compute: args.compute,
            },
            &dir,
            &scene,
            &split,
            &points,
            &map,
            &out,
        )?);
    }
    match summary.pearson_r {
        Some(r) => println!(
            "Pearson r between uncertainty and feature error: {r:.3} over {} labelled points seen twice",
            summary.correlated_points
        ),
        None => {
            println!("no labelled points with class embeddings: the error correlation is skipped")
        }
    }
    Ok(written)
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

fn summarise(
    map: &UncertaintyMap,
    errors: Option<&[f64]>,
    opts: &UncertaintyOptions,
) -> UncertaintySummary {
    let twice: Vec<usize> = (0..map.counts.len())
        .filter(|&i| map.counts[i] >= 2)
        .collect();
    let mut lds: Vec<f64> = twice.iter().map(|&i| map.log_det[i]).collect();
    lds.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        if lds.is_empty() {
            f64::NAN
        } else {
            lds[((lds.len() - 1) as f64 * q).round() as usize]
        }
    };
    let (xs, ys): (Vec<f64>, Vec<f64>) = match errors {
        Some(e) => twice
            .iter()
            .filter(|&&i| e[i].is_finite())
            .map(|&i| (map.log_det[i], e[i]))
            .unzip(),
        None => (Vec::new(), Vec::new()),
    };
    UncertaintySummary {
        points: map.counts.len(),
        seen: map.counts.iter().filter(|&&c| c > 0).count(),
        seen_twice: twice.len(),
        k: map.k,
        eps: opts.eps,
        log_det_min: pick(0.0),
        log_det_median: pick(0.5),
        log_det_max: pick(1.0),
        pearson_r: errors.and_then(|_| pearson(&xs, &ys)),
        correlated_points: xs.len(),
        failed_factorisations: map.failed_factorisations,
        normalisation: opts.normalisation.to_string(),
        target_draws: Vec::new(),
    }
}

fn write_csv(
    path: &Path,
    points: &[Vec3],
    map: &UncertaintyMap,
    errors: Option<&[f64]>,
) -> Result<(), OpsError> {
    let io = |e| OpsError::io(path, e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    writeln!(w, "x,y,z,views,log_det,uncertainty,feature_error").map_err(io)?;
    for (i, p) in points.iter().enumerate() {
        let e = errors.map_or(f64::NAN, |e| e[i]);
        writeln!(
            w,
            "{:.4},{:.4},{:.4},{},{:.5},{:.5},{}",
            p[0],
            p[1],
            p[2],
            map.counts[i],
            map.log_det[i],
            map.normalised[i],
            if e.is_finite() {
                format!("{e:.5}")
            } else {
                String::new()
            }
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)
}

fn write_uncertainty_ply(
    path: &Path,
    points: &[Vec3],
    map: &UncertaintyMap,
) -> Result<(), OpsError> {
    let colors = map
        .normalised
        .iter()
        .map(|&u| turbo(u as f32).map(to_u8))
        .collect();
    let cloud = PointCloud {
        positions: points.to_vec(),
        colors: Some(colors),
        labels: None,
    };
    let u: Vec<f32> = map.normalised.iter().map(|&u| u as f32).collect();
    let views: Vec<f32> = map.counts.iter().map(|&c| c as f32).collect();
    write_ply(path, &cloud, &[("uncertainty", &u), ("views", &views)]).map_err(OpsError::from)
}
