//! Bodies: from a lattice, from nodes and hexahedra (the lattice detected as the C API and the
//! command line detect it), or from a VTK file; displacements set in place.

use std::sync::{Arc, PoisonError, RwLock, RwLockReadGuard};

use cgcontact::adaptive::FlatConstraints;
use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, Body, CellId, Lattice};
use cgcontact_baseline::BodyRef;
use cgcontact_io::{CellMap, CellNumbering, HexMesh, LATTICE_TOLERANCE, MeshBody, NodeSources};
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;

use crate::arrays;

/// Rounding allowance relative to a value's magnitude (as `cgcontact-io`'s checks).
const ROUNDING_SLACK: f64 = 4.0 * f64::EPSILON;

/// A library or input error as Python's `ValueError`.
pub fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The body a `Body` holds: one lattice level, or an adaptive body of several.
#[derive(Debug)]
pub enum AnyBody {
    /// Every cell one cell of the lattice.
    Uniform(Body),
    /// Leaves of several refinement levels of a base lattice.
    Adaptive(AdaptiveBody),
}

impl AnyBody {
    /// The body as the baselines take it.
    pub fn as_ref(&self) -> BodyRef<'_> {
        match self {
            Self::Uniform(body) => body.into(),
            Self::Adaptive(body) => body.into(),
        }
    }
}

/// What a `Body` holds; shared with the locators made from it.
#[derive(Debug)]
pub struct BodyState {
    pub body: AnyBody,
    /// How the caller numbers the cells: the mesh's input order, or the lattice's cell ids.
    pub cells: CellNumbering,
    /// Number of displacement rows the caller passes (lattice nodes, or input nodes).
    pub source_count: usize,
    /// For each of the body's displacement slots, the caller's node that gives it; `None` when slot
    /// s is node s (a lattice body with every cell active).
    source_of_slot: Option<Vec<u32>>,
    /// Further caller's nodes at a slot's node (an unmerged mesh): (node, slot).
    duplicates: Vec<(usize, usize)>,
    /// The hanging nodes' constraints (none for uniform bodies).
    hanging: FlatConstraints,
    /// The displacements in slot order, reused by every update.
    scratch: Vec<DVec3>,
}

impl BodyState {
    fn lattice(body: Body) -> Self {
        let lattice = body.lattice();
        // Lattice node indices fit u32 (`Lattice::new` refuses more nodes).
        let source_of_slot = (body.node_count() != lattice.node_count())
            .then(|| body.nodes().map(|n| n as u32).collect());
        Self {
            scratch: vec![DVec3::ZERO; body.node_count()],
            source_count: lattice.node_count(),
            source_of_slot,
            duplicates: Vec::new(),
            hanging: FlatConstraints::default(),
            cells: CellNumbering::Lattice {
                cells: lattice.cell_count(),
            },
            body: AnyBody::Uniform(body),
        }
    }

    /// The state of the body detected from `mesh` (`found` is `mesh.to_body()`).
    fn mesh(mesh: &HexMesh, found: MeshBody) -> Self {
        match found {
            MeshBody::Uniform(found) => uniform_state(mesh, found.body, found.cells),
            MeshBody::Adaptive(found) => adaptive_state(mesh, found.body, found.cells),
        }
    }

    /// The caller's numbers of the cells whose Jacobian determinant is not positive at some
    /// corner (inverted or degenerate), ascending: one pass over every cell.
    fn inverted_cells(&self) -> Vec<i64> {
        let found = self.body.as_ref().inverted_cells();
        self.cells
            .sorted_numbers(found.iter().map(|&(cell, _)| cell))
    }

    /// The caller's numbers of the cells that f64 coordinates of their magnitude cannot resolve
    /// through their deformation (`Body::unresolved_cells`), ascending: one pass over every cell.
    fn unresolved_cells(&self) -> Vec<i64> {
        let found = self.body.as_ref().unresolved_cells();
        self.cells
            .sorted_numbers(found.iter().map(|&(cell, _)| cell))
    }

    /// The caller's node that gives slot `slot`.
    fn source(&self, slot: usize) -> usize {
        self.source_of_slot
            .as_ref()
            .map_or(slot, |source| source[slot] as usize)
    }

