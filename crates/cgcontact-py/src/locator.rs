//! Locators: every strategy of the command line by name, queries on numpy arrays with the GIL
//! released.

use std::ffi::CString;
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, Answer, GapAnswer, GapFinder, LatticeLocator, Locator, Settings};
use cgcontact_baseline::Strategy;
use cgcontact_io::{Kept, KeptBuffers};
use numpy::ndarray::Dimension;
use numpy::{
    BorrowError, Element, IntoPyArray, PyArray, PyArray1, PyArray2, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyMemoryError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use rayon::prelude::*;

use crate::arrays;
use crate::body::{AnyBody, BodyState, PyBody, body_ref, value_error};

/// What `locate` returns: the cells, and xi.
type Located<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray2<f64>>);
/// `locate_unordered`'s answers: `order`, then `Located`.
type Unordered<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray2<f64>>,
);

/// Points per piece of a query: a worker's answer buffer (about 60 kB) stays in its cache.
const PIECE: usize = 1024;

/// The most threads a locator's own pool may have.
const MAX_THREADS: usize = 1024;

/// Newton step tolerances (xi units) above which `tol` gets a warning, as the command line's
/// `--tol` does: xi spans 2 across a cell, so a step tolerance this large stops Newton before
/// it has found the point, and points near faces land in the wrong cell.
const LOOSE_TOL: f64 = 1e-3;

/// The strategy named `name` (the command line's spelling, `_` for `-` allowed).
fn parse_strategy(name: &str) -> PyResult<Strategy> {
    Strategy::from_name(&name.replace('_', "-")).ok_or_else(|| {
        let names: Vec<&str> = Strategy::ALL.iter().map(|s| s.name()).collect();
        PyValueError::new_err(format!(
            "strategy {name:?}: must be one of {}",
            names.join(", ")
        ))
    })
}

/// The error for the first point of `what` a query refused (a NaN or infinite coordinate).
fn refused(what: &str, points: &[DVec3], row: usize) -> PyErr {
    PyValueError::new_err(format!(
        "{what} row {row} (0-based) is not finite: {}",
        arrays::show(points[row])
    ))
}

/// Finds the cell of a body holding each point, and its local coordinates.
///
/// `Locator(body, strategy="lattice", precision="f64", tol=None, max_iter=None, threads=None)`:
/// `strategy` is one of "lattice" (this library's), "centroid", "noderad", "noderad-seed",
/// "rtree" or "brute" (the command line's baselines); `precision` "f64" or "f32" ("f32" on a body
/// whose finest spacing lies outside [1e-11, 1e11] raises ValueError: use "f64"); `tol` the
/// Newton step tolerance in xi units (default 1e-10 in f64, 1e-5 in f32; above 1e-3 a
/// UserWarning, as the command line warns for `--tol`); `max_iter` the Newton iteration limit
/// per candidate cell; `threads` the worker threads of a pool of its own, 1 to 1024 (None:
/// every core, rayon's global pool).
///
/// The locator shares its body: each query searches the body's current displacements (the
/// strategy's setup, a pass over the nodes for the lattice strategy, runs again at each query).
/// Queries release the GIL and run on `threads` worker threads.
#[pyclass(name = "Locator", module = "cgcontact", frozen)]
pub struct PyLocator {
    body: Arc<RwLock<BodyState>>,
    strategy: Strategy,
    settings: Settings,
    pool: Option<rayon::ThreadPool>,
    kept: KeptBuffers,
}

impl PyLocator {
    /// Runs `f` with the strategy over the body's current state, on this locator's threads (the
    /// body stays read-locked meanwhile, so that an update waits for it).
    ///
    /// The lock is taken here, on the caller's thread, never on a pool worker: a worker waiting
    /// for its share of one query runs other queued jobs, another query's among them, and a
    /// lock taken there would wait behind a waiting update, which waits for the first query.
    fn with<R: Send>(&self, f: impl FnOnce(&dyn Locator, &BodyState) -> R + Send) -> PyResult<R> {
        let state = PyBody::read(&self.body);
        let state: &BodyState = &state;
        self.on_threads(|| {
            let locator = self
                .strategy
                .build(body_ref(&state.body), self.settings)
                .map_err(value_error)?;
            Ok(f(&*locator, state))
        })
    }

