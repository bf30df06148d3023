//! A body as a binding's caller holds it (the C API and the Python module): built from a lattice
//! or detected from nodes and hexahedra, its cells and nodes numbered as the caller's, and its
//! displacements set in place from the caller's nodes, checked first so that an error leaves the
//! body as it was. Each binding words the errors ([`UpdateError`]) in its own terms. Also the
//! answer buffers a binding's locator keeps from one call to the next ([`KeptBuffers`]).

use std::sync::{Mutex, TryLockError};

use cgcontact::adaptive::FlatConstraints;
use cgcontact::{AdaptiveBody, Answer, Body, Lattice};
use glam::DVec3;

use crate::mesh::ROUNDING_SLACK;
use crate::{CellMap, CellNumbering, HexMesh, LATTICE_TOLERANCE, MeshBody, NodeSources};

/// The buffers of a locator's last batch answered whole (one the library sorts by cell), kept for
/// its next call: a solver loop asks the same batch again, and a fresh answer buffer of that size
/// costs its page faults at every call (Python's `bench_unordered.py`: 17 to 25 % of the query on
/// 1 M points in a 4.2 M-cell block).
#[derive(Debug, Default)]
pub struct Kept {
    /// The answers, in the order found.
    pub answers: Vec<Answer>,
    /// The point each answer is for.
    pub order: Vec<usize>,
}

/// A binding's locator's [`Kept`] buffers, shared by the calls of its threads.
#[derive(Debug, Default)]
pub struct KeptBuffers(Mutex<Kept>);

impl KeptBuffers {
    /// Runs `f` with the kept buffers, or with fresh ones while another call (from another
    /// thread) holds them.
    pub fn with<R>(&self, f: impl FnOnce(&mut Kept) -> R) -> R {
        let mut fresh = None;
        let mut guard = match self.0.try_lock() {
            Ok(kept) => Some(kept),
            // A panic left them as they were: every use overwrites them.
            Err(TryLockError::Poisoned(p)) => Some(p.into_inner()),
            Err(TryLockError::WouldBlock) => None,
        };
        f(match guard.as_deref_mut() {
            Some(kept) => kept,
            None => fresh.insert(Kept::default()),
        })
    }
}

/// The body a caller holds: one lattice level, or an adaptive body of several.
#[derive(Debug)]
pub enum AnyBody {
    /// Every cell one cell of the lattice.
    Uniform(Body),
    /// Leaves of several refinement levels of a base lattice; a leaf's id is its input cell.
    Adaptive(AdaptiveBody),
}

impl AnyBody {
    /// The (base) lattice.
    #[must_use]
    pub fn lattice(&self) -> &Lattice {
        match self {
            Self::Uniform(body) => body.lattice(),
            Self::Adaptive(body) => body.lattice(),
        }
    }

    /// The spacing of the body's finest cells (its lattice's, on a uniform body).
    #[must_use]
    pub fn finest_spacing(&self) -> DVec3 {
        match self {
            Self::Uniform(body) => body.lattice().h(),
            Self::Adaptive(body) => body.spacing(body.finest_level()),
        }
    }

    /// Cells searched: the active cells, or the leaves.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        match self {
            Self::Uniform(body) => body.active_count(),
            Self::Adaptive(body) => body.cell_count(),
        }
    }
}

/// Why [`CallerBody::set_displacements`] changed nothing. Nodes are the caller's, 0-based.
#[derive(Clone, Debug, PartialEq)]
pub enum UpdateError {
    /// A NaN or an infinity, at the first such node.
    NonFinite {
        /// The node.
        node: usize,
        /// Its value.
        value: DVec3,
    },
    /// Two of the caller's nodes at one place (an unmerged mesh) given different values.
    Disagree {
        /// The node that gives the place's value.
        first: usize,
        /// The other node.
        node: usize,
        /// `first`'s value.
        first_value: DVec3,
        /// `node`'s value.
        value: DVec3,
    },
    /// A displacement beyond what the body's coordinates resolve.
    TooLarge {
        /// The first such node.
        node: usize,
        /// Its value.
        value: DVec3,
        /// The largest displacement per axis.
        limit: f64,
    },
    /// Hanging nodes off their constraints by more than a tolerance.
    Hanging {
        /// How many are off.
        violating: usize,
        /// How many hanging nodes the body has.
        hanging: usize,
        /// The tolerance (largest component, length units).
        tol: f64,
        /// The worst node.
        node: usize,
        /// Its undeformed position.
        at: DVec3,
        /// How far it is off (largest component).
        by: f64,
    },
    /// Any other error of the library's.
    Library(cgcontact::Error),
}

