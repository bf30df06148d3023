//! Adaptive meshes through the files: round trips in every format, cells and nodes in any order,
//! extreme offsets and anisotropic spacings, and each malformed mesh refused naming its cell.

use cgcontact::{AdaptiveBody, CORNER_OFFSETS, CellId, Lattice, Leaf};
use cgcontact_io::{ErrorKind, HexMesh, MeshBody, MeshFormat, read_body, write_adaptive_mesh};
use glam::DVec3;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::mesh_of;
use crate::common::probes::corner_refined_leaves;

fn body(origin: DVec3, h: DVec3, cells: [u32; 3], depth: u8, seed: u64) -> AdaptiveBody {
    let lattice = Lattice::new(origin, h, cells).unwrap();
    let mut body =
        AdaptiveBody::from_leaves(lattice, corner_refined_leaves(cells, depth.into())).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let fine = body.spacing(body.finest_level());
    body.update_independent(|_, x, u| {
        let t = (x - origin) / h;
        *u = 0.03 * h * DVec3::new(t.y.sin(), t.z.cos(), t.x.sin())
            + 0.05
                * fine
                * DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    0.0,
                );
    })
    .unwrap();
    body.validate().unwrap();
    body
}

fn adaptive(mesh: &HexMesh) -> cgcontact_io::AdaptiveMesh {
    match mesh.to_body().unwrap() {
        MeshBody::Adaptive(m) => m,
        MeshBody::Uniform(_) => panic!("read as uniform"),
    }
}

#[test]
fn every_format_round_trips_leaves_levels_and_displacements() {
    let dir = tempfile::tempdir().unwrap();
    for (origin, h) in [
        (DVec3::new(-1.0, 2.0, 0.5), DVec3::new(0.5, 0.25, 1.0)),
        (DVec3::new(1e6, -3e6, 7e5), DVec3::new(2.0, 0.125, 40.0)),
        (DVec3::new(1e-3, 0.0, -2e-3), DVec3::splat(1e-4)),
    ] {
        let body = body(origin, h, [3, 2, 4], 3, 1);
        for format in [
            MeshFormat::LegacyAscii,
            MeshFormat::LegacyBinary,
            MeshFormat::Xml,
            MeshFormat::XmlZlib,
        ] {
            let path = dir.path().join(format!("mesh.{}", format.extension()));
            write_adaptive_mesh(&path, &body, format).unwrap();
            let MeshBody::Adaptive(read) = read_body(&path, &Default::default()).unwrap() else {
                panic!("{format:?}: read as uniform");
            };
            assert_eq!(read.body.leaves(), body.leaves(), "{format:?} at {origin}");
            assert_eq!(read.body.finest_level(), 3);
            let l = read.body.lattice();
            assert_eq!(l.cells(), [3, 2, 4]);
            assert!(
                (l.origin() - origin).abs().max_element()
                    <= 1e-9 * h.max_element() + 1e-15 * origin.abs().max_element()
            );
            assert!(
                ((l.h() - h) / h).abs().max_element() < 1e-12,
                "{} vs {h}",
                l.h()
            );
            assert_eq!(
                read.body.displacements(),
                body.displacements(),
                "{format:?}"
            );
            assert!(read.has_displacement);
            assert!(
                read.constraints.holds() && read.constraints.hanging > 0,
                "{:?}",
                read.constraints
            );
        }
    }
}

