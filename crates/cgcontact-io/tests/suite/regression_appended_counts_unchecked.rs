//! Regression: an uncompressed appended array holding more values than its `<Piece>` asks for was
//! read in part without a word. vtkio reads as many values as `NumberOfCells` or
//! `NumberOfPoints` ask and ignores the header's byte count, so a `NumberOfCells` one short read
//! one cell fewer and the points in it were outside the body, exit 0 (inline and compressed
//! arrays of the wrong size were already refused). Found by the black-box audit on a raw
//! appended file that VTK wrote.

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh};

use crate::common::{body_with_holes, vtu_raw_appended};

#[test]
fn appended_arrays_of_another_count_than_their_piece_asks_are_named() {
    let mesh = HexMesh::from_body(&body_with_holes(
        DVec3::ZERO,
        DVec3::splat(0.5),
        [3, 2, 2],
        5,
    ));
    let (nodes, cells) = (mesh.points.len(), mesh.cells.len());
    for header64 in [false, true] {
        let file = vtu_raw_appended(&mesh, false, header64, 1 << 15);
        let read = parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
        assert_eq!(read.cells.len(), cells);
        let text = |bytes: &[u8]| bytes.to_vec();
        let edit = |from: String, to: String| {
            let at = file
                .windows(from.len())
                .position(|w| w == from.as_bytes())
                .unwrap();
            [
                text(&file[..at]),
                to.into_bytes(),
                text(&file[at + from.len()..]),
            ]
            .concat()
        };
        for (count, attribute, shown) in [
            (cells - 1, "NumberOfCells", "`offsets`"),
            (cells + 1, "NumberOfCells", "`offsets`"),
            (nodes - 1, "NumberOfPoints", "NumberOfPoints"),
        ] {
            let all = if attribute == "NumberOfCells" {
                cells
            } else {
                nodes
            };
            let edited = edit(
                format!("{attribute}=\"{all}\""),
                format!("{attribute}=\"{count}\""),
            );
            let message = parse_hex_mesh(&edited, &DisplacementArray::Default)
                .unwrap_err()
                .to_string();
            assert!(
                message.contains(shown) && message.contains(&format!("{attribute}={count}")),
                "header64 {header64}, {attribute}={count}: {message}"
            );
        }
    }
}
