//! Warm starts: [`Locator::relocate`] for the lattice locator. A solver relocates the same points
//! at every Newton iteration with displacements that changed a little, so the cell of the previous
//! answer almost always still holds the point: it is inverted first, from the previous ξ, with no
//! hashing and no guess; the cold search (`scalar.rs`) answers only when it does not hold it.

use glam::DVec3;

use super::batched::Nodes;
use super::{Answer, Hit, LatticeLocator, Locator};
use crate::hex8::lanes::Maps;
use crate::hex8::{Hex8Map, Hex8Map32, Kernel, NewtonOptions, Status};
use crate::lanes::{Lanes, MAX_W, Real as _, V3};
use crate::lattice::CellId;
use crate::settings::Precision;

/// A usable hint: the previous answer's cell, its lattice indices and the starting ξ.
#[derive(Clone, Copy)]
struct Hint {
    cell: CellId,
    ijk: [u32; 3],
    xi0: DVec3,
}

/// The starting ξ of a hint: the previous ξ, or the centre when it is not finite (a hand-made
/// answer); `invert` clamps it into [−1, 1]³.
#[inline(always)]
pub(crate) fn start(xi: DVec3) -> DVec3 {
    if xi.is_finite() { xi } else { DVec3::ZERO }
}

/// Points [`relocate_split`] sorts at a time (on the stack: 256 points and answers, 20 kB).
const SPLIT: usize = 256;

/// [`Locator::relocate`] for a chunk, `answers` holding the hints and taking the answers: the
/// points with a hint through `hinted` (their hinted cells first, in lanes), those without one (a
/// miss or a refusal the last time) through `cold`, the batched cold search. Without a hint,
/// `relocate` is the cold search, so the answers are the same bit for bit; gathered, those points
/// keep the cold path's SIMD lanes instead of taking the scalar search one at a time in the
/// hinted path's lanes. That matters to a contact solve, where most points touch nothing.
pub(crate) fn relocate_split(
    points: &[DVec3],
    answers: &mut [Answer],
    hinted: impl Fn(&[DVec3], &mut [Answer]),
    cold: impl Fn(&[DVec3], &mut [Answer]),
) {
    let has_hint = |a: &Answer| matches!(a, Ok(Some(_)));
    for (points, answers) in points.chunks(SPLIT).zip(answers.chunks_mut(SPLIT)) {
        let with = answers.iter().filter(|a| has_hint(a)).count();
        if with == answers.len() {
            hinted(points, answers);
            continue;
        }
        if with == 0 {
            cold(points, answers);
            continue;
        }
        // The hinted points first, then the others, each in input order; answered, then put back.
        let mut xs = [DVec3::ZERO; SPLIT];
        let mut hs: [Answer; SPLIT] = [Ok(None); SPLIT];
        let mut from = [0u16; SPLIT];
        let (mut first, mut last) = (0, with);
        for (i, (&x, a)) in points.iter().zip(answers.iter()).enumerate() {
            let k = if has_hint(a) { &mut first } else { &mut last };
            (xs[*k], hs[*k], from[*k]) = (x, *a, i as u16);
            *k += 1;
        }
        let n = points.len();
        hinted(&xs[..with], &mut hs[..with]);
        cold(&xs[with..n], &mut hs[with..n]);
        for (&i, h) in from[..n].iter().zip(&hs[..n]) {
            answers[usize::from(i)] = *h;
        }
    }
}

