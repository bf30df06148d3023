//! `cgcontact locate --all-owners` on adaptive meshes written by VTK 9.7.2
//! (fixtures/vtk-written-adaptive, made by its make.py, which computed every owner of each point
//! and its ξ): the rows name the file's cells, every owner of a point on a shared node, edge or
//! face, and a hanging node's coarse cell among them, on cells sheared by x += 10 z and x += 1e3 z
//! far from the origin too. And on meshes from VTK's HyperTreeGrid pipeline
//! (fixtures/vtk-written-htg): vtkHyperTreeGridToUnstructuredGrid's voxels, masked cells as holes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use cgcontact_io::read_results;

fn folder() -> PathBuf {
    fixtures("vtk-written-adaptive")
}

fn fixtures(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// Per point: (x, y, z) as written, and its owners (file cell, ξ).
type Row = (String, Vec<(usize, [f64; 3])>);

/// Rows of a results file by point: (cell, ξ) of each owner.
type Found = BTreeMap<usize, Vec<(usize, [f64; 3])>>;

fn expected(scene: &str) -> Vec<Row> {
    expected_in(&folder(), scene)
}

fn expected_in(dir: &Path, scene: &str) -> Vec<Row> {
    std::fs::read_to_string(dir.join(format!("{scene}.expected.csv")))
        .unwrap()
        .lines()
        .skip(2)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let owners = f[3]
                .split('|')
                .filter(|e| !e.is_empty())
                .map(|e| {
                    let v: Vec<f64> = e.split(' ').map(|v| v.parse().unwrap()).collect();
                    (v[0] as usize, [v[1], v[2], v[3]])
                })
                .collect();
            (f[..3].join(","), owners)
        })
        .collect()
}

/// Runs `locate --all-owners` with `flags` on `mesh`; the exit status, stderr and rows by point.
fn locate(mesh: &str, rows: &[Row], flags: &[&str]) -> (std::process::Output, Found) {
    locate_in(&folder(), mesh, rows, flags)
}

fn locate_in(
    dir: &Path,
    mesh: &str,
    rows: &[Row],
    flags: &[&str],
) -> (std::process::Output, Found) {
    let tmp = tempfile::tempdir().unwrap();
    let points = tmp.path().join("points.csv");
    let text: String = rows.iter().map(|(x, _)| format!("{x}\n")).collect();
    std::fs::write(&points, format!("x,y,z\n{text}")).unwrap();
    let out = tmp.path().join("owners.csv");
    let mut args = vec![
        "locate".to_string(),
        "--mesh".into(),
        dir.join(mesh).to_str().unwrap().into(),
        "--points".into(),
        points.to_str().unwrap().into(),
        "--out".into(),
        out.to_str().unwrap().into(),
        "--all-owners".into(),
    ];
    args.extend(flags.iter().map(|f| f.to_string()));
    let run = Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(&args)
        .output()
        .unwrap();
    let mut found = Found::new();
    if run.status.success() {
        for row in read_results(&out).unwrap() {
            let entry = found.entry(row.point).or_default();
            if let Some(cell) = row.cell {
                entry.push((cell, row.xi.to_array()));
            }
        }
    }
    (run, found)
}

#[test]
fn every_owner_of_every_point_in_the_files_numbering() {
    // Each mesh with its finest cells' shortest edge, or less (for the ξ bound below).
    every_owner_in(
        &folder(),
        &[
            ("jumps", "jumps.appended-zlib.vtu", 0.0625),
            ("balanced", "balanced.legacy-binary.vtk", 0.0625),
            ("all-refined", "all-refined.appended.vtu", 0.0625),
            // Spacings 4 x 0.25 x 0.002 (finest z edge 0.0005), sheared by x += 10 z at 1e5 and by
            // x += 1e3 z at -1e7: nodes lost owners at c203d69, whose inside test took its allowance
            // for rounding from J⁻¹'s diagonal alone (92 of 940 and 209 of 1315 owners missed).
            ("sheared-1e5", "sheared-1e5.appended-zlib.vtu", 0.0005),
            ("sheared-m1e7", "sheared-m1e7.binary-zlib.vtu", 0.0005),
        ],
        &[],
    );
}

