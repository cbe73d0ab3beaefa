//! `eval segment`: zero-shot 3D semantic segmentation of a point cloud
//! with its scores and prediction PLYs (and, with `--compare`, the table of
//! `compare`).

mod compare;
mod outputs;

use std::path::PathBuf;

use burn::tensor::Device;
use datasets::Scene;
use datasets::text::TextEmbeddings;
use field_ops::OpsError;
use field_ops::backend::BackendArgs;
use field_ops::frame::{FrameArgs, OutputFrame};
use field_ops::json::read_json;
use field_ops::project::ProjectOptions;
use field_ops::run_dir::LoadedRun;
use field_ops::scores::SegmentationScores;

use super::common::{Context, PointArgs, evenly, load_points_with, select_cameras};
use crate::cameras::NamedCamera;
use crate::checks::{at_least_one, invalid, max_views, radius};
use crate::metrics::{ClassSplit, format_per_class, format_table};
use crate::segment::{EvalPoints, SegmentMode, SegmentOptions, View, segment_with_field_modes};

/// Arguments of `segment`.
#[derive(Debug, Clone, clap::Args)]
pub struct SegmentArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// How each point's feature is obtained from the field: sampled,
    /// project or hybrid.
    #[arg(long, value_enum, default_value_t = SegmentMode::Hybrid)]
    pub mode: SegmentMode,
    /// Points and classes.
    #[command(flatten)]
    pub data: PointArgs,
    /// Cameras to project into: train (the training frames, novel views
    /// included), captured (the captured training frames only: the same
    /// cameras whether or not a run added novel views), heldout, all, or a
    /// transforms.json / traj.txt.
    #[arg(long, default_value = "train")]
    pub cameras: String,
    /// cam_params.json for a traj.txt (default: next to it or its parent).
    #[arg(long)]
    pub cam_params: Option<PathBuf>,
    /// Use the rendered depth for the occlusion test even where sensor depth exists.
    #[arg(long)]
    pub rendered_depth: bool,
    /// Render feature images at this fraction of the camera resolution.
    #[arg(long, default_value_t = 1.0)]
    pub render_scale: f64,
    /// Use at most this many cameras (evenly spaced).
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Radius (metres) of the Gaussian a point is queried with.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub radius: f64,
    /// Rays or points per forward pass.
    #[arg(long, default_value_t = 4096)]
    pub chunk: usize,
    /// Head / common / tail split (JSON `{"head": [...], "common": [...], "tail": [...]}`).
    #[arg(long)]
    pub split: Option<PathBuf>,
    /// Output directory for `segmentation.json`, the prediction and error
    /// point clouds and, with `--compare`, `segmentation_compare.json`
    /// [default: the run directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Compute backend and device.
    #[command(flatten)]
    pub compute: BackendArgs,
    /// Also score the other field modes, the projection of the scene's own 2D
    /// feature maps (no field: the bound the field is measured against) and
    /// the ground-truth-feature oracle, in one table (`segmentation_compare.json`).
    #[arg(long)]
    pub compare: bool,
    /// Classes to segment into, in free text, comma-separated (e.g. "chair,
    /// wooden table, something to sit on"); embedded by --text-model
    /// (default: the run's --vlm model) instead of --embeddings/--names.
    /// Points of other classes are not scored.
    #[arg(long, conflicts_with_all = ["embeddings", "names"])]
    pub classes: Option<String>,
    /// CLIP text model directory (Hugging Face: model.safetensors, config.json,
    /// vocab.json, merges.txt; or OpenCLIP: open_clip_model.safetensors and its
    /// vocabulary) that embeds --classes. It must be the CLIP model whose image
    /// features the field was trained on, which a run trained with --vlm
    /// uses by default. Embeddings are cached in the run directory
    /// (text_embeddings_cache.json).
    #[arg(long, value_name = "DIR", requires = "classes")]
    pub text_model: Option<PathBuf>,
    /// Frame of the written point clouds (and of a --points file).
    #[command(flatten)]
    pub frame: FrameArgs,
}

