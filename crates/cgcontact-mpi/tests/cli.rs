//! `mpirun -np P cgcontact-mpi locate` against `cgcontact locate`: the same results file, byte for
//! byte, for P = 1..4 and every partition, on scenes `cgcontact scene` writes, with points on the
//! cells' faces, edges and nodes. `CGCONTACT_BIN` names the `cgcontact` binary; without it the test
//! builds it from the main workspace (release, in a folder of this crate's target directory).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use cgcontact::CellId;
use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, MeshBody, read_body};

fn cgcontact() -> PathBuf {
    if let Some(bin) = std::env::var_os("CGCONTACT_BIN") {
        return PathBuf::from(bin);
    }
    // .../target/<profile>/deps/cli-HASH: the target folder is three levels up.
    let exe = std::env::current_exe().expect("the test's own path");
    let target = exe
        .ancestors()
        .nth(3)
        .expect("a target folder")
        .join("main-cli");
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../Cargo.toml");
    let status = Command::new(env!("CARGO"))
        .args([
            "build",
            "--release",
            "--locked",
            "-p",
            "cgcontact-cli",
            "--manifest-path",
        ])
        .arg(&manifest)
        .env("CARGO_TARGET_DIR", &target)
        .status()
        .expect("cargo runs");
    assert!(status.success(), "building cgcontact failed");
    target.join("release/cgcontact")
}

/// Whether this runs as root (Open MPI then wants to be told that it may).
fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|out| String::from_utf8_lossy(&out.stdout).trim() == "0")
}

fn mpirun(ranks: usize, args: &[&str]) -> Output {
    let mut command = Command::new("mpirun");
    command.arg("--oversubscribe");
    if is_root() {
        command.arg("--allow-run-as-root");
    }
    command
        .args(["-np", &ranks.to_string()])
        .arg(env!("CARGO_BIN_EXE_cgcontact-mpi"))
        .args(args)
        .output()
        .expect("mpirun runs: is Open MPI installed?")
}

