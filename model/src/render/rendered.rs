//! What the inference pass returns: the fine level of the rendered rays
//! on the host, ray after ray.

/// The fine level of rendered rays, on the host, ray after ray.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderedRays {
    /// `3 n` colours (with the background behind the unoccluded part).
    pub rgb: Vec<f32>,
    /// `n` expected depths along the ray (metres of `t`).
    pub depth: Vec<f32>,
    /// `n` median depths along the ray (metres of `t`): where the
    /// accumulated weight reaches a half, or the expected depth where it
    /// never does ([`crate::composite::median_depth`]). What a depth image
    /// shows and a held-out depth error measures: on an unbounded ray the
    /// little weight a field leaves in its last interval, thousands of
    /// units long, pulls the expected depth out by metres.
    pub median_depth: Vec<f32>,
    /// `n` accumulated opacities.
    pub acc: Vec<f32>,
    /// `n * feature_dim` features (empty with [`super::FeatureMode::None`]).
    pub feature: Vec<f32>,
    /// Channels per ray of `feature`.
    pub feature_dim: usize,
    /// Samples evaluated over all levels (of `2 n samples` in all with the
    /// coarse and the fine level; the proposal rounds count too).
    pub samples_evaluated: usize,
}

impl RenderedRays {
    /// No rays, with `feature_dim` channels per feature.
    pub(super) fn empty(feature_dim: usize) -> Self {
        RenderedRays {
            feature_dim,
            ..RenderedRays::default()
        }
    }

    /// `n` rays of zeros.
    pub(super) fn zeros(n: usize, feature_dim: usize) -> Self {
        RenderedRays {
            rgb: vec![0.0; 3 * n],
            depth: vec![0.0; n],
            median_depth: vec![0.0; n],
            acc: vec![0.0; n],
            feature: vec![0.0; n * feature_dim],
            feature_dim,
            samples_evaluated: 0,
        }
    }

    /// Appends the rays of `more` (with as many feature channels).
    pub(super) fn append(&mut self, more: RenderedRays) {
        self.rgb.extend(more.rgb);
        self.depth.extend(more.depth);
        self.median_depth.extend(more.median_depth);
        self.acc.extend(more.acc);
        self.feature.extend(more.feature);
        self.samples_evaluated += more.samples_evaluated;
    }
}
