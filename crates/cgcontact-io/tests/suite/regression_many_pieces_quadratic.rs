//! Regression: the check of uncompressed appended arrays against their piece counted the line of
//! each `<Piece>` from the start of the file, for every file: quadratic in the pieces. A raw
//! appended `.vtu` of 20,000 one-cell pieces (14 MB) took 35 s to read in release, against 0.7 s
//! now; lines are counted only for a message. This test's 40,000 pieces read in 1.5 s; counting
//! each piece's line again, it ran past its 30 s guard.

use std::sync::mpsc;
use std::time::Duration;

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

/// `pieces` unit cells side by side along x, one per `<Piece>`, raw appended, uncompressed.
fn many_pieces(pieces: u32) -> Vec<u8> {
    let mut xml = String::from(
        "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" \
         header_type=\"UInt64\">\n<UnstructuredGrid>\n",
    );
    let mut data = Vec::new();
    for p in 0..pieces {
        let x = f64::from(p);
        let corners = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
        let points: Vec<u8> = [0.0, 1.0]
            .iter()
            .flat_map(|&z| corners.iter().map(move |c| [x + c[0], c[1], z]))
            .flatten()
            .flat_map(f64::to_le_bytes)
            .collect();
        let connectivity: Vec<u8> = (0..8i64).flat_map(i64::to_le_bytes).collect();
        let mut tags = Vec::new();
        for (name, kind, components, bytes) in [
            ("Points", "Float64", " NumberOfComponents=\"3\"", points),
            ("connectivity", "Int64", "", connectivity),
            ("offsets", "Int64", "", 8i64.to_le_bytes().to_vec()),
            ("types", "UInt8", "", vec![12]),
        ] {
            tags.push(format!(
                "<DataArray type=\"{kind}\" Name=\"{name}\"{components} format=\"appended\" \
                 offset=\"{}\"/>",
                data.len()
            ));
            data.extend((bytes.len() as u64).to_le_bytes());
            data.extend(bytes);
        }
        xml.push_str(&format!(
            "<Piece NumberOfPoints=\"8\" NumberOfCells=\"1\">\n<Points>{}</Points>\n\
             <Cells>{}{}{}</Cells>\n</Piece>\n",
            tags[0], tags[1], tags[2], tags[3]
        ));
    }
    xml.push_str("</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_");
    let mut file = xml.into_bytes();
    file.extend(data);
    file.extend(b"\n</AppendedData>\n</VTKFile>\n");
    file
}

#[test]
fn a_file_of_many_pieces_is_read_in_linear_time() {
    let file = many_pieces(40_000);
    let (done, finished) = mpsc::channel();
    std::thread::spawn(move || {
        let mesh = parse_hex_mesh(&file, &DisplacementArray::Default).map(|m| m.cells.len());
        done.send(mesh).unwrap();
    });
    // A guard against the quadratic scan, not a timing: the whole read takes a second or two in
    // the test build, the old scan minutes.
    let cells = finished
        .recv_timeout(Duration::from_secs(30))
        .expect("40,000 pieces read within 30 s")
        .unwrap();
    assert_eq!(cells, 40_000);
}
