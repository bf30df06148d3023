//! Round trips: a body written in each flavour reads back as the same lattice, cells and
//! displacements; so do shuffled meshes in files written the way VTK and ParaView write them.

use crate::common::{
    LegacyData, body_with_holes, expected_cells, legacy_ascii, shuffled, vtu_ascii,
    vtu_raw_appended, vtu_raw_appended_lzma,
};
use cgcontact::glam::DVec3;
use cgcontact::{Body, LatticeLocator, Locator, Settings};
use cgcontact_io::{
    CellMap, DisplacementArray, HexMesh, LatticeMesh, MeshFormat, read_mesh, write_deformed_vtu,
    write_mesh, write_points_vtu,
};

const FORMATS: [MeshFormat; 4] = [
    MeshFormat::LegacyAscii,
    MeshFormat::LegacyBinary,
    MeshFormat::Xml,
    MeshFormat::XmlZlib,
];

fn assert_same_body(found: &LatticeMesh, body: &Body) {
    let (a, b) = (found.body.lattice(), body.lattice());
    assert_eq!(a.cells(), b.cells());
    assert_eq!(a.origin(), b.origin(), "origin is a node coordinate: exact");
    // The spacing is the extent over the cell count: exact to the rounding of the coordinates,
    // which is relative to their magnitude, not to h (origin 1e-3 with h = 1e-6, say).
    let n = DVec3::from_array(b.cells().map(f64::from));
    let magnitude = b.origin().abs().max(b.upper().abs());
    let bound = 4.0 * f64::EPSILON * (magnitude / n + b.h());
    assert!(
        (a.h() - b.h()).abs().cmple(bound).all(),
        "spacing {} vs {}",
        a.h(),
        b.h()
    );
    assert!(found.body.active_cells().eq(body.active_cells()));
    assert_eq!(
        found.body.displacements(),
        body.displacements(),
        "displacements bitwise"
    );
}

#[test]
fn every_format_round_trips_a_body_with_holes() {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(
        DVec3::new(-3.0, 1e6, 0.125),
        DVec3::new(0.5, 0.25, 1.5),
        [5, 4, 3],
        7,
    );
    for format in FORMATS {
        let path = dir
            .path()
            .join(format!("body-{format:?}.{}", format.extension()));
        write_mesh(&path, &body, format).unwrap();
        let found = read_mesh(&path, &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{format:?}: {e}"));
        assert_same_body(&found, &body);
        assert_eq!(
            found.cells,
            CellMap::ascending(&body),
            "{format:?}: cell order is the written order"
        );
        assert!(found.has_displacement);
        assert_eq!(found.point_count, body.node_count());
    }
}

#[test]
fn extreme_scales_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for (origin, h) in [
        (DVec3::new(1e6, -1e6, 2e6), DVec3::splat(0.5)),
        (DVec3::new(1e-3, -2e-3, 0.0), DVec3::splat(1e-6)),
        (DVec3::new(0.0, 5e4, -1e5), DVec3::splat(1e4)),
        (DVec3::ZERO, DVec3::new(0.01, 1.0, 0.1)),
    ] {
        let body = body_with_holes(origin, h, [4, 3, 5], 3);
        for format in FORMATS {
            let path = dir.path().join(format!("scale.{}", format.extension()));
            write_mesh(&path, &body, format).unwrap();
            let found = read_mesh(&path, &DisplacementArray::Default)
                .unwrap_or_else(|e| panic!("{format:?} h={h}: {e}"));
            assert_same_body(&found, &body);
        }
    }
}

/// Shuffled cells and nodes, in every hand-written flavour: the map back to lattice cells is right.
#[test]
fn shuffled_meshes_as_vtk_and_paraview_write_them() {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(
        DVec3::new(10.0, -20.0, 1e6),
        DVec3::new(0.25, 0.5, 0.125),
        [6, 5, 4],
        11,
    );
    let (mesh, perm) = shuffled(&HexMesh::from_body(&body), 5);
    let expected = expected_cells(&body, &perm);
    let files: Vec<(&str, Vec<u8>)> = vec![
        (
            "vectors.vtk",
            legacy_ascii(&mesh, LegacyData::Vectors, false).into_bytes(),
        ),
        (
            "field.vtk",
            legacy_ascii(&mesh, LegacyData::Field, false).into_bytes(),
        ),
        (
            "v51.vtk",
            legacy_ascii(&mesh, LegacyData::Vectors, true).into_bytes(),
        ),
        (
            "v51-field.vtk",
            legacy_ascii(&mesh, LegacyData::Field, true).into_bytes(),
        ),
        ("ascii.vtu", vtu_ascii(&mesh).into_bytes()),
        ("raw64.vtu", vtu_raw_appended(&mesh, false, true, 0)),
        ("raw32.vtu", vtu_raw_appended(&mesh, false, false, 0)),
        ("zlib64.vtu", vtu_raw_appended(&mesh, true, true, 1000)),
        ("zlib32.vtu", vtu_raw_appended(&mesh, true, false, 256)),
        (
            "zlib-one-block.vtu",
            vtu_raw_appended(&mesh, true, true, 1 << 20),
        ),
        ("lzma64.vtu", vtu_raw_appended_lzma(&mesh, true, 1000)),
        ("lzma32.vtu", vtu_raw_appended_lzma(&mesh, false, 256)),
    ];
    for (name, bytes) in files {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let found =
            read_mesh(&path, &DisplacementArray::Default).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same_body(&found, &body);
        assert_eq!(found.cells.lattice_cells(), expected.as_slice(), "{name}");
        for (input, &cell) in expected.iter().enumerate() {
            assert_eq!(found.input_cell(cell), Some(input), "{name}");
        }
        assert_eq!(found.cells.len(), body.active_count());
        for cell in (0..body.lattice().cell_count() as u32).map(cgcontact::CellId) {
            if !body.is_active(cell) {
                assert_eq!(found.input_cell(cell), None, "{name}: hole {cell}");
            }
        }
    }
}

