//! Shared helpers for the end-to-end tests: the CI-sized synthetic scene
//! (generated once per test binary), a tiny training configuration, scratch
//! directories and the path of the real data.
#![warn(missing_docs)]

use std::path::PathBuf;
use std::sync::OnceLock;

use datasets::Scene;
use train::TrainConfig;

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
