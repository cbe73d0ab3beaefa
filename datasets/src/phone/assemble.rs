//! [`assemble`]: any phone capture into a scene (the module docs of
//! [`crate::phone`] say how).

use std::path::Path;

use model::geometry::{Camera, Intrinsics, SceneBox, Similarity, Vec3, aligning_yaw, yaw_rotation};

use super::{ARKIT_FRAME, ARKIT_TO_Z_UP, Assembled, Capture, CaptureFrame, DepthSource};
use crate::error::DatasetError;
use crate::mesh::{Raycaster, TriangleMesh, read_obj};
use crate::options::{LoaderOptions, PhoneOptions};
use crate::points::PointCloud;
use crate::poses::{box_of, checked_pose};
use crate::scannet::reproject_depth;
use crate::scene::{DepthImage, Frame, Scene, SceneSource, WorldFrame};

/// Largest relative difference between the aspect ratios of a depth map and
/// its colour image (they are one camera at two resolutions).
const ASPECT_TOLERANCE: f64 = 0.01;

/// The pose of `frame` in the z-up (not yet centred) frame, OpenCV axes.
fn z_up_pose(frame: &CaptureFrame) -> Result<model::geometry::Pose, DatasetError> {
    let arkit = checked_pose(&frame.pose_file, "camera pose", frame.pose, true)?;
    Ok(up().apply_pose(&arkit))
}

fn up() -> Similarity {
    Similarity {
        rotation: ARKIT_TO_Z_UP,
        scale: 1.0,
        translation: [0.0; 3],
    }
}

/// Checks that the depth map (`depth` of `size`) has the colour image's
/// aspect ratio.
fn check_aspect(path: &Path, size: (u32, u32), colour: &Intrinsics) -> Result<(), DatasetError> {
    let aspect = |w: u32, h: u32| w as f64 / h as f64;
    let (d, c) = (aspect(size.0, size.1), aspect(colour.width, colour.height));
    if size.0 == 0 || size.1 == 0 || ((d - c) / c).abs() > ASPECT_TOLERANCE {
        return Err(DatasetError::invalid(
            path,
            format!(
                "depth map is {}x{}, not the {}x{} colour image's aspect ratio: it cannot be \
                 the colour camera's view",
                size.0, size.1, colour.width, colour.height
            ),
        ));
    }
    Ok(())
}

/// Pixels a frame's depth lost to each mask.
#[derive(Debug, Default, Clone, Copy)]
struct Dropped {
    confidence: usize,
    range: usize,
    all: usize,
}

/// The frame's sensor depth at the colour camera `target`: masked by
/// confidence and range, then reprojected.
fn sensor_depth(
    frame: &CaptureFrame,
    depth: &DepthSource,
    colour: &Intrinsics,
    target: &Intrinsics,
    options: &PhoneOptions,
    dropped: &mut Dropped,
) -> Result<DepthImage, DatasetError> {
    let mut raw = depth.load()?;
    let size = (raw.width, raw.height);
    check_aspect(depth.path(), size, colour)?;
    let levels = frame
        .confidence
        .as_ref()
        .map(|c| c.load(size))
        .transpose()?;
    let min = options.min_depth_confidence.level();
    for (i, d) in raw.values_mut().iter_mut().enumerate() {
        dropped.all += 1;
        if *d <= 0.0 {
            continue;
        }
        if levels.as_ref().is_some_and(|l| l[i] < min) {
            dropped.confidence += 1;
            *d = 0.0;
        } else if *d as f64 > options.max_depth {
            dropped.range += 1;
            *d = 0.0;
        }
    }
    Ok(reproject_depth(
        &raw,
        &colour.scaled(size.0, size.1),
        target,
    ))
}

/// The intrinsics of `frame` at its image's actual size `size`, refusing an
/// image of another aspect ratio than the intrinsics describe.
fn colour_intrinsics(frame: &CaptureFrame, size: (u32, u32)) -> Result<Intrinsics, DatasetError> {
    let k = frame.intrinsics;
    if (k.width, k.height) == size {
        return Ok(k);
    }
    let (a, b) = (
        k.width as f64 / k.height as f64,
        size.0 as f64 / size.1 as f64,
    );
    if ((a - b) / b).abs() > ASPECT_TOLERANCE {
        return Err(DatasetError::invalid(
            frame.image.path(),
            format!(
                "image is {}x{} but its intrinsics ({}) describe a {}x{} image",
                size.0,
                size.1,
                frame.pose_file.display(),
                k.width,
                k.height
            ),
        ));
    }
    Ok(k.scaled(size.0, size.1))
}

