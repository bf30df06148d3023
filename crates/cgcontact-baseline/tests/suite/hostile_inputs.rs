//! Hostile inputs through the public API, drawn from a seeded generator: lattices, active cells,
//! displacements, settings, hints, reused buffers, gap distances and adaptive leaves that are
//! zero, negative, NaN, infinite, tiny, huge, out of range, overlapping or repeated. Every call
//! must return (no panic: a panic crashes the C, Octave and Python callers), with an error where
//! the input is unusable, and otherwise an answer checked against brute force or against the
//! (cell, ξ) a point was made from.

use std::collections::BTreeSet;

use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Answer, Body, CandidateOrder, CellId, Error, GapFinder, Hit,
    Lattice, LatticeLocator, Leaf, Locator, PointError, Precision, Settings,
};
use cgcontact_baseline::{BodyRef, BruteForce, CentroidRadius, NodeRadius, RTree};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A hostile f64: special values, the ends of the ranges, or an ordinary value of any scale.
fn hostile(rng: &mut ChaCha8Rng, ordinary: f64) -> f64 {
    const SPECIAL: [f64; 12] = [
        0.0,
        -0.0,
        -1.0,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e-300,
        1e300,
        f64::MIN_POSITIVE,
        f64::MAX,
        1e-100,
        1e100,
    ];
    if rng.random_bool(0.3) {
        SPECIAL[rng.random_range(0..SPECIAL.len())]
    } else {
        ordinary * rng.random_range(0.5..2.0)
    }
}

fn hostile_vec(rng: &mut ChaCha8Rng, ordinary: f64) -> DVec3 {
    DVec3::new(
        hostile(rng, ordinary),
        hostile(rng, ordinary),
        hostile(rng, ordinary),
    )
}

fn hostile_count(rng: &mut ChaCha8Rng) -> u32 {
    const SPECIAL: [u32; 6] = [0, u32::MAX, u32::MAX - 1, 1 << 16, 1 << 21, 1 << 31];
    if rng.random_bool(0.15) {
        SPECIAL[rng.random_range(0..SPECIAL.len())]
    } else {
        rng.random_range(1..5)
    }
}

/// Settings with a hostile field now and then, and whether `validate` must accept them.
fn hostile_settings(rng: &mut ChaCha8Rng) -> (Settings, bool) {
    let mut s = if rng.random_bool(0.5) {
        Settings::default()
    } else {
        Settings::f32()
    };
    s.order = if rng.random_bool(0.5) {
        CandidateOrder::Predicted
    } else {
        CandidateOrder::Undeformed
    };
    match rng.random_range(0..6) {
        0 => s.newton_tol = hostile(rng, s.newton_tol),
        1 => s.inside_tol = hostile(rng, s.inside_tol),
        2 => s.max_iter = [0, 1, u32::MAX][rng.random_range(0..3)],
        _ => {}
    }
    let valid = s.newton_tol.is_finite()
        && s.newton_tol > 0.0
        && s.inside_tol >= 0.0
        && s.inside_tol <= Settings::MAX_INSIDE_TOL
        && s.max_iter > 0;
    (s, valid)
}

/// The cells of `answer` (`None` for a miss), and whether it was refused.
fn cell(answer: &Answer) -> Result<Option<CellId>, PointError> {
    answer.map(|hit| hit.map(|h| h.cell))
}

/// Lattice::new accepts exactly the lattices its documentation describes, and each one it
/// accepts has finite corners, fewer than 2^32 nodes and spacings in range.
#[test]
fn hostile_lattices_are_refused_or_sound() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x1a77);
    let mut accepted = 0;
    for _ in 0..20_000 {
        let origin = hostile_vec(&mut rng, 3.0);
        let h = hostile_vec(&mut rng, 0.5);
        let cells = [0; 3].map(|_| hostile_count(&mut rng));
        let nodes: u128 = cells.iter().map(|&n| u128::from(n) + 1).product();
        let plain = origin.is_finite()
            && h.is_finite()
            && h.min_element() >= Lattice::MIN_SPACING
            && h.max_element() <= Lattice::MAX_SPACING
            && !cells.contains(&0)
            && nodes < u128::from(u32::MAX);
        match Lattice::new(origin, h, cells) {
            Ok(lattice) => {
                accepted += 1;
                assert!(plain, "{origin} {h} {cells:?} accepted");
                assert!(lattice.upper().is_finite());
                assert!(lattice.node_count() < u32::MAX as usize);
                let last = CellId(lattice.cell_count() as u32 - 1);
                let ijk = lattice.cell_ijk(last).unwrap();
                assert_eq!(lattice.cell_id(ijk), last);
                assert_eq!(lattice.cell_ijk(CellId(u32::MAX)), None);
                assert!(lattice.displacement_limit(h) >= 0.0);
            }
            Err(Error::InvalidLattice(_)) => {}
            Err(other) => panic!("{other:?}"),
        }
    }
    assert!(accepted > 1000, "{accepted}");
}

