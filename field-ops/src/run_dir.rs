//! Run directories: the file layout written by training and read back by
//! every later command.
//!
//! A run directory holds `config.json` (the full training configuration; its
//! top-level `"model"` key is the [`OpenNerfConfig`]), `model.bpk` (the
//! weights, burnpack), `scene.json` ([`SceneMeta`]) and `split.json`
//! ([`Split`]), plus training logs and renders.

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use datasets::SceneMeta;
use model::{OpenNerf, OpenNerfConfig};

use crate::error::OpsError;
use crate::json::read_json;
use crate::novel::record::{RecordedViews, append_recorded};

/// The paths of the files in a run directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunDir {
    /// The directory itself.
    pub dir: PathBuf,
}

impl RunDir {
    /// A run directory rooted at `dir` (nothing is checked or created).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// `config.json`: the full training configuration.
    pub fn config(&self) -> PathBuf {
        self.dir.join("config.json")
    }

    /// `model.bpk`: the model weights (burnpack).
    pub fn weights(&self) -> PathBuf {
        self.dir.join("model.bpk")
    }

    /// `scene.json`: how to rebuild the scene, its box and PCA basis.
    pub fn scene(&self) -> PathBuf {
        self.dir.join("scene.json")
    }

    /// `split.json`: training and held-out frame indices.
    pub fn split(&self) -> PathBuf {
        self.dir.join("split.json")
    }

    /// `metrics.jsonl`: one JSON object per logged training step.
    pub fn metrics(&self) -> PathBuf {
        self.dir.join("metrics.jsonl")
    }

    /// `summary.json`: final training figures.
    pub fn summary(&self) -> PathBuf {
        self.dir.join("summary.json")
    }

    /// `renders/`: images written during and after training.
    pub fn renders(&self) -> PathBuf {
        self.dir.join("renders")
    }

    /// `checkpoints/`: intermediate weights.
    pub fn checkpoints(&self) -> PathBuf {
        self.dir.join("checkpoints")
    }

    /// `occupancy.bin`: the occupancy grid of a run trained with
    /// empty-space skipping (rendering uses it).
    pub fn occupancy(&self) -> PathBuf {
        self.dir.join("occupancy.bin")
    }

    /// `novel/`: novel views rendered by the field and added as training
    /// frames (see [`datasets::novel_record`]).
    pub fn novel(&self) -> PathBuf {
        self.dir.join("novel")
    }

    /// `segmentation.json`: the default output of the `segment` command.
    pub fn segmentation(&self) -> PathBuf {
        self.dir.join("segmentation.json")
    }
}

/// Which frames of the scene were trained on and which were held out.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Split {
    /// Indices of the training frames.
    pub train: Vec<usize>,
    /// Indices of the held-out frames.
    pub heldout: Vec<usize>,
}

impl Split {
    /// Refuses indices outside a scene of `frames` frames, naming `path`
    /// (the split file they were read from): every later step indexes the
    /// scene's frames with them.
    pub fn check(&self, frames: usize, path: &Path) -> Result<(), OpsError> {
        for (list, indices) in [("train", &self.train), ("heldout", &self.heldout)] {
            if let Some(i) = indices.iter().find(|&&i| i >= frames) {
                return Err(OpsError::Invalid(format!(
                    "{}: {list} frame {i} is not in the scene, which has {frames} frames \
                     (frames 0 to {}); the split does not belong to this scene",
                    path.display(),
                    frames.saturating_sub(1)
                )));
            }
        }
        Ok(())
    }
}

/// A trained run loaded back into memory.
#[derive(Debug)]
pub struct LoadedRun {
    /// The field with its trained weights.
    pub model: OpenNerf,
    /// The model configuration it was built from.
    pub config: OpenNerfConfig,
    /// What the run recorded about its scene.
    pub meta: SceneMeta,
    /// The train / held-out split.
    pub split: Split,
    /// The run directory.
    pub dir: RunDir,
}

