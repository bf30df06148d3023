//! The gap search against a brute-force oracle: every boundary face of the body (found by its own
//! definition, sampled across each face on adaptive bodies), each measured by a dense grid of its
//! quad polished by a pattern search (no Newton, no certificate, no closed-form edges).

use bitvec::prelude::*;
use glam::{DVec2, DVec3};

use super::*;
use crate::{
    AdaptiveBody, AdaptiveLocator, Body, Error, Lattice, LatticeLocator, Leaf, Locator,
    MAX_DISPLACEMENT, Settings,
};

/// The oracle's answer for one point.
#[derive(Debug)]
struct Oracle {
    dist: f64,
    point: DVec3,
    /// The face normal at the closest point (outward), when it is inside its face.
    interior_normal: Option<DVec3>,
}

/// A face of the surface for the oracle: deformed corners (world coordinates).
type Quad = [DVec3; 4];

fn bilinear(q: &Quad, st: DVec2) -> DVec3 {
    let (s, t) = (st.x, st.y);
    0.25 * ((1.0 - s) * (1.0 - t) * q[0]
        + (1.0 + s) * (1.0 - t) * q[1]
        + (1.0 + s) * (1.0 + t) * q[2]
        + (1.0 - s) * (1.0 + t) * q[3])
}

/// The outward normal of a quad at `st`, from the shape functions' derivatives.
fn oracle_normal(q: &Quad, st: DVec2) -> DVec3 {
    let (s, t) = (st.x, st.y);
    let ds = 0.25 * (-(1.0 - t) * q[0] + (1.0 - t) * q[1] + (1.0 + t) * q[2] - (1.0 + t) * q[3]);
    let dt = 0.25 * (-(1.0 - s) * q[0] - (1.0 + s) * q[1] + (1.0 + s) * q[2] + (1.0 - s) * q[3]);
    ds.cross(dt).normalize()
}

/// Closest point of one quad: a 48 × 48 grid, then a pattern search down to 1e-15.
fn oracle_quad(x: DVec3, q: &Quad) -> (f64, DVec2) {
    super::quad::grid_oracle(x, |st| bilinear(q, st), 48)
}

/// The closest point over all `faces` (brute force).
fn oracle(x: DVec3, faces: &[Quad]) -> Oracle {
    let mut best = (f64::INFINITY, DVec2::ZERO, 0);
    for (i, q) in faces.iter().enumerate() {
        let (d2, st) = oracle_quad(x, q);
        if d2 < best.0 {
            best = (d2, st, i);
        }
    }
    let (d2, st, i) = best;
    let q = &faces[i];
    let interior = st.x.abs() < 1.0 - 1e-9 && st.y.abs() < 1.0 - 1e-9;
    Oracle {
        dist: d2.sqrt(),
        point: bilinear(q, st),
        interior_normal: interior.then(|| oracle_normal(q, st)),
    }
}

/// Boundary faces of a uniform body by the definition: an active cell's face whose neighbour
/// across is outside the lattice or inactive.
fn uniform_faces(body: &Body) -> Vec<Quad> {
    let lattice = body.lattice();
    let n = lattice.cells();
    let mut faces = Vec::new();
    for cell in body.active_cells() {
        let ijk = lattice.cell_ijk(cell).unwrap();
        let corners = body.corners(cell).unwrap();
        for (f, fc) in FACE_CORNERS.iter().enumerate() {
            let axis = f / 2;
            let step: i64 = if f % 2 == 1 { 1 } else { -1 };
            let across = i64::from(ijk[axis]) + step;
            let open = if across < 0 || across >= i64::from(n[axis]) {
                true
            } else {
                let mut other = ijk;
                other[axis] = across as u32;
                !body.is_active(lattice.cell_id(other))
            };
            if open {
                faces.push(fc.map(|c| corners[c]));
            }
        }
    }
    faces
}

/// Boundary faces of an adaptive body by the definition, sampled: each face is cut into its
/// finest-level squares, and a square is open when the point just across its centre is in no
/// leaf. Each open square is the quad through the deformed points (the leaf's trilinear map) of
/// its corners, ordered so that its normal points outwards.
fn adaptive_faces(body: &AdaptiveBody) -> Vec<Quad> {
    let lattice = body.lattice();
    let fine = body.spacing(body.finest_level());
    let upper = lattice.upper();
    let mut faces = Vec::new();
    for (id, leaf) in body.leaves().iter().enumerate() {
        let cell = CellId(id as u32);
        let low = body.leaf_origin(leaf);
        let size = body.spacing(leaf.level);
        let per = 1u32 << (body.finest_level() - leaf.level);
        for f in 0..6 {
            let axis = f / 2;
            let side = if f % 2 == 1 { 1.0 } else { -1.0 };
            let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..per {
                for j in 0..per {
                    let mut p = low;
                    p[a1] += (f64::from(i) + 0.5) * fine[a1];
                    p[a2] += (f64::from(j) + 0.5) * fine[a2];
                    p[axis] += if side > 0.0 {
                        size[axis] + 0.25 * fine[axis]
                    } else {
                        -0.25 * fine[axis]
                    };
                    let outside = p.cmplt(lattice.origin()).any() || p.cmpgt(upper).any();
                    if !(outside || body.leaf_at(p).is_none()) {
                        continue;
                    }
                    let xi = |di: u32, dj: u32| {
                        let mut xi = DVec3::ZERO;
                        xi[axis] = side;
                        xi[a1] = -1.0 + 2.0 * f64::from(i + di) / f64::from(per);
                        xi[a2] = -1.0 + 2.0 * f64::from(j + dj) / f64::from(per);
                        body.point_at(cell, xi).unwrap()
                    };
                    let mut q = [xi(0, 0), xi(1, 0), xi(1, 1), xi(0, 1)];
                    if oracle_normal(&q, DVec2::ZERO)[axis] * side < 0.0 {
                        q.swap(1, 3);
                    }
                    faces.push(q);
                }
            }
        }
    }
    faces
}

