//! The clusters of the balanced sampler: which cells have a target, the
//! k-means fit of the centres on a sample of them, and every cell's nearest
//! centre, streamed over the maps on all cores.
//!
//! Nothing here allocates per cell: map values are converted from `f16`
//! into one reused buffer per thread, and each thread writes its own chunk
//! of the output (a validity bit set, then a `u16` cluster id per cell).

use half::slice::HalfFloatSliceExt;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::layout::{Layout, any_pixel, map_of};
use crate::features::FeatureSet;
use crate::scene::Scene;

/// Map pixels sampled to fit the cluster centres.
const FIT_SAMPLES: usize = 16_384;
/// Lloyd iterations of the k-means fit.
const ITERATIONS: usize = 10;
/// Fewest output items a thread is given (smaller outputs run on fewer
/// threads, a tiny scene on the calling one).
const MIN_CHUNK: usize = 4096;
/// Independent partial sums of [`dist2`]: enough for the compiler to keep
/// whole vector registers busy instead of one serial chain of additions.
const LANES: usize = 16;

/// Runs `f(first, chunk)` over consecutive chunks of `out` (`first` the
/// index of the chunk's first item), one chunk per available core.
fn in_parallel<T: Send>(out: &mut [T], f: impl Fn(usize, &mut [T]) + Sync) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let per = out.len().div_ceil(threads).max(MIN_CHUNK);
    if out.len() <= per {
        f(0, out);
        return;
    }
    std::thread::scope(|s| {
        for (i, chunk) in out.chunks_mut(per).enumerate() {
            let f = &f;
            s.spawn(move || f(i * per, chunk));
        }
    });
}

/// Which cells have a target: an unmasked pixel and a map pixel that is a
/// target. One bit per cell (cell `c` is bit `c % 64` of word `c / 64`),
/// and the number of bits set.
///
/// # Shapes
/// The bit set has `ceil(layout.cells / 64)` words.
pub(super) fn targets(layout: &Layout, scene: &Scene, fs: &FeatureSet) -> (Vec<u64>, usize) {
    let mut bits = vec![0u64; layout.cells.div_ceil(64)];
    in_parallel(&mut bits, |first, words| {
        for (w, word) in words.iter_mut().enumerate() {
            let base = (first + w) * 64;
            for b in 0..64.min(layout.cells.saturating_sub(base)) {
                let at = layout.locate(base + b);
                let (fi, frame) = layout.frame(scene, &at);
                let valid = map_of(fs, fi).is_some_and(|m| {
                    any_pixel(frame, at.x, at.y) && fs.is_target(m.pixel(at.x.0, at.y.0))
                });
                *word |= u64::from(valid) << b;
            }
        }
    });
    let count = bits.iter().map(|w| w.count_ones() as usize).sum();
    (bits, count)
}

/// The cell of each rank in `ranks` (rank `r`: the `r`-th set bit of
/// `bits`, counting from 0; every rank below the number of bits set).
fn select(bits: &[u64], ranks: &[usize]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..ranks.len()).collect();
    order.sort_unstable_by_key(|&i| ranks[i]);
    let mut out = vec![0; ranks.len()];
    let (mut w, mut before) = (0usize, 0usize);
    for i in order {
        let r = ranks[i];
        while before + bits[w].count_ones() as usize <= r {
            before += bits[w].count_ones() as usize;
            w += 1;
        }
        let mut word = bits[w];
        for _ in 0..r - before {
            word &= word - 1; // drops the lowest set bit
        }
        out[i] = w * 64 + word.trailing_zeros() as usize;
    }
    out
}

/// Squared distance, summed in [`LANES`] interleaved partial sums. The
/// order of the additions differs from a serial sum's (the per-cell sampler
/// before this one), so a cell at a floating-point tie between two centres
/// may go to the other one; the fit and the assignment use this one alike.
fn dist2(a: &[f32], b: &[f32]) -> f32 {
    let (ac, ar) = a.as_chunks::<LANES>();
    let (bc, br) = b.as_chunks::<LANES>();
    let mut lanes = [0f32; LANES];
    for (x, y) in ac.iter().zip(bc) {
        for l in 0..LANES {
            let d = x[l] - y[l];
            lanes[l] += d * d;
        }
    }
    let tail: f32 = ar.iter().zip(br).map(|(x, y)| (x - y) * (x - y)).sum();
    lanes.iter().sum::<f32>() + tail
}

