//! Empty-space skipping during training: the grid's updates from the
//! field's density, the clipping of each batch to the occupied cells, and
//! the grid's place in checkpoints and the run directory.

use std::path::Path;

use burn::tensor::{Device, Tensor, TensorData};
use datasets::sampler::RayBatch;
use model::{OccupancyConfig, OccupancyGrid, OpenNerf};

use crate::error::TrainError;

/// Points per density query of an update (bounds the peak memory).
const QUERY_CHUNK: usize = 8192;

/// Refreshes `grid` from `model` (an inference model): the density at the
/// grid's jittered points of this update (several per cell during the early
/// updates, one after), drawn from `seed`, is folded in (see
/// [`OccupancyGrid::update`]). Each point is encoded as a Gaussian of a
/// quarter cell (the scale the samples crossing the cell are seen at).
pub fn update_grid(grid: &mut OccupancyGrid, model: &OpenNerf, seed: u64, device: &Device) {
    let points = grid.sample_points(seed);
    let radius = 0.25 * grid.cell_size() as f32;
    let mut density = Vec::with_capacity(points.len());
    for part in points.chunks(QUERY_CHUNK) {
        let flat: Vec<f32> = part.iter().flatten().copied().collect();
        let p = Tensor::<2>::from_data(TensorData::new(flat, [part.len(), 3]), device);
        density.extend(field_ops::render::tensor_to_vec(
            model.query_density(p, radius),
        ));
    }
    grid.update(&density);
}

/// What clipping did to a batch.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClipStats {
    /// Rays drawn.
    pub drawn: usize,
    /// Rays rendered: those that crossed an occupied cell, and during the
    /// grid's warm-up (`keep_dropped_updates`) those that crossed none.
    pub kept: usize,
    /// Sum over drawn rays of the fraction of their length still sampled
    /// (0 for a skipped ray, 1 for one kept whole).
    pub span_sum: f64,
    /// Rays that crossed no occupied cell (rendered whole during the
    /// warm-up, skipped after).
    pub empty: usize,
}

impl ClipStats {
    /// Adds the counts of `other` (another batch).
    pub fn add(&mut self, other: ClipStats) {
        self.drawn += other.drawn;
        self.kept += other.kept;
        self.span_sum += other.span_sum;
        self.empty += other.empty;
    }
}

/// Whether training still renders the rays that cross no occupied cell of
/// `grid`: during its first `keep_dropped_updates` updates, while a region
/// freed by mistake should still get a loss that brings it back.
pub fn keeps_dropped_rays(config: &OccupancyConfig, grid: &OccupancyGrid) -> bool {
    grid.updates() < config.keep_dropped_updates as u64
}

/// `batch` clipped to the occupied cells of `grid`: each ray to its
/// occupied span, and the rays that cross no occupied cell dropped, or kept
/// whole while [`keeps_dropped_rays`]. A batch in which no ray crosses one
/// is returned whole (an empty step teaches nothing, and its rays may show
/// the grid is wrong).
pub fn clip_batch(
    grid: &OccupancyGrid,
    config: &OccupancyConfig,
    batch: RayBatch,
) -> (RayBatch, ClipStats) {
    let clipped = if keeps_dropped_rays(config, grid) {
        grid.clip_keeping(&batch.rays)
    } else {
        grid.clip(&batch.rays)
    };
    let drawn = batch.len();
    let mut stats = ClipStats {
        drawn,
        kept: clipped.kept.len(),
        span_sum: clipped.span_fraction_sum,
        empty: clipped.empty,
    };
    if clipped.kept.is_empty() {
        stats.kept = drawn;
        stats.span_sum = drawn as f64;
        return (batch, stats);
    }
    let keep = &clipped.kept;
    let pick = |v: &Vec<f32>, width: usize| -> Vec<f32> {
        keep.iter()
            .flat_map(|&i| v[i * width..(i + 1) * width].iter().copied())
            .collect()
    };
    let out = RayBatch {
        rays: clipped.rays,
        rgb: keep.iter().map(|&i| batch.rgb[i]).collect(),
        rgb_weight: batch.rgb_weight.as_ref().map(|w| pick(w, 1)),
        depth: batch.depth.as_ref().map(|d| pick(d, 1)),
        depth_weight: batch.depth_weight.as_ref().map(|d| pick(d, 1)),
        features: batch.features.as_ref().map(|f| pick(f, batch.feature_dim)),
        feature_mask: batch.feature_mask.as_ref().map(|m| pick(m, 1)),
        feature_dim: batch.feature_dim,
        pixels: keep.iter().map(|&i| batch.pixels[i]).collect(),
    };
    (out, stats)
}

