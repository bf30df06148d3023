//! Regression: vtkio's errors for a negative node number or offset ("Validation error:
//! InvalidDataFormat"), a `NumberOfCells` past 2^32 ("InvalidInt(ParseIntError { kind:
//! PosOverflow })") and a `NumberOfPoints` its `<Points>` array does not hold
//! ("DataArraySizeMismatch { name: \"\", ... }") named neither the array nor the attribute at
//! fault, nor a line. Each is now named, with its line.

use base64::Engine as _;
use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh};

use crate::common::{body_with_holes, vtu_ascii};

fn error(file: &str) -> String {
    parse_hex_mesh(file.as_bytes(), &DisplacementArray::Default)
        .unwrap_err()
        .to_string()
}

/// The 1-based line of the first `needle` in `text`.
fn line_of(text: &str, needle: &str) -> usize {
    1 + text[..text.find(needle).unwrap()].matches('\n').count()
}

#[test]
fn xml_counts_and_cell_values_vtk_cannot_read_name_their_array_or_attribute() {
    let mesh = HexMesh::from_body(&body_with_holes(
        DVec3::ZERO,
        DVec3::splat(0.5),
        [3, 2, 2],
        5,
    ));
    let (nodes, cells) = (mesh.points.len(), mesh.cells.len());
    let text = vtu_ascii(&mesh);
    let connectivity: Vec<String> = mesh.cells.iter().flatten().map(u32::to_string).collect();
    let offsets: Vec<String> = (1..=cells).map(|c| (8 * c).to_string()).collect();
    let piece = format!("NumberOfPoints=\"{nodes}\" NumberOfCells=\"{cells}\"");
    let cells_line = line_of(&text, "Name=\"connectivity\"");
    let offsets_line = line_of(&text, "Name=\"offsets\"");
    let piece_line = line_of(&text, "<Piece");
    let points_line = line_of(&text, "Name=\"Points\"");

    // A negative node number, as ascii and as inline binary.
    let negative = text.replacen(
        &connectivity.join(" "),
        &format!("{} -1", connectivity[..connectivity.len() - 1].join(" ")),
        1,
    );
    let mut binary = (8 * connectivity.len() as u64).to_le_bytes().to_vec();
    for (i, node) in mesh.cells.iter().flatten().enumerate() {
        let node = if i == 3 { -7 } else { i64::from(*node) };
        binary.extend(node.to_le_bytes());
    }
    let binary = text
        .replacen(
            "Name=\"connectivity\" format=\"ascii\"",
            "Name=\"connectivity\" format=\"binary\"",
            1,
        )
        .replacen(
            &connectivity.join(" "),
            &base64::engine::general_purpose::STANDARD.encode(binary),
            1,
        );
    let cases = [
        (negative, cells_line, vec!["`connectivity`", "-1"]),
        (binary, cells_line, vec!["`connectivity`", "-7 at index 3"]),
        (
            text.replacen(
                &offsets.join(" "),
                &format!("{} -8", offsets[..cells - 1].join(" ")),
                1,
            ),
            offsets_line,
            vec!["`offsets`", "-8"],
        ),
        (
            text.replacen(
                &piece,
                &format!("NumberOfPoints=\"{nodes}\" NumberOfCells=\"1000000000000\""),
                1,
            ),
            piece_line,
            vec!["NumberOfCells=`1000000000000`"],
        ),
        (
            text.replacen(
                &piece,
                &format!("NumberOfPoints=\"4000000000\" NumberOfCells=\"{cells}\""),
                1,
            ),
            points_line,
            vec!["<Points>", "NumberOfPoints=`4000000000`", "12000000000"],
        ),
    ];
    for (file, line, named) in cases {
        let message = error(&file);
        assert!(message.contains(&format!("line {line}: ")), "{message}");
        for name in named {
            assert!(message.contains(name), "{name}: {message}");
        }
        assert!(
            !message.contains("InvalidDataFormat")
                && !message.contains("InvalidInt")
                && !message.contains("name: \"\""),
            "{message}"
        );
    }
}
