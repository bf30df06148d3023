//! VTK's legacy writer puts the global ids, pedigree ids and edge flags of point and cell data
//! (what ParaView's Exodus reader and its "Generate Global Ids" set) in sections of their own,
//! `GLOBAL_IDS name type`, `PEDIGREE_IDS name type` and `EDGE_FLAGS name type`, which vtkio's
//! parser does not know: such a file was refused whole. They are now blanked out before parsing,
//! in ASCII and binary files, versions 4.2 and 5.1, of every type VTK writes there: each file VTK
//! 9.7.2 wrote with them (fixtures/vtk-written-ids, made by its make.py) reads as the same body
//! written without them, bit for bit. A section that is cut, or does not hold one value a node or
//! cell, is an error naming it and its line.

use std::path::PathBuf;

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh, read_mesh};

use crate::common::legacy_fixtures::{
    self, FLAVOURS, assert_same, line_of, parse, position, replaced,
};

fn folder() -> PathBuf {
    legacy_fixtures::folder("vtk-written-ids")
}

fn file(name: &str) -> Vec<u8> {
    legacy_fixtures::read(&folder(), name)
}

/// The id sections of `ids-{flavour}.vtk`, in file order: cell data, then point data.
const IDS: [&str; 5] = [
    "GLOBAL_IDS GlobalElementId vtkIdType",
    "PEDIGREE_IDS element%20name string",
    "GLOBAL_IDS GlobalNodeId vtkIdType",
    "PEDIGREE_IDS PedigreeNodeId vtktypeint64",
    "EDGE_FLAGS edge%20flag bit",
];

/// The id sections of `ids-alone-{flavour}.vtk`: all its cell and point data.
const IDS_ALONE: [&str; 3] = [
    "PEDIGREE_IDS element%20tag variant",
    "PEDIGREE_IDS node%20label string",
    "EDGE_FLAGS EdgeFlag unsigned_char",
];

/// The body of `plain-{flavour}.vtk`: the file written without the id sections.
fn plain(flavour: &str) -> HexMesh {
    legacy_fixtures::plain(&folder(), flavour)
}

/// The body of `plain-alone-{flavour}.vtk`: the same, without point or cell data.
fn plain_alone(flavour: &str) -> HexMesh {
    let mesh = parse(&file(&format!("plain-alone-{flavour}.vtk"))).unwrap();
    assert_eq!(mesh.cells.len(), 10, "{flavour}");
    assert_eq!(mesh.points.len(), 35, "{flavour}");
    assert_eq!(mesh.displacement, None, "{flavour}");
    mesh
}

fn refused(bytes: &[u8], what: &str) -> String {
    match parse(bytes) {
        Ok(_) => panic!("{what}: read"),
        Err(message) => message,
    }
}

#[test]
fn id_sections_vtk_wrote_are_read_past_in_every_flavour() {
    for flavour in FLAVOURS {
        let name = format!("ids-{flavour}.vtk");
        let bytes = file(&name);
        for header in IDS {
            position(&bytes, format!("{header}\n").as_bytes());
        }
        // The cell data holds nothing but id sections; the string pedigree ids have METADATA.
        position(&bytes, b"CELL_DATA 10\nGLOBAL_IDS");
        position(
            &bytes,
            b"METADATA\nCOMPONENT_NAMES\nelement%20name\n\nPOINT_DATA 35\n",
        );
        let read = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same(&read, &plain(flavour), &name);
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

        // Id sections that are all their cell and point data: the file ends with one.
        let name = format!("ids-alone-{flavour}.vtk");
        let bytes = file(&name);
        for header in IDS_ALONE {
            position(&bytes, format!("{header}\n").as_bytes());
        }
        position(&bytes, b"CELL_DATA 10\nPEDIGREE_IDS");
        position(&bytes, b"POINT_DATA 35\nPEDIGREE_IDS");
        let read = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same(&read, &plain_alone(flavour), &name);
    }
}

