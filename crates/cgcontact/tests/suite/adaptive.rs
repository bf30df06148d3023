//! Adaptive bodies against independent answers: points made from known (leaf, ξ), a brute-force
//! oracle that inverts every leaf, the leaves that geometrically meet a hanging node, hand-counted
//! hanging nodes, and the uniform locator on single-level bodies.

use std::collections::BTreeSet;

use cgcontact::adaptive::{FlatConstraints, MAX_LEVEL};
use cgcontact::hex8::Status;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Answer, Body, CellId, Error, Frame, Hit, InsideTolerance,
    Lattice, LatticeLocator, Leaf, Locator, Settings,
};
use glam::DVec3;

use crate::common::{Rng, linear_maps};

/// The leaf of `leaves` holding the finest cell `q` (level `finest`), by walking up its ancestors.
fn holder(leaves: &BTreeSet<Leaf>, q: [u32; 3], finest: u8) -> Option<Leaf> {
    (0..=finest).find_map(|level| {
        let leaf = Leaf::new(level, q.map(|v| v >> (finest - level)));
        leaves.contains(&leaf).then_some(leaf)
    })
}

/// A random refinement of a full `cells` lattice: `splits` times a random leaf above `levels` is
/// split in 8; `balanced` then splits every leaf more than one level coarser than a leaf touching
/// it (faces, edges or corners) until none is; `holes` removes about that share of the leaves.
fn refine(
    cells: [u32; 3],
    levels: u8,
    splits: usize,
    balanced: bool,
    holes: f64,
    seed: u64,
) -> Vec<Leaf> {
    let mut rng = Rng(seed);
    let mut leaves: BTreeSet<Leaf> = BTreeSet::new();
    for k in 0..cells[2] {
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                leaves.insert(Leaf::new(0, [i, j, k]));
            }
        }
    }
    for _ in 0..splits {
        let all: Vec<Leaf> = leaves
            .iter()
            .copied()
            .filter(|l| l.level < levels)
            .collect();
        if all.is_empty() {
            break;
        }
        let leaf = all[rng.below(all.len())];
        leaves.remove(&leaf);
        leaves.extend(leaf.children());
    }
    if balanced {
        let finest = levels;
        let limit = cells.map(|n| i64::from(n << finest));
        loop {
            let mut coarse: Option<Leaf> = None;
            'scan: for leaf in &leaves {
                let s = finest - leaf.level;
                let lo = leaf.ijk.map(|v| i64::from(v << s));
                let size = 1i64 << s;
                // The finest cells just outside each face, edge and corner.
                for d in 0..27 {
                    let off = [d % 3, (d / 3) % 3, d / 9].map(|o| o as i64 - 1);
                    if off == [0, 0, 0] {
                        continue;
                    }
                    let q: [i64; 3] = [0, 1, 2].map(|a| match off[a] {
                        -1 => lo[a] - 1,
                        0 => lo[a],
                        _ => lo[a] + size,
                    });
                    if (0..3).any(|a| q[a] < 0 || q[a] >= limit[a]) {
                        continue;
                    }
                    let q = q.map(|v| v as u32);
                    if let Some(n) = holder(&leaves, q, finest) {
                        if n.level + 1 < leaf.level {
                            coarse = Some(n);
                            break 'scan;
                        }
                    }
                }
            }
            match coarse {
                Some(n) => {
                    leaves.remove(&n);
                    leaves.extend(n.children());
                }
                None => break,
            }
        }
    }
    let mut out: Vec<Leaf> = leaves
        .into_iter()
        .filter(|_| rng.uniform(0.0, 1.0) >= holes)
        .collect();
    if out.is_empty() {
        out.push(Leaf::new(0, [0, 0, 0]));
    }
    // Any order: shuffled.
    for i in (1..out.len()).rev() {
        out.swap(i, rng.below(i + 1));
    }
    out
}

/// A smooth field of gradient about `strain`, plus nodal jitter of `jitter` finest spacings on the
/// independent nodes, hanging nodes filled from their constraints.
fn deform(body: &mut AdaptiveBody, strain: f64, jitter: f64, seed: u64) {
    let mut rng = Rng(seed);
    let h = body.spacing(0);
    let fine = body.spacing(body.finest_level()).min_element();
    let o = body.lattice().origin();
    body.update_independent(|_, x, u| {
        let t = (x - o) / h;
        *u = strain
            * h
            * DVec3::new(
                (0.7 * t.y + 0.3 * t.z).sin(),
                (0.5 * t.z - 0.4 * t.x).cos(),
                (0.6 * t.x + 0.2 * t.y).sin(),
            )
            + rng.vec(-jitter, jitter) * fine;
    })
    .unwrap();
}

/// Every leaf holding `x` by inverting each one (the oracle), ascending.
/// The cells `locator.locate_owners(x)` answers, ascending.
fn owner_cells(locator: &impl Locator, x: DVec3) -> Vec<u32> {
    locator
        .locate_owners(x)
        .unwrap()
        .iter()
        .map(|h| h.cell.0)
        .collect()
}

fn brute_owners(body: &AdaptiveBody, settings: &Settings, x: DVec3) -> Vec<u32> {
    let h = body.spacing(body.finest_level());
    let frame = Frame::of_displacements(settings.precision, body.displacements(), h);
    let tol = InsideTolerance::with_spacing(settings, body.lattice().origin(), h, frame.reach());
    // Each leaf's own allowance follows from its J (the rounding length carried through J⁻¹).
    let options = tol.options(settings, x);
    (0..body.cell_count() as u32)
        .filter(|&c| {
            let (map, origin) = body.cell_map(CellId(c)).unwrap();
            map.invert(x - origin, DVec3::ZERO, &options).status == Status::Inside
        })
        .collect()
}

fn scene(balanced: bool, holes: f64, seed: u64) -> AdaptiveBody {
    let lattice = Lattice::new(
        DVec3::new(-3.5, 1.0, 0.25),
        DVec3::new(0.5, 0.25, 0.4),
        [3, 4, 2],
    )
    .unwrap();
    let leaves = refine([3, 4, 2], 3, 14, balanced, holes, seed);
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    deform(&mut body, 0.04, 0.05, seed ^ 7);
    body.validate().unwrap();
    body
}

