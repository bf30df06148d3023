//! Every baseline on adaptive bodies, against the adaptive locator and the brute-force oracle: on
//! random refinements (balanced and not, with holes) with points of known (leaf, ξ), points on
//! shared and hanging faces, edges and nodes, points anywhere in the box and far outside. A body of
//! one level built through the adaptive path answers bitwise as the uniform body, and the filters'
//! per-level radii find every leaf of an undeformed body.

use crate::common;

use crate::common::Kind;
use crate::common::adaptive::AdaptiveSpec;
use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, CellId, Hit, InsideTolerance, Lattice, Leaf, Locator, Owners,
    PointError, Settings,
};
use cgcontact_baseline::{
    BodyRef, BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree,
    RadiusRule, SEED_TOL,
};

const BASE: AdaptiveSpec = AdaptiveSpec {
    origin: DVec3::new(-3.5, 1.0, 0.25),
    h: DVec3::new(0.5, 0.25, 0.4),
    cells: [3, 4, 2],
    levels: 3,
    splits: 14,
    balanced: false,
    holes: 0.0,
    strain: 0.04,
    jitter: 0.05,
    seed: 0,
};

/// The scenes: unbalanced and balanced, with and without holes, one far from the origin.
fn specs() -> Vec<AdaptiveSpec> {
    let mut specs = Vec::new();
    for seed in 0..6 {
        specs.push(AdaptiveSpec {
            balanced: seed % 2 == 1,
            holes: if seed % 3 == 0 { 0.2 } else { 0.0 },
            seed,
            ..BASE
        });
    }
    specs.push(AdaptiveSpec {
        origin: DVec3::new(2.0e4, -1.0e4, 3.0e3),
        levels: 4,
        splits: 10,
        holes: 0.1,
        strain: 0.1,
        seed: 40,
        ..BASE
    });
    specs
}

fn cells(owners: &Owners) -> Vec<CellId> {
    owners.iter().map(|hit| hit.cell).collect()
}

/// How a filter that may miss fared against the oracle.
#[derive(Debug, Default)]
struct Tally {
    located: usize,
    missed: usize,
}

/// `hit`, answered by a filter that inverts its candidates exactly from ξ = 0 like brute force, is
/// one of the oracle's owners with the same ξ, bit for bit; and the filter answers exactly when an
/// owner passes it: `gap(owner)` is the owner's distance to the point (from its nearest corner, or
/// its centroid) less the filter's radius for it (points within 1e-9 of the radius are not judged).
fn check_filter(
    label: &str,
    hit: Option<Hit>,
    owners: &Owners,
    gap: impl Fn(CellId) -> f64,
    tally: &mut Tally,
    at: &str,
) {
    let gaps: Vec<f64> = owners.iter().map(|o| gap(o.cell)).collect();
    let passes = gaps.iter().any(|&g| g < -1e-9);
    let fails = gaps.iter().all(|&g| g > 1e-9);
    match hit {
        Some(hit) => {
            tally.located += 1;
            let owner = owners
                .iter()
                .find(|o| o.cell == hit.cell)
                .unwrap_or_else(|| {
                    panic!(
                        "{label}: {} is no owner {:?}, {at}",
                        hit.cell,
                        cells(owners)
                    )
                });
            assert_eq!(owner.xi, hit.xi, "{label}, {at}");
            assert!(
                !fails,
                "{label} found what its radius excludes, gaps {gaps:?}, {at}"
            );
        }
        None => {
            tally.missed += usize::from(!owners.is_empty());
            assert!(
                !passes,
                "{label} missed an owner within its radius, gaps {gaps:?}, {at}"
            );
        }
    }
}

