//! A run out of memory aborted: `memory allocation of N bytes failed`, exit code 134 (SIGABRT),
//! and the temporary file of a write in progress left behind. Under a limit on the address space
//! (`ulimit -v`, as batch systems set) a mesh too large for it must end the run as any other
//! error does: one line, exit code 2, outputs as they were or whole.
#![cfg(target_os = "linux")]

use std::path::Path;
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_cgcontact");

/// `cgcontact ARGS` under `ulimit -v KIB`.
fn capped(kib: u64, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(args)
        .output()
        .expect("sh runs")
}

/// Every file and folder below `dir`, relative to it.
fn listing(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, all: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            all.push(
                path.strip_prefix(root)
                    .unwrap()
                    .to_string_lossy()
                    .into_owned(),
            );
            if path.is_dir() {
                walk(root, &path, all);
            }
        }
    }
    let mut all = Vec::new();
    walk(dir, dir, &mut all);
    all.sort();
    all
}

#[test]
fn a_run_out_of_memory_ends_with_exit_code_2_and_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let made = Command::new(BIN)
        .args([
            "scene", "block", "--cells", "30,30,30", "--known", "2000", "--out",
        ])
        .arg(&scene)
        .output()
        .unwrap();
    assert!(made.status.success(), "{made:?}");
    let (mesh, points) = (scene.join("mesh.vtu"), scene.join("points.csv"));
    // The smallest limit the program starts under, in steps of 8 MiB: below it the loader fails,
    // before any code of ours runs.
    let start = (1..64)
        .map(|k| k * 8192)
        .find(|&kib| capped(kib, &["--version"]).status.success())
        .expect("the program starts under 512 MiB");
    let out = dir.path().join("out");
    let (results, vtk) = (out.join("results.csv"), out.join("vtk"));
    let mut out_of_memory = 0;
    // From the start up, by 8 MiB: the 4.5 MB mesh's read and the VTK files written need more
    // than the start, so the first limits fail, some while writing; the last ones pass.
    for kib in (0..24).map(|k| start + k * 8192) {
        std::fs::create_dir_all(&out).unwrap();
        let run = capped(
            kib,
            &[
                "locate",
                "--mesh",
                mesh.to_str().unwrap(),
                "--points",
                points.to_str().unwrap(),
                "--out",
                results.to_str().unwrap(),
                "--vtk",
                vtk.to_str().unwrap(),
                "--quiet",
            ],
        );
        let message = String::from_utf8_lossy(&run.stderr);
        let files = listing(&out);
        match run.status.code() {
            Some(0) => assert!(
                files.contains(&"results.csv".to_owned()) && files.len() > 2,
                "ulimit -v {kib}: {files:?}"
            ),
            Some(2) => {
                assert_eq!(message.lines().count(), 1, "ulimit -v {kib}: {message}");
                assert!(message.starts_with("cgcontact: "), "{message}");
                out_of_memory += usize::from(message.contains("out of memory"));
                // Whole or absent: results.csv is written before the VTK files, and the folder
                // made for these is removed again while empty.
                assert!(
                    files.is_empty() || files == ["results.csv"] || files.len() > 2,
                    "ulimit -v {kib}: {files:?} after {message}"
                );
            }
            code => panic!("ulimit -v {kib}: exit code {code:?}: {message}"),
        }
        assert!(
            !files.iter().any(|f| f.contains(".partial")),
            "ulimit -v {kib}: a temporary file is left: {files:?}"
        );
        std::fs::remove_dir_all(&out).unwrap();
    }
    assert!(out_of_memory > 0, "no limit from {start} KiB up ran out");
}
