//! `cgcontact demo`: the seed's sphere-on-block case, built in.

use std::path::PathBuf;

use anyhow::Result;
use cgcontact::GapAnswer;
use cgcontact_io::{CellMap, write_deformed_adaptive_vtu, write_deformed_vtu, write_points_vtu};
use cgcontact_scenes::{SphereOnAdaptiveBlock, SphereOnBlock};
use clap::Args;

use crate::locate::measure_gaps;
use crate::output::{check_outputs, prepare_folder, say, write_owner_rows};
use crate::picture::{adaptive_patch_svg, contact_patch_svg};
use crate::run::{SearchArgs, Searched, search};

/// The seed's case, no files needed: a 5 × 10 × 5 mm block (h = 0.25 mm) indented by a 1 mm sphere;
/// locate the sphere's 6,700 contact points in the deformed block.
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact demo --out demo-out
  cgcontact demo --strategy noderad-seed --json
  cgcontact demo --adaptive

Writes to DIR: results.csv (point,cell,xi,eta,zeta,..., then each point's gap to the block's surface
within h: gap,cx,cy,cz,nx,ny,nz,face_cell,face), block.vtu (the deformed block with the number of
points each cell holds), points.vtu (the contact points with their cell and ξ) for ParaView, and
contact.svg (the top of the block with the located cells shaded and the contact points coloured by
gap). The summary reports the sphere's penetration: its most negative gap.
With --adaptive the block is refined by halving under the sphere (2 levels within 1 mm of the contact
patch, 2:1 balanced): block.vtu carries a `level` cell array and the picture outlines each level.")]
pub struct DemoArgs {
    /// Folder for the results, VTK files and picture.
    #[arg(long, value_name = "DIR", default_value = "cgcontact-demo")]
    out: PathBuf,
    /// Use the seed's coarse mesh (h = 0.5 mm) instead of the fine one.
    #[arg(long)]
    coarse: bool,
    /// Refine the block by halving under the sphere (an h-adaptive mesh with hanging nodes).
    #[arg(long)]
    adaptive: bool,
    #[command(flatten)]
    search: SearchArgs,
}

pub fn run(args: &DemoArgs) -> Result<()> {
    let pool = args.search.check()?;
    let _made = prepare_folder("--out", &args.out)?;
    let (knobs, name) = match (args.coarse, args.adaptive) {
        (true, false) => (SphereOnBlock::coarse(), "sphere-coarse"),
        (false, false) => (SphereOnBlock::fine(), "sphere-fine"),
        (true, true) => (SphereOnBlock::coarse(), "sphere-coarse-adaptive"),
        (false, true) => (SphereOnBlock::fine(), "sphere-fine-adaptive"),
    };
    let knobs = SphereOnBlock {
        known_points: 0,
        ..knobs
    };
    let dir = &args.out;
    let (results, block, points, picture) = (
        dir.join("results.csv"),
        dir.join("block.vtu"),
        dir.join("points.vtu"),
        dir.join("contact.svg"),
    );
    // Each file's name free for a file, before the scene is built and searched.
    let files = [&results, &block, &points, &picture].map(|f| ("--out", f.clone()));
    check_outputs(&[], &files)?;
    let mut summary = if args.adaptive {
        let scene = SphereOnAdaptiveBlock::refining(knobs).build(name)?;
        let Searched {
            answers,
            tried,
            summary,
        } = search(
            (&scene.body).into(),
            &scene.contact_points,
            &args.search,
            &pool,
        )?;
        // A leaf's id is its index in the mesh written.
        let cells = CellMap::identity(scene.body.cell_count());
        let distance = scene.body.lattice().h().min_element();
        let (gaps, gap) = measure_gaps(
            (&scene.body).into(),
            &scene.contact_points,
            distance,
            args.search.settings()?,
            &pool,
        );
        let mut summary = summary;
        summary.gap = Some(gap);
        write_rows(&results, &answers, &tried, &cells, &gaps)?;
        write_deformed_adaptive_vtu(&block, &scene.body, &answers)?;
        write_points_vtu(&points, &scene.contact_points, &answers, &cells)?;
        adaptive_patch_svg(&picture, &scene, &answers, &gaps, distance)?;
        summary
    } else {
        let scene = knobs.build(name)?;
        let Searched {
            answers,
            tried,
            summary,
        } = search(
            (&scene.body).into(),
            &scene.contact_points,
            &args.search,
            &pool,
        )?;
        let cells = CellMap::ascending(&scene.body);
        let distance = scene.body.lattice().h().min_element();
        let (gaps, gap) = measure_gaps(
            (&scene.body).into(),
            &scene.contact_points,
            distance,
            args.search.settings()?,
            &pool,
        );
        let mut summary = summary;
        summary.gap = Some(gap);
        write_rows(&results, &answers, &tried, &cells, &gaps)?;
        write_deformed_vtu(&block, &scene.body, &cells, &answers, false)?;
        write_points_vtu(&points, &scene.contact_points, &answers, &cells)?;
        contact_patch_svg(&picture, &scene, &answers, &gaps, distance)?;
        summary
    };
    summary.files = [results, block, points, picture]
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    if !args.search.json && !args.search.quiet {
        say!(
            "scene: {name}, the seed's 5 x 10 x 5 mm block indented by a 1 mm sphere{}",
            if args.adaptive {
                ", refined by halving under it"
            } else {
                ""
            }
        )?;
    }
    summary.print(&args.search)
}

/// The results file, one row per contact point, with its gap columns.
fn write_rows(
    path: &std::path::Path,
    answers: &[cgcontact::Answer],
    tried: &[u32],
    cells: &CellMap,
    gaps: &[GapAnswer],
) -> Result<()> {
    let one = answers.iter().map(|a| match a {
        Ok(Some(hit)) => std::slice::from_ref(hit),
        _ => &[],
    });
    write_owner_rows(path, one, tried, |c| cells.input_cell(c), Some(gaps))?;
    Ok(())
}
