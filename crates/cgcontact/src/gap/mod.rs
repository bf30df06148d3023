//! What a contact solver needs besides the cell: the signed gap of a point to the other body's
//! deformed boundary surface, the closest point there and the outward normal.
//!
//! The **boundary surface** is every face of an active cell (a leaf, on adaptive bodies) whose
//! other side no active cell covers; each deforms into a bilinear quad. The **gap** of x is the
//! distance to the closest point c of that surface, negative when a cell holds x (the locator's
//! answer, with its inside tolerance). The **normal** n is the face's unit outward normal when c
//! lies inside a face, and (x − c)/gap when c is on an edge or a corner; either way
//! x = c + gap·n. Within the locator's allowance of the surface (its inside tolerance as a
//! distance, and the rounding it carries) the locator's sign may be against x − c: the normal is
//! then the face's at c, and x = c + gap·n holds to 2|gap|.
//!
//! The search is exact and complete within the search distance D without any global structure:
//! a face point c = X + u(X) within D of x has X in [x − D − u_high, x + D − u_low] (u's range
//! per axis), so only the faces of the cells meeting that box can be closest. A point farther than
//! D from the whole lattice's shifted box is answered at once. Otherwise the cell at the point's
//! undeformed position (or the previous answer's, on a warm start) is measured first; its best
//! distance then shrinks the box, whose cells are each dropped by lower bounds in turn (the cell's
//! box shifted by the displacement range, its faces', their deformed corners' boxes) before the
//! coverage of a face is settled and the exact closest point of its quad is found (`quad.rs`).
//! The box is walked cell by cell of the lattice, active or not, unless it holds more than 8
//! lattice cells per active cell (a sparse body on a large lattice, a long distance): then the
//! body's active cells in the box are visited, in the same order. Walking the box, a body of 2
//! cells at opposite corners of a 1290³ lattice took 13 s per point at a distance of 1e4 cells
//! (`gaps_on_a_sparse_body_with_cells_far_apart_match_the_oracle` did not end within a minute;
//! 0.05 s now).
//!
//! The whole body's range makes that box as large as the largest displacement: one node moved
//! 100 h made every point walk up to 200 cells per axis (135× the smooth body's time on a 60³
//! lattice). So where the displacements spread over more than a few cells the finder keeps the
//! lattice locator's octree of block ranges (`reach.rs`: per block of 2³ base cells, then 2³ of
//! those, the range of its cells' corner displacements; over base cells on adaptive bodies), and
//! a box of more than `RING_CELLS` (125) base cells is walked through it: a block is entered only
//! when its own box shifted by its own range is within the best distance (a face point of any of
//! its cells lies in it), and each cell is pruned by its block's range. The base cells found are
//! then visited in the walk's order, so the answers are bitwise the walk's (the same faces
//! measured in the same order against the same bounds: a cell left out held no face as near).
//!
//! | file | what |
//! |---|---|
//! | `mod.rs` | [`GapFinder`], [`Contact`], [`Face`]: the search, the sign and the normal |
//! | `surface.rs` | [`Surface`]: what the search asks of a body (uniform or adaptive) |
//! | `quad.rs` | the closest point of one bilinear quad: edges, Newton, branch and bound |

mod quad;
mod surface;

use glam::{DVec2, DVec3};
use smallvec::SmallVec;

use crate::lattice::CellId;
use crate::reach::{Pyramid, RING_CELLS, Range};
use crate::schedule::Scheduler;
use crate::{Error, Frame, InsideTolerance, PointError};
use quad::{Locus, Patch, box_distance2};
use surface::Cell;
pub(crate) use surface::Coverage;
pub use surface::Surface;
use surface::sealed::Blocks;

/// The corners of each local face of a hexahedron (VTK order), counter-clockwise seen from
/// outside: face `f` lies at local coordinate `f / 2` (ξ, η, ζ) = −1 when `f` is even, +1 when
/// odd. A face's coordinates (s, t) ∈ [−1, 1]² put its corners at (−1, −1), (1, −1), (1, 1) and
/// (−1, 1), in this order.
pub const FACE_CORNERS: [[usize; 4]; 6] = [
    [0, 4, 7, 3],
    [1, 2, 6, 5],
    [0, 1, 5, 4],
    [3, 7, 6, 2],
    [0, 3, 2, 1],
    [4, 5, 6, 7],
];

