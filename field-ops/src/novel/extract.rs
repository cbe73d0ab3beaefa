//! Rendering novel cameras with the field and reading their features with
//! the scene's 2D extractor (or the oracle's ground truth).

use burn::tensor::Device;
use datasets::extractor::{CommandExtractor, FeatureExtractor};
use datasets::features::{FeatureMap, compress_map};
use datasets::novel_record::NovelView;
use datasets::{DepthImage, RgbImage, Scene, SceneSource};
use model::OpenNerf;
use model::geometry::Camera;

use super::cameras::AimedCamera;
use super::config::NovelViewConfig;
use super::oracle::GroundTruth;
use super::view::ExtractedView;
use crate::error::OpsError;
use crate::render::{ViewSettings, render_view};

/// Where a scene's novel views get their features, as far as can be told
/// without loading anything.
enum ExtractorSource<'a> {
    /// The CLIP model that made the scene's maps (`--vlm`).
    Vlm(&'a datasets::VlmSource),
    /// An external command (program and leading arguments).
    Command(&'a str, &'a [String]),
    /// The synthetic scene's simulated extractor.
    Synthetic(u64, datasets::synthetic::SceneSize),
}

/// The source of `scene`'s novel-view features, refusing a scene without
/// maps, an oracle on a scene without ground truth and a scene on disk
/// without a way to extract.
fn extractor_source<'a>(
    scene: &'a Scene,
    config: &'a NovelViewConfig,
) -> Result<ExtractorSource<'a>, OpsError> {
    if scene.features.is_none() {
        return Err(OpsError::Invalid(format!(
            "scene {} has no feature maps: novel views need a feature extractor and a feature head",
            scene.name
        )));
    }
    if let Some(oracle) = config.oracle {
        // Refused here, before training, rather than half-way through it.
        GroundTruth::of(scene, oracle)?;
    }
    match (scene.source.vlm(), scene.source.base(), &config.extractor) {
        (_, _, Some(cmd)) => {
            let (program, args) = cmd
                .split_first()
                .ok_or_else(|| OpsError::Invalid("the extractor command is empty".into()))?;
            Ok(ExtractorSource::Command(program, args))
        }
        (Some(vlm), _, None) => {
            if !vlm.model.is_dir() {
                return Err(OpsError::Invalid(format!(
                    "the run's --vlm {}: not a directory (novel views are extracted with it)",
                    vlm.model.display()
                )));
            }
            Ok(ExtractorSource::Vlm(vlm))
        }
        (None, SceneSource::Synthetic { seed, size, .. }, None) => {
            Ok(ExtractorSource::Synthetic(*seed, size.parse()?))
        }
        (None, _, None) => Err(OpsError::Invalid(format!(
            "novel views of scene {} need the 2D feature extractor that made its feature maps: give --extractor-command (or train with --vlm)",
            scene.name
        ))),
    }
}

/// Checks before training that novel views of `scene` can be extracted as
/// `config` says (see [`scene_extractor`]), without loading a model.
pub fn check_extractor(scene: &Scene, config: &NovelViewConfig) -> Result<(), OpsError> {
    extractor_source(scene, config).map(|_| ())
}

/// The scene's 2D feature extractor: the configured command, the CLIP model
/// that made its maps (in process, on `device`), or the simulated one of a
/// synthetic scene. Also refuses an oracle on a scene without ground truth.
pub fn scene_extractor(
    scene: &Scene,
    config: &NovelViewConfig,
    device: &Device,
) -> Result<Box<dyn FeatureExtractor>, OpsError> {
    Ok(match extractor_source(scene, config)? {
        ExtractorSource::Command(program, args) => Box::new(CommandExtractor::new(
            program,
            args.to_vec(),
            scene.features.as_ref().map_or(0, |f| f.full_dim),
        )),
        ExtractorSource::Vlm(vlm) => {
            let model = clip::VisionModel::load(&vlm.model, device).map_err(|e| {
                OpsError::Invalid(format!("the run's --vlm {}: {e}", vlm.model.display()))
            })?;
            let options = clip::DenseOptions {
                variant: vlm.dense,
                short_side: Some(vlm.short_side),
                ..clip::DenseOptions::default()
            };
            Box::new(clip::ClipExtractor::new(
                std::sync::Arc::new(model),
                options,
            ))
        }
        ExtractorSource::Synthetic(seed, size) => {
            Box::new(datasets::synthetic::extractor_for(seed, size))
        }
    })
}

