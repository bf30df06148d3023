//! `cgcontact tradeoff`: the accuracy/speed trade over strategies × settings × scenes, measured on
//! this machine; writes a markdown table (`tradeoff.md`) and a plot (`tradeoff.svg`).
//!
//! Every answer is checked against one obtained independently: the known (cell, ξ) of generated
//! points (random ξ in the open cube, so a point on a shared face has probability zero; a differing
//! cell still counts as right when brute force lists it among the owners), or brute force in f64 for
//! the sphere's contact points.

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use cgcontact::glam::DVec3;
use cgcontact::hex8::{Kernel, NewtonOptions};
use cgcontact::{Answer, Body, CandidateOrder, CellId, Locator, Precision, Settings};
use cgcontact_baseline::BruteForce;
use cgcontact_scenes::{SphereOnBlock, indented_block};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use plotters::prelude::*;

use crate::run::{StrategyName, build_locator};

/// Measure the accuracy/speed trade of every strategy and setting on generated scenes.
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact tradeoff                 # the full report into docs/ (about 3 minutes on 2 cores)
  cgcontact tradeoff --quick --out /tmp/report

Writes DIR/tradeoff.md (the table, the machine, the command) and DIR/tradeoff.svg (throughput
against ξ error on the fine-jitter scene, one mark per configuration). A block between the markers
<!-- reading --> and <!-- /reading --> of an existing DIR/tradeoff.md is kept.")]
pub struct TradeoffArgs {
    /// Folder for tradeoff.md and tradeoff.svg.
    #[arg(long, value_name = "DIR", default_value = "docs")]
    out: PathBuf,
    /// Tiny scenes and subsamples: finishes in seconds (CI checks that the report still builds).
    #[arg(long)]
    quick: bool,
    /// Worker threads of the "all threads" column [default: all cores].
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
}

/// O(cells) per point: runs on a subsample of big scenes.
fn is_slow(strategy: StrategyName) -> bool {
    matches!(
        strategy,
        StrategyName::Centroid
            | StrategyName::Noderad
            | StrategyName::NoderadSeed
            | StrategyName::Brute
    )
}

/// Points a slow strategy runs on a scene of `cells` active cells: about the same work (and time)
/// everywhere. Brute force inverts every cell; the filters only scan them.
fn subsample(strategy: StrategyName, cells: usize, quick: bool) -> usize {
    let (cap, work) = match strategy {
        StrategyName::Brute => (2_000, 2.0e7),
        _ => (2_000, 2.5e8),
    };
    let cap = if quick { cap / 10 } else { cap };
    ((work / cells.max(1) as f64) as usize).clamp(50, cap)
}

/// One strategy with its settings.
#[derive(Clone, Debug)]
struct Config {
    label: String,
    strategy: StrategyName,
    settings: Settings,
}

/// The grid of configurations: the lattice locator's settings, then every baseline at defaults.
fn configs() -> Vec<Config> {
    let d = Settings::default();
    let lattice = |label: &str, settings: Settings| Config {
        label: label.to_owned(),
        strategy: StrategyName::Lattice,
        settings,
    };
    let baseline = |label: &str, strategy| Config {
        label: label.to_owned(),
        strategy,
        settings: d,
    };
    vec![
        lattice("lattice f64 (default)", d),
        lattice(
            "lattice f64 tol 1e-6",
            Settings {
                newton_tol: 1e-6,
                ..d
            },
        ),
        lattice(
            "lattice f64 tol 1e-14",
            Settings {
                newton_tol: 1e-14,
                ..d
            },
        ),
        lattice("lattice f64 max_iter 3", Settings { max_iter: 3, ..d }),
        lattice(
            "lattice f64 inside 0",
            Settings {
                inside_tol: 0.0,
                ..d
            },
        ),
        lattice(
            "lattice f64 inside 1e-6",
            Settings {
                inside_tol: 1e-6,
                ..d
            },
        ),
        lattice(
            "lattice f64 undeformed order",
            Settings {
                order: CandidateOrder::Undeformed,
                ..d
            },
        ),
        lattice("lattice f32 (Settings::f32)", Settings::f32()),
        lattice(
            "lattice f32 tol 1e-3",
            Settings {
                newton_tol: 1e-3,
                ..Settings::f32()
            },
        ),
        baseline("rtree f64", StrategyName::Rtree),
        baseline("centroid f64", StrategyName::Centroid),
        baseline("noderad exact f64", StrategyName::Noderad),
        baseline("noderad seed-faithful", StrategyName::NoderadSeed),
        baseline("brute f64", StrategyName::Brute),
    ]
}