/// A body, how the caller numbers its cells and nodes, and what an update needs.
#[derive(Debug)]
pub struct CallerBody {
    /// The body.
    pub body: AnyBody,
    /// How the caller numbers the cells: the mesh's input order, or the lattice's cell ids.
    pub cells: CellNumbering,
    /// Number of nodes the caller passes (lattice nodes, or input nodes).
    source_count: usize,
    /// For each of the body's displacement slots, the caller's node that gives it; `None` when slot
    /// s is node s (a lattice body with every cell active), so that such bodies store nothing.
    source_of_slot: Option<Vec<u32>>,
    /// Further caller's nodes at a slot's node (an unmerged mesh): (node, slot). Their
    /// displacements must agree with the slot's.
    duplicates: Vec<(usize, usize)>,
    /// The hanging nodes' constraints (none for uniform bodies).
    hanging: FlatConstraints,
    /// The displacements in slot order, reused by every update.
    scratch: Vec<DVec3>,
    /// How far the mesh's nodes lie from their lattice positions (slot order), added to every
    /// update so that a deformed node is the caller's node plus its displacement: `None` where
    /// every node is at its lattice position to f64 rounding ([`crate::LatticeMesh::node_offsets`]).
    offsets: Option<Vec<DVec3>>,
    /// The displacements before an update that fills hanging nodes on a body with `offsets`,
    /// taken back if the offsets cannot be added; reused.
    previous: Vec<DVec3>,
}

impl CallerBody {
    /// A lattice body, its cells and nodes numbered as the lattice's, or
    /// [`cgcontact::Error::OutOfMemory`] when its buffers (28 bytes a node of the body at most)
    /// cannot be allocated: a binding raises its out-of-memory error where a failed allocation
    /// would abort the process.
    pub fn lattice(body: Body) -> Result<Self, cgcontact::Error> {
        let lattice = body.lattice();
        let n = body.node_count();
        let out_of_memory = |what, len: usize, bytes: usize| cgcontact::Error::OutOfMemory {
            what,
            bytes: len.saturating_mul(bytes),
        };
        let mut scratch = Vec::new();
        scratch
            .try_reserve_exact(n)
            .map_err(|_| out_of_memory("the displacements' copy", n, size_of::<DVec3>()))?;
        scratch.resize(n, DVec3::ZERO);
        // Lattice node indices fit u32 (`Lattice::new` refuses more nodes).
        let source_of_slot = if n == lattice.node_count() {
            None
        } else {
            let mut sources = Vec::new();
            sources
                .try_reserve_exact(n)
                .map_err(|_| out_of_memory("the nodes' numbers", n, size_of::<u32>()))?;
            sources.extend(body.nodes().map(|n| n as u32));
            Some(sources)
        };
        Ok(Self {
            scratch,
            source_count: lattice.node_count(),
            source_of_slot,
            duplicates: Vec::new(),
            hanging: FlatConstraints::default(),
            cells: CellNumbering::Lattice {
                cells: lattice.cell_count(),
            },
            body: AnyBody::Uniform(body),
            offsets: None,
            previous: Vec::new(),
        })
    }

    /// The body detected from `mesh` (`found` is `mesh.to_body()`), its cells and nodes numbered
    /// as the mesh's (an adaptive body's leaves through its cell map: input cell `c`, or the leaf
    /// a ghost copy repeats, with its corners in the same, VTK, order).
    #[must_use]
    pub fn mesh(mesh: &HexMesh, found: MeshBody) -> Self {
        match found {
            MeshBody::Uniform(found) => {
                let sources = NodeSources::uniform(mesh, &found.body, &found.cells);
                let body = AnyBody::Uniform(found.body);
                Self::of_mesh(mesh, sources, found.cells, body, found.node_offsets)
            }
            MeshBody::Adaptive(found) => {
                let sources = NodeSources::adaptive(mesh, &found.body, &found.cells);
                let body = AnyBody::Adaptive(found.body);
                Self::of_mesh(mesh, sources, found.cells, body, found.node_offsets)
            }
        }
    }