/// The centre (of `centres`, `dim` values each) nearest to `v`, the first
/// on ties; 0 without centres.
fn nearest(v: &[f32], centres: &[f32], dim: usize) -> usize {
    let mut best = (0, f32::INFINITY);
    for (c, centre) in centres.chunks_exact(dim.max(1)).enumerate() {
        let d = dist2(v, centre);
        if d < best.1 {
            best = (c, d);
        }
    }
    best.0
}

/// The map values of cell `cell` (which has a target) as `f32`s in `out`.
fn read(layout: &Layout, fs: &FeatureSet, cell: usize, out: &mut [f32]) {
    let at = layout.locate(cell);
    let fi = layout.frames[at.slot].frame;
    if let Some(m) = map_of(fs, fi) {
        m.pixel(at.x.0, at.y.0).convert_to_f32_slice(out);
    }
}

/// K-means centres (`k x dim`, row-major) of at most `clusters` clusters,
/// fitted on [`FIT_SAMPLES`] cells with a target drawn with `seed`:
/// the same draws, starting centres and Lloyd steps as the per-cell
/// sampler before it (so the same centres). `bits` and `count` are
/// [`targets`]' output. Empty when no cell has a target.
pub(super) fn fit(
    layout: &Layout,
    fs: &FeatureSet,
    (bits, count): (&[u64], usize),
    clusters: usize,
    seed: u64,
) -> Vec<f32> {
    let dim = fs.dim();
    let k = clusters.min(count).max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba1a_9ce5);
    let ranks: Vec<usize> = (0..FIT_SAMPLES.min(count))
        .map(|_| rng.random_range(0..count))
        .collect();
    let n = ranks.len();
    let mut samples = vec![0f32; n * dim];
    for (cell, out) in select(bits, &ranks)
        .into_iter()
        .zip(samples.chunks_mut(dim.max(1)))
    {
        read(layout, fs, cell, out);
    }
    let sample = |i: usize| &samples[i * dim..(i + 1) * dim];
    let mut centres: Vec<f32> = Vec::with_capacity(k * dim);
    for i in 0..k.min(n) {
        centres.extend_from_slice(sample(i * n / k.min(n)));
    }
    let k = centres.len() / dim.max(1);
    for _ in 0..ITERATIONS {
        let mut sums = vec![0f64; k * dim];
        let mut counts = vec![0usize; k];
        for i in 0..n {
            let v = sample(i);
            let c = nearest(v, &centres, dim);
            counts[c] += 1;
            for (s, &x) in sums[c * dim..(c + 1) * dim].iter_mut().zip(v) {
                *s += x as f64;
            }
        }
        for c in 0..k {
            if counts[c] > 0 {
                for j in 0..dim {
                    centres[c * dim + j] = (sums[c * dim + j] / counts[c] as f64) as f32;
                }
            }
        }
    }
    centres
}

/// The cluster of every cell: its nearest centre where it has a target
/// (`bits`), else `k` (the number of centres: "no target"). `k` is at most
/// [`FIT_SAMPLES`], so it fits a `u16`.
///
/// # Shapes
/// `centres` is `k x fs.dim()`; the result has `layout.cells` entries.
pub(super) fn assign(layout: &Layout, fs: &FeatureSet, bits: &[u64], centres: &[f32]) -> Vec<u16> {
    let dim = fs.dim();
    let k = centres.len() / dim.max(1);
    let mut ids = vec![k as u16; layout.cells];
    in_parallel(&mut ids, |first, chunk| {
        let mut v = vec![0f32; dim];
        for (i, id) in chunk.iter_mut().enumerate() {
            let cell = first + i;
            if bits[cell / 64] >> (cell % 64) & 1 == 1 {
                read(layout, fs, cell, &mut v);
                *id = nearest(&v, centres, dim) as u16;
            }
        }
    });
    ids
}