/// An id section is no displacement: asking for one lists the point arrays vtkio read.
#[test]
fn an_id_section_asked_for_as_the_displacement_is_not_found() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("ids-{flavour}.vtk"));
        for name in ["GlobalNodeId", "PedigreeNodeId", "edge flag"] {
            let named = DisplacementArray::Named(name.to_owned());
            let message = parse_hex_mesh(&bytes, &named).unwrap_err().to_string();
            assert!(
                message.contains(&format!("no point data array named `{name}`"))
                    && message.contains("found: displacement)"),
                "{flavour}: {message}"
            );
        }
    }
}

/// Sections of each type VTK's writer writes (`vtkDataWriter::WriteArray`), in cell and point
/// data, in either case, with a METADATA block after some: read past in ASCII and binary, 4.2
/// and 5.1.
#[test]
fn id_sections_of_every_type_vtk_writes_are_read_past() {
    let types: [(&str, usize); 17] = [
        ("char", 1),
        ("signed_char", 1),
        ("unsigned_char", 1),
        ("short", 2),
        ("unsigned_short", 2),
        ("int", 4),
        ("unsigned_int", 4),
        ("long", 8),
        ("unsigned_long", 8),
        ("vtktypeint64", 8),
        ("vtktypeuint64", 8),
        ("float", 4),
        ("double", 8),
        ("vtkIdType", 4),
        ("bit", 0),
        ("string", 0),
        ("variant", 0),
    ];
    // `n` values of a type as VTK writes them, the line end after them included.
    let values = |kind: &str, size: usize, n: usize, binary: bool| -> Vec<u8> {
        match (kind, binary) {
            ("string", false) => (0..n)
                .flat_map(|i| format!("s%20{i}\n").into_bytes())
                .collect(),
            ("string", true) => {
                let mut out: Vec<u8> = (0..n)
                    .flat_map(|i| {
                        let s = format!("s {i}");
                        [vec![0xc0 | s.len() as u8], s.into_bytes()].concat()
                    })
                    .collect();
                out.push(b'\n');
                out
            }
            ("variant", _) => (0..n)
                .flat_map(|i| {
                    if i % 2 == 0 {
                        format!("13 v%20{i}\n").into_bytes()
                    } else {
                        format!("6 {i}\n").into_bytes()
                    }
                })
                .collect(),
            ("bit", true) => [vec![0xa5; n.div_ceil(8)], b"\n".to_vec()].concat(),
            (_, true) => [vec![0x01; size * n], b"\n".to_vec()].concat(),
            ("bit", false) => {
                let ones: Vec<String> = (0..n).map(|i| (i % 2).to_string()).collect();
                format!("{}\n", ones.join(" ")).into_bytes()
            }
            (_, false) => {
                let numbers: Vec<String> = (0..n).map(|i| (i % 100).to_string()).collect();
                format!("{}\n", numbers.join(" ")).into_bytes()
            }
        }
    };
    for flavour in FLAVOURS {
        let binary = flavour.ends_with("binary");
        let bytes = file(&format!("plain-{flavour}.vtk"));
        let expected = plain(flavour);
        for (kind, size) in types {
            for (keyword, metadata) in [("PEDIGREE_IDS", false), ("global_ids", true)] {
                let metadata: &[u8] = if metadata {
                    b"METADATA\nINFORMATION 0\n\n"
                } else {
                    b""
                };
                let mut cells = format!("CELL_DATA 10\n{keyword} c {kind}\n").into_bytes();
                cells.extend(values(kind, size, 10, binary));
                cells.extend(metadata);
                cells.extend(b"POINT_DATA 35\n");
                let mut points = format!("{keyword} p {kind}\n").into_bytes();
                points.extend(values(kind, size, 35, binary));
                points.extend(metadata);
                let mut with = replaced(&bytes, b"POINT_DATA 35\n", &cells);
                with = replaced(
                    &with,
                    b"FIELD FieldData",
                    &[&points, &b"FIELD FieldData"[..]].concat(),
                );
                let what = format!("{flavour}, {keyword} of {kind}");
                let read = parse(&with).unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_same(&read, &expected, &what);
            }
            // Edge flags, the last section of the file.
            let mut flags = format!("EDGE_FLAGS f {kind}\n").into_bytes();
            flags.extend(values(kind, size, 35, binary));
            let alone = [
                &file(&format!("plain-alone-{flavour}.vtk"))[..],
                b"POINT_DATA 35\n",
                &flags,
            ]
            .concat();
            let what = format!("{flavour}, EDGE_FLAGS of {kind}");
            let read = parse(&alone).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_same(&read, &plain_alone(flavour), &what);
        }
    }
}

