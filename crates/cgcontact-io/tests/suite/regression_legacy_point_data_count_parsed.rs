//! Regression: a legacy file whose `POINT_DATA n` or `CELL_DATA n` was not its node or cell
//! count read without a word when vtkio's parser got through it: the parser reads each array by
//! its own length and never compares it with the section's count (`POINT_DATA 1` before a
//! displacement of every node read as a whole mesh). Found by an audit with files VTK wrote;
//! docs/formats.md lists the mismatch as an error. Each count is now checked, ASCII and binary.

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, MeshFormat, parse_hex_mesh, write_mesh};

use crate::common::body_with_holes;

/// `file` with its line `from` (whole) replaced by `to`.
fn with_line(file: &[u8], from: &str, to: &str) -> Vec<u8> {
    let key = format!("\n{from}\n");
    let at = file
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .unwrap_or_else(|| panic!("no line {from}"));
    [&file[..=at], to.as_bytes(), &file[at + key.len() - 1..]].concat()
}

#[test]
fn data_section_counts_that_parse_are_checked() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 4);
    let dir = tempfile::tempdir().unwrap();
    for format in [MeshFormat::LegacyAscii, MeshFormat::LegacyBinary] {
        let path = dir.path().join("mesh.vtk");
        write_mesh(&path, &body, format).unwrap();
        let file = std::fs::read(&path).unwrap();
        let mesh = parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
        let nodes = mesh.points.len();
        let cells = HexMesh::from_body(&body).cells.len();
        for count in [nodes - 1, 1, 2 * nodes, nodes + 1] {
            let file = with_line(
                &file,
                &format!("POINT_DATA {nodes}"),
                &format!("POINT_DATA {count}"),
            );
            let error = parse_hex_mesh(&file, &DisplacementArray::Default)
                .map(|_| ())
                .unwrap_err()
                .to_string();
            assert!(
                error.contains(&format!(
                    "`POINT_DATA {count}` does not match the {nodes} nodes"
                )),
                "{format:?}, {count}: {error}"
            );
        }
        for count in [cells - 1, cells + 1] {
            let file = with_line(
                &file,
                &format!("CELL_DATA {cells}"),
                &format!("CELL_DATA {count}"),
            );
            assert!(
                parse_hex_mesh(&file, &DisplacementArray::Default).is_err(),
                "{format:?}, CELL_DATA {count}"
            );
        }
    }
}