fn run(command: &mut Command) {
    let out = command.output().expect("runs");
    assert!(
        out.status.success(),
        "{command:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The two cells of `cgcontact_scenes::hanging_node_moved(moved)` (the second refined once, its
/// first hanging node moved by `moved`) as `mesh.vtu` in `dir`, and the points `csv` as
/// `points.csv`.
fn two_cells(dir: &Path, moved: f64, csv: &str) -> (PathBuf, PathBuf) {
    let body = cgcontact_scenes::hanging_node_moved(moved).unwrap();
    let mesh = dir.join("mesh.vtu");
    cgcontact_io::write_adaptive_mesh(&mesh, &body, cgcontact_io::MeshFormat::Xml).unwrap();
    let points = dir.join("points.csv");
    std::fs::write(&points, csv).unwrap();
    (mesh, points)
}

/// A refusal: exit code 2 and one message, holding `cause`; returns the message.
fn refused_with(result: &Output, cause: &str) -> String {
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
    assert_eq!(result.status.code(), Some(2), "hung or went on: {stderr}");
    assert_eq!(stderr.matches("cgcontact-mpi:").count(), 1, "{stderr}");
    assert!(stderr.contains(cause), "{cause} not in {stderr}");
    stderr
}

/// [`refused_with`], before the mesh (a `missing.vtu`) was read.
fn refused_before_reading(result: &Output, cause: &str) {
    let stderr = refused_with(result, cause);
    assert!(
        !stderr.contains("missing.vtu"),
        "the mesh was read first: {stderr}"
    );
}

/// The point of a cell at ξ.
type PointAt<'a> = dyn Fn(CellId, DVec3) -> Option<DVec3> + 'a;

/// Points at ξ ∈ {−1, 0, 1}³ of the mesh's cells (faces, edges and nodes shared between cells,
/// so between ranks; on an adaptive mesh, between leaves of different levels), then the scene's
/// own points, as a CSV file.
fn with_boundary_points(mesh: &Path, scene_points: &Path, out: &Path, count: usize) {
    let mesh = read_body(mesh, &DisplacementArray::from_option(None)).unwrap();
    let (cells, point_at) = match &mesh {
        MeshBody::Uniform(mesh) => (
            mesh.body.active_cells().collect(),
            Box::new(|cell, xi| mesh.body.point_at(cell, xi)) as Box<PointAt<'_>>,
        ),
        MeshBody::Adaptive(mesh) => (
            (0..mesh.body.cell_count() as u32)
                .map(CellId)
                .collect::<Vec<_>>(),
            Box::new(|cell, xi| mesh.body.point_at(cell, xi)) as Box<PointAt<'_>>,
        ),
    };
    let mut text = String::from("x,y,z\n");
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    for _ in 0..count {
        let cell = cells[next(cells.len())];
        let xi = DVec3::new(
            [-1.0, 0.0, 1.0][next(3)],
            [-1.0, 0.0, 1.0][next(3)],
            [-1.0, 0.0, 1.0][next(3)],
        );
        let x = point_at(cell, xi).unwrap();
        text.push_str(&format!("{},{},{}\n", x.x, x.y, x.z));
    }
    let scene = std::fs::read_to_string(scene_points).unwrap();
    text.extend(scene.lines().skip(1).map(|line| format!("{line}\n")));
    std::fs::write(out, text).unwrap();
}

#[test]
fn results_files_are_byte_for_byte_those_of_cgcontact_locate() {
    let bin = cgcontact();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scenes: [(&str, &[&str]); 4] = [
        ("fine", &["sphere-fine"]),
        (
            "jitter",
            &[
                "sphere-coarse",
                "--jitter",
                "0.15",
                "--sink",
                "1.5",
                "--format",
                "vtk",
            ],
        ),
        (
            "block",
            &[
                "block",
                "--cells",
                "3,7,4",
                "--known",
                "3000",
                "--format",
                "vtk-binary",
            ],
        ),
        // Three levels, unbalanced (jumps of more than one level), leaves in random order, on
        // the coarse block's spacing.
        (
            "adaptive",
            &[
                "sphere-adaptive",
                "--h",
                "0.5",
                "--levels",
                "3",
                "--unbalanced",
                "--shuffle",
                "--known",
                "3000",
            ],
        ),
    ];
    for (name, scene) in scenes {
        let folder = d.join(name);
        run(Command::new(&bin)
            .arg("scene")
            .args(scene)
            .arg("--out")
            .arg(&folder));
        let mesh = ["mesh.vtu", "mesh.vtk"]
            .map(|f| folder.join(f))
            .into_iter()
            .find(|p| p.exists())
            .expect("the scene's mesh");
        let points = folder.join("all.csv");
        with_boundary_points(&mesh, &folder.join("points.csv"), &points, 3000);
        let runs = (1..=4)
            .flat_map(|ranks| ["slabs", "morton", "random"].map(|p| (ranks, p, false)))
            .chain([(1, "slabs", true), (3, "slabs", true), (2, "random", true)]);
        // With gaps within about two cells of these scenes.
        assert_mpi_writes_the_serial_file(&bin, name, &folder, &mesh, &points, "0.6", runs);
    }
}

/// Adaptive meshes printed by VTK's legacy ASCII writer (11 digits), whose hanging nodes lie off
/// their coarse faces by the print's rounding: the reader gives the body that seam, which the
/// locator's allowance takes. The ranks' local bodies did not have it: on the fixtures' own
/// points (nodes, edge midpoints, face centres), 3 ranks found no cell for 47 of aniso-1e3's 625
/// points that `cgcontact locate` located, and named another owner for 226 more (4 of jumps'
/// 406).
#[test]
fn results_files_are_the_serial_ones_on_meshes_printed_with_11_digits() {
    let bin = cgcontact();
    let dir = tempfile::tempdir().unwrap();
    let fixtures =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written-adaptive");
    for (name, gap) in [("aniso-1e3", "0.01"), ("jumps", "0.5")] {
        let folder = dir.path().join(name);
        std::fs::create_dir(&folder).unwrap();
        let mesh = fixtures.join(format!("{name}.legacy-ascii.vtk"));
        // The fixture's points (at nodes, edge midpoints and face centres), x, y and z only.
        let expected =
            std::fs::read_to_string(fixtures.join(format!("{name}.expected.csv"))).unwrap();
        let mut known = String::new();
        for line in expected.lines().filter(|l| !l.starts_with('#')) {
            let xyz: Vec<&str> = line.split(',').take(3).collect();
            known.push_str(&xyz.join(","));
            known.push('\n');
        }
        let known_path = folder.join("known.csv");
        std::fs::write(&known_path, known).unwrap();
        let points = folder.join("all.csv");
        with_boundary_points(&mesh, &known_path, &points, 1000);
        let runs = [2, 3, 4]
            .into_iter()
            .flat_map(|ranks| ["slabs", "morton", "random"].map(|p| (ranks, p, false)))
            .chain([(3, "random", true)]);
        assert_mpi_writes_the_serial_file(&bin, name, &folder, &mesh, &points, gap, runs);
    }
}

/// `cgcontact-mpi locate` on `mesh` and `points` under each of `runs` (ranks, partition, with
/// `--gap gap`) writes, byte for byte, the file `cgcontact locate` (`bin`) writes.
fn assert_mpi_writes_the_serial_file(
    bin: &Path,
    name: &str,
    folder: &Path,
    mesh: &Path,
    points: &Path,
    gap: &str,
    runs: impl Iterator<Item = (usize, &'static str, bool)>,
) {
    // `cgcontact locate` with `extra` flags: the file to match.
    let serial = |name: &str, extra: &[&str]| {
        let out = folder.join(name);
        run(Command::new(bin)
            .args(["locate", "--quiet"])
            .args(extra)
            .arg("--mesh")
            .arg(mesh)
            .arg("--points")
            .arg(points)
            .arg("--out")
            .arg(&out));
        std::fs::read(&out).unwrap()
    };
    let want = serial("serial.csv", &[]);
    let want_gaps = serial("serial-gaps.csv", &["--gap", gap]);
    for (ranks, partition, gaps) in runs {
        let out = folder.join(format!("mpi-{ranks}-{partition}-{gaps}.csv"));
        let mut args = vec![
            "locate",
            "--quiet",
            "--partition",
            partition,
            "--mesh",
            mesh.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        let want = if gaps {
            args.extend(["--gap", gap]);
            &want_gaps
        } else {
            &want
        };
        let result = mpirun(ranks, &args);
        assert!(
            result.status.success(),
            "{name}, {ranks} ranks, {partition}: {}",
            String::from_utf8_lossy(&result.stderr)
        );
        let got = std::fs::read(&out).unwrap();
        assert!(
            &got == want,
            "{name}, {ranks} ranks, {partition}, gaps {gaps}: {} differs from the serial file",
            out.display(),
        );
    }
}

/// A hanging node moved off its constraint: one warning naming the count and the worst node's
/// offset, as `cgcontact locate` gives it, or with `--strict` exit code 2 on every rank.
#[test]
fn a_broken_hanging_node_warns_once_and_strict_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(dir.path(), 0.01, "x,y,z\n0.5,0.5,0.5\n1.5,0.25,0.25\n");
    let out = dir.path().join("results.csv");
    let (mesh, points, out) = (
        mesh.to_str().unwrap(),
        points.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let args = ["locate", "--mesh", mesh, "--points", points, "--out", out];
    let run = mpirun(3, &args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(stderr.matches("warning").count(), 1, "{stderr}");
    assert!(
        stderr.contains("1 of 5 hanging nodes") && stderr.contains("1.000e-2"),
        "{stderr}"
    );
    let rows = std::fs::read_to_string(out).unwrap();
    // Both points located: a cell in every row.
    let located = rows
        .lines()
        .skip(1)
        .filter(|row| row.split(',').nth(1) != Some("-1"));
    assert_eq!(located.count(), 2, "{rows}");
    std::fs::remove_file(out).unwrap();
    let strict = mpirun(3, &[&args[..], &["--strict"]].concat());
    let stderr = String::from_utf8_lossy(&strict.stderr);
    assert_eq!(strict.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    assert_eq!(
        stderr.matches("break their constraint").count(),
        1,
        "{stderr}"
    );
    assert!(!Path::new(out).exists());
}

/// A thread count no machine has is capped, with one warning, and the search runs (before, each
/// rank asked rayon for that many threads).
#[test]
fn absurd_thread_counts_are_capped_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(dir.path(), 0.0, "x,y,z\n0.5,0.5,0.5\n");
    let out = dir.path().join("results.csv");
    let args = [
        "locate",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--threads",
        "100000000",
    ];
    let run = mpirun(2, &args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert_eq!(stderr.matches("capped at").count(), 1, "{stderr}");
    let rows = std::fs::read_to_string(&out).unwrap();
    assert_eq!(rows.lines().count(), 2, "{rows}");
}

#[test]
fn bad_input_stops_every_rank_with_one_message() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let points = d.join("points.csv");
    std::fs::write(&points, "x,y,z\n0,0,0\n").unwrap();
    let missing = d.join("missing.vtu");
    let out = d.join("results.csv");
    let cases: [Vec<&str>; 3] = [
        vec![
            "locate",
            "--mesh",
            missing.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
        ],
        vec![
            "locate",
            "--mesh",
            missing.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--out",
            points.to_str().unwrap(),
        ],
        vec![
            "locate",
            "--mesh",
            missing.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--block",
            "0",
        ],
    ];
    for args in cases {
        let result = mpirun(3, &args);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{args:?} succeeded");
        assert_eq!(
            stderr.matches("cgcontact-mpi:").count(),
            1,
            "{args:?}: one message, from one rank: {stderr}"
        );
    }
    assert!(!out.exists());
}

/// `--out` a hard link of `--points` (or of `--mesh`): refused before any work with one message,
/// as `cgcontact locate` refuses it, both names left one file with its content. Before, the
/// canonical paths differed, the run went on and the results' rename split the link.
#[test]
fn an_output_hard_linked_to_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let points = d.join("points.csv");
    let text = "x,y,z\n0.1,0.2,0.3\n";
    std::fs::write(&points, text).unwrap();
    let mesh = d.join("mesh.vtk");
    std::fs::write(&mesh, "not read: the check comes first\n").unwrap();
    for input in [&points, &mesh] {
        let link = d.join("results.csv");
        std::fs::hard_link(input, &link).unwrap();
        let before = std::fs::read(input).unwrap();
        let result = mpirun(
            2,
            &[
                "locate",
                "--mesh",
                mesh.to_str().unwrap(),
                "--points",
                points.to_str().unwrap(),
                "--out",
                link.to_str().unwrap(),
            ],
        );
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{input:?}: the run went on");
        assert_eq!(
            stderr.matches("cgcontact-mpi:").count(),
            1,
            "one message, from one rank: {stderr}"
        );
        assert!(stderr.contains("would be overwritten"), "{stderr}");
        use std::os::unix::fs::MetadataExt;
        let (a, b) = (
            std::fs::metadata(input).unwrap(),
            std::fs::metadata(&link).unwrap(),
        );
        assert_eq!((a.dev(), a.ino()), (b.dev(), b.ino()), "the link was split");
        assert_eq!(std::fs::read(input).unwrap(), before);
        std::fs::remove_file(&link).unwrap();
    }
    assert_eq!(std::fs::read_to_string(&points).unwrap(), text);
}

/// `--out` on a piece file of a parallel `--mesh` (directly, or through a symbolic link): refused
/// with one message naming the piece, and the piece left as it was, as `cgcontact locate`
/// refuses it. Before, the run replaced the piece with its results.
#[test]
fn an_output_on_a_piece_of_a_parallel_mesh_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixtures =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written-parallel");
    for name in [
        "split-appended.pvtu",
        "split-appended_0.vtu",
        "split-appended_1.vtu",
        "split-appended_2.vtu",
    ] {
        std::fs::copy(fixtures.join(name), d.join(name)).unwrap();
    }
    let points = d.join("points.csv");
    std::fs::write(&points, "x,y,z\n0.1,0.2,0.3\n").unwrap();
    let piece = d.join("split-appended_1.vtu");
    let before = std::fs::read(&piece).unwrap();
    let link = d.join("results.csv");
    std::os::unix::fs::symlink(&piece, &link).unwrap();
    for out in [&piece, &link] {
        let result = mpirun(
            2,
            &[
                "locate",
                "--mesh",
                d.join("split-appended.pvtu").to_str().unwrap(),
                "--points",
                points.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
        );
        let stderr = refused_with(&result, "would be overwritten");
        assert!(stderr.contains("piece 1"), "{stderr}");
        assert_eq!(
            std::fs::read(&piece).unwrap(),
            before,
            "{out:?}: the piece was replaced"
        );
    }
}

/// `--out` in a folder rank 0 cannot write in (here /proc, where no file can be made, even by
/// root): refused before any file is read, with one message naming the folder, as `cgcontact
/// locate` refuses it. Before, every rank read the mesh (here a missing one, whose error came
/// first) and searched, and only the final write failed.
#[test]
fn an_unwritable_output_folder_is_refused_before_any_file_is_read() {
    if !Path::new("/proc").is_dir() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n0,0,0\n").unwrap();
    let missing = dir.path().join("missing.vtu");
    let args = [
        "locate",
        "--mesh",
        missing.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--out",
        "/proc/results.csv",
    ];
    let serial = Command::new(cgcontact()).args(args).output().unwrap();
    let serial_stderr = String::from_utf8_lossy(&serial.stderr);
    assert_eq!(serial.status.code(), Some(2), "{serial_stderr}");
    assert!(
        serial_stderr.contains("cannot write in /proc"),
        "{serial_stderr}"
    );
    for ranks in [1, 3] {
        refused_before_reading(&mpirun(ranks, &args), "cannot write in /proc");
    }
}

/// What `cgcontact locate` takes of the flags the two share, this takes alike: `--gap` with a
/// negative number is refused with the serial message (before, clap read `-1` as an unknown
/// flag), and `-q` is `--quiet` (before, an unknown flag).
#[test]
fn shared_flags_are_taken_as_cgcontact_locate_takes_them() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(dir.path(), 0.0, "x,y,z\n0.5,0.5,0.5\n");
    let base = [
        "locate",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
    ];
    let negative = [&base[..], &["--gap", "-1"]].concat();
    let serial = Command::new(cgcontact()).args(&negative).output().unwrap();
    let serial_stderr = String::from_utf8_lossy(&serial.stderr);
    assert_eq!(serial.status.code(), Some(2), "{serial_stderr}");
    let message = serial_stderr
        .trim()
        .strip_prefix("cgcontact: error: ")
        .expect("one error line");
    let result = mpirun(2, &negative);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.matches(message).count(), 1, "{message} in {stderr}");
    let quiet = mpirun(2, &[&base[..], &["-q"]].concat());
    let stderr = String::from_utf8_lossy(&quiet.stderr);
    assert!(quiet.status.success(), "{stderr}");
    assert!(
        quiet.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&quiet.stdout)
    );
}

/// The `cgcontact: warning: ...` lines of `stderr` (or `cgcontact-mpi: warning: ...`), without
/// the prefix.
fn warnings(stderr: &[u8]) -> Vec<String> {
    String::from_utf8_lossy(stderr)
        .lines()
        .filter_map(|line| line.split_once(": warning: ").map(|(_, w)| w.to_owned()))
        .collect()
}

/// A mesh with inverted cells, and one with cells f64 cannot resolve: `cgcontact locate` warns
/// that answers there are not to be trusted; so must this, in the same words, naming the same
/// input cells, once (rank 0), and not with `--quiet`. Before, it warned of neither: the same
/// untrusted answers came back without a word.
#[test]
fn cell_warnings_are_those_of_cgcontact_locate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 3 × 2 × 2 cells of h = 1 whose middle node (1, 1, 1) is pushed through its neighbours.
    let lattice = cgcontact::Lattice::new(DVec3::ZERO, DVec3::ONE, [3, 2, 2]).unwrap();
    let mut inverted = cgcontact::Body::full(lattice);
    inverted
        .update_displacements(|_, x, u| {
            if x == DVec3::ONE {
                *u = DVec3::splat(-1.6);
            }
        })
        .unwrap();
    let inverted_mesh = d.join("inverted.vtk");
    cgcontact_io::write_mesh(
        &inverted_mesh,
        &inverted,
        cgcontact_io::MeshFormat::LegacyAscii,
    )
    .unwrap();
    // Two cells at 1e7 from the origin, 1.6e-5 thin along z, sheared by u_z = 1e3 (y − y0): a
    // rounding of y moves ξ_z by about 1.1 (`cgcontact locate`'s own test of this warning).
    let origin = -1e7;
    let h = DVec3::new(0.03125, 0.001953125, 1.5625e-5);
    let lattice = cgcontact::Lattice::new(DVec3::splat(origin), h, [1, 1, 2]).unwrap();
    let mut sheared = cgcontact::Body::full(lattice);
    sheared
        .update_displacements(|_, x, u| *u = DVec3::new(0.0, 0.0, 1e3 * (x.y - origin)))
        .unwrap();
    let sheared_mesh = d.join("sheared.vtu");
    cgcontact_io::write_mesh(&sheared_mesh, &sheared, cgcontact_io::MeshFormat::Xml).unwrap();
    let points = d.join("points.csv");
    std::fs::write(
        &points,
        "x,y,z\n0.5,0.5,0.5\n-1e7,-1e7,-9999999.999976562\n",
    )
    .unwrap();
    for mesh in [&inverted_mesh, &sheared_mesh] {
        assert_warns_as_cgcontact_locate(mesh, &points, 1);
    }
}