    /// `locate` (`warm` false) and `relocate` (`warm` true, the hints in `out`).
    fn query<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
        warm: bool,
    ) -> PyResult<Located<'py>> {
        let (rows, _) = arrays::rows(points, "points", false)?;
        let vectors = rows.vectors()?;
        let points: &[DVec3] = &vectors;
        // Before `out` is touched: a refused `relocate` keeps its hints (a solver loop may
        // retry), a refused `locate` the caller's previous answers.
        arrays::finite(points, "points")?;
        let n = points.len();
        let (cells, xi) = match out {
            Some(out) => out_arrays(out, n)?,
            None => (zeros(py, vec![n])?, zeros(py, vec![n, 3])?),
        };
        let outs = [
            ("cell", arrays::extent(&cells)),
            ("xi", arrays::extent(&xi)),
        ];
        disjoint(&rows.extent(), &outs)?;
        {
            let mut cells_out = cells.try_readwrite().map_err(|e| out_borrow(e, "cell"))?;
            let mut xi_out = xi.try_readwrite().map_err(|e| out_borrow(e, "xi"))?;
            // `out_arrays` checked both C-contiguous (so `as_slice_mut` reads x, y, z rows),
            // aligned and of the points' length.
            let cells_slice = cells_out.as_slice_mut().map_err(value_error)?;
            let xi_slice = xi_out.as_slice_mut().map_err(value_error)?;
            py.detach(|| {
                self.kept.with(|kept| {
                    self.with(|locator, state| {
                        if warm
                            && let Some(row) = cells_slice.iter().position(|&c| !is_hint(state, c))
                        {
                            let why = if state.cells.cell(cells_slice[row]).is_ok() {
                                format!(
                                    "lattice cell {} is not active in this body",
                                    cells_slice[row]
                                )
                            } else {
                                format!(
                                    "cells are numbered 0 to {} (-1 for none)",
                                    state.cells.len() as i64 - 1
                                )
                            };
                            return Err(PyValueError::new_err(format!(
                                "out cell row {row} (0-based) is {}, not a previous answer: {why}",
                                cells_slice[row]
                            )));
                        }
                        if locator.sorts_batch(points) {
                            reserve_sorted(kept, points.len(), false)?;
                        }
                        let whole = &mut kept.answers;
                        locate_into(locator, state, points, cells_slice, xi_slice, warm, whole)
                            .map_err(|row| refused("points", points, row))
                    })
                })
            })??;
        }
        Ok((cells, xi))
    }

    /// Runs `f` on this locator's threads.
    fn on_threads<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

