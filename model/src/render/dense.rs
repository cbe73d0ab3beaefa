//! The training pass: coarse/fine rendering with the shared MLP, or the
//! proposal rounds and the NeRF level, every sample of a level evaluated
//! at once, outputs as (autodiff) tensors.

use burn::tensor::{Int, Tensor};

use super::grid::{ClipStats, clip_for_training};
use super::levels::{Level, LevelField, LevelPass};
use super::posts::{Posts, ProposalLevel};
use super::sealed::{Sealed, Token};
use super::{FeatureMode, RenderPass, RenderRequest};
use crate::composite::{composite, composite_features_mean};
use crate::nerf::{OpenNerf, Radiance, Rays};

/// The training pass: both levels of the rendered rays as tensors, with
/// the autodiff graph when the model is on an autodiff device.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Train {
    /// Jitter the stratified coarse posts and the resampled fine ones (off:
    /// the deterministic render).
    pub randomized: bool,
    /// The fraction of training done, in `[0, 1]`: the proposal sampler
    /// anneals its resampling weights with it (1: no annealing).
    pub progress: f32,
}

/// What a training ray's photograph has learned, one row per input ray of
/// the request (`None`: nothing of that kind).
#[derive(Debug, Clone, Default)]
pub struct PerPhotograph {
    /// Pose corrections, `[n, 6]`, as
    /// [`crate::pose::PoseCorrection::per_ray`] gives them: each ray's
    /// origin shifted and direction turned ([`crate::Rays::corrected`]).
    pub pose_correction: Option<Tensor<2>>,
    /// Appearance codes, `[n, dim]`, as
    /// [`crate::appearance::AppearanceCodes::per_ray`] gives them, for the
    /// colour branch.
    pub appearance: Option<Tensor<2>>,
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

/// What the training pass returns: the levels of the rendered rays (`n` of
/// them: all input rays, or those [`RenderOutputs::kept`] names) and what
/// the occupancy grid did.
#[derive(Debug, Clone)]
pub struct RenderOutputs {
    /// Coarse level (`None` with the proposal sampler).
    pub coarse: Option<LevelOutputs>,
    /// Fine level, the NeRF level with the proposal sampler (the one to
    /// display and evaluate).
    pub fine: LevelOutputs,
    /// The proposal rounds, in order (empty without the proposal sampler).
    pub proposals: Vec<ProposalLevel>,
    /// The fine level's posts in `s` (see
    /// [`Extent::spacing`](crate::extent::Extent::spacing)), for the
    /// interlevel and distortion losses; `None` for the box field with
    /// coarse and fine level.
    pub fine_s: Option<Tensor<2>>,
    /// Index in the input of each rendered ray, in order, when the grid
    /// dropped some (`None`: every input ray, in input order). Select the
    /// targets of these rays for the losses.
    pub kept: Option<Vec<usize>>,
    /// What clipping to the grid did (`None`: no grid was used).
    pub clip: Option<ClipStats>,
}

impl Sealed for Train {}

impl RenderPass for Train {
    type Output = RenderOutputs;

