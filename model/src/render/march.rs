//! Inference rendering with early ray termination: each level's samples are
//! evaluated front to back in segments, and a ray whose transmittance falls
//! below a threshold leaves the batch, so the samples behind a surface (the
//! coarse samples behind it, and the fine samples behind the middle of the
//! surface's cluster) are never evaluated. Only for inference: there is no
//! autodiff graph to keep, and what is skipped weighs at most the threshold.

use burn::tensor::{Device, Int, Tensor, TensorData};

use super::FeatureMode;
use super::levels::{Level, LevelField, LevelPass};
use super::posts::Posts;
use super::rendered::RenderedRays;
use crate::composite::{
    FEATURE_ACC_EPS, SegmentOptics, composite_features_mean, composite_values, depth_crossing,
    expected_depth, over_background, segment_weights, t_mids,
};
use crate::host_work::{ReadReason, read_back};
use crate::nerf::{OpenNerf, Rays};

/// A march's values on the host (an inference read).
fn host<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    read_back(ReadReason::Inference, t)
}

/// When a ray stops being evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Termination {
    /// A ray whose transmittance falls below this ends (0: never), so the
    /// weight left unevaluated behind it is below this too.
    pub transmittance: f32,
    /// Samples evaluated between two checks.
    pub segment: usize,
}

impl Default for Termination {
    /// Transmittance 1e-4, checked every 8 samples.
    fn default() -> Self {
        Termination {
            transmittance: 1e-4,
            segment: 8,
        }
    }
}

impl Termination {
    /// Every sample evaluated: the fine level of the deterministic dense
    /// render ([`super::Train`] without jitter), the same numbers on the
    /// CPU backends (checked by the model's tests).
    pub fn off() -> Self {
        Termination {
            transmittance: 0.0,
            segment: usize::MAX,
        }
    }
}

/// The march's levels: the levels before the last evaluated whole (the
/// proposal rounds, which are small) or marched (the coarse level), the
/// last marched into `out`.
struct MarchLevels<'r> {
    rays: &'r Rays,
    dir_norm: Tensor<2>,
    view_enc: Tensor<2>,
    background: Option<[f32; 3]>,
    mode: FeatureMode,
    termination: Termination,
    out: RenderedRays,
}

impl MarchLevels<'_> {
    /// Every ray alive at the start of a march over `t_vals`.
    fn start(&self, t_vals: Tensor<2>) -> Alive {
        let n = self.rays.len();
        Alive {
            ids: (0..n).collect(),
            rays: self.rays.clone(),
            dir_norm: self.dir_norm.clone(),
            view_enc: self.view_enc.clone(),
            tau: Tensor::zeros([n, 1], &t_vals.device()),
            t_vals,
        }
    }
}

impl LevelPass for MarchLevels<'_> {
    type Output = RenderedRays;

    fn sample(&mut self, model: &OpenNerf, level: Level<'_>, posts: &Posts) -> Tensor<2> {
        let n = self.rays.len();
        let t = posts.t.clone();
        match level.field {
            LevelField::Proposal(mlp) => {
                self.out.samples_evaluated += n * level.samples;
                model.proposal_weights(mlp, t, self.rays, &self.dir_norm)
            }
            LevelField::Mlp => {
                let device = t.device();
                let alive = self.start(t);
                let (weights, evaluated) =
                    model.march_coarse(alive, level.samples, self.termination);
                self.out.samples_evaluated += evaluated;
                Tensor::from_data(TensorData::new(weights, [n, level.samples]), &device)
            }
        }
    }

    fn last(mut self, model: &OpenNerf, posts: Posts) -> RenderedRays {
        let alive = self.start(posts.t);
        let evaluated = model.march_fine(
            alive,
            self.background,
            self.mode,
            self.termination,
            &mut self.out,
        );
        self.out.samples_evaluated += evaluated;
        self.out
    }
}

/// The rays still being marched, compacted: row `i` is ray `ids[i]`.
struct Alive {
    ids: Vec<usize>,
    rays: Rays,
    dir_norm: Tensor<2>,
    view_enc: Tensor<2>,
    t_vals: Tensor<2>,
    /// Optical depth accumulated so far, `[m, 1]`.
    tau: Tensor<2>,
}