#[test]
fn known_points_are_found_in_their_leaf_with_exact_xi() {
    for seed in 0..12 {
        for balanced in [false, true] {
            let body = scene(balanced, if seed % 3 == 0 { 0.2 } else { 0.0 }, seed);
            assert!(
                body.finest_level() >= 2,
                "seed {seed}: a refinement to test"
            );
            let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
            let f32 = AdaptiveLocator::new(&body, Settings::f32()).unwrap();
            let mut rng = Rng(seed + 100);
            let mut inversions = 0;
            let n = 400;
            for _ in 0..n {
                let cell = CellId(rng.below(body.cell_count()) as u32);
                // Open cube: a point on a shared face has probability zero.
                let xi = rng.vec(-0.999, 0.999);
                let x = body.point_at(cell, xi).unwrap();
                let (answer, tried) = locator.locate_counted(x);
                let hit = answer
                    .unwrap()
                    .unwrap_or_else(|| panic!("seed {seed}: {x} in {cell} missed"));
                inversions += tried;
                assert_eq!(hit.cell, cell, "seed {seed} at {x}");
                assert!(
                    (hit.xi - xi).abs().max_element() <= 1e-12,
                    "seed {seed}: ξ {} vs {xi}",
                    hit.xi
                );
                let hit32 = f32.locate(x).unwrap().unwrap();
                assert_eq!(hit32.cell, cell, "f32, seed {seed} at {x}");
                assert!(
                    (hit32.xi - xi).abs().max_element() <= 1e-5,
                    "f32 ξ {}",
                    hit32.xi
                );
            }
            // One inversion for almost every point.
            assert!(
                f64::from(inversions) / f64::from(n) < 1.3,
                "seed {seed}: {inversions} inversions"
            );
        }
    }
}

/// f32 on an adaptive body moved rigidly by 1e5 base cells: the kernel's frame takes the
/// translation out (whole finest cells), so every path finds the known leaf and ξ to f32's 1e-5,
/// as on the unmoved body; without it the rounding was 1e-2 of a base cell.
#[test]
fn f32_on_an_adaptive_body_moved_1e5_cells_finds_the_known_leaf() {
    for seed in [3, 8] {
        let mut body = scene(seed % 2 == 0, 0.1, seed);
        let moved = DVec3::new(1.0, -0.6, 0.3) * 1e5 * body.spacing(0);
        let before = body.displacements().to_vec();
        body.update_independent(|node, _, u| *u = before[node] + moved)
            .unwrap();
        let locator = AdaptiveLocator::new(&body, Settings::f32()).unwrap();
        let fine = body.spacing(body.finest_level());
        let shift = locator.frame_shift() / fine;
        assert!(
            shift == shift.round() && (shift - moved / fine).abs().max_element() < 1.0,
            "seed {seed}: frame {shift}"
        );
        let mut rng = Rng(seed + 500);
        let known: Vec<(CellId, DVec3)> = (0..600)
            .map(|_| {
                let cell = CellId(rng.below(body.cell_count()) as u32);
                (cell, rng.vec(-0.999, 0.999))
            })
            .collect();
        let points: Vec<DVec3> = known
            .iter()
            .map(|&(cell, xi)| body.point_at(cell, xi).unwrap())
            .collect();
        let mut answers = locator.locate_all(&points);
        let check = |answers: &[Answer], path: &str| {
            for (answer, &(cell, xi)) in answers.iter().zip(&known) {
                let hit = answer
                    .unwrap()
                    .unwrap_or_else(|| panic!("seed {seed} {path}: {cell} missed"));
                assert_eq!(hit.cell, cell, "seed {seed} {path}");
                assert!(
                    (hit.xi - xi).abs().max_element() <= 1e-5,
                    "seed {seed} {path}: ξ {} vs {xi}",
                    hit.xi
                );
            }
        };
        check(&answers, "locate_all");
        let each: Vec<Answer> = points.iter().map(|&x| locator.locate(x)).collect();
        assert_eq!(each, answers, "seed {seed}: locate against locate_all");
        locator.relocate_all(&points, &mut answers);
        check(&answers, "relocate_all");
    }
}

#[test]
fn random_points_agree_with_brute_force() {
    for seed in 0..8 {
        let body = scene(
            seed % 2 == 0,
            if seed % 4 == 1 { 0.25 } else { 0.0 },
            seed + 50,
        );
        let settings = Settings::default();
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        let mut rng = Rng(seed);
        let low = body.lattice().origin() - body.spacing(0);
        let high = body.lattice().upper() + body.spacing(0);
        let mut found = 0;
        for _ in 0..600 {
            let x = DVec3::new(
                rng.uniform(low.x, high.x),
                rng.uniform(low.y, high.y),
                rng.uniform(low.z, high.z),
            );
            let oracle = brute_owners(&body, &settings, x);
            let owners = owner_cells(&locator, x);
            assert_eq!(owners, oracle, "seed {seed} at {x}");
            match locator.locate(x).unwrap() {
                Some(hit) => {
                    found += 1;
                    assert!(oracle.contains(&hit.cell.0), "seed {seed} at {x}");
                }
                None => assert!(
                    oracle.is_empty(),
                    "seed {seed}: {x} missed, held by {oracle:?}"
                ),
            }
        }
        assert!(found > 50, "seed {seed}: {found} points inside");
    }
}

/// The leaves whose closed undeformed box holds the finest-lattice point `p` (independent of the
/// body's own neighbour search).
fn leaves_meeting(body: &AdaptiveBody, p: [u32; 3]) -> Vec<u32> {
    let finest = body.finest_level();
    (0..body.cell_count() as u32)
        .filter(|&c| {
            let leaf = body.leaves().get(c as usize).expect("a leaf of the body");
            let s = finest - leaf.level;
            (0..3).all(|a| {
                let lo = leaf.ijk[a] << s;
                lo <= p[a] && p[a] <= lo + (1 << s)
            })
        })
        .collect()
}

#[test]
fn hanging_nodes_edges_and_faces_are_held_by_every_leaf_meeting_them() {
    for seed in 0..6 {
        let body = scene(seed % 2 == 1, 0.0, seed + 300);
        let settings = Settings::default();
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        let finest = body.finest_level();
        let h = body.spacing(finest);
        let o = body.lattice().origin();
        let hanging: Vec<usize> = body.hanging_nodes().collect();
        assert!(
            !hanging.is_empty(),
            "seed {seed}: a refinement has hanging nodes"
        );
        for &node in &hanging {
            let x0 = body.node_position(node).unwrap();
            let p = ((x0 - o) / h).round().to_array().map(|v| v as u32);
            let x = x0 + body.displacements()[node];
            let meeting = leaves_meeting(&body, p);
            let owners = owner_cells(&locator, x);
            for leaf in &meeting {
                assert!(
                    owners.contains(leaf),
                    "seed {seed}: hanging node {node} at {x}: {leaf} missing from {owners:?}"
                );
            }
            assert_eq!(
                owners,
                brute_owners(&body, &settings, x),
                "seed {seed} node {node}"
            );
            assert!(locator.locate(x).unwrap().is_some());
        }
        // Points on the faces and edges of fine leaves: each is held by its own leaf at ξ on the
        // boundary, and by whatever coarse leaf lies across.
        let mut rng = Rng(seed);
        for _ in 0..300 {
            let cell = CellId(rng.below(body.cell_count()) as u32);
            let mut xi = rng.vec(-1.0, 1.0);
            xi[rng.below(3)] = if rng.below(2) == 0 { -1.0 } else { 1.0 };
            if rng.below(2) == 0 {
                xi[rng.below(3)] = 1.0;
            }
            let x = body.point_at(cell, xi).unwrap();
            let owners = owner_cells(&locator, x);
            assert!(
                owners.contains(&cell.0),
                "seed {seed}: {x} on the boundary of {cell}: {owners:?}"
            );
            assert_eq!(
                owners,
                brute_owners(&body, &settings, x),
                "seed {seed} at {x}"
            );
        }
    }
}