#[pymethods]
impl PyLocator {
    /// A locator over `body` (its arguments are described in the class docs, where pyo3 shows
    /// them to Python).
    #[new]
    #[pyo3(signature = (body, strategy = "lattice", precision = "f64", tol = None, max_iter = None, threads = None))]
    fn new(
        py: Python<'_>,
        body: &PyBody,
        strategy: &str,
        precision: &str,
        tol: Option<&Bound<'_, PyAny>>,
        max_iter: Option<&Bound<'_, PyAny>>,
        threads: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let tol = tol
            .map(|t| arrays::not_boolean::<f64>(t, "tol", "a number"))
            .transpose()?;
        let max_iter = max_iter
            .map(|m| arrays::not_boolean::<u32>(m, "max_iter", "a whole number from 1 to 2^32 - 1"))
            .transpose()?;
        let threads = threads
            .map(|t| arrays::not_boolean::<usize>(t, "threads", "a whole number at least 1"))
            .transpose()?;
        let strategy = parse_strategy(strategy)?;
        let mut settings = match precision {
            "f64" => Settings::default(),
            "f32" => Settings::f32(),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "precision {precision:?}: must be \"f64\" or \"f32\""
                )));
            }
        };
        if let Some(tol) = tol {
            settings.newton_tol = tol;
        }
        if let Some(max_iter) = max_iter {
            settings.max_iter = max_iter;
        }
        // The spacing too, as `cgc_locator_new` checks it: the library checks it only when a
        // query builds its search, so f32 on cells it cannot resolve was taken here and every
        // query then refused.
        let spacing = PyBody::read(&body.state).body.finest_spacing();
        settings.validate_for(spacing).map_err(value_error)?;
        if let Some(tol) = tol
            && tol > LOOSE_TOL
        {
            // The command line's warning, word for word but for the flag's name.
            let message = format!(
                "tol {tol:?} is a Newton step tolerance in ξ units (a cell spans 2); above {LOOSE_TOL:e} answers can be off by about tol² and points near faces can be put in the wrong cell"
            );
            let message = CString::new(message).unwrap_or_default();
            PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)?;
        }
        let pool = match threads {
            None => None,
            Some(0) => return Err(PyValueError::new_err("threads must be at least 1")),
            Some(n) if n > MAX_THREADS => {
                return Err(PyValueError::new_err(format!(
                    "threads {n}: at most {MAX_THREADS}"
                )));
            }
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| PyValueError::new_err(format!("{n} threads: {e}")))?,
            ),
        };
        // Every worker of the pool (rayon's global one without `threads`) has started, and so
        // allocated this module's thread-local data, before the locator is returned: a worker
        // that first ran later, in a call under little memory, aborted the interpreter ("cannot
        // allocate memory for thread-local data") where the call raises MemoryError.
        match &pool {
            Some(pool) => pool.broadcast(|_| ()),
            None => rayon::broadcast(|_| ()),
        };
        Ok(Self {
            body: Arc::clone(&body.state),
            strategy,
            settings,
            pool,
            kept: KeptBuffers::default(),
        })
    }

    /// The strategy's name.
    #[getter]
    fn strategy(&self) -> &'static str {
        self.strategy.name()
    }

    /// Locates every point of `points` (n, 3). Returns `(cell, xi)`: int64[n], the cell holding
    /// each point (-1 where none does), and float64[n, 3], its local coordinates in [-1, 1]^3
    /// (NaN where not found). Cells are numbered as the body's input: rows of `hexes`, cells of
    /// the VTK file, or lattice cells. A C-contiguous, aligned float64 array is read in place.
    /// With `out=(cell, xi)`, C-contiguous, aligned int64[n] and float64[n, 3] arrays sharing no
    /// memory with the points or each other, the answers are written there and `out` is returned
    /// (a solver loop then allocates no output arrays per query). On a large body (more than 8 MB
    /// of nodal data: about 350,000 nodes in f64, 520,000 in f32), a batch of 16,384 points or
    /// more not already in order is answered whole, so that the library can sort it by cell: the
    /// call then holds about 100 bytes per point of buffers, of which the answers' 56 stay with
    /// the locator for its next call (a solver loop's next batch).
    #[pyo3(signature = (points, out = None))]
    fn locate<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Located<'py>> {
        self.query(py, points, out, false)
    }

    /// `locate` without putting the answers back in the points' order: returns `(order, cell,
    /// xi)`, row k of `cell` and `xi` answering point `order[k]` (int64[n]), each point once, in
    /// the order the library answered them. A batch the library sorts by cell (see `locate`)
    /// then comes cell by cell, and the call saves putting each answer back at its point's row,
    /// a store to a random place per point; otherwise `order[k]` is k. For a solver that
    /// assembles each point's contribution wherever its answer comes. The answers are bitwise
    /// `locate`'s; a NaN or infinite point raises `ValueError` naming its row in `points`. With
    /// `out=(order, cell, xi)`, C-contiguous, aligned int64[n], int64[n] and float64[n, 3] arrays
    /// sharing no memory with the points or each other, the answers are written there and `out`
    /// is returned. A sorted batch holds about 110 bytes per point of buffers, of which 64
    /// stay with the locator for its next call.
    #[pyo3(signature = (points, out = None))]
    fn locate_unordered<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Unordered<'py>> {
        let (rows, _) = arrays::rows(points, "points", false)?;
        let vectors = rows.vectors()?;
        let points: &[DVec3] = &vectors;
        // Before `out` is touched: a refused `relocate` keeps its hints (a solver loop may
        // retry), a refused `locate` the caller's previous answers.
        arrays::finite(points, "points")?;
        let n = points.len();
        let (order, cells, xi) = match out {
            Some(out) => unordered_arrays(out, n)?,
            None => (
                zeros(py, vec![n])?,
                zeros(py, vec![n])?,
                zeros(py, vec![n, 3])?,
            ),
        };
        let outs = [
            ("order", arrays::extent(&order)),
            ("cell", arrays::extent(&cells)),
            ("xi", arrays::extent(&xi)),
        ];
        disjoint(&rows.extent(), &outs)?;
        {
            let mut order_out = order.try_readwrite().map_err(|e| out_borrow(e, "order"))?;
            let mut cells_out = cells.try_readwrite().map_err(|e| out_borrow(e, "cell"))?;
            let mut xi_out = xi.try_readwrite().map_err(|e| out_borrow(e, "xi"))?;
            // `unordered_arrays` checked all three C-contiguous, aligned and of the points'
            // length.
            let order_slice = order_out.as_slice_mut().map_err(value_error)?;
            let cells_slice = cells_out.as_slice_mut().map_err(value_error)?;
            let xi_slice = xi_out.as_slice_mut().map_err(value_error)?;
            py.detach(|| {
                self.kept.with(|kept| {
                    self.with(|locator, state| {
                        if locator.sorts_batch(points) {
                            reserve_sorted(kept, points.len(), true)?;
                        }
                        let out = (order_slice, cells_slice, xi_slice);
                        locate_unordered_into(locator, state, points, out, kept)
                            .map_err(|row| refused("points", points, row))
                    })
                })
            })??;
        }
        Ok((order, cells, xi))
    }

    /// `locate` warm started, for the next iteration of a solver loop: `out=(cell, xi)` holds
    /// each point's previous answer (as `locate` or `relocate` wrote it; cell -1 for none) and
    /// receives the new one, in place; `out` is returned. A point whose previous cell still holds
    /// it costs one Newton inversion from its previous xi, with no search; the others are
    /// searched as `locate` does. The answers are `locate`'s (the same cells, xi within the
    /// Newton tolerance; on a face shared by two cells either may answer) whatever the hints; a
    /// NaN xi starts from the cell's centre. A previous cell that is neither -1 nor a cell of the
    /// body (an inactive lattice cell included), or a NaN or infinite point, raises `ValueError`
    /// before anything is written.
    fn relocate<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        out: &Bound<'py, PyAny>,
    ) -> PyResult<Located<'py>> {
        self.query(py, points, Some(out), true)
    }

    /// Every cell holding the point `x` (3 floats): a list of `(cell, xi)`, cells ascending, xi a
    /// tuple of 3 floats; empty when no cell holds it. A point on a shared face has 2 owners, on
    /// an edge 4, at a node 8. With `x` of shape (n, 3), one such list per point. Not with the
    /// strategy "noderad-seed", whose loose Newton misses owners (`ValueError`, as the command
    /// line's `--all-owners` refuses it).
    fn locate_owners<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyList>> {
        if self.strategy == Strategy::NoderadSeed {
            return Err(PyValueError::new_err(
                "locate_owners cannot be used with strategy \"noderad-seed\": the seed's Newton \
                 stops at a residual of 0.1 and tests |xi| <= 1 without tolerance, so it misses \
                 cells sharing a face, edge or node (use strategy \"noderad\": the same filter \
                 with the exact Newton)",
            ));
        }
        let (rows, single) = arrays::rows(x, "x", true)?;
        let vectors = rows.vectors()?;
        let points: &[DVec3] = &vectors;
        // A list per point, reserved here: a failed allocation in Rust aborts the interpreter.
        // Each list's first owner is probed for too (most points have one).
        type Owner = (i64, (f64, f64, f64));
        let n = points.len();
        let too_many = |_| out_of_memory(n, size_of::<Vec<Owner>>() + size_of::<Owner>());
        let mut owners: Vec<Result<Vec<Owner>, ()>> = Vec::new();
        owners.try_reserve_exact(n).map_err(too_many)?;
        Vec::<Owner>::new().try_reserve_exact(n).map_err(too_many)?;
        py.detach(|| {
            self.with(|locator, state| {
                points
                    .par_iter()
                    .map(|&x| {
                        let owners = locator.locate_owners(x).map_err(|_| ())?;
                        let mut owners: Vec<Owner> = owners
                            .iter()
                            .map(|hit| (state.cells.number(hit.cell), hit.xi.to_array().into()))
                            .collect();
                        // Ascending in the caller's numbering, which need not be the body's.
                        owners.sort_unstable_by_key(|owner| owner.0);
                        Ok(owners)
                    })
                    .collect_into_vec(&mut owners)
            })
        })?;
        let owners = match owners.iter().position(Result::is_err) {
            Some(row) => return Err(refused("x", points, row)),
            None => owners.into_iter().flatten(),
        };
        if single {
            let one = owners.into_iter().next().unwrap_or_default();
            return PyList::new(py, one);
        }
        // Appended one by one, so that Python's own allocations raise its MemoryError.
        let lists = PyList::empty(py);
        for o in owners {
            lists.append(PyList::new(py, o)?)?;
        }
        Ok(lists)
    }

    /// Signed gaps of `points` (n, 3) to the body's deformed boundary surface, searched within
    /// `dist` (at least 0, at most 1e150). Returns a dict of arrays: "gap" float64[n] (negative
    /// inside the body), "closest" float64[n, 3] (the closest surface point), "normal"
    /// float64[n, 3] (the unit outward normal there: point = closest + gap * normal, to 2 |gap|
    /// within the locator's rounding allowance of the surface), "face_cell" int64[n] (the cell
    /// of the face, numbered as `locate` numbers cells) and "face" int32[n] (its VTK local face
    /// 0-5); NaN and -1 where the surface is farther than `dist`. The sign is the lattice
    /// locator's with this locator's precision and tolerances, so that `gap` and `locate` agree on
    /// which points a cell holds; the closest point and normal are computed in f64 (as
    /// `cgcontact locate --gap`).
    fn gap<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        dist: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let dist: f64 = arrays::not_boolean(dist, "dist", "a number")?;
        if !(dist.is_finite() && dist >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "dist {dist}: the search distance must be a finite number at least 0"
            )));
        }
        let (rows, _) = arrays::rows(points, "points", false)?;
        let vectors = rows.vectors()?;
        let points: &[DVec3] = &vectors;
        let n = points.len();
        let out = py.detach(|| {
            // Locked on the caller's thread, as `with` explains.
            let state = PyBody::read(&self.body);
            let state: &BodyState = &state;
            self.on_threads(|| -> PyResult<GapArrays> {
                // The sign is the lattice locator's with this locator's precision and tolerances,
                // so that `gap` and `locate` agree on which points a cell holds.
                let settings = self.settings;
                let mut gaps = Vec::new();
                gaps.try_reserve_exact(n)
                    .map_err(|_| out_of_memory(n, size_of::<GapAnswer>()))?;
                match &state.body {
                    AnyBody::Uniform(body) => {
                        let locator = LatticeLocator::new(body, settings).map_err(value_error)?;
                        GapFinder::new(&locator, dist)
                            .map_err(value_error)?
                            .gap_all_into(points, &mut gaps);
                    }
                    AnyBody::Adaptive(body) => {
                        let locator = AdaptiveLocator::new(body, settings).map_err(value_error)?;
                        GapFinder::new(&locator, dist)
                            .map_err(value_error)?
                            .gap_all_into(points, &mut gaps);
                    }
                }
                if let Some(row) = gaps.iter().position(Result::is_err) {
                    return Err(refused("points", points, row));
                }
                GapArrays::of(&gaps, state)
            })
        })?;
        let dict = PyDict::new(py);
        dict.set_item("gap", out.gap.into_pyarray(py))?;
        dict.set_item("closest", out.closest.into_pyarray(py).reshape([n, 3])?)?;
        dict.set_item("normal", out.normal.into_pyarray(py).reshape([n, 3])?)?;
        dict.set_item("face_cell", out.face_cell.into_pyarray(py))?;
        dict.set_item("face", out.face.into_pyarray(py))?;
        Ok(dict)
    }

    fn __repr__(&self) -> String {
        format!(
            "<cgcontact.Locator {} ({:?})>",
            self.strategy.name(),
            self.settings.precision
        )
    }
}

