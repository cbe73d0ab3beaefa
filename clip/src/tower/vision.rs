//! The CLIP vision transformer: patch embedding, class token, position
//! embeddings stretched to any patch grid, pre-LN blocks, post-LN and the
//! projection into the joint space; pooled (the class token, CLIP's image
//! embedding) or dense (every patch, through a training-free last block).

use burn::module::{Module, Param};
use burn::nn::{Initializer, LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::{Device, Tensor, TensorData};

use super::DenseVariant;
use super::block::{BlockSizes, ResidualAttentionBlock};
use super::dense::dense_last_block;
use super::resample::bicubic_weights;
use super::text::l2_normalize;
use super::vision_config::ClipVisionConfig;

/// CLIP's image encoder.
#[derive(Module, Debug)]
pub struct ClipVisionEncoder {
    /// The patch embedding as a linear map of flattened patches
    /// (`[3 * p * p, width]`, channel-major then rows then columns, as a
    /// PyTorch convolution's `[width, 3, p, p]` flattens), no bias.
    pub patch_embedding: Linear,
    /// The class token, `[width]`.
    pub class_embedding: Param<Tensor<1>>,
    /// Position embeddings of the class token and the native `g x g` grid,
    /// `[1 + g * g, width]`.
    pub position_embedding: Param<Tensor<2>>,
    /// Layer norm before the blocks.
    pub pre_ln: LayerNorm,
    /// The residual attention blocks (not causal).
    pub blocks: Vec<ResidualAttentionBlock>,
    /// Layer norm after the blocks.
    pub post_ln: LayerNorm,
    /// Projection into the joint space, `width -> embed_dim`, no bias.
    pub projection: Linear,
    /// Patch side in pixels.
    #[module(skip)]
    pub patch_size: usize,
}

impl ClipVisionConfig {
    /// A randomly initialised encoder of these sizes (load real weights over
    /// it). Check [`ClipVisionConfig::problem`] first for configurations
    /// from a file.
    pub fn init(&self, device: &Device) -> ClipVisionEncoder {
        let normal = |std: f64| Initializer::Normal { mean: 0.0, std };
        let p = self.patch_size;
        let g = self.grid();
        let sizes = BlockSizes {
            width: self.width,
            heads: self.heads,
            mlp_width: self.mlp_width,
            activation: self.activation,
            layer_norm_eps: self.layer_norm_eps,
            causal: false,
        };
        let ln = || {
            LayerNormConfig::new(self.width)
                .with_epsilon(self.layer_norm_eps)
                .init(device)
        };
        ClipVisionEncoder {
            patch_embedding: LinearConfig::new(3 * p * p, self.width)
                .with_bias(false)
                .init(device),
            class_embedding: normal(0.02).init([self.width], device),
            position_embedding: normal(0.01).init([1 + g * g, self.width], device),
            pre_ln: ln(),
            blocks: (0..self.layers)
                .map(|_| ResidualAttentionBlock::with_sizes(&sizes, device))
                .collect(),
            post_ln: ln(),
            projection: LinearConfig::new(self.width, self.embed_dim)
                .with_bias(false)
                .init(device),
            patch_size: p,
        }
    }
}

impl ClipVisionEncoder {
    /// Output dimension.
    pub fn embed_dim(&self) -> usize {
        self.projection.weight.dims()[1]
    }

    /// Patches along each side of the native input.
    pub fn native_grid(&self) -> usize {
        let n = self.position_embedding.dims()[0].saturating_sub(1);
        (n as f64).sqrt().round() as usize
    }

    /// Position embeddings for a `rows x cols` grid: the native ones,
    /// stretched bicubically (PyTorch's `align_corners=False`) when the grid
    /// differs.
    ///
    /// # Shapes
    /// - output: `[1 + rows * cols, width]`.
    pub fn positions(&self, rows: usize, cols: usize) -> Tensor<2> {
        let pos = self.position_embedding.val();
        let g = self.native_grid();
        if (rows, cols) == (g, g) {
            return pos;
        }
        let [n, w] = pos.dims();
        let device = pos.device();
        let (ry, rx) = (bicubic_weights(g, rows), bicubic_weights(g, cols));
        // The 2D stretch as one matrix, [rows * cols, g * g].
        let mut kron = vec![0f32; rows * cols * g * g];
        for y in 0..rows {
            for x in 0..cols {
                let row = &mut kron[(y * cols + x) * g * g..(y * cols + x + 1) * g * g];
                for yi in 0..g {
                    for xi in 0..g {
                        row[yi * g + xi] = ry[y * g + yi] * rx[x * g + xi];
                    }
                }
            }
        }
        let kron = Tensor::<2>::from_data(TensorData::new(kron, [rows * cols, g * g]), &device);
        let class = pos.clone().slice([0..1, 0..w]);
        let patches = kron.matmul(pos.slice([1..n, 0..w]));
        Tensor::cat(vec![class, patches], 0)
    }

    /// Class token and patch tokens with their positions, after the pre-LN.
    ///
    /// # Shapes
    /// - `pixels`: `[batch, 3, rows * p, cols * p]` (normalised);
    ///   output: `[batch, 1 + rows * cols, width]`.
    pub fn tokens(&self, pixels: Tensor<4>) -> Tensor<3> {
        let [b, c, h, w] = pixels.dims();
        let p = self.patch_size;
        let (rows, cols) = (h / p, w / p);
        let patches = pixels
            .reshape([b, c, rows, p, cols, p])
            .permute([0, 2, 4, 1, 3, 5])
            .reshape([b, rows * cols, c * p * p]);
        let x = self.patch_embedding.forward(patches);
        let width = x.dims()[2];
        let class = self
            .class_embedding
            .val()
            .reshape([1, 1, width])
            .expand([b, 1, width]);
        let x = Tensor::cat(vec![class, x], 1);
        let pos = self.positions(rows, cols).unsqueeze_dim::<3>(0);
        self.pre_ln.forward(x + pos)
    }

    /// CLIP's image embedding: the class token after every block, the
    /// post-LN and the projection (not normalised).
    ///
    /// # Shapes
    /// - `pixels`: `[batch, 3, h, w]`, sides whole patches; output: `[batch, embed_dim]`.
    pub fn forward(&self, pixels: Tensor<4>) -> Tensor<2> {
        let mut x = self.tokens(pixels);
        for block in &self.blocks {
            x = block.forward(x);
        }
        let [b, _, w] = x.dims();
        let class = x.slice([0..b, 0..1, 0..w]).reshape([b, w]);
        self.projection.forward(self.post_ln.forward(class))
    }

    /// Pixel-aligned features: every block but the last as trained, the last
    /// as `variant` says, then each patch token through the post-LN and the
    /// projection, scaled to unit length.
    ///
    /// # Shapes
    /// - `pixels`: `[batch, 3, rows * p, cols * p]`; output: `[batch, rows,
    ///   cols, embed_dim]`.
    pub fn dense(&self, pixels: Tensor<4>, variant: DenseVariant) -> Tensor<4> {
        let [b, _, h, w] = pixels.dims();
        let device = pixels.device();
        let (rows, cols) = (h / self.patch_size, w / self.patch_size);
        let mut x = self.tokens(pixels);
        let Some((last, rest)) = self.blocks.split_last() else {
            panic!("a vision tower without blocks has no last block to make dense");
        };
        for block in rest {
            x = block.forward(x);
        }
        let x = dense_last_block(last, x, variant, (rows, cols), &device);
        let [_, s, width] = x.dims();
        let patches = self
            .post_ln
            .forward(x.slice([0..b, 1..s, 0..width]))
            .reshape([b * rows * cols, width]);
        let e = self.embed_dim();
        l2_normalize(self.projection.forward(patches)).reshape([b, rows, cols, e])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Distribution;

    fn tiny() -> ClipVisionConfig {
        ClipVisionConfig::new()
            .with_image_size(16)
            .with_patch_size(4)
            .with_width(8)
            .with_layers(2)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(6)
    }

    #[test]
    fn dense_maps_have_the_grid_and_unit_vectors() {
        let device = Device::flex();
        device.seed(4);
        let enc = tiny().init(&device);
        let pixels: Tensor<4> =
            Tensor::random([2, 3, 12, 20], Distribution::Normal(0.0, 1.0), &device);
        for v in DenseVariant::ALL {
            let d = enc.dense(pixels.clone(), v);
            assert_eq!(d.dims(), [2, 3, 5, 6]);
            let vals = d.try_into_vec_as::<f32>().unwrap();
            for c in vals.chunks(6) {
                let n: f32 = c.iter().map(|x| x * x).sum::<f32>().sqrt();
                assert!((n - 1.0).abs() < 1e-4, "{v}: {n}");
            }
        }
        assert_eq!(
            enc.forward(pixels.slice([0..2, 0..3, 0..16, 0..16])).dims(),
            [2, 6]
        );
    }

    #[test]
    fn maskclip_features_are_per_patch() {
        // Without attention across tokens, changing one patch changes only
        // that patch's feature.
        let device = Device::flex();
        device.seed(5);
        let enc = tiny().with_layers(1).init(&device);
        let pixels: Tensor<4> =
            Tensor::random([1, 3, 8, 8], Distribution::Normal(0.0, 1.0), &device);
        let a = enc.dense(pixels.clone(), DenseVariant::Maskclip);
        let bumped = pixels.clone().slice_assign(
            [0..1, 0..3, 4..8, 4..8],
            Tensor::ones([1, 3, 4, 4], &device),
        );
        let b = enc.dense(bumped, DenseVariant::Maskclip);
        let (a, b) = (
            a.try_into_vec_as::<f32>().unwrap(),
            b.try_into_vec_as::<f32>().unwrap(),
        );
        for cell in 0..4 {
            let diff: f32 = (0..6)
                .map(|i| (a[cell * 6 + i] - b[cell * 6 + i]).abs())
                .sum();
            assert_eq!(diff > 1e-4, cell == 3, "cell {cell}: {diff}");
        }
    }

    #[test]
    fn the_native_grid_keeps_its_positions() {
        let device = Device::flex();
        let enc = tiny().init(&device);
        let a = enc.positions(4, 4).try_into_vec_as::<f32>().unwrap();
        let b = enc
            .position_embedding
            .val()
            .try_into_vec_as::<f32>()
            .unwrap();
        assert_eq!(a, b);
        // A stretched grid keeps the class position.
        let c = enc.positions(3, 7).try_into_vec_as::<f32>().unwrap();
        assert_eq!(c.len(), (1 + 21) * 8);
        assert_eq!(&c[..8], &b[..8]);
    }
}
