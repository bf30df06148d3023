//! What vtkio refuses in an XML file without naming it: a `<Piece>` count or a
//! `NumberOfComponents` it cannot read as a `u32` ("InvalidInt(PosOverflow)"), a cell array
//! holding a value it cannot cast (a negative node number or offset, a cell type above 255:
//! "InvalidDataFormat"), and a `<Points>` array of the wrong length (an array named `""`).

use base64::Engine as _;
use quick_xml::events::{BytesStart, Event};

/// The value of attribute `name` of `tag`, as written.
fn value(tag: &BytesStart, name: &str) -> Option<Vec<u8>> {
    tag.try_get_attribute(name)
        .ok()
        .flatten()
        .map(|a| a.value.into_owned())
}

/// A count attribute vtkio reads as a `u32` (`NumberOfPoints`, `NumberOfCells` of a `<Piece>`,
/// `NumberOfComponents` of a `<DataArray>`) that is not one, named with the element.
pub(crate) fn check_counts(tag: &BytesStart) -> Result<(), String> {
    let names: &[&str] = match tag.name().as_ref() {
        b"Piece" => &["NumberOfPoints", "NumberOfCells"],
        b"DataArray" => &["NumberOfComponents"],
        _ => return Ok(()),
    };
    for name in names {
        let Some(count) = value(tag, name) else {
            continue;
        };
        if std::str::from_utf8(&count)
            .ok()
            .and_then(|c| c.parse::<u32>().ok())
            .is_none()
        {
            let array = value(tag, "Name")
                .map_or_else(String::new, |n| format!(" {}", crate::excerpt(&n, 40)));
            return Err(format!(
                "<{}>{array}: {name}={} is not a count VTK reads (a whole number from 0 to {})",
                String::from_utf8_lossy(tag.name().as_ref()),
                crate::excerpt(&count, 40),
                u32::MAX
            ));
        }
    }
    Ok(())
}

/// An attribute vtkio needs and the tag lacks ("missing field `@type`", naming neither the
/// element nor its line), or a `format` it cannot read, named with the element.
pub(crate) fn check_required(tag: &BytesStart) -> Result<(), String> {
    let (names, what): (&[&str], &str) = match tag.name().as_ref() {
        b"VTKFile" => (
            &["type", "version", "byte_order"],
            "VTK writes type=\"UnstructuredGrid\", a version and a byte_order",
        ),
        b"DataArray" => (
            &["type", "format"],
            "VTK writes the number type and the format of every data array",
        ),
        _ => return Ok(()),
    };
    let element = || {
        let array =
            value(tag, "Name").map_or_else(String::new, |n| format!(" {}", crate::excerpt(&n, 40)));
        format!("<{}>{array}", String::from_utf8_lossy(tag.name().as_ref()))
    };
    for name in names {
        if value(tag, name).is_none() {
            return Err(format!("{} has no `{name}` attribute ({what})", element()));
        }
    }
    if let Some(format) = value(tag, "format").filter(|_| tag.name().as_ref() == b"DataArray")
        && !matches!(
            format.as_slice(),
            b"ascii" | b"ASCII" | b"binary" | b"appended"
        )
    {
        return Err(format!(
            "{}: format={} is none of ascii, binary and appended",
            element(),
            crate::excerpt(&format, 40)
        ));
    }
    Ok(())
}

/// The encoding of binary arrays, from the `<VTKFile>` tag.
#[derive(Default)]
struct Encoding {
    compressor: Compressor,
    header64: bool,
    big_endian: bool,
}

#[derive(Default, Clone, Copy, PartialEq)]
enum Compressor {
    #[default]
    None,
    Zlib,
    Lz4,
    /// One this module does not decode (LZMA arrays were decompressed before vtkio saw them).
    Other,
}

