//! `cgcontact scene`'s flags: scenes too large to build refused by their size before anything
//! is built, comma lists that start with a negative number taken as the flag's value, and the
//! library's refusals of a scene reported with the flags that caused them. Each refusal is one
//! line on stderr, exit code 2, and writes nothing.

use std::path::Path;
use std::process::Command;

/// Run `cgcontact scene ARGS --out OUT`; return (exit code, stderr), checked for panics.
fn scene(args: &[&str], out: &Path) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .arg("scene")
        .args(args)
        .arg("--out")
        .arg(out)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(
        !stderr.contains("panicked") && !stderr.contains("memory allocation"),
        "{args:?}: {stderr}"
    );
    (output.status.code(), stderr)
}

/// Each case: exit 2, one line on stderr holding every needle and none of `absent`, no folder.
fn refused(cases: &[(&[&str], &[&str])], absent: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene");
    for (args, needles) in cases {
        let (code, stderr) = scene(args, &out);
        assert_eq!(code, Some(2), "{args:?}: exit code; stderr: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(
            lines.len(),
            1,
            "{args:?}: one line on stderr, got {stderr:?}"
        );
        for needle in *needles {
            assert!(
                lines[0].contains(needle),
                "{args:?}: `{needle}` missing from {:?}",
                lines[0]
            );
        }
        for word in absent {
            assert!(
                !lines[0].contains(word),
                "{args:?}: `{word}` in {:?}",
                lines[0]
            );
        }
        assert!(!out.exists(), "{args:?} wrote its folder");
    }
}

/// Regression: the size cap applied to `block --cells` only, at 2^26 cells (about 41 GB at the
/// 610 bytes a cell measured): `sphere-fine --h 0.01` (250 M cells) was accepted and aborted on a
/// failed allocation of 6 GB (exit 134), and an adaptive scene's leaves were not counted. Every
/// scene is now refused beyond 2^23 cells or leaves, with the count, the cap and the flags to
/// change, before anything is built (the adaptive ones at once, however many levels).
#[test]
fn scenes_beyond_the_cap_are_refused_before_building() {
    refused(
        &[
            (
                &["sphere-fine", "--h", "0.01"],
                &["--h 0.01", "250000000 cells", "8388608", "larger --h"],
            ),
            (
                &["sphere-coarse", "--h", "0.01,0.02,0.05"],
                &["--h 0.01,0.02,0.05", "25000000 cells", "8388608"],
            ),
            (
                &["block", "--cells", "256,256,256"],
                &[
                    "--cells 256,256,256",
                    "16777216 cells",
                    "8388608",
                    "--cells",
                ],
            ),
            (
                &["sphere-adaptive", "--levels", "4", "--refine-radius", "100"],
                &["--levels 4", "--refine-radius 100", "8388608"],
            ),
            (
                &["sphere-adaptive", "--levels", "8", "--refine-radius", "1"],
                &["--levels 8", "--refine-radius 1", "8388608"],
            ),
            (
                &["sphere-adaptive", "--levels", "6", "--unbalanced"],
                &["--levels 6", "8388608"],
            ),
            (
                &["sphere-adaptive", "--h", "0.01"],
                &["--h 0.01", "8388608"],
            ),
            (
                &["block", "--known", "20000000"],
                &["--known 20000000", "16777216"],
            ),
        ],
        &[],
    );
}

/// Regression: a comma list starting with a negative number was refused by the parser
/// ("unexpected argument '-1' found": `allow_negative_numbers` takes single numbers only). It is
/// the flag's value now: a negative offset is a scene, a negative spacing or count is refused by
/// the flag's name, and a flag taken for a missing value says so.
#[test]
fn comma_lists_starting_with_a_negative_number_are_values() {
    let dir = tempfile::tempdir().unwrap();
    for offset in ["-1,2,3", "-1e7,0,0"] {
        let out = dir.path().join(format!("offset{offset}"));
        let (code, stderr) = scene(
            &["sphere-coarse", "--offset", offset, "--known", "10"],
            &out,
        );
        assert_eq!(code, Some(0), "--offset {offset}: {stderr}");
        assert!(out.join("mesh.vtu").exists());
    }
    refused(
        &[
            (&["sphere-fine", "--h", "-1,2,3"], &["--h", "-1"]),
            (&["block", "--cells", "-1,2,3"], &["--cells", "-1"]),
            (&["block", "--cells", "1,-2,3"], &["--cells", "-2"]),
            // The next flag is taken as --offset's value, and said to be a flag.
            (
                &["sphere-fine", "--offset", "--h", "1"],
                &["--offset", "--h", "flag"],
            ),
            (
                &["sphere-fine", "--h", "--offset", "1"],
                &["--h", "--offset", "flag"],
            ),
            (&["sphere-fine", "stray"], &["unexpected argument 'stray'"]),
        ],
        &["tip", "'-- "],
    );
}

