//! After a miss in the predicted cell: every other cell that can hold the point, in rings of growing
//! Chebyshev distance around the refined guess ([`Rings`]), or, where the displacements spread over
//! many cells, the candidates of the block-range octree (`reach.rs`) in the same order.

use glam::DVec3;

use super::scalar::Collect;
use super::{Hit, LatticeLocator};
use crate::hex8::{Kernel, NewtonOptions};
use crate::reach::{self, Candidates, RING_CELLS};
use crate::settings::CandidateOrder;

impl LatticeLocator<'_> {
    /// The search after a miss in the predicted cell `first`: every other active cell that can
    /// hold x, nearest first. Kept out of line: the common path stays small.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn search_rings<K: Kernel>(
        &self,
        x: DVec3,
        t_x: DVec3,
        t_guess: DVec3,
        first: [u32; 3],
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let lattice = self.body.lattice();
        let h = lattice.h();
        // A miss: where the displacement varies fast, ũ(x) is a poor estimate of u at the undeformed
        // point. Refine the guess by the fixed point X ← x − ũ(X) before ordering the rings around it.
        let t_guess = match self.settings.order {
            CandidateOrder::Predicted => self.refine_guess::<K>(t_x, t_guess),
            CandidateOrder::Undeformed => t_guess,
        };
        // Then every other active cell meeting x − the displacement range (widened by the inside
        // tolerance) whose own shifted box holds x, in rings of growing Chebyshev distance around
        // the predicted cell.
        // The filters widen by the largest of the per-axis tolerances of an undeformed cell.
        let tau = self.admit.tau(options);
        let range = self.u_range;
        let w = reach::widening(h, range.high - range.low, tau);
        let low = lattice.clamped_cell(t_x - (range.high + w) * self.inv_h);
        let high = lattice.clamped_cell(t_x - (range.low - w) * self.inv_h);
        let center = [0, 1, 2].map(|a| lattice.clamped_cell(t_guess)[a].clamp(low[a], high[a]));
        // A cell that the displacements of its own corners cannot bring to x is never inverted.
        let reaches = |ijk: [u32; 3], u: &[DVec3; 8]| {
            reach::cell_reaches(x - lattice.node_position(ijk), h, u, tau)
        };
        let box_cells: u64 = (0..3).map(|a| u64::from(high[a] - low[a] + 1)).product();
        // A large box: its candidates gathered, then visited in the ring walk's order.
        let mut candidates = Candidates::new();
        let gathered =
            if let Some(pyramid) = self.pyramid.as_ref().filter(|_| box_cells > RING_CELLS) {
                // A far-moved node, large strains: the pyramid finds the few cells whose
                // blocks reach x.
                pyramid.candidates(self.body, x, t_x, low, high, center, tau, &mut candidates);
                candidates.retain(|(_, ijk)| *ijk != first);
                true
            } else if box_cells > RING_CELLS && self.body.box_outnumbers_cells(box_cells) {
                // Far more lattice cells than the body has (a sparse body, which keeps no pyramid,
                // moved far): its active cells in the box that reach x.
                self.body.for_each_active_in(low, high, |ijk| {
                    if ijk != first && reaches(ijk, &self.body.corner_displacements(ijk)) {
                        candidates.push((reach::ring_key(ijk, center), ijk));
                    }
                });
                true
            } else {
                false
            };
        if gathered {
            candidates.sort_unstable_by_key(|(key, _)| *key);
            for (_, ijk) in candidates {
                let u = self.body.corner_displacements(ijk);
                let map = Some(self.u_map::<K>(&u));
                let hit = self.visit(x, ijk, map, t_guess, options, collect, inversions);
                if hit.is_some() {
                    return hit;
                }
            }
            return None;
        }
        for ijk in Rings::new(low, high, center) {
            if ijk == first || !self.body.is_active(lattice.cell_id(ijk)) {
                continue;
            }
            let u = self.body.corner_displacements(ijk);
            if !reaches(ijk, &u) {
                continue;
            }
            let map = Some(self.u_map::<K>(&u));
            let hit = self.visit(x, ijk, map, t_guess, options, collect, inversions);
            if hit.is_some() {
                return hit;
            }
        }
        None
    }
}

