//! Numerical extremes of the lattice locator, each checked against points built from a known
//! (cell, ξ): far offsets, tiny and huge cells, anisotropy, near-degenerate and inverted cells, large
//! displacements, points on every node/edge/face, points a hair inside and outside the boundary,
//! far and non-finite points; f64 and f32 side by side.
//!
//! Every test prints its measured bound on one `MEASURED` line (`cargo test -p cgcontact --test
//! suite extremes -- --skip gap_extremes --nocapture`); docs/numerics.md records them with the
//! name of the test that backs each.

use crate::common::{Rng, body, linear_maps, point_at};
use cgcontact::hex8::{Hex8Map, Kernel, min_corner_det};
use cgcontact::{
    Body, CellId, Error, Hit, Lattice, LatticeLocator, Locator, PointError, Precision, Settings,
};
use glam::DVec3;

/// Both precisions with their default settings.
fn precisions() -> [(&'static str, Settings); 2] {
    [("f64", Settings::default()), ("f32", Settings::f32())]
}

/// Largest ξ error one locator may make on a point built from a known (cell, ξ) at `x`: the kernel's
/// own error (`base`: 1e-12 in f64, 1e-5 in f32, times `condition` for distorted cells) plus the
/// rounding of x itself, which is only known to ε₆₄ |x|, i.e. 2 ε₆₄ |x| / h in ξ per rounding.
fn xi_bound(settings: &Settings, lattice: &Lattice, x: DVec3, condition: f64) -> f64 {
    let base = match settings.precision {
        Precision::F64 => 1e-12,
        Precision::F32 => 1e-5,
    };
    let magnitude = x
        .abs()
        .max_element()
        .max(lattice.origin().abs().max_element());
    base * condition + 8.0 * f64::EPSILON * magnitude / lattice.h().min_element() * condition
}

/// What a run over known points measured.
#[derive(Debug, Default)]
struct Measured {
    points: usize,
    /// Largest |ξ − ξ_known|∞ over the points.
    max_xi_error: f64,
    /// Largest error divided by its allowed bound (≤ 1 passes).
    max_ratio: f64,
    /// Largest physical residual over h_min.
    max_residual: f64,
}

/// Locate every known point: the same cell, ξ within [`xi_bound`]. Returns what was measured.
fn check_known(
    label: &str,
    body: &Body,
    settings: Settings,
    known: &[(CellId, DVec3)],
    condition: f64,
) -> Measured {
    let locator = LatticeLocator::new(body, settings).unwrap();
    let lattice = body.lattice();
    let mut measured = Measured::default();
    let points: Vec<DVec3> = known.iter().map(|&(c, xi)| point_at(body, c, xi)).collect();
    let answers = locator.locate_all(&points);
    for ((&(cell, xi), &x), answer) in known.iter().zip(&points).zip(answers) {
        let hit = answer
            .unwrap()
            .unwrap_or_else(|| panic!("{label}: {x} made in {cell} at ξ {xi} was not found"));
        assert_eq!(
            hit.cell, cell,
            "{label}: {x} made at ξ {xi}, found at {}",
            hit.xi
        );
        let error = (hit.xi - xi).abs().max_element();
        let bound = xi_bound(&settings, lattice, x, condition);
        assert!(
            error <= bound,
            "{label}: ξ error {error:.3e} > {bound:.3e} at {x} ({cell}, ξ {xi})"
        );
        measured.points += 1;
        measured.max_xi_error = measured.max_xi_error.max(error);
        measured.max_ratio = measured.max_ratio.max(error / bound);
        measured.max_residual = measured
            .max_residual
            .max(hit.residual / lattice.h().min_element());
    }
    measured
}

fn report(test: &str, case: &str, precision: &str, m: &Measured) {
    println!(
        "MEASURED {test} | {case} | {precision} | points {} | max ξ error {:.2e} | of bound {:.2} | max residual/h {:.2e}",
        m.points, m.max_xi_error, m.max_ratio, m.max_residual
    );
}

/// `n` random (cell, ξ) pairs in active cells, ξ in [−`reach`, `reach`]³.
fn random_known(body: &Body, n: usize, reach: f64, seed: u64) -> Vec<(CellId, DVec3)> {
    let mut rng = Rng(seed);
    let active: Vec<CellId> = body.active_cells().collect();
    (0..n)
        .map(|_| (active[rng.below(active.len())], rng.vec(-reach, reach)))
        .collect()
}

/// A mildly distorted 4 × 3 × 5 block (smooth field 0.1 h, jitter 0.05 h, 10 % holes).
fn distorted_block(origin: DVec3, h: DVec3, seed: u64) -> Body {
    let lattice = Lattice::new(origin, h, [4, 3, 5]).unwrap();
    body(lattice, 0.1, 0.1, DVec3::ZERO, 0.05, seed)
}

#[test]
fn far_offsets_1e3_to_1e9_cells_known_cell_and_xi() {
    for exponent in 3..=9 {
        let h = DVec3::splat(0.25);
        let offset = 10f64.powi(exponent);
        let origin = DVec3::new(1.0, -0.7, 0.3) * offset * h.x;
        let body = distorted_block(origin, h, exponent as u64);
        let known = random_known(&body, 2000, 0.999, 7 + exponent as u64);
        for (name, settings) in precisions() {
            let m = check_known(
                &format!("offset 1e{exponent} h"),
                &body,
                settings,
                &known,
                1.0,
            );
            report(
                "far_offsets_1e3_to_1e9_cells_known_cell_and_xi",
                &format!("offset 1e{exponent} h"),
                name,
                &m,
            );
        }
    }
}

#[test]
fn cell_sizes_1e_9_to_1e6_known_cell_and_xi() {
    for exponent in [-9, -6, -3, 0, 3, 6] {
        let h = DVec3::splat(10f64.powi(exponent));
        // An origin a few cells from zero, so only the scale changes.
        let origin = DVec3::new(3.0, -2.0, 0.5) * h;
        let body = distorted_block(origin, h, (100 + exponent) as u64);
        let known = random_known(&body, 2000, 0.999, 3);
        for (name, settings) in precisions() {
            let m = check_known(&format!("h = 1e{exponent}"), &body, settings, &known, 1.0);
            report(
                "cell_sizes_1e_9_to_1e6_known_cell_and_xi",
                &format!("h = 1e{exponent}"),
                name,
                &m,
            );
        }
    }
    // Both extremes at once: nanometre cells 1e9 cells from the origin, megametre cells likewise.
    for exponent in [-9, 6] {
        let h = DVec3::splat(10f64.powi(exponent));
        let origin = DVec3::new(-1.0, 1.0, 0.5) * 1e9 * h;
        let body = distorted_block(origin, h, 7);
        let known = random_known(&body, 1000, 0.999, 5);
        for (name, settings) in precisions() {
            let m = check_known("tiny/huge cells at 1e9 h", &body, settings, &known, 1.0);
            report(
                "cell_sizes_1e_9_to_1e6_known_cell_and_xi",
                &format!("h = 1e{exponent} at offset 1e9 h"),
                name,
                &m,
            );
        }
    }
}

#[test]
fn anisotropic_spacing_up_to_1_to_100_known_cell_and_xi() {
    for (case, h) in [
        ("1 : 10 : 100", DVec3::new(1.0, 0.1, 0.01)),
        ("100 : 1 : 10", DVec3::new(1.0, 0.01, 0.1)),
        ("1 : 1 : 100", DVec3::new(0.01, 0.01, 1.0)),
    ] {
        let body = distorted_block(DVec3::new(5.0, -3.0, 2.0), h, 21);
        let known = random_known(&body, 2000, 0.999, 9);
        for (name, settings) in precisions() {
            let m = check_known(case, &body, settings, &known, 1.0);
            report(
                "anisotropic_spacing_up_to_1_to_100_known_cell_and_xi",
                case,
                name,
                &m,
            );
        }
    }
}

/// Corner 6 of cell (1, 1, 1) of a 2 × 2 × 2 block (the block's top node, so no other cell moves)
/// pushed along the diagonal towards the cell's centre until its min corner det J ratio is `target`.
fn pushed_corner_block(target: f64, origin: DVec3, h: f64) -> (Body, f64) {
    let lattice = Lattice::new(origin, DVec3::splat(h), [2, 2, 2]).unwrap();
    let top = lattice.node_index([2, 2, 2]);
    let ratio_for = |d: f64| {
        let mut corners: [DVec3; 8] =
            std::array::from_fn(|c| DVec3::from_array(cgcontact::CORNER_OFFSETS[c].map(f64::from)));
        corners[6] -= DVec3::splat(d);
        min_corner_det(&corners) / (1.0 / 8.0)
    };
    // The ratio falls from 1 (d = 0) to 0 (d = 1/3: the corner reaches the plane of its neighbours).
    let (mut lo, mut hi) = (0.0, 1.0 / 3.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if ratio_for(mid) > target {
            lo = mid
        } else {
            hi = mid
        }
    }
    let d = lo;
    let mut body = Body::full(lattice);
    body.update_displacements(|node, _, u| {
        if node == top {
            *u = DVec3::splat(-d * h);
        }
    })
    .unwrap();
    let cell = lattice.cell_id([1, 1, 1]);
    let ratio = body
        .corners(cell)
        .map(|c| min_corner_det(&c.map(|p| (p - lattice.node_position([1, 1, 1])) / h)) * 8.0)
        .unwrap();
    (body, ratio)
}

#[test]
fn distortion_min_det_ratio_1e_3_known_cell_and_xi() {
    for target in [1e-1, 1e-2, 1e-3] {
        for (case_offset, origin) in [("origin", DVec3::ZERO), ("offset 1e6 h", DVec3::splat(1e6))]
        {
            let (body, ratio) = pushed_corner_block(target, origin, 1.0);
            assert!(
                (ratio / target - 1.0).abs() < 1e-6,
                "built ratio {ratio} for target {target}"
            );
            assert!(
                body.validate().is_ok(),
                "det J > 0 everywhere: the cell is valid"
            );
            let cell = body.lattice().cell_id([1, 1, 1]);
            // Random ξ all over the cell, plus a cluster at the crushed corner (ξ → (1, 1, 1)).
            let mut rng = Rng(31);
            let mut known: Vec<(CellId, DVec3)> =
                (0..2000).map(|_| (cell, rng.vec(-0.999, 0.999))).collect();
            for _ in 0..1000 {
                known.push((cell, DVec3::splat(1.0) - rng.vec(1e-3, 0.05)));
            }
            // The other (undistorted but neighbouring) cells.
            known.extend(random_known(&body, 500, 0.999, 4));
            for (name, settings) in precisions() {
                // Newton's error grows like cond(J) ~ 1 / ratio near the crushed corner.
                let condition = 1.0 / ratio;
                let case = format!("min det ratio {target:.0e}, {case_offset}");
                let m = check_known(&case, &body, settings, &known, condition);
                report(
                    "distortion_min_det_ratio_1e_3_known_cell_and_xi",
                    &case,
                    name,
                    &m,
                );
            }
        }
    }
}

#[test]
fn displacements_up_to_3h_known_cell_and_xi() {
    for (case, shift) in [
        ("rigid 3 h", DVec3::new(3.0, -3.0, 3.0)),
        ("rigid 2.7 h + smooth 0.3 h", DVec3::new(-2.7, 2.7, 2.0)),
    ] {
        let lattice = Lattice::new(
            DVec3::new(1e4, 2e4, -3e4),
            DVec3::new(0.5, 0.4, 0.3),
            [6, 5, 4],
        )
        .unwrap();
        let body = body(lattice, 0.2, 0.3, shift, 0.05, 77);
        let u_max = (body.max_displacement() / lattice.h()).max_element();
        assert!(u_max >= 2.9, "{case}: u_max {u_max} h");
        let known = random_known(&body, 3000, 0.999, 12);
        for (name, settings) in precisions() {
            let m = check_known(case, &body, settings, &known, 1.0);
            report(
                "displacements_up_to_3h_known_cell_and_xi",
                &format!("{case} (u_max {u_max:.2} h)"),
                name,
                &m,
            );
        }
    }
}

/// Node (1, 1, 1) of a 4 × 4 × 4 block of unit cells moved by +1.3 h along x: it passes the nodes
/// (2, 1±1, 1±1) of the cells on its +x side, which fold over; the cells on its −x side are only
/// stretched and sheared (the corner determinants keep their sign, worked out by hand below).
fn folded_block() -> (Body, usize) {
    let lattice = Lattice::new(DVec3::new(-2.0, 7.0, 1e3), DVec3::ONE, [4, 4, 4]).unwrap();
    let moved = lattice.node_index([1, 1, 1]);
    let mut body = Body::full(lattice);
    body.update_displacements(|node, _, u| {
        if node == moved {
            u.x = 1.3;
        }
    })
    .unwrap();
    (body, moved)
}

#[test]
fn inverted_cells_are_reported_and_far_cells_still_located() {
    let (body, moved) = folded_block();
    let lattice = *body.lattice();
    // By hand: at the moved node, the +x cells' edge along +x now points along −x (length 1 − 1.3),
    // the other two edges keep their directions' components: det J < 0 there. The −x cells' corner
    // determinants are (edge along x) · (edge y × edge z) with only the x components changed: same sign.
    let mut expected: Vec<CellId> = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            expected.push(lattice.cell_id([1, j, k]));
        }
    }
    expected.sort();
    let inverted = body.inverted_cells();
    let cells: Vec<CellId> = inverted.iter().map(|(c, _)| *c).collect();
    assert_eq!(cells, expected, "inverted cells, ascending");
    for (cell, ratio) in &inverted {
        assert!(*ratio <= 0.0, "{cell}: ratio {ratio}");
        let ijk = lattice.cell_ijk(*cell).unwrap();
        assert!(lattice.corner_nodes(ijk).contains(&moved));
    }
    match body.validate() {
        Err(Error::InvertedCells(list)) => assert_eq!(list, inverted),
        other => panic!("validate: {other:?}"),
    }
    let message = body.validate().unwrap_err().to_string();
    assert!(
        message.contains("4 inverted") && message.contains("cell 1"),
        "{message}"
    );

    // The locator does not refuse the body (the caller asks `inverted_cells` which answers to distrust);
    // points in cells that share no node with a cell touching the moved node are answered exactly.
    let near = |cell: CellId| {
        let ijk = lattice.cell_ijk(cell).unwrap();
        ijk.iter().all(|&v| v <= 2)
    };
    let mut rng = Rng(5);
    let far: Vec<(CellId, DVec3)> = body
        .active_cells()
        .filter(|&c| !near(c))
        .flat_map(|c| (0..20).map(move |_| c).collect::<Vec<_>>())
        .map(|c| (c, rng.vec(-0.999, 0.999)))
        .collect();
    assert!(far.len() > 500);
    for (name, settings) in precisions() {
        let m = check_known("far from the fold", &body, settings, &far, 1.0);
        report(
            "inverted_cells_are_reported_and_far_cells_still_located",
            "cells ≥ 1 cell away from the fold",
            name,
            &m,
        );
    }

    // Near the fold, cells overlap: a point may be held by several cells (a valid one and a folded
    // one), and Newton in a folded cell may stop as singular. What the locator guarantees there: an
    // answer is a cell whose map sends the answered ξ back to the point (never a made-up cell), and
    // no panic. Count how often the answer differs from the cell the point was made in.
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let (mut other_cell, mut missed, mut total, mut worst) = (0, 0, 0, 0.0f64);
    for cell in body.active_cells().filter(|&c| near(c)) {
        for _ in 0..50 {
            let xi = rng.vec(-0.999, 0.999);
            let x = point_at(&body, cell, xi);
            total += 1;
            match locator.locate(x).unwrap() {
                None => missed += 1,
                Some(hit) => {
                    let back = point_at(&body, hit.cell, hit.xi);
                    worst = worst.max((back - x).abs().max_element());
                    if hit.cell != cell {
                        other_cell += 1;
                    }
                }
            }
        }
    }
    assert!(
        worst < 1e-9,
        "an answer near the fold does not map back: {worst:e}"
    );
    println!(
        "MEASURED inverted_cells_are_reported_and_far_cells_still_located | near the fold | f64 | points {total} | answered another (overlapping) cell {other_cell} | not found {missed} | max |x(ξ) − x| {worst:.2e}"
    );
}

