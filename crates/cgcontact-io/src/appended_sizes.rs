//! Checking that each uncompressed appended array holds as many values as its `<Piece>` asks.
//!
//! vtkio reads an appended array's values from its offset, as many as the piece's counts ask
//! (`NumberOfCells` for `offsets` and `types`, `NumberOfPoints` × components for the points and
//! point data), and ignores what the array's header says it holds. So a `NumberOfCells` of 101
//! over cell arrays of 102 read 101 cells, and the points in the last one were outside the body,
//! without a word (VTK's own reader does the same). Inline arrays and compressed ones are
//! refused by vtkio when their size does not match; uncompressed appended ones are checked here:
//! each header's byte count must be the count asked times the value's width.
//!
//! Except that a cell array the reader never reads (any but `vtkGhostType`) may hold more values
//! than the piece has cells: VTK's reader reads the first ones, and vtkio reads as many as asked,
//! as inline and compressed arrays of any length are read. vtkHyperTreeGridToUnstructuredGrid
//! (VTK 9.7.2) writes such an array when the tree grid has masked cells: `OriginalIds` with a
//! value per leaf, masked ones included.

use base64::Engine as _;
use quick_xml::events::Event;

use crate::ErrorKind;
use crate::raw_appended::{appended_text, find, header_word};

/// Bytes of one value of a VTK number type.
fn width(kind: &[u8]) -> Option<u64> {
    Some(match kind {
        b"Int8" | b"UInt8" => 1,
        b"Int16" | b"UInt16" => 2,
        b"Int32" | b"UInt32" | b"Float32" => 4,
        b"Int64" | b"UInt64" | b"Float64" => 8,
        _ => return None,
    })
}

/// Refuse an uncompressed appended array (base64: raw data was re-encoded before) whose header
/// gives another byte count than its piece asks for, naming the array, its line and the count.
pub(crate) fn check(xml: &[u8]) -> Result<(), ErrorKind> {
    let Some(appended_at) = find(xml, b"<AppendedData", 0) else {
        return Ok(());
    };
    // The base64 text of the appended data, after its `_`.
    let Some(data) = appended_text(xml, appended_at) else {
        return Ok(());
    };
    let value = |tag: &quick_xml::events::BytesStart, name: &str| {
        tag.try_get_attribute(name)
            .ok()
            .flatten()
            .map(|a| a.value.into_owned())
    };
    let number = |bytes: Option<Vec<u8>>| {
        bytes.and_then(|b| std::str::from_utf8(&b).ok()?.trim().parse::<u64>().ok())
    };
    // Lines are counted only for the message: counting them at each piece was a scan from the
    // start of the file per piece.
    let line = |at: u64| crate::raw_appended::line_of(&xml[..appended_at], at as usize);
    let mut reader = quick_xml::Reader::from_reader(&xml[..appended_at]);
    let (mut header64, mut little) = (false, true);
    // The open piece: its counts and where it starts.
    let (mut points, mut cells, mut piece_at) = (None, None, 0);
    let mut section: Vec<u8> = Vec::new();
    loop {
        let at = reader.buffer_position();
        let (tag, empty) = match reader.read_event() {
            Ok(Event::Start(tag)) => (tag, false),
            Ok(Event::Empty(tag)) => (tag, true),
            Ok(Event::End(tag)) => {
                if tag.name().as_ref() == section.as_slice() {
                    section.clear();
                }
                continue;
            }
            Ok(Event::Eof) | Err(_) => return Ok(()),
            Ok(_) => continue,
        };
        match tag.name().as_ref() {
            b"VTKFile" => {
                if value(&tag, "compressor").is_some_and(|c| !c.trim_ascii().is_empty()) {
                    // vtkio checks the size of compressed arrays itself.
                    return Ok(());
                }
                header64 = value(&tag, "header_type").as_deref() == Some(b"UInt64");
                little = value(&tag, "byte_order").as_deref() != Some(b"BigEndian");
            }
            b"Piece" => {
                points = number(value(&tag, "NumberOfPoints"));
                cells = number(value(&tag, "NumberOfCells"));
                piece_at = at;
            }
            name @ (b"Points" | b"PointData" | b"CellData" | b"Cells") if !empty => {
                section = name.to_vec();
            }
            b"DataArray" if value(&tag, "format").as_deref() == Some(b"appended") => {
                let name = value(&tag, "Name").unwrap_or_default();
                let components = number(value(&tag, "NumberOfComponents")).unwrap_or(1);
                let (count, what) = match (section.as_slice(), name.as_slice()) {
                    (b"Points" | b"PointData", _) => (points, "NumberOfPoints"),
                    (b"CellData", _) | (b"Cells", b"offsets" | b"types") => {
                        (cells, "NumberOfCells")
                    }
                    _ => continue,
                };
                // Cell data is read for `vtkGhostType` alone (its length checked there).
                let unread = section == b"CellData" && name != b"vtkGhostType";
                let (Some(count), Some(offset), Some(width)) = (
                    count,
                    number(value(&tag, "offset")),
                    value(&tag, "type").as_deref().and_then(width),
                ) else {
                    continue;
                };
                let header_bytes: usize = if header64 { 8 } else { 4 };
                let Some(held) = usize::try_from(offset)
                    .ok()
                    .and_then(|o| data.get(o..o.checked_add(header_bytes.div_ceil(3) * 4)?))
                    .and_then(|head| base64::engine::general_purpose::STANDARD.decode(head).ok())
                    .and_then(|bytes| Some(header_word(bytes.get(..header_bytes)?, little)))
                else {
                    continue;
                };
                let asked = count.saturating_mul(components).saturating_mul(width);
                if held != asked && !(unread && held > asked) {
                    return Err(ErrorKind::Vtk(crate::one_line(&format!(
                        "line {}: the appended array {} holds {held} bytes ({} values), but \
                         {what}={count} of its <Piece> (line {}){} asks for {asked} \
                         ({} values)",
                        line(at),
                        crate::excerpt(&name, 40),
                        held / width,
                        line(piece_at),
                        if components == 1 {
                            String::new()
                        } else {
                            format!(" × NumberOfComponents={components}")
                        },
                        asked / width,
                    ))));
                }
            }
            _ => {}
        }
    }
}
