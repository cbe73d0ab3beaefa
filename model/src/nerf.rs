//! The OpenNeRF field: the Mip-NeRF MLP (shared by the coarse and the fine
//! level, or fed by the proposal sampler) or the fast field in its place
//! (see [`Radiance`]), the open-set feature head, the
//! scene's extent (a box, or unbounded with Mip-NeRF 360's contraction, see
//! [`Extent`]) and the occupancy grid it carries, with point queries. Rendering is
//! [`OpenNerf::render`] (see [`crate::render`]).

use std::sync::Arc;

use burn::config::Config;
use burn::module::Module;
use burn::tensor::{Device, Tensor};

use crate::appearance::{AppearanceCodes, AppearanceCodesConfig};
use crate::exposure::{Exposure, ExposureConfig};
use crate::extent::Extent;
use crate::fast_field::{FastField, FastFieldConfig};
use crate::field::{FeatureHead, FeatureHeadConfig, FieldOutputs, MipMlp, MipMlpConfig};
use crate::hashgrid::{HashGrid, HashGridConfig};
use crate::mip::{integrated_pos_enc, pos_enc};
use crate::occupancy::OccupancyGrid;
use crate::pose::{PoseCorrection, PoseCorrectionConfig};
use crate::proposal::{ProposalConfig, ProposalMlp};
pub use crate::rays::Rays;
use crate::sh::sh_encoding;
use crate::unbounded::UnboundedConfig;

/// Configuration of [`OpenNerf`].
#[derive(Config, Debug)]
pub struct OpenNerfConfig {
    /// The open-set head (its `out_dim` is `D` or the number of PCA coefficients).
    pub head: FeatureHeadConfig,
    /// The shared Mip-NeRF MLP (unused when `fast` is set).
    #[config(default = "MipMlpConfig::new()")]
    pub mlp: MipMlpConfig,
    /// The fast field (a hash encoding and small MLPs, see
    /// [`crate::fast_field`]) in place of the Mip-NeRF MLP; `None`: the
    /// Mip-NeRF MLP.
    pub fast: Option<FastFieldConfig>,
    /// Samples per ray at each level (values below 1 are treated as 1).
    #[config(default = 64)]
    pub num_samples: usize,
    /// Added to the blurred coarse weights before resampling.
    #[config(default = 0.01)]
    pub resample_padding: f32,
    /// Evaluate the feature head only on the `k` samples of largest (fine)
    /// weight per ray. Exact when the remaining weights are ~0, which holds
    /// once the density has converged to surfaces; early in training it
    /// drops the contribution of the other samples. `None` evaluates all.
    pub head_top_k: Option<usize>,
    /// Also composite features at the coarse level.
    #[config(default = false)]
    pub coarse_features: bool,
    /// An unbounded scene (Mip-NeRF 360's contraction, rays to effectively
    /// infinite distance); `None`: the scene box. The field's [`Extent`]
    /// is built from it.
    pub unbounded: Option<UnboundedConfig>,
    /// The proposal sampler (small density MLPs decide where the MLP
    /// samples, `num_samples` per ray); `None`: the coarse and the fine
    /// level of the MLP.
    pub proposal: Option<ProposalConfig>,
    /// A learned exposure per training photograph, applied to the training
    /// loss only (see [`crate::exposure`]); `None`: none.
    pub exposure: Option<ExposureConfig>,
    /// A learned pose correction per training photograph, applied to its
    /// rays in training only (see [`crate::pose`]); `None`: the poses as
    /// given.
    pub pose: Option<PoseCorrectionConfig>,
    /// A learned appearance code per training photograph, given to the
    /// colour branch (see [`crate::appearance`]); `None`: none.
    pub appearance: Option<AppearanceCodesConfig>,
    /// A multiresolution hash encoding whose features the Mip-NeRF MLP
    /// takes beside the IPE (see [`crate::hashgrid`]); `None`: the IPE
    /// alone. The fast field has its own (`fast.grid`).
    pub hash: Option<HashGridConfig>,
}

impl OpenNerfConfig {
    /// Builds the model on `device`.
    pub fn init(&self, device: &Device) -> OpenNerf {
        let appearance_dim = self.appearance.as_ref().map_or(0, |a| a.dim.max(1));
        let (mlp, fast, head_width) = match &self.fast {
            Some(fast) => {
                let field = fast.init(appearance_dim, device);
                let width = field.head_width();
                (None, Some(field), width)
            }
            None => {
                let extra = self.hash.as_ref().map_or(0, HashGridConfig::output_dim);
                let mlp = self.mlp.init_with_inputs(appearance_dim, extra, device);
                (Some(mlp), None, self.mlp.width.max(1))
            }
        };
        let hash = match self.fast {
            Some(_) => None,
            None => self.hash.as_ref().map(|h| h.init(device)),
        };
        OpenNerf {
            mlp,
            fast,
            head: self.head.init(head_width, device),
            num_samples: self.num_samples.max(1),
            resample_padding: self.resample_padding as f64,
            head_top_k: self.head_top_k.unwrap_or(0),
            coarse_features: self.coarse_features,
            proposal: self.proposal.as_ref().map(|p| p.init(device)),
            proposal_config: self.proposal.clone(),
            extent: Extent::from_config(self.unbounded.as_ref()),
            exposure: self.exposure.as_ref().map(|e| e.init(device)),
            pose: self.pose.as_ref().map(|p| p.init(device)),
            appearance: self.appearance.as_ref().map(|a| a.init(device)),
            hash,
            occupancy: None,
        }
    }
}

