//! ScanNet exports: the Replica frames converted to ScanNet's layout (depth
//! rendered by another camera) load back with Replica's poses and depth;
//! lost-tracking poses are skipped; bad exports are refused naming the file.

use std::path::Path;

use datasets::options::FrameSelection;
use datasets::replica::{ReplicaOptions, load_replica};
use datasets::scannet::{ScannetOptions, load_scannet_with_report};
use datasets::{DepthImage, Scene};
use model::geometry::{Intrinsics, Pose};

fn write_matrix(path: &Path, m: &[[f64; 4]; 4]) {
    let text: String = m
        .iter()
        .map(|r| format!("{} {} {} {}\n", r[0], r[1], r[2], r[3]))
        .collect();
    std::fs::write(path, text).expect("matrix");
}

fn k_matrix(k: &Intrinsics) -> [[f64; 4]; 4] {
    [
        [k.fx, 0.0, k.cx, 0.0],
        [0.0, k.fy, k.cy, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// The depth camera's view of a colour-camera depth map (same centre and
/// axes): each depth pixel takes the colour pixel nearest to where its
/// centre falls (the reference the loader's splatting is checked against).
fn render_depth(colour: &DepthImage, ck: &Intrinsics, dk: &Intrinsics) -> Vec<u16> {
    let mut out = Vec::new();
    for y in 0..dk.height {
        for x in 0..dk.width {
            let u = ck.fx / dk.fx * (x as f64 - dk.cx) + ck.cx;
            let v = ck.fy / dk.fy * (y as f64 - dk.cy) + ck.cy;
            let (ui, vi) = (u.round(), v.round());
            let inside =
                ui >= 0.0 && vi >= 0.0 && ui < colour.width as f64 && vi < colour.height as f64;
            let d = if inside {
                colour.get(ui as u32, vi as u32) as f64
            } else {
                0.0
            };
            out.push((d * 1000.0).round().clamp(0.0, 65535.0) as u16);
        }
    }
    out
}

fn write_depth(path: &Path, (w, h): (u32, u32), mm: Vec<u16>) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, mm)
        .expect("size")
        .save(path)
        .expect("depth");
}

fn layout(dir: &Path) {
    for sub in ["color", "depth", "pose", "intrinsic"] {
        std::fs::create_dir_all(dir.join(sub)).expect("dir");
    }
}

const LOST: &str =
    "-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n";

/// Agreement of loaded depth with the reference where both have depth:
/// `(share within tol, share of reference pixels covered, median error)`.
fn agreement(got: &DepthImage, want: &DepthImage, tol: f32) -> (f64, f64, f32) {
    let mut errors = Vec::new();
    let mut reference = 0usize;
    for (a, b) in got.to_f32().iter().zip(want.to_f32().iter()) {
        if *b > 0.0 {
            reference += 1;
            if *a > 0.0 {
                errors.push((a - b).abs());
            }
        }
    }
    errors.sort_by(f32::total_cmp);
    let within = errors.iter().filter(|&&e| e <= tol).count();
    (
        within as f64 / errors.len().max(1) as f64,
        errors.len() as f64 / reference.max(1) as f64,
        errors.get(errors.len() / 2).copied().unwrap_or(f32::NAN),
    )
}

#[test]
fn replica_frames_in_scannet_layout_load_back() {
    // Skipped only on a machine without the shared data at all.
    let Some(src) = datasets::shared_dataset("replica_room0_20f") else {
        return;
    };
    let replica = load_replica(
        &src,
        &ReplicaOptions {
            selection: FrameSelection {
                max_frames: Some(6),
                ..FrameSelection::default()
            },
            ..ReplicaOptions::default()
        },
    )
    .expect("replica");
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path();
    layout(dir);
    let ck = replica.frames[0].camera.intrinsics;
    // A depth camera of another size, focal length and principal point.
    let dk = Intrinsics {
        width: 560,
        height: 330,
        fx: 290.0,
        fy: 295.0,
        cx: 275.3,
        cy: 160.8,
        ..ck
    };
    write_matrix(&dir.join("intrinsic/intrinsic_color.txt"), &k_matrix(&ck));
    write_matrix(&dir.join("intrinsic/intrinsic_depth.txt"), &k_matrix(&dk));
    // Numbers 0, 5, ..., 25: name order (10 before 5) is not number order.
    let number = |j: usize| 5 * j;
    for (j, f) in replica.frames.iter().enumerate() {
        let i = number(j);
        let jpg = src.join("results").join(format!("{}.jpg", f.name));
        std::fs::copy(&jpg, dir.join(format!("color/{i}.jpg"))).expect("colour");
        let depth = render_depth(f.depth.as_ref().expect("depth"), &ck, &dk);
        write_depth(
            &dir.join(format!("depth/{i}.png")),
            (dk.width, dk.height),
            depth,
        );
        let pose = dir.join(format!("pose/{i}.txt"));
        if j == 2 {
            std::fs::write(&pose, LOST).expect("pose");
        } else {
            write_matrix(&pose, &f.camera.pose.to_matrix());
        }
    }
    let (scene, report) =
        load_scannet_with_report(dir, &ScannetOptions::default()).expect("scannet");
    assert_eq!(report.skipped, vec![dir.join("pose/10.txt")]);
    let note = report.note(dir).expect("note");
    assert_eq!(
        note,
        "scannet: skipped 1 frames with invalid poses (pose/10.txt)"
    );
    let kept: Vec<usize> = vec![0, 1, 3, 4, 5];
    assert_eq!(scene.frames.len(), kept.len());
    assert!(scene.world.is_none());
    let tol = 0.01 + 0.0005 + 0.5 / 6553.5;
    for (f, &j) in scene.frames.iter().zip(&kept) {
        let r = &replica.frames[j];
        assert_eq!(f.name, format!("frame{:06}", number(j)));
        assert_eq!(f.camera, r.camera);
        assert_eq!(f.rgb, r.rgb);
        let (within, covered, median) = agreement(
            f.depth.as_ref().expect("d"),
            r.depth.as_ref().expect("d"),
            tol,
        );
        println!(
            "{}: depth covers {:.1}% of Replica's pixels, {:.2}% of them within {:.1} mm, \
             median error {:.2} mm",
            f.name,
            100.0 * covered,
            100.0 * within,
            1000.0 * tol,
            1000.0 * median
        );
        assert!(covered >= 0.9 && within >= 0.8, "{}", f.name);
    }
    check_resolution(dir, &src);
}

/// At a lower resolution the depth agrees with Replica's depth resampled
/// to that resolution.
fn check_resolution(dir: &Path, src: &Path) {
    let res = (600, 340);
    let scene: Scene = datasets::scannet::load_scannet(
        dir,
        &ScannetOptions {
            selection: FrameSelection {
                resolution: Some(res),
                max_frames: Some(2),
                ..FrameSelection::default()
            },
            ..ScannetOptions::default()
        },
    )
    .expect("scannet at 600x340");
    let replica = load_replica(
        src,
        &ReplicaOptions {
            selection: FrameSelection {
                max_frames: Some(2),
                resolution: Some(res),
                ..FrameSelection::default()
            },
            ..ReplicaOptions::default()
        },
    )
    .expect("replica");
    for (f, r) in scene.frames.iter().zip(&replica.frames) {
        assert_eq!(f.camera, r.camera);
        let (within, covered, median) = agreement(
            f.depth.as_ref().expect("d"),
            r.depth.as_ref().expect("d"),
            0.0105 + 0.5 / 6553.5,
        );
        println!(
            "{} at 600x340: covers {:.1}%, {:.2}% within 1 cm, median {:.2} mm",
            f.name,
            100.0 * covered,
            100.0 * within,
            1000.0 * median
        );
        assert!(covered >= 0.9 && within >= 0.8);
    }
}

/// A tiny export: three 64x48 frames, depth at half size (the same field
/// of view) at 1.234 m.
fn tiny_export(dir: &Path) {
    layout(dir);
    let ck = Intrinsics::from_fov_x(64, 48, 1.0);
    let dk = ck.scaled(32, 24);
    write_matrix(&dir.join("intrinsic/intrinsic_color.txt"), &k_matrix(&ck));
    write_matrix(&dir.join("intrinsic/intrinsic_depth.txt"), &k_matrix(&dk));
    for i in 0..3 {
        image::RgbImage::from_pixel(64, 48, image::Rgb([10, 20, 30 * i as u8]))
            .save(dir.join(format!("color/{i}.png")))
            .expect("colour");
        write_depth(
            &dir.join(format!("depth/{i}.png")),
            (32, 24),
            vec![1234; 32 * 24],
        );
        let mut m = Pose::identity().to_matrix();
        m[0][3] = i as f64;
        write_matrix(&dir.join(format!("pose/{i}.txt")), &m);
    }
}

/// Loads the tiny export after `edit`, returning the error message.
fn refused(edit: impl FnOnce(&Path)) -> String {
    let tmp = tempfile::tempdir().expect("tmp");
    tiny_export(tmp.path());
    edit(tmp.path());
    let Err(e) = load_scannet_with_report(tmp.path(), &ScannetOptions::default()) else {
        panic!("loaded a bad export");
    };
    println!("refused: {e}");
    e.to_string()
}

#[test]
fn lost_poses_are_skipped_and_bad_exports_refused() {
    let tmp = tempfile::tempdir().expect("tmp");
    tiny_export(tmp.path());
    std::fs::write(tmp.path().join("pose/1.txt"), LOST).expect("pose");
    let (scene, report) =
        load_scannet_with_report(tmp.path(), &ScannetOptions::default()).expect("loads");
    assert_eq!(scene.frames.len(), 2);
    assert_eq!(report.skipped.len(), 1);
    assert_eq!(scene.frames[1].camera.pose.translation, [2.0, 0.0, 0.0]);
    // Depth at half size with the same view covers every colour pixel.
    let d = scene.frames[0].depth.as_ref().expect("depth");
    assert!(d.to_f32().iter().all(|&v| (v - 1.234).abs() < 1e-6));

    let msg = refused(|d| {
        write_depth(&d.join("depth/0.png"), (32, 32), vec![1; 32 * 32]);
    });
    assert!(
        msg.contains("depth/0.png") && msg.contains("principal point"),
        "{msg}"
    );
    let msg = refused(|d| {
        write_depth(&d.join("depth/2.png"), (16, 12), vec![1; 16 * 12]);
    });
    assert!(
        msg.contains("depth/2.png") && msg.contains("16x12"),
        "{msg}"
    );
    let msg =
        refused(|d| std::fs::remove_file(d.join("intrinsic/intrinsic_depth.txt")).expect("rm"));
    assert!(
        msg.contains("intrinsic_depth.txt") && msg.contains("missing"),
        "{msg}"
    );
    let msg =
        refused(|d| std::fs::remove_file(d.join("intrinsic/intrinsic_color.txt")).expect("rm"));
    assert!(
        msg.contains("intrinsic_color.txt") && msg.contains("missing"),
        "{msg}"
    );
    let msg = refused(|d| std::fs::remove_file(d.join("depth/2.png")).expect("rm"));
    assert!(
        msg.contains("depth/2.png") && msg.contains("missing depth"),
        "{msg}"
    );
    let msg = refused(|d| {
        let mut m = Pose::identity().to_matrix();
        m[0][0] = 2.0;
        write_matrix(&d.join("pose/0.txt"), &m);
    });
    assert!(msg.contains("pose/0.txt") && msg.contains("rigid"), "{msg}");
    let msg = refused(|d| {
        for i in 0..3 {
            std::fs::write(d.join(format!("pose/{i}.txt")), LOST).expect("pose");
        }
    });
    assert!(msg.contains("no frame with a valid pose"), "{msg}");
}
