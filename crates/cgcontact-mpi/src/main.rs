//! `cgcontact-mpi`: `cgcontact locate` over MPI ranks.
//!
//! Every rank parses the whole mesh file (true parallel reading of VTK is out of scope) and keeps
//! only its partition's cells; it parses the points file and keeps a contiguous run of rows. The
//! ranks locate every point as one process would, and rank 0 writes the results file through
//! `cgcontact-io`'s writer, byte for byte the file `cgcontact locate` writes. Any failure on any
//! rank stops every rank with exit code 2, the error printed once, by the rank that met it.
#![forbid(unsafe_code)]

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use cgcontact::glam::DVec3;
use cgcontact::{CellId, Settings};
use cgcontact_io::{
    DisplacementArray, MeshBody, MeshFile, read_points, same_file, unended_points_file,
    write_owner_rows, write_results_counted,
};
use cgcontact_mpi::{
    Config, DistributedBody, Error, Gaps, Located, OwnedCell, OwnedLeaf, Partition, QueryStats,
    SetupStats, gather_gaps, gather_located,
};
use clap::{Args, Parser, Subcommand};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// cgcontact's contact search over MPI ranks.
#[derive(Parser, Debug)]
#[command(name = "cgcontact-mpi", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    Locate(LocateArgs),
}

/// Locate the points of a CSV file in a VTK mesh, over the ranks of `mpirun`.
#[derive(Args, Debug, Clone)]
#[command(after_help = "Example:
  mpirun -np 4 cgcontact-mpi locate --mesh block.vtu --points contact.csv --out results.csv --partition slabs

The results file is the one `cgcontact locate` writes for the same mesh and points, byte for byte.
Each rank reads the whole mesh and keeps its partition's cells (slabs across the longest lattice
axis, Morton runs, or scattered; the leaves of an adaptive mesh go with the base cell they lie
in), and keeps a contiguous run of the points' rows. Every rank must be given the same arguments
(but --threads) and read the same files: else exit code 2, on every rank. Exit code 2 on bad
input, on every rank.

Rank 0 prints the summary (or --json) through mpirun, which does not report a failure to write
it: Open MPI's mpirun exits 0 with its standard output on a full disk. The results file is
written by rank 0 itself, atomically, and checked: keep what you need in --out.")]
struct LocateArgs {
    /// The mesh (.vtk, .vtu, or .pvtu and its pieces).
    #[arg(long, value_name = "FILE")]
    mesh: PathBuf,
    /// The points (CSV x,y,z).
    #[arg(long, value_name = "FILE")]
    points: PathBuf,
    /// Where rank 0 writes the results CSV [default: none, only the summary].
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// How the cells are split over the ranks: slabs, morton or random.
    #[arg(long, default_value = "slabs")]
    partition: Partition,
    /// Name of the point-data displacement array [default: `displacement` if present, else undeformed].
    #[arg(long, value_name = "NAME")]
    displacement: Option<String>,
    /// Threads of each rank's local search.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Edge of the ownership map's blocks, in (base) cells [default: 8 on a uniform mesh; on an
    /// adaptive one, 8 cells of the finest level: 8 / 2^finest base cells, at least 1, so that a
    /// refined patch spans several blocks and its points several homes].
    #[arg(long, value_name = "CELLS")]
    block: Option<u32>,
    /// Also measure each point's signed gap to the mesh's deformed boundary surface within D, as
    /// `cgcontact locate --gap D` does: the same columns appended to every row, byte for byte.
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    gap: Option<f64>,
    /// Query the points N more times after the first, and report the fastest run's phases.
    #[arg(long, default_value_t = 0)]
    repeat: usize,
    /// Print one JSON object with the timings, messages and bytes of every rank.
    #[arg(long)]
    json: bool,
    /// On an adaptive mesh, refuse hanging nodes whose displacement breaks their constraint (as
    /// `cgcontact locate --strict` does); without it, rank 0 warns.
    #[arg(long)]
    strict: bool,
    /// Print nothing but errors (and the JSON object with --json, as `cgcontact locate` does).
    #[arg(long, short)]
    quiet: bool,
}

