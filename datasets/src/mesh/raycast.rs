//! Nearest ray/triangle hits through a bounding volume hierarchy (the `bvh`
//! crate), exact in `f64`, and z-depth images rendered from them.

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::{BHShape, BoundingHierarchy};
use bvh::bvh::Bvh;
use bvh::ray::Ray;
use model::geometry::Camera;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::TriangleMesh;
use crate::scene::DepthImage;

/// Barycentric slack of the triangle test: a ray through an edge shared by
/// two triangles must not slip between them through rounding (a hole in a
/// depth image), so each triangle is widened by this fraction of itself.
const EDGE_SLACK: f64 = 1e-12;

/// Relative padding of the triangles' boxes: the crate's slab test and the
/// exact triangle test round differently, and a box must never reject a hit
/// the triangle test would accept (boxes of axis-aligned triangles are flat).
const BOX_PADDING: f64 = 1e-9;

/// One triangle as the hierarchy sees it: its corner and edges for the
/// intersection test, its padded box, and its node in the hierarchy.
#[derive(Debug, Clone)]
struct Triangle {
    a: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
    aabb: Aabb<f64, 3>,
    node: usize,
}

impl Bounded<f64, 3> for Triangle {
    fn aabb(&self) -> Aabb<f64, 3> {
        self.aabb
    }
}

impl BHShape<f64, 3> for Triangle {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }

    fn bh_node_index(&self) -> usize {
        self.node
    }
}

/// Nearest-hit queries against a triangle mesh, through a bounding volume
/// hierarchy over its triangles.
///
/// Triangles with an index past the mesh's vertex list or a non-finite
/// corner are left out (a mesh from [`super::read_obj`] has none).
#[derive(Debug, Clone)]
pub struct Raycaster {
    bvh: Bvh<f64, 3>,
    triangles: Vec<Triangle>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Triangle {
    /// Möller–Trumbore: `t` of the hit with `origin + t * direction`, when
    /// the ray meets the triangle at `t > 0`.
    fn hit(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<f64> {
        let p = cross(direction, self.e2);
        let det = dot(self.e1, p);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let inv = 1.0 / det;
        let s = sub(origin, self.a);
        let u = dot(s, p) * inv;
        if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
            return None;
        }
        let q = cross(s, self.e1);
        let v = dot(direction, q) * inv;
        if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
            return None;
        }
        let t = dot(self.e2, q) * inv;
        (t > 0.0 && t.is_finite()).then_some(t)
    }
}

impl Raycaster {
    /// Builds the hierarchy over `mesh`'s triangles (in parallel).
    pub fn new(mesh: &TriangleMesh) -> Self {
        let corners = |t: &[u32; 3]| -> Option<[[f64; 3]; 3]> {
            let c = t.map(|i| mesh.positions.get(i as usize).copied());
            let c = [c[0]?, c[1]?, c[2]?];
            c.iter().flatten().all(|x| x.is_finite()).then_some(c)
        };
        // One padding for the whole mesh, scaled by its size and distance
        // from the origin, so that flat boxes get a thickness too.
        let scale = mesh
            .triangles
            .iter()
            .filter_map(corners)
            .flatten()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let pad = BOX_PADDING * scale.max(f64::MIN_POSITIVE);
        let mut triangles: Vec<Triangle> = mesh
            .triangles
            .iter()
            .filter_map(corners)
            .map(|[a, b, c]| {
                let lo = [0, 1, 2].map(|k| a[k].min(b[k]).min(c[k]) - pad);
                let hi = [0, 1, 2].map(|k| a[k].max(b[k]).max(c[k]) + pad);
                Triangle {
                    a,
                    e1: sub(b, a),
                    e2: sub(c, a),
                    aabb: Aabb::with_bounds(Point3::from(lo), Point3::from(hi)),
                    node: 0,
                }
            })
            .collect();
        let bvh = Bvh::build_par(&mut triangles);
        Self { bvh, triangles }
    }

    /// Distance along `direction` (any length, nonzero) from `origin` to the
    /// nearest triangle hit with `t > 0`, in units of `direction`'s length
    /// (the hit point is `origin + t * direction`); `None` on a miss, and
    /// for a zero or non-finite ray.
    pub fn hit(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<f64> {
        let length = dot(direction, direction).sqrt();
        if !(length > 0.0 && length.is_finite() && origin.iter().all(|x| x.is_finite())) {
            return None;
        }
        // The crate's ray has a unit direction: its box distances are
        // `length` times ours.
        let ray = Ray::new(Point3::from(origin), Vector3::from(direction));
        let mut best = f64::INFINITY;
        for triangle in self.bvh.nearest_traverse_iterator(&ray, &self.triangles) {
            // Leaves come in order of where the ray enters their boxes, so
            // once a box starts beyond the best hit no later triangle can
            // be nearer (the slack covers the two tests' rounding).
            if let Some((entry, _)) = ray.intersection_slice_for_aabb(&triangle.aabb)
                && entry > best * length * (1.0 + 1e-9)
            {
                break;
            }
            if let Some(t) = triangle.hit(origin, direction) {
                best = best.min(t);
            }
        }
        best.is_finite().then_some(best)
    }

    /// The z-depth image of `camera` at its pixel centres (pixel `(i, j)`
    /// is `u = i`, `v = j`), `0` where the ray misses; rows in parallel.
    /// [`Camera::ray`] gives directions with camera-space `z = 1`, so the
    /// distance along them is the z-depth.
    pub fn depth_image(&self, camera: &Camera) -> DepthImage {
        let (width, height) = (camera.intrinsics.width, camera.intrinsics.height);
        let mut data = vec![0.0f32; width as usize * height as usize];
        if width > 0 {
            data.par_chunks_mut(width as usize)
                .enumerate()
                .for_each(|(j, row)| {
                    for (i, depth) in row.iter_mut().enumerate() {
                        let ray = camera.ray(i as f64, j as f64);
                        if let Some(t) = self.hit(ray.origin, ray.direction) {
                            *depth = t as f32;
                        }
                    }
                });
        }
        DepthImage {
            width,
            height,
            data: crate::scene::DepthData::F32(data),
        }
    }
}
