//! FEAVOX's original filter: cells whose deformed centroid lies within a radius of the point.

use cgcontact::glam::DVec3;
use cgcontact::{Answer, CellId, Error, Locator, Owners, PointError, Settings};
use smallvec::SmallVec;

use crate::common::{BodyRef, Cells, Collect, owners_of};

/// Diagonals of a hexahedron as pairs of opposite corners, VTK order.
const SPACE_DIAGONALS: [(usize, usize); 4] = [(0, 6), (1, 7), (2, 4), (3, 5)];

/// Candidate list of one query; spills to the heap only for very large radii.
type Candidates = SmallVec<[(f64, CellId); 32]>;

/// FEAVOX's original filter ("centroid-radius"): the candidates of a point are the cells whose
/// deformed centroid (mean of the 8 deformed corners) lies within the radius of the cell's level of
/// it, tried nearest centroid first (ties by cell id) with the core's exact kernel; the first inside
/// wins.
///
/// Like the seed, each query scans **every** centroid (O(cells) per point); this is a baseline, kept
/// honest to the original.
///
/// **Default radius**: 1.0 × the largest deformed half-diagonal over all cells (half the longest of
/// a cell's 4 space diagonals). A point in a cell can lie up to the cell's circumradius about its
/// centroid, which the half-diagonal only approximates: for strongly distorted cells a point near a
/// stretched corner can lie farther from the centroid than any half-diagonal, and the filter then
/// **misses** it. The filter is not provably complete (docs/baselines.md counts its misses).
///
/// **Adaptive bodies**: the rule is applied to each level apart, as if the leaves of one level were
/// a uniform body: a leaf's radius is the factor × the largest deformed half-diagonal over the leaves
/// of its level ([`CentroidRadius::level_radius`]). One radius for every leaf would be either the
/// finest leaves' (coarse leaves lose most of their volume) or the coarsest's (a fine leaf's point
/// then has every fine leaf around it as a candidate). An absolute radius
/// ([`CentroidRadius::with_radius`]) is the same for every level.
#[derive(Clone, Debug)]
pub struct CentroidRadius<'a> {
    cells: Cells<'a>,
    /// Each cell, its level and its deformed centroid relative to the lattice origin, ascending
    /// cell order.
    centroids: Vec<(CellId, u8, DVec3)>,
    /// The largest deformed half-diagonal over the cells of each level (0 where a level has none).
    half_diagonals: Vec<f64>,
    /// The search radius of each level (one entry for a uniform body).
    radii: Vec<f64>,
}

impl<'a> CentroidRadius<'a> {
    /// The filter with the default radius, 1.0 × the largest deformed half-diagonal (of the cell's
    /// level), over `body`, a `&Body` or a `&AdaptiveBody`.
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: impl Into<BodyRef<'a>>, settings: Settings) -> Result<Self, Error> {
        Self::with_factor(body, settings, 1.0)
    }

    /// The filter with radius `factor` × the largest deformed half-diagonal (of the cell's level).
    ///
    /// Errors when `factor` is not finite and positive, or the settings are out of range.
    pub fn with_factor(
        body: impl Into<BodyRef<'a>>,
        settings: Settings,
        factor: f64,
    ) -> Result<Self, Error> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(Error::InvalidSettings(format!(
                "centroid radius factor {factor} must be finite and > 0"
            )));
        }
        let mut filter = Self::build(body.into(), settings)?;
        filter.radii = filter.half_diagonals.iter().map(|d| factor * d).collect();
        Ok(filter)
    }

    /// The filter with an absolute radius (length units of the body), the same for every level.
    ///
    /// Errors when `radius` is not finite and non-negative, or the settings are out of range.
    pub fn with_radius(
        body: impl Into<BodyRef<'a>>,
        settings: Settings,
        radius: f64,
    ) -> Result<Self, Error> {
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(Error::InvalidSettings(format!(
                "centroid radius {radius} must be finite and ≥ 0"
            )));
        }
        let mut filter = Self::build(body.into(), settings)?;
        filter.radii.fill(radius);
        Ok(filter)
    }

    fn build(body: BodyRef<'a>, settings: Settings) -> Result<Self, Error> {
        let cells = Cells::new(body, settings)?;
        let mut half_diagonals = vec![0.0f64; usize::from(body.finest_level()) + 1];
        let centroids = body
            .cells()
            .map(|cell| {
                let level = body.level_of(cell);
                let largest = &mut half_diagonals[usize::from(level)];
                let corners = cells.origin_relative_corners(cell);
                for (a, b) in SPACE_DIAGONALS {
                    *largest = largest.max(0.5 * corners[a].distance(corners[b]));
                }
                (cell, level, corners.iter().sum::<DVec3>() / 8.0)
            })
            .collect();
        Ok(Self {
            cells,
            centroids,
            radii: half_diagonals.clone(),
            half_diagonals,
        })
    }

    /// The largest search radius in force (the radius of every cell of a uniform body): no
    /// candidate's centroid is farther from the point.
    #[must_use]
    pub fn radius(&self) -> f64 {
        self.radii.iter().copied().fold(0.0, f64::max)
    }

    /// The search radius of the cells of `level` (0 where the body has no cell of that level),
    /// `None` beyond the finest level.
    #[must_use]
    pub fn level_radius(&self, level: u8) -> Option<f64> {
        self.radii.get(usize::from(level)).copied()
    }

    /// The largest deformed half-diagonal over all cells (the default radius of a uniform body).
    #[must_use]
    pub fn max_half_diagonal(&self) -> f64 {
        self.half_diagonals.iter().copied().fold(0.0, f64::max)
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        self.cells.settings()
    }

    /// Candidate cells of `x`, nearest centroid first (a linear scan over every centroid, like the seed).
    fn candidates(&self, x: DVec3) -> Candidates {
        let p = x - self.cells.lattice().origin();
        match self.radii.as_slice() {
            // One level: one radius, as in the uniform original.
            &[radius] => {
                let r2 = radius * radius;
                self.within(p, |_| r2)
            }
            radii => self.within(p, |level| {
                let radius = radii[usize::from(level)];
                radius * radius
            }),
        }
    }

    /// The cells whose centroid is within `squared_radius(level)` of `p`, nearest first.
    #[inline(always)]
    fn within(&self, p: DVec3, squared_radius: impl Fn(u8) -> f64) -> Candidates {
        let mut found: Candidates = self
            .centroids
            .iter()
            .map(|&(cell, level, c)| (c.distance_squared(p), level, cell))
            .filter(|&(d2, level, _)| d2 <= squared_radius(level))
            .map(|(d2, _, cell)| (d2, cell))
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
