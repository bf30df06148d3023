//! Hostile variants of the LZMA-compressed files VTK wrote (fixtures/vtk-written): a block cut
//! short, a block header claiming a huge size, an .xz stream corrupted inside, a wrong check, data
//! that is not .xz at all, a stream that holds fewer bytes than its header claims, a block with a
//! chain of filters, a file cut anywhere, a misspelt compressor. Each must be an error naming the
//! array (and, read from a file, the file), never a panic, an abort or a mesh.

use std::path::{Path, PathBuf};

use base64::Engine as _;
use cgcontact_io::{DisplacementArray, parse_hex_mesh, read_mesh};

fn fixture(name: &str) -> Vec<u8> {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written");
    std::fs::read(folder.join(name)).unwrap()
}

fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .unwrap_or_else(|| panic!("{} not found", String::from_utf8_lossy(needle)))
}

/// `xml-appended-raw-lzma-uint64.vtu` and where its first array (at offset 0) lies: its 64-bit
/// block header `[blocks, block size, last size, compressed sizes...]` and its first .xz stream.
struct RawFile {
    bytes: Vec<u8>,
    /// Where the header's words are.
    header: usize,
    /// The first block's .xz stream.
    stream: std::ops::Range<usize>,
}

impl RawFile {
    fn new() -> Self {
        let bytes = fixture("xml-appended-raw-lzma-uint64.vtu");
        let header = find(&bytes, b"<AppendedData");
        let header = header + find(&bytes[header..], b"_") + 1;
        let word = |k: usize| {
            let at = header + 8 * k;
            u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize
        };
        assert_eq!(word(0), 1, "the first array is one block");
        let start = header + 8 * 4;
        let stream = start..start + word(3);
        assert_eq!(&bytes[stream.start..stream.start + 6], b"\xFD7zXZ\0");
        Self {
            bytes,
            header,
            stream,
        }
    }

    fn set_word(&mut self, k: usize, value: u64) {
        let at = self.header + 8 * k;
        self.bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
    }

    /// Where the block's check (CRC32) is: just before the index, whose size the stream footer
    /// gives.
    fn check(&self) -> std::ops::Range<usize> {
        let end = self.stream.end;
        let backward = u32::from_le_bytes(self.bytes[end - 8..end - 4].try_into().unwrap());
        let index = end - 12 - 4 * (backward as usize + 1);
        assert_eq!(self.bytes[index], 0, "the index indicator");
        index - 4..index
    }
}