/// A smooth displacement field of amplitude `amp` (per unit h).
fn field(x: DVec3, h: DVec3, amp: f64) -> DVec3 {
    let y = x / h;
    DVec3::new(
        (0.7 * y.x + 1.3 * y.y).sin(),
        (0.9 * y.y - 0.4 * y.z).cos(),
        (0.5 * y.z + 0.8 * y.x).sin(),
    ) * h
        * amp
}

/// A uniform body 5 × 4 × 3 with a step (a concave edge and corner) and a hole, displaced.
fn stepped_body(origin: DVec3, h: DVec3, amp: f64) -> Body {
    let lattice = Lattice::new(origin, h, [5, 4, 3]).unwrap();
    let mut active = bitvec![1; lattice.cell_count()];
    for k in 0..3u32 {
        for j in 0..4u32 {
            for i in 0..5u32 {
                // The step: the upper layer only over i < 3; a hole through the middle.
                let step = k == 2 && i >= 3;
                let hole = i == 1 && j == 2;
                if step || hole {
                    active.set(lattice.cell_id([i, j, k]).index(), false);
                }
            }
        }
    }
    // The field is a function of the position relative to the origin: offset bodies move alike.
    let dense: Vec<DVec3> = (0..lattice.node_count())
        .map(|n| {
            field(
                lattice.node_position(lattice.node_ijk(n).unwrap()) - origin,
                h,
                amp,
            )
        })
        .collect();
    Body::from_dense(lattice, active, &dense).unwrap()
}

/// Deterministic points in the box [low, high].
fn points_in(low: DVec3, high: DVec3, count: usize, mut seed: u64) -> Vec<DVec3> {
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..count)
        .map(|_| low + (high - low) * DVec3::new(next(), next(), next()))
        .collect()
}

/// Checks every point's answer against the oracle: the gap and the closest point within 1e-10·h,
/// the normal within 1e-8 (against the face's where the closest point is inside a face), the
/// sign against the locator, `None` beyond the distance; and x = c + gap·n.
fn check(finder: &GapFinder<'_, impl Surface>, faces: &[Quad], points: &[DVec3], h: f64) {
    let d = finder.distance();
    let (mut found, mut none, mut interior, mut boundary, mut negative) = (0, 0, 0, 0, 0);
    for (i, &x) in points.iter().enumerate() {
        let want = oracle(x, faces);
        let got = finder.gap(x).unwrap();
        // Points within rounding of the search distance may go either way.
        if (want.dist - d).abs() < 1e-9 * h {
            continue;
        }
        let Some(c) = got else {
            assert!(
                want.dist > d,
                "point {i} {x}: None, but the surface is {} away (D = {d})",
                want.dist
            );
            none += 1;
            continue;
        };
        assert!(want.dist <= d, "point {i}: found beyond D: {c:?}");
        found += 1;
        assert!(
            (c.gap.abs() - want.dist).abs() <= 1e-10 * h,
            "point {i} {x}: |gap| {} against the oracle's {}",
            c.gap.abs(),
            want.dist
        );
        // The closest point is unique unless two faces tie: compare it where the oracle's is.
        let along = (c.point - want.point).length();
        assert!(
            along <= 1e-10 * h || (c.point - x).length() - want.dist <= 1e-10 * h,
            "point {i}: closest point {} against the oracle's {}",
            c.point,
            want.point
        );
        let held = finder.surface.locate(x).unwrap().is_some();
        assert_eq!(
            c.gap < 0.0,
            held && c.gap != 0.0,
            "point {i}: sign of {}",
            c.gap
        );
        if c.gap < 0.0 {
            negative += 1;
        }
        assert!((c.normal.length() - 1.0).abs() < 1e-12, "point {i}: |n|");
        assert!(
            (c.point + c.gap * c.normal - x).length() <= 1e-9 * h,
            "point {i}: x != c + gap n: {x} {c:?} {want:?}"
        );
        if c.interior {
            interior += 1;
            if let (Some(n), true) = (want.interior_normal, along <= 1e-9 * h) {
                assert!(
                    (c.normal - n).length() < 1e-8,
                    "point {i}: normal {} against {n}",
                    c.normal
                );
            }
        } else {
            boundary += 1;
        }
        // The warm start answers the same.
        let warm = finder.regap(x, &Ok(Some(c))).unwrap().unwrap();
        assert!((warm.gap - c.gap).abs() <= 1e-12 * h, "point {i}: warm gap");
    }
    // The scenes exercise every case.
    assert!(found > 20 && none > 0, "found {found}, none {none}");
    assert!(
        interior > 0 && boundary > 0 && negative > 0,
        "interior {interior}, edges and corners {boundary}, inside {negative}"
    );
}

#[test]
fn uniform_body_against_the_oracle() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let body = stepped_body(DVec3::new(-1.0, 2.0, 0.5), h, 0.08);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.6).unwrap();
    let faces = uniform_faces(&body);
    let lattice = body.lattice();
    let points = points_in(lattice.origin() - 0.8, lattice.upper() + 0.8, 400, 0x5eed);
    check(&finder, &faces, &points, h.min_element());
}

#[test]
fn huge_offsets_answer_as_at_the_origin() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let offset = DVec3::new(1e6, -3e6, 2e6);
    let near = stepped_body(DVec3::ZERO, h, 0.08);
    let far = stepped_body(offset, h, 0.08);
    let near_locator = LatticeLocator::new(&near, Settings::default()).unwrap();
    let far_locator = LatticeLocator::new(&far, Settings::default()).unwrap();
    let near_finder = GapFinder::new(&near_locator, 0.6).unwrap();
    let far_finder = GapFinder::new(&far_locator, 0.6).unwrap();
    let points = points_in(DVec3::splat(-0.5), near.lattice().upper() + 0.5, 300, 0xfa2);
    let mut compared = 0;
    for &x in &points {
        let a = near_finder.gap(x).unwrap();
        let b = far_finder.gap(x + offset).unwrap();
        match (a, b) {
            (Some(a), Some(b)) => {
                // The coordinates' own rounding at 3e6 is 5e-10: the answers agree to that.
                assert!((a.gap - b.gap).abs() < 1e-8, "{} against {}", a.gap, b.gap);
                assert!((a.point + offset - b.point).length() < 1e-8);
                compared += 1;
            }
            (None, None) => {}
            (a, b) => {
                let d = a.or(b).unwrap().gap.abs();
                assert!((d - 0.6).abs() < 1e-8, "{a:?} against {b:?}");
            }
        }
    }
    assert!(compared > 100);
}

