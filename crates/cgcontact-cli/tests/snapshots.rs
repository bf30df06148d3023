//! Snapshot regression suite (insta): every strategy on the committed fixtures, the located cells
//! (input cell numbers, as `cgcontact locate` writes them) and ξ rounded to 1e-9 (f32: 1e-5), plus the
//! summary counts. No timings. See docs/snapshots.md for how to review a change.
//!
//! The answers are computed on pools of 1 and 4 threads and must be identical before they are
//! compared with the snapshot, so a snapshot never depends on the thread count.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, Answer, LatticeLocator, Locator, Settings};
use cgcontact_baseline::{
    BodyRef, BruteForce, CentroidRadius, Inversion, NodeRadius, NodeRadiusOptions, RTree,
};
use cgcontact_io::{CellMap, DisplacementArray, MeshBody, read_body, read_points};
use serde::Serialize;

/// The strategies of `cgcontact locate --strategy ... --precision ...`, by snapshot name.
const STRATEGIES: [&str; 7] = [
    "lattice-f64",
    "lattice-f32",
    "rtree",
    "centroid",
    "noderad",
    "noderad-seed",
    "brute",
];

fn locator<'a>(name: &str, body: BodyRef<'a>) -> Box<dyn Locator + 'a> {
    let f64s = Settings::default();
    let lattice = |settings| -> Box<dyn Locator + 'a> {
        match body {
            BodyRef::Uniform(b) => Box::new(LatticeLocator::new(b, settings).unwrap()),
            BodyRef::Adaptive(b) => Box::new(AdaptiveLocator::new(b, settings).unwrap()),
        }
    };
    match name {
        "lattice-f64" => lattice(f64s),
        "lattice-f32" => lattice(Settings::f32()),
        "rtree" => Box::new(RTree::new(body, f64s).unwrap()),
        "centroid" => Box::new(CentroidRadius::new(body, f64s).unwrap()),
        "noderad" => Box::new(NodeRadius::new(body, f64s).unwrap()),
        "noderad-seed" => Box::new(
            NodeRadius::with_options(
                body,
                f64s,
                NodeRadiusOptions {
                    inversion: Inversion::SeedFaithful,
                    ..Default::default()
                },
            )
            .unwrap(),
        ),
        "brute" => Box::new(BruteForce::new(body, f64s).unwrap()),
        other => unreachable!("unknown strategy {other}"),
    }
}

fn fixture(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(path)
}

/// `x` rounded to `digits` decimals, printed without a negative zero.
fn rounded(x: f64, digits: usize) -> String {
    let scale = 10f64.powi(digits as i32);
    let r = (x * scale).round() / scale + 0.0;
    format!("{r:.digits$}")
}

/// Locate on pools of 1 and 4 threads; the two must agree bitwise.
fn answers(locator: &dyn Locator, points: &[DVec3]) -> Vec<Answer> {
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| locator.locate_all(points))
    };
    let one = run(1);
    assert_eq!(
        run(4),
        one,
        "{}: answers depend on the thread count",
        locator.name()
    );
    one
}

#[derive(Serialize)]
struct Counts {
    points: usize,
    located: usize,
    not_located: usize,
    non_finite: usize,
}

/// One line per point: `point,cell,xi,eta,zeta` (cell −1 when not found, `nan` for refused points).
fn rows(answers: &[Answer], cells: &CellMap, digits: usize, every: usize) -> String {
    let mut out = String::from("point,cell,xi,eta,zeta\n");
    for (point, answer) in answers.iter().enumerate().step_by(every) {
        match answer {
            Ok(Some(hit)) => {
                let cell = cells
                    .input_cell(hit.cell)
                    .expect("a located cell is in the mesh");
                let [a, b, c] = hit.xi.to_array().map(|v| rounded(v, digits));
                writeln!(out, "{point},{cell},{a},{b},{c}").unwrap();
            }
            Ok(None) => writeln!(out, "{point},-1,,,").unwrap(),
            Err(e) => writeln!(out, "{point},error,{e},,").unwrap(),
        }
    }
    out
}

fn counts(answers: &[Answer]) -> Counts {
    let located = answers.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
    let non_finite = answers.iter().filter(|a| a.is_err()).count();
    Counts {
        points: answers.len(),
        located,
        not_located: answers.len() - located - non_finite,
        non_finite,
    }
}

/// FNV-1a of a text: pins every row of a listing too long to commit whole.
fn fnv1a(text: &str) -> String {
    let hash = text.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{hash:016x}")
}

/// Snapshot every strategy on one fixture: counts of all, and rows (every `every`-th point; with a
/// hash of all rows when that is not all of them).
fn snapshot_fixture(name: &str, mesh: &str, points: &[&str], known: &str, every: usize) {
    let known = cgcontact_io::read_results(fixture(known)).unwrap();
    let mesh = read_body(fixture(mesh), &DisplacementArray::Default).unwrap();
    let body: BodyRef<'_> = match &mesh {
        MeshBody::Uniform(m) => (&m.body).into(),
        MeshBody::Adaptive(m) => (&m.body).into(),
    };
    let cells = mesh.cells();
    let mut all_points = Vec::new();
    for p in points {
        all_points.extend(read_points(fixture(p)).unwrap());
    }
    let mut summary = BTreeMap::new();
    for strategy in STRATEGIES {
        let locator = locator(strategy, body);
        let answers = answers(locator.as_ref(), &all_points);
        let digits = if strategy == "lattice-f32" { 5 } else { 9 };
        summary.insert(strategy, counts(&answers));
        // The independent answer: points made from a known (cell, ξ) by the scene generator.
        if matches!(strategy, "lattice-f64" | "rtree" | "brute") {
            for row in &known {
                let hit = answers[row.point].unwrap().expect("a known point is found");
                assert_eq!(
                    cells.input_cell(hit.cell),
                    row.cell,
                    "{strategy}: point {}",
                    row.point
                );
                assert!(
                    (hit.xi - row.xi).abs().max_element() < 1e-9,
                    "{strategy}: point {}",
                    row.point
                );
            }
        }
        let mut listing = rows(&answers, cells, digits, every);
        if every > 1 {
            let full = rows(&answers, cells, digits, 1);
            listing = format!(
                "every {every}th point of {}; FNV-1a of all rows: {}\n{listing}",
                answers.len(),
                fnv1a(&full)
            );
        }
        insta::assert_snapshot!(format!("{name}__{strategy}"), listing);
    }
    insta::assert_yaml_snapshot!(format!("{name}__counts"), summary);
}

#[test]
fn jittered_block_every_strategy() {
    snapshot_fixture(
        "jittered_block",
        "jittered-block/mesh.vtk",
        &[
            "jittered-block/points.csv",
            "jittered-block/extra-points.csv",
        ],
        "jittered-block/known.csv",
        1,
    );
}

#[test]
fn sphere_coarse_every_strategy() {
    snapshot_fixture(
        "sphere_coarse",
        "sphere-coarse/mesh.vtu",
        &["sphere-coarse/points.csv"],
        "sphere-coarse/known.csv",
        25,
    );
}

/// An adaptive mesh: the coarse sphere block refined 2 levels under the sphere without balance
/// (jumps of two levels), cells shuffled.
#[test]
fn sphere_adaptive_every_strategy() {
    snapshot_fixture(
        "sphere_adaptive",
        "sphere-adaptive/mesh.vtu",
        &["sphere-adaptive/points.csv"],
        "sphere-adaptive/known.csv",
        25,
    );
}
