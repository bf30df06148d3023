//! Regressions of the CLI audit:
//! - two outputs of one run on one file through a *dangling* symbolic link were not seen: the
//!   check compared the link's own name, while the write follows the link to its target. `scene
//!   --out d` with `d/known.csv -> mesh.vtu` (no `mesh.vtu` yet) exited 0 with the mesh replaced
//!   by the known answers; likewise `demo`, `tradeoff`, and `locate --out` into its `--vtk`
//!   folder. A link whose target existed was refused already.
//! - a run ended by Ctrl-C or SIGTERM left the folders it had made for its outputs, empty; a run
//!   that fails removes them.

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn cgcontact(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// A block of 2 × 2 × 2 cells and 5 known points, in `dir/scene`.
fn small_scene(dir: &Path) -> std::path::PathBuf {
    let scene = dir.join("scene");
    let made = cgcontact(&[
        "scene",
        "block",
        "--cells",
        "2,2,2",
        "--known",
        "5",
        "--out",
        s(&scene),
    ]);
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    scene
}

fn refused_naming(run: &Output, names: &[&str]) {
    let message = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{message}");
    assert_eq!(message.lines().count(), 1, "{message}");
    for name in names {
        assert!(message.contains(name), "{name} not in: {message}");
    }
}

#[cfg(unix)]
#[test]
fn a_dangling_link_to_another_output_of_the_run_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (case, (command, link, target)) in [
        (
            &["scene", "block", "--cells", "2,2,2", "--known", "5"][..],
            "known.csv",
            "mesh.vtu",
        ),
        (&["demo", "--coarse", "-q"], "results.csv", "block.vtu"),
        (&["tradeoff", "--quick"], "scale.svg", "tradeoff.md"),
        // A chain of links, one of them into a folder.
        (&["tradeoff", "--quick"], "scale.svg", "sub/x.svg"),
    ]
    .into_iter()
    .enumerate()
    {
        let out = dir.path().join(format!("{case}-{}", command[0]));
        std::fs::create_dir_all(out.join("sub")).unwrap();
        std::os::unix::fs::symlink(target, out.join(link)).unwrap();
        if target == "sub/x.svg" {
            std::os::unix::fs::symlink("../tradeoff.md", out.join(target)).unwrap();
        }
        let run = cgcontact(&[command, &["--out", s(&out)]].concat());
        // Both files named: the link and the file it leads to.
        let last = if target == "sub/x.svg" {
            "tradeoff.md"
        } else {
            target
        };
        refused_naming(&run, &["the same file as", link, last]);
        assert!(!out.join("tradeoff.md").exists() && !out.join("mesh.vtu").exists());
        assert!(!out.join("block.vtu").exists(), "{command:?}");
    }
    // locate: its results through a dangling link into its own --vtk folder.
    let scene = small_scene(dir.path());
    let out = dir.path().join("locate");
    std::fs::create_dir_all(out.join("vt")).unwrap();
    std::os::unix::fs::symlink("vt/points.vtu", out.join("r.csv")).unwrap();
    let run = cgcontact(&[
        "locate",
        "--mesh",
        s(&scene.join("mesh.vtu")),
        "--points",
        s(&scene.join("points.csv")),
        "--out",
        s(&out.join("r.csv")),
        "--vtk",
        s(&out.join("vt")),
    ]);
    refused_naming(&run, &["would both write", "--out", "--vtk"]);
    assert!(!out.join("vt/points.vtu").exists());
}

/// The run waits on its points, a named pipe no one writes, with its `--vtk` folder made.
#[cfg(target_os = "linux")]
#[test]
fn an_interrupted_run_removes_the_folders_it_made() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_scene(dir.path());
    let pipe = dir.path().join("points.pipe");
    assert!(
        Command::new("mkfifo")
            .arg(&pipe)
            .status()
            .unwrap()
            .success()
    );
    let kept = dir.path().join("kept");
    std::fs::create_dir(&kept).unwrap();
    for signal in ["-INT", "-TERM"] {
        let vtk = kept.join("new/deeper/vtk");
        let run = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
            .args([
                "locate",
                "--mesh",
                s(&scene.join("mesh.vtu")),
                "--points",
                s(&pipe),
            ])
            .args(["--vtk", s(&vtk)])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until the folder is made (the run then waits for a writer of the pipe).
        let start = std::time::Instant::now();
        while !vtk.is_dir() && start.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(vtk.is_dir(), "{signal}: the folder was never made");
        let sent = Command::new("kill")
            .args([signal, &run.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let output = run.wait_with_output().unwrap();
        assert_eq!(output.status.code(), Some(130), "{signal}");
        assert!(
            !kept.join("new").exists(),
            "{signal}: a folder it made is left"
        );
        assert!(kept.is_dir(), "{signal}: a folder that was there is gone");
    }
}
