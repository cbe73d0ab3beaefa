//! The novel-view oracle: ground-truth renders of a captured camera are the
//! captured frame, with the captured features; ground-truth labels name the
//! class under every map cell; scenes without ground truth are refused.

#[allow(dead_code)] // only the tiny field of the shared helpers is used here
mod common;

use burn::tensor::Device;
use datasets::synthetic::{SceneSize, generate};
use datasets::{Scene, SceneSource};
use field_ops::novel::oracle::{GroundTruth, NovelOracle, label_features};
use field_ops::novel::{AimedCamera, NovelViewConfig, render_views, scene_extractor};

fn ci_scene() -> Scene {
    generate(0, SceneSize::Ci).expect("CI scene")
}

fn oracle_views(
    scene: &Scene,
    frames: &[usize],
    oracle: NovelOracle,
) -> Vec<datasets::novel_record::NovelView> {
    let config = NovelViewConfig {
        views: frames.len(),
        scale: 1.0,
        oracle: Some(oracle),
        ..NovelViewConfig::default()
    };
    let extractor = scene_extractor(scene, &config, &Device::flex()).expect("extractor");
    let model =
        common::tiny_config(scene.features.as_ref().expect("features").dim()).init(&Device::flex());
    let cameras: Vec<AimedCamera> = frames
        .iter()
        .map(|&i| AimedCamera {
            camera: scene.frames[i].camera,
            target: None,
            uncertainty: None,
        })
        .collect();
    render_views(
        &model,
        &cameras,
        scene,
        extractor.as_ref(),
        &config,
        4096,
        |_, _| {},
    )
    .expect("oracle views")
}

#[test]
fn ground_truth_renders_of_a_captured_camera_are_the_captured_frame_and_features() {
    let scene = ci_scene();
    let set = scene.features.as_ref().expect("features");
    assert!(
        set.pca.is_none(),
        "the CI scene keeps its features uncompressed"
    );
    for (view, &i) in oracle_views(&scene, &[0, 7], NovelOracle::Renders)
        .iter()
        .zip(&[0usize, 7])
    {
        let frame = &scene.frames[i];
        assert_eq!(view.rgb, frame.rgb, "colour of frame {i}");
        assert_eq!(
            Some(&view.depth),
            frame.depth.as_ref(),
            "depth of frame {i}"
        );
        assert!(view.depth.to_f32().iter().all(|&d| d > 0.0));
        assert_eq!(view.features, set.maps[i], "features of frame {i}");
    }
}

#[test]
fn ground_truth_labels_name_the_class_under_every_map_cell() {
    let scene = ci_scene();
    let set = scene.features.as_ref().expect("features");
    let SceneSource::Synthetic { seed, .. } = scene.source else {
        panic!("synthetic")
    };
    let emb = datasets::synthetic::extractor_for(seed, SceneSize::Ci)
        .embeddings()
        .clone();
    let argmax = |f: &[half::f16]| -> usize {
        (0..emb.len())
            .max_by(|&a, &b| {
                let dot = |c: usize| -> f32 {
                    emb.row(c).iter().zip(f).map(|(e, v)| e * v.to_f32()).sum()
                };
                dot(a).total_cmp(&dot(b))
            })
            .expect("classes")
    };
    let i = 5;
    let view = &oracle_views(&scene, &[i], NovelOracle::Labels)[0];
    let frame = &scene.frames[i];
    let labels = frame.labels.as_ref().expect("labels");
    let (w, h) = (frame.rgb.width, frame.rgb.height);
    let map = &view.features;
    assert_eq!(
        (map.width, map.height, map.dim),
        (set.maps[i].width, set.maps[i].height, emb.dim)
    );
    let (mut right, mut extractor_right, mut cells) = (0, 0, 0);
    for y in 0..map.height {
        for x in 0..map.width {
            // The cell centre in image pixels, computed independently.
            let px = ((2 * x + 1) * w) / (2 * map.width);
            let py = ((2 * y + 1) * h) / (2 * map.height);
            let label = labels[(py * w + px) as usize] as usize;
            let o = (y * map.width + x) as usize * map.dim;
            right += usize::from(argmax(&map.data[o..o + map.dim]) == label);
            extractor_right += usize::from(argmax(&set.maps[i].data[o..o + map.dim]) == label);
            cells += 1;
        }
    }
    assert_eq!(right, cells, "every cell names its class");
    assert!(
        extractor_right < cells,
        "the extractor misreads some cells ({extractor_right} of {cells} right), the oracle none"
    );
}

