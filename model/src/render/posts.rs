//! Where the MLP samples: the fence posts of the coarse and the fine level,
//! or of the NeRF level after the proposal rounds (Mip-NeRF 360, section
//! 3). Shared by the training and the inference pass.

use burn::tensor::Tensor;

use crate::composite::compute_weights;
use crate::mip::integrated_pos_enc;
use crate::nerf::{OpenNerf, Rays};
use crate::proposal::rounds::{Round, resample};
use crate::proposal::{ProposalConfig, ProposalMlp};
use crate::stepfun::anneal_exponent;

/// One proposal round's histogram along the rays, what the interlevel loss
/// makes an upper envelope of the NeRF weights.
#[derive(Debug, Clone)]
pub struct ProposalLevel {
    /// Fence posts in `s` (the ray coordinate, see
    /// [`Extent::spacing`](crate::extent::Extent::spacing)),
    /// `[n, samples + 1]`.
    pub s_vals: Tensor<2>,
    /// The proposal MLP's compositing weights, `[n, samples]` (with the
    /// autodiff graph on an autodiff model).
    pub weights: Tensor<2>,
}

impl OpenNerf {
    /// The coarse level's posts: stratified in `t` in the box, in `s`
    /// (normalised disparity) in an unbounded scene.
    ///
    /// # Shapes
    /// - output: `[n, num_samples + 1]`.
    pub(super) fn coarse_posts(&self, rays: &Rays, randomized: bool) -> Tensor<2> {
        let (near, far) = (rays.near.clone(), rays.far.clone());
        self.extent
            .spacing()
            .stratified(near, far, self.num_samples, randomized)
    }

    /// The fine level's posts, resampled from the coarse `weights` on the
    /// coarse posts (in `t` in the box, in `s` in an unbounded scene).
    ///
    /// # Shapes
    /// - `t_coarse`: `[n, samples + 1]`; `weights`: `[n, samples]`; output:
    ///   like `t_coarse`.
    pub(super) fn fine_posts(
        &self,
        rays: &Rays,
        t_coarse: Tensor<2>,
        weights: Tensor<2>,
        randomized: bool,
    ) -> Tensor<2> {
        let pad = self.resample_padding as f32;
        let (near, far) = (rays.near.clone(), rays.far.clone());
        self.extent
            .spacing()
            .resampled(t_coarse, weights, near, far, pad, randomized)
    }

    /// The proposal rounds along `rays`: each round resamples the last
    /// histogram (dilated, and annealed at `progress`, the fraction of
    /// training done; 1 at inference) and evaluates the proposal MLP.
    /// Returns the rounds and the NeRF level's posts in `s`.
    ///
    /// # Shapes
    /// - `dir_norm`: `[n, 1]`; posts: `[n, num_samples + 1]`.
    pub(super) fn propose(
        &self,
        (cfg, mlp): (&ProposalConfig, &ProposalMlp),
        rays: &Rays,
        dir_norm: &Tensor<2>,
        randomized: bool,
        progress: f32,
    ) -> (Vec<ProposalLevel>, Tensor<2>) {
        let n = rays.len();
        let device = rays.near.device();
        let mut s: Tensor<2> = Tensor::cat(
            vec![
                Tensor::zeros([n, 1], &device),
                Tensor::ones([n, 1], &device),
            ],
            1,
        );
        let mut w: Tensor<2> = Tensor::ones([n, 1], &device);
        let exponent = anneal_exponent(progress, cfg.anneal_slope);
        let rounds = cfg.samples.iter().copied().map(|k| k.max(1));
        let mut levels = Vec::with_capacity(cfg.samples.len());
        for (round, count) in rounds.chain([self.num_samples]).enumerate() {
            let spec = Round {
                dilation: (round > 0).then(|| cfg.dilation(round)),
                exponent,
                padding: cfg.resample_padding,
                count,
                randomized,
            };
            s = resample(&spec, s, w);
            if round == cfg.samples.len() {
                break;
            }
            let t = self
                .extent
                .spacing()
                .s_to_t(s.clone(), rays.near.clone(), rays.far.clone());
            let g = self.extent.frustums(t.clone(), rays);
            let ipe = integrated_pos_enc(g.mean, g.cov_diag, mlp.min_deg, mlp.max_deg);
            let [_, _, dim] = ipe.dims();
            let density = mlp.density(ipe.reshape([n * count, dim]));
            w = compute_weights(density.reshape([n, count]), t, dir_norm.clone());
            levels.push(ProposalLevel {
                s_vals: s.clone(),
                weights: w.clone(),
            });
        }
        (levels, s)
    }
}