/// A small valid body with holes, displaced smoothly, on a lattice anywhere in scale and
/// place; its cells are given with repeats and in any order.
fn small_body(rng: &mut ChaCha8Rng) -> Body {
    let scale = 10f64.powi(rng.random_range(-6..6));
    let origin = DVec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    ) * scale
        * 10f64.powi(rng.random_range(0..8));
    let h = DVec3::new(
        rng.random_range(0.3..1.0),
        rng.random_range(0.3..1.0),
        rng.random_range(0.3..1.0),
    ) * scale;
    let cells = [0; 3].map(|_| rng.random_range(1..5));
    let lattice = Lattice::new(origin, h, cells).unwrap();
    let n = lattice.cell_count() as u32;
    let ids: Vec<CellId> = (0..rng.random_range(1..2 * n + 1))
        .map(|_| CellId(rng.random_range(0..n)))
        .collect();
    let mut body = Body::from_cells(lattice, ids).unwrap();
    let phase = rng.random_range(0.0..6.0);
    let amplitude = rng.random_range(0.0..0.15);
    let shift = rng.random_range(-3.0..3.0);
    body.update_displacements(|_, x, u| {
        let t = (x - origin) / h;
        *u = h
            * (shift
                + amplitude * DVec3::new((t.y + phase).sin(), (t.z - phase).cos(), (t.x).sin()));
    })
    .unwrap();
    body.validate().unwrap();
    body
}

/// Points for `body`: made from a known (cell, ξ) strictly inside, on a boundary of a cell,
/// anywhere around the body, and hostile ones (not finite, huge, tiny).
fn points(body: &Body, rng: &mut ChaCha8Rng) -> (Vec<DVec3>, Vec<(DVec3, CellId)>) {
    let lattice = body.lattice();
    let active: Vec<CellId> = body.active_cells().collect();
    let mut known = Vec::new();
    let mut all = Vec::new();
    for _ in 0..40 {
        let c = active[rng.random_range(0..active.len())];
        let xi = DVec3::new(
            rng.random_range(-0.9..0.9),
            rng.random_range(-0.9..0.9),
            rng.random_range(-0.9..0.9),
        );
        let x = body.point_at(c, xi).unwrap();
        known.push((x, c));
        all.push(x);
        let face = DVec3::new(
            f64::from(rng.random_range(-1..=1)),
            f64::from(rng.random_range(-1..=1)),
            rng.random_range(-1.0..=1.0),
        );
        all.push(body.point_at(c, face).unwrap());
        let low = lattice.origin() - (lattice.upper() - lattice.origin());
        let size = 3.0 * (lattice.upper() - lattice.origin());
        all.push(
            low + size
                * DVec3::new(
                    rng.random_range(0.0..1.0),
                    rng.random_range(0.0..1.0),
                    rng.random_range(0.0..1.0),
                ),
        );
        all.push(hostile_vec(rng, lattice.origin().length() + 1.0));
    }
    (all, known)
}

