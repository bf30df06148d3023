//! A fixed amount of single-threaded locating, for profilers (perf, callgrind).
//!
//! Run: `cargo run --release -p cgcontact-benches --example profile_locate [repeats] [f32] [each] [big|huge|sphere] [sorted [mix=F] [window=N]|slabs] [input|blocked] [unordered] [stats]`
//! (`each`: one `locate` call per point instead of the batched `locate_all_into`; `sorted`: the
//! points in lattice order instead of random order, to tell waiting on memory from computing;
//! `mix=F`: then a share F of them swapped with points anywhere (what `Schedule::Auto`'s
//! coherence sample decides on);
//! `window=N`: then shuffled within consecutive windows of N points, so that the lanes of a batch
//! hold different cells while memory stays local; `slabs`: random order within slabs of 5 cell
//! layers; `input`: `Schedule::Input`, no sort inside the batched path; `blocked`:
//! `Schedule::Blocked` with single cells, sorted whatever the order and size; `unordered`:
//! `locate_all_unordered_into`, the answers in the order they were found, with the permutation;
//! `stats`: how many points needed more than one inversion, and Newton iterations per hit).
//! `CGCONTACT_SIMD=avx2` (or `portable`) caps the instruction set the batched path uses.
//!
//! `ratio`: the `scale` bench's 16,000- and 4,194,304-cell blocks, 1 M random points each, in one
//! process, alternated pass by pass (`repeats` rounds, at least 3: the small block's
//! `locate_all_into`, the large block's, then its `locate_all_unordered_into`), so that a VM whose
//! speed drifts over seconds moves them alike; prints each round's large ÷ small for both calls
//! and their medians (the targets of docs/benchmarks.md, "scale").

use std::time::Instant;

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId, LatticeLocator, Locator, Precision, Schedule, Settings};
use cgcontact_scenes::{SphereOnBlock, indented_block};

