//! Every strategy on the same scene: the seed's fine block (20 × 40 × 20 cells, h = 0.25)
//! with 10,000 points made from known (cell, ξ), and the seed's 6,700 sphere contact points (most of
//! them outside the block, as in the seed). One thread, so that the ratios compare work, not cores.
//! The O(cells)-per-point strategies (centroid, node-radius, brute force) run on an evenly spaced
//! subsample; `Throughput::Elements` makes every line read in points per second.
//!
//! Run: `cargo bench -p cgcontact-benches --bench strategies`

use std::hint::black_box;
use std::time::Duration;

use cgcontact::glam::DVec3;
use cgcontact::{Body, LatticeLocator, Locator, Settings};
use cgcontact_baseline::{
    BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree,
};
use cgcontact_scenes::SphereOnBlock;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// Points a slow strategy runs on.
const SLOW: usize = 2_000;
const BRUTE: usize = 200;

/// `n` points spread evenly over `points` (the sphere's points are ordered by height).
fn strided(points: &[DVec3], n: usize) -> Vec<DVec3> {
    let n = n.min(points.len());
    (0..n).map(|i| points[i * points.len() / n]).collect()
}

fn strategies<'a>(body: &'a Body) -> Vec<(&'static str, Box<dyn Locator + 'a>, usize)> {
    let d = Settings::default();
    let seed = NodeRadiusOptions {
        inversion: Inversion::SeedFaithful,
        ..Default::default()
    };
    vec![
        (
            "lattice f64",
            Box::new(LatticeLocator::new(body, d).expect("valid")),
            usize::MAX,
        ),
        (
            "lattice f32",
            Box::new(LatticeLocator::new(body, Settings::f32()).expect("valid")),
            usize::MAX,
        ),
        (
            "rtree",
            Box::new(RTree::new(body, d).expect("valid")),
            usize::MAX,
        ),
        (
            "centroid",
            Box::new(CentroidRadius::new(body, d).expect("valid")),
            SLOW,
        ),
        (
            "noderad exact",
            Box::new(NodeRadius::new(body, d).expect("valid")),
            SLOW,
        ),
        (
            "noderad seed-faithful",
            Box::new(NodeRadius::with_options(body, d, seed).expect("valid")),
            SLOW,
        ),
        (
            "brute",
            Box::new(BruteForce::new(body, d).expect("valid")),
            BRUTE,
        ),
    ]
}

fn every_strategy(c: &mut Criterion) {
    let scene = SphereOnBlock::fine()
        .build("sphere-fine")
        .expect("valid scene");
    let known: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let locators = strategies(&scene.body);
    for (name, points) in [
        ("fine-known", &known),
        ("fine-sphere", &scene.contact_points),
    ] {
        let mut group = c.benchmark_group(format!("strategies/{name}"));
        group
            .sample_size(10)
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2));
        for (strategy, locator, cap) in &locators {
            let subset = strided(points, *cap);
            group.throughput(Throughput::Elements(subset.len() as u64));
            let label = if subset.len() < points.len() {
                format!("{strategy} ({} of {} points)", subset.len(), points.len())
            } else {
                (*strategy).to_owned()
            };
            let mut out = Vec::with_capacity(subset.len());
            group.bench_function(label, |b| {
                b.iter(|| one.install(|| locator.locate_all_into(black_box(&subset), &mut out)))
            });
        }
        group.finish();
    }
}

/// What building each strategy costs (the R-tree's bulk load against the lattice locator's scan).
fn build(c: &mut Criterion) {
    let body = SphereOnBlock {
        contact_points: 0,
        known_points: 0,
        ..SphereOnBlock::fine()
    }
    .build("fine")
    .expect("valid scene")
    .body;
    let d = Settings::default();
    let mut group = c.benchmark_group("strategies/build-fine");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    group.bench_function("lattice", |b| {
        b.iter(|| LatticeLocator::new(black_box(&body), d).expect("valid"))
    });
    group.bench_function("rtree", |b| {
        b.iter(|| RTree::new(black_box(&body), d).expect("valid"))
    });
    group.bench_function("noderad (global min radius)", |b| {
        b.iter(|| NodeRadius::new(black_box(&body), d).expect("valid"))
    });
    group.finish();
}

criterion_group!(benches, every_strategy, build);
criterion_main!(benches);