/// Turns a phone capture into a scene (module docs), without its feature
/// maps ([`crate::load_disk`] attaches them).
pub fn assemble(
    dir: &Path,
    options: &PhoneOptions,
    capture: Capture,
    loader: &LoaderOptions,
) -> Result<Assembled, DatasetError> {
    options.selection.check(dir)?;
    if !(options.max_depth.is_finite() && options.max_depth > 0.0) {
        return Err(DatasetError::invalid(dir, "max depth must be positive"));
    }
    let mut notes = capture.notes;
    let kept = select(&options.selection, capture.frames, &mut notes)?;
    let Some(first) = kept.first() else {
        return Err(DatasetError::invalid(dir, "the export holds no frame"));
    };
    let first_size = first.image.dimensions()?;
    let has_depth = kept.iter().any(|f| f.depth.is_some()) || capture.mesh.is_some();
    let ((tw, th), chosen) = crate::footprint::plan_size(
        dir,
        &options.selection,
        kept.len(),
        first_size,
        if has_depth { 2 } else { 0 },
        true,
    )?;
    if let Some(line) = &chosen {
        eprintln!("{}: {line}", loader.format());
    }
    let resolution = chosen.map(|_| (tw, th));
    let up = up();
    let mesh = match &capture.mesh {
        Some(path) => {
            let file = read_obj(path)?;
            notes.extend(file.notes);
            Some(transformed(file.mesh, &up))
        }
        None => None,
    };
    let any_depth = kept.iter().any(|f| f.depth.is_some());
    let raycaster = match (&mesh, any_depth) {
        (Some(m), false) => {
            notes.push("no depth maps: depth targets are ray-cast from the mesh".into());
            Some(Raycaster::new(m))
        }
        _ => None,
    };
    if mesh.is_none() && !any_depth {
        notes.push("no depth maps and no mesh: the field is trained on colour alone".into());
    }
    let frames = load_frames(
        &kept,
        first_size,
        (tw, th),
        raycaster.as_ref(),
        options,
        &mut notes,
    )?;
    // The box holds the cameras, the mesh and the sensor's depth maps: a
    // mesh can cover less than the depth maps do (cropped in the app, made
    // from part of the scan), and a box cut at the mesh cuts the field there.
    let depth_points = any_depth.then(|| depth_cloud(&frames, options.box_pixel_step));
    let (points, fitted, also) = match (mesh, depth_points) {
        (Some(m), depth) => {
            let n = m.positions.len();
            let fitted = match depth {
                Some(_) => format!("the mesh's {n} vertices and the depth maps"),
                None => format!("the mesh's {n} vertices"),
            };
            let also = depth.map(|d| d.positions).unwrap_or_default();
            (m.point_cloud(), fitted, also)
        }
        (None, depth) => (
            depth.unwrap_or_default(),
            "the depth maps".to_string(),
            Vec::new(),
        ),
    };
    let (frames, points, scene_box, shift) =
        centred(dir, frames, points, &also, options.box_margin)?;
    let world = WorldFrame {
        name: ARKIT_FRAME.into(),
        to_scene: shift.compose(&up),
        fitted_to: format!(
            "z up from ARKit's gravity-aligned y, metric; turned about z to the tightest \
             box of the {} cameras and {fitted}, and centred on it",
            frames.len()
        ),
    };
    let scene = Scene {
        name: dir.file_name().map_or(loader.format().name().into(), |n| {
            n.to_string_lossy().into_owned()
        }),
        frames,
        features: None,
        scene_box,
        background: None,
        points: (!points.positions.is_empty()).then_some(points),
        classes: None,
        source: SceneSource::Disk {
            loader: loader.without_basis(),
            path: dir.to_path_buf(),
        },
        world: Some(world),
    };
    Ok(Assembled {
        scene,
        notes,
        resolution,
    })
}

/// The frames `selection` keeps: by sharpness within windows when it says
/// so (the export's own blur scores where every frame has one, else the
/// variance of the Laplacian of each decoded image; a note says which),
/// else by stride.
fn select(
    selection: &crate::options::FrameSelection,
    frames: Vec<CaptureFrame>,
    notes: &mut Vec<String>,
) -> Result<Vec<CaptureFrame>, DatasetError> {
    let listed = frames.len();
    let by_blur_score = frames.iter().all(|f| f.blur_score.is_some());
    let kept = selection.select_sharpest(frames, |f| match f.blur_score {
        Some(s) if by_blur_score => Ok(s),
        _ => f.image.sharpness(),
    })?;
    if let Some(k) = selection.sharpest_of.filter(|&k| k > 1) {
        let by = if by_blur_score {
            "the export's blur scores"
        } else {
            "the variance of the Laplacian"
        };
        notes.push(format!(
            "kept the sharpest frame of each {k} ({} of {listed}, by {by})",
            kept.len()
        ));
    }
    Ok(kept)
}

