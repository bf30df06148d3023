//! Point location: the [`Locator`] trait every strategy implements, and the lattice locator.
//!
//! | file | what |
//! |---|---|
//! | `mod.rs` | [`Hit`], [`Locator`], [`LatticeLocator`] and its construction |
//! | `scalar.rs` | the search one point at a time: admit, predict, invert the predicted cell |
//! | `rings.rs` | after a miss: every other cell that can hold the point, nearest shell first ([`rings::Rings`]) |
//! | `batched.rs` | `locate_all`'s common path, 4 or 8 points per SIMD lane set, and the instruction-set dispatch |
//! | `warm.rs` | `relocate`: the previous answer's cell inverted first, from its ξ (solver loops), one point or a lane set at a time |
//! | `avx.rs` | the AVX lane types, private to the `#[target_feature]` entry points that use them |
//!
//! The batched path is written once: the lane traits and the portable lanes are in `crate::lanes`,
//! the lane Newton in `hex8/lanes.rs` beside the scalar Newton it copies (`hex8/mod.rs`), the AVX
//! lanes and their entry points in `avx.rs`, and the dispatch between them in `batched.rs`, as
//! memchr splits its generic algorithm, per-ISA wrappers and dispatch.
//!
//! # Why the lattice search is complete
//! A point x inside deformed cell c satisfies x = X(ξ) + u(ξ), with X(ξ) the undeformed point of c and
//! u(ξ) a convex combination of c's corner displacements. So the undeformed point X = x − u(ξ) lies in
//! x minus the range of the nodal displacements, and c is one of the lattice cells meeting that box.
//! The locator visits those cells (the active ones whose own deformed bounds hold x: `reach.rs`), so
//! it cannot miss the containing cell of a valid mesh. It visits them nearest first, starting at the
//! cell holding x − ũ, ũ the displacement interpolated at x on the undeformed lattice, which is the
//! containing cell for almost every point.

#[cfg(target_arch = "x86_64")]
mod avx;
mod batched;
#[cfg(target_arch = "x86_64")]
pub(crate) use batched::{Isa, answer_the_rest, clamped_cells, lane_indices, write_hits};
mod rings;
mod scalar;
mod warm;

use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use smallvec::SmallVec;

use crate::body::Body;
use crate::hex8::NewtonOptions;
use crate::lattice::CellId;
use crate::reach::{self, Pyramid, Range};
use crate::schedule::{Layout, Scheduler};
use crate::settings::{Frame, InsideTolerance, Precision, Settings};
use crate::{Error, PointError};

pub(crate) use scalar::Collect;
pub(crate) use warm::{relocate_split, start as warm_start};
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

impl Hit {
    /// A previous answer made from only a cell and ξ, as a caller outside Rust keeps them between
    /// solver iterations: the hint [`Locator::relocate`] tries first (a ξ that is not finite
    /// starts from the cell's centre). Its counts and residual are zero; `relocate` reads only
    /// the cell and ξ.
    pub fn hint(cell: CellId, xi: DVec3) -> Answer {
        Ok(Some(Self {
            cell,
            xi,
            iterations: 0,
            residual: 0.0,
            inversions: 0,
        }))
    }
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

    /// Whether the batched queries would sort `points` by lattice cell before answering them
    /// ([`crate::Schedule`]: on a large body, the order decides the speed; under the default
    /// schedule, a sample of 2,048 points tells whether they already come in order). A caller
    /// that splits such a batch into small pieces (to convert each piece's answers while they
    /// are in cache, say) loses the sort, and random points then run up to 2.5× slower on a
    /// 4.2 M-cell block: it should pass the batch whole. The default (the baselines): false.
    fn sorts_batch(&self, points: &[DVec3]) -> bool {
        let _ = points;
        false
    }