/// This process's rank as its launcher sets it in the environment (Open MPI's mpirun, PMIx,
/// MPICH's Hydra and other PMI launchers, MVAPICH, Slurm's srun), before MPI is initialised;
/// `None` when run alone.
fn launcher_rank() -> Option<u64> {
    [
        "OMPI_COMM_WORLD_RANK",
        "PMIX_RANK",
        "PMI_RANK",
        "MV2_COMM_WORLD_RANK",
        "SLURM_PROCID",
    ]
    .iter()
    .find_map(|name| std::env::var(name).ok()?.trim().parse().ok())
}

/// The exit code of a run ended by Ctrl-C or SIGTERM: 128 + SIGINT's number, as shells report.
const INTERRUPTED: i32 = 130;

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // Every rank parses the same arguments: rank 0 alone speaks (MPI is not running yet:
            // the launcher's variables tell the rank).
            if launcher_rank().is_none_or(|rank| rank == 0) {
                let _ = e.print();
            }
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let Some(universe) = mpi::initialize() else {
        eprintln!("cgcontact-mpi: MPI was already initialised");
        return ExitCode::from(2);
    };
    // A bug of ours on one rank must end the run with one line, not leave the others waiting.
    cgcontact_mpi::abort_on_panic(2);
    let world = universe.world();
    // Ctrl-C or SIGTERM (mpirun forwards SIGTERM to every rank, and answers SIGINT by terminating
    // them): the writes in progress are abandoned, so that no hidden temporary file is left beside
    // an output (every output is as it was or complete), and the rank exits with 130 as
    // `cgcontact locate` does. Silently: mpirun reports the interruption itself, and when it
    // terminates the ranks because one refused its input, that rank's message must stay the
    // run's one line. Without the handler (it could not be set), the signal's default applies.
    let _ = ctrlc::set_handler(|| {
        cgcontact_io::abandon_writes();
        std::process::exit(INTERRUPTED);
    });
    let Command::Locate(args) = &cli.command;
    match locate(&world, args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Here(e))
            if e.downcast_ref::<StdoutError>()
                .is_some_and(|e| e.0.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            // The reader went away (`| head`): a normal end, as for any Unix tool.
            ExitCode::SUCCESS
        }
        Err(Failure::Here(e)) => {
            eprintln!("cgcontact-mpi: {e:#}");
            ExitCode::from(2)
        }
        Err(Failure::Elsewhere) => ExitCode::from(2),
    }
}

/// How a rank's run failed: its own error, printed by it, or another rank's.
enum Failure {
    Here(anyhow::Error),
    Elsewhere,
}

/// All ranks agree on whether every rank's step succeeded: collective, so that no rank goes on
/// into a collective the others left. The lowest failing rank alone keeps its error to print.
fn agree<T>(world: &SimpleCommunicator, step: Result<T>) -> Result<T, Failure> {
    let me = world.rank();
    let failed = if step.is_err() { me } else { i32::MAX };
    let mut first = i32::MAX;
    world.all_reduce_into(&failed, &mut first, SystemOperation::min());
    match (step, first) {
        (Ok(value), i32::MAX) => Ok(value),
        (Err(e), first) if first == me => Err(Failure::Here(e)),
        _ => Err(Failure::Elsewhere),
    }
}

/// Collective: for each of `keys`, whether every rank holds the same (the greatest key is the
/// complement of the greatest complement only when all are equal): one reduction.
fn same_everywhere(world: &SimpleCommunicator, keys: &[u64]) -> Vec<bool> {
    let words: Vec<u64> = keys.iter().flat_map(|&k| [k, !k]).collect();
    let mut greatest = vec![0u64; words.len()];
    world.all_reduce_into(&words[..], &mut greatest[..], SystemOperation::max());
    greatest.chunks_exact(2).map(|w| w[0] == !w[1]).collect()
}

/// A failure every rank knows of: rank 0 prints it, the others stop with it.
fn on_rank_0(rank: i32, error: anyhow::Error) -> Failure {
    if rank == 0 {
        Failure::Here(error)
    } else {
        Failure::Elsewhere
    }
}

