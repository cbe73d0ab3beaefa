//! Frames rendered by the field itself (novel views) and recorded in a run
//! directory, so that a resumed run and every evaluation rebuild exactly the
//! scene the field was trained on.
//!
//! The record is a directory holding `views.json` ([`NovelRecord`]), and per
//! view a colour PNG, a rendered depth `.npy` (`H x W` float32, metres, 0
//! where the field was not opaque enough to trust) and a feature `.npy`
//! (`h x w x c` float16, the extractor's map compressed like the scene's).
//! `views.json` is written last (atomically), so a record without it is
//! incomplete and ignored.

use std::path::{Path, PathBuf};

use half::f16;
use model::geometry::Camera;
use serde::{Deserialize, Serialize};

use crate::error::DatasetError;
use crate::features::FeatureMap;
use crate::npy::{NpyInfo, write_npy_f16, write_npy_f32};
use crate::scene::{DepthImage, Frame, RgbImage, Scene};

/// Name of the record's index file.
pub const INDEX: &str = "views.json";

/// One recorded view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NovelViewEntry {
    /// Frame name (also the stem of its files).
    pub name: String,
    /// Intrinsics and camera-to-world pose (OpenCV axes).
    pub camera: Camera,
    /// Colour image, relative to the record directory.
    pub rgb: String,
    /// Rendered depth, relative to the record directory.
    pub depth: String,
    /// Feature map, relative to the record directory.
    pub features: String,
    /// Weight of the rendered depth in the depth loss.
    pub depth_weight: f32,
    /// Weight of the rendered colour in the colour loss (records written
    /// before the weight existed trained on it at 1).
    #[serde(default = "unit_weight")]
    pub color_weight: f32,
    /// The point the camera was aimed at, when it was aimed at one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<[f64; 3]>,
    /// Normalised uncertainty of that point (guided views).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<f64>,
}

/// The index of a record: how and when the views were made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NovelRecord {
    /// How the cameras were chosen (`guided`, `trajectory` or `random`).
    pub mode: String,
    /// Training iteration the views join the training frames at.
    pub added_at: usize,
    /// The views, in the order they are appended to the scene.
    pub views: Vec<NovelViewEntry>,
}

fn unit_weight() -> f32 {
    1.0
}

/// A view to record: its camera, rendered colour and depth, and features.
#[derive(Debug, Clone, PartialEq)]
pub struct NovelView {
    /// Frame name.
    pub name: String,
    /// Camera.
    pub camera: Camera,
    /// Rendered colour.
    pub rgb: RgbImage,
    /// Rendered depth (0 = untrusted).
    pub depth: DepthImage,
    /// Feature map of the rendered colour, in the scene's feature space.
    pub features: FeatureMap,
    /// Depth-loss weight.
    pub depth_weight: f32,
    /// Colour-loss weight.
    pub color_weight: f32,
    /// Aim point.
    pub target: Option<[f64; 3]>,
    /// Uncertainty of the aim point.
    pub uncertainty: Option<f64>,
}

/// Writes `views` into `dir` (created) with `views.json` last.
pub fn write_record(
    dir: &Path,
    mode: &str,
    added_at: usize,
    views: &[NovelView],
) -> Result<NovelRecord, DatasetError> {
    std::fs::create_dir_all(dir).map_err(|e| DatasetError::io(dir, e))?;
    let mut entries = Vec::with_capacity(views.len());
    for v in views {
        let entry = NovelViewEntry {
            name: v.name.clone(),
            camera: v.camera,
            rgb: format!("{}.png", v.name),
            depth: format!("{}_depth.npy", v.name),
            features: format!("{}_features.npy", v.name),
            depth_weight: v.depth_weight,
            color_weight: v.color_weight,
            target: v.target,
            uncertainty: v.uncertainty,
        };
        crate::extractor::save_png(&v.rgb, &dir.join(&entry.rgb))?;
        let d = &v.depth;
        write_npy_f32(
            &dir.join(&entry.depth),
            &[d.height as usize, d.width as usize],
            &d.to_f32(),
        )?;
        let f = &v.features;
        write_npy_f16(
            &dir.join(&entry.features),
            &[f.height as usize, f.width as usize, f.dim],
            &f.data,
        )?;
        entries.push(entry);
    }
    let record = NovelRecord {
        mode: mode.into(),
        added_at,
        views: entries,
    };
    let index = dir.join(INDEX);
    let text = serde_json::to_string_pretty(&record)
        .map_err(|e| DatasetError::invalid(&index, e.to_string()))?;
    let tmp = dir.join(format!("{INDEX}.tmp"));
    std::fs::write(&tmp, text).map_err(|e| DatasetError::io(&tmp, e))?;
    std::fs::rename(&tmp, &index).map_err(|e| DatasetError::io(&index, e))?;
    Ok(record)
}

