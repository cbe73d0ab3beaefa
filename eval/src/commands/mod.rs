//! The command-line subcommands as library functions: one module per
//! subcommand with its arguments (clap), their checks and what it does.

pub mod common;
pub mod extract;
pub mod gather;
pub mod photographs;
pub mod proposals;
pub mod query;
pub mod render;
pub mod segment;
pub mod targets;
pub mod uncertainty;
pub mod view;
