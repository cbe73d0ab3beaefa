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
