//! `cgcontact tradeoff --quick` still builds its report: both files, a row per configuration and
//! scene, and the default lattice locator exact on every scene. Accuracy columns only: timings are
//! never asserted. The configurations are read from the report's own list (written from
//! `ConfigId`, so their labels are typed once, in `tradeoff/grid.rs`).

use std::process::Command;

/// Columns of the results table (see `tradeoff/report.rs`).
const SCENE: usize = 0;
const CONFIG: usize = 1;
const FOUND: usize = 8;
const WRONG_CELL: usize = 9;
const FALSE_INSIDE: usize = 10;
const MAX_XI: usize = 11;

/// The configuration that must stay exact on every scene; the others are read from the report.
const DEFAULT_LATTICE: &str = "lattice f64 (default)";
/// The scenes, typed here rather than read back: the targets and docs/ name them, so a scene that
/// went missing from the report must fail this test, not shrink it.
const SCENES: [&str; 7] = [
    "fine",
    "fine-jitter",
    "block-small",
    "block-big",
    "sphere",
    "adaptive",
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

    // The configurations as the report lists them ("1. label"), numbered 1, 2, … in order.
    let configs: Vec<&str> = section(&md, "## Configurations")
        .filter_map(|l| {
            let (number, label) = l.split_once(". ")?;
            Some((number.parse::<usize>().ok()?, label))
        })
        .enumerate()
        .map(|(k, (number, label))| {
            assert_eq!(number, k + 1, "numbering of {label}");
            label
        })
        .collect();
    assert!(!configs.is_empty(), "no configuration listed");
    assert!(
        configs.contains(&DEFAULT_LATTICE),
        "{DEFAULT_LATTICE} not listed: {configs:?}"
    );
    let scenes: Vec<&str> = section(&md, "## Scenes")
        .filter(|l| l.starts_with("| ") && !l.starts_with("| scene"))
        .filter_map(|l| l.trim_matches('|').split(" | ").next())
        .map(str::trim)
        .collect();
    assert_eq!(scenes, SCENES, "the scenes table");

    let rows: Vec<Vec<&str>> = section(&md, "## Results")
        .filter(|l| l.starts_with("| ") && !l.starts_with("| scene"))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    for scene in SCENES {
        for config in &configs {
            let n = rows
                .iter()
                .filter(|r| r[SCENE] == scene && r[CONFIG] == *config)
                .count();
            assert_eq!(n, 1, "{config} on {scene}: {n} rows");
        }
    }
    assert_eq!(rows.len(), SCENES.len() * configs.len());
    for row in &rows {
        assert_eq!(row.len(), 14, "a cell holds a stray '|': {row:?}");
    }

    let default_rows: Vec<&Vec<&str>> = rows
        .iter()
        .filter(|r| r[CONFIG] == DEFAULT_LATTICE)
        .collect();
    assert_eq!(default_rows.len(), SCENES.len(), "{DEFAULT_LATTICE} rows");
    for row in default_rows {
        let scene = row[SCENE];
        let (found, should) = row[FOUND].split_once('/').expect("found/should");
        assert_eq!(found, should, "{scene}: misses");
        assert_eq!(row[WRONG_CELL], "0", "{scene}: wrong cells");
        assert_eq!(row[FALSE_INSIDE], "0", "{scene}: false inside");
        let max_xi: f64 = row[MAX_XI].parse().expect("a number");
        assert!(max_xi < 1e-12, "{scene}: max ξ error {max_xi}");
    }

    // The scale section: a row per block size (two with --quick), every answer in its known cell,
    // and its plot.
    let scale: Vec<Vec<&str>> = section(&md, "## Scale")
        .filter(|l| l.starts_with("| ") && !l.starts_with("| cells"))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    assert_eq!(scale.len(), 2, "scale rows: {scale:?}");
    for row in &scale {
        assert_eq!(row.len(), 10, "scale row {row:?}");
        assert_eq!(row[9], "0", "wrong cells in scale row {row:?}");
    }
    let svg = std::fs::read_to_string(dir.path().join("scale.svg")).expect("scale.svg");
    assert!(
        svg.starts_with("<svg") && svg.contains("<polyline"),
        "not a line plot"
    );
}

/// The lines of a section of the report: after its heading, up to the next `## ` heading.
fn section<'a>(md: &'a str, heading: &str) -> impl Iterator<Item = &'a str> {
    md.lines()
        .skip_while(move |l| *l != heading)
        .skip(1)
        .take_while(|l| !l.starts_with("## "))
}
