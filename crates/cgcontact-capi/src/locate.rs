//! Locators: settings, and locating a batch of points into caller-owned arrays.

use std::ptr;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};
use std::time::Instant;

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, Answer, LatticeLocator, Locator, Precision, Settings};
use cgcontact_baseline::BruteForce;
use cgcontact_io::{Kept, KeptBuffers};
use rayon::prelude::*;

use crate::body::{AnyBody, BodyState, CgcBody};
use crate::error::{CgcError, Failure, guard};
use crate::raw;

/// The lattice locator: hashes each point to its lattice cell (on an adaptive body, its leaf),
/// inverts the few neighbours that can hold it. The one to use.
pub const CGC_STRATEGY_LATTICE: u32 = 0;
/// Brute force: every active cell is tried (the test oracle; O(cells) per point).
pub const CGC_STRATEGY_BRUTE: u32 = 1;

/// Newton in f64 (the default; ξ to about 1e-15).
pub const CGC_PRECISION_F64: u32 = 0;
/// Newton in f32 in each cell's local frame (faster; ξ to about 1e-6).
pub const CGC_PRECISION_F32: u32 = 1;

/// A cell holds the point; its cell and ξ are written.
pub const CGC_POINT_INSIDE: u8 = 0;
/// No cell holds the point: cell −1, ξ NaN.
pub const CGC_POINT_OUTSIDE: u8 = 1;
/// The point has a NaN or infinite coordinate: cell −1, ξ NaN.
pub const CGC_POINT_NON_FINITE: u8 = 2;

/// The most threads a locator's own pool may have (`CgcSettings::threads`).
const MAX_THREADS: u32 = 1024;

/// Settings of a locator. Start from `cgc_settings_init`, then change fields.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgcSettings {
    /// `CGC_STRATEGY_LATTICE` or `CGC_STRATEGY_BRUTE`.
    pub strategy: u32,
    /// `CGC_PRECISION_F64` or `CGC_PRECISION_F32`.
    pub precision: u32,
    /// Newton stops when its step is at most this (ξ units); > 0. Keep it at most 1e-3: ξ spans 2
    /// across a cell, and a looser tolerance stops Newton before it has found the point, so
    /// answers can be off by about tol² and points near faces can be put in the wrong cell (or
    /// in none). `cgcontact --tol` and Python warn above 1e-3; this library accepts it silently.
    pub newton_tol: f64,
    /// Newton iteration limit per candidate cell; ≥ 1.
    pub max_iter: u32,
    /// A point is inside a cell when every |ξ_k| ≤ 1 + inside_tol (plus a rounding allowance); in
    /// [0, 0.1].
    pub inside_tol: f64,
    /// Threads for a query: 0 for every core (one pool shared by the process), else a pool of its
    /// own of this many threads, at most 1024.
    pub threads: u32,
}

/// Writes the default settings for `precision` (`CGC_PRECISION_F64` or `CGC_PRECISION_F32`) to
/// `*settings`: the lattice strategy, the library's measured default tolerances, every core.
///
/// # Safety
/// `settings` must be NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_settings_init(precision: u32, settings: *mut CgcSettings) -> CgcError {
    guard(|| {
        let core = match precision {
            CGC_PRECISION_F64 => Settings::default(),
            CGC_PRECISION_F32 => Settings::f32(),
            _ => return Err(bad_precision(precision)),
        };
        // SAFETY: the caller guarantees a writable settings struct.
        let out = unsafe { raw::slice_mut(settings, 1, "settings") }?;
        out[0] = CgcSettings {
            strategy: CGC_STRATEGY_LATTICE,
            precision,
            newton_tol: core.newton_tol,
            max_iter: core.max_iter,
            inside_tol: core.inside_tol,
            threads: 0,
        };
        Ok(())
    })
}

fn bad_precision(precision: u32) -> Failure {
    Failure::new(
        CgcError::InvalidArgument,
        format!(
            "precision is {precision}; it must be CGC_PRECISION_F64 (0) or CGC_PRECISION_F32 (1)"
        ),
    )
}

/// A locator over a body (opaque). Created by `cgc_locator_new`, freed by `cgc_locator_free`.
pub struct CgcLocator {
    body: Arc<RwLock<BodyState>>,
    strategy: u32,
    pub(crate) settings: Settings,
    pool: Option<rayon::ThreadPool>,
    kept: KeptBuffers,
}

