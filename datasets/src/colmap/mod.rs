//! COLMAP reconstructions: a directory with the images (`images/`, or a
//! downscaled copy such as `images_2` named by [`ColmapOptions::images`])
//! and a sparse model in `sparse/0/` or `sparse/`, binary (`cameras.bin`,
//! `images.bin`, `points3D.bin`) or text (`.txt`), as COLMAP writes them
//! ([`read_model`] detects which). With [`ColmapOptions::depth`], COLMAP's
//! dense depth maps `stereo/depth_maps/<image>.geometric.bin` are the
//! depth targets; with [`ColmapOptions::sparse_depth`], the sparse points'
//! depths at the pixels of the features that observe them
//! ([`sparse_depth`]).
//!
//! Cameras: `SIMPLE_PINHOLE`, `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL` and
//! `OPENCV` are read (with their radial-tangential distortion); other
//! models are refused with a pointer to COLMAP's `image_undistorter`.
//! COLMAP's principal point counts from the pixel corner, ours from the
//! pixel centre (`cx = cx_colmap - 0.5`); intrinsics are scaled to the
//! size of the image files found. Images store world-to-camera poses,
//! converted to camera-to-world (OpenCV axes).
//!
//! Scene frame ([`frame`]): COLMAP's world frame is arbitrary, so every
//! pose, point and depth is moved by a similarity into a frame where up
//! (the cameras' mean up vector) is +z, and the region the capture sees
//! (the sparse points' robust box, per-axis 2nd to 98th percentiles, grown
//! to hold every image's footprint at the median depth of its points; with
//! too few points, fitted to the cameras, see [`frame::FrameFit`]) is
//! centred on the origin with largest side 3 units, like the synthetic
//! scenes of a few units the sampler is tuned for. The map is recorded as
//! the scene's [`WorldFrame`] `colmap`. The scene box is that region grown
//! by [`ColmapOptions::box_margin`] of its largest extent; cameras may lie
//! outside it (their rays start where they enter it). The frame is computed
//! from every registered image and point, whatever the stride. With
//! [`ColmapOptions::feature_input`], the feature maps `<image stem>.npy` are
//! loaded for the frames kept.
//!
//! Frames are sorted by image name, then `stride` and `max_frames` apply;
//! a frame's name is its image file's stem.

pub mod binary;
pub mod camera;
pub mod depth;
pub mod frame;
pub mod model;
pub mod sparse_depth;
pub mod text;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::model::geometry::{Camera, Intrinsics, Pose, Vec3};

pub use self::model::{
    Camera as ColmapCamera, CameraModel, Image, Model, ModelFormat, Point2D, Point3D,
};
use crate::detect::Format;
use crate::error::DatasetError;
use crate::imageio;
pub use crate::options::ColmapOptions;
use crate::options::LoaderOptions;
use crate::points::PointCloud;
use crate::scene::{Frame, Scene, SceneSource, WorldFrame};
use crate::sharpness::file_sharpness;

/// The model directory of a reconstruction: `dir/sparse/0` when it holds
/// a model, else `dir/sparse`.
pub fn sparse_dir(dir: &Path) -> Result<PathBuf, DatasetError> {
    let sparse = dir.join("sparse");
    [sparse.join("0"), sparse.clone()]
        .into_iter()
        .find(|d| model_format(d).is_some())
        .ok_or_else(|| {
            DatasetError::invalid(
                &sparse,
                "no COLMAP model: expected cameras.bin or cameras.txt in sparse/0 or sparse",
            )
        })
}

/// The format of the model in `sparse` (binary when `cameras.bin` exists,
/// else text when `cameras.txt` does), `None` when there is none.
pub fn model_format(sparse: &Path) -> Option<ModelFormat> {
    [ModelFormat::Binary, ModelFormat::Text]
        .into_iter()
        .find(|&f| model::model_file(sparse, f, "cameras").is_file())
}

