//! Parallel files (`.pvtu`) written by VTK 9.7.2 itself (fixtures/vtk-written-parallel, made by its
//! make.py): a body split into 3 pieces by VTK's piece filter, in raw appended, inline binary and
//! ascii pieces; the same with a ghost level; pieces of no cell; an adaptive body in 2 pieces, and
//! with a ghost level. Ghost copies read as the cells they copy. And
//! hostile parallel files made here from them: each piece file is read as a mesh file of its own
//! is (the size limit, the format sniffed from its first bytes, every check of a serial file), so
//! a piece that is a device, a missing file, a legacy file or a parallel file itself is refused,
//! naming the piece.

use std::path::{Path, PathBuf};

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveLocator, LatticeLocator, Locator, Settings};
use cgcontact_io::{
    AdaptiveMesh, DisplacementArray, MeshBody, MeshFile, parse_hex_mesh, read_body, read_hex_mesh,
    read_mesh,
};

fn folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/vtk-written-parallel")
}

/// `NAME.centres.csv`: every cell's centre, in the order VTK's own reader numbers the cells.
fn centres(name: &str) -> Vec<DVec3> {
    centres_and_ghosts(name)
        .into_iter()
        .map(|(x, _)| x)
        .collect()
}

/// `NAME.centres.csv`: every cell's centre and whether VTK's reader flags it a ghost copy.
fn centres_and_ghosts(name: &str) -> Vec<(DVec3, bool)> {
    let text = std::fs::read_to_string(folder().join(format!("{name}.centres.csv"))).unwrap();
    text.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
            (DVec3::new(f[1], f[2], f[3]), f[4] == 1.0)
        })
        .collect()
}

/// For each cell of `cells` (centre, ghost flag), the cell answers name: the first copy at its
/// centre not flagged a ghost, else the first copy.
fn answering(cells: &[(DVec3, bool)]) -> Vec<usize> {
    cells
        .iter()
        .map(|(x, _)| {
            let copies = || (0..cells.len()).filter(|&c| cells[c].0 == *x);
            copies()
                .find(|&c| !cells[c].1)
                .unwrap_or_else(|| copies().next().unwrap())
        })
        .collect()
}

/// The input cell holding each of `points` (undeformed mesh), and its ξ.
fn located(path: &Path, points: &[DVec3]) -> Vec<(usize, DVec3)> {
    let body = read_body(path, &DisplacementArray::Ignore)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    points
        .iter()
        .map(|&x| match &body {
            MeshBody::Uniform(mesh) => {
                let hit = LatticeLocator::new(&mesh.body, Settings::default())
                    .unwrap()
                    .locate(x)
                    .unwrap()
                    .unwrap();
                (mesh.input_cell(hit.cell).unwrap(), hit.xi)
            }
            MeshBody::Adaptive(mesh) => {
                let hit = AdaptiveLocator::new(&mesh.body, Settings::default())
                    .unwrap()
                    .locate(x)
                    .unwrap()
                    .unwrap();
                (mesh.cells.input_cell(hit.cell).unwrap(), hit.xi)
            }
        })
        .collect()
}

#[test]
fn pieces_are_numbered_as_vtk_numbers_them_and_make_the_whole_body() {
    let whole = read_mesh(folder().join("whole.vtu"), &DisplacementArray::Default).unwrap();
    for name in ["split-appended", "split-binary", "split-ascii"] {
        let path = folder().join(format!("{name}.pvtu"));
        let mesh =
            read_mesh(&path, &DisplacementArray::Default).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(mesh.has_displacement, "{name}");
        // The same lattice, cells and displacements as the body written in one file (the pieces'
        // float points hold this lattice's values exactly; ascii prints the doubles in full).
        let (body, reference) = (&mesh.body, &whole.body);
        assert_eq!(body.lattice(), reference.lattice(), "{name}");
        assert!(body.active_cells().eq(reference.active_cells()), "{name}");
        assert!(body.nodes().eq(reference.nodes()), "{name}");
        assert_eq!(body.displacements(), reference.displacements(), "{name}");
        // Each cell where VTK's reader puts it: its centre is located in it, at ξ = 0.
        let centres = centres(name);
        assert_eq!(centres.len(), mesh.cells.len(), "{name}");
        for (cell, (found, xi)) in located(&path, &centres).into_iter().enumerate() {
            assert_eq!(found, cell, "{name}: centre {}", centres[cell]);
            assert!(
                xi.abs().max_element() < 1e-12,
                "{name}: cell {cell}: ξ {xi}"
            );
        }
    }
}

