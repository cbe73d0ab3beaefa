//! Lifting the class text embeddings into a wider feature space, so the
//! synthetic room can stand in for scenes whose VLM features are wider than
//! the CLIP text embeddings it is built from (768-D at the paper's scale).
//!
//! The lift is `x -> Q x` with `Q` a fixed, seeded `D_out x D_in` matrix with
//! orthonormal columns: `Q^T Q = I`, so every inner product, norm and cosine
//! between lifted embeddings is that of the originals, and the room's classes
//! are exactly as (dis)similar as before.

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::DatasetError;
use crate::text::TextEmbeddings;

/// Seed of the lift matrix used by the synthetic scene.
pub const LIFT_SEED: u64 = 0x11f7_0768;

/// A `rows x cols` matrix (row-major, f64) with orthonormal columns: the
/// `Q` factor of the QR decomposition of a seeded Gaussian matrix.
///
/// # Shapes
/// `-> [rows, cols]`, `rows >= cols`.
pub fn orthonormal_columns(rows: usize, cols: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let gauss = DMatrix::<f64>::from_fn(rows, cols, |_, _| {
        // Box-Muller: a rotation-invariant draw, so the span is uniform.
        let u: f64 = rng.random_range(f64::EPSILON..1.0);
        let v: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    });
    let q = gauss.qr().q();
    let mut out = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        out.extend((0..cols).map(|c| q[(r, c)]));
    }
    out
}

/// `embeddings` (`C x D_in`) mapped to `C x dim` by the seeded matrix with
/// orthonormal columns ([`orthonormal_columns`]), computed in f64: inner
/// products and cosines between rows are preserved up to f32 rounding.
///
/// # Errors
/// When `dim` is smaller than the embeddings' dimension (no such matrix).
pub fn lift_embeddings(
    embeddings: &TextEmbeddings,
    dim: usize,
    seed: u64,
) -> Result<TextEmbeddings, DatasetError> {
    let d_in = embeddings.dim;
    if dim < d_in || d_in == 0 {
        return Err(DatasetError::invalid(
            "<class embeddings>",
            format!("cannot lift {d_in}-D embeddings to {dim} dimensions"),
        ));
    }
    let q = orthonormal_columns(dim, d_in, seed);
    let mut data = Vec::with_capacity(embeddings.len() * dim);
    for row in embeddings.data.chunks_exact(d_in) {
        data.extend(q.chunks_exact(d_in).map(|q_row| {
            q_row
                .iter()
                .zip(row)
                .map(|(&a, &b)| a * b as f64)
                .sum::<f64>() as f32
        }));
    }
    Ok(TextEmbeddings {
        names: embeddings.names.clone(),
        dim,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot64(a: &[f32], b: &[f32]) -> f64 {
        a.iter().zip(b).map(|(&x, &y)| x as f64 * y as f64).sum()
    }

    #[test]
    fn columns_are_orthonormal() {
        let (rows, cols) = (40, 24);
        let q = orthonormal_columns(rows, cols, 7);
        for i in 0..cols {
            for j in 0..cols {
                let d: f64 = (0..rows).map(|r| q[r * cols + i] * q[r * cols + j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((d - want).abs() < 1e-12, "column {i}.{j}: {d}");
            }
        }
        assert_eq!(q, orthonormal_columns(rows, cols, 7), "seeded");
    }

    #[test]
    fn lift_preserves_norms_and_cosines() {
        let e = crate::synthetic::classes::fallback_embeddings();
        let lifted = lift_embeddings(&e, 768, LIFT_SEED).expect("lift");
        assert_eq!((lifted.dim, lifted.len()), (768, e.len()));
        assert_eq!(lifted.names, e.names);
        for i in 0..e.len() {
            let (a, la) = (e.row(i), lifted.row(i));
            let (n, ln) = (dot64(a, a).sqrt(), dot64(la, la).sqrt());
            assert!((n - ln).abs() < 1e-5, "norm of {i}: {n} vs {ln}");
            for j in 0..e.len() {
                let (b, lb) = (e.row(j), lifted.row(j));
                let cos = dot64(a, b) / (n * dot64(b, b).sqrt());
                let lcos = dot64(la, lb) / (ln * dot64(lb, lb).sqrt());
                assert!((cos - lcos).abs() < 1e-5, "cosine {i}.{j}: {cos} vs {lcos}");
            }
        }
        assert!(lift_embeddings(&e, 100, LIFT_SEED).is_err());
    }
}