impl CgcLocator {
    /// Runs `f` on the body's current state, on this locator's threads (the body stays read-locked
    /// meanwhile, so that an update waits for it).
    pub(crate) fn on_body<R: Send>(
        &self,
        f: impl FnOnce(&BodyState) -> Result<R, Failure> + Send,
    ) -> Result<R, Failure> {
        let state = CgcBody::read(&self.body);
        let state = &*state;
        match &self.pool {
            Some(pool) => pool.install(|| f(state)),
            None => f(state),
        }
    }

    /// Runs `f` with a locator over the body's current displacements, on this locator's threads.
    fn with<R: Send>(
        &self,
        f: impl FnOnce(&dyn Locator, &BodyState) -> R + Send,
    ) -> Result<R, Failure> {
        let state = CgcBody::read(&self.body);
        let state = &*state;
        let run = || -> Result<R, Failure> {
            Ok(match (&state.body, self.strategy) {
                (AnyBody::Uniform(body), CGC_STRATEGY_BRUTE) => {
                    f(&BruteForce::new(body, self.settings)?, state)
                }
                (AnyBody::Uniform(body), _) => f(&LatticeLocator::new(body, self.settings)?, state),
                (AnyBody::Adaptive(body), CGC_STRATEGY_BRUTE) => {
                    f(&BruteForce::new(body, self.settings)?, state)
                }
                (AnyBody::Adaptive(body), _) => {
                    f(&AdaptiveLocator::new(body, self.settings)?, state)
                }
            })
        };
        match &self.pool {
            Some(pool) => pool.install(run),
            None => run(),
        }
    }
}

/// A locator over `body` with `settings` (NULL: the f64 defaults). It shares the body: it sees
/// every later `cgc_body_set_displacements`, and keeps the body alive after `cgc_body_free`.
/// Writes the new handle to `*out`. Settings out of range are `CGC_ERROR_INVALID_ARGUMENT`, as
/// is `CGC_PRECISION_F32` on a body whose finest spacing lies outside [1e-11, 1e11] (the f32
/// kernel cannot resolve such cells: use f64).
///
/// # Safety
/// `body` must be a live handle or NULL; `settings` readable or NULL; `out` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_locator_new(
    body: *const CgcBody,
    settings: *const CgcSettings,
    out: *mut *mut CgcLocator,
) -> CgcError {
    guard(|| {
        // SAFETY: the caller guarantees a live handle.
        let body = unsafe { raw::handle(body, "body") }?;
        let given = if settings.is_null() {
            None
        } else {
            // SAFETY: the caller guarantees a readable struct when not NULL; `slice` checks its
            // alignment.
            Some(unsafe { raw::slice(settings, 1, "settings") }?[0])
        };
        let given = match given {
            Some(s) => s,
            None => {
                let mut s = std::mem::MaybeUninit::<CgcSettings>::uninit();
                // SAFETY: `s` is writable; on success it is initialised.
                let code = unsafe { cgc_settings_init(CGC_PRECISION_F64, s.as_mut_ptr()) };
                debug_assert_eq!(code, CgcError::Ok);
                // SAFETY: cgc_settings_init with a valid precision and pointer always writes it.
                unsafe { s.assume_init() }
            }
        };
        if given.strategy != CGC_STRATEGY_LATTICE && given.strategy != CGC_STRATEGY_BRUTE {
            return Err(Failure::new(
                CgcError::InvalidArgument,
                format!(
                    "strategy is {}; it must be CGC_STRATEGY_LATTICE (0) or CGC_STRATEGY_BRUTE (1)",
                    given.strategy
                ),
            ));
        }
        let precision = match given.precision {
            CGC_PRECISION_F64 => Precision::F64,
            CGC_PRECISION_F32 => Precision::F32,
            p => return Err(bad_precision(p)),
        };
        let settings = Settings {
            precision,
            newton_tol: given.newton_tol,
            max_iter: given.max_iter,
            inside_tol: given.inside_tol,
            ..Settings::default()
        };
        // The body's cells never change size: settings its search cannot use (f32 on cells too
        // small or too large for f32) are refused here, not at every query.
        settings.validate_for(CgcBody::read(&body.state).body.finest_spacing())?;
        let pool = match given.threads {
            0 => None,
            n if n > MAX_THREADS => {
                return Err(Failure::new(
                    CgcError::InvalidArgument,
                    format!(
                        "threads is {n}; a locator's own pool has at most {MAX_THREADS} threads \
                         (0: every core, the shared pool)"
                    ),
                ));
            }
            n => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n as usize)
                    .build()
                    .map_err(|e| {
                        Failure::new(CgcError::InvalidArgument, format!("{n} threads: {e}"))
                    })?,
            ),
        };
        // Every worker of the pool (rayon's shared one with 0 threads) has started, and so
        // allocated this library's thread-local data, before the locator is returned: loaded
        // with dlopen (Octave's MEX file), a worker that first ran later, in a call under little
        // memory, aborted the process ("cannot allocate memory for thread-local data").
        match &pool {
            Some(pool) => pool.broadcast(|_| ()),
            None => rayon::broadcast(|_| ()),
        };
        let locator = CgcLocator {
            body: Arc::clone(&body.state),
            strategy: given.strategy,
            settings,
            pool,
            kept: KeptBuffers::default(),
        };
        // SAFETY: the caller guarantees `out` is writable.
        unsafe { raw::give(out, locator, "out") }
    })
}

