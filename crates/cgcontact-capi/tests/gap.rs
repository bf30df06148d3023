//! `cgc_gap` called as C would call it: answers checked against gaps known by construction (a
//! translated block) and against the Rust library's `GapFinder`, bitwise; cells numbered as the
//! caller's mesh; every bad input answered with its error code.
//! (The adaptive body's gaps are checked in `adaptive.rs`, beside its scene.)

use std::ffi::CStr;
use std::ptr;

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId, GapAnswer, GapFinder, Lattice, LatticeLocator, Settings};
use cgcontact_capi::*;
use cgcontact_io::HexMesh;

fn last_error() -> String {
    // SAFETY: cgc_last_error returns a NUL-terminated string owned by this thread.
    unsafe { CStr::from_ptr(cgc_last_error()) }
        .to_string_lossy()
        .into_owned()
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
    /// A lattice body over every cell of `lattice`, each node displaced by `u(x)`.
    fn lattice(lattice: &Lattice, u: impl Fn(DVec3) -> DVec3) -> Self {
        let (origin, h, counts) = (
            lattice.origin().to_array(),
            lattice.h().to_array(),
            lattice.cells(),
        );
        let mut handles = Self {
            body: ptr::null_mut(),
            locator: ptr::null_mut(),
        };
        let n = lattice.node_count();
        let dense: Vec<f64> = (0..n)
            .flat_map(|k| u(lattice.node_position(lattice.node_ijk(k).unwrap())).to_array())
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
}

/// `Gaps` with the doubles as bit patterns.
type Bits<'a> = (Vec<u64>, Vec<u64>, Vec<u64>, &'a [i64], &'a [i32]);

/// Every output of `cgc_gap`, prefilled with values no answer has.
#[derive(Debug)]
struct Gaps {
    gap: Vec<f64>,
    closest: Vec<f64>,
    normal: Vec<f64>,
    face_cell: Vec<i64>,
    face: Vec<i32>,
}

impl Gaps {
    fn new(n: usize) -> Self {
        Self {
            gap: vec![7.0; n],
            closest: vec![7.0; 3 * n],
            normal: vec![7.0; 3 * n],
            face_cell: vec![7; n],
            face: vec![7; n],
        }
    }

    /// What `cgc_gap` must write for the library's `answers`, cells numbered by `number`.
    fn expected(answers: &[GapAnswer], number: impl Fn(CellId) -> i64) -> Self {
        let mut out = Self::new(0);
        for answer in answers {
            let (gap, point, normal, cell, face) = match answer {
                Ok(Some(c)) => (
                    c.gap,
                    c.point,
                    c.normal,
                    number(c.face.cell),
                    i32::from(c.face.local),
                ),
                _ => (f64::NAN, DVec3::NAN, DVec3::NAN, -1, -1),
            };
            out.gap.push(gap);
            out.closest.extend(point.to_array());
            out.normal.extend(normal.to_array());
            out.face_cell.push(cell);
            out.face.push(face);
        }
        out
    }

    /// Bit patterns, so that NaN compares equal to NaN.
    fn bits(&self) -> Bits<'_> {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (
            bits(&self.gap),
            bits(&self.closest),
            bits(&self.normal),
            &self.face_cell,
            &self.face,
        )
    }
}

fn flat(v: &[DVec3]) -> Vec<f64> {
    v.iter().flat_map(|p| p.to_array()).collect()
}

/// `cgc_gap` with every output.
fn gaps(locator: *const CgcLocator, points: &[DVec3], distance: f64) -> (CgcError, Gaps) {
    let n = points.len();
    let points = flat(points);
    let mut out = Gaps::new(n);
    // SAFETY: the arrays hold n or 3 n values and do not overlap.
    let code = unsafe {
        cgc_gap(
            locator,
            points.as_ptr(),
            n,
            distance,
            out.gap.as_mut_ptr(),
            out.closest.as_mut_ptr(),
            out.normal.as_mut_ptr(),
            out.face_cell.as_mut_ptr(),
            out.face.as_mut_ptr(),
        )
    };
    (code, out)
}

/// A 6 × 5 × 4 block with a smooth displacement of up to about 0.4 h (as `capi.rs`).
fn block() -> Body {
    let lattice = Lattice::new(
        DVec3::new(1.0, -2.0, 0.5),
        DVec3::new(0.5, 0.25, 0.4),
        [6, 5, 4],
    )
    .unwrap();
    let mut body = Body::full(lattice);
    body.update_displacements(|_, x, u| *u = field(x)).unwrap();
    body
}

fn field(x: DVec3) -> DVec3 {
    DVec3::new(
        0.05 * (x.y * 3.0).sin(),
        0.03 * x.x * x.z,
        -0.1 * (x.x - 1.0) * (x.z - 0.5),
    )
}

