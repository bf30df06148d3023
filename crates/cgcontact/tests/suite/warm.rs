//! Warm starts (`Locator::relocate`, `Locator::relocate_all`) against the cold search, as a solver
//! loop uses them: points located cold, the displacements moved by up to 1 % of h, the locator
//! rebuilt, the points relocated with the old answers as hints. The contract: the same refusals
//! and misses as the cold search; a cell returned is one of `locate_owners`; with a single owner,
//! the cold search's cell and ξ. A hinted cell that still holds its point costs one inversion.

use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Answer, Body, CellId, Hit, Lattice, LatticeLocator, Leaf,
    Locator, PointError, Precision, Settings,
};
use glam::DVec3;

use crate::common::Rng;

/// How far a warm ξ may be from the cold one, with a single owner: the Newton tolerance is
/// reached from two different starts. Quadratic convergence leaves f64 rounding (measured here:
/// 9e-16); f32 keeps its own rounding (measured: 5e-7).
fn xi_tolerance(settings: &Settings) -> f64 {
    match settings.precision {
        Precision::F64 => 1e-12,
        Precision::F32 => 1e-5,
    }
}

/// Checks `warm`, the answer of `relocate(x, _)`, against the cold search of `locator`.
fn check_contract(locator: &impl Locator, settings: &Settings, x: DVec3, warm: &Answer) {
    let cold = locator.locate(x);
    match (&cold, warm) {
        (Err(a), Err(b)) => assert_eq!(a, b, "refusal at {x}"),
        (Ok(None), Ok(None)) => {}
        (Ok(Some(cold_hit)), Ok(Some(hit))) => {
            let owners = locator.locate_owners(x).expect("admitted");
            assert!(
                owners.iter().any(|o| o.cell == hit.cell),
                "warm cell {:?} not among the owners {:?} of {x}",
                hit.cell,
                owners.iter().map(|o| o.cell).collect::<Vec<_>>()
            );
            assert!(hit.xi.abs().max_element() <= 1.0, "ξ {} at {x}", hit.xi);
            if owners.len() == 1 {
                assert_eq!(hit.cell, cold_hit.cell, "single owner of {x}");
                let gap = (hit.xi - cold_hit.xi).abs().max_element();
                assert!(
                    gap <= xi_tolerance(settings),
                    "ξ {} warm, {} cold at {x}: {gap:e}",
                    hit.xi,
                    cold_hit.xi
                );
            }
        }
        _ => panic!("warm {warm:?}, cold {cold:?} at {x}"),
    }
}

/// What the hints of one pass did: points whose hinted cell still held them, and those of them
/// answered in one inversion.
#[derive(Debug, Default)]
struct Held {
    held: usize,
    located: usize,
}

/// Relocates `points` with `hints` (the old answers) on `locator`, checks the contract for each
/// point, that a point still in its hinted cell got that cell in one inversion, and that
/// `relocate_all` answers as `relocate`, bit for bit.
fn relocate_and_check(
    locator: &impl Locator,
    settings: &Settings,
    points: &[DVec3],
    hints: &[Answer],
) -> Held {
    let mut held = Held::default();
    for (&x, hint) in points.iter().zip(hints) {
        let warm = locator.relocate(x, hint);
        check_contract(locator, settings, x, &warm);
        let Ok(Some(old)) = hint else { continue };
        let Ok(Some(hit)) = warm else { continue };
        held.located += 1;
        let owners = locator.locate_owners(x).expect("located");
        if owners.iter().any(|o| o.cell == old.cell) {
            held.held += 1;
            assert_eq!(hit.cell, old.cell, "hinted cell still holds {x}");
            assert_eq!(hit.inversions, 1, "{x} still in its hinted cell");
        }
    }
    let mut all = hints.to_vec();
    locator.relocate_all(points, &mut all);
    for ((&x, hint), batched) in points.iter().zip(hints).zip(&all) {
        assert_eq!(
            bits(batched),
            bits(&locator.relocate(x, hint)),
            "relocate_all at {x}"
        );
    }
    held
}

/// A hit's fields as bits.
pub(crate) type HitBits = (CellId, [u64; 3], u32, u64, u32);

pub(crate) fn bits(a: &Answer) -> Result<Option<HitBits>, PointError> {
    a.map(|hit| {
        hit.map(|h| {
            (
                h.cell,
                h.xi.to_array().map(f64::to_bits),
                h.iterations,
                h.residual.to_bits(),
                h.inversions,
            )
        })
    })
}

/// Points of a body: `known` made from (cell, ξ) by `point_at` (a third of them on a face), random
/// points over `low`..`high` (some outside), and refused ones.
pub(crate) fn points(
    rng: &mut Rng,
    cells: usize,
    point_at: impl Fn(CellId, DVec3) -> Option<DVec3>,
    low: DVec3,
    high: DVec3,
) -> Vec<DVec3> {
    let mut points = Vec::new();
    while points.len() < 1500 {
        let cell = CellId(rng.below(cells) as u32);
        let mut xi = rng.vec(-1.0, 1.0);
        if points.len() % 3 == 0 {
            xi.y = 1.0;
        }
        if let Some(x) = point_at(cell, xi) {
            points.push(x);
        }
    }
    for _ in 0..500 {
        points.push(low + (high - low) * rng.vec(0.0, 1.0));
    }
    points.extend([
        DVec3::NAN,
        DVec3::new(0.0, f64::INFINITY, 0.0),
        DVec3::splat(1e9),
    ]);
    points
}