/// Points per piece of a query: each piece's answers are converted into the caller's arrays while
/// they are still in cache (2,048 answers take 115 kB). A batch the library may sort by cell
/// (`Locator::sorts_batch`: a large body, points out of order) is answered whole first, then
/// converted by pieces.
pub(crate) const PIECE: usize = 2048;

/// Locates `n_points` points. `points` holds `3 n_points` doubles, x y z per point (an n × 3
/// row-major array in C, 3 × n in MATLAB or Fortran), read in place. Writes for each point its cell
/// to `cells[i]` (−1 when none holds it), its local coordinates ξ ∈ [−1, 1]³ to `xi[3i..3i+3]`
/// (NaN when none), and, when `status` is not NULL, `CGC_POINT_INSIDE`, `CGC_POINT_OUTSIDE` or
/// `CGC_POINT_NON_FINITE` to `status[i]`. Answers use the body's displacements at the time of the
/// call. On a large body (more than 8 MB of nodal data: about 350,000 nodes in f64, 520,000 in
/// f32), a batch of 16,384 points or more not already in order is answered whole, so that the
/// library can sort it by cell: the call then holds about 100 bytes per point of buffers, of
/// which the answers' 56 stay with the locator for its next call (a solver loop's next batch;
/// `cgc_locator_free` releases them). Other batches are answered 2,048 points at a time.
///
/// Returns `CGC_ERROR_NON_FINITE_POINT` when some point has a NaN or infinite coordinate, after
/// writing every answer (the message names the first such point).
///
/// # Safety
/// `locator` must be a live handle or NULL; the arrays must hold the stated lengths. Output arrays
/// that overlap each other or `points` are refused (`CGC_ERROR_INVALID_ARGUMENT`), before
/// anything is written.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_locate(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    cells: *mut i64,
    xi: *mut f64,
    status: *mut u8,
) -> CgcError {
    // SAFETY: forwarded from the caller.
    guard(|| unsafe { locate(locator, points, n_points, None, cells, xi, status, false) })
}

/// `cgc_locate` warm started, for a solver loop: `cells` and `xi` hold each point's previous
/// answer (as `cgc_locate` or this call wrote it; cell −1 for none) and are overwritten with the
/// new one. A point whose previous cell still holds it costs one Newton inversion from its
/// previous ξ, with no search; the others are searched as `cgc_locate` does. The answers are
/// `cgc_locate`'s (the same cells, and ξ within the Newton tolerance: the inversion starts
/// elsewhere; on a face shared by two cells, either may answer, as in `cgc_locate`), whatever the
/// hints; a ξ that is not finite starts from the cell's centre.
///
/// Returns `CGC_ERROR_INVALID_ARGUMENT`, before anything is written, when a previous cell is
/// neither −1 nor a cell of the body (the message names the first such point), and
/// `CGC_ERROR_NON_FINITE_POINT` as `cgc_locate` does.
///
/// # Safety
/// As `cgc_locate`; `cells` and `xi` must also be readable (initialised).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_relocate(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    cells: *mut i64,
    xi: *mut f64,
    status: *mut u8,
) -> CgcError {
    // SAFETY: forwarded from the caller.
    guard(|| unsafe { locate(locator, points, n_points, None, cells, xi, status, true) })
}

