//! What the server knows: the run's fixed data (points, classes, cameras)
//! and the current field, which a training process replaces as it learns;
//! the points' features and predicted classes are computed once per field.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, RwLock};

use burn::tensor::Device;
use datasets::text::TextEmbeddings;
use datasets::{Scene, SceneMeta};
use model::OpenNerf;
use model::geometry::Camera;

use crate::points::{NO_CLASS, PointSet, attach_uncertainty, from_rendered_depth, from_scene};
use field_ops::OpsError;
use field_ops::run_dir::{RunDir, Split};
use field_ops::sample::sampled_features;
use field_ops::similarity::ClassScorer;

/// Settings of a viewer.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerOptions {
    /// Points sent to the page at most (the cloud is thinned evenly).
    pub max_points: usize,
    /// Rays or points per forward pass.
    pub chunk: usize,
    /// Radius (metres) of the Gaussian a point is queried with.
    pub radius: f64,
    /// CLIP text model for free text (class names work without one).
    pub text_model: Option<PathBuf>,
    /// Whether a training process serves the page.
    pub training: bool,
    /// Largest width or height of a render request, pixels.
    pub max_render_side: u32,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        Self {
            max_points: 200_000,
            chunk: 4096,
            radius: 0.01,
            text_model: None,
            training: false,
            max_render_side: 640,
        }
    }
}

/// A camera the page draws as a frustum.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// Frame name.
    pub name: String,
    /// `train`, `heldout` or `novel`.
    pub kind: &'static str,
    /// The camera.
    pub camera: Camera,
}

/// The run's data that does not change while the page is open.
#[derive(Debug, Clone)]
pub struct ViewerData {
    /// The run directory.
    pub run: RunDir,
    /// What the run recorded about its scene.
    pub meta: SceneMeta,
    /// The points the page shows.
    pub points: PointSet,
    /// The classes the points are segmented into (none: no class mode).
    pub classes: Option<TextEmbeddings>,
    /// Training, held-out and novel cameras.
    pub cameras: Vec<CameraInfo>,
    /// The settings.
    pub options: ViewerOptions,
}

impl ViewerData {
    /// The data of a run whose scene is `scene`: its cloud (or points
    /// back-projected from depth `model` renders at the training cameras),
    /// thinned to `options.max_points`, the uncertainty of
    /// `uncertainty/uncertainty.csv` when the run has one, and its cameras
    /// (`novel`: indices of frames the field rendered itself).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        run: RunDir,
        meta: SceneMeta,
        scene: &Scene,
        split: &Split,
        novel: &[usize],
        classes: Option<TextEmbeddings>,
        model: &OpenNerf,
        options: ViewerOptions,
    ) -> Result<Self, OpsError> {
        let n_classes = classes.as_ref().map_or(0, |c| c.names.len());
        let kind = |i: usize| {
            if novel.contains(&i) {
                "novel"
            } else if split.heldout.contains(&i) {
                "heldout"
            } else {
                "train"
            }
        };
        let cameras: Vec<CameraInfo> = scene
            .frames
            .iter()
            .enumerate()
            .filter(|(i, _)| split.train.contains(i) || split.heldout.contains(i))
            .map(|(i, f)| CameraInfo {
                name: f.name.clone(),
                kind: kind(i),
                camera: f.camera,
            })
            .collect();
        let points = match from_scene(scene, n_classes) {
            Some(p) => p,
            None => {
                let train: Vec<Camera> = cameras
                    .iter()
                    .filter(|c| c.kind != "heldout")
                    .map(|c| c.camera)
                    .collect();
                from_rendered_depth(model, &train, &meta.scene_box, meta.background, (16, 96))
            }
        };
        let mut points = points.thinned(options.max_points);
        let csv = run.dir.join("uncertainty").join("uncertainty.csv");
        if csv.is_file() {
            let b = &meta.scene_box;
            let extent = (0..3).map(|k| b.max[k] - b.min[k]).fold(0.0, f64::max);
            let matched = attach_uncertainty(&mut points, &csv, 0.02 * extent)?;
            eprintln!(
                "uncertainty of {} on {matched} of {} points",
                csv.display(),
                points.len()
            );
        }
        Ok(Self {
            run,
            meta,
            points,
            classes,
            cameras,
            options,
        })
    }

    /// The run directory's name.
    pub fn run_name(&self) -> String {
        self.run
            .dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.run.dir.display().to_string())
    }
}