fn index(rows: &[usize], device: &Device) -> Tensor<1, Int> {
    let v: Vec<i64> = rows.iter().map(|&r| r as i64).collect();
    Tensor::from_data(TensorData::new(v, [rows.len()]), device)
}

impl Alive {
    /// Keeps rows `rows` (local indices).
    fn keep(self, rows: &[usize]) -> Alive {
        let device = self.tau.device();
        let idx = index(rows, &device);
        let s = |t: Tensor<2>| t.select(0, idx.clone());
        Alive {
            ids: rows.iter().map(|&r| self.ids[r]).collect(),
            rays: Rays {
                origins: s(self.rays.origins),
                directions: s(self.rays.directions),
                radii: s(self.rays.radii),
                near: s(self.rays.near),
                far: s(self.rays.far),
                appearance: self.rays.appearance.map(s),
            },
            dir_norm: s(self.dir_norm),
            view_enc: s(self.view_enc),
            t_vals: s(self.t_vals),
            tau: s(self.tau),
        }
    }

    /// Local rows whose transmittance is still at or above `threshold`,
    /// and those below it.
    fn split(&self, threshold: f32) -> (Vec<usize>, Vec<usize>) {
        let tau = host(self.tau.clone());
        (0..tau.len()).partition(|&i| (-tau[i]).exp() >= threshold)
    }
}

/// What the fine level accumulates per alive ray for its feature.
// One value per rendered chunk: its size on the stack does not matter.
#[allow(clippy::large_enum_variant)]
enum FeatureState {
    None,
    /// `sum w f` of the per-sample features.
    Sum(Tensor<2>),
    /// `sum w h` of the head's hidden activations.
    HiddenSum(Tensor<2>),
    /// The `k` largest weights so far, `[m, k]`, and the head's inputs there, `[m, k, width]`.
    TopK(Tensor<2>, Tensor<3>),
}

impl FeatureState {
    fn select(&self, idx: &Tensor<1, Int>) -> FeatureState {
        match self {
            FeatureState::None => FeatureState::None,
            FeatureState::Sum(t) => FeatureState::Sum(t.clone().select(0, idx.clone())),
            FeatureState::HiddenSum(t) => FeatureState::HiddenSum(t.clone().select(0, idx.clone())),
            FeatureState::TopK(w, f) => FeatureState::TopK(
                w.clone().select(0, idx.clone()),
                f.clone().select(0, idx.clone()),
            ),
        }
    }
}

/// Sums composited at the fine level for the alive rays.
struct FineState {
    rgb: Tensor<2>,
    depth: Tensor<2>,
    /// Where the accumulated weight reached a half (zero until it has).
    median: Tensor<2>,
    /// 1 once the accumulated weight has reached a half.
    crossed: Tensor<2>,
    acc: Tensor<2>,
    feature: FeatureState,
}

impl FineState {
    fn select(&self, rows: &[usize]) -> FineState {
        let idx = index(rows, &self.acc.device());
        let s = |t: &Tensor<2>| t.clone().select(0, idx.clone());
        FineState {
            rgb: s(&self.rgb),
            depth: s(&self.depth),
            median: s(&self.median),
            crossed: s(&self.crossed),
            acc: s(&self.acc),
            feature: self.feature.select(&idx),
        }
    }
}

impl OpenNerf {
    /// The fine level of `rays` (deterministic, no autodiff graph), marched
    /// front to back with early termination (see [`Termination`]); the
    /// occupancy grid has been applied to `rays` already. With
    /// [`Termination::off`] it equals the fine level of the deterministic
    /// dense render; otherwise each output differs from it by what a
    /// transmittance below the threshold can still add.
    pub(super) fn march(
        &self,
        rays: &Rays,
        background: Option<[f32; 3]>,
        mode: FeatureMode,
        termination: Termination,
    ) -> RenderedRays {
        let n = rays.len();
        let out = RenderedRays::zeros(n, self.feature_dim(mode));
        if n == 0 {
            return out;
        }
        let (dir_norm, view_enc) = self.view_encoding(rays);
        let pass = MarchLevels {
            rays,
            dir_norm,
            view_enc,
            background,
            mode,
            termination,
            out,
        };
        self.run_levels(rays, false, 1.0, pass)
    }

