//! The markdown report: headline figures against the targets, the scenes, the configurations, the
//! table of rows, the machine and the date, and the hand-written reading kept from an earlier report.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use cgcontact::{Precision, Settings};

use super::TradeoffArgs;
use super::grid::{Config, ConfigId, configs};
use super::measure::Row;
use super::scenes::TradeScene;
use crate::run::StrategyName;

/// The settings for the table: precision, Newton tolerance, iteration limit and inside tolerance
/// always, the candidate order only when it is not the default. The seed-faithful mode ignores them
/// and runs the seed's own Newton, so it says that instead.
fn settings_text(config: &Config) -> String {
    if config.strategy == StrategyName::NoderadSeed {
        return "seed's Newton: from ξ = 0, stop at residual ≤ 0.1, inside ξ ∈ [−1, 1]³".to_owned();
    }
    let settings = &config.settings;
    let d = Settings::default();
    format!(
        "{}, tol {:e}, iter {}, inside {:e}{}",
        match settings.precision {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
        },
        settings.newton_tol,
        settings.max_iter,
        settings.inside_tol,
        if settings.order == d.order {
            ""
        } else {
            ", undeformed order"
        }
    )
}

const READING_START: &str = "<!-- reading -->";
const READING_END: &str = "<!-- /reading -->";

/// The hand-written block of an earlier report, markers included.
pub(super) fn kept_reading(text: &str) -> Option<String> {
    let start = text.find(READING_START)?;
    let end = text[start..].find(READING_END)? + start + READING_END.len();
    Some(text[start..end].to_owned())
}

fn machine() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find_map(|l| {
            l.strip_prefix("model name")
                .map(|r| r.trim_start_matches([' ', '\t', ':']))
        })
        .unwrap_or("unknown CPU")
        .trim()
        .to_owned();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{model}, {cores} cores available")
}

/// Days since 1970-01-01 to a civil date (proleptic Gregorian), so no date crate is needed.
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}

fn rate(pps: f64) -> String {
    if pps >= 1e6 {
        format!("{:.2} M", pps / 1e6)
    } else if pps >= 1e3 {
        format!("{:.1} k", pps / 1e3)
    } else {
        format!("{pps:.0}")
    }
}

fn sci(v: f64) -> String {
    if v == 0.0 {
        "0".to_owned()
    } else {
        format!("{v:.1e}")
    }
}

fn find<'r>(rows: &'r [Row], scene: &str, id: ConfigId) -> Option<&'r Row> {
    rows.iter().find(|r| r.scene == scene && r.config.id == id)
}

