//! What the subcommands share: the point and class arguments,
//! the loaded run with its scene, and the choice of cameras.

use std::path::{Path, PathBuf};

use crate::checks::labels_in_range;

use burn::tensor::Device;
use datasets::Scene;
use datasets::points::{ClassMap, IGNORE_LABEL, read_labels_txt, read_ply};
use datasets::text::TextEmbeddings;

use crate::cameras::{NamedCamera, load_traj, load_transforms_json};
use crate::segment::EvalPoints;
use field_ops::OpsError;
use field_ops::frame::OutputFrame;
use field_ops::run_dir::{LoadedRun, load_run};

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
    pub fn load(dir: &Path, device: &Device) -> Result<Self, OpsError> {
        let mut run = load_run(dir, device)?;
        let scene = field_ops::run_dir::load_run_scene(&run.dir, &run.meta, &mut run.split)?;
        Ok(Self {
            run,
            scene: Some(scene),
        })
    }
}

/// Points, labels and class embeddings from the arguments, falling back on
/// the scene's own labelled cloud and classes.
pub fn load_points(args: &PointArgs, scene: Option<&Scene>) -> Result<EvalPoints, OpsError> {
    load_points_with(args, scene, None, &OutputFrame::SCENE)
}

/// The error for points without labels and no classes to segment them into.
fn no_classes(what: &str) -> OpsError {
    OpsError::Invalid(format!(
        "{what}: the points have no labels and there are no classes to segment them into; \
         give --classes with --text-model, or --embeddings with --names (or --labels)"
    ))
}

/// [`load_points`] with class embeddings given (e.g. from free text); a
/// `--points` file is read in `frame` and moved into the scene's frame.
/// Points without labels come back unlabelled (to be segmented, not scored)
/// when there are classes to segment them into.
pub fn load_points_with(
    args: &PointArgs,
    scene: Option<&Scene>,
    given: Option<TextEmbeddings>,
    frame: &OutputFrame,
) -> Result<EvalPoints, OpsError> {
    let texts = match (&args.embeddings, &args.names) {
        _ if given.is_some() => given,
        (Some(e), Some(n)) => Some(TextEmbeddings::load(e, n)?),
        (None, None) => None,
        _ => {
            return Err(OpsError::Invalid(
                "--embeddings and --names go together".into(),
            ));
        }
    };
    let Some(ply) = &args.points else {
        let scene = scene.ok_or_else(|| {
            OpsError::Invalid("no --points and no scene to take them from".into())
        })?;
        if let Some(cloud) = scene.points.as_ref().filter(|c| c.labels.is_none()) {
            // A capture's own cloud (e.g. COLMAP's sparse points): no ground truth.
            let texts = texts.ok_or_else(|| no_classes(&format!("scene {}", scene.name)))?;
            return Ok(EvalPoints::unlabelled(cloud.positions.clone(), &texts));
        }
        let mut p = EvalPoints::from_scene(scene)?;
        if let Some(t) = texts {
            reembed(&mut p, &t)?;
        }
        return Ok(p);
    };
    let cloud = read_ply(ply)?;
    let positions = frame.scene_points(&cloud.positions);
    let raw = match (&args.labels, &cloud.labels) {
        (Some(l), _) => read_labels_txt(l, cloud.positions.len())?,
        (None, Some(raw)) => raw.clone(),
        (None, None) => {
            let texts = texts
                .or_else(|| scene.and_then(|s| s.classes.clone()))
                .ok_or_else(|| no_classes(&ply.display().to_string()))?;
            return Ok(EvalPoints::unlabelled(positions, &texts));
        }
    };
    let texts = match texts {
        Some(t) => t,
        None => scene.and_then(|s| s.classes.clone()).ok_or_else(|| {
            OpsError::Invalid("no --embeddings/--names and the scene has no classes".into())
        })?,
    };
    let map = match &args.class_map {
        Some(m) => ClassMap::load_replica(m)?,
        None => ClassMap::identity(texts.names.clone()),
    };
    let label_file = args.labels.as_deref().unwrap_or(ply);
    labels_in_range(&raw, &map, label_file, args.class_map.as_deref())?;
    let mut p = EvalPoints {
        positions,
        labels: map.map(&raw),
        names: map.names.clone(),
        embeddings: Vec::new(),
        dim: texts.dim,
        labelled: true,
    };
    reembed(&mut p, &texts)?;
    Ok(p)
}

/// Replaces the class embeddings by the rows of `texts` with the same names;
/// classes without an embedding are dropped (their points ignored).
fn reembed(p: &mut EvalPoints, texts: &TextEmbeddings) -> Result<(), OpsError> {
    let mut keep = Vec::new();
    let mut remap = vec![IGNORE_LABEL; p.names.len()];
    for (i, n) in p.names.iter().enumerate() {
        if let Some(j) = texts.index_of(n) {
            remap[i] = keep.len() as u32;
            keep.push((n.clone(), j));
        }
    }
    if keep.is_empty() {
        return Err(OpsError::Invalid(
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
) -> Result<(Vec<NamedCamera>, Option<Vec<usize>>), OpsError> {
    let from_scene = |idx: Vec<usize>| -> Result<(Vec<NamedCamera>, Option<Vec<usize>>), OpsError> {
        let scene =
            scene.ok_or_else(|| OpsError::Invalid("no scene to take cameras from".into()))?;
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
                        OpsError::Invalid(format!(
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
            let split: field_ops::run_dir::Split = if run.dir.split().exists() {
                field_ops::json::read_json(&run.dir.split())?
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
