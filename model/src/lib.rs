//! The OpenNeRF field and its pure math: cameras and rays ([`geometry`]),
//! Mip-NeRF encodings, sampling, compositing, the MLP with its stop-gradient
//! open-set head, coarse/fine rendering and the losses. No file I/O.
#![warn(missing_docs)]

pub mod geometry;