#[test]
fn undeformed_files_and_chosen_displacement_names() {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [3, 3, 3], 1);
    let mesh = HexMesh::from_body(&body);
    let path = dir.path().join("plain.vtk");
    std::fs::write(&path, legacy_ascii(&mesh, LegacyData::None, false)).unwrap();
    let found = read_mesh(&path, &DisplacementArray::Default).unwrap();
    assert!(!found.has_displacement);
    assert!(found.body.displacements().iter().all(|u| *u == DVec3::ZERO));

    // Renamed array: found when asked by name, ignored by default, an error when asked and missing.
    let renamed = legacy_ascii(&mesh, LegacyData::Vectors, false)
        .replace("VECTORS displacement", "VECTORS u_total");
    std::fs::write(&path, renamed).unwrap();
    let by_name = read_mesh(&path, &DisplacementArray::Named("u_total".into())).unwrap();
    assert_eq!(by_name.body.displacements(), body.displacements());
    assert!(
        !read_mesh(&path, &DisplacementArray::Default)
            .unwrap()
            .has_displacement
    );
    let err = read_mesh(&path, &DisplacementArray::Named("displacement".into())).unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains("plain.vtk")
            && message.contains("displacement")
            && message.contains("u_total"),
        "{message}"
    );
    let ignored = read_mesh(&path, &DisplacementArray::Ignore).unwrap();
    assert!(!ignored.has_displacement);
}

#[test]
fn paraview_outputs_are_readable_and_carry_the_answers() {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [4, 4, 4], 2);
    let cells = CellMap::ascending(&body);
    let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
    let points = vec![
        DVec3::splat(0.2),
        DVec3::new(1.1, 0.9, 1.3),
        DVec3::splat(-3.0),
        DVec3::new(f64::NAN, 0.0, 0.0),
    ];
    let answers = locator.locate_all(&points);
    let mesh_path = dir.path().join("deformed.vtu");
    write_deformed_vtu(&mesh_path, &body, &cells, &answers, true).unwrap();
    // Read back through vtkio: the deformed mesh is a valid .vtu whose node coordinates moved.
    let deformed = cgcontact_io::read_hex_mesh(&mesh_path, &DisplacementArray::Default).unwrap();
    assert_eq!(deformed.cells.len(), body.lattice().cell_count());
    let held = int_array(&mesh_path, "points_held", Data::Cell);
    let located = answers.iter().filter(|a| matches!(a, Ok(Some(_)))).count() as i64;
    assert_eq!(held.iter().sum::<i64>(), located);

    let points_path = dir.path().join("points.vtu");
    write_points_vtu(&points_path, &points, &answers, &cells).unwrap();
    let cell = int_array(&points_path, "cell", Data::Point);
    let expected: Vec<i64> = answers
        .iter()
        .map(|a| match a {
            Ok(Some(hit)) => cells.input_cell(hit.cell).unwrap() as i64,
            _ => -1,
        })
        .collect();
    assert_eq!(cell, expected);
    assert_eq!(cell[2], -1);
    assert!(cell[0] >= 0);
}

/// Which attributes of a piece to look in.
enum Data {
    Point,
    Cell,
}

/// The integer data array `name` of the first piece of `path`, read back through vtkio.
fn int_array(path: &std::path::Path, name: &str, data: Data) -> Vec<i64> {
    let vtk = vtkio::Vtk::import(path).unwrap();
    let vtkio::model::DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not a grid")
    };
    let piece = pieces
        .into_iter()
        .next()
        .unwrap()
        .into_loaded_piece_data(None)
        .unwrap();
    let attributes = match data {
        Data::Point => &piece.data.point,
        Data::Cell => &piece.data.cell,
    };
    attributes
        .iter()
        .find_map(|a| match a {
            vtkio::model::Attribute::DataArray(d) if d.name == name => {
                d.data.clone().cast_into::<i64>()
            }
            _ => None,
        })
        .unwrap_or_else(|| panic!("{}: no array {name}", path.display()))
}
