//! Property tests, one per parser (`parse_hex_mesh`, `parse_points`, `parse_results`): arbitrary
//! bytes and mutated valid files never panic (an error value or a parse, nothing else), and valid
//! files round-trip. Case counts are bounded so the file runs in a few seconds in the test profile.

use crate::common;

use bitvec::vec::BitVec;
use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, Body, CellId, Hit, Lattice, Leaf};
use cgcontact_io::{
    CellMap, DisplacementArray, HexMesh, MeshFormat, parse_hex_mesh, parse_points, parse_results,
    write_adaptive_mesh, write_mesh, write_results_to,
};
use proptest::prelude::*;

/// A small displaced body with holes: 1–3 cells per axis, any origin and spacing a lattice allows.
fn body_strategy() -> impl Strategy<Value = Body> {
    (
        prop::array::uniform3(1u32..=3),
        prop::array::uniform3(-1e6f64..1e6),
        prop::array::uniform3(-6i32..6),
        any::<u64>(),
        0.0f64..0.3,
    )
        .prop_map(|(cells, origin, h_exp, mask, amplitude)| {
            let h = DVec3::from_array(h_exp.map(|e| 10f64.powi(e)));
            let lattice = Lattice::new(DVec3::from_array(origin), h, cells).unwrap();
            let mut active = BitVec::repeat(false, lattice.cell_count());
            for c in 0..lattice.cell_count() {
                active.set(c, (mask >> (c % 64)) & 1 == 1);
            }
            active.set(0, true);
            let mut body = Body::undeformed(lattice, active).unwrap();
            body.update_displacements(|n, _, u| {
                *u = h * amplitude * DVec3::new((n as f64).sin(), (n as f64 * 1.3).cos(), 0.5)
            })
            .unwrap();
            body
        })
}

const FORMATS: [MeshFormat; 4] = [
    MeshFormat::LegacyAscii,
    MeshFormat::LegacyBinary,
    MeshFormat::Xml,
    MeshFormat::XmlZlib,
];

/// A small adaptive body: 2–3 base cells along x and 1–3 along y and z (so that a base cell stays
/// unrefined: a file shows levels only relative to its coarsest cells), one of them refined
/// `depth` levels toward a corner (jumps of up to `depth` levels), any origin and spacing a
/// lattice allows.
fn adaptive_strategy() -> impl Strategy<Value = AdaptiveBody> {
    (
        (2u32..=3, 1u32..=3, 1u32..=3).prop_map(|(x, y, z)| [x, y, z]),
        prop::array::uniform3(-1e6f64..1e6),
        prop::array::uniform3(-6i32..6),
        1u8..=3,
        0.0f64..0.2,
    )
        .prop_map(|(cells, origin, h_exp, depth, amplitude)| {
            let h = DVec3::from_array(h_exp.map(|e| 10f64.powi(e)));
            let lattice = Lattice::new(DVec3::from_array(origin), h, cells).unwrap();
            let mut leaves: Vec<Leaf> = (1..lattice.cell_count() as u32)
                .map(|c| Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap()))
                .collect();
            common::probes::refine_corner(&mut leaves, depth.into());
            let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
            let fine = body.spacing(depth);
            body.update_independent(|n, _, u| {
                *u = fine * amplitude * DVec3::new((n as f64).sin(), (n as f64 * 1.3).cos(), 0.5)
            })
            .unwrap();
            body
        })
}

fn adaptive_bytes(body: &AdaptiveBody, format: MeshFormat) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("m.{}", format.extension()));
    write_adaptive_mesh(&path, body, format).unwrap();
    std::fs::read(path).unwrap()
}

fn mesh_bytes(body: &Body, format: MeshFormat) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("m.{}", format.extension()));
    write_mesh(&path, body, format).unwrap();
    std::fs::read(path).unwrap()
}