/// Checks every strategy on the scene of `spec` with `settings`; returns the filters' tallies
/// (centroid, node-radius exact) and the number of points located.
fn check_scene(spec: &AdaptiveSpec, settings: Settings, xi_tol: f64) -> (Tally, Tally, usize) {
    let body = common::adaptive::body(spec);
    assert!(body.finest_level() >= 2, "{spec:?}: a refinement to test");
    let adaptive = AdaptiveLocator::new(&body, settings).unwrap();
    let brute = BruteForce::new(&body, settings).unwrap();
    let rtree = RTree::new(&body, settings).unwrap();
    let centroid = CentroidRadius::new(&body, settings).unwrap();
    let noderad = NodeRadius::new(&body, settings).unwrap();
    let seed = NodeRadius::with_options(
        &body,
        settings,
        NodeRadiusOptions {
            inversion: Inversion::SeedFaithful,
            ..Default::default()
        },
    )
    .unwrap();
    let h_min = body.spacing(body.finest_level()).min_element();
    let u_max = body.max_displacement();
    let finest = body.spacing(body.finest_level());
    let inside = InsideTolerance::with_spacing(&settings, body.lattice().origin(), finest, u_max);
    let (mut by_centroid, mut by_noderad, mut located) = (Tally::default(), Tally::default(), 0);
    for (index, (x, kind)) in common::adaptive::points(&body, 150, spec.seed + 1)
        .into_iter()
        .enumerate()
    {
        let at = format!("point {index} {x} ({kind:?}) in {spec:?}");
        // Against a known ξ the bound adds the rounding of the generated point's global
        // coordinates (half an ulp of |x|, over the finest cell's half-width, with margin).
        let known_tol = xi_tol + 8.0 * f64::EPSILON * x.abs().max_element() / h_min;
        let boundary_resolved = 2e-9 > 2.0 * inside.at(x).max_element();
        let owners = brute.locate_owners(x).unwrap();

        // The adaptive locator finds exactly the oracle's owners, at the same ξ.
        let found = adaptive.locate_owners(x).unwrap();
        assert_eq!(cells(&found), cells(&owners), "adaptive owners, {at}");
        for (hit, owner) in found.iter().zip(&owners) {
            assert!(
                (hit.xi - owner.xi).abs().max_element() <= xi_tol,
                "ξ {} vs {}, {at}",
                hit.xi,
                owner.xi
            );
        }
        let first = brute.locate(x).unwrap();
        let expected = adaptive.locate(x).unwrap();
        assert_eq!(
            first.map(|h| h.cell),
            owners.first().map(|h| h.cell),
            "{at}"
        );
        assert_eq!(
            expected.is_some(),
            first.is_some(),
            "adaptive vs brute, {at}"
        );
        if let Some(hit) = expected {
            located += 1;
            assert!(owners.iter().any(|o| o.cell == hit.cell), "{at}");
        }

        // The R-tree is complete: the same owners, the same lowest owner, the same ξ bit for bit.
        let tree_owners = rtree.locate_owners(x).unwrap();
        assert_eq!(cells(&tree_owners), cells(&owners), "rtree owners, {at}");
        for (hit, owner) in tree_owners.iter().zip(&owners) {
            assert_eq!(hit.xi, owner.xi, "rtree ξ, {at}");
        }
        let by_tree = rtree.locate(x).unwrap();
        assert_eq!(
            by_tree.map(|h| (h.cell, h.xi)),
            first.map(|h| (h.cell, h.xi)),
            "{at}"
        );

        // The exact filters may miss (where no owner is within the radius of its level), never
        // answer a cell the oracle does not.
        let level = |cell: CellId| {
            body.leaves()
                .get(cell.index())
                .expect("a leaf of the body")
                .level
        };
        let corners = |cell: CellId| body.corners(cell).unwrap();
        let from_centroid = |cell: CellId| {
            let centre = corners(cell).iter().sum::<DVec3>() / 8.0;
            centre.distance(x) - centroid.level_radius(level(cell)).unwrap()
        };
        let from_corners = |cell: CellId| {
            let nearest = corners(cell)
                .iter()
                .map(|c| c.distance(x))
                .fold(f64::INFINITY, f64::min);
            nearest - noderad.level_radius(level(cell)).unwrap()
        };
        let hit = centroid.locate(x).unwrap();
        check_filter(
            "centroid",
            hit,
            &owners,
            from_centroid,
            &mut by_centroid,
            &at,
        );
        let hit = noderad.locate(x).unwrap();
        check_filter("noderad", hit, &owners, from_corners, &mut by_noderad, &at);
        for filtered in [
            centroid.locate_owners(x).unwrap(),
            noderad.locate_owners(x).unwrap(),
        ] {
            for hit in &filtered {
                let owner = owners.iter().find(|o| o.cell == hit.cell);
                assert_eq!(owner.map(|o| o.xi), Some(hit.xi), "filter owners, {at}");
            }
        }

        // The seed's Newton stops within its absolute tolerance of the point, at some |ξ| ≤ 1 of
        // the leaf it answers (the leaf need not hold the point: its flaw).
        if let Some(hit) = seed.locate(x).unwrap() {
            assert!(hit.xi.abs().max_element() <= 1.0, "seed ξ {}, {at}", hit.xi);
            let reached = body.point_at(hit.cell, hit.xi).unwrap();
            assert!(
                reached.distance(x) <= SEED_TOL * (1.0 + 1e-12),
                "seed stops {} from the point, {at}",
                reached.distance(x)
            );
        }

        // Known answers.
        match kind {
            Kind::Volume { cell, xi } => {
                // Strictly inside one leaf of a conforming mesh: its only owner.
                assert_eq!(cells(&owners), [cell], "known leaf, {at}");
                for (label, hit) in [("brute", first), ("rtree", by_tree), ("adaptive", expected)] {
                    let hit = hit.unwrap_or_else(|| panic!("{label} missed, {at}"));
                    assert_eq!(hit.cell, cell, "{label}, {at}");
                    assert!(
                        (hit.xi - xi).abs().max_element() <= known_tol,
                        "{label}: ξ {} vs known {xi}, {at}",
                        hit.xi
                    );
                }
            }
            Kind::Shared { cell, xi } => {
                let owner = owners
                    .iter()
                    .find(|o| o.cell == cell)
                    .unwrap_or_else(|| panic!("known leaf {cell} missed, {at}"));
                assert!(
                    (owner.xi - xi).abs().max_element() <= known_tol,
                    "ξ {} vs known {xi}, {at}",
                    owner.xi
                );
            }
            // Where the inside tolerance exceeds the offset (far from the origin), only the
            // strategies' agreement above is checked.
            Kind::NearBoundary { .. } if !boundary_resolved => {}
            Kind::NearBoundary { cell, outside } => assert_eq!(
                owners.iter().any(|o| o.cell == cell),
                !outside,
                "2e-9 in ξ off an outer face, {at}"
            ),
            Kind::Far => assert!(owners.is_empty(), "{at}"),
            Kind::InBox => {}
        }
    }
    (by_centroid, by_noderad, located)
}