#[test]
fn points_on_the_surface_have_gap_zero() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let body = stepped_body(DVec3::new(3.0, 1.0, -2.0), h, 0.08);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.1).unwrap();
    let faces = uniform_faces(&body);
    let mut checked = 0;
    for (i, q) in faces.iter().enumerate() {
        for st in [DVec2::new(0.3, -0.6), DVec2::new(1.0, 0.2), DVec2::ONE] {
            let x = bilinear(q, st);
            let c = finder.gap(x).unwrap().expect("on the surface");
            assert!(c.gap.abs() <= 1e-12, "face {i} at {st}: gap {}", c.gap);
            assert!((c.point - x).length() <= 1e-12);
            checked += 1;
        }
    }
    assert!(checked > 100);
}

#[test]
fn nearest_face_changes_along_a_line() {
    // A line passing over the step's convex and concave edges, just above the surface.
    let h = DVec3::new(0.5, 0.7, 0.3);
    let body = stepped_body(DVec3::ZERO, h, 0.03);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 1.0).unwrap();
    let faces = uniform_faces(&body);
    let points: Vec<DVec3> = (0..=120)
        .map(|i| DVec3::new(-0.4 + 3.3 * f64::from(i) / 120.0, 0.35, 0.98))
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    for &x in &points {
        let c = finder.gap(x).unwrap().unwrap();
        let want = oracle(x, &faces);
        assert!((c.gap.abs() - want.dist).abs() <= 1e-10 * 0.3, "{x}");
        seen.insert((c.face.local, c.interior));
    }
    assert!(
        seen.len() >= 3,
        "the line crosses several faces and edges: {seen:?}"
    );
}

#[test]
fn far_and_deep_points_are_none_and_bad_points_refused() {
    let h = DVec3::splat(1.0);
    let lattice = Lattice::new(DVec3::ZERO, h, [6, 6, 6]).unwrap();
    let body = Body::full(lattice);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 1.0).unwrap();
    assert_eq!(finder.gap(DVec3::splat(3.0)), Ok(None), "deep inside");
    assert_eq!(finder.gap(DVec3::new(3.0, 3.0, 8.5)), Ok(None), "far above");
    let c = finder.gap(DVec3::new(3.0, 3.0, 5.25)).unwrap().unwrap();
    assert!((c.gap + 0.75).abs() < 1e-15 && c.normal == DVec3::Z && c.face.local == 5);
    assert_eq!(
        finder.gap(DVec3::new(f64::NAN, 0.0, 0.0)),
        Err(PointError::NonFinite)
    );
    assert!(GapFinder::new(&locator, -1.0).is_err());
    assert!(GapFinder::new(&locator, f64::INFINITY).is_err());
    // A bad hint is only a hint.
    let x = DVec3::new(2.5, -0.5, 2.5);
    let cold = finder.gap(x).unwrap();
    for hint in [
        Face {
            cell: CellId(0),
            local: 0,
        },
        Face {
            cell: CellId(10_000),
            local: 1,
        },
        Face {
            cell: CellId(3),
            local: 9,
        },
    ] {
        let fake = Contact {
            face: hint,
            ..cold.unwrap()
        };
        assert_eq!(
            finder.regap(x, &Ok(Some(fake))).unwrap().map(|c| c.gap),
            cold.map(|c| c.gap)
        );
    }
}

#[test]
fn batched_and_warm_answers_are_the_single_ones() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let body = stepped_body(DVec3::ZERO, h, 0.08);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.5).unwrap();
    let points = points_in(DVec3::splat(-0.7), body.lattice().upper() + 0.7, 3000, 99);
    let mut all = Vec::new();
    finder.gap_all_into(&points, &mut all);
    for (x, a) in points.iter().zip(&all) {
        assert_eq!(*a, finder.gap(*x));
    }
    let cold = all.clone();
    finder.regap_all(&points, &mut all);
    for (a, b) in all.iter().zip(&cold) {
        assert_eq!(a.map(|c| c.map(|c| c.gap)), b.map(|c| c.map(|c| c.gap)));
    }
}

/// An adaptive body: a 3 × 3 × 2 base lattice, one base cell refined twice in a corner (a level
/// jump of two), one refined once with a hole at level 1, and a missing base cell.
fn adaptive_body(amp: f64) -> AdaptiveBody {
    let h = DVec3::new(0.8, 0.6, 0.5);
    let lattice = Lattice::new(DVec3::new(0.5, -1.0, 2.0), h, [3, 3, 2]).unwrap();
    let mut leaves = Vec::new();
    for k in 0..2 {
        for j in 0..3 {
            for i in 0..3 {
                let base = Leaf::new(0, [i, j, k]);
                match (i, j, k) {
                    (2, 2, 1) => {} // missing
                    (1, 1, 1) => {
                        for (c, child) in base.children().into_iter().enumerate() {
                            if c == 0 {
                                leaves.extend(child.children());
                            } else {
                                leaves.push(child);
                            }
                        }
                    }
                    (0, 0, 0) => {
                        // A hole at level 1: the upper-corner child is missing.
                        leaves.extend(base.children().into_iter().take(7));
                    }
                    _ => leaves.push(base),
                }
            }
        }
    }
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    body.update_independent(|_, x, u| *u = field(x, h, amp))
        .unwrap();
    body
}

#[test]
fn adaptive_body_against_the_oracle() {
    let body = adaptive_body(0.05);
    let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.4).unwrap();
    let faces = adaptive_faces(&body);
    let lattice = body.lattice();
    let points = points_in(lattice.origin() - 0.5, lattice.upper() + 0.5, 400, 0xada);
    check(&finder, &faces, &points, 0.5 / 4.0);
    // A fine face against a coarse leaf is interior: a point just inside the refined cell's
    // lower face towards its coarse neighbour is deep, not on the surface.
    let x = body.leaf_origin(Leaf::new(0, [1, 1, 1])) + DVec3::new(0.01, 0.3, 0.25);
    let c = finder.gap(x).unwrap();
    assert!(c.is_none_or(|c| c.gap < -0.05), "{c:?}");
}

