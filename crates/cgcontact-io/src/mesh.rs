//! Explicit hexahedral meshes as files hold them, and lattice detection: turning one into a
//! [`Body`] while keeping the map between the input's cell order and lattice cells.

use bitvec::vec::BitVec;
use cgcontact::{Answer, Body, CORNER_OFFSETS, CellId, Hit, Lattice};
use glam::DVec3;

use crate::ErrorKind;

/// Relative tolerance, in units of the spacing, within which a node counts as a lattice node.
pub const LATTICE_TOLERANCE: f64 = 1e-9;

/// Extra tolerance in units of the coordinates' own magnitude, for the rounding of `origin + i * h`
/// to f64 (a few ulps): far from the origin it can exceed `LATTICE_TOLERANCE * h`.
pub(crate) const ROUNDING_SLACK: f64 = 4.0 * f64::EPSILON;

/// [`ROUNDING_SLACK`] for coordinates that are all 32-bit floats (VTK's `vtkPoints` default): a
/// node is then off its lattice position by the float's rounding (ε₃₂ / 2 of its magnitude), or
/// by a 6-digit decimal print of it (VTK's legacy ASCII writer: up to 5e-6 of it).
pub(crate) const F32_ROUNDING_SLACK: f64 = 64.0 * f32::EPSILON as f64;

/// Whether every value is a 32-bit float (`v as f32` gives it back): data a file stored as
/// floats, or that a parser read as floats.
pub(crate) fn all_f32<'a>(values: impl IntoIterator<Item = &'a DVec3>) -> bool {
    values
        .into_iter()
        .all(|v| v.to_array().iter().all(|&c| f64::from(c as f32) == c))
}

/// How the used coordinates of a mesh were rounded: what its lattice detection tolerates, and
/// what its errors say when even that is not enough ([`ErrorKind::Imprecise`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Rounding {
    /// 64-bit floats, as computed: [`ROUNDING_SLACK`].
    F64,
    /// All 32-bit floats (or read as floats): [`F32_ROUNDING_SLACK`].
    F32,
    /// Every coordinate printed with at most this many significant decimal digits (9 to 15),
    /// as VTK's legacy ASCII writer prints doubles (11): found only once the detection failed
    /// with [`Rounding::F64`] ([`HexMesh::detect_rounded`]).
    Decimal(u32),
}

impl Rounding {
    /// The rounding of the used coordinates as far as it is cheap to tell: 32-bit floats or not.
    pub(crate) fn of(points: &[DVec3], used: &BitVec) -> Self {
        if all_f32(used.iter_ones().map(|n| &points[n])) {
            Self::F32
        } else {
            Self::F64
        }
    }

    /// How far a coordinate near `magnitude` may be off by this rounding, with a margin for the
    /// origin and spacing found from rounded coordinates: [`ROUNDING_SLACK`] and
    /// [`F32_ROUNDING_SLACK`] of it, and for D digits a unit of the D-th digit there (twice the
    /// print's rounding).
    pub(crate) fn slack_at(self, magnitude: f64) -> f64 {
        match self {
            Self::F64 => ROUNDING_SLACK * magnitude,
            Self::F32 => F32_ROUNDING_SLACK * magnitude,
            Self::Decimal(_) => 2.0 * self.resolution(magnitude),
        }
    }

    /// Half a unit in the last place near `magnitude`: how far a coordinate there may be from
    /// the value it stands for.
    pub(crate) fn resolution(self, magnitude: f64) -> f64 {
        match self {
            Self::F64 => 0.5 * f64::EPSILON * magnitude,
            Self::F32 => 0.5 * f64::from(f32::EPSILON) * magnitude,
            Self::Decimal(_) if !(magnitude > 0.0 && magnitude.is_finite()) => 0.0,
            Self::Decimal(d) => {
                0.5 * 10f64.powi((magnitude.log10().floor() as i32).saturating_add(1 - d as i32))
            }
        }
    }

    /// The rounding in words.
    pub(crate) fn describe(self) -> String {
        match self {
            Self::F64 => "64-bit floats".to_owned(),
            Self::F32 => "32-bit floats".to_owned(),
            Self::Decimal(d) => format!("printed with {d} significant digits"),
        }
    }
}

/// The most significant decimal digits any of `values` needs (its shortest exact print), or
/// `None` when one needs more than 15: then they are not decimal prints of fewer digits.
pub(crate) fn decimal_digits(values: impl IntoIterator<Item = f64>) -> Option<u32> {
    use std::fmt::Write as _;
    most_digits(values, |v, text| write!(text, "{v:e}"))
}

/// [`decimal_digits`] of 32-bit floats: the digits of each value's shortest print that reads
/// back as the same float (a legacy `float` coordinate printed as -99999.8 is -99999.796875 as
/// a double, 11 digits).
pub(crate) fn float_decimal_digits(values: impl IntoIterator<Item = f64>) -> Option<u32> {
    use std::fmt::Write as _;
    most_digits(values, |v, text| write!(text, "{:e}", v as f32))
}

fn most_digits(
    values: impl IntoIterator<Item = f64>,
    print: impl Fn(f64, &mut String) -> std::fmt::Result,
) -> Option<u32> {
    let mut text = String::with_capacity(32);
    let mut most = 1;
    for v in values {
        text.clear();
        print(v, &mut text).expect("a String takes any text");
        let mantissa = text.split('e').next().unwrap_or("");
        let digits = mantissa.bytes().filter(u8::is_ascii_digit).count() as u32;
        if digits > 15 {
            return None;
        }
        most = most.max(digits);
    }
    Some(most)
}

