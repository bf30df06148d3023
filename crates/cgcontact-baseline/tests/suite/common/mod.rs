//! Generated scenes for the baseline tests: a lattice body with a smooth large displacement field, seeded
//! node jitter and holes, and query points with known answers, near the boundary and far outside.
#![allow(dead_code)] // Each test binary uses part of this module.

pub mod adaptive;

use bitvec::vec::BitVec;
use cgcontact::glam::DVec3;
use cgcontact::hex8::Hex8Map;
use cgcontact::{Body, CellId, Lattice};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Parameters of a generated body.
#[derive(Clone, Copy, Debug)]
pub struct Spec {
    pub origin: DVec3,
    pub h: DVec3,
    pub cells: [u32; 3],
    /// Amplitude of the smooth field, in cell sizes (per axis).
    pub amplitude: f64,
    /// Node jitter, uniform in ±`jitter` cell sizes per component.
    pub jitter: f64,
    /// Probability that a cell is a hole (inactive).
    pub holes: f64,
    pub seed: u64,
}

/// The body of `spec`, checked valid (det J > 0 at every corner of every cell).
pub fn body(spec: &Spec) -> Body {
    let lattice = Lattice::new(spec.origin, spec.h, spec.cells).expect("valid lattice");
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut active: BitVec = (0..lattice.cell_count())
        .map(|_| !rng.random_bool(spec.holes))
        .collect();
    if active.not_any() {
        active.set(0, true);
    }
    let mut body = Body::undeformed(lattice, active).expect("non-empty body");
    let extent = lattice.upper() - lattice.origin();
    let (a, h, origin) = (spec.amplitude, spec.h, spec.origin);
    let tau = std::f64::consts::TAU;
    // Shears (x by y and z, y by z) and a z-only wave: the continuous field's gradient is upper
    // triangular with a diagonal near 1, so det J stays near 1 whatever the amplitude.
    let smooth = |x: DVec3| {
        let s = (x - origin) / extent;
        DVec3::new(
            a * h.x * ((tau * (s.y + 0.3 * s.z)).sin() - 0.3 * s.x),
            a * h.y * (tau * s.z + 0.5).sin(),
            0.25 * a * h.z * (tau * s.z).cos(),
        )
    };
    let mut noise: Vec<DVec3> = (0..lattice.node_count())
        .map(|_| {
            let r = DVec3::new(
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
            );
            r * spec.jitter * h
        })
        .collect();
    // Jitter that folds a sheared cell over is taken back from that cell's nodes, until none is left.
    for _ in 0..8 {
        body.update_displacements(|node, x, u| *u = smooth(x) + noise[node])
            .expect("finite displacements");
        let inverted = body.inverted_cells();
        if inverted.is_empty() {
            break;
        }
        for (cell, _) in inverted {
            let ijk = lattice.cell_ijk(cell).expect("inverted cells are active");
            for node in lattice.corner_nodes(ijk) {
                noise[node] = DVec3::ZERO;
            }
        }
    }
    if let Err(e) = body.validate() {
        panic!("scene {spec:?} is not valid: {e}");
    }
    body
}

/// Map of active `cell` in its local frame (with the core kernel) and the cell's lowest node.
pub fn cell_map(body: &Body, cell: CellId) -> (Hex8Map, DVec3) {
    body.cell_map(cell).expect("an active cell")
}

/// The point at local coordinates `xi` of active `cell`.
pub fn point_at(body: &Body, cell: CellId, xi: DVec3) -> DVec3 {
    let (map, low) = cell_map(body, cell);
    low + map.map(xi)
}

/// What a generated point is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// Strictly inside `cell` at `xi` (every |ξ_k| < 1).
    Volume { cell: CellId, xi: DVec3 },
    /// On a face, edge or node of `cell` (some |ξ_k| = 1 exactly).
    Shared { cell: CellId, xi: DVec3 },
    /// 2e-9 in ξ (≈ 1e-9 h) inside (`outside == false`) or outside an outer face of the body.
    NearBoundary { cell: CellId, outside: bool },
    /// Anywhere in the deformed body's box (holes, gaps, outside).
    InBox,
    /// Far outside the body.
    Far,
}

/// `n` points of each kind, deterministic in `seed`.
pub fn points(body: &Body, n: usize, seed: u64) -> Vec<(DVec3, Kind)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let lattice = body.lattice();
    let cells: Vec<CellId> = body.active_cells().collect();
    let mut out = Vec::new();
    let random_cell = |rng: &mut ChaCha8Rng| cells[rng.random_range(0..cells.len())];
    for _ in 0..n {
        let cell = random_cell(&mut rng);
        let xi = DVec3::new(
            rng.random_range(-0.999..0.999),
            rng.random_range(-0.999..0.999),
            rng.random_range(-0.999..0.999),
        );
        out.push((point_at(body, cell, xi), Kind::Volume { cell, xi }));
    }
    for _ in 0..n {
        let cell = random_cell(&mut rng);
        let xi = DVec3::from_array(std::array::from_fn(|_| match rng.random_range(0..4) {
            0 => -1.0,
            1 => 1.0,
            _ => rng.random_range(-1.0..1.0),
        }));
        out.push((point_at(body, cell, xi), Kind::Shared { cell, xi }));
    }
    // Outer faces: the neighbour across them is outside the lattice or a hole.
    let counts = lattice.cells();
    let mut faces = Vec::new();
    for cell in body.active_cells() {
        let ijk = lattice.cell_ijk(cell).expect("active cell");
        for axis in 0..3 {
            for side in [-1i64, 1] {
                let n = i64::from(ijk[axis]) + side;
                let outer = n < 0 || n >= i64::from(counts[axis]) || {
                    let mut nb = ijk;
                    nb[axis] = n as u32;
                    !body.is_active(lattice.cell_id(nb))
                };
                if outer {
                    faces.push((cell, axis, side as f64));
                }
            }
        }
    }
    for i in 0..n {
        let (cell, axis, side) = faces[rng.random_range(0..faces.len())];
        let outside = i % 2 == 0;
        let mut xi = DVec3::new(
            rng.random_range(-0.99..0.99),
            rng.random_range(-0.99..0.99),
            rng.random_range(-0.99..0.99),
        );
        xi[axis] = side * if outside { 1.0 + 2e-9 } else { 1.0 - 2e-9 };
        out.push((
            point_at(body, cell, xi),
            Kind::NearBoundary { cell, outside },
        ));
    }
    let u_max = body.max_displacement();
    let (low, high) = (lattice.origin() - u_max, lattice.upper() + u_max);
    for _ in 0..n {
        let t = DVec3::new(rng.random(), rng.random(), rng.random());
        out.push((low + (high - low) * t, Kind::InBox));
    }
    for i in 0..n.div_ceil(10) {
        let t = DVec3::new(rng.random(), rng.random(), rng.random());
        let far = if i % 2 == 0 {
            high + (high - low) * (0.1 + t)
        } else {
            low - (high - low) * (0.1 + t)
        };
        out.push((far, Kind::Far));
    }
    out
}