/// A file cut inside an id section, after its header or among its values, names the section and
/// its line.
#[test]
fn a_cut_id_section_is_refused_naming_it() {
    for flavour in FLAVOURS {
        for (name, headers) in [("ids", &IDS[..]), ("ids-alone", &IDS_ALONE[..])] {
            let bytes = file(&format!("{name}-{flavour}.vtk"));
            for header in headers {
                let line = line_of(&bytes, header.as_bytes());
                let start = position(&bytes, header.as_bytes()) + header.len() + 1;
                for cut in [start, start + 1, start + 3] {
                    let message =
                        refused(&bytes[..cut], &format!("{name}-{flavour}, cut at {cut}"));
                    assert!(
                        message.contains(&format!("line {line}: the `{header}` section")),
                        "{name}-{flavour}, cut at {cut}: {message}"
                    );
                }
            }
        }
    }
}

/// A file cut right after a `CELL_DATA n` or `POINT_DATA n` header whose sections are all id
/// sections is still a cut file: blanking them leaves an empty block behind the header of a whole
/// file, not a bare header.
#[test]
fn a_file_cut_after_the_header_of_data_holding_only_ids_is_refused() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("ids-alone-{flavour}.vtk"));
        for header in ["CELL_DATA 10", "POINT_DATA 35"] {
            let line = line_of(&bytes, header.as_bytes());
            let cut = position(&bytes, header.as_bytes()) + header.len() + 1;
            let message = refused(&bytes[..cut], flavour);
            assert!(
                message.contains(&format!(
                    "line {line}: the file ends after `{header}`, before any of its arrays"
                )),
                "{flavour}: {message}"
            );
        }
    }
}

