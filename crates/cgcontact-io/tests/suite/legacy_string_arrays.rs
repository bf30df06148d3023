//! VTK's legacy writer puts a `vtkStringArray` (material names, a block name, node labels) in a
//! `FIELD` block of the data set, its cells or its nodes, with the type `string`; vtkio's parser
//! has no such type, and such a file was refused whole. String arrays are now blanked out before
//! parsing, in ASCII and binary files, versions 4.2 and 5.1: each file VTK 9.7.2 wrote with them
//! (fixtures/vtk-written-strings, made by its make.py) reads as the same body written without
//! them. A string array that is cut, holds more or fewer strings than it declares, or whose
//! lengths run past the end of the file is an error naming its line.

use std::path::PathBuf;

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh, read_mesh};

use crate::common::legacy_fixtures::{self, FLAVOURS, line_of, parse, position, replaced};

fn folder() -> PathBuf {
    legacy_fixtures::folder("vtk-written-strings")
}

fn file(name: &str) -> Vec<u8> {
    legacy_fixtures::read(&folder(), name)
}

/// The body of `plain-{flavour}.vtk`: the file written without the string arrays.
fn plain(flavour: &str) -> HexMesh {
    legacy_fixtures::plain(&folder(), flavour)
}

#[test]
fn string_arrays_vtk_wrote_are_read_past_in_every_flavour() {
    for flavour in FLAVOURS {
        let name = format!("strings-{flavour}.vtk");
        let bytes = file(&name);
        // The string arrays the file holds, in data set, cell and point data.
        for header in [
            "block%20name 1 1 string",
            "notes 1 6 string",
            "material 1 10 string",
            "tags 2 10 string",
            "node%20label 1 35 string",
            "remark 1 35 string",
        ] {
            position(&bytes, header.as_bytes());
        }
        let read = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(read, plain(flavour), "{name}");
        // And as a lattice body, from the file.
        let mesh = read_mesh(folder().join(&name), &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(mesh.cells.len(), 10, "{name}");
        assert_eq!(
            mesh.body.lattice().h(),
            DVec3::new(0.5, 0.25, 0.125),
            "{name}"
        );
        assert!(mesh.has_displacement, "{name}");
    }
}

/// A string array is no displacement: asking for one lists the number arrays.
#[test]
fn a_string_array_asked_for_as_the_displacement_is_not_found() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let named = DisplacementArray::Named("node label".to_owned());
        let message = parse_hex_mesh(&bytes, &named).unwrap_err().to_string();
        assert!(
            message.contains("no point data array named `node label`")
                && message.contains("found: displacement)"),
            "{flavour}: {message}"
        );
    }
}

/// Every width of binary length VTK's reader knows (1, 2, 4 and 8 bytes; VTK writes the 8-byte
/// one from 2^30 bytes on), strings holding line ends and header text, and the type name
/// `utf8_string`, in ASCII and binary.
#[test]
fn every_length_width_and_utf8_string_are_read_past() {
    let expected = plain("4.2-binary");
    let mut strings = b"FIELD FieldData 2\nlong 1 4 utf8_string\n".to_vec();
    strings.push(0xc0 | 1);
    strings.extend(b"\n");
    let hundred = b"\nPOINTS 1 double\n".repeat(6);
    strings.extend((0x8000u16 | hundred.len() as u16).to_be_bytes());
    strings.extend(&hundred);
    let many = vec![b'\n'; 20_000];
    strings.extend((0x4000_0000u32 | many.len() as u32).to_be_bytes());
    strings.extend(&many);
    strings.extend(5u64.to_be_bytes());
    strings.extend(b"CELLS");
    strings.extend(b"\n");
    let binary = replaced(
        &file("plain-4.2-binary.vtk"),
        b"FIELD FieldData 1\n",
        &strings,
    );
    assert_eq!(parse(&binary).unwrap(), expected);

    let ascii = replaced(
        &file("plain-4.2-ascii.vtk"),
        b"FIELD FieldData 1\n",
        b"FIELD FieldData 2\nnames 1 3 utf8_string\nZ%C3%BCrich\n\n12\n\n",
    );
    assert_eq!(parse(&ascii).unwrap(), plain("4.2-ascii"));
}

/// A file cut inside a string array names the array and its line.
#[test]
fn a_cut_string_array_is_refused_naming_it() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let header = b"node%20label 1 35 string";
        let line = line_of(&bytes, header);
        // Cut after the header and a few strings, and in the middle of one.
        let start = position(&bytes, header);
        for cut in [start + header.len() + 1, start + 60, start + 61] {
            let message = parse(&bytes[..cut]).unwrap_err();
            assert!(
                message.contains(&format!(
                    "line {line}: the string array `node%20label 1 35 string`"
                )),
                "{flavour}, cut at {cut}: {message}"
            );
        }
    }
}