    /// [`Locator::locate_all_into`]'s answers without putting them back in input order:
    /// `out[k]` is the answer to `points[order[k]]`, `order` a permutation of the indices (both
    /// resized). The lattice and adaptive locators answer in their schedule's order (sorted by
    /// lattice cell on large bodies, [`crate::Schedule`]); the default, in input order.
    ///
    /// For callers that can use the answers in any order (a contact solver assembling each
    /// point's contribution): on bodies whose nodal data leaves the caches, putting each answer
    /// back at its input place is a store to a random place per point, about a fifth of
    /// `locate_all_into`'s time on a 4.2 M-cell block (docs/benchmarks.md, section `scale`).
    fn locate_all_unordered_into(
        &self,
        points: &[DVec3],
        order: &mut Vec<usize>,
        out: &mut Vec<Answer>,
    ) {
        order.clear();
        order.extend(0..points.len());
        self.locate_all_into(points, out);
    }

    /// [`Locator::locate`] for every point, in parallel, answers in input order.
    fn locate_all(&self, points: &[DVec3]) -> Vec<Answer> {
        let mut out = Vec::with_capacity(points.len());
        self.locate_all_into(points, &mut out);
        out
    }

    /// [`Locator::locate`] warm-started: `previous` is this point's answer from an earlier search
    /// (the last iteration of a solver loop, whose displacements changed a little since).
    ///
    /// The answer is always one a cold search could give:
    /// - a point [`Locator::locate`] refuses or answers `Ok(None)` gets the same answer, whatever
    ///   the hint;
    /// - a cell returned is among [`Locator::locate_owners`]`(x)`; when that has exactly one owner,
    ///   it is [`Locator::locate`]'s cell, with the same ξ up to the Newton tolerance (within
    ///   1e-12 with the f64 defaults, about 1e-6 with f32: two starts, one root).
    ///
    /// Any `previous` is accepted: a miss, a refused point or a cell out of range or inactive is
    /// no hint, and a hint whose cell no longer holds the point costs one inversion before the
    /// cold search. The lattice and adaptive locators invert the previous hit's cell first,
    /// starting from its ξ, and return it when it holds the point (`inversions` 1, no hashing);
    /// a hit found after that failed try counts it in `inversions`. The default is the cold
    /// search (the baselines).
    fn relocate(&self, x: DVec3, previous: &Answer) -> Answer {
        let _ = previous;
        self.locate(x)
    }

    /// [`Locator::relocate`] for every point, in parallel on the current rayon pool: `answers`
    /// holds the previous answers (one per point, in input order) and is overwritten in place
    /// with the new ones (no allocation per point). When its length is not `points`' it holds no
    /// usable hints: it is resized and every point is located cold ([`Locator::locate_all_into`]).
    fn relocate_all(&self, points: &[DVec3], answers: &mut Vec<Answer>) {
        if answers.len() != points.len() {
            return self.locate_all_into(points, answers);
        }
        // Pieces of 256 points, as `locate_all_into`'s.
        answers
            .par_chunks_mut(256)
            .zip(points.par_chunks(256))
            .for_each(|(answers, points)| {
                for (answer, &x) in answers.iter_mut().zip(points) {
                    *answer = self.relocate(x, answer);
                }
            });
    }
}

/// A body's displacements copied over the box of its nodes, x fastest, zero at nodes without one:
/// on a body that is not a full block, the batched gather's corner loads then need no slot table
/// (one dependent load fewer per corner; 1.5× the points per second on half a block, measured with
/// `profile_locate big partial`). Kept only while the box holds at most [`Boxed::MOST`] times the
/// body's nodes, so that it costs at most that many times their 24 bytes.
#[derive(Clone, Debug)]
pub(crate) struct Boxed {
    /// The box's lowest lattice node, as f64 lanes compare it.
    low: DVec3,
    /// The box's last cell per axis (nodes − 2), likewise.
    last: DVec3,
    /// Nodes per axis.
    dims: [u32; 3],
    /// Each corner's offset from its cell's lowest node, in the box (VTK order).
    corner: [usize; 8],
    /// The displacements.
    u: Vec<DVec3>,
}