/// `cgc_locate` (`order` `None`, `warm` false), `cgc_relocate` (`warm` true) and
/// `cgc_locate_unordered` (`order` given).
///
/// # Safety
/// As `cgc_relocate` when `warm`, `cgc_locate_unordered` when `order` is given, else as
/// `cgc_locate`.
#[allow(clippy::too_many_arguments)]
unsafe fn locate(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    order: Option<*mut i64>,
    cells: *mut i64,
    xi: *mut f64,
    status: *mut u8,
    warm: bool,
) -> Result<(), Failure> {
    // SAFETY: forwarded from the caller.
    let (locator, arrays) =
        unsafe { query_arrays(locator, points, n_points, order, cells, xi, status) }?;
    locate_checked(locator, arrays, warm)
}

/// A query's arrays, checked: lengths, alignment, and no output overlapping another or the
/// points (`order` only for `cgc_locate_unordered`).
struct Arrays<'a> {
    points: &'a [DVec3],
    order: Option<&'a mut [i64]>,
    cells: &'a mut [i64],
    xi: &'a mut [f64],
    status: Option<&'a mut [u8]>,
}

/// The locator behind `locator` and the query's [`Arrays`], or the error for the first that is
/// wrong; nothing is written.
///
/// # Safety
/// As `cgc_locate_unordered` (`order` `None` for the other calls).
unsafe fn query_arrays<'a>(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    order: Option<*mut i64>,
    cells: *mut i64,
    xi: *mut f64,
    status: *mut u8,
) -> Result<(&'a CgcLocator, Arrays<'a>), Failure> {
    let n3 = raw::triples(n_points, "points")?;
    let status_len = if status.is_null() { 0 } else { n_points };
    let order_region = match order {
        Some(order) => raw::region(order, n_points, "order")?,
        None => raw::region(ptr::null::<i64>(), 0, "order")?,
    };
    raw::disjoint(&[
        raw::region(points, n3, "points")?,
        order_region,
        raw::region(cells, n_points, "cells")?,
        raw::region(xi, n3, "xi")?,
        raw::region(status, status_len, "status")?,
    ])?;
    // SAFETY: the caller guarantees a live handle and arrays of the stated lengths (`status`
    // NULL or as long), which were just checked not to overlap.
    unsafe {
        Ok((
            raw::handle(locator, "locator")?,
            Arrays {
                points: raw::points(points, n_points, "points")?,
                order: order
                    .map(|order| raw::slice_mut(order, n_points, "order"))
                    .transpose()?,
                cells: raw::slice_mut(cells, n_points, "cells")?,
                xi: raw::slice_mut(xi, n3, "xi")?,
                status: (!status.is_null())
                    .then(|| raw::slice_mut(status, n_points, "status"))
                    .transpose()?,
            },
        ))
    }
}