/// The owners of a half-cell sample `half` (node: all even, edge: one odd, face: two odd, interior:
/// three odd) of `lattice`, active ones only, ascending; and the sample's ξ in each.
fn owners_of_sample(body: &Body, half: [u32; 3]) -> Vec<(CellId, DVec3)> {
    let lattice = body.lattice();
    let cells = lattice.cells();
    let ranges: Vec<Vec<u32>> = (0..3)
        .map(|a| {
            let v = half[a];
            if v % 2 == 0 {
                ((v / 2).saturating_sub(1)..=(v / 2).min(cells[a] - 1)).collect()
            } else {
                vec![v / 2]
            }
        })
        .collect();
    let mut owners = Vec::new();
    for &k in &ranges[2] {
        for &j in &ranges[1] {
            for &i in &ranges[0] {
                let cell = lattice.cell_id([i, j, k]);
                if body.is_active(cell) {
                    let ijk = [i, j, k];
                    let xi = DVec3::from_array(
                        [0, 1, 2].map(|a| half[a] as f64 - 1.0 - 2.0 * ijk[a] as f64),
                    );
                    owners.push((cell, xi));
                }
            }
        }
    }
    owners.sort_by_key(|(c, _)| *c);
    owners
}

#[test]
fn points_on_every_node_edge_and_face_have_all_owners_sorted() {
    for (case, origin, holes) in [
        ("origin, full", DVec3::new(3.0, -2.0, 1.0), 0.0),
        ("origin, 25 % holes", DVec3::new(3.0, -2.0, 1.0), 0.25),
        (
            "offset 1e6 h, full",
            DVec3::new(1.0, -1.0, 0.5) * 1e6 * 0.5,
            0.0,
        ),
        (
            "offset 1e9 h, full",
            DVec3::new(1.0, -1.0, 0.5) * 1e9 * 0.5,
            0.0,
        ),
    ] {
        let lattice = Lattice::new(origin, DVec3::new(0.5, 0.7, 0.3), [3, 3, 3]).unwrap();
        let body = body(lattice, holes, 0.1, DVec3::ZERO, 0.05, 11);
        for (name, settings) in precisions() {
            let locator = LatticeLocator::new(&body, settings).unwrap();
            let (mut samples, mut worst) = (0, Measured::default());
            for k in 0..=6u32 {
                for j in 0..=6u32 {
                    for i in 0..=6u32 {
                        let half = [i, j, k];
                        let expected = owners_of_sample(&body, half);
                        let Some(&(first, xi_first)) = expected.first() else {
                            continue;
                        };
                        let x = point_at(&body, first, xi_first);
                        let owners = locator.locate_owners(x).unwrap();
                        let got: Vec<CellId> = owners.iter().map(|h| h.cell).collect();
                        let want: Vec<CellId> = expected.iter().map(|(c, _)| *c).collect();
                        assert_eq!(got, want, "{case} {name}: sample {half:?} at {x}");
                        assert!(got.windows(2).all(|w| w[0] < w[1]), "strictly ascending");
                        for (hit, (_, xi)) in owners.iter().zip(&expected) {
                            let error = (hit.xi - *xi).abs().max_element();
                            let bound = xi_bound(&settings, &lattice, x, 1.0);
                            assert!(error <= bound, "{case} {name}: {half:?} ξ error {error:e}");
                            worst.max_xi_error = worst.max_xi_error.max(error);
                            worst.max_ratio = worst.max_ratio.max(error / bound);
                        }
                        let hit = locator.locate(x).unwrap().expect("on the body");
                        assert!(want.contains(&hit.cell));
                        samples += 1;
                        worst.points += owners.len();
                    }
                }
            }
            assert!(samples > 200);
            report(
                "points_on_every_node_edge_and_face_have_all_owners_sorted",
                case,
                name,
                &worst,
            );
        }
    }
}

