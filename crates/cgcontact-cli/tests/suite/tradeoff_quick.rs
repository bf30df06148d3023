//! `cgcontact tradeoff --quick` still builds its report: both files, a row per configuration and
//! scene, and the default lattice locator exact on every scene. Accuracy columns only: timings are
//! never asserted. The configurations are read from the report's own list (written from
//! `ConfigId`, so their labels are typed once, in `tradeoff/grid.rs`).

use std::path::Path;
use std::process::{Command, Output};

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
    let output = tradeoff(&["--threads", "2"], dir.path(), None);
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

    // The scale section: a row per block size (two with --quick), every answer in its known cell
    // (the unordered run's through its permutation), and its plot.
    let scale: Vec<Vec<&str>> = section(&md, "## Scale")
        .filter(|l| l.starts_with("| ") && !l.starts_with("| cells"))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    assert_eq!(scale.len(), 2, "scale rows: {scale:?}");
    for row in &scale {
        assert_eq!(row.len(), 12, "scale row {row:?}");
        assert_eq!(row[11], "0", "wrong cells in scale row {row:?}");
    }
    let svg = std::fs::read_to_string(dir.path().join("scale.svg")).expect("scale.svg");
    assert!(
        svg.starts_with("<svg") && svg.contains("<polyline"),
        "not a line plot"
    );
}

/// With `--gslib LOG`, the scale section and its plot carry gslib's points/s from the log (a log
/// of `benches/gslib/run.sh`, here for the quick sizes of 250 and 2,000 cells, and one size the
/// report does not run).
#[test]
fn quick_tradeoff_adds_gslib_from_its_log() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let log = dir.path().join("gslib.log");
    std::fs::write(
        &log,
        "# 2026-11-24T00:00:00Z vm, 2 cores\n\
         ## block 5 x 10 x 5\n\
         gslib cells=250 points=20000 setup_s=0.01 find_s=0.02 points_per_s=1234567 repeats=3\n\
         gslib agree_1e-10=20000 code0=20000 code1_border=0 code2_notfound=0 wrong_cell=0\n\
         gslib cells=2000 points=20000 setup_s=0.02 find_s=0.03 points_per_s=765432.1 repeats=3\n\
         gslib cells=16000 points=20000 setup_s=0.1 find_s=0.9 points_per_s=555555 repeats=3\n",
    )
    .expect("the log is written");
    let out = dir.path().join("report");
    let output = tradeoff(&["--threads", "1"], &out, Some(&log));
    assert!(
        output.status.success(),
        "tradeoff failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let md = std::fs::read_to_string(out.join("tradeoff.md")).expect("tradeoff.md");
    assert!(
        md.contains("2026-11-24T00:00:00Z vm, 2 cores"),
        "the log's header"
    );
    assert!(
        md.contains(&format!("--gslib {}`", log.display())),
        "the command names the log"
    );
    let scale: Vec<Vec<&str>> = section(&md, "## Scale")
        .filter(|l| l.starts_with("| ") && !l.starts_with("| cells"))
        .map(|l| l.trim_matches('|').split(" | ").map(str::trim).collect())
        .collect();
    let gslib: Vec<(&str, &str)> = scale.iter().map(|row| (row[0], row[8])).collect();
    assert_eq!(gslib, [("250", "1.23 M"), ("2000", "0.77 M")], "{scale:?}");
    let svg = std::fs::read_to_string(out.join("scale.svg")).expect("scale.svg");
    assert!(svg.contains("gslib findpts"), "no gslib line in the plot");
}

/// A `--gslib` log that cannot be used is refused before anything is measured or written, with
/// exit code 2 and the file (and line) named.
#[test]
fn tradeoff_refuses_a_bad_gslib_log() {
    let dir = tempfile::tempdir().expect("temporary folder");
    for (text, expected) in [
        ("# a log\nscene [5, 10, 5]: 250 cells\n", "no `gslib cells="),
        (
            "gslib cells=250 points=1 points_per_s=fast\n",
            "gslib.log:1: `points_per_s` is not a rate",
        ),
        (
            "gslib cells=250 points_per_s=1\n\ngslib cells=250 points_per_s=2\n",
            "gslib.log:3: a second gslib run of 250 cells",
        ),
        (
            "gslib cells=-3 points_per_s=1\n",
            "`cells` is not a cell count",
        ),
    ] {
        let log = dir.path().join("gslib.log");
        std::fs::write(&log, text).expect("the log is written");
        let out = dir.path().join("report");
        let output = tradeoff(&[], &out, Some(&log));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{text:?}: {stderr}");
        assert!(stderr.contains(expected), "{text:?}: {stderr}");
        assert!(!out.exists(), "{text:?}: a report was written");
    }
    let missing = dir.path().join("nowhere.log");
    let output = tradeoff(&[], &dir.path().join("report"), Some(&missing));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("nowhere.log"), "{stderr}");
}

/// `cgcontact tradeoff --quick` with `args`, into `out`, with `--gslib` when given.
fn tradeoff(args: &[&str], out: &Path, gslib: Option<&Path>) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_cgcontact"));
    command
        .args(["tradeoff", "--quick"])
        .args(args)
        .arg("--out")
        .arg(out);
    if let Some(log) = gslib {
        command.arg("--gslib").arg(log);
    }
    command.output().expect("the binary runs")
}

/// The lines of a section of the report: after its heading, up to the next `## ` heading.
fn section<'a>(md: &'a str, heading: &str) -> impl Iterator<Item = &'a str> {
    md.lines()
        .skip_while(move |l| *l != heading)
        .skip(1)
        .take_while(|l| !l.starts_with("## "))
}

/// `tradeoff --threads` started as many threads as asked (100,000 tried to start them all),
/// where every other command caps them at 4 per available core: now capped too, with the same
/// warning, and the report still written.
#[test]
fn tradeoff_threads_are_capped_as_elsewhere() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let output = tradeoff(&["--threads", "1000"], dir.path(), None);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("--threads 1000 capped at"), "{stderr}");
    let md = std::fs::read_to_string(dir.path().join("tradeoff.md")).expect("tradeoff.md");
    assert!(
        !md.contains("1000 threads"),
        "the report names the threads asked for"
    );
}

/// Regression: `tradeoff --quick` without `--out` wrote into `docs/`, so that a quick run in the
/// repository replaced the published full report with tiny-scene timings; and `--threads 1`
/// reported "1 threads vs 1: 1.00×" against the 2-thread target. A quick run now writes into
/// `tradeoff-quick/` unless told otherwise, and one thread is said to measure no thread ratio.
#[test]
fn a_quick_run_leaves_docs_alone_and_one_thread_claims_no_ratio() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let docs = dir.path().join("docs");
    std::fs::create_dir(&docs).expect("docs/");
    std::fs::write(docs.join("tradeoff.md"), "the full report\n").expect("a report");
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(["tradeoff", "--quick", "--threads", "1"])
        .current_dir(dir.path())
        .output()
        .expect("the binary runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(docs.join("tradeoff.md")).expect("docs/tradeoff.md"),
        "the full report\n",
        "docs/ untouched"
    );
    assert_eq!(std::fs::read_dir(&docs).expect("docs/").count(), 1);
    let md = std::fs::read_to_string(dir.path().join("tradeoff-quick/tradeoff.md"))
        .expect("tradeoff-quick/tradeoff.md");
    assert!(
        md.contains("tradeoff --quick --threads 1`"),
        "the command as run"
    );
    assert!(!md.contains("threads vs 1"), "a ratio of one thread to one");
    assert!(md.contains("Threads: not measured"), "{md}");
}