impl Boxed {
    /// The most box nodes per body node.
    const MOST: usize = 2;

    fn new(body: &Body) -> Option<Self> {
        let (low, dims, u) = body.boxed_displacements(Self::MOST * body.node_count())?;
        if dims.contains(&1) {
            // A box one node thin holds no cell.
            return None;
        }
        let [dx, dy, _] = dims.map(|n| n as usize);
        Some(Self {
            low: DVec3::from(low.map(f64::from)),
            last: DVec3::from(dims.map(|n| f64::from(n - 2))),
            dims,
            corner: crate::lattice::CORNER_OFFSETS
                .map(|[i, j, k]| i as usize + dx * (j as usize + dy * k as usize)),
            u,
        })
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
    /// Which points can be held at all, and the inside tolerance's constants.
    admit: reach::Admit,
    /// Per-block displacement ranges, built only where the displacements spread over more than a
    /// few cells: the search then visits only cells whose own shifted box holds the point.
    pyramid: Option<Pyramid>,
    /// The frame the kernel works in (f32: shifted by the displacements' common translation).
    frame: Frame,
    /// With f32 precision, the displacements in the kernel's frame (u − T) rounded to f32, in the
    /// body's slot order (16 bytes per node): the batched path reads them as they are. Empty with
    /// f64.
    u_f32: Vec<Vec3A>,
    /// An undisplaced node in the f32 kernel's frame, −T (the batched path's corners without a
    /// displacement).
    zero_f32: Vec3A,
    /// With f64 on a body with a slot table whose nodes fill their box densely, the displacements
    /// over that box: the batched path's gather loads each corner at once instead of through the
    /// table (see [`Boxed`]).
    boxed: Option<Boxed>,
    /// Every cell of the lattice is active: the batched path skips the activity lookup.
    all_active: bool,
    /// The batched queries' schedule and its sort's buffers.
    scheduler: Scheduler,
}

impl<'a> LatticeLocator<'a> {
    /// A locator over `body`: one pass over the displacements for their range, and, only when they
    /// spread over more than a few cells, one over the active cells for per-block ranges.
    ///
    /// Errors when the settings are out of range for this body ([`Settings::validate_for`]).
    pub fn new(body: &'a Body, settings: Settings) -> Result<Self, Error> {
        settings.validate_for(body.lattice().h())?;
        let u_range = reach::displacement_range(body);
        // Bodies refuse non-finite displacements (every entry point checks), so the range is finite.
        let u_max = u_range.high.max(-u_range.low);
        let lattice = body.lattice();
        let spread = u_range.high - u_range.low;
        let frame = Frame::new(settings.precision, u_range.low, u_range.high, lattice.h());
        // The kernel rounds the displacements in its frame: its share of the inside tolerance
        // grows with |u − T| (|u| with f64).
        let inside = InsideTolerance::new(&settings, lattice, frame.reach());
        Ok(Self {
            body,
            settings,
            newton: inside.newton(&settings),
            u_max,
            u_range,
            inv_h: lattice.h().recip(),
            admit: reach::Admit::new(inside, lattice, u_range),
            frame,
            // Not on a sparse body whose lattice dwarfs it: the pyramid is dense over the lattice
            // (48 bytes per 8 cells), and the body's memory must grow with its cells.
            pyramid: (reach::pyramid_pays(spread, lattice.h())
                && lattice.cell_count() <= 64 * body.active_count())
            .then(|| Pyramid::new(body)),
            u_f32: match settings.precision {
                Precision::F32 => body
                    .displacements()
                    .iter()
                    .map(|&u| (u - frame.shift()).as_vec3a())
                    .collect(),
                Precision::F64 => Vec::new(),
            },
            zero_f32: (DVec3::ZERO - frame.shift()).as_vec3a(),
            all_active: body.active_count() == lattice.cell_count(),
            boxed: match settings.precision {
                Precision::F64 => Boxed::new(body),
                Precision::F32 => None,
            },
            scheduler: Scheduler::new(settings.schedule),
        })
    }

