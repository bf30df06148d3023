//! A contact solver's loop: the seed's indented block (20 × 40 × 20 cells, h = 0.25) and 1,000,000
//! points made from known (cell, ξ), relocated at each of 20 Newton iterations after the
//! displacements moved a little. Each iteration adds to every displacement a deterministic
//! pseudo-random amount of up to 1 % of h per component (a hash of the iteration and the node),
//! rebuilds the locator (`LatticeLocator::new`), relocates every point and measures the gaps of
//! the seed's 6,700 sphere points within h: "cold" with `locate_all_into` and `gap_all_into`,
//! "warm" with `relocate_all` and `regap_all`, the previous iteration's answers as hints.
//! f64 and f32, one thread; printed once: Newton inversions per located point of each.
//!
//! Also the last iterations of a converged solve, where the displacements no longer change: one
//! relocation of the same 1 M points with their own answers as hints, against `locate_all_into`,
//! on that block and on the adaptive block of the `adaptive` bench (1 M points).
//!
//! Run: `cargo bench -p cgcontact-benches --bench solver_loop`

use std::hint::black_box;
use std::time::{Duration, Instant};

use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveLocator, Answer, Body, GapAnswer, GapFinder, LatticeLocator, Locator, Settings,
};
use cgcontact_scenes::{SphereOnBlock, adaptive_block, indented_block};
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};

const POINTS: usize = 1_000_000;
const ITERATIONS: u32 = 20;
const SEED: u64 = 7;
const H: f64 = 0.25;
/// The largest change of a displacement component per iteration, in units of h.
const STEP: f64 = 0.01;

/// How each iteration relocates the points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// `locate_all_into`: every point searched from scratch.
    Cold,
    /// `relocate_all`: the previous answers as hints.
    Warm,
}

/// A uniform value in [−1, 1) from (iteration, node, axis): SplitMix64's finalizer, a few
/// multiplications per value, so that updating the displacements stays a small part of the loop.
fn jitter(iteration: u32, node: usize, axis: u64) -> f64 {
    let mut z = ((u64::from(iteration) << 40) ^ ((node as u64) << 2) ^ axis)
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// What one loop found: Newton inversions and iterations (of the successful inversion) of the
/// located points, and how many were located, summed over the solver's iterations.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    inversions: u64,
    iterations: u64,
    located: u64,
}

/// The solver loop: `ITERATIONS` times, move every displacement of `body` by up to `STEP` h,
/// rebuild the locator, relocate `points` into `answers` and measure the gaps of `sphere` within
/// h into `gaps` (each holding the answers of the iteration before: a cold search of the starting
/// displacements for the first).
fn solver_loop(
    body: &mut Body,
    points: &[DVec3],
    answers: &mut Vec<Answer>,
    sphere: &[DVec3],
    gaps: &mut Vec<GapAnswer>,
    settings: Settings,
    start: Start,
) -> Tally {
    let mut tally = Tally::default();
    let h = body.lattice().h();
    for iteration in 1..=ITERATIONS {
        body.update_displacements(|node, _, u| {
            let step = DVec3::new(
                jitter(iteration, node, 0),
                jitter(iteration, node, 1),
                jitter(iteration, node, 2),
            );
            *u += STEP * h * step;
        })
        .expect("finite displacements");
        let locator = LatticeLocator::new(body, settings).expect("valid settings");
        let finder = GapFinder::new(&locator, H).expect("a valid distance");
        match start {
            Start::Cold => {
                locator.locate_all_into(points, answers);
                finder.gap_all_into(sphere, gaps);
            }
            Start::Warm => {
                locator.relocate_all(points, answers);
                finder.regap_all(sphere, gaps);
            }
        }
        for hit in answers.iter().filter_map(|a| a.ok().flatten()) {
            tally.inversions += u64::from(hit.inversions);
            tally.iterations += u64::from(hit.iterations);
            tally.located += 1;
        }
    }
    tally
}