/// The lattice axes of each local face's coordinates s and t (s = −1 at the cell's lower side
/// along the first, t along the second).
pub(crate) const FACE_ST_AXES: [[usize; 2]; 6] = [[2, 1], [1, 2], [0, 2], [2, 0], [1, 0], [0, 1]];

/// A face of the boundary surface: a cell and its local face (see [`FACE_CORNERS`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Face {
    /// The cell (the leaf, on an adaptive body).
    pub cell: CellId,
    /// Its local face, 0..6.
    pub local: u8,
}

/// The contact quantities of a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Signed distance to the boundary surface: positive apart, negative inside the body.
    pub gap: f64,
    /// The closest point of the deformed boundary surface.
    pub point: DVec3,
    /// Unit outward normal: x = point + gap · normal (to 2|gap| where |gap| is within the
    /// locator's allowance and its sign is against x − point: see the module).
    pub normal: DVec3,
    /// The face holding the closest point (on an edge or corner shared by several, one of them).
    pub face: Face,
    /// The closest point's coordinates on that face, in [−1, 1]².
    pub st: DVec2,
    /// Whether the closest point lies inside the face (false: on one of its edges or corners).
    pub interior: bool,
}

/// A point's answer: its contact quantities, `None` when the surface is farther than the search
/// distance, or why the point was refused.
pub type GapAnswer = Result<Option<Contact>, PointError>;

/// Signed gaps, closest points and normals to the boundary surface of the body a locator
/// searches, within a search distance. Built in one pass over the displacements.
#[derive(Clone, Debug)]
pub struct GapFinder<'l, L> {
    surface: &'l L,
    distance: f64,
    u_range: Range,
    /// The displacement range of each block of base cells (the lattice locator's octree), where
    /// the whole body's range spreads over more than a few cells: a search box of more cells is
    /// then walked through the blocks whose own shifted box is near enough.
    blocks: Option<Blocks<'l>>,
    /// The locator's inside tolerance: how far outside a cell the locator's sign may reach.
    inside: InsideTolerance,
    /// The batched queries' schedule (the locator's) and its sort's buffers.
    scheduler: Scheduler,
}

#[cfg(test)]
thread_local! {
    /// The tests' work counter, per thread: the cells the search visited (each handed to its
    /// lower bound) and the faces or squares it measured exactly.
    static WORK: std::cell::Cell<[u64; 2]> = const { std::cell::Cell::new([0; 2]) };
}

#[cfg(test)]
fn count(what: usize) {
    WORK.with(|w| {
        let mut v = w.get();
        v[what] += 1;
        w.set(v);
    });
}

/// The best face so far.
#[derive(Clone, Copy)]
struct Best {
    d2: f64,
    face: Face,
    st: DVec2,
    /// The closest point in the cell's frame, and that frame's origin.
    local: DVec3,
    origin: DVec3,
    locus: Locus,
    normal: DVec3,
    /// Distances below this are left to the locator's sign, at least (a millionth of the cell's
    /// size).
    band: f64,
    /// Half the cell's thickness across the face, scaled to a base cell: the distance a unit of
    /// ξ is along the face's normal, what the locator's allowance in ξ is a share of.
    half_thickness: f64,
}

/// The cell a search measured to cap its bound ([`GapFinder::probe`]), and its nearest face
/// within the bound of then (`u32::MAX`: none measured).
struct Probed {
    cell: u32,
    found: Option<Best>,
    /// Whether the search's walk came to the cell.
    visited: bool,
}

impl Default for Probed {
    fn default() -> Self {
        Self {
            cell: u32::MAX,
            found: None,
            visited: false,
        }
    }
}

/// Every local face, as a bit set.
const ALL_FACES: u8 = 0b11_1111;

/// Relative slack of the pruning bounds: a face never is dropped by a rounding of its bound.
const SLACK: f64 = 1e-12;

