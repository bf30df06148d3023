//! Brute force: every cell, exact Newton. The oracle of the tests.

use cgcontact::glam::DVec3;
use cgcontact::{Answer, Error, Locator, Owners, PointError, Settings};

use crate::common::{BodyRef, Cells, Collect, owners_of};

/// Brute force: inverts every cell (active lattice cell, or leaf of an adaptive body) in ascending
/// cell order with the core's exact kernel (precision from [`Settings::precision`]); the first
/// inside cell wins, so the answer is the **lowest cell id among the owners**. O(cells) inversions
/// per point: the test oracle, not a strategy for production.
#[derive(Clone, Debug)]
pub struct BruteForce<'a> {
    cells: Cells<'a>,
}

impl<'a> BruteForce<'a> {
    /// A brute-force locator over `body`, a `&Body` or a `&AdaptiveBody` (nothing is built).
    ///
    /// Errors when the settings are out of range.
    pub fn new(body: impl Into<BodyRef<'a>>, settings: Settings) -> Result<Self, Error> {
        Ok(Self {
            cells: Cells::new(body.into(), settings)?,
        })
    }

    /// The body searched.
    #[must_use]
    pub fn body(&self) -> BodyRef<'a> {
        self.cells.body()
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        self.cells.settings()
    }

    fn search(&self, x: DVec3, collect: &mut Collect<'_>) -> Answer {
        let options = self.cells.options(x)?;
        Ok(self
            .cells
            .search(x, &options, self.cells.body().cells(), collect))
    }
}

impl Locator for BruteForce<'_> {
    fn name(&self) -> &str {
        "brute"
    }

    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, &mut Collect::First)
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        owners_of(|collect| self.search(x, collect).map(drop))
    }
}
