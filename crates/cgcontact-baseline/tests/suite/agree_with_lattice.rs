//! Brute force and the R-tree agree with the lattice locator on generated scenes: volume points with
//! known answers, points on shared faces/edges/nodes, points within 1e-9 h of the outer boundary (both
//! sides), points anywhere in the body's box, and points far outside.

use crate::common;

use crate::common::{Kind, Spec};
use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, PointError, Settings};
use cgcontact_baseline::{BruteForce, RTree};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Checks every point; returns how many were located (so callers can check the scene is not trivial).
///
/// `xi_tol` bounds the ξ difference between strategies; against a known ξ the bound adds the rounding
/// of the generated point's global coordinates. Where the inside tolerance exceeds the ±1e-9 h offset
/// of the boundary points (f32, or coordinates far from the origin: the tolerance absorbs the rounding
/// of the data), only the strategies' agreement is checked there.
fn check_scene(spec: &Spec, points_per_kind: usize, settings: Settings, xi_tol: f64) -> usize {
    check_body(&common::body(spec), spec, points_per_kind, settings, xi_tol)
}

/// [`check_scene`] on `body`, a body of `spec` whose displacements may have been changed since.
fn check_body(
    body: &cgcontact::Body,
    spec: &Spec,
    points_per_kind: usize,
    settings: Settings,
    xi_tol: f64,
) -> usize {
    let body = body.clone();
    let lattice = LatticeLocator::new(&body, settings).unwrap();
    let brute = BruteForce::new(&body, settings).unwrap();
    let rtree = RTree::new(&body, settings).unwrap();
    // What the kernel's rounding grows with: |u − T| in f32's frame, |u| in f64.
    let u_max = cgcontact_baseline::BodyRef::Uniform(&body)
        .frame(&settings)
        .reach();
    let mut located = 0;
    for (index, (x, kind)) in common::points(&body, points_per_kind, spec.seed + 1)
        .into_iter()
        .enumerate()
    {
        let boundary_resolved = 2e-9
            > 2.0
                * settings
                    .inside_tolerance(body.lattice(), u_max, x)
                    .max_element();
        let known_tol = xi_tol + 64.0 * f64::EPSILON * x.abs().max_element() / spec.h.min_element();
        let context = || format!("point {index} {x} ({kind:?}) in {spec:?}");
        let expected = lattice.locate(x).unwrap();
        let owners = brute.locate_owners(x).unwrap();
        let first = brute.locate(x).unwrap();
        let by_tree = rtree.locate(x).unwrap();
        let tree_owners = rtree.locate_owners(x).unwrap();

        // Same found / not found.
        assert_eq!(
            expected.is_some(),
            !owners.is_empty(),
            "lattice vs brute owners, {}",
            context()
        );
        assert_eq!(
            first.is_some(),
            !owners.is_empty(),
            "brute locate vs owners, {}",
            context()
        );
        assert_eq!(
            by_tree.is_some(),
            !owners.is_empty(),
            "rtree vs brute, {}",
            context()
        );
        // Brute force answers the lowest owner; so does the R-tree (it tries its candidates ascending).
        if let Some(hit) = first {
            assert_eq!(hit.cell, owners[0].cell, "{}", context());
            assert_eq!(by_tree.unwrap().cell, hit.cell, "{}", context());
        }
        let cells = |o: &cgcontact::Owners| o.iter().map(|h| h.cell).collect::<Vec<_>>();
        assert_eq!(
            cells(&tree_owners),
            cells(&owners),
            "rtree owners, {}",
            context()
        );
        // The lattice's cell is among the owners, at the same ξ.
        if let Some(hit) = expected {
            located += 1;
            let owner = owners
                .iter()
                .find(|o| o.cell == hit.cell)
                .unwrap_or_else(|| {
                    panic!(
                        "lattice cell {} not among brute owners {:?}, {}",
                        hit.cell,
                        cells(&owners),
                        context()
                    )
                });
            assert!(
                (owner.xi - hit.xi).abs().max_element() <= xi_tol,
                "ξ {} vs {}, {}",
                owner.xi,
                hit.xi,
                context()
            );
        }
        // Known answers.
        match kind {
            Kind::Volume { cell, xi } | Kind::Shared { cell, xi } => {
                let owner = owners
                    .iter()
                    .find(|o| o.cell == cell)
                    .unwrap_or_else(|| panic!("known cell missed, {}", context()));
                assert!(
                    (owner.xi - xi).abs().max_element() <= known_tol,
                    "ξ {} vs known {xi}, {}",
                    owner.xi,
                    context()
                );
            }
            Kind::NearBoundary { .. } if !boundary_resolved => {}
            Kind::NearBoundary {
                cell,
                outside: false,
            } => {
                assert!(
                    owners.iter().any(|o| o.cell == cell),
                    "known cell missed, {}",
                    context()
                );
            }
            Kind::NearBoundary {
                cell,
                outside: true,
            } => {
                assert!(
                    owners.iter().all(|o| o.cell != cell),
                    "1e-9 h outside yet inside, {}",
                    context()
                );
            }
            Kind::Far => assert!(owners.is_empty(), "{}", context()),
            Kind::InBox => {}
        }
        // Inversions are counted: at least one per hit.
        for hit in [expected, first, by_tree].into_iter().flatten() {
            assert!(hit.inversions >= 1);
        }
    }
    located
}

