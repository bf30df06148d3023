//! Bodies: from a lattice, or from nodes and hexahedra whose lattice (one level, or dyadic
//! refinements of it with hanging nodes) is detected; displacements set in place.

use std::sync::{Arc, PoisonError, RwLock, RwLockReadGuard, RwLockWriteGuard};

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId, Lattice};
use cgcontact_io::{HexMesh, UpdateError};

use crate::error::{CgcError, Failure, guard, shown};
use crate::raw;

/// Displacements given node by node: x, y, z of node 0, then of node 1, ... (an n × 3 row-major
/// array in C, a 3 × n array in MATLAB or Fortran).
pub const CGC_LAYOUT_NODE_MAJOR: u32 = 0;
/// Displacements given component by component: x of every node, then y, then z (an n × 3 array
/// in MATLAB or Fortran, a 3 × n row-major array in C).
pub const CGC_LAYOUT_COMPONENT_MAJOR: u32 = 1;
/// A flag OR-ed into the layout of `cgc_body_set_displacements`: on an adaptive body, set each
/// hanging node to its constraint's value (the trilinear interpolation of the coarse cell it hangs
/// on) instead of checking the value given, which is then ignored (it must still be finite). No
/// effect on bodies without hanging nodes.
pub const CGC_FILL_HANGING: u32 = 2;

/// A body handle's state: the body, how the caller numbers its cells and nodes, and what an
/// update needs; shared with the locators made from it.
pub(crate) use cgcontact_io::{AnyBody, CallerBody as BodyState};

/// A deformed body (opaque). Created by `cgc_body_from_lattice` or `cgc_body_from_mesh`, freed by
/// `cgc_body_free`.
pub struct CgcBody {
    pub(crate) state: Arc<RwLock<BodyState>>,
}

/// Sets every displacement of `state` from the caller's `3 n` values `u` in `layout`, or changes
/// nothing and says why.
fn set_displacements(state: &mut BodyState, u: &[f64], layout: u32) -> Result<(), Failure> {
    let n = state.node_count();
    let at = |node: usize| match layout & !CGC_FILL_HANGING {
        CGC_LAYOUT_NODE_MAJOR => DVec3::new(u[3 * node], u[3 * node + 1], u[3 * node + 2]),
        _ => DVec3::new(u[node], u[n + node], u[2 * n + node]),
    };
    let fill = layout & CGC_FILL_HANGING != 0;
    state.set_displacements(at, fill).map_err(|e| match e {
        UpdateError::NonFinite { node, value } => Failure::new(
            CgcError::NonFinite,
            format!(
                "the displacement of node {node} (0-based) is not finite: {}",
                shown(value)
            ),
        ),
        UpdateError::Disagree {
            first,
            node,
            first_value,
            value,
        } => Failure::new(
            CgcError::NotLattice,
            format!(
                "nodes {first} and {node} (0-based) coincide but their displacements differ: {} and {}",
                shown(first_value),
                shown(value)
            ),
        ),
        UpdateError::TooLarge { node, value, limit } => Failure::new(
            CgcError::InvalidArgument,
            format!(
                "the displacement of node {node} (0-based) is too large: {:?} (at most {limit:e} \
                 per axis: displaced farther, coordinates cannot resolve this body's cells)",
                value.to_array()
            ),
        ),
        UpdateError::Hanging {
            violating,
            hanging,
            tol,
            node,
            at,
            by,
        } => Failure::new(
            CgcError::HangingConstraint,
            format!(
                "displacements: {violating} of {hanging} hanging nodes break their constraint by more than {tol:.1e}; the worst, node {node} (0-based) at {}, by {by:.3e}: the deformed mesh would gap or overlap there (give each hanging node the trilinear interpolation of the coarse cell it hangs on, or pass CGC_FILL_HANGING)",
                shown(at)
            ),
        ),
        UpdateError::Library(e) => Failure::from(e),
    })
}

impl CgcBody {
    fn new(state: BodyState) -> Self {
        Self {
            state: Arc::new(RwLock::new(state)),
        }
    }

    /// The state for reading (a panic while it was written left it whole: updates check first).
    pub(crate) fn read(state: &RwLock<BodyState>) -> RwLockReadGuard<'_, BodyState> {
        state.read().unwrap_or_else(PoisonError::into_inner)
    }

    fn write(&self) -> RwLockWriteGuard<'_, BodyState> {
        self.state.write().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A body on a lattice: `origin[3]`, spacing `h[3]`, `cells[3]` cells per axis. `active` is NULL
