//! Point location: the [`Locator`] trait every strategy implements, and the lattice locator.
//!
//! # Why the lattice search is complete
//! A point x inside deformed cell c satisfies x = X(ξ) + u(ξ), with X(ξ) the undeformed point of c and
//! u(ξ) a convex combination of c's corner displacements. So the undeformed point X = x − u(ξ) lies
//! within `u_max` (per axis, the largest nodal displacement component) of x, and c is one of the lattice
//! cells meeting the box [x − u_max, x + u_max]. The locator visits exactly those cells (and only the
//! active ones), so it cannot miss the containing cell of a valid mesh. It visits them nearest first,
//! starting at the cell holding x − ũ, ũ the displacement interpolated at x on the undeformed lattice,
//! which is the containing cell for almost every point.

use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use smallvec::SmallVec;

use crate::batch::{Lanes, MAX_W, Maps, Real, V3, Wide};
use crate::body::Body;
use crate::hex8::{Hex8Map, Hex8Map32, Inversion, Kernel, NewtonOptions, Status};
use crate::lattice::CellId;
use crate::reach::{self, Candidates, Pyramid, RING_CELLS, Range};
use crate::settings::{CandidateOrder, InsideTolerance, Precision, Settings};
use crate::{Error, PointError};

/// A located point: the cell holding it and its local coordinates there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The cell (lattice cell id for the lattice locator; each strategy documents its numbering).
    pub cell: CellId,
    /// Local coordinates in [−1, 1]³ (up to the inside tolerance), VTK corner 0 at (−1, −1, −1).
    pub xi: DVec3,
    /// Newton iterations of the successful inversion.
    pub iterations: u32,
    /// Physical residual |x − x(ξ)| of the answer.
    pub residual: f64,
    /// Newton inversions tried for this point, the successful one included.
    pub inversions: u32,
}

/// The answer for one point: a hit, `Ok(None)` when no cell holds it, or why the point was refused.
pub type Answer = Result<Option<Hit>, PointError>;

/// Every cell holding a point (points on shared faces, edges and nodes have 2, 4 or 8), sorted by cell.
pub type Owners = SmallVec<[Hit; 8]>;

/// A point-location strategy. Implemented by the lattice locator and by every baseline, so that
/// tests and benchmarks treat them alike. Implementations are `Sync`: queries take `&self`.
pub trait Locator: Sync {
    /// Short name for reports ("lattice", "brute", ...).
    fn name(&self) -> &str;

    /// The cell holding `x` (one of them when `x` is on a shared face, edge or node).
    fn locate(&self, x: DVec3) -> Answer;

    /// Every cell holding `x`, sorted by cell id.
    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError>;

    /// [`Locator::locate`], and the Newton inversions the search tried, failed ones included, so that
    /// the cost of a point no cell holds is seen too. The default counts only a hit's inversions (a
    /// miss counts 0): the lattice locator overrides it.
    fn locate_counted(&self, x: DVec3) -> (Answer, u32) {
        let answer = self.locate(x);
        let tried = match answer {
            Ok(Some(hit)) => hit.inversions,
            _ => 0,
        };
        (answer, tried)
    }

    /// [`Locator::locate`] for every point, in parallel on the current rayon pool, answers in input
    /// order, written into `out` (resized; no allocation per point).
    fn locate_all_into(&self, points: &[DVec3], out: &mut Vec<Answer>) {
        // Pieces of at least 256 points: a point costs ~100 ns, so finer splitting only adds rayon's
        // bookkeeping (measured on the fine block, one thread: 7.4 -> 8.0 M points/s).
        points
            .par_iter()
            .with_min_len(256)
            .map(|&x| self.locate(x))
            .collect_into_vec(out);
    }

    /// [`Locator::locate`] for every point, in parallel, answers in input order.
    fn locate_all(&self, points: &[DVec3]) -> Vec<Answer> {
        let mut out = Vec::with_capacity(points.len());
        self.locate_all_into(points, &mut out);
        out
    }
}

