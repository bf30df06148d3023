//! `cgcontact scene`: write a generated scene (mesh, points, known answers).

use std::path::PathBuf;

use anyhow::{Result, anyhow, bail};

/// The most cells (of a uniform scene) or leaves (of `sphere-adaptive`) a generated scene may have:
/// 2^23, checked before anything is built. The scene is built in memory before it is written, at
/// about 600 bytes a cell: `block --cells 256,256,128` (2^23 cells, 1 M known points) peaked at
/// 5.1 GB resident, `block --cells 256,256,64` (2^22) at 2.6 GB, `sphere-adaptive --levels 3
/// --refine-radius 100` (8.19 M leaves) at 4.7 GB. Beyond, `sphere-fine --h 0.01` (250 M cells)
/// aborted the process on a failed allocation of 6 GB.
const MAX_SCENE_CELLS: u64 = 1 << 23;
/// The most known points (`--known`) a generated scene may have: 2^24, about 120 bytes each in
/// memory (2^26 of them on `sphere-coarse` peaked at 7.9 GB resident), so about 2 GB.
const MAX_KNOWN_POINTS: u64 = 1 << 24;
/// The most cells along one axis of a generated scene: the scenes library's own limit (it builds
/// no lattice of 10^6 cells or more along an axis). Far below [`cgcontact::Lattice::new`]'s limit
/// (fewer than 2^32 − 1 nodes in all), which [`MAX_SCENE_CELLS`] keeps out of reach.
const MAX_CELLS_PER_AXIS: u32 = 999_999;
/// The shortest spacing and the farthest coordinate of a generated scene: the lattice's own
/// spacing range, whose squares (the sphere's distances) and cubes stay normal numbers.
const MIN_LENGTH: f64 = cgcontact::Lattice::MIN_SPACING;
const MAX_LENGTH: f64 = cgcontact::Lattice::MAX_SPACING;
use cgcontact::glam::DVec3;
use cgcontact::{Error, Lattice};
use cgcontact_io::{CellMap, MeshFormat, write_adaptive_mesh, write_mesh, write_points};
use cgcontact_scenes::{KnownPoint, LeafCount, LeafOrder, SphereOnAdaptiveBlock, SphereOnBlock};

use crate::output::{check_outputs, prepare_folder, say};
use crate::run::spinning;
use clap::{Args, ValueEnum};

/// Scene names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SceneName {
    /// The seed's fine mesh: 5 × 10 × 5 mm block, h = 0.25 mm, 1 mm sphere, 6,700 contact points.
    SphereFine,
    /// The seed's coarse mesh: the same with h = 0.5 mm.
    SphereCoarse,
    /// An indented block of --cells cells (default 40 × 80 × 40 = 128,000) of spacing --h (default
    /// 0.125), known points only.
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
    /// Cells per axis of the `block` scene [default: 40,80,40]; at most 8,388,608 (2^23) in all,
    /// as for every scene (cells, or `sphere-adaptive`'s leaves), and 999,999 along an axis.
    #[arg(
        long,
        value_name = "NX,NY,NZ",
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_parser = count
    )]
    cells: Option<Vec<u32>>,
    /// Lattice spacing: one value, or three for anisotropic cells [default: the scene's].
    // Negative numbers, and lists that start with one ("-1,2,3", which `allow_negative_numbers`
    // does not take), are taken as values, so that the check below names them.
    #[arg(
        long,
        value_name = "H[,HY,HZ]",
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_parser = number
    )]
    h: Option<Vec<f64>>,
    /// Largest sink of the indented top face, in units of h (up to several h) [default: 0.45,
    /// 0.225 for `sphere-coarse`: the seed's 0.1125 mm].
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
        allow_hyphen_values = true,
        value_parser = number
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
    /// Number of points made from known (cell, ξ) [default: 10,000; 1,000,000 for `block`]; at
    /// most 16,777,216 (2^24).
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
    /// Arguments left over. Hidden: it is there so that a flag taken as the value of a list flag
    /// before it (`--offset --h 1`: `--h` is --offset's value, as `-1,2,3` must be) is reported as
    /// that flag's bad value, not as the number after it being unexpected; `run` refuses any.
    #[arg(hide = true)]
    stray: Vec<String>,
}

/// A value of --h or --offset: a number, or an error that says a flag was taken for it.
fn number(value: &str) -> Result<f64, String> {
    if value.starts_with("--") {
        return Err(format!(
            "{value} is a flag, not a number: give the option its value"
        ));
    }
    value.parse().map_err(|e| format!("{e}"))
}