/// How far (per axis) a node may be off its lattice position by the `rounding` of its
/// coordinates, at the lattice's `magnitude`: [`Rounding::slack_at`] it, at most a twentieth
/// of a cell of spacing `h` when the coordinates are rounded beyond 64-bit floats (so that a
/// node is never near two lattice positions; coordinates that round more than that are off the
/// lattice, an error naming the node).
pub(crate) fn coordinate_slack(rounding: Rounding, magnitude: DVec3, h: DVec3) -> DVec3 {
    let slack = DVec3::from_array(magnitude.to_array().map(|m| rounding.slack_at(m)));
    match rounding {
        Rounding::F64 => slack,
        _ => slack.min(h / 20.0),
    }
}

/// The corner one edge from corner 0 along each axis (VTK hexahedron order).
pub(crate) const STEP: [usize; 3] = [1, 3, 4];

/// Below this share of the coordinates' magnitude (per axis), nodes' offsets from their lattice
/// positions are the rounding of f64 arithmetic (`origin + i * h` with a spacing found to an ulp)
/// and the nodes are taken at their lattice positions. When any node is farther off (coordinates
/// stored as floats: 6e-8 of their magnitude; printed with 11 or 6 digits), every node keeps its
/// offset, as displacement ([`beyond_rounding`]).
pub(crate) const ROUNDING_OFFSET: f64 = 64.0 * f64::EPSILON;

/// Whether a node's `offset` from its lattice position is beyond the rounding of f64 arithmetic
/// at the lattice's `magnitude` ([`ROUNDING_OFFSET`]): then every node's offset is kept.
pub(crate) fn beyond_rounding(offset: DVec3, magnitude: DVec3) -> bool {
    offset.abs().cmpgt(ROUNDING_OFFSET * magnitude).any()
}

/// A lattice may have at most this many nodes, or 64 per node in use if that is more. Beyond that
/// the body's per-node slot array (4 bytes per lattice node) would dwarf the mesh: a few cells far
/// apart, or a spacing detected wrong.
const MAX_LATTICE_NODES: u64 = 1 << 26;
const MAX_LATTICE_NODES_PER_USED_NODE: u64 = 64;

/// Sentinel in [`CellMap`]'s lattice-to-input table.
const NO_CELL: u32 = u32::MAX;

/// An explicit mesh of hexahedra, as read from a file: node coordinates, 8 node indices per cell in
/// VTK corner order, and optionally one displacement per node.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HexMesh {
    /// Undeformed node coordinates.
    pub points: Vec<DVec3>,
    /// Each cell's 8 node indices, in VTK hexahedron order.
    pub cells: Vec<[u32; 8]>,
    /// One displacement per node, or `None` for an undeformed mesh.
    pub displacement: Option<Vec<DVec3>>,
    /// The cells flagged as ghost copies (the `vtkGhostType` cell array's bit 1, `DUPLICATECELL`:
    /// a copy of a cell that another piece of a parallel file owns), ascending. A ghost copy may
    /// repeat a cell: it is then read as that cell, and answers name the copy not flagged. Empty
    /// for a mesh without ghosts.
    pub ghosts: Vec<u32>,
}

/// The map between the input mesh's cell order and lattice cells (both ways).
///
/// Results report the input's cell index; the locator works in lattice cells.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CellMap {
    lattice_of_input: Vec<CellId>,
    input_of_lattice: InputOfLattice,
}

/// Lattice cell → input cell: a table over the lattice's cells while it costs at most 64 entries
/// per input cell, else the pairs sorted by lattice cell (memory grows with the input's cells).
#[derive(Clone, Debug, PartialEq, Eq)]
enum InputOfLattice {
    /// One entry per lattice cell: its input index, or `NO_CELL`.
    Table(Vec<u32>),
    /// (lattice cell, input cell), ascending by lattice cell.
    Sorted(Vec<(u32, u32)>),
}

impl CellMap {
    /// The map for a body whose input order is its active cells in ascending lattice order: the
    /// order [`crate::write_mesh`] writes, and the natural one for generated bodies.
    #[must_use]
    pub fn ascending(body: &Body) -> Self {
        let lattice_of_input: Vec<CellId> = body.active_cells().collect();
        Self::new(lattice_of_input, body.lattice().cell_count())
            .expect("a body's active cells are distinct")
    }

    /// The map of `cells` input cells that are their own ids (an adaptive body's leaves, whose id
    /// is their index in the mesh file).
    #[must_use]
    pub fn identity(cells: usize) -> Self {
        let ids: Vec<CellId> = (0..cells as u32).map(CellId).collect();
        Self::new(ids, cells).expect("distinct ids")
    }

    /// The map of input cells `lattice_of_input` on a lattice of `cell_count` cells; the input
    /// index of a cell that appears twice, as `Err((first, second))`.
    pub(crate) fn new(
        lattice_of_input: Vec<CellId>,
        cell_count: usize,
    ) -> Result<Self, (usize, usize)> {
        Self::with_ghosts(lattice_of_input, cell_count, &[])
    }

