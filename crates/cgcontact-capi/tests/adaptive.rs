//! Adaptive meshes through the C ABI: a body of several refinement levels given as nodes and
//! hexahedra in shuffled order (some nodes duplicated, one unused) answers as the Rust library's
//! `AdaptiveLocator` and brute force on the same leaves; hanging nodes off their constraint are
//! refused with their own error code, or filled on request; bad adaptive meshes are refused.

use std::ffi::CStr;
use std::ptr;

use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, CellId, GapFinder, Lattice, Leaf, Locator, Settings,
};
use cgcontact_baseline::BruteForce;
use cgcontact_capi::*;

fn last_error() -> String {
    // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
    unsafe { CStr::from_ptr(cgc_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// A deterministic permutation of 0..n (a multiplicative step coprime with n, then a rotation).
fn permutation(n: usize, step: usize, shift: usize) -> Vec<usize> {
    let step = (step..)
        .find(|s| gcd(*s, n) == 1)
        .expect("some step is coprime");
    (0..n).map(|k| (k * step + shift) % n).collect()
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// A 3 × 2 × 2 block, base cell (1, 0, 0) refined once and its upper child refined again (level 2
/// beside level 0: unbalanced), base cell (0, 1, 1) refined once; leaves in shuffled order, a
/// smooth displacement on the independent nodes and the hanging ones filled.
fn scene() -> AdaptiveBody {
    let lattice = Lattice::new(
        DVec3::new(0.5, -1.0, 2.0),
        DVec3::new(0.6, 0.5, 0.4),
        [3, 2, 2],
    )
    .unwrap();
    let mut leaves = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..3 {
                let base = Leaf::new(0, [i, j, k]);
                match [i, j, k] {
                    [1, 0, 0] => {
                        for child in base.children() {
                            if child.ijk == [3, 1, 1] {
                                leaves.extend(child.children());
                            } else {
                                leaves.push(child);
                            }
                        }
                    }
                    [0, 1, 1] => leaves.extend(base.children()),
                    _ => leaves.push(base),
                }
            }
        }
    }
    let order = permutation(leaves.len(), 7, 3);
    let leaves = order.iter().map(|&k| leaves[k]).collect();
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    body.update_independent(|_, x, u| {
        *u = DVec3::new(
            0.03 * (2.0 * x.y + x.z).sin(),
            0.02 * (1.5 * x.x).cos() * x.z,
            -0.025 * (x.x + 0.5 * x.y).sin(),
        )
    })
    .unwrap();
    assert!(body.validate().is_ok());
    assert!(body.hanging_nodes().count() > 10);
    body
}

/// The body as a C caller gives it: node k of the body is input node `input_of[k]`; every other
/// leaf's corner 0 uses a copy of its node appended at the end; one unused node last: nodes (x y
/// z per node), 0-based topology, node-major displacements.
struct Input {
    nodes: Vec<f64>,
    topology: Vec<i64>,
    u: Vec<f64>,
}

fn input(body: &AdaptiveBody) -> Input {
    let m = body.node_count();
    let input_of = permutation(m, 101, 5);
    let mut positions = vec![DVec3::ZERO; m];
    let mut u = vec![DVec3::ZERO; m];
    for k in 0..m {
        positions[input_of[k]] = body.node_position(k).unwrap();
        u[input_of[k]] = body.displacements()[k];
    }
    let mut topology = Vec::new();
    for c in 0..body.cell_count() {
        let mut corners = body
            .cell_nodes(CellId(c as u32))
            .unwrap()
            .map(|n| input_of[n] as i64);
        if c % 2 == 1 {
            let original = corners[0] as usize;
            corners[0] = positions.len() as i64;
            positions.push(positions[original]);
            u.push(u[original]);
        }
        topology.extend(corners);
    }
    positions.push(DVec3::new(-50.0, 7.0, 3.0));
    u.push(DVec3::new(9.0, 9.0, 9.0));
    Input {
        nodes: positions.iter().flat_map(|p| p.to_array()).collect(),
        topology,
        u: u.iter().flat_map(|v| v.to_array()).collect(),
    }
}

impl Input {
    fn n_nodes(&self) -> usize {
        self.nodes.len() / 3
    }

    fn n_cells(&self) -> usize {
        self.topology.len() / 8
    }

    /// `cgc_body_from_mesh` on these arrays (0-based): the code and the handle.
    fn body(&self, topology: &[i64]) -> (CgcError, *mut CgcBody) {
        let mut body = ptr::null_mut();
        // SAFETY: the arrays hold 3 n_nodes and 8 n_cells values.
        let code = unsafe {
            cgc_body_from_mesh(
                self.nodes.as_ptr(),
                self.n_nodes(),
                topology.as_ptr(),
                topology.len() / 8,
                0,
                &mut body,
            )
        };
        (code, body)
    }
}

/// A body and a locator, freed on drop.
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

impl Handles {
    fn new(input: &Input, strategy: u32, precision: u32) -> Self {
        let (code, body) = input.body(&input.topology);
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        let mut handles = Self {
            body,
            locator: ptr::null_mut(),
        };
        let mut settings = std::mem::MaybeUninit::<CgcSettings>::uninit();
        // SAFETY: valid pointers and lengths; the settings are initialised before use.
        unsafe {
            assert_eq!(
                cgc_settings_init(precision, settings.as_mut_ptr()),
                CgcError::Ok
            );
            let mut settings = settings.assume_init();
            settings.strategy = strategy;
            assert_eq!(handles.set(&input.u, CGC_LAYOUT_NODE_MAJOR), CgcError::Ok);
            assert_eq!(
                cgc_locator_new(handles.body, &settings, &mut handles.locator),
                CgcError::Ok
            );
        }
        handles
    }

    fn set(&self, u: &[f64], layout: u32) -> CgcError {
        // SAFETY: `u` holds 3 n values.
        unsafe { cgc_body_set_displacements(self.body, u.as_ptr(), u.len() / 3, layout) }
    }

    fn locate(&self, points: &[DVec3]) -> (Vec<i64>, Vec<DVec3>) {
        let n = points.len();
        let flat: Vec<f64> = points.iter().flat_map(|p| p.to_array()).collect();
        let (mut cells, mut xi) = (vec![7i64; n], vec![7.0; 3 * n]);
        // SAFETY: the arrays hold n, 3 n values and do not overlap.
        let code = unsafe {
            cgc_locate(
                self.locator,
                flat.as_ptr(),
                n,
                cells.as_mut_ptr(),
                xi.as_mut_ptr(),
                ptr::null_mut(),
            )
        };
        assert_eq!(code, CgcError::Ok, "{}", last_error());
        (cells, xi.chunks(3).map(DVec3::from_slice).collect())
    }
}

/// Points at known (leaf, ξ) inside every leaf, then a spread of points in and around the body.
fn points(body: &AdaptiveBody) -> (Vec<DVec3>, usize) {
    let mut points: Vec<DVec3> = (0..body.cell_count())
        .map(|c| {
            let t = c as f64 * 0.61;
            let xi = DVec3::new(t.sin(), (1.7 * t).cos(), (0.3 + t).sin()) * 0.9;
            body.point_at(CellId(c as u32), xi).unwrap()
        })
        .collect();
    let known = points.len();
    let (low, high) = (DVec3::new(0.3, -1.2, 1.8), DVec3::new(2.5, 0.2, 3.0));
    for k in 0..4000u32 {
        let f = |m: f64| (f64::from(k) * m).fract();
        points.push(low + (high - low) * DVec3::new(f(0.618_034), f(0.754_878), f(0.569_840)));
    }
    (points, known)
}

/// The Rust library's answers for `points`: (leaf or −1, ξ).
fn answers(search: &dyn Locator, points: &[DVec3]) -> Vec<(i64, DVec3)> {
    let mut out = Vec::new();
    search.locate_all_into(points, &mut out);
    out.into_iter()
        .map(|a| match a.unwrap() {
            Some(hit) => (i64::from(hit.cell.0), hit.xi),
            None => (-1, DVec3::NAN),
        })
        .collect()
}

/// Answers as bit patterns, so that NaN compares equal to NaN.
fn bits(answers: &(Vec<i64>, Vec<DVec3>)) -> (Vec<i64>, Vec<[u64; 3]>) {
    let xi = answers.1.iter().map(|x| x.to_array().map(f64::to_bits));
    (answers.0.clone(), xi.collect())
}

fn assert_same(capi: &(Vec<i64>, Vec<DVec3>), expected: &[(i64, DVec3)], tol: f64) {
    for (i, &(cell, xi)) in expected.iter().enumerate() {
        assert_eq!(capi.0[i], cell, "point {i}");
        if cell >= 0 {
            let off = (capi.1[i] - xi).abs().max_element();
            assert!(off <= tol, "point {i}: ξ off by {off:e}");
        } else {
            assert!(capi.1[i].is_nan());
        }
    }
}

#[test]
fn shuffled_adaptive_mesh_answers_as_the_adaptive_locator() {
    let body = scene();
    let input = input(&body);
    let (points, known) = points(&body);
    let expected = answers(
        &AdaptiveLocator::new(&body, Settings::default()).unwrap(),
        &points,
    );
    assert!(
        expected[..known]
            .iter()
            .enumerate()
            .all(|(c, a)| a.0 == c as i64)
    );
    let inside = expected.iter().filter(|a| a.0 >= 0).count();
    assert!(inside > 1000 && inside < points.len() - 500, "{inside}");

    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    let mut n = 0;
    // SAFETY: valid handle and outputs.
    unsafe {
        assert_eq!(cgc_body_node_count(handles.body, &mut n), CgcError::Ok);
        assert_eq!(n, input.n_nodes());
        assert_eq!(cgc_body_hanging_count(handles.body, &mut n), CgcError::Ok);
    }
    assert_eq!(n, body.hanging_nodes().count());
    let capi = handles.locate(&points);
    assert_same(&capi, &expected, 1e-12);

    // Component-major, the same field: the same answers, bitwise.
    let m = input.n_nodes();
    let component_major: Vec<f64> = (0..3)
        .flat_map(|a| (0..m).map(move |k| (a, k)))
        .map(|(a, k)| input.u[3 * k + a])
        .collect();
    assert_eq!(
        handles.set(&component_major, CGC_LAYOUT_COMPONENT_MAJOR),
        CgcError::Ok
    );
    assert_eq!(bits(&handles.locate(&points)), bits(&capi));

    // Brute force over the same leaves: the same cells.
    let brute = Handles::new(&input, CGC_STRATEGY_BRUTE, CGC_PRECISION_F64);
    let oracle = answers(
        &BruteForce::new(&body, Settings::default()).unwrap(),
        &points,
    );
    assert_same(&brute.locate(&points), &oracle, 1e-12);
    assert_same(&capi, &oracle, 1e-12);

    // f32: the known points' cells, ξ to 1e-4.
    let f32 = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F32);
    assert_same(&f32.locate(&points[..known]), &expected[..known], 1e-4);
}

#[test]
fn points_at_hanging_nodes_are_found_in_a_leaf_that_has_them() {
    let body = scene();
    let input = input(&body);
    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    let hanging: Vec<usize> = body.hanging_nodes().collect();
    let points: Vec<DVec3> = hanging
        .iter()
        .map(|&n| body.node_position(n).unwrap() + body.displacements()[n])
        .collect();
    let (cells, xi) = handles.locate(&points);
    for (i, &x) in points.iter().enumerate() {
        assert!(cells[i] >= 0, "hanging node {} not found", hanging[i]);
        let back = body.point_at(CellId(cells[i] as u32), xi[i]).unwrap();
        assert!((back - x).abs().max_element() < 1e-12, "point {i}");
    }
}

#[test]
fn hanging_nodes_off_their_constraint_are_refused_or_filled() {
    let body = scene();
    let input = input(&body);
    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    let (points, _) = points(&body);
    let before = handles.locate(&points);
    let hanging: Vec<usize> = body.hanging_nodes().collect();

    // The input nodes at body node k (duplicates included), ascending: the first is named.
    let at = |k: usize| -> Vec<usize> {
        let x = body.node_position(k).unwrap().to_array();
        (0..input.n_nodes())
            .filter(|&n| input.nodes[3 * n..3 * n + 3] == x)
            .collect()
    };
    let moved = |u: &mut [f64], k: usize, axis: usize, by: f64| {
        for n in at(k) {
            u[3 * n + axis] += by;
        }
        at(k)[0]
    };
    // One hanging node 1e-3 off (its input number named), another a rounding error off (passes).
    let mut u = input.u.clone();
    let bad = moved(&mut u, hanging[3], 1, 1e-3);
    moved(&mut u, hanging[8], 0, 1e-17);
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR),
        CgcError::HangingConstraint
    );
    let message = last_error();
    assert!(
        message.contains(&format!("1 of {} hanging nodes", hanging.len()))
            && message.contains(&format!("node {bad} (0-based)"))
            && message.contains("1.000e-3")
            && message.contains("CGC_FILL_HANGING"),
        "{message}"
    );
    assert_eq!(
        bits(&handles.locate(&points)),
        bits(&before),
        "a refused update changes nothing"
    );

    // Two off: counted, the worst named.
    let worse = moved(&mut u, hanging[5], 2, -0.01);
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR),
        CgcError::HangingConstraint
    );
    assert!(
        last_error().contains("2 of") && last_error().contains(&format!("node {worse} (0-based)")),
        "{}",
        last_error()
    );

    // Filled instead: the values given at hanging nodes are ignored, whatever they are.
    for &k in &hanging {
        for n in at(k) {
            u[3 * n] = 1e3;
        }
    }
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR | CGC_FILL_HANGING),
        CgcError::Ok,
        "{}",
        last_error()
    );
    let after = handles.locate(&points);
    same_answers(&after, &before);

    // A NaN is refused even where it would be filled; a bad layout too.
    u[3 * bad] = f64::NAN;
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR | CGC_FILL_HANGING),
        CgcError::NonFinite
    );
    assert!(
        last_error().contains(&format!("node {bad}")),
        "{}",
        last_error()
    );
    assert_eq!(handles.set(&input.u, 4), CgcError::InvalidArgument);
    assert_eq!(
        handles.set(&input.u[3..], CGC_LAYOUT_NODE_MAJOR),
        CgcError::LengthMismatch
    );
    assert_eq!(bits(&handles.locate(&points)), bits(&after));
}