/// What [`cell_array_fault`] looks for.
#[derive(Clone, Copy)]
pub(crate) enum Sought {
    /// A value vtkio cannot cast ("InvalidDataFormat"): a negative node number or offset, a cell
    /// type outside 0–255.
    Uncastable,
    /// The first cell type `t`, which vtkio knows as no VTK cell type ("InvalidCellType(t)").
    CellType(u8),
}

/// The first value of an XML file's cell arrays that vtkio refused (`sought`), as `line N: the
/// cell array ...`, whatever the array's format: `ascii`, inline `binary` or `appended` (base64;
/// raw appended data was re-encoded before vtkio saw it), uncompressed or compressed with zlib or
/// LZ4. `None` when none is found.
///
/// Called after vtkio refused the file, so that a valid file is not decoded twice.
pub(crate) fn cell_array_fault(xml: &[u8], sought: Sought) -> Option<String> {
    let appended_at = crate::raw_appended::find(xml, b"<AppendedData", 0);
    let end = appended_at.unwrap_or(xml.len());
    // The appended data's base64 text: after the `_` that opens it.
    let appended = appended_at.and_then(|tag| crate::raw_appended::appended_text(xml, tag));
    let mut reader = quick_xml::Reader::from_reader(&xml[..end]);
    let line = |at: u64| crate::raw_appended::line_of(&xml[..end], at as usize);
    let mut encoding = Encoding::default();
    let mut in_cells = false;
    // The open cell array.
    let mut array: Option<CellArray> = None;
    let said = |array: &CellArray, fault: String| {
        format!(
            "line {}: the cell array {} holds {fault}",
            line(array.at),
            crate::excerpt(&array.name, 40)
        )
    };
    loop {
        let at = reader.buffer_position();
        match reader.read_event().ok()? {
            Event::Eof => return None,
            Event::Start(tag) if tag.name().as_ref() == b"VTKFile" => {
                encoding = Encoding {
                    compressor: match value(&tag, "compressor").as_deref().map(<[u8]>::trim_ascii) {
                        None | Some(b"") => Compressor::None,
                        Some(b"vtkZLibDataCompressor") => Compressor::Zlib,
                        Some(b"vtkLZ4DataCompressor") => Compressor::Lz4,
                        Some(_) => Compressor::Other,
                    },
                    header64: value(&tag, "header_type").as_deref() == Some(b"UInt64"),
                    big_endian: value(&tag, "byte_order").as_deref() == Some(b"BigEndian"),
                };
            }
            Event::Start(tag) if tag.name().as_ref() == b"Cells" => in_cells = true,
            Event::Start(tag) | Event::Empty(tag)
                if in_cells && tag.name().as_ref() == b"DataArray" =>
            {
                let cell_array = CellArray {
                    name: value(&tag, "Name").unwrap_or_default(),
                    kind: value(&tag, "type").unwrap_or_default(),
                    format: value(&tag, "format").unwrap_or_default(),
                    at,
                };
                if cell_array.format == b"appended" {
                    let offset = value(&tag, "offset")
                        .and_then(|o| std::str::from_utf8(&o).ok()?.trim().parse::<usize>().ok());
                    if let Some(text) = appended.zip(offset).and_then(|(a, o)| a.get(o..))
                        && let Some(fault) = first_fault(&cell_array, text, &encoding, sought)
                    {
                        return Some(said(&cell_array, fault));
                    }
                } else {
                    array = Some(cell_array);
                }
            }
            Event::Text(text) => {
                if let Some(array) = array.take()
                    && let Some(fault) = first_fault(&array, &text, &encoding, sought)
                {
                    return Some(said(&array, fault));
                }
            }
            Event::End(tag) => {
                if tag.name().as_ref() == b"Cells" {
                    in_cells = false;
                }
                array = None;
            }
            _ => {}
        }
    }
}

/// A `<DataArray>` inside `<Cells>`, as its tag says.
struct CellArray {
    name: Vec<u8>,
    kind: Vec<u8>,
    format: Vec<u8>,
    /// Where its tag starts (its line is counted only for a message).
    at: u64,
}