/// `cgc_locate`, `cgc_relocate` (`warm`) and `cgc_locate_unordered` (with `order`) on checked
/// arrays, with one locator built for the query.
fn locate_checked(locator: &CgcLocator, arrays: Arrays<'_>, warm: bool) -> Result<(), Failure> {
    let Arrays {
        points,
        order,
        cells,
        xi,
        status,
    } = arrays;
    let first_bad = AtomicUsize::new(usize::MAX);
    locator.kept.with(|kept| {
        locator.with(|search, state| {
            if warm && let Some(i) = cells.iter().position(|&c| !is_hint(state, c)) {
                let why = if state.cells.cell(cells[i]).is_ok() {
                    format!("lattice cell {} is not active in this body", cells[i])
                } else {
                    format!(
                        "the cells are numbered 0 to {}",
                        state.cells.len() as i64 - 1
                    )
                };
                return Err(Failure::new(
                    CgcError::InvalidArgument,
                    format!(
                        "cells[{i}] = {} is not a previous answer: {why} (-1 for none)",
                        cells[i]
                    ),
                ));
            }
            let sorted = search.sorts_batch(points);
            if let Some(order) = order {
                if sorted {
                    let Kept {
                        answers,
                        order: found,
                    } = kept;
                    search.locate_all_unordered_into(points, found, answers);
                    let answered = (&found[..], &answers[..]);
                    write_unordered(state, answered, order, cells, xi, status, &first_bad);
                    return Ok(());
                }
                // Not sorted: the rows in the points' order, answered as `cgc_locate` does.
                order
                    .par_iter_mut()
                    .enumerate()
                    .for_each(|(k, o)| *o = k as i64);
            }
            // A point's answer, cold or warm (`answers` holds the hints, read from `cells` and `xi`).
            let answer =
                |points: &[DVec3], cells: &[i64], xi: &[f64], answers: &mut Vec<Answer>| {
                    if warm {
                        state.cells.previous_answers(cells, xi, answers);
                        search.relocate_all(points, answers);
                    } else {
                        search.locate_all_into(points, answers);
                    }
                };
            // The answers of points `start..` into the caller's arrays.
            let write = |start: usize,
                         answers: &[Answer],
                         cells: &mut [i64],
                         xi: &mut [f64],
                         mut status: Option<&mut [u8]>| {
                for (i, answer) in answers.iter().enumerate() {
                    let (cell, local, code) = converted(state, answer);
                    if code == CGC_POINT_NON_FINITE {
                        first_bad.fetch_min(start + i, Ordering::Relaxed);
                    }
                    cells[i] = cell;
                    local.write_to_slice(&mut xi[3 * i..3 * i + 3]);
                    if let Some(status) = status.as_deref_mut() {
                        status[i] = code;
                    }
                }
            };
            // A batch the library may sort by cell (a large body) is answered whole, then written
            // piece by piece: split into pieces, it would be answered in the caller's order, up to
            // 2.5x slower at scale. Else each piece is answered and written while in cache.
            let whole = sorted.then(|| {
                answer(points, cells, xi, &mut kept.answers);
                &kept.answers[..]
            });
            let pieces = points
                .par_chunks(PIECE)
                .zip(cells.par_chunks_mut(PIECE))
                .zip(xi.par_chunks_mut(3 * PIECE))
                .enumerate();
            let piece = |answers: &mut Vec<Answer>,
                         k: usize,
                         points: &[DVec3],
                         cells: &mut [i64],
                         xi: &mut [f64],
                         status: Option<&mut [u8]>| {
                let start = k * PIECE;
                match whole {
                    Some(all) => write(start, &all[start..start + points.len()], cells, xi, status),
                    None => {
                        answer(points, cells, xi, answers);
                        write(start, answers, cells, xi, status);
                    }
                }
            };
            match status {
                Some(status) => pieces
                    .zip(status.par_chunks_mut(PIECE))
                    .for_each_init(Vec::new, |answers, ((k, ((p, c), x)), s)| {
                        piece(answers, k, p, c, x, Some(s))
                    }),
                None => pieces.for_each_init(Vec::new, |answers, (k, ((p, c), x))| {
                    piece(answers, k, p, c, x, None)
                }),
            }
            Ok(())
        })
    })??;
    first_non_finite(points, first_bad.into_inner())
}

/// An answer as the caller's arrays hold it: the cell in the caller's numbering (−1 for none), ξ
/// (NaN for none) and the point's status.
fn converted(state: &BodyState, answer: &Answer) -> (i64, DVec3, u8) {
    match answer {
        Ok(Some(hit)) => (state.cells.number(hit.cell), hit.xi, CGC_POINT_INSIDE),
        Ok(None) => (-1, DVec3::NAN, CGC_POINT_OUTSIDE),
        Err(_) => (-1, DVec3::NAN, CGC_POINT_NON_FINITE),
    }
}

/// `cgc_locate` without putting the answers back in the points' order: row `k` of `cells`, `xi`
/// and `status` answers point `order[k]`, in the order the library answered them, each point once.
/// On a large body with a batch it sorts by cell (see `cgc_locate`), that is cell by cell, and the
/// call saves putting each answer back at its point's place, a store to a random place per
/// point: `Locator::locate_all_unordered_into` ran 1.1 to 1.4 times as fast as the library's
/// `locate_all_into` on 1 M random points in a 4.2 M-cell block (docs/benchmarks.md). Otherwise
/// the rows come in the points' order (`order[k]` = k). A solver that assembles each point's
/// contribution wherever its answer comes does not need them in order. The answers are bitwise
/// `cgc_locate`'s. The whole batch is answered at once: about 110 bytes per point of buffers when
/// it is sorted, of which 64 stay with the locator for its next call.
///
/// Returns `CGC_ERROR_NON_FINITE_POINT` as `cgc_locate` does, naming the first such point in the
/// points' order (0-based), after writing every row.
///
/// # Safety
/// As `cgc_locate`; `order` must be writable for `n_points` values and overlap no other array.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_locate_unordered(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    order: *mut i64,
    cells: *mut i64,
    xi: *mut f64,
    status: *mut u8,
) -> CgcError {
    // SAFETY: forwarded from the caller.
    guard(|| unsafe {
        locate(
            locator,
            points,
            n_points,
            Some(order),
            cells,
            xi,
            status,
            false,
        )
    })
}

