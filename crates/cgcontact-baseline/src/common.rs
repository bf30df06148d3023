//! What every strategy shares: the body (uniform or adaptive), input checks, the per-point inside
//! tolerance, and the exact inversion of one cell in its local frame with the core's kernel.

use cgcontact::glam::DVec3;
use cgcontact::hex8::{Hex8Map, Hex8Map32, Kernel, NewtonOptions, Status};
use cgcontact::{
    AdaptiveBody, Body, CORNER_OFFSETS, CellId, Error, Frame, Hit, InsideTolerance, Lattice,
    Owners, PointError, Precision, Settings,
};

/// The body a strategy searches: a uniform lattice body or an h-adaptive one.
///
/// Every constructor of this crate takes `impl Into<BodyRef>`, so `&Body` and `&AdaptiveBody` can be
/// passed as they are. The cells of a uniform body are its active lattice cells; those of an
/// adaptive body are its leaves, `CellId(i)` being the position in [`AdaptiveBody::leaves`], as
/// [`cgcontact::AdaptiveLocator`] reports them.
#[derive(Clone, Copy, Debug)]
pub enum BodyRef<'a> {
    /// A body on one lattice, with active and inactive cells.
    Uniform(&'a Body),
    /// A body of leaf cells at several refinement levels of a base lattice.
    Adaptive(&'a AdaptiveBody),
}

impl<'a> From<&'a Body> for BodyRef<'a> {
    fn from(body: &'a Body) -> Self {
        Self::Uniform(body)
    }
}

impl<'a> From<&'a AdaptiveBody> for BodyRef<'a> {
    fn from(body: &'a AdaptiveBody) -> Self {
        Self::Adaptive(body)
    }
}

