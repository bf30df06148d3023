//! `cgcontact tradeoff --quick` still builds its report: both files, a row per configuration and
//! scene, and the default lattice locator exact on every scene. Accuracy columns only: timings are
//! never asserted.

use std::process::Command;

/// Columns of the results table (see `tradeoff.rs`).
const SCENE: usize = 0;
const CONFIG: usize = 1;
const FOUND: usize = 8;
const WRONG_CELL: usize = 9;
const FALSE_INSIDE: usize = 10;
const MAX_XI: usize = 11;

const CONFIGS: [&str; 14] = [
    "lattice f64 (default)",
    "lattice f64 tol 1e-6",
    "lattice f64 tol 1e-14",
    "lattice f64 max_iter 3",
    "lattice f64 inside 0",
    "lattice f64 inside 1e-6",
    "lattice f64 undeformed order",
    "lattice f32 (Settings::f32)",
    "lattice f32 tol 1e-3",
    "rtree f64",
    "centroid f64",
    "noderad exact f64",
    "noderad seed-faithful",
    "brute f64",
];
const SCENES: [&str; 6] = [
    "fine",
    "fine-jitter",
    "block-small",
    "block-big",
    "sphere",
    "far",
];

#[test]
fn quick_tradeoff_writes_a_row_per_configuration_and_lattice_f64_is_exact() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(["tradeoff", "--quick", "--threads", "2", "--out"])
        .arg(dir.path())
        .output()
        .expect("the binary runs");
    assert!(
        output.status.success(),
        "tradeoff failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let svg = std::fs::read_to_string(dir.path().join("tradeoff.svg")).expect("tradeoff.svg");
    assert!(
        svg.starts_with("<svg") && svg.contains("<circle"),
        "not a plot"
    );
    let md = std::fs::read_to_string(dir.path().join("tradeoff.md")).expect("tradeoff.md");
    assert!(md.contains("--quick"), "the command is named");

    let rows: Vec<Vec<&str>> = md
        .lines()
        .skip_while(|l| !l.starts_with("## Results"))
        .filter(|l| l.starts_with("| ") && !l.starts_with("| scene"))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    for scene in SCENES {
        for config in CONFIGS {
            let n = rows
                .iter()
                .filter(|r| r[SCENE] == scene && r[CONFIG] == config)
                .count();
            assert_eq!(n, 1, "{config} on {scene}: {n} rows");
        }
    }
    assert_eq!(rows.len(), SCENES.len() * CONFIGS.len());
    for row in &rows {
        assert_eq!(row.len(), 14, "a cell holds a stray '|': {row:?}");
    }

    for row in rows.iter().filter(|r| r[CONFIG] == "lattice f64 (default)") {
        let scene = row[SCENE];
        let (found, should) = row[FOUND].split_once('/').expect("found/should");
        assert_eq!(found, should, "{scene}: misses");
        assert_eq!(row[WRONG_CELL], "0", "{scene}: wrong cells");
        assert_eq!(row[FALSE_INSIDE], "0", "{scene}: false inside");
        let max_xi: f64 = row[MAX_XI].parse().expect("a number");
        assert!(max_xi < 1e-12, "{scene}: max ξ error {max_xi}");
    }
}
