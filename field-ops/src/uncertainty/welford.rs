//! Single-pass mean and covariance (Welford) and the log-determinant of a
//! covariance by Cholesky: the per-point statistics of the uncertainty map.

use nalgebra::DMatrix;

/// Running mean and scatter of `k`-dimensional samples (Welford's update,
/// generalised to covariances): numerically stable in one pass, with no
/// sample kept.
///
/// After `n` samples `x_1..x_n`, `mean = sum x_i / n` and
/// `scatter = sum (x_i - mean)(x_i - mean)^T` (row-major `k x k`).
#[derive(Debug, Clone, PartialEq)]
pub struct Welford {
    /// Samples seen.
    pub count: u64,
    /// `[k]` running mean.
    pub mean: Vec<f64>,
    /// `[k * k]` running scatter matrix, row-major, symmetric.
    pub scatter: Vec<f64>,
}

impl Welford {
    /// An empty accumulator of dimension `k`.
    pub fn new(k: usize) -> Self {
        Self {
            count: 0,
            mean: vec![0.0; k],
            scatter: vec![0.0; k * k],
        }
    }

    /// Dimension of the samples.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Adds one sample `x` (`[k]`).
    ///
    /// `delta = x - mean_old`, `mean += delta / n`, and
    /// `scatter += delta (x - mean_new)^T`, which keeps the scatter symmetric
    /// positive semi-definite up to rounding.
    pub fn push(&mut self, x: &[f32]) {
        let k = self.dim();
        debug_assert_eq!(x.len(), k);
        self.count += 1;
        let n = self.count as f64;
        let delta: Vec<f64> = x
            .iter()
            .zip(&self.mean)
            .map(|(&v, m)| v as f64 - m)
            .collect();
        for (m, d) in self.mean.iter_mut().zip(&delta) {
            *m += d / n;
        }
        for (r, dr) in delta.iter().enumerate() {
            let row = &mut self.scatter[r * k..(r + 1) * k];
            for ((s, &v), m) in row.iter_mut().zip(x).zip(&self.mean) {
                *s += dr * (v as f64 - m);
            }
        }
    }

    /// The sample covariance `scatter / (n - 1)`, symmetrised; `None` with
    /// fewer than two samples.
    pub fn covariance(&self) -> Option<Vec<f64>> {
        if self.count < 2 {
            return None;
        }
        let k = self.dim();
        let d = (self.count - 1) as f64;
        let mut cov = vec![0.0; k * k];
        for r in 0..k {
            for c in 0..k {
                cov[r * k + c] = 0.5 * (self.scatter[r * k + c] + self.scatter[c * k + r]) / d;
            }
        }
        Some(cov)
    }
}

impl Welford {
    /// The covariance shrunk towards `prior` (`k x k`) as if `weight` extra
    /// samples had been drawn from it: `(scatter + weight prior) / (n - 1 +
    /// weight)` (the posterior mean of an inverse-Wishart prior). With
    /// `weight = 0` this is [`Welford::covariance`]. A point seen by few
    /// views gets about the prior instead of a rank-deficient estimate whose
    /// log-determinant is mostly `eps`. A point seen once has no scatter and
    /// gets the prior itself (with `weight > 0`), like any other point
    /// measured by its evidence rather than set to the maximum. `None` without
    /// samples, or with one sample and no prior weight.
    pub fn shrunk_covariance(&self, prior: &[f64], weight: f64) -> Option<Vec<f64>> {
        let d = self.count.checked_sub(1)? as f64 + weight;
        if d <= 0.0 || prior.len() != self.scatter.len() {
            return None;
        }
        let k = self.dim();
        let mut cov = vec![0.0; k * k];
        for r in 0..k {
            for c in 0..k {
                let s = 0.5 * (self.scatter[r * k + c] + self.scatter[c * k + r]);
                cov[r * k + c] = (s + weight * prior[r * k + c]) / d;
            }
        }
        Some(cov)
    }
}

/// The pooled within-group covariance of `stats` (`k x k`): the sum of their
/// scatters over the sum of their degrees of freedom (`n - 1` each); `None`
/// when no group has two samples. Groups with a non-finite scatter are left
/// out: one of them would make every shrunk covariance non-finite.
pub fn pooled_covariance(stats: &[Welford], k: usize) -> Option<Vec<f64>> {
    let mut sum = vec![0.0; k * k];
    let mut dof = 0.0;
    for w in stats
        .iter()
        .filter(|w| w.count >= 2 && w.scatter.iter().all(|x| x.is_finite()))
    {
        sum.iter_mut().zip(&w.scatter).for_each(|(s, x)| *s += x);
        dof += (w.count - 1) as f64;
    }
    (dof > 0.0).then(|| sum.into_iter().map(|s| s / dof).collect())
}

