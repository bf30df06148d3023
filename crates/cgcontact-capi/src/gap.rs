//! Gaps: the signed distance of points to the body's deformed boundary surface, the closest
//! point there, the outward normal and the face, into caller-owned arrays.

use std::sync::atomic::{AtomicUsize, Ordering};

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, GapAnswer, GapFinder, LatticeLocator, Surface};
use rayon::prelude::*;

use crate::body::{AnyBody, BodyState};
use crate::error::{CgcError, Failure, guard};
use crate::locate::{CgcLocator, PIECE};
use crate::raw;

/// The caller's output arrays for one piece of the points; `None` where the caller passed NULL.
struct Out<'a> {
    gap: Option<&'a mut [f64]>,
    closest: Option<&'a mut [f64]>,
    normal: Option<&'a mut [f64]>,
    face_cell: Option<&'a mut [i64]>,
    face: Option<&'a mut [i32]>,
}

impl Out<'_> {
    /// Writes point `i`'s answer (of this piece): NaN, −1 and −1 where there is none.
    #[inline]
    fn write(&mut self, i: usize, answer: &GapAnswer, state: &BodyState) {
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
        if let Some(out) = self.gap.as_deref_mut() {
            out[i] = gap;
        }
        if let Some(out) = self.closest.as_deref_mut() {
            closest.write_to_slice(&mut out[3 * i..3 * i + 3]);
        }
        if let Some(out) = self.normal.as_deref_mut() {
            normal.write_to_slice(&mut out[3 * i..3 * i + 3]);
        }
        if let Some(out) = self.face_cell.as_deref_mut() {
            out[i] = cell;
        }
        if let Some(out) = self.face.as_deref_mut() {
            out[i] = face;
        }
    }
}

/// `count` pieces of `values` per `size` values each (all `None` when the caller passed NULL).
fn pieces<T>(values: Option<&mut [T]>, size: usize, count: usize) -> Vec<Option<&mut [T]>> {
    match values {
        Some(values) => values.chunks_mut(size).map(Some).collect(),
        None => (0..count).map(|_| None).collect(),
    }
}

/// An optional output of `len` values: `None` when `ptr` is NULL.
///
/// # Safety
/// As [`raw::slice_mut`].
unsafe fn optional<'a, T>(
    ptr: *mut T,
    len: usize,
    what: &str,
) -> Result<Option<&'a mut [T]>, Failure> {
    if ptr.is_null() {
        Ok(None)
    } else {
        // SAFETY: forwarded from the caller.
        unsafe { raw::slice_mut(ptr, len, what) }.map(Some)
    }
}

/// Answers every point with `finder` into the pieces `out`; returns the first point refused (or
/// `usize::MAX`). A batch the library may sort by cell (a large body) is answered whole first: in
/// pieces it would be answered in the caller's order, slower at scale.
fn answer_all<L: Surface + Sync>(
    finder: &GapFinder<'_, L>,
    points: &[DVec3],
    out: Vec<Out<'_>>,
    state: &BodyState,
) -> usize {
    let whole = finder.sorts_batch(points).then(|| {
        let mut answers = Vec::new();
        finder.gap_all_into(points, &mut answers);
        answers
    });
    let first_bad = AtomicUsize::new(usize::MAX);
    out.into_par_iter()
        .zip(points.par_chunks(PIECE))
        .enumerate()
        .for_each(|(k, (mut out, points))| {
            for (i, &x) in points.iter().enumerate() {
                let answer = match &whole {
                    Some(all) => all[k * PIECE + i],
                    None => finder.gap(x),
                };
                if answer.is_err() {
                    first_bad.fetch_min(k * PIECE + i, Ordering::Relaxed);
                }
                out.write(i, &answer, state);
            }
        });
    first_bad.into_inner()
}

