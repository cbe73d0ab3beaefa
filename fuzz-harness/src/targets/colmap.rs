//! Targets of COLMAP's sparse models (binary and text) and depth maps.
//!
//! Each model file is fuzzed through `colmap::read_model` on a directory
//! whose other two files are small valid companions, then every camera's
//! intrinsics and every image's pose are converted, as loading does.

use std::fmt::Write as _;
use std::path::Path;

use datasets::colmap::{self, binary, depth};

use super::{Seeds, Target, present};

const BIN_TOKENS: &[&str] = &[
    "\u{1}\0\0\0",
    "\0\0\0\0\0\0\0\0",
    "\u{ff}\u{ff}\u{ff}\u{ff}",
];

const TEXT_TOKENS: &[&str] = &[
    "# comment\n",
    "PINHOLE",
    "SIMPLE_RADIAL",
    "OPENCV",
    "FULL_OPENCV",
    "FOV",
    " -1",
    " 4294967295",
    "\n\n",
    "nan",
];

/// The statue's model as its parts' bytes (cameras, images, points).
fn statue(s: &Seeds, part: &str) -> Option<Vec<u8>> {
    s.data_file(&format!("colmap_statue/sparse/{part}.bin"))
}

/// A one-camera `cameras.bin` (PINHOLE 64x48).
fn small_cameras_bin() -> Vec<u8> {
    let mut b = 1u64.to_le_bytes().to_vec();
    b.extend(1u32.to_le_bytes());
    b.extend(1i32.to_le_bytes());
    b.extend(64u64.to_le_bytes());
    b.extend(48u64.to_le_bytes());
    [50.0f64, 51.0, 32.0, 24.0]
        .iter()
        .for_each(|v| b.extend(v.to_le_bytes()));
    b
}

/// A two-image `images.bin` on camera 1, the first seeing point 1.
fn small_images_bin() -> Vec<u8> {
    let mut b = 2u64.to_le_bytes().to_vec();
    for (id, name) in [(1u32, "a.png"), (2, "dir/b.jpg")] {
        b.extend(id.to_le_bytes());
        [1.0f64, 0.0, 0.0, 0.0, 0.5, -0.25, 2.0]
            .iter()
            .for_each(|v| b.extend(v.to_le_bytes()));
        b.extend(1u32.to_le_bytes());
        b.extend(name.as_bytes());
        b.push(0);
        let points: &[(f64, f64, u64)] = if id == 1 {
            &[(10.0, 12.0, 1), (3.0, 4.0, u64::MAX)]
        } else {
            &[]
        };
        b.extend((points.len() as u64).to_le_bytes());
        for (x, y, p) in points {
            b.extend(x.to_le_bytes());
            b.extend(y.to_le_bytes());
            b.extend(p.to_le_bytes());
        }
    }
    b
}

