//! A deformed body: a lattice, its active cells, and one displacement per node of an active cell.
//!
//! Nothing else is stored: no coordinates (they come from the lattice), no connectivity (corners come
//! from index arithmetic). Displacements live in one compact array, in ascending lattice node order.
//! How a lattice node finds its slot there depends on how much of the lattice the body fills, so
//! that memory grows with the active cells, never with the lattice alone:
//!
//! | body | node → slot | active cells |
//! |---|---|---|
//! | every cell active (a full block) | slot n is node n: no table, 24 bytes per node | all |
//! | nodes fill ≥ 1/32 of the lattice | a `u32` per lattice node | a bit per lattice cell |
//! | sparser | a hash map of its nodes (about 20 bytes per node) | a sorted list and a hash set |

use bitvec::vec::BitVec;
use glam::DVec3;

use crate::Error;
use crate::error::{displacement_error, displacement_ok};
use crate::hex8;
use crate::idmap::IdMap;
use crate::lattice::{CORNER_OFFSETS, CellId, Lattice};
use crate::memory;
use crate::settings::{InsideTolerance, Settings};

/// What [`Error::OutOfMemory`] names for the buffers of a body's active cells.
const ACTIVE_CELLS: &str = "the active cells";

/// Slot value of a lattice node that belongs to no active cell.
const NO_SLOT: u32 = u32::MAX;

/// A body uses a slot table while the lattice has at most this many nodes per active cell (the
/// table then costs at most 128 bytes per active cell); sparser bodies use hash maps.
const TABLE_NODES_PER_CELL: usize = 32;

/// Where each lattice node's displacement lives.
#[derive(Clone, Debug)]
enum Slots {
    /// Every lattice node carries one: node n's slot is n.
    Dense,
    /// One slot per lattice node, `NO_SLOT` where none: the body's `table`.
    Table,
    /// The nodes in slot order (ascending) and a map node → slot.
    Sparse { nodes: Vec<u32>, map: IdMap },
}

/// Which lattice cells are active.
#[derive(Clone, Debug)]
enum Cells {
    /// A bit per lattice cell.
    Mask(BitVec),
    /// The active cells ascending, and the set of them.
    Sparse { cells: Vec<u32>, set: IdMap },
}

/// A body's active cells, decoded once ([`Body::active_set`]).
#[derive(Clone, Copy)]
pub(crate) struct ActiveSet<'a> {
    /// The mask's words and its length in bits, when the body keeps a mask.
    words: Option<(&'a [usize], usize)>,
    body: &'a Body,
}

impl ActiveSet<'_> {
    /// [`Body::is_active`].
    #[inline]
    pub(crate) fn contains(&self, cell: CellId) -> bool {
        match self.words {
            Some((words, len)) => {
                let i = cell.index();
                let word = words.get(i / usize::BITS as usize).copied().unwrap_or(0);
                i < len && (word >> (i % usize::BITS as usize)) & 1 == 1
            }
            None => self.body.is_active(cell),
        }
    }
}

/// A body meshed on a cartesian lattice and deformed by nodal displacements.
#[derive(Clone, Debug)]
pub struct Body {
    lattice: Lattice,
    cells: Cells,
    active_count: usize,
    /// Each lattice node's slot in `u` (see [`Slots`]).
    slots: Slots,
    /// `Slots::Dense`, read first by the corner gather (one flag, no match, on the hot path).
    dense: bool,
    /// The slot table of `Slots::Table` (empty otherwise), outside the enum for the same reason.
    table: Vec<u32>,
    /// Displacement of each node of an active cell, in ascending lattice node order.
    u: Vec<DVec3>,
    /// Node index of each corner (VTK order) minus that of corner 0, for any cell.
    corner_offsets: [usize; 8],
}

impl Body {
    /// An undeformed body: the lattice's cells where `active` is set.
    ///
    /// Errors when the mask's length is not the lattice's cell count, or no cell is active, or
    /// with [`Error::OutOfMemory`] when the body's buffers cannot be allocated.
    pub fn undeformed(lattice: Lattice, active: BitVec) -> Result<Self, Error> {
        if active.len() != lattice.cell_count() {
            return Err(Error::LengthMismatch {
                what: "active cell mask",
                expected: lattice.cell_count(),
                got: active.len(),
            });
        }
        let mut cells = memory::with_capacity(active.count_ones(), ACTIVE_CELLS)?;
        cells.extend(active.iter_ones().map(|c| c as u32));
        Self::build(lattice, cells, Some(active))
    }

    /// An undeformed body of the given active cells (any order, repeats ignored), in memory that
    /// grows with the cells, not the lattice: a few cells on a huge lattice take kilobytes.
    ///
    /// Errors when a cell lies outside the lattice, or there is none, or with
    /// [`Error::OutOfMemory`] when the body's buffers cannot be allocated.
    pub fn from_cells(
        lattice: Lattice,
        cells: impl IntoIterator<Item = CellId>,
    ) -> Result<Self, Error> {
        let mut ids = memory::collected(cells.into_iter().map(|c| c.0), ACTIVE_CELLS)?;
        if let Some(&bad) = ids.iter().find(|&&c| c as usize >= lattice.cell_count()) {
            return Err(Error::CellOutOfRange {
                cell: CellId(bad),
                cells: lattice.cell_count(),
            });
        }
        ids.sort_unstable();
        ids.dedup();
        Self::build(lattice, ids, None)
    }