    /// Sets every displacement from the caller's rows, or changes nothing and says why.
    fn set_displacements(&mut self, u: &[DVec3], fill: bool) -> Result<(), String> {
        let n = self.source_count;
        if u.len() != n {
            return Err(format!(
                "displacements: the body has {n} nodes, got {} rows",
                u.len()
            ));
        }
        // Every row, those of nodes no (active) cell uses too: the command line refuses a NaN at
        // any node of the file, and `from_hexes` at any of `nodes`.
        if let Some(row) = u.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "displacement row {row} (0-based) is not finite: {}",
                arrays::show(u[row])
            ));
        }
        match &self.source_of_slot {
            None => self.scratch.copy_from_slice(u),
            Some(source) => {
                for (slot, &node) in self.scratch.iter_mut().zip(source) {
                    *slot = u[node as usize];
                }
            }
        }
        let h = match &self.body {
            AnyBody::Uniform(body) => body.lattice().h(),
            AnyBody::Adaptive(body) => body.lattice().h(),
        };
        let tol = LATTICE_TOLERANCE * h.max_element();
        for &(node, slot) in &self.duplicates {
            let (value, first) = (u[node], self.scratch[slot]);
            if (value - first).abs().max_element()
                > tol + ROUNDING_SLACK * first.abs().max_element()
            {
                return Err(format!(
                    "nodes {} and {node} (0-based) coincide but their displacements differ: {} and {}",
                    self.source(slot),
                    arrays::show(first),
                    arrays::show(value)
                ));
            }
        }
        if fill {
            // The rows of hanging nodes are ignored once found finite, as the C API ignores them:
            // zeros in their place, which `fill_hanging` overwrites, so that the body's limit on
            // a displacement's size does not refuse a value it would not keep.
            for node in self.hanging.nodes() {
                self.scratch[node] = DVec3::ZERO;
            }
        }
        match &mut self.body {
            AnyBody::Uniform(body) => body
                .set_displacements(&self.scratch)
                .map_err(|e| in_caller_rows(e, &self.scratch, self.source_of_slot.as_deref()))?,
            AnyBody::Adaptive(body) => {
                if !fill {
                    check_hanging(
                        body,
                        &self.hanging,
                        &self.scratch,
                        self.source_of_slot.as_deref(),
                    )?;
                }
                body.set_displacements(&self.scratch).map_err(|e| {
                    in_caller_rows(e, &self.scratch, self.source_of_slot.as_deref())
                })?;
                if fill {
                    body.fill_hanging();
                }
            }
        }
        Ok(())
    }
}

/// The library's error for displacements `u` (slot order), with a displacement too large named
/// by the caller's row (`source[slot]`): the library names its own node, a lattice node, which
/// on a mesh is not the row the caller gave.
fn in_caller_rows(e: cgcontact::Error, u: &[DVec3], source: Option<&[u32]>) -> String {
    if let cgcontact::Error::DisplacementTooLarge { limit, .. } = e
        && let Some(slot) = u.iter().position(|v| v.abs().max_element() > limit)
    {
        let row = source.map_or(slot, |s| s[slot] as usize);
        return format!(
            "displacement row {row} (0-based) is too large: {} (at most {limit:e} per axis: \
             displaced farther, coordinates cannot resolve this body's cells)",
            arrays::show(u[slot])
        );
    }
    e.to_string()
}

/// An error naming how many hanging nodes of `body` break their constraint in `u` (slot order)
/// and the worst, as the caller's node `source[slot]`; `Ok` when none does (the tolerance the
/// command line warns at: 1e-9 of the finest spacing plus the largest displacement's rounding).
fn check_hanging(
    body: &AdaptiveBody,
    hanging: &FlatConstraints,
    u: &[DVec3],
    source: Option<&[u32]>,
) -> Result<(), String> {
    if hanging.is_empty() {
        return Ok(());
    }
    let largest = u.iter().fold(0.0f64, |m, v| m.max(v.abs().max_element()));
    let tol = LATTICE_TOLERANCE * body.spacing(body.finest_level()).min_element()
        + ROUNDING_SLACK * largest;
    let (count, worst) = hanging.violations(u, tol).map_err(|e| e.to_string())?;
    let Some((slot, by)) = worst else {
        return Ok(());
    };
    let node = source.map_or(slot, |s| s[slot] as usize);
    let at = body.node_position(slot).unwrap_or(DVec3::NAN);
    Err(format!(
        "displacements: {count} of {} hanging nodes break their constraint by more than {tol:.1e}; the worst, node {node} (0-based) at {}, by {by:.3e}: the deformed mesh would gap or overlap there (give each hanging node the trilinear interpolation of the coarse cell it hangs on, or pass fill_hanging=True)",
        hanging.len(),
        arrays::show(at)
    ))
}

/// The state of a uniform body detected from `mesh`: which input node gives each slot.
fn uniform_state(mesh: &HexMesh, body: Body, cells: CellMap) -> BodyState {
    let NodeSources {
        source_of_slot,
        duplicates,
    } = NodeSources::uniform(mesh, &body, &cells);
    BodyState {
        scratch: vec![DVec3::ZERO; source_of_slot.len()],
        source_count: mesh.points.len(),
        source_of_slot: Some(source_of_slot),
        duplicates,
        hanging: FlatConstraints::default(),
        cells: CellNumbering::Mesh(cells),
        body: AnyBody::Uniform(body),
    }
}

