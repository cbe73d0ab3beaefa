//! The tiny field the viewer's tests serve: a 2 x 16 trunk, a one-layer
//! head to `dim` channels, 4 + 4 samples a ray.

use burn::tensor::Device;
use model::{FeatureHeadConfig, MipMlpConfig, OpenNerf, OpenNerfConfig};

pub fn tiny_model(dim: usize, device: &Device) -> OpenNerf {
    OpenNerfConfig::new(FeatureHeadConfig::new(dim).with_width(8).with_layers(1))
        .with_mlp(
            MipMlpConfig::new()
                .with_width(16)
                .with_depth(2)
                .with_skip_layer(1)
                .with_max_deg(4),
        )
        .with_num_samples(4)
        .init(device)
}
