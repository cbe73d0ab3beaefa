//! The command-line subcommands as library functions: argument structs
//! (clap) and what each command does with them.

use std::path::{Path, PathBuf};

use burn::tensor::Device;
use datasets::Scene;
use datasets::points::{ClassMap, IGNORE_LABEL, read_labels_txt, read_ply, write_ply};
use datasets::text::TextEmbeddings;

use crate::backend::{BackendKind, parse_device_index};
use crate::cameras::{NamedCamera, camera_path, load_traj, load_transforms_json, resized};
use crate::error::EvalError;
use crate::metrics::{ClassSplit, SegmentationScores, format_per_class, format_table};
use crate::project::ProjectOptions;
use crate::query::{
    RELEVANCY_THRESHOLD, RelevancyScale, cosine_scores, embedding_by_name, embedding_from_npy,
    normalize_scores, relevancy_overlay, view_cosines,
};
use crate::render::{render_view, save_rgb8, save_view_pngs};
use crate::run::{LoadedRun, load_run, read_json, write_json};
use crate::segment::{
    EvalPoints, SegmentMode, SegmentOptions, View, sampled_features, segment_oracle,
    segment_with_2d_features, segment_with_field_modes, write_prediction_plys,
};

/// The compute device of `--backend` and `--device`, as in `train`.
pub fn device_of(backend: BackendKind, index: Option<usize>) -> Device {
    crate::backend::device(backend, index)
}

/// Where the points and classes come from (all optional: the run's scene
/// provides defaults when it carries a labelled cloud and class embeddings).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct PointArgs {
    /// Point cloud (PLY, ascii or binary; an integer label property is used when present).
    #[arg(long)]
    pub points: Option<PathBuf>,
    /// One integer label per point (e.g. Replica's ground truth), overriding the PLY's.
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Raw id to class name map (`id name` per line, Replica's format); without it ids index the names.
    #[arg(long)]
    pub class_map: Option<PathBuf>,
    /// Class text embeddings (`C x D` .npy).
    #[arg(long)]
    pub embeddings: Option<PathBuf>,
    /// Class names for the embeddings, one per line.
    #[arg(long)]
    pub names: Option<PathBuf>,
}

/// Arguments of `segment`.
#[derive(Debug, Clone, clap::Args)]
pub struct SegmentArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// Feature mode: sampled, project or hybrid.
    #[arg(long, default_value = "hybrid")]
    pub mode: String,
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
    /// Compute backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Flex)]
    pub backend: BackendKind,
    /// wgpu only: index of the discrete GPU to use [default: wgpu's default adapter].
    #[arg(long, value_parser = parse_device_index)]
    pub device: Option<usize>,
    /// Also score the other field modes, the projection of the scene's own 2D
    /// feature maps (no field: the bound the field is measured against) and
    /// the ground-truth-feature oracle, in one table (`segmentation_compare.json`).
    #[arg(long)]
    pub compare: bool,
    /// Classes to segment into, in free text, comma-separated (e.g. "chair,
    /// wooden table, something to sit on"); embedded by --text-model instead
    /// of --embeddings/--names. Points of other classes are not scored.
    #[arg(long, requires = "text_model", conflicts_with_all = ["embeddings", "names"])]
    pub classes: Option<String>,
    /// CLIP text model directory (Hugging Face: model.safetensors, config.json,
    /// vocab.json, merges.txt; or OpenCLIP: open_clip_model.safetensors and its
    /// vocabulary) that embeds --classes. It must be the CLIP model whose image
    /// features the field was trained on. Embeddings are cached in the run
    /// directory (text_embeddings_cache.json).
    #[arg(long, value_name = "DIR", requires = "classes")]
    pub text_model: Option<PathBuf>,
}

/// The loaded evaluation data of a command: the run, its scene when needed,
/// and the labelled points.
pub struct Context {
    /// The trained run.
    pub run: LoadedRun,
    /// The run's scene, rebuilt from `scene.json` (when it could be).
    pub scene: Option<Scene>,
}

impl Context {
    /// Loads the run and rebuilds its scene.
    pub fn load(dir: &Path, device: &Device) -> Result<Self, EvalError> {
        let mut run = load_run(dir, device)?;
        let scene = crate::run::load_run_scene(&run.dir, &run.meta, &mut run.split)?;
        Ok(Self {
            run,
            scene: Some(scene),
        })
    }
}