    fn run(model: &OpenNerf, request: &RenderRequest<'_, Self>, _: Token) -> RenderOutputs {
        model.render_train_with(request, PerPhotograph::default())
    }
}

impl OpenNerf {
    /// The training pass of `request` with what each ray's photograph has
    /// learned applied to it (see [`PerPhotograph`]), so that the loss
    /// reaches those parameters.
    pub fn render_train_with(
        &self,
        request: &RenderRequest<'_, Train>,
        photographs: PerPhotograph,
    ) -> RenderOutputs {
        let model = self;
        let bounded = model.extent.bound_rays(request.rays);
        let clipped = clip_for_training(model.sampler_grid(), request.grid, &bounded);
        let rays = clipped.rays.as_deref().unwrap_or(&bounded);
        let mut rays = Rays::from_normalized(rays, &model.device());
        // Rows of the rays the grid kept.
        let kept = |t: Tensor<2>| match &clipped.kept {
            Some(kept) => {
                let ids: Vec<i64> = kept.iter().map(|&i| i as i64).collect();
                let ids = Tensor::<1, Int>::from_data(
                    burn::tensor::TensorData::new(ids, [kept.len()]),
                    &t.device(),
                );
                t.select(0, ids)
            }
            None => t,
        };
        if let Some(c) = photographs.pose_correction {
            rays = rays.corrected(kept(c));
        }
        rays.appearance = photographs.appearance.map(kept);
        let (dir_norm, view_enc) = model.view_encoding(&rays);
        let pass = TrainLevels {
            rays: &rays,
            dir_norm,
            view_enc,
            background: request.background,
            mode: request.features,
            coarse: None,
            proposals: Vec::new(),
            progress: request.pass.progress,
        };
        let (randomized, progress) = (request.pass.randomized, request.pass.progress);
        let mut out = model.run_levels(&rays, randomized, progress, pass);
        out.kept = clipped.kept;
        out.clip = clipped.stats;
        out
    }
}

/// The training pass's levels: each evaluated whole, its outputs kept
/// for the losses.
struct TrainLevels<'r> {
    rays: &'r Rays,
    dir_norm: Tensor<2>,
    view_enc: Tensor<2>,
    background: Option<[f32; 3]>,
    mode: FeatureMode,
    /// The coarse level (the NeRF MLP's level before the last).
    coarse: Option<LevelOutputs>,
    /// The proposal rounds, in order.
    proposals: Vec<ProposalLevel>,
    /// The fraction of training done (the fast field's coarse-to-fine
    /// ramp reads it).
    progress: f32,
}

impl LevelPass for TrainLevels<'_> {
    type Output = RenderOutputs;

    fn sample(&mut self, model: &OpenNerf, level: Level<'_>, posts: &Posts) -> Tensor<2> {
        let t = posts.t.clone();
        match level.field {
            LevelField::Proposal(mlp) => {
                let weights = model.proposal_weights(mlp, t.clone(), self.rays, &self.dir_norm);
                let s_vals = match &posts.s {
                    Some(s) => s.clone(),
                    None => model.extent.spacing().t_to_s(
                        t,
                        self.rays.near.clone(),
                        self.rays.far.clone(),
                    ),
                };
                self.proposals.push(ProposalLevel {
                    s_vals,
                    weights: weights.clone(),
                });
                weights
            }
            LevelField::Mlp => {
                // The feature is composited at the coarse level only when
                // so configured.
                let mode = if model.coarse_features {
                    self.mode
                } else {
                    FeatureMode::None
                };
                let coarse = model.render_level(self.rays, t, self.level_inputs(), mode);
                let weights = coarse.weights.clone();
                self.coarse = Some(coarse);
                weights
            }
        }
    }

    fn last(self, model: &OpenNerf, posts: Posts) -> RenderOutputs {
        let rays = self.rays;
        let fine = model.render_level(rays, posts.t, self.level_inputs(), self.mode);
        // The fine level's posts in `s`: as the proposal sampler drew them,
        // or (the coarse/fine sampler) from `t` in an unbounded scene.
        let fine_s = posts.s.or_else(|| {
            model.extent.is_unbounded().then(|| {
                model.extent.spacing().t_to_s(
                    fine.t_vals.clone(),
                    rays.near.clone(),
                    rays.far.clone(),
                )
            })
        });
        RenderOutputs {
            coarse: self.coarse,
            fine,
            proposals: self.proposals,
            fine_s,
            kept: None,
            clip: None,
        }
    }
}

/// What every NeRF level of a training ray takes besides its posts.
struct LevelInputs {
    view_enc: Tensor<2>,
    dir_norm: Tensor<2>,
    background: Option<[f32; 3]>,
    progress: f32,
}

impl TrainLevels<'_> {
    fn level_inputs(&self) -> LevelInputs {
        LevelInputs {
            view_enc: self.view_enc.clone(),
            dir_norm: self.dir_norm.clone(),
            background: self.background,
            progress: self.progress,
        }
    }
}

