//! `NodeSources`, the map from a body's nodes back to the file's, against coordinates: each body
//! node's first file node lies where the body has that node, every file node a cell uses is
//! given exactly once (as a first node or as a further copy), and an unmerged copy is listed
//! with the body node it merged into. On meshes written by VTK (shuffled nodes and cells), uniform
//! and adaptive, with copies of some nodes added.

use std::path::Path;

use cgcontact::glam::DVec3;
use cgcontact_io::{DisplacementArray, HexMesh, MeshBody, NodeSources, read_hex_mesh};

fn fixture(folder: &str, name: &str) -> HexMesh {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(folder)
        .join(name);
    read_hex_mesh(&path, &DisplacementArray::default()).unwrap()
}

/// `mesh` with a copy of a node of every 7th cell, given to that cell in its place.
fn unmerged(mut mesh: HexMesh) -> HexMesh {
    for c in (0..mesh.cells.len()).step_by(7) {
        let node = mesh.cells[c][c % 8] as usize;
        mesh.points.push(mesh.points[node]);
        if let Some(u) = mesh.displacement.as_mut() {
            u.push(u[node]);
        }
        mesh.cells[c][c % 8] = (mesh.points.len() - 1) as u32;
    }
    mesh
}

/// Checks `sources` against the body's node positions (`position(slot)`) and the cells' nodes.
fn check(mesh: &HexMesh, sources: &NodeSources, slots: usize, position: impl Fn(usize) -> DVec3) {
    assert_eq!(sources.source_of_slot.len(), slots);
    let scale = mesh
        .points
        .iter()
        .fold(1.0f64, |m, p| m.max(p.abs().max_element()));
    let near = |a: DVec3, b: DVec3| (a - b).abs().max_element() <= 1e-9 * scale;
    let mut given = vec![0u32; mesh.points.len()];
    for (slot, &node) in sources.source_of_slot.iter().enumerate() {
        given[node as usize] += 1;
        assert!(
            near(mesh.points[node as usize], position(slot)),
            "slot {slot}"
        );
    }
    for &(node, slot) in &sources.duplicates {
        given[node] += 1;
        assert!(
            near(mesh.points[node], position(slot)),
            "copy {node} at {slot}"
        );
        assert_ne!(sources.source_of_slot[slot] as usize, node);
    }
    let mut used = vec![false; mesh.points.len()];
    for cell in &mesh.cells {
        for &n in cell {
            used[n as usize] = true;
        }
    }
    for (node, (&g, &u)) in given.iter().zip(&used).enumerate() {
        assert_eq!(g, u32::from(u), "file node {node}");
    }
    // The copies: every used file node beyond one per body node.
    let used = used.iter().filter(|&&u| u).count();
    assert_eq!(sources.duplicates.len(), used - slots);
}

#[test]
fn uniform_sources_lie_where_the_body_has_its_nodes() {
    for name in ["xml-appended-raw.vtu", "legacy-binary.vtk"] {
        for copy in [false, true] {
            let mut mesh = fixture("vtk-written", name);
            if copy {
                mesh = unmerged(mesh);
            }
            let MeshBody::Uniform(found) = mesh.to_body().unwrap() else {
                panic!("{name}: a uniform mesh");
            };
            let sources = NodeSources::uniform(&mesh, &found.body, &found.cells);
            assert_eq!(!sources.duplicates.is_empty(), copy, "{name}");
            let lattice = found.body.lattice();
            let nodes: Vec<usize> = found.body.nodes().collect();
            check(&mesh, &sources, nodes.len(), |slot| {
                lattice.node_position(lattice.node_ijk(nodes[slot]).unwrap())
            });
        }
    }
}

#[test]
fn adaptive_sources_lie_where_the_body_has_its_nodes() {
    for name in [
        "jumps.ascii.vtu",
        "balanced.appended.vtu",
        "aniso-1e3.binary.vtu",
    ] {
        for copy in [false, true] {
            let mut mesh = fixture("vtk-written-adaptive", name);
            if copy {
                mesh = unmerged(mesh);
            }
            let MeshBody::Adaptive(found) = mesh.to_body().unwrap() else {
                panic!("{name}: an adaptive mesh");
            };
            let sources = NodeSources::adaptive(&mesh, &found.body, &found.cells);
            assert_eq!(!sources.duplicates.is_empty(), copy, "{name}");
            check(&mesh, &sources, found.body.node_count(), |slot| {
                found.body.node_position(slot).unwrap()
            });
        }
    }
}