/// The best squared distance so far, and the bound that prunes a box: that distance grown by the
/// rounding of the boxes' bounds and of x's offset from a cell (lengths of the coordinates'
/// magnitude), then by [`SLACK`]. Relative slack alone fails near the surface: a point on an
/// edge is at 1e-17 of two faces by rounding, and a box within 1e-16 of it, all rounding, was
/// pruned by a bound of 1e-34, so the cold search kept one face and the warm one, measuring the
/// other first, the other.
///
/// A cap may lower the pruning bound below the best distance's, not the distance a face must
/// beat: the squared distance of a face measured only to bound the search (`cap`). Only boxes
/// farther than that face are pruned, so every face at least as near is still measured, in the
/// same order, and the answer (ties included) is the one without the cap.
#[derive(Clone, Copy, Debug)]
struct Bound {
    d2: f64,
    prune2: f64,
    rounding: f64,
    /// The capping face's squared distance, and its pruning bound (infinite without one).
    cap_d2: f64,
    cap2: f64,
}

impl Bound {
    fn new(d2: f64, rounding: f64) -> Self {
        let mut bound = Self {
            d2,
            prune2: 0.0,
            rounding,
            cap_d2: f64::INFINITY,
            cap2: f64::INFINITY,
        };
        bound.set(d2);
        bound
    }

    /// A new best squared distance.
    #[inline]
    fn set(&mut self, d2: f64) {
        self.d2 = d2;
        self.prune2 = self.grown(d2).min(self.cap2);
    }

    /// A face at squared distance `d2` exists, measured outside the search's order: nothing
    /// farther can be the answer.
    fn cap(&mut self, d2: f64) {
        self.cap_d2 = self.cap_d2.min(d2);
        self.cap2 = self.grown(self.cap_d2);
        self.prune2 = self.prune2.min(self.cap2);
    }

    /// The squared distance within which the answer lies.
    fn reach2(&self) -> f64 {
        self.d2.min(self.cap_d2)
    }

    /// `d2` grown by the rounding and the slack.
    #[inline]
    fn grown(&self, d2: f64) -> f64 {
        let d = d2.sqrt() + self.rounding;
        d * d * (1.0 + SLACK)
    }

    /// Whether a box at squared distance `d2` (as `box_distance2` computes it) holds nothing
    /// nearer than the best so far.
    #[inline]
    fn prunes(&self, d2: f64) -> bool {
        d2 > self.prune2
    }
}

impl<'l, L: Surface> GapFinder<'l, L> {
    /// A finder over the body `surface` searches, for points within `distance` of its boundary
    /// surface. Errors when `distance` is negative, not finite or beyond
    /// [`crate::MAX_DISPLACEMENT`] (its square, and those of the distances it admits, would
    /// overflow: a point 1e200 away was answered an infinite gap).
    pub fn new(surface: &'l L, distance: f64) -> Result<Self, Error> {
        if !(0.0..=crate::MAX_DISPLACEMENT).contains(&distance) {
            return Err(Error::InvalidSettings(format!(
                "the gap search distance must be at least 0 and at most {:e}, got {distance:e}",
                crate::MAX_DISPLACEMENT
            )));
        }
        surface.prepare();
        let u_range = surface
            .displacements()
            .iter()
            .fold(Range::EMPTY, |r, &u| Range {
                low: r.low.min(u),
                high: r.high.max(u),
            });
        let u_range = if u_range.low.cmple(u_range.high).all() {
            u_range
        } else {
            Range {
                low: DVec3::ZERO,
                high: DVec3::ZERO,
            }
        };
        // The locator's own allowance (the kernel rounds u − T, |u| with f64; an adaptive
        // body's seam enters as its locator takes it, through the rounding length).
        let settings = surface.locator_settings();
        let finest = surface.finest_spacing();
        let frame = Frame::new(settings.precision, u_range.low, u_range.high, finest);
        let inside = InsideTolerance::with_spacing(
            settings,
            surface.lattice().origin(),
            finest,
            frame.reach(),
        )
        .with_added_length(surface.seam());
        Ok(Self {
            surface,
            distance,
            u_range,
            blocks: surface.block_ranges(u_range.high - u_range.low),
            inside,
            scheduler: Scheduler::new(surface.schedule().0),
        })
    }

    /// The search distance.
    #[must_use]
    pub fn distance(&self) -> f64 {
        self.distance
    }

    /// The contact quantities of `x`.
    pub fn gap(&self, x: DVec3) -> GapAnswer {
        self.search(x, None)
    }

