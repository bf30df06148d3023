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
        found: &mut Option<Hit>,
    ) {
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
        let tau = options.inside_tol;
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
        if let Some(pyramid) = self.pyramid.as_ref().filter(|_| box_cells > RING_CELLS) {
            // A large box (a far-moved node, large strains): the pyramid finds the few cells whose
            // blocks reach x, and they are visited in the ring walk's order.
            let mut candidates = Candidates::new();
            pyramid.candidates(self.body, x, t_x, low, high, center, tau, &mut candidates);
            candidates.retain(|(_, ijk)| *ijk != first);
            candidates.sort_unstable_by_key(|(key, _)| *key);
            for (_, ijk) in candidates {
                let u = self.body.corner_displacements(ijk);
                if self.visit(
                    x,
                    ijk,
                    Some(K::displacement_map(&u)),
                    t_guess,
                    options,
                    collect,
                    inversions,
                    found,
                ) {
                    return;
                }
            }
            return;
        }
        let s = center.map(i64::from);
        let (lo, hi) = (low.map(i64::from), high.map(i64::from));
        let radius = (0..3)
            .map(|a| (s[a] - lo[a]).max(hi[a] - s[a]))
            .max()
            .unwrap_or(0);
        for r in 0..=radius {
            for k in (s[2] - r).max(lo[2])..=(s[2] + r).min(hi[2]) {
                for j in (s[1] - r).max(lo[1])..=(s[1] + r).min(hi[1]) {
                    // On the shell's top, bottom and sides the whole row is at distance r; elsewhere
                    // only its two ends are.
                    let whole_row = (k - s[2]).abs() == r || (j - s[1]).abs() == r;
                    let (from, to) = ((s[0] - r).max(lo[0]), (s[0] + r).min(hi[0]));
                    let step = if whole_row {
                        1
                    } else {
                        (2 * r).max(1) as usize
                    };
                    for i in (s[0] - r..=s[0] + r).step_by(step) {
                        let ijk = [i as u32, j as u32, k as u32];
                        if i < from || i > to || ijk == first {
                            continue;
                        }
                        if !self.body.is_active(lattice.cell_id(ijk)) {
                            continue;
                        }
                        let u = self.body.corner_displacements(ijk);
                        if !reaches(ijk, &u) {
                            continue;
                        }
                        if self.visit(
                            x,
                            ijk,
                            Some(K::displacement_map(&u)),
                            t_guess,
                            options,
                            collect,
                            inversions,
                            found,
                        ) {
                            return;
                        }
                    }
                }
            }
        }
    }
}
