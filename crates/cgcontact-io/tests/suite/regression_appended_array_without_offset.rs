//! Regression: an appended `<DataArray>` whose `offset` attribute was missing or misspelt
//! (`offzet="0"`) was read by vtkio from offset 0, the first array's block: the mesh was solved
//! with the wrong displacements and the run exited 0. Such an array is now an error naming it.

use std::path::Path;

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/vtk-written")
            .join(name),
    )
    .unwrap()
}

/// `bytes` with the first `from` after the tag of `array` replaced by `to`.
fn in_array_tag(bytes: &[u8], array: &str, from: &str, to: &str) -> Vec<u8> {
    let find = |needle: &[u8], start: usize| {
        start
            + bytes[start..]
                .windows(needle.len())
                .position(|w| w == needle)
                .unwrap()
    };
    let tag = find(format!("Name=\"{array}\"").as_bytes(), 0);
    let at = find(from.as_bytes(), tag);
    [&bytes[..at], to.as_bytes(), &bytes[at + from.len()..]].concat()
}

#[test]
fn an_appended_array_without_a_readable_offset_is_named() {
    for file in [
        "xml-appended-raw.vtu",
        "xml-appended-base64-lz4.vtu",
        "xml-appended-raw-zlib.vtu",
    ] {
        let intact = fixture(file);
        parse_hex_mesh(&intact, &DisplacementArray::Default).unwrap();
        for array in ["displacement", "connectivity"] {
            for (from, to, expected) in [
                (" offset=\"", " offzet=\"", "has no offset attribute"),
                (" offset=\"", " offset=\"x", "is not a byte count"),
            ] {
                let corrupt = in_array_tag(&intact, array, from, to);
                let message = parse_hex_mesh(&corrupt, &DisplacementArray::Default)
                    .map(|_| "read as a mesh".to_owned())
                    .unwrap_or_else(|e| e.to_string());
                assert!(
                    message.contains(expected) && message.contains(&format!("`{array}`")),
                    "{file}, {array}, {to}: {message}"
                );
            }
        }
    }
}
