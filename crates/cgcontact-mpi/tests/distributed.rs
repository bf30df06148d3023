//! The distributed search against the serial one, under mpirun.
//!
//! Run by `cargo test`, this program is the driver: it starts itself under `mpirun --oversubscribe
//! -np P` for P = 1, 2, 3, 4 and fails when any run fails. Started by mpirun (Open MPI sets
//! `OMPI_COMM_WORLD_SIZE`), it is one rank: on every scene, partition and block size, each rank's
//! answers must be bitwise those of the serial `LatticeLocator` on the whole body (cell, ξ,
//! iterations, residual, inversions, and the inversions tried by points not found), and its gap
//! answers those of the serial `GapFinder` (gap, closest point, normal, face, (s, t)); on adaptive
//! scenes, those of the serial `AdaptiveLocator` and its `GapFinder`. A mismatch aborts every rank
//! with a message naming the point.

use std::process::Command;
use std::time::{Duration, Instant};

use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Answer, Body, CellId, GapAnswer, GapFinder, Lattice,
    LatticeLocator, Leaf, Locator, PointError, Settings,
};
use cgcontact_mpi::{
    Config, DistributedBody, Error, Gaps, Located, OwnedCell, OwnedLeaf, Partition,
};
use cgcontact_scenes::{
    LeafDraw, LeafOrder, SphereOnAdaptiveBlock, SphereOnBlock, adaptive_known_points, known_points,
    refine_lattice,
};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

fn main() {
    let under_mpirun = std::env::var_os("OMPI_COMM_WORLD_SIZE").is_some()
        || std::env::var_os("PMI_SIZE").is_some();
    match (under_mpirun, std::env::var_os(PANIC_ON_RANK)) {
        (false, _) => {
            a_panic_aborts_every_rank();
            drive();
        }
        (true, Some(rank)) => panicking_rank(&rank.to_string_lossy()),
        (true, None) => rank(),
    }
}

/// Set for the run of [`a_panic_aborts_every_rank`]: the rank that panics.
const PANIC_ON_RANK: &str = "CGCONTACT_MPI_TEST_PANIC_ON_RANK";

/// One rank panics while the others wait in a collective: with `abort_on_panic`, mpirun returns
/// with the code given to it and the panic is printed with its rank, instead of waiting forever.
fn a_panic_aborts_every_rank() {
    let start = Instant::now();
    let (status, stderr) = mpirun(
        "3",
        |command| {
            command
                .env(PANIC_ON_RANK, "1")
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped());
        },
        Duration::from_secs(60),
    );
    // Open MPI's mpirun returns the code given to MPI_Abort.
    assert_eq!(status.code(), Some(3), "mpirun's status: {status}");
    assert!(
        stderr.contains("cgcontact-mpi: rank 1 panicked at") && stderr.contains("on purpose"),
        "the panic and its rank are printed: {stderr}"
    );
    println!(
        "a panic on rank 1 of 3 ended mpirun in {:.1} s",
        start.elapsed().as_secs_f64()
    );
}

/// A rank of [`a_panic_aborts_every_rank`]: rank `which` panics, the others wait in a barrier.
fn panicking_rank(which: &str) {
    let universe = mpi::initialize().expect("MPI starts once");
    cgcontact_mpi::abort_on_panic(3);
    let world = universe.world();
    if world.rank().to_string() == which {
        panic!("on purpose, to test abort_on_panic");
    }
    world.barrier();
}

/// Start this program under mpirun for P = 1..=4 (or the `CGCONTACT_MPI_RANKS` list).
fn drive() {
    let ranks = std::env::var("CGCONTACT_MPI_RANKS").unwrap_or_else(|_| "1,2,3,4".to_owned());
    for p in ranks.split(',') {
        let start = Instant::now();
        let (status, _) = mpirun(p, |_| {}, Duration::from_secs(600));
        assert!(status.success(), "mpirun -np {p} failed: {status}");
        println!(
            "mpirun -np {p}: every answer bitwise the serial one ({:.1} s)",
            start.elapsed().as_secs_f64()
        );
    }
}

/// Runs this program under `mpirun --oversubscribe -np P`, with what `configure` adds, and fails
/// when it is still running after `limit`: its status, and its standard error when piped.
fn mpirun(
    np: &str,
    configure: impl FnOnce(&mut Command),
    limit: Duration,
) -> (std::process::ExitStatus, String) {
    let exe = std::env::current_exe().expect("the test's own path");
    let mut command = Command::new("mpirun");
    command.arg("--oversubscribe");
    if is_root() {
        command.arg("--allow-run-as-root");
    }
    command.args(["-np", np]).arg(&exe);
    configure(&mut command);
    let start = Instant::now();
    let mut child = command
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start mpirun ({e}): is Open MPI installed?"));
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting on mpirun") {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!(
                "mpirun -np {np} was still running after {} s",
                limit.as_secs()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut stderr = String::new();
    if let Some(mut pipe) = child.stderr.take() {
        std::io::Read::read_to_string(&mut pipe, &mut stderr).expect("mpirun's standard error");
    }
    (status, stderr)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|out| String::from_utf8_lossy(&out.stdout).trim() == "0")
}

/// One test scene: a body and every query point (all ranks build the same).
struct Case {
    name: &'static str,
    body: Body,
    points: Vec<DVec3>,
}

