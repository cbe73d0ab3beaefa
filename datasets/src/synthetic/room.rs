//! The procedural room: an axis-aligned box of walls, floor and ceiling
//! holding furniture and small objects made of labelled axis-aligned boxes,
//! with an analytic ray tracer and a distance-to-surface query.

use model::geometry::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

/// The room of a seed: dimensions and object placements jittered by the
/// seed, the same furniture and small objects in every room.
pub fn build_room(seed: u64) -> Room {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_f700);
    let mut j = |a: f64| rng.random_range(-a..a);
    let (hx, hy, h) = (3.0 + j(0.2), 2.5 + j(0.15), 2.7 + j(0.08));
    let mut b = Builder {
        primitives: Vec::new(),
        groups: Vec::new(),
    };
    dining_corner(&mut b, &mut j);
    sofa_wall(&mut b, &mut j, hy);
    let by0 = bed_wall(&mut b, &mut j, hx);
    north_wall(&mut b, &mut j, hy, h);
    west_wall(&mut b, &mut j, hx, hy, by0);
    // A potted plant in the south-east corner.
    b.plant((hx - 0.35, -hy + 0.35), (0.17, 0.35), (0.28, 1.2));
    Room::from_parts([-hx, -hy, 0.0], [hx, hy, h], b)
}

/// Rug and table near the middle, chairs at its ends, bowl / bottle / book on it.
fn dining_corner(b: &mut Builder, j: &mut impl FnMut(f64) -> f64) {
    let (cx, cy) = (-0.6 + j(0.15), 0.1 + j(0.15));
    b.object(&[(
        "rug",
        [cx - 1.2, cy - 0.8, 0.0],
        [cx + 1.2, cy + 0.8, 0.012],
    )]);
    let (tx, ty, th) = (0.6, 0.4, 0.74);
    let mut table = vec![(
        "table",
        [cx - tx, cy - ty, th - 0.04],
        [cx + tx, cy + ty, th],
    )];
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let (lx, ly) = (cx + sx * (tx - 0.06), cy + sy * (ty - 0.06));
        table.push((
            "table",
            [lx - 0.03, ly - 0.03, 0.012],
            [lx + 0.03, ly + 0.03, th - 0.04],
        ));
    }
    b.object(&table);
    let (bx, by) = (cx + 0.25 + j(0.05), cy + 0.1 + j(0.05));
    b.object(&[(
        "bowl",
        [bx - 0.09, by - 0.09, th],
        [bx + 0.09, by + 0.09, th + 0.07],
    )]);
    let (ox, oy) = (cx - 0.3 + j(0.05), cy - 0.15 + j(0.05));
    b.object(&[(
        "bottle",
        [ox - 0.035, oy - 0.035, th],
        [ox + 0.035, oy + 0.035, th + 0.26],
    )]);
    b.object(&[(
        "book",
        [cx - 0.05, cy - 0.3, th],
        [cx + 0.17, cy - 0.14, th + 0.035],
    )]);
    for side in [-1.0, 1.0] {
        let sx = cx + side * (tx + 0.35);
        let (x0, x1) = (sx - 0.22, sx + 0.22);
        let mut chair = vec![("chair", [x0, cy - 0.22, 0.43], [x1, cy + 0.22, 0.47])];
        let back_x = if side > 0.0 { x1 - 0.04 } else { x0 };
        chair.push((
            "chair",
            [back_x, cy - 0.22, 0.47],
            [back_x + 0.04, cy + 0.22, 0.95],
        ));
        for (lx, ly) in [
            (x0, cy - 0.22),
            (x0, cy + 0.18),
            (x1 - 0.04, cy - 0.22),
            (x1 - 0.04, cy + 0.18),
        ] {
            chair.push(("chair", [lx, ly, 0.012], [lx + 0.04, ly + 0.04, 0.43]));
        }
        b.object(&chair);
    }
}

/// Sofa with two pillows against the south wall, a clock above it.
fn sofa_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hy: f64) {
    let sx = -0.8 + j(0.2);
    let y0 = -hy + 0.02;
    b.object(&[
        ("sofa", [sx - 1.0, y0, 0.0], [sx + 1.0, y0 + 0.9, 0.42]),
        ("sofa", [sx - 1.0, y0, 0.42], [sx + 1.0, y0 + 0.2, 0.85]),
        (
            "sofa",
            [sx - 1.0, y0 + 0.2, 0.42],
            [sx - 0.8, y0 + 0.9, 0.62],
        ),
        (
            "sofa",
            [sx + 0.8, y0 + 0.2, 0.42],
            [sx + 1.0, y0 + 0.9, 0.62],
        ),
    ]);
    for px in [sx - 0.55, sx + 0.15] {
        b.object(&[("pillow", [px, y0 + 0.2, 0.42], [px + 0.4, y0 + 0.34, 0.78])]);
    }
    b.object(&[("clock", [sx - 0.15, -hy, 1.6], [sx + 0.15, -hy + 0.04, 1.9])]);
}