/// 6,000 points spread over the block's box grown by 0.5 on each side: inside, near outside and
/// beyond a search distance of 0.3.
fn spread(body: &Body) -> Vec<DVec3> {
    let (low, high) = (body.lattice().origin() - 0.5, body.lattice().upper() + 0.5);
    (0..6000u32)
        .map(|k| {
            let f = |m: f64| (f64::from(k) * m).fract();
            low + (high - low) * DVec3::new(f(0.618_034), f(0.754_878), f(0.569_840))
        })
        .collect()
}

#[test]
fn lattice_body_gaps_are_the_gap_finders_bitwise() {
    let body = block();
    let points = spread(&body);
    let handles = Handles::lattice(body.lattice(), field);
    let (code, got) = gaps(handles.locator, &points, 0.3);
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let mut answers = Vec::new();
    GapFinder::new(&locator, 0.3)
        .unwrap()
        .gap_all_into(&points, &mut answers);
    let expected = Gaps::expected(&answers, |c| i64::from(c.0));
    assert_eq!(got.bits(), expected.bits());
    // The spread reaches every case: inside, outside within the distance, beyond it.
    let inside = got.gap.iter().filter(|g| **g < 0.0).count();
    let near = got.gap.iter().filter(|g| **g > 0.0).count();
    let far = got.gap.iter().filter(|g| g.is_nan()).count();
    assert!(
        inside > 500 && near > 500 && far > 500,
        "{inside} {near} {far}"
    );
    for (i, &point) in points.iter().enumerate() {
        if got.gap[i].is_nan() {
            assert_eq!((got.face_cell[i], got.face[i]), (-1, -1), "point {i}");
            assert!(got.closest[3 * i..3 * i + 3].iter().all(|v| v.is_nan()));
            assert!(got.normal[3 * i..3 * i + 3].iter().all(|v| v.is_nan()));
        } else {
            // x = closest + gap · normal, the face one of the body's.
            let x = DVec3::from_slice(&got.closest[3 * i..])
                + got.gap[i] * DVec3::from_slice(&got.normal[3 * i..]);
            assert!((x - point).length() < 1e-9, "point {i}");
            assert!((0..120).contains(&got.face_cell[i]) && (0..6).contains(&got.face[i]));
        }
    }
}

/// A 2 × 2 × 2 block of unit cells translated by (0, 0, 0.1): gaps, closest points, normals and
/// faces known without the library.
#[test]
fn translated_block_gaps_are_known() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap();
    let handles = Handles::lattice(&lattice, |_| DVec3::new(0.0, 0.0, 0.1));
    let points = [
        DVec3::new(0.5, 0.5, 2.4),   // 0.3 above the top face of cell (0, 0, 1)
        DVec3::new(1.5, 0.5, 1.9),   // 0.2 below the top of cell (1, 0, 1)
        DVec3::new(-0.25, 1.5, 0.6), // 0.25 beyond the face x = 0 of cell (0, 1, 0)
        DVec3::new(2.2, 2.3, 2.5),   // 0.5 from the corner (2, 2, 2.1): beyond 0.4
        DVec3::new(2.2, 2.2, 2.3),   // 0.3 from that corner, along (1, 1, 1)
    ];
    let (code, got) = gaps(handles.locator, &points, 0.4);
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let close = |a: &[f64], b: [f64; 3]| (DVec3::from_slice(a) - DVec3::from(b)).length() < 1e-12;
    let expect = [
        (0.3, [0.5, 0.5, 2.1], [0.0, 0.0, 1.0], 4, 5),
        (-0.2, [1.5, 0.5, 2.1], [0.0, 0.0, 1.0], 5, 5),
        (0.25, [0.0, 1.5, 0.6], [-1.0, 0.0, 0.0], 2, 0),
    ];
    for (i, &(gap, closest, normal, cell, face)) in expect.iter().enumerate() {
        assert!(
            (got.gap[i] - gap).abs() < 1e-12,
            "point {i}: {}",
            got.gap[i]
        );
        assert!(
            close(&got.closest[3 * i..3 * i + 3], closest),
            "point {i}: {got:?}"
        );
        assert!(
            close(&got.normal[3 * i..3 * i + 3], normal),
            "point {i}: {got:?}"
        );
        assert_eq!((got.face_cell[i], got.face[i]), (cell, face), "point {i}");
    }
    assert!(got.gap[3].is_nan() && got.closest[9..12].iter().all(|v| v.is_nan()));
    assert_eq!((got.face_cell[3], got.face[3]), (-1, -1));
    let corner = DVec3::new(2.0, 2.0, 2.1);
    assert!((got.gap[4] - (points[4] - corner).length()).abs() < 1e-12);
    assert!(close(&got.closest[12..15], corner.to_array()));
    assert!(close(
        &got.normal[12..15],
        (points[4] - corner).normalize().to_array()
    ));
    assert_eq!(got.face_cell[4], 7, "the corner's only cell");
}