    fn of_mesh(
        mesh: &HexMesh,
        sources: NodeSources,
        cells: CellMap,
        body: AnyBody,
        offsets: Option<Vec<DVec3>>,
    ) -> Self {
        let NodeSources {
            source_of_slot,
            duplicates,
        } = sources;
        Self {
            scratch: vec![DVec3::ZERO; source_of_slot.len()],
            source_count: mesh.points.len(),
            source_of_slot: Some(source_of_slot),
            duplicates,
            hanging: match &body {
                AnyBody::Uniform(_) => FlatConstraints::default(),
                AnyBody::Adaptive(body) => FlatConstraints::of(body),
            },
            cells: CellNumbering::Mesh(cells),
            body,
            offsets,
            previous: Vec::new(),
        }
    }

    /// How many nodes an update takes: the lattice's for a lattice body, the mesh's for a mesh.
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.source_count
    }

    /// Hanging nodes (0 for a uniform body).
    #[must_use]
    pub fn hanging_count(&self) -> usize {
        self.hanging.len()
    }

    /// The caller's numbers of the cells whose Jacobian determinant is not positive at some
    /// corner (inverted or degenerate), ascending: one pass over every cell.
    #[must_use]
    pub fn inverted_cells(&self) -> Vec<i64> {
        let found = match &self.body {
            AnyBody::Uniform(body) => body.inverted_cells(),
            AnyBody::Adaptive(body) => body.inverted_cells(),
        };
        self.cells
            .sorted_numbers(found.iter().map(|&(cell, _)| cell))
    }

    /// The caller's numbers of the cells that f64 coordinates of their magnitude cannot resolve
    /// through their deformation (`Body::unresolved_cells`), ascending: one pass over every cell.
    #[must_use]
    pub fn unresolved_cells(&self) -> Vec<i64> {
        let found = match &self.body {
            AnyBody::Uniform(body) => body.unresolved_cells(),
            AnyBody::Adaptive(body) => body.unresolved_cells(),
        };
        self.cells
            .sorted_numbers(found.iter().map(|&(cell, _)| cell))
    }

    /// The caller's node that gives slot `slot`.
    fn source(&self, slot: usize) -> usize {
        self.source_of_slot
            .as_ref()
            .map_or(slot, |source| source[slot] as usize)
    }

    /// Sets every displacement, `at(node)` giving the caller's node `node` (for each node below
    /// [`CallerBody::node_count`]), or changes nothing and says why.
    ///
    /// Every value must be finite, at nodes no cell uses too. Nodes at one place must agree (to
    /// 1e-9 of the spacing plus their rounding). On an adaptive body, each hanging node must be
    /// its constraint's value (to 1e-9 of the finest spacing plus the rounding of the largest
    /// displacement), unless `fill`: then the hanging nodes are set to their constraints' values
    /// and the values given there are not used.
    ///
    /// A mesh's nodes stay where the mesh has them: where they lie off their lattice positions
    /// by more than f64 rounding (32-bit float coordinates, short decimal prints), each body
    /// node's offset is added to the value given (after the checks above, which are on the
    /// values given), as when the mesh was read.
    pub fn set_displacements(
        &mut self,
        at: impl Fn(usize) -> DVec3,
        fill: bool,
    ) -> Result<(), UpdateError> {
        if let Some(node) = (0..self.source_count).find(|&node| !at(node).is_finite()) {
            return Err(UpdateError::NonFinite {
                node,
                value: at(node),
            });
        }
        match &self.source_of_slot {
            None => {
                for (node, slot) in self.scratch.iter_mut().enumerate() {
                    *slot = at(node);
                }
            }
            Some(source) => {
                for (slot, &node) in self.scratch.iter_mut().zip(source) {
                    *slot = at(node as usize);
                }
            }
        }
        let tol = LATTICE_TOLERANCE * self.body.lattice().h().max_element();
        for &(node, slot) in &self.duplicates {
            let (value, first) = (at(node), self.scratch[slot]);
            if (value - first).abs().max_element()
                > tol + ROUNDING_SLACK * first.abs().max_element()
            {
                return Err(UpdateError::Disagree {
                    first: self.source(slot),
                    node,
                    first_value: first,
                    value,
                });
            }
        }
        if fill {
            // The values given at hanging nodes are not used: zeros in their place, which
            // `fill_hanging` overwrites, so that the body's limit on a displacement's size does
            // not refuse a value it would not keep.
            for node in self.hanging.nodes() {
                self.scratch[node] = DVec3::ZERO;
            }
        }
        let source = self.source_of_slot.as_deref();
        let caller_nodes = |e, u: &[DVec3]| in_caller_nodes(e, u, source);
        let offsets = self.offsets.as_deref();
        let add = |u: &mut [DVec3], offsets: &[DVec3]| {
            for (u, o) in u.iter_mut().zip(offsets) {
                *u += *o;
            }
        };
        match &mut self.body {
            AnyBody::Uniform(body) => {
                if let Some(offsets) = offsets {
                    add(&mut self.scratch, offsets);
                }
                (body.set_displacements(&self.scratch)).map_err(|e| caller_nodes(e, &self.scratch))
            }
            AnyBody::Adaptive(body) => {
                if !fill {
                    check_hanging(body, &self.hanging, &self.scratch, source)?;
                    if let Some(offsets) = offsets {
                        add(&mut self.scratch, offsets);
                    }
                    return (body.set_displacements(&self.scratch))
                        .map_err(|e| caller_nodes(e, &self.scratch));
                }
                let Some(offsets) = offsets else {
                    body.set_displacements(&self.scratch)
                        .map_err(|e| caller_nodes(e, &self.scratch))?;
                    body.fill_hanging();
                    return Ok(());
                };
                // The hanging nodes' values are their constraints' on the values given; then
                // every node's offset, a hanging node's own included, is added. Should that
                // fail, the body takes its previous displacements back.
                self.previous.clear();
                self.previous.extend_from_slice(body.displacements());
                body.set_displacements(&self.scratch)
                    .map_err(|e| caller_nodes(e, &self.scratch))?;
                body.fill_hanging();
                self.scratch.copy_from_slice(body.displacements());
                add(&mut self.scratch, offsets);
                body.set_displacements(&self.scratch).map_err(|e| {
                    body.set_displacements(&self.previous)
                        .expect("the body's previous displacements are valid");
                    caller_nodes(e, &self.scratch)
                })
            }
        }
    }
}

