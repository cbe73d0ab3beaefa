//! Principal component analysis of feature vectors: fit a basis on samples,
//! project features to `k` coefficients and lift coefficients back.

use super::eigen::symmetric_eigen;
use crate::error::DatasetError;

/// A PCA basis: `x ~ mean + components^T coeffs`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pca {
    /// Input dimension D.
    pub dim: usize,
    /// Number of kept components k.
    pub k: usize,
    /// Sample mean, `[dim]`.
    pub mean: Vec<f32>,
    /// `k x dim` row-major, orthonormal rows, by decreasing variance.
    pub components: Vec<f32>,
    /// Fraction of the sample variance the kept components explain.
    pub explained_variance_ratio: f64,
}

/// How many components to keep.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PcaTarget {
    /// Exactly this many (at most D).
    Components(usize),
    /// The fewest components explaining at least this fraction of variance.
    ExplainedVariance(f64),
}

/// How a scene's feature maps are compressed, as users choose it
/// (`--pca auto|off|K`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PcaSetting {
    /// Full dimension D.
    Off,
    /// The fewest components explaining [`AUTO_EXPLAINED_VARIANCE`] of the
    /// variance.
    Auto,
    /// Exactly this many components.
    Components(usize),
}

/// Explained-variance target of [`PcaSetting::Auto`].
pub const AUTO_EXPLAINED_VARIANCE: f64 = 0.99;

impl PcaSetting {
    /// The fitting target, `None` for no compression.
    pub fn target(self) -> Option<PcaTarget> {
        match self {
            Self::Off => None,
            Self::Auto => Some(PcaTarget::ExplainedVariance(AUTO_EXPLAINED_VARIANCE)),
            Self::Components(k) => Some(PcaTarget::Components(k)),
        }
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
        }
    }
}

impl Pca {
    /// Fits a basis to `samples` (`n x dim`, row-major).
    ///
    /// # Shapes
    /// `samples`: `[n, dim]` with `n >= 2`.
    pub fn fit(samples: &[f32], dim: usize, target: PcaTarget) -> Result<Self, DatasetError> {
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
        let (values, vectors) = symmetric_eigen(&cov, dim)
            .ok_or_else(|| err("eigendecomposition did not converge".into()))?;
        let values: Vec<f64> = values.iter().map(|v| v.max(0.0)).collect();
        let total: f64 = values.iter().sum();
        let k = match target {
            PcaTarget::Components(k) if k >= 1 && k <= dim => k,
            PcaTarget::Components(k) => {
                return Err(err(format!("cannot keep {k} components of {dim}")));
            }
            PcaTarget::ExplainedVariance(f) if f > 0.0 && f <= 1.0 => {
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
            PcaTarget::ExplainedVariance(f) => {
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
    pub fn project(&self, x: &[f32]) -> Vec<f32> {
        let mut out = Vec::with_capacity(x.len() / self.dim.max(1) * self.k);
        let mut centred = vec![0f32; self.dim];
        for row in x.chunks_exact(self.dim) {
            for ((c, &v), &m) in centred.iter_mut().zip(row).zip(&self.mean) {
                *c = v - m;
            }
            for comp in self.components.chunks_exact(self.dim) {
                out.push(comp.iter().zip(&centred).map(|(a, b)| a * b).sum());
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
