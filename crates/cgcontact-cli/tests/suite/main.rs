//! The crate's integration tests in one binary: one link instead of one per file (the build
//! time that matters on 2 cores). Each file is a module, named as the file.

mod bad_input;
mod end_to_end;
mod lzma;
mod output_safety;
mod regression_links_and_interrupted_folders;
mod regression_out_of_memory_aborted;
mod scene_flags;
mod tradeoff_gslib_input;
mod tradeoff_quick;
mod vtk_written_adaptive;