/// `cgc_locate_unordered`'s rows from the library's unordered answers of a sorted batch: row k
/// answers point `found[k]` (written to `order[k]`); `first_bad` gets the first refused point
/// in the points' order.
fn write_unordered(
    state: &BodyState,
    (found, answers): (&[usize], &[Answer]),
    order_out: &mut [i64],
    cells: &mut [i64],
    xi: &mut [f64],
    status: Option<&mut [u8]>,
    first_bad: &AtomicUsize,
) {
    let rows = order_out
        .par_chunks_mut(PIECE)
        .zip(cells.par_chunks_mut(PIECE))
        .zip(xi.par_chunks_mut(3 * PIECE))
        .zip(found.par_chunks(PIECE).zip(answers.par_chunks(PIECE)));
    let write = |order: &mut [i64],
                 cells: &mut [i64],
                 xi: &mut [f64],
                 (found, answers): (&[usize], &[Answer]),
                 mut status: Option<&mut [u8]>| {
        for (k, (&i, answer)) in found.iter().zip(answers).enumerate() {
            let (cell, local, code) = converted(state, answer);
            if code == CGC_POINT_NON_FINITE {
                first_bad.fetch_min(i, Ordering::Relaxed);
            }
            order[k] = i as i64;
            cells[k] = cell;
            local.write_to_slice(&mut xi[3 * k..3 * k + 3]);
            if let Some(status) = status.as_deref_mut() {
                status[k] = code;
            }
        }
    };
    match status {
        Some(status) => rows.zip(status.par_chunks_mut(PIECE)).for_each(
            |((((order, cells), xi), answered), status)| {
                write(order, cells, xi, answered, Some(status))
            },
        ),
        None => rows
            .for_each(|(((order, cells), xi), answered)| write(order, cells, xi, answered, None)),
    }
}

/// Whether `number` may be a previous answer of the body in `state`: −1, or one of its cells (on a
/// lattice body with inactive cells, a lattice cell number of an active cell).
fn is_hint(state: &BodyState, number: i64) -> bool {
    match (state.cells.cell(number), &state.body) {
        (Err(()), _) => false,
        (Ok(Some(cell)), AnyBody::Uniform(body)) => body.is_active(cell),
        (Ok(_), _) => true,
    }
}

/// `CGC_ERROR_NON_FINITE_POINT` naming point `first` (0-based), the first a query refused, or
/// success when it refused none (`usize::MAX`).
pub(crate) fn first_non_finite(points: &[DVec3], first: usize) -> Result<(), Failure> {
    match first {
        usize::MAX => Ok(()),
        i => Err(Failure::new(
            CgcError::NonFinitePoint,
            format!(
                "point {i} (0-based) has a NaN or infinite coordinate: {}",
                crate::error::shown(points[i])
            ),
        )),
    }
}

/// The library's own query time, for measuring what this API adds: runs the Rust library's
/// `locate_all_into` on the points `1 + repeats` times into one reused answer buffer (no
/// conversion, nothing written for the caller) and writes the shortest of the last `repeats` runs
/// (the first when `repeats` is 0), in seconds, to `*seconds`.
///
/// # Safety
/// As `cgc_locate`; `seconds` writable or NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_locator_query_seconds(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    repeats: u32,
    seconds: *mut f64,
) -> CgcError {
    guard(|| {
        let n3 = raw::triples(n_points, "points")?;
        raw::disjoint(&[
            raw::region(points, n3, "points")?,
            raw::region(seconds.cast_const(), 1, "seconds")?,
        ])?;
        // SAFETY: the caller guarantees a live handle, readable points and a writable output,
        // which was just checked not to overlap the points.
        let (locator, points, seconds) = unsafe {
            (
                raw::handle(locator, "locator")?,
                raw::points(points, n_points, "points")?,
                raw::slice_mut(seconds, 1, "seconds")?,
            )
        };
        seconds[0] = locator.with(|search, _| {
            let mut answers = Vec::new();
            let mut best = f64::INFINITY;
            for run in 0..=repeats {
                let start = Instant::now();
                search.locate_all_into(points, &mut answers);
                let t = start.elapsed().as_secs_f64();
                if run > 0 || repeats == 0 {
                    best = best.min(t);
                }
            }
            best
        })?;
        Ok(())
    })
}

/// Frees a locator (NULL is a no-op).
///
/// # Safety
/// `locator` must be NULL or a live handle, not used again after this call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_locator_free(locator: *mut CgcLocator) {
    // SAFETY: forwarded from the caller; a panic in a destructor is caught.
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| unsafe {
        raw::free(locator)
    }));
}