fn rank() {
    let universe = mpi::initialize().expect("MPI starts once");
    // A failed assertion ends the run at once rather than leaving the other ranks waiting.
    cgcontact_mpi::abort_on_panic(1);
    let world = universe.world();
    let size = world.size() as usize;
    let (mut checked, mut patched) = (0usize, 0usize);
    for case in cases() {
        for partition in Partition::ALL {
            for block in [8, 2] {
                for placement in [
                    Placement::Split,
                    Placement::AllOnLast,
                    Placement::Own,
                    Placement::MostlyOwn,
                ] {
                    let (n, p) = check(&world, &case, partition, block, placement);
                    checked += n;
                    patched += p;
                }
            }
        }
    }
    let mut gaps = 0usize;
    for case in cases() {
        for partition in Partition::ALL {
            for placement in [Placement::Split, Placement::MostlyOwn] {
                gaps += check_gaps(&world, &case, partition, placement);
            }
        }
    }
    let mut adaptive = 0usize;
    for case in adaptive_cases() {
        for split in [
            Split::Base(Partition::Slabs),
            Split::Base(Partition::Morton),
            Split::Base(Partition::Random),
            Split::Leafwise,
        ] {
            for placement in [Placement::Split, Placement::AllOnLast, Placement::MostlyOwn] {
                adaptive += check_adaptive(&world, &case, split, placement, 0.0);
            }
            adaptive += check_adaptive(&world, &case, split, Placement::Split, 1.0);
        }
    }
    refusals_agree(&world);
    adaptive_refusals_agree(&world);
    collective_misuse_fails_on_every_rank(&world);
    let mut total = 0usize;
    world.all_reduce_into(
        &checked,
        &mut total,
        mpi::collective::SystemOperation::sum(),
    );
    let mut patched_total = 0usize;
    world.all_reduce_into(
        &patched,
        &mut patched_total,
        mpi::collective::SystemOperation::sum(),
    );
    if size > 1 && patched_total == 0 {
        fail(&world, "no query searched in place with points leaving");
    }
    let mut gaps_total = 0usize;
    world.all_reduce_into(
        &gaps,
        &mut gaps_total,
        mpi::collective::SystemOperation::sum(),
    );
    let mut adaptive_total = 0usize;
    world.all_reduce_into(
        &adaptive,
        &mut adaptive_total,
        mpi::collective::SystemOperation::sum(),
    );
    if world.rank() == 0 {
        println!(
            "{size} ranks: {total} answers bitwise the serial ones ({patched_total} in-place \
             queries with points leaving), {gaps_total} gap answers, and \
             {adaptive_total} answers and gap answers on adaptive bodies"
        );
    }
}

/// Which rank asks about which points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// Contiguous runs of rows, as the command line reads them.
    Split,
    /// Every point on the last rank; the others have none.
    AllOnLast,
    /// Each rank asks about the points whose home it is, and rank 0 also about those with no
    /// home: no point leaves its rank, so each searches its own in place.
    Own,
    /// As `Own`, and besides one in 200 of the other ranks' points, in among its own: so few
    /// leave that each rank searches all of its points in place and replaces the answers of
    /// those that left.
    MostlyOwn,
}

/// The distributed answers of this rank's share of the case's points against the serial ones;
/// returns how many were checked, and 1 if this rank searched in place with points leaving.
fn check(
    world: &SimpleCommunicator,
    case: &Case,
    partition: Partition,
    block: u32,
    placement: Placement,
) -> (usize, usize) {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let lattice = *case.body.lattice();
    let cells: Vec<CellId> = case.body.active_cells().collect();
    let mine = cells_of(case, partition, rank, size);
    let config = Config {
        block,
        ..Config::default()
    };
    let what = format!(
        "{} / {} / block {block} / {placement:?} on rank {rank} of {size}",
        case.name,
        partition.name()
    );
    let distributed = DistributedBody::new(world, lattice, &mine, config)
        .unwrap_or_else(|e| fail(world, &format!("{what}: setup: {e}")));
    let points = share(&case.points, &distributed, placement, rank, size);
    let points = &points[..];
    // A rank whose points leave, but few enough (at most one in 32) for the in-place search
    // with patched answers.
    let leaving = points
        .iter()
        .filter(|&&x| distributed.home_of(x).is_some_and(|h| h as usize != rank))
        .count();
    let patched = usize::from(leaving > 0 && leaving * 32 <= points.len());
    let locator = distributed
        .locator()
        .unwrap_or_else(|e| fail(world, &format!("{what}: locator: {e}")));
    // A query's buffers reused by the next: first the points in reverse (another routing), then
    // the points themselves into the same `Located`.
    let mut located = Located::default();
    let reversed: Vec<DVec3> = points.iter().rev().copied().collect();
    locator
        .locate_all_into(world, &reversed, &mut located)
        .unwrap_or_else(|e| fail(world, &format!("{what}: query: {e}")));
    locator
        .locate_all_into(world, points, &mut located)
        .unwrap_or_else(|e| fail(world, &format!("{what}: query: {e}")));

    // The serial answers on the whole body: the oracle.
    let serial = LatticeLocator::new(&case.body, Settings::default()).expect("default settings");
    expect_located(world, &what, points, &located, &serial);
    // Memory follows the cells: with slabs over several ranks no rank holds the whole body.
    let stats = distributed.stats();
    if partition == Partition::Slabs && size > 1 && block == 8 && case.name == "sphere-fine" {
        let most = stats.local_cells;
        if most >= cells.len() {
            fail(
                world,
                &format!("{what}: the local body holds all {most} cells"),
            );
        }
    }
    (points.len(), patched)
}