/// Two unit base cells along x, the second split once: 5 hanging nodes on their shared face.
fn split_beside_coarse() -> AdaptiveBody {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1]).unwrap();
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    leaves.extend(Leaf::new(0, [1, 0, 0]).children());
    AdaptiveBody::from_leaves(lattice, leaves).unwrap()
}

#[test]
fn one_refined_cell_beside_a_coarse_one_has_five_hanging_nodes() {
    // Two base cells along x; the second split once: its face against the first has 4 edge
    // midpoints and 1 face centre that are not corners of the coarse cell.
    let mut body = split_beside_coarse();
    assert_eq!(body.node_count(), 8 + 27 - 4);
    // A leaf squashed flat is reported; the body is otherwise valid.
    assert!(body.validate().is_ok());
    let flat = body.cell_nodes(CellId(0)).unwrap()[1];
    let mut u = vec![DVec3::ZERO; body.node_count()];
    u[flat].x = -1.0;
    body.set_displacements(&u).unwrap();
    assert_eq!(
        body.inverted_cells()
            .iter()
            .map(|c| c.0)
            .collect::<Vec<_>>(),
        [CellId(0)]
    );
    body.set_displacements(&vec![DVec3::ZERO; body.node_count()])
        .unwrap();
    let hanging: Vec<DVec3> = body
        .hanging_nodes()
        .map(|n| body.node_position(n).unwrap())
        .collect();
    assert_eq!(hanging.len(), 5);
    for x in &hanging {
        assert_eq!(x.x, 1.0, "on the shared face: {x}");
    }
    let centre = body.node_at_finest([2, 1, 1]).unwrap();
    let weights = body.constraint(centre).unwrap();
    assert_eq!(weights.len(), 4);
    assert!(weights.iter().all(|&(_, w)| w == 0.25));
    let edge = body.node_at_finest([2, 0, 1]).unwrap();
    assert_eq!(
        body.constraint(edge)
            .unwrap()
            .iter()
            .map(|&(_, w)| w)
            .collect::<Vec<_>>(),
        [0.5, 0.5]
    );
    // Not hanging: the corners of the coarse cell, and the fine cells' own interior nodes.
    assert!(
        body.constraint(body.node_at_finest([2, 2, 2]).unwrap())
            .is_none()
    );
    assert!(
        body.constraint(body.node_at_finest([3, 1, 1]).unwrap())
            .is_none()
    );
}

#[test]
fn constraints_checked_per_axis_on_an_anisotropic_lattice() {
    // Spacings 1 : 1e-3 : 0.1, base cell 1 split against base cell 0: 5 hanging nodes on x = 1.
    let h = DVec3::new(1.0, 1e-3, 0.1);
    let lattice = Lattice::new(DVec3::ZERO, h, [2, 1, 1]).unwrap();
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    leaves.extend(Leaf::new(0, [1, 0, 0]).children());
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    deform(&mut body, 0.01, 0.0, 5);
    let tol = 1e-9 * body.spacing(1);
    assert!(body.check_constraints_per_axis(tol).holds());
    let node = body.hanging_nodes().nth(1).unwrap();
    // 1e-12 along x is 2e-12 of a fine cell's x edge: within its axis's tolerance, although
    // beyond the shortest axis's (5e-13), which the one-number check can only take.
    let mut u = body.displacements().to_vec();
    u[node].x += 1e-12;
    body.set_displacements(&u).unwrap();
    assert!(body.check_constraints_per_axis(tol).holds());
    assert_eq!(body.check_constraints(tol.min_element()).violating, 1);
    // 1e-12 along y is 2e-9 of the y edge: off, and the worst, by that component.
    u[node].y += 1e-12;
    let other = body.hanging_nodes().nth(3).unwrap();
    u[other].x += 3e-10;
    body.set_displacements(&u).unwrap();
    let report = body.check_constraints_per_axis(tol);
    assert_eq!(report.violating, 1);
    let (worst, by) = report.worst.unwrap();
    assert_eq!(worst, node);
    assert!((by - 1e-12).abs() < 1e-15, "{by}");
    // A splat tolerance judges as the one-number check.
    for t in [0.0, 1e-13, 1e-11, 1e-9] {
        assert_eq!(
            body.check_constraints_per_axis(DVec3::splat(t)),
            body.check_constraints(t)
        );
    }
}

/// A NaN tolerance failed every comparison `offset > tol`: a body whose hanging nodes were all
/// far off their constraints was reported to hold them. It now holds none within it; each
/// node's offset is checked against its constraint's weights from the public API.
#[test]
fn a_nan_constraint_tolerance_holds_no_hanging_node() {
    let mut body = split_beside_coarse();
    deform(&mut body, 0.02, 0.01, 11);
    let mut u = body.displacements().to_vec();
    let hanging: Vec<usize> = body.hanging_nodes().collect();
    for (k, &node) in hanging.iter().enumerate() {
        u[node] += DVec3::new(0.1, -0.05, 0.02) * (k + 1) as f64;
    }
    body.set_displacements(&u).unwrap();
    let offset = |node: usize| {
        let bound = body
            .constraint(node)
            .unwrap()
            .iter()
            .fold(DVec3::ZERO, |s, &(p, w)| s + w * u[p]);
        (u[node] - bound).abs()
    };
    // Every hanging node is off by at least 0.02 on some axis.
    assert!(hanging.iter().all(|&n| offset(n).max_element() > 0.01));
    assert_eq!(body.check_constraints(0.01).violating, hanging.len());
    for report in [
        body.check_constraints(f64::NAN),
        body.check_constraints_per_axis(DVec3::splat(f64::NAN)),
        body.check_constraints_per_axis(DVec3::new(1.0, 1.0, f64::NAN)),
    ] {
        assert!(!report.holds(), "{report:?}");
        assert_eq!(report.violating, hanging.len(), "{report:?}");
    }
}

