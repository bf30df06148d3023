//! Query points built from known (cell, ξ): every answer is checkable.

use cgcontact::glam::DVec3;
use cgcontact::{Body, CellId};
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
