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

/// The encoding of inline binary arrays, from the `<VTKFile>` tag.
#[derive(Default)]
struct Encoding {
    compressed: bool,
    header64: bool,
    big_endian: bool,
}

/// The first value of an XML file's cell arrays that vtkio cannot cast (a negative node number or
/// offset, a cell type outside 0–255), as `line N: the cell array ...`; for arrays written as
/// `ascii` or as uncompressed inline `binary`. `None` when none is found.
///
/// Called after vtkio refused the file with "InvalidDataFormat", so that a valid file is not
/// decoded twice.
pub(crate) fn cell_array_fault(xml: &[u8]) -> Option<String> {
    let end = crate::raw_appended::find(xml, b"<AppendedData", 0).unwrap_or(xml.len());
    let mut reader = quick_xml::Reader::from_reader(&xml[..end]);
    let line = |at: u64| {
        1 + xml[..(at as usize).min(end)]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    };
    let mut encoding = Encoding::default();
    let mut in_cells = false;
    // The open cell array.
    let mut array: Option<CellArray> = None;
    loop {
        let at = reader.buffer_position();
        match reader.read_event().ok()? {
            Event::Eof => return None,
            Event::Start(tag) if tag.name().as_ref() == b"VTKFile" => {
                encoding = Encoding {
                    compressed: value(&tag, "compressor")
                        .is_some_and(|c| !c.trim_ascii().is_empty()),
                    header64: value(&tag, "header_type").as_deref() == Some(b"UInt64"),
                    big_endian: value(&tag, "byte_order").as_deref() == Some(b"BigEndian"),
                };
            }
            Event::Start(tag) if tag.name().as_ref() == b"Cells" => in_cells = true,
            Event::Start(tag) if in_cells && tag.name().as_ref() == b"DataArray" => {
                array = Some(CellArray {
                    name: value(&tag, "Name").unwrap_or_default(),
                    kind: value(&tag, "type").unwrap_or_default(),
                    format: value(&tag, "format").unwrap_or_default(),
                    line: line(at),
                });
            }
            Event::Text(text) => {
                if let Some(array) = array.take()
                    && let Some(fault) = first_fault(&array, &text, &encoding)
                {
                    return Some(format!(
                        "line {}: the cell array {} holds {fault}",
                        array.line,
                        crate::excerpt(&array.name, 40)
                    ));
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
    line: usize,
}

/// The first value of one cell array that vtkio cannot cast, in words.
fn first_fault(array: &CellArray, text: &[u8], encoding: &Encoding) -> Option<String> {
    let name = array.name.as_slice();
    let types = name == b"types";
    let bad = |v: i128| {
        if types {
            !(0..=255).contains(&v)
        } else {
            v < 0
        }
    };
    let why = if types {
        "a cell type is from 0 to 255"
    } else if name == b"offsets" {
        "an offset is not negative"
    } else {
        "a node number is not negative"
    };
    let found = match array.format.as_slice() {
        b"ascii" => std::str::from_utf8(text)
            .ok()?
            .split_ascii_whitespace()
            .map(|t| t.parse::<i128>().ok())
            .enumerate()
            .find_map(|(i, v)| v.filter(|&v| bad(v)).map(|v| (i, v))),
        b"binary" if !encoding.compressed => {
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
            let compact: Vec<u8> = text
                .iter()
                .copied()
                .filter(|b| !b.is_ascii_whitespace())
                .collect();
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(compact)
                .ok()?;
            let header = if encoding.header64 { 8 } else { 4 };
            bytes
                .get(header..)?
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
        }
        _ => None,
    };
    let (index, v) = found?;
    Some(format!("{v} at index {index}: {why}"))
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
    let end = crate::raw_appended::find(xml, b"<AppendedData", 0).unwrap_or(xml.len());
    let mut reader = quick_xml::Reader::from_reader(&xml[..end]);
    let line = |at: u64| {
        1 + xml[..(at as usize).min(end)]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    };
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
