//! The undeformed cartesian lattice: origin, spacing per axis, cell counts, and index arithmetic.
//!
//! Node positions are never stored: node (i, j, k) sits at `origin + (i, j, k) * h`, exact to one
//! rounding. Cells and nodes are numbered x fastest, then y, then z (VTK's structured order).

use glam::DVec3;

use crate::Error;

/// The 8 corners of a hexahedron in VTK order, as lattice offsets (0 or 1 per axis) from the cell's
/// lowest node. Corner `c` sits at local coordinates `2 * CORNER_OFFSETS[c] - 1`.
pub const CORNER_OFFSETS: [[u32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// Identity of a cell: its linear index in the lattice (x fastest, then y, then z).
///
/// A newtype, so that h-adaptive bodies can later widen it to a (level, i, j, k) key without
/// changing the signatures that carry it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CellId(pub u32);

impl CellId {
    /// The linear index, for indexing arrays of per-cell values.
    #[inline]
    #[must_use]
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

impl std::fmt::Display for CellId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cell {}", self.0)
    }
}

/// A regular cartesian lattice of `cells[0] × cells[1] × cells[2]` hexahedra.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    origin: DVec3,
    h: DVec3,
    cells: [u32; 3],
}

impl Lattice {
    /// A lattice with its lowest node at `origin`, spacing `h` per axis and `cells` cells per axis.
    ///
    /// Errors when a value is not finite, a spacing is not positive, a count is zero, the node
    /// count does not fit the `u32` indices used throughout, or a spacing lies outside
    /// [[`Lattice::MIN_SPACING`], [`Lattice::MAX_SPACING`]] or is too fine for f64 coordinates of
    /// the lattice's magnitude to resolve ([`Lattice::check_resolution`]).
    pub fn new(origin: DVec3, h: DVec3, cells: [u32; 3]) -> Result<Self, Error> {
        if !origin.is_finite() {
            return Err(Error::InvalidLattice(format!(
                "origin {origin} is not finite"
            )));
        }
        if !(h.is_finite() && h.min_element() > 0.0) {
            return Err(Error::InvalidLattice(format!(
                "spacing {h} must be finite and positive on every axis"
            )));
        }
        if cells.contains(&0) {
            return Err(Error::InvalidLattice(format!(
                "cell counts {cells:?} must be at least 1 on every axis"
            )));
        }
        // In u128: three axes of up to 2^32 nodes overflow u64.
        let nodes: u128 = cells.iter().map(|&n| u128::from(n) + 1).product();
        if nodes >= u128::from(u32::MAX) {
            return Err(Error::InvalidLattice(format!(
                "{nodes} nodes exceed the 2^32 - 1 indices this library uses"
            )));
        }
        let lattice = Self { origin, h, cells };
        lattice.check_resolution(h)?;
        Ok(lattice)
    }

    /// Refuses cells of spacing `h` on this lattice (its own, or an adaptive body's finest level)
    /// when f64 coordinates of the lattice's magnitude M (the largest |coordinate| of its box)
    /// cannot resolve them: when the rounding of a coordinate, in ξ units of a cell
    /// (8 ε₆₄ M / h_k, the inside test's allowance), exceeds [`Lattice::RESOLUTION`] on some axis.
    /// Past that, the nodes themselves are off by a visible share of a cell, and a point could
    /// be called inside cells it is far outside of (at 1e12 with h = 1e-4, by 0.6 h).
    /// Also refuses a spacing outside [[`Lattice::MIN_SPACING`], [`Lattice::MAX_SPACING`]], and
    /// a NaN one.
    pub fn check_resolution(&self, h: DVec3) -> Result<(), Error> {
        // Per axis: `min_element` and `max_element` skip a NaN component, which then passed.
        let in_range = h.cmpge(DVec3::splat(Self::MIN_SPACING)).all()
            && h.cmple(DVec3::splat(Self::MAX_SPACING)).all();
        if !in_range {
            return Err(Error::InvalidLattice(format!(
                "spacing {:?} lies outside [{:e}, {:e}]: a cell's volume, the Newton \
                 inversion's determinant, would under- or overflow f64",
                h.to_array(),
                Self::MIN_SPACING,
                Self::MAX_SPACING
            )));
        }
        let magnitude = self.origin.abs().max(self.upper().abs()).max_element();
        for a in 0..3 {
            let share = 8.0 * f64::EPSILON * magnitude / h[a];
            if share > Self::RESOLUTION {
                return Err(Error::InvalidLattice(format!(
                    "spacing {h} is too fine for coordinates as large as {magnitude:e}: their \
                     rounding is {share:.1e} of a cell along axis {a} (at most {:e}); move the \
                     mesh nearer the origin",
                    Self::RESOLUTION
                )));
            }
        }
        Ok(())
    }