/// Gap queries within four cells of the case's widest spacing, on a body set up for that distance,
/// against the serial `GapFinder` on the whole body, bit for bit: the case's points and the same
/// moved by about half a cell (many outside the body, within the distance of its surface).
/// Returns how many were checked.
fn check_gaps(
    world: &SimpleCommunicator,
    case: &Case,
    partition: Partition,
    placement: Placement,
) -> usize {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let lattice = *case.body.lattice();
    let h = lattice.h();
    let distance = 4.0 * h.max_element();
    let what = format!(
        "{} / {} / gaps / {placement:?} on rank {rank} of {size}",
        case.name,
        partition.name()
    );
    let config = Config {
        gap_distance: distance,
        ..Config::default()
    };
    let mine = cells_of(case, partition, rank, size);
    let distributed = DistributedBody::new(world, lattice, &mine, config)
        .unwrap_or_else(|e| fail(world, &format!("{what}: setup: {e}")));
    let moved: Vec<DVec3> = case
        .points
        .iter()
        .flat_map(|&x| [x, x + h * DVec3::new(0.6, -0.45, 0.55)])
        .collect();
    let points = share(&moved, &distributed, placement, rank, size);
    let locator = distributed
        .locator()
        .unwrap_or_else(|e| fail(world, &format!("{what}: locator: {e}")));
    // Buffers reused: first the points reversed, then the points.
    let mut gaps = Gaps::default();
    let reversed: Vec<DVec3> = points.iter().rev().copied().collect();
    for query in [&reversed, &points] {
        locator
            .gap_all_into(world, query, distance, &mut gaps)
            .unwrap_or_else(|e| fail(world, &format!("{what}: {e}")));
    }
    let serial = LatticeLocator::new(&case.body, Settings::default()).expect("default settings");
    let finder = GapFinder::new(&serial, distance).expect("a valid distance");
    let mut expected = Vec::new();
    finder.gap_all_into(&points, &mut expected);
    expect_gaps(world, &what, &points, &gaps.answers, &expected);
    let contacts = expected
        .iter()
        .filter(|want| matches!(want, Ok(Some(c)) if c.gap > 0.0))
        .count();
    // Points outside within the distance are part of what is checked.
    let mut outside = 0usize;
    world.all_reduce_into(
        &contacts,
        &mut outside,
        mpi::collective::SystemOperation::sum(),
    );
    if outside == 0 {
        fail(
            world,
            &format!("{what}: no point outside the body within the distance"),
        );
    }
    points.len()
}

/// Fails every rank unless `located` holds, for each of `points`, the `serial` locator's answer
/// bit for bit, and for a point not found the inversions its serial search tries.
fn expect_located(
    world: &SimpleCommunicator,
    what: &str,
    points: &[DVec3],
    located: &Located,
    serial: &impl Locator,
) {
    let expected = serial.locate_all(points);
    if located.answers.len() != points.len() || located.tried.len() != points.len() {
        fail(
            world,
            &format!("{what}: answers for {} points", located.answers.len()),
        );
    }
    for (i, (x, (got, want))) in points
        .iter()
        .zip(located.answers.iter().zip(&expected))
        .enumerate()
    {
        let want_tried = match want {
            Ok(Some(hit)) => hit.inversions,
            _ => serial.locate_counted(*x).1,
        };
        if bits(got) != bits(want) || located.tried[i] != want_tried {
            fail(
                world,
                &format!(
                    "{what}: this rank's point {i} at {x}: distributed {got:?} (tried {}), serial {want:?} (tried {want_tried})",
                    located.tried[i]
                ),
            );
        }
    }
}

/// Fails every rank unless each of `got` is the `expected` gap answer of its point, bit for bit.
fn expect_gaps(
    world: &SimpleCommunicator,
    what: &str,
    points: &[DVec3],
    got: &[GapAnswer],
    expected: &[GapAnswer],
) {
    if got.len() != points.len() {
        fail(
            world,
            &format!("{what}: gap answers for {} points", got.len()),
        );
    }
    for (i, (x, (got, want))) in points.iter().zip(got.iter().zip(expected)).enumerate() {
        if gap_bits(got) != gap_bits(want) {
            fail(
                world,
                &format!(
                    "{what}: this rank's point {i} at {x}: distributed {got:?}, serial {want:?}"
                ),
            );
        }
    }
}

/// A gap answer's fields as bits.
type GapBits = (Vec<u64>, u32, u8, bool);

fn gap_bits(answer: &GapAnswer) -> Result<Option<GapBits>, PointError> {
    answer.map(|c| {
        c.map(|c| {
            let mut words = vec![c.gap.to_bits(), c.st.x.to_bits(), c.st.y.to_bits()];
            words.extend(c.point.to_array().map(f64::to_bits));
            words.extend(c.normal.to_array().map(f64::to_bits));
            (words, c.face.cell.0, c.face.local, c.interior)
        })
    })
}

/// The cells `partition` gives `rank` of `size`, with their displacements.
fn cells_of(case: &Case, partition: Partition, rank: usize, size: usize) -> Vec<OwnedCell> {
    let lattice = *case.body.lattice();
    let cells: Vec<CellId> = case.body.active_cells().collect();
    let owners = partition.owners(&lattice, &cells, size);
    cells
        .iter()
        .zip(&owners)
        .filter(|&(_, &r)| r == rank)
        .map(|(&cell, _)| OwnedCell {
            cell,
            u: case.body.cell_displacements(cell).expect("an active cell"),
        })
        .collect()
}

/// The points `rank` of `size` asks about under `placement`.
fn share(
    all_points: &[DVec3],
    distributed: &DistributedBody,
    placement: Placement,
    rank: usize,
    size: usize,
) -> Vec<DVec3> {
    let all = 0..all_points.len();
    let range = match placement {
        Placement::Split => {
            let n = all_points.len();
            rank * n / size..(rank + 1) * n / size
        }
        Placement::AllOnLast if rank == size - 1 => all,
        Placement::AllOnLast => 0..0,
        Placement::Own | Placement::MostlyOwn => all,
    };
    match placement {
        Placement::Own | Placement::MostlyOwn => all_points
            .iter()
            .copied()
            .enumerate()
            .filter(|&(i, x)| match distributed.home_of(x) {
                Some(home) => {
                    home as usize == rank || (placement == Placement::MostlyOwn && i % 200 == 0)
                }
                None => rank == 0,
            })
            .map(|(_, x)| x)
            .collect(),
        _ => all_points[range].to_vec(),
    }
}

