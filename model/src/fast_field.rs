//! The fast field (nerfacto's, after Instant-NGP): a multiresolution hash
//! encoding of the sample's position, a small density MLP giving the
//! density and a geometry feature, and a small colour MLP on the geometry
//! feature and a spherical-harmonics encoding of the view direction. Per
//! sample it costs about a hundredth of the Mip-NeRF trunk; the open-set
//! head reads the detached geometry feature, as it reads the detached
//! trunk of the Mip-NeRF MLP, and, where the field has one, the encoding
//! of a hash grid of its own that the feature loss alone trains (LERF's
//! and nerfacto's semantic fields keep such a grid for their features).
//!
//! The first colour layer acts on a concatenation (geometry feature, view
//! encoding and appearance code) and is stored as two linear maps whose
//! outputs are added, as the Mip-NeRF MLP's view branch is: the view part is
//! evaluated once per ray and broadcast over its samples.

use burn::config::Config;
use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::{relu, sigmoid};
use burn::tensor::{Device, Tensor, TensorData};

use crate::field::{FieldOutputs, split_linear};
use crate::hash_footprint::{isotropic_variance, level_weights, weigh_levels};
use crate::hashgrid::{HashGrid, HashGridConfig};
use crate::level_ramp::{ramp_done, ramp_weights};
use crate::sh::sh_dim;

/// Configuration of [`FastField`].
#[derive(Config, Debug)]
pub struct FastFieldConfig {
    /// The position's hash encoding (nerfacto: 16 levels of 2 features, 16
    /// to 2048 cells across, tables of 2^19 rows).
    #[config(default = "HashGridConfig::new().with_log2_table(19).with_max_resolution(2048)")]
    pub grid: HashGridConfig,
    /// Hidden layers of the density MLP.
    #[config(default = 1)]
    pub density_layers: usize,
    /// Width of the density MLP.
    #[config(default = 64)]
    pub density_width: usize,
    /// Width of the geometry feature the density MLP gives beside the
    /// density (the colour MLP's and the open-set head's input).
    #[config(default = 15)]
    pub geo_features: usize,
    /// Hidden layers of the colour MLP.
    #[config(default = 2)]
    pub color_layers: usize,
    /// Width of the colour MLP.
    #[config(default = 64)]
    pub color_width: usize,
    /// Bands of the view direction's spherical-harmonics encoding (1..=4).
    #[config(default = 4)]
    pub sh_degree: usize,
    /// Scale each hash level's features by how much of the sample's
    /// Gaussian a cell of the level resolves ([`crate::hash_footprint`]):
    /// wide samples (the coarse level's, far ones) read the coarse levels
    /// only. Off (or `None`, as in runs written before this key): every
    /// level at full weight, whatever the sample's size.
    pub footprint_weights: Option<bool>,
    /// Added to the density MLP's raw output before the exponential: a
    /// negative shift starts the field nearly empty, so that the first
    /// steps reach past the space right in front of each camera. `None`
    /// (runs written before this key): 0.
    pub density_shift: Option<f32>,
    /// A hash grid of the open-set head's own: the head reads its encoding
    /// of the sample's position beside the detached geometry feature, and
    /// the feature loss trains it (and only it: the density and colour
    /// never read it). `None` (and runs written before this key): the head
    /// reads the geometry feature alone.
    pub feature_grid: Option<HashGridConfig>,
    /// Whether the open-set head reads the detached geometry feature beside
    /// the feature grid's encoding. Off (with a feature grid): it reads the
    /// feature grid alone, and its features vary in space only as finely as
    /// that grid's finest level. `None` (and runs written before this
    /// key): on.
    pub head_reads_geometry: Option<bool>,
    /// Coarse-to-fine training ([`crate::level_ramp`]): the fraction of
    /// training by which every level of the grid reaches the MLP, a
    /// quarter of them from the start and the finer ones let in one after
    /// another. `None` or 0 (and runs written before this key): every
    /// level from the first step.
    pub coarse_to_fine: Option<f32>,
}