    /// [`CellMap::new`] where the input cells `ghosts` (ascending) are ghost copies: a lattice
    /// cell may have several input cells when all but one are ghosts, and then answers as the one
    /// that is not (as the first ghost when all are). Two copies not flagged are `Err`.
    pub(crate) fn with_ghosts(
        lattice_of_input: Vec<CellId>,
        cell_count: usize,
        ghosts: &[u32],
    ) -> Result<Self, (usize, usize)> {
        let ghost = |input: u32| ghosts.binary_search(&input).is_ok();
        let input_of_lattice = if cell_count <= 64 * lattice_of_input.len().max(1) {
            let mut table = vec![NO_CELL; cell_count];
            for (input, cell) in lattice_of_input.iter().enumerate() {
                let input = input as u32;
                let slot = &mut table[cell.index()];
                if *slot == NO_CELL || (ghost(*slot) && !ghost(input)) {
                    *slot = input;
                } else if !ghost(input) {
                    return Err((*slot as usize, input as usize));
                }
            }
            InputOfLattice::Table(table)
        } else {
            let mut pairs: Vec<(u32, u32)> = lattice_of_input
                .iter()
                .enumerate()
                .map(|(input, cell)| (cell.0, input as u32))
                .collect();
            pairs.sort_unstable();
            let mut kept: Vec<(u32, u32)> = Vec::with_capacity(pairs.len());
            for (cell, input) in pairs {
                match kept.last_mut() {
                    Some(last) if last.0 == cell => {
                        if ghost(last.1) && !ghost(input) {
                            last.1 = input;
                        } else if !ghost(input) {
                            return Err((last.1 as usize, input as usize));
                        }
                    }
                    _ => kept.push((cell, input)),
                }
            }
            InputOfLattice::Sorted(kept)
        };
        Ok(Self {
            lattice_of_input,
            input_of_lattice,
        })
    }

    /// Input cell index of lattice cell `cell`, or `None` when the input has no such cell.
    #[inline]
    #[must_use]
    pub fn input_cell(&self, cell: CellId) -> Option<usize> {
        match &self.input_of_lattice {
            InputOfLattice::Table(table) => match table.get(cell.index()) {
                Some(&i) if i != NO_CELL => Some(i as usize),
                _ => None,
            },
            InputOfLattice::Sorted(pairs) => pairs
                .binary_search_by_key(&cell.0, |&(c, _)| c)
                .ok()
                .map(|at| pairs[at].1 as usize),
        }
    }

    /// Bytes on the heap.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.lattice_of_input.capacity() * size_of::<CellId>()
            + match &self.input_of_lattice {
                InputOfLattice::Table(table) => table.capacity() * size_of::<u32>(),
                InputOfLattice::Sorted(pairs) => pairs.capacity() * size_of::<(u32, u32)>(),
            }
    }

    /// Lattice cell of input cell `input`, or `None` when out of range.
    #[inline]
    #[must_use]
    pub fn lattice_cell(&self, input: usize) -> Option<CellId> {
        self.lattice_of_input.get(input).copied()
    }

    /// Lattice cells in input order.
    #[must_use]
    pub fn lattice_cells(&self) -> &[CellId] {
        &self.lattice_of_input
    }

    /// Number of input cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.lattice_of_input.len()
    }

    /// Whether there is no cell.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.lattice_of_input.is_empty()
    }
}

/// A body's cells as a caller outside Rust numbers them: the input mesh's order, or, for a body
/// built on a lattice, the lattice's own cell ids. The C and Python bindings write answers in it
/// and read a warm start's previous cells from it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CellNumbering {
    /// Lattice cell ids, 0 up to `cells`.
    Lattice {
        /// The lattice's cell count.
        cells: usize,
    },
    /// The input mesh's cell order.
    Mesh(CellMap),
}

impl CellNumbering {
    /// The caller's number of the body's cell `cell` (−1 if the caller has no such cell, which a
    /// locator never returns).
    #[inline]
    #[must_use]
    pub fn number(&self, cell: CellId) -> i64 {
        match self {
            Self::Lattice { .. } => i64::from(cell.0),
            Self::Mesh(map) => map.input_cell(cell).map_or(-1, |c| c as i64),
        }
    }

    /// The body's cell of the caller's `number`, as a warm start's previous answer: `Ok(None)`
    /// for −1 (none), `Err(())` for a number no cell has.
    #[inline]
    #[allow(clippy::result_unit_err)]
    pub fn cell(&self, number: i64) -> Result<Option<CellId>, ()> {
        if number == -1 {
            return Ok(None);
        }
        let index = usize::try_from(number).map_err(|_| ())?;
        match self {
            Self::Lattice { cells } => (index < *cells)
                .then_some(Some(CellId(index as u32)))
                .ok_or(()),
            Self::Mesh(map) => map.lattice_cell(index).map(Some).ok_or(()),
        }
    }

    /// The caller's numbers of `cells`, ascending (a mesh's input order is not the lattice's).
    #[must_use]
    pub fn sorted_numbers(&self, cells: impl IntoIterator<Item = CellId>) -> Vec<i64> {
        let mut numbers: Vec<i64> = cells.into_iter().map(|c| self.number(c)).collect();
        numbers.sort_unstable();
        numbers
    }

    /// How many cells the caller numbers (0 up to this).
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Self::Lattice { cells } => *cells,
            Self::Mesh(map) => map.len(),
        }
    }

    /// Whether the caller numbers no cell.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The previous answers of a warm start, made from the caller's `cells` and `xi` (three per
    /// point), into `out`: a hit to try first where the cell is one of the body's, none where it
    /// is −1 or no cell (the caller checks those first).
    pub fn previous_answers(&self, cells: &[i64], xi: &[f64], out: &mut Vec<Answer>) {
        out.clear();
        out.extend(
            cells
                .iter()
                .zip(xi.chunks_exact(3))
                .map(|(&c, x)| match self.cell(c) {
                    Ok(Some(cell)) => Hit::hint(cell, DVec3::from_slice(x)),
                    _ => Ok(None),
                }),
        );
    }
}

