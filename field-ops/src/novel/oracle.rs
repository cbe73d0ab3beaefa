//! Ground truth in place of the field's render or of the extractor's
//! reading, for novel views of a synthetic scene: what the novel-view
//! mechanism could give with a perfect field (`renders`) or with an
//! extractor that reads every pixel right (`labels`). These bound what
//! camera choice can achieve on a scene; they are diagnostics, not a way to
//! train on real captures (there is no ground truth there).

use datasets::extractor::{FeatureExtractor, SimulatedExtractor};
use datasets::grid::nearest_pixel;
use datasets::synthetic::{self, Room, SceneSize, classes, raytrace};
use datasets::text::TextEmbeddings;
use datasets::{FeatureMap, Scene, SceneSource};
use half::f16;
use model::geometry::Camera;
use serde::{Deserialize, Serialize};

use super::view::ExtractedView;
use crate::error::OpsError;

/// Which ground truth replaces the pipeline's own output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum NovelOracle {
    /// Colour and depth ray-traced from the scene instead of rendered by the
    /// field; the extractor reads them as it reads the captured frames.
    Renders,
    /// As `renders`, and each feature-map pixel is the text embedding of
    /// the class under its centre instead of the extractor's reading.
    Labels,
}

impl NovelOracle {
    /// The name on the command line and in records.
    pub fn name(self) -> &'static str {
        match self {
            NovelOracle::Renders => "renders",
            NovelOracle::Labels => "labels",
        }
    }
}

/// The ground truth of a synthetic scene, ready to ray-trace views.
pub struct GroundTruth {
    oracle: NovelOracle,
    room: Room,
    palette: Vec<[f64; 3]>,
    /// The scene's own extractor: its map grid and the class embeddings it
    /// mixes its features from are those of the label maps.
    simulated: SimulatedExtractor,
}

impl GroundTruth {
    /// The ground truth of `scene`.
    ///
    /// # Errors
    /// When the scene is not a synthetic one.
    pub fn of(scene: &Scene, oracle: NovelOracle) -> Result<Self, OpsError> {
        let SceneSource::Synthetic { seed, size, .. } = &scene.source else {
            return Err(OpsError::Invalid(format!(
                "the novel-view oracle `{}` needs a synthetic scene (its ground truth); scene {} is read from disk",
                oracle.name(),
                scene.name
            )));
        };
        let size: SceneSize = size.parse()?;
        Ok(Self {
            oracle,
            room: synthetic::build_room(*seed),
            palette: classes::palette(*seed),
            simulated: synthetic::extractor_for(*seed, size),
        })
    }

    /// Ray-traces `camera` and reads the result: with `extractor` for
    /// [`NovelOracle::Renders`]; from the labels for [`NovelOracle::Labels`],
    /// on the grid of the scene's own extractor (the label under each cell's
    /// centre), without running an extractor.
    pub fn view(
        &self,
        camera: &Camera,
        extractor: &dyn FeatureExtractor,
    ) -> Result<ExtractedView, OpsError> {
        let r = raytrace::render_view(&self.room, &self.palette, camera);
        let (width, height) = (r.rgb.width, r.rgb.height);
        let features = match self.oracle {
            NovelOracle::Renders => extractor.extract(&r.rgb)?,
            NovelOracle::Labels => label_features(
                &r.labels,
                (width, height),
                self.simulated.map_size(width, height),
                self.simulated.embeddings(),
            )?,
        };
        Ok(ExtractedView {
            rgb: r.rgb,
            depth: r.depth,
            features,
        })
    }
}

/// A `map_w x map_h` feature map whose pixels are the embeddings of the
/// labels (`width x height`, row-major) under the cells' centres.
///
/// # Shapes
/// labels `[height * width]` -> `[map_h, map_w, D]`.
pub fn label_features(
    labels: &[u16],
    (width, height): (u32, u32),
    (map_w, map_h): (u32, u32),
    embeddings: &TextEmbeddings,
) -> Result<FeatureMap, OpsError> {
    let dim = embeddings.dim;
    let mut data = Vec::with_capacity((map_w * map_h) as usize * dim);
    for y in 0..map_h {
        for x in 0..map_w {
            let (px, py) = nearest_pixel(x as f64, y as f64, (map_w, map_h), (width, height));
            let label = labels[(py * width + px) as usize] as usize;
            if label >= embeddings.len() {
                return Err(OpsError::Invalid(format!(
                    "label {label} at pixel ({px}, {py}) has no class embedding ({} classes)",
                    embeddings.len()
                )));
            }
            data.extend(embeddings.row(label).iter().map(|&v| f16::from_f32(v)));
        }
    }
    Ok(FeatureMap {
        width: map_w,
        height: map_h,
        dim,
        data,
    })
}
