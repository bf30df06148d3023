//! What every command shares: strategy and settings flags, running a search with a progress bar and
//! timing, and the summary (plain or `--json`).

use std::io::IsTerminal;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use cgcontact::glam::DVec3;
use cgcontact::{Answer, Hit, Locator, Precision, Settings};
use cgcontact_baseline::{BodyRef, Strategy};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use serde::Serialize;

use crate::output::say;

/// Search strategy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum StrategyName {
    /// The lattice locator (this project): complete, about one inversion per point.
    Lattice,
    /// FEAVOX's original centroid-radius filter.
    Centroid,
    /// The seed's node-radius filter (`whereami`) with the exact Newton.
    Noderad,
    /// The seed's node-radius filter with the seed's own Newton (0.1 absolute residual).
    NoderadSeed,
    /// An R-tree (rstar) over deformed cell bounding boxes.
    Rtree,
    /// Every cell: the oracle.
    Brute,
}

/// The most worker threads per available core `--threads` starts.
pub const THREADS_PER_CORE: usize = 4;

/// How far f32's rounding of the displacements may move ξ, as a share of a cell ([`f32_rounding`]:
/// 4 ε₃₂ |u − T| / h in an unrotated cell, T the displacements' common translation that the f32
/// kernel takes out), above which `--precision f32` gets a warning: in unrotated cells,
/// displacements about 840 cells away from their common translation (a body rotated or strained
/// over many cells; a rigid translation costs nothing).
const F32_ROUNDING_WARNING: f64 = 4e-4;

/// Newton step tolerances (ξ units) above which `--tol` gets a warning.
const LOOSE_TOL: f64 = 1e-3;

/// Kernel precision.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrecisionName {
    /// Double precision (default).
    F64,
    /// Single precision, SIMD, in each cell's local frame.
    F32,
}

/// Flags shared by the commands that search. Numbers take negative values (`allow_negative_numbers`)
/// so that `--tol -1` is refused naming the flag, not as an unexpected argument `-1`.
#[derive(Args, Debug, Clone)]
pub struct SearchArgs {
    /// Search strategy.
    #[arg(long, value_enum, default_value_t = StrategyName::Lattice)]
    pub strategy: StrategyName,
    /// Kernel precision.
    #[arg(long, value_enum, default_value_t = PrecisionName::F64)]
    pub precision: PrecisionName,
    /// Newton tolerance on the step, in ξ units [default: 1e-10 in f64, 1e-5 in f32].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub tol: Option<f64>,
    /// Newton iteration limit per candidate cell (a run that reaches it runs once more from the
    /// cell's centre, with 16 times the limit where the cell may hold the point).
    #[arg(long, value_name = "N", default_value_t = Settings::MAX_ITER, allow_negative_numbers = true)]
    pub max_iter: u32,
    /// Worker threads [default: all cores].
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// Print one JSON object on stdout instead of the text summary.
    #[arg(long)]
    pub json: bool,
    /// Print nothing but errors (and the JSON object with --json).
    #[arg(long, short)]
    pub quiet: bool,
    /// Time the query N more times after the first (a warm-up), reusing the answer buffer as a
    /// solver loop does, and report the minimum and the median (N at most 1,000,000).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    pub repeat: u32,
}

/// The most `--repeat` takes.
pub const MAX_REPEAT: u32 = 1_000_000;

impl SearchArgs {
    /// Check every flag before any file is read: the settings (an error when out of range, a
    /// warning when `--tol` is loose enough to give wrong answers) and the thread count.
    pub fn check(&self) -> Result<rayon::ThreadPool> {
        self.settings()?;
        if self.repeat > MAX_REPEAT {
            // Each repeat's time is kept for the median: u32::MAX of them asked for 34 GB at
            // once, and the allocation's failure aborted the program.
            bail!(
                "--repeat {}: at most {MAX_REPEAT} (each repeat's time is kept for the median)",
                self.repeat
            );
        }
        if let Some(tol) = self.tol
            && tol > LOOSE_TOL
            && !self.quiet
        {
            // ξ spans 2 across a cell: a step tolerance this large stops Newton before it has found
            // the point, and points near faces land in the wrong cell.
            eprintln!(
                "cgcontact: warning: --tol {tol:?} is a Newton step tolerance in ξ units (a cell spans 2); above {LOOSE_TOL:e} answers can be off by about tol² and points near faces can be put in the wrong cell"
            );
        }
        self.pool()
    }

