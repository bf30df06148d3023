//! Nothing lost: an output never replaces an input, a bad output target fails before any work,
//! standard output closing early is a normal end, and flags are checked before any file is read.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn cgcontact(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A folder with a small scene: `mesh.vtu`, `points.csv`.
fn scene() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap().to_owned();
    let made = cgcontact(&[
        "scene", "block", "--cells", "3,3,2", "--known", "50", "--out", &out,
    ]);
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    let (mesh, points) = (dir.path().join("mesh.vtu"), dir.path().join("points.csv"));
    (dir, mesh, points)
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// `cgcontact locate --mesh MESH --points POINTS` and `extra`.
fn locate(mesh: &Path, points: &Path, extra: &[&str]) -> Output {
    cgcontact(
        &[
            &["locate", "--mesh", s(mesh), "--points", s(points)][..],
            extra,
        ]
        .concat(),
    )
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Exit code 2, one line naming `names`, and the files in `kept` byte for byte as before.
fn refused(output: &Output, names: &[&str], kept: &[(&Path, &[u8])]) {
    let message = stderr(output);
    assert_eq!(output.status.code(), Some(2), "{message}");
    assert_eq!(message.lines().count(), 1, "{message}");
    for name in names {
        assert!(message.contains(name), "{name} not in: {message}");
    }
    for (path, bytes) in kept {
        assert_eq!(
            &std::fs::read(path).unwrap()[..],
            *bytes,
            "{} changed",
            path.display()
        );
    }
}

#[test]
fn out_equal_to_the_points_is_refused_and_the_points_kept() {
    let (_dir, mesh, points) = scene();
    let before = std::fs::read(&points).unwrap();
    let run = locate(&mesh, &points, &["--out", s(&points)]);
    refused(
        &run,
        &["--out", "--points", "points.csv"],
        &[(&points, &before)],
    );
}

#[cfg(unix)]
#[test]
fn out_through_a_symlink_or_a_hard_link_to_the_mesh_is_refused() {
    let (dir, mesh, points) = scene();
    let before = std::fs::read(&mesh).unwrap();
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&mesh, &link).unwrap();
    let run = locate(&mesh, &points, &["--out", s(&link)]);
    refused(
        &run,
        &["link.csv", "--mesh", "mesh.vtu"],
        &[(&mesh, &before)],
    );
    let hard = dir.path().join("hard.csv");
    std::fs::hard_link(&mesh, &hard).unwrap();
    let run = locate(&mesh, &points, &["--out", s(&hard)]);
    refused(&run, &["hard.csv", "--mesh"], &[(&mesh, &before)]);
}

/// A parallel file naming the pieces `sources` (relative to its folder), beside them in `dir`.
fn parallel_file(dir: &Path, sources: &[&str]) -> PathBuf {
    let pieces: String = sources
        .iter()
        .map(|source| format!("    <Piece Source=\"{source}\"/>\n"))
        .collect();
    let path = dir.join("p.pvtu");
    std::fs::write(
        &path,
        format!(
            "<?xml version=\"1.0\"?>\n\
             <VTKFile type=\"PUnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n\
             <PUnstructuredGrid GhostLevel=\"0\">\n\
             <PPointData>\n\
             <PDataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\"/>\n\
             </PPointData>\n\
             <PPoints>\n\
             <PDataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"/>\n\
             </PPoints>\n\
             {pieces}</PUnstructuredGrid>\n\
             </VTKFile>\n"
        ),
    )
    .unwrap();
    path
}