/// The lattice locator: hashes a point to its lattice cell and inverts only the few deformed
/// neighbours that can hold it. Built in O(nodes) from a body it borrows.
#[derive(Clone, Debug)]
pub struct LatticeLocator<'a> {
    body: &'a Body,
    settings: Settings,
    newton: NewtonOptions,
    /// Largest displacement component per axis.
    u_max: DVec3,
    /// The range of the displacements (signed, per axis): the search box of a point x is
    /// x − this range, in undeformed space.
    u_range: Range,
    /// 1 / h per axis.
    inv_h: DVec3,
    /// The inside tolerance's constants.
    inside_tol: InsideTolerance,
    /// The lattice's box shifted by the displacement range: points outside are rejected at once.
    reach_low: DVec3,
    reach_high: DVec3,
    /// The reach box's widening per unit of inside tolerance (`reach::widening`).
    reach_pad: DVec3,
    /// Per-block displacement ranges, built only where the displacements spread over more than a
    /// few cells: the search then visits only cells whose own shifted box holds the point.
    pyramid: Option<Pyramid>,
    /// With f32 precision, the displacements rounded to f32, in the body's slot order (16 bytes per
    /// node): the batched path reads them as they are. Empty with f64.
    u_f32: Vec<Vec3A>,
    /// Every cell of the lattice is active: the batched path skips the activity lookup.
    all_active: bool,
}

/// The displacements as the batched path reads them: the body's f64 ones, or the locator's f32 copy.
trait Nodes: Copy + 'static {
    const ZERO: Self;
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self];
}

impl Nodes for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    #[inline(always)]
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self] {
        locator.body.displacements()
    }
}

impl Nodes for Vec3A {
    const ZERO: Self = Vec3A::ZERO;
    #[inline(always)]
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self] {
        &locator.u_f32
    }
}

/// Lattice coordinates of a cell's lowest node.
#[inline]
fn lattice_point(ijk: [u32; 3]) -> DVec3 {
    DVec3::new(f64::from(ijk[0]), f64::from(ijk[1]), f64::from(ijk[2]))
}

/// Local coordinates in cell `ijk` of the undeformed point at lattice coordinates `t`.
#[inline]
fn undeformed_xi(t: DVec3, ijk: [u32; 3]) -> DVec3 {
    2.0 * (t - lattice_point(ijk)) - 1.0
}

/// What a candidate search does with each inside hit.
enum Collect<'o> {
    First,
    All(&'o mut Owners),
}

impl<'a> LatticeLocator<'a> {
    /// A locator over `body`: one pass over the displacements for their range, and, only when they
    /// spread over more than a few cells, one over the active cells for per-block ranges.
    pub fn new(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        settings.validate()?;
        let u_range = reach::displacement_range(body);
        // Bodies refuse non-finite displacements (every entry point checks), so the range is finite.
        let u_max = u_range.high.max(-u_range.low);
        let lattice = body.lattice();
        let spread = u_range.high - u_range.low;
        Ok(Self {
            body,
            settings,
            newton: settings.newton(),
            u_max,
            u_range,
            inv_h: lattice.h().recip(),
            inside_tol: InsideTolerance::new(&settings, lattice, u_max.max_element()),
            reach_low: lattice.origin() + u_range.low,
            reach_high: lattice.upper() + u_range.high,
            reach_pad: reach::widening(lattice.h(), spread, 1.0),
            // Not on a sparse body whose lattice dwarfs it: the pyramid is dense over the lattice
            // (48 bytes per 8 cells), and the body's memory must grow with its cells.
            pyramid: (reach::pyramid_pays(spread, lattice.h())
                && lattice.cell_count() <= 64 * body.active_count())
            .then(|| Pyramid::new(body)),
            u_f32: match settings.precision {
                Precision::F32 => body.displacements().iter().map(|u| u.as_vec3a()).collect(),
                Precision::F64 => Vec::new(),
            },
            all_active: body.active_count() == lattice.cell_count(),
        })
    }

    /// The body searched.
    #[must_use]
    pub fn body(&self) -> &Body {
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
        self.u_max
    }

