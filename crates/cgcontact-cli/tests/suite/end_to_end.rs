//! The command line end to end, as a user runs it: write a scene, locate its points, compare the
//! results with the scene's known answers (cell in the mesh file's numbering, ξ).

use std::path::Path;
use std::process::Command;

use cgcontact_io::read_results;

fn cgcontact(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// known.csv: point,cell,xi,eta,zeta.
fn known(path: &Path) -> Vec<(usize, usize, [f64; 3])> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let xi = [
                f[2].parse().unwrap(),
                f[3].parse().unwrap(),
                f[4].parse().unwrap(),
            ];
            (f[0].parse().unwrap(), f[1].parse().unwrap(), xi)
        })
        .collect()
}

fn scene_then_locate(scene_args: &[&str], locate_args: &[&str], xi_bound: f64) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let scene = cgcontact(&[&["scene"], scene_args, &["--out", out]].concat());
    assert!(
        scene.status.success(),
        "{}",
        String::from_utf8_lossy(&scene.stderr)
    );
    let mesh = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.file_stem().is_some_and(|s| s == "mesh"))
        .unwrap();
    let results = dir.path().join("results.csv");
    let points = format!("{out}/points.csv");
    let vtk = dir.path().join("vtk");
    let run = cgcontact(
        &[
            &[
                "locate",
                "--mesh",
                mesh.to_str().unwrap(),
                "--points",
                &points,
            ][..],
            &[
                "--out",
                results.to_str().unwrap(),
                "--json",
                "--vtk",
                vtk.to_str().unwrap(),
            ],
            locate_args,
        ]
        .concat(),
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&run.stdout).expect("--json prints one JSON object");
    for key in [
        "points",
        "located",
        "setup_seconds",
        "query_seconds",
        "points_per_second",
        "strategy",
        "precision",
        "threads",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
    let rows = read_results(&results).unwrap();
    let known = known(&dir.path().join("known.csv"));
    assert!(!known.is_empty());
    for (point, cell, xi) in known {
        let row = &rows[point];
        assert_eq!(row.point, point);
        assert_eq!(row.cell, Some(cell), "point {point}");
        let error = (row.xi - cgcontact::glam::DVec3::from_array(xi))
            .abs()
            .max_element();
        assert!(error < xi_bound, "point {point}: xi {} vs {xi:?}", row.xi);
    }
    assert_eq!(summary["points"].as_u64().unwrap() as usize, rows.len());
    assert!(vtk.join("mesh.vtu").exists() && vtk.join("points.vtu").exists());
}

#[test]
fn coarse_sphere_scene_located_as_known() {
    scene_then_locate(&["sphere-coarse", "--known", "2000"], &[], 1e-10);
}

#[test]
fn legacy_binary_jittered_anisotropic_offset_scene() {
    scene_then_locate(
        &[
            "sphere-coarse",
            "--known",
            "1000",
            "--format",
            "vtk-binary",
            "--jitter",
            "0.3",
            "--h",
            "0.5,0.25,0.125",
            "--offset",
            "1000",
        ],
        &["--threads", "1"],
        1e-8,
    );
}

#[test]
fn every_strategy_and_f32_on_a_small_scene() {
    for strategy in ["lattice", "rtree", "brute", "centroid", "noderad"] {
        scene_then_locate(
            &["sphere-coarse", "--known", "300", "--format", "vtk"],
            &["--strategy", strategy],
            1e-10,
        );
    }
    scene_then_locate(
        &["sphere-coarse", "--known", "300"],
        &["--precision", "f32"],
        1e-4,
    );
}

#[test]
fn demo_writes_its_files_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let run = cgcontact(&["demo", "--out", out.to_str().unwrap(), "--json"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["points"], 6700);
    let located = summary["located"].as_u64().unwrap();
    assert!((100..1000).contains(&located), "{located}");
    for file in ["results.csv", "block.vtu", "points.vtu", "contact.svg"] {
        assert!(out.join(file).exists(), "{file}");
    }
    let svg = std::fs::read_to_string(out.join("contact.svg")).unwrap();
    assert!(svg.contains("<polygon") && svg.contains("<circle"));
    let rows = read_results(out.join("results.csv")).unwrap();
    assert_eq!(
        rows.iter().filter(|r| r.cell.is_some()).count() as u64,
        located
    );
}

/// `--repeat N` times the query N more times and reports the min and the median; without it, the
/// summary has neither.
#[test]
fn repeat_reports_min_and_median() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let scene = cgcontact(&[
        "scene", "block", "--cells", "3,3,2", "--known", "200", "--out", out,
    ]);
    assert!(
        scene.status.success(),
        "{}",
        String::from_utf8_lossy(&scene.stderr)
    );
    let (mesh, points) = (format!("{out}/mesh.vtu"), format!("{out}/points.csv"));
    let json = |extra: &[&str]| -> serde_json::Value {
        let run = cgcontact(
            &[
                &["locate", "--mesh", &mesh, "--points", &points, "--json"],
                extra,
            ]
            .concat(),
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        serde_json::from_slice(&run.stdout).unwrap()
    };
    let repeated = json(&["--repeat", "5"]);
    let (min, median) = (
        repeated["query_seconds_min"].as_f64().unwrap(),
        repeated["query_seconds_median"].as_f64().unwrap(),
    );
    assert!(0.0 < min && min <= median, "{repeated}");
    let once = json(&[]);
    assert!(once.get("query_seconds_min").is_none(), "{once}");
}