impl<'a> BodyRef<'a> {
    /// The lattice: a uniform body's, or an adaptive body's base lattice (level 0).
    #[must_use]
    pub fn lattice(&self) -> &'a Lattice {
        match self {
            Self::Uniform(body) => body.lattice(),
            Self::Adaptive(body) => body.lattice(),
        }
    }

    /// Number of cells searched: active cells, or leaves.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        match self {
            Self::Uniform(body) => body.active_count(),
            Self::Adaptive(body) => body.cell_count(),
        }
    }

    /// The cells searched, ascending: active cells, or leaf ids.
    #[must_use]
    pub fn cells(&self) -> Box<dyn Iterator<Item = CellId> + 'a> {
        match self {
            Self::Uniform(body) => body.active_cells(),
            Self::Adaptive(body) => Box::new((0..body.cell_count() as u32).map(CellId)),
        }
    }

    /// Refinement level of `cell`: 0 for an active cell of a uniform body, the leaf's level on an
    /// adaptive one; `None` when `cell` is none of the body's cells.
    #[must_use]
    pub fn level(&self, cell: CellId) -> Option<u8> {
        match self {
            Self::Uniform(body) => body.is_active(cell).then_some(0),
            Self::Adaptive(body) => body.leaves().get(cell.index()).map(|leaf| leaf.level),
        }
    }

    /// [`BodyRef::level`] of a cell the strategies took from the body (no check on a uniform
    /// body: the filters' inner loops call it).
    pub(crate) fn level_of(&self, cell: CellId) -> u8 {
        match self {
            Self::Uniform(_) => 0,
            Self::Adaptive(body) => {
                body.leaves()
                    .get(cell.index())
                    .expect("a leaf of the body")
                    .level
            }
        }
    }

    /// The deepest level of any cell (0 for a uniform body).
    #[must_use]
    pub fn finest_level(&self) -> u8 {
        match self {
            Self::Uniform(_) => 0,
            Self::Adaptive(body) => body.finest_level(),
        }
    }

    /// Largest displacement component per axis (absolute).
    #[must_use]
    pub fn max_displacement(&self) -> DVec3 {
        match self {
            Self::Uniform(body) => body.max_displacement(),
            Self::Adaptive(body) => body.max_displacement(),
        }
    }

    /// The cells whose Jacobian determinant is not positive at some corner, with the smallest
    /// corner determinant over the undeformed one, ascending by cell ([`Body::inverted_cells`],
    /// [`AdaptiveBody::inverted_cells`]).
    #[must_use]
    pub fn inverted_cells(&self) -> Vec<(CellId, f64)> {
        match self {
            Self::Uniform(body) => body.inverted_cells(),
            Self::Adaptive(body) => body.inverted_cells(),
        }
    }

    /// The cells that f64 coordinates of their magnitude cannot resolve, with the share,
    /// ascending by cell ([`Body::unresolved_cells`], [`AdaptiveBody::unresolved_cells`]).
    #[must_use]
    pub fn unresolved_cells(&self) -> Vec<(CellId, f64)> {
        match self {
            Self::Uniform(body) => body.unresolved_cells(),
            Self::Adaptive(body) => body.unresolved_cells(),
        }
    }

    /// The frame of the settings' kernel, as the core's locator of this kind of body takes it
    /// (f32: shifted by the displacements' common translation in whole cells, of the finest
    /// level for an adaptive body).
    #[must_use]
    pub fn frame(&self, settings: &Settings) -> Frame {
        Frame::of_displacements(
            settings.precision,
            self.displacements(),
            self.finest_spacing(),
        )
    }

    /// The nodes' displacements.
    #[must_use]
    pub fn displacements(&self) -> &'a [DVec3] {
        match self {
            Self::Uniform(body) => body.displacements(),
            Self::Adaptive(body) => body.displacements(),
        }
    }

    /// The spacing of the smallest cells: the lattice's, or an adaptive body's finest level's.
    #[must_use]
    pub fn finest_spacing(&self) -> DVec3 {
        match self {
            Self::Uniform(body) => body.lattice().h(),
            Self::Adaptive(body) => body.spacing(body.finest_level()),
        }
    }

    /// The inside tolerance's constants, as the core's locator of this kind of body computes them
    /// (for an adaptive body: from the finest spacing, as [`cgcontact::AdaptiveLocator::new`]), so
    /// that every strategy agrees with it on what "inside" means.
    #[must_use]
    pub fn inside_tolerance(&self, settings: &Settings) -> InsideTolerance {
        // Bodies refuse non-finite displacements (every entry point), so the bound is finite: the
        // kernel's rounding grows with |u − T| (|u| with f64).
        let u_max = self.frame(settings).reach();
        let inside = InsideTolerance::with_spacing(
            settings,
            self.lattice().origin(),
            self.finest_spacing(),
            u_max,
        );
        // An adaptive body's seam (hanging nodes off their faces, in a file's rounding) widens
        // it as it widens the adaptive locator's.
        match self {
            Self::Uniform(_) => inside,
            Self::Adaptive(body) => inside.with_added_length(body.seam()),
        }
    }
}

/// What a candidate search does with each inside hit.
pub(crate) enum Collect<'o> {
    /// Stop at the first inside candidate.
    First,
    /// Try every candidate and keep every inside one.
    All(&'o mut Owners),
}

/// The body, the settings and what follows from them, shared by every strategy.
#[derive(Clone, Debug)]
pub(crate) struct Cells<'a> {
    body: BodyRef<'a>,
    settings: Settings,
    newton: NewtonOptions,
    /// The inside tolerance's per-body constants (shared definition with the lattice locator).
    inside: InsideTolerance,
    /// The kernel's frame (shared definition with the lattice locator).
    frame: Frame,
}

impl<'a> Cells<'a> {
    /// Checks the settings and the displacement bound (the body itself refuses non-finite values).
    pub(crate) fn new(body: BodyRef<'a>, settings: Settings) -> Result<Self, Error> {
        settings.validate_for(body.finest_spacing())?;
        Ok(Self {
            body,
            settings,
            newton: body.inside_tolerance(&settings).newton(&settings),
            inside: body.inside_tolerance(&settings),
            frame: body.frame(&settings),
        })
    }

