//! Regression: a legacy file whose `POINT_DATA n` was not its node count (28 for 27 nodes, or
//! 4000000000), and a binary file with `POINTS 4000000000`, `CELLS 27 4000000000` or
//! `POINT_DATA 65` for 64 nodes, said "line 1: cannot parse `# vtk DataFile Version 4.2`": the
//! parser backtracks to the start of the file. `POINTS 12297829382473034438` said "holds 81 of its
//! 82 values": 3 × n wrapped (a panic in a debug build). Each now names the section and its line.

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, MeshFormat, parse_hex_mesh, write_mesh};

use crate::common::{LegacyData, body_with_holes, legacy_ascii};

fn error(file: &[u8]) -> String {
    parse_hex_mesh(file, &DisplacementArray::Default)
        .unwrap_err()
        .to_string()
}

/// The file with the first line starting `keyword ` replaced by `with`, and that line's number.
fn replace_header(file: &[u8], keyword: &str, with: &str) -> (Vec<u8>, usize) {
    let key = format!("\n{keyword} ");
    let at = 1 + file
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .unwrap_or_else(|| panic!("no {keyword} line"));
    let end = at + file[at..].iter().position(|&b| b == b'\n').unwrap();
    let line = 1 + file[..at].iter().filter(|&&b| b == b'\n').count();
    ([&file[..at], with.as_bytes(), &file[end..]].concat(), line)
}

#[test]
fn legacy_sections_with_impossible_counts_are_named_with_their_line() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 4);
    let nodes = HexMesh::from_body(&body).points.len();
    let ascii = legacy_ascii(&HexMesh::from_body(&body), LegacyData::Vectors, false);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.vtk");
    write_mesh(&path, &body, MeshFormat::LegacyBinary).unwrap();
    let binary = std::fs::read(&path).unwrap();
    let binary_nodes = parse_hex_mesh(&binary, &DisplacementArray::Default)
        .unwrap()
        .points
        .len();
    let cells = body.active_count();
    let cases = [
        (
            "ascii",
            ascii.as_bytes(),
            "POINT_DATA",
            format!("POINT_DATA {}", nodes + 1),
            "does not match",
        ),
        (
            "ascii",
            ascii.as_bytes(),
            "POINT_DATA",
            "POINT_DATA 4000000000".to_owned(),
            "does not match",
        ),
        (
            "ascii",
            ascii.as_bytes(),
            "POINTS",
            "POINTS 12297829382473034438 double".to_owned(),
            "impossible count",
        ),
        (
            "binary",
            &binary,
            "POINTS",
            "POINTS 4000000000 double".to_owned(),
            "bytes follow its header",
        ),
        (
            "binary",
            &binary,
            "CELLS",
            format!("CELLS {cells} 4000000000"),
            "bytes follow its header",
        ),
        (
            "binary",
            &binary,
            "POINT_DATA",
            format!("POINT_DATA {}", binary_nodes + 1),
            "does not match",
        ),
        (
            "binary",
            &binary,
            "POINTS",
            "POINTS 6148914691236517206 double".to_owned(),
            "impossible count",
        ),
    ];
    for (flavour, file, keyword, header, fault) in cases {
        let (bad, line) = replace_header(file, keyword, &header);
        let message = error(&bad);
        assert!(
            message.contains(&format!("line {line}: "))
                && message.contains(&format!("`{header}`"))
                && message.contains(fault),
            "{flavour} `{header}`: {message}"
        );
        assert!(!message.contains("line 1:"), "{flavour}: {message}");
    }
}

/// A binary file whose `POINTS n` or `CELL_TYPES n` is one more or one less than the values it
/// holds was refused with vtkio's message, which quoted the raw bytes it landed on ("line 10:
/// cannot parse `\u{1}\u{0}\u{0}\u{0}…`"). The walk now finds where the section's values end and
/// that no header follows them, and names the section's line and header.
#[test]
fn binary_counts_off_by_one_name_their_section() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 4);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.vtk");
    write_mesh(&path, &body, MeshFormat::LegacyBinary).unwrap();
    let binary = std::fs::read(&path).unwrap();
    let mesh = parse_hex_mesh(&binary, &DisplacementArray::Default).unwrap();
    let (nodes, cells) = (mesh.points.len(), mesh.cells.len());
    for (keyword, count, tail) in [
        ("POINTS", nodes - 1, " double"),
        ("POINTS", nodes + 1, " double"),
        ("CELL_TYPES", cells - 1, ""),
        ("CELL_TYPES", cells + 1, ""),
    ] {
        let header = format!("{keyword} {count}{tail}");
        let (bad, line) = replace_header(&binary, keyword, &header);
        let message = error(&bad);
        assert!(
            message.contains(&format!("line {line}: the `{header}` section"))
                && message.contains("no section header follows"),
            "`{header}`: {message}"
        );
        assert!(!message.contains("\\u{"), "`{header}`: {message}");
    }
}
