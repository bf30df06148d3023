//! The report's scale section: the lattice locator on indented blocks of the seed's shape from
//! 16,000 to 4.2 M cells, one million known points, one thread, in random order answered as given
//! (`Schedule::Input`) and as the default schedule answers them (`Schedule::Auto`, which sorts by
//! lattice cell on large bodies), and sorted by cell beforehand (under `Schedule::Auto`, which
//! finds them in order and keeps it); f64 and f32; and, f64, random order, under the default
//! schedule by `locate_all_unordered_into` (the answers in the order found, with the
//! permutation). Every answer is checked against its known cell. Writes `scale.svg`: points/s
//! against cells.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use cgcontact::glam::DVec3;
use cgcontact::{Answer, LatticeLocator, Locator, Schedule, Settings};
use cgcontact_io::{TextInput, read_text};
use cgcontact_scenes::indented_block;
use plotters::prelude::*;

use super::measure::{best_time, best_time_of};

/// One measured size.
pub(super) struct ScaleRow {
    cells: usize,
    /// Bytes of f64 displacements.
    bytes: usize,
    /// Points/s, one thread: f64 random as given, random under Auto, lattice order under Auto;
    /// then f32 random as given and under Auto; then f64 random under Auto, unordered.
    pps: [f64; 6],
    /// Answers whose cell is not the known one, over every run.
    wrong: usize,
    points: usize,
}

const LABELS: [&str; 6] = [
    "f64, random order, as given",
    "f64, random order, default schedule",
    "f64, lattice order, default schedule",
    "f32, random order, as given",
    "f32, random order, default schedule",
    "f64, random order, default schedule, unordered",
];

/// gslib's `findpts` on the same blocks and points, one thread, read from a log of
/// `benches/gslib/run.sh` (its own run, not this one): points/s per cell count.
pub(super) struct Gslib {
    /// The log's path and its first comment line (when and where it ran).
    source: String,
    pps: Vec<(usize, f64)>,
}

/// The rates a gslib log may give, in points/s: a normal f64 in this range. `findpts` answers
/// between a few thousand and a few million points/s; the bounds leave orders of magnitude either
/// side but refuse what no run gives (a subnormal rate hung the log axis of `scale.svg`). The
/// `--gslib` help names the range.
const GSLIB_RATE_RANGE: std::ops::RangeInclusive<f64> = 1e-9..=1e15;

/// The longest gslib log read, in bytes: a log of `benches/gslib/run.sh` is a few KB.
const GSLIB_LOG_MAX_BYTES: u64 = 16 << 20;

/// The text of the gslib log at `path`: at most [`GSLIB_LOG_MAX_BYTES`], UTF-8 without NUL bytes,
/// refused from its first bytes otherwise (`/dev/zero` was read until memory ran out), read as
/// cgcontact-io reads its inputs ([`read_text`]). The `--gslib` help names the limits: change it
/// with them.
fn read_log(path: &Path) -> Result<String> {
    let log = TextInput {
        max_bytes: GSLIB_LOG_MAX_BYTES,
        what: "a log of benches/gslib/run.sh",
        over_limit: "not a log of benches/gslib/run.sh (a few KB)",
    };
    let bytes = read_text(path, &log).context("cannot read the gslib log")?;
    String::from_utf8(bytes).map_err(|e| {
        anyhow!(
            "{}: not UTF-8 text (an invalid byte at byte {}), not a log of benches/gslib/run.sh",
            path.display(),
            e.utf8_error().valid_up_to()
        )
    })
}