/// The adaptive body of the parallel file `path`, and `adaptive-whole.vtu`'s.
fn with_the_whole_adaptive_body(path: &Path) -> (AdaptiveMesh, AdaptiveMesh) {
    let adaptive = |path: &Path| match read_body(path, &DisplacementArray::Default).unwrap() {
        MeshBody::Adaptive(mesh) => mesh,
        MeshBody::Uniform(_) => panic!("{}: not read as adaptive", path.display()),
    };
    (
        adaptive(path),
        adaptive(&folder().join("adaptive-whole.vtu")),
    )
}

#[test]
fn an_adaptive_body_in_pieces_is_the_one_in_one_file() {
    let path = folder().join("adaptive.pvtu");
    let (split, whole) = with_the_whole_adaptive_body(&path);
    assert_eq!(split.body.cell_count(), 32);
    assert_eq!(split.body.node_count(), whole.body.node_count());
    assert_eq!(
        split.body.hanging_nodes().count(),
        whole.body.hanging_nodes().count()
    );
    assert!(split.constraints.holds());
    let centres = centres("adaptive");
    assert_eq!(centres.len(), 32);
    for (cell, (found, xi)) in located(&path, &centres).into_iter().enumerate() {
        assert_eq!(found, cell, "centre {}", centres[cell]);
        assert!(xi.abs().max_element() < 1e-12, "cell {cell}: ξ {xi}");
    }
}

#[test]
fn pieces_of_no_cell_add_nothing() {
    let path = folder().join("empty-pieces.pvtu");
    let mesh = read_mesh(&path, &DisplacementArray::Default).unwrap();
    assert_eq!(mesh.cells.len(), 2);
    let centres = centres("empty-pieces");
    for (cell, (found, _)) in located(&path, &centres).into_iter().enumerate() {
        assert_eq!(found, cell);
    }
}

#[test]
fn ghost_copies_are_read_as_the_cells_they_copy() {
    let whole = read_mesh(folder().join("whole.vtu"), &DisplacementArray::Default).unwrap();
    let path = folder().join("ghosts.pvtu");
    let cells = centres_and_ghosts("ghosts");
    // The ghosts as VTK's reader flags them.
    let flagged: Vec<u32> = (0..cells.len() as u32)
        .filter(|&c| cells[c as usize].1)
        .collect();
    assert_eq!(
        read_hex_mesh(&path, &DisplacementArray::Default)
            .unwrap()
            .ghosts,
        flagged
    );
    assert!(flagged.len() > 100);
    let mesh = read_mesh(&path, &DisplacementArray::Default).unwrap();
    assert_eq!(mesh.cells.len(), cells.len());
    assert_eq!(mesh.body.lattice(), whole.body.lattice());
    assert!(mesh.body.active_cells().eq(whole.body.active_cells()));
    assert_eq!(mesh.body.displacements(), whole.body.displacements());
    let centres: Vec<DVec3> = cells.iter().map(|c| c.0).collect();
    for (cell, ((found, xi), owner)) in located(&path, &centres)
        .into_iter()
        .zip(answering(&cells))
        .enumerate()
    {
        assert_eq!(found, owner, "cell {cell} at {}", centres[cell]);
        assert!(!cells[found].1, "cell {cell}: answered as a ghost");
        assert!(xi.abs().max_element() < 1e-12, "cell {cell}: ξ {xi}");
    }
}

#[test]
fn ghost_copies_of_leaves_are_read_as_the_leaves_they_copy() {
    let path = folder().join("adaptive-ghosts.pvtu");
    let (split, whole) = with_the_whole_adaptive_body(&path);
    let cells = centres_and_ghosts("adaptive-ghosts");
    assert_eq!(cells.iter().filter(|c| c.1).count(), 32);
    assert_eq!(split.cells.len(), 64);
    assert_eq!(split.body.cell_count(), 32);
    assert_eq!(split.body.node_count(), whole.body.node_count());
    assert_eq!(split.body.displacements(), whole.body.displacements());
    assert!(split.constraints.holds());
    let centres: Vec<DVec3> = cells.iter().map(|c| c.0).collect();
    for (cell, ((found, _), owner)) in located(&path, &centres)
        .into_iter()
        .zip(answering(&cells))
        .enumerate()
    {
        assert_eq!(found, owner, "cell {cell} at {}", centres[cell]);
    }
}

