//! A displacement array that is in the file but cannot be decoded is an error naming it. vtkio
//! drops such an array silently, and the mesh was then solved as undeformed with exit code 0.

use crate::common;

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, MeshFormat, parse_hex_mesh, write_mesh};

fn mesh() -> HexMesh {
    common::displaced_mesh(5)
}

/// Both ways of asking for the array refuse the file, naming the array.
fn refused(bytes: &[u8], case: &str) {
    for which in [
        DisplacementArray::Default,
        DisplacementArray::Named("displacement".to_owned()),
    ] {
        match parse_hex_mesh(bytes, &which) {
            Ok(mesh) => panic!(
                "{case}: read, displacement {}",
                if mesh.displacement.is_some() {
                    "present"
                } else {
                    "dropped"
                }
            ),
            Err(error) => {
                let message = error.to_string();
                assert!(message.contains("displacement"), "{case}: {message}");
                assert!(!message.contains("found: none"), "{case}: {message}");
            }
        }
    }
}

/// The byte range of the displacement DataArray's text content.
fn displacement_content(text: &str) -> std::ops::Range<usize> {
    let tag = text.find("Name=\"displacement\"").unwrap();
    let start = tag + text[tag..].find('>').unwrap() + 1;
    let end = start + text[start..].find("</DataArray>").unwrap();
    start..end
}

#[test]
fn the_intact_files_read_with_their_displacement() {
    let mesh = mesh();
    let ascii = common::vtu_ascii(&mesh);
    let read = parse_hex_mesh(ascii.as_bytes(), &DisplacementArray::Default).unwrap();
    assert_eq!(read.displacement, mesh.displacement);
    for compressed in [false, true] {
        let raw = common::vtu_raw_appended(&mesh, compressed, true, 4096);
        let read = parse_hex_mesh(&raw, &DisplacementArray::Default).unwrap();
        assert_eq!(read.displacement, mesh.displacement);
    }
}

#[test]
fn ascii_array_one_tuple_short_or_long() {
    let text = common::vtu_ascii(&mesh());
    let range = displacement_content(&text);
    let values: Vec<&str> = text[range.clone()].split_whitespace().collect();
    let short = values[..values.len() - 3].join(" ");
    let long = format!("{} 0 0 0", values.join(" "));
    for (case, content) in [("one tuple short", short), ("one tuple long", long)] {
        let corrupt = format!("{}{content}{}", &text[..range.start], &text[range.end..]);
        refused(corrupt.as_bytes(), case);
    }
}

#[test]
fn a_short_array_after_a_piece_of_no_cell() {
    // The piece of no cell is blanked before vtkio reads the file, and the arrays the text
    // declares were looked up by vtkio's piece index: the empty piece's (none) stood for the
    // corrupt one's, and the mesh read as undeformed.
    let text = common::vtu_ascii(&mesh());
    let range = displacement_content(&text);
    let values: Vec<&str> = text[range.clone()].split_whitespace().collect();
    let short = values[..values.len() - 3].join(" ");
    let corrupt = format!("{}{short}{}", &text[..range.start], &text[range.end..]);
    let empty = "<Piece NumberOfPoints=\"0\" NumberOfCells=\"0\">\n<PointData>\n</PointData>\n\
        <Points>\n<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" \
        format=\"ascii\">\n</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" \
        Name=\"connectivity\" format=\"ascii\">\n</DataArray>\n<DataArray type=\"Int64\" \
        Name=\"offsets\" format=\"ascii\">\n</DataArray>\n<DataArray type=\"UInt8\" \
        Name=\"types\" format=\"ascii\">\n</DataArray>\n</Cells>\n</Piece>\n";
    let at = corrupt.find("<Piece").unwrap();
    let with_empty = format!("{}{empty}{}", &corrupt[..at], &corrupt[at..]);
    refused(with_empty.as_bytes(), "short, after a piece of no cell");
}

#[test]
fn base64_array_with_garbage_or_an_extra_pad() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.vtu");
    let body = common::body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 9);
    let mut body = body;
    body.update_displacements(|_, x, u| *u = DVec3::new(0.01 * x.y, 0.0, -0.01 * x.x))
        .unwrap();
    write_mesh(&path, &body, MeshFormat::Xml).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let range = displacement_content(&text);
    let content = &text[range.clone()];
    let middle = content.len() / 2;
    for (case, corrupt) in [
        (
            "garbage",
            format!("{}!!*~{}", &content[..middle], &content[middle..]),
        ),
        ("an extra =", format!("{}=", content.trim_end())),
        ("one tuple short", content[..content.len() - 32].to_owned()),
    ] {
        let file = format!("{}{corrupt}{}", &text[..range.start], &text[range.end..]);
        refused(file.as_bytes(), case);
    }
}