/// A new array of zeros of `shape`, allocated by numpy: `PyArray::zeros` panics when numpy
/// cannot allocate it (a `PanicException` where numpy raises `MemoryError`).
fn zeros<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: Vec<usize>,
) -> PyResult<Bound<'py, PyArray<T, D>>> {
    let array = py
        .import("numpy")?
        .call_method1("zeros", (shape, numpy::dtype::<T>(py)))?;
    Ok(array.cast_into::<PyArray<T, D>>()?)
}

/// The error for answers to `n` points, `bytes` a point, that cannot be allocated: a failed
/// allocation in Rust aborts the interpreter.
fn out_of_memory(n: usize, bytes: usize) -> PyErr {
    PyMemoryError::new_err(format!(
        "the answers to {n} points do not fit in memory ({bytes} bytes a point): give fewer points \
         a call"
    ))
}

/// Room for a batch of `n` points that the library sorts by cell, or a `MemoryError`: the
/// locator's kept answers (and, `unordered`, their order) reserved, and the sort's own buffers
/// (40 bytes a point, allocated by the library) probed, since a failed allocation in Rust aborts
/// the interpreter.
fn reserve_sorted(kept: &mut Kept, n: usize, unordered: bool) -> PyResult<()> {
    let answers = n.saturating_sub(kept.answers.len());
    kept.answers
        .try_reserve_exact(answers)
        .map_err(|_| out_of_memory(n, size_of::<Answer>()))?;
    if unordered {
        let order = n.saturating_sub(kept.order.len());
        kept.order
            .try_reserve_exact(order)
            .map_err(|_| out_of_memory(n, size_of::<usize>()))?;
    }
    let mut sort = Vec::<[u64; 6]>::new();
    sort.try_reserve_exact(n)
        .map_err(|_| out_of_memory(n, size_of::<[u64; 6]>()))
}

