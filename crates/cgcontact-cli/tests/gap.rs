//! `cgcontact locate --gap D` end to end, on a block with a step written by hand (legacy ASCII
//! VTK, cells in reverse order) and moved rigidly: its surface is the undeformed one translated, so
//! each point's gap, closest point, normal and face follow from the construction.

use std::process::Command;

/// VTK hexahedron corner offsets.
const CORNERS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];
/// The rigid motion of every node.
const T: [f64; 3] = [0.01, -0.02, 0.03];
/// Cells 3 × 2 × 2 of edge 1, less the upper back right one: a step.
const CELLS: [u32; 3] = [3, 2, 2];
const MISSING: [u32; 3] = [2, 1, 1];

fn cgcontact(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// The cells in file order (reversed lattice order, the missing one left out).
fn cells() -> Vec<[u32; 3]> {
    let mut cells = Vec::new();
    for k in 0..CELLS[2] {
        for j in 0..CELLS[1] {
            for i in 0..CELLS[0] {
                if [i, j, k] != MISSING {
                    cells.push([i, j, k]);
                }
            }
        }
    }
    cells.reverse();
    cells
}

fn write_mesh(path: &std::path::Path) {
    let n = CELLS.map(|c| c + 1);
    let node = |p: [u32; 3]| p[0] + n[0] * (p[1] + n[1] * p[2]);
    let count = n[0] * n[1] * n[2];
    let mut text = format!(
        "# vtk DataFile Version 3.0\nstep\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {count} double\n"
    );
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                text += &format!("{i} {j} {k}\n");
            }
        }
    }
    let cells = cells();
    text += &format!("CELLS {} {}\n", cells.len(), 9 * cells.len());
    for c in &cells {
        let ids: Vec<String> = CORNERS
            .iter()
            .map(|o| node([c[0] + o[0], c[1] + o[1], c[2] + o[2]]).to_string())
            .collect();
        text += &format!("8 {}\n", ids.join(" "));
    }
    text += &format!("CELL_TYPES {}\n", cells.len());
    text += &"12\n".repeat(cells.len());
    text += &format!("POINT_DATA {count}\nVECTORS displacement double\n");
    text += &format!("{} {} {}\n", T[0], T[1], T[2]).repeat(count as usize);
    std::fs::write(path, text).unwrap();
}

/// A point, and what its gap columns must say: (gap, closest point, normal, cell, face), or
/// `None` beyond the distance. Positions are undeformed ones; the motion is added.
type Expected = Option<(f64, [f64; 3], [f64; 3], [u32; 3], &'static [u8])>;

fn cases() -> Vec<([f64; 3], Expected)> {
    vec![
        // Above the top of cell (0, 0, 1): a face's interior.
        (
            [0.5, 0.5, 2.3],
            Some((0.3, [0.5, 0.5, 2.0], [0.0, 0.0, 1.0], [0, 0, 1], &[5])),
        ),
        // Inside the same cell, 0.2 under its top.
        (
            [0.5, 0.5, 1.8],
            Some((-0.2, [0.5, 0.5, 2.0], [0.0, 0.0, 1.0], [0, 0, 1], &[5])),
        ),
        // Beside the +x face of cell (2, 0, 0).
        (
            [3.3, 0.5, 0.5],
            Some((0.3, [3.0, 0.5, 0.5], [1.0, 0.0, 0.0], [2, 0, 0], &[1])),
        ),
        // Beyond the convex edge x = 3, z = 2 of cell (2, 0, 1) (its +x face's or its top's): the
        // normal points from the edge.
        (
            [3.3, 0.25, 2.4],
            Some((0.5, [3.0, 0.25, 2.0], [0.6, 0.0, 0.8], [2, 0, 1], &[1, 5])),
        ),
        // Far from everything.
        ([10.0, 10.0, 10.0], None),
    ]
}

#[test]
fn gap_columns_match_the_construction() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("step.vtk");
    write_mesh(&mesh);
    let cases = cases();
    let points: String = cases
        .iter()
        .map(|(p, _)| format!("{},{},{}\n", p[0] + T[0], p[1] + T[1], p[2] + T[2]))
        .collect();
    let points_path = dir.path().join("points.csv");
    std::fs::write(&points_path, points).unwrap();
    let file_cells = cells();
    for owners in [false, true] {
        let out = dir.path().join("out.csv");
        let mut args = vec![
            "locate",
            "--mesh",
            mesh.to_str().unwrap(),
            "--points",
            points_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--gap",
            "0.6",
            "--quiet",
        ];
        if owners {
            args.push("--all-owners");
        }
        let run = cgcontact(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let text = std::fs::read_to_string(&out).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "point,cell,xi,eta,zeta,iterations,residual,inversions,gap,cx,cy,cz,nx,ny,nz,face_cell,face"
        );
        let mut seen = vec![0; cases.len()];
        for line in lines {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 17, "{line}");
            let point: usize = f[0].parse().unwrap();
            seen[point] += 1;
            match cases[point].1 {
                None => assert!(f[8..].iter().all(|v| v.is_empty()), "{line}"),
                Some((gap, c, n, cell, face)) => {
                    let num = |i: usize| f[i].parse::<f64>().unwrap();
                    assert!((num(8) - gap).abs() < 1e-12, "{line}");
                    for a in 0..3 {
                        assert!((num(9 + a) - (c[a] + T[a])).abs() < 1e-12, "{line}");
                        assert!((num(12 + a) - n[a]).abs() < 1e-12, "{line}");
                    }
                    let index = file_cells.iter().position(|&x| x == cell).unwrap();
                    assert_eq!(f[15], index.to_string(), "{line}");
                    assert!(face.contains(&f[16].parse().unwrap()), "{line}");
                }
            }
        }
        assert!(
            seen.iter().all(|&s| s >= 1),
            "every point has a row: {seen:?}"
        );
    }
}

