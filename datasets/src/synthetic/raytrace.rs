//! Procedural textures, shading, ray-traced frames and the labelled surface
//! point cloud of a [`Room`].

use model::geometry::{Camera, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::classes::{CLASSES, Pattern};
use super::room::Room;
use crate::numeric::hash01;
use crate::scene::{DepthImage, RgbImage};

/// Rays start this far from the camera (nothing is closer).
const T_MIN: f64 = 1e-6;

/// Hash of a lattice cell and a salt.
fn cell_hash(c: [i64; 3], salt: u64) -> f64 {
    let k = (c[0] as u64).wrapping_mul(0x8da6_b343)
        ^ (c[1] as u64).wrapping_mul(0xd816_3841)
        ^ (c[2] as u64).wrapping_mul(0xcb1a_b31f)
        ^ salt.wrapping_mul(0x1656_67b1);
    hash01(k)
}

/// Trilinear value noise in `[0, 1]` at `p * freq`.
fn value_noise(p: Vec3, freq: f64, salt: u64) -> f64 {
    let q = p.map(|v| v * freq);
    let c = q.map(|v| v.floor());
    let f = [q[0] - c[0], q[1] - c[1], q[2] - c[2]].map(|t| t * t * (3.0 - 2.0 * t));
    let c = c.map(|v| v as i64);
    let mut sum = 0.0;
    for corner in 0..8i64 {
        let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
        let w: f64 = (0..3)
            .map(|k| if o[k] == 1 { f[k] } else { 1.0 - f[k] })
            .product();
        sum += w * cell_hash([c[0] + o[0], c[1] + o[1], c[2] + o[2]], salt);
    }
    sum
}

/// The two in-surface coordinates of `p` on a face with axis-aligned `normal`.
fn surface_uv(p: Vec3, normal: Vec3) -> (f64, f64) {
    if normal[2].abs() > 0.5 {
        (p[1], p[0])
    } else if normal[0].abs() > 0.5 {
        (p[1], p[2])
    } else {
        (p[0], p[2])
    }
}

/// Albedo of class `class` at surface point `p` (multi-view consistent: a
/// function of the point, not of the ray). Patterns modulate the base colour
/// around 1 so the class's mean colour stays near its base colour.
pub fn albedo(palette: &[[f64; 3]], class: u16, p: Vec3, normal: Vec3) -> [f64; 3] {
    let base = palette[class as usize];
    let salt = class as u64 + 1;
    let (u, v) = surface_uv(p, normal);
    let m = match CLASSES[class as usize].pattern {
        Pattern::Noise => [0.9 + 0.2 * value_noise(p, 9.0, salt); 3],
        Pattern::Wood => {
            let plank = (u / 0.14).floor() as i64;
            let tint = 0.85 + 0.3 * cell_hash([plank, 0, 0], salt);
            let grain = 0.94 + 0.12 * (v * 35.0 + 4.0 * value_noise(p, 3.0, salt)).sin().abs();
            let seam = if (u / 0.14).rem_euclid(1.0) < 0.04 {
                0.75
            } else {
                1.0
            };
            [tint * grain * seam; 3]
        }
        Pattern::Slats => {
            let s = if (p[2] / 0.05).rem_euclid(1.0) < 0.2 {
                0.8
            } else {
                1.05
            };
            [s; 3]
        }
        Pattern::Checker => {
            let odd = ((p[0] / 0.2).floor() as i64 + (p[1] / 0.2).floor() as i64).rem_euclid(2);
            let s = if odd == 1 { 0.8 } else { 1.2 };
            [s * (0.95 + 0.1 * value_noise(p, 20.0, salt)); 3]
        }
        Pattern::Painting => [
            1.0 + 0.45 * (u * 9.0 + 2.0 * value_noise(p, 2.0, salt)).sin(),
            1.0 + 0.45 * (v * 11.0 + 1.0).sin(),
            1.0 + 0.45 * ((u + v) * 7.0 + 2.0).sin(),
        ],
        Pattern::Glass => [0.9 + 0.2 * ((v * 2.0).rem_euclid(1.0)); 3],
    };
    [0, 1, 2].map(|k| (base[k] * m[k]).clamp(0.0, 1.0))
}

/// Light direction (from the window side, above).
const LIGHT: Vec3 = [0.277, -0.370, 0.887];

/// Lambertian shading factor of a surface with unit `normal`: ambient plus
/// one directional light, so shading is view-independent.
pub fn shade(normal: Vec3) -> f64 {
    let d = normal[0] * LIGHT[0] + normal[1] * LIGHT[1] + normal[2] * LIGHT[2];
    0.8 + 0.2 * d.max(0.0)
}

/// Colour, z-depth and labels of one view, traced through pixel centres.
pub struct Rendered {
    /// Colour image.
    pub rgb: RgbImage,
    /// Z-depth (every pixel hits a surface inside the room).
    pub depth: DepthImage,
    /// Class index per pixel, row-major.
    pub labels: Vec<u16>,
}

/// Ray-traces one view of `room`.
pub fn render_view(room: &Room, palette: &[[f64; 3]], camera: &Camera) -> Rendered {
    let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
    let n = (w * h) as usize;
    let mut rgb = Vec::with_capacity(3 * n);
    let mut depth = Vec::with_capacity(n);
    let mut labels = Vec::with_capacity(n);
    for j in 0..h {
        for i in 0..w {
            let ray = camera.ray(i as f64, j as f64);
            match room.trace(ray.origin, ray.direction, T_MIN) {
                Some(hit) => {
                    let a = albedo(palette, hit.class, hit.point, hit.normal);
                    let s = shade(hit.normal);
                    rgb.extend(a.map(|c| (c * s).clamp(0.0, 1.0) as f32));
                    depth.push(hit.t as f32);
                    labels.push(hit.class);
                }
                None => {
                    rgb.extend([0.0f32; 3]);
                    depth.push(0.0);
                    labels.push(u16::MAX);
                }
            }
        }
    }
    Rendered {
        rgb: RgbImage::from_f32(w, h, rgb),
        depth: DepthImage {
            width: w,
            height: h,
            data: crate::scene::DepthData::F32(depth),
        },
        labels,
    }
}

/// Renders all `cameras` on up to the machine's parallelism in threads;
/// the result does not depend on the thread count.
pub fn render_views(room: &Room, palette: &[[f64; 3]], cameras: &[Camera]) -> Vec<Rendered> {
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 16);
    let chunk = cameras.len().div_ceil(threads).max(1);
    std::thread::scope(|s| {
        let handles: Vec<_> = cameras
            .chunks(chunk)
            .map(|cams| {
                s.spawn(move || {
                    cams.iter()
                        .map(|c| render_view(room, palette, c))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

/// A labelled point on a scene surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Position, metres.
    pub position: Vec3,
    /// Shaded colour.
    pub color: [u8; 3],
    /// Class index.
    pub class: u16,
}

/// Samples exposed surface points: `density` points per square metre on
/// every face of the shell and of every object box (at least `min_per_face`
/// candidates per face, so tiny objects are represented), dropping points
/// buried in or touching another box.
pub fn sample_surface(
    room: &Room,
    palette: &[[f64; 3]],
    density: f64,
    min_per_face: usize,
    seed: u64,
) -> Vec<SurfacePoint> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x90_1275);
    let mut out = Vec::new();
    let eps = 1e-4;
    // Shell faces: (axis, at max?, normal sign into the room).
    let shell: Vec<(Vec3, Vec3, usize, f64, Option<usize>)> = (0..3)
        .flat_map(|k| {
            [(room.min, 1.0), (room.max, -1.0)].map(|(b, sign)| {
                let (mut lo, mut hi) = (room.min, room.max);
                lo[k] = b[k];
                hi[k] = b[k];
                (lo, hi, k, sign, None)
            })
        })
        .collect();
    let faces = room.primitives.iter().enumerate().flat_map(|(i, p)| {
        (0..3).flat_map(move |k| {
            [(p.min, -1.0), (p.max, 1.0)].map(|(b, sign)| {
                let (mut lo, mut hi) = (p.min, p.max);
                lo[k] = b[k];
                hi[k] = b[k];
                (lo, hi, k, sign, Some(i))
            })
        })
    });
    for (lo, hi, axis, sign, owner) in shell.into_iter().chain(faces) {
        let area: f64 = (0..3)
            .filter(|&k| k != axis)
            .map(|k| hi[k] - lo[k])
            .product();
        let n = ((area * density).round() as usize).max(min_per_face);
        let mut normal = [0.0; 3];
        normal[axis] = sign;
        for _ in 0..n {
            let p: Vec3 = [0, 1, 2].map(|k| {
                if k == axis || hi[k] <= lo[k] {
                    lo[k]
                } else {
                    rng.random_range(lo[k]..hi[k])
                }
            });
            let buried = match owner {
                // Shell points: only objects can bury them.
                None => room.buried_in_objects(p, None, eps),
                Some(i) => room.is_buried(p, Some(i), eps),
            };
            if buried {
                continue;
            }
            let class = match owner {
                Some(i) => room.primitives[i].class,
                None => room.shell_class(axis, sign < 0.0),
            };
            let a = albedo(palette, class, p, normal);
            let s = shade(normal);
            out.push(SurfacePoint {
                position: p,
                color: a.map(|c| ((c * s).clamp(0.0, 1.0) * 255.0).round() as u8),
                class,
            });
        }
    }
    out
}
