//! Resampling as PyTorch does it, as separable weight matrices: bicubic
//! (`F.interpolate(mode="bicubic", align_corners=False)`, how the dense-CLIP
//! methods stretch a ViT's position embeddings to another patch grid) and
//! antialiased bilinear (`mode="bilinear", antialias=True`, how images are
//! resized before feature extraction). One output row of a matrix holds the
//! weights of every input sample; rows sum to one.

/// PyTorch's cubic convolution constant.
const CUBIC_A: f64 = -0.75;

fn cubic_near(x: f64) -> f64 {
    ((CUBIC_A + 2.0) * x - (CUBIC_A + 3.0)) * x * x + 1.0
}

fn cubic_far(x: f64) -> f64 {
    ((CUBIC_A * x - 5.0 * CUBIC_A) * x + 8.0 * CUBIC_A) * x - 4.0 * CUBIC_A
}

/// Bicubic weights from `n_in` samples to `n_out`, `[n_out, n_in]`
/// row-major. Sample `i` of the output sits at `(i + 0.5) * n_in / n_out -
/// 0.5` in input units; the four neighbours' indices are clamped to the
/// edge, so an edge sample takes the weight of the ones beyond it.
pub fn bicubic_weights(n_in: usize, n_out: usize) -> Vec<f32> {
    let mut w = vec![0f64; n_in * n_out];
    let scale = n_in as f64 / n_out as f64;
    for i in 0..n_out {
        let src = (i as f64 + 0.5) * scale - 0.5;
        let base = src.floor();
        let t = src - base;
        let coeffs = [
            cubic_far(t + 1.0),
            cubic_near(t),
            cubic_near(1.0 - t),
            cubic_far(2.0 - t),
        ];
        for (k, c) in coeffs.iter().enumerate() {
            let j = (base as i64 - 1 + k as i64).clamp(0, n_in as i64 - 1) as usize;
            w[i * n_in + j] += c;
        }
    }
    w.into_iter().map(|v| v as f32).collect()
}

/// Antialiased bilinear weights from `n_in` samples to `n_out`, `[n_out,
/// n_in]` row-major: a triangle filter as wide as one output sample when
/// shrinking (so every input sample counts), plain linear interpolation
/// when growing; weights that fall outside the input are dropped and the
/// rest renormalised.
pub fn antialiased_bilinear_weights(n_in: usize, n_out: usize) -> Vec<f32> {
    let mut w = vec![0f64; n_in * n_out];
    let scale = n_in as f64 / n_out as f64;
    let (support, inv) = if scale >= 1.0 {
        (scale, 1.0 / scale)
    } else {
        (1.0, 1.0)
    };
    for i in 0..n_out {
        let center = scale * (i as f64 + 0.5);
        // PyTorch truncates towards zero here.
        let lo = ((center - support + 0.5) as i64).max(0) as usize;
        let hi = ((center + support + 0.5) as i64).min(n_in as i64) as usize;
        let row = &mut w[i * n_in..(i + 1) * n_in];
        let mut total = 0.0;
        for (j, r) in row.iter_mut().enumerate().take(hi).skip(lo) {
            let x = ((j as f64 - center + 0.5) * inv).abs();
            *r = (1.0 - x).max(0.0);
            total += *r;
        }
        if total > 0.0 {
            row.iter_mut().for_each(|r| *r /= total);
        }
    }
    w.into_iter().map(|v| v as f32).collect()
}

