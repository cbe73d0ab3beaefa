//! The level loop (as mipnerf's `models.py`): a list of levels, each placing
//! its posts from the previous level's weights (see [`super::posts`]), the
//! last one the NeRF MLP's. Coarse/fine: two levels of the shared MLP.
//! The proposal sampler: one level per proposal round, then the NeRF level.
//! The training pass and the march run the same loop; what they do at each
//! level is a [`LevelPass`].

use burn::tensor::Tensor;

use super::posts::{Posts, Sampler};
use crate::nerf::OpenNerf;
use crate::proposal::ProposalMlp;
use crate::rays::Rays;

/// What evaluates a level.
#[derive(Debug, Clone, Copy)]
pub enum LevelField<'m> {
    /// The proposal MLP (density only).
    Proposal(&'m ProposalMlp),
    /// The NeRF MLP.
    Mlp,
}

/// One level of the loop.
#[derive(Debug, Clone, Copy)]
pub struct Level<'m> {
    /// Samples per ray.
    pub samples: usize,
    /// What evaluates it.
    pub field: LevelField<'m>,
}

/// What a pass does at each level.
pub(super) trait LevelPass {
    /// What the pass returns.
    type Output;

    /// Evaluates `level`, one before the last, at `posts`; returns its
    /// weights, `[n, samples]`, which the next level resamples.
    fn sample(&mut self, model: &OpenNerf, level: Level<'_>, posts: &Posts) -> Tensor<2>;

    /// Evaluates the last level (the NeRF MLP's) at `posts`.
    fn last(self, model: &OpenNerf, posts: Posts) -> Self::Output;
}

impl OpenNerf {
    /// The levels a ray is rendered in, in order; the last is the NeRF
    /// MLP's: the coarse and the fine level of the shared MLP, or the
    /// proposal rounds (a round of 0 samples takes 1) and the NeRF level.
    pub fn levels(&self) -> Vec<Level<'_>> {
        let mlp = |samples| Level {
            samples,
            field: LevelField::Mlp,
        };
        match self.proposal_sampler() {
            Some((config, proposal)) => config
                .samples
                .iter()
                .map(|&k| Level {
                    samples: k.max(1),
                    field: LevelField::Proposal(proposal),
                })
                .chain([mlp(self.num_samples)])
                .collect(),
            None => vec![mlp(self.num_samples), mlp(self.num_samples)],
        }
    }

    /// Runs `pass` over the levels of `rays`: each level's posts drawn
    /// from the previous level's posts and weights (jittered when
    /// `randomized`; `progress`, the fraction of training done, anneals
    /// the proposal sampler's weights).
    pub(super) fn run_levels<P: LevelPass>(
        &self,
        rays: &Rays,
        randomized: bool,
        progress: f32,
        mut pass: P,
    ) -> P::Output {
        let sampler = Sampler::of(self, progress);
        let levels = self.levels();
        let (before, last) = levels.split_at(levels.len().saturating_sub(1));
        let mut prev: Option<(Posts, Tensor<2>)> = None;
        for (index, &level) in before.iter().enumerate() {
            let posts = self.level_posts(&sampler, index, level.samples, prev, rays, randomized);
            let weights = pass.sample(self, level, &posts);
            prev = Some((posts, weights));
        }
        // The last level is the NeRF MLP's (`levels` always ends with it).
        let samples = last.first().map_or(self.num_samples, |level| level.samples);
        let posts = self.level_posts(&sampler, before.len(), samples, prev, rays, randomized);
        pass.last(self, posts)
    }
}