    /// [`GapFinder::gap`] with the previous answer of the same point as a hint: its face is
    /// measured first, so that the rest of the search is cut to the faces that could be nearer.
    /// The answer is the cold one (the same minimum; on a tie, the hinted face).
    pub fn regap(&self, x: DVec3, previous: &GapAnswer) -> GapAnswer {
        let hint = match previous {
            Ok(Some(contact)) => Some(contact.face),
            _ => None,
        };
        self.search(x, hint)
    }

    /// [`GapFinder::gap`] for every point, in parallel on the current rayon pool, answers in
    /// input order, written into `out` (resized).
    pub fn gap_all_into(&self, points: &[DVec3], out: &mut Vec<GapAnswer>) {
        if out.len() != points.len() {
            out.clear();
            out.resize(points.len(), Ok(None));
        }
        self.batch(points, out, false);
    }

    /// Whether the batched queries would sort `points` by lattice cell, as
    /// [`crate::Locator::sorts_batch`] says for the locators: a caller should then pass such a
    /// batch whole rather than in small pieces.
    pub fn sorts_batch(&self, points: &[DVec3]) -> bool {
        let (_, layout) = self.surface.schedule();
        self.scheduler.would_sort(layout, points)
    }

    /// [`GapFinder::gap_all_into`]'s answers without putting them back in input order: `out[k]`
    /// is the answer to `points[order[k]]`, `order` a permutation of the indices (both resized),
    /// in the order the schedule answered them (sorted by lattice cell on large bodies). For
    /// callers that can use the answers in any order: it saves a store to a random place per
    /// point (see [`crate::Locator::locate_all_unordered_into`]).
    pub fn gap_all_unordered_into(
        &self,
        points: &[DVec3],
        order: &mut Vec<usize>,
        out: &mut Vec<GapAnswer>,
    ) {
        let (_, layout) = self.surface.schedule();
        self.scheduler
            .run_unordered(layout, points, order, out, Ok(None), |points, out| {
                for (o, &x) in out.iter_mut().zip(points) {
                    *o = self.search(x, None);
                }
            });
    }

    /// [`GapFinder::regap`] for every point, in parallel: `answers` holds the previous answers
    /// (no hints where its length differs from `points`) and is overwritten with the new ones.
    pub fn regap_all(&self, points: &[DVec3], answers: &mut Vec<GapAnswer>) {
        if answers.len() != points.len() {
            self.gap_all_into(points, answers);
            return;
        }
        self.batch(points, answers, true);
    }

    /// The batched queries, scheduled as the locator's settings say; with `warm`, each answer's
    /// previous value is its hint.
    fn batch(&self, points: &[DVec3], out: &mut [GapAnswer], warm: bool) {
        let (_, layout) = self.surface.schedule();
        self.scheduler
            .run(layout, points, out, warm, |points, out| {
                for (o, &x) in out.iter_mut().zip(points) {
                    let hint = match o {
                        Ok(Some(contact)) if warm => Some(contact.face),
                        _ => None,
                    };
                    *o = self.search(x, hint);
                }
            });
    }

    /// The search of one point (see the module), `hint` the previous answer's face.
    fn search(&self, x: DVec3, hint: Option<Face>) -> GapAnswer {
        self.search_with(x, hint, true)
    }