/// In an ASCII file the values of an id section are words, as VTK's reader reads them: one
/// missing, one more on the last line or on a line after it, and a corrupt one name the section.
#[test]
fn ascii_id_values_that_are_not_one_a_node_or_cell_are_refused_naming_the_section() {
    for flavour in ["4.2-ascii", "5.1-ascii"] {
        let bytes = file(&format!("ids-{flavour}.vtk"));
        let header = "GLOBAL_IDS GlobalNodeId vtkIdType";
        let line = line_of(&bytes, header.as_bytes());
        let declared = format!(
            "the 35 values that `POINT_DATA 35` (line {}) declares",
            line_of(&bytes, b"POINT_DATA 35")
        );
        let fewer = replaced(&bytes, b"33 34 35 \n", b"33 34 \n");
        let message = refused(&fewer, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds 34 of {declared}: line {}, \
                 `PEDIGREE_IDS PedigreeNodeId vtktypeint64`, is no value of it",
                line + 5
            )),
            "{flavour}: {message}"
        );
        let more = replaced(&bytes, b"33 34 35 \n", b"33 34 35 36 \n");
        let message = refused(&more, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds more than {declared}: line {}, \
                 `28 29 30 31 32 33 34 35 36`, holds the last and more",
                line + 4
            )),
            "{flavour}: {message}"
        );
        let after = replaced(&bytes, b"33 34 35 \n", b"33 34 35 \n36\n");
        let message = refused(&after, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds more than its 35 values: line {}, \
                 `36`, follows them where a header should",
                line + 5
            )),
            "{flavour}: {message}"
        );
        let corrupt = replaced(&bytes, b" 12 13 ", b" 12 1x ");
        let message = refused(&corrupt, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds 12 of {declared}: line {}, \
                 `10 11 12 1x",
                line + 2
            )),
            "{flavour}: {message}"
        );
        // A variant is two words: a pair missing leaves `POINT_DATA 35` where a type should be.
        let bytes = file(&format!("ids-alone-{flavour}.vtk"));
        let header = "PEDIGREE_IDS element%20tag variant";
        let line = line_of(&bytes, header.as_bytes());
        let fewer = replaced(&bytes, b"13 zone%209\n", b"");
        let message = refused(&fewer, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds 9 of the 10 values that `CELL_DATA \
                 10` (line {}) declares: line {}, `POINT_DATA 35`, is no value of it",
                line - 1,
                line + 10
            )),
            "{flavour}: {message}"
        );
        // A string pedigree id is a string a line.
        let header = "PEDIGREE_IDS node%20label string";
        let line = line_of(&bytes, header.as_bytes());
        let more = replaced(&bytes, b"node%2034\n", b"node%2034\nnode%2035\n");
        let message = refused(&more, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section holds more than its 35 strings: line {}, \
                 `node%2035`, follows them",
                line + 36
            )),
            "{flavour}: {message}"
        );
    }
}

/// In a binary file the values of an id section are measured in bytes by their type: another
/// type, a value more, or a length past the end of the file names the section.
#[test]
fn binary_id_values_that_are_not_one_a_node_or_cell_are_refused_naming_the_section() {
    for flavour in ["4.2-binary", "5.1-binary"] {
        let bytes = file(&format!("ids-{flavour}.vtk"));
        let declared = format!(
            "the 35 values that `POINT_DATA 35` (line {}) declares",
            line_of(&bytes, b"POINT_DATA 35")
        );
        // 4-byte ids read as 2 or 8 bytes; 8-byte ones as 4; bits as bytes.
        for (header, wrong) in [
            (
                "GLOBAL_IDS GlobalNodeId vtkIdType",
                "GLOBAL_IDS GlobalNodeId short",
            ),
            (
                "GLOBAL_IDS GlobalNodeId vtkIdType",
                "GLOBAL_IDS GlobalNodeId double",
            ),
            (
                "PEDIGREE_IDS PedigreeNodeId vtktypeint64",
                "PEDIGREE_IDS PedigreeNodeId int",
            ),
            ("EDGE_FLAGS edge%20flag bit", "EDGE_FLAGS edge%20flag char"),
        ] {
            let line = line_of(&bytes, header.as_bytes());
            let message = refused(
                &replaced(&bytes, header.as_bytes(), wrong.as_bytes()),
                wrong,
            );
            assert!(
                message.contains(&format!(
                    "line {line}: the `{wrong}` section: {declared} end at byte "
                )) && message.contains("where VTK writes a line end"),
                "{flavour}, {wrong}: {message}"
            );
        }
        // A value more: 4 bytes before the line end.
        let header = "GLOBAL_IDS GlobalElementId vtkIdType";
        let line = line_of(&bytes, header.as_bytes());
        let values = position(&bytes, header.as_bytes()) + header.len() + 1;
        let more = [&bytes[..values], &[0, 0, 0, 11], &bytes[values..]].concat();
        let message = refused(&more, flavour);
        assert!(
            message.contains(&format!(
                "line {line}: the `{header}` section: the 10 values that `CELL_DATA 10` (line {}) \
                 declares end at byte {}, where VTK writes a line end",
                line - 1,
                values + 40
            )),
            "{flavour}: {message}"
        );
        // A type that takes more bytes than the file holds.
        let huge = replaced(
            &bytes,
            b"EDGE_FLAGS edge%20flag bit",
            b"EDGE_FLAGS edge%20flag double",
        );
        let cut = &huge[..position(&huge, b"FIELD FieldData")];
        let message = refused(cut, flavour);
        assert!(
            message.contains(&format!(
                "line {}: the `EDGE_FLAGS edge%20flag double` section needs 280 bytes for \
                 {declared}, but only ",
                line_of(&bytes, b"EDGE_FLAGS")
            )),
            "{flavour}: {message}"
        );
    }
}

/// Sections VTK's reader would not read are refused, naming them: edge flags of cell data, a type
/// it does not know, a header of other than three words, and one outside point and cell data.
#[test]
fn id_sections_vtk_would_not_read_are_refused_naming_them() {
    for flavour in FLAVOURS {
        let bytes = file(&format!("ids-{flavour}.vtk"));
        let line = line_of(&bytes, b"GLOBAL_IDS GlobalElementId");
        let cell_data = line_of(&bytes, b"CELL_DATA 10");
        for (wrong, said) in [
            (
                "EDGE_FLAGS GlobalElementId vtkIdType",
                format!(
                    "line {line}: the `EDGE_FLAGS GlobalElementId vtkIdType` section is cell data \
                     (of `CELL_DATA 10`, line {cell_data}): VTK reads edge flags of point data only"
                ),
            ),
            (
                "GLOBAL_IDS GlobalElementId vtkIdTyqe",
                format!(
                    "line {line}: the `GLOBAL_IDS GlobalElementId vtkIdTyqe` section is of type \
                     `vtkIdTyqe`, which VTK's reader does not read"
                ),
            ),
            (
                "GLOBAL_IDS GlobalElementIdvtkIdType",
                format!(
                    "line {line}: `GLOBAL_IDS GlobalElementIdvtkIdType` is not `GLOBAL_IDS name \
                     type`"
                ),
            ),
        ] {
            let corrupt = replaced(
                &bytes,
                b"GLOBAL_IDS GlobalElementId vtkIdType",
                wrong.as_bytes(),
            );
            let message = refused(&corrupt, wrong);
            assert!(message.contains(&said), "{flavour}: {message}");
        }
        let before = replaced(&bytes, b"POINTS 35", b"GLOBAL_IDS g int\nPOINTS 35");
        let message = refused(&before, flavour);
        assert!(
            message.contains(&format!(
                "line {}: the `GLOBAL_IDS g int` section comes before any `POINT_DATA n` or \
                 `CELL_DATA n` line",
                line_of(&bytes, b"POINTS 35")
            )),
            "{flavour}: {message}"
        );
    }
}

/// Every cut of each file up to the end of its id sections, and every byte of those sections
/// (headers, values, METADATA) set to values that move a binary length or a line end, is refused
/// or reads as the whole body: never a panic, never another mesh. A file cut between whole
/// sections before its displacement reads as the body undeformed, as any legacy file cut there
/// does.
#[test]
fn every_cut_and_corrupt_id_byte_is_refused_or_reads_the_same_body() {
    for flavour in FLAVOURS {
        // Each file, its body, and the header after its last id section (none: the end).
        for (name, expected, after) in [
            ("ids", plain(flavour), "FIELD FieldData"),
            ("ids-alone", plain_alone(flavour), ""),
        ] {
            let bytes = file(&format!("{name}-{flavour}.vtk"));
            let what = format!("{name}-{flavour}");
            let undeformed = HexMesh {
                ghosts: Vec::new(),
                displacement: None,
                ..expected.clone()
            };
            let read = parse(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_same(&read, &expected, &what);
            let end = if after.is_empty() {
                bytes.len()
            } else {
                position(&bytes, after.as_bytes())
            };
            if !after.is_empty() {
                // Cut after the id sections of the point data, before the displacement.
                let read = parse(&bytes[..end]).unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_same(&read, &undeformed, &format!("{what}, cut at {end}"));
            }
            for cut in 0..end {
                if let Ok(read) = parse(&bytes[..cut]) {
                    let whole = if read.displacement.is_none() {
                        &undeformed
                    } else {
                        &expected
                    };
                    assert_same(&read, whole, &format!("{what}, cut at {cut}"));
                }
            }
            // From the first id section's header to the line end before the header after the
            // last (which would join that header: a corrupt name of the array after).
            let from = position(&bytes, b"CELL_DATA 10\n") + 13;
            let to = if after.is_empty() { end } else { end - 1 };
            for at in from..to {
                for value in [b'\n', b' ', b'x', b'7', 0x00, 0x41, 0x85, 0xc3] {
                    let mut corrupt = bytes.clone();
                    corrupt[at] = value;
                    if let Ok(read) = parse(&corrupt) {
                        assert_same(
                            &read,
                            &expected,
                            &format!("{what}, byte {at} set to {value:#x}"),
                        );
                    }
                }
            }
        }
    }
}