    /// The library settings these flags ask for.
    pub fn settings(&self) -> Result<Settings> {
        let mut settings = match self.precision {
            PrecisionName::F64 => Settings::default(),
            PrecisionName::F32 => Settings::f32(),
        };
        if let Some(tol) = self.tol {
            settings.newton_tol = tol;
        }
        settings.max_iter = self.max_iter;
        settings.validate().context("bad --tol or --max-iter")?;
        Ok(settings)
    }

    /// A rayon pool with `--threads` workers, at most [`THREADS_PER_CORE`] per available core
    /// (more only adds switching; a warning says so).
    pub fn pool(&self) -> Result<rayon::ThreadPool> {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(n) = self.threads {
            builder = builder.num_threads(capped_threads(n, self.quiet)?);
        }
        build_pool(builder)
    }
}

/// The pool `builder` makes, or an error naming the system's refusal once: rayon's error shows
/// its cause, and gives it as its source too, so a chain of causes said it twice.
pub fn build_pool(builder: rayon::ThreadPoolBuilder) -> Result<rayon::ThreadPool> {
    builder
        .build()
        .map_err(|e| anyhow::anyhow!("cannot start the worker threads: {e}"))
}

/// A `--threads N` count checked (at least 1) and capped at [`THREADS_PER_CORE`] per available
/// core, with a warning unless `quiet`.
pub fn capped_threads(n: usize, quiet: bool) -> Result<usize> {
    if n == 0 {
        bail!("--threads must be at least 1");
    }
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let cap = THREADS_PER_CORE * cores;
    if n <= cap {
        return Ok(n);
    }
    if !quiet {
        eprintln!(
            "cgcontact: warning: --threads {n} capped at {cap} ({THREADS_PER_CORE} per available core, {cores} here)"
        );
    }
    Ok(cap)
}

/// Hanging nodes off their constraint, in `--json`.
#[derive(Serialize, Debug)]
pub struct ConstraintSummary {
    /// Hanging nodes whose displacement is farther than `tolerance` from their constraint.
    pub violating: usize,
    /// The farthest one: its node index in the body's numbering, its undeformed position, and
    /// by how much (largest component, length units).
    pub worst_node: usize,
    pub worst_position: [f64; 3],
    pub worst_offset: f64,
    /// The tolerance per axis (length units).
    pub tolerance: [f64; 3],
}

/// The outcome of a search: answers, timings, and what the summary prints.
#[derive(Serialize, Debug)]
pub struct Summary {
    pub points: usize,
    pub located: usize,
    pub not_located: usize,
    pub invalid_points: usize,
    pub setup_seconds: f64,
    pub query_seconds: f64,
    /// With `--repeat N`: the fastest and the median of the N timed repeats (warm caches, the
    /// answer buffer reused: what a solver loop sees).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub query_seconds_min: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub query_seconds_median: Option<f64>,
    pub points_per_second: f64,
    /// Newton inversions per point, failed ones included (lattice; the baselines count those of
    /// located points only).
    pub inversions_per_point: f64,
    /// Newton inversions per located point (the failed candidates of a located point included).
    pub inversions_per_located_point: f64,
    pub strategy: String,
    pub precision: String,
    pub threads: usize,
    /// Cells of the (base) lattice.
    pub cells: usize,
    /// Cells searched: active cells, or an adaptive body's leaves.
    pub active_cells: usize,
    pub nodes: usize,
    /// An adaptive body's refinement levels (finest level + 1); absent for a uniform body.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub levels: Option<u8>,
    /// An adaptive body's hanging nodes; absent for a uniform body.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hanging_nodes: Option<usize>,
    pub max_displacement: [f64; 3],
    /// With f32 precision: how far f32's rounding of the displacements may move ξ, as a share of
    /// a cell (4 ε₃₂ · |u − T| per axis through each cell's J⁻¹, the largest over the cells:
    /// 4 ε₃₂ · |u − T| / h in unrotated cells); absent with f64.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub f32_rounding: Option<f64>,
    /// Where the displacement came from: the point-data array read, `generated` for a built-in
    /// scene, or null when the mesh file had none (the body is undeformed).
    pub displacement: Option<String>,
    /// Cells whose det J ≤ 0 at a corner (inverted or degenerate): answers in or near them are not
    /// to be trusted. Input cell indices where the caller knows them, else lattice cell ids.
    pub inverted_cells: Vec<usize>,
    /// Cells that f64 coordinates of their magnitude cannot resolve through their deformation
    /// (`Body::unresolved_cells`: a coordinate's rounding moves ξ there by more than a tenth of
    /// the cell): near their faces a point may be given the cell beside it too. Input cell
    /// indices where the caller knows them, else lattice cell ids.
    pub unresolved_cells: Vec<usize>,
    /// The largest such share of a cell (ξ units); absent when no cell is unresolved.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unresolved_share: Option<f64>,
    /// An adaptive mesh read from a file whose hanging nodes break their constraint (what the
    /// warning says, which `--quiet` silences); absent when every one obeys it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hanging_constraints: Option<ConstraintSummary>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
    /// With `locate --all-owners`: what listing every owner found; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub owners: Option<OwnersSummary>,
    /// With `locate --gap D`: the contact quantities found; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gap: Option<GapSummary>,
}