/// The model configuration stored under the `"model"` key of `config.json`.
pub fn read_model_config(path: &Path) -> Result<OpenNerfConfig, OpsError> {
    let value: serde_json::Value = read_json(path)?;
    let model = value
        .get("model")
        .ok_or_else(|| OpsError::json(path, "no top-level \"model\" key"))?;
    serde_json::from_value(model.clone()).map_err(|e| OpsError::json(path, format!("model: {e}")))
}

/// Loads a trained run: configuration, weights, scene metadata and split.
///
/// The split file is optional (an empty split is used without it), so runs
/// exported without one can still be rendered and segmented.
pub fn load_run(dir: &Path, device: &Device) -> Result<LoadedRun, OpsError> {
    let run = RunDir::new(dir);
    let config = read_model_config(&run.config())?;
    let meta: SceneMeta = read_json(&run.scene())?;
    let split = if run.split().exists() {
        read_json(&run.split())?
    } else {
        Split::default()
    };
    let weights = run.weights();
    if !weights.exists() {
        return Err(OpsError::Missing {
            path: weights,
            what: "model weights (burnpack)".into(),
        });
    }
    let model = load_weights(config.init(device), &weights)?;
    let grid_path = run.occupancy();
    let grid = if grid_path.exists() {
        let bytes = std::fs::read(&grid_path).map_err(|e| OpsError::io(&grid_path, e))?;
        let grid = model::OccupancyGrid::from_bytes(&bytes).map_err(|m| {
            OpsError::Invalid(format!(
                "{}: damaged occupancy grid: {m} (delete it to render without empty-space skipping)",
                grid_path.display()
            ))
        })?;
        Some(grid)
    } else {
        None
    };
    let model = model.with_occupancy(grid);
    Ok(LoadedRun {
        model,
        config,
        meta,
        split,
        dir: run,
    })
}

/// Loads the weights of `weights` into `model`, read whole into memory.
///
/// Burn's own file loading keeps the tensors file-backed and reads them on
/// first use; a run directory is rewritten while runs are loaded (training
/// resumes, a checkpoint renamed over `model.bpk`), and a lazily read model
/// would then fail on first use or, worse, render with another run's bytes.
pub fn load_weights(model: OpenNerf, weights: &Path) -> Result<OpenNerf, OpsError> {
    let weights_error = |message: String| OpsError::Weights {
        path: weights.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(weights).map_err(|e| OpsError::io(weights, e))?;
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| weights_error(e.to_string()))?;
    model
        .try_load_record(record)
        .map_err(|e| weights_error(e.to_string()))
}

/// The scene a run was trained on, rebuilt from its directory.
pub struct RunScene {
    /// The scene of `scene.json` (feature maps compressed with the stored
    /// basis) with the run's recorded novel views appended.
    pub scene: datasets::Scene,
    /// The recorded novel views, if the run made any.
    pub novel: Option<RecordedViews>,
}

/// Rebuilds the scene a run was trained on: the one way every command
/// (a resumed training run, `eval`) gets it back. The feature maps are
/// compressed with the stored basis (not a new fit), so that the targets
/// are the ones the field was trained on, and the recorded novel views are
/// appended as read from `novel/`.
///
/// The capture is refused where it no longer loads into the frame the run
/// recorded (the capture or its loader changed since training): the field's
/// coordinates would silently mean other places.
pub fn rebuild_scene(dir: &RunDir, meta: &SceneMeta) -> Result<RunScene, OpsError> {
    let mut scene = datasets::load_scene_with_basis(&meta.source, meta.pca.as_ref())?;
    check_same_frame(dir, meta.world.as_ref(), scene.world.as_ref())?;
    let novel = append_recorded(&mut scene, &dir.novel())?;
    Ok(RunScene { scene, novel })
}

