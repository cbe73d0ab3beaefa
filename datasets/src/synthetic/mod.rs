//! The built-in benchmark scene: a seeded procedural room (floor, ceiling,
//! walls, furniture and tiny objects labelled with Replica class names),
//! ray-traced colour, z-depth and labels along a camera loop (or, at
//! [`SceneSize::Outdoor`], a few objects under a distant backdrop seen from
//! a ring of cameras), a labelled
//! surface point cloud, and feature maps from the simulated VLM
//! ([`crate::extractor::SimulatedExtractor`]). Everything is a function of
//! `(seed, size)`.

pub mod classes;
pub mod furnishing;
pub mod lift;
pub mod outdoor;
pub mod raytrace;
pub mod room;
mod size;

use std::f64::consts::PI;

use model::geometry::{Camera, Intrinsics, SceneBox, Vec3, look_at};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use classes::{CLASSES, SizeGroup, class_embeddings, try_class_embeddings};
pub use furnishing::build_room;
pub use outdoor::build_outdoor;
pub use room::Room;

use crate::error::DatasetError;
use crate::extractor::{FeatureExtractor, SimulatedExtractor};
use crate::features::{FeatureSet, PcaBasis, PcaSetting, compress_map, gather_pixels, sample_plan};
use crate::points::PointCloud;
use crate::scene::{Frame, Scene, SceneSource};

pub use size::{PAPER_FEATURE_DIM, SceneSize};

/// Horizontal field of view of the synthetic camera (that of Replica's).
pub const FOV_X: f64 = PI / 2.0;

/// The camera loop: positions on an ellipse around the room's middle at
/// varying height, looking across the room with a yaw that swings towards
/// the walls and a varying pitch. Seeded jitter; cameras keep clear of objects.
pub fn trajectory(room: &Room, size: SceneSize, seed: u64) -> Result<Vec<Camera>, DatasetError> {
    let (n, w, h) = size.views();
    let intrinsics = Intrinsics::from_fov_x(w, h, FOV_X);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7a_3ec7);
    let (a, b) = (0.6 * room.max[0], 0.55 * room.max[1]);
    let phase = rng.random_range(0.0..2.0 * PI);
    let mut cameras = Vec::with_capacity(n);
    for i in 0..n {
        let theta = phase + 2.0 * PI * i as f64 / n as f64 + rng.random_range(-0.05..0.05);
        let mut pos = [
            a * theta.cos(),
            b * theta.sin(),
            1.55 + 0.2 * (3.0 * theta).sin() + rng.random_range(-0.05..0.05),
        ];
        if !room.is_free(pos, 0.2) {
            pos[2] = 1.8;
        }
        let yaw = theta + PI + 1.4 * (5.0 * theta).sin() + rng.random_range(-0.1..0.1);
        let target = [
            pos[0] + 2.0 * yaw.cos(),
            pos[1] + 2.0 * yaw.sin(),
            0.75 + 0.45 * (4.0 * theta).cos(),
        ];
        let pose = look_at(pos, target, [0.0, 0.0, 1.0])
            .map_err(|e| DatasetError::invalid("<synthetic scene>", format!("camera {i}: {e}")))?;
        cameras.push(Camera { intrinsics, pose });
    }
    Ok(cameras)
}

/// The outdoor scene's cameras: a ring of radius 2.2 m around the objects
/// at a height of about 1.2 m, each looking at a point near the table.
pub fn ring_trajectory(size: SceneSize, seed: u64) -> Result<Vec<Camera>, DatasetError> {
    let (n, w, h) = size.views();
    let intrinsics = Intrinsics::from_fov_x(w, h, FOV_X);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0ce1_1a55);
    let phase = rng.random_range(0.0..2.0 * PI);
    (0..n)
        .map(|i| {
            let theta = phase + 2.0 * PI * i as f64 / n as f64 + rng.random_range(-0.05..0.05);
            let radius = 2.2 + rng.random_range(-0.1..0.1);
            let pos = [
                radius * theta.cos(),
                radius * theta.sin(),
                1.2 + 0.3 * (2.0 * theta).sin(),
            ];
            let target = [
                rng.random_range(-0.15..0.15),
                rng.random_range(-0.15..0.15),
                0.45 + rng.random_range(-0.1..0.1),
            ];
            let pose = look_at(pos, target, [0.0, 0.0, 1.0]).map_err(|e| {
                DatasetError::invalid("<synthetic scene>", format!("camera {i}: {e}"))
            })?;
            Ok(Camera { intrinsics, pose })
        })
        .collect()
}