/// One version of the field.
#[derive(Debug)]
pub struct FieldSnapshot {
    /// The field (inference: no autodiff).
    pub model: OpenNerf,
    /// Increments with every published field.
    pub version: u64,
    /// The training iteration of these weights, when known.
    pub iteration: Option<usize>,
}

/// The points' features and classes under one field version.
#[derive(Debug, Clone)]
pub struct PointFeatures {
    /// The field version they came from.
    pub version: u64,
    /// `[n, k]` features in the field's output space.
    pub features: Arc<Vec<f32>>,
    /// Predicted class per point ([`NO_CLASS`] without classes).
    pub predicted: Arc<Vec<u16>>,
}

/// The server's state: fixed data, the current field and caches.
pub struct Viewer {
    /// The run's data.
    pub data: ViewerData,
    /// The device fields run on.
    pub device: Device,
    field: RwLock<Arc<FieldSnapshot>>,
    features: Mutex<Option<PointFeatures>>,
    /// Free text is embedded one request at a time (the embedding cache is
    /// a file in the run directory).
    pub(crate) embedding: Mutex<()>,
}

impl Viewer {
    /// A viewer of `data` showing `model` (at training `iteration`, if known).
    pub fn new(
        data: ViewerData,
        model: OpenNerf,
        iteration: Option<usize>,
        device: Device,
    ) -> Self {
        Self {
            data,
            device,
            field: RwLock::new(Arc::new(FieldSnapshot {
                model,
                version: 1,
                iteration,
            })),
            features: Mutex::new(None),
            embedding: Mutex::new(()),
        }
    }

    /// The current field.
    pub fn field(&self) -> Arc<FieldSnapshot> {
        self.field
            .read()
            .map_or_else(|e| e.into_inner().clone(), |f| f.clone())
    }

    /// Replaces the field (training publishes its weights); the page sees
    /// the new version in `/api/summary` and refetches the points.
    pub fn publish(&self, model: OpenNerf, iteration: usize) {
        let mut slot = self.field.write().unwrap_or_else(|e| e.into_inner());
        let version = slot.version + 1;
        *slot = Arc::new(FieldSnapshot {
            model,
            version,
            iteration: Some(iteration),
        });
    }

    /// The points' features and predicted classes under the current field,
    /// computed on first use after each new version.
    pub fn point_features(&self) -> PointFeatures {
        let field = self.field();
        let mut cache = self.features.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = cache.as_ref()
            && c.version == field.version
        {
            return c.clone();
        }
        let d = &self.data;
        let features = sampled_features(
            &field.model,
            &d.points.positions,
            &d.meta.scene_box,
            d.options.radius,
            d.options.chunk,
            &self.device,
        );
        let predicted = predict(
            &features,
            d.classes.as_ref(),
            d.meta.pca.as_ref(),
            d.points.len(),
        );
        let computed = PointFeatures {
            version: field.version,
            features: Arc::new(features),
            predicted: Arc::new(predicted),
        };
        *cache = Some(computed.clone());
        computed
    }
}

/// The class of each point: the class embedding of highest cosine (what
/// `eval segment --mode sampled` predicts).
fn predict(
    features: &[f32],
    classes: Option<&TextEmbeddings>,
    pca: Option<&datasets::features::PcaBasis>,
    n: usize,
) -> Vec<u16> {
    let scorer = classes.and_then(|c| ClassScorer::new(&c.data, c.dim, pca).ok());
    match scorer {
        Some(s) if n > 0 && features.len() == n * s.dim => {
            features.chunks(s.dim).map(|f| s.argmax(f) as u16).collect()
        }
        _ => vec![NO_CLASS; n],
    }
}