#[test]
fn every_strategy_agrees_with_the_adaptive_locator() {
    for spec in specs() {
        let (centroid, noderad, located) = check_scene(&spec, Settings::default(), 1e-12);
        println!("{located} located; centroid {centroid:?}, noderad {noderad:?}");
        assert!(located > 300, "{located} located in {spec:?}");
        // The per-level radii keep the filters useful (they are not complete: the node radius
        // loses the centres of these anisotropic cells, as on uniform bodies).
        for (label, tally) in [("centroid", centroid), ("noderad", noderad)] {
            assert!(
                tally.missed * 4 <= tally.located,
                "{label}: {tally:?} in {spec:?}"
            );
        }
    }
}

#[test]
fn single_precision_kernel_agrees_with_the_adaptive_locator() {
    for spec in specs().into_iter().step_by(2) {
        check_scene(&spec, Settings::f32(), 1e-5);
    }
}

/// An adaptive body of one level on the leaves of a uniform body (with holes), same displacements:
/// every strategy answers bitwise as on the uniform body, leaf i standing for the i-th active cell.
#[test]
fn a_single_level_body_answers_as_the_uniform_body() {
    let spec = common::Spec {
        origin: DVec3::new(-1.0, 0.5, 2.0),
        h: DVec3::new(0.25, 0.2, 0.3),
        cells: [7, 6, 5],
        amplitude: 0.8,
        jitter: 0.1,
        holes: 0.15,
        seed: 71,
    };
    let uniform = common::body(&spec);
    let lattice = uniform.lattice();
    let active: Vec<CellId> = uniform.active_cells().collect();
    let leaves: Vec<Leaf> = active
        .iter()
        .map(|&cell| Leaf::new(0, lattice.cell_ijk(cell).unwrap()))
        .collect();
    let mut adaptive = AdaptiveBody::from_leaves(*lattice, leaves).unwrap();
    adaptive.set_displacements(uniform.displacements()).unwrap();
    for (leaf, &cell) in active.iter().enumerate() {
        assert_eq!(adaptive.corners(CellId(leaf as u32)), uniform.corners(cell));
    }
    let settings = Settings::default();
    type Build<'b> = fn(BodyRef<'b>, Settings) -> Box<dyn Locator + 'b>;
    let strategies: [(&str, Build); 5] = [
        ("brute", |b, s| Box::new(BruteForce::new(b, s).unwrap())),
        ("rtree", |b, s| Box::new(RTree::new(b, s).unwrap())),
        ("centroid", |b, s| {
            Box::new(CentroidRadius::new(b, s).unwrap())
        }),
        ("noderad", |b, s| Box::new(NodeRadius::new(b, s).unwrap())),
        ("noderad-seed", |b, s| {
            let seed = NodeRadiusOptions {
                inversion: Inversion::SeedFaithful,
                ..Default::default()
            };
            Box::new(NodeRadius::with_options(b, s, seed).unwrap())
        }),
    ];
    let to_uniform = |hit: Hit| Hit {
        cell: active[hit.cell.index()],
        ..hit
    };
    let points = common::points(&uniform, 150, 5);
    for (label, build) in strategies {
        let on_uniform = build(BodyRef::Uniform(&uniform), settings);
        let on_adaptive = build(BodyRef::Adaptive(&adaptive), settings);
        let mut located = 0;
        for (x, kind) in &points {
            let expected = on_uniform.locate(*x).unwrap();
            located += usize::from(expected.is_some());
            assert_eq!(
                on_adaptive.locate(*x).unwrap().map(to_uniform),
                expected,
                "{label} at {x} ({kind:?})"
            );
            let owners: Vec<Hit> = on_adaptive
                .locate_owners(*x)
                .unwrap()
                .into_iter()
                .map(to_uniform)
                .collect();
            assert_eq!(
                owners,
                on_uniform.locate_owners(*x).unwrap().to_vec(),
                "{label} at {x}"
            );
        }
        assert!(located > 300, "{label}: {located}");
    }
    // The filters' radii are the uniform rule's (node positions differ in rounding only: the
    // uniform body's pass through the global origin).
    let centroid = |b: BodyRef| CentroidRadius::new(b, settings).unwrap().radius();
    assert_eq!(
        centroid(BodyRef::Adaptive(&adaptive)),
        centroid(BodyRef::Uniform(&uniform))
    );
    let noderad = |b: BodyRef| NodeRadius::new(b, settings).unwrap().radius();
    let (a, u) = (
        noderad(BodyRef::Adaptive(&adaptive)),
        noderad(BodyRef::Uniform(&uniform)),
    );
    assert!((a - u).abs() <= 1e-14 * u, "{a} vs {u}");
}