/// `log det(cov + eps I)` of a symmetric positive semi-definite `k x k`
/// matrix (row-major), by Cholesky: `2 sum ln L_ii`.
///
/// `eps > 0` makes the matrix positive definite, so rank-deficient and
/// near-singular covariances give finite values (at least `k ln eps`).
/// Returns `None` only when the factorisation fails (a matrix that is not
/// positive semi-definite beyond rounding, or a non-finite entry).
pub fn log_det_regularised(cov: &[f64], k: usize, eps: f64) -> Option<f64> {
    if cov.len() != k * k || !cov.iter().all(|v| v.is_finite()) {
        return None;
    }
    let m = DMatrix::from_fn(k, k, |r, c| cov[r * k + c] + if r == c { eps } else { 0.0 });
    let l = m.cholesky()?;
    let diag = l.l_dirty().diagonal();
    Some(2.0 * diag.iter().map(|d| d.ln()).sum::<f64>())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn two_pass(xs: &[Vec<f32>]) -> (Vec<f64>, Vec<f64>) {
        let k = xs[0].len();
        let n = xs.len() as f64;
        let mut mean = vec![0.0; k];
        for x in xs {
            for j in 0..k {
                mean[j] += x[j] as f64 / n;
            }
        }
        let mut cov = vec![0.0; k * k];
        for x in xs {
            for r in 0..k {
                for c in 0..k {
                    cov[r * k + c] += (x[r] as f64 - mean[r]) * (x[c] as f64 - mean[c]) / (n - 1.0);
                }
            }
        }
        (mean, cov)
    }

    #[test]
    fn matches_the_two_pass_f64_result_on_random_data() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for k in [1, 3, 16] {
            let xs: Vec<Vec<f32>> = (0..200)
                .map(|_| {
                    (0..k)
                        .map(|j| rng.random_range(-1.0..1.0) * (j + 1) as f32 + 5.0)
                        .collect()
                })
                .collect();
            let mut w = Welford::new(k);
            xs.iter().for_each(|x| w.push(x));
            let (mean, cov) = two_pass(&xs);
            let got = w.covariance().expect("two or more samples");
            for (j, (a, b)) in w.mean.iter().zip(&mean).enumerate() {
                assert!((a - b).abs() < 1e-12, "mean {j}");
            }
            for (a, b) in got.iter().zip(&cov) {
                assert!((a - b).abs() < 1e-10 * (1.0 + b.abs()), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn a_million_updates_stay_accurate() {
        // A large offset and a small spread: the naive sum-of-squares formula
        // loses every digit here; Welford keeps them.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut w = Welford::new(2);
        let xs: Vec<[f32; 2]> = (0..1_000_000)
            .map(|_| {
                [
                    1000.0 + rng.random_range(-1.0f32..1.0),
                    rng.random_range(-2.0f32..2.0),
                ]
            })
            .collect();
        xs.iter().for_each(|x| w.push(x));
        let n = xs.len() as f64;
        let mean: Vec<f64> = (0..2)
            .map(|j| xs.iter().map(|x| x[j] as f64).sum::<f64>() / n)
            .collect();
        let var: Vec<f64> = (0..2)
            .map(|j| {
                xs.iter()
                    .map(|x| (x[j] as f64 - mean[j]).powi(2))
                    .sum::<f64>()
                    / (n - 1.0)
            })
            .collect();
        let cov = w.covariance().expect("samples");
        for j in 0..2 {
            assert!(((w.mean[j] - mean[j]) / mean[j].abs().max(1.0)).abs() < 1e-6);
            assert!(
                ((cov[j * 2 + j] - var[j]) / var[j]).abs() < 1e-6,
                "{} vs {}",
                cov[j * 2 + j],
                var[j]
            );
        }
    }

    #[test]
    fn identical_samples_give_the_eps_floor_never_nan() {
        let mut w = Welford::new(4);
        for _ in 0..10 {
            w.push(&[0.3, -1.0, 2.0, 0.0]);
        }
        let cov = w.covariance().expect("samples");
        assert!(cov.iter().all(|v| v.abs() < 1e-12));
        let eps = 1e-4;
        let ld = log_det_regularised(&cov, 4, eps).expect("finite");
        assert!((ld - 4.0 * eps.ln()).abs() < 1e-6, "{ld}");
        assert!(Welford::new(4).covariance().is_none());
    }

    #[test]
    fn rank_deficient_and_near_singular_covariances_have_finite_log_dets() {
        // Samples on a line in 3D: rank 1.
        let mut w = Welford::new(3);
        for t in 0..20 {
            let t = t as f32 * 0.1;
            w.push(&[t, 2.0 * t, -t]);
        }
        let cov = w.covariance().expect("samples");
        let ld = log_det_regularised(&cov, 3, 1e-6).expect("rank 1 + eps is definite");
        assert!(ld.is_finite());
        // Exactly: eigenvalues (6 var(t) + eps, eps, eps).
        let var_t = (0..20)
            .map(|t| (t as f64 * 0.1 - 0.95).powi(2))
            .sum::<f64>()
            / 19.0;
        let expected = (6.0 * var_t + 1e-6).ln() + 2.0 * 1e-6f64.ln();
        assert!((ld - expected).abs() < 1e-3, "{ld} vs {expected}");
        // Slightly indefinite by rounding still factorises once eps is added.
        let near = [1.0, 1.0, 1.0, 1.0 - 1e-13];
        assert!(
            log_det_regularised(&near, 2, 1e-8)
                .expect("finite")
                .is_finite()
        );
        assert!(log_det_regularised(&[f64::NAN], 1, 1e-6).is_none());
    }

    #[test]
    fn shrinkage_moves_from_the_sample_covariance_to_the_prior() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let groups: Vec<Welford> = (0..3)
            .map(|g| {
                let mut w = Welford::new(2);
                for _ in 0..(5 + 10 * g) {
                    w.push(&[rng.random_range(-1.0..1.0), rng.random_range(0.0..2.0)]);
                }
                w
            })
            .collect();
        let pooled = pooled_covariance(&groups, 2).expect("pooled");
        // Pooled = sum of scatters / sum of (n - 1), checked by hand.
        let dof: f64 = groups.iter().map(|w| (w.count - 1) as f64).sum();
        let s00: f64 = groups.iter().map(|w| w.scatter[0]).sum();
        assert!((pooled[0] - s00 / dof).abs() < 1e-12);
        let w = &groups[0];
        let own = w.covariance().expect("cov");
        let none = w.shrunk_covariance(&pooled, 0.0).expect("cov");
        assert!(own.iter().zip(&none).all(|(a, b)| (a - b).abs() < 1e-15));
        let heavy = w.shrunk_covariance(&pooled, 1e9).expect("cov");
        assert!(heavy.iter().zip(&pooled).all(|(a, b)| (a - b).abs() < 1e-6));
        let half = w
            .shrunk_covariance(&pooled, (w.count - 1) as f64)
            .expect("cov");
        for i in 0..4 {
            assert!((half[i] - 0.5 * (own[i] + pooled[i])).abs() < 1e-12);
        }
        assert!(pooled_covariance(&[Welford::new(2)], 2).is_none());
    }

    #[test]
    fn a_point_seen_once_gets_the_prior_and_one_seen_never_gets_nothing() {
        let prior = [2.0, 0.5, 0.5, 1.0];
        let mut once = Welford::new(2);
        once.push(&[3.0, -1.0]);
        // (0 scatter + w prior) / (1 - 1 + w) = prior, whatever the weight.
        for weight in [0.5, 16.0] {
            let cov = once.shrunk_covariance(&prior, weight).expect("prior");
            assert!(cov.iter().zip(&prior).all(|(a, b)| (a - b).abs() < 1e-15));
        }
        // Without prior weight one sample defines no covariance.
        assert!(once.shrunk_covariance(&prior, 0.0).is_none());
        assert!(Welford::new(2).shrunk_covariance(&prior, 16.0).is_none());
        // A prior of the wrong size is refused, not indexed out of bounds.
        assert!(once.shrunk_covariance(&prior[..3], 16.0).is_none());
        // Two samples: the scatter enters, (s + w P) / (1 + w).
        let mut twice = once.clone();
        twice.push(&[1.0, 1.0]);
        let cov = twice.shrunk_covariance(&prior, 1.0).expect("cov");
        let s = [2.0, -2.0, -2.0, 2.0];
        for i in 0..4 {
            assert!((cov[i] - (s[i] + prior[i]) / 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn cholesky_log_det_equals_the_eigenvalue_sum() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let k = 8;
        let a = DMatrix::<f64>::from_fn(k, k, |_, _| rng.random_range(-1.0..1.0));
        let spd = &a * a.transpose();
        let flat: Vec<f64> = (0..k * k).map(|i| spd[(i / k, i % k)]).collect();
        let eps = 1e-3;
        let ld = log_det_regularised(&flat, k, eps).expect("definite");
        let eig = spd.symmetric_eigen();
        let expected: f64 = eig.eigenvalues.iter().map(|l| (l + eps).ln()).sum();
        assert!((ld - expected).abs() < 1e-9, "{ld} vs {expected}");
    }
}
