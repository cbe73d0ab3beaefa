//! The OpenNeRF field: one shared Mip-NeRF MLP for both levels, the
//! open-set feature head and the occupancy grid it carries, with point
//! queries. Rendering is [`OpenNerf::render`] (see [`crate::render`]).

use std::sync::Arc;

use burn::config::Config;
use burn::module::Module;
use burn::tensor::{Device, Tensor, TensorData};

use crate::field::{FeatureHead, FeatureHeadConfig, MipMlp, MipMlpConfig};
use crate::geometry::NormalizedRay;
use crate::mip::integrated_pos_enc;
use crate::occupancy::OccupancyGrid;

/// Configuration of [`OpenNerf`].
#[derive(Config, Debug)]
pub struct OpenNerfConfig {
    /// The open-set head (its `out_dim` is `D` or the number of PCA coefficients).
    pub head: FeatureHeadConfig,
    /// The shared Mip-NeRF MLP.
    #[config(default = "MipMlpConfig::new()")]
    pub mlp: MipMlpConfig,
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
}

impl OpenNerfConfig {
    /// Builds the model on `device`.
    pub fn init(&self, device: &Device) -> OpenNerf {
        let mlp = self.mlp.init(device);
        let head = self.head.init(self.mlp.width.max(1), device);
        OpenNerf {
            mlp,
            head,
            num_samples: self.num_samples.max(1),
            resample_padding: self.resample_padding as f64,
            head_top_k: self.head_top_k.unwrap_or(0),
            coarse_features: self.coarse_features,
            occupancy: None,
        }
    }
}

/// The OpenNeRF field: the shared MLP and the open-set head.
#[derive(Module, Debug)]
pub struct OpenNerf {
    /// Shared coarse/fine MLP.
    pub mlp: MipMlp,
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
    /// Occupancy grid of the field's density, when empty-space skipping is
    /// on: [`OpenNerf::render`] clips its rays with it unless the request
    /// says otherwise (see [`crate::GridUse`]). Not part of the weights.
    #[module(skip)]
    pub occupancy: Option<Arc<OccupancyGrid>>,
}

/// A batch of rays in the normalised frame (metric `t`) on the device: what
/// rendering uploads its host rays ([`NormalizedRay`]) into.
#[derive(Debug, Clone)]
pub struct Rays {
    /// Origins, `[n, 3]`.
    pub origins: Tensor<2>,
    /// Unnormalised directions, `[n, 3]`.
    pub directions: Tensor<2>,
    /// Cone radii at `t = 1`, `[n, 1]`.
    pub radii: Tensor<2>,
    /// Near bounds, `[n, 1]`.
    pub near: Tensor<2>,
    /// Far bounds, `[n, 1]`.
    pub far: Tensor<2>,
}

impl Rays {
    /// Uploads normalised rays to `device`.
    pub fn from_normalized(rays: &[NormalizedRay], device: &Device) -> Rays {
        let n = rays.len();
        let vec3 = |f: &dyn Fn(&NormalizedRay) -> [f32; 3]| {
            let v: Vec<f32> = rays.iter().flat_map(f).collect();
            Tensor::from_data(TensorData::new(v, [n, 3]), device)
        };
        let scalar = |f: &dyn Fn(&NormalizedRay) -> f32| {
            let v: Vec<f32> = rays.iter().map(f).collect();
            Tensor::from_data(TensorData::new(v, [n, 1]), device)
        };
        Rays {
            origins: vec3(&|r: &NormalizedRay| r.origin),
            directions: vec3(&|r: &NormalizedRay| r.direction),
            radii: scalar(&|r: &NormalizedRay| r.radius),
            near: scalar(&|r: &NormalizedRay| r.near),
            far: scalar(&|r: &NormalizedRay| r.far.max(r.near)),
        }
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origins.dims()[0]
    }

    /// Whether there are no rays.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
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
        self.head.forward(trunk)
    }

    /// Density at 3D points (normalised frame), per unit of normalised length.
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; output: `[n, 1]`.
    pub fn query_density(&self, points: Tensor<2>, radius: f32) -> Tensor<2> {
        self.query_trunk(points, radius).1
    }

    fn query_trunk(&self, points: Tensor<2>, radius: f32) -> (Tensor<2>, Tensor<2>) {
        let cov = points.zeros_like().add_scalar(radius * radius);
        let ipe = integrated_pos_enc(points, cov, self.mlp.min_deg, self.mlp.max_deg);
        self.mlp.trunk_density(ipe)
    }
}