#[test]
fn uniform_and_one_level_adaptive_bodies_agree() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let body = stepped_body(DVec3::ZERO, h, 0.0);
    let leaves: Vec<Leaf> = body
        .active_cells()
        .map(|c| Leaf::new(0, body.lattice().cell_ijk(c).unwrap()))
        .collect();
    let mut adaptive = AdaptiveBody::from_leaves(*body.lattice(), leaves).unwrap();
    adaptive
        .update_independent(|_, x, u| *u = field(x, h, 0.08))
        .unwrap();
    let body = stepped_body(DVec3::ZERO, h, 0.08);
    let a = LatticeLocator::new(&body, Settings::default()).unwrap();
    let b = AdaptiveLocator::new(&adaptive, Settings::default()).unwrap();
    let fa = GapFinder::new(&a, 0.5).unwrap();
    let fb = GapFinder::new(&b, 0.5).unwrap();
    for x in points_in(DVec3::splat(-0.6), body.lattice().upper() + 0.6, 500, 5) {
        let (p, q) = (fa.gap(x).unwrap(), fb.gap(x).unwrap());
        assert_eq!(p.map(|c| c.gap), q.map(|c| c.gap), "{x}");
    }
}

/// A uniform body 4 × 3 × 3 with two cells missing (concave edges and corners), each node
/// displaced at random by up to `amp`·h per axis.
fn jittered_body(h: DVec3, amp: f64, seed: u64) -> Body {
    let lattice = Lattice::new(DVec3::new(-1.0, 2.0, 0.5), h, [4, 3, 3]).unwrap();
    let mut active = bitvec![1; lattice.cell_count()];
    for ijk in [[3, 2, 2], [1, 1, 2]] {
        active.set(lattice.cell_id(ijk).index(), false);
    }
    let noise = points_in(
        DVec3::splat(-amp),
        DVec3::splat(amp),
        lattice.node_count(),
        seed,
    );
    let dense: Vec<DVec3> = noise.iter().map(|&u| u * h).collect();
    Body::from_dense(lattice, active, &dense).unwrap()
}

/// Points 1e-9·h to 1e-5·h inside and outside a deformed body, beside the corners and edges of
/// its boundary faces, against the oracle. The closest point's descent gave up there, and the
/// face's edge answered (a gap too large, a normal far off): near the minimum |S − x|² rounds
/// at 1e-10 of itself (its rounding is absolute, 2|S − x| times that of S − x), beyond the
/// relative slack of the uphill test; and a minimum a hair inside an edge was approached by
/// steps shortened to stay in the square, ever shorter, until the backtracking gave up.
#[test]
fn points_a_hair_off_the_surface_near_edges_find_the_nearest_face() {
    let h = DVec3::new(0.5, 0.7, 0.3);
    let hmin = h.min_element();
    let body = jittered_body(h, 0.08, 0x0ed9e);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 0.2).unwrap();
    let faces = uniform_faces(&body);
    // Two draws a point: `pick` its face and how far off on which side, `near` where on it.
    let draws = points_in(DVec3::ZERO, DVec3::ONE, 16000, 0xc0de);
    let (mut interior, mut inside) = (0, 0);
    for (i, (&pick, &near)) in draws.iter().zip(&draws[1..]).enumerate().step_by(2) {
        let q = &faces[(pick.x * faces.len() as f64) as usize];
        // From u in [0, 2): 1e-9 to 1e-3 of the face's size from its edge at −1 or at 1.
        let hair = |u: f64| (1.0 - 10f64.powf(-9.0 + 6.0 * u.fract())) * (u - 1.0).signum();
        let st = match i % 3 {
            0 => DVec2::new(hair(near.x * 2.0), hair(near.y * 2.0)),
            1 => DVec2::new(hair(near.x * 2.0), 2.0 * near.y - 1.0),
            _ => DVec2::new(2.0 * near.x - 1.0, hair(near.y * 2.0)),
        };
        let depth = 10f64.powf(-9.0 + 4.0 * pick.y) * hmin * (pick.z - 0.5).signum();
        let x = bilinear(q, st) + oracle_normal(q, st) * depth;
        // The surface is within 1e-5·h: the faces whose corners' box (which holds the face) is
        // within 0.1·h are enough.
        let near: Vec<Quad> = faces
            .iter()
            .filter(|q| {
                let (lo, hi) = q[1..]
                    .iter()
                    .fold((q[0], q[0]), |(l, h), &p| (l.min(p), h.max(p)));
                (lo - x).max(x - hi).max(DVec3::ZERO).length() < 0.1 * hmin
            })
            .copied()
            .collect();
        let want = oracle(x, &near);
        let c = finder.gap(x).unwrap().expect("within the search distance");
        assert!(
            (c.gap.abs() - want.dist).abs() <= 1e-13 * hmin,
            "point {i} {x} ({depth:e} off face {q:?} at {st}): |gap| {} against the oracle's {}",
            c.gap.abs(),
            want.dist
        );
        if let (Some(n), true) = (want.interior_normal, c.interior) {
            assert!(
                (c.point - want.point).length() <= 1e-9 * hmin,
                "point {i} {x}: closest point {} against the oracle's {}",
                c.point,
                want.point
            );
            assert!(
                (c.normal - n).length() < 1e-8,
                "point {i}: normal {} against {n}",
                c.normal
            );
            interior += 1;
        }
        inside += usize::from(c.gap < 0.0);
    }
    assert!(
        interior > 3000 && inside > 3000,
        "interior {interior}, inside {inside}"
    );
}