/// What `locate --gap D` found, for the summary.
#[derive(Serialize, Debug, Clone, Copy)]
pub struct GapSummary {
    /// The search distance D.
    pub distance: f64,
    /// Points whose closest surface point is within D.
    pub within: usize,
    /// Of those, points inside the body (negative gap).
    pub inside: usize,
    /// The most negative gap (the deepest penetration), if any point is inside.
    pub penetration: Option<f64>,
    /// Time measuring the gaps of every point.
    pub seconds: f64,
}

/// What `locate --all-owners` found, for the summary.
#[derive(Serialize, Debug, Clone, Copy)]
pub struct OwnersSummary {
    /// Rows of the results: one per owner, one for each point with none.
    pub rows: usize,
    /// Points held by more than one cell (on a shared face, edge or node, or a hanging node).
    pub points_with_several_owners: usize,
    /// The most owners of any point.
    pub most_owners: usize,
    /// Time listing the owners of every point (a second pass, after the timed query).
    pub seconds: f64,
}

impl Summary {
    /// Print the summary: JSON on stdout, or a few lines of text unless quiet.
    pub fn print(&self, args: &SearchArgs) -> Result<()> {
        if args.json {
            say!(
                "{}",
                serde_json::to_string_pretty(self).context("cannot format the summary")?
            )?;
        } else if !args.quiet {
            say!(
                "{} points: {} located, {} not located{}",
                self.points,
                self.located,
                self.not_located,
                if self.invalid_points > 0 {
                    format!(", {} with NaN/inf coordinates", self.invalid_points)
                } else {
                    String::new()
                }
            )?;
            let displacement = match &self.displacement {
                Some(name) => format!(
                    "max displacement {:.4e} ({name})",
                    DVec3::from_array(self.max_displacement).max_element()
                ),
                None => "no displacement array in the mesh: undeformed".to_owned(),
            };
            match (self.levels, self.hanging_nodes) {
                (Some(levels), Some(hanging)) => say!(
                    "body: {} leaf cells on {levels} level{} of a {}-cell base lattice, {} nodes ({hanging} hanging), {displacement}",
                    self.active_cells,
                    if levels == 1 { "" } else { "s" },
                    self.cells,
                    self.nodes,
                )?,
                _ => say!(
                    "body: {} active of {} lattice cells, {} nodes, {displacement}",
                    self.active_cells,
                    self.cells,
                    self.nodes,
                )?,
            }
            say!(
                "{} ({}, {} thread{}): setup {:.3} ms, query {:.3} ms, {:.3e} points/s, {:.3} inversions per point ({:.3} per located point)",
                self.strategy,
                self.precision,
                self.threads,
                if self.threads == 1 { "" } else { "s" },
                self.setup_seconds * 1e3,
                self.query_seconds * 1e3,
                self.points_per_second,
                self.inversions_per_point,
                self.inversions_per_located_point
            )?;
            if let (Some(min), Some(median)) = (self.query_seconds_min, self.query_seconds_median) {
                say!(
                    "repeated {} times: query min {:.3} ms, median {:.3} ms, {:.3e} points/s at the min (the first query also pays for touching a fresh answer buffer)",
                    args.repeat,
                    min * 1e3,
                    median * 1e3,
                    self.points as f64 / min.max(1e-12)
                )?;
            }
            if let Some(owners) = &self.owners {
                say!(
                    "all owners: {} rows for {} points, {} point{} with several owners (up to {}), listed in {:.3} ms",
                    owners.rows,
                    self.points,
                    owners.points_with_several_owners,
                    if owners.points_with_several_owners == 1 {
                        ""
                    } else {
                        "s"
                    },
                    owners.most_owners,
                    owners.seconds * 1e3
                )?;
            }
            if let Some(gap) = &self.gap {
                say!(
                    "gap: {} of {} points within {} of the surface, {} inside{}, measured in {:.3} ms",
                    gap.within,
                    self.points,
                    gap.distance,
                    gap.inside,
                    gap.penetration
                        .map(|p| format!(" (penetration {p:.6e})"))
                        .unwrap_or_default(),
                    gap.seconds * 1e3
                )?;
            }
            for file in &self.files {
                say!("wrote {file}")?;
            }
        }
        if let Some(rounding) = self.f32_rounding.filter(|&r| r > F32_ROUNDING_WARNING)
            && !args.quiet
        {
            eprintln!(
                "cgcontact: warning: f32: the displacements spread so far from their common \
                 translation that f32's rounding of them may move ξ by {rounding:.0e} of a cell: ξ \
                 is good to about that, and a point that close to a face may be put in the cell \
                 beside it (--precision f64 is exact)"
            );
        }
        if let Some(share) = self.unresolved_share
            && !args.quiet
        {
            eprintln!(
                "cgcontact: warning: {} cell(s) are sheared or distorted beyond what f64 \
                 coordinates of their magnitude resolve: a coordinate's rounding moves ξ in them \
                 by up to {share:.2} of a cell (at most {} is resolved), so a point that close to \
                 a face of theirs may be given the cell beside it as well; move the mesh nearer \
                 the origin: {}",
                self.unresolved_cells.len(),
                cgcontact::Lattice::RESOLUTION,
                first_ten(&self.unresolved_cells)
            );
        }
        if !self.inverted_cells.is_empty() && !args.quiet {
            eprintln!(
                "cgcontact: warning: {} inverted or degenerate cell(s) (det J <= 0 at a corner), answers in or near them are not trusted: {}",
                self.inverted_cells.len(),
                first_ten(&self.inverted_cells)
            );
        }
        Ok(())
    }
}