/// `locate --mesh mesh --points points` warns `count` times under `cgcontact locate`, and on 1
/// and 3 ranks gives the same warnings in the same words, once (rank 0), and none with `--quiet`.
fn assert_warns_as_cgcontact_locate(mesh: &Path, points: &Path, count: usize) {
    let args = [
        "locate",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
    ];
    let serial = Command::new(cgcontact()).args(args).output().unwrap();
    assert!(serial.status.success(), "{serial:?}");
    let want = warnings(&serial.stderr);
    assert_eq!(want.len(), count, "{mesh:?}: {want:?}");
    for ranks in [1, 3] {
        let result = mpirun(ranks, &args);
        assert!(result.status.success(), "{result:?}");
        assert_eq!(warnings(&result.stderr), want, "{mesh:?}, {ranks} ranks");
        let quiet = mpirun(ranks, &[&args[..], &["--quiet"]].concat());
        assert!(quiet.status.success(), "{quiet:?}");
        assert!(warnings(&quiet.stderr).is_empty(), "{quiet:?}");
    }
}

/// A points file whose last line has no line end (a file cut inside its last number reads as
/// another number): the warning `cgcontact locate` gives, in its words, once (rank 0), and not
/// with `--quiet`; none for the file with its line end.
#[test]
fn an_unended_points_file_is_warned_about_as_cgcontact_locate_warns() {
    let dir = tempfile::tempdir().unwrap();
    for (csv, warned) in [
        ("x,y,z\n0.5,0.5,0.5\n0.25,0.5,0.75", true),
        ("x,y,z\n0.5,0.5,0.5\n0.25,0.5,0.75\n", false),
    ] {
        let (mesh, points) = two_cells(dir.path(), 0.0, csv);
        assert_warns_as_cgcontact_locate(&mesh, &points, usize::from(warned));
    }
}

