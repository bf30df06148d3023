//! Speed as meshes grow, whatever the point order: blocks of the seed's shape (1 : 2 : 1, 5 × 10 × 5
//! mm, indented as `indented_block` does) of 16,000, 128,000, 1,024,000 and 4,194,304 cells, with
//! 1,000,000 points made from known (cell, ξ) in random order, then the same points sorted by cell
//! (lattice order). Each is answered by `locate_all_into` (a reused buffer) under the input-order
//! schedule and sorted by cell inside (`Schedule::Blocked { log2_cells: 0 }`, what
//! `Schedule::Auto` does above its threshold to points out of order), in f64 and f32, on 1 and 2
//! threads; on one thread also under `Schedule::Auto` (random and lattice order) and lattice order
//! sorted again; random points under `Schedule::Auto` by `locate_all_unordered_into` (answers in
//! the order found, and the permutation), on 1 and 2 threads; for f64 on one thread also sorted
//! by blocks of 8³ and 16³ cells. Printed once per size: the bytes of nodal data (what
//! `Schedule::Auto` decides by), and the sort's buffers per point.
//!
//! Run: `cargo bench -p cgcontact-benches --bench scale` (about 6 minutes; one size:
//! `-- scale/1024000`).

use std::hint::black_box;
use std::time::Duration;

use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Schedule, Settings};
use cgcontact_scenes::indented_block;
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};

const POINTS: usize = 1_000_000;
const SEED: u64 = 7;
const SIZES: [[u32; 3]; 4] = [[20, 40, 20], [40, 80, 40], [80, 160, 80], [128, 256, 128]];

fn scale(c: &mut Criterion) {
    let pools: Vec<rayon::ThreadPool> = [1, 2]
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .expect("pool")
        })
        .collect();
    for cells in SIZES {
        let scene = indented_block(cells, DVec3::splat(5.0 / f64::from(cells[0])), POINTS, SEED)
            .expect("valid scene");
        let count = scene.body.lattice().cell_count();
        let random: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        let mut sorted = scene.known.clone();
        sorted.sort_by_key(|k| k.cell);
        let ordered: Vec<DVec3> = sorted.iter().map(|k| k.x).collect();
        for (name, base) in [("f64", Settings::default()), ("f32", Settings::f32())] {
            let locator = |schedule| {
                LatticeLocator::new(&scene.body, Settings { schedule, ..base }).expect("valid")
            };
            let input = locator(Schedule::Input);
            let blocked = locator(Schedule::Blocked { log2_cells: 0 });
            let mut out = Vec::with_capacity(POINTS);
            blocked.locate_all_into(&random, &mut out);
            eprintln!(
                "{count} cells {name}: {} nodes, {:.1} MB of displacements; the sort's buffers \
                 {:.1} bytes per point",
                scene.body.node_count(),
                scene.body.node_count() as f64 * if name == "f64" { 24.0 } else { 16.0 } / 1e6,
                (blocked.heap_bytes() - input.heap_bytes()) as f64 / POINTS as f64,
            );
            let auto = locator(Schedule::Auto);
            // (label, locator, points, pool, whether the answers come unordered)
            let mut runs: Vec<(
                String,
                &LatticeLocator<'_>,
                &[DVec3],
                &rayon::ThreadPool,
                bool,
            )> = Vec::new();
            for pool in &pools {
                let t = pool.current_num_threads();
                runs.push((
                    format!("random, input order, {t} thr"),
                    &input,
                    &random,
                    pool,
                    false,
                ));
                runs.push((
                    format!("random, sorted by cell, {t} thr"),
                    &blocked,
                    &random,
                    pool,
                    false,
                ));
                runs.push((
                    format!("lattice order, input order, {t} thr"),
                    &input,
                    &ordered,
                    pool,
                    false,
                ));
                runs.push((
                    format!("random, auto, unordered, {t} thr"),
                    &auto,
                    &random,
                    pool,
                    true,
                ));
            }
            // What the default schedule makes of each order: it sorts points in random order and
            // keeps points already in lattice order as they come.
            for (label, points) in [("random", &random), ("lattice order", &ordered)] {
                runs.push((
                    format!("{label}, auto, 1 thr"),
                    &auto,
                    points,
                    &pools[0],
                    false,
                ));
            }
            runs.push((
                "lattice order, sorted by cell, 1 thr".to_owned(),
                &blocked,
                &ordered,
                &pools[0],
                false,
            ));
            let others: Vec<(u8, LatticeLocator<'_>)> = if name == "f64" {
                [3, 4]
                    .map(|k| (k, locator(Schedule::Blocked { log2_cells: k })))
                    .into()
            } else {
                Vec::new()
            };
            for (k, l) in &others {
                runs.push((
                    format!("random, blocked {}, 1 thr", 1 << k),
                    l,
                    &random,
                    &pools[0],
                    false,
                ));
            }
            let mut order = Vec::with_capacity(POINTS);
            let mut group = c.benchmark_group(format!("scale/{count}-{name}"));
            group
                .throughput(Throughput::Elements(POINTS as u64))
                .sample_size(10)
                .sampling_mode(SamplingMode::Flat)
                .warm_up_time(Duration::from_millis(500))
                .measurement_time(Duration::from_secs(2));
            for (label, l, points, pool, unordered) in runs {
                group.bench_function(label, |b| {
                    b.iter(|| {
                        if unordered {
                            pool.install(|| {
                                l.locate_all_unordered_into(black_box(points), &mut order, &mut out)
                            });
                            black_box(&order);
                        } else {
                            pool.install(|| l.locate_all_into(black_box(points), &mut out));
                            black_box(&out);
                        }
                    })
                });
            }
            group.finish();
        }
    }
}

criterion_group!(benches, scale);
criterion_main!(benches);