/// Renders each camera, runs `extractor` on the rendered colour and
/// compresses the map with the scene's basis. Rendered depth is kept where
/// the accumulated opacity reaches `config.min_acc` (0 elsewhere: no target).
/// With `config.oracle`, a synthetic scene's ground truth stands in for the
/// field's render (and for the extractor's reading with
/// [`NovelOracle::Labels`](super::oracle::NovelOracle::Labels)). `progress(done, total)` is called per view rendered;
/// the extractor then reads every rendered view in one batch.
#[allow(clippy::too_many_arguments)]
pub fn render_views(
    model: &OpenNerf,
    cameras: &[AimedCamera],
    scene: &Scene,
    extractor: &dyn FeatureExtractor,
    config: &NovelViewConfig,
    chunk: usize,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<NovelView>, OpsError> {
    let pca = scene.features.as_ref().and_then(|f| f.pca.as_ref());
    let truth = config
        .oracle
        .map(|o| GroundTruth::of(scene, o))
        .transpose()?;
    // Each map is compressed (and its fog cleared) as soon as it is read,
    // so that one full-dimensional map is held at a time.
    let finish = |full: FeatureMap, depth: &DepthImage| {
        let mut features = match pca {
            Some(basis) => compress_map(&full, basis),
            None => full,
        };
        if config.mask_features {
            mask_fog_cells(&mut features, depth);
        }
        features
    };
    let extracted: Vec<ExtractedView> = match &truth {
        Some(truth) => {
            let mut views = Vec::with_capacity(cameras.len());
            for (i, aimed) in cameras.iter().enumerate() {
                let view = truth.view(&aimed.camera, extractor)?;
                let features = finish(view.features, &view.depth);
                views.push(ExtractedView { features, ..view });
                progress(i + 1, cameras.len());
            }
            views
        }
        None => {
            // Every view is rendered first, then read by the extractor in
            // one batch: an external command starts once, not per view.
            let mut rendered = Vec::with_capacity(cameras.len());
            for (i, aimed) in cameras.iter().enumerate() {
                rendered.push(field_render(model, &aimed.camera, scene, config, chunk));
                progress(i + 1, cameras.len());
            }
            let images: Vec<&RgbImage> = rendered.iter().map(|(rgb, _)| rgb).collect();
            let mut maps = Vec::with_capacity(rendered.len());
            let mut returned = 0;
            extractor.extract_each(&images, &mut |full| {
                if let Some((_, depth)) = rendered.get(returned) {
                    maps.push(finish(full, depth));
                }
                returned += 1;
                Ok(())
            })?;
            if returned != rendered.len() {
                return Err(OpsError::Invalid(format!(
                    "the extractor returned {returned} feature maps for {} views",
                    rendered.len()
                )));
            }
            rendered
                .into_iter()
                .zip(maps)
                .map(|((rgb, depth), features)| ExtractedView {
                    rgb,
                    depth,
                    features,
                })
                .collect()
        }
    };
    let mut out = Vec::with_capacity(cameras.len());
    for (i, (aimed, view)) in cameras.iter().zip(extracted).enumerate() {
        out.push(NovelView {
            name: format!("novel_{i:03}"),
            camera: aimed.camera,
            rgb: view.rgb,
            depth: view.depth,
            features: view.features,
            depth_weight: config.depth_weight,
            color_weight: config.color_weight,
            target: aimed.target,
            uncertainty: aimed.uncertainty,
        });
    }
    Ok(out)
}

/// Clears (NaN: no target) every cell of `map` whose image pixels mostly
/// lack trusted depth, i.e. whose rendered opacity stayed below the
/// threshold `field_render` keeps depth at. The extractor reads such cells
/// off fog or background, and a field trained on them learns what it
/// rendered, not what is there. A cell covers the image pixels whose centres
/// fall in its footprint (the map may be coarser than the image); it keeps
/// its target when at least half of them have depth. Returns the cells
/// cleared.
pub fn mask_fog_cells(map: &mut FeatureMap, depth: &DepthImage) -> usize {
    let (mw, mh) = (map.width as usize, map.height as usize);
    let (w, h) = (depth.width as usize, depth.height as usize);
    if mw == 0 || mh == 0 || w == 0 || h == 0 {
        return 0;
    }
    let mut opaque = vec![0u32; mw * mh];
    let mut total = vec![0u32; mw * mh];
    for y in 0..h {
        let cy = (y * mh / h).min(mh - 1);
        for x in 0..w {
            let c = cy * mw + (x * mw / w).min(mw - 1);
            total[c] += 1;
            opaque[c] += u32::from(depth.value(y * w + x) > 0.0);
        }
    }
    let dim = map.dim;
    let mut cleared = 0;
    for (c, (&o, &t)) in opaque.iter().zip(&total).enumerate() {
        if 2 * o < t {
            map.data[c * dim..(c + 1) * dim].fill(half::f16::NAN);
            cleared += 1;
        }
    }
    cleared
}

/// The field's render of `camera`: colour clamped to [0, 1], depth kept
/// where the opacity reaches `config.min_acc` (0 elsewhere).
fn field_render(
    model: &OpenNerf,
    camera: &Camera,
    scene: &Scene,
    config: &NovelViewConfig,
    chunk: usize,
) -> (RgbImage, DepthImage) {
    let settings = ViewSettings::new(scene.background, chunk);
    let view = render_view(model, camera, &scene.scene_box, &settings)
        .expect("never cancelled without an observer");
    let rgb = RgbImage {
        width: view.width,
        height: view.height,
        data: datasets::RgbData::F32(view.rgb.iter().map(|v| v.clamp(0.0, 1.0)).collect()),
    };
    let depth = DepthImage {
        width: view.width,
        height: view.height,
        data: datasets::DepthData::F32(
            view.depth
                .iter()
                .zip(&view.acc)
                .map(|(&d, &a)| {
                    if a >= config.min_acc && d.is_finite() && d > 0.0 {
                        d
                    } else {
                        0.0
                    }
                })
                .collect(),
        ),
    };
    (rgb, depth)
}
