//! Legacy array types that vtkio's parser does not know, renamed before it parses the file.
//!
//! VTK's legacy writer names the types of a `vtkUnsignedShortArray`, a `vtkSignedCharArray`, a
//! `vtkTypeInt64Array` and a `vtkTypeUInt64Array` `unsigned_short`, `signed_char`, `vtktypeint64`
//! and `vtktypeuint64` (VTK 9.7.2 writes its 64-bit integer arrays so), and its reader reads
//! them; vtkio 0.7.0-rc2's parser knows none of these words and refused the whole file as
//! malformed, whichever array held one. So the type word of each number array of point, cell or
//! field data (`SCALARS`, `VECTORS`, `NORMALS`, a `FIELD` array; as `legacy_sections` walks
//! them) is rewritten as a type vtkio reads to the same values, padded with spaces to its length
//! so that lines and bytes keep their numbers:
//! - `signed_char` as `char` (1 byte, signed), `vtktypeint64` as `long` and `vtktypeuint64` as
//!   `unsigned_long` (8 bytes each, as vtkio reads them, signed and unsigned);
//! - `unsigned_short`: vtkio's parser has no unsigned 2-byte type. In an ASCII file it is read as
//!   `unsigned_int` (the same numbers); in a binary file as `short` (the same 2 bytes), and its
//!   values are taken back as unsigned after parsing ([`Renamed::restore`]), so that 65535 is
//!   not read as −1.
//!
//! Where the walk stops early (at a section of a binary file it does not measure), arrays after
//! it keep their types, and vtkio's parser refuses the file as before.

use std::borrow::Cow;

use vtkio::model::{Attribute, DataSet, IOBuffer, Piece, Vtk};

use crate::legacy_sections::Array;

/// The type vtkio's parser reads in place of the legacy type word `kind` (in a binary file when
/// `binary`); `None` for a word it knows, or no VTK type.
fn known_as(kind: &str, binary: bool) -> Option<&'static str> {
    Some(match kind.to_ascii_lowercase().as_str() {
        "signed_char" => "char",
        "vtktypeint64" => "long",
        "vtktypeuint64" => "unsigned_long",
        "unsigned_short" if binary => "short",
        "unsigned_short" => "unsigned_int",
        _ => return None,
    })
}

/// A 2-byte array of point or cell data, which vtkio reads as `short`.
struct TwoBytes {
    cell: bool,
    name: String,
    /// Written `unsigned_short` (renamed `short`): its values are unsigned.
    unsigned: bool,
}

/// What [`rename`] renamed that the parsed file must be told: the 2-byte arrays of a binary file
/// in which some are `unsigned_short`, in file order.
#[derive(Default)]
pub(crate) struct Renamed {
    two_bytes: Vec<TwoBytes>,
}

/// Rewrites in `bytes` each type word of `arrays` (a walk of `bytes`) that vtkio's parser does not
/// know; `binary`: the file is binary.
pub(crate) fn rename(bytes: &mut Cow<'_, [u8]>, arrays: &[Array], binary: bool) -> Renamed {
    let mut renamed = Renamed::default();
    for array in arrays {
        let Some(known) = known_as(array.kind, binary) else {
            continue;
        };
        let word = &mut bytes.to_mut()[array.kind_at..array.kind_at + array.kind.len()];
        word.fill(b' ');
        word[..known.len()].copy_from_slice(known.as_bytes());
    }
    let unsigned = |array: &Array| array.kind.eq_ignore_ascii_case("unsigned_short");
    if !binary || !arrays.iter().any(unsigned) {
        return renamed;
    }
    // Every 2-byte array of point and cell data, so that an `unsigned_short` array is told from
    // a `short` one of the same name. The data set's own field data is blanked before parsing.
    for array in arrays {
        let Some(of) = array.of else {
            continue;
        };
        if unsigned(array) || array.kind.eq_ignore_ascii_case("short") {
            renamed.two_bytes.push(TwoBytes {
                cell: of
                    .text
                    .get(..9)
                    .is_some_and(|start| start.eq_ignore_ascii_case("CELL_DATA")),
                name: array.name.to_owned(),
                unsigned: unsigned(array),
            });
        }
    }
    renamed
}