/// with `active_len` 0 (every cell active) or `active_len` bytes, one per lattice cell, nonzero
/// for an active cell, cells numbered `i + nx (j + ny k)` (x fastest). The body starts
/// undeformed. Cell numbers in answers are lattice cell numbers. Writes the new handle to `*out`.
///
/// Displacements (`cgc_body_set_displacements`) are then given for every lattice node,
/// `(nx + 1)(ny + 1)(nz + 1)` of them numbered `i + (nx + 1)(j + (ny + 1) k)`; values at nodes of
/// no active cell are ignored.
///
/// # Safety
/// Every non-NULL pointer must point to as many readable values as stated; `out` to one writable
/// pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_from_lattice(
    origin: *const f64,
    h: *const f64,
    cells: *const u32,
    active: *const u8,
    active_len: usize,
    out: *mut *mut CgcBody,
) -> CgcError {
    guard(|| {
        // SAFETY: the caller guarantees 3 readable values behind each non-NULL pointer.
        let (origin, h, counts) = unsafe {
            (
                raw::slice(origin, 3, "origin")?,
                raw::slice(h, 3, "h")?,
                raw::slice(cells, 3, "cells")?,
            )
        };
        let (origin, h) = (DVec3::from_slice(origin), DVec3::from_slice(h));
        if !(origin.is_finite() && h.is_finite()) {
            return Err(Failure::new(
                CgcError::NonFinite,
                format!(
                    "the lattice's origin {} or spacing {} is not finite",
                    shown(origin),
                    shown(h)
                ),
            ));
        }
        let lattice = Lattice::new(origin, h, [counts[0], counts[1], counts[2]])?;
        // A body takes about 48 bytes per node (its displacements and this API's copy): refuse
        // what cannot be allocated as an error, before an allocation failure would abort. The
        // kernel's overcommit grants each allocation of the build alone, then kills the process
        // that fills them: this asks for them together. The build's own allocations are fallible
        // too (`cgcontact::Error::OutOfMemory`), for what this misses: a limit on the address
        // space (RLIMIT_AS) that the build's peak, above these 48 bytes, exceeds.
        let mut probe = Vec::<[DVec3; 2]>::new();
        probe
            .try_reserve_exact(if active.is_null() {
                lattice.node_count()
            } else {
                0
            })
            .map_err(|_| {
                Failure::new(
                    CgcError::InvalidArgument,
                    format!(
                        "a body of {} lattice nodes does not fit in memory",
                        lattice.node_count()
                    ),
                )
            })?;
        drop(probe);
        if active.is_null() && active_len != 0 {
            return Err(Failure::new(
                CgcError::NullPointer,
                format!("active is NULL (for {active_len} flags): pass NULL with 0 for every cell"),
            ));
        }
        let body = if active.is_null() {
            Body::try_full(lattice)?
        } else {
            if active_len != lattice.cell_count() {
                return Err(Failure::new(
                    CgcError::LengthMismatch,
                    format!(
                        "active: the lattice has {} cells, got {active_len} flags",
                        lattice.cell_count()
                    ),
                ));
            }
            // SAFETY: the caller guarantees `active_len` readable bytes behind `active`.
            let flags = unsafe { raw::slice(active, active_len, "active") }?;
            let ids = flags.iter().enumerate().filter(|(_, f)| **f != 0);
            Body::from_cells(lattice, ids.map(|(c, _)| CellId(c as u32)))?
        };
        // SAFETY: the caller guarantees `out` is writable.
        unsafe { raw::give(out, CgcBody::new(BodyState::lattice(body)?), "out") }
    })
}

