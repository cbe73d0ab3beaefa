//! Where the 2D feature maps disagree: per-point uncertainty of the
//! projected training features (the selection signal for novel views).
//!
//! Every training feature map is projected onto a coarse point cloud (with
//! the occlusion test and the border margin of [`crate::project`]). Per
//! point, Welford's single-pass update keeps the mean and covariance of the
//! observed features in the scene's top-`k` principal subspace, and the
//! uncertainty is `u = log det(Sigma + eps I)`. Points seen once get the
//! prior's covariance (below); points never seen get the largest uncertainty
//! observed, and so do points whose covariance cannot be factorised (non-finite, or not positive definite after
//! rounding with a tiny `eps`); those are counted in
//! [`UncertaintyMap::failed_factorisations`] so that callers report them
//! rather than pass them off as measured.
//!
//! `Sigma` is shrunk towards the covariance pooled over all points, worth
//! `prior_weight` observations (16 by default). The plain sample covariance
//! of a point seen by `n <= k` views has rank `n - 1`: its log-determinant is
//! then mostly `(k - n + 1) ln eps` and measures the number of views, not
//! their disagreement. On the bench room (seed 21) that made the uncertainty
//! *anti*-correlated with the feature error (Pearson r = -0.39, views vs log
//! det r = 0.77); shrunk with 4 / 16 / 64 pseudo-observations, r = 0.40 /
//! 0.46 / 0.41.

pub mod coarse;
pub mod normalise;
pub mod scatter;
pub mod welford;

use datasets::Scene;
use datasets::features::{FeatureSet, PcaBasis, PcaSetting};
use model::geometry::Vec3;

use crate::error::OpsError;
use crate::project::{DepthRef, ProjectOptions, visible_pixel};
pub use normalise::Normalisation;
use welford::{Welford, log_det_regularised, pooled_covariance};

/// Settings of the uncertainty map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UncertaintyOptions {
    /// Principal directions the covariance is kept in.
    pub k: usize,
    /// Added to the covariance's diagonal before the log-determinant.
    pub eps: f64,
    /// Pseudo-observations of the pooled covariance every point's covariance
    /// is shrunk towards (0: the plain sample covariance), see
    /// [`Welford::shrunk_covariance`].
    pub prior_weight: f64,
    /// Measure the uncertainty of each point's *mean* feature (covariance
    /// divided by the number of views) rather than of a single view's.
    pub of_mean: bool,
    /// How the log-determinants become target chances
    /// ([`UncertaintyMap::normalised`]).
    pub normalisation: Normalisation,
    /// Visibility rules of the projection.
    pub project: ProjectOptions,
}

impl Default for UncertaintyOptions {
    fn default() -> Self {
        Self {
            k: 16,
            eps: 1e-6,
            prior_weight: 16.0,
            of_mean: false,
            normalisation: Normalisation::default(),
            project: ProjectOptions::default(),
        }
    }
}

/// The uncertainty of every point, and what it was computed from.
#[derive(Debug, Clone, PartialEq)]
pub struct UncertaintyMap {
    /// Observations per point.
    pub counts: Vec<u64>,
    /// `log det(Sigma + eps I)` per point; points never seen (or seen once
    /// without a prior) hold the largest value of the others.
    pub log_det: Vec<f64>,
    /// `log_det` as chances in `[0, 1]` (see
    /// [`UncertaintyOptions::normalisation`]).
    pub normalised: Vec<f64>,
    /// Per point, the mean observed feature in the maps' own space (PCA
    /// coefficients or full vectors), `None` where no view saw the point.
    pub mean_features: Vec<Option<Vec<f32>>>,
    /// Per point, the mean centre of the cameras that saw it (`None` where
    /// none did): the free side a new camera can look from.
    pub mean_view_centres: Vec<Option<Vec3>>,
    /// Per point, the mean colour the training frames saw it with (`None`
    /// where none did): what a faithful render of the point shows.
    pub mean_colors: Vec<Option<[f32; 3]>>,
    /// Dimension of the subspace the covariances live in.
    pub k: usize,
    /// Points seen at least twice whose `log det` could not be computed
    /// (the Cholesky factorisation failed): they hold the largest value.
    pub failed_factorisations: usize,
}

