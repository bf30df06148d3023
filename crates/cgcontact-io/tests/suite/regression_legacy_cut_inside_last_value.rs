//! Regression: a legacy ASCII file cut inside its last number (`0.0123456789` cut to `0.012`)
//! read without an error, that number shortened into another value: every count was still whole.
//! VTK's writer ends every line, the last included, so a file that ends in a value with no line
//! end after it is now an error naming the last line; the same file with its line end reads.

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, parse_hex_mesh};

use crate::common::legacy_fixtures::{folder, read};
use crate::common::{LegacyData, body_with_holes, legacy_ascii};

/// ASCII legacy files written by VTK (displacements last, string arrays last, id sections last)
/// and by the tests' own writer.
fn files() -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = [
        "vtk-written/legacy-ascii.vtk",
        "vtk-written/float-points-legacy-ascii.vtk",
        "vtk-written-adaptive/aniso-1e3.legacy-ascii.vtk",
        "vtk-written-strings/plain-4.2-ascii.vtk",
        "vtk-written-strings/strings-5.1-ascii.vtk",
        "vtk-written-ids/ids-4.2-ascii.vtk",
        "vtk-written-ids/ids-alone-5.1-ascii.vtk",
    ]
    .iter()
    .map(|name| {
        let (dir, file) = name.split_once('/').unwrap();
        (name.to_string(), read(&folder(dir), file))
    })
    .collect();
    let body = body_with_holes(DVec3::new(1.0, -2.0, 0.5), DVec3::splat(0.25), [3, 2, 2], 4);
    let mesh = HexMesh::from_body(&body);
    for (name, data) in [
        ("vectors", LegacyData::Vectors),
        ("field", LegacyData::Field),
    ] {
        files.push((
            name.to_owned(),
            legacy_ascii(&mesh, data, false).into_bytes(),
        ));
    }
    files
}

#[test]
fn a_legacy_ascii_file_cut_inside_its_last_value_is_refused() {
    for (name, file) in files() {
        let whole = parse_hex_mesh(&file, &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        // The file without its final line end(s), then cut inside its last word.
        let end = file.iter().rposition(|b| !b.is_ascii_whitespace()).unwrap() + 1;
        let word = file[..end]
            .iter()
            .rposition(u8::is_ascii_whitespace)
            .unwrap()
            + 1;
        let lines = 1 + file[..end].iter().filter(|&&b| b == b'\n').count();
        for cut in word + 1..=end {
            let error = parse_hex_mesh(&file[..cut], &DisplacementArray::Default)
                .map(|_| ())
                .expect_err(&format!("{name} cut to {cut} of {} bytes", file.len()))
                .to_string();
            // A cut that leaves no number (`-`, `1e`) is a section short of its values; any
            // other is the new error, on the last line.
            let named = error.contains(&format!("line {lines}: the file ends in"))
                && error.contains("cut inside its last value");
            assert!(
                named || (cut < end && error.contains("the file is cut")),
                "{name} cut to {cut}: {error}"
            );
        }
        // The same file with a line end after the whole last value reads as before: only the line
        // end tells a whole file from a cut one.
        let mut ended = file[..end].to_vec();
        ended.extend_from_slice(b"\r\n");
        let again = parse_hex_mesh(&ended, &DisplacementArray::Default).unwrap();
        assert_eq!(again.points, whole.points, "{name}");
        assert_eq!(again.cells, whole.cells, "{name}");
        assert_eq!(
            again.displacement.map(|u| u
                .iter()
                .map(|v| v.to_array().map(f64::to_bits))
                .collect::<Vec<_>>()),
            whole.displacement.map(|u| u
                .iter()
                .map(|v| v.to_array().map(f64::to_bits))
                .collect::<Vec<_>>()),
            "{name}"
        );
    }
}

/// A file VTK wrote, cut inside its last `METADATA` block (`INFORMATION` lines after the
/// displacement), at every byte of its last 3 lines: an error, and never one quoting an empty
/// excerpt (it said "line 71: cannot parse `` there" where the parser stopped at the end of the
/// file).
#[test]
fn a_file_cut_inside_its_last_metadata_says_it_ends() {
    let file = read(
        &folder("vtk-written-adaptive"),
        "float32-huge.legacy-ascii.vtk",
    );
    parse_hex_mesh(&file, &DisplacementArray::Default).unwrap();
    let meta = file
        .windows(9)
        .rposition(|w| w == b"METADATA\n")
        .expect("VTK wrote a METADATA block last");
    let mut ends = 0;
    for cut in meta + 9..file.len() - 4 {
        let Err(error) = parse_hex_mesh(&file[..cut], &DisplacementArray::Default) else {
            continue;
        };
        let error = error.to_string();
        assert!(!error.contains("``"), "cut at {cut}: {error}");
        ends += usize::from(error.contains("the file ends"));
    }
    assert!(ends > 0, "no cut said the file ends");
}