/// The first value of one cell array that vtkio refused, in words. `text` is the array's text
/// (`ascii` or inline `binary`), or the appended data from the array's offset on.
fn first_fault(
    array: &CellArray,
    text: &[u8],
    encoding: &Encoding,
    sought: Sought,
) -> Option<String> {
    let name = array.name.as_slice();
    let types = name == b"types";
    let (bad, why): (&dyn Fn(i128) -> bool, _) = match sought {
        Sought::CellType(t) if types => (&move |v| v == i128::from(t), "not a VTK cell type"),
        Sought::CellType(_) => return None,
        Sought::Uncastable if types => {
            (&|v| !(0..=255).contains(&v), "a cell type is from 0 to 255")
        }
        Sought::Uncastable if name == b"offsets" => (&|v| v < 0, "an offset is not negative"),
        Sought::Uncastable => (&|v| v < 0, "a node number is not negative"),
    };
    let found = if array.format == b"ascii" || array.format == b"ASCII" {
        std::str::from_utf8(text)
            .ok()?
            .split_ascii_whitespace()
            .map(|t| t.parse::<i128>().ok())
            .enumerate()
            .find_map(|(i, v)| v.filter(|&v| bad(v)).map(|v| (i, v)))
    } else {
        let (width, signed) = match array.kind.as_slice() {
            b"Int8" => (1, true),
            b"UInt8" => (1, false),
            b"Int16" => (2, true),
            b"UInt16" => (2, false),
            b"Int32" => (4, true),
            b"UInt32" => (4, false),
            b"Int64" => (8, true),
            b"UInt64" => (8, false),
            _ => return None,
        };
        decode(text, encoding)?
            .chunks_exact(width)
            .map(|c| {
                let mut word = [0u8; 8];
                if encoding.big_endian {
                    word[8 - width..].copy_from_slice(c);
                    word.reverse();
                } else {
                    word[..width].copy_from_slice(c);
                }
                let unsigned = u64::from_le_bytes(word);
                let shift = 64 - 8 * width as u32;
                if signed {
                    i128::from(((unsigned << shift) as i64) >> shift)
                } else {
                    i128::from(unsigned)
                }
            })
            .enumerate()
            .find(|&(_, v)| bad(v))
    };
    let (index, v) = found?;
    Some(format!("{v} at index {index}: {why}"))
}

/// The bytes of a binary array held in base64 `text` (from its start; what follows its end is
/// not read): its header (`[bytes]`, or `[blocks, block size, last block size, compressed
/// sizes...]` when compressed), then its data, decompressed. `None` when the text cannot be
/// decoded so far. The block sizes were bounded before vtkio ran (`block_headers::check`), and
/// each block is decompressed to at most its size.
fn decode(text: &[u8], encoding: &Encoding) -> Option<Vec<u8>> {
    let engine = &base64::engine::general_purpose::STANDARD;
    let compact: Vec<u8> = text
        .iter()
        .copied()
        .take_while(|&b| b != b'<')
        .filter(|b| !b.is_ascii_whitespace())
        .collect();
    let chars = |bytes: usize| bytes.div_ceil(3).saturating_mul(4);
    let header_bytes = if encoding.header64 { 8 } else { 4 };
    let word = |bytes: &[u8], k: usize| {
        let w = bytes.get(k * header_bytes..(k + 1) * header_bytes)?;
        usize::try_from(crate::raw_appended::header_word(w, !encoding.big_endian)).ok()
    };
    match encoding.compressor {
        Compressor::None => {
            // The header and the data in one base64 stream, as VTK writes them.
            let size = word(&engine.decode(compact.get(..chars(header_bytes))?).ok()?, 0)?;
            let length = chars(header_bytes.checked_add(size)?).min(compact.len());
            let mut bytes = engine.decode(&compact[..length]).ok()?;
            bytes.drain(..header_bytes.min(bytes.len()));
            Some(bytes)
        }
        Compressor::Zlib | Compressor::Lz4 => {
            let three = engine
                .decode(compact.get(..chars(3 * header_bytes))?)
                .ok()?;
            let (blocks, block_size, last) = (word(&three, 0)?, word(&three, 1)?, word(&three, 2)?);
            let header_length = header_bytes.checked_mul(blocks.checked_add(3)?)?;
            let header = engine.decode(compact.get(..chars(header_length))?).ok()?;
            let sizes: Vec<usize> = (3..3 + blocks)
                .map(|k| word(&header, k))
                .collect::<Option<_>>()?;
            let total = sizes.iter().try_fold(0usize, |t, &s| t.checked_add(s))?;
            let rest = &compact[chars(header_length)..];
            let data = engine
                .decode(rest.get(..chars(total).min(rest.len()))?)
                .ok()?;
            let mut bytes = Vec::new();
            let mut at = 0usize;
            for (k, &size) in sizes.iter().enumerate() {
                let block = data.get(at..at.checked_add(size)?)?;
                at += size;
                let expected = if k + 1 == blocks && last != 0 {
                    last
                } else {
                    block_size
                };
                if encoding.compressor == Compressor::Zlib {
                    use std::io::Read as _;
                    flate2::read::ZlibDecoder::new(block)
                        .take(expected as u64)
                        .read_to_end(&mut bytes)
                        .ok()?;
                } else {
                    bytes.extend(lz4_flex::block::decompress(block, expected).ok()?);
                }
            }
            Some(bytes)
        }
        Compressor::Other => None,
    }
}

