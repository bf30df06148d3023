//! The batched queries' schedules (`Settings::schedule`): sorting the points by lattice block
//! changes the order of the work, never an answer. Every batched query (`locate_all_into`,
//! `locate_all_unordered_into`, `relocate_all`, `gap_all_into`, `gap_all_unordered_into`,
//! `regap_all`) of the lattice and adaptive locators, in f64 and f32, on one and three threads,
//! answers bit for bit as the input order and as the one-point query, with points inside, on
//! faces, outside, refused, and repeated.

use cgcontact::{
    AdaptiveLocator, Answer, Body, GapAnswer, GapFinder, Lattice, LatticeLocator, Locator,
    Schedule, Settings, Surface,
};
use glam::DVec3;

use crate::common::Rng;
use crate::warm::{adaptive_body, bits, perturb_uniform, points, uniform_body};

const SCHEDULES: [Schedule; 5] = [
    Schedule::Input,
    Schedule::Auto,
    Schedule::Blocked { log2_cells: 0 },
    Schedule::Blocked { log2_cells: 2 },
    Schedule::Blocked { log2_cells: 40 },
];

/// `copies` shuffled copies of `points`: enough points for several pieces of the sort on
/// several threads, each point answered more than once.
fn shuffled(points: &[DVec3], copies: usize, seed: u64) -> Vec<DVec3> {
    let mut all: Vec<DVec3> = (0..copies).flat_map(|_| points.iter().copied()).collect();
    let mut rng = Rng(seed);
    for i in (1..all.len()).rev() {
        all.swap(i, rng.below(i + 1));
    }
    all
}

fn pools() -> Vec<rayon::ThreadPool> {
    [1, 3]
        .map(|n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        })
        .into()
}

fn assert_bitwise(got: &[Answer], expected: &[Answer], what: &str) {
    assert_eq!(got.len(), expected.len(), "{what}");
    for (i, (a, b)) in got.iter().zip(expected).enumerate() {
        assert_eq!(bits(a), bits(b), "{what}: point {i}");
    }
}

/// `order` holds each index of `expected` once, and `got[k]` is bit for bit the answer of
/// index `order[k]`.
fn assert_unordered(order: &[usize], got: &[Answer], expected: &[Answer], what: &str) {
    assert_eq!(order.len(), expected.len(), "{what}");
    assert_eq!(got.len(), expected.len(), "{what}");
    let mut seen = vec![false; expected.len()];
    for (&i, answer) in order.iter().zip(got) {
        assert!(
            !std::mem::replace(&mut seen[i], true),
            "{what}: index {i} twice"
        );
        assert_eq!(bits(answer), bits(&expected[i]), "{what}: point {i}");
    }
}

/// Cold and warm batches of `make(settings)` under every schedule against the one-point queries.
fn check_locator<L: Locator>(make: impl Fn(Settings) -> L, points: &[DVec3], hints: &[Answer]) {
    for base in [Settings::default(), Settings::f32()] {
        let reference = make(base);
        let cold: Vec<Answer> = points.iter().map(|&x| reference.locate(x)).collect();
        let warm: Vec<Answer> = points
            .iter()
            .zip(hints)
            .map(|(&x, hint)| reference.relocate(x, hint))
            .collect();
        assert!(
            cold.iter().filter(|a| matches!(a, Ok(Some(_)))).count() > points.len() / 2,
            "most points are located"
        );
        for schedule in SCHEDULES {
            let locator = make(Settings { schedule, ..base });
            for pool in pools() {
                let what = format!(
                    "{schedule:?}, {:?}, {} threads",
                    base.precision,
                    pool.current_num_threads()
                );
                // Twice into one buffer (the pool's buffers reused), then a shorter batch.
                let mut out = Vec::new();
                for _ in 0..2 {
                    pool.install(|| locator.locate_all_into(points, &mut out));
                    assert_bitwise(&out, &cold, &format!("locate_all, {what}"));
                }
                let short = points.len() / 3;
                pool.install(|| locator.locate_all_into(&points[..short], &mut out));
                assert_bitwise(&out, &cold[..short], &format!("short, {what}"));
                let mut answers = hints.to_vec();
                pool.install(|| locator.relocate_all(points, &mut answers));
                assert_bitwise(&answers, &warm, &format!("relocate_all, {what}"));
                // Unordered: each index once, with its point's answer; twice into one buffer,
                // then a shorter batch.
                let (mut order, mut out) = (Vec::new(), Vec::new());
                for n in [points.len(), points.len(), short] {
                    pool.install(|| {
                        locator.locate_all_unordered_into(&points[..n], &mut order, &mut out)
                    });
                    assert_unordered(&order, &out, &cold[..n], &format!("unordered, {what}"));
                }
            }
        }
    }
}