/// The grid a run starts with: a complete one when skipping is on.
pub fn initial_grid(config: &OccupancyConfig) -> Option<OccupancyGrid> {
    config.enabled.then(|| OccupancyGrid::new(config))
}

/// The grid as a hex string (for the checkpoint's JSON state).
pub fn encode(grid: &OccupancyGrid) -> String {
    grid.to_bytes().iter().map(|b| format!("{b:02x}")).collect()
}

/// Reads [`encode`]'s output; `path` names the checkpoint in errors.
pub fn decode(hex: &str, path: &Path) -> Result<OccupancyGrid, TrainError> {
    let bad = |m: String| TrainError::checkpoint(path, format!("occupancy grid: {m}"));
    if !hex.len().is_multiple_of(2) {
        return Err(bad("odd number of hex digits".into()));
    }
    // Pairs of bytes, not of characters: a damaged state may hold any text,
    // and slicing a `str` inside a multi-byte character would panic.
    let digit = |c: u8| (c as char).to_digit(16);
    let bytes = hex
        .as_bytes()
        .chunks_exact(2)
        .enumerate()
        .map(|(i, pair)| match (digit(pair[0]), digit(pair[1])) {
            (Some(h), Some(l)) => Ok((h * 16 + l) as u8),
            _ => Err(bad(format!(
                "byte {i}: {:?} is not two hex digits",
                String::from_utf8_lossy(pair)
            ))),
        })
        .collect::<Result<Vec<u8>, _>>()?;
    OccupancyGrid::from_bytes(&bytes).map_err(bad)
}

/// Reads the grid settings of a run's configuration, taking the default of
/// every key it leaves out (Burn's `Config` derive requires them all, and
/// configurations written before a setting existed lack it).
pub fn deserialize_config<'de, D>(d: D) -> Result<OccupancyConfig, D::Error>
where
    D: serde::Deserializer<'de>,
{
    use serde::Deserialize;
    use serde::de::Error;
    let mut value = serde_json::to_value(OccupancyConfig::default()).map_err(D::Error::custom)?;
    match (serde_json::Value::deserialize(d)?, &mut value) {
        // The settings are flat: the file's keys replace the defaults'.
        (serde_json::Value::Object(given), serde_json::Value::Object(all)) => all.extend(given),
        (other, _) => value = other,
    }
    serde_json::from_value(value).map_err(D::Error::custom)
}

/// Checks the grid settings.
pub fn validate(c: &OccupancyConfig) -> Result<(), String> {
    if !(2..=256).contains(&c.resolution) {
        return Err(format!(
            "occupancy.resolution {}: must be in 2..=256 cells per axis",
            c.resolution
        ));
    }
    if c.update_every == 0 {
        return Err("occupancy.update_every 0: give a period of at least 1 iteration".into());
    }
    if !(c.decay.is_finite() && c.decay > 0.0 && c.decay <= 1.0) {
        return Err(format!("occupancy.decay {}: must be in (0, 1]", c.decay));
    }
    if !(c.min_opacity.is_finite() && c.min_opacity > 0.0 && c.min_opacity < 1.0) {
        return Err(format!(
            "occupancy.min_opacity {}: must be in (0, 1)",
            c.min_opacity
        ));
    }
    let most = model::occupancy::MAX_EARLY_SAMPLES;
    if !(1..=most).contains(&c.early_samples) {
        return Err(format!(
            "occupancy.early_samples (--grid-early-samples) {}: must be in 1..={most} points per cell",
            c.early_samples
        ));
    }
    at_most_updates("early_updates", "grid-early-updates", c.early_updates)?;
    let most = model::occupancy::MAX_DILATION;
    if c.dilation > most {
        return Err(format!(
            "occupancy.dilation (--grid-dilation) {}: must be in 0..={most} cells",
            c.dilation
        ));
    }
    at_most_updates(
        "keep_dropped_updates",
        "grid-keep-dropped",
        c.keep_dropped_updates,
    )?;
    Ok(())
}

/// Most updates a warm-up setting may span.
const MAX_WARMUP_UPDATES: usize = 1 << 20;

