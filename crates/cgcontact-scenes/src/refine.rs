//! Refining a lattice by halving: the leaves of an h-adaptive body, chosen by a split predicate,
//! 2:1 balanced or not.
//!
//! The tree is kept as one set of split cells per level (a cell of level l exists when it is a base
//! cell or a child of a split cell of level l − 1); nothing of the finest level's full lattice is
//! allocated, so memory grows with the leaves.

use std::collections::HashSet;

use cgcontact::adaptive::MAX_LEVEL;
use cgcontact::glam::DVec3;
use cgcontact::{Error, Lattice, Leaf};

/// The most leaves [`refine_lattice`] makes before it gives up with an error (a guard against
/// knobs that would ask for billions of cells).
pub const MAX_REFINED_LEAVES: usize = 1 << 24;

/// Bits per axis of a packed cell index (the core's finest-level limit, 2^21 − 1 cells per axis).
const BITS: u32 = 21;

fn pack(ijk: [u32; 3]) -> u64 {
    u64::from(ijk[0]) | (u64::from(ijk[1]) << BITS) | (u64::from(ijk[2]) << (2 * BITS))
}

fn unpack(key: u64) -> [u32; 3] {
    let mask = (1u64 << BITS) - 1;
    [0, 1, 2].map(|a| ((key >> (a as u32 * BITS)) & mask) as u32)
}

/// The undeformed box (lowest and highest corner) of `leaf` on the base `lattice`, computed as
/// [`cgcontact::AdaptiveBody::leaf_origin`] does.
#[must_use]
pub fn leaf_box(lattice: &Lattice, leaf: Leaf) -> (DVec3, DVec3) {
    let h = lattice.h() * 0.5f64.powi(i32::from(leaf.level));
    let [i, j, k] = leaf.ijk;
    let low = DVec3::new(f64::from(i), f64::from(j), f64::from(k));
    (
        lattice.origin() + h * low,
        lattice.origin() + h * (low + 1.0),
    )
}

/// The leaves that refine every cell of `lattice` (all of it: no holes) down to at most `levels`
/// levels: a cell of level l < `levels` is split in 8 when `split(leaf, low, high)` says so (its
/// undeformed box from `low` to `high`), level by level from the base cells down, so that the
/// predicate sees only cells that exist.
///
/// With `balanced`, cells are then split until no two leaves touching by a face, an edge or a
/// corner differ by more than one level (the 2:1 balance, by splitting the coarser neighbours,
/// recursively); without, any jump the predicate makes is kept.
///
/// The leaves come sorted by their lowest corner on the finest level's lattice, z then y then x:
/// with `levels` = 0 that is the uniform body's cell order.
///
/// Errors when `levels` exceeds [`MAX_LEVEL`], when the finest level's lattice exceeds the
/// 2^21 − 1 cells per axis the core indexes, or when more than [`MAX_REFINED_LEAVES`] leaves
/// would be made.
pub fn refine_lattice(
    lattice: &Lattice,
    levels: u8,
    balanced: bool,
    mut split: impl FnMut(Leaf, DVec3, DVec3) -> bool,
) -> Result<Vec<Leaf>, Error> {
    check_levels(lattice, levels)?;
    let counts = lattice.cells();
    let mut tree = Tree {
        split: vec![HashSet::new(); usize::from(levels)],
        leaves: counts.iter().map(|&n| n as usize).product(),
    };
    tree.check()?;
    for level in 0..levels {
        let mut consider = |tree: &mut Tree, ijk: [u32; 3]| {
            let leaf = Leaf::new(level, ijk);
            let (low, high) = leaf_box(lattice, leaf);
            if split(leaf, low, high) {
                tree.split(level, ijk)
            } else {
                Ok(())
            }
        };
        if level == 0 {
            let [nx, ny, nz] = counts;
            for k in 0..nz {
                for j in 0..ny {
                    for i in 0..nx {
                        consider(&mut tree, [i, j, k])?;
                    }
                }
            }
        } else {
            for parent in tree.sorted_splits(level - 1) {
                for child in Leaf::new(level - 1, parent).children() {
                    consider(&mut tree, child.ijk)?;
                }
            }
        }
    }
    if balanced {
        tree.balance(counts)?;
    }
    Ok(tree.leaves(counts, levels))
}

/// Refuse `levels` beyond [`MAX_LEVEL`], or a finest level's lattice beyond the 2^21 − 1 cells per
/// axis the core indexes: the knobs [`refine_lattice`] refuses before it refines anything.
pub(crate) fn check_levels(lattice: &Lattice, levels: u8) -> Result<(), Error> {
    if levels > MAX_LEVEL {
        return Err(Error::InvalidLattice(format!(
            "{levels} refinement levels exceed the {MAX_LEVEL} an adaptive body holds"
        )));
    }
    let counts = lattice.cells();
    if counts.iter().any(|&n| u64::from(n) << levels >= 1 << BITS) {
        return Err(Error::InvalidLattice(format!(
            "{counts:?} base cells refined {levels} levels exceed the 2^{BITS} - 1 finest cells per axis"
        )));
    }
    Ok(())
}

/// The error of a refinement that makes more than [`MAX_REFINED_LEAVES`] leaves.
pub(crate) fn too_many_leaves() -> Error {
    Error::InvalidLattice(format!(
        "the refinement makes more than {MAX_REFINED_LEAVES} leaves"
    ))
}

/// The split cells of each level, and how many leaves they make.
struct Tree {
    split: Vec<HashSet<u64>>,
    leaves: usize,
}

impl Tree {
    fn check(&self) -> Result<(), Error> {
        if self.leaves > MAX_REFINED_LEAVES {
            return Err(too_many_leaves());
        }
        Ok(())
    }