/// Up to 4 edits of a file: overwrite a byte, delete a range, duplicate a range, or cut the tail.
fn mutate(mut bytes: Vec<u8>, edits: &[(u8, usize, usize, u8)]) -> Vec<u8> {
    for &(kind, at, len, value) in edits {
        if bytes.is_empty() {
            break;
        }
        let at = at % bytes.len();
        let end = (at + len % 16).min(bytes.len());
        match kind % 5 {
            0 => bytes[at] = value,
            1 => {
                bytes.drain(at..end);
            }
            2 => {
                let copy = bytes[at..end].to_vec();
                bytes.splice(at..at, copy);
            }
            3 => bytes.truncate(at),
            // Digits, signs and separators: the edits most likely to keep a text file parseable.
            _ => bytes[at] = b"0123456789-+.e \n,"[value as usize % 17],
        }
    }
    bytes
}

fn edits() -> impl Strategy<Value = Vec<(u8, usize, usize, u8)>> {
    prop::collection::vec(
        (any::<u8>(), any::<usize>(), any::<usize>(), any::<u8>()),
        1..=4,
    )
}

fn read_any_mesh(bytes: &[u8]) {
    for displacement in [
        DisplacementArray::Default,
        DisplacementArray::Ignore,
        DisplacementArray::Named("displacement".into()),
        DisplacementArray::Named("nope".into()),
    ] {
        if let Ok(mesh) = parse_hex_mesh(bytes, &displacement) {
            let _ = mesh.to_lattice();
            let _ = mesh.to_body();
            let _ = mesh.to_adaptive();
        }
    }
}

fn points_text(points: &[[f64; 3]], header: bool) -> String {
    let mut text = if header {
        "x,y,z\n".to_owned()
    } else {
        String::new()
    };
    for p in points {
        text += &format!("{},{},{}\n", p[0], p[1], p[2]);
    }
    text
}

fn results_bytes(rows: &[(Option<u32>, [f64; 3], u32, f64)]) -> (Vec<u8>, CellMap) {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [4, 4, 4]).unwrap();
    let body = Body::full(lattice);
    let cells = CellMap::ascending(&body);
    let answers: Vec<cgcontact::Answer> = rows
        .iter()
        .map(|&(cell, xi, iterations, residual)| {
            Ok(cell.map(|c| Hit {
                cell: CellId(c),
                xi: DVec3::from_array(xi),
                iterations,
                residual,
                inversions: iterations + 1,
            }))
        })
        .collect();
    let mut out = Vec::new();
    write_results_to(&mut out, &answers, &cells).unwrap();
    (out, cells)
}

/// The hand-written flavours of `tests/common` (what VTK and ParaView write that our writer does
/// not): XML ascii, raw appended (plain, zlib and LZMA, 32- and 64-bit headers), legacy 4.2 with
/// VECTORS, legacy 5.1 with a FIELD array.
fn flavour_bytes(body: &Body, flavour: usize) -> Vec<u8> {
    let mesh = HexMesh::from_body(body);
    match flavour % 8 {
        0 => common::vtu_ascii(&mesh).into_bytes(),
        1 => common::vtu_raw_appended(&mesh, false, true, 4096),
        2 => common::vtu_raw_appended(&mesh, true, false, 4096),
        3 => common::vtu_raw_appended(&mesh, true, true, 4096),
        4 => common::legacy_ascii(&mesh, common::LegacyData::Vectors, false).into_bytes(),
        5 => common::legacy_ascii(&mesh, common::LegacyData::Field, true).into_bytes(),
        // Blocks of 64 bytes: several per array, a last one partial.
        6 => common::vtu_raw_appended_lzma(&mesh, false, 64),
        _ => common::vtu_raw_appended_lzma(&mesh, true, 4096),
    }
}

