//! The crate's integration tests in one binary: one link instead of one per file (the build
//! time that matters on 2 cores). Each file is a module, named as the file.

mod adaptive;
mod agree_with_lattice;
mod common;
mod extremes_oracle;
mod hostile_inputs;
mod seed_filters_failure_counts;
mod sparse_far;
