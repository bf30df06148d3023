//! `cgcontact locate`: user points in a user mesh.

use std::path::PathBuf;

use anyhow::Result;
use cgcontact::{AdaptiveLocator, GapAnswer, GapFinder, LatticeLocator, Settings};
use cgcontact_baseline::BodyRef;
use cgcontact_io::{
    DEFAULT_DISPLACEMENT, DisplacementArray, MeshBody, MeshFile, MeshRead,
    read_points_with_warning, write_deformed_adaptive_vtu, write_deformed_vtu, write_points_vtu,
    write_results_counted,
};
use clap::Args;
use std::time::Instant;

use crate::output::{check_outputs, check_pieces, prepare_folder, write_owner_rows};
use crate::run::{
    ConstraintSummary, GapSummary, SearchArgs, Searched, StrategyName, reading,
    search_listing_owners,
};

/// Locate the points of a CSV file in a VTK mesh of hexahedra on a cartesian lattice.
#[derive(Args, Debug)]
#[command(after_help = "Example:
  cgcontact locate --mesh block.vtu --points contact.csv --out results.csv --strategy lattice --json

The mesh is a VTK unstructured grid of hexahedra (legacy .vtk ASCII/binary, XML .vtu, or a parallel .pvtu of
.vtu pieces) whose nodes lie on a cartesian lattice, or whose cells are dyadic refinements of one (an adaptive mesh: levels are detected
from the cell sizes, cells and nodes may come in any order); the displacement is the point-data vector `displacement` (or --displacement NAME).
The points file has three columns x,y,z and an optional header line. Results: CSV with header
point,cell,xi,eta,zeta,... where cell is the 0-based input cell index, or -1 when not found.

With --all-owners, a point on a face, edge or node shared by several cells (or on a fine/coarse
interface, or at a hanging node) gets one row per cell holding it: the same point index repeated,
cells ascending, each row with its own xi; a point no cell holds keeps its one row with cell -1:
  cgcontact locate --mesh block.vtu --points contact.csv --out owners.csv --all-owners")]
pub struct LocateArgs {
    /// The mesh (.vtk, .vtu, or .pvtu and its pieces).
    #[arg(long, value_name = "FILE")]
    mesh: PathBuf,
    /// The points (CSV x,y,z).
    #[arg(long, value_name = "FILE")]
    points: PathBuf,
    /// Where to write the results CSV [default: none, only the summary].
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Name of the point-data displacement array [default: `displacement` if present, else undeformed].
    #[arg(long, value_name = "NAME")]
    displacement: Option<String>,
    /// Also write `mesh.vtu` (deformed, with points held per cell) and `points.vtu` for ParaView to DIR.
    #[arg(long, value_name = "DIR")]
    vtk: Option<PathBuf>,
    /// On an adaptive mesh, refuse hanging nodes whose displacement breaks their constraint (the
    /// coarse cell's interpolation there) instead of warning.
    #[arg(long)]
    strict: bool,
    /// Write a results row for every cell holding a point, not one cell per point.
    ///
    /// A point on a shared face has 2 rows, on an edge 4, at a node 8 (on an adaptive mesh, a
    /// hanging node's coarse cell and fine cells): the point index repeated, cells ascending in
    /// the input numbering, each row with its own xi. A point no cell holds keeps its one row
    /// with cell -1. Not with --strategy noderad-seed (its loose Newton misses owners);
    /// centroid and noderad are filters that may leave owners out (a warning says so). --vtk
    /// still shows one cell per point.
    #[arg(long)]
    all_owners: bool,
    /// Also measure each point's signed gap to the mesh's deformed boundary surface, within
    /// distance D (0 to 1e150).
    ///
    /// Appends the columns gap,cx,cy,cz,nx,ny,nz,face_cell,face to every results row: the signed
    /// distance (negative inside the body), the closest surface point, the unit outward normal
    /// there, and the face holding it (its cell, in the input numbering, and its VTK local face
    /// 0-5). They are empty where the surface is farther than D. Exact (every face, edge and
    /// corner within D): the closest point and normal in f64 whatever --precision says, the sign
    /// (inside or not) by the lattice locator with this run's --precision, --tol and --max-iter,
    /// whatever --strategy says.
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    gap: Option<f64>,
    #[command(flatten)]
    search: SearchArgs,
}

