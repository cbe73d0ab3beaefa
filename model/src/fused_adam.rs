//! Adam in one pass over each parameter on the flex backend.
//!
//! Burn's Adam takes a dozen element-wise tensor operations a parameter a
//! step, each a pass over memory. Over the hash grids' tables (a million
//! numbers or more) those passes are a large part of a small field's step
//! on a CPU, so on flex [`FusedAdam`] reads each parameter, its gradient
//! and its two moments once and writes them back in place. It computes
//! the same operations in the same order as Burn's Adam, so parameters
//! and moments come out bit for bit the same, and it keeps Burn's state
//! type, so an optimiser record saved by either loads into the other. On
//! other backends it is Burn's Adam.

// ndarray is deprecated upstream; the workspace keeps it as the reference
// CPU backend, so the extension routes to it too.
#![allow(deprecated)]

use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, Dispatch, Flex, TensorMetadata, backend_extension};
use burn::config::Config;
use burn::optim::{
    Adam, AdamConfig, AdamState, AdaptiveMomentumState, LearningRate, ModuleOptimizer, Optimizer,
};
use burn::tensor::{DType, Device, Tensor, TensorData};
use rayon::prelude::*;

use crate::hash_kernel::host;
use crate::host_work::is_cpu_backend;

/// Adam's hyper-parameters; Burn's defaults.
#[derive(Config, Debug)]
pub struct FusedAdamConfig {
    /// Decay of the first moment.
    #[config(default = 0.9)]
    pub beta_1: f32,
    /// Decay of the second moment.
    #[config(default = 0.999)]
    pub beta_2: f32,
    /// Added to the second moment's root.
    #[config(default = 1e-5)]
    pub epsilon: f32,
}

impl FusedAdamConfig {
    /// The optimiser of every parameter of a module.
    pub fn init(&self) -> ModuleOptimizer {
        ModuleOptimizer::from(FusedAdam {
            config: self.clone(),
        })
    }

    /// Burn's Adam of the same hyper-parameters, for the backends without
    /// the one-pass form.
    fn tensor_ops(&self) -> Adam {
        AdamConfig::new()
            .with_beta_1(self.beta_1)
            .with_beta_2(self.beta_2)
            .with_epsilon(self.epsilon)
            .build()
    }
}

/// Adam, one pass a parameter on flex ([module docs](self)).
#[derive(Clone)]
pub struct FusedAdam {
    config: FusedAdamConfig,
}

/// The scalars of one step, computed as Burn's Adam computes them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamStep {
    /// `beta_1`.
    pub beta_1: f32,
    /// `1 - beta_1`.
    pub one_minus_beta_1: f32,
    /// `beta_2`.
    pub beta_2: f32,
    /// `1 - beta_2`.
    pub one_minus_beta_2: f32,
    /// `sqrt(1 - beta_2^t) / (1 - beta_1^t)`.
    pub combined: f32,
    /// `epsilon * sqrt(1 - beta_2^t)`.
    pub epsilon: f32,
    /// The learning rate.
    pub lr: f32,
}

impl AdamStep {
    /// The scalars of step `time` (1 for the first) at learning rate `lr`.
    pub fn new(config: &FusedAdamConfig, time: usize, lr: LearningRate) -> Self {
        let t = time as i32;
        let bias_correction2_sqrt = (1.0 - config.beta_2.powi(t)).sqrt();
        Self {
            beta_1: config.beta_1,
            one_minus_beta_1: 1.0 - config.beta_1,
            beta_2: config.beta_2,
            one_minus_beta_2: 1.0 - config.beta_2,
            combined: bias_correction2_sqrt / (1.0 - config.beta_1.powi(t)),
            epsilon: config.epsilon * bias_correction2_sqrt,
            lr: lr as f32,
        }
    }
}

/// Numbers a parallel task of the update takes.
const CHUNK: usize = 1 << 14;

/// One step of Adam over flat slices, in place: the moments first (on the
/// first step, `first`, from zero), then the parameter.
pub fn adam_in_place(
    param: &mut [f32],
    grad: &[f32],
    moment_1: &mut [f32],
    moment_2: &mut [f32],
    step: &AdamStep,
    first: bool,
) {
    // Compiled for the widest SIMD the CPU has: the loop vectorises with
    // the same operations, so the results do not depend on the width.
    let arch = pulp::Arch::new();
    let run = |p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32]| {
        arch.dispatch(
            #[inline(always)]
            || adam_chunk(p, g, m, v, step, first),
        )
    };
    if param.len() <= CHUNK {
        run(param, grad, moment_1, moment_2);
        return;
    }
    param
        .par_chunks_mut(CHUNK)
        .zip(grad.par_chunks(CHUNK))
        .zip(moment_1.par_chunks_mut(CHUNK))
        .zip(moment_2.par_chunks_mut(CHUNK))
        .for_each(|(((p, g), m), v)| run(p, g, m, v));
}

/// [`adam_in_place`] on one chunk.
#[inline(always)]
fn adam_chunk(
    param: &mut [f32],
    grad: &[f32],
    moment_1: &mut [f32],
    moment_2: &mut [f32],
    step: &AdamStep,
    first: bool,
) {
    let iter = param
        .iter_mut()
        .zip(grad)
        .zip(moment_1.iter_mut())
        .zip(moment_2.iter_mut());
    for (((p, &g), m), v) in iter {
        // Burn's operations in Burn's order: `m b1 + g (1 - b1)`,
        // `v b2 + g^2 (1 - b2)`, `(m c) / (sqrt(v) + eps)`, times lr.
        if first {
            *m = g * step.one_minus_beta_1;
            *v = (g * g) * step.one_minus_beta_2;
        } else {
            *m = *m * step.beta_1 + g * step.one_minus_beta_1;
            *v = *v * step.beta_2 + (g * g) * step.one_minus_beta_2;
        }
        let update = (*m * step.combined) / (v.sqrt() + step.epsilon);
        *p -= update * step.lr;
    }
}

