//! Coarse/fine rendering with one shared MLP and the open-set feature head.

use std::ops::Range;
use std::sync::Arc;

use burn::config::Config;
use burn::module::Module;
use burn::tensor::{Device, Int, Tensor, TensorData};

use crate::composite::{composite, composite_features_mean};
use crate::field::{FeatureHead, FeatureHeadConfig, MipMlp, MipMlpConfig};
use crate::geometry::NormalizedRay;
use crate::mip::{cast_rays, integrated_pos_enc, pos_enc};
use crate::occupancy::OccupancyGrid;
use crate::sampling::{resample_t_vals, stratified_t_vals};

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
    /// on: callers that build rays on the host clip them with it (see
    /// [`OccupancyGrid::clip`]). Not part of the weights.
    #[module(skip)]
    pub occupancy: Option<Arc<OccupancyGrid>>,
}

/// A batch of rays in the normalised frame (metric `t`).
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

    /// Rays `range` (clamped to the batch).
    pub fn slice(&self, range: Range<usize>) -> Rays {
        let end = range.end.min(self.len());
        let start = range.start.min(end);
        let s = |t: &Tensor<2>| t.clone().slice_dim(0, start..end);
        Rays {
            origins: s(&self.origins),
            directions: s(&self.directions),
            radii: s(&self.radii),
            near: s(&self.near),
            far: s(&self.far),
        }
    }
}

/// Outputs of one level.
#[derive(Debug, Clone)]
pub struct LevelOutputs {
    /// Colour, `[n, 3]`.
    pub rgb: Tensor<2>,
    /// Expected metric depth, `[n, 1]`.
    pub depth: Tensor<2>,
    /// Accumulated opacity, `[n, 1]`.
    pub acc: Tensor<2>,
    /// Open-set feature, `[n, out_dim]`, when computed at this level: the
    /// weighted mean of the samples' features (`sum w o / sum w`, detached
    /// weights), i.e. the feature of what the ray hits.
    pub feature: Option<Tensor<2>>,
    /// Compositing weights, `[n, samples]`.
    pub weights: Tensor<2>,
    /// Fence posts, `[n, samples + 1]`.
    pub t_vals: Tensor<2>,
}

impl LevelOutputs {
    fn detach(self) -> Self {
        LevelOutputs {
            rgb: self.rgb.detach(),
            depth: self.depth.detach(),
            acc: self.acc.detach(),
            feature: self.feature.map(|f| f.detach()),
            weights: self.weights.detach(),
            t_vals: self.t_vals.detach(),
        }
    }

    fn cat(levels: Vec<LevelOutputs>) -> LevelOutputs {
        let pick =
            |f: &dyn Fn(&LevelOutputs) -> Tensor<2>| Tensor::cat(levels.iter().map(f).collect(), 0);
        let feature = if levels.iter().all(|l| l.feature.is_some()) {
            let parts: Vec<Tensor<2>> = levels.iter().filter_map(|l| l.feature.clone()).collect();
            Some(Tensor::cat(parts, 0))
        } else {
            None
        };
        LevelOutputs {
            rgb: pick(&|l| l.rgb.clone()),
            depth: pick(&|l| l.depth.clone()),
            acc: pick(&|l| l.acc.clone()),
            feature,
            weights: pick(&|l| l.weights.clone()),
            t_vals: pick(&|l| l.t_vals.clone()),
        }
    }
}

/// Outputs of both levels.
#[derive(Debug, Clone)]
pub struct RenderOutputs {
    /// Coarse level.
    pub coarse: LevelOutputs,
    /// Fine level (the one to display and evaluate).
    pub fine: LevelOutputs,
}