    /// The segment's density (and trunk features) of the alive rays.
    ///
    /// # Shapes
    /// - outputs: `[m, len]` density, `[m * len, width]` trunk, `[m, len + 1]` posts.
    fn evaluate(
        &self,
        alive: &Alive,
        range: std::ops::Range<usize>,
    ) -> (Tensor<2>, Tensor<2>, Tensor<2>) {
        let m = alive.ids.len();
        let len = range.len();
        let t = alive
            .t_vals
            .clone()
            .slice_dim(1, range.start..range.end + 1);
        let ipe = self.encode_samples(t.clone(), &alive.rays, 1.0);
        let (trunk, density) = self.radiance().trunk_density(ipe);
        (density.reshape([m, len]), trunk, t)
    }

    /// Coarse weights `[n * s]` (0 behind terminated rays) over `s`
    /// samples and the number of samples evaluated.
    fn march_coarse(&self, mut alive: Alive, s: usize, term: Termination) -> (Vec<f32>, usize) {
        let n = alive.ids.len();
        let mut weights = vec![0.0f32; n * s];
        let mut evaluated = 0;
        let mut begin = 0;
        while begin < s && !alive.ids.is_empty() {
            let end = begin.saturating_add(term.segment.max(1)).min(s);
            let (density, _, t) = self.evaluate(&alive, begin..end);
            let (w, tau) = segment_weights(density, t, alive.dir_norm.clone(), alive.tau);
            alive.tau = tau;
            let len = end - begin;
            evaluated += alive.ids.len() * len;
            for (row, chunk) in host(w).chunks(len).enumerate() {
                let ray = alive.ids[row];
                weights[ray * s + begin..ray * s + end].copy_from_slice(chunk);
            }
            begin = end;
            if begin < s {
                let (keep, _) = alive.split(term.transmittance);
                if keep.len() < alive.ids.len() {
                    alive = alive.keep(&keep);
                }
            }
        }
        (weights, evaluated)
    }

    /// Marches the fine level, writing each ray's outputs into `out` when it
    /// ends; returns the number of samples evaluated.
    fn march_fine(
        &self,
        mut alive: Alive,
        background: Option<[f32; 3]>,
        mode: FeatureMode,
        term: Termination,
        out: &mut RenderedRays,
    ) -> usize {
        let s = self.num_samples;
        let m = alive.ids.len();
        let device = alive.tau.device();
        let width = self.radiance().head_width();
        let k = self.head_top_k;
        let mut state = FineState {
            rgb: Tensor::zeros([m, 3], &device),
            depth: Tensor::zeros([m, 1], &device),
            median: Tensor::zeros([m, 1], &device),
            crossed: Tensor::zeros([m, 1], &device),
            acc: Tensor::zeros([m, 1], &device),
            feature: match mode {
                FeatureMode::None => FeatureState::None,
                FeatureMode::PerSample => {
                    FeatureState::Sum(Tensor::zeros([m, out.feature_dim], &device))
                }
                FeatureMode::Composited if k > 0 && k <= s => FeatureState::TopK(
                    Tensor::zeros([m, k], &device),
                    Tensor::zeros([m, k, width], &device),
                ),
                FeatureMode::Composited => {
                    let hd = self.head.output.weight.dims()[0];
                    FeatureState::HiddenSum(Tensor::zeros([m, hd], &device))
                }
            },
        };
        let mut evaluated = 0;
        let mut begin = 0;
        while begin < s && !alive.ids.is_empty() {
            let end = begin.saturating_add(term.segment.max(1)).min(s);
            let len = end - begin;
            let rows = alive.ids.len();
            let (density, trunk, t) = self.evaluate(&alive, begin..end);
            let rgb = self
                .radiance()
                .color(trunk.clone(), alive.view_enc.clone(), len);
            let optics = SegmentOptics::new(density, t.clone(), alive.dir_norm.clone(), alive.tau);
            let (median, crossed) = depth_crossing(&optics, t.clone(), 0.5);
            state.median = state.median.add(median);
            state.crossed = state.crossed.add(crossed);
            let w = optics.weights();
            alive.tau = optics.after;
            evaluated += rows * len;
            state.rgb = state
                .rgb
                .add(composite_values(w.clone(), rgb.reshape([rows, len, 3])));
            state.depth = state.depth.add(w.clone().mul(t_mids(t)).sum_dim(1));
            state.acc = state.acc.add(w.clone().sum_dim(1));
            // The head's input, formed only where features are asked for.
            let input = match state.feature {
                FeatureState::None => trunk,
                _ => self.radiance().head_input(trunk),
            };
            state.feature = match state.feature {
                FeatureState::None => FeatureState::None,
                FeatureState::Sum(sum) => {
                    let f = self.head.forward(input);
                    let [_, c] = f.dims();
                    FeatureState::Sum(sum.add(composite_values(w, f.reshape([rows, len, c]))))
                }
                FeatureState::HiddenSum(sum) => {
                    let h = self.head.hidden_of(input);
                    let [_, hd] = h.dims();
                    FeatureState::HiddenSum(
                        sum.add(composite_values(w, h.reshape([rows, len, hd]))),
                    )
                }
                FeatureState::TopK(top_w, top_f) => {
                    let cand_w = Tensor::cat(vec![top_w, w], 1);
                    let cand_f = Tensor::cat(vec![top_f, input.reshape([rows, len, width])], 1);
                    let (w, idx) = cand_w.topk_with_indices(k, 1);
                    let idx: Tensor<3, Int> = idx.unsqueeze_dim::<3>(2).expand([rows, k, width]);
                    FeatureState::TopK(w, cand_f.gather(1, idx))
                }
            };
            begin = end;
            let (keep, done) = if begin < s {
                alive.split(term.transmittance)
            } else {
                (Vec::new(), (0..rows).collect())
            };
            if !done.is_empty() {
                let ids: Vec<usize> = done.iter().map(|&r| alive.ids[r]).collect();
                self.finish(state.select(&done), &ids, background, out);
            }
            if keep.is_empty() {
                break;
            }
            if keep.len() < rows {
                state = state.select(&keep);
                alive = alive.keep(&keep);
            }
        }
        evaluated
    }

