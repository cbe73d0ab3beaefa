//! The math of unbounded scenes (Mip-NeRF 360): the scene contraction and
//! Gaussians pushed through it ([`mod@contract`]), the normalised-disparity ray
//! parameterisation ([`spacing`]), and the proposal (interlevel) and
//! distortion losses with the proposal-weight helpers ([`stepfun`], and
//! the dilation and the resampling on the host, [`mod@dilate`],
//! [`mod@resample`], and one proposal round in either form, [`rounds`]), and an
//! unbounded scene's configuration with the ray coordinate `s` ([`scene`]).
//!
//! Everything but the configuration is a pure, differentiable function on
//! tensors; [`crate::OpenNerf`] composes them when its configuration has
//! an [`UnboundedConfig`].

pub mod contract;
pub mod dilate;
pub mod resample;
pub mod rounds;
pub mod scene;
pub mod spacing;
pub mod stepfun;

pub use contract::{
    NORM_EPS, cast_rays_contracted, contract, contract_gaussian, contract_jacobian, cov_diagonal,
    frustum_covariance,
};
pub use dilate::max_dilate_weights_host;
pub use resample::{anneal_weights_host, sample_pdf_host};
pub use scene::{CONTRACTED_SCALE, UnboundedConfig};
pub use spacing::{s_to_t, t_to_s};
pub use stepfun::{
    INTERLEVEL_EPS, anneal_exponent, anneal_weights, distortion_loss, interlevel_loss,
    max_dilate_weights, outer_measure,
};