/// The subspace the covariances are kept in: the maps' own leading PCA
/// coefficients when they are compressed (components come by decreasing
/// variance), else a basis fitted to a sample of the maps.
enum Subspace {
    Leading(usize),
    Fitted(PcaBasis),
}

impl Subspace {
    fn of(set: &FeatureSet, k: usize) -> Result<Self, OpsError> {
        let dim = set.dim();
        if set.pca.is_some() || dim <= k {
            return Ok(Self::Leading(k.min(dim)));
        }
        // An even sample of target pixels over the maps.
        let mut samples = Vec::new();
        let per = (20_000 / set.maps.len().max(1)).max(1);
        for map in &set.maps {
            let pixels = (map.width * map.height) as usize;
            let step = (pixels / per).max(1);
            for i in (0..pixels).step_by(step) {
                let v = &map.data[i * dim..(i + 1) * dim];
                if set.is_target(v) {
                    samples.extend(v.iter().map(|x| x.to_f32()));
                }
            }
        }
        let pca = PcaBasis::fit(&samples, dim, PcaSetting::Components(k))
            .map_err(|e| OpsError::Invalid(format!("fitting the uncertainty subspace: {e}")))?;
        Ok(Self::Fitted(pca))
    }

    fn dim(&self) -> usize {
        match self {
            Self::Leading(k) => *k,
            Self::Fitted(p) => p.k,
        }
    }

    fn coefficients(&self, f: &[f32]) -> Vec<f32> {
        match self {
            Self::Leading(k) => f[..*k].to_vec(),
            Self::Fitted(p) => p.project(f),
        }
    }
}

/// Bytes the uncertainty map of `points` points holds per point while it is
/// computed, for features of `dim` channels and a `k`-dimensional subspace
/// (at most `dim`): the Welford mean and scatter (`k + k^2` f64), the
/// feature sum (`dim` f64) and mean (`dim` f32), camera centre and colour
/// sums, and the outputs. Saturates rather than overflows.
pub fn memory_needed(points: usize, k: usize, dim: usize) -> u64 {
    let k = k.min(dim) as u64;
    let per_point = 8 * (k + k * k) + 12 * dim as u64 + 160;
    per_point.saturating_mul(points as u64)
}