/// The summary on a standard output that cannot take it, the binary started without mpirun (a
/// singleton, where the rank's standard output is the caller's): on a full device, exit code 2
/// and one line saying so, as `cgcontact locate` gives; on a closed pipe, exit code 0. Before,
/// `println!` panicked and the panic hook aborted the run with a panic message, exit code 2 for
/// a closed pipe too. (Under mpirun the failure happens in mpirun, which drops it: Open MPI's
/// mpirun exits 0 on `> /dev/full` whatever the ranks do.)
#[test]
fn a_full_or_closed_standard_output_ends_as_cgcontact_locate_ends() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(dir.path(), 0.0, "x,y,z\n0.5,0.5,0.5\n");
    let args = [
        "locate",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
    ];
    let singleton = || {
        let mut command = Command::new(env!("CARGO_BIN_EXE_cgcontact-mpi"));
        command.args(args).stdin(std::process::Stdio::null());
        if is_root() {
            command.env("OMPI_ALLOW_RUN_AS_ROOT", "1");
            command.env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
        }
        command
    };
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let serial = Command::new(cgcontact())
        .args(args)
        .stdout(full())
        .output()
        .unwrap();
    assert_eq!(serial.status.code(), Some(2), "{serial:?}");
    let result = singleton().stdout(full()).output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        stderr
            .matches("cgcontact-mpi: cannot write to standard output")
            .count(),
        1,
        "{stderr}"
    );
    // A reader gone before the summary: a normal end.
    let mut child = singleton()
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let result = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(result.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `--json --quiet`: the JSON object and nothing else, as `cgcontact locate --json --quiet`
/// prints it. Before, `--quiet` dropped the JSON too, without a word.
#[test]
fn json_with_quiet_still_prints_the_json() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(
        dir.path(),
        0.0,
        "x,y,z\n0.5,0.5,0.5\n1.5,0.25,0.25\n9,9,9\n",
    );
    let args = [
        "locate",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--json",
        "--quiet",
    ];
    let serial = Command::new(cgcontact()).args(args).output().unwrap();
    let serial_out = String::from_utf8_lossy(&serial.stdout);
    assert!(serial_out.trim_start().starts_with('{'), "{serial_out}");
    let result = mpirun(2, &args);
    let stdout = String::from_utf8_lossy(&result.stdout);
    assert!(result.status.success(), "{result:?}");
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(
        stdout.starts_with('{') && stdout.contains("\"points\": 3"),
        "{stdout}"
    );
}

