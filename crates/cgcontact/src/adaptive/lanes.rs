//! The adaptive locator's batched path: W points at a time in SIMD lanes, as the uniform
//! locator's (`locate/batched.rs`), in lane types of 4 lanes: AVX's f64 and f32 (128-bit f32
//! registers, whose f64 lanes are one 256-bit register), the portable f32.
//!
//! The leaf holding a point is found in lanes wherever the forest answers without a descent (an
//! unrefined base cell, or a brick: a base cell refined uniformly): the base cell, the leaf's
//! indices and its rank in the brick are computed for all lanes at once, then each lane loads its
//! base entry and its leaf id. A lane under a tree takes the scalar descent. The corner nodes are
//! computed per lane (`nodes.rs`), their displacements gathered into lanes. On a body of one
//! level each leaf is its base cell, and its corners come from the cell's lattice index
//! (`OneLevel`), as the uniform locator's do. Then, as the scalar
//! search does: the guess x − ũ in lanes; the leaf there, which is x's own (no lookup) when the
//! guess lies in its box; one inversion in lanes, each with its leaf's spacing.
//!
//! On points the schedule sorted by leaf (`MEMO`), each lane walks its own run of the chunk and
//! keeps its last leaves, at x and at the guess, with their displacement maps (`Memo`): a point
//! in the same leaf's box takes them without a lookup, a corner or a gather.
//!
//! Every step computes what [`super::AdaptiveLocator`]'s scalar search computes, with the same
//! IEEE operations in the same order, so the answers are bitwise [`Locator::locate`]'s; a lane
//! that leaves this path (refused, in a hole) is answered by it, and one that missed in its
//! predicted leaf by the search's next step (`after_miss`).

use glam::DVec3;

use super::forest::Forest;
use super::locate::{LaneNodes, level_scale, level_size};
use super::{AdaptiveLocator, Leaf};
use crate::hex8::lanes::Maps;
use crate::lanes::{Lanes, MAX_W, V3, Wide};
use crate::lattice::CellId;
use crate::locate::{Answer, Locator, answer_the_rest, clamped_cells, lane_indices, write_hits};

/// The leaves holding W points, one per lane.
#[derive(Clone, Copy)]
struct Found<D> {
    /// Lanes holding a leaf (bits); the others are in a hole or were not asked.
    has: u32,
    id: [u32; MAX_W],
    /// 2^level and 2^−level.
    scale: D,
    size: D,
    /// The leaf's indices on its level's lattice.
    ijk: V3<D>,
    /// Its corner nodes, VTK order.
    nodes: [[u32; 8]; MAX_W],
}

impl<D: Wide> Found<D> {
    /// The lanes holding a leaf whose half-open box holds `t` (base lattice coordinates): the
    /// leaf [`Forest::leaf_at`] finds there, since the box's bounds are exact multiples of
    /// 2^−level; NaN and points outside the lattice are held by none.
    #[inline(always)]
    fn holds(&self, t: V3<D>) -> u32 {
        let low = self.ijk.scale(self.size);
        let high = (self.ijk + V3::splat(DVec3::ONE)).scale(self.size);
        let inside = low.x.le(t.x) & low.y.le(t.y) & low.z.le(t.z);
        let inside = inside & t.x.lt(high.x) & t.y.lt(high.y) & t.z.lt(high.z);
        D::bits(inside) & self.has
    }

    fn none() -> Self {
        let zero = V3::splat(DVec3::ZERO);
        Self {
            has: 0,
            id: [0; MAX_W],
            scale: D::splat(1.0),
            size: D::splat(1.0),
            ijk: zero,
            nodes: [[0; 8]; MAX_W],
        }
    }
}

/// The leaves the previous batch of a chunk found in each lane, at x and at the guess, and their
/// displacement maps: [`AdaptiveLocator::batch`]'s memory from one batch to the next.
pub(super) struct Memo<V: Lanes> {
    at_x: Found<V::Wide>,
    x_maps: Maps<V>,
    at_guess: Found<V::Wide>,
    guess_maps: Maps<V>,
}

impl<V: Lanes> Memo<V> {
    /// No leaf in any lane.
    pub(super) fn new() -> Self {
        let maps = Maps::<V> {
            a: [V3::splat(DVec3::ZERO); 8],
        };
        Self {
            at_x: Found::none(),
            x_maps: maps,
            at_guess: Found::none(),
            guess_maps: maps,
        }
    }
}

