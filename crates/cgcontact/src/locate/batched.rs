//! `locate_all`'s common path: 4 or 8 points per SIMD lane set through the predicted cell and one
//! Newton inversion there (`crate::lanes` has the lane types, `hex8/lanes.rs` the lane Newton), the scalar search for the rest, and the
//! one place where the instruction set is chosen.

use glam::{DVec3, Vec3A};

use super::{Answer, Boxed, Hit, LatticeLocator, Locator};
use crate::PointError;
use crate::hex8::lanes::Maps;
use crate::lanes::{Lanes, MAX_W, V3, Wide};
use crate::lattice::CellId;
use crate::settings::{CandidateOrder, Precision};

/// The displacements as the batched path reads them: the body's f64 ones, or the locator's f32 copy.
pub(super) trait Nodes: Copy + 'static {
    /// A node without a displacement (a corner of inactive cells only), undisplaced: zero in the
    /// body's frame, −T in the f32 kernel's.
    fn zero(locator: &LatticeLocator<'_>) -> Self;
    /// Whether these displacements are in the shifted frame of the f32 kernel (u − T).
    const SHIFTED: bool;
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self];
    /// The locator's copy over the box of the body's nodes, and its data, if it keeps one.
    fn boxed<'l>(locator: &'l LatticeLocator<'_>) -> Option<(&'l Boxed, &'l [Self])>;
}

impl Nodes for DVec3 {
    const SHIFTED: bool = false;
    #[inline(always)]
    fn zero(_: &LatticeLocator<'_>) -> Self {
        DVec3::ZERO
    }
    #[inline(always)]
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self] {
        locator.body.displacements()
    }
    #[inline(always)]
    fn boxed<'l>(locator: &'l LatticeLocator<'_>) -> Option<(&'l Boxed, &'l [Self])> {
        locator.boxed.as_ref().map(|b| (b, &b.u[..]))
    }
}

impl Nodes for Vec3A {
    const SHIFTED: bool = true;
    #[inline(always)]
    fn zero(locator: &LatticeLocator<'_>) -> Self {
        locator.zero_f32
    }
    #[inline(always)]
    fn of<'l>(locator: &'l LatticeLocator<'_>) -> &'l [Self] {
        &locator.u_f32
    }
    #[inline(always)]
    fn boxed<'l>(_: &'l LatticeLocator<'_>) -> Option<(&'l Boxed, &'l [Self])> {
        None
    }
}

/// The first half of the batched search for W points, up to the displacement maps of the cells
/// holding them (see `LatticeLocator::front`).
struct Front<V: Lanes> {
    /// The points, their lattice coordinates and the cells holding them, in f64 lanes.
    x: V3<V::Wide>,
    t_x: V3<V::Wide>,
    cell_x: V3<V::Wide>,
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
    /// path (`hex8/lanes.rs` over `crate::lanes`); the remainder and every point that leaves the common path go through
    /// the scalar search. The answers are bitwise those of [`Locator::locate`].
    ///
    /// Software-pipelined: the first half of the next W points (their cells and the loads of their
    /// corners) is issued before the second half of the current ones, so that the loads' latency
    /// overlaps the current Newton inversions. The two halves meet in two `Front`s used in turn,
    /// written in place (moving one, about 1 KB, cost a copy and a store-forwarding stall).
    #[inline(always)]
    pub(super) fn locate_chunk_with<V: Lanes, const BOXED: bool>(
        &self,
        points: &[DVec3],
        out: &mut [Answer],
    ) where
        V::Node: Nodes,
    {
        let w = V::W;
        let batches = points.len() / w;
        let mut fronts = [Front::<V>::new(), Front::<V>::new()];
        if batches > 0 {
            self.front::<V, BOXED>(&points[..w], &mut fronts[0]);
        }
        for b in 0..batches {
            if b + 1 < batches {
                self.front::<V, BOXED>(&points[(b + 1) * w..(b + 2) * w], &mut fronts[(b + 1) % 2]);
            }
            let (points, out) = (&points[b * w..(b + 1) * w], &mut out[b * w..(b + 1) * w]);
            self.back::<V, BOXED>(points, &fronts[b % 2], out);
        }
        for (&x, o) in points.iter().zip(out.iter_mut()).skip(batches * w) {
            *o = self.locate(x);
        }
    }

    /// `search` up to the cell holding each of W points (`points` has W entries), one lane each, and
    /// that cell's displacement map: the same f64 operations in f64 lanes (`V::Wide`).
    #[inline(always)]
    fn front<V: Lanes, const BOXED: bool>(&self, points: &[DVec3], front: &mut Front<V>)
    where
        V::Node: Nodes,
    {
        let lattice = self.body.lattice();
        let x = V::Wide::transpose(|l| &points[l]);
        // `admit`: finite and within reach (the lattice's box shifted by the displacement range,
        // widened by the tolerance).
        let (finite, take) = self.admit.lanes(x);
        let t_x = (x - V3::splat(lattice.origin())).mul_each(self.inv_h);
        let cell_x = clamped_cells(lattice.cells(), t_x);
        if take != 0 {
            front.maps = self.maps_of::<V, BOXED>(&cell_x);
        }
        *front = Front {
            x,
            t_x,
            cell_x,
            take,
            finite,
            maps: front.maps,
        };
    }