/// mpirun's MPMD form: `ranks` ranks started in `folder` with `args`, for each part, under a
/// 120 s limit (coreutils `timeout`: exit code 124 when it struck, the run having hung).
fn mpirun_parts(parts: &[(usize, &Path, Vec<&str>)]) -> Output {
    let mut command = Command::new("timeout");
    command.args(["-k", "10", "120", "mpirun", "--oversubscribe"]);
    if is_root() {
        command.arg("--allow-run-as-root");
    }
    for (at, (ranks, folder, args)) in parts.iter().enumerate() {
        if at > 0 {
            command.arg(":");
        }
        command
            .args(["-np", &ranks.to_string(), "-wdir"])
            .arg(folder)
            .arg(env!("CARGO_BIN_EXE_cgcontact-mpi"))
            .args(args);
    }
    command.output().expect("timeout and mpirun run")
}

/// Ranks given different arguments (mpirun's `:` form) or reading different files under one
/// name (each node its own copy; here each rank its own working folder): refused on every rank
/// with one message naming the cause, and no results file. Before, another `--repeat` on one
/// rank hung the run (the others waited in a collective it never entered), and points files of
/// other lengths gave a results file of the wrong rows.
#[test]
fn ranks_given_different_arguments_or_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let lattice = cgcontact::Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 3, 2]).unwrap();
    let mut body = cgcontact::Body::full(lattice);
    body.update_displacements(|_, x, u| *u = DVec3::new(0.1 * x.y, 0.0, 0.05 * x.x))
        .unwrap();
    let (a, b) = (d.join("a"), d.join("b"));
    let out = d.join("results.csv");
    let points = (0..30)
        .map(|i| {
            format!(
                "{},{},{}\n",
                0.1 * f64::from(i % 3),
                0.1 * f64::from(i),
                0.5
            )
        })
        .collect::<String>();
    for (folder, rows) in [(&a, 30), (&b, 20)] {
        std::fs::create_dir(folder).unwrap();
        cgcontact_io::write_mesh(
            folder.join("mesh.vtu"),
            &body,
            cgcontact_io::MeshFormat::Xml,
        )
        .unwrap();
        let rows: String = points
            .lines()
            .take(rows)
            .map(|l| format!("{l}\n"))
            .collect();
        std::fs::write(folder.join("points.csv"), format!("x,y,z\n{rows}")).unwrap();
    }
    // The same arguments (but --threads), run in one folder: the serial file, byte for byte.
    let args = vec![
        "locate",
        "--mesh",
        "mesh.vtu",
        "--points",
        "points.csv",
        "--out",
        out.to_str().unwrap(),
    ];
    let with = |extra: &[&'static str]| [&args[..], extra].concat();
    let same = mpirun_parts(&[(1, &a, with(&["--threads", "2"])), (2, &a, args.clone())]);
    assert!(same.status.success(), "{same:?}");
    let serial = d.join("serial.csv");
    run(Command::new(cgcontact())
        .current_dir(&a)
        .args([
            "locate",
            "--quiet",
            "--mesh",
            "mesh.vtu",
            "--points",
            "points.csv",
        ])
        .arg("--out")
        .arg(&serial));
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&serial).unwrap()
    );
    std::fs::remove_file(&out).unwrap();
    let refused = |result: Output, cause: &str| {
        let stderr = refused_with(&result, cause);
        assert!(!out.exists(), "{stderr}");
    };
    refused(
        mpirun_parts(&[(1, &a, with(&["--repeat", "2"])), (2, &a, args.clone())]),
        "different arguments",
    );
    refused(
        mpirun_parts(&[(1, &a, args.clone()), (1, &a, with(&["--gap", "0.5"]))]),
        "different arguments",
    );
    // Points files of 30 and 20 rows.
    refused(
        mpirun_parts(&[(1, &a, args.clone()), (2, &b, args.clone())]),
        "points.csv: the ranks read different contents",
    );
    // Meshes one displacement apart.
    body.update_displacements(|_, x, u| {
        if x == DVec3::ONE {
            u.z += 1e-9;
        }
    })
    .unwrap();
    cgcontact_io::write_mesh(b.join("mesh.vtu"), &body, cgcontact_io::MeshFormat::Xml).unwrap();
    std::fs::copy(a.join("points.csv"), b.join("points.csv")).unwrap();
    refused(
        mpirun_parts(&[(2, &a, args.clone()), (1, &b, args.clone())]),
        "mesh.vtu: the ranks read different contents",
    );
}

