//! `tradeoff --gslib LOG` treats the log as an input: never replaced by the report, read within a
//! size limit, and its rates checked before `scale.svg` draws them on a log axis.
//!
//! Each of these once went wrong: the report overwrote a log named as one of its files (exit 0), a
//! rate of 5e-324 hung the plot for ever (plotters' log axis on a range from 0), and `/dev/zero` was
//! read until memory ran out (2.5 GB after 3 s). The runs are timed out here, so that a regression
//! fails instead of hanging the suite or filling memory.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A log of `benches/gslib/run.sh` with the quick sizes (250 and 2,000 cells).
const LOG: &str = "# 2026-11-24T00:00:00Z vm, 2 cores\n\
    ## block 5 x 10 x 5\n\
    gslib cells=250 points=20000 setup_s=0.01 find_s=0.02 points_per_s=1234567 repeats=3\n\
    gslib cells=2000 points=20000 setup_s=0.02 find_s=0.03 points_per_s=765432.1 repeats=3\n";

/// `cgcontact tradeoff --quick --threads 1 --out OUT --gslib LOG`, killed after `limit`: `None`
/// then.
fn tradeoff(out: &Path, log: &Path, limit: Duration) -> Option<Output> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(["tradeoff", "--quick", "--threads", "1", "--out"])
        .arg(out)
        .arg("--gslib")
        .arg(log)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let started = Instant::now();
    while child.try_wait().expect("the child is waited for").is_none() {
        if started.elapsed() > limit {
            child.kill().expect("the child is killed");
            child.wait().expect("the child is waited for");
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Some(child.wait_with_output().expect("the output is read"))
}

/// Exit code 2 within `limit`, one line on stderr holding every one of `names`.
fn refused(out: &Path, log: &Path, limit: Duration, names: &[&str]) {
    let started = Instant::now();
    let Some(output) = tradeoff(out, log, limit) else {
        panic!("{}: still running after {limit:?}", log.display());
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{}: {stderr}", log.display());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    for name in names {
        assert!(stderr.contains(name), "{name} not in: {stderr}");
    }
    eprintln!("{}: refused in {:?}", log.display(), started.elapsed());
}

/// The log named as `tradeoff.md` or `scale.svg` of the report was replaced by it (exit 0): now
/// refused as `locate` refuses an output on its input, the log kept byte for byte.
#[test]
fn a_gslib_log_among_the_reports_files_is_refused_and_kept() {
    let dir = tempfile::tempdir().expect("temporary folder");
    for file in ["tradeoff.md", "scale.svg"] {
        let log = dir.path().join(file);
        std::fs::write(&log, LOG).expect("the log is written");
        refused(
            dir.path(),
            &log,
            Duration::from_secs(120),
            &[
                file,
                "--out would overwrite the input --gslib",
                "(the same file)",
            ],
        );
        assert_eq!(
            std::fs::read_to_string(&log).expect("the log is read"),
            LOG,
            "{file}: the log was replaced"
        );
        std::fs::remove_file(&log).expect("the log is removed");
    }
}

/// A rate of 5e-324 (subnormal) hung `scale.svg`'s log axis for ever; now any rate that is not a
/// normal f64 in [1e-9, 1e15] points/s is refused, with the file, the line and the value, before
/// anything is measured.
#[test]
fn a_gslib_rate_out_of_range_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let out = dir.path().join("report");
    for rate in ["5e-324", "1e-320", "0", "-5", "inf", "NaN", "1e-10", "2e15"] {
        let log = dir.path().join("sub.log");
        std::fs::write(&log, format!("# t\ngslib cells=250 points_per_s={rate}\n"))
            .expect("the log is written");
        refused(
            &out,
            &log,
            Duration::from_secs(60),
            &[
                "sub.log:2:",
                &format!("`points_per_s={rate}`"),
                "[1e-9, 1e15]",
            ],
        );
        assert!(!out.exists(), "{rate}: a report was written");
    }
}

/// The extremes of the range are drawn: the plot's log axis spans them (24 decades) and the run
/// ends.
#[test]
fn gslib_rates_at_the_ends_of_the_range_are_plotted() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let log = dir.path().join("gslib.log");
    std::fs::write(
        &log,
        "# t\ngslib cells=250 points_per_s=1e-9\ngslib cells=2000 points_per_s=1e15\n",
    )
    .expect("the log is written");
    let out = dir.path().join("report");
    let output = tradeoff(&out, &log, Duration::from_secs(120)).expect("the run ends");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let svg = std::fs::read_to_string(out.join("scale.svg")).expect("scale.svg");
    assert!(svg.contains("gslib findpts"), "no gslib line in the plot");
}

/// `/dev/zero` as the log was read until memory ran out; now refused from its first bytes, and a
/// log too large or not UTF-8 likewise, each with the file named.
#[test]
fn a_gslib_log_that_is_not_a_small_text_file_is_refused_at_once() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let out = dir.path().join("report");
    #[cfg(target_os = "linux")]
    refused(
        &out,
        Path::new("/dev/zero"),
        Duration::from_secs(5),
        &["/dev/zero", "a NUL byte at byte 0"],
    );
    // Sparse: 17 MiB reported, nothing written.
    let big = dir.path().join("big.log");
    let file = std::fs::File::create(&big).expect("the log is made");
    file.set_len(17 << 20).expect("the log is sized");
    refused(
        &out,
        &big,
        Duration::from_secs(5),
        &["big.log", "more than 16777216 bytes"],
    );
    let latin1 = dir.path().join("latin1.log");
    std::fs::write(&latin1, b"# caf\xe9\ngslib cells=250 points_per_s=1\n").expect("written");
    refused(
        &out,
        &latin1,
        Duration::from_secs(5),
        &["latin1.log", "not UTF-8"],
    );
    assert!(!out.exists(), "a report was written");
}
