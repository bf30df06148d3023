//! Which node of a mesh file gives each node of the body detected from it: what the C and
//! Python bindings need to take displacements in the file's node order.
//!
//! A body numbers its own nodes (the lattice's order, or the adaptive numbering) and merges the
//! file's copies of one node, so each body node (a *slot*) has a first file node, and every
//! further copy is listed, for its displacement to be checked against the first one's.

use cgcontact::{AdaptiveBody, Body};

use crate::mesh::{CellMap, HexMesh};

/// A file node no cell uses.
const UNSET: usize = usize::MAX;

/// Where each body node's displacement comes from, for a body detected from a mesh.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NodeSources {
    /// The first file node at each body node, in body node order (file nodes used by cells are
    /// `u32`, as the cells' indices are).
    pub source_of_slot: Vec<u32>,
    /// The further file nodes at a body node already given, as (file node, body node).
    pub duplicates: Vec<(usize, usize)>,
}

impl NodeSources {
    /// For the uniform `body` detected from `mesh`, `cells` mapping its cells.
    ///
    /// # Panics
    /// When `body` and `cells` are not those detected from `mesh` (a cell outside the lattice, a
    /// corner that is not a body node).
    #[must_use]
    pub fn uniform(mesh: &HexMesh, body: &Body, cells: &CellMap) -> Self {
        let lattice = body.lattice();
        let slot_nodes: Vec<usize> = body.nodes().collect();
        let mut slot_of_input = vec![UNSET; mesh.points.len()];
        for (input, corners) in mesh.cells.iter().enumerate() {
            let cell = cells
                .lattice_cell(input)
                .expect("one lattice cell per input cell");
            let ijk = lattice
                .cell_ijk(cell)
                .expect("detected cells lie in the lattice");
            for (&node, lattice_node) in corners.iter().zip(lattice.corner_nodes(ijk)) {
                slot_of_input[node as usize] = slot_nodes
                    .binary_search(&lattice_node)
                    .expect("corners of active cells are body nodes");
            }
        }
        Self::of(&slot_of_input, slot_nodes.len())
    }

    /// For the adaptive `body` detected from `mesh`, `cells` mapping each input cell to its leaf
    /// (with its corners in the same, VTK, order).
    ///
    /// # Panics
    /// When `body` and `cells` are not those detected from `mesh` (an input cell without a leaf).
    #[must_use]
    pub fn adaptive(mesh: &HexMesh, body: &AdaptiveBody, cells: &CellMap) -> Self {
        let mut slot_of_input = vec![UNSET; mesh.points.len()];
        for (input, corners) in mesh.cells.iter().enumerate() {
            let nodes = cells
                .lattice_cell(input)
                .and_then(|leaf| body.cell_nodes(leaf))
                .expect("a leaf per input cell");
            for (&node, slot) in corners.iter().zip(nodes) {
                slot_of_input[node as usize] = slot;
            }
        }
        Self::of(&slot_of_input, body.node_count())
    }

    /// From each file node's slot (or `UNSET`): the first file node of each of `slots` slots,
    /// and the further file nodes at a slot already given.
    fn of(slot_of_input: &[usize], slots: usize) -> Self {
        let mut source_of_slot = vec![u32::MAX; slots];
        let mut duplicates = Vec::new();
        for (node, &slot) in slot_of_input
            .iter()
            .enumerate()
            .filter(|(_, s)| **s != UNSET)
        {
            if source_of_slot[slot] == u32::MAX {
                source_of_slot[slot] = node as u32;
            } else {
                duplicates.push((node, slot));
            }
        }
        debug_assert!(!source_of_slot.contains(&u32::MAX));
        Self {
            source_of_slot,
            duplicates,
        }
    }
}
