//! Where the leaves are: one entry per base cell (dense, or a hash map on a sparse body), and under
//! each refined base cell an octree of entries, down to the leaves. A point is hashed to its base
//! cell and descends one level per step; a box visits the entries that meet it. Memory grows with
//! the leaves (about 32 bytes per 7 leaves of tree, plus the base index), never with the finest
//! level's lattice.

use std::collections::HashMap;

use glam::DVec3;

use super::Leaf;
use crate::idmap::IdMap;

/// An entry no leaf covers.
pub(super) const EMPTY: u32 = u32::MAX;
/// Tag of an entry that is a tree node (its index in `tree`); an entry without it is a leaf id.
const NODE: u32 = 1 << 31;
/// With [`NODE`], tag of an entry that is a brick: a base cell refined uniformly L levels, whose
/// (2^L)³ leaf ids are stored densely (`bricks[start]` holds L, then the ids in (z, y, x) order),
/// found in one load rather than L steps down a tree.
const BRICK: u32 = 1 << 30;

/// The base cell index: dense while the body fills at least 1/32 of the base lattice.
#[derive(Clone, Debug)]
enum Base {
    Dense(Vec<u32>),
    Sparse(IdMap),
}

/// Base cells and their octrees.
#[derive(Clone, Debug)]
pub(super) struct Forest {
    base: Base,
    /// Children of each tree node, binary order (bit 0: +x, bit 1: +y, bit 2: +z).
    tree: Vec<[u32; 8]>,
    /// The bricks: each its level L, then its (2^L)³ leaf ids.
    bricks: Vec<u32>,
    /// Base cells per axis.
    cells: [u32; 3],
    /// The deepest leaf's level: every descent takes this many steps (a loop of fixed length,
    /// whose branch the processor predicts whatever the levels of the points' leaves).
    depth: u8,
}

/// Why a leaf cannot be inserted: the leaf id already covering (part of) its region.
pub(super) struct Overlap(pub u32);

impl Forest {
    /// The forest of `leaves` (ids are their positions); the leaves are in range (checked by the
    /// caller). Errors with the first pair of leaves that overlap.
    pub(super) fn new(cells: [u32; 3], leaves: &[Leaf]) -> Result<Self, (u32, Overlap)> {
        Self::build(cells, leaves, true)
    }

