//! The state of a session in and out of checkpoints: the optimiser, the
//! model and optimiser restored from a checkpoint, and a checkpoint saved.

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::optim::ModuleOptimizer;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device};
use field_ops::run_dir::RunDir;
use model::{FusedAdamConfig, OccupancyGrid, OpenNerf};

use crate::checkpoint::{Checkpoint, CheckpointState, checkpoint_path, prune_checkpoints};
use crate::config::TrainConfig;
use crate::error::TrainError;

/// A fresh optimiser of `config`: Adam, in one pass a parameter on flex
/// (its records the same as Burn's Adam's).
pub(super) fn adam(config: &TrainConfig) -> ModuleOptimizer {
    FusedAdamConfig::new()
        .with_beta_1(config.optimiser.beta_1)
        .with_beta_2(config.optimiser.beta_2)
        .with_epsilon(config.optimiser.epsilon)
        .init()
}

/// Model and optimiser from a checkpoint; any mismatch is reported against
/// the checkpoint file.
pub fn restore(
    config: &TrainConfig,
    ckpt: &Checkpoint,
    path: &Path,
    device: &Device,
) -> Result<(OpenNerf, ModuleOptimizer), TrainError> {
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(ckpt.model.clone()))
        .map_err(|e| TrainError::checkpoint(path, format!("model record: {e}")))?;
    let model = config
        .model
        .init(device)
        .try_load_record(record)
        .map_err(|e| {
            TrainError::checkpoint(path, format!("model does not match config.json: {e}"))
        })?;
    let optim = adam(config)
        .from_bytes(Bytes::from_bytes_vec(ckpt.optimizer.clone()))
        .map_err(|e| TrainError::checkpoint(path, format!("optimiser record: {e}")))?;
    let grid = match &ckpt.state.occupancy {
        Some(hex) => Some(crate::occupancy::decode(hex, path)?),
        None => config.occupancy.initial_grid(),
    };
    Ok((model.with_occupancy(grid), optim))
}

/// Serialised model weights (burnpack).
pub fn model_bytes(model: &OpenNerf) -> Result<Vec<u8>, TrainError> {
    let bytes = model
        .clone()
        .into_record()
        .into_bytes()
        .map_err(|e| TrainError::Device(format!("cannot serialise the model: {e}")))?;
    Ok(bytes.to_vec())
}

/// Saves a checkpoint of `state` (with the model's occupancy grid, also
/// written as `occupancy.bin`) and keeps the newest `keep`.
pub(super) fn save_checkpoint(
    run: &RunDir,
    model: &OpenNerf,
    optim: &ModuleOptimizer,
    state: &CheckpointState,
    keep: usize,
) -> Result<PathBuf, TrainError> {
    let optimizer = optim
        .into_bytes()
        .map_err(|e| TrainError::Device(format!("cannot serialise the optimiser: {e}")))?
        .to_vec();
    let mut state = state.clone();
    state.occupancy = model.occupancy().map(OccupancyGrid::to_hex);
    let ckpt = Checkpoint {
        state,
        model: model_bytes(model)?,
        optimizer,
    };
    let path = checkpoint_path(&run.checkpoints(), ckpt.state.iteration);
    ckpt.write(&path)?;
    if let Some(grid) = model.occupancy() {
        field_ops::files::write_atomic(&run.occupancy(), &grid.to_bytes())?;
    }
    prune_checkpoints(&run.checkpoints(), keep)?;
    Ok(path)
}