/// A 64-bit fingerprint of `words` (each through a multiply–rotate step, which any one changed
/// word changes): the ranks compare their inputs by it.
fn fingerprint(words: impl IntoIterator<Item = u64>) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for word in words {
        hash = (hash ^ word)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29);
    }
    hash
}

/// The fingerprint of the points, bitwise.
fn fingerprint_points(points: &[DVec3]) -> u64 {
    fingerprint(std::iter::once(points.len() as u64).chain(bits(points)))
}

/// The bits of each vector's components, in order.
fn bits(vectors: &[DVec3]) -> impl Iterator<Item = u64> + '_ {
    vectors.iter().flat_map(|x| x.to_array()).map(f64::to_bits)
}

/// The fingerprint of a mesh as read: its lattice, its cells in input order and their nodes'
/// displacements, bitwise.
fn mesh_fingerprint(mesh: &MeshBody) -> u64 {
    let lattice_words = |lattice: &cgcontact::Lattice| {
        let [origin, h] = [lattice.origin(), lattice.h()].map(|v| v.to_array().map(f64::to_bits));
        let cells = lattice.cells().map(u64::from);
        origin.into_iter().chain(h).chain(cells)
    };
    match mesh {
        MeshBody::Uniform(mesh) => fingerprint(
            lattice_words(mesh.body.lattice())
                .chain([mesh.cells.len() as u64, u64::from(mesh.has_displacement)])
                .chain(mesh.cells.lattice_cells().iter().map(|c| u64::from(c.0)))
                .chain(bits(mesh.body.displacements())),
        ),
        MeshBody::Adaptive(mesh) => fingerprint(
            lattice_words(mesh.body.lattice())
                .chain([
                    mesh.body.cell_count() as u64,
                    u64::from(mesh.has_displacement),
                ])
                .chain(mesh.body.leaves().iter().flat_map(|leaf| {
                    let [i, j, k] = leaf.ijk.map(u64::from);
                    [u64::from(leaf.level), i, j, k]
                }))
                .chain(bits(mesh.body.displacements())),
        ),
    }
}

/// The failure of a collective call of the library, which fails on every rank alike: the rank
/// that met the error prints it, the others stop with it.
fn collective<T>(result: Result<T, Error>, step: &str) -> Result<T, Failure> {
    result.map_err(|e| match e {
        Error::OnAnotherRank { .. } => Failure::Elsewhere,
        e => Failure::Here(anyhow!(e).context(step.to_owned())),
    })
}

/// What one rank reports to rank 0 (f64 each, in this order).
const REPORT: [&str; 14] = [
    "setup_seconds",
    "setup_messages",
    "setup_bytes",
    "own_cells",
    "local_cells",
    "points",
    "searched",
    "routing_seconds",
    "search_seconds",
    "return_seconds",
    "routing_messages",
    "routing_bytes",
    "return_messages",
    "return_bytes",
];

fn report(setup: &SetupStats, query: &QueryStats) -> [f64; 14] {
    [
        setup.seconds,
        setup.traffic.messages as f64,
        setup.traffic.bytes as f64,
        setup.own_cells as f64,
        setup.local_cells as f64,
        query.points as f64,
        query.searched as f64,
        query.routing_seconds,
        query.search_seconds,
        query.return_seconds,
        query.routing.messages as f64,
        query.routing.bytes as f64,
        query.returned.messages as f64,
        query.returned.bytes as f64,
    ]
}

