//! Targets of a run directory: checkpoints, `metrics.jsonl`,
//! `config.json`, `scene.json`, `split.json`, `occupancy.bin` and the
//! novel views' `views.json`.
//!
//! No run directory is shared, so the seeds are made by the product's own
//! writers from small in-memory values.

use std::path::Path;

use datasets::{SceneMeta, SceneSource};
use field_ops::json::read_json;
use field_ops::run_dir::{Split, read_model_config};
use model::geometry::SceneBox;
use model::{OccupancyConfig, OccupancyGrid};
use train::TrainConfig;
use train::checkpoint::{Checkpoint, CheckpointState};

use super::{Seeds, Target, no_setup};

const RUN_TOKENS: &[&str] = &[
    "\"iteration\"",
    "\"occupancy\"",
    "\"event\": \"train\"",
    "\"event\": \"eval\"",
    "\"event\": \"final\"",
    "\"kind\": \"disk\"",
    "\"kind\": \"synthetic\"",
    "\"model\"",
    "\"pca\"",
    "\"train\": [",
    "\"heldout\": [",
    "4f43434752494431",
    "ONERFCK1",
    "OCCGRID1",
    "OCCGRID2",
    "4f43434752494432",
];

/// Checkpoint magic and header length (see `train::checkpoint`).
const MAGIC: &[u8; 8] = b"ONERFCK1";

fn grid() -> OccupancyGrid {
    let config = OccupancyConfig {
        resolution: 4,
        ..OccupancyConfig::default()
    };
    let mut grid = OccupancyGrid::new(&config);
    let density: Vec<f32> = (0..64).map(|i| (i % 7) as f32 * 0.3).collect();
    grid.update(&density);
    grid
}

fn state(occupancy: bool) -> CheckpointState {
    CheckpointState {
        iteration: 1200,
        seed: 7,
        skipped_steps: 1,
        wall_seconds: 12.5,
        train_seconds: 10.25,
        rays_processed: 4096 * 1200,
        occupancy: occupancy.then(|| grid().to_hex()),
    }
}

fn checkpoint_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    [true, false]
        .iter()
        .map(|&occ| {
            Checkpoint {
                state: state(occ),
                model: (0..64).collect(),
                optimizer: (0..32).rev().collect(),
            }
            .to_bytes()
        })
        .collect()
}

/// Reads a checkpoint and decodes its state, as resuming does.
fn run_checkpoint(path: &Path) {
    if let Ok(ckpt) = Checkpoint::read(path)
        && let Some(hex) = &ckpt.state.occupancy
    {
        let _ = train::occupancy::decode(hex, path);
    }
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Seals a mutated training state into a checkpoint with a right header
/// and checksum, so that the mutations reach the JSON and the occupancy
/// grid instead of stopping at the checksum.
fn run_checkpoint_state(path: &Path) {
    let Ok(state) = std::fs::read(path) else {
        return;
    };
    let mut file = MAGIC.to_vec();
    for len in [state.len(), 0, 0] {
        file.extend((len as u64).to_le_bytes());
    }
    file.extend(fnv1a(&state).to_le_bytes());
    file.extend(&state);
    let sealed = path.with_extension("onck");
    if std::fs::write(&sealed, file).is_ok() {
        run_checkpoint(&sealed);
    }
}

fn metrics_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let lines = [
        r#"{"depth_mae_interior":1.31,"event":"eval","feature_cosine_interior":0.026,"iteration":0,"pixels_interior":1024,"psnr_interior":11.8,"wall_seconds":0.0}"#,
        r#"{"depth":0.28,"event":"train","iteration":25,"loss":0.51,"lr":0.0014,"open":0.44,"psnr":14.98,"rays_per_second":1528.9,"rgb_mse":0.0318,"wall_seconds":5.05}"#,
        r#"{"depth":0.277,"event":"train","iteration":50,"loss":0.478,"lr":0.0018,"occupied_cells":1.0,"open":0.41,"psnr":15.0,"ray_length_sampled":1.0,"rays_per_second":1241.6,"rays_rendered":1.0,"rgb_mse":0.0315,"wall_seconds":6.26}"#,
        r#"{"depth_mae_interior":0.9,"event":"final","feature_cosine_interior":0.5,"iteration":50,"pixels_interior":1024,"psnr_interior":16.2,"wall_seconds":7.0}"#,
    ];
    vec![(lines.join("\n") + "\n").into_bytes()]
}

fn run_metrics(path: &Path) {
    if let Ok(text) = std::fs::read_to_string(path) {
        let _ = train::curve::parse(&text);
    }
    let _ = train::metrics_log::read(path);
    let _ = train::metrics_log::initial_eval(path);
}

fn config_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let full = serde_json::to_vec_pretty(&TrainConfig::default_run(512)).unwrap_or_default();
    let patch =
        br#"{"schedule": {"iterations": 100}, "occupancy": {"enabled": true, "resolution": 32}}"#;
    vec![full, patch.to_vec()]
}