/// A mesh read from a file and recognised as a lattice body.
#[derive(Clone, Debug)]
pub struct LatticeMesh {
    /// The body: lattice, active cells, displacements.
    pub body: Body,
    /// Input cell order ↔ lattice cells.
    pub cells: CellMap,
    /// Number of nodes in the input (used by cells or not).
    pub point_count: usize,
    /// Whether the input carried a displacement array (otherwise the body is undeformed).
    pub has_displacement: bool,
    /// How far each node of the body (slot order) lies from its lattice position, where some
    /// node lies off it by more than f64 rounding (32-bit float coordinates, short decimal
    /// prints): the body's displacements include them, so that its nodes are the input's. `None`
    /// where every node is at its lattice position to f64 rounding. An update of the
    /// displacements adds them again ([`crate::CallerBody::set_displacements`]).
    pub node_offsets: Option<Vec<DVec3>>,
}

impl LatticeMesh {
    /// Input cell index of lattice cell `cell` (see [`CellMap::input_cell`]).
    #[inline]
    #[must_use]
    pub fn input_cell(&self, cell: CellId) -> Option<usize> {
        self.cells.input_cell(cell)
    }

    /// Lattice cell of input cell `input` (see [`CellMap::lattice_cell`]).
    #[inline]
    #[must_use]
    pub fn lattice_cell(&self, input: usize) -> Option<CellId> {
        self.cells.lattice_cell(input)
    }
}

impl HexMesh {
    /// A mesh of `body`'s active cells in ascending lattice order (undeformed coordinates, the
    /// body's displacements), nodes in ascending lattice node order: what [`crate::write_mesh`] writes.
    #[must_use]
    pub fn from_body(body: &Body) -> Self {
        let lattice = body.lattice();
        // The body's nodes, ascending: a node's index is its place here (no table over the lattice).
        let nodes: Vec<usize> = body.nodes().collect();
        let points = nodes
            .iter()
            .map(|&node| {
                let ijk = lattice
                    .node_ijk(node)
                    .expect("body nodes are lattice nodes");
                lattice.node_position(ijk)
            })
            .collect();
        let index = |n: usize| {
            nodes
                .binary_search(&n)
                .expect("corners of active cells are body nodes") as u32
        };
        let cells = body
            .active_cells()
            .map(|cell| {
                let ijk = lattice.cell_ijk(cell).expect("active cells are in range");
                lattice.corner_nodes(ijk).map(index)
            })
            .collect();
        Self {
            points,
            cells,
            displacement: Some(body.displacements().to_vec()),
            ghosts: Vec::new(),
        }
    }

    /// [`HexMesh::ghosts`] as the detection reads them: ascending, distinct, each a cell.
    pub(crate) fn check_ghosts(&self) -> Result<(), ErrorKind> {
        let ascending = self.ghosts.windows(2).all(|w| w[0] < w[1]);
        match self.ghosts.last() {
            Some(&last) if !ascending || last as usize >= self.cells.len() => {
                Err(ErrorKind::Mismatch(format!(
                    "ghosts must be distinct cells in ascending order, of the {} cells",
                    self.cells.len()
                )))
            }
            _ => Ok(()),
        }
    }

    /// Recognise the mesh as a lattice body: detect origin, spacing and counts from the nodes of the
    /// cells, check that every cell is one lattice cube with corners in VTK order, and build the
    /// body with its active cells and displacements.
    ///
    /// Nodes used by no cell are ignored (neither checked nor kept). Input nodes that coincide
    /// (an unmerged mesh) are fine when their displacements agree.
    pub fn to_lattice(&self) -> Result<LatticeMesh, ErrorKind> {
        if self.cells.is_empty() {
            return Err(ErrorKind::NoCells);
        }
        self.check_ghosts()?;
        if let Some(u) = &self.displacement
            && u.len() != self.points.len()
        {
            return Err(ErrorKind::Mismatch(format!(
                "{} displacements for {} nodes",
                u.len(),
                self.points.len()
            )));
        }
        let used = self.used_nodes()?;
        let (lattice, node_ijk, cells) = self.detect_rounded(&used, |rounding| {
            let lattice = self.detect_lattice(&used)?;
            let node_ijk = self.lattice_nodes(&lattice, &used, rounding)?;
            let cells = self.lattice_cells(&lattice, &node_ijk)?;
            Ok((lattice, node_ijk, cells))
        })?;

        let mut body = Body::from_cells(lattice, cells.lattice_of_input.iter().copied())?;
        let u = match &self.displacement {
            Some(u) => Some(self.slot_displacements(&body, &used, &node_ijk, u)?),
            None => None,
        };
        // The nodes where the file has them: the lattice positions are only where they round to.
        let node_offsets = self.lattice_offsets(&body, &used, &node_ijk);
        match (u, &node_offsets) {
            (Some(u), Some(offsets)) => {
                let sum: Vec<DVec3> = u.iter().zip(offsets).map(|(u, o)| *u + *o).collect();
                body.set_displacements(&sum)?;
            }
            (Some(values), None) => body.set_displacements(&values)?,
            (None, Some(values)) => body.set_displacements(values)?,
            (None, None) => {}
        }
        Ok(LatticeMesh {
            body,
            cells,
            point_count: self.points.len(),
            has_displacement: self.displacement.is_some(),
            node_offsets,
        })
    }