/// The settings for the table: precision, Newton tolerance, iteration limit and inside tolerance
/// always, the candidate order only when it is not the default.
fn settings_text(settings: &Settings) -> String {
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

/// The expected answer for one point.
#[derive(Clone, Copy, Debug)]
struct Reference {
    cell: CellId,
    xi: DVec3,
}

/// A scene of the report: a body, its query points and their expected answers (`None`: outside).
struct TradeScene {
    name: &'static str,
    what: String,
    body: Body,
    points: Vec<DVec3>,
    reference: Vec<Option<Reference>>,
}

impl TradeScene {
    fn from_known(name: &'static str, what: String, scene: cgcontact_scenes::Scene) -> Self {
        let points = scene.known.iter().map(|k| k.x).collect();
        let reference = scene
            .known
            .iter()
            .map(|k| {
                Some(Reference {
                    cell: k.cell,
                    xi: k.xi,
                })
            })
            .collect();
        Self {
            name,
            what,
            body: scene.body,
            points,
            reference,
        }
    }
}

/// Build the scenes; the sphere's reference is brute force in f64 on `pool`.
fn scenes(quick: bool, pool: &rayon::ThreadPool) -> Result<Vec<TradeScene>> {
    let h8 = DVec3::splat(0.125);
    let (known, block_points, small, big) = if quick {
        (400, 4_000, [5, 10, 5], [10, 20, 10])
    } else {
        (10_000, 1_000_000, [10, 20, 10], [40, 80, 40])
    };
    let base = if quick {
        SphereOnBlock {
            contact_points: 600,
            ..SphereOnBlock::coarse()
        }
    } else {
        SphereOnBlock::fine()
    };
    let mesh = if quick { "coarse" } else { "fine" };
    let cells = |c: [u32; 3]| c[0] * c[1] * c[2];
    let mut out = vec![
        TradeScene::from_known(
            "fine",
            format!("the seed's {mesh} block, {known} known points"),
            SphereOnBlock {
                contact_points: 0,
                known_points: known,
                ..base.clone()
            }
            .build("fine")?,
        ),
        TradeScene::from_known(
            "fine-jitter",
            format!("{mesh} block + nodal jitter ±0.3 h, {known} known points"),
            SphereOnBlock {
                contact_points: 0,
                known_points: known,
                jitter: 0.3,
                ..base.clone()
            }
            .build("fine-jitter")?,
        ),
        TradeScene::from_known(
            "block-small",
            format!(
                "indented block {}×{}×{} = {} cells (h 0.125), {block_points} known points",
                small[0],
                small[1],
                small[2],
                cells(small)
            ),
            indented_block(small, h8, block_points, 11)?,
        ),
        TradeScene::from_known(
            "block-big",
            format!(
                "indented block {}×{}×{} = {} cells (h 0.125), {block_points} known points",
                big[0],
                big[1],
                big[2],
                cells(big)
            ),
            indented_block(big, h8, block_points, 11)?,
        ),
    ];

    // The sphere's contact points: most lie outside the block; brute force (f64) says which do not.
    let sphere = SphereOnBlock {
        known_points: 0,
        ..base.clone()
    }
    .build("sphere")?;
    let oracle = BruteForce::new(&sphere.body, Settings::default())?;
    let answers = pool.install(|| oracle.locate_all(&sphere.contact_points));
    let reference = answers
        .iter()
        .map(|a| {
            a.map(|hit| {
                hit.map(|h| Reference {
                    cell: h.cell,
                    xi: h.xi,
                })
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow!("sphere point refused by brute force: {e}"))?;
    out.push(TradeScene {
        name: "sphere",
        what: format!(
            "the seed's case: {} sphere contact points on the {mesh} block ({} inside), reference brute force f64",
            sphere.contact_points.len(),
            reference.iter().flatten().count()
        ),
        body: sphere.body,
        points: sphere.contact_points,
        reference,
    });

    // Far from the origin: every coordinate offset by 1e6. Rounding the generated points to f64 at
    // that magnitude moves them by ~1e-10, i.e. ~1e-9 in ξ on 0.25 cells: the reference ξ is the f64
    // inversion of the rounded point in its known cell, in that cell's local frame (exact there).
    let far = SphereOnBlock {
        contact_points: 0,
        known_points: known,
        offset: DVec3::splat(1e6),
        ..base
    }
    .build("far")?;
    let mut far = TradeScene::from_known(
        "far",
        format!(
            "{mesh} block offset by 1e6 in every coordinate, {known} known points (reference ξ: the rounded point re-inverted in f64 in its cell's local frame)"
        ),
        far,
    );
    let tight = NewtonOptions {
        tol: 1e-16,
        max_iter: 50,
        inside_tol: 1e-6,
        ..NewtonOptions::default()
    };
    for (x, reference) in far.points.iter().zip(&mut far.reference) {
        let Some(r) = reference else { continue };
        let Some((map, origin)) = far.body.cell_map(r.cell) else {
            bail!("far scene: known cell {} is not an active cell", r.cell);
        };
        r.xi = map.invert_f64(*x - origin, r.xi, &tight).xi;
    }
    out.push(far);
    Ok(out)
}

/// One row of the table.
#[derive(Clone, Debug)]
struct Row {
    scene: &'static str,
    label: String,
    strategy: StrategyName,
    settings: String,
    cells: usize,
    points_run: usize,
    points_total: usize,
    setup_seconds: f64,
    pps_one: f64,
    pps_all: f64,
    inversions: f64,
    found: usize,
    should: usize,
    wrong_cells: usize,
    wrong_inside: usize,
    max_xi: f64,
    p99_xi: f64,
    max_residual: f64,
}

/// `n` points spread evenly over `0..len` (the sphere's points are ordered by height: a prefix would
/// miss the cap inside the block).
fn strided(len: usize, n: usize) -> Vec<usize> {
    if n >= len {
        return (0..len).collect();
    }
    (0..n).map(|i| i * len / n).collect()
}

/// Best wall time of `locate_all_into` on `pool`, after one untimed warm-up run (first touch of the
/// answers' pages, caches, the pool's threads), repeated at least 3 and at most 5 times while the
/// total stays under `budget`.
fn best_time(
    locator: &dyn Locator,
    points: &[DVec3],
    pool: &rayon::ThreadPool,
    out: &mut Vec<Answer>,
    budget: Duration,
) -> f64 {
    pool.install(|| locator.locate_all_into(points, out));
    let start = Instant::now();
    let mut best = f64::INFINITY;
    for run in 0..5 {
        let t = Instant::now();
        pool.install(|| locator.locate_all_into(points, out));
        best = best.min(t.elapsed().as_secs_f64());
        if run >= 2 && start.elapsed() * 2 > budget {
            break;
        }
    }
    best
}

/// Physical residual |x − x(ξ)| of an answer, recomputed in f64 in the cell's local frame.
fn residual(body: &Body, cell: CellId, xi: DVec3, x: DVec3) -> f64 {
    match body.cell_map(cell) {
        Some((map, origin)) => (x - origin - map.map(xi)).length(),
        None => f64::INFINITY,
    }
}

/// Run one configuration on one scene and check every answer.
fn measure(
    config: &Config,
    scene: &TradeScene,
    pools: (&rayon::ThreadPool, &rayon::ThreadPool),
    quick: bool,
) -> Result<Row> {
    let active = scene.body.active_count();
    let n = if is_slow(config.strategy) {
        subsample(config.strategy, active, quick)
    } else {
        scene.points.len()
    };
    let picked = strided(scene.points.len(), n);
    let points: Vec<DVec3> = picked.iter().map(|&i| scene.points[i]).collect();

    // Ties are judged with the configuration's own definition of inside, in f64: its inside tolerance
    // plus its kernel's rounding allowance (Settings::inside_tolerance), so that a point that close to
    // a neighbour's face belongs to the neighbour too.
    let h_min = scene.body.lattice().h().min_element();
    let u_max = scene.body.max_displacement().max_element();
    let oracle = BruteForce::new(
        &scene.body,
        Settings {
            inside_tol: config.settings.inside_tol
                + 8.0 * (config.settings.epsilon() - f64::EPSILON) * (2.0 + u_max / h_min),
            ..Settings::default()
        },
    )?;
    let setup = Instant::now();
    let locator = build_locator(config.strategy, &scene.body, config.settings)
        .with_context(|| format!("{} on {}", config.label, scene.name))?;
    let setup_seconds = setup.elapsed().as_secs_f64();

    let budget = Duration::from_millis(if quick { 1 } else { 600 });
    let mut answers = Vec::with_capacity(points.len());
    let one = best_time(&*locator, &points, pools.0, &mut answers, budget);
    let all = best_time(&*locator, &points, pools.1, &mut answers, budget);

    let mut row = Row {
        scene: scene.name,
        label: config.label.clone(),
        strategy: config.strategy,
        settings: match config.strategy {
            StrategyName::NoderadSeed => {
                "seed's Newton: from ξ = 0, stop at residual ≤ 0.1, inside ξ ∈ [−1, 1]³".to_owned()
            }
            _ => settings_text(&config.settings),
        },
        cells: active,
        points_run: points.len(),
        points_total: scene.points.len(),
        setup_seconds,
        pps_one: points.len() as f64 / one.max(1e-12),
        pps_all: points.len() as f64 / all.max(1e-12),
        inversions: 0.0,
        found: 0,
        should: 0,
        wrong_cells: 0,
        wrong_inside: 0,
        max_xi: 0.0,
        p99_xi: 0.0,
        max_residual: 0.0,
    };
    let mut errors = Vec::with_capacity(points.len());
    let mut inversions = 0u64;
    let mut hits = 0usize;
    for ((&i, &x), answer) in picked.iter().zip(&points).zip(&answers) {
        let reference = scene.reference[i];
        row.should += usize::from(reference.is_some());
        let hit = match answer {
            Ok(Some(hit)) => hit,
            Ok(None) => continue,
            Err(e) => bail!("{} on {}: point {i} refused: {e}", config.label, scene.name),
        };
        hits += 1;
        inversions += u64::from(hit.inversions);
        row.max_residual = row
            .max_residual
            .max(residual(&scene.body, hit.cell, hit.xi, x));
        let Some(reference) = reference else {
            row.wrong_inside += 1;
            continue;
        };
        row.found += 1;
        let expected = if hit.cell == reference.cell {
            Some(reference.xi)
        } else {
            // A tie (shared face) is right when the oracle lists the cell among the owners.
            oracle
                .locate_owners(x)
                .ok()
                .and_then(|owners| owners.iter().find(|o| o.cell == hit.cell).map(|o| o.xi))
        };
        match expected {
            Some(xi) => errors.push((hit.xi - xi).abs().max_element()),
            None => row.wrong_cells += 1,
        }
    }
    row.inversions = inversions as f64 / hits.max(1) as f64;
    errors.sort_unstable_by(f64::total_cmp);
    if let Some(&max) = errors.last() {
        row.max_xi = max;
        row.p99_xi =
            errors[((errors.len() as f64 * 0.99).ceil() as usize).clamp(1, errors.len()) - 1];
    }
    Ok(row)
}

pub fn run(args: &TradeoffArgs) -> Result<()> {
    let threads = match args.threads {
        Some(0) => bail!("--threads must be at least 1"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .context("cannot start the worker threads")
    };
    let (one, all) = (pool(1)?, pool(threads)?);
    crate::output::prepare_folder("--out", &args.out)?;

    let started = Instant::now();
    let configs = configs();
    let bar = progress_bar();
    bar.set_message("building scenes (brute force for the sphere's reference)");
    let scenes = scenes(args.quick, &all)?;
    bar.set_length((scenes.len() * configs.len()) as u64);
    let mut rows = Vec::new();
    for scene in &scenes {
        for config in &configs {
            bar.set_message(format!("{} / {}", scene.name, config.label));
            rows.push(measure(config, scene, (&one, &all), args.quick)?);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let svg = args.out.join("tradeoff.svg");
    let plotted = plot(&svg, &rows)?;
    let md = args.out.join("tradeoff.md");
    let reading = std::fs::read_to_string(&md)
        .ok()
        .and_then(|text| kept_reading(&text));
    let report = report(
        &rows,
        &scenes,
        threads,
        args,
        started.elapsed(),
        plotted,
        reading,
    );
    crate::output::write_text(&md, &report)?;
    crate::output::say!(
        "{} configurations × {} scenes in {:.1} s; wrote {} and {}",
        configs.len(),
        scenes.len(),
        started.elapsed().as_secs_f64(),
        md.display(),
        svg.display()
    )?;
    Ok(())
}

/// A bar on stderr, only on a terminal.
fn progress_bar() -> ProgressBar {
    let target = if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    };
    let bar = ProgressBar::with_draw_target(None, target);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} runs, {elapsed} {msg}")
            .expect("the template is valid")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

const READING_START: &str = "<!-- reading -->";
const READING_END: &str = "<!-- /reading -->";

/// The hand-written block of an earlier report, markers included.
fn kept_reading(text: &str) -> Option<String> {
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

fn find<'r>(rows: &'r [Row], scene: &str, label: &str) -> Option<&'r Row> {
    rows.iter().find(|r| r.scene == scene && r.label == label)
}

/// Headline figures against the targets of issues 3 and 5, computed from the rows (reported, never
/// asserted: timings on a shared machine move).
fn targets(rows: &[Row], threads: usize) -> String {
    let mut s = String::new();
    let f64_label = "lattice f64 (default)";
    let f32_label = "lattice f32 (Settings::f32)";
    let mut line = |text: String| {
        let _ = writeln!(s, "- {text}");
    };
    if let Some(big) = find(rows, "block-big", f64_label) {
        line(format!(
            "Lattice f64, 1 thread, {} cells / {} points: **{} points/s** (target ≥ 11 M).",
            big.cells,
            big.points_run,
            rate(big.pps_one)
        ));
        line(format!(
            "{threads} threads vs 1: **{:.2}×** (target ≥ 1.8× on 2 threads).",
            big.pps_all / big.pps_one
        ));
        if let Some(f32_row) = find(rows, "block-big", f32_label) {
            line(format!(
                "f32 vs f64, 1 thread: **{:.2}×** ({} points/s; target ≥ 1.5×).",
                f32_row.pps_one / big.pps_one,
                rate(f32_row.pps_one)
            ));
        }
        if let Some(small) = find(rows, "block-small", f64_label) {
            line(format!(
                "Throughput {} cells vs {} cells (1 thread, same point count): **{:.2}×** (target within 1.5×).",
                small.cells,
                big.cells,
                small.pps_one / big.pps_one
            ));
        }
    }
    // Over every scene run, or over one.
    let worst = |label: &str, scene: Option<&str>| {
        rows.iter()
            .filter(|r| r.label == label && scene.is_none_or(|s| r.scene == s))
            .map(|r| r.max_xi)
            .fold(0.0, f64::max)
    };
    line(format!(
        "Lattice f64 max ξ error over every scene: **{}** (target ≤ 1e-12); f32 at offset 1e6: **{}** (target ≤ 1e-5); f32 over every scene: {}.",
        sci(worst(f64_label, None)),
        sci(worst(f32_label, Some("far"))),
        sci(worst(f32_label, None)),
    ));
    if let (Some(lattice), Some(noderad), Some(rtree)) = (
        find(rows, "sphere", f64_label),
        find(rows, "sphere", "noderad exact f64"),
        find(rows, "sphere", "rtree f64"),
    ) {
        let seed = find(rows, "sphere", "noderad seed-faithful");
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

fn report(
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
    if args.out != Path::new("docs") {
        let _ = write!(command, " --out {}", args.out.display());
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
        "| scene | what | active cells | points |\n|---|---|---|---|"
    );
    for scene in scenes {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            scene.name,
            scene.what,
            scene.body.active_count(),
            scene.points.len()
        );
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
            r.label.replace('|', "\\|"),
            r.settings.replace('|', "\\|"),
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

/// Colour of a strategy's marks.
fn colour(strategy: StrategyName, settings: &Settings) -> RGBColor {
    match (strategy, settings.precision) {
        (StrategyName::Lattice, Precision::F64) => RGBColor(31, 119, 180),
        (StrategyName::Lattice, Precision::F32) => RGBColor(44, 160, 44),
        (StrategyName::Rtree, _) => RGBColor(255, 127, 14),
        (StrategyName::Centroid, _) => RGBColor(148, 103, 189),
        (StrategyName::Noderad, _) => RGBColor(214, 39, 40),
        (StrategyName::NoderadSeed, _) => RGBColor(140, 86, 75),
        (StrategyName::Brute, _) => RGBColor(127, 127, 127),
    }
}

/// Share of a row's points answered wrongly: missed (a reference cell, no answer), put in a cell that
/// does not hold them, or put inside when no cell holds them.
fn failure_share(r: &Row) -> f64 {
    let missed = r.should.saturating_sub(r.found);
    (missed + r.wrong_cells + r.wrong_inside) as f64 / r.points_run.max(1) as f64
}

/// Lowest value of each panel's y axis; a value of exactly 0 is drawn there (and labelled `0`).
const FAILURE_FLOOR: f64 = 1e-6;
const XI_FLOOR: f64 = 1e-17;

/// Write the trade plot: one column per scene (small multiples), throughput on 1 thread (x) against
/// the share of points answered wrongly (top row) and the max ξ error of the right answers (bottom
/// row), one numbered mark per configuration, with a shared legend. Returns the number of marks.
///
/// The workspace builds plotters without a font stack (no `ttf`/`ab_glyph`): its text then falls back
/// to a crude size estimate, which the SVG backend accepts (it writes `<text>` elements and leaves the
/// glyphs to the viewer), so captions, tick labels and mark labels do render; positions of labels are
/// approximate, which is why marks are labelled by number with a legend beside the plot.
fn plot(path: &Path, rows: &[Row]) -> Result<usize> {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene) {
            scenes.push(r.scene);
        }
    }
    let width = 300 * scenes.len() as u32 + 330;
    let mut svg = String::new();
    let root = SVGBackend::with_string(&mut svg, (width, 700)).into_drawing_area();
    let plotted = draw_plot(root, path, rows, &scenes)?;
    crate::output::write_text(path, &svg)?;
    Ok(plotted)
}

/// [`plot`]'s drawing, on `root`.
fn draw_plot(
    root: DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    rows: &[Row],
    scenes: &[&str],
) -> Result<usize> {
    if rows.is_empty() {
        bail!("no configuration ran");
    }
    let fail = |e: &dyn std::fmt::Display| anyhow!("{}: cannot draw the plot: {e}", path.display());
    let configs = configs();
    let number = |label: &str| configs.iter().position(|c| c.label == label).unwrap_or(0) + 1;
    let settings_of = |label: &str| {
        configs
            .iter()
            .find(|c| c.label == label)
            .map_or(Settings::default(), |c| c.settings)
    };
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let (plots, legend) = root.split_horizontally(300 * scenes.len() as u32);
    let (title, plots) = plots.split_vertically(40);
    title
        .draw(&Text::new(
            "accuracy/speed trade: points/s on 1 thread (x, log) against the share of points answered \
             wrongly (top) and the max ξ error of the right answers (bottom); lower right is better",
            (10, 12),
            ("sans-serif", 15).into_font(),
        ))
        .map_err(|e| fail(&e))?;
    let panels = plots.split_evenly((2, scenes.len()));
    let decade = |v: f64, up: bool| {
        let e = v.log10();
        10f64.powf(if up { e.ceil() } else { e.floor() })
    };
    type Metric = fn(&Row) -> f64;
    let metrics: [(&str, Metric, f64); 2] = [
        (
            "wrong, missed or falsely inside",
            |r| failure_share(r).max(FAILURE_FLOOR),
            FAILURE_FLOOR,
        ),
        ("max ξ error", |r| r.max_xi.max(XI_FLOOR), XI_FLOOR),
    ];
    let mut plotted = 0;
    for (row, (name, metric, floor)) in metrics.iter().enumerate() {
        for (col, scene) in scenes.iter().enumerate() {
            let marks: Vec<&Row> = rows.iter().filter(|r| r.scene == *scene).collect();
            let x_lo = decade(
                marks
                    .iter()
                    .map(|r| r.pps_one)
                    .fold(f64::INFINITY, f64::min),
                false,
            );
            // Headroom on the right, so that the fastest marks' numbers are not clipped.
            let x_hi = decade(
                marks.iter().map(|r| r.pps_one).fold(0.0, f64::max) * 3.0,
                true,
            );
            let y_lo = *floor;
            let y_hi = if row == 0 {
                1.0
            } else {
                decade(
                    marks.iter().map(|r| metric(r)).fold(0.0, f64::max) * 1.01,
                    true,
                )
                .max(y_lo * 10.0)
            };
            let mut chart = ChartBuilder::on(&panels[row * scenes.len() + col])
                .caption(format!("{scene}: {name}"), ("sans-serif", 14))
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(58)
                .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale())
                .map_err(|e| fail(&e))?;
            let floor = *floor;
            chart
                .configure_mesh()
                .x_labels(4)
                .y_labels(6)
                .y_desc(if row == 0 {
                    "share of points (0 at the bottom)"
                } else {
                    "(0 at the bottom)"
                })
                .x_label_formatter(&|v| format!("{v:.0e}"))
                // The floor stands for exactly 0.
                .y_label_formatter(&|v| {
                    if *v <= floor * 1.0001 {
                        "0".to_owned()
                    } else {
                        format!("{v:.0e}")
                    }
                })
                .draw()
                .map_err(|e| fail(&e))?;
            for (k, r) in marks.iter().enumerate() {
                let c = colour(r.strategy, &settings_of(&r.label));
                let at = (r.pps_one, metric(r));
                chart
                    .draw_series([Circle::new(at, 4, c.filled())])
                    .map_err(|e| fail(&e))?;
                chart
                    // Marks of nearly equal configurations coincide: stagger their numbers.
                    .draw_series([EmptyElement::at(at)
                        + Text::new(
                            format!("{}", number(&r.label)),
                            (6 + 12 * (k % 3) as i32, -4 - 11 * (k % 4) as i32),
                            ("sans-serif", 11).into_font(),
                        )])
                    .map_err(|e| fail(&e))?;
            }
            plotted = plotted.max(marks.len());
        }
    }
    for (k, config) in configs.iter().enumerate() {
        let top = 60 + 22 * k as i32;
        legend
            .draw(&Circle::new(
                (16, top),
                5,
                colour(config.strategy, &config.settings).filled(),
            ))
            .map_err(|e| fail(&e))?;
        legend
            .draw(&Text::new(
                format!("{}  {}", k + 1, config.label),
                (28, top - 7),
                ("sans-serif", 14).into_font(),
            ))
            .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(plotted)
}
