//! A multiresolution hash encoding (Instant-NGP, Müller et al. 2022, as
//! nerfacto uses it): `levels` grids from `base_resolution` to
//! `max_resolution` cells across the field's domain, each a table of
//! `2^log2_table` learned feature vectors, hashed where the grid has more
//! vertices than the table has rows. A point's encoding is, per level, the
//! trilinear interpolation of its cell's eight vertex features.
//!
//! Gradients flow to the tables only: the corner indices (the integer
//! cell, the spatial hash, the level's offset) and the trilinear weights are
//! computed from the detached sample positions with tensor ops on the
//! positions' device, so the encoding reads nothing back to the host; the
//! table lookup is a gather whose backward is a scatter-add into the
//! tables. [`HashGrid::corners`] computes the same on the host, the
//! reference the tests hold the tensor form to.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::{Device, Int, Tensor, TensorData};

use crate::hash_kernel::{GridSpec, PRIMES, level_corners, unit_point};

/// Configuration of [`HashGrid`].
#[derive(Config, Debug)]
pub struct HashGridConfig {
    /// Grid levels.
    #[config(default = 16)]
    pub levels: usize,
    /// Features per level.
    #[config(default = 2)]
    pub features: usize,
    /// Rows of each level's table, as a power of two.
    #[config(default = 15)]
    pub log2_table: usize,
    /// Cells across the domain at the coarsest level.
    #[config(default = 16)]
    pub base_resolution: usize,
    /// Cells across the domain at the finest level (512: on a capture of
    /// 20 photographs, finer grids fit detail the training views alone
    /// show; docs/measurements/unbounded.md).
    #[config(default = 512)]
    pub max_resolution: usize,
    /// Half the side of the cube the grids cover, centred at the origin:
    /// the encoded coordinates' range (`pi`: the box field's `[-pi, pi]^3`
    /// and the unbounded field's contracted ball, scaled to radius `pi`).
    #[config(default = "std::f32::consts::PI")]
    pub half_extent: f32,
}

impl HashGridConfig {
    /// Width of the encoding.
    pub fn output_dim(&self) -> usize {
        self.levels.max(1) * self.features.max(1)
    }

    /// Builds the tables, uniform in `+-1e-4` as Instant-NGP starts them.
    pub fn init(&self, device: &Device) -> HashGrid {
        let levels = self.levels.max(1);
        // `train` refuses tables outside 2^4..=2^24 rows; the clamp keeps a
        // library caller's mistake from allocating without bound.
        let rows = 1usize << self.log2_table.clamp(4, 24);
        let table = Tensor::random(
            [levels * rows, self.features.max(1)],
            burn::tensor::Distribution::Uniform(-1e-4, 1e-4),
            device,
        );
        let growth = if levels > 1 {
            ((self.max_resolution.max(1) as f64).ln() - (self.base_resolution.max(1) as f64).ln())
                / (levels - 1) as f64
        } else {
            0.0
        };
        let resolutions = (0..levels)
            // Instant-NGP's floor; the nudge keeps the last level at
            // `max_resolution` where exp(ln) rounds just below it.
            .map(|l| {
                let r = (self.base_resolution.max(1) as f64) * (growth * l as f64).exp();
                (r * (1.0 + 1e-9)).floor() as u32
            })
            .collect();
        HashGrid {
            table: Param::from_tensor(table),
            rows,
            resolutions,
            half_extent: self.half_extent,
        }
    }
}

/// The learned tables of a multiresolution hash encoding.
#[derive(Module, Debug)]
pub struct HashGrid {
    /// `[levels * rows, features]`: level `l`'s table is rows
    /// `l * rows .. (l + 1) * rows`.
    pub table: Param<Tensor<2>>,
    /// Rows of each level's table.
    #[module(skip)]
    pub rows: usize,
    /// Cells across the domain at each level.
    #[module(skip)]
    pub resolutions: Vec<u32>,
    /// Half the side of the covered cube.
    #[module(skip)]
    pub half_extent: f32,
}

