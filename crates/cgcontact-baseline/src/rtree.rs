//! A general-purpose R-tree (rstar) over the deformed cells' bounding boxes.

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use cgcontact::glam::DVec3;
use cgcontact::{Answer, CellId, Error, Locator, Owners, PointError, Settings};
use rstar::primitives::{GeomWithData, Rectangle};
use smallvec::SmallVec;

use crate::common::{BodyRef, Cells, Collect, owners_of};

/// One tree entry: a cell's widened bounding box (relative to the lattice origin) and its id.
type CellBox = GeomWithData<Rectangle<[f64; 3]>, CellId>;

/// Candidate cells of one query.
type Candidates = SmallVec<[CellId; 16]>;

/// What a user with a general unstructured mesh would reach for: an R*-tree ([`rstar`], bulk-loaded)
/// over the axis-aligned bounding boxes of the deformed cells. The candidates of a point are the cells
/// whose box contains it, inverted in **ascending cell order** with the core's exact kernel; the first
/// inside wins, so the answer is the lowest cell id among the owners, like [`crate::BruteForce`].
///
/// Complete: a cell lies inside the box of its corners (a trilinear map is a convex combination of
/// them), and each box is widened by what the inside tolerance allows beyond the faces
/// (2 × tolerance × the box's largest extent, the tolerance taken at the box's farthest corner from
/// the origin), so every point the kernel calls inside passes the filter.
///
/// The constructor builds the tree; [`RTree::build_time`] reports how long that took.
#[derive(Debug)]
pub struct RTree<'a> {
    cells: Cells<'a>,
    tree: rstar::RTree<CellBox>,
    build_time: Duration,
}

impl<'a> RTree<'a> {
    /// Builds the tree over every cell of `body`, a `&Body` (its active cells) or a
    /// `&AdaptiveBody` (its leaves), in O(cells log cells).
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: impl Into<BodyRef<'a>>, settings: Settings) -> Result<Self, Error> {
        let start = Instant::now();
        let body = body.into();
        let cells = Cells::new(body, settings)?;
        let origin = body.lattice().origin();
        let boxes: Vec<CellBox> = body
            .cells()
            .map(|cell| {
                let corners = cells.origin_relative_corners(cell);
                let low = corners.iter().copied().fold(DVec3::INFINITY, DVec3::min);
                let high = corners
                    .iter()
                    .copied()
                    .fold(DVec3::NEG_INFINITY, DVec3::max);
                let farthest = (low + origin).abs().max((high + origin).abs());
                let pad = 2.0
                    * cells.inside_tolerance(farthest).max_element()
                    * (high - low).max_element();
                let rectangle =
                    Rectangle::from_corners((low - pad).to_array(), (high + pad).to_array());
                GeomWithData::new(rectangle, cell)
            })
            .collect();
        let tree = rstar::RTree::bulk_load(boxes);
        Ok(Self {
            cells,
            tree,
            build_time: start.elapsed(),
        })
    }

    /// Wall-clock time the constructor took to compute the boxes and bulk-load the tree.
    #[must_use]
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// Number of cells in the tree (the body's active cells, or leaves).
    #[must_use]
    pub fn len(&self) -> usize {
        self.tree.size()
    }

    /// Whether the tree is empty (never, for a valid body).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.tree.size() == 0
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        self.cells.settings()
    }

    /// Cells whose widened box contains `x`, ascending.
    fn candidates(&self, x: DVec3) -> Candidates {
        let p = (x - self.cells.lattice().origin()).to_array();
        let mut found = Candidates::new();
        let _: ControlFlow<()> = self.tree.locate_all_at_point_int(&p, |entry| {
            found.push(entry.data);
            ControlFlow::Continue(())
        });
        found.sort_unstable();
        found
    }

    fn search(&self, x: DVec3, collect: &mut Collect<'_>) -> Answer {
        let options = self.cells.options(x)?;
        let candidates = self.candidates(x);
        Ok(self.cells.search(x, &options, candidates, collect))
    }
}

impl Locator for RTree<'_> {
    fn name(&self) -> &str {
        "rtree"
    }

    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, &mut Collect::First)
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        owners_of(|collect| self.search(x, collect).map(drop))
    }
}