    /// The body as the schedule sees it: its lattice, and the bytes of nodal data the batched
    /// path reads (what decides [`crate::Schedule::Auto`]).
    pub(crate) fn layout(&self) -> Layout<'_> {
        let u = match self.settings.precision {
            Precision::F64 => size_of_val(self.body.displacements()),
            Precision::F32 => size_of_val(self.u_f32.as_slice()),
        };
        Layout {
            lattice: self.body.lattice(),
            level: 0,
            bytes: u + self.pyramid.as_ref().map_or(0, Pyramid::heap_bytes),
            remembers: false,
        }
    }

    /// The layout `locate_all_into` is scheduled by: [`Self::layout`] (the batches keep
    /// nothing from one to the next).
    pub(crate) fn locate_layout(&self) -> Layout<'_> {
        self.layout()
    }

    /// `locate_all_into`'s chunks, whether the schedule sorted them or not.
    fn locate_run(&self, points: &[DVec3], out: &mut [Answer], _sorted: bool) {
        self.locate_chunk(points, out);
    }

    /// The body searched.
    #[must_use]
    pub fn body(&self) -> &Body {
        self.body
    }

    /// The per-block displacement ranges, where they were built (the gap search borrows them).
    pub(crate) fn pyramid(&self) -> Option<&Pyramid> {
        self.pyramid.as_ref()
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

    /// The common translation T the kernel's frame is shifted by: with f32, the displacements'
    /// mid-range per axis rounded to whole cells, so that f32 rounds u − T instead of u and a
    /// rigid translation costs no precision; zero with f64, and wherever the mid-range is under
    /// half a cell. docs/numerics.md has the measured effect.
    #[must_use]
    pub fn frame_shift(&self) -> DVec3 {
        self.frame.shift()
    }

    /// Bytes this locator keeps on the heap besides the body (the f32 copy of the displacements,
    /// the per-block displacement ranges, the batched queries' sort buffers).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.u_f32.capacity() * size_of::<Vec3A>()
            + self
                .boxed
                .as_ref()
                .map_or(0, |b| b.u.capacity() * size_of::<DVec3>())
            + self.pyramid.as_ref().map_or(0, Pyramid::heap_bytes)
            + self.scheduler.heap_bytes()
    }
}

