//! What every strategy shares: input checks, the per-point inside tolerance, and the exact inversion
//! of one lattice cell in its local frame with the core's kernel.

use cgcontact::glam::DVec3;
use cgcontact::hex8::{Hex8Map, Hex8Map32, Kernel, NewtonOptions, Status};
use cgcontact::{
    Body, CellId, Error, Hit, InsideTolerance, Lattice, Owners, PointError, Precision, Settings,
};

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
    body: &'a Body,
    settings: Settings,
    newton: NewtonOptions,
    /// The inside tolerance's per-body constants (shared definition with the lattice locator).
    inside: InsideTolerance,
}

impl<'a> Cells<'a> {
    /// Checks the settings and the displacement bound (the body itself refuses non-finite values).
    pub(crate) fn new(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        settings.validate()?;
        // Bodies refuse non-finite displacements (`Body::set_displacements` and every other entry
        // point), so the bound is finite.
        let u_max = body.max_displacement();
        Ok(Self {
            body,
            settings,
            newton: settings.newton(),
            inside: InsideTolerance::new(&settings, body.lattice(), u_max.max_element()),
        })
    }

    #[inline]
    pub(crate) fn body(&self) -> &'a Body {
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

    /// Inside tolerance (ξ units) for a query at `x`: the one definition every strategy shares.
    #[inline]
    pub(crate) fn inside_tolerance(&self, x: DVec3) -> f64 {
        self.inside.at(x)
    }

    /// Newton options for a query at `x`, or the point's error when it is not finite.
    #[inline]
    pub(crate) fn options(&self, x: DVec3) -> Result<NewtonOptions, PointError> {
        if !x.is_finite() {
            return Err(PointError::NonFinite);
        }
        Ok(NewtonOptions {
            inside_tol: self.inside_tolerance(x),
            ..self.newton
        })
    }

    /// Lattice indices, lowest undeformed node and corner displacements (VTK order) of active `cell`.
    #[inline]
    pub(crate) fn local(&self, cell: CellId) -> ([u32; 3], DVec3, [DVec3; 8]) {
        let lattice = self.lattice();
        let ijk = lattice
            .cell_ijk(cell)
            .expect("candidate cells come from the body's active cells");
        let u = self
            .body
            .cell_displacements(cell)
            .expect("candidate cells are active cells");
        (ijk, lattice.node_position(ijk), u)
    }

    /// Deformed corners of active `cell` relative to the lattice origin, VTK order (for filters'
    /// geometry: centroids, boxes; the origin-relative frame keeps them accurate far from the origin).
    pub(crate) fn origin_relative_corners(&self, cell: CellId) -> [DVec3; 8] {
        let (ijk, _, u) = self.local(cell);
        let h = self.lattice().h();
        std::array::from_fn(|c| {
            let [a, b, d] = cgcontact::CORNER_OFFSETS[c];
            DVec3::new(
                f64::from(ijk[0] + a),
                f64::from(ijk[1] + b),
                f64::from(ijk[2] + d),
            ) * h
                + u[c]
        })
    }

    /// Exact inversion of `x` in active `cell` with kernel `K`, in the cell's local frame, from ξ = 0.
    /// `Some` (with `inversions` left at 0) only when the point is inside.
    #[inline]
    pub(crate) fn invert_exact<K: Kernel>(
        &self,
        cell: CellId,
        x: DVec3,
        options: &NewtonOptions,
    ) -> Option<Hit> {
        let (_, low, u) = self.local(cell);
        let map = K::lattice_cell(self.lattice().h(), &u);
        let inversion = map.invert_f64(x - low, DVec3::ZERO, options);
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
