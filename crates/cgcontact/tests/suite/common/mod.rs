//! Deterministic bodies and points with known answers for the core's integration tests.
#![allow(dead_code, reason = "each test file uses its own subset")]

use bitvec::vec::BitVec;
use cgcontact::hex8::{Hex8Map, Kernel};
use cgcontact::{Body, CellId, Lattice};
use glam::DVec3;

/// SplitMix64: a tiny deterministic generator (the core has no rand dependency).
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn vec(&mut self, lo: f64, hi: f64) -> DVec3 {
        DVec3::new(
            self.uniform(lo, hi),
            self.uniform(lo, hi),
            self.uniform(lo, hi),
        )
    }
}

/// A body on `lattice` with every cell active except about `holes` of them, displaced by a smooth
/// field of amplitude `amplitude` (in units of h, per axis) plus a rigid shift `shift` (units of h) plus
/// random nodal jitter of `jitter` h. Panics if the result has an inverted cell (tests choose values
/// that keep det J > 0).
pub fn body(
    lattice: Lattice,
    holes: f64,
    amplitude: f64,
    shift: DVec3,
    jitter: f64,
    seed: u64,
) -> Body {
    let mut rng = Rng(seed);
    let mut active = BitVec::repeat(true, lattice.cell_count());
    for c in 0..lattice.cell_count() {
        if rng.uniform(0.0, 1.0) < holes {
            active.set(c, false);
        }
    }
    if active.not_any() {
        active.set(0, true);
    }
    let mut body = Body::undeformed(lattice, active).unwrap();
    let h = lattice.h();
    let size = lattice.upper() - lattice.origin();
    let phase = rng.vec(0.0, 6.0);
    body.update_displacements(|_, x, u| {
        let t = (x - lattice.origin()) / size * std::f64::consts::TAU;
        let smooth = DVec3::new(
            (t.y + phase.x).sin() * (t.z * 0.5).cos(),
            (t.z + phase.y).sin() * (t.x * 0.5).cos(),
            (t.x + phase.z).sin() * (t.y * 0.5).cos(),
        );
        *u = h * (shift + amplitude * smooth + jitter * rng.vec(-1.0, 1.0));
    })
    .unwrap();
    body.validate().expect("test bodies are valid");
    body
}

/// Corner displacements of an active cell, from the public API.
pub fn corner_u(body: &Body, cell: CellId) -> [DVec3; 8] {
    let l = body.lattice();
    let ijk = l.cell_ijk(cell).unwrap();
    l.corner_nodes(ijk).map(|n| body.displacement(n).unwrap())
}

/// The deformed point of `cell` at `xi`, computed in the cell's local frame.
pub fn point_at(body: &Body, cell: CellId, xi: DVec3) -> DVec3 {
    body.point_at(cell, xi).unwrap()
}

/// The oracle: every active cell that holds `x`, by exhaustive exact inversion with the f64
/// locator's allowances ([`cgcontact::InsideTolerance`]).
pub fn brute_owners(body: &Body, x: DVec3) -> Vec<CellId> {
    let l = body.lattice();
    let settings = cgcontact::Settings::default();
    let u_max = body.max_displacement();
    let options = cgcontact::InsideTolerance::new(&settings, l, u_max).options(&settings, x);
    body.active_cells()
        .filter(|&cell| {
            let ijk = l.cell_ijk(cell).unwrap();
            let map = Hex8Map::lattice_cell(l.h(), &corner_u(body, cell));
            map.invert(x - l.node_position(ijk), DVec3::ZERO, &options)
                .status
                == cgcontact::hex8::Status::Inside
        })
        .collect()
}

/// Linear deformations x = o + A (X − o) of a body, that move each axis's rounding into the
/// others' ξ: shears and rotations. (name, A's rows.)
pub fn linear_maps() -> Vec<(&'static str, [DVec3; 3])> {
    let rotation = |axis: DVec3, angle: f64| {
        let q = glam::DQuat::from_axis_angle(axis.normalize(), angle);
        let m = glam::DMat3::from_quat(q).transpose();
        [m.x_axis, m.y_axis, m.z_axis]
    };
    vec![
        (
            "x += 10 z",
            [DVec3::new(1.0, 0.0, 10.0), DVec3::Y, DVec3::Z],
        ),
        (
            "x += 1e3 z",
            [DVec3::new(1.0, 0.0, 1e3), DVec3::Y, DVec3::Z],
        ),
        (
            "z += 1e3 y",
            [DVec3::X, DVec3::Y, DVec3::new(0.0, 1e3, 1.0)],
        ),
        (
            "rotated 45° about z",
            rotation(DVec3::Z, std::f64::consts::FRAC_PI_4),
        ),
        ("rotated 30° about (1, 1, 1)", rotation(DVec3::ONE, 0.5)),
    ]
}
