//! Precision and threads on the big scene: an indented block of 40 × 80 × 40 = 128,000
//! cells (h = 0.125, top sinking 0.45 h) with 1,000,000 points made from known (cell, ξ). The lattice
//! locator in f64 and f32 (`Settings::f32()`, in each cell's local frame): batched `locate_all` on one
//! thread and on all threads, and the scalar `locate` one point at a time. The same 1 M points on a
//! 2,000-cell block show how flat throughput is in the number of cells. On the big block the same
//! points are also run sorted by their cell ("lattice order", as a contact surface's points mostly
//! come): there the displacements they read are near one another in memory and a batch's lanes
//! share cells, which is where f32 is asked to reach 1.5× f64.
//!
//! Run: `cargo bench -p cgcontact-benches --bench precision`

use std::hint::black_box;
use std::time::Duration;

use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Settings};
use cgcontact_scenes::indented_block;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

const POINTS: usize = 1_000_000;

fn precision(c: &mut Criterion) {
    let all = rayon::current_num_threads();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    for cells in [[40, 80, 40], [10, 20, 10]] {
        let scene = indented_block(cells, DVec3::splat(0.125), POINTS, 7).expect("valid scene");
        let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        let mut by_cell = scene.known.clone();
        by_cell.sort_by_key(|k| k.cell);
        let sorted: Vec<DVec3> = by_cell.iter().map(|k| k.x).collect();
        let mut group = c.benchmark_group(format!(
            "precision/block-{}-cells-1M",
            cells[0] * cells[1] * cells[2]
        ));
        group
            .throughput(Throughput::Elements(POINTS as u64))
            .sample_size(10)
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(4));
        let mut out = Vec::with_capacity(POINTS);
        for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
            let locator = LatticeLocator::new(&scene.body, settings).expect("valid settings");
            group.bench_function(format!("{name} 1 thread"), |b| {
                b.iter(|| one.install(|| locator.locate_all_into(black_box(&points), &mut out)))
            });
            if cells[0] == 40 {
                group.bench_function(format!("{name} 1 thread, lattice order"), |b| {
                    b.iter(|| one.install(|| locator.locate_all_into(black_box(&sorted), &mut out)))
                });
                group.bench_function(format!("{name} {all} threads"), |b| {
                    b.iter(|| locator.locate_all_into(black_box(&points), &mut out))
                });
                // The scalar search one point at a time: what the batched `locate_all` gains.
                group.bench_function(format!("{name} 1 thread, sequential locate"), |b| {
                    b.iter(|| {
                        for (slot, &x) in out.iter_mut().zip(black_box(&points)) {
                            *slot = locator.locate(x);
                        }
                    })
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, precision);
criterion_main!(benches);
