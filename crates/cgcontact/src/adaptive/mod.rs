//! h-adaptive bodies: leaf cells at several refinement levels of one base lattice, hanging nodes
//! and their Q1 constraints, and the locator that searches them.
//!
//! A cell of level l has edges h/2^l and its lowest corner at o + (i, j, k)·h/2^l: a [`Leaf`]. The
//! body lists its leaves (they tile it without overlap; regions no leaf covers are outside, as
//! inactive cells of a uniform body are). Nodes are shared by the leaves that meet there and are
//! numbered by owner cell (`nodes.rs`): the base cell whose half-open box holds them, owners in
//! lattice order (z, then y, then x), and within an owner by finest-level position in the same
//! order. With one level that is the uniform body's node order.
//!
//! | file | what |
//! |---|---|
//! | `mod.rs` | [`AdaptiveBody`]: leaves, nodes, displacements, the constraint API |
//! | `leaves.rs` | the leaves, packed in 8 bytes each |
//! | `nodes.rs` | the node numbering: a leaf's corner nodes computed from its position |
//! | `forest.rs` | the base cell index, bricks and octrees under it: point → leaf, box → leaves |
//! | `hanging.rs` | hanging nodes and the leaves they hang on |
//! | `locate.rs` | [`AdaptiveLocator`]: predicted leaf first, then every leaf that can hold the point |
//! | `lanes.rs` | the locator's batched path: 4 points at a time in SIMD lanes |
//!
//! Memory grows with the leaves and their nodes (per node: its displacement, 24 bytes, and about 3
//! of numbering; per leaf: 8 bytes, and about 4 of brick or octree; 12 per hanging node; 32 more
//! per leaf with [`AdaptiveBody::set_corner_table`]): a body refined 6 levels in one corner
//! allocates nothing of the finest level's lattice.

mod forest;
mod hanging;
mod lanes;
mod leaves;
mod locate;
mod nodes;

use glam::DVec3;

use crate::Error;
use crate::error::{displacement_error, displacement_ok};
use crate::hex8::{self, Kernel};
use crate::lattice::{CORNER_OFFSETS, CellId, Lattice};
use crate::settings::{InsideTolerance, Settings};
use forest::{Forest, Overlap};
use hanging::{Constraints, Direct, corner_weights};
use leaves::LeafStore;
use nodes::Nodes;

pub use hanging::{ConstraintReport, FlatConstraints};
pub use leaves::Leaves;
pub use locate::AdaptiveLocator;

/// The deepest level of a leaf.
pub const MAX_LEVEL: u8 = 20;
/// Bits per axis of a finest-level coordinate: at most 2^21 - 1 finest cells per axis.
const KEY_BITS: u32 = 21;

/// A leaf cell: its refinement level and its indices on that level's lattice (spacing h/2^level).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Leaf {
    /// Refinement level, 0 for a base cell.
    pub level: u8,
    /// Indices of the lowest corner on the level's lattice.
    pub ijk: [u32; 3],
}

impl Leaf {
    /// A leaf of `level` at `ijk`.
    #[must_use]
    pub fn new(level: u8, ijk: [u32; 3]) -> Self {
        Self { level, ijk }
    }

    /// The 8 leaves of the next level that refine this one, in binary order (bit 0: +x, ...).
    ///
    /// A leaf of level 255, or with an index of 2^31 or more, has no children a body can hold:
    /// its level, or those indices, saturate (at 255 and `u32::MAX`), into leaves that
    /// [`AdaptiveBody::from_leaves`] refuses.
    #[must_use]
    pub fn children(self) -> [Leaf; 8] {
        std::array::from_fn(|c| Leaf {
            level: self.level.saturating_add(1),
            ijk: [0, 1, 2].map(|a| {
                self.ijk[a]
                    .checked_mul(2)
                    .map_or(u32::MAX, |v| v + ((c as u32 >> a) & 1))
            }),
        })
    }

    /// The base lattice cell (level 0) this leaf lies in.
    ///
    /// ```
    /// use cgcontact::Leaf;
    /// assert_eq!(Leaf::new(2, [5, 0, 11]).base(), [1, 0, 2]);
    /// assert_eq!(Leaf::new(0, [5, 0, 11]).base(), [5, 0, 11]);
    /// ```
    #[must_use]
    pub fn base(self) -> [u32; 3] {
        // Checked: a shift by 32 or more overflowed (a level that no body holds, but a `Leaf`
        // can be made with it); the quotient is then 0.
        self.ijk
            .map(|v| v.checked_shr(u32::from(self.level)).unwrap_or(0))
    }
}

/// The leaves' faces on the boundary surface.
#[derive(Clone, Debug)]
struct OpenFaces {
    /// Per leaf, its local faces not covered from the other side (bit f: face f): 1 byte a leaf.
    leaves: Box<[u8]>,
    /// The base cells (index, x fastest) holding a leaf with such a face, ascending.
    bases: Box<[u32]>,
}