fn main() -> Result<(), cgcontact::Error> {
    let repeats: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    let precision = if std::env::args().any(|a| a == "f32") {
        Precision::F32
    } else {
        Precision::F64
    };
    // `big`: the 128,000-cell block with 1 M points of the `precision` bench; `huge`: the
    // 4.2 M-cell block of the `scale` bench with 1 M points; `sphere`: the seed's
    // 6,700 sphere contact points on its fine block (most of them outside the block).
    let args: Vec<String> = std::env::args().collect();
    let has = |flag: &str| args.iter().any(|a| a == flag);
    if has("ratio") {
        return ratio(repeats, precision);
    }
    let (body, points) = if has("sphere") {
        let scene = SphereOnBlock::fine().build("sphere")?;
        (scene.body, scene.contact_points)
    } else {
        let scene = if has("huge") {
            indented_block([128, 256, 128], DVec3::splat(5.0 / 128.0), 1_000_000, 7)?
        } else if has("big") {
            indented_block([40, 80, 40], DVec3::splat(0.125), 1_000_000, 7)?
        } else {
            indented_block([20, 40, 20], DVec3::splat(0.25), 100_000, 7)?
        };
        (scene.body, scene.known.iter().map(|k| k.x).collect())
    };
    let (body, points) = if has("partial") {
        // The cells of the lower y half and 4 layers beyond (a rank's local body under MPI with
        // two slabs), and the points of the lower half only: the partial body's slot table and
        // activity mask against the full body's dense layout, on the same points.
        let lattice = *body.lattice();
        let half = lattice.cells()[1] / 2;
        let keep = |c: CellId| lattice.cell_ijk(c).is_some_and(|ijk| ijk[1] < half + 4);
        let mut part = Body::from_cells(lattice, body.active_cells().filter(|&c| keep(c)))?;
        part.update_displacements(|node, _, u| *u = body.displacement(node).unwrap_or_default())?;
        let y = lattice.origin().y + f64::from(half) * lattice.h().y;
        let points: Vec<DVec3> = points.into_iter().filter(|x| x.y < y).collect();
        if has("full") {
            (body, points)
        } else {
            (part, points)
        }
    } else {
        (body, points)
    };
    let mut points = points;
    if has("sorted") {
        // Points in lattice order (diagnosis: how much of the time is memory latency).
        let (o, h) = (body.lattice().origin(), body.lattice().h());
        let key = |x: &DVec3| {
            let t = ((*x - o) / h).floor();
            (t.z as i64, t.y as i64, t.x as i64)
        };
        points.sort_by_key(key);
        if let Some(f) = args.iter().find_map(|a| a.strip_prefix("mix=")) {
            // A share `f` of the points swapped with points anywhere: lattice order with that
            // share of far jumps between consecutive points.
            let f: f64 = f.parse().expect("mix=F with F a share in [0, 1]");
            let n = points.len();
            let mut state = 12345u64;
            let mut next = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                state >> 11
            };
            for _ in 0..(f * n as f64 / 2.0) as usize {
                let (i, j) = (next() as usize % n, next() as usize % n);
                points.swap(i, j);
            }
        }
        if let Some(w) = args.iter().find_map(|a| a.strip_prefix("window=")) {
            let w: usize = w.parse().expect("window=N with N a number of points");
            // A fixed linear congruential shuffle: the same order on every run.
            let mut state = 12345u64;
            for chunk in points.chunks_mut(w) {
                for i in (1..chunk.len()).rev() {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    chunk.swap(i, (state >> 33) as usize % (i + 1));
                }
            }
        }
    } else if has("slabs") {
        // Points in random order within z slabs of 5 cell layers: memory as local as `sorted`, cells
        // within a batch as mixed as random order (diagnosis: memory versus batch coherence).
        let (o, h) = (body.lattice().origin(), body.lattice().h());
        points.sort_by_key(|x| ((x.z - o.z) / h.z / 5.0).floor() as i64);
    }
    let mut settings = if precision == Precision::F32 {
        Settings::f32()
    } else {
        Settings::default()
    };
    if has("input") {
        settings.schedule = Schedule::Input;
    }
    if has("blocked") {
        settings.schedule = Schedule::Blocked { log2_cells: 0 };
    }
    let unordered = has("unordered");
    let each = std::env::args().any(|a| a == "each");
    let locator = LatticeLocator::new(&body, settings)?;
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let mut out = Vec::with_capacity(points.len());
    let mut order = Vec::with_capacity(points.len());
    let start = Instant::now();
    let mut located = 0usize;
    for _ in 0..repeats {
        if each {
            for &x in &points {
                located += usize::from(matches!(
                    locator.locate(std::hint::black_box(x)),
                    Ok(Some(_))
                ));
            }
        } else if unordered {
            one.install(|| {
                locator.locate_all_unordered_into(
                    std::hint::black_box(&points),
                    &mut order,
                    &mut out,
                )
            });
            located += out.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
        } else {
            one.install(|| locator.locate_all_into(std::hint::black_box(&points), &mut out));
            located += out.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    if has("stats") {
        let answers = locator.locate_all(&points);
        let hits: Vec<_> = answers.iter().filter_map(|a| a.ok().flatten()).collect();
        let more = hits.iter().filter(|h| h.inversions > 1).count();
        let iters: u64 = hits.iter().map(|h| u64::from(h.iterations)).sum();
        println!(
            "{} of {} points found, {more} after more than one inversion, {:.2} Newton iterations per hit",
            hits.len(),
            points.len(),
            iters as f64 / hits.len() as f64
        );
    }
    let how = if each {
        "locate"
    } else if unordered {
        "locate_all_unordered"
    } else {
        "locate_all"
    };
    println!(
        "{precision:?} {how}: {located} located in {seconds:.3} s: {:.3} M points/s on one thread",
        (repeats * points.len()) as f64 / seconds / 1e6
    );
    Ok(())
}

/// The `ratio` mode (see the header): the `scale` bench's smallest and largest blocks alternated.
fn ratio(repeats: usize, precision: Precision) -> Result<(), cgcontact::Error> {
    let block = |cells: [u32; 3]| {
        let scene = indented_block(cells, DVec3::splat(5.0 / f64::from(cells[0])), 1_000_000, 7)?;
        let points: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        Ok::<_, cgcontact::Error>((scene.body, points))
    };
    let (small, small_points) = block([20, 40, 20])?;
    let (large, large_points) = block([128, 256, 128])?;
    let settings = Settings {
        precision,
        ..Settings::default()
    };
    let small = LatticeLocator::new(&small, settings)?;
    let large = LatticeLocator::new(&large, settings)?;
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let (mut out, mut order) = (Vec::new(), Vec::new());
    let mut pass = |locator: &LatticeLocator<'_>, points: &[DVec3], unordered: bool| {
        let start = Instant::now();
        one.install(|| {
            if unordered {
                locator.locate_all_unordered_into(points, &mut order, &mut out);
            } else {
                locator.locate_all_into(points, &mut out);
            }
        });
        std::hint::black_box(&out);
        points.len() as f64 / start.elapsed().as_secs_f64() / 1e6
    };
    // A warm-up pass each: the buffers, the sort's pool.
    pass(&small, &small_points, false);
    pass(&large, &large_points, false);
    pass(&large, &large_points, true);
    let (mut into, mut unordered) = (Vec::new(), Vec::new());
    for round in 0..repeats.max(3) {
        let s = pass(&small, &small_points, false);
        let l = pass(&large, &large_points, false);
        let u = pass(&large, &large_points, true);
        println!(
            "round {round}: 16,000 cells {s:.2}, 4.2 M cells {l:.2}, unordered {u:.2} M points/s: \
             {:.3}, {:.3}",
            l / s,
            u / s
        );
        into.push(l / s);
        unordered.push(u / s);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[0], v[v.len() - 1])
    };
    for (name, v) in [
        ("locate_all_into", &mut into),
        ("locate_all_unordered_into", &mut unordered),
    ] {
        let (m, low, high) = median(v);
        println!(
            "{precision:?} {name}, 4.2 M cells / 16,000 cells: median {m:.3}, from {low:.3} to \
             {high:.3} over {} rounds",
            v.len()
        );
    }
    Ok(())
}