    /// [`Forest::new`], with bricks or with trees alone.
    fn build(cells: [u32; 3], leaves: &[Leaf], with_bricks: bool) -> Result<Self, (u32, Overlap)> {
        let mut base: HashMap<u32, u32> = HashMap::with_capacity(leaves.len().min(1 << 20));
        let mut tree: Vec<[u32; 8]> = Vec::new();
        for (id, leaf) in leaves.iter().enumerate() {
            let id = id as u32;
            let l = u32::from(leaf.level);
            let b = leaf.base();
            let key = b[0] + cells[0] * (b[1] + cells[1] * b[2]);
            let mut entry = *base.entry(key).or_insert(EMPTY);
            if l == 0 {
                if entry != EMPTY {
                    return Err((id, Overlap(Self::any_leaf(&tree, entry))));
                }
                base.insert(key, id);
                continue;
            }
            if entry == EMPTY {
                tree.push([EMPTY; 8]);
                entry = NODE | (tree.len() as u32 - 1);
                base.insert(key, entry);
            } else if entry & NODE == 0 {
                return Err((id, Overlap(entry)));
            }
            // Descend from level 0 to the leaf's parent, making tree nodes where there are none.
            for depth in 1..=l {
                let node = (entry & !NODE) as usize;
                let shift = l - depth;
                let child = ((leaf.ijk[0] >> shift) & 1)
                    | (((leaf.ijk[1] >> shift) & 1) << 1)
                    | (((leaf.ijk[2] >> shift) & 1) << 2);
                let slot = tree[node][child as usize];
                if depth == l {
                    if slot != EMPTY {
                        return Err((id, Overlap(Self::any_leaf(&tree, slot))));
                    }
                    tree[node][child as usize] = id;
                } else if slot == EMPTY {
                    tree.push([EMPTY; 8]);
                    let new = NODE | (tree.len() as u32 - 1);
                    tree[node][child as usize] = new;
                    entry = new;
                } else if slot & NODE == 0 {
                    return Err((id, Overlap(slot)));
                } else {
                    entry = slot;
                }
            }
        }
        // Base cells refined uniformly become bricks; the trees left are copied compactly. The
        // bricks start with a 0 that no brick owns: the level (and the leaf) that the lanes read
        // for an entry that is no brick (`flat_lane`, `flat_id`).
        let mut bricks = vec![0];
        let mut kept: Vec<[u32; 8]> = Vec::new();
        for entry in base.values_mut() {
            if *entry == EMPTY || *entry & NODE == 0 {
                continue;
            }
            match Self::uniform_depth(&tree, *entry).filter(|_| with_bricks) {
                Some(level) if bricks.len() + (1usize << (3 * level)) < (BRICK - 1) as usize => {
                    let start = bricks.len();
                    bricks.push(level);
                    let side = 1u32 << level;
                    bricks.resize(start + 1 + (1 << (3 * level)), EMPTY);
                    Self::fill_brick(&tree, *entry, level, [0; 3], &mut |q, id| {
                        bricks[start + 1 + (q[0] + side * (q[1] + side * q[2])) as usize] = id;
                    });
                    *entry = NODE | BRICK | start as u32;
                }
                _ => *entry = Self::copy_tree(&tree, *entry, &mut kept),
            }
        }
        // The descent reads node 0 in every step, even where it does not descend.
        if kept.is_empty() {
            kept.push([EMPTY; 8]);
        }
        let tree = kept;
        let base_cells = cells.iter().map(|&n| n as usize).product::<usize>();
        let base = if base_cells <= 32 * base.len().max(1) {
            let mut dense = vec![EMPTY; base_cells];
            for (&key, &entry) in &base {
                dense[key as usize] = entry;
            }
            Base::Dense(dense)
        } else {
            Base::Sparse(IdMap::new(base.into_iter()))
        };
        bricks.shrink_to_fit();
        let depth = leaves.iter().map(|l| l.level).max().unwrap_or(0);
        Ok(Self {
            base,
            tree,
            bricks,
            cells,
            depth,
        })
    }

    /// The level L when every leaf under tree node `entry` is at depth L below it, all (2^L)³ of
    /// them present.
    fn uniform_depth(tree: &[[u32; 8]], entry: u32) -> Option<u32> {
        if entry == EMPTY {
            return None;
        }
        if entry & NODE == 0 {
            return Some(0);
        }
        let children = &tree[(entry & !NODE) as usize];
        let first = Self::uniform_depth(tree, children[0])?;
        for &c in &children[1..] {
            if Self::uniform_depth(tree, c)? != first {
                return None;
            }
        }
        Some(first + 1)
    }

    /// Calls `put(local ijk, id)` for every leaf under `entry`, a uniform subtree of `level` levels
    /// whose lowest cell is at `at` (local indices at the leaves' level).
    fn fill_brick(
        tree: &[[u32; 8]],
        entry: u32,
        level: u32,
        at: [u32; 3],
        put: &mut impl FnMut([u32; 3], u32),
    ) {
        if level == 0 {
            put(at, entry);
            return;
        }
        let half = 1 << (level - 1);
        for (child, &c) in tree[(entry & !NODE) as usize].iter().enumerate() {
            let at = [0, 1, 2].map(|a| at[a] + half * ((child as u32 >> a) & 1));
            Self::fill_brick(tree, c, level - 1, at, put);
        }
    }

    /// Copies the subtree of `entry` into `kept`, returning its new entry.
    fn copy_tree(tree: &[[u32; 8]], entry: u32, kept: &mut Vec<[u32; 8]>) -> u32 {
        if entry == EMPTY || entry & NODE == 0 {
            return entry;
        }
        let at = kept.len();
        kept.push([EMPTY; 8]);
        let children = tree[(entry & !NODE) as usize];
        for (child, c) in children.into_iter().enumerate() {
            let copied = Self::copy_tree(tree, c, kept);
            kept[at][child] = copied;
        }
        NODE | at as u32
    }