const MILD: Spec = Spec {
    origin: DVec3::new(-1.0, 0.5, 2.0),
    h: DVec3::new(0.25, 0.25, 0.25),
    cells: [8, 7, 6],
    amplitude: 0.5,
    jitter: 0.1,
    holes: 0.0,
    seed: 11,
};

#[test]
fn mild_scene() {
    assert!(check_scene(&MILD, 300, Settings::default(), 1e-10) > 600);
}

#[test]
fn large_displacements_jitter_and_holes() {
    // Displacements up to 2 h (more than a cell), seeded jitter, 15 % of cells missing.
    let spec = Spec {
        amplitude: 2.0,
        jitter: 0.15,
        holes: 0.15,
        cells: [12, 10, 8],
        seed: 23,
        ..MILD
    };
    assert!(
        common::body(&spec).max_displacement().max_element() > 1.5 * spec.h.x,
        "displacements exceed a cell"
    );
    assert!(check_scene(&spec, 300, Settings::default(), 1e-10) > 600);
}

/// Mean Newton inversions per point of the lattice locator over `points`, failed ones included.
fn inversions_per_point(locator: &LatticeLocator<'_>, points: &[DVec3]) -> f64 {
    let tried: u64 = points
        .iter()
        .map(|&x| u64::from(locator.locate_counted(x).1))
        .sum();
    tried as f64 / points.len() as f64
}

/// A rigid translation of 10 cells on every axis: the search box of each point is its own cell's
/// neighbourhood, not 21³ cells (30 s against 0.5 s before the displacement range bounded it).
#[test]
fn rigid_translation_of_ten_cells_agrees_and_costs_one_inversion() {
    let spec = Spec {
        holes: 0.1,
        seed: 53,
        ..MILD
    };
    let mut body = common::body(&spec);
    body.update_displacements(|_, _, u| *u += 10.0 * spec.h)
        .unwrap();
    assert!(check_body(&body, &spec, 300, Settings::default(), 1e-10) > 600);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let points: Vec<DVec3> = common::points(&body, 300, 7)
        .into_iter()
        .map(|p| p.0)
        .collect();
    let per_point = inversions_per_point(&locator, &points);
    assert!(per_point < 1.5, "{per_point} inversions per point");
}

/// f32 on a body moved rigidly by 1e5 cells (plus the scene's mild field): f32 used to round each
/// displacement by 1e-2 of a cell. The kernel's frame takes the common translation out, in every
/// strategy alike, so they agree with each other and with the known ξ to 1e-4, as unmoved.
#[test]
fn rigid_translation_of_1e5_cells_in_f32_agrees() {
    let spec = Spec {
        holes: 0.1,
        seed: 61,
        ..MILD
    };
    let mut body = common::body(&spec);
    body.update_displacements(|_, _, u| *u += 1e5 * spec.h)
        .unwrap();
    assert!(check_body(&body, &spec, 300, Settings::f32(), 1e-4) > 600);
}