/// A value of --cells: a count, or an error that says a flag was taken for it.
fn count(value: &str) -> Result<u32, String> {
    if value.starts_with("--") {
        return Err(format!(
            "{value} is a flag, not a count: give the option its value"
        ));
    }
    value
        .parse()
        .map_err(|_| format!("{value} is not a count of cells (0 to {})", u32::MAX))
}

fn vector(values: &[f64], flag: &str) -> Result<DVec3> {
    match values {
        [v] => Ok(DVec3::splat(*v)),
        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
        _ => bail!("--{flag} takes one value or three"),
    }
}

/// `v` as a flag would take it, short: `1e300`, not its 301 digits.
fn shown(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// `v` as a list flag would take it: one value when its three are equal.
fn shown3(v: DVec3) -> String {
    if v.x == v.y && v.y == v.z {
        shown(v.x)
    } else {
        v.to_array().map(shown).join(",")
    }
}

/// The cells per axis of the scene `knobs` describe, as the scenes library lays them out
/// (block / h, rounded), checked against the per-axis and the total limits with the flags that
/// set them named: `--cells` for `block` (its counts), `--h` for the others (their block is the
/// seed's).
fn cell_counts(knobs: &SphereOnBlock) -> Result<[u32; 3]> {
    let counts = (knobs.block / knobs.h).round();
    let h = shown3(knobs.h);
    for (axis, n) in ["x", "y", "z"].into_iter().zip(counts.to_array()) {
        // Finite: the block and --h are (checked above).
        if n < 1.0 {
            bail!(
                "--h {h} is coarser than the scene's {} mm block: no cell along {axis}; use a \
                 smaller --h",
                knobs.block.to_array().map(shown).join(" x ")
            );
        }
        if n > f64::from(MAX_CELLS_PER_AXIS) {
            bail!(
                "--h {h} makes {n} cells along {axis}; a generated scene has at most \
                 {MAX_CELLS_PER_AXIS} per axis: use a larger --h"
            );
        }
    }
    let counts = counts.to_array().map(|n| n as u32);
    let count: u64 = counts.iter().map(|&n| u64::from(n)).product();
    if count > MAX_SCENE_CELLS {
        // `block`'s counts are its --cells, checked already: only --h gets here.
        bail!(
            "--h {h} makes {count} cells ({} x {} x {}); a generated scene holds at most \
             {MAX_SCENE_CELLS} (it is built in memory, about 600 bytes a cell): use a larger --h",
            counts[0],
            counts[1],
            counts[2]
        );
    }
    Ok(counts)
}

/// The scene's base lattice, as the scenes library builds it (`counts` cells of spacing h × scale
/// from the offset), with the resolution its finest cells need (`finest` levels of halving below
/// it) checked first, naming the flags: far from the origin, f64 coordinates cannot resolve fine
/// cells ([`Lattice::check_resolution`]), which the library reports as a mesh to move.
fn base_lattice(
    args: &SceneArgs,
    knobs: &SphereOnBlock,
    counts: [u32; 3],
    finest: u8,
) -> Result<Lattice> {
    let h = knobs.h * args.scale;
    let cells = DVec3::from_array(counts.map(f64::from));
    let magnitude = knobs
        .offset
        .abs()
        .max((knobs.offset + h * cells).abs())
        .max_element();
    let fine = h.min_element() * 0.5f64.powi(i32::from(finest));
    let share = 8.0 * f64::EPSILON * magnitude / fine;
    if share > Lattice::RESOLUTION {
        let refined = if finest > 0 {
            format!(", halved {finest} times by --levels")
        } else {
            String::new()
        };
        // Without --offset the scene's own extent is too large for its finest spacing: a --h far
        // finer along one axis than along another (`--h 1e-12,1,1e12`). Naming `--offset 0`,
        // which the user never gave, sent them to the wrong flag.
        if args.offset.is_none() {
            bail!(
                "the scene reaches {magnitude:.3e} from the origin, too far for its spacing \
                 {fine:e} (from --h, --cells and --scale{refined}): coordinates there round by \
                 {share:.1e} of a cell (at most {:e}); use spacings in --h closer to each other, \
                 or fewer --cells",
                Lattice::RESOLUTION
            );
        }
        bail!(
            "--offset {} puts the scene {magnitude:.3e} from the origin, too far for its spacing \
             {fine:e} (from --h and --scale{refined}): coordinates there round by {share:.1e} of \
             a cell (at most {:e}); use a smaller --offset or a larger --h",
            shown3(knobs.offset),
            Lattice::RESOLUTION
        );
    }
    Lattice::new(knobs.offset, h, counts)
        .map_err(|e| anyhow!("the scene's lattice (from --h, --scale and --offset): {e}"))
}

/// The leaves `adaptive` refines `base` into and the finest level among them, counted before the
/// scene is built ([`SphereOnAdaptiveBlock::leaf_count`]), refused beyond [`MAX_SCENE_CELLS`]: a
/// scene far too large at once, a balanced one within the cap after its leaves are made (at the
/// cap, 5 of the 38 s that `--levels 3 --refine-radius 100`, 8.19 M leaves, takes).
fn count_leaves(adaptive: &SphereOnAdaptiveBlock, base: &Lattice) -> Result<(u64, u8)> {
    let cap = MAX_SCENE_CELLS;
    let levels = adaptive.levels;
    let too_many = |count: &str| {
        anyhow!(
            "--levels {levels} and --refine-radius {} make {count} cells; a generated scene holds \
             at most {cap} (it is built in memory, about 600 bytes a cell): lower --levels or \
             --refine-radius, or use a larger --h",
            shown(adaptive.refine_radius)
        )
    };
    // The core indexes 2^21 - 1 cells per axis on the finest level (`refine_lattice`'s limit).
    if let Some(n) = base
        .cells()
        .iter()
        .find(|&&n| u64::from(n) << levels >= 1 << 21)
    {
        bail!(
            "--levels {levels} halves the scene's {n} cells along an axis into more than the \
             2^21 - 1 an adaptive body holds: lower --levels or use a larger --h"
        );
    }
    let count = adaptive.leaf_count(cap).map_err(|e| {
        anyhow!(
            "--levels {levels} on the scene's lattice: {e}: lower --levels or --refine-radius, \
             or use a larger --h"
        )
    })?;
    match count {
        LeafCount::MoreThan(_) => Err(too_many(&format!("more than {cap}"))),
        LeafCount::Exact { leaves, .. } if leaves > cap => Err(too_many(&leaves.to_string())),
        LeafCount::Exact { leaves, finest } => Ok((leaves, finest)),
    }
}

/// The library's error on building the scene, with the flags that made it named: the
/// displacements are the indentation (--sink, in units of h) and the jitter (--jitter).
fn name_the_flags(error: Error, args: &SceneArgs, knobs: &SphereOnBlock) -> anyhow::Error {
    let sink = knobs.sink_in_h;
    let sink_flag = match args.sink {
        Some(_) => format!("--sink {}", shown(sink)),
        None => format!("--sink (default {})", shown(sink)),
    };
    let jitter = args.jitter;
    match &error {
        Error::InvertedCells(_) => {
            let (by, flags) = if jitter > 0.0 {
                (
                    format!("{sink_flag} and --jitter {}", shown(jitter)),
                    "--sink or --jitter",
                )
            } else {
                (sink_flag, "--sink")
            };
            anyhow!(
                "the displacements of {by} (in units of h) invert cells: {error}; use a smaller \
                 {flags}, or --allow-inverted to keep inverted cells"
            )
        }
        Error::DisplacementTooLarge { node, value, limit } => {
            // The indentation moves no node farther than its sink; past the limit without it, the
            // jitter did.
            let flag = if jitter > 0.0 && (sink * knobs.h.z * args.scale).abs() <= *limit {
                format!("--jitter {}", shown(jitter))
            } else {
                sink_flag
            };
            anyhow!(
                "{flag} (in units of h) moves node {node} by {value:?}, more than the {limit:e} \
                 per axis that coordinates resolve on this scene's cells: use a smaller {}",
                flag.split(' ').next().unwrap_or("value")
            )
        }
        Error::NonFiniteDisplacement { node, .. } => {
            let flag = if jitter > 0.0 { "--jitter" } else { "--sink" };
            anyhow!("{flag} (in units of h) moves node {node} beyond f64: use a smaller {flag}")
        }
        _ => error.into(),
    }
}

pub fn run(args: &SceneArgs) -> Result<()> {
    if let Some(stray) = args.stray.first() {
        bail!("unexpected argument '{stray}' found");
    }
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
            let list = cells
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(",");
            if let Some(n) = cells.iter().find(|&&n| n > MAX_CELLS_PER_AXIS) {
                bail!(
                    "--cells {list}: {n} cells along one axis; a generated scene has at most \
                     {MAX_CELLS_PER_AXIS} per axis"
                );
            }
            let count: u64 = cells.iter().map(|&n| u64::from(n)).product();
            if count > MAX_SCENE_CELLS {
                bail!(
                    "--cells {list} asks for {count} cells; a generated scene holds at most \
                     {MAX_SCENE_CELLS} (it is built in memory, about 600 bytes a cell): lower \
                     --cells"
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
        if known as u64 > MAX_KNOWN_POINTS {
            bail!(
                "--known {known}: a generated scene holds at most {MAX_KNOWN_POINTS} known points \
                 (they are built in memory before they are written): lower --known"
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
    // Each bound names the flags that set its length (the spacing's are not --offset's).
    if h.min_element() < MIN_LENGTH {
        bail!(
            "the scene's spacing {:e} (from --h and --scale) is below {MIN_LENGTH:e}: use a \
             larger --h or --scale",
            h.min_element()
        );
    }
    if far > MAX_LENGTH {
        bail!(
            "the scene's farthest coordinate {far:e} (from --h, --cells, --scale and --offset) \
             is beyond {MAX_LENGTH:e}: use a smaller --scale, --h or --offset"
        );
    }
    // `block` has no contact points: with no known points either, points.csv would hold a header
    // only, which `locate` refuses ("no data rows") after `scene` said it wrote it.
    if knobs.contact_points == 0 && knobs.known_points == 0 {
        eprintln!(
            "cgcontact: warning: --known 0 on `{}`, which has no contact points: points.csv and \
             known.csv will hold their header only (`locate` needs at least one point)",
            match args.name {
                SceneName::Block => "block",
                _ => "this scene",
            }
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
    let adaptive = SphereOnAdaptiveBlock {
        levels: args.levels.unwrap_or(2),
        refine_radius: args.refine_radius.unwrap_or(knobs.radius),
        balanced: !args.unbalanced,
        order: if args.shuffle {
            LeafOrder::Shuffled
        } else {
            LeafOrder::Sorted
        },
        ..SphereOnAdaptiveBlock::refining(knobs.clone())
    };
    // The size checked before anything is built: the cells, or the leaves the refinement makes.
    let counts = cell_counts(&knobs)?;
    let (cells, finest) = if args.name == SceneName::SphereAdaptive {
        let base = base_lattice(args, &knobs, counts, 0)?;
        spinning("counting the leaves of sphere-adaptive", false, || {
            count_leaves(&adaptive, &base)
        })?
    } else {
        let count: u64 = counts.iter().map(|&n| u64::from(n)).product();
        (count, 0)
    };
    base_lattice(args, &knobs, counts, finest)?;
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
    let building = format!("building {name} ({cells} cells)");
    let writing = |path: &std::path::Path| format!("writing {}", path.display());
    let (contact, known_points, summary) = if args.name == SceneName::SphereAdaptive {
        let scene = spinning(&building, false, || adaptive.build(name))
            .map_err(|e| name_the_flags(e, args, &knobs))?;
        // The count checked is the scene's: the refinement above is the one `build` makes.
        debug_assert_eq!(scene.body.cell_count() as u64, cells);
        spinning(&writing(&mesh), false, || {
            write_adaptive_mesh(&mesh, &scene.body, format)
        })?;
        spinning(&writing(&points), false, || {
            write_points(&points, &scene.all_points())
        })?;
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
        let scene = spinning(&building, false, || knobs.build(name))
            .map_err(|e| name_the_flags(e, args, &knobs))?;
        debug_assert_eq!(scene.body.lattice().cell_count() as u64, cells);
        spinning(&writing(&mesh), false, || {
            write_mesh(&mesh, &scene.body, format)
        })?;
        spinning(&writing(&points), false, || {
            write_points(&points, &scene.all_points())
        })?;
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
    spinning(&writing(&known), false, || {
        write_known(&known, contact, &known_points)
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

/// `known.csv`: the known answers, row `contact + i` of points.csv for the i-th.
fn write_known(
    known: &std::path::Path,
    contact: usize,
    known_points: &[(usize, KnownPoint)],
) -> Result<(), cgcontact_io::IoError> {
    cgcontact_io::write_file(known, |out| {
        writeln!(out, "point,cell,xi,eta,zeta")?;
        for (row, (cell, k)) in known_points.iter().enumerate() {
            writeln!(
                out,
                "{},{},{},{},{}",
                contact + row,
                cell,
                cgcontact_io::Num(k.xi.x),
                cgcontact_io::Num(k.xi.y),
                cgcontact_io::Num(k.xi.z)
            )?;
        }
        Ok(())
    })
}
