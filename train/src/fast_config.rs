//! The fast field's parts as `train` builds them (`--field-model fast`,
//! its proposal networks, the open-set head's feature grid), their one
//! home: the configuration, the settings line and the bench import them
//! from here through [`crate::config`].

use model::{FastFieldConfig, HashGridConfig, ProposalConfig};

/// The fast field `train` builds unless the `--config` file sizes it:
/// nerfacto's MLPs and levels, with the tables and the finest level of the
/// hash grid the Mip-NeRF field's grid was measured with on the CPU (2^15
/// rows, 512 cells across): on the default run 2^19 rows and 2048 cells
/// took twice the seconds a step. Its density starts at `exp(-1)` per
/// normalised unit: unshifted, a photographed object's field filled the
/// space in front of each camera and never formed the object
/// (docs/measurements/fast-field.md).
pub fn fast_field() -> FastFieldConfig {
    FastFieldConfig::new()
        .with_grid(HashGridConfig::new())
        .with_density_shift(Some(FAST_DENSITY_SHIFT))
}

/// The open-set head's own hash grid where a `--config` file asks the
/// fast field for one (`model.fast.feature_grid`) and gives only some of
/// its keys: 12 levels of 2^15 rows of 2 features, 16 to 512 cells
/// across (the field's grid's span in fewer levels).
pub fn fast_feature_grid() -> HashGridConfig {
    HashGridConfig::new().with_levels(12)
}

/// The shift of the fast field's raw density (and of its proposal
/// networks') that `train` builds.
pub const FAST_DENSITY_SHIFT: f32 = -1.0;

/// The proposal sampler of the fast field unless the `--config` file sets
/// one: nerfacto's small hash-grid density network (5 levels of 2^15 rows
/// up to 128 cells across, one layer of 16, its density shifted as the
/// fast field's), shared by two rounds of 64 and 32 samples (nerfacto's
/// 256 and 96 are for a GPU). Most kinds of capture take fewer rounds'
/// samples: the `train::settings::table` rows.
pub fn fast_proposal() -> ProposalConfig {
    ProposalConfig::new()
        .with_samples(vec![64, 32])
        .with_depth(1)
        .with_width(16)
        .with_hash(Some(
            HashGridConfig::new()
                .with_levels(5)
                .with_max_resolution(128),
        ))
        .with_density_shift(Some(FAST_DENSITY_SHIFT))
}
