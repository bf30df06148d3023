//! Work bounded by the local displacement: the seed's fine block with jitter (0.3 h) and its 6,700
//! sphere contact points (most of them outside the block), as deformed, then with one node moved
//! 100 h on every axis (a spike), then rigidly translated by 10 h on every axis, with the same points
//! (the moved block then holds 3,339 of them instead of 653) and with the points moved along (the
//! same work as the deformed block, were it O(1) per point). One thread.
//!
//! Before the displacement range and the per-block ranges bounded the search, the spike cost O(cells)
//! per point (85 s for the 6,700 points) and the translation 120× the deformed query; the targets
//! are 50× and 3×.
//!
//! Then the gap search (`GapFinder::gap_all_into`, D = h) on the same bodies and points: it was
//! bounded by the whole body's displacement range until it walked the same block ranges.
//!
//! Run: `cargo bench -p cgcontact-benches --bench locality`

use std::hint::black_box;
use std::time::Duration;

use cgcontact::glam::DVec3;
use cgcontact::{Body, GapFinder, LatticeLocator, Locator, Settings};
use cgcontact_scenes::SphereOnBlock;
use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main};

/// The bodies of the comparison (as deformed, with a spike, translated twice) and how far each moves
/// the query points.
pub fn bodies() -> Vec<(&'static str, Body, DVec3)> {
    let scene = SphereOnBlock {
        jitter: 0.3,
        known_points: 0,
        ..SphereOnBlock::fine()
    }
    .build("sphere-fine-jitter")
    .expect("valid scene");
    let base = scene.body;
    let h = base.lattice().h();
    let spike_node = base.lattice().node_index([10, 20, 10]);
    let mut spike = base.clone();
    spike
        .update_displacements(|node, _, u| {
            if node == spike_node {
                *u += 100.0 * h;
            }
        })
        .expect("finite");
    let mut translated = base.clone();
    translated
        .update_displacements(|_, _, u| *u += 10.0 * h)
        .expect("finite");
    vec![
        ("deformed", base, DVec3::ZERO),
        ("spike 100 h", spike, DVec3::ZERO),
        ("translated 10 h", translated.clone(), DVec3::ZERO),
        ("translated 10 h, points too", translated, 10.0 * h),
    ]
}

/// A group of 10 samples of 2 s each, after half a second of warm-up.
fn new_group<'c>(c: &'c mut Criterion, name: &str) -> BenchmarkGroup<'c, WallTime> {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    group
}

fn locality(c: &mut Criterion) {
    let points = SphereOnBlock {
        jitter: 0.3,
        known_points: 0,
        ..SphereOnBlock::fine()
    }
    .build("sphere-fine-jitter")
    .expect("valid scene")
    .contact_points;
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut group = new_group(c, "locality/fine-sphere");
    group.throughput(Throughput::Elements(points.len() as u64));
    for (name, body, shift) in bodies() {
        let locator = LatticeLocator::new(&body, Settings::default()).expect("valid");
        let points: Vec<DVec3> = points.iter().map(|&x| x + shift).collect();
        let mut out = Vec::with_capacity(points.len());
        group.bench_function(name, |b| {
            b.iter(|| one.install(|| locator.locate_all_into(black_box(&points), &mut out)))
        });
    }
    group.finish();
    // The gap search (D = h) on the same bodies and points: its box was bounded by the whole
    // body's displacement range, so the spike made every point walk most of the lattice.
    let mut group = new_group(c, "locality/gap-fine-sphere");
    group.throughput(Throughput::Elements(points.len() as u64));
    for (name, body, shift) in bodies() {
        let locator = LatticeLocator::new(&body, Settings::default()).expect("valid");
        let finder = GapFinder::new(&locator, body.lattice().h().z).expect("a valid distance");
        let points: Vec<DVec3> = points.iter().map(|&x| x + shift).collect();
        let mut out = Vec::with_capacity(points.len());
        group.bench_function(name, |b| {
            b.iter(|| one.install(|| finder.gap_all_into(black_box(&points), &mut out)))
        });
    }
    group.finish();
    let mut group = new_group(c, "locality/build");
    for (name, body, _) in bodies().into_iter().take(3) {
        group.bench_function(name, |b| {
            b.iter(|| LatticeLocator::new(black_box(&body), Settings::default()).expect("valid"))
        });
    }
    group.finish();
}

criterion_group!(benches, locality);
criterion_main!(benches);