/// A body meshed by leaf cells of several refinement levels of a base lattice, deformed by nodal
/// displacements that obey (or are reported against) the hanging nodes' constraints.
#[derive(Clone, Debug)]
pub struct AdaptiveBody {
    /// The base lattice (level 0).
    lattice: Lattice,
    /// The deepest level of any leaf.
    finest: u8,
    leaves: LeafStore,
    /// The node numbering: a leaf's corner nodes are computed from its position.
    nodes: Nodes,
    /// Each leaf's corner nodes, when stored ([`AdaptiveBody::set_corner_table`]); else empty.
    corner_table: Vec<[u32; 8]>,
    u: Vec<DVec3>,
    forest: Forest,
    hanging: Constraints,
    /// How far (length units, per axis) the hanging nodes may lie off the leaves they hang on
    /// ([`AdaptiveBody::set_seam`]): the locator's allowance grows by it.
    seam: DVec3,
    /// What the gap search measures, from the geometry alone: computed once, by the first gap
    /// search's [`AdaptiveBody::prepare_open_faces`], and kept.
    open_faces: std::sync::OnceLock<Box<OpenFaces>>,
}

/// The last leaf whose corners [`AdaptiveBody::bound_value`] computed, and those corners.
#[derive(Clone, Copy, Default)]
struct CornerCache(Option<(u32, [u32; 8])>);

impl AdaptiveBody {
    /// An undeformed body of `leaves` on the base `lattice`; a leaf's id ([`CellId`]) is its
    /// position in `leaves`.
    ///
    /// Errors, naming the leaf, when a leaf is deeper than [`MAX_LEVEL`], lies outside the
    /// lattice, or overlaps another, when the finest level's lattice exceeds 2^21 − 1 cells per
    /// axis or is too fine for its coordinates ([`Lattice::check_resolution`]), or when there is
    /// no leaf.
    pub fn from_leaves(lattice: Lattice, leaves: Vec<Leaf>) -> Result<Self, Error> {
        if leaves.is_empty() {
            return Err(Error::EmptyBody);
        }
        if leaves.len() >= (1 << 31) {
            return Err(Error::InvalidLeaf {
                cell: CellId(u32::MAX),
                reason: format!(
                    "{} leaves exceed the 2^31 this library indexes",
                    leaves.len()
                ),
            });
        }
        let counts = lattice.cells();
        let mut finest = 0;
        for (id, leaf) in leaves.iter().enumerate() {
            let bad = |reason: String| Error::InvalidLeaf {
                cell: CellId(id as u32),
                reason,
            };
            if leaf.level > MAX_LEVEL {
                return Err(bad(format!(
                    "level {} is deeper than {MAX_LEVEL}",
                    leaf.level
                )));
            }
            let l = u32::from(leaf.level);
            for a in 0..3 {
                if u64::from(leaf.ijk[a]) >= u64::from(counts[a]) << l {
                    return Err(bad(format!(
                        "indices {:?} at level {} lie outside the base lattice's {:?} cells",
                        leaf.ijk, leaf.level, counts
                    )));
                }
            }
            finest = finest.max(leaf.level);
        }
        lattice.check_resolution(lattice.h() / f64::from(1u32 << finest))?;
        if let Some(&n) = counts.iter().max() {
            if u64::from(n) << finest >= 1 << KEY_BITS {
                return Err(Error::InvalidLattice(format!(
                    "{n} base cells refined {finest} levels exceed the 2^{KEY_BITS} - 1 finest cells per axis this library indexes"
                )));
            }
        }
        let forest = Forest::new(counts, &leaves).map_err(|(id, Overlap(other))| {
            Error::OverlappingCells {
                cell: CellId(id),
                other: CellId(other),
            }
        })?;

        // Nodes: every corner's finest-level coordinates, numbered by their owner cells.
        let mut positions: Vec<[u32; 3]> = Vec::with_capacity(8 * leaves.len());
        for leaf in &leaves {
            let s = finest - leaf.level;
            for off in CORNER_OFFSETS {
                positions.push([0, 1, 2].map(|a| (leaf.ijk[a] + off[a]) << s));
            }
        }
        let nodes = Nodes::new(counts, finest, positions);
        let mut body = Self {
            lattice,
            finest,
            u: vec![DVec3::ZERO; nodes.len()],
            leaves: LeafStore::new(leaves, counts, finest),
            nodes,
            corner_table: Vec::new(),
            forest,
            hanging: Constraints::default(),
            seam: DVec3::ZERO,
            open_faces: std::sync::OnceLock::new(),
        };
        body.hanging = body.find_hanging();
        Ok(body)
    }