/// Reads the record in `dir`: `None` when it has no `views.json`.
pub fn read_record(dir: &Path) -> Result<Option<NovelRecord>, DatasetError> {
    let index = dir.join(INDEX);
    if !index.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&index).map_err(|e| DatasetError::io(&index, e))?;
    let record: NovelRecord =
        serde_json::from_str(&text).map_err(|e| DatasetError::invalid(&index, e.to_string()))?;
    Ok(Some(record))
}

/// Loads the frames and feature maps of a record, checking every file
/// against its camera and the expected feature channels.
pub fn load_views(
    dir: &Path,
    record: &NovelRecord,
    feature_dim: usize,
) -> Result<Vec<(Frame, FeatureMap)>, DatasetError> {
    record
        .views
        .iter()
        .map(|e| load_view(dir, e, feature_dim))
        .collect()
}

fn load_view(
    dir: &Path,
    e: &NovelViewEntry,
    feature_dim: usize,
) -> Result<(Frame, FeatureMap), DatasetError> {
    let (w, h) = (e.camera.intrinsics.width, e.camera.intrinsics.height);
    let rgb_path = dir.join(&e.rgb);
    let rgb = crate::imageio::load_rgb(&rgb_path, None, None)?;
    if (rgb.width, rgb.height) != (w, h) {
        return Err(DatasetError::invalid(
            &rgb_path,
            format!(
                "image is {}x{} but its camera is {w}x{h}",
                rgb.width, rgb.height
            ),
        ));
    }
    let depth_path = dir.join(&e.depth);
    let info = NpyInfo::open(&depth_path)?;
    info.expect_rank(2, "height x width")?;
    if info.shape != [h as usize, w as usize] {
        return Err(DatasetError::invalid(
            &depth_path,
            format!("depth is {:?} but its camera is {w}x{h}", info.shape),
        ));
    }
    let depth = info.read_f32_range(0, (w * h) as usize)?;
    if depth.iter().any(|d| !d.is_finite() || *d < 0.0) {
        return Err(DatasetError::invalid(
            &depth_path,
            "depth must be finite and non-negative",
        ));
    }
    let feat_path = dir.join(&e.features);
    let info = NpyInfo::open(&feat_path)?;
    info.expect_rank(3, "height x width x channels")?;
    let (fh, fw, fd) = (info.shape[0], info.shape[1], info.shape[2]);
    if fd != feature_dim || fh == 0 || fw == 0 || fh > h as usize || fw > w as usize {
        return Err(DatasetError::invalid(
            &feat_path,
            format!(
                "feature map {fh}x{fw}x{fd} does not fit a {w}x{h} view with {feature_dim} channels"
            ),
        ));
    }
    let data: Vec<f16> = info.read_f16_range(0, fh * fw * fd)?;
    if !(e.color_weight.is_finite() && (0.0..=1.0).contains(&e.color_weight)) {
        return Err(DatasetError::invalid(
            dir.join(INDEX),
            format!(
                "{}: colour weight {} is not a weight in [0, 1]",
                e.name, e.color_weight
            ),
        ));
    }
    if !(e.depth_weight.is_finite() && e.depth_weight >= 0.0) {
        return Err(DatasetError::invalid(
            dir.join(INDEX),
            format!(
                "{}: depth weight {} is not a weight",
                e.name, e.depth_weight
            ),
        ));
    }
    let frame = Frame {
        name: e.name.clone(),
        camera: e.camera,
        rgb,
        depth: Some(DepthImage {
            width: w,
            height: h,
            data: crate::scene::DepthData::F32(depth),
        }),
        depth_weight: e.depth_weight,
        color_weight: e.color_weight,
        labels: None,
        mask: None,
    };
    let map = FeatureMap {
        width: fw as u32,
        height: fh as u32,
        dim: fd,
        data,
    };
    Ok((frame, map))
}

/// Appends recorded views to `scene` (frames and feature maps). Returns the
/// indices the views received.
pub fn append(
    scene: &mut Scene,
    views: Vec<(Frame, FeatureMap)>,
) -> Result<Vec<usize>, DatasetError> {
    let set = scene.features.as_mut().ok_or_else(|| {
        DatasetError::invalid(
            PathBuf::from(&scene.name),
            "novel views carry features, but the scene has no feature maps",
        )
    })?;
    let start = scene.frames.len();
    for (frame, map) in views {
        scene.frames.push(frame);
        set.maps.push(map);
    }
    Ok((start..scene.frames.len()).collect())
}

