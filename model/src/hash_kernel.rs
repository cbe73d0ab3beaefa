//! The hash encoding computed in one pass on the CPU backends: for each
//! level, every point's cell, its eight corner rows and trilinear weights,
//! and the weighted sum of those rows, with no corner array written to
//! memory; and its backward, the same corners recomputed and the output's
//! gradient scatter-added into the level's rows.
//!
//! The work goes level by level: one level's table (2^15 rows of two
//! features: 256 KB) stays in the core's cache while every point reads it,
//! where point by point each read lands in another level's table. Before
//! its corners are read, a level's rows are read in order (the gradient's
//! written), so that the random reads find them in the cache. The forward
//! runs one task of points per thread; the backward runs levels in
//! parallel, and since each level writes only its own rows of the table's
//! gradient, it needs no atomics.
//!
//! It is a Burn backend extension ([`HashEncode`]): flex runs the loops on
//! its tensors' memory, ndarray through copies, and the autodiff form
//! registers the backward. The GPU backends keep the tensor-op form
//! ([`crate::hashgrid::HashGrid::forward_device`]).

// ndarray is deprecated upstream; the workspace keeps it as the reference
// CPU backend, so the extension routes to it too.
#![allow(deprecated)]

use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, Dispatch, Flex, TensorMetadata, backend_extension};
use burn::tensor::{DType, Tensor, TensorData};
use rayon::prelude::*;

/// Instant-NGP's spatial hash primes.
pub const PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

/// The table row of vertex `v` of a level with `res` cells across and
/// `rows` rows: dense indexing where the grid fits, the hash elsewhere.
#[inline(always)]
pub fn vertex_row(v: [u32; 3], res: u32, rows: usize) -> usize {
    let side = res as u64 + 1;
    if side * side * side <= rows as u64 {
        (v[0] as u64 + side * (v[1] as u64 + side * v[2] as u64)) as usize
    } else {
        let h = v[0].wrapping_mul(PRIMES[0])
            ^ v[1].wrapping_mul(PRIMES[1])
            ^ v[2].wrapping_mul(PRIMES[2]);
        h as usize & (rows - 1)
    }
}

/// A point of the grids' cube (half side `half_extent`) in the unit cube,
/// clamped to it.
pub fn unit_point(p: &[f32], half_extent: f32) -> [f32; 3] {
    let scale = 0.5 / half_extent;
    [
        ((p[0] * scale) + 0.5).clamp(0.0, 1.0),
        ((p[1] * scale) + 0.5).clamp(0.0, 1.0),
        ((p[2] * scale) + 0.5).clamp(0.0, 1.0),
    ]
}

/// The rows (within the level's table of `rows` rows) and trilinear
/// weights of the eight corners of unit point `u`'s cell at a level of
/// `res` cells across; corner `c` takes axis `k`'s upper vertex where bit
/// `k` of `c` is set.
#[inline(always)]
pub fn level_corners(u: [f32; 3], res: u32, rows: usize) -> ([usize; 8], [f32; 8]) {
    let mut cell = [0u32; 3];
    let mut frac = [0f32; 3];
    for k in 0..3 {
        let x = u[k] * res as f32;
        // `x` is not negative (the point is clamped to the unit cube), so
        // the conversion's truncation is its floor.
        let c = (x as u32).min(res.saturating_sub(1));
        cell[k] = c;
        frac[k] = x - c as f32;
    }
    let mut ids = [0usize; 8];
    let mut weights = [0f32; 8];
    for corner in 0..8u32 {
        let mut v = cell;
        let mut w = 1.0;
        for k in 0..3 {
            if corner >> k & 1 == 1 {
                v[k] += 1;
                w *= frac[k];
            } else {
                w *= 1.0 - frac[k];
            }
        }
        ids[corner as usize] = vertex_row(v, res, rows);
        weights[corner as usize] = w;
    }
    (ids, weights)
}

/// What the encoding needs of a grid besides its table.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    /// Cells across the domain at each level.
    pub resolutions: Vec<u32>,
    /// Rows of each level's table.
    pub rows: usize,
    /// Half the side of the covered cube.
    pub half_extent: f32,
}

/// The fewest points a parallel task of [`encode`] takes.
const MIN_ENCODE_CHUNK: usize = 2048;