    /// The largest share of a cell (in ξ units) that the rounding of a coordinate may take:
    /// a lattice finer than that for its magnitude is refused ([`Lattice::check_resolution`]).
    pub const RESOLUTION: f64 = 0.1;

    /// The largest displacement component a body of cells of spacing `h` on this lattice accepts
    /// (`h`: its own, or an adaptive body's finest level's): displaced farther, the coordinates'
    /// rounding exceeds [`Lattice::RESOLUTION`] of a cell, as [`Lattice::check_resolution`]
    /// measures it (at 1e14 from the origin with h = 1, a point 0.05 h outside a cell was found
    /// inside it); never beyond [`crate::MAX_DISPLACEMENT`].
    #[must_use]
    pub fn displacement_limit(&self, h: DVec3) -> f64 {
        let magnitude = self.origin.abs().max(self.upper().abs()).max_element();
        let resolved = Self::RESOLUTION * h.min_element() / (8.0 * f64::EPSILON);
        (resolved - magnitude).clamp(0.0, crate::MAX_DISPLACEMENT)
    }

    /// The smallest and largest spacing of a cell (per axis; on an adaptive body, of its finest
    /// level): a cell's volume h³, the determinant of its map's Jacobian, stays a normal f64
    /// (1e-300 to 1e300). Beyond, points inside a cell of spacing 1e-110 or 1e120 were reported
    /// outside it, and their gap positive.
    pub const MIN_SPACING: f64 = 1e-100;
    /// See [`Lattice::MIN_SPACING`].
    pub const MAX_SPACING: f64 = 1e100;

    /// Position of node (0, 0, 0).
    #[inline]
    #[must_use]
    pub fn origin(&self) -> DVec3 {
        self.origin
    }

    /// Spacing per axis.
    #[inline]
    #[must_use]
    pub fn h(&self) -> DVec3 {
        self.h
    }

    /// Cell counts per axis.
    #[inline]
    #[must_use]
    pub fn cells(&self) -> [u32; 3] {
        self.cells
    }

    /// Node counts per axis (`cells + 1`).
    #[inline]
    #[must_use]
    pub fn nodes(&self) -> [u32; 3] {
        [self.cells[0] + 1, self.cells[1] + 1, self.cells[2] + 1]
    }