impl Gslib {
    /// Reads the `gslib cells=N … points_per_s=P …` lines of the log at `path`.
    pub(super) fn read(path: &Path) -> Result<Self> {
        let name = path.display();
        let text = read_log(path)?;
        let mut pps: Vec<(usize, f64)> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            if !line.starts_with("gslib cells=") {
                continue;
            }
            let field = |key: &str| {
                line.split_whitespace()
                    .find_map(|f| f.strip_prefix(key)?.strip_prefix('='))
                    .ok_or_else(|| anyhow!("{name}:{}: no `{key}=` in a gslib line", n + 1))
            };
            let cells: usize = field("cells")?
                .parse()
                .ok()
                .filter(|&c| c > 0)
                .ok_or_else(|| anyhow!("{name}:{}: `cells` is not a cell count", n + 1))?;
            let value = field("points_per_s")?;
            let rate: f64 = value
                .parse()
                .map_err(|_| anyhow!("{name}:{}: `points_per_s` is not a rate", n + 1))?;
            if !(rate.is_normal() && GSLIB_RATE_RANGE.contains(&rate)) {
                bail!(
                    "{name}:{}: `points_per_s={}` is not a rate of points/s in [{:e}, {:e}]",
                    n + 1,
                    value.escape_default(),
                    GSLIB_RATE_RANGE.start(),
                    GSLIB_RATE_RANGE.end()
                );
            }
            if pps.iter().any(|&(c, _)| c == cells) {
                bail!("{name}:{}: a second gslib run of {cells} cells", n + 1);
            }
            pps.push((cells, rate));
        }
        if pps.is_empty() {
            bail!(
                "{name}: no `gslib cells=… points_per_s=…` line: not a log of benches/gslib/run.sh"
            );
        }
        let header = text
            .lines()
            .find_map(|l| l.strip_prefix("# "))
            .unwrap_or("no header line");
        Ok(Self {
            source: format!("`{name}` ({header})"),
            pps,
        })
    }

    /// Points/s on the block of `cells` cells, if the log has it.
    fn at(&self, cells: usize) -> Option<f64> {
        self.pps.iter().find(|&&(c, _)| c == cells).map(|&(_, r)| r)
    }
}

/// Blocks and point counts: tiny ones with `quick`.
fn sizes(quick: bool) -> (Vec<[u32; 3]>, usize) {
    if quick {
        (vec![[5, 10, 5], [10, 20, 10]], 20_000)
    } else {
        (
            vec![[20, 40, 20], [40, 80, 40], [80, 160, 80], [128, 256, 128]],
            1_000_000,
        )
    }
}

/// Measure every size on the one-thread `pool`; `progress` is told each size.
pub(super) fn measure_scale(
    quick: bool,
    pool: &rayon::ThreadPool,
    mut progress: impl FnMut(String),
) -> Result<Vec<ScaleRow>> {
    let (sizes, points) = sizes(quick);
    let budget = Duration::from_millis(if quick { 1 } else { 1_500 });
    let mut rows = Vec::new();
    for cells in sizes {
        progress(format!(
            "scale: {}×{}×{} cells",
            cells[0], cells[1], cells[2]
        ));
        let scene = indented_block(cells, DVec3::splat(5.0 / f64::from(cells[0])), points, 7)?;
        let random: Vec<DVec3> = scene.known.iter().map(|k| k.x).collect();
        let mut by_cell = scene.known.clone();
        by_cell.sort_by_key(|k| k.cell);
        let ordered: Vec<DVec3> = by_cell.iter().map(|k| k.x).collect();
        let mut out: Vec<Answer> = Vec::new();
        let mut order: Vec<usize> = Vec::new();
        let mut wrong = 0;
        let mut pps = [0.0; 6];
        let runs = [
            (Settings::default(), Schedule::Input, false),
            (Settings::default(), Schedule::Auto, false),
            (Settings::default(), Schedule::Auto, true),
            (Settings::f32(), Schedule::Input, false),
            (Settings::f32(), Schedule::Auto, false),
            (Settings::default(), Schedule::Auto, false),
        ];
        for (k, (base, schedule, sorted)) in runs.into_iter().enumerate() {
            let locator = LatticeLocator::new(&scene.body, Settings { schedule, ..base })?;
            let (points, known) = if sorted {
                (&ordered, &by_cell)
            } else {
                (&random, &scene.known)
            };
            let unordered = k == LABELS.len() - 1;
            let seconds = if unordered {
                best_time_of(pool, budget, || {
                    locator.locate_all_unordered_into(points, &mut order, &mut out)
                })
            } else {
                order.clear();
                order.extend(0..points.len());
                best_time(&locator, points, pool, &mut out, budget)
            };
            pps[k] = points.len() as f64 / seconds;
            // Another cell than the known one is right only when it holds the point too (ξ is
            // drawn in the closed cube, and a face is shared): the locator's own owners decide,
            // for the few such points.
            wrong += out
                .iter()
                .zip(order.iter().map(|&i| &known[i]))
                .filter(|(a, k)| match a {
                    Ok(Some(hit)) if hit.cell == k.cell => false,
                    Ok(Some(hit)) => !locator.locate_owners(k.x).is_ok_and(|owners| {
                        owners.iter().any(|o| o.cell == hit.cell)
                            && owners.iter().any(|o| o.cell == k.cell)
                    }),
                    _ => true,
                })
                .count();
        }
        rows.push(ScaleRow {
            cells: scene.body.lattice().cell_count(),
            bytes: size_of_val(scene.body.displacements()),
            pps,
            wrong,
            points,
        });
    }
    Ok(rows)
}