/// Runs `segment`: predictions, scores (printed and written as JSON) and the
/// prediction / error PLYs next to the JSON. Points without ground truth
/// (a capture's sparse cloud) are segmented only: their prediction PLY is
/// written and `None` returned.
pub fn segment_command(args: &SegmentArgs) -> Result<Option<SegmentationScores>, OpsError> {
    check(args)?;
    let device = args.compute.device();
    let mode = args.mode;
    let ctx = Context::load(&args.run, &device)?;
    let frame = args.frame.resolve(&ctx.run.meta)?;
    let scene = ctx.scene.as_ref();
    let points = points_to_segment(args, &ctx, &frame, &device)?;
    let views = SegmentViews::select(args, &ctx.run, scene)?;
    let opts = SegmentOptions {
        mode,
        sample_radius: args.radius,
        chunk: args.chunk,
        render_scale: args.render_scale,
        project: ProjectOptions::default(),
    };
    let segmented = segment_points(args, &ctx.run, &points, &views.views, &opts, &device)?;
    let (pred, seen) = (&segmented.pred, segmented.seen);
    let dir = args.out.clone().unwrap_or_else(|| ctx.run.dir.dir.clone());
    if !points.labelled {
        outputs::write_unscored(&dir, mode, &points, pred, seen, views.views.len(), &frame)?;
        return Ok(None);
    }
    let split = match &args.split {
        Some(p) => Some(read_json::<ClassSplit>(p)?),
        None => points.split(),
    };
    let score_of = |name: &str, pred: &[u32]| {
        let mut cm = crate::metrics::ConfusionMatrix::new(points.names.len());
        cm.add_all(&points.labels, pred);
        crate::metrics::score(name, &cm, &points.names, split.as_ref())
    };
    let scores = score_of(&mode.to_string(), pred);
    println!(
        "{} points, {} classes, {} views; {} points seen by a view",
        points.positions.len(),
        points.names.len(),
        views.views.len(),
        seen
    );
    print!("{}", format_table(&[(&mode.to_string(), &scores)]));
    print!("{}", format_per_class(&scores, split.as_ref()));
    outputs::write_scores(&dir, mode, &scores, &points, pred, &frame)?;
    if args.compare {
        let features = scene.and_then(|s| s.features.as_ref());
        let compared = compare::Compared {
            field_modes: &segmented.computed,
            features,
            views: &views,
            points: &points,
            opts: &opts,
        };
        compare::write_comparison(&dir, &compared, &score_of)?;
    }
    Ok(Some(scores))
}

/// The points to segment, with the classes of `--classes` when given (the
/// asked classes the points lack are noted); refuses `--compare` on points
/// without labels.
fn points_to_segment(
    args: &SegmentArgs,
    ctx: &Context,
    frame: &OutputFrame,
    device: &Device,
) -> Result<EvalPoints, OpsError> {
    let given = asked_classes(args, ctx, device)?;
    let asked = given.as_ref().map(|t| t.names.clone()).unwrap_or_default();
    let points = load_points_with(&args.data, ctx.scene.as_ref(), given, frame)?;
    if !points.labelled && args.compare {
        return Err(invalid(
            "--compare scores every mode against ground truth, and these points have no labels"
                .into(),
        ));
    }
    if points.labelled {
        crate::text_query::note_unscored(&asked, &points.names);
    }
    Ok(points)
}

/// The views to segment from (`--cameras`, at most `--max-views` of them)
/// and, when they are scene frames, which.
struct SegmentViews<'a> {
    views: Vec<View<'a>>,
    /// The scene frames of the views, in order.
    frames: Option<Vec<usize>>,
}

impl<'a> SegmentViews<'a> {
    fn select(
        args: &SegmentArgs,
        run: &LoadedRun,
        scene: Option<&'a Scene>,
    ) -> Result<SegmentViews<'a>, OpsError> {
        let (cams, idx) = select_cameras(&args.cameras, run, scene, args.cam_params.as_deref())?;
        let views = scene_views_of(&cams, idx.as_deref(), scene, !args.rendered_depth);
        Ok(SegmentViews {
            views: evenly(&views, args.max_views),
            frames: idx.as_ref().map(|i| evenly(i, args.max_views)),
        })
    }
}

