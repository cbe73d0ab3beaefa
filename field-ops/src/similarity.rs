//! Cosine similarity between field features and text embeddings, computed
//! exactly in the field's (possibly PCA-compressed) feature space.
//!
//! With a PCA basis the full feature is `f = mean + B^T c` (`B`: `k x D`).
//! For a unit text embedding `t`:
//!
//! ```text
//! f . t  = mean . t + c . (B t)
//! |f|^2  = |mean|^2 + 2 c . (B mean) + c^T (B B^T) c
//! ```
//!
//! so the cosine in the lifted space costs `O(k^2 + k C)` per point instead of
//! `O(D (k + C))`, and equals lifting then comparing up to rounding (a test
//! checks this against the explicit lift).

use datasets::features::PcaBasis;

use crate::OpsError;

/// Scores features (in the field's output space) against class embeddings.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassScorer {
    /// Channels of the field's features (k with PCA, else D).
    pub dim: usize,
    /// Number of classes C.
    pub classes: usize,
    /// `mean . t_j` per class (0 without PCA).
    offset: Vec<f64>,
    /// `C x dim`: `B t_j` (or `t_j` without PCA), `t_j` unit length.
    proj: Vec<f64>,
    /// `dim x dim` Gram matrix `B B^T` (identity without PCA).
    gram: Vec<f64>,
    /// `B mean` (`dim`; zero without PCA).
    mean_proj: Vec<f64>,
    /// `|mean|^2`.
    mean_sq: f64,
}

impl ClassScorer {
    /// A scorer for `classes` embeddings (`C x D` row-major) and the run's
    /// PCA basis (`None` when the field predicts D-dimensional features).
    pub fn new(
        embeddings: &[f32],
        embed_dim: usize,
        pca: Option<&PcaBasis>,
    ) -> Result<Self, OpsError> {
        if embed_dim == 0 || !embeddings.len().is_multiple_of(embed_dim) {
            return Err(OpsError::Invalid(format!(
                "embeddings of {} values do not split into rows of {embed_dim}",
                embeddings.len()
            )));
        }
        if let Some(p) = pca
            && p.dim != embed_dim
        {
            return Err(OpsError::Invalid(format!(
                "text embeddings have dimension {embed_dim} but the run's feature space has {}",
                p.dim
            )));
        }
        let classes = embeddings.len() / embed_dim;
        let unit: Vec<Vec<f64>> = embeddings
            .chunks(embed_dim)
            .map(|r| {
                let n = r.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
                r.iter().map(|&x| x as f64 / n.max(1e-12)).collect()
            })
            .collect();
        let Some(p) = pca else {
            let mut gram = vec![0.0; embed_dim * embed_dim];
            (0..embed_dim).for_each(|i| gram[i * embed_dim + i] = 1.0);
            return Ok(Self {
                dim: embed_dim,
                classes,
                offset: vec![0.0; classes],
                proj: unit.concat(),
                gram,
                mean_proj: vec![0.0; embed_dim],
                mean_sq: 0.0,
            });
        };
        let (k, d) = (p.k, p.dim);
        let row = |i: usize| &p.components[i * d..(i + 1) * d];
        let dotf = |a: &[f32], b: &[f64]| a.iter().zip(b).map(|(&x, &y)| x as f64 * y).sum::<f64>();
        let mean: Vec<f64> = p.mean.iter().map(|&x| x as f64).collect();
        let mut proj = Vec::with_capacity(classes * k);
        let mut offset = Vec::with_capacity(classes);
        for t in &unit {
            offset.push(mean.iter().zip(t).map(|(a, b)| a * b).sum());
            proj.extend((0..k).map(|i| dotf(row(i), t)));
        }
        let mut gram = vec![0.0; k * k];
        for i in 0..k {
            let ri: Vec<f64> = row(i).iter().map(|&x| x as f64).collect();
            for j in 0..k {
                gram[i * k + j] = dotf(row(j), &ri);
            }
        }
        Ok(Self {
            dim: k,
            classes,
            offset,
            proj,
            gram,
            mean_proj: (0..k).map(|i| dotf(row(i), &mean)).collect(),
            mean_sq: mean.iter().map(|x| x * x).sum(),
        })
    }