/// Regression: refusals of the library that named no flag: inverted cells and displacements too
/// large from --sink or --jitter, a `block` axis past the per-axis limit ("makes no lattice"),
/// and an offset too far for the spacing ("move the mesh nearer the origin").
#[test]
fn refusals_name_the_flags_at_fault() {
    refused(
        &[
            (
                &["sphere-coarse", "--sink", "10"],
                &[
                    "--sink 10",
                    "inverted",
                    "smaller --sink",
                    "--allow-inverted",
                ],
            ),
            (
                &["sphere-coarse", "--jitter", "1e300"],
                &["--jitter 1e300", "smaller --jitter"],
            ),
            (
                &["sphere-adaptive", "--jitter", "1e300"],
                &["--jitter 1e300", "smaller --jitter"],
            ),
            (
                &["sphere-coarse", "--sink", "1e15", "--allow-inverted"],
                &["--sink 1e15", "smaller --sink"],
            ),
            (
                &["block", "--cells", "1000000,1,1"],
                &["--cells 1000000,1,1", "999999 per axis"],
            ),
            (
                &["sphere-fine", "--h", "1e-6,1,1"],
                &["--h", "999999 per axis"],
            ),
            (&["sphere-fine", "--h", "100"], &["--h 100", "no cell"]),
            (
                &[
                    "block", "--cells", "10,10,10", "--h", "1e-12", "--offset", "1e4",
                ],
                &["--offset 10000", "smaller --offset", "larger --h"],
            ),
            (
                &["sphere-adaptive", "--offset", "1e13"],
                &["--offset 1e13", "--levels", "smaller --offset"],
            ),
        ],
        &[
            "makes no lattice",
            "nearer the origin",
            "displacement of node",
        ],
    );
}

/// Regression: `--out new/.` (or `new/./`), a folder that `mkdir -p` makes, failed with "cannot
/// create the folder: No such file or directory": the standard library's `create_dir_all` asks
/// for `new/.` before `new` exists. Found by running `scene`, `demo` and `tradeoff` with unusual
/// `--out` targets. The scene must land in `new`, as the shell would put it there, and its mesh
/// hold the cells the summary names.
#[test]
fn an_out_folder_named_with_a_trailing_dot_is_made() {
    let dir = tempfile::tempdir().unwrap();
    for (i, suffix) in ["/.", "/./", "/./."].into_iter().enumerate() {
        let folder = dir.path().join(format!("new{i}"));
        let out = std::path::PathBuf::from(format!("{}{suffix}", folder.display()));
        let (code, stderr) = scene(&["block", "--cells", "2,1,1", "--known", "3"], &out);
        assert_eq!(code, Some(0), "--out {}: {stderr}", out.display());
        let known = std::fs::read_to_string(folder.join("known.csv")).unwrap();
        // The header and one row per known point.
        assert_eq!(known.lines().count(), 4, "{known}");
        let mesh = std::fs::read_to_string(folder.join("mesh.vtu")).unwrap();
        assert!(mesh.contains("NumberOfCells=\"2\""), "{mesh}");
    }
}

/// Regression: a scene too wide for its finest spacing without any `--offset` (a `--h` far finer
/// along one axis than another) was refused as "--offset 0 puts the scene ... from the origin":
/// it named a flag the user never gave. Found with `block --h 1e-90,1,1e90`. The refusal itself
/// is the lattice's (`Lattice::new` refuses the same lattice), checked here by the message naming
/// --h and --cells and not --offset.
#[test]
fn a_scene_too_wide_for_its_spacing_without_an_offset_names_h_not_offset() {
    refused(
        &[
            (
                &["block", "--cells", "2,3,4", "--h", "1e-90,1,1e90"],
                &["--h", "--cells", "from the origin"],
            ),
            (
                &["block", "--cells", "2,3,4", "--h", "1e-12,1,1e12"],
                &["--h", "--cells", "from the origin"],
            ),
        ],
        &["--offset"],
    );
    // With an --offset given, it is still the flag named.
    refused(
        &[(
            &["block", "--cells", "2,3,4", "--offset", "1e15"],
            &["--offset 1e15"],
        )],
        &[],
    );
}

/// Regression: `block --known 0` (no contact points, no known points) wrote a points.csv with a
/// header only and said nothing, and `locate` then refused that file ("no data rows"). The scene
/// now warns. Checked against `locate` itself: it refuses the file the warning is about.
#[test]
fn a_scene_without_any_point_warns() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("empty");
    let (code, stderr) = scene(&["block", "--cells", "2,2,2", "--known", "0"], &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("warning") && stderr.contains("--known 0"),
        "{stderr}"
    );
    let located = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .arg("locate")
        .arg("--mesh")
        .arg(out.join("mesh.vtu"))
        .arg("--points")
        .arg(out.join("points.csv"))
        .output()
        .unwrap();
    assert_eq!(located.status.code(), Some(2));
    // A scene with points says nothing of the kind.
    let (code, stderr) = scene(&["block", "--cells", "2,2,2", "--known", "1"], &out);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}

/// Regression: `--scale 1e-300` was refused as "the scene's spacing 1.25e-301 and farthest
/// coordinate 1e-299 (from --h, --scale and --offset) must lie between …", which blamed an
/// --offset never given and did not say which of the two lengths was out of range. Each bound now
/// names its own length and the flags that set it.
#[test]
fn a_spacing_or_extent_out_of_range_names_its_own_length() {
    refused(
        &[
            (
                &["block", "--scale", "1e-300"],
                &["spacing 1.25e-301", "--h", "--scale", "below"],
            ),
            (&["block", "--h", "1e-120"], &["spacing 1e-120", "below"]),
        ],
        &["--offset", "farthest"],
    );
    refused(
        &[(
            &["block", "--scale", "1e300"],
            &["farthest coordinate", "--scale", "beyond"],
        )],
        &["spacing 1.25e299"],
    );
}