    /// Whether `entry` is a brick.
    #[inline(always)]
    fn is_brick(entry: u32) -> bool {
        entry & (NODE | BRICK) == NODE | BRICK && entry != EMPTY
    }

    /// The leaf of brick `entry` at local indices `q` on its level's lattice, and that level.
    #[inline(always)]
    fn brick_leaf(&self, entry: u32, q: [u32; 3]) -> u32 {
        let start = (entry & !(NODE | BRICK)) as usize;
        let level = self.bricks[start];
        self.bricks[start + 1 + (q[0] | q[1] << level | q[2] << (2 * level)) as usize]
    }

    /// The level of brick `entry`.
    #[inline(always)]
    fn brick_level(&self, entry: u32) -> u32 {
        self.bricks[(entry & !(NODE | BRICK)) as usize]
    }

    /// Some leaf under `entry` (a leaf id or a tree node), for an overlap message.
    fn any_leaf(tree: &[[u32; 8]], mut entry: u32) -> u32 {
        while entry & NODE != 0 && entry != EMPTY {
            let children = &tree[(entry & !NODE) as usize];
            entry = children
                .iter()
                .copied()
                .find(|&c| c != EMPTY)
                .unwrap_or(EMPTY);
        }
        entry
    }

    /// Whether the base index is dense: what [`Forest::flat_lane`] reads.
    #[inline(always)]
    pub(super) fn dense_base(&self) -> Option<&[u32]> {
        match &self.base {
            Base::Dense(dense) => Some(dense),
            Base::Sparse(_) => None,
        }
    }

    /// Whether a base `entry` (of [`Forest::dense_base`]) is *flat*, its leaf found without a
    /// descent: an unrefined cell (level 0, the word its leaf id) or a brick (its level L, the
    /// word its start in `bricks`, for [`Forest::flat_id`]). A tree or no leaf is not flat
    /// ([`Forest::leaf_at`] answers those; the level and word are then meaningless).
    ///
    /// Without a branch on the entry: the lanes' entries change from lane to lane (an unrefined
    /// cell in one, a brick in the next), which the processor cannot predict. So the level is
    /// always loaded, from `bricks[0]` (a 0 no brick owns) where the entry is no brick. (Masking
    /// the load's value instead, the compiler skipped the load with a branch.)
    #[inline(always)]
    pub(super) fn flat_lane(&self, entry: u32) -> (bool, u32, u32) {
        let leaf = entry & NODE == 0;
        let brick = Self::is_brick(entry);
        // All ones on a brick, zero otherwise.
        let on_brick = 0u32.wrapping_sub(u32::from(brick));
        let word = entry & !((NODE | BRICK) & on_brick);
        let level = self.bricks[(word & on_brick) as usize];
        (leaf | brick, level, word)
    }

    /// The leaf of a base `entry` on a body of one level: the entry itself, or `None` in a hole
    /// (such a body has no bricks or trees).
    #[inline(always)]
    pub(super) fn unrefined_leaf(entry: u32) -> Option<u32> {
        (entry & NODE == 0).then_some(entry)
    }

    /// The leaf of a flat entry ([`Forest::flat_lane`]'s level and word) of rank `rank` on its
    /// level's lattice ((z, y, x) order): the word itself on level 0, else the brick's entry.
    /// Without a branch, as `flat_lane`: on level 0 it loads `bricks[0]`, 0, and adds the word.
    #[inline(always)]
    pub(super) fn flat_id(&self, level: u32, word: u32, rank: usize) -> u32 {
        let refined = usize::from(level != 0);
        let at = self.bricks[(word as usize + 1 + rank) & 0usize.wrapping_sub(refined)];
        at + (word & (refined as u32).wrapping_sub(1))
    }

