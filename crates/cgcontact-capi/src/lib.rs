//! # cgcontact-capi
//!
//! The C ABI of [`cgcontact`]: build a lattice body, set its displacements in place between solver
//! iterations, and locate points (which deformed hexahedron holds each, at which ξ ∈ [−1, 1]³) from
//! C, C++, Fortran, or MATLAB/Octave through the MEX in `octave/`. Built as a shared library
//! (`libcgcontact_capi.so`) and a static one (`libcgcontact_capi.a`); the header
//! `include/cgcontact.h` is generated from this crate by cbindgen and checked in.
//!
//! | call | what it does |
//! |---|---|
//! | [`cgc_body_from_lattice`] | a body on a lattice (origin, spacing, counts, optional active mask) |
//! | [`cgc_body_from_mesh`] | a body from nodes and hexahedra (VTK order); the lattice is detected, with its refinement levels on an adaptive mesh |
//! | [`cgc_body_set_displacements`] | every nodal displacement, in place, node- or component-major; hanging nodes checked or filled ([`CGC_FILL_HANGING`]) |
//! | [`cgc_body_hanging_count`] | how many nodes hang on a coarser neighbour (0 for a uniform body) |
//! | [`cgc_body_inverted_cells`] | the cells the displacements invert (det J ≤ 0 at a corner), where no point is found: one pass over the cells, on demand |
//! | [`cgc_body_unresolved_cells`] | the cells that f64 coordinates of their magnitude cannot resolve through their deformation (far from the origin, sheared or crushed), where a point near a face may be given the cell beside it too: one pass over the cells, on demand |
//! | [`cgc_settings_init`], [`cgc_locator_new`] | a locator with settings (strategy, precision, tolerances, threads) |
//! | [`cgc_locate`] | n points → cell (−1 none), ξ (n × 3), a status per point |
//! | [`cgc_relocate`] | the same, warm started from each point's previous cell and ξ (a solver loop): one inversion where the cell still holds the point |
//! | [`cgc_gap`] | n points → signed gap to the deformed boundary surface within a distance, closest point, outward normal, face (cell and local face) |
//! | [`cgc_last_error`] | the message of the calling thread's last failure |
//!
//! Every call returns a [`CgcError`] code; nothing unwinds across the boundary (a panic becomes
//! `CGC_ERROR_PANIC`). NULL pointers, wrong lengths, misaligned arrays and NaN are errors, never
//! crashes. Which calls are thread-safe is in `include/cgcontact.h`'s opening comment.
//!
//! ```
//! use cgcontact_capi::*;
//! use std::ptr;
//!
//! // A 2 × 1 × 1 block of unit cells, every node moved by +0.1 along x.
//! let (origin, h, counts) = ([0.0; 3], [1.0; 3], [2u32, 1, 1]);
//! let mut body = ptr::null_mut();
//! let mut locator = ptr::null_mut();
//! let u: Vec<f64> = (0..12).flat_map(|_| [0.1, 0.0, 0.0]).collect();
//! let (mut cells, mut xi) = ([0i64; 2], [0.0; 6]);
//! // SAFETY: every pointer points to the lengths stated; the handles are freed once.
//! unsafe {
//!     assert_eq!(cgc_body_from_lattice(origin.as_ptr(), h.as_ptr(), counts.as_ptr(), ptr::null(), 0, &mut body), CgcError::Ok);
//!     assert_eq!(cgc_body_set_displacements(body, u.as_ptr(), 12, CGC_LAYOUT_NODE_MAJOR), CgcError::Ok);
//!     assert_eq!(cgc_locator_new(body, ptr::null(), &mut locator), CgcError::Ok);
//!     let points = [1.6, 0.5, 0.5, 9.0, 9.0, 9.0];
//!     assert_eq!(cgc_locate(locator, points.as_ptr(), 2, cells.as_mut_ptr(), xi.as_mut_ptr(), ptr::null_mut()), CgcError::Ok);
//!     cgc_locator_free(locator);
//!     cgc_body_free(body);
//! }
//! assert_eq!(cells, [1, -1]);
//! assert!((xi[0] - 0.0).abs() < 1e-12 && xi[3].is_nan());
//! ```
#![deny(missing_docs)]
#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]

mod body;
mod error;
mod gap;
mod locate;
mod raw;

pub use body::{
    CGC_FILL_HANGING, CGC_LAYOUT_COMPONENT_MAJOR, CGC_LAYOUT_NODE_MAJOR, CgcBody, cgc_body_free,
    cgc_body_from_lattice, cgc_body_from_mesh, cgc_body_hanging_count, cgc_body_inverted_cells,
    cgc_body_node_count, cgc_body_set_displacements, cgc_body_unresolved_cells,
};
pub use error::{CgcError, cgc_last_error};
pub use gap::cgc_gap;
pub use locate::{
    CGC_POINT_INSIDE, CGC_POINT_NON_FINITE, CGC_POINT_OUTSIDE, CGC_PRECISION_F32,
    CGC_PRECISION_F64, CGC_STRATEGY_BRUTE, CGC_STRATEGY_LATTICE, CgcLocator, CgcSettings,
    cgc_locate, cgc_locate_unordered, cgc_locator_free, cgc_locator_new, cgc_locator_query_seconds,
    cgc_relocate, cgc_settings_init,
};

/// The version of the C ABI: it changes whenever a signature, a struct or a constant of
/// `cgcontact.h` changes incompatibly. Compare with `cgc_abi_version()` at run time. New
/// functions are compatible and leave it unchanged: `cgc_gap`, `cgc_relocate` and
/// `cgc_locate_unordered` were added within ABI 1, so a program that may load an older library of
/// ABI 1 looks them up with `dlsym`.
pub const CGC_ABI_VERSION: u32 = 1;

/// The ABI version of the library loaded: `CGC_ABI_VERSION` of its build.
#[unsafe(no_mangle)]
pub extern "C" fn cgc_abi_version() -> u32 {
    CGC_ABI_VERSION
}

/// The library's version, a NUL-terminated string owned by the library ("0.1.0").
#[unsafe(no_mangle)]
pub extern "C" fn cgc_version() -> *const std::ffi::c_char {
    const VERSION: &std::ffi::CStr = match std::ffi::CStr::from_bytes_with_nul(
        concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes(),
    ) {
        Ok(v) => v,
        Err(_) => panic!("the version holds no NUL"),
    };
    VERSION.as_ptr()
}
