//! Replica frames as a 3D Scanner App "All Data" export.

use std::path::Path;

use anyhow::{Context, Result};
use model::geometry::Camera;

use super::{ReplicaFrames, confidence, copy, millimetres, write_png8, write_png16};

/// What to put in the export.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScannerExport {
    /// Write the LiDAR depth and confidence maps.
    pub depth: bool,
    /// Write `textured_output.obj` (+ `.mtl`, `.jpg`).
    pub mesh: bool,
}

/// Frames whose depth makes the mesh (its texture stacks their images).
pub const MESH_FRAMES: [usize; 4] = [0, 5, 10, 15];

/// Writes `frames` to `out` as a 3D Scanner App export: frame `i` is
/// `frame_{2i:05}` (the app numbers every ARKit frame and keeps images of
/// some), with a pose-only JSON `frame_{2i+1:05}.json` after each.
pub fn write(frames: &ReplicaFrames, out: &Path, what: ScannerExport) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("{}", out.display()))?;
    let k = frames.intrinsics;
    let size = frames.depth_size();
    for i in 0..frames.images.len() {
        let n = 2 * i;
        copy(&frames.images[i], &out.join(format!("frame_{n:05}.jpg")))?;
        let pose = frames.arkit_pose(i);
        let json = serde_json::json!({
            "cameraPoseARFrame": pose.iter().flatten().collect::<Vec<_>>(),
            "intrinsics": [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
            "projectionMatrix": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            "motionQuality": 1.0,
            "time": i as f64 / 6.0,
        });
        for m in [n, n + 1] {
            let path = out.join(format!("frame_{m:05}.json"));
            std::fs::write(&path, json.to_string())
                .with_context(|| format!("{}", path.display()))?;
        }
        if what.depth {
            let depth = frames.depth(i)?;
            write_png16(
                &out.join(format!("depth_{n:05}.png")),
                size,
                millimetres(&depth),
            )?;
            write_png8(
                &out.join(format!("conf_{n:05}.png")),
                size,
                confidence(i, &depth),
            )?;
        }
    }
    if what.mesh {
        write_mesh(frames, out)?;
    }
    Ok(())
}

/// Writes `textured_output.obj`: for each of [`MESH_FRAMES`], a grid of
/// triangles through every other depth pixel, leaving out cells across a
/// depth edge; UVs into a texture of the frames' images stacked top to
/// bottom.
fn write_mesh(frames: &ReplicaFrames, out: &Path) -> Result<()> {
    let (dw, dh) = frames.depth_size();
    let to_arkit = ReplicaFrames::to_arkit();
    let (w, h) = (frames.intrinsics.width, frames.intrinsics.height);
    let slots = MESH_FRAMES.len() as u32;
    let mut atlas = image::RgbImage::new(w, h * slots);
    let mut obj = String::from("mtllib textured_output.mtl\nusemtl textured\n");
    let mut faces = String::new();
    let mut next = 1usize; // OBJ indices start at 1
    let step = 2u32;
    for (slot, &i) in MESH_FRAMES.iter().enumerate() {
        let img = image::open(&frames.images[i])
            .with_context(|| format!("{}", frames.images[i].display()))?
            .to_rgb8();
        image::imageops::replace(&mut atlas, &img, 0, slot as i64 * h as i64);
        let depth = frames.depth(i)?;
        let camera = Camera {
            intrinsics: frames.intrinsics.scaled(dw, dh),
            pose: frames.poses[i],
        };
        let (gw, gh) = (dw.div_ceil(step), dh.div_ceil(step));
        let mut index = vec![0usize; (gw * gh) as usize];
        for gy in 0..gh {
            for gx in 0..gw {
                let (x, y) = (gx * step, gy * step);
                let d = depth.get(x, y) as f64;
                if d <= 0.0 {
                    continue;
                }
                let r = camera.ray(x as f64, y as f64);
                let p =
                    to_arkit.apply_point(std::array::from_fn(|a| r.origin[a] + d * r.direction[a]));
                let u = (x as f64 + 0.5) / dw as f64;
                let v_top = (slot as f64 + (y as f64 + 0.5) / dh as f64) / slots as f64;
                obj.push_str(&format!(
                    "v {} {} {}\nvt {} {}\n",
                    p[0],
                    p[1],
                    p[2],
                    u,
                    1.0 - v_top
                ));
                index[(gy * gw + gx) as usize] = next;
                next += 1;
            }
        }
        for gy in 0..gh.saturating_sub(1) {
            for gx in 0..gw.saturating_sub(1) {
                let at = |dx: u32, dy: u32| {
                    let i = index[((gy + dy) * gw + gx + dx) as usize];
                    (i, depth.get((gx + dx) * step, (gy + dy) * step))
                };
                let c = [at(0, 0), at(1, 0), at(0, 1), at(1, 1)];
                let (lo, hi) = c
                    .iter()
                    .fold((f32::MAX, 0f32), |(lo, hi), &(_, d)| (lo.min(d), hi.max(d)));
                if c.iter().any(|&(i, _)| i == 0) || hi > 1.03 * lo {
                    continue;
                }
                let [a, b, cc, d] = c.map(|(i, _)| i);
                faces.push_str(&format!(
                    "f {a}/{a} {cc}/{cc} {b}/{b}\nf {b}/{b} {cc}/{cc} {d}/{d}\n"
                ));
            }
        }
    }
    obj.push_str(&faces);
    let write = |name: &str, text: &str| {
        let p = out.join(name);
        std::fs::write(&p, text).with_context(|| format!("{}", p.display()))
    };
    write("textured_output.obj", &obj)?;
    write(
        "textured_output.mtl",
        "newmtl textured\nKd 1 1 1\nmap_Kd textured_output.jpg\n",
    )?;
    let p = out.join("textured_output.jpg");
    atlas.save(&p).with_context(|| format!("{}", p.display()))
}