/// How the open-set feature is computed at a level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureMode {
    /// Not at all.
    None,
    /// Head applied per sample, then composited (reference path).
    PerSample,
    /// Hidden activations composited, output layer once per ray (default).
    Composited,
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

    /// Renders `rays` at the coarse and fine level with the shared MLP; the
    /// feature is composited at the fine level (and the coarse one when so
    /// configured), with detached weights.
    pub fn render(
        &self,
        rays: &Rays,
        randomized: bool,
        background: Option<[f32; 3]>,
    ) -> RenderOutputs {
        self.render_with(rays, randomized, background, FeatureMode::Composited)
    }

    /// [`OpenNerf::render`] with an explicit feature path (for checks and benchmarks).
    pub fn render_with(
        &self,
        rays: &Rays,
        randomized: bool,
        background: Option<[f32; 3]>,
        mode: FeatureMode,
    ) -> RenderOutputs {
        let (dir_norm, view_enc) = self.view_encoding(rays);
        let t_coarse = stratified_t_vals(
            rays.near.clone(),
            rays.far.clone(),
            self.num_samples,
            randomized,
        );
        let coarse_mode = if self.coarse_features {
            mode
        } else {
            FeatureMode::None
        };
        let coarse = self.render_level(
            rays,
            t_coarse,
            view_enc.clone(),
            dir_norm.clone(),
            background,
            coarse_mode,
        );
        let t_fine = resample_t_vals(
            coarse.t_vals.clone(),
            coarse.weights.clone(),
            self.resample_padding as f32,
            randomized,
        );
        let fine = self.render_level(rays, t_fine, view_enc, dir_norm, background, mode);
        RenderOutputs { coarse, fine }
    }

    /// Deterministic rendering in chunks of `chunk` rays (for full images);
    /// outputs are detached, so no graph is kept between chunks. `mode`
    /// chooses how (and whether) the feature head is evaluated: scenes
    /// without feature targets pass [`FeatureMode::None`] and skip it.
    pub fn render_inference(
        &self,
        rays: &Rays,
        chunk: usize,
        background: Option<[f32; 3]>,
        mode: FeatureMode,
    ) -> RenderOutputs {
        let chunk = chunk.max(1);
        let n = rays.len();
        let mut coarse = Vec::new();
        let mut fine = Vec::new();
        let mut start = 0;
        while start < n {
            let end = (start + chunk).min(n);
            let out = self.render_with(&rays.slice(start..end), false, background, mode);
            coarse.push(out.coarse.detach());
            fine.push(out.fine.detach());
            start = end;
        }
        if coarse.is_empty() {
            return self.render_with(rays, false, background, mode);
        }
        RenderOutputs {
            coarse: LevelOutputs::cat(coarse),
            fine: LevelOutputs::cat(fine),
        }
    }

    fn render_level(
        &self,
        rays: &Rays,
        t_vals: Tensor<2>,
        view_enc: Tensor<2>,
        dir_norm: Tensor<2>,
        background: Option<[f32; 3]>,
        mode: FeatureMode,
    ) -> LevelOutputs {
        let [n, posts] = t_vals.dims();
        let s = posts - 1;
        let ipe = self.encode_samples(t_vals.clone(), rays);
        let field = self.mlp.forward(ipe, view_enc, s);
        let comp = composite(
            field.density.reshape([n, s]),
            field.rgb.reshape([n, s, 3]),
            t_vals.clone(),
            dir_norm,
            background,
        );
        let feature = match mode {
            FeatureMode::None => None,
            FeatureMode::PerSample => {
                let f = self.head.forward(field.trunk);
                let [_, c] = f.dims();
                Some(composite_features_mean(
                    comp.weights.clone(),
                    f.reshape([n, s, c]),
                ))
            }
            FeatureMode::Composited => {
                Some(self.composited_feature(field.trunk, comp.weights.clone(), n, s))
            }
        };
        LevelOutputs {
            rgb: comp.rgb,
            depth: comp.depth,
            acc: comp.acc,
            feature,
            weights: comp.weights,
            t_vals,
        }
    }

    /// The length of each ray's direction and the encoding of its unit
    /// direction (the colour branch's view input).
    ///
    /// # Shapes
    /// - outputs: `[n, 1]`, `[n, view_dim]`.
    pub(crate) fn view_encoding(&self, rays: &Rays) -> (Tensor<2>, Tensor<2>) {
        let dir_norm = rays.directions.clone().square().sum_dim(1).sqrt();
        let viewdirs = rays
            .directions
            .clone()
            .div(dir_norm.clone().clamp_min(1e-20));
        (dir_norm, pos_enc(viewdirs, 0, self.mlp.viewdir_deg, true))
    }

    /// The integrated positional encoding of the frustums between
    /// consecutive fence posts, ray-major.
    ///
    /// # Shapes
    /// - `t_vals`: `[n, samples + 1]`; output: `[n * samples, ipe_dim]`.
    pub(crate) fn encode_samples(&self, t_vals: Tensor<2>, rays: &Rays) -> Tensor<2> {
        let [n, posts] = t_vals.dims();
        let g = cast_rays(
            t_vals,
            rays.origins.clone(),
            rays.directions.clone(),
            rays.radii.clone(),
        );
        let ipe = integrated_pos_enc(g.mean, g.cov_diag, self.mlp.min_deg, self.mlp.max_deg);
        let [_, _, dim] = ipe.dims();
        ipe.reshape([n * (posts - 1), dim])
    }

    /// Feature by averaging the head's hidden activations with the (detached)
    /// weights, optionally over the top-k samples only, and applying the
    /// linear output layer once per ray: `A (sum w h / sum w) + b` equals the
    /// weighted mean of the per-sample features `A h + b`.
    fn composited_feature(
        &self,
        trunk: Tensor<2>,
        weights: Tensor<2>,
        n: usize,
        s: usize,
    ) -> Tensor<2> {
        let weights = weights.detach();
        let trunk = trunk.detach();
        let [_, width] = trunk.dims();
        let k = self.head_top_k;
        let (trunk, weights, s) = if k > 0 && k <= s {
            let (w, idx) = weights.topk_with_indices(k, 1); // [n, k]
            let idx: Tensor<3, Int> = idx.unsqueeze_dim::<3>(2).expand([n, k, width]);
            let t = trunk.reshape([n, s, width]).gather(1, idx);
            (t.reshape([n * k, width]), w, k)
        } else {
            (trunk, weights, s)
        };
        let hidden = self.head.hidden(trunk);
        let [_, hd] = hidden.dims();
        let hmean = composite_features_mean(weights, hidden.reshape([n, s, hd]));
        self.head.output.forward(hmean)
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