/// Refuses a rebuilt scene whose map from the capture's frame differs from
/// the recorded one (beyond rounding). Where either side has none (a run
/// written before runs recorded it, or a frame given to the run by hand
/// over a scene whose loader records none) there is nothing to compare.
fn check_same_frame(
    dir: &RunDir,
    recorded: Option<&datasets::WorldFrame>,
    rebuilt: Option<&datasets::WorldFrame>,
) -> Result<(), OpsError> {
    let (Some(recorded), Some(rebuilt)) = (recorded, rebuilt) else {
        return Ok(());
    };
    let (a, b) = (recorded.to_scene.to_matrix(), rebuilt.to_scene.to_matrix());
    let moved = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .any(|(x, y)| (x - y).abs() > 1e-6 * (1.0 + x.abs()));
    if moved {
        return Err(OpsError::Invalid(format!(
            "{}: the capture now loads into another frame than the `{}` frame this run was \
             trained in (the capture or its loader changed since): the field's coordinates \
             would mean other places; train the run again",
            dir.scene().display(),
            recorded.name
        )));
    }
    Ok(())
}

/// [`rebuild_scene`], with the novel views' indices added to
/// `split.train` (they are training frames); indices of `split.json`
/// outside the scene are refused.
pub fn load_run_scene(
    dir: &RunDir,
    meta: &SceneMeta,
    split: &mut Split,
) -> Result<datasets::Scene, OpsError> {
    let rebuilt = rebuild_scene(dir, meta)?;
    if let Some(novel) = rebuilt.novel {
        split.train.extend(novel.frames);
    }
    split.check(rebuilt.scene.frames.len(), &dir.split())?;
    Ok(rebuilt.scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_capture_loaded_into_another_frame_is_refused() {
        let dir = RunDir::new("/tmp/run");
        let frame = |yaw: f64| datasets::WorldFrame {
            name: "arkit".into(),
            to_scene: model::geometry::yaw_rotation(yaw),
            fitted_to: String::new(),
        };
        check_same_frame(&dir, Some(&frame(0.3)), Some(&frame(0.3))).expect("same frame");
        check_same_frame(&dir, None, Some(&frame(0.3))).expect("older runs are not checked");
        check_same_frame(&dir, Some(&frame(0.3)), None).expect("nothing to compare");
        for turn in [0.31, 0.3 + 1e-4, -0.3] {
            let e = check_same_frame(&dir, Some(&frame(0.3)), Some(&frame(turn)))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("/tmp/run/scene.json") && e.contains("`arkit` frame"),
                "{e}"
            );
        }
    }

    #[test]
    fn run_dir_paths() {
        let r = RunDir::new("/tmp/x");
        assert_eq!(r.config(), PathBuf::from("/tmp/x/config.json"));
        assert_eq!(r.weights(), PathBuf::from("/tmp/x/model.bpk"));
        assert_eq!(r.scene(), PathBuf::from("/tmp/x/scene.json"));
        assert_eq!(r.split(), PathBuf::from("/tmp/x/split.json"));
    }

    #[test]
    fn split_indices_outside_the_scene_name_the_file() {
        let split = Split {
            train: vec![0, 2],
            heldout: vec![1, 7],
        };
        split.check(8, Path::new("run/split.json")).expect("all in");
        let e = split
            .check(3, Path::new("run/split.json"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("run/split.json") && e.contains("heldout frame 7"),
            "{e}"
        );
    }

    #[test]
    fn missing_run_is_a_typed_error_naming_the_file() {
        let dir = std::env::temp_dir().join("eval-missing-run-dir-does-not-exist");
        let err = load_run(&dir, &Device::flex()).unwrap_err();
        match err {
            OpsError::Missing { path, .. } => assert!(path.ends_with("config.json")),
            other => panic!("unexpected error {other}"),
        }
    }

    #[test]
    fn config_without_model_key_is_rejected() {
        let dir = std::env::temp_dir().join(format!("eval-run-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("config.json");
        std::fs::write(&path, r#"{"iterations": 3}"#).unwrap();
        let err = read_model_config(&path).unwrap_err();
        assert!(err.to_string().contains("model"), "{err}");
        std::fs::write(&path, "{not json").unwrap();
        assert!(matches!(
            read_model_config(&path),
            Err(OpsError::Json { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
