//! The measurement of `eval uncertainty`: the uncertainty map of the
//! training views' feature maps, each labelled point's feature error, and
//! the summary `uncertainty.json` records.

use field_ops::OpsError;
use field_ops::project::ProjectOptions;
use field_ops::uncertainty::{UncertaintyMap, UncertaintyOptions, pearson, uncertainty_map};
use model::geometry::Vec3;

use super::{Measured, TrainedScene, UncertaintyArgs, UncertaintySummary, feature_errors};
use crate::commands::targets;
use crate::segment::EvalPoints;

/// Projects the training views' feature maps onto `points` (with a
/// progress bar), then measures the map: its summary, the feature errors
/// of the `labelled` points and where targets land.
pub(super) fn measure(
    args: &UncertaintyArgs,
    run: &TrainedScene,
    points: &[Vec3],
    labelled: Option<&EvalPoints>,
) -> Result<Measured, OpsError> {
    let (scene, train) = (&run.scene, &run.split.train);
    let opts = UncertaintyOptions {
        k: args.k,
        eps: args.eps,
        prior_weight: args.prior_weight,
        of_mean: args.of_mean,
        normalisation: args.normalisation,
        project: ProjectOptions::default(),
    };
    let bar = field_ops::progress::progress(train.len(), "projecting feature maps");
    let map = uncertainty_map(scene, train, points, &opts, |d, _| {
        bar.set_position(d as u64)
    })?;
    bar.finish_and_clear();
    let errors = match (labelled, scene.features.as_ref()) {
        (Some(l), Some(set)) => Some(feature_errors(&map, l, set.pca.as_ref())?),
        _ => None,
    };
    let mut summary = summarise(&map, errors.as_deref(), &opts);
    summary.target_draws =
        targets::draws_by_normalisation(&map, points, labelled, args.normalisation, args.seed);
    Ok(Measured {
        map,
        errors,
        summary,
    })
}

/// The summary of `uncertainty.json` (without the target draws): counts,
/// the spread of `log det` over the points seen twice and its correlation
/// with the feature `errors`.
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
