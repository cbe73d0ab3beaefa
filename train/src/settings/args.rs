//! The command-line values of the settings `train` decides per capture
//! (`--field-model`, `--field`, `--sampler`, `--appearance`, `--pose-refine`, `--hash-grid`,
//! `--sparse-depth`): `auto` (or the flag left out) takes the capture
//! kind's default ([`super::table`]).

/// What gives density and colour (`--field-model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum FieldModelArg {
    /// `mip`, the paper's field, on every kind of capture until the fast
    /// field is measured better there (docs/measurements/fast-field.md); a
    /// `--config` file's `model.fast` wins.
    #[default]
    Auto,
    /// The Mip-NeRF MLP (8 x 256 at the paper's size) on the IPE of each
    /// sample's conical frustum.
    Mip,
    /// Nerfacto's field: a multiresolution hash grid and two small MLPs
    /// (density and geometry feature; colour on a spherical-harmonics view
    /// encoding), about a hundredth of the Mip-NeRF MLP's work a sample;
    /// with `--sampler proposal` its proposal networks are small hash grids
    /// too.
    Fast,
}

/// The field's extent (`--field`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum FieldArg {
    /// The capture kind's: `unbounded` for a photographed object walked
    /// around and an open scene, `box` otherwise (where the unbounded field
    /// was not measured better: docs/reference/capture-defaults.md).
    #[default]
    Auto,
    /// The scene box mapped to `[-pi, pi]^3`; rays end where they leave it.
    Box,
    /// Mip-NeRF 360's contraction: the ball around the scene box kept as it
    /// is, everything beyond it contracted, rays from where they enter the
    /// scene box to effectively infinite distance.
    Unbounded,
}

/// How the MLP's samples are placed (`--sampler`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum SamplerArg {
    /// The field model's: `coarse-fine` for the Mip-NeRF field (at the
    /// default sizes the proposal sampler was both slower and less accurate,
    /// docs/measurements/unbounded.md), `proposal` for the fast field (its
    /// hash-grid proposal networks trained better than its coarse and fine
    /// levels on lego and the bench room in equal seconds,
    /// docs/measurements/fast-field.md).
    #[default]
    Auto,
    /// The coarse and fine level of the one field.
    CoarseFine,
    /// Proposal rounds, then the field's samples where they found density:
    /// for the Mip-NeRF field Mip-NeRF 360's (two rounds of 64 samples of a
    /// small density MLP), for the fast field nerfacto's (two rounds of a
    /// small hash-grid density network, of 32 and 16 samples, or 64 and 32
    /// on a room or an open scene).
    Proposal,
}

/// How the photographs' appearance is modelled (`--appearance`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum AppearanceArg {
    /// The capture kind's: `embedding` for a photographed object walked
    /// around (measured to lift its held-out views), else `none`; a
    /// `--config` file's `model.exposure` or `model.appearance` wins.
    #[default]
    Auto,
    /// Every photograph is taken at the same exposure.
    None,
    /// A gain and an offset per colour channel for each training
    /// photograph, applied to its rays' colours in the training loss only.
    Exposure,
    /// A learned code per training photograph given to the colour branch
    /// (nerfacto's appearance embedding); every render uses the zero code.
    Embedding,
}

/// Whether the training cameras' poses are refined (`--pose-refine`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PoseRefineArg {
    /// `off`, unless the `--config` file asks for `model.pose`: on the
    /// captures measured it did not lift the held-out views
    /// (docs/measurements/unbounded.md).
    #[default]
    Auto,
    /// The poses as the capture gives them.
    Off,
    /// A rotation about its centre and a shift of its centre for each
    /// training photograph, learned with the field.
    On,
}

/// Whether the MLP takes a hash encoding (`--hash-grid`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HashGridArg {
    /// The capture kind's: `on` for a photographed object walked around
    /// (measured to lift its held-out views at equal seconds:
    /// docs/measurements/unbounded.md), else `off`; a `--config` file's
    /// `model.hash` wins.
    #[default]
    Auto,
    /// The IPE alone.
    Off,
    /// The IPE and the hash encoding of each sample's mean.
    On,
}

/// Whether the sparse points are depth targets (`--sparse-depth`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum SparseDepthArg {
    /// `off`: on real captures at 600 s the sparse points' depth lifted
    /// one of the two COLMAP captures measured and lowered the other
    /// (docs/measurements/real-capture-defaults.md).
    #[default]
    Auto,
    /// No depth from the sparse points.
    Off,
    /// The sparse points' depths at the pixels of their features (COLMAP
    /// captures only).
    On,
}