#[test]
fn a_level_jump_of_two_constrains_to_the_coarsest_leaf() {
    // Base cell 1 split twice in its corner against base cell 0: nodes of the level-2 leaves on the
    // shared face interpolate base cell 0's corners (weights of 1/4, 3/4 · 1/4 ...), summing to 1.
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1]).unwrap();
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    let children = Leaf::new(0, [1, 0, 0]).children();
    leaves.extend(children[1..].iter().copied());
    leaves.extend(children[0].children());
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    let coarse: BTreeSet<usize> = body.cell_nodes(CellId(0)).unwrap().into_iter().collect();
    // On the face x = 1 at finest coords (4, 1, 1): ξ = (−1/2, −1/2) on the coarse face.
    let node = body.node_at_finest([4, 1, 1]).unwrap();
    let weights = body.constraint(node).unwrap();
    assert!(
        weights.iter().all(|(p, _)| coarse.contains(p)),
        "{weights:?}"
    );
    let mut w: Vec<f64> = weights.iter().map(|&(_, w)| w).collect();
    w.sort_by(f64::total_cmp);
    assert_eq!(w, [0.0625, 0.1875, 0.1875, 0.5625]);
    for node in body.hanging_nodes().collect::<Vec<_>>() {
        let sum: f64 = body.constraint(node).unwrap().iter().map(|&(_, w)| w).sum();
        assert_eq!(sum, 1.0, "node {node}");
        assert!(
            body.constraint(node)
                .unwrap()
                .iter()
                .all(|&(p, _)| !body.is_hanging(p))
        );
    }
    // Filled from the constraints, they hold; one moved, it is reported with its offset.
    deform(&mut body, 0.05, 0.05, 3);
    let report = body.check_constraints(1e-14);
    assert!(report.holds() && report.hanging > 0, "{report:?}");
    let mut u = body.displacements().to_vec();
    u[node].y += 1e-3;
    body.set_displacements(&u).unwrap();
    let report = body.check_constraints(1e-9);
    assert_eq!(report.violating, 1);
    let (worst, by) = report.worst.unwrap();
    assert_eq!(worst, node);
    assert!((by - 1e-3).abs() < 1e-12, "{by}");
    body.fill_hanging();
    assert!(body.check_constraints(1e-14).holds());
}

/// The flattened constraints agree with the fill: on unbalanced bodies (chains of hanging nodes
/// across level jumps of up to 3) every hanging node the fill set holds within rounding; one
/// hanging node moved is the one reported, by its offset, even where other hanging nodes hang on
/// it (the leaf-by-leaf check then also reports those); a vector of another length is refused.
#[test]
fn flat_constraints_agree_with_the_fill_and_name_the_node_moved() {
    for seed in 0..6 {
        let mut body = scene(seed % 2 == 0, 0.1, 40 + seed);
        let flat = FlatConstraints::of(&body);
        assert_eq!(flat.len(), body.hanging_nodes().count());
        assert!(flat.nodes().eq(body.hanging_nodes()));
        let u = body.displacements().to_vec();
        let tol = 1e-14;
        assert_eq!(flat.violations(&u, tol).unwrap(), (0, None), "seed {seed}");
        assert!(body.check_constraints(tol).holds(), "seed {seed}");
        let mut parents_of_hanging = 0;
        let hanging: Vec<usize> = body.hanging_nodes().collect();
        for &node in hanging.iter().step_by(3) {
            let mut moved = u.clone();
            moved[node].z -= 1e-3;
            let (count, worst) = flat.violations(&moved, 1e-9).unwrap();
            assert_eq!(count, 1, "seed {seed}, node {node}");
            let (at, by) = worst.unwrap();
            assert_eq!(at, node);
            assert!((by - 1e-3).abs() < 1e-12, "{by}");
            body.set_displacements(&moved).unwrap();
            let report = body.check_constraints(1e-9);
            assert_eq!(report.worst.map(|w| w.0), Some(node), "seed {seed}");
            parents_of_hanging += usize::from(report.violating > 1);
        }
        body.fill_hanging();
        assert_eq!(
            body.displacements(),
            u.as_slice(),
            "seed {seed}: the fill is its own"
        );
        if seed % 2 == 1 {
            assert!(parents_of_hanging > 0, "seed {seed}: no chain was tried");
        }
        assert!(matches!(
            flat.violations(&u[1..], tol),
            Err(Error::LengthMismatch { .. })
        ));
        // A NaN tolerance holds no node, as in check_constraints.
        let (count, _) = flat.violations(&u, f64::NAN).unwrap();
        assert_eq!(count, flat.len());
        assert_eq!(body.check_constraints(f64::NAN).violating, count);
    }
}

#[test]
fn a_single_level_body_answers_as_the_uniform_one() {
    let lattice = Lattice::new(
        DVec3::new(10.0, -4.0, 2.5),
        DVec3::new(0.3, 0.25, 0.2),
        [5, 4, 3],
    )
    .unwrap();
    let mut uniform = Body::full(lattice);
    let mut rng = Rng(9);
    uniform
        .update_displacements(|_, x, u| {
            *u = 0.03 * DVec3::new(x.y.sin(), x.z.cos(), (x.x * 2.0).sin()) + rng.vec(-0.01, 0.01)
        })
        .unwrap();
    let mut leaves = Vec::new();
    for c in 0..lattice.cell_count() as u32 {
        leaves.push(Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap()));
    }
    let mut adaptive = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    assert_eq!(adaptive.node_count(), lattice.node_count());
    for n in 0..lattice.node_count() {
        let ijk = lattice.node_ijk(n).unwrap();
        assert_eq!(adaptive.node_position(n), Some(lattice.node_position(ijk)));
    }
    adaptive.set_displacements(uniform.displacements()).unwrap();
    assert_eq!(adaptive.hanging_nodes().count(), 0);
    for settings in [Settings::default(), Settings::f32()] {
        let a = AdaptiveLocator::new(&adaptive, settings).unwrap();
        let u = LatticeLocator::new(&uniform, settings).unwrap();
        let mut inside = 0;
        for _ in 0..2000 {
            let x = rng.vec(0.0, 1.0) * (lattice.upper() - lattice.origin() + 0.4)
                + lattice.origin()
                - 0.2;
            let (ha, hu) = (a.locate(x).unwrap(), u.locate(x).unwrap());
            match (ha, hu) {
                (Some(ha), Some(hu)) => {
                    inside += 1;
                    assert_eq!(ha.cell, hu.cell, "at {x}");
                    assert_eq!(
                        ha.xi.to_array().map(f64::to_bits),
                        hu.xi.to_array().map(f64::to_bits),
                        "at {x}"
                    );
                    assert_eq!(ha.iterations, hu.iterations);
                }
                (None, None) => {}
                other => panic!("at {x}: {other:?}"),
            }
        }
        assert!(inside > 500, "{inside}");
    }
}