/// The state of an adaptive body detected from `mesh`, whose leaf `c` is input cell `c` with its
/// corners in the same (VTK) order.
fn adaptive_state(mesh: &HexMesh, body: AdaptiveBody, cells: CellMap) -> BodyState {
    let NodeSources {
        source_of_slot,
        duplicates,
    } = NodeSources::adaptive(mesh, &body);
    BodyState {
        scratch: vec![DVec3::ZERO; source_of_slot.len()],
        source_count: mesh.points.len(),
        source_of_slot: Some(source_of_slot),
        duplicates,
        hanging: FlatConstraints::of(&body),
        cells: CellNumbering::Mesh(cells),
        body: AnyBody::Adaptive(body),
    }
}

/// An error, before the allocation, when a body of `nodes` nodes with every cell active cannot be
/// allocated: its displacements and this binding's copy take 48 bytes a node, and a failed
/// allocation would abort the interpreter (as the C API checks, `cgc_body_from_lattice`).
fn probe_memory(nodes: usize) -> PyResult<()> {
    let mut probe = Vec::<[DVec3; 2]>::new();
    probe.try_reserve_exact(nodes).map_err(|_| {
        PyMemoryError::new_err(format!(
            "a body of {nodes} lattice nodes does not fit in memory (48 bytes a node)"
        ))
    })
}

/// A deformed body of hexahedra on a cartesian lattice.
///
/// Build one with `Body(origin, spacing, counts, active=None)`, `Body.from_hexes(nodes, hexes)`
/// or `cgcontact.read_mesh(path)`. Locators made from a body share it: they see every later
/// `set_displacements`.
///
/// `Body(origin, spacing, counts, active=None)`: a body on a lattice, `origin` and `spacing` 3
/// floats each, `counts` cells per axis (MemoryError, before allocating, when its 48 bytes a
/// node cannot be had). `active` is None (every cell) or one flag per lattice cell (booleans,
/// or 0s and 1s), x fastest (a flat array, or one of shape (nz, ny, nx)); other shapes and
/// values raise ValueError. The body starts undeformed; its cells are numbered as the
/// lattice's, `i + nx (j + ny k)`, and `set_displacements` takes one row per lattice node,
/// `i + (nx + 1)(j + (ny + 1) k)`.
#[pyclass(name = "Body", module = "cgcontact", frozen)]
pub struct PyBody {
    pub(crate) state: Arc<RwLock<BodyState>>,
}

impl PyBody {
    pub(crate) fn new_state(state: BodyState) -> Self {
        Self {
            state: Arc::new(RwLock::new(state)),
        }
    }

    /// The body from a mesh of nodes and hexahedra, as `HexMesh::to_body` detects it.
    pub(crate) fn from_mesh(mesh: &HexMesh, found: MeshBody) -> Self {
        Self::new_state(BodyState::mesh(mesh, found))
    }

    /// The state for reading (updates check before they write, so a poisoned lock holds a whole
    /// state).
    pub(crate) fn read(state: &RwLock<BodyState>) -> RwLockReadGuard<'_, BodyState> {
        state.read().unwrap_or_else(PoisonError::into_inner)
    }
}