/// A count above or below the strings an ASCII array holds names the array.
#[test]
fn an_ascii_string_count_that_is_not_the_strings_is_refused_naming_it() {
    for flavour in ["4.2-ascii", "5.1-ascii"] {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let line = line_of(&bytes, b"notes 1 6 string");
        // 8: the writer's blank line after the 6 strings, then the `POINTS` header.
        let more = replaced(&bytes, b"notes 1 6 string", b"notes 1 8 string");
        let message = parse(&more).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {line}: the string array `notes 1 8 string` holds 7 of its 8 strings: \
                 line {} is a section header, `POINTS 35 double`",
                line_of(&bytes, b"POINTS")
            )),
            "{flavour}: {message}"
        );
        // 5: the 6th string follows where a header should.
        let fewer = replaced(&bytes, b"notes 1 6 string", b"notes 1 5 string");
        let message = parse(&fewer).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {line}: the string array `notes 1 5 string` holds more than its 5 \
                 strings: line {}, `xxxx",
                line + 6
            )),
            "{flavour}: {message}"
        );
    }
}

/// A string array of cell or point data holds one string a cell or node (per component).
#[test]
fn a_string_array_of_other_tuples_than_its_cells_or_nodes_is_refused_naming_it() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let line = line_of(&bytes, b"material 1 10 string");
        let more = replaced(&bytes, b"material 1 10 string", b"material 1 11 string");
        let message = parse(&more).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {line}: the string array `material 1 11 string` has 11 tuples, but \
                 `CELL_DATA 10` (line {}) declares 10",
                line_of(&bytes, b"CELL_DATA 10")
            )),
            "{flavour}: {message}"
        );
    }
}

/// In a binary file: a count above the strings reads the next header as lengths, past the end of
/// the file; one below, or a length a little long, ends the strings where VTK's line end is not; a
/// length past the end of the file, in any width, a length that lands the walk on an array header
/// of another section, and a count that overflows are named too.
#[test]
fn a_binary_string_length_or_count_that_is_not_the_strings_is_refused_naming_it() {
    for flavour in ["4.2-binary", "5.1-binary"] {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let notes = line_of(&bytes, b"notes 1 6 string");
        let more = replaced(&bytes, b"notes 1 6 string", b"notes 1 7 string");
        let message = parse(&more).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {notes}: the string array `notes 1 7 string`: string 7 of 7 is "
            )) && message.contains("bytes long, but only"),
            "{flavour}: {message}"
        );
        // VTK ends the strings with a line end: 5 end before the 6th's length.
        let fewer = replaced(&bytes, b"notes 1 6 string", b"notes 1 5 string");
        let message = parse(&fewer).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {notes}: the string array `notes 1 5 string`: its 5 strings end at byte "
            )) && message.contains("where VTK writes a line end, not `\\u{fffd}Fxxx"),
            "{flavour}: {message}"
        );
        // The last node label, `node 34` (length byte 0xc7), made 2 bytes longer: it would take
        // the line end and the `d` of `displacement`, the displacement renamed `isplacement`.
        let label = line_of(&bytes, b"node%20label 1 35 string");
        let last = position(&bytes, b"\xc7node 34\ndisplacement");
        let longer = [&bytes[..last], &[0xc9], &bytes[last + 1..]].concat();
        let message = parse(&longer).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {label}: the string array `node%20label 1 35 string`: its 35 strings end \
                 at byte {}, where VTK writes a line end, not `isplacement",
                last + 10
            )),
            "{flavour}: {message}"
        );
        // The first string of `material`, `steel plate` (length byte 0xcb), made longer than
        // the file in the widths of 2, 4 and 8 bytes.
        let line = line_of(&bytes, b"material 1 10 string");
        let start = position(&bytes, b"material 1 10 string\n") + 21;
        assert_eq!(bytes[start], 0xc0 | 11, "{flavour}");
        let with_length =
            |at: usize, length: &[u8]| [&bytes[..at], length, &bytes[at + 1..]].concat();
        for length in [
            vec![0xbf, 0xff],
            vec![0x7f, 0xff, 0xff, 0xff],
            vec![0, 0, 0, 0, 0, 0, 0x10, 0],
            (u64::MAX >> 2).to_be_bytes().to_vec(),
        ] {
            let message = parse(&with_length(start, &length)).unwrap_err();
            assert!(
                message.contains(&format!(
                    "line {line}: the string array `material 1 10 string`: string 1 of 10 is "
                )) && message.contains("bytes long, but only"),
                "{flavour}, {length:x?}: {message}"
            );
        }
        // 63 bytes, the most one byte says, take the next lengths from the strings.
        let message = parse(&with_length(start, &[0xff])).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {line}: the string array `material 1 10 string`: string "
            )),
            "{flavour}: {message}"
        );
        // Its last string, `aluminium 6061-T6` (0xd1), given a 2-byte length that ends it on
        // the line end before `remark 1 35 string`: from the `tags` array over the point data,
        // `remark` read as the cell data's next array.
        let last = position(&bytes, b"\xd1aluminium 6061-T6\ntags");
        // The length takes a byte more than 0xd1 did: the strings end where `\nremark` was.
        let length = (position(&bytes, b"\nremark 1 35 string") - last - 1) as u16;
        let message = parse(&with_length(last, &(0x8000 | length).to_be_bytes())).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {line}: the string array `material 1 10 string` ends where `"
            )) && message.contains(&format!(
                "1 35 string` (line {}) starts, an array of 35 tuples where `CELL_DATA 10` \
                     (line {}) declares 10 (a wrong length or count of its strings?)",
                line_of(&bytes, b"remark 1 35 string"),
                line_of(&bytes, b"CELL_DATA 10")
            )),
            "{flavour}: {message}"
        );
        // A length cut by the end of the file.
        let cut = [&bytes[..start], &[0x40, 0x00][..]].concat();
        let message = parse(&cut).unwrap_err();
        assert!(
            message.contains("string 1 of 10 has a 4-byte length, but the file ends inside it"),
            "{flavour}: {message}"
        );
        let huge = replaced(
            &bytes,
            b"notes 1 6 string",
            b"notes 4294967296 4294967296 string",
        );
        let message = parse(&huge).unwrap_err();
        assert!(
            message.contains(&format!(
                "line {notes}: the `notes 4294967296 4294967296 string` section declares an \
                 impossible count"
            )),
            "{flavour}: {message}"
        );
    }
}

