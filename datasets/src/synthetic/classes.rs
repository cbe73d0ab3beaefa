//! The classes of the synthetic room: Replica names, their ScanNet200
//! counterparts (for the real CLIP text embeddings), size groups, base
//! colours and surface patterns, and the class text embeddings.

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::DatasetError;
use crate::numeric::normalized;
use crate::text::TextEmbeddings;

/// How large a class's objects are in the room; the evaluation reports
/// extractor accuracy per group.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SizeGroup {
    /// Room surfaces and furniture (walls, sofa, bed, ...).
    Large,
    /// Hand-to-arm sized objects (pillow, lamp, picture, ...).
    Medium,
    /// Objects a few centimetres across (switch, wall plug, book, ...).
    Tiny,
}

impl std::fmt::Display for SizeGroup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SizeGroup::Large => "large",
            SizeGroup::Medium => "medium",
            SizeGroup::Tiny => "tiny",
        })
    }
}

/// Procedural surface pattern of a class (evaluated on world coordinates, so
/// it is consistent across views).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Base colour with mild value noise (paint, plaster, fabric).
    Noise,
    /// Wooden planks / grain with per-plank tint.
    Wood,
    /// Horizontal slats.
    Slats,
    /// Woven checker with a border (rugs).
    Checker,
    /// Smooth colourful gradients (paintings, prints).
    Painting,
    /// Nearly uniform dark or glassy surface with a soft gradient.
    Glass,
}

/// Static description of one class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassInfo {
    /// Replica class name (what the scene's labels are called).
    pub name: &'static str,
    /// The ScanNet200 label whose CLIP text embedding stands for it.
    pub scannet: &'static str,
    /// Size group.
    pub size: SizeGroup,
    /// Base albedo (linear-ish RGB in `[0, 1]`) before the per-seed jitter.
    pub color: [f64; 3],
    /// Surface pattern.
    pub pattern: Pattern,
}

const fn class(
    name: &'static str,
    scannet: &'static str,
    size: SizeGroup,
    color: [f64; 3],
    pattern: Pattern,
) -> ClassInfo {
    ClassInfo {
        name,
        scannet,
        size,
        color,
        pattern,
    }
}

use Pattern::*;
use SizeGroup::*;

/// The scene's classes, in label order. Colours are chosen so that some
/// classes look alike (wall / ceiling / blinds / switch / wall-plug; floor /
/// table / chair / nightstand / door; sofa / pillow; tv-screen / clock;
/// indoor-plant / bottle; rug / book), as real classes do to a VLM.
pub const CLASSES: [ClassInfo; 26] = [
    class("wall", "wall", Large, [0.82, 0.80, 0.74], Noise),
    class("floor", "floor", Large, [0.56, 0.39, 0.25], Wood),
    class("ceiling", "ceiling", Large, [0.88, 0.87, 0.84], Noise),
    class("rug", "mat", Large, [0.58, 0.20, 0.17], Checker),
    class("window", "window", Medium, [0.62, 0.78, 0.92], Glass),
    class("blinds", "blinds", Medium, [0.86, 0.84, 0.76], Slats),
    class("door", "door", Large, [0.62, 0.46, 0.32], Wood),
    class("table", "table", Large, [0.48, 0.32, 0.19], Wood),
    class("sofa", "couch", Large, [0.28, 0.36, 0.56], Noise),
    class("chair", "chair", Large, [0.42, 0.27, 0.17], Wood),
    class("cabinet", "cabinet", Large, [0.70, 0.67, 0.60], Noise),
    class("tv-screen", "tv", Medium, [0.07, 0.07, 0.09], Glass),
    class("pillow", "pillow", Medium, [0.36, 0.44, 0.64], Noise),
    class("lamp", "lamp", Medium, [0.95, 0.88, 0.62], Noise),
    class("bed", "bed", Large, [0.78, 0.76, 0.84], Noise),
    class("nightstand", "nightstand", Medium, [0.46, 0.31, 0.20], Wood),
    class("shelf", "shelf", Medium, [0.64, 0.52, 0.38], Wood),
    class("picture", "picture", Medium, [0.62, 0.46, 0.36], Painting),
    class("indoor-plant", "plant", Medium, [0.20, 0.48, 0.22], Noise),
    class("vent", "vent", Tiny, [0.74, 0.74, 0.74], Slats),
    class("book", "book", Tiny, [0.64, 0.16, 0.22], Noise),
    class("clock", "clock", Tiny, [0.14, 0.14, 0.15], Glass),
    class("switch", "light switch", Tiny, [0.93, 0.93, 0.91], Noise),
    class("wall-plug", "power outlet", Tiny, [0.90, 0.90, 0.87], Noise),
    class("bottle", "bottle", Tiny, [0.24, 0.54, 0.34], Glass),
    class("bowl", "bowl", Tiny, [0.86, 0.55, 0.20], Noise),
];