/// With `CGC_FILL_HANGING` the values given at hanging nodes are ignored (finite is all the header
/// asks), but one beyond the body's displacement limit was refused as "too large", naming a node
/// whose value the call was about to replace.
#[test]
fn filled_hanging_nodes_may_hold_any_finite_value() {
    let body = scene();
    let input = input(&body);
    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    let (points, _) = points(&body);
    let before = handles.locate(&points);
    let mut u = input.u.clone();
    for k in body.hanging_nodes() {
        let x = body.node_position(k).unwrap().to_array();
        for n in (0..input.n_nodes()).filter(|&n| input.nodes[3 * n..3 * n + 3] == x) {
            u[3 * n..3 * n + 3].copy_from_slice(&[1e300, -1e300, f64::MAX]);
        }
    }
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR | CGC_FILL_HANGING),
        CgcError::Ok,
        "{}",
        last_error()
    );
    same_answers(&handles.locate(&points), &before);
    // Without the flag the same values are checked, and refused.
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR),
        CgcError::HangingConstraint,
        "{}",
        last_error()
    );
}

#[test]
fn duplicated_nodes_must_agree_on_adaptive_meshes() {
    let body = scene();
    let input = input(&body);
    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    // The last duplicate (appended before the unused node) moved alone.
    let duplicate = input.n_nodes() - 2;
    let mut u = input.u.clone();
    u[3 * duplicate] += 1e-3;
    assert_eq!(
        handles.set(&u, CGC_LAYOUT_NODE_MAJOR | CGC_FILL_HANGING),
        CgcError::NotLattice
    );
    assert!(
        last_error().contains(&format!("{duplicate} (0-based) coincide")),
        "{}",
        last_error()
    );
}

