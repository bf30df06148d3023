//! Errors: every input a user can pass is checked and answered with a value, never a panic.

use glam::DVec3;

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
    #[error(
        "displacement of node {node} (a lattice node index on a uniform body, the body's node \
         number on an adaptive one) is not finite: {value:?}"
    )]
    NonFiniteDisplacement {
        /// The node: a lattice node index on a uniform body, the body's node number on an adaptive
        /// one.
        node: usize,
        /// The value found.
        value: [f64; 3],
    },
    /// A displacement component beyond the body's limit in absolute value (see
    /// [`crate::Lattice::displacement_limit`]).
    #[error(
        "displacement of node {node} (a lattice node index on a uniform body, the body's node \
         number on an adaptive one) is too large: {value:?} (at most {limit:e} per axis: \
         displaced farther, coordinates cannot resolve this body's cells)"
    )]
    DisplacementTooLarge {
        /// The node: a lattice node index on a uniform body, the body's node number on an adaptive
        /// one.
        node: usize,
        /// The value found.
        value: [f64; 3],
        /// The body's limit.
        limit: f64,
    },
    /// Cells whose Jacobian determinant is not positive at some corner (inverted or degenerate).
    #[error("{}", inverted_message(.0))]
    InvertedCells(Vec<(CellId, f64)>),
    /// A setting is out of its range.
    #[error("invalid setting: {0}")]
    InvalidSettings(String),
    /// A leaf of an adaptive body that cannot be: too deep, or outside the base lattice.
    #[error("leaf {cell}: {reason}")]
    InvalidLeaf {
        /// The leaf's id (its position in the list given).
        cell: CellId,
        /// What is wrong with it.
        reason: String,
    },
    /// Two leaves of an adaptive body cover the same region.
    #[error("leaf {cell} overlaps leaf {other}: a region is covered twice")]
    OverlappingCells {
        /// The leaf found overlapping.
        cell: CellId,
        /// A leaf listed before it that covers part of the same region.
        other: CellId,
    },
    /// A cell id beyond the lattice's cells.
    #[error("{cell} is outside the lattice's {cells} cells")]
    CellOutOfRange {
        /// The cell given.
        cell: CellId,
        /// The lattice's cell count.
        cells: usize,
    },
    /// Memory for a body's buffer could not be allocated (a binding raises its out-of-memory
    /// error: a failed allocation in a plain `Vec` would abort the process).
    #[error("{what}: {bytes} bytes cannot be allocated")]
    OutOfMemory {
        /// The buffer asked for.
        what: &'static str,
        /// Its size.
        bytes: usize,
    },
}

/// The largest displacement component a body accepts, in absolute value. Squared distances
/// between points this far apart stay far below f64's overflow (1.8e308): with a displacement
/// of 1e160 a gap search squared past it and answered an infinite gap with a zero normal.
pub const MAX_DISPLACEMENT: f64 = 1e150;

/// Whether a body accepts displacement `u`: finite and within `limit` on each axis (the body's
/// [`crate::Lattice::displacement_limit`]).
#[inline]
pub(crate) fn displacement_ok(u: DVec3, limit: f64) -> bool {
    // Per axis: NaN fails its comparison (`max_element` would skip it).
    u.abs().cmple(DVec3::splat(limit)).all()
}

/// Why displacement `u` of lattice node `node`, refused by [`displacement_ok`] with `limit`, is
/// refused.
pub(crate) fn displacement_error(node: usize, u: DVec3, limit: f64) -> Error {
    let value = u.to_array();
    if u.is_finite() {
        Error::DisplacementTooLarge { node, value, limit }
    } else {
        Error::NonFiniteDisplacement { node, value }
    }
}

/// The message of [`Error::InvertedCells`]: the count and the first cell (an empty list, which no
/// entry point returns, still displays).
fn inverted_message(cells: &[(CellId, f64)]) -> String {
    match cells.first() {
        Some((cell, ratio)) => format!(
            "{} inverted or degenerate cell(s), first {cell}: det J ratio {ratio:.3e}",
            cells.len()
        ),
        None => "no inverted cell".to_owned(),
    }
}

/// Why a single query point got no answer (the other points of a batch are unaffected).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum PointError {
    /// The point has a NaN or infinite coordinate.
    #[error("the point has a NaN or infinite coordinate")]
    NonFinite,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `InvertedCells(vec![])` indexed `[0]` in its message and panicked.
    #[test]
    fn inverted_cells_display_without_panicking() {
        assert_eq!(Error::InvertedCells(vec![]).to_string(), "no inverted cell");
        let one = Error::InvertedCells(vec![(CellId(4), -0.5)]).to_string();
        assert!(
            one.starts_with("1 inverted") && one.contains("cell 4"),
            "{one}"
        );
    }
}