/// The raw output above which the density's exponential stops growing (and
/// passes no gradient): `exp(15)` is far denser than any surface needs,
/// and the bound keeps a diverging step finite.
const MAX_LOG_DENSITY: f32 = 15.0;

/// The fast field's density from the density MLP's raw output: `exp(raw)`,
/// the raw value capped at 15 (Instant-NGP's activation:
/// its range spans the orders of magnitude between empty space and a
/// surface, where a softplus would need raw values as large as the density).
///
/// # Shapes
/// - `raw`: `[n, 1]`; output: `[n, 1]`, positive.
pub fn exp_density(raw: Tensor<2>) -> Tensor<2> {
    raw.clamp_max(MAX_LOG_DENSITY).exp()
}

impl FastFieldConfig {
    /// Width of the view encoding.
    pub fn view_dim(&self) -> usize {
        sh_dim(self.sh_degree)
    }

    /// Builds the field, whose colour MLP also takes a per-photograph
    /// appearance code of `appearance_dim` numbers after the view encoding
    /// (0: none). Sizes of 0 are taken as 1.
    pub fn init(&self, appearance_dim: usize, device: &Device) -> FastField {
        let grid = self.grid.init(device);
        let encoded = self.grid.output_dim();
        let width = self.density_width.max(1);
        let geo = self.geo_features.max(1);
        let density_hidden = (0..self.density_layers)
            .map(|i| LinearConfig::new(if i == 0 { encoded } else { width }, width).init(device))
            .collect();
        let density_in = if self.density_layers == 0 {
            encoded
        } else {
            width
        };
        let color_width = self.color_width.max(1);
        let view_in = self.view_dim() + appearance_dim;
        let fan = geo + view_in;
        let color_hidden = (1..self.color_layers.max(1))
            .map(|_| LinearConfig::new(color_width, color_width).init(device))
            .collect();
        FastField {
            grid,
            density_hidden,
            density_out: LinearConfig::new(density_in, 1 + geo).init(device),
            color_geo: split_linear(geo, color_width, fan, true, device),
            color_view: split_linear(view_in, color_width, fan, false, device),
            color_hidden,
            rgb: LinearConfig::new(color_width, 3).init(device),
            sh_degree: self.sh_degree.clamp(1, crate::sh::MAX_SH_DEGREE),
            appearance_dim,
            footprint_weights: self.footprint_weights.unwrap_or(false),
            density_shift: self.density_shift.unwrap_or(0.0),
            feature_grid: self.feature_grid.as_ref().map(|g| g.init(device)),
            head_reads_geometry: self.head_reads_geometry.unwrap_or(true)
                || self.feature_grid.is_none(),
            coarse_to_fine: self.coarse_to_fine.unwrap_or(0.0),
        }
    }
}

/// The fast field: hash encoding, density MLP, colour MLP.
#[derive(Module, Debug)]
pub struct FastField {
    /// The position's hash encoding.
    pub grid: HashGrid,
    /// Hidden ReLU layers of the density MLP.
    pub density_hidden: Vec<Linear>,
    /// Raw density (first output) and geometry feature (the rest).
    pub density_out: Linear,
    /// First colour layer, the part acting on the geometry feature.
    pub color_geo: Linear,
    /// First colour layer, the part acting on the view encoding and the
    /// appearance code (no bias).
    pub color_view: Linear,
    /// Further hidden layers of the colour MLP.
    pub color_hidden: Vec<Linear>,
    /// Colour output.
    pub rgb: Linear,
    /// Bands of the view encoding.
    pub sh_degree: usize,
    /// Length of the appearance code the colour MLP takes (0: none).
    pub appearance_dim: usize,
    /// Whether the levels are weighed by the sample's footprint.
    pub footprint_weights: bool,
    /// Added to the raw density before the exponential.
    pub density_shift: f32,
    /// The open-set head's own hash grid, if the field has one.
    pub feature_grid: Option<HashGrid>,
    /// Whether the open-set head reads the geometry feature (always, where
    /// the field has no feature grid).
    pub head_reads_geometry: bool,
    /// The fraction of training by which every level reaches the MLP (0:
    /// from the first step).
    pub coarse_to_fine: f32,
}