/// The field's segmentation of the points: every field mode computed and
/// the prediction of `--mode` with the number of points a view saw.
struct Segmented {
    /// `(mode, prediction, points seen)` of each mode computed.
    computed: Vec<(SegmentMode, Vec<u32>, usize)>,
    pred: Vec<u32>,
    seen: usize,
}

/// Segments the points with the field in `--mode` (with `--compare`, in
/// every field mode), behind a spinner.
fn segment_points(
    args: &SegmentArgs,
    run: &LoadedRun,
    points: &EvalPoints,
    views: &[View<'_>],
    opts: &SegmentOptions,
    device: &Device,
) -> Result<Segmented, OpsError> {
    let mode = args.mode;
    let busy = field_ops::progress::spinner(format!(
        "segmenting {} points ({mode}, {} views)",
        points.positions.len(),
        views.len()
    ));
    // With --compare every field mode comes from one pass: the views are
    // rendered once for project and hybrid, the points sampled once.
    let all_modes = [
        SegmentMode::Sampled,
        SegmentMode::Project,
        SegmentMode::Hybrid,
    ];
    let computed = segment_with_field_modes(
        &run.model,
        run.meta.pca.as_ref(),
        points,
        views,
        &run.meta.scene_box,
        run.meta.background,
        opts,
        if args.compare {
            &all_modes
        } else {
            std::slice::from_ref(&mode)
        },
        device,
    )?;
    let (pred, seen) = computed
        .iter()
        .find(|(m, _, _)| *m == mode)
        .map(|(_, p, s)| (p.clone(), *s))
        .ok_or_else(|| OpsError::Invalid(format!("mode {mode} was not computed")))?;
    busy.finish_and_clear();
    Ok(Segmented {
        computed,
        pred,
        seen,
    })
}

/// The class names of `--classes` embedded by `--text-model` (`None`
/// without them: the points' own classes are used).
fn asked_classes(
    args: &SegmentArgs,
    ctx: &Context,
    device: &Device,
) -> Result<Option<TextEmbeddings>, OpsError> {
    match &args.classes {
        Some(list) => {
            let names = crate::text_query::parse_classes(list)?;
            let dir = crate::text_query::model_for(
                args.text_model.as_deref(),
                &ctx.run.meta,
                "--classes",
            )?;
            Ok(Some(crate::text_query::embed(
                &dir,
                &names,
                &args.run,
                &ctx.run.meta,
                device,
            )?))
        }
        None => Ok(None),
    }
}

/// The views to segment from: scene frames with their sensor depth (when
/// `sensor`), else the cameras alone.
fn scene_views_of<'a>(
    cams: &[NamedCamera],
    frames: Option<&[usize]>,
    scene: Option<&'a Scene>,
    sensor: bool,
) -> Vec<View<'a>> {
    match (frames, scene) {
        (Some(idx), Some(s)) => idx
            .iter()
            .map(|&i| View {
                camera: s.frames[i].camera,
                depth: if sensor {
                    s.frames[i].depth.as_ref()
                } else {
                    None
                },
            })
            .collect(),
        _ => cams
            .iter()
            .map(|c| View {
                camera: c.camera,
                depth: None,
            })
            .collect(),
    }
}

/// Checks `segment`.
pub fn check(a: &SegmentArgs) -> Result<(), OpsError> {
    radius(a.radius)?;
    if !(a.render_scale.is_finite() && a.render_scale > 0.0 && a.render_scale <= 4.0) {
        return Err(invalid(format!(
            "--render-scale {}: must be in (0, 4] (a fraction of the camera resolution)",
            a.render_scale
        )));
    }
    max_views(a.max_views)?;
    at_least_one("chunk", Some(a.chunk), "")?;
    crate::text_query::check_flags(None, a.classes.as_deref(), a.text_model.as_deref())?;
    if let Some(out) = &a.out
        && out.is_file()
    {
        return Err(invalid(format!(
            "--out {}: is a file; segment writes several files and takes a directory",
            out.display()
        )));
    }
    a.compute.check().map_err(OpsError::Invalid)
}
