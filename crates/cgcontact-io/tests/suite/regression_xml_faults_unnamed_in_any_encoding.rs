//! Regression: vtkio's errors for cell arrays it cannot cast, when they are compressed or
//! appended ("Validation error: InvalidDataFormat"), for a cell type it does not know
//! ("InvalidCellType(255)"), for an array appended to a file without `<AppendedData>` (again
//! "InvalidDataFormat"), and for an attribute it needs ("missing field `@type`") named neither
//! the array nor the line. Each is now named, in every encoding VTK writes: ascii, inline binary
//! and appended (base64 or raw), uncompressed, zlib and LZ4.

use std::io::Write as _;

use base64::Engine as _;
use cgcontact_io::{DisplacementArray, parse_hex_mesh};

fn error(file: &[u8]) -> String {
    parse_hex_mesh(file, &DisplacementArray::Default)
        .unwrap_err()
        .to_string()
}

/// Two unit cells side by side along x.
const POINTS: [[f64; 3]; 12] = [
    [0., 0., 0.],
    [1., 0., 0.],
    [2., 0., 0.],
    [0., 1., 0.],
    [1., 1., 0.],
    [2., 1., 0.],
    [0., 0., 1.],
    [1., 0., 1.],
    [2., 0., 1.],
    [0., 1., 1.],
    [1., 1., 1.],
    [2., 1., 1.],
];
const CONNECTIVITY: [i64; 16] = [0, 1, 4, 3, 6, 7, 10, 9, 1, 2, 5, 4, 7, 8, 11, 10];

#[derive(Clone, Copy, Debug)]
enum Encoding {
    Ascii,
    /// Inline binary, uncompressed: the header and the data in one base64 stream, as VTK writes
    /// them (compressed, each is a stream of its own).
    Binary,
    Zlib,
    Lz4,
    /// Appended base64, uncompressed.
    Appended,
    AppendedZlib,
    /// Appended raw bytes, LZ4.
    AppendedRawLz4,
}

fn b64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// An array's binary form: `[bytes]` then the bytes, or the compressed header
/// `[blocks, block size, last block size, compressed sizes]` (UInt64 words) and the blocks, in
/// blocks of 40 bytes so that the arrays take several.
fn binary(raw: &[u8], encoding: Encoding) -> (Vec<u8>, Vec<u8>) {
    let block = 40;
    let compress = |chunk: &[u8]| -> Vec<u8> {
        match encoding {
            Encoding::Zlib | Encoding::AppendedZlib => {
                let mut z =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                z.write_all(chunk).unwrap();
                z.finish().unwrap()
            }
            _ => lz4_flex::block::compress(chunk),
        }
    };
    match encoding {
        Encoding::Binary | Encoding::Appended => {
            ((raw.len() as u64).to_le_bytes().to_vec(), raw.to_vec())
        }
        _ => {
            let chunks: Vec<Vec<u8>> = raw.chunks(block).map(compress).collect();
            let mut header = vec![
                chunks.len() as u64,
                block as u64,
                (raw.len() % block) as u64,
            ];
            header.extend(chunks.iter().map(|c| c.len() as u64));
            let header = header.iter().flat_map(|w| w.to_le_bytes()).collect();
            (header, chunks.concat())
        }
    }
}

