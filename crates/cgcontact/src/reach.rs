//! Where each part of a deformed body can reach, so that a search's work is bounded by the local
//! displacement, not by the largest one.
//!
//! A point x held by deformed cell c lies in the bounds of c's deformed corners (a trilinear cell
//! lies in their convex hull), so in c's undeformed box shifted by the range of its corner
//! displacements (both widened by the inside tolerance, see [`widening`]). The latter holds for
//! any block of cells with the range of displacements over the block. So the candidates for x are
//! the cells whose own bounds hold x, found by descending a pyramid of blocks (2³ cells, then 2³
//! of those, ...: an octree over the lattice) that keeps, per block, the displacement range of the
//! nodes of its active cells. A rigid translation then costs O(1) per point, and a single
//! far-moved node only the blocks that hold it. Leaves of 2³ cells and two children per axis
//! measured fewest instructions for a far-moved node (516 M against 680 M with 4³-cell leaves and
//! 741 M with 4³ children per level, the `locality` bench's scenes under callgrind).
//!
//! The pyramid is built only when the displacements' spread makes the search box of the ring walk
//! larger than [`RING_CELLS`] cells; below that, the ring walk with the per-cell test is cheaper.

use glam::DVec3;
use smallvec::SmallVec;

use crate::PointError;
use crate::body::Body;
use crate::hex8::NewtonOptions;
use crate::lanes::{V3, Wide};
use crate::lattice::{CORNER_OFFSETS, Lattice};
use crate::settings::InsideTolerance;

/// Cells of a search box up to which the ring walk visits every cell (each tested by its own
/// bounds before any inversion); above, the pyramid finds the candidates.
pub(crate) const RING_CELLS: u64 = 125;

/// log2 of a block's edge in children per axis (2).
const FANOUT_BITS: u32 = 1;

/// log2 of the finest blocks' edge, in cells.
const LEAF_BITS: u32 = 1;

/// A candidate cell found by the pyramid, with its place in the ring order.
pub(crate) type Candidate = ([u32; 4], [u32; 3]);

/// Candidates of one search: a handful in a smooth field, more where a block reaches far.
pub(crate) type Candidates = SmallVec<[Candidate; 32]>;

/// A displacement range: the lowest and highest component per axis (empty: low > high).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Range {
    pub(crate) low: DVec3,
    pub(crate) high: DVec3,
}

impl Range {
    pub(crate) const EMPTY: Self = Self {
        low: DVec3::INFINITY,
        high: DVec3::NEG_INFINITY,
    };

    /// The range of a cell's corner displacements.
    #[inline(always)]
    pub(crate) fn of(u: &[DVec3; 8]) -> Self {
        let (mut low, mut high) = (u[0], u[0]);
        for &u in &u[1..] {
            low = low.min(u);
            high = high.max(u);
        }
        Self { low, high }
    }

    #[inline]
    fn union(self, other: Self) -> Self {
        Self {
            low: self.low.min(other.low),
            high: self.high.max(other.high),
        }
    }

    /// Whether `rel`, a point relative to the lowest corner of an undeformed box of size `size`, can
    /// lie in that box shifted by this range, up to the inside tolerance `tau` (ξ units).
    #[inline(always)]
    pub(crate) fn reaches(&self, rel: DVec3, size: DVec3, h: DVec3, tau: f64) -> bool {
        let w = widening(h, self.high - self.low, tau);
        // Written so that an empty range (low = +inf) or a NaN answers false.
        rel.cmpge(self.low - w).all() && rel.cmple(size + self.high + w).all()
    }
}

/// Which points a body can hold at all, and with what inside tolerance: the lattice's box shifted
/// by the displacement range and widened by the tolerance. The first step of every search (the
/// lattice locator's and the adaptive one's, scalar or batched).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Admit {
    /// The inside tolerance's constants.
    pub(crate) inside_tol: InsideTolerance,
    /// The lattice's box shifted by the displacement range.
    pub(crate) low: DVec3,
    pub(crate) high: DVec3,
    /// The box's widening per unit of inside tolerance ([`widening`]).
    pub(crate) pad: DVec3,
}

impl Admit {
    pub(crate) fn new(inside_tol: InsideTolerance, lattice: &Lattice, range: Range) -> Self {
        Self {
            inside_tol,
            low: lattice.origin() + range.low,
            high: lattice.upper() + range.high,
            pad: widening(lattice.h(), range.high - range.low, 1.0),
        }
    }