/// Whether `number` may be a previous answer of the body in `state`: -1, or one of its cells (on a
/// lattice body with inactive cells, a lattice cell number of an active cell), as `cgc_relocate`
/// decides.
fn is_hint(state: &BodyState, number: i64) -> bool {
    match (state.cells.cell(number), &state.body) {
        (Err(()), _) => false,
        (Ok(Some(cell)), AnyBody::Uniform(body)) => body.is_active(cell),
        (Ok(_), _) => true,
    }
}

/// Every point located straight into `cells` (the caller's numbering, -1 where none) and `xi`
/// (NaN where none), piece by piece, each piece's answers in a buffer its worker reuses: no
/// answer array for all the points, whose fresh pages cost a third of the query (measured: 0.36
/// of the library's points/s with one, 0.61 without). But a batch the library may sort by cell
/// (`Locator::sorts_batch`: a large body, points out of order) is answered whole, into `whole`
/// (the locator's kept buffer), then written piece by piece: in pieces it would be answered in
/// the caller's order, up to 2.5x slower at scale. `Err` holds the first point refused.
fn locate_into(
    locator: &dyn Locator,
    state: &BodyState,
    points: &[DVec3],
    cells: &mut [i64],
    xi: &mut [f64],
    warm: bool,
    whole: &mut Vec<Answer>,
) -> Result<(), usize> {
    let first_refused = AtomicUsize::new(usize::MAX);
    // The answers of `points`, cold or warm (the hints read from `cells` and `xi`).
    let answer = |points: &[DVec3], cells: &[i64], xi: &[f64], answers: &mut Vec<Answer>| {
        if warm {
            // The hints: each point's previous answer, as `relocate` reads it.
            state.cells.previous_answers(cells, xi, answers);
            locator.relocate_all(points, answers);
        } else {
            locator.locate_all_into(points, answers);
        }
    };
    let whole = locator.sorts_batch(points).then(|| {
        answer(points, cells, xi, whole);
        &whole[..]
    });
    cells
        .par_chunks_mut(PIECE)
        .zip(xi.par_chunks_mut(3 * PIECE))
        .zip(points.par_chunks(PIECE))
        .enumerate()
        .for_each_init(
            || Vec::with_capacity(if whole.is_some() { 0 } else { PIECE }),
            |answers: &mut Vec<Answer>, (k, ((cells, xi), points))| {
                let answers = match whole {
                    Some(all) => &all[k * PIECE..k * PIECE + points.len()],
                    None => {
                        answer(points, cells, xi, answers);
                        &answers[..]
                    }
                };
                let out = cells.iter_mut().zip(xi.chunks_exact_mut(3));
                for (i, ((cell, xi), answer)) in out.zip(answers.iter()).enumerate() {
                    let (c, x) = match answer {
                        Ok(Some(hit)) => (state.cells.number(hit.cell), hit.xi),
                        Ok(None) => (-1, DVec3::NAN),
                        Err(_) => {
                            first_refused.fetch_min(k * PIECE + i, Ordering::Relaxed);
                            (-1, DVec3::NAN)
                        }
                    };
                    *cell = c;
                    x.write_to_slice(xi);
                }
            },
        );
    match first_refused.into_inner() {
        usize::MAX => Ok(()),
        row => Err(row),
    }
}