#[test]
fn bad_leaves_are_errors_naming_the_leaf() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap();
    let overlap = vec![Leaf::new(0, [0, 0, 0]), Leaf::new(1, [1, 1, 0])];
    assert_eq!(
        AdaptiveBody::from_leaves(lattice, overlap).unwrap_err(),
        Error::OverlappingCells {
            cell: CellId(1),
            other: CellId(0)
        }
    );
    // The finer one first: the coarse leaf covers it.
    let overlap = vec![
        Leaf::new(2, [3, 3, 3]),
        Leaf::new(1, [0, 0, 0]),
        Leaf::new(0, [0, 0, 0]),
    ];
    assert!(matches!(
        AdaptiveBody::from_leaves(lattice, overlap).unwrap_err(),
        Error::OverlappingCells {
            cell: CellId(2),
            ..
        }
    ));
    let twice = vec![Leaf::new(1, [3, 3, 3]), Leaf::new(1, [3, 3, 3])];
    assert_eq!(
        AdaptiveBody::from_leaves(lattice, twice).unwrap_err(),
        Error::OverlappingCells {
            cell: CellId(1),
            other: CellId(0)
        }
    );
    let outside = vec![Leaf::new(0, [0, 0, 0]), Leaf::new(1, [4, 0, 0])];
    assert!(matches!(
        AdaptiveBody::from_leaves(lattice, outside).unwrap_err(),
        Error::InvalidLeaf {
            cell: CellId(1),
            ..
        }
    ));
    let deep = vec![Leaf::new(MAX_LEVEL + 1, [0, 0, 0])];
    assert!(matches!(
        AdaptiveBody::from_leaves(lattice, deep).unwrap_err(),
        Error::InvalidLeaf {
            cell: CellId(0),
            ..
        }
    ));
    assert_eq!(
        AdaptiveBody::from_leaves(lattice, vec![]).unwrap_err(),
        Error::EmptyBody
    );
    let mut body = AdaptiveBody::from_leaves(lattice, vec![Leaf::new(0, [0, 0, 0])]).unwrap();
    let mut u = vec![DVec3::ZERO; body.node_count()];
    u[3].z = f64::NAN;
    assert!(matches!(
        body.set_displacements(&u),
        Err(Error::NonFiniteDisplacement { node: 3, .. })
    ));
    assert!(body.set_displacements(&u[1..]).is_err());
}

/// `Leaf::children` overflowed its level past 255 and its indices past 2^31, and `Leaf::base`
/// shifted by the level (a panic past level 31 where overflow is checked, a wrong base cell
/// where it is not). The base is now the exact quotient, and children that cannot exist
/// saturate into leaves that `from_leaves` refuses.
#[test]
fn leaf_arithmetic_at_the_ends_of_its_ranges_does_not_overflow() {
    for level in [0, 1, 19, 20, 31, 32, 33, 63, 64, 200, u8::MAX] {
        for ijk in [
            [0, 1, 2],
            [u32::MAX, 1 << 31, (1 << 31) - 1],
            [12345, 0, u32::MAX],
        ] {
            let leaf = Leaf::new(level, ijk);
            let expected = ijk.map(|v| u32::try_from(u64::from(v) >> level.min(63)).unwrap());
            assert_eq!(leaf.base(), expected, "{leaf:?}");
            for (c, child) in leaf.children().into_iter().enumerate() {
                if level < u8::MAX && ijk.iter().all(|&v| v < 1 << 31) {
                    assert_eq!(child.level, level + 1);
                    let bits = [0, 1, 2].map(|a| (c as u32 >> a) & 1);
                    assert_eq!(child.ijk, [0, 1, 2].map(|a| 2 * ijk[a] + bits[a]));
                    if level < 20 {
                        assert_eq!(child.base(), leaf.base(), "{child:?}");
                    }
                }
            }
        }
    }
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap();
    for parent in [
        Leaf::new(u8::MAX, [0, 0, 0]),
        Leaf::new(3, [1 << 31, 0, 0]),
        Leaf::new(0, [0, u32::MAX, 0]),
    ] {
        let refused = AdaptiveBody::from_leaves(lattice, parent.children().to_vec());
        assert!(
            matches!(refused, Err(Error::InvalidLeaf { .. })),
            "{parent:?}: {refused:?}"
        );
    }
}

#[test]
fn six_levels_in_one_corner_allocate_with_the_leaves() {
    // A 10³ base lattice refined 6 levels toward its lowest corner: the finest level's lattice
    // would have 640³ cells; the body keeps its ~1,040 leaves and their nodes.
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [10, 10, 10]).unwrap();
    let mut leaves: Vec<Leaf> = (1..1000u32)
        .map(|c| Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap()))
        .collect();
    let mut corner = Leaf::new(0, [0, 0, 0]);
    for _ in 0..6 {
        let children = corner.children();
        leaves.extend(children[1..].iter().copied());
        corner = children[0];
    }
    leaves.push(corner);
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    assert_eq!(body.finest_level(), 6);
    let bytes = body.heap_bytes();
    assert!(bytes < 200 * 1024, "{bytes} bytes");
    deform(&mut body, 0.02, 0.0, 1);
    let locator = AdaptiveLocator::new(&body, Settings::default()).unwrap();
    let cell = CellId(body.cell_count() as u32 - 1);
    let x = body.point_at(cell, DVec3::splat(0.25)).unwrap();
    assert_eq!(locator.locate(x).unwrap().unwrap().cell, cell);
}

/// A body refined toward one corner down to `MAX_LEVEL`: points made from known (leaf, ξ) in
/// leaves of every level, on their faces, edges and corners too, are found in their leaf with
/// their ξ by `locate` and `locate_all`, `locate_owners` gives brute force's owners, and
/// `relocate_all` from those answers keeps their leaves. A debug build overflowed a corner's rank
/// from level 16 on.
#[test]
fn leaves_of_every_level_to_the_deepest_are_found() {
    // One base cell: 2^20 finest cells per axis is as many as the library indexes.
    let lattice = Lattice::new(DVec3::new(-0.75, 0.5, 2.0), DVec3::ONE, [1, 1, 1]).unwrap();
    let mut leaves = Vec::new();
    let mut corner = Leaf::new(0, [0, 0, 0]);
    for level in 0..MAX_LEVEL {
        let children = corner.children();
        // Toward the upper corner, then the lower one, in turn: each level's leaves meet the
        // deeper ones across faces, edges and corners.
        let deeper = if level % 2 == 0 { 7 } else { 0 };
        leaves.extend((0..8).filter(|&c| c != deeper).map(|c| children[c]));
        corner = children[deeper];
    }
    leaves.push(corner);
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    assert_eq!(body.finest_level(), MAX_LEVEL);
    deform(&mut body, 0.02, 0.1, 3);
    let settings = Settings::default();
    let locator = AdaptiveLocator::new(&body, settings).unwrap();
    let mut rng = Rng(11);
    let mut points = Vec::new();
    let mut made = Vec::new();
    for c in 0..body.cell_count() as u32 {
        for k in 0..4 {
            // Inside, then on a face, an edge and a corner.
            let mut xi = rng.vec(-0.9, 0.9);
            for a in 0..k.min(3) {
                xi[a] = if rng.below(2) == 0 { -1.0 } else { 1.0 };
            }
            points.push(body.point_at(CellId(c), xi).unwrap());
            made.push((c, xi, k == 0));
        }
    }
    let mut batched = Vec::new();
    locator.locate_all_into(&points, &mut batched);
    let mut warm = batched.clone();
    locator.relocate_all(&points, &mut warm);
    for (p, (&x, &(c, xi, interior))) in points.iter().zip(&made).enumerate() {
        let one = locator.locate(x);
        assert_eq!(one, batched[p], "point {p}");
        let hit = one.unwrap().unwrap();
        // ξ as well as the coordinates resolve it in a leaf of that size (1e-9 at level 20).
        let k = body.corners(hit.cell).unwrap();
        let edge = (k[1] - k[0])
            .length()
            .min((k[3] - k[0]).length())
            .min((k[4] - k[0]).length());
        let bound = 1e-12 + 64.0 * f64::EPSILON * (x.abs().max_element() + 1.0) * 2.0 / edge;
        // Warm from the answer itself: its own leaf again.
        let again = warm[p].unwrap().unwrap();
        assert_eq!(again.cell, hit.cell, "point {p}");
        let moved = (again.xi - hit.xi).abs().max_element();
        assert!(
            moved < bound,
            "point {p}: ξ moved by {moved:e}, beyond {bound:e}"
        );
        let owners = owner_cells(&locator, x);
        assert_eq!(owners, brute_owners(&body, &settings, x), "point {p}");
        assert!(
            owners.contains(&c),
            "point {p}: leaf {c} not among {owners:?}"
        );
        if interior {
            assert_eq!(hit.cell.0, c, "point {p}");
            let error = (hit.xi - xi).abs().max_element();
            assert!(
                error < bound,
                "point {p}: ξ off by {error:e}, beyond {bound:e}"
            );
        }
    }
}

