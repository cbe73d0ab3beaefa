//! The occupancy grid's place in a run: read back from a checkpoint's
//! state, and its settings in the run's configuration (read with defaults
//! for the keys older runs lack, checked with the flags that set them).
//! The grid itself, its update and the clipping of rays are the model's
//! (`model::occupancy`, `model::render`).

use std::path::Path;

use model::{OccupancyConfig, OccupancyGrid};

use crate::error::TrainError;

/// Reads a grid saved as hex in a checkpoint's state
/// ([`OccupancyGrid::to_hex`]); `path` names the checkpoint in errors.
pub fn decode(hex: &str, path: &Path) -> Result<OccupancyGrid, TrainError> {
    OccupancyGrid::from_hex(hex)
        .map_err(|e| TrainError::checkpoint(path, format!("occupancy grid: {e}")))
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

    #[test]
    fn a_checkpoint_grid_round_trips_through_hex() {
        let config = OccupancyConfig::new()
            .with_resolution(4)
            .with_early_samples(1)
            .with_early_updates(0);
        let mut grid = OccupancyGrid::new(&config);
        let mut d = vec![0.0f32; 64];
        d[63] = 10.0; // the top corner only
        grid.update(&d);
        let path = Path::new("ckpt");
        assert_eq!(decode(&grid.to_hex(), path).unwrap(), grid);
        assert!(decode("abc", path).is_err() && decode("zz", path).is_err());
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
