//! `eval extract`: a capture's pixel-aligned CLIP feature maps, made by a
//! CLIP model's vision tower, written as `.npy` for inspection or reuse
//! (`train --vlm MODEL --features-out DIR` finds and reuses them), with PNG
//! previews: the features' top principal components as colours and,
//! for `--text`, the cosine relevancy of the text.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clip::DenseVariant;
use clip::vision::{DenseOptions, Vlm};
use datasets::imageio::save_rgb8;
use datasets::npy::NpyInfo;
use datasets::{Scene, SceneSource};
use field_ops::OpsError;
use field_ops::backend::BackendArgs;
use field_ops::colormap::{to_u8, turbo};
use field_ops::dataset_arg::DatasetArg;
use field_ops::images::pca_colors;

/// Arguments of `extract`.
#[derive(Debug, Clone, clap::Args)]
pub struct ExtractArgs {
    /// CLIP model directory with both towers (Hugging Face `CLIPModel`
    /// files or OpenCLIP's `open_clip_model.safetensors` +
    /// `open_clip_config.json`, with the tokenizer files).
    #[arg(long, value_name = "DIR")]
    pub vlm: PathBuf,
    /// Scene directory (not for `--dataset synthetic`).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Scene format.
    #[arg(long, value_enum, default_value_t = DatasetArg::Auto)]
    pub dataset: DatasetArg,
    /// Output directory: `<frame>.npy` (f16, rows x cols x D), the stamp
    /// `vlm_features.json` and `previews/`.
    #[arg(long)]
    pub out: PathBuf,
    /// Dense variant of the last block: naclip, clearclip or maskclip.
    #[arg(long, default_value_t = DenseVariant::Naclip,
          value_parser = field_ops::vlm_maps::dense_variant_parser())]
    pub dense: DenseVariant,
    /// Short side images are resized to, in pixels [default: 336, or the
    /// model's input size if larger].
    #[arg(long)]
    pub short_side: Option<usize>,
    /// Also preview the relevancy of this text (cosine with each cell,
    /// coloured over the range of all frames).
    #[arg(long)]
    pub text: Option<String>,
    /// Compute backend and device.
    #[command(flatten)]
    pub compute: BackendArgs,
}

fn scene_of(args: &ExtractArgs) -> Result<Scene, OpsError> {
    let invalid = |m: String| OpsError::Invalid(m);
    let source = match (args.dataset, &args.data) {
        (DatasetArg::Synthetic, Some(d)) => {
            return Err(invalid(format!(
                "--data {} is given with --dataset synthetic (the built-in scene reads no files)",
                d.display()
            )));
        }
        (DatasetArg::Synthetic, None) => SceneSource::Synthetic {
            seed: 0,
            size: "ci".into(),
            pca: None,
        },
        (_, None) => return Err(invalid("--data DIR is needed (the scene directory)".into())),
        (f, Some(path)) => {
            if !path.exists() {
                return Err(invalid(format!("--data {}: not found", path.display())));
            }
            let format = match f.format() {
                Some(format) => format,
                None => datasets::detect::detect(path)?.format,
            };
            SceneSource::Disk {
                loader: format.default_loader(),
                path: path.clone(),
            }
        }
    };
    Ok(datasets::load_scene(&source)?)
}

/// Runs `extract`; returns the files written (maps, then previews).
pub fn extract_command(args: &ExtractArgs) -> Result<Vec<PathBuf>, OpsError> {
    args.compute.check().map_err(OpsError::Invalid)?;
    if let Some(t) = &args.text
        && t.trim().is_empty()
    {
        return Err(OpsError::Invalid("--text: empty text".into()));
    }
    if !args.vlm.is_dir() {
        return Err(OpsError::Invalid(format!(
            "--vlm {}: not a directory",
            args.vlm.display()
        )));
    }
    let device = args.compute.device();
    let vlm = Vlm::load(&args.vlm, &device)
        .map_err(|e| OpsError::Invalid(format!("--vlm {}: {e}", args.vlm.display())))?;
    for note in vlm.notes() {
        eprintln!("note: {note}");
    }
    let query = match &args.text {
        Some(t) => Some(
            vlm.text
                .embed(std::slice::from_ref(t))
                .map_err(|e| OpsError::Invalid(format!("--text: {e}")))?
                .remove(0),
        ),
        None => None,
    };
    let scene = scene_of(args)?;
    let options = DenseOptions {
        variant: args.dense,
        short_side: args.short_side,
        ..DenseOptions::default()
    };
    let vision = Arc::new(vlm.vision);
    field_ops::vlm_maps::ensure_maps(&scene, &vision, &options, &args.out)?;
    let mut written: Vec<PathBuf> = scene
        .frames
        .iter()
        .map(|f| args.out.join(format!("{}.npy", f.name)))
        .collect();
    written.extend(previews(&scene, &args.out, query.as_deref())?);
    Ok(written)
}

/// One feature map back from disk: `(rows, cols, dim, values)`.
fn read_map(path: &Path) -> Result<(usize, usize, usize, Vec<f32>), OpsError> {
    let info = NpyInfo::open(path)?;
    info.expect_rank(3, "rows x cols x D")?;
    let data = info.read_f32_range(0, info.len())?;
    Ok((info.shape[0], info.shape[1], info.shape[2], data))
}

/// PCA colours of every map and, with `query`, its relevancy on one scale.
fn previews(scene: &Scene, dir: &Path, query: Option<&[f32]>) -> Result<Vec<PathBuf>, OpsError> {
    let out = dir.join("previews");
    std::fs::create_dir_all(&out).map_err(|e| OpsError::io(&out, e))?;
    let mut written = Vec::new();
    let mut scores = Vec::new();
    for f in &scene.frames {
        let (rows, cols, dim, data) = read_map(&dir.join(format!("{}.npy", f.name)))?;
        let rgb: Vec<u8> = pca_colors(&data, dim).into_iter().flatten().collect();
        let path = out.join(format!("{}_pca.png", f.name));
        save_rgb8(&path, cols as u32, rows as u32, &rgb)?;
        written.push(path);
        if let Some(q) = query {
            let s: Vec<f32> = data
                .chunks_exact(dim)
                .map(|v| v.iter().zip(q).map(|(a, b)| a * b).sum())
                .collect();
            scores.push((f.name.clone(), rows, cols, s));
        }
    }
    let (lo, hi) = scores
        .iter()
        .flat_map(|(_, _, _, s)| s.iter().copied())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let span = (hi - lo).max(1e-12);
    for (name, rows, cols, s) in scores {
        let rgb: Vec<u8> = s
            .iter()
            .flat_map(|v| turbo((v - lo) / span).map(to_u8))
            .collect();
        let path = out.join(format!("{name}_relevancy.png"));
        save_rgb8(&path, cols as u32, rows as u32, &rgb)?;
        written.push(path);
    }
    Ok(written)
}
