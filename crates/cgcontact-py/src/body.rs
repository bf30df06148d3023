//! Bodies: from a lattice, from nodes and hexahedra (the lattice detected as the C API and the
//! command line detect it), or from a VTK file; displacements set in place.

use std::sync::{Arc, PoisonError, RwLock, RwLockReadGuard};

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId, Lattice};
use cgcontact_baseline::BodyRef;
use cgcontact_io::{HexMesh, MeshBody, UpdateError};
use numpy::{IntoPyArray, PyArray1};
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;

use crate::arrays;

/// A library or input error as Python's `ValueError`.
pub fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// What a `Body` holds: the body, how the caller numbers its cells and nodes, and what an update
/// needs; shared with the locators made from it.
pub use cgcontact_io::{AnyBody, CallerBody as BodyState};

/// `body` as the baselines take it.
pub fn body_ref(body: &AnyBody) -> BodyRef<'_> {
    match body {
        AnyBody::Uniform(body) => body.into(),
        AnyBody::Adaptive(body) => body.into(),
    }
}

/// Sets every displacement of `state` from the caller's rows `u`, or changes nothing and says
/// why.
fn set_displacements(state: &mut BodyState, u: &[DVec3], fill: bool) -> Result<(), String> {
    let n = state.node_count();
    if u.len() != n {
        return Err(format!(
            "displacements: the body has {n} nodes, got {} rows",
            u.len()
        ));
    }
    state
        .set_displacements(|row| u[row], fill)
        .map_err(|e| match e {
            UpdateError::NonFinite { node, value } => format!(
                "displacement row {node} (0-based) is not finite: {}",
                arrays::show(value)
            ),
            UpdateError::Disagree {
                first,
                node,
                first_value,
                value,
            } => format!(
                "nodes {first} and {node} (0-based) coincide but their displacements differ: {} and {}",
                arrays::show(first_value),
                arrays::show(value)
            ),
            UpdateError::TooLarge { node, value, limit } => format!(
                "displacement row {node} (0-based) is too large: {} (at most {limit:e} per axis: \
                 displaced farther, coordinates cannot resolve this body's cells)",
                arrays::show(value)
            ),
            UpdateError::Hanging {
                violating,
                hanging,
                tol,
                node,
                at,
                by,
            } => format!(
                "displacements: {violating} of {hanging} hanging nodes break their constraint by more than {tol:.1e}; the worst, node {node} (0-based) at {}, by {by:.3e}: the deformed mesh would gap or overlap there (give each hanging node the trilinear interpolation of the coarse cell it hangs on, or pass fill_hanging=True)",
                arrays::show(at)
            ),
            UpdateError::Library(e) => e.to_string(),
        })
}

/// A library error building a body as Python's: `MemoryError` where a buffer could not be
/// allocated, else `ValueError`.
fn build_error(e: cgcontact::Error) -> PyErr {
    match e {
        cgcontact::Error::OutOfMemory { .. } => {
            PyMemoryError::new_err(format!("the body does not fit in memory: {e}"))
        }
        e => value_error(e),
    }
}

/// An error, before the allocation, when a body of `nodes` nodes (every lattice node, or at most 8
/// a cell of the active ones) cannot be allocated: its displacements and this binding's copy take
/// 48 bytes a node, and a failed allocation would abort the interpreter (as the C API checks,
/// `cgc_body_from_lattice`). The kernel's overcommit grants each allocation of the build alone,
/// then kills the process that fills them: this asks for them together. The build's own
/// allocations are fallible too ([`build_error`]), for what this misses: a limit on the address
/// space (RLIMIT_AS) that the build's peak, above these 48 bytes, exceeds.
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
/// floats each, `counts` cells per axis (MemoryError when it does not fit in memory: about 48
/// bytes a node). `active` is None (every cell) or one flag per lattice cell (booleans,
/// or 0s and 1s), x fastest (a flat array, or one of shape (nz, ny, nx)); other shapes and
/// values, and complex, text, date and time arrays, raise ValueError. The body starts
/// undeformed; its cells are numbered as the lattice's, `i + nx (j + ny k)`, and
/// `set_displacements` takes one row per lattice node, `i + (nx + 1)(j + (ny + 1) k)`.
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
        let origin = DVec3::from_array(arrays::not_boolean(origin, "origin", three)?);
        let h = DVec3::from_array(arrays::not_boolean(spacing, "spacing", three)?);
        let counts: [u32; 3] = arrays::not_boolean(
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
                Body::try_full(lattice).map_err(build_error)?
            }
            Some(active) => {
                let cells = arrays::flags(active, "active", counts)?;
                probe_memory(lattice.node_count().min(cells.len().saturating_mul(8)))?;
                Body::from_cells(lattice, cells.into_iter().map(CellId)).map_err(build_error)?
            }
        };
        Ok(Self::new_state(
            BodyState::lattice(body).map_err(build_error)?,
        ))
    }

    /// A body from undeformed `nodes` (n, 3) and `hexes` (m, 8) of 0-based node numbers in VTK
    /// hexahedron order; the lattice (one level, or dyadic refinements with hanging nodes) is
    /// detected from the nodes. Cells are numbered by their row in `hexes`;
    /// `set_displacements` takes one row per node. `MemoryError` when the body, or detecting its
    /// lattice, does not fit in memory.
    #[staticmethod]
    fn from_hexes(
        py: Python<'_>,
        nodes: &Bound<'_, PyAny>,
        hexes: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let (rows, _) = arrays::rows(nodes, "nodes", false)?;
        let vectors = rows.vectors()?;
        arrays::finite(&vectors, "nodes")?;
        let n = vectors.len();
        let cells = arrays::hexes(hexes, "hexes", n)?;
        if cells.is_empty() {
            return Err(PyValueError::new_err("hexes: the mesh has no cell"));
        }
        let mut points = Vec::new();
        points.try_reserve_exact(n).map_err(|_| {
            PyMemoryError::new_err(format!("nodes: the {n} nodes do not fit in memory"))
        })?;
        points.extend_from_slice(&vectors);
        let mesh = HexMesh {
            ghosts: Vec::new(),
            points,
            cells,
            displacement: None,
        };
        // Detection's allocations are not fallible: ask for all they may take first.
        let bytes = mesh.build_bytes();
        let mut probe = Vec::<u8>::new();
        probe.try_reserve_exact(bytes).map_err(|_| {
            PyMemoryError::new_err(format!(
                "a mesh of {n} nodes and {} hexahedra does not fit in memory (detecting its \
                 lattice takes up to {bytes} bytes)",
                mesh.cells.len()
            ))
        })?;
        drop(probe);
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
            set_displacements(&mut state, u, fill_hanging)
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
        Self::read(&self.state).node_count()
    }

    /// Cells searched: the active cells, or an adaptive body's leaves.
    #[getter]
    fn cell_count(&self) -> usize {
        Self::read(&self.state).body.cell_count()
    }

    /// Whether the body has cells of several refinement levels.
    #[getter]
    fn is_adaptive(&self) -> bool {
        matches!(Self::read(&self.state).body, AnyBody::Adaptive(_))
    }

    /// Hanging nodes (0 for a uniform body).
    #[getter]
    fn hanging_count(&self) -> usize {
        Self::read(&self.state).hanging_count()
    }

    fn __repr__(&self) -> String {
        let state = Self::read(&self.state);
        let kind = match state.body {
            AnyBody::Uniform(_) => "uniform",
            AnyBody::Adaptive(_) => "adaptive",
        };
        format!(
            "<cgcontact.Body {kind}: {} cells, {} nodes>",
            state.body.cell_count(),
            state.node_count()
        )
    }
}