impl FastField {
    /// Width of the geometry feature (the colour MLP's input).
    pub fn geo_features(&self) -> usize {
        self.density_out.weight.dims()[1] - 1
    }

    /// Width of the trunk feature [`FastField::trunk_density`] gives (the
    /// open-set head's input): the geometry feature, then the feature
    /// grid's encoding where the field has one.
    pub fn trunk_width(&self) -> usize {
        self.geo_features() + self.feature_grid.as_ref().map_or(0, HashGrid::output_dim)
    }

    /// Width of the open-set head's input ([`FastField::head_input`]): the
    /// geometry feature where the head reads it, then the feature grid's
    /// encoding.
    pub fn head_width(&self) -> usize {
        if self.head_reads_geometry {
            self.trunk_width()
        } else {
            self.trunk_width() - self.geo_features()
        }
    }

    /// The hash encoding of the samples' Gaussians (the field's input): of
    /// their means, each level weighed by the Gaussian's footprint where
    /// the field asks for it; then the feature grid's encoding of the
    /// means, where the field has one.
    ///
    /// # Shapes
    /// - `mean`, `cov_diag`: `[n, 3]`; output: `[n, levels * features]`
    ///   (both grids' levels).
    pub fn encode(&self, mean: Tensor<2>, cov_diag: Tensor<2>) -> Tensor<2> {
        if !self.footprint_weights {
            return self.encode_means(mean);
        }
        let mean = mean.detach();
        let weights = level_weights(
            isotropic_variance(cov_diag.detach()),
            &self.grid.resolutions,
            self.grid.half_extent,
        );
        let encoded = weigh_levels(self.grid.forward(mean.clone()), weights);
        self.with_feature_grid(encoded, mean)
    }

    /// Whether [`FastField::encode`] reads the Gaussians' covariances (to
    /// weigh the levels by their footprint); if not, [`FastField::encode_means`]
    /// gives the same encoding from the means alone.
    pub fn reads_covariance(&self) -> bool {
        self.footprint_weights
    }

    /// The encoding of the means `mean` with every level at full weight:
    /// [`FastField::encode`]'s where the field weighs no level by footprint.
    ///
    /// # Shapes
    /// - `mean`: `[n, 3]`; output: `[n, levels * features]`.
    pub fn encode_means(&self, mean: Tensor<2>) -> Tensor<2> {
        let mean = mean.detach();
        let encoded = self.grid.forward(mean.clone());
        self.with_feature_grid(encoded, mean)
    }

    /// `encoded`, then the feature grid's encoding of `mean` where the
    /// field has one.
    fn with_feature_grid(&self, encoded: Tensor<2>, mean: Tensor<2>) -> Tensor<2> {
        match &self.feature_grid {
            Some(grid) => Tensor::cat(vec![encoded, grid.forward(mean)], 1),
            None => encoded,
        }
    }

    /// `encoded` ([`FastField::encode`]'s) with the field grid's levels
    /// weighed by the coarse-to-fine ramp at `progress`, the fraction of
    /// training done ([`crate::level_ramp::ramp_weights`]); the feature
    /// grid's columns as they are. Unchanged once the ramp is done.
    ///
    /// # Shapes
    /// - `encoded`: `[n, width]`; output: as `encoded`.
    pub fn ramp_levels(&self, encoded: Tensor<2>, progress: f32) -> Tensor<2> {
        if ramp_done(progress, self.coarse_to_fine) {
            return encoded;
        }
        let levels = self.grid.resolutions.len();
        let features = self.grid.output_dim() / levels.max(1);
        let [_, width] = encoded.dims();
        let mut scale = vec![1.0f32; width];
        for (l, w) in ramp_weights(levels, progress, self.coarse_to_fine)
            .into_iter()
            .enumerate()
        {
            scale[l * features..(l + 1) * features].fill(w);
        }
        let scale = Tensor::<2>::from_data(TensorData::new(scale, [1, width]), &encoded.device());
        encoded.mul(scale)
    }

