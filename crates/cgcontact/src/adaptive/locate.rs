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
//!
//! `relocate` (solver loops) inverts the previous answer's leaf first, from its ξ, as the uniform
//! locator's `locate/warm.rs` does, in lanes for `relocate_all`.

use glam::{DVec3, Vec3A};
use smallvec::SmallVec;

use super::lanes::Memo;
use super::nodes::OneLevel;
use super::{AdaptiveBody, Leaf};
use crate::hex8::lanes::Maps;
use crate::hex8::{Hex8Map, Hex8Map32, Kernel, NewtonOptions, Status};
use crate::lanes::{Lanes, MAX_W, Real as _, V3};
use crate::lattice::CellId;
#[cfg(target_arch = "x86_64")]
use crate::locate::Isa;
use crate::locate::{Answer, Collect, Hit, Locator, Owners, warm_start, write_hits};
use crate::reach::{self, Range};
use crate::schedule::{Layout, Scheduler};
use crate::settings::{CandidateOrder, Frame, InsideTolerance, Precision, Settings};
use crate::{Error, PointError};

/// The locator of an [`AdaptiveBody`]: complete, exact, one inversion for most points. Built in
/// O(nodes) (one pass for the displacement range) from a body it borrows.
#[derive(Clone, Debug)]
pub struct AdaptiveLocator<'a> {
    pub(super) body: &'a AdaptiveBody,
    settings: Settings,
    pub(super) newton: NewtonOptions,
    /// The range of the displacements (signed, per axis).
    u_range: Range,
    /// 1 / h per axis, h the base spacing.
    pub(super) inv_h: DVec3,
    /// Which points can be held at all (the base lattice's box shifted by the displacement
    /// range), and the inside tolerance's constants, from the finest spacing.
    pub(super) admit: reach::Admit,
    /// The frame the kernel works in (f32: shifted by the displacements' common translation,
    /// in whole cells of the finest level).
    frame: Frame,
    /// With f32 precision, the displacements in the kernel's frame (u − T) rounded to f32, in
    /// node order (16 bytes per node), as the f32 lanes read them. Empty with f64.
    u_f32: Vec<Vec3A>,
    /// The batched queries' schedule and its sort's buffers.
    scheduler: Scheduler,
    /// On a body of one level with dense base cells and owners, its node numbering as a uniform
    /// body's: the lanes then find its leaves and their corners as the uniform locator finds
    /// its cells.
    pub(crate) one_level: Option<OneLevel<'a>>,
}

impl<'a> AdaptiveLocator<'a> {
    /// A locator over `body`: one pass over the displacements for their range.
    ///
    /// Errors when the settings are out of range for this body ([`Settings::validate_for`], with
    /// its finest level's spacing).
    pub fn new(body: &'a AdaptiveBody, settings: Settings) -> Result<Self, Error> {
        settings.validate_for(body.spacing(body.finest))?;
        let u_range = body.u.iter().fold(Range::EMPTY, |r, &u| Range {
            low: r.low.min(u),
            high: r.high.max(u),
        });
        let lattice = body.lattice();
        let h_finest = body.spacing(body.finest);
        let frame = Frame::new(settings.precision, u_range.low, u_range.high, h_finest);
        let inside = InsideTolerance::with_spacing(
            &settings,
            lattice.origin(),
            h_finest,
            // The kernel rounds u − T (|u| with f64).
            frame.reach(),
        )
        // The hanging nodes lie off their faces by up to the body's seam.
        .with_added_length(body.seam());
        Ok(Self {
            body,
            settings,
            newton: inside.newton(&settings),
            u_range,
            inv_h: lattice.h().recip(),
            admit: reach::Admit::new(inside, lattice, u_range),
            frame,
            u_f32: match settings.precision {
                Precision::F32 => body
                    .u
                    .iter()
                    .map(|&u| (u - frame.shift()).as_vec3a())
                    .collect(),
                Precision::F64 => Vec::new(),
            },
            scheduler: Scheduler::new(settings.schedule),
            one_level: body
                .forest
                .dense_base()
                .and_then(|_| body.nodes.one_level()),
        })
    }

