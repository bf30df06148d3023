//! Lattice detection on shifted, scaled and anisotropic lattices with holes and shuffled order, and
//! the errors for meshes that are not lattices (each naming the cell or node).

use crate::common::{LegacyData, body_with_holes, expected_cells, legacy_ascii, shuffled};
use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, ErrorKind, HexMesh, read_mesh};

fn cases() -> Vec<(DVec3, DVec3)> {
    vec![
        (DVec3::new(1e6, 1e6, -1e6), DVec3::splat(0.5)),
        (DVec3::new(-0.5e-3, 0.0, 2e-3), DVec3::splat(1e-6)),
        (DVec3::new(0.0, -1e5, 3e5), DVec3::splat(1e4)),
        (DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.01, 1.0, 0.1)),
        (DVec3::new(-7.0, 1e3, 0.0), DVec3::new(100.0, 1.0, 7.0)),
    ]
}

#[test]
fn detects_shifted_scaled_anisotropic_lattices_in_any_order() {
    for (k, (origin, h)) in cases().into_iter().enumerate() {
        let body = body_with_holes(origin, h, [5, 4, 6], k as u64);
        let (mesh, perm) = shuffled(&HexMesh::from_body(&body), 100 + k as u64);
        let found = mesh
            .to_lattice()
            .unwrap_or_else(|e| panic!("origin {origin} h {h}: {e}"));
        let lattice = found.body.lattice();
        assert_eq!(lattice.cells(), [5, 4, 6]);
        assert_eq!(lattice.origin(), origin);
        assert!(
            ((lattice.h() - h) / h).abs().max_element() < 1e-12,
            "h {} vs {h}",
            lattice.h()
        );
        assert_eq!(
            found.cells.lattice_cells(),
            expected_cells(&body, &perm).as_slice()
        );
        assert!(found.body.active_cells().eq(body.active_cells()));
        assert_eq!(found.body.displacements(), body.displacements());
    }
}

/// Rounding the coordinates to a relative 1e-10 of h is tolerated; 1e-6 of h is not.
#[test]
fn tolerates_rounding_but_not_perturbation() {
    for (origin, h) in cases() {
        let body = body_with_holes(origin, h, [3, 3, 3], 9);
        let mut mesh = HexMesh::from_body(&body);
        let node = 13;
        mesh.points[node].y += 1e-10 * h.y;
        assert!(
            mesh.to_lattice().is_ok(),
            "origin {origin} h {h}: 1e-10 h rejected"
        );
        mesh.points[node].y += 1e-6 * h.y;
        match mesh.to_lattice() {
            Err(ErrorKind::OffLattice { node: n, .. }) => assert_eq!(n, node),
            other => panic!("origin {origin} h {h}: {other:?}"),
        }
    }
}

#[test]
fn a_perturbed_extreme_node_is_the_one_named() {
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [3, 3, 3], 4);
    let mut mesh = HexMesh::from_body(&body);
    // Node 0 is the lattice's lowest corner: moving it must not move the detected origin.
    for delta in [-0.3, -0.7, 0.2, -1.5] {
        let mut m = mesh.clone();
        m.points[0].x += delta;
        match m.to_lattice() {
            Err(
                ErrorKind::OffLattice { node: 0, .. }
                | ErrorKind::OutsideLattice { node: 0, .. }
                | ErrorKind::NotLatticeCell { .. },
            ) => {}
            other => panic!("delta {delta}: {other:?}"),
        }
    }
    mesh.points[0].x -= 0.3;
    let message = mesh.to_lattice().unwrap_err().to_string();
    assert!(message.starts_with("node 0 "), "{message}");
}

#[test]
fn corners_in_the_wrong_order_name_the_cell() {
    let body = body_with_holes(DVec3::splat(5.0), DVec3::splat(0.5), [3, 2, 2], 1);
    let mesh = HexMesh::from_body(&body);
    for (a, b) in [(2, 3), (0, 1), (0, 6), (4, 5)] {
        let mut m = mesh.clone();
        m.cells[3].swap(a, b);
        match m.to_lattice() {
            Err(ErrorKind::NotLatticeCell { cell: 3, .. }) => {}
            other => panic!("swap {a}/{b}: {other:?}"),
        }
    }
    // Mirrored (corners 0-3 on top): not VTK order either.
    let mut m = mesh.clone();
    let c = m.cells[1];
    m.cells[1] = [c[4], c[5], c[6], c[7], c[0], c[1], c[2], c[3]];
    assert!(matches!(
        m.to_lattice(),
        Err(ErrorKind::NotLatticeCell { cell: 1, .. })
    ));
}

