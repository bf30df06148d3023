//! Adaptive bodies against uniform ones (the adaptive targets). The seed's block (20 × 40 × 20 base
//! cells, h = 0.25) refined two levels within 1.5 of the top face's centre, 2:1 balanced: 51,840
//! leaves, most of them at level 2, with 1,000,000 points made from known (leaf, ξ), drawn per leaf.
//! Against it, a uniform indented block of about as many cells (`block_cells_for`, shape 1 : 2 : 1,
//! the same physical size) with 1 M known points, and its twin (`uniform_twin`): the same cells
//! under the adaptive scene's indentation, with the adaptive scene's points. All on one thread,
//! f64 and f32 (the adaptive body with and without its corner table:
//! `AdaptiveBody::set_corner_table`), answers written into a reused buffer. Also the adaptive locator's build (`AdaptiveLocator::new`), on this scene
//! and on a body of over a million nodes, and, printed once: memory per node, where it goes, and
//! Newton inversions per located point (`locate_counted`, failed inversions included). Last, the
//! same block unrefined, as an adaptive body of one level and as its uniform twin.
//!
//! Run: `cargo bench -p cgcontact-benches --bench adaptive`

use std::hint::black_box;
use std::time::{Duration, Instant};

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, AdaptiveLocator, LatticeLocator, Locator, Settings};
use cgcontact_scenes::{adaptive_block, block_cells_for, indented_block, uniform_twin};
use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};

const POINTS: usize = 1_000_000;
const SEED: u64 = 7;
/// The seed's fine block: base cells and spacing.
const BASE_CELLS: [u32; 3] = [20, 40, 20];
const BASE_H: f64 = 0.25;
/// Refinement levels and radius (mm) around the top face's centre.
const LEVELS: u8 = 2;
const RADIUS: f64 = 1.5;

/// Leaves per level.
fn level_counts(body: &AdaptiveBody) -> Vec<usize> {
    let mut counts = vec![0; usize::from(body.finest_level()) + 1];
    for leaf in body.leaves() {
        counts[usize::from(leaf.level)] += 1;
    }
    counts
}

/// Heap bytes per node, and where they go.
fn report_memory(body: &AdaptiveBody) {
    let nodes = body.node_count();
    let per_node = |bytes: usize| bytes as f64 / nodes as f64;
    let parts: Vec<String> = body
        .heap_parts()
        .iter()
        .map(|&(part, bytes)| format!("{part} {:.1}", per_node(bytes)))
        .collect();
    eprintln!(
        "adaptive body: {} leaves, {nodes} nodes ({} hanging), heap {} bytes = {:.1} bytes per \
         node: {}",
        body.cell_count(),
        body.hanging_nodes().count(),
        body.heap_bytes(),
        per_node(body.heap_bytes()),
        parts.join(", "),
    );
}

/// Newton inversions per located point, failed ones included, and how many points were located.
fn report_inversions(name: &str, locator: &impl Locator, points: &[DVec3]) {
    let mut tried = 0u64;
    let mut located = 0u64;
    let mut worst = 0;
    for &x in points {
        let (answer, n) = locator.locate_counted(x);
        tried += u64::from(n);
        worst = worst.max(n);
        if matches!(answer, Ok(Some(_))) {
            located += 1;
        }
    }
    eprintln!(
        "{name}: {located} of {} points located, {:.4} inversions per located point (most for one \
         point: {worst})",
        points.len(),
        tried as f64 / located as f64
    );
}

fn adaptive(c: &mut Criterion) {
    let start = Instant::now();
    let h = DVec3::splat(BASE_H);
    let scene =
        adaptive_block(BASE_CELLS, h, LEVELS, RADIUS, POINTS, SEED).expect("valid adaptive scene");
    let body = &scene.body;
    let leaves = body.cell_count();
    // The uniform block: as many cells, the adaptive block's shape and physical size.
    let cells = block_cells_for(leaves, DVec3::new(1.0, 2.0, 1.0));
    let size = h * DVec3::new(
        f64::from(BASE_CELLS[0]),
        f64::from(BASE_CELLS[1]),
        f64::from(BASE_CELLS[2]),
    );
    let uniform_h = size
        / DVec3::new(
            f64::from(cells[0]),
            f64::from(cells[1]),
            f64::from(cells[2]),
        );
    let uniform = indented_block(cells, uniform_h, POINTS, SEED).expect("valid uniform scene");
    // The same problem meshed uniformly: the adaptive scene's indentation and points.
    let twin = uniform_twin(BASE_CELLS, h, cells, &scene).expect("valid uniform twin");
    eprintln!(
        "scenes built in {:.1} s: adaptive {BASE_CELLS:?} base cells, h = {BASE_H}, {LEVELS} levels \
         within {RADIUS}: {leaves} leaves (per level {:?}); uniform {cells:?} = {} cells, h = {:.4}",
        start.elapsed().as_secs_f64(),
        level_counts(body),
        uniform.body.lattice().cell_count(),
        uniform_h.x,
    );
    report_memory(body);
    // The same body storing its corner table: the memory-for-speed trade.
    let mut tabled = body.clone();
    tabled.set_corner_table(true);
    report_memory(&tabled);
    eprintln!(
        "uniform body: {} nodes, heap {} bytes = {:.1} bytes per node",
        uniform.body.node_count(),
        uniform.body.heap_bytes(),
        uniform.body.heap_bytes() as f64 / uniform.body.node_count() as f64
    );
    let adaptive_points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    let uniform_points: Vec<DVec3> = uniform.known.iter().map(|k| k.x).collect();
    let twin_points: Vec<DVec3> = twin.known.iter().map(|k| k.x).collect();
    // Where the known points lie: per leaf level.
    let mut per_level = vec![0usize; usize::from(body.finest_level()) + 1];
    for k in &scene.known {
        per_level[usize::from(
            body.leaves()
                .get(k.cell.index())
                .expect("a leaf of the body")
                .level,
        )] += 1;
    }
    eprintln!("adaptive known points per leaf level: {per_level:?}");

    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
        let adaptive = AdaptiveLocator::new(body, settings).expect("valid settings");
        let with_table = AdaptiveLocator::new(&tabled, settings).expect("valid settings");
        let lattice = LatticeLocator::new(&uniform.body, settings).expect("valid settings");
        report_inversions(&format!("adaptive {name}"), &adaptive, &adaptive_points);
        report_inversions(&format!("uniform {name}"), &lattice, &uniform_points);
        let twin_lattice = LatticeLocator::new(&twin.body, settings).expect("valid settings");
        report_inversions(&format!("uniform twin {name}"), &twin_lattice, &twin_points);

        let rows: [(String, &dyn Locator, &[DVec3]); 4] = [
            (
                format!("adaptive {leaves} leaves, 1 thread"),
                &adaptive,
                &adaptive_points,
            ),
            (
                format!("adaptive {leaves} leaves, corner table, 1 thread"),
                &with_table,
                &adaptive_points,
            ),
            (
                format!(
                    "uniform {} cells, 1 thread",
                    uniform.body.lattice().cell_count()
                ),
                &lattice,
                &uniform_points,
            ),
            (
                format!(
                    "uniform twin {} cells, same indentation and points, 1 thread",
                    twin.body.lattice().cell_count()
                ),
                &twin_lattice,
                &twin_points,
            ),
        ];
        bench_rows(c, &format!("adaptive/locate-1M-{name}"), &rows, &one);
    }
    one_level(c, &one);
}

