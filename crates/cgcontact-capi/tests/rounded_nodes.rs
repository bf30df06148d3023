//! Meshes whose node coordinates lie off their lattice by more than f64 rounding (32-bit float
//! coordinates on a spacing of 0.1, as a mesh stored in single precision gives them): each node
//! stays where the caller has it, before and after an update, as `cgcontact locate` places a
//! file's nodes. A point on a boundary face where the caller's nodes put it is in that face's
//! cell, uniform or adaptive; with the nodes' offsets dropped by the first update, it was 5e-8
//! of a cell outside and found in no cell.

use std::ffi::CStr;
use std::ptr;

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, CORNER_OFFSETS, CellId, Lattice, Leaf};
use cgcontact_capi::*;

fn last_error() -> String {
    // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
    unsafe { CStr::from_ptr(cgc_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// A coordinate as a 32-bit float holds it.
fn f32_rounded(v: f64) -> f64 {
    f64::from(v as f32)
}

/// A body and a locator from a mesh (0-based topology), freed on drop.
struct Handles {
    body: *mut CgcBody,
    locator: *mut CgcLocator,
    n_nodes: usize,
}

impl Handles {
    fn new(nodes: &[DVec3], topology: &[i64]) -> Self {
        let flat: Vec<f64> = nodes.iter().flat_map(|p| p.to_array()).collect();
        let (mut body, mut locator) = (ptr::null_mut(), ptr::null_mut());
        // SAFETY: the arrays hold 3 n_nodes and 8 n_cells values; the handles are written once.
        unsafe {
            let code = cgc_body_from_mesh(
                flat.as_ptr(),
                nodes.len(),
                topology.as_ptr(),
                topology.len() / 8,
                0,
                &mut body,
            );
            assert_eq!(code, CgcError::Ok, "{}", last_error());
            let code = cgc_locator_new(body, ptr::null(), &mut locator);
            assert_eq!(code, CgcError::Ok, "{}", last_error());
        }
        Self {
            body,
            locator,
            n_nodes: nodes.len(),
        }
    }

    /// Every node displaced by `u`.
    fn set(&self, u: DVec3, layout: u32) {
        let values: Vec<f64> = if layout & CGC_LAYOUT_COMPONENT_MAJOR != 0 {
            u.to_array()
                .iter()
                .flat_map(|&v| std::iter::repeat_n(v, self.n_nodes))
                .collect()
        } else {
            (0..self.n_nodes).flat_map(|_| u.to_array()).collect()
        };
        // SAFETY: `values` holds 3 n_nodes doubles; the handle is live.
        let code =
            unsafe { cgc_body_set_displacements(self.body, values.as_ptr(), self.n_nodes, layout) };
        assert_eq!(code, CgcError::Ok, "{}", last_error());
    }

    /// The cell and ξ of one point.
    fn locate(&self, p: DVec3) -> (i64, DVec3) {
        let (mut cell, mut xi) = (0i64, [0.0; 3]);
        // SAFETY: one point, one cell and three ξ values; the handle is live.
        let code = unsafe {
            cgc_locate(
                self.locator,
                p.to_array().as_ptr(),
                1,
                &mut cell,
                xi.as_mut_ptr(),
                ptr::null_mut(),
            )
        };
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        (cell, DVec3::from_array(xi))
    }

    /// The point's signed gap to the surface within `distance`.
    fn gap(&self, p: DVec3, distance: f64) -> f64 {
        let mut gap = 0.0;
        // SAFETY: one point and one gap; the other outputs are skipped; the handle is live.
        let code = unsafe {
            cgc_gap(
                self.locator,
                p.to_array().as_ptr(),
                1,
                distance,
                &mut gap,
                ptr::null_mut(),
                ptr::null_mut(),
                ptr::null_mut(),
                ptr::null_mut(),
            )
        };
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        gap
    }
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

/// `p` in cell `cell` with ξ along x at `xi_x` (a face), before and after updates that leave the
/// body undeformed or translate it, with either layout flag.
fn assert_stays_on_its_face(handles: &Handles, p: DVec3, cell: i64, xi_x: f64) {
    let check = |p: DVec3, when: &str| {
        let (found, xi) = handles.locate(p);
        assert_eq!(found, cell, "{when}: the point on cell {cell}'s face");
        assert!((xi.x - xi_x).abs() < 1e-6, "{when}: ξ {xi}");
        let gap = handles.gap(p, 0.05);
        assert!(gap.abs() < 1e-12, "{when}: gap {gap:e} on the surface");
    };
    check(p, "a new body");
    handles.set(DVec3::ZERO, CGC_LAYOUT_NODE_MAJOR);
    check(p, "displaced by zero");
    let t = DVec3::new(0.01, -0.02, 0.03);
    handles.set(t, CGC_LAYOUT_COMPONENT_MAJOR | CGC_FILL_HANGING);
    check(p + t, "translated");
}

/// An L-shaped uniform block, 10 × 2 × 1 cells of 0.1 with the row j = 1 cut at i = 3: the face
/// x = 0.3 of cell (2, 1, 0) is on the surface. Nodes as 32-bit floats (0.3 is 1.2e-8 above).
#[test]
fn a_uniform_mesh_of_float_coordinates_keeps_its_nodes_where_given() {
    let (nx, ny) = (10, 2);
    let node = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut nodes = vec![DVec3::ZERO; (nx + 1) * (ny + 1) * 2];
    for k in 0..2 {
        for j in 0..=ny {
            for i in 0..=nx {
                let x = DVec3::new(i as f64, j as f64, k as f64) * 0.1;
                nodes[node(i, j, k)] = DVec3::from_array(x.to_array().map(f32_rounded));
            }
        }
    }
    let mut topology = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if j == 1 && i >= 3 {
                continue;
            }
            topology.extend(
                CORNER_OFFSETS
                    .map(|[a, b, c]| node(i + a as usize, j + b as usize, c as usize) as i64),
            );
        }
    }
    let cell = topology.len() as i64 / 8 - 1; // (2, 1, 0), the last one
    let p = DVec3::new(f32_rounded(0.3), 0.15, 0.05);
    assert!(p.x > 0.3 + 1e-8, "the face lies off the lattice: {}", p.x);
    assert_stays_on_its_face(&Handles::new(&nodes, &topology), p, cell, 1.0);
}

/// An adaptive block: base cells (0, 0, 0), (1, 0, 0), (2, 0, 0) and (2, 1, 0) of 0.1, the first
/// halved (hanging nodes on its face with (1, 0, 0)). The face x = 0.2 of (2, 1, 0) is on the
/// surface; as a 32-bit float it lies 5e-9 from where the detected lattice has it.
#[test]
fn an_adaptive_mesh_of_float_coordinates_keeps_its_nodes_where_given() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.1), [3, 2, 1]).unwrap();
    let mut leaves: Vec<Leaf> = Leaf::new(0, [0, 0, 0]).children().into_iter().collect();
    leaves.extend([[1, 0, 0], [2, 0, 0], [2, 1, 0]].map(|ijk| Leaf::new(0, ijk)));
    let body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    assert!(body.hanging_nodes().count() > 0);
    let nodes: Vec<DVec3> = (0..body.node_count())
        .map(|k| DVec3::from_array(body.node_position(k).unwrap().to_array().map(f32_rounded)))
        .collect();
    let topology: Vec<i64> = (0..body.cell_count())
        .flat_map(|c| body.cell_nodes(CellId(c as u32)).unwrap().map(|n| n as i64))
        .collect();
    let handles = Handles::new(&nodes, &topology);
    let mut hanging = 0;
    // SAFETY: the handle is live; one writable count.
    let code = unsafe { cgc_body_hanging_count(handles.body, &mut hanging) };
    assert_eq!(
        (code, hanging),
        (CgcError::Ok, body.hanging_nodes().count())
    );
    let cell = body.cell_count() as i64 - 1; // (2, 1, 0), the last one
    let p = DVec3::new(f32_rounded(0.2), 0.15, 0.05);
    assert_stays_on_its_face(&handles, p, cell, -1.0);
}