    /// The body of the active cells `ids` (ascending, distinct, in range), `mask` their bit mask
    /// when the caller has one. Every buffer is allocated fallibly ([`memory`]).
    fn build(lattice: Lattice, ids: Vec<u32>, mask: Option<BitVec>) -> Result<Self, Error> {
        if ids.is_empty() {
            return Err(Error::EmptyBody);
        }
        let active_count = ids.len();
        let corner_offsets = lattice.corner_nodes([0, 0, 0]);
        let corners = |id: u32| {
            let ijk = lattice
                .cell_ijk(CellId(id))
                .expect("active cells lie in the lattice");
            lattice.corner_nodes(ijk)
        };
        let mut slot_table = Vec::new();
        let (slots, nodes) = if active_count == lattice.cell_count() {
            (Slots::Dense, lattice.node_count())
        } else if lattice.node_count() <= TABLE_NODES_PER_CELL * active_count {
            let mut table = memory::filled(NO_SLOT, lattice.node_count(), "the node slot table")?;
            for &id in &ids {
                for node in corners(id) {
                    table[node] = 0;
                }
            }
            let mut next = 0u32;
            for s in table.iter_mut().filter(|s| **s != NO_SLOT) {
                *s = next;
                next += 1;
            }
            slot_table = table;
            (Slots::Table, next as usize)
        } else {
            let mut nodes = memory::with_capacity(8 * ids.len(), "the active cells' nodes")?;
            nodes.extend(ids.iter().flat_map(|&id| corners(id)).map(|n| n as u32));
            nodes.sort_unstable();
            nodes.dedup();
            let slots = nodes.iter().enumerate().map(|(s, &n)| (n, s as u32));
            let map = IdMap::try_new(slots, "the node slot map")?;
            let count = nodes.len();
            (Slots::Sparse { nodes, map }, count)
        };
        let cells = if lattice.cell_count() <= 64 * active_count {
            Cells::Mask(match mask {
                Some(mask) => mask,
                None => {
                    let mut bits = memory::bits(false, lattice.cell_count(), ACTIVE_CELLS)?;
                    for &id in &ids {
                        bits.set(id as usize, true);
                    }
                    bits
                }
            })
        } else {
            let set = IdMap::try_new(ids.iter().map(|&id| (id, 0)), ACTIVE_CELLS)?;
            Cells::Sparse { cells: ids, set }
        };
        let u = memory::filled(DVec3::ZERO, nodes, "the displacements")?;
        Ok(Self {
            lattice,
            cells,
            active_count,
            dense: matches!(slots, Slots::Dense),
            slots,
            table: slot_table,
            u,
            corner_offsets,
        })
    }

