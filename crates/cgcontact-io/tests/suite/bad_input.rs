//! Truncated and corrupted VTK files, in every flavour: always an error value, never a panic.

use crate::common::{LegacyData, body_with_holes, legacy_ascii, vtu_ascii, vtu_raw_appended};
use cgcontact::glam::DVec3;
use cgcontact_io::{
    DisplacementArray, ErrorKind, HexMesh, MeshFormat, parse_hex_mesh, read_mesh, write_mesh,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn files() -> Vec<(String, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let body = body_with_holes(DVec3::new(1.0, 2.0, 3.0), DVec3::splat(0.5), [3, 2, 2], 8);
    let mesh = HexMesh::from_body(&body);
    let mut out = Vec::new();
    for format in [
        MeshFormat::LegacyAscii,
        MeshFormat::LegacyBinary,
        MeshFormat::Xml,
        MeshFormat::XmlZlib,
    ] {
        let path = dir.path().join(format!("m.{}", format.extension()));
        write_mesh(&path, &body, format).unwrap();
        out.push((format!("{format:?}"), std::fs::read(&path).unwrap()));
    }
    out.push((
        "legacy 5.1".into(),
        legacy_ascii(&mesh, LegacyData::Field, true).into_bytes(),
    ));
    out.push(("vtu ascii".into(), vtu_ascii(&mesh).into_bytes()));
    out.push(("vtu raw".into(), vtu_raw_appended(&mesh, false, true, 0)));
    out.push((
        "vtu raw zlib".into(),
        vtu_raw_appended(&mesh, true, false, 200),
    ));
    out
}

/// Parse and detect; the result does not matter, only that it is a value.
fn try_read(bytes: &[u8]) -> Result<(), ErrorKind> {
    parse_hex_mesh(bytes, &DisplacementArray::Default)?
        .to_lattice()
        .map(|_| ())
}

#[test]
fn every_flavour_parses_whole() {
    for (name, bytes) in files() {
        try_read(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn truncated_files_are_errors() {
    for (name, bytes) in files() {
        let step = (bytes.len() / 150).max(1);
        for cut in (0..bytes.len() - 40).step_by(step) {
            // The tail of a legacy file may be optional sections; anything cut before the cell
            // types must fail.
            let result = try_read(&bytes[..cut]);
            if cut < bytes.len() / 2 {
                assert!(
                    result.is_err(),
                    "{name} cut at {cut} of {} was accepted",
                    bytes.len()
                );
            }
        }
    }
}

#[test]
fn corrupted_files_never_panic() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    for (_, bytes) in files() {
        for _ in 0..300 {
            let mut bad = bytes.clone();
            for _ in 0..rng.random_range(1..4) {
                let at = rng.random_range(0..bad.len());
                bad[at] = match rng.random_range(0..4) {
                    0 => rng.random(),
                    1 => b'9',
                    2 => b' ',
                    _ => b'\n',
                };
            }
            let _ = try_read(&bad);
        }
    }
}

#[test]
fn not_vtk_at_all() {
    for text in [
        "",
        "   \n",
        "hello",
        "x,y,z\n1,2,3\n",
        "<html></html>",
        "# vtk DataFile Version 4.2\n",
    ] {
        assert!(try_read(text.as_bytes()).is_err(), "{text:?}");
    }
    let polydata = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\nPOLYGONS 1 4\n3 0 1 2\n";
    assert!(matches!(
        try_read(polydata.as_bytes()),
        Err(ErrorKind::NotUnstructuredGrid(_))
    ));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("poly.vtk");
    std::fs::write(&path, polydata).unwrap();
    let message = read_mesh(&path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("poly.vtk") && message.contains("unstructured"),
        "{message}"
    );
    let missing =
        read_mesh(dir.path().join("absent.vtu"), &DisplacementArray::Default).unwrap_err();
    assert!(
        matches!(missing.kind(), ErrorKind::Io(_)) && missing.to_string().contains("absent.vtu")
    );
}

#[test]
fn wrong_counts_and_missing_nodes_name_the_cell() {
    let body = body_with_holes(DVec3::ZERO, DVec3::ONE, [2, 2, 1], 3);
    let mesh = HexMesh::from_body(&body);
    let text = legacy_ascii(&mesh, LegacyData::Vectors, false);
    // Cell 1 references a node past the end.
    let mut broken = mesh.clone();
    broken.cells[1][2] = 999;
    match try_read(legacy_ascii(&broken, LegacyData::Vectors, false).as_bytes()) {
        Err(ErrorKind::MissingNode {
            cell: 1, node: 999, ..
        }) => {}
        other => panic!("{other:?}"),
    }
    match try_read(vtu_ascii(&broken).as_bytes()) {
        Err(ErrorKind::MissingNode {
            cell: 1, node: 999, ..
        }) => {}
        other => panic!("{other:?}"),
    }
    // More cell types than cells.
    let extra = text.replace(
        &format!("CELL_TYPES {}\n", mesh.cells.len()),
        &format!("CELL_TYPES {}\n12\n", mesh.cells.len() + 1),
    );
    assert!(try_read(extra.as_bytes()).is_err());
}