/// A bad cell on one rank, or a cell on two: every rank gets an error, none hangs.
fn refusals_agree(world: &SimpleCommunicator) {
    let (rank, size) = (world.rank(), world.size());
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [4, 3, 2]).expect("a lattice");
    let good = |c: u32| OwnedCell {
        cell: CellId(c),
        u: [DVec3::ZERO; 8],
    };
    let last = size - 1;
    // Out of range on the last rank.
    let mut mine: Vec<OwnedCell> = (0..24)
        .filter(|c| c % size as u32 == rank as u32)
        .map(good)
        .collect();
    if rank == last {
        mine.push(good(99));
    }
    match DistributedBody::new(world, lattice, &mine, Config::default()) {
        Err(Error::CellOutOfRange { cell, .. }) if rank == last && cell == CellId(99) => {}
        Err(Error::OnAnotherRank { rank: r }) if rank != last && r == last => {}
        other => fail(
            world,
            &format!("out of range on rank {last}: rank {rank} got {other:?}"),
        ),
    }
    // Cell 0 on every rank (a duplicate whenever there are two ranks).
    let mut mine: Vec<OwnedCell> = (1..24)
        .filter(|c| c % size as u32 == rank as u32)
        .map(good)
        .collect();
    mine.push(good(0));
    let result = DistributedBody::new(world, lattice, &mine, Config::default());
    if (size > 1) != result.is_err() {
        fail(
            world,
            &format!(
                "cell 0 on {size} ranks: rank {rank} got {:?}",
                result.map(|_| ())
            ),
        );
    }
    // A gap distance beyond the core's gap finder's on the last rank: refused at setup, not at
    // the first gap query (before, the setup took it, with halos spanning the lattice).
    let mine: Vec<OwnedCell> = (0..24)
        .filter(|c| c % size as u32 == rank as u32)
        .map(good)
        .collect();
    let config = Config {
        gap_distance: if rank == last { 1e300 } else { 1.0 },
        ..Config::default()
    };
    match DistributedBody::new(world, lattice, &mine, config) {
        Err(Error::GapDistance(d)) if rank == last && d == 1e300 => {}
        Err(Error::OnAnotherRank { rank: r }) if rank != last && r == last => {}
        other => fail(
            world,
            &format!(
                "gap distance 1e300 on rank {last}: rank {rank} got {:?}",
                other.map(|_| ())
            ),
        ),
    }
    // No cell anywhere.
    match DistributedBody::new(world, lattice, &[], Config::default()) {
        Err(Error::EmptyBody) => {}
        other => fail(
            world,
            &format!("no cells: rank {rank} got {:?}", other.map(|_| ())),
        ),
    }
}

/// Ranks that disagree on a collective call: each gets an error (the same kind on every rank, or
/// its own refusal and `OnAnotherRank` on the others), none hangs, crashes or answers with
/// another rank's body or distance, and a correct query afterwards gets the serial answers.
/// Before, a setup with another block size on one rank died in MPI, other settings or another
/// body gave answers silently wrong, and a gap distance refused on one rank left the others
/// waiting in the routing; a query on another communicator crashed.
fn collective_misuse_fails_on_every_rank(world: &SimpleCommunicator) {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let last = size - 1;
    let case = &cases()[4];
    assert_eq!(case.name, "tiny");
    let lattice = *case.body.lattice();
    let mine = cells_of(case, Partition::Slabs, rank, size);
    let h = lattice.h().max_element();
    let config = Config {
        gap_distance: h,
        ..Config::default()
    };
    // Another block size, settings or lattice on the last rank.
    let odd_settings = Settings {
        max_iter: 1,
        ..Settings::default()
    };
    let other_lattice =
        Lattice::new(lattice.origin() + 0.1, lattice.h(), lattice.cells()).expect("a lattice");
    for (name, odd, odd_lattice) in [
        ("block", Config { block: 2, ..config }, lattice),
        (
            "settings",
            Config {
                settings: odd_settings,
                ..config
            },
            lattice,
        ),
        ("lattice", config, other_lattice),
    ] {
        let (config, lattice) = if rank == last {
            (odd, odd_lattice)
        } else {
            (config, lattice)
        };
        match DistributedBody::new(world, lattice, &mine, config) {
            Err(Error::SetupMismatch) if size > 1 => {}
            Ok(_) if size == 1 => {}
            other => fail(
                world,
                &format!(
                    "another {name} on rank {last}: rank {rank} got {:?}",
                    other.map(|_| ())
                ),
            ),
        }
    }
    let body = DistributedBody::new(world, lattice, &mine, config)
        .unwrap_or_else(|e| fail(world, &format!("misuse: setup: {e}")));
    let mut moved = case.body.clone();
    moved
        .update_displacements(|_, _, u| *u += DVec3::new(0.3 * h, 0.0, -0.2 * h))
        .expect("finite");
    let mine_moved = cells_of(
        &Case {
            name: "moved",
            body: moved.clone(),
            points: Vec::new(),
        },
        Partition::Slabs,
        rank,
        size,
    );
    let other = DistributedBody::new(world, lattice, &mine_moved, config)
        .unwrap_or_else(|e| fail(world, &format!("misuse: setup: {e}")));
    let locator = body
        .locator()
        .unwrap_or_else(|e| fail(world, &format!("misuse: locator: {e}")));
    let other_locator = other
        .locator()
        .unwrap_or_else(|e| fail(world, &format!("misuse: locator: {e}")));
    // Every point on every rank: most of them leave it.
    let points = &case.points[..];
    let mut gaps = Gaps::default();
    let mut located = Located::default();
    // A distance refused on the last rank (beyond the setup's), then on rank 0 (NaN).
    for (bad_rank, bad) in [(last, 2.0 * h), (0, f64::NAN)] {
        let distance = if rank == bad_rank { bad } else { h };
        match locator.gap_all_into(world, points, distance, &mut gaps) {
            Err(Error::GapBeyondSetup { .. } | Error::GapDistance(_)) if rank == bad_rank => {}
            Err(Error::OnAnotherRank { rank: r }) if rank != bad_rank && r as usize == bad_rank => {
            }
            other => fail(
                world,
                &format!("gap distance {bad} on rank {bad_rank}: rank {rank} got {other:?}"),
            ),
        }
        if !gaps.answers.is_empty() {
            fail(world, "a refused gap query left answers");
        }
    }
    // What differs on the last rank: the gap distance, the body, the kind of query.
    let mismatch = |what: &str, result: Result<(), Error>| match result {
        Err(Error::QueryMismatch) if size > 1 => {}
        Ok(()) if size == 1 => {}
        other => fail(
            world,
            &format!("another {what} on rank {last}: rank {rank} got {other:?}"),
        ),
    };
    let distance = if rank == last { 0.5 * h } else { h };
    mismatch(
        "gap distance",
        locator.gap_all_into(world, points, distance, &mut gaps),
    );
    let which = if rank == last {
        &other_locator
    } else {
        &locator
    };
    mismatch("body", which.locate_all_into(world, points, &mut located));
    mismatch(
        "body (gaps)",
        which.gap_all_into(world, points, h, &mut gaps),
    );
    if rank == last {
        mismatch(
            "kind of query",
            locator.gap_all_into(world, points, h, &mut gaps),
        );
    } else {
        mismatch(
            "kind of query",
            locator.locate_all_into(world, points, &mut located),
        );
    }
    // A query on a communicator of other ranks (the world split in two): the homes name the
    // world's ranks. Before, ranks panicked in the return's exchange or read homes beyond the
    // split's size as none ("not found"). Each rank refuses it on its own.
    let half = world
        .split_by_color(mpi::topology::Color::with_value((rank % 2) as i32))
        .expect("every rank has a colour");
    match locator.locate_all_into(&half, points, &mut located) {
        Err(Error::Communicator { .. }) if size > 1 => {}
        Ok(()) if size == 1 => {}
        other => fail(
            world,
            &format!("a query on a split communicator: rank {rank} got {other:?}"),
        ),
    }
    match locator.gap_all_into(&half, points, h, &mut gaps) {
        Err(Error::Communicator { .. }) if size > 1 => {}
        Ok(()) if size == 1 => {}
        other => fail(
            world,
            &format!("a gap query on a split communicator: rank {rank} got {other:?}"),
        ),
    }
    // The ranks are still in step: a query agreed on gets the serial answers, on either body.
    for (locator, whole) in [(&locator, &case.body), (&other_locator, &moved)] {
        locator
            .locate_all_into(world, points, &mut located)
            .unwrap_or_else(|e| fail(world, &format!("misuse: query: {e}")));
        let serial = LatticeLocator::new(whole, Settings::default()).expect("default settings");
        expect_located(world, "after misuse", points, &located, &serial);
    }
}