#[test]
fn cells_and_nodes_in_any_order_make_the_same_body() {
    let body = body(
        DVec3::new(3.0, -1.0, 2.0),
        DVec3::new(0.4, 0.3, 0.5),
        [4, 3, 2],
        2,
        5,
    );
    let mesh = mesh_of(&body);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..5 {
        // Nodes renumbered, a few duplicated (an unmerged mesh), and cells shuffled.
        let mut perm: Vec<usize> = (0..mesh.points.len()).collect();
        perm.shuffle(&mut rng);
        let mut points = vec![DVec3::ZERO; perm.len()];
        let mut u = vec![DVec3::ZERO; perm.len()];
        for (old, &new) in perm.iter().enumerate() {
            points[new] = mesh.points[old];
            u[new] = mesh.displacement.as_ref().unwrap()[old];
        }
        let mut cells: Vec<(usize, [u32; 8])> = mesh
            .cells
            .iter()
            .enumerate()
            .map(|(c, cell)| (c, cell.map(|n| perm[n as usize] as u32)))
            .collect();
        for (_, cell) in cells.iter_mut().take(7) {
            points.push(points[cell[6] as usize]);
            u.push(u[cell[6] as usize]);
            cell[6] = points.len() as u32 - 1;
        }
        cells.shuffle(&mut rng);
        let shuffled = HexMesh {
            ghosts: Vec::new(),
            points,
            cells: cells.iter().map(|(_, c)| *c).collect(),
            displacement: Some(u),
        };
        let read = adaptive(&shuffled);
        for (input, (original, _)) in cells.iter().enumerate() {
            let leaf = read.body.leaves().get(input).expect("a leaf of the body");
            assert_eq!(
                leaf,
                body.leaves().get(*original).expect("a leaf of the body"),
                "input cell {input}"
            );
            assert_eq!(
                read.body.cell_displacements(CellId(input as u32)),
                body.cell_displacements(CellId(*original as u32))
            );
        }
        assert!(read.constraints.holds());
        assert_eq!(read.cells.input_cell(CellId(3)), Some(3));
    }
}

#[test]
fn a_hanging_node_off_its_constraint_is_reported_with_its_offset() {
    let body = body(DVec3::ZERO, DVec3::ONE, [2, 2, 2], 2, 3);
    let mut mesh = mesh_of(&body);
    let node = body.hanging_nodes().nth(2).unwrap();
    mesh.displacement.as_mut().unwrap()[node].z += 1e-4;
    let read = adaptive(&mesh);
    assert_eq!(read.constraints.violating, 1);
    let (worst, by) = read.constraints.worst.unwrap();
    assert_eq!(worst, node);
    assert!((by - 1e-4).abs() < 1e-12);
    // Below the tolerance (1e-9 of the finest spacing): not reported.
    let mut mesh = mesh_of(&body);
    mesh.displacement.as_mut().unwrap()[node].z += 1e-12;
    assert!(adaptive(&mesh).constraints.holds());
}

#[test]
fn malformed_adaptive_meshes_are_refused_naming_the_cell() {
    let body = body(DVec3::ZERO, DVec3::ONE, [3, 2, 2], 2, 4);
    let good = mesh_of(&body);
    let fine_cell = body.leaves().iter().position(|l| l.level == 2).unwrap();

    // A level-1 cell shifted by one finest step: on the finest lattice, not on its own level's.
    let mut shifted = good.clone();
    let mid = body.leaves().iter().position(|l| l.level == 1).unwrap();
    let start = shifted.points.len() as u32;
    for c in 0..8 {
        let node = body.cell_nodes(CellId(mid as u32)).unwrap()[c];
        shifted
            .points
            .push(body.node_position(node).unwrap() + body.spacing(2));
        shifted.displacement.as_mut().unwrap().push(DVec3::ZERO);
    }
    shifted.cells[mid] = std::array::from_fn(|c| start + c as u32);
    assert!(
        matches!(shifted.to_body(), Err(ErrorKind::NotAligned { cell, level: 1, .. }) if cell == mid),
        "{:?}",
        shifted.to_body().err()
    );

    // Half a finest step: off the lattice altogether.
    let mut off = good.clone();
    let old = off.cells[fine_cell][6] as usize;
    off.points.push(off.points[old] + 0.5 * body.spacing(2));
    let u = off.displacement.as_mut().unwrap();
    u.push(u[old]);
    let n = off.points.len() - 1;
    off.cells[fine_cell][6] = n as u32;
    assert!(matches!(off.to_body(), Err(ErrorKind::OffLattice { node, .. }) if node == n));

    // A coarse cell listed again over the refined region: overlap.
    let mut twice = good.clone();
    let coarse = body.leaves().iter().position(|l| l.level == 0).unwrap();
    let mut over = twice.cells[coarse];
    let offset = over.map(|n| twice.points[n as usize]);
    // Move the copy onto base cell (0, 0, 0), which is refined.
    let shift = -offset[0];
    let start = twice.points.len() as u32;
    for (c, p) in offset.iter().enumerate() {
        twice.points.push(*p + shift);
        twice.displacement.as_mut().unwrap().push(DVec3::ZERO);
        over[c] = start + c as u32;
    }
    twice.cells.push(over);
    let last = twice.cells.len() - 1;
    assert!(
        matches!(twice.to_body(), Err(ErrorKind::OverlappingCells { second, .. }) if second == last),
        "{:?}",
        twice.to_body().err()
    );

    // A cell of 3/4 the coarse size: no level.
    let mut odd = good.clone();
    push_cube(&mut odd, DVec3::new(10.0, 0.0, 0.0), 0.75);
    let last = odd.cells.len() - 1;
    assert!(
        matches!(odd.to_body(), Err(ErrorKind::CellSize { cell, .. }) if cell == last),
        "{:?}",
        odd.to_body().err()
    );

    // Corners out of VTK order.
    let mut swapped = good.clone();
    swapped.cells[fine_cell].swap(2, 3);
    assert!(
        matches!(swapped.to_body(), Err(ErrorKind::NotLatticeCell { cell, .. }) if cell == fine_cell)
    );

    // Coinciding nodes with different displacements.
    let mut split = good.clone();
    let n = split.cells[fine_cell][6];
    split.points.push(split.points[n as usize]);
    let u = split.displacement.as_mut().unwrap();
    u.push(u[n as usize] + DVec3::X);
    split.cells[fine_cell][6] = split.points.len() as u32 - 1;
    assert!(matches!(
        split.to_body(),
        Err(ErrorKind::InconsistentDisplacement { .. })
    ));

    // Copies 6e-10 apart: beyond 1e-9 of the finest spacing (0.25), within 1e-9 of the base
    // spacing, which the check used to take.
    let mut near = good.clone();
    let n = near.cells[fine_cell][6];
    near.points.push(near.points[n as usize]);
    let u = near.displacement.as_mut().unwrap();
    u.push(u[n as usize] + DVec3::X * 6e-10);
    near.cells[fine_cell][6] = near.points.len() as u32 - 1;
    assert!(
        matches!(
            near.to_body(),
            Err(ErrorKind::InconsistentDisplacement { .. })
        ),
        "{:?}",
        near.to_body().err()
    );
}

