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
    /// Hanging nodes, ascending. (Boxed slices, not vectors: they are built once, and the body
    /// stays small enough to sit unboxed in the io crate's enums beside a uniform body.)
    pub(super) nodes: Box<[u32]>,
    /// The leaf each row's node hangs on.
    pub(super) leaf: Box<[u32]>,
    /// Rows by the level of their leaf, coarsest first, then by leaf and node: in this order a
    /// node's leaf's corners are independent or filled already, and the nodes a leaf binds come
    /// together (its corners are computed once for them).
    pub(super) order: Box<[u32]>,
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
            order: order.into_boxed_slice(),
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
        (self.nodes.len() + self.leaf.len() + self.order.len()) * size_of::<u32>()
    }
}

/// Every hanging node's constraint flattened to independent nodes and weights
/// ([`super::AdaptiveBody::constraint`] of each), in one table: to check displacements that are
/// not the body's own, such as a caller's before the body takes them, in a few multiply-adds a
/// node. The C and Python bindings refuse an update with it.
///
/// Unlike [`super::AdaptiveBody::check_constraints`], which compares each hanging node with its
/// coarse leaf's interpolation of the values given (so a wrong value at a hanging corner also
/// shows in the nodes that hang on its leaf), this compares each hanging node with the
/// independent nodes alone: a wrong value shows at its own node only.
#[derive(Clone, Debug, Default)]
pub struct FlatConstraints {
    /// Nodes of the body.
    nodes: usize,
    /// (hanging node, end of its parents in `parents`), ascending by node.
    rows: Vec<(u32, u32)>,
    /// (independent node, weight).
    parents: Vec<(u32, f64)>,
}

impl FlatConstraints {
    /// The flattened constraints of `body`'s hanging nodes (none on a body without).
    #[must_use]
    pub fn of(body: &super::AdaptiveBody) -> Self {
        let mut flat = Self {
            nodes: body.node_count(),
            ..Self::default()
        };
        for node in body.hanging_nodes() {
            let parents = body
                .constraint(node)
                .expect("a hanging node has a constraint");
            flat.parents
                .extend(parents.into_iter().map(|(p, w)| (p as u32, w)));
            // Node and parent counts fit u32: the body indexes its nodes with u32.
            flat.rows.push((node as u32, flat.parents.len() as u32));
        }
        flat
    }

    /// How many hanging nodes there are.
    #[must_use]
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there is no hanging node.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The hanging nodes, ascending.
    pub fn nodes(&self) -> impl Iterator<Item = usize> + '_ {
        self.rows.iter().map(|&(node, _)| node as usize)
    }

    /// The hanging nodes farther than `tol` (largest component, length units) from their
    /// constraint in `u`, one displacement per node of the body: how many, and the farthest of
    /// them (node, by how much), `None` when none is. A NaN tolerance holds no node within it:
    /// every hanging node is counted, as [`super::AdaptiveBody::check_constraints`] counts them.
    ///
    /// # Errors
    /// [`crate::Error::LengthMismatch`] when `u` does not hold one displacement per node.
    pub fn violations(
        &self,
        u: &[DVec3],
        tol: f64,
    ) -> Result<(usize, Option<(usize, f64)>), crate::Error> {
        if u.len() != self.nodes {
            return Err(crate::Error::LengthMismatch {
                what: "node displacements",
                expected: self.nodes,
                got: u.len(),
            });
        }
        let (mut count, mut worst) = (0, None);
        let mut start = 0;
        for &(node, end) in &self.rows {
            let value: DVec3 = self.parents[start..end as usize]
                .iter()
                .map(|&(p, w)| w * u[p as usize])
                .sum();
            start = end as usize;
            let off = (u[node as usize] - value).abs().max_element();
            // Written so that a NaN tolerance counts the node (`off > tol` passed every node).
            let within = off <= tol;
            if !within {
                count += 1;
                if worst.is_none_or(|(_, w)| off > w) {
                    worst = Some((node as usize, off));
                }
            }
        }
        Ok((count, worst))
    }
}
