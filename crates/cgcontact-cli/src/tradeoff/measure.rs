//! Timing and accuracy of one configuration on one scene: a [`Row`] of the table.

use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use cgcontact::glam::DVec3;
use cgcontact::{Answer, CellId, Locator, Settings};
use cgcontact_baseline::BruteForce;

use super::grid::Config;
use super::scenes::{SceneBody, TradeScene};
use crate::run::{StrategyName, build_locator};

/// One row of the table: what ran (typed; the report writes it out) and what it measured.
#[derive(Clone, Debug)]
pub(super) struct Row {
    pub(super) scene: &'static str,
    pub(super) config: Config,
    pub(super) cells: usize,
    pub(super) points_run: usize,
    pub(super) points_total: usize,
    pub(super) setup_seconds: f64,
    pub(super) pps_one: f64,
    pub(super) pps_all: f64,
    pub(super) inversions: f64,
    pub(super) found: usize,
    pub(super) should: usize,
    pub(super) wrong_cells: usize,
    pub(super) wrong_inside: usize,
    pub(super) max_xi: f64,
    pub(super) p99_xi: f64,
    pub(super) max_residual: f64,
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
pub(super) fn best_time(
    locator: &dyn Locator,
    points: &[DVec3],
    pool: &rayon::ThreadPool,
    out: &mut Vec<Answer>,
    budget: Duration,
) -> f64 {
    best_time_of(pool, budget, || locator.locate_all_into(points, out))
}

/// [`best_time`] of any batch `run`.
pub(super) fn best_time_of(
    pool: &rayon::ThreadPool,
    budget: Duration,
    mut run: impl FnMut() + Send,
) -> f64 {
    pool.install(&mut run);
    let start = Instant::now();
    let mut best = f64::INFINITY;
    for k in 0..5 {
        let t = Instant::now();
        pool.install(&mut run);
        best = best.min(t.elapsed().as_secs_f64());
        if k >= 2 && start.elapsed() * 2 > budget {
            break;
        }
    }
    best
}

/// Physical residual |x − x(ξ)| of an answer, recomputed in f64 in the cell's local frame.
fn residual(body: &SceneBody, cell: CellId, xi: DVec3, x: DVec3) -> f64 {
    match body.cell_map(cell) {
        Some((map, origin)) => (x - origin - map.map(xi)).length(),
        None => f64::INFINITY,
    }
}

/// Run one configuration on one scene and check every answer.
pub(super) fn measure(
    config: &Config,
    scene: &TradeScene,
    pools: (&rayon::ThreadPool, &rayon::ThreadPool),
    quick: bool,
) -> Result<Row> {
    let active = scene.body.cell_count();
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
    let h_min = scene.body.h_min();
    let u_max = scene.body.as_ref().max_displacement().max_element();
    let oracle = BruteForce::new(
        scene.body.as_ref(),
        Settings {
            inside_tol: config.settings.inside_tol
                + 8.0 * (config.settings.epsilon() - f64::EPSILON) * (2.0 + u_max / h_min),
            ..Settings::default()
        },
    )?;
    let setup = Instant::now();
    let locator = build_locator(config.strategy, scene.body.as_ref(), config.settings)
        .with_context(|| format!("{} on {}", config.id.label(), scene.name))?;
    let setup_seconds = setup.elapsed().as_secs_f64();

    let budget = Duration::from_millis(if quick { 1 } else { 600 });
    let mut answers = Vec::with_capacity(points.len());
    let one = best_time(&*locator, &points, pools.0, &mut answers, budget);
    let all = best_time(&*locator, &points, pools.1, &mut answers, budget);

    let mut row = Row {
        scene: scene.name,
        config: *config,
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
            Err(e) => bail!(
                "{} on {}: point {i} refused: {e}",
                config.id.label(),
                scene.name
            ),
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