    /// The body as the schedule sees it: its base lattice and finest level, and the bytes of
    /// nodal data the batched path reads (displacements, node numbering, the corner table if
    /// stored, bricks and octrees: what decides [`crate::Schedule::Auto`]).
    pub(crate) fn layout(&self) -> Layout<'_> {
        let u = match self.settings.precision {
            Precision::F64 => size_of_val(self.body.u.as_slice()),
            Precision::F32 => size_of_val(self.u_f32.as_slice()),
        };
        Layout {
            lattice: self.body.lattice(),
            level: self.body.finest,
            bytes: u
                + self.body.nodes.heap_bytes()
                + size_of_val(self.body.corner_table.as_slice())
                + self.body.forest.heap_bytes(),
            remembers: false,
        }
    }

    /// The layout `locate_all_into` is scheduled by: [`Self::layout`], remembering leaves
    /// where [`AdaptiveLocator::locate_run`] does, so that `Auto` sorts whatever the body's size.
    pub(crate) fn locate_layout(&self) -> Layout<'_> {
        Layout {
            remembers: self.remembers(),
            ..self.layout()
        }
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

    /// The common translation T the kernel's frame is shifted by, as
    /// [`crate::LatticeLocator::frame_shift`]: with f32, the displacements' mid-range per axis
    /// rounded to whole cells of the finest level; zero with f64.
    #[must_use]
    pub fn frame_shift(&self) -> DVec3 {
        self.frame.shift()
    }

    /// The map of a leaf of `level` with corner displacements `u`, in the kernel's frame.
    #[inline(always)]
    fn leaf_map<K: Kernel>(&self, level: u8, u: &[DVec3; 8]) -> K {
        let h = self.body.spacing(level);
        self.frame.corners::<K, _>(u, |u| K::lattice_cell(h, u))
    }

    /// The displacement map of corner displacements `u`, in the kernel's frame.
    #[inline(always)]
    fn u_map<K: Kernel>(&self, u: &[DVec3; 8]) -> K {
        self.frame.corners::<K, _>(u, K::displacement_map)
    }

    /// `x` in the local frame of `leaf` (its lowest corner undeformed at the origin), shifted as
    /// the kernel's frame is.
    #[inline(always)]
    fn local<K: Kernel>(&self, x: DVec3, leaf: Leaf) -> DVec3 {
        self.frame.point::<K>(x) - self.body.leaf_origin(leaf)
    }

    fn search(
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

    /// [`Locator::relocate`]; the inversions tried go to `tried` (the hinted one included).
    fn relocate_counted(&self, x: DVec3, previous: &Answer, tried: &mut u32) -> Answer {
        // The cold search's admission first: refused and unreachable points answer as there.
        let Some(length) = self.admit.admit(x)? else {
            return Ok(None);
        };
        let options = self.admit.options(&self.newton, length);
        Ok(match self.settings.precision {
            Precision::F64 => self.relocate_with::<Hex8Map>(x, previous, &options, tried),
            Precision::F32 => self.relocate_with::<Hex8Map32>(x, previous, &options, tried),
        })
    }

    /// The previous hit's leaf (when it is one of this body's) inverted first, from the previous
    /// ξ, with the cold search's kernel and options; the cold search when it does not hold `x`.
    #[inline(always)]
    fn relocate_with<K: Kernel>(
        &self,
        x: DVec3,
        previous: &Answer,
        options: &NewtonOptions,
        tried: &mut u32,
    ) -> Option<Hit> {
        let body = self.body;
        if let Ok(Some(hint)) = previous
            && let Some(leaf) = body.leaves.get(hint.cell.index())
        {
            let map = self.leaf_map::<K>(leaf.level, &body.leaf_displacements(hint.cell.0));
            let inversion = map.invert_f64(self.local::<K>(x, leaf), warm_start(hint.xi), options);
            *tried += 1;
            if inversion.status == Status::Inside {
                return Some(Hit {
                    cell: hint.cell,
                    xi: inversion.xi.clamp(DVec3::NEG_ONE, DVec3::ONE),
                    iterations: inversion.iterations,
                    residual: inversion.residual,
                    inversions: 1,
                });
            }
        }
        self.search_with::<K>(x, options, &mut Collect::First, tried)
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
        self.guess_known::<K>(t_x, t_at, None)
    }

    /// [`Self::guess`] where the leaf `known` (id, leaf, displacements) may be the one at
    /// `t_at`: its displacements are then reused, not computed again.
    #[inline(always)]
    fn guess_known<K: Kernel>(
        &self,
        t_x: DVec3,
        t_at: DVec3,
        known: Option<&(u32, Leaf, [DVec3; 8])>,
    ) -> (DVec3, Option<(u32, Leaf, [DVec3; 8])>) {
        let Some((id, leaf)) = self.body.forest.leaf_at(t_at) else {
            return (t_x, None);
        };
        let u = match known {
            Some(&(at, _, u)) if at == id => u,
            _ => self.body.leaf_displacements(id),
        };
        (self.guess_in::<K>(t_x, t_at, leaf, &u), Some((id, leaf, u)))
    }

    /// The guess t_x − ũ(t_at) of [`Self::guess`], `leaf` (displacements `u`) holding `t_at`.
    #[inline(always)]
    fn guess_in<K: Kernel>(&self, t_x: DVec3, t_at: DVec3, leaf: Leaf, u: &[DVec3; 8]) -> DVec3 {
        let u_map = self.u_map::<K>(u);
        let xi = Self::undeformed_xi(t_at, leaf.level, leaf.ijk).clamp(DVec3::NEG_ONE, DVec3::ONE);
        let u_at = self.frame.displacement::<K>(u_map.map_f64(xi));
        t_x - u_at * self.inv_h
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
        let map = self.leaf_map::<K>(leaf.level, u);
        let xi0 = Self::undeformed_xi(t_guess, leaf.level, leaf.ijk);
        let inversion = map.invert_f64(self.local::<K>(x, leaf), xi0, options);
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
        let mut first = None;
        if let Some((id, leaf)) = body.forest.leaf_at(t_guess) {
            // Most often the leaf holding x itself: its displacements are at hand.
            let u = match at_x {
                Some((at, _, u)) if at == id => u,
                _ => body.leaf_displacements(id),
            };
            let hit = self.visit::<K>(x, id, leaf, &u, t_guess, options, collect, inversions);
            if hit.is_some() {
                return hit;
            }
            first = Some((id, leaf, u));
        }
        self.search_box::<K>(x, t_x, &mut t_guess, first, options, collect, inversions)
    }

    /// [`Locator::locate`] for a point whose inversion in lanes failed in its predicted leaf
    /// `first` (the leaf at `t_guess`): the guess and the leaf, which the lanes computed bitwise
    /// as the search does, are taken as they are, and the search goes on from there. The lanes'
    /// inside test leaves out the rounding allowance of `admit`'s options, so the leaf is
    /// inverted once more with them before `search_box`: the answer is `locate`'s, counts
    /// included.
    #[inline(never)]
    pub(super) fn after_miss(&self, x: DVec3, t_guess: DVec3, first: u32) -> Answer {
        let Some(length) = self.admit.admit(x)? else {
            return Ok(None);
        };
        let options = self.admit.options(&self.newton, length);
        Ok(match self.settings.precision {
            Precision::F64 => self.after_miss_with::<Hex8Map>(x, t_guess, first, &options),
            Precision::F32 => self.after_miss_with::<Hex8Map32>(x, t_guess, first, &options),
        })
    }

    /// `search_with` from its first visit on.
    #[inline(always)]
    fn after_miss_with<K: Kernel>(
        &self,
        x: DVec3,
        mut t_guess: DVec3,
        first: u32,
        options: &NewtonOptions,
    ) -> Option<Hit> {
        let body = self.body;
        let (collect, mut inversions) = (&mut Collect::First, 0);
        let leaf = body.leaves.at(first);
        let u = body.leaf_displacements(first);
        let hit = self.visit::<K>(
            x,
            first,
            leaf,
            &u,
            t_guess,
            options,
            collect,
            &mut inversions,
        );
        if hit.is_some() {
            return hit;
        }
        let t_x = (x - body.lattice().origin()) * self.inv_h;
        self.search_box::<K>(
            x,
            t_x,
            &mut t_guess,
            Some((first, leaf, u)),
            options,
            collect,
            &mut inversions,
        )
    }

    /// After a miss in the predicted leaf `first` (the leaf at `t_guess`, with its
    /// displacements): refine the guess by the fixed point X ← x − ũ(X), as the uniform locator
    /// does, then try every other leaf meeting x − the displacement range whose deformed
    /// corners' bounds hold x, nearest the guess first. The displacements of a leaf met again
    /// (the first step starts in `first`; the refined guess is often in the leaf of the step
    /// before) are reused. Out of line: the common path stays small.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn search_box<K: Kernel>(
        &self,
        x: DVec3,
        t_x: DVec3,
        t_guess: &mut DVec3,
        first: Option<(u32, Leaf, [DVec3; 8])>,
        options: &NewtonOptions,
        collect: &mut Collect<'_>,
        inversions: &mut u32,
    ) -> Option<Hit> {
        let body = self.body;
        let mut known = None;
        if self.settings.order == CandidateOrder::Predicted {
            // The first step from the guess, in `first` (no lookup); the second where it leads.
            (*t_guess, known) = match first {
                Some((_, leaf, u)) => (self.guess_in::<K>(t_x, *t_guess, leaf, &u), first),
                None => self.guess::<K>(t_x, *t_guess),
            };
            (*t_guess, known) = self.guess_known::<K>(t_x, *t_guess, known.as_ref());
        }
        let first = first.map(|(id, _, _)| id);
        let t_guess = *t_guess;
        // The filters widen by the largest of the per-axis tolerances of an undeformed finest leaf.
        let tau = self.admit.tau(options);
        let range = self.u_range;
        let w = reach::widening(body.lattice().h(), range.high - range.low, tau);
        let low = t_x - (range.high + w) * self.inv_h;
        let high = t_x - (range.low - w) * self.inv_h;
        let reaches = |id: u32, leaf: Leaf| {
            let u = match known {
                Some((at, _, u)) if at == id => u,
                _ => body.leaf_displacements(id),
            };
            reach::cell_reaches(
                x - body.leaf_origin(leaf),
                body.spacing(leaf.level),
                &u,
                tau,
            )
            .then_some(u)
        };
        // The leaf's box (base lattice units) and the distance from the guess to it: the
        // candidates' order.
        let bounds = |leaf: Leaf| {
            let size = level_size(leaf.level);
            let [i, j, k] = leaf.ijk;
            let lo = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * size;
            (lo, lo + size)
        };
        // The leaf holding the refined guess in its interior is the first candidate of the order
        // below when it is one (it meets the box, its corners reach x, it is not `first`): no
        // other leaf is at distance 0. It is tried before the others are gathered, and holds x
        // most often; the answer is the same (the same leaves in the same order).
        let mut tried = first;
        if let Some((id, leaf)) = body.forest.leaf_at(t_guess)
            && Some(id) != first
        {
            let (lo, hi) = bounds(leaf);
            if t_guess.cmpgt(lo).all()
                && t_guess.cmplt(hi).all()
                && lo.cmple(high).all()
                && hi.cmpge(low).all()
                && let Some(u) = reaches(id, leaf)
            {
                let hit = self.visit::<K>(x, id, leaf, &u, t_guess, options, collect, inversions);
                if hit.is_some() {
                    return hit;
                }
                tried = Some(id);
            }
        }
        // Only the leaves whose own deformed corners can reach x: usually none to a few.
        let mut candidates: SmallVec<[(f64, u32, Leaf); 16]> = SmallVec::new();
        body.forest.for_each_in_box(low, high, |id, leaf| {
            if Some(id) == first || Some(id) == tried {
                return;
            }
            if reaches(id, leaf).is_none() {
                return;
            }
            let (lo, hi) = bounds(leaf);
            let gap = (lo - t_guess).max(t_guess - hi).max(DVec3::ZERO);
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

/// 2^level, exactly: the level-`level` cells per base cell edge.
#[inline(always)]
pub(super) fn level_scale(level: u8) -> f64 {
    f64::from_bits((1023 + u64::from(level)) << 52)
}

/// The edge of a level-`level` cell in base lattice units, 2^−level (exact).
#[inline(always)]
pub(super) fn level_size(level: u8) -> f64 {
    f64::from_bits((1023 - u64::from(level)) << 52)
}

/// Points per group of the grouped path: enough independent memory chains to overlap their misses
/// (and a whole number of lanes of every lane type).
const GROUP: usize = 8;

/// A group's common path up to the inversion: for each point, its rounding length (`None`: refused
/// or out of reach), the predicted leaf, that leaf's corner displacements, and the guess.
struct Front {
    length: [Option<DVec3>; GROUP],
    first: [Option<(u32, Leaf)>; GROUP],
    u: [[DVec3; 8]; GROUP],
    t_guess: [DVec3; GROUP],
}

/// A 3-vector per lane, lane `l` being `f(l)` rounded to the lanes' precision.
#[inline(always)]
fn lanes3<V: Lanes>(f: impl Fn(usize) -> DVec3) -> V3<V> {
    V3 {
        x: V::from_fn(|l| V::S::of(f(l).x)),
        y: V::from_fn(|l| V::S::of(f(l).y)),
        z: V::from_fn(|l| V::S::of(f(l).z)),
    }
}

impl AdaptiveLocator<'_> {
    /// Answers for `points` into `out` (same length): SIMD lanes where they measured faster (the
    /// lane types and the instruction-set choice of the uniform locator), otherwise [`GROUP`]
    /// points at a time in scalar code. Either way each answer is bitwise that of
    /// [`Locator::locate`].
    fn locate_chunk(&self, points: &[DVec3], out: &mut [Answer]) {
        self.locate_run(points, out, false);
    }

    /// [`AdaptiveLocator::locate_chunk`] for `points` sorted by leaf (`sorted`: the schedule
    /// sorted them) or not: in lanes, sorted points reuse each batch's leaves in the next
    /// (`lanes.rs`, `Memo`).
    pub(crate) fn locate_run(&self, points: &[DVec3], out: &mut [Answer], sorted: bool) {
        #[cfg(target_arch = "x86_64")]
        match Isa::get() {
            // SAFETY: `Isa::get` answers `Avx512` only where AVX2, AVX-512F and AVX-512VL were
            // detected on this CPU, `Avx2` only where AVX2 was: the entry points' requirements.
            #[allow(unsafe_code)]
            Isa::Avx512 => return unsafe { self.locate_chunk_avx512(points, out, sorted) },
            #[allow(unsafe_code)]
            Isa::Avx2 => return unsafe { self.locate_chunk_avx2(points, out, sorted) },
            Isa::Portable => {}
        }
        match self.settings.precision {
            // One point at a time, each reusing the previous point's leaves.
            Precision::F64 if sorted => self.locate_chunk_lanes::<Hex8Map, f64, true>(points, out),
            Precision::F64 => self.locate_chunk_grouped::<Hex8Map>(points, out),
            Precision::F32 if sorted => {
                self.locate_chunk_lanes::<Hex8Map32, glam::Vec4, true>(points, out);
            }
            Precision::F32 => self.locate_chunk_lanes::<Hex8Map32, glam::Vec4, false>(points, out),
        }
    }

    /// Whether the schedule should sort for [`AdaptiveLocator::locate_run`]'s reuse of leaves
    /// from batch to batch (in lanes: the `Predicted` order), whatever the body's size: on a
    /// refined body. A body of one level finds its leaves as the uniform body finds its cells,
    /// from the lattice index, and sorting it cost more than the reuse saved (0.87–0.89× of its
    /// uniform twin sorted, 0.96–1.00× in input order: docs/benchmarks.md).
    fn remembers(&self) -> bool {
        self.settings.order == CandidateOrder::Predicted && self.body.finest > 0
    }

    /// The common path of a group up to the inversion, step by step over the whole group (the
    /// leaf at x; its corner table rows; their displacements; the guess and the leaf there; that
    /// leaf's displacements), so that the group's independent memory loads (octree, corner
    /// table, displacements) overlap instead of waiting one after the other. The same operations
    /// as [`AdaptiveLocator::search_with`]'s, on the kernel `K` of the settings' precision.
    #[inline(always)]
    fn front<K: Kernel>(&self, xs: &[DVec3]) -> Front {
        let body = self.body;
        let origin = body.lattice().origin();
        let predicted = self.settings.order == CandidateOrder::Predicted;
        let mut length = [None; GROUP];
        let mut t_x = [DVec3::ZERO; GROUP];
        let mut at_x = [None; GROUP];
        for (l, &x) in xs.iter().enumerate() {
            length[l] = self.admit.admit(x).ok().flatten();
            t_x[l] = (x - origin) * self.inv_h;
            if predicted && length[l].is_some() {
                at_x[l] = body.forest.leaf_at(t_x[l]);
            }
        }
        let mut corners = [[0u32; 8]; GROUP];
        for l in 0..xs.len() {
            if let Some((id, leaf)) = at_x[l] {
                corners[l] = body.leaf_nodes(id, leaf);
            }
        }
        let mut u = [[DVec3::ZERO; 8]; GROUP];
        for l in 0..xs.len() {
            if at_x[l].is_some() {
                for c in 0..8 {
                    u[l][c] = body.u[corners[l][c] as usize];
                }
            }
        }
        let mut t_guess = t_x;
        let mut first = [None; GROUP];
        for l in 0..xs.len() {
            if length[l].is_none() {
                continue;
            }
            if let Some((_, leaf)) = at_x[l] {
                let u_map = self.u_map::<K>(&u[l]);
                let xi = Self::undeformed_xi(t_x[l], leaf.level, leaf.ijk)
                    .clamp(DVec3::NEG_ONE, DVec3::ONE);
                t_guess[l] = t_x[l] - self.frame.displacement::<K>(u_map.map_f64(xi)) * self.inv_h;
            }
            first[l] = body.forest.leaf_at(t_guess[l]);
        }
        // Most often the predicted leaf is x's own: its displacements are at hand.
        for l in 0..xs.len() {
            if let Some((id, _)) = first[l]
                && at_x[l].is_none_or(|(at, _)| at != id)
            {
                u[l] = body.leaf_displacements(id);
            }
        }
        Front {
            length,
            first,
            u,
            t_guess,
        }
    }

    /// [`AdaptiveLocator::locate_chunk`] in scalar code, [`GROUP`] points at a time: the fronts,
    /// then one inversion of each point's predicted leaf; a point refused, in a hole or missed
    /// there is answered by the scalar search from scratch.
    fn locate_chunk_grouped<K: Kernel>(&self, points: &[DVec3], out: &mut [Answer]) {
        for (xs, answers) in points.chunks(GROUP).zip(out.chunks_mut(GROUP)) {
            let front = self.front::<K>(xs);
            for (l, (&x, answer)) in xs.iter().zip(answers.iter_mut()).enumerate() {
                let (Some(length), Some((id, leaf))) = (front.length[l], front.first[l]) else {
                    *answer = self.search(x, Collect::First, &mut 0);
                    continue;
                };
                let options = self.admit.options(&self.newton, length);
                let hit = self.visit::<K>(
                    x,
                    id,
                    leaf,
                    &front.u[l],
                    front.t_guess[l],
                    &options,
                    &mut Collect::First,
                    &mut 0,
                );
                *answer = match hit {
                    Some(hit) => Ok(Some(hit)),
                    None => self.search(x, Collect::First, &mut 0),
                };
            }
        }
    }

    /// [`AdaptiveLocator::locate_chunk`] in lanes `V` (whose precision is the kernel `K`'s), as the
    /// uniform locator's batched path (`lanes.rs`): for `V::W` points at once, the leaf at x, its
    /// displacement map in lanes (the corners transposed in registers straight from the
    /// displacements), the guess in lanes, the leaf at the guess (the same leaf for most points:
    /// its map is reused), and one inversion in lanes with each lane's own leaf spacing. The
    /// `Undeformed` order goes through [`AdaptiveLocator::locate_chunk_grouped`]; the remainder
    /// and every lane that leaves the common path through the scalar search, whose answers
    /// these are, bitwise.
    #[inline(always)]
    pub(crate) fn locate_chunk_lanes<K: Kernel, V: Lanes, const MEMO: bool>(
        &self,
        points: &[DVec3],
        out: &mut [Answer],
    ) where
        V::Node: LaneNodes,
    {
        if self.settings.order != CandidateOrder::Predicted {
            return self.locate_chunk_grouped::<K>(points, out);
        }
        let w = V::W;
        let batches = points.len() / w;
        let mut memo = Memo::new();
        if MEMO && w > 1 {
            // Sorted points: lane l walks the l-th of W runs of the chunk, so that each lane's
            // previous point, whose leaves its memo holds, is its neighbour in leaf order.
            let (mut xs, mut answers) = ([DVec3::ZERO; MAX_W], [Ok(None); MAX_W]);
            for b in 0..batches {
                for (l, x) in xs.iter_mut().enumerate().take(w) {
                    *x = points[l * batches + b];
                }
                self.batch::<V, true>(&xs[..w], &mut answers[..w], &mut memo);
                for (l, &answer) in answers.iter().enumerate().take(w) {
                    out[l * batches + b] = answer;
                }
            }
        } else {
            for b in 0..batches {
                let range = b * w..(b + 1) * w;
                let (points, out) = (&points[range.clone()], &mut out[range]);
                self.batch::<V, MEMO>(points, out, &mut memo);
            }
        }
        let rest = batches * w;
        self.locate_chunk_grouped::<K>(&points[rest..], &mut out[rest..]);
    }
}

impl AdaptiveLocator<'_> {
    /// [`Locator::relocate`] for a chunk of points, `answers` holding the hints and taking the
    /// answers: in lanes where [`AdaptiveLocator::locate_chunk`] uses them, one point at a time
    /// otherwise. The answers are bitwise those of [`Locator::relocate`].
    fn relocate_chunk(&self, points: &[DVec3], answers: &mut [Answer]) {
        #[cfg(target_arch = "x86_64")]
        match Isa::get() {
            // SAFETY: as in `locate_chunk`: `Isa::get` answers only what this CPU has.
            #[allow(unsafe_code)]
            Isa::Avx512 => return unsafe { self.relocate_chunk_avx512(points, answers) },
            #[allow(unsafe_code)]
            Isa::Avx2 => return unsafe { self.relocate_chunk_avx2(points, answers) },
            Isa::Portable => {}
        }
        match self.settings.precision {
            Precision::F64 => {
                for (answer, &x) in answers.iter_mut().zip(points) {
                    *answer = self.relocate(x, answer);
                }
            }
            Precision::F32 => self.relocate_chunk_lanes::<glam::Vec4>(points, answers),
        }
    }

    /// [`AdaptiveLocator::relocate_chunk`] in lanes `V`: for `V::W` points at once, the hinted
    /// leaves inverted from the hints' ξ, each lane with its leaf's spacing; the remainder, and
    /// every point without a usable hint or not found inside its hinted leaf on the lanes' common
    /// path, through [`Locator::relocate`].
    #[inline(always)]
    pub(crate) fn relocate_chunk_lanes<V: Lanes>(&self, points: &[DVec3], answers: &mut [Answer])
    where
        V::Node: LaneNodes,
    {
        let w = V::W;
        let batches = points.len() / w;
        for b in 0..batches {
            let range = b * w..(b + 1) * w;
            self.relocate_batch::<V>(&points[range.clone()], &mut answers[range]);
        }
        for (answer, &x) in answers.iter_mut().zip(points).skip(batches * w) {
            *answer = self.relocate(x, answer);
        }
    }

    /// One batch of `V::W` points of [`AdaptiveLocator::relocate_chunk_lanes`]: the admission,
    /// the hinted leaves' spacings, local coordinates and tolerances in lanes, as the cold
    /// batch's visit computes them (`lanes.rs`); only the hints and the corner nodes per lane.
    #[inline(always)]
    fn relocate_batch<V: Lanes>(&self, xs: &[DVec3], answers: &mut [Answer])
    where
        V::Node: LaneNodes,
    {
        let body = self.body;
        let lattice = body.lattice();
        let x = V::Wide::transpose(|l| &xs[l]);
        // Lanes refused or out of reach, and lanes without a usable hint, go to `relocate`.
        let (_, admitted) = self.admit.lanes(x);
        let mut take = 0u32;
        let mut cell = [CellId(0); MAX_W];
        // Lanes not taken read leaf 0's corners (there is one: a lane took a leaf), and are ignored.
        let mut rows = [[0u32; 8]; MAX_W];
        let mut leaves = [Leaf::new(0, [0; 3]); MAX_W];
        let mut xi0 = [DVec3::ZERO; MAX_W];
        for l in 0..V::W {
            if admitted & (1 << l) == 0 {
                continue;
            }
            let Ok(Some(hint)) = &answers[l] else {
                continue;
            };
            let Some(leaf) = body.leaves.get(hint.cell.index()) else {
                continue;
            };
            cell[l] = hint.cell;
            rows[l] = body.leaf_nodes(hint.cell.index() as u32, leaf);
            leaves[l] = leaf;
            xi0[l] = warm_start(hint.xi);
            take |= 1 << l;
        }
        let mut found = 0;
        if take != 0 {
            let splat = V3::<V::Wide>::splat;
            let size = V::Wide::from_fn(|l| level_size(leaves[l].level));
            let index = |a: usize| V::Wide::from_fn(|l| f64::from(leaves[l].ijk[a]));
            let ijk = V3 {
                x: index(0),
                y: index(1),
                z: index(2),
            };
            // `visit`'s: the leaf's spacing h · 2^−level and its lowest corner.
            let spacing = splat(lattice.h()).scale(size);
            let nodes = V::Node::of(self);
            let mut maps = Maps::<V>::from_nodes(|l, c| &nodes[rows[l][c] as usize]);
            maps.add_lattice_lanes(V3::narrow(spacing.scale(V::Wide::splat(0.5))));
            let x_local = self.point_lanes::<V>(x) - (splat(lattice.origin()) + spacing * ijk);
            let inverted = maps.invert(
                V3::narrow(x_local),
                lanes3::<V>(|l| xi0[l]),
                V3::<V>::splat(DVec3::ONE + self.newton.inside_tol),
                V::mask_from_bits(take),
                &self.newton,
            );
            found = write_hits(answers, inverted, |l| cell[l]);
        }
        for (l, (answer, &x)) in answers.iter_mut().zip(xs).enumerate() {
            if found & (1 << l) == 0 {
                *answer = self.relocate(x, answer);
            }
        }
    }
}

/// The displacements as the lanes read them: the body's f64 ones, or the locator's f32 copy.
pub(crate) trait LaneNodes: Copy + 'static {
    /// Whether these displacements are in the shifted frame of the f32 kernel (u − T).
    const SHIFTED: bool;
    fn of<'l>(locator: &'l AdaptiveLocator<'_>) -> &'l [Self];
}

