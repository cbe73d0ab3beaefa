//! Novel training views rendered by the field (SPEC 5): cameras chosen by
//! one of the ablation's modes (aimed at uncertain points, interpolated
//! along the capture path, or placed at random), rendered, run through the
//! scene's 2D feature extractor and compressed into the scene's feature
//! space, ready to be recorded and appended as training frames.

use burn::tensor::Device;
use datasets::extractor::{CommandExtractor, FeatureExtractor};
use datasets::features::compress_map;
use datasets::novel::NovelView;
use datasets::{DepthImage, RgbImage, Scene, SceneSource};
use model::OpenNerf;
use model::geometry::{Camera, Intrinsics, SceneBox, Vec3, add_scaled, look_at, norm, sub};
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::error::EvalError;
use crate::oracle::{GroundTruth, NovelOracle};
use crate::project::ProjectOptions;
use crate::render::render_view;
use crate::uncertainty::proposals::{
    FieldProbe, ProposalOptions, SPARE_TARGETS, propose_cameras, select_targets, target_chances,
};
use crate::uncertainty::propose::scene_up;
use crate::uncertainty::report::coarse_points;
use crate::uncertainty::{UncertaintyOptions, uncertainty_map};

/// How novel cameras are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum NovelMode {
    /// No novel views.
    None,
    /// Views interpolated between consecutive training cameras.
    Trajectory,
    /// Cameras placed uniformly in the scene box, looking in random directions.
    Random,
    /// Cameras aimed at the points whose training features disagree most.
    #[default]
    Guided,
}

impl NovelMode {
    /// The mode's name on the command line and in records.
    pub fn name(self) -> &'static str {
        match self {
            NovelMode::None => "none",
            NovelMode::Trajectory => "trajectory",
            NovelMode::Random => "random",
            NovelMode::Guided => "guided",
        }
    }
}

impl std::fmt::Display for NovelMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of the novel views (the `novel` key of a run's configuration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct NovelViewConfig {
    /// Views added (0 = none).
    pub views: usize,
    /// Iteration they are added at (`None`: half-way through the schedule).
    pub after: Option<usize>,
    /// How the cameras are chosen.
    pub mode: NovelMode,
    /// Weight of the rendered depth in the depth loss (sensor depth has 1).
    pub depth_weight: f32,
    /// Rendered depth is kept only where the accumulated opacity reaches this.
    pub min_acc: f32,
    /// Views are rendered at this fraction of the first training frame's
    /// resolution (intrinsics scaled with it). Rendering costs the square of
    /// it; a close view resolves small objects at half the resolution still.
    pub scale: f64,
    /// Voxel size (metres) of the point cloud the uncertainty is measured on.
    pub voxel: f64,
    /// Distance of a guided camera from its target, metres.
    pub offset: f64,
    /// Guided targets closer than this to an accepted one are skipped, metres.
    pub min_separation: f64,
    /// Guided cameras whose render of their target differs from the colour
    /// the capture saw there by more than this (RMS, colours in [0, 1]) are
    /// rejected; `None` (`null` in JSON, the default): no check. See
    /// [`ProposalOptions::max_color_error`].
    pub max_color_error: Option<f64>,
    /// External extractor for scenes on disk: program and leading arguments
    /// (see [`CommandExtractor`]); synthetic scenes use their own.
    pub extractor: Option<Vec<String>>,
    /// Ground truth in place of the field's render or the extractor's
    /// reading (synthetic scenes only; a diagnostic, see [`NovelOracle`]);
    /// `None` (the default): the method as specified.
    pub oracle: Option<NovelOracle>,
}

impl Default for NovelViewConfig {
    fn default() -> Self {
        Self {
            views: 0,
            after: None,
            mode: NovelMode::Guided,
            depth_weight: 0.1,
            min_acc: 0.5,
            scale: 0.5,
            voxel: 0.1,
            offset: 0.5,
            min_separation: 0.5,
            max_color_error: None,
            extractor: None,
            oracle: None,
        }
    }
}

impl NovelViewConfig {
    /// Whether views are to be added at all.
    pub fn enabled(&self) -> bool {
        self.views > 0 && self.mode != NovelMode::None
    }