/// The cells of the box [`low`, `high`] in rings of growing Chebyshev distance around `center` (a
/// cell of the box): each cell once, nearest shell first, and within a shell by z, then y, then x
/// (the order of `reach::ring_key`, which the block-range candidates are sorted by).
#[derive(Clone, Debug)]
pub(crate) struct Rings {
    center: [i64; 3],
    low: [i64; 3],
    high: [i64; 3],
    radius: i64,
    /// The current shell, row (k, j), next x to look at, and the step along x.
    r: i64,
    k: i64,
    j: i64,
    i: i64,
    step: i64,
}

impl Rings {
    pub(crate) fn new(low: [u32; 3], high: [u32; 3], center: [u32; 3]) -> Self {
        let (center, low, high) = (
            center.map(i64::from),
            low.map(i64::from),
            high.map(i64::from),
        );
        let radius = (0..3)
            .map(|a| (center[a] - low[a]).max(high[a] - center[a]))
            .max()
            .unwrap_or(0);
        let mut rings = Self {
            center,
            low,
            high,
            radius,
            r: 0,
            k: center[2],
            j: center[1],
            i: 0,
            step: 1,
        };
        rings.start_row();
        rings
    }

    /// Start row (k, j) of shell r: on the shell's top, bottom and sides the whole row is at
    /// distance r; elsewhere only its two ends are.
    fn start_row(&mut self) {
        let (c, r) = (self.center, self.r);
        let whole_row = (self.k - c[2]).abs() == r || (self.j - c[1]).abs() == r;
        self.step = if whole_row { 1 } else { (2 * r).max(1) };
        self.i = c[0] - r;
    }
}

impl Iterator for Rings {
    type Item = [u32; 3];

    fn next(&mut self) -> Option<[u32; 3]> {
        let (c, lo, hi) = (self.center, self.low, self.high);
        loop {
            if self.r > self.radius {
                return None;
            }
            let r = self.r;
            if self.i <= c[0] + r {
                let i = self.i;
                self.i += self.step;
                if i >= (c[0] - r).max(lo[0]) && i <= (c[0] + r).min(hi[0]) {
                    // In the box: every index is between 0 and a u32 bound.
                    return Some([i as u32, self.j as u32, self.k as u32]);
                }
                continue;
            }
            // The next row of this shell, or the next shell.
            self.j += 1;
            if self.j > (c[1] + r).min(hi[1]) {
                self.k += 1;
                self.j = (c[1] - r).max(lo[1]);
            }
            if self.k > (c[2] + r).min(hi[2]) {
                self.r += 1;
                let r = self.r;
                self.k = (c[2] - r).max(lo[2]);
                self.j = (c[1] - r).max(lo[1]);
            }
            self.start_row();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each cell of the box exactly once, nearest shell first, z then y then x within a shell: the
    /// box's cells sorted by their ring key, for boxes and centres of every shape.
    #[test]
    fn rings_visit_each_cell_once_nearest_shell_first() {
        let mut state = 11u64;
        let mut next = |n: u32| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) % u64::from(n)) as u32
        };
        for _ in 0..300 {
            let low = [next(5), next(5), next(5)];
            let high = low.map(|l| l + next(6));
            let center = [0, 1, 2].map(|a| low[a] + next(high[a] - low[a] + 1));
            let walked: Vec<[u32; 3]> = Rings::new(low, high, center).collect();
            let mut expected = Vec::new();
            for k in low[2]..=high[2] {
                for j in low[1]..=high[1] {
                    for i in low[0]..=high[0] {
                        expected.push([i, j, k]);
                    }
                }
            }
            expected.sort_by_key(|&ijk| reach::ring_key(ijk, center));
            assert_eq!(walked, expected, "box {low:?}..{high:?} around {center:?}");
        }
        assert_eq!(Rings::new([3, 3, 3], [3, 3, 3], [3, 3, 3]).count(), 1);
    }
}