/// `--gap` beyond the core gap finder's limit (`MAX_DISPLACEMENT`): refused with the other flags,
/// before any file is read (here a missing mesh, whose error would otherwise come first). Before,
/// it was taken, every rank's halo spanned the lattice, and the run failed at the gap query,
/// after the search.
#[test]
fn a_gap_beyond_the_core_limit_is_refused_before_any_file_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n0,0,0\n").unwrap();
    let missing = dir.path().join("missing.vtu");
    let beyond = format!("{:e}", cgcontact::MAX_DISPLACEMENT * 10.0);
    let result = mpirun(
        2,
        &[
            "locate",
            "--mesh",
            missing.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--gap",
            &beyond,
        ],
    );
    refused_before_reading(&result, "--gap");
}

/// `--points /dev/stdin` (or any pipe) over several ranks: mpirun gives standard input to rank 0
/// alone, so the other ranks read nothing. Refused with one message saying why, before any
/// file is read; one rank reads it as `cgcontact locate` does. Before, the message was
/// `/dev/stdin: no data rows`, from a rank that had been given none.
#[test]
fn points_from_a_pipe_are_refused_over_several_ranks_with_the_reason() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let csv = "x,y,z\n0.5,0.5,0.5\n1.5,0.25,0.25\n";
    let (mesh, points) = two_cells(dir.path(), 0.0, csv);
    let with_stdin = |ranks: usize, out: &Path| {
        let mut command = Command::new("mpirun");
        command.arg("--oversubscribe");
        if is_root() {
            command.arg("--allow-run-as-root");
        }
        let mut child = command
            .args(["-np", &ranks.to_string()])
            .arg(env!("CARGO_BIN_EXE_cgcontact-mpi"))
            .args(["locate", "--quiet", "--points", "/dev/stdin", "--mesh"])
            .arg(&mesh)
            .arg("--out")
            .arg(out)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // mpirun may not read it all before the ranks stop: a closed pipe is no failure here.
        let _ = child.stdin.take().unwrap().write_all(csv.as_bytes());
        child.wait_with_output().unwrap()
    };
    let out = dir.path().join("results.csv");
    let result = with_stdin(2, &out);
    refused_with(&result, "not a regular file");
    assert!(!out.exists());
    // One rank: the serial file.
    let serial = dir.path().join("serial.csv");
    run(Command::new(cgcontact())
        .args(["locate", "--quiet", "--mesh"])
        .arg(&mesh)
        .arg("--points")
        .arg(&points)
        .arg("--out")
        .arg(&serial));
    let result = with_stdin(1, &out);
    assert!(result.status.success(), "{result:?}");
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&serial).unwrap()
    );
}