/// Up to ten cell indices, joined by commas, then ", ..." when there are more.
fn first_ten(cells: &[usize]) -> String {
    let first: Vec<String> = cells.iter().take(10).map(usize::to_string).collect();
    let more = if cells.len() > 10 { ", ..." } else { "" };
    format!("{}{more}", first.join(", "))
}

/// The strategy this name stands for.
impl From<StrategyName> for Strategy {
    fn from(name: StrategyName) -> Self {
        match name {
            StrategyName::Lattice => Self::Lattice,
            StrategyName::Centroid => Self::Centroid,
            StrategyName::Noderad => Self::Noderad,
            StrategyName::NoderadSeed => Self::NoderadSeed,
            StrategyName::Rtree => Self::Rtree,
            StrategyName::Brute => Self::Brute,
        }
    }
}

/// The command line's `--strategy` and the tradeoff's configurations build their strategy here
/// ([`Strategy::build`], which the Python module shares).
pub fn build_locator<'a>(
    strategy: StrategyName,
    body: BodyRef<'a>,
    settings: Settings,
) -> Result<Box<dyn Locator + 'a>> {
    Ok(Strategy::from(strategy).build(body, settings)?)
}

/// Build the strategy, locate every point on `pool` with a progress bar (on a terminal, for long
/// work), and time both steps.
pub fn search(
    body: BodyRef<'_>,
    points: &[DVec3],
    args: &SearchArgs,
    pool: &rayon::ThreadPool,
) -> Result<Searched> {
    search_listing_owners(body, points, args, pool, false).map(|(searched, _)| searched)
}