/// The markdown section, with a column for gslib when its log was given.
pub(super) fn scale_section(rows: &[ScaleRow], gslib: Option<&Gslib>) -> String {
    let mut s = String::new();
    let Some(first) = rows.first() else {
        return s;
    };
    let _ = writeln!(
        s,
        "## Scale\n\n\
         The lattice locator (`locate_all_into`, 1 thread) on indented blocks of the seed's shape (1 : 2 : 1, \
         5 × 10 × 5) with {} known points (random cells, random ξ). *As given*: the points answered in \
         their order (`Schedule::Input`); *default schedule*: `Schedule::Auto`, which sorts them by \
         lattice cell above {} MB of nodal data unless a sample of consecutive points shows them \
         already in order; *lattice order*: the same points sorted by cell beforehand, under the \
         default schedule, which keeps their order; *unordered*: `locate_all_unordered_into`, which \
         leaves the answers in the order it found them, beside the permutation, instead of putting \
         them back in input order. *vs smallest*: the default schedule's points/s against the \
         smallest block's (target ≥ 0.7 at 4.2 M cells), by `locate_all_into` and unordered. \
         Every answer is checked against its known cell; *wrong cells* counts answers in another \
         cell that does not hold the point too (over all runs).\n",
        first.points,
        Schedule::AUTO_BYTES >> 20,
    );
    if let Some(gslib) = gslib {
        let _ = writeln!(
            s,
            "*gslib findpts*: gslib's `findpts` on the same blocks and points, one thread, from \
             {}, written by `benches/gslib/run.sh` ([gslib.md](gslib.md)): another run than \
             this report's, so compare orders of magnitude.\n",
            gslib.source
        );
    }
    let _ = write!(s, "| cells | f64 displacements MB |");
    for label in LABELS {
        let _ = write!(s, " {label} pts/s |");
    }
    if gslib.is_some() {
        let _ = write!(s, " gslib findpts pts/s |");
    }
    let _ = writeln!(
        s,
        " vs smallest (f64, default) | vs smallest (f64, unordered) | f32 / f64 (default) | \
         wrong cells |"
    );
    let columns = 6 + LABELS.len() + usize::from(gslib.is_some());
    let _ = writeln!(s, "|{}", "---|".repeat(columns));
    for r in rows {
        let _ = write!(s, "| {} | {:.1} |", r.cells, r.bytes as f64 / 1e6);
        for pps in r.pps {
            let _ = write!(s, " {:.2} M |", pps / 1e6);
        }
        if let Some(gslib) = gslib {
            match gslib.at(r.cells) {
                Some(pps) => {
                    let _ = write!(s, " {:.2} M |", pps / 1e6);
                }
                None => {
                    let _ = write!(s, " not in the log |");
                }
            }
        }
        let _ = writeln!(
            s,
            " {:.2} | {:.2} | {:.2} | {} |",
            r.pps[1] / first.pps[1],
            r.pps[5] / first.pps[1],
            r.pps[4] / r.pps[1],
            r.wrong
        );
    }
    let _ = writeln!(s, "\n![points/s against cells](scale.svg)\n");
    s
}

