//! The legacy files VTK wrote for the string-array and id-section tests
//! (`fixtures/vtk-written-strings`, `fixtures/vtk-written-ids`), and byte edits on them.

use std::path::{Path, PathBuf};

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh};

/// The legacy file versions and kinds VTK 9.7.2 writes.
pub const FLAVOURS: [&str; 4] = ["4.2-ascii", "4.2-binary", "5.1-ascii", "5.1-binary"];

/// The fixture folder `fixtures/{name}`.
pub fn folder(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(name)
}

/// The bytes of `folder/name`.
pub fn read(folder: &Path, name: &str) -> Vec<u8> {
    std::fs::read(folder.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The mesh `bytes` hold, or the error's message.
pub fn parse(bytes: &[u8]) -> Result<HexMesh, String> {
    parse_hex_mesh(bytes, &DisplacementArray::Default).map_err(|e| e.to_string())
}

/// The body of `folder/plain-{flavour}.vtk`, the one both make.py scripts write without the
/// arrays under test: 10 cells of 12, 35 nodes, displaced.
pub fn plain(folder: &Path, flavour: &str) -> HexMesh {
    let mesh = parse(&read(folder, &format!("plain-{flavour}.vtk"))).unwrap();
    assert_eq!(mesh.cells.len(), 10, "{flavour}");
    assert_eq!(mesh.points.len(), 35, "{flavour}");
    assert!(
        mesh.displacement
            .as_ref()
            .is_some_and(|u| u.iter().any(|v| *v != DVec3::ZERO)),
        "{flavour}"
    );
    mesh
}

/// `bytes` with the first `from` replaced by `to`.
pub fn replaced(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let at = position(bytes, from);
    [&bytes[..at], to, &bytes[at + from.len()..]].concat()
}

/// Where the first `text` is in `bytes`.
pub fn position(bytes: &[u8], text: &[u8]) -> usize {
    bytes
        .windows(text.len())
        .position(|w| w == text)
        .unwrap_or_else(|| panic!("{:?} is in the file", String::from_utf8_lossy(text)))
}

/// The 1-based line of the first `text` in `bytes`, every line end before it counted.
pub fn line_of(bytes: &[u8], text: &[u8]) -> usize {
    1 + bytes[..position(bytes, text)]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// `read` is `expected`, every coordinate and displacement bit for bit.
pub fn assert_same(read: &HexMesh, expected: &HexMesh, what: &str) {
    let bits = |v: &[DVec3]| {
        v.iter()
            .flat_map(|p| p.to_array().map(f64::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(read.cells, expected.cells, "{what}");
    assert_eq!(bits(&read.points), bits(&expected.points), "{what}");
    assert_eq!(
        read.displacement.as_deref().map(bits),
        expected.displacement.as_deref().map(bits),
        "{what}"
    );
}
