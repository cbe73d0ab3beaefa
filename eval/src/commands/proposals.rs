//! The proposals part of `eval uncertainty`: novel cameras written as a
//! `transforms.json`-style file, with a preview render of each.

use std::path::{Path, PathBuf};

use datasets::Scene;
use field_ops::OpsError;
use field_ops::depth_image::DepthQuantity;
use field_ops::images::save_view_pngs;
use field_ops::novel::cameras::{mean_centre, scene_up};
use field_ops::novel::guided::{FieldProbe, GuidedProposals, ProposalOptions, guided_proposals};
use field_ops::render::{ViewSettings, render_view};
use field_ops::run_dir::{RunDir, Split, load_run};
use field_ops::uncertainty::UncertaintyMap;
use model::geometry::{Camera, Intrinsics, Pose, Vec3};
use rand::SeedableRng;
use serde_json::json;

use field_ops::backend::BackendArgs;

/// Width of the preview renders, pixels (the aspect ratio is kept).
const PREVIEW_WIDTH: u32 = 160;

/// A nerfstudio-style `transforms.json` of cameras sharing `intrinsics`:
/// each frame has its name as `file_path`, its pose as an OpenGL
/// `transform_matrix`, and the fields of its `extra` object.
pub fn transforms_json(
    intrinsics: Intrinsics,
    frames: impl Iterator<Item = (String, Pose, serde_json::Value)>,
) -> serde_json::Value {
    let k = intrinsics;
    let frames: Vec<serde_json::Value> = frames
        .map(|(name, pose, extra)| {
            let mut f = json!({ "file_path": name, "transform_matrix": pose.to_opengl() });
            if let (Some(f), Some(e)) = (f.as_object_mut(), extra.as_object()) {
                f.extend(e.clone());
            }
            f
        })
        .collect();
    // nerfstudio's principal point is in pixel-edge coordinates.
    json!({
        "w": k.width, "h": k.height, "fl_x": k.fx, "fl_y": k.fy,
        "cx": k.cx + 0.5, "cy": k.cy + 0.5,
        "frames": frames,
    })
}

/// How many cameras to propose, with which draw, on which backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProposalRequest {
    /// Most cameras proposed.
    pub views: usize,
    /// Seed of the target draw and the position noise.
    pub seed: u64,
    /// Backend and device of the field's checks and the previews.
    pub compute: BackendArgs,
}

/// Proposes cameras, writes `novel_views.json` and previews into `out`.
#[allow(clippy::too_many_arguments)]
pub fn write_proposals(
    args: ProposalRequest,
    run_dir: &RunDir,
    scene: &Scene,
    split: &Split,
    points: &[Vec3],
    map: &UncertaintyMap,
    out: &Path,
) -> Result<Vec<PathBuf>, OpsError> {
    let device = args.compute.device();
    let run = load_run(&run_dir.dir, &device)?;
    let opts = ProposalOptions {
        max_views: args.views,
        ..ProposalOptions::default()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed);
    let first = *split.train.first().ok_or_else(|| {
        OpsError::Invalid(format!(
            "{}: the run has no training frames to place novel cameras by",
            run_dir.split().display()
        ))
    })?;
    let intrinsics = scene.frames[first].camera.intrinsics;
    let probe = FieldProbe {
        model: &run.model,
        scene_box: &run.meta.scene_box,
        device: &device,
        samples: 64,
        background: run.meta.background,
    };
    let GuidedProposals {
        targets_drawn,
        proposals,
    } = guided_proposals(
        map,
        points,
        intrinsics,
        scene_up(scene, &split.train),
        mean_centre(scene, &split.train),
        &probe,
        &opts,
        &mut rng,
    );
    println!(
        "proposed {} novel cameras from {} candidate targets drawn by uncertainty",
        proposals.len(),
        targets_drawn
    );
    let mut written = Vec::new();
    let file = transforms_json(
        intrinsics,
        proposals.iter().enumerate().map(|(i, p)| {
            (
                format!("novel_{i:03}"),
                p.camera.pose,
                json!({
                    "target": points[p.target],
                    "uncertainty": map.normalised[p.target],
                    "transmittance": p.transmittance,
                    "color_error": p.color_error,
                }),
            )
        }),
    );
    let k = intrinsics;
    let path = out.join("novel_views.json");
    field_ops::json::write_json(&path, &file)?;
    written.push(path);
    let previews = out.join("previews");
    for (i, p) in proposals.iter().enumerate() {
        let w = PREVIEW_WIDTH.min(k.width);
        let h = ((k.height as f64 * w as f64 / k.width as f64).round() as u32).max(1);
        let cam = Camera {
            intrinsics: k.scaled(w, h),
            pose: p.camera.pose,
        };
        let settings = ViewSettings::new(run.meta.background, 4096);
        let view = render_view(&run.model, &cam, &run.meta.scene_box, &settings)
            .expect("never cancelled without an observer");
        let depth = DepthQuantity::of(&run.model);
        written.extend(save_view_pngs(
            &view,
            &previews,
            &format!("novel_{i:03}"),
            depth,
        )?);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::look_at;

    #[test]
    fn written_cameras_load_back_as_the_same_cameras() {
        let k = Intrinsics {
            width: 64,
            height: 48,
            fx: 50.0,
            fy: 52.0,
            cx: 31.5,
            cy: 23.0,
            distortion: model::geometry::Distortion::NONE,
        };
        let poses = [
            look_at([1.0, 2.0, 0.5], [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).expect("pose"),
            look_at([-1.0, 0.2, 2.0], [0.3, 0.0, 0.0], [0.0, 0.0, 1.0]).expect("pose"),
        ];
        let file = transforms_json(
            k,
            poses
                .iter()
                .enumerate()
                .map(|(i, p)| (format!("novel_{i:03}"), *p, json!({ "uncertainty": 0.5 }))),
        );
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("novel_views.json");
        field_ops::json::write_json(&path, &file).expect("write");
        let cams = crate::cameras::load_transforms_json(&path).expect("load");
        assert_eq!(cams.len(), 2);
        for (c, p) in cams.iter().zip(&poses) {
            let i = c.camera.intrinsics;
            assert_eq!((i.width, i.height), (64, 48));
            for (a, b) in [(i.fx, k.fx), (i.fy, k.fy), (i.cx, k.cx), (i.cy, k.cy)] {
                assert!((a - b).abs() < 1e-12, "{a} vs {b}");
            }
            let (m, n) = (c.camera.pose.to_matrix(), p.to_matrix());
            for r in 0..4 {
                for col in 0..4 {
                    assert!((m[r][col] - n[r][col]).abs() < 1e-12);
                }
            }
        }
        assert_eq!(cams[1].name, "novel_001");
    }
}