    #[inline]
    pub(crate) fn body(&self) -> BodyRef<'a> {
        self.body
    }

    #[inline]
    pub(crate) fn lattice(&self) -> &'a Lattice {
        self.body.lattice()
    }

    #[inline]
    pub(crate) fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Inside tolerance (ξ units) for a query at `x` in an undeformed cell of the finest spacing:
    /// what the filters widen by ([`InsideTolerance::at`]).
    #[inline]
    pub(crate) fn inside_tolerance(&self, x: DVec3) -> DVec3 {
        self.inside.at(x)
    }

    /// Newton options for a query at `x`, or the point's error when it is not finite.
    #[inline]
    pub(crate) fn options(&self, x: DVec3) -> Result<NewtonOptions, PointError> {
        if !x.is_finite() {
            return Err(PointError::NonFinite);
        }
        Ok(NewtonOptions {
            inside_length: self.inside.length(x),
            ..self.newton
        })
    }

    /// The local frame of `cell` (its lowest undeformed corner), its spacing and its corner
    /// displacements (VTK order), for a cell the body searches (active cell, or leaf).
    #[inline]
    pub(crate) fn local(&self, cell: CellId) -> (DVec3, DVec3, [DVec3; 8]) {
        match self.body {
            BodyRef::Uniform(body) => uniform_local(body, cell),
            BodyRef::Adaptive(body) => adaptive_local(body, cell),
        }
    }

    /// Deformed corners of `cell` relative to the lattice origin, VTK order (for filters' geometry:
    /// centroids, boxes; the origin-relative frame keeps them accurate far from the origin).
    pub(crate) fn origin_relative_corners(&self, cell: CellId) -> [DVec3; 8] {
        let (ijk, h, u) = match self.body {
            BodyRef::Uniform(body) => {
                let (_, h, u) = uniform_local(body, cell);
                let ijk = body
                    .lattice()
                    .cell_ijk(cell)
                    .expect("candidate cells come from the body's active cells");
                (ijk, h, u)
            }
            BodyRef::Adaptive(body) => {
                let leaf = body.leaves().get(cell.index()).expect("a leaf of the body");
                let u = body
                    .cell_displacements(cell)
                    .expect("candidate cells are leaves");
                // (ijk + offset) · h rounds once and the power of two scales exactly, so a node's
                // position is the same from every leaf that has it as a corner.
                (leaf.ijk, body.spacing(leaf.level), u)
            }
        };
        std::array::from_fn(|c| {
            let [a, b, d] = CORNER_OFFSETS[c];
            DVec3::new(
                f64::from(ijk[0] + a),
                f64::from(ijk[1] + b),
                f64::from(ijk[2] + d),
            ) * h
                + u[c]
        })
    }

    /// Exact inversion of `x` in `cell` with kernel `K`, in the cell's local frame, from ξ = 0.
    /// `Some` (with `inversions` left at 0) only when the point is inside.
    ///
    /// An inversion that runs out of iterations is run again with [`PATIENT_ITERATIONS`] times
    /// as many: from the centre of a strongly distorted but valid cell (a corner moved 300 h),
    /// Newton may need 70 iterations, and an oracle that gave up there would call a point that
    /// the cell holds not located. (The reported iterations are the second run's.) Only where
    /// the cell may hold the point ([`may_hold`]): far from a distorted cell Newton often runs
    /// out of iterations too, and retrying there made brute force 10 times slower on a jittered
    /// block.
    #[inline]
    pub(crate) fn invert_exact<K: Kernel>(
        &self,
        cell: CellId,
        x: DVec3,
        options: &NewtonOptions,
    ) -> Option<Hit> {
        let (low, h, u) = self.local(cell);
        let map: K = self.frame.corners::<K, _>(&u, |u| K::lattice_cell(h, u));
        let x_local = self.frame.point::<K>(x) - low;
        let mut inversion = map.invert_f64(x_local, DVec3::ZERO, options);
        if inversion.status == Status::NotConverged
            && may_hold(h, &u, x - low, self.inside.undeformed(x, h))
        {
            let patient = NewtonOptions {
                max_iter: options.max_iter.saturating_mul(PATIENT_ITERATIONS),
                ..*options
            };
            inversion = map.invert_f64(x_local, DVec3::ZERO, &patient);
        }
        (inversion.status == Status::Inside).then(|| Hit {
            cell,
            xi: inversion.xi.clamp(DVec3::NEG_ONE, DVec3::ONE),
            iterations: inversion.iterations,
            residual: inversion.residual,
            inversions: 0,
        })
    }

    /// Tries `candidates` in the order given with the exact kernel of the settings' precision.
    pub(crate) fn search(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        candidates: impl IntoIterator<Item = CellId>,
        collect: &mut Collect<'_>,
    ) -> Option<Hit> {
        match self.settings.precision {
            Precision::F64 => self.search_with::<Hex8Map>(x, options, candidates, collect),
            Precision::F32 => self.search_with::<Hex8Map32>(x, options, candidates, collect),
        }
    }

    fn search_with<K: Kernel>(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        candidates: impl IntoIterator<Item = CellId>,
        collect: &mut Collect<'_>,
    ) -> Option<Hit> {
        try_in_order(candidates, collect, |cell| {
            self.invert_exact::<K>(cell, x, options)
        })
    }
}