impl AdaptiveLocator<'_> {
    /// The leaves holding the base lattice coordinates `t` in the lanes `ask`, as
    /// [`super::forest::Forest::leaf_at`] finds them (`t` clamped into the lattice; on a boundary
    /// between leaves, the upper one), and their corner nodes: written into `found` in those
    /// lanes, the others kept (no merge afterwards, whose per-lane branch the processor could not
    /// predict).
    #[inline(always)]
    fn leaves_at<D: Wide>(&self, found: &mut Found<D>, t: V3<D>, ask: u32) {
        let body = self.body;
        let forest = &body.forest;
        let cells = body.lattice().cells();
        let zero = D::splat(0.0);
        let b = clamped_cells(cells, t);
        if let (Some(one), Some(dense)) = (&self.one_level, forest.dense_base()) {
            // One level: each leaf is the base cell holding t, its corners found from the cell's
            // lattice index, as the uniform locator finds its cells'. The level and indices the
            // lookup below would compute: 0, and the cell's own.
            let asked = D::mask_from_bits(ask);
            let one_ = D::splat(1.0);
            found.scale = D::select(asked, one_, found.scale);
            found.size = D::select(asked, one_, found.size);
            found.ijk = V3::select(asked, b, found.ijk);
            found.has &= !ask;
            let key = lane_indices(&b, cells);
            let base = lane_indices(&b, one.grid);
            for l in 0..D::W {
                let bit = 1 << l;
                if ask & bit == 0 {
                    continue;
                }
                if let Some(id) = Forest::unrefined_leaf(dense[key[l]]) {
                    found.id[l] = id;
                    found.nodes[l] = one.corners(base[l]);
                    found.has |= bit;
                }
            }
            return;
        }
        let mut level = [0u32; MAX_W];
        let mut word = [0u32; MAX_W];
        let mut flat = 0u32;
        if let Some(dense) = forest.dense_base() {
            // Every lane, without a branch on its entry (`flat_lane`): the base cell is clamped
            // into the lattice, so its entry exists.
            let key = lane_indices(&b, cells);
            for l in 0..D::W {
                let (is_flat, lv, w) = forest.flat_lane(dense[key[l]]);
                (level[l], word[l]) = (lv, w);
                flat |= u32::from(is_flat) << l;
            }
            flat &= ask;
        }
        // A flat lane's leaf, as `leaf_at` finds it in a brick: t · 2^L is exact, its floor
        // clamped into the base cell (an unrefined cell: L = 0, the cell itself).
        let scale = D::from_fn(|l| level_scale(level[l] as u8));
        let size = D::from_fn(|l| level_size(level[l] as u8));
        let top = scale - D::splat(1.0);
        let fine = |t: D, b: D| {
            ((t * scale).max(zero).trunc() - b * scale)
                .max(zero)
                .min(top)
        };
        let q = V3 {
            x: fine(t.x, b.x),
            y: fine(t.y, b.y),
            z: fine(t.z, b.z),
        };
        let asked = D::mask_from_bits(ask);
        found.scale = D::select(asked, scale, found.scale);
        found.size = D::select(asked, size, found.size);
        let flat_ijk = b.scale(scale) + q;
        found.ijk = V3::select(asked, flat_ijk, found.ijk);
        found.has &= !ask;
        let mut rank = [0usize; MAX_W];
        (q.x + scale * (q.y + scale * q.z)).indices_into(&mut rank);
        let mut ijk = [[0usize; MAX_W]; 3];
        flat_ijk.x.indices_into(&mut ijk[0]);
        flat_ijk.y.indices_into(&mut ijk[1]);
        flat_ijk.z.indices_into(&mut ijk[2]);
        // The other lanes descend; their levels and indices replace the computed ones below.
        let mut slow = 0u32;
        let mut slow_leaf = [Leaf::new(0, [0; 3]); MAX_W];
        for l in 0..D::W {
            let bit = 1 << l;
            if ask & bit == 0 {
                continue;
            }
            let (id, leaf) = if flat & bit != 0 {
                let leaf = Leaf::new(
                    level[l] as u8,
                    [ijk[0][l] as u32, ijk[1][l] as u32, ijk[2][l] as u32],
                );
                let id = forest.flat_id(level[l], word[l], rank[l]);
                (id, leaf)
            } else {
                let Some(found) = forest.leaf_at(t.lane(l)) else {
                    continue;
                };
                slow |= bit;
                slow_leaf[l] = found.1;
                found
            };
            found.id[l] = id;
            found.nodes[l] = body.leaf_nodes(id, leaf);
            found.has |= bit;
        }
        if slow != 0 {
            let m = D::mask_from_bits(slow);
            let level = |l: usize| u32::from(slow_leaf[l].level);
            found.scale = D::select(m, D::from_fn(|l| level_scale(level(l) as u8)), found.scale);
            found.size = D::select(m, D::from_fn(|l| level_size(level(l) as u8)), found.size);
            let index = |a: usize| D::from_fn(|l| f64::from(slow_leaf[l].ijk[a]));
            let slow_ijk = V3 {
                x: index(0),
                y: index(1),
                z: index(2),
            };
            found.ijk = V3::select(m, slow_ijk, found.ijk);
        }
    }

    /// The displacement maps of `found`'s leaves (node 0's in lanes without one: there is one).
    #[inline(always)]
    fn maps_of<V: Lanes>(&self, found: &Found<V::Wide>) -> Maps<V>
    where
        V::Node: LaneNodes,
    {
        let nodes = V::Node::of(self);
        Maps::from_nodes(|l, c| &nodes[found.nodes[l][c] as usize])
    }

    /// `search`'s common path for W points (`points` has W entries): the leaf at x, the guess,
    /// the leaf there and one inversion. A lane refused gets `admit`'s answer; one leaving the
    /// common path, the scalar search's. With `MEMO`, `memo` holds the leaves (and their maps)
    /// the previous batch of the chunk found in each lane: a lane whose point lies in its box
    /// takes them without a lookup, so points sorted by leaf find each leaf about once.
    #[inline(always)]
    pub(super) fn batch<V: Lanes, const MEMO: bool>(
        &self,
        points: &[DVec3],
        out: &mut [Answer],
        memo: &mut Memo<V>,
    ) where
        V::Node: LaneNodes,
    {
        let lattice = self.body.lattice();
        let splat = V3::<V::Wide>::splat;
        let two = V::Wide::splat(2.0);
        let x = V::Wide::transpose(|l| &points[l]);
        let (finite, admitted) = self.admit.lanes(x);
        let t_x = (x - splat(lattice.origin())).mul_each(self.inv_h);
        // Both lookups from one place in the code: x's leaves, then the guess's in the lanes
        // where it left them. Inlined at two places (and software-pipelined as the uniform
        // path is), the batch ran at 5.8-5.9 M points/s against 6.4 (`profile_adaptive`, f64).
        let (mut t, mut take) = (t_x, admitted);
        let mut t_guess = t_x;
        // Lanes whose guess left x's leaf: they take the guess's leaf (`memo.at_guess`).
        let (mut moved, mut second) = (0, false);
        loop {
            // Without `MEMO`, the guess's leaves replace x's in their lanes, as one set.
            let (found, maps) = if second && MEMO {
                (&mut memo.at_guess, &mut memo.guess_maps)
            } else {
                (&mut memo.at_x, &mut memo.x_maps)
            };
            let asked = if second { moved } else { admitted };
            let held = if MEMO { found.holds(t) } else { 0 };
            let ask = asked & !held;
            if ask != 0 {
                self.leaves_at(found, t, ask);
                *maps = self.maps_of::<V>(found);
            }
            take &= !(asked & !found.has);
            if second || take == 0 {
                break;
            }
            // `guess`: ũ interpolated at x in x's leaf (`undeformed_xi`, clamped).
            let leaf = &memo.at_x;
            let xi = ((t_x.scale(leaf.scale) - leaf.ijk).scale(two) - splat(DVec3::ONE))
                .clamp(-1.0, 1.0);
            t_guess = t_x
                - self
                    .displacement_lanes::<V>(memo.x_maps.map(V3::narrow(xi)).widen())
                    .mul_each(self.inv_h);
            // The leaf at the guess: x's own where the guess lies in its half-open box (the leaf
            // `leaf_at` finds there: the box's bounds are exact multiples of 2^−level), else
            // looked up.
            moved = take & !leaf.holds(t_guess);
            if moved == 0 {
                break;
            }
            (t, second) = (t_guess, true);
        }
        // The leaf each lane inverts in: x's, or the guess's where the guess moved (without
        // `MEMO`, already in x's set).
        let x_leaf = &memo.at_x;
        let (mut id, mut scale, mut size, mut ijk) =
            (x_leaf.id, x_leaf.scale, x_leaf.size, x_leaf.ijk);
        let mut maps = memo.x_maps;
        if MEMO && moved != 0 {
            let g = &memo.at_guess;
            for (l, id) in id.iter_mut().enumerate().take(V::W) {
                if moved & (1 << l) != 0 {
                    *id = g.id[l];
                }
            }
            let m = V::Wide::mask_from_bits(moved);
            (scale, size) = (
                V::Wide::select(m, g.scale, scale),
                V::Wide::select(m, g.size, size),
            );
            ijk = V3::select(m, g.ijk, ijk);
            let m = V::mask_from_bits(moved);
            for (c, a) in maps.a.iter_mut().enumerate() {
                *a = V3::select(m, memo.guess_maps.a[c], *a);
            }
        }
        let mut found = 0;
        if take != 0 {
            // `visit`: the leaf's spacing h · 2^−level and lowest corner, the guess's ξ there.
            let spacing = splat(lattice.h()).scale(size);
            maps.add_lattice_lanes(V3::narrow(spacing.scale(V::Wide::splat(0.5))));
            let x_local = self.point_lanes::<V>(x) - (splat(lattice.origin()) + spacing * ijk);
            let xi0 = (t_guess.scale(scale) - ijk).scale(two) - splat(DVec3::ONE);
            let inside = V3::<V>::splat(DVec3::ONE + self.newton.inside_tol);
            let inverted = maps.invert(
                V3::narrow(x_local),
                V3::narrow(xi0),
                inside,
                V::mask_from_bits(take),
                &self.newton,
            );
            found = write_hits(out, inverted, |l| CellId(id[l]));
        }
        // The lanes whose inversion in their predicted leaf failed: the search goes on from there.
        let mut missed = take & !found;
        while missed != 0 {
            let l = missed.trailing_zeros() as usize;
            missed &= missed - 1;
            out[l] = self.after_miss(points[l], t_guess.lane(l), id[l]);
        }
        answer_the_rest(out, points, found | take, admitted, finite, |x| {
            self.locate(x)
        });
    }
}
