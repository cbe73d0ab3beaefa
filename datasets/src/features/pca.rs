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
