//! Which backends do the non-differentiable bookkeeping of a step (the hash
//! encoding's corners, the fine level's and the proposal rounds'
//! resampling) on the host, and the
//! one function every host read of a tensor goes through ([`read_back`]),
//! which counts the reads of its thread by [`ReadReason`] ([`read_backs`]).
//!
//! On the CPU backends the host loops are the faster form: their tensor
//! ops write every intermediate to memory where a loop keeps it in
//! registers (measured in docs/measurements/training-step.md). On a GPU the tensor form
//! is the one to use: the host form would wait for the device's queue to
//! drain to read its inputs back, every step.

use std::cell::RefCell;

use burn::tensor::{Device, Tensor};

/// Why a tensor is read back to the host; every read is counted under one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ReadReason {
    /// The hash encoding's corners computed on the host (the CPU backends'
    /// form, [`is_cpu_backend`]).
    HashCorners,
    /// A proposal round's resampling on the host (the CPU backends' form).
    ProposalRound,
    /// The fine level's blur-resample on the host (the CPU backends'
    /// form).
    FineResample,
    /// The occupancy grid's refresh from the field's density.
    OccupancyUpdate,
    /// The values a training step measured (loss terms, gradient norm),
    /// read by the training loop when it logs or checks them.
    StepValues,
    /// Rendering, querying or evaluating a trained field (not a training
    /// step).
    Inference,
}

impl ReadReason {
    /// Every reason, in counting order.
    pub const ALL: [ReadReason; 6] = [
        ReadReason::HashCorners,
        ReadReason::ProposalRound,
        ReadReason::FineResample,
        ReadReason::OccupancyUpdate,
        ReadReason::StepValues,
        ReadReason::Inference,
    ];

    /// Whether a training step reads for this reason only as the CPU
    /// backends' faster form of work a GPU does with tensor ops.
    pub fn is_cpu_form(self) -> bool {
        matches!(
            self,
            ReadReason::HashCorners | ReadReason::ProposalRound | ReadReason::FineResample
        )
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// The read-backs of one thread, by reason: a snapshot from [`read_backs`];
/// subtract two ([`ReadBacks::since`]) to count what a piece of work read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadBacks {
    counts: [u64; ReadReason::ALL.len()],
}

impl ReadBacks {
    /// Reads for `reason`.
    pub fn of(&self, reason: ReadReason) -> u64 {
        self.counts[reason.index()]
    }

    /// Reads for every reason together.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// The reads made after `earlier` (a snapshot of the same thread).
    pub fn since(&self, earlier: &ReadBacks) -> ReadBacks {
        let mut counts = self.counts;
        for (c, e) in counts.iter_mut().zip(earlier.counts) {
            *c -= e;
        }
        ReadBacks { counts }
    }

    /// The reasons read for, with their counts (none when nothing was read).
    pub fn nonzero(&self) -> Vec<(ReadReason, u64)> {
        ReadReason::ALL
            .iter()
            .map(|&r| (r, self.of(r)))
            .filter(|&(_, n)| n > 0)
            .collect()
    }
}

thread_local! {
    // Always on: one increment beside a read that waits for the device is
    // free, and tests of release builds count the real binary's reads.
    static READS: RefCell<ReadBacks> = RefCell::new(ReadBacks::default());
}

/// The read-backs this thread has made so far (see [`ReadBacks::since`]).
pub fn read_backs() -> ReadBacks {
    READS.with(|r| *r.borrow())
}

/// Whether `device` is one of the CPU backends (flex, ndarray).
pub fn is_cpu_backend(device: &Device) -> bool {
    // Burn 0.22's `Device` keeps its backend behind an opaque type; its
    // debug form names it (`Flex(Cpu)`, `NdArray(Cpu)`, `Cube(..)`), also
    // inside `Autodiff { device: .. }`.
    let name = format!("{:?}", device.as_dispatch());
    name.contains("Flex(") || name.contains("NdArray(")
}

/// Counts a read of the host's copy of a tensor under `reason`, made by a
/// CPU backend's operation on its own memory (no device to wait for).
pub fn count_host_read(reason: ReadReason) {
    READS.with(|r| r.borrow_mut().counts[reason.index()] += 1);
}

/// The values of `t` on the host, as `f32` (detached), counted under
/// `reason`. On a GPU this waits for the device's queue to drain: the
/// training step reads nothing (the loop reads its values when it logs),
/// the hash encoding, the fine level's resampling and the proposal rounds
/// read only on the CPU backends
/// ([`is_cpu_backend`]); inference's early ray termination reads its alive
/// rays back once a segment of samples.
pub fn read_back<const D: usize>(reason: ReadReason, t: Tensor<D>) -> Vec<f32> {
    count_host_read(reason);
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

    #[test]
    fn reads_are_counted_by_reason_on_their_own_thread() {
        let device = Device::flex();
        let start = read_backs();
        let t = Tensor::<1>::from_floats([1.0, 2.0], &device);
        assert_eq!(read_back(ReadReason::Inference, t.clone()), vec![1.0, 2.0]);
        read_back(ReadReason::StepValues, t.clone());
        read_back(ReadReason::StepValues, t.clone());
        let done = read_backs().since(&start);
        assert_eq!(done.of(ReadReason::Inference), 1);
        assert_eq!(done.of(ReadReason::StepValues), 2);
        assert_eq!(done.total(), 3);
        assert_eq!(
            done.nonzero(),
            vec![(ReadReason::StepValues, 2), (ReadReason::Inference, 1)]
        );
        let other = std::thread::spawn(move || {
            let before = read_backs();
            read_back(ReadReason::HashCorners, t);
            read_backs().since(&before).total()
        });
        assert_eq!(other.join().unwrap(), 1);
        assert_eq!(
            read_backs().since(&start).total(),
            3,
            "another thread's read"
        );
    }
}
