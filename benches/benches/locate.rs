//! The core's headline benchmark: `locate_all` on the seed's fine block, a 20 × 40 × 20
//! lattice (h = 0.25) indented by a smooth field of maximum displacement 0.45 h, 100,000 points
//! made from known (cell, ξ), f64, on one thread and on all threads. Also: building a locator from a
//! 136,000-node body.
//!
//! Run: `cargo bench -p cgcontact-benches --bench locate`

use std::hint::black_box;

use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Settings};
use cgcontact_scenes::indented_block;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

const POINTS: usize = 100_000;

fn locate_all(c: &mut Criterion) {
    let scene = indented_block([20, 40, 20], DVec3::splat(0.25), POINTS, 7).expect("valid scene");
    let body = scene.body;
    let points: Vec<DVec3> = scene.known.iter().map(|p| p.x).collect();
    let locator = LatticeLocator::new(&body, Settings::default()).expect("valid settings");

    // Report what the benchmark cannot: inversions per located point, and the max displacement.
    let answers = locator.locate_all(&points);
    let located: Vec<_> = answers.iter().filter_map(|a| a.ok().flatten()).collect();
    let inversions: u64 = located.iter().map(|h| u64::from(h.inversions)).sum();
    let iterations: u64 = located.iter().map(|h| u64::from(h.iterations)).sum();
    println!(
        "scene: 20x40x20 cells, h = 0.25, u_max = {:.4} (= {:.3} h), {} points, located {}, \
         Newton inversions per located point {:.4}, iterations per point {:.3}",
        locator.max_displacement().max_element(),
        locator.max_displacement().max_element() / 0.25,
        points.len(),
        located.len(),
        inversions as f64 / located.len() as f64,
        iterations as f64 / located.len() as f64,
    );

    let mut group = c.benchmark_group("locate_all/fine-block-f64");
    group.throughput(Throughput::Elements(POINTS as u64));
    let mut out = Vec::with_capacity(POINTS);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    group.bench_function("1 thread", |b| {
        b.iter(|| one.install(|| locator.locate_all_into(black_box(&points), &mut out)))
    });
    group.bench_function(format!("{} threads", rayon::current_num_threads()), |b| {
        b.iter(|| locator.locate_all_into(black_box(&points), &mut out))
    });
    // Answers for every point whichever functions ran before (a filtered run starts with none).
    out.resize(POINTS, Ok(None));
    group.bench_function("1 thread, sequential locate", |b| {
        b.iter(|| {
            for (slot, &x) in out.iter_mut().zip(&points) {
                *slot = locator.locate(black_box(x));
            }
            black_box(&out);
        })
    });
    group.finish();
}

fn build(c: &mut Criterion) {
    let body = indented_block([40, 80, 40], DVec3::splat(0.125), 0, 7)
        .expect("valid scene")
        .body;
    println!(
        "build scene: {} nodes, body heap {} bytes = {:.1} bytes per node",
        body.node_count(),
        body.heap_bytes(),
        body.heap_bytes() as f64 / body.node_count() as f64
    );
    c.bench_function("build/locator-136k-nodes", |b| {
        b.iter(|| LatticeLocator::new(black_box(&body), Settings::default()).expect("valid"))
    });
    // f32 locators also round the displacements into their own f32 copy (16 bytes per node).
    c.bench_function("build/locator-136k-nodes-f32", |b| {
        b.iter(|| LatticeLocator::new(black_box(&body), Settings::f32()).expect("valid"))
    });
}

criterion_group!(benches, locate_all, build);
criterion_main!(benches);