    /// [`Self::search`], with or without the probe that caps the bound ([`Self::probe`]).
    fn search_with(&self, x: DVec3, hint: Option<Face>, probe: bool) -> GapAnswer {
        if !x.is_finite() {
            return Err(PointError::NonFinite);
        }
        let d = self.distance;
        let mut best: Option<Best> = None;
        let lattice = self.surface.lattice();
        let inv_h = lattice.h().recip();
        let range = self.u_range;
        // The magnitude of every coordinate a box test rounds: x, a cell's origin and corners,
        // a displacement.
        let magnitude = x.abs().max_element()
            + lattice.origin().abs().max_element()
            + (lattice.upper() - lattice.origin()).max_element()
            + range.low.abs().max(range.high.abs()).max_element();
        let mut bound = Bound::new(d * d, 8.0 * f64::EPSILON * magnitude);
        // Farther than D from the lattice's box shifted by the displacement range: no face near.
        let reach = box_distance2(
            x - lattice.origin(),
            range.low,
            lattice.upper() - lattice.origin() + range.high,
        );
        if bound.prunes(reach) {
            return Ok(None);
        }
        // First the hinted face's cell (the previous answer's), or else the cell at x's
        // undeformed position (x less the middle of the displacement range, clamped into the
        // lattice): its faces usually set a bound that shrinks the box to a cell or two. The
        // hinted face is measured first, so that on a tie it stays the answer.
        let hinted = hint.and_then(|face| Some((self.surface.cell(face.cell.0)?, face.local)));
        let mut probed = Probed::default();
        let first = match hinted {
            Some((cell, local)) if local < 6 => {
                self.offer_cell(x, cell, 1 << local, &range, &mut best, &mut bound);
                let others = ALL_FACES & !(1 << local);
                self.offer_cell(x, cell, others, &range, &mut best, &mut bound);
                Some(cell)
            }
            _ => {
                let t = (x - lattice.origin() - 0.5 * (range.low + range.high)) * inv_h;
                let first = self.surface.cell_near(t);
                if let Some(cell) = first {
                    self.offer_cell(x, cell, ALL_FACES, &range, &mut best, &mut bound);
                }
                if let Some(Blocks(blocks)) = self.blocks.as_ref().filter(|_| probe) {
                    probed = self.probe(x, blocks, first.map(|c| c.id), &mut bound);
                }
                first
            }
        };
        let first = first.map_or(u32::MAX, |cell| cell.id);
        // Then every cell of the lattice bound's box for the best distance so far, each pruned by
        // its own bound with the best distance when its turn comes.
        // The slack: 1e-9 of a cell, and the rounding of the box's bounds (of x's coordinates
        // and the distance), which on a fine spacing far out is larger: an ulp of 3000 is 4.5e-13,
        // 1e-9 of a spacing of 1e-4 only 1e-13, and a face at D to within that rounding was left
        // out of the box, though the warm search, measuring it directly, found it within D. The
        // faces are measured in their cells' frames, whose origins round at the lattice origin's
        // magnitude: at 1e8 a face 2e-9 away in its frame lay 6e-9 off in lattice coordinates.
        let reach = bound.reach2().sqrt();
        let rounding = 8.0
            * f64::EPSILON
            * ((x - lattice.origin()).abs()
                + lattice.origin().abs()
                + range.low.abs().max(range.high.abs())
                + reach);
        let reach = DVec3::splat(reach) + lattice.h() * 1e-9 + rounding;
        let low = (x - lattice.origin() - range.high - reach) * inv_h;
        let high = (x - lattice.origin() - range.low + reach) * inv_h;
        let blocks = self.blocks.as_ref().and_then(|Blocks(blocks)| {
            let n = lattice.cells();
            let mut cells = [(0, 0); 3];
            for a in 0..3 {
                cells[a] = surface::sealed::axis_range(low[a], high[a], n[a])?;
            }
            let count: u64 = cells.iter().map(|&(l, h)| u64::from(h - l + 1)).product();
            (count > RING_CELLS).then_some((blocks, cells))
        });
        if let Some((blocks, cells)) = blocks {
            // A box of many cells on a body whose displacements spread (a far-moved node):
            // only the base cells of the blocks whose own shifted box is near enough, each cell
            // then pruned by its block's range. Visited in the order the walk below visits them
            // (ascending id: the first face found at the least distance stays the answer).
            let mut bases: SmallVec<[(u32, [u32; 3], Range); 32]> = SmallVec::new();
            let h = lattice.h();
            blocks.descend(
                cells.map(|c| c.0),
                cells.map(|c| c.1),
                |first, edge, range| {
                    let origin = lattice.node_position(first);
                    let size = h * f64::from(edge);
                    !bound.prunes(box_distance2(x - origin, range.low, size + range.high))
                },
                |from, to, range| {
                    for k in from[2]..=to[2] {
                        for j in from[1]..=to[1] {
                            for i in from[0]..=to[0] {
                                let ijk = [i, j, k];
                                bases.push((lattice.cell_id(ijk).0, ijk, *range));
                            }
                        }
                    }
                },
            );
            bases.sort_unstable_by_key(|b| b.0);
            for (_, base, range) in bases {
                self.surface.cells_of_base(base, low, high, |cell| {
                    self.visit(x, cell, first, &mut probed, &range, &mut best, &mut bound);
                });
            }
        } else {
            self.surface.cells_in_box(low, high, |cell| {
                self.visit(x, cell, first, &mut probed, &range, &mut best, &mut bound);
            });
        }
        if probed.found.is_some() && !probed.visited {
            // The probed cell holds a face within the bound it capped, so the walk's box holds
            // that cell: never here. Should rounding prove that wrong, the search again without
            // the cap, rather than an answer that could have missed the nearest face.
            debug_assert!(false, "the probed cell of {x} lay outside the search's box");
            return self.search_with(x, hint, false);
        }
        let Some(b) = best else {
            return Ok(None);
        };
        let dist = b.d2.sqrt();
        // x − c, in the closest face's cell frame.
        let away = (x - b.origin) - b.local;
        // How far outside a cell the locator may still hold x: its allowance in ξ (t, times the
        // distance a unit of ξ is across the face) and the rounding length L it carries through
        // J⁻¹ (at most |L| off a face of a cell that is not degenerate), taken four times over
        // (the kernel's own noise). With f32 t alone is a millionth of the cell, and with f64
        // far from the origin L is: a fixed millionth of the cell's smallest edge left points
        // the locator holds with a positive gap.
        let allowance =
            4.0 * (self.inside.xi() * b.half_thickness + self.inside.length(x).element_sum());
        // The sign: a point inside the body reaches its closest surface point c from inside (the
        // segment to c crosses no surface), so where c is inside a face, x − c, normal to it,
        // points against its outward normal. Near the surface (where the locator's inside
        // tolerance decides), and at edges and corners, the locator says.
        let side = away.dot(b.normal);
        let band = b.band.max(allowance);
        let inside = if b.locus == Locus::Interior && dist > band && side.abs() >= 0.5 * dist {
            side < 0.0
        } else {
            self.surface.locate(x)?.is_some()
        };
        let gap = if dist == 0.0 {
            0.0
        } else if inside {
            -dist
        } else {
            dist
        };
        let normal = match b.locus {
            Locus::Boundary if dist > 0.0 => {
                // On an edge or a corner, x − c is the normal's direction and the gap's sign its
                // side. Within the allowance the locator's sign may be against x − c, which then
                // pointed into the body, against the face's outward normal; and x − c may be
                // only the rounding of x and c. The face's normal is a normal of the surface at c
                // there (x = c + gap·n then holds to 2|gap|, as inside a face whose sign the
                // locator turned).
                let n = away / gap;
                let noise = 16.0
                    * f64::EPSILON
                    * ((x - b.origin).abs().max_element() + b.local.abs().max_element());
                let against = dist <= allowance && n.dot(b.normal) <= 0.0;
                if (against || dist <= noise) && b.normal != DVec3::ZERO {
                    b.normal
                } else {
                    n
                }
            }
            _ => b.normal,
        };
        Ok(Some(Contact {
            gap,
            point: b.origin + b.local,
            // (+ 0 turns a −0 component into 0: files show "0", not "-0".)
            normal: normal + DVec3::ZERO,
            face: b.face,
            st: b.st,
            interior: b.locus == Locus::Interior,
        }))
    }