/// Whether the cell of spacing `h` and corner displacements `u` may hold `x` (all in the cell's
/// local frame, corner 0 undisplaced at the origin) with ξ inside [−1 − t, 1 + t]³, `t` =
/// `inside_tol`: false only when `x` lies outside the box of the cell's corners widened by what
/// the tolerance allows. The trilinear weights sum to 1 and their absolute values to at most
/// Π_k max(1, |ξ_k|) ≤ Π_k (1 + t_k) =: P, so each coordinate of x(ξ) lies within its corners'
/// range widened by (P − 1) times its extent on both sides. A thousandth of the extent (and
/// 1e-12 of the corners' magnitude) more covers the rounding of the inversion's inside test.
fn may_hold(h: DVec3, u: &[DVec3; 8], x: DVec3, inside_tol: DVec3) -> bool {
    let corners: [DVec3; 8] = std::array::from_fn(|c| {
        let [a, b, d] = CORNER_OFFSETS[c];
        DVec3::new(f64::from(a), f64::from(b), f64::from(d)) * h + u[c]
    });
    let (lo, hi) = corners[1..]
        .iter()
        .fold((corners[0], corners[0]), |(l, h), &c| (l.min(c), h.max(c)));
    let widen = (DVec3::ONE + inside_tol.abs()).element_product() - 1.0 + 1e-3;
    let slack = (hi - lo) * widen + lo.abs().max(hi.abs()) * 1e-12;
    x.cmpge(lo - slack).all() && x.cmple(hi + slack).all()
}

/// How many times the iteration limit an exact inversion that ran out of iterations gets on its
/// second try ([`Cells::invert_exact`]).
pub(crate) const PATIENT_ITERATIONS: u32 = 16;

/// [`Cells::local`] of an active cell of a uniform body. A function of its own, not an arm of the
/// match, and the only caller of `Body::cell_displacements` in this crate, so that it compiles as
/// before adaptive bodies: with a second caller, the brute-force oracle's inner loop called
/// `cell_displacements` instead of inlining it, 5 % more instructions (cachegrind).
#[inline]
fn uniform_local(body: &Body, cell: CellId) -> (DVec3, DVec3, [DVec3; 8]) {
    let lattice = body.lattice();
    let ijk = lattice
        .cell_ijk(cell)
        .expect("candidate cells come from the body's active cells");
    let u = body
        .cell_displacements(cell)
        .expect("candidate cells are active cells");
    (lattice.node_position(ijk), lattice.h(), u)
}