/// Points a parallel task of [`encode`] takes: as few tasks as the pool
/// has threads. Each task goes level by level over its points and reads
/// every level's table from memory once, so fewer, larger tasks read the
/// tables fewer times.
fn encode_chunk(n: usize) -> usize {
    n.div_ceil(rayon::current_num_threads().max(1))
        .max(MIN_ENCODE_CHUNK)
}

/// f32 in a 64-byte cache line.
const FLOATS_PER_LINE: usize = 16;

/// The rows of a level's table of `rows` rows that its vertices can
/// reach: the dense grid's where it fits, else every row.
fn reachable_rows(res: u32, rows: usize) -> usize {
    let side = res as u64 + 1;
    (side * side * side).min(rows as u64) as usize
}

/// Whether `reads` random reads (or writes) of `numbers` f32 are worth
/// going over them in order first: at least one a cache line. An in-order
/// pass is streamed by the hardware prefetcher, where a random read of a
/// line not in the cache waits for it alone.
fn worth_warming(reads: usize, numbers: usize) -> bool {
    reads >= numbers / FLOATS_PER_LINE
}

/// Reads `numbers` in order, one a cache line, where `reads` random reads
/// of them follow ([`worth_warming`]), so that those reads find their
/// lines in the cache.
fn warm(numbers: &[f32], reads: usize) {
    if !worth_warming(reads, numbers.len()) {
        return;
    }
    let mut acc = 0.0f32;
    for line in numbers.chunks(FLOATS_PER_LINE) {
        acc += line[0];
    }
    std::hint::black_box(acc);
}

/// The encoding of `points` (`[n, 3]`, flat) from `table` (`[levels *
/// rows, features]`, flat): `[n, levels * features]`, flat.
///
/// Chunks of points run in parallel (so a grid of few levels still keeps
/// every core busy), and within a chunk the levels run one after another,
/// each level's reachable rows read in order before its corners.
pub fn encode(points: &[f32], table: &[f32], spec: &GridSpec, features: usize) -> Vec<f32> {
    let n = points.len() / 3;
    let f = features.max(1);
    let levels = spec.resolutions.len();
    let width = levels * f;
    let mut out = vec![0.0f32; n * width];
    if width == 0 || n == 0 {
        return out;
    }
    let chunk = encode_chunk(n);
    out.par_chunks_mut(chunk * width)
        .zip(points.par_chunks(chunk * 3))
        .for_each(|(out, points)| {
            for (l, &res) in spec.resolutions.iter().enumerate() {
                let level = &table[l * spec.rows * f..(l + 1) * spec.rows * f];
                let reachable = &level[..reachable_rows(res, spec.rows) * f];
                warm(reachable, points.len() / 3 * 8);
                let at = Slot {
                    offset: l * f,
                    stride: width,
                };
                match f {
                    2 => encode_level::<2>(points, level, res, spec, out, at),
                    4 => encode_level::<4>(points, level, res, spec, out, at),
                    _ => encode_level_any(points, level, res, spec, f, out, at),
                }
            }
        });
    out
}

/// Where a level's features go in the rows of [`encode`]'s output: from
/// `offset` in each row of `stride` numbers.
#[derive(Clone, Copy)]
struct Slot {
    offset: usize,
    stride: usize,
}

/// The gradient of [`encode`] with respect to the table, from the output's
/// gradient `grad` (`[n, levels * features]`, flat): `[levels * rows,
/// features]`, flat.
pub fn encode_backward(points: &[f32], grad: &[f32], spec: &GridSpec, features: usize) -> Vec<f32> {
    let f = features.max(1);
    let levels = spec.resolutions.len();
    let n = points.len() / 3;
    let mut table = vec![0.0f32; levels * spec.rows * f];
    table
        .par_chunks_mut(spec.rows * f)
        .enumerate()
        .for_each(|(l, level)| {
            let res = spec.resolutions[l];
            // Written in order first, so that the scatter's random writes
            // find the rows in the cache (the fresh allocation's pages are
            // mapped here, in order, and not one by one under the scatter).
            let reachable = reachable_rows(res, spec.rows) * f;
            if worth_warming(n * 8, reachable) {
                level[..reachable].fill(0.0);
            }
            let row_grad = |i: usize| &grad[(i * levels + l) * f..(i * levels + l + 1) * f];
            match f {
                2 => scatter_level::<2>(points, row_grad, level, res, spec),
                _ => {
                    for (i, p) in points.chunks_exact(3).enumerate() {
                        let g = row_grad(i);
                        let (ids, weights) =
                            level_corners(unit_point(p, spec.half_extent), res, spec.rows);
                        for (&row, &w) in ids.iter().zip(&weights) {
                            for (t, &v) in level[row * f..row * f + f].iter_mut().zip(g) {
                                *t += w * v;
                            }
                        }
                    }
                }
            }
        });
    table
}

