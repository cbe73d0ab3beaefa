//! The measurement programs of OpenNeRF and what they share. The binaries:
//! `bench` (training-step throughput per backend, optionally against JAX),
//! `bench-vlm` (dense CLIP feature extraction per backend, optionally
//! against PyTorch), `sweep` (speed against accuracy, one training run per
//! setting), `time_to_accuracy` (seconds to held-out PSNR targets with and
//! without the occupancy grid) and `scale_report` (the time and memory of
//! each stage over the synthetic scene sizes). The examples are the
//! experiments behind the README's findings.
#![warn(missing_docs)]

pub mod csv_table;
pub mod phone_export;
pub mod sweep;
