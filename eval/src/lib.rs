//! eval crate.