    /// A body with every lattice cell active.
    ///
    /// It holds 24 bytes per lattice node (the displacements) and a bit per cell, so a lattice
    /// of 10^9 nodes takes 24 GB; where the allocation fails, this panics ([`Body::try_full`]
    /// returns the error instead). A body of some cells of a large lattice
    /// ([`Body::from_cells`]) takes memory that grows with its cells.
    pub fn full(lattice: Lattice) -> Self {
        Self::try_full(lattice).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Body::full`], or [`Error::OutOfMemory`] when its buffers cannot be allocated: for a
    /// binding that must raise its out-of-memory error rather than abort the process. While it
    /// builds, it holds 4 bytes per cell besides the body.
    pub fn try_full(lattice: Lattice) -> Result<Self, Error> {
        let active = memory::bits(true, lattice.cell_count(), ACTIVE_CELLS)?;
        // A lattice has at least one cell and the mask fits it: only allocations can fail.
        Self::undeformed(lattice, active)
    }

    /// A body with displacements given per node of an active cell, in ascending lattice node order
    /// (the order of [`Body::nodes`]).
    pub fn new(lattice: Lattice, active: BitVec, u: &[DVec3]) -> Result<Self, Error> {
        let mut body = Self::undeformed(lattice, active)?;
        body.set_displacements(u)?;
        Ok(body)
    }

    /// A body with displacements taken from a dense field, one per lattice node (values at nodes of
    /// no active cell are ignored).
    pub fn from_dense(lattice: Lattice, active: BitVec, dense: &[DVec3]) -> Result<Self, Error> {
        let mut body = Self::undeformed(lattice, active)?;
        if dense.len() != lattice.node_count() {
            return Err(Error::LengthMismatch {
                what: "dense displacement field",
                expected: lattice.node_count(),
                got: dense.len(),
            });
        }
        body.update_displacements(|node, _, u| *u = dense[node])?;
        Ok(body)
    }

    /// The lattice.
    #[inline]
    #[must_use]
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// Whether lattice cell `cell` is active (false when out of range).
    #[inline]
    #[must_use]
    pub fn is_active(&self, cell: CellId) -> bool {
        match &self.cells {
            Cells::Mask(mask) => {
                // A word lookup: BitVec's proxy-reference `get` costs measurably on the hot path.
                let i = cell.index();
                let word = mask
                    .as_raw_slice()
                    .get(i / usize::BITS as usize)
                    .copied()
                    .unwrap_or(0);
                i < mask.len() && (word >> (i % usize::BITS as usize)) & 1 == 1
            }
            Cells::Sparse { .. } => self.is_active_sparse(cell),
        }
    }

    /// The active cells, for loops that test many: [`Body::is_active`] decodes the bit mask at
    /// every call, this once.
    #[inline]
    pub(crate) fn active_set(&self) -> ActiveSet<'_> {
        ActiveSet {
            words: match &self.cells {
                Cells::Mask(mask) => Some((mask.as_raw_slice(), mask.len())),
                Cells::Sparse { .. } => None,
            },
            body: self,
        }
    }

    /// [`Body::is_active`] on a sparse body: a hash lookup, out of line.
    #[inline(never)]
    fn is_active_sparse(&self, cell: CellId) -> bool {
        match &self.cells {
            // u32::MAX is the map's empty key, never a cell.
            Cells::Sparse { set, .. } => cell.0 != u32::MAX && set.get(cell.0).is_some(),
            Cells::Mask(_) => false,
        }
    }

    /// Number of active cells.
    #[inline]
    #[must_use]
    pub fn active_count(&self) -> usize {
        self.active_count
    }

    /// Ids of the active cells, ascending.
    pub fn active_cells(&self) -> Box<dyn Iterator<Item = CellId> + '_> {
        match &self.cells {
            Cells::Mask(mask) => Box::new(mask.iter_ones().map(|c| CellId(c as u32))),
            Cells::Sparse { cells, .. } => Box::new(cells.iter().map(|&c| CellId(c))),
        }
    }

    /// Whether a search box of `box_cells` lattice cells is better served by the body's active
    /// cells ([`Body::for_each_active_in`]) than by testing each of its cells: past 8 box cells
    /// per active cell (a sparse body, a long search distance).
    #[inline]
    pub(crate) fn box_outnumbers_cells(&self, box_cells: u64) -> bool {
        box_cells > 8 * self.active_count as u64
    }

    /// Calls `f` with each active cell of the lattice box [`low`, `high`] (cell indices, inclusive),
    /// ascending by id, reading only the active cells whose ids lie between the box's lowest and
    /// highest: for searches whose box holds far more lattice cells than the body has.
    pub(crate) fn for_each_active_in(
        &self,
        low: [u32; 3],
        high: [u32; 3],
        mut f: impl FnMut([u32; 3]),
    ) {
        let lattice = &self.lattice;
        let (first, last) = (lattice.cell_id(low).0, lattice.cell_id(high).0);
        let mut visit = |c: u32| {
            let ijk = lattice.cell_ijk(CellId(c)).unwrap_or([u32::MAX; 3]);
            if (0..3).all(|a| (low[a]..=high[a]).contains(&ijk[a])) {
                f(ijk);
            }
        };
        match &self.cells {
            Cells::Sparse { cells, .. } => {
                let from = cells.partition_point(|&c| c < first);
                let to = cells.partition_point(|&c| c <= last);
                cells[from..to].iter().for_each(|&c| visit(c));
            }
            Cells::Mask(mask) => {
                if let Some(range) = mask.get(first as usize..=last as usize) {
                    range.iter_ones().for_each(|c| visit(first + c as u32));
                }
            }
        }
    }

    /// Number of nodes carrying a displacement (nodes of active cells).
    #[inline]
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.u.len()
    }

    /// Lattice indices of the nodes carrying a displacement, in slot order (ascending).
    pub fn nodes(&self) -> Box<dyn Iterator<Item = usize> + '_> {
        match &self.slots {
            Slots::Dense => Box::new(0..self.u.len()),
            Slots::Table => Box::new(
                self.table
                    .iter()
                    .enumerate()
                    .filter(|(_, s)| **s != NO_SLOT)
                    .map(|(n, _)| n),
            ),
            Slots::Sparse { nodes, .. } => Box::new(nodes.iter().map(|&n| n as usize)),
        }
    }

    /// The slot of lattice node `node` in the displacements, or `None` when it has none.
    #[inline(always)]
    fn slot_of(&self, node: usize) -> Option<usize> {
        match &self.slots {
            Slots::Dense => (node < self.u.len()).then_some(node),
            Slots::Table => match self.table.get(node) {
                Some(&s) if s != NO_SLOT => Some(s as usize),
                _ => None,
            },
            Slots::Sparse { map, .. } => {
                // u32::MAX is the map's empty key, never a node (as in `is_active_sparse`).
                let key = u32::try_from(node).ok().filter(|&k| k != u32::MAX)?;
                map.get(key).map(|s| s as usize)
            }
        }
    }

    /// Displacements in slot order (see [`Body::nodes`]).
    #[inline]
    #[must_use]
    pub fn displacements(&self) -> &[DVec3] {
        &self.u
    }

    /// Displacement of lattice node `node`, or `None` when it belongs to no active cell.
    #[inline]
    #[must_use]
    pub fn displacement(&self, node: usize) -> Option<DVec3> {
        self.slot_of(node).map(|s| self.u[s])
    }

    /// The largest displacement component this body accepts: its lattice's
    /// [`Lattice::displacement_limit`].
    #[must_use]
    pub fn displacement_limit(&self) -> f64 {
        self.lattice.displacement_limit(self.lattice.h())
    }

    /// Replace every displacement (slot order), in place: nothing is rebuilt. Errors on a length
    /// mismatch or a value not finite or beyond [`Body::displacement_limit`] (naming the node).
    pub fn set_displacements(&mut self, u: &[DVec3]) -> Result<(), Error> {
        if u.len() != self.u.len() {
            return Err(Error::LengthMismatch {
                what: "displacements",
                expected: self.u.len(),
                got: u.len(),
            });
        }
        let limit = self.displacement_limit();
        if let Some(i) = u.iter().position(|&v| !displacement_ok(v, limit)) {
            let node = self.nodes().nth(i).expect("slot exists");
            return Err(displacement_error(node, u[i], limit));
        }
        self.u.copy_from_slice(u);
        Ok(())
    }

    /// Update displacements in place with `f(lattice node, undeformed position, &mut u)`.
    ///
    /// On a non-finite result, or one beyond [`Body::displacement_limit`], the error names the
    /// node; every displacement is then reset to zero so that the body never holds a value the
    /// locator would trip on. So it is when `f` panics part way (the panic goes on): the values
    /// written before it, a NaN among them, are not kept.
    pub fn update_displacements(
        &mut self,
        mut f: impl FnMut(usize, DVec3, &mut DVec3),
    ) -> Result<(), Error> {
        /// Zeroes the displacements when dropped armed: on a panic of `f`.
        struct ZeroOnUnwind<'a> {
            u: &'a mut [DVec3],
            armed: bool,
        }
        impl Drop for ZeroOnUnwind<'_> {
            fn drop(&mut self) {
                if self.armed {
                    self.u.fill(DVec3::ZERO);
                }
            }
        }
        let lattice = self.lattice;
        let limit = self.displacement_limit();
        let mut bad = None;
        let nodes: Vec<usize> = match &self.slots {
            // Slot n is node n: no list needed.
            Slots::Dense => Vec::new(),
            _ => self.nodes().collect(),
        };
        let mut guard = ZeroOnUnwind {
            u: &mut self.u,
            armed: true,
        };
        for s in 0..guard.u.len() {
            let node = if nodes.is_empty() { s } else { nodes[s] };
            let ijk = lattice.node_ijk(node).expect("node in range");
            let u = &mut guard.u[s];
            f(node, lattice.node_position(ijk), u);
            if bad.is_none() && !displacement_ok(*u, limit) {
                bad = Some(displacement_error(node, *u, limit));
            }
        }
        // On an error, every value goes back to zero as on a panic.
        guard.armed = bad.is_some();
        drop(guard);
        bad.map_or(Ok(()), Err)
    }

    /// On a body with a slot table, the box of lattice nodes holding all its nodes (lowest node,
    /// nodes per axis) and every displacement there, x fastest, zero at nodes without one; `None`
    /// on other bodies or when the box holds more than `most` nodes. One pass over the table.
    pub(crate) fn boxed_displacements(
        &self,
        most: usize,
    ) -> Option<([u32; 3], [u32; 3], Vec<DVec3>)> {
        if self.table.is_empty() {
            return None;
        }
        let [nx, ny, nz] = self.lattice.nodes().map(|n| n as usize);
        let (mut low, mut high) = ([usize::MAX; 3], [0usize; 3]);
        for (row, slots) in self.table.chunks_exact(nx).enumerate() {
            let Some(first) = slots.iter().position(|&s| s != NO_SLOT) else {
                continue;
            };
            let last = slots.iter().rposition(|&s| s != NO_SLOT).unwrap_or(first);
            let (y, z) = (row % ny, row / ny);
            low = [low[0].min(first), low[1].min(y), low[2].min(z)];
            high = [high[0].max(last), high[1].max(y), high[2].max(z)];
        }
        debug_assert!(high[2] < nz);
        let dims = [0, 1, 2].map(|a| high[a] + 1 - low[a]);
        if dims.iter().product::<usize>() > most {
            return None;
        }
        let mut u = Vec::with_capacity(dims.iter().product());
        for z in low[2]..=high[2] {
            for y in low[1]..=high[1] {
                let row = nx * (y + ny * z);
                u.extend(
                    self.table[row + low[0]..=row + high[0]]
                        .iter()
                        .map(|&s| self.u.get(s as usize).copied().unwrap_or(DVec3::ZERO)),
                );
            }
        }
        Some((low.map(|v| v as u32), dims.map(|v| v as u32), u))
    }

    /// Heap bytes held by the body (mask, node slots, displacements): what "memory per node" measures.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        let cells = match &self.cells {
            Cells::Mask(mask) => mask.capacity() / 8,
            Cells::Sparse { cells, set } => cells.capacity() * size_of::<u32>() + set.heap_bytes(),
        };
        let slots = match &self.slots {
            Slots::Dense => 0,
            Slots::Table => self.table.capacity() * size_of::<u32>(),
            Slots::Sparse { nodes, map } => nodes.capacity() * size_of::<u32>() + map.heap_bytes(),
        };
        cells + slots + self.u.capacity() * size_of::<DVec3>()
    }

    /// Largest displacement component per axis over all nodes (the search bound of the locator).
    #[must_use]
    pub fn max_displacement(&self) -> DVec3 {
        self.u.iter().fold(DVec3::ZERO, |m, v| m.max(v.abs()))
    }

    /// Displacements of the 8 corners of `cell` (VTK order), or `None` when it is inactive or out of range.
    #[inline]
    #[must_use]
    pub fn cell_displacements(&self, cell: CellId) -> Option<[DVec3; 8]> {
        if !self.is_active(cell) {
            return None;
        }
        Some(self.corner_displacements(self.lattice.cell_ijk(cell)?))
    }

    /// Corner displacements of active cell `ijk`, in VTK order. The caller guarantees the cell is active.
    #[inline(always)]
    pub(crate) fn corner_displacements(&self, ijk: [u32; 3]) -> [DVec3; 8] {
        // Every corner of an active cell has a displacement: the gather with zeros is this gather.
        self.corner_displacements_or_zero(ijk)
    }

    /// Corner displacements where they exist, zero elsewhere (for cells that may be inactive).
    #[inline(always)]
    pub(crate) fn corner_displacements_or_zero(&self, ijk: [u32; 3]) -> [DVec3; 8] {
        // An explicit loop, not `array::map`: the latter costs ~100 instructions of MaybeUninit
        // bookkeeping per call on the hot path (measured with callgrind).
        let (base, zero) = (self.lattice.node_index(ijk), DVec3::ZERO);
        let mut u = [zero; 8];
        for (c, u) in u.iter_mut().enumerate() {
            *u = *self.corner_entry(&self.u, base, c, &zero);
        }
        u
    }

    /// Corner `c`'s entry of `data`, an array in slot order like the displacements (a locator's f32
    /// copy of them, say), for the cell whose lowest lattice node is `base`; `zero` where the corner
    /// has no slot. The one gather: the scalar search's and, one corner of one lane at a time, the
    /// batched search's.
    #[inline(always)]
    pub(crate) fn corner_entry<'d, T>(
        &self,
        data: &'d [T],
        base: usize,
        c: usize,
        zero: &'d T,
    ) -> &'d T {
        let node = base + self.corner_offsets[c];
        if self.dense {
            &data[node]
        } else if !self.table.is_empty() {
            // NO_SLOT is u32::MAX, never a valid slot: `get` answers None for it.
            data.get(self.table[node] as usize).unwrap_or(zero)
        } else {
            self.sparse_entry(data, node, zero)
        }
    }

    /// [`Body::corner_entry`] on a sparse body: a hash lookup, kept out of line so that the gather
    /// of full and table bodies stays small.
    #[inline(never)]
    fn sparse_entry<'d, T>(&self, data: &'d [T], node: usize, zero: &'d T) -> &'d T {
        match &self.slots {
            Slots::Sparse { map, .. } => match map.get(node as u32) {
                Some(s) => &data[s as usize],
                None => zero,
            },
            _ => zero,
        }
    }

    /// Corner positions of a deformed cell relative to its lowest undeformed node, VTK order.
    #[inline]
    pub(crate) fn local_corners(&self, ijk: [u32; 3]) -> [DVec3; 8] {
        let u = self.corner_displacements(ijk);
        let h = self.lattice.h();
        std::array::from_fn(|c| {
            let [a, b, d] = CORNER_OFFSETS[c];
            DVec3::new(a as f64, b as f64, d as f64) * h + u[c]
        })
    }

    /// Deformed corner positions of active cell `cell` in global coordinates, VTK order.
    ///
    /// Returns `None` when the cell is inactive or out of range.
    #[must_use]
    pub fn corners(&self, cell: CellId) -> Option<[DVec3; 8]> {
        if !self.is_active(cell) {
            return None;
        }
        let ijk = self.lattice.cell_ijk(cell)?;
        let low = self.lattice.node_position(ijk);
        Some(self.local_corners(ijk).map(|c| low + c))
    }

    /// The trilinear map of active cell `cell` in its local frame, and that frame's origin (the
    /// cell's lowest undeformed node): the deformed point at ξ is `origin + map.map(ξ)`, and a point
    /// x is inverted as `map.invert(x − origin, ...)`, magnitudes of order h whatever the global
    /// coordinates (parry's local/global pair). `None` when the cell is inactive or out of range.
    #[must_use]
    pub fn cell_map(&self, cell: CellId) -> Option<(hex8::Hex8Map, DVec3)> {
        use hex8::Kernel;
        let u = self.cell_displacements(cell)?;
        let ijk = self.lattice.cell_ijk(cell)?;
        Some((
            hex8::Hex8Map::lattice_cell(self.lattice.h(), &u),
            self.lattice.node_position(ijk),
        ))
    }

    /// The deformed point of active cell `cell` at local coordinates `xi`, computed in the cell's
    /// local frame and then placed (one rounding of the global coordinates); `None` when the cell
    /// is inactive or out of range.
    #[must_use]
    pub fn point_at(&self, cell: CellId, xi: DVec3) -> Option<DVec3> {
        let (map, origin) = self.cell_map(cell)?;
        Some(origin + map.map(xi))
    }

    /// Active cells whose Jacobian determinant is not positive at some corner, with the smallest
    /// corner determinant divided by the undeformed one (≤ 0), ascending by cell.
    #[must_use]
    pub fn inverted_cells(&self) -> Vec<(CellId, f64)> {
        let h = self.lattice.h();
        let undeformed = h.x * h.y * h.z / 8.0;
        self.active_cells()
            .filter_map(|cell| {
                let ijk = self
                    .lattice
                    .cell_ijk(cell)
                    .expect("active cells are in range");
                let ratio = hex8::min_corner_det(&self.local_corners(ijk)) / undeformed;
                // NaN counts as inverted: only a ratio known to be positive is valid.
                (ratio.is_nan() || ratio <= 0.0).then_some((cell, ratio))
            })
            .collect()
    }

    /// Active cells that f64 coordinates of their magnitude cannot resolve, with the share: where
    /// a rounding of the point's coordinates (the inside test's L_j = 4 ε₆₄ max(|x_j|, |origin_j|)
    /// at the cell's centre), carried through the cell's J⁻¹, moves ξ by more than
    /// [`Lattice::RESOLUTION`] on some axis ([`hex8::Hex8Map::rounding_share`]), ascending by
    /// cell. A cell whose det J ≤ 0 at its centre is not listed: it is an inverted cell
    /// ([`Body::inverted_cells`]). [`Lattice::check_resolution`] refuses such undeformed
    /// cells; a deformation that shears a cell (x += 1e3 y) or crushes it carries a rounding along
    /// one axis into a large share of another. Near such a cell the inside test's allowance
    /// reaches that share of it: a point that near a face may be given the cell beside it too.
    #[must_use]
    pub fn unresolved_cells(&self) -> Vec<(CellId, f64)> {
        let tolerance = InsideTolerance::new(&Settings::default(), &self.lattice, DVec3::ZERO);
        self.active_cells()
            .filter_map(|cell| {
                let (map, origin) = self.cell_map(cell)?;
                unresolved_share(&tolerance, &map, origin).map(|share| (cell, share))
            })
            .collect()
    }

    /// Check the body: every displacement finite and within [`Body::displacement_limit`], and no
    /// inverted cell (errors name them).
    pub fn validate(&self) -> Result<(), Error> {
        let limit = self.displacement_limit();
        if let Some(i) = self.u.iter().position(|&v| !displacement_ok(v, limit)) {
            let node = self.nodes().nth(i).expect("slot exists");
            return Err(displacement_error(node, self.u[i], limit));
        }
        let inverted = self.inverted_cells();
        if inverted.is_empty() {
            Ok(())
        } else {
            Err(Error::InvertedCells(inverted))
        }
    }
}

/// The share of a cell that a rounding of the point's coordinates (f64's L at the cell's centre,
/// `tolerance` made with f64 settings and no displacement) takes through the cell's J⁻¹
/// ([`hex8::Hex8Map::rounding_share`]), when it exceeds [`Lattice::RESOLUTION`]; `None` below
/// it, and where det J ≤ 0 at the centre (an inverted cell). `map` is the cell's map in its local
/// frame, `origin` its lowest undeformed corner: what [`Body::unresolved_cells`] and
/// `AdaptiveBody::unresolved_cells` ask of each cell.
pub(crate) fn unresolved_share(
    tolerance: &InsideTolerance,
    map: &hex8::Hex8Map,
    origin: DVec3,
) -> Option<f64> {
    let centre = origin + map.map(DVec3::ZERO);
    let share = map.rounding_share(tolerance.length(centre));
    (share.is_finite() && share > Lattice::RESOLUTION).then_some(share)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice() -> Lattice {
        Lattice::new(DVec3::new(1.0, 2.0, 3.0), DVec3::splat(0.5), [3, 2, 2]).unwrap()
    }

    /// Every representation (full, slot table, hash maps: chosen by how much of the lattice the
    /// cells fill) against an independent answer: the corners of the chosen cells.
    #[test]
    fn every_storage_answers_as_the_cells_it_was_given() {
        let l = Lattice::new(
            DVec3::new(-3.0, 0.5, 1e3),
            DVec3::new(0.5, 0.25, 1.0),
            [30, 20, 25],
        )
        .unwrap();
        let mut state = 7u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        let field =
            |n: usize| DVec3::new(n as f64 * 1e-6, -(n as f64) * 2e-6, (n % 13) as f64 * 1e-3);
        for count in [3, 40, 2_000, l.cell_count() / 2, l.cell_count()] {
            let mut chosen: Vec<u32> = (0..count)
                .map(|_| (next() % l.cell_count()) as u32)
                .collect();
            if count == l.cell_count() {
                chosen = (0..count as u32).collect();
            }
            let mut body = Body::from_cells(l, chosen.iter().map(|&c| CellId(c))).unwrap();
            chosen.sort_unstable();
            chosen.dedup();
            assert_eq!(body.active_count(), chosen.len());
            assert!(body.active_cells().map(|c| c.0).eq(chosen.iter().copied()));
            let mut corners: Vec<usize> = chosen
                .iter()
                .flat_map(|&c| l.corner_nodes(l.cell_ijk(CellId(c)).unwrap()))
                .collect();
            corners.sort_unstable();
            corners.dedup();
            assert!(body.nodes().eq(corners.iter().copied()), "{count} cells");
            body.update_displacements(|n, _, u| *u = field(n)).unwrap();
            for n in 0..l.node_count() {
                let expected = corners.binary_search(&n).is_ok().then(|| field(n));
                assert_eq!(body.displacement(n), expected, "node {n}, {count} cells");
            }
            for c in 0..l.cell_count() as u32 {
                let active = chosen.binary_search(&c).is_ok();
                assert_eq!(body.is_active(CellId(c)), active);
                let ijk = l.cell_ijk(CellId(c)).unwrap();
                let gathered = body.corner_displacements_or_zero(ijk);
                for (k, node) in l.corner_nodes(ijk).into_iter().enumerate() {
                    let expected = if corners.binary_search(&node).is_ok() {
                        field(node)
                    } else {
                        DVec3::ZERO
                    };
                    assert_eq!(gathered[k], expected);
                }
            }
            assert!(!body.is_active(CellId(u32::MAX)));
            // Node u32::MAX is the sparse map's empty key, which it found in every empty slot
            // (the displacement of slot 0).
            for node in [
                l.node_count(),
                u32::MAX as usize,
                u32::MAX as usize + 1,
                usize::MAX,
            ] {
                assert_eq!(body.displacement(node), None, "node {node}, {count} cells");
            }
            // Memory grows with the cells: a few cells take a few kilobytes.
            if count <= 40 {
                assert!(body.heap_bytes() < 64 * 1024, "{}", body.heap_bytes());
            }
        }
        assert!(matches!(
            Body::from_cells(l, [CellId(l.cell_count() as u32)]),
            Err(Error::CellOutOfRange { .. })
        ));
        assert!(matches!(Body::from_cells(l, []), Err(Error::EmptyBody)));
    }

    /// `point_at` against the shape functions on the deformed corners (an independent formula):
    /// corners at the corners, and any ξ at Σ N_c(ξ) x_c.
    #[test]
    fn point_at_is_the_trilinear_map_of_the_deformed_corners() {
        let l = lattice();
        let mut body = Body::full(l);
        body.update_displacements(|n, x, u| {
            *u = DVec3::new(0.01 * x.y, -0.02 * n as f64 * 1e-2, 0.03 * x.x)
        })
        .unwrap();
        let cell = l.cell_id([1, 0, 1]);
        let corners = body.corners(cell).unwrap();
        for (c, sign) in hex8::CORNER_XI.iter().enumerate() {
            let p = body.point_at(cell, DVec3::from_array(*sign)).unwrap();
            assert!((p - corners[c]).abs().max_element() < 1e-14, "corner {c}");
        }
        let xi = DVec3::new(0.3, -0.7, 0.1);
        let expected: DVec3 = hex8::CORNER_XI
            .iter()
            .zip(corners)
            .map(|(s, x)| {
                x * ((1.0 + xi.x * s[0]) * (1.0 + xi.y * s[1]) * (1.0 + xi.z * s[2]) / 8.0)
            })
            .sum();
        assert!(
            (body.point_at(cell, xi).unwrap() - expected)
                .abs()
                .max_element()
                < 1e-14
        );
        let mut holed = BitVec::repeat(true, l.cell_count());
        holed.set(0, false);
        let holed = Body::undeformed(l, holed).unwrap();
        assert!(holed.point_at(CellId(0), DVec3::ZERO).is_none());
        assert!(holed.cell_map(CellId(u32::MAX)).is_none());
    }

    #[test]
    fn only_nodes_of_active_cells_carry_displacements() {
        let l = lattice();
        let mut active = BitVec::repeat(false, l.cell_count());
        active.set(0, true);
        let body = Body::undeformed(l, active).unwrap();
        assert_eq!(body.node_count(), 8);
        let corners = l.corner_nodes([0, 0, 0]);
        let nodes: Vec<usize> = body.nodes().collect();
        let mut sorted = corners.to_vec();
        sorted.sort_unstable();
        assert_eq!(nodes, sorted);
        assert!(body.displacement(l.node_index([3, 0, 0])).is_none());
    }

    /// An update whose closure wrote a NaN and then panicked left the NaN in the body: a locator
    /// built on it then answered every point as in no cell (found by an API audit). The body is
    /// now undeformed after such a panic, as after an error, on every storage.
    #[test]
    fn a_panicking_update_leaves_the_body_undeformed() {
        let l = lattice();
        let cells = [CellId(0), CellId(5)];
        for mut body in [
            Body::full(l),
            Body::from_cells(l, cells).unwrap(),
            Body::undeformed(l, BitVec::repeat(true, l.cell_count())).unwrap(),
        ] {
            body.update_displacements(|_, _, u| *u = DVec3::splat(0.01))
                .unwrap();
            let count = body.nodes().count();
            let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                let mut seen = 0;
                body.update_displacements(|_, _, u| {
                    seen += 1;
                    *u = DVec3::NAN;
                    assert!(seen < count / 2, "the solver's closure panics");
                })
            }));
            assert!(panicked.is_err());
            assert!(
                body.nodes()
                    .all(|n| body.displacement(n) == Some(DVec3::ZERO)),
                "a value written before the panic was kept"
            );
            body.validate().unwrap();
        }
    }

    #[test]
    fn dense_field_and_in_place_update() {
        let l = lattice();
        let dense: Vec<DVec3> = (0..l.node_count())
            .map(|n| DVec3::splat(n as f64 * 1e-3))
            .collect();
        let mut body = Body::from_dense(l, BitVec::repeat(true, l.cell_count()), &dense).unwrap();
        assert_eq!(body.node_count(), l.node_count());
        assert_eq!(body.displacement(7), Some(dense[7]));
        body.update_displacements(|node, x, u| *u = x * 0.0 + DVec3::X * node as f64 * 1e-4)
            .unwrap();
        assert_eq!(body.displacement(7), Some(DVec3::X * 7e-4));
        assert!((body.max_displacement().x - (l.node_count() - 1) as f64 * 1e-4).abs() < 1e-15);
    }

    /// A full body keeps no slot table; it answers exactly as the same field on a body with one
    /// inactive cell (which keeps the table) wherever both have the node.
    #[test]
    fn full_body_needs_no_slot_table() {
        let l = lattice();
        let field =
            |n: usize| DVec3::new(n as f64 * 1e-3, -(n as f64) * 2e-3, 0.5e-3 * (n % 7) as f64);
        let dense: Vec<DVec3> = (0..l.node_count()).map(field).collect();
        let full = Body::from_dense(l, BitVec::repeat(true, l.cell_count()), &dense).unwrap();
        let mut mask = BitVec::repeat(true, l.cell_count());
        mask.set(0, false);
        let holed = Body::from_dense(l, mask, &dense).unwrap();
        assert_eq!(
            full.nodes().collect::<Vec<_>>(),
            (0..l.node_count()).collect::<Vec<_>>()
        );
        assert_eq!(full.nodes().count(), full.node_count());
        assert_eq!(
            holed.nodes().count(),
            l.node_count() - 1,
            "corner node 0 of cell 0 is unused"
        );
        assert_eq!(full.displacement(l.node_count()), None);
        assert_eq!(
            full.heap_bytes(),
            l.cell_count().div_ceil(64) * 8 + l.node_count() * size_of::<DVec3>()
        );
        assert!(holed.heap_bytes() > full.heap_bytes());
        for cell in 1..l.cell_count() as u32 {
            let ijk = l.cell_ijk(CellId(cell)).unwrap();
            let expected = l.corner_nodes(ijk).map(field);
            assert_eq!(full.corner_displacements(ijk), expected);
            assert_eq!(holed.corner_displacements(ijk), expected);
            assert_eq!(full.corner_displacements_or_zero(ijk), expected);
        }
        let first = holed.corner_displacements_or_zero([0, 0, 0]);
        assert_eq!(first[0], DVec3::ZERO);
        assert_eq!(first[6], field(l.corner_nodes([0, 0, 0])[6]));
    }

    #[test]
    fn bad_input_is_an_error() {
        let l = lattice();
        assert_eq!(
            Body::undeformed(l, BitVec::repeat(false, l.cell_count())).unwrap_err(),
            Error::EmptyBody
        );
        assert!(matches!(
            Body::undeformed(l, BitVec::repeat(true, 3)),
            Err(Error::LengthMismatch { .. })
        ));
        let mut body = Body::full(l);
        let mut u = vec![DVec3::ZERO; body.node_count()];
        u[5] = DVec3::new(0.0, f64::NAN, 0.0);
        assert!(matches!(
            body.set_displacements(&u),
            Err(Error::NonFiniteDisplacement { node: 5, .. })
        ));
        assert!(matches!(
            body.set_displacements(&u[1..]),
            Err(Error::LengthMismatch { .. })
        ));
        let err = body
            .update_displacements(|n, _, u| {
                if n == 9 {
                    u.x = f64::INFINITY
                }
            })
            .unwrap_err();
        assert!(matches!(err, Error::NonFiniteDisplacement { node: 9, .. }));
        assert!(body.displacements().iter().all(|u| *u == DVec3::ZERO));
    }

    #[test]
    fn cells_sheared_beyond_the_coordinates_resolution_are_named() {
        // Two cells stacked along z, far from the origin, thin along z; u_z = s (Y − Y0): a
        // rounding of y (4 ε 1e7 ≈ 9e-9) moves z by s times that, against a half cell of 7.8e-6.
        let sheared = |origin: DVec3, s: f64| {
            let h = DVec3::new(0.03125, 0.001953125, 1.5625e-5);
            let lattice = Lattice::new(origin, h, [1, 1, 2]).unwrap();
            let mut body = Body::full(lattice);
            body.update_displacements(|_, x, u| *u = DVec3::new(0.0, 0.0, s * (x.y - origin.y)))
                .unwrap();
            body.unresolved_cells()
        };
        let far = DVec3::splat(-1e7);
        // Shear 1e3: about 1.1 of a cell in ξ_z, both cells named.
        let named = sheared(far, 1e3);
        assert_eq!(named.iter().map(|(c, _)| c.0).collect::<Vec<_>>(), [0, 1]);
        assert!(
            named.iter().all(|&(_, share)| share > 1.0 && share < 1.3),
            "{named:?}"
        );
        // Only y's rounding matters (row z of J⁻¹): far along y alone, the same; far along x and
        // z alone (y near 0), none.
        let only_y = sheared(DVec3::new(0.0, -1e7, 0.0), 1e3);
        assert_eq!(only_y.len(), 2, "{only_y:?}");
        assert!(sheared(DVec3::new(-1e7, 0.0, -1e7), 1e3).is_empty());
        // Shear 10 at the same place (about 0.013), shear 1e3 near the origin, and no shear: none.
        assert!(sheared(far, 10.0).is_empty());
        assert!(sheared(DVec3::ZERO, 1e3).is_empty());
        assert!(sheared(far, 0.0).is_empty());
    }

    #[test]
    fn inverted_cells_are_named() {
        let l = lattice();
        let mut body = Body::full(l);
        assert!(body.validate().is_ok());
        // Push node (1, 1, 1) past its neighbours along x: cells on both sides of it fold over.
        let target = l.node_index([1, 1, 1]);
        body.update_displacements(|n, _, u| {
            if n == target {
                u.x = 0.8
            }
        })
        .unwrap();
        let inverted = body.inverted_cells();
        assert!(!inverted.is_empty());
        for (cell, ratio) in &inverted {
            assert!(*ratio <= 0.0);
            let ijk = l.cell_ijk(*cell).unwrap();
            assert!(
                l.corner_nodes(ijk).contains(&target),
                "{cell} does not touch the moved node"
            );
        }
        assert!(matches!(body.validate(), Err(Error::InvertedCells(_))));
    }
}
