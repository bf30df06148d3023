//! Property tests of the lattice locator against known answers and an exhaustive oracle.

use crate::common::{Rng, body, brute_owners, point_at};
use cgcontact::{
    Answer, CandidateOrder, CellId, Lattice, LatticeLocator, Locator, PointError, Settings,
};
use glam::DVec3;
use proptest::prelude::*;

fn random_lattice(rng: &mut Rng) -> Lattice {
    let h = DVec3::new(
        rng.uniform(0.1, 2.0),
        rng.uniform(0.1, 2.0),
        rng.uniform(0.1, 2.0),
    );
    let cells = [
        2 + rng.below(6) as u32,
        2 + rng.below(6) as u32,
        2 + rng.below(6) as u32,
    ];
    Lattice::new(rng.vec(-100.0, 100.0), h, cells).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Make x from a known (cell, ξ) on a randomly distorted body; locate it: same cell, ξ within 1e-12.
    #[test]
    fn round_trip_on_distorted_cells(seed in any::<u64>(), order in prop_oneof![Just(CandidateOrder::Predicted), Just(CandidateOrder::Undeformed)]) {
        let mut rng = Rng(seed);
        let lattice = random_lattice(&mut rng);
        let body = body(lattice, 0.2, 0.15, DVec3::ZERO, 0.12, seed);
        let locator = LatticeLocator::new(&body, Settings { order, ..Settings::default() }).unwrap();
        let active: Vec<CellId> = body.active_cells().collect();
        for _ in 0..200 {
            let cell = active[rng.below(active.len())];
            // Strictly inside, so the owner is unique.
            let xi = rng.vec(-0.999, 0.999);
            let x = point_at(&body, cell, xi);
            let hit = locator.locate(x).unwrap().expect("a point made inside a cell is found");
            prop_assert_eq!(hit.cell, cell);
            prop_assert!((hit.xi - xi).abs().max_element() < 1e-12, "xi {} vs {}", hit.xi, xi);
            prop_assert!(hit.residual < 1e-12 * lattice.h().max_element());
        }
    }

    /// `locate_all` runs the common path in SIMD batches (4 or 8 points per lane set); its answers must
    /// be bitwise those of `locate`, one point at a time, in both precisions and candidate orders, on
    /// distorted bodies with holes and shifts, at any scale and offset: points inside, on corners, edges and faces (ξ = ±1, 0),
    /// outside, and not finite, in a count that leaves a partial batch.
    #[test]
    fn batched_answers_are_bitwise_the_scalar_answers(
        seed in any::<u64>(),
        f32 in any::<bool>(),
        order in prop_oneof![Just(CandidateOrder::Predicted), Just(CandidateOrder::Undeformed)],
    ) {
        let mut rng = Rng(seed);
        // Any scale from 1e-9 to 1e6 and any offset up to 1e9 cells' worth.
        let shape = random_lattice(&mut rng);
        let scale = 10f64.powi(rng.below(16) as i32 - 9);
        let offset = rng.vec(-1.0, 1.0) * 10f64.powi(rng.below(10) as i32) * scale;
        let lattice = Lattice::new(offset, shape.h() * scale, shape.cells()).unwrap();
        let shift = rng.vec(-1.5, 1.5);
        let body = body(lattice, 0.2, 0.2, shift, 0.12, seed);
        let base = if f32 { Settings::f32() } else { Settings::default() };
        let locator = LatticeLocator::new(&body, Settings { order, ..base }).unwrap();
        let active: Vec<CellId> = body.active_cells().collect();
        let mut points = Vec::new();
        for _ in 0..300 {
            let cell = active[rng.below(active.len())];
            points.push(point_at(&body, cell, rng.vec(-1.0, 1.0)));
            let on_boundary = DVec3::new(rng.below(3) as f64 - 1.0, rng.below(3) as f64 - 1.0, rng.vec(-1.0, 1.0).z);
            points.push(point_at(&body, cell, on_boundary));
            points.push(lattice.origin() + (lattice.upper() - lattice.origin()) * rng.vec(-0.2, 1.2));
        }
        points.insert(rng.below(points.len()), DVec3::new(f64::NAN, 0.0, 0.0));
        points.insert(rng.below(points.len()), DVec3::splat(f64::INFINITY));
        points.push(lattice.origin());
        let batched = locator.locate_all(&points);
        let bits = |a: &Answer| a.map(|hit| hit.map(|h| (h.cell, h.xi.to_array().map(f64::to_bits), h.iterations, h.residual.to_bits(), h.inversions)));
        for (x, answer) in points.iter().zip(&batched) {
            prop_assert_eq!(bits(answer), bits(&locator.locate(*x)), "at {}", x);
        }
        prop_assert!(batched.iter().filter(|a| matches!(a, Ok(Some(_)))).count() >= 600);
    }

    /// Displacements up to 3 h (a rigid shift of up to 3 h plus a smooth field): the search is complete.
    #[test]
    fn complete_with_displacements_up_to_three_cells(seed in any::<u64>()) {
        let mut rng = Rng(seed);
        let lattice = random_lattice(&mut rng);
        let sign = rng.vec(-1.0, 1.0).signum();
        let shift = sign * rng.vec(1.5, 2.6);
        let body = body(lattice, 0.3, 0.3, shift, 0.05, seed);
        let u_max = body.max_displacement() / lattice.h();
        prop_assert!(u_max.max_element() > 1.0, "the scene must displace by more than a cell");
        let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
        let active: Vec<CellId> = body.active_cells().collect();
        for _ in 0..100 {
            let cell = active[rng.below(active.len())];
            let xi = rng.vec(-0.999, 0.999);
            let hit = locator.locate(point_at(&body, cell, xi)).unwrap().expect("found");
            prop_assert_eq!(hit.cell, cell);
        }
        // Random points anywhere near the body agree with the exhaustive oracle.
        for _ in 0..100 {
            let x = lattice.origin() + lattice.h() * shift + (lattice.upper() - lattice.origin()) * rng.vec(-0.1, 1.1);
            let oracle = brute_owners(&body, x);
            let owners: Vec<CellId> = locator.locate_owners(x).unwrap().iter().map(|h| h.cell).collect();
            prop_assert_eq!(&owners, &oracle);
            let hit = locator.locate(x).unwrap();
            prop_assert_eq!(hit.is_some(), !oracle.is_empty());
            if let Some(hit) = hit {
                prop_assert!(oracle.contains(&hit.cell));
            }
        }
    }
}