/// A legacy ASCII file of `cells` (each a cube: low corner and edge, nodes unmerged) with the
/// cell array vtkGhostType holding `flags`.
fn legacy_with_ghosts(cells: &[(DVec3, f64)], flags: &[u8]) -> String {
    let mut text = format!(
        "# vtk DataFile Version 4.2\nghosts\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
        8 * cells.len()
    );
    for (low, edge) in cells {
        for (a, b, c) in [
            (0., 0., 0.),
            (1., 0., 0.),
            (1., 1., 0.),
            (0., 1., 0.),
            (0., 0., 1.),
            (1., 0., 1.),
            (1., 1., 1.),
            (0., 1., 1.),
        ] {
            let p = *low + *edge * DVec3::new(a, b, c);
            text += &format!("{} {} {}\n", p.x, p.y, p.z);
        }
    }
    text += &format!("CELLS {} {}\n", cells.len(), 9 * cells.len());
    for c in 0..cells.len() {
        text += "8";
        for n in 0..8 {
            text += &format!(" {}", 8 * c + n);
        }
        text += "\n";
    }
    text += &format!("CELL_TYPES {}\n", cells.len());
    text += &"12\n".repeat(cells.len());
    text += &format!(
        "CELL_DATA {}\nSCALARS vtkGhostType unsigned_char 1\nLOOKUP_TABLE default\n",
        cells.len()
    );
    for f in flags {
        text += &format!("{f}\n");
    }
    text
}

#[test]
fn ghosts_given_out_of_order_or_beyond_the_cells_are_refused() {
    let mut mesh =
        read_hex_mesh(folder().join("ghosts.pvtu"), &DisplacementArray::Default).unwrap();
    assert!(mesh.to_body().is_ok());
    let sorted = mesh.ghosts.clone();
    mesh.ghosts.reverse();
    for ghosts in [
        mesh.ghosts.clone(),
        vec![sorted[0], sorted[0]],
        vec![mesh.cells.len() as u32],
    ] {
        mesh.ghosts = ghosts;
        for message in [
            mesh.to_lattice().unwrap_err(),
            mesh.to_adaptive().unwrap_err(),
        ] {
            let message = message.to_string();
            assert!(
                message.contains("ghosts must be distinct cells in ascending order"),
                "{message}"
            );
        }
    }
}

#[test]
fn a_ghost_that_is_not_a_copy_is_refused_saying_it_is_a_ghost() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.vtk");
    let unit = |x: f64| (DVec3::new(x, 0.0, 0.0), 1.0);
    // Cell 2 is a flagged copy of cell 0 (bit 1 among others: 1 + 16), in a legacy file: read.
    std::fs::write(
        &path,
        legacy_with_ghosts(&[unit(0.0), unit(1.0), unit(0.0)], &[0, 0, 17]),
    )
    .unwrap();
    let mesh = read_mesh(&path, &DisplacementArray::Default).unwrap();
    assert_eq!(
        read_hex_mesh(&path, &DisplacementArray::Default)
            .unwrap()
            .ghosts,
        [2]
    );
    assert_eq!(mesh.body.active_count(), 2);
    assert_eq!(mesh.cells.lattice_cell(2), mesh.cells.lattice_cell(0));
    assert_eq!(
        mesh.input_cell(mesh.cells.lattice_cell(2).unwrap()),
        Some(0)
    );
    // Not flagged (16 alone is not DUPLICATECELL): two cells at one place, as before.
    std::fs::write(
        &path,
        legacy_with_ghosts(&[unit(0.0), unit(1.0), unit(0.0)], &[0, 0, 16]),
    )
    .unwrap();
    let message = read_mesh(&path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("cells 0 and 2 are the same lattice cell"),
        "{message}"
    );
    assert!(!message.contains("ghost"), "{message}");
    // A flag array of another length than the cells, in a legacy FIELD (vtkio reads it as it
    // is): an error, not flags on the next piece's cells.
    let field = legacy_with_ghosts(&[unit(0.0), unit(1.0)], &[]).replace(
        "SCALARS vtkGhostType unsigned_char 1\nLOOKUP_TABLE default\n",
        "FIELD FieldData 1\nvtkGhostType 1 3 unsigned_char\n0 0 1\n",
    );
    std::fs::write(&path, field).unwrap();
    let message = read_mesh(&path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("vtkGhostType holds 3 values for 2 cells"),
        "{message}"
    );
    // A flagged cell that overlaps another without being its copy: an eighth of cell 0.
    std::fs::write(
        &path,
        legacy_with_ghosts(&[unit(0.0), unit(1.0), (DVec3::ZERO, 0.5)], &[0, 0, 1]),
    )
    .unwrap();
    let message = read_body(&path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains("cells 0 and 2 overlap"), "{message}");
    assert!(message.contains("cell 2 is a ghost cell"), "{message}");
}