/// The corner table changes where the locators read a leaf's corners, not what they answer: the
/// same nodes per leaf, and bitwise the same answers, batched and one by one, on random
/// refinements (balanced or not, with holes) and points anywhere, each leaf's corners checked
/// against the node at its corner's position.
#[test]
fn the_corner_table_changes_no_answer() {
    for seed in 0..6 {
        let body = scene(seed % 2 == 0, if seed % 3 == 0 { 0.2 } else { 0.0 }, seed);
        let mut tabled = body.clone();
        let before = tabled.heap_bytes();
        tabled.set_corner_table(true);
        assert!(tabled.has_corner_table() && !body.has_corner_table());
        assert_eq!(tabled.heap_bytes(), before + 32 * body.cell_count());
        let finest = body.finest_level();
        for (id, leaf) in body.leaves().iter().enumerate() {
            let nodes = body.cell_nodes(CellId(id as u32)).unwrap();
            assert_eq!(tabled.cell_nodes(CellId(id as u32)), Some(nodes));
            let s = finest - leaf.level;
            // VTK order: bit 0 of (c + c / 2) is +x, bit 1 of c is +y, bit 2 is +z.
            for (c, &node) in nodes.iter().enumerate() {
                let off = [
                    ((c ^ (c >> 1)) & 1) as u32,
                    ((c >> 1) & 1) as u32,
                    (c >> 2) as u32,
                ];
                let q = [0, 1, 2].map(|a| (leaf.ijk[a] + off[a]) << s);
                assert_eq!(
                    body.node_at_finest(q),
                    Some(node),
                    "seed {seed}, leaf {id}, {c}"
                );
            }
        }
        let mut rng = Rng(seed + 300);
        let (low, high) = (DVec3::new(-4.0, 0.8, 0.0), DVec3::new(-1.5, 2.2, 1.2));
        let points: Vec<DVec3> = (0..3000)
            .map(|_| rng.vec(0.0, 1.0) * (high - low) + low)
            .collect();
        for settings in [Settings::default(), Settings::f32()] {
            let plain = AdaptiveLocator::new(&body, settings).unwrap();
            let table = AdaptiveLocator::new(&tabled, settings).unwrap();
            let a = plain.locate_all(&points);
            let b = table.locate_all(&points);
            assert!(a.iter().filter(|r| matches!(r, Ok(Some(_)))).count() > 100);
            for ((x, a), b) in points.iter().zip(&a).zip(&b) {
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "seed {seed} at {x}");
                assert_eq!(format!("{:?}", plain.locate(*x)), format!("{a:?}"));
            }
        }
    }
}

/// A base lattice that its coordinates resolve, refined until its finest level's cells are
/// finer than they do (at 1e9, 17 levels of a unit spacing: 7.6e-6): refused, as the uniform
/// lattice of that spacing would be; 10 levels (1e-3) are not.
#[test]
fn a_finest_level_finer_than_the_coordinates_resolve_is_refused() {
    let lattice = Lattice::new(DVec3::splat(1e9), DVec3::ONE, [1, 1, 1]).unwrap();
    let refined = |levels: u8| {
        let mut leaves = Vec::new();
        let mut corner = Leaf::new(0, [0, 0, 0]);
        for _ in 0..levels {
            let children = corner.children();
            leaves.extend_from_slice(&children[1..]);
            corner = children[0];
        }
        leaves.push(corner);
        AdaptiveBody::from_leaves(lattice, leaves)
    };
    refined(10).unwrap();
    assert!(matches!(
        refined(17).unwrap_err(),
        Error::InvalidLattice(message) if message.contains("too fine")
    ));
}

/// A leaf's inside tolerance is its own level's: the allowance for the rounding of x
/// (8 ε |x| / h) shrinks with its spacing. With the finest spacing's on every leaf, points 1e-8 to
/// 3e-7 outside a level-0 leaf at x = 1e5 beside a level-15 leaf (whose allowance is 2^15 times
/// larger in ξ) were found inside it in f64, ξ clamped to 1; by every strategy, since they share
/// the definition. Points as far inside are found, by the scalar and the batched searches alike.
#[test]
fn coarse_leaves_beside_deep_ones_keep_their_own_tolerance() {
    let lattice = Lattice::new(DVec3::new(1e5, 0.0, 0.0), DVec3::ONE, [3, 1, 1]).unwrap();
    // Base cell 0 whole, base cell 1 a hole, one level-15 leaf in a corner of base cell 2.
    let leaves = vec![Leaf::new(0, [0, 0, 0]), Leaf::new(15, [2 << 15, 0, 0])];
    let body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    // f32's own tolerance (1e-6 + 16 ε₃₂ in ξ) holds points up to 1.5e-6 outside the face; the
    // deep leaf's allowance had added 2.9e-6.
    let offsets: [(Settings, &[f64]); 2] = [
        (Settings::default(), &[1e-8, 1e-7, 3e-7]),
        (Settings::f32(), &[2.5e-6, 4e-6]),
    ];
    for (settings, offsets) in offsets {
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        let face = 1e5 + 1.0;
        let mut points = Vec::new();
        for &off in offsets {
            for &(y, z) in &[(0.5, 0.5), (0.1, 0.9), (0.999, 0.001)] {
                points.push((DVec3::new(face + off, y, z), false));
                points.push((DVec3::new(face - off, y, z), true));
            }
        }
        let xs: Vec<DVec3> = points.iter().map(|p| p.0).collect();
        let batch = locator.locate_all(&xs);
        for ((x, inside), batched) in points.iter().zip(&batch) {
            let one = locator.locate(*x).unwrap();
            assert_eq!(one, *batched.as_ref().unwrap(), "{x}: batch against scalar");
            let owners = locator.locate_owners(*x).unwrap();
            if *inside {
                let hit = one.unwrap_or_else(|| panic!("{x} ({settings:?}): not found"));
                assert_eq!(hit.cell, CellId(0));
                assert_eq!(owners.len(), 1, "{x}");
            } else {
                assert!(one.is_none(), "{x} ({settings:?}): found in {one:?}");
                assert!(owners.is_empty(), "{x}: owners {owners:?}");
            }
        }
    }
}

