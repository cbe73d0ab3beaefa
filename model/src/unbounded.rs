//! The math of unbounded scenes (Mip-NeRF 360): the scene contraction and
//! Gaussians pushed through it ([`mod@contract`]), the normalised-disparity
//! ray parameterisation ([`spacing`]), and an unbounded scene's
//! configuration: its bounds and its frustums in contracted coordinates
//! ([`scene`]). The step functions the proposal sampler resamples and the
//! losses it learns from are [`crate::stepfun`]'s, shared with the box.
//!
//! Everything but the configuration is a pure, differentiable function on
//! tensors; [`crate::Extent::Unbounded`] composes them.

pub mod contract;
pub mod scene;
pub mod spacing;

pub use contract::{
    NORM_EPS, cast_rays_contracted, contract, contract_gaussian, contract_jacobian, cov_diagonal,
    frustum_covariance,
};
pub use scene::{CONTRACTED_SCALE, UnboundedConfig};
pub use spacing::{s_to_t, t_to_s};
