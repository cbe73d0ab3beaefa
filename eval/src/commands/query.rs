//! `eval query`: relevancy images of a text query (a class name, an
//! embedding or free text) over a run's views.

use std::path::{Path, PathBuf};

use super::common::Context;
use super::render::{RenderArgs, render_cameras};
use crate::checks::radius;

use burn::tensor::Device;
use datasets::points::{read_ply, write_ply};
use datasets::text::TextEmbeddings;

use crate::query::{
    RELEVANCY_THRESHOLD, RelevancyScale, cosine_scores, embedding_by_name, embedding_from_npy,
    normalize_scores, relevancy_overlay, view_cosines,
};
use crate::segment::sampled_features;
use datasets::imageio::save_rgb8;
use field_ops::OpsError;
use field_ops::render::render_view;

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
    /// (default: the run's --vlm model) instead of --query or --query-npy.
    #[arg(long, conflicts_with_all = ["query", "query_npy"])]
    pub text: Option<String>,
    /// CLIP text model directory (Hugging Face: model.safetensors, config.json,
    /// vocab.json, merges.txt; or OpenCLIP: open_clip_model.safetensors and its
    /// vocabulary) that embeds --text. It must be the CLIP model whose image
    /// features the field was trained on, which a run trained with --vlm
    /// uses by default. Embeddings are cached in the run directory
    /// (text_embeddings_cache.json).
    #[arg(long, value_name = "DIR", requires = "text")]
    pub text_model: Option<PathBuf>,
    /// Class embeddings to look the name up in.
    #[arg(long)]
    pub embeddings: Option<PathBuf>,
    /// Names of the class embeddings.
    #[arg(long)]
    pub names: Option<PathBuf>,
    /// Also score this point cloud (PLY, in the --frame frame); `scene` uses the
    /// scene's own cloud.
    #[arg(long)]
    pub points: Option<String>,
    /// Radius (metres) of the Gaussian a point is queried with.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub radius: f64,
}

/// The query embedding and the label its files are named with: from
/// `--query-npy`, a `--query` class name, or `--text` with `--text-model`.
fn query_embedding(
    args: &QueryArgs,
    ctx: &Context,
    device: &Device,
) -> Result<(Vec<f32>, String), OpsError> {
    let r = &args.render;
    let from_text = match &args.text {
        Some(text) => {
            let dir =
                crate::text_query::model_for(args.text_model.as_deref(), &ctx.run.meta, "--text")?;
            let texts = [text.clone()];
            let e = crate::text_query::embed(&dir, &texts, &r.run, &ctx.run.meta, device)?;
            Some((e.data, crate::text_query::label(text)))
        }
        None => None,
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
                        OpsError::Invalid(
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
            OpsError::Invalid(
                "give --query NAME, --query-npy FILE or --text \"...\" with --text-model DIR"
                    .into(),
            )
        })?,
    };
    Ok((query, label))
}

/// Writes the point cloud `spec` (`scene` or a PLY) with a per-point
/// `relevancy` scalar and relevancy colours; returns its path.
fn write_point_relevancy(
    args: &QueryArgs,
    ctx: &Context,
    spec: &str,
    query: &[f32],
    label: &str,
    out: &Path,
    device: &Device,
) -> Result<PathBuf, OpsError> {
    let (r, m) = (&args.render, &ctx.run.meta);
    let pca = m.pca.as_ref();
    let frame = r.frame.resolve(m)?;
    // The scene's cloud is in the scene's frame; a user's is in --frame's.
    let (mut cloud, in_scene) = if spec == "scene" {
        let c = ctx
            .scene
            .as_ref()
            .and_then(|s| s.points.clone())
            .ok_or_else(|| OpsError::Invalid("the scene has no point cloud".into()))?;
        let p = c.positions.clone();
        (c, p)
    } else {
        let c = read_ply(Path::new(spec))?;
        let p = frame.scene_points(&c.positions);
        (c, p)
    };
    if spec == "scene" {
        cloud.positions = frame.points(&cloud.positions);
    }
    let f = sampled_features(
        &ctx.run.model,
        &in_scene,
        &m.scene_box,
        args.radius,
        r.chunk,
        device,
    );
    let rel = normalize_scores(&cosine_scores(&f, query, pca)?);
    cloud.colors = Some(
        relevancy_overlay(&vec![0.6; 3 * rel.len()], &rel)
            .chunks(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    );
    let path = out.join(format!("{label}_relevancy.ply"));
    write_ply(&path, &cloud, &[("relevancy", &rel)])?;
    Ok(path)
}

/// Runs `query`: relevancy overlays per camera and, with `--points`, a PLY
/// with a per-point `relevancy` scalar. Returns the written files.
pub fn query_command(args: &QueryArgs) -> Result<Vec<PathBuf>, OpsError> {
    let r = &args.render;
    check(args)?;
    let device = r.compute.device();
    let ctx = Context::load(&r.run, &device)?;
    let (query, label) = query_embedding(args, &ctx, &device)?;
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
    std::fs::create_dir_all(&out).map_err(|e| OpsError::io(&out, e))?;
    let mut written = Vec::new();
    // Every view is scored first, so that one relevancy scale spans them all.
    let cams = render_cameras(r, &ctx)?;
    let bar = field_ops::progress::progress(cams.len(), "rendering");
    let mut views = Vec::with_capacity(cams.len());
    for c in &cams {
        let v = render_view(
            &ctx.run.model,
            &c.camera,
            &m.scene_box,
            &r.settings(m.background, true),
        )
        .expect("never cancelled without an observer");
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
        let (bw, px) = crate::figures::with_colour_bar(
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
        save_rgb8(&path, bw, *h, &px)?;
        written.push(path);
    }
    if !animation.is_empty() {
        let path = out.join(format!("{label}_relevancy.gif"));
        crate::figures::write_gif(&path, gif_size.0, gif_size.1, &animation, 10)?;
        written.push(path);
    }
    if let Some(spec) = &args.points {
        written.push(write_point_relevancy(
            args, &ctx, spec, &query, &label, &out, &device,
        )?);
    }
    Ok(written)
}

/// Checks `query`.
pub fn check(a: &QueryArgs) -> Result<(), OpsError> {
    super::render::check(&a.render)?;
    crate::text_query::check_flags(a.text.as_deref(), None, a.text_model.as_deref())?;
    radius(a.radius)
}
