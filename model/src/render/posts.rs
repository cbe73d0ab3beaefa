//! Where each level of the loop ([`super::levels`]) samples: the coarse
//! level's stratified posts and the fine level's blur-resample of them, or
//! one proposal round per level (Mip-NeRF 360, section 3), and the
//! proposal MLP's weights at a round's posts.

use burn::tensor::Tensor;

use crate::composite::compute_weights;
use crate::nerf::OpenNerf;
use crate::proposal::rounds::{Round, resample};
use crate::proposal::{ProposalConfig, ProposalMlp};
use crate::rays::Rays;
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

/// A level's fence posts.
#[derive(Debug, Clone)]
pub(super) struct Posts {
    /// In metric `t`, `[n, samples + 1]`.
    pub t: Tensor<2>,
    /// In `s`, where the sampler drew them there (the proposal sampler's);
    /// `None`: drawn in `t`.
    pub s: Option<Tensor<2>>,
}

/// How the levels' posts are drawn.
pub(super) enum Sampler<'a> {
    /// Stratified at the first level (in `t` in the box, in `s` in an
    /// unbounded scene), Mip-NeRF's blur-resample of the previous level's
    /// weights after.
    CoarseFine,
    /// One proposal round per level: dilated (after the first), annealed
    /// with `exponent`, drawn in `s`.
    Proposal {
        config: &'a ProposalConfig,
        exponent: f32,
    },
}

impl<'a> Sampler<'a> {
    /// The sampler of `model` at `progress`, the fraction of training done
    /// (1 at inference).
    pub(super) fn of(model: &'a OpenNerf, progress: f32) -> Self {
        match model.proposal_sampler() {
            Some((config, _)) => Sampler::Proposal {
                config,
                exponent: anneal_exponent(progress, config.anneal_slope),
            },
            None => Sampler::CoarseFine,
        }
    }
}

impl OpenNerf {
    /// The posts of the `index`-th level, of `samples` samples, from the
    /// previous level's posts and weights (`None` at the first level).
    ///
    /// # Shapes
    /// - output: `[n, samples + 1]`.
    pub(super) fn level_posts(
        &self,
        sampler: &Sampler<'_>,
        index: usize,
        samples: usize,
        prev: Option<(Posts, Tensor<2>)>,
        rays: &Rays,
        randomized: bool,
    ) -> Posts {
        let spacing = self.extent.spacing();
        let (near, far) = (rays.near.clone(), rays.far.clone());
        match sampler {
            Sampler::CoarseFine => {
                let pad = self.resample_padding as f32;
                let t = match prev {
                    None => spacing.stratified(near, far, samples, randomized),
                    Some((p, w)) => spacing.resampled(p.t, w, near, far, pad, randomized),
                };
                Posts { t, s: None }
            }
            Sampler::Proposal { config, exponent } => {
                let (s, w) = match prev {
                    Some((p, w)) => {
                        let s = match p.s {
                            Some(s) => s,
                            None => spacing.t_to_s(p.t, near.clone(), far.clone()),
                        };
                        (s, w)
                    }
                    None => whole_ray(rays),
                };
                let round = Round {
                    dilation: (index > 0).then(|| config.dilation(index)),
                    exponent: *exponent,
                    padding: config.resample_padding,
                    count: samples,
                    randomized,
                };
                let s = resample(&round, s, w);
                let t = spacing.s_to_t(s.clone(), near, far);
                Posts { t, s: Some(s) }
            }
        }
    }

    /// The proposal MLP's compositing weights at the posts `t`.
    ///
    /// # Shapes
    /// - `t`: `[n, samples + 1]`; `dir_norm`: `[n, 1]`; output: `[n, samples]`.
    pub(super) fn proposal_weights(
        &self,
        mlp: &ProposalMlp,
        t: Tensor<2>,
        rays: &Rays,
        dir_norm: &Tensor<2>,
    ) -> Tensor<2> {
        let [n, posts] = t.dims();
        let count = posts - 1;
        let m = n * count;
        // The hash form reads the frustums' means alone: their covariances
        // are never formed.
        let density = match &mlp.hash {
            Some(grid) => {
                let mean = self.extent.frustum_means(t.clone(), rays);
                mlp.hash_density(grid, mean.reshape([m, 3]))
            }
            None => {
                let g = self.extent.frustums(t.clone(), rays);
                mlp.density_at(g.mean.reshape([m, 3]), g.cov_diag.reshape([m, 3]))
            }
        };
        compute_weights(density.reshape([n, count]), t, dir_norm.clone())
    }
}

/// The first round's histogram: one interval over the whole ray in `s`,
/// `[n, 2]` posts and `[n, 1]` weight 1.
fn whole_ray(rays: &Rays) -> (Tensor<2>, Tensor<2>) {
    let n = rays.len();
    let device = rays.near.device();
    let s = Tensor::cat(
        vec![
            Tensor::zeros([n, 1], &device),
            Tensor::ones([n, 1], &device),
        ],
        1,
    );
    (s, Tensor::ones([n, 1], &device))
}
