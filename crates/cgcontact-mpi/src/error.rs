//! What can go wrong in a collective call. Every rank returns an error when any rank found one, so
//! that no rank goes on into a collective that the others left.

use cgcontact::CellId;

/// Why a collective setup failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A cell index beyond the lattice's cells.
    #[error("cell {cell} is outside the lattice's {cells} cells")]
    CellOutOfRange {
        /// The cell.
        cell: CellId,
        /// The lattice's cell count.
        cells: usize,
    },
    /// A corner displacement is NaN or infinite.
    #[error("cell {cell}: corner {corner} has a NaN or infinite displacement")]
    NonFiniteDisplacement {
        /// The cell.
        cell: CellId,
        /// The corner (VTK order).
        corner: usize,
    },
    /// A leaf deeper than the core's deepest level or outside the base lattice.
    #[error(
        "leaf {leaf} (level {level}, indices {ijk:?}) is deeper than 20 levels or outside the lattice"
    )]
    LeafOutOfRange {
        /// The leaf's id.
        leaf: CellId,
        /// Its level.
        level: u8,
        /// Its indices on its level's lattice.
        ijk: [u32; 3],
    },
    /// A leaf's corner is a node that another leaf gives a different displacement.
    #[error("leaf {cell}: corner {corner} is a node another leaf gives a different displacement")]
    InconsistentCorner {
        /// The leaf.
        cell: CellId,
        /// The corner (VTK order).
        corner: usize,
    },
    /// No rank holds any cell.
    #[error("no rank holds any cell: the body is empty")]
    EmptyBody,
    /// The same cell was given by more than one rank (or twice by one).
    #[error("cell {cell} is held twice (each active cell belongs to one rank)")]
    DuplicateCell {
        /// The cell.
        cell: CellId,
    },
    /// Two cells sharing a node give it different displacements.
    #[error("node {node} has two different displacements in the cells sharing it")]
    InconsistentNode {
        /// The lattice node index.
        node: usize,
    },
    /// The block size is 0 or over 2^20.
    #[error("block size {0}: it must be between 1 and 2^20 cells")]
    BlockSize(u32),
    /// The gap search distance is negative, NaN, or above [`cgcontact::MAX_DISPLACEMENT`] (the
    /// core's gap finder's limit).
    #[error("gap distance {0}: it must be between 0 and {max:e}", max = cgcontact::MAX_DISPLACEMENT)]
    GapDistance(f64),
    /// A gap query on a body set up for a shorter gap distance.
    #[error("gap distance {asked} is beyond the {set_up} the body was set up for")]
    GapBeyondSetup {
        /// The distance asked.
        asked: f64,
        /// `Config::gap_distance` at setup.
        set_up: f64,
    },
    /// The ranks' leaf ids are not 0, 1, …, n − 1 each once (n leaves in all): an id given
    /// twice, out of range, or counted from 0 on each rank.
    #[error(
        "the ranks' {leaves} leaves do not have the ids 0 to {} each once (the greatest is \
         {greatest}): each leaf's id is its place in the whole body",
        leaves.saturating_sub(1)
    )]
    LeafIds {
        /// The leaves on all ranks.
        leaves: u64,
        /// The greatest id given.
        greatest: u64,
    },
    /// The ranks were given different lattices or configs: a collective setup needs the same on
    /// every rank (else the ranks' maps of blocks differ, and their collectives with them).
    #[error(
        "the ranks were given different lattices or configs (block, gap distance, settings): \
         every rank must pass the same"
    )]
    SetupMismatch,
    /// The ranks' queries differ: another body (or none set up with the others), another kind
    /// of query or another gap distance on some rank.
    #[error(
        "the ranks' queries differ (another body, another kind of query or another gap distance \
         on some rank): every rank must make the same query on the same body"
    )]
    QueryMismatch,
    /// A query on a communicator other than the setup's: its ranks are not the setup's ranks
    /// (the homes name ranks of the setup's communicator).
    #[error(
        "queried as rank {rank} of {size}, but set up as rank {setup_rank} of {setup_size}: \
         query on the communicator the body was set up on"
    )]
    Communicator {
        /// This rank in the query's communicator.
        rank: i32,
        /// The query's communicator's size.
        size: i32,
        /// This rank in the setup's communicator.
        setup_rank: i32,
        /// The setup's communicator's size.
        setup_size: i32,
    },
    /// The core library refused the settings or the local body.
    #[error(transparent)]
    Core(#[from] cgcontact::Error),
    /// Another rank failed (its own error is reported there); this one stopped with it.
    #[error("rank {rank} failed")]
    OnAnotherRank {
        /// The lowest rank that failed.
        rank: i32,
    },
}