fn locate(world: &SimpleCommunicator, args: &LocateArgs) -> Result<(), Failure> {
    let (rank, size) = (world.rank(), world.size() as usize);
    let start = Instant::now();
    // The ranks' arguments (mpirun's MPMD form gives each its own) decide the collectives each
    // makes: ranks given different ones (another --repeat, another --gap) would wait forever
    // in collectives the others never enter.
    let same_args = {
        let mut args = args.clone();
        // Threads are each rank's own business.
        args.threads = 1;
        fingerprint(format!("{args:?}").bytes().map(u64::from))
    };
    if !same_everywhere(world, &[same_args])[0] {
        return Err(on_rank_0(
            rank,
            anyhow!(
                "the ranks were given different arguments (mpirun's `:` form): every rank \
                 must be given the same, but --threads"
            ),
        ));
    }
    // Every flag and the output checked before any file is read.
    agree(world, check_args(args, rank, size))?;
    // The local search runs on rayon's global pool (a communicator cannot enter another pool's
    // threads).
    agree(
        world,
        rayon::ThreadPoolBuilder::new()
            .num_threads(capped_threads(args, rank))
            .build_global()
            .context("cannot start the search threads"),
    )?;
    let read_start = Instant::now();
    // The mesh file first, then (a parallel file's pieces known) the output checked against them,
    // then the pieces read.
    let mesh = agree(
        world,
        MeshFile::read(&args.mesh)
            .map_err(anyhow::Error::from)
            .and_then(|file| {
                check_pieces(args, rank, file.piece_files())?;
                let displacement = DisplacementArray::from_option(args.displacement.as_deref());
                Ok(file.into_body(&displacement)?.body)
            })
            .and_then(|mesh| check_constraints(args, rank, mesh)),
    )?;
    let points = agree(
        world,
        read_points(&args.points).map_err(anyhow::Error::from),
    )?;
    if rank == 0
        && !args.quiet
        && let Some(warning) = unended_points_file(&args.points)
    {
        eprintln!("cgcontact-mpi: warning: {warning}");
    }
    let read_seconds = read_start.elapsed().as_secs_f64();
    // Each rank keeps its partition of the cells and its run of the points by what it read
    // itself: ranks that read different files (another copy on another node's disk, a file
    // rewritten during the run) would leave cells or points to no rank, or give them twice,
    // and rank 0 would write a results file of the wrong rows without a word.
    let same = same_everywhere(
        world,
        &[mesh_fingerprint(&mesh), fingerprint_points(&points)],
    );
    for (same, path) in same.into_iter().zip([&args.mesh, &args.points]) {
        if !same {
            return Err(on_rank_0(
                rank,
                anyhow!(
                    "{}: the ranks read different contents (the file changed while they read \
                     it, or the nodes hold different copies): every rank must read the same",
                    path.display()
                ),
            ));
        }
    }

    // This rank's cells (or leaves, split by the base cell they lie in) and points.
    let mine = match &mesh {
        MeshBody::Uniform(mesh) => {
            let cells: Vec<CellId> = mesh.body.active_cells().collect();
            let owners = args.partition.owners(mesh.body.lattice(), &cells, size);
            Mine::Cells(
                cells
                    .iter()
                    .zip(&owners)
                    .filter(|&(_, &r)| r == rank as usize)
                    .map(|(&cell, _)| OwnedCell {
                        cell,
                        u: mesh
                            .body
                            .cell_displacements(cell)
                            .expect("an active cell of the body"),
                    })
                    .collect(),
            )
        }
        MeshBody::Adaptive(mesh) => {
            let lattice = mesh.body.lattice();
            let leaves = mesh.body.leaves();
            let base: Vec<CellId> = leaves
                .iter()
                .map(|leaf| lattice.cell_id(leaf.base()))
                .collect();
            let owners = args.partition.owners(lattice, &base, size);
            Mine::Leaves(
                leaves
                    .iter()
                    .enumerate()
                    .zip(&owners)
                    .filter(|&(_, &r)| r == rank as usize)
                    .map(|((id, leaf), _)| {
                        let id = CellId(id as u32);
                        OwnedLeaf {
                            id,
                            leaf,
                            u: mesh
                                .body
                                .cell_displacements(id)
                                .expect("a leaf of the body"),
                        }
                    })
                    .collect(),
            )
        }
    };
    let (lattice, cell_count) = match &mesh {
        MeshBody::Uniform(mesh) => (*mesh.body.lattice(), mesh.body.active_count()),
        MeshBody::Adaptive(mesh) => (*mesh.body.lattice(), mesh.body.cell_count()),
    };
    let n = points.len();
    let rows = rank as usize * n / size..(rank as usize + 1) * n / size;
    let my_points = &points[rows];

    let block = args.block.unwrap_or(match &mesh {
        MeshBody::Uniform(_) => 8,
        MeshBody::Adaptive(mesh) => (8u32 >> mesh.body.finest_level().min(3)).max(1),
    });
    let config = Config {
        settings: Settings::default(),
        block,
        gap_distance: args.gap.unwrap_or(0.0),
        // A file printed with few digits leaves its hanging nodes off their coarse faces: the
        // reader's seam, which the serial locator's allowance takes.
        seam: match &mesh {
            MeshBody::Uniform(_) => DVec3::ZERO,
            MeshBody::Adaptive(mesh) => mesh.body.seam(),
        },
    };
    world.barrier();
    let distributed = match &mine {
        Mine::Cells(cells) => DistributedBody::new(world, lattice, cells, config),
        Mine::Leaves(leaves) => DistributedBody::new_adaptive(world, lattice, leaves, config),
    };
    drop(mine);
    let distributed = collective(distributed, "setup")?;
    let locator = agree(world, distributed.locator().map_err(anyhow::Error::from))?;
    let mut best: Option<(f64, QueryStats)> = None;
    // One set of buffers for every repeat, as a solver loop would keep it.
    let mut located = Located::default();
    for _ in 0..=args.repeat {
        world.barrier();
        let query_start = Instant::now();
        collective(
            locator.locate_all_into(world, my_points, &mut located),
            "query",
        )?;
        let local = query_start.elapsed().as_secs_f64();
        // The query's time is the slowest rank's.
        let mut slowest = 0.0f64;
        world.all_reduce_into(&local, &mut slowest, SystemOperation::max());
        // Every repeat gives the same answers: the best one's figures are kept.
        if best.as_ref().is_none_or(|(t, _)| slowest < *t) {
            best = Some((slowest, located.stats));
        }
    }
    let (query_seconds, stats) = best.expect("at least one query");
    located.stats = stats;
    // The gaps, once, timed on the slowest rank.
    let gaps = match args.gap {
        Some(d) => {
            world.barrier();
            let gap_start = Instant::now();
            let mut gaps = Gaps::default();
            collective(
                locator.gap_all_into(world, my_points, d, &mut gaps),
                "gap query",
            )?;
            let local = gap_start.elapsed().as_secs_f64();
            let mut slowest = 0.0f64;
            world.all_reduce_into(&local, &mut slowest, SystemOperation::max());
            Some((gather_gaps(world, 0, &gaps), slowest))
        }
        None => None,
    };

    // Rank 0 gathers the answers and writes them; every rank learns whether it could.
    let gathered = gather_located(world, 0, &located);
    let written = match (&gathered, &args.out, &gaps) {
        // One row per point, with its gap columns (as `cgcontact locate --gap` writes them).
        (Some((answers, tried)), Some(out), Some((Some(gaps), _))) => {
            let one = answers.iter().map(|a| match a {
                Ok(Some(hit)) => std::slice::from_ref(hit),
                _ => &[],
            });
            write_owner_rows(out, one, tried, |c| mesh.cells().input_cell(c), Some(gaps))
                .with_context(|| format!("{}: cannot write the results", out.display()))
        }
        (Some((answers, tried)), Some(out), _) => {
            write_results_counted(out, answers, tried, mesh.cells())
                .with_context(|| format!("{}: cannot write the results", out.display()))
        }
        _ => Ok(()),
    };
    agree(world, written)?;

    // The report: every rank's figures on rank 0.
    let mine_report = report(&distributed.stats(), &located.stats);
    let mut all = vec![0.0f64; REPORT.len() * size];
    world.all_gather_into(&mine_report[..], &mut all[..]);
    if rank == 0 && (args.json || !args.quiet) {
        let (answers, _) = gathered.as_ref().expect("rank 0 gathers");
        let located_count = answers.iter().filter(|a| matches!(a, Ok(Some(_)))).count();
        let invalid_count = answers.iter().filter(|a| a.is_err()).count();
        let text = summary_text(
            args,
            &Summary {
                ranks: size,
                points: n,
                located: located_count,
                invalid: invalid_count,
                cells: cell_count,
                block,
                blocks: distributed.stats().blocks,
                read_seconds,
                query_seconds,
                gap_seconds: gaps.as_ref().map(|(_, seconds)| *seconds),
                total_seconds: start.elapsed().as_secs_f64(),
                per_rank: &all,
            },
        );
        print_text(&text).map_err(Failure::Here)?;
    }
    if rank == 0 && !args.quiet {
        warn_about_cells(&mesh);
    }
    Ok(())
}