/// The number after `"key": ` in a JSON text.
fn json_count(json: &str, key: &str) -> Option<u64> {
    let at = json.find(&format!("\"{key}\": "))? + key.len() + 4;
    json[at..]
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

/// Points with NaN or infinite coordinates are counted apart, as `cgcontact locate` counts them:
/// `not_located` and `invalid_points` in `--json` are the serial command's. Before, they were
/// counted as not located, and `--json` had neither field.
#[test]
fn points_with_nan_coordinates_are_counted_as_cgcontact_locate_counts_them() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, points) = two_cells(
        dir.path(),
        0.0,
        "x,y,z\n0.5,0.5,0.5\nNaN,0,0\n9,9,9\ninf,1,1\n1.5,0.25,0.25\n-9,0,0\n",
    );
    let args = [
        "locate",
        "--json",
        "--mesh",
        mesh.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
    ];
    let serial = Command::new(cgcontact()).args(args).output().unwrap();
    let serial = String::from_utf8_lossy(&serial.stdout);
    for ranks in [1, 3] {
        let result = mpirun(ranks, &args);
        assert!(result.status.success(), "{result:?}");
        let json = String::from_utf8_lossy(&result.stdout);
        for key in ["located", "not_located", "invalid_points"] {
            let want = json_count(&serial, key);
            assert!(want.is_some(), "{key} in {serial}");
            assert_eq!(json_count(&json, key), want, "{key}, {ranks} ranks: {json}");
        }
    }
}

