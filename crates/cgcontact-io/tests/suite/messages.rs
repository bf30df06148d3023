//! Error messages that name the file, the place and the fault in words a user understands, and
//! never echo raw bytes.

use crate::common;

use crate::common::{LegacyData, body_with_holes, legacy_ascii};
use cgcontact::glam::DVec3;
use cgcontact_io::{
    DisplacementArray, HexMesh, parse_hex_mesh, parse_points, parse_results, read_points,
};

fn points_error(text: &[u8]) -> String {
    parse_points(text).unwrap_err().to_string()
}

/// `1;2;3` read as one field was "header with 1 fields": now the separator is named.
#[test]
fn semicolon_and_tab_separated_rows_name_the_separator() {
    for (text, separator) in [
        (&b"x;y;z\n1;2;3\n"[..], "`;`"),
        (b"1;2;3\n4;5;6\n", "`;`"),
        (b"1\t2\t3\n", "tabs"),
    ] {
        let message = points_error(text);
        assert!(message.contains(separator), "{message}");
        assert!(message.contains("expected commas"), "{message}");
    }
    // Two commas and a semicolon: a plain field count, with the line.
    let message = points_error(b"1,2\n");
    assert!(message.contains("2 fields"), "{message}");
}

/// docs/formats.md says blank lines are skipped: lines of spaces were refused.
#[test]
fn whitespace_only_lines_are_skipped() {
    let points = parse_points(&b"x,y,z\n   \n1,2,3\n\t \n4,5,6\n  "[..]).unwrap();
    assert_eq!(points.len(), 2);
    let rows = parse_results(&b"point,cell,xi,eta,zeta\n  \n0,-1,NaN,NaN,NaN\n"[..]).unwrap();
    assert_eq!(rows.len(), 1);
    // A row of empty fields is not a blank line: it is an error, so that rows keep their numbers.
    assert!(parse_points(&b"1,2,3\n , , \n"[..]).is_err());
}

/// Raw bytes (control characters, invalid UTF-8) are escaped in messages, never printed as is.
#[test]
fn binary_bytes_are_escaped_in_messages() {
    let message = points_error(b"1,2,3\n4,\x1b[31m\x07,6\n");
    assert!(message.contains("line 2"), "{message}");
    assert!(
        !message.contains('\x1b') && !message.contains('\x07'),
        "{message:?}"
    );
    assert!(message.contains("\\u{1b}"), "{message}");
    let message = parse_results(&b"point,cell,xi,eta,zeta\n0,\x01\x02,0,0,0\n"[..])
        .unwrap_err()
        .to_string();
    assert!(!message.contains('\x01'), "{message:?}");
    let long = format!("1,2,{}\n", "9x".repeat(250));
    let message = points_error(long.as_bytes());
    assert!(message.len() < 200, "{message}");
}

/// A binary file given as points is refused from its first bytes, naming the file.
#[test]
fn binary_points_file_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.csv");
    std::fs::write(&path, b"1,2,3\n\0\0\0\x01").unwrap();
    let message = read_points(&path).unwrap_err().to_string();
    assert!(message.contains("points.csv"), "{message}");
    assert!(message.contains("NUL byte at byte 6"), "{message}");
}

/// `/dev/zero` as points or mesh was read until memory ran out.
#[cfg(target_os = "linux")]
#[test]
fn dev_zero_is_refused_not_read_forever() {
    let message = read_points("/dev/zero").unwrap_err().to_string();
    assert!(
        message.contains("/dev/zero") && message.contains("NUL byte"),
        "{message}"
    );
    let message = cgcontact_io::read_mesh("/dev/zero", &Default::default())
        .unwrap_err()
        .to_string();
    assert!(message.contains("neither a legacy"), "{message}");
    assert!(message.contains("\\u{0}"), "{message}");
}