/// The warnings `cgcontact locate` gives about the mesh's cells, in its words: cells f64
/// coordinates cannot resolve, and inverted or degenerate cells, named by their input index.
/// Rank 0 holds the whole mesh, as every rank does.
fn warn_about_cells(mesh: &MeshBody) {
    let (inverted, unresolved) = match mesh {
        MeshBody::Uniform(mesh) => (mesh.body.inverted_cells(), mesh.body.unresolved_cells()),
        MeshBody::Adaptive(mesh) => (mesh.body.inverted_cells(), mesh.body.unresolved_cells()),
    };
    let input = |cells: &[(CellId, f64)]| -> Vec<usize> {
        cells
            .iter()
            .map(|&(cell, _)| mesh.cells().input_cell(cell).unwrap_or(cell.index()))
            .collect()
    };
    if let Some(share) = unresolved.iter().map(|&(_, share)| share).reduce(f64::max) {
        eprintln!(
            "cgcontact-mpi: warning: {} cell(s) are sheared or distorted beyond what f64 \
             coordinates of their magnitude resolve: a coordinate's rounding moves ξ in them by \
             up to {share:.2} of a cell (at most {} is resolved), so a point that close to a \
             face of theirs may be given the cell beside it as well; move the mesh nearer the \
             origin: {}",
            unresolved.len(),
            cgcontact::Lattice::RESOLUTION,
            first_ten(&input(&unresolved))
        );
    }
    if !inverted.is_empty() {
        eprintln!(
            "cgcontact-mpi: warning: {} inverted or degenerate cell(s) (det J <= 0 at a corner), \
             answers in or near them are not trusted: {}",
            inverted.len(),
            first_ten(&input(&inverted))
        );
    }
}