#[test]
fn bad_adaptive_meshes_are_refused_naming_the_cell() {
    let body = scene();
    let mut input = input(&body);
    let e = input.n_cells();
    let (lattice, h) = (*body.lattice(), body.lattice().h());
    // A cube of 8 new nodes at `low` with edges `edge`, appended as cell e.
    let cube = |input: &mut Input, low: DVec3, edge: DVec3| -> Vec<i64> {
        let first = input.n_nodes() as i64;
        for offset in cgcontact::CORNER_OFFSETS {
            let p = low + edge * DVec3::new(offset[0] as f64, offset[1] as f64, offset[2] as f64);
            input.nodes.extend(p.to_array());
        }
        let mut topology = input.topology.clone();
        topology.extend(first..first + 8);
        topology
    };
    // The parent of refined leaves listed beside them: an overlap.
    let parent = cube(&mut input, lattice.origin() + h * DVec3::X, h);
    // Level 1 (edges h/2) but shifted by a level-2 step: not aligned to its level's lattice.
    let shifted = cube(
        &mut input,
        lattice.origin() + h * DVec3::new(0.25, 0.0, 0.0),
        h / 2.0,
    );
    // Edges 0.75 h: no level's size.
    let odd = cube(&mut input, lattice.origin(), h * 0.75);
    let mut swapped = input.topology.clone();
    let level2 = (0..e)
        .find(|&c| body.leaves().get(c).expect("a leaf of the body").level == 2)
        .unwrap();
    swapped.swap(8 * level2 + 1, 8 * level2 + 2);
    for (topology, what) in [
        (parent, format!("and {e} overlap")),
        (shifted, format!("cell {e}")),
        (odd, format!("cell {e}")),
        (swapped, format!("cell {level2}")),
    ] {
        let (code, handle) = input.body(&topology);
        assert_eq!(code, CgcError::NotLattice, "{what}: {}", last_error());
        assert!(handle.is_null());
        assert!(last_error().contains(&what), "{what}: {}", last_error());
    }
}