/// One adaptive test scene: a body and every query point (all ranks build the same).
struct AdaptiveCase {
    name: &'static str,
    body: AdaptiveBody,
    points: Vec<DVec3>,
}

/// How the leaves are split over the ranks.
#[derive(Clone, Copy, Debug)]
enum Split {
    /// By the base cell each leaf lies in, as the command line splits them.
    Base(Partition),
    /// Leaf by leaf, scattered: the leaves of one base cell on several ranks.
    Leafwise,
}

/// The leaves `split` gives `rank` of `size`, with their ids and displacements.
fn leaves_of(body: &AdaptiveBody, split: Split, rank: usize, size: usize) -> Vec<OwnedLeaf> {
    let lattice = *body.lattice();
    let leaves = body.leaves().to_vec();
    let owners = match split {
        Split::Base(partition) => {
            let base: Vec<CellId> = leaves
                .iter()
                .map(|leaf| lattice.cell_id(leaf.base()))
                .collect();
            partition.owners(&lattice, &base, size)
        }
        // The random partition hashes the ids it is given: here the leaves'.
        Split::Leafwise => {
            let ids: Vec<CellId> = (0..leaves.len() as u32).map(CellId).collect();
            Partition::Random.owners(&lattice, &ids, size)
        }
    };
    leaves
        .iter()
        .enumerate()
        .filter(|&(id, _)| owners[id] == rank)
        .map(|(id, &leaf)| {
            let id = CellId(id as u32);
            OwnedLeaf {
                id,
                leaf,
                u: body.cell_displacements(id).expect("a leaf"),
            }
        })
        .collect()
}

/// The distributed answers (with `gap_cells` > 0, the gap answers within that many base cells)
/// of this rank's share of an adaptive case's points against the serial ones on the whole body.
/// Returns how many were checked.
fn check_adaptive(
    world: &SimpleCommunicator,
    case: &AdaptiveCase,
    split: Split,
    placement: Placement,
    gap_cells: f64,
) -> usize {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let lattice = *case.body.lattice();
    let distance = gap_cells * lattice.h().max_element();
    let what = format!(
        "{} / {split:?} / {placement:?} / gap {distance} on rank {rank} of {size}",
        case.name
    );
    let config = Config {
        block: 4,
        gap_distance: distance,
        ..Config::default()
    };
    let mine = leaves_of(&case.body, split, rank, size);
    let distributed = DistributedBody::new_adaptive(world, lattice, &mine, config)
        .unwrap_or_else(|e| fail(world, &format!("{what}: setup: {e}")));
    let points = share(&case.points, &distributed, placement, rank, size);
    let locator = distributed
        .locator()
        .unwrap_or_else(|e| fail(world, &format!("{what}: locator: {e}")));
    let serial = AdaptiveLocator::new(&case.body, Settings::default()).expect("default settings");
    let reversed: Vec<DVec3> = points.iter().rev().copied().collect();
    if gap_cells > 0.0 {
        let mut gaps = Gaps::default();
        for query in [&reversed, &points] {
            locator
                .gap_all_into(world, query, distance, &mut gaps)
                .unwrap_or_else(|e| fail(world, &format!("{what}: {e}")));
        }
        let mut expected = Vec::new();
        GapFinder::new(&serial, distance)
            .expect("a valid distance")
            .gap_all_into(&points, &mut expected);
        expect_gaps(world, &what, &points, &gaps.answers, &expected);
        return points.len();
    }
    let mut located = Located::default();
    locator
        .locate_all_into(world, &reversed, &mut located)
        .unwrap_or_else(|e| fail(world, &format!("{what}: query: {e}")));
    locator
        .locate_all_into(world, &points, &mut located)
        .unwrap_or_else(|e| fail(world, &format!("{what}: query: {e}")));
    expect_located(world, &what, &points, &located, &serial);
    // Every local body has the whole body's finest level, on which the search's tolerance
    // depends, even where no leaf near its points is that fine.
    if let Some((local, _)) = distributed.local_adaptive_body()
        && local.finest_level() != case.body.finest_level()
    {
        fail(
            world,
            &format!(
                "{what}: the local body's finest level is {}, the body's {}",
                local.finest_level(),
                case.body.finest_level()
            ),
        );
    }
    // Memory follows the leaves: with slabs over several ranks no rank holds the whole body
    // (unless the halo covers it, as on the two-cell body).
    if let (Split::Base(Partition::Slabs), true) = (split, size > 1 && case.name != "two-cells") {
        let local = distributed.stats().local_cells;
        if local >= case.body.cell_count() {
            fail(
                world,
                &format!("{what}: the local body holds all {local} leaves"),
            );
        }
    }
    points.len()
}