impl Renamed {
    /// Takes the values of each `unsigned_short` array of a binary file, which vtkio read as
    /// `short`, back as unsigned: the n-th 2-byte array of a name in the point (cell) data is the
    /// n-th the walk met there.
    pub(crate) fn restore(&self, vtk: &mut Vtk) {
        if !self.two_bytes.iter().any(|a| a.unsigned) {
            return;
        }
        let DataSet::UnstructuredGrid { pieces, .. } = &mut vtk.data else {
            return;
        };
        let mut taken = vec![false; self.two_bytes.len()];
        for piece in pieces {
            let Piece::Inline(piece) = piece else {
                continue;
            };
            for (cell, attributes) in [(false, &mut piece.data.point), (true, &mut piece.data.cell)]
            {
                for attribute in attributes.iter_mut() {
                    let arrays: Vec<(&str, &mut IOBuffer)> = match attribute {
                        Attribute::DataArray(array) => vec![(&array.name, &mut array.data)],
                        Attribute::Field { data_array, .. } => data_array
                            .iter_mut()
                            .map(|a| (a.name.as_str(), &mut a.data))
                            .collect(),
                    };
                    for (name, data) in arrays {
                        let IOBuffer::I16(values) = data else {
                            continue;
                        };
                        let Some(at) = (0..self.two_bytes.len()).find(|&k| {
                            !taken[k]
                                && self.two_bytes[k].cell == cell
                                && self.two_bytes[k].name == name
                        }) else {
                            continue;
                        };
                        taken[at] = true;
                        if self.two_bytes[at].unsigned {
                            // The same 2 bytes, read unsigned.
                            let values = values
                                .iter()
                                .map(|v| u16::from_ne_bytes(v.to_ne_bytes()))
                                .collect();
                            *data = IOBuffer::U16(values);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::borrow::Cow;

    use super::rename;
    use crate::legacy_sections::walk;

    #[test]
    fn unknown_type_words_are_renamed_in_place() {
        let file = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                    FIELD FieldData 1\nt 1 1 vtktypeuint64\n5\nPOINTS 0 double\n\
                    POINT_DATA 0\nSCALARS s unsigned_short 1\nLOOKUP_TABLE default\n\
                    VECTORS v vtktypeint64\nFIELD FieldData 1\nc 1 0 signed_char\n";
        let arrays = walk(file.as_bytes()).unwrap().arrays;
        let mut bytes = Cow::Borrowed(file.as_bytes());
        let renamed = rename(&mut bytes, &arrays, false);
        assert!(renamed.two_bytes.is_empty());
        let expected = file
            .replace("vtktypeuint64", "unsigned_long")
            .replace("unsigned_short", "unsigned_int  ")
            .replace("vtktypeint64", "long        ")
            .replace("signed_char", "char       ");
        assert_eq!(String::from_utf8_lossy(&bytes), expected);
        // Binary: `unsigned_short` is read as `short`, then made unsigned.
        let binary = b"# vtk DataFile Version 4.2\nt\nBINARY\nPOINT_DATA 1\n\
                       SCALARS s unsigned_short 1\nLOOKUP_TABLE default\n\xff\xfe\n";
        let arrays = walk(binary).unwrap().arrays;
        let mut bytes = Cow::Borrowed(&binary[..]);
        let renamed = rename(&mut bytes, &arrays, true);
        assert!(bytes.ends_with(b"\nSCALARS s short          1\nLOOKUP_TABLE default\n\xff\xfe\n"));
        assert_eq!(renamed.two_bytes.len(), 1);
        assert!(renamed.two_bytes[0].unsigned && !renamed.two_bytes[0].cell);
        // Known types are left as they are.
        let known = b"# vtk DataFile Version 4.2\nt\nASCII\nPOINT_DATA 0\nSCALARS s short\n";
        let arrays = walk(known).unwrap().arrays;
        let mut bytes = Cow::Borrowed(&known[..]);
        rename(&mut bytes, &arrays, false);
        assert!(matches!(bytes, Cow::Borrowed(_)));
    }
}