/// Every hostile variant, with a piece of the message it must give.
fn variants() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let mut out = Vec::new();

    // Header words: the block's compressed size 10 short (the stream is cut), a huge block size,
    // a last block claiming 8 bytes more than the stream holds.
    let mut f = RawFile::new();
    let held = f.stream.len() as u64;
    f.set_word(3, held - 10);
    out.push(("stream cut short", f.bytes, "ends early"));
    let mut f = RawFile::new();
    f.set_word(1, 1 << 50);
    f.set_word(2, 1 << 49);
    out.push(("huge block size", f.bytes, "more than LZMA can expand"));
    let mut f = RawFile::new();
    f.set_word(1, 1 << 20);
    f.set_word(2, 0);
    out.push(("whole block of 1 MiB", f.bytes, "LZMA2 chunks hold"));
    let mut f = RawFile::new();
    let last = u64::from_le_bytes(f.bytes[f.header + 16..f.header + 24].try_into().unwrap());
    f.set_word(2, last + 8);
    out.push(("last block 8 bytes long", f.bytes, "its header says"));
    let mut f = RawFile::new();
    f.set_word(0, u64::MAX);
    out.push(("2^64 - 1 blocks", f.bytes, "blocks, more than"));

    // The .xz stream: a byte inside the LZMA2 data flipped, the check wrong, the magic bytes
    // gone, every byte replaced, a second filter in the block flags.
    let mut f = RawFile::new();
    let middle = f.stream.start + f.stream.len() / 2;
    f.bytes[middle] ^= 0x5A;
    out.push(("corrupt LZMA2 data", f.bytes, "block 0 of 1"));
    let mut f = RawFile::new();
    let check = f.check();
    f.bytes[check.start] ^= 0x01;
    out.push(("wrong check", f.bytes, "CRC32"));
    let mut f = RawFile::new();
    let start = f.stream.start;
    f.bytes[start..start + 6].copy_from_slice(b"\x78\x9c\x00\x00\x00\x00");
    out.push(("zlib magic", f.bytes, "not an .xz stream"));
    let mut f = RawFile::new();
    let stream = f.stream.clone();
    f.bytes[stream].fill(0x55);
    out.push(("not xz at all", f.bytes, "not an .xz stream"));
    let mut f = RawFile::new();
    let flags = f.stream.start + 13;
    f.bytes[flags] |= 0x01;
    out.push(("two filters", f.bytes, "more than one filter"));

    // The file cut inside the appended data.
    let f = RawFile::new();
    out.push((
        "file cut in the stream",
        f.bytes[..f.stream.start + f.stream.len() / 2].to_vec(),
        "truncated",
    ));

    // Inline base64: the first array's data run cut by 8 characters (the file otherwise whole),
    // its header claiming 2^40 bytes, and its data not base64.
    let inline = fixture("xml-binary-lzma.vtu");
    let (text_start, text_end) = first_inline_text(&inline);
    let mut cut = inline.clone();
    cut.drain(text_end - 8..text_end);
    out.push(("inline data cut", cut, "truncated?"));
    let mut huge = inline.clone();
    let mut header = base64::engine::general_purpose::STANDARD
        .decode(&inline[text_start..text_start + 24])
        .unwrap();
    header[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    header[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let encoded = base64::engine::general_purpose::STANDARD.encode(&header);
    huge[text_start..text_start + 24].copy_from_slice(encoded.as_bytes());
    out.push(("inline huge header", huge, "more than LZMA can expand"));
    let mut not_base64 = inline.clone();
    not_base64[text_end - 30] = b'*';
    out.push(("inline not base64", not_base64, "not base64"));
    out
}

/// The trimmed base64 text of the first inline array.
fn first_inline_text(bytes: &[u8]) -> (usize, usize) {
    let tag = find(bytes, b"format=\"binary\"");
    let start = tag + find(&bytes[tag..], b">") + 1;
    let start = start
        + bytes[start..]
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap();
    let end = start + find(&bytes[start..], b"\n");
    (start, end)
}

#[test]
fn the_untouched_fixtures_read() {
    let raw = RawFile::new();
    parse_hex_mesh(&raw.bytes, &DisplacementArray::Default).unwrap();
    parse_hex_mesh(&fixture("xml-binary-lzma.vtu"), &DisplacementArray::Default).unwrap();
}

#[test]
fn every_hostile_variant_is_an_error_naming_the_array_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (what, bytes, expected) in variants() {
        for which in [DisplacementArray::Default, DisplacementArray::Ignore] {
            let error = parse_hex_mesh(&bytes, &which)
                .err()
                .unwrap_or_else(|| panic!("{what}: read as a mesh"))
                .to_string();
            assert!(
                error.contains(expected) && error.contains("LZMA-compressed"),
                "{what}: {error}"
            );
        }
        let path: PathBuf = dir.path().join(format!("{}.vtu", what.replace(' ', "-")));
        std::fs::write(&path, &bytes).unwrap();
        let error = read_mesh(&path, &DisplacementArray::Default)
            .err()
            .unwrap_or_else(|| panic!("{what}: read as a mesh"));
        assert_eq!(error.path(), path, "{what}");
        let message = error.to_string();
        assert!(
            message.starts_with(&path.display().to_string()) && !message.contains('\n'),
            "{what}: {message}"
        );
    }
}

/// Every cut of the raw appended fixture inside its data, and every byte of its first block
/// flipped: an error or a mesh, never a panic. A flip inside the .xz stream, which carries CRC32
/// checks of its framing and of the decompressed bytes, is an error or reads the very mesh of the
/// untouched file (lzma-rs ignores the first byte of each LZMA2 chunk's range coder, which liblzma
/// requires to be 0): never another mesh.
#[test]
fn every_cut_and_every_flipped_byte_of_a_block_is_caught() {
    let f = RawFile::new();
    let intact = parse_hex_mesh(&f.bytes, &DisplacementArray::Default).unwrap();
    for end in (f.header..f.bytes.len()).step_by(7) {
        let _ = parse_hex_mesh(&f.bytes[..end], &DisplacementArray::Default);
    }
    let mut errors = 0;
    for at in f.header..f.stream.end {
        let mut bytes = f.bytes.clone();
        bytes[at] ^= 0x10;
        let result = parse_hex_mesh(&bytes, &DisplacementArray::Default);
        if at >= f.stream.start {
            match result {
                Ok(mesh) => assert!(mesh == intact, "byte {at} flipped read as another mesh"),
                Err(_) => errors += 1,
            }
        }
    }
    assert!(errors + 8 > f.stream.len(), "{errors} errors");
}

/// A `compressor` VTK does not have (one letter off) is an error: vtkio would read the
/// compressed data as uncompressed.
#[test]
fn an_unknown_compressor_is_an_error() {
    for (file, name) in [
        ("xml-binary-lzma.vtu", "vtkLZMADataCompressor"),
        ("xml-appended-raw-lzma-uint64.vtu", "vtkLZMADataCompressor"),
        ("xml-appended-base64-lzma.vtu", "vtkLZMADataCompressor"),
        ("xml-binary-zlib.vtu", "vtkZLibDataCompressor"),
        ("xml-appended-base64-lz4.vtu", "vtkLZ4DataCompressor"),
    ] {
        let mut bytes = fixture(file);
        let at = find(&bytes, name.as_bytes());
        bytes[at + name.len() - 1] = b'X';
        let error = parse_hex_mesh(&bytes, &DisplacementArray::Default)
            .err()
            .unwrap_or_else(|| panic!("{file}: read as a mesh"))
            .to_string();
        assert!(error.contains("is none of VTK's"), "{file}: {error}");
    }
}