/// Up to ten cell indices, joined by commas, then ", ..." when there are more (as `cgcontact
/// locate` lists them).
fn first_ten(cells: &[usize]) -> String {
    let first: Vec<String> = cells.iter().take(10).map(usize::to_string).collect();
    let more = if cells.len() > 10 { ", ..." } else { "" };
    format!("{}{more}", first.join(", "))
}

/// This rank's share of the body.
enum Mine {
    Cells(Vec<OwnedCell>),
    Leaves(Vec<OwnedLeaf>),
}

/// An adaptive mesh's hanging nodes against their constraints, as `cgcontact locate` checks
/// them: a warning on rank 0 (unless `--quiet`), or with `--strict` an error.
fn check_constraints(args: &LocateArgs, rank: i32, mesh: MeshBody) -> anyhow::Result<MeshBody> {
    if let MeshBody::Adaptive(adaptive) = &mesh
        && let Some(message) = adaptive.constraint_problem(&args.mesh)
    {
        if args.strict {
            anyhow::bail!("{message}");
        }
        if !args.quiet && rank == 0 {
            eprintln!("cgcontact-mpi: warning: {message} (--strict refuses such a mesh)");
        }
    }
    Ok(mesh)
}

/// Search threads per available core at most, as `cgcontact locate` caps them: more only adds
/// switching, and a mistyped count (`--threads 1000000`) would ask the system for a million.
const THREADS_PER_CORE: usize = 4;

/// `--threads`, capped at [`THREADS_PER_CORE`] per core this rank can run on; a warning on rank 0
/// (unless `--quiet`) says so.
fn capped_threads(args: &LocateArgs, rank: i32) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let cap = THREADS_PER_CORE * cores;
    if args.threads > cap && !args.quiet && rank == 0 {
        eprintln!(
            "cgcontact-mpi: warning: --threads {} capped at {cap} ({THREADS_PER_CORE} per \
             available core, {cores} here)",
            args.threads
        );
    }
    args.threads.min(cap)
}

