//! `cgcontact scene`: write a generated scene (mesh, points, known answers).

use std::path::PathBuf;

use anyhow::{Result, bail};

/// The most cells (`block --cells`) and known points (`--known`) a generated scene may have:
/// 2^26, a few GB built in memory. Beyond, the allocation aborted the process.
const MAX_SCENE_SIZE: u64 = 1 << 26;
/// The shortest spacing and the farthest coordinate of a generated scene: the lattice's own
/// spacing range, whose squares (the sphere's distances) and cubes stay normal numbers.
const MIN_LENGTH: f64 = cgcontact::Lattice::MIN_SPACING;
const MAX_LENGTH: f64 = cgcontact::Lattice::MAX_SPACING;
use cgcontact::glam::DVec3;
use cgcontact_io::{CellMap, MeshFormat, write_adaptive_mesh, write_mesh, write_points};
use cgcontact_scenes::{KnownPoint, LeafOrder, SphereOnAdaptiveBlock, SphereOnBlock};

use crate::output::{check_outputs, prepare_folder, say};
use clap::{Args, ValueEnum};

/// Scene names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SceneName {
    /// The seed's fine mesh: 5 × 10 × 5 mm block, h = 0.25 mm, 1 mm sphere, 6,700 contact points.
    SphereFine,
    /// The seed's coarse mesh: the same with h = 0.5 mm.
    SphereCoarse,
    /// An indented block of --cells cells (default 40 × 80 × 40 = 128,000) of spacing --h, known points only.
    Block,
    /// The seed's fine block refined by halving under the sphere: --levels levels (default 2) within
    /// --refine-radius (default the sphere's radius, 1 mm) of the contact patch, 2:1 balanced unless
    /// --unbalanced; the mesh carries a `level` cell array.
    SphereAdaptive,
}

/// Mesh file flavour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatName {
    /// XML `.vtu` (base64 binary).
    Vtu,
    /// Legacy `.vtk`, ASCII.
    Vtk,
    /// Legacy `.vtk`, binary.
    VtkBinary,
}

/// Write a generated scene: `mesh.vtu` (or `.vtk`), `points.csv` (the contact points, then the
/// points made from known (cell, ξ)), and `known.csv` (the known answers of those points).
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact scene sphere-fine --out fine
  cgcontact locate --mesh fine/mesh.vtu --points fine/points.csv --out fine/results.csv
  cgcontact scene block --cells 40,80,40 --known 1000000 --out big

known.csv has the header point,cell,xi,eta,zeta: `point` is the row in points.csv, `cell` the 0-based
cell index in the mesh file, so it compares directly with `cgcontact locate`'s results.")]
pub struct SceneArgs {
    /// Which scene.
    #[arg(value_enum)]
    name: SceneName,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Mesh file flavour.
    #[arg(long, value_enum, default_value_t = FormatName::Vtu)]
    format: FormatName,
    /// Cells per axis of the `block` scene [default: 40,80,40].
    #[arg(
        long,
        value_name = "NX,NY,NZ",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    cells: Option<Vec<u32>>,
    /// Lattice spacing: one value, or three for anisotropic cells [default: the scene's].
    // Negative numbers are taken as values, so that the check below names them.
    #[arg(
        long,
        value_name = "H[,HY,HZ]",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    h: Option<Vec<f64>>,
    /// Largest sink of the indented top face, in units of h (up to several h).
    #[arg(long, value_name = "H", allow_negative_numbers = true)]
    sink: Option<f64>,
    /// Random nodal jitter in units of h (kept to det J > 0 unless --allow-inverted).
    #[arg(
        long,
        value_name = "H",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    jitter: f64,
    /// Keep cells the jitter inverts.
    #[arg(long)]
    allow_inverted: bool,
    /// Offset added to every coordinate (one value for all axes, or three).
    #[arg(
        long,
        value_name = "X[,Y,Z]",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    offset: Option<Vec<f64>>,
    /// Factor on every length.
    #[arg(
        long,
        value_name = "S",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    scale: f64,
    /// Number of points made from known (cell, ξ) [default: 10,000; 1,000,000 for `block`].
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    known: Option<usize>,
    /// Seed of the jitter and the known points.
    #[arg(long, default_value_t = 2019, allow_negative_numbers = true)]
    seed: u64,
    /// `sphere-adaptive`: refinement levels below the base lattice [default: 2].
    #[arg(long, value_name = "L", allow_negative_numbers = true)]
    levels: Option<u8>,
    /// `sphere-adaptive`: cells closer than this to the contact patch's centre are refined
    /// [default: the sphere's radius].
    #[arg(long, value_name = "R", allow_negative_numbers = true)]
    refine_radius: Option<f64>,
    /// `sphere-adaptive`: no 2:1 balance (neighbouring cells may differ by several levels).
    #[arg(long)]
    unbalanced: bool,
    /// `sphere-adaptive`: write the cells in a random order (from --seed) instead of sorted.
    #[arg(long)]
    shuffle: bool,
}