/// The OpenNeRF field: the shared MLP (or the fast field) and the
/// open-set head.
#[derive(Module, Debug)]
pub struct OpenNerf {
    /// Shared coarse/fine Mip-NeRF MLP; `None` when the fast field is the
    /// field (exactly one of `mlp` and `fast` is set).
    pub mlp: Option<MipMlp>,
    /// The fast field, in place of the Mip-NeRF MLP.
    pub fast: Option<FastField>,
    /// Open-set feature head.
    pub head: FeatureHead,
    /// Samples per ray at each level.
    pub num_samples: usize,
    /// Resample padding.
    pub resample_padding: f64,
    /// Top-k samples for the head; 0 means all.
    pub head_top_k: usize,
    /// Whether coarse features are composited.
    pub coarse_features: bool,
    /// The proposal MLP, with the proposal sampler.
    pub proposal: Option<ProposalMlp>,
    /// The proposal sampler's rounds (`None`: coarse and fine level).
    #[module(skip)]
    pub proposal_config: Option<ProposalConfig>,
    /// The scene box, or an unbounded scene with its contraction.
    #[module(skip)]
    pub extent: Extent,
    /// The training photographs' exposure (training loss only).
    pub exposure: Option<Exposure>,
    /// The training photographs' pose corrections (training rays only).
    pub pose: Option<PoseCorrection>,
    /// The training photographs' appearance codes (training rays only).
    pub appearance: Option<AppearanceCodes>,
    /// The hash encoding the MLP takes beside the IPE.
    pub hash: Option<HashGrid>,
    /// Occupancy grid of the field's density, when empty-space skipping is
    /// on: [`OpenNerf::render`] clips its rays with it unless the request
    /// says otherwise (see [`crate::GridUse`]). Not part of the weights.
    #[module(skip)]
    pub occupancy: Option<Arc<OccupancyGrid>>,
}

impl OpenNerf {
    /// The field with `grid` as its occupancy grid (`None`: no skipping).
    pub fn with_occupancy(mut self, grid: Option<OccupancyGrid>) -> Self {
        self.occupancy = grid.map(Arc::new);
        self
    }

    /// The occupancy grid, when empty-space skipping is on.
    pub fn occupancy(&self) -> Option<&OccupancyGrid> {
        self.occupancy.as_deref()
    }

    /// The grid rendering samples with: the model's grid where the extent
    /// takes one ([`Extent::sampler_grid`]).
    pub fn sampler_grid(&self) -> Option<&OccupancyGrid> {
        self.extent.sampler_grid(self.occupancy())
    }

    /// The device the field's weights live on (where rendering uploads its
    /// rays and point queries are evaluated).
    pub fn device(&self) -> Device {
        self.head.output.weight.device()
    }

    /// Features at 3D points (normalised frame), encoding each point as an
    /// isotropic Gaussian of standard deviation `radius`.
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; output: `[n, out_dim]`.
    pub fn query_features(&self, points: Tensor<2>, radius: f32) -> Tensor<2> {
        let (trunk, _) = self.query_trunk(points, radius);
        self.head.forward(self.radiance().head_input(trunk))
    }

    /// Density at 3D points (normalised frame), per unit of normalised length.
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; output: `[n, 1]`.
    pub fn query_density(&self, points: Tensor<2>, radius: f32) -> Tensor<2> {
        self.query_trunk(points, radius).1
    }

    fn query_trunk(&self, points: Tensor<2>, radius: f32) -> (Tensor<2>, Tensor<2>) {
        let g = self.extent.points(points, radius);
        let input = self.encode_gaussians(g.mean, g.cov_diag);
        self.radiance().trunk_density(input)
    }