/// Refuse, before any file is read, what cannot work: a block size out of range, no threads, an
/// output that is an input, in a missing folder or in one rank 0 cannot write in. Only rank 0
/// writes, so only rank 0 checks the output (another node need not see its folder).
fn check_args(args: &LocateArgs, rank: i32, size: usize) -> Result<()> {
    if let Some(block) = args.block
        && (block == 0 || block > 1 << 20)
    {
        bail!("--block {block}: it must be between 1 and 1048576 cells");
    }
    if args.threads == 0 {
        bail!("--threads 0: at least one thread searches");
    }
    // The core's gap finder's range (beyond it the gap query would fail only after the search),
    // in `cgcontact locate`'s words.
    if let Some(d) = args.gap
        && !(0.0..=cgcontact::MAX_DISPLACEMENT).contains(&d)
    {
        bail!(
            "--gap {d:?}: the search distance must be a number from 0 to {:e}",
            cgcontact::MAX_DISPLACEMENT
        );
    }
    // Every rank reads the inputs itself: a pipe or standard input (`--points /dev/stdin`,
    // `<(...)`) reaches one rank, and the others would read nothing, or no such file.
    for (flag, input) in [("--mesh", &args.mesh), ("--points", &args.points)] {
        if size > 1
            && let Ok(meta) = std::fs::metadata(input)
            && !meta.is_file()
            && !meta.is_dir()
        {
            bail!(
                "{flag} {}: not a regular file; each of the {size} ranks reads it, and a pipe or \
                 standard input reaches only one: give a file",
                input.display()
            );
        }
    }
    if let Some(out) = args.out.as_ref().filter(|_| rank == 0) {
        for (flag, input) in [("--mesh", &args.mesh), ("--points", &args.points)] {
            if same_file(out, input) {
                bail!(
                    "--out {} is the {flag} file {}: it would be overwritten",
                    out.display(),
                    input.display()
                );
            }
        }
        let folder = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !folder.is_dir() {
            bail!(
                "--out {}: the folder {} does not exist",
                out.display(),
                folder.display()
            );
        }
        if out.is_dir() {
            bail!("--out {}: a folder, not a file", out.display());
        }
        // A folder rank 0 cannot write in fails now, as `cgcontact locate` fails, not after the
        // whole search (a device such as /dev/null is written in place).
        if !out.exists() || out.is_file() {
            tempfile::tempfile_in(&folder).with_context(|| {
                format!(
                    "--out {}: cannot write in {}",
                    out.display(),
                    folder.display()
                )
            })?;
        }
    }
    Ok(())
}

/// `--out` against the files of a parallel `--mesh`'s pieces, inputs too, as `cgcontact locate`
/// checks them: known once the `.pvtu` is read, before any piece is. Only rank 0 writes, so only
/// rank 0 checks.
fn check_pieces(args: &LocateArgs, rank: i32, pieces: &[PathBuf]) -> Result<()> {
    let Some(out) = args.out.as_ref().filter(|_| rank == 0) else {
        return Ok(());
    };
    if let Some((piece, file)) = cgcontact_io::piece_file(out, pieces) {
        bail!(
            "--out {} is {}, the file of piece {piece} of the --mesh {}: it would be overwritten",
            out.display(),
            file.display(),
            args.mesh.display()
        );
    }
    Ok(())
}

struct Summary<'a> {
    ranks: usize,
    points: usize,
    located: usize,
    /// Points refused for NaN or infinite coordinates (neither located nor not located, as
    /// `cgcontact locate` counts them).
    invalid: usize,
    cells: usize,
    /// The blocks' edge, in (base) cells.
    block: u32,
    blocks: usize,
    read_seconds: f64,
    query_seconds: f64,
    /// The gap query's time on the slowest rank, with `--gap`.
    gap_seconds: Option<f64>,
    total_seconds: f64,
    per_rank: &'a [f64],
}

