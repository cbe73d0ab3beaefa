//! Step functions along rays against f64 host references: the interlevel
//! and distortion losses against brute-force evaluations of their
//! definitions, the proposal weights' dilation and annealing, and the
//! resampling (inverse-CDF sampling, one proposal round) in its host and
//! tensor forms.
// Index loops mirror the formulas in these reference computations.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{assert_close, devices, tensor, vec};
use model::stepfun::{
    anneal_exponent, anneal_weights, distortion_loss, interlevel_loss, max_dilate_weights,
    max_dilate_weights_host,
};

/// The step-function losses and proposal helpers.
#[path = "stepfun/losses.rs"]
mod losses;

/// The proposal sampler's resampling on the host and on the device.
#[path = "stepfun/resample.rs"]
mod resample;
