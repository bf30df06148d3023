//! VTK writes a legacy file's points in their own type, an integer one for a `vtkPoints` of ints
//! (`POINTS 8 int`). vtkio's parser reads float and double points only, and the file was refused as
//! "cannot parse `0 0 0 1 0 0 ...` there", quoting the first coordinates as if they were the fault.
//! The message now names the header, the type, and what to write instead (an XML file of integer
//! points reads).

use cgcontact::CORNER_OFFSETS;

use crate::common::legacy_fixtures::parse;

/// One unit cube, its points of type `kind`, in an ASCII or a big-endian binary legacy file.
fn cube(kind: &str, binary: bool) -> Vec<u8> {
    // The unit cube's corners in VTK order, as integers.
    let corners = CORNER_OFFSETS.map(|corner| corner.map(|v| v as i32));
    let mode = if binary { "BINARY" } else { "ASCII" };
    let mut file = format!(
        "# vtk DataFile Version 4.2\ncube\n{mode}\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 {kind}\n"
    )
    .into_bytes();
    if binary {
        for value in corners.iter().flatten() {
            file.extend(value.to_be_bytes());
        }
        file.extend(b"\nCELLS 1 9\n");
        for value in [8, 0, 1, 2, 3, 4, 5, 6, 7] {
            file.extend(i32::to_be_bytes(value));
        }
        file.extend(b"\nCELL_TYPES 1\n");
        file.extend(12i32.to_be_bytes());
        file.push(b'\n');
    } else {
        for corner in corners {
            file.extend(format!("{} {} {}\n", corner[0], corner[1], corner[2]).bytes());
        }
        file.extend(b"CELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\n");
    }
    file
}

#[test]
fn integer_points_are_named_with_their_type() {
    // The same cube with float points reads (ASCII: the binary values are written as integers).
    let mesh = parse(&cube("float", false)).unwrap();
    assert_eq!(mesh.cells.len(), 1);
    for binary in [false, true] {
        let message = parse(&cube("int", binary)).unwrap_err();
        assert!(
            message.contains("line 5: `POINTS 8 int`: points of type int")
                && message.contains("float or double"),
            "binary {binary}: {message}"
        );
    }
}