/// An undeformed body of cubic base cells refined 3 levels without balance: the node-radius rule
/// gives each level its own edge (the finest edge alone would lose the centre of every coarser
/// leaf), the centroid rule each level's half-diagonal, and both then find every known point.
#[test]
fn per_level_radii_find_every_leaf_of_an_undeformed_body() {
    let spec = AdaptiveSpec {
        origin: DVec3::new(1.0, -2.0, 0.5),
        h: DVec3::splat(0.5),
        cells: [3, 3, 2],
        splits: 12,
        strain: 0.0,
        jitter: 0.0,
        seed: 81,
        ..BASE
    };
    let body = common::adaptive::body(&spec);
    let settings = Settings::default();
    let centroid = CentroidRadius::new(&body, settings).unwrap();
    let noderad = NodeRadius::new(&body, settings).unwrap();
    let finest = body.finest_level();
    assert_eq!(finest, 3);
    let mut levels = [false; 4];
    for leaf in body.leaves() {
        levels[usize::from(leaf.level)] = true;
    }
    for (level, present) in levels.into_iter().enumerate() {
        let edge = 0.5 / f64::from(1u32 << level);
        let node = noderad.level_radius(level as u8).unwrap();
        let half_diagonal = centroid.level_radius(level as u8).unwrap();
        if present {
            assert_eq!(node, edge, "level {level}");
            assert!(
                (half_diagonal - edge * 3f64.sqrt() / 2.0).abs() < 1e-15,
                "level {level}"
            );
        } else {
            assert_eq!((node, half_diagonal), (0.0, 0.0), "level {level}");
        }
    }
    assert_eq!(noderad.level_radius(finest + 1), None);
    assert_eq!(noderad.radius(), 0.5);

    let fixed = NodeRadius::with_options(
        &body,
        settings,
        NodeRadiusOptions {
            radius: RadiusRule::Fixed(noderad.level_radius(finest).unwrap()),
            ..Default::default()
        },
    )
    .unwrap();
    let mut missed_by_fixed = 0;
    for (x, kind) in common::adaptive::points(&body, 200, 3) {
        let Kind::Volume { cell, xi } = kind else {
            continue;
        };
        for (label, strategy) in [
            ("centroid", &centroid as &dyn Locator),
            ("noderad", &noderad),
        ] {
            let hit = strategy
                .locate(x)
                .unwrap()
                .unwrap_or_else(|| panic!("{label} missed {cell} at {x}"));
            assert_eq!(hit.cell, cell, "{label} at {x}");
            assert!((hit.xi - xi).abs().max_element() <= 1e-12, "{label} at {x}");
        }
        missed_by_fixed += usize::from(fixed.locate(x).unwrap().is_none());
    }
    assert!(missed_by_fixed > 20, "{missed_by_fixed}");
}

