//! VTK's legacy writer names the types of unsigned 16-bit, signed 8-bit and 64-bit integer arrays
//! `unsigned_short`, `signed_char`, `vtktypeint64` and `vtktypeuint64`, which vtkio's parser does
//! not know: a valid file holding one such array anywhere (an id, a material number, a time
//! stamp) was refused as malformed, where the same data in a `.vtu` read. They are now read, in
//! ASCII and binary files, versions 4.2 and 5.1: each file VTK 9.7.2 wrote with them in its point,
//! cell and field data (fixtures/vtk-written-types, made by its make.py) reads as the same body
//! written without them, bit for bit; and a displacement of each type reads as VTK's `.vtu` of it
//! does, to the value (65535 is not −1).

use std::path::PathBuf;

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, MeshFile, read_hex_mesh};

use crate::common::legacy_fixtures::{self, FLAVOURS, assert_same, parse, position};

fn folder() -> PathBuf {
    legacy_fixtures::folder("vtk-written-types")
}

/// The headers of the arrays of the four types in `types-{flavour}.vtk`, in file order: the data
/// set's field data, cell data, point data.
const HEADERS: [&str; 12] = [
    "step 1 1 unsigned_short",
    "flag 1 2 signed_char",
    "time%20ns 1 2 vtktypeint64",
    "seed 1 1 vtktypeuint64",
    "SCALARS zone signed_char",
    "material 1 10 unsigned_short",
    "element 2 10 vtktypeint64",
    "hash 1 10 vtktypeuint64",
    "SCALARS code unsigned_short",
    "VECTORS offset vtktypeint64",
    "tag 1 35 signed_char",
    "serial 1 35 vtktypeuint64",
];

#[test]
fn arrays_of_the_types_vtk_writes_are_read_in_every_flavour() {
    for flavour in FLAVOURS {
        let name = format!("types-{flavour}.vtk");
        let bytes = legacy_fixtures::read(&folder(), &name);
        for header in HEADERS {
            position(&bytes, header.as_bytes());
        }
        let read = parse(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same(&read, &legacy_fixtures::plain(&folder(), flavour), &name);
        // From the file, as a body, with its point arrays named.
        let file = MeshFile::read(folder().join(&name)).unwrap();
        let read = file
            .into_body(&DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(read.body.has_displacement(), "{name}");
        assert_eq!(
            read.point_arrays,
            ["code", "displacement", "offset", "serial", "tag"],
            "{name}"
        );
    }
}

/// The 3-component `vtktypeint64` point array `offset` (`VECTORS`), read as the displacement:
/// its values, ±2^50 among them, exactly, in every flavour.
#[test]
fn a_64_bit_vector_reads_to_the_value() {
    let offset = DisplacementArray::Named("offset".to_owned());
    let mut first: Option<Vec<DVec3>> = None;
    for flavour in FLAVOURS {
        let name = format!("types-{flavour}.vtk");
        let bytes = legacy_fixtures::read(&folder(), &name);
        let mesh =
            cgcontact_io::parse_hex_mesh(&bytes, &offset).unwrap_or_else(|e| panic!("{name}: {e}"));
        let u = mesh.displacement.unwrap();
        let values: Vec<f64> = u.iter().flat_map(|v| v.to_array()).collect();
        assert!(values.contains(&-(2f64.powi(50))), "{name}");
        assert!(values.contains(&(2f64.powi(50) + 3.0)), "{name}");
        match &first {
            None => first = Some(u),
            Some(first) => assert_eq!(&u, first, "{name}"),
        }
    }
}

/// A displacement of each type reads as VTK's `.vtu` of the same array does, value for value,
/// each type's extremes included.
#[test]
fn integer_displacements_read_as_in_xml() {
    for (kind, extreme) in [
        ("u16", 65535.0),
        ("i8", -128.0),
        ("i64", -(2f64.powi(50))),
        ("u64", 2f64.powi(52) + 5.0),
    ] {
        let xml = read_hex_mesh(
            folder().join(format!("displacement-{kind}.vtu")),
            &DisplacementArray::Default,
        )
        .unwrap();
        let expected = xml.displacement.clone().unwrap();
        assert!(
            expected.iter().any(|v| v.to_array().contains(&extreme)),
            "{kind}"
        );
        for flavour in FLAVOURS {
            let name = format!("displacement-{kind}-{flavour}.vtk");
            let read = read_hex_mesh(folder().join(&name), &DisplacementArray::Default)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_same(&read, &xml, &name);
        }
    }
}

/// In a binary file an `unsigned_short` array is read as `short` and taken back as unsigned: a
/// `short` array of the same name in the other data (cell or point) stays signed.
#[test]
fn unsigned_and_signed_shorts_of_one_name_keep_their_signs() {
    let mut head = b"# vtk DataFile Version 4.2\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\n\
                     POINTS 8 double\n"
        .to_vec();
    for k in 0..8u8 {
        for axis in 0..3 {
            head.extend(f64::from((k >> axis) & 1).to_be_bytes());
        }
    }
    head.extend(b"\nCELLS 1 9\n");
    for v in [8u32, 0, 1, 3, 2, 4, 5, 7, 6] {
        head.extend(v.to_be_bytes());
    }
    head.extend(b"\nCELL_TYPES 1\n");
    head.extend(12u32.to_be_bytes());
    let array = |file: &mut Vec<u8>, header: &str, kind: &str, values: usize| {
        file.extend(format!("{header}\nFIELD FieldData 1\ndisplacement {kind}\n").as_bytes());
        for _ in 0..values {
            file.extend(0xFFFF_u16.to_be_bytes());
        }
        file.push(b'\n');
    };
    for (cell, point, expected) in [
        ("short", "unsigned_short", 65535.0),
        ("unsigned_short", "short", -1.0),
    ] {
        let mut file = head.clone();
        array(&mut file, "\nCELL_DATA 1", &format!("1 1 {cell}"), 1);
        array(&mut file, "POINT_DATA 8", &format!("3 8 {point}"), 24);
        let mesh = parse(&file).unwrap_or_else(|e| panic!("{point}: {e}"));
        let u = mesh.displacement.unwrap();
        assert!(u.iter().all(|v| *v == DVec3::splat(expected)), "{point}");
    }
}