    /// Bytes this locator keeps on the heap besides the body (the f32 copy of the displacements,
    /// the per-block displacement ranges).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.u_f32.capacity() * size_of::<Vec3A>()
            + self.pyramid.as_ref().map_or(0, Pyramid::heap_bytes)
    }

    /// Whether `x` can be held by a cell at all: its inside tolerance when it can, `Ok(None)` when it
    /// lies outside the lattice's box shifted by the displacement range (and widened by the
    /// tolerance), an error when not finite.
    /// The first step of every search, batched or not.
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

    /// The search for `x`, and the inversions it tried.
    fn search(&self, x: DVec3, mut collect: Collect<'_>) -> Result<(Option<Hit>, u32), PointError> {
        let Some(inside_tol) = self.admit(x)? else {
            return Ok((None, 0));
        };
        let options = NewtonOptions {
            inside_tol,
            ..self.newton
        };
        Ok(match self.settings.precision {
            Precision::F64 => self.search_with::<Hex8Map>(x, &options, &mut collect),
            Precision::F32 => self.search_with::<Hex8Map32>(x, &options, &mut collect),
        })
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
            None => K::lattice_cell(lattice.h(), &self.body.corner_displacements(ijk)),
        };
        let xi0 = undeformed_xi(t_guess, ijk);
        map.invert_f64(x - lattice.node_position(ijk), xi0, options)
    }

    /// The guess x − ũ in lattice coordinates, ũ the displacement map `u_map` of `cell` evaluated at
    /// lattice coordinates `t_at` (clamped into the cell).
    #[inline]
    fn guess<K: Kernel>(&self, t_x: DVec3, cell: [u32; 3], t_at: DVec3, u_map: &K) -> DVec3 {
        let xi = undeformed_xi(t_at, cell).clamp(DVec3::NEG_ONE, DVec3::ONE);
        t_x - u_map.map_f64(xi) * self.inv_h
    }

    /// Two steps of the fixed point X ← x − ũ(X) in lattice coordinates (ũ interpolated on the
    /// undeformed lattice, inactive corners as zero), from `t_guess`.
    fn refine_guess<K: Kernel>(&self, t_x: DVec3, mut t_guess: DVec3) -> DVec3 {
        let lattice = self.body.lattice();
        for _ in 0..2 {
            let cell = lattice.clamped_cell(t_guess);
            let u_map = K::displacement_map(&self.body.corner_displacements_or_zero(cell));
            t_guess = self.guess(t_x, cell, t_guess, &u_map);
        }
        t_guess
    }

    /// Invert `ijk` (active) for `x` and collect the hit: true when the search is over (the first
    /// hit wanted and found, written to `found`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn visit<K: Kernel>(
        &self,
        x: DVec3,
        ijk: [u32; 3],
        u_map: Option<K>,
        t_guess: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
        found: &mut Option<Hit>,
    ) -> bool {
        let inversion = self.try_cell::<K>(x, ijk, t_guess, u_map, options);
        *inversions += 1;
        if inversion.status != Status::Inside {
            return false;
        }
        let hit = Hit {
            cell: self.body.lattice().cell_id(ijk),
            xi: inversion.xi.clamp(DVec3::NEG_ONE, DVec3::ONE),
            iterations: inversion.iterations,
            residual: inversion.residual,
            inversions: *inversions,
        };
        match collect {
            Collect::First => {
                *found = Some(hit);
                true
            }
            Collect::All(owners) => {
                owners.push(hit);
                false
            }
        }
    }

    fn search_with<K: Kernel>(
        &self,
        x: DVec3,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
    ) -> (Option<Hit>, u32) {
        let lattice = self.body.lattice();
        let t_x = (x - lattice.origin()) * self.inv_h;
        let cell_x = lattice.clamped_cell(t_x);
        // The displacement map of the cell holding x (corners of inactive cells count as undisplaced:
        // it only serves the guess), and the predicted undeformed position x − ũ, ũ interpolated at x.
        // Kept in one place, never moved: it is 192 bytes, and moves cost a memcpy call each.
        let u_map_x = K::displacement_map(&self.body.corner_displacements_or_zero(cell_x));
        let t_guess = match self.settings.order {
            CandidateOrder::Predicted => self.guess(t_x, cell_x, t_x, &u_map_x),
            CandidateOrder::Undeformed => t_x,
        };
        let first = lattice.clamped_cell(t_guess);
        let mut inversions = 0u32;
        let mut found = None;
        // The predicted cell first, without the range test: it holds the point almost always, and
        // when it is the cell holding x its displacement map is already built.
        if self.body.is_active(lattice.cell_id(first)) {
            let reuse = (first == cell_x).then_some(u_map_x);
            let (c, n, f) = (&mut *collect, &mut inversions, &mut found);
            if self.visit(x, first, reuse, t_guess, options, c, n, f) {
                return (found, inversions);
            }
        }
        self.search_rings::<K>(
            x,
            t_x,
            t_guess,
            first,
            options,
            collect,
            &mut inversions,
            &mut found,
        );
        (found, inversions)
    }

    /// The search after a miss in the predicted cell `first`: every other active cell that can
    /// hold x, nearest first. Kept out of line: the common path stays small.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn search_rings<K: Kernel>(
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