/// Every cut of each file, and every byte of its string arrays (headers, strings, METADATA) set
/// to values that move a binary length or a line end, is refused or reads as the whole body:
/// never a panic, never another mesh.
#[test]
fn every_cut_and_corrupt_string_byte_is_refused_or_reads_the_same_body() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("strings-{flavour}.vtk"));
        let expected = plain(flavour);
        let check = |bytes: &[u8], what: &str| {
            if let Ok(read) = parse(bytes) {
                assert_eq!(read, expected, "{flavour}, {what}");
            }
        };
        // A file cut before its point data is a file without them: read undeformed.
        let point_data = position(&bytes, b"POINT_DATA");
        let undeformed = HexMesh {
            ghosts: Vec::new(),
            displacement: None,
            ..expected.clone()
        };
        for cut in 0..bytes.len() {
            if let Ok(read) = parse(&bytes[..cut]) {
                if cut <= point_data && read.displacement.is_none() {
                    assert_eq!(read, undeformed, "{flavour}, cut at {cut}");
                } else {
                    assert_eq!(read, expected, "{flavour}, cut at {cut}");
                }
            }
        }
        // Each string array, from its header to the line end before the next header (which
        // would join that header: a corrupt name of the array after).
        for (from, to) in [
            ("block%20name 1 1 string", "TimeValue"),
            ("notes 1 6 string", "POINTS"),
            ("material 1 10 string", "POINT_DATA"),
            ("node%20label 1 35 string", "displacement 3 35"),
        ] {
            let (from, to) = (
                position(&bytes, from.as_bytes()),
                position(&bytes, to.as_bytes()),
            );
            for at in from..to - 1 {
                for value in [b'\n', b' ', b'x', b'7', 0x00, 0x41, 0x85, 0xc3] {
                    let mut corrupt = bytes.clone();
                    corrupt[at] = value;
                    check(&corrupt, &format!("byte {at} set to {value:#x}"));
                }
            }
        }
        let remark = position(&bytes, b"remark 1 35 string");
        for at in remark..bytes.len() {
            for value in [b'\n', b' ', b'x', b'7', 0x00, 0x41, 0x85, 0xc3] {
                let mut corrupt = bytes.clone();
                corrupt[at] = value;
                check(&corrupt, &format!("byte {at} set to {value:#x}"));
            }
        }
    }
}
