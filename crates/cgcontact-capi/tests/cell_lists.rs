//! The body's cell lists. `cgc_body_inverted_cells`: a node moved through its neighbour inverts
//! the cells known by construction, named as `cgc_locate` names cells (lattice, reordered mesh,
//! adaptive mesh); an undeformed or mildly deformed body has none; the two-call pattern and bad
//! arguments answer with their error codes. `cgc_body_unresolved_cells`: cells far from the
//! origin, sheared so that a rounding of y moves ξ_z by more than a tenth of the cell, are named
//! by construction (lattice and reordered mesh); a milder shear names none.

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

/// One of the body's cell lists (`cgc_body_inverted_cells` or `cgc_body_unresolved_cells`).
type CellList = unsafe extern "C" fn(*const CgcBody, *mut i64, usize, *mut usize) -> CgcError;

/// A list through the two-call pattern: the count, then the cells.
fn listed(body: &Handle, list: CellList) -> Vec<i64> {
    let mut count = usize::MAX;
    // SAFETY: a live handle; NULL cells with capacity 0; `count` is writable.
    let code = unsafe { list(body.0, ptr::null_mut(), 0, &mut count) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let mut cells = vec![-7i64; count];
    let mut again = usize::MAX;
    // SAFETY: `cells` holds `count` values.
    let code = unsafe { list(body.0, cells.as_mut_ptr(), count, &mut again) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    assert_eq!(again, count);
    cells
}

fn inverted(body: &Handle) -> Vec<i64> {
    listed(body, cgc_body_inverted_cells)
}

fn unresolved(body: &Handle) -> Vec<i64> {
    listed(body, cgc_body_unresolved_cells)
}

fn set(body: &Handle, u: &[[f64; 3]]) {
    let flat: Vec<f64> = u.iter().flatten().copied().collect();
    // SAFETY: `flat` holds 3 values per node.
    let code = unsafe {
        cgc_body_set_displacements(body.0, flat.as_ptr(), u.len(), CGC_LAYOUT_NODE_MAJOR)
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
}

/// A 4 × 3 × 2 lattice of unit cells at the origin: node (i, j, k) is i + 5 (j + 4 k), cell
/// (i, j, k) is i + 4 (j + 3 k).
const COUNTS: [u32; 3] = [4, 3, 2];
const NODES: usize = 5 * 4 * 3;

fn node(i: usize, j: usize, k: usize) -> usize {
    i + 5 * (j + 4 * k)
}

fn lattice_cell(i: usize, j: usize, k: usize) -> i64 {
    (i + 4 * (j + 3 * k)) as i64
}

/// Interior node (2, 1, 1) moved +1.5 h in x, through its neighbour (3, 1, 1): the four cells
/// with it at their −x corners (i = 2) turn inside out there; the four at i = 1 only stretch.
fn through_neighbour() -> Vec<[f64; 3]> {
    let mut u = vec![[0.0; 3]; NODES];
    u[node(2, 1, 1)] = [1.5, 0.0, 0.0];
    u
}

fn expected_lattice_cells() -> Vec<i64> {
    vec![
        lattice_cell(2, 0, 0),
        lattice_cell(2, 1, 0),
        lattice_cell(2, 0, 1),
        lattice_cell(2, 1, 1),
    ]
}

/// A mild deformation: every node moved by up to 0.2 h.
fn mild() -> Vec<[f64; 3]> {
    (0..NODES)
        .map(|n| {
            let t = n as f64;
            [
                0.2 * (0.7 * t).sin(),
                0.15 * (1.1 * t).cos(),
                -0.2 * (0.3 * t).sin(),
            ]
        })
        .collect()
}

fn lattice_body() -> Handle {
    let (origin, h) = ([0.0; 3], [1.0; 3]);
    let mut body = ptr::null_mut();
    // SAFETY: 3 values each; no active mask.
    let code = unsafe {
        cgc_body_from_lattice(
            origin.as_ptr(),
            h.as_ptr(),
            COUNTS.as_ptr(),
            ptr::null(),
            0,
            &mut body,
        )
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    Handle(body)
}

#[test]
fn a_node_moved_through_its_neighbour_inverts_the_cells_beyond_it() {
    let body = lattice_body();
    assert_eq!(inverted(&body), Vec::<i64>::new(), "undeformed");
    set(&body, &mild());
    assert_eq!(inverted(&body), Vec::<i64>::new(), "mildly deformed");
    set(&body, &through_neighbour());
    assert_eq!(inverted(&body), expected_lattice_cells());
    // Back to undeformed: the list follows the displacements.
    set(&body, &vec![[0.0; 3]; NODES]);
    assert_eq!(inverted(&body), Vec::<i64>::new());
}

/// The same lattice given as a mesh: nodes numbered in reverse, cells listed in reverse, 1-based.
/// The list is in the mesh's cell numbers, ascending, as `cgc_locate` answers.
#[test]
fn mesh_cells_are_named_by_their_place_in_the_mesh() {
    let nodes: Vec<f64> = (0..NODES)
        .rev()
        .flat_map(|n| [(n % 5) as f64, ((n / 5) % 4) as f64, (n / 20) as f64])
        .collect();
    let renumber = |n: usize| (NODES - n) as i64; // 1-based, reversed
    let mut cells = Vec::new();
    for k in (0..2).rev() {
        for j in (0..3).rev() {
            for i in (0..4).rev() {
                let corners = [
                    node(i, j, k),
                    node(i + 1, j, k),
                    node(i + 1, j + 1, k),
                    node(i, j + 1, k),
                    node(i, j, k + 1),
                    node(i + 1, j, k + 1),
                    node(i + 1, j + 1, k + 1),
                    node(i, j + 1, k + 1),
                ];
                cells.extend(corners.map(renumber));
            }
        }
    }
    let n_cells = cells.len() / 8;
    let mut body = ptr::null_mut();
    // SAFETY: 3 NODES coordinates and 8 n_cells node numbers.
    let code =
        unsafe { cgc_body_from_mesh(nodes.as_ptr(), NODES, cells.as_ptr(), n_cells, 1, &mut body) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let body = Handle(body);
    assert_eq!(inverted(&body), Vec::<i64>::new());
    let u: Vec<[f64; 3]> = (0..NODES).rev().map(|n| through_neighbour()[n]).collect();
    set(&body, &u);
    let mut expected: Vec<i64> = expected_lattice_cells()
        .iter()
        .map(|c| n_cells as i64 - 1 - c)
        .collect();
    expected.sort_unstable();
    assert_eq!(expected, [5, 9, 17, 21]);
    assert_eq!(inverted(&body), expected);
}

/// An adaptive mesh: base cells (0, 0, 0) and (1, 0, 0) of a unit lattice, the first halved into
/// 8 leaves (5 hanging nodes on the shared face). Its corner node at the origin, in leaf 0 only,
/// moved +0.75 in x through its neighbour at 0.5: leaf 0 alone is inverted.
#[test]
fn an_adaptive_leaf_is_named_by_its_place_in_the_mesh() {
    let mut positions: Vec<[i64; 3]> = Vec::new(); // in half steps
    fn index(p: [i64; 3], positions: &mut Vec<[i64; 3]>) -> i64 {
        let n = positions.iter().position(|q| *q == p).unwrap_or_else(|| {
            positions.push(p);
            positions.len() - 1
        });
        n as i64
    }
    let offsets = cgcontact::CORNER_OFFSETS.map(|o| o.map(i64::from));
    let mut cells = Vec::new();
    // Leaves in the order x, y, z fastest; then the coarse cell.
    let mut boxes: Vec<([i64; 3], i64)> = Vec::new();
    for c in 0..8 {
        boxes.push(([c & 1, (c >> 1) & 1, (c >> 2) & 1], 1));
    }
    boxes.push(([2, 0, 0], 2));
    for (low, size) in &boxes {
        for o in offsets {
            let p = [
                low[0] + o[0] * size,
                low[1] + o[1] * size,
                low[2] + o[2] * size,
            ];
            cells.push(index(p, &mut positions));
        }
    }
    let nodes: Vec<f64> = positions
        .iter()
        .flat_map(|p| p.map(|v| v as f64 * 0.5))
        .collect();
    let m = positions.len();
    let mut body = ptr::null_mut();
    // SAFETY: 3 m coordinates and 8 per cell.
    let code = unsafe { cgc_body_from_mesh(nodes.as_ptr(), m, cells.as_ptr(), 9, 0, &mut body) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let body = Handle(body);
    let mut hanging = 0;
    // SAFETY: a live handle, a writable count.
    assert_eq!(
        unsafe { cgc_body_hanging_count(body.0, &mut hanging) },
        CgcError::Ok
    );
    assert_eq!(hanging, 5);
    assert_eq!(inverted(&body), Vec::<i64>::new());
    let mut u = vec![[0.0; 3]; m];
    u[cells[0] as usize] = [0.75, 0.0, 0.0];
    set(&body, &u);
    assert_eq!(inverted(&body), [0]);
}

#[test]
fn too_small_a_buffer_and_null_pointers_are_errors_that_write_no_cell() {
    let body = lattice_body();
    set(&body, &through_neighbour());
    let mut cells = [-7i64; 3];
    let mut count = 0;
    // SAFETY: `cells` holds 3 values, `count` is writable.
    let code = unsafe { cgc_body_inverted_cells(body.0, cells.as_mut_ptr(), 3, &mut count) };
    assert_eq!(code, CgcError::LengthMismatch);
    assert_eq!(count, 4, "the number needed");
    assert_eq!(cells, [-7; 3], "no cell written");
    assert!(
        last_error().contains("4 inverted cells, room for 3"),
        "{}",
        last_error()
    );
    // A buffer larger than needed: the first `count` values written, the rest untouched.
    let mut large = [-7i64; 6];
    // SAFETY: `large` holds 6 values.
    let code = unsafe { cgc_body_inverted_cells(body.0, large.as_mut_ptr(), 6, &mut count) };
    assert_eq!(code, CgcError::Ok);
    assert_eq!(count, 4);
    assert_eq!(&large[..4], expected_lattice_cells().as_slice());
    assert_eq!(&large[4..], [-7, -7]);
    // SAFETY: NULL pointers are refused before anything is read or written.
    unsafe {
        assert_eq!(
            cgc_body_inverted_cells(ptr::null(), ptr::null_mut(), 0, &mut count),
            CgcError::NullPointer
        );
        assert!(last_error().contains("body is NULL"), "{}", last_error());
        assert_eq!(
            cgc_body_inverted_cells(body.0, ptr::null_mut(), 0, ptr::null_mut()),
            CgcError::NullPointer
        );
        assert!(last_error().contains("count is NULL"), "{}", last_error());
        assert_eq!(
            cgc_body_inverted_cells(body.0, ptr::null_mut(), 4, &mut count),
            CgcError::NullPointer
        );
        assert!(last_error().contains("cells is NULL"), "{}", last_error());
    }
}

/// Three cells along x at (−1e7)³, 1.6e-5 thin along z: node (i, j, k) is i + 4 (j + 2 k), cell
/// i is i. At 1e7 a coordinate is known to 4 ε |x| ≈ 8.9e-9, half a thousandth of the cell's
/// thickness: unsheared, every cell resolves.
const FAR_ORIGIN: [f64; 3] = [-1e7; 3];
const FAR_H: [f64; 3] = [0.03125, 0.001953125, 1.5625e-5];
const FAR_NODES: usize = 4 * 2 * 2;

fn far_node(i: usize, j: usize, k: usize) -> usize {
    i + 4 * (j + 2 * k)
}

/// u_z = s (y − y0) on the nodes with i ≤ 1, 0 on the others: cell 0 is sheared by dz/dy = s,
/// cell 1 by s/2 at its centre, cell 2 not at all. A rounding of y moves ξ_z by
/// 2 s · 8.9e-9 / 1.6e-5 ≈ 1.1e-3 s in cell 0 and half that in cell 1, z's own rounding adding
/// about 1.1e-3: with s = 1000 cells 0 and 1 exceed a tenth of the cell; with s = 10 none does.
fn sheared(s: f64) -> Vec<[f64; 3]> {
    let mut u = vec![[0.0; 3]; FAR_NODES];
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                u[far_node(i, j, k)] = [0.0, 0.0, s * j as f64 * FAR_H[1]];
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
            FAR_ORIGIN.as_ptr(),
            FAR_H.as_ptr(),
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
fn unresolved_mesh_cells_are_named_by_their_place_in_the_mesh() {
    let nodes: Vec<f64> = (0..FAR_NODES)
        .rev()
        .flat_map(|n| {
            let ijk = [n % 4, (n / 4) % 2, n / 8];
            [0, 1, 2].map(|a| FAR_ORIGIN[a] + ijk[a] as f64 * FAR_H[a])
        })
        .collect();
    let renumber = |n: usize| (FAR_NODES - n) as i64; // 1-based, reversed
    let cells: Vec<i64> = (0..3)
        .rev()
        .flat_map(|i| {
            [
                far_node(i, 0, 0),
                far_node(i + 1, 0, 0),
                far_node(i + 1, 1, 0),
                far_node(i, 1, 0),
                far_node(i, 0, 1),
                far_node(i + 1, 0, 1),
                far_node(i + 1, 1, 1),
                far_node(i, 1, 1),
            ]
            .map(renumber)
        })
        .collect();
    let mut body = ptr::null_mut();
    // SAFETY: 3 FAR_NODES coordinates and 8 × 3 node numbers.
    let code =
        unsafe { cgc_body_from_mesh(nodes.as_ptr(), FAR_NODES, cells.as_ptr(), 3, 1, &mut body) };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let body = Handle(body);
    let lattice_u = sheared(1e3);
    let u: Vec<[f64; 3]> = (0..FAR_NODES).rev().map(|n| lattice_u[n]).collect();
    set(&body, &u);
    // Lattice cells 0 and 1 are the mesh's cells 2 and 1.
    assert_eq!(unresolved(&body), [1, 2]);
}