impl AdaptiveLocator<'_> {
    /// A displacement interpolated in lanes of `V` (in the frame of its kernel), back in the
    /// body's frame, as [`Frame::displacement`] does one at a time.
    #[inline(always)]
    pub(super) fn displacement_lanes<V: Lanes>(&self, u: V3<V::Wide>) -> V3<V::Wide>
    where
        V::Node: LaneNodes,
    {
        if V::Node::SHIFTED {
            u + V3::splat(self.frame.shift())
        } else {
            u
        }
    }

    /// A point in lanes of `V`, in the frame of its kernel, as [`Frame::point`] does.
    #[inline(always)]
    pub(super) fn point_lanes<V: Lanes>(&self, x: V3<V::Wide>) -> V3<V::Wide>
    where
        V::Node: LaneNodes,
    {
        if V::Node::SHIFTED {
            x - V3::splat(self.frame.shift())
        } else {
            x
        }
    }
}

impl LaneNodes for DVec3 {
    const SHIFTED: bool = false;
    #[inline(always)]
    fn of<'l>(locator: &'l AdaptiveLocator<'_>) -> &'l [Self] {
        &locator.body.u
    }
}

impl LaneNodes for Vec3A {
    const SHIFTED: bool = true;
    #[inline(always)]
    fn of<'l>(locator: &'l AdaptiveLocator<'_>) -> &'l [Self] {
        &locator.u_f32
    }
}