/// The files of a parallel mesh's pieces are inputs as much as the mesh is: `--out p_0.vtu` with
/// `--mesh p.pvtu` replaced the piece with the results (exit code 0, the mesh lost), and so did
/// `--vtk DIR` when a piece was `DIR/mesh.vtu`, and an `--out` link to a piece. Now each is
/// refused before the pieces are read or any work is done, naming the output and the piece.
#[cfg(unix)]
#[test]
fn outputs_on_a_piece_of_a_parallel_mesh_are_refused() {
    let (dir, mesh, points) = scene();
    let before = std::fs::read(&mesh).unwrap();
    let parallel = parallel_file(dir.path(), &["mesh.vtu"]);
    let run = locate(&parallel, &points, &["--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let names = ["--out", "mesh.vtu", "piece 0", "--mesh", "p.pvtu"];
    let run = locate(&parallel, &points, &["--out", s(&mesh)]);
    refused(&run, &names, &[(&mesh, &before)]);
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&mesh, &link).unwrap();
    let run = locate(&parallel, &points, &["--out", s(&link)]);
    refused(
        &run,
        &[&["link.csv"][..], &names].concat(),
        &[(&mesh, &before)],
    );
    // A piece in the --vtk folder, the other outputs fine: nothing is written.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::copy(&mesh, out.join("mesh.vtu")).unwrap();
    let parallel = parallel_file(dir.path(), &["out/mesh.vtu"]);
    let results = dir.path().join("results.csv");
    let run = locate(
        &parallel,
        &points,
        &["--vtk", s(&out), "--out", s(&results)],
    );
    refused(
        &run,
        &["--vtk", "out/mesh.vtu", "piece 0", "p.pvtu"],
        &[(&out.join("mesh.vtu"), &before)],
    );
    assert!(!results.exists() && !out.join("points.vtu").exists());
}

#[test]
fn vtk_folder_holding_the_input_mesh_is_refused() {
    let (dir, mesh, points) = scene();
    let before = std::fs::read(&mesh).unwrap();
    let run = locate(&mesh, &points, &["--vtk", s(dir.path())]);
    refused(&run, &["--vtk", "--mesh", "mesh.vtu"], &[(&mesh, &before)]);
}

/// Before, the results were written and then `--vtk` failed: now nothing is written.
#[test]
fn vtk_naming_a_file_fails_before_the_results_are_written() {
    let (dir, mesh, points) = scene();
    let results = dir.path().join("results.csv");
    std::fs::write(&results, "previous results\n").unwrap();
    let not_a_folder = dir.path().join("a-file");
    std::fs::write(&not_a_folder, "x").unwrap();
    let run = locate(
        &mesh,
        &points,
        &["--out", s(&results), "--vtk", s(&not_a_folder)],
    );
    refused(
        &run,
        &["a-file", "not a folder"],
        &[(&results, b"previous results\n")],
    );
}

#[test]
fn out_in_a_missing_folder_fails_before_the_mesh_is_read() {
    let (dir, _mesh, points) = scene();
    let missing = dir.path().join("no-such-folder").join("results.csv");
    let no_mesh = Path::new("/no/such/mesh.vtu");
    let run = locate(no_mesh, &points, &["--out", s(&missing)]);
    refused(&run, &["no-such-folder", "does not exist"], &[]);
}

#[test]
fn settings_are_checked_before_any_file_is_read() {
    let (no_mesh, no_points) = (
        Path::new("/no/such/mesh.vtu"),
        Path::new("/no/such/points.csv"),
    );
    refused(
        &locate(no_mesh, no_points, &["--threads", "0"]),
        &["--threads"],
        &[],
    );
    refused(&locate(no_mesh, no_points, &["--tol=-1"]), &["--tol"], &[]);
}

/// A full disk under the VTK writer is named as such (it read "Deserialization error"), and the
/// results file is never left half written.
#[cfg(target_os = "linux")]
#[test]
fn full_disk_is_reported_as_no_space_left() {
    let (dir, mesh, points) = scene();
    let vtk = dir.path().join("vtk");
    std::fs::create_dir(&vtk).unwrap();
    std::os::unix::fs::symlink("/dev/full", vtk.join("mesh.vtu")).unwrap();
    let run = locate(&mesh, &points, &["--vtk", s(&vtk)]);
    refused(&run, &["mesh.vtu", "No space left on device"], &[]);
    let full = dir.path().join("full.csv");
    std::os::unix::fs::symlink("/dev/full", &full).unwrap();
    let run = locate(&mesh, &points, &["--out", s(&full)]);
    refused(&run, &["full.csv", "No space left on device"], &[]);
}

/// `cgcontact ... --json | head -c 1`: the reader goes away, the tool ends quietly with success.
#[test]
fn closed_stdout_is_a_quiet_end() {
    let (_dir, mesh, points) = scene();
    let mut child = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args([
            "locate",
            "--mesh",
            s(&mesh),
            "--points",
            s(&points),
            "--json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Close the read end before the tool writes anything.
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(stderr(&output).is_empty(), "{}", stderr(&output));
}

/// Standard output on a full device is an error with a message (it was "internal error").
#[cfg(target_os = "linux")]
#[test]
fn full_stdout_is_an_error() {
    let (_dir, mesh, points) = scene();
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args([
            "locate",
            "--mesh",
            s(&mesh),
            "--points",
            s(&points),
            "--json",
        ])
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    refused(
        &output,
        &["standard output", "No space left on device"],
        &[],
    );
}

/// `--threads 100000` started over 1,700 threads: now at most 4 per available core, with a warning.
#[test]
fn absurd_thread_counts_are_capped_with_a_warning() {
    let (_dir, mesh, points) = scene();
    let run = locate(&mesh, &points, &["--threads", "100000", "--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).contains("capped"), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let cores = std::thread::available_parallelism().map_or(1, usize::from) as u64;
    assert!(
        summary["threads"].as_u64().unwrap() <= 4 * cores,
        "{summary}"
    );
}

#[test]
fn loose_newton_tolerance_is_warned() {
    let (_dir, mesh, points) = scene();
    let run = locate(&mesh, &points, &["--tol", "10"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("warning: --tol 10"),
        "{}",
        stderr(&run)
    );
    let quiet = locate(&mesh, &points, &["--tol", "1e-8"]);
    assert!(stderr(&quiet).is_empty(), "{}", stderr(&quiet));
}

/// A results file replaced by a run is replaced whole: no temporary file is left beside it.
#[test]
fn results_replace_the_old_file_whole() {
    let (dir, mesh, points) = scene();
    let results = dir.path().join("results.csv");
    std::fs::write(&results, "previous results\n").unwrap();
    let run = locate(&mesh, &points, &["--out", s(&results), "-q"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let rows = cgcontact_io::read_results(&results).unwrap();
    assert_eq!(
        rows.len(),
        cgcontact_io::read_points(&points).unwrap().len()
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty());
}

/// `--out` with a name of 240 to 255 bytes passed the checks, then failed after the whole run:
/// its temporary name `.NAME.XXXXXX.partial` was 16 bytes past the limit ("File name too long").
/// Such names are written; a name past the limit is refused before the mesh is read.
#[test]
fn out_names_near_the_length_limit_are_written_and_past_it_refused_first() {
    let (dir, mesh, points) = scene();
    for length in [245, 255] {
        let results = dir.path().join(format!("{}.csv", "r".repeat(length - 4)));
        let run = locate(&mesh, &points, &["--out", s(&results), "-q"]);
        assert!(run.status.success(), "{length}: {}", stderr(&run));
        assert_eq!(
            cgcontact_io::read_results(&results).unwrap().len(),
            cgcontact_io::read_points(&points).unwrap().len()
        );
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(leftovers.is_empty());
    let too_long = dir.path().join(format!("{}.csv", "r".repeat(252)));
    let no_mesh = Path::new("/no/such/mesh.vtu");
    let run = locate(no_mesh, &points, &["--out", s(&too_long)]);
    refused(&run, &["256 bytes", "--out"], &[]);
}

/// `--out` naming a symbolic link to a file not made yet replaced the link with a regular file
/// and never made its target, though links are written through. Now the target is made (the
/// link kept), and a link whose target's folder does not exist is refused before any work.
#[cfg(unix)]
#[test]
fn out_through_a_dangling_symlink_makes_its_target() {
    let (dir, mesh, points) = scene();
    let link = dir.path().join("results.csv");
    let target = dir.path().join("made.csv");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let run = locate(&mesh, &points, &["--out", s(&link), "-q"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(
        cgcontact_io::read_results(&target).unwrap().len(),
        cgcontact_io::read_points(&points).unwrap().len()
    );

    let nowhere = dir.path().join("nowhere.csv");
    std::os::unix::fs::symlink(dir.path().join("no-such-folder/x.csv"), &nowhere).unwrap();
    let no_mesh = Path::new("/no/such/mesh.vtu");
    let run = locate(no_mesh, &points, &["--out", s(&nowhere)]);
    refused(
        &run,
        &["symbolic link", "no-such-folder", "does not exist"],
        &[],
    );
    assert!(
        std::fs::symlink_metadata(&nowhere)
            .unwrap()
            .file_type()
            .is_symlink()
    );
}

/// A legacy file cut just before `POINT_DATA` is a valid undeformed mesh: the summary says it has no
/// displacement (text and `--json`), where it used to look like any other run.
#[test]
fn mesh_read_without_displacement_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let made = cgcontact(&[
        "scene", "block", "--cells", "3,3,2", "--known", "50", "--format", "vtk", "--out", out,
    ]);
    assert!(made.status.success(), "{}", stderr(&made));
    let text = std::fs::read_to_string(dir.path().join("mesh.vtk")).unwrap();
    let cut = &text[..text
        .find("POINT_DATA")
        .expect("the scene has a displacement")];
    let mesh = dir.path().join("cut.vtk");
    std::fs::write(&mesh, cut).unwrap();
    let points = dir.path().join("points.csv");
    let run = locate(&mesh, &points, &["--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(summary["displacement"].is_null(), "{summary}");
    let run = locate(&mesh, &points, &[]);
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("no displacement array"), "{stdout}");
    let whole = dir.path().join("mesh.vtk");
    let run = locate(&whole, &points, &["--json"]);
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["displacement"], "displacement", "{summary}");
}

/// f32 rounded a displacement of 1e5 cells by about 1e-2 of a cell: points near faces landed in
/// the neighbouring cell without a word. Now the f32 kernel takes the displacements' common
/// translation out, so a body moved rigidly by 1e5 cells rounds nothing (no warning, ξ to f32's
/// precision); displacements that spread over 1e5 cells about it (two cells moved apart) still
/// round by ε₃₂ · 1e5, allowed for four times over, and `--precision f32` warns when that
/// allowance passes 4e-4 of a cell, with the value in `--json`. f64, and f32 on small displacements, say nothing.
#[test]
fn f32_on_displacements_of_many_cells_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    // Cells at x = 0 and x = 10 (unit spacing), moved by `moves`.
    let mesh_moved = |name: &str, moves: [f64; 2]| {
        let mesh = dir.path().join(name);
        let mut text = String::from(
            "# vtk DataFile Version 4.2\nmoved\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 16 double\n",
        );
        for x0 in [0, 10] {
            for k in 0..2 {
                for (i, j) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                    text += &format!("{} {j} {k}\n", x0 + i);
                }
            }
        }
        text += "CELLS 2 18\n8 0 1 2 3 4 5 6 7\n8 8 9 10 11 12 13 14 15\nCELL_TYPES 2\n12\n12\n";
        text += "POINT_DATA 16\nVECTORS displacement double\n";
        for u in moves {
            text += &format!("{u} 0 0\n").repeat(8);
        }
        std::fs::write(&mesh, text).unwrap();
        mesh
    };
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n100000.75,0.5,0.5\n100010.25,0.5,0.5\n").unwrap();
    let out = dir.path().join("results.csv");
    // Both cells moved 1e5 cells: nothing rounds, both points found where they are.
    let moved = mesh_moved("moved.vtk", [1e5, 1e5]);
    let run = locate(
        &moved,
        &points,
        &["--precision", "f32", "--json", "--out", s(&out)],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).is_empty(), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["f32_rounding"].as_f64(), Some(0.0), "{summary}");
    let results = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<f64>> = results
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    // point, cell, ξ, η, ζ: ξ = 0.5 in cell 0 and −0.5 in cell 1, to f32's precision.
    for (row, (cell, xi)) in rows.iter().zip([(0.0, 0.5), (1.0, -0.5)]) {
        assert_eq!(row[1], cell, "{results}");
        assert!((row[2] - xi).abs() < 1e-6, "{results}");
        assert!(row[3].abs() < 1e-6 && row[4].abs() < 1e-6, "{results}");
    }
    // One cell left in place, the other moved 2e5 cells: 1e5 cells each way about their mid-range.
    let spread = mesh_moved("spread.vtk", [0.0, 2e5]);
    let run = locate(&spread, &points, &["--precision", "f32", "--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).contains("warning: f32"), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let rounding = summary["f32_rounding"].as_f64().unwrap();
    assert!(
        (rounding - 4e5 * f64::from(f32::EPSILON)).abs() < 1e-9,
        "{summary}"
    );
    let exact = locate(&spread, &points, &["--json"]);
    assert!(stderr(&exact).is_empty(), "{}", stderr(&exact));
    let summary: serde_json::Value = serde_json::from_slice(&exact.stdout).unwrap();
    assert!(summary.get("f32_rounding").is_none(), "{summary}");
    let (_small, mesh, points) = scene();
    let small = locate(&mesh, &points, &["--precision", "f32"]);
    assert!(stderr(&small).is_empty(), "{}", stderr(&small));
}

/// The f32 warning's figure was taken axis by axis (4 ε₃₂ |u − T| / h): a thin cell
/// (1 × 0.001 × 1) turned by 0.5 rad and moved 2e5 cells along x, beside one left in place,
/// rounds the long axis's displacement (1e5 cells about the mid-range) into its thin one, where
/// the allowance for it is 4 ε₃₂ · 1e5 · sin 0.5 / 0.001 ≈ 23 cells; the figure said 4.8e-2. Now
/// it goes through each cell's J⁻¹, and on the unrotated body of the test above it is what it
/// was.
#[test]
fn f32_rounding_counts_a_thin_cell_turned_across_its_anisotropy() {
    let dir = tempfile::tempdir().unwrap();
    let (h, angle, moved) = ([1.0, 1e-3, 1.0], 0.5_f64, 2e5);
    let mut text = String::from(
        "# vtk DataFile Version 4.2\nturned\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 16 double\n",
    );
    let mut corners = Vec::new();
    for x0 in [0.0, 10.0] {
        for k in 0..2 {
            for (i, j) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                let x = [
                    x0 + f64::from(i) * h[0],
                    f64::from(j) * h[1],
                    f64::from(k) * h[2],
                ];
                text += &format!("{} {} {}\n", x[0], x[1], x[2]);
                corners.push(x);
            }
        }
    }
    text += "CELLS 2 18\n8 0 1 2 3 4 5 6 7\n8 8 9 10 11 12 13 14 15\nCELL_TYPES 2\n12\n12\n";
    text += "POINT_DATA 16\nVECTORS displacement double\n";
    // The first cell stays; the second turns about its centre's z axis and moves along x.
    let (sin, cos) = angle.sin_cos();
    let centre = [10.0 + 0.5 * h[0], 0.5 * h[1]];
    for (n, x) in corners.iter().enumerate() {
        let u = if n < 8 {
            [0.0, 0.0]
        } else {
            let (dx, dy) = (x[0] - centre[0], x[1] - centre[1]);
            [cos * dx - sin * dy - dx + moved, sin * dx + cos * dy - dy]
        };
        text += &format!("{:e} {:e} 0\n", u[0], u[1]);
    }
    let mesh = dir.path().join("turned.vtk");
    std::fs::write(&mesh, text).unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n0.5,0.0005,0.5\n").unwrap();
    let run = locate(&mesh, &points, &["--precision", "f32", "--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(stderr(&run).contains("warning: f32"), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let rounding = summary["f32_rounding"].as_f64().unwrap();
    let across = 4.0 * f64::from(f32::EPSILON) * 0.5 * moved * sin / h[1];
    assert!(
        rounding > across && rounding < 1.01 * across + 4e-3,
        "{rounding} against {across}: {summary}"
    );
}

/// `--out DIR/points.vtu --vtk DIR` named one file for two outputs: the results were written,
/// then replaced by the points' VTK file without a word. Now refused before any work, naming
/// both flags, the old file kept.
#[test]
fn two_outputs_naming_one_file_are_refused() {
    let (dir, mesh, points) = scene();
    let vtk = dir.path().join("vtk");
    std::fs::create_dir(&vtk).unwrap();
    for name in ["points.vtu", "mesh.vtu"] {
        let out = vtk.join(name);
        std::fs::write(&out, "previous\n").unwrap();
        let run = locate(&mesh, &points, &["--out", s(&out), "--vtk", s(&vtk)]);
        refused(&run, &["--out", "--vtk", name], &[(&out, b"previous\n")]);
    }
}

/// `--out new/` (a folder's name, with its slash) passed every check, the work was done, and the
/// write failed with the system's bare "Not a directory". Now refused first, naming the flag.
#[test]
fn out_naming_a_folder_by_its_slash_fails_before_the_mesh_is_read() {
    let (dir, _mesh, points) = scene();
    let no_mesh = Path::new("/no/such/mesh.vtu");
    for out in [
        format!("{}/", dir.path().join("new").display()),
        format!("{}/.", dir.path().display()),
        format!("{}/..", dir.path().display()),
    ] {
        let run = locate(no_mesh, &points, &["--out", &out]);
        refused(&run, &["--out", "folder"], &[]);
        assert!(!stderr(&run).contains("mesh.vtu"), "{}", stderr(&run));
    }
    assert!(!dir.path().join("new").exists());
}

/// `scene`, `demo` and `tradeoff` wrote some of their files, did the work, and failed on the
/// last when its name was taken by a folder (`known.csv/`): a scene half written, or a 4-minute
/// report lost. Now every file they write is checked before anything is built.
#[test]
fn every_file_of_scene_demo_and_tradeoff_is_checked_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    for (command, taken, written) in [
        (
            &["scene", "block", "--cells", "2,2,2", "--known", "5"][..],
            "known.csv",
            "mesh.vtu",
        ),
        (&["demo", "--coarse", "-q"], "contact.svg", "results.csv"),
        (&["tradeoff", "--quick"], "tradeoff.md", "scale.svg"),
    ] {
        let out = dir.path().join(command[0]);
        std::fs::create_dir_all(out.join(taken)).unwrap();
        let run = cgcontact(&[command, &["--out", s(&out)]].concat());
        refused(&run, &[taken, "folder"], &[]);
        assert!(!out.join(written).exists(), "{command:?} wrote {written}");
    }
}

/// Ctrl-C or SIGTERM in the middle of a run: exit code 130, one line saying so, the output as it
/// was and no temporary file beside it. The run waits on its points, a named pipe no one writes.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_run_exits_130_and_leaves_its_output_as_it_was() {
    let (dir, mesh, _) = scene();
    let pipe = dir.path().join("points.pipe");
    let made = Command::new("mkfifo").arg(&pipe).status().unwrap();
    assert!(made.success());
    let out = dir.path().join("results.csv");
    for signal in ["-INT", "-TERM"] {
        std::fs::write(&out, "old\n").unwrap();
        let run = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .args(["locate", "--mesh", s(&mesh), "--points", s(&pipe)])
            .args(["--out", s(&out)])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Time to set the handler and read the mesh; the run then waits for a writer.
        std::thread::sleep(std::time::Duration::from_millis(1000));
        let sent = Command::new("kill")
            .args([signal, &run.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let output = run.wait_with_output().unwrap();
        let message = stderr(&output);
        assert_eq!(output.status.code(), Some(130), "{signal}: {message}");
        assert_eq!(message.lines().count(), 1, "{message}");
        assert!(message.contains("interrupted"), "{message}");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "old\n");
        let mut names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(
            names,
            [
                "known.csv",
                "mesh.vtu",
                "points.csv",
                "points.pipe",
                "results.csv"
            ]
        );
    }
}

/// Runs `cgcontact args`, each `(file, pipe)` of `feeds` written into its named pipe by a `cat`
/// of its own, and gives its output; panics if it has not ended within 30 seconds.
#[cfg(target_os = "linux")]
fn fed(args: &[&str], feeds: &[(&Path, &Path)]) -> Output {
    let mut writers: Vec<_> = feeds
        .iter()
        .map(|(file, pipe)| {
            assert!(Command::new("mkfifo").arg(pipe).status().unwrap().success());
            Command::new("sh")
                .args(["-c", "cat \"$1\" > \"$2\"", "sh", s(file), s(pipe)])
                .spawn()
                .unwrap()
        })
        .collect();
    let mut run = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let ended = loop {
        if run.try_wait().unwrap().is_some() {
            break true;
        }
        if start.elapsed() > std::time::Duration::from_secs(30) {
            run.kill().unwrap();
            break false;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let output = run.wait_with_output().unwrap();
    for writer in &mut writers {
        // A writer whose pipe was never opened waits for ever.
        let _ = writer.kill();
        writer.wait().unwrap();
    }
    assert!(
        ended,
        "cgcontact {args:?} still ran after 30 s: {}",
        stderr(&output)
    );
    output
}

/// A named pipe as `--points` hung for ever: the points were read, then the file was opened
/// again to look at its last line, which waits for a writer no one starts; and as `--mesh`
/// without a displacement, the warning that lists its point arrays read the mesh a second time.
/// Each input is now read once; the warnings come from that one read.
#[cfg(target_os = "linux")]
#[test]
fn named_pipes_as_inputs_are_read_once() {
    let (dir, mesh, points) = scene();
    let pipe = dir.path().join("points.pipe");
    let run = fed(
        &["locate", "--mesh", s(&mesh), "--points", s(&pipe), "--json"],
        &[(&points, &pipe)],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["points"], 50, "{summary}");
    // A points file whose last line has no line end is still warned about.
    let text = std::fs::read_to_string(&points).unwrap();
    let unended = dir.path().join("unended.csv");
    std::fs::write(&unended, text.trim_end()).unwrap();
    let pipe = dir.path().join("unended.pipe");
    let run = fed(
        &["locate", "--mesh", s(&mesh), "--points", s(&pipe)],
        &[(&unended, &pipe)],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("unended.pipe: the file ends in"),
        "{}",
        stderr(&run)
    );
    // A mesh whose displacement is named otherwise, and the points, both through pipes.
    let renamed = dir.path().join("u.vtu");
    let text = std::fs::read_to_string(&mesh).unwrap();
    std::fs::write(
        &renamed,
        text.replace("Name=\"displacement\"", "Name=\"U\""),
    )
    .unwrap();
    let (mesh_pipe, points_pipe) = (dir.path().join("mesh.pipe"), dir.path().join("p.pipe"));
    let run = fed(
        &[
            "locate",
            "--mesh",
            s(&mesh_pipe),
            "--points",
            s(&points_pipe),
        ],
        &[(&renamed, &mesh_pipe), (&points, &points_pipe)],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("mesh.pipe: no point array named `displacement`")
            && stderr(&run).contains("its point arrays: U"),
        "{}",
        stderr(&run)
    );
}

/// A run that fails after its `--vtk` folder was made (reading the points) removes the folders
/// it made, and only those; a run that writes keeps them.
#[test]
fn a_failed_run_leaves_no_folder_it_made() {
    let (dir, mesh, points) = scene();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "x,y,z\n1,2\n").unwrap();
    let new = dir.path().join("new");
    let vtk = new.join("deeper/vtk");
    let run = locate(&mesh, &bad, &["--vtk", s(&vtk)]);
    refused(&run, &["bad.csv", "line 2"], &[]);
    assert!(!new.exists());
    // A folder that was there stays, though empty.
    std::fs::create_dir(&new).unwrap();
    let run = locate(&mesh, &bad, &["--vtk", s(&vtk)]);
    refused(&run, &["bad.csv"], &[]);
    assert!(new.is_dir() && !new.join("deeper").exists());
    let run = locate(&mesh, &points, &["--vtk", s(&vtk)]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(vtk.join("mesh.vtu").is_file() && vtk.join("points.vtu").is_file());
}

/// `--out /dev/stdout` with standard output appended to a log (`>> run.log`): the results go
/// into the log after what it held, then the summary; the log is the same file (inode) as
/// before. Renamed over, as a regular file is, it lost its lines and the summary went nowhere.
#[cfg(target_os = "linux")]
#[test]
fn out_to_standard_output_writes_into_the_redirected_file() {
    use std::os::unix::fs::MetadataExt;
    let (dir, mesh, points) = scene();
    for (flag, name) in [("/dev/stdout", "run.log"), ("/dev/stderr", "err.log")] {
        let log = dir.path().join(name);
        std::fs::write(&log, "a line before\n").unwrap();
        let inode = std::fs::metadata(&log).unwrap().ino();
        let file = std::fs::OpenOptions::new().append(true).open(&log).unwrap();
        let (stdout, stderr) = if name == "run.log" {
            (Stdio::from(file), Stdio::null())
        } else {
            (Stdio::null(), Stdio::from(file))
        };
        let status = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .args(["locate", "--mesh", s(&mesh), "--points", s(&points)])
            .args(["--out", flag])
            .stdout(stdout)
            .stderr(stderr)
            .status()
            .unwrap();
        assert!(status.success(), "{flag}");
        assert_eq!(std::fs::metadata(&log).unwrap().ino(), inode, "{flag}");
        let text = std::fs::read_to_string(&log).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("a line before"), "{flag}: {text}");
        assert_eq!(
            lines.next(),
            Some("point,cell,xi,eta,zeta,iterations,residual,inversions"),
            "{flag}: {text}"
        );
        // The 50 points' rows, one after the other.
        let rows = lines.take_while(|l| l.split(',').count() == 8).count();
        assert_eq!(rows, 50, "{flag}: {text}");
        if name == "run.log" {
            assert!(text.contains(&format!("wrote {flag}")), "{text}");
        }
    }
}

/// The descriptor of another redirection (`3>> extra.log`, `--out /dev/fd/3`) is appended to, in
/// place, and an output on a descriptor needs no writable folder.
#[cfg(target_os = "linux")]
#[test]
fn out_to_another_descriptor_appends_in_place() {
    use std::os::unix::fs::MetadataExt;
    let (dir, mesh, points) = scene();
    let log = dir.path().join("extra.log");
    std::fs::write(&log, "kept\n").unwrap();
    let inode = std::fs::metadata(&log).unwrap().ino();
    let script = format!(
        "exec 3>>'{}'; exec '{}' locate --mesh '{}' --points '{}' --out /dev/fd/3 --quiet",
        s(&log),
        env!("CARGO_BIN_EXE_cgcontact"),
        s(&mesh),
        s(&points)
    );
    let run = Command::new("sh").args(["-c", &script]).output().unwrap();
    assert!(run.status.success(), "{}", stderr(&run));
    assert_eq!(std::fs::metadata(&log).unwrap().ino(), inode);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.starts_with("kept\npoint,cell,xi"), "{text}");
    assert_eq!(text.lines().count(), 52, "{text}");
}

/// Whether this test runs as root (the owner of a file it makes).
#[cfg(unix)]
fn running_as_root() -> bool {
    use std::os::unix::fs::MetadataExt;
    tempfile::tempfile().unwrap().metadata().unwrap().uid() == 0
}

/// A result the shell's `>` could not write (read-only for the user, `chmod a-w`) is refused
/// before any work, and kept; so is another user's file in a sticky folder (`/tmp`), whose rename
/// the system refuses after the work. Root may replace a read-only file, as the shell's `>` does,
/// so as root the run goes through `su nobody` (and the sticky case, which needs a file of
/// another user, runs only then).
#[cfg(unix)]
#[test]
fn results_that_cannot_be_replaced_are_refused_before_any_work() {
    use std::os::unix::fs::PermissionsExt;
    let root = running_as_root();
    let (dir, mesh, points) = scene();
    let mode = |path: &Path, mode: u32| {
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
    };
    mode(dir.path(), 0o755);
    let own = dir.path().join("own");
    std::fs::create_dir(&own).unwrap();
    let run = |out: &Path| -> Output {
        let bin = env!("CARGO_BIN_EXE_cgcontact");
        let args = [
            "locate",
            "--mesh",
            s(&mesh),
            "--points",
            s(&points),
            "--out",
            s(out),
        ];
        if root {
            let line = std::iter::once(bin)
                .chain(args)
                .map(|a| format!("'{a}'"))
                .collect::<Vec<_>>()
                .join(" ");
            Command::new("su")
                .args(["nobody", "-s", "/bin/sh", "-c", &line])
                .output()
                .expect("su runs")
        } else {
            cgcontact(&args)
        }
    };
    if root {
        let status = Command::new("chown")
            .args(["nobody", s(&own)])
            .status()
            .unwrap();
        assert!(status.success());
    }
    let kept = own.join("kept.csv");
    let run_ok = run(&own.join("fresh.csv"));
    assert!(run_ok.status.success(), "{}", stderr(&run_ok));
    std::fs::rename(own.join("fresh.csv"), &kept).unwrap();
    let before = std::fs::read(&kept).unwrap();
    mode(&kept, 0o444);
    let refusal = run(&kept);
    refused(
        &refusal,
        &["kept.csv", "--out", "read-only"],
        &[(&kept, &before)],
    );
    // Nothing was located: the refusal came first.
    assert!(!String::from_utf8_lossy(&refusal.stdout).contains("located"));
    if root {
        let sticky = dir.path().join("sticky");
        std::fs::create_dir(&sticky).unwrap();
        mode(&sticky, 0o1777);
        let foreign = sticky.join("res.csv");
        std::fs::write(&foreign, "root's\n").unwrap();
        mode(&foreign, 0o666);
        refused(
            &run(&foreign),
            &["res.csv", "--out", "another user", "sticky"],
            &[(&foreign, b"root's\n")],
        );
    }
}
