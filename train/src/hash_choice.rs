//! Whether the field's MLP takes a multiresolution hash encoding beside
//! its IPE (`--hash-grid`, see `model::hashgrid`), and why. `train`
//! prints the choice and why.

use datasets::Scene;

use crate::appearance::is_colmap;
use model::{HashGridConfig, OpenNerfConfig};

/// Whether the MLP takes a hash encoding (`--hash-grid`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HashGridArg {
    /// `on` for a COLMAP capture with the unbounded field (measured to
    /// lift its held-out views at equal seconds: docs/measurements/unbounded.md), else
    /// `off`, unless the `--config` file sets `model.hash`.
    #[default]
    Auto,
    /// The IPE alone.
    Off,
    /// The IPE and the hash encoding of each sample's mean.
    On,
}

/// Whether a run's MLP takes the hash encoding, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HashChoice {
    /// The hash encoding is on.
    pub on: bool,
    /// Why, in words.
    pub reason: String,
}

impl HashChoice {
    /// The one-line message `train` prints.
    pub fn message(&self, model: &OpenNerfConfig) -> String {
        match (&model.hash, self.on) {
            (Some(h), true) => format!(
                "hash grid: {} levels of 2^{} rows x {} features, {} to {} cells across, \
                 beside the IPE ({})",
                h.levels,
                h.log2_table,
                h.features,
                h.base_resolution,
                h.max_resolution,
                self.reason
            ),
            _ => format!("hash grid: none, the IPE alone ({})", self.reason),
        }
    }
}

/// Chooses from the flag (`None`: not given, `auto`) and the configuration
/// (`model` as `--config`, the presets and the field choice left it).
pub fn choose(arg: Option<HashGridArg>, model: &OpenNerfConfig, scene: &Scene) -> HashChoice {
    let (on, reason) = match arg.unwrap_or_default() {
        HashGridArg::Auto if model.hash.is_some() => {
            (true, "auto: the configuration's model.hash".to_string())
        }
        HashGridArg::Auto if model.unbounded.is_some() && is_colmap(scene) => (
            true,
            "auto: a colmap capture with the unbounded field, where it was measured to lift the \
             held-out views at equal seconds (docs/measurements/unbounded.md)"
                .to_string(),
        ),
        HashGridArg::Auto => (false, "auto: not measured to help this capture".to_string()),
        HashGridArg::Off => (false, "--hash-grid off".into()),
        HashGridArg::On => (true, "--hash-grid on".into()),
    };
    HashChoice { on, reason }
}

/// Sets `model.hash` as `choice` says: the configuration's own settings
/// where it has them, else the defaults.
pub fn apply(choice: &HashChoice, model: &mut OpenNerfConfig) {
    model.hash = choice
        .on
        .then(|| model.hash.clone().unwrap_or_else(HashGridConfig::new));
}

/// Checks `model.hash`'s ranges; the message names the offending key.
pub fn validate(model: &OpenNerfConfig) -> Result<(), String> {
    let Some(h) = &model.hash else {
        return Ok(());
    };
    let checks = [
        ("levels", h.levels >= 1 && h.levels <= 32, "in 1..=32"),
        ("features", h.features >= 1 && h.features <= 16, "in 1..=16"),
        ("log2_table", (4..=24).contains(&h.log2_table), "in 4..=24"),
        (
            "base_resolution",
            h.base_resolution >= 1 && h.base_resolution <= 1 << 20,
            "in 1..=1048576",
        ),
        (
            "max_resolution",
            h.max_resolution >= h.base_resolution && h.max_resolution <= 1 << 20,
            "at least base_resolution and at most 1048576",
        ),
    ];
    for (key, ok, range) in checks {
        if !ok {
            let value = serde_json::to_value(h)
                .map(|v| v[key].to_string())
                .unwrap_or_default();
            return Err(format!("model.hash.{key} must be {range}, got {value}"));
        }
    }
    if !(h.half_extent.is_finite() && h.half_extent > 0.0) {
        return Err(format!(
            "model.hash.half_extent must be positive and finite, got {}",
            h.half_extent
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::FeatureHeadConfig;

    fn synthetic() -> Scene {
        use datasets::synthetic::{SceneSize, generate};
        generate(0, SceneSize::Ci).expect("the tiny scene")
    }

    #[test]
    fn auto_follows_the_configuration_and_the_flags_win() {
        let scene = synthetic();
        let mut model = OpenNerfConfig::new(FeatureHeadConfig::new(4));
        let off = choose(None, &model, &scene);
        assert!(!off.on, "{}", off.reason);
        model.hash = Some(HashGridConfig::new().with_levels(4));
        let kept = choose(None, &model, &scene);
        assert!(kept.on);
        apply(&kept, &mut model);
        let h = model.hash.clone().expect("hash on");
        assert_eq!(h.levels, 4, "the configuration's settings are kept");
        let refused = choose(Some(HashGridArg::Off), &model, &scene);
        apply(&refused, &mut model);
        assert!(model.hash.is_none());
        assert!(choose(Some(HashGridArg::On), &model, &scene).on);
    }

    #[test]
    fn bad_settings_are_refused_naming_the_key() {
        let mut model = OpenNerfConfig::new(FeatureHeadConfig::new(4));
        model.hash = Some(HashGridConfig::new());
        assert_eq!(validate(&model), Ok(()));
        let bad = [
            (HashGridConfig::new().with_levels(0), "model.hash.levels"),
            (
                HashGridConfig::new().with_features(0),
                "model.hash.features",
            ),
            (
                HashGridConfig::new().with_log2_table(30),
                "model.hash.log2_table",
            ),
            (
                HashGridConfig::new().with_base_resolution(0),
                "model.hash.base_resolution",
            ),
            (
                HashGridConfig::new()
                    .with_base_resolution(64)
                    .with_max_resolution(32),
                "model.hash.max_resolution",
            ),
            (
                HashGridConfig::new().with_half_extent(f32::NAN),
                "model.hash.half_extent",
            ),
            (
                HashGridConfig::new().with_half_extent(0.0),
                "model.hash.half_extent",
            ),
        ];
        for (h, key) in bad {
            model.hash = Some(h);
            let err = validate(&model).expect_err(key);
            assert!(err.contains(key), "{err}");
        }
    }
}
