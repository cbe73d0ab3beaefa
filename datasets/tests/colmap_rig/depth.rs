//! Dense depth maps of the rig: a plane's true z-depth, with holes.

use datasets::grid::nearest_pixel;

use super::*;

/// A COLMAP `.geometric.bin` depth map.
pub fn encode(w: u32, h: u32, values: &[f32]) -> Vec<u8> {
    let mut b = format!("{w}&{h}&1&").into_bytes();
    for v in values {
        b.extend(v.to_le_bytes());
    }
    b
}

/// z-depth of the plane through the target perpendicular to up (the rig's
/// floor) along the camera's ray through pixel `(u, v)`.
fn plane_depth(cam: &Camera, u: f64, v: f64) -> f64 {
    let r = cam.ray(u, v);
    dot(UP, sub(TARGET, r.origin)) / dot(UP, r.direction)
}

/// The plane's depth map of a camera at `w x h`, with a zero, a NaN and a
/// negative depth in the first row.
fn plane_map(cam: &Camera, w: u32, h: u32) -> Vec<f32> {
    let c = cam.scaled(w, h);
    let mut m: Vec<f32> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| plane_depth(&c, x as f64, y as f64) as f32)
        .collect();
    m[0] = 0.0;
    m[1] = f32::NAN;
    m[2] = -1.0;
    m
}

pub fn depth_dir(dir: &Path) -> std::path::PathBuf {
    let d = dir.join("stereo").join("depth_maps");
    std::fs::create_dir_all(&d).expect("mkdir");
    d
}

/// Writes every camera's map (camera 1's at half size); returns the maps.
pub fn write_depth_maps(dir: &Path, cams: &[RigCam]) -> Vec<(u32, u32, Vec<f32>)> {
    let d = depth_dir(dir);
    cams.iter()
        .enumerate()
        .map(|(i, c)| {
            let k = &c.camera.intrinsics;
            let (w, h) = if i == 1 {
                (k.width / 2, k.height / 2)
            } else {
                (k.width, k.height)
            };
            let m = plane_map(&c.camera, w, h);
            let name = format!("{}.geometric.bin", image_name(i));
            std::fs::write(d.join(name), encode(w, h, &m)).expect("write");
            (w, h, m)
        })
        .collect()
}

#[test]
fn depth_targets_are_the_planes_depth_in_scene_units() {
    let cams = rig();
    let dir = rig_dir(&cams);
    let maps = write_depth_maps(dir.path(), &cams);
    let opts = ColmapOptions {
        depth: true,
        ..Default::default()
    };
    let scene = load_colmap(dir.path(), &opts).expect("loads");
    let world = scene.world.expect("world").to_scene;
    let s = world.scale;
    for (i, (frame, (mw, mh, map))) in scene.frames.iter().zip(&maps).enumerate() {
        let depth = frame.depth.as_ref().expect("depth");
        assert_eq!(frame.depth_weight, 1.0);
        let k = &frame.camera.intrinsics;
        assert_eq!((depth.width, depth.height), (k.width, k.height));
        let mut valid = 0;
        for y in 0..k.height {
            for x in 0..k.width {
                let (sx, sy) = nearest_pixel(x as f64, y as f64, (k.width, k.height), (*mw, *mh));
                let raw = map[(sy * mw + sx) as usize] as f64;
                let got = depth.get(x, y) as f64;
                if raw.is_nan() || raw <= 0.0 {
                    assert_eq!(got, 0.0, "camera {i} pixel ({x}, {y})");
                    continue;
                }
                valid += 1;
                assert!(
                    (got - raw * s).abs() <= 1e-6 * raw * s,
                    "{got} vs {raw} * {s}"
                );
                if i != 1 {
                    let truth = plane_depth(&cams[i].camera, x as f64, y as f64);
                    assert!((got - truth * s).abs() <= 1e-6 * truth * s);
                    // The point at that depth lies on the rig's plane.
                    let r = frame.camera.ray(x as f64, y as f64);
                    let p = world
                        .inverse()
                        .apply_point(add_scaled(r.origin, got, r.direction));
                    assert!(dot(UP, sub(p, TARGET)).abs() < 1e-5, "{p:?}");
                }
            }
        }
        assert!(
            valid > (k.width * k.height) as usize * 9 / 10,
            "camera {i}: {valid}"
        );
        assert_eq!(depth.get(0, 0), 0.0);
    }
}