/// Points, labels and class embeddings from the arguments, falling back on
/// the scene's own labelled cloud and classes.
pub fn load_points(args: &PointArgs, scene: Option<&Scene>) -> Result<EvalPoints, EvalError> {
    load_points_with(args, scene, None)
}

/// [`load_points`] with class embeddings given (e.g. from free text).
pub fn load_points_with(
    args: &PointArgs,
    scene: Option<&Scene>,
    given: Option<TextEmbeddings>,
) -> Result<EvalPoints, EvalError> {
    let texts = match (&args.embeddings, &args.names) {
        _ if given.is_some() => given,
        (Some(e), Some(n)) => Some(TextEmbeddings::load(e, n)?),
        (None, None) => None,
        _ => {
            return Err(EvalError::Invalid(
                "--embeddings and --names go together".into(),
            ));
        }
    };
    let Some(ply) = &args.points else {
        let scene = scene.ok_or_else(|| {
            EvalError::Invalid("no --points and no scene to take them from".into())
        })?;
        let mut p = EvalPoints::from_scene(scene)?;
        if let Some(t) = texts {
            reembed(&mut p, &t)?;
        }
        return Ok(p);
    };
    let cloud = read_ply(ply)?;
    let raw = match &args.labels {
        Some(l) => read_labels_txt(l, cloud.positions.len())?,
        None => cloud.labels.clone().ok_or_else(|| {
            EvalError::Invalid(format!(
                "{}: no label property and no --labels",
                ply.display()
            ))
        })?,
    };
    let texts = match texts {
        Some(t) => t,
        None => scene.and_then(|s| s.classes.clone()).ok_or_else(|| {
            EvalError::Invalid("no --embeddings/--names and the scene has no classes".into())
        })?,
    };
    let map = match &args.class_map {
        Some(m) => ClassMap::load_replica(m)?,
        None => ClassMap::identity(texts.names.clone()),
    };
    let label_file = args.labels.as_deref().unwrap_or(ply);
    crate::checks::labels_in_range(&raw, &map, label_file, args.class_map.as_deref())?;
    let mut p = EvalPoints {
        positions: cloud.positions,
        labels: map.map(&raw),
        names: map.names.clone(),
        embeddings: Vec::new(),
        dim: texts.dim,
    };
    reembed(&mut p, &texts)?;
    Ok(p)
}

/// Replaces the class embeddings by the rows of `texts` with the same names;
/// classes without an embedding are dropped (their points ignored).
fn reembed(p: &mut EvalPoints, texts: &TextEmbeddings) -> Result<(), EvalError> {
    let mut keep = Vec::new();
    let mut remap = vec![IGNORE_LABEL; p.names.len()];
    for (i, n) in p.names.iter().enumerate() {
        if let Some(j) = texts.index_of(n) {
            remap[i] = keep.len() as u32;
            keep.push((n.clone(), j));
        }
    }
    if keep.is_empty() {
        return Err(EvalError::Invalid(
            "none of the point classes has a text embedding".into(),
        ));
    }
    if keep.len() < p.names.len() {
        let missing: Vec<&String> = p
            .names
            .iter()
            .filter(|n| texts.index_of(n).is_none())
            .collect();
        eprintln!(
            "note: {} classes have no text embedding and are not evaluated: {missing:?}",
            missing.len()
        );
    }
    p.labels = p
        .labels
        .iter()
        .map(|&l| remap.get(l as usize).copied().unwrap_or(IGNORE_LABEL))
        .collect();
    p.names = keep.iter().map(|(n, _)| n.clone()).collect();
    p.embeddings = keep
        .iter()
        .flat_map(|&(_, j)| texts.row(j).to_vec())
        .collect();
    p.dim = texts.dim;
    Ok(())
}

