//! `cgcontact tradeoff`: the accuracy/speed trade over strategies × settings × scenes, measured on
//! this machine; writes a markdown table (`tradeoff.md`) and a plot (`tradeoff.svg`).
//!
//! Every answer is checked against one obtained independently: the known (cell, ξ) of generated
//! points (random ξ in the open cube, so a point on a shared face has probability zero; a differing
//! cell still counts as right when brute force lists it among the owners), or brute force in f64 for
//! the sphere's contact points.
//!
//! | module | holds |
//! |---|---|
//! | `grid` | the configurations, one `ConfigId` each |
//! | `scenes` | the scenes and their reference answers |
//! | `measure` | timing and accuracy of one configuration on one scene: a `Row` |
//! | `report` | the markdown |
//! | `plot` | the svg |
//!
//! This module holds the command line, the loop over scenes × configurations and its progress bar.

mod grid;
mod measure;
mod plot;
mod report;
mod scale;
mod scenes;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use grid::configs;
use measure::measure;
use plot::plot;
use report::{kept_reading, report};
use scale::{Gslib, measure_scale, scale_plot, scale_section};
use scenes::scenes;

/// Measure the accuracy/speed trade of every strategy and setting on generated scenes.
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact tradeoff                 # the full report into docs/ (about 4 minutes on 2 cores)
  cgcontact tradeoff --quick         # tiny scenes, into tradeoff-quick/ (never docs/)
  cgcontact tradeoff --gslib benches/gslib/run-2026-11-24.log   # with gslib's line

Writes DIR/tradeoff.md (the table, the machine, the command), DIR/tradeoff.svg (throughput
against ξ error, one mark per configuration) and DIR/scale.svg (points/s against cells, 16,000 to
4.2 M cells, random and lattice order). A block between the markers
<!-- reading --> and <!-- /reading --> of an existing DIR/tradeoff.md is kept.")]
pub struct TradeoffArgs {
    /// Folder for tradeoff.md, tradeoff.svg and scale.svg [default: docs, or tradeoff-quick with
    /// --quick, so that a quick run never replaces the full report].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Tiny scenes and subsamples: finishes in seconds (CI checks that the report still builds).
    #[arg(long)]
    quick: bool,
    /// Worker threads of the "all threads" column [default: all cores].
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    threads: Option<usize>,
    /// A log of benches/gslib/run.sh: adds gslib findpts's points/s on the same blocks to the
    /// scale section and its plot. Refused when it is not UTF-8 text of at most 16 MiB, when a
    /// `points_per_s` is not in [1e-9, 1e15], or when it is one of the files written.
    #[arg(long, value_name = "LOG")]
    gslib: Option<PathBuf>,
}

impl TradeoffArgs {
    /// The folder written: `--out`, else `docs` (the full report) or `tradeoff-quick`.
    fn out(&self) -> PathBuf {
        self.out
            .clone()
            .unwrap_or_else(|| PathBuf::from(Self::default_out(self.quick)))
    }

    /// The folder written without `--out`.
    fn default_out(quick: bool) -> &'static str {
        if quick { "tradeoff-quick" } else { "docs" }
    }
}

pub fn run(args: &TradeoffArgs) -> Result<()> {
    let out = args.out();
    let threads = match args.threads {
        // As for the other commands: more threads than 4 per core only add switching (and
        // `--threads 100000` tried to start them all).
        Some(n) => crate::run::capped_threads(n, false)?,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = |n: usize| crate::run::build_pool(rayon::ThreadPoolBuilder::new().num_threads(n));
    let (one, all) = (pool(1)?, pool(threads)?);
    // Read before the long measurements, so that a bad log fails at once.
    let gslib = args.gslib.as_deref().map(Gslib::read).transpose()?;
    let _made = crate::output::prepare_folder("--out", &out)?;
    // Each file's name free for a file, before minutes of measurements.
    let files = ["tradeoff.md", "tradeoff.svg", "scale.svg"].map(|f| ("--out", out.join(f)));
    // None of them the --gslib log: it was read above, but the report would replace it.
    let inputs: Vec<(&str, &Path)> = args
        .gslib
        .as_deref()
        .map(|log| ("--gslib", log))
        .into_iter()
        .collect();
    crate::output::check_outputs(&inputs, &files)?;

    let started = Instant::now();
    let configs = configs();
    let bar = progress_bar();
    bar.set_message("building scenes (brute force for the sphere's reference)");
    let scenes = scenes(args.quick, &all)?;
    bar.set_length((scenes.len() * configs.len()) as u64);
    let mut rows = Vec::new();
    for scene in &scenes {
        for config in &configs {
            bar.set_message(format!("{} / {}", scene.name, config.id.label()));
            rows.push(measure(config, scene, (&one, &all), args.quick)?);
            bar.inc(1);
        }
    }
    let scale = measure_scale(args.quick, &one, |m| bar.set_message(m))?;
    bar.finish_and_clear();

    scale_plot(&out.join("scale.svg"), &scale, gslib.as_ref())?;
    let svg = out.join("tradeoff.svg");
    let plotted = plot(&svg, &rows)?;
    let md = out.join("tradeoff.md");
    let reading = std::fs::read_to_string(&md)
        .ok()
        .and_then(|text| kept_reading(&text));
    let mut report = report(
        &rows,
        &scenes,
        threads,
        args,
        started.elapsed(),
        plotted,
        reading,
    );
    report.push_str(&scale_section(&scale, gslib.as_ref()));
    crate::output::write_text(&md, &report)?;
    crate::output::say!(
        "{} configurations × {} scenes and {} sizes in {:.1} s; wrote {}, {} and {}",
        configs.len(),
        scenes.len(),
        scale.len(),
        started.elapsed().as_secs_f64(),
        md.display(),
        svg.display(),
        out.join("scale.svg").display()
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