    /// The rounding length of `x` ([`InsideTolerance::length`]) when some cell can hold it,
    /// `Ok(None)` when it lies outside the shifted box (widened by [`InsideTolerance::tau`], as
    /// every filter is), an error when it is not finite.
    #[inline(always)]
    pub(crate) fn admit(&self, x: DVec3) -> Result<Option<DVec3>, PointError> {
        if !x.is_finite() {
            return Err(PointError::NonFinite);
        }
        let length = self.inside_tol.length(x);
        let slack = self.pad * self.inside_tol.tau(length);
        if x.cmplt(self.low - slack).any() || x.cmpgt(self.high + slack).any() {
            return Ok(None);
        }
        Ok(Some(length))
    }

    /// [`Admit::admit`] for W points in f64 lanes, the same operations: the lanes whose point is
    /// finite, and those within reach (bits). (The lanes' Newton needs no rounding length: a
    /// lane converged within it but beyond 1 + t is redone by the scalar kernel.)
    #[inline(always)]
    pub(crate) fn lanes<D: Wide>(&self, x: V3<D>) -> (u32, u32) {
        let splat = V3::<D>::splat;
        let length = self.inside_tol.length_lanes(x);
        let slack = splat(self.pad).scale(self.inside_tol.tau_lanes(length));
        let (low, high) = (splat(self.low) - slack, splat(self.high) + slack);
        let outside = x.x.lt(low.x) | x.y.lt(low.y) | x.z.lt(low.z);
        let outside = outside | x.x.gt(high.x) | x.y.gt(high.y) | x.z.gt(high.z);
        let finite = x.is_finite();
        (D::bits(finite), D::bits(finite & !outside))
    }

    /// The Newton options for a point `admit` gave `length`: `base` with this body's allowances.
    #[inline(always)]
    pub(crate) fn options(&self, base: &NewtonOptions, length: DVec3) -> NewtonOptions {
        NewtonOptions {
            inside_length: length,
            ..*base
        }
    }

    /// The filters' widening, ξ units, for a search with `options` ([`InsideTolerance::tau`]).
    #[inline(always)]
    pub(crate) fn tau(&self, options: &NewtonOptions) -> f64 {
        self.inside_tol.tau(options.inside_length)
    }
}

/// How far outside a cell's shifted box a point may be and still be found inside it by a Newton
/// inversion with inside tolerance `tau` (the largest of the per-axis tolerances: the filters
/// widen by it on every axis, a superset of what each axis needs): at |ξ_k| ≤ 1 + τ the
/// undeformed part leaves the cell by τh/2 and the trilinear extrapolation of the displacements
/// leaves their range by at most ((1 + τ)³ − 1)/2 ≈ 1.5τ of its width `spread`. 2τ (h + spread)
/// per axis covers both, and covers [`cell_reaches`]'s widening of a cell of the range, so that a
/// block's test passes wherever one of its cells' does.
#[inline(always)]
pub(crate) fn widening(h: DVec3, spread: DVec3, tau: f64) -> DVec3 {
    2.0 * tau * (h + spread)
}

/// Whether `rel`, a point relative to the lowest undeformed node of a cell of spacing `h` whose
/// corners are displaced by `u`, can lie in the deformed cell: in the bounds of its deformed corners
/// (a trilinear cell lies in their convex hull), widened by 2τ times their extent (an inversion
/// accepting |ξ_k| ≤ 1 + τ leaves the hull by at most ((1 + τ)³ − 1)/2 ≈ 1.5τ of it).
#[inline(always)]
pub(crate) fn cell_reaches(rel: DVec3, h: DVec3, u: &[DVec3; 8], tau: f64) -> bool {
    let (mut low, mut high) = (u[0], u[0]);
    for (c, &u) in u.iter().enumerate().skip(1) {
        let [a, b, d] = CORNER_OFFSETS[c];
        let corner = DVec3::new(f64::from(a), f64::from(b), f64::from(d)) * h + u;
        low = low.min(corner);
        high = high.max(corner);
    }
    let w = 2.0 * tau * (high - low);
    // Written so that NaN answers false.
    if !(rel.cmpge(low - w).all() && rel.cmple(high + w).all()) {
        return false;
    }
    // A cell stretched past twice its size (a far-moved node, an inverted cell) is a needle or a
    // sliver whose box is mostly empty, and its inversion is the costliest kind: also test the
    // hull's extent along the six face diagonals (the same widening, along each).
    if (high - low).cmple(2.0 * h).all() {
        return true;
    }
    DIAGONALS.iter().all(|&n| {
        let (mut low, mut high) = (n.dot(u[0]), n.dot(u[0]));
        for (c, &u) in u.iter().enumerate().skip(1) {
            let [a, b, d] = CORNER_OFFSETS[c];
            let p = n.dot(DVec3::new(f64::from(a), f64::from(b), f64::from(d)) * h + u);
            low = low.min(p);
            high = high.max(p);
        }
        let (r, w) = (n.dot(rel), 2.0 * tau * (high - low));
        r >= low - w && r <= high + w
    })
}

