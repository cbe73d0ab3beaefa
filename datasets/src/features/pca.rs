//! Principal component analysis of feature vectors: fit a basis on samples,
//! project features to `k` coefficients and lift coefficients back.

use nalgebra::{DMatrix, SymmetricEigen};

use crate::error::DatasetError;

/// A fitted PCA basis: `x ~ mean + components^T coeffs`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PcaBasis {
    /// Input dimension D.
    pub dim: usize,
    /// Number of kept components k.
    pub k: usize,
    /// Sample mean, `[dim]`.
    pub mean: Vec<f32>,
    /// `k x dim` row-major, orthonormal rows, by decreasing variance; each
    /// row's largest-magnitude entry is positive.
    pub components: Vec<f32>,
    /// Fraction of the sample variance the kept components explain.
    pub explained_variance_ratio: f64,
}

/// How a scene's feature maps are compressed: chosen on the command line
/// (`--pca auto|off|K`), stored with the scene and handed to the loaders.
///
/// Serialised as `"off"`, `"auto"`, `{"components": K}` or
/// `{"explained_variance": F}`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PcaSetting {
    /// Full dimension D.
    #[default]
    Off,
    /// The fewest components explaining [`AUTO_EXPLAINED_VARIANCE`] of the
    /// variance.
    Auto,
    /// Exactly this many components (at most D).
    Components(usize),
    /// The fewest components explaining at least this fraction of variance.
    ExplainedVariance(f64),
}

/// Explained-variance target of [`PcaSetting::Auto`].
pub const AUTO_EXPLAINED_VARIANCE: f64 = 0.99;

impl PcaSetting {
    /// Whether the maps are compressed at all.
    pub fn is_on(self) -> bool {
        self != Self::Off
    }
}

impl std::str::FromStr for PcaSetting {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "auto" => Ok(Self::Auto),
            "off" => Ok(Self::Off),
            k => match k.parse::<usize>() {
                Ok(k) if k >= 1 => Ok(Self::Components(k)),
                _ => Err(format!(
                    "expected auto, off or a number of components >= 1, got {s:?}"
                )),
            },
        }
    }
}

impl std::fmt::Display for PcaSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Off => write!(f, "off"),
            Self::Auto => write!(f, "auto"),
            Self::Components(k) => write!(f, "{k}"),
            Self::ExplainedVariance(v) => write!(f, "{v} of the variance"),
        }
    }
}

