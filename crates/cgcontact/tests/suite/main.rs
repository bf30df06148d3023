//! The crate's integration tests in one binary: one link instead of one per file (the build
//! time that matters on 2 cores). Each file is a module, named as the file.

mod adaptive;
mod common;
mod extremes;
mod gap_extremes;
mod locate_property;
mod regression_low_iteration_limit;
mod regression_newton_options_unchecked;
mod schedule;
mod warm;