    /// Where the whole body's displacements spread (a far-moved node), the first cell, at x less
    /// the middle of their range, can be far from x's surface, and its bound then D: on the
    /// lattice locator's 12³ body with one node moved 100 h, 2.6× the cells a smooth body's
    /// search visits. So the cell at x less the middle of the range of x's own block is measured
    /// too, outside the search's order, and caps the pruning bound (`Bound::cap`): the answer
    /// is the one without it, ties included.
    ///
    /// Its nearest face is kept for the search's turn at the cell ([`Probed`]), so that no face
    /// is measured twice.
    fn probe(&self, x: DVec3, blocks: &Pyramid, first: Option<u32>, bound: &mut Bound) -> Probed {
        let lattice = self.surface.lattice();
        let inv_h = lattice.h().recip();
        let local = blocks.range_at(lattice.clamped_cell((x - lattice.origin()) * inv_h));
        if !local.low.cmple(local.high).all() {
            return Probed::default();
        }
        let t = (x - lattice.origin() - 0.5 * (local.low + local.high)) * inv_h;
        let Some(cell) = self.surface.cell_near(t).filter(|c| Some(c.id) != first) else {
            return Probed::default();
        };
        let (mut found, mut scratch) = (None, Bound::new(bound.d2, bound.rounding));
        // The whole range bounds every cell's corner displacements.
        self.offer_cell(x, cell, ALL_FACES, &self.u_range, &mut found, &mut scratch);
        if let Some(found) = &found {
            bound.cap(found.d2);
        }
        Probed {
            cell: cell.id,
            found,
            visited: false,
        }
    }