/// Cameras by name (`train`, `captured`, `heldout`, `all`: frames of the
/// run's scene; `captured` leaves out the novel views of `train`) or
/// from a `transforms.json` / `traj.txt`. Scene frames come with their index.
pub fn select_cameras(
    spec: &str,
    run: &LoadedRun,
    scene: Option<&Scene>,
    cam_params: Option<&Path>,
) -> Result<(Vec<NamedCamera>, Option<Vec<usize>>), EvalError> {
    let from_scene =
        |idx: Vec<usize>| -> Result<(Vec<NamedCamera>, Option<Vec<usize>>), EvalError> {
            let scene =
                scene.ok_or_else(|| EvalError::Invalid("no scene to take cameras from".into()))?;
            let idx = if idx.is_empty() {
                (0..scene.frames.len()).collect()
            } else {
                idx
            };
            let cams = idx
                .iter()
                .map(|&i| {
                    scene
                        .frames
                        .get(i)
                        .map(|f| NamedCamera {
                            name: f.name.clone(),
                            camera: f.camera,
                        })
                        .ok_or_else(|| {
                            EvalError::Invalid(format!(
                                "{}: frame {i} is not in the scene, which has {} frames",
                                run.dir.split().display(),
                                scene.frames.len()
                            ))
                        })
                })
                .collect::<Result<_, _>>()?;
            Ok((cams, Some(idx)))
        };
    match spec {
        "train" => from_scene(run.split.train.clone()),
        "captured" => {
            // The training frames of split.json: without the novel views the
            // field rendered for itself.
            let split: crate::run::Split = if run.dir.split().exists() {
                crate::run::read_json(&run.dir.split())?
            } else {
                run.split.clone()
            };
            from_scene(split.train)
        }
        "heldout" => from_scene(run.split.heldout.clone()),
        "all" => from_scene(Vec::new()),
        path => {
            let p = Path::new(path);
            if p.extension().is_some_and(|e| e == "json") {
                return Ok((load_transforms_json(p)?, None));
            }
            let params = match cam_params {
                Some(c) => c.to_path_buf(),
                None => {
                    let here = p.with_file_name("cam_params.json");
                    let up = p
                        .parent()
                        .and_then(|d| d.parent())
                        .map(|d| d.join("cam_params.json"));
                    match up {
                        Some(u) if !here.exists() && u.exists() => u,
                        _ => here,
                    }
                }
            };
            Ok((load_traj(p, &params, 1)?, None))
        }
    }
}

/// `n` evenly spaced items of `v` (all when `n >= len`).
pub fn evenly<T: Clone>(v: &[T], n: Option<usize>) -> Vec<T> {
    match n {
        Some(n) if n > 0 && n < v.len() => (0..n).map(|i| v[i * v.len() / n].clone()).collect(),
        _ => v.to_vec(),
    }
}

/// Runs `segment`: predictions, scores (printed and written as JSON) and the
/// prediction / error PLYs next to the JSON.
pub fn segment_command(args: &SegmentArgs) -> Result<SegmentationScores, EvalError> {
    crate::checks::segment_args(args)?;
    let device = device_of(args.backend, args.device);
    let mode: SegmentMode = args.mode.parse()?;
    let ctx = Context::load(&args.run, &device)?;
    let scene = ctx.scene.as_ref();
    let given = match (&args.classes, &args.text_model) {
        (Some(list), Some(dir)) => {
            let names = crate::text_query::parse_classes(list)?;
            Some(crate::text_query::embed(
                dir,
                &names,
                &args.run,
                &ctx.run.meta,
                &device,
            )?)
        }
        _ => None,
    };
    let asked = given.as_ref().map(|t| t.names.clone()).unwrap_or_default();
    let points = load_points_with(&args.data, scene, given)?;
    crate::text_query::note_unscored(&asked, &points.names);
    let (cams, idx) = select_cameras(&args.cameras, &ctx.run, scene, args.cam_params.as_deref())?;
    let sensor = !args.rendered_depth;
    let views: Vec<View<'_>> = match (&idx, scene) {
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
    };
    let views = evenly(&views, args.max_views);
    let view_frames = idx.as_ref().map(|i| evenly(i, args.max_views));
    let opts = SegmentOptions {
        mode,
        sample_radius: args.radius,
        chunk: args.chunk,
        render_scale: args.render_scale,
        project: ProjectOptions::default(),
    };
    let run = &ctx.run;
    let busy = crate::visual::spinner(format!(
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
        &points,
        &views,
        &run.meta.scene_box,
        run.meta.background,
        &opts,
        if args.compare {
            &all_modes
        } else {
            std::slice::from_ref(&mode)
        },
        &device,
    )?;
    let (pred, seen) = computed
        .iter()
        .find(|(m, _, _)| *m == mode)
        .map(|(_, p, s)| (p.clone(), *s))
        .ok_or_else(|| EvalError::Invalid(format!("mode {mode} was not computed")))?;
    busy.finish_and_clear();
    let split = match &args.split {
        Some(p) => Some(read_json::<ClassSplit>(p)?),
        None => points.split(),
    };
    let score_of = |name: &str, pred: &[u32]| {
        let mut cm = crate::metrics::ConfusionMatrix::new(points.names.len());
        cm.add_all(&points.labels, pred);
        crate::metrics::score(name, &cm, &points.names, split.as_ref())
    };
    let scores = score_of(&mode.to_string(), &pred);
    println!(
        "{} points, {} classes, {} views; {} points seen by a view",
        points.positions.len(),
        points.names.len(),
        views.len(),
        seen
    );
    print!("{}", format_table(&[(&mode.to_string(), &scores)]));
    print!("{}", format_per_class(&scores, split.as_ref()));
    let dir = args.out.clone().unwrap_or_else(|| run.dir.dir.clone());
    std::fs::create_dir_all(&dir).map_err(|e| EvalError::io(&dir, e))?;
    let out = dir.join("segmentation.json");
    write_json(&out, &scores)?;
    let stem = format!("segmentation_{mode}");
    write_prediction_plys(&dir, &stem, &points, &pred)?;
    for path in [
        out.clone(),
        dir.join(format!("{stem}_pred.ply")),
        dir.join(format!("{stem}_error.ply")),
    ] {
        println!("wrote {}", path.display());
    }
    if args.compare {
        let mut rows = Vec::new();
        for (m, p, _) in &computed {
            rows.push(score_of(&m.to_string(), p));
        }
        let maps = match (&view_frames, scene.and_then(|s| s.features.as_ref())) {
            (Some(frames), Some(set)) => frames
                .iter()
                .map(|&i| set.maps.get(i))
                .collect::<Option<Vec<_>>>(),
            _ => None,
        };
        match (maps, scene.and_then(|s| s.features.as_ref())) {
            (Some(maps), Some(set)) => {
                let pred = segment_with_2d_features(set, &maps, &points, &views, &opts.project)?;
                rows.push(score_of("2D-feature projection", &pred));
            }
            _ => eprintln!(
                "note: no 2D feature maps for these cameras; the 2D-feature bound is skipped"
            ),
        }
        rows.push(score_of("oracle (GT features)", &segment_oracle(&points)?));
        let table: Vec<(&str, &SegmentationScores)> =
            rows.iter().map(|r| (r.mode.as_str(), r)).collect();
        print!("{}", format_table(&table));
        let compare = dir.join("segmentation_compare.json");
        write_json(&compare, &rows)?;
        println!("wrote {}", compare.display());
    }
    Ok(scores)
}