#[pymethods]
impl PyBody {
    /// A body on a lattice (pyo3 shows Python this comment's place in the class docs, which
    /// say what each argument takes).
    #[new]
    #[pyo3(signature = (origin, spacing, counts, active = None))]
    fn new(
        origin: &Bound<'_, PyAny>,
        spacing: &Bound<'_, PyAny>,
        counts: &Bound<'_, PyAny>,
        active: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let three = "3 numbers (x, y, z)";
        let origin = DVec3::from_array(arrays::argument(origin, "origin", three)?);
        let h = DVec3::from_array(arrays::argument(spacing, "spacing", three)?);
        let counts: [u32; 3] = arrays::argument(
            counts,
            "counts",
            "3 whole numbers of cells (x, y, z), each from 1 to 2^32 - 1",
        )?;
        if !(origin.is_finite() && h.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "the lattice's origin {} or spacing {} is not finite",
                arrays::show(origin),
                arrays::show(h)
            )));
        }
        let lattice = Lattice::new(origin, h, counts).map_err(value_error)?;
        let body = match active {
            None => {
                probe_memory(lattice.node_count())?;
                Body::full(lattice)
            }
            Some(active) => {
                let flags = arrays::flags(active, "active", counts)?;
                let ids = flags.iter().enumerate().filter(|(_, f)| **f);
                Body::from_cells(lattice, ids.map(|(c, _)| CellId(c as u32)))
                    .map_err(value_error)?
            }
        };
        Ok(Self::new_state(BodyState::lattice(body)))
    }

    /// A body from undeformed `nodes` (n, 3) and `hexes` (m, 8) of 0-based node numbers in VTK
    /// hexahedron order; the lattice (one level, or dyadic refinements with hanging nodes) is
    /// detected from the nodes. Cells are numbered by their row in `hexes`;
    /// `set_displacements` takes one row per node.
    #[staticmethod]
    fn from_hexes(
        py: Python<'_>,
        nodes: &Bound<'_, PyAny>,
        hexes: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let (rows, _) = arrays::rows(nodes, "nodes", false)?;
        let points = rows.vectors()?.into_owned();
        arrays::finite(&points, "nodes")?;
        let topology = arrays::hexes(hexes, "hexes")?;
        if topology.is_empty() {
            return Err(PyValueError::new_err("hexes: the mesh has no cell"));
        }
        let n = points.len();
        let mut cells = Vec::with_capacity(topology.len());
        for (c, corners) in topology.iter().enumerate() {
            let mut cell = [0u32; 8];
            for (k, &node) in corners.iter().enumerate() {
                cell[k] = u32::try_from(node)
                    .ok()
                    .filter(|&i| (i as usize) < n)
                    .ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "hexes row {c} corner {k}: node {node} is not one of the {n} nodes (numbered from 0)"
                        ))
                    })?;
            }
            cells.push(cell);
        }
        let mesh = HexMesh {
            points,
            cells,
            displacement: None,
        };
        let found = py.detach(|| mesh.to_body()).map_err(value_error)?;
        Ok(Self::from_mesh(&mesh, found))
    }

    /// Sets every displacement, in place: `u` has one row (ux, uy, uz) per node (`node_count`).
    /// On an adaptive body each hanging node's row must be its constraint's value (the trilinear
    /// interpolation of the coarse cell it hangs on) unless `fill_hanging` sets it so. On any
    /// error (a shape, a NaN, a hanging node off its constraint) the body keeps its displacements.
    #[pyo3(signature = (u, fill_hanging = false))]
    fn set_displacements(
        &self,
        py: Python<'_>,
        u: &Bound<'_, PyAny>,
        fill_hanging: bool,
    ) -> PyResult<()> {
        let (rows, _) = arrays::rows(u, "u", false)?;
        let u = rows.vectors()?;
        let u: &[DVec3] = &u;
        py.detach(|| {
            let mut state = self.state.write().unwrap_or_else(PoisonError::into_inner);
            state.set_displacements(u, fill_hanging)
        })
        .map_err(PyValueError::new_err)
    }

    /// The cells the current displacements invert (det J <= 0 at a corner: a node moved through
    /// its neighbours), ascending, numbered as `Locator.locate` numbers cells; empty when none.
    /// Answers in or near them are not to be trusted (a point in one may be found in no cell).
    /// Updates do not check for them: this costs one pass over every cell, so call it when
    /// wanted (after an update, or when a point is not found).
    fn inverted_cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let cells = py.detach(|| Self::read(&self.state).inverted_cells());
        cells.into_pyarray(py)
    }

    /// The cells that f64 coordinates of their magnitude cannot resolve through their
    /// deformation, ascending, numbered as `Locator.locate` numbers cells; empty when none: far
    /// from the origin, a cell sheared or crushed enough turns a coordinate's rounding
    /// (4 eps |x|) into more than a tenth of itself, and a point that close to one of its faces
    /// may be given the cell beside it as well (`cgcontact locate` warns). One pass over every
    /// cell, as `inverted_cells`.
    fn unresolved_cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let cells = py.detach(|| Self::read(&self.state).unresolved_cells());
        cells.into_pyarray(py)
    }

    /// How many rows `set_displacements` takes: the lattice's nodes for a lattice body, the nodes
    /// given for a mesh.
    #[getter]
    fn node_count(&self) -> usize {
        Self::read(&self.state).source_count
    }

    /// Cells searched: the active cells, or an adaptive body's leaves.
    #[getter]
    fn cell_count(&self) -> usize {
        Self::read(&self.state).body.as_ref().cell_count()
    }

    /// Whether the body has cells of several refinement levels.
    #[getter]
    fn is_adaptive(&self) -> bool {
        matches!(Self::read(&self.state).body, AnyBody::Adaptive(_))
    }

    /// Hanging nodes (0 for a uniform body).
    #[getter]
    fn hanging_count(&self) -> usize {
        Self::read(&self.state).hanging.len()
    }

    fn __repr__(&self) -> String {
        let state = Self::read(&self.state);
        let kind = match state.body {
            AnyBody::Uniform(_) => "uniform",
            AnyBody::Adaptive(_) => "adaptive",
        };
        format!(
            "<cgcontact.Body {kind}: {} cells, {} nodes>",
            state.body.as_ref().cell_count(),
            state.source_count
        )
    }
}