/// Every node (hanging ones too), edge midpoint and face centre of every leaf of adaptive bodies
/// deformed by [`linear_maps`] (shears and rotations, which carry each axis's rounding into the
/// others' ξ), anisotropic and far from the origin, is held by exactly the leaves whose closed
/// box holds it, in both precisions, batched and not. With an allowance of 2L / h_k per axis
/// (J⁻¹'s diagonal alone), some lost owners.
#[test]
fn sheared_and_rotated_leaves_keep_every_owner_of_nodes_edges_and_faces() {
    let mut checked = 0;
    for (seed, (map_name, a)) in linear_maps().into_iter().enumerate() {
        for (h, origin) in [
            (DVec3::new(4.0, 0.25, 0.002), DVec3::splat(1e5)),
            (DVec3::splat(0.5), DVec3::new(-1e7, 3.0, 2e6)),
        ] {
            let lattice = Lattice::new(origin, h, [3, 2, 2]).unwrap();
            let leaves = refine([3, 2, 2], 3, 8, seed % 2 == 0, 0.0, seed as u64 + 40);
            let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
            body.update_independent(|_, x, u| {
                let r = x - origin;
                *u = DVec3::new(a[0].dot(r), a[1].dot(r), a[2].dot(r)) - r;
            })
            .unwrap();
            let finest = body.finest_level();
            // Each point with its finest-lattice coordinates, from every leaf's 27 ξ in {−1, 0, 1}³.
            let mut points = Vec::new();
            for c in 0..body.cell_count() as u32 {
                let leaf = body.leaves().get(c as usize).unwrap();
                let s = finest - leaf.level;
                if s == 0 {
                    continue; // Its midpoints are no finest-lattice points.
                }
                for d in 0..27u32 {
                    let xi = DVec3::new(
                        f64::from(d % 3) - 1.0,
                        f64::from(d / 3 % 3) - 1.0,
                        f64::from(d / 9) - 1.0,
                    );
                    let p = [0, 1, 2]
                        .map(|k| (leaf.ijk[k] << s) + ((xi[k] + 1.0) as u32) * (1 << (s - 1)));
                    points.push((body.point_at(CellId(c), xi).unwrap(), p));
                }
            }
            for settings in [Settings::default(), Settings::f32()] {
                let locator = AdaptiveLocator::new(&body, settings).unwrap();
                let xs: Vec<DVec3> = points.iter().map(|p| p.0).collect();
                let batched = locator.locate_all(&xs);
                // Warm starts: each owner, as the hint at its own ξ, answers itself.
                let (mut warm_points, mut hints) = (Vec::new(), Vec::new());
                for (&(x, p), hit) in points.iter().zip(batched) {
                    let at = format!(
                        "{map_name}, h {h}, {:?}: {x} (finest {p:?})",
                        settings.precision
                    );
                    let owners = locator.locate_owners(x).unwrap();
                    let cells: Vec<u32> = owners.iter().map(|h| h.cell.0).collect();
                    assert_eq!(cells, leaves_meeting(&body, p), "{at}");
                    let hit = hit.unwrap().expect("on the body");
                    assert!(cells.contains(&hit.cell.0), "{at}: located in {}", hit.cell);
                    for owner in owners.iter() {
                        warm_points.push(x);
                        hints.push(Hit::hint(owner.cell, owner.xi));
                    }
                    checked += 1;
                }
                let mut answers = hints.clone();
                locator.relocate_all(&warm_points, &mut answers);
                for ((x, hint), answer) in warm_points.iter().zip(&hints).zip(&answers) {
                    let hinted = hint.as_ref().unwrap().unwrap().cell;
                    let got = answer.as_ref().unwrap().map(|h| h.cell);
                    assert_eq!(got, Some(hinted), "{map_name}, h {h}: {x} warm");
                }
            }
        }
    }
    assert!(checked > 1000, "{checked}");
}

/// The cells f64 coordinates cannot resolve through their deformation: an adaptive body names
/// the leaves the uniform body of the same cells names, and a refined leaf, half as thick, twice
/// its share.
#[test]
fn adaptive_bodies_name_the_cells_their_coordinates_cannot_resolve() {
    // Cells 1.6e-5 thin along z at 1e7 from the origin, u_z = s (Y − Y0): a rounding of y moves
    // ξ_z by about 1.1 with s = 1e3, by 0.011 with s = 10.
    let origin = -1e7;
    let h = DVec3::new(0.03125, 0.001953125, 1.5625e-5);
    let lattice = Lattice::new(DVec3::splat(origin), h, [1, 1, 2]).unwrap();
    let shear = |s: f64| {
        move |_: usize, x: DVec3, u: &mut DVec3| *u = DVec3::new(0.0, 0.0, s * (x.y - origin))
    };
    for s in [1e3, 10.0] {
        let mut uniform = Body::full(lattice);
        uniform.update_displacements(shear(s)).unwrap();
        let leaves = vec![Leaf::new(0, [0, 0, 0]), Leaf::new(0, [0, 0, 1])];
        let mut one_level = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        one_level.update_independent(shear(s)).unwrap();
        let (a, b) = (one_level.unresolved_cells(), uniform.unresolved_cells());
        assert_eq!(a.len(), b.len(), "{a:?} {b:?}");
        for ((ca, sa), (cb, sb)) in a.iter().zip(&b) {
            // Leaves and lattice cells are numbered alike here: bottom, then top.
            assert_eq!(ca, cb);
            assert!((sa - sb).abs() <= 1e-12 * sb, "{sa} {sb}");
        }
        assert_eq!(a.len(), if s == 1e3 { 2 } else { 0 });
    }
    // The top cell refined once: its leaves are half as thick, so a rounding takes twice the
    // share of them; with s = 10, 0.02 of a leaf, still resolved, and no cell is named.
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    leaves.extend(Leaf::new(0, [0, 0, 1]).children());
    for (s, named) in [(1e3, 9), (10.0, 0)] {
        let mut body = AdaptiveBody::from_leaves(lattice, leaves.clone()).unwrap();
        body.update_independent(shear(s)).unwrap();
        let unresolved = body.unresolved_cells();
        assert_eq!(unresolved.len(), named, "{unresolved:?}");
        let coarse = unresolved.iter().find(|(c, _)| c.0 == 0).map(|&(_, v)| v);
        for &(cell, share) in &unresolved {
            if cell.0 != 0 {
                let ratio = share / coarse.unwrap();
                assert!(
                    (ratio - 2.0).abs() < 0.01,
                    "leaf {cell}: {share} against {coarse:?}"
                );
            }
        }
    }
}