/// One level's part of [`encode_backward`], `F` features a row: each
/// point's gradient (`row_grad(i)`), weighted, added to its corners' rows.
fn scatter_level<'g, const F: usize>(
    points: &[f32],
    row_grad: impl Fn(usize) -> &'g [f32],
    level: &mut [f32],
    res: u32,
    spec: &GridSpec,
) {
    for (i, p) in points.chunks_exact(3).enumerate() {
        let g: [f32; F] = std::array::from_fn(|k| row_grad(i)[k]);
        let (ids, weights) = level_corners(unit_point(p, spec.half_extent), res, spec.rows);
        for (&row, &w) in ids.iter().zip(&weights) {
            let t = &mut level[row * F..row * F + F];
            for k in 0..F {
                t[k] += w * g[k];
            }
        }
    }
}

/// One level's encoding of every point, `F` features a row, written to
/// its slot of each point's output row.
fn encode_level<const F: usize>(
    points: &[f32],
    level: &[f32],
    res: u32,
    spec: &GridSpec,
    out: &mut [f32],
    at: Slot,
) {
    for (p, row) in points.chunks_exact(3).zip(out.chunks_exact_mut(at.stride)) {
        let (ids, weights) = level_corners(unit_point(p, spec.half_extent), res, spec.rows);
        let mut sum = [0.0f32; F];
        for (&r, &w) in ids.iter().zip(&weights) {
            let t = &level[r * F..r * F + F];
            for k in 0..F {
                sum[k] += w * t[k];
            }
        }
        row[at.offset..at.offset + F].copy_from_slice(&sum);
    }
}

/// [`encode_level`] for any number of features.
fn encode_level_any(
    points: &[f32],
    level: &[f32],
    res: u32,
    spec: &GridSpec,
    f: usize,
    out: &mut [f32],
    at: Slot,
) {
    for (p, row) in points.chunks_exact(3).zip(out.chunks_exact_mut(at.stride)) {
        let (ids, weights) = level_corners(unit_point(p, spec.half_extent), res, spec.rows);
        let acc = &mut row[at.offset..at.offset + f];
        for (&r, &w) in ids.iter().zip(&weights) {
            for (a, &t) in acc.iter_mut().zip(&level[r * f..r * f + f]) {
                *a += w * t;
            }
        }
    }
}

/// The hash encoding as one backend operation.
#[backend_extension(Flex, NdArray, Autodiff)]
pub trait HashEncode: Backend {
    /// The encoding of `points` (`[n, 3]`, no gradient) from `table`
    /// (`[levels * rows, features]`): `[n, levels * features]` ([`encode`]).
    fn hash_encode(
        points: FloatTensor<Self>,
        table: FloatTensor<Self>,
        spec: GridSpec,
    ) -> FloatTensor<Self> {
        encode_copied::<Self>(points, table, spec)
    }

    /// The table's gradient from the encoding's, `grad` (`[n, levels *
    /// features]`): `[levels * rows, features]` ([`encode_backward`]).
    fn hash_encode_backward(
        points: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        spec: GridSpec,
    ) -> FloatTensor<Self> {
        backward_copied::<Self>(points, grad, spec)
    }
}

/// [`encode`] on copies of the tensors' values (any CPU backend).
fn encode_copied<B: Backend>(
    points: FloatTensor<B>,
    table: FloatTensor<B>,
    spec: GridSpec,
) -> FloatTensor<B> {
    let features = table.shape()[1];
    let device = table.device();
    let n = points.shape()[0];
    let out = encode(&host::<B>(points), &host::<B>(table), &spec, features);
    let shape = [n, spec.resolutions.len() * features];
    B::float_from_data(TensorData::new(out, shape), &device)
}