impl HashGrid {
    /// Width of the encoding.
    pub fn output_dim(&self) -> usize {
        self.resolutions.len() * self.table.val().dims()[1]
    }

    /// The corner rows and trilinear weights of each point at each level,
    /// point-major, then level, then the eight corners.
    pub fn corners(&self, points: &[f32]) -> (Vec<i64>, Vec<f32>) {
        let n = points.len() / 3;
        let levels = self.resolutions.len();
        let mut rows = Vec::with_capacity(n * levels * 8);
        let mut weights = Vec::with_capacity(n * levels * 8);
        for p in points.chunks_exact(3) {
            let u = unit_point(p, self.half_extent);
            for (l, &res) in self.resolutions.iter().enumerate() {
                let base = (l * self.rows) as i64;
                let (ids, w) = level_corners(u, res, self.rows);
                rows.extend(ids.iter().map(|&r| base + r as i64));
                weights.extend(w);
            }
        }
        (rows, weights)
    }

    /// The corner rows and trilinear weights of [`HashGrid::corners`] as
    /// tensors on the points' device (no read-back): the same rows bit for
    /// bit and the same weights, from the same f32 operations.
    ///
    /// Each axis contributes a lower and an upper term (its vertex
    /// coordinate times its prime, or times its dense stride; its weight
    /// `1 - frac` or `frac`), laid along a dimension of its own, so that the
    /// eight corners come out of broadcast XORs (or sums) and products,
    /// corner `c` taking axis `k`'s upper term where bit `k` of `c` is set.
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; outputs: rows `[n * levels * 8]`, weights
    ///   `[n * levels * 8, 1]`, point-major, then level, then corner.
    pub fn corner_tensors(&self, points: Tensor<2>) -> (Tensor<1, Int>, Tensor<2>) {
        let [n, _] = points.dims();
        let device = points.device();
        let levels = self.resolutions.len();
        let level = |values: Vec<f32>| {
            Tensor::<3>::from_data(TensorData::new(values, [1, levels, 1]), &device)
        };
        let res: Vec<f32> = self.resolutions.iter().map(|&r| r as f32).collect();
        let last: Vec<f32> = res.iter().map(|r| (r - 1.0).max(0.0)).collect();
        let x = points
            .detach()
            .mul_scalar(0.5 / self.half_extent)
            .add_scalar(0.5)
            .clamp(0.0, 1.0)
            .unsqueeze_dim::<3>(1)
            .mul(level(res));
        let cell = x
            .clone()
            .floor()
            .min_pair(level(last).expand([n, levels, 3]));
        let frac = x.sub(cell.clone());
        let cell = cell.int();
        // Axis k's pair of terms along dimension 4 - k of [n, levels, 2, 2, 2].
        let spread = |k: usize| {
            let mut shape = [n, levels, 1, 1, 1];
            shape[4 - k] = 2;
            shape
        };
        let weights = (0..3)
            .map(|k| {
                let f = frac.clone().narrow(2, k, 1);
                Tensor::cat(vec![f.clone().neg().add_scalar(1.0), f], 2).reshape(spread(k))
            })
            .reduce(|acc, w| acc.mul(w))
            .expect("three axes");
        let vertex = |k: usize| {
            let c = cell.clone().narrow(2, k, 1);
            Tensor::cat(vec![c.clone(), c.add_scalar(1)], 2).reshape(spread(k))
        };
        let rows = self.vertex_rows([vertex(0), vertex(1), vertex(2)], &device);
        (
            rows.reshape([n * levels * 8]),
            weights.reshape([n * levels * 8, 1]),
        )
    }

