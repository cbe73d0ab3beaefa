//! From log-determinants to the chance of each point to become a novel-view
//! target (the `u_i` of the paper's draw `x < u_i`, Sec. 3.3).
//!
//! The paper draws against the generalized variance itself. Rescaling the
//! log-determinant to `[0, 1]` (`minmax-logdet`) instead flattens it: in 16
//! dimensions a factor of 10 in every principal variance is only a shift of
//! `16 ln 10` in the log, so most seen points land between 0.3 and 0.6 and
//! about half the cloud becomes a candidate. `det-over-max` is the
//! generalized variance over its largest value, the paper's draw; `rank:T`
//! is the point's quantile `q` raised to `1 / T`, a draw whose expected
//! share of candidates is `T / (1 + T)` whatever the spread of the values.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// How log-determinants become target chances in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Normalisation {
    /// `(l - min) / (max - min)` of the log-determinant `l`.
    #[default]
    MinmaxLogdet,
    /// `det / max det = exp(l - max l)`: the generalized variance relative
    /// to the largest.
    DetOverMax,
    /// `q^(1 / temperature)` with `q` the point's rank quantile (0 for the
    /// smallest value, 1 for the largest; ties share their mean rank).
    RankQuantile {
        /// Positive; small values keep the top of the ranking only.
        temperature: f64,
    },
}

impl Normalisation {
    /// Every normalisation, the rank one at a few temperatures (for reports).
    pub fn catalogue() -> Vec<Normalisation> {
        let mut all = vec![Self::MinmaxLogdet, Self::DetOverMax];
        all.extend([1.0, 0.25, 0.1].map(|temperature| Self::RankQuantile { temperature }));
        all
    }

    /// The chances of `values` (one per point; `None` for a point without a
    /// value, which gets 1, the largest).
    ///
    /// # Shapes
    /// `values: [n]` -> `[n]`, every entry in `[0, 1]`.
    pub fn apply(self, values: &[Option<f64>]) -> Vec<f64> {
        let known: Vec<f64> = values.iter().flatten().copied().collect();
        let max = known.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = known.iter().copied().fold(f64::INFINITY, f64::min);
        if !max.is_finite() || !min.is_finite() {
            return vec![1.0; values.len()];
        }
        match self {
            Self::MinmaxLogdet => {
                let span = max - min;
                values
                    .iter()
                    .map(|v| match v {
                        Some(v) if span > 0.0 => (v - min) / span,
                        _ => 1.0,
                    })
                    .collect()
            }
            Self::DetOverMax => values
                .iter()
                .map(|v| v.map_or(1.0, |v| (v - max).exp()))
                .collect(),
            Self::RankQuantile { temperature } => {
                let q = rank_quantiles(values);
                q.into_iter()
                    .map(|q| q.powf(1.0 / temperature).clamp(0.0, 1.0))
                    .collect()
            }
        }
    }
}

/// Target chances of the points seen by at least one view (`counts > 0`),
/// normalised among those points only; points never seen get 1 (callers
/// that draw targets exclude them, see `novel::guided::target_chances`).
///
/// # Shapes
/// `values: [n]`, `counts: [n]` -> `[n]`.
pub fn seen_chances(values: &[Option<f64>], counts: &[u64], how: Normalisation) -> Vec<f64> {
    let seen: Vec<usize> = (0..values.len()).filter(|&i| counts[i] > 0).collect();
    let chances = how.apply(&seen.iter().map(|&i| values[i]).collect::<Vec<_>>());
    let mut out = vec![1.0; values.len()];
    for (&i, c) in seen.iter().zip(chances) {
        out[i] = c;
    }
    out
}

/// Each value's rank quantile among all values in `[0, 1]`: ties share their
/// mean rank; a missing value ranks above every value.
fn rank_quantiles(values: &[Option<f64>]) -> Vec<f64> {
    let n = values.len();
    if n < 2 {
        return vec![1.0; n];
    }
    let key = |i: usize| values[i].unwrap_or(f64::INFINITY);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| key(a).total_cmp(&key(b)));
    let mut q = vec![0.0; n];
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && key(order[end]) == key(order[start]) {
            end += 1;
        }
        let mean_rank = (start + end - 1) as f64 / 2.0;
        for &i in &order[start..end] {
            q[i] = mean_rank / (n - 1) as f64;
        }
        start = end;
    }
    q
}