/// `locate_unordered`'s work: `order[k]` the point whose answer is row k of `cells` and `xi`, in
/// the order the library answered them (the points' order when it does not sort the batch),
/// through the locator's `kept` buffers. `Err` holds the first point refused, in the points'
/// order.
fn locate_unordered_into(
    locator: &dyn Locator,
    state: &BodyState,
    points: &[DVec3],
    (order, cells, xi): (&mut [i64], &mut [i64], &mut [f64]),
    kept: &mut Kept,
) -> Result<(), usize> {
    if !locator.sorts_batch(points) {
        order
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, o)| *o = k as i64);
        return locate_into(locator, state, points, cells, xi, false, &mut kept.answers);
    }
    let Kept {
        answers,
        order: found,
    } = kept;
    locator.locate_all_unordered_into(points, found, answers);
    let first_refused = AtomicUsize::new(usize::MAX);
    order
        .par_chunks_mut(PIECE)
        .zip(cells.par_chunks_mut(PIECE))
        .zip(xi.par_chunks_mut(3 * PIECE))
        .zip(found.par_chunks(PIECE).zip(answers.par_chunks(PIECE)))
        .for_each(|(((order, cells), xi), (found, answers))| {
            for (k, (&i, answer)) in found.iter().zip(answers).enumerate() {
                let (c, x) = match answer {
                    Ok(Some(hit)) => (state.cells.number(hit.cell), hit.xi),
                    Ok(None) => (-1, DVec3::NAN),
                    Err(_) => {
                        first_refused.fetch_min(i, Ordering::Relaxed);
                        (-1, DVec3::NAN)
                    }
                };
                order[k] = i as i64;
                cells[k] = c;
                x.write_to_slice(&mut xi[3 * k..3 * k + 3]);
            }
        });
    match first_refused.into_inner() {
        usize::MAX => Ok(()),
        row => Err(row),
    }
}