/// Points 1e-12 h inside the outer faces are always found; points outside by more than the inside
/// tolerance of their axis (converted to a distance, plus the rounding of x) never are. 1e-12 h
/// outside is reported. On a 1000 : 1 lattice too: with one tolerance for every axis, from the
/// smallest spacing, a point 5e-4 h outside a face of the long axis was found at 1e9.
#[test]
fn boundary_1e_12_h_inside_found_outside_beyond_tolerance_not() {
    for (exponent, h) in [0, 3, 6, 9].into_iter().flat_map(|e| {
        [
            (e, DVec3::new(0.5, 0.4, 0.3)),
            (e, DVec3::new(1.0, 1e-3, 0.25)),
        ]
    }) {
        let origin = if exponent == 0 {
            DVec3::new(0.2, -0.1, 0.3)
        } else {
            DVec3::new(1.0, -1.0, 0.5) * 10f64.powi(exponent) * h.x
        };
        let lattice = Lattice::new(origin, h, [3, 3, 3]).unwrap();
        // Undeformed: the outer faces are the lattice's planes, so "d inside" is exact to one rounding.
        let body = Body::full(lattice);
        let mut rng = Rng(exponent as u64);
        for (name, settings) in precisions() {
            let locator = LatticeLocator::new(&body, settings).unwrap();
            let (mut outside_hair_found, mut total) = (0, 0);
            for _ in 0..300 {
                let axis = rng.below(3);
                let high = rng.below(2) == 1;
                let mut on_face =
                    lattice.origin() + (lattice.upper() - lattice.origin()) * rng.vec(0.01, 0.99);
                on_face[axis] = if high {
                    lattice.upper()[axis]
                } else {
                    lattice.origin()[axis]
                };
                let outward = if high { 1.0 } else { -1.0 };
                let mut normal = DVec3::ZERO;
                normal[axis] = outward;
                // Inside by 1e-12 h (at large offsets this rounds onto the face: still inside).
                let inside = on_face - normal * 1e-12 * h[axis];
                assert!(
                    locator.locate(inside).unwrap().is_some(),
                    "{name} 1e{exponent}: {inside} inside"
                );
                // Exactly on the face.
                assert!(
                    locator.locate(on_face).unwrap().is_some(),
                    "{name} 1e{exponent}: {on_face} on"
                );
                // Outside by the tolerance of this axis (ξ units → distance h/2 · tol) twice over,
                // plus x's rounding. The tolerance as docs/numerics.md defines it, written out here
                // (u = 0), so that the library's own cannot widen it unseen.
                let magnitude = on_face.abs().max_element().max(origin.abs().max_element());
                let tol = settings.inside_tol
                    + 16.0 * settings.epsilon()
                    + 8.0 * f64::EPSILON * magnitude / h[axis];
                assert!(
                    settings.inside_tolerance(&lattice, DVec3::ZERO, on_face)[axis]
                        <= tol * (1.0 + 1e-9),
                    "{name} 1e{exponent}: the tolerance of axis {axis}"
                );
                let beyond =
                    2.0 * tol * h[axis] / 2.0 + 4.0 * f64::EPSILON * on_face.abs().max_element();
                let outside = on_face + normal * beyond;
                assert_eq!(
                    locator.locate(outside).unwrap(),
                    None,
                    "{name} 1e{exponent}: {outside} is {beyond:e} outside (tolerance {tol:e} in ξ)"
                );
                // 1e-12 h outside: inside the allowance or not, depending on magnitude and precision.
                if locator
                    .locate(on_face + normal * 1e-12 * h[axis])
                    .unwrap()
                    .is_some()
                {
                    outside_hair_found += 1;
                }
                total += 1;
            }
            let tol = settings
                .inside_tolerance(&lattice, DVec3::ZERO, lattice.upper())
                .max_element();
            println!(
                "MEASURED boundary_1e_12_h_inside_found_outside_beyond_tolerance_not | offset 1e{exponent} h | spacing {h} | {name} | inside tolerance (largest axis) {tol:.2e} ξ = {:.2e} h | 1e-12 h outside found {outside_hair_found}/{total}",
                tol / 2.0
            );
        }
    }
}

