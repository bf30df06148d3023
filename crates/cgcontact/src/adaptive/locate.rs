//! The locator of adaptive bodies: the lattice locator's search with leaves for cells.
//!
//! A point x is hashed to the leaf that holds it undeformed; the displacement ũ interpolated there
//! gives the guess x − ũ, and the leaf holding the guess is inverted first (one inversion for
//! almost every point, whatever the levels). After a miss, every leaf meeting x minus the
//! displacement range is a candidate: a point inside deformed leaf c is x = X(ξ) + u(ξ), u(ξ) a
//! convex combination of c's corner displacements, so X lies in that box whatever c's level, and
//! the search is complete. Candidates whose own deformed corners' bounds miss x are skipped;
//! the rest are inverted nearest the refined guess first.
//!
//! On a body of one level every step computes what the uniform locator computes, in the same
//! order, so the predicted leaf's answers are bitwise the uniform locator's.

use glam::DVec3;
use smallvec::SmallVec;

use super::{AdaptiveBody, Leaf};
use crate::hex8::{Hex8Map, Hex8Map32, Kernel, NewtonOptions, Status};
use crate::lattice::CellId;
use crate::locate::{Answer, Hit, Locator, Owners};
use crate::reach::{self, Range};
use crate::settings::{CandidateOrder, InsideTolerance, Precision, Settings};
use crate::{Error, PointError};

/// What a search does with each inside hit.
enum Collect<'o> {
    First,
    All(&'o mut Owners),
}

/// The locator of an [`AdaptiveBody`]: complete, exact, one inversion for most points. Built in
/// O(nodes) (one pass for the displacement range) from a body it borrows.
#[derive(Clone, Debug)]
pub struct AdaptiveLocator<'a> {
    body: &'a AdaptiveBody,
    settings: Settings,
    newton: NewtonOptions,
    /// The range of the displacements (signed, per axis).
    u_range: Range,
    /// 1 / h per axis, h the base spacing.
    inv_h: DVec3,
    inside_tol: InsideTolerance,
    /// The base lattice's box shifted by the displacement range: points outside are rejected.
    reach_low: DVec3,
    reach_high: DVec3,
    reach_pad: DVec3,
}

impl<'a> AdaptiveLocator<'a> {
    /// A locator over `body`: one pass over the displacements for their range.
    pub fn new(body: &'a AdaptiveBody, settings: Settings) -> Result<Self, Error> {
        settings.validate()?;
        let u_range = body.u.iter().fold(Range::EMPTY, |r, &u| Range {
            low: r.low.min(u),
            high: r.high.max(u),
        });
        let u_max = u_range.high.max(-u_range.low);
        let lattice = body.lattice();
        let h_min = body.spacing(body.finest).min_element();
        Ok(Self {
            body,
            settings,
            newton: settings.newton(),
            u_range,
            inv_h: lattice.h().recip(),
            inside_tol: InsideTolerance::with_h_min(
                &settings,
                lattice.origin(),
                h_min,
                u_max.max_element(),
            ),
            reach_low: lattice.origin() + u_range.low,
            reach_high: lattice.upper() + u_range.high,
            reach_pad: reach::widening(lattice.h(), u_range.high - u_range.low, 1.0),
        })
    }

    /// The body searched.
    #[must_use]
    pub fn body(&self) -> &AdaptiveBody {
        self.body
    }

    /// The settings in force.
    #[must_use]
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Largest displacement component per axis.
    #[must_use]
    pub fn max_displacement(&self) -> DVec3 {
        self.u_range.high.max(-self.u_range.low)
    }

    /// The inside tolerance for `x`, or `None` when no leaf can hold it; an error when it is not
    /// finite.
    #[inline(always)]
    fn admit(&self, x: DVec3) -> Result<Option<f64>, PointError> {
        if !x.is_finite() {
            return Err(PointError::NonFinite);
        }
        let inside_tol = self.inside_tol.at(x);
        let slack = self.reach_pad * inside_tol;
        if x.cmplt(self.reach_low - slack).any() || x.cmpgt(self.reach_high + slack).any() {
            return Ok(None);
        }
        Ok(Some(inside_tol))
    }

    fn search(
        &self,
        x: DVec3,
        mut collect: Collect<'_>,
        tried: &mut u32,
    ) -> Result<Option<Hit>, PointError> {
        let Some(inside_tol) = self.admit(x)? else {
            return Ok(None);
        };
        let options = NewtonOptions {
            inside_tol,
            ..self.newton
        };
        Ok(match self.settings.precision {
            Precision::F64 => self.search_with::<Hex8Map>(x, &options, &mut collect, tried),
            Precision::F32 => self.search_with::<Hex8Map32>(x, &options, &mut collect, tried),
        })
    }

    /// Local coordinates in `leaf` of the undeformed point at base lattice coordinates `t`.
    #[inline(always)]
    fn undeformed_xi(t: DVec3, level: u8, ijk: [u32; 3]) -> DVec3 {
        let scale = f64::from(1u32 << level);
        let [i, j, k] = ijk;
        2.0 * (t * scale - DVec3::new(f64::from(i), f64::from(j), f64::from(k))) - 1.0
    }

