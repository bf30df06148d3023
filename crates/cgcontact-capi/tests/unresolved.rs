//! `cgc_body_unresolved_cells`: cells far from the origin, sheared so that a rounding of y moves
//! ξ_z by more than a tenth of the cell, are named by construction, as `cgc_locate` names cells
//! (lattice and reordered mesh); a milder shear names none; a buffer too small is an error.

use std::ffi::CStr;
use std::ptr;

use cgcontact_capi::*;

fn last_error() -> String {
    // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
    unsafe { CStr::from_ptr(cgc_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// A body handle, freed on drop.
struct Handle(*mut CgcBody);

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: the handle comes from this library and is freed once, here.
        unsafe { cgc_body_free(self.0) }
    }
}

/// The list through the two-call pattern: the count, then the cells.
fn unresolved(body: &Handle) -> Vec<i64> {
    let mut count = usize::MAX;
    // SAFETY: a live handle; NULL cells with capacity 0; `count` is writable.
    let code = unsafe { cgc_body_unresolved_cells(body.0, ptr::null_mut(), 0, &mut count) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let mut cells = vec![-7i64; count];
    let mut again = usize::MAX;
    // SAFETY: `cells` holds `count` values.
    let code = unsafe { cgc_body_unresolved_cells(body.0, cells.as_mut_ptr(), count, &mut again) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    assert_eq!(again, count);
    cells
}

fn set(body: &Handle, u: &[[f64; 3]]) {
    let flat: Vec<f64> = u.iter().flatten().copied().collect();
    // SAFETY: `flat` holds 3 values per node.
    let code = unsafe {
        cgc_body_set_displacements(body.0, flat.as_ptr(), u.len(), CGC_LAYOUT_NODE_MAJOR)
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
}

/// Three cells along x at (−1e7)³, 1.6e-5 thin along z: node (i, j, k) is i + 4 (j + 2 k), cell
/// i is i. At 1e7 a coordinate is known to 4 ε |x| ≈ 8.9e-9, half a thousandth of the cell's
/// thickness: unsheared, every cell resolves.
const ORIGIN: [f64; 3] = [-1e7; 3];
const H: [f64; 3] = [0.03125, 0.001953125, 1.5625e-5];
const NODES: usize = 4 * 2 * 2;

fn node(i: usize, j: usize, k: usize) -> usize {
    i + 4 * (j + 2 * k)
}

/// u_z = s (y − y0) on the nodes with i ≤ 1, 0 on the others: cell 0 is sheared by dz/dy = s,
/// cell 1 by s/2 at its centre, cell 2 not at all. A rounding of y moves ξ_z by
/// 2 s · 8.9e-9 / 1.6e-5 ≈ 1.1e-3 s in cell 0 and half that in cell 1, z's own rounding adding
/// about 1.1e-3: with s = 1000 cells 0 and 1 exceed a tenth of the cell; with s = 10 none does.
fn sheared(s: f64) -> Vec<[f64; 3]> {
    let mut u = vec![[0.0; 3]; NODES];
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                u[node(i, j, k)] = [0.0, 0.0, s * j as f64 * H[1]];
            }
        }
    }
    u
}

#[test]
fn lattice_cells_sheared_beyond_the_coordinates_resolution_are_named() {
    let counts = [3u32, 1, 1];
    let mut body = ptr::null_mut();
    // SAFETY: 3 values each; no active mask.
    let code = unsafe {
        cgc_body_from_lattice(
            ORIGIN.as_ptr(),
            H.as_ptr(),
            counts.as_ptr(),
            ptr::null(),
            0,
            &mut body,
        )
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let body = Handle(body);
    assert_eq!(unresolved(&body), Vec::<i64>::new(), "undeformed");
    set(&body, &sheared(1e3));
    assert_eq!(unresolved(&body), [0, 1]);
    set(&body, &sheared(10.0));
    assert_eq!(unresolved(&body), Vec::<i64>::new(), "a milder shear");

    // The two-call pattern's errors, as for the inverted cells.
    set(&body, &sheared(1e3));
    let mut one = [-7i64];
    let mut count = 0;
    // SAFETY: `one` holds 1 value, `count` is writable.
    let code = unsafe { cgc_body_unresolved_cells(body.0, one.as_mut_ptr(), 1, &mut count) };
    assert_eq!(code, CgcError::LengthMismatch);
    assert_eq!(
        (count, one),
        (2, [-7]),
        "the number needed, no cell written"
    );
    assert!(
        last_error().contains("2 unresolved cells, room for 1"),
        "{}",
        last_error()
    );
    // SAFETY: NULL pointers are refused before anything is read or written.
    unsafe {
        assert_eq!(
            cgc_body_unresolved_cells(ptr::null(), ptr::null_mut(), 0, &mut count),
            CgcError::NullPointer
        );
        assert_eq!(
            cgc_body_unresolved_cells(body.0, ptr::null_mut(), 2, &mut count),
            CgcError::NullPointer
        );
    }
}

/// The same cells given as a mesh, nodes and cells listed in reverse (1-based): the list is in
/// the mesh's cell numbers, ascending, as `cgc_locate` answers.
#[test]
fn mesh_cells_are_named_by_their_place_in_the_mesh() {
    let nodes: Vec<f64> = (0..NODES)
        .rev()
        .flat_map(|n| {
            let ijk = [n % 4, (n / 4) % 2, n / 8];
            [0, 1, 2].map(|a| ORIGIN[a] + ijk[a] as f64 * H[a])
        })
        .collect();
    let renumber = |n: usize| (NODES - n) as i64; // 1-based, reversed
    let cells: Vec<i64> = (0..3)
        .rev()
        .flat_map(|i| {
            [
                node(i, 0, 0),
                node(i + 1, 0, 0),
                node(i + 1, 1, 0),
                node(i, 1, 0),
                node(i, 0, 1),
                node(i + 1, 0, 1),
                node(i + 1, 1, 1),
                node(i, 1, 1),
            ]
            .map(renumber)
        })
        .collect();
    let mut body = ptr::null_mut();
    // SAFETY: 3 NODES coordinates and 8 × 3 node numbers.
    let code =
        unsafe { cgc_body_from_mesh(nodes.as_ptr(), NODES, cells.as_ptr(), 3, 1, &mut body) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let body = Handle(body);
    let lattice_u = sheared(1e3);
    let u: Vec<[f64; 3]> = (0..NODES).rev().map(|n| lattice_u[n]).collect();
    set(&body, &u);
    // Lattice cells 0 and 1 are the mesh's cells 2 and 1.
    assert_eq!(unresolved(&body), [1, 2]);
}
