//! `cgcontact demo`: the seed's sphere-on-block case, built in.

use std::path::PathBuf;

use anyhow::Result;
use cgcontact_io::{CellMap, write_deformed_vtu, write_points_vtu, write_results_counted};
use cgcontact_scenes::SphereOnBlock;
use clap::Args;

use crate::output::{prepare_folder, say};
use crate::picture::contact_patch_svg;
use crate::run::{SearchArgs, Searched, search};

/// The seed's case, no files needed: a 5 × 10 × 5 mm block (h = 0.25 mm) indented by a 1 mm sphere;
/// locate the sphere's 6,700 contact points in the deformed block.
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact demo --out demo-out
  cgcontact demo --strategy noderad-seed --json

Writes to DIR: results.csv (point,cell,xi,eta,zeta,...), block.vtu (the deformed block with the number
of points each cell holds), points.vtu (the contact points with their cell and ξ) for ParaView, and
contact.svg (the top of the block with the located cells shaded and the contact points drawn).")]
pub struct DemoArgs {
    /// Folder for the results, VTK files and picture.
    #[arg(long, value_name = "DIR", default_value = "cgcontact-demo")]
    out: PathBuf,
    /// Use the seed's coarse mesh (h = 0.5 mm) instead of the fine one.
    #[arg(long)]
    coarse: bool,
    #[command(flatten)]
    search: SearchArgs,
}

pub fn run(args: &DemoArgs) -> Result<()> {
    let pool = args.search.check()?;
    prepare_folder("--out", &args.out)?;
    let (knobs, name) = if args.coarse {
        (SphereOnBlock::coarse(), "sphere-coarse")
    } else {
        (SphereOnBlock::fine(), "sphere-fine")
    };
    let scene = SphereOnBlock {
        known_points: 0,
        ..knobs
    }
    .build(name)?;
    let Searched {
        answers,
        tried,
        mut summary,
    } = search(
        (&scene.body).into(),
        &scene.contact_points,
        &args.search,
        &pool,
    )?;

    let dir = &args.out;
    let cells = CellMap::ascending(&scene.body);
    let results = dir.join("results.csv");
    write_results_counted(&results, &answers, &tried, &cells)?;
    let block = dir.join("block.vtu");
    write_deformed_vtu(&block, &scene.body, &cells, &answers, false)?;
    let points = dir.join("points.vtu");
    write_points_vtu(&points, &scene.contact_points, &answers, &cells)?;
    let picture = dir.join("contact.svg");
    contact_patch_svg(&picture, &scene, &answers)?;
    summary.files = [results, block, points, picture]
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    if !args.search.json && !args.search.quiet {
        say!("scene: {name}, the seed's 5 x 10 x 5 mm block indented by a 1 mm sphere")?;
    }
    summary.print(&args.search)
}