/// The face diagonals, the directions along which a stretched cell's hull is also bounded.
const DIAGONALS: [DVec3; 6] = [
    DVec3::new(1.0, 1.0, 0.0),
    DVec3::new(1.0, -1.0, 0.0),
    DVec3::new(1.0, 0.0, 1.0),
    DVec3::new(1.0, 0.0, -1.0),
    DVec3::new(0.0, 1.0, 1.0),
    DVec3::new(0.0, 1.0, -1.0),
];

/// One level of the pyramid: blocks of 2^shift cells per axis.
#[derive(Clone, Debug)]
struct Level {
    /// log2 of a block's edge in cells.
    shift: u32,
    /// Blocks per axis.
    blocks: [u32; 3],
    /// The displacement range of each block (x fastest), empty where it has no active cell.
    ranges: Vec<Range>,
}

impl Level {
    #[inline]
    fn index(&self, b: [u32; 3]) -> usize {
        let [nx, ny, _] = self.blocks.map(|n| n as usize);
        b[0] as usize + nx * (b[1] as usize + ny * b[2] as usize)
    }
}

/// The displacement ranges of a body's blocks of cells, finest level first.
#[derive(Clone, Debug, Default)]
pub(crate) struct Pyramid {
    levels: Vec<Level>,
}

impl Pyramid {
    /// The pyramid of `body`: one pass over its active cells' corners, then one over each level.
    pub(crate) fn new(body: &Body) -> Self {
        let lattice = body.lattice();
        Self::from_ranges(
            lattice.cells(),
            body.active_cells().map(|cell| {
                let ijk = lattice
                    .cell_ijk(cell)
                    .expect("active cells lie in the lattice");
                (ijk, Range::of(&body.corner_displacements(ijk)))
            }),
        )
    }

    /// The pyramid over a lattice of `cells` cells per axis from the displacement range of each
    /// cell that has one (`(ijk, range)`, a cell may come several times: the ranges are joined;
    /// an adaptive body gives each leaf's under its base cell).
    pub(crate) fn from_ranges(
        cells: [u32; 3],
        ranges: impl IntoIterator<Item = ([u32; 3], Range)>,
    ) -> Self {
        let blocks_of =
            |shift: u32| cells.map(|n| ((u64::from(n) + (1 << shift) - 1) >> shift) as u32);
        let mut finest = Level {
            shift: LEAF_BITS,
            blocks: blocks_of(LEAF_BITS),
            ranges: Vec::new(),
        };
        finest.ranges = vec![Range::EMPTY; finest.blocks.iter().map(|&n| n as usize).product()];
        for (ijk, range) in ranges {
            let slot = finest.index(ijk.map(|i| i >> LEAF_BITS));
            finest.ranges[slot] = finest.ranges[slot].union(range);
        }
        let mut levels = vec![finest];
        loop {
            let below = levels.last().expect("the finest level");
            if below.blocks.iter().all(|&n| n <= 1 << FANOUT_BITS) {
                break;
            }
            let shift = below.shift + FANOUT_BITS;
            let mut level = Level {
                shift,
                blocks: blocks_of(shift),
                ranges: Vec::new(),
            };
            level.ranges = vec![Range::EMPTY; level.blocks.iter().map(|&n| n as usize).product()];
            for k in 0..below.blocks[2] {
                for j in 0..below.blocks[1] {
                    for i in 0..below.blocks[0] {
                        let range = below.ranges[below.index([i, j, k])];
                        let slot = level.index([i, j, k].map(|b| b >> FANOUT_BITS));
                        level.ranges[slot] = level.ranges[slot].union(range);
                    }
                }
            }
            levels.push(level);
        }
        Self { levels }
    }

    /// The displacement range of the finest block holding cell `ijk` (in the lattice; empty
    /// where the block has no active cell).
    #[inline]
    pub(crate) fn range_at(&self, ijk: [u32; 3]) -> Range {
        let level = &self.levels[0];
        level.ranges[level.index(ijk.map(|i| i >> level.shift))]
    }

