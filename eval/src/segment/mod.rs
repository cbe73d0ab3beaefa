//! Zero-shot 3D semantic segmentation of a point cloud with a trained field:
//! per-point features (sampled from the field, projected from rendered
//! feature images, or both), argmax cosine similarity with class text
//! embeddings, and the paper's metrics.

use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use burn::tensor::Device;
use datasets::features::{FeatureSet, PcaBasis};
use datasets::points::{IGNORE_LABEL, PointCloud, write_ply};
use datasets::text::TextEmbeddings;
use datasets::{DepthImage, FeatureMap, Scene};
use model::OpenNerf;
use model::geometry::{Camera, SceneBox, Vec3};

use crate::metrics::{ClassSplit, ConfusionMatrix, NO_PREDICTION, score};
use crate::similarity::ClassScorer;
use field_ops::OpsError;
use field_ops::colormap::class_color;
use field_ops::frame::OutputFrame;
use field_ops::project::ProjectOptions;
use field_ops::scores::SegmentationScores;

pub mod features;

pub use features::{projected_2d_features, projected_features, scaled_index};
pub use field_ops::sample::sampled_features;

/// How per-point features are obtained from the field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SegmentMode {
    /// Query the field's feature at each point.
    Sampled,
    /// Average rendered feature images over the views that see the point.
    Project,
    /// Project, and the sampled feature for points no view sees.
    Hybrid,
}

impl fmt::Display for SegmentMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SegmentMode::Sampled => "sampled",
            SegmentMode::Project => "project",
            SegmentMode::Hybrid => "hybrid",
        })
    }
}

impl FromStr for SegmentMode {
    type Err = OpsError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "sampled" => Ok(Self::Sampled),
            "project" => Ok(Self::Project),
            "hybrid" => Ok(Self::Hybrid),
            o => Err(OpsError::Invalid(format!(
                "unknown mode {o:?} (expected sampled, project or hybrid)"
            ))),
        }
    }
}

/// A view to project points into: its camera and, optionally, a depth image
/// for the occlusion test (without one the rendered depth is used).
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    /// The camera (at the resolution of its depth image, if any).
    pub camera: Camera,
    /// Sensor depth for the occlusion test.
    pub depth: Option<&'a DepthImage>,
}

/// Settings of the field-based segmentation.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentOptions {
    /// Feature mode.
    pub mode: SegmentMode,
    /// Standard deviation (metres) of the Gaussian a point is encoded as when
    /// the field is queried directly.
    pub sample_radius: f64,
    /// Rays (or points) per forward pass.
    pub chunk: usize,
    /// Feature images are rendered at this fraction of each view's resolution.
    pub render_scale: f64,
    /// Visibility rules of the projection.
    pub project: ProjectOptions,
}

impl Default for SegmentOptions {
    fn default() -> Self {
        Self {
            mode: SegmentMode::Hybrid,
            sample_radius: 0.01,
            chunk: 4096,
            render_scale: 1.0,
            project: ProjectOptions::default(),
        }
    }
}

/// Labelled points to segment, with the classes to choose from.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalPoints {
    /// Positions in metres.
    pub positions: Vec<Vec3>,
    /// Class index per point ([`IGNORE_LABEL`] = not evaluated).
    pub labels: Vec<u32>,
    /// Class names; labels index into them.
    pub names: Vec<String>,
    /// `C x dim` text embeddings, one row per class name.
    pub embeddings: Vec<f32>,
    /// Embedding dimension D.
    pub dim: usize,
    /// Whether the points carry ground-truth labels (a capture's sparse
    /// cloud does not: it is segmented, not scored).
    pub labelled: bool,
}

impl EvalPoints {
    /// Points without ground truth, to be segmented into the classes of
    /// `texts` (every label [`IGNORE_LABEL`]).
    pub fn unlabelled(positions: Vec<Vec3>, texts: &TextEmbeddings) -> Self {
        Self {
            labels: vec![IGNORE_LABEL; positions.len()],
            positions,
            names: texts.names.clone(),
            embeddings: texts.data.clone(),
            dim: texts.dim,
            labelled: false,
        }
    }

    /// The labelled point cloud and class embeddings a scene carries (the
    /// synthetic scene's defaults). Negative labels become [`IGNORE_LABEL`].
    pub fn from_scene(scene: &Scene) -> Result<Self, OpsError> {
        let points = scene
            .points
            .as_ref()
            .ok_or_else(|| OpsError::Invalid(format!("scene {} has no point cloud", scene.name)))?;
        let classes = scene.classes.as_ref().ok_or_else(|| {
            OpsError::Invalid(format!("scene {} has no class embeddings", scene.name))
        })?;
        let labels = points.labels.as_ref().ok_or_else(|| {
            OpsError::Invalid(format!("scene {}'s points have no labels", scene.name))
        })?;
        let c = classes.names.len() as i64;
        Ok(Self {
            positions: points.positions.clone(),
            labels: labels
                .iter()
                .map(|&l| {
                    if (0..c).contains(&l) {
                        l as u32
                    } else {
                        IGNORE_LABEL
                    }
                })
                .collect(),
            names: classes.names.clone(),
            embeddings: classes.data.clone(),
            dim: classes.dim,
            labelled: true,
        })
    }

