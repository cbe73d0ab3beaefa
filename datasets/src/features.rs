//! Per-frame feature maps: lazy `.npy` sources (one file per frame, or one
//! stacked `N x H x W x D` array), validation against the frames' images, and
//! optional PCA compression applied while the maps are read, so that never
//! all maps are held at full dimension at once.

mod pca;

use std::path::{Path, PathBuf};

use half::f16;
use half::slice::HalfFloatSliceExt;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub use pca::{AUTO_EXPLAINED_VARIANCE, PcaBasis, PcaSetting, symmetric_eigen};

use crate::error::DatasetError;
use crate::grid::nearest_pixel;
use crate::npy::NpyInfo;

/// Pixels sampled (over all maps) to fit a PCA basis.
const PCA_SAMPLES: usize = 8192;

/// A full-dimensional feature vector with a norm below this carries no
/// target (extractors write zeros where they have no prediction).
pub const ZERO_FEATURE_NORM: f32 = 1e-6;

/// A pixel-aligned feature map of one frame, row-major `[height, width, dim]`,
/// stored as `f16`. Its resolution may be lower than the frame's image.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMap {
    /// Map width.
    pub width: u32,
    /// Map height.
    pub height: u32,
    /// Channels per pixel (D, or k PCA coefficients).
    pub dim: usize,
    /// `height * width * dim` values.
    pub data: Vec<f16>,
}

impl FeatureMap {
    /// Feature vector at map pixel `(x, y)`.
    pub fn pixel(&self, x: u32, y: u32) -> &[f16] {
        let i = (y as usize * self.width as usize + x as usize) * self.dim;
        &self.data[i..i + self.dim]
    }

    /// Feature at image point `(u, v)` of an `image_width x image_height`
    /// image (pixel centres at integers): nearest map pixel after scaling.
    pub fn lookup(&self, u: f64, v: f64, image_width: u32, image_height: u32) -> &[f16] {
        let (x, y) = nearest_pixel(u, v, (image_width, image_height), (self.width, self.height));
        self.pixel(x, y)
    }
}

/// Whether a full-dimensional feature vector is a target: finite and not
/// (numerically) zero.
pub fn is_full_target(v: &[f16]) -> bool {
    let mut n2 = 0f32;
    for x in v {
        let x = x.to_f32();
        if !x.is_finite() {
            return false;
        }
        n2 += x * x;
    }
    n2 >= ZERO_FEATURE_NORM * ZERO_FEATURE_NORM
}

/// [`is_full_target`] of the vector already converted to f32 (the same
/// sums, so the same answer).
fn is_full_target_f32(v: &[f32]) -> bool {
    let mut n2 = 0f32;
    for &x in v {
        if !x.is_finite() {
            return false;
        }
        n2 += x * x;
    }
    n2 >= ZERO_FEATURE_NORM * ZERO_FEATURE_NORM
}

/// Feature maps of a scene, one per frame, possibly PCA-compressed.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureSet {
    /// One map per frame; `dim` is `k` when compressed.
    pub maps: Vec<FeatureMap>,
    /// The basis the maps were compressed with.
    pub pca: Option<PcaBasis>,
    /// Dimension of the original features (D).
    pub full_dim: usize,
}

impl FeatureSet {
    /// Wraps in-memory maps, fitting PCA on a seeded sample of their pixels
    /// and compressing them unless `pca` is off. All maps must share `dim`.
    pub fn from_maps(
        maps: Vec<FeatureMap>,
        pca: PcaSetting,
        seed: u64,
    ) -> Result<Self, DatasetError> {
        let full_dim = maps.first().map_or(0, |m| m.dim);
        if let Some(i) = maps.iter().position(|m| m.dim != full_dim) {
            return Err(DatasetError::invalid(
                "<feature maps>",
                format!("map {i} has dim {} but map 0 has {full_dim}", maps[i].dim),
            ));
        }
        if !pca.is_on() {
            return Ok(Self {
                maps,
                pca: None,
                full_dim,
            });
        }
        let sizes: Vec<usize> = maps.iter().map(|m| (m.width * m.height) as usize).collect();
        let picks = sample_plan(&sizes, seed);
        let mut samples = Vec::new();
        for (m, idx) in maps.iter().zip(&picks) {
            gather_pixels(m, idx, &mut samples);
        }
        let basis = PcaBasis::fit(&samples, full_dim, pca)?;
        let maps = maps.iter().map(|m| compress_map(m, &basis)).collect();
        Ok(Self {
            maps,
            pca: Some(basis),
            full_dim,
        })
    }

