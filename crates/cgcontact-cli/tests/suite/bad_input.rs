//! Bad input at the command line: the built `cgcontact` binary on truncated and malformed VTK files,
//! malformed CSV, missing or unreadable paths and bad flag values. Every case must exit with code 2,
//! print exactly one line on stderr that names the file (and the line or cell where there is one),
//! and never show a panic or a backtrace hint.

use std::path::{Path, PathBuf};
use std::process::Command;

use cgcontact::glam::DVec3;
use cgcontact::{Body, Lattice};
use cgcontact_io::{MeshFormat, write_mesh, write_points};

/// A tempdir holding a good legacy ASCII mesh (`good.vtk`, 3 × 2 × 2 cells, displaced) and a good
/// points file (`good.csv`).
struct Files {
    dir: tempfile::TempDir,
    mesh_text: String,
}

impl Files {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let lattice =
            Lattice::new(DVec3::new(1.0, 2.0, 3.0), DVec3::splat(0.5), [3, 2, 2]).unwrap();
        let mut body = Body::full(lattice);
        body.update_displacements(|_, x, u| *u = DVec3::new(0.0, 0.0, -0.02 * (x.x - 1.0)))
            .unwrap();
        let mesh = dir.path().join("good.vtk");
        write_mesh(&mesh, &body, MeshFormat::LegacyAscii).unwrap();
        write_points(
            dir.path().join("good.csv"),
            &[
                DVec3::new(1.2, 2.3, 3.4),
                DVec3::new(1.9, 2.1, 3.6),
                DVec3::splat(9.0),
            ],
        )
        .unwrap();
        let mesh_text = std::fs::read_to_string(&mesh).unwrap();
        Self { dir, mesh_text }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Write `text` to `name` in the tempdir.
    fn write(&self, name: &str, text: &str) -> PathBuf {
        let path = self.path(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// The good mesh with `from` replaced once by `to` (which must occur).
    fn mesh_with(&self, name: &str, from: &str, to: &str) -> PathBuf {
        assert!(self.mesh_text.contains(from), "`{from}` is not in the mesh");
        self.write(name, &self.mesh_text.replacen(from, to, 1))
    }

    /// The good mesh with the VTK type of input cell `cell` set to `vtk_type`.
    fn mesh_with_cell_type(&self, name: &str, cell: usize, vtk_type: &str) -> PathBuf {
        let mut lines: Vec<String> = self.mesh_text.lines().map(str::to_owned).collect();
        let at = lines
            .iter()
            .position(|l| l.starts_with("CELL_TYPES"))
            .unwrap();
        // The types follow, whitespace-separated over one or more lines.
        let mut seen = 0;
        for line in &mut lines[at + 1..] {
            let mut fields: Vec<String> = line.split_whitespace().map(str::to_owned).collect();
            if seen + fields.len() > cell {
                fields[cell - seen] = vtk_type.to_owned();
                *line = fields.join(" ");
                break;
            }
            seen += fields.len();
        }
        self.write(name, &(lines.join("\n") + "\n"))
    }
}

/// Run `cgcontact locate --mesh MESH --points POINTS EXTRA...`; return (exit code, stderr).
fn locate(mesh: &Path, points: &Path, extra: &[&str]) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .arg("locate")
        .arg("--mesh")
        .arg(mesh)
        .arg("--points")
        .arg(points)
        .args(extra)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    for text in [&stderr, &stdout] {
        assert!(
            !text.contains("panicked") && !text.contains("RUST_BACKTRACE"),
            "a panic: {text}"
        );
    }
    (output.status.code(), stderr)
}

/// Exit 2, one line on stderr containing every `needle`.
fn assert_one_line_error(case: &str, result: (Option<i32>, String), needles: &[&str]) {
    let (code, stderr) = result;
    assert_eq!(code, Some(2), "{case}: exit code; stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{case}: one line on stderr, got {stderr:?}");
    for needle in needles {
        assert!(
            lines[0].contains(needle),
            "{case}: `{needle}` missing from {:?}",
            lines[0]
        );
    }
}

#[test]
fn good_files_pass() {
    let files = Files::new();
    let (code, stderr) = locate(
        &files.path("good.vtk"),
        &files.path("good.csv"),
        &["--quiet"],
    );
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

#[test]
fn truncated_vtk_names_the_file_and_a_line() {
    let files = Files::new();
    let good = files.path("good.csv");
    let text = &files.mesh_text;
    for (i, fraction) in [0.1, 0.3, 0.5, 0.7, 0.9].into_iter().enumerate() {
        let cut = (text.len() as f64 * fraction) as usize;
        let name = format!("cut{i}.vtk");
        let mesh = files.write(&name, &text[..cut]);
        let (code, stderr) = locate(&mesh, &good, &[]);
        assert_one_line_error(
            &format!("cut at {fraction}"),
            (code, stderr.clone()),
            &[&name],
        );
        assert!(
            stderr.contains("line ") || stderr.contains("cell") || stderr.contains("CELL"),
            "cut at {fraction}: no line or cell named: {stderr}"
        );
    }
}

#[test]
fn wrong_counts_are_one_line_errors() {
    let files = Files::new();
    let good = files.path("good.csv");
    // 36 nodes, 12 cells.
    let more_points = files.mesh_with("points.vtk", "POINTS 36 double", "POINTS 38 double");
    assert_one_line_error(
        "POINTS count",
        locate(&more_points, &good, &[]),
        &["points.vtk", "line"],
    );
    let more_cells = files.mesh_with("cells.vtk", "CELLS 12 108", "CELLS 13 108");
    assert_one_line_error(
        "CELLS count",
        locate(&more_cells, &good, &[]),
        &["cells.vtk", "cell"],
    );
    let fewer_cells = files.mesh_with("fewer.vtk", "CELLS 12 108", "CELLS 11 108");
    assert_one_line_error(
        "CELLS count",
        locate(&fewer_cells, &good, &[]),
        &["fewer.vtk"],
    );
    let types = files.mesh_with("types.vtk", "CELL_TYPES 12", "CELL_TYPES 13");
    assert_one_line_error(
        "CELL_TYPES count",
        locate(&types, &good, &[]),
        &["types.vtk"],
    );
    let data = files.mesh_with("data.vtk", "POINT_DATA 36", "POINT_DATA 35");
    assert_one_line_error("POINT_DATA count", locate(&data, &good, &[]), &["data.vtk"]);
}

#[test]
fn unknown_and_mixed_cell_types_name_the_cell() {
    let files = Files::new();
    let good = files.path("good.csv");
    let unknown = files.mesh_with_cell_type("unknown.vtk", 7, "99");
    assert_one_line_error(
        "unknown type",
        locate(&unknown, &good, &[]),
        &["unknown.vtk"],
    );
    // A tetrahedron (10) and a voxel's neighbour wedge (13) among hexahedra.
    let tetra = files.mesh_with_cell_type("tetra.vtk", 4, "10");
    assert_one_line_error(
        "tetra",
        locate(&tetra, &good, &[]),
        &["tetra.vtk", "cell 4"],
    );
    let wedge = files.mesh_with_cell_type("wedge.vtk", 11, "13");
    assert_one_line_error(
        "wedge",
        locate(&wedge, &good, &[]),
        &["wedge.vtk", "cell 11"],
    );
}

#[test]
fn non_lattice_node_names_the_node() {
    let files = Files::new();
    let good = files.path("good.csv");
    // Node 1 of the writer's order sits at (1.5, 2, 3): move it off the lattice by 0.0123.
    let line = files
        .mesh_text
        .lines()
        .find(|l| l.starts_with("1 2 3 1.5 2 3"))
        .expect("the POINTS list starts with nodes 0 and 1");
    let off = files.mesh_with("off.vtk", line, &line.replacen("1.5 2 3", "1.5123 2 3", 1));
    assert_one_line_error(
        "off lattice",
        locate(&off, &good, &[]),
        &["off.vtk", "node 1", "not on the lattice"],
    );
}

#[test]
fn missing_displacement_array_names_the_array() {
    let files = Files::new();
    let result = locate(
        &files.path("good.vtk"),
        &files.path("good.csv"),
        &["--displacement", "velocity"],
    );
    assert_one_line_error("--displacement velocity", result, &["good.vtk", "velocity"]);
}

#[test]
fn malformed_csv_names_the_line() {
    let files = Files::new();
    let mesh = files.path("good.vtk");
    for (name, text, needles) in [
        ("two.csv", "x,y,z\n1,2,3\n1,2\n", &["two.csv", "line 3"][..]),
        (
            "four.csv",
            "1,2,3\n4,5,6\n7,8,9,10\n",
            &["four.csv", "line 3"],
        ),
        (
            "word.csv",
            "x,y,z\n1,2,3\n1,abc,3\n",
            &["word.csv", "line 3", "abc"],
        ),
        (
            "blank.csv",
            "x,y,z\n\n1,2,3\n\n1,2,three\n",
            &["blank.csv", "line 5"],
        ),
        ("empty.csv", "", &["empty.csv"]),
        ("header.csv", "x,y,z\n", &["header.csv"]),
        ("binary.csv", "\u{0}\u{1}\u{2}\u{ff}", &["binary.csv"]),
    ] {
        let points = files.write(name, text);
        assert_one_line_error(name, locate(&mesh, &points, &[]), needles);
    }
    // A mesh given as points and points given as a mesh.
    assert_one_line_error(
        "vtk as csv",
        locate(&mesh, &mesh, &[]),
        &["good.vtk", "line"],
    );
    let points = files.path("good.csv");
    assert_one_line_error("csv as vtk", locate(&points, &points, &[]), &["good.csv"]);
}

#[test]
fn missing_and_unreadable_paths_name_the_path() {
    let files = Files::new();
    let (mesh, points) = (files.path("good.vtk"), files.path("good.csv"));
    let absent = files.path("absent.vtk");
    assert_one_line_error("no mesh", locate(&absent, &points, &[]), &["absent.vtk"]);
    let absent = files.path("absent.csv");
    assert_one_line_error("no points", locate(&mesh, &absent, &[]), &["absent.csv"]);
    // A folder where a file is expected: unreadable as a file.
    let folder = files.path("folder");
    std::fs::create_dir(&folder).unwrap();
    assert_one_line_error("folder mesh", locate(&folder, &points, &[]), &["folder"]);
    assert_one_line_error("folder points", locate(&mesh, &folder, &[]), &["folder"]);
    // An output path in a folder that does not exist.
    let out = files.path("no/such/folder/results.csv");
    let out = out.to_str().unwrap();
    assert_one_line_error(
        "unwritable --out",
        locate(&mesh, &points, &["--out", out]),
        &["results.csv"],
    );
}

#[test]
fn bad_flag_values_checked_by_the_tool_are_one_line_errors() {
    let files = Files::new();
    let (mesh, points) = (files.path("good.vtk"), files.path("good.csv"));
    for (flags, needle) in [
        (&["--threads", "0"][..], "--threads"),
        (&["--tol=-1"], "tol"),
        (&["--tol", "nan"], "tol"),
        (&["--tol", "inf"], "tol"),
        (&["--max-iter", "0"], "max-iter"),
        // Beyond the core's limit on distances (it was an internal error, after the search).
        (&["--gap", "1e300"], "--gap 1e300"),
        (&["--gap=-1"], "--gap -1"),
        (&["--gap", "nan"], "--gap NaN"),
        // Each repeat's time is kept: 4e9 of them asked for 34 GB at once, and the failed
        // allocation aborted the program (no message, SIGABRT).
        (&["--repeat", "4000000000"], "--repeat 4000000000: at most"),
    ] {
        assert_one_line_error(
            &format!("{flags:?}"),
            locate(&mesh, &points, flags),
            &[needle],
        );
    }
}

/// Values rejected by the argument parser (clap): exit 2, the first line names the flag and the value,
/// no panic. (clap adds a usage hint after a blank line; the one-line form is pinned below.)
#[test]
fn bad_flag_values_rejected_by_the_parser_exit_2() {
    let files = Files::new();
    let (mesh, points) = (files.path("good.vtk"), files.path("good.csv"));
    for (flags, needles) in [
        (&["--strategy", "bogus"][..], &["--strategy", "bogus"][..]),
        (&["--precision", "f16"], &["--precision", "f16"]),
        (&["--threads", "x"], &["--threads", "x"]),
        (&["--max-iter", "-3"], &["--max-iter", "-3"]),
        // A negative number was "unexpected argument '-1' found", naming no flag.
        (&["--tol", "-1"], &["--tol", "-1"]),
        (&["--threads", "-2"], &["--threads", "-2"]),
        (&["--repeat", "-1"], &["--repeat", "-1"]),
        (&["--tol", "abc"], &["--tol", "abc"]),
        (&["--no-such-flag"], &["--no-such-flag"]),
    ] {
        let (code, stderr) = locate(&mesh, &points, flags);
        assert_eq!(code, Some(2), "{flags:?}: {stderr}");
        let first = stderr.lines().next().unwrap_or_default();
        for needle in needles {
            assert!(
                first.contains(needle),
                "{flags:?}: `{needle}` not in {first:?}"
            );
        }
    }
}

/// BUG (cli): clap's own errors (an unknown `--strategy`, a non-number `--threads`) print 3–5 lines
/// (the error, the possible values, a blank line, a `--help` hint) instead of the one line the design
/// promises for every error.
#[test]

fn bad_flag_values_rejected_by_the_parser_are_one_line() {
    let files = Files::new();
    let (mesh, points) = (files.path("good.vtk"), files.path("good.csv"));
    let result = locate(&mesh, &points, &["--strategy", "bogus"]);
    assert_one_line_error("--strategy bogus", result, &["--strategy", "bogus"]);
}

/// Regression: `cgcontact scene block --cells 40,80,40`, the form the command's own help shows, was
/// refused ("3 values required ... but 1 was provided": `num_args = 3` was checked before the value
/// was split on commas).
#[test]
fn scene_cells_comma_form_from_the_help_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args([
            "scene", "block", "--cells", "3,2,2", "--known", "5", "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The adaptive scene's flags on another scene, even at their default value, and too many levels:
/// one-line errors, exit 2, and no folder written.
#[test]
fn adaptive_scene_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &["scene", "block", "--levels", "2"][..],
        &["scene", "sphere-fine", "--unbalanced"],
        &["scene", "sphere-adaptive", "--levels", "9"],
        &["scene", "sphere-adaptive", "--refine-radius", "-1"],
    ] {
        let out = dir.path().join("never");
        let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
        assert!(!out.exists(), "{args:?} wrote its folder");
    }
}

/// A scene too large to build in memory (`--known 300000000`, `--cells 1600,1600,1600`) aborted
/// the process on a failed allocation (exit 134). It is now a one-line error before any work, and
/// nothing is written.
#[test]
fn scenes_too_large_to_build_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene");
    for (flags, needle) in [
        (&["block", "--known", "300000000"][..], "--known 300000000"),
        (&["sphere-fine", "--known", "99999999999999"], "--known"),
        (
            &["block", "--cells", "1600,1600,1600"],
            "--cells 1600,1600,1600",
        ),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .arg("scene")
            .args(flags)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_one_line_error(
            &format!("{flags:?}"),
            (output.status.code(), stderr),
            &[needle],
        );
        assert!(!out.join("mesh.vtu").exists());
    }
}

/// Scene numbers a scene cannot be built from: NaN or negative jitter (NaN had been taken as no
/// jitter), negative values (which clap had reported as unknown arguments), spacings and
/// coordinates whose squares leave the normal range (the build had failed on a NaN
/// displacement, naming no option), and `--cells` on a scene that has its own block (ignored
/// before). Each is a one-line error naming the option, exit 2, nothing written.
#[test]
fn scene_numbers_out_of_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene");
    for (flags, needle) in [
        (&["sphere-fine", "--jitter", "nan"][..], "--jitter NaN"),
        (&["sphere-fine", "--jitter", "-0.1"], "--jitter -0.1"),
        (&["sphere-fine", "--scale", "-1"], "--scale -1"),
        (&["sphere-fine", "--scale", "1e300"], "--scale"),
        (&["sphere-adaptive", "--scale", "1e-300"], "--scale"),
        (&["block", "--h", "1e-300"], "--h"),
        (&["block", "--h", "-1"], "--h [-1, -1, -1]"),
        (&["sphere-fine", "--sink", "nan"], "--sink NaN"),
        (&["sphere-fine", "--offset", "1e120"], "--offset"),
        // NaN passed the range check and failed in the lattice, naming no flag.
        (&["block", "--offset", "nan"], "--offset"),
        (&["block", "--offset", "0,nan,0"], "--offset"),
        // Negative counts were "unexpected argument", naming no flag.
        (&["block", "--known", "-1"], "--known"),
        (&["sphere-adaptive", "--levels", "-1"], "--levels"),
        (&["sphere-adaptive", "--cells", "10,10,10"], "--cells"),
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .arg("scene")
            .args(flags)
            .args(["--known", "10", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_one_line_error(
            &format!("{flags:?}"),
            (output.status.code(), stderr),
            &[needle],
        );
        assert!(!out.exists(), "{flags:?} wrote its folder");
    }
    // A negative sink (a bump) is a scene: accepted.
    let status = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args([
            "scene",
            "sphere-fine",
            "--sink",
            "-0.5",
            "--known",
            "10",
            "--out",
        ])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
}

/// A points file cut inside its last number reads as another number: a points file that ends in
/// a value with no line end after it gets a warning naming it (not an error: CSV writers often
/// leave the last line unended), and the answers are those of the file with its line end.
#[test]
fn a_points_file_with_its_last_line_unended_is_warned_about() {
    let files = Files::new();
    let text = "x,y,z\n1.2,2.3,3.4\n1.9,2.1,3.6";
    let locate = |points: &Path, quiet: bool| {
        let out = files.path("out.csv");
        let mut command = Command::new(env!("CARGO_BIN_EXE_cgcontact"));
        command
            .args(["locate", "--mesh"])
            .arg(files.path("good.vtk"))
            .arg("--points")
            .arg(points)
            .arg("--out")
            .arg(&out);
        if quiet {
            command.arg("-q");
        }
        let output = command.output().unwrap();
        assert!(output.status.success(), "{output:?}");
        (
            String::from_utf8_lossy(&output.stderr).into_owned(),
            std::fs::read_to_string(out).unwrap(),
        )
    };
    let unended = files.write("unended.csv", text);
    let ended = files.write("ended.csv", &format!("{text}\r\n"));
    let (warned, answers) = locate(&unended, false);
    assert!(
        warned.contains("warning: ")
            && warned.contains("unended.csv: the file ends in `3.6` with no line end after it"),
        "{warned}"
    );
    let (silent, ended_answers) = locate(&ended, false);
    assert!(!silent.contains("warning"), "{silent}");
    assert_eq!(answers, ended_answers);
    let (quiet, _) = locate(&unended, true);
    assert!(quiet.is_empty(), "{quiet}");
}

/// A displacement array under another name (`Displacement`, `U`) solves the mesh undeformed, as
/// documented: a warning on stderr says so and lists the point arrays, unless `--quiet`. Nothing
/// to warn of when the file has the array, names it with `--displacement`, or has no point
/// arrays at all.
#[test]
fn a_displacement_under_another_name_is_warned_of() {
    let files = Files::new();
    let points = files.path("good.csv");
    for name in ["Displacement", "U"] {
        let mesh = files.mesh_with(
            &format!("{name}.vtk"),
            "VECTORS displacement",
            &format!("VECTORS {name}"),
        );
        let out = files.path("o.csv");
        let (code, stderr) = locate(&mesh, &points, &["--out", out.to_str().unwrap()]);
        assert_eq!(code, Some(0), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        for needle in [
            "warning",
            "undeformed",
            &format!("point arrays: {name} "),
            "--displacement",
        ] {
            assert!(stderr.contains(needle), "{needle} not in {stderr}");
        }
        let quiet = ["--out", out.to_str().unwrap(), "--quiet"];
        assert_eq!(locate(&mesh, &points, &quiet), (Some(0), String::new()));
        let named = ["--out", out.to_str().unwrap(), "--displacement", name];
        assert_eq!(locate(&mesh, &points, &named), (Some(0), String::new()));
    }
    let good = files.path("good.vtk");
    let o = files.path("o.csv");
    let out = ["--out", o.to_str().unwrap()];
    assert_eq!(locate(&good, &points, &out), (Some(0), String::new()));
    // An XML mesh without point arrays: plainly undeformed.
    let xml = files.path("bare.vtu");
    let body = Body::full(Lattice::new(DVec3::ZERO, DVec3::splat(0.5), [2, 2, 2]).unwrap());
    write_mesh(&xml, &body, MeshFormat::Xml).unwrap();
    let text = std::fs::read_to_string(&xml).unwrap();
    let (start, end) = (
        text.find("<PointData").unwrap(),
        text.find("</PointData>").unwrap(),
    );
    std::fs::write(
        &xml,
        format!("{}<PointData>{}", &text[..start], &text[end..]),
    )
    .unwrap();
    assert_eq!(locate(&xml, &points, &out), (Some(0), String::new()));
}
