//! Scenes and frames built in memory for the sampler tests.
#![allow(dead_code)]

use datasets::features::FeatureSet;
use datasets::{Frame, RgbImage, Scene, SceneSource};
use model::geometry::{Camera, Intrinsics, SceneBox, look_at};

/// Frame `i`: `w x h` pixels of grey, a camera looking at the origin from
/// `[3, i, 1]`, no depth or labels, and `mask` (`None`: every pixel kept).
pub fn grey_frame(i: usize, w: u32, h: u32, mask: Option<Vec<bool>>) -> Frame {
    let pose = look_at([3.0, i as f64, 1.0], [0.0; 3], [0.0, 0.0, 1.0]).expect("pose");
    Frame {
        name: format!("f{i}"),
        camera: Camera {
            intrinsics: Intrinsics::from_fov_x(w, h, 1.0),
            pose,
        },
        rgb: RgbImage {
            width: w,
            height: h,
            data: datasets::RgbData::F32(vec![0.5; (w * h * 3) as usize]),
        },
        depth: None,
        depth_weight: 0.0,
        color_weight: 1.0,
        labels: None,
        mask,
    }
}

/// A scene of `frames` with `features`, in the unit box, without points,
/// classes or a background.
pub fn scene_of(name: &str, frames: Vec<Frame>, features: Option<FeatureSet>) -> Scene {
    Scene {
        name: name.into(),
        frames,
        features,
        scene_box: SceneBox {
            min: [-1.0; 3],
            max: [1.0; 3],
        },
        background: None,
        points: None,
        classes: None,
        source: SceneSource::Synthetic {
            seed: 0,
            size: "ci".into(),
            pca: None,
        },
        world: None,
    }
}
