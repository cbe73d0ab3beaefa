//! Plain image and feature metrics shared by training and evaluation.

/// PSNR in dB of a mean squared error of colours in `[0, 1]`.
pub fn psnr(mse: f64) -> f64 {
    -10.0 * mse.max(1e-20).log10()
}

/// Cosine similarity of two vectors; 0 when either has (near) zero norm.
pub fn cosine(a: &[f32], b: &[f32]) -> f64 {
    let (mut ab, mut aa, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x as f64, y as f64);
        ab += x * y;
        aa += x * x;
        bb += y * y;
    }
    if aa <= 1e-24 || bb <= 1e-24 {
        0.0
    } else {
        ab / (aa.sqrt() * bb.sqrt())
    }
}
