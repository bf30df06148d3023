//! The indented block and its known points as raw binaries for gslib's `findpts` (docs/gslib.md),
//! and, with `--measure`, cgcontact's lattice locator timed on the same scene.
//!
//! Run: `cargo run --release -p cgcontact-benches --example export_block -- NX NY NZ POINTS SEED OUTDIR`
//! or `... -- NX NY NZ POINTS SEED --measure`.
//!
//! The scene is `indented_block([NX, NY, NZ], h, POINTS, SEED)` with h = 5 / NX on every axis (the
//! seed's block is 20 × 40 × 20 cells of 0.25: shape 1 : 2 : 1, 5 × 10 × 5). All files are raw
//! little-endian, `E` elements (the active cells, in cell id order), `P` points:
//!
//! - `nodes.f64`: the deformed corner positions as gslib's `elx[3]` wants them, planar: E × 8
//!   x coordinates, then E × 8 y, then E × 8 z; per element the 8 corners in lexicographic order
//!   (x fastest, then y, then z: corner (a, b, c) ∈ {0, 1}³ at a + 2b + 4c), so gslib's r is our ξ.
//! - `elements.u32`: the cell id of each element (the identity when every cell is active).
//! - `points.f64`: P × (x, y, z) of the known points, interleaved, in their random order.
//! - `cells.u32`: P known cell ids; `xi.f64`: P × (ξ, η, ζ), interleaved.
//! - `meta.txt`: `key value` lines (sizes, spacing, layout).
//!
//! `--measure` writes nothing: it builds `LatticeLocator::new(&body, settings)` for
//! `Schedule::Input` and `Schedule::Auto`, warms up once, and times `locate_all_into` over the
//! points on a one-thread rayon pool, best of 3; it checks the answers against the known cells.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::Instant;

use cgcontact::glam::DVec3;
use cgcontact::{CORNER_OFFSETS, CellId, LatticeLocator, Locator, Schedule, Settings};
use cgcontact_scenes::{KnownPoint, Scene, indented_block};

type Failure = Box<dyn std::error::Error>;

/// Lexicographic corner (x fastest) → VTK corner of `Body::corners`.
fn lexicographic_to_vtk() -> [usize; 8] {
    let mut map = [0usize; 8];
    for (vtk, [a, b, c]) in CORNER_OFFSETS.iter().enumerate() {
        map[(a + 2 * b + 4 * c) as usize] = vtk;
    }
    map
}

fn writer(dir: &Path, name: &str) -> Result<BufWriter<File>, Failure> {
    Ok(BufWriter::with_capacity(
        1 << 20,
        File::create(dir.join(name))?,
    ))
}

fn export(scene: &Scene, h: f64, seed: u64, dir: &Path) -> Result<(), Failure> {
    std::fs::create_dir_all(dir)?;
    let body = &scene.body;
    let elements: Vec<CellId> = body.active_cells().collect();
    let lex = lexicographic_to_vtk();

    let mut out = writer(dir, "nodes.f64")?;
    for axis in 0..3 {
        for &cell in &elements {
            let corners = body.corners(cell).ok_or("an active cell has corners")?;
            for &vtk in &lex {
                out.write_all(&corners[vtk][axis].to_le_bytes())?;
            }
        }
    }
    out.flush()?;

    let mut out = writer(dir, "elements.u32")?;
    for cell in &elements {
        out.write_all(&cell.0.to_le_bytes())?;
    }
    out.flush()?;

    let mut points = writer(dir, "points.f64")?;
    let mut cells = writer(dir, "cells.u32")?;
    let mut xis = writer(dir, "xi.f64")?;
    for k in &scene.known {
        for v in k.x.to_array() {
            points.write_all(&v.to_le_bytes())?;
        }
        cells.write_all(&k.cell.0.to_le_bytes())?;
        for v in k.xi.to_array() {
            xis.write_all(&v.to_le_bytes())?;
        }
    }
    points.flush()?;
    cells.flush()?;
    xis.flush()?;

    let lattice = body.lattice();
    let [nx, ny, nz] = lattice.cells();
    let origin = lattice.origin();
    let mut meta = writer(dir, "meta.txt")?;
    writeln!(meta, "cells {nx} {ny} {nz}")?;
    writeln!(meta, "cell_count {}", lattice.cell_count())?;
    writeln!(meta, "elements {}", elements.len())?;
    writeln!(meta, "nodes_per_element 8")?;
    writeln!(meta, "points {}", scene.known.len())?;
    writeln!(meta, "seed {seed}")?;
    writeln!(meta, "h {h:.17}")?;
    writeln!(meta, "origin {} {} {}", origin.x, origin.y, origin.z)?;
    writeln!(
        meta,
        "nodes_layout planar x[E*8] y[E*8] z[E*8], corners lexicographic x fastest"
    )?;
    writeln!(
        meta,
        "points_layout interleaved xyz; xi interleaved; cells and elements u32"
    )?;
    meta.flush()?;
    Ok(())
}