/// The kept frames, loaded at `size` (`first_size` the images' own size):
/// poses in the z-up frame, depth from the sensor or the mesh.
fn load_frames(
    kept: &[CaptureFrame],
    first_size: (u32, u32),
    (tw, th): (u32, u32),
    raycaster: Option<&Raycaster>,
    options: &PhoneOptions,
    notes: &mut Vec<String>,
) -> Result<Vec<Frame>, DatasetError> {
    let any_depth = kept.iter().any(|f| f.depth.is_some());
    let loaded = crate::progress::par_map(kept, "loading frames", |cf| {
        load_frame(cf, first_size, (tw, th), raycaster, options)
    })?;
    let mut dropped = Dropped::default();
    let frames = loaded
        .into_iter()
        .map(|(frame, d)| {
            dropped.confidence += d.confidence;
            dropped.range += d.range;
            dropped.all += d.all;
            frame
        })
        .collect();
    if any_depth && dropped.all > 0 {
        let pct = |n: usize| 100.0 * n as f64 / dropped.all as f64;
        notes.push(format!(
            "{:.1}% of depth pixels below {} confidence and {:.1}% beyond {} m are no target",
            pct(dropped.confidence),
            options.min_depth_confidence.name(),
            pct(dropped.range),
            options.max_depth
        ));
    }
    Ok(frames)
}

/// One frame loaded at `(tw, th)`, with the depth pixels it dropped.
fn load_frame(
    cf: &CaptureFrame,
    first_size: (u32, u32),
    (tw, th): (u32, u32),
    raycaster: Option<&Raycaster>,
    options: &PhoneOptions,
) -> Result<(Frame, Dropped), DatasetError> {
    let mut dropped = Dropped::default();
    let size = cf.image.dimensions()?;
    if size != first_size {
        return Err(DatasetError::invalid(
            cf.image.path(),
            format!(
                "image is {}x{}, the first image {}x{}",
                size.0, size.1, first_size.0, first_size.1
            ),
        ));
    }
    let colour = colour_intrinsics(cf, size)?;
    let target = colour.scaled(tw, th);
    let camera = Camera {
        intrinsics: target,
        pose: z_up_pose(cf)?,
    };
    let depth = match (&cf.depth, raycaster) {
        (Some(d), _) => Some(sensor_depth(
            cf,
            d,
            &colour,
            &target,
            options,
            &mut dropped,
        )?),
        (None, Some(r)) => Some(r.depth_image(&camera)),
        (None, None) => None,
    }
    // Half floats keep the LiDAR's centimetres and halve the memory.
    .map(DepthImage::to_half);
    let rgb = cf.image.load_rgb((tw, th))?;
    Ok((
        Frame::captured(cf.name.clone(), camera, rgb, depth),
        dropped,
    ))
}

/// Frames, points and box turned about the vertical so that the smallest
/// rectangle around the footprint of the camera centres, the points and
/// `also` (positions the box must hold that are not the scene's points)
/// runs along x and y, and moved so that their box is centred on the
/// origin, with the map that did it.
fn centred(
    dir: &Path,
    mut frames: Vec<Frame>,
    points: PointCloud,
    also: &[Vec3],
    margin: f64,
) -> Result<(Vec<Frame>, PointCloud, SceneBox, Similarity), DatasetError> {
    let mut extent: Vec<Vec3> = frames.iter().map(|f| f.camera.pose.center()).collect();
    extent.extend(points.positions.iter().copied());
    extent.extend(also.iter().copied());
    let turn = yaw_rotation(aligning_yaw(&extent));
    let turned: Vec<Vec3> = extent.iter().map(|&p| turn.apply_point(p)).collect();
    let centre = box_of(dir, turned, 0.0)?.center();
    let map = Similarity {
        translation: centre.map(|c| -c),
        ..Similarity::IDENTITY
    }
    .compose(&turn);
    for f in &mut frames {
        f.camera.pose = map.apply_pose(&f.camera.pose);
    }
    let points = PointCloud {
        positions: points
            .positions
            .iter()
            .map(|&p| map.apply_point(p))
            .collect(),
        ..points
    };
    let scene_box = box_of(
        dir,
        extent.iter().map(|&p| map.apply_point(p)).collect(),
        margin,
    )?;
    Ok((frames, points, scene_box, map))
}

/// `mesh` with its vertices mapped by `s`.
fn transformed(mesh: TriangleMesh, s: &Similarity) -> TriangleMesh {
    TriangleMesh {
        positions: mesh.positions.iter().map(|&p| s.apply_point(p)).collect(),
        ..mesh
    }
}

/// Every `step`-th depth pixel of every frame, with its image's colour.
fn depth_cloud(frames: &[Frame], step: u32) -> PointCloud {
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    let step = step.max(1);
    for f in frames {
        let Some(depth) = &f.depth else { continue };
        for y in (0..depth.height).step_by(step as usize) {
            for x in (0..depth.width).step_by(step as usize) {
                let d = depth.get(x, y) as f64;
                if d > 0.0 {
                    let r = f.camera.ray(x as f64, y as f64);
                    positions.push(std::array::from_fn(|i| r.origin[i] + d * r.direction[i]));
                    colors.push(f.rgb.get(x, y).map(|c| (c * 255.0).round() as u8));
                }
            }
        }
    }
    PointCloud {
        positions,
        colors: Some(colors),
        labels: None,
    }
}