    /// Every hanging node's constraint, flattened.
    fn find_hanging(&self) -> Constraints {
        let finest = u32::from(self.finest);
        let limit = self.lattice.cells().map(|n| n << finest);
        let mut direct = Vec::new();
        let Ok(()) = self.nodes.try_for_each_position(|node, p| {
            // The coarsest leaf that holds p without having it as a corner (lowest id on a tie).
            let mut binding: Option<(u8, u32)> = None;
            for octant in 0..8u32 {
                let mut q = [0u32; 3];
                let mut inside = true;
                for a in 0..3 {
                    let upper = (octant >> a) & 1 == 1;
                    if upper {
                        inside &= p[a] < limit[a];
                        q[a] = p[a];
                    } else {
                        inside &= p[a] > 0;
                        q[a] = p[a].wrapping_sub(1);
                    }
                }
                if !inside {
                    continue;
                }
                let Some(id) = self.forest.leaf_at_finest(q, self.finest) else {
                    continue;
                };
                let leaf = self.leaves.at(id);
                let s = finest - u32::from(leaf.level);
                let size = 1u32 << s;
                let rel = [0, 1, 2].map(|a| p[a] - (leaf.ijk[a] << s));
                if rel.iter().all(|&r| r == 0 || r == size) {
                    continue;
                }
                if binding.is_none_or(|best| (leaf.level, id) < best) {
                    binding = Some((leaf.level, id));
                }
            }
            if let Some((level, id)) = binding {
                direct.push(Direct {
                    node,
                    level,
                    leaf: id,
                });
            }
            Ok::<(), std::convert::Infallible>(())
        });
        Constraints::new(direct)
    }

    /// The base lattice.
    #[must_use]
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The deepest level of any leaf.
    #[must_use]
    pub fn finest_level(&self) -> u8 {
        self.finest
    }