/// Bodies, settings, locators and every strategy on hostile inputs: errors where the docs say,
/// and otherwise answers that agree with brute force.
#[test]
fn hostile_queries_answer_as_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(0xb0d1);
    let (mut checked, mut found) = (0, 0);
    for round in 0..150 {
        let mut body = small_body(&mut rng);
        let lattice = *body.lattice();
        let count = body.node_count();

        // Setters with wrong lengths or values leave an error and a usable body.
        let before = body.displacements().to_vec();
        let len = [0, count - 1, count + 1, count][rng.random_range(0..4)];
        let mut u = vec![DVec3::ZERO; len];
        if let Some(v) = u.get_mut(rng.random_range(0..len.max(1))) {
            *v = hostile_vec(&mut rng, lattice.h().x);
        }
        let limit = body.displacement_limit();
        let fine = u.iter().all(|v| v.abs().cmple(DVec3::splat(limit)).all());
        let set = body.set_displacements(&u);
        assert_eq!(set.is_ok(), len == count && fine, "{round}: {set:?}");
        if set.is_ok() {
            body.set_displacements(&before).unwrap();
        }
        assert_eq!(body.displacements(), &before[..]);
        assert!(
            Body::from_cells(lattice, [CellId(lattice.cell_count() as u32)]).is_err()
                && Body::from_cells(lattice, []).is_err()
        );

        let (settings, valid) = hostile_settings(&mut rng);
        let strategies = [
            LatticeLocator::new(&body, settings).map(|l| Box::new(l) as Box<dyn Locator>),
            BruteForce::new(&body, settings).map(|l| Box::new(l) as Box<dyn Locator>),
            CentroidRadius::new(&body, settings).map(|l| Box::new(l) as Box<dyn Locator>),
            NodeRadius::new(&body, settings).map(|l| Box::new(l) as Box<dyn Locator>),
            RTree::new(&body, settings).map(|l| Box::new(l) as Box<dyn Locator>),
        ];
        for s in &strategies {
            assert_eq!(s.is_ok(), valid, "{round}: {settings:?}");
        }
        let (all, known) = points(&body, &mut rng);
        let Ok(strategies) = strategies.into_iter().collect::<Result<Vec<_>, _>>() else {
            continue;
        };
        let (locator, brute) = (&strategies[0], &strategies[1]);
        // With hostile tolerances the answers only have to come back; with the defaults of a
        // precision they agree with brute force.
        let plain = settings.newton_tol
            == if settings.precision == Precision::F64 {
                Settings::NEWTON_TOL
            } else {
                Settings::NEWTON_TOL_F32
            }
            && settings.inside_tol <= Settings::INSIDE_TOL_F32
            && settings.max_iter >= Settings::MAX_ITER;
        for &x in &all {
            let answers: Vec<Answer> = strategies.iter().map(|s| s.locate(x)).collect();
            for a in &answers {
                assert_eq!(a.is_err(), !x.is_finite(), "{round}: {x}");
            }
            let owners = brute.locate_owners(x);
            if plain && let Ok(owners) = owners {
                let cells: Vec<CellId> = owners.iter().map(|h| h.cell).collect();
                // The complete strategies: the lattice locator and the R-tree.
                for a in [&answers[0], &answers[4]] {
                    match cell(a).unwrap() {
                        Some(c) => assert!(cells.contains(&c), "{round}: {x} {c} {cells:?}"),
                        None => assert!(cells.is_empty(), "{round}: {x} missed {cells:?}"),
                    }
                }
            }
        }
        if plain {
            checked += 1;
            for &(x, c) in &known {
                assert_eq!(cell(&locator.locate(x)), Ok(Some(c)), "{round}: {x}");
            }
            found += all
                .iter()
                .filter(|&&x| matches!(locator.locate(x), Ok(Some(_))))
                .count();
        }

        // A reused buffer of any length holds the answers of `locate`, in order.
        let mut out: Vec<Answer> = vec![Err(PointError::NonFinite); rng.random_range(0..300)];
        locator.locate_all_into(&all, &mut out);
        assert_eq!(out.len(), all.len());
        for (x, a) in all.iter().zip(&out) {
            assert_eq!(cell(a), cell(&locator.locate(*x)), "{round}: {x}");
        }
        // Hints out of range, of another body, with NaN or huge ξ, or refusals: the answer
        // is still one a cold search could give.
        let mut hints: Vec<Answer> = all
            .iter()
            .map(|_| match rng.random_range(0..5) {
                0 => Hit::hint(CellId(u32::MAX), DVec3::ZERO),
                1 => Hit::hint(
                    CellId(rng.random_range(0..lattice.cell_count() as u32 + 3)),
                    hostile_vec(&mut rng, 0.5),
                ),
                2 => Err(PointError::NonFinite),
                3 => Ok(None),
                _ => Hit::hint(CellId(rng.random_range(0..1 << 20)), DVec3::NAN),
            })
            .collect();
        for (&x, hint) in all.iter().zip(&hints) {
            let warm = locator.relocate(x, hint);
            let cold = locator.locate(x);
            assert_eq!(warm.is_err(), cold.is_err(), "{round}: {x}");
            match cell(&warm) {
                Ok(Some(c)) => {
                    let owners = locator.locate_owners(x).unwrap();
                    assert!(owners.iter().any(|h| h.cell == c), "{round}: {x} {c}");
                }
                Ok(None) => assert_eq!(cell(&cold), Ok(None), "{round}: {x}"),
                Err(_) => {}
            }
        }
        let single: Vec<_> = all
            .iter()
            .zip(&hints)
            .map(|(&x, h)| cell(&locator.relocate(x, h)))
            .collect();
        locator.relocate_all(&all, &mut hints);
        assert_eq!(
            hints.iter().map(cell).collect::<Vec<_>>(),
            single,
            "{round}"
        );

        // Gap distances: refused outside [0, 1e150]; answers finite or refused for NaN points.
        {
            let lattice_locator = LatticeLocator::new(&body, settings).unwrap();
            let distance = hostile(&mut rng, 2.0 * lattice.h().max_element());
            let finder = GapFinder::new(&lattice_locator, distance);
            assert_eq!(
                finder.is_ok(),
                (0.0..=cgcontact::MAX_DISPLACEMENT).contains(&distance),
                "{distance:e}"
            );
            if let Ok(finder) = finder {
                for &x in all.iter().take(40) {
                    match finder.gap(x) {
                        Ok(Some(c)) => {
                            assert!(c.gap.is_finite() && c.gap.abs() <= distance * (1.0 + 1e-12));
                            assert!((c.normal.length() - 1.0).abs() < 1e-9, "{c:?}");
                        }
                        Ok(None) => {}
                        Err(_) => assert!(!x.is_finite()),
                    }
                }
            }
        }
    }
    assert!(checked > 50 && found > 40 * checked, "{checked} {found}");
}