    /// Channels per map pixel (k when compressed, else D).
    pub fn dim(&self) -> usize {
        self.pca.as_ref().map_or(self.full_dim, |p| p.k)
    }

    /// Whether a stored map pixel (`dim()` values) is a training target.
    /// Compressed maps mark pixels without a target (a zero feature, which
    /// compresses to `-U m`, not to "nothing") with NaN coefficients;
    /// uncompressed maps are checked in the full space.
    pub fn is_target(&self, v: &[f16]) -> bool {
        if self.pca.is_some() {
            v.iter().all(|x| x.is_finite())
        } else {
            is_full_target(v)
        }
    }

    /// The target of frame `frame` at image point `(u, v)` of its
    /// `width x height` image, `None` where there is none (no map for the
    /// frame, or a pixel without a target).
    pub fn target(&self, frame: usize, u: f64, v: f64, width: u32, height: u32) -> Option<&[f16]> {
        let t = self.maps.get(frame)?.lookup(u, v, width, height);
        self.is_target(t).then_some(t)
    }
}

/// Which pixels of each map feed the PCA fit: about `PCA_SAMPLES` in all,
/// spread evenly over the maps, drawn with a seeded generator.
pub(crate) fn sample_plan(sizes: &[usize], seed: u64) -> Vec<Vec<usize>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5ca1_ab1e);
    let per = PCA_SAMPLES.div_ceil(sizes.len().max(1));
    sizes
        .iter()
        .map(|&n| {
            if n <= per {
                (0..n).collect()
            } else {
                (0..per).map(|_| rng.random_range(0..n)).collect()
            }
        })
        .collect()
}

/// Appends the feature vectors of the map pixels `pixels` to `out` as f32
/// (the PCA fitting sample). Pixels without a target (zero vectors) are left
/// out: they are not part of the feature distribution.
pub(crate) fn gather_pixels(map: &FeatureMap, pixels: &[usize], out: &mut Vec<f32>) {
    let d = map.dim;
    for &p in pixels {
        let v = &map.data[p * d..(p + 1) * d];
        if is_full_target(v) {
            out.extend(v.iter().map(|h| h.to_f32()));
        }
    }
}

/// A map projected onto `pca`'s `k` components (stored as f16 coefficients).
/// Pixels without a target (zero or non-finite vectors) get NaN
/// coefficients, which [`FeatureSet::is_target`] reads as "no target".
///
/// The pixels are projected a block at a time ([`PcaBasis::project`] works
/// on several rows at once), which is what makes compressing hundreds of
/// millions of pixels affordable.
pub fn compress_map(map: &FeatureMap, pca: &PcaBasis) -> FeatureMap {
    /// Pixels converted and projected together.
    const BLOCK: usize = 256;
    let d = map.dim.max(1);
    let mut data = Vec::with_capacity((map.width * map.height) as usize * pca.k);
    let mut rows = Vec::with_capacity(BLOCK * d);
    let mut targets = Vec::with_capacity(BLOCK);
    for block in map.data.chunks(BLOCK * d) {
        rows.clear();
        targets.clear();
        for v in block.chunks_exact(d) {
            // Converted once, checked in f32, kept only if it is a target.
            let start = rows.len();
            rows.resize(start + d, 0.0);
            v.convert_to_f32_slice(&mut rows[start..]);
            let target = is_full_target_f32(&rows[start..]);
            if !target {
                rows.truncate(start);
            }
            targets.push(target);
        }
        let coeffs = pca.project(&rows);
        let mut next = coeffs.chunks_exact(pca.k.max(1));
        for &target in &targets {
            let row = if target { next.next() } else { None };
            match row {
                Some(c) => data.extend(c.iter().map(|&x| f16::from_f32(x))),
                None => data.extend(std::iter::repeat_n(f16::NAN, pca.k)),
            }
        }
    }
    FeatureMap {
        width: map.width,
        height: map.height,
        dim: pca.k,
        data,
    }
}

