//! Depth of one camera carried into another that shares its centre and
//! axes (ScanNet's depth and colour cameras: the export's depth-to-colour
//! extrinsics are the identity), by splatting each depth pixel's footprint.

use model::geometry::Intrinsics;

use crate::scene::DepthImage;

/// The colour pixels `[first, end)` along one axis whose centres lie in
/// `[lo, hi)`, clipped to `0..size`.
fn covered(lo: f64, hi: f64, size: u32) -> (u32, u32) {
    let clip = |v: f64| v.ceil().clamp(0.0, size as f64) as u32;
    (clip(lo), clip(hi))
}

/// The depth of `depth` (z-depth in the camera of `depth_k`) seen by the
/// camera of `colour_k` at the same place: every valid depth pixel is
/// back-projected at its depth, its four corners are projected into the
/// colour image, and every colour pixel whose centre lies in that
/// footprint takes the depth, the nearest one where footprints overlap.
/// The footprints of neighbouring pixels tile the image, so the colour
/// image has no holes where the depth camera sees (upsampling included);
/// colour pixels outside its view, or under invalid (0) depth, stay 0. No
/// hole is filled by guessing.
pub fn reproject_depth(
    depth: &DepthImage,
    depth_k: &Intrinsics,
    colour_k: &Intrinsics,
) -> DepthImage {
    let (w, h) = (colour_k.width, colour_k.height);
    let mut out = vec![f32::INFINITY; w as usize * h as usize];
    // The corners of depth pixel (x, y) on the colour image. With a shared
    // centre the depth cancels: the map is the same for every depth.
    let corner = |u: f64, v: f64| {
        let d = depth_k.camera_direction(u, v);
        colour_k.image_point(d[0] / d[2], d[1] / d[2])
    };
    for y in 0..depth.height {
        for x in 0..depth.width {
            let z = depth.get(x, y);
            if !(z > 0.0 && z.is_finite()) {
                continue;
            }
            let (xf, yf) = (x as f64, y as f64);
            let corners = [
                corner(xf - 0.5, yf - 0.5),
                corner(xf + 0.5, yf - 0.5),
                corner(xf - 0.5, yf + 0.5),
                corner(xf + 0.5, yf + 0.5),
            ];
            let (u0, u1) = extent(corners.iter().map(|c| c.0));
            let (v0, v1) = extent(corners.iter().map(|c| c.1));
            let (xa, xb) = covered(u0, u1, w);
            let (ya, yb) = covered(v0, v1, h);
            for cy in ya..yb {
                let row = cy as usize * w as usize;
                for cx in xa..xb {
                    let slot = &mut out[row + cx as usize];
                    *slot = slot.min(z);
                }
            }
        }
    }
    DepthImage {
        width: w,
        height: h,
        data: crate::scene::DepthData::F32(
            out.into_iter()
                .map(|d| if d.is_finite() { d } else { 0.0 })
                .collect(),
        ),
    }
}

/// `(min, max)` of the values.
fn extent(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::Distortion;

    fn k(width: u32, height: u32, f: f64, cx: f64, cy: f64) -> Intrinsics {
        Intrinsics {
            width,
            height,
            fx: f,
            fy: f,
            cx,
            cy,
            distortion: Distortion::NONE,
        }
    }

    /// Upsampling by 2 fills 2x2 blocks; pixels outside the depth camera's
    /// view, or under invalid depth, stay 0.
    #[test]
    fn footprints_tile_and_keep_the_nearest() {
        let dk = k(2, 2, 1.0, 0.5, 0.5);
        let ck = dk.scaled(4, 4);
        let depth = DepthImage {
            width: 2,
            height: 2,
            data: crate::scene::DepthData::F32(vec![1.0, 2.0, 3.0, 0.0]),
        };
        let out = reproject_depth(&depth, &dk, &ck);
        #[rustfmt::skip]
        let want = vec![
            1.0, 1.0, 2.0, 2.0,
            1.0, 1.0, 2.0, 2.0,
            3.0, 3.0, 0.0, 0.0,
            3.0, 3.0, 0.0, 0.0,
        ];
        assert_eq!(out.to_f32(), want);
        // A colour camera with twice the field of view: the depth covers its
        // central half only, and each colour pixel centre lies in exactly
        // one depth footprint (half-open: a centre on an edge belongs to the
        // footprint on its right / below).
        let wide = k(4, 4, 0.5, 1.5, 1.5);
        let fine = DepthImage {
            width: 4,
            height: 4,
            data: crate::scene::DepthData::F32((0..16).map(|i| 1.0 + i as f32).collect()),
        };
        let out = reproject_depth(&fine, &k(4, 4, 1.0, 1.5, 1.5), &wide);
        #[rustfmt::skip]
        let want = vec![
            0.0, 0.0, 0.0, 0.0,
            0.0, 6.0, 8.0, 0.0,
            0.0, 14.0, 16.0, 0.0,
            0.0, 0.0, 0.0, 0.0,
        ];
        assert_eq!(out.to_f32(), want);
    }
}