#[test]
fn a_mesh_of_one_size_stays_uniform() {
    let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap();
    let leaves: Vec<Leaf> = (0..8u32)
        .map(|c| Leaf::new(0, [c % 2, (c / 2) % 2, c / 4]))
        .collect();
    let body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
    assert!(matches!(
        mesh_of(&body).to_body().unwrap(),
        MeshBody::Uniform(_)
    ));
    // And a one-level mesh read as adaptive on purpose is a one-level body.
    assert_eq!(mesh_of(&body).to_adaptive().unwrap().body.finest_level(), 0);
}

/// An adaptive mesh whose coordinates and displacements are 32-bit floats (VTK's default), on
/// spacings no float holds exactly: each leaf is found at its level and place, and the hanging
/// nodes' displacements, rounded as floats, still hold their constraints. With f64's rounding as
/// the only slack the nodes were off the lattice.
#[test]
fn float_coordinates_and_displacements_make_the_same_leaves() {
    let body = body(
        DVec3::new(0.3, -1.7, 2.9),
        DVec3::new(0.1, 0.3, 0.07),
        [3, 2, 2],
        2,
        11,
    );
    let mesh = mesh_of(&body);
    let float = |v: &DVec3| v.as_vec3().as_dvec3();
    let rounded = HexMesh {
        ghosts: Vec::new(),
        points: mesh.points.iter().map(float).collect(),
        cells: mesh.cells.clone(),
        displacement: mesh
            .displacement
            .as_ref()
            .map(|u| u.iter().map(float).collect()),
    };
    assert_ne!(rounded.points, mesh.points);
    let read = adaptive(&rounded);
    assert_eq!(read.body.leaves(), body.leaves());
    assert!(read.constraints.holds(), "{:?}", read.constraints);
}