/// The displacement is the first array of the appended block: its header starts right after `_`.
fn appended_start(bytes: &[u8]) -> usize {
    let tag = bytes
        .windows(13)
        .position(|w| w == b"<AppendedData")
        .unwrap();
    tag + bytes[tag..].iter().position(|&b| b == b'_').unwrap() + 1
}

#[test]
fn raw_appended_array_of_size_zero() {
    let mut bytes = common::vtu_raw_appended(&mesh(), false, true, 64);
    let at = appended_start(&bytes);
    bytes[at..at + 8].copy_from_slice(&0u64.to_le_bytes());
    refused(&bytes, "size 0");
}

/// Never a silently different displacement: an error naming the array, or (where the size error
/// is harmless: the last block's stream ends where it should) the right values.
#[test]
fn zlib_block_size_off_by_8_or_16() {
    let mesh = mesh();
    let original = common::vtu_raw_appended(&mesh, true, true, 100);
    let at = appended_start(&original);
    let blocks = u64::from_le_bytes(original[at..at + 8].try_into().unwrap()) as usize;
    assert!(blocks > 2, "{blocks} blocks");
    let mut refused_any = false;
    for block in 0..blocks {
        // Header: blocks, block size, last block size, then each block's compressed size.
        let field = at + 24 + 8 * block;
        let size = u64::from_le_bytes(original[field..field + 8].try_into().unwrap());
        for delta in [8, 16] {
            for sized in [size + delta, size - delta] {
                let mut bytes = original.clone();
                bytes[field..field + 8].copy_from_slice(&sized.to_le_bytes());
                let case = format!("block {block}: compressed size {size} -> {sized}");
                match parse_hex_mesh(&bytes, &DisplacementArray::Default) {
                    Ok(read) => assert_eq!(read.displacement, mesh.displacement, "{case}"),
                    Err(error) => {
                        refused_any = true;
                        let message = error.to_string();
                        assert!(!message.contains("found: none"), "{case}: {message}");
                    }
                }
            }
        }
    }
    assert!(refused_any);
}

#[test]
fn payload_that_is_not_zlib() {
    let mut bytes = common::vtu_raw_appended(&mesh(), true, true, 4096);
    let at = appended_start(&bytes);
    let blocks = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let data = at + 24 + 8 * blocks;
    for b in &mut bytes[data..data + 6] {
        *b = 0x55;
    }
    refused(&bytes, "not zlib");
}

/// One rule for every format: a NaN at a node no cell uses was refused in legacy files and
/// accepted in XML; now it is refused in both, naming the node.
#[test]
fn nan_at_an_unused_node_is_refused_in_every_format() {
    for (what, at_point) in [("coordinate", true), ("displacement", false)] {
        let mut mesh = mesh();
        let unused = mesh.points.len();
        mesh.points
            .push(DVec3::new(0.25, if at_point { f64::NAN } else { 0.0 }, 9.0));
        let u = mesh.displacement.as_mut().unwrap();
        u.push(DVec3::new(if at_point { 0.0 } else { f64::NAN }, 0.0, 0.0));
        let files: Vec<(&str, Vec<u8>)> = vec![
            (
                "legacy ascii",
                common::legacy_ascii(&mesh, common::LegacyData::Vectors, false).into_bytes(),
            ),
            ("vtu ascii", common::vtu_ascii(&mesh).into_bytes()),
            (
                "vtu raw appended",
                common::vtu_raw_appended(&mesh, false, true, 4096),
            ),
        ];
        for (format, bytes) in files {
            let error = parse_hex_mesh(&bytes, &DisplacementArray::Default).expect_err(&format!(
                "{format}: NaN {what} at unused node {unused} accepted"
            ));
            let message = error.to_string();
            if format != "legacy ascii" {
                assert!(
                    message.contains(&format!("{unused}")),
                    "{format}: {message}"
                );
            }
        }
    }
}