/// Bed against the east wall with a pillow and headboard; nightstand with
/// lamp and a picture. Returns where the bed starts along y.
fn bed_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hx: f64) -> f64 {
    let by0 = -0.2 + j(0.1);
    b.object(&[
        ("bed", [hx - 2.0, by0, 0.0], [hx - 0.12, by0 + 1.5, 0.5]),
        ("bed", [hx - 0.12, by0, 0.0], [hx - 0.02, by0 + 1.5, 1.0]),
    ]);
    b.object(&[(
        "pillow",
        [hx - 0.55, by0 + 0.3, 0.5],
        [hx - 0.15, by0 + 1.2, 0.64],
    )]);
    let ny = by0 + 1.6;
    b.object(&[(
        "nightstand",
        [hx - 0.47, ny, 0.0],
        [hx - 0.02, ny + 0.42, 0.55],
    )]);
    let (lx, ly) = (hx - 0.25, ny + 0.21);
    b.object(&[
        (
            "lamp",
            [lx - 0.05, ly - 0.05, 0.55],
            [lx + 0.05, ly + 0.05, 0.85],
        ),
        (
            "lamp",
            [lx - 0.15, ly - 0.15, 0.85],
            [lx + 0.15, ly + 0.15, 1.1],
        ),
    ]);
    b.object(&[("picture", [hx - 0.03, by0 + 0.3, 1.3], [hx, by0 + 1.2, 1.9])]);
    by0
}

/// Cabinet and tv on the north wall, window with blinds, a vent.
fn north_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hy: f64, h: f64) {
    let kx = -1.5 + j(0.2);
    b.object(&[(
        "cabinet",
        [kx - 0.5, hy - 0.45, 0.0],
        [kx + 0.5, hy - 0.01, 0.9],
    )]);
    b.object(&[(
        "tv-screen",
        [kx - 0.45, hy - 0.05, 1.15],
        [kx + 0.45, hy, 1.7],
    )]);
    let wx = 0.8 + j(0.2);
    b.object(&[("window", [wx - 0.6, hy - 0.02, 0.9], [wx + 0.6, hy, 2.1])]);
    b.object(&[(
        "blinds",
        [wx - 0.65, hy - 0.06, 1.75],
        [wx + 0.65, hy - 0.02, 2.2],
    )]);
    b.object(&[(
        "vent",
        [wx - 0.2, hy - 0.02, h - 0.3],
        [wx + 0.2, hy, h - 0.1],
    )]);
    b.object(&[("vent", [-0.2, -0.1, h - 0.02], [0.2, 0.1, h])]);
}

/// West wall: door with switch, shelf with books; wall plugs on every wall.
fn west_wall(b: &mut Builder, j: &mut impl FnMut(f64) -> f64, hx: f64, hy: f64, by0: f64) {
    let dy = 1.2 + j(0.1);
    b.object(&[("door", [-hx, dy - 0.45, 0.0], [-hx + 0.04, dy + 0.45, 2.05])]);
    b.object(&[(
        "switch",
        [-hx, dy - 0.65, 1.05],
        [-hx + 0.015, dy - 0.57, 1.17],
    )]);
    let (s0, s1) = (-1.6 + j(0.1), -0.6);
    for z in [1.2, 1.6] {
        b.object(&[("shelf", [-hx, s0, z], [-hx + 0.28, s1, z + 0.03])]);
        let mut y = s0 + 0.05;
        let mut books = Vec::new();
        while y < s1 - 0.35 {
            let t = 0.03 + rng_step(&mut y);
            books.push((
                "book",
                [-hx + 0.04, y, z + 0.03],
                [-hx + 0.24, y + t, z + 0.23 + t],
            ));
            y += t + 0.005;
        }
        b.object(&books);
    }
    for (p0, p1) in [
        ([-hx, -1.0, 0.27], [-hx + 0.015, -0.92, 0.33]),
        ([0.0, hy - 0.015, 0.27], [0.08, hy, 0.33]),
        ([hx - 0.015, by0 + 1.52, 0.6], [hx, by0 + 1.58, 0.68]),
        ([1.0, -hy, 0.27], [1.08, -hy + 0.015, 0.33]),
    ] {
        b.object(&[("wall-plug", p0, p1)]);
    }
}

/// Book thickness from the shelf position: a deterministic wobble, so books
/// differ without another random stream.
fn rng_step(y: &mut f64) -> f64 {
    0.02 * (0.5 + 0.5 * (*y * 37.0).sin())
}
