//! A fixed single-threaded load on the `adaptive` bench's scene, for profilers (perf, callgrind).
//!
//! Run: `cargo run --release -p cgcontact-benches --example profile_adaptive [repeats] [f32] [uniform [twin]] [ratio] [big] [table] [each] [points=N] [levels=L] [radius=R] [input] [blocked=N] [adaptive-blocked=N] [threads=N] [stats]`
//! (`uniform`: the uniform block of about as many cells instead, `twin` its `uniform_twin`: the
//! adaptive scene's indentation and points; `big`: the bench's 1.3 M-node
//! block; `table`: the body stores its corner table; `each`: one `locate` call per
//! point instead of `locate_all_into`; `points=N`: N known points instead of 1 M; `levels=L`
//! and `radius=R`: refined L levels (2 by default) within R (1.5) of the top face's centre;
//! `input`: `Schedule::Input` for every body (no sort: the adaptive batches keep nothing from one
//! to the next); `blocked=N`: `Schedule::Blocked` with blocks of 2^N finest cells for every body,
//! `adaptive-blocked=N` for the adaptive body only; `threads=N`: a pool of N threads instead of 1;
//! `stats`: the body's leaves, nodes and heap bytes per node on stderr).
//!
//! `ratio`: the adaptive body against its uniform twin in one process, alternated pass by pass
//! (`repeats` rounds, at least 3, of one `locate_all_into` each), so that a VM whose speed drifts
//! over seconds moves both alike; prints each round's adaptive ÷ twin and their median. With
//! `levels=0`, the twin has the adaptive body's own cells.

use std::time::Instant;

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, LatticeLocator, Locator, Settings};
use cgcontact_scenes::{adaptive_block, block_cells_for, indented_block, uniform_twin};

fn main() -> Result<(), cgcontact::Error> {
    let args: Vec<String> = std::env::args().collect();
    let has = |flag: &str| args.iter().any(|a| a == flag);
    let repeats: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(5);
    let points: usize = args
        .iter()
        .find_map(|a| a.strip_prefix("points="))
        .map(|n| n.parse().expect("points=N with N a number"))
        .unwrap_or(1_000_000);
    let threads: usize = args
        .iter()
        .find_map(|a| a.strip_prefix("threads="))
        .map_or(1, |n| n.parse().expect("threads=N with N a number"));
    let mut settings = if has("f32") {
        Settings::f32()
    } else {
        Settings::default()
    };
    if let Some(log2) = args.iter().find_map(|a| a.strip_prefix("blocked=")) {
        settings.schedule = cgcontact::Schedule::Blocked {
            log2_cells: log2.parse().expect("blocked=N with N a number"),
        };
    }
    if has("input") {
        settings.schedule = cgcontact::Schedule::Input;
    }
    // `adaptive-blocked=N`: that schedule for the adaptive body only, the uniform ones in
    // their default one.
    let mut adaptive_settings = settings;
    if let Some(log2) = args
        .iter()
        .find_map(|a| a.strip_prefix("adaptive-blocked="))
    {
        adaptive_settings.schedule = cgcontact::Schedule::Blocked {
            log2_cells: log2.parse().expect("adaptive-blocked=N with N a number"),
        };
    }
    // `big`: the `adaptive` bench's build scene (1.3 M nodes): a third of the base spacing.
    let (h, base) = if has("big") {
        (DVec3::splat(0.25 / 3.0), [60, 120, 60])
    } else {
        (DVec3::splat(0.25), [20, 40, 20])
    };
    let levels: u8 = args
        .iter()
        .find_map(|a| a.strip_prefix("levels="))
        .map_or(2, |n| n.parse().expect("levels=N with N a number"));
    let radius: f64 = args
        .iter()
        .find_map(|a| a.strip_prefix("radius="))
        .map_or(1.5, |r| r.parse().expect("radius=R with R a number"));
    let mut scene = adaptive_block(base, h, levels, radius, points, 7)?;
    if has("stats") {
        eprintln!(
            "{} leaves, {} nodes, {:.1} bytes per node",
            scene.body.cell_count(),
            scene.body.node_count(),
            scene.body.heap_bytes() as f64 / scene.body.node_count() as f64
        );
    }
    scene.body.set_corner_table(has("table"));
    let run = |locator: &dyn Locator, xs: &[DVec3]| {
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let mut out = Vec::with_capacity(xs.len());
        let start = Instant::now();
        for _ in 0..repeats {
            if has("each") {
                out.clear();
                out.extend(xs.iter().map(|&x| locator.locate(x)));
            } else {
                one.install(|| locator.locate_all_into(xs, &mut out));
            }
            std::hint::black_box(&out);
        }
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "{}: {:.2} M points/s",
            if has("uniform") {
                "uniform"
            } else {
                "adaptive"
            },
            (repeats * xs.len()) as f64 / seconds / 1e6
        );
    };
    if has("ratio") {
        let cells = block_cells_for(scene.body.cell_count(), DVec3::new(1.0, 2.0, 1.0));
        let cells = if levels == 0 { base } else { cells };
        let twin = uniform_twin(base, h, cells, &scene)?;
        let adaptive = AdaptiveLocator::new(&scene.body, adaptive_settings)?;
        let uniform = LatticeLocator::new(&twin.body, settings)?;
        let xs: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        let ys: Vec<DVec3> = twin.known.iter().map(|k| k.x).collect();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let mut out = Vec::with_capacity(xs.len());
        let mut pass = |locator: &dyn Locator, xs: &[DVec3]| {
            let start = Instant::now();
            one.install(|| locator.locate_all_into(xs, &mut out));
            std::hint::black_box(&out);
            xs.len() as f64 / start.elapsed().as_secs_f64() / 1e6
        };
        // A warm-up pass each: buffers, caches.
        pass(&adaptive, &xs);
        pass(&uniform, &ys);
        let mut ratios = Vec::new();
        for round in 0..repeats.max(3) {
            let (a, u) = (pass(&adaptive, &xs), pass(&uniform, &ys));
            println!(
                "round {round}: adaptive {a:.2}, twin {u:.2} M points/s: {:.3}",
                a / u
            );
            ratios.push(a / u);
        }
        ratios.sort_by(f64::total_cmp);
        println!(
            "adaptive / twin ({} cells): median {:.3}, from {:.3} to {:.3} over {} rounds",
            twin.body.lattice().cell_count(),
            ratios[ratios.len() / 2],
            ratios[0],
            ratios[ratios.len() - 1],
            ratios.len()
        );
        return Ok(());
    }
    if has("uniform") {
        let cells = block_cells_for(scene.body.cell_count(), DVec3::new(1.0, 2.0, 1.0));
        let size = h * DVec3::new(f64::from(base[0]), f64::from(base[1]), f64::from(base[2]));
        let uniform_h = size
            / DVec3::new(
                f64::from(cells[0]),
                f64::from(cells[1]),
                f64::from(cells[2]),
            );
        if has("twin") {
            // The same problem meshed uniformly (`uniform_twin`).
            let twin = uniform_twin(base, h, cells, &scene)?;
            let xs: Vec<DVec3> = twin.known.iter().map(|k| k.x).collect();
            run(&LatticeLocator::new(&twin.body, settings)?, &xs);
        } else {
            let uniform = indented_block(cells, uniform_h, points, 7)?;
            let xs: Vec<DVec3> = uniform.known.iter().map(|k| k.x).collect();
            run(&LatticeLocator::new(&uniform.body, settings)?, &xs);
        }
    } else {
        let xs: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        run(&AdaptiveLocator::new(&scene.body, adaptive_settings)?, &xs);
    }
    Ok(())
}