/// The [`Locator`] implementation of the lattice and the adaptive locator, written once: their
/// searches, lanes and warm starts differ, what the trait asks of them does not. `$locator`
/// supplies, as inherent methods: `search(x, Collect, &mut tried)`, `relocate_counted(x,
/// &previous, &mut tried)`, `locate_chunk(points, out)` and `relocate_chunk(points, answers)`
/// (batched, each answer bitwise that of the one-point method), `layout()` and a `scheduler`.
macro_rules! lattice_search_locator {
    ($locator:ty) => {
        impl $crate::locate::Locator for $locator {
            fn name(&self) -> &str {
                "lattice"
            }

            #[inline]
            fn locate(&self, x: DVec3) -> Answer {
                self.search(x, Collect::First, &mut 0)
            }

            fn sorts_batch(&self, points: &[DVec3]) -> bool {
                self.scheduler.would_sort(self.locate_layout(), points)
            }

            /// Every inversion counted, failed ones included (0 for a point refused before any).
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

            /// Batched: 4 or 8 points at a time share SIMD instructions on the common path (the
            /// predicted cell, one Newton inversion there), the instruction set detected at run
            /// time, in the schedule's order ([`crate::Schedule`]); the answers are bitwise those
            /// of [`Locator::locate`], whichever path computed them.
            fn locate_all_into(&self, points: &[DVec3], out: &mut Vec<Answer>) {
                // Every answer is overwritten: a buffer of the right length is reused without a
                // pass over it.
                if out.len() != points.len() {
                    out.clear();
                    out.resize(points.len(), Ok(None));
                }
                self.scheduler.run_told(
                    self.locate_layout(),
                    points,
                    out,
                    false,
                    |points, out, sorted| self.locate_run(points, out, sorted),
                );
            }

            /// Batched and scheduled as [`Locator::locate_all_into`], without the scatter back to
            /// input order.
            fn locate_all_unordered_into(
                &self,
                points: &[DVec3],
                order: &mut Vec<usize>,
                out: &mut Vec<Answer>,
            ) {
                self.scheduler.run_unordered_told(
                    self.locate_layout(),
                    points,
                    order,
                    out,
                    Ok(None),
                    |points, out, sorted| self.locate_run(points, out, sorted),
                );
            }

            /// The previous hit's cell first, from its ξ (see the trait).
            #[inline]
            fn relocate(&self, x: DVec3, previous: &Answer) -> Answer {
                self.relocate_counted(x, previous, &mut 0)
            }

            /// Batched as [`Locator::locate_all_into`]: the hinted cells of 4 or 8 points inverted
            /// at once; the answers are bitwise those of [`Locator::relocate`].
            fn relocate_all(&self, points: &[DVec3], answers: &mut Vec<Answer>) {
                if answers.len() != points.len() {
                    return self.locate_all_into(points, answers);
                }
                self.scheduler
                    .run(self.layout(), points, answers, true, |points, answers| {
                        $crate::locate::relocate_split(
                            points,
                            answers,
                            |p, a| self.relocate_chunk(p, a),
                            |p, o| self.locate_chunk(p, o),
                        );
                    });
            }
        }
    };
}
pub(crate) use lattice_search_locator;