/// Headline figures against the speed and precision targets, computed from the rows (reported, never
/// asserted: timings on a shared machine move).
fn targets(rows: &[Row], threads: usize) -> String {
    let mut s = String::new();
    let mut line = |text: String| {
        let _ = writeln!(s, "- {text}");
    };
    if let Some(big) = find(rows, "block-big", ConfigId::LatticeDefault) {
        line(format!(
            "Lattice f64, 1 thread, {} cells / {} points: **{} points/s** (target ≥ 11 M).",
            big.cells,
            big.points_run,
            rate(big.pps_one)
        ));
        if threads > 1 {
            line(format!(
                "{threads} threads vs 1: **{:.2}×** (target ≥ 1.8× on 2 threads).",
                big.pps_all / big.pps_one
            ));
        } else {
            line(
                "Threads: not measured, the \"all threads\" column ran on 1 thread \
                 (target ≥ 1.8× on 2 threads; run with --threads 2 or more)."
                    .to_string(),
            );
        }
        if let Some(f32_row) = find(rows, "block-big", ConfigId::LatticeF32) {
            line(format!(
                "f32 vs f64, 1 thread: **{:.2}×** ({} points/s; target ≥ 1.5×).",
                f32_row.pps_one / big.pps_one,
                rate(f32_row.pps_one)
            ));
        }
        if let Some(small) = find(rows, "block-small", ConfigId::LatticeDefault) {
            line(format!(
                "Throughput {} cells vs {} cells (1 thread, same point count): **{:.2}×** (target within 1.5×).",
                small.cells,
                big.cells,
                small.pps_one / big.pps_one
            ));
        }
    }
    // Over every scene run, or over one.
    let worst = |id: ConfigId, scene: Option<&str>| {
        rows.iter()
            .filter(|r| r.config.id == id && scene.is_none_or(|s| r.scene == s))
            .map(|r| r.max_xi)
            .fold(0.0, f64::max)
    };
    line(format!(
        "Lattice f64 max ξ error over every scene: **{}** (target ≤ 1e-12); f32 at offset 1e6: **{}** (target ≤ 1e-5); f32 over every scene: {}.",
        sci(worst(ConfigId::LatticeDefault, None)),
        sci(worst(ConfigId::LatticeF32, Some("far"))),
        sci(worst(ConfigId::LatticeF32, None)),
    ));
    if let (Some(lattice), Some(noderad), Some(rtree)) = (
        find(rows, "sphere", ConfigId::LatticeDefault),
        find(rows, "sphere", ConfigId::NoderadExact),
        find(rows, "sphere", ConfigId::Rtree),
    ) {
        let seed = find(rows, "sphere", ConfigId::NoderadSeed);
        line(format!(
            "Seed's case ({} sphere points): lattice {} points/s vs node-radius exact {} points/s: **{:.0}×** faster{} (target ≥ 1000× at equal or better accuracy: lattice max ξ error {}, {} wrong cells; node-radius exact {}, {} wrong, found {}/{}{}).",
            lattice.points_total,
            rate(lattice.pps_one),
            rate(noderad.pps_one),
            lattice.pps_one / noderad.pps_one,
            seed.map_or(String::new(), |s| format!(
                ", {:.0}× faster than the seed-faithful mode",
                lattice.pps_one / s.pps_one
            )),
            sci(lattice.max_xi),
            lattice.wrong_cells,
            sci(noderad.max_xi),
            noderad.wrong_cells,
            noderad.found,
            noderad.should,
            seed.map_or(String::new(), |s| format!(
                "; seed-faithful: max ξ error {}, {} wrong cells, {} wrongly inside",
                sci(s.max_xi),
                s.wrong_cells,
                s.wrong_inside
            )),
        ));
        line(format!(
            "R-tree beside it: build {:.2} ms, query {} points/s (1 thread); lattice locator build {:.3} ms.",
            rtree.setup_seconds * 1e3,
            rate(rtree.pps_one),
            lattice.setup_seconds * 1e3
        ));
    }
    s
}

