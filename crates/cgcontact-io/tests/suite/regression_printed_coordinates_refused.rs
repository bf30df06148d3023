//! Regression: meshes whose coordinates are decimal prints of 9 to 15 significant digits. VTK's
//! legacy ASCII writer prints doubles with 11, which near 1000 put the nodes of a lattice of
//! spacing 1/3 up to 5e-8 off their positions, past the slack of 64-bit floats: such a file,
//! written by VTK itself, was refused ("node 1 at [1000.3333333, ..] is not on the lattice").
//! The detection now finds the print's digits once the first attempt fails and tolerates its
//! rounding; the offsets go into the displacement, as for float files, so the deformed nodes
//! are the file's. Where even the print cannot place the cells (cells of 1e-4 near 2e6 at 11
//! digits), the error says so.
//!
//! The independent answer: points made from each cell's corners as the file holds them, whose
//! owners are the cells whose closed box holds the point's lattice position (`common::probes`).

use cgcontact::{AdaptiveBody, AdaptiveLocator, CORNER_OFFSETS, Lattice, LatticeLocator, Leaf};
use cgcontact::{Locator, Settings};
use cgcontact_io::{ErrorKind, HexMesh, MeshBody};
use glam::DVec3;

use crate::common::mesh_of;
use crate::common::probes::{displaced_leaf_boxes, found, owners_of, probes};

/// The mesh with each coordinate printed with `digits` significant digits and read back.
fn printed(mesh: &HexMesh, digits: usize) -> HexMesh {
    let print = |c: f64| -> f64 { format!("{c:.*e}", digits - 1).parse().unwrap() };
    HexMesh {
        ghosts: Vec::new(),
        points: (mesh.points.iter())
            .map(|p| DVec3::from_array(p.to_array().map(print)))
            .collect(),
        ..mesh.clone()
    }
}

/// An n × n × n block at `origin` with spacing `h`, each cell's lowest lattice node beside it.
fn block(origin: DVec3, h: DVec3, n: u32, displaced: bool) -> (HexMesh, Vec<[u32; 3]>) {
    let node = |i: u32, j: u32, k: u32| i + (n + 1) * (j + (n + 1) * k);
    let mut points = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                points.push(origin + h * DVec3::new(i as f64, j as f64, k as f64));
            }
        }
    }
    let (mut cells, mut low) = (Vec::new(), Vec::new());
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                cells.push(CORNER_OFFSETS.map(|[a, b, c]| node(i + a, j + b, k + c)));
                low.push([i, j, k]);
            }
        }
    }
    let displacement = displaced.then(|| {
        (0..points.len())
            .map(|m| 0.04 * h * DVec3::new((0.7 * m as f64).sin(), (0.5 * m as f64).cos(), 0.3))
            .collect()
    });
    let mesh = HexMesh {
        ghosts: Vec::new(),
        points,
        cells,
        displacement,
    };
    (mesh, low)
}

/// Lattices whose 11-digit prints lie off them by more than 64-bit floats' slack.
fn cases() -> [(DVec3, DVec3); 3] {
    [
        (DVec3::splat(1000.0), DVec3::splat(1.0 / 3.0)),
        (
            DVec3::new(-2e4, 3e3, 7.0),
            DVec3::new(0.1, 1.0 / 3.0, 1.0 / 7.0),
        ),
        (
            DVec3::new(5e5, -5e5, 1e5),
            DVec3::new(0.01, 0.02 / 3.0, 0.03),
        ),
    ]
}

#[test]
fn a_lattice_printed_with_11_digits_is_read_with_every_owner() {
    for (origin, h) in cases() {
        for displaced in [false, true] {
            let (exact, low) = block(origin, h, 3, displaced);
            let mesh = printed(&exact, 11);
            let read = match mesh.to_body() {
                Ok(MeshBody::Uniform(read)) => read,
                other => panic!("origin {origin} h {h}: {:?}", other.err()),
            };
            let size = vec![1; low.len()];
            let locator = LatticeLocator::new(&read.body, Settings::default()).unwrap();
            for (x, cell, half) in probes(&mesh, &low, &size) {
                let expected = owners_of(&low, &size, half);
                let got = found(&locator.locate_owners(x).unwrap(), &read.cells);
                assert_eq!(
                    got, expected,
                    "origin {origin} h {h} cell {cell} at {half:?}"
                );
            }
        }
    }
}

#[test]
fn an_adaptive_mesh_printed_with_11_digits_keeps_each_point_in_its_leaf() {
    for (origin, h) in cases() {
        let cells = [3, 2, 2];
        let mut leaves: Vec<Leaf> = (1..12)
            .map(|c| Leaf::new(0, [c % 3, (c / 3) % 2, c / 6]))
            .collect();
        leaves.extend(Leaf::new(0, [0, 0, 0]).children());
        let lattice = Lattice::new(origin, h, cells).unwrap();
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        let (low, size) = displaced_leaf_boxes(&mut body);
        let mesh = printed(&mesh_of(&body), 11);
        let read = match mesh.to_body() {
            Ok(MeshBody::Adaptive(read)) => read,
            other => panic!("origin {origin} h {h}: {:?}", other.err()),
        };
        let locator = AdaptiveLocator::new(&read.body, Settings::default()).unwrap();
        for (x, cell, half) in probes(&mesh, &low, &size) {
            let got = found(&locator.locate_owners(x).unwrap(), &read.cells);
            assert!(
                got.contains(&cell),
                "origin {origin} h {h} cell {cell} at {half:?}: {got:?}"
            );
        }
    }
}