/// The caller's `out=(order, cell, xi)` of `locate_unordered` for `n` points: int64 arrays of
/// shape (n,), then a float64 array of shape (n, 3), all C-contiguous and aligned.
fn unordered_arrays<'py>(out: &Bound<'py, PyAny>, n: usize) -> PyResult<Unordered<'py>> {
    let fits = |(order, cells, xi): &Unordered<'py>| {
        [order, cells]
            .iter()
            .all(|a| a.len() == n && a.is_c_contiguous() && a.data().is_aligned())
            && xi.shape() == [n, 3]
            && xi.is_c_contiguous()
            && xi.data().is_aligned()
    };
    match out.extract::<Unordered<'py>>() {
        Ok(arrays) if fits(&arrays) => Ok(arrays),
        _ => Err(PyValueError::new_err(format!(
            "out must be a tuple (order, cell, xi) of C-contiguous, aligned arrays: int64 of \
             shape ({n},), int64 of shape ({n},) and float64 of shape ({n}, 3); got {}",
            describe_out(out)
        ))),
    }
}

/// The caller's `out=(cell, xi)` for `n` points: an int64 array of shape (n,) and a float64 array
/// of shape (n, 3), both C-contiguous (a Fortran-order xi's memory is not x, y, z rows) and
/// aligned (a misaligned slice would be undefined behaviour). Arrays of another dtype (int32
/// cells, float32 xi) are refused, not converted: the answers must land in the caller's arrays.
fn out_arrays<'py>(out: &Bound<'py, PyAny>, n: usize) -> PyResult<Located<'py>> {
    let fits = |(cells, xi): &Located<'py>| {
        cells.len() == n
            && cells.is_c_contiguous()
            && cells.data().is_aligned()
            && xi.shape() == [n, 3]
            && xi.is_c_contiguous()
            && xi.data().is_aligned()
    };
    match out.extract::<Located<'py>>() {
        Ok(located) if fits(&located) => Ok(located),
        _ => Err(PyValueError::new_err(format!(
            "out must be a tuple (cell, xi) of C-contiguous, aligned arrays: int64 of shape \
             ({n},) and float64 of shape ({n}, 3); got {}",
            describe_out(out)
        ))),
    }
}