/// The same body given as a mesh, cells listed in reverse: `face_cell` names the mesh's cell, as
/// `cgc_locate` does.
#[test]
fn mesh_body_names_the_mesh_cell_of_each_face() {
    let body = block();
    let points = spread(&body);
    let mesh = HexMesh::from_body(&body);
    let (m, e) = (mesh.points.len(), mesh.cells.len());
    let topology: Vec<i64> = mesh
        .cells
        .iter()
        .rev()
        .flat_map(|c| c.map(i64::from))
        .collect();
    let u = flat(mesh.displacement.as_ref().unwrap());
    let nodes = flat(&mesh.points);
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
                0,
                &mut handles.body
            ),
            CgcError::Ok,
            "{}",
            last_error()
        );
        assert_eq!(
            cgc_body_set_displacements(handles.body, u.as_ptr(), m, CGC_LAYOUT_NODE_MAJOR),
            CgcError::Ok
        );
        assert_eq!(
            cgc_locator_new(handles.body, ptr::null(), &mut handles.locator),
            CgcError::Ok
        );
    }
    let (code, got) = gaps(handles.locator, &points, 0.3);
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let mut answers = Vec::new();
    GapFinder::new(&locator, 0.3)
        .unwrap()
        .gap_all_into(&points, &mut answers);
    // from_body lists cells ascending by lattice cell, and the topology reversed them.
    let expected = Gaps::expected(&answers, |c| (e - 1 - c.0 as usize) as i64);
    assert_eq!(got.bits(), expected.bits());
}