impl Summary<'_> {
    /// Points searched and not found.
    fn not_located(&self) -> usize {
        self.points - self.located - self.invalid
    }
}

fn summary_text(args: &LocateArgs, s: &Summary<'_>) -> String {
    let rows: Vec<&[f64]> = s.per_rank.chunks_exact(REPORT.len()).collect();
    if args.json {
        let ranks: Vec<String> = rows
            .iter()
            .map(|row| {
                let fields: Vec<String> = REPORT
                    .iter()
                    .zip(row.iter())
                    .map(|(name, value)| format!("\"{name}\": {value}"))
                    .collect();
                format!("{{{}}}", fields.join(", "))
            })
            .collect();
        return format!(
            "{{\"ranks\": {}, \"partition\": \"{}\", \"block\": {}, \"threads\": {}, \"points\": {}, \"located\": {}, \"not_located\": {}, \"invalid_points\": {}, \"cells\": {}, \"blocks\": {}, \"read_seconds\": {}, \"query_seconds\": {}, \"points_per_second\": {}, \"gap_seconds\": {}, \"total_seconds\": {}, \"per_rank\": [{}]}}\n",
            s.ranks,
            args.partition.name(),
            s.block,
            args.threads,
            s.points,
            s.located,
            s.not_located(),
            s.invalid,
            s.cells,
            s.blocks,
            s.read_seconds,
            s.query_seconds,
            s.points as f64 / s.query_seconds.max(1e-12),
            s.gap_seconds
                .map_or_else(|| "null".to_owned(), |t| t.to_string()),
            s.total_seconds,
            ranks.join(", ")
        );
    }
    let mut lines = vec![
        format!(
            "{} ranks ({} partition), {} cells, {} points: {} located, {} not located{}",
            s.ranks,
            args.partition.name(),
            s.cells,
            s.points,
            s.located,
            s.not_located(),
            if s.invalid > 0 {
                format!(", {} with NaN/inf coordinates", s.invalid)
            } else {
                String::new()
            }
        ),
        format!(
            "query {:.3} ms ({:.3e} points/s), slowest rank; files read in {:.3} s",
            1e3 * s.query_seconds,
            s.points as f64 / s.query_seconds.max(1e-12),
            s.read_seconds
        ),
    ];
    if let Some(t) = s.gap_seconds {
        lines.push(format!("gap query {:.3} ms, slowest rank", 1e3 * t));
    }
    for (rank, row) in rows.iter().enumerate() {
        lines.push(format!(
            "rank {rank}: setup {:.3} ms ({} cells own, {} local); points {} asked, {} searched; routing {:.3} ms, search {:.3} ms, return {:.3} ms; sent {} + {} messages, {} + {} bytes",
            1e3 * row[0],
            row[3],
            row[4],
            row[5],
            row[6],
            1e3 * row[7],
            1e3 * row[8],
            1e3 * row[9],
            row[10],
            row[12],
            row[11],
            row[13],
        ));
    }
    if let Some(out) = &args.out {
        lines.push(format!("wrote {}", out.display()));
    }
    lines.iter().map(|line| format!("{line}\n")).collect()
}

/// Standard output could not be written. A closed pipe (`cgcontact-mpi ... | head -c 1`) is a
/// normal end, as for `cgcontact locate`; anything else (a full disk) is an error.
///
/// Under mpirun, rank 0's standard output is a pipe or terminal that mpirun reads and copies to
/// its own, and Open MPI's mpirun drops what it cannot write there without a word (`mpirun ...`
/// redirected to /dev/full exits 0 whatever the rank does). This catches what the rank itself
/// can see: a run started without mpirun (a singleton), or a launcher that passes it on.
#[derive(Debug)]
struct StdoutError(std::io::Error);

impl std::fmt::Display for StdoutError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cannot write to standard output: {}", self.0)
    }
}

impl std::error::Error for StdoutError {}

/// `text` on standard output, flushed: an error rather than `println!`'s panic (which aborted
/// the run with a panic message) when it cannot be written.
fn print_text(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| StdoutError(e).into())
}