    /// The field that gives density and colour.
    pub fn radiance(&self) -> Radiance<'_> {
        match (&self.fast, &self.mlp) {
            (Some(fast), _) => Radiance::Fast(fast),
            (None, Some(mlp)) => Radiance::Mip(mlp),
            // `OpenNerfConfig::init` sets exactly one, and loading weights
            // keeps the structure the configuration built.
            (None, None) => unreachable!("a field has the Mip-NeRF MLP or the fast field"),
        }
    }

    /// What the field takes for each Gaussian: for the Mip-NeRF MLP its
    /// IPE, then its mean's hash encoding when the field has one; for the
    /// fast field its mean's hash encoding.
    ///
    /// # Shapes
    /// - `mean`, `cov_diag`: `[m, 3]`; output: `[m, input]`.
    pub fn encode_gaussians(&self, mean: Tensor<2>, cov_diag: Tensor<2>) -> Tensor<2> {
        let mlp = match self.radiance() {
            Radiance::Fast(fast) => return fast.encode(mean, cov_diag),
            Radiance::Mip(mlp) => mlp,
        };
        let ipe = integrated_pos_enc(mean.clone(), cov_diag, mlp.min_deg, mlp.max_deg);
        match &self.hash {
            Some(h) => Tensor::cat(vec![ipe, h.forward(mean.detach())], 1),
            None => ipe,
        }
    }

    /// The proposal sampler's configuration and MLP, when the field has one.
    pub fn proposal_sampler(&self) -> Option<(&ProposalConfig, &ProposalMlp)> {
        self.proposal_config.as_ref().zip(self.proposal.as_ref())
    }

    /// Samples a ray takes over all levels ([`OpenNerf::levels`]) without
    /// early termination: the coarse and the fine level's, or the proposal
    /// rounds' and the MLP's.
    pub fn samples_per_ray(&self) -> usize {
        self.levels().iter().map(|level| level.samples).sum()
    }
}

/// The part of the field that gives density and colour: the Mip-NeRF MLP
/// or the fast field. The renderer and the point queries go through it.
#[derive(Debug, Clone, Copy)]
pub enum Radiance<'m> {
    /// The Mip-NeRF MLP (its input: the IPE, with a hash encoding beside).
    Mip(&'m MipMlp),
    /// The fast field (its input: the hash encoding).
    Fast(&'m FastField),
}

impl Radiance<'_> {
    /// Trunk feature (the open-set head's input) and density from the
    /// encoded samples ([`OpenNerf::encode_gaussians`]).
    ///
    /// # Shapes
    /// - `input`: `[n, input]`; output: (`[n, trunk_width]`, `[n, 1]`).
    pub fn trunk_density(self, input: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        match self {
            Radiance::Mip(mlp) => mlp.trunk_density(input),
            Radiance::Fast(fast) => fast.trunk_density(input),
        }
    }

    /// View-dependent colour of `samples` samples a ray.
    ///
    /// # Shapes
    /// - `trunk`: `[rays * samples, trunk_width]`, ray-major;
    ///   `view_enc`: `[rays, view_dim + appearance_dim]`; output:
    ///   `[rays * samples, 3]`.
    pub fn color(self, trunk: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> Tensor<2> {
        match self {
            Radiance::Mip(mlp) => mlp.color(trunk, view_enc, samples),
            Radiance::Fast(fast) => fast.color(trunk, view_enc, samples),
        }
    }

    /// Density, colour and trunk feature of `samples` samples a ray.
    ///
    /// # Shapes
    /// - `input`: `[rays * samples, input]`; `view_enc`: `[rays, ..]`.
    pub fn forward(self, input: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> FieldOutputs {
        match self {
            Radiance::Mip(mlp) => mlp.forward(input, view_enc, samples),
            Radiance::Fast(fast) => fast.forward(input, view_enc, samples),
        }
    }

    /// The encoding of unit view directions (without the appearance code):
    /// the Mip-NeRF MLP's positional encoding, or the fast field's
    /// spherical harmonics.
    ///
    /// # Shapes
    /// - `viewdirs`: `[n, 3]`; output: `[n, view_dim]`.
    pub fn view_encoding(self, viewdirs: Tensor<2>) -> Tensor<2> {
        match self {
            Radiance::Mip(mlp) => pos_enc(viewdirs, 0, mlp.viewdir_deg, true),
            Radiance::Fast(fast) => sh_encoding(viewdirs, fast.sh_degree),
        }
    }

    /// Length of the appearance code the colour branch takes (0: none).
    pub fn appearance_dim(self) -> usize {
        match self {
            Radiance::Mip(mlp) => mlp.appearance_dim,
            Radiance::Fast(fast) => fast.appearance_dim,
        }
    }

    /// Width of the trunk feature.
    pub fn trunk_width(self) -> usize {
        match self {
            Radiance::Mip(mlp) => mlp.bottleneck.weight.dims()[0],
            Radiance::Fast(fast) => fast.trunk_width(),
        }
    }

    /// Width of the open-set head's input ([`Radiance::head_input`]).
    pub fn head_width(self) -> usize {
        match self {
            Radiance::Mip(_) => self.trunk_width(),
            Radiance::Fast(fast) => fast.head_width(),
        }
    }

    /// The open-set head's input from the trunk feature: the trunk
    /// detached (the paper's head does not shape the field), but for the
    /// fast field's feature grid, which the feature loss trains.
    ///
    /// # Shapes
    /// - `trunk`: `[n, trunk_width]`; output: `[n, head_width]`.
    pub fn head_input(self, trunk: Tensor<2>) -> Tensor<2> {
        match self {
            Radiance::Mip(_) => trunk.detach(),
            Radiance::Fast(fast) => fast.head_input(trunk),
        }
    }
}