/// Projects the feature maps of `frames` onto `points` and computes the
/// uncertainty of every point. `progress(done, total)` is called per frame.
///
/// Frames without depth are projected without an occlusion test.
pub fn uncertainty_map(
    scene: &Scene,
    frames: &[usize],
    points: &[Vec3],
    opts: &UncertaintyOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<UncertaintyMap, OpsError> {
    let set = scene.features.as_ref().ok_or_else(|| {
        OpsError::Invalid(format!(
            "scene {} has no feature maps to measure uncertainty on",
            scene.name
        ))
    })?;
    if opts.k == 0
        || !(opts.eps.is_finite() && opts.eps > 0.0)
        || !(opts.prior_weight.is_finite() && opts.prior_weight >= 0.0)
    {
        return Err(OpsError::Invalid(format!(
            "the subspace size must be at least 1, eps positive and the prior weight non-negative, got k = {}, eps = {}, prior weight = {}",
            opts.k, opts.eps, opts.prior_weight
        )));
    }
    let dim = set.dim();
    let sub = Subspace::of(set, opts.k)?;
    let k = sub.dim();
    let mut stats: Vec<Welford> = (0..points.len()).map(|_| Welford::new(k)).collect();
    let mut sums = vec![0f64; points.len() * dim];
    let mut centres = vec![[0f64; 3]; points.len()];
    let mut colors = vec![([0f64; 3], 0u64); points.len()];
    let mut feature = vec![0f32; dim];
    for (n, &fi) in frames.iter().enumerate() {
        let frame = scene.frames.get(fi).ok_or_else(|| {
            OpsError::Invalid(format!("frame {fi} is not in scene {}", scene.name))
        })?;
        let intr = &frame.camera.intrinsics;
        let centre = frame.camera.pose.center();
        let rgb = &frame.rgb;
        let has_rgb =
            rgb.width > 0 && rgb.height > 0 && rgb.len() >= 3 * (rgb.width * rgb.height) as usize;
        let depth_values = frame.depth.as_ref().map(|d| d.to_f32());
        let depth = frame
            .depth
            .as_ref()
            .zip(depth_values.as_deref())
            .map(|(d, data)| DepthRef {
                width: d.width,
                height: d.height,
                data,
            });
        for (i, &p) in points.iter().enumerate() {
            let Some(hit) = visible_pixel(&frame.camera, p, depth, &opts.project) else {
                continue;
            };
            let Some(f) = set.target(fi, hit.u, hit.v, intr.width, intr.height) else {
                continue;
            };
            feature.iter_mut().zip(f).for_each(|(o, x)| *o = x.to_f32());
            stats[i].push(&sub.coefficients(&feature));
            (0..3).for_each(|a| centres[i][a] += centre[a]);
            if has_rgb {
                let c = rgb.lookup(hit.u, hit.v, intr.width, intr.height);
                (0..3).for_each(|a| colors[i].0[a] += c[a] as f64);
                colors[i].1 += 1;
            }
            sums[i * dim..(i + 1) * dim]
                .iter_mut()
                .zip(&feature)
                .for_each(|(s, &x)| *s += x as f64);
        }
        progress(n + 1, frames.len());
    }
    let (log_det, normalised, failed_factorisations) = log_dets(&stats, k, opts);
    let counts: Vec<u64> = stats.iter().map(|w| w.count).collect();
    let mean_features = counts
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            (c > 0).then(|| {
                sums[i * dim..(i + 1) * dim]
                    .iter()
                    .map(|&s| (s / c as f64) as f32)
                    .collect()
            })
        })
        .collect();
    let mean_view_centres = counts
        .iter()
        .zip(&centres)
        .map(|(&c, s)| (c > 0).then(|| s.map(|v| v / c as f64)))
        .collect();
    let mean_colors = colors
        .iter()
        .map(|&(s, c)| (c > 0).then(|| s.map(|v| (v / c as f64) as f32)))
        .collect();
    Ok(UncertaintyMap {
        mean_view_centres,
        mean_colors,
        counts,
        log_det,
        normalised,
        mean_features,
        k,
        failed_factorisations,
    })
}

/// Each point's `log det(Sigma + eps I)` of its shrunk covariance (points
/// seen once get the prior's; points never seen, or whose factorisation
/// fails, get the largest value), the same as target chances (see
/// [`Normalisation`]), and how many points seen at least once failed.
fn log_dets(stats: &[Welford], k: usize, opts: &UncertaintyOptions) -> (Vec<f64>, Vec<f64>, usize) {
    let pooled = pooled_covariance(stats, k).unwrap_or_else(|| vec![0.0; k * k]);
    let raw: Vec<Option<f64>> = stats
        .iter()
        .map(|w| {
            let mut c = w.shrunk_covariance(&pooled, opts.prior_weight)?;
            if opts.of_mean {
                c.iter_mut().for_each(|v| *v /= w.count as f64);
            }
            log_det_regularised(&c, k, opts.eps)
        })
        .collect();
    let max = raw
        .iter()
        .flatten()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let failed = raw
        .iter()
        .zip(stats)
        .filter(|(u, w)| u.is_none() && (w.count >= 2 || (w.count == 1 && opts.prior_weight > 0.0)))
        .count();
    // With no point measured there is nothing to compare: all maximal.
    let max = if max.is_finite() { max } else { 0.0 };
    let log_det: Vec<f64> = raw.iter().map(|u| u.unwrap_or(max)).collect();
    let counts: Vec<u64> = stats.iter().map(|w| w.count).collect();
    let normalised = normalise::seen_chances(&raw, &counts, opts.normalisation);
    (log_det, normalised, failed)
}

/// Points on a grid of `voxel` metres: the first point of every occupied
/// cell is kept. Returns the indices of the kept points, in input order.
pub fn voxel_downsample(points: &[Vec3], voxel: f64) -> Vec<usize> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return (0..points.len()).collect();
    }
    let mut seen = std::collections::HashSet::new();
    points
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            let cell = p.map(|x| (x / voxel).floor() as i64);
            seen.insert(cell)
        })
        .map(|(i, _)| i)
        .collect()
}