/// Adam's step as one backend operation on flat tensors.
#[backend_extension(Flex, NdArray)]
pub trait AdamKernel: Backend {
    /// The parameter and moments after a step from `moment_1` and
    /// `moment_2` ([`adam_in_place`]).
    fn adam_update(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        moment_1: FloatTensor<Self>,
        moment_2: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        copied_step::<Self>(param, grad, Some((moment_1, moment_2)), step)
    }

    /// The parameter and moments after the first step ([`adam_in_place`]).
    fn adam_first(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        copied_step::<Self>(param, grad, None, step)
    }
}

/// [`adam_in_place`] on copies of the tensors' values (any CPU backend),
/// from `moments`, or from zero on the first step (`None`).
fn copied_step<B: Backend>(
    param: FloatTensor<B>,
    grad: FloatTensor<B>,
    moments: Option<(FloatTensor<B>, FloatTensor<B>)>,
    step: AdamStep,
) -> (FloatTensor<B>, FloatTensor<B>, FloatTensor<B>) {
    let device = param.device();
    let (mut p, g) = (host::<B>(param), host::<B>(grad));
    let first = moments.is_none();
    let (mut m, mut v) = match moments {
        Some((m, v)) => (host::<B>(m), host::<B>(v)),
        None => (vec![0.0; g.len()], vec![0.0; g.len()]),
    };
    adam_in_place(&mut p, &g, &mut m, &mut v, &step, first);
    let [p, m, v] = [p, m, v].map(|x| back::<B>(x, &device));
    (p, m, v)
}

/// A flat tensor of `values` on `device`.
fn back<B: Backend>(values: Vec<f32>, device: &B::Device) -> FloatTensor<B> {
    let n = values.len();
    B::float_from_data(TensorData::new(values, [n]), device)
}

impl AdamKernel for burn::backend::NdArray {}

/// `t` with a buffer of exactly its values, contiguous from the start, so
/// that its storage is its values in order.
fn dense(t: FloatTensor<Flex>) -> FloatTensor<Flex> {
    let exact = t.layout().num_elements() * size_of::<f32>() == t.bytes().len();
    if t.is_contiguous() && t.layout().start_offset() == 0 && exact {
        t
    } else {
        Flex::float_from_data(t.into_data(), &Default::default())
    }
}

/// flex updates the tensors' own memory (copied first where shared).
impl AdamKernel for Flex {
    fn adam_update(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        moment_1: FloatTensor<Self>,
        moment_2: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        flex_step(param, grad, moment_1, moment_2, step, false)
    }

    fn adam_first(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        let n = grad.shape().num_elements();
        let zeros = || back::<Self>(vec![0.0; n], &Default::default());
        flex_step(param, grad, zeros(), zeros(), step, true)
    }
}

/// [`adam_in_place`] on flex tensors' memory; tensors not of f32 on copies.
fn flex_step(
    param: FloatTensor<Flex>,
    grad: FloatTensor<Flex>,
    moment_1: FloatTensor<Flex>,
    moment_2: FloatTensor<Flex>,
    step: AdamStep,
    first: bool,
) -> (FloatTensor<Flex>, FloatTensor<Flex>, FloatTensor<Flex>) {
    let tensors = [param, grad, moment_1, moment_2];
    if tensors.iter().any(|t| t.dtype() != DType::F32) {
        let [p, g, m, v] = tensors;
        let moments = (!first).then_some((m, v));
        return copied_step::<Flex>(p, g, moments, step);
    }
    let [mut p, g, mut m, mut v] = tensors.map(dense);
    adam_in_place(
        p.storage_mut::<f32>(),
        g.storage::<f32>(),
        m.storage_mut::<f32>(),
        v.storage_mut::<f32>(),
        &step,
        first,
    );
    (p, m, v)
}

impl Optimizer for FusedAdam {
    type State<const D: usize> = AdamState<D>;

    fn step<const D: usize>(
        &self,
        lr: LearningRate,
        tensor: Tensor<D>,
        grad: Tensor<D>,
        state: Option<Self::State<D>>,
    ) -> (Tensor<D>, Option<Self::State<D>>) {
        // The optimiser's tensors are the parameters' inner values (no
        // autodiff); other backends take Burn's Adam.
        let device = tensor.device();
        if !is_cpu_backend(&device) || device.is_autodiff() {
            return self.config.tensor_ops().step(lr, tensor, grad, state);
        }
        let time = state.as_ref().map_or(1, |s| s.momentum.time + 1);
        let step = AdamStep::new(&self.config, time, lr);
        let shape = tensor.shape();
        let n = shape.num_elements();
        let flat = |t: Tensor<D>| t.reshape([n]).into_dispatch();
        let (p, m, v) = match state {
            Some(s) => Dispatch::adam_update(
                flat(tensor),
                flat(grad),
                flat(s.momentum.moment_1),
                flat(s.momentum.moment_2),
                step,
            ),
            None => Dispatch::adam_first(flat(tensor), flat(grad), step),
        };
        let shaped = |t| Tensor::<1>::from_dispatch(t).reshape(shape.clone());
        let momentum = AdaptiveMomentumState::new(time, shaped(m), shaped(v));
        (shaped(p), Some(AdamState::new(momentum)))
    }

    fn to_device<const D: usize>(state: Self::State<D>, device: &Device) -> Self::State<D> {
        <Adam as Optimizer>::to_device(state, device)
    }
}