fn solver(c: &mut Criterion) {
    let scene = indented_block([20, 40, 20], DVec3::splat(H), POINTS, SEED).expect("valid scene");
    let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    let sphere = SphereOnBlock::fine()
        .build("sphere-fine")
        .expect("the seed's scene")
        .contact_points;
    let start_u = scene.body.displacements().to_vec();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    // The state every loop starts from: the scene's displacements and their cold answers.
    let fresh = |settings: Settings| {
        let mut body = scene.body.clone();
        body.set_displacements(&start_u).expect("same body");
        let mut answers = Vec::with_capacity(POINTS);
        let locator = LatticeLocator::new(&body, settings).expect("valid settings");
        locator.locate_all_into(&points, &mut answers);
        let mut gaps = Vec::with_capacity(sphere.len());
        GapFinder::new(&locator, H)
            .expect("a valid distance")
            .gap_all_into(&sphere, &mut gaps);
        (body, answers, gaps)
    };
    for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
        // Once, untimed: inversions per located point of each start, and the same answers.
        let runs = [Start::Cold, Start::Warm].map(|start| {
            let (mut body, mut answers, mut gaps) = fresh(settings);
            let tally = one.install(|| {
                solver_loop(
                    &mut body,
                    &points,
                    &mut answers,
                    &sphere,
                    &mut gaps,
                    settings,
                    start,
                )
            });
            (tally, answers, body, gaps)
        });
        let [
            (cold, cold_answers, body, cold_gaps),
            (warm, warm_answers, _, warm_gaps),
        ] = &runs;
        // Warm gaps are the cold ones.
        let worst = cold_gaps
            .iter()
            .zip(warm_gaps)
            .map(|(a, b)| match (a, b) {
                (Ok(Some(a)), Ok(Some(b))) => (a.gap - b.gap).abs(),
                (Ok(None), Ok(None)) => 0.0,
                _ => f64::INFINITY,
            })
            .fold(0.0, f64::max);
        println!(
            "solver loop {name}: last gaps of the sphere points, warm against cold: worst {worst:e}"
        );
        // Where the last answers differ, both cells must hold the point (a shared face).
        let locator = LatticeLocator::new(body, settings).expect("valid settings");
        let (mut differ, mut shared) = (0, 0);
        for ((a, b), &x) in cold_answers.iter().zip(warm_answers).zip(&points) {
            let cell = |a: &Answer| a.map(|h| h.map(|h| h.cell));
            if cell(a) != cell(b) {
                differ += 1;
                let owners = locator.locate_owners(x).unwrap_or_default();
                let owns = |a: &Answer| owners.iter().any(|o| Ok(Some(o.cell)) == cell(a));
                shared += usize::from(owns(a) && owns(b));
            }
        }
        let per = |t: &Tally| t.inversions as f64 / t.located as f64;
        let newton = |t: &Tally| t.iterations as f64 / t.located as f64;
        println!(
            "solver loop {name}: {ITERATIONS} iterations x {POINTS} points, steps of up to {STEP} h; \
             located per iteration {:.0} (cold) {:.0} (warm); inversions per located point: cold \
             {:.4}, warm {:.4}, warm / cold = {:.4}; Newton iterations per located point: cold \
             {:.3}, warm {:.3}; last answers in another cell: {differ} of {POINTS}, of which held by \
             both cells: {shared}",
            cold.located as f64 / f64::from(ITERATIONS),
            warm.located as f64 / f64::from(ITERATIONS),
            per(cold),
            per(warm),
            per(warm) / per(cold),
            newton(cold),
            newton(warm),
        );

        let mut group = c.benchmark_group(format!("solver_loop/1M-{name}"));
        group
            .throughput(Throughput::Elements(u64::from(ITERATIONS) * POINTS as u64))
            .sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(20));
        for start in [Start::Cold, Start::Warm] {
            let label = match start {
                Start::Cold => "cold, 1 thread",
                Start::Warm => "warm, 1 thread",
            };
            group.bench_function(label, |b| {
                b.iter_custom(|loops| {
                    let mut timed = Duration::ZERO;
                    for _ in 0..loops {
                        let (mut body, mut answers, mut gaps) = fresh(settings);
                        let begin = Instant::now();
                        let tally = one.install(|| {
                            solver_loop(
                                &mut body,
                                black_box(&points),
                                &mut answers,
                                black_box(&sphere),
                                &mut gaps,
                                settings,
                                start,
                            )
                        });
                        timed += begin.elapsed();
                        black_box((tally, &answers, &gaps));
                    }
                    timed
                })
            });
        }
        group.finish();
    }
}

/// Cold and warm relocation of `points` on `locator` when nothing moved since the hints were
/// found: what a warm start saves at best.
fn converged(c: &mut Criterion, name: &str, locator: &impl Locator, points: &[DVec3]) {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut group = c.benchmark_group(format!("solver_loop/converged-1M-{name}"));
    group
        .throughput(Throughput::Elements(points.len() as u64))
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    let mut answers = Vec::with_capacity(points.len());
    group.bench_function("cold, 1 thread", |b| {
        b.iter(|| one.install(|| locator.locate_all_into(black_box(points), &mut answers)))
    });
    // The answers found are their own hints: every iteration relocates from the same ones.
    locator.locate_all_into(points, &mut answers);
    group.bench_function("warm, 1 thread", |b| {
        b.iter(|| one.install(|| locator.relocate_all(black_box(points), &mut answers)))
    });
    group.finish();
}

fn converged_uniform(c: &mut Criterion) {
    let scene = indented_block([20, 40, 20], DVec3::splat(H), POINTS, SEED).expect("valid scene");
    let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
        let locator = LatticeLocator::new(&scene.body, settings).expect("valid settings");
        converged(c, &format!("uniform-{name}"), &locator, &points);
    }
}

fn converged_adaptive(c: &mut Criterion) {
    let scene = adaptive_block([20, 40, 20], DVec3::splat(H), 2, 1.5, POINTS, SEED)
        .expect("valid adaptive scene");
    let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
        let locator = AdaptiveLocator::new(&scene.body, settings).expect("valid settings");
        converged(c, &format!("adaptive-{name}"), &locator, &points);
    }
}

criterion_group!(benches, solver, converged_uniform, converged_adaptive);
criterion_main!(benches);