/// Hints that are wrong in every way the contract allows, for a point whose right hint is `hint`:
/// a cell far from it, a miss, a refusal, ids out of range, a cell `other` (inactive or far) and
/// the right cell with a ξ that is not finite or far outside.
fn wrong_hints(hint: &Answer, far: CellId, cells: usize) -> Vec<Answer> {
    let template = Hit {
        cell: far,
        xi: DVec3::ZERO,
        iterations: 3,
        residual: 0.0,
        inversions: 1,
    };
    let mut hints = vec![
        Ok(Some(template)),
        Ok(None),
        Err(PointError::NonFinite),
        Ok(Some(Hit {
            cell: CellId(cells as u32),
            ..template
        })),
        Ok(Some(Hit {
            cell: CellId(u32::MAX),
            ..template
        })),
    ];
    if let Ok(Some(hit)) = hint {
        hints.push(Ok(Some(Hit {
            xi: DVec3::NAN,
            ..*hit
        })));
        hints.push(Ok(Some(Hit {
            xi: DVec3::splat(-1e300),
            ..*hit
        })));
    }
    hints
}

/// Checks every wrong hint of every point: the contract holds, and a hint that is no hint (a miss,
/// a refusal, an id out of range) gives the cold answer bit for bit; a far cell that does not hold
/// the point costs one inversion more than the cold search, which then answers.
fn check_wrong_hints(
    locator: &impl Locator,
    settings: &Settings,
    points: &[DVec3],
    old: &[Answer],
    far_of: impl Fn(usize) -> CellId,
    cells: usize,
    inactive: Option<CellId>,
) {
    let mut fallbacks = 0;
    for (i, (&x, hint)) in points.iter().zip(old).enumerate() {
        let far = far_of(i);
        let cold = locator.locate(x);
        for (k, wrong) in wrong_hints(hint, far, cells).iter().enumerate() {
            let warm = locator.relocate(x, wrong);
            check_contract(locator, settings, x, &warm);
            if (1..=4).contains(&k) {
                assert_eq!(bits(&warm), bits(&cold), "no hint ({k}) at {x}");
            }
            let far_holds = locator
                .locate_owners(x)
                .is_ok_and(|o| o.iter().any(|o| o.cell == far));
            if k == 0
                && !far_holds
                && let (Ok(Some(warm)), Ok(Some(cold))) = (warm, cold)
            {
                assert_eq!(warm.inversions, cold.inversions + 1, "far hint at {x}");
                assert_eq!(
                    (warm.cell, warm.xi),
                    (cold.cell, cold.xi),
                    "far hint at {x}"
                );
                fallbacks += 1;
            }
        }
        if let Some(inactive) = inactive {
            let wrong = Ok(Some(Hit {
                cell: inactive,
                xi: DVec3::ZERO,
                iterations: 1,
                residual: 0.0,
                inversions: 1,
            }));
            assert_eq!(
                bits(&locator.relocate(x, &wrong)),
                bits(&cold),
                "inactive hint at {x}"
            );
        }
    }
    assert!(
        fallbacks > 1000,
        "{fallbacks} points answered after a far hint"
    );
}

/// A uniform body with holes, distorted, on a lattice away from the origin.
pub(crate) fn uniform_body(seed: u64) -> Body {
    let lattice = Lattice::new(
        DVec3::new(-12.0, 40.5, 3.0),
        DVec3::new(0.3, 0.25, 0.4),
        [12, 10, 8],
    )
    .unwrap();
    crate::common::body(lattice, 0.08, 0.3, DVec3::new(0.2, -0.1, 0.0), 0.05, seed)
}

/// Every displacement moved by up to `step` h per component, as one solver iteration does.
pub(crate) fn perturb_uniform(body: &mut Body, step: f64, seed: u64) {
    let mut rng = Rng(seed);
    let h = body.lattice().h();
    body.update_displacements(|_, _, u| *u += step * h * rng.vec(-1.0, 1.0))
        .unwrap();
    body.validate().expect("still valid");
}