    /// Split cell `ijk` of `level` and, where they are not yet, its ancestors.
    fn split(&mut self, mut level: u8, mut ijk: [u32; 3]) -> Result<(), Error> {
        while self.split[usize::from(level)].insert(pack(ijk)) {
            // Each split turns one leaf into eight, once the chain above it is split too.
            self.leaves += 7;
            if level == 0 {
                break;
            }
            level -= 1;
            ijk = ijk.map(|v| v >> 1);
        }
        self.check()
    }

    /// The split cells of `level`, sorted so that a stateful predicate sees the cells in one order
    /// whatever the hashing.
    fn sorted_splits(&self, level: u8) -> Vec<[u32; 3]> {
        let mut keys: Vec<u64> = self.split[usize::from(level)].iter().copied().collect();
        keys.sort_unstable();
        keys.into_iter().map(unpack).collect()
    }

    /// 2:1 balance: every split cell's 26 neighbours of its level must exist (their parents
    /// split), which is the same as touching leaves differing by one level at most. Finest first,
    /// so that the cells a level's splits create are checked when their own level comes.
    fn balance(&mut self, counts: [u32; 3]) -> Result<(), Error> {
        for level in (1..self.split.len() as u8).rev() {
            let limit = counts.map(|n| i64::from(n << level));
            let mut cells: Vec<u64> = self.split[usize::from(level)].iter().copied().collect();
            cells.sort_unstable();
            for key in cells {
                let ijk = unpack(key).map(i64::from);
                for d in 0..27 {
                    let near: [i64; 3] = [d % 3, (d / 3) % 3, d / 9].map(|o| o - 1);
                    let q: [i64; 3] = [0, 1, 2].map(|a| ijk[a] + near[a]);
                    if near == [0, 0, 0] || (0..3).any(|a| q[a] < 0 || q[a] >= limit[a]) {
                        continue;
                    }
                    self.split(level - 1, q.map(|v| (v >> 1) as u32))?;
                }
            }
        }
        Ok(())
    }

    /// The leaves, sorted by lowest corner on the finest lattice (z, y, x).
    fn leaves(&self, counts: [u32; 3], levels: u8) -> Vec<Leaf> {
        let mut leaves = Vec::with_capacity(self.leaves);
        let [nx, ny, nz] = counts;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    if levels == 0 || !self.split[0].contains(&pack([i, j, k])) {
                        leaves.push(Leaf::new(0, [i, j, k]));
                    }
                }
            }
        }
        for level in 1..=levels {
            for parent in self.sorted_splits(level - 1) {
                for child in Leaf::new(level - 1, parent).children() {
                    if level == levels || !self.split[usize::from(level)].contains(&pack(child.ijk))
                    {
                        leaves.push(child);
                    }
                }
            }
        }
        leaves.sort_unstable_by_key(|leaf| {
            let q = leaf.ijk.map(|v| u64::from(v) << (levels - leaf.level));
            (q[2], q[1], q[0])
        });
        leaves
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(cells: [u32; 3]) -> Lattice {
        Lattice::new(DVec3::ZERO, DVec3::ONE, cells).unwrap()
    }

    #[test]
    fn nothing_split_is_the_base_lattice_in_cell_order() {
        let l = lattice([3, 2, 2]);
        let leaves = refine_lattice(&l, 3, true, |_, _, _| false).unwrap();
        assert_eq!(leaves.len(), 12);
        for (id, leaf) in leaves.iter().enumerate() {
            assert_eq!(leaf.level, 0);
            assert_eq!(l.cell_id(leaf.ijk).index(), id);
        }
    }

    /// Split the cells holding a point just below the base cell's centre: the level-3 leaves end
    /// at the centre, where level-1 leaves begin (a jump of 2).
    fn near_centre(_: Leaf, low: DVec3, high: DVec3) -> bool {
        let c = DVec3::splat(0.49);
        low.cmple(c).all() && c.cmplt(high).all()
    }

    fn per_level(leaves: &[Leaf]) -> [usize; 4] {
        std::array::from_fn(|l| {
            leaves
                .iter()
                .filter(|leaf| usize::from(leaf.level) == l)
                .count()
        })
    }

    #[test]
    fn one_chain_refined_three_levels_unbalanced() {
        let leaves = refine_lattice(&lattice([2, 2, 2]), 3, false, near_centre).unwrap();
        assert_eq!(per_level(&leaves), [7, 7, 7, 8]);
    }

    #[test]
    fn balancing_one_chain_splits_its_coarse_neighbours() {
        // Hand count. The split level-2 cell (1,1,1) needs its 26 level-2 neighbours: all 8
        // level-1 cells of base cell 0 split (7 more). Those need their level-1 neighbours: all 8
        // base cells split. Leaves: 8 at level 3; 8 × 8 − 1 at level 2; 7 × 8 at level 1.
        let leaves = refine_lattice(&lattice([2, 2, 2]), 3, true, near_centre).unwrap();
        assert_eq!(per_level(&leaves), [0, 56, 63, 8]);
    }

    #[test]
    fn knobs_beyond_the_core_are_errors() {
        let l = lattice([2, 2, 2]);
        assert!(refine_lattice(&l, MAX_LEVEL + 1, false, |_, _, _| false).is_err());
        let wide = lattice([1 << 20, 1, 1]);
        assert!(refine_lattice(&wide, 2, false, |_, _, _| false).is_err());
        let everything = refine_lattice(&lattice([8, 8, 8]), 9, false, |_, _, _| true);
        assert!(everything.is_err());
    }
}