#[test]
fn a_cell_spanning_two_lattice_cells_is_named() {
    // Three unit cells along x, then one 2-wide cell on top of the first two.
    let mut points = Vec::new();
    for z in 0..3 {
        for y in 0..2 {
            for x in 0..4 {
                points.push(DVec3::new(x as f64, y as f64, z as f64));
            }
        }
    }
    let id = |x: u32, y: u32, z: u32| x + 4 * (y + 2 * z);
    let hex = |x0: u32, x1: u32, z: u32| {
        [
            id(x0, 0, z),
            id(x1, 0, z),
            id(x1, 1, z),
            id(x0, 1, z),
            id(x0, 0, z + 1),
            id(x1, 0, z + 1),
            id(x1, 1, z + 1),
            id(x0, 1, z + 1),
        ]
    };
    let cells = vec![hex(0, 1, 0), hex(1, 2, 0), hex(2, 3, 0), hex(0, 2, 1)];
    let mesh = HexMesh {
        ghosts: Vec::new(),
        points,
        cells,
        displacement: None,
    };
    match mesh.to_lattice() {
        Err(ErrorKind::NotLatticeCell {
            cell: 3, corner: 1, ..
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn duplicate_cells_and_unmerged_nodes() {
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [2, 2, 2], 0);
    let mut mesh = HexMesh::from_body(&body);
    let again = mesh.cells[2];
    mesh.cells.push(again);
    let last = mesh.cells.len() - 1;
    match mesh.to_lattice() {
        Err(ErrorKind::DuplicateCell {
            first: 2, second, ..
        }) => assert_eq!(second, last),
        other => panic!("{other:?}"),
    }

    // Unmerged: every cell with its own 8 nodes (some exporters write that): fine.
    let mut unmerged = unmerge(&HexMesh::from_body(&body));
    let found = unmerged.to_lattice().unwrap();
    assert_eq!(found.body.displacements(), body.displacements());
    // ... unless the copies of a node disagree.
    let copy = (1..unmerged.points.len())
        .find(|&n| unmerged.points[..n].contains(&unmerged.points[n]))
        .unwrap();
    let original = unmerged
        .points
        .iter()
        .position(|p| *p == unmerged.points[copy])
        .unwrap();
    unmerged.displacement.as_mut().unwrap()[copy].x += 0.01;
    match unmerged.to_lattice() {
        Err(ErrorKind::InconsistentDisplacement { first, second, .. }) => {
            assert_eq!((first, second), (original, copy))
        }
        other => panic!("{other:?}"),
    }
}

/// `mesh` with every cell on its own 8 nodes (copies of the shared ones, same displacements).
fn unmerge(mesh: &HexMesh) -> HexMesh {
    let u = mesh.displacement.clone().unwrap();
    let mut points = Vec::new();
    let mut disp = Vec::new();
    let cells = mesh
        .cells
        .iter()
        .map(|c| {
            c.map(|n| {
                points.push(mesh.points[n as usize]);
                disp.push(u[n as usize]);
                (points.len() - 1) as u32
            })
        })
        .collect();
    HexMesh {
        ghosts: Vec::new(),
        points,
        cells,
        displacement: Some(disp),
    }
}

/// Copies of a node agree to 1e-9 of the shortest spacing: on a 1 : 0.01 : 1 lattice, copies
/// 5e-10 apart (5e-8 of the short side) passed while the check took the longest.
#[test]
fn copies_of_a_node_agree_to_the_shortest_spacing() {
    let body = body_with_holes(DVec3::ZERO, DVec3::new(1.0, 0.01, 1.0), [2, 2, 2], 0);
    let mut unmerged = unmerge(&HexMesh::from_body(&body));
    assert!(unmerged.to_lattice().is_ok());
    let copy = (1..unmerged.points.len())
        .find(|&n| unmerged.points[..n].contains(&unmerged.points[n]))
        .unwrap();
    unmerged.displacement.as_mut().unwrap()[copy].y += 5e-10;
    assert!(
        matches!(
            unmerged.to_lattice(),
            Err(ErrorKind::InconsistentDisplacement { .. })
        ),
        "{:?}",
        unmerged.to_lattice().err()
    );
}

#[test]
fn unused_nodes_are_ignored_even_off_the_lattice() {
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [2, 2, 2], 0);
    let mut mesh = HexMesh::from_body(&body);
    mesh.points.push(DVec3::new(0.123, f64::NAN, 1e9));
    mesh.displacement
        .as_mut()
        .unwrap()
        .push(DVec3::splat(f64::INFINITY));
    let found = mesh.to_lattice().unwrap();
    assert_eq!(found.point_count, body.node_count() + 1);
    assert_eq!(found.body.displacements(), body.displacements());
}

#[test]
fn bad_values_at_used_nodes_are_named() {
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [2, 2, 2], 0);
    let mut mesh = HexMesh::from_body(&body);
    mesh.displacement.as_mut().unwrap()[5].z = f64::NAN;
    assert!(matches!(
        mesh.to_lattice(),
        Err(ErrorKind::NonFiniteDisplacement { node: 5, .. })
    ));
    let mut mesh = HexMesh::from_body(&body);
    mesh.points[7].x = f64::INFINITY;
    assert!(matches!(
        mesh.to_lattice(),
        Err(ErrorKind::NonFiniteNode { node: 7, .. })
    ));
    let mut mesh = HexMesh::from_body(&body);
    mesh.cells[1][4] = 10_000;
    assert!(matches!(
        mesh.to_lattice(),
        Err(ErrorKind::MissingNode {
            cell: 1,
            node: 10_000,
            ..
        })
    ));
}

#[test]
fn far_apart_cells_are_refused_not_allocated() {
    let unit = |o: DVec3| -> Vec<DVec3> {
        cgcontact::CORNER_OFFSETS
            .iter()
            .map(|c| o + DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            .collect()
    };
    let mut points = unit(DVec3::ZERO);
    points.extend(unit(DVec3::splat(1e5)));
    let mesh = HexMesh {
        ghosts: Vec::new(),
        points,
        cells: vec![[0, 1, 2, 3, 4, 5, 6, 7], [8, 9, 10, 11, 12, 13, 14, 15]],
        displacement: None,
    };
    assert!(matches!(
        mesh.to_lattice(),
        Err(ErrorKind::TooSparse { .. })
    ));
}

#[test]
fn errors_from_files_name_the_file_and_the_cell() {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [3, 2, 2], 6);
    let mesh = HexMesh::from_body(&body);
    let text = legacy_ascii(&mesh, LegacyData::Vectors, false);

    // A wedge among the hexahedra: cell 2 gets type 13 and 6 nodes.
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let cells_at = lines.iter().position(|l| l.starts_with("CELLS")).unwrap();
    let n = mesh.cells.len();
    lines[cells_at] = format!("CELLS {n} {}", 9 * n - 2);
    let c = mesh.cells[2];
    lines[cells_at + 3] = format!("6 {} {} {} {} {} {}", c[0], c[1], c[2], c[4], c[5], c[6]);
    let types_at = lines
        .iter()
        .position(|l| l.starts_with("CELL_TYPES"))
        .unwrap();
    lines[types_at + 3] = "13".into();
    let path = dir.path().join("wedge.vtk");
    // Every line ended, the last one too, as VTK writes them.
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let err = read_mesh(&path, &DisplacementArray::Default).unwrap_err();
    assert!(
        matches!(
            err.kind(),
            ErrorKind::NotHexahedron {
                cell: 2,
                vtk_type: 13,
                ..
            }
        ),
        "{err}"
    );
    let message = err.to_string();
    assert!(
        message.contains("wedge.vtk") && message.contains("cell 2"),
        "{message}"
    );

    // A node off the lattice.
    let mut moved = mesh.clone();
    moved.points[4].z += 0.01;
    let path = dir.path().join("moved.vtk");
    std::fs::write(&path, legacy_ascii(&moved, LegacyData::Vectors, false)).unwrap();
    let message = read_mesh(&path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("moved.vtk") && message.contains("node 4 "),
        "{message}"
    );

    // Displacement with 2 components.
    let two = text.replace(
        "VECTORS displacement double",
        &format!(
            "FIELD FieldData 1\ndisplacement 2 {} double",
            mesh.points.len() * 3 / 2
        ),
    );
    let path = dir.path().join("two.vtk");
    std::fs::write(&path, two).unwrap();
    let err = read_mesh(&path, &DisplacementArray::Default).unwrap_err();
    assert!(
        matches!(err.kind(), ErrorKind::BadDisplacement { .. }),
        "{err}"
    );
}

#[test]
fn voxels_are_read_as_hexahedra() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 12);
    let mut mesh = HexMesh::from_body(&body);
    // VTK_VOXEL numbers corners x fastest: swap 2/3 and 6/7 and mark the cells type 11.
    for c in &mut mesh.cells {
        c.swap(2, 3);
        c.swap(6, 7);
    }
    let text = legacy_ascii(&mesh, LegacyData::Vectors, false);
    let text = text
        .lines()
        .map(|l| if l == "12" { "11" } else { l })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    let found = cgcontact_io::parse_hex_mesh(text.as_bytes(), &DisplacementArray::Default)
        .unwrap()
        .to_lattice()
        .unwrap();
    assert_eq!(found.cells, cgcontact_io::CellMap::ascending(&body));
    assert_eq!(found.body.displacements(), body.displacements());
}