/// A displacement of 1e160 was accepted, and a gap within a large search distance then came out
/// infinite with a zero normal: its squared distances overflowed. Such displacements are refused
/// by every way of setting them; at the limit the gap is finite.
#[test]
fn displacements_too_large_for_squared_distances_are_refused() {
    let h = DVec3::splat(1.0);
    let lattice = Lattice::new(DVec3::ZERO, h, [2, 2, 2]).unwrap();
    let flung = 26; // the lattice's upper corner node
    let field = |big: f64| {
        let mut u = vec![DVec3::ZERO; lattice.node_count()];
        u[flung] = DVec3::new(0.0, 0.0, big);
        u
    };
    let too_large = |e: Result<(), Error>| match e {
        Err(Error::DisplacementTooLarge { node, .. }) => node == flung,
        _ => false,
    };
    let active = bitvec![1; lattice.cell_count()];
    assert!(too_large(
        Body::from_dense(lattice, active.clone(), &field(1e160)).map(drop)
    ));
    let mut body = Body::full(lattice);
    assert!(too_large(body.set_displacements(&field(-1e160))));
    assert!(too_large(body.update_displacements(|n, _, u| {
        *u = field(1e160)[n];
    })));
    let leaves = (0..8).map(|c| Leaf::new(0, [c & 1, (c >> 1) & 1, c >> 2]));
    let mut adaptive = AdaptiveBody::from_leaves(lattice, leaves.collect()).unwrap();
    let n = adaptive.displacements().len();
    let mut u = vec![DVec3::ZERO; n];
    u[n - 1] = DVec3::splat(1e160);
    assert!(matches!(
        adaptive.set_displacements(&u),
        Err(Error::DisplacementTooLarge { .. })
    ));
    assert!(matches!(
        adaptive.update_independent(|_, _, u| *u = DVec3::splat(1e160)),
        Err(Error::DisplacementTooLarge { .. })
    ));
    // At the limit, a point beside the flung node's faces has a finite gap, a unit normal and
    // x = c + gap·n.
    let limit = Body::full(lattice).displacement_limit();
    assert!(limit > 1e13 && limit <= MAX_DISPLACEMENT, "{limit:e}");
    let body = Body::from_dense(lattice, active, &field(limit)).unwrap();
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let finder = GapFinder::new(&locator, 1e150).unwrap();
    for x in [DVec3::new(1.5, 0.5, 3.0), DVec3::new(-2.0, 1.5, 5e149)] {
        let c = finder.gap(x).unwrap().expect("within the search distance");
        assert!(c.gap.is_finite() && c.gap != 0.0, "{x}: {c:?}");
        assert!((c.normal.length() - 1.0).abs() < 1e-12, "{x}: {c:?}");
        let miss = (c.point + c.gap * c.normal - x).length();
        assert!(miss <= 1e-9 * (x - c.point).length(), "{x}: {c:?}");
    }
    // A search distance whose square would overflow is refused too: a point 1e200 away was
    // answered an infinite gap.
    assert!(GapFinder::new(&locator, 1e200).is_err());
}

/// A search distance out of range is refused naming the value in e notation: 1e300 printed in
/// full was a 300-digit message from every binding.
#[test]
fn a_search_distance_out_of_range_is_named_briefly() {
    let body = stepped_body(DVec3::ZERO, DVec3::ONE, 0.0);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    for (distance, shown) in [
        (1e300, "got 1e300"),
        (-2.5, "got -2.5e0"),
        (f64::NAN, "got NaN"),
    ] {
        let message = GapFinder::new(&locator, distance)
            .err()
            .unwrap()
            .to_string();
        assert!(message.contains(shown), "{message}");
        assert!(message.len() < 200, "{message}");
    }
    assert!(GapFinder::new(&locator, 1e150).is_ok());
}

/// `x` moved by `n` units in the last place along each axis.
fn ulps(x: DVec3, n: DVec3) -> DVec3 {
    let step = |v: f64, k: f64| {
        let bits = v.to_bits() as i64 + k as i64 * v.signum() as i64;
        f64::from_bits(bits as u64)
    };
    DVec3::new(step(x.x, n.x), step(x.y, n.y), step(x.z, n.z))
}

/// Near the surface the sign is the locator's, whose allowance is its inside tolerance plus the
/// rounding it carries: 1.9e-6 of a cell in ξ with f32, 4 ε |x| per component with f64 far
/// from the origin. The sign was left to the locator only within a millionth of the cell's
/// smallest edge, less than either: a point 5e-7 beyond the long face of a 1 × 1 × 0.01 cell
/// with f32, or 2 units in the last place (3e-8) beyond it at 1e8 with f64, was held by the
/// locator and answered a positive gap.
#[test]
fn the_sign_is_the_locators_within_its_rounding_allowance() {
    let h = DVec3::new(1.0, 1.0, 0.01);
    for (name, settings, origin) in [
        ("f32", Settings::f32(), DVec3::ZERO),
        ("f64 at 1e8", Settings::default(), DVec3::splat(1e8)),
    ] {
        let lattice = Lattice::new(origin, h, [2, 2, 2]).unwrap();
        let body = Body::full(lattice);
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let finder = GapFinder::new(&locator, 0.1).unwrap();
        // On the face x = 2 (the lattice's upper x face), then just beyond it.
        let on = origin + DVec3::new(2.0, 0.7, 0.013);
        let beyond = if settings.precision == crate::Precision::F32 {
            vec![on + DVec3::X * 5e-7, on + DVec3::X * 2e-7]
        } else {
            vec![ulps(on, DVec3::X * 2.0), ulps(on, DVec3::X * 4.0)]
        };
        let mut answers = Vec::new();
        finder.gap_all_into(&beyond, &mut answers);
        for (&x, batched) in beyond.iter().zip(&answers) {
            assert!(
                locator.locate(x).unwrap().is_some(),
                "{name}: the locator holds {x} (the scene's premise)"
            );
            let c = finder.gap(x).unwrap().expect("within the search distance");
            assert!(
                c.gap < 0.0,
                "{name}: {x}, held by the locator, has gap {:e}",
                c.gap
            );
            assert_eq!(*batched, Ok(Some(c)), "{name}: batched");
            assert_eq!(c.normal, DVec3::X, "{name}: the face's normal");
        }
        // Well beyond the allowance: outside, a positive gap, and geometry alone says so.
        let x = on + DVec3::X * 1e-4;
        assert!(locator.locate(x).unwrap().is_none(), "{name}");
        let c = finder.gap(x).unwrap().unwrap();
        assert!((c.gap - 1e-4).abs() < 1e-7, "{name}: {}", c.gap);
    }
}

