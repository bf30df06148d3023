//! VTK's legacy writer puts a data set's own field data (ParaView's `TimeValue`, a solver's
//! `CYCLE`) in a `FIELD` block right after the `DATASET` line, before `POINTS`. vtkio's parser
//! knows `FIELD` only as point or cell data, and such a file was refused at that line. The block
//! is now skipped, in ASCII and binary files, and the mesh reads as it does without it.

use crate::common::{self, LegacyData, legacy_ascii};

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, MeshFormat, parse_hex_mesh, write_mesh};

fn mesh() -> HexMesh {
    common::displaced_mesh(7)
}

/// `bytes` with `block` inserted after the `DATASET UNSTRUCTURED_GRID` line.
fn with_block(bytes: &[u8], block: &[u8]) -> Vec<u8> {
    let line = b"DATASET UNSTRUCTURED_GRID\n";
    let at = bytes
        .windows(line.len())
        .position(|w| w == line)
        .expect("a DATASET line")
        + line.len();
    [&bytes[..at], block, &bytes[at..]].concat()
}

fn same_mesh(read: &HexMesh, expected: &HexMesh) {
    assert_eq!(read.points, expected.points);
    assert_eq!(read.cells, expected.cells);
    assert_eq!(read.displacement, expected.displacement);
}

#[test]
fn ascii_files_with_data_set_field_data_read_as_without_it() {
    let expected = mesh();
    for v51 in [false, true] {
        for data in [LegacyData::Vectors, LegacyData::Field] {
            let text = legacy_ascii(&expected, data, v51);
            for block in [
                "FIELD FieldData 1\nTimeValue 1 1 double\n0.5\n",
                "field FieldData 2\nTIME 1 1 double\n0.5\nCYCLE 1 1 int\n3\n",
                // CRLF line ends and a METADATA block, as VTK 9 writes for arrays with
                // information keys.
                "FIELD FieldData 1\r\nTimeValue 1 2 float\r\n0.5 1.5\r\nMETADATA\r\nINFORMATION 0\r\n\r\n",
            ] {
                let file = with_block(text.as_bytes(), block.as_bytes());
                let read = parse_hex_mesh(&file, &DisplacementArray::Default)
                    .unwrap_or_else(|e| panic!("{block:?}: {e}"));
                same_mesh(&read, &expected);
            }
        }
    }
}

#[test]
fn binary_files_with_data_set_field_data_read_as_without_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.vtk");
    let body = common::body_with_holes(DVec3::new(1.0, -2.0, 0.5), DVec3::splat(0.5), [3, 2, 2], 7);
    write_mesh(&path, &body, MeshFormat::LegacyBinary).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let expected = parse_hex_mesh(&bytes, &DisplacementArray::Default).unwrap();
    // Big-endian values whose bytes include a newline, a space and what reads as `POINTS`.
    let mut block = b"FIELD FieldData 2\nTimeValue 1 1 double\n".to_vec();
    block.extend(f64::from_bits(0x0a20_504f_494e_5453).to_be_bytes());
    block.extend(b"\nCYCLE 1 2 int\n");
    block.extend(7i32.to_be_bytes());
    block.extend(0x0a0a_0a0ai32.to_be_bytes());
    block.extend(b"\n");
    let file = with_block(&bytes, &block);
    let read = parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
    same_mesh(&read, &expected);
}

/// A malformed block is still an error, naming its line.
#[test]
fn a_malformed_data_set_field_block_names_its_line() {
    let text = legacy_ascii(&mesh(), LegacyData::Vectors, false);
    for block in [
        "FIELD FieldData 1\nTimeValue 1 2 double\n0.5\n",
        "FIELD FieldData 2\nTimeValue 1 1 double\n0.5\n",
        "FIELD FieldData 1\nTimeValue 1 1 complex\n0.5\n",
    ] {
        let file = with_block(text.as_bytes(), block.as_bytes());
        let message = parse_hex_mesh(&file, &DisplacementArray::Default)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("line 5") || message.contains("line 6"),
            "{block:?}: {message}"
        );
    }
}
