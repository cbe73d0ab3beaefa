//! Feature-unification crate: see its Cargo.toml.