/// The library's error for displacements `u` (slot order), a displacement too large named by the
/// caller's node (`source[slot]`): the library names its own node, which on a mesh is not the
/// node the caller gave.
fn in_caller_nodes(e: cgcontact::Error, u: &[DVec3], source: Option<&[u32]>) -> UpdateError {
    if let cgcontact::Error::DisplacementTooLarge { limit, .. } = e
        && let Some(slot) = u.iter().position(|v| v.abs().max_element() > limit)
    {
        return UpdateError::TooLarge {
            node: source.map_or(slot, |s| s[slot] as usize),
            value: u[slot],
            limit,
        };
    }
    UpdateError::Library(e)
}

/// The hanging nodes of `body` that break their constraint in `u` (slot order), as an error; `Ok`
/// when none does. The tolerance is the one `cgcontact locate` warns at: 1e-9 of the finest
/// spacing plus the rounding of the largest displacement.
fn check_hanging(
    body: &AdaptiveBody,
    hanging: &FlatConstraints,
    u: &[DVec3],
    source: Option<&[u32]>,
) -> Result<(), UpdateError> {
    if hanging.is_empty() {
        return Ok(());
    }
    let largest = u.iter().fold(0.0f64, |m, v| m.max(v.abs().max_element()));
    let tol = LATTICE_TOLERANCE * body.spacing(body.finest_level()).min_element()
        + ROUNDING_SLACK * largest;
    let (violating, worst) = hanging
        .violations(u, tol)
        .map_err(|e| in_caller_nodes(e, u, source))?;
    let Some((slot, by)) = worst else {
        return Ok(());
    };
    Err(UpdateError::Hanging {
        violating,
        hanging: hanging.len(),
        tol,
        node: source.map_or(slot, |s| s[slot] as usize),
        at: body.node_position(slot).unwrap_or(DVec3::NAN),
        by,
    })
}