    /// Checks ranges; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        if self.views > 1000 {
            return Err(format!(
                "novel.views must be at most 1000, got {}",
                self.views
            ));
        }
        if self.after == Some(0) {
            return Err("novel.after must be at least 1 (the field must be trained first)".into());
        }
        if !(self.depth_weight.is_finite() && (0.0..=1.0).contains(&self.depth_weight)) {
            return Err(format!(
                "novel.depth_weight must be in [0, 1], got {}",
                self.depth_weight
            ));
        }
        if !(self.min_acc.is_finite() && (0.0..=1.0).contains(&self.min_acc)) {
            return Err(format!(
                "novel.min_acc must be in [0, 1], got {}",
                self.min_acc
            ));
        }
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1.0) {
            return Err(format!(
                "novel.scale must be in (0, 1] (a fraction of the capture resolution), got {}",
                self.scale
            ));
        }
        for (k, v) in [
            ("novel.voxel", self.voxel),
            ("novel.offset", self.offset),
            ("novel.min_separation", self.min_separation),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{k} must be a positive length in metres, got {v}"));
            }
        }
        if let Some(e) = self.max_color_error
            && !(e.is_finite() && e >= 0.0)
        {
            return Err(format!(
                "novel.max_color_error must be a non-negative colour difference or null, got {e}"
            ));
        }
        if let Some(cmd) = &self.extractor
            && cmd.first().is_none_or(|p| p.trim().is_empty())
        {
            return Err("novel.extractor must name a program".into());
        }
        Ok(())
    }
}

/// A novel view's colour, depth (0 = no target) and full-dimension
/// features, before compression into the scene's feature space.
#[derive(Debug, Clone)]
pub struct ExtractedView {
    /// Colour image.
    pub rgb: RgbImage,
    /// Z-depth, metres.
    pub depth: DepthImage,
    /// The feature map read from the colour.
    pub features: datasets::FeatureMap,
}

/// A camera to render, with the point it is aimed at (guided views).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AimedCamera {
    /// The camera.
    pub camera: Camera,
    /// Aim point.
    pub target: Option<Vec3>,
    /// Normalised uncertainty of the aim point.
    pub uncertainty: Option<f64>,
}

/// The scene's 2D feature extractor: the simulated one of a synthetic scene,
/// the configured command for a scene on disk. Also refuses an oracle on a
/// scene without ground truth.
pub fn scene_extractor(
    scene: &Scene,
    config: &NovelViewConfig,
) -> Result<Box<dyn FeatureExtractor>, EvalError> {
    let set = scene.features.as_ref().ok_or_else(|| {
        EvalError::Invalid(format!(
            "scene {} has no feature maps: novel views need a feature extractor and a feature head",
            scene.name
        ))
    })?;
    if let Some(oracle) = config.oracle {
        // Refused here, before training, rather than half-way through it.
        GroundTruth::of(scene, oracle)?;
    }
    match (&scene.source, &config.extractor) {
        (_, Some(cmd)) => {
            let (program, args) = cmd
                .split_first()
                .ok_or_else(|| EvalError::Invalid("the extractor command is empty".into()))?;
            Ok(Box::new(CommandExtractor::new(
                program,
                args.to_vec(),
                set.full_dim,
            )))
        }
        (SceneSource::Synthetic { seed, size, .. }, None) => {
            let size: datasets::synthetic::SceneSize = size.parse()?;
            Ok(Box::new(datasets::synthetic::extractor_for(*seed, size)))
        }
        (SceneSource::Disk { .. }, None) => Err(EvalError::Invalid(format!(
            "novel views of scene {} need the 2D feature extractor that made its feature maps: give --extractor-command",
            scene.name
        ))),
    }
}

