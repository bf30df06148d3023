//! Hanging nodes and their Q1 constraints.
//!
//! A node is hanging when some leaf holds it on an edge or a face without having it as a corner.
//! Its displacement must then be that leaf's trilinear interpolation there (1/2, 1/2 at an edge's
//! midpoint, 1/4 each at a face's centre, other dyadic weights across level jumps of more than
//! one), or the deformed mesh would gap or overlap. When several leaves hold it so, the coarsest
//! one binds (the finer ones' corners on that face are themselves constrained by it).
//!
//! Constraints are flattened to independent nodes: a coarse leaf's corner can hang on a still
//! coarser leaf, but only on one of a strictly lower level (a leaf's corners lie on the lattice
//! of its level, and a leaf of that level or finer holding such a point has it as a corner), so
//! the chains are at most as long as the levels, and resolving them coarsest first needs one pass.
//! Every weight is a dyadic rational, exact in f64.

use glam::DVec3;

use crate::hex8;

/// Each hanging node and the independent nodes and weights its displacement interpolates,
/// ascending by node (compressed rows).
#[derive(Clone, Debug, Default)]
pub(super) struct Constraints {
    /// Hanging nodes, ascending.
    pub(super) nodes: Vec<u32>,
    /// Row `r`'s parents are `parents[start[r]..start[r + 1]]`.
    pub(super) start: Vec<u32>,
    /// (independent node, weight), ascending by node within a row.
    pub(super) parents: Vec<(u32, f64)>,
}

/// How far the displacements are from obeying the constraints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstraintReport {
    /// Hanging nodes in the body.
    pub hanging: usize,
    /// Hanging nodes whose displacement is farther than the tolerance from their constraint.
    pub violating: usize,
    /// The node farthest from its constraint and by how much (largest component, length units);
    /// `None` when the body has no hanging node.
    pub worst: Option<(usize, f64)>,
}

impl ConstraintReport {
    /// Whether every hanging node obeys its constraint within the tolerance.
    #[must_use]
    pub fn holds(&self) -> bool {
        self.violating == 0
    }
}

/// One hanging node before flattening: the level of the leaf it hangs on and that leaf's corners
/// with their (non-zero) weights.
pub(super) struct Direct {
    pub(super) node: u32,
    pub(super) level: u8,
    pub(super) parents: Vec<(u32, f64)>,
}

/// The weights of the 8 corners of a leaf at local coordinates `xi` (exact for dyadic ξ), the
/// zero ones dropped.
pub(super) fn corner_weights(corners: &[u32; 8], xi: DVec3) -> Vec<(u32, f64)> {
    hex8::shape(xi)
        .into_iter()
        .zip(corners)
        .filter(|(w, _)| *w != 0.0)
        .map(|(w, &n)| (n, w))
        .collect()
}

impl Constraints {
    /// Flattens `direct` (one entry per hanging node, any order) to independent parents.
    pub(super) fn flatten(node_count: usize, mut direct: Vec<Direct>) -> Self {
        // Coarsest first: a parent that hangs hangs on a coarser leaf, so it is resolved already.
        direct.sort_unstable_by_key(|d| (d.level, d.node));
        let mut row_of: Vec<u32> = vec![u32::MAX; node_count];
        let mut rows: Vec<Vec<(u32, f64)>> = Vec::with_capacity(direct.len());
        for d in &direct {
            let mut flat: Vec<(u32, f64)> = Vec::with_capacity(d.parents.len());
            for &(parent, w) in &d.parents {
                match row_of[parent as usize] {
                    u32::MAX => flat.push((parent, w)),
                    r => flat.extend(rows[r as usize].iter().map(|&(p, wp)| (p, w * wp))),
                }
            }
            flat.sort_unstable_by_key(|&(p, _)| p);
            let mut merged: Vec<(u32, f64)> = Vec::with_capacity(flat.len());
            for (p, w) in flat {
                match merged.last_mut() {
                    Some((q, v)) if *q == p => *v += w,
                    _ => merged.push((p, w)),
                }
            }
            row_of[d.node as usize] = rows.len() as u32;
            rows.push(merged);
        }
        let mut order: Vec<usize> = (0..direct.len()).collect();
        order.sort_unstable_by_key(|&r| direct[r].node);
        let mut out = Self {
            nodes: Vec::with_capacity(order.len()),
            start: Vec::with_capacity(order.len() + 1),
            parents: Vec::new(),
        };
        out.start.push(0);
        for r in order {
            out.nodes.push(direct[r].node);
            out.parents.extend_from_slice(&rows[r]);
            out.start.push(out.parents.len() as u32);
        }
        out
    }

    /// Row `r`: its node and its parents.
    #[inline]
    pub(super) fn row(&self, r: usize) -> (u32, &[(u32, f64)]) {
        let range = self.start[r] as usize..self.start[r + 1] as usize;
        (self.nodes[r], &self.parents[range])
    }

    /// The constrained displacement of row `r`.
    #[inline]
    pub(super) fn interpolate(&self, r: usize, u: &[DVec3]) -> DVec3 {
        self.row(r)
            .1
            .iter()
            .fold(DVec3::ZERO, |sum, &(p, w)| sum + w * u[p as usize])
    }

    /// Whether `node` hangs.
    #[inline]
    pub(super) fn contains(&self, node: u32) -> bool {
        self.nodes.binary_search(&node).is_ok()
    }

    /// Bytes on the heap.
    pub(super) fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * 4
            + self.start.capacity() * 4
            + self.parents.capacity() * size_of::<(u32, f64)>()
    }
}