/// A half-size cell beside a unit cell but a quarter of a unit off its level's lattice (at
/// x = 1.25): the extent, 1.75, is no whole number of half cells, and the spacing taken from it
/// (0.4375) made the error quote a spacing the mesh does not have. The finest spacing now comes
/// from the cells' edges when the extent disagrees: the error names a node of the shifted cell,
/// with spacing 0.5 and half a spacing off.
#[test]
fn a_cell_off_its_levels_lattice_is_reported_with_the_meshs_spacing() {
    let cube = |low: DVec3, edge: f64| -> Vec<DVec3> {
        CORNER_OFFSETS
            .iter()
            .map(|o| low + edge * DVec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])))
            .collect()
    };
    let mut points = cube(DVec3::ZERO, 1.0);
    points.extend(cube(DVec3::new(1.25, 0.0, 0.0), 0.5));
    let mesh = HexMesh {
        ghosts: Vec::new(),
        points,
        cells: vec![
            std::array::from_fn(|c| c as u32),
            std::array::from_fn(|c| 8 + c as u32),
        ],
        displacement: None,
    };
    match mesh.to_body() {
        Err(ErrorKind::OffLattice {
            node, h, offset, ..
        }) => {
            assert!(node >= 8, "node {node}");
            assert_eq!(h[0], 0.5);
            assert_eq!(offset[0].abs(), 0.5);
        }
        other => panic!("{:?}", other.err()),
    }
}

/// A cube of edge `edge` at `low`, appended to `mesh` with zero displacements.
fn push_cube(mesh: &mut HexMesh, low: DVec3, edge: f64) {
    push_box(mesh, low, DVec3::splat(edge));
}

/// A box of edges `edges` at `low`, appended to `mesh` with zero displacements.
fn push_box(mesh: &mut HexMesh, low: DVec3, edges: DVec3) {
    let start = mesh.points.len() as u32;
    for off in CORNER_OFFSETS {
        mesh.points
            .push(low + edges * DVec3::new(off[0] as f64, off[1] as f64, off[2] as f64));
        if let Some(u) = mesh.displacement.as_mut() {
            u.push(DVec3::ZERO);
        }
    }
    mesh.cells.push(std::array::from_fn(|c| start + c as u32));
}

/// Cells that are flat, collapsed or listed with their corners rotated, and a cell one level too
/// deep, are named with what is wrong with them: they had been blamed on another cell, or on
/// edges "not the coarsest cells' halved" that were.
#[test]
fn flat_rotated_and_too_deep_cells_are_named() {
    let body = body(DVec3::ZERO, DVec3::ONE, [3, 2, 2], 2, 4);
    let good = mesh_of(&body);
    let fine_cell = body.leaves().iter().position(|l| l.level == 2).unwrap();

    // Every corner of a fine cell on one node.
    let mut collapsed = good.clone();
    collapsed.cells[fine_cell] = [collapsed.cells[fine_cell][0]; 8];
    assert!(
        matches!(collapsed.to_body(), Err(ErrorKind::FlatCell { cell, corner: 1, axis: "x" }) if cell == fine_cell),
        "{:?}",
        collapsed.to_body().err()
    );

    // Every cell's corners rotated a quarter turn about z: corner 1 lies along y.
    let mut rotated = good.clone();
    for cell in &mut rotated.cells {
        *cell = [
            cell[3], cell[0], cell[1], cell[2], cell[7], cell[4], cell[5], cell[6],
        ];
    }
    assert!(
        matches!(
            rotated.to_body(),
            Err(ErrorKind::FlatCell {
                cell: 0,
                corner: 1,
                axis: "x"
            })
        ),
        "{:?}",
        rotated.to_body().err()
    );

    // A unit cube and one of edge 2^-21, one level deeper than MAX_LEVEL.
    let mut deep = HexMesh {
        ghosts: Vec::new(),
        points: Vec::new(),
        cells: Vec::new(),
        displacement: None,
    };
    push_cube(&mut deep, DVec3::ZERO, 1.0);
    push_cube(&mut deep, DVec3::new(2.0, 0.0, 0.0), 0.5f64.powi(21));
    assert!(
        matches!(
            deep.to_body(),
            Err(ErrorKind::TooDeep {
                cell: 1,
                level: 21,
                ..
            })
        ),
        "{:?}",
        deep.to_body().err()
    );
    // At MAX_LEVEL itself the size is accepted (the mesh then fails elsewhere or not at all,
    // but not on the cell's size).
    let mut deepest = deep.clone();
    deepest.points.truncate(8);
    deepest.cells.truncate(1);
    push_cube(&mut deepest, DVec3::new(2.0, 0.0, 0.0), 0.5f64.powi(20));
    assert!(
        !matches!(
            deepest.to_body(),
            Err(ErrorKind::TooDeep { .. } | ErrorKind::CellSize { .. })
        ),
        "{:?}",
        deepest.to_body().err()
    );
}

