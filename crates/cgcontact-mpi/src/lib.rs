//! # cgcontact-mpi
//!
//! cgcontact's contact search over MPI ranks: each rank holds any subset of a body's active cells
//! (or of an adaptive body's leaves) and any set of points; every point gets **the answer the
//! serial search on the whole body gives**, bit for bit, whatever the partition.
//!
//! | piece | what it is |
//! |---|---|
//! | [`DistributedBody`] | the collective setup: the displacement range, the ownership map of lattice blocks, each rank's local body (its home blocks' cells and their halo); `new` takes [`OwnedCell`]s, `new_adaptive` an adaptive body's [`OwnedLeaf`]s |
//! | [`DistributedLocator`] | collective queries: points routed to their block's home, searched there by the core's `LatticeLocator` or `AdaptiveLocator` (or its `GapFinder`: `gap_all_into`, into [`Gaps`]), answers back in input order (`locate_all_into` reuses one [`Located`]'s buffers across a solver's iterations) |
//! | [`Partition`] | slabs, Morton runs or scattered cells: the splits the command line and the tests use |
//! | [`gather_located`], [`gather_gaps`] | every rank's answers on one rank, for one results file |
//! | [`abort_on_panic`] | a panic on one rank aborts every rank, rather than leaving mpirun waiting |
//!
//! ```no_run
//! use cgcontact::glam::DVec3;
//! use cgcontact::{Body, Lattice};
//! use cgcontact_mpi::{Config, DistributedBody, OwnedCell, Partition};
//! use mpi::traits::*;
//!
//! let universe = mpi::initialize().expect("MPI starts once");
//! let world = universe.world();
//! // Every rank knows the lattice; here each also builds the whole body and keeps its slab.
//! let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.25), [4, 8, 4])?;
//! let body = Body::full(lattice);
//! let cells: Vec<_> = body.active_cells().collect();
//! let owners = Partition::Slabs.owners(&lattice, &cells, world.size() as usize);
//! let mine: Vec<OwnedCell> = cells
//!     .iter()
//!     .zip(&owners)
//!     .filter(|&(_, &rank)| rank == world.rank() as usize)
//!     .map(|(&cell, _)| OwnedCell { cell, u: body.cell_displacements(cell).expect("active") })
//!     .collect();
//! let distributed = DistributedBody::new(&world, lattice, &mine, Config::default())?;
//! let locator = distributed.locator()?;
//! let points = [DVec3::new(0.6, 1.1, 0.2)]; // each rank its own points
//! let located = locator.locate_all(&world, &points)?;
//! assert!(located.answers[0].unwrap().is_some());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod distributed;
mod error;
mod exchange;
mod panic;
mod partition;

pub use distributed::{
    Config, DistributedBody, DistributedLocator, Gaps, Located, OwnedCell, OwnedLeaf, QueryStats,
    SetupStats, gather_gaps, gather_located,
};
pub use error::Error;
pub use exchange::Traffic;
pub use panic::abort_on_panic;
pub use partition::Partition;