    /// Runs a lattice detection `detect` with the coordinates' [`Rounding::of`]; when that fails
    /// for a reason rounding can explain ([`ErrorKind::rounding_may_explain`]) and the used
    /// coordinates are decimal prints of 9 to 15 significant digits ([`decimal_digits`]), once
    /// more with that print's rounding. VTK's legacy ASCII writer prints doubles with 11 digits,
    /// which near 1000 leave the nodes of a lattice of spacing 1/3 a ten-millionth of a cell off
    /// their positions, past the 64-bit floats' slack. The nodes keep their offsets as
    /// displacement, so the deformed mesh is the file's. A failure that remains is wrapped in
    /// [`ErrorKind::Imprecise`] where the rounding is a thousandth of the smallest cell edge or
    /// more: then the coordinates cannot place cells this small this far from the origin.
    pub(crate) fn detect_rounded<T>(
        &self,
        used: &BitVec,
        detect: impl Fn(Rounding) -> Result<T, ErrorKind>,
    ) -> Result<T, ErrorKind> {
        let rounding = Rounding::of(&self.points, used);
        let result = detect(rounding);
        match result {
            Err(e) if e.rounding_may_explain() && rounding == Rounding::F64 => {
                match self.decimal_rounding(used) {
                    Some(decimal) => detect(decimal).map_err(|e| self.imprecise(e, decimal, used)),
                    None => Err(self.imprecise(e, rounding, used)),
                }
            }
            result => result.map_err(|e| self.imprecise(e, rounding, used)),
        }
    }

    /// [`Rounding::Decimal`] when the used coordinates are decimal prints of 9 to 15 significant
    /// digits ([`decimal_digits`]). Fewer digits are more likely numbers written on purpose: a
    /// cell 1.0001 wide beside cells of 1 is a wrong cell, not a 6-digit print of 1.
    fn decimal_rounding(&self, used: &BitVec) -> Option<Rounding> {
        let digits = decimal_digits(used.iter_ones().flat_map(|n| self.points[n].to_array()))?;
        (digits >= 9).then_some(Rounding::Decimal(digits))
    }

    /// [`Rounding::Decimal`] of 6 to 8 digits when every used coordinate is a decimal print of at
    /// most that many significant digits (as a 32-bit float when all are:
    /// [`float_decimal_digits`]), at least one of exactly that many, and that print is
    /// coarser near `magnitude` than the binary rounding the values have: VTK's legacy ASCII
    /// writer prints `float` coordinates (vtkHyperTreeGridToUnstructuredGrid's, for one) with 6
    /// (`%g`), so near 1e5 they are known only to 0.5, not to a 32-bit float's 4e-3. Only for the
    /// words of an error: too few digits to tell a print from numbers written on purpose for the
    /// lattice detection ([`Self::decimal_rounding`]).
    fn short_print(&self, used: &BitVec, magnitude: f64) -> Option<Rounding> {
        let binary = Rounding::of(&self.points, used);
        let values = used.iter_ones().flat_map(|n| self.points[n].to_array());
        let digits = match binary {
            Rounding::F32 => float_decimal_digits(values),
            _ => decimal_digits(values),
        }?;
        let print = Rounding::Decimal(digits);
        ((6..=8).contains(&digits) && print.resolution(magnitude) > binary.resolution(magnitude))
            .then_some(print)
    }

    /// `error`, found before the lattice detection (a flat cell), as [`Self::detect_rounded`]
    /// words it.
    pub(crate) fn imprecise_before_detection(&self, error: ErrorKind, used: &BitVec) -> ErrorKind {
        if !error.rounding_may_explain() {
            return error;
        }
        let rounding = match Rounding::of(&self.points, used) {
            Rounding::F64 => self.decimal_rounding(used).unwrap_or(Rounding::F64),
            r => r,
        };
        self.imprecise(error, rounding, used)
    }

    /// `error`, wrapped in [`ErrorKind::Imprecise`] when rounding may explain it and the
    /// coordinates' `rounding` near their largest magnitude is a thousandth of the smallest cell
    /// edge or more.
    fn imprecise(&self, error: ErrorKind, rounding: Rounding, used: &BitVec) -> ErrorKind {
        if !error.rounding_may_explain() {
            return error;
        }
        let points = &self.points;
        let magnitude = (used.iter_ones())
            .map(|n| points[n].abs().max_element())
            .fold(0.0, f64::max);
        let rounding = self.short_print(used, magnitude).unwrap_or(rounding);
        let edge = (self.cells.iter())
            .flat_map(|c| {
                [0, 1, 2].map(|a| (points[c[STEP[a]] as usize][a] - points[c[0] as usize][a]).abs())
            })
            .filter(|&e| e > 0.0)
            .fold(f64::INFINITY, f64::min);
        let resolution = rounding.resolution(magnitude);
        // No edge left at all (a float file far out along every axis): every corner rounded onto
        // its cell's corner 0, the rounding's doing as surely as where some edges are left, if
        // those corners are other nodes than corner 0; a cell that names one node for all its
        // corners is flat by its connectivity, whatever the digits.
        let distinct = |c: &[u32; 8]| STEP.iter().any(|&s| c[s] != c[0]);
        let edge = if edge.is_finite() {
            edge
        } else if self.cells.iter().any(distinct) {
            0.0
        } else {
            return error;
        };
        if !(resolution > 0.0 && resolution >= 1e-3 * edge) {
            return error;
        }
        ErrorKind::Imprecise {
            error: Box::new(error),
            rounding: rounding.describe(),
            magnitude,
            resolution,
            edge,
        }
    }