/// The two-cell mesh as a `.vtu` in `encoding`, with `connectivity` and `types` as given, and
/// the lines of the connectivity and types arrays.
fn vtu(encoding: Encoding, connectivity: &[i64], types: &[u8]) -> (Vec<u8>, usize, usize) {
    let points: Vec<f64> = POINTS.iter().flatten().copied().collect();
    let offsets = [8i64, 16];
    let raw = |values: &mut dyn Iterator<Item = Vec<u8>>| values.flatten().collect::<Vec<u8>>();
    let arrays: [(&str, &str, &str, Vec<u8>, String); 4] = [
        (
            "Points",
            "Float64",
            " NumberOfComponents=\"3\"",
            raw(&mut points.iter().map(|v| v.to_le_bytes().to_vec())),
            points
                .iter()
                .map(f64::to_string)
                .collect::<Vec<_>>()
                .join(" "),
        ),
        (
            "connectivity",
            "Int64",
            "",
            raw(&mut connectivity.iter().map(|v| v.to_le_bytes().to_vec())),
            connectivity
                .iter()
                .map(i64::to_string)
                .collect::<Vec<_>>()
                .join(" "),
        ),
        (
            "offsets",
            "Int64",
            "",
            raw(&mut offsets.iter().map(|v| v.to_le_bytes().to_vec())),
            "8 16".to_owned(),
        ),
        (
            "types",
            "UInt8",
            "",
            types.to_vec(),
            types
                .iter()
                .map(u8::to_string)
                .collect::<Vec<_>>()
                .join(" "),
        ),
    ];
    let compressor = match encoding {
        Encoding::Zlib | Encoding::AppendedZlib => " compressor=\"vtkZLibDataCompressor\"",
        Encoding::Lz4 | Encoding::AppendedRawLz4 => " compressor=\"vtkLZ4DataCompressor\"",
        _ => "",
    };
    let mut elements = Vec::new();
    let mut appended: Vec<u8> = Vec::new();
    for (name, kind, components, bytes, text) in &arrays {
        let head = format!("<DataArray type=\"{kind}\" Name=\"{name}\"{components}");
        let (header, data) = binary(bytes, encoding);
        elements.push(match encoding {
            Encoding::Ascii => format!("{head} format=\"ascii\">{text}</DataArray>"),
            Encoding::Binary => format!(
                "{head} format=\"binary\">{}</DataArray>",
                b64(&[header, data].concat())
            ),
            Encoding::Zlib | Encoding::Lz4 => format!(
                "{head} format=\"binary\">{}{}</DataArray>",
                b64(&header),
                b64(&data)
            ),
            Encoding::Appended | Encoding::AppendedZlib | Encoding::AppendedRawLz4 => {
                let element = format!("{head} format=\"appended\" offset=\"{}\"/>", appended.len());
                match encoding {
                    Encoding::AppendedRawLz4 => {
                        appended.extend(header);
                        appended.extend(data);
                    }
                    Encoding::Appended => appended.extend(b64(&[header, data].concat()).bytes()),
                    _ => {
                        appended.extend(b64(&header).bytes());
                        appended.extend(b64(&data).bytes());
                    }
                }
                element
            }
        });
    }
    let mut file = format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\"{compressor}>\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"12\" NumberOfCells=\"2\">\n\
         <Points>\n{}\n</Points>\n<Cells>\n{}\n{}\n{}\n</Cells>\n</Piece>\n</UnstructuredGrid>\n",
        elements[0], elements[1], elements[2], elements[3]
    )
    .into_bytes();
    if !appended.is_empty() {
        let raw = matches!(encoding, Encoding::AppendedRawLz4);
        let kind = if raw { "raw" } else { "base64" };
        file.extend(format!("<AppendedData encoding=\"{kind}\">\n_").bytes());
        file.extend(appended);
        file.extend(b"\n</AppendedData>\n");
    }
    file.extend(b"</VTKFile>\n");
    (file, 8, 10)
}

const ALL: [Encoding; 7] = [
    Encoding::Ascii,
    Encoding::Binary,
    Encoding::Zlib,
    Encoding::Lz4,
    Encoding::Appended,
    Encoding::AppendedZlib,
    Encoding::AppendedRawLz4,
];

