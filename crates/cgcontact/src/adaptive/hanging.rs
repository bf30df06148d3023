//! Hanging nodes and their Q1 constraints.
//!
//! A node is hanging when some leaf holds it on an edge or a face without having it as a corner.
//! Its displacement must then be that leaf's trilinear interpolation there (1/2, 1/2 at an edge's
//! midpoint, 1/4 each at a face's centre, other dyadic weights across level jumps of more than
//! one), or the deformed mesh would gap or overlap. When several leaves hold it so, the coarsest
//! one binds (the finer ones' corners on that face are themselves constrained by it).
//!
//! Each hanging node keeps only the leaf it hangs on; its constraint is that leaf's interpolation
//! of the current displacements. A coarse leaf's corner can hang on a still coarser leaf, but only
//! on one of a strictly lower level (a leaf's corners lie on the lattice of its level, and a leaf
//! of that level or finer holding such a point has it as a corner), so the chains are at most as
//! long as the levels: filling the nodes coarsest leaf first needs one pass, and
//! `AdaptiveBody::constraint` flattens a chain to independent nodes on request. Every weight is a
//! dyadic rational, exact in f64.

use glam::DVec3;

use crate::hex8;

/// Each hanging node and the leaf it hangs on (the coarsest leaf holding it without having it as
/// a corner): the constraint is that leaf's interpolation there, recomputed when needed rather
/// than stored (12 bytes per hanging node).
#[derive(Clone, Debug, Default)]
pub(super) struct Constraints {
    /// Hanging nodes, ascending.
    pub(super) nodes: Vec<u32>,
    /// The leaf each row's node hangs on.
    pub(super) leaf: Vec<u32>,
    /// Rows by the level of their leaf, coarsest first, then by leaf and node: in this order a
    /// node's leaf's corners are independent or filled already, and the nodes a leaf binds come
    /// together (its corners are computed once for them).
    pub(super) order: Vec<u32>,
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

/// One hanging node: the level and id of the leaf it hangs on.
pub(super) struct Direct {
    pub(super) node: u32,
    pub(super) level: u8,
    pub(super) leaf: u32,
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
    /// The constraints of `direct` (one entry per hanging node, any order).
    pub(super) fn new(mut direct: Vec<Direct>) -> Self {
        direct.sort_unstable_by_key(|d| d.node);
        let mut order: Vec<u32> = (0..direct.len() as u32).collect();
        order.sort_unstable_by_key(|&r| {
            let d = &direct[r as usize];
            (d.level, d.leaf, d.node)
        });
        Self {
            nodes: direct.iter().map(|d| d.node).collect(),
            leaf: direct.iter().map(|d| d.leaf).collect(),
            order,
        }
    }

    /// The row of `node`, if it hangs.
    #[inline]
    pub(super) fn row(&self, node: u32) -> Option<usize> {
        self.nodes.binary_search(&node).ok()
    }

    /// Whether `node` hangs.
    #[inline]
    pub(super) fn contains(&self, node: u32) -> bool {
        self.row(node).is_some()
    }

    /// Bytes on the heap.
    pub(super) fn heap_bytes(&self) -> usize {
        (self.nodes.capacity() + self.leaf.capacity() + self.order.capacity()) * size_of::<u32>()
    }
}
