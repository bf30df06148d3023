//! A panic on one rank ends every rank.
//!
//! A rank that panics unwinds out of its `main` and drops its `Universe`, whose `MPI_Finalize`
//! waits for the other ranks; they wait in the next collective for the rank that panicked, and
//! mpirun never returns. [`abort_on_panic`] installs a panic hook that prints the panic with the
//! rank's number and calls `MPI_Abort` on the world communicator instead, which ends every rank.

use mpi::environment::is_initialized;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Makes a panic on this rank print one line (`cgcontact-mpi: rank R panicked at FILE:LINE:
/// MESSAGE`) and abort every rank with `MPI_Abort(MPI_COMM_WORLD, code)`, so that mpirun returns
/// (with `code`, under Open MPI) instead of waiting forever for this rank. Replaces the process's
/// panic hook; a panic before MPI is initialised, or after it is finalised, is only printed.
///
/// Call it on every rank, after `mpi::initialize`.
pub fn abort_on_panic(code: i32) {
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("a panic without a message");
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        if is_initialized() && !mpi::environment::is_finalized() {
            let world = SimpleCommunicator::world();
            eprintln!(
                "cgcontact-mpi: rank {} panicked{place}: {message}",
                world.rank()
            );
            world.abort(code);
        }
        eprintln!("cgcontact-mpi: panicked{place}: {message}");
    }));
}