/// Reads the sparse model in `sparse` (binary or text, detected), checking
/// that every image's camera exists.
pub fn read_model(sparse: &Path) -> Result<Model, DatasetError> {
    let format = model_format(sparse).ok_or_else(|| {
        DatasetError::invalid(sparse, "no COLMAP model: no cameras.bin or cameras.txt")
    })?;
    let file = |part| model::model_file(sparse, format, part);
    let (cameras, images, points) = match format {
        ModelFormat::Binary => (
            binary::read_cameras(&file("cameras"))?,
            binary::read_images(&file("images"))?,
            binary::read_points(&file("points3D"))?,
        ),
        ModelFormat::Text => (
            text::read_cameras(&file("cameras"))?,
            text::read_images(&file("images"))?,
            text::read_points(&file("points3D"))?,
        ),
    };
    let model = Model {
        dir: sparse.to_path_buf(),
        format,
        cameras,
        images,
        points,
    };
    model.validate()?;
    Ok(model)
}

/// One registered image, converted: its full-size intrinsics and its
/// camera-to-world pose in COLMAP's frame.
struct View<'a> {
    image: &'a Image,
    intrinsics: Intrinsics,
    pose: Pose,
}

/// Converts every image of the model.
fn views(model: &Model) -> Result<Vec<View<'_>>, DatasetError> {
    model
        .images
        .iter()
        .map(|image| {
            let camera = model.cameras.get(&image.camera_id).ok_or_else(|| {
                DatasetError::invalid(
                    model.file("images"),
                    format!(
                        "image {} refers to camera {}, which does not exist",
                        image.id, image.camera_id
                    ),
                )
            })?;
            let intrinsics = camera
                .intrinsics()
                .map_err(|m| DatasetError::invalid(model.file("cameras"), m))?;
            let pose = image
                .pose()
                .map_err(|m| DatasetError::invalid(model.file("images"), m))?;
            Ok(View {
                image,
                intrinsics,
                pose,
            })
        })
        .collect()
}

/// The intrinsics `k` scaled to an image file of `(w, h)` pixels, which
/// must have `k`'s aspect ratio (within a pixel).
pub fn fit_to_image(
    path: &Path,
    k: &Intrinsics,
    (w, h): (u32, u32),
) -> Result<Intrinsics, DatasetError> {
    if (w, h) == (k.width, k.height) {
        return Ok(*k);
    }
    let expected_h = w as f64 * k.height as f64 / k.width as f64;
    let expected_w = h as f64 * k.width as f64 / k.height as f64;
    if (h as f64 - expected_h).abs() > 1.0 || (w as f64 - expected_w).abs() > 1.0 {
        return Err(DatasetError::invalid(
            path,
            format!(
                "image is {w}x{h}, which does not have the aspect ratio of its {}x{} camera",
                k.width, k.height
            ),
        ));
    }
    Ok(k.scaled(w, h))
}

/// The frame of one view, in the scene frame.
fn load_frame(
    dir: &Path,
    model: &Model,
    view: &View<'_>,
    options: &ColmapOptions,
    to_scene: &::model::geometry::Similarity,
    points: &HashMap<u64, (Vec3, f64)>,
) -> Result<Frame, DatasetError> {
    let name = &view.image.name;
    let path = dir.join(&options.images).join(name);
    if !path.is_file() {
        return Err(DatasetError::invalid(
            &path,
            format!(
                "image file not found ({} lists it as image {})",
                model::file_name(&model.file("images")),
                view.image.id
            ),
        ));
    }
    let size = imageio::dimensions(&path)?;
    let intrinsics = fit_to_image(&path, &view.intrinsics, size)?;
    let rgb = imageio::load_rgb(&path, None, None)?;
    let depth = if options.depth {
        let dpath = depth::depth_path(dir, name);
        let raw = depth::read_depth_map(&dpath)?;
        Some(depth::depth_target(&dpath, &raw, size, to_scene.scale)?)
    } else if options.sparse_depth {
        let pose = to_scene.apply_pose(&view.pose);
        let width = view.intrinsics.width;
        let d = sparse_depth::sparse_depth_target(view.image, &pose, points, width, size);
        // An image that observes no point has no depth at all.
        (0..d.len()).any(|i| d.value(i) > 0.0).then_some(d)
    } else {
        None
    };
    Ok(Frame {
        name: Path::new(name)
            .file_stem()
            .map_or_else(|| name.clone(), |s| s.to_string_lossy().into_owned()),
        camera: Camera {
            intrinsics,
            pose: to_scene.apply_pose(&view.pose),
        },
        rgb,
        depth_weight: if depth.is_some() { 1.0 } else { 0.0 },
        color_weight: 1.0,
        depth,
        labels: None,
        mask: None,
    })
}