#[test]
fn uniform_batches_answer_alike_under_every_schedule() {
    let mut body = uniform_body(31);
    let lattice = *body.lattice();
    let base = points(
        &mut Rng(4),
        lattice.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin() - 0.5,
        lattice.upper() + 0.5,
    );
    let points = shuffled(&base, 20, 9);
    let hints = LatticeLocator::new(&body, Settings::default())
        .unwrap()
        .locate_all(&points);
    perturb_uniform(&mut body, 0.01, 5);
    check_locator(
        |settings| LatticeLocator::new(&body, settings).unwrap(),
        &points,
        &hints,
    );
}

#[test]
fn adaptive_batches_answer_alike_under_every_schedule() {
    let body = adaptive_body(8);
    let lattice = *body.lattice();
    let base = points(
        &mut Rng(6),
        body.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin() - 0.3,
        lattice.upper() + 0.3,
    );
    let points = shuffled(&base, 20, 2);
    // Hints from the same body: the warm path's common case (the hinted leaf holds the point).
    let hints = AdaptiveLocator::new(&body, Settings::default())
        .unwrap()
        .locate_all(&points);
    check_locator(
        |settings| AdaptiveLocator::new(&body, settings).unwrap(),
        &points,
        &hints,
    );
}

/// `gap_all_into` and `regap_all` under every schedule against `gap` and `regap`.
fn check_gaps<L: Surface>(make: impl Fn(Settings) -> L, points: &[DVec3], distance: f64) {
    let reference = make(Settings::default());
    let finder = GapFinder::new(&reference, distance).unwrap();
    let cold: Vec<GapAnswer> = points.iter().map(|&x| finder.gap(x)).collect();
    // Hints: the answers of the points one place along (mostly wrong faces).
    let mut hints = cold.clone();
    hints.rotate_left(1);
    let warm: Vec<GapAnswer> = points
        .iter()
        .zip(&hints)
        .map(|(&x, hint)| finder.regap(x, hint))
        .collect();
    assert!(cold.iter().filter(|a| matches!(a, Ok(Some(_)))).count() > points.len() / 2);
    for schedule in SCHEDULES {
        let locator = make(Settings {
            schedule,
            ..Settings::default()
        });
        let finder = GapFinder::new(&locator, distance).unwrap();
        for pool in pools() {
            let what = format!("{schedule:?}, {} threads", pool.current_num_threads());
            let mut out = Vec::new();
            pool.install(|| finder.gap_all_into(points, &mut out));
            assert!(out == cold, "gap_all_into, {what}");
            let mut order = Vec::new();
            pool.install(|| finder.gap_all_unordered_into(points, &mut order, &mut out));
            let mut seen = vec![false; points.len()];
            for (&i, answer) in order.iter().zip(&out) {
                assert!(
                    !std::mem::replace(&mut seen[i], true),
                    "{what}: index {i} twice"
                );
                assert!(
                    *answer == cold[i],
                    "gap_all_unordered_into, {what}: point {i}"
                );
            }
            assert_eq!(order.len(), points.len(), "{what}");
            let mut answers = hints.clone();
            pool.install(|| finder.regap_all(points, &mut answers));
            assert!(answers == warm, "regap_all, {what}");
        }
    }
}

#[test]
fn gap_batches_answer_alike_under_every_schedule() {
    let body = uniform_body(12);
    let lattice = *body.lattice();
    let base = points(
        &mut Rng(3),
        lattice.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin() - 0.5,
        lattice.upper() + 0.5,
    );
    check_gaps(
        |settings| LatticeLocator::new(&body, settings).unwrap(),
        &shuffled(&base, 3, 1),
        1.0,
    );

    let body = adaptive_body(5);
    let lattice = *body.lattice();
    let base = points(
        &mut Rng(7),
        body.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin() - 0.3,
        lattice.upper() + 0.3,
    );
    check_gaps(
        |settings| AdaptiveLocator::new(&body, settings).unwrap(),
        &shuffled(&base, 3, 4),
        0.5,
    );
}