lattice_search_locator!(LatticeLocator<'_>);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Lattice;
    use crate::settings::CandidateOrder;

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
        let least = if locator.body().active_count() < 100 {
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

    /// Cells of the sub-box [2, 7) × [1, 5) × [1, 5) of the scenes' 9 × 7 × 6 lattice, every fifth
    /// removed: a slot table whose nodes fill their box (the locator copies it), and points all
    /// over the lattice, so that lanes of one batch fall in and out of that box.
    fn in_sub_box(c: usize) -> bool {
        let (i, j, k) = (c % 9, c / 9 % 7, c / 63);
        (2..7).contains(&i) && (1..5).contains(&j) && (1..5).contains(&k) && c % 5 != 2
    }

    /// The scenes of the lane tests: every cell; every fifth removed (a slot table); a sub-box
    /// (a slot table over part of the lattice); every 40th kept (hash maps); each with both
    /// candidate orders where they differ.
    fn lane_scenes() -> Vec<(Body, Vec<DVec3>, CandidateOrder)> {
        [
            (0, CandidateOrder::Predicted),
            (5, CandidateOrder::Predicted),
            (5, CandidateOrder::Undeformed),
            (1, CandidateOrder::Predicted),
            (1, CandidateOrder::Undeformed),
            (40, CandidateOrder::Predicted),
        ]
        .into_iter()
        .map(|(cells, order)| {
            let (body, points) = scene_keeping(|c| match cells {
                0 => true,
                1 => in_sub_box(c),
                5 => c % 5 != 2,
                _ => c % cells == 2,
            });
            (body, points, order)
        })
        .collect()
    }

    #[test]
    fn the_boxed_copy_is_kept_where_it_pays_and_holds_the_displacements() {
        let (body, _) = scene_keeping(in_sub_box);
        let locator = LatticeLocator::new(&body, Settings::default()).unwrap();
        let boxed = locator
            .boxed
            .as_ref()
            .expect("a slot table filling its box");
        assert_eq!(boxed.dims, [6, 5, 5]);
        assert_eq!(boxed.low, DVec3::new(2.0, 1.0, 1.0));
        // Every node of the box, read there and through the body.
        let [dx, dy, _] = boxed.dims.map(|n| n as usize);
        for (at, u) in boxed.u.iter().enumerate() {
            let ijk = [at % dx + 2, at / dx % dy + 1, at / (dx * dy) + 1].map(|v| v as u32);
            let node = body.lattice().node_index(ijk);
            assert_eq!(
                *u,
                body.displacement(node).unwrap_or(DVec3::ZERO),
                "node {ijk:?}"
            );
        }
        // Not with f32, not on a full block (no table), not on hash maps.
        let f32 = LatticeLocator::new(&body, Settings::f32()).unwrap();
        assert!(f32.boxed.is_none());
        for keep in [|_: usize| true, |c: usize| c % 40 == 2] {
            let (body, _) = scene_keeping(keep);
            assert!(
                LatticeLocator::new(&body, Settings::default())
                    .unwrap()
                    .boxed
                    .is_none()
            );
        }
    }

    /// Runs `entry` on every lane scene with f64 and f32 locators (`f64_too` false: f32 only) and
    /// checks its answers bitwise against the scalar search. Every answer starts as a sentinel
    /// (`NonFinite`, which no point here is), so an entry that skipped a point fails.
    fn check_lanes(f64_too: bool, entry: impl Fn(&LatticeLocator<'_>, &[DVec3], &mut [Answer])) {
        for (body, points, order) in lane_scenes() {
            let precisions: &[Settings] = if f64_too {
                &[Settings::default(), Settings::f32()]
            } else {
                &[Settings::f32()]
            };
            for &base in precisions {
                let locator = LatticeLocator::new(&body, Settings { order, ..base }).unwrap();
                let mut out = vec![Err(PointError::NonFinite); points.len()];
                entry(&locator, &points, &mut out);
                check(&locator, &points, &out);
            }
        }
    }

    /// Runs `entry`, a warm lane path, on every lane scene with f64 and f32 locators (`f64_too`
    /// false: f32 only) and checks its answers bitwise against the scalar [`Locator::relocate`].
    /// The hints are the answers at points moved by up to a tenth of a cell (some hinted cells
    /// hold their point, some do not), with misses, refusals and ids out of range among them.
    fn check_warm_lanes(
        f64_too: bool,
        entry: impl Fn(&LatticeLocator<'_>, &[DVec3], &mut [Answer]),
    ) {
        for (body, points, order) in lane_scenes() {
            let precisions: &[Settings] = if f64_too {
                &[Settings::default(), Settings::f32()]
            } else {
                &[Settings::f32()]
            };
            let h = body.lattice().h();
            for &base in precisions {
                let locator = LatticeLocator::new(&body, Settings { order, ..base }).unwrap();
                let hints: Vec<Answer> = points
                    .iter()
                    .enumerate()
                    .map(|(i, &x)| match i % 11 {
                        0 => Err(PointError::NonFinite),
                        1 => locator.locate(x).map(|hit| {
                            hit.map(|hit| Hit {
                                cell: CellId(u32::MAX - 1),
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
                // Hinted cells that hold their point: a few on the sparse body and the sub-box,
                // hundreds elsewhere.
                let least = if body.active_count() < 100 { 5 } else { 300 };
                assert!(one > least, "{one}");
            }
        }
    }

    /// The warm start's portable lanes (glam's `Vec4`, 4 × f32) and its dispatch: answers bitwise
    /// those of the scalar `relocate`.
    #[test]
    fn warm_portable_lanes_answer_bitwise_as_the_scalar_relocate() {
        check_warm_lanes(false, |locator, points, out| {
            locator.relocate_chunk_with::<glam::Vec4>(points, out)
        });
        check_warm_lanes(true, |locator, points, out| {
            locator.relocate_chunk(points, out)
        });
    }

    /// The warm start's AVX2 entry point, forced. Ignored where the build machine has no AVX2.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(not(cgcontact_host_avx2), ignore = "this CPU has no AVX2")]
    fn warm_avx2_lanes_answer_bitwise_as_the_scalar_relocate() {
        assert!(
            std::is_x86_feature_detected!("avx2"),
            "built where AVX2 was detected, run where it is not"
        );
        check_warm_lanes(true, |locator, points, out| {
            // SAFETY: AVX2 was detected just above.
            #[allow(unsafe_code)]
            unsafe {
                locator.relocate_chunk_avx2(points, out)
            }
        });
    }

    /// The warm start's AVX-512VL entry point, forced. Ignored where the build machine lacks
    /// AVX-512F/VL.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(
        not(cgcontact_host_avx512),
        ignore = "this CPU has no AVX-512F and AVX-512VL"
    )]
    fn warm_avx512_lanes_answer_bitwise_as_the_scalar_relocate() {
        use std::is_x86_feature_detected as has;
        assert!(
            has!("avx2") && has!("avx512f") && has!("avx512vl"),
            "built where AVX-512VL was detected, run where it is not"
        );
        check_warm_lanes(true, |locator, points, out| {
            // SAFETY: AVX2, AVX-512F and AVX-512VL were detected just above.
            #[allow(unsafe_code)]
            unsafe {
                locator.relocate_chunk_avx512(points, out)
            }
        });
    }

    /// The portable lanes (glam's `Vec4`, 4 × f32), on every target: answers bitwise those of the
    /// scalar search.
    #[test]
    fn portable_lanes_answer_bitwise_as_the_scalar_search() {
        check_lanes(false, |locator, points, out| {
            locator.locate_chunk_with::<glam::Vec4, false>(points, out)
        });
    }

    /// The AVX2 entry point, forced (the dispatch picks one per machine). Ignored where the build
    /// machine has no AVX2 (build.rs).
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(not(cgcontact_host_avx2), ignore = "this CPU has no AVX2")]
    fn avx2_lanes_answer_bitwise_as_the_scalar_search() {
        assert!(
            std::is_x86_feature_detected!("avx2"),
            "built where AVX2 was detected, run where it is not"
        );
        // The entry the dispatch takes (the box copy's where the locator has one), then the
        // slot table's on every body.
        check_lanes(true, |locator, points, out| {
            // SAFETY: AVX2 was detected just above.
            #[allow(unsafe_code)]
            unsafe {
                if locator.boxed.is_some() {
                    locator.locate_chunk_avx2_boxed(points, out)
                } else {
                    locator.locate_chunk_avx2(points, out)
                }
            }
        });
        check_lanes(true, |locator, points, out| {
            // SAFETY: AVX2 was detected just above.
            #[allow(unsafe_code)]
            unsafe {
                locator.locate_chunk_avx2(points, out)
            }
        });
    }

    /// The AVX-512VL entry point, forced. Ignored where the build machine lacks AVX-512F/VL.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[cfg_attr(
        not(cgcontact_host_avx512),
        ignore = "this CPU has no AVX-512F and AVX-512VL"
    )]
    fn avx512_lanes_answer_bitwise_as_the_scalar_search() {
        use std::is_x86_feature_detected as has;
        assert!(
            has!("avx2") && has!("avx512f") && has!("avx512vl"),
            "built where AVX-512VL was detected, run where it is not"
        );
        // The entry the dispatch takes (the box copy's where the locator has one), then the
        // slot table's on every body.
        check_lanes(true, |locator, points, out| {
            // SAFETY: AVX2, AVX-512F and AVX-512VL were detected just above.
            #[allow(unsafe_code)]
            unsafe {
                if locator.boxed.is_some() {
                    locator.locate_chunk_avx512_boxed(points, out)
                } else {
                    locator.locate_chunk_avx512(points, out)
                }
            }
        });
        check_lanes(true, |locator, points, out| {
            // SAFETY: AVX2, AVX-512F and AVX-512VL were detected just above.
            #[allow(unsafe_code)]
            unsafe {
                locator.locate_chunk_avx512(points, out)
            }
        });
    }
}
