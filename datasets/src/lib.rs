//! Everything that turns files on disk (or a seed) into scenes and ray
//! batches: Nice-SLAM Replica, Blender/nerfstudio, LLFF, COLMAP and ScanNet
//! loaders, lazy
//! feature maps with PCA compression, text embeddings, point clouds, the
//! synthetic benchmark scene with its simulated 2D feature extractor, and the
//! ray sampler.
#![warn(missing_docs)]

pub mod balance;
pub mod blender;
pub mod capture_kind;
pub mod colmap;
pub mod detect;
pub mod error;
pub mod extractor;
pub mod features;
pub mod footprint;
pub mod grid;
pub mod imageio;
pub mod llff;
pub mod mesh;
pub mod novel_record;
pub mod npy;
mod numeric;
pub mod options;
pub mod phone;
pub mod points;
pub mod poses;
pub mod progress;
pub mod replica;
pub mod sampler;
pub mod scannet;
pub mod scene;
pub mod sharpness;
pub mod synthetic;
pub mod text;
pub mod unseen;
pub mod writer;

pub use error::DatasetError;
pub use features::FeatureMap;
pub use options::{LoaderOptions, PhoneOptions};
pub use scene::{
    DepthData, DepthImage, Frame, RgbData, RgbImage, Scene, SceneMeta, SceneSource, VlmSource,
    WorldFrame,
};

use std::path::{Path, PathBuf};

/// Loads (or generates) the scene `source` describes.
pub fn load_scene(source: &SceneSource) -> Result<Scene, DatasetError> {
    load_scene_with_basis(source, None)
}

/// [`load_scene`], compressing the feature maps with `basis` (a run's
/// stored PCA basis) instead of fitting one: a rebuilt scene then has
/// exactly the targets its field was trained on.
pub fn load_scene_with_basis(
    source: &SceneSource,
    basis: Option<&features::PcaBasis>,
) -> Result<Scene, DatasetError> {
    match source {
        SceneSource::WithFeatures {
            base,
            features,
            pca,
            ..
        } => {
            let mut scene = load_scene_with_basis(base, None)?;
            overlay_features(&mut scene, features, *pca, basis)?;
            scene.source = source.clone();
            Ok(scene)
        }
        SceneSource::Synthetic { seed, size, pca } => {
            let size: synthetic::SceneSize = size.parse()?;
            let pca = pca.unwrap_or(size.default_pca());
            let mut scene = synthetic::generate_with(*seed, size, pca, basis)?;
            scene.source = source.clone();
            Ok(scene)
        }
        SceneSource::Disk { loader, path } => {
            // The basis given replaces any in the options (none is saved).
            let mut loader = loader.clone();
            if let Some(input) = loader.feature_input_mut() {
                input.basis = basis.cloned();
            }
            load_disk(path, &loader)
        }
    }
}

/// Loads the scene at `path` that `loader` describes: its format's loader
/// reads the frames, then the feature maps are attached
/// ([`FeatureInput::attach`](options::FeatureInput::attach)) for the
/// formats that have them. What the loader left out or assumed is printed
/// to stderr (one line each, naming the format) once the scene is whole.
/// The scene's source records `loader` without its basis.
pub fn load_disk(path: &Path, loader: &LoaderOptions) -> Result<Scene, DatasetError> {
    let mut resolution = None;
    let (mut scene, notes) = match loader {
        LoaderOptions::Replica(o) => (replica::load_without_features(path, o)?, Vec::new()),
        LoaderOptions::Blender(o) => (blender::load_blender(path, o)?, Vec::new()),
        LoaderOptions::Llff(o) => (llff::load_llff(path, o)?, Vec::new()),
        LoaderOptions::Colmap(o) => (colmap::load_without_features(path, o)?, Vec::new()),
        LoaderOptions::Scannet(o) => {
            let (scene, report) = scannet::load_scannet_with_report(path, o)?;
            (scene, report.note(path).into_iter().collect())
        }
        LoaderOptions::ScannerApp(_) | LoaderOptions::Record3d(_) | LoaderOptions::Polycam(_) => {
            let assembled = phone::assemble_export(path, loader)?;
            resolution = assembled.resolution;
            let notes = assembled.notes.iter();
            let notes = notes.map(|n| format!("{}: {n}", loader.format()));
            (assembled.scene, notes.collect())
        }
    };
    if let Some(input) = loader.feature_input() {
        input.attach(&mut scene)?;
    }
    // A size the loader chose is recorded, so that the scene is rebuilt at
    // it whatever the machine.
    let mut recorded = loader.without_basis();
    if resolution.is_some() {
        recorded.selection_mut().resolution = resolution;
    }
    scene.source = SceneSource::Disk {
        loader: recorded,
        path: path.to_path_buf(),
    };
    for note in notes {
        eprintln!("{note}");
    }
    Ok(scene)
}

/// Replaces `scene`'s feature maps by those in `dir` (`<frame name>.npy`
/// each), compressed with `basis` when given, else as `pca` says; and its
/// class embeddings, when it has classes, by `dir/classes.npy` +
/// `dir/classes.txt` (the same names, in the maps' space).
pub fn overlay_features(
    scene: &mut Scene,
    dir: &Path,
    pca: features::PcaSetting,
    basis: Option<&features::PcaBasis>,
) -> Result<(), DatasetError> {
    scene.features = None;
    scene.features = Some(features::load_frame_features(
        dir,
        &scene.frames,
        pca,
        basis,
        0,
    )?);
    if let Some(old) = &scene.classes {
        let (npy, txt) = (dir.join("classes.npy"), dir.join("classes.txt"));
        let classes = text::TextEmbeddings::load(&npy, &txt)?;
        if classes.names != old.names {
            return Err(DatasetError::invalid(
                &txt,
                format!(
                    "the class names differ from the scene's ({} vs {} classes): the maps were \
                     made for another scene",
                    classes.names.len(),
                    old.names.len()
                ),
            ));
        }
        scene.classes = Some(classes);
    }
    Ok(())
}

/// Directory of the shared real data: `$OPENNERF_DATA`, else `shared/data`
/// next to the workspace root.
pub fn data_dir() -> PathBuf {
    match std::env::var_os("OPENNERF_DATA") {
        Some(p) => PathBuf::from(p),
        None => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")),
    }
}

/// `name` under [`data_dir`], for tests and benchmarks on real data: `None`
/// (saying so) only where the data directory itself is absent; with the
/// directory there, a missing dataset panics, so that a test fails instead
/// of passing unexamined.
pub fn shared_dataset(name: &str) -> Option<PathBuf> {
    let root = data_dir();
    if !root.is_dir() {
        println!(
            "SKIP: no data directory {} (set OPENNERF_DATA)",
            root.display()
        );
        return None;
    }
    let path = root.join(name);
    assert!(
        path.is_dir(),
        "{}: missing from the shared data",
        path.display()
    );
    Some(path)
}

/// The directory this crate was compiled from (its manifest directory).
/// Every crate of one build names the same checkout; a test checks it, so
/// that a build never mixes in artifacts compiled from another checkout
/// sharing the target directory.
pub const BUILT_FROM: &str = env!("CARGO_MANIFEST_DIR");