/// Cameras for `count` novel views chosen by `mode`, with the intrinsics of
/// the first training frame scaled by `config.scale`. `train` are the training frames' indices.
#[allow(clippy::too_many_arguments)]
pub fn choose_cameras(
    mode: NovelMode,
    count: usize,
    model: &OpenNerf,
    scene: &Scene,
    train: &[usize],
    config: &NovelViewConfig,
    seed: u64,
    device: &Device,
) -> Result<Vec<AimedCamera>, EvalError> {
    let first = *train
        .first()
        .ok_or_else(|| EvalError::Invalid("no training frames to place novel views by".into()))?;
    let intrinsics = scaled_intrinsics(scene.frames[first].camera.intrinsics, config.scale);
    let up = scene_up(scene, train);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let probe = FieldProbe {
        model,
        scene_box: &scene.scene_box,
        device,
        samples: 64,
        background: scene.background,
    };
    let opts = ProposalOptions {
        max_views: count,
        offset: config.offset,
        min_separation: config.min_separation,
        max_color_error: config.max_color_error.unwrap_or(f64::INFINITY),
        ..ProposalOptions::default()
    };
    Ok(match mode {
        NovelMode::None => Vec::new(),
        NovelMode::Trajectory => trajectory_cameras(scene, train, count, up)
            .into_iter()
            .map(|camera| AimedCamera {
                camera: Camera {
                    intrinsics,
                    ..camera
                },
                target: None,
                uncertainty: None,
            })
            .collect(),
        NovelMode::Random => random_cameras(
            &scene.scene_box,
            intrinsics,
            count,
            up,
            |p| probe.density(&[p])[0] <= opts.max_density,
            &mut rng,
        ),
        NovelMode::Guided => {
            let split = crate::run::Split {
                train: train.to_vec(),
                heldout: Vec::new(),
            };
            let (points, _) = coarse_points(scene, &split, config.voxel)?;
            let map = uncertainty_map(
                scene,
                train,
                &points,
                &UncertaintyOptions {
                    project: ProjectOptions::default(),
                    ..UncertaintyOptions::default()
                },
                |_, _| {},
            )?;
            let targets = select_targets(
                &target_chances(&map),
                &points,
                count.saturating_mul(SPARE_TARGETS),
                opts.min_separation,
                &mut rng,
            );
            let centre = mean_centre(scene, train);
            propose_cameras(
                &map,
                &points,
                &targets,
                intrinsics,
                up,
                centre,
                |camera, t| probe.accept(camera, points[t], map.mean_colors[t], &opts),
                &opts,
                &mut rng,
            )
            .into_iter()
            .take(count)
            .map(|p| AimedCamera {
                camera: p.camera,
                target: Some(points[p.target]),
                uncertainty: Some(map.normalised[p.target]),
            })
            .collect()
        }
    })
}

/// `k` resampled to `scale` times its size (at least one pixel a side).
pub fn scaled_intrinsics(k: Intrinsics, scale: f64) -> Intrinsics {
    let side = |n: u32| ((n as f64 * scale).round() as u32).max(1);
    k.scaled(side(k.width), side(k.height))
}

fn mean_centre(scene: &Scene, frames: &[usize]) -> Vec3 {
    let mut c = [0.0; 3];
    for &i in frames {
        let p = scene.frames[i].camera.pose.center();
        (0..3).for_each(|a| c[a] += p[a] / frames.len() as f64);
    }
    c
}

/// `count` cameras half-way between consecutive training cameras (in
/// capture order), spread evenly over the path: the position is the
/// midpoint, the view direction the normalised mean of the two.
pub fn trajectory_cameras(scene: &Scene, train: &[usize], count: usize, up: Vec3) -> Vec<Camera> {
    let mut order = train.to_vec();
    order.sort_unstable();
    if order.len() < 2 {
        return Vec::new();
    }
    let segments = order.len() - 1;
    let mut out = Vec::new();
    for j in 0..count.min(segments) {
        // Segment j * segments / count, evenly spaced over the path.
        let s = j * segments / count.min(segments);
        let (a, b) = (
            &scene.frames[order[s]].camera,
            &scene.frames[order[s + 1]].camera,
        );
        let (ca, cb) = (a.pose.center(), b.pose.center());
        let p = add_scaled(ca, 0.5, sub(cb, ca));
        let f = add_scaled(a.pose.forward(), 1.0, b.pose.forward());
        if norm(f) < 1e-9 {
            continue;
        }
        if let Ok(pose) = look_at(p, add_scaled(p, 1.0, f), up) {
            out.push(Camera {
                intrinsics: a.intrinsics,
                pose,
            });
        }
    }
    out
}