    /// Total number of cells.
    #[inline]
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.cells.iter().map(|&n| n as usize).product()
    }

    /// Total number of nodes.
    #[inline]
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.nodes().iter().map(|&n| n as usize).product()
    }

    /// The upper corner of the lattice's box.
    #[inline]
    #[must_use]
    pub fn upper(&self) -> DVec3 {
        self.origin
            + self.h
                * DVec3::new(
                    self.cells[0] as f64,
                    self.cells[1] as f64,
                    self.cells[2] as f64,
                )
    }

    /// Linear index of cell (i, j, k). The caller guarantees it lies in the lattice.
    #[inline]
    #[must_use]
    pub fn cell_id(&self, ijk: [u32; 3]) -> CellId {
        debug_assert!(ijk[0] < self.cells[0] && ijk[1] < self.cells[1] && ijk[2] < self.cells[2]);
        CellId(ijk[0] + self.cells[0] * (ijk[1] + self.cells[1] * ijk[2]))
    }

    /// Lattice indices of a cell, or `None` when the id is out of range.
    #[inline]
    #[must_use]
    pub fn cell_ijk(&self, cell: CellId) -> Option<[u32; 3]> {
        if cell.index() >= self.cell_count() {
            return None;
        }
        let [nx, ny, _] = self.cells;
        let c = cell.0;
        Some([c % nx, (c / nx) % ny, c / (nx * ny)])
    }

    /// Linear index of node (i, j, k). The caller guarantees it lies in the lattice.
    #[inline]
    #[must_use]
    pub fn node_index(&self, ijk: [u32; 3]) -> usize {
        let [nx, ny, _] = self.nodes();
        ijk[0] as usize + nx as usize * (ijk[1] as usize + ny as usize * ijk[2] as usize)
    }

    /// Lattice indices of node `index`, or `None` when out of range.
    #[inline]
    #[must_use]
    pub fn node_ijk(&self, index: usize) -> Option<[u32; 3]> {
        if index >= self.node_count() {
            return None;
        }
        let [nx, ny, _] = self.nodes().map(|n| n as usize);
        Some([
            (index % nx) as u32,
            ((index / nx) % ny) as u32,
            (index / (nx * ny)) as u32,
        ])
    }

    /// Undeformed position of node (i, j, k).
    #[inline]
    #[must_use]
    pub fn node_position(&self, ijk: [u32; 3]) -> DVec3 {
        self.origin + self.h * DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64)
    }

    /// Linear node indices of a cell's 8 corners, in VTK order.
    #[inline]
    #[must_use]
    pub fn corner_nodes(&self, ijk: [u32; 3]) -> [usize; 8] {
        let [nx, ny, _] = self.nodes().map(|n| n as usize);
        let base = self.node_index(ijk);
        CORNER_OFFSETS.map(|[a, b, c]| base + a as usize + nx * (b as usize + ny * c as usize))
    }

    /// Continuous lattice coordinates of `x`: `(x - origin) / h`; cell (i, j, k) spans [i, i+1] etc.
    #[inline]
    #[must_use]
    pub fn lattice_coords(&self, x: DVec3) -> DVec3 {
        (x - self.origin) / self.h
    }

    /// The cell holding `x` in the undeformed lattice, or `None` when `x` lies outside the lattice's
    /// box (or is not finite). Points on the upper boundary belong to the last cell.
    #[inline]
    #[must_use]
    pub fn cell_of(&self, x: DVec3) -> Option<[u32; 3]> {
        let t = self.lattice_coords(x);
        let mut ijk = [0u32; 3];
        for axis in 0..3 {
            let n = self.cells[axis] as f64;
            // Written so that NaN fails the test.
            if !(t[axis] >= 0.0 && t[axis] <= n) {
                return None;
            }
            ijk[axis] = (t[axis] as u32).min(self.cells[axis] - 1);
        }
        Some(ijk)
    }

    /// The cell nearest to continuous lattice coordinates `t` ([`Lattice::lattice_coords`]),
    /// clamped into the lattice, for finite `t`: the cell holding `t` when one does.
    #[inline]
    #[must_use]
    pub fn clamped_cell(&self, t: DVec3) -> [u32; 3] {
        let mut ijk = [0u32; 3];
        for axis in 0..3 {
            // Truncation is floor for t ≥ 0; `max` maps negatives and NaN to 0 and `as` saturates.
            // (No `floor`: without SSE4.1 in the baseline target it is a libm call on the hot path.)
            ijk[axis] = (t[axis].max(0.0) as u32).min(self.cells[axis] - 1);
        }
        ijk
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice() -> Lattice {
        Lattice::new(
            DVec3::new(-1.0, 2.0, 0.5),
            DVec3::new(0.5, 0.25, 1.0),
            [4, 3, 2],
        )
        .unwrap()
    }

    #[test]
    fn cell_and_node_indices_round_trip() {
        let l = lattice();
        for c in 0..l.cell_count() as u32 {
            let ijk = l.cell_ijk(CellId(c)).unwrap();
            assert_eq!(l.cell_id(ijk), CellId(c));
        }
        assert_eq!(l.cell_ijk(CellId(l.cell_count() as u32)), None);
        for n in 0..l.node_count() {
            assert_eq!(l.node_index(l.node_ijk(n).unwrap()), n);
        }
        assert_eq!(l.node_ijk(l.node_count()), None);
    }

    #[test]
    fn corners_follow_vtk_order() {
        let l = lattice();
        let ijk = [1, 2, 0];
        let corners = l.corner_nodes(ijk);
        let low = l.node_position(ijk);
        for (c, &node) in corners.iter().enumerate() {
            let p = l.node_position(l.node_ijk(node).unwrap());
            let o = CORNER_OFFSETS[c];
            let expected = low + l.h() * DVec3::new(o[0] as f64, o[1] as f64, o[2] as f64);
            assert_eq!(p, expected, "corner {c}");
        }
    }

    #[test]
    fn cell_of_point() {
        let l = lattice();
        assert_eq!(l.cell_of(DVec3::new(-1.0, 2.0, 0.5)), Some([0, 0, 0]));
        assert_eq!(l.cell_of(l.upper()), Some([3, 2, 1]));
        assert_eq!(l.cell_of(DVec3::new(-0.26, 2.3, 1.6)), Some([1, 1, 1]));
        assert_eq!(l.cell_of(DVec3::new(-1.0001, 2.0, 0.5)), None);
        assert_eq!(l.cell_of(DVec3::new(f64::NAN, 2.0, 0.5)), None);
        assert_eq!(l.cell_of(l.upper() + DVec3::X * 1e-9), None);
    }

    #[test]
    fn bad_lattices_are_errors() {
        assert!(Lattice::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0), [1, 1, 1]).is_err());
        assert!(Lattice::new(DVec3::ZERO, DVec3::ONE, [1, 0, 1]).is_err());
        assert!(Lattice::new(DVec3::NAN, DVec3::ONE, [1, 1, 1]).is_err());
        assert!(Lattice::new(DVec3::ZERO, DVec3::ONE, [100_000, 100_000, 1]).is_err());
        // (2^32)^3 nodes: more than u64 counts, refused rather than overflowing.
        assert!(Lattice::new(DVec3::ZERO, DVec3::ONE, [u32::MAX; 3]).is_err());
    }

    /// At 1e12 a coordinate rounds by 1.2e-4: a spacing of 1e-4 there is refused (the nodes are
    /// off by most of a cell, and the inside test would admit points 0.6 h outside), 1 is not.
    /// At both ends of the spacing range a point inside a cell is found there, at its ξ, with a
    /// negative gap; just beyond, the lattice is refused (before, it was built, and the point
    /// reported outside with a positive gap).
    #[test]
    fn spacings_at_the_ends_of_the_range_locate_exactly_and_beyond_are_refused() {
        use crate::{Body, GapFinder, LatticeLocator, Locator, Settings};
        for h in [Lattice::MIN_SPACING, Lattice::MAX_SPACING] {
            let lattice = Lattice::new(DVec3::ZERO, DVec3::splat(h), [2, 2, 2]).unwrap();
            let body = Body::full(lattice);
            let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
            let xi = DVec3::new(0.25, -0.5, 0.75);
            let x = lattice.origin() + (DVec3::new(1.0, 0.0, 1.0) + (xi + 1.0) / 2.0) * h;
            let hit = locator.locate(x).unwrap().expect("inside cell 5");
            assert_eq!(hit.cell, lattice.cell_id([1, 0, 1]), "{h:e}");
            assert!(
                (hit.xi - xi).abs().max_element() < 1e-12,
                "{h:e}: {}",
                hit.xi
            );
            let finder = GapFinder::new(&locator, 2.0 * h).unwrap();
            let contact = finder.gap(x).unwrap().expect("within the search distance");
            assert!(contact.gap < 0.0, "{h:e}: {}", contact.gap);
        }
        for h in [Lattice::MIN_SPACING / 10.0, Lattice::MAX_SPACING * 10.0] {
            let error = Lattice::new(DVec3::ZERO, DVec3::splat(h), [2, 2, 2]).unwrap_err();
            assert!(error.to_string().contains("lies outside"), "{error}");
        }
    }

    /// The f32 kernel's Jacobian determinant, about (h/2)³, left f32's range for spacings of
    /// 1e-13 or 1e14, which the lattice accepts: every point of every cell was then reported
    /// outside, silently. At both ends of f32's range a point is found in its cell, at its ξ,
    /// on a uniform and on an adaptive body (whose finest spacing counts); beyond, f32 settings
    /// are refused, and f64 still finds the point.
    #[test]
    fn f32_finds_points_at_the_ends_of_its_spacing_range_and_is_refused_beyond() {
        use crate::{AdaptiveBody, AdaptiveLocator, Body, Error, LatticeLocator, Leaf, Locator};
        use crate::{GapFinder, Settings};
        let xi = DVec3::new(0.25, -0.5, 0.75);
        let check = |h: DVec3, settings: Settings| -> Result<(), Error> {
            let lattice = Lattice::new(DVec3::ZERO, h, [2, 2, 2]).unwrap();
            let mut body = Body::full(lattice);
            body.update_displacements(|n, _, u| *u = h * 0.05 * (n % 3) as f64)
                .unwrap();
            let cell = lattice.cell_id([1, 0, 1]);
            let x = body.point_at(cell, xi).unwrap();
            let locator = LatticeLocator::new(&body, settings)?;
            let hit = locator.locate(x).unwrap().expect("inside its cell");
            assert_eq!(hit.cell, cell, "{h}");
            assert!((hit.xi - xi).abs().max_element() < 1e-5, "{h}: {}", hit.xi);
            let gap = GapFinder::new(&locator, 2.0 * h.max_element()).unwrap();
            assert!(gap.gap(x).unwrap().unwrap().gap < 0.0, "{h}");
            // Base cells of 2 h, one split: its leaves have spacing h.
            let base = Lattice::new(DVec3::ZERO, 2.0 * h, [2, 1, 1]).unwrap();
            let mut leaves = vec![Leaf::new(0, [1, 0, 0])];
            leaves.extend(Leaf::new(0, [0, 0, 0]).children());
            let adaptive = AdaptiveBody::from_leaves(base, leaves).unwrap();
            let locator = AdaptiveLocator::new(&adaptive, settings)?;
            let leaf = crate::CellId(3);
            let x = adaptive.point_at(leaf, xi).unwrap();
            let hit = locator.locate(x).unwrap().expect("inside its leaf");
            assert_eq!(hit.cell, leaf, "{h}");
            assert!((hit.xi - xi).abs().max_element() < 1e-5, "{h}: {}", hit.xi);
            Ok(())
        };
        let (low, high) = (Settings::F32_MIN_SPACING, Settings::F32_MAX_SPACING);
        for h in [
            DVec3::splat(low),
            DVec3::splat(high),
            DVec3::new(low, 10.0 * low, 100.0 * low),
            DVec3::new(high / 100.0, high, high / 10.0),
        ] {
            check(h, Settings::f32()).unwrap();
            check(h, Settings::default()).unwrap();
        }
        // 1e-13 and 1e14: where the f32 kernel had found nothing.
        for h in [
            DVec3::splat(low / 100.0),
            DVec3::splat(high * 1000.0),
            DVec3::new(low, low, low / 100.0),
            DVec3::new(high, high * 1000.0, high),
        ] {
            let refused = check(h, Settings::f32());
            assert!(matches!(refused, Err(Error::InvalidSettings(_))), "{h}");
            check(h, Settings::default()).unwrap();
        }
    }

    /// Displaced far from the origin, a body's coordinates cannot resolve its cells: translated
    /// by 1e14 with h = 1, a point 0.05 h outside a cell was found inside it. Such displacements
    /// are refused; at half the limit, points 0.1 h outside and inside a face are told apart.
    #[test]
    fn displacements_beyond_the_coordinates_resolution_are_refused() {
        use crate::{Body, Error, LatticeLocator, Locator, Settings};
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [2, 2, 2]).unwrap();
        let mut body = Body::full(lattice);
        let limit = body.displacement_limit();
        let shift = |by: f64| vec![DVec3::splat(by); lattice.node_count()];
        let refused = body.set_displacements(&shift(1e14));
        assert!(
            matches!(refused, Err(Error::DisplacementTooLarge { node: 0, .. })),
            "{limit:e}: {refused:?}"
        );
        let by = 0.5 * limit;
        body.set_displacements(&shift(by)).unwrap();
        let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
        let outside = DVec3::new(2.1, 0.5, 0.5) + by;
        assert_eq!(locator.locate(outside).unwrap().map(|h| h.cell), None);
        let inside = DVec3::new(1.9, 0.5, 0.5) + by;
        let found = locator.locate(inside).unwrap().map(|h| h.cell);
        assert_eq!(found, Some(lattice.cell_id([1, 0, 0])));
    }

    /// `check_resolution` read the spacing through `min_element` and `max_element`, which skip
    /// NaN: a spacing with a NaN component was accepted. Every component is now checked.
    #[test]
    fn a_nan_spacing_is_refused_by_the_resolution_check() {
        let l = lattice();
        for a in 0..3 {
            let mut h = l.h();
            h[a] = f64::NAN;
            let error = l.check_resolution(h).unwrap_err();
            assert!(error.to_string().contains("lies outside"), "{error}");
            // The same spacing with that component in range passes, out of range does not.
            h[a] = l.h()[a];
            l.check_resolution(h).unwrap();
            h[a] = Lattice::MAX_SPACING * 2.0;
            assert!(l.check_resolution(h).is_err());
        }
    }

    #[test]
    fn spacings_finer_than_the_coordinates_resolve_are_refused() {
        let far = DVec3::new(0.0, 1e12, 0.0);
        let error = Lattice::new(far, DVec3::new(1.0, 1e-4, 1.0), [2, 2, 2]).unwrap_err();
        assert!(error.to_string().contains("axis 1"), "{error}");
        Lattice::new(far, DVec3::new(1.0, 1.0, 1.0), [2, 2, 2]).unwrap();
        // Either side of the limit, 8 ε M / h = RESOLUTION, M the largest |coordinate| of the
        // box: here its lowest corner's, on the negative side.
        let limit = Lattice::RESOLUTION / (8.0 * f64::EPSILON);
        for (m, ok) in [(0.9 * limit, true), (1.1 * limit, false)] {
            let origin = DVec3::new(-m, 0.0, 0.0);
            assert_eq!(
                Lattice::new(origin, DVec3::ONE, [1, 1, 1]).is_ok(),
                ok,
                "{m:e}"
            );
        }
    }
}