/// A cell stretched along one axis, or a level-0 cell off the base lattice listed first, is the
/// cell named: the largest edge per axis had taken the stretched cell's, and the first level-0
/// cell had set the base lattice's phase, so that valid cells were blamed.
#[test]
fn the_odd_cell_is_named_wherever_it_is_listed() {
    let body = body(DVec3::ZERO, DVec3::ONE, [3, 2, 2], 2, 4);
    let good = mesh_of(&body);

    // Twice as long along x as a base cell, beside the body.
    let mut stretched = good.clone();
    push_box(
        &mut stretched,
        DVec3::new(10.0, 0.0, 0.0),
        DVec3::new(2.0, 1.0, 1.0),
    );
    let last = stretched.cells.len() - 1;
    assert!(
        matches!(stretched.to_body(), Err(ErrorKind::CellSize { cell, .. }) if cell == last),
        "{:?}",
        stretched.to_body().err()
    );

    // A base cell a finest step (0.25) off the base lattice, listed first.
    for first in [false, true] {
        let mut shifted = good.clone();
        push_cube(&mut shifted, DVec3::new(10.25, 0.0, 0.0), 1.0);
        let last = shifted.cells.len() - 1;
        let named = if first {
            shifted.cells.swap(0, last);
            0
        } else {
            last
        };
        assert!(
            matches!(shifted.to_body(), Err(ErrorKind::NotAligned { cell, level: 0, .. }) if cell == named),
            "first {first}: {:?}",
            shifted.to_body().err()
        );
    }
}

/// A cell larger than the coarsest by a factor that is no power of two (1.25, 1.5, 3) had set
/// the base spacing, the largest edge, and the first cell listed was named instead: "cell 0:
/// edges [0.5, 0.5, 0.5] are not the coarsest cells' edges [1.5, 1.5, 1.5] halved". Made with
/// VTK in `make.py --hostile` (`h-size-three-halves`, `h-size-triple`, `h-size-five-quarters`).
/// A cell twice the base, on the doubled lattice, is a valid coarser level.
#[test]
fn regression_an_oversized_cell_is_named_not_the_first() {
    let body = body(DVec3::ZERO, DVec3::ONE, [3, 2, 2], 2, 4);
    let good = mesh_of(&body);
    for factor in [1.25, 1.5, 3.0, 1.0 + 1e-4] {
        for first in [false, true] {
            let mut big = good.clone();
            push_cube(&mut big, DVec3::new(10.0, 0.0, 0.0), factor);
            let last = big.cells.len() - 1;
            let named = if first {
                big.cells.swap(0, last);
                0
            } else {
                last
            };
            assert!(
                matches!(big.to_body(), Err(ErrorKind::CellSize { cell, base, .. }) if cell == named && base == [1.0; 3]),
                "factor {factor}, first {first}: {:?}",
                big.to_body().err()
            );
        }
    }
    let mut double = good.clone();
    push_cube(&mut double, DVec3::new(10.0, 0.0, 0.0), 2.0);
    let MeshBody::Adaptive(read) = double.to_body().unwrap() else {
        panic!("read as uniform");
    };
    assert_eq!(read.body.finest_level(), 3);
    assert_eq!(read.body.spacing(0), DVec3::splat(2.0));
}

/// A mesh whose finest lattice would exceed 2^21 − 1 cells along an axis says so: two unit
/// cubes 3,000 apart and one cube of level 10 (3,001 · 1,024 finest cells along x).
#[test]
fn a_finest_lattice_too_wide_names_the_limit() {
    let mut wide = HexMesh {
        ghosts: Vec::new(),
        points: Vec::new(),
        cells: Vec::new(),
        displacement: None,
    };
    push_cube(&mut wide, DVec3::ZERO, 1.0);
    push_cube(&mut wide, DVec3::new(3000.0, 0.0, 0.0), 1.0);
    push_cube(&mut wide, DVec3::new(2.0, 0.0, 0.0), 0.5f64.powi(10));
    match wide.to_body() {
        Err(ErrorKind::Degenerate(message)) => {
            assert!(
                message.contains("2^21 - 1") && message.contains("along x"),
                "{message}"
            )
        }
        other => panic!("{:?}", other.err()),
    }
}