/// [`search`], and with `all_owners` every cell holding each point too (`Locator::locate_owners`,
/// with the same locator, in a second pass after the timed query; its time and counts go to the
/// summary's `owners`).
pub fn search_listing_owners(
    body: BodyRef<'_>,
    points: &[DVec3],
    args: &SearchArgs,
    pool: &rayon::ThreadPool,
    all_owners: bool,
) -> Result<(Searched, Option<OwnerLists>)> {
    let settings = args.settings()?;
    let setup = Instant::now();
    let locator = build_locator(args.strategy, body, settings)?;
    let setup_seconds = setup.elapsed().as_secs_f64();

    // Chunks keep the progress bar moving; each chunk is split over the pool, answers stay in order.
    let chunk = match args.strategy {
        StrategyName::Lattice | StrategyName::Rtree => 1 << 18,
        _ => 1 << 10,
    };
    let progress = progress_bar(points.len() as u64, args.quiet || args.json, "locating");
    let query = Instant::now();
    let mut answers = Vec::with_capacity(points.len());
    let mut buffer = Vec::with_capacity(chunk.min(points.len()));
    pool.install(|| {
        for part in points.chunks(chunk) {
            locator.locate_all_into(part, &mut buffer);
            answers.extend_from_slice(&buffer);
            advance(progress.as_ref(), part.len(), query);
        }
    });
    let query_seconds = query.elapsed().as_secs_f64();
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    // `--repeat N`: the same query again on warm caches, into a reused buffer.
    let total = u64::from(args.repeat).saturating_mul(points.len() as u64);
    let progress = progress_bar(total, args.quiet || args.json, "timing");
    let timing = Instant::now();
    let mut repeats: Vec<f64> = (0..args.repeat)
        .map(|_| {
            let start = Instant::now();
            pool.install(|| locator.locate_all_into(points, &mut buffer));
            let seconds = start.elapsed().as_secs_f64();
            advance(progress.as_ref(), points.len(), timing);
            seconds
        })
        .collect();
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    repeats.sort_unstable_by(f64::total_cmp);
    let (query_seconds_min, query_seconds_median) = match repeats.len() {
        0 => (None, None),
        n => (Some(repeats[0]), Some(repeats[n / 2])),
    };
    let owners = all_owners.then(|| {
        let start = Instant::now();
        let lists = list_owners(&*locator, points, pool, args.quiet || args.json);
        (lists, start.elapsed().as_secs_f64())
    });

    let located: Vec<_> = answers.iter().filter_map(|a| a.ok().flatten()).collect();
    let invalid_points = answers.iter().filter(|a| a.is_err()).count();
    // Counted in a second, untimed pass: the lattice locator counts the inversions of the points it
    // does not find too (the baselines count those of located points only).
    let tried: Vec<u32> = pool.install(|| {
        points
            .par_iter()
            .map(|&x| locator.locate_counted(x).1)
            .collect()
    });
    let inversions: u64 = tried.iter().map(|&t| u64::from(t)).sum();
    let unresolved = body.unresolved_cells();
    let summary = Summary {
        points: points.len(),
        located: located.len(),
        not_located: points.len() - located.len() - invalid_points,
        invalid_points,
        setup_seconds,
        query_seconds,
        query_seconds_min,
        query_seconds_median,
        points_per_second: points.len() as f64 / query_seconds.max(1e-12),
        inversions_per_point: inversions as f64 / points.len().max(1) as f64,
        // A fold from +0: an empty float sum is −0, printed "-0.000".
        inversions_per_located_point: located
            .iter()
            .fold(0.0, |sum, h| sum + f64::from(h.inversions))
            / located.len().max(1) as f64,
        strategy: locator.name().to_owned(),
        precision: match settings.precision {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
        }
        .to_owned(),
        threads: pool.current_num_threads(),
        cells: body.lattice().cell_count(),
        active_cells: body.cell_count(),
        nodes: match body {
            BodyRef::Uniform(b) => b.node_count(),
            BodyRef::Adaptive(b) => b.node_count(),
        },
        levels: match body {
            BodyRef::Uniform(_) => None,
            BodyRef::Adaptive(b) => Some(b.finest_level() + 1),
        },
        hanging_nodes: match body {
            BodyRef::Uniform(_) => None,
            BodyRef::Adaptive(b) => Some(b.hanging_nodes().count()),
        },
        max_displacement: body.max_displacement().to_array(),
        f32_rounding: (settings.precision == Precision::F32).then(|| f32_rounding(body, &settings)),
        displacement: Some("generated".to_owned()),
        inverted_cells: body
            .inverted_cells()
            .iter()
            .map(|(cell, _)| cell.index())
            .collect(),
        unresolved_cells: unresolved.iter().map(|(cell, _)| cell.index()).collect(),
        hanging_constraints: None,
        unresolved_share: unresolved.iter().map(|&(_, share)| share).reduce(f64::max),
        files: Vec::new(),
        owners: owners
            .as_ref()
            .map(|(lists, seconds)| lists.summary(*seconds)),
        gap: None,
    };
    Ok((
        Searched {
            answers,
            tried,
            summary,
        },
        owners.map(|(lists, _)| lists),
    ))
}

