//! Meshes written by VTK 9.7.2 itself (fixtures/vtk-written, made by its make.py): legacy ASCII
//! (VTK 5.1 layout) and binary; XML ascii, inline binary with zlib, raw appended, raw appended with
//! zlib, base64 appended with LZ4; LZMA inline (one block, and blocks of 2048 bytes with 64-bit
//! headers), raw appended (64-bit headers) and base64 appended; zlib and LZ4 in blocks that some
//! arrays fill exactly (a last block of 0 bytes). The same body in each: anisotropic
//! cells 1e3 from the origin, a
//! quarter of the cells missing, nodes and cells shuffled. Points made by VTK's side at known (cell, ξ)
//! must be located in that cell (the file's numbering) at that ξ. And empty grids in every
//! flavour, and a piece of no cell beside one with a cell.

use std::path::{Path, PathBuf};

use cgcontact::glam::DVec3;
use cgcontact::{LatticeLocator, Locator, Settings};
use cgcontact_io::{DisplacementArray, read_hex_mesh, read_mesh};

fn folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written")
}

/// known.csv: x,y,z,cell,xi,eta,zeta.
fn known() -> Vec<(DVec3, usize, DVec3)> {
    known_in("known.csv")
}

/// A file of points made at known (cell, ξ): x,y,z,cell,xi,eta,zeta.
fn known_in(file: &str) -> Vec<(DVec3, usize, DVec3)> {
    let text = std::fs::read_to_string(folder().join(file)).unwrap();
    text.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
            (
                DVec3::new(f[0], f[1], f[2]),
                f[3] as usize,
                DVec3::new(f[4], f[5], f[6]),
            )
        })
        .collect()
}