impl OpenNerf {
    fn render_level(
        &self,
        rays: &Rays,
        t_vals: Tensor<2>,
        inputs: LevelInputs,
        mode: FeatureMode,
    ) -> LevelOutputs {
        let LevelInputs {
            view_enc,
            dir_norm,
            background,
            progress,
        } = inputs;
        let [n, posts] = t_vals.dims();
        let s = posts - 1;
        let ipe = self.encode_samples(t_vals.clone(), rays, progress);
        let field = self.radiance().forward(ipe, view_enc, s);
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
                let input = self.radiance().head_input(field.trunk);
                let f = self.head.forward(input);
                let [_, c] = f.dims();
                Some(composite_features_mean(
                    comp.weights.clone(),
                    f.reshape([n, s, c]),
                ))
            }
            FeatureMode::Composited => {
                let input = self.radiance().head_input(field.trunk);
                Some(self.composited_feature(input, comp.weights.clone(), n, s))
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
    pub(super) fn view_encoding(&self, rays: &Rays) -> (Tensor<2>, Tensor<2>) {
        let dir_norm = rays.directions.clone().square().sum_dim(1).sqrt();
        let viewdirs = rays
            .directions
            .clone()
            .div(dir_norm.clone().clamp_min(1e-20));
        let radiance = self.radiance();
        let enc = radiance.view_encoding(viewdirs);
        let dim = radiance.appearance_dim();
        if dim == 0 {
            return (dir_norm, enc);
        }
        let [n, _] = enc.dims();
        let code = match &rays.appearance {
            Some(code) => code.clone(),
            None => Tensor::zeros([n, dim], &enc.device()),
        };
        (dir_norm, Tensor::cat(vec![enc, code], 1))
    }

    /// The field's encoding of the frustums between consecutive fence
    /// posts, ray-major ([`OpenNerf::encode_gaussians`]); a field that reads
    /// no covariance gets the frustums' means alone, and their covariances
    /// are never formed. The fast field's levels are weighed by its
    /// coarse-to-fine ramp at `progress`, the fraction of training done (1
    /// for inference: every level).
    ///
    /// # Shapes
    /// - `t_vals`: `[n, samples + 1]`; output: `[n * samples, input]`.
    pub(super) fn encode_samples(
        &self,
        t_vals: Tensor<2>,
        rays: &Rays,
        progress: f32,
    ) -> Tensor<2> {
        let [n, posts] = t_vals.dims();
        let m = n * (posts - 1);
        let fast = match self.radiance() {
            Radiance::Fast(fast) => Some(fast),
            Radiance::Mip(_) => None,
        };
        let encoded = match fast {
            Some(fast) if !fast.reads_covariance() => {
                let mean = self.extent.frustum_means(t_vals, rays);
                fast.encode_means(mean.reshape([m, 3]))
            }
            _ => {
                let g = self.extent.frustums(t_vals, rays);
                self.encode_gaussians(g.mean.reshape([m, 3]), g.cov_diag.reshape([m, 3]))
            }
        };
        match fast {
            Some(fast) => fast.ramp_levels(encoded, progress),
            None => encoded,
        }
    }

    /// Feature by averaging the head's hidden activations of its input
    /// ([`crate::nerf::Radiance::head_input`]) with the (detached) weights,
    /// optionally over the top-k samples only, and applying the linear
    /// output layer once per ray: `A (sum w h / sum w) + b` equals the
    /// weighted mean of the per-sample features `A h + b`.
    fn composited_feature(
        &self,
        trunk: Tensor<2>,
        weights: Tensor<2>,
        n: usize,
        s: usize,
    ) -> Tensor<2> {
        let weights = weights.detach();
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
        let hidden = self.head.hidden_of(trunk);
        let [_, hd] = hidden.dims();
        let hmean = composite_features_mean(weights, hidden.reshape([n, s, hd]));
        self.head.output.forward(hmean)
    }
}
