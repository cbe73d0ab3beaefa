//! Shared helpers for the end-to-end tests: the CI-sized synthetic scene
//! (generated once per test binary), a tiny training configuration, scratch
//! directories and the path of the real data.
#![warn(missing_docs)]

use std::path::PathBuf;
use std::sync::OnceLock;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Tensor};
use datasets::Scene;
use model::OpenNerf;
use train::{BackendKind, SessionOptions, TrainConfig};

/// The CI-sized synthetic scene with seed 0, generated once.
pub fn ci_scene() -> &'static Scene {
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        datasets::synthetic::generate(0, datasets::synthetic::SceneSize::Ci)
            .expect("the synthetic CI scene generates")
    })
}

/// The tiny training configuration (width 64, depth 4, 32 + 32 samples)
/// for `scene`, `iterations` long.
pub fn tiny_config(scene: &Scene, iterations: usize) -> TrainConfig {
    let mut c = TrainConfig::tiny(scene.features.as_ref().map_or(0, |f| f.dim()));
    c.schedule.iterations = iterations;
    c
}

/// A fresh scratch directory, removed when the returned guard drops.
pub fn scratch_dir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("opennerf-e2e-")
        .tempdir()
        .expect("a temporary directory can be created")
}

/// The real-data directory: `$OPENNERF_DATA`, else `../shared/data` next to
/// the workspace. `None` (with a printed message) when it does not exist.
pub fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("OPENNERF_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data"))
        });
    if dir.exists() {
        Some(dir)
    } else {
        println!(
            "skipped: real data not found at {} (set OPENNERF_DATA)",
            dir.display()
        );
        None
    }
}

/// Whether the wgpu backend should be exercised: a Vulkan driver manifest
/// is installed, or `OPENNERF_TEST_WGPU=1`.
pub fn wgpu_enabled() -> bool {
    std::env::var("OPENNERF_TEST_WGPU").is_ok_and(|v| v == "1")
        || train::backend::vulkan_available()
}

/// Serialises the training tests of one binary: the CPU backends draw the
/// stratified jitter from a process-wide generator that training reseeds
/// every iteration, so two trainings interleaving in threads would perturb
/// each other's random streams (and they would only compete for the same
/// cores anyway).
pub fn serial() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A flex session without the final render, stopping at `stop_at`.
pub fn flex_session(stop_at: Option<usize>) -> SessionOptions {
    SessionOptions {
        backend: BackendKind::Flex,
        final_render: false,
        stop_at,
        ..Default::default()
    }
}

/// All weights of `model`, flattened in visiting order.
pub fn weights(model: &OpenNerf) -> Vec<f32> {
    struct Collect(Vec<f32>);
    impl ModuleVisitor for Collect {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0
                .extend(p.val().into_data().try_to_vec::<f32>().unwrap());
        }
    }
    let mut c = Collect(Vec::new());
    model.visit(&mut c);
    c.0
}

/// All weights of the run in `dir`, flattened.
pub fn run_weights(dir: &std::path::Path) -> Vec<f32> {
    weights(
        &field_ops::run_dir::load_run(dir, &Device::flex())
            .unwrap()
            .model,
    )
}

/// The largest absolute difference between two equally long vectors.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max)
}