/// A legacy file cut inside a data block named "line 1 … `# vtk DataFile Version 4.2`": the parser
/// backtracks to the start. Now the short section is named, with its line.
#[test]
fn legacy_file_cut_inside_a_section_names_that_section() {
    let body = body_with_holes(DVec3::new(1.0, 2.0, 3.0), DVec3::splat(0.5), [3, 2, 2], 8);
    let mesh = HexMesh::from_body(&body);
    for (flavour, text) in [
        (
            "4.2 vectors",
            legacy_ascii(&mesh, LegacyData::Vectors, false),
        ),
        ("5.1 field", legacy_ascii(&mesh, LegacyData::Field, true)),
    ] {
        let lines: Vec<&str> = text.lines().collect();
        let mut named = 0;
        // Cut after every line of data, and inside lines (a value cut short reads as a number).
        for cut in 5..lines.len() {
            for keep in [lines[cut].len() / 2, 0] {
                let head = lines[..cut].join("\n");
                let cut_text = format!("{head}\n{}", &lines[cut][..keep]);
                let Err(error) = parse_hex_mesh(cut_text.as_bytes(), &DisplacementArray::Default)
                else {
                    // Cut exactly at a section's end: a valid file (perhaps undeformed).
                    continue;
                };
                let message = error.to_string();
                assert!(
                    !message.contains("line 1:"),
                    "{flavour}, cut at line {cut}: {message}"
                );
                if message.contains("section holds") {
                    named += 1;
                }
            }
        }
        assert!(named > 5, "{flavour}: {named} cuts named their section");
    }
}

/// A node beyond the lattice's extent was "[0, 0, 0] spacings from the nearest node": now it is
/// named as outside, with the lattice's extent.
#[test]
fn node_outside_the_lattice_is_named_as_outside() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 1);
    let mut mesh = HexMesh::from_body(&body);
    let far = mesh
        .points
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.x.total_cmp(&b.1.x))
        .unwrap()
        .0;
    mesh.points[far].x += 2.0;
    let message = mesh.to_lattice().unwrap_err().to_string();
    assert!(message.contains(&format!("node {far}")), "{message}");
    assert!(message.contains("outside the lattice"), "{message}");
    assert!(!message.contains("[0.0, 0.0, 0.0] spacings"), "{message}");
}

/// XML errors named no place: now the line and byte of the fault, or of the array at fault.
#[test]
fn xml_errors_name_the_line() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 3);
    let text = common::vtu_ascii(&HexMesh::from_body(&body));
    let truncated = &text[..text.len() / 2];
    let message = parse_hex_mesh(truncated.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("line ") && message.contains("truncated"),
        "{message}"
    );
    let mismatched = text.replacen("</Points>", "</Pointz>", 1);
    let line = 1 + text[..text.find("</Points>").unwrap()]
        .matches('\n')
        .count();
    let message = parse_hex_mesh(mismatched.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains(&format!("line {line}")), "{message}");
}

/// A cell type the parser does not know (255) said "expected MapOpt", the parser's combinator;
/// now the line and the value, in words. A legacy 5.x `OFFSETS` list that does not start at 0
/// said "3 cells in the connectivity but 2 cell types"; now it says where the offsets start.
#[test]
fn parser_internals_and_offsets_not_starting_at_zero() {
    let body = body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [2, 1, 1], 1);
    let mesh = HexMesh::from_body(&body);
    let text = legacy_ascii(&mesh, LegacyData::Vectors, false);
    let types_at = text.find("CELL_TYPES").unwrap();
    let line = 2 + text[..types_at].matches('\n').count();
    let unknown = format!(
        "{}{}",
        &text[..types_at],
        text[types_at..].replacen("\n12\n", "\n255\n", 1)
    );
    let message = parse_hex_mesh(unknown.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains(&format!("line {line}")), "{message}");
    assert!(
        message.contains("`255`") && !message.contains("MapOpt"),
        "{message}"
    );

    let v51 = legacy_ascii(&mesh, LegacyData::Vectors, true);
    let n = mesh.cells.len();
    let starts: Vec<String> = (0..=n).map(|c| (8 * c).to_string()).collect();
    let shifted: Vec<String> = (0..=n).map(|c| (8 * c.max(1)).to_string()).collect();
    let bad = v51.replacen(&starts.join(" "), &shifted.join(" "), 1);
    assert_ne!(bad, v51);
    let message = parse_hex_mesh(bad.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains("start at 8"), "{message}");
}