    /// Which nodes some cell uses; checks indices and coordinates of those.
    pub(crate) fn used_nodes(&self) -> Result<BitVec, ErrorKind> {
        let mut used = BitVec::repeat(false, self.points.len());
        for (c, cell) in self.cells.iter().enumerate() {
            for &n in cell {
                if n as usize >= self.points.len() {
                    return Err(ErrorKind::MissingNode {
                        cell: c,
                        node: u64::from(n),
                        points: self.points.len(),
                    });
                }
                used.set(n as usize, true);
            }
        }
        for n in used.iter_ones() {
            let p = self.points[n];
            if !p.is_finite() {
                return Err(ErrorKind::NonFiniteNode {
                    node: n,
                    position: p.to_array(),
                });
            }
        }
        Ok(used)
    }

    /// Origin, spacing and counts from the used nodes.
    ///
    /// The spacing's first estimate is the median edge length per axis over the cells (robust to a
    /// few bad cells); the extreme lattice planes are the outermost clusters of coordinates holding at
    /// least 4 nodes (every cell puts 4 on each of its faces, so a lone stray node cannot pose as a
    /// plane), each taken at its middle value; the spacing is then the extent over the rounded
    /// number of cells, which is accurate to about an ulp over the whole extent.
    fn detect_lattice(&self, used: &BitVec) -> Result<Lattice, ErrorKind> {
        let mut origin = [0.0; 3];
        let mut h = [0.0; 3];
        let mut counts = [0u32; 3];
        let axis_name = ["x", "y", "z"];
        for axis in 0..3 {
            let mut edges: Vec<f64> = self
                .cells
                .iter()
                .map(|c| {
                    (self.points[c[STEP[axis]] as usize][axis] - self.points[c[0] as usize][axis])
                        .abs()
                })
                .collect();
            let mid = edges.len() / 2;
            let (_, &mut h0, _) = edges.select_nth_unstable_by(mid, f64::total_cmp);
            if !(h0 > 0.0 && h0.is_finite()) {
                return Err(ErrorKind::Degenerate(format!(
                    "the typical cell edge along {} is {h0}; cells must have positive extent on every axis",
                    axis_name[axis]
                )));
            }
            let (low, high) = self.axis_planes(used, axis, 0.5 * h0)?;
            let n = ((high - low) / h0).round();
            if n.is_nan() || n < 1.0 {
                return Err(ErrorKind::Degenerate(format!(
                    "the nodes span {} along {} for a typical edge of {h0}",
                    high - low,
                    axis_name[axis]
                )));
            }
            if n > f64::from(u32::MAX - 1) {
                return Err(ErrorKind::TooSparse {
                    lattice_nodes: u64::MAX,
                    used_nodes: used.count_ones(),
                    message: "more cells along one axis than indices",
                });
            }
            origin[axis] = low;
            h[axis] = (high - low) / n;
            counts[axis] = n as u32;
        }
        // Saturating: three axes of up to 2^32 cells overflow u64, and a wrapped count could pass.
        let lattice_nodes =
            (counts.iter()).fold(1u64, |nodes, &n| nodes.saturating_mul(u64::from(n) + 1));
        let used_count = used.count_ones();
        let limit = MAX_LATTICE_NODES.max(MAX_LATTICE_NODES_PER_USED_NODE * used_count as u64);
        if lattice_nodes > limit {
            return Err(ErrorKind::TooSparse {
                lattice_nodes,
                used_nodes: used_count,
                message: "refused, the body's per-node table would dwarf the mesh (cells far apart or a \
                          spacing detected wrong?)",
            });
        }
        Ok(Lattice::new(
            DVec3::from_array(origin),
            DVec3::from_array(h),
            counts,
        )?)
    }

    /// Lattice indices of every used node (unused ones get `[u32::MAX; 3]`).
    fn lattice_nodes(
        &self,
        lattice: &Lattice,
        used: &BitVec,
        rounding: Rounding,
    ) -> Result<Vec<[u32; 3]>, ErrorKind> {
        let origin = lattice.origin();
        let h = lattice.h();
        let nodes = lattice.nodes();
        let magnitude = origin.abs().max(lattice.upper().abs());
        let tol = LATTICE_TOLERANCE * h + coordinate_slack(rounding, magnitude, h);
        let mut ijk = vec![[u32::MAX; 3]; self.points.len()];
        for n in used.iter_ones() {
            let p = self.points[n];
            let t = (p - origin) / h;
            let i = t.round();
            let off = p - (origin + i * h);
            let inside = (0..3).all(|a| i[a] >= 0.0 && i[a] < f64::from(nodes[a]));
            if !inside {
                return Err(ErrorKind::OutsideLattice {
                    node: n,
                    position: p.to_array(),
                    origin: origin.to_array(),
                    h: h.to_array(),
                    nodes,
                    index: i.to_array(),
                });
            }
            if off.abs().cmpgt(tol).any() {
                return Err(ErrorKind::OffLattice {
                    node: n,
                    position: p.to_array(),
                    origin: origin.to_array(),
                    h: h.to_array(),
                    offset: (t - i).to_array(),
                });
            }
            ijk[n] = [i.x as u32, i.y as u32, i.z as u32];
        }
        Ok(ijk)
    }