/// Leaves drawn to be refined cells of a small lattice, with hostile ones mixed in (too deep,
/// out of range, repeated, overlapping): `from_leaves` refuses exactly the sets with such a
/// leaf, and on the others every point made from a known (leaf, ξ) is found in that leaf, as
/// brute force finds it.
#[test]
fn hostile_leaves_are_refused_or_located_as_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x1eaf);
    let mut built = 0;
    for round in 0..300 {
        let cells = [0; 3].map(|_| rng.random_range(1..4));
        let lattice = Lattice::new(
            DVec3::new(rng.random_range(-5.0..5.0), 2.0, -1.0),
            DVec3::new(0.5, 0.25, 1.0),
            cells,
        )
        .unwrap();
        // A valid cover: each base cell kept, dropped or refined a few levels in a corner.
        let mut leaves = Vec::new();
        for k in 0..cells[2] {
            for j in 0..cells[1] {
                for i in 0..cells[0] {
                    let mut leaf = Leaf::new(0, [i, j, k]);
                    if rng.random_bool(0.2) {
                        continue;
                    }
                    for _ in 0..rng.random_range(0..4) {
                        let children = leaf.children();
                        leaves.extend(children[1..].iter().copied());
                        leaf = children[0];
                    }
                    leaves.push(leaf);
                }
            }
        }
        let mut broken = false;
        match rng.random_range(0..8) {
            0 if !leaves.is_empty() => {
                let twin = leaves[rng.random_range(0..leaves.len())];
                leaves.push(twin);
                broken = true;
            }
            1 if !leaves.is_empty() => {
                // A parent of a leaf beside it, or a child of it: an overlap either way.
                let leaf = leaves[rng.random_range(0..leaves.len())];
                leaves.push(if leaf.level > 0 {
                    Leaf::new(leaf.level - 1, leaf.ijk.map(|v| v / 2))
                } else {
                    leaf.children()[rng.random_range(0..8)]
                });
                broken = true;
            }
            2 => {
                let level = rng.random_range(21..=u8::MAX);
                leaves.push(Leaf::new(level, [0; 3]));
                broken = true;
            }
            3 => {
                let level = rng.random_range(0..4);
                let a = rng.random_range(0..3);
                let mut ijk = [0; 3];
                ijk[a] = [cells[a] << level, u32::MAX][rng.random_range(0..2)];
                leaves.push(Leaf::new(level, ijk));
                broken = true;
            }
            _ => {}
        }
        let n = leaves.len();
        if n > 1 {
            leaves.swap(rng.random_range(0..n), rng.random_range(0..n));
        }
        let body = AdaptiveBody::from_leaves(lattice, leaves.clone());
        if leaves.is_empty() {
            assert_eq!(body.err(), Some(Error::EmptyBody));
            continue;
        }
        let distinct: BTreeSet<Leaf> = leaves.iter().copied().collect();
        assert_eq!(body.is_ok(), !broken, "{round}: {:?}", body.err());
        let Ok(mut body) = body else {
            assert!(distinct.len() <= leaves.len());
            continue;
        };
        built += 1;
        let h = body.spacing(body.finest_level());
        body.update_independent(|_, x, u| {
            *u = 0.1 * h * DVec3::new((3.0 * x.y).sin(), (2.0 * x.z).cos(), (x.x + x.y).sin())
        })
        .unwrap();
        body.validate().unwrap();
        // Wrong lengths and values are refused, and the body keeps its displacements.
        let before = body.displacements().to_vec();
        assert!(body.set_displacements(&before[1..]).is_err());
        let mut bad = before.clone();
        let at = rng.random_range(0..bad.len());
        bad[at] = hostile_vec(&mut rng, 1e200);
        if body.set_displacements(&bad).is_ok() {
            body.set_displacements(&before).unwrap();
        }
        assert_eq!(body.displacements(), &before[..]);

        let settings = [Settings::default(), Settings::f32()][round % 2];
        let locator = AdaptiveLocator::new(&body, settings).unwrap();
        let brute = BruteForce::new(&body, settings).unwrap();
        let rtree = RTree::new(&body, settings).unwrap();
        for _ in 0..30 {
            let c = CellId(rng.random_range(0..body.cell_count() as u32));
            let xi = DVec3::new(
                rng.random_range(-0.9..0.9),
                rng.random_range(-0.9..0.9),
                rng.random_range(-0.9..0.9),
            );
            let x = body.point_at(c, xi).unwrap();
            for s in [&locator as &dyn Locator, &brute, &rtree] {
                assert_eq!(cell(&s.locate(x)), Ok(Some(c)), "{round}: {}", s.name());
            }
            let hint = Hit::hint(CellId(rng.random_range(0..u32::MAX)), DVec3::NAN);
            assert_eq!(cell(&locator.relocate(x, &hint)), Ok(Some(c)), "{round}");
            let away = x + DVec3::splat(1e3);
            assert_eq!(cell(&locator.locate(away)), Ok(None));
            assert_eq!(cell(&brute.locate(away)), Ok(None));
        }
        assert!(locator.locate(DVec3::NAN).is_err());
    }
    assert!(built > 100, "{built}");
}