    /// Norm of the lifted feature of coefficients `c`.
    pub fn lifted_norm(&self, c: &[f32]) -> f64 {
        let k = self.dim;
        let mut q = self.mean_sq;
        for i in 0..k {
            let ci = c[i] as f64;
            q += 2.0 * ci * self.mean_proj[i];
            q += ci
                * self.gram[i * k..(i + 1) * k]
                    .iter()
                    .zip(c)
                    .map(|(g, &cj)| g * cj as f64)
                    .sum::<f64>();
        }
        q.max(0.0).sqrt()
    }

    /// Cosine similarity of the lifted feature `c` with every class, written
    /// into `out` (length C). A zero feature scores 0 for every class.
    pub fn cosines(&self, c: &[f32], out: &mut [f64]) {
        let norm = self.lifted_norm(c);
        for (j, o) in out.iter_mut().enumerate().take(self.classes) {
            let p = &self.proj[j * self.dim..(j + 1) * self.dim];
            let dot = self.offset[j] + p.iter().zip(c).map(|(a, &b)| a * b as f64).sum::<f64>();
            *o = if norm > 1e-12 { dot / norm } else { 0.0 };
        }
    }

    /// Index of the most similar class (ties: the lower index).
    pub fn argmax(&self, c: &[f32]) -> u32 {
        let mut buf = vec![0.0; self.classes];
        self.cosines(c, &mut buf);
        argmax(&buf)
    }
}

/// Index of the largest value (the first on ties; 0 for an empty slice).
pub fn argmax(v: &[f64]) -> u32 {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use datasets::features::PcaSetting;

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 33) as f64 / (1u64 << 31) as f64 - 0.5) as f32
    }

    /// The closed form in PCA space equals lifting to D and taking the cosine
    /// there (f64 reference).
    #[test]
    fn compressed_cosine_equals_lifted_cosine() {
        let (d, n, classes) = (12, 64, 5);
        let mut s = 7u64;
        let samples: Vec<f32> = (0..n * d)
            .map(|i| lcg(&mut s) + 0.3 * (i % d) as f32 / d as f32)
            .collect();
        let pca = PcaBasis::fit(&samples, d, PcaSetting::Components(4)).unwrap();
        let text: Vec<f32> = (0..classes * d).map(|_| lcg(&mut s)).collect();
        let scorer = ClassScorer::new(&text, d, Some(&pca)).unwrap();
        assert_eq!(scorer.dim, 4);
        for _ in 0..20 {
            let c: Vec<f32> = (0..4).map(|_| 2.0 * lcg(&mut s)).collect();
            let f = pca.lift(&c);
            let fnorm = f.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
            let mut got = vec![0.0; classes];
            scorer.cosines(&c, &mut got);
            for j in 0..classes {
                let t = &text[j * d..(j + 1) * d];
                let tn = t.iter().map(|&x| (x as f64).powi(2)).sum::<f64>().sqrt();
                let want = f
                    .iter()
                    .zip(t)
                    .map(|(&a, &b)| a as f64 * b as f64)
                    .sum::<f64>()
                    / (fnorm * tn);
                assert!(
                    (got[j] - want).abs() < 1e-5,
                    "class {j}: {} vs {want}",
                    got[j]
                );
            }
        }
    }

    #[test]
    fn uncompressed_cosine_and_argmax() {
        let text = [1.0, 0.0, 0.0, 0.0, 2.0, 0.0];
        let s = ClassScorer::new(&text, 3, None).unwrap();
        let mut out = [0.0; 2];
        s.cosines(&[1.0, 1.0, 0.0], &mut out);
        let h = 1.0 / 2f64.sqrt();
        assert!((out[0] - h).abs() < 1e-12 && (out[1] - h).abs() < 1e-12);
        assert_eq!(s.argmax(&[0.1, 3.0, 1.0]), 1);
        s.cosines(&[0.0; 3], &mut out);
        assert_eq!(out, [0.0, 0.0]);
        assert!(ClassScorer::new(&text, 4, None).is_err());
    }
}
