//! Regression: an adaptive mesh whose coordinates (VTK's `vtkPoints` default) or displacements
//! are 32-bit floats holds its hanging nodes off the coarse faces they hang on by the floats'
//! rounding (3e-8 of a base cell at the spacings below): the file's mesh is conforming only to
//! that rounding. A point at a hanging node, or on a fine face against a coarse one, made from
//! the fine leaf's corners as the file holds them, lay that far outside the coarse leaf, beyond
//! the locator's inside tolerance (1e-12 of a cell plus f64 rounding), and `locate_owners` left
//! the coarse leaf out: in a VTK-written mesh refined 3 levels with float points, about one
//! point in six made at ξ ∈ {−1, −½, 0, ½, 1}³ lost an owner.
//!
//! The independent answer: points made from each leaf's corners as the file holds them at
//! ξ ∈ {−1, 0, 1}³, whose owners are the leaves whose closed box holds the point's lattice
//! position (`owners_of`): every one of them, and no other, must be listed.

use cgcontact::{AdaptiveBody, AdaptiveLocator, Locator, Settings};
use cgcontact_io::{HexMesh, MeshBody};
use glam::DVec3;

use crate::common::mesh_of;
use crate::common::probes::{corner_refined_body, displaced_leaf_boxes, found, owners_of, probes};

/// Refined three levels in a corner: level jumps of 1 to 3.
fn body() -> AdaptiveBody {
    corner_refined_body(3)
}

fn round(p: &DVec3) -> DVec3 {
    DVec3::from_array(p.to_array().map(|c| f64::from(c as f32)))
}

#[test]
fn hanging_nodes_of_a_float_file_keep_every_owner() {
    let mut body = body();
    let (low, size) = displaced_leaf_boxes(&mut body);
    let exact = mesh_of(&body);
    assert!(body.hanging_nodes().count() > 0);
    // Float coordinates, float displacements, both.
    for (points, displacements) in [(true, false), (false, true), (true, true)] {
        let mesh = HexMesh {
            ghosts: Vec::new(),
            points: if points {
                exact.points.iter().map(round).collect()
            } else {
                exact.points.clone()
            },
            displacement: exact.displacement.as_ref().map(|u| {
                if displacements {
                    u.iter().map(round).collect()
                } else {
                    u.clone()
                }
            }),
            ..exact.clone()
        };
        let MeshBody::Adaptive(read) = mesh.to_body().unwrap() else {
            panic!("read as uniform");
        };
        assert!(read.constraints.holds(), "{:?}", read.constraints);
        let locator = AdaptiveLocator::new(&read.body, Settings::default()).unwrap();
        let mut wrong = Vec::new();
        let probes = probes(&mesh, &low, &size);
        for (x, cell, half) in &probes {
            let expected = owners_of(&low, &size, *half);
            let got = found(&locator.locate_owners(*x).unwrap(), &read.cells);
            if got != expected {
                wrong.push((*cell, *half, expected, got));
            }
        }
        assert!(
            wrong.is_empty(),
            "float points {points}, float displacements {displacements}: {} of {} probes: {:?}",
            wrong.len(),
            probes.len(),
            &wrong[..wrong.len().min(4)]
        );
    }
}