#[test]
fn every_flavour_vtk_writes_is_read_and_located_as_known() {
    let known = known();
    assert!(known.len() > 200);
    let files = [
        "legacy-ascii.vtk",
        "legacy-binary.vtk",
        "xml-ascii.vtu",
        "xml-binary-zlib.vtu",
        "xml-appended-raw.vtu",
        "xml-appended-raw-zlib.vtu",
        "xml-appended-base64-lz4.vtu",
        "xml-binary-lzma.vtu",
        "xml-binary-lzma-blocks.vtu",
        "xml-appended-raw-lzma-uint64.vtu",
        "xml-appended-base64-lzma.vtu",
        // Arrays that fill their blocks exactly (last block size 0 in the header): vtkio alone
        // dropped a block of each and refused the file.
        "xml-binary-zlib-whole-blocks.vtu",
        "xml-appended-raw-zlib-whole-blocks.vtu",
        "xml-appended-base64-lz4-whole-blocks.vtu",
    ];
    // VTK writes ASCII values to 11 significant digits (legacy) or its own precision (XML ascii):
    // binary flavours must agree bit for bit, ASCII ones to that rounding.
    let reference = read_mesh(
        folder().join("legacy-binary.vtk"),
        &DisplacementArray::Default,
    )
    .unwrap()
    .body
    .displacements()
    .to_vec();
    for file in files {
        let mesh = read_mesh(folder().join(file), &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(mesh.has_displacement, "{file}");
        assert_eq!(mesh.cells.len(), 99, "{file}");
        let lattice = mesh.body.lattice();
        assert!(
            (lattice.h() - DVec3::new(0.5, 0.25, 0.125))
                .abs()
                .max_element()
                < 1e-12,
            "{file}"
        );
        let displacements = mesh.body.displacements();
        if file.contains("ascii") {
            for (a, b) in displacements.iter().zip(&reference) {
                assert!(
                    (*a - *b).abs().max_element() <= 1e-10 * b.abs().max_element(),
                    "{file}: {a} vs {b}"
                );
            }
        } else {
            assert_eq!(displacements, reference.as_slice(), "{file}");
        }
        for settings in [Settings::default(), Settings::f32()] {
            let locator = LatticeLocator::new(&mesh.body, settings).unwrap();
            let bound = if settings == Settings::default() {
                1e-9
            } else {
                1e-4
            };
            for (x, cell, xi) in &known {
                let hit = locator
                    .locate(*x)
                    .unwrap()
                    .unwrap_or_else(|| panic!("{file}: {x} not found"));
                assert_eq!(mesh.input_cell(hit.cell), Some(*cell), "{file}: point {x}");
                assert!(
                    (hit.xi - *xi).abs().max_element() < bound,
                    "{file}: xi {} vs {xi}",
                    hit.xi
                );
            }
        }
    }
}

/// VTK's points are 32-bit floats unless told otherwise. With spacings no float holds exactly
/// (0.1, 0.3, 0.07), each node is off its lattice position by the float's rounding, and such a
/// mesh was refused as off the lattice (the tolerance was f64's rounding). Nodes that are all
/// floats now get the float's rounding as slack: both files (legacy ASCII, whose writer prints
/// 6 digits, and XML binary) read, each file cell on its lattice cell, and a cell's centre is
/// located in it.
#[test]
fn float_points_as_vtk_writes_them_by_default() {
    let text = std::fs::read_to_string(folder().join("float-cells.csv")).unwrap();
    let expected: Vec<[u32; 3]> = text
        .lines()
        .skip(1)
        .map(|line| {
            let v: Vec<u32> = line.split(',').map(|v| v.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    assert!(expected.len() > 40);
    let h = DVec3::new(0.1, 0.3, 0.07);
    for file in [
        "float-points-legacy-ascii.vtk",
        "float-points-xml-binary.vtu",
    ] {
        let mesh = read_mesh(folder().join(file), &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let lattice = *mesh.body.lattice();
        assert!(
            ((lattice.h() - h) / h).abs().max_element() < 1e-6,
            "{file}: {}",
            lattice.h()
        );
        let low = expected.iter().fold([u32::MAX; 3], |m, c| {
            [m[0].min(c[0]), m[1].min(c[1]), m[2].min(c[2])]
        });
        let locator = LatticeLocator::new(&mesh.body, Settings::default()).unwrap();
        for (input, ijk) in expected.iter().enumerate() {
            let cell = mesh.cells.lattice_cell(input).unwrap();
            let found = lattice.cell_ijk(cell).unwrap();
            assert_eq!(
                [0, 1, 2].map(|a| found[a] + low[a]),
                *ijk,
                "{file}: cell {input}"
            );
            let centre = lattice.node_position(found) + 0.5 * lattice.h();
            let hit = locator.locate(centre).unwrap().unwrap();
            assert_eq!(mesh.input_cell(hit.cell), Some(input), "{file}");
        }
    }
}

/// VTK's legacy ASCII writer prints doubles with 11 significant digits. On spacings no decimal
/// holds (1/3, 1/7, 1/9) near (1000, −2000, 3000) that leaves the nodes up to 5e-8 off their
/// lattice positions, and the file was refused ("node 0 at [1001.0, -1999.8571429, ..] is not on
/// the lattice"). It now reads, the print's offsets kept in the displacement: each point made
/// at a known (cell, ξ) from the exact values is found in that cell, at that ξ to the print's
/// rounding (5e-8 over cells of 1/9: 1e-6 of ξ).
#[test]
fn double_points_printed_with_11_digits_read() {
    let file = "thirds-legacy-ascii.vtk";
    let known = known_in("thirds-known.csv");
    assert!(known.len() > 100);
    let mesh = read_mesh(folder().join(file), &DisplacementArray::Default)
        .unwrap_or_else(|e| panic!("{file}: {e}"));
    let h = DVec3::new(1.0 / 3.0, 1.0 / 7.0, 1.0 / 9.0);
    // Found from the extreme planes, each rounded by the print.
    assert!(((mesh.body.lattice().h() - h) / h).abs().max_element() < 1e-6);
    let locator = LatticeLocator::new(&mesh.body, Settings::default()).unwrap();
    for (x, cell, xi) in &known {
        let hit = locator.locate(*x).unwrap().expect("a known point is found");
        assert_eq!(mesh.input_cell(hit.cell), Some(*cell), "point {x}");
        assert!(
            (hit.xi - *xi).abs().max_element() < 1e-6,
            "xi {} vs {xi}",
            hit.xi
        );
    }
}

/// The files VTK wrote with its LZMA compressor (`vtkLZMADataCompressor`, each block an .xz
/// stream) read as the uncompressed raw appended file of the same body: the same nodes, cells and
/// displacements, bit for bit. (vtkio, built without liblzma, refused them before `lzma_arrays`.)
#[test]
fn lzma_files_read_as_the_uncompressed_one() {
    let uncompressed = read_hex_mesh(
        folder().join("xml-appended-raw.vtu"),
        &DisplacementArray::Default,
    )
    .unwrap();
    assert!(uncompressed.displacement.is_some());
    for file in [
        "xml-binary-lzma.vtu",
        "xml-binary-lzma-blocks.vtu",
        "xml-appended-raw-lzma-uint64.vtu",
        "xml-appended-base64-lzma.vtu",
    ] {
        let text = std::fs::read(folder().join(file)).unwrap();
        assert!(
            text.windows(21).any(|w| w == b"vtkLZMADataCompressor"),
            "{file}"
        );
        let mesh = read_hex_mesh(folder().join(file), &DisplacementArray::Default)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(mesh == uncompressed, "{file}");
    }
}

/// Regression: an empty grid as VTK writes it was refused as malformed: "compressed array
/// `Points`: its header says 0 blocks of 32768 bytes" (VTK's header of an empty compressed array,
/// which vtkio cannot read), or for a legacy file, whose `POINTS 0 float` VTK follows by no cell
/// section, "line 12: the file ends before its data does". Every flavour now says the mesh has
/// no cells. A file of two pieces whose second is empty was refused the same way; the empty
/// piece is now skipped and the other read.
#[test]
fn empty_grids_have_no_cells_and_an_empty_piece_is_skipped() {
    use cgcontact_io::ErrorKind;
    for file in [
        "empty-xml-ascii.vtu",
        "empty-xml-binary.vtu",
        "empty-xml-appended.vtu",
        "empty-legacy-ascii.vtk",
        "empty-legacy-binary.vtk",
    ] {
        let error = read_mesh(folder().join(file), &DisplacementArray::Default)
            .err()
            .unwrap_or_else(|| panic!("{file} was read"));
        assert!(
            matches!(error.kind(), ErrorKind::NoCells),
            "{file}: {error}"
        );
        assert!(error.to_string().contains("no cells"), "{file}: {error}");
    }
    let file = "one-cell-and-an-empty-piece.vtu";
    let mesh = read_mesh(folder().join(file), &DisplacementArray::Default)
        .unwrap_or_else(|e| panic!("{file}: {e}"));
    assert_eq!(mesh.cells.len(), 1);
    let locator = LatticeLocator::new(&mesh.body, Settings::default()).unwrap();
    let hit = locator
        .locate(DVec3::new(0.75, 0.5, 0.25))
        .unwrap()
        .unwrap();
    assert_eq!(mesh.input_cell(hit.cell), Some(0));
    assert_eq!(hit.xi, DVec3::new(0.5, 0.0, -0.5));
}