/// A body from undeformed nodes and hexahedra, whose lattice is detected from the nodes (to 1e-9
/// of the spacing). `nodes` holds `3 n_nodes` doubles, x y z per node; `cells` holds `8 n_cells`
/// node numbers per cell in VTK hexahedron order, numbered from `index_base` (0 for C, 1 for
/// MATLAB or Fortran). The body starts undeformed. Cell numbers in answers are 0-based places in
/// `cells`. Writes the new handle to `*out`.
///
/// Cells of one size make a uniform body: each must be one lattice cube. Cells of several sizes
/// make an adaptive body: each cell is a dyadic refinement of one base lattice (edges h/2^l, its
/// lowest corner on its level's lattice), no two overlap, and the nodes of finer cells that lie on
/// a coarser neighbour's edge or face (hanging nodes) are nodes of the mesh too. Cells and nodes
/// may come in any order.
///
/// Nodes are matched to the lattice within 1e-9 of the spacing plus their coordinates' rounding.
/// Where they lie off it by more than f64 rounding (coordinates that were 32-bit floats, or
/// decimal prints of few digits), each node stays where it is given: the deformed node `n` is
/// `nodes[n]` plus its displacement, before and after any `cgc_body_set_displacements`, as
/// `cgcontact locate` places a mesh file's nodes.
///
/// Every coordinate must be finite, at nodes that no cell uses too (`CGC_ERROR_NON_FINITE` names
/// the first such node, 0-based).
///
/// Displacements are then given for every node (`n_nodes` of them; those of nodes no cell uses
/// are ignored, and nodes at the same place must get the same displacement). On an adaptive body a
/// hanging node's displacement must be the trilinear interpolation of the coarse cell it hangs on
/// (1/2 and 1/2 of an edge's ends, 1/4 each of a face's corners, recursively): otherwise
/// `cgc_body_set_displacements` returns `CGC_ERROR_HANGING_CONSTRAINT`, unless the layout carries
/// `CGC_FILL_HANGING`.
///
/// # Safety
/// Every non-NULL pointer must point to as many readable values as stated; `out` to one writable
/// pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_from_mesh(
    nodes: *const f64,
    n_nodes: usize,
    cells: *const i64,
    n_cells: usize,
    index_base: i64,
    out: *mut *mut CgcBody,
) -> CgcError {
    guard(|| {
        // SAFETY: the caller guarantees the stated lengths behind non-NULL pointers.
        let (points, topology) = unsafe {
            (
                raw::points(nodes, n_nodes, "nodes")?,
                raw::slice(
                    cells,
                    n_cells.checked_mul(8).ok_or_else(|| {
                        Failure::new(
                            CgcError::LengthMismatch,
                            format!("cells: {n_cells} cells do not fit in memory"),
                        )
                    })?,
                    "cells",
                )?,
            )
        };
        if n_cells == 0 {
            return Err(Failure::new(
                CgcError::InvalidArgument,
                "the mesh has no cell",
            ));
        }
        if index_base != 0 && index_base != 1 {
            return Err(Failure::new(
                CgcError::InvalidArgument,
                format!("index_base is {index_base}; it must be 0 or 1"),
            ));
        }
        let mut hexes = Vec::with_capacity(n_cells);
        for (c, corners) in topology.chunks_exact(8).enumerate() {
            let mut cell = [0u32; 8];
            for (k, &node) in corners.iter().enumerate() {
                let index = node
                    .checked_sub(index_base)
                    .filter(|&i| i >= 0 && (i as u64) < n_nodes as u64);
                cell[k] = match index.and_then(|i| u32::try_from(i).ok()) {
                    Some(i) => i,
                    None => {
                        return Err(Failure::new(
                            CgcError::InvalidArgument,
                            format!(
                                "cell {} corner {k} (VTK corners count from 0): node {node} is not one of the {n_nodes} nodes numbered from {index_base}",
                                c as i64 + index_base
                            ),
                        ));
                    }
                };
            }
            hexes.push(cell);
        }
        // Every node, used or not, as the CLI's reader, Python and the MEX file check them: the
        // library checks only the nodes some cell uses.
        if let Some(node) = points.iter().position(|p| !p.is_finite()) {
            return Err(Failure::new(
                CgcError::NonFinite,
                format!(
                    "the coordinates of node {node} (0-based) are not finite: {}",
                    shown(points[node])
                ),
            ));
        }
        let mesh = HexMesh {
            ghosts: Vec::new(),
            points: points.to_vec(),
            cells: hexes,
            displacement: None,
        };
        let state = BodyState::mesh(&mesh, mesh.to_body()?);
        // SAFETY: the caller guarantees `out` is writable.
        unsafe { raw::give(out, CgcBody::new(state), "out") }
    })
}

