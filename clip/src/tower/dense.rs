//! The training-free dense variants of a ViT's last block (NACLIP,
//! ClearCLIP, MaskCLIP): patch tokens that stay aligned with their pixels
//! instead of pooling the image into the class token.

use burn::tensor::activation::softmax;
use burn::tensor::{Device, Tensor, TensorData};

use super::DenseVariant;
use super::block::ResidualAttentionBlock;

/// NACLIP's additive attention bias for a `rows x cols` patch grid behind a
/// class token, `[(1 + n)^2]` row-major with `n = rows * cols`: zero on the
/// class token's row and column; `exp(-d^2 / (2 std^2))` between two
/// patches `d` patches apart (1 on the diagonal).
pub fn gaussian_window_bias(rows: usize, cols: usize, std: f64) -> Vec<f32> {
    let n = rows * cols;
    let s = n + 1;
    let mut out = vec![0f32; s * s];
    let denom = 2.0 * std * std;
    for q in 0..n {
        let (qy, qx) = ((q / cols) as f64, (q % cols) as f64);
        for k in 0..n {
            let (ky, kx) = ((k / cols) as f64, (k % cols) as f64);
            let d2 = (qy - ky).powi(2) + (qx - kx).powi(2);
            out[(q + 1) * s + k + 1] = (-d2 / denom).exp() as f32;
        }
    }
    out
}

/// The last block as `variant` runs it: no residual connection, no MLP.
/// `grid` is the patch grid behind the class token (NACLIP's window).
///
/// # Shapes
/// - `x`: `[batch, 1 + rows * cols, width]` (the block's input); output:
///   the same.
pub fn dense_last_block(
    block: &ResidualAttentionBlock,
    x: Tensor<3>,
    variant: DenseVariant,
    grid: (usize, usize),
    device: &Device,
) -> Tensor<3> {
    let attn = &block.attn;
    let h = block.ln1.forward(x);
    let [_, s, w] = h.dims();
    let scale = 1.0 / ((w / attn.heads) as f64).sqrt();
    let v = attn.v_proj.forward(h.clone());
    let logits = match variant {
        DenseVariant::Maskclip => return attn.out_proj.forward(v),
        DenseVariant::Naclip => {
            let k = attn.split_heads(attn.k_proj.forward(h));
            let bias = gaussian_window_bias(grid.0, grid.1, super::vision_config::NACLIP_STD);
            let bias = Tensor::<2>::from_data(TensorData::new(bias, [s, s]), device);
            k.clone().matmul(k.swap_dims(2, 3)).mul_scalar(scale) + bias.reshape([1, 1, s, s])
        }
        DenseVariant::Clearclip => {
            let q = attn.split_heads(attn.q_proj.forward(h));
            q.clone().matmul(q.swap_dims(2, 3)).mul_scalar(scale)
        }
    };
    let out = softmax(logits, 3).matmul(attn.split_heads(v));
    attn.out_proj.forward(attn.merge_heads(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_a_gaussian_of_patch_distance_and_spares_the_class_token() {
        let (rows, cols) = (3, 4);
        let b = gaussian_window_bias(rows, cols, 5.0);
        let s = rows * cols + 1;
        assert_eq!(b.len(), s * s);
        for i in 0..s {
            assert_eq!(b[i], 0.0);
            assert_eq!(b[i * s], 0.0);
        }
        // Patch (0, 0) and patch (2, 3): squared distance 4 + 9.
        let (q, k) = (1, 1 + 2 * cols + 3);
        let want = (-13.0f64 / 50.0).exp() as f32;
        assert!((b[q * s + k] - want).abs() < 1e-7);
        assert!((b[k * s + q] - want).abs() < 1e-7);
        for p in 1..s {
            assert_eq!(b[p * s + p], 1.0);
        }
    }
}