    /// The guess x − ũ in base lattice coordinates, ũ interpolated in the leaf holding `t_at`
    /// (zero in a hole), and that leaf with its corner displacements.
    #[inline(always)]
    fn guess<K: Kernel>(
        &self,
        t_x: DVec3,
        t_at: DVec3,
    ) -> (DVec3, Option<(u32, Leaf, [DVec3; 8])>) {
        let Some((id, leaf)) = self.body.forest.leaf_at(t_at) else {
            return (t_x, None);
        };
        let u = self.body.leaf_displacements(id);
        let u_map = K::displacement_map(&u);
        let xi = Self::undeformed_xi(t_at, leaf.level, leaf.ijk).clamp(DVec3::NEG_ONE, DVec3::ONE);
        (t_x - u_map.map_f64(xi) * self.inv_h, Some((id, leaf, u)))
    }

    /// Invert leaf `id` for `x` from the guess `t_guess` and collect the hit: `Some` when the
    /// search is over.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn visit<K: Kernel>(
        &self,
        x: DVec3,
        id: u32,
        leaf: Leaf,
        u: &[DVec3; 8],
        t_guess: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let map = K::lattice_cell(self.body.spacing(leaf.level), u);
        let xi0 = Self::undeformed_xi(t_guess, leaf.level, leaf.ijk);
        let inversion = map.invert_f64(x - self.body.leaf_origin(leaf), xi0, options);
        *inversions += 1;
        if inversion.status != Status::Inside {
            return None;
        }
        let hit = Hit {
            cell: CellId(id),
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

    fn search_with<K: Kernel>(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let body = self.body;
        let t_x = (x - body.lattice().origin()) * self.inv_h;
        let (mut t_guess, at_x) = match self.settings.order {
            CandidateOrder::Predicted => self.guess::<K>(t_x, t_x),
            CandidateOrder::Undeformed => (t_x, None),
        };
        let first = body.forest.leaf_at(t_guess);
        if let Some((id, leaf)) = first {
            // Most often the leaf holding x itself: its displacements are at hand.
            let u = match at_x {
                Some((at, _, u)) if at == id => u,
                _ => body.leaf_displacements(id),
            };
            let hit = self.visit::<K>(x, id, leaf, &u, t_guess, options, collect, inversions);
            if hit.is_some() {
                return hit;
            }
        }
        self.search_box::<K>(
            x,
            t_x,
            &mut t_guess,
            first.map(|(id, _)| id),
            options,
            collect,
            inversions,
        )
    }

    /// After a miss in the predicted leaf `first`: refine the guess by the fixed point
    /// X ← x − ũ(X), as the uniform locator does, then try every other leaf meeting x − the
    /// displacement range whose deformed corners' bounds hold x, nearest the guess first. Out of
    /// line: the common path stays small.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn search_box<K: Kernel>(
        &self,
        x: DVec3,
        t_x: DVec3,
        t_guess: &mut DVec3,
        first: Option<u32>,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let body = self.body;
        if self.settings.order == CandidateOrder::Predicted {
            for _ in 0..2 {
                *t_guess = self.guess::<K>(t_x, *t_guess).0;
            }
        }
        let t_guess = *t_guess;
        let tau = options.inside_tol;
        let range = self.u_range;
        let w = reach::widening(body.lattice().h(), range.high - range.low, tau);
        let low = t_x - (range.high + w) * self.inv_h;
        let high = t_x - (range.low - w) * self.inv_h;
        // Only the leaves whose own deformed corners can reach x: usually none to a few.
        let mut candidates: SmallVec<[(f64, u32, Leaf); 16]> = SmallVec::new();
        body.forest.for_each_in_box(low, high, |id, leaf| {
            if Some(id) == first {
                return;
            }
            let u = body.leaf_displacements(id);
            if !reach::cell_reaches(
                x - body.leaf_origin(leaf),
                body.spacing(leaf.level),
                &u,
                tau,
            ) {
                return;
            }
            let size = 0.5f64.powi(i32::from(leaf.level));
            let [i, j, k] = leaf.ijk;
            let lo = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * size;
            let gap = (lo - t_guess).max(t_guess - (lo + size)).max(DVec3::ZERO);
            candidates.push((gap.max_element(), id, leaf));
        });
        candidates.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (_, id, leaf) in candidates {
            let u = body.leaf_displacements(id);
            let hit = self.visit::<K>(x, id, leaf, &u, t_guess, options, collect, inversions);
            if hit.is_some() {
                return hit;
            }
        }
        None
    }
}

impl Locator for AdaptiveLocator<'_> {
    fn name(&self) -> &str {
        "lattice"
    }

    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, Collect::First, &mut 0)
    }

    /// Every inversion counted, failed ones included.
    fn locate_counted(&self, x: DVec3) -> (Answer, u32) {
        let mut tried = 0;
        let answer = self.search(x, Collect::First, &mut tried);
        (answer, tried)
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        let mut owners = Owners::new();
        self.search(x, Collect::All(&mut owners), &mut 0)?;
        owners.sort_unstable_by_key(|hit| hit.cell);
        Ok(owners)
    }
}