/// `BodyRef::level` of a cell the body does not have panicked on an adaptive body ("a leaf of
/// the body") and answered 0 on a uniform one; it now answers `None` for both, and each leaf's
/// own level, or 0 for each active cell, otherwise.
#[test]
fn body_ref_level_answers_only_for_the_bodys_cells() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 1, 1]).unwrap();
    let mut leaves = vec![Leaf::new(0, [0, 0, 0])];
    let children = Leaf::new(0, [1, 0, 0]).children();
    leaves.extend(children[1..].iter().copied());
    leaves.extend(children[0].children());
    let adaptive = AdaptiveBody::from_leaves(lattice, leaves.clone()).unwrap();
    let body = BodyRef::from(&adaptive);
    for (id, leaf) in leaves.iter().enumerate() {
        assert_eq!(body.level(CellId(id as u32)), Some(leaf.level));
    }
    for id in [leaves.len() as u32, 1 << 20, u32::MAX] {
        assert_eq!(body.level(CellId(id)), None);
    }
    let uniform = Body::from_cells(lattice, [CellId(1)]).unwrap();
    let body = BodyRef::from(&uniform);
    assert_eq!(body.level(CellId(1)), Some(0));
    for id in [0, 2, u32::MAX] {
        assert_eq!(body.level(CellId(id)), None);
    }
}