/// The files VTK 9.7.2 wrote with its LZMA compressor (fixtures/vtk-written and
/// fixtures/vtk-written-adaptive): LZMA2 chunks that compress, CRC32 checks, inline and appended
/// raw and base64, 32- and 64-bit headers, several blocks per array.
const VTK_LZMA_FILES: [&str; 7] = [
    "vtk-written/xml-binary-lzma.vtu",
    "vtk-written/xml-binary-lzma-blocks.vtu",
    "vtk-written/xml-appended-raw-lzma-uint64.vtu",
    "vtk-written/xml-appended-base64-lzma.vtu",
    "vtk-written-adaptive/sheared-1e5.appended-lzma.vtu",
    "vtk-written-adaptive/sheared-1e5.binary-lzma-uint64.vtu",
    "vtk-written-adaptive/sheared-m1e7.appended-base64-lzma.vtu",
];

fn vtk_lzma_file(index: usize) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(VTK_LZMA_FILES[index]);
    std::fs::read(path).unwrap()
}

/// The legacy files VTK 9.7.2 wrote with string arrays (fixtures/vtk-written-strings) and with
/// id sections (fixtures/vtk-written-ids), which are measured and blanked before vtkio parses
/// them: a mutation may move a binary length, a count or a line end.
const VTK_LEGACY_FILES: [&str; 12] = [
    "vtk-written-strings/strings-4.2-ascii.vtk",
    "vtk-written-strings/strings-4.2-binary.vtk",
    "vtk-written-strings/strings-5.1-ascii.vtk",
    "vtk-written-strings/strings-5.1-binary.vtk",
    "vtk-written-ids/ids-4.2-ascii.vtk",
    "vtk-written-ids/ids-4.2-binary.vtk",
    "vtk-written-ids/ids-5.1-ascii.vtk",
    "vtk-written-ids/ids-5.1-binary.vtk",
    "vtk-written-ids/ids-alone-4.2-ascii.vtk",
    "vtk-written-ids/ids-alone-4.2-binary.vtk",
    "vtk-written-ids/ids-alone-5.1-ascii.vtk",
    "vtk-written-ids/ids-alone-5.1-binary.vtk",
];

fn vtk_legacy_file(index: usize) -> Vec<u8> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(VTK_LEGACY_FILES[index]);
    std::fs::read(path).unwrap()
}

/// The byte range of the displacement array's data in an XML file: its inline text, or (appended)
/// the block its `offset` points to, up to the next array's.
fn displacement_range(bytes: &[u8]) -> Option<std::ops::Range<usize>> {
    let find = |needle: &[u8], from: usize| {
        bytes[from..]
            .windows(needle.len())
            .position(|w| w == needle)
            .map(|i| i + from)
    };
    let tag = find(b"Name=\"displacement\"", 0)?;
    let close = find(b">", tag)?;
    if bytes[close - 1] != b'/' {
        let end = find(b"</DataArray>", close)?;
        return Some(close + 1..end);
    }
    // Appended: from the block's start to the next block's (the Points array's offset).
    let offset_of = |from: usize| -> Option<usize> {
        let at = find(b"offset=\"", from)? + 8;
        let end = find(b"\"", at)?;
        std::str::from_utf8(&bytes[at..end]).ok()?.parse().ok()
    };
    let start = offset_of(tag)?;
    let next = offset_of(close)?;
    let data = find(b"_", find(b"<AppendedData", 0)?)? + 1;
    Some(data + start..data + next)
}