/// A one-point `points3D.bin` seen by image 1.
fn small_points_bin() -> Vec<u8> {
    let mut b = 1u64.to_le_bytes().to_vec();
    b.extend(1u64.to_le_bytes());
    [0.5f64, 0.25, 3.0]
        .iter()
        .for_each(|v| b.extend(v.to_le_bytes()));
    b.extend([200u8, 100, 50]);
    b.extend(0.75f64.to_le_bytes());
    b.extend(1u64.to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.extend(0u32.to_le_bytes());
    b
}

/// The small model in COLMAP's text format (cameras, images, points).
const SMALL_TEXT: [&str; 3] = [
    "# Camera list\n1 PINHOLE 64 48 50 51 32 24\n2 SIMPLE_RADIAL 640 480 500 320 240 0.01\n",
    "# Image list\n1 1 0 0 0 0.5 -0.25 2 1 a.png\n10 12 1 3 4 -1\n\
2 0.7071 0 0.7071 0 0 0 1 2 dir/b.jpg\n\n",
    "# 3D point list\n1 0.5 0.25 3 200 100 50 0.75 1 0\n",
];

/// The statue's model converted to text (all cameras, the first images and
/// points), for seeds as long as real text models.
fn statue_text(s: &Seeds, part: usize) -> Option<Vec<u8>> {
    let dir = s.data.join("colmap_statue/sparse");
    let mut out = String::new();
    match part {
        0 => {
            for c in binary::read_cameras(&dir.join("cameras.bin"))
                .ok()?
                .values()
            {
                let params: Vec<String> = c.params.iter().map(|p| p.to_string()).collect();
                let (id, model, w, h) = (c.id, c.model.name(), c.width, c.height);
                let _ = writeln!(out, "{id} {model} {w} {h} {}", params.join(" "));
            }
        }
        1 => {
            for im in binary::read_images(&dir.join("images.bin"))
                .ok()?
                .iter()
                .take(3)
            {
                let [qw, qx, qy, qz] = im.qvec;
                let [tx, ty, tz] = im.tvec;
                let (id, cam, name) = (im.id, im.camera_id, &im.name);
                let _ = writeln!(out, "{id} {qw} {qx} {qy} {qz} {tx} {ty} {tz} {cam} {name}");
                let pts: Vec<String> = im
                    .points2d
                    .iter()
                    .take(20)
                    .map(|p| {
                        let id3 = p.point3d_id.map_or(-1i128, |v| v as i128);
                        format!("{} {} {id3}", p.xy[0], p.xy[1])
                    })
                    .collect();
                let _ = writeln!(out, "{}", pts.join(" "));
            }
        }
        _ => {
            for p in binary::read_points(&dir.join("points3D.bin"))
                .ok()?
                .iter()
                .take(50)
            {
                let [x, y, z] = p.xyz;
                let [r, g, b] = p.rgb;
                let track: Vec<String> = p.track.iter().map(|(i, k)| format!("{i} {k}")).collect();
                let (id, e) = (p.id, p.error);
                let _ = writeln!(out, "{id} {x} {y} {z} {r} {g} {b} {e} {}", track.join(" "));
            }
        }
    }
    Some(out.into_bytes())
}

/// Reads the model in `path`'s directory and converts what loading converts.
fn run_model(path: &Path) {
    let Some(dir) = path.parent() else { return };
    if let Ok(model) = colmap::read_model(dir) {
        for c in model.cameras.values() {
            let _ = c.intrinsics();
        }
        for im in &model.images {
            let _ = im.pose();
        }
    }
}

fn bin_setup(dir: &Path, own: &str) -> std::io::Result<()> {
    let parts = [
        ("cameras.bin", small_cameras_bin()),
        ("images.bin", small_images_bin()),
        ("points3D.bin", small_points_bin()),
    ];
    for (name, bytes) in parts {
        if name != own {
            std::fs::write(dir.join(name), bytes)?;
        }
    }
    Ok(())
}

fn text_setup(dir: &Path, own: &str) -> std::io::Result<()> {
    for (name, text) in ["cameras.txt", "images.txt", "points3D.txt"]
        .iter()
        .zip(SMALL_TEXT)
    {
        if *name != own {
            std::fs::write(dir.join(name), text)?;
        }
    }
    Ok(())
}

fn depth_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let mut a = b"4&3&1&".to_vec();
    (0..12).for_each(|i| a.extend((i as f32 * 0.5).to_le_bytes()));
    let mut b = b"2 & 2 & 1 &".to_vec();
    [1.0f32, -1.0, f32::NAN, 0.0]
        .iter()
        .for_each(|v| b.extend(v.to_le_bytes()));
    present([Some(a), Some(b)])
}

fn run_depth(path: &Path) {
    if let Ok(raw) = depth::read_depth_map(path) {
        let _ = depth::depth_target(path, &raw, (8, 6), 1.0);
    }
}

macro_rules! model_target {
    ($name:literal, $file:literal, $tokens:expr, $seeds:expr, $setup:ident) => {
        Target {
            name: $name,
            about: concat!("colmap::read_model with a mutated ", $file),
            file: $file,
            tokens: $tokens,
            seeds: $seeds,
            setup: |dir, _| $setup(dir, $file),
            run: run_model,
        }
    };
}

/// The targets of this module.
pub(super) fn targets() -> Vec<Target> {
    vec![
        model_target!(
            "colmap-cameras-bin",
            "cameras.bin",
            BIN_TOKENS,
            |s| present([Some(small_cameras_bin()), statue(s, "cameras")]),
            bin_setup
        ),
        model_target!(
            "colmap-images-bin",
            "images.bin",
            BIN_TOKENS,
            |s| present([Some(small_images_bin()), statue(s, "images")]),
            bin_setup
        ),
        model_target!(
            "colmap-points-bin",
            "points3D.bin",
            BIN_TOKENS,
            |s| present([Some(small_points_bin()), statue(s, "points3D")]),
            bin_setup
        ),
        model_target!(
            "colmap-cameras-txt",
            "cameras.txt",
            TEXT_TOKENS,
            |s| present([Some(SMALL_TEXT[0].into()), statue_text(s, 0)]),
            text_setup
        ),
        model_target!(
            "colmap-images-txt",
            "images.txt",
            TEXT_TOKENS,
            |s| present([Some(SMALL_TEXT[1].into()), statue_text(s, 1)]),
            text_setup
        ),
        model_target!(
            "colmap-points-txt",
            "points3D.txt",
            TEXT_TOKENS,
            |s| present([Some(SMALL_TEXT[2].into()), statue_text(s, 2)]),
            text_setup
        ),
        Target {
            name: "colmap-depth",
            about: "colmap::depth::read_depth_map, depth_target",
            file: "depth.bin",
            tokens: &["&", "1&", "4294967296&"],
            seeds: depth_seeds,
            setup: |_, _| Ok(()),
            run: run_depth,
        },
    ]
}
