//! Multi-head self-attention: with a causal mask in CLIP's text tower,
//! over every token in its vision tower.

use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::softmax;
use burn::tensor::{Bool, Device, Tensor};

/// Multi-head self-attention. Causal (the text tower): every position
/// attends to itself and the positions before it; otherwise (the vision
/// tower) to every position. Queries are scaled by `1 / sqrt(head_dim)`.
/// Four separate projections, as Hugging Face stores them (OpenCLIP's packed
/// `in_proj_weight` is split into these when loading).
#[derive(Module, Debug)]
pub struct CausalSelfAttention {
    /// Query projection, `width -> width`.
    pub q_proj: Linear,
    /// Key projection, `width -> width`.
    pub k_proj: Linear,
    /// Value projection, `width -> width`.
    pub v_proj: Linear,
    /// Output projection, `width -> width`.
    pub out_proj: Linear,
    /// Number of heads.
    pub heads: usize,
    /// Whether a position sees only itself and earlier ones.
    #[module(skip)]
    pub causal: bool,
}

impl CausalSelfAttention {
    /// An attention layer of `width` channels in `heads` heads (`heads`
    /// must divide `width`; see [`super::ClipTextConfig::problem`]).
    pub fn new(width: usize, heads: usize, device: &Device) -> Self {
        Self::with_mask(width, heads, true, device)
    }

    /// [`CausalSelfAttention::new`], causal or not.
    pub fn with_mask(width: usize, heads: usize, causal: bool, device: &Device) -> Self {
        let linear = || LinearConfig::new(width, width).init(device);
        Self {
            q_proj: linear(),
            k_proj: linear(),
            v_proj: linear(),
            out_proj: linear(),
            heads: heads.max(1),
            causal,
        }
    }

    /// Splits channels into heads.
    ///
    /// # Shapes
    /// - `t`: `[batch, seq, width]`; output: `[batch, heads, seq, width / heads]`.
    pub fn split_heads(&self, t: Tensor<3>) -> Tensor<4> {
        let [b, s, w] = t.dims();
        t.reshape([b, s, self.heads, w / self.heads])
            .swap_dims(1, 2)
    }

    /// The inverse of [`CausalSelfAttention::split_heads`].
    ///
    /// # Shapes
    /// - `t`: `[batch, heads, seq, head_dim]`; output: `[batch, seq, heads * head_dim]`.
    pub fn merge_heads(&self, t: Tensor<4>) -> Tensor<3> {
        let [b, h, s, d] = t.dims();
        t.swap_dims(1, 2).reshape([b, s, h * d])
    }

    /// Attention of every position over itself and the earlier positions.
    ///
    /// # Shapes
    /// - `x`: `[batch, seq, width]`; output: `[batch, seq, width]`.
    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let [_, s, w] = x.dims();
        let device = x.device();
        let d = w / self.heads;
        let q = self.split_heads(
            self.q_proj
                .forward(x.clone())
                .mul_scalar(1.0 / (d as f64).sqrt()),
        );
        let k = self.split_heads(self.k_proj.forward(x.clone()));
        let v = self.split_heads(self.v_proj.forward(x));
        let mut scores = q.matmul(k.swap_dims(2, 3));
        if self.causal {
            scores = scores + causal_bias(s, &device);
        }
        let attn = softmax(scores, 3);
        self.out_proj.forward(self.merge_heads(attn.matmul(v)))
    }
}

/// The additive causal mask, `[1, 1, s, s]`: 0 on and below the diagonal,
/// `-inf` above it (a position never attends to a later one).
fn causal_bias(s: usize, device: &Device) -> Tensor<4> {
    let later: Tensor<2, Bool> = Tensor::tril_mask([s, s], 0, device);
    Tensor::<2>::zeros([s, s], device)
        .mask_fill(later, f32::NEG_INFINITY)
        .reshape([1, 1, s, s])
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::{Distribution, TensorData};

    #[test]
    fn a_position_never_sees_later_ones() {
        let device = Device::flex();
        device.seed(3);
        let attn = CausalSelfAttention::new(8, 2, &device);
        let x: Tensor<3> = Tensor::random([1, 4, 8], Distribution::Normal(0.0, 1.0), &device);
        let y = attn.forward(x.clone()).try_into_vec_as::<f32>().unwrap();
        // Changing the last position leaves the outputs of the others alone.
        let mut v = x.clone().try_into_vec_as::<f32>().unwrap();
        for e in &mut v[24..32] {
            *e += 5.0;
        }
        let x2 = Tensor::<3>::from_data(TensorData::new(v, [1, 4, 8]), &device);
        let y2 = attn.forward(x2).try_into_vec_as::<f32>().unwrap();
        for i in 0..24 {
            assert!((y[i] - y2[i]).abs() < 1e-6, "{i}: {} vs {}", y[i], y2[i]);
        }
        assert!((24..32).any(|i| (y[i] - y2[i]).abs() > 1e-3));
        // The first position attends to itself alone: its output is the value
        // of its own input, projected out.
        let first = x.clone().slice([0..1, 0..1, 0..8]);
        let v0 = attn.out_proj.forward(attn.v_proj.forward(first));
        let v0 = v0.try_into_vec_as::<f32>().unwrap();
        for i in 0..8 {
            assert!((y[i] - v0[i]).abs() < 1e-5, "{i}");
        }
    }
}