/// Rows not located had `NaN` for ξ but an empty `inversions`: now every row carries its count,
/// and the lattice strategy's misses show the inversions they cost.
#[test]
fn rows_not_located_carry_their_inversions() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let demo = cgcontact(&["demo", "--coarse", "--out", out, "--quiet"]);
    assert!(
        demo.status.success(),
        "{}",
        String::from_utf8_lossy(&demo.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("results.csv")).unwrap();
    let mut missed_with_work = 0;
    for line in text.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        // The usual 8 columns, then the demo's 9 gap columns.
        assert_eq!(fields.len(), 17, "{line}");
        let inversions: u32 = fields[7].parse().unwrap_or_else(|_| panic!("{line}"));
        if fields[1] == "-1" {
            assert!(
                fields[2..5].iter().all(|f| *f == "NaN") && fields[5] == "0",
                "{line}"
            );
            missed_with_work += usize::from(inversions > 0);
        } else {
            assert!(inversions >= 1, "{line}");
        }
    }
    assert!(
        missed_with_work > 0,
        "no miss near the body cost an inversion"
    );
    assert!(read_results(dir.path().join("results.csv")).is_ok());
}

/// No point located: the summary's per-located-point figure is 0, not the −0 of an empty float
/// sum ("-0.000 per located point" before), in the text and in `--json`.
#[test]
fn nothing_located_reports_zero_per_located_point() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let scene = cgcontact(&["scene", "sphere-coarse", "--known", "10", "--out", out]);
    assert!(scene.status.success());
    let far = dir.path().join("far.csv");
    std::fs::write(&far, "x,y,z\n1000,1000,1000\n").unwrap();
    let mesh = dir.path().join("mesh.vtu");
    let results = dir.path().join("results.csv");
    let args = |json: bool| {
        let mut args = vec!["locate", "--mesh", mesh.to_str().unwrap()];
        args.extend(["--points", far.to_str().unwrap(), "--out"]);
        args.push(results.to_str().unwrap());
        if json {
            args.push("--json");
        }
        cgcontact(&args)
    };
    let text = String::from_utf8(args(false).stdout).unwrap();
    assert!(text.contains("(0.000 per located point)"), "{text}");
    let json = String::from_utf8(args(true).stdout).unwrap();
    assert!(
        json.contains("\"inversions_per_located_point\": 0.0,"),
        "{json}"
    );
}

#[test]
fn adaptive_scene_located_as_known_by_every_strategy() {
    for strategy in ["lattice", "rtree", "brute", "centroid", "noderad"] {
        scene_then_locate(
            &["sphere-adaptive", "--h", "0.5", "--known", "300"],
            &["--strategy", strategy],
            1e-10,
        );
    }
    // Unbalanced (jumps of two levels), cells shuffled, legacy ASCII, jittered, far from the origin.
    scene_then_locate(
        &[
            "sphere-adaptive",
            "--h",
            "0.5",
            "--known",
            "1000",
            "--unbalanced",
            "--levels",
            "3",
            "--shuffle",
            "--format",
            "vtk",
            "--jitter",
            "0.2",
            "--offset",
            "1000",
        ],
        &["--threads", "1"],
        1e-8,
    );
    scene_then_locate(
        &["sphere-adaptive", "--h", "0.5", "--known", "300"],
        &["--precision", "f32"],
        1e-4,
    );
}