#[test]
fn the_files_of_this_test_read_as_two_cells_in_every_encoding() {
    for encoding in ALL {
        let (file, _, _) = vtu(encoding, &CONNECTIVITY, &[12, 12]);
        let mesh = parse_hex_mesh(&file, &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{encoding:?}: {e}"));
        assert_eq!(mesh.cells.len(), 2, "{encoding:?}");
        assert_eq!(mesh.cells[1][1], 2, "{encoding:?}");
    }
}

#[test]
fn negative_node_numbers_and_unknown_cell_types_are_named_in_every_encoding() {
    let mut negative = CONNECTIVITY;
    negative[13] = -3;
    for encoding in ALL {
        let (file, connectivity_line, types_line) = vtu(encoding, &negative, &[12, 12]);
        let message = error(&file);
        let expected = format!(
            "line {connectivity_line}: the cell array `connectivity` holds -3 at index 13: a node \
             number is not negative"
        );
        assert!(message.contains(&expected), "{encoding:?}: {message}");

        let (file, _, _) = vtu(encoding, &CONNECTIVITY, &[12, 255]);
        let message = error(&file);
        let expected = format!(
            "line {types_line}: the cell array `types` holds 255 at index 1: not a VTK cell type"
        );
        assert!(message.contains(&expected), "{encoding:?}: {message}");
    }
}

#[test]
fn missing_attributes_and_missing_appended_data_are_named_with_their_line() {
    let (file, _, _) = vtu(Encoding::Ascii, &CONNECTIVITY, &[12, 12]);
    let file = String::from_utf8(file).unwrap();
    let cases = [
        (
            file.replacen(
                "<DataArray type=\"Int64\" Name=\"offsets\"",
                "<DataArray Name=\"offsets\"",
                1,
            ),
            "line 9: <DataArray> `offsets` has no `type` attribute",
        ),
        (
            file.replacen("Name=\"types\" format=\"ascii\"", "Name=\"types\"", 1),
            "line 10: <DataArray> `types` has no `format` attribute",
        ),
        (
            file.replacen(
                "Name=\"types\" format=\"ascii\"",
                "Name=\"types\" format=\"asci\"",
                1,
            ),
            "line 10: <DataArray> `types`: format=`asci` is none of ascii, binary and appended",
        ),
        (
            file.replacen(" version=\"1.0\"", "", 1),
            "line 1: <VTKFile> has no `version` attribute",
        ),
        (
            file.replacen(" byte_order=\"LittleEndian\"", "", 1),
            "line 1: <VTKFile> has no `byte_order` attribute",
        ),
        (
            file.replacen(
                "Name=\"types\" format=\"ascii\">12 12<",
                "Name=\"types\" format=\"appended\" offset=\"0\"><",
                1,
            ),
            "line 10: the appended data array `types`: the file has no <AppendedData> to hold it",
        ),
    ];
    for (file, expected) in cases {
        let message = error(file.as_bytes());
        assert!(message.contains(expected), "{expected}\n{message}");
    }
}

/// VTK writes string arrays (`vtkStringArray`) as `<Array>` elements beside the data arrays; they
/// were refused as corrupt tags ("<Array> inside <PointData> is not a DataArray"). They are read
/// past: the mesh is the same as without them.
#[test]
fn string_arrays_beside_the_data_are_read_past() {
    let (file, _, _) = vtu(Encoding::Ascii, &CONNECTIVITY, &[12, 12]);
    let plain = parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
    let file = String::from_utf8(file).unwrap();
    let with_strings = file
        .replacen(
            "<Points>",
            "<PointData>\n<Array type=\"String\" Name=\"names\" NumberOfTuples=\"12\" \
             format=\"ascii\">\n110 0 97 0\n</Array>\n</PointData>\n<CellData><Array \
             type=\"String\" Name=\"tags\" format=\"ascii\">116 0</Array></CellData>\n<Points>",
            1,
        )
        .replacen(
            "<UnstructuredGrid>",
            "<UnstructuredGrid>\n<FieldData><Array type=\"String\" Name=\"note\" \
             NumberOfTuples=\"1\" format=\"ascii\">104 105 0</Array></FieldData>",
            1,
        );
    let read = parse_hex_mesh(with_strings.as_bytes(), &DisplacementArray::Default)
        .unwrap_or_else(|e| panic!("{e}\n{with_strings}"));
    assert_eq!(read, plain);
}