/// Sets every displacement of the body, in place (nothing is rebuilt; locators made from the body
/// see the new values at their next call). `u` holds `3 n_nodes` doubles in `layout`
/// (`CGC_LAYOUT_NODE_MAJOR` or `CGC_LAYOUT_COMPONENT_MAJOR`, optionally `| CGC_FILL_HANGING`);
/// `n_nodes` must be `cgc_body_node_count`. Every value must be finite, at nodes that no cell
/// uses too (`CGC_ERROR_NON_FINITE` names the first such node). On any error (a length, a NaN, a
/// flag, a hanging node off its constraint) the body keeps its displacements.
///
/// On an adaptive body, each hanging node's displacement is checked against its constraint (to
/// 1e-9 of the finest spacing plus the rounding of the largest displacement):
/// `CGC_ERROR_HANGING_CONSTRAINT` names how many break it and the worst node. With
/// `CGC_FILL_HANGING`, the hanging nodes are set to their constraints' values instead.
///
/// # Safety
/// `body` must be a live handle or NULL; `u` must point to `3 n_nodes` readable doubles or be NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_set_displacements(
    body: *mut CgcBody,
    u: *const f64,
    n_nodes: usize,
    layout: u32,
) -> CgcError {
    guard(|| {
        // SAFETY: the caller guarantees a live handle.
        let body = unsafe { raw::handle(body, "body") }?;
        let order = layout & !CGC_FILL_HANGING;
        if order != CGC_LAYOUT_NODE_MAJOR && order != CGC_LAYOUT_COMPONENT_MAJOR {
            return Err(Failure::new(
                CgcError::InvalidArgument,
                format!(
                    "layout is {layout}; it must be CGC_LAYOUT_NODE_MAJOR (0) or CGC_LAYOUT_COMPONENT_MAJOR (1), optionally | CGC_FILL_HANGING (2)"
                ),
            ));
        }
        let mut state = body.write();
        if n_nodes != state.node_count() {
            return Err(Failure::new(
                CgcError::LengthMismatch,
                format!(
                    "displacements: the body has {} nodes, got {n_nodes}",
                    state.node_count()
                ),
            ));
        }
        // SAFETY: the caller guarantees 3 n_nodes readable doubles.
        let u = unsafe { raw::slice(u, n_nodes.saturating_mul(3), "u") }?;
        set_displacements(&mut state, u, layout)
    })
}

/// Writes to `*n_nodes` how many nodes `cgc_body_set_displacements` takes: the lattice's nodes for
/// a lattice body, the nodes given for a mesh body.
///
/// # Safety
/// `body` must be a live handle or NULL; `n_nodes` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_node_count(
    body: *const CgcBody,
    n_nodes: *mut usize,
) -> CgcError {
    // SAFETY: forwarded from the caller, under the same contract.
    unsafe { write_count(body, n_nodes, "n_nodes", BodyState::node_count) }
}

/// Writes to `*n_hanging` how many of the body's nodes are hanging (a node of a finer cell on an
/// edge or a face of a coarser neighbour, constrained by it): 0 for a uniform body.
///
/// # Safety
/// `body` must be a live handle or NULL; `n_hanging` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_hanging_count(
    body: *const CgcBody,
    n_hanging: *mut usize,
) -> CgcError {
    // SAFETY: forwarded from the caller, under the same contract.
    unsafe { write_count(body, n_hanging, "n_hanging", BodyState::hanging_count) }
}

/// Writes `count` of the body's current state to `*out` (named `name` in errors).
///
/// # Safety
/// As the public functions that call it: `body` a live handle or NULL, `out` writable or NULL.
unsafe fn write_count(
    body: *const CgcBody,
    out: *mut usize,
    name: &str,
    count: fn(&BodyState) -> usize,
) -> CgcError {
    guard(|| {
        // SAFETY: the caller guarantees a live handle and a writable output.
        let (body, out) = unsafe { (raw::handle(body, "body")?, raw::slice_mut(out, 1, name)?) };
        out[0] = count(&CgcBody::read(&body.state));
        Ok(())
    })
}