/// Applies separable weights to a channel-first image: `rows` is `[h_out,
/// h_in]`, `cols` `[w_out, w_in]`.
///
/// # Shapes
/// - `chw`: `[c, h_in, w_in]`; output: `[c, h_out, w_out]`.
pub fn resample_chw(
    chw: &[f32],
    c: usize,
    (h_in, w_in): (usize, usize),
    (h_out, w_out): (usize, usize),
    rows: &[f32],
    cols: &[f32],
) -> Vec<f32> {
    debug_assert_eq!(chw.len(), c * h_in * w_in);
    // Columns first (every input row), then rows. Each output column reads
    // only the span of its non-zero weights (a few taps of a wide row).
    let spans: Vec<(usize, usize)> = cols
        .chunks_exact(w_in)
        .map(|row| {
            let lo = row.iter().position(|w| *w != 0.0).unwrap_or(0);
            let hi = row.iter().rposition(|w| *w != 0.0).map_or(lo, |i| i + 1);
            (lo, hi)
        })
        .collect();
    let mut wide = vec![0f32; c * h_in * w_out];
    for (src, dst) in chw.chunks_exact(w_in).zip(wide.chunks_exact_mut(w_out)) {
        for (x, (d, &(lo, hi))) in dst.iter_mut().zip(&spans).enumerate() {
            let weights = &cols[x * w_in + lo..x * w_in + hi];
            *d = weights.iter().zip(&src[lo..hi]).map(|(w, s)| w * s).sum();
        }
    }
    let mut out = vec![0f32; c * h_out * w_out];
    for ch in 0..c {
        let plane = &wide[ch * h_in * w_out..(ch + 1) * h_in * w_out];
        for y in 0..h_out {
            let dst = &mut out[(ch * h_out + y) * w_out..(ch * h_out + y + 1) * w_out];
            for (yi, &w) in rows[y * h_in..(y + 1) * h_in].iter().enumerate() {
                if w != 0.0 {
                    let src = &plane[yi * w_out..(yi + 1) * w_out];
                    dst.iter_mut().zip(src).for_each(|(d, s)| *d += w * s);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows_sum_to_one(w: &[f32], n_in: usize) {
        for (i, row) in w.chunks(n_in).enumerate() {
            let s: f32 = row.iter().sum();
            assert!((s - 1.0).abs() < 1e-6, "row {i} sums to {s}");
        }
    }

    #[test]
    fn same_size_is_the_identity() {
        for n in [1, 4, 7] {
            for w in [bicubic_weights(n, n), antialiased_bilinear_weights(n, n)] {
                for i in 0..n {
                    for j in 0..n {
                        assert_eq!(w[i * n + j], f32::from(u8::from(i == j)), "{n}: {i},{j}");
                    }
                }
            }
        }
    }

    #[test]
    fn bicubic_has_pytorchs_taps() {
        let (n_in, n_out) = (4, 11);
        rows_sum_to_one(&bicubic_weights(n_in, n_out), n_in);
        // Halving puts output 1 at input 2.5: the A = -0.75 kernel at t = 0.5.
        let w = bicubic_weights(8, 4);
        rows_sum_to_one(&w, 8);
        let want = [-0.09375, 0.59375, 0.59375, -0.09375];
        for (k, v) in want.iter().enumerate() {
            assert!((w[8 + 1 + k] - v).abs() < 1e-7, "{k}: {:?}", &w[8..16]);
        }
        // Output 0 sits at 0.5: its tap at -1 is clamped onto sample 0.
        assert!((w[0] - (0.59375 - 0.09375)).abs() < 1e-7);
        // At t = 0.25 (doubling): the kernel's values there.
        let w = bicubic_weights(4, 8);
        let t: f64 = 0.25;
        let a = -0.75;
        let near = |x: f64| ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0;
        let far = |x: f64| ((a * x - 5.0 * a) * x + 8.0 * a) * x - 4.0 * a;
        let want = [far(1.0 + t), near(t), near(1.0 - t), far(2.0 - t)];
        // Output 3 sits at 1.25: taps 0..=3.
        for (k, v) in want.iter().enumerate() {
            assert!((w[3 * 4 + k] as f64 - v).abs() < 1e-7);
        }
    }

    #[test]
    fn antialiased_halving_is_the_one_three_three_one_filter() {
        let w = antialiased_bilinear_weights(12, 6);
        rows_sum_to_one(&w, 12);
        for i in 1..5 {
            let row = &w[i * 12..(i + 1) * 12];
            let want = [0.125, 0.375, 0.375, 0.125];
            for (k, v) in want.iter().enumerate() {
                assert!((row[2 * i - 1 + k] - v).abs() < 1e-6, "{i} {k}: {row:?}");
            }
            assert!(row.iter().filter(|x| **x != 0.0).count() == 4);
        }
        // The first output loses its out-of-image tap and renormalises.
        assert!((w[0] - 3.0 / 7.0).abs() < 1e-6 && (w[2] - 1.0 / 7.0).abs() < 1e-6);
    }

    #[test]
    fn growing_is_linear_interpolation_between_neighbours() {
        let (n_in, n_out) = (5, 13);
        let w = antialiased_bilinear_weights(n_in, n_out);
        rows_sum_to_one(&w, n_in);
        let scale = n_in as f64 / n_out as f64;
        for i in 0..n_out {
            let src = (i as f64 + 0.5) * scale - 0.5;
            if src >= 0.0 && src <= (n_in - 1) as f64 {
                let got: f64 = (0..n_in).map(|j| w[i * n_in + j] as f64 * j as f64).sum();
                assert!((got - src).abs() < 1e-5, "{i}: {got} vs {src}");
            }
        }
    }

    #[test]
    fn separable_resampling_applies_both_matrices() {
        // 1 channel, 2x3 -> 4x6 by the weights, against a direct double sum.
        let img: Vec<f32> = (0..6).map(|v| v as f32 * 0.7 - 1.0).collect();
        let (rows, cols) = (bicubic_weights(2, 4), bicubic_weights(3, 6));
        let out = resample_chw(&img, 1, (2, 3), (4, 6), &rows, &cols);
        for y in 0..4 {
            for x in 0..6 {
                let mut want = 0.0;
                for yi in 0..2 {
                    for xi in 0..3 {
                        want += rows[y * 2 + yi] * cols[x * 3 + xi] * img[yi * 3 + xi];
                    }
                }
                assert!((out[y * 6 + x] - want).abs() < 1e-5);
            }
        }
    }
}
