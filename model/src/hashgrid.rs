//! A multiresolution hash encoding (Instant-NGP, Müller et al. 2022, as
//! nerfacto uses it): `levels` grids from `base_resolution` to
//! `max_resolution` cells across the field's domain, each a table of
//! `2^log2_table` learned feature vectors, hashed where the grid has more
//! vertices than the table has rows. A point's encoding is, per level, the
//! trilinear interpolation of its cell's eight vertex features.
//!
//! Gradients flow to the tables only: the corner indices and trilinear
//! weights are computed on the host from the (constant) sample positions.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::{Device, Int, Tensor, TensorData};

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
    /// show; docs/unbounded.md).
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

/// Instant-NGP's spatial hash primes.
const PRIMES: [u32; 3] = [1, 2_654_435_761, 805_459_861];

/// The table row of vertex `v` of a level with `res` cells across and
/// `rows` rows: dense indexing where the grid fits, the hash elsewhere.
fn vertex_row(v: [u32; 3], res: u32, rows: usize) -> usize {
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
        let scale = 0.5 / self.half_extent;
        for p in points.chunks_exact(3) {
            let u = [
                ((p[0] * scale) + 0.5).clamp(0.0, 1.0),
                ((p[1] * scale) + 0.5).clamp(0.0, 1.0),
                ((p[2] * scale) + 0.5).clamp(0.0, 1.0),
            ];
            for (l, &res) in self.resolutions.iter().enumerate() {
                let base = (l * self.rows) as i64;
                let mut cell = [0u32; 3];
                let mut frac = [0f32; 3];
                for k in 0..3 {
                    let x = u[k] * res as f32;
                    let c = (x.floor() as u32).min(res.saturating_sub(1));
                    cell[k] = c;
                    frac[k] = x - c as f32;
                }
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
                    rows.push(base + vertex_row(v, res, self.rows) as i64);
                    weights.push(w);
                }
            }
        }
        (rows, weights)
    }

    /// The encoding of `points`.
    ///
    /// # Shapes
    /// - `points`: `[n, 3]`; output: `[n, levels * features]`.
    pub fn forward(&self, points: Tensor<2>) -> Tensor<2> {
        let [n, _] = points.dims();
        let device = points.device();
        let host: Vec<f32> = points
            .into_data()
            .convert::<f32>()
            .try_to_vec::<f32>()
            .expect("converted to f32 above");
        let (rows, weights) = self.corners(&host);
        let levels = self.resolutions.len();
        let table = self.table.val();
        let [_, f] = table.dims();
        let ids = Tensor::<1, Int>::from_data(TensorData::new(rows, [n * levels * 8]), &device);
        let w = Tensor::<2>::from_data(TensorData::new(weights, [n * levels * 8, 1]), &device);
        let picked = table.select(0, ids).mul(w);
        picked
            .reshape([n * levels, 8, f])
            .sum_dim(1)
            .reshape([n, levels * f])
    }
}