    /// Final outputs of the ended rays `ids` from their sums.
    fn finish(
        &self,
        state: FineState,
        ids: &[usize],
        background: Option<[f32; 3]>,
        out: &mut RenderedRays,
    ) {
        let rgb = over_background(state.rgb, state.acc.clone(), background);
        let depth = expected_depth(state.depth, state.acc.clone());
        // The median where the weight reached a half, else the mean.
        let median = state
            .median
            .mask_where(state.crossed.lower_elem(0.5), depth.clone());
        let feature = match state.feature {
            FeatureState::None => None,
            FeatureState::Sum(sum) => Some(sum.div(state.acc.clone().clamp_min(FEATURE_ACC_EPS))),
            FeatureState::HiddenSum(sum) => {
                let mean = sum.div(state.acc.clone().clamp_min(FEATURE_ACC_EPS));
                Some(self.head.output.forward(mean))
            }
            FeatureState::TopK(w, f) => {
                let [m, k, width] = f.dims();
                let h = self.head.hidden_of(f.reshape([m * k, width]));
                let [_, hd] = h.dims();
                let mean = composite_features_mean(w, h.reshape([m, k, hd]));
                Some(self.head.output.forward(mean))
            }
        };
        // One read for the three per-ray values: depth, median depth, opacity.
        let rgb = host(rgb);
        let scalars = host(Tensor::cat(vec![depth, median, state.acc], 1));
        for (row, &ray) in ids.iter().enumerate() {
            out.rgb[3 * ray..3 * ray + 3].copy_from_slice(&rgb[3 * row..3 * row + 3]);
            let [depth, median, acc] = [0, 1, 2].map(|c| scalars[3 * row + c]);
            out.depth[ray] = depth;
            out.median_depth[ray] = median;
            out.acc[ray] = acc;
        }
        if let Some(f) = feature {
            let d = out.feature_dim;
            let f = host(f);
            for (row, &ray) in ids.iter().enumerate() {
                out.feature[ray * d..(ray + 1) * d].copy_from_slice(&f[row * d..(row + 1) * d]);
            }
        }
    }
}
