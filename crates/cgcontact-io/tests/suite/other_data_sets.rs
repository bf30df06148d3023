//! Data sets other than unstructured grids, as VTK 9.7.2 writes them
//! (fixtures/vtk-written-other, made by its make.py): each is refused naming what it holds. Poly
//! data was refused for a "corrupt" block header (its empty vertex and line arrays are compressed
//! arrays of 0 blocks), and a multiblock file with vtkio's list of the types it knows.

use std::path::Path;

use cgcontact_io::{DisplacementArray, read_mesh};

#[test]
fn each_data_set_vtk_writes_is_named() {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written-other");
    for (file, what) in [
        ("image.vti", "image data (.vti)"),
        ("surface.vtp", "polygonal data (.vtp)"),
        ("structured.vts", "a structured grid (.vts)"),
        ("rectilinear.vtr", "a rectilinear grid (.vtr)"),
        (
            "blocks.vtm",
            "a multiblock data set (.vtm; give the .vtu of its block)",
        ),
    ] {
        let message = read_mesh(folder.join(file), &DisplacementArray::Default)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains(&format!("the data set is {what}")),
            "{file}: {message}"
        );
        assert!(
            message.ends_with("expected an unstructured grid"),
            "{file}: {message}"
        );
    }
    // The multiblock's block itself is an unstructured grid of hexahedra, and reads.
    let block = read_mesh(
        folder.join("blocks/blocks_0.vtu"),
        &DisplacementArray::Default,
    )
    .unwrap();
    assert_eq!(block.cells.len(), 8);
}