    /// Trunk feature (the geometry feature, then the feature grid's
    /// encoding where the field has one) and density from the encoding
    /// ([`FastField::encode`]).
    ///
    /// # Shapes
    /// - `encoded`: `[n, levels * features]`; output: (`[n,
    ///   trunk_width]`, `[n, 1]`).
    pub fn trunk_density(&self, encoded: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let field_dim = self.grid.output_dim();
        let [_, encoded_dim] = encoded.dims();
        // Without a feature grid the encoding is the field grid's alone and
        // goes to the density MLP as it is (no slicing op in the step).
        let (mut h, feature) = if encoded_dim > field_dim {
            let feature = encoded
                .clone()
                .narrow(1, field_dim, encoded_dim - field_dim);
            (encoded.narrow(1, 0, field_dim), Some(feature))
        } else {
            (encoded, None)
        };
        for layer in &self.density_hidden {
            h = relu(layer.forward(h));
        }
        let out = self.density_out.forward(h);
        let [_, width] = out.dims();
        let density = exp_density(out.clone().narrow(1, 0, 1).add_scalar(self.density_shift));
        let geo = out.narrow(1, 1, width - 1);
        let trunk = match feature {
            Some(feature) => Tensor::cat(vec![geo, feature], 1),
            None => geo,
        };
        (trunk, density)
    }

    /// The open-set head's input from the trunk feature: the geometry
    /// feature detached (the head does not shape the geometry), unless the
    /// head reads the feature grid alone; the feature grid's encoding
    /// attached (the feature loss trains it).
    ///
    /// # Shapes
    /// - `trunk`: `[n, trunk_width]`; output: `[n, head_width]`.
    pub fn head_input(&self, trunk: Tensor<2>) -> Tensor<2> {
        let geo = self.geo_features();
        let [_, width] = trunk.dims();
        if width == geo {
            return trunk.detach();
        }
        let feature = trunk.clone().narrow(1, geo, width - geo);
        if !self.head_reads_geometry {
            return feature;
        }
        Tensor::cat(vec![trunk.narrow(1, 0, geo).detach(), feature], 1)
    }

    /// View-dependent colour from the geometry feature (the trunk
    /// feature's first `geo_features` columns).
    ///
    /// # Shapes
    /// - `trunk`: `[rays * samples, trunk_width]`, ray-major.
    /// - `view_enc`: `[rays, sh_dim + appearance_dim]`.
    /// - output: `[rays * samples, 3]`, in `[0, 1]`.
    pub fn color(&self, trunk: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> Tensor<2> {
        let [n, width] = trunk.dims();
        let geo_width = self.geo_features();
        let geo = if width == geo_width {
            trunk
        } else {
            trunk.narrow(1, 0, geo_width)
        };
        let rays = n / samples.max(1);
        let g = self.color_geo.forward(geo);
        let [_, width] = g.dims();
        let v = self.color_view.forward(view_enc).unsqueeze_dim::<3>(1);
        let mut h = relu(g.reshape([rays, samples, width]).add(v)).reshape([n, width]);
        for layer in &self.color_hidden {
            h = relu(layer.forward(h));
        }
        sigmoid(self.rgb.forward(h))
    }

    /// Full evaluation on `rays * samples` encoded samples.
    ///
    /// # Shapes
    /// - `encoded`: `[rays * samples, levels * features]`, ray-major;
    ///   `view_enc`: `[rays, sh_dim + appearance_dim]`.
    pub fn forward(&self, encoded: Tensor<2>, view_enc: Tensor<2>, samples: usize) -> FieldOutputs {
        let (trunk, density) = self.trunk_density(encoded);
        let rgb = self.color(trunk.clone(), view_enc, samples);
        FieldOutputs {
            trunk,
            density,
            rgb,
        }
    }
}
