//! Depth targets from the sparse points: every feature that observes a
//! well-placed point gives that point's z-depth (COLMAP's own projection,
//! in scene units) at the feature's pixel, and no other pixel has one.

use super::*;

/// Point 7's mean reprojection error: above the loader's 2 px limit.
const BAD_POINT: usize = 7;

/// The rig's model with every point listed as a feature of each image it
/// projects into (COLMAP's projection, pixel-corner convention), point
/// `BAD_POINT` badly placed, and one feature that observes no point.
fn rig_with_features(cams: &[RigCam]) -> [String; 3] {
    let [cameras, images, points] = rig_text(cams, &rig_points());
    let mut lines = images.lines();
    let mut out = format!("{}\n", lines.next().expect("header"));
    for cam in cams {
        out += &format!("{}\n", lines.next().expect("pose line"));
        lines.next();
        let k = &cam.camera.intrinsics;
        let mut features = vec!["1.5 2.5 -1".to_string()];
        for (id, p) in rig_points().into_iter().enumerate() {
            let (u, v) = colmap_project(cam, p);
            if u >= 0.0 && v >= 0.0 && u < k.width as f64 && v < k.height as f64 {
                features.push(format!("{u} {v} {id}"));
            }
        }
        out += &format!("{}\n", features.join(" "));
    }
    let points = points
        .lines()
        .map(|l| match l.split(' ').next() {
            Some(id) if id == BAD_POINT.to_string() => l.replacen(" 0.5 ", " 3 ", 1),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    [cameras, out, points + "\n"]
}

#[test]
fn sparse_depth_targets_are_the_points_z_depths_at_their_features() {
    let cams = rig();
    let dir = tempfile::tempdir().expect("tmp");
    write_model(dir.path(), &rig_with_features(&cams));
    write_images(dir.path(), "images", &cams, 1);
    let opts = ColmapOptions {
        sparse_depth: true,
        ..Default::default()
    };
    let scene = load_colmap(dir.path(), &opts).expect("loads");
    let s = scene.world.as_ref().expect("world").to_scene.scale;
    let mut targets = 0;
    for (i, (frame, cam)) in scene.frames.iter().zip(&cams).enumerate() {
        let depth = frame.depth.as_ref().expect("sparse depth");
        let k = &frame.camera.intrinsics;
        assert_eq!((depth.width, depth.height), (k.width, k.height));
        // The nearest good point whose feature falls in each pixel.
        let mut want = vec![0.0f64; (k.width * k.height) as usize];
        let (r, t) = world_to_camera(&cam.camera.pose);
        for (id, p) in rig_points().into_iter().enumerate() {
            let (u, v) = colmap_project(cam, p);
            let z = (0..3).map(|j| r[2][j] * p[j]).sum::<f64>() + t[2];
            if id == BAD_POINT || u < 0.0 || v < 0.0 || u >= k.width as f64 || v >= k.height as f64
            {
                continue;
            }
            let cell = &mut want[(v.floor() as u32 * k.width + u.floor() as u32) as usize];
            if *cell == 0.0 || z * s < *cell {
                *cell = z * s;
            }
        }
        for (j, (&got, &w)) in depth.to_f32().iter().zip(&want).enumerate() {
            assert!(
                (got as f64 - w).abs() <= 1e-5 * w.max(1.0),
                "camera {i} pixel {j}: {got} vs {w}"
            );
        }
        targets += want.iter().filter(|&&w| w > 0.0).count();
    }
    assert!(targets > 60, "{targets} targets");
    // Without the option the loader gives no depth.
    let plain = load_colmap(dir.path(), &ColmapOptions::default()).expect("loads");
    assert!(plain.frames.iter().all(|f| f.depth.is_none()));
}
