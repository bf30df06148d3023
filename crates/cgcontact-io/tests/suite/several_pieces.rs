//! XML files with several `<Piece>`s are read as one mesh, the pieces' nodes and cells
//! concatenated in order (docs/formats.md). A piece without the displacement that another piece
//! has used to be read as undeformed, without a word: its cells were solved with zero
//! displacement. That is now an error naming the piece and the array.

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, ErrorKind, parse_hex_mesh};

/// One unit cube with its lowest corner at `corner0`, in VTK corner order.
fn cube(corner0: DVec3) -> Vec<DVec3> {
    [
        (0, 0, 0),
        (1, 0, 0),
        (1, 1, 0),
        (0, 1, 0),
        (0, 0, 1),
        (1, 0, 1),
        (1, 1, 1),
        (0, 1, 1),
    ]
    .map(|(x, y, z)| corner0 + DVec3::new(f64::from(x), f64::from(y), f64::from(z)))
    .to_vec()
}

fn join(values: impl IntoIterator<Item = f64>) -> String {
    values
        .into_iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(" ")
}

/// A `<Piece>` holding one cube at `corner0`, with the displacement `u` at every node if given.
fn piece(corner0: DVec3, u: Option<DVec3>) -> String {
    let points = cube(corner0);
    let mut s =
        "    <Piece NumberOfPoints=\"8\" NumberOfCells=\"1\">\n      <PointData>\n".to_owned();
    if let Some(u) = u {
        s += "        <DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">";
        s += &join(std::iter::repeat_n(u.to_array(), 8).flatten());
        s += "</DataArray>\n";
    }
    s += "      </PointData>\n      <Points>\n        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">";
    s += &join(points.iter().flat_map(|p| p.to_array()));
    s += "</DataArray>\n      </Points>\n      <Cells>\n";
    s += "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 4 5 6 7</DataArray>\n";
    s += "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">8</DataArray>\n";
    s += "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">12</DataArray>\n";
    s += "      </Cells>\n    </Piece>\n";
    s
}

fn file(pieces: &[String]) -> String {
    format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n  <UnstructuredGrid>\n{}  </UnstructuredGrid>\n</VTKFile>\n",
        pieces.concat()
    )
}

/// Two cubes apart, each in its own piece: nodes and cells concatenated, each with its piece's
/// displacement.
#[test]
fn pieces_are_concatenated_in_order() {
    let (u0, u1) = (DVec3::new(0.1, 0.0, -0.05), DVec3::new(0.0, 0.2, 0.0));
    let text = file(&[
        piece(DVec3::ZERO, Some(u0)),
        piece(DVec3::new(3.0, 0.0, 0.0), Some(u1)),
    ]);
    let mesh = parse_hex_mesh(text.as_bytes(), &DisplacementArray::Default).unwrap();
    let expected_points: Vec<DVec3> = [cube(DVec3::ZERO), cube(DVec3::new(3.0, 0.0, 0.0))].concat();
    assert_eq!(mesh.points, expected_points);
    assert_eq!(
        mesh.cells,
        vec![[0, 1, 2, 3, 4, 5, 6, 7], [8, 9, 10, 11, 12, 13, 14, 15]]
    );
    let expected_u: Vec<DVec3> = [vec![u0; 8], vec![u1; 8]].concat();
    assert_eq!(mesh.displacement, Some(expected_u));
    let lattice = mesh.to_lattice().unwrap();
    assert_eq!(lattice.body.lattice().cells(), [4, 1, 1]);
}

/// One piece with the displacement and one without: which nodes move is unknown, so the file is
/// refused, naming the piece and the array, whichever piece lacks it and however it is asked for.
#[test]
fn a_piece_missing_the_displacement_another_has_is_an_error() {
    let u = Some(DVec3::new(0.1, 0.0, -0.05));
    let (near, far) = (DVec3::ZERO, DVec3::new(3.0, 0.0, 0.0));
    for (text, missing) in [
        (file(&[piece(near, u), piece(far, None)]), 1),
        (file(&[piece(near, None), piece(far, u)]), 0),
    ] {
        for which in [
            DisplacementArray::Default,
            DisplacementArray::Named("displacement".to_owned()),
        ] {
            let error = parse_hex_mesh(text.as_bytes(), &which).unwrap_err();
            assert!(
                matches!(&error, ErrorKind::BadDisplacement { name, .. } if name == "displacement"),
                "{error}"
            );
            let message = error.to_string();
            assert!(message.contains(&format!("piece {missing}")), "{message}");
        }
        // Asked to ignore the displacement, the file reads (undeformed).
        let mesh = parse_hex_mesh(text.as_bytes(), &DisplacementArray::Ignore).unwrap();
        assert_eq!(mesh.displacement, None);
    }
    // No piece with it: an undeformed mesh, as for one piece.
    let text = file(&[piece(near, None), piece(far, None)]);
    let mesh = parse_hex_mesh(text.as_bytes(), &DisplacementArray::Default).unwrap();
    assert_eq!(mesh.displacement, None);
}