/// [`encode_backward`] on copies of the tensors' values (any CPU backend).
fn backward_copied<B: Backend>(
    points: FloatTensor<B>,
    grad: FloatTensor<B>,
    spec: GridSpec,
) -> FloatTensor<B> {
    let levels = spec.resolutions.len().max(1);
    let features = grad.shape()[1] / levels;
    let device = grad.device();
    let table = encode_backward(&host::<B>(points), &host::<B>(grad), &spec, features);
    let shape = [levels * spec.rows, features];
    B::float_from_data(TensorData::new(table, shape), &device)
}

/// A tensor's values on the host as f32 (a copy).
pub(crate) fn host<B: Backend>(t: FloatTensor<B>) -> Vec<f32> {
    let data = burn::tensor::try_read_sync(B::float_into_data(t))
        .and_then(Result::ok)
        .expect("a CPU backend's tensor reads synchronously");
    data.convert::<f32>()
        .into_vec::<f32>()
        .expect("converted to f32")
}

impl HashEncode for burn::backend::NdArray {}

/// flex runs the loops on its tensors' own memory (f32; other dtypes on
/// copies).
impl HashEncode for Flex {
    fn hash_encode(
        points: FloatTensor<Self>,
        table: FloatTensor<Self>,
        spec: GridSpec,
    ) -> FloatTensor<Self> {
        if points.dtype() != DType::F32 || table.dtype() != DType::F32 {
            return encode_copied::<Self>(points, table, spec);
        }
        let features = table.shape()[1];
        let (points, table) = (points.to_contiguous(), table.to_contiguous());
        let out = encode(
            points.storage::<f32>(),
            table.storage::<f32>(),
            &spec,
            features,
        );
        let shape = [points.shape()[0], spec.resolutions.len() * features];
        Flex::float_from_data(TensorData::new(out, shape), &Default::default())
    }

    fn hash_encode_backward(
        points: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        spec: GridSpec,
    ) -> FloatTensor<Self> {
        if points.dtype() != DType::F32 || grad.dtype() != DType::F32 {
            return backward_copied::<Self>(points, grad, spec);
        }
        let levels = spec.resolutions.len().max(1);
        let features = grad.shape()[1] / levels;
        let (points, grad) = (points.to_contiguous(), grad.to_contiguous());
        let table = encode_backward(
            points.storage::<f32>(),
            grad.storage::<f32>(),
            &spec,
            features,
        );
        let shape = [levels * spec.rows, features];
        Flex::float_from_data(TensorData::new(table, shape), &Default::default())
    }
}

impl<B: Backend + HashEncode, C: CheckpointStrategy> HashEncode for Autodiff<B, C> {
    fn hash_encode(
        points: FloatTensor<Self>,
        table: FloatTensor<Self>,
        spec: GridSpec,
    ) -> FloatTensor<Self> {
        #[derive(Debug)]
        struct HashEncodeBackward;

        impl<B: Backend + HashEncode> Backward<B, 1> for HashEncodeBackward {
            type State = (FloatTensor<B>, GridSpec);

            fn backward(
                self,
                ops: Ops<Self::State, 1>,
                grads: &mut Gradients,
                _checkpointer: &mut Checkpointer,
            ) {
                let [node] = ops.parents;
                let grad = grads.consume::<B>(&ops.node);
                let (points, spec) = ops.state;
                if let Some(node) = node {
                    grads.register::<B>(node.id, B::hash_encode_backward(points, grad, spec));
                }
            }
        }

        // The positions are constants: the encoding's gradient reaches only
        // the table.
        let points = points.into_primitive();
        match HashEncodeBackward
            .prepare::<C>([table.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let out = B::hash_encode(points.clone(), table.into_primitive(), spec.clone());
                prep.finish((points, spec), out)
            }
            OpsKind::UnTracked(prep) => {
                prep.finish(B::hash_encode(points, table.into_primitive(), spec))
            }
        }
    }
}

/// [`HashEncode::hash_encode`] on tensors of a CPU backend (flex or
/// ndarray, with or without autodiff).
///
/// # Shapes
/// - `points`: `[n, 3]`; `table`: `[levels * rows, features]`; output:
///   `[n, levels * features]`.
pub fn hash_encode(points: Tensor<2>, table: Tensor<2>, spec: GridSpec) -> Tensor<2> {
    Tensor::from_dispatch(<Dispatch as HashEncode>::hash_encode(
        points.detach().into_dispatch(),
        table.into_dispatch(),
        spec,
    ))
}
