//! `cgcontact locate --all-owners` end to end: small meshes written by hand (legacy ASCII VTK, cells
//! in a shuffled order), points placed at known undeformed positions (on a node shared by 8 cells,
//! an edge shared by 4, a face shared by 2, inside one cell, outside, at hanging nodes of a
//! fine/coarse interface), then deformed by the meshes' own trilinear maps. The expected owners of
//! a point are the cells whose undeformed box holds its undeformed position, named by their place
//! in the file, with ξ from that position: obtained from the construction, not from the program.

use std::collections::BTreeMap;
use std::process::Command;

use cgcontact_io::{ResultRow, read_results};

/// VTK hexahedron corner offsets, in units of the cell's edge.
const CORNERS: [[i64; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// Every strategy `locate --strategy` accepts with `--all-owners` (all but `noderad-seed`, refused).
const STRATEGIES: [&str; 5] = ["lattice", "centroid", "noderad", "rtree", "brute"];

fn cgcontact(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cgcontact"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A cell: lowest corner and edge, in units of the finest spacing.
#[derive(Clone, Copy, Debug)]
struct Cell {
    low: [i64; 3],
    edge: i64,
}

impl Cell {
    fn corner(&self, k: usize) -> [i64; 3] {
        std::array::from_fn(|a| self.low[a] + CORNERS[k][a] * self.edge)
    }

    /// Whether the closed box of the cell holds `t` (finest-spacing units).
    fn holds(&self, t: [f64; 3]) -> bool {
        (0..3).all(|a| {
            let low = self.low[a] as f64;
            (low..=low + self.edge as f64).contains(&t[a])
        })
    }

    /// ξ of undeformed position `t` in this cell.
    fn xi(&self, t: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| 2.0 * (t[a] - self.low[a] as f64) / self.edge as f64 - 1.0)
    }
}

/// A mesh as built: cells in file order, a spacing and origin, a displacement per finest-lattice
/// node (in physical units). Every value is a short dyadic fraction, so the points placed below
/// are exactly where the construction says.
struct Mesh {
    cells: Vec<Cell>,
    h: f64,
    origin: [f64; 3],
    u: BTreeMap<[i64; 3], [f64; 3]>,
}

/// A smooth-looking but dyadic displacement (at most h/16 per axis): cells stay valid.
fn wobble(p: [i64; 3], h: f64) -> [f64; 3] {
    let [i, j, k] = p;
    [
        ((i * j + k).rem_euclid(3) - 1) as f64 * h / 16.0,
        ((j + 2 * k + i).rem_euclid(3) - 1) as f64 * h / 32.0,
        ((i + k * j).rem_euclid(2)) as f64 * h / 16.0,
    ]
}

/// The trilinear weights of ξ, VTK corner order.
fn weights(xi: [f64; 3]) -> [f64; 8] {
    std::array::from_fn(|k| {
        (0..3)
            .map(|a| (1.0 + xi[a] * (2 * CORNERS[k][a] - 1) as f64) / 2.0)
            .product()
    })
}

impl Mesh {
    /// `cells` (file order) with displacement [`wobble`] at every node, then, for a node lying on
    /// a larger cell's edge or face without being its corner (a hanging node), that cell's
    /// interpolation there, so the deformed mesh stays conforming.
    fn new(cells: Vec<Cell>, h: f64, origin: [f64; 3]) -> Self {
        let mut u = BTreeMap::new();
        for cell in &cells {
            for k in 0..8 {
                let p = cell.corner(k);
                u.insert(p, wobble(p, h));
            }
        }
        let mut mesh = Self {
            cells,
            h,
            origin,
            u,
        };
        // Coarsest cells first, so a node's constraint reads corners that are final.
        let mut by_size = mesh.cells.clone();
        by_size.sort_by_key(|c| std::cmp::Reverse(c.edge));
        for coarse in by_size {
            let nodes: Vec<[i64; 3]> = mesh.u.keys().copied().collect();
            for p in nodes {
                let t = p.map(|v| v as f64);
                let is_corner = (0..8).any(|k| coarse.corner(k) == p);
                if coarse.holds(t) && !is_corner {
                    let w = weights(coarse.xi(t));
                    let mut value = [0.0; 3];
                    for (k, wk) in w.iter().enumerate() {
                        let corner = mesh.u[&coarse.corner(k)];
                        for a in 0..3 {
                            value[a] += wk * corner[a];
                        }
                    }
                    mesh.u.insert(p, value);
                }
            }
        }
        mesh
    }

    /// Undeformed physical position of finest-lattice node `p`.
    fn position(&self, p: [i64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| self.origin[a] + p[a] as f64 * self.h)
    }

    /// The deformed position of the undeformed point `t` (finest units), through the trilinear map
    /// of a cell holding it; `None` when no cell does (then `t` is not moved).
    fn deformed(&self, t: [f64; 3]) -> [f64; 3] {
        let Some(cell) = self.cells.iter().find(|c| c.holds(t)) else {
            return std::array::from_fn(|a| self.origin[a] + t[a] * self.h);
        };
        let w = weights(cell.xi(t));
        let mut x = [0.0; 3];
        for (k, wk) in w.iter().enumerate() {
            let p = cell.corner(k);
            let (position, u) = (self.position(p), self.u[&p]);
            for a in 0..3 {
                x[a] += wk * (position[a] + u[a]);
            }
        }
        x
    }

    /// The expected owners of undeformed point `t`: (input cell, ξ), ascending by input cell.
    fn owners(&self, t: [f64; 3]) -> Vec<(usize, [f64; 3])> {
        self.cells
            .iter()
            .enumerate()
            .filter(|(_, c)| c.holds(t))
            .map(|(i, c)| (i, c.xi(t)))
            .collect()
    }

    /// Legacy ASCII VTK text, nodes in descending lattice order (not the order a writer picks).
    fn vtk(&self) -> String {
        let nodes: Vec<[i64; 3]> = self.u.keys().rev().copied().collect();
        let index: BTreeMap<[i64; 3], usize> =
            nodes.iter().enumerate().map(|(i, p)| (*p, i)).collect();
        let mut text = format!(
            "# vtk DataFile Version 4.2\nowners test\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
            nodes.len()
        );
        for p in &nodes {
            let x = self.position(*p);
            text += &format!("{} {} {}\n", x[0], x[1], x[2]);
        }
        text += &format!("CELLS {} {}\n", self.cells.len(), 9 * self.cells.len());
        for cell in &self.cells {
            let corners: Vec<String> = (0..8).map(|k| index[&cell.corner(k)].to_string()).collect();
            text += &format!("8 {}\n", corners.join(" "));
        }
        text += &format!("CELL_TYPES {}\n", self.cells.len());
        text += &"12\n".repeat(self.cells.len());
        text += &format!("POINT_DATA {}\nVECTORS displacement double\n", nodes.len());
        for p in &nodes {
            let u = self.u[p];
            text += &format!("{} {} {}\n", u[0], u[1], u[2]);
        }
        text
    }
}

/// A test case: a mesh, and the undeformed positions of its points (finest units) with the number
/// of owners each was placed to have (checked against the construction first).
struct Case {
    mesh: Mesh,
    points: Vec<([f64; 3], usize)>,
    dir: tempfile::TempDir,
}

impl Case {
    fn new(mesh: Mesh, points: Vec<([f64; 3], usize)>) -> Self {
        for (t, count) in &points {
            assert_eq!(mesh.owners(*t).len(), *count, "the test's own point {t:?}");
        }
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("mesh.vtk"), mesh.vtk()).unwrap();
        let mut csv = String::from("x,y,z\n");
        for (t, _) in &points {
            let x = mesh.deformed(*t);
            csv += &format!("{},{},{}\n", x[0], x[1], x[2]);
        }
        // A refused point: it keeps its one row, as without --all-owners.
        csv += "nan,nan,nan\n";
        std::fs::write(dir.path().join("points.csv"), csv).unwrap();
        Self { mesh, points, dir }
    }

    fn path(&self, name: &str) -> String {
        self.dir.path().join(name).to_str().unwrap().to_owned()
    }

    /// Run `locate --all-owners` with `extra` flags; the results file and the JSON summary.
    fn locate(&self, out: &str, extra: &[&str]) -> (Vec<ResultRow>, serde_json::Value) {
        let (mesh, points, out) = (
            self.path("mesh.vtk"),
            self.path("points.csv"),
            self.path(out),
        );
        let run = cgcontact(
            &[
                &[
                    "locate",
                    "--mesh",
                    &mesh,
                    "--points",
                    &points,
                    "--out",
                    &out,
                    "--all-owners",
                    "--json",
                ][..],
                extra,
            ]
            .concat(),
        );
        assert!(
            run.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let summary = serde_json::from_slice(&run.stdout).expect("--json prints one object");
        (read_results(&out).unwrap(), summary)
    }

    /// The rows as expected: every owner of each point in input order, cells ascending, ξ within
    /// `xi_bound`; one row with no cell for a point without owners (and for the refused one).
    fn check(&self, rows: &[ResultRow], summary: &serde_json::Value, xi_bound: f64, what: &str) {
        let mut at = 0;
        let mut several = 0;
        for (point, (t, _)) in self.points.iter().enumerate() {
            let expected = self.mesh.owners(*t);
            several += usize::from(expected.len() > 1);
            if expected.is_empty() {
                let row = &rows[at];
                assert_eq!(
                    (row.point, row.cell),
                    (point, None),
                    "{what}: point {point}"
                );
                assert!(row.xi.is_nan(), "{what}: point {point}");
                at += 1;
                continue;
            }
            for (cell, xi) in expected {
                let row = rows
                    .get(at)
                    .unwrap_or_else(|| panic!("{what}: no row for point {point} cell {cell}"));
                assert_eq!(
                    (row.point, row.cell),
                    (point, Some(cell)),
                    "{what}: row {at}"
                );
                let error = (0..3)
                    .map(|a| (row.xi.to_array()[a] - xi[a]).abs())
                    .fold(0.0, f64::max);
                assert!(
                    error <= xi_bound,
                    "{what}: point {point} cell {cell}: xi {} vs {xi:?}",
                    row.xi
                );
                at += 1;
            }
        }
        let refused = self.points.len();
        assert_eq!(
            rows.get(at).map(|r| (r.point, r.cell)),
            Some((refused, None)),
            "{what}: the refused point's row"
        );
        assert_eq!(rows.len(), at + 1, "{what}: rows after the last point");
        assert_eq!(summary["points"], refused + 1, "{what}");
        assert_eq!(summary["owners"]["rows"], rows.len(), "{what}");
        assert_eq!(
            summary["owners"]["points_with_several_owners"], several,
            "{what}"
        );
    }

    /// Every strategy, both precisions, 1 and 3 threads (which must write the same bytes).
    fn check_every_strategy(&self) {
        for strategy in STRATEGIES {
            for (precision, xi_bound) in [("f64", 1e-9), ("f32", 1e-4)] {
                let what = format!("{strategy} {precision}");
                let settings = ["--strategy", strategy, "--precision", precision];
                let (rows, summary) =
                    self.locate("one.csv", &[&settings[..], &["--threads", "1"]].concat());
                self.check(&rows, &summary, xi_bound, &what);
                let (_, _) =
                    self.locate("three.csv", &[&settings[..], &["--threads", "3"]].concat());
                assert_eq!(
                    std::fs::read(self.path("one.csv")).unwrap(),
                    std::fs::read(self.path("three.csv")).unwrap(),
                    "{what}: 1 and 3 threads wrote different rows"
                );
            }
        }
    }
}

/// 2 × 2 × 2 cells of h = 0.5 off the origin, in a shuffled file order.
fn uniform_case() -> Case {
    let lattice_order: Vec<Cell> = (0..8)
        .map(|c| Cell {
            low: [c & 1, (c >> 1) & 1, c >> 2],
            edge: 1,
        })
        .collect();
    let cells = [5, 2, 7, 0, 3, 6, 1, 4].map(|c| lattice_order[c]).to_vec();
    let mesh = Mesh::new(cells, 0.5, [1.0, -2.0, 0.25]);
    Case::new(
        mesh,
        vec![
            ([1.0, 1.0, 1.0], 8),   // the node all 8 cells share
            ([1.0, 1.0, 0.5], 4),   // an edge inside
            ([1.0, 0.5, 0.5], 2),   // a face inside
            ([0.25, 1.5, 0.75], 1), // inside a cell
            ([3.0, 1.0, 1.0], 0),   // outside
            ([1.0, 1.0, 0.0], 4),   // a node on the bottom face
            ([0.0, 0.0, 0.0], 1),   // a corner of the block
            ([1.5, 1.0, 1.75], 2),  // a face, off its centre
            ([0.5, 1.0, 2.0], 2),   // an edge on the top face
            ([-0.5, 0.5, 0.5], 0),  // outside, the other side
        ],
    )
}

/// A 2 × 2 × 1 base lattice of h = 0.5 (edge 2 in finest units) whose cell (1, 0, 0) is halved into
/// 8 cells: a fine/coarse interface with hanging nodes. Cells shuffled in the file.
fn adaptive_case() -> Case {
    let mut cells = vec![
        Cell {
            low: [0, 0, 0],
            edge: 2,
        },
        Cell {
            low: [0, 2, 0],
            edge: 2,
        },
        Cell {
            low: [2, 2, 0],
            edge: 2,
        },
    ];
    cells.extend((0..8).map(|c| Cell {
        low: [2 + (c & 1), (c >> 1) & 1, c >> 2],
        edge: 1,
    }));
    let cells = [4, 9, 0, 6, 2, 10, 5, 1, 8, 3, 7]
        .map(|c| cells[c])
        .to_vec();
    let mesh = Mesh::new(cells, 0.25, [0.5, 1.0, -0.75]);
    Case::new(
        mesh,
        vec![
            ([3.0, 1.0, 1.0], 8),  // the node the 8 fine cells share
            ([3.0, 1.0, 0.5], 4),  // a fine edge
            ([3.0, 0.5, 0.5], 2),  // a fine face
            ([2.0, 0.5, 0.5], 2),  // the interface: a coarse and a fine cell
            ([2.0, 1.0, 1.0], 5),  // the hanging node at the coarse face's centre
            ([2.0, 1.0, 0.0], 3),  // a hanging node on the coarse face's edge
            ([2.0, 2.0, 1.0], 5),  // a hanging node on the edge of 3 coarse cells
            ([2.0, 2.0, 0.0], 4),  // a node of 3 coarse cells and 1 fine one
            ([1.0, 2.0, 1.0], 2),  // the centre of a coarse face
            ([0.5, 1.5, 0.75], 1), // inside a coarse cell
            ([3.5, 0.25, 1.5], 1), // inside a fine cell
            ([5.0, 1.0, 1.0], 0),  // outside
        ],
    )
}

#[test]
fn uniform_mesh_every_owner_of_shared_nodes_edges_and_faces() {
    uniform_case().check_every_strategy();
}

#[test]
fn adaptive_mesh_every_owner_at_the_fine_coarse_interface() {
    adaptive_case().check_every_strategy();
}

/// Without `--all-owners` the results keep one row per point and the summary has no `owners`.
#[test]
fn without_all_owners_one_row_per_point() {
    let case = uniform_case();
    let (mesh, points, out) = (
        case.path("mesh.vtk"),
        case.path("points.csv"),
        case.path("one-each.csv"),
    );
    let run = cgcontact(&[
        "locate", "--mesh", &mesh, "--points", &points, "--out", &out, "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(summary.get("owners").is_none());
    let rows = read_results(&out).unwrap();
    assert_eq!(rows.len(), case.points.len() + 1);
    for (point, row) in rows.iter().enumerate() {
        assert_eq!(row.point, point);
        let expected: Vec<usize> = case
            .points
            .get(point)
            .map(|(t, _)| case.mesh.owners(*t).iter().map(|o| o.0).collect())
            .unwrap_or_default();
        match row.cell {
            Some(cell) => assert!(expected.contains(&cell), "point {point}: {cell}"),
            None => assert!(expected.is_empty(), "point {point}"),
        }
    }
}

/// The text summary says how many rows were written and how many points had several owners.
#[test]
fn text_summary_counts_rows_and_shared_points() {
    let case = adaptive_case();
    let (mesh, points, out) = (
        case.path("mesh.vtk"),
        case.path("points.csv"),
        case.path("owners.csv"),
    );
    let run = cgcontact(&[
        "locate",
        "--mesh",
        &mesh,
        "--points",
        &points,
        "--out",
        &out,
        "--all-owners",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8(run.stdout).unwrap();
    let rows: usize = case
        .points
        .iter()
        .map(|(_, count)| (*count).max(1))
        .sum::<usize>()
        + 1;
    let several = case.points.iter().filter(|(_, c)| *c > 1).count();
    let line = format!(
        "all owners: {rows} rows for {} points, {several} points with several owners (up to 8)",
        case.points.len() + 1
    );
    assert!(text.contains(&line), "`{line}` not in:\n{text}");
    assert!(text.contains(&format!("wrote {out}")), "{text}");
}

/// The seed's Newton (0.1 absolute residual, |ξ| ≤ 1 with no tolerance) cannot list owners: the
/// combination is refused before any file is read, with one line and exit code 2.
#[test]
fn noderad_seed_refused_with_all_owners() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("owners.csv");
    let run = cgcontact(&[
        "locate",
        "--mesh",
        "no-such-mesh.vtk",
        "--points",
        "no-such-points.csv",
        "--out",
        out.to_str().unwrap(),
        "--all-owners",
        "--strategy",
        "noderad-seed",
    ]);
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(
            "cgcontact: error: --all-owners cannot be used with --strategy noderad-seed"
        ),
        "{stderr}"
    );
    assert!(!out.exists());
}

/// `locate --help` describes the flag and names the strategy it refuses.
#[test]
fn help_describes_all_owners() {
    let run = cgcontact(&["locate", "--help"]);
    assert!(run.status.success());
    let help = String::from_utf8(run.stdout).unwrap();
    assert!(help.contains("--all-owners"), "{help}");
    assert!(help.contains("one row per cell holding it"), "{help}");
    assert!(help.contains("Not with --strategy noderad-seed"), "{help}");
}

/// `centroid` and `noderad` are filters: a cell they never offer is never inverted, so
/// `--all-owners` may list fewer owners than there are (an audit: on an undeformed 3 × 3 × 3
/// block, `centroid` left out owners of every interior node). They used to do it without a word;
/// `locate` now warns on stderr (not under `--quiet`), and the complete strategies do not.
#[test]
fn all_owners_with_a_filter_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene");
    let made = cgcontact(&[
        "scene",
        "block",
        "--cells",
        "3,3,3",
        "--known",
        "20",
        "--out",
        scene.to_str().unwrap(),
    ]);
    assert!(made.status.success(), "{made:?}");
    let mesh = scene.join("mesh.vtu");
    let points = scene.join("points.csv");
    let out = dir.path().join("out.csv");
    for (strategy, warned) in [
        ("centroid", true),
        ("noderad", true),
        ("lattice", false),
        ("rtree", false),
        ("brute", false),
    ] {
        for quiet in [false, true] {
            let mut args = vec![
                "locate",
                "--mesh",
                mesh.to_str().unwrap(),
                "--points",
                points.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--all-owners",
                "--strategy",
                strategy,
            ];
            if quiet {
                args.push("--quiet");
            }
            let run = cgcontact(&args);
            assert!(run.status.success(), "{strategy}: {run:?}");
            let stderr = String::from_utf8(run.stderr).unwrap();
            let said = stderr.contains("may list fewer owners");
            assert_eq!(
                said,
                warned && !quiet,
                "{strategy}, quiet {quiet}: {stderr}"
            );
        }
    }
}
