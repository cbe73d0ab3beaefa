//! Depth a person can read: rendered depth coloured over a robust range of
//! the opaque pixels (the 2nd to 98th percentile), in disparity for an
//! unbounded field (whose far samples reach thousands of scene radii, as
//! Mip-NeRF 360's figures show it) and in metres for a box field, near red
//! and far blue in both; the range and units go with the image.

use serde::{Deserialize, Serialize};

use crate::colormap::{to_u8, turbo};

/// Pixels with an accumulated opacity above this are coloured; the rest
/// (rays that crossed nothing) are black.
pub const OPACITY_THRESHOLD: f32 = 0.5;
/// The percentiles of the opaque pixels' values that span the colours.
pub const PERCENTILES: [f64; 2] = [2.0, 98.0];

/// What the colours of a depth image stand for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthQuantity {
    /// Z-depth in metres (a box field).
    Depth,
    /// One over the z-depth, per metre (an unbounded field).
    Disparity,
}

impl DepthQuantity {
    /// Disparity for an unbounded field, depth for a box field.
    pub fn of(model: &model::OpenNerf) -> Self {
        if model.extent.is_unbounded() {
            DepthQuantity::Disparity
        } else {
            DepthQuantity::Depth
        }
    }

    /// Units of the quantity.
    pub fn units(self) -> &'static str {
        match self {
            DepthQuantity::Depth => "m",
            DepthQuantity::Disparity => "1/m",
        }
    }

    /// The quantity at z-depth `depth`; `None` where it has none (a
    /// non-finite depth, or a depth at or behind the camera for disparity).
    pub fn value(self, depth: f32) -> Option<f32> {
        match self {
            DepthQuantity::Depth if depth.is_finite() => Some(depth),
            DepthQuantity::Disparity if depth.is_finite() && depth > 0.0 => Some(1.0 / depth),
            _ => None,
        }
    }
}

/// The colour scale of one depth image, written beside it as JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DepthScale {
    /// What the colours stand for.
    pub quantity: DepthQuantity,
    /// Units of `lo` and `hi`.
    pub units: String,
    /// The quantity at the low percentile (blue for depth, the far end).
    pub lo: f32,
    /// The quantity at the high percentile.
    pub hi: f32,
    /// The nearest depth the colours tell apart, metres (red).
    pub near_m: f32,
    /// The farthest depth the colours tell apart, metres (blue).
    pub far_m: f32,
    /// The percentiles `lo` and `hi` are at.
    pub percentiles: [f64; 2],
    /// Pixels whose opacity is above [`OPACITY_THRESHOLD`] and whose value
    /// the range was taken from.
    pub opaque_pixels: usize,
    /// Opacity at or below which a pixel is black.
    pub opacity_threshold: f32,
    /// How to read the colours.
    pub colours: String,
}

impl DepthScale {
    /// The scale of a `depth` image with opacities `acc` (empty or shorter:
    /// every pixel opaque).
    pub fn of(depth: &[f32], acc: &[f32], quantity: DepthQuantity) -> Self {
        let mut values: Vec<f32> = (0..depth.len())
            .filter(|&i| opaque(acc, i))
            .filter_map(|i| quantity.value(depth[i]))
            .collect();
        values.sort_by(f32::total_cmp);
        let (lo, hi) = match values.len() {
            0 => (0.0, 0.0),
            _ => (
                percentile(&values, PERCENTILES[0]),
                percentile(&values, PERCENTILES[1]),
            ),
        };
        // Every disparity taken is positive; 0 stands for an image without
        // an opaque pixel (and keeps the JSON free of infinities).
        let metres = |v: f32| match quantity {
            DepthQuantity::Depth => v,
            DepthQuantity::Disparity if v > 0.0 => 1.0 / v,
            DepthQuantity::Disparity => 0.0,
        };
        let (near_m, far_m) = match quantity {
            DepthQuantity::Depth => (metres(lo), metres(hi)),
            DepthQuantity::Disparity => (metres(hi), metres(lo)),
        };
        DepthScale {
            quantity,
            units: quantity.units().to_string(),
            lo,
            hi,
            near_m,
            far_m,
            percentiles: PERCENTILES,
            opaque_pixels: values.len(),
            opacity_threshold: OPACITY_THRESHOLD,
            colours: format!(
                "Turbo: near red, far blue, clamped to the range; opacity at or below \
                 {OPACITY_THRESHOLD} black"
            ),
        }
    }

    /// Where on the colour scale (0 far/blue, 1 near/red) z-depth `depth`
    /// falls; `None` where the quantity has no value.
    pub fn position(&self, depth: f32) -> Option<f32> {
        let v = self.quantity.value(depth)?;
        let span = (self.hi - self.lo).max(f32::MIN_POSITIVE);
        let t = ((v - self.lo) / span).clamp(0.0, 1.0);
        Some(match self.quantity {
            DepthQuantity::Depth => 1.0 - t,
            DepthQuantity::Disparity => t,
        })
    }

    /// One line for a caption: the depths at the two ends of the colours
    /// and, for disparity, the range of the quantity itself.
    pub fn caption(&self) -> String {
        let ends = format!(
            "{:.2} m (red, near) to {:.2} m (blue, far), 2nd to 98th percentile",
            self.near_m, self.far_m
        );
        match self.quantity {
            DepthQuantity::Depth => ends,
            DepthQuantity::Disparity => format!(
                "disparity {:.3} to {:.3} {}: {ends}",
                self.lo, self.hi, self.units
            ),
        }
    }