/// The signed gap of `n_points` points to the body's deformed boundary surface, searched within
/// `distance`. `points` holds `3 n_points` doubles, x y z per point, read in place. The boundary
/// surface is every face of an active cell (a leaf, on an adaptive body) that no other active cell
/// covers, deformed into a bilinear quad. For each point i, writes:
///
/// - `gap[i]`: the distance to the closest point of that surface, negative when a cell of the
///   body holds the point (the locator's answer, with its inside tolerance), 0 on the surface;
/// - `closest[3i..3i+3]`: that closest point;
/// - `normal[3i..3i+3]`: the unit outward normal, so that point = closest + gap · normal (the
///   face's normal where the closest point lies inside a face, the direction from it to the point
///   where it lies on an edge or a corner; within the locator's rounding allowance of the surface,
///   where the locator's sign is against that direction, the face's normal, and the equation
///   holds to 2 |gap|);
/// - `face_cell[i]`: the cell of the face holding the closest point, numbered as `cgc_locate`
///   numbers cells (lattice cell numbers, or 0-based places in `cells` for a body from
///   `cgc_body_from_mesh`); on an edge or a corner shared by several faces, one of them;
/// - `face[i]`: which face of that cell, 0..5: face f lies at local coordinate f / 2 (ξ, η, ζ)
///   = −1 for even f and +1 for odd f, through the VTK corners {0 4 7 3}, {1 2 6 5}, {0 1 5 4},
///   {3 7 6 2}, {0 3 2 1}, {4 5 6 7} (5 is the top, ζ = +1).
///
/// Where the surface is farther than `distance` from a point (outside the body, or deep inside
/// it), its gap, closest point and normal
/// are NaN and its `face_cell` and `face` −1; likewise for a point with a NaN or infinite
/// coordinate, and then the call returns `CGC_ERROR_NON_FINITE_POINT` after writing every answer
/// (the message names the first such point). The cost grows with `distance`: give the largest
/// gap the solver needs, not more. A large batch on a large body is answered whole, as by
/// `cgc_locate`, with temporary buffers of about 130 bytes per point.
///
/// Each output may be NULL, to skip it; those given hold `n_points` values (`3 n_points` for
/// `closest` and `normal`). `distance` must be finite, ≥ 0 and ≤ 1e150 (else
/// `CGC_ERROR_INVALID_ARGUMENT`, and nothing is written). Answers use the body's displacements at
/// the time of the call, on the locator's threads; the search is the lattice's for either
/// strategy, with the locator's precision and tolerances deciding the sign near the surface.
///
/// # Safety
/// `locator` must be a live handle or NULL; the arrays must hold the stated lengths. Output arrays
/// that overlap each other or `points` are refused (`CGC_ERROR_INVALID_ARGUMENT`), before
/// anything is written.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cgc_gap(
    locator: *const CgcLocator,
    points: *const f64,
    n_points: usize,
    distance: f64,
    gap: *mut f64,
    closest: *mut f64,
    normal: *mut f64,
    face_cell: *mut i64,
    face: *mut i32,
) -> CgcError {
    guard(|| {
        let n3 = raw::triples(n_points, "points")?;
        let given = |ptr: bool, len: usize| if ptr { 0 } else { len };
        raw::disjoint(&[
            raw::region(points, n3, "points")?,
            raw::region(gap, given(gap.is_null(), n_points), "gap")?,
            raw::region(closest, given(closest.is_null(), n3), "closest")?,
            raw::region(normal, given(normal.is_null(), n3), "normal")?,
            raw::region(face_cell, given(face_cell.is_null(), n_points), "face_cell")?,
            raw::region(face, given(face.is_null(), n_points), "face")?,
        ])?;
        // SAFETY: the caller guarantees a live handle and arrays of the stated lengths, which
        // were just checked not to overlap.
        let (locator, points, gap, closest, normal, face_cell, face) = unsafe {
            (
                raw::handle(locator, "locator")?,
                raw::points(points, n_points, "points")?,
                optional(gap, n_points, "gap")?,
                optional(closest, n3, "closest")?,
                optional(normal, n3, "normal")?,
                optional(face_cell, n_points, "face_cell")?,
                optional(face, n_points, "face")?,
            )
        };
        if !(0.0..=cgcontact::MAX_DISPLACEMENT).contains(&distance) {
            return Err(Failure::new(
                CgcError::InvalidArgument,
                format!(
                    "distance is {}; the gap search distance must be finite, at least 0 \
                     and at most {:e}",
                    crate::error::number(distance),
                    cgcontact::MAX_DISPLACEMENT
                ),
            ));
        }
        let count = n_points.div_ceil(PIECE);
        let out: Vec<Out<'_>> = pieces(gap, PIECE, count)
            .into_iter()
            .zip(pieces(closest, 3 * PIECE, count))
            .zip(pieces(normal, 3 * PIECE, count))
            .zip(pieces(face_cell, PIECE, count))
            .zip(pieces(face, PIECE, count))
            .map(|((((gap, closest), normal), face_cell), face)| Out {
                gap,
                closest,
                normal,
                face_cell,
                face,
            })
            .collect();
        let settings = locator.settings;
        let first_bad = locator.on_body(|state| {
            Ok(match &state.body {
                AnyBody::Uniform(body) => {
                    let search = LatticeLocator::new(body, settings)?;
                    answer_all(&GapFinder::new(&search, distance)?, points, out, state)
                }
                AnyBody::Adaptive(body) => {
                    let search = AdaptiveLocator::new(body, settings)?;
                    answer_all(&GapFinder::new(&search, distance)?, points, out, state)
                }
            })
        })?;
        crate::locate::first_non_finite(points, first_bad)
    })
}