#[test]
fn far_points_are_not_found() {
    let lattice = Lattice::new(DVec3::new(-1.0, 2.0, 1e5), DVec3::splat(0.5), [3, 3, 3]).unwrap();
    let body = body(lattice, 0.0, 0.2, DVec3::new(1.0, 0.0, 0.0), 0.05, 3);
    for (name, settings) in precisions() {
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let c = (lattice.origin() + lattice.upper()) * 0.5;
        for x in [
            c + DVec3::X * 1e3,
            c - DVec3::Y * 5.0,
            DVec3::ZERO,
            DVec3::splat(1e300),
            DVec3::splat(-1e300),
            DVec3::splat(f64::MAX),
            DVec3::new(f64::MIN, 0.0, f64::MAX),
            DVec3::splat(f64::MIN_POSITIVE * 1e-10),
            c + DVec3::new(0.0, 0.0, 1e17),
        ] {
            assert_eq!(locator.locate(x), Ok(None), "{name}: {x}");
            assert_eq!(
                locator.locate_owners(x).map(|o| o.len()),
                Ok(0),
                "{name}: {x}"
            );
        }
    }
}

#[test]
fn non_finite_points_get_their_own_error_and_leave_the_others_alone() {
    let lattice = Lattice::new(DVec3::new(4.0, 5.0, 6.0), DVec3::splat(0.3), [4, 4, 4]).unwrap();
    let body = body(lattice, 0.1, 0.1, DVec3::ZERO, 0.05, 9);
    let known = random_known(&body, 200, 0.999, 1);
    let bad = [
        DVec3::new(f64::NAN, 5.0, 6.0),
        DVec3::new(4.5, f64::INFINITY, 6.0),
        DVec3::new(4.5, 5.0, f64::NEG_INFINITY),
        DVec3::NAN,
        DVec3::new(f64::NAN, f64::INFINITY, 0.0),
    ];
    let mut points = Vec::new();
    let mut expected = Vec::new();
    for (i, &(cell, xi)) in known.iter().enumerate() {
        points.push(point_at(&body, cell, xi));
        expected.push(Some(cell));
        if i % 7 == 0 {
            points.push(bad[i % bad.len()]);
            expected.push(None);
        }
    }
    for (name, settings) in precisions() {
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let answers = locator.locate_all(&points);
        for ((answer, want), &x) in answers.iter().zip(&expected).zip(&points) {
            match want {
                None => {
                    assert_eq!(*answer, Err(PointError::NonFinite), "{name}: {x}");
                    assert_eq!(locator.locate_owners(x), Err(PointError::NonFinite));
                }
                Some(cell) => {
                    assert_eq!(answer.unwrap().unwrap().cell, *cell, "{name}: {x}");
                    // Bitwise the same as asking for this point alone.
                    assert_eq!(*answer, locator.locate(x));
                }
            }
        }
    }
}