    /// The displacement maps of each lane's cell (zero where a corner has none).
    #[inline(always)]
    fn maps_of<V: Lanes, const BOXED: bool>(&self, cell: &V3<V::Wide>) -> Maps<V>
    where
        V::Node: Nodes,
    {
        let zero = V::Node::zero(self);
        // Chosen per chunk (`BOXED`), not per batch: a test here cost the full block 8 %.
        if BOXED && let Some((boxed, data)) = V::Node::boxed(self) {
            return self.maps_boxed::<V>(cell, boxed, data);
        }
        let base = lane_indices(cell, self.body.lattice().nodes());
        let nodes = V::Node::of(self);
        Maps::from_nodes(|l, c| self.body.corner_entry(nodes, base[l], c, &zero))
    }

    /// [`Self::maps_of`] with the locator's copy over the box of the body's nodes: the cells are in
    /// the lattice (clamped), those in the box read it, one load a corner, the same values as
    /// through the slot table; the others take the table.
    #[inline(always)]
    fn maps_boxed<V: Lanes>(&self, cell: &V3<V::Wide>, boxed: &Boxed, data: &[V::Node]) -> Maps<V>
    where
        V::Node: Nodes,
    {
        let splat = V3::<V::Wide>::splat;
        let at = *cell - splat(boxed.low);
        let (last, zero) = (splat(boxed.last), V::Wide::splat(0.0));
        let outside = at.x.lt(zero) | at.y.lt(zero) | at.z.lt(zero) | at.x.gt(last.x);
        let outside = V::Wide::bits(outside | at.y.gt(last.y) | at.z.gt(last.z));
        let base = lane_indices(&at, boxed.dims);
        if outside == 0 {
            return Maps::from_nodes(|l, c| &data[base[l] + boxed.corner[c]]);
        }
        let global = lane_indices(cell, self.body.lattice().nodes());
        let (nodes, zero) = (V::Node::of(self), V::Node::zero(self));
        Maps::from_nodes(|l, c| {
            if outside & (1 << l) == 0 {
                &data[base[l] + boxed.corner[c]]
            } else {
                self.body.corner_entry(nodes, global[l], c, &zero)
            }
        })
    }

    /// The rest of the common path for W points: the predicted cell and one Newton inversion there.
    /// A point refused by `admit` gets `admit`'s answer; one leaving the common path, the scalar
    /// search's.
    #[inline(always)]
    fn back<V: Lanes, const BOXED: bool>(
        &self,
        points: &[DVec3],
        front: &Front<V>,
        out: &mut [Answer],
    ) where
        V::Node: Nodes,
    {
        let (finite, take) = (front.finite, front.take);
        let found = if take != 0 {
            self.invert_lanes::<V, BOXED>(front, out)
        } else {
            0
        };
        answer_the_rest(out, points, found, take, finite, |x| self.locate(x));
    }

