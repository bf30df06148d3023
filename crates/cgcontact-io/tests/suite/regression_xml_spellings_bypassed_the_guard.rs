//! Regression: the checks run before vtkio found XML elements and attributes by searching bytes,
//! so legal XML spelt otherwise slipped past them. A comment or a processing instruction holding
//! `<VTKFile>` before the root, a `>` inside an attribute value, or a character reference in
//! `format` or `compressor` hid a zlib block header claiming 549 GB from the block-header check,
//! and vtkio's allocation aborted the process (exit 134, in the CLI, Python and MPI alike). The
//! file is now tokenized with quick-xml and rewritten in one plain spelling first
//! (`xml_normal`), which also bounds nesting and attributes and refuses trailing content.

use std::path::Path;

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

fn fixture(path: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures")
            .join(path),
    )
    .unwrap()
}

fn error(bytes: &[u8]) -> String {
    parse_hex_mesh(bytes, &DisplacementArray::Default)
        .unwrap_err()
        .to_string()
}

/// `text` with the first `from` replaced by `to`.
fn replaced(text: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = text
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap_or_else(|| panic!("{from} not found"));
    [&text[..at], to.as_bytes(), &text[at + from.len()..]].concat()
}

#[test]
fn a_corrupt_block_header_is_refused_however_the_xml_is_spelt() {
    let corrupt = fixture("regressions/corrupt-zlib-block-header.vtu");
    let spellings: [(&str, Vec<u8>); 6] = [
        (
            "comment before the root",
            [b"<!-- <VTKFile> -->\n".as_slice(), &corrupt].concat(),
        ),
        (
            "processing instruction before the root",
            [b"<?note <VTKFile> ?>\n".as_slice(), &corrupt].concat(),
        ),
        (
            "`>` in a DataArray attribute before format",
            replaced(&corrupt, "<DataArray type=", "<DataArray note=\">\" type="),
        ),
        (
            "`>` in a VTKFile attribute before compressor",
            replaced(&corrupt, "<VTKFile type=", "<VTKFile note=\">\" type="),
        ),
        (
            "character reference in format",
            replaced(&corrupt, "format=\"binary\"", "format=\"&#98;inary\""),
        ),
        (
            "character reference in compressor",
            replaced(
                &corrupt,
                "\"vtkZLibDataCompressor\"",
                "\"vtk&#x5A;LibDataCompressor\"",
            ),
        ),
    ];
    for (spelling, bytes) in spellings {
        let message = error(&bytes);
        assert!(
            message.contains("compressed array"),
            "{spelling}: {message}"
        );
    }
}

#[test]
fn vtk_files_spelt_otherwise_read_as_the_plain_ones() {
    for file in [
        "vtk-written/xml-binary-zlib.vtu",
        "vtk-written/xml-appended-raw.vtu",
    ] {
        let plain = fixture(file);
        let expected = parse_hex_mesh(&plain, &DisplacementArray::Default).unwrap();
        let mut spelt = [
            b"<?xml version=\"1.0\"?>\n<!-- a <VTKFile> -->\n".as_slice(),
            &plain,
        ]
        .concat();
        spelt = replaced(&spelt, "<VTKFile type=", "<VTKFile note='a > b' type=");
        spelt = replaced(&spelt, "Name=\"displacement\"", "Name=\"displa&#99;ement\"");
        spelt = replaced(&spelt, "type=\"Float64\"", "type=\"Float&#54;4\"");
        spelt.extend_from_slice(b"\n<!-- trailing comment -->\n");
        let mesh = parse_hex_mesh(&spelt, &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(mesh.points, expected.points, "{file}");
        assert_eq!(mesh.cells, expected.cells, "{file}");
        assert!(mesh.displacement.is_some(), "{file}");
        assert_eq!(mesh.displacement, expected.displacement, "{file}");
    }
}

/// A `<Piece>` with 60,000 attributes took 13 s (300,000 more than a minute): quick-xml's check
/// for duplicates compares each with all before it. Elements with more than 256 are refused
/// before any check.
#[test]
fn an_element_with_very_many_attributes_is_refused_at_once() {
    let plain = fixture("vtk-written/xml-binary-zlib.vtu");
    let many: String = (0..60_000).map(|i| format!(" a{i}=\"{i}\"")).collect();
    let bytes = replaced(&plain, "<Piece ", &format!("<Piece{many} "));
    let message = error(&bytes);
    assert!(message.contains("60002 attributes"), "{message}");
    assert!(message.contains("line 3"), "{message}");
}

/// 30 MB of unclosed `<a>` made vtkio's parser hold 765 MB before it reported the missing end
/// tag. Nesting deeper than a VTK file needs is refused as it is read.
#[test]
fn unclosed_nested_elements_are_refused_at_a_depth_bound() {
    let plain = fixture("vtk-written/xml-binary-zlib.vtu");
    let deep = replaced(
        &plain,
        "<PointData>",
        &format!("<PointData>{}", "<a>".repeat(100_000)),
    );
    let message = error(&deep);
    assert!(message.contains("nested 33 elements deep"), "{message}");
}

/// Content after `</VTKFile>` was ignored, where the legacy reader refuses input left over.
#[test]
fn content_after_the_root_element_is_refused() {
    let plain = fixture("vtk-written/xml-binary-zlib.vtu");
    for (tail, expected) in [
        ("garbage<<<", "content after </VTKFile>: `garbage"),
        ("<VTKFile></VTKFile>", "a second root element <VTKFile>"),
    ] {
        let message = error(&[plain.as_slice(), tail.as_bytes()].concat());
        assert!(message.contains(expected), "{tail}: {message}");
    }
    let raw = fixture("vtk-written/xml-appended-raw.vtu");
    let message = error(&[raw.as_slice(), b"</VTKFile>\n"].concat());
    assert!(message.contains("content after </VTKFile>"), "{message}");
}