impl LatticeLocator<'_> {
    /// The hint `previous` gives: a hit in an active cell of this lattice, or none (a miss, a
    /// refused point, a cell out of range or inactive).
    #[inline(always)]
    fn hint(&self, previous: &Answer) -> Option<Hint> {
        let Ok(Some(hit)) = previous else {
            return None;
        };
        let ijk = self.body.lattice().cell_ijk(hit.cell)?;
        self.body.is_active(hit.cell).then_some(Hint {
            cell: hit.cell,
            ijk,
            xi0: start(hit.xi),
        })
    }

    /// [`Locator::relocate`]; the inversions tried go to `tried` (the hinted one included).
    #[inline]
    pub(super) fn relocate_counted(&self, x: DVec3, previous: &Answer, tried: &mut u32) -> Answer {
        // The cold search's admission first: refused and unreachable points answer as there.
        let Some(length) = self.admit.admit(x)? else {
            return Ok(None);
        };
        let options = self.admit.options(&self.newton, length);
        if let Some(hint) = self.hint(previous) {
            *tried += 1;
            let hit = match self.settings.precision {
                Precision::F64 => self.invert_hint::<Hex8Map>(x, hint, &options),
                Precision::F32 => self.invert_hint::<Hex8Map32>(x, hint, &options),
            };
            if hit.is_some() {
                return Ok(hit);
            }
        }
        Ok(self.search_admitted(x, &options, tried))
    }

    /// The hinted cell inverted for `x` from the hint's ξ, with the cold search's kernel and
    /// options: the hit when it ends inside.
    #[inline(always)]
    fn invert_hint<K: Kernel>(&self, x: DVec3, hint: Hint, options: &NewtonOptions) -> Option<Hit> {
        let map = self.cell_map::<K>(hint.ijk);
        let inversion = map.invert_f64(self.local::<K>(x, hint.ijk), hint.xi0, options);
        (inversion.status == Status::Inside).then(|| Hit {
            cell: hint.cell,
            xi: inversion.xi.clamp(DVec3::NEG_ONE, DVec3::ONE),
            iterations: inversion.iterations,
            residual: inversion.residual,
            inversions: 1,
        })
    }

    /// [`Locator::relocate`] for a chunk of points, `answers` holding the hints and taking the
    /// answers: batched where the cold search is ([`LatticeLocator::locate_chunk`]'s choice), one
    /// point at a time otherwise. The answers are bitwise those of [`Locator::relocate`].
    pub(super) fn relocate_chunk(&self, points: &[DVec3], answers: &mut [Answer]) {
        #[cfg(target_arch = "x86_64")]
        match super::Isa::get() {
            // SAFETY: `Isa::get` answers `Avx512` only where AVX2, AVX-512F and AVX-512VL were
            // detected on this CPU, `Avx2` only where AVX2 was: the entry points' requirements.
            #[allow(unsafe_code)]
            super::Isa::Avx512 => return unsafe { self.relocate_chunk_avx512(points, answers) },
            #[allow(unsafe_code)]
            super::Isa::Avx2 => return unsafe { self.relocate_chunk_avx2(points, answers) },
            super::Isa::Portable => {}
        }
        match self.settings.precision {
            Precision::F32 => self.relocate_chunk_with::<glam::Vec4>(points, answers),
            Precision::F64 => {
                for (answer, &x) in answers.iter_mut().zip(points) {
                    *answer = self.relocate(x, answer);
                }
            }
        }
    }

    /// [`LatticeLocator::relocate_chunk`] in lanes `V`: W points at a time, their hinted cells
    /// inverted at once (the lane Newton of the cold batched path, from the hints' ξ); the
    /// remainder, and every point without a usable hint or whose hinted cell does not end inside
    /// on the lanes' common path, through [`Locator::relocate`].
    ///
    /// Software-pipelined as the cold path: the next W points' hints are read and their corners
    /// loaded before the current W are inverted, in two fronts used in turn.
    #[inline(always)]
    pub(super) fn relocate_chunk_with<V: Lanes>(&self, points: &[DVec3], answers: &mut [Answer])
    where
        V::Node: Nodes,
    {
        let w = V::W;
        let batches = points.len() / w;
        let mut fronts = [WarmFront::<V>::new(), WarmFront::<V>::new()];
        if batches > 0 {
            self.warm_front(&points[..w], &answers[..w], &mut fronts[0]);
        }
        for b in 0..batches {
            if b + 1 < batches {
                let (next, front) = ((b + 1) * w..(b + 2) * w, &mut fronts[(b + 1) % 2]);
                self.warm_front(&points[next.clone()], &answers[next], front);
            }
            let (current, front) = (b * w..(b + 1) * w, &fronts[b % 2]);
            self.warm_back(&points[current.clone()], front, &mut answers[current]);
        }
        for (answer, &x) in answers.iter_mut().zip(points).skip(batches * w) {
            *answer = self.relocate(x, answer);
        }
    }

    /// The first half of a warm batch: which lanes have a usable hint (and are admitted), and
    /// their hinted cells' displacement maps. The admission and the local coordinates in lanes, as
    /// the cold batch computes them; only the hints per lane.
    #[inline(always)]
    fn warm_front<V: Lanes>(&self, xs: &[DVec3], hints: &[Answer], front: &mut WarmFront<V>)
    where
        V::Node: Nodes,
    {
        let lattice = self.body.lattice();
        let x = V::Wide::transpose(|l| &xs[l]);
        // Lanes refused or out of reach, and lanes without a usable hint, go to `relocate`.
        let (_, admitted) = self.admit.lanes(x);
        let mut base = [0usize; MAX_W];
        let mut ijk = [[0u32; 3]; MAX_W];
        front.take = 0;
        for l in 0..V::W {
            if admitted & (1 << l) == 0 {
                continue;
            }
            let Some(hint) = self.hint(&hints[l]) else {
                continue;
            };
            front.cell[l] = hint.cell;
            front.xi0[l] = hint.xi0;
            ijk[l] = hint.ijk;
            base[l] = lattice.node_index(hint.ijk);
            front.take |= 1 << l;
        }
        if front.take != 0 {
            let splat = V3::<V::Wide>::splat;
            let index = |a: usize| V::Wide::from_fn(|l| f64::from(ijk[l][a]));
            let cell = V3 {
                x: index(0),
                y: index(1),
                z: index(2),
            };
            let x = if V::Node::SHIFTED {
                x - splat(self.frame.shift())
            } else {
                x
            };
            front.x_local = x - (splat(lattice.origin()) + cell.mul_each(lattice.h()));
            // The corners of each lane's hinted cell (active: every corner has a displacement;
            // lanes not taken read the lattice's first cell, and are ignored).
            let nodes = V::Node::of(self);
            let zero = V::Node::zero(self);
            front.maps = Maps::from_nodes(|l, c| self.body.corner_entry(nodes, base[l], c, &zero));
        }
    }

    /// The second half of a warm batch: one Newton inversion of each taken lane's hinted cell;
    /// every other lane through [`Locator::relocate`].
    #[inline(always)]
    fn warm_back<V: Lanes>(&self, xs: &[DVec3], front: &WarmFront<V>, answers: &mut [Answer])
    where
        V::Node: Nodes,
    {
        let take = front.take;
        let mut found = 0;
        if take != 0 {
            let mut maps = front.maps;
            maps.add_lattice(self.body.lattice().h());
            let xi0 = V3::<V> {
                x: V::from_fn(|l| V::S::of(front.xi0[l].x)),
                y: V::from_fn(|l| V::S::of(front.xi0[l].y)),
                z: V::from_fn(|l| V::S::of(front.xi0[l].z)),
            };
            let inside = V3::<V>::splat(DVec3::ONE + self.newton.inside_tol);
            let inverted = maps.invert(
                V3::narrow(front.x_local),
                xi0,
                inside,
                V::mask_from_bits(take),
                &self.newton,
            );
            found = super::write_hits(answers, inverted, |l| front.cell[l]);
        }
        for (l, (answer, &x)) in answers.iter_mut().zip(xs).enumerate() {
            if found & (1 << l) == 0 {
                *answer = self.relocate(x, answer);
            }
        }
    }
}

/// The first half of a warm batch of W points ([`LatticeLocator::relocate_chunk_with`]): per lane
/// its hinted cell and starting ξ, and in lanes the points in their
/// hinted cells' local frames (valid in the lanes `take` has), and the hinted cells'
/// displacement maps.
struct WarmFront<V: Lanes> {
    take: u32,
    cell: [CellId; MAX_W],
    x_local: V3<V::Wide>,
    xi0: [DVec3; MAX_W],
    maps: Maps<V>,
}

impl<V: Lanes> WarmFront<V> {
    #[inline(always)]
    fn new() -> Self {
        let zero = V3::splat(DVec3::ZERO);
        Self {
            take: 0,
            cell: [CellId(0); MAX_W],
            x_local: zero,
            xi0: [DVec3::ZERO; MAX_W],
            maps: Maps {
                a: [V3::splat(DVec3::ZERO); 8],
            },
        }
    }
}