/// Every node, edge midpoint and face centre of a distorted block: all owners, sorted by cell.
#[test]
fn points_on_nodes_edges_and_faces_belong_to_every_owner() {
    let lattice = Lattice::new(
        DVec3::new(3.0, -2.0, 1.0),
        DVec3::new(0.5, 0.7, 0.3),
        [3, 3, 3],
    )
    .unwrap();
    let body = body(lattice, 0.0, 0.1, DVec3::ZERO, 0.05, 11);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let mut checked = 0;
    // Sample the lattice at half-cell steps: (2i, 2j, 2k) are nodes, one odd index an edge, etc.
    for k in 0..=6u32 {
        for j in 0..=6u32 {
            for i in 0..=6u32 {
                let half = [i, j, k];
                // The owners in lattice arithmetic: cells whose closed box contains the sample.
                let mut expected = Vec::new();
                let ranges = half.map(|v| {
                    if v % 2 == 0 {
                        (v / 2).saturating_sub(1)..=(v / 2).min(2)
                    } else {
                        v / 2..=v / 2
                    }
                });
                for ck in ranges[2].clone() {
                    for cj in ranges[1].clone() {
                        for ci in ranges[0].clone() {
                            expected.push(lattice.cell_id([ci, cj, ck]));
                        }
                    }
                }
                expected.sort();
                // Build the point from the first owner's map at the matching ξ.
                let cell = expected[0];
                let ijk = lattice.cell_ijk(cell).unwrap();
                let xi = DVec3::from_array(
                    [0, 1, 2].map(|a| half[a] as f64 - 1.0 - 2.0 * ijk[a] as f64),
                );
                let x = point_at(&body, cell, xi);
                let owners: Vec<CellId> = locator
                    .locate_owners(x)
                    .unwrap()
                    .iter()
                    .map(|h| h.cell)
                    .collect();
                assert_eq!(owners, expected, "sample {half:?} at {x}");
                let hit = locator.locate(x).unwrap().expect("on the body");
                assert!(expected.contains(&hit.cell));
                assert!(hit.xi.abs().max_element() <= 1.0);
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 343);
}

/// Points just outside the body's outer faces, far away, and non-finite.
#[test]
fn outside_and_non_finite_points() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.25), [4, 4, 4]).unwrap();
    let body = body(lattice, 0.0, 0.0, DVec3::ZERO, 0.0, 1);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let h = 0.25;
    for x in [
        DVec3::new(-1e-9 * h, 0.5, 0.5),
        DVec3::new(0.5, 1.0 + 1e-9 * h, 0.5),
        DVec3::splat(1e6),
        DVec3::splat(-3.0),
    ] {
        assert_eq!(locator.locate(x), Ok(None), "{x}");
        assert!(locator.locate_owners(x).unwrap().is_empty());
    }
    // 1e-12 h inside the boundary face: found, in the boundary cell.
    let hit = locator
        .locate(DVec3::new(1e-12 * h, 0.1, 0.1))
        .unwrap()
        .unwrap();
    assert_eq!(hit.cell, lattice.cell_id([0, 0, 0]));
    for x in [
        DVec3::new(f64::NAN, 0.5, 0.5),
        DVec3::new(0.5, f64::INFINITY, 0.5),
        DVec3::splat(f64::NEG_INFINITY),
    ] {
        assert_eq!(locator.locate(x), Err(PointError::NonFinite));
        assert_eq!(locator.locate_owners(x), Err(PointError::NonFinite));
    }
    let answers = locator.locate_all(&[DVec3::splat(0.5), DVec3::NAN, DVec3::splat(0.3)]);
    assert!(answers[0].unwrap().is_some() && answers[2].unwrap().is_some());
    assert_eq!(answers[1], Err(PointError::NonFinite));
}

/// The same answers, in the same order, on 1 and 2 threads.
#[test]
fn results_identical_for_one_and_two_threads() {
    let lattice = Lattice::new(
        DVec3::new(10.0, 20.0, 30.0),
        DVec3::new(0.2, 0.3, 0.25),
        [12, 10, 8],
    )
    .unwrap();
    let body = body(lattice, 0.1, 0.2, DVec3::new(0.5, 0.0, -0.3), 0.1, 5);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let mut rng = Rng(99);
    let points: Vec<DVec3> = (0..20_000)
        .map(|_| lattice.origin() + (lattice.upper() - lattice.origin()) * rng.vec(-0.05, 1.05))
        .collect();
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| locator.locate_all(&points))
    };
    let one = run(1);
    let two = run(2);
    assert_eq!(one, two);
    let sequential: Vec<_> = points.iter().map(|&x| locator.locate(x)).collect();
    assert_eq!(one, sequential);
    assert!(one.iter().filter(|a| matches!(a, Ok(Some(_)))).count() > 10_000);
}