/// Loads a COLMAP reconstruction directory (see the module documentation),
/// with its feature maps ([`crate::load_disk`]).
pub fn load_colmap(dir: &Path, options: &ColmapOptions) -> Result<Scene, DatasetError> {
    crate::load_disk(dir, &LoaderOptions::Colmap(options.clone()))
}

/// [`load_colmap`] without the feature maps, which
/// [`crate::load_disk`] attaches.
pub(crate) fn load_without_features(
    dir: &Path,
    options: &ColmapOptions,
) -> Result<Scene, DatasetError> {
    options.selection.check_without_resampling(
        dir,
        Format::Colmap,
        "pick a downscaled copy of the images with images (e.g. images_2)",
    )?;
    let model = read_model(&sparse_dir(dir)?)?;
    if model.images.is_empty() {
        return Err(DatasetError::invalid(
            model.file("images"),
            "the model has no registered image",
        ));
    }
    let mut views = views(&model)?;
    let positions: Vec<Vec3> = model.points.iter().map(|p| p.xyz).collect();
    let cameras: Vec<Camera> = views
        .iter()
        .map(|v| Camera {
            intrinsics: v.intrinsics,
            pose: v.pose,
        })
        .collect();
    let poses: Vec<Pose> = cameras.iter().map(|c| c.pose).collect();
    let fit = frame::frame_fit(&positions, &poses);
    let to_scene = frame::to_scene(&cameras, &positions)
        .map_err(|m| DatasetError::invalid(model.file("points3D"), m))?;
    views.sort_by(|a, b| a.image.name.cmp(&b.image.name));
    let mapped: Vec<Vec3> = positions.iter().map(|&p| to_scene.apply_point(p)).collect();
    // Only the sparse depth targets look points up by id.
    let by_id = if options.sparse_depth && !options.depth {
        sparse_depth::points_by_id(&model.points, &mapped)
    } else {
        HashMap::new()
    };
    let kept = options
        .selection
        .select_sharpest(views.iter().collect(), |v| {
            file_sharpness(&dir.join(&options.images).join(&v.image.name))
        })?;
    if let Some(first) = kept.first() {
        let image = dir.join(&options.images).join(&first.image.name);
        if let Ok(size) = imageio::dimensions(&image) {
            let depth = if options.depth || options.sparse_depth {
                4
            } else {
                0
            };
            crate::footprint::check_fits(dir, &options.selection, kept.len(), size, depth)?;
        }
    }
    let frames = crate::progress::par_map(&kept, "loading frames", |v| {
        load_frame(dir, &model, v, options, &to_scene, &by_id)
    })?;
    let mapped_cameras: Vec<Camera> = cameras
        .iter()
        .map(|c| Camera {
            intrinsics: c.intrinsics,
            pose: to_scene.apply_pose(&c.pose),
        })
        .collect();
    let scene_box =
        frame::scene_box(&mapped, &mapped_cameras, options.box_margin).ok_or_else(|| {
            DatasetError::invalid(model.file("points3D"), "no point to bound the scene")
        })?;
    Ok(Scene {
        name: dir
            .file_name()
            .map_or("colmap".into(), |n| n.to_string_lossy().into_owned()),
        frames,
        features: None,
        scene_box,
        background: None,
        points: Some(PointCloud {
            positions: mapped,
            colors: Some(model.points.iter().map(|p| p.rgb).collect()),
            labels: None,
        }),
        classes: None,
        source: SceneSource::Disk {
            loader: LoaderOptions::Colmap(options.clone()),
            path: dir.to_path_buf(),
        },
        world: Some(WorldFrame {
            name: "colmap".into(),
            to_scene,
            fitted_to: fit.describe(),
        }),
    })
}