    /// Bytes on the heap.
    pub(crate) fn heap_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.ranges.capacity() * size_of::<Range>())
            .sum()
    }

    /// Descends to every finest block that meets the box of cells [`low`, `high`] and that
    /// `keep` admits, as every block above it: `keep(first, cells, range)` is given a block's
    /// lowest cell, its edge in cells and the displacement range of its cells (empty where it
    /// has none). `leaf(from, to, range)` is then given the admitted finest block's cells
    /// clipped to the box, [`from`, `to`], and its range. Blocks come depth first, in no
    /// particular order.
    pub(crate) fn descend(
        &self,
        low: [u32; 3],
        high: [u32; 3],
        mut keep: impl FnMut([u32; 3], u32, &Range) -> bool,
        mut leaf: impl FnMut([u32; 3], [u32; 3], &Range),
    ) {
        let top = self.levels.len() - 1;
        let mut stack: SmallVec<[(usize, [u32; 3]); 64]> = SmallVec::new();
        let shift = self.levels[top].shift;
        for k in low[2] >> shift..=high[2] >> shift {
            for j in low[1] >> shift..=high[1] >> shift {
                for i in low[0] >> shift..=high[0] >> shift {
                    stack.push((top, [i, j, k]));
                }
            }
        }
        while let Some((l, b)) = stack.pop() {
            let level = &self.levels[l];
            let range = &level.ranges[level.index(b)];
            let first = b.map(|b| b << level.shift);
            if !keep(first, 1 << level.shift, range) {
                continue;
            }
            let last = first.map(|f| f + (1 << level.shift) - 1);
            let from = [0, 1, 2].map(|a| first[a].max(low[a]));
            let to = [0, 1, 2].map(|a| last[a].min(high[a]));
            if (0..3).any(|a| from[a] > to[a]) {
                continue;
            }
            if l == 0 {
                leaf(from, to, range);
                continue;
            }
            let child = self.levels[l - 1].shift;
            for k in from[2] >> child..=to[2] >> child {
                for j in from[1] >> child..=to[1] >> child {
                    for i in from[0] >> child..=to[0] >> child {
                        stack.push((l - 1, [i, j, k]));
                    }
                }
            }
        }
    }

    /// The active cells of `body` in the box of cells [`low`, `high`] whose own shifted box holds
    /// `x` (lattice coordinates `t_x`) with inside tolerance `tau`, each with its key in the ring
    /// order around `center`, pushed to `out` (unsorted).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn candidates(
        &self,
        body: &Body,
        x: DVec3,
        t_x: DVec3,
        low: [u32; 3],
        high: [u32; 3],
        center: [u32; 3],
        tau: f64,
        out: &mut Candidates,
    ) {
        let lattice = body.lattice();
        let h = lattice.h();
        let keep = |first: [u32; 3], edge: u32, range: &Range| {
            range.reaches(
                x - lattice.node_position(first),
                h * f64::from(edge),
                h,
                tau,
            )
        };
        self.descend(low, high, keep, |from, to, range| {
            // The cells of this block that its range lets reach x: X = x − u, u in the range, and
            // cell i spans [i, i + 1] in lattice coordinates.
            let w = widening(h, range.high - range.low, tau);
            let t_low = t_x - (range.high + w) / h;
            let t_high = t_x - (range.low - w) / h;
            let (mut lo, mut hi) = ([0u32; 3], [0u32; 3]);
            let mut empty = false;
            for a in 0..3 {
                let l = (t_low[a].floor() - 1.0).max(f64::from(from[a]));
                let u = t_high[a].floor().min(f64::from(to[a]));
                // NaN (a non-finite range) empties the box too.
                if l.partial_cmp(&u).is_none_or(|o| o.is_gt()) {
                    empty = true;
                    break;
                }
                (lo[a], hi[a]) = (l as u32, u as u32);
            }
            if empty {
                return;
            }
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        let ijk = [i, j, k];
                        if !body.is_active(lattice.cell_id(ijk)) {
                            continue;
                        }
                        let u = body.corner_displacements(ijk);
                        if cell_reaches(x - lattice.node_position(ijk), h, &u, tau) {
                            out.push((ring_key(ijk, center), ijk));
                        }
                    }
                }
            }
        });
    }
}

/// The place of cell `ijk` in the ring walk around `center`: Chebyshev distance, then z, y, x.
#[inline]
pub(crate) fn ring_key(ijk: [u32; 3], center: [u32; 3]) -> [u32; 4] {
    let r = (0..3)
        .map(|a| ijk[a].abs_diff(center[a]))
        .max()
        .unwrap_or(0);
    [r, ijk[2], ijk[1], ijk[0]]
}

/// The range of every displacement of `body` (signed, per axis): the deformed body lies in the
/// lattice's box shifted by it.
pub(crate) fn displacement_range(body: &Body) -> Range {
    body.displacements()
        .iter()
        .fold(Range::EMPTY, |r, &u| Range {
            low: r.low.min(u),
            high: r.high.max(u),
        })
}

/// Whether a search box of `spread / h` cells per axis (plus the cell holding x on each side) may
/// exceed [`RING_CELLS`] cells: then the pyramid pays for its build.
pub(crate) fn pyramid_pays(spread: DVec3, h: DVec3) -> bool {
    let cells = (spread / h + 2.0).min(DVec3::splat(1e7));
    cells.x * cells.y * cells.z > RING_CELLS as f64
}