/// The y range of `scale.svg`, log scale: the normal rates in [`GSLIB_RATE_RANGE`] among `rates`,
/// widened by a factor of 1.5 each side, so never empty, and at most about 24 decades. plotters'
/// log axis never ends on a range that reaches 0 or a subnormal (a gslib rate of 5e-324 hung
/// `tradeoff` in `LogCoord::key_points`) or infinity, so a rate outside is left out of the range
/// (its mark is cut off).
fn log_range(rates: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = rates
        .filter(|r| r.is_normal() && GSLIB_RATE_RANGE.contains(r))
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), r| {
            (lo.min(r), hi.max(r))
        });
    if hi < lo {
        // No rate to show: an axis around 1 M points/s.
        return (1e5, 1e7);
    }
    (lo / 1.5, hi * 1.5)
}

/// Write `scale.svg`: points/s (1 thread) against cells, log–log, one line per column, and one for
/// gslib at the sizes its log has.
pub(super) fn scale_plot(path: &Path, rows: &[ScaleRow], gslib: Option<&Gslib>) -> Result<()> {
    if rows.is_empty() {
        bail!("no size ran");
    }
    let fail = |e: &dyn std::fmt::Display| anyhow!("{}: cannot draw the plot: {e}", path.display());
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (760, 460)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let x_lo = rows.iter().map(|r| r.cells).min().unwrap_or(1) as f64 / 1.5;
        let x_hi = rows.iter().map(|r| r.cells).max().unwrap_or(1) as f64 * 1.5;
        let gslib_line: Vec<(f64, f64)> = gslib.map_or_else(Vec::new, |g| {
            rows.iter()
                .filter_map(|r| Some((r.cells as f64, g.at(r.cells)?)))
                .collect()
        });
        let all = rows
            .iter()
            .flat_map(|r| r.pps)
            .chain(gslib_line.iter().map(|p| p.1));
        let (y_lo, y_hi) = log_range(all);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "lattice locator, 1 thread: points/s against cells",
                ("sans-serif", 16),
            )
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(64)
            .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale())
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("cells")
            .y_desc("points/s")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| fail(&e))?;
        let colours = [
            RGBColor(214, 39, 40),
            RGBColor(31, 119, 180),
            RGBColor(127, 127, 127),
            RGBColor(255, 127, 14),
            RGBColor(44, 160, 44),
            RGBColor(23, 190, 207),
        ];
        for (k, (label, colour)) in LABELS.iter().zip(colours).enumerate() {
            let line: Vec<(f64, f64)> = rows.iter().map(|r| (r.cells as f64, r.pps[k])).collect();
            chart
                .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label(*label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour));
            chart
                .draw_series(line.into_iter().map(|p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| fail(&e))?;
        }
        // gslib's line runs along the bottom, an order of magnitude below the others: the legend
        // goes between, on the right, just below the lowest of ours at the largest size.
        let legend = match rows.last() {
            Some(last) if !gslib_line.is_empty() => {
                let lowest = last.pps.iter().copied().fold(f64::INFINITY, f64::min);
                let (right, top) = chart.backend_coord(&(x_hi, lowest / 1.25));
                SeriesLabelPosition::Coordinate(right - 380, top)
            }
            _ => SeriesLabelPosition::LowerLeft,
        };
        if !gslib_line.is_empty() {
            let colour = RGBColor(148, 103, 189);
            chart
                .draw_series(LineSeries::new(gslib_line.clone(), colour.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label("gslib findpts, f64, random order (its own run)")
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour));
            chart
                .draw_series(
                    gslib_line
                        .into_iter()
                        .map(|p| Circle::new(p, 3, colour.filled())),
                )
                .map_err(|e| fail(&e))?;
        }
        chart
            .configure_series_labels()
            .position(legend)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
    }
    crate::output::write_text(path, &svg)?;
    Ok(())
}
