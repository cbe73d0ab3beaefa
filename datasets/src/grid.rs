//! Mapping between pixel grids that cover the same image at different
//! resolutions (images, depth maps, feature maps, label maps).

/// The pixel of a `to_width x to_height` grid nearest to point `(u, v)` of
/// a `from_width x from_height` grid covering the same image (pixel centres
/// at integers in both), clamped to the grid. With `(u, v)` a pixel of the
/// first grid, it is the pixel of the second under that pixel's centre.
pub fn nearest_pixel(
    u: f64,
    v: f64,
    (from_width, from_height): (u32, u32),
    (to_width, to_height): (u32, u32),
) -> (u32, u32) {
    let sx = to_width as f64 / from_width as f64;
    let sy = to_height as f64 / from_height as f64;
    let x = (((u + 0.5) * sx).floor().max(0.0) as u32).min(to_width.saturating_sub(1));
    let y = (((v + 0.5) * sy).floor().max(0.0) as u32).min(to_height.saturating_sub(1));
    (x, y)
}

/// Whether grids of sizes `a` and `b` can cover the same image: scaling
/// either to the other's width gives its height to within one pixel (so a
/// downscale that rounded an odd side still counts).
pub fn same_aspect(a: (u32, u32), b: (u32, u32)) -> bool {
    let close = |(w0, h0): (u32, u32), (w1, h1): (u32, u32)| {
        (h0 as f64 * w1 as f64 / w0 as f64 - h1 as f64).abs() <= 1.0
    };
    a.0 > 0 && a.1 > 0 && b.0 > 0 && b.1 > 0 && close(a, b) && close(b, a)
}

/// Resamples a row-major `from` grid to `to` by nearest pixel
/// ([`nearest_pixel`]): every pixel of the result takes the value under its
/// centre (nothing is averaged, so depths and masks keep their values).
pub fn resample_nearest<T: Copy>(data: &[T], from: (u32, u32), to: (u32, u32)) -> Vec<T> {
    if from == to {
        return data.to_vec();
    }
    let mut out = Vec::with_capacity(to.0 as usize * to.1 as usize);
    for y in 0..to.1 {
        for x in 0..to.0 {
            let (sx, sy) = nearest_pixel(x as f64, y as f64, to, from);
            out.push(data[sy as usize * from.0 as usize + sx as usize]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aspect_allows_rounded_sides_only() {
        assert!(same_aspect((801, 601), (400, 300)));
        assert!(same_aspect((640, 480), (1296, 972)));
        assert!(!same_aspect((640, 480), (640, 360)));
        assert!(!same_aspect((640, 480), (0, 0)));
    }

    #[test]
    fn nearest_resampling_repeats_and_picks_values() {
        let up = resample_nearest(&[1, 2, 3, 4], (2, 2), (4, 2));
        assert_eq!(up, vec![1, 1, 2, 2, 3, 3, 4, 4]);
        let down = resample_nearest(&[1, 2, 3, 4, 5, 6, 7, 8], (4, 2), (2, 1));
        // Centre of output pixel 0 lies over input pixel 1 (x) of row 1.
        assert_eq!(down, vec![6, 8]);
    }
}
