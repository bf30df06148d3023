//! Regression: a raw appended cell array that the reader never reads, holding more values than
//! its piece has cells, was refused ("the appended array `OriginalIds` holds 544 bytes (68
//! values), but NumberOfCells=65 ... asks for 520"), where the same mesh inline, compressed or
//! legacy read, and VTK's own reader reads it. vtkHyperTreeGridToUnstructuredGrid (VTK 9.7.2)
//! writes such an `OriginalIds` whenever the tree grid has masked cells: a value per leaf, masked
//! ones included. `vtkGhostType`, the one cell array the reader reads, is still held to the
//! piece's cell count.

use std::path::Path;

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

fn file() -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/vtk-written-htg/masked-1e5.appended.vtu"),
    )
    .unwrap()
}

fn renamed(file: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = file
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap();
    [&file[..at], to.as_bytes(), &file[at + from.len()..]].concat()
}

#[test]
fn an_unread_cell_array_may_hold_more_values_than_cells() {
    let file = file();
    let text = String::from_utf8_lossy(&file);
    assert!(text.contains("NumberOfCells=\"65\"") && text.contains("Name=\"OriginalIds\""));
    let mesh = parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
    assert_eq!(mesh.cells.len(), 65);
    // The same array as the ghost flags: refused, naming it and the counts.
    let ghost = renamed(&file, "Name=\"OriginalIds\"", "Name=\"vtkGhostType\"");
    let message = parse_hex_mesh(&ghost, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("`vtkGhostType` holds 544 bytes (68 values)")
            && message.contains("NumberOfCells=65"),
        "{message}"
    );
}

#[test]
fn an_unread_cell_array_holding_fewer_values_is_still_refused() {
    // NumberOfCells=69: the cell arrays (before the cells in the file) now hold fewer, `Depth`
    // (the source's, a value per cell) first.
    let file = renamed(&file(), "NumberOfCells=\"65\"", "NumberOfCells=\"69\"");
    let message = parse_hex_mesh(&file, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("`Depth` holds 520 bytes (65 values)")
            && message.contains("NumberOfCells=69"),
        "{message}"
    );
}
