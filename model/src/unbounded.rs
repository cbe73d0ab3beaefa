//! The math of unbounded scenes (Mip-NeRF 360): the scene contraction and
//! Gaussians pushed through it ([`mod@contract`]), the normalised-disparity ray
//! parameterisation ([`spacing`]), and the proposal (interlevel) and
//! distortion losses with the proposal-weight helpers ([`stepfun`]).
//!
//! Everything is a pure, differentiable function on tensors; nothing here is
//! wired into [`crate::OpenNerf`].

pub mod contract;
pub mod spacing;
pub mod stepfun;

pub use contract::{
    NORM_EPS, cast_rays_contracted, contract, contract_gaussian, contract_jacobian, cov_diagonal,
    frustum_covariance,
};
pub use spacing::{s_to_t, t_to_s};
pub use stepfun::{
    INTERLEVEL_EPS, anneal_exponent, anneal_weights, distortion_loss, interlevel_loss,
    max_dilate_weights, outer_measure,
};