/// One batch on pools of 1, 2, 3 and 8 threads: bitwise identical answers, f64 and f32.
#[test]
fn answers_identical_across_thread_counts_on_extreme_bodies() {
    let bodies = [
        distorted_block(DVec3::splat(1e9 * 0.25), DVec3::splat(0.25), 1),
        distorted_block(DVec3::ZERO, DVec3::new(1.0, 0.1, 0.01), 2),
        pushed_corner_block(1e-3, DVec3::ZERO, 1.0).0,
        folded_block().0,
    ];
    for body in &bodies {
        let lattice = body.lattice();
        let mut rng = Rng(8);
        let points: Vec<DVec3> = (0..4000)
            .map(|_| lattice.origin() + (lattice.upper() - lattice.origin()) * rng.vec(-0.1, 1.1))
            .collect();
        for (_, settings) in precisions() {
            let locator = LatticeLocator::new(body, settings).unwrap();
            let run = |threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| locator.locate_all(&points))
            };
            let one = run(1);
            for threads in [2, 3, 8] {
                assert_eq!(run(threads), one, "{threads} threads");
            }
        }
    }
}

/// f32 against f64 on the same points: the ξ difference, across all the extremes above.
#[test]
fn f32_against_f64_measured() {
    let cases: Vec<(String, Body)> = vec![
        (
            "offset 1e9 h".into(),
            distorted_block(DVec3::splat(1e9 * 0.25), DVec3::splat(0.25), 1),
        ),
        (
            "h = 1e-9".into(),
            distorted_block(DVec3::splat(3e-9), DVec3::splat(1e-9), 2),
        ),
        (
            "h = 1e6".into(),
            distorted_block(DVec3::splat(3e6), DVec3::splat(1e6), 3),
        ),
        (
            "1 : 10 : 100".into(),
            distorted_block(DVec3::ZERO, DVec3::new(1.0, 0.1, 0.01), 4),
        ),
        (
            "min det ratio 1e-3".into(),
            pushed_corner_block(1e-3, DVec3::ZERO, 1.0).0,
        ),
        (
            "displacement 3 h".into(),
            body(
                Lattice::new(DVec3::ZERO, DVec3::splat(0.5), [5, 5, 5]).unwrap(),
                0.1,
                0.3,
                DVec3::splat(2.7),
                0.05,
                6,
            ),
        ),
    ];
    for (case, body) in &cases {
        let known = random_known(body, 3000, 0.999, 17);
        let points: Vec<DVec3> = known.iter().map(|&(c, xi)| point_at(body, c, xi)).collect();
        let f64s = LatticeLocator::new(body, Settings::default())
            .unwrap()
            .locate_all(&points);
        let f32s = LatticeLocator::new(body, Settings::f32())
            .unwrap()
            .locate_all(&points);
        let (mut worst, mut same_cell) = (0.0f64, 0);
        for (a, b) in f64s.iter().zip(&f32s) {
            let (a, b) = (a.unwrap().unwrap(), b.unwrap().unwrap());
            if a.cell == b.cell {
                same_cell += 1;
                worst = worst.max((a.xi - b.xi).abs().max_element());
            }
        }
        assert_eq!(
            same_cell,
            points.len(),
            "{case}: points strictly inside one cell"
        );
        assert!(worst < 1e-3, "{case}: |ξ32 − ξ64| {worst:e}");
        println!(
            "MEASURED f32_against_f64_measured | {case} | f32 − f64 | points {} | max |ξ32 − ξ64| {worst:.2e}",
            points.len()
        );
    }
}

/// The f32 kernel alone, in a local frame: what ξ error single precision costs before any offset.
#[test]
fn f32_kernel_error_in_the_local_frame() {
    let h = DVec3::splat(1.0);
    let mut rng = Rng(3);
    let mut worst = 0.0f64;
    for _ in 0..200 {
        let u: [DVec3; 8] = std::array::from_fn(|_| rng.vec(-0.15, 0.15));
        let map64 = Hex8Map::lattice_cell(h, &u);
        let map32 = cgcontact::hex8::Hex8Map32::lattice_cell(h, &u);
        for _ in 0..20 {
            let xi = rng.vec(-1.0, 1.0);
            let x = map64.map(xi);
            let inv = map32.invert_f64(x, DVec3::ZERO, &Settings::f32().newton());
            worst = worst.max((inv.xi - xi).abs().max_element());
        }
    }
    assert!(worst < 1e-5);
    println!(
        "MEASURED f32_kernel_error_in_the_local_frame | jitter 0.15 h | f32 | points 4000 | max ξ error {worst:.2e}"
    );
}

/// Regression (f32 kernel): near the crushed corner of a valid cell with min det J ratio 1e-3, the f32
/// Newton sat at the right ξ (error ~2e-6) but its step never fell below the f32 Newton tolerance
/// (1e-5): rounding noise × cond(J) ≈ 1e3 · 6e-8 kept it above, so the inversion ended `NotConverged`
/// and the point was reported in no cell. Fixed: Newton also stops at the step's rounding noise.
#[test]

fn f32_finds_points_near_a_corner_with_det_ratio_1e_3() {
    let (body, _) = pushed_corner_block(1e-3, DVec3::ZERO, 1.0);
    let cell = body.lattice().cell_id([1, 1, 1]);
    let xi = DVec3::new(0.9974346683088426, 0.9878844622358395, 0.9943298347442555);
    let x = point_at(&body, cell, xi);
    assert_eq!(
        x,
        DVec3::new(1.669096271352292, 1.6643211683157904, 1.6675438545699985)
    );
    let f64_hit = LatticeLocator::new(&body, Settings::default())
        .unwrap()
        .locate(x)
        .unwrap();
    assert_eq!(f64_hit.map(|h| h.cell), Some(cell));
    let f32_hit = LatticeLocator::new(&body, Settings::f32())
        .unwrap()
        .locate(x)
        .unwrap();
    assert_eq!(f32_hit.map(|h| h.cell), Some(cell), "f32 lost the point");
}