#[test]
fn label_features_refuse_a_label_without_embedding_and_disk_scenes_have_no_oracle() {
    let emb = datasets::synthetic::extractor_for(0, SceneSize::Ci)
        .embeddings()
        .clone();
    let ok = label_features(&[0, 1, 2, 3], (2, 2), (1, 1), &emb).expect("one cell");
    // The centre of a 2 x 2 image in a 1 x 1 map is pixel (1, 1): label 3.
    let row: Vec<f32> = ok.data.iter().map(|v| v.to_f32()).collect();
    let want: Vec<f32> = emb
        .row(3)
        .iter()
        .map(|&v| half::f16::from_f32(v).to_f32())
        .collect();
    assert_eq!(row, want);
    let err = label_features(&[0, 1, 2, u16::MAX], (2, 2), (1, 1), &emb).expect_err("no class");
    assert!(err.to_string().contains("65535"), "{err}");

    let mut scene = ci_scene();
    scene.source = SceneSource::Disk {
        loader: datasets::LoaderOptions::Replica(Default::default()),
        path: "/data/room0".into(),
    };
    let err = GroundTruth::of(&scene, NovelOracle::Labels)
        .err()
        .expect("no ground truth on disk");
    assert!(err.to_string().contains("synthetic"), "{err}");
    // Training asks for the extractor before its first step: refused there.
    let config = NovelViewConfig {
        views: 2,
        oracle: Some(NovelOracle::Renders),
        extractor: Some(vec!["extract".into()]),
        ..NovelViewConfig::default()
    };
    let err = scene_extractor(&scene, &config, &Device::flex())
        .err()
        .expect("refused before training");
    assert!(err.to_string().contains("renders"), "{err}");
}

/// Counts how the extractor is asked: one image at a time, or in batches.
struct CountingExtractor {
    inner: Box<dyn datasets::extractor::FeatureExtractor>,
    single: std::cell::Cell<usize>,
    batches: std::cell::RefCell<Vec<usize>>,
}

impl datasets::extractor::FeatureExtractor for CountingExtractor {
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    fn extract(
        &self,
        image: &datasets::RgbImage,
    ) -> Result<datasets::FeatureMap, datasets::DatasetError> {
        self.single.set(self.single.get() + 1);
        self.inner.extract(image)
    }

    fn extract_batch(
        &self,
        images: &[&datasets::RgbImage],
    ) -> Result<Vec<datasets::FeatureMap>, datasets::DatasetError> {
        self.batches.borrow_mut().push(images.len());
        images.iter().map(|i| self.inner.extract(i)).collect()
    }

    fn extract_each(
        &self,
        images: &[&datasets::RgbImage],
        each: &mut dyn FnMut(datasets::FeatureMap) -> Result<(), datasets::DatasetError>,
    ) -> Result<(), datasets::DatasetError> {
        for map in self.extract_batch(images)? {
            each(map)?;
        }
        Ok(())
    }
}

#[test]
fn the_field_s_novel_views_are_read_by_the_extractor_in_one_batch() {
    let scene = ci_scene();
    let config = NovelViewConfig {
        views: 3,
        scale: 0.5,
        ..NovelViewConfig::default()
    };
    let extractor = CountingExtractor {
        inner: scene_extractor(&scene, &config, &Device::flex()).expect("extractor"),
        single: std::cell::Cell::new(0),
        batches: std::cell::RefCell::new(Vec::new()),
    };
    let model =
        common::tiny_config(scene.features.as_ref().expect("features").dim()).init(&Device::flex());
    let cameras: Vec<AimedCamera> = [2, 5, 9]
        .iter()
        .map(|&i| AimedCamera {
            camera: scene.frames[i].camera.scaled(48, 27),
            target: None,
            uncertainty: None,
        })
        .collect();
    let mut progress = Vec::new();
    let views = render_views(
        &model,
        &cameras,
        &scene,
        &extractor,
        &config,
        4096,
        |done, total| progress.push((done, total)),
    )
    .expect("views");
    assert_eq!(views.len(), 3);
    assert_eq!(
        *extractor.batches.borrow(),
        vec![3],
        "one batch of every view"
    );
    assert_eq!(extractor.single.get(), 0, "no view read on its own");
    assert_eq!(progress, vec![(1, 3), (2, 3), (3, 3)]);
    // Each view's map is the extractor's reading of that view's render,
    // cleared where the render stayed transparent.
    for v in &views {
        let mut expected = extractor.inner.extract(&v.rgb).expect("map");
        field_ops::novel::extract::mask_fog_cells(&mut expected, &v.depth);
        let bits =
            |m: &datasets::FeatureMap| m.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            (v.features.width, v.features.height),
            (expected.width, expected.height)
        );
        assert_eq!(bits(&v.features), bits(&expected));
    }
}
