//! Sliding windows over an image of any size: the resized size, the window
//! origins and the averaging of overlapping windows' feature grids.

/// Where the windows of one image go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WindowPlan {
    /// The image's size after resizing, `(height, width)`, whole patches.
    pub resized: (usize, usize),
    /// Patch grid of the resized image, `(rows, cols)`.
    pub grid: (usize, usize),
    /// Window side in pixels (the model's input size).
    pub crop: usize,
    /// Step between windows in pixels (whole patches).
    pub stride: usize,
    /// Top-left corners `(y, x)` in pixels, rows outer.
    pub origins: Vec<(usize, usize)>,
    /// Patch size in pixels.
    pub patch: usize,
}

/// `v` rounded to the nearest whole number of patches, at least one.
fn round_to_patch(v: f64, patch: usize) -> usize {
    (((v / patch as f64) + 0.5).floor() as usize).max(1) * patch
}

/// Window origins along one axis of `len` pixels: every `stride`, the last
/// one moved back to end at the edge.
fn origins_1d(len: usize, crop: usize, stride: usize) -> Vec<usize> {
    let n = (len - crop).div_ceil(stride) + 1;
    (0..n).map(|k| (k * stride).min(len - crop)).collect()
}

/// The plan for a `height x width` image whose short side is resized to
/// `short_side` (both sides then rounded to whole patches), covered by
/// `crop`-pixel windows every half window (in whole patches).
///
/// Errors (as text for the caller to place) when the image is smaller than
/// a patch, or the short side smaller than one window.
pub fn plan_windows(
    (height, width): (usize, usize),
    short_side: usize,
    crop: usize,
    patch: usize,
) -> Result<WindowPlan, String> {
    if patch == 0 || crop == 0 || !crop.is_multiple_of(patch) {
        return Err(format!(
            "window {crop} px is not a whole number of {patch}-px patches"
        ));
    }
    if height < patch || width < patch {
        return Err(format!(
            "a {width}x{height} image is smaller than one {patch}-px patch"
        ));
    }
    if short_side < crop {
        return Err(format!(
            "the short side {short_side} px is smaller than the model's {crop}-px input"
        ));
    }
    let s = short_side as f64 / height.min(width) as f64;
    let resized = (
        round_to_patch(height as f64 * s, patch).max(crop),
        round_to_patch(width as f64 * s, patch).max(crop),
    );
    let stride = patch * (crop / patch / 2).max(1);
    let ys = origins_1d(resized.0, crop, stride);
    let xs = origins_1d(resized.1, crop, stride);
    let origins = ys
        .iter()
        .flat_map(|&y| xs.iter().map(move |&x| (y, x)))
        .collect();
    Ok(WindowPlan {
        resized,
        grid: (resized.0 / patch, resized.1 / patch),
        crop,
        stride,
        origins,
        patch,
    })
}

impl WindowPlan {
    /// Patches along a window's side.
    pub fn window_grid(&self) -> usize {
        self.crop / self.patch
    }

    /// The global grid from every window's features (`[windows, g, g, d]`
    /// row-major, `g` the window grid): each cell the mean of the windows
    /// covering it, scaled to unit length.
    ///
    /// # Shapes
    /// - `windows`: `[origins.len() * g * g * d]`; output: `[rows * cols * d]`.
    pub fn assemble(&self, windows: &[f32], d: usize) -> Vec<f32> {
        let g = self.window_grid();
        let (rows, cols) = self.grid;
        let mut sum = vec![0f32; rows * cols * d];
        let mut count = vec![0u32; rows * cols];
        for (w, &(y0, x0)) in self.origins.iter().enumerate() {
            let (py, px) = (y0 / self.patch, x0 / self.patch);
            for gy in 0..g {
                for gx in 0..g {
                    let cell = (py + gy) * cols + px + gx;
                    let src = ((w * g + gy) * g + gx) * d;
                    count[cell] += 1;
                    sum[cell * d..(cell + 1) * d]
                        .iter_mut()
                        .zip(&windows[src..src + d])
                        .for_each(|(s, v)| *s += v);
                }
            }
        }
        for v in sum.chunks_exact_mut(d.max(1)) {
            let norm = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            if norm > 0.0 {
                v.iter_mut().for_each(|x| *x /= norm);
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wide_frame_is_covered_by_whole_windows() {
        // 640x360 at short side 336 with ViT-B/16's 224-px input.
        let p = plan_windows((360, 640), 336, 224, 16).unwrap();
        assert_eq!(p.resized, (336, 592));
        assert_eq!(p.grid, (21, 37));
        assert_eq!(p.stride, 112);
        assert_eq!(p.origins.len(), 2 * 5);
        assert_eq!(p.origins[4], (0, 368));
        assert_eq!(p.origins[9], (112, 368));
        // Every cell is covered, every window inside the image.
        let mut covered = vec![false; 21 * 37];
        for &(y, x) in &p.origins {
            assert!(y + 224 <= 336 && x + 224 <= 592);
            assert!(y % 16 == 0 && x % 16 == 0);
            for gy in 0..14 {
                for gx in 0..14 {
                    covered[(y / 16 + gy) * 37 + x / 16 + gx] = true;
                }
            }
        }
        assert!(covered.iter().all(|c| *c));
        // ViT-B/32: the stride stays whole patches.
        assert_eq!(plan_windows((360, 640), 336, 224, 32).unwrap().stride, 96);
    }

    #[test]
    fn bad_sizes_are_refused_with_the_reason() {
        assert!(
            plan_windows((7, 40), 48, 32, 8)
                .unwrap_err()
                .contains("smaller than one 8-px patch")
        );
        assert!(
            plan_windows((40, 40), 24, 32, 8)
                .unwrap_err()
                .contains("smaller than the model's")
        );
        assert!(
            plan_windows((40, 40), 48, 30, 8)
                .unwrap_err()
                .contains("whole number")
        );
        // Exactly one window when the resized image is the window.
        let p = plan_windows((50, 50), 32, 32, 8).unwrap();
        assert_eq!(p.origins, vec![(0, 0)]);
    }

    #[test]
    fn overlapping_windows_are_averaged_then_normalised() {
        // A 1x3-patch image... made of two 1x2-patch windows? Windows are
        // square: use 2x3 patches of 1 px, crop 2, stride 1.
        let p = WindowPlan {
            resized: (2, 3),
            grid: (2, 3),
            crop: 2,
            stride: 1,
            origins: vec![(0, 0), (0, 1)],
            patch: 1,
        };
        // d = 2; window 0 all (1, 0); window 1 all (0, 1).
        let mut w = vec![];
        for _ in 0..4 {
            w.extend([1.0, 0.0]);
        }
        for _ in 0..4 {
            w.extend([0.0, 1.0]);
        }
        let out = p.assemble(&w, 2);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let want = [1.0, 0.0, h, h, 0.0, 1.0];
        for row in 0..2 {
            for (i, v) in want.iter().enumerate() {
                assert!((out[row * 6 + i] - v).abs() < 1e-6, "{out:?}");
            }
        }
    }
}