/// A copy of `split-appended` in a fresh folder, with piece `which` named `source` instead.
fn with_piece(which: usize, source: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for piece in 0..3 {
        let name = format!("split-appended_{piece}.vtu");
        std::fs::copy(folder().join(&name), dir.path().join(&name)).unwrap();
    }
    let text = std::fs::read_to_string(folder().join("split-appended.pvtu")).unwrap();
    let wanted = format!("Source=\"split-appended_{which}.vtu\"");
    assert!(text.contains(&wanted));
    let path = dir.path().join("hostile.pvtu");
    std::fs::write(
        &path,
        text.replace(&wanted, &format!("Source=\"{source}\"")),
    )
    .unwrap();
    (dir, path)
}

fn refusal(path: &Path) -> String {
    read_mesh(path, &DisplacementArray::Default)
        .unwrap_err()
        .to_string()
}

/// The refusal of the parallel file `path`, which must name its piece `piece` and say `wanted`.
fn refused_naming(path: &Path, piece: usize, wanted: &str) {
    let message = refusal(path);
    assert!(message.contains(&format!("piece {piece} (")), "{message}");
    assert!(message.contains(wanted), "{message}");
}

#[test]
#[cfg(unix)]
fn a_piece_that_is_a_device_is_refused_at_once() {
    // vtkio read it whole, and the process aborted when memory ran out.
    let (dir, path) = with_piece(1, "zero.vtu");
    std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero.vtu")).unwrap();
    refused_naming(&path, 1, "zero.vtu): unrecognised format");
}

#[test]
fn a_missing_piece_is_named() {
    let (_dir, path) = with_piece(2, "gone.vtu");
    refused_naming(&path, 2, "gone.vtu): ");
}

#[test]
fn a_parallel_file_as_a_piece_is_refused() {
    // Itself, and another parallel file.
    for source in ["hostile.pvtu", "other.pvtu"] {
        let (dir, path) = with_piece(0, source);
        std::fs::copy(&path, dir.path().join("other.pvtu")).unwrap();
        refused_naming(
            &path,
            0,
            "the pieces of a parallel file are serial .vtu files",
        );
    }
}

#[test]
fn a_piece_file_named_twice_is_refused_before_it_is_read_again() {
    // Through another spelling of the same file, and a link to it.
    let (_dir, path) = with_piece(2, "./split-appended_0.vtu");
    refused_naming(&path, 2, "the file of piece 0 again");
    #[cfg(unix)]
    {
        let (dir, path) = with_piece(2, "link.vtu");
        std::os::unix::fs::symlink("split-appended_1.vtu", dir.path().join("link.vtu")).unwrap();
        refused_naming(&path, 2, "the file of piece 1 again");
    }
}

#[test]
fn a_legacy_piece_is_refused() {
    let (dir, path) = with_piece(1, "legacy.vtk");
    std::fs::copy(
        folder().join("../vtk-written/legacy-binary.vtk"),
        dir.path().join("legacy.vtk"),
    )
    .unwrap();
    refused_naming(&path, 1, "a legacy VTK file");
}

/// An empty piece file, or one cut inside its first bytes (a parallel write that failed), was
/// refused as "a legacy VTK file".
#[test]
fn an_empty_or_cut_piece_is_not_called_legacy() {
    for (bytes, wanted) in [
        (&b""[..], "the file is empty"),
        (b" \n\t\n", "the file is empty"),
        (b"# v", "neither a legacy VTK file"),
    ] {
        let (dir, path) = with_piece(1, "cut.vtu");
        std::fs::write(dir.path().join("cut.vtu"), bytes).unwrap();
        refused_naming(&path, 1, wanted);
        assert!(!refusal(&path).contains("a legacy VTK file:"), "{bytes:?}");
    }
}