    /// `3 * n` bytes: the colour of every pixel of `depth` (opacities
    /// `acc`); pixels that are not opaque, or have no value, black.
    pub fn colours(&self, depth: &[f32], acc: &[f32]) -> Vec<u8> {
        let mut out = Vec::with_capacity(3 * depth.len());
        for (i, &d) in depth.iter().enumerate() {
            let c = match self.position(d).filter(|_| opaque(acc, i)) {
                Some(t) => turbo(t).map(to_u8),
                None => [0; 3],
            };
            out.extend(c);
        }
        out
    }
}

/// `3 * n` bytes: accumulated opacity as grey (0 black, 1 white).
pub fn opacity_grey(acc: &[f32]) -> Vec<u8> {
    acc.iter().flat_map(|&a| [to_u8(a); 3]).collect()
}

fn opaque(acc: &[f32], i: usize) -> bool {
    acc.get(i).is_none_or(|&a| a > OPACITY_THRESHOLD)
}

/// The `p`-th percentile of sorted `values` (linear between ranks, as
/// NumPy's default).
fn percentile(values: &[f32], p: f64) -> f32 {
    let pos = (values.len() - 1) as f64 * p / 100.0;
    let (i, f) = (pos.floor() as usize, pos.fract());
    let next = values[(i + 1).min(values.len() - 1)];
    (values[i] as f64 * (1.0 - f) + next as f64 * f) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_is_robust_to_a_few_far_pixels() {
        // 100 opaque pixels from 1 to 2 m and two at 1e4 m (an unbounded
        // field's far samples): the range ignores the two.
        let mut depth: Vec<f32> = (0..100).map(|i| 1.0 + i as f32 / 99.0).collect();
        depth.extend([1e4, 1e4]);
        let acc = vec![1.0; depth.len()];
        let s = DepthScale::of(&depth, &acc, DepthQuantity::Depth);
        assert!(s.hi < 2.01 && s.lo > 0.99 && s.lo < 1.05, "{s:?}");
        assert_eq!(s.opaque_pixels, 102);
        // Near is red (the top of Turbo), far and beyond the range blue.
        assert_eq!(s.position(1.0), Some(1.0));
        assert_eq!(s.position(1e4), Some(0.0));
        let d = DepthScale::of(&depth, &acc, DepthQuantity::Disparity);
        // The 98th percentile of the disparities lies between the 97th and
        // 98th nearest pixels' (1 / 1.0303 and 1 / 1.0202).
        assert!(
            (d.lo - 0.5).abs() < 0.001 && (d.hi - 0.98).abs() < 0.001,
            "{d:?}"
        );
        assert!(
            (d.near_m - 1.0 / d.hi).abs() < 1e-6 && (d.far_m - 2.0).abs() < 0.01,
            "{d:?}"
        );
        assert_eq!(d.position(1.0), Some(1.0));
        assert_eq!(d.position(1e4), Some(0.0));
        assert!(
            s.caption()
                .starts_with("1.02 m (red, near) to 2.00 m (blue, far)"),
            "{}",
            s.caption()
        );
        assert!(
            d.caption()
                .starts_with("disparity 0.500 to 0.980 1/m: 1.02 m (red, near)"),
            "{}",
            d.caption()
        );
        // The two quantities order the pixels alike: near above far.
        assert!(s.position(1.2).unwrap() > s.position(1.8).unwrap());
        assert!(d.position(1.2).unwrap() > d.position(1.8).unwrap());
    }

    #[test]
    fn percentiles_interpolate_between_ranks_as_numpy() {
        let v: Vec<f32> = (0..=10).map(|i| i as f32).collect();
        assert_eq!(percentile(&v, 2.0), 0.2);
        assert_eq!(percentile(&v, 98.0), 9.8);
        assert_eq!(percentile(&[3.0], 50.0), 3.0);
    }

    #[test]
    fn transparent_and_invalid_pixels_are_black_and_left_out_of_the_range() {
        let depth = [1.0, 2.0, 3.0, 50.0, f32::NAN, 0.0];
        let acc = [1.0, 1.0, 1.0, 0.2, 1.0, 1.0];
        let s = DepthScale::of(&depth, &acc, DepthQuantity::Disparity);
        assert_eq!(s.opaque_pixels, 3, "{s:?}");
        let c = s.colours(&depth, &acc);
        assert_eq!(c.len(), 18);
        assert_eq!(&c[0..3], &turbo(1.0).map(to_u8));
        assert_eq!(&c[6..9], &turbo(0.0).map(to_u8));
        for px in c[9..].chunks(3) {
            assert_eq!(px, [0, 0, 0]);
        }
        let empty = DepthScale::of(&[], &[], DepthQuantity::Depth);
        assert_eq!((empty.opaque_pixels, empty.lo, empty.hi), (0, 0.0, 0.0));
        let empty = DepthScale::of(&[1.0], &[0.0], DepthQuantity::Disparity);
        assert_eq!(
            (empty.opaque_pixels, empty.near_m, empty.far_m),
            (0, 0.0, 0.0)
        );
        assert_eq!(opacity_grey(&[0.0, 1.0]), vec![0, 0, 0, 255, 255, 255]);
    }
}