/// Corners of every leaf of sheared, strongly anisotropic adaptive bodies (base spacing
/// 1000 : 1 : 10, three levels, balanced and not, x += 2.8 H_x z / H_z plus a field of an eighth of
/// a finest cell) are held by every leaf meeting them, in f64 and f32. In f32, before Newton's
/// rounding noise was taken per axis, such corners lost owners and some points were answered 0.27
/// off in ξ with residuals of several finest cells.
#[test]
fn corners_of_sheared_anisotropic_leaves_keep_every_owner_in_both_precisions() {
    for seed in 0..4 {
        let cells = [3, 4, 2];
        let h = DVec3::new(1000.0, 1.0, 10.0);
        let lattice = Lattice::new(DVec3::new(-1500.0, 2.0, 30.0), h, cells).unwrap();
        let leaves = refine(cells, 3, 10, seed % 2 == 0, 0.0, seed + 40);
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        let size = h * DVec3::new(3.0, 4.0, 2.0);
        let fine = body.spacing(body.finest_level());
        let o = lattice.origin();
        body.update_independent(|_, x, u| {
            let t = (x - o) / size;
            let wave = DVec3::new((7.0 * t.y).sin(), (5.0 * t.z).cos(), (3.0 * t.x).sin());
            *u = DVec3::new(2.8 * size.x * t.z, 0.0, 0.0) + 0.125 * fine * wave;
        })
        .unwrap();
        body.validate().unwrap();
        let finest = body.finest_level();
        for settings in [Settings::default(), Settings::f32()] {
            let locator = AdaptiveLocator::new(&body, settings).unwrap();
            let mut checked = 0;
            for c in (0..body.cell_count() as u32).step_by(3) {
                let leaf = body.leaves().get(c as usize).unwrap();
                let s = finest - leaf.level;
                for corner in [[0, 0, 0], [1, 0, 1], [1, 1, 0], [0, 1, 1]] {
                    let p = [0, 1, 2].map(|a| (leaf.ijk[a] + corner[a]) << s);
                    let xi = DVec3::from_array(corner.map(|v| 2.0 * f64::from(v) - 1.0));
                    let x = body.point_at(CellId(c), xi).unwrap();
                    let owners = owner_cells(&locator, x);
                    let meeting = leaves_meeting(&body, p);
                    assert_eq!(
                        owners, meeting,
                        "seed {seed}, {:?}: corner {corner:?} of leaf {c} at {x}",
                        settings.precision
                    );
                    checked += 1;
                }
            }
            assert!(checked > 100, "seed {seed}: {checked} corners");
        }
    }
}

/// The hardest scene of an independent audit (a Python generator with a long-double oracle,
/// nothing shared with this crate), kept as a check: level jumps of three (a level-0 leaf beside
/// level-3 leaves), leaves in shuffled order, spacings 1000 : 1 : 100 at 1e9 from the origin,
/// sheared x += 0.5 z and bent. On every node, edge midpoint and face centre of every leaf that
/// has them on the finest lattice, the owners are exactly the leaves whose closed box holds the
/// point, and each owner's ξ is the point's dyadic ξ in it, to the rounding of the coordinates.
#[test]
fn jumps_of_three_levels_far_and_anisotropic_keep_every_owner_and_exact_xi() {
    let cells = [3, 2, 2];
    let mut leaves: BTreeSet<Leaf> = BTreeSet::new();
    for k in 0..cells[2] {
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                leaves.insert(Leaf::new(0, [i, j, k]));
            }
        }
    }
    // Split the leaf holding each focus (in base cells) down to level 3: unbalanced on purpose.
    for focus in [[1.3, 0.9, 1.1], [2.6, 1.7, 0.2]] {
        for level in 0..3u8 {
            let scale = f64::from(1u32 << level);
            let ijk = focus.map(|f: f64| (f * scale) as u32);
            let leaf = Leaf::new(level, ijk);
            assert!(leaves.remove(&leaf), "focus {focus:?} in {leaf:?}");
            leaves.extend(leaf.children());
        }
    }
    let mut rng = Rng(91);
    let mut list: Vec<Leaf> = leaves.into_iter().collect();
    for i in (1..list.len()).rev() {
        list.swap(i, rng.below(i + 1));
    }
    let origin = DVec3::new(1e9, -1e9, 1e9);
    let h = DVec3::new(16.0, 0.016, 1.6);
    let lattice = Lattice::new(origin, h, cells).unwrap();
    let mut body = AdaptiveBody::from_leaves(lattice, list).unwrap();
    body.update_independent(|_, x, u| {
        let t = (x - origin) / h;
        *u = DVec3::new(0.5 * (x.z - origin.z), 0.0, 0.0)
            + 0.04 * h * DVec3::new((0.7 * t.y + 0.3 * t.z).sin(), (0.5 * t.z).cos(), t.x.sin());
    })
    .unwrap();
    body.validate().unwrap();
    let finest = body.finest_level();
    assert_eq!(finest, 3);
    let mut points = Vec::new();
    for c in 0..body.cell_count() as u32 {
        let leaf = body.leaves().get(c as usize).unwrap();
        let s = finest - leaf.level;
        if s == 0 {
            continue;
        }
        for d in 0..27u32 {
            let xi = DVec3::new(
                f64::from(d % 3) - 1.0,
                f64::from(d / 3 % 3) - 1.0,
                f64::from(d / 9) - 1.0,
            );
            let p = [0, 1, 2].map(|k| (leaf.ijk[k] << s) + ((xi[k] + 1.0) as u32) * (1 << (s - 1)));
            points.push((body.point_at(CellId(c), xi).unwrap(), p));
        }
    }
    let h_min = body.spacing(finest).min_element();
    for settings in [Settings::default(), Settings::f32()] {
        let base = match settings.precision {
            cgcontact::Precision::F64 => 1e-12,
            cgcontact::Precision::F32 => 1e-5,
        };
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        for &(x, p) in &points {
            let magnitude = x.abs().max(origin.abs()).max_element();
            // Twice `xi_bound`'s (extremes.rs): the shear couples the axes' roundings.
            let bound = 2.0 * (base + 8.0 * f64::EPSILON * magnitude / h_min);
            let at = format!("{:?}: {x} (finest {p:?})", settings.precision);
            let owners = locator.locate_owners(x).unwrap();
            let cells: Vec<u32> = owners.iter().map(|hit| hit.cell.0).collect();
            assert_eq!(cells, leaves_meeting(&body, p), "{at}");
            for owner in owners.iter() {
                let leaf = body.leaves().get(owner.cell.0 as usize).unwrap();
                let s = finest - leaf.level;
                let exact = DVec3::from_array([0, 1, 2].map(|k| {
                    f64::from(p[k] - (leaf.ijk[k] << s)) * 2.0 / f64::from(1u32 << s) - 1.0
                }));
                let error = (owner.xi - exact).abs().max_element();
                assert!(
                    error <= bound,
                    "{at}: {} ξ {} off {error:.2e} > {bound:.2e}",
                    owner.cell,
                    owner.xi
                );
            }
        }
    }
    assert!(points.len() > 1000, "{}", points.len());
}