/// [`Cells::local`] of a leaf of an adaptive body.
#[inline]
fn adaptive_local(body: &AdaptiveBody, cell: CellId) -> (DVec3, DVec3, [DVec3; 8]) {
    let leaf = body.leaves().get(cell.index()).expect("a leaf of the body");
    let u = body
        .cell_displacements(cell)
        .expect("candidate cells are leaves");
    (body.leaf_origin(leaf), body.spacing(leaf.level), u)
}

/// Runs `invert` over `candidates` in order, counting inversions; first inside wins, or every inside
/// one is collected.
#[inline]
pub(crate) fn try_in_order(
    candidates: impl IntoIterator<Item = CellId>,
    collect: &mut Collect<'_>,
    mut invert: impl FnMut(CellId) -> Option<Hit>,
) -> Option<Hit> {
    for (tried, cell) in (1u32..).zip(candidates) {
        if let Some(hit) = invert(cell) {
            let hit = Hit {
                inversions: tried,
                ..hit
            };
            match collect {
                Collect::First => return Some(hit),
                Collect::All(owners) => owners.push(hit),
            }
        }
    }
    None
}

/// Runs a search that collects every owner, then sorts them by cell.
pub(crate) fn owners_of(
    search: impl FnOnce(&mut Collect<'_>) -> Result<(), PointError>,
) -> Result<Owners, PointError> {
    let mut owners = Owners::new();
    search(&mut Collect::All(&mut owners))?;
    owners.sort_unstable_by_key(|hit| hit.cell);
    Ok(owners)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points mapped from ξ anywhere in [−1 − t, 1 + t]³ (the widened cube's corners, edges and
    /// faces included) of cells with their corners thrown up to 3 h about (tangled ones included:
    /// the bound holds for any corners) are never ruled out; points a hundredth of the extent
    /// outside the corners' box are.
    #[test]
    fn may_hold_never_rules_out_a_point_the_cell_may_hold() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut unit = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let tolerances = [
            DVec3::ZERO,
            DVec3::splat(1e-12),
            DVec3::splat(1e-6),
            DVec3::new(0.1, 0.0, 0.3),
        ];
        for case in 0..2000 {
            let h = DVec3::new(
                0.1 + 10.0 * unit(),
                0.1 + 10.0 * unit(),
                0.1 + 10.0 * unit(),
            );
            let u: [DVec3; 8] = std::array::from_fn(|_| {
                DVec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) * 6.0 * h
            });
            let t = tolerances[case % tolerances.len()];
            let map = Hex8Map::lattice_cell(h, &u);
            for _ in 0..20 {
                // Each coordinate at −1 − t, 1 + t or anywhere between.
                let pick = |r: f64, s: f64, t: f64| match (r * 3.0) as u32 {
                    0 => -1.0 - t,
                    1 => 1.0 + t,
                    _ => (2.0 * s - 1.0) * (1.0 + t),
                };
                let xi = DVec3::new(
                    pick(unit(), unit(), t.x),
                    pick(unit(), unit(), t.y),
                    pick(unit(), unit(), t.z),
                );
                let x = map.map(xi);
                assert!(
                    may_hold(h, &u, x, t),
                    "case {case}: ξ {xi} in h {h}, u {u:?}"
                );
            }
            let corners: [DVec3; 8] = std::array::from_fn(|c| map.map(corner_xi(c)));
            let hi = corners.iter().fold(corners[0], |m, &c| m.max(c));
            let lo = corners.iter().fold(corners[0], |m, &c| m.min(c));
            let out = hi + (hi - lo) * (0.01 + 4.0 * t.element_sum());
            assert!(!may_hold(h, &u, out, t), "case {case}: {out} beyond {hi}");
        }
    }

    fn corner_xi(c: usize) -> DVec3 {
        let [a, b, d] = CORNER_OFFSETS[c];
        DVec3::new(f64::from(a), f64::from(b), f64::from(d)) * 2.0 - DVec3::ONE
    }
}