fn vector(values: &[f64], flag: &str) -> Result<DVec3> {
    match values {
        [v] => Ok(DVec3::splat(*v)),
        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
        _ => bail!("--{flag} takes one value or three"),
    }
}

pub fn run(args: &SceneArgs) -> Result<()> {
    let adaptive_only =
        args.levels.is_some() || args.refine_radius.is_some() || args.unbalanced || args.shuffle;
    if adaptive_only && args.name != SceneName::SphereAdaptive {
        bail!(
            "--levels, --refine-radius, --unbalanced and --shuffle apply to `sphere-adaptive` only"
        );
    }
    let mut knobs = match args.name {
        SceneName::SphereFine | SceneName::SphereAdaptive => SphereOnBlock::fine(),
        SceneName::SphereCoarse => SphereOnBlock::coarse(),
        SceneName::Block => {
            let cells = args.cells.as_deref().unwrap_or(&[40, 80, 40]);
            if cells.len() != 3 || cells.contains(&0) {
                bail!("--cells takes three positive counts, e.g. --cells 40,80,40");
            }
            let count: u64 = cells.iter().map(|&n| u64::from(n)).product();
            if count > MAX_SCENE_SIZE {
                bail!(
                    "--cells {} asks for {count} cells; a generated scene holds at most \
                     {MAX_SCENE_SIZE} (the block, its nodes and displacements are built in memory)",
                    cells
                        .iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(",")
                );
            }
            let h = DVec3::splat(0.125);
            let cells = DVec3::new(cells[0] as f64, cells[1] as f64, cells[2] as f64);
            SphereOnBlock {
                block: h * cells,
                h,
                radius: 0.2 * (h * cells).min_element(),
                contact_points: 0,
                known_points: 1_000_000,
                ..SphereOnBlock::fine()
            }
        }
    };
    if args.cells.is_some() && args.name != SceneName::Block {
        bail!("--cells applies to `block` only: the other scenes have the seed's block");
    }
    if let Some(h) = &args.h {
        let h = vector(h, "h")?;
        if !(h.is_finite() && h.min_element() > 0.0) {
            bail!("--h {h} must be finite and positive");
        }
        if args.name == SceneName::Block {
            knobs.block = knobs.block / knobs.h * h;
        }
        knobs.h = h;
    }
    if let Some(sink) = args.sink {
        if !sink.is_finite() {
            bail!("--sink {sink} must be finite");
        }
        knobs.sink_in_h = sink;
    }
    if let Some(offset) = &args.offset {
        knobs.offset = vector(offset, "offset")?;
        // NaN passes the range check below (every comparison with it is false).
        if !knobs.offset.is_finite() {
            bail!("--offset {} must be finite", knobs.offset);
        }
    }
    if let Some(known) = args.known {
        if known as u64 > MAX_SCENE_SIZE {
            bail!(
                "--known {known}: a generated scene holds at most {MAX_SCENE_SIZE} known points \
                 (they are built in memory before they are written)"
            );
        }
        knobs.known_points = known;
    }
    if !(args.jitter.is_finite() && args.jitter >= 0.0) {
        bail!("--jitter {} must be finite and at least 0", args.jitter);
    }
    if !(args.scale.is_finite() && args.scale > 0.0) {
        bail!("--scale {} must be finite and positive", args.scale);
    }
    // Every length of the scene, squared, must stay a normal number: the sphere's distances and
    // the indentation are computed from squares.
    let (h, size) = (knobs.h * args.scale, knobs.block * args.scale);
    let far = (size.abs() + knobs.offset.abs()).max_element();
    if h.min_element() < MIN_LENGTH || far > MAX_LENGTH {
        bail!(
            "the scene's spacing {:e} and farthest coordinate {far:e} (from --h, --scale and \
             --offset) must lie between {MIN_LENGTH:e} and {MAX_LENGTH:e}",
            h.min_element()
        );
    }
    knobs.jitter = args.jitter;
    knobs.allow_inverted = args.allow_inverted;
    knobs.scale = args.scale;
    knobs.seed = args.seed;
    let name = match args.name {
        SceneName::SphereFine => "sphere-fine",
        SceneName::SphereCoarse => "sphere-coarse",
        SceneName::Block => "block",
        SceneName::SphereAdaptive => "sphere-adaptive",
    };
    // Every flag checked before the scene is built or any file written.
    if args.name == SceneName::SphereAdaptive {
        if let Some(r) = args.refine_radius
            && !(r.is_finite() && r >= 0.0)
        {
            bail!("--refine-radius {r} must be finite and at least 0");
        }
        if let Some(levels @ 9..) = args.levels {
            bail!("--levels {levels} is more than 8: the scene would have billions of cells");
        }
    }
    let _made = prepare_folder("--out", &args.out)?;
    let format = match args.format {
        FormatName::Vtu => MeshFormat::Xml,
        FormatName::Vtk => MeshFormat::LegacyAscii,
        FormatName::VtkBinary => MeshFormat::LegacyBinary,
    };
    let mesh = args.out.join(format!("mesh.{}", format.extension()));
    let points = args.out.join("points.csv");
    let known = args.out.join("known.csv");
    // Each file's name free for a file, before the scene is built.
    check_outputs(
        &[],
        &[
            ("--out", mesh.clone()),
            ("--out", points.clone()),
            ("--out", known.clone()),
        ],
    )?;
    let (contact, known_points, summary) = if args.name == SceneName::SphereAdaptive {
        let adaptive = SphereOnAdaptiveBlock {
            levels: args.levels.unwrap_or(2),
            refine_radius: args.refine_radius.unwrap_or(knobs.radius),
            balanced: !args.unbalanced,
            order: if args.shuffle {
                LeafOrder::Shuffled
            } else {
                LeafOrder::Sorted
            },
            ..SphereOnAdaptiveBlock::refining(knobs)
        };
        let scene = adaptive.build(name)?;
        write_adaptive_mesh(&mesh, &scene.body, format)?;
        write_points(&points, &scene.all_points())?;
        let mut per_level = vec![0usize; usize::from(scene.body.finest_level()) + 1];
        for leaf in scene.body.leaves() {
            per_level[usize::from(leaf.level)] += 1;
        }
        let summary = format!(
            "scene {}: {} cells on {} levels ({} per level), {} hanging nodes",
            scene.name,
            scene.body.cell_count(),
            per_level.len(),
            per_level
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join("/"),
            scene.body.hanging_nodes().count(),
        );
        // A leaf's id is its index in the mesh file.
        let known: Vec<(usize, KnownPoint)> =
            scene.known.iter().map(|k| (k.cell.index(), *k)).collect();
        (scene.contact_points.len(), known, summary)
    } else {
        let scene = knobs.build(name)?;
        write_mesh(&mesh, &scene.body, format)?;
        write_points(&points, &scene.all_points())?;
        let cells = CellMap::ascending(&scene.body);
        let known: Vec<(usize, KnownPoint)> = scene
            .known
            .iter()
            .map(|k| {
                (
                    cells
                        .input_cell(k.cell)
                        .expect("known points lie in active cells"),
                    *k,
                )
            })
            .collect();
        let summary = format!(
            "scene {}: {} cells ({} active)",
            scene.name,
            scene.body.lattice().cell_count(),
            scene.body.active_count(),
        );
        (scene.contact_points.len(), known, summary)
    };
    cgcontact_io::write_file(&known, |out| {
        writeln!(out, "point,cell,xi,eta,zeta")?;
        for (row, (cell, k)) in known_points.iter().enumerate() {
            writeln!(
                out,
                "{},{},{},{},{}",
                contact + row,
                cell,
                k.xi.x,
                k.xi.y,
                k.xi.z
            )?;
        }
        Ok(())
    })?;
    say!(
        "{summary}, {contact} contact points, {} known points",
        known_points.len()
    )?;
    for file in [&mesh, &points, &known] {
        say!("wrote {}", file.display())?;
    }
    Ok(())
}
