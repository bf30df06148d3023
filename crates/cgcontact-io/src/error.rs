//! Errors: every file a user can pass is answered with a value that names the file and the offending
//! line, cell or node, never with a panic.

use std::path::{Path, PathBuf};

/// An error reading or writing a file: the file's path and what went wrong in it.
///
/// Displays as one line, `PATH: what (cell/node/line)`, fit for a command line's error message.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct IoError {
    path: PathBuf,
    // Boxed: the kinds carry coordinates, and a small `Err` keeps every `Result` cheap to return.
    kind: Box<ErrorKind>,
}

impl IoError {
    /// An error in file `path`.
    #[must_use]
    pub fn new(path: impl Into<PathBuf>, kind: ErrorKind) -> Self {
        Self {
            path: path.into(),
            kind: Box::new(kind),
        }
    }

    /// The file the error is about.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What went wrong.
    #[must_use]
    pub fn kind(&self) -> &ErrorKind {
        &self.kind
    }

    /// What went wrong, by value.
    #[must_use]
    pub fn into_kind(self) -> ErrorKind {
        *self.kind
    }
}

/// What went wrong in a mesh, points or results file (or in an in-memory [`crate::HexMesh`]).
///
/// Cell and node indices are 0-based indices in the input's own order; line numbers are 1-based.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The operating system refused to read or write the file.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The file is not in a format this crate reads.
    #[error("unrecognised format: {}", crate::one_line(.0))]
    Format(String),
    /// The VTK parser rejected the file (truncated, malformed, or a feature it does not support).
    #[error("malformed VTK file: {}", crate::one_line(.0))]
    Vtk(String),
    /// A piece file of a parallel file (`.pvtu`): its index among the parallel file's pieces, its
    /// path, and what went wrong in it (its lines are the piece file's own; cell and node numbers
    /// count across the pieces, as VTK's reader numbers them).
    #[error("piece {piece} ({}): {error}", file.display())]
    Piece {
        /// The piece's index in the parallel file's list.
        piece: usize,
        /// The piece file, as resolved from the parallel file's folder.
        file: PathBuf,
        /// What went wrong.
        error: Box<ErrorKind>,
    },
    /// A cell flagged a ghost copy by the file's `vtkGhostType` cell array that overlaps a cell
    /// without being its copy (a copy is read as the cell it copies).
    #[error(
        "{error}: cell {ghost} is a ghost cell (its vtkGhostType flags it a copy of a cell that \
         another piece owns), but no copy of the cell there; write the file without ghost levels \
         (a parallel writer's GhostLevel 0)"
    )]
    GhostCell {
        /// The copy flagged a ghost.
        ghost: usize,
        /// The error that refuses the copy.
        error: Box<ErrorKind>,
    },
    /// A parallel file (`.pvtu`) that cannot be read as one: pieces nested in a piece, or bytes
    /// that name files but come from no file.
    #[error("{0}")]
    Parallel(String),
    /// The data set is not an unstructured grid.
    #[error("the data set is {0}, expected an unstructured grid")]
    NotUnstructuredGrid(&'static str),
    /// The mesh has no cells.
    #[error("the mesh has no cells")]
    NoCells,
    /// The point coordinates are unusable as a whole (wrong type or count).
    #[error("POINTS: {0}")]
    Points(String),
    /// The cell arrays are inconsistent (counts, offsets, connectivity).
    #[error("cells: {0}")]
    Topology(String),
    /// A cell is not a hexahedron.
    #[error(
        "cell {cell}: VTK cell type {vtk_type} ({name}); only hexahedra (type 12) and voxels (type 11) are supported"
    )]
    NotHexahedron {
        /// Input cell index.
        cell: usize,
        /// Its VTK type number.
        vtk_type: u8,
        /// Its VTK type name.
        name: String,
    },
    /// A cell references a node that the file does not have.
    #[error("cell {cell}: references node {node}, but the mesh has {points} nodes")]
    MissingNode {
        /// Input cell index.
        cell: usize,
        /// The node index referenced.
        node: u64,
        /// The number of nodes in the mesh.
        points: usize,
    },
    /// A node of some cell has a NaN or infinite coordinate.
    #[error("node {node}: coordinates {position:?} are not finite")]
    NonFiniteNode {
        /// Input node index.
        node: usize,
        /// The coordinates found.
        position: [f64; 3],
    },
    /// The nodes do not span a lattice (all on one plane, or too few to tell).
    #[error("not a lattice: {0}")]
    Degenerate(String),
    /// A node of some cell is not on the lattice detected from the others.
    #[error(
        "node {node} at {position:?} is not on the lattice (origin {origin:?}, spacing {h:?}): \
         it is {offset:?} spacings from the nearest lattice node"
    )]
    OffLattice {
        /// Input node index.
        node: usize,
        /// Its coordinates.
        position: [f64; 3],
        /// Detected lattice origin.
        origin: [f64; 3],
        /// Detected lattice spacing.
        h: [f64; 3],
        /// Offset from the nearest lattice node, in units of the spacing per axis.
        offset: [f64; 3],
    },
    /// A hexahedron whose corners are not one lattice cell's corners in VTK order.
    #[error(
        "cell {cell}: corner {corner} (node {node}) is at lattice node {found:?}, expected {expected:?}: \
         the cell is not one lattice cube with its corners in VTK order"
    )]
    NotLatticeCell {
        /// Input cell index.
        cell: usize,
        /// The corner (0..8, VTK order) that does not fit.
        corner: usize,
        /// Input node index of that corner.
        node: usize,
        /// The lattice node it sits at.
        found: [i64; 3],
        /// The lattice node it should sit at, given corner 0.
        expected: [i64; 3],
    },
    /// Two input cells are the same lattice cell.
    #[error("cells {first} and {second} are the same lattice cell {ijk:?}")]
    DuplicateCell {
        /// The earlier input cell index.
        first: usize,
        /// The later input cell index.
        second: usize,
        /// Lattice indices of the cell.
        ijk: [u32; 3],
    },
    /// The lattice spanned by the nodes would be far larger than the mesh (a few cells far apart).
    #[error(
        "the lattice spanned by the nodes has {lattice_nodes} nodes for {used_nodes} used ones: {message}"
    )]
    TooSparse {
        /// Nodes of the detected lattice (saturated at `u64::MAX`).
        lattice_nodes: u64,
        /// Nodes used by cells.
        used_nodes: usize,
        /// Why that is refused.
        message: &'static str,
    },
    /// The displacement array asked for is not in the file.
    #[error("no point data array named `{name}` (point arrays found: {available})")]
    MissingDisplacement {
        /// The name asked for.
        name: String,
        /// The point data arrays present, comma separated.
        available: String,
    },
    /// The displacement array is not a 3-vector per node.
    #[error("point data array `{name}`: {message}")]
    BadDisplacement {
        /// The array's name.
        name: String,
        /// What is wrong with it.
        message: String,
    },
    /// A node of some cell has a NaN or infinite displacement.
    #[error("node {node}: displacement {value:?} is not finite")]
    NonFiniteDisplacement {
        /// Input node index.
        node: usize,
        /// The value found.
        value: [f64; 3],
    },
    /// Two input nodes at the same lattice node carry different displacements.
    #[error(
        "nodes {first} and {second} are the same lattice node but have different displacements \
         {first_u:?} and {second_u:?}"
    )]
    InconsistentDisplacement {
        /// The earlier input node index.
        first: usize,
        /// The later input node index.
        second: usize,
        /// Displacement of the first.
        first_u: [f64; 3],
        /// Displacement of the second.
        second_u: [f64; 3],
    },
    /// A bad row in a CSV file.
    #[error("line {line}: {message}")]
    Csv {
        /// 1-based line number.
        line: u64,
        /// What is wrong with it.
        message: String,
    },
    /// A CSV file with no data rows.
    #[error("no data rows")]
    Empty,
    /// Two inputs that must match do not (points and answers, say).
    #[error("{0}")]
    Mismatch(String),
    /// A cell whose corner 1, 3 or 4 has corner 0's coordinate along the axis it should advance:
    /// flat, collapsed, or with its corners not in VTK hexahedron order.
    #[error(
        "cell {cell}: corners 0 and {corner} have the same {axis} coordinate: the cell is flat, or \
         its corners are not in VTK hexahedron order (from corner 0, corner 1 along x, 3 along y, \
         4 along z)"
    )]
    FlatCell {
        /// Input cell index.
        cell: usize,
        /// The corner (1, 3 or 4) that does not advance.
        corner: usize,
        /// The axis along which it should: "x", "y" or "z".
        axis: &'static str,
    },
    /// A cell of an adaptive mesh whose edges are the coarsest cells' halved more times than an
    /// adaptive body's deepest level.
    #[error(
        "cell {cell}: edges {edges:?} are the coarsest cells' edges {base:?} halved {level} times, \
         deeper than the {max} levels an adaptive body holds"
    )]
    TooDeep {
        /// Input cell index.
        cell: usize,
        /// Its edge lengths per axis.
        edges: [f64; 3],
        /// The coarsest cells' edge lengths.
        base: [f64; 3],
        /// Its level.
        level: u32,
        /// The deepest level ([`cgcontact::adaptive::MAX_LEVEL`]).
        max: u8,
    },
    /// A cell of an adaptive mesh whose size is not the coarsest cells' halved a whole number of
    /// times, equally on every axis.
    #[error(
        "cell {cell}: edges {edges:?} are not the coarsest cells' edges {base:?} halved a whole \
         number of times (equally on every axis): not a dyadic refinement of one lattice"
    )]
    CellSize {
        /// Input cell index.
        cell: usize,
        /// Its edge lengths per axis.
        edges: [f64; 3],
        /// The coarsest cells' edge lengths.
        base: [f64; 3],
    },
    /// A cell of an adaptive mesh whose lowest corner is not a node of its level's lattice.
    #[error(
        "cell {cell}: level {level} cell at {position:?} is not aligned to its level's lattice \
         (origin {origin:?}, spacing {h:?})"
    )]
    NotAligned {
        /// Input cell index.
        cell: usize,
        /// Its refinement level (0 for the coarsest cells).
        level: u8,
        /// Its lowest corner.
        position: [f64; 3],
        /// The base lattice's origin.
        origin: [f64; 3],
        /// The spacing of the cell's level.
        h: [f64; 3],
    },
    /// A mesh that is not a lattice at the precision of its coordinates: the lattice detection's
    /// `error`, where the coordinates' rounding near their largest magnitude is a thousandth of
    /// the smallest cell edge or more (cells too small for how far from the origin they lie, at
    /// the digits the file holds).
    #[error(
        "{error}; the coordinates are {rounding}: near {magnitude:.3e} they are known only to about \
         {resolution:.1e}, {}: too coarse to place cells this small this far from the origin \
         (keep more digits, as binary data do, or move the mesh nearer the origin)",
        share_of_edge(*resolution, *edge)
    )]
    Imprecise {
        /// What the lattice detection refused.
        error: Box<ErrorKind>,
        /// How the coordinates are rounded, in words.
        rounding: String,
        /// The largest magnitude of a used coordinate.
        magnitude: f64,
        /// Half a unit in the last place there.
        resolution: f64,
        /// The smallest cell edge; 0 when every edge rounded to 0 (no corner of any cell apart
        /// from its corner 0 along its axis).
        edge: f64,
    },
    /// Two input cells cover the same region (an adaptive mesh's leaves must tile without overlap).
    #[error("cells {first} and {second} overlap: a region is covered twice")]
    OverlappingCells {
        /// The earlier input cell.
        first: usize,
        /// The later one.
        second: usize,
    },
    /// The core library refused the lattice or body built from the file.
    #[error(transparent)]
    Core(#[from] cgcontact::Error),
    /// A node of some cell lies outside the extent of the lattice detected from the nodes.
    #[error(
        "node {node} at {position:?} lies outside the lattice (origin {origin:?}, spacing {h:?}, \
         {nodes:?} nodes per axis): it would be lattice node {index:?}"
    )]
    OutsideLattice {
        /// Input node index.
        node: usize,
        /// Its coordinates.
        position: [f64; 3],
        /// Detected lattice origin.
        origin: [f64; 3],
        /// Detected lattice spacing.
        h: [f64; 3],
        /// Lattice nodes per axis.
        nodes: [u32; 3],
        /// The lattice index it rounds to, per axis (out of range on some axis).
        index: [f64; 3],
    },
}