/// A point a hair beyond an edge or a corner, within the locator's allowance, is held by it: its
/// gap is negative, and (x − c)/gap, the normal on edges and corners, pointed into the body
/// (x − c points out of it). With f32 a point 3e-7 of a cell beyond an edge of an undeformed
/// block got the normal (−1, 0, −1)/√2; with f64 so did one 4e-13 beyond it near the origin, and
/// one 2 units in the last place beyond it at 1e8. The normal there is now the face's, an
/// outward normal of the surface at c.
#[test]
fn normals_at_edges_and_corners_point_out_where_the_locator_holds_the_point() {
    for (name, settings, origin) in [
        ("f32", Settings::f32(), DVec3::ZERO),
        ("f64", Settings::default(), DVec3::ZERO),
        ("f64 at 1e8", Settings::default(), DVec3::splat(1e8)),
    ] {
        let lattice = Lattice::new(origin, DVec3::ONE, [2, 2, 2]).unwrap();
        let body = Body::full(lattice);
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let finder = GapFinder::new(&locator, 0.5).unwrap();
        let edge = origin + DVec3::new(2.0, 0.6, 2.0);
        let corner = origin + DVec3::splat(2.0);
        for (on, out) in [(edge, DVec3::new(1.0, 0.0, 1.0)), (corner, DVec3::ONE)] {
            let x = match name {
                "f32" => on + out * 3e-7,
                "f64" => on + out * 4e-13,
                _ => ulps(on, out * 2.0),
            };
            assert!(
                locator.locate(x).unwrap().is_some(),
                "{name}: the locator holds {x} (the scene's premise)"
            );
            let c = finder.gap(x).unwrap().expect("within the search distance");
            assert!(c.gap < 0.0 && !c.interior, "{name}: {x}: {c:?}");
            assert!((c.normal.length() - 1.0).abs() < 1e-12, "{name}: {c:?}");
            // An outward normal of a face through c: one of the axes `out` has.
            assert!(
                c.normal.dot(out) > 0.99,
                "{name}: {x}: normal {} points into the body",
                c.normal
            );
            // x = c + gap·n up to twice the gap.
            assert!(
                (c.point + c.gap * c.normal - x).length() <= 2.0 * c.gap.abs() + 1e-15,
                "{name}: {c:?}"
            );
        }
        // Beyond the allowance, on an edge the normal is (x − c)/gap again.
        let x = edge + DVec3::new(1.0, 0.0, 1.0) * 1e-3;
        let c = finder.gap(x).unwrap().unwrap();
        assert!(c.gap > 0.0 && !c.interior, "{name}: {c:?}");
        let n = DVec3::new(1.0, 0.0, 1.0).normalize();
        assert!((c.normal - n).length() < 1e-9, "{name}: {}", c.normal);
    }
}

/// Regression: points whose distance to the nearest face is D to within the rounding of their
/// coordinates. The cold search's box of cells had an absolute slack of 1e-9 h, below the
/// rounding of a coordinate of 3000 on a spacing of 1e-4 (an ulp of 3000 is 4.5e-13): it left
/// out the face's cell, and answered no face, while the warm search measured the hinted face
/// and found it within D. The documented promise is that warm answers are the cold ones.
#[test]
fn warm_and_cold_answers_agree_at_the_search_distance() {
    let h = DVec3::new(1.0, 1e-4, 1.0);
    let lattice = Lattice::new(DVec3::ZERO, h, [3000, 2000, 6]).unwrap();
    let cells: Vec<[u32; 3]> = vec![[1323, 56, 3], [644, 1474, 0], [2960, 1558, 4], [7, 1999, 5]];
    let ids: Vec<_> = cells.iter().map(|&c| lattice.cell_id(c)).collect();
    let body = Body::from_cells(lattice, ids).unwrap();
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let d = 3000.0;
    let finder = GapFinder::new(&locator, d).unwrap();
    let mut disagree = Vec::new();
    let mut measured = 0;
    for c in &cells {
        let low = lattice.node_position(*c);
        for (fx, fz) in [(0.0, 0.0), (0.5, 0.25), (1.0, 1.0)] {
            for side in [0.0, 1.0] {
                // On the face y = low + side·h, then D away along −y or +y (outward).
                let face = low + DVec3::new(fx, side * h.y, fz);
                let out = if side == 0.0 { -1.0 } else { 1.0 };
                for step in [-2.0, -1.0, 0.0, 1.0, 2.0] {
                    let x = face + DVec3::new(0.0, out * (d + step * 4.5e-13), 0.0);
                    // The hint: the answer of a point a little nearer, on the same line.
                    let near = finder.gap(face + DVec3::new(0.0, out * 0.5 * d, 0.0));
                    let cold = finder.gap(x);
                    let warm = finder.regap(x, &near);
                    measured += usize::from(cold.as_ref().is_ok_and(Option::is_some));
                    if cold.map(|c| c.map(|c| c.gap)) != warm.map(|c| c.map(|c| c.gap)) {
                        disagree.push((x, cold, warm));
                    }
                }
            }
        }
    }
    assert!(
        disagree.is_empty(),
        "{} of 120: {:?}",
        disagree.len(),
        disagree.first()
    );
    assert!(measured > 0);
}