/// Pearson's correlation of `x` and `y`, in f64; `None` with fewer than two
/// pairs or a constant series.
pub fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len().min(y.len());
    if n < 2 {
        return None;
    }
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x[..n].iter().zip(&y[..n]) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pearson_of_exact_lines_and_of_independent_series() {
        let x: Vec<f64> = (0..50).map(|i| i as f64).collect();
        let up: Vec<f64> = x.iter().map(|v| 3.0 * v - 2.0).collect();
        let down: Vec<f64> = x.iter().map(|v| -0.5 * v).collect();
        assert!((pearson(&x, &up).expect("r") - 1.0).abs() < 1e-12);
        assert!((pearson(&x, &down).expect("r") + 1.0).abs() < 1e-12);
        // A symmetric parabola is uncorrelated with its centred argument.
        let c: Vec<f64> = (-25..=25).map(|i| i as f64).collect();
        let sq: Vec<f64> = c.iter().map(|v| v * v).collect();
        assert!(pearson(&c, &sq).expect("r").abs() < 1e-12);
        assert!(pearson(&x, &vec![1.0; 50]).is_none());
        assert!(pearson(&[1.0], &[2.0]).is_none());
    }

    #[test]
    fn a_point_seen_once_gets_the_log_det_of_the_prior() {
        let mut stats = Vec::new();
        for xs in [
            [[0.0f32, 1.0], [1.0, 0.5], [0.2, 0.3]],
            [[0.4, 0.0], [0.1, 0.9], [0.7, 0.7]],
        ] {
            let mut w = Welford::new(2);
            xs.iter().for_each(|x| w.push(x));
            stats.push(w);
        }
        let mut once = Welford::new(2);
        once.push(&[0.5, 0.5]);
        stats.push(once);
        stats.push(Welford::new(2));
        let opts = UncertaintyOptions::default();
        let (log_det, normalised, failed) = log_dets(&stats, 2, &opts);
        let pooled = pooled_covariance(&stats, 2).expect("pooled");
        let prior = log_det_regularised(&pooled, 2, opts.eps).expect("definite");
        assert!((log_det[2] - prior).abs() < 1e-12);
        assert_eq!(failed, 0);
        // Never seen: the largest value, chance 1.
        assert_eq!(
            log_det[3],
            log_det[..3].iter().copied().fold(f64::MIN, f64::max)
        );
        assert_eq!(normalised[3], 1.0);
    }

    #[test]
    fn failed_factorisations_are_counted_and_get_the_largest_value() {
        let seen = |xs: &[[f32; 2]]| {
            let mut w = Welford::new(2);
            xs.iter().for_each(|x| w.push(x));
            w
        };
        let stats = [
            seen(&[[0.0, 1.0], [1.0, 0.5], [0.2, 0.3]]),
            seen(&[[0.0, 0.0], [0.1, 0.0]]),
            // A non-finite feature: no covariance to factorise.
            seen(&[[f32::NAN, 0.0], [0.1, 0.0]]),
            // Seen once: the largest value, but not a failure.
            seen(&[[0.5, 0.5]]),
        ];
        let opts = UncertaintyOptions {
            prior_weight: 0.0,
            ..UncertaintyOptions::default()
        };
        let (log_det, normalised, failed) = log_dets(&stats, 2, &opts);
        assert_eq!(failed, 1);
        assert_eq!(log_det[2], log_det[0].max(log_det[1]));
        assert_eq!(normalised[2], 1.0);
        assert!(log_det.iter().all(|u| u.is_finite()));
    }

    #[test]
    fn voxel_downsampling_keeps_one_point_per_cell() {
        let pts = vec![
            [0.01, 0.01, 0.01],
            [0.02, 0.03, 0.04],
            [0.12, 0.01, 0.01],
            [-0.01, 0.01, 0.01],
            [0.11, 0.09, 0.02],
        ];
        assert_eq!(voxel_downsample(&pts, 0.1), vec![0, 2, 3]);
        assert_eq!(voxel_downsample(&pts, 0.0), vec![0, 1, 2, 3, 4]);
    }
}