    /// Lattice cell of every input cell, checking each is one lattice cube in VTK corner order.
    fn lattice_cells(
        &self,
        lattice: &Lattice,
        node_ijk: &[[u32; 3]],
    ) -> Result<CellMap, ErrorKind> {
        let counts = lattice.cells();
        let mut lattice_of_input = Vec::with_capacity(self.cells.len());
        if self.cells.len() >= NO_CELL as usize {
            return Err(ErrorKind::Topology(format!(
                "{} cells exceed the 2^32 - 1 this library indexes",
                self.cells.len()
            )));
        }
        for (c, cell) in self.cells.iter().enumerate() {
            let base = node_ijk[cell[0] as usize];
            for (corner, offset) in CORNER_OFFSETS.iter().enumerate() {
                let found = node_ijk[cell[corner] as usize];
                let expected: [i64; 3] =
                    std::array::from_fn(|a| i64::from(base[a]) + i64::from(offset[a]));
                let found_i: [i64; 3] = found.map(i64::from);
                if found_i != expected {
                    return Err(ErrorKind::NotLatticeCell {
                        cell: c,
                        corner,
                        node: cell[corner] as usize,
                        found: found_i,
                        expected,
                    });
                }
            }
            // Corner 6 sits at base + 1 and is a lattice node, so base < counts on every axis.
            debug_assert!((0..3).all(|a| base[a] < counts[a]));
            lattice_of_input.push(lattice.cell_id(base));
        }
        CellMap::with_ghosts(lattice_of_input, lattice.cell_count(), &self.ghosts).map_err(
            |(first, second)| {
                // Both are the cell whose lowest corner is this lattice node.
                let ijk = node_ijk[self.cells[second][0] as usize];
                ErrorKind::DuplicateCell { first, second, ijk }
            },
        )
    }

    /// How far each body node's input node lies from its lattice position (`None` when every
    /// one lies within f64 rounding of it: [`beyond_rounding`]), in body node order; of copies of a
    /// node, the first input node's.
    ///
    /// A node counts as a lattice node within [`LATTICE_TOLERANCE`] of a spacing plus the
    /// rounding of its coordinates: VTK's default float points at a spacing of 0.1 lie up to
    /// 6e-8 of a cell off it. Dropping that offset moved the body's faces off the file's: a
    /// point on a shared node or face, given where the file has it, lost owners, and one on a
    /// boundary face was outside the body. The offset is added to the displacement instead, so
    /// that the deformed nodes are the file's (position plus displacement) to an ulp.
    fn lattice_offsets(
        &self,
        body: &Body,
        used: &BitVec,
        node_ijk: &[[u32; 3]],
    ) -> Option<Vec<DVec3>> {
        let lattice = body.lattice();
        let offset = |n: usize| self.points[n] - lattice.node_position(node_ijk[n]);
        // Most files hold their nodes within rounding: one pass tells, before any sort.
        let magnitude = lattice.origin().abs().max(lattice.upper().abs());
        if !used
            .iter_ones()
            .any(|n| beyond_rounding(offset(n), magnitude))
        {
            return None;
        }
        let mut by_node: Vec<(usize, usize)> = used
            .iter_ones()
            .map(|n| (lattice.node_index(node_ijk[n]), n))
            .collect();
        by_node.sort_unstable();
        by_node.dedup_by_key(|&mut (node, _)| node);
        Some(by_node.into_iter().map(|(_, n)| offset(n)).collect())
    }

    /// The displacements of `body`'s nodes in its slot order (ascending lattice node), from the
    /// used input nodes, checking that coinciding input nodes agree. Memory grows with the used
    /// nodes, not the lattice.
    fn slot_displacements(
        &self,
        body: &Body,
        used: &BitVec,
        node_ijk: &[[u32; 3]],
        u: &[DVec3],
    ) -> Result<Vec<DVec3>, ErrorKind> {
        let lattice = body.lattice();
        // 1e-9 of the shortest spacing: of the largest, copies 1e-9 of a long side apart passed
        // on a 1 : 0.01 lattice, 1e-7 of its short side, the scale of ξ along it.
        let tol = LATTICE_TOLERANCE * lattice.h().min_element();
        // (lattice node, input node): copies of a lattice node come together once sorted.
        let by_node: Vec<(usize, usize)> = used
            .iter_ones()
            .map(|n| (lattice.node_index(node_ijk[n]), n))
            .collect();
        let values = merge_displacements(by_node, u, tol)?;
        // Every node of the body is a corner of an input cell, so a used input node: the lists
        // match one to one.
        debug_assert_eq!(values.len(), body.node_count());
        Ok(values)
    }
}

/// One displacement per body node from the input nodes at it: `by_node` holds (body node, input
/// node) pairs, any order. Every value must be finite, and input nodes at one body node (an
/// unmerged mesh) must agree within `tol` plus the rounding of the values. Returns the values in
/// ascending body node order.
pub(crate) fn merge_displacements(
    mut by_node: Vec<(usize, usize)>,
    u: &[DVec3],
    tol: f64,
) -> Result<Vec<DVec3>, ErrorKind> {
    by_node.sort_unstable();
    for &(_, n) in &by_node {
        if !u[n].is_finite() {
            return Err(ErrorKind::NonFiniteDisplacement {
                node: n,
                value: u[n].to_array(),
            });
        }
    }
    for w in by_node.windows(2) {
        let ((node, first), (next, second)) = (w[0], w[1]);
        let (a, b) = (u[first], u[second]);
        if node == next
            && (a - b).abs().max_element() > tol + ROUNDING_SLACK * b.abs().max_element()
        {
            return Err(ErrorKind::InconsistentDisplacement {
                first,
                second,
                first_u: a.to_array(),
                second_u: b.to_array(),
            });
        }
    }
    by_node.dedup_by_key(|&mut (node, _)| node);
    Ok(by_node.into_iter().map(|(_, n)| u[n]).collect())
}

