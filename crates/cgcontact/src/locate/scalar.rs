//! The search one point at a time: admit the point, predict its cell, invert that cell; after a
//! miss, `rings.rs` visits the other cells that can hold it.

use glam::DVec3;

use super::{Hit, LatticeLocator, Owners};
use crate::PointError;
use crate::hex8::{Hex8Map, Hex8Map32, Inversion, Kernel, NewtonOptions, Status};
use crate::settings::{CandidateOrder, Precision};

/// Lattice coordinates of a cell's lowest node.
#[inline]
pub(super) fn lattice_point(ijk: [u32; 3]) -> DVec3 {
    DVec3::new(f64::from(ijk[0]), f64::from(ijk[1]), f64::from(ijk[2]))
}

/// Local coordinates in cell `ijk` of the undeformed point at lattice coordinates `t`.
#[inline]
pub(super) fn undeformed_xi(t: DVec3, ijk: [u32; 3]) -> DVec3 {
    2.0 * (t - lattice_point(ijk)) - 1.0
}

/// What a candidate search does with each inside hit.
pub(crate) enum Collect<'o> {
    First,
    All(&'o mut Owners),
}

impl LatticeLocator<'_> {
    /// The search for `x`; the inversions it tried go to `tried`. `#[inline]`, as `search_with`:
    /// without it, `locate` (in another codegen unit) called it and copied the hit through the stack,
    /// which cost the point-by-point `locate` a quarter of its time (perf: stalls on those copies).
    #[inline]
    pub(super) fn search(
        &self,
        x: DVec3,
        mut collect: Collect<'_>,
        tried: &mut u32,
    ) -> Result<Option<Hit>, PointError> {
        let Some(length) = self.admit.admit(x)? else {
            return Ok(None);
        };
        let options = self.admit.options(&self.newton, length);
        Ok(match self.settings.precision {
            Precision::F64 => self.search_with::<Hex8Map>(x, &options, &mut collect, tried),
            Precision::F32 => self.search_with::<Hex8Map32>(x, &options, &mut collect, tried),
        })
    }

    /// The first hit of the search for `x`, already admitted with `options` (its inside
    /// tolerance): [`LatticeLocator::search`] after `admit`, for a caller that admitted `x` itself.
    #[inline]
    pub(super) fn search_admitted(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        tried: &mut u32,
    ) -> Option<Hit> {
        let collect = &mut Collect::First;
        match self.settings.precision {
            Precision::F64 => self.search_with::<Hex8Map>(x, options, collect, tried),
            Precision::F32 => self.search_with::<Hex8Map32>(x, options, collect, tried),
        }
    }

    /// Invert candidate cell `ijk` (active) for `x`; `t_guess` is the predicted undeformed position in
    /// lattice coordinates (gives the starting ξ), `u_map` the cell's displacement map when the caller
    /// already has it.
    #[inline]
    fn try_cell<K: Kernel>(
        &self,
        x: DVec3,
        ijk: [u32; 3],
        t_guess: DVec3,
        u_map: Option<K>,
        options: &NewtonOptions,
    ) -> Inversion {
        let lattice = self.body.lattice();
        let map = match u_map {
            Some(mut map) => {
                map.add_lattice(lattice.h());
                map
            }
            None => self.cell_map::<K>(ijk),
        };
        let xi0 = undeformed_xi(t_guess, ijk);
        map.invert_f64(self.local::<K>(x, ijk), xi0, options)
    }

    /// The map of cell `ijk` (active) in the kernel's frame.
    #[inline(always)]
    pub(super) fn cell_map<K: Kernel>(&self, ijk: [u32; 3]) -> K {
        let h = self.body.lattice().h();
        let u = self.body.corner_displacements(ijk);
        self.frame.corners::<K, _>(&u, |u| K::lattice_cell(h, u))
    }

    /// The displacement map of corner displacements `u` in the kernel's frame.
    #[inline(always)]
    pub(super) fn u_map<K: Kernel>(&self, u: &[DVec3; 8]) -> K {
        self.frame.corners::<K, _>(u, K::displacement_map)
    }

    /// `x` in the local frame of cell `ijk` (its lowest undeformed node at the origin), shifted
    /// as the kernel's frame is.
    #[inline(always)]
    pub(super) fn local<K: Kernel>(&self, x: DVec3, ijk: [u32; 3]) -> DVec3 {
        self.frame.point::<K>(x) - self.body.lattice().node_position(ijk)
    }

    /// The guess x − ũ in lattice coordinates, ũ the displacement map `u_map` of `cell` evaluated at
    /// lattice coordinates `t_at` (clamped into the cell).
    #[inline]
    fn guess<K: Kernel>(&self, t_x: DVec3, cell: [u32; 3], t_at: DVec3, u_map: &K) -> DVec3 {
        let xi = undeformed_xi(t_at, cell).clamp(DVec3::NEG_ONE, DVec3::ONE);
        t_x - self.frame.displacement::<K>(u_map.map_f64(xi)) * self.inv_h
    }

    /// Two steps of the fixed point X ← x − ũ(X) in lattice coordinates (ũ interpolated on the
    /// undeformed lattice, inactive corners as zero), from `t_guess`.
    pub(super) fn refine_guess<K: Kernel>(&self, t_x: DVec3, mut t_guess: DVec3) -> DVec3 {
        let lattice = self.body.lattice();
        for _ in 0..2 {
            let cell = lattice.clamped_cell(t_guess);
            let u_map = self.u_map::<K>(&self.body.corner_displacements_or_zero(cell));
            t_guess = self.guess(t_x, cell, t_guess, &u_map);
        }
        t_guess
    }

    /// Invert `ijk` (active) for `x` and collect the hit: `Some` when the search is over (the first
    /// hit wanted, and found).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn visit<K: Kernel>(
        &self,
        x: DVec3,
        ijk: [u32; 3],
        u_map: Option<K>,
        t_guess: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let inversion = self.try_cell::<K>(x, ijk, t_guess, u_map, options);
        *inversions += 1;
        if inversion.status != Status::Inside {
            return None;
        }
        let hit = Hit {
            cell: self.body.lattice().cell_id(ijk),
            xi: inversion.xi.clamp(DVec3::NEG_ONE, DVec3::ONE),
            iterations: inversion.iterations,
            residual: inversion.residual,
            inversions: *inversions,
        };
        match collect {
            Collect::First => Some(hit),
            Collect::All(owners) => {
                owners.push(hit);
                None
            }
        }
    }

    #[inline]
    fn search_with<K: Kernel>(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let lattice = self.body.lattice();
        let t_x = (x - lattice.origin()) * self.inv_h;
        let cell_x = lattice.clamped_cell(t_x);
        // The displacement map of the cell holding x (corners of inactive cells count as undisplaced:
        // it only serves the guess), and the predicted undeformed position x − ũ, ũ interpolated at x.
        // Kept in one place, never moved: it is 192 bytes, and moves cost a memcpy call each.
        let u_map_x = self.u_map::<K>(&self.body.corner_displacements_or_zero(cell_x));
        let t_guess = match self.settings.order {
            CandidateOrder::Predicted => self.guess(t_x, cell_x, t_x, &u_map_x),
            CandidateOrder::Undeformed => t_x,
        };
        let first = lattice.clamped_cell(t_guess);
        // The predicted cell first, without the range test: it holds the point almost always, and
        // when it is the cell holding x its displacement map is already built.
        if self.body.is_active(lattice.cell_id(first)) {
            let reuse = (first == cell_x).then_some(u_map_x);
            let hit = self.visit(x, first, reuse, t_guess, options, &mut *collect, inversions);
            if hit.is_some() {
                return hit;
            }
        }
        self.search_rings::<K>(x, t_x, t_guess, first, options, collect, inversions)
    }
}
