//! What a closer look can teach: per class of a synthetic room, how often
//! the simulated extractor names a surface correctly in the captured views,
//! and in views placed 0.5, 1 and 2 metres in front of the class's surface
//! points (rendered from the ground truth, so the field plays no part).
//!
//! Novel views can only correct the classes the extractor reads right from
//! close by: where even a close, perfect render is misread, the error is
//! the extractor's own (look-alike colours, its prior for large classes),
//! repeated in every view, and no choice of camera fixes it.
//!
//! `cargo run -p bench --release --example extractor_reach -- [SEED] [SCALE]`
//! (seed 21 and scale 0.5, the render scale of novel views, by default).

use datasets::extractor::FeatureExtractor;
use datasets::grid::nearest_pixel;
use datasets::scene::RgbImage;
use datasets::synthetic::{self, CLASSES, SceneSize, build_room, classes, raytrace};
use model::geometry::{Camera, Intrinsics, Vec3, look_at, norm, sub};

/// Distances of the close views, metres.
const DISTANCES: [f64; 3] = [0.5, 1.0, 2.0];
/// Surface points tried per class.
const POINTS_PER_CLASS: usize = 40;
/// Every this many captured views is read.
const CAPTURE_STRIDE: usize = 5;

/// Index of the class embedding with the largest dot product with `f`.
fn read_class(f: &[f32], emb: &[f32], dim: usize) -> usize {
    let mut best = (0, f32::NEG_INFINITY);
    for (c, row) in emb.chunks(dim).enumerate() {
        let s: f32 = row.iter().zip(f).map(|(a, b)| a * b).sum();
        if s > best.1 {
            best = (c, s);
        }
    }
    best.0
}

/// The class read at every pixel of the extractor's map of `rgb`, row-major.
fn read_at(
    ex: &impl FeatureExtractor,
    rgb: &RgbImage,
    emb: &[f32],
    dim: usize,
) -> Result<Vec<usize>, Box<dyn std::error::Error>> {
    let map = ex.extract(rgb)?;
    Ok((0..(map.width * map.height) as usize)
        .map(|i| {
            let f: Vec<f32> = map.data[i * map.dim..(i + 1) * map.dim]
                .iter()
                .map(|v| v.to_f32())
                .collect();
            read_class(&f, emb, dim)
        })
        .collect())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let seed: u64 = args.next().map_or(Ok(21), |s| s.parse())?;
    let scale: f64 = args.next().map_or(Ok(0.5), |s| s.parse())?;
    let size = SceneSize::Bench;
    let room = build_room(seed);
    let palette = classes::palette(seed);
    let ex = synthetic::extractor_for(seed, size);
    // Rows already L2-normalised: the dot product ranks like the cosine.
    let emb = ex.embeddings();
    let nc = CLASSES.len();

    // Captured views: every map pixel against the label under its centre.
    let cams = synthetic::trajectory(&room, size, seed)?;
    let mut captured = vec![(0usize, 0usize); nc];
    for cam in cams.iter().step_by(CAPTURE_STRIDE) {
        let r = raytrace::render_view(&room, &palette, cam);
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let (mw, mh) = ex.map_size(w, h);
        let read = read_at(&ex, &r.rgb, &emb.data, emb.dim)?;
        for y in 0..mh {
            for x in 0..mw {
                let (px, py) = nearest_pixel(x as f64, y as f64, (mw, mh), (w, h));
                let label = r.labels[(py * w + px) as usize] as usize;
                if label < nc {
                    captured[label].1 += 1;
                    captured[label].0 += usize::from(read[(y * mw + x) as usize] == label);
                }
            }
        }
    }

    // Close views: the map pixel at the image centre, where the point is.
    let (_, w, h) = size.views();
    let side = |n: u32| ((n as f64 * scale).round() as u32).max(1);
    let k = Intrinsics::from_fov_x(side(w), side(h), synthetic::FOV_X);
    let (mw, mh) = ex.map_size(k.width, k.height);
    let cloud = synthetic::surface_points(&room, seed, size);
    let labels = cloud
        .labels
        .as_ref()
        .ok_or("surface points carry no labels")?;
    let centre = [
        0.5 * (room.min[0] + room.max[0]),
        0.5 * (room.min[1] + room.max[1]),
        1.5,
    ];
    println!("seed {seed}, close views at {}x{}", k.width, k.height);
    println!("| class | size | captured | 0.5 m | 1 m | 2 m |");
    println!("|---|---|---|---|---|---|");
    for (c, info) in CLASSES.iter().enumerate() {
        let pts: Vec<Vec3> = cloud
            .positions
            .iter()
            .zip(labels)
            .filter(|&(_, &l)| l == c as i64)
            .map(|(p, _)| *p)
            .collect();
        let stride = (pts.len() / POINTS_PER_CLASS).max(1);
        let mut close = [(0usize, 0usize); DISTANCES.len()];
        for &p in pts.iter().step_by(stride) {
            let d = sub(centre, p);
            let n = norm(d);
            if n < 1e-6 {
                continue;
            }
            for (slot, &dist) in close.iter_mut().zip(&DISTANCES) {
                let eye: Vec3 = std::array::from_fn(|i| p[i] + dist * d[i] / n);
                let Ok(pose) = look_at(eye, p, [0.0, 0.0, 1.0]) else {
                    continue;
                };
                if !room.is_free(eye, 0.02) {
                    continue;
                }
                let cam = Camera {
                    intrinsics: k,
                    pose,
                };
                let r = raytrace::render_view(&room, &palette, &cam);
                let (cx, cy) = (k.width / 2, k.height / 2);
                if r.labels[(cy * k.width + cx) as usize] as usize != c {
                    continue; // the point is hidden from here
                }
                let read = read_at(&ex, &r.rgb, &emb.data, emb.dim)?;
                slot.1 += 1;
                slot.0 += usize::from(read[((mh / 2) * mw + mw / 2) as usize] == c);
            }
        }
        let pct = |(ok, n): (usize, usize)| {
            if n == 0 {
                "-".to_string()
            } else {
                format!("{:.0}% of {n}", 100.0 * ok as f64 / n as f64)
            }
        };
        println!(
            "| {} | {} | {} | {} | {} | {} |",
            info.name,
            info.size,
            pct(captured[c]),
            pct(close[0]),
            pct(close[1]),
            pct(close[2])
        );
    }
    Ok(())
}
