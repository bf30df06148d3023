//! Contact quantities on the seed's scene: the signed gap, closest point and normal of the 6,700
//! sphere points to the fine block's deformed surface (20 × 40 × 20 cells, h = 0.25, the top
//! indented by 0.45 h), search distance D = h, one thread, f64. Beside it, in the same run:
//! locating the same points, and the warm gap (each point's previous face measured first).
//! Printed once: how many points are within D, the penetration (the most negative gap), and how
//! many closest points lie on an edge or corner rather than inside a face.
//!
//! Then the same on the seed's block refined 2 levels under the sphere (`cgcontact demo
//! --adaptive`'s scene), and the first `GapFinder::new` on that body, which makes the table of its
//! leaves' open faces (kept by the body for every later finder).
//!
//! Run: `cargo bench -p cgcontact-benches --bench gap`; for callgrind, a fixed load without
//! criterion: `CGCONTACT_GAP_PASSES=N` and the bench's binary (see docs/benchmarks.md).

use std::hint::black_box;

use cgcontact::{AdaptiveLocator, GapFinder, LatticeLocator, Locator, Settings};
use cgcontact_scenes::{SphereOnAdaptiveBlock, SphereOnBlock};
use criterion::{Criterion, Throughput, criterion_group};

fn gap(c: &mut Criterion) {
    let scene = SphereOnBlock::fine()
        .build("sphere-fine")
        .expect("the seed's scene");
    let points = scene.contact_points.clone();
    let h = scene.body.lattice().h().z;
    let locator = LatticeLocator::new(&scene.body, Settings::default()).expect("valid settings");
    let finder = GapFinder::new(&locator, h).expect("a valid distance");

    let answers: Vec<_> = points.iter().map(|&x| finder.gap(x)).collect();
    let found: Vec<_> = answers.iter().filter_map(|a| a.ok().flatten()).collect();
    let penetration = found.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
    println!(
        "{} sphere points, D = h = {h}: {} within D, {} inside the block, penetration {:.6} \
         (= {:.3} h), {} closest points on an edge or corner",
        points.len(),
        found.len(),
        found.iter().filter(|c| c.gap < 0.0).count(),
        penetration,
        penetration / h,
        found.iter().filter(|c| !c.interior).count(),
    );

    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut group = c.benchmark_group("gap/sphere-6700-f64");
    group.throughput(Throughput::Elements(points.len() as u64));
    let mut located = Vec::with_capacity(points.len());
    group.bench_function("locate, 1 thread", |b| {
        b.iter(|| one.install(|| locator.locate_all_into(black_box(&points), &mut located)))
    });
    let mut gaps = Vec::with_capacity(points.len());
    group.bench_function("gap D = h, 1 thread", |b| {
        b.iter(|| one.install(|| finder.gap_all_into(black_box(&points), &mut gaps)))
    });
    finder.gap_all_into(&points, &mut gaps);
    group.bench_function("gap D = h, warm, 1 thread", |b| {
        b.iter(|| one.install(|| finder.regap_all(black_box(&points), &mut gaps)))
    });
    group.finish();

    let adaptive = SphereOnAdaptiveBlock::fine()
        .build("sphere-adaptive")
        .expect("the seed's scene, refined");
    let points = adaptive.contact_points.clone();
    let locator =
        AdaptiveLocator::new(&adaptive.body, Settings::default()).expect("valid settings");
    let mut group = c.benchmark_group("gap/sphere-adaptive-6700-f64");
    group.sample_size(10);
    group.bench_function("first GapFinder::new (open-face table), 1 thread", |b| {
        b.iter_batched(
            || adaptive.body.clone(),
            |body| {
                let locator = AdaptiveLocator::new(&body, Settings::default()).expect("valid");
                one.install(|| black_box(GapFinder::new(&locator, h).map(|_| ()).is_ok()))
            },
            criterion::BatchSize::LargeInput,
        )
    });
    let finder = GapFinder::new(&locator, h).expect("a valid distance");
    let found = points
        .iter()
        .filter(|&&x| matches!(finder.gap(x), Ok(Some(_))))
        .count();
    println!(
        "{} sphere points on the adaptive block ({} leaves): {found} within D",
        points.len(),
        adaptive.body.cell_count()
    );
    group.sample_size(20);
    group.throughput(Throughput::Elements(points.len() as u64));
    group.bench_function("locate, 1 thread", |b| {
        b.iter(|| one.install(|| locator.locate_all_into(black_box(&points), &mut located)))
    });
    group.bench_function("gap D = h, 1 thread", |b| {
        b.iter(|| one.install(|| finder.gap_all_into(black_box(&points), &mut gaps)))
    });
    group.finish();
}

criterion_group!(benches, gap);
/// `CGCONTACT_GAP_PASSES=N`: instead of criterion, N passes of the uniform group's
/// `gap_all_into` (D = h, one thread) and nothing else, a fixed load for callgrind.
fn main() {
    if let Some(passes) = std::env::var("CGCONTACT_GAP_PASSES")
        .ok()
        .and_then(|n| n.parse::<usize>().ok())
    {
        let scene = SphereOnBlock::fine()
            .build("sphere-fine")
            .expect("the seed's scene");
        let h = scene.body.lattice().h().z;
        let locator = LatticeLocator::new(&scene.body, Settings::default()).expect("valid");
        let finder = GapFinder::new(&locator, h).expect("a valid distance");
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let mut gaps = Vec::new();
        for _ in 0..passes {
            one.install(|| finder.gap_all_into(black_box(&scene.contact_points), &mut gaps));
        }
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