/// Index of the class called `name` in [`CLASSES`].
pub fn class_index(name: &str) -> Option<u16> {
    CLASSES
        .iter()
        .position(|c| c.name == name)
        .map(|i| i as u16)
}

/// Replica class names in label order.
pub fn class_names() -> Vec<String> {
    CLASSES.iter().map(|c| c.name.to_string()).collect()
}

/// Per-class albedos for a scene seed: the base colours with a small seeded
/// jitter (at most 0.03 per channel), so scenes differ but keep their look.
pub fn palette(seed: u64) -> Vec<[f64; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9a1e_77e5);
    CLASSES
        .iter()
        .map(|c| {
            c.color
                .map(|v| (v + rng.random_range(-0.03..0.03)).clamp(0.0, 1.0))
        })
        .collect()
}

/// Root of the shared data: `$OPENNERF_DATA`, else the workspace's
/// `../shared/data`.
pub fn data_dir() -> PathBuf {
    std::env::var_os("OPENNERF_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")))
}

/// Dimension of the built-in fallback embeddings (that of CLIP ViT-B).
pub const FALLBACK_DIM: usize = 512;

/// The scene's class text embeddings: rows of the real CLIP ViT-B text
/// embeddings of the ScanNet200 names (`clip_text/` in the data directory),
/// renamed to the Replica names and L2-normalised; the built-in
/// [`fallback_embeddings`] when that folder is absent.
///
/// # Errors
/// When the folder exists but the files are unreadable or lack a class.
pub fn try_class_embeddings() -> Result<TextEmbeddings, DatasetError> {
    let dir = data_dir().join("clip_text");
    if !dir.is_dir() {
        return Ok(fallback_embeddings());
    }
    let npy = dir.join("scannet200_vitb_512.npy");
    let labels = dir.join("scannet200_labels.txt");
    let all = TextEmbeddings::load(&npy, &labels)?;
    let mut data = Vec::with_capacity(CLASSES.len() * all.dim);
    for c in &CLASSES {
        let i = all.index_of(c.scannet).ok_or_else(|| {
            DatasetError::invalid(&labels, format!("no class named {:?}", c.scannet))
        })?;
        data.extend(normalized(all.row(i)));
    }
    Ok(TextEmbeddings {
        names: class_names(),
        dim: all.dim,
        data,
    })
}

/// [`try_class_embeddings`], falling back to [`fallback_embeddings`] on any
/// error, so the product runs without the shared data.
pub fn class_embeddings() -> TextEmbeddings {
    try_class_embeddings().unwrap_or_else(|_| fallback_embeddings())
}

/// Deterministic stand-in embeddings (512-d unit vectors): a shared
/// component (text embeddings are strongly correlated), one per
/// look-alike group, and a per-class part.
pub fn fallback_embeddings() -> TextEmbeddings {
    let mut rng = ChaCha8Rng::seed_from_u64(0x0e9e_12f0);
    let gauss = |rng: &mut ChaCha8Rng| -> Vec<f32> {
        (0..FALLBACK_DIM)
            .map(|_| {
                // Sum of uniforms: close enough to Gaussian for random directions.
                (0..4).map(|_| rng.random_range(-1.0f32..1.0)).sum::<f32>()
            })
            .collect()
    };
    let common = normalized(&gauss(&mut rng));
    let groups: Vec<Vec<f32>> = (0..6).map(|_| normalized(&gauss(&mut rng))).collect();
    let mut data = Vec::with_capacity(CLASSES.len() * FALLBACK_DIM);
    for c in &CLASSES {
        let own = normalized(&gauss(&mut rng));
        let group = &groups[look_alike_group(c.name)];
        let v: Vec<f32> = (0..FALLBACK_DIM)
            .map(|k| 0.75 * common[k] + 0.35 * group[k] + 0.55 * own[k])
            .collect();
        data.extend(normalized(&v));
    }
    TextEmbeddings {
        names: class_names(),
        dim: FALLBACK_DIM,
        data,
    }
}

/// Which look-alike group a class belongs to in the fallback embeddings.
fn look_alike_group(name: &str) -> usize {
    match name {
        "wall" | "ceiling" | "blinds" | "switch" | "wall-plug" | "vent" => 0,
        "floor" | "table" | "chair" | "nightstand" | "door" | "shelf" | "cabinet" => 1,
        "sofa" | "pillow" | "bed" | "rug" => 2,
        "tv-screen" | "clock" | "picture" | "window" => 3,
        "indoor-plant" | "bottle" | "bowl" | "lamp" => 4,
        _ => 5,
    }
}