#[test]
fn bad_distances_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("step.vtk");
    write_mesh(&mesh);
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "0,0,0\n").unwrap();
    for bad in ["-1", "NaN", "inf"] {
        let run = cgcontact(&[
            "locate",
            "--mesh",
            mesh.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--gap",
            bad,
        ]);
        assert_eq!(run.status.code(), Some(2), "--gap {bad}");
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(err.contains("--gap"), "{err}");
    }
}

/// A row's `cell` and `gap` agree in both precisions: points a hair outside the step's faces,
/// edges and corners (1e-9 to 2e-6 of a cell, within f32's inside tolerance for the smaller
/// ones), and as far inside: wherever the row names a cell, its gap is at most 0, and where it
/// names none, its gap is positive. The gap was measured in f64 whatever `--precision`, so f32
/// rows said "cell 4" beside a positive gap.
#[test]
fn a_rows_cell_and_gap_sign_agree_in_both_precisions() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("step.vtk");
    write_mesh(&mesh);
    let mut points = String::from("x,y,z\n");
    for d in [1e-9, 1e-7, 5e-7, 1e-6, 2e-6] {
        for s in [1.0, -1.0] {
            let e = s * d;
            // Past the top face (z = 2), the front face (y = 0), the step's inner face (x = 2
            // above z = 1), an edge and a corner.
            for p in [
                [0.5, 0.5, 2.0 + e],
                [1.5, -e, 0.5],
                [2.0 + e, 1.5, 1.5],
                [3.0 + e, -e, 0.5],
                [3.0 + e, 2.0 + e, 1.0 + e],
            ] {
                points += &format!("{},{},{}\n", p[0] + T[0], p[1] + T[1], p[2] + T[2]);
            }
        }
    }
    let points_path = dir.path().join("points.csv");
    std::fs::write(&points_path, points).unwrap();
    for precision in ["f64", "f32"] {
        let out = dir.path().join(format!("{precision}.csv"));
        let run = cgcontact(&[
            "locate",
            "--mesh",
            mesh.to_str().unwrap(),
            "--points",
            points_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--gap",
            "0.5",
            "--precision",
            precision,
            "--quiet",
        ]);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let text = std::fs::read_to_string(&out).unwrap();
        let (mut held, mut rows) = (0, 0);
        for line in text.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let cell: i64 = f[1].parse().unwrap();
            let gap: f64 = f[8].parse().unwrap();
            assert_eq!(cell >= 0, gap <= 0.0, "{precision}: {line}");
            held += usize::from(cell >= 0);
            rows += 1;
        }
        assert_eq!(rows, 50);
        // The 25 inside are held; in f32 some a hair outside too (the case at stake).
        let least = if precision == "f32" { 26 } else { 25 };
        assert!(held >= least, "{precision}: {held} held");
    }
}