/// Arguments of `render` and the camera part of `query`.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// Run directory.
    #[arg(long)]
    pub run: PathBuf,
    /// Cameras: heldout (default), train, all, or a transforms.json / traj.txt.
    #[arg(long, default_value = "heldout")]
    pub cameras: String,
    /// cam_params.json for a traj.txt (default: next to it or its parent).
    #[arg(long)]
    pub cam_params: Option<PathBuf>,
    /// Output width (height follows the aspect ratio unless given).
    #[arg(long)]
    pub width: Option<u32>,
    /// Output height.
    #[arg(long)]
    pub height: Option<u32>,
    /// Render a smooth path of this many cameras through the selected poses instead.
    #[arg(long)]
    pub camera_path: Option<usize>,
    /// Use at most this many cameras (evenly spaced).
    #[arg(long)]
    pub max_views: Option<usize>,
    /// Rays per forward pass.
    #[arg(long, default_value_t = 4096)]
    pub chunk: usize,
    /// Output directory (default: `renders/eval` in the run directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Compute backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Flex)]
    pub backend: BackendKind,
    /// wgpu only: index of the discrete GPU to use [default: wgpu's default adapter].
    #[arg(long, value_parser = parse_device_index)]
    pub device: Option<usize>,
}

fn render_cameras(args: &RenderArgs, ctx: &Context) -> Result<Vec<NamedCamera>, EvalError> {
    let (cams, _) = select_cameras(
        &args.cameras,
        &ctx.run,
        ctx.scene.as_ref(),
        args.cam_params.as_deref(),
    )?;
    let cams = evenly(&cams, args.max_views);
    let cams = match args.camera_path {
        Some(n) => camera_path(&cams, n)?,
        None => cams,
    };
    let Some(first) = cams.first() else {
        return Err(EvalError::Invalid(format!(
            "no cameras selected by {:?}",
            args.cameras
        )));
    };
    let k = first.camera.intrinsics;
    Ok(match (args.width, args.height) {
        (None, None) => cams,
        (w, h) => {
            let w = w.unwrap_or_else(|| {
                (h.unwrap_or(k.height) as f64 * k.width as f64 / k.height as f64).round() as u32
            });
            let h =
                h.unwrap_or_else(|| (w as f64 * k.height as f64 / k.width as f64).round() as u32);
            resized(&cams, w.max(1), h.max(1))
        }
    })
}