/// Lists the cells that the current displacements invert: those whose Jacobian determinant is
/// not positive at some corner (a node moved through its neighbours, or a collapsed cell).
/// Answers in or near such a cell are not to be trusted: a point in it may be found in no cell
/// (`cgc_locate` answers −1). The search does not check for them on each update: this call costs
/// one pass over every cell, so call it when wanted (after an update, or when a point is not
/// found).
///
/// Writes to `*count` how many cells are inverted, and, when they fit in `capacity`, their
/// numbers to `cells[0 .. *count]`, ascending and numbered as `cgc_locate` numbers cells (0-based
/// places in the mesh's `cells`, or lattice cell numbers). Two calls: `cells` NULL with
/// `capacity` 0 writes the count alone, then a buffer of `*count` values gets the list (a buffer
/// with room for every cell of the body does it in one call). A `capacity` from 1 to
/// `*count − 1` returns `CGC_ERROR_LENGTH_MISMATCH`, with `*count` written and `cells` left as it
/// was (another thread's update between the two calls can change the count).
///
/// # Safety
/// `body` must be a live handle or NULL; `cells` must point to `capacity` writable int64 or be
/// NULL; `count` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_inverted_cells(
    body: *const CgcBody,
    cells: *mut i64,
    capacity: usize,
    count: *mut usize,
) -> CgcError {
    // SAFETY: forwarded from the caller, under the same contract.
    unsafe {
        list_cells(
            body,
            cells,
            capacity,
            count,
            "inverted",
            BodyState::inverted_cells,
        )
    }
}

/// Lists the cells that f64 coordinates of their magnitude cannot resolve through their current
/// deformation. Far from the origin a coordinate is known only to its rounding (4 ε |x|); a cell
/// sheared or crushed enough turns that rounding into more than a tenth of the cell in ξ, and a
/// point that close to one of its faces may be given the cell beside it as well (`cgcontact
/// locate` warns, and reports the same cells in `--json` as `unresolved_cells`). As
/// [`cgc_body_inverted_cells`], this costs one pass over every cell and is called when wanted.
///
/// Writes to `*count` how many cells there are and, when they fit in `capacity`, their numbers
/// to `cells[0 .. *count]`, with the same two-call protocol, numbering and errors as
/// [`cgc_body_inverted_cells`].
///
/// # Safety
/// `body` must be a live handle or NULL; `cells` must point to `capacity` writable int64 or be
/// NULL; `count` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_unresolved_cells(
    body: *const CgcBody,
    cells: *mut i64,
    capacity: usize,
    count: *mut usize,
) -> CgcError {
    // SAFETY: forwarded from the caller, under the same contract.
    unsafe {
        list_cells(
            body,
            cells,
            capacity,
            count,
            "unresolved",
            BodyState::unresolved_cells,
        )
    }
}

/// The two-call protocol of the cell lists: writes the list's length to `*count` and, when
/// `capacity` is not 0, the list to `cells`, or says that it does not fit.
///
/// # Safety
/// As the public functions that call it: `body` a live handle or NULL, `cells` `capacity`
/// writable int64 or NULL, `count` writable or NULL.
unsafe fn list_cells(
    body: *const CgcBody,
    cells: *mut i64,
    capacity: usize,
    count: *mut usize,
    what: &str,
    list: fn(&BodyState) -> Vec<i64>,
) -> CgcError {
    guard(|| {
        raw::disjoint(&[
            raw::region(cells.cast_const(), capacity, "cells")?,
            raw::region(count.cast_const(), 1, "count")?,
        ])?;
        // SAFETY: the caller guarantees a live handle and the stated writable lengths; the two
        // outputs do not overlap (checked above).
        let (body, out, count) = unsafe {
            (
                raw::handle(body, "body")?,
                raw::slice_mut(cells, capacity, "cells")?,
                raw::slice_mut(count, 1, "count")?,
            )
        };
        let found = list(&CgcBody::read(&body.state));
        count[0] = found.len();
        if capacity == 0 {
            return Ok(());
        }
        let Some(out) = out.get_mut(..found.len()) else {
            return Err(Failure::new(
                CgcError::LengthMismatch,
                format!(
                    "cells: the body has {} {what} cells, room for {capacity} (*count holds the number needed)",
                    found.len()
                ),
            ));
        };
        out.copy_from_slice(&found);
        Ok(())
    })
}

/// Frees a body handle (NULL is a no-op). Locators made from it stay valid: they share the body,
/// which is freed with the last of them.
///
/// # Safety
/// `body` must be NULL or a live handle, not used again after this call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_body_free(body: *mut CgcBody) {
    // SAFETY: forwarded from the caller; a panic in a destructor is caught.
    let _ = std::panic::catch_unwind(|| unsafe { raw::free(body) });
}
