//! Regression: a zlib block that decompresses to more bytes than its header gives was read in
//! part (vtkio fills a buffer of the header's size and ignores the rest), and a raw appended
//! block whose header claims one byte more than the array holds ran into the next array's block:
//! both files read without a word. docs/formats.md calls a block of the wrong size an error, as
//! the LZMA path always checked.

use std::io::Write as _;
use std::path::Path;

use base64::Engine as _;
use cgcontact_io::{DisplacementArray, parse_hex_mesh};

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/vtk-written")
            .join(name),
    )
    .unwrap()
}

fn find(bytes: &[u8], needle: &[u8]) -> usize {
    bytes
        .windows(needle.len())
        .position(|w| w == needle)
        .unwrap()
}

fn error(bytes: &[u8]) -> String {
    parse_hex_mesh(bytes, &DisplacementArray::Default)
        .map(|_| "read as a mesh".to_owned())
        .unwrap_or_else(|e| e.to_string())
}

#[test]
fn a_zlib_block_larger_or_smaller_than_its_header_is_an_error() {
    let intact = fixture("xml-binary-zlib.vtu");
    // The displacement: 205 nodes × 3 doubles, one block, UInt32 header words.
    let size = 205 * 3 * 8;
    let tag = find(&intact, b"Name=\"displacement\"");
    let start = tag + find(&intact[tag..], b">") + 1;
    let start = start
        + intact[start..]
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap();
    let end = start + find(&intact[start..], b"<");
    let end = start + intact[start..end].trim_ascii_end().len();
    for (held, expected) in [(size + 8, "more than"), (size - 8, "fewer than")] {
        let mut zlib = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        zlib.write_all(&vec![0u8; held]).unwrap();
        let block = zlib.finish().unwrap();
        let header: Vec<u8> = [1, size as u32, size as u32, block.len() as u32]
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect();
        let engine = &base64::engine::general_purpose::STANDARD;
        let text = [engine.encode(header), engine.encode(block)].concat();
        let corrupt = [&intact[..start], text.as_bytes(), &intact[end..]].concat();
        let message = error(&corrupt);
        assert!(
            message.contains(&format!("decompresses to {expected} the {size} bytes"))
                && message.contains("`displacement`"),
            "{held}: {message}"
        );
    }
}

#[test]
fn a_raw_block_running_into_the_next_one_is_an_error() {
    let intact = fixture("xml-appended-raw.vtu");
    parse_hex_mesh(&intact, &DisplacementArray::Default).unwrap();
    // The first block, the displacement's at offset 0: its UInt32 size 4920 made 4921.
    let data = find(&intact, b"<AppendedData");
    let data = data + find(&intact[data..], b"_") + 1;
    assert_eq!(intact[data..data + 4], 4920u32.to_le_bytes());
    let mut corrupt = intact.clone();
    corrupt[data..data + 4].copy_from_slice(&4921u32.to_le_bytes());
    let message = error(&corrupt);
    assert!(
        message.contains("`displacement`") && message.contains("1 more than there are"),
        "{message}"
    );
}