/// A legacy file cut right after its `POINT_DATA n` line, or after a `CELL_DATA n` line before
/// it (where VTK writes it), was read as a mesh without displacement (vtkio accepts a data
/// section with no array), and solved as undeformed with exit code 0. Now it is refused, naming
/// the line. A file that ends with vtkio's own bare `CELL_DATA n` after its `POINT_DATA` still
/// reads.
#[test]
fn legacy_file_cut_after_a_data_section_header() {
    let mut body = common::body_with_holes(DVec3::ZERO, DVec3::splat(0.5), [3, 2, 2], 9);
    body.update_displacements(|_, x, u| *u = DVec3::new(0.01 * x.y, 0.0, -0.01 * x.x))
        .unwrap();
    let mesh = HexMesh::from_body(&body);
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for (format, how) in [
        ("ascii", MeshFormat::LegacyAscii),
        ("binary", MeshFormat::LegacyBinary),
    ] {
        let path = dir.path().join(format!("{format}.vtk"));
        write_mesh(&path, &body, how).unwrap();
        files.push((format, std::fs::read(&path).unwrap()));
    }
    let cells = mesh.cells.len();
    for (format, bytes) in files {
        // The intact file (vtkio's: a bare `CELL_DATA` line ends it) reads with its
        // displacement.
        assert!(
            bytes
                .trim_ascii_end()
                .ends_with(format!("CELL_DATA {cells}").as_bytes())
        );
        let read = parse_hex_mesh(&bytes, &DisplacementArray::Default).unwrap();
        assert_eq!(read.displacement, mesh.displacement, "{format}");
        let header = bytes
            .windows(11)
            .rposition(|w| w == b"POINT_DATA ")
            .unwrap();
        let line_end = header + bytes[header..].iter().position(|&b| b == b'\n').unwrap();
        let cut_points = bytes[..=line_end].to_vec();
        let mut cut_cells = bytes[..header].to_vec();
        cut_cells.extend_from_slice(format!("CELL_DATA {cells}\n").as_bytes());
        for (case, cut) in [("POINT_DATA", cut_points), ("CELL_DATA", cut_cells)] {
            let error = parse_hex_mesh(&cut, &DisplacementArray::Default)
                .expect_err(&format!("{format}: cut after {case} accepted"));
            let message = error.to_string();
            assert!(
                message.contains(case) && message.contains("truncated"),
                "{format}, {case}: {message}"
            );
        }
    }
}

/// What vtkio skips without a word in a well-formed XML file: a tag that is not `<DataArray>`
/// inside the data sections (one corrupt byte of the displacement's tag dropped it, and the mesh
/// was solved as undeformed with exit code 0), a section tag that is not a known one inside
/// `<Piece>`, an array type VTK does not have, and cell arrays that are not integers (vtkio
/// truncated a connectivity of 6.5 to 6). Each is refused, naming the line and the element.
#[test]
fn xml_elements_and_types_vtkio_would_skip() {
    let text = common::vtu_ascii(&mesh());
    let intact = parse_hex_mesh(text.as_bytes(), &DisplacementArray::Default).unwrap();
    assert!(intact.displacement.is_some());
    let line_of = |needle: &str| 1 + text[..text.find(needle).unwrap()].matches('\n').count();
    let cases = [
        (
            "<DataArray type=\"Float64\" Name=\"displacement\"",
            "<DataArrax type=\"Float64\" Name=\"displacement\"",
            "<DataArrax> inside <PointData>",
        ),
        ("<PointData", "<PointDatx", "<PointDatx> inside <Piece>"),
        (
            "<DataArray type=\"Float64\" Name=\"displacement\"",
            "<DataArray type=\"Float128\" Name=\"displacement\"",
            "Float128",
        ),
        (
            "<DataArray type=\"Float64\" Name=\"Points\"",
            "<DataArray type=\"String\" Name=\"Points\"",
            "String",
        ),
        (
            "<DataArray type=\"Int64\" Name=\"connectivity\"",
            "<DataArray type=\"Float64\" Name=\"connectivity\"",
            "`connectivity` is of type Float64",
        ),
    ];
    for (from, to, expected) in cases {
        let corrupt = text.replacen(from, to, 1);
        assert_ne!(corrupt, text);
        let error = parse_hex_mesh(corrupt.as_bytes(), &DisplacementArray::Default)
            .expect_err(&format!("{to}: accepted"));
        let message = error.to_string();
        let line = format!("line {}:", line_of(from));
        assert!(
            message.contains(expected) && message.contains(&line),
            "{to}: {message}"
        );
    }
    // Other numeric types still read: an Int32 connectivity, Float32 points.
    let other = text
        .replacen(
            "type=\"Int64\" Name=\"connectivity\"",
            "type=\"Int32\" Name=\"connectivity\"",
            1,
        )
        .replacen(
            "type=\"Float64\" Name=\"Points\"",
            "type=\"Float32\" Name=\"Points\"",
            1,
        );
    parse_hex_mesh(other.as_bytes(), &DisplacementArray::Default).unwrap();
}