impl fmt::Display for Normalisation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::MinmaxLogdet => f.write_str("minmax-logdet"),
            Self::DetOverMax => f.write_str("det-over-max"),
            Self::RankQuantile { temperature } => write!(f, "rank:{temperature}"),
        }
    }
}

impl FromStr for Normalisation {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "minmax-logdet" => Ok(Self::MinmaxLogdet),
            "det-over-max" => Ok(Self::DetOverMax),
            _ => {
                let t = s.strip_prefix("rank:").ok_or_else(|| {
                    format!("unknown normalisation {s:?} (minmax-logdet, det-over-max or rank:T, e.g. rank:0.25)")
                })?;
                match t.parse::<f64>() {
                    Ok(temperature) if temperature.is_finite() && temperature > 0.0 => {
                        Ok(Self::RankQuantile { temperature })
                    }
                    _ => Err(format!(
                        "rank:{t}: the temperature must be a positive number (e.g. rank:0.25)"
                    )),
                }
            }
        }
    }
}

impl Serialize for Normalisation {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for Normalisation {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_normalisation_against_its_formula() {
        let l = [Some(2.0), Some(-1.0), None, Some(0.5), Some(2.0)];
        let mm = Normalisation::MinmaxLogdet.apply(&l);
        assert_eq!(mm, vec![1.0, 0.0, 1.0, 0.5, 1.0]);
        let det = Normalisation::DetOverMax.apply(&l);
        let want = [1.0, (-3.0f64).exp(), 1.0, (-1.5f64).exp(), 1.0];
        assert!(det.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-15));
        // Sorted: -1 (rank 0), 0.5 (1), 2 and 2 (2, 3: mean 2.5), None (4).
        let rank = Normalisation::RankQuantile { temperature: 1.0 }.apply(&l);
        assert_eq!(rank, vec![2.5 / 4.0, 0.0, 1.0, 0.25, 2.5 / 4.0]);
        let sharp = Normalisation::RankQuantile { temperature: 0.5 }.apply(&l);
        assert!((sharp[3] - 0.0625).abs() < 1e-15);
    }

    #[test]
    fn the_rank_draw_keeps_its_expected_share_of_candidates() {
        // E[q^(1/T)] over uniform quantiles is T / (1 + T).
        let values: Vec<Option<f64>> = (0..10_001).map(|i| Some((i as f64).sin())).collect();
        for t in [1.0, 0.25, 0.1] {
            let u = Normalisation::RankQuantile { temperature: t }.apply(&values);
            let mean = u.iter().sum::<f64>() / u.len() as f64;
            assert!((mean - t / (1.0 + t)).abs() < 1e-3, "T {t}: {mean}");
        }
    }

    #[test]
    fn unseen_points_take_no_part_in_the_normalisation() {
        let values = [Some(1.0), None, Some(3.0), Some(2.0)];
        let counts = [4, 0, 2, 1];
        let rank = Normalisation::RankQuantile { temperature: 1.0 };
        assert_eq!(
            seen_chances(&values, &counts, rank),
            vec![0.0, 1.0, 1.0, 0.5]
        );
        let mm = seen_chances(&values, &counts, Normalisation::MinmaxLogdet);
        assert_eq!(mm, vec![0.0, 1.0, 1.0, 0.5]);
    }

    #[test]
    fn degenerate_inputs_give_the_largest_chance() {
        assert_eq!(
            Normalisation::DetOverMax.apply(&[None, None]),
            vec![1.0, 1.0]
        );
        assert_eq!(Normalisation::MinmaxLogdet.apply(&[Some(3.0)]), vec![1.0]);
        assert!(Normalisation::MinmaxLogdet.apply(&[]).is_empty());
    }

    #[test]
    fn names_round_trip_and_bad_ones_are_refused() {
        for n in Normalisation::catalogue() {
            assert_eq!(n.to_string().parse::<Normalisation>(), Ok(n));
            let json = serde_json::to_string(&n).expect("json");
            assert_eq!(
                serde_json::from_str::<Normalisation>(&json).expect("back"),
                n
            );
        }
        for bad in [
            "", "minmax", "rank:", "rank:0", "rank:-1", "rank:nan", "rank:inf",
        ] {
            assert!(bad.parse::<Normalisation>().is_err(), "{bad}");
        }
    }
}