#[test]
fn non_finite_points_and_bad_settings_are_errors() {
    let body = common::adaptive::body(&BASE);
    let settings = Settings::default();
    let strategies: Vec<Box<dyn Locator + '_>> = vec![
        Box::new(BruteForce::new(&body, settings).unwrap()),
        Box::new(RTree::new(&body, settings).unwrap()),
        Box::new(CentroidRadius::new(&body, settings).unwrap()),
        Box::new(NodeRadius::new(&body, settings).unwrap()),
    ];
    for strategy in &strategies {
        for x in [
            DVec3::new(f64::NAN, 0.0, 0.0),
            DVec3::new(0.0, f64::INFINITY, 0.0),
        ] {
            assert_eq!(strategy.locate(x), Err(PointError::NonFinite));
            assert_eq!(
                strategy.locate_owners(x).unwrap_err(),
                PointError::NonFinite
            );
        }
        assert_eq!(strategy.locate(DVec3::splat(1e3)), Ok(None));
    }
    assert_eq!(
        RTree::new(&body, settings).unwrap().len(),
        body.cell_count()
    );
    let bad = Settings {
        max_iter: 0,
        ..settings
    };
    assert!(BruteForce::new(&body, bad).is_err());
    assert!(RTree::new(&body, bad).is_err());
    assert!(CentroidRadius::new(&body, bad).is_err());
    assert!(NodeRadius::new(&body, bad).is_err());
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [1, 1, 1]).unwrap();
    let one = AdaptiveBody::from_leaves(lattice, vec![Leaf::new(0, [0, 0, 0])]).unwrap();
    assert!(matches!(
        BruteForce::new(&one, settings).unwrap().body(),
        BodyRef::Adaptive(_)
    ));
}

/// Far from the origin the inside tolerance grows with |x| / h, h the finest spacing along the
/// axis (the adaptive locator's definition): points off outer faces by half of it are inside for
/// every strategy, by twice it outside. A strategy taking h_min from the base lattice would call the
/// first outside.
#[test]
fn every_strategy_uses_the_adaptive_locators_inside_tolerance() {
    let spec = AdaptiveSpec {
        origin: DVec3::new(1.0e5, -4.0e4, 2.0e4),
        h: DVec3::splat(0.25),
        splits: 30,
        seed: 91,
        ..BASE
    };
    let body = common::adaptive::body(&spec);
    let settings = Settings::default();
    let h_min = body.spacing(body.finest_level()).min_element();
    assert!(h_min < 0.25 / 4.0, "a refinement to test");
    let u_max = body.max_displacement();
    let finest = body.spacing(body.finest_level());
    let inside = InsideTolerance::with_spacing(&settings, body.lattice().origin(), finest, u_max);
    let adaptive = AdaptiveLocator::new(&body, settings).unwrap();
    let strategies: Vec<Box<dyn Locator + '_>> = vec![
        Box::new(BruteForce::new(&body, settings).unwrap()),
        Box::new(RTree::new(&body, settings).unwrap()),
        Box::new(CentroidRadius::new(&body, settings).unwrap()),
        Box::new(NodeRadius::new(&body, settings).unwrap()),
    ];
    let mut checked = 0;
    for (x, kind) in common::adaptive::points(&body, 100, 7) {
        let Kind::NearBoundary { cell, .. } = kind else {
            continue;
        };
        // Back onto the face, then off it by a multiple of the tolerance there.
        let hit = adaptive.locate_owners(x).unwrap();
        let Some(on_face) = hit.iter().find(|h| h.cell == cell).map(|h| h.xi) else {
            continue;
        };
        let axis = (0..3)
            .max_by(|&a, &b| on_face[a].abs().total_cmp(&on_face[b].abs()))
            .unwrap();
        // The allowance of the cell's own level (its own spacing; this field deforms it by
        // little, so that its J⁻¹ is nearly that of the undeformed leaf).
        let level = body.leaves().get(cell.index()).unwrap().level;
        let tol = inside.undeformed(x, body.spacing(level))[axis];
        for (factor, expected) in [(0.5, true), (2.0, false)] {
            let mut xi = on_face;
            xi[axis] = on_face[axis].signum() * (1.0 + factor * tol);
            let y = body.point_at(cell, xi).unwrap();
            let holds = |owners: Owners| owners.iter().any(|h| h.cell == cell);
            assert_eq!(
                holds(adaptive.locate_owners(y).unwrap()),
                expected,
                "{factor} τ at {y}"
            );
            for strategy in &strategies {
                let owners = strategy.locate_owners(y).unwrap();
                assert_eq!(
                    holds(owners),
                    expected,
                    "{} at {factor} τ, {y}",
                    strategy.name()
                );
            }
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked}");
}

