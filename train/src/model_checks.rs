//! Range checks of the field's optional parts in a configuration
//! (`model.unbounded`, `model.proposal`, `model.hash`); each message names
//! the offending key.

use model::OpenNerfConfig;

/// Checks the unbounded field's and the proposal sampler's settings; the
/// message names the offending key.
pub fn field(model: &OpenNerfConfig) -> Result<(), String> {
    if let Some(u) = &model.unbounded {
        let positive = |k: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "model.unbounded.{k} must be positive and finite, got {v}"
                ))
            }
        };
        positive("radius", u.radius)?;
        positive("near", u.near)?;
        positive("far", u.far)?;
        if u.far <= u.near {
            return Err(format!(
                "model.unbounded.far ({}) must be larger than model.unbounded.near ({})",
                u.far, u.near
            ));
        }
        // The frustum moments overflow f32 for intervals wider than ~4e9.
        if u.far * u.radius > 1e8 {
            return Err(format!(
                "model.unbounded.far x radius must be at most 1e8 normalised units, got {}",
                u.far * u.radius
            ));
        }
    }
    if let Some(p) = &model.proposal {
        if p.samples.is_empty() || p.samples.contains(&0) {
            return Err(format!(
                "model.proposal.samples must list at least one round of at least 1 sample, got {:?}",
                p.samples
            ));
        }
        if p.width == 0 || p.depth == 0 || p.max_deg <= p.min_deg {
            return Err(format!(
                "model.proposal needs width and depth of at least 1 and max_deg above min_deg, \
                 got width {}, depth {}, degrees {}..{}",
                p.width, p.depth, p.min_deg, p.max_deg
            ));
        }
        for (k, v) in [
            ("dilation_bias", p.dilation_bias),
            ("dilation_multiplier", p.dilation_multiplier),
            ("anneal_slope", p.anneal_slope),
            ("resample_padding", p.resample_padding),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "model.proposal.{k} must be finite and non-negative, got {v}"
                ));
            }
        }
    }
    Ok(())
}

/// Checks `model.hash`'s ranges; the message names the offending key.
pub fn hash(model: &OpenNerfConfig) -> Result<(), String> {
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
    use model::{FeatureHeadConfig, HashGridConfig};

    #[test]
    fn bad_settings_are_refused_naming_the_key() {
        let mut model = OpenNerfConfig::new(FeatureHeadConfig::new(4));
        model.hash = Some(HashGridConfig::new());
        assert_eq!(hash(&model), Ok(()));
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
            let err = hash(&model).expect_err(key);
            assert!(err.contains(key), "{err}");
        }
    }
}
