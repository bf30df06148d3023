//! A sparse body (a few cells on a huge lattice, kept in hash maps, with no pyramid) whose cells
//! moved hundreds of cells apart: every search after a miss spans a box of millions of lattice
//! cells. The lattice locator answers from the body's active cells in that box, as brute force
//! does, and fast (it walked every lattice cell of the box before: about a second a point).

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId, Lattice, LatticeLocator, Locator, Settings};
use cgcontact_baseline::BruteForce;

use crate::common::point_at;

#[test]
fn clusters_moved_far_apart_on_a_sparse_body_agree_with_brute_force() {
    let n = 600;
    let lattice = Lattice::new(
        DVec3::new(-3.0, 7.5, 0.25),
        DVec3::new(0.5, 0.25, 0.4),
        [n; 3],
    )
    .unwrap();
    let h = lattice.h();
    // Two 2 × 2 × 2 clusters and a lone cell, far from each other.
    let cluster = |at: [u32; 3]| {
        (0..8u32).map(move |c| {
            lattice.cell_id([at[0] + (c & 1), at[1] + (c >> 1 & 1), at[2] + (c >> 2)])
        })
    };
    let cells: Vec<CellId> = cluster([100, 120, 140])
        .chain(cluster([400, 380, 360]))
        .chain([lattice.cell_id([250, 250, 250])])
        .collect();
    let mut body = Body::from_cells(lattice, cells.iter().copied()).unwrap();
    // The clusters swap places, more or less (±150 cells on every axis), gently sheared; the
    // lone cell stays.
    let middle = lattice.node_position([300, 300, 300]);
    body.update_displacements(|_, x, u| {
        // In cells from the middle: the first cluster at −200 along x, the second at +100, the
        // lone cell at −50.
        let t = (x - middle) / h;
        let moved = if t.x < -100.0 {
            150.0
        } else if t.x > 75.0 {
            -150.0
        } else {
            0.0
        };
        let shear = DVec3::new(0.1 * (0.3 * t.y).sin(), 0.0, 0.05 * (0.2 * t.x).cos());
        *u = (DVec3::splat(moved) + shear) * h;
    })
    .unwrap();
    let settings = Settings::default();
    let locator = LatticeLocator::new(&body, settings).unwrap();
    let brute = BruteForce::new(&body, settings).unwrap();
    let mut points = Vec::new();
    for (k, &cell) in cells.iter().enumerate() {
        let f = k as f64 / cells.len() as f64;
        // Inside, on a face, an edge and a node (shared within a cluster).
        for xi in [
            DVec3::new(0.3 - f, f - 0.5, 0.7 * f),
            DVec3::new(1.0, f - 0.5, 0.2),
            DVec3::new(-1.0, 1.0, 0.6 - f),
            DVec3::new(1.0, 1.0, 1.0),
        ] {
            points.push((point_at(&body, cell, xi), Some((cell, xi))));
        }
    }
    // Between the clusters and beside them: in the admitted box, in no cell.
    for k in 0..24 {
        let t = f64::from(k) / 24.0;
        let x = lattice.node_position([300, 300, 300])
            + DVec3::new(t - 0.5, (7.0 * t).sin(), (3.0 * t).cos()) * 180.0 * h;
        points.push((x, None));
    }
    let xs: Vec<DVec3> = points.iter().map(|&(x, _)| x).collect();
    let mut batched = Vec::new();
    locator.locate_all_into(&xs, &mut batched);
    for (p, &(x, made)) in points.iter().enumerate() {
        let cells = |owners: cgcontact::Owners| owners.iter().map(|h| h.cell).collect::<Vec<_>>();
        let owners = cells(locator.locate_owners(x).unwrap());
        let expected = cells(brute.locate_owners(x).unwrap());
        assert_eq!(owners, expected, "point {p} at {x}");
        let one = locator.locate(x).unwrap();
        assert_eq!(Ok(one), batched[p], "point {p}");
        match made {
            Some((cell, xi)) => {
                assert!(
                    owners.contains(&cell),
                    "point {p}: {cell:?} not among {owners:?}"
                );
                let hit = one.unwrap();
                if xi.abs().max_element() < 1.0 {
                    assert_eq!(hit.cell, cell, "point {p}");
                    assert!(
                        (hit.xi - xi).abs().max_element() < 1e-9,
                        "point {p}: {hit:?}"
                    );
                }
            }
            None => assert_eq!(one, None, "point {p}: {owners:?}"),
        }
    }
}
