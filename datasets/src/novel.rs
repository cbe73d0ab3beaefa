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
use crate::npy::{NpyInfo, write_npy_f16, write_npy_f32};
use crate::scene::{DepthImage, FeatureMap, Frame, RgbImage, Scene};

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
            target: v.target,
            uncertainty: v.uncertainty,
        };
        crate::extractor::save_png(&v.rgb, &dir.join(&entry.rgb))?;
        let d = &v.depth;
        write_npy_f32(
            &dir.join(&entry.depth),
            &[d.height as usize, d.width as usize],
            &d.data,
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
            data: depth,
        }),
        depth_weight: e.depth_weight,
        labels: None,
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