impl HexMesh {
    /// The lowest and highest lattice planes along `axis` of the used nodes ([`extreme_planes`]
    /// with gaps below `gap`), or an error naming the axis when none holds 4 nodes.
    pub(crate) fn axis_planes(
        &self,
        used: &BitVec,
        axis: usize,
        gap: f64,
    ) -> Result<(f64, f64), ErrorKind> {
        let mut values: Vec<f64> = used.iter_ones().map(|n| self.points[n][axis]).collect();
        values.sort_unstable_by(f64::total_cmp);
        extreme_planes(&values, gap).ok_or_else(|| {
            ErrorKind::Degenerate(format!(
                "no plane of nodes along {} holds 4 nodes or more",
                ["x", "y", "z"][axis]
            ))
        })
    }
}

/// The middle values of the lowest and highest clusters of at least 4 sorted values, clusters being
/// runs whose consecutive gaps are below `gap`.
fn extreme_planes(sorted: &[f64], gap: f64) -> Option<(f64, f64)> {
    let mut clusters = Vec::new();
    let mut start = 0;
    for i in 1..=sorted.len() {
        if i == sorted.len() || sorted[i] - sorted[i - 1] >= gap {
            clusters.push(start..i);
            start = i;
        }
    }
    let big = |r: &std::ops::Range<usize>| r.len() >= 4;
    let low = clusters.iter().find(|r| big(r))?;
    let high = clusters.iter().rev().find(|r| big(r))?;
    let middle = |r: &std::ops::Range<usize>| sorted[r.start + r.len() / 2];
    Some((middle(low), middle(high)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(origin: DVec3, h: DVec3, n: [u32; 3]) -> Body {
        Body::full(Lattice::new(origin, h, n).unwrap())
    }

    #[test]
    fn decimal_digits_are_those_of_the_shortest_exact_print() {
        assert_eq!(decimal_digits([1000.3333333, 1000.0, -0.0]), Some(11));
        assert_eq!(decimal_digits([0.1, 2.5e-7, -3e300]), Some(2));
        assert_eq!(decimal_digits([123_456_789_012_345.0]), Some(15));
        assert_eq!(decimal_digits([0.1, 1.0 / 3.0]), None);
        // A float read from "-99999.8" is -99999.796875: 6 digits as a float, 11 as a double.
        let float = f64::from(-99999.8_f32);
        assert_eq!(decimal_digits([float]), Some(11));
        assert_eq!(float_decimal_digits([float, 25000.0, 1e5]), Some(6));
        assert_eq!(decimal_digits([f64::from(0.1f32)]), None);
        assert_eq!(decimal_digits([]), Some(1));
    }

    #[test]
    fn a_decimal_print_resolves_half_a_unit_of_its_last_digit() {
        let r = Rounding::Decimal(11);
        assert!((r.resolution(1000.3) - 5e-8).abs() < 1e-20);
        assert!((r.resolution(2e6) - 5e-5).abs() < 1e-17);
        assert!((r.resolution(9.99e5) - 5e-6).abs() < 1e-18);
        assert_eq!(r.resolution(0.0), 0.0);
        assert_eq!(r.slack_at(2e6), 2.0 * r.resolution(2e6));
    }

    #[test]
    fn from_body_round_trips_through_detection() {
        let mut body = block(
            DVec3::new(-1.0, 2.0, 3.5),
            DVec3::new(0.5, 0.25, 1.0),
            [3, 4, 2],
        );
        body.update_displacements(|n, x, u| {
            *u = DVec3::new(0.01 * x.y, -0.02 * n as f64 * 1e-3, 0.0)
        })
        .unwrap();
        let mesh = HexMesh::from_body(&body);
        let found = mesh.to_lattice().unwrap();
        assert_eq!(found.body.lattice().cells(), body.lattice().cells());
        assert_eq!(found.body.lattice().origin(), body.lattice().origin());
        assert!(
            (found.body.lattice().h() - body.lattice().h())
                .abs()
                .max_element()
                < 1e-15
        );
        assert_eq!(found.body.displacements(), body.displacements());
        assert_eq!(found.cells, CellMap::ascending(&body));
    }

    #[test]
    fn extreme_planes_skip_stray_values() {
        let v = [-5.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.01, 7.0];
        assert_eq!(extreme_planes(&v, 0.5), Some((0.0, 2.0)));
        assert_eq!(extreme_planes(&[0.0, 1.0], 0.5), None);
    }

    /// Two unit cubes 2^22 apart on every axis: (2^22 + 2)^3 lattice nodes overflow u64, and the
    /// mesh must be refused as too sparse, not panic (debug) or wrap into a small count (release).
    #[test]
    fn a_lattice_too_large_to_count_is_refused() {
        let far = f64::from(1u32 << 22);
        let cube =
            |o: f64| CORNER_OFFSETS.map(|[a, b, c]| DVec3::new(a as f64, b as f64, c as f64) + o);
        let mesh = HexMesh {
            ghosts: Vec::new(),
            points: [cube(0.0), cube(far)].concat(),
            cells: vec![[0, 1, 2, 3, 4, 5, 6, 7], [8, 9, 10, 11, 12, 13, 14, 15]],
            displacement: None,
        };
        assert!(matches!(
            mesh.to_lattice(),
            Err(ErrorKind::TooSparse {
                lattice_nodes: u64::MAX,
                ..
            })
        ));
    }

    #[test]
    fn empty_and_out_of_range_are_errors() {
        assert!(matches!(
            HexMesh::default().to_lattice(),
            Err(ErrorKind::NoCells)
        ));
        let mesh = HexMesh {
            ghosts: Vec::new(),
            points: vec![DVec3::ZERO; 4],
            cells: vec![[0, 1, 2, 3, 4, 5, 6, 7]],
            displacement: None,
        };
        assert!(matches!(
            mesh.to_lattice(),
            Err(ErrorKind::MissingNode {
                cell: 0,
                node: 4,
                ..
            })
        ));
    }
}