/// vtkio's "DataArraySizeMismatch" for a `<Points>` array named `name` (`""` when it has no
/// `Name`) in words: the array's line, and the `<Piece>` whose `NumberOfPoints` (times the
/// array's `NumberOfComponents`) asks for `expected` values. `None` when no `<Points>` array
/// fits (the mismatch is another array's).
pub(crate) fn points_size_fault(
    xml: &[u8],
    name: &str,
    expected: usize,
    actual: usize,
) -> Option<String> {
    let head = crate::raw_appended::head(xml);
    let mut reader = quick_xml::Reader::from_reader(head);
    let line = |at: u64| crate::raw_appended::line_of(head, at as usize);
    let count = |text: &[u8]| {
        std::str::from_utf8(text)
            .ok()
            .and_then(|c| c.parse::<usize>().ok())
    };
    // The open piece's line and NumberOfPoints, and whether a <Points> element is open.
    let mut piece = (0, Vec::new());
    let mut in_points = false;
    loop {
        let at = reader.buffer_position();
        match reader.read_event() {
            Ok(Event::Start(tag)) if tag.name().as_ref() == b"Piece" => {
                piece = (line(at), value(&tag, "NumberOfPoints").unwrap_or_default());
            }
            Ok(Event::Start(tag)) if tag.name().as_ref() == b"Points" => in_points = true,
            Ok(Event::End(tag)) if tag.name().as_ref() == b"Points" => in_points = false,
            Ok(Event::Start(tag) | Event::Empty(tag))
                if in_points && tag.name().as_ref() == b"DataArray" =>
            {
                let components = value(&tag, "NumberOfComponents");
                let asks = count(&piece.1)
                    .zip(components.as_deref().map_or(Some(1), count))
                    .and_then(|(n, c)| n.checked_mul(c));
                let named = value(&tag, "Name").unwrap_or_default() == name.as_bytes();
                if named && asks == Some(expected) {
                    let components = components.map_or_else(
                        || " (1 component)".to_owned(),
                        |c| format!(" × NumberOfComponents={}", crate::excerpt(&c, 20)),
                    );
                    return Some(format!(
                        "line {}: the <Points> data array holds {actual} values, but \
                         NumberOfPoints={} of its <Piece> (line {}){components} asks for \
                         {expected}",
                        line(at),
                        crate::excerpt(&piece.1, 40),
                        piece.0
                    ));
                }
            }
            Ok(Event::Eof) | Err(_) => return None,
            _ => {}
        }
    }
}