/// vtkHyperTreeGridToUnstructuredGrid's meshes (voxels with float32 points at 1e5, masked cells,
/// jumps of 3 levels, unmerged and merged, sheared by x += 10 z), with the lattice, brute force
/// and the R-tree. The raw appended file's `OriginalIds` holds more values than it has cells
/// (a value per leaf, masked ones too): refused before an unread cell array could.
#[test]
fn hyper_tree_grids_converted_by_vtk() {
    let dir = fixtures("vtk-written-htg");
    let meshes = [
        ("masked-1e5", "masked-1e5.appended.vtu", 0.015625),
        ("masked-1e5", "masked-1e5.legacy-binary.vtk", 0.015625),
        ("jumps-sheared", "jumps-sheared.binary-zlib.vtu", 0.015625),
    ];
    for strategy in [&[][..], &["--strategy", "brute"], &["--strategy", "rtree"]] {
        every_owner_in(&dir, &meshes, strategy);
    }
}

/// `locate --all-owners --strict` with 1 and 3 threads and `flags` on each (scene, mesh, finest
/// edge): every expected owner and no other, each ξ to the rounding of the point's coordinates.
fn every_owner_in(dir: &Path, meshes: &[(&str, &str, f64)], flags: &[&str]) {
    for &(scene, mesh, edge) in meshes {
        let rows = expected_in(dir, scene);
        for threads in ["1", "3"] {
            let mut all = vec!["--threads", threads, "--strict"];
            all.extend(flags);
            let (run, found) = locate_in(dir, mesh, &rows, &all);
            assert!(
                run.status.success() && run.stderr.is_empty(),
                "{mesh} {flags:?}: {}",
                String::from_utf8_lossy(&run.stderr)
            );
            assert_eq!(found.len(), rows.len(), "{mesh}");
            for (p, (x, owners)) in rows.iter().enumerate() {
                let got = &found[&p];
                let cells: Vec<usize> = got.iter().map(|g| g.0).collect();
                let want: Vec<usize> = owners.iter().map(|o| o.0).collect();
                assert_eq!(cells, want, "{mesh} {flags:?}: point {p} at {x}");
                let magnitude = x
                    .split(',')
                    .map(|v| v.parse::<f64>().unwrap().abs())
                    .fold(0.0, f64::max);
                for ((_, xi), (_, known)) in got.iter().zip(owners) {
                    // The rounding of the point's coordinates, in ξ of a finest cell at most (a
                    // sheared cell's J⁻¹, 2 s / h_x with s = 10 or 1e3, stays below 2 / edge).
                    let bound = 1e-10 + 64.0 * f64::EPSILON * magnitude / edge;
                    assert!(
                        (0..3).all(|a| (xi[a] - known[a]).abs() <= bound),
                        "{mesh} {flags:?}: point {p}: {xi:?} vs {known:?}"
                    );
                }
            }
        }
    }
}

/// Spacings 1 : 1e-3 : 0.1 as VTK's legacy ASCII writer rounds them (11 digits): `--strict`
/// accepts the file (its hanging nodes are within 1e-9 of a cell along each axis), where the
/// check with the shortest axis's tolerance everywhere had refused it.
#[test]
fn regression_strict_accepts_an_anisotropic_legacy_ascii_mesh() {
    let rows = expected("aniso-1e3");
    let (run, found) = locate("aniso-1e3.legacy-ascii.vtk", &rows, &["--strict"]);
    assert!(
        run.status.success() && run.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // Points inside one cell are found there, whatever the rounding of the file.
    for (p, (x, owners)) in rows.iter().enumerate() {
        if owners.len() == 1 && owners[0].1.iter().all(|v| v.abs() < 1.0) {
            let cells: Vec<usize> = found[&p].iter().map(|g| g.0).collect();
            assert_eq!(cells, [owners[0].0], "point {p} at {x}");
        }
    }
}
