//! The C ABI called as C would call it: answers checked against points made from known (cell, ξ)
//! and against the Rust library itself; every bad input answered with its error code.

use std::ffi::CStr;
use std::ptr;

use cgcontact::glam::DVec3;
use cgcontact::{Answer, Body, CellId, Lattice, LatticeLocator, Locator, Settings};
use cgcontact_capi::*;
use cgcontact_io::HexMesh;

fn last_error() -> String {
    // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
    unsafe { CStr::from_ptr(cgc_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// Bit patterns, so that NaN compares equal to NaN.
fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// `cgc_settings_init`'s defaults for `precision`.
fn settings(precision: u32) -> CgcSettings {
    // SAFETY: zeroed is a valid CgcSettings (numbers only); init writes every field.
    unsafe {
        let mut settings = std::mem::zeroed::<CgcSettings>();
        assert_eq!(cgc_settings_init(precision, &mut settings), CgcError::Ok);
        settings
    }
}

/// `cgc_locator_new(body, settings, ..)` fails with `code`, a message holding each of `names`,
/// and no handle written.
///
/// # Safety
/// `body` a live handle; `settings` readable (or misaligned: what is tested) or NULL.
unsafe fn locator_refused(
    body: *const CgcBody,
    settings: *const CgcSettings,
    code: CgcError,
    names: &[&str],
) {
    let mut locator = ptr::null_mut();
    // SAFETY: forwarded from the caller.
    assert_eq!(
        unsafe { cgc_locator_new(body, settings, &mut locator) },
        code
    );
    let message = last_error();
    for name in names {
        assert!(message.contains(name), "{name} not in: {message}");
    }
    assert!(locator.is_null());
}

/// A 6 × 5 × 4 block with a smooth displacement of up to about 0.4 h.
fn block() -> Body {
    let lattice = Lattice::new(
        DVec3::new(1.0, -2.0, 0.5),
        DVec3::new(0.5, 0.25, 0.4),
        [6, 5, 4],
    )
    .unwrap();
    let mut body = Body::full(lattice);
    body.update_displacements(|_, x, u| {
        *u = DVec3::new(
            0.05 * (x.y * 3.0).sin(),
            0.03 * x.x * x.z,
            -0.1 * (x.x - 1.0) * (x.z - 0.5),
        )
    })
    .unwrap();
    body
}

/// Points from known (cell, ξ): the deformed point at ξ of each listed cell, plus a point far away.
fn known_points(body: &Body) -> (Vec<DVec3>, Vec<(u32, DVec3)>) {
    let mut known = Vec::new();
    for (k, cell) in body.active_cells().enumerate().step_by(7) {
        let t = k as f64 * 0.37;
        let xi = DVec3::new(t.sin() * 0.9, (1.3 * t).cos() * 0.8, (0.7 * t).sin() * 0.95);
        known.push((cell.0, xi));
    }
    let mut points: Vec<DVec3> = known
        .iter()
        .map(|&(c, xi)| body.point_at(CellId(c), xi).unwrap())
        .collect();
    points.push(DVec3::splat(100.0));
    (points, known)
}

fn flat(v: &[DVec3]) -> Vec<f64> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

struct Handles {
    body: *mut CgcBody,
    locator: *mut CgcLocator,
}

impl Drop for Handles {
    fn drop(&mut self) {
        // SAFETY: both handles come from this library and are freed once, here.
        unsafe {
            cgc_locator_free(self.locator);
            cgc_body_free(self.body);
        }
    }
}

fn locate(locator: *const CgcLocator, points: &[f64]) -> (CgcError, Vec<i64>, Vec<f64>, Vec<u8>) {
    let n = points.len() / 3;
    let (mut cells, mut xi, mut status) = (vec![7i64; n], vec![7.0; 3 * n], vec![9u8; n]);
    // SAFETY: the arrays hold n, 3 n and n values and do not overlap.
    let code = unsafe {
        cgc_locate(
            locator,
            points.as_ptr(),
            n,
            cells.as_mut_ptr(),
            xi.as_mut_ptr(),
            status.as_mut_ptr(),
        )
    };
    (code, cells, xi, status)
}

/// A lattice body with the given active flags (one per cell), without a locator yet.
fn masked_body(lattice: &Lattice, active: &[u8]) -> Handles {
    let (origin, h, counts) = (
        lattice.origin().to_array(),
        lattice.h().to_array(),
        lattice.cells(),
    );
    let mut handles = Handles {
        body: ptr::null_mut(),
        locator: ptr::null_mut(),
    };
    // SAFETY: every array holds the length passed; the handles are freed by `Handles`.
    unsafe {
        assert_eq!(
            cgc_body_from_lattice(
                origin.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                active.as_ptr(),
                active.len(),
                &mut handles.body,
            ),
            CgcError::Ok
        );
    }
    handles
}

/// A fixed linear congruential sequence in [0, 1) from `seed`.
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// What `cgc_locate` writes for the library's `answers` on a lattice body: cells, ξ, status.
fn written(answers: &[Answer]) -> (Vec<i64>, Vec<f64>, Vec<u8>) {
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for answer in answers {
        let (cell, xi, code) = match answer {
            Ok(Some(hit)) => (i64::from(hit.cell.0), hit.xi, CGC_POINT_INSIDE),
            Ok(None) => (-1, DVec3::NAN, CGC_POINT_OUTSIDE),
            Err(_) => (-1, DVec3::NAN, CGC_POINT_NON_FINITE),
        };
        out.0.push(cell);
        out.1.extend(xi.to_array());
        out.2.push(code);
    }
    out
}

/// Each point's ξ in `got` within the Newton tolerance of `expected`'s, or both NaN.
fn assert_xi_close(got: &[f64], expected: &[f64], what: &str) {
    for (i, (got, known)) in got.chunks(3).zip(expected.chunks(3)).enumerate() {
        let (got, known) = (DVec3::from_slice(got), DVec3::from_slice(known));
        assert!(
            (got - known).abs().max_element() < 1e-12 || (got.is_nan() && known.is_nan()),
            "{what}: point {i}: {got} against {known}"
        );
    }
}

fn lattice_handles(body: &Body) -> Handles {
    let lattice = body.lattice();
    let (origin, h, counts) = (
        lattice.origin().to_array(),
        lattice.h().to_array(),
        lattice.cells(),
    );
    let mut handles = Handles {
        body: ptr::null_mut(),
        locator: ptr::null_mut(),
    };
    let dense: Vec<f64> = (0..lattice.node_count())
        .flat_map(|n| body.displacement(n).unwrap_or(DVec3::ZERO).to_array())
        .collect();
    // SAFETY: every array holds the length passed.
    unsafe {
        assert_eq!(
            cgc_body_from_lattice(
                origin.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                ptr::null(),
                0,
                &mut handles.body
            ),
            CgcError::Ok
        );
        let mut n = 0;
        assert_eq!(cgc_body_node_count(handles.body, &mut n), CgcError::Ok);
        assert_eq!(n, lattice.node_count());
        assert_eq!(
            cgc_body_set_displacements(handles.body, dense.as_ptr(), n, CGC_LAYOUT_NODE_MAJOR),
            CgcError::Ok
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
    }
    handles
}

#[test]
fn lattice_body_answers_known_cells_and_as_the_library_does() {
    let body = block();
    let (points, known) = known_points(&body);
    let handles = lattice_handles(&body);
    let (code, cells, xi, status) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let library = LatticeLocator::new(&body, Settings::default())
        .unwrap()
        .locate_all(&points);
    for (i, &(cell, expected)) in known.iter().enumerate() {
        assert_eq!(cells[i], i64::from(cell), "point {i}");
        assert_eq!(status[i], CGC_POINT_INSIDE);
        let got = DVec3::from_slice(&xi[3 * i..]);
        assert!(
            (got - expected).abs().max_element() < 1e-12,
            "point {i}: {got} vs {expected}"
        );
        assert_eq!(
            got,
            library[i].unwrap().unwrap().xi,
            "bitwise the library's answer"
        );
    }
    let last = known.len();
    assert_eq!((cells[last], status[last]), (-1, CGC_POINT_OUTSIDE));
    assert!(xi[3 * last..].iter().all(|v| v.is_nan()));
}

/// `body` given as a mesh: nodes renumbered, cells listed in reverse (mesh cell e − 1 − c is
/// lattice cell c), 1-based, displacements component-major (as MATLAB passes them). Returns the
/// handles, the cell count e, the node count m and the displacements as passed.
fn reversed_mesh_handles(body: &Body) -> (Handles, usize, usize, Vec<f64>) {
    let mesh = HexMesh::from_body(body);
    let m = mesh.points.len();
    let e = mesh.cells.len();
    // Node k of the mesh becomes node new_of[k]; cells are listed in reverse.
    let new_of: Vec<usize> = (0..m).map(|k| (k * 7919) % m).collect();
    assert_eq!(
        {
            let mut s = new_of.clone();
            s.sort();
            s.dedup();
            s.len()
        },
        m,
        "a permutation"
    );
    let mut nodes = vec![0.0; 3 * m];
    let mut u_component_major = vec![0.0; 3 * m];
    let u = mesh.displacement.as_ref().unwrap();
    for k in 0..m {
        nodes[3 * new_of[k]..3 * new_of[k] + 3].copy_from_slice(&mesh.points[k].to_array());
        for a in 0..3 {
            u_component_major[a * m + new_of[k]] = u[k][a];
        }
    }
    let topology: Vec<i64> = mesh
        .cells
        .iter()
        .rev()
        .flat_map(|c| c.map(|n| new_of[n as usize] as i64 + 1))
        .collect();
    let mut handles = Handles {
        body: ptr::null_mut(),
        locator: ptr::null_mut(),
    };
    // SAFETY: every array holds the length passed.
    unsafe {
        assert_eq!(
            cgc_body_from_mesh(
                nodes.as_ptr(),
                m,
                topology.as_ptr(),
                e,
                1,
                &mut handles.body
            ),
            CgcError::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_body_set_displacements(
                handles.body,
                u_component_major.as_ptr(),
                m,
                CGC_LAYOUT_COMPONENT_MAJOR
            ),
            CgcError::Ok
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
    }
    (handles, e, m, u_component_major)
}

/// The same body given as a mesh ([`reversed_mesh_handles`]): cell numbers are the mesh's.
#[test]
fn mesh_body_numbers_cells_as_the_mesh_and_reads_both_layouts() {
    let body = block();
    let (points, known) = known_points(&body);
    let (handles, e, m, u_component_major) = reversed_mesh_handles(&body);
    let (code, cells, xi, _) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    for (i, &(cell, expected)) in known.iter().enumerate() {
        // from_body lists cells ascending, and the topology reversed them.
        assert_eq!(cells[i], (e - 1 - cell as usize) as i64, "point {i}");
        assert!(
            (DVec3::from_slice(&xi[3 * i..]) - expected)
                .abs()
                .max_element()
                < 1e-12
        );
    }
    assert_eq!(*cells.last().unwrap(), -1);

    // Node-major, the same field: the same answers, bitwise. Then undeformed: other answers.
    let node_major: Vec<f64> = (0..m)
        .flat_map(|n| [0, 1, 2].map(|a| u_component_major[a * m + n]))
        .collect();
    // SAFETY: 3 m values.
    assert_eq!(
        unsafe {
            cgc_body_set_displacements(handles.body, node_major.as_ptr(), m, CGC_LAYOUT_NODE_MAJOR)
        },
        CgcError::Ok
    );
    assert_eq!(bits(&locate(handles.locator, &flat(&points)).2), bits(&xi));
    let zero = vec![0.0; 3 * m];
    // SAFETY: 3 m values.
    assert_eq!(
        unsafe {
            cgc_body_set_displacements(handles.body, zero.as_ptr(), m, CGC_LAYOUT_NODE_MAJOR)
        },
        CgcError::Ok
    );
    assert_ne!(
        bits(&locate(handles.locator, &flat(&points)).2),
        bits(&xi),
        "the locator sees the update"
    );
}

/// A node that no cell uses still needs a finite displacement, as in Python and in mesh files:
/// a NaN there is refused, naming it, in both layouts, and nothing changes.
#[test]
fn a_nan_at_a_node_no_cell_uses_is_refused() {
    let body = block();
    let (points, _) = known_points(&body);
    let mesh = HexMesh::from_body(&body);
    let m = mesh.points.len();
    // The mesh's nodes, then one more that no cell lists, far from the body.
    let mut nodes: Vec<f64> = mesh.points.iter().flat_map(|p| p.to_array()).collect();
    nodes.extend([1e3, -1e3, 7.0]);
    let topology: Vec<i64> = mesh.cells.iter().flat_map(|c| c.map(i64::from)).collect();
    let u = mesh.displacement.as_ref().unwrap();
    let mut node_major: Vec<f64> = u.iter().flat_map(|v| v.to_array()).collect();
    node_major.extend([0.5, 0.0, 0.0]);
    let mut handles = Handles {
        body: ptr::null_mut(),
        locator: ptr::null_mut(),
    };
    // SAFETY: every array holds the length passed (m + 1 nodes, 8 corners per cell).
    unsafe {
        let code = cgc_body_from_mesh(
            nodes.as_ptr(),
            m + 1,
            topology.as_ptr(),
            mesh.cells.len(),
            0,
            &mut handles.body,
        );
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        let set =
            |u: &[f64], layout| cgc_body_set_displacements(handles.body, u.as_ptr(), m + 1, layout);
        assert_eq!(
            set(&node_major, CGC_LAYOUT_NODE_MAJOR),
            CgcError::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
        let before = locate(handles.locator, &flat(&points));
        assert_eq!(before.0, CgcError::Ok);

        let mut bad = node_major.clone();
        bad[3 * m + 1] = f64::NAN;
        assert_eq!(set(&bad, CGC_LAYOUT_NODE_MAJOR), CgcError::NonFinite);
        assert!(
            last_error().contains(&format!("node {m} ")),
            "{}",
            last_error()
        );
        let mut component_major: Vec<f64> = (0..3)
            .flat_map(|a| (0..=m).map(move |n| (n, a)))
            .map(|(n, a)| node_major[3 * n + a])
            .collect();
        component_major[2 * (m + 1) + m] = f64::INFINITY;
        assert_eq!(
            set(&component_major, CGC_LAYOUT_COMPONENT_MAJOR),
            CgcError::NonFinite
        );
        assert!(
            last_error().contains(&format!("node {m} ")),
            "{}",
            last_error()
        );
        // With the fill flag too: the node is not a hanging node, its value is checked.
        assert_eq!(
            set(&bad, CGC_LAYOUT_NODE_MAJOR | CGC_FILL_HANGING),
            CgcError::NonFinite
        );

        // Nothing changed: the same answers, bitwise.
        let after = locate(handles.locator, &flat(&points));
        assert_eq!((bits(&after.2), &after.1), (bits(&before.2), &before.1));
    }
}

#[test]
fn bad_inputs_are_error_codes_with_messages() {
    let body = block();
    let handles = lattice_handles(&body);
    let n = body.lattice().node_count();
    let mut u = vec![0.0; 3 * n];
    // SAFETY: NULLs and short lengths are what is tested; every non-NULL array holds its length.
    unsafe {
        assert_eq!(
            cgc_body_set_displacements(handles.body, ptr::null(), n, 0),
            CgcError::NullPointer
        );
        assert_eq!(
            cgc_body_set_displacements(ptr::null_mut(), u.as_ptr(), n, 0),
            CgcError::NullPointer
        );
        assert_eq!(
            cgc_body_set_displacements(handles.body, u.as_ptr(), n - 1, 0),
            CgcError::LengthMismatch
        );
        assert_eq!(
            cgc_body_set_displacements(handles.body, u.as_ptr(), n, 5),
            CgcError::InvalidArgument
        );
        u[3 * 17 + 1] = f64::NAN;
        assert_eq!(
            cgc_body_set_displacements(handles.body, u.as_ptr(), n, 0),
            CgcError::NonFinite
        );
        assert!(last_error().contains("node 17"), "{}", last_error());
        // Misaligned points.
        let bytes = [0.0f64; 8];
        let odd = bytes.as_ptr().cast::<u8>().add(1).cast::<f64>();
        let (mut c, mut x) = ([0i64; 1], [0.0; 3]);
        assert_eq!(
            cgc_locate(
                handles.locator,
                odd,
                1,
                c.as_mut_ptr(),
                x.as_mut_ptr(),
                ptr::null_mut()
            ),
            CgcError::InvalidArgument
        );
        assert_eq!(
            cgc_locate(
                handles.locator,
                ptr::null(),
                1,
                c.as_mut_ptr(),
                x.as_mut_ptr(),
                ptr::null_mut()
            ),
            CgcError::NullPointer
        );
        assert_eq!(
            cgc_locate(
                ptr::null(),
                bytes.as_ptr(),
                1,
                c.as_mut_ptr(),
                x.as_mut_ptr(),
                ptr::null_mut()
            ),
            CgcError::NullPointer
        );
        assert_eq!(
            cgc_locate(
                handles.locator,
                ptr::null(),
                0,
                ptr::null_mut(),
                ptr::null_mut(),
                ptr::null_mut()
            ),
            CgcError::Ok,
            "no points"
        );
        // Settings out of range.
        let mut settings = std::mem::zeroed::<CgcSettings>();
        assert_eq!(
            cgc_settings_init(3, &mut settings),
            CgcError::InvalidArgument
        );
        assert_eq!(
            cgc_settings_init(CGC_PRECISION_F32, &mut settings),
            CgcError::Ok
        );
        settings.newton_tol = f64::NAN;
        let mut other = ptr::null_mut();
        assert_eq!(
            cgc_locator_new(handles.body, &settings, &mut other),
            CgcError::InvalidArgument
        );
        assert!(other.is_null());
        // Lattices.
        let (o, h, bad_h, counts) = ([0.0; 3], [1.0; 3], [1.0, f64::NAN, 1.0], [2u32, 2, 2]);
        let mut b = ptr::null_mut();
        assert_eq!(
            cgc_body_from_lattice(
                o.as_ptr(),
                bad_h.as_ptr(),
                counts.as_ptr(),
                ptr::null(),
                0,
                &mut b
            ),
            CgcError::NonFinite
        );
        let none = [0u8; 8];
        assert_eq!(
            cgc_body_from_lattice(
                o.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                none.as_ptr(),
                8,
                &mut b
            ),
            CgcError::InvalidArgument
        );
        assert_eq!(
            cgc_body_from_lattice(
                o.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                none.as_ptr(),
                7,
                &mut b
            ),
            CgcError::LengthMismatch
        );
        assert_eq!(
            cgc_body_from_lattice(
                o.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                ptr::null(),
                0,
                ptr::null_mut()
            ),
            CgcError::NullPointer
        );
        assert!(b.is_null());
    }
    // The body kept its displacements through the failed updates: the same answers as before.
    let (points, _) = known_points(&body);
    let before = locate(handles.locator, &flat(&points));
    assert_eq!(before.0, CgcError::Ok);
    assert_eq!(before.1[0], i64::from(known_points(&body).1[0].0));
}

#[test]
fn non_finite_points_are_answered_and_reported() {
    let body = block();
    let handles = lattice_handles(&body);
    let (mut points, known) = known_points(&body);
    points[1].y = f64::NAN;
    points[2].z = f64::INFINITY;
    let (code, cells, _, status) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::NonFinitePoint);
    assert!(last_error().starts_with("point 1 "), "{}", last_error());
    assert_eq!(
        &status[..3],
        &[CGC_POINT_INSIDE, CGC_POINT_NON_FINITE, CGC_POINT_NON_FINITE]
    );
    assert_eq!(&cells[..3], &[i64::from(known[0].0), -1, -1]);
}

/// Values far from 1 in a message are written with an exponent: `{}` wrote a point at 1e300 with
/// its 301 digits, and a distance of 1e200 with 201, burying what the message says.
#[test]
fn values_far_from_one_are_written_short_in_messages() {
    let short = |what: &str, expected: &str| {
        let message = last_error();
        assert!(
            message.contains(expected) && message.len() < 300,
            "{what}: expected {expected} in a short message, got {} bytes: {message}",
            message.len()
        );
    };
    let body = block();
    let handles = lattice_handles(&body);
    let (code, ..) = locate(handles.locator, &[1e300, f64::NAN, 1e-300]);
    assert_eq!(code, CgcError::NonFinitePoint);
    short("a point", "[1e300, NaN, 1e-300]");
    let (mut gap, point) = (0.0, [0.0; 3]);
    // SAFETY: one point and one gap; the other outputs are skipped.
    let code = unsafe {
        cgc_gap(
            handles.locator,
            point.as_ptr(),
            1,
            1e200,
            &mut gap,
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(code, CgcError::InvalidArgument);
    short("a gap distance", "distance is 1e200;");
    let mut n = 0;
    // SAFETY: the handle is live; one writable count.
    assert_eq!(
        unsafe { cgc_body_node_count(handles.body, &mut n) },
        CgcError::Ok
    );
    let mut u = vec![0.0; 3 * n];
    u[3..6].copy_from_slice(&[-1e300, f64::INFINITY, 0.0]);
    // SAFETY: `u` holds 3 n values.
    let code =
        unsafe { cgc_body_set_displacements(handles.body, u.as_ptr(), n, CGC_LAYOUT_NODE_MAJOR) };
    assert_eq!(code, CgcError::NonFinite);
    short("a displacement", "[-1e300, inf, 0]");
    let (origin, h, counts) = ([1e300, f64::NAN, 0.0], [1.0; 3], [1u32; 3]);
    let mut b = ptr::null_mut();
    // SAFETY: three values each; `b` is writable.
    let code = unsafe {
        cgc_body_from_lattice(
            origin.as_ptr(),
            h.as_ptr(),
            counts.as_ptr(),
            ptr::null(),
            0,
            &mut b,
        )
    };
    assert_eq!(code, CgcError::NonFinite);
    short("an origin", "[1e300, NaN, 0]");
    let nodes: Vec<f64> = (0..8)
        .flat_map(|c| [c & 1, (c >> 1) & 1, c >> 2].map(f64::from))
        .chain([2e300, f64::NAN, 0.5])
        .collect();
    let topology = [0i64, 1, 3, 2, 4, 5, 7, 6];
    // SAFETY: the arrays hold 3 × 9 and 8 values.
    let code = unsafe { cgc_body_from_mesh(nodes.as_ptr(), 9, topology.as_ptr(), 1, 0, &mut b) };
    assert_eq!(code, CgcError::NonFinite);
    short("a node", "[2e300, NaN, 0.5]");
    assert!(b.is_null());
}

#[test]
fn meshes_that_are_not_lattices_are_refused() {
    let mesh = HexMesh::from_body(&block());
    let nodes = flat(&mesh.points);
    let topology: Vec<i64> = mesh.cells.iter().flat_map(|c| c.map(i64::from)).collect();
    let (m, e) = (mesh.points.len(), mesh.cells.len());
    let mut b = ptr::null_mut();
    // SAFETY: every array holds the length passed.
    unsafe {
        let mut moved = nodes.clone();
        moved[3 * 5] += 0.1;
        assert_eq!(
            cgc_body_from_mesh(moved.as_ptr(), m, topology.as_ptr(), e, 0, &mut b),
            CgcError::NotLattice
        );
        assert!(last_error().contains("node 5"), "{}", last_error());
        let mut swapped = topology.clone();
        swapped.swap(0, 1);
        assert_eq!(
            cgc_body_from_mesh(nodes.as_ptr(), m, swapped.as_ptr(), e, 0, &mut b),
            CgcError::NotLattice
        );
        let mut beyond = topology.clone();
        beyond[9] = m as i64;
        assert_eq!(
            cgc_body_from_mesh(nodes.as_ptr(), m, beyond.as_ptr(), e, 0, &mut b),
            CgcError::InvalidArgument
        );
        assert!(
            last_error().contains("cell 1 corner 1 (VTK"),
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_body_from_mesh(nodes.as_ptr(), m, topology.as_ptr(), e, 2, &mut b),
            CgcError::InvalidArgument
        );
        let mut nan = nodes.clone();
        nan[7] = f64::NAN;
        assert_eq!(
            cgc_body_from_mesh(nan.as_ptr(), m, topology.as_ptr(), e, 0, &mut b),
            CgcError::NonFinite
        );
        assert!(b.is_null());
    }
}

/// A node that no cell uses is still a node of the input: a NaN or infinite coordinate there is
/// refused, as the CLI's reader, Python and the MEX file refuse it (the library checks only the
/// nodes its cells use).
#[test]
fn a_non_finite_node_that_no_cell_uses_is_refused() {
    let cube = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    for (extra, shown) in [
        ([f64::NAN; 3], "[NaN, NaN, NaN]"),
        ([f64::INFINITY, 0.0, 0.0], "[inf, 0, 0]"),
        ([0.0, f64::NEG_INFINITY, 0.0], "[0, -inf, 0]"),
    ] {
        let nodes: Vec<f64> = cube.iter().chain([&extra]).flatten().copied().collect();
        for base in [0i64, 1] {
            let topology: Vec<i64> = (base..base + 8).collect();
            let mut b = ptr::null_mut();
            // SAFETY: the arrays hold 3 × 9 and 8 values.
            let code = unsafe {
                cgc_body_from_mesh(nodes.as_ptr(), 9, topology.as_ptr(), 1, base, &mut b)
            };
            assert_eq!(code, CgcError::NonFinite, "{shown}: {}", last_error());
            assert!(b.is_null());
            let message = last_error();
            assert!(
                message.contains("node 8 (0-based)") && message.contains(shown),
                "{message}"
            );
        }
    }
    // The same cube without the node is a body.
    let nodes: Vec<f64> = cube.iter().flatten().copied().collect();
    let topology: Vec<i64> = (0..8).collect();
    let mut b = ptr::null_mut();
    // SAFETY: the arrays hold 3 × 8 and 8 values; the handle is freed once.
    unsafe {
        assert_eq!(
            cgc_body_from_mesh(nodes.as_ptr(), 8, topology.as_ptr(), 1, 0, &mut b),
            CgcError::Ok
        );
        cgc_body_free(b);
    }
}

#[test]
fn a_locator_outlives_its_body_handle() {
    let body = block();
    let (points, known) = known_points(&body);
    let mut handles = lattice_handles(&body);
    // SAFETY: the body handle is freed once and nulled; the locator still shares the body.
    unsafe { cgc_body_free(handles.body) };
    handles.body = ptr::null_mut();
    let (code, cells, _, _) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::Ok);
    assert_eq!(cells[0], i64::from(known[0].0));
}

#[test]
fn the_brute_strategy_and_f32_agree_on_cells() {
    let body = block();
    let (points, known) = known_points(&body);
    let handles = lattice_handles(&body);
    for (precision, strategy) in [
        (CGC_PRECISION_F64, CGC_STRATEGY_BRUTE),
        (CGC_PRECISION_F32, CGC_STRATEGY_LATTICE),
    ] {
        let mut settings = CgcSettings {
            strategy: 9,
            precision: 9,
            newton_tol: 0.0,
            max_iter: 0,
            inside_tol: 0.0,
            threads: 0,
        };
        let mut locator = ptr::null_mut();
        // SAFETY: valid pointers; the locator is freed below.
        unsafe {
            assert_eq!(cgc_settings_init(precision, &mut settings), CgcError::Ok);
            settings.strategy = strategy;
            settings.threads = 1;
            assert_eq!(
                cgc_locator_new(handles.body, &settings, &mut locator),
                CgcError::Ok
            );
        }
        let (code, cells, xi, _) = locate(locator, &flat(&points));
        // SAFETY: freed once.
        unsafe { cgc_locator_free(locator) };
        assert_eq!(code, CgcError::Ok);
        for (i, &(cell, expected)) in known.iter().enumerate() {
            assert_eq!(cells[i], i64::from(cell));
            assert!(
                (DVec3::from_slice(&xi[3 * i..]) - expected)
                    .abs()
                    .max_element()
                    < 1e-4
            );
        }
    }
}

#[test]
fn query_seconds_times_the_library() {
    let body = block();
    let (points, _) = known_points(&body);
    let handles = lattice_handles(&body);
    let mut seconds = -1.0;
    // SAFETY: valid pointers.
    let code = unsafe {
        cgc_locator_query_seconds(
            handles.locator,
            flat(&points).as_ptr(),
            points.len(),
            3,
            &mut seconds,
        )
    };
    assert_eq!(code, CgcError::Ok);
    assert!(seconds >= 0.0 && seconds.is_finite());
}

/// `*seconds` inside the points was written over a point (the header refuses outputs over the
/// inputs, "as cgc_locate"); now refused before anything is written.
#[test]
fn query_seconds_over_the_points_is_refused() {
    let body = block();
    let (points, _) = known_points(&body);
    let handles = lattice_handles(&body);
    let mut given = flat(&points);
    let before = bits(&given);
    // SAFETY: the points hold 3 n values; `seconds` over the second coordinate is what is tested.
    let code = unsafe {
        let seconds = given.as_mut_ptr().add(1);
        cgc_locator_query_seconds(handles.locator, given.as_ptr(), points.len(), 1, seconds)
    };
    assert_eq!(code, CgcError::InvalidArgument);
    assert!(
        last_error().starts_with("points and seconds overlap"),
        "{}",
        last_error()
    );
    assert_eq!(bits(&given), before, "a point was written");
}

/// Raw handles shared by the threads of one test (the C ABI documents them as thread-safe).
#[derive(Clone, Copy)]
struct Shared(*mut CgcBody, *mut CgcLocator);
// SAFETY: the handles are thread-safe by the header's contract, which this test checks; they are
// freed only after every thread has joined.
unsafe impl Send for Shared {}

impl Shared {
    /// Both handles; a method, so that a closure captures the whole `Shared` (which is `Send`).
    fn get(self) -> (*mut CgcBody, *mut CgcLocator) {
        (self.0, self.1)
    }
}

/// Queries and displacement updates from several threads at once: every answer is that of one
/// of the two fields, never a mix (updates wait for running queries).
#[test]
fn concurrent_updates_and_queries_never_mix_fields() {
    let body = block();
    let (points, _) = known_points(&body);
    let points = flat(&points);
    let handles = lattice_handles(&body);
    let n = body.lattice().node_count();
    let fields: Vec<Vec<f64>> = [0.0, 1.0]
        .iter()
        .map(|&s| {
            (0..n)
                .flat_map(|node| (s * body.displacement(node).unwrap()).to_array())
                .collect()
        })
        .collect();
    let answers: Vec<Vec<u64>> = fields
        .iter()
        .map(|u| {
            // SAFETY: 3 n values.
            let code = unsafe { cgc_body_set_displacements(handles.body, u.as_ptr(), n, 0) };
            assert_eq!(code, CgcError::Ok);
            bits(&locate(handles.locator, &points).2)
        })
        .collect();
    let shared = Shared(handles.body, handles.locator);
    std::thread::scope(|scope| {
        for t in 0..4 {
            let (fields, answers, points) = (&fields, &answers, &points);
            scope.spawn(move || {
                let (body, locator) = shared.get();
                for round in 0..40 {
                    if t % 2 == 0 {
                        let u = &fields[(round + t) % 2];
                        // SAFETY: 3 n values; the handles outlive the scope.
                        let code = unsafe { cgc_body_set_displacements(body, u.as_ptr(), n, 0) };
                        assert_eq!(code, CgcError::Ok);
                    } else {
                        let got = bits(&locate(locator, points).2);
                        assert!(answers.contains(&got), "a query mixed two fields");
                    }
                }
            });
        }
    });
}

/// A lattice body with inactive cells: displacements still come one per lattice node (those of
/// nodes of no active cell ignored), and points in inactive cells are not found.
#[test]
fn masked_lattice_body_answers_only_active_cells() {
    let full = block();
    let lattice = *full.lattice();
    let active: Vec<u8> = (0..lattice.cell_count())
        .map(|c| u8::from(c % 3 != 1))
        .collect();
    let (origin, h, counts) = (
        lattice.origin().to_array(),
        lattice.h().to_array(),
        lattice.cells(),
    );
    let mut dense: Vec<f64> = (0..lattice.node_count())
        .flat_map(|n| full.displacement(n).unwrap().to_array())
        .collect();
    let (points, known) = known_points(&full);
    let mut handles = Handles {
        body: ptr::null_mut(),
        locator: ptr::null_mut(),
    };
    // Node 0 is a corner of cell 0, which is active: a NaN there is refused.
    // SAFETY: every array holds the length passed.
    unsafe {
        let code = cgc_body_from_lattice(
            origin.as_ptr(),
            h.as_ptr(),
            counts.as_ptr(),
            active.as_ptr(),
            active.len(),
            &mut handles.body,
        );
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        let n = lattice.node_count();
        assert_eq!(
            cgc_body_set_displacements(handles.body, dense.as_ptr(), n, 0),
            CgcError::Ok
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
        dense[0] = f64::NAN;
        assert_eq!(
            cgc_body_set_displacements(handles.body, dense.as_ptr(), n, 0),
            CgcError::NonFinite
        );
        assert!(last_error().contains("node 0 "), "{}", last_error());
    }
    let (code, cells, xi, status) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::Ok);
    for (i, &(cell, expected)) in known.iter().enumerate() {
        if active[cell as usize] != 0 {
            assert_eq!(cells[i], i64::from(cell), "point {i}");
            assert!(
                (DVec3::from_slice(&xi[3 * i..]) - expected)
                    .abs()
                    .max_element()
                    < 1e-12
            );
        } else {
            // Inside an inactive cell: no active cell holds it (it is not on a shared face).
            assert_eq!((cells[i], status[i]), (-1, CGC_POINT_OUTSIDE), "point {i}");
        }
    }
}

/// Outputs written over the points or over each other answered wrong without an error (cells
/// written as int64 over ξ: a third of the ξ values were garbage); now refused before writing.
#[test]
fn overlapping_outputs_are_refused_before_anything_is_written() {
    let body = block();
    let handles = lattice_handles(&body);
    let (points, _) = known_points(&body);
    let n = points.len();
    let mut given = flat(&points);
    let before = bits(&given);
    let mut buffer = vec![7.0f64; 4 * n];
    let mut cells = vec![7i64; n];
    let mut status = vec![9u8; n];
    let (base, xi_alone) = (buffer.as_mut_ptr(), vec![7.0f64; 3 * n]);
    let mut xi_alone = xi_alone;
    // SAFETY: every array holds the length passed; the overlaps are what is tested, and the
    // library refuses them before it makes a slice of any.
    unsafe {
        let cases: [(*mut i64, *mut f64, *mut u8, &str); 4] = [
            // ξ in place over the points.
            (
                cells.as_mut_ptr(),
                given.as_mut_ptr(),
                ptr::null_mut(),
                "points and xi",
            ),
            // The cells over the points' first values.
            (
                given.as_mut_ptr().cast(),
                xi_alone.as_mut_ptr(),
                ptr::null_mut(),
                "points and cells",
            ),
            // The cells over ξ's last n values.
            (
                base.add(3 * n - 1).cast(),
                base,
                ptr::null_mut(),
                "cells and xi",
            ),
            // The status bytes inside the cells.
            (
                cells.as_mut_ptr(),
                xi_alone.as_mut_ptr(),
                cells.as_mut_ptr().cast(),
                "cells and status",
            ),
        ];
        for (c, x, s, names) in cases {
            let code = cgc_locate(handles.locator, given.as_ptr(), n, c, x, s);
            assert_eq!(code, CgcError::InvalidArgument, "{names}");
            assert!(last_error().starts_with(names), "{names}: {}", last_error());
        }
        assert_eq!(bits(&given), before, "the points were written");
        assert!(
            buffer.iter().chain(&xi_alone).all(|&v| v == 7.0),
            "an output was written"
        );
        assert!(cells.iter().all(|&c| c == 7) && status.iter().all(|&s| s == 9));
        // Adjacent, not overlapping: answered.
        let (c, x) = (base.cast::<i64>(), base.add(n));
        assert_eq!(
            cgc_locate(
                handles.locator,
                given.as_ptr(),
                n,
                c,
                x,
                status.as_mut_ptr()
            ),
            CgcError::Ok
        );
        let expected = locate(handles.locator, &given);
        assert_eq!(std::slice::from_raw_parts(c, n), &expected.1[..]);
        assert_eq!(
            bits(std::slice::from_raw_parts(x, 3 * n)),
            bits(&expected.2)
        );
        // The gap's outputs likewise: gap over closest, closest over the points, face in face_cell.
        let (mut gap, mut closest, mut face_cell) = (vec![7.0; n], vec![7.0; 3 * n], vec![7i64; n]);
        let null_f = ptr::null_mut::<f64>();
        let gap_cases: [(*mut f64, *mut f64, *mut i64, *mut i32, &str); 3] = [
            (
                closest.as_mut_ptr(),
                closest.as_mut_ptr(),
                ptr::null_mut(),
                ptr::null_mut(),
                "gap and closest",
            ),
            (
                null_f,
                given.as_mut_ptr(),
                ptr::null_mut(),
                ptr::null_mut(),
                "points and closest",
            ),
            (
                gap.as_mut_ptr(),
                null_f,
                face_cell.as_mut_ptr(),
                face_cell.as_mut_ptr().cast(),
                "face_cell and face",
            ),
        ];
        for (g, c, fc, f, names) in gap_cases {
            let code = cgc_gap(handles.locator, given.as_ptr(), n, 0.5, g, c, null_f, fc, f);
            assert_eq!(code, CgcError::InvalidArgument, "{names}");
            assert!(last_error().starts_with(names), "{names}: {}", last_error());
        }
        assert_eq!(bits(&given), before, "the points were written");
        assert!(gap.iter().chain(&closest).all(|&v| v == 7.0));
        assert!(face_cell.iter().all(|&c| c == 7));
    }
}

/// A misaligned `out` or `settings` was written or read through as if aligned (undefined
/// behaviour in Rust, where every other pointer argument is checked); now refused as the arrays
/// are, with nothing written.
#[test]
fn misaligned_handle_outputs_and_settings_are_refused() {
    let body = block();
    let handles = lattice_handles(&body);
    let (origin, h, counts) = ([0.0; 3], [1.0; 3], [2u32, 2, 2]);
    let mesh_nodes: Vec<f64> = (0..8)
        .flat_map(|c| [(c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64])
        .collect();
    let mesh_cell: [i64; 8] = [0, 1, 3, 2, 4, 5, 7, 6];
    let mut words = [0u64; 16];
    let base = words.as_mut_ptr().cast::<u8>();
    // SAFETY: every pointer points to enough memory (words holds 128 bytes); the misalignment is
    // what is tested, and the library refuses it before any read or write through the pointer.
    unsafe {
        let odd_out = base.add(1);
        assert_eq!(
            cgc_body_from_lattice(
                origin.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                ptr::null(),
                0,
                odd_out.cast()
            ),
            CgcError::InvalidArgument
        );
        assert!(
            last_error().contains("out is not aligned"),
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_body_from_mesh(
                mesh_nodes.as_ptr(),
                8,
                mesh_cell.as_ptr(),
                1,
                0,
                odd_out.cast()
            ),
            CgcError::InvalidArgument
        );
        assert!(
            last_error().contains("out is not aligned"),
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), odd_out.cast()),
            CgcError::InvalidArgument
        );
        assert!(
            last_error().contains("out is not aligned"),
            "{}",
            last_error()
        );
        assert!(words.iter().all(|&w| w == 0), "a handle was written");

        let settings = settings(CGC_PRECISION_F64);
        let odd_settings = base.add(4);
        ptr::copy_nonoverlapping(
            (&raw const settings).cast::<u8>(),
            odd_settings,
            size_of::<CgcSettings>(),
        );
        locator_refused(
            handles.body,
            odd_settings.cast(),
            CgcError::InvalidArgument,
            &["settings is not aligned"],
        );
    }
}

/// A thread count above 1024 (say a negative int cast to uint32_t) was quietly capped to a pool of
/// 1024 threads; it is refused, naming the count and the limit, as the Python binding does.
#[test]
fn too_many_threads_are_refused_not_capped() {
    let body = block();
    let handles = lattice_handles(&body);
    // SAFETY: valid pointers; the settings are initialised by cgc_settings_init.
    unsafe {
        let mut settings = settings(CGC_PRECISION_F64);
        for threads in [1025, u32::MAX] {
            settings.threads = threads;
            locator_refused(
                handles.body,
                &settings,
                CgcError::InvalidArgument,
                &[&format!("threads is {threads}"), "at most 1024"],
            );
        }
        settings.threads = 2;
        let mut locator = ptr::null_mut();
        assert_eq!(
            cgc_locator_new(handles.body, &settings, &mut locator),
            CgcError::Ok
        );
        cgc_locator_free(locator);
    }
}

/// A NULL mask with a length was read as "every cell active": the caller's flags were dropped.
#[test]
fn a_null_active_mask_with_a_length_is_refused() {
    let (origin, h, counts) = ([0.0; 3], [1.0; 3], [2u32, 2, 2]);
    let mut body = ptr::null_mut();
    // SAFETY: origin, h and counts hold 3 values; NULL with a length is what is tested.
    let code = unsafe {
        cgc_body_from_lattice(
            origin.as_ptr(),
            h.as_ptr(),
            counts.as_ptr(),
            ptr::null(),
            8,
            &mut body,
        )
    };
    assert_eq!(code, CgcError::NullPointer);
    assert!(
        last_error().contains("active is NULL (for 8 flags)"),
        "{}",
        last_error()
    );
    assert!(body.is_null());
}

/// A displacement too large was named by the library's lattice node, not by the caller's node of
/// the mesh: node 0 for a mesh whose nodes come in reverse order named the caller's last node.
#[test]
fn a_displacement_too_large_is_named_by_the_callers_node() {
    // Two unit cubes along x, their 12 nodes given in reverse lattice order.
    let m = 12;
    let lattice_node = |k: usize| m - 1 - k;
    let nodes: Vec<f64> = (0..m)
        .flat_map(|k| {
            let n = lattice_node(k);
            [(n % 3) as f64, ((n / 3) % 2) as f64, (n / 6) as f64]
        })
        .collect();
    let corners = |i: usize| [i, i + 1, i + 4, i + 3, i + 6, i + 7, i + 10, i + 9];
    let cells: Vec<i64> = (0..2)
        .flat_map(|i| corners(i).map(|n| lattice_node(n) as i64))
        .collect();
    let mut body = ptr::null_mut();
    let mut u = vec![0.0; 3 * m];
    u[3 * 2 + 1] = 1e300; // the caller's node 2, lattice node 9
    // SAFETY: every array holds the length passed; the handle is freed once.
    unsafe {
        assert_eq!(
            cgc_body_from_mesh(nodes.as_ptr(), m, cells.as_ptr(), 2, 0, &mut body),
            CgcError::Ok
        );
        let code = cgc_body_set_displacements(body, u.as_ptr(), m, CGC_LAYOUT_NODE_MAJOR);
        assert_eq!(code, CgcError::InvalidArgument);
        let message = last_error();
        assert!(
            message.contains("node 2 (0-based) is too large: [0.0, 1e300, 0.0]"),
            "{message}"
        );
        // Written as a number is, not as 301 digits.
        assert!(message.len() < 250, "{message}");
        cgc_body_free(body);
    }
}

/// `cgc_relocate` from `cells` and `xi` (the previous answers, overwritten).
fn relocate(
    locator: *const CgcLocator,
    points: &[f64],
    cells: &mut [i64],
    xi: &mut [f64],
) -> (CgcError, Vec<u8>) {
    let n = points.len() / 3;
    assert_eq!((cells.len(), xi.len()), (n, 3 * n));
    let mut status = vec![9u8; n];
    // SAFETY: the arrays hold n, 3 n and n values and do not overlap.
    let code = unsafe {
        cgc_relocate(
            locator,
            points.as_ptr(),
            n,
            cells.as_mut_ptr(),
            xi.as_mut_ptr(),
            status.as_mut_ptr(),
        )
    };
    (code, status)
}

/// A solver loop: answers for one field are the hints for the next, and the warm answers are the
/// known cells and ξ of the new field, whatever the hints (the previous answers, none, wrong
/// cells, NaN ξ); without hints they are `cgc_locate`'s bitwise.
#[test]
fn relocate_answers_the_known_cells_from_any_hint() {
    let mut body = block();
    let handles = lattice_handles(&body);
    let (points, _) = known_points(&body);
    let (code, mut cells, mut xi, _) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::Ok);
    // The next iteration: the field grown by a fifth, and points made in it.
    body.update_displacements(|_, _, u| *u *= 1.2).unwrap();
    let dense: Vec<f64> = (0..body.lattice().node_count())
        .flat_map(|n| body.displacement(n).unwrap().to_array())
        .collect();
    // SAFETY: one displacement per lattice node.
    let set = unsafe {
        cgc_body_set_displacements(
            handles.body,
            dense.as_ptr(),
            dense.len() / 3,
            CGC_LAYOUT_NODE_MAJOR,
        )
    };
    assert_eq!(set, CgcError::Ok);
    let (points, known) = known_points(&body);
    let points = flat(&points);
    let n = points.len() / 3;
    let cold = locate(handles.locator, &points);
    let wrong: Vec<i64> = (0..n as i64).map(|i| (i * 37) % 120).collect();
    let hints: [(&str, Vec<i64>, Vec<f64>); 4] = [
        ("previous answers", cells.clone(), xi.clone()),
        ("none", vec![-1; n], vec![f64::NAN; 3 * n]),
        ("wrong cells", wrong.clone(), vec![0.3; 3 * n]),
        ("NaN xi", cells.clone(), vec![f64::NAN; 3 * n]),
    ];
    for (what, mut c, mut x) in hints {
        let (code, status) = relocate(handles.locator, &points, &mut c, &mut x);
        assert_eq!(code, CgcError::Ok, "{what}: {}", last_error());
        for (i, &(cell, expected)) in known.iter().enumerate() {
            assert_eq!(c[i], i64::from(cell), "{what}: point {i}");
            assert_eq!(status[i], CGC_POINT_INSIDE);
            let got = DVec3::from_slice(&x[3 * i..]);
            assert!(
                (got - expected).abs().max_element() < 1e-12,
                "{what}: point {i}: {got} vs {expected}"
            );
        }
        assert_eq!((c[n - 1], status[n - 1]), (-1, CGC_POINT_OUTSIDE), "{what}");
        if what == "none" {
            assert_eq!((c.clone(), bits(&x)), (cold.1.clone(), bits(&cold.2)));
        }
    }
    // A hint that is no cell is refused before anything is written.
    for bad in [-2, 120, i64::MAX] {
        cells[3] = bad;
        let before = (cells.clone(), bits(&xi));
        let (code, status) = relocate(handles.locator, &points, &mut cells, &mut xi);
        assert_eq!(code, CgcError::InvalidArgument, "cell {bad}");
        let message = last_error();
        assert!(
            message.contains(&format!("cells[3] = {bad}")) && message.contains("0 to 119"),
            "{message}"
        );
        assert_eq!((cells.clone(), bits(&xi)), before, "nothing written");
        assert!(status.iter().all(|&s| s == 9));
    }
}

/// The hint is read in the caller's numbering and tried first: a point on the face between two
/// cells is answered by whichever of them the hint names (each holds it), on a lattice body and
/// on a mesh whose cells are numbered in reverse.
#[test]
fn relocate_tries_the_hinted_cell_in_the_callers_numbering() {
    let body = block();
    let lattice = *body.lattice();
    let (left, right) = (lattice.cell_id([2, 2, 1]), lattice.cell_id([3, 2, 1]));
    // On the face x = +1 of `left`, which is x = −1 of `right`.
    let face = body.point_at(left, DVec3::new(1.0, 0.3, -0.4)).unwrap();
    let points = flat(&[face]);
    let lattice_handles = lattice_handles(&body);
    let (mesh_handles, e, _, _) = reversed_mesh_handles(&body);
    let numbers = [
        (&lattice_handles, left.0 as i64, right.0 as i64),
        (
            &mesh_handles,
            (e - 1 - left.index()) as i64,
            (e - 1 - right.index()) as i64,
        ),
    ];
    for (handles, l, r) in numbers {
        let (_, cold, _, _) = locate(handles.locator, &points);
        assert!(
            cold[0] == l || cold[0] == r,
            "cold {} not {l} or {r}",
            cold[0]
        );
        for (hint, xi) in [(l, [1.0, 0.3, -0.4]), (r, [-1.0, 0.3, -0.4])] {
            let (mut c, mut x) = ([hint], [0.0; 3]);
            let (code, _) = relocate(handles.locator, &points, &mut c, &mut x);
            assert_eq!(code, CgcError::Ok, "{}", last_error());
            assert_eq!(c[0], hint, "the hinted owner answers");
            let got = DVec3::from_array(x);
            assert!(
                (got - DVec3::from_array(xi)).abs().max_element() < 1e-12,
                "{got}"
            );
        }
    }
}

/// On a lattice body with inactive cells, a previous cell that is an inactive lattice cell is no
/// cell of the body, which the header refuses as a hint (`CGC_ERROR_INVALID_ARGUMENT`, before
/// anything is written); it was taken as a hint, so a hint array from another body went unseen.
#[test]
fn relocate_refuses_an_inactive_lattice_cell_as_a_hint() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [3, 2, 2]).unwrap();
    // Every third cell inactive: cells 0, 3, 6 and 9.
    let active: Vec<u8> = (0..12).map(|c| u8::from(c % 3 != 0)).collect();
    let mut handles = masked_body(&lattice, &active);
    // SAFETY: a live body; the locator is freed by `Handles`.
    unsafe {
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
    }
    // A point in active cell 1, then one in inactive cell 0 (found in none).
    let points = [1.5, 0.5, 0.5, 0.5, 0.5, 0.5];
    let (mut cells, mut xi) = ([1i64, 3], [0.25; 6]);
    let (code, status) = relocate(handles.locator, &points, &mut cells, &mut xi);
    assert_eq!(code, CgcError::InvalidArgument);
    assert!(
        last_error().starts_with("cells[1] = 3 is not a previous answer")
            && last_error().contains("not active"),
        "{}",
        last_error()
    );
    assert_eq!((cells, xi), ([1, 3], [0.25; 6]), "nothing is written");
    assert_eq!(status, [9, 9]);
    // Active cells and −1 are hints, whatever they say.
    let mut cells = [4i64, -1];
    let (code, status) = relocate(handles.locator, &points, &mut cells, &mut xi);
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    assert_eq!(cells, [1, -1]);
    assert_eq!(status, [CGC_POINT_INSIDE, CGC_POINT_OUTSIDE]);
}

/// f32 settings on a body whose cells the f32 kernel cannot resolve (spacing 1e-13) were taken by
/// `cgc_locator_new`, and every later query then failed with an "invalid setting" error (the
/// library checks the spacing when a query builds its search): the locator refuses them instead,
/// once, where the settings are given. f64 settings are fine there.
#[test]
fn f32_settings_on_cells_too_small_for_f32_are_refused_by_the_locator() {
    let (origin, h, counts) = ([0.0; 3], [1e-13; 3], [2u32, 2, 2]);
    let mut body = ptr::null_mut();
    // SAFETY: every array holds the length passed; the handles are freed once, here.
    unsafe {
        assert_eq!(
            cgc_body_from_lattice(
                origin.as_ptr(),
                h.as_ptr(),
                counts.as_ptr(),
                ptr::null(),
                0,
                &mut body
            ),
            CgcError::Ok
        );
        let settings = settings(CGC_PRECISION_F32);
        locator_refused(body, &settings, CgcError::InvalidArgument, &["f32"]);
        let mut locator = ptr::null_mut();
        assert_eq!(
            cgc_locator_new(body, ptr::null(), &mut locator),
            CgcError::Ok
        );
        let points = [1.5e-13, 0.5e-13, 0.5e-13];
        let (code, cells, _, _) = locate(locator, &points);
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        assert_eq!(cells, [1]);
        cgc_locator_free(locator);
        cgc_body_free(body);
    }
}

/// On a body whose displacements leave the caches, the library sorts a large batch by cell; the C
/// API then answers it whole (in pieces it would be answered in the caller's order) and writes
/// the answers piece by piece: each point's answer at its own place, bitwise the library's, cold
/// and warm, with the first non-finite point reported.
/// A body whose displacements leave the caches (90³ cells), and more random points in it than
/// `Schedule::AUTO_MIN_POINTS` (from random cells and ξ), point 5000 non-finite and one far
/// outside: a batch the library sorts by cell.
fn large_scene() -> (Body, Vec<DVec3>) {
    let lattice =
        Lattice::new(DVec3::new(-1.0, 2.0, 0.0), DVec3::splat(0.1), [90, 90, 90]).unwrap();
    let mut body = Body::full(lattice);
    body.update_displacements(|_, x, u| {
        *u = DVec3::new(
            0.02 * (x.y * 2.0).sin(),
            0.01 * x.x * x.z,
            -0.03 * x.x.cos(),
        )
    })
    .unwrap();
    let n = 3 * cgcontact::Schedule::AUTO_MIN_POINTS / 2;
    let mut next = uniform(7);
    let cells = lattice.cell_count() as f64;
    let mut points: Vec<DVec3> = (0..n)
        .map(|_| {
            let cell = CellId((next() * cells) as u32);
            let xi = DVec3::new(next(), next(), next()) * 2.0 - 1.0;
            body.point_at(cell, xi).unwrap()
        })
        .collect();
    points[5000].x = f64::NAN;
    points[n - 3] = DVec3::splat(1e3);
    (body, points)
}

#[test]
fn large_batches_on_large_bodies_are_answered_whole_and_in_place() {
    let (body, points) = large_scene();
    let library = LatticeLocator::new(&body, Settings::default()).unwrap();
    assert!(library.sorts_batch(&points), "the library sorts this batch");
    let expected = written(&library.locate_all(&points));
    let handles = lattice_handles(&body);
    let (code, mut cells, mut xi, status) = locate(handles.locator, &flat(&points));
    assert_eq!(code, CgcError::NonFinitePoint);
    assert!(last_error().starts_with("point 5000 "), "{}", last_error());
    assert_eq!((&cells, &status), (&expected.0, &expected.2), "cgc_locate");
    assert_eq!(bits(&xi), bits(&expected.1), "cgc_locate");
    // Warm, from the answers just written: the same cells and status, ξ within the Newton
    // tolerance (each hinted cell is inverted again from its own ξ).
    let (code, status) = relocate(handles.locator, &flat(&points), &mut cells, &mut xi);
    assert_eq!(code, CgcError::NonFinitePoint);
    assert_eq!(
        (&cells, &status),
        (&expected.0, &expected.2),
        "cgc_relocate"
    );
    assert_xi_close(&xi, &expected.1, "cgc_relocate");
}

/// `cgc_locate_unordered`, with its `order` array: the answers of `points` row by row, each point
/// once, and the first non-finite point in the points' order reported.
fn locate_unordered(
    locator: *const CgcLocator,
    points: &[DVec3],
    with_status: bool,
) -> (CgcError, Vec<i64>, Vec<i64>, Vec<f64>, Vec<u8>) {
    let points = flat(points);
    let n = points.len() / 3;
    let (mut order, mut cells, mut xi) = (vec![-7i64; n], vec![7i64; n], vec![7.0; 3 * n]);
    let mut status = vec![9u8; if with_status { n } else { 0 }];
    // SAFETY: the arrays hold n, n, 3 n and n (or no) values and do not overlap.
    let code = unsafe {
        cgc_locate_unordered(
            locator,
            points.as_ptr(),
            n,
            order.as_mut_ptr(),
            cells.as_mut_ptr(),
            xi.as_mut_ptr(),
            if with_status {
                status.as_mut_ptr()
            } else {
                ptr::null_mut()
            },
        )
    };
    (code, order, cells, xi, status)
}

/// Unordered rows: row k answers point `order[k]` bitwise as `cgc_locate` answers it, each point
/// once. A batch the library sorts comes cell by cell (not in the points' order); a small one
/// in the points' order. Overlapping arrays are refused before anything is written.
#[test]
fn unordered_rows_answer_their_points_bitwise() {
    let (body, points) = large_scene();
    let handles = lattice_handles(&body);
    let expected = written(
        &LatticeLocator::new(&body, Settings::default())
            .unwrap()
            .locate_all(&points),
    );
    // The whole batch (sorted), and 1,000 points around point 5000 (too few to sort).
    for (batch, sorted) in [(0..points.len(), true), (4500..5500, false)] {
        for with_status in [true, false] {
            let (code, order, cells, xi, status) =
                locate_unordered(handles.locator, &points[batch.clone()], with_status);
            assert_eq!(code, CgcError::NonFinitePoint);
            let first = format!("point {} ", 5000 - batch.start);
            assert!(last_error().starts_with(&first), "{}", last_error());
            let mut seen = vec![false; batch.len()];
            for (k, &i) in order.iter().enumerate() {
                let i = usize::try_from(i).expect("an index");
                assert!(!std::mem::replace(&mut seen[i], true), "point {i} twice");
                let p = batch.start + i;
                assert_eq!(cells[k], expected.0[p], "row {k}, point {i}");
                assert_eq!(
                    bits(&xi[3 * k..3 * k + 3]),
                    bits(&expected.1[3 * p..3 * p + 3])
                );
                if with_status {
                    assert_eq!(status[k], expected.2[p], "row {k}, point {i}");
                }
            }
            let in_order = order.iter().enumerate().all(|(k, &i)| i == k as i64);
            assert_eq!(in_order, !sorted, "points {batch:?}");
        }
    }
    // `order` overlapping `cells`: refused, nothing written.
    let flat_points = flat(&points[..10]);
    let mut shared = vec![-5i64; 10];
    let mut xi = vec![-5.0; 30];
    // SAFETY: every array holds what is passed; two of them overlap on purpose.
    let code = unsafe {
        cgc_locate_unordered(
            handles.locator,
            flat_points.as_ptr(),
            10,
            shared.as_mut_ptr(),
            shared.as_mut_ptr(),
            xi.as_mut_ptr(),
            ptr::null_mut(),
        )
    };
    assert_eq!(code, CgcError::InvalidArgument);
    assert!(last_error().contains("order"), "{}", last_error());
    assert!(shared.iter().all(|&c| c == -5) && xi.iter().all(|&x| x == -5.0));
    // A NULL `order`: refused, nothing written.
    // SAFETY: every array but `order` holds what is passed.
    let code = unsafe {
        cgc_locate_unordered(
            handles.locator,
            flat_points.as_ptr(),
            10,
            ptr::null_mut(),
            shared.as_mut_ptr(),
            xi.as_mut_ptr(),
            ptr::null_mut(),
        )
    };
    assert_eq!(code, CgcError::NullPointer);
    assert!(
        last_error().starts_with("order is NULL"),
        "{}",
        last_error()
    );
    assert!(shared.iter().all(|&c| c == -5) && xi.iter().all(|&x| x == -5.0));
}

/// A locator keeps the answers of its last sorted batch for its next call. Batches that grow and
/// shrink, cold, unordered and warm, answer as a new locator answers each: nothing of an earlier
/// batch comes back.
#[test]
fn kept_buffers_never_leak_a_previous_batch() {
    let (body, points) = large_scene();
    let kept = lattice_handles(&body);
    for (start, len) in [(0, 20_000), (1_000, 17_000), (0, 24_576), (3_000, 16_500)] {
        let batch = &points[start..start + len];
        let fresh = lattice_handles(&body);
        let (code, cells, xi, status) = locate(fresh.locator, &flat(batch));
        let (got_code, mut got_cells, mut got_xi, got_status) = locate(kept.locator, &flat(batch));
        assert_eq!((got_code, &got_cells, &got_status), (code, &cells, &status));
        assert_eq!(bits(&got_xi), bits(&xi), "points {start}.. ({len})");
        let (_, order, rows, _, _) = locate_unordered(kept.locator, batch, false);
        for (k, &i) in order.iter().enumerate() {
            assert_eq!(rows[k], cells[i as usize], "unordered row {k}");
        }
        let (_, warm_status) = relocate(kept.locator, &flat(batch), &mut got_cells, &mut got_xi);
        assert_eq!((&got_cells, &warm_status), (&cells, &status), "warm");
        assert_xi_close(&got_xi, &xi, "warm");
    }
}

/// The whole-batch path of a sortable batch, on the caller's own threads (1 to 3), with a last
/// piece shorter than the others, a NULL `status`, a body with inactive cells and bad hints
/// (−1, NaN and infinite ξ, another point's cell): the answers of batches too small to sort, cold
/// bitwise and warm within the Newton tolerance; a hint to an inactive cell refused unwritten.
#[test]
fn whole_batches_answer_as_small_ones_from_any_hint() {
    let lattice =
        Lattice::new(DVec3::new(-1.0, 2.0, 0.0), DVec3::splat(0.1), [90, 90, 90]).unwrap();
    let inactive = |c: usize| c % 11 == 3;
    let active: Vec<u8> = (0..lattice.cell_count())
        .map(|c| u8::from(!inactive(c)))
        .collect();
    // The C API's pieces are 2,048 points: the last is 777.
    let n = 2 * cgcontact::Schedule::AUTO_MIN_POINTS + 2048 + 777;
    let mut next = uniform(3);
    let mut points: Vec<DVec3> = (0..n)
        .map(|_| lattice.origin() + DVec3::new(next(), next(), next()) * 9.2 - 0.1)
        .collect();
    points[n - 1].y = f64::INFINITY;
    let points = flat(&points);
    let mut handles = masked_body(&lattice, &active);
    for threads in [1, 2, 3] {
        let settings = CgcSettings {
            threads,
            ..settings(CGC_PRECISION_F64)
        };
        // SAFETY: live body, readable settings; the locator is freed below.
        unsafe {
            cgc_locator_free(handles.locator);
            handles.locator = ptr::null_mut();
            assert_eq!(
                cgc_locator_new(handles.body, &settings, &mut handles.locator),
                CgcError::Ok
            );
        }
        // Batches of 1,000 points: too small to sort, answered piece by piece.
        let mut expected = (Vec::new(), Vec::new(), Vec::new());
        for piece in points.chunks(3000) {
            let (_, cells, xi, status) = locate(handles.locator, piece);
            expected.0.extend(cells);
            expected.1.extend(xi);
            expected.2.extend(status);
        }
        assert!(expected.0.iter().filter(|&&c| c >= 0).count() > n / 2);
        let (code, mut cells, mut xi, status) = locate(handles.locator, &points);
        let what = format!("{threads} threads");
        assert_eq!(code, CgcError::NonFinitePoint, "{what}");
        assert_eq!(cells, expected.0, "cgc_locate, {what}");
        assert_eq!(bits(&xi), bits(&expected.1), "cgc_locate, {what}");
        assert_eq!(status, expected.2, "cgc_locate, {what}");
        for i in 0..n {
            match i % 4 {
                0 => cells[i] = -1,
                1 => xi[3 * i] = f64::NAN,
                2 => xi[3 * i + 1] = f64::INFINITY,
                _ => cells[i] = cells[(i * 7919) % n],
            }
        }
        // SAFETY: the arrays hold n, 3 n values and do not overlap; no status.
        let code = unsafe {
            cgc_relocate(
                handles.locator,
                points.as_ptr(),
                n,
                cells.as_mut_ptr(),
                xi.as_mut_ptr(),
                ptr::null_mut(),
            )
        };
        assert_eq!(code, CgcError::NonFinitePoint, "{what}");
        assert_eq!(cells, expected.0, "cgc_relocate, {what}");
        assert_xi_close(&xi, &expected.1, &format!("cgc_relocate, {what}"));
        cells[n / 2] = 3;
        let before = (cells.clone(), bits(&xi));
        let (code, _) = relocate(handles.locator, &points, &mut cells, &mut xi);
        assert_eq!(code, CgcError::InvalidArgument, "{what}");
        assert_eq!((cells, bits(&xi)), before, "{what}: nothing is written");
    }
}