/// Large shears (up to 4 cells): the per-block displacement ranges are built and the search visits
/// only the cells whose blocks reach a point; the answers are still brute force's.
#[test]
fn displacements_of_four_cells_agree_through_the_block_ranges() {
    let spec = Spec {
        amplitude: 4.0,
        jitter: 0.1,
        holes: 0.1,
        cells: [14, 12, 10],
        seed: 59,
        ..MILD
    };
    let body = common::body(&spec);
    let u_max = body.max_displacement() / spec.h;
    assert!(u_max.x > 4.0 && u_max.y > 3.0, "{u_max}");
    // An f64 locator keeps nothing on the heap but the block ranges.
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    assert!(locator.heap_bytes() > 0, "the block ranges were not built");
    assert!(check_scene(&spec, 300, Settings::default(), 1e-10) > 600);
    assert!(check_scene(&spec, 150, Settings::f32(), 1e-4) > 300);
}

/// One node moved 30 cells on every axis (its cells invert): every point of a valid cell is still
/// found, at its known ξ, and a point costs a few inversions, not one per cell of the 61³ box
/// around it (85 s for 6,700 points on the seed's block before per-block ranges).
#[test]
fn one_far_moved_node_is_searched_only_where_it_reaches() {
    let spec = Spec {
        holes: 0.1,
        cells: [14, 12, 10],
        seed: 61,
        ..MILD
    };
    let mut body = common::body(&spec);
    let spike = body.lattice().node_index([7, 6, 5]);
    body.update_displacements(|node, _, u| {
        if node == spike {
            *u += 30.0 * spec.h;
        }
    })
    .unwrap();
    let inverted: Vec<_> = body.inverted_cells().into_iter().map(|(c, _)| c).collect();
    assert!(!inverted.is_empty());
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    assert!(locator.heap_bytes() > 0, "the block ranges were not built");
    let brute = BruteForce::new(&body, Settings::default()).unwrap();
    let points = common::points(&body, 300, 3);
    let mut checked = 0;
    for (x, kind) in &points {
        let owners = brute.locate_owners(*x).unwrap();
        let found = locator.locate_owners(*x).unwrap();
        let cells = |o: &cgcontact::Owners| o.iter().map(|h| h.cell).collect::<Vec<_>>();
        // Where only valid cells are involved, the owners are brute force's.
        if cells(&owners)
            .iter()
            .chain(&cells(&found))
            .all(|c| !inverted.contains(c))
        {
            assert_eq!(cells(&found), cells(&owners), "at {x} ({kind:?})");
            checked += 1;
        }
        if let Kind::Volume { cell, xi } | Kind::Shared { cell, xi } = kind
            && !inverted.contains(cell)
        {
            let hit = found
                .iter()
                .find(|h| h.cell == *cell)
                .unwrap_or_else(|| panic!("known {cell} missed at {x}"));
            assert!((hit.xi - *xi).abs().max_element() < 1e-9);
        }
    }
    assert!(checked > 1000, "{checked}");
    let xs: Vec<DVec3> = points.iter().map(|p| p.0).collect();
    let per_point = inversions_per_point(&locator, &xs);
    assert!(per_point < 3.0, "{per_point} inversions per point");
}

#[test]
fn anisotropic_and_far_from_origin() {
    let spec = Spec {
        origin: DVec3::new(1.0e5, -3.0e5, 2.0e4),
        h: DVec3::new(0.5, 0.25, 0.1),
        amplitude: 1.5,
        jitter: 0.1,
        holes: 0.1,
        cells: [7, 8, 9],
        seed: 37,
    };
    assert!(check_scene(&spec, 300, Settings::default(), 1e-10) > 600);
}

