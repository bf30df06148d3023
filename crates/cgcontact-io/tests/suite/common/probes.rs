//! Points made on a mesh as its file holds it, with their owners known independently: the
//! trilinear map of each cell's corners at ξ ∈ {−1, 0, 1}³ (nodes, edge and face centres, the
//! centre), whose owners are the cells whose closed box holds the point's lattice position.

use std::collections::BTreeSet;

use cgcontact::{AdaptiveBody, CORNER_OFFSETS, Lattice, Leaf};
use cgcontact_io::{CellMap, HexMesh};
use glam::DVec3;

/// The trilinear map of a cell's 8 deformed corners (VTK order) at `xi`.
pub fn map(corners: &[DVec3; 8], xi: DVec3) -> DVec3 {
    let mut x = DVec3::ZERO;
    for (c, offset) in CORNER_OFFSETS.iter().enumerate() {
        let s = DVec3::new(offset[0] as f64, offset[1] as f64, offset[2] as f64) * 2.0 - 1.0;
        let w = (DVec3::ONE + s * xi) * 0.5;
        x += corners[c] * (w.x * w.y * w.z);
    }
    x
}

/// Each cell's deformed corners as the file holds them.
pub fn deformed(mesh: &HexMesh, cell: usize) -> [DVec3; 8] {
    mesh.cells[cell].map(|n| {
        let u = mesh
            .displacement
            .as_ref()
            .map_or(DVec3::ZERO, |u| u[n as usize]);
        mesh.points[n as usize] + u
    })
}

/// Every point made from each cell at ξ ∈ {−1, 0, 1}³, with its cell and its position on the
/// finest lattice in half steps (`2 · low + s · (ξ + 1)` for a cell of `s` finest steps).
pub fn probes(mesh: &HexMesh, low: &[[u32; 3]], size: &[u32]) -> Vec<(DVec3, usize, [u32; 3])> {
    let mut out = Vec::new();
    for cell in 0..mesh.cells.len() {
        let corners = deformed(mesh, cell);
        for k in 0..27u32 {
            let step = [k % 3, (k / 3) % 3, k / 9];
            let xi = DVec3::new(step[0] as f64, step[1] as f64, step[2] as f64) - 1.0;
            let half = std::array::from_fn(|a| 2 * low[cell][a] + size[cell] * step[a]);
            out.push((map(&corners, xi), cell, half));
        }
    }
    out
}

/// The cells whose closed box holds the half-step lattice position `half`.
pub fn owners_of(low: &[[u32; 3]], size: &[u32], half: [u32; 3]) -> BTreeSet<usize> {
    (0..low.len())
        .filter(|&c| {
            (0..3).all(|a| 2 * low[c][a] <= half[a] && half[a] <= 2 * (low[c][a] + size[c]))
        })
        .collect()
}

pub fn found(owners: &cgcontact::Owners, cells: &CellMap) -> BTreeSet<usize> {
    owners
        .iter()
        .map(|hit| cells.input_cell(hit.cell).expect("a cell of the mesh"))
        .collect()
}

/// `body` displaced by a smooth field of 3 % of a base cell, and each leaf's lowest corner and
/// edge in steps of the finest lattice: what [`probes`] and [`owners_of`] take for its leaves.
pub fn displaced_leaf_boxes(body: &mut AdaptiveBody) -> (Vec<[u32; 3]>, Vec<u32>) {
    let (origin, h) = (body.lattice().origin(), body.lattice().h());
    body.update_independent(|_, x, u| {
        let t = (x - origin) / h;
        *u = 0.03 * h * DVec3::new(t.y.sin(), t.z.cos(), t.x.sin());
    })
    .unwrap();
    let finest = body.finest_level();
    let leaves = body.leaves();
    let low = (leaves.iter())
        .map(|l| l.ijk.map(|v| v << (finest - l.level)))
        .collect();
    let size = leaves.iter().map(|l| 1 << (finest - l.level)).collect();
    (low, size)
}

/// Base cells 3 × 2 × 2 of spacings floats cannot hold (0.3, 0.1, 0.7 from (0.1, −0.3, 0.7)):
/// the first refined `depth` times toward its lowest corner (level jumps of 1 to `depth`
/// against its neighbours), the last once.
pub fn corner_refined_body(depth: u32) -> AdaptiveBody {
    let cells = [3, 2, 2];
    let lattice = Lattice::new(DVec3::new(0.1, -0.3, 0.7), DVec3::new(0.3, 0.1, 0.7), cells);
    AdaptiveBody::from_leaves(lattice.unwrap(), corner_refined_leaves(cells, depth)).unwrap()
}

/// The leaves of base cells `cells`: the first base cell refined to `depth` levels toward its
/// lowest corner ([`refine_corner`]), the last one once, the others not.
pub fn corner_refined_leaves(cells: [u32; 3], depth: u32) -> Vec<Leaf> {
    let n = cells[0] * cells[1] * cells[2];
    let mut leaves: Vec<Leaf> = (1..n - 1)
        .map(|c| {
            let ijk = [
                c % cells[0],
                (c / cells[0]) % cells[1],
                c / (cells[0] * cells[1]),
            ];
            Leaf::new(0, ijk)
        })
        .collect();
    refine_corner(&mut leaves, depth);
    leaves.extend(Leaf::new(0, cells.map(|v| v - 1)).children());
    leaves
}

/// Base cell (0, 0, 0) halved `depth` times toward its lowest corner, appended to `leaves`: the
/// 7 upper children of each level, then the last lowest child (a jump of `depth` levels against
/// the cell's neighbours).
pub fn refine_corner(leaves: &mut Vec<Leaf>, depth: u32) {
    let mut corner = Leaf::new(0, [0, 0, 0]);
    for _ in 0..depth {
        let children = corner.children();
        leaves.extend_from_slice(&children[1..]);
        corner = children[0];
    }
    leaves.push(corner);
}