    /// The leaves, in id order.
    #[must_use]
    pub fn leaves(&self) -> Leaves<'_> {
        Leaves(&self.leaves)
    }

    /// Number of leaves.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.leaves.len()
    }

    /// Number of nodes (hanging ones included).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The spacing of level `level`'s lattice, h / 2^level (exact).
    #[must_use]
    pub fn spacing(&self, level: u8) -> DVec3 {
        self.lattice.h() * locate::level_size(level)
    }

    /// The undeformed lowest corner of `leaf`: o + ijk · h/2^level.
    #[must_use]
    pub fn leaf_origin(&self, leaf: Leaf) -> DVec3 {
        let [i, j, k] = leaf.ijk;
        self.lattice.origin() + self.spacing(leaf.level) * DVec3::new(i as f64, j as f64, k as f64)
    }

    /// The undeformed position of `node`, `None` when out of range.
    #[must_use]
    pub fn node_position(&self, node: usize) -> Option<DVec3> {
        let q = self.nodes.position(
            u32::try_from(node)
                .ok()
                .filter(|&n| (n as usize) < self.nodes.len())?,
        );
        let h = self.spacing(self.finest);
        Some(self.lattice.origin() + h * DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64))
    }

    /// The node at the finest-level lattice coordinates `q`, if the body has one there.
    #[must_use]
    pub fn node_at_finest(&self, q: [u32; 3]) -> Option<usize> {
        self.nodes.at(q).map(|n| n as usize)
    }

    /// The nodes of `cell`'s 8 corners, VTK order.
    #[must_use]
    pub fn cell_nodes(&self, cell: CellId) -> Option<[usize; 8]> {
        Some(
            self.leaf_nodes(cell.index() as u32, self.leaves.get(cell.index())?)
                .map(|n| n as usize),
        )
    }

    /// The leaf whose undeformed box holds `x` (on a boundary, the upper one), if any.
    #[must_use]
    pub fn leaf_at(&self, x: DVec3) -> Option<CellId> {
        let t = (x - self.lattice.origin()) / self.lattice.h();
        let inside = t.cmpge(DVec3::ZERO).all() && t.cmple(self.upper_t()).all();
        inside
            .then(|| self.forest.leaf_at(t))
            .flatten()
            .map(|(id, _)| CellId(id))
    }

    /// The base lattice's upper corner in lattice coordinates.
    fn upper_t(&self) -> DVec3 {
        let [a, b, c] = self.lattice.cells();
        DVec3::new(f64::from(a), f64::from(b), f64::from(c))
    }

    /// Every node's displacement, in node order.
    #[must_use]
    pub fn displacements(&self) -> &[DVec3] {
        &self.u
    }

    /// The largest displacement component this body accepts: its base lattice's
    /// [`Lattice::displacement_limit`] for the finest level's cells.
    #[must_use]
    pub fn displacement_limit(&self) -> f64 {
        self.lattice.displacement_limit(self.spacing(self.finest))
    }

    /// Sets every node's displacement (hanging ones included, as given: see
    /// [`AdaptiveBody::check_constraints`] and [`AdaptiveBody::fill_hanging`]).
    ///
    /// Errors on a length mismatch or a value not finite or beyond
    /// [`AdaptiveBody::displacement_limit`] (naming the node); the body is then unchanged.
    pub fn set_displacements(&mut self, u: &[DVec3]) -> Result<(), Error> {
        if u.len() != self.u.len() {
            return Err(Error::LengthMismatch {
                what: "node displacements",
                expected: self.u.len(),
                got: u.len(),
            });
        }
        let limit = self.displacement_limit();
        if let Some(node) = u.iter().position(|&v| !displacement_ok(v, limit)) {
            return Err(displacement_error(node, u[node], limit));
        }
        self.u.copy_from_slice(u);
        Ok(())
    }

    /// Sets each independent node's displacement with `f(node, undeformed position, &mut u)`, then
    /// fills the hanging nodes from their constraints: the solver-facing update, conforming by
    /// construction.
    ///
    /// Errors on a value not finite or beyond [`AdaptiveBody::displacement_limit`] (naming the
    /// node); the body then keeps its previous displacements.
    pub fn update_independent(
        &mut self,
        mut f: impl FnMut(usize, DVec3, &mut DVec3),
    ) -> Result<(), Error> {
        let mut u = self.u.clone();
        let mut row = 0;
        let h = self.spacing(self.finest);
        let origin = self.lattice.origin();
        let limit = self.displacement_limit();
        self.nodes.try_for_each_position(|node, q| {
            if self.hanging.nodes.get(row) == Some(&node) {
                row += 1;
                return Ok(());
            }
            let (node, u) = (node as usize, &mut u[node as usize]);
            let x = origin + h * DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2]));
            f(node, x, u);
            if displacement_ok(*u, limit) {
                Ok(())
            } else {
                Err(displacement_error(node, *u, limit))
            }
        })?;
        self.u = u;
        self.fill_hanging();
        Ok(())
    }

    /// Sets every hanging node's displacement to its constraint's value.
    pub fn fill_hanging(&mut self) {
        let mut corners = CornerCache::default();
        for &r in &self.hanging.order {
            let r = r as usize;
            let node = self.hanging.nodes[r];
            let value = self.bound_value(node, self.hanging.leaf[r], &mut corners);
            self.u[node as usize] = value;
        }
    }

    /// `node`'s local coordinates in `leaf` (`node` a point of the leaf's closed box; exact,
    /// dyadic).
    fn binding_xi(&self, node: u32, leaf: Leaf) -> DVec3 {
        let p = self.nodes.position(node);
        let s = u32::from(self.finest - leaf.level);
        let rel = [0, 1, 2].map(|a| f64::from(p[a] - (leaf.ijk[a] << s)));
        DVec3::from_array(rel) * (2.0 / f64::from(1u32 << s)) - 1.0
    }

    /// The corners of leaf `id` and their weights at `node` (the zero weights dropped): what
    /// `node` interpolates when it hangs on that leaf.
    fn binding(&self, node: u32, id: u32) -> Vec<(u32, f64)> {
        let leaf = self.leaves.at(id);
        corner_weights(&self.leaf_nodes(id, leaf), self.binding_xi(node, leaf))
    }

    /// The displacement leaf `id` interpolates at `node`: the sum of [`AdaptiveBody::binding`]'s
    /// terms in its order, without a list (it runs for every hanging node at every update). The
    /// leaf's corners come from `cache` when they are the last leaf's: the hanging nodes are
    /// visited leaf by leaf, and a leaf binds several.
    fn bound_value(&self, node: u32, id: u32, cache: &mut CornerCache) -> DVec3 {
        let leaf = self.leaves.at(id);
        let corners = match *cache {
            CornerCache(Some((last, corners))) if last == id => corners,
            _ => {
                let corners = self.leaf_nodes(id, leaf);
                *cache = CornerCache(Some((id, corners)));
                corners
            }
        };
        hex8::shape(self.binding_xi(node, leaf))
            .into_iter()
            .zip(corners)
            .filter(|&(w, _)| w != 0.0)
            .fold(DVec3::ZERO, |sum, (w, p)| sum + w * self.u[p as usize])
    }

    /// How far the hanging nodes are from their constraints: the count farther than `tol`
    /// (largest component, length units), and the worst node. A NaN tolerance holds no node
    /// within it: every hanging node is counted.
    #[must_use]
    pub fn check_constraints(&self, tol: f64) -> ConstraintReport {
        self.constraint_report(|off| {
            let by = off.max_element();
            // Written so that a NaN tolerance counts the node (`by > tol` passed every node).
            let within = by <= tol;
            (!within, (by, by), by)
        })
    }

    /// [`AdaptiveBody::check_constraints`] with a tolerance per axis: a node is off its
    /// constraint when some component of its offset exceeds that axis's tolerance, and the worst
    /// node is the one farthest beyond, in shares of the tolerance (its `by`: that component's
    /// offset, length units). On a lattice of spacings 1 : 1e-3, an offset of 1e-12 along x is
    /// 1e-12 of a cell, along y 1e-9 of one: one tolerance for every axis is either loose on
    /// the short axis or strict on the long ones. A NaN component holds no offset along its
    /// axis within it.
    #[must_use]
    pub fn check_constraints_per_axis(&self, tol: DVec3) -> ConstraintReport {
        self.constraint_report(|off| {
            let share: [f64; 3] = std::array::from_fn(|a| match (off[a], tol[a]) {
                (_, t) if t > 0.0 => off[a] / t,
                (o, _) if o > 0.0 => f64::INFINITY,
                _ => 0.0,
            });
            let axis = (0..3).fold(0, |m, a| if share[a] > share[m] { a } else { m });
            // Ties (a zero tolerance: every offset infinitely beyond) go to the larger offset.
            // `!cmple(..).all()`, not `cmpgt(..).any()`: a NaN tolerance counts the node.
            (!off.cmple(tol).all(), (share[axis], off[axis]), off[axis])
        })
    }

    /// The report of the hanging nodes' offsets from their constraints, `judge(offset)` giving
    /// whether a node is off, its rank for the worst (the larger pair wins), and its `by`.
    fn constraint_report(
        &self,
        judge: impl Fn(DVec3) -> (bool, (f64, f64), f64),
    ) -> ConstraintReport {
        let mut report = ConstraintReport {
            hanging: self.hanging.nodes.len(),
            violating: 0,
            worst: None,
        };
        let mut worst_rank = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut corners = CornerCache::default();
        // Leaf by leaf (the fill's order, which shares each leaf's corners); of nodes equally
        // far, the lowest is the worst, as in node order.
        for &r in &self.hanging.order {
            let r = r as usize;
            let node = self.hanging.nodes[r] as usize;
            let bound = self.bound_value(node as u32, self.hanging.leaf[r], &mut corners);
            let (breaks, rank, by) = judge((self.u[node] - bound).abs());
            if breaks {
                report.violating += 1;
            }
            let worse = match report.worst {
                None => true,
                Some((worst, _)) => rank > worst_rank || (rank == worst_rank && node < worst),
            };
            if worse {
                report.worst = Some((node, by));
                worst_rank = rank;
            }
        }
        report
    }

    /// The largest offset of any hanging node from its constraint, per axis (length units; zero
    /// without hanging nodes): how far the deformed mesh is from conforming at its fine/coarse
    /// interfaces.
    #[must_use]
    pub fn constraint_offsets(&self) -> DVec3 {
        let mut most = DVec3::ZERO;
        let mut corners = CornerCache::default();
        for &r in &self.hanging.order {
            let r = r as usize;
            let node = self.hanging.nodes[r];
            let bound = self.bound_value(node, self.hanging.leaf[r], &mut corners);
            most = most.max((self.u[node as usize] - bound).abs());
        }
        most
    }

    /// How far (length units, per axis) the hanging nodes may lie off the leaves they hang on:
    /// the locators built afterwards (and the gap search's sign) hold a point that much beyond a
    /// leaf's faces, on top of their inside tolerance, so that a point at a hanging node or on
    /// a fine face against a coarse one is held by the leaves on both sides. A mesh read from
    /// a file whose coordinates or displacements are 32-bit floats (VTK's default) or printed
    /// decimals is conforming only to their rounding: the reader sets that rounding here. Zero
    /// unless set.
    ///
    /// # Errors
    /// [`Error::InvalidSettings`] when a component is negative or not finite.
    pub fn set_seam(&mut self, seam: DVec3) -> Result<(), Error> {
        if !(seam.is_finite() && seam.cmpge(DVec3::ZERO).all()) {
            return Err(Error::InvalidSettings(format!(
                "the seam {seam} must be finite and not negative"
            )));
        }
        self.seam = seam;
        Ok(())
    }

    /// The seam set by [`AdaptiveBody::set_seam`] (zero unless set).
    #[must_use]
    pub fn seam(&self) -> DVec3 {
        self.seam
    }

    /// Whether `node` is hanging.
    #[must_use]
    pub fn is_hanging(&self, node: usize) -> bool {
        u32::try_from(node).is_ok_and(|n| self.hanging.contains(n))
    }

    /// The hanging nodes, ascending.
    pub fn hanging_nodes(&self) -> impl Iterator<Item = usize> + '_ {
        self.hanging.nodes.iter().map(|&n| n as usize)
    }

    /// The independent nodes and weights whose combination a hanging node's displacement must
    /// be, `None` when the node is not hanging.
    #[must_use]
    pub fn constraint(&self, node: usize) -> Option<Vec<(usize, f64)>> {
        let node = u32::try_from(node).ok()?;
        let r = self.hanging.row(node)?;
        // A parent that hangs hangs on a coarser leaf: the recursion ends within the levels.
        let mut flat = Vec::new();
        let mut stack = vec![(node, self.hanging.leaf[r], 1.0)];
        while let Some((node, leaf, weight)) = stack.pop() {
            for (p, w) in self.binding(node, leaf) {
                match self.hanging.row(p) {
                    Some(r) => stack.push((p, self.hanging.leaf[r], weight * w)),
                    None => flat.push((p as usize, weight * w)),
                }
            }
        }
        flat.sort_unstable_by_key(|&(p, _)| p);
        let mut merged: Vec<(usize, f64)> = Vec::with_capacity(flat.len());
        for (p, w) in flat {
            match merged.last_mut() {
                Some((q, v)) if *q == p => *v += w,
                _ => merged.push((p, w)),
            }
        }
        Some(merged)
    }

    /// Largest displacement component per axis (absolute).
    #[must_use]
    pub fn max_displacement(&self) -> DVec3 {
        self.u.iter().fold(DVec3::ZERO, |m, u| m.max(u.abs()))
    }

    /// The corner displacements of `cell`, VTK order.
    #[must_use]
    pub fn cell_displacements(&self, cell: CellId) -> Option<[DVec3; 8]> {
        let leaf = self.leaves.get(cell.index())?;
        Some(self.displacements_of(cell.index() as u32, leaf))
    }

    /// The trilinear map of `cell` in its local frame and that frame's origin (the leaf's lowest
    /// undeformed corner), as [`crate::Body::cell_map`].
    #[must_use]
    pub fn cell_map(&self, cell: CellId) -> Option<(hex8::Hex8Map, DVec3)> {
        let leaf = self.leaves.get(cell.index())?;
        let u = self.displacements_of(cell.index() as u32, leaf);
        Some((
            hex8::Hex8Map::lattice_cell(self.spacing(leaf.level), &u),
            self.leaf_origin(leaf),
        ))
    }

    /// The deformed point of `cell` at local coordinates `xi`.
    #[must_use]
    pub fn point_at(&self, cell: CellId, xi: DVec3) -> Option<DVec3> {
        let (map, origin) = self.cell_map(cell)?;
        Some(origin + map.map(xi))
    }

    /// Deformed corner positions of `cell`, global coordinates, VTK order.
    #[must_use]
    pub fn corners(&self, cell: CellId) -> Option<[DVec3; 8]> {
        let leaf = self.leaves.get(cell.index())?;
        let u = self.displacements_of(cell.index() as u32, leaf);
        let (h, low) = (self.spacing(leaf.level), self.leaf_origin(leaf));
        Some(std::array::from_fn(|c| {
            let [a, b, d] = CORNER_OFFSETS[c];
            low + (DVec3::new(a as f64, b as f64, d as f64) * h + u[c])
        }))
    }

    /// Leaves whose Jacobian determinant is not positive at some corner, with the smallest corner
    /// determinant divided by the undeformed one (≤ 0), ascending by leaf.
    #[must_use]
    pub fn inverted_cells(&self) -> Vec<(CellId, f64)> {
        (0..self.leaves.len() as u32)
            .filter_map(|id| {
                let leaf = self.leaves.at(id);
                let h = self.spacing(leaf.level);
                let u = self.displacements_of(id, leaf);
                let local: [DVec3; 8] = std::array::from_fn(|c| {
                    let [a, b, d] = CORNER_OFFSETS[c];
                    DVec3::new(a as f64, b as f64, d as f64) * h + u[c]
                });
                let ratio = hex8::min_corner_det(&local) / (h.x * h.y * h.z / 8.0);
                // NaN counts as inverted: only a ratio known to be positive is valid.
                (ratio.is_nan() || ratio <= 0.0).then_some((CellId(id), ratio))
            })
            .collect()
    }

    /// Leaves that f64 coordinates of their magnitude cannot resolve, with the share, ascending
    /// by leaf: [`crate::Body::unresolved_cells`], each leaf with its own J.
    #[must_use]
    pub fn unresolved_cells(&self) -> Vec<(CellId, f64)> {
        let tolerance = InsideTolerance::new(&Settings::default(), self.lattice(), DVec3::ZERO);
        (0..self.leaves.len() as u32)
            .filter_map(|id| {
                let (map, origin) = self.cell_map(CellId(id))?;
                crate::body::unresolved_share(&tolerance, &map, origin).map(|s| (CellId(id), s))
            })
            .collect()
    }

    /// Check the body: no inverted leaf (displacements are finite by construction).
    pub fn validate(&self) -> Result<(), Error> {
        let inverted = self.inverted_cells();
        if inverted.is_empty() {
            Ok(())
        } else {
            Err(Error::InvertedCells(inverted))
        }
    }

    /// Bytes on the heap.
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.heap_parts().iter().map(|&(_, bytes)| bytes).sum()
    }

    /// Bytes on the heap, part by part: the displacements, the leaves, the node numbering (owner
    /// cells and the listed nodes around level changes), the octrees with the base cell index,
    /// the hanging nodes' constraints, and the corner table when stored.
    #[must_use]
    pub fn heap_parts(&self) -> [(&'static str, usize); 7] {
        [
            ("displacements", self.u.capacity() * size_of::<DVec3>()),
            ("leaves", self.leaves.heap_bytes()),
            ("node numbering", self.nodes.heap_bytes()),
            ("octrees and base index", self.forest.heap_bytes()),
            ("constraints", self.hanging.heap_bytes()),
            (
                "corner table",
                self.corner_table.capacity() * size_of::<[u32; 8]>(),
            ),
            (
                "open faces (after a gap search)",
                self.open_faces.get().map_or(0, |o| {
                    size_of::<OpenFaces>() + o.leaves.len() + size_of_val(&*o.bases)
                }),
            ),
        ]
    }

    /// The local faces of leaf `id` not covered from the other side (bit f: face f), from the
    /// table when [`AdaptiveBody::prepare_open_faces`] made it.
    #[inline]
    pub(crate) fn open_faces(&self, id: u32) -> u8 {
        match self.open_faces.get() {
            Some(open) => open.leaves[id as usize],
            None => self.leaf_open_faces(self.leaves.at(id)),
        }
    }

    /// Calls `visit(id, leaf)` for every leaf whose closed undeformed box meets [`low`, `high`]
    /// (base lattice coordinates), each once, in base cell order and depth first, leaving out the
    /// base cells without a leaf on the boundary surface once
    /// [`AdaptiveBody::prepare_open_faces`] has found them.
    pub(crate) fn for_each_surface_leaf_in_box(
        &self,
        low: DVec3,
        high: DVec3,
        visit: impl FnMut(u32, Leaf),
    ) {
        match self.open_faces.get() {
            Some(open) => self.forest.for_each_in_box_where(
                low,
                high,
                |base| open.bases.binary_search(&base).is_ok(),
                visit,
            ),
            None => self.forest.for_each_in_box(low, high, visit),
        }
    }

    /// Makes the table of [`AdaptiveBody::open_faces`] if it is not made yet (in parallel on the
    /// current rayon pool; 4.6 ms for 27,984 leaves on one thread in the `gap` bench). Computed
    /// outside the cell, then stored: a rayon worker that waited inside the cell's initialisation
    /// could be handed another task that initialises the same cell, and deadlock. Two threads may
    /// both compute it; the first stored is kept.
    pub(crate) fn prepare_open_faces(&self) {
        use rayon::prelude::*;
        if self.open_faces.get().is_some() {
            return;
        }
        let leaves: Box<[u8]> = (0..self.leaves.len() as u32)
            .into_par_iter()
            .map(|id| self.leaf_open_faces(self.leaves.at(id)))
            .collect::<Vec<u8>>()
            .into_boxed_slice();
        let [nx, ny, _] = self.lattice.cells();
        let mut bases: Vec<u32> = leaves
            .iter()
            .enumerate()
            .filter(|&(_, &open)| open != 0)
            .map(|(id, _)| {
                let leaf = self.leaves.at(id as u32);
                let b = leaf.base();
                b[0] + nx * (b[1] + ny * b[2])
            })
            .collect();
        bases.sort_unstable();
        bases.dedup();
        let _ = self.open_faces.set(Box::new(OpenFaces {
            leaves,
            bases: bases.into_boxed_slice(),
        }));
    }

    fn leaf_open_faces(&self, leaf: Leaf) -> u8 {
        (0..6).fold(0, |open, face| {
            let covered = self.face_coverage(leaf, face) == crate::gap::Coverage::Covered;
            open | u8::from(!covered) << face
        })
    }

    /// The leaf at base lattice coordinates `t` clamped into the lattice's box, with its id.
    #[inline]
    pub(crate) fn leaf_near(&self, t: DVec3) -> Option<(u32, Leaf)> {
        self.forest.leaf_at(t)
    }

    /// How much of face `face` (VTK local face: axis `face / 2`, upper side when odd) of `leaf` is
    /// on the boundary surface: the parts of it whose other side no leaf covers. A leaf as coarse
    /// as the square across a part of the face, or coarser, covers all of it (dyadic cells nest);
    /// an empty tree entry that coarse covers none of it; otherwise the part is split in four.
    pub(crate) fn face_coverage(&self, leaf: Leaf, face: usize) -> crate::gap::Coverage {
        use crate::gap::Coverage;
        let axis = face / 2;
        let l = u32::from(leaf.level);
        let mut across = leaf.ijk;
        if face % 2 == 1 {
            across[axis] += 1;
            if across[axis] >= self.lattice.cells()[axis] << l {
                return Coverage::Open;
            }
        } else if across[axis] == 0 {
            return Coverage::Open;
        } else {
            across[axis] -= 1;
        }
        let [sa, ta] = crate::gap::FACE_ST_AXES[face];
        let mut open = smallvec::SmallVec::new();
        match self.cover(
            across,
            axis,
            face % 2 == 1,
            [sa, ta],
            l,
            [0, 0],
            0,
            &mut open,
        ) {
            Some(true) => Coverage::Covered,
            Some(false) => Coverage::Open,
            None => Coverage::Partial(open.into_vec().into_boxed_slice()),
        }
    }

    /// Coverage of the square `sq` (indices `m` levels below the leaf's level `l`, along the
    /// face's s and t axes) across a face: `Some(true)` covered, `Some(false)` open, `None` partly,
    /// its open squares pushed to `open` as [s0, t0, s1, t1] in the face's coordinates.
    #[allow(clippy::too_many_arguments)]
    fn cover(
        &self,
        across: [u32; 3],
        axis: usize,
        upper: bool,
        st_axes: [usize; 2],
        l: u32,
        sq: [u32; 2],
        m: u32,
        open: &mut smallvec::SmallVec<[[f64; 4]; 4]>,
    ) -> Option<bool> {
        let level = l + m;
        let finest = u32::from(self.finest);
        // The square's cell across, at `level`.
        let mut cell = across.map(|v| v << m);
        if !upper {
            // Across a lower face, the layer touching it is the last of the cell across.
            cell[axis] += (1 << m) - 1;
        }
        cell[st_axes[0]] += sq[0];
        cell[st_axes[1]] += sq[1];
        let (entry, depth) = self
            .forest
            .probe(cell.map(|v| v << (finest - level)), self.finest);
        if u32::from(depth) <= level {
            return Some(entry != forest::EMPTY);
        }
        let children: [[u32; 2]; 4] =
            std::array::from_fn(|c| [2 * sq[0] + (c as u32 & 1), 2 * sq[1] + (c as u32 >> 1)]);
        let parts =
            children.map(|child| self.cover(across, axis, upper, st_axes, l, child, m + 1, open));
        if parts.iter().all(|&p| p == Some(true)) {
            return Some(true);
        }
        if parts.iter().all(|&p| p == Some(false)) {
            return Some(false);
        }
        let n = f64::from(1u32 << (m + 1));
        for (child, part) in children.iter().zip(parts) {
            if part == Some(false) {
                let (s0, t0) = (f64::from(child[0]) / n, f64::from(child[1]) / n);
                let (s1, t1) = (s0 + 1.0 / n, t0 + 1.0 / n);
                open.push([
                    2.0 * s0 - 1.0,
                    2.0 * t0 - 1.0,
                    2.0 * s1 - 1.0,
                    2.0 * t1 - 1.0,
                ]);
            }
        }
        None
    }

    /// The corner nodes of `leaf` (a leaf of the body), VTK order.
    #[inline(always)]
    pub(crate) fn leaf_nodes(&self, id: u32, leaf: Leaf) -> [u32; 8] {
        match self.corner_table.get(id as usize) {
            Some(&corners) => corners,
            // One level: as a uniform body's (a test on the body, the same for every leaf).
            None if self.finest == 0 => self.nodes.unrefined_corners(leaf.ijk),
            None => self.nodes.corners(u32::from(leaf.level), leaf.ijk),
        }
    }

    /// Stores (`true`) or drops (`false`) each leaf's 8 corner nodes: 32 bytes per leaf that the
    /// locators then read instead of computing the corners from the node numbering. On the
    /// benchmarks' adaptive block the batched locate ran 1.16× (f64) and 1.26× (f32) faster with
    /// it, for about 28 more bytes per node (docs/benchmarks.md). Off when a body is made.
    /// The answers are the same, bitwise.
    pub fn set_corner_table(&mut self, on: bool) {
        self.corner_table = if on {
            (0..self.leaves.len() as u32)
                .map(|id| {
                    let leaf = self.leaves.at(id);
                    self.nodes.corners(u32::from(leaf.level), leaf.ijk)
                })
                .collect()
        } else {
            Vec::new()
        };
    }

    /// Whether the body stores its leaves' corner nodes ([`AdaptiveBody::set_corner_table`]).
    #[must_use]
    pub fn has_corner_table(&self) -> bool {
        !self.corner_table.is_empty()
    }

    /// The corner displacements of leaf `id` (unchecked id).
    #[inline(always)]
    pub(crate) fn leaf_displacements(&self, id: u32) -> [DVec3; 8] {
        self.displacements_of(id, self.leaves.at(id))
    }

    /// The corner displacements of leaf `id`, which is `leaf`.
    #[inline(always)]
    fn displacements_of(&self, id: u32, leaf: Leaf) -> [DVec3; 8] {
        self.leaf_nodes(id, leaf).map(|n| self.u[n as usize])
    }
}
