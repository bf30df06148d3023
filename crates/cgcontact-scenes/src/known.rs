//! Query points built from known (cell, ξ): every answer is checkable.

use cgcontact::glam::DVec3;
use cgcontact::{AdaptiveBody, Body, CellId};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A point made from a known cell and local coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownPoint {
    /// The point, x = X(ξ) + u(ξ) of `cell`.
    pub x: DVec3,
    /// The cell it was made in.
    pub cell: CellId,
    /// Its local coordinates there.
    pub xi: DVec3,
}

/// `count` points in random active cells of `body` at random ξ ∈ [−1, 1]³ (uniform), from `seed`.
#[must_use]
pub fn known_points(body: &Body, count: usize, seed: u64) -> Vec<KnownPoint> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let active: Vec<CellId> = body.active_cells().collect();
    (0..count)
        .map(|_| {
            let cell = active[rng.random_range(0..active.len())];
            let xi = DVec3::new(
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
            );
            let x = body.point_at(cell, xi).expect("an active cell");
            KnownPoint { x, cell, xi }
        })
        .collect()
}

/// How [`adaptive_known_points`] picks the leaf of each point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LeafDraw {
    /// Every leaf equally likely: points crowd where the mesh is refined, as contact queries do
    /// (the refinement is where the contact is), and every level is exercised in proportion to its
    /// leaves. On a one-level body this is [`known_points`], draw for draw.
    #[default]
    PerLeaf,
    /// Leaves weighted by their undeformed volume (8^(finest − level)): points uniform over the
    /// undeformed body, so most land in the coarse leaves.
    ByVolume,
}

/// `count` points in random leaves of `body` (picked as `draw` says) at random ξ ∈ [−1, 1]³
/// (uniform), from `seed`; a point's `cell` is its leaf's id.
#[must_use]
pub fn adaptive_known_points(
    body: &AdaptiveBody,
    count: usize,
    draw: LeafDraw,
    seed: u64,
) -> Vec<KnownPoint> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let leaves = body.cell_count();
    // Volumes in finest cells: 8^20 × 2^31 leaves fits in u128.
    let cumulative: Vec<u128> = match draw {
        LeafDraw::PerLeaf => Vec::new(),
        LeafDraw::ByVolume => {
            let finest = body.finest_level();
            body.leaves()
                .iter()
                .scan(0u128, |sum, leaf| {
                    *sum += 1u128 << (3 * u32::from(finest - leaf.level));
                    Some(*sum)
                })
                .collect()
        }
    };
    (0..count)
        .map(|_| {
            let id = match draw {
                // The same draws as `known_points` (a usize range), so one-level bodies agree.
                LeafDraw::PerLeaf => rng.random_range(0..leaves),
                LeafDraw::ByVolume => {
                    let total = *cumulative.last().expect("a body has at least one leaf");
                    let at = rng.random_range(0..total);
                    cumulative.partition_point(|&c| c <= at)
                }
            };
            let cell = CellId(id as u32);
            let xi = DVec3::new(
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
                rng.random_range(-1.0..=1.0),
            );
            let x = body
                .point_at(cell, xi)
                .expect("a leaf id below the leaf count");
            KnownPoint { x, cell, xi }
        })
        .collect()
}