pub fn run(args: &LocateArgs) -> Result<()> {
    // Every setting and every output checked before any file is read or any work done.
    if args.all_owners && args.search.strategy == StrategyName::NoderadSeed {
        // Its owners would be wrong, not merely incomplete: the seed's Newton stops at a physical
        // residual of 0.1 and then tests |ξ| ≤ 1 with no tolerance, so at a shared node it keeps
        // whichever owners its loose ξ happens to fall in (and may name a cell that does not hold
        // the point at all).
        anyhow::bail!(
            "--all-owners cannot be used with --strategy noderad-seed: the seed's Newton stops at a residual of 0.1 and tests |xi| <= 1 without tolerance, so it misses cells sharing a face, edge or node (use --strategy noderad: the same filter with the exact Newton)"
        );
    }
    if args.all_owners
        && matches!(
            args.search.strategy,
            StrategyName::Centroid | StrategyName::Noderad
        )
        && !args.search.quiet
    {
        // Filters, not complete searches: a cell they never offer is never inverted, so a point
        // on a face, edge or node may get fewer owners (an audit: centroid left out owners of
        // every interior node of an undeformed 3 x 3 x 3 block).
        eprintln!(
            "cgcontact: warning: --strategy {} is a filter that may leave out cells holding a \
             point (docs/baselines.md), so --all-owners may list fewer owners than there are; \
             lattice, rtree and brute list every one",
            if args.search.strategy == StrategyName::Centroid {
                "centroid"
            } else {
                "noderad"
            }
        );
    }
    if let Some(d) = args.gap {
        // The gap finder's own range (distances beyond it would overflow when squared).
        if !(0.0..=cgcontact::MAX_DISPLACEMENT).contains(&d) {
            anyhow::bail!(
                "--gap {d:?}: the search distance must be a number from 0 to {:e}",
                cgcontact::MAX_DISPLACEMENT
            );
        }
    }
    let pool = args.search.check()?;
    let inputs = [
        ("--mesh", args.mesh.as_path()),
        ("--points", args.points.as_path()),
    ];
    let mut outputs = Vec::new();
    if let Some(out) = &args.out {
        outputs.push(("--out", out.clone()));
    }
    let vtk_files = args
        .vtk
        .as_ref()
        .map(|dir| [dir.join("mesh.vtu"), dir.join("points.vtu")]);
    if let Some(files) = &vtk_files {
        outputs.extend(files.iter().map(|f| ("--vtk", f.clone())));
    }
    // The --vtk folder need not exist yet: its files are checked against the inputs first.
    let mut _made = None;
    if let Some(dir) = &args.vtk {
        if dir.exists() && !dir.is_dir() {
            anyhow::bail!("{}: --vtk names a file, not a folder", dir.display());
        }
        let existing: Vec<_> = outputs
            .iter()
            .filter(|(flag, _)| *flag != "--vtk" || dir.is_dir())
            .cloned()
            .collect();
        check_outputs(&inputs, &existing)?;
        _made = Some(prepare_folder("--vtk", dir)?);
    }
    check_outputs(&inputs, &outputs)?;
    let quiet = args.search.quiet || args.search.json;
    // Each input is read once (a named pipe can be read only once): the mesh file here, its
    // pieces' files below, the points after.
    let file = reading(&args.mesh, quiet, || MeshFile::read(&args.mesh))?;
    // A parallel file's pieces are inputs too, known now: no output may replace one.
    check_pieces(&args.mesh, file.piece_files(), &outputs)?;
    let MeshRead {
        body: mesh,
        point_arrays,
    } = reading(&args.mesh, quiet, || {
        file.into_body(&DisplacementArray::from_option(
            args.displacement.as_deref(),
        ))
    })?;
    if let MeshBody::Adaptive(adaptive) = &mesh
        && let Some(message) = adaptive.constraint_problem(&args.mesh)
    {
        if args.strict {
            anyhow::bail!("{message}");
        }
        if !args.search.quiet {
            eprintln!("cgcontact: warning: {message} (--strict refuses such a mesh)");
        }
    }
    if !mesh.has_displacement()
        && args.displacement.is_none()
        && !args.search.quiet
        && !point_arrays.is_empty()
    {
        eprintln!(
            "cgcontact: warning: {}: no point array named `{DEFAULT_DISPLACEMENT}`, so the mesh \
             is read undeformed; its point arrays: {} (--displacement NAME reads one as the \
             displacement)",
            args.mesh.display(),
            point_arrays.join(", ")
        );
    }
    let (points, unended) = reading(&args.points, quiet, || {
        read_points_with_warning(&args.points)
    })?;
    if let Some(warning) = unended
        && !args.search.quiet
    {
        eprintln!("cgcontact: warning: {warning}");
    }
    let body: BodyRef<'_> = match &mesh {
        MeshBody::Uniform(m) => (&m.body).into(),
        MeshBody::Adaptive(m) => (&m.body).into(),
    };
    let cells = mesh.cells();
    let (
        Searched {
            answers,
            tried,
            mut summary,
        },
        owners,
    ) = search_listing_owners(body, &points, &args.search, &pool, args.all_owners)?;
    if let MeshBody::Adaptive(adaptive) = &mesh
        && let (false, Some((node, by))) =
            (adaptive.constraints.holds(), adaptive.constraints.worst)
    {
        summary.hanging_constraints = Some(ConstraintSummary {
            violating: adaptive.constraints.violating,
            worst_node: node,
            worst_position: adaptive
                .body
                .node_position(node)
                .unwrap_or_default()
                .to_array(),
            worst_offset: by,
            tolerance: adaptive.constraint_tolerance_by_axis.to_array(),
        });
    }
    summary.displacement = mesh.has_displacement().then(|| {
        args.displacement
            .clone()
            .unwrap_or_else(|| cgcontact_io::DEFAULT_DISPLACEMENT.to_owned())
    });
    // Name inverted and unresolved cells as the user knows them: by their index in the input
    // mesh.
    for cell in summary
        .inverted_cells
        .iter_mut()
        .chain(summary.unresolved_cells.iter_mut())
    {
        *cell = cells
            .input_cell(cgcontact::CellId(*cell as u32))
            .unwrap_or(*cell);
    }
    let settings = args.search.settings()?;
    let gaps = args.gap.map(|d| {
        let (gaps, gap) = measure_gaps(body, &points, d, settings, &pool);
        summary.gap = Some(gap);
        gaps
    });
    if let Some(out) = &args.out {
        match (&owners, &gaps) {
            // Owners are named as the `cell` column names them: by their input cell index.
            (Some(owners), gaps) => {
                write_owner_rows(
                    out,
                    owners.per_point(),
                    &tried,
                    |c| cells.input_cell(c),
                    gaps.as_deref(),
                )?;
            }
            (None, Some(gaps)) => {
                let one = answers.iter().map(|a| match a {
                    Ok(Some(hit)) => std::slice::from_ref(hit),
                    _ => &[],
                });
                write_owner_rows(out, one, &tried, |c| cells.input_cell(c), Some(gaps))?;
            }
            (None, None) => write_results_counted(out, &answers, &tried, cells)?,
        }
        summary.files.push(out.display().to_string());
    }
    if let Some([mesh_path, points_path]) = &vtk_files {
        match &mesh {
            MeshBody::Uniform(m) => write_deformed_vtu(mesh_path, &m.body, cells, &answers, false)?,
            MeshBody::Adaptive(m) => write_deformed_adaptive_vtu(mesh_path, &m.body, &answers)?,
        }
        write_points_vtu(points_path, &points, &answers, cells)?;
        summary.files.push(mesh_path.display().to_string());
        summary.files.push(points_path.display().to_string());
    }
    summary.print(&args.search)
}