/// A hanging node moved off its constraint: a warning naming the count and the worst node's
/// offset, the same in `--json` (`hanging_constraints`, also under `--quiet`), or with `--strict`
/// exit code 2.
#[test]
fn broken_hanging_node_warns_and_strict_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let body = cgcontact_scenes::hanging_node_moved(0.01).unwrap();
    let mesh = dir.path().join("mesh.vtu");
    cgcontact_io::write_adaptive_mesh(&mesh, &body, cgcontact_io::MeshFormat::Xml).unwrap();
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "x,y,z\n0.5,0.5,0.5\n1.5,0.25,0.25\n").unwrap();
    let (mesh, points) = (mesh.to_str().unwrap(), points.to_str().unwrap());
    let run = cgcontact(&["locate", "--mesh", mesh, "--points", points, "--json"]);
    assert!(run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("1 of 5 hanging nodes") && stderr.contains("1.000e-2"),
        "{stderr}"
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["levels"], 2);
    assert_eq!(summary["hanging_nodes"], 5);
    assert_eq!(summary["located"], 2);
    // The same in `--json`, which `--quiet` does not silence.
    let quiet = cgcontact(&[
        "locate", "--mesh", mesh, "--points", points, "--json", "--quiet",
    ]);
    assert!(quiet.status.success() && quiet.stderr.is_empty());
    let summary: serde_json::Value = serde_json::from_slice(&quiet.stdout).unwrap();
    let constraints = &summary["hanging_constraints"];
    assert_eq!(constraints["violating"], 1, "{summary}");
    assert!((constraints["worst_offset"].as_f64().unwrap() - 0.01).abs() < 1e-12);
    assert_eq!(constraints["tolerance"].as_array().unwrap().len(), 3);
    let fine = cgcontact_scenes::hanging_node_moved(0.0).unwrap();
    cgcontact_io::write_adaptive_mesh(
        dir.path().join("fine.vtu"),
        &fine,
        cgcontact_io::MeshFormat::Xml,
    )
    .unwrap();
    let fine = dir.path().join("fine.vtu");
    let run = cgcontact(&[
        "locate",
        "--mesh",
        fine.to_str().unwrap(),
        "--points",
        points,
        "--json",
    ]);
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(summary.get("hanging_constraints").is_none(), "{summary}");
    let strict = cgcontact(&["locate", "--mesh", mesh, "--points", points, "--strict"]);
    assert_eq!(strict.status.code(), Some(2));
    assert!(!String::from_utf8_lossy(&strict.stderr).contains("warning"));
    assert!(String::from_utf8_lossy(&strict.stderr).contains("break their constraint"));
}

/// Two cells at 1e7 from the origin, 1.6e-5 thin along z, sheared by u_z = s (Y − Y0): with
/// s = 1e3 a rounding of y moves ξ_z by about 1.1 (both cells named, a point given both cells);
/// with s = 10, by about 0.01 (no warning).
#[test]
fn cells_sheared_beyond_the_coordinates_resolution_warn() {
    let run = |shear: f64, extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let origin = -1e7;
        let h = cgcontact::glam::DVec3::new(0.03125, 0.001953125, 1.5625e-5);
        let lattice =
            cgcontact::Lattice::new(cgcontact::glam::DVec3::splat(origin), h, [1, 1, 2]).unwrap();
        let mut body = cgcontact::Body::full(lattice);
        body.update_displacements(|_, x, u| {
            *u = cgcontact::glam::DVec3::new(0.0, 0.0, shear * (x.y - origin));
        })
        .unwrap();
        let mesh = dir.path().join("mesh.vtu");
        cgcontact_io::write_mesh(&mesh, &body, cgcontact_io::MeshFormat::Xml).unwrap();
        // On the cells' common edge at y = Y0, halfway up the upper cell: in cell 1 alone.
        let points = dir.path().join("points.csv");
        std::fs::write(&points, "x,y,z\n-1e7,-1e7,-9999999.999976562\n").unwrap();
        let out = dir.path().join("out.csv");
        let mut args = vec![
            "locate",
            "--mesh",
            mesh.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let run = cgcontact(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let rows = std::fs::read_to_string(&out).unwrap().lines().count() - 1;
        (run, rows)
    };
    let (sheared, _) = run(1e3, &["--json"]);
    let stderr = String::from_utf8_lossy(&sheared.stderr);
    assert!(
        stderr.contains("2 cell(s) are sheared or distorted"),
        "{stderr}"
    );
    let summary: serde_json::Value = serde_json::from_slice(&sheared.stdout).unwrap();
    assert_eq!(summary["unresolved_cells"], serde_json::json!([0, 1]));
    let share = summary["unresolved_share"].as_f64().unwrap();
    assert!(share > 1.0 && share < 1.3, "{share}");
    // What the warning is about: the point is given the cell beside it as well.
    assert_eq!(run(1e3, &["--all-owners"]).1, 2);
    let (mild, rows) = run(10.0, &["--json", "--all-owners"]);
    assert!(!String::from_utf8_lossy(&mild.stderr).contains("sheared"));
    let summary: serde_json::Value = serde_json::from_slice(&mild.stdout).unwrap();
    assert_eq!(summary["unresolved_cells"], serde_json::json!([]));
    assert!(summary.get("unresolved_share").is_none());
    assert_eq!(rows, 1);
}

#[test]
fn adaptive_demo_writes_levels() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let run = cgcontact(&[
        "demo",
        "--adaptive",
        "--coarse",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["levels"], 3);
    assert!(summary["hanging_nodes"].as_u64().unwrap() > 0);
    assert!(summary["located"].as_u64().unwrap() > 0);
    let svg = std::fs::read_to_string(out.join("contact.svg")).unwrap();
    assert!(svg.contains("level 2") && svg.contains("<polygon"));
    let block = std::fs::read_to_string(out.join("block.vtu")).unwrap();
    assert!(block.contains("Name=\"level\""));
    let rows = read_results(out.join("results.csv")).unwrap();
    assert_eq!(
        rows.iter().filter(|r| r.cell.is_some()).count() as u64,
        summary["located"].as_u64().unwrap()
    );
}