/// The strategies give a leaf its own level's inside tolerance, as the adaptive locator does:
/// with the finest spacing's, brute force and the R-tree found points 1e-8 to 3e-7 outside a
/// level-0 leaf at x = 1e5 (beside a level-15 leaf) inside it, ξ clamped to 1.
#[test]
fn coarse_leaves_beside_deep_ones_keep_their_own_tolerance() {
    let lattice = Lattice::new(DVec3::new(1e5, 0.0, 0.0), DVec3::ONE, [3, 1, 1]).unwrap();
    let leaves = vec![Leaf::new(0, [0, 0, 0]), Leaf::new(15, [2 << 15, 0, 0])];
    let body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    let settings = Settings::default();
    let strategies: Vec<Box<dyn Locator + '_>> = vec![
        Box::new(AdaptiveLocator::new(&body, settings).unwrap()),
        Box::new(BruteForce::new(&body, settings).unwrap()),
        Box::new(RTree::new(&body, settings).unwrap()),
        Box::new(CentroidRadius::new(&body, settings).unwrap()),
        Box::new(NodeRadius::new(&body, settings).unwrap()),
    ];
    for off in [1e-8, 1e-7, 3e-7] {
        for (y, z) in [(0.5, 0.5), (0.999, 0.001)] {
            let (out, inside) = (
                DVec3::new(1e5 + 1.0 + off, y, z),
                DVec3::new(1e5 + 1.0 - off, y, z),
            );
            for strategy in &strategies {
                let name = strategy.name();
                assert_eq!(strategy.locate(out).unwrap(), None, "{name}, {out}");
                assert!(
                    strategy.locate_owners(out).unwrap().is_empty(),
                    "{name}, {out}"
                );
                let hit = strategy.locate(inside).unwrap();
                assert_eq!(hit.map(|h| h.cell), Some(CellId(0)), "{name}, {inside}");
            }
        }
    }
}

/// A body whose hanging nodes lie off their faces by a file's rounding (float coordinates) has a
/// seam (`AdaptiveBody::set_seam`), which the adaptive locator adds to its allowance so that a
/// point at a hanging node keeps the coarse leaf as an owner. The baselines did not, so the
/// brute-force oracle listed fewer owners than the locator. Every node's deformed position must
/// get the same owners from both.
#[test]
fn the_oracle_takes_the_seam_as_the_locator_does() {
    let mut body = common::adaptive::body(&BASE);
    let hanging: Vec<usize> = body.hanging_nodes().collect();
    assert!(!hanging.is_empty(), "a refinement with hanging nodes");
    let h = body.spacing(0);
    let off = 3e-8 * h;
    let mut u = body.displacements().to_vec();
    for (k, &node) in hanging.iter().enumerate() {
        // Off the constraint by up to `off` per axis, in both directions.
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        u[node] += sign * off * DVec3::new(1.0, 0.5, -0.75);
    }
    body.set_displacements(&u).unwrap();
    body.set_seam(off).unwrap();
    let settings = Settings::default();
    let adaptive = AdaptiveLocator::new(&body, settings).unwrap();
    let brute = BruteForce::new(&body, settings).unwrap();
    let mut several = 0;
    for (node, &u) in u.iter().enumerate() {
        let x = body.node_position(node).unwrap() + u;
        let want = cells(&brute.locate_owners(x).unwrap());
        let got = cells(&adaptive.locate_owners(x).unwrap());
        assert_eq!(
            got,
            want,
            "node {node} at {x} (hanging: {})",
            body.is_hanging(node)
        );
        several += usize::from(want.len() > 1);
    }
    assert!(several > 100, "{several} nodes with several owners");
}
