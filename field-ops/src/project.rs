//! Projecting 3D points into views with an occlusion test, and averaging the
//! features the views see at those points.

use model::geometry::{Camera, Vec3};

/// A point counts as seen by a view when its z-depth is within this many
/// metres of the view's depth at its pixel.
pub const OCCLUSION_THRESHOLD: f64 = 0.1;

/// A z-depth image in metres, row-major `[height, width]`; `0` (or any value
/// that is not positive and finite) marks pixels without depth.
#[derive(Debug, Clone, Copy)]
pub struct DepthRef<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height * width` depths.
    pub data: &'a [f32],
}

/// Visibility rules of a projection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectOptions {
    /// Pixels this close to the border are not used: the training sampler's
    /// margin (2D feature maps are least reliable there), given for a
    /// 360-pixel shorter side and scaled with each view's image
    /// ([`datasets::sampler::scaled_margin`]).
    pub border_margin: u32,
    /// Maximum `|depth(u, v) - z|` in metres for a point to count as visible.
    pub occlusion_threshold: f64,
}

impl Default for ProjectOptions {
    fn default() -> Self {
        Self {
            border_margin: 10,
            occlusion_threshold: OCCLUSION_THRESHOLD,
        }
    }
}

/// Where a visible point lands: image coordinates and its pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Image x coordinate (pixel centres at integers).
    pub u: f64,
    /// Image y coordinate.
    pub v: f64,
    /// Pixel column.
    pub x: u32,
    /// Pixel row.
    pub y: u32,
    /// Depth of the point along the camera axis, metres.
    pub z: f64,
}

/// The pixel `p` lands on when it is in front of the camera, inside the image
/// (minus the border margin) and, with a depth image, not occluded: the
/// depth at that pixel must be valid and within the threshold of the point's
/// z. Without a depth image there is no occlusion test. The depth image may
/// have another resolution than the camera: pixels are looked up by scaling.
pub fn visible_pixel(
    camera: &Camera,
    p: Vec3,
    depth: Option<DepthRef<'_>>,
    opts: &ProjectOptions,
) -> Option<Hit> {
    let proj = camera.project(p)?;
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    let m = datasets::sampler::scaled_margin(opts.border_margin, w, h) as f64;
    let (xf, yf) = (proj.u.round(), proj.v.round());
    if !(xf >= m && yf >= m && xf < w as f64 - m && yf < h as f64 - m) {
        return None;
    }
    let (x, y) = (xf as u32, yf as u32);
    if let Some(d) = depth {
        let dx = (((proj.u + 0.5) * d.width as f64 / w as f64).floor() as u32).min(d.width - 1);
        let dy = (((proj.v + 0.5) * d.height as f64 / h as f64).floor() as u32).min(d.height - 1);
        let z = d.data[dy as usize * d.width as usize + dx as usize] as f64;
        if !(z > 0.0 && z.is_finite()) || (z - proj.z).abs() >= opts.occlusion_threshold {
            return None;
        }
    }
    Some(Hit {
        u: proj.u,
        v: proj.v,
        x,
        y,
        z: proj.z,
    })
}

/// Per-point running sums of features and observation counts.
///
/// Memory is `points * dim` floats, so features should be accumulated in the
/// compressed (PCA) space: averaging commutes with the affine lift, so the
/// mean of coefficients lifts to the mean of the lifted features exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureAccumulator {
    /// Channels per point.
    pub dim: usize,
    /// `points * dim` sums.
    pub sums: Vec<f32>,
    /// Observations per point.
    pub counts: Vec<u32>,
}

impl FeatureAccumulator {
    /// Zero sums for `points` points of `dim` channels.
    pub fn new(points: usize, dim: usize) -> Self {
        Self {
            dim,
            sums: vec![0.0; points * dim],
            counts: vec![0; points],
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// Adds one observation `f` (length `dim`) of point `i`.
    pub fn add(&mut self, i: usize, f: &[f32]) {
        let s = &mut self.sums[i * self.dim..(i + 1) * self.dim];
        s.iter_mut().zip(f).for_each(|(a, &b)| *a += b);
        self.counts[i] += 1;
    }

    /// Mean feature of point `i`, `None` when no view saw it.
    pub fn mean(&self, i: usize) -> Option<Vec<f32>> {
        let c = self.counts[i];
        (c > 0).then(|| {
            self.sums[i * self.dim..(i + 1) * self.dim]
                .iter()
                .map(|s| s / c as f32)
                .collect()
        })
    }

    /// Projects `points` into one view and adds the feature found there to
    /// every visible point; `feature_at(hit, out)` writes the view's feature
    /// at the hit into `out` and returns whether there is one (a map pixel
    /// without a target adds nothing). Returns the number of points added.
    pub fn add_view(
        &mut self,
        points: &[Vec3],
        camera: &Camera,
        depth: Option<DepthRef<'_>>,
        opts: &ProjectOptions,
        mut feature_at: impl FnMut(&Hit, &mut [f32]) -> bool,
    ) -> usize {
        let mut buf = vec![0.0f32; self.dim];
        let mut seen = 0;
        for (i, &p) in points.iter().enumerate() {
            if let Some(hit) = visible_pixel(camera, p, depth, opts)
                && feature_at(&hit, &mut buf)
            {
                self.add(i, &buf);
                seen += 1;
            }
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::{Intrinsics, Pose};

    fn camera() -> Camera {
        Camera {
            intrinsics: Intrinsics {
                width: 8,
                height: 6,
                fx: 4.0,
                fy: 4.0,
                cx: 3.5,
                cy: 2.5,
                distortion: model::geometry::Distortion::NONE,
            },
            pose: Pose::identity(),
        }
    }

    #[test]
    fn in_front_inside_and_not_occluded() {
        let cam = camera();
        let depth = vec![2.0f32; 48];
        let d = DepthRef {
            width: 8,
            height: 6,
            data: &depth,
        };
        let o = ProjectOptions::default();
        // On the optical axis at z = 2: u = 3.5 rounds to 4, v = 2.5 rounds to 3 (ties away from 0).
        let hit = visible_pixel(&cam, [0.0, 0.0, 2.0], Some(d), &o).unwrap();
        assert_eq!((hit.x, hit.y), (4, 3));
        // Behind the surface by more than the threshold: occluded.
        assert!(visible_pixel(&cam, [0.0, 0.0, 2.2], Some(d), &o).is_none());
        // Within the threshold: visible.
        assert!(visible_pixel(&cam, [0.0, 0.0, 2.09], Some(d), &o).is_some());
        // Behind the camera.
        assert!(visible_pixel(&cam, [0.0, 0.0, -2.0], None, &o).is_none());
        // Outside the image: u = 4 * 2 / 2 + 3.5 = 7.5 rounds to 8 = width.
        assert!(visible_pixel(&cam, [2.0, 0.0, 2.0], None, &o).is_none());
        // The border margin removes the outer pixel ring.
        let inner = visible_pixel(&cam, [1.6, 0.0, 2.0], None, &o).unwrap();
        assert_eq!(inner.x, 7);
        // A margin of 60 px at a 360-px side is 1 px on this 6-px side.
        let m = ProjectOptions {
            border_margin: 60,
            ..o
        };
        assert!(visible_pixel(&cam, [1.6, 0.0, 2.0], None, &m).is_none());
        // Invalid depth: the point cannot be verified, so it is not used.
        let zero = vec![0.0f32; 48];
        let dz = DepthRef {
            width: 8,
            height: 6,
            data: &zero,
        };
        assert!(visible_pixel(&cam, [0.0, 0.0, 2.0], Some(dz), &o).is_none());
    }

    #[test]
    fn accumulator_averages_observations() {
        let cam = camera();
        let mut acc = FeatureAccumulator::new(2, 2);
        let pts = [[0.0, 0.0, 2.0], [0.0, 0.0, -1.0]];
        let o = ProjectOptions::default();
        let seen = acc.add_view(&pts, &cam, None, &o, |h, out| {
            out[0] = h.x as f32;
            out[1] = 1.0;
            true
        });
        assert_eq!(seen, 1);
        acc.add_view(&pts, &cam, None, &o, |_, out| {
            out[0] = 0.0;
            out[1] = 3.0;
            true
        });
        // A view without a feature at the point adds no observation.
        let none = acc.add_view(&pts, &cam, None, &o, |_, out| {
            out[0] = 100.0;
            false
        });
        assert_eq!(none, 0);
        assert_eq!(acc.counts[0], 2);
        assert_eq!(acc.mean(0), Some(vec![2.0, 2.0]));
        assert_eq!(acc.mean(1), None);
    }

    /// Projection leaves out the same border as the training sampler: on a
    /// 640x360 view the default 10-px margin, on a 320x180 view 5 px.
    #[test]
    fn default_projection_skips_the_training_border() {
        let o = ProjectOptions::default();
        for (w, h, margin) in [(640u32, 360u32, 10u32), (320, 180, 5)] {
            let cam = Camera {
                intrinsics: Intrinsics {
                    width: w,
                    height: h,
                    fx: w as f64 / 2.0,
                    fy: w as f64 / 2.0,
                    cx: (w as f64 - 1.0) / 2.0,
                    cy: (h as f64 - 1.0) / 2.0,
                    distortion: model::geometry::Distortion::NONE,
                },
                pose: Pose::identity(),
            };
            // A point landing on column x at z = 1.
            let at = |x: f64| [(x - cam.intrinsics.cx) / cam.intrinsics.fx, 0.0, 1.0];
            let m = margin as f64;
            assert!(
                visible_pixel(&cam, at(m - 1.0), None, &o).is_none(),
                "{w}x{h}"
            );
            assert_eq!(
                visible_pixel(&cam, at(m), None, &o).map(|h| h.x),
                Some(margin)
            );
            let right = w as f64 - 1.0 - m;
            assert!(visible_pixel(&cam, at(right + 1.0), None, &o).is_none());
            assert!(visible_pixel(&cam, at(right), None, &o).is_some());
        }
    }
}