/// A flag clap refuses is reported by rank 0 alone, whichever launcher set the rank (its
/// variables are read before MPI starts), and by a process run alone.
#[test]
fn a_refused_flag_is_reported_by_rank_0_alone_under_any_launcher() {
    let bad = ["locate", "--no-such-flag"];
    let launchers = [
        "OMPI_COMM_WORLD_RANK",
        "PMIX_RANK",
        "PMI_RANK",
        "MV2_COMM_WORLD_RANK",
        "SLURM_PROCID",
    ];
    let run = |vars: &[(&str, &str)]| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_cgcontact-mpi"));
        for name in launchers {
            command.env_remove(name);
        }
        let out = command
            .args(bad)
            .envs(vars.iter().copied())
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{vars:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(run(&[]).contains("--no-such-flag"));
    for name in launchers {
        assert!(run(&[(name, "0")]).contains("--no-such-flag"), "{name}=0");
        assert_eq!(run(&[(name, "3")]), "", "{name}=3");
    }
}

/// SIGTERM or Ctrl-C while rank 0 writes the results: the rank exits with 130, silently (mpirun
/// reports the interruption; when it terminates the ranks because one refused its input, that
/// rank's message stays the run's one line, as `bad_input_stops_every_rank_with_one_message`
/// checks), the output is as it was, and no hidden temporary file is left beside it. Before, the
/// rank had no handler: killed in the middle of its write, it left its `.partial` file (found by
/// an audit: three of three runs ended by SIGTERM to every rank).
///
/// Deterministic: the run (a singleton, so that the test signals the rank itself) is stopped
/// (SIGSTOP) as soon as its temporary file appears, then sent the signal and continued.
#[cfg(target_os = "linux")]
#[test]
fn a_rank_interrupted_while_writing_leaves_no_temporary_file() {
    use std::fmt::Write as _;
    let dir = tempfile::tempdir().unwrap();
    // 300,000 points in two cells: a results file of about 20 MB, written over tens of ms.
    let mut csv = String::from("x,y,z\n");
    for k in 0..300_000u32 {
        let t = f64::from(k) / 300_000.0;
        writeln!(
            csv,
            "{},{},{}",
            0.05 + 1.9 * t,
            0.5 + 0.4 * (t * 7.0).sin(),
            0.3
        )
        .unwrap();
    }
    let (mesh, points) = two_cells(dir.path(), 0.0, &csv);
    let out = dir.path().join("results.csv");
    let kill = |signal: &str, pid: u32| {
        let sent = Command::new("kill")
            .args([signal, &pid.to_string()])
            .status()
            .unwrap();
        assert!(sent.success(), "kill {signal}");
    };
    let partials = || -> Vec<String> {
        std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|name| name.ends_with(".partial"))
            .collect()
    };
    let mut caught = 0;
    for signal in ["-TERM", "-INT", "-TERM", "-INT"] {
        std::fs::write(&out, "old\n").unwrap();
        let mut command = Command::new(env!("CARGO_BIN_EXE_cgcontact-mpi"));
        command
            .args(["locate", "--mesh", mesh.to_str().unwrap()])
            .args([
                "--points",
                points.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped());
        if is_root() {
            command.env("OMPI_ALLOW_RUN_AS_ROOT", "1");
            command.env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
        }
        let run = command.spawn().unwrap();
        let start = std::time::Instant::now();
        let mut stopped = false;
        while start.elapsed() < std::time::Duration::from_secs(60) {
            if !partials().is_empty() {
                kill("-STOP", run.id());
                stopped = true;
                break;
            }
            if std::fs::read_to_string(&out).is_ok_and(|text| text != "old\n") {
                break;
            }
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        if stopped && !partials().is_empty() {
            // Stopped in the middle of the write: the signal comes then.
            caught += 1;
            kill(signal, run.id());
            kill("-CONT", run.id());
            let output = run.wait_with_output().unwrap();
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert_eq!(output.status.code(), Some(130), "{signal}: {stderr}");
            assert!(!stderr.contains("cgcontact-mpi"), "{signal}: {stderr}");
            assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n", "{signal}");
            assert_eq!(partials(), Vec::<String>::new(), "{signal}");
        } else {
            // The write finished first (or the run was stopped between two steps of it).
            if stopped {
                kill("-CONT", run.id());
            }
            let output = run.wait_with_output().unwrap();
            assert!(
                output.status.success(),
                "{}",
                String::from_utf8_lossy(&output.stderr)
            );
        }
    }
    assert!(caught > 0, "no run was caught in the middle of its write");
}
