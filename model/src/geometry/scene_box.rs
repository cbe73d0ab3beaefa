//! The scene box and the rays normalised into it.

use std::f64::consts::PI;

use super::{Ray, Vec3};

/// Axis-aligned box enclosing the scene; the field sees coordinates mapped
/// into it with one uniform scale so that the box fits in `[-pi, pi]^3`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneBox {
    /// Minimum corner, metres.
    pub min: Vec3,
    /// Maximum corner, metres.
    pub max: Vec3,
}

impl SceneBox {
    /// The bounding box of `points`, grown by `margin` times its largest
    /// extent on every side (and at least a small absolute amount, so a single
    /// point still gives a box). `None` when there is no finite point.
    pub fn from_points<I: IntoIterator<Item = Vec3>>(points: I, margin: f64) -> Option<Self> {
        let mut min = [f64::INFINITY; 3];
        let mut max = [f64::NEG_INFINITY; 3];
        let mut any = false;
        for p in points {
            if p.iter().all(|v| v.is_finite()) {
                any = true;
                for k in 0..3 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                }
            }
        }
        if !any {
            return None;
        }
        let extent = (0..3).map(|k| max[k] - min[k]).fold(0.0, f64::max);
        let pad = (extent * margin).max(1e-3 * (1.0 + extent));
        for k in 0..3 {
            min[k] -= pad;
            max[k] += pad;
        }
        Some(Self { min, max })
    }

    /// Box centre.
    pub fn center(&self) -> Vec3 {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }

    /// Uniform scale mapping the box into `[-pi, pi]^3`.
    pub fn scale(&self) -> f64 {
        let half = (0..3)
            .map(|k| 0.5 * (self.max[k] - self.min[k]))
            .fold(0.0, f64::max);
        PI / half.max(1e-12)
    }

    /// Maps a world point into normalised coordinates (`[-pi, pi]` inside the box).
    pub fn normalize_point(&self, p: Vec3) -> Vec3 {
        let c = self.center();
        let s = self.scale();
        [(p[0] - c[0]) * s, (p[1] - c[1]) * s, (p[2] - c[2]) * s]
    }

    /// Maps a normalised point back to world coordinates.
    pub fn denormalize_point(&self, p: Vec3) -> Vec3 {
        let c = self.center();
        let s = self.scale();
        [p[0] / s + c[0], p[1] / s + c[1], p[2] / s + c[2]]
    }

    /// Whether `p` lies inside the box.
    pub fn contains(&self, p: Vec3) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] && p[k] <= self.max[k])
    }

    /// Parameter interval `[t_near, t_far]` (with `t >= 0`) where the ray is
    /// inside the box, by the slab method; `None` if it misses the box.
    /// Axis-parallel directions (zero components) are handled exactly.
    pub fn intersect(&self, origin: Vec3, direction: Vec3) -> Option<(f64, f64)> {
        let mut t0: f64 = 0.0;
        let mut t1 = f64::INFINITY;
        for k in 0..3 {
            if direction[k] == 0.0 {
                if origin[k] < self.min[k] || origin[k] > self.max[k] {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / direction[k];
            let (a, b) = (
                (self.min[k] - origin[k]) * inv,
                (self.max[k] - origin[k]) * inv,
            );
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            t0 = t0.max(lo);
            t1 = t1.min(hi);
        }
        (t0 <= t1 && t1.is_finite()).then_some((t0, t1))
    }

    /// A world ray in the field's normalised frame, in `f32`. The ray parameter
    /// `t` is unchanged (so depth stays metric); `near`/`far` are the box
    /// interval clamped below by `min_near`, and `near == far` for a ray that
    /// misses the box (it then renders as empty).
    pub fn normalize_ray(&self, ray: &Ray, min_near: f64) -> NormalizedRay {
        let s = self.scale();
        let o = self.normalize_point(ray.origin);
        let (near, far) = match self.intersect(ray.origin, ray.direction) {
            Some((a, b)) => (a.max(min_near), b.max(min_near)),
            None => (min_near, min_near),
        };
        NormalizedRay {
            origin: [o[0] as f32, o[1] as f32, o[2] as f32],
            direction: [
                (ray.direction[0] * s) as f32,
                (ray.direction[1] * s) as f32,
                (ray.direction[2] * s) as f32,
            ],
            radius: (ray.radius * s) as f32,
            near: near as f32,
            far: far as f32,
        }
    }
}

/// A ray in the field's normalised frame, ready for the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalizedRay {
    /// Origin in normalised coordinates.
    pub origin: [f32; 3],
    /// Direction scaled by the box scale (camera-space z = box scale).
    pub direction: [f32; 3],
    /// Base radius scaled by the box scale.
    pub radius: f32,
    /// Metric near bound on `t`.
    pub near: f32,
    /// Metric far bound on `t`.
    pub far: f32,
}
