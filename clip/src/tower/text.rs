//! The whole text tower: embeddings, blocks, final layer norm, end-of-text
//! pooling and the projection.

use burn::module::{Module, Param};
use burn::nn::{
    Embedding, EmbeddingConfig, Initializer, LayerNorm, LayerNormConfig, Linear, LinearConfig,
};
use burn::tensor::{Device, Int, Tensor};

use super::block::ResidualAttentionBlock;
use super::text_config::{ClipTextConfig, EotPooling};

/// CLIP's text encoder: token ids in, one embedding per sequence out.
#[derive(Module, Debug)]
pub struct ClipTextEncoder {
    /// Token embeddings, `[vocab_size, width]`.
    pub token_embedding: Embedding,
    /// Learned position embeddings, `[context_length, width]`.
    pub position_embedding: Param<Tensor<2>>,
    /// The residual attention blocks.
    pub blocks: Vec<ResidualAttentionBlock>,
    /// Layer norm after the last block.
    pub final_ln: LayerNorm,
    /// Projection into the joint space, `width -> embed_dim`, no bias.
    pub projection: Linear,
    /// Which token's output is pooled.
    #[module(skip)]
    pub pooling: EotPooling,
}

impl ClipTextConfig {
    /// A randomly initialised encoder of these sizes (normal embeddings as
    /// in CLIP; load real weights over it). Sizes are used as given: check
    /// [`ClipTextConfig::problem`] first for configurations from a file.
    pub fn init(&self, device: &Device) -> ClipTextEncoder {
        let normal = |std: f64| Initializer::Normal { mean: 0.0, std };
        ClipTextEncoder {
            token_embedding: EmbeddingConfig::new(self.vocab_size, self.width)
                .with_initializer(normal(0.02))
                .init(device),
            position_embedding: normal(0.01).init([self.context_length, self.width], device),
            blocks: (0..self.layers)
                .map(|_| ResidualAttentionBlock::new(self, device))
                .collect(),
            final_ln: LayerNormConfig::new(self.width)
                .with_epsilon(self.layer_norm_eps)
                .init(device),
            projection: LinearConfig::new(self.width, self.embed_dim)
                .with_bias(false)
                .init(device),
            pooling: self.pooling,
        }
    }
}

impl ClipTextEncoder {
    /// Maximum sequence length (number of position embeddings).
    pub fn context_length(&self) -> usize {
        self.position_embedding.dims()[0]
    }

    /// Vocabulary size.
    pub fn vocab_size(&self) -> usize {
        self.token_embedding.weight.dims()[0]
    }

    /// Output dimension.
    pub fn embed_dim(&self) -> usize {
        self.projection.weight.dims()[1]
    }

    /// The final-layer-normed output at every position (Hugging Face's
    /// `last_hidden_state`).
    ///
    /// # Shapes
    /// - `tokens`: `[batch, seq]` ids below `vocab_size`, `seq <=
    ///   context_length`; output: `[batch, seq, width]`.
    ///
    /// # Panics
    /// When `seq` exceeds the context length.
    pub fn hidden_states(&self, tokens: Tensor<2, Int>) -> Tensor<3> {
        let [_, s] = tokens.dims();
        let [ctx, w] = self.position_embedding.dims();
        assert!(s <= ctx, "{s} tokens exceed the context length {ctx}");
        let pos = self
            .position_embedding
            .val()
            .slice([0..s, 0..w])
            .reshape([1, s, w]);
        let mut x = self.token_embedding.forward(tokens) + pos;
        for block in &self.blocks {
            x = block.forward(x);
        }
        self.final_ln.forward(x)
    }

    /// The position pooled in each sequence (see [`EotPooling`]).
    ///
    /// # Shapes
    /// - `tokens`: `[batch, seq]`; output: `[batch, 1]`.
    pub fn pooled_positions(&self, tokens: Tensor<2, Int>) -> Tensor<2, Int> {
        match self.pooling {
            EotPooling::HighestId => tokens.argmax(1),
            EotPooling::EosId(eos) => {
                let [_, s] = tokens.dims();
                let device = tokens.device();
                // Score s + 1 - p at an end-of-text position p (the first
                // scores highest), plus 1 at the last position, so that a
                // sequence without end-of-text pools its last token.
                let pos = Tensor::<1, Int>::arange(0..s as i64, &device).reshape([1, s]);
                let first = tokens.equal_elem(eos as i64).int()
                    * pos.clone().neg().add_scalar(s as i64 + 1);
                let last = pos.equal_elem(s as i64 - 1).int();
                (first + last).argmax(1)
            }
        }
    }