/// Where a scene's feature maps are stored on disk.
#[derive(Debug, Clone, PartialEq)]
pub enum FeatureSource {
    /// One `H x W x D` `.npy` per frame, in frame order.
    PerFrame(Vec<PathBuf>),
    /// One `N x H x W x D` `.npy` holding all frames.
    Stacked(PathBuf),
}

impl FeatureSource {
    /// Finds the maps for `frame_names` at `path`: a file is a stacked array;
    /// a directory holds `<frame name>.npy` per frame or, failing that,
    /// exactly one `.npy` per frame (taken in sorted order).
    pub fn discover(path: &Path, frame_names: &[String]) -> Result<Self, DatasetError> {
        if path.is_file() {
            return Ok(Self::Stacked(path.to_path_buf()));
        }
        if !path.is_dir() {
            return Err(DatasetError::invalid(path, "feature path does not exist"));
        }
        let named: Vec<PathBuf> = frame_names
            .iter()
            .map(|n| path.join(format!("{n}.npy")))
            .collect();
        if named.iter().all(|p| p.is_file()) {
            return Ok(Self::PerFrame(named));
        }
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|e| DatasetError::io(path, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "npy"))
            .collect();
        files.sort();
        if files.len() != frame_names.len() {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "{} feature maps (.npy files) but {} frames",
                    files.len(),
                    frame_names.len()
                ),
            ));
        }
        Ok(Self::PerFrame(files))
    }
}

/// One map's location: the file, its element offset, and `(h, w, d)`.
struct MapSlot {
    info: NpyInfo,
    offset: usize,
    h: usize,
    w: usize,
    d: usize,
}

impl MapSlot {
    fn read(&self) -> Result<FeatureMap, DatasetError> {
        let data = self
            .info
            .read_f16_range(self.offset, self.h * self.w * self.d)?;
        if data.iter().any(|v| !v.is_finite()) {
            return Err(DatasetError::invalid(
                &self.info.path,
                "feature map contains NaN or infinite values",
            ));
        }
        Ok(FeatureMap {
            width: self.w as u32,
            height: self.h as u32,
            dim: self.d,
            data,
        })
    }
}

/// Validates headers against `image_sizes` (`(width, height)` per frame):
/// counts agree, dims agree, aspect ratios match within a pixel.
fn plan(source: &FeatureSource, image_sizes: &[(u32, u32)]) -> Result<Vec<MapSlot>, DatasetError> {
    let mut slots = Vec::new();
    match source {
        FeatureSource::Stacked(path) => {
            let info = NpyInfo::open(path)?;
            info.expect_rank(4, "frames x height x width x dim")?;
            let [n, h, w, d] = [info.shape[0], info.shape[1], info.shape[2], info.shape[3]];
            if n != image_sizes.len() {
                return Err(DatasetError::invalid(
                    path,
                    format!("{n} feature maps but {} frames", image_sizes.len()),
                ));
            }
            for i in 0..n {
                slots.push(MapSlot {
                    info: info.clone(),
                    offset: i * h * w * d,
                    h,
                    w,
                    d,
                });
            }
        }
        FeatureSource::PerFrame(paths) => {
            if paths.len() != image_sizes.len() {
                return Err(DatasetError::invalid(
                    paths
                        .first()
                        .map_or(Path::new("<features>"), |p| p.as_path()),
                    format!(
                        "{} feature maps but {} frames",
                        paths.len(),
                        image_sizes.len()
                    ),
                ));
            }
            for p in paths {
                let info = NpyInfo::open(p)?;
                info.expect_rank(3, "height x width x dim")?;
                let [h, w, d] = [info.shape[0], info.shape[1], info.shape[2]];
                slots.push(MapSlot {
                    info,
                    offset: 0,
                    h,
                    w,
                    d,
                });
            }
        }
    }
    for (s, &(iw, ih)) in slots.iter().zip(image_sizes) {
        let path = &s.info.path;
        if s.h == 0 || s.w == 0 || s.d == 0 {
            return Err(DatasetError::invalid(path, "feature map is empty"));
        }
        if s.d != slots[0].d {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "feature dim {} differs from the first map's {}",
                    s.d, slots[0].d
                ),
            ));
        }
        // The map height implied by the image's aspect ratio at the map's width.
        let expect_h = s.w as f64 * ih as f64 / iw as f64;
        if (expect_h - s.h as f64).abs() > 1.0 {
            return Err(DatasetError::invalid(
                path,
                format!(
                    "feature map aspect ratio ({}x{}) does not match its image ({iw}x{ih})",
                    s.w, s.h
                ),
            ));
        }
    }
    Ok(slots)
}