#[test]
fn outputs_may_be_null_and_threads_do_not_change_answers() {
    let body = block();
    let points = spread(&body);
    let all = gaps(
        Handles::lattice(body.lattice(), field).locator,
        &points,
        0.3,
    )
    .1;
    let mut handles = Handles::lattice(body.lattice(), field);
    let mut settings = std::mem::MaybeUninit::<CgcSettings>::uninit();
    // SAFETY: valid pointers; the settings are initialised before use; the old locator is freed once.
    unsafe {
        assert_eq!(
            cgc_settings_init(CGC_PRECISION_F64, settings.as_mut_ptr()),
            CgcError::Ok
        );
        let mut settings = settings.assume_init();
        settings.threads = 3;
        cgc_locator_free(handles.locator);
        handles.locator = ptr::null_mut();
        assert_eq!(
            cgc_locator_new(handles.body, &settings, &mut handles.locator),
            CgcError::Ok
        );
    }
    assert_eq!(gaps(handles.locator, &points, 0.3).1.bits(), all.bits());
    // Only the gaps and the faces.
    let flat = flat(&points);
    let mut gap = vec![7.0; points.len()];
    let mut face = vec![7i32; points.len()];
    // SAFETY: the arrays hold n values; NULL outputs are skipped.
    let code = unsafe {
        cgc_gap(
            handles.locator,
            flat.as_ptr(),
            points.len(),
            0.3,
            gap.as_mut_ptr(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            face.as_mut_ptr(),
        )
    };
    assert_eq!(code, CgcError::Ok, "{}", last_error());
    assert_eq!(
        gap.iter().map(|g| g.to_bits()).collect::<Vec<_>>(),
        all.bits().0
    );
    assert_eq!(face, all.face);
    // No output at all: nothing to write, still a success.
    // SAFETY: NULL outputs are skipped.
    let code = unsafe {
        cgc_gap(
            handles.locator,
            flat.as_ptr(),
            points.len(),
            0.3,
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        )
    };
    assert_eq!(code, CgcError::Ok);
}

#[test]
fn bad_arguments_are_error_codes_and_write_nothing() {
    let body = block();
    let handles = Handles::lattice(body.lattice(), field);
    let points = spread(&body)[..10].to_vec();
    // Beyond 1e150 too: finite, but refused by the search (its square would overflow), which the
    // header did not say.
    // Large ones with an exponent, not all their digits (309 for f64::MAX).
    for (distance, shown) in [
        (-0.1, "-0.1"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
        (1e151, "1e151"),
        (f64::MAX, "1.7976931348623157e308"),
    ] {
        let (code, got) = gaps(handles.locator, &points, distance);
        assert_eq!(code, CgcError::InvalidArgument, "distance {distance}");
        assert!(
            last_error().starts_with(&format!("distance is {shown};")),
            "{}",
            last_error()
        );
        assert_eq!(got.bits(), Gaps::new(10).bits(), "nothing written");
    }
    assert_eq!(gaps(handles.locator, &points, 1e150).0, CgcError::Ok);
    // A distance of 0: only points on the surface have a gap.
    let (code, got) = gaps(handles.locator, &points, 0.0);
    assert_eq!(code, CgcError::Ok);
    assert!(got.gap.iter().all(|g| g.is_nan()));

    let (code, _) = gaps(ptr::null(), &points, 0.3);
    assert_eq!(code, CgcError::NullPointer);
    assert_eq!(last_error(), "locator is NULL");
    let mut gap = [0.0; 2];
    let misaligned = [0u8; 40];
    // SAFETY: NULL and misaligned pointers are what is tested; nothing is read or written
    // through them.
    unsafe {
        let null_points = cgc_gap(
            handles.locator,
            ptr::null(),
            2,
            0.3,
            gap.as_mut_ptr(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        );
        assert_eq!(null_points, CgcError::NullPointer);
        assert!(
            last_error().starts_with("points is NULL"),
            "{}",
            last_error()
        );
        let flat = flat(&points);
        let odd = cgc_gap(
            handles.locator,
            flat.as_ptr(),
            2,
            0.3,
            gap.as_mut_ptr(),
            misaligned.as_ptr().add(1).cast_mut().cast(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        );
        assert_eq!(odd, CgcError::InvalidArgument);
        assert!(
            last_error().starts_with("closest is not aligned"),
            "{}",
            last_error()
        );
        // No points: nothing to read or write, whatever the pointers.
        let none = cgc_gap(
            handles.locator,
            ptr::null(),
            0,
            0.3,
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
            ptr::null_mut(),
        );
        assert_eq!(none, CgcError::Ok);
    }
}

#[test]
fn non_finite_points_are_answered_and_reported() {
    let body = block();
    let handles = Handles::lattice(body.lattice(), field);
    let mut points = vec![DVec3::new(2.0, -1.5, 1.0); 3000];
    points[2500].x = f64::NAN;
    points[2700].z = f64::INFINITY;
    let (code, got) = gaps(handles.locator, &points, 1.0);
    assert_eq!(code, CgcError::NonFinitePoint);
    assert!(last_error().starts_with("point 2500 "), "{}", last_error());
    for i in [2500, 2700] {
        assert!(got.gap[i].is_nan() && got.closest[3 * i].is_nan() && got.normal[3 * i].is_nan());
        assert_eq!((got.face_cell[i], got.face[i]), (-1, -1));
    }
    // Every other point answered, on both sides of the 2,048-point pieces.
    assert!(got.gap[0] < 0.0 && got.gap[2999] < 0.0 && got.gap[2499] == got.gap[0]);
}

/// On a body whose displacements leave the caches, a batch the library may sort is answered
/// whole, then written piece by piece: each point's gap at its own place, bitwise the gap finder's
/// one-point answers, with the first non-finite point reported.
#[test]
fn large_batches_on_large_bodies_are_answered_whole_and_in_place() {
    let lattice =
        Lattice::new(DVec3::new(-1.0, 2.0, 0.0), DVec3::splat(0.1), [90, 90, 90]).unwrap();
    let u = |x: DVec3| {
        DVec3::new(
            0.02 * (x.y * 2.0).sin(),
            0.01 * x.x * x.z,
            -0.03 * x.x.cos(),
        )
    };
    let mut body = Body::full(lattice);
    body.update_displacements(|_, x, d| *d = u(x)).unwrap();
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.25).unwrap();
    // Points near the faces of the box, inside and out, in a scrambled order, one of them NaN.
    let n = 3 * cgcontact::Schedule::AUTO_MIN_POINTS / 2;
    let (low, high) = (lattice.origin(), lattice.upper());
    let mut points: Vec<DVec3> = (0..n as u32)
        .map(|k| {
            let f = |m: f64| (f64::from(k) * m).fract();
            let mut x = low + (high - low) * DVec3::new(f(0.618_034), f(0.754_878), f(0.569_840));
            // Pull one coordinate within 0.2 of a face, either side.
            let axis = k as usize % 3;
            x[axis] = if k % 2 == 0 { low[axis] } else { high[axis] } + (f(0.3) - 0.5) * 0.4;
            x
        })
        .collect();
    points[7000].z = f64::NAN;
    assert!(finder.sorts_batch(&points), "the library sorts this batch");
    let handles = Handles::lattice(&lattice, u);
    let (code, got) = gaps(handles.locator, &points, 0.25);
    assert_eq!(code, CgcError::NonFinitePoint);
    assert!(last_error().starts_with("point 7000 "), "{}", last_error());
    let answers: Vec<GapAnswer> = points.iter().map(|&x| finder.gap(x)).collect();
    assert_eq!(
        got.bits(),
        Gaps::expected(&answers, |c| i64::from(c.0)).bits()
    );
    let found = got.gap.iter().filter(|g| !g.is_nan()).count();
    assert!(found > n / 2, "{found} gaps of {n}");
}