/// A leaf out of range on one rank, or leaves overlapping across ranks: every rank gets an
/// error, none hangs.
fn adaptive_refusals_agree(world: &SimpleCommunicator) {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [4, 3, 2]).expect("a lattice");
    // Base cell 0 refined once, the other 23 base cells whole.
    let mut leaves: Vec<Leaf> = Leaf::new(0, [0; 3]).children().to_vec();
    leaves.extend((1..24).map(|c| Leaf::new(0, lattice.cell_ijk(CellId(c)).expect("a cell"))));
    let owned = |id: usize, leaf: Leaf| OwnedLeaf {
        id: CellId(id as u32),
        leaf,
        u: [DVec3::ZERO; 8],
    };
    let mine = |extra: Option<Leaf>| -> Vec<OwnedLeaf> {
        let mut mine: Vec<OwnedLeaf> = leaves
            .iter()
            .enumerate()
            .filter(|(id, _)| id % size == rank)
            .map(|(id, &leaf)| owned(id, leaf))
            .collect();
        if let Some(leaf) = extra.filter(|_| rank == size - 1) {
            mine.push(owned(leaves.len(), leaf));
        }
        mine
    };
    let last = size - 1;
    // Level 1 indices beyond the lattice's 8 finer cells along x, on the last rank.
    match DistributedBody::new_adaptive(
        world,
        lattice,
        &mine(Some(Leaf::new(1, [8, 0, 0]))),
        Config::default(),
    ) {
        Err(Error::LeafOutOfRange { leaf, .. })
            if rank == last && leaf == CellId(leaves.len() as u32) => {}
        Err(Error::OnAnotherRank { rank: r }) if rank != last && r as usize == last => {}
        other => fail(
            world,
            &format!(
                "leaf out of range on rank {last}: rank {rank} got {:?}",
                other.map(|_| ())
            ),
        ),
    }
    // Base cell 0 whole as well as refined: an overlap, found where both arrive.
    let result = DistributedBody::new_adaptive(
        world,
        lattice,
        &mine(Some(Leaf::new(0, [0; 3]))),
        Config::default(),
    );
    match result {
        Err(Error::Core(cgcontact::Error::OverlappingCells { cell, other })) => {
            let ids = [cell, other];
            if !ids.contains(&CellId(leaves.len() as u32)) {
                fail(
                    world,
                    &format!(
                        "the overlap names {ids:?}, not the whole cell {}",
                        leaves.len()
                    ),
                );
            }
        }
        Err(Error::OnAnotherRank { .. }) => {}
        other => fail(
            world,
            &format!(
                "overlapping leaves: rank {rank} got {:?}",
                other.map(|_| ())
            ),
        ),
    }
    // Leaf ids that are not the whole body's 0..n each once. Every rank numbering its own
    // leaves from 0: before, refused only on the ranks where two such leaves met. And on a
    // bar of 12 cells in blocks of 1, in runs of cells, the last rank's last leaf (cell 11)
    // given the id of leaf 0 (cell 0, on rank 0): with more than one rank the two never meet on
    // one rank (the halos reach 3 cells, and leaf 0 travels as an extreme but is not added
    // where its id is), so before it set up and answered with one id for two leaves.
    let local_ids: Vec<OwnedLeaf> = mine(None)
        .into_iter()
        .enumerate()
        .map(|(at, leaf)| OwnedLeaf {
            id: CellId(at as u32),
            ..leaf
        })
        .collect();
    let bar = Lattice::new(DVec3::ZERO, DVec3::ONE, [12, 1, 1]).expect("a lattice");
    let mut twice: Vec<OwnedLeaf> = (0..12)
        .filter(|c| c * size / 12 == rank)
        .map(|c| owned(c, Leaf::new(0, [c as u32, 0, 0])))
        .collect();
    if rank == last {
        twice.last_mut().expect("a leaf on every rank").id = CellId(0);
    }
    let block_1 = Config {
        block: 1,
        ..Config::default()
    };
    for (what, lattice, given, config, count, wrong) in [
        (
            "local ids",
            lattice,
            local_ids,
            Config::default(),
            leaves.len(),
            size > 1,
        ),
        ("an id twice", bar, twice, block_1, 12, true),
    ] {
        match DistributedBody::new_adaptive(world, lattice, &given, config) {
            Err(Error::LeafIds { leaves, .. }) if wrong && leaves == count as u64 => {}
            Ok(_) if !wrong => {}
            other => fail(
                world,
                &format!("{what}: rank {rank} got {:?}", other.map(|_| ())),
            ),
        }
    }
    // Without the extra leaf, the body sets up on every rank.
    if let Err(e) = DistributedBody::new_adaptive(world, lattice, &mine(None), Config::default()) {
        fail(
            world,
            &format!("a valid adaptive body: rank {rank} got {e}"),
        );
    }
}