/// The feature maps at `path` (a stacked `.npy` or a directory of per-frame
/// `.npy`, see [`FeatureSource::discover`]) for `frames`, compressed with
/// `basis` when given (a run's stored basis), else as `pca` asks (fitted
/// on a sample drawn with `seed`).
pub fn load_frame_features(
    path: &Path,
    frames: &[crate::Frame],
    pca: PcaSetting,
    basis: Option<&PcaBasis>,
    seed: u64,
) -> Result<FeatureSet, DatasetError> {
    let names: Vec<String> = frames.iter().map(|f| f.name.clone()).collect();
    let source = FeatureSource::discover(path, &names)?;
    let sizes: Vec<(u32, u32)> = frames.iter().map(|f| (f.rgb.width, f.rgb.height)).collect();
    match basis {
        Some(basis) => load_features_with_basis(&source, &sizes, basis),
        None => load_features(&source, &sizes, pca, seed),
    }
}

/// Loads the maps of `source` for frames of `image_sizes` (`(width, height)`),
/// one map at a time. Unless `pca` is off, a first pass samples pixels to
/// fit the basis and a second pass compresses each map as it is read.
pub fn load_features(
    source: &FeatureSource,
    image_sizes: &[(u32, u32)],
    pca: PcaSetting,
    seed: u64,
) -> Result<FeatureSet, DatasetError> {
    let slots = plan(source, image_sizes)?;
    let full_dim = slots.first().map_or(0, |s| s.d);
    if !pca.is_on() {
        let maps = slots.iter().map(MapSlot::read).collect::<Result<_, _>>()?;
        return Ok(FeatureSet {
            maps,
            pca: None,
            full_dim,
        });
    }
    let sizes: Vec<usize> = slots.iter().map(|s| s.h * s.w).collect();
    let picks = sample_plan(&sizes, seed);
    let mut samples = Vec::new();
    for (s, idx) in slots.iter().zip(&picks) {
        gather_pixels(&s.read()?, idx, &mut samples);
    }
    let basis = PcaBasis::fit(&samples, full_dim, pca)?;
    let maps = slots
        .iter()
        .map(|s| s.read().map(|m| compress_map(&m, &basis)))
        .collect::<Result<_, _>>()?;
    Ok(FeatureSet {
        maps,
        pca: Some(basis),
        full_dim,
    })
}

/// Loads the maps of `source` and compresses each, as it is read, with a
/// given `basis` (the one stored with a run), so that a reloaded or extended
/// scene has targets in exactly the space its field was trained in.
pub fn load_features_with_basis(
    source: &FeatureSource,
    image_sizes: &[(u32, u32)],
    basis: &PcaBasis,
) -> Result<FeatureSet, DatasetError> {
    let slots = plan(source, image_sizes)?;
    let full_dim = slots.first().map_or(0, |s| s.d);
    if let Some(s) = slots.first()
        && basis.dim != full_dim
    {
        return Err(DatasetError::invalid(
            &s.info.path,
            format!(
                "feature maps have dimension {full_dim} but the stored PCA basis expects {}",
                basis.dim
            ),
        ));
    }
    let maps = slots
        .iter()
        .map(|s| s.read().map(|m| compress_map(&m, basis)))
        .collect::<Result<_, _>>()?;
    Ok(FeatureSet {
        maps,
        pca: Some(basis.clone()),
        full_dim,
    })
}