/// Runs `render`: colour, depth and feature-PCA PNGs per camera. Returns the written files.
pub fn render_command(args: &RenderArgs) -> Result<Vec<PathBuf>, EvalError> {
    crate::checks::render_args(args)?;
    let device = device_of(args.backend, args.device);
    let ctx = Context::load(&args.run, &device)?;
    let cams = render_cameras(args, &ctx)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| ctx.run.dir.renders().join("eval"));
    let mut written = Vec::new();
    let mut animation = Vec::new();
    let bar = crate::visual::progress(cams.len(), "rendering");
    for c in &cams {
        let m = &ctx.run.meta;
        let v = render_view(
            &ctx.run.model,
            &c.camera,
            &m.scene_box,
            m.background,
            args.chunk,
            m.feature_dim.is_some(),
            &device,
        );
        written.extend(save_view_pngs(&v, &out, &c.name)?);
        // A scene frame rendered at its own size is shown next to its
        // ground truth and the error between them.
        let truth = ctx
            .scene
            .as_ref()
            .and_then(|s| s.frames.iter().find(|f| f.name == c.name));
        if let Some((w, h, px)) = truth.and_then(|f| crate::visual::comparison(&f.rgb, &v)) {
            let path = out.join(format!("{}_compare.png", c.name));
            save_rgb8(&path, w, h, px)?;
            written.push(path);
        }
        if args.camera_path.is_some() {
            animation.push(v.rgb.iter().map(|&x| crate::colormap::to_u8(x)).collect());
        }
        bar.inc(1);
        crate::visual::note(&bar, format!("rendered {}", c.name));
    }
    bar.finish_and_clear();
    if let Some(first) = cams.first().filter(|_| !animation.is_empty()) {
        let k = first.camera.intrinsics;
        let path = out.join("path.gif");
        crate::visual::write_gif(&path, k.width, k.height, &animation, 10)?;
        written.push(path);
    }
    Ok(written)
}

/// Arguments of `query`.
#[derive(Debug, Clone, clap::Args)]
pub struct QueryArgs {
    /// Cameras, resolution and output.
    #[command(flatten)]
    pub render: RenderArgs,
    /// Class name to query (looked up in --embeddings/--names or the scene's classes).
    #[arg(long)]
    pub query: Option<String>,
    /// Raw query embedding (.npy, shape [D] or [1, D]) instead of a name.
    #[arg(long)]
    pub query_npy: Option<PathBuf>,
    /// Free-text query (e.g. "something to sit on"), embedded by --text-model
    /// instead of --query or --query-npy.
    #[arg(long, requires = "text_model", conflicts_with_all = ["query", "query_npy"])]
    pub text: Option<String>,
    /// CLIP text model directory (Hugging Face: model.safetensors, config.json,
    /// vocab.json, merges.txt; or OpenCLIP: open_clip_model.safetensors and its
    /// vocabulary) that embeds --text. It must be the CLIP model whose image
    /// features the field was trained on. Embeddings are cached in the run
    /// directory (text_embeddings_cache.json).
    #[arg(long, value_name = "DIR", requires = "text")]
    pub text_model: Option<PathBuf>,
    /// Class embeddings to look the name up in.
    #[arg(long)]
    pub embeddings: Option<PathBuf>,
    /// Names of the class embeddings.
    #[arg(long)]
    pub names: Option<PathBuf>,
    /// Also score this point cloud (PLY); `scene` uses the scene's own cloud.
    #[arg(long)]
    pub points: Option<String>,
    /// Radius (metres) of the Gaussian a point is queried with.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub radius: f64,
}

