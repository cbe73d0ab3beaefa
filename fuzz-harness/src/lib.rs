//! Mutation fuzzing of every file parser of the workspace, on stable Rust.
//!
//! # Engine
//!
//! The inputs are seed files (the shared data sets, read from
//! `../shared/data` at run time, the repository's test fixtures, and
//! files written by the product's own writers) changed by byte-level
//! mutations: bit flips, boundary integers, deletions, duplications,
//! dictionary tokens, boundary numbers in text, splices of two seeds. The
//! mutations are chosen by the [`arbitrary`] crate (rust-fuzz's, the
//! input layer of `cargo fuzz`) from a ChaCha stream seeded by the target
//! and the execution index. That choice over `bolero`'s stable engine:
//! bolero off nightly generates values from types and replays corpus
//! files, but does not mutate seed files, and the formats here are only
//! reached deeply from real files. Without nightly there is no coverage
//! instrumentation, so the search is blind (no corpus growth); what it
//! gains is that execution `i` is a pure function of `i`, so a worker
//! that died can be replayed exactly and every failing input rebuilt.
//!
//! # Checks
//!
//! Every execution is a defect when it
//! - panics (caught with `catch_unwind`);
//! - allocates, in one request or in live total, more than
//!   max(64 MiB, 64 x the input's size) ([`guard::cap_for`]; counted by
//!   [`guard::CountingAlloc`], the binary's global allocator): a header
//!   must not make a loader reserve what the file cannot hold;
//! - runs longer than the time limit (a watchdog thread; 5 s of wall-clock
//!   time by default, generous because the machine may be shared).
//!
//! An allocation over the cap or a hang cannot be recovered in-process, so
//! each target runs in a worker process that the supervisor restarts after
//! the failing execution. Failing inputs are saved for the regression
//! tests of the crate that owns the parser.

pub mod guard;
pub mod mutate;
pub mod report;
pub mod supervisor;
pub mod targets;
pub mod worker;
