//! Regression: the block-header check took each compressed appended array's text to run from its
//! offset to the next `<`, the end of all the appended data, and scanned it for that `<`: with
//! many arrays, quadratic. 4,000 arrays in 5.6 MB took 48 s; more did not finish. Each array's
//! text now ends at the next array's offset, found in the sorted offsets.

use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

use cgcontact_io::{DisplacementArray, parse_hex_mesh};

#[test]
fn many_compressed_appended_arrays_are_checked_in_linear_time() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/vtk-written/xml-appended-base64-lz4.vtu");
    let intact = std::fs::read_to_string(path).unwrap();
    let expected = parse_hex_mesh(intact.as_bytes(), &DisplacementArray::Default).unwrap();
    // 12,000 more point arrays sharing the displacement's block at offset 0, and 16 MB of base64
    // after the last block (vtkio reads each array from its offset and ignores what follows): the
    // old check scanned 12,000 × 16 MB (48 s in release for 4,000 × 5.6 MB).
    let copies: String = (0..12_000)
        .map(|i| {
            format!(
                "<DataArray type=\"Float64\" Name=\"copy{i}\" NumberOfComponents=\"3\" \
                 format=\"appended\" offset=\"0\"/>\n"
            )
        })
        .collect();
    let text = intact
        .replacen("<PointData>", &format!("<PointData>\n{copies}"), 1)
        .replacen(
            "</AppendedData>",
            &format!("{}\n</AppendedData>", "A".repeat(16 << 20)),
            1,
        );
    let (send, receive) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = send.send(parse_hex_mesh(text.as_bytes(), &DisplacementArray::Default));
    });
    // A bound against a hang, not a measurement: the check takes milliseconds now, minutes before.
    let mesh = receive
        .recv_timeout(Duration::from_secs(60))
        .expect("still checking after a minute: quadratic again?")
        .unwrap();
    assert_eq!(mesh.displacement, expected.displacement);
    assert_eq!(mesh.cells, expected.cells);
}