crate::locate::lattice_search_locator!(AdaptiveLocator<'_>);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Lattice, PointError};

    /// A body of 3 × 2 × 2 base cells, two of them refined (one twice, against its neighbours:
    /// a jump of two levels), displaced smoothly, and points inside, on faces and outside.
    fn scene() -> (AdaptiveBody, Vec<DVec3>) {
        let lattice = Lattice::new(
            DVec3::new(-7.0, 1e3, 0.5),
            DVec3::new(0.5, 0.4, 0.3),
            [3, 2, 2],
        )
        .unwrap();
        let mut leaves: Vec<Leaf> = (2..12u32)
            .map(|c| Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap()))
            .collect();
        leaves.extend(Leaf::new(0, [1, 0, 0]).children());
        let children = Leaf::new(0, [0, 0, 0]).children();
        leaves.extend_from_slice(&children[..7]);
        leaves.extend(children[7].children());
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        body.update_independent(|n, x, u| {
            *u = DVec3::new(
                0.03 * (x.y * 3.0).sin(),
                0.02 * (x.z * 5.0).cos(),
                0.01 * (n % 7) as f64,
            )
        })
        .unwrap();
        let mut points = Vec::new();
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for cell in 0..body.cell_count() as u32 {
            for k in 0..9 {
                let mut xi = DVec3::new(next(), next(), next()) * 2.0 - 1.0;
                if k % 3 == 0 {
                    xi.x = 1.0; // on a face, shared with a neighbour of another level or none
                }
                points.push(body.point_at(CellId(cell), xi).unwrap());
            }
        }
        // Just beyond a face of each leaf, by 1e-15 to 1e-4 in ξ: each leaf's inside tolerance
        // shrinks with its level, so a path must give each point its own leaf's tolerance.
        for cell in 0..body.cell_count() as u32 {
            for e in (0..=44).step_by(2) {
                let over = 1e-15 * 10f64.powf(f64::from(e) / 4.0);
                let xi = DVec3::new(1.0 + over, 0.3, -0.2);
                points.push(body.point_at(CellId(cell), xi).unwrap());
            }
        }
        let (low, high) = (lattice.origin() - 0.3, lattice.upper() + 0.3);
        for _ in 0..200 {
            points.push(low + (high - low) * DVec3::new(next(), next(), next()));
        }
        points.push(DVec3::NAN);
        (body, points)
    }

    /// A body of `counts` base cells, each by a hash of its index one of: unrefined, a brick of
    /// level 1, 2 or 3, a tree (a brick of level 1 with one child refined twice more), or a hole;
    /// with `only` set, just the first `only` base cells that hold leaves (a sparse forest and
    /// node numbering on a large lattice). Displaced smoothly and by node, a small fraction of
    /// the finest spacing times `amplitude`, then moved by `shift` along y; points from known
    /// (leaf, ξ), a third of them on a lower y face, and points all over the lattice's box.
    /// Spacings, origin and a dyadic shift keep the arithmetic exact without the smooth part:
    /// the guesses of the points on faces are exactly on faces, the lower face of their leaf, or
    /// (shifted down) the upper face of the leaf holding x undeformed.
    fn refined_scene(
        counts: [u32; 3],
        only: Option<usize>,
        amplitude: f64,
        shift: f64,
    ) -> (AdaptiveBody, Vec<DVec3>) {
        let lattice = Lattice::new(
            DVec3::new(3.0, -2.0, 0.25),
            DVec3::new(0.5, 0.25, 0.125),
            counts,
        )
        .unwrap();
        let mut leaves = Vec::new();
        let mut kept = 0;
        for c in 0..lattice.cell_count() as u32 {
            let base = Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap());
            let kind = (c.wrapping_mul(2_654_435_761) >> 7) % 6;
            if kind == 5 || only.is_some_and(|n| kept == n) {
                continue;
            }
            kept += 1;
            let mut brick = vec![base];
            for _ in 0..kind.min(3) {
                brick = brick.iter().flat_map(|l| l.children()).collect();
            }
            if kind == 4 {
                let children = base.children();
                leaves.extend_from_slice(&children[1..]);
                leaves.extend(children[0].children().iter().flat_map(|l| l.children()));
            } else {
                leaves.extend(brick);
            }
        }
        // Leaves in any order: ids are not the bricks' order.
        let n = leaves.len();
        for i in 0..n {
            leaves.swap(i, (i * 7919 + 13) % n);
        }
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        let fine = amplitude * body.spacing(body.finest).min_element();
        displace(&mut body, fine, shift);
        let points = scene_points(&body, 0x9e37_79b9_7f4a_7c15, 500, |cell, xi| {
            if cell % 3 == 0 {
                xi.y = -1.0;
            }
        });
        (body, points)
    }

    /// Displaces `body`'s independent nodes smoothly and by node, by about `scale`, then moves
    /// them by `shift` along y.
    fn displace(body: &mut AdaptiveBody, scale: f64, shift: f64) {
        body.update_independent(|n, x, u| {
            *u = scale
                * DVec3::new(
                    0.3 * (x.y * 3.0).sin() + 0.05 * (n % 5) as f64,
                    0.2 * (x.z * 5.0).cos(),
                    0.1 * (n % 7) as f64,
                )
                + DVec3::new(0.0, shift, 0.0)
        })
        .unwrap();
    }

    /// One point in each leaf, at a random ξ that `place` may move onto the leaf's faces, edges
    /// or nodes, then `random` points all over the lattice's box widened by 0.2: a xorshift
    /// stream from `state`.
    fn scene_points(
        body: &AdaptiveBody,
        mut state: u64,
        random: usize,
        place: impl Fn(u32, &mut DVec3),
    ) -> Vec<DVec3> {
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut points = Vec::new();
        for cell in 0..body.cell_count() as u32 {
            let mut xi = DVec3::new(next(), next(), next()) * 2.0 - 1.0;
            place(cell, &mut xi);
            points.push(body.point_at(CellId(cell), xi).unwrap());
        }
        let lattice = body.lattice();
        let (low, high) = (lattice.origin() - 0.2, lattice.upper() + 0.2);
        for _ in 0..random {
            points.push(low + (high - low) * DVec3::new(next(), next(), next()));
        }
        points
    }

    /// A body of one level: every base cell of an 8 × 6 × 5 lattice a leaf (every lattice node
    /// a node), or with `holes` a sixth of them missing, the lattice's first corner cell among
    /// them (so that some lattice node is no node). Its leaves in any order, its displacements
    /// and points as [`refined_scene`]'s; the lanes find its leaves through [`OneLevel`].
    fn one_level_scene(holes: bool) -> (AdaptiveBody, Vec<DVec3>) {
        let lattice = Lattice::new(
            DVec3::new(-1.5, 2.0, 0.75),
            DVec3::new(0.25, 0.5, 0.125),
            [8, 6, 5],
        )
        .unwrap();
        let mut leaves: Vec<Leaf> = (0..lattice.cell_count() as u32)
            .filter(|&c| !holes || (c != 0 && (c.wrapping_mul(2_654_435_761) >> 7) % 6 != 5))
            .map(|c| Leaf::new(0, lattice.cell_ijk(CellId(c)).unwrap()))
            .collect();
        let n = leaves.len();
        for i in 0..n {
            leaves.swap(i, (i * 7919 + 13) % n);
        }
        let mut body = AdaptiveBody::from_leaves(lattice, leaves).unwrap();
        assert_eq!(body.node_count() < lattice.node_count(), holes);
        let h = body.spacing(0).min_element();
        displace(&mut body, h, 0.0);
        // On faces, edges and nodes too.
        let points = scene_points(&body, 0x2545_f491_4f6c_dd1d, 300, |cell, xi| {
            match cell % 4 {
                0 => xi.y = -1.0,
                1 => (xi.x, xi.z) = (1.0, -1.0),
                2 => *xi = DVec3::new(1.0, 1.0, -1.0),
                _ => {}
            }
        });
        (body, points)
    }

    /// A hit's fields as bits: cell, ξ, iterations, residual, inversions.
    type HitBits = (u32, [u64; 3], u32, u64, u32);

    fn bits(a: &Answer) -> Result<Option<HitBits>, PointError> {
        a.map(|h| {
            h.map(|h| {
                (
                    h.cell.0,
                    h.xi.to_array().map(f64::to_bits),
                    h.iterations,
                    h.residual.to_bits(),
                    h.inversions,
                )
            })
        })
    }

    /// Runs `entry` on seven scenes with every candidate order and each of `precisions`, and
    /// compares each answer bitwise with `locate`'s; every answer starts as a sentinel that no
    /// point here gets. Each scene's points are run as given, then sorted by the schedule's key
    /// with near copies (runs of points in one leaf, for the sorted path's memo).
    fn check(
        precisions: &[Settings],
        entry: impl Fn(&AdaptiveLocator<'_>, &[DVec3], &mut [Answer]),
    ) {
        let scenes = [
            scene(),
            refined_scene([6, 5, 4], None, 1.0, 0.0),
            refined_scene([6, 5, 4], None, 0.0, 0.0),
            refined_scene([6, 5, 4], None, 0.0, -1.0 / 128.0),
            refined_scene([70, 60, 50], Some(5), 1.0, 0.0),
            one_level_scene(false),
            one_level_scene(true),
        ];
        for (body, points) in &scenes {
            // Also sorted as the schedule sorts them, each point with 8 near copies: runs of
            // points in one leaf, which the lanes' memo serves.
            let blocks = crate::schedule::Blocks::new(body.lattice(), body.finest, 0);
            let nudge = body.spacing(body.finest) * 1e-3;
            let mut sorted: Vec<DVec3> = points
                .iter()
                .flat_map(|&x| (0..9).map(move |k| x + nudge * f64::from(k)))
                .collect();
            sorted.sort_by_key(|&x| blocks.key(x));
            for points in [points, &sorted] {
                check_points(precisions, &entry, body, points);
            }
        }
    }

    /// [`check`] on one body and its points.
    fn check_points(
        precisions: &[Settings],
        entry: &impl Fn(&AdaptiveLocator<'_>, &[DVec3], &mut [Answer]),
        body: &AdaptiveBody,
        points: &[DVec3],
    ) {
        for order in [CandidateOrder::Predicted, CandidateOrder::Undeformed] {
            for &base in precisions {
                let locator = AdaptiveLocator::new(body, Settings { order, ..base }).unwrap();
                // The one-level scenes take the lanes' one-level lookup, the others not.
                assert_eq!(locator.one_level.is_some(), body.finest == 0);
                let mut out: Vec<Answer> = points
                    .iter()
                    .map(|x| match x.is_finite() {
                        true => Err(PointError::NonFinite),
                        false => Ok(None),
                    })
                    .collect();
                entry(&locator, points, &mut out);
                let mut found = 0;
                for (x, answer) in points.iter().zip(&out) {
                    assert_eq!(bits(answer), bits(&locator.locate(*x)), "at {x}");
                    found += usize::from(matches!(answer, Ok(Some(_))));
                }
                assert!(found > 150, "{found}");
            }
        }
    }

    /// Runs `entry`, a warm lane path, with each of `precisions` and compares each answer bitwise
    /// with the scalar `relocate`'s. The hints are the answers at points moved by up to a tenth of
    /// the base spacing (some hinted leaves hold their point, some do not), with refusals and ids
    /// out of range among them.
    fn check_warm(
        precisions: &[Settings],
        entry: impl Fn(&AdaptiveLocator<'_>, &[DVec3], &mut [Answer]),
    ) {
        let (body, points) = scene();
        let h = body.spacing(0);
        for &settings in precisions {
            let locator = AdaptiveLocator::new(&body, settings).unwrap();
            let hints: Vec<Answer> = points
                .iter()
                .enumerate()
                .map(|(i, &x)| match i % 11 {
                    0 => Err(PointError::NonFinite),
                    1 => locator.locate(x).map(|hit| {
                        hit.map(|hit| Hit {
                            cell: CellId(body.cell_count() as u32),
                            ..hit
                        })
                    }),
                    _ => locator.locate(x + h * 0.1 * ((i % 7) as f64 / 3.0 - 1.0)),
                })
                .collect();
            let mut out = hints.clone();
            entry(&locator, &points, &mut out);
            let mut one = 0;
            for ((&x, hint), answer) in points.iter().zip(&hints).zip(&out) {
                assert_eq!(bits(answer), bits(&locator.relocate(x, hint)), "at {x}");
                one += usize::from(matches!(answer, Ok(Some(hit)) if hit.inversions == 1));
            }
            assert!(one > 100, "{one}");
        }
    }

    /// Points just beyond a face of their hinted leaf, by 1e-15 to 1e-4 in ξ: each leaf's
    /// inside tolerance shrinks with its level, so the lanes must give each lane its own leaf's
    /// tolerance to accept and refuse exactly the points the scalar `relocate` does.
    #[test]
    fn warm_lanes_take_each_leafs_own_tolerance() {
        let (body, _) = scene();
        let mut points = Vec::new();
        let mut hints = Vec::new();
        for leaf in 0..body.cell_count() as u32 {
            for e in 0..=44 {
                let over = 1e-15 * 10f64.powf(f64::from(e) / 4.0);
                let xi = DVec3::new(1.0 + over, 0.3, -0.2);
                points.push(body.point_at(CellId(leaf), xi).unwrap());
                hints.push(Hit::hint(CellId(leaf), DVec3::new(1.0, 0.3, -0.2)));
            }
        }
        for settings in [Settings::default(), Settings::f32()] {
            let locator = AdaptiveLocator::new(&body, settings).unwrap();
            let mut kept = 0;
            let mut out = hints.clone();
            locator.relocate_chunk(&points, &mut out);
            let mut lanes = hints.clone();
            match settings.precision {
                Precision::F64 => locator.relocate_chunk_lanes::<f64>(&points, &mut lanes),
                Precision::F32 => locator.relocate_chunk_lanes::<glam::Vec4>(&points, &mut lanes),
            }
            for (((&x, hint), a), b) in points.iter().zip(&hints).zip(&out).zip(&lanes) {
                let scalar = locator.relocate(x, hint);
                assert_eq!(bits(a), bits(&scalar), "dispatched, at {x}");
                assert_eq!(bits(b), bits(&scalar), "portable lanes, at {x}");
                kept += usize::from(
                    matches!((a, hint), (Ok(Some(a)), Ok(Some(h))) if a.cell == h.cell),
                );
            }
            // Some points stay in their hinted leaf (within its tolerance), some do not.
            assert!(
                kept > 0 && kept < points.len(),
                "{kept} of {}",
                points.len()
            );
        }
    }

    #[test]
    fn warm_portable_lanes_answer_bitwise_as_the_scalar_relocate() {
        let (f64s, f32s) = (Settings::default(), Settings::f32());
        check_warm(&[f32s], |l, p, o| {
            l.relocate_chunk_lanes::<glam::Vec4>(p, o)
        });
        check_warm(&[f64s], |l, p, o| l.relocate_chunk_lanes::<f64>(p, o));
        // Whatever this machine dispatches to.
        check_warm(&[f64s, f32s], |l, p, o| l.relocate_chunk(p, o));
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(not(cgcontact_host_avx2), ignore = "this CPU has no AVX2")]
    fn warm_avx2_lanes_answer_bitwise_as_the_scalar_relocate() {
        assert!(std::is_x86_feature_detected!("avx2"));
        // SAFETY: AVX2 was detected just above.
        #[allow(unsafe_code)]
        check_warm(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.relocate_chunk_avx2(p, o)
        });
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(
        not(cgcontact_host_avx512),
        ignore = "this CPU has no AVX-512F and AVX-512VL"
    )]
    fn warm_avx512_lanes_answer_bitwise_as_the_scalar_relocate() {
        use std::is_x86_feature_detected as has;
        assert!(has!("avx2") && has!("avx512f") && has!("avx512vl"));
        // SAFETY: AVX2, AVX-512F and AVX-512VL were detected just above.
        #[allow(unsafe_code)]
        check_warm(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.relocate_chunk_avx512(p, o)
        });
    }

    #[test]
    fn grouped_and_portable_lanes_answer_bitwise_as_locate() {
        let (f64s, f32s) = (Settings::default(), Settings::f32());
        check(&[f64s], |l, p, o| l.locate_chunk_grouped::<Hex8Map>(p, o));
        check(&[f32s], |l, p, o| l.locate_chunk_grouped::<Hex8Map32>(p, o));
        check(&[f32s], |l, p, o| {
            l.locate_chunk_lanes::<Hex8Map32, glam::Vec4, false>(p, o)
        });
        check(&[f32s], |l, p, o| {
            l.locate_chunk_lanes::<Hex8Map32, glam::Vec4, true>(p, o)
        });
        check(&[f64s], |l, p, o| {
            l.locate_chunk_lanes::<Hex8Map, f64, false>(p, o)
        });
        check(&[f64s], |l, p, o| {
            l.locate_chunk_lanes::<Hex8Map, f64, true>(p, o)
        });
        check(&[f64s, f32s], |l, p, o| l.locate_run(p, o, true));
        // Through the trait, whatever this machine dispatches to.
        check(&[f64s, f32s], |l, p, o| {
            let mut all = Vec::new();
            l.locate_all_into(p, &mut all);
            o.copy_from_slice(&all);
        });
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(not(cgcontact_host_avx2), ignore = "this CPU has no AVX2")]
    fn avx2_lanes_answer_bitwise_as_locate() {
        assert!(std::is_x86_feature_detected!("avx2"));
        // SAFETY: AVX2 was detected just above.
        #[allow(unsafe_code)]
        check(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.locate_chunk_avx2(p, o, false)
        });
        // SAFETY: as above.
        #[allow(unsafe_code)]
        check(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.locate_chunk_avx2(p, o, true)
        });
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(
        not(cgcontact_host_avx512),
        ignore = "this CPU has no AVX-512F and AVX-512VL"
    )]
    fn avx512_lanes_answer_bitwise_as_locate() {
        use std::is_x86_feature_detected as has;
        assert!(has!("avx2") && has!("avx512f") && has!("avx512vl"));
        // SAFETY: AVX2, AVX-512F and AVX-512VL were detected just above.
        #[allow(unsafe_code)]
        check(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.locate_chunk_avx512(p, o, false)
        });
        // SAFETY: as above.
        #[allow(unsafe_code)]
        check(&[Settings::default(), Settings::f32()], |l, p, o| unsafe {
            l.locate_chunk_avx512(p, o, true)
        });
    }

    /// The search as documented, without the shortcut of `search_box`: the predicted leaf, then
    /// every other leaf of the box whose corners reach x, by distance to the refined guess and id.
    fn documented_search<K: Kernel>(locator: &AdaptiveLocator<'_>, x: DVec3) -> Answer {
        let Some(length) = locator.admit.admit(x)? else {
            return Ok(None);
        };
        let options = locator.admit.options(&locator.newton, length);
        let body = locator.body;
        let predicted = locator.settings.order == CandidateOrder::Predicted;
        let t_x = (x - body.lattice().origin()) * locator.inv_h;
        let mut t_guess = if predicted {
            locator.guess::<K>(t_x, t_x).0
        } else {
            t_x
        };
        let mut inversions = 0;
        let mut collect = Collect::First;
        let mut visit = |id: u32, leaf: Leaf, t_guess: DVec3| {
            let u = body.leaf_displacements(id);
            locator.visit::<K>(
                x,
                id,
                leaf,
                &u,
                t_guess,
                &options,
                &mut collect,
                &mut inversions,
            )
        };
        let first = body.forest.leaf_at(t_guess);
        if let Some((id, leaf)) = first
            && let Some(hit) = visit(id, leaf, t_guess)
        {
            return Ok(Some(hit));
        }
        if predicted {
            for _ in 0..2 {
                t_guess = locator.guess::<K>(t_x, t_guess).0;
            }
        }
        // The filters widen by the largest of the per-axis tolerances of an undeformed finest leaf.
        let tau = locator.admit.tau(&options);
        let range = locator.u_range;
        let w = reach::widening(body.lattice().h(), range.high - range.low, tau);
        let low = t_x - (range.high + w) * locator.inv_h;
        let high = t_x - (range.low - w) * locator.inv_h;
        let mut candidates = Vec::new();
        body.forest.for_each_in_box(low, high, |id, leaf| {
            let u = body.leaf_displacements(id);
            let origin = x - body.leaf_origin(leaf);
            if Some(id) != first.map(|f| f.0)
                && reach::cell_reaches(origin, body.spacing(leaf.level), &u, tau)
            {
                let size = 0.5f64.powi(i32::from(leaf.level));
                let lo = DVec3::from_array(leaf.ijk.map(f64::from)) * size;
                let gap = (lo - t_guess).max(t_guess - (lo + size)).max(DVec3::ZERO);
                candidates.push((gap.max_element(), id, leaf));
            }
        });
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Ok(candidates
            .into_iter()
            .find_map(|(_, id, leaf)| visit(id, leaf, t_guess)))
    }

    /// The scene with larger displacements than its own, so that many points miss their
    /// predicted leaf (along x too, or not: then the guesses of points on the faces normal to x
    /// lie exactly on those faces), and points on every corner, edge and face of every leaf.
    fn scene_of_misses(along_x: bool) -> (AdaptiveBody, Vec<DVec3>) {
        let (mut body, mut points) = scene();
        let x_part = if along_x { 1.0 } else { 0.0 };
        body.update_independent(|n, x, u| {
            *u = DVec3::new(
                x_part * (0.2 * (x.y * 7.0).sin() + 0.03 * (n % 5) as f64),
                0.15 * (x.z * 9.0).cos(),
                0.2 * (x.x * 5.0).sin(),
            )
        })
        .unwrap();
        for cell in 0..body.cell_count() as u32 {
            for k in 0..27 {
                let xi = DVec3::new((k % 3) as f64, (k / 3 % 3) as f64, (k / 9) as f64) - 1.0;
                points.push(body.point_at(CellId(cell), xi).unwrap());
            }
        }
        (body, points)
    }

    #[test]
    fn the_search_answers_as_documented() {
        for (along_x, order) in [true, false]
            .into_iter()
            .flat_map(|a| [CandidateOrder::Predicted, CandidateOrder::Undeformed].map(|o| (a, o)))
        {
            let (body, points) = scene_of_misses(along_x);
            for base in [Settings::default(), Settings::f32()] {
                let locator = AdaptiveLocator::new(&body, Settings { order, ..base }).unwrap();
                let mut beyond_first = 0;
                for &x in &points {
                    let expected = match base.precision {
                        Precision::F64 => documented_search::<Hex8Map>(&locator, x),
                        Precision::F32 => documented_search::<Hex8Map32>(&locator, x),
                    };
                    assert_eq!(bits(&locator.locate(x)), bits(&expected), "at {x}");
                    beyond_first +=
                        usize::from(matches!(expected, Ok(Some(h)) if h.inversions > 1));
                }
                // The search past the predicted leaf is exercised.
                assert!(beyond_first > 50, "{beyond_first}");
            }
        }
    }
}
