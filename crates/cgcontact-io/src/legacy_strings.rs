//! Legacy string arrays and id sections, blanked out before vtkio parses the file.
//!
//! VTK's legacy writer puts a `vtkStringArray` (material names, a block name) in a `FIELD` block,
//! of the data set, its cells or its nodes, with the type `string`; and the attributes of point
//! and cell data that mark global ids, pedigree ids and edge flags (what ParaView's Exodus reader
//! and its "Generate Global Ids" filter set) in sections of their own, `GLOBAL_IDS name type`,
//! `PEDIGREE_IDS name type` and `EDGE_FLAGS name type`. vtkio 0.7.0-rc2's parser has no `string`
//! type and knows none of those sections, and refused the whole file. They carry no geometry and
//! no displacement, so each (`legacy_sections` finds and measures them) is blanked out: every byte
//! of its header, its values and a `METADATA` block after them made a space but line ends (so that
//! later errors name the right lines).
//! - A string array's `FIELD` block has its count lowered by one. A block left with no array
//!   stays, as `FIELD name 0`.
//! - An id section's header (and a `TENSORS6 name type` section's, symmetric tensors that vtkio
//!   does not know either, measured as an id section of six values a node or cell) becomes
//!   `FIELD name 0`, padded with spaces: a section that was all
//!   its `POINT_DATA n` or `CELL_DATA n` held leaves that header followed by an empty block, not
//!   bare, so the file does not read as one cut after its header (a bare `CELL_DATA n` or
//!   `POINT_DATA n` at the end of a file).

use std::collections::BTreeMap;

use crate::legacy_sections::{Header, Walk, Within};

/// The file with its string arrays and id sections, as `walk` measured them, blanked out; `None`
/// when it has none; `Err` names one that is cut, holds other than what it declares or
/// whose lengths run past the end of the file, as `line N: what is wrong`, and a `POINT_DATA n`
/// or `CELL_DATA n` that is not the file's node or cell count (which vtkio's parser never checks).
///
/// A fault in another section ends the walk: string arrays and id sections after it are left,
/// and vtkio's parser then refuses the file at that section or at one of them.
pub(crate) fn blank(bytes: &[u8], walk: &Walk) -> Result<Option<Vec<u8>>, String> {
    if let Some(fault) = &walk.fault
        && (fault.in_unread || fault.unparsed_count)
    {
        return Err(fault.message.clone());
    }
    if walk.unread.is_empty() {
        return Ok(None);
    }
    let mut blanked = bytes.to_vec();
    // Each FIELD block, by the byte its header starts at: its header, its arrays, and the string
    // arrays it loses.
    let mut fields: BTreeMap<usize, (Header, u64, u64)> = BTreeMap::new();
    for unread in &walk.unread {
        for byte in &mut blanked[unread.span.clone()] {
            if *byte != b'\n' && *byte != b'\r' {
                *byte = b' ';
            }
        }
        match unread.within {
            Within::Field { header, arrays } => {
                fields.entry(header.at).or_insert((header, arrays, 0)).2 += 1;
            }
            Within::Attribute(header) => empty_field(&mut blanked, header),
        }
    }
    for (header, arrays, removed) in fields.into_values() {
        lower_count(&mut blanked, header, arrays - removed);
    }
    Ok(Some(blanked))
}

/// Writes `FIELD name 0` where the blanked header `KEYWORD name type` of an id section was: no
/// longer than it (`FIELD` is shorter than each keyword, `0` than each type name), and a block
/// that vtkio reads as one without arrays.
fn empty_field(bytes: &mut [u8], header: Header) {
    let name = header
        .text
        .split_whitespace()
        .nth(1)
        .expect("the walk measures an id section only when its header has three words");
    let field = format!("FIELD {name} 0");
    bytes[header.at..header.at + field.len()].copy_from_slice(field.as_bytes());
}

/// Rewrites the count of the header `FIELD name n` as `arrays`, padded with spaces to its
/// width: `arrays` is below `n` (the walk counts a string array only among the `n` arrays of its
/// block), so it has no more digits.
fn lower_count(bytes: &mut [u8], field: Header, arrays: u64) {
    // The header's last word is its count.
    let end = field.at + field.text.len();
    let width = field.text.len()
        - field
            .text
            .trim_end_matches(|c: char| !c.is_whitespace())
            .len();
    let lowered = arrays.to_string();
    let count = &mut bytes[end - width..end];
    count.fill(b' ');
    count[..lowered.len()].copy_from_slice(lowered.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::blank;
    use crate::legacy_sections::walk;

    /// What `blank` makes of a file: the blanked text, `None` for none.
    fn blanked(file: &[u8]) -> Option<String> {
        blank(file, &walk(file).unwrap())
            .unwrap()
            .map(|bytes| String::from_utf8_lossy(&bytes).into_owned())
    }

    #[test]
    fn ascii_string_arrays_become_spaces_and_their_block_counts_fall() {
        let head = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n";
        let file = format!(
            "{head}FIELD FieldData 2\nnames 1 2 string\na%20b\n\nTimeValue 1 1 double\n0.5\n\
             POINTS 0 double\n"
        );
        assert_eq!(
            blanked(file.as_bytes()).unwrap(),
            format!(
                "{head}FIELD FieldData 1\n{}\n     \n\nTimeValue 1 1 double\n0.5\n\
                 POINTS 0 double\n",
                " ".repeat(16)
            )
        );
        // Ten arrays, all strings: the count keeps its width.
        let arrays = "s 1 0 string\n".repeat(10);
        let file = format!("{head}FIELD FieldData 10\r\n{arrays}POINTS 0 double\n");
        assert_eq!(
            blanked(file.as_bytes()).unwrap(),
            format!(
                "{head}FIELD FieldData 0 \r\n{}POINTS 0 double\n",
                format!("{}\n", " ".repeat(12)).repeat(10)
            )
        );
        // No string array: nothing to blank.
        let file = format!("{head}FIELD FieldData 1\nTimeValue 1 1 double\n0.5\n");
        assert_eq!(blanked(file.as_bytes()), None);
    }

    #[test]
    fn id_sections_become_empty_field_blocks() {
        let head =
            "# vtk DataFile Version 4.2\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINT_DATA 2\n";
        let mut file = head.as_bytes().to_vec();
        // Ids 1 and 10, a line end among the bytes of its values.
        file.extend(b"GLOBAL_IDS ids vtkIdType\n\0\0\0\x01\0\0\0\n\n");
        file.extend(b"EDGE_FLAGS flags bit\n\x80\nMETADATA\nINFORMATION 0\n\n");
        let expected = format!(
            "{head}FIELD ids 0{}\n{}\n\nFIELD flags 0{}\n \n        \n             \n\n",
            " ".repeat(13),
            " ".repeat(7),
            " ".repeat(7)
        );
        assert_eq!(blanked(&file).unwrap(), expected);
    }

    #[test]
    fn binary_string_arrays_become_spaces_but_their_line_ends() {
        let head = b"# vtk DataFile Version 5.1\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\n";
        let mut file = head.to_vec();
        file.extend(b"FIELD FieldData 1\nnames 1 2 string\n\xc2a\n\x80\x03\r\nb\nMETADATA\n");
        file.extend(b"COMPONENT_NAMES\nx\n\nPOINTS 0 double\n");
        let mut expected = String::from_utf8(head.to_vec()).unwrap();
        expected += "FIELD FieldData 0\n";
        expected += &" ".repeat(16);
        expected += "\n  \n  \r\n ";
        expected += "\n        \n               \n \n\nPOINTS 0 double\n";
        assert_eq!(blanked(&file).unwrap(), expected);
    }
}