/// How far f32's rounding of the displacements may move ξ, as a share of a cell: the kernel
/// rounds each corner's u − T to f32, and every locator allows for 4 ε₃₂ · |u − T| per axis (the
/// frame's reach; `cgcontact::InsideTolerance`'s kernel length), which each cell's J⁻¹ at its
/// centre turns into ξ (`Hex8Map::rounding_share`, halved: ξ spans 2 across a cell); the largest
/// over the cells. A point that close outside a face may be found inside, so ξ is good to about
/// that. Taken through J⁻¹ rather than axis by axis, so that a cell rotated across its anisotropy
/// counts the rounding of a long axis's displacement in its thin one; in an unrotated cell J⁻¹ is
/// diagonal, and it is 4 ε₃₂ |u − T| / h, the largest over the axes.
fn f32_rounding(body: BodyRef<'_>, settings: &Settings) -> f64 {
    let length = 4.0 * f64::from(f32::EPSILON) * body.frame(settings).reach();
    let share = |cell| {
        let map = match body {
            BodyRef::Uniform(b) => b.cell_map(cell),
            BodyRef::Adaptive(b) => b.cell_map(cell),
        };
        // An inverted cell (infinite) is reported as such, not as rounding.
        map.map(|(map, _)| 0.5 * map.rounding_share(length))
            .filter(|s| s.is_finite())
            .unwrap_or(0.0)
    };
    body.cells().map(share).fold(0.0, f64::max)
}

/// Every cell holding each point, point by point in input order: the owners of point p are
/// `hits[ends[p - 1]..ends[p]]` (from 0 for the first point), ascending by the locator's cell id.
/// A point no cell holds, and a point refused (NaN or infinite coordinates), has none.
/// Kept flat: a point costs one offset and its hits, not a list of eight inline.
pub struct OwnerLists {
    pub hits: Vec<Hit>,
    pub ends: Vec<usize>,
}

impl OwnerLists {
    /// The owners of each point, in input order.
    pub fn per_point(&self) -> impl Iterator<Item = &[Hit]> + '_ {
        let starts = std::iter::once(0).chain(self.ends.iter().copied());
        starts
            .zip(self.ends.iter().copied())
            .map(|(start, end)| &self.hits[start..end])
    }

    fn summary(&self, seconds: f64) -> OwnersSummary {
        let counts = || self.per_point().map(<[Hit]>::len);
        OwnersSummary {
            rows: counts().map(|n| n.max(1)).sum(),
            points_with_several_owners: counts().filter(|&n| n > 1).count(),
            most_owners: counts().max().unwrap_or(0),
            seconds,
        }
    }
}

