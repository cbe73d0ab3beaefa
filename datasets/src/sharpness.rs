//! How sharp a photograph is: the variance of the Laplacian of its
//! luminance (Pech-Pacheco et al., "Diatom autofocusing in brightfield
//! microscopy", 2000), the measure frame pickers use to drop the blurred
//! frames of a hand-held video: blur removes the high frequencies the
//! Laplacian responds to.

use image::DynamicImage;

/// The variance of the 4-neighbour Laplacian over the interior pixels of
/// a `width x height` luminance image (row-major); 0 for an image with no
/// interior pixel.
///
/// # Shapes
/// `luma`: `[height * width]`.
pub fn laplacian_variance(luma: &[f32], width: usize, height: usize) -> f64 {
    if width < 3 || height < 3 || luma.len() < width * height {
        return 0.0;
    }
    let (mut sum, mut sum_sq, mut n) = (0f64, 0f64, 0f64);
    for y in 1..height - 1 {
        let row = y * width;
        for x in 1..width - 1 {
            let i = row + x;
            let l = f64::from(luma[i - 1] + luma[i + 1] + luma[i - width] + luma[i + width])
                - 4.0 * f64::from(luma[i]);
            sum += l;
            sum_sq += l * l;
            n += 1.0;
        }
    }
    let mean = sum / n;
    (sum_sq / n - mean * mean).max(0.0)
}

/// The sharpness of the image file at `path` ([`image_sharpness`]).
pub fn file_sharpness(path: &std::path::Path) -> Result<f64, crate::DatasetError> {
    Ok(image_sharpness(&crate::imageio::open(path)?))
}

/// The sharpness of an image: [`laplacian_variance`] of its 8-bit
/// luminance (in grey levels, 0 to 255).
pub fn image_sharpness(img: &DynamicImage) -> f64 {
    let luma = img.to_luma8();
    let (w, h) = (luma.width() as usize, luma.height() as usize);
    let values: Vec<f32> = luma.into_raw().into_iter().map(f32::from).collect();
    laplacian_variance(&values, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_and_linear_images_have_no_sharpness() {
        let flat = vec![0.3f32; 8 * 6];
        assert_eq!(laplacian_variance(&flat, 8, 6), 0.0);
        // A plane's Laplacian is 0 everywhere.
        let ramp: Vec<f32> = (0..8 * 6)
            .map(|i| 0.5 * (i % 8) as f32 + 0.25 * (i / 8) as f32)
            .collect();
        assert!(laplacian_variance(&ramp, 8, 6) < 1e-9);
        assert_eq!(laplacian_variance(&[1.0; 4], 2, 2), 0.0);
    }

    #[test]
    fn a_checkerboard_has_the_variance_worked_out_by_hand() {
        // 0/1 checkerboard: an interior 1 has four 0 neighbours (Laplacian
        // -4), an interior 0 four 1 neighbours (+4): mean 0, variance 16
        // when the interior has as many of each.
        let (w, h) = (6, 6);
        let board: Vec<f32> = (0..w * h).map(|i| ((i % w + i / w) % 2) as f32).collect();
        assert!((laplacian_variance(&board, w, h) - 16.0).abs() < 1e-12);
    }

    #[test]
    fn blurring_lowers_the_sharpness() {
        let (w, h) = (32usize, 24usize);
        let mut state = 12345u64;
        let noise: Vec<f32> = (0..w * h)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 40) as f32 / (1u64 << 24) as f32
            })
            .collect();
        let blurred: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut s = 0.0;
                for dy in 0..3 {
                    for dx in 0..3 {
                        let xx = (x + dx).saturating_sub(1).min(w - 1);
                        let yy = (y + dy).saturating_sub(1).min(h - 1);
                        s += noise[yy * w + xx];
                    }
                }
                s / 9.0
            })
            .collect();
        let (sharp, soft) = (
            laplacian_variance(&noise, w, h),
            laplacian_variance(&blurred, w, h),
        );
        assert!(soft < sharp / 4.0, "{soft} vs {sharp}");
    }
}