/// Refuses a warm-up of more than [`MAX_WARMUP_UPDATES`] updates, naming the
/// configuration key and its flag.
fn at_most_updates(key: &str, flag: &str, updates: usize) -> Result<(), String> {
    if updates > MAX_WARMUP_UPDATES {
        return Err(format!(
            "occupancy.{key} (--{flag}) {updates}: must be at most {MAX_WARMUP_UPDATES} updates"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::geometry::NormalizedRay;

    fn batch(n: usize) -> RayBatch {
        let rays = (0..n)
            .map(|i| {
                // Rays along +x at heights from -3 to 3: the low ones pass
                // through the lower half of the cube only.
                let y = -3.0 + 6.0 * i as f32 / (n - 1) as f32;
                NormalizedRay {
                    origin: [-4.0, y, 0.1],
                    direction: [1.0, 0.0, 0.0],
                    radius: 0.01,
                    near: 1.0,
                    far: 7.0,
                }
            })
            .collect();
        RayBatch {
            rays,
            rgb: (0..n).map(|i| [i as f32; 3]).collect(),
            rgb_weight: Some((0..n).map(|i| 0.5 * (i % 3) as f32).collect()),
            depth: Some((0..n).map(|i| i as f32).collect()),
            depth_weight: Some(vec![1.0; n]),
            features: Some((0..2 * n).map(|i| i as f32).collect()),
            feature_mask: Some(vec![1.0; n]),
            feature_dim: 2,
            pixels: (0..n as u32).map(|i| [0, i, 0]).collect(),
        }
    }

    /// The grid's rules before the conservative ones: the first update
    /// decides alone, no dilation, rays over free space skipped at once.
    fn plain() -> OccupancyConfig {
        OccupancyConfig::new()
            .with_resolution(4)
            .with_early_samples(1)
            .with_early_updates(0)
            .with_dilation(0)
            .with_keep_dropped_updates(0)
    }

    #[test]
    fn targets_follow_their_rays_through_the_clip() {
        // Only cells with y < 0 hold density.
        let mut grid = OccupancyGrid::new(&plain());
        let d: Vec<f32> = (0..64)
            .map(|c| if (c / 4) % 4 < 2 { 10.0 } else { 0.0 })
            .collect();
        grid.update(&d);
        let (out, stats) = clip_batch(&grid, &plain(), batch(9));
        assert_eq!(stats.drawn, 9);
        assert_eq!(out.len(), stats.kept);
        assert!(stats.kept > 0 && stats.kept < 9, "kept {}", stats.kept);
        for (j, (r, p)) in out.rays.iter().zip(&out.pixels).enumerate() {
            assert!(r.origin[1] < 0.0);
            assert_eq!(out.rgb[j], [p[1] as f32; 3]);
        }
        let j = 1;
        let i = out.pixels[j][1] as usize;
        assert_eq!(out.depth.as_ref().unwrap()[j], i as f32);
        assert_eq!(out.rgb_weight.as_ref().unwrap()[j], 0.5 * (i % 3) as f32);
        assert_eq!(
            &out.features.as_ref().unwrap()[2 * j..2 * j + 2],
            &[2.0 * i as f32, 2.0 * i as f32 + 1.0]
        );
    }

    #[test]
    fn a_batch_that_misses_every_cell_is_kept_whole_and_hex_round_trips() {
        let mut grid = OccupancyGrid::new(&plain());
        let mut d = vec![0.0f32; 64];
        d[63] = 10.0; // the top corner only
        grid.update(&d);
        let b = batch(3);
        let mut low = b.clone();
        for r in &mut low.rays {
            r.origin[1] = -2.5;
        }
        let (out, stats) = clip_batch(&grid, &plain(), low.clone());
        assert_eq!(out, low);
        assert_eq!(stats.kept, 3);
        let path = Path::new("ckpt");
        assert_eq!(decode(&encode(&grid), path).unwrap(), grid);
        assert!(decode("abc", path).is_err() && decode("zz", path).is_err());
    }

    #[test]
    fn rays_over_free_space_are_rendered_whole_during_the_warm_up_only() {
        // Density in the upper half only (y > 0): the low rays of the batch
        // cross no occupied cell.
        let config = plain().with_keep_dropped_updates(3);
        let mut grid = OccupancyGrid::new(&config);
        let d: Vec<f32> = (0..64)
            .map(|c| if (c / 4) % 4 >= 2 { 10.0 } else { 0.0 })
            .collect();
        let b = batch(9);
        let low = b.rays.iter().filter(|r| r.origin[1] < 0.0).count();
        assert!(low > 0 && low < 9);
        for update in 1..=5 {
            grid.update(&d);
            let (out, stats) = clip_batch(&grid, &config, b.clone());
            assert_eq!((stats.drawn, stats.empty), (9, low), "update {update}");
            assert_eq!(out.len(), stats.kept);
            if update < 3 {
                assert!(keeps_dropped_rays(&config, &grid));
                // Every ray rendered; the empty ones over their whole span
                // and in their place, with their targets.
                assert_eq!(stats.kept, 9, "update {update}");
                assert_eq!(out.pixels, b.pixels);
                for (o, r) in out.rays.iter().zip(&b.rays) {
                    if r.origin[1] < 0.0 {
                        assert_eq!(o, r);
                    }
                }
                assert!(stats.span_sum > low as f64 && stats.span_sum <= 9.0);
            } else {
                assert!(!keeps_dropped_rays(&config, &grid));
                assert_eq!(stats.kept, 9 - low, "update {update}");
                assert!(out.rays.iter().all(|r| r.origin[1] >= 0.0));
                assert!(stats.span_sum <= (9 - low) as f64);
            }
        }
    }

    /// Minimised from a fuzzed checkpoint state: a non-ASCII character
    /// inside the hex of the occupancy grid made decoding panic.
    #[test]
    fn non_hex_text_is_an_error_naming_the_checkpoint() {
        let path = Path::new("ckpt-00000010.onck");
        for hex in ["4\u{e9}b", "\u{e9}\u{e9}", "+f00"] {
            let msg = decode(hex, path).unwrap_err().to_string();
            assert!(msg.contains("ckpt-00000010.onck"), "{msg}");
            assert!(msg.contains("not two hex digits"), "{msg}");
        }
    }

    /// Run configurations written before the conservative grid have no
    /// `early_samples`, `early_updates`, `dilation` or
    /// `keep_dropped_updates`: they load with the defaults.
    #[test]
    fn old_grid_settings_load_with_the_new_defaults() {
        /// The field as `TrainConfig` declares it.
        #[derive(serde::Deserialize)]
        struct Run {
            #[serde(default, deserialize_with = "deserialize_config")]
            occupancy: OccupancyConfig,
        }
        let read = |text: &str| serde_json::from_str::<Run>(text).map(|r| r.occupancy);
        let c = read(
            r#"{"occupancy": {"enabled": true, "resolution": 16, "update_every": 8,
                "warmup": 100, "decay": 0.9, "min_opacity": 0.02}}"#,
        )
        .unwrap();
        let want = OccupancyConfig::new()
            .with_enabled(true)
            .with_resolution(16)
            .with_update_every(8)
            .with_warmup(100)
            .with_decay(0.9)
            .with_min_opacity(0.02);
        assert_eq!(c, want);
        assert_eq!((c.early_samples, c.early_updates), (8, 4));
        assert_eq!((c.dilation, c.keep_dropped_updates), (0, 8));
        // A bad value is still an error, and a run without the section gets
        // the default grid.
        assert!(read(r#"{"occupancy": {"dilation": "wide"}}"#).is_err());
        assert!(read(r#"{"occupancy": 3}"#).is_err());
        assert_eq!(read("{}").unwrap(), OccupancyConfig::default());
        let back = serde_json::to_string(&want).unwrap();
        assert_eq!(read(&format!(r#"{{"occupancy": {back}}}"#)).unwrap(), want);
    }

    #[test]
    fn bad_settings_are_named() {
        let ok = OccupancyConfig::new();
        assert!(validate(&ok).is_ok());
        for (bad, word) in [
            (ok.clone().with_resolution(1), "resolution"),
            (ok.clone().with_resolution(1000), "resolution"),
            (ok.clone().with_update_every(0), "update_every"),
            (ok.clone().with_decay(f32::NAN), "decay"),
            (ok.clone().with_decay(0.0), "decay"),
            (ok.clone().with_min_opacity(1.0), "min_opacity"),
            (ok.clone().with_min_opacity(-0.1), "min_opacity"),
            (ok.clone().with_early_samples(0), "--grid-early-samples"),
            (ok.clone().with_early_samples(33), "early_samples"),
            (
                ok.clone().with_early_updates(usize::MAX),
                "--grid-early-updates",
            ),
            (ok.clone().with_dilation(5), "--grid-dilation"),
            (ok.clone().with_dilation(usize::MAX), "dilation"),
            (
                ok.clone().with_keep_dropped_updates(usize::MAX),
                "--grid-keep-dropped",
            ),
        ] {
            let msg = validate(&bad).unwrap_err();
            assert!(msg.contains(word), "{msg}");
        }
        for fine in [
            ok.clone().with_early_samples(1).with_dilation(0),
            ok.clone().with_early_samples(32).with_dilation(4),
            ok.clone()
                .with_early_updates(0)
                .with_keep_dropped_updates(0),
        ] {
            assert!(validate(&fine).is_ok());
        }
    }
}
