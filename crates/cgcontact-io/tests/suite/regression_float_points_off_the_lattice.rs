//! Regression: meshes whose coordinates are 32-bit floats (VTK's `vtkPoints` default) lie off
//! their lattice by the floats' rounding, 6e-8 of a cell at a spacing of 0.1. The reader took
//! each node at its lattice position and dropped that offset, so the body's faces were not the
//! file's: a point on a shared node or face, given where the file has it, lost owners (an
//! interior node of a 3 × 3 × 3 block: 1 owner of 8), and a point on a boundary face was outside
//! the body. The offset now goes into the displacement, so that the deformed nodes are the
//! file's, in uniform and adaptive meshes alike.
//!
//! The independent answer: points made from each cell's corners as the file holds them (the
//! trilinear map at ξ ∈ {−1, 0, 1}³: nodes, edge and face centres, the centre), whose owners
//! are the cells whose closed box holds the point's lattice position.

use cgcontact::{AdaptiveLocator, CORNER_OFFSETS, LatticeLocator, Locator, Settings};
use cgcontact_io::{HexMesh, MeshBody};
use glam::DVec3;

use crate::common::mesh_of;
use crate::common::probes::{corner_refined_body, displaced_leaf_boxes, found, owners_of, probes};

/// The mesh as a file of float coordinates holds it: each coordinate rounded to f32.
fn as_floats(mesh: &HexMesh) -> HexMesh {
    let round = |p: &DVec3| DVec3::from_array(p.to_array().map(|c| f64::from(c as f32)));
    HexMesh {
        ghosts: Vec::new(),
        points: mesh.points.iter().map(round).collect(),
        ..mesh.clone()
    }
}

/// A 3 × 3 × 3 block without its centre cell, at an origin and spacings floats cannot hold.
fn uniform_mesh(displaced: bool) -> (HexMesh, Vec<[u32; 3]>) {
    let origin = DVec3::new(0.1, -0.2, 0.3);
    let h = DVec3::new(0.1, 0.3, 0.7);
    let node = |i: u32, j: u32, k: u32| i + 4 * (j + 4 * k);
    let mut points = Vec::new();
    for k in 0..4 {
        for j in 0..4 {
            for i in 0..4 {
                points.push(origin + h * DVec3::new(i as f64, j as f64, k as f64));
            }
        }
    }
    let mut cells = Vec::new();
    let mut low = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..3 {
                if [i, j, k] == [1, 1, 1] {
                    continue;
                }
                cells.push(CORNER_OFFSETS.map(|[a, b, c]| node(i + a, j + b, k + c)));
                low.push([i, j, k]);
            }
        }
    }
    let displacement = displaced.then(|| {
        points
            .iter()
            .map(|p| 0.04 * h * DVec3::new((7.0 * p.y).sin(), (5.0 * p.z).cos(), (3.0 * p.x).sin()))
            .collect()
    });
    let mesh = HexMesh {
        ghosts: Vec::new(),
        points,
        cells,
        displacement,
    };
    (as_floats(&mesh), low)
}

#[test]
fn points_where_a_float_file_has_them_keep_every_owner_in_a_uniform_mesh() {
    for displaced in [false, true] {
        let (mesh, low) = uniform_mesh(displaced);
        let size = vec![1; low.len()];
        let MeshBody::Uniform(read) = mesh.to_body().unwrap() else {
            panic!("read as adaptive");
        };
        let locator = LatticeLocator::new(&read.body, Settings::default()).unwrap();
        let mut lost = Vec::new();
        for (x, cell, half) in probes(&mesh, &low, &size) {
            let expected = owners_of(&low, &size, half);
            let got = found(&locator.locate_owners(x).unwrap(), &read.cells);
            if got != expected {
                lost.push((cell, half, expected, got));
            }
        }
        assert!(
            lost.is_empty(),
            "displaced {displaced}: {} of {} probes: {:?}",
            lost.len(),
            26 * 27,
            &lost[..lost.len().min(4)]
        );
    }
}

#[test]
fn points_where_a_float_file_has_them_are_in_their_leaf_in_an_adaptive_mesh() {
    // Refined twice toward a corner: a jump of two levels.
    let mut body = corner_refined_body(2);
    let (low, size) = displaced_leaf_boxes(&mut body);
    let mesh = as_floats(&mesh_of(&body));

    let MeshBody::Adaptive(read) = mesh.to_body().unwrap() else {
        panic!("read as uniform");
    };
    assert_eq!(read.constraints.violating, 0, "{:?}", read.constraints);
    let locator = AdaptiveLocator::new(&read.body, Settings::default()).unwrap();
    let cells_map = read.cells.clone();
    let mut lost = Vec::new();
    let probes = probes(&mesh, &low, &size);
    for (x, cell, half) in &probes {
        let got = found(&locator.locate_owners(*x).unwrap(), &cells_map);
        if !got.contains(cell) {
            lost.push((*cell, *half, got));
        }
    }
    assert!(
        lost.is_empty(),
        "{} of {} probes: {:?}",
        lost.len(),
        probes.len(),
        &lost[..lost.len().min(4)]
    );
}