/// The coordinates' `resolution` as a share of the smallest cell `edge` (0: none left).
fn share_of_edge(resolution: f64, edge: f64) -> String {
    if edge > 0.0 {
        format!(
            "{} % of the smallest cell edge {edge:.3e}",
            percent(resolution / edge)
        )
    } else {
        "and every cell edge rounded to 0".to_owned()
    }
}

/// `share` in percent: whole from 10 % up, with two decimals below.
fn percent(share: f64) -> String {
    let p = 100.0 * share;
    if p >= 10.0 {
        format!("{p:.0}")
    } else {
        format!("{p:.2}")
    }
}

impl ErrorKind {
    /// Whether the coordinates' rounding may explain this refusal of a mesh as a lattice: a node
    /// off or outside the lattice, a cell of the wrong size, not aligned, flat, or whose corners
    /// are not one lattice cell's.
    #[must_use]
    pub fn rounding_may_explain(&self) -> bool {
        matches!(
            self,
            Self::OffLattice { .. }
                | Self::OutsideLattice { .. }
                | Self::CellSize { .. }
                | Self::NotAligned { .. }
                | Self::NotLatticeCell { .. }
                | Self::FlatCell { .. }
        )
    }

    /// This error, in file `path`.
    #[must_use]
    pub fn in_file(self, path: impl Into<PathBuf>) -> IoError {
        IoError::new(path, self)
    }
}