#[test]
fn a_corrupt_piece_is_refused_as_its_own_file_would_be() {
    // The one piece's displacement cut short by a value. vtkio drops such an array; read alone,
    // the piece is refused for it, but through the parallel file vtkio read the piece by itself,
    // and the mesh came out undeformed without a word.
    let (dir, path) = with_piece(1, "split-appended_1.vtu");
    let text = std::fs::read_to_string(&path).unwrap();
    let only_1: String = text
        .lines()
        .filter(|l| !l.contains("_0.vtu") && !l.contains("_2.vtu"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&path, only_1).unwrap();
    let piece = dir.path().join("split-appended_1.vtu");
    let ascii = std::fs::read_to_string(folder().join("split-ascii_1.vtu")).unwrap();
    let start = ascii.find("Name=\"displacement\"").unwrap();
    let values = start + ascii[start..].find('>').unwrap() + 1;
    let cut = values + ascii[values..].find(char::is_numeric).unwrap();
    let end = cut + ascii[cut..].find(char::is_whitespace).unwrap();
    std::fs::write(&piece, format!("{}{}", &ascii[..cut], &ascii[end..])).unwrap();
    let wanted = "declares it, but its data cannot be decoded";
    let alone = refusal(&piece);
    assert!(alone.contains(wanted), "{alone}");
    refused_naming(&path, 0, wanted);
}

/// A copy of `split-ascii` in a fresh folder, its pieces `without` written without their point
/// data.
fn without_point_data(without: &[usize]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for piece in 0..3 {
        let name = format!("split-ascii_{piece}.vtu");
        let mut text = std::fs::read_to_string(folder().join(&name)).unwrap();
        if without.contains(&piece) {
            let start = text.find("<PointData").unwrap();
            let end = text.find("</PointData>").unwrap() + "</PointData>".len();
            text.replace_range(start..end, "<PointData>\n      </PointData>");
        }
        std::fs::write(dir.path().join(&name), text).unwrap();
    }
    let path = dir.path().join("split-ascii.pvtu");
    std::fs::copy(folder().join("split-ascii.pvtu"), &path).unwrap();
    (dir, path)
}

/// The parallel file declares the displacement in its `<PPointData>`, and no piece carries it:
/// the mesh was read as undeformed, only the summary saying "no displacement array". Now that is
/// an error naming the parallel file and the array, as a piece without it beside one with it is.
#[test]
fn a_declared_displacement_that_no_piece_has_is_refused() {
    let (_dir, path) = without_point_data(&[0, 1, 2]);
    for asked in [
        DisplacementArray::Default,
        DisplacementArray::Named("displacement".to_owned()),
    ] {
        let error = read_mesh(&path, &asked).unwrap_err();
        let message = error.to_string();
        assert_eq!(error.path(), path, "{message}");
        assert!(
            message.contains("point data array `displacement`")
                && message.contains("the parallel file declares it in its <PPointData>")
                && message.contains("piece 0 (")
                && message.contains("would be read as undeformed"),
            "{message}"
        );
    }
    // Asked to ignore it, the body is read undeformed.
    let mesh = read_mesh(&path, &DisplacementArray::Ignore).unwrap();
    assert!(!mesh.has_displacement);
    // One piece without it, the others with it: named as before.
    let (_dir, path) = without_point_data(&[1]);
    let message = refusal(&path);
    assert!(
        message.contains("piece 1 (") && message.contains("has no such point array, but piece 0"),
        "{message}"
    );
    // Not declared and in no piece: an undeformed mesh, as a serial file without it is.
    let (dir, path) = without_point_data(&[0, 1, 2]);
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text.find("<PPointData").unwrap();
    let end = text.find("</PPointData>").unwrap() + "</PPointData>".len();
    let undeclared = dir.path().join("undeclared.pvtu");
    std::fs::write(&undeclared, format!("{}{}", &text[..start], &text[end..])).unwrap();
    let mesh = read_mesh(&undeclared, &DisplacementArray::Default).unwrap();
    assert!(!mesh.has_displacement);
}

/// A parallel file's pieces' files are listed once it is read, before any is read: a caller
/// that writes files compares them with every input first.
#[test]
fn piece_files_are_listed_before_they_are_read() {
    let (dir, path) = with_piece(2, "gone.vtu");
    let file = MeshFile::read(&path).unwrap();
    let expected: Vec<PathBuf> = ["split-appended_0.vtu", "split-appended_1.vtu", "gone.vtu"]
        .iter()
        .map(|name| dir.path().join(name))
        .collect();
    assert_eq!(file.piece_files(), expected);
    let message = file
        .into_body(&DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("piece 2 (") && message.contains("gone.vtu"),
        "{message}"
    );
    // A serial file has none.
    let serial = MeshFile::read(folder().join("whole.vtu")).unwrap();
    assert!(serial.piece_files().is_empty());
    assert_eq!(
        serial
            .into_body(&DisplacementArray::Default)
            .unwrap()
            .point_arrays,
        ["displacement"]
    );
}

#[test]
fn a_parallel_file_in_memory_is_refused() {
    let bytes = std::fs::read(folder().join("split-appended.pvtu")).unwrap();
    let message = parse_hex_mesh(&bytes, &DisplacementArray::Default)
        .unwrap_err()
        .to_string();
    assert!(message.contains("read it from its path"), "{message}");
}