    /// The pooled, projected embedding of each sequence (not normalised;
    /// see [`ClipTextEncoder::embed`]).
    ///
    /// # Shapes
    /// - `tokens`: `[batch, seq]`; output: `[batch, embed_dim]`.
    pub fn forward(&self, tokens: Tensor<2, Int>) -> Tensor<2> {
        let at = self.pooled_positions(tokens.clone());
        let hidden = self.hidden_states(tokens);
        let [b, _, w] = hidden.dims();
        let pooled = hidden
            .gather(1, at.reshape([b, 1, 1]).expand([b, 1, w]))
            .reshape([b, w]);
        self.projection.forward(pooled)
    }

    /// [`ClipTextEncoder::forward`], scaled to unit length (as CLIP's text
    /// embeddings are compared).
    ///
    /// # Shapes
    /// - `tokens`: `[batch, seq]`; output: `[batch, embed_dim]`.
    pub fn embed(&self, tokens: Tensor<2, Int>) -> Tensor<2> {
        l2_normalize(self.forward(tokens))
    }
}

/// Each row divided by its Euclidean norm (a zero row stays zero).
///
/// # Shapes
/// - `x`: `[n, d]`; output: `[n, d]`.
pub fn l2_normalize(x: Tensor<2>) -> Tensor<2> {
    let norm = x
        .clone()
        .powf_scalar(2.0)
        .sum_dim(1)
        .sqrt()
        .clamp_min(1e-12);
    x / norm
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::TensorData;

    fn tiny() -> ClipTextConfig {
        ClipTextConfig::new()
            .with_vocab_size(20)
            .with_context_length(6)
            .with_width(8)
            .with_layers(2)
            .with_heads(2)
            .with_mlp_width(16)
            .with_embed_dim(4)
    }

    fn ids(v: Vec<i64>, b: usize, s: usize, device: &Device) -> Tensor<2, Int> {
        Tensor::from_data(TensorData::new(v, [b, s]), device)
    }

    #[test]
    fn pooling_picks_the_end_of_text_and_ignores_what_follows() {
        let device = Device::flex();
        device.seed(1);
        let enc = tiny().init(&device);
        // End-of-text (19, the highest id) at position 3, then padding.
        let a = enc.forward(ids(vec![18, 4, 5, 19, 0, 0], 1, 6, &device));
        let b = enc.forward(ids(vec![18, 4, 5, 19, 7, 9], 1, 6, &device));
        let c = enc.forward(ids(vec![18, 4, 5, 19], 1, 4, &device));
        let (a, b, c) = (
            a.try_into_vec_as::<f32>().unwrap(),
            b.try_into_vec_as::<f32>().unwrap(),
            c.try_into_vec_as::<f32>().unwrap(),
        );
        assert_eq!(a.len(), 4);
        for i in 0..4 {
            assert!((a[i] - b[i]).abs() < 1e-6 && (a[i] - c[i]).abs() < 1e-6);
        }
        let d = enc.forward(ids(vec![18, 4, 6, 19], 1, 4, &device));
        let d = d.try_into_vec_as::<f32>().unwrap();
        assert!((0..4).any(|i| (a[i] - d[i]).abs() > 1e-4));
        let n = enc.embed(ids(vec![18, 4, 5, 19], 1, 4, &device));
        let n = n.try_into_vec_as::<f32>().unwrap();
        let len: f32 = n.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{len}");
    }

    #[test]
    fn eos_pooling_takes_the_first_eos_or_the_last_position() {
        let device = Device::flex();
        let enc = tiny().with_pooling(EotPooling::EosId(2)).init(&device);
        let at = enc.pooled_positions(ids(vec![1, 5, 2, 2, 9, 3, 4, 5], 2, 4, &device));
        let at = at.try_into_vec_as::<i64>().unwrap();
        assert_eq!(at, vec![2, 3]);
        let enc = tiny().init(&device);
        let at = enc.pooled_positions(ids(vec![1, 5, 19, 0], 1, 4, &device));
        assert_eq!(at.try_into_vec_as::<i64>().unwrap(), vec![2]);
    }
}
