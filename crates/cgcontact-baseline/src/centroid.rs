//! FEAVOX's original filter: cells whose deformed centroid lies within a radius of the point.

use cgcontact::glam::DVec3;
use cgcontact::{Answer, Body, CellId, Error, Locator, Owners, PointError, Settings};
use smallvec::SmallVec;

use crate::common::{Cells, Collect, owners_of};

/// Diagonals of a hexahedron as pairs of opposite corners, VTK order.
const SPACE_DIAGONALS: [(usize, usize); 4] = [(0, 6), (1, 7), (2, 4), (3, 5)];

/// Candidate list of one query; spills to the heap only for very large radii.
type Candidates = SmallVec<[(f64, CellId); 32]>;

/// FEAVOX's original filter ("centroid-radius"): the candidates of a point are the active cells whose
/// deformed centroid (mean of the 8 deformed corners) lies within [`CentroidRadius::radius`] of it,
/// tried nearest centroid first (ties by cell id) with the core's exact kernel; the first inside wins.
///
/// Like the seed, each query scans **every** centroid (O(cells) per point); this is a baseline, kept
/// honest to the original.
///
/// **Default radius**: 1.0 × the largest deformed half-diagonal over all active cells (half the
/// longest of a cell's 4 space diagonals). A point in a cell can lie up to the cell's circumradius
/// about its centroid, which the half-diagonal only approximates: for strongly distorted cells a
/// point near a stretched corner can lie farther from the centroid than any half-diagonal, and the
/// filter then **misses** it. The filter is not provably complete (docs/baselines.md counts its misses).
#[derive(Clone, Debug)]
pub struct CentroidRadius<'a> {
    cells: Cells<'a>,
    /// Deformed centroid of each active cell relative to the lattice origin, ascending cell order.
    centroids: Vec<(CellId, DVec3)>,
    max_half_diagonal: f64,
    radius: f64,
}

impl<'a> CentroidRadius<'a> {
    /// The filter with the default radius, 1.0 × the largest deformed half-diagonal.
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        Self::with_factor(body, settings, 1.0)
    }

    /// The filter with radius `factor` × the largest deformed half-diagonal.
    ///
    /// Errors when `factor` is not finite and positive, or the settings are out of range.
    pub fn with_factor(body: &'a Body, settings: Settings, factor: f64) -> Result<Self, Error> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(Error::InvalidSettings(format!(
                "centroid radius factor {factor} must be finite and > 0"
            )));
        }
        let mut filter = Self::build(body, settings)?;
        filter.radius = factor * filter.max_half_diagonal;
        Ok(filter)
    }

    /// The filter with an absolute radius (length units of the body).
    ///
    /// Errors when `radius` is not finite and non-negative, or the settings are out of range.
    pub fn with_radius(body: &'a Body, settings: Settings, radius: f64) -> Result<Self, Error> {
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(Error::InvalidSettings(format!(
                "centroid radius {radius} must be finite and ≥ 0"
            )));
        }
        let mut filter = Self::build(body, settings)?;
        filter.radius = radius;
        Ok(filter)
    }

    fn build(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        let cells = Cells::new(body, settings)?;
        let mut max_half_diagonal = 0.0f64;
        let centroids = body
            .active_cells()
            .map(|cell| {
                let corners = cells.origin_relative_corners(cell);
                for (a, b) in SPACE_DIAGONALS {
                    max_half_diagonal =
                        max_half_diagonal.max(0.5 * corners[a].distance(corners[b]));
                }
                (cell, corners.iter().sum::<DVec3>() / 8.0)
            })
            .collect();
        Ok(Self {
            cells,
            centroids,
            max_half_diagonal,
            radius: max_half_diagonal,
        })
    }

    /// The search radius in force.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The largest deformed half-diagonal over all active cells (the default radius).
    #[must_use]
    pub fn max_half_diagonal(&self) -> f64 {
        self.max_half_diagonal
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        self.cells.settings()
    }

    /// Candidate cells of `x`, nearest centroid first (a linear scan over every centroid, like the seed).
    fn candidates(&self, x: DVec3) -> Candidates {
        let p = x - self.cells.lattice().origin();
        let r2 = self.radius * self.radius;
        let mut found: Candidates = self
            .centroids
            .iter()
            .map(|&(cell, c)| (c.distance_squared(p), cell))
            .filter(|&(d2, _)| d2 <= r2)
            .collect();
        found.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        found
    }

    fn search(&self, x: DVec3, collect: &mut Collect<'_>) -> Answer {
        let options = self.cells.options(x)?;
        let candidates = self.candidates(x);
        Ok(self.cells.search(
            x,
            &options,
            candidates.iter().map(|&(_, cell)| cell),
            collect,
        ))
    }
}

impl Locator for CentroidRadius<'_> {
    fn name(&self) -> &str {
        "centroid"
    }

    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, &mut Collect::First)
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        owners_of(|collect| self.search(x, collect).map(drop))
    }
}