/// f32 rounds each displacement by ε₃₂ |u|: on a body moved rigidly by 1e5 cells that was 1e-2 of
/// a cell, and points near faces landed in the neighbouring cell. The f32 kernel now works in a
/// frame shifted by the displacements' common translation (`LatticeLocator::frame_shift`), so a
/// rigid translation of any size costs nothing: the known cell and ξ to f32's 1e-5, batched,
/// point by point and warm-started, as on the unmoved body. The frame is whole cells and absent
/// where the translation is under half a cell (answers bitwise as before).
#[test]
fn f32_rigid_translations_of_1e3_to_1e6_cells_known_cell_and_xi() {
    let lattice = Lattice::new(
        DVec3::new(3.0, -2.0, 7.0),
        DVec3::new(0.5, 0.25, 0.4),
        [5, 4, 3],
    )
    .unwrap();
    for exponent in 3..=6 {
        let cells = DVec3::new(1.0, -0.7, 0.4) * 10f64.powi(exponent);
        let body = body(lattice, 0.1, 0.1, cells, 0.05, exponent as u64);
        let settings = Settings::f32();
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let shift = locator.frame_shift() / lattice.h();
        assert!(
            (shift - cells).abs().max_element() <= 0.5 && shift == shift.round(),
            "the frame is whole cells near the translation: {shift}"
        );
        let known = random_known(&body, 2000, 0.999, 40 + exponent as u64);
        let case = format!("rigid 1e{exponent} h + smooth 0.1 h");
        let m = check_known(&case, &body, settings, &known, 1.0);
        report(
            "f32_rigid_translations_of_1e3_to_1e6_cells_known_cell_and_xi",
            &case,
            "f32",
            &m,
        );
        // Point by point and warm-started from the batched answers: the same answers.
        let points: Vec<DVec3> = known
            .iter()
            .map(|&(c, xi)| point_at(&body, c, xi))
            .collect();
        let mut answers = locator.locate_all(&points);
        for (&x, answer) in points.iter().zip(&answers) {
            assert_eq!(locator.locate(x), *answer, "{case}: locate at {x}");
        }
        let batched = answers.clone();
        locator.relocate_all(&points, &mut answers);
        for ((answer, cold), &(cell, xi)) in answers.iter().zip(&batched).zip(&known) {
            let hit = answer.unwrap().unwrap();
            assert_eq!(hit.cell, cell, "{case}: warm");
            assert!(
                (hit.xi - xi).abs().max_element() <= 1e-5,
                "{case}: warm ξ {}",
                hit.xi
            );
            assert_eq!(hit.inversions, 1, "{case}: the hint holds it ({cold:?})");
        }
    }
    // Under half a cell: no frame.
    let body = body(lattice, 0.1, 0.1, DVec3::splat(0.45), 0.0, 3);
    let locator = LatticeLocator::new(&body, Settings::f32()).unwrap();
    assert_eq!(locator.frame_shift(), DVec3::ZERO);
    assert_eq!(
        LatticeLocator::new(&body, Settings::default())
            .unwrap()
            .frame_shift(),
        DVec3::ZERO
    );
}

/// The 7³ points at the half-cell samples of a 3 × 3 × 3 body (nodes, edge and face centres,
/// cell centres), each made from its first owner's map, and each one's owners in order.
fn samples_and_owners(body: &Body) -> (Vec<DVec3>, Vec<Vec<CellId>>) {
    let mut samples = Vec::new();
    let mut wanted = Vec::new();
    for k in 0..=6u32 {
        for j in 0..=6u32 {
            for i in 0..=6u32 {
                let expected = owners_of_sample(body, [i, j, k]);
                let (first, xi) = expected[0];
                samples.push(point_at(body, first, xi));
                wanted.push(expected.iter().map(|(c, _)| *c).collect());
            }
        }
    }
    (samples, wanted)
}

/// Points on every node, edge and face of lattices deformed by [`linear_maps`] (anisotropic and
/// not, near the origin and far from it) have all their owners, in every precision and path. With
/// an allowance of 2L / h_k per axis, a node of the 4 × 0.25 × 0.002 lattice at 1e5 sheared by
/// x += 10 z lost owners: the rounding of z moved ξ along x by 10 times more than x's own.
#[test]
fn sheared_and_rotated_cells_keep_every_owner_of_nodes_edges_and_faces() {
    for (map_name, a) in linear_maps() {
        for h in [DVec3::new(4.0, 0.25, 0.002), DVec3::splat(0.5)] {
            for origin in [
                DVec3::new(3.0, -2.0, 1.0),
                DVec3::splat(1e5),
                DVec3::splat(-1e8),
            ] {
                let lattice = Lattice::new(origin, h, [3, 3, 3]).unwrap();
                let mut body = Body::full(lattice);
                body.update_displacements(|_, x, u| {
                    let r = x - origin;
                    *u = DVec3::new(a[0].dot(r), a[1].dot(r), a[2].dot(r)) - r;
                })
                .unwrap();
                let case = format!("{map_name}, h {h}, origin {origin}");
                for (name, settings) in precisions() {
                    let locator = LatticeLocator::new(&body, settings).unwrap();
                    let (samples, wanted) = samples_and_owners(&body);
                    let batched = locator.locate_all(&samples);
                    // Warm starts: each owner, as the hint at its own ξ, answers itself.
                    let (mut warm_points, mut hints) = (Vec::new(), Vec::new());
                    for ((x, want), hit) in samples.iter().zip(&wanted).zip(batched) {
                        let owners = locator.locate_owners(*x).unwrap();
                        let got: Vec<CellId> = owners.iter().map(|h| h.cell).collect();
                        assert_eq!(&got, want, "{case} {name}: owners of {x}");
                        let hit = hit.unwrap().expect("on the body");
                        assert!(
                            want.contains(&hit.cell),
                            "{case} {name}: {x} in {}",
                            hit.cell
                        );
                        let one = locator.locate(*x).unwrap().expect("on the body");
                        assert_eq!(one.cell, hit.cell, "{case} {name}: batched against scalar");
                        for owner in owners.iter() {
                            warm_points.push(*x);
                            hints.push(Hit::hint(owner.cell, owner.xi));
                        }
                    }
                    let mut answers = hints.clone();
                    locator.relocate_all(&warm_points, &mut answers);
                    for ((x, hint), answer) in warm_points.iter().zip(&hints).zip(&answers) {
                        let (Ok(Some(hint)), Ok(Some(hit))) = (hint, answer) else {
                            panic!("{case} {name}: {x} not relocated");
                        };
                        assert_eq!(hit.cell, hint.cell, "{case} {name}: {x} batched warm");
                        let one = locator.relocate(*x, &Hit::hint(hint.cell, hint.xi));
                        assert_eq!(
                            one.unwrap().map(|h| h.cell),
                            Some(hint.cell),
                            "{case} {name}"
                        );
                    }
                }
            }
        }
    }
}