    /// The entry of base cell `b` (in range).
    #[inline(always)]
    fn base_entry(&self, b: [u32; 3]) -> u32 {
        let key = b[0] + self.cells[0] * (b[1] + self.cells[1] * b[2]);
        match &self.base {
            Base::Dense(dense) => dense[key as usize],
            Base::Sparse(map) => map.get(key).unwrap_or(EMPTY),
        }
    }

    /// The leaf whose undeformed box holds `t` (base lattice coordinates), with `t` clamped into
    /// the lattice's box first; on a boundary between leaves, the upper one. `None` in a hole.
    /// With the leaf's id come its level and indices, found on the way down (the hot path then
    /// reads no leaf record).
    #[inline(always)]
    pub(super) fn leaf_at(&self, t: DVec3) -> Option<(u32, Leaf)> {
        let mut ijk = [0u32; 3];
        for axis in 0..3 {
            // As `Lattice::clamped_cell`: `max` maps negatives and NaN to 0, `as` saturates.
            ijk[axis] = (t[axis].max(0.0) as u32).min(self.cells[axis] - 1);
        }
        let mut entry = self.base_entry(ijk);
        if Self::is_brick(entry) {
            // Where the tree's steps below end, in one step: t · 2^L is exact (a power of two), so
            // its floor is the cell the L comparisons choose; clamped into the base cell as they
            // are (t beyond the lattice, NaN to the lowest).
            let brick_level = self.brick_level(entry);
            let scale = super::locate::level_scale(brick_level as u8);
            let top = (1 << brick_level) - 1;
            let mut q = [0u32; 3];
            for axis in 0..3 {
                let low = ijk[axis] << brick_level;
                let fine = (t[axis] * scale).max(0.0) as u32;
                q[axis] = fine.saturating_sub(low).min(top);
                ijk[axis] = low + q[axis];
            }
            let id = self.brick_leaf(entry, q);
            return Some((
                id,
                Leaf {
                    level: brick_level as u8,
                    ijk,
                },
            ));
        }
        let mut scale = 1.0;
        let mut level = 0;
        // Branch-free steps: a point in a coarse leaf keeps its entry (selects, not jumps), so the
        // loop is the same for every point.
        for _ in 0..self.depth {
            let descend = entry & NODE != 0 && entry != EMPTY;
            let next_scale = scale * 2.0;
            let mut child = 0;
            let mut next_ijk = ijk;
            for axis in 0..3 {
                // The child's half along this axis: t · 2^(l+1) against 2 ijk + 1 (exact: dyadic).
                let upper = t[axis] * next_scale >= f64::from(2 * ijk[axis] + 1);
                next_ijk[axis] = 2 * ijk[axis] + u32::from(upper);
                child |= u32::from(upper) << axis;
            }
            let node = if descend { entry & !NODE } else { 0 };
            let next = self.tree[node as usize][child as usize];
            entry = if descend { next } else { entry };
            ijk = if descend { next_ijk } else { ijk };
            scale = if descend { next_scale } else { scale };
            level += u8::from(descend);
        }
        (entry != EMPTY).then_some((entry, Leaf { level, ijk }))
    }

    /// The leaf holding the finest-level cell `q` (indices at level `finest`), if any.
    pub(super) fn leaf_at_finest(&self, q: [u32; 3], finest: u8) -> Option<u32> {
        let (entry, _) = self.probe(q, finest);
        (entry != EMPTY).then_some(entry)
    }

    /// Where the descent towards the finest-level cell `q` stops: a leaf's id or [`EMPTY`] (no
    /// leaf covers the region), and the level it stopped at. `EMPTY` at level m means no leaf
    /// meets the level-m cell holding `q`.
    pub(super) fn probe(&self, q: [u32; 3], finest: u8) -> (u32, u8) {
        let f = u32::from(finest);
        let b = q.map(|v| v >> f);
        let mut entry = self.base_entry(b);
        if Self::is_brick(entry) {
            let level = self.brick_level(entry);
            let local = [0, 1, 2].map(|a| (q[a] >> (f - level)) - (b[a] << level));
            return (self.brick_leaf(entry, local), level as u8);
        }
        let mut depth = 0;
        while entry & NODE != 0 && entry != EMPTY {
            depth += 1;
            let shift = f - depth;
            let child =
                ((q[0] >> shift) & 1) | (((q[1] >> shift) & 1) << 1) | (((q[2] >> shift) & 1) << 2);
            entry = self.tree[(entry & !NODE) as usize][child as usize];
        }
        (entry, depth as u8)
    }