/// `count` cameras at positions uniform in the inner 80% of `scene_box`
/// where `free(p)` holds, looking in directions uniform on the sphere.
/// Gives up after `50 * count` draws.
pub fn random_cameras(
    scene_box: &SceneBox,
    intrinsics: Intrinsics,
    count: usize,
    up: Vec3,
    mut free: impl FnMut(Vec3) -> bool,
    rng: &mut impl Rng,
) -> Vec<AimedCamera> {
    let mut out = Vec::new();
    for _ in 0..50 * count {
        if out.len() == count {
            break;
        }
        let p: Vec3 = std::array::from_fn(|a| {
            let (lo, hi) = (scene_box.min[a], scene_box.max[a]);
            lo + (0.1 + 0.8 * rng.random::<f64>()) * (hi - lo)
        });
        // A uniform direction: a normalised Gaussian vector.
        let d: Vec3 = std::array::from_fn(|_| gaussian(rng));
        if norm(d) < 1e-9 || !free(p) {
            continue;
        }
        if let Ok(pose) = look_at(p, add_scaled(p, 1.0, d), up) {
            out.push(AimedCamera {
                camera: Camera { intrinsics, pose },
                target: None,
                uncertainty: None,
            });
        }
    }
    out
}

fn gaussian(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// Renders each camera, runs `extractor` on the rendered colour and
/// compresses the map with the scene's basis. Rendered depth is kept where
/// the accumulated opacity reaches `config.min_acc` (0 elsewhere: no target).
/// With `config.oracle`, a synthetic scene's ground truth stands in for the
/// field's render (and for the extractor's reading with
/// [`NovelOracle::Labels`]). `progress(done, total)` is called per view.
#[allow(clippy::too_many_arguments)]
pub fn render_views(
    model: &OpenNerf,
    cameras: &[AimedCamera],
    scene: &Scene,
    extractor: &dyn FeatureExtractor,
    config: &NovelViewConfig,
    chunk: usize,
    device: &Device,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<NovelView>, EvalError> {
    let pca = scene.features.as_ref().and_then(|f| f.pca.as_ref());
    let truth = config
        .oracle
        .map(|o| GroundTruth::of(scene, o))
        .transpose()?;
    let mut out = Vec::with_capacity(cameras.len());
    for (i, aimed) in cameras.iter().enumerate() {
        let ExtractedView {
            rgb,
            depth,
            features: full,
        } = match &truth {
            Some(truth) => truth.view(&aimed.camera, extractor)?,
            None => field_view(
                model,
                &aimed.camera,
                scene,
                extractor,
                config,
                chunk,
                device,
            )?,
        };
        let features = match pca {
            Some(basis) => compress_map(&full, basis),
            None => full,
        };
        out.push(NovelView {
            name: format!("novel_{i:03}"),
            camera: aimed.camera,
            rgb,
            depth,
            features,
            depth_weight: config.depth_weight,
            target: aimed.target,
            uncertainty: aimed.uncertainty,
        });
        progress(i + 1, cameras.len());
    }
    Ok(out)
}

/// The field's render of `camera` (colour clamped to [0, 1], depth kept
/// where the opacity reaches `config.min_acc`) and the extractor's reading
/// of it, before compression.
fn field_view(
    model: &OpenNerf,
    camera: &Camera,
    scene: &Scene,
    extractor: &dyn FeatureExtractor,
    config: &NovelViewConfig,
    chunk: usize,
    device: &Device,
) -> Result<ExtractedView, EvalError> {
    let view = render_view(
        model,
        camera,
        &scene.scene_box,
        scene.background,
        chunk,
        false,
        device,
    );
    let rgb = RgbImage {
        width: view.width,
        height: view.height,
        data: view.rgb.iter().map(|v| v.clamp(0.0, 1.0)).collect(),
    };
    let depth = DepthImage {
        width: view.width,
        height: view.height,
        data: view
            .depth
            .iter()
            .zip(&view.acc)
            .map(|(&d, &a)| {
                if a >= config.min_acc && d.is_finite() && d > 0.0 {
                    d
                } else {
                    0.0
                }
            })
            .collect(),
    };
    let features = extractor.extract(&rgb)?;
    Ok(ExtractedView {
        rgb,
        depth,
        features,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_cameras_stay_inside_the_box_and_where_free() {
        let b = SceneBox {
            min: [-1.0, -2.0, 0.0],
            max: [1.0, 2.0, 3.0],
        };
        let k = Intrinsics::from_fov_x(32, 24, 1.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // Only the half x < 0 is free.
        let cams = random_cameras(&b, k, 12, [0.0, 0.0, 1.0], |p| p[0] < 0.0, &mut rng);
        assert_eq!(cams.len(), 12);
        for c in &cams {
            let p = c.camera.pose.center();
            assert!(p[0] < 0.0 && p[0] >= -0.8, "{p:?}");
            assert!(p[1].abs() <= 1.6 && (0.3..=2.7).contains(&p[2]), "{p:?}");
            assert!(c.camera.pose.orthonormality_error() < 1e-9);
        }
        // Nowhere free: bounded, empty.
        assert!(random_cameras(&b, k, 5, [0.0, 0.0, 1.0], |_| false, &mut rng).is_empty());
    }

    #[test]
    fn scaled_intrinsics_keep_the_field_of_view() {
        let k = Intrinsics::from_fov_x(320, 180, 1.2);
        let h = scaled_intrinsics(k, 0.5);
        assert_eq!((h.width, h.height), (160, 90));
        // The same ray through the image centre and through a corner edge.
        assert!((h.fx * 2.0 - k.fx).abs() < 1e-9);
        assert!(((h.cx + 0.5) * 2.0 - (k.cx + 0.5)).abs() < 1e-9);
        assert_eq!(scaled_intrinsics(k, 1.0), k);
        let tiny = scaled_intrinsics(k, 1e-6);
        assert_eq!((tiny.width, tiny.height), (1, 1));
    }

    #[test]
    fn config_validation_names_the_key() {
        let ok = NovelViewConfig {
            views: 4,
            ..Default::default()
        };
        assert!(ok.validate().is_ok() && ok.enabled());
        assert!(
            !NovelViewConfig {
                mode: NovelMode::None,
                ..ok.clone()
            }
            .enabled()
        );
        let bad = [
            NovelViewConfig {
                depth_weight: f32::NAN,
                ..ok.clone()
            },
            NovelViewConfig {
                depth_weight: 2.0,
                ..ok.clone()
            },
            NovelViewConfig {
                after: Some(0),
                ..ok.clone()
            },
            NovelViewConfig {
                voxel: 0.0,
                ..ok.clone()
            },
            NovelViewConfig {
                scale: 0.0,
                ..ok.clone()
            },
            NovelViewConfig {
                scale: f64::NAN,
                ..ok.clone()
            },
            NovelViewConfig {
                offset: -1.0,
                ..ok.clone()
            },
            NovelViewConfig {
                extractor: Some(vec![]),
                ..ok.clone()
            },
            NovelViewConfig {
                max_color_error: Some(-0.1),
                ..ok.clone()
            },
            NovelViewConfig {
                max_color_error: Some(f64::NAN),
                ..ok.clone()
            },
        ];
        for (b, key) in bad.iter().zip([
            "depth_weight",
            "depth_weight",
            "after",
            "voxel",
            "scale",
            "scale",
            "offset",
            "extractor",
            "max_color_error",
            "max_color_error",
        ]) {
            let e = b.validate().expect_err("invalid");
            assert!(e.contains(key), "{e}");
        }
        // The check is off with null and stays off through the JSON.
        let off = NovelViewConfig {
            max_color_error: None,
            ..ok.clone()
        };
        assert!(off.validate().is_ok());
        let json = serde_json::to_string(&off).expect("json");
        assert!(json.contains("\"max_color_error\":null"), "{json}");
        let back: NovelViewConfig = serde_json::from_str(&json).expect("read back");
        assert_eq!(back, off);
    }
}