/// `sorts_batch` (of the locators and of the gap finder) says whether a batch would be sorted,
/// as the schedule decides: always under `Blocked`, never under `Input`, and under `Auto` for
/// batches of `Schedule::AUTO_MIN_POINTS` or more, out of order, on a body of more than
/// `Schedule::AUTO_BYTES` of nodal data, or on an adaptive body of any size (its batches reuse
/// the leaves of sorted points).
#[test]
fn sorts_batch_follows_the_schedule() {
    let small = uniform_body(8);
    let n = cells_for_bytes(Schedule::AUTO_BYTES);
    let large = Body::full(Lattice::new(DVec3::ZERO, DVec3::ONE, [n, n, n]).unwrap());
    let adaptive = adaptive_body(3);
    let min = Schedule::AUTO_MIN_POINTS;
    // Points in random order over the large body, and the same sorted by lattice cell.
    let mut rng = Rng(11);
    let random: Vec<DVec3> = (0..min)
        .map(|_| {
            let mut at = || rng.uniform(0.0, f64::from(n));
            DVec3::new(at(), at(), at())
        })
        .collect();
    let mut ordered = random.clone();
    ordered.sort_by_key(|x| {
        let c = x.floor().as_uvec3();
        (c.z, c.y, c.x)
    });
    for (schedule, small_sorts, large_sorts) in [
        (Schedule::Input, false, false),
        (Schedule::Blocked { log2_cells: 0 }, true, true),
        (Schedule::Auto, false, true),
    ] {
        let adaptive_sorts = schedule != Schedule::Input;
        for precision in [Settings::default(), Settings::f32()] {
            let settings = Settings {
                schedule,
                ..precision
            };
            let what = format!("{schedule:?}, {:?}", precision.precision);
            let small = LatticeLocator::new(&small, settings).unwrap();
            let large = LatticeLocator::new(&large, settings).unwrap();
            let adaptive = AdaptiveLocator::new(&adaptive, settings).unwrap();
            assert_eq!(small.sorts_batch(&random), small_sorts, "small, {what}");
            assert_eq!(
                adaptive.sorts_batch(&random),
                adaptive_sorts,
                "adaptive, {what}"
            );
            let blocked = matches!(schedule, Schedule::Blocked { .. });
            let fewer = adaptive.sorts_batch(&random[..min - 1]);
            assert_eq!(fewer, blocked, "adaptive, fewer, {what}");
            assert_eq!(large.sorts_batch(&random), large_sorts, "large, {what}");
            // The gap finder decides by its surface's locator.
            let gaps = |l| GapFinder::new(l, 1.0).unwrap().sorts_batch(&random);
            assert_eq!(gaps(&small), small_sorts, "small gaps, {what}");
            assert_eq!(gaps(&large), large_sorts, "large gaps, {what}");
            // One point is never sorted; under Auto, fewer than the minimum neither, nor points
            // already in lattice order.
            assert!(!large.sorts_batch(&random[..1]), "{what}");
            let auto = schedule == Schedule::Auto;
            let fewer = large.sorts_batch(&random[..min - 1]);
            assert_eq!(fewer, large_sorts && !auto, "fewer, {what}");
            let sorted = large.sorts_batch(&ordered);
            assert_eq!(sorted, large_sorts && !auto, "in order, {what}");
        }
    }
}

/// Cells per axis of a cube whose nodes' displacements take more than `bytes` in f64 (24 bytes
/// a node) and in the f32 locator's copy (16).
fn cells_for_bytes(bytes: usize) -> u32 {
    (1..)
        .find(|&n: &u32| (n as usize + 1).pow(3) * 16 > bytes)
        .unwrap()
}

/// Batches on one locator from several threads at once: one call holds the locator's sort
/// buffers, the others sort in fresh ones (`try_lock`). Every call, ordered or not, on two
/// threads, with lengths no multiple of the pieces, answers each point once, as `locate`.
#[test]
fn concurrent_batches_on_one_locator_answer_each_point_once() {
    let body = uniform_body(21);
    let lattice = *body.lattice();
    let base = points(
        &mut Rng(8),
        lattice.cell_count(),
        |cell, xi| body.point_at(cell, xi),
        lattice.origin() - 0.5,
        lattice.upper() + 0.5,
    );
    let points = shuffled(&base, 14, 3);
    let settings = Settings {
        schedule: Schedule::Blocked { log2_cells: 0 },
        ..Settings::default()
    };
    let locator = LatticeLocator::new(&body, settings).unwrap();
    let cold: Vec<Answer> = points.iter().map(|&x| locator.locate(x)).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    std::thread::scope(|scope| {
        for caller in 0..4 {
            let (locator, points, cold, pool) = (&locator, &points, &cold, &pool);
            scope.spawn(move || {
                let (mut order, mut out) = (Vec::new(), Vec::new());
                for round in 0..3 {
                    let from = 1 + caller * 37 + round;
                    let what = format!("caller {caller}, round {round}");
                    if (caller + round) % 2 == 0 {
                        pool.install(|| {
                            locator.locate_all_unordered_into(&points[from..], &mut order, &mut out)
                        });
                        assert_unordered(&order, &out, &cold[from..], &what);
                    } else {
                        pool.install(|| locator.locate_all_into(&points[from..], &mut out));
                        assert_bitwise(&out, &cold[from..], &what);
                    }
                }
            });
        }
    });
}