    /// Calls `visit(id, leaf)` for every leaf whose closed undeformed box meets the box [`low`,
    /// `high`] (base lattice coordinates), each once, in base cell order and depth first.
    pub(super) fn for_each_in_box(&self, low: DVec3, high: DVec3, visit: impl FnMut(u32, Leaf)) {
        self.for_each_in_box_where(low, high, |_| true, visit);
    }

    /// [`Forest::for_each_in_box`] in the base cells `base` accepts (by their index, x fastest)
    /// alone: the others' leaves are not visited.
    pub(super) fn for_each_in_box_where(
        &self,
        low: DVec3,
        high: DVec3,
        base: impl Fn(u32) -> bool,
        mut visit: impl FnMut(u32, Leaf),
    ) {
        let mut lo = [0u32; 3];
        let mut hi = [0u32; 3];
        for axis in 0..3 {
            // A NaN or a box beyond the lattice visits nothing.
            if !(high[axis] >= 0.0 && low[axis] <= f64::from(self.cells[axis])) {
                return;
            }
            // The cell whose upper face is at `low` meets the closed box too.
            lo[axis] = ((low[axis] - 1.0).ceil().max(0.0) as u32).min(self.cells[axis] - 1);
            // The cell whose lower face is at `high` meets the closed box too.
            hi[axis] = (high[axis].floor().max(0.0) as u32).min(self.cells[axis] - 1);
        }
        // (entry, level, ijk) still to look at.
        let mut stack: smallvec::SmallVec<[(u32, u8, [u32; 3]); 64]> = smallvec::SmallVec::new();
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    if !base(i + self.cells[0] * (j + self.cells[1] * k)) {
                        continue;
                    }
                    stack.push((self.base_entry([i, j, k]), 0, [i, j, k]));
                    while let Some((entry, level, ijk)) = stack.pop() {
                        if entry == EMPTY {
                            continue;
                        }
                        if entry & NODE == 0 {
                            visit(entry, Leaf { level, ijk });
                            continue;
                        }
                        // A brick is walked as the tree it replaces: the same order.
                        let brick = Self::is_brick(entry);
                        if brick && u32::from(level) == self.brick_level(entry) {
                            let l = u32::from(level);
                            let q = [0, 1, 2].map(|a| ijk[a] - ([i, j, k][a] << l));
                            visit(self.brick_leaf(entry, q), Leaf { level, ijk });
                            continue;
                        }
                        let size = 0.5f64.powi(i32::from(level) + 1);
                        let children = if brick {
                            &[entry; 8]
                        } else {
                            &self.tree[(entry & !NODE) as usize]
                        };
                        // Pushed high to low so that they pop in binary order.
                        for child in (0..8u32).rev() {
                            let c = children[child as usize];
                            if c == EMPTY {
                                continue;
                            }
                            let cijk = [0, 1, 2].map(|a| 2 * ijk[a] + ((child >> a) & 1));
                            let meets = (0..3).all(|a| {
                                let start = f64::from(cijk[a]) * size;
                                start <= high[a] && start + size >= low[a]
                            });
                            if meets {
                                stack.push((c, level + 1, cijk));
                            }
                        }
                    }
                }
            }
        }
    }

    /// Bytes on the heap.
    pub(super) fn heap_bytes(&self) -> usize {
        self.tree.capacity() * size_of::<[u32; 8]>()
            + self.bricks.capacity() * size_of::<u32>()
            + match &self.base {
                Base::Dense(dense) => dense.capacity() * size_of::<u32>(),
                Base::Sparse(map) => map.heap_bytes(),
            }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Leaves of a 3 × 2 × 2 base lattice: a brick of level 2, a brick of level 1, a base cell
    /// refined unevenly (a tree), unrefined cells and a hole.
    fn leaves() -> Vec<Leaf> {
        let mut leaves = Vec::new();
        let refine = |leaf: Leaf, levels: u8, leaves: &mut Vec<Leaf>| {
            let mut cells = vec![leaf];
            for _ in 0..levels {
                cells = cells.iter().flat_map(|c| c.children()).collect();
            }
            leaves.extend(cells);
        };
        refine(Leaf::new(0, [0, 0, 0]), 2, &mut leaves);
        refine(Leaf::new(0, [1, 0, 0]), 1, &mut leaves);
        // Base cell (2, 0, 0): one octant refined once more.
        let children = Leaf::new(0, [2, 0, 0]).children();
        refine(children[0], 1, &mut leaves);
        leaves.extend(&children[1..]);
        for ijk in [
            [0, 1, 0],
            [1, 1, 0],
            [2, 1, 0],
            [0, 0, 1],
            [1, 0, 1],
            [2, 1, 1],
        ] {
            leaves.push(Leaf::new(0, ijk));
        }
        // Base cells (2, 0, 1), (0, 1, 1) and (1, 1, 1) are holes.
        leaves
    }

    #[test]
    fn bricks_answer_as_the_trees_they_replace() {
        let cells = [3, 2, 2];
        let leaves = leaves();
        let bricked = Forest::build(cells, &leaves, true).unwrap_or_else(|_| panic!("valid"));
        let trees = Forest::build(cells, &leaves, false).unwrap_or_else(|_| panic!("valid"));
        // The lanes' 0, then two bricks: 1 + 64 and 1 + 8 entries.
        assert_eq!(bricked.bricks.len(), 1 + 65 + 9);
        assert!(trees.bricks == [0] && bricked.tree.len() < trees.tree.len());
        // Points on a grid of eighths of the finest cells, on faces and beyond the lattice.
        let steps = |n: u32| (-2..=(n * 32 + 2) as i32).map(|v| f64::from(v) / 32.0);
        for z in steps(2) {
            for y in steps(2) {
                for x in steps(3) {
                    let t = DVec3::new(x, y, z);
                    assert_eq!(bricked.leaf_at(t), trees.leaf_at(t), "{t}");
                }
            }
        }
        // Far beyond the lattice, and not numbers: clamped as the trees clamp them.
        let odd = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e300,
            -1e300,
            5e9,
            0.999,
        ];
        for (a, b) in odd.iter().flat_map(|&a| odd.iter().map(move |&b| (a, b))) {
            for t in [
                DVec3::new(a, b, 0.4),
                DVec3::new(0.2, a, b),
                DVec3::new(b, 0.7, a),
            ] {
                assert_eq!(bricked.leaf_at(t), trees.leaf_at(t), "{t}");
            }
        }
        for q in (0..12u32 * 4 * 4).map(|i| [i % 12, (i / 12) % 8, i / 96]) {
            assert_eq!(bricked.probe(q, 2), trees.probe(q, 2), "{q:?}");
        }
        // Boxes: the same leaves in the same order.
        for (low, high) in [
            (DVec3::splat(-1.0), DVec3::splat(5.0)),
            (DVec3::new(0.3, 0.1, 0.2), DVec3::new(0.6, 0.5, 0.9)),
            (DVec3::new(0.75, 0.25, 0.5), DVec3::new(0.75, 0.25, 0.5)),
            (DVec3::new(0.9, 0.0, 0.0), DVec3::new(2.2, 0.4, 1.0)),
        ] {
            let mut a = Vec::new();
            let mut b = Vec::new();
            bricked.for_each_in_box(low, high, |id, leaf| a.push((id, leaf)));
            trees.for_each_in_box(low, high, |id, leaf| b.push((id, leaf)));
            assert!(!a.is_empty());
            assert_eq!(a, b, "{low} {high}");
        }
    }
}