/// What the caller gave as `out`, for an error message: each item's dtype, shape and layout.
fn describe_out(out: &Bound<'_, PyAny>) -> String {
    let describe = |item: &Bound<'_, PyAny>| -> PyResult<String> {
        let Ok(array) = item.cast::<PyUntypedArray>() else {
            return Ok(format!("{} object", item.get_type().name()?));
        };
        let shape: Vec<String> = array.shape().iter().map(usize::to_string).collect();
        let comma = if shape.len() == 1 { "," } else { "" };
        let mut text = format!(
            "{} array of shape ({}{comma})",
            array.dtype().str()?,
            shape.join(", ")
        );
        if !array.is_c_contiguous() {
            text.push_str(", not C-contiguous");
        }
        if !item
            .getattr("flags")?
            .getattr("aligned")?
            .extract::<bool>()?
        {
            text.push_str(", misaligned");
        }
        Ok(text)
    };
    let items = if out.is_instance_of::<PyTuple>() {
        out.try_iter().and_then(|items| {
            items
                .map(|item| describe(&item?))
                .collect::<PyResult<Vec<String>>>()
        })
    } else {
        Err(PyValueError::new_err("not a tuple"))
    };
    match items {
        Ok(items) => format!("({})", items.join("; ")),
        Err(_) => describe(out).unwrap_or_else(|_| "?".to_owned()),
    }
}

/// An error when an `out` array (`outs`: each one's name and [`arrays::extent`]) shares memory with
/// the points read (`points`, their extent) or with another `out` array: the answers written
/// would overwrite points not yet read, or each other. Checked on the addresses, before any
/// array is borrowed for writing: numpy's borrow flags, which [`out_borrow`] reports, catch views
/// of one Python object only, not a view of a `bytearray` and one of a `memoryview` of it.
fn disjoint(points: &Range<usize>, outs: &[(&str, Range<usize>)]) -> PyResult<()> {
    for (k, (name, out)) in outs.iter().enumerate() {
        let shares = |with: &str| {
            PyValueError::new_err(format!(
                "out: the {name} array shares memory with {with}; give each out array memory of \
                 its own"
            ))
        };
        if arrays::overlap(points, out) {
            return Err(shares("the points"));
        }
        if let Some((other, _)) = outs[..k].iter().find(|(_, o)| arrays::overlap(o, out)) {
            return Err(shares(&format!("the {other} array")));
        }
    }
    Ok(())
}

/// The error for an `out` array that cannot be written: read-only, sharing memory with the
/// points (read in place) or with the other `out` array, or borrowed by a call running in
/// another thread (numpy's borrow flags cannot tell these apart; [`disjoint`] has already
/// refused arrays sharing memory).
fn out_borrow(e: BorrowError, name: &str) -> PyErr {
    match e {
        BorrowError::NotWriteable => {
            PyValueError::new_err(format!("out: the {name} array is read-only"))
        }
        _ => PyValueError::new_err(format!(
            "out: the {name} array shares memory with the points or with the other out array, \
             or another call is writing to it; give each call arrays of its own"
        )),
    }
}

/// Gap answers as flat arrays.
struct GapArrays {
    gap: Vec<f64>,
    closest: Vec<f64>,
    normal: Vec<f64>,
    face_cell: Vec<i64>,
    face: Vec<i32>,
}

impl GapArrays {
    /// The arrays of `gaps`, or a `MemoryError` when they cannot be allocated.
    fn of(gaps: &[GapAnswer], state: &BodyState) -> PyResult<Self> {
        let n = gaps.len();
        let mut out = Self {
            gap: Vec::new(),
            closest: Vec::new(),
            normal: Vec::new(),
            face_cell: Vec::new(),
            face: Vec::new(),
        };
        let reserved = out.gap.try_reserve_exact(n).is_ok()
            && out.closest.try_reserve_exact(3 * n).is_ok()
            && out.normal.try_reserve_exact(3 * n).is_ok()
            && out.face_cell.try_reserve_exact(n).is_ok()
            && out.face.try_reserve_exact(n).is_ok();
        if !reserved {
            return Err(out_of_memory(n, 68));
        }
        for answer in gaps {
            let (gap, closest, normal, cell, face) = match answer {
                Ok(Some(contact)) => (
                    contact.gap,
                    contact.point,
                    contact.normal,
                    state.cells.number(contact.face.cell),
                    i32::from(contact.face.local),
                ),
                Ok(None) | Err(_) => (f64::NAN, DVec3::NAN, DVec3::NAN, -1, -1),
            };
            out.gap.push(gap);
            out.closest.extend_from_slice(&closest.to_array());
            out.normal.extend_from_slice(&normal.to_array());
            out.face_cell.push(cell);
            out.face.push(face);
        }
        Ok(out)
    }
}