/// Regression: at a point on an edge of the surface, two faces are at a distance of rounding
/// (1e-17). The pruning bounds were relative to the best distance alone (1e-12 of 1e-34), below
/// the rounding of the boxes' bounds, so the cold search pruned the face the warm search,
/// hinted there, measured first and found nearer: a different face and normal, on 34 of 810,000
/// points of a deformed adaptive block. The promise is that warm answers are the cold ones.
/// Here: every corner of the surface and points at random along its edges (a cell's edges are
/// straight), cold against warm hinted at each face of each leaf holding the point.
#[test]
fn warm_and_cold_answers_agree_on_the_surfaces_edges() {
    let mut rng = 7u64;
    let mut random = move || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    // A block like the audit's: 3 × 4 × 3 base cells of 0.25 at the origin, the top layer's
    // two middle rows (along y) refined twice; and this file's adaptive body.
    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.25), [3, 4, 3]).unwrap();
    let mut leaves = Vec::new();
    for k in 0..3 {
        for j in 0..4 {
            for i in 0..3 {
                let base = Leaf::new(0, [i, j, k]);
                if k == 2 && (1..3).contains(&j) {
                    base.children()
                        .iter()
                        .for_each(|c| leaves.extend(c.children()));
                } else {
                    leaves.push(base);
                }
            }
        }
    }
    let block = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    for (mut body, amp) in [
        (block.clone(), 0.05),
        (block.clone(), 0.2),
        (block, 0.4),
        (adaptive_body(0.0), 0.05),
        (adaptive_body(0.0), 0.2),
    ] {
        let h = body.lattice().h();
        let jitter: Vec<DVec3> = (0..body.node_count())
            .map(|_| (DVec3::new(random(), random(), random()) - 0.5) * h * 0.04)
            .collect();
        body.update_independent(|node, x, u| *u = field(x, h, amp) + jitter[node])
            .unwrap();
        let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
        let finder = GapFinder::new(&locator, 0.3).unwrap();
        let (mut checked, mut disagree) = (0, Vec::new());
        for q in adaptive_faces(&body) {
            for e in 0..4 {
                for k in 0..16 {
                    // The corner, then along the edge, half of them near the corner; moved by
                    // a few ulps, as a point computed another way is.
                    let t = match k {
                        0 => 0.0,
                        _ if k % 2 == 0 => 1e-12 * random(),
                        _ => random(),
                    };
                    let x = q[e].lerp(q[(e + 1) % 4], t);
                    let ulps = DVec3::new(random(), random(), random()) - 0.5;
                    let x = x + ulps * 8.0 * f64::EPSILON * x.abs();
                    let Some(cold) = finder.gap(x).unwrap() else {
                        panic!("{x}: on the surface, no face within D");
                    };
                    for hit in locator.locate_owners(x).unwrap() {
                        for local in 0..6 {
                            let face = Face {
                                cell: hit.cell,
                                local,
                            };
                            let warm = finder.regap(x, &Ok(Some(Contact { face, ..cold })));
                            let warm = warm.unwrap().unwrap();
                            checked += 1;
                            if warm.gap.to_bits() != cold.gap.to_bits() {
                                disagree.push((x, face, cold, warm));
                            }
                        }
                    }
                }
            }
        }
        assert!(
            disagree.is_empty(),
            "amp {amp}: {} of {checked}: {:?}",
            disagree.len(),
            disagree.first()
        );
        assert!(checked > 50_000, "amp {amp}: {checked}");
    }
}

/// The work of `points`' searches on this thread: cells visited and faces measured.
fn work(finder: &GapFinder<'_, impl Surface>, points: &[DVec3]) -> ([u64; 2], Vec<GapAnswer>) {
    let before = WORK.with(std::cell::Cell::get);
    let answers = points.iter().map(|&x| finder.gap(x)).collect();
    let after = WORK.with(std::cell::Cell::get);
    ([after[0] - before[0], after[1] - before[1]], answers)
}

/// A full 12³ body (h = 0.1) with a smooth field, and the same with one interior node moved
/// 100 h on every axis (its 8 cells inverted into a spike): the audit's case. The gap search
/// was bounded by the whole body's displacement range, so the spike made every point walk a box
/// of up to 100 cells per axis (clamped to the lattice): 135× the smooth body's time on a 60³
/// lattice, and here 26× the cells visited. Now each point visits about the cells near it, and
/// those of the blocks holding the spike where it passes near; the answers are the brute force's.
#[test]
fn one_far_moved_node_costs_the_gap_search_only_near_it() {
    let h = DVec3::splat(0.1);
    let lattice = Lattice::new(DVec3::ZERO, h, [12, 12, 12]).unwrap();
    let dense: Vec<DVec3> = (0..lattice.node_count())
        .map(|n| field(lattice.node_position(lattice.node_ijk(n).unwrap()), h, 0.05))
        .collect();
    let active = bitvec![1; lattice.cell_count()];
    let smooth = Body::from_dense(lattice, active.clone(), &dense).unwrap();
    let mut spiked = dense.clone();
    spiked[lattice.node_index([7, 5, 4])] += 100.0 * h;
    let spike = Body::from_dense(lattice, active, &spiked).unwrap();
    let points = points_in(DVec3::splat(-0.3), lattice.upper() + 0.3, 120, 0x5b1e);
    let d = 0.15;
    let faces = uniform_faces(&smooth);
    assert_eq!(faces, uniform_faces(&spike), "the spike is inside the body");
    let want: Vec<f64> = points.iter().map(|&x| oracle(x, &faces).dist).collect();
    let mut counts = Vec::new();
    for body in [&smooth, &spike] {
        let locator = LatticeLocator::new(body, Settings::default()).unwrap();
        let finder = GapFinder::new(&locator, d).unwrap();
        let (count, answers) = work(&finder, &points);
        let mut found = 0;
        for (i, ((&x, answer), &want)) in points.iter().zip(&answers).zip(&want).enumerate() {
            if (want - d).abs() < 1e-9 {
                continue;
            }
            match answer.unwrap() {
                None => assert!(want > d, "point {i} {x}: None, the surface is {want} away"),
                Some(c) => {
                    found += 1;
                    assert!(
                        (c.gap.abs() - want).abs() <= 1e-11,
                        "point {i} {x}: |gap| {} against {want}",
                        c.gap
                    );
                }
            }
        }
        assert!(found > 20 && found < points.len() - 20, "found {found}");
        counts.push(count);
    }
    let (smooth, spike) = (counts[0], counts[1]);
    eprintln!("cells visited, faces measured: smooth {smooth:?}, spike {spike:?}");
    // Cells visited and faces measured, the spike's within a small factor of the smooth body's:
    // 2.3× and 1.05× (the walk of the whole body's range visited 26× the cells). The spike's
    // first cell, at x less the middle of that range, is far off, and its bound D; the cell at
    // x less the middle of x's own block's range caps it (2.6× and 2.2× without that probe).
    assert!(
        spike[0] <= 3 * smooth[0] && 2 * spike[1] <= 3 * smooth[1],
        "cells visited {} against {}, faces measured {} against {}",
        spike[0],
        smooth[0],
        spike[1],
        smooth[1]
    );
}