/// The first half of the batched search for W points, up to the displacement maps of the cells
/// holding them (see `LatticeLocator::front`).
struct Front<V: Lanes> {
    /// The points, their lattice coordinates and the cells holding them, in f64 lanes.
    x: V3<V::Wide>,
    t_x: V3<V::Wide>,
    cell_x: V3<V::Wide>,
    inside_tol: V::Wide,
    /// Lanes with a finite point, and lanes within reach (bits): `admit`'s two answers.
    finite: u32,
    take: u32,
    /// The displacement maps of the cells holding the points (zero where a corner has none); not
    /// computed when no lane is within reach (a contact surface mostly away from the body).
    maps: Maps<V>,
}

impl<V: Lanes> Front<V> {
    fn new() -> Self {
        let zero = V3::splat(DVec3::ZERO);
        Self {
            x: zero,
            t_x: zero,
            cell_x: zero,
            inside_tol: V::Wide::splat(0.0),
            finite: 0,
            take: 0,
            maps: Maps {
                a: [V3::splat(DVec3::ZERO); 8],
            },
        }
    }
}

impl LatticeLocator<'_> {
    /// Answers for `points` into `out` (same length), W points at a time through the batched common
    /// path ([`crate::batch`]); the remainder and every point that leaves the common path go through
    /// the scalar search. The answers are bitwise those of [`Locator::locate`].
    ///
    /// Software-pipelined: the first half of the next W points (their cells and the loads of their
    /// corners) is issued before the second half of the current ones, so that the loads' latency
    /// overlaps the current Newton inversions. The two halves meet in two `Front`s used in turn,
    /// written in place (moving one, about 1 KB, cost a copy and a store-forwarding stall).
    #[inline(always)]
    fn locate_chunk_with<V: Lanes>(&self, points: &[DVec3], out: &mut [Answer])
    where
        V::Node: Nodes,
    {
        let w = V::W;
        let batches = points.len() / w;
        let mut fronts = [Front::<V>::new(), Front::<V>::new()];
        if batches > 0 {
            self.front(&points[..w], &mut fronts[0]);
        }
        for b in 0..batches {
            if b + 1 < batches {
                self.front(&points[(b + 1) * w..(b + 2) * w], &mut fronts[(b + 1) % 2]);
            }
            let (points, out) = (&points[b * w..(b + 1) * w], &mut out[b * w..(b + 1) * w]);
            self.back(points, &fronts[b % 2], out);
        }
        for (&x, o) in points.iter().zip(out.iter_mut()).skip(batches * w) {
            *o = self.locate(x);
        }
    }

    /// `search` up to the cell holding each of W points (`points` has W entries), one lane each, and
    /// that cell's displacement map: the same f64 operations in f64 lanes (`V::Wide`).
    #[inline(always)]
    fn front<V: Lanes>(&self, points: &[DVec3], front: &mut Front<V>)
    where
        V::Node: Nodes,
    {
        let lattice = self.body.lattice();
        let splat = V3::<V::Wide>::splat;
        let x = V::Wide::transpose(|l| &points[l]);
        // `admit`: finite and within reach (the lattice's box shifted by the displacement range,
        // widened by the tolerance).
        let inside_tol = self.inside_tol.at_magnitude(x.abs().max_element());
        let slack = splat(self.reach_pad).scale(inside_tol);
        let (low, high) = (
            splat(self.reach_low) - slack,
            splat(self.reach_high) + slack,
        );
        let outside = x.x.lt(low.x) | x.y.lt(low.y) | x.z.lt(low.z);
        let outside = outside | x.x.gt(high.x) | x.y.gt(high.y) | x.z.gt(high.z);
        let finite = x.is_finite();
        let take = V::Wide::bits(finite & !outside);
        let t_x = (x - splat(lattice.origin())).mul_each(self.inv_h);
        let cell_x = self.clamped_cells::<V::Wide>(t_x);
        if take != 0 {
            front.maps = self.maps_of::<V>(&cell_x);
        }
        *front = Front {
            x,
            t_x,
            cell_x,
            inside_tol,
            take,
            finite: V::Wide::bits(finite),
            maps: front.maps,
        };
    }

    /// `Lattice::clamped_cell` in f64 lanes: max(0), then min(cells − 1) before truncating, which
    /// is the same (MAXPD maps NaN to 0, as `f64::max` does).
    #[inline(always)]
    fn clamped_cells<D: Wide>(&self, t: V3<D>) -> V3<D> {
        let last = DVec3::from(self.body.lattice().cells().map(|n| f64::from(n - 1)));
        let clamp = |t: D, last: f64| t.max(D::splat(0.0)).min(D::splat(last)).trunc();
        V3 {
            x: clamp(t.x, last.x),
            y: clamp(t.y, last.y),
            z: clamp(t.z, last.z),
        }
    }

    /// `Lattice::node_index` (`nodes`) or `Lattice::cell_id` (`cells`) of each lane's cell, exactly
    /// (integers below 2^32 in f64).
    #[inline(always)]
    fn lane_indices<D: Wide>(cell: &V3<D>, [nx, ny, _]: [u32; 3]) -> [usize; MAX_W] {
        let index = cell.x + D::splat(f64::from(nx)) * (cell.y + D::splat(f64::from(ny)) * cell.z);
        let mut lanes = [0; MAX_W];
        index.indices_into(&mut lanes);
        lanes
    }

    /// The displacement maps of each lane's cell (zero where a corner has none).
    #[inline(always)]
    fn maps_of<V: Lanes>(&self, cell: &V3<V::Wide>) -> Maps<V>
    where
        V::Node: Nodes,
    {
        let base = Self::lane_indices(cell, self.body.lattice().nodes());
        let nodes = V::Node::of(self);
        let zero = V::Node::ZERO;
        Maps::from_nodes(|l, c| self.body.corner_entry(nodes, base[l], c, &zero))
    }

    /// The rest of the common path for W points: the predicted cell and one Newton inversion there.
    /// A point refused by `admit` gets `admit`'s answer; one leaving the common path, the scalar
    /// search's.
    #[inline(always)]
    fn back<V: Lanes>(&self, points: &[DVec3], front: &Front<V>, out: &mut [Answer])
    where
        V::Node: Nodes,
    {
        let (finite, take) = (front.finite, front.take);
        let found = if take != 0 {
            self.invert_lanes(front, out)
        } else {
            0
        };
        for (l, out) in out.iter_mut().enumerate() {
            let bit = 1 << l;
            if found & bit != 0 {
                continue;
            }
            *out = if take & bit != 0 {
                self.locate(points[l])
            } else if finite & bit != 0 {
                Ok(None)
            } else {
                Err(PointError::NonFinite)
            };
        }
    }

    /// The predicted cells and one Newton inversion there, for the lanes `front` takes: writes the
    /// answer of every lane it finds and returns their bits.
    #[inline(always)]
    fn invert_lanes<V: Lanes>(&self, front: &Front<V>, out: &mut [Answer]) -> u32
    where
        V::Node: Nodes,
    {
        let lattice = self.body.lattice();
        let splat = V3::<V::Wide>::splat;
        let Front {
            x,
            t_x,
            cell_x,
            inside_tol,
            mut take,
            mut maps,
            ..
        } = *front;
        // The guess x − ũ, ũ interpolated at x in the cell holding x (`guess`).
        let t_guess = match self.settings.order {
            CandidateOrder::Predicted => {
                let two = V::Wide::splat(2.0);
                let xi = ((t_x - cell_x).scale(two) - splat(DVec3::ONE)).clamp(-1.0, 1.0);
                t_x - maps.map(V3::narrow(xi)).widen().mul_each(self.inv_h)
            }
            CandidateOrder::Undeformed => t_x,
        };
        let first = self.clamped_cells(t_guess);
        let cell = Self::lane_indices(&first, lattice.cells());
        if !self.all_active {
            for (l, &cell) in cell.iter().enumerate().take(V::W) {
                if !self.body.is_active(CellId(cell as u32)) {
                    take &= !(1 << l);
                }
            }
        }
        let moved = first.x.lt(cell_x.x) | first.x.gt(cell_x.x) | first.y.lt(cell_x.y);
        let moved = moved | first.y.gt(cell_x.y) | first.z.lt(cell_x.z) | first.z.gt(cell_x.z);
        if V::Wide::bits(moved) & take != 0 {
            maps = self.maps_of(&first);
        }
        maps.add_lattice(lattice.h());
        let x_local = x - (splat(lattice.origin()) + first.mul_each(lattice.h()));
        let xi0 = (t_guess - first).scale(V::Wide::splat(2.0)) - splat(DVec3::ONE);
        let inside = V::splat(V::S::of(1.0)) + V::narrow(inside_tol);
        let (xi, rr, iterations, found) = maps.invert(
            V3::narrow(x_local),
            V3::narrow(xi0),
            inside,
            V::mask_from_bits(take),
            &self.newton,
        );
        let xi = xi.widen().clamp(-1.0, 1.0);
        let residual = rr.widen().sqrt();
        for (l, out) in out.iter_mut().enumerate() {
            if found & (1 << l) != 0 {
                *out = Ok(Some(Hit {
                    cell: CellId(cell[l] as u32),
                    xi: xi.lane(l),
                    iterations: iterations[l],
                    residual: residual.lane(l),
                    inversions: 1,
                }));
            }
        }
        found
    }

    /// [`Locator::locate`] for a chunk of points: batched where that measured faster (with AVX2,
    /// detected at run time: 4 f64 or 8 f32 lanes; without it, 4 f32 lanes of glam's SSE2 `Vec4`),
    /// one point at a time otherwise (f64 without AVX2: SSE2 pairs measured slower than scalar).
    fn locate_chunk(&self, points: &[DVec3], out: &mut [Answer]) {
        #[cfg(target_arch = "x86_64")]
        match Isa::get() {
            // SAFETY: `Isa::get` answers `Avx512` only where AVX2, AVX-512F and AVX-512VL were
            // detected on this CPU, `Avx2` only where AVX2 was; these are the only ways in to the
            // AVX lanes (`batch::avx`).
            #[allow(unsafe_code)]
            Isa::Avx512 => return unsafe { self.locate_chunk_avx512(points, out) },
            #[allow(unsafe_code)]
            Isa::Avx2 => return unsafe { self.locate_chunk_avx2(points, out) },
            Isa::Portable => {}
        }
        match self.settings.precision {
            Precision::F32 => self.locate_chunk_with::<glam::Vec4>(points, out),
            Precision::F64 => {
                for (o, &x) in out.iter_mut().zip(points) {
                    *o = self.locate(x);
                }
            }
        }
    }

    /// The batch in AVX registers, the whole of it compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn locate_chunk_avx2(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx(points, out);
    }

    /// The same 256-bit lanes compiled with AVX-512VL as well: the compiler then has 32 vector
    /// registers instead of 16, and spills less (docs/benchmarks.md has the measured gain). The
    /// operations are the same IEEE operations, so the answers are the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    fn locate_chunk_avx512(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_chunk_avx(points, out);
    }

    /// The AVX lanes of the settings' precision; inlined into the caller's instruction set.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn locate_chunk_avx(&self, points: &[DVec3], out: &mut [Answer]) {
        use crate::batch::avx::{F32x8, F64x4};
        match self.settings.precision {
            Precision::F32 => self.locate_chunk_with::<F32x8>(points, out),
            Precision::F64 => self.locate_chunk_with::<F64x4>(points, out),
        }
    }
}