/// One criterion group of `rows` (name, locator, points): each row a `locate_all_into` of its
/// points into a reused buffer, on the one-thread pool `one`.
fn bench_rows(
    c: &mut Criterion,
    group: &str,
    rows: &[(String, &dyn Locator, &[DVec3])],
    one: &rayon::ThreadPool,
) {
    let mut group = c.benchmark_group(group);
    group
        .throughput(Throughput::Elements(POINTS as u64))
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    let mut out = Vec::with_capacity(POINTS);
    for &(ref row, locator, points) in rows {
        group.bench_function(row, |b| {
            b.iter(|| {
                one.install(|| locator.locate_all_into(black_box(points), &mut out));
                black_box(&out);
            })
        });
    }
    group.finish();
}

/// An adaptive body of one level is a uniform body, not a slower copy of one: the seed's block
/// unrefined (`adaptive_block` with 0 levels: 16,000 leaves of level 0) against its uniform twin,
/// the same cells, indentation and points, 1 M of them, one thread.
fn one_level(c: &mut Criterion, one: &rayon::ThreadPool) {
    let h = DVec3::splat(BASE_H);
    let scene = adaptive_block(BASE_CELLS, h, 0, RADIUS, POINTS, SEED).expect("valid scene");
    let twin = uniform_twin(BASE_CELLS, h, BASE_CELLS, &scene).expect("valid uniform twin");
    let adaptive_points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    let twin_points: Vec<DVec3> = twin.known.iter().map(|k| k.x).collect();
    for (name, settings) in [("f64", Settings::default()), ("f32", Settings::f32())] {
        let adaptive = AdaptiveLocator::new(&scene.body, settings).expect("valid settings");
        let uniform = LatticeLocator::new(&twin.body, settings).expect("valid settings");
        let cells = scene.body.cell_count();
        let rows: [(String, &dyn Locator, &[DVec3]); 2] = [
            (
                format!("adaptive, one level, {cells} leaves, 1 thread"),
                &adaptive,
                &adaptive_points,
            ),
            (
                format!("uniform, the same {cells} cells and points, 1 thread"),
                &uniform,
                &twin_points,
            ),
        ];
        bench_rows(c, &format!("adaptive/one-level-1M-{name}"), &rows, one);
    }
}

fn build(c: &mut Criterion) {
    let scene = adaptive_block(BASE_CELLS, DVec3::splat(BASE_H), LEVELS, RADIUS, 0, SEED)
        .expect("valid adaptive scene");
    // A body of over a million nodes: the same block at a third of the base spacing, refined
    // within the same radius (three times as many base cells across it).
    let big = adaptive_block(
        [60, 120, 60],
        DVec3::splat(BASE_H / 3.0),
        LEVELS,
        RADIUS,
        0,
        SEED,
    )
    .expect("valid adaptive scene");
    eprintln!(
        "build scenes: {} nodes ({} leaves) and {} nodes ({} leaves, per level {:?})",
        scene.body.node_count(),
        scene.body.cell_count(),
        big.body.node_count(),
        big.body.cell_count(),
        level_counts(&big.body),
    );
    report_memory(&big.body);
    let mut group = c.benchmark_group("adaptive/build");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (name, body) in [("seed block", &scene.body), ("big block", &big.body)] {
        let nodes = body.node_count();
        group.bench_function(format!("locator f64, {name}, {nodes} nodes"), |b| {
            b.iter(|| AdaptiveLocator::new(black_box(body), Settings::default()).expect("valid"))
        });
        group.bench_function(format!("locator f32, {name}, {nodes} nodes"), |b| {
            b.iter(|| AdaptiveLocator::new(black_box(body), Settings::f32()).expect("valid"))
        });
    }
    group.finish();
}

criterion_group!(benches, adaptive, build);
criterion_main!(benches);