/// Hits in the known cell with every |ξ − ξ_known| ≤ 1e-10, and misses (no cell or an error).
fn agreement(known: &[KnownPoint], answers: &[cgcontact::Answer]) -> (usize, usize) {
    let mut agree = 0;
    let mut missed = 0;
    for (k, a) in known.iter().zip(answers) {
        match a {
            Ok(Some(hit)) => {
                if hit.cell == k.cell && (hit.xi - k.xi).abs().max_element() <= 1e-10 {
                    agree += 1;
                }
            }
            _ => missed += 1,
        }
    }
    (agree, missed)
}

/// Peak resident set of this process (VmHWM), in MiB, where /proc has it.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn measure(scene: &Scene) -> Result<(), Failure> {
    let xs: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let cells = scene.body.lattice().cell_count();
    for (name, schedule) in [("Input", Schedule::Input), ("Auto", Schedule::Auto)] {
        let settings = Settings {
            schedule,
            ..Settings::default()
        };
        let start = Instant::now();
        let locator = LatticeLocator::new(&scene.body, settings)?;
        let setup = start.elapsed().as_secs_f64();
        let mut out = Vec::with_capacity(xs.len());
        one.install(|| locator.locate_all_into(&xs, &mut out));
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let start = Instant::now();
            one.install(|| locator.locate_all_into(&xs, &mut out));
            std::hint::black_box(&out);
            best = best.min(start.elapsed().as_secs_f64());
        }
        let (agree, missed) = agreement(&scene.known, &out);
        println!(
            "cgcontact schedule={name} cells={cells} points={} setup_s={setup:.4} \
             find_s={best:.4} points_per_s={:.0} agree_1e-10={agree} missed={missed}",
            xs.len(),
            xs.len() as f64 / best,
        );
    }
    if let Some(mib) = peak_rss_mib() {
        println!("cgcontact peak_rss_mib={mib:.1} (whole process, scene generation included)");
    }
    Ok(())
}

fn main() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let measuring = args.iter().any(|a| a == "--measure");
    let positional: Vec<&String> = args.iter().filter(|a| *a != "--measure").collect();
    let usage = "usage: export_block NX NY NZ POINTS SEED (OUTDIR | --measure)";
    if positional.len() != if measuring { 5 } else { 6 } {
        return Err(usage.into());
    }
    let cells: [u32; 3] = [
        positional[0].parse()?,
        positional[1].parse()?,
        positional[2].parse()?,
    ];
    let points: usize = positional[3].parse()?;
    let seed: u64 = positional[4].parse()?;
    let h = 5.0 / f64::from(cells[0]);

    let start = Instant::now();
    let scene = indented_block(cells, DVec3::splat(h), points, seed)?;
    eprintln!(
        "scene {:?}: {} cells ({} active), {} points, h = {h}, built in {:.1} s",
        cells,
        scene.body.lattice().cell_count(),
        scene.body.active_count(),
        scene.known.len(),
        start.elapsed().as_secs_f64()
    );
    if measuring {
        measure(&scene)
    } else {
        let start = Instant::now();
        let dir = Path::new(positional[5].as_str());
        export(&scene, h, seed, dir)?;
        eprintln!(
            "written to {} in {:.1} s",
            dir.display(),
            start.elapsed().as_secs_f64()
        );
        Ok(())
    }
}
