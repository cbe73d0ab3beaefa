//! The procedural room: an axis-aligned box of walls, floor and ceiling
//! holding furniture and small objects made of labelled axis-aligned boxes,
//! with an analytic ray tracer and a distance-to-surface query, and the
//! builder that assembles the boxes into objects (what stands where is
//! `furnishing`'s for the room and `outdoor`'s for the outdoor scene).

use model::geometry::Vec3;

use super::classes::class_index;

/// A labelled solid axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    /// Minimum corner, metres.
    pub min: Vec3,
    /// Maximum corner, metres.
    pub max: Vec3,
    /// Class index into [`super::classes::CLASSES`].
    pub class: u16,
}

/// The first surface a ray meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter (z-depth for camera rays).
    pub t: f64,
    /// Hit point.
    pub point: Vec3,
    /// Outward unit normal of the surface (pointing towards the ray origin's side).
    pub normal: Vec3,
    /// Class index.
    pub class: u16,
}

/// A room: the inside of the box `[min, max]` (floor at `min[2]`, ceiling at
/// `max[2]`) and the objects standing in it.
#[derive(Debug, Clone, PartialEq)]
pub struct Room {
    /// Minimum corner of the room's interior.
    pub min: Vec3,
    /// Maximum corner of the room's interior.
    pub max: Vec3,
    /// All object boxes.
    pub primitives: Vec<Primitive>,
    /// Objects as `(bounding box min, max, primitive range)`, to skip whole
    /// objects a ray misses.
    groups: Vec<(Vec3, Vec3, std::ops::Range<usize>)>,
}

/// Entry parameter and entry axis of a ray into a box (slab test), for
/// `t > t_min`; `None` when it misses.
fn ray_box(origin: Vec3, dir: Vec3, min: Vec3, max: Vec3, t_min: f64) -> Option<(f64, usize)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    let mut axis = 0;
    for k in 0..3 {
        if dir[k].abs() < 1e-15 {
            if origin[k] < min[k] || origin[k] > max[k] {
                return None;
            }
            continue;
        }
        let inv = 1.0 / dir[k];
        let (a, b) = ((min[k] - origin[k]) * inv, (max[k] - origin[k]) * inv);
        let (near, far) = if a < b { (a, b) } else { (b, a) };
        if near > t0 {
            t0 = near;
            axis = k;
        }
        t1 = t1.min(far);
    }
    (t0 <= t1 && t0 > t_min).then_some((t0, axis))
}

