//! Coarse-to-fine training of a hash encoding (Neuralangelo, Li et al.
//! 2023, section 3.2; FreeNeRF's frequency regularisation, Yang et al.
//! 2023, for positional encodings): early in training only the coarse
//! levels reach the MLP, and the finer ones are let in one after another,
//! so that the coarse geometry settles before the fine levels can fit
//! what a few photographs alone show.
//!
//! Level `l` (0: the coarsest) of `L` gets the weight `clamp(a - l, 0, 1)`
//! with `a = s + (L - s) * min(p / u, 1)`: `s` levels from the start, all
//! `L` once the fraction `p` of training done reaches `u`.

/// The levels that reach the MLP from the first step: a quarter of them
/// (Neuralangelo starts 4 of its 16), at least one.
pub fn ramp_start_levels(levels: usize) -> usize {
    levels.div_ceil(4).max(1)
}

/// Each level's weight at `progress`, the fraction of training done, for
/// a ramp that lets every level in by the fraction `until` (`until <= 0`:
/// no ramp, every level at 1). The weights are 1 for the first
/// [`ramp_start_levels`] levels, then fall from 1 to 0 over one level.
pub fn ramp_weights(levels: usize, progress: f32, until: f32) -> Vec<f32> {
    if ramp_done(progress, until) {
        return vec![1.0; levels];
    }
    let start = ramp_start_levels(levels) as f32;
    let done = (progress / until).clamp(0.0, 1.0);
    let active = start + (levels as f32 - start) * done;
    (0..levels)
        .map(|l| (active - l as f32).clamp(0.0, 1.0))
        .collect()
}

/// Whether [`ramp_weights`] leaves every level at 1.
pub fn ramp_done(progress: f32, until: f32) -> bool {
    until <= 0.0 || progress >= until
}
