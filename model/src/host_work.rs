//! Which backends do the non-differentiable bookkeeping of a step (the hash
//! encoding's corners, the proposal rounds' resampling) on the host, and the
//! one function every such host read of the model goes through.
//!
//! On the CPU backends the host loops are the faster form: their tensor
//! ops write every intermediate to memory where a loop keeps it in
//! registers (measured in docs/measurements/training-step.md). On a GPU the tensor form
//! is the one to use: the host form would wait for the device's queue to
//! drain to read its inputs back, every step.

use burn::tensor::{Device, Tensor};

/// Whether `device` is one of the CPU backends (flex, ndarray).
pub fn is_cpu_backend(device: &Device) -> bool {
    // Burn 0.22's `Device` keeps its backend behind an opaque type; its
    // debug form names it (`Flex(Cpu)`, `NdArray(Cpu)`, `Cube(..)`), also
    // inside `Autodiff { device: .. }`.
    let name = format!("{:?}", device.as_dispatch());
    name.contains("Flex(") || name.contains("NdArray(")
}

/// The values of `t` on the host, as `f32` (detached). On a GPU this waits
/// for the device's queue to drain: the training step calls it only on the
/// CPU backends ([`is_cpu_backend`]); inference's early ray termination
/// reads its alive rays back once a segment of samples.
pub fn read_back<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.detach()
        .into_data()
        .try_into_vec_as::<f32>()
        .expect("a float tensor converts to f32")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_backends_are_told_apart_with_and_without_autodiff() {
        assert!(is_cpu_backend(&Device::flex()));
        assert!(is_cpu_backend(&Device::flex().autodiff()));
        #[allow(deprecated)]
        let ndarray = Device::ndarray();
        assert!(is_cpu_backend(&ndarray));
        assert!(is_cpu_backend(&ndarray.autodiff()));
    }
}
