//! Legacy string arrays, blanked out before vtkio parses the file.
//!
//! VTK's legacy writer puts a `vtkStringArray` (material names, a block name) in a `FIELD` block,
//! of the data set, its cells or its nodes, with the type `string`; vtkio 0.7.0-rc2's parser has
//! no such type and refused the whole file. The strings carry no geometry and no displacement, so
//! each string array (`legacy_sections` finds and measures them) is blanked out: every byte of
//! its header, its strings and a `METADATA` block after them made a space but line ends (so that
//! later errors name the right lines), and the count of its `FIELD` block lowered by one. A block
//! left with no array stays, as `FIELD name 0`: a bare `CELL_DATA n` at the end of a file reads
//! as one cut after its header.

use std::collections::BTreeMap;

use crate::legacy_sections::{self, Header, StringArray};

/// The file with its string arrays blanked out; `None` when it has none (or is no legacy file
/// the walk reads); `Err` names a string array that is cut or whose lengths run past the end of
/// the file, as `line N: what is wrong`.
///
/// A fault in another section ends the walk: string arrays after it are left, and vtkio's parser
/// then refuses the file at that section or at one of them.
pub(crate) fn blank(bytes: &[u8]) -> Result<Option<Vec<u8>>, String> {
    let Some(walk) = legacy_sections::walk(bytes) else {
        return Ok(None);
    };
    if let Some(fault) = walk.fault
        && fault.in_strings
    {
        return Err(fault.message);
    }
    if walk.strings.is_empty() {
        return Ok(None);
    }
    let mut blanked = bytes.to_vec();
    // Each FIELD block, by the byte its header starts at, with the string arrays it loses.
    let mut fields: BTreeMap<usize, (&StringArray, u64)> = BTreeMap::new();
    for array in &walk.strings {
        for byte in &mut blanked[array.span.clone()] {
            if *byte != b'\n' && *byte != b'\r' {
                *byte = b' ';
            }
        }
        fields.entry(array.field.at).or_insert((array, 0)).1 += 1;
    }
    for (array, removed) in fields.into_values() {
        lower_count(&mut blanked, array.field, array.field_arrays - removed);
    }
    Ok(Some(blanked))
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

    /// What `blank` makes of a file: the blanked text, `None` for none.
    fn blanked(file: &[u8]) -> Option<String> {
        blank(file)
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