    /// The predicted cells and one Newton inversion there, for the lanes `front` takes: writes the
    /// answer of every lane it finds and returns their bits.
    #[inline(always)]
    fn invert_lanes<V: Lanes, const BOXED: bool>(&self, front: &Front<V>, out: &mut [Answer]) -> u32
    where
        V::Node: Nodes,
    {
        let lattice = self.body.lattice();
        let splat = V3::<V::Wide>::splat;
        let Front {
            x,
            t_x,
            cell_x,
            mut take,
            mut maps,
            ..
        } = *front;
        // The guess x − ũ, ũ interpolated at x in the cell holding x (`guess`).
        let t_guess = match self.settings.order {
            CandidateOrder::Predicted => {
                let two = V::Wide::splat(2.0);
                let xi = ((t_x - cell_x).scale(two) - splat(DVec3::ONE)).clamp(-1.0, 1.0);
                let mut u = maps.map(V3::narrow(xi)).widen();
                if V::Node::SHIFTED {
                    u = u + splat(self.frame.shift());
                }
                t_x - u.mul_each(self.inv_h)
            }
            CandidateOrder::Undeformed => t_x,
        };
        let first = clamped_cells(lattice.cells(), t_guess);
        let cell = lane_indices(&first, lattice.cells());
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
            maps = self.maps_of::<V, BOXED>(&first);
        }
        maps.add_lattice(lattice.h());
        let x = if V::Node::SHIFTED {
            x - splat(self.frame.shift())
        } else {
            x
        };
        let x_local = x - (splat(lattice.origin()) + first.mul_each(lattice.h()));
        let xi0 = (t_guess - first).scale(V::Wide::splat(2.0)) - splat(DVec3::ONE);
        let inside = V3::<V>::splat(DVec3::ONE + self.newton.inside_tol);
        let inverted = maps.invert(
            V3::narrow(x_local),
            V3::narrow(xi0),
            inside,
            V::mask_from_bits(take),
            &self.newton,
        );
        write_hits(out, inverted, |l| CellId(cell[l] as u32))
    }

    /// [`Locator::locate`] for a chunk of points: batched where that measured faster (with AVX2,
    /// detected at run time: 4 f64 or 8 f32 lanes; without it, 4 f32 lanes of glam's SSE2 `Vec4`),
    /// one point at a time otherwise (f64 without AVX2: SSE2 pairs measured slower than scalar).
    pub(super) fn locate_chunk(&self, points: &[DVec3], out: &mut [Answer]) {
        #[cfg(target_arch = "x86_64")]
        match Isa::get() {
            // SAFETY: `Isa::get` answers `Avx512` only where AVX2, AVX-512F and AVX-512VL were
            // detected on this CPU, `Avx2` only where AVX2 was: the entry points' requirements.
            // The box copy exists only with f64.
            #[allow(unsafe_code)]
            Isa::Avx512 if self.boxed.is_some() => {
                return unsafe { self.locate_chunk_avx512_boxed(points, out) };
            }
            #[allow(unsafe_code)]
            Isa::Avx512 => return unsafe { self.locate_chunk_avx512(points, out) },
            #[allow(unsafe_code)]
            Isa::Avx2 if self.boxed.is_some() => {
                return unsafe { self.locate_chunk_avx2_boxed(points, out) };
            }
            #[allow(unsafe_code)]
            Isa::Avx2 => return unsafe { self.locate_chunk_avx2(points, out) },
            Isa::Portable => {}
        }
        match self.settings.precision {
            Precision::F32 => self.locate_chunk_with::<glam::Vec4, false>(points, out),
            Precision::F64 => {
                for (o, &x) in out.iter_mut().zip(points) {
                    *o = self.locate(x);
                }
            }
        }
    }
}

/// `Lattice::clamped_cell` in f64 lanes: max(0), then min(cells − 1) before truncating, which
/// is the same (MAXPD maps NaN to 0, as `f64::max` does).
#[inline(always)]
pub(crate) fn clamped_cells<D: Wide>(cells: [u32; 3], t: V3<D>) -> V3<D> {
    let last = DVec3::from(cells.map(|n| f64::from(n - 1)));
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
pub(crate) fn lane_indices<D: Wide>(cell: &V3<D>, [nx, ny, _]: [u32; 3]) -> [usize; MAX_W] {
    let index = cell.x + D::splat(f64::from(nx)) * (cell.y + D::splat(f64::from(ny)) * cell.z);
    let mut lanes = [0; MAX_W];
    index.indices_into(&mut lanes);
    lanes
}

/// The answers of a batch's lanes not `found`: the scalar search's (`locate`) for those within
/// reach (`take`), `admit`'s for the others (none for a finite point, else an error).
#[inline(always)]
pub(crate) fn answer_the_rest(
    out: &mut [Answer],
    points: &[DVec3],
    found: u32,
    take: u32,
    finite: u32,
    locate: impl Fn(DVec3) -> Answer,
) {
    for (l, out) in out.iter_mut().enumerate() {
        let bit = 1 << l;
        if found & bit != 0 {
            continue;
        }
        *out = if take & bit != 0 {
            locate(points[l])
        } else if finite & bit != 0 {
            Ok(None)
        } else {
            Err(PointError::NonFinite)
        };
    }
}

/// Writes into `out` the hits of an inversion in lanes (`Maps::invert`'s ξ, squared residual,
/// iterations and lanes found): for each lane found, its cell `cell(l)`, ξ clamped into [−1, 1]³,
/// the residual and one inversion. Returns the lanes found.
#[inline(always)]
pub(crate) fn write_hits<V: Lanes>(
    out: &mut [Answer],
    (xi, rr, iterations, found): (V3<V>, V, [u32; MAX_W], u32),
    cell: impl Fn(usize) -> CellId,
) -> u32 {
    let xi = xi.widen().clamp(-1.0, 1.0);
    let residual = rr.widen().sqrt();
    for (l, out) in out.iter_mut().enumerate() {
        if found & (1 << l) != 0 {
            *out = Ok(Some(Hit {
                cell: cell(l),
                xi: xi.lane(l),
                iterations: iterations[l],
                residual: residual.lane(l),
                inversions: 1,
            }));
        }
    }
    found
}

/// The instruction sets the batched path can be compiled for, least first.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
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
    pub(crate) fn get() -> Self {
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