#[test]
fn uniform_relocate_answers_as_the_cold_search_after_a_solver_step() {
    for settings in [Settings::default(), Settings::f32()] {
        let mut body = uniform_body(11);
        let lattice = *body.lattice();
        let mut rng = Rng(5);
        let points = points(
            &mut rng,
            lattice.cell_count(),
            |cell, xi| body.point_at(cell, xi),
            lattice.origin() - 0.5,
            lattice.upper() + 0.5,
        );
        let old = LatticeLocator::new(&body, settings)
            .unwrap()
            .locate_all(&points);
        perturb_uniform(&mut body, 0.01, 9);
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let held = relocate_and_check(&locator, &settings, &points, &old);
        // Almost every point stays in its cell: the warm start is used, not only correct.
        assert!(held.held * 4 > held.located * 3, "{held:?}");
        assert!(held.located > 1400, "{held:?}");

        // A hint of the same iteration: every located point is answered in one inversion.
        let now = locator.locate_all(&points);
        let mut again = now.clone();
        locator.relocate_all(&points, &mut again);
        for (&x, (a, b)) in points.iter().zip(now.iter().zip(&again)) {
            if let (Ok(Some(a)), Ok(Some(b))) = (a, b) {
                assert_eq!((b.cell, b.inversions), (a.cell, 1), "at {x}");
            }
        }

        let inactive = (0..lattice.cell_count() as u32)
            .map(CellId)
            .find(|&c| !body.is_active(c));
        let active: Vec<CellId> = body.active_cells().collect();
        check_wrong_hints(
            &locator,
            &settings,
            &points,
            &old,
            // The cell "opposite" the point's in the list of active cells: far away.
            |i| active[(i * 7919 + active.len() / 2) % active.len()],
            lattice.cell_count(),
            inactive,
        );
    }
}

/// A base lattice of 4 × 3 × 3 cells, one removed, two refined (one of their children once more:
/// a jump of two levels against its coarse neighbours), displaced smoothly with nodal jitter.
pub(crate) fn adaptive_body(seed: u64) -> AdaptiveBody {
    let lattice = Lattice::new(
        DVec3::new(7.0, -2.0, 100.25),
        DVec3::new(0.5, 0.4, 0.3),
        [4, 3, 3],
    )
    .unwrap();
    let mut leaves = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..4 {
                let leaf = Leaf::new(0, [i, j, k]);
                match [i, j, k] {
                    [3, 2, 2] => {}
                    [1, 1, 1] => {
                        let children = leaf.children();
                        leaves.extend_from_slice(&children[..7]);
                        leaves.extend(children[7].children());
                    }
                    [2, 0, 1] => leaves.extend(leaf.children()),
                    _ => leaves.push(leaf),
                }
            }
        }
    }
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    let mut rng = Rng(seed);
    let h = lattice.h();
    let fine = body.spacing(body.finest_level()).min_element();
    body.update_independent(|_, x, u| {
        let t = (x - lattice.origin()) / h;
        *u = 0.05
            * h
            * DVec3::new(
                (0.7 * t.y + 0.3 * t.z).sin(),
                (0.5 * t.z - 0.4 * t.x).cos(),
                (0.6 * t.x + 0.2 * t.y).sin(),
            )
            + rng.vec(-0.05, 0.05) * fine;
    })
    .unwrap();
    body.validate().unwrap();
    body
}

#[test]
fn adaptive_relocate_answers_as_the_cold_search_after_a_solver_step() {
    for settings in [Settings::default(), Settings::f32()] {
        let mut body = adaptive_body(3);
        let lattice = *body.lattice();
        let mut rng = Rng(17);
        let points = points(
            &mut rng,
            body.cell_count(),
            |cell, xi| body.point_at(cell, xi),
            lattice.origin() - 0.3,
            lattice.upper() + 0.3,
        );
        let old = AdaptiveLocator::new(&body, settings)
            .unwrap()
            .locate_all(&points);
        // Up to 1 % of the finest spacing per component on the independent nodes.
        let fine = body.spacing(body.finest_level());
        let mut jitter = Rng(23);
        body.update_independent(|_, _, u| *u += 0.01 * fine * jitter.vec(-1.0, 1.0))
            .unwrap();
        body.validate().unwrap();
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        let held = relocate_and_check(&locator, &settings, &points, &old);
        assert!(held.held * 4 > held.located * 3, "{held:?}");
        assert!(held.located > 1400, "{held:?}");

        let leaves = body.cell_count();
        check_wrong_hints(
            &locator,
            &settings,
            &points,
            &old,
            |i| CellId(((i * 7919 + leaves / 2) % leaves) as u32),
            leaves,
            None,
        );
    }
}

/// `relocate_all` given answers of another length has no hints: it resizes them and answers as
/// `locate_all`, bit for bit.
#[test]
fn relocate_all_with_answers_of_another_length_locates_cold() {
    let body = uniform_body(2);
    let lattice = *body.lattice();
    let points = points(
        &mut Rng(8),
        lattice.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin(),
        lattice.upper(),
    );
    for settings in [Settings::default(), Settings::f32()] {
        let locator = LatticeLocator::new(&body, settings).unwrap();
        let cold = locator.locate_all(&points);
        for len in [0, 7, points.len() + 3] {
            let mut answers = vec![Ok(None); len];
            locator.relocate_all(&points, &mut answers);
            assert_eq!(answers.len(), points.len());
            for (a, b) in answers.iter().zip(&cold) {
                assert_eq!(bits(a), bits(b));
            }
        }
    }
}