/// The adaptive scenes: the seed's coarse block refined two levels under the sphere (balanced,
/// leaves shuffled) and three levels unbalanced (jumps of more than one level, jittered), with
/// holes; each with the sphere's contact points, known points, and points at ξ ∈ {−1, 0, 1}³ of
/// random leaves (on faces, edges and nodes shared by leaves of different levels and ranks).
fn adaptive_cases() -> Vec<AdaptiveCase> {
    let balanced = SphereOnAdaptiveBlock {
        order: LeafOrder::Shuffled,
        ..SphereOnAdaptiveBlock::coarse()
    }
    .build("balanced")
    .expect("the adaptive scene");
    let unbalanced = SphereOnAdaptiveBlock {
        levels: 3,
        balanced: false,
        order: LeafOrder::Shuffled,
        ..SphereOnAdaptiveBlock::refining(SphereOnBlock {
            jitter: 0.1,
            known_points: 1500,
            ..SphereOnBlock::coarse()
        })
    }
    .build("unbalanced")
    .expect("the adaptive scene");
    let mut cases = Vec::new();
    for (name, scene, every) in [
        ("balanced", balanced, 0),
        ("unbalanced-holed", unbalanced, 9),
    ] {
        let body = if every == 0 {
            scene.body.clone()
        } else {
            // Every `every`-th leaf left out, the displacements the scene's at the nodes left.
            let kept: Vec<Leaf> = scene
                .body
                .leaves()
                .iter()
                .enumerate()
                .filter(|(i, _)| i % every != 4)
                .map(|(_, leaf)| leaf)
                .collect();
            let mut holed =
                AdaptiveBody::from_leaves(*scene.body.lattice(), kept).expect("leaves left");
            let whole = &scene.body;
            let finest = whole.finest_level();
            assert_eq!(
                holed.finest_level(),
                finest,
                "the holes keep the finest level"
            );
            let u: Vec<DVec3> = (0..holed.node_count())
                .map(|node| {
                    let x = holed.node_position(node).expect("a node");
                    let at = whole
                        .node_at_finest(finest_coords(whole, x))
                        .expect("a node of the whole");
                    whole.displacements()[at]
                })
                .collect();
            holed.set_displacements(&u).expect("finite");
            holed
        };
        let mut points = scene.all_points();
        points.extend([DVec3::NAN, DVec3::splat(1e6), DVec3::splat(-3.0)]);
        points.extend(adaptive_boundary_points(&body, 1500, 3));
        cases.push(AdaptiveCase { name, body, points });
    }

    // Two levels in the corner of high x and low y, the displacement extremes at the corners
    // of low and high x + y: ranks away from the refined corner hold no fine leaf near their
    // points, nor an extreme one.
    let lattice = Lattice::new(
        DVec3::new(1.0, -2.0, 0.5),
        DVec3::new(0.5, 0.4, 0.3),
        [48, 6, 4],
    )
    .expect("a lattice");
    let upper = lattice.upper();
    let leaves = refine_lattice(&lattice, 2, true, |_, low, _| {
        low.x >= upper.x - 0.5 && low.y < lattice.origin().y + 0.4
    })
    .expect("leaves");
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).expect("an adaptive body");
    let span = upper - lattice.origin();
    body.update_independent(|_, x, u| {
        let s = (x - lattice.origin()) / span;
        let ramp = s.x + s.y + 0.1 * s.z;
        *u = DVec3::new(0.02 + 0.05 * ramp, -0.01 + 0.03 * ramp, 0.015 * ramp);
    })
    .expect("finite");
    let mut points: Vec<DVec3> = adaptive_known_points(&body, 1500, LeafDraw::PerLeaf, 11)
        .iter()
        .map(|k| k.x)
        .collect();
    points.extend(adaptive_boundary_points(&body, 1500, 12));
    cases.push(AdaptiveCase {
        name: "corner-refined",
        body,
        points,
    });

    // Two base cells, one refined: with more ranks than base cells along the slabs' axis, some
    // ranks hold no leaf.
    let mut body = cgcontact_scenes::hanging_node_moved(0.0).expect("a body");
    body.update_independent(|_, x, u| {
        *u = DVec3::new(0.05 * x.y * x.z, -0.04 * x.x, 0.03 * (x.x + x.y))
    })
    .expect("finite");
    let mut points: Vec<DVec3> = adaptive_known_points(&body, 300, LeafDraw::PerLeaf, 13)
        .iter()
        .map(|k| k.x)
        .collect();
    points.extend(adaptive_boundary_points(&body, 300, 14));
    cases.push(AdaptiveCase {
        name: "two-cells",
        body,
        points,
    });
    cases
}

/// The finest-level lattice coordinates of an undeformed node position of `body`.
fn finest_coords(body: &AdaptiveBody, x: DVec3) -> [u32; 3] {
    let lattice = body.lattice();
    let t = (x - lattice.origin()) / lattice.h() * f64::from(1u32 << body.finest_level());
    t.round().to_array().map(|v| v as u32)
}

/// `count` points of random leaves at ξ whose components are −1, 0 or 1, from `seed`.
fn adaptive_boundary_points(body: &AdaptiveBody, count: usize, seed: u64) -> Vec<DVec3> {
    let leaves: Vec<CellId> = (0..body.cell_count() as u32).map(CellId).collect();
    points_at_corners(&leaves, |leaf, xi| body.point_at(leaf, xi), count, seed)
}

fn fail(world: &SimpleCommunicator, message: &str) -> ! {
    eprintln!("MISMATCH: {message}");
    world.abort(1)
}

/// A hit's fields as bits, or the refusal.
type Bits = (CellId, [u64; 3], u32, u64, u32);

