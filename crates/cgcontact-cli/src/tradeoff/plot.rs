//! The trade plot (`tradeoff.svg`, via plotters): throughput against the share of wrong answers and
//! the ξ error, one column per scene, one numbered mark per configuration.

use std::path::Path;

use anyhow::{Result, anyhow, bail};
use cgcontact::Precision;
use plotters::prelude::*;

use super::grid::{Config, ConfigId, configs};
use super::measure::Row;
use crate::run::StrategyName;

/// Colour of a configuration's marks: one per strategy, the lattice locator's split by precision.
fn colour(config: &Config) -> RGBColor {
    match (config.strategy, config.settings.precision) {
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
pub(super) fn plot(path: &Path, rows: &[Row]) -> Result<usize> {
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
    let number = |id: ConfigId| configs.iter().position(|c| c.id == id).unwrap_or(0) + 1;
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
                let c = colour(&r.config);
                let at = (r.pps_one, metric(r));
                chart
                    .draw_series([Circle::new(at, 4, c.filled())])
                    .map_err(|e| fail(&e))?;
                chart
                    // Marks of nearly equal configurations coincide: stagger their numbers.
                    .draw_series([EmptyElement::at(at)
                        + Text::new(
                            format!("{}", number(r.config.id)),
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
            .draw(&Circle::new((16, top), 5, colour(config).filled()))
            .map_err(|e| fail(&e))?;
        legend
            .draw(&Text::new(
                format!("{}  {}", k + 1, config.id.label()),
                (28, top - 7),
                ("sans-serif", 14).into_font(),
            ))
            .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(plotted)
}
