//! Where guided targets land under each normalisation of the uncertainty:
//! the same map and the same seeded draw, one row per normalisation, with the
//! share of candidates and the true classes of the targets drawn.

use std::collections::BTreeMap;

use model::geometry::Vec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::segment::EvalPoints;
use datasets::points::IGNORE_LABEL;
use field_ops::novel::guided::select_targets;
use field_ops::uncertainty::normalise::seen_chances;
use field_ops::uncertainty::{Normalisation, UncertaintyMap};

/// Targets drawn to describe a normalisation (the novel-view ablation adds
/// 24 views).
pub const REPORT_TARGETS: usize = 24;

/// One normalisation's draw.
#[derive(Debug, Clone, Serialize)]
pub struct TargetDraw {
    /// The normalisation (`minmax-logdet`, `det-over-max`, `rank:T`).
    pub normalisation: String,
    /// Expected share of the seen points that become candidates (the mean
    /// chance over the points a training view saw).
    pub candidate_share: f64,
    /// Targets drawn (at most [`REPORT_TARGETS`], 0.5 m apart).
    pub targets: usize,
    /// True class of each target, counted (labelled clouds only; `unlabelled`
    /// for a target without a label).
    pub classes: BTreeMap<String, usize>,
}

/// The draw of every normalisation in [`Normalisation::catalogue`] (and
/// `chosen` when it is not among them) over `map`, with the seed `seed`.
pub fn draws_by_normalisation(
    map: &UncertaintyMap,
    points: &[Vec3],
    labelled: Option<&EvalPoints>,
    chosen: Normalisation,
    seed: u64,
) -> Vec<TargetDraw> {
    let mut all = Normalisation::catalogue();
    if !all.contains(&chosen) {
        all.push(chosen);
    }
    let values: Vec<Option<f64>> = map.log_det.iter().map(|&v| Some(v)).collect();
    let seen = map.counts.iter().filter(|&&c| c > 0).count().max(1);
    all.into_iter()
        .map(|how| {
            let mut chances = seen_chances(&values, &map.counts, how);
            chances
                .iter_mut()
                .zip(&map.counts)
                .filter(|(_, n)| **n == 0)
                .for_each(|(c, _)| *c = 0.0);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let picked = select_targets(&chances, points, REPORT_TARGETS, 0.5, &mut rng);
            let mut classes = BTreeMap::new();
            for &i in &picked {
                let name = labelled
                    .and_then(|l| {
                        let c = *l.labels.get(i)?;
                        (c != IGNORE_LABEL).then(|| l.names.get(c as usize).cloned())?
                    })
                    .unwrap_or_else(|| "unlabelled".into());
                *classes.entry(name).or_insert(0) += 1;
            }
            TargetDraw {
                normalisation: how.to_string(),
                candidate_share: chances.iter().sum::<f64>() / seen as f64,
                targets: picked.len(),
                classes,
            }
        })
        .collect()
}

/// One line per draw: `rank:0.25: 9% candidates; wall 10, floor 6, ...`.
pub fn describe(draws: &[TargetDraw]) -> Vec<String> {
    draws
        .iter()
        .map(|d| {
            let mut by_count: Vec<(&String, &usize)> = d.classes.iter().collect();
            by_count.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
            let classes: Vec<String> = by_count.iter().map(|(k, v)| format!("{k} {v}")).collect();
            format!(
                "{}: {:.1}% of the seen points candidates, {} targets: {}",
                d.normalisation,
                100.0 * d.candidate_share,
                d.targets,
                classes.join(", ")
            )
        })
        .collect()
}