/// The instruction sets the batched path can be compiled for, least first.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Isa {
    /// glam's SSE2 `Vec4` for f32, the scalar search for f64.
    Portable,
    Avx2,
    /// AVX2's lanes with AVX-512VL's 32 registers.
    Avx512,
}

#[cfg(target_arch = "x86_64")]
impl Isa {
    /// The best this CPU has, capped by the environment variable `CGCONTACT_SIMD` (`avx2` or
    /// `portable`; any other value caps nothing), once per process. The answers are the same bits
    /// whichever is used: the cap is there to measure and compare speeds.
    fn get() -> Self {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(|| {
            let cap = match std::env::var("CGCONTACT_SIMD").as_deref() {
                Ok("avx2") => Isa::Avx2,
                Ok("portable") => Isa::Portable,
                _ => Isa::Avx512,
            };
            Self::detected().min(cap)
        })
    }

    /// The best this CPU has.
    fn detected() -> Self {
        use std::is_x86_feature_detected as has;
        if !has!("avx2") {
            Isa::Portable
        } else if has!("avx512f") && has!("avx512vl") {
            Isa::Avx512
        } else {
            Isa::Avx2
        }
    }
}

impl Locator for LatticeLocator<'_> {
    fn name(&self) -> &str {
        "lattice"
    }

    #[inline]
    fn locate(&self, x: DVec3) -> Answer {
        self.search(x, Collect::First).map(|(hit, _)| hit)
    }

    /// Every inversion counted, failed ones included (0 for a point refused before any).
    fn locate_counted(&self, x: DVec3) -> (Answer, u32) {
        match self.search(x, Collect::First) {
            Ok((answer, tried)) => (Ok(answer), tried),
            Err(error) => (Err(error), 0),
        }
    }

    fn locate_owners(&self, x: DVec3) -> Result<Owners, PointError> {
        let mut owners = Owners::new();
        self.search(x, Collect::All(&mut owners))?;
        owners.sort_unstable_by_key(|hit| hit.cell);
        Ok(owners)
    }

    /// Batched: 4 or 8 points at a time share SIMD instructions on the common path (the predicted
    /// cell, one Newton inversion there), with AVX2 detected at run time for f64; the answers are
    /// bitwise those of [`Locator::locate`], whichever path computed them.
    fn locate_all_into(&self, points: &[DVec3], out: &mut Vec<Answer>) {
        // Every answer is overwritten: a buffer of the right length is reused without a pass over it.
        if out.len() != points.len() {
            out.clear();
            out.resize(points.len(), Ok(None));
        }
        // Pieces of 256 points: a point costs ~100 ns, so finer splitting only adds rayon's bookkeeping.
        out.par_chunks_mut(256)
            .zip(points.par_chunks(256))
            .for_each(|(out, points)| self.locate_chunk(points, out));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Lattice;

    /// A distorted body away from the origin (full, or with every fifth cell inactive, which keeps
    /// the slot table) and points inside, on its cells' boundaries and outside.
    fn scene(holes: bool) -> (Body, Vec<DVec3>) {
        scene_keeping(|c| !holes || c % 5 != 2)
    }

    /// [`scene`] with the cells `keep` says (every 40th makes a sparse body: hash maps, no table).
    fn scene_keeping(keep: impl Fn(usize) -> bool) -> (Body, Vec<DVec3>) {
        let lattice = Lattice::new(
            DVec3::new(1000.5, -20.0, 3.0),
            DVec3::new(0.3, 0.25, 0.4),
            [9, 7, 6],
        )
        .unwrap();
        let active = (0..lattice.cell_count()).map(keep).collect();
        let mut body = Body::undeformed(lattice, active).unwrap();
        let hash = |n: usize, k: u64| {
            let z = (n as u64 ^ k).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        body.update_displacements(|n, x, u| {
            let smooth = DVec3::new((x.y * 2.0).sin(), (x.z * 1.5).cos(), (x.x * 0.7).sin());
            *u = 0.08 * smooth + 0.05 * DVec3::new(hash(n, 1), hash(n, 2), hash(n, 3));
        })
        .unwrap();
        let low = lattice.origin();
        let size = lattice.upper() - low;
        let points = (0..2003)
            .map(|i| {
                let f = |k| hash(i, k) * 1.3 + 0.5;
                let x = low + size * DVec3::new(f(4), f(5), f(6));
                // Every third point on a lattice plane (a face of the undeformed lattice).
                if i % 3 == 0 {
                    x.with_x(low.x + 0.3 * (i % 9) as f64)
                } else {
                    x
                }
            })
            .collect();
        (body, points)
    }

    /// A hit's fields as bits: cell, ξ, iterations, residual, inversions.
    type Bits = (CellId, [u64; 3], u32, u64, u32);

    fn bits(a: &Answer) -> Result<Option<Bits>, PointError> {
        a.map(|hit| {
            hit.map(|h| {
                let xi = h.xi.to_array().map(f64::to_bits);
                (h.cell, xi, h.iterations, h.residual.to_bits(), h.inversions)
            })
        })
    }

    /// `out`, the batched answers for `points`, against the scalar search, bit for bit.
    fn check(locator: &LatticeLocator<'_>, points: &[DVec3], out: &[Answer]) {
        let mut found = 0;
        for (x, answer) in points.iter().zip(out) {
            assert_eq!(bits(answer), bits(&locator.locate(*x)), "at {x}");
            found += usize::from(matches!(answer, Ok(Some(_))));
        }
        let least = if locator.body().active_count() < 50 {
            10
        } else {
            500
        };
        assert!(found > least, "{found}");
    }

    /// The block ranges only choose which cells the ring walk would invert: with them and without
    /// them (every cell of the box walked, each tested by its own range), the answers are the same
    /// bits, owners included, on a body with a far-moved node and on one with large shears.
    #[test]
    fn block_ranges_answer_bitwise_as_the_full_ring_walk() {
        let (mut body, points) = scene(true);
        let h = body.lattice().h();
        let spike = body.lattice().node_index([4, 3, 3]);
        body.update_displacements(|node, _, u| {
            if node == spike {
                *u += 12.0 * h;
            }
        })
        .unwrap();
        let mut sheared = body.clone();
        sheared
            .update_displacements(|_, x, u| {
                *u += DVec3::new(3.0 * h.x * (x.y * 2.0).sin(), 0.0, 0.0)
            })
            .unwrap();
        for body in [&body, &sheared] {
            for settings in [Settings::default(), Settings::f32()] {
                let with = LatticeLocator::new(body, settings).unwrap();
                assert!(with.pyramid.is_some());
                let without = LatticeLocator {
                    pyramid: None,
                    ..with.clone()
                };
                let mut found = 0;
                for &x in &points {
                    let (a, b) = (with.locate_counted(x), without.locate_counted(x));
                    assert_eq!(bits(&a.0), bits(&b.0), "at {x}");
                    assert_eq!(a.1, b.1, "inversions at {x}");
                    let owners = |l: &LatticeLocator<'_>| {
                        let o = l.locate_owners(x).unwrap();
                        o.iter()
                            .map(|h| bits(&Ok(Some(*h))).unwrap())
                            .collect::<Vec<_>>()
                    };
                    assert_eq!(owners(&with), owners(&without), "owners at {x}");
                    found += usize::from(matches!(a.0, Ok(Some(_))));
                }
                assert!(found > 300, "{found}");
            }
        }
    }

    /// Every lane type and instruction set, forced in turn (the dispatch picks one per machine):
    /// answers bitwise those of the scalar search.
    #[test]
    fn every_lane_type_answers_bitwise_as_the_scalar_search() {
        for (cells, order) in [
            (0, CandidateOrder::Predicted),
            (5, CandidateOrder::Predicted),
            (5, CandidateOrder::Undeformed),
            (40, CandidateOrder::Predicted),
        ] {
            // Every cell; every fifth removed (a slot table); every 40th kept (hash maps).
            let (body, points) = scene_keeping(|c| match cells {
                0 => true,
                5 => c % 5 != 2,
                _ => c % cells == 2,
            });
            let locator =
                |base: Settings| LatticeLocator::new(&body, Settings { order, ..base }).unwrap();
            // Every answer overwritten by each run: a point is never non-finite here.
            let mut out = vec![Err(PointError::NonFinite); points.len()];
            let f32 = locator(Settings::f32());
            f32.locate_chunk_with::<glam::Vec4>(&points, &mut out);
            check(&f32, &points, &out);
            #[cfg(target_arch = "x86_64")]
            for locator in [f32, locator(Settings::default())] {
                use std::is_x86_feature_detected as has;
                // SAFETY (both blocks): each entry is run only where its instruction sets were
                // detected, just before.
                if has!("avx2") {
                    out.fill(Err(PointError::NonFinite));
                    #[allow(unsafe_code)]
                    unsafe {
                        locator.locate_chunk_avx2(&points, &mut out);
                    }
                    check(&locator, &points, &out);
                }
                if has!("avx2") && has!("avx512f") && has!("avx512vl") {
                    out.fill(Err(PointError::NonFinite));
                    #[allow(unsafe_code)]
                    unsafe {
                        locator.locate_chunk_avx512(&points, &mut out);
                    }
                    check(&locator, &points, &out);
                } else {
                    eprintln!("no AVX-512VL here: its path is not checked");
                }
            }
        }
    }
}