/// Points off the outer faces of sheared and rotated lattices far from the origin (needle cells of
/// 1e-6 sheared by 1e3 at 1e5 among them: there the rounding length L dominates the setting) by a
/// multiple k of L, along the face's outward normal: held up to k = 1/2 (with J⁻¹'s diagonal
/// alone, not: checked), never from k = 100 (f64). The inside test accepts the points within L of
/// a cell and no more, whatever its shape.
#[test]
fn sheared_and_rotated_cells_hold_nothing_beyond_the_rounding() {
    let settings = Settings::default();
    let mut checked = 0;
    for (map_name, a) in linear_maps() {
        for (h, origin) in [
            (DVec3::splat(1e-6), DVec3::splat(1e5)),
            (DVec3::new(4.0, 0.25, 0.002), DVec3::splat(1e5)),
            (DVec3::splat(0.5), DVec3::new(-1e6, 3e5, 1e6)),
        ] {
            let lattice = Lattice::new(origin, h, [3, 3, 3]).unwrap();
            let mut body = Body::full(lattice);
            body.update_displacements(|_, x, u| {
                let r = x - origin;
                *u = DVec3::new(a[0].dot(r), a[1].dot(r), a[2].dot(r)) - r;
            })
            .unwrap();
            let locator = LatticeLocator::new(&body, settings).unwrap();
            let inside =
                cgcontact::InsideTolerance::new(&settings, &lattice, body.max_displacement());
            let mut rng = Rng(7);
            for cell in body.active_cells() {
                let ijk = lattice.cell_ijk(cell).unwrap();
                for axis in 0..3 {
                    for (side, boundary) in [(-1.0, ijk[axis] == 0), (1.0, ijk[axis] == 2)] {
                        if !boundary {
                            continue;
                        }
                        // A point of the face, and the face's outward unit normal.
                        let mut xi = rng.vec(-0.9, 0.9);
                        xi[axis] = side;
                        let on_face = point_at(&body, cell, xi);
                        let (mut du, mut dv) = (DVec3::ZERO, DVec3::ZERO);
                        du[(axis + 1) % 3] = 1e-3;
                        dv[(axis + 2) % 3] = 1e-3;
                        let normal = (point_at(&body, cell, xi + du) - on_face)
                            .cross(point_at(&body, cell, xi + dv) - on_face)
                            .normalize();
                        let inward = point_at(&body, cell, xi * DVec3::splat(0.5)) - on_face;
                        let normal = if normal.dot(inward) > 0.0 {
                            -normal
                        } else {
                            normal
                        };
                        let length = inside.length(on_face).min_element();
                        for (k, held) in [(0.5, true), (100.0, false), (1e4, false)] {
                            let x = on_face + normal * (k * length);
                            let found = locator.locate(x).unwrap().is_some();
                            assert_eq!(
                                found,
                                held,
                                "{map_name}, h {h}: {k} L = {:e} off face {axis} ({side}) of {cell} at {x}",
                                k * length
                            );
                            checked += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 1000, "{checked}");
}

/// The ξ error one locator may make on axis k for a point built from a known (cell, ξ) at `x`,
/// per axis: the kernel's own (1e-12 in f64, 1e-5 in f32) plus the rounding of each coordinate
/// j of x (ε₆₄ max(|x_j|, |origin_j|), once in the point and once in the locator's frame)
/// carried into ξ through J⁻¹ of a mildly distorted cell: 2 / h_j per unit length, times 4 for
/// the cross terms and slack. [`xi_bound`] takes the largest magnitude over the smallest spacing, which on a
/// 1 : 1e3 : 1e6 lattice allows errors of order 1 and would hide what these tests look for.
fn xi_bound_per_axis(settings: &Settings, lattice: &Lattice, x: DVec3) -> f64 {
    let base = match settings.precision {
        Precision::F64 => 1e-12,
        Precision::F32 => 1e-5,
    };
    let magnitude = x.abs().max(lattice.origin().abs());
    base + 16.0 * f64::EPSILON * (magnitude / lattice.h()).element_sum()
}

/// Strongly anisotropic cells (1 : 1e3 : 1e6 and 1 : 1 : 1e4, jitter 0.15 h) translated rigidly
/// along the coarse axis by up to 1e5 of its cells: every known point in its cell, ξ within the
/// rounding its coordinates carry, on every axis. Newton once stopped when its step fell below the
/// rounding noise of the largest coordinate carried through the finest axis: 4e-7 off in f64
/// at 1e5 cells, 2e-2 in f32 at 100, some points in the wrong cell.
#[test]
fn anisotropic_1_to_1e6_translated_1e5_cells_known_cell_and_xi_per_axis() {
    for (case, h) in [
        ("1 : 1e3 : 1e6", DVec3::new(1e-3, 1.0, 1e3)),
        ("1 : 1 : 1e4", DVec3::new(1e-2, 1e-2, 1e2)),
    ] {
        let lattice = Lattice::new(DVec3::new(0.0, -2.0, 5.0), h, [3, 3, 3]).unwrap();
        for cells in [0.0, 1e2, 1e4, 1e5] {
            let body = body(lattice, 0.0, 0.0, DVec3::new(0.0, 0.0, cells), 0.15, 77);
            let known = random_known(&body, 1000, 0.999, 5);
            for (name, settings) in precisions() {
                let locator = LatticeLocator::new(&body, settings).unwrap();
                let mut m = Measured::default();
                for &(cell, xi) in &known {
                    let x = point_at(&body, cell, xi);
                    let hit = locator.locate(x).unwrap().unwrap_or_else(|| {
                        panic!("{case}, {cells} cells, {name}: {x} ({cell}, ξ {xi}) not found")
                    });
                    assert_eq!(hit.cell, cell, "{case}, {cells} cells, {name}: ξ {xi}");
                    let error = (hit.xi - xi).abs().max_element();
                    let bound = xi_bound_per_axis(&settings, &lattice, x);
                    assert!(
                        error <= bound,
                        "{case}, {cells} cells, {name}: ξ error {error:.3e} > {bound:.3e} \
                         ({cell}, ξ {xi})"
                    );
                    m.points += 1;
                    m.max_xi_error = m.max_xi_error.max(error);
                    m.max_ratio = m.max_ratio.max(error / bound);
                }
                report(
                    "anisotropic_1_to_1e6_translated_1e5_cells_known_cell_and_xi_per_axis",
                    &format!("{case}, translated {cells:e} cells"),
                    name,
                    &m,
                );
            }
        }
    }
}

/// Points on every node, edge and face of strongly anisotropic lattices (up to 1 : 1e3 : 1e6,
/// jitter 0.15 h) have all their owners, f64 and f32. In f32 a third of them lost an owner, and
/// some were in no cell, while Newton stopped at the coarse axis's rounding noise.
#[test]
fn anisotropic_nodes_edges_and_faces_keep_every_owner() {
    for (case, h) in [
        ("1 : 100 : 1e4", DVec3::new(1.0, 100.0, 1e4)),
        ("1 : 1e3 : 1e6", DVec3::new(1.0, 1e3, 1e6)),
        ("1e4 : 1 : 1", DVec3::new(1e4, 1.0, 1.0)),
    ] {
        let lattice = Lattice::new(DVec3::ZERO, h, [2, 2, 2]).unwrap();
        let body = body(lattice, 0.0, 0.0, DVec3::ZERO, 0.15, 3);
        for (name, settings) in precisions() {
            let locator = LatticeLocator::new(&body, settings).unwrap();
            let mut samples = 0;
            for k in 0..=4u32 {
                for j in 0..=4u32 {
                    for i in 0..=4u32 {
                        let expected = owners_of_sample(&body, [i, j, k]);
                        let &(first, xi_first) = expected.first().expect("a full block");
                        let x = point_at(&body, first, xi_first);
                        let got: Vec<CellId> = locator
                            .locate_owners(x)
                            .unwrap()
                            .iter()
                            .map(|hit| hit.cell)
                            .collect();
                        let want: Vec<CellId> = expected.iter().map(|(c, _)| *c).collect();
                        assert_eq!(got, want, "{case} {name}: sample {:?} at {x}", [i, j, k]);
                        samples += 1;
                    }
                }
            }
            assert_eq!(samples, 125);
        }
    }
}

/// Newton from any start in a strongly sheared cell reaches its root: the cell of an anisotropic
/// mesh (h = 1e-3 : 1 : 1e3) whose corner 1 is lifted 1.25 cells along z more than its
/// neighbours, inverted at that corner from a grid of 9,261 starts in [−1, 1]³. From 699 of them
/// Newton crept toward the corner for more than 20 iterations (a point on the corner was reported
/// in no cell); it now starts again from the centre, which converges in 5.
#[test]
fn newton_reaches_a_sheared_corner_from_every_start() {
    use cgcontact::hex8::{NewtonOptions, Status};
    let h = DVec3::new(1e-3, 1.0, 1e3);
    let u = [
        DVec3::new(-3.4e-5, -0.0142, 37.18),
        DVec3::new(-1.4e-5, -0.0288, 1289.1),
        DVec3::new(-2.1e-5, -0.0043, 21.19),
        DVec3::new(3.9e-5, -0.0108, -27.92),
        DVec3::new(-2.3e-6, 0.0285, -29.33),
        DVec3::new(2.2e-5, -0.0427, 1233.4),
        DVec3::new(1.0e-5, -0.0476, 41.97),
        DVec3::new(-1.3e-5, 0.0004, -29.63),
    ];
    let map = Hex8Map::lattice_cell(h, &u);
    let corner = DVec3::new(1.0, -1.0, -1.0);
    let x = map.map(corner);
    let options = NewtonOptions::default();
    let mut worst = 0;
    for i in 0..=20 {
        for j in 0..=20 {
            for k in 0..=20 {
                let start = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) / 10.0 - 1.0;
                let inversion = map.invert(x, start, &options);
                assert_eq!(
                    inversion.status,
                    Status::Inside,
                    "from {start}: {inversion:?}"
                );
                assert!(
                    (inversion.xi - corner).abs().max_element() < 1e-9,
                    "from {start}"
                );
                worst = worst.max(inversion.iterations);
            }
        }
    }
    println!("MEASURED newton_reaches_a_sheared_corner_from_every_start | most iterations {worst}");
}

/// Regression (an audit): `Hex8Map::invert`'s early `Outside` (an iterate moving by less than
/// 1e-3 while 1e-2 beyond a face) ignored the rounding allowance. On a VTK-written adaptive mesh
/// at 1.5e9 with h = 1e-3, a node of 7 cells was given 3 owners: the other 4 converged to
/// ξ ≈ −1.0125, within the allowance, but Newton had already stopped. Here a uniform body at
/// 1.5e9, h = 1e-3, sheared (x += 30 z, so z's rounding reaches ξ_x) and smoothly bent (so
/// Newton takes more than one step): every node, edge, face and centre of its 27 cells must be
/// owned by exactly the cells whose closed undeformed box holds it, by the lattice (scalar and
/// batched) and by the brute-force oracle, in f64 and f32.
#[test]
fn the_early_outside_exit_keeps_owners_within_the_rounding_allowance() {
    let h = DVec3::splat(1e-3);
    let mut checked = 0;
    for origin in [DVec3::splat(1.5e9), DVec3::new(-1e9, 1.5e9, -1.5e9)] {
        let lattice = Lattice::new(origin, h, [3, 3, 3]).unwrap();
        let mut body = Body::full(lattice);
        body.update_displacements(|_, x, u| {
            let r = (x - origin) / h;
            let bend = DVec3::new(
                (2.1 * r.y + 0.3 * r.z).sin(),
                (1.7 * r.z).sin(),
                (1.3 * r.x).sin(),
            );
            *u = DVec3::new(30.0 * (x.z - origin.z), 0.0, 0.0) + bend * (0.003 * h);
        })
        .unwrap();
        body.validate().expect("no cell folds");
        let (samples, wanted) = samples_and_owners(&body);
        for (x, want) in samples.iter().zip(&wanted) {
            assert_eq!(
                &crate::common::brute_owners(&body, *x),
                want,
                "origin {origin}: brute-force owners of {x}"
            );
        }
        for (name, settings) in precisions() {
            let locator = LatticeLocator::new(&body, settings).unwrap();
            let batched = locator.locate_all(&samples);
            for ((x, want), hit) in samples.iter().zip(&wanted).zip(batched) {
                let owners = locator.locate_owners(*x).unwrap();
                let got: Vec<CellId> = owners.iter().map(|o| o.cell).collect();
                assert_eq!(&got, want, "origin {origin} {name}: owners of {x}");
                let hit = hit.unwrap().expect("on the body");
                let one = locator.locate(*x).unwrap().expect("on the body");
                assert!(
                    want.contains(&one.cell),
                    "origin {origin} {name}: {x} in {}",
                    one.cell
                );
                assert_eq!(hit, one, "origin {origin} {name}: batched against scalar");
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 2 * 2 * 343);
}