    /// [`crate::hash_kernel::vertex_row`] of every corner plus its level's first row, from each
    /// axis's vertex coordinates (`[n, levels, ..]`, the axis's pair along
    /// its own dimension): `[n, levels, 2, 2, 2]`. The levels whose grid
    /// fits its table (the coarse ones, first) index it densely, the rest
    /// by the hash; each part is computed on its own levels.
    fn vertex_rows(&self, v: [Tensor<5, Int>; 3], device: &Device) -> Tensor<5, Int> {
        let levels = self.resolutions.len();
        let sides: Vec<i64> = self.resolutions.iter().map(|&r| r as i64 + 1).collect();
        let dense = sides
            .iter()
            .take_while(|&&s| (s * s * s) as u64 <= self.rows as u64)
            .count();
        let per_level = |range: std::ops::Range<usize>, value: &dyn Fn(usize) -> i64| {
            let values: Vec<i64> = range.clone().map(value).collect();
            Tensor::<5, Int>::from_data(TensorData::new(values, [1, range.len(), 1, 1, 1]), device)
        };
        let part = |k: usize, range: std::ops::Range<usize>| {
            v[k].clone().narrow(1, range.start, range.len())
        };
        let base = |l: usize| (l * self.rows) as i64;
        let mut parts = Vec::new();
        if dense > 0 {
            let r = 0..dense;
            let x = part(0, r.clone()).add(per_level(r.clone(), &base));
            let y = part(1, r.clone()).mul(per_level(r.clone(), &|l| sides[l]));
            let z = part(2, r.clone()).mul(per_level(r.clone(), &|l| sides[l] * sides[l]));
            parts.push(z.add(y).add(x));
        }
        if dense < levels {
            let r = dense..levels;
            let mask = (self.rows - 1) as i64;
            // The primes as the i32 bit patterns of their u32 values: every
            // int width keeps the low 32 bits of the product, all the mask
            // reads. Each term is masked first, and the level's first row
            // (its bits above the mask's) joins by XOR, which is its sum.
            let term = |k: usize| {
                part(k, r.clone())
                    .mul_scalar(PRIMES[k] as i32 as i64)
                    .bitwise_and_scalar(mask)
            };
            let x = term(0).bitwise_xor(per_level(r.clone(), &base));
            parts.push(term(2).bitwise_xor(term(1)).bitwise_xor(x));
        }
        Tensor::cat(parts, 1)
    }

    /// The encoding of `points`: its corners computed with tensor ops on
    /// the points' device ([`HashGrid::corner_tensors`], nothing read back)
    /// on a GPU backend, and in one pass over the backend's memory
    /// ([`HashGrid::forward_fused`]) on the CPU backends, where that is the
    /// faster form (`bench`'s `hash_encoding` times the forms side by side).
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; output: `[n, levels * features]`.
    pub fn forward(&self, points: Tensor<2>) -> Tensor<2> {
        if crate::host_work::is_cpu_backend(&points.device()) {
            self.forward_fused(points)
        } else {
            self.forward_device(points)
        }
    }

    /// The encoding of `points` with its corners computed with tensor ops on
    /// the points' device ([`HashGrid::corner_tensors`]): nothing is read
    /// back to the host.
    pub fn forward_device(&self, points: Tensor<2>) -> Tensor<2> {
        let [n, _] = points.dims();
        let (ids, w) = self.corner_tensors(points);
        self.gather(n, ids, w)
    }

    /// The encoding of `points` computed level by level in one pass, its
    /// backward a scatter-add of the same kind ([`crate::hash_kernel`]); the
    /// CPU backends only (flex, ndarray), which hold their tensors on the
    /// host: the read of the positions is counted as the hash corners'.
    pub fn forward_fused(&self, points: Tensor<2>) -> Tensor<2> {
        crate::host_work::count_host_read(crate::host_work::ReadReason::HashCorners);
        let spec = GridSpec {
            resolutions: self.resolutions.clone(),
            rows: self.rows,
            half_extent: self.half_extent,
        };
        crate::hash_kernel::hash_encode(points, self.table.val(), spec)
    }

    /// The trilinear sum of the table rows `ids` weighted by `w`, eight
    /// corners a level: `[n, levels * features]`.
    fn gather(&self, n: usize, ids: Tensor<1, Int>, w: Tensor<2>) -> Tensor<2> {
        let levels = self.resolutions.len();
        let table = self.table.val();
        let [_, f] = table.dims();
        let picked = table.select(0, ids).mul(w);
        picked
            .reshape([n * levels, 8, f])
            .sum_dim(1)
            .reshape([n, levels * f])
    }
}