/// The unused node last in the input, at NaN or infinity: refused as a used one would be.
#[test]
fn a_non_finite_unused_node_of_an_adaptive_mesh_is_refused() {
    let body = scene();
    let mut input = input(&body);
    let last = input.n_nodes() - 1;
    let (code, handle) = input.body(&input.topology);
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    // SAFETY: a live handle, freed once.
    unsafe { cgc_body_free(handle) };
    for value in [f64::NAN, f64::INFINITY] {
        input.nodes[3 * last + 1] = value;
        let (code, handle) = input.body(&input.topology);
        assert_eq!(code, CgcError::NonFinite, "{value}: {}", last_error());
        assert!(handle.is_null());
        assert!(
            last_error().contains(&format!("node {last} (0-based)")),
            "{}",
            last_error()
        );
    }
}

/// `cgc_gap` on the shuffled adaptive mesh (hanging faces partly covered, leaves of 3 levels):
/// the adaptive locator's `GapFinder` answers, faces named by the input cell.
#[test]
fn adaptive_mesh_gaps_are_the_gap_finders() {
    let body = scene();
    let input = input(&body);
    let (points, _) = points(&body);
    let distance = 0.2;
    let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
    let mut expected = Vec::new();
    GapFinder::new(&locator, distance)
        .unwrap()
        .gap_all_into(&points, &mut expected);
    let handles = Handles::new(&input, CGC_STRATEGY_LATTICE, CGC_PRECISION_F64);
    let n = points.len();
    let flat: Vec<f64> = points.iter().flat_map(|p| p.to_array()).collect();
    let (mut gap, mut closest, mut normal) = (vec![7.0; n], vec![7.0; 3 * n], vec![7.0; 3 * n]);
    let (mut face_cell, mut face) = (vec![7i64; n], vec![7i32; n]);
    // SAFETY: the arrays hold n or 3 n values and do not overlap.
    let code = unsafe {
        cgc_gap(
            handles.locator,
            flat.as_ptr(),
            n,
            distance,
            gap.as_mut_ptr(),
            closest.as_mut_ptr(),
            normal.as_mut_ptr(),
            face_cell.as_mut_ptr(),
            face.as_mut_ptr(),
        )
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    // The body detected from the input's nodes may differ from `body` by a rounding of the
    // lattice, as in `shuffled_adaptive_mesh_answers_as_the_adaptive_locator`: 1e-12, not bits.
    let (mut inside, mut near, mut far) = (0, 0, 0);
    for (i, answer) in expected.iter().enumerate() {
        let at = |v: &[f64]| DVec3::from_slice(&v[3 * i..3 * i + 3]);
        match answer {
            Ok(Some(c)) => {
                assert!(
                    (gap[i] - c.gap).abs() < 1e-12,
                    "point {i}: {} vs {}",
                    gap[i],
                    c.gap
                );
                assert!((at(&closest) - c.point).length() < 1e-12, "point {i}");
                assert!((at(&normal) - c.normal).length() < 1e-9, "point {i}");
                // Leaf c is input cell c (`input` lists the body's leaves in order).
                assert_eq!(face_cell[i], i64::from(c.face.cell.0), "point {i}");
                assert_eq!(face[i], i32::from(c.face.local), "point {i}");
                if c.gap < 0.0 {
                    inside += 1;
                } else {
                    near += 1;
                }
            }
            Ok(None) => {
                assert!(gap[i].is_nan() && at(&closest).is_nan() && at(&normal).is_nan());
                assert_eq!((face_cell[i], face[i]), (-1, -1), "point {i}");
                far += 1;
            }
            Err(e) => panic!("point {i}: {e}"),
        }
    }
    assert!(
        inside > 300 && near > 300 && far > 300,
        "{inside} {near} {far}"
    );
}

/// `after` answers as `before`: the same cells, ξ within 1e-12 wherever found.
fn same_answers(after: &(Vec<i64>, Vec<DVec3>), before: &(Vec<i64>, Vec<DVec3>)) {
    assert_eq!(after.0, before.0);
    let off = after
        .1
        .iter()
        .zip(&before.1)
        .filter(|(a, _)| !a.is_nan())
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0, f64::max);
    assert!(off < 1e-12, "ξ off by {off:e}");
}