fn bits(answer: &Answer) -> Result<Option<Bits>, PointError> {
    answer.map(|hit| {
        hit.map(|h| {
            let xi = h.xi.to_array().map(f64::to_bits);
            (h.cell, xi, h.iterations, h.residual.to_bits(), h.inversions)
        })
    })
}

/// The scenes: the seed's case; a jittered, holed block with points on cell faces, edges and
/// nodes (ξ = ±1, which lie on rank boundaries for every partition); a block with one node moved
/// far (a search box of many cells, the core's block-range path); and a tiny block with fewer
/// cells along its slab axis than ranks (empty ranks).
fn cases() -> Vec<Case> {
    let mut cases = Vec::new();
    let fine = SphereOnBlock::fine()
        .build("sphere-fine")
        .expect("the seed's scene");
    let mut points = fine.all_points();
    points.extend([
        DVec3::NAN,
        DVec3::new(0.1, f64::INFINITY, 0.0),
        DVec3::splat(1e6),
        DVec3::splat(-3.0),
    ]);
    points.extend(boundary_points(&fine.body, 3000, 1));
    cases.push(Case {
        name: "sphere-fine",
        body: fine.body,
        points,
    });

    let jittered = SphereOnBlock {
        jitter: 0.15,
        sink_in_h: 1.5,
        known_points: 2000,
        ..SphereOnBlock::coarse()
    }
    .build("jittered")
    .expect("a valid jittered scene");
    let holed = holed(&jittered.body, 5);
    let mut points: Vec<DVec3> = known_points(&holed, 2000, 7).iter().map(|k| k.x).collect();
    points.extend(boundary_points(&holed, 4000, 2));
    points.extend(jittered.contact_points.iter().take(2000));
    cases.push(Case {
        name: "jittered-holed",
        body: holed,
        points,
    });

    let lattice = Lattice::new(
        DVec3::new(-2.0, 5.0, 1.0),
        DVec3::new(0.3, 0.25, 0.4),
        [10, 8, 6],
    )
    .expect("a lattice");
    let mut spiked = Body::full(lattice);
    let spike = lattice.node_index([4, 3, 3]);
    let h = lattice.h();
    spiked
        .update_displacements(|node, x, u| {
            *u = 0.05 * DVec3::new((x.y * 2.0).sin(), (x.z * 1.5).cos(), (x.x * 0.7).sin());
            if node == spike {
                *u += 5.0 * h;
            }
        })
        .expect("finite");
    let mut points: Vec<DVec3> = known_points(&spiked, 1500, 3).iter().map(|k| k.x).collect();
    points.extend(boundary_points(&spiked, 1500, 4));
    cases.push(Case {
        name: "spiked",
        body: spiked,
        points,
    });

    // One node moved 2 h along x at one end of a long bar, and points beyond the other end: the
    // serial search admits them (the lattice's box shifted by the displacement range reaches
    // there) and inverts their predicted cell; a rank whose local body lacked that far node's
    // range would refuse them untried.
    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.5), [30, 4, 4]).expect("a lattice");
    let mut bar = Body::full(lattice);
    let far = lattice.node_index([1, 2, 2]);
    bar.update_displacements(|node, x, u| {
        *u = DVec3::new(0.01 * x.y, 0.02 * (x.x * 0.3).sin(), -0.01 * x.x);
        if node == far {
            u.x += 1.0;
        }
    })
    .expect("finite");
    let mut points: Vec<DVec3> = (0..400)
        .map(|i| {
            let f = f64::from(i);
            DVec3::new(
                15.0 + 0.002 * f,
                0.1 + (f * 0.37) % 1.8,
                0.1 + (f * 0.71) % 1.8,
            )
        })
        .collect();
    points.extend(known_points(&bar, 500, 8).iter().map(|k| k.x));
    cases.push(Case {
        name: "far-spike",
        body: bar,
        points,
    });

    let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2]).expect("a lattice");
    let mut tiny = Body::full(lattice);
    tiny.update_displacements(|_, x, u| *u = DVec3::new(0.04 * x.y, -0.03 * x.x * x.z, 0.05 * x.x))
        .expect("finite");
    let mut points = boundary_points(&tiny, 500, 5);
    points.extend(known_points(&tiny, 200, 6).iter().map(|k| k.x));
    cases.push(Case {
        name: "tiny",
        body: tiny,
        points,
    });
    cases
}

/// `body` without every `every`-th active cell.
fn holed(body: &Body, every: usize) -> Body {
    let lattice = *body.lattice();
    let kept: Vec<CellId> = body
        .active_cells()
        .enumerate()
        .filter(|(i, _)| i % every != 2)
        .map(|(_, c)| c)
        .collect();
    let mut holed = Body::from_cells(lattice, kept).expect("cells left");
    holed
        .update_displacements(|node, _, u| {
            *u = body.displacement(node).expect("a node of the body")
        })
        .expect("finite");
    holed
}

/// `count` points of random cells at ξ whose components are −1, 0 or 1 (faces, edges, nodes and
/// centres: shared between cells, often of two ranks), from `seed`.
fn boundary_points(body: &Body, count: usize, seed: u64) -> Vec<DVec3> {
    let cells: Vec<CellId> = body.active_cells().collect();
    points_at_corners(&cells, |cell, xi| body.point_at(cell, xi), count, seed)
}

/// `count` points `point_at` gives for random `cells` at random ξ ∈ {−1, 0, 1}³, from `seed`.
fn points_at_corners(
    cells: &[CellId],
    point_at: impl Fn(CellId, DVec3) -> Option<DVec3>,
    count: usize,
    seed: u64,
) -> Vec<DVec3> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = |n: usize| {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 33) % n as u64) as usize
    };
    (0..count)
        .map(|_| {
            let cell = cells[next(cells.len())];
            let xi = DVec3::new(
                [-1.0, 0.0, 1.0][next(3)],
                [-1.0, 0.0, 1.0][next(3)],
                [-1.0, 0.0, 1.0][next(3)],
            );
            point_at(cell, xi).expect("a cell of the body")
        })
        .collect()
}