/// The print's rounding is tolerated, not more: a node 4 units of the 11th digit off, then
/// printed, is still named.
#[test]
fn a_node_off_by_more_than_the_print_is_still_named() {
    for (origin, h) in cases() {
        let (mut exact, _) = block(origin, h, 3, false);
        let p = exact.points[21];
        let unit = |c: f64| 10f64.powf(c.abs().log10().floor() - 10.0);
        exact.points[21].x += 4.0 * unit(p.x);
        match printed(&exact, 11).to_body() {
            Err(ErrorKind::OffLattice { node: 21, .. }) => {}
            other => panic!("origin {origin} h {h}: {:?}", other.err()),
        }
    }
}

/// Cells a file's coordinates cannot place: the error names the refusal and the rounding that
/// explains it.
#[test]
fn cells_the_coordinates_cannot_place_are_refused_saying_why() {
    let far = DVec3::new(2e6, -2e6, 3e5);
    let f32_mesh = |mesh: &HexMesh| HexMesh {
        ghosts: Vec::new(),
        points: (mesh.points.iter())
            .map(|p| DVec3::from_array(p.to_array().map(|c| f64::from(c as f32))))
            .collect(),
        ..mesh.clone()
    };
    let cases = [
        // Flat cells: 2e6 + 1e-4 / 3 prints as 2e6.
        (
            printed(&block(far, DVec3::splat(1e-4 / 3.0), 3, false).0, 11),
            "printed with 11 significant digits",
        ),
        // Cells of unequal sizes, nodes off the lattice.
        (
            printed(&block(far, DVec3::splat(4e-4 / 3.0), 3, false).0, 11),
            "printed with 11 significant digits",
        ),
        (
            printed(
                &block(far, DVec3::new(1e-5, 3e-5, 2e-5) / 7.0, 3, true).0,
                12,
            ),
            "printed with 12 significant digits",
        ),
        (
            f32_mesh(&block(far * 0.1, DVec3::splat(1e-2), 3, false).0),
            "32-bit floats",
        ),
        // Every edge of every cell rounded to 0: floats 1e9 from the origin along every axis,
        // which are 64 apart, and cells of 1 (no edge left to compare the rounding with, such a
        // file was refused as flat without a word on the rounding).
        (
            f32_mesh(&block(DVec3::splat(1e9), DVec3::ONE, 3, false).0),
            "32-bit floats: near 1.000e9 they are known only to about 6.0e1, and every cell edge \
             rounded to 0",
        ),
    ];
    // A cell naming one node for all its corners, 0.4 from the origin: flat by its connectivity,
    // not its digits, and not said to be the rounding's doing.
    let one_node = HexMesh {
        ghosts: Vec::new(),
        points: vec![DVec3::new(0.4, 0.2, 0.3)],
        cells: vec![[0; 8]],
        displacement: None,
    };
    let message = one_node.to_body().err().unwrap().to_string();
    assert!(message.contains("the cell is flat"), "{message}");
    assert!(!message.contains("rounded"), "{message}");
    for (mesh, words) in cases {
        match mesh.to_body() {
            Err(ErrorKind::Imprecise { error, .. }) => {
                assert!(error.rounding_may_explain(), "{error}");
            }
            other => panic!("{words}: {:?}", other.err()),
        }
        let message = mesh.to_body().err().unwrap().to_string();
        assert!(message.contains(words), "{message}");
        assert!(
            message.contains("too coarse to place cells this small"),
            "{message}"
        );
    }
}

/// VTK's legacy ASCII writer prints `float` coordinates with 6 significant digits (`%g`):
/// vtkHyperTreeGridToUnstructuredGrid's points near 1e5, on cells of 0.25, print as 100000 and
/// 100001, flat cells. Those values are also 32-bit floats, and the error said so: "known only to
/// about 6.0e-3, 0.60 % of the smallest cell edge 1.000e0", no reason for a cell to be flat; it names
/// the print and its rounding, 0.5 there. The legacy reader reads such prints as floats, so a
/// print such as -99999.8 is counted in the digits of its float, not of its double (11), which
/// the first version of the wording missed.
#[test]
fn six_digit_prints_are_named_not_their_float_rounding() {
    let mesh = printed(&block(DVec3::splat(1e5), DVec3::splat(0.25), 3, false).0, 6);
    assert!(
        mesh.points
            .iter()
            .all(|p| p.to_array().iter().all(|&c| f64::from(c as f32) == c))
    );
    let message = mesh.to_body().err().unwrap().to_string();
    assert!(
        message.contains(
            "printed with 6 significant digits: near 1.000e5 they are known only to about 5.0e-1"
        ),
        "{message}"
    );
    assert!(!message.contains("32-bit floats"), "{message}");
    // Prints that are no integers, read as the legacy reader reads `float` points: "-99999.9"
    // is -99999.8984375 as a double (11 digits), 6 digits as the float it is.
    let printed_floats = |mesh: &HexMesh| HexMesh {
        ghosts: Vec::new(),
        points: (printed(mesh, 6).points.iter())
            .map(|p| DVec3::from_array(p.to_array().map(|c| f64::from(c as f32))))
            .collect(),
        ..mesh.clone()
    };
    let far = DVec3::new(1e5, -1e5, 2.5e4);
    let mesh = printed_floats(&block(far, DVec3::new(0.25, 0.0625, 0.015625), 3, false).0);
    let message = mesh.to_body().err().unwrap().to_string();
    assert!(
        message.contains(
            "printed with 6 significant digits: near 1.000e5 they are known only to about 5.0e-1"
        ),
        "{message}"
    );
    // 11 digits of the same cells: still read (the print's rounding tolerated).
    printed(
        &block(DVec3::splat(1e5), DVec3::splat(0.25), 3, false).0,
        11,
    )
    .to_body()
    .unwrap();
}
