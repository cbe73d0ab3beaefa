//! train crate.
