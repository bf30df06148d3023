//! An XML file holding a polyhedron (VTK_POLYHEDRON, type 42) was refused with vtkio's
//! "Deserialization error: Cells data arrays must contain three DataArrays named ...", naming no
//! cell, no type and no line: VTK writes a polyhedron's faces as cell arrays of their own, which
//! vtkio does not take. The legacy form named the cell and its type. Now every form does, in
//! every encoding VTK writes and through a parallel file's piece (fixtures/vtk-written-polyhedra,
//! written by VTK 9.7.2 with its make.py), and in the layout of VTK before 9.4 (`faces`,
//! `faceoffsets`).

use std::path::{Path, PathBuf};

use cgcontact_io::{DisplacementArray, ErrorKind, parse_hex_mesh, read_body, read_hex_mesh};

fn folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written-polyhedra")
}

/// The refusal of `path`: it must be that cell 7 is a polyhedron.
fn refused(path: &Path) -> String {
    let error = read_body(path, &DisplacementArray::Default).unwrap_err();
    let message = error.to_string();
    let mut kind = error.kind();
    if let ErrorKind::Piece { error, .. } = kind {
        kind = error;
    }
    assert!(
        matches!(
            kind,
            ErrorKind::NotHexahedron {
                cell: 7,
                vtk_type: 42,
                ..
            }
        ),
        "{message}"
    );
    assert!(
        message.contains("cell 7: VTK cell type 42 (Polyhedron)"),
        "{message}"
    );
    message
}

#[test]
fn a_polyhedron_is_named_in_every_form_vtk_writes() {
    for name in [
        "polyhedron-ascii.vtu",
        "polyhedron-binary.vtu",
        "polyhedron-appended.vtu",
        "polyhedron-raw.vtu",
        "polyhedron-lzma.vtu",
        "polyhedron-5.1-ascii.vtk",
        "polyhedron-5.1-binary.vtk",
    ] {
        let message = refused(&folder().join(name));
        assert!(
            message.starts_with(&folder().join(name).display().to_string()),
            "{message}"
        );
    }
    // In a parallel file, the piece that holds it is named, the cell numbered across pieces.
    let message = refused(&folder().join("polyhedron.pvtu"));
    assert!(
        message.contains("piece 1 (") && message.contains("polyhedron_1.vtu"),
        "{message}"
    );
    // The piece without one reads.
    let piece = read_hex_mesh(
        folder().join("polyhedron_0.vtu"),
        &DisplacementArray::Default,
    );
    assert!(piece.is_ok_and(|mesh| mesh.displacement.is_some()));
}

/// VTK before 9.4 wrote the faces as `faces` and `faceoffsets`.
#[test]
fn a_polyhedron_in_the_older_layout_is_named() {
    let text = std::fs::read_to_string(folder().join("polyhedron-ascii.vtu")).unwrap();
    let older = text
        .replace("Name=\"face_connectivity\"", "Name=\"faces\"")
        .replace("Name=\"face_offsets\"", "Name=\"faceoffsets\"");
    let older: String = older
        .split_inclusive('\n')
        .scan(false, |skipping, line| {
            // Without the arrays from polyhedron_to_faces on: VTK wrote none.
            if line.contains("Name=\"polyhedron_") {
                *skipping = true;
            }
            let keep = !*skipping;
            if line.contains("</DataArray>") {
                *skipping = false;
            }
            Some(if keep { line } else { "" })
        })
        .collect();
    assert!(older.contains("Name=\"faces\"") && !older.contains("polyhedron_to_faces"));
    let message = parse_hex_mesh(older.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("cell 7: VTK cell type 42 (Polyhedron)"),
        "{message}"
    );
}

/// Another array among the cell arrays is still refused, as vtkio refuses it, with its line.
#[test]
fn another_extra_cell_array_is_still_refused() {
    let text = std::fs::read_to_string(folder().join("polyhedron-ascii.vtu")).unwrap();
    let other = text.replace("Name=\"face_offsets\"", "Name=\"extra\"");
    let message = parse_hex_mesh(other.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains("three DataArrays"), "{message}");
}