/// Appends the record in `dir`, if there is one, to `scene`. Returns the
/// record and the indices its views received.
pub fn append_recorded(
    scene: &mut Scene,
    dir: &Path,
) -> Result<Option<(NovelRecord, Vec<usize>)>, DatasetError> {
    let Some(record) = read_record(dir)? else {
        return Ok(None);
    };
    let dim = scene.features.as_ref().map_or(0, |f| f.dim());
    let views = load_views(dir, &record, dim)?;
    let indices = append(scene, views)?;
    Ok(Some((record, indices)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::{Intrinsics, look_at};

    fn view(i: usize, w: u32, h: u32, dim: usize) -> NovelView {
        let n = (w * h) as usize;
        NovelView {
            name: format!("novel_{i:03}"),
            camera: Camera {
                intrinsics: Intrinsics::from_fov_x(w, h, 1.1),
                pose: look_at([0.1 * i as f64, 1.0, 0.3], [0.0; 3], [0.0, 0.0, 1.0]).expect("pose"),
            },
            rgb: RgbImage::from_f32(w, h, (0..3 * n).map(|k| (k % 256) as f32 / 255.0).collect()),
            depth: DepthImage {
                width: w,
                height: h,
                data: crate::scene::DepthData::F32(
                    (0..n)
                        .map(|k| if k % 5 == 0 { 0.0 } else { 0.37 * k as f32 })
                        .collect(),
                ),
            },
            features: FeatureMap {
                width: w / 2,
                height: h / 2,
                dim,
                data: (0..(w / 2 * (h / 2)) as usize * dim)
                    .map(|k| {
                        if k == 3 {
                            f16::NAN
                        } else {
                            f16::from_f32(k as f32 * 0.01)
                        }
                    })
                    .collect(),
            },
            depth_weight: 0.25,
            color_weight: 0.5 * i as f32,
            target: Some([0.0; 3]),
            uncertainty: Some(0.8),
        }
    }

    /// What is read back is what was written: 8-bit colour, exact depth,
    /// f16 features (NaN kept), camera, weight.
    #[test]
    fn a_record_reads_back_as_written() {
        let dir = tempfile::tempdir().expect("tmp");
        assert_eq!(read_record(dir.path()).expect("none"), None);
        let views = [view(0, 8, 6, 3), view(1, 8, 6, 3)];
        let record = write_record(dir.path(), "guided", 40, &views).expect("write");
        assert_eq!(read_record(dir.path()).expect("read"), Some(record.clone()));
        let back = load_views(dir.path(), &record, 3).expect("load");
        for ((frame, map), v) in back.iter().zip(&views) {
            assert_eq!(frame.name, v.name);
            assert_eq!(frame.camera, v.camera);
            assert_eq!(frame.depth.as_ref().expect("depth"), &v.depth);
            assert_eq!(frame.depth_weight, 0.25);
            assert_eq!(frame.color_weight, v.color_weight);
            for (a, b) in frame.rgb.to_f32().iter().zip(v.rgb.to_f32().iter()) {
                assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6, "{a} vs {b}");
            }
            assert_eq!((map.width, map.height, map.dim), (4, 3, 3));
            for (a, b) in map.data.iter().zip(&v.features.data) {
                assert!(a.to_bits() == b.to_bits());
            }
        }
        // The wrong channel count, or a depth map of the wrong size, is
        // named by file.
        let e = load_views(dir.path(), &record, 5).expect_err("dim");
        assert!(e.to_string().contains("novel_000_features.npy"), "{e}");
        write_npy_f32(&dir.path().join("novel_001_depth.npy"), &[2, 2], &[1.0; 4]).expect("w");
        let e = load_views(dir.path(), &record, 3).expect_err("depth");
        assert!(e.to_string().contains("novel_001_depth.npy"), "{e}");
        // A record written before the colour weight existed reads as 1; a
        // weight outside [0, 1] is refused naming the index.
        let index = std::fs::read_to_string(dir.path().join(INDEX)).expect("index");
        let old = index.replace("\"color_weight\": 0.0,", "");
        assert_ne!(old, index, "{index}");
        std::fs::write(dir.path().join(INDEX), &old).expect("w");
        let record = read_record(dir.path()).expect("old").expect("some");
        assert_eq!(record.views[0].color_weight, 1.0);
        std::fs::write(
            dir.path().join(INDEX),
            index.replace("\"color_weight\": 0.0", "\"color_weight\": 2.0"),
        )
        .expect("w");
        let record = read_record(dir.path()).expect("read").expect("some");
        let e = load_views(dir.path(), &record, 3).expect_err("weight");
        assert!(e.to_string().contains("colour weight"), "{e}");
        std::fs::write(dir.path().join(INDEX), "{\"mode\": 3").expect("w");
        let e = read_record(dir.path()).expect_err("json");
        assert!(e.to_string().contains(INDEX), "{e}");
    }
}