/// The parameter interval `[t0, t1]` in which the line `origin + t * dir`
/// is inside the box, if any.
fn ray_span(origin: Vec3, dir: Vec3, min: Vec3, max: Vec3) -> Option<(f64, f64)> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for k in 0..3 {
        if dir[k].abs() < 1e-15 {
            if origin[k] < min[k] || origin[k] > max[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((min[k] - origin[k]) / dir[k], (max[k] - origin[k]) / dir[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Distance from `p` to the surface of the box (0 on it, positive inside
/// and outside).
fn box_surface_distance(p: Vec3, min: Vec3, max: Vec3) -> f64 {
    let mut outside = 0.0f64;
    let mut inside = f64::INFINITY;
    for k in 0..3 {
        let d = (min[k] - p[k]).max(p[k] - max[k]);
        if d > 0.0 {
            outside += d * d;
        }
        inside = inside.min(-d);
    }
    if outside > 0.0 {
        outside.sqrt()
    } else {
        inside.max(0.0)
    }
}

impl Room {
    /// The room `[min, max]` holding what `b` built.
    pub(super) fn from_parts(min: Vec3, max: Vec3, b: Builder) -> Room {
        Room {
            min,
            max,
            primitives: b.primitives,
            groups: b.groups,
        }
    }

    /// The nearest surface along `origin + t * dir` with `t > t_min`: an
    /// object box or the room's inner shell. `None` only for rays starting
    /// outside the room that never enter it.
    pub fn trace(&self, origin: Vec3, dir: Vec3, t_min: f64) -> Option<Hit> {
        let mut best: Option<(f64, usize, u16, f64)> = None;
        for (gmin, gmax, range) in &self.groups {
            // Skip objects whose bounds the ray misses or meets only behind
            // the nearest hit so far.
            match ray_span(origin, dir, *gmin, *gmax) {
                Some((t0, t1)) if t1 > t_min && best.is_none_or(|b| t0 < b.0) => {}
                _ => continue,
            }
            for p in &self.primitives[range.clone()] {
                if let Some((t, axis)) = ray_box(origin, dir, p.min, p.max, t_min)
                    && best.is_none_or(|b| t < b.0)
                {
                    best = Some((t, axis, p.class, -dir[axis].signum()));
                }
            }
        }
        // The shell: where the ray leaves the room's interior.
        let mut t_exit = f64::INFINITY;
        let mut exit_axis = 0;
        for k in 0..3 {
            let t = if dir[k] > 1e-15 {
                (self.max[k] - origin[k]) / dir[k]
            } else if dir[k] < -1e-15 {
                (self.min[k] - origin[k]) / dir[k]
            } else {
                f64::INFINITY
            };
            if t < t_exit {
                t_exit = t;
                exit_axis = k;
            }
        }
        let shell = (t_exit > t_min && t_exit.is_finite()).then(|| {
            let class = self.shell_class(exit_axis, dir[exit_axis] > 0.0);
            (t_exit, exit_axis, class, -dir[exit_axis].signum())
        });
        let (t, axis, class, sign) = match (best, shell) {
            (Some(b), Some(s)) => {
                if b.0 <= s.0 {
                    b
                } else {
                    s
                }
            }
            (Some(b), None) => b,
            (None, s) => s?,
        };
        let mut normal = [0.0; 3];
        normal[axis] = sign;
        Some(Hit {
            t,
            point: [
                origin[0] + t * dir[0],
                origin[1] + t * dir[1],
                origin[2] + t * dir[2],
            ],
            normal,
            class,
        })
    }

    /// Class of the shell face crossed along `axis` in the positive (`true`)
    /// or negative direction.
    pub(crate) fn shell_class(&self, axis: usize, positive: bool) -> u16 {
        let name = match (axis, positive) {
            (2, false) => "floor",
            (2, true) => "ceiling",
            _ => "wall",
        };
        class_index(name).unwrap_or(0)
    }

    /// Distance from `p` to the nearest surface of the scene (object boxes and
    /// the shell) with that surface's class: an independent check of the ray
    /// tracer and of back-projected depth.
    pub fn surface_distance(&self, p: Vec3) -> (f64, u16) {
        let mut best = (f64::INFINITY, 0u16);
        for (k, &x) in p.iter().enumerate() {
            for (bound, positive) in [(self.min[k], false), (self.max[k], true)] {
                let d = (x - bound).abs();
                if d < best.0 {
                    best = (d, self.shell_class(k, positive));
                }
            }
        }
        for prim in &self.primitives {
            let d = box_surface_distance(p, prim.min, prim.max);
            if d < best.0 {
                best = (d, prim.class);
            }
        }
        best
    }

    /// Whether `p` lies inside (or within `eps` of) any object box other than
    /// `skip`, or within `eps` of the shell or outside it.
    pub fn is_buried(&self, p: Vec3, skip: Option<usize>, eps: f64) -> bool {
        if (0..3).any(|k| p[k] < self.min[k] + eps || p[k] > self.max[k] - eps) {
            return true;
        }
        self.buried_in_objects(p, skip, eps)
    }

    /// Whether `p` lies inside (or within `eps` of) any object box other
    /// than `skip`.
    pub fn buried_in_objects(&self, p: Vec3, skip: Option<usize>, eps: f64) -> bool {
        self.primitives.iter().enumerate().any(|(i, b)| {
            Some(i) != skip && (0..3).all(|k| p[k] > b.min[k] - eps && p[k] < b.max[k] + eps)
        })
    }

    /// Whether `p` is strictly inside the room and not inside any object
    /// grown by `clearance` (where a camera may stand).
    pub fn is_free(&self, p: Vec3, clearance: f64) -> bool {
        (0..3).all(|k| p[k] > self.min[k] + clearance && p[k] < self.max[k] - clearance)
            && !self
                .primitives
                .iter()
                .any(|b| (0..3).all(|k| p[k] > b.min[k] - clearance && p[k] < b.max[k] + clearance))
    }
}

/// Builds objects one by one, recording each object's primitive range.
pub(super) struct Builder {
    pub(super) primitives: Vec<Primitive>,
    pub(super) groups: Vec<(Vec3, Vec3, std::ops::Range<usize>)>,
}

impl Builder {
    /// Adds a potted plant at `(x, y)`: a pot of half-width and height
    /// `pot`, foliage of half-width `foliage.0` from the pot up to `foliage.1`.
    pub(super) fn plant(&mut self, (x, y): (f64, f64), pot: (f64, f64), foliage: (f64, f64)) {
        let (p, f) = (pot.0, foliage.0);
        self.object(&[
            ("indoor-plant", [x - p, y - p, 0.0], [x + p, y + p, pot.1]),
            (
                "indoor-plant",
                [x - f, y - f, pot.1],
                [x + f, y + f, foliage.1],
            ),
        ]);
    }

    /// Adds one object made of `(class, min, max)` boxes.
    pub(super) fn object(&mut self, parts: &[(&str, Vec3, Vec3)]) {
        let start = self.primitives.len();
        let mut gmin = [f64::INFINITY; 3];
        let mut gmax = [f64::NEG_INFINITY; 3];
        for (name, min, max) in parts {
            for k in 0..3 {
                gmin[k] = gmin[k].min(min[k]);
                gmax[k] = gmax[k].max(max[k]);
            }
            self.primitives.push(Primitive {
                min: *min,
                max: *max,
                class: class_index(name).unwrap_or(0),
            });
        }
        self.groups.push((gmin, gmax, start..self.primitives.len()));
    }
}