/// Two point arrays named as the displacement asked for (in a `.vtu` or in a legacy file): the
/// first one was used without a word. Now it is an error: which one is meant is ambiguous.
#[test]
fn two_arrays_with_the_displacements_name() {
    let mesh = mesh();
    let vtu = common::vtu_ascii(&mesh);
    let start = vtu
        .find("        <DataArray type=\"Float64\" Name=\"displacement\"")
        .unwrap();
    let end = vtu[start..].find("</DataArray>\n").unwrap() + start + "</DataArray>\n".len();
    let twice_vtu = format!("{}{}{}", &vtu[..end], &vtu[start..end], &vtu[end..]);
    let legacy = common::legacy_ascii(&mesh, common::LegacyData::Vectors, false);
    let start = legacy.find("VECTORS displacement").unwrap();
    let end = legacy[start..]
        .find("\nCELL_DATA")
        .map_or(legacy.len(), |i| start + i + 1);
    let twice_legacy = format!(
        "{}{}{}",
        &legacy[..end],
        &legacy[start..end],
        &legacy[end..]
    );
    for (format, bytes) in [("vtu", twice_vtu), ("legacy", twice_legacy)] {
        let error = parse_hex_mesh(bytes.as_bytes(), &DisplacementArray::Default)
            .expect_err(&format!("{format}: accepted"));
        let message = error.to_string();
        assert!(
            message.contains("displacement") && message.contains("ambiguous"),
            "{format}: {message}"
        );
    }
}

/// Messages that quote a file's text, newlines included (a raw appended `offset` attribute, an
/// end tag that does not match), stay on one line, their control characters escaped.
#[test]
fn messages_that_quote_the_file_stay_on_one_line() {
    let mesh = mesh();
    let raw = common::vtu_raw_appended(&mesh, false, true, 4096);
    let at = raw.windows(8).position(|w| w == b"offset=\"").unwrap() + 8;
    let mut bad_offset = raw[..at].to_vec();
    bad_offset.extend_from_slice(b"0\n  x");
    bad_offset.extend_from_slice(&raw[at + raw[at..].iter().position(|&b| b == b'"').unwrap()..]);
    let text = common::vtu_ascii(&mesh);
    let bad_end = text.replacen("</Points>", "</Poi\nnts>", 1);
    for (case, bytes) in [("offset", bad_offset), ("end tag", bad_end.into_bytes())] {
        let error = parse_hex_mesh(&bytes, &DisplacementArray::Default)
            .expect_err(&format!("{case}: accepted"));
        let message = error.to_string();
        assert!(!message.contains('\n'), "{case}: {message}");
        assert!(message.contains("\\n"), "{case}: {message}");
    }
}

/// A displacement declared with `NumberOfComponents="2"` (or none, which VTK reads as 1) over the
/// 3 values a node of the file holds: vtkio drops the array, and the message listed a wrong
/// length, corrupt base64 or compressed data as the causes without naming the component count,
/// the one the file states. It now names it; the causes stay for a declared 3.
#[test]
fn a_component_count_other_than_3_is_named() {
    let text = common::vtu_ascii(&mesh());
    let declared = "Name=\"displacement\" NumberOfComponents=\"3\"";
    assert!(text.contains(declared), "the fixture's declaration moved");
    for (with, says) in [
        (
            "Name=\"displacement\" NumberOfComponents=\"2\"",
            "NumberOfComponents=\"2\"",
        ),
        ("Name=\"displacement\"", "without NumberOfComponents"),
    ] {
        let bad = text.replacen(declared, with, 1);
        refused(bad.as_bytes(), with);
        let message = parse_hex_mesh(bad.as_bytes(), &DisplacementArray::Default)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains(says) && message.contains("3 components per node"),
            "{with}: {message}"
        );
    }
    let range = displacement_content(&text);
    let values: Vec<&str> = text[range.clone()].split_whitespace().collect();
    let short = values[..values.len() - 3].join(" ");
    let short = format!("{}{short}{}", &text[..range.start], &text[range.end..]);
    let message = parse_hex_mesh(short.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains("cannot be decoded"), "{message}");
}

/// A displacement array of one or two components is named with its count, in the right number
/// ("1 components per node" read as a typo).
#[test]
fn a_displacement_of_one_or_two_components_is_counted_in_words() {
    for (components, says) in [(1, "1 component per node"), (2, "2 components per node")] {
        let mut text = String::from(
            "# vtk DataFile Version 4.2\nc\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 double\n",
        );
        for k in 0..2 {
            for (i, j) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                text += &format!("{i} {j} {k}\n");
            }
        }
        text += "CELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\nPOINT_DATA 8\n";
        text += &format!("FIELD f 1\ndisplacement {components} 8 double\n");
        text += &"0 ".repeat(8 * components);
        text += "\n";
        let which = DisplacementArray::Named("displacement".to_owned());
        let error = parse_hex_mesh(text.as_bytes(), &which).unwrap_err();
        let message = error.to_string();
        assert!(message.contains(says), "{components}: {message}");
    }
}