#[test]
fn single_precision_kernel() {
    // f32 in the local frame: same cells, ξ to single precision, far from the origin too.
    let spec = Spec {
        origin: DVec3::new(3.0e4, 1.0e4, -2.0e4),
        amplitude: 1.0,
        holes: 0.1,
        seed: 41,
        ..MILD
    };
    assert!(check_scene(&spec, 150, Settings::f32(), 1e-4) > 300);
}

#[test]
fn non_finite_points_are_errors() {
    let body = common::body(&MILD);
    let brute = BruteForce::new(&body, Settings::default()).unwrap();
    let rtree = RTree::new(&body, Settings::default()).unwrap();
    for x in [
        DVec3::new(f64::NAN, 0.0, 0.0),
        DVec3::new(0.0, f64::INFINITY, 0.0),
    ] {
        assert_eq!(brute.locate(x), Err(PointError::NonFinite));
        assert_eq!(rtree.locate(x), Err(PointError::NonFinite));
        assert_eq!(rtree.locate_owners(x).unwrap_err(), PointError::NonFinite);
    }
    let answers = brute.locate_all(&[DVec3::NAN, DVec3::splat(-50.0)]);
    assert_eq!(answers, vec![Err(PointError::NonFinite), Ok(None)]);
    // The trait's unordered batch: input order.
    let (mut order, mut out) = (vec![7; 5], Vec::new());
    brute.locate_all_unordered_into(&[DVec3::splat(-50.0), DVec3::NAN], &mut order, &mut out);
    assert_eq!(order, [0, 1]);
    assert_eq!(out, [Ok(None), Err(PointError::NonFinite)]);
    assert!(rtree.build_time().as_secs_f64() >= 0.0);
    assert_eq!(rtree.len(), body.active_count());
}

#[test]
fn bad_settings_are_errors() {
    let body = common::body(&MILD);
    let bad = Settings {
        max_iter: 0,
        ..Settings::default()
    };
    assert!(BruteForce::new(&body, bad).is_err());
    assert!(RTree::new(&body, bad).is_err());
}

/// The largest inside tolerance `Settings::validate` accepts: points up to 1.5 times that far
/// beyond faces, edges and corners of a distorted body with holes, and anywhere in its box. The
/// lattice's owner lists are brute force's (the search's filters widen enough for it), and
/// `locate` answers one of them.
#[test]
fn the_largest_inside_tolerance_keeps_every_owner() {
    let spec = Spec {
        amplitude: 1.5,
        jitter: 0.15,
        holes: 0.2,
        cells: [7, 6, 5],
        seed: 41,
        ..MILD
    };
    let body = common::body(&spec);
    let settings = Settings {
        inside_tol: Settings::MAX_INSIDE_TOL,
        ..Settings::default()
    };
    let lattice = LatticeLocator::new(&body, settings).unwrap();
    let brute = BruteForce::new(&body, settings).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let reach = 1.0 + 1.5 * Settings::MAX_INSIDE_TOL;
    let mut points: Vec<DVec3> = Vec::new();
    for cell in body.active_cells() {
        for _ in 0..12 {
            let xi = DVec3::new(
                rng.random_range(-reach..=reach),
                rng.random_range(-reach..=reach),
                rng.random_range(-reach..=reach),
            );
            points.push(common::point_at(&body, cell, xi));
        }
    }
    points.extend(common::points(&body, 200, 9).into_iter().map(|(x, _)| x));
    let mut held = 0;
    for (p, &x) in points.iter().enumerate() {
        let cells = |o: cgcontact::Owners| o.iter().map(|h| h.cell).collect::<Vec<_>>();
        let owners = cells(brute.locate_owners(x).unwrap());
        assert_eq!(
            cells(lattice.locate_owners(x).unwrap()),
            owners,
            "point {p} at {x}"
        );
        let one = lattice.locate(x).unwrap().map(|h| h.cell);
        assert_eq!(one.is_some(), !owners.is_empty(), "point {p} at {x}");
        assert!(one.is_none_or(|c| owners.contains(&c)), "point {p} at {x}");
        held += usize::from(owners.len() > 1);
    }
    assert!(held > 500, "only {held} points with several owners");
}