impl PcaBasis {
    /// Fits a basis to `samples` (`n x dim`, row-major), keeping as many
    /// components as `setting` asks for (an error for [`PcaSetting::Off`]).
    ///
    /// # Shapes
    /// `samples`: `[n, dim]` with `n >= 2`.
    pub fn fit(samples: &[f32], dim: usize, setting: PcaSetting) -> Result<Self, DatasetError> {
        let err = |m: String| DatasetError::invalid("<pca>", m);
        if dim == 0 || !samples.len().is_multiple_of(dim) || samples.len() < 2 * dim {
            return Err(err(format!(
                "need at least 2 samples of dimension {dim}, got {} values",
                samples.len()
            )));
        }
        if samples.iter().any(|v| !v.is_finite()) {
            return Err(err("samples contain NaN or infinite values".into()));
        }
        let n = samples.len() / dim;
        let mut mean = vec![0f64; dim];
        for row in samples.chunks_exact(dim) {
            for (m, &x) in mean.iter_mut().zip(row) {
                *m += x as f64;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let cov = covariance(samples, dim, &mean);
        let (values, vectors) = symmetric_eigen(cov, dim)
            .ok_or_else(|| err("eigendecomposition did not converge".into()))?;
        let values: Vec<f64> = values.iter().map(|v| v.max(0.0)).collect();
        let total: f64 = values.iter().sum();
        let setting = match setting {
            PcaSetting::Auto => PcaSetting::ExplainedVariance(AUTO_EXPLAINED_VARIANCE),
            s => s,
        };
        let k = match setting {
            PcaSetting::Off | PcaSetting::Auto => {
                return Err(err("PCA is off: there is no basis to fit".into()));
            }
            PcaSetting::Components(k) if k >= 1 && k <= dim => k,
            PcaSetting::Components(k) => {
                return Err(err(format!("cannot keep {k} components of {dim}")));
            }
            PcaSetting::ExplainedVariance(f) if f > 0.0 && f <= 1.0 => {
                let mut acc = 0.0;
                let mut k = dim;
                for (i, v) in values.iter().enumerate() {
                    acc += v;
                    if acc >= f * total - 1e-12 * total {
                        k = i + 1;
                        break;
                    }
                }
                k
            }
            PcaSetting::ExplainedVariance(f) => {
                return Err(err(format!("explained variance target {f} not in (0, 1]")));
            }
        };
        let kept: f64 = values[..k].iter().sum();
        Ok(Self {
            dim,
            k,
            mean: mean.iter().map(|&m| m as f32).collect(),
            components: vectors[..k * dim].iter().map(|&v| v as f32).collect(),
            explained_variance_ratio: if total > 0.0 { kept / total } else { 1.0 },
        })
    }

    /// Coefficients of one or more vectors.
    ///
    /// # Shapes
    /// `x`: `[n, dim]` -> `[n, k]`.
    ///
    /// `LANES` rows are projected together: their centred values are laid
    /// out channel-major, so the inner loop runs across rows (vector
    /// instructions) while each row's dot product still adds its terms in
    /// channel order from `-0.0`, exactly as a plain per-row sum does: the
    /// coefficients are bit for bit those of the one-row-at-a-time loop.
    pub fn project(&self, x: &[f32]) -> Vec<f32> {
        const LANES: usize = 16;
        let (d, k) = (self.dim, self.k);
        if d == 0 {
            return Vec::new();
        }
        let n = x.len() / d;
        let mut out = vec![0f32; n * k];
        let mut block = vec![[0f32; LANES]; d];
        for (b, rows) in x[..n * d].chunks(d * LANES).enumerate() {
            let lanes = rows.len() / d;
            block.iter_mut().for_each(|column| *column = [0.0; LANES]);
            for (l, row) in rows.chunks_exact(d).enumerate() {
                for ((column, &v), &m) in block.iter_mut().zip(row).zip(&self.mean) {
                    column[l] = v - m;
                }
            }
            for (c, comp) in self.components.chunks_exact(d).enumerate() {
                let mut acc = [-0.0f32; LANES];
                for (&w, column) in comp.iter().zip(&block) {
                    for l in 0..LANES {
                        acc[l] += w * column[l];
                    }
                }
                for (l, &a) in acc[..lanes].iter().enumerate() {
                    out[(b * LANES + l) * k + c] = a;
                }
            }
        }
        out
    }

    /// Vectors from coefficients (the reconstruction in the full space).
    ///
    /// # Shapes
    /// `coeffs`: `[n, k]` -> `[n, dim]`.
    pub fn lift(&self, coeffs: &[f32]) -> Vec<f32> {
        let mut out = Vec::with_capacity(coeffs.len() / self.k.max(1) * self.dim);
        for c in coeffs.chunks_exact(self.k) {
            let start = out.len();
            out.extend_from_slice(&self.mean);
            for (&ci, comp) in c.iter().zip(self.components.chunks_exact(self.dim)) {
                for (o, &v) in out[start..].iter_mut().zip(comp) {
                    *o += ci * v;
                }
            }
        }
        out
    }
}

/// Eigenvalues (descending) and unit eigenvectors of the symmetric
/// `n x n` row-major matrix `a`; eigenvector `i` is
/// `vectors[i * n..(i + 1) * n]`, its largest-magnitude entry positive (the
/// first such entry on ties). `None` if the iteration does not converge.
///
/// # Shapes
/// `a`: `[n, n]` -> (`[n]`, `[n, n]` rows = eigenvectors).
pub fn symmetric_eigen(a: Vec<f64>, n: usize) -> Option<(Vec<f64>, Vec<f64>)> {
    let m = DMatrix::from_row_slice(n, n, &a);
    let eig = SymmetricEigen::try_new(m, f64::EPSILON, 10_000)?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&x, &y| eig.eigenvalues[y].total_cmp(&eig.eigenvalues[x]));
    let values = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let mut vectors = Vec::with_capacity(n * n);
    for &i in &order {
        let v = eig.eigenvectors.column(i);
        let lead = v
            .iter()
            .fold(0.0f64, |m, &x| if x.abs() > m.abs() { x } else { m });
        let sign = if lead < 0.0 { -1.0 } else { 1.0 };
        vectors.extend(v.iter().map(|&x| sign * x));
    }
    Some((values, vectors))
}

/// Sample covariance (divided by `n - 1`), `[dim, dim]` row-major.
fn covariance(samples: &[f32], dim: usize, mean: &[f64]) -> Vec<f64> {
    let n = samples.len() / dim;
    let mut cov = vec![0f64; dim * dim];
    let mut c = vec![0f64; dim];
    for row in samples.chunks_exact(dim) {
        for ((ci, &x), &m) in c.iter_mut().zip(row).zip(mean) {
            *ci = x as f64 - m;
        }
        // Upper triangle only; mirrored below.
        for i in 0..dim {
            let ci = c[i];
            let out = &mut cov[i * dim + i..(i + 1) * dim];
            for (o, &cj) in out.iter_mut().zip(&c[i..]) {
                *o += ci * cj;
            }
        }
    }
    let denom = (n.max(2) - 1) as f64;
    for i in 0..dim {
        for j in i..dim {
            let v = cov[i * dim + j] / denom;
            cov[i * dim + j] = v;
            cov[j * dim + i] = v;
        }
    }
    cov
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocked_projection_is_the_per_row_dot_product_bit_for_bit() {
        let (dim, n) = (37, 21); // rows not a multiple of the block
        let value = |i: usize| ((i * 7919 % 1000) as f32 / 500.0 - 1.0) * 0.37;
        let samples: Vec<f32> = (0..n * dim).map(value).collect();
        let basis = PcaBasis::fit(&samples, dim, PcaSetting::Components(5)).unwrap();
        let x: Vec<f32> = (0..n * dim).map(|i| value(i * 3 + 1)).collect();
        let mut want = Vec::new();
        for row in x.chunks_exact(dim) {
            let centred: Vec<f32> = row.iter().zip(&basis.mean).map(|(v, m)| v - m).collect();
            for comp in basis.components.chunks_exact(dim) {
                want.push(comp.iter().zip(&centred).map(|(a, b)| a * b).sum::<f32>());
            }
        }
        let got = basis.project(&x);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&want));
        assert!(basis.project(&x[..dim - 1]).is_empty());
    }
}