    /// Replica's head/common/tail split when the classes are Replica's.
    pub fn split(&self) -> Option<ClassSplit> {
        ClassSplit::replica_for(&self.names)
    }
}

/// Class of every point from features `[n, k]` (`None` rows get
/// [`NO_PREDICTION`]).
pub fn predict<'a>(
    scorer: &ClassScorer,
    features: impl Iterator<Item = Option<&'a [f32]>>,
) -> Vec<u32> {
    features
        .map(|f| f.map_or(NO_PREDICTION, |f| scorer.argmax(f)))
        .collect()
}

/// Per-point predictions of the field in `opts.mode`. Returns the
/// predictions and the number of points seen by at least one view (all
/// points in sampled mode).
#[allow(clippy::too_many_arguments)]
pub fn segment_with_field(
    model: &OpenNerf,
    pca: Option<&PcaBasis>,
    points: &EvalPoints,
    views: &[View<'_>],
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    opts: &SegmentOptions,
    device: &Device,
) -> Result<(Vec<u32>, usize), OpsError> {
    let mut all = segment_with_field_modes(
        model,
        pca,
        points,
        views,
        scene_box,
        background,
        opts,
        &[opts.mode],
        device,
    )?;
    let (_, pred, seen) = all.remove(0);
    Ok((pred, seen))
}

/// Predictions of the field in each of `modes`, sharing the work between
/// them: the views are rendered once for `project` and `hybrid`, and points
/// are sampled once for `sampled` and the unseen points of `hybrid`.
/// Returns `(mode, predictions, points seen)` in the order of `modes`.
#[allow(clippy::too_many_arguments)]
pub fn segment_with_field_modes(
    model: &OpenNerf,
    pca: Option<&PcaBasis>,
    points: &EvalPoints,
    views: &[View<'_>],
    scene_box: &SceneBox,
    background: Option<[f32; 3]>,
    opts: &SegmentOptions,
    modes: &[SegmentMode],
    device: &Device,
) -> Result<Vec<(SegmentMode, Vec<u32>, usize)>, OpsError> {
    let scorer = ClassScorer::new(&points.embeddings, points.dim, pca)?;
    let pos = &points.positions;
    let check_dim = |k: usize| {
        if k != scorer.dim {
            Err(OpsError::Invalid(format!(
                "the field predicts {k} channels but the class embeddings give {} (PCA mismatch?)",
                scorer.dim
            )))
        } else {
            Ok(())
        }
    };
    let sample = |idx: &[usize]| -> Result<Vec<u32>, OpsError> {
        let p: Vec<Vec3> = idx.iter().map(|&i| pos[i]).collect();
        let f = sampled_features(model, &p, scene_box, opts.sample_radius, opts.chunk, device);
        let k = f.len() / idx.len().max(1);
        check_dim(k)?;
        Ok(predict(&scorer, f.chunks(k.max(1)).map(Some)))
    };
    let sampled = if modes.contains(&SegmentMode::Sampled) {
        Some(sample(&(0..pos.len()).collect::<Vec<_>>())?)
    } else {
        None
    };
    let needs_views = modes.iter().any(|m| *m != SegmentMode::Sampled);
    let projected = if needs_views {
        let acc = projected_features(model, pos, views, scene_box, background, opts, |_, _| {})?;
        check_dim(acc.dim)?;
        let means: Vec<Option<Vec<f32>>> = (0..pos.len()).map(|i| acc.mean(i)).collect();
        let pred = predict(&scorer, means.iter().map(|m| m.as_deref()));
        Some((pred, acc.counts))
    } else {
        None
    };
    let mut out = Vec::with_capacity(modes.len());
    for &mode in modes {
        let result = match (mode, &sampled, &projected) {
            (SegmentMode::Sampled, Some(p), _) => (p.clone(), pos.len()),
            (SegmentMode::Project, _, Some((p, counts))) => {
                (p.clone(), counts.iter().filter(|&&c| c > 0).count())
            }
            (SegmentMode::Hybrid, _, Some((p, counts))) => {
                let unseen: Vec<usize> = (0..pos.len()).filter(|&i| counts[i] == 0).collect();
                let mut pred = p.clone();
                let fill = match &sampled {
                    Some(all) => unseen.iter().map(|&i| all[i]).collect(),
                    None if unseen.is_empty() => Vec::new(),
                    None => sample(&unseen)?,
                };
                for (&i, c) in unseen.iter().zip(fill) {
                    pred[i] = c;
                }
                (pred, counts.iter().filter(|&&c| c > 0).count())
            }
            _ => unreachable_mode(mode)?,
        };
        out.push((mode, result.0, result.1));
    }
    Ok(out)
}

/// Every mode's inputs are computed above; this keeps the match total
/// without a panic.
fn unreachable_mode<T>(mode: SegmentMode) -> Result<T, OpsError> {
    Err(OpsError::Invalid(format!(
        "internal: inputs of mode {mode} were not computed"
    )))
}

/// Predictions of the 2D-feature projection bound: the scene's feature maps
/// projected onto the points; points no view sees get [`NO_PREDICTION`].
pub fn segment_with_2d_features(
    set: &FeatureSet,
    maps: &[&FeatureMap],
    points: &EvalPoints,
    views: &[View<'_>],
    opts: &ProjectOptions,
) -> Result<Vec<u32>, OpsError> {
    let scorer = ClassScorer::new(&points.embeddings, points.dim, set.pca.as_ref())?;
    let acc = projected_2d_features(set, maps, views, &points.positions, opts)?;
    let means: Vec<Option<Vec<f32>>> = (0..acc.len()).map(|i| acc.mean(i)).collect();
    Ok(predict(&scorer, means.iter().map(|m| m.as_deref())))
}

/// The oracle: every point gets its own class's text embedding as feature.
/// Scores 1 unless two classes share an embedding.
pub fn segment_oracle(points: &EvalPoints) -> Result<Vec<u32>, OpsError> {
    let scorer = ClassScorer::new(&points.embeddings, points.dim, None)?;
    let d = points.dim;
    Ok(points
        .labels
        .iter()
        .map(|&l| {
            if (l as usize) < points.names.len() {
                let row: Vec<f32> =
                    points.embeddings[l as usize * d..(l as usize + 1) * d].to_vec();
                scorer.argmax(&row)
            } else {
                NO_PREDICTION
            }
        })
        .collect())
}

/// Scores predictions against the points' labels.
pub fn evaluate(mode: &str, points: &EvalPoints, pred: &[u32]) -> SegmentationScores {
    let mut cm = ConfusionMatrix::new(points.names.len());
    cm.add_all(&points.labels, pred);
    score(mode, &cm, &points.names, points.split().as_ref())
}

/// Writes `{stem}_pred.ply` (points coloured by predicted class, with the
/// predicted class as label) and, for labelled points, `{stem}_error.ply`
/// (green correct, red wrong, grey not evaluated or unpredicted) into
/// `dir`, positions in `frame`. Returns the files written.
pub fn write_prediction_plys(
    dir: &Path,
    stem: &str,
    points: &EvalPoints,
    pred: &[u32],
    frame: &OutputFrame,
) -> Result<Vec<PathBuf>, OpsError> {
    let positions = frame.points(&points.positions);
    std::fs::create_dir_all(dir).map_err(|e| OpsError::io(dir, e))?;
    let colors = pred
        .iter()
        .map(|&p| {
            if p == NO_PREDICTION {
                [128; 3]
            } else {
                class_color(p as usize)
            }
        })
        .collect();
    let cloud = PointCloud {
        positions: positions.clone(),
        colors: Some(colors),
        labels: Some(
            pred.iter()
                .map(|&p| if p == NO_PREDICTION { -1 } else { p as i64 })
                .collect(),
        ),
    };
    let pred_ply = dir.join(format!("{stem}_pred.ply"));
    write_ply(&pred_ply, &cloud, &[])?;
    if !points.labelled {
        return Ok(vec![pred_ply]);
    }
    let err = PointCloud {
        positions,
        colors: Some(
            points
                .labels
                .iter()
                .zip(pred)
                .map(
                    |(&g, &p)| match (g == IGNORE_LABEL || p == NO_PREDICTION, g == p) {
                        (true, _) => [128, 128, 128],
                        (false, true) => [40, 200, 60],
                        (false, false) => [220, 40, 40],
                    },
                )
                .collect(),
        ),
        labels: Some(
            points
                .labels
                .iter()
                .map(|&l| if l == IGNORE_LABEL { -1 } else { l as i64 })
                .collect(),
        ),
    };
    let err_ply = dir.join(format!("{stem}_error.ply"));
    write_ply(&err_ply, &err, &[])?;
    Ok(vec![pred_ply, err_ply])
}

/// Views of `scene`'s frames `indices` with their sensor depth (when
/// `sensor_depth` and present); all frames when `indices` is empty.
pub fn scene_views<'a>(
    scene: &'a Scene,
    indices: &[usize],
    sensor_depth: bool,
) -> Result<Vec<View<'a>>, OpsError> {
    let all: Vec<usize> = (0..scene.frames.len()).collect();
    let idx = if indices.is_empty() {
        &all[..]
    } else {
        indices
    };
    idx.iter()
        .map(|&i| {
            let f = scene.frames.get(i).ok_or_else(|| {
                OpsError::Invalid(format!(
                    "frame index {i} but the scene has {} frames",
                    scene.frames.len()
                ))
            })?;
            Ok(View {
                camera: f.camera,
                depth: if sensor_depth { f.depth.as_ref() } else { None },
            })
        })
        .collect()
}