pub(super) fn report(
    rows: &[Row],
    scenes: &[TradeScene],
    threads: usize,
    args: &TradeoffArgs,
    elapsed: Duration,
    plotted: usize,
    reading: Option<String>,
) -> String {
    let mut s = String::new();
    let mut command = String::from("cargo run --release -p cgcontact-cli -- tradeoff");
    if args.quick {
        command.push_str(" --quick");
    }
    if args.threads.is_some() {
        let _ = write!(command, " --threads {threads}");
    }
    if let Some(out) = args.out.as_deref()
        && out != Path::new(TradeoffArgs::default_out(args.quick))
    {
        let _ = write!(command, " --out {}", out.display());
    }
    if let Some(log) = &args.gslib {
        let _ = write!(command, " --gslib {}", log.display());
    }
    let _ = writeln!(s, "# The accuracy/speed trade\n");
    let _ = writeln!(
        s,
        "Generated by `{command}` on {} ({}; {threads} threads in the \"all threads\" column) in {:.0} s. \
         Timings are the best of 3 to 5 runs after a warm-up, on a machine shared with other work: read ratios, not digits.\n",
        today(),
        machine(),
        elapsed.as_secs_f64()
    );
    let _ = writeln!(s, "## Targets\n\n{}", targets(rows, threads));
    if let Some(reading) = reading {
        let _ = writeln!(s, "{reading}\n");
    }
    let _ = writeln!(s, "## Scenes\n");
    let _ = writeln!(
        s,
        "| scene | what | cells searched | points |\n|---|---|---|---|"
    );
    for scene in scenes {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            scene.name,
            scene.what,
            scene.body.cell_count(),
            scene.points.len()
        );
    }
    let _ = writeln!(
        s,
        "\n## Configurations\n\n\
         Numbered as in the plot's legend; the results table names them by label.\n"
    );
    for (k, config) in configs().iter().enumerate() {
        let _ = writeln!(s, "{}. {}", k + 1, config.id.label());
    }
    let (newton_tol, max_iter, inside_tol) = (
        Settings::NEWTON_TOL,
        Settings::MAX_ITER,
        Settings::INSIDE_TOL,
    );
    let _ = writeln!(
        s,
        "\n## Columns\n\n\
         - *points*: points run / points in the scene. Brute force, centroid and node-radius cost O(cells) per \
         point and run on an evenly spaced subsample (**marked `sub`**).\n\
         - *setup*: building the locator (the R-tree's bulk load, the node-radius radius; the lattice locator \
         only scans the displacements).\n\
         - *1 thread*, *{threads} threads*: points per second of `locate_all`.\n\
         - *inv/pt*: Newton inversions per located point (failed candidates included).\n\
         - *found*: located / should be located (reference has a cell).\n\
         - *wrong cell*: located in a cell that does not hold the point: not the reference cell, and \
         not among brute force's owners (f64, with the configuration's inside tolerance and rounding \
         allowance, so that a point that close to a shared face may land in either cell).\n\
         - *false inside*: located although the reference says no cell holds the point.\n\
         - *max ξ err*, *p99 ξ err*: |ξ − ξ_ref|∞ over the right-cell answers.\n\
         - *max residual*: |x − x(ξ)| of the answers, recomputed in f64 (length units; h = 0.25 on fine/sphere/far, \
         0.125 on the blocks; coarse 0.5 in --quick).\n\
         \n\
         Settings (`Settings::default()`): f64, Newton tolerance {newton_tol:e} on the step, {max_iter} iterations, \
         inside tolerance {inside_tol:e}, predicted candidate order. Baselines run at the defaults; the seed-faithful mode \
         uses the seed's own Newton (0.1 absolute residual).\n"
    );
    let _ = writeln!(s, "## Results\n");
    let _ = writeln!(
        s,
        "| scene | configuration | settings | points | setup ms | 1 thread pts/s | {threads} threads pts/s | inv/pt | found | wrong cell | false inside | max ξ err | p99 ξ err | max residual |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let sub = if r.points_run < r.points_total {
            " sub"
        } else {
            ""
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {}/{}{sub} | {:.2} | {} | {} | {:.2} | {}/{} | {} | {} | {} | {} | {} |",
            r.scene,
            r.config.id.label().replace('|', "\\|"),
            settings_text(&r.config).replace('|', "\\|"),
            r.points_run,
            r.points_total,
            r.setup_seconds * 1e3,
            rate(r.pps_one),
            rate(r.pps_all),
            r.inversions,
            r.found,
            r.should,
            r.wrong_cells,
            r.wrong_inside,
            sci(r.max_xi),
            sci(r.p99_xi),
            sci(r.max_residual),
        );
    }
    let _ = writeln!(
        s,
        "\n## Plot\n\n![throughput against ξ error](tradeoff.svg)\n\n\
         `tradeoff.svg`: one column per scene, one numbered mark per configuration (up to {plotted} per scene; the legend \
         numbers them): points/s on 1 thread (x, log) against, on top, the share of the points answered wrongly \
         (missed, put in a cell that does not hold them, or put inside when no cell does; log, 0 drawn at the \
         bottom line) and, below, the max ξ error of the right answers (log, 0 drawn at 1e-17). Lower right is \
         better in both rows: a configuration is only as good as its worse row."
    );
    s
}