/// The bounding box of the outdoor scene's centre piece (the objects within
/// [`outdoor::OUTDOOR_CENTRE`] of the middle).
fn objects_bounds(room: &Room) -> (Vec3, Vec3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let central = |p: &&room::Primitive| {
        (0..2).all(|k| p.min[k] > -outdoor::OUTDOOR_CENTRE && p.max[k] < outdoor::OUTDOOR_CENTRE)
    };
    for p in room.primitives.iter().filter(central) {
        for k in 0..3 {
            lo[k] = lo[k].min(p.min[k]);
            hi[k] = hi[k].max(p.max[k]);
        }
    }
    (lo, hi)
}

/// Expected image colour of each class: its albedo under the average shading
/// (between the 0.8 of surfaces facing away from the light and 1).
pub fn class_prototypes(seed: u64) -> Vec<[f32; 3]> {
    classes::palette(seed)
        .iter()
        .map(|c| c.map(|v| (v * 0.86) as f32))
        .collect()
}

/// The simulated VLM of scene `(seed, size)`, for running rendered novel
/// views through the same extractor as the training frames. It favours
/// large (common) classes over tiny ones, as real VLMs favour head classes.
pub fn extractor_for(seed: u64, size: SceneSize) -> SimulatedExtractor {
    let prior = CLASSES
        .iter()
        .map(|c| match c.size {
            SizeGroup::Large => 0.8,
            SizeGroup::Medium => 0.0,
            SizeGroup::Tiny => -1.0,
        })
        .collect();
    base_extractor(seed, size)
        .with_log_prior(prior)
        .unwrap_or_else(|_| unreachable_extractor())
}

/// The extractor without class prior, with the preset's feature dimension
/// and map resolution.
fn base_extractor(seed: u64, size: SceneSize) -> SimulatedExtractor {
    let salt = match size {
        SceneSize::Ci => 0,
        SceneSize::Bench => 1,
        SceneSize::Paper => 2,
        SceneSize::PaperFull => 3,
        SceneSize::Outdoor => 4,
    };
    let base = class_embeddings();
    let embeddings = match size.feature_dim() {
        Some(dim) => lift::lift_embeddings(&base, dim, lift::LIFT_SEED).unwrap_or(base),
        None => base,
    };
    SimulatedExtractor::new(
        embeddings,
        class_prototypes(seed),
        seed.wrapping_mul(2) + salt,
    )
    .and_then(|x| x.with_downsample(size.feature_downsample()))
    .unwrap_or_else(|_| unreachable_extractor())
}

/// The prototypes and embeddings always agree in count, so construction
/// cannot fail; this only keeps the signature total.
fn unreachable_extractor() -> SimulatedExtractor {
    let e = classes::fallback_embeddings();
    let p = vec![[0.5f32; 3]; e.len()];
    match SimulatedExtractor::new(e, p, 0) {
        Ok(x) => x,
        Err(e) => panic!("built-in extractor is inconsistent: {e}"),
    }
}

/// The labelled surface point cloud of a scene (labels = class indices).
pub fn surface_points(room: &Room, seed: u64, size: SceneSize) -> PointCloud {
    let (density, min_per_face) = size.point_density();
    let pts = raytrace::sample_surface(room, &classes::palette(seed), density, min_per_face, seed);
    PointCloud {
        positions: pts.iter().map(|p| p.position).collect(),
        colors: Some(pts.iter().map(|p| p.color).collect()),
        labels: Some(pts.iter().map(|p| p.class as i64).collect()),
    }
}

/// Generates the scene `(seed, size)`: frames with colour, depth and labels,
/// simulated feature maps (PCA-compressed unless the preset is [`SceneSize::Ci`], fitted on
/// every 10th frame and applied map by map, so all maps are never held at
/// full dimension), the labelled point cloud and the class embeddings.
pub fn generate(seed: u64, size: SceneSize) -> Result<Scene, DatasetError> {
    generate_with(seed, size, size.default_pca(), None)
}