/// The `CGCONTACT_FUZZ_SCALE` multiplier (1 when unset or not a number).
fn fuzz_scale() -> u32 {
    std::env::var("CGCONTACT_FUZZ_SCALE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
}

proptest! {
    // `CGCONTACT_FUZZ_SCALE=N` runs N times the cases, to hunt rare inputs (it found the node-count
    // overflow of `HexMesh::to_lattice` at 100×; debug builds, which check overflow, are the ones to run).
    #![proptest_config(ProptestConfig { cases: 512 * fuzz_scale(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mesh_parser_never_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        read_any_mesh(&bytes);
        // The same bytes behind each format's signature, so they reach the parsers proper.
        for prefix in [&b"# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n"[..], b"<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">"] {
            let mut prefixed = prefix.to_vec();
            prefixed.extend_from_slice(&bytes);
            read_any_mesh(&prefixed);
        }
    }

    #[test]
    fn mesh_parser_never_panics_on_mutated_files(body in body_strategy(), format in 0usize..4, edits in edits()) {
        let bytes = mesh_bytes(&body, FORMATS[format]);
        read_any_mesh(&mutate(bytes, &edits));
    }

    #[test]
    fn adaptive_mesh_parser_never_panics_on_mutated_files(body in adaptive_strategy(), format in 0usize..4, edits in edits()) {
        let bytes = adaptive_bytes(&body, FORMATS[format]);
        read_any_mesh(&mutate(bytes, &edits));
    }

    #[test]
    fn adaptive_mesh_files_round_trip(body in adaptive_strategy(), format in 0usize..4) {
        let bytes = adaptive_bytes(&body, FORMATS[format]);
        let mesh = parse_hex_mesh(&bytes, &DisplacementArray::Default).unwrap();
        let read = mesh.to_adaptive().unwrap();
        prop_assert_eq!(read.body.leaves(), body.leaves());
        prop_assert_eq!(read.body.displacements(), body.displacements());
        prop_assert!(read.constraints.holds());
        prop_assert!(matches!(mesh.to_body().unwrap(), cgcontact_io::MeshBody::Adaptive(_)));
    }

    #[test]
    fn mesh_parser_never_panics_on_mutated_hand_written_flavours(body in body_strategy(), flavour in 0usize..8, edits in edits()) {
        read_any_mesh(&mutate(flavour_bytes(&body, flavour), &edits));
    }

    /// The LZMA files VTK wrote, mutated: an error value or a mesh, never a panic or an abort (a
    /// block header claiming terabytes, an .xz stream cut or corrupted).
    #[test]
    fn mesh_parser_never_panics_on_mutated_lzma_files_written_by_vtk(file in 0usize..VTK_LZMA_FILES.len(), edits in edits()) {
        read_any_mesh(&mutate(vtk_lzma_file(file), &edits));
    }

    /// The legacy files VTK wrote with string arrays and id sections, mutated: an error value or
    /// a mesh, never a panic.
    #[test]
    fn mesh_parser_never_panics_on_mutated_legacy_files_written_by_vtk(file in 0usize..VTK_LEGACY_FILES.len(), edits in edits()) {
        read_any_mesh(&mutate(vtk_legacy_file(file), &edits));
    }

    /// The silent drop: a file whose displacement array is corrupted (edits inside its data only)
    /// either fails to read or reads with a displacement, never as an undeformed mesh.
    #[test]
    fn corrupt_displacement_is_never_dropped_silently(body in body_strategy(), flavour in 0usize..8, edits in edits()) {
        let bytes = match flavour {
            // The XML flavours: ascii, raw appended (plain, zlib, LZMA), ours (inline base64).
            0..=3 | 6 | 7 => flavour_bytes(&body, flavour),
            _ => mesh_bytes(&body, MeshFormat::Xml),
        };
        let range = displacement_range(&bytes).expect("the files carry a displacement");
        let (head, rest) = bytes.split_at(range.start);
        let (data, tail) = rest.split_at(range.end - range.start);
        let mut corrupt = head.to_vec();
        corrupt.extend(mutate(data.to_vec(), &edits));
        corrupt.extend_from_slice(tail);
        for which in [DisplacementArray::Default, DisplacementArray::Named("displacement".into())] {
            if let Ok(mesh) = parse_hex_mesh(&corrupt, &which) {
                prop_assert!(mesh.displacement.is_some(), "read as undeformed, flavour {}", flavour);
            }
        }
    }

    #[test]
    fn mesh_files_round_trip(body in body_strategy(), format in 0usize..4) {
        let bytes = mesh_bytes(&body, FORMATS[format]);
        let mesh = parse_hex_mesh(&bytes, &DisplacementArray::Default).unwrap().to_lattice().unwrap();
        // The detected lattice may be smaller (trimmed to the active cells' box), so compare cell by
        // cell in the file's order: same count, same deformed corners. Node coordinates are stored
        // rounded, so positions agree to the rounding of the largest coordinate and to the detection
        // tolerance (1e-9 h); displacements are stored exactly.
        let written = CellMap::ascending(&body);
        prop_assert_eq!(mesh.cells.len(), written.len());
        let l = body.lattice();
        let magnitude = l.origin().abs().max(l.upper().abs()).max_element();
        let slack = 1e-9 * l.h() + DVec3::splat(8.0 * f64::EPSILON * magnitude) * 4.0;
        for input in 0..written.len() {
            let ours = body.corners(written.lattice_cell(input).unwrap()).unwrap();
            let theirs = mesh.body.corners(mesh.cells.lattice_cell(input).unwrap()).unwrap();
            for (p, q) in ours.iter().zip(&theirs) {
                prop_assert!((*p - *q).abs().cmple(slack).all(), "cell {input}: {p} vs {q}");
            }
        }
        let mut ours: Vec<[u64; 3]> = body.displacements().iter().map(|u| u.to_array().map(f64::to_bits)).collect();
        let mut theirs: Vec<[u64; 3]> = mesh.body.displacements().iter().map(|u| u.to_array().map(f64::to_bits)).collect();
        ours.sort_unstable();
        theirs.sort_unstable();
        prop_assert_eq!(ours, theirs);
    }

    #[test]
    fn points_parser_never_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_points(bytes.as_slice());
    }

    #[test]
    fn points_parser_never_panics_on_mutated_files(points in prop::collection::vec(prop::array::uniform3(any::<f64>()), 1..20), header: bool, edits in edits()) {
        let text = points_text(&points, header);
        let _ = parse_points(mutate(text.into_bytes(), &edits).as_slice());
    }

    #[test]
    fn points_round_trip(points in prop::collection::vec(prop::array::uniform3(any::<f64>()), 1..40), header: bool) {
        let text = points_text(&points, header);
        let parsed = parse_points(text.as_bytes()).unwrap();
        prop_assert_eq!(parsed.len(), points.len());
        for (p, q) in parsed.iter().zip(&points) {
            for axis in 0..3 {
                // Bitwise, NaN included (a NaN reads back as a NaN).
                prop_assert!(p[axis].to_bits() == q[axis].to_bits() || (p[axis].is_nan() && q[axis].is_nan()), "{} vs {}", p[axis], q[axis]);
            }
        }
    }

    #[test]
    fn results_parser_never_panics_on_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse_results(bytes.as_slice());
        let mut prefixed = b"point,cell,xi,eta,zeta\n".to_vec();
        prefixed.extend_from_slice(&bytes);
        let _ = parse_results(prefixed.as_slice());
    }

    #[test]
    fn results_parser_never_panics_on_mutated_files(rows in prop::collection::vec((prop::option::of(0u32..64), prop::array::uniform3(-1.0f64..=1.0), 0u32..30, 0.0f64..1e-9), 1..20), edits in edits()) {
        let (bytes, _) = results_bytes(&rows);
        let _ = parse_results(mutate(bytes, &edits).as_slice());
    }

    #[test]
    fn results_round_trip(rows in prop::collection::vec((prop::option::of(0u32..64), prop::array::uniform3(-1.0f64..=1.0), 0u32..30, 0.0f64..1e-9), 1..40)) {
        let (bytes, cells) = results_bytes(&rows);
        let parsed = parse_results(bytes.as_slice()).unwrap();
        prop_assert_eq!(parsed.len(), rows.len());
        for (i, (row, &(cell, xi, iterations, residual))) in parsed.iter().zip(&rows).enumerate() {
            prop_assert_eq!(row.point, i);
            prop_assert_eq!(row.cell, cell.and_then(|c| cells.input_cell(CellId(c))));
            if cell.is_some() {
                prop_assert_eq!(row.xi, DVec3::from_array(xi));
                prop_assert_eq!(row.iterations, iterations);
                prop_assert_eq!(row.residual, residual);
            } else {
                prop_assert!(row.xi.is_nan());
            }
        }
    }
}