/// Reads `config.json` as training (over the defaults, then checked) and
/// as every later command (its `"model"` key) reads it.
fn run_config(path: &Path) {
    // The base `train` lays a config file over.
    let base = TrainConfig::default_run(512);
    if let Ok(c) = TrainConfig::from_file(path, &base) {
        let _ = c.validate();
    }
    let _ = train::validate::config_keys(path, &base);
    let _ = read_model_config(path);
}

fn scene_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let meta = SceneMeta {
        source: SceneSource::Synthetic {
            seed: 3,
            size: "ci".into(),
            pca: None,
        },
        scene_box: SceneBox {
            min: [-1.0, -2.0, -0.5],
            max: [1.0, 2.0, 1.5],
        },
        background: Some([1.0, 1.0, 1.0]),
        pca: Some(datasets::features::PcaBasis {
            dim: 4,
            k: 2,
            mean: vec![0.1, 0.2, 0.3, 0.4],
            components: vec![1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            explained_variance_ratio: 0.9,
        }),
        feature_dim: Some(4),
        world: None,
    };
    let disk = br#"{"source": {"kind": "disk", "format": "replica", "options": {"stride": 2}, "path": "/data/room0"},
 "scene_box": {"min": [-3, -3, -1], "max": [3, 3, 2]}, "background": null, "pca": null, "feature_dim": 512}"#;
    vec![
        serde_json::to_vec_pretty(&meta).unwrap_or_default(),
        disk.to_vec(),
    ]
}

fn run_scene(path: &Path) {
    let _ = read_json::<SceneMeta>(path);
}

fn run_split(path: &Path) {
    let _ = read_json::<Split>(path);
}

fn run_occupancy(path: &Path) {
    if let Ok(bytes) = std::fs::read(path) {
        let _ = OccupancyGrid::from_bytes(&bytes);
    }
}

fn views_seeds(_: &Seeds) -> Vec<Vec<u8>> {
    let view = br#"{"mode": "guided", "added_at": 500, "views": [{"name": "novel_0000",
 "camera": {"intrinsics": {"width": 64, "height": 48, "fx": 50.0, "fy": 50.0, "cx": 31.5, "cy": 23.5,
  "distortion": {"k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0}},
  "pose": {"rotation": [[1,0,0],[0,1,0],[0,0,1]], "translation": [0.5, 0.0, 2.0]}},
 "rgb": "novel_0000.png", "depth": "novel_0000_depth.npy", "features": "novel_0000_features.npy",
 "depth_weight": 0.5, "target": [0, 0, 0], "uncertainty": 0.75}]}"#;
    vec![view.to_vec()]
}

fn run_views(path: &Path) {
    if let Some(dir) = path.parent() {
        let _ = datasets::novel_record::read_record(dir);
    }
}

macro_rules! target {
    ($name:literal, $about:literal, $file:literal, $seeds:expr, $run:expr) => {
        Target {
            name: $name,
            about: $about,
            file: $file,
            tokens: RUN_TOKENS,
            seeds: $seeds,
            setup: no_setup,
            run: $run,
        }
    };
}

/// The targets of this module.
pub(super) fn targets() -> Vec<Target> {
    vec![
        target!(
            "checkpoint",
            "train::checkpoint::Checkpoint::read, train::occupancy::decode",
            "ckpt-00001200.onck",
            checkpoint_seeds,
            run_checkpoint
        ),
        target!(
            "checkpoint-state",
            "Checkpoint::read of a resealed mutated state, train::occupancy::decode",
            "state.json",
            |_| [true, false]
                .iter()
                .map(|&o| serde_json::to_vec(&state(o)).unwrap_or_default())
                .collect(),
            run_checkpoint_state
        ),
        target!(
            "metrics-jsonl",
            "train::metrics_log::read, initial_eval, train::curve::parse",
            "metrics.jsonl",
            metrics_seeds,
            run_metrics
        ),
        target!(
            "run-config",
            "TrainConfig::from_file + validate, validate::config_keys, run_dir::read_model_config",
            "config.json",
            config_seeds,
            run_config
        ),
        target!(
            "run-scene",
            "field_ops::json::read_json::<SceneMeta> (scene.json)",
            "scene.json",
            scene_seeds,
            run_scene
        ),
        target!(
            "run-split",
            "field_ops::json::read_json::<Split> (split.json)",
            "split.json",
            |_| vec![br#"{"train": [0, 1, 2, 4, 5, 6], "heldout": [3, 7]}"#.to_vec()],
            run_split
        ),
        target!(
            "occupancy-grid",
            "model::OccupancyGrid::from_bytes (occupancy.bin)",
            "occupancy.bin",
            |_| vec![grid().to_bytes()],
            run_occupancy
        ),
        target!(
            "novel-views",
            "datasets::novel_record::read_record (novel/views.json)",
            "views.json",
            views_seeds,
            run_views
        ),
    ]
}
