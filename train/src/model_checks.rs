//! Range checks of the field's optional parts in a configuration
//! (`model.unbounded`, `model.proposal`, `model.hash`, `model.fast`); each
//! message names the offending key.

use model::{HashGridConfig, OpenNerfConfig};

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

/// Checks the ranges of the hash grids (`model.hash`, `model.fast.grid`,
/// `model.proposal.hash`) and of the fast field's sizes; the message names
/// the offending key.
pub fn hash(model: &OpenNerfConfig) -> Result<(), String> {
    if let Some(h) = &model.hash {
        grid(h, "model.hash")?;
    }
    if let Some(p) = model.proposal.as_ref().and_then(|p| p.hash.as_ref()) {
        grid(p, "model.proposal.hash")?;
    }
    if let Some(p) = &model.proposal {
        density_shift(p.density_shift, "model.proposal.density_shift")?;
    }
    let Some(fast) = &model.fast else {
        return Ok(());
    };
    grid(&fast.grid, "model.fast.grid")?;
    if let Some(g) = &fast.feature_grid {
        grid(g, "model.fast.feature_grid")?;
    }
    if fast.head_reads_geometry == Some(false) && fast.feature_grid.is_none() {
        return Err(
            "model.fast.head_reads_geometry is false, but the fast field has no \
             model.fast.feature_grid: the open-set head would read nothing (give it a \
             feature grid, or leave the key out)"
                .into(),
        );
    }
    if model.hash.is_some() {
        return Err(
            "model.hash is a hash grid beside the Mip-NeRF MLP's IPE; the fast field \
             (model.fast) has its own, model.fast.grid: leave model.hash out (or --hash-grid off)"
                .into(),
        );
    }
    let sizes = [
        ("density_width", fast.density_width, 1..=4096),
        ("density_layers", fast.density_layers, 0..=16),
        ("geo_features", fast.geo_features, 1..=4096),
        ("color_width", fast.color_width, 1..=4096),
        ("color_layers", fast.color_layers, 1..=16),
        ("sh_degree", fast.sh_degree, 1..=model::sh::MAX_SH_DEGREE),
    ];
    for (key, value, range) in sizes {
        if !range.contains(&value) {
            return Err(format!(
                "model.fast.{key} must be in {}..={}, got {value}",
                range.start(),
                range.end()
            ));
        }
    }
    if let Some(until) = fast.coarse_to_fine
        && !(until.is_finite() && (0.0..=1.0).contains(&until))
    {
        return Err(format!(
            "model.fast.coarse_to_fine is the fraction of training by which every level \
             of the grid is on, in 0..=1 (0: from the start), got {until}"
        ));
    }
    density_shift(fast.density_shift, "model.fast.density_shift")
}

/// A density shift within the exponential's range: beyond +-15 every
/// density the MLP can give is capped or next to nothing.
fn density_shift(shift: Option<f32>, key: &str) -> Result<(), String> {
    match shift {
        Some(s) if !(-15.0..=15.0).contains(&s) => {
            Err(format!("{key} must be in -15..=15, got {s}"))
        }
        _ => Ok(()),
    }
}

/// Checks one hash grid's ranges, its keys under `prefix`.
fn grid(h: &HashGridConfig, prefix: &str) -> Result<(), String> {
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
            return Err(format!("{prefix}.{key} must be {range}, got {value}"));
        }
    }
    if !(h.half_extent.is_finite() && h.half_extent > 0.0) {
        return Err(format!(
            "{prefix}.half_extent must be positive and finite, got {}",
            h.half_extent
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::{FastFieldConfig, FeatureHeadConfig, HashGridConfig, ProposalConfig};

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
        for (h, key) in bad.clone() {
            model.hash = Some(h);
            let err = hash(&model).expect_err(key);
            assert!(err.contains(key), "{err}");
        }
        // The same checks name the fast field's grid and the proposal's.
        model.hash = None;
        for (h, key) in bad.clone() {
            model.fast = Some(FastFieldConfig::new().with_grid(h));
            let key = key.replace("model.hash", "model.fast.grid");
            let err = hash(&model).expect_err(&key);
            assert!(err.contains(&key), "{err}");
        }
        model.fast = None;
        for (h, key) in bad {
            model.proposal = Some(ProposalConfig::new().with_hash(Some(h)));
            let key = key.replace("model.hash", "model.proposal.hash");
            let err = hash(&model).expect_err(&key);
            assert!(err.contains(&key), "{err}");
        }
    }

    #[test]
    fn the_fast_fields_sizes_are_checked_and_it_takes_no_second_grid() {
        let mut model = OpenNerfConfig::new(FeatureHeadConfig::new(4));
        model.fast = Some(FastFieldConfig::new());
        assert_eq!(hash(&model), Ok(()));
        for (fast, key) in [
            (
                FastFieldConfig::new().with_density_width(0),
                "model.fast.density_width",
            ),
            (
                FastFieldConfig::new().with_geo_features(0),
                "model.fast.geo_features",
            ),
            (
                FastFieldConfig::new().with_color_layers(0),
                "model.fast.color_layers",
            ),
            (
                FastFieldConfig::new().with_sh_degree(5),
                "model.fast.sh_degree",
            ),
            (
                FastFieldConfig::new().with_density_shift(Some(-40.0)),
                "model.fast.density_shift",
            ),
            (
                FastFieldConfig::new().with_density_shift(Some(f32::NAN)),
                "model.fast.density_shift",
            ),
        ] {
            model.fast = Some(fast);
            let err = hash(&model).expect_err(key);
            assert!(err.contains(key), "{err}");
        }
        model.fast = Some(FastFieldConfig::new());
        model.proposal = Some(ProposalConfig::new().with_density_shift(Some(16.0)));
        let err = hash(&model).expect_err("proposal shift");
        assert!(err.contains("model.proposal.density_shift"), "{err}");
        model.proposal = None;
        model.hash = Some(HashGridConfig::new());
        let err = hash(&model).expect_err("two grids");
        assert!(err.contains("model.fast.grid"), "{err}");
    }
}
