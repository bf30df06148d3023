//! The only place where C pointers become Rust references: each helper checks NULL, alignment and
//! size before it builds a slice, so that the entry points hold no `unsafe` of their own beyond
//! calling these.

use glam::DVec3;

use crate::error::{CgcError, Failure};

// A point or a displacement is read as a `DVec3`, which glam declares `#[repr(C)]` with fields
// x, y, z: three f64, 24 bytes aligned as f64. The casts below rely on it.
const _: () = assert!(size_of::<DVec3>() == 3 * size_of::<f64>());
const _: () = assert!(align_of::<DVec3>() == align_of::<f64>());

/// Checks `ptr` for `len` elements of `T`: not NULL (unless `len` is 0), aligned, and at most
/// `isize::MAX` bytes. `what` names the argument in the error.
fn check<T>(ptr: *const T, len: usize, what: &str) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::new(
            CgcError::NullPointer,
            format!("{what} is NULL (for {len} values)"),
        ));
    }
    if !ptr.is_aligned() {
        return Err(Failure::new(
            CgcError::InvalidArgument,
            format!(
                "{what} is not aligned to {} bytes (address {ptr:p})",
                align_of::<T>()
            ),
        ));
    }
    if len
        .checked_mul(size_of::<T>())
        .is_none_or(|b| b > isize::MAX as usize)
    {
        return Err(Failure::new(
            CgcError::LengthMismatch,
            format!("{what}: {len} values do not fit in memory"),
        ));
    }
    Ok(())
}

/// Where an array argument lies in memory: its name and its bytes `start..end`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Region<'a> {
    what: &'a str,
    start: usize,
    end: usize,
}

/// The memory of `len` values of `T` at `ptr`, checked as [`slice`] checks it (an empty region
/// when `ptr` is NULL and `len` is 0), for [`disjoint`] to compare before any slice is made.
pub(crate) fn region<'a, T>(
    ptr: *const T,
    len: usize,
    what: &'a str,
) -> Result<Region<'a>, Failure> {
    if len == 0 {
        return Ok(Region {
            what,
            start: 0,
            end: 0,
        });
    }
    check(ptr, len, what)?;
    let start = ptr as usize;
    // `check` bounded the bytes by isize::MAX; an allocation cannot wrap the address space.
    let end = start.saturating_add(len * size_of::<T>());
    Ok(Region { what, start, end })
}

/// An error when two of `regions` share a byte: an output written over an input, or two outputs
/// over each other, would give answers that depend on the order of the writes (and Rust's
/// slices of them would alias).
pub(crate) fn disjoint(regions: &[Region<'_>]) -> Result<(), Failure> {
    let filled = |r: &&Region<'_>| r.start < r.end;
    for (k, a) in regions.iter().enumerate().filter(|(_, r)| filled(r)) {
        for b in regions[k + 1..].iter().filter(filled) {
            if a.start < b.end && b.start < a.end {
                return Err(Failure::new(
                    CgcError::InvalidArgument,
                    format!(
                        "{} and {} overlap in memory ({:#x}..{:#x} and {:#x}..{:#x}): outputs must not overlap each other or the inputs",
                        a.what, b.what, a.start, a.end, b.start, b.end
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// `len` values of `T` read from `ptr`; an empty slice when `len` is 0, whatever `ptr` is.
///
/// # Safety
/// When `ptr` is not NULL and `len > 0`, it must point to `len` initialised values of `T` that
/// nothing writes to while the slice lives.
pub(crate) unsafe fn slice<'a, T>(
    ptr: *const T,
    len: usize,
    what: &str,
) -> Result<&'a [T], Failure> {
    if len == 0 {
        return Ok(&[]);
    }
    check(ptr, len, what)?;
    // SAFETY: `ptr` is non-null, aligned and the byte size fits isize (checked above); the caller
    // guarantees `len` initialised values that nobody mutates meanwhile.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// `len` values of `T` written through `ptr`; an empty slice when `len` is 0.
///
/// # Safety
/// When `ptr` is not NULL and `len > 0`, it must point to `len` writable values of `T` that
/// nothing else reads or writes while the slice lives (in particular, no other argument of the
/// same call).
pub(crate) unsafe fn slice_mut<'a, T>(
    ptr: *mut T,
    len: usize,
    what: &str,
) -> Result<&'a mut [T], Failure> {
    if len == 0 {
        return Ok(&mut []);
    }
    check(ptr, len, what)?;
    // SAFETY: as in `slice`, and the caller guarantees exclusive access for the call.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, len) })
}

/// 3 n, the values of `n` points (x y z each) of the array `what`, or the error that they do not
/// fit in memory.
pub(crate) fn triples(n: usize, what: &str) -> Result<usize, Failure> {
    n.checked_mul(3).ok_or_else(|| {
        Failure::new(
            CgcError::LengthMismatch,
            format!("{what}: {n} points do not fit in memory"),
        )
    })
}

/// `n` points given as 3 n doubles, x y z per point, read in place as `DVec3` (no copy).
///
/// # Safety
/// As [`slice`] for `3 n` values of f64.
pub(crate) unsafe fn points<'a>(
    ptr: *const f64,
    n: usize,
    what: &str,
) -> Result<&'a [DVec3], Failure> {
    let len = triples(n, what)?;
    // SAFETY: forwarded from the caller.
    let flat = unsafe { slice(ptr, len, what) }?;
    // SAFETY: `flat` holds 3 n f64 at an address aligned for f64; DVec3 is #[repr(C)] of three f64
    // with f64's alignment (asserted at compile time above), so the same memory is n DVec3.
    Ok(unsafe { std::slice::from_raw_parts(flat.as_ptr().cast::<DVec3>(), n) })
}

/// A reference to the object behind a handle, or a NULL-pointer error naming `what`.
///
/// # Safety
/// When not NULL, `ptr` must come from this library's constructor of `T` and not be freed.
pub(crate) unsafe fn handle<'a, T>(ptr: *const T, what: &str) -> Result<&'a T, Failure> {
    // SAFETY: the caller guarantees a live handle created by this library (a Box<T>).
    unsafe { ptr.as_ref() }
        .ok_or_else(|| Failure::new(CgcError::NullPointer, format!("{what} is NULL")))
}

/// Writes a new handle to `out`.
///
/// # Safety
/// `out` must be NULL (an error) or point to writable memory for one pointer.
pub(crate) unsafe fn give<T>(out: *mut *mut T, value: T, what: &str) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::new(
            CgcError::NullPointer,
            format!("{what} is NULL"),
        ));
    }
    if !out.is_aligned() {
        return Err(Failure::new(
            CgcError::InvalidArgument,
            format!(
                "{what} is not aligned to {} bytes (address {out:p})",
                align_of::<*mut T>()
            ),
        ));
    }
    // SAFETY: `out` is non-null and aligned, and the caller guarantees it is writable; `write`
    // does not read (or drop) whatever it held before.
    unsafe { out.write(Box::into_raw(Box::new(value))) };
    Ok(())
}

/// Takes back and drops a handle given by [`give`]; NULL is a no-op.
///
/// # Safety
/// `ptr` must be NULL or a handle from [`give`] of the same `T`, not freed before, and unused after.
pub(crate) unsafe fn free<T>(ptr: *mut T) {
    if !ptr.is_null() {
        // SAFETY: the caller guarantees `ptr` came from Box::into_raw in `give` and is freed once.
        drop(unsafe { Box::from_raw(ptr) });
    }
}