/// `finder`'s answers, cold, batched and warm, bitwise those of the same finder walking the box
/// of the whole body's displacement range (the search before the block ranges), with the cells
/// visited of each.
fn same_as_the_walk<L: Surface>(finder: &GapFinder<'_, L>, points: &[DVec3]) -> [[u64; 2]; 2] {
    assert!(finder.blocks.is_some(), "the body keeps block ranges");
    let mut walk = GapFinder::new(finder.surface, finder.distance).unwrap();
    walk.blocks = None;
    let (a, blocks) = work(finder, points);
    let (b, walked) = work(&walk, points);
    let bits = |g: &GapAnswer| {
        g.map(|c| {
            c.map(|c| {
                (
                    c.gap.to_bits(),
                    c.point.to_array().map(f64::to_bits),
                    c.normal.to_array().map(f64::to_bits),
                    c.st.to_array().map(f64::to_bits),
                    c.face,
                    c.interior,
                )
            })
        })
    };
    for (i, (p, q)) in blocks.iter().zip(&walked).enumerate() {
        assert_eq!(bits(p), bits(q), "point {i} {}", points[i]);
    }
    let (mut p, mut q) = (Vec::new(), Vec::new());
    finder.gap_all_into(points, &mut p);
    assert_eq!(p, blocks);
    finder.regap_all(points, &mut p);
    walk.gap_all_into(points, &mut q);
    walk.regap_all(points, &mut q);
    for (p, q) in p.iter().zip(&q) {
        assert_eq!(bits(p), bits(q));
    }
    [a, b]
}

/// The walk through the block ranges answers bitwise as the walk of the whole range's box, on
/// uniform bodies with a far-moved node inside and on the surface (its faces then measured),
/// with inactive cells, and on an adaptive body; and visits fewer cells.
#[test]
fn block_ranges_answer_bitwise_as_the_whole_range() {
    let h = DVec3::new(0.1, 0.12, 0.09);
    let lattice = Lattice::new(DVec3::new(-0.4, 0.3, 1.0), h, [14, 11, 13]).unwrap();
    let smooth: Vec<DVec3> = (0..lattice.node_count())
        .map(|n| field(lattice.node_position(lattice.node_ijk(n).unwrap()), h, 0.07))
        .collect();
    let mut active = bitvec![1; lattice.cell_count()];
    for k in 0..13 {
        for j in 0..11 {
            // A notch through the body (concave edges across the blocks) and a hole.
            active.set(lattice.cell_id([9, j, k]).index(), k > 8);
            active.set(lattice.cell_id([3, 4, k]).index(), !(3..7).contains(&k));
        }
    }
    let points = points_in(lattice.origin() - 0.4, lattice.upper() + 0.4, 700, 0xb10c);
    let mut on_lattice = points.clone();
    // Points on nodes, edges and faces of the lattice: ties between faces.
    for (n, x) in on_lattice.iter_mut().enumerate().take(200) {
        let t = ((*x - lattice.origin()) / h * 2.0).round() * 0.5;
        *x = lattice.origin()
            + t * h
            + if n % 3 == 0 {
                smooth[n % 50]
            } else {
                DVec3::ZERO
            };
    }
    for (node, by) in [
        ([6, 5, 7], DVec3::splat(100.0)),
        ([0, 4, 6], DVec3::new(-30.0, 2.0, 1.0)),
        ([14, 11, 13], DVec3::new(3.0, 5.0, 40.0)),
        ([9, 3, 10], DVec3::new(0.5, -20.0, 7.0)),
    ] {
        let mut u = smooth.clone();
        u[lattice.node_index(node)] += by * h;
        let body = Body::from_dense(lattice, active.clone(), &u).unwrap();
        let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
        for d in [0.05, 0.2, 0.6] {
            let finder = GapFinder::new(&locator, d).unwrap();
            let [blocks, walk] = same_as_the_walk(&finder, &on_lattice);
            eprintln!("{node:?} {d}: {blocks:?} {walk:?}");
            assert!(
                blocks[0] <= walk[0],
                "{node:?} {d}: cells {blocks:?} {walk:?}"
            );
        }
    }
    // An adaptive body: a 10 × 9 × 8 base lattice, its top layer refined once and a corner of
    // it twice (hanging nodes), one node moved far inside and one on the refined surface.
    let h = DVec3::new(0.2, 0.15, 0.25);
    let lattice = Lattice::new(DVec3::new(1.0, -0.5, 0.2), h, [10, 9, 8]).unwrap();
    let mut leaves = Vec::new();
    for k in 0..8 {
        for j in 0..9 {
            for i in 0..10 {
                let base = Leaf::new(0, [i, j, k]);
                if k < 7 {
                    if (i, j, k) != (4, 4, 3) {
                        leaves.push(base);
                    }
                    continue;
                }
                for child in base.children() {
                    if i < 3 && j < 3 {
                        leaves.extend(child.children());
                    } else {
                        leaves.push(child);
                    }
                }
            }
        }
    }
    let points = points_in(lattice.origin() - 0.3, lattice.upper() + 0.3, 700, 0xada5);
    for (at, by) in [
        (DVec3::new(5.0, 4.0, 3.0), DVec3::splat(60.0)),
        (DVec3::new(1.5, 1.0, 8.0), DVec3::new(2.0, -1.0, 25.0)),
    ] {
        let mut body = AdaptiveBody::from_leaves(lattice, leaves.clone()).unwrap();
        let spike = lattice.origin() + at * h;
        body.update_independent(|_, x, u| {
            *u = field(x, h, 0.05);
            if (x - spike).length() < 1e-9 {
                *u += by * h;
            }
        })
        .unwrap();
        let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
        for d in [0.05, 0.3] {
            let finder = GapFinder::new(&locator, d).unwrap();
            let [blocks, walk] = same_as_the_walk(&finder, &points);
            eprintln!("{at} {d}: {blocks:?} {walk:?}");
            assert!(blocks[0] <= walk[0], "{at} {d}: cells {blocks:?} {walk:?}");
        }
    }
}