    /// A cell of the search box (other than `first`, measured already; the probed cell's face,
    /// measured then, is taken as it would be measured now), its corners' displacements in
    /// `range`: measured unless its box shifted by `range` is farther than the best so far.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn visit(
        &self,
        x: DVec3,
        cell: Cell,
        first: u32,
        probed: &mut Probed,
        range: &Range,
        best: &mut Option<Best>,
        bound: &mut Bound,
    ) {
        #[cfg(test)]
        count(0);
        if cell.id == first || (L::OPEN_FACES_STORED && self.surface.open_faces(cell) == 0) {
            return;
        }
        if cell.id == probed.cell {
            probed.visited = true;
            // Measured already, from a bound no nearer than this one: its nearest face (the
            // first of its faces at that distance) is what `offer_cell` would find, and is kept
            // as `offer` keeps a face.
            if let Some(found) = probed.found
                && found.d2 <= bound.d2
                && (best.is_none() || found.d2 < bound.d2)
            {
                bound.set(found.d2);
                *best = Some(found);
            }
            return;
        }
        let origin = self.surface.cell_origin(cell);
        let size = self.surface.size(cell);
        if !bound.prunes(box_distance2(x - origin, range.low, size + range.high)) {
            self.offer_cell(x, cell, ALL_FACES, range, best, bound);
        }
    }

    /// Measures the faces of `cell` in the bit set `faces` (bit f: local face f) that can be
    /// nearer than the best so far and are on the surface, its corners' displacements in
    /// `range`.
    #[inline]
    fn offer_cell(
        &self,
        x: DVec3,
        cell: Cell,
        faces: u8,
        range: &Range,
        best: &mut Option<Best>,
        bound: &mut Bound,
    ) {
        let faces = faces & self.surface.open_faces(cell);
        if faces == 0 {
            return;
        }
        let origin = self.surface.cell_origin(cell);
        let size = self.surface.size(cell);
        let xl = x - origin;
        let mut u: Option<[DVec3; 8]> = None;
        if faces == ALL_FACES {
            // Every face may be open (an adaptive leaf: its coverage is a forest walk): the
            // deformed corners' box of the whole cell first, tight where the displacement range
            // is wide against the cell.
            let corners = u.insert(self.surface.corner_displacements(cell));
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for (c, u) in corners.iter().enumerate() {
                let [a, b, e] = crate::lattice::CORNER_OFFSETS[c];
                let p = DVec3::new(f64::from(a), f64::from(b), f64::from(e)) * size + *u;
                lo = lo.min(p);
                hi = hi.max(p);
            }
            if bound.prunes(box_distance2(xl, lo, hi)) {
                return;
            }
        }
        for (f, face_corners) in FACE_CORNERS.iter().enumerate() {
            if faces & (1 << f) == 0 {
                continue;
            }
            // The undeformed face, shifted by the displacement range.
            let axis = f / 2;
            let (mut lo, mut hi) = (range.low, size + range.high);
            if f % 2 == 0 {
                hi[axis] = range.high[axis];
            } else {
                lo[axis] = size[axis] + range.low[axis];
            }
            if bound.prunes(box_distance2(xl, lo, hi)) {
                continue;
            }
            let u = u.get_or_insert_with(|| self.surface.corner_displacements(cell));
            // The deformed face's corners' box: tight where the displacement range is not (a
            // fine leaf under a wide range). Checked before the coverage, which on an adaptive
            // body walks the forest.
            let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for &c in face_corners {
                let [a, b, e] = crate::lattice::CORNER_OFFSETS[c];
                let p = DVec3::new(f64::from(a), f64::from(b), f64::from(e)) * size + u[c];
                lo = lo.min(p);
                hi = hi.max(p);
            }
            if bound.prunes(box_distance2(xl, lo, hi)) {
                continue;
            }
            let coverage = self.surface.coverage(cell, f);
            if coverage == Coverage::Covered {
                continue;
            }
            self.offer_face(x, cell, u, f, &coverage, best, bound);
        }
    }

    /// Measures the open part of face `f` of `cell` (corner displacements `u`): all of it, or
    /// its open squares.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn offer_face(
        &self,
        x: DVec3,
        cell: Cell,
        u: &[DVec3; 8],
        f: usize,
        coverage: &Coverage,
        best: &mut Option<Best>,
        bound: &mut Bound,
    ) {
        match coverage {
            Coverage::Covered => {}
            Coverage::Open => self.offer(x, cell, u, f, None, best, bound),
            Coverage::Partial(squares) => {
                for &square in squares.iter() {
                    self.offer(x, cell, u, f, Some(square), best, bound);
                }
            }
        }
    }

    /// Measures face `f` of `cell` (corner displacements `u`), or its square `square` ([s0, t0,
    /// s1, t1]) only, and keeps it in `best` when nearer (the first face within the search
    /// distance, then strictly nearer ones).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn offer(
        &self,
        x: DVec3,
        cell: Cell,
        u: &[DVec3; 8],
        f: usize,
        square: Option<[f64; 4]>,
        best: &mut Option<Best>,
        bound: &mut Bound,
    ) {
        let origin = self.surface.cell_origin(cell);
        let size = self.surface.size(cell);
        let xl = x - origin;
        let q = FACE_CORNERS[f].map(|c| {
            let [a, b, e] = crate::lattice::CORNER_OFFSETS[c];
            DVec3::new(f64::from(a), f64::from(b), f64::from(e)) * size + u[c]
        });
        let patch = Patch::new(&q);
        // A square of the face is the bilinear patch over it: its corners, and the map back.
        let (part, st_lo, st_hi) = match square {
            None => (q, DVec2::NEG_ONE, DVec2::ONE),
            Some([s0, t0, s1, t1]) => {
                let (lo, hi) = (DVec2::new(s0, t0), DVec2::new(s1, t1));
                (patch.sub(lo, hi), lo, hi)
            }
        };
        let (mut lo, mut hi) = (part[0], part[0]);
        for &p in &part[1..] {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if bound.prunes(box_distance2(xl, lo, hi)) {
            return;
        }
        #[cfg(test)]
        count(1);
        let Some(mut p) = quad::closest_below(xl, &part, bound.d2) else {
            return;
        };
        if best.is_some() && p.d2 >= bound.d2 {
            return;
        }
        if square.is_some() {
            p.st = st_lo + (p.st + 1.0) * 0.5 * (st_hi - st_lo);
        }
        bound.set(p.d2);
        *best = Some(Best {
            d2: p.d2,
            face: Face {
                cell: CellId(cell.id),
                local: f as u8,
            },
            st: p.st,
            local: p.point,
            origin,
            locus: p.locus,
            normal: quad::unit(patch.normal(p.st)),
            band: 1e-6 * size.min_element(),
            // (A coarser neighbour of an adaptive leaf may hold x: as thick as a base cell.)
            half_thickness: half_thickness(size, u, f / 2)
                * (self.surface.lattice().h() / size).max_element(),
        });
    }
}

/// Half the thickness of a cell (edge lengths `size`, corner displacements `u`, VTK order)
/// across its faces normal to lattice axis `axis`, at its centre: the distance along their
/// normal a unit of ξ_axis moves, det J / |J_i × J_j| (h_axis / 2 undeformed). Where the other
/// two columns are parallel (a degenerate face), the length of J's column along `axis`.
fn half_thickness(size: DVec3, u: &[DVec3; 8], axis: usize) -> f64 {
    // J's columns at the centre: the cell's edges along each axis, averaged, halved.
    let mut j = [DVec3::ZERO; 3];
    for (c, u) in u.iter().enumerate() {
        let o = crate::lattice::CORNER_OFFSETS[c];
        let p = DVec3::new(f64::from(o[0]), f64::from(o[1]), f64::from(o[2])) * size + *u;
        for (a, j) in j.iter_mut().enumerate() {
            *j += if o[a] == 1 { p } else { -p };
        }
    }
    let j = j.map(|v| v * 0.125);
    let across = j[(axis + 1) % 3].cross(j[(axis + 2) % 3]);
    let t = j[axis].dot(across).abs() / across.length();
    if t.is_finite() { t } else { j[axis].length() }
}

#[cfg(test)]
mod tests;
