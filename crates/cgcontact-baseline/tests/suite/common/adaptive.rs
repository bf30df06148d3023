//! Generated adaptive bodies: a base lattice refined at random (balanced or not, with holes),
//! deformed by a smooth field plus jitter on the independent nodes (hanging nodes filled from their
//! constraints), and query points with known (leaf, ξ), on shared and hanging faces, in the box and
//! far outside.

use std::collections::BTreeSet;

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, CellId, Lattice, Leaf};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::Kind;

/// Parameters of a generated adaptive body.
#[derive(Clone, Copy, Debug)]
pub struct AdaptiveSpec {
    pub origin: DVec3,
    pub h: DVec3,
    pub cells: [u32; 3],
    /// The deepest level a split may reach.
    pub levels: u8,
    /// How many random leaves are split in 8.
    pub splits: usize,
    /// Whether neighbouring leaves (faces, edges, corners) are then made to differ by ≤ 1 level.
    pub balanced: bool,
    /// Probability that a leaf is removed (a hole).
    pub holes: f64,
    /// Gradient of the smooth field, in base cells per base cell.
    pub strain: f64,
    /// Jitter of the independent nodes, in finest spacings.
    pub jitter: f64,
    pub seed: u64,
}

/// The leaf of `leaves` holding the finest cell `q` (level `finest`), by walking up its ancestors.
fn holder(leaves: &BTreeSet<Leaf>, q: [u32; 3], finest: u8) -> Option<Leaf> {
    (0..=finest).find_map(|level| {
        let leaf = Leaf::new(level, q.map(|v| v >> (finest - level)));
        leaves.contains(&leaf).then_some(leaf)
    })
}

/// A random refinement of the full lattice of `spec`, in shuffled order.
pub fn refine(spec: &AdaptiveSpec, rng: &mut ChaCha8Rng) -> Vec<Leaf> {
    let cells = spec.cells;
    let mut leaves: BTreeSet<Leaf> = BTreeSet::new();
    for k in 0..cells[2] {
        for j in 0..cells[1] {
            for i in 0..cells[0] {
                leaves.insert(Leaf::new(0, [i, j, k]));
            }
        }
    }
    for _ in 0..spec.splits {
        let splittable: Vec<Leaf> = leaves
            .iter()
            .copied()
            .filter(|l| l.level < spec.levels)
            .collect();
        if splittable.is_empty() {
            break;
        }
        let leaf = splittable[rng.random_range(0..splittable.len())];
        leaves.remove(&leaf);
        leaves.extend(leaf.children());
    }
    if spec.balanced {
        let finest = spec.levels;
        let limit = cells.map(|n| i64::from(n << finest));
        // Split any leaf more than one level coarser than a leaf touching it, until none is.
        'balance: loop {
            for leaf in &leaves {
                let s = finest - leaf.level;
                let lo = leaf.ijk.map(|v| i64::from(v << s));
                let size = 1i64 << s;
                for d in 0..27 {
                    let off = [d % 3, (d / 3) % 3, d / 9].map(|o| o as i64 - 1);
                    let q: [i64; 3] = [0, 1, 2].map(|a| match off[a] {
                        -1 => lo[a] - 1,
                        0 => lo[a],
                        _ => lo[a] + size,
                    });
                    if off == [0, 0, 0] || (0..3).any(|a| q[a] < 0 || q[a] >= limit[a]) {
                        continue;
                    }
                    if let Some(coarse) = holder(&leaves, q.map(|v| v as u32), finest)
                        && coarse.level + 1 < leaf.level
                    {
                        leaves.remove(&coarse);
                        leaves.extend(coarse.children());
                        continue 'balance;
                    }
                }
            }
            break;
        }
    }
    let mut out: Vec<Leaf> = leaves
        .into_iter()
        .filter(|_| !rng.random_bool(spec.holes))
        .collect();
    if out.is_empty() {
        out.push(Leaf::new(0, [0, 0, 0]));
    }
    for i in (1..out.len()).rev() {
        out.swap(i, rng.random_range(0..=i));
    }
    out
}

/// The body of `spec`, deformed and checked valid (no inverted leaf).
pub fn body(spec: &AdaptiveSpec) -> AdaptiveBody {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let lattice = Lattice::new(spec.origin, spec.h, spec.cells).expect("valid lattice");
    let leaves = refine(spec, &mut rng);
    let mut body = AdaptiveBody::from_leaves(lattice, leaves).expect("valid leaves");
    let h = spec.h;
    let fine = body.spacing(body.finest_level()).min_element();
    let (strain, jitter, origin) = (spec.strain, spec.jitter, spec.origin);
    body.update_independent(|_, x, u| {
        let t = (x - origin) / h;
        let noise = DVec3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        );
        *u = strain
            * h
            * DVec3::new(
                (0.7 * t.y + 0.3 * t.z).sin(),
                (0.5 * t.z - 0.4 * t.x).cos(),
                (0.6 * t.x + 0.2 * t.y).sin(),
            )
            + noise * jitter * fine;
    })
    .expect("finite displacements");
    if let Err(e) = body.validate() {
        panic!("adaptive scene {spec:?} is not valid: {e}");
    }
    body
}

/// `n` points of each kind (volume, shared, ±2e-9 in ξ off outer faces, box; a tenth far),
/// deterministic in `seed`. Shared points have each ξ component ±1 with probability 1/2, so that
/// many lie on hanging faces, edges and nodes.
pub fn points(body: &AdaptiveBody, n: usize, seed: u64) -> Vec<(DVec3, Kind)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let leaves = body.cell_count() as u32;
    for _ in 0..n {
        let cell = CellId(rng.random_range(0..leaves));
        let xi = DVec3::new(
            rng.random_range(-0.999..0.999),
            rng.random_range(-0.999..0.999),
            rng.random_range(-0.999..0.999),
        );
        let x = body.point_at(cell, xi).expect("a leaf");
        out.push((x, Kind::Volume { cell, xi }));
    }
    for _ in 0..n {
        let cell = CellId(rng.random_range(0..leaves));
        let xi = DVec3::from_array(std::array::from_fn(|_| match rng.random_range(0..4) {
            0 => -1.0,
            1 => 1.0,
            _ => rng.random_range(-1.0..1.0),
        }));
        let x = body.point_at(cell, xi).expect("a leaf");
        out.push((x, Kind::Shared { cell, xi }));
    }
    // Outer faces of leaves: just beyond the undeformed face centre lies no leaf (outside the
    // lattice, or a hole).
    let mut faces = Vec::new();
    for (id, leaf) in body.leaves().iter().enumerate() {
        let h = body.spacing(leaf.level);
        let centre = body.leaf_origin(leaf) + 0.5 * h;
        for axis in 0..3 {
            for side in [-1.0, 1.0] {
                let mut beyond = centre;
                beyond[axis] += side * 0.501 * h[axis];
                if body.leaf_at(beyond).is_none() {
                    faces.push((CellId(id as u32), axis, side));
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
        let x = body.point_at(cell, xi).expect("a leaf");
        out.push((x, Kind::NearBoundary { cell, outside }));
    }
    let u_max = body.max_displacement();
    let lattice = body.lattice();
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