/// [`generate`] with the feature compression chosen (`pca`); a given
/// `basis` is used instead of fitting one (a run's stored basis).
pub fn generate_with(
    seed: u64,
    size: SceneSize,
    pca: PcaSetting,
    basis: Option<&PcaBasis>,
) -> Result<Scene, DatasetError> {
    let outdoor = size == SceneSize::Outdoor;
    let room = if outdoor {
        build_outdoor(seed)
    } else {
        build_room(seed)
    };
    let palette = classes::palette(seed);
    let cameras = if outdoor {
        ring_trajectory(size, seed)?
    } else {
        trajectory(&room, size, seed)?
    };
    let rendered = raytrace::render_views(&room, &palette, &cameras);
    let extractor = extractor_for(seed, size);
    let frames: Vec<Frame> = rendered
        .into_iter()
        .zip(&cameras)
        .enumerate()
        .map(|(i, (r, camera))| Frame {
            name: format!("frame{i:06}"),
            camera: *camera,
            rgb: r.rgb,
            depth: Some(r.depth),
            depth_weight: 1.0,
            color_weight: 1.0,
            labels: Some(r.labels),
            mask: None,
        })
        .collect();
    let features = extract_all(&extractor, &frames, pca, basis, seed)?;
    let points = surface_points(&room, seed, size);
    // The room's box is its shell with the cameras; the outdoor scene's
    // holds its centre piece only, as a capture's box holds the object its
    // cameras look at, not the ground, the pillars or the backdrop.
    let (lo, hi, centres) = if outdoor {
        let (lo, hi) = objects_bounds(&room);
        (lo, hi, Vec::new())
    } else {
        let centres = cameras.iter().map(|c| c.pose.center()).collect();
        (room.min, room.max, centres)
    };
    let corners = (0..8).map(|c| [0, 1, 2].map(|k| if (c >> k) & 1 == 1 { hi[k] } else { lo[k] }));
    let margin = if outdoor { 0.05 } else { 0.02 };
    let scene_box = SceneBox::from_points(corners.chain(centres), margin)
        .ok_or_else(|| DatasetError::invalid("<synthetic scene>", "empty scene box"))?;
    Ok(Scene {
        name: format!("synthetic-{size}-{seed}"),
        frames,
        features: Some(features),
        scene_box,
        background: None,
        points: Some(points),
        classes: Some(extractor.embeddings().clone()),
        source: SceneSource::Synthetic {
            seed,
            size: size.to_string(),
            pca: None,
        },
        world: None,
    })
}

/// Runs the extractor on every frame in parallel threads; unless PCA is
/// off, fits the basis on every 10th frame (or takes `basis`) and compresses each
/// map right after extraction.
fn extract_all(
    extractor: &SimulatedExtractor,
    frames: &[Frame],
    pca: PcaSetting,
    basis: Option<&PcaBasis>,
    seed: u64,
) -> Result<FeatureSet, DatasetError> {
    let full_dim = extractor.dim();
    let basis = match (basis, pca) {
        (Some(b), _) if b.dim != full_dim => {
            return Err(DatasetError::invalid(
                "<synthetic scene>",
                format!(
                    "the stored PCA basis expects dimension {} but the extractor gives {full_dim}",
                    b.dim
                ),
            ));
        }
        (Some(b), _) => b.clone(),
        (None, PcaSetting::Off) => {
            let maps = parallel_map(frames, |_, f| extractor.extract(&f.rgb))?;
            return FeatureSet::from_maps(maps, PcaSetting::Off, seed);
        }
        (None, pca) => fit_basis(extractor, frames, pca, seed)?,
    };
    let maps = parallel_map(frames, |_, f| {
        let m = extractor.extract(&f.rgb)?;
        Ok(compress_map(&m, &basis))
    })?;
    Ok(FeatureSet {
        maps,
        pca: Some(basis),
        full_dim,
    })
}

/// Fits the PCA basis on every 10th frame's map. Each map is extracted at
/// full dimension and only its pixels in the sample plan are kept (the
/// plan and sample order of [`FeatureSet::from_maps`], so the basis is the
/// one fitted on all those maps at once), so at most one full map per
/// thread is held.
fn fit_basis(
    extractor: &SimulatedExtractor,
    frames: &[Frame],
    pca: PcaSetting,
    seed: u64,
) -> Result<PcaBasis, DatasetError> {
    let fit_frames: Vec<&Frame> = frames.iter().step_by(10).collect();
    let sizes: Vec<usize> = fit_frames
        .iter()
        .map(|f| {
            let (w, h) = extractor.map_size(f.rgb.width, f.rgb.height);
            (w * h) as usize
        })
        .collect();
    let picks = sample_plan(&sizes, seed);
    let samples = parallel_map(&fit_frames, |i, f| {
        let map = extractor.extract(&f.rgb)?;
        let mut out = Vec::new();
        gather_pixels(&map, &picks[i], &mut out);
        Ok(out)
    })?;
    PcaBasis::fit(&samples.concat(), extractor.dim(), pca)
}

/// `f(index, item)` over all `items` in scoped threads, results in order.
fn parallel_map<I, T, F>(items: &[I], f: F) -> Result<Vec<T>, DatasetError>
where
    I: Sync,
    T: Send,
    F: Fn(usize, &I) -> Result<T, DatasetError> + Sync,
{
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .clamp(1, 16);
    let chunk = items.len().div_ceil(threads).max(1);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .enumerate()
            .map(|(c, part)| {
                s.spawn(move || {
                    part.iter()
                        .enumerate()
                        .map(|(i, item)| f(c * chunk + i, item))
                        .collect::<Result<Vec<_>, _>>()
                })
            })
            .collect();
        let mut out = Vec::with_capacity(items.len());
        for h in handles {
            let part = h.join().map_err(|_| {
                DatasetError::invalid("<synthetic scene>", "feature thread panicked")
            })??;
            out.extend(part);
        }
        Ok(out)
    })
}
