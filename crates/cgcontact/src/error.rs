//! Errors: every input a user can pass is checked and answered with a value, never a panic.

use crate::CellId;

/// What went wrong building or querying a body. Messages name the offending item.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The lattice's origin, spacing or counts are unusable.
    #[error("invalid lattice: {0}")]
    InvalidLattice(String),
    /// Two inputs that must match in length do not.
    #[error("{what}: expected {expected} values, got {got}")]
    LengthMismatch {
        /// What was being read.
        what: &'static str,
        /// The length required.
        expected: usize,
        /// The length passed.
        got: usize,
    },
    /// The body has no active cell.
    #[error("the body has no active cell")]
    EmptyBody,
    /// A displacement is NaN or infinite.
    #[error("displacement of node {node} (lattice node index) is not finite: {value:?}")]
    NonFiniteDisplacement {
        /// Lattice node index.
        node: usize,
        /// The value found.
        value: [f64; 3],
    },
    /// Cells whose Jacobian determinant is not positive at some corner (inverted or degenerate).
    #[error("{} inverted or degenerate cell(s), first {}: det J ratio {:.3e}", .0.len(), .0[0].0, .0[0].1)]
    InvertedCells(Vec<(CellId, f64)>),
    /// A setting is out of its range.
    #[error("invalid setting: {0}")]
    InvalidSettings(String),
    /// A cell id beyond the lattice's cells.
    #[error("{cell} is outside the lattice's {cells} cells")]
    CellOutOfRange {
        /// The cell given.
        cell: CellId,
        /// The lattice's cell count.
        cells: usize,
    },
}

/// Why a single query point got no answer (the other points of a batch are unaffected).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PointError {
    /// The point has a NaN or infinite coordinate.
    #[error("the point has a NaN or infinite coordinate")]
    NonFinite,
}
