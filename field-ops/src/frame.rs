//! The frame outputs are written in: the scene's own (where the field was
//! trained) or the capture's original world frame (e.g. COLMAP's), which a
//! loader moved the scene out of and recorded in `scene.json`.

use datasets::SceneMeta;
use model::geometry::{Camera, Similarity, Vec3};

use crate::OpsError;

/// `--frame`: which frame point clouds and camera poses are written in.
#[derive(Debug, Clone, clap::Args)]
pub struct FrameArgs {
    /// Frame of the written point clouds and camera poses: `scene` (the
    /// frame the field was trained in), `capture` (the capture's own world
    /// frame, whichever it is) or that frame by its name (`colmap` for a
    /// COLMAP or nerfstudio capture, `arkit` for a phone capture; the
    /// transform between them is in the run's `scene.json` under `world`).
    #[arg(long, default_value = "scene")]
    pub frame: String,
}

/// A map from the scene's frame to the frame outputs are written in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputFrame {
    /// Scene frame to output frame.
    pub from_scene: Similarity,
    /// Output frame to scene frame (for point clouds a user gives in it).
    pub to_scene: Similarity,
}

impl Default for FrameArgs {
    fn default() -> Self {
        Self {
            frame: "scene".into(),
        }
    }
}

impl FrameArgs {
    /// The output frame these flags ask for, checked against the run's
    /// scene: a capture frame must be the one the run recorded.
    pub fn resolve(&self, meta: &SceneMeta) -> Result<OutputFrame, OpsError> {
        if self.frame == "scene" {
            return Ok(OutputFrame::SCENE);
        }
        match &meta.world {
            Some(w) if w.name == self.frame || self.frame == "capture" => Ok(OutputFrame {
                from_scene: w.to_scene.inverse(),
                to_scene: w.to_scene,
            }),
            Some(w) => Err(OpsError::Invalid(format!(
                "--frame {}: this run's capture frame is `{}` (use --frame {}, --frame capture \
                 or --frame scene)",
                self.frame, w.name, w.name
            ))),
            None => Err(OpsError::Invalid(format!(
                "--frame {}: this run's scene was not moved out of a capture frame, so its \
                 outputs are already in the capture's coordinates (use --frame scene)",
                self.frame
            ))),
        }
    }
}

impl OutputFrame {
    /// The scene's own frame.
    pub const SCENE: Self = Self {
        from_scene: Similarity::IDENTITY,
        to_scene: Similarity::IDENTITY,
    };

    /// True when outputs are written in the scene's own frame.
    pub fn is_scene(&self) -> bool {
        self.from_scene == Similarity::IDENTITY
    }

    /// A point in the output frame.
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.from_scene.apply_point(p)
    }

    /// Points in the output frame.
    pub fn points(&self, ps: &[Vec3]) -> Vec<Vec3> {
        ps.iter().map(|&p| self.point(p)).collect()
    }

    /// Points given in the output frame (a user's point cloud), in the
    /// scene's frame.
    pub fn scene_points(&self, ps: &[Vec3]) -> Vec<Vec3> {
        ps.iter().map(|&p| self.to_scene.apply_point(p)).collect()
    }

    /// A camera in the output frame (same intrinsics; the pose mapped).
    pub fn camera(&self, c: &Camera) -> Camera {
        Camera {
            intrinsics: c.intrinsics,
            pose: self.from_scene.apply_pose(&c.pose),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use datasets::{SceneSource, WorldFrame};
    use model::geometry::SceneBox;

    fn meta(world: Option<WorldFrame>) -> SceneMeta {
        SceneMeta {
            source: SceneSource::Synthetic {
                seed: 0,
                size: "ci".into(),
                pca: None,
            },
            scene_box: SceneBox {
                min: [-1.0; 3],
                max: [1.0; 3],
            },
            background: None,
            pca: None,
            feature_dim: None,
            world,
        }
    }

    #[test]
    fn capture_frame_maps_back_and_wrong_names_are_refused() {
        let to_scene = Similarity {
            rotation: [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            scale: 0.5,
            translation: [1.0, 2.0, 3.0],
        };
        let m = meta(Some(WorldFrame {
            name: "colmap".into(),
            to_scene,
            fitted_to: String::new(),
        }));
        let args = |f: &str| FrameArgs { frame: f.into() };
        let out = args("colmap").resolve(&m).expect("colmap frame");
        let p = [0.3, -2.0, 5.0];
        let back = out.point(to_scene.apply_point(p));
        assert!((0..3).all(|i| (back[i] - p[i]).abs() < 1e-12), "{back:?}");
        let there = out.scene_points(&[p])[0];
        assert_eq!(there, to_scene.apply_point(p));
        assert!(!out.is_scene());
        assert_eq!(args("capture").resolve(&m).expect("capture frame"), out);
        assert!(args("scene").resolve(&m).expect("scene").is_scene());
        let e = args("nerfstudio").resolve(&m).expect_err("other name");
        assert!(e.to_string().contains("`colmap`"), "{e}");
        let e = args("colmap")
            .resolve(&meta(None))
            .expect_err("no capture frame");
        assert!(e.to_string().contains("--frame scene"), "{e}");
        let e = args("capture")
            .resolve(&meta(None))
            .expect_err("no capture frame");
        assert!(e.to_string().contains("--frame scene"), "{e}");
    }
}