/// [`Locator::locate_owners`] for every point on `pool`, in chunks that keep the progress bar
/// moving; each chunk is split over the pool and its lists are appended in input order, so the
/// result does not depend on the thread count.
fn list_owners(
    locator: &dyn Locator,
    points: &[DVec3],
    pool: &rayon::ThreadPool,
    quiet: bool,
) -> OwnerLists {
    // 4096 points: their lists (eight hits inline each) take about 2 MB before they are flattened.
    const CHUNK: usize = 1 << 12;
    let progress = progress_bar(points.len() as u64, quiet, "listing owners");
    let start = Instant::now();
    let mut lists = OwnerLists {
        hits: Vec::with_capacity(points.len()),
        ends: Vec::with_capacity(points.len()),
    };
    let mut chunk_lists = Vec::with_capacity(CHUNK.min(points.len()));
    pool.install(|| {
        for part in points.chunks(CHUNK) {
            part.par_iter()
                .with_min_len(64)
                // A refused point has no owner: its row is that of a point not found, as with `locate`.
                .map(|&x| locator.locate_owners(x).unwrap_or_default())
                .collect_into_vec(&mut chunk_lists);
            for owners in &chunk_lists {
                lists.hits.extend_from_slice(owners);
                lists.ends.push(lists.hits.len());
            }
            advance(progress.as_ref(), part.len(), start);
        }
    });
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    lists
}

/// What [`search`] found: the answers, the Newton inversions each point's search tried (failed
/// ones included), and the summary.
pub struct Searched {
    pub answers: Vec<Answer>,
    pub tried: Vec<u32>,
    pub summary: Summary,
}

/// `read()`, the reading of the input `path`, with a spinner on stderr (the file's name and size,
/// the time so far) once it has lasted a second: a mesh of a few gigabytes takes a while. Never
/// shown when stderr is not a terminal or the user asked for quiet.
pub fn reading<T>(path: &std::path::Path, quiet: bool, read: impl FnOnce() -> T) -> T {
    if quiet || !std::io::stderr().is_terminal() {
        return read();
    }
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    let what = format!("reading {} ({:.1} MB)", path.display(), size as f64 / 1e6);
    spinning(&what, quiet, read)
}

/// `work()` with a spinner on stderr (`what`, then the time so far) once it has lasted a second.
/// Never shown when stderr is not a terminal or the user asked for quiet.
pub fn spinning<T>(what: &str, quiet: bool, work: impl FnOnce() -> T) -> T {
    if quiet || !std::io::stderr().is_terminal() {
        return work();
    }
    let spinner = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    spinner.set_style(
        ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("the template is valid"),
    );
    spinner.set_message(what.to_owned());
    let (done, finished) = std::sync::mpsc::channel::<()>();
    let value = std::thread::scope(|scope| {
        let shown = spinner.clone();
        scope.spawn(move || {
            // Shown after a second unless the work ended first (its sender dropped).
            if finished.recv_timeout(std::time::Duration::from_secs(1))
                == Err(std::sync::mpsc::RecvTimeoutError::Timeout)
            {
                shown.set_draw_target(ProgressDrawTarget::stderr());
                shown.enable_steady_tick(std::time::Duration::from_millis(120));
            }
        });
        let value = work();
        drop(done);
        value
    });
    spinner.finish_and_clear();
    value
}

/// `points` more done on `bar`, shown once the work begun at `since` has lasted about a second.
fn advance(bar: Option<&ProgressBar>, points: usize, since: Instant) {
    if let Some(bar) = bar {
        bar.inc(points as u64);
        if since.elapsed().as_secs_f64() > 1.0 && bar.is_hidden() {
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    }
}

/// A progress bar on stderr for the step `what` ("locating"), hidden until shown (by the caller,
/// after a second) and never shown when stderr is not a terminal or the user asked for quiet.
fn progress_bar(len: u64, quiet: bool, what: &str) -> Option<ProgressBar> {
    if quiet || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:40}] {pos}/{len} points ({rate}, {eta} left)",
        )
        .expect("the template is valid")
        // Whole points per second: indicatif's own {per_sec} prints four decimals.
        .with_key(
            "rate",
            |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{:.0} points/s", state.per_sec());
            },
        )
        .progress_chars("=> "),
    );
    bar.set_message(what.to_owned());
    Some(bar)
}