/// The contact quantities of `points` towards `body`'s boundary surface within `distance` (finite,
/// at least 0: checked by the caller), measured with the exact `GapFinder` on `pool`, and their
/// summary. The gap's sign is the lattice locator's with the query's `settings` (precision,
/// tolerances): a row's `cell` and `gap` agree whatever the precision (with f64 signs beside f32
/// cells, a point up to about 1.5e-6 of a cell outside was held by the f32 locator and given a
/// positive gap). The closest point and normal are computed in f64 either way.
pub fn measure_gaps(
    body: BodyRef<'_>,
    points: &[cgcontact::glam::DVec3],
    distance: f64,
    settings: Settings,
    pool: &rayon::ThreadPool,
) -> (Vec<GapAnswer>, GapSummary) {
    let start = Instant::now();
    let mut gaps = Vec::new();
    pool.install(|| match body {
        BodyRef::Uniform(body) => {
            let locator = LatticeLocator::new(body, settings).expect("settings validated");
            GapFinder::new(&locator, distance)
                .expect("a checked distance")
                .gap_all_into(points, &mut gaps);
        }
        BodyRef::Adaptive(body) => {
            let locator = AdaptiveLocator::new(body, settings).expect("settings validated");
            GapFinder::new(&locator, distance)
                .expect("a checked distance")
                .gap_all_into(points, &mut gaps);
        }
    });
    let summary = gap_summary(&gaps, distance, start.elapsed().as_secs_f64());
    (gaps, summary)
}

/// The summary of the gaps of every point within `distance`, measured in `seconds`.
fn gap_summary(gaps: &[GapAnswer], distance: f64, seconds: f64) -> GapSummary {
    let found = gaps.iter().filter_map(|g| g.ok().flatten());
    let (mut within, mut inside, mut penetration) = (0, 0, None::<f64>);
    for contact in found {
        within += 1;
        if contact.gap < 0.0 {
            inside += 1;
            penetration = Some(penetration.map_or(contact.gap, |p| p.min(contact.gap)));
        }
    }
    GapSummary {
        distance,
        within,
        inside,
        penetration,
        seconds,
    }
}