/// Runs `query`: relevancy overlays per camera and, with `--points`, a PLY
/// with a per-point `relevancy` scalar. Returns the written files.
pub fn query_command(args: &QueryArgs) -> Result<Vec<PathBuf>, EvalError> {
    let r = &args.render;
    crate::checks::query_args(args)?;
    let device = device_of(r.backend, r.device);
    let ctx = Context::load(&r.run, &device)?;
    let from_text = match (&args.text, &args.text_model) {
        (Some(text), Some(dir)) => {
            let texts = [text.clone()];
            let e = crate::text_query::embed(dir, &texts, &r.run, &ctx.run.meta, &device)?;
            Some((e.data, crate::text_query::label(text)))
        }
        _ => None,
    };
    let (query, label) = match (&args.query, &args.query_npy) {
        (_, Some(p)) => (
            embedding_from_npy(p)?,
            p.file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("query")
                .to_string(),
        ),
        (Some(name), None) => {
            let texts = match (&args.embeddings, &args.names) {
                (Some(e), Some(n)) => TextEmbeddings::load(e, n)?,
                _ => ctx
                    .scene
                    .as_ref()
                    .and_then(|s| s.classes.clone())
                    .ok_or_else(|| {
                        EvalError::Invalid(
                            "no --embeddings/--names and the scene has no classes".into(),
                        )
                    })?,
            };
            (
                embedding_by_name(&texts, name)?,
                name.replace(|c: char| !c.is_ascii_alphanumeric(), "_"),
            )
        }
        (None, None) => from_text.ok_or_else(|| {
            EvalError::Invalid(
                "give --query NAME, --query-npy FILE or --text \"...\" with --text-model DIR"
                    .into(),
            )
        })?,
    };
    let m = &ctx.run.meta;
    let source = match (&args.query_npy, &args.text) {
        (Some(p), _) => p.display().to_string(),
        (None, Some(t)) => format!("--text {t:?}"),
        (None, None) => format!("--query {label}"),
    };
    crate::checks::query_dimension(&query, m, &r.run, &source)?;
    let pca = m.pca.as_ref();
    let out = r
        .out
        .clone()
        .unwrap_or_else(|| ctx.run.dir.renders().join("query"));
    std::fs::create_dir_all(&out).map_err(|e| EvalError::io(&out, e))?;
    let mut written = Vec::new();
    // Every view is scored first, so that one relevancy scale spans them all.
    let cams = render_cameras(r, &ctx)?;
    let bar = crate::visual::progress(cams.len(), "rendering");
    let mut views = Vec::with_capacity(cams.len());
    for c in &cams {
        let v = render_view(
            &ctx.run.model,
            &c.camera,
            &m.scene_box,
            m.background,
            r.chunk,
            true,
            &device,
        );
        let scores = view_cosines(&v, &query, pca)?;
        views.push((c, v.width, v.height, v.rgb, scores));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let scale = RelevancyScale::spanning(views.iter().map(|v| v.4.as_slice()));
    println!(
        "relevancy scale over {} views: cosine {:.3} -> 0, {:.3} -> 1; highlighted from {RELEVANCY_THRESHOLD} (cosine {:.3})",
        views.len(),
        scale.lo,
        scale.hi,
        scale.lo + RELEVANCY_THRESHOLD as f64 * (scale.hi - scale.lo)
    );
    let (mut animation, mut gif_size) = (Vec::new(), (0, 0));
    for (c, w, h, rgb, scores) in &views {
        let overlay = relevancy_overlay(rgb, &scale.apply(scores));
        let (bw, px) = crate::visual::with_colour_bar(
            *w,
            *h,
            &overlay,
            RELEVANCY_THRESHOLD,
            scale.lo,
            scale.hi,
        );
        let path = out.join(format!("{}_{label}_relevancy.png", c.name));
        if r.camera_path.is_some() {
            animation.push(px.clone());
            gif_size = (bw, *h);
        }
        save_rgb8(&path, bw, *h, px)?;
        written.push(path);
    }
    if !animation.is_empty() {
        let path = out.join(format!("{label}_relevancy.gif"));
        crate::visual::write_gif(&path, gif_size.0, gif_size.1, &animation, 10)?;
        written.push(path);
    }
    if let Some(spec) = &args.points {
        let mut cloud = if spec == "scene" {
            ctx.scene
                .as_ref()
                .and_then(|s| s.points.clone())
                .ok_or_else(|| EvalError::Invalid("the scene has no point cloud".into()))?
        } else {
            read_ply(Path::new(spec))?
        };
        let f = sampled_features(
            &ctx.run.model,
            &cloud.positions,
            &m.scene_box,
            args.radius,
            r.chunk,
            &device,
        );
        let rel = normalize_scores(&cosine_scores(&f, &query, pca)?);
        cloud.colors = Some(
            relevancy_overlay(&vec![0.6; 3 * rel.len()], &rel)
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        );
        let path = out.join(format!("{label}_relevancy.ply"));
        write_ply(&path, &cloud, &[("relevancy", &rel)])?;
        written.push(path);
    }
    Ok(written)
}
