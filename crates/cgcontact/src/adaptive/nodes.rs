//! The nodes of an adaptive body, numbered so that a leaf's corner nodes are computed, not stored.
//!
//! Each node belongs to the base cell whose half-open box [b, b + 1)³ (base lattice units) holds
//! it, its *owner*; nodes on the lattice's upper faces belong to cells one past the last, so the
//! owners form a grid of n + 1 cells per axis. Nodes are numbered owner by owner in lattice order
//! (z, then y, then x), and within an owner in (z, y, x) order of their finest-level coordinates.
//!
//! An owner whose nodes are exactly the points of the level-L lattice in its box is *full*: an
//! unrefined cell owning its lowest corner alone (L = 0), or a cell refined uniformly L levels
//! ((2^L)³ nodes). Its node at local coordinates q is its first node plus q's rank on that
//! lattice: no table. The other owners (around level changes, where hanging nodes sit on their
//! faces) keep a mask of the points they hold on the coarsest lattice L holding them all (a
//! node's number is then the count of the bits below its own): one 64-bit word for L ≤ 2; for
//! 3 ≤ L ≤ 5, 8^L / 64 words and a 16-bit count of the bits before each word, where that takes
//! no more memory than a list. Else they list their nodes' local coordinates, searched by
//! bisection. Memory: 8 bytes per cell of the owner grid (dense) or per owner (sparse, plus the
//! map), 8 per masked owner of L ≤ 2 and 10 · 8^(L−2) per deeper one (no more than its list),
//! and 4 or 8 per node of a listing owner.

use crate::idmap::IdMap;
use crate::lattice::CORNER_OFFSETS;

/// Tag of an owner that lists its nodes; the other bits are the list's start in `local`.
const LIST: u32 = 1 << 31;
/// Tag of an owner whose nodes are some of the points of the level-L lattice in its box,
/// L ≤ [`MAX_MASK_LEVEL`]: one bit per point ([`mask_words`] words), a node's number the count
/// of the bits below its own. The low 5 bits are L, the next 25 the mask's first word in `masks`.
const MASK: u32 = 1 << 30;
/// Mask words at most (25 bits of index); beyond, owners list their nodes.
const MAX_MASKS: usize = 1 << 25;
/// The deepest level of a mask: its counts of the bits before each word (below 8^5) fit 16 bits.
const MAX_MASK_LEVEL: u32 = 5;

/// The words of a level-`level` mask: its 8^level bits (at least one word), then for more than
/// one word the 16-bit count of the bits before each word, 4 to a word.
#[inline(always)]
fn mask_words(level: u32) -> (usize, usize) {
    if level <= 2 {
        (1, 0)
    } else {
        let words = 1usize << (3 * level - 6);
        (words, words / 4)
    }
}

/// An owner cell: its first node, and its shape (the level L of a full owner, [`MASK`] with its
/// mask's index and level, or [`LIST`] with the start of its local coordinates).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Owner {
    first: u32,
    shape: u32,
}

/// An owner without nodes: an empty list.
const EMPTY_OWNER: Owner = Owner {
    first: 0,
    shape: LIST,
};

/// The owners, with one more entry at the end whose `first` is the node count (so that an
/// owner's node count is the next entry's `first` minus its own).
#[derive(Clone, Debug)]
enum Owners {
    /// One entry per cell of the owner grid, empty ones included.
    Dense(Vec<Owner>),
    /// Only the owners that hold a node, ascending by cell, and the map cell → entry.
    Sparse {
        map: IdMap,
        cells: Vec<u32>,
        owners: Vec<Owner>,
    },
}

/// The node numbering of a body of one level (finest level 0) whose owners are stored densely,
/// as a uniform body's: every owner cell holds at most its lowest corner, so a lattice node's
/// number is its owner's first node, and on a body holding every lattice node, the node's
/// lattice index itself. What [`Nodes::corners`] computes for such a body, without its search
/// among the owners around a cell.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OneLevel<'a> {
    /// Owner cells per axis: the lattice's nodes per axis.
    pub(super) grid: [u32; 3],
    /// The owners, where some lattice node is no node; `None` where every one is.
    owners: Option<&'a [Owner]>,
    /// The lattice index offsets of a cell's 8 corners (VTK order) from its lowest corner's.
    offsets: [usize; 8],
}

impl OneLevel<'_> {
    /// The corner nodes (VTK order) of the cell whose lowest corner has lattice index `base`.
    #[inline(always)]
    pub(super) fn corners(&self, base: usize) -> [u32; 8] {
        match self.owners {
            None => self.offsets.map(|o| (base + o) as u32),
            Some(owners) => self
                .offsets
                .map(|o| owners.get(base + o).map_or(0, |owner| owner.first)),
        }
    }
}

/// The node numbering of an adaptive body.
#[derive(Clone, Debug)]
pub(super) struct Nodes {
    /// The finest level F: node coordinates are on its lattice.
    finest: u32,
    /// Owner cells per axis (base cells + 1).
    grid: [u32; 3],
    owners: Owners,
    /// The local coordinates (packed, [`pack`]) of the nodes of listing owners, in node order.
    local: Local,
    /// The masks of masked owners ([`MASK`]).
    masks: Vec<u64>,
    count: usize,
}

/// Packed local coordinates: 4 bytes each while they fit (F ≤ 10), else 8.
#[derive(Clone, Debug)]
enum Local {
    Narrow(Vec<u32>),
    Wide(Vec<u64>),
}

impl Local {
    #[cfg(test)]
    fn is_empty(&self) -> bool {
        match self {
            Self::Narrow(v) => v.is_empty(),
            Self::Wide(v) => v.is_empty(),
        }
    }

    #[inline(always)]
    fn get(&self, i: usize) -> u64 {
        match self {
            Self::Narrow(v) => u64::from(v[i]),
            Self::Wide(v) => v[i],
        }
    }

    /// The position of `key` in `range`, if there.
    #[inline(always)]
    fn find(&self, range: std::ops::Range<usize>, key: u64) -> Option<usize> {
        match self {
            Self::Narrow(v) => v[range].binary_search(&u32::try_from(key).ok()?).ok(),
            Self::Wide(v) => v[range].binary_search(&key).ok(),
        }
    }

    fn heap_bytes(&self) -> usize {
        match self {
            Self::Narrow(v) => v.capacity() * size_of::<u32>(),
            Self::Wide(v) => v.capacity() * size_of::<u64>(),
        }
    }
}

/// Local coordinates (each below 2^F, F ≤ 20) packed so that (z, y, x) order is ascending order.
#[inline(always)]
fn pack(q: [u32; 3], f: u32) -> u64 {
    u64::from(q[0]) | (u64::from(q[1]) << f) | (u64::from(q[2]) << (2 * f))
}

#[inline(always)]
fn unpack(key: u64, f: u32) -> [u32; 3] {
    let mask = (1u64 << f) - 1;
    [0, 1, 2].map(|a| ((key >> (a as u32 * f)) & mask) as u32)
}

impl Nodes {
    /// The numbering of the nodes at the finest-level `positions` (any order, repeats allowed) on
    /// a base lattice of `cells` refined `finest` levels. Every coordinate is at most
    /// `cells << finest`, and the owner grid has fewer than 2^32 cells (the lattice's nodes).
    pub(super) fn new(cells: [u32; 3], finest: u8, positions: Vec<[u32; 3]>) -> Self {
        let f = u32::from(finest);
        let grid = cells.map(|n| n + 1);
        let slot = |b: [u32; 3]| b[0] + grid[0] * (b[1] + grid[1] * b[2]);
        let mut keyed: Vec<(u32, u64)> = positions
            .into_iter()
            .map(|p| {
                let b = p.map(|v| v >> f);
                (slot(b), pack([0, 1, 2].map(|a| p[a] - (b[a] << f)), f))
            })
            .collect();
        keyed.sort_unstable();
        keyed.dedup();
        let count = keyed.len();
        let mut found: Vec<(u32, Owner)> = Vec::new();
        let mut local: Vec<u64> = Vec::new();
        let mut masks: Vec<u64> = Vec::new();
        let mut start = 0;
        while start < count {
            let cell = keyed[start].0;
            let end = start + keyed[start..].partition_point(|&(c, _)| c == cell);
            let run = &keyed[start..end];
            // The coarsest lattice holding every node of the run.
            let zeros = run
                .iter()
                .flat_map(|&(_, key)| unpack(key, f))
                .filter(|&v| v != 0)
                .map(u32::trailing_zeros)
                .min()
                .unwrap_or(f);
            let level = f - zeros.min(f);
            let (words, counts) = mask_words(level);
            // A deeper mask where it takes no more memory than the list (4 or 8 bytes a node).
            let list_bytes = run.len() * if 3 * f <= u32::BITS { 4 } else { 8 };
            let masked =
                level <= 2 || (level <= MAX_MASK_LEVEL && 8 * (words + counts) <= list_bytes);
            let shape = if run.len() == 1 << (3 * level) {
                level
            } else if masked && masks.len() + words + counts <= MAX_MASKS {
                let s = f - level;
                let first = masks.len();
                masks.resize(first + words + counts, 0);
                for &(_, key) in run {
                    let q = unpack(key, f).map(|v| v >> s);
                    let bit = (q[0] | q[1] << level | q[2] << (2 * level)) as usize;
                    masks[first + bit / 64] |= 1 << (bit % 64);
                }
                let mut before = 0u64;
                for w in 0..counts * 4 {
                    masks[first + words + w / 4] |= before << (16 * (w % 4));
                    before += u64::from(masks[first + w].count_ones());
                }
                MASK | ((first as u32) << 5) | level
            } else {
                let shape = LIST | local.len() as u32;
                local.extend(run.iter().map(|&(_, key)| key));
                shape
            };
            found.push((
                cell,
                Owner {
                    first: start as u32,
                    shape,
                },
            ));
            start = end;
        }
        let local = if 3 * f <= u32::BITS {
            // 3F bits: each key fits.
            Local::Narrow(local.into_iter().map(|k| k as u32).collect())
        } else {
            local.shrink_to_fit();
            Local::Wide(local)
        };
        let slots = grid.iter().map(|&n| n as usize).product::<usize>();
        let end = Owner {
            first: count as u32,
            shape: 0,
        };
        let owners = if slots <= 4 * found.len().max(1) {
            let mut dense = vec![Owner::default(); slots + 1];
            let mut next = 0;
            for (s, owner) in dense.iter_mut().take(slots).enumerate() {
                if found.get(next).is_some_and(|&(cell, _)| cell as usize == s) {
                    *owner = found[next].1;
                    next += 1;
                } else {
                    // An empty owner: no node (an empty list, never full); its `first` is where
                    // the next one's nodes start.
                    *owner = Owner {
                        first: found.get(next).map_or(count as u32, |&(_, o)| o.first),
                        ..EMPTY_OWNER
                    };
                }
            }
            dense[slots] = end;
            Owners::Dense(dense)
        } else {
            let map = IdMap::new(
                found
                    .iter()
                    .enumerate()
                    .map(|(r, &(cell, _))| (cell, r as u32)),
            );
            let cells = found.iter().map(|&(cell, _)| cell).collect();
            let mut owners: Vec<Owner> = found.iter().map(|&(_, o)| o).collect();
            owners.push(end);
            Owners::Sparse { map, cells, owners }
        };
        masks.shrink_to_fit();
        Self {
            finest: f,
            grid,
            owners,
            local,
            masks,
            count,
        }
    }

    /// Number of nodes.
    pub(super) fn len(&self) -> usize {
        self.count
    }

    /// The node at finest-level coordinates `p`, if there is one.
    #[inline(always)]
    pub(super) fn at(&self, p: [u32; 3]) -> Option<u32> {
        let f = self.finest;
        let b = p.map(|v| v >> f);
        self.in_owner(b, [0, 1, 2].map(|a| p[a] - (b[a] << f)), f)
    }

    /// The node of owner cell `b` at local coordinates `q` on level `l`'s lattice (each below
    /// 2^l), if there is one.
    #[inline(always)]
    fn in_owner(&self, b: [u32; 3], q: [u32; 3], l: u32) -> Option<u32> {
        if (0..3).any(|a| b[a] >= self.grid[a]) {
            return None;
        }
        let cell = b[0] + self.grid[0] * (b[1] + self.grid[1] * b[2]);
        let (owner, next) = match &self.owners {
            Owners::Dense(owners) => (owners[cell as usize], owners[cell as usize + 1].first),
            Owners::Sparse { map, owners, .. } => {
                let r = map.get(cell)? as usize;
                (owners[r], owners[r + 1].first)
            }
        };
        self.in_record(owner, next, q, l)
    }

    /// The node of the owner `owner` (whose successor's first node is `next`) at local
    /// coordinates `q` on level `l`'s lattice, if there is one.
    #[inline(always)]
    fn in_record(&self, owner: Owner, next: u32, q: [u32; 3], l: u32) -> Option<u32> {
        if owner.shape & LIST == 0 {
            let level = owner.shape & 31;
            let off = if level >= l {
                q.map(|v| v << (level - l))
            } else {
                let s = l - level;
                if q.iter().any(|&v| v & ((1 << s) - 1) != 0) {
                    return None;
                }
                q.map(|v| v >> s)
            };
            let bit = off[0] | (off[1] << level) | (off[2] << (2 * level));
            if owner.shape & MASK != 0 {
                self.mask_rank(owner.shape, bit).map(|r| owner.first + r)
            } else {
                // A full owner is never empty (empty owners are empty lists).
                Some(owner.first + bit)
            }
        } else {
            let start = (owner.shape & !LIST) as usize;
            let list = start..start + (next - owner.first) as usize;
            let key = pack(q.map(|v| v << (self.finest - l)), self.finest);
            Some(owner.first + self.local.find(list, key)? as u32)
        }
    }

    /// The rank among a masked owner's nodes (shape `shape`) of the point `bit` of its level's
    /// lattice in its box, if the owner holds that point.
    #[inline(always)]
    fn mask_rank(&self, shape: u32, bit: u32) -> Option<u32> {
        let first = ((shape & !MASK) >> 5) as usize;
        let level = shape & 31;
        let w = (bit / 64) as usize;
        let word = self.masks[first + w];
        let r = bit % 64;
        if (word >> r) & 1 == 0 {
            return None;
        }
        let below = (word & ((1 << r) - 1)).count_ones();
        if level <= 2 {
            return Some(below);
        }
        let (words, _) = mask_words(level);
        let before = (self.masks[first + words + w / 4] >> (16 * (w % 4))) & 0xffff;
        Some(before as u32 + below)
    }

    /// The point of its level's lattice (its bit) that a masked owner's node of rank `i` is.
    fn mask_select(&self, shape: u32, i: u32) -> u32 {
        let first = ((shape & !MASK) >> 5) as usize;
        let (words, _) = mask_words(shape & 31);
        let before = |w: usize| {
            if words == 1 {
                0
            } else {
                ((self.masks[first + words + w / 4] >> (16 * (w % 4))) & 0xffff) as u32
            }
        };
        // The last word with at most i bits before it holds the i-th (word 0 has none before).
        let (mut w, mut past) = (0, words);
        while past - w > 1 {
            let mid = (w + past) / 2;
            if before(mid) <= i {
                w = mid;
            } else {
                past = mid;
            }
        }
        let mut word = self.masks[first + w];
        for _ in 0..i - before(w) {
            word &= word - 1;
        }
        (w * 64) as u32 + word.trailing_zeros()
    }

    /// The 8 corner nodes (VTK order) of the cell of level `l` at `ijk` (on that level's
    /// lattice), 0 for a corner that is no node (never, for a leaf of the body).
    ///
    /// Out of line: the lanes call it from per-lane loops the compiler unrolls. Inlined there, it
    /// measured 4 % slower in f32 and 3 % faster in f64 (`profile_adaptive`, best of 5 alternated
    /// runs: 5.70 against 5.92, and 6.28 against 6.17 M points/s).
    #[inline(never)]
    pub(super) fn corners(&self, l: u32, ijk: [u32; 3]) -> [u32; 8] {
        let b = [ijk[0] >> l, ijk[1] >> l, ijk[2] >> l];
        let lo = [
            ijk[0] - (b[0] << l),
            ijk[1] - (b[1] << l),
            ijk[2] - (b[2] << l),
        ];
        // Most often every corner's owner is full at the cell's level: the cell's own base cell,
        // or across its upper faces the next one (where the corner is at local 0). Then each
        // corner is its owner's first node plus its rank, computed for all 8 without a branch
        // from the 8 owner records b + e (e in {0, 1}³; b is a base cell, so all 8 are in the
        // owner grid), and checked once.
        if let Owners::Dense(owners) = &self.owners {
            let gx = self.grid[0] as usize;
            let gxy = gx * self.grid[1] as usize;
            let cell = b[0] as usize + gx * b[1] as usize + gxy * b[2] as usize;
            let owner = |d: usize| owners.get(cell + d).copied().unwrap_or(EMPTY_OWNER);
            let near = [
                owner(0),
                owner(1),
                owner(gx),
                owner(gx + 1),
                owner(gxy),
                owner(gxy + 1),
                owner(gxy + gx),
                owner(gxy + gx + 1),
            ];
            let side = 1 << l;
            let (ux, uy, uz) = (lo[0] + 1 == side, lo[1] + 1 == side, lo[2] + 1 == side);
            let up = u32::from(ux) | u32::from(uy) << 1 | u32::from(uz) << 2;
            // Per axis, the rank's part of the corner's coordinate: at `lo`, and one step up (0
            // where that step crosses into the next owner).
            // Wrapping: past level 10 the ranks leave u32 (and 2l its shifts past level 15), but
            // no owner is full at such a level, so they are never used there (the corners go the
            // per-corner way below); a debug build must not panic computing them.
            let rank = |x: u32, y: u32, z: u32| x.wrapping_add(y).wrapping_add(z);
            let (x0, y0, z0) = (lo[0], lo[1] << l, lo[2].wrapping_shl(2 * l));
            let x1 = if ux { 0 } else { x0 + 1 };
            let y1 = if uy { 0 } else { y0.wrapping_add(side) };
            let z1 = if uz { 0 } else { z0.wrapping_add(side << l) };
            let ranks = [
                rank(x0, y0, z0),
                rank(x1, y0, z0),
                rank(x1, y1, z0),
                rank(x0, y1, z0),
                rank(x0, y0, z1),
                rank(x1, y0, z1),
                rank(x1, y1, z1),
                rank(x0, y1, z1),
            ];
            // The owner of each corner (VTK order): bit a of its offset, where that step crosses.
            const BITS: [u32; 8] = [0, 1, 3, 2, 4, 5, 7, 6];
            let mut nodes = [0u32; 8];
            // The corners whose owner is not full at level l (bits).
            let mut other = 0u32;
            for c in 0..8 {
                let owner = near[(BITS[c] & up) as usize];
                other |= u32::from(owner.shape != l) << c;
                nodes[c] = owner.first.wrapping_add(ranks[c]);
            }
            // Those corner by corner from the same records (masked owners, full ones at another
            // level); listing owners are searched as `in_owner` does.
            while other != 0 {
                let c = other.trailing_zeros() as usize;
                other &= other - 1;
                let e = BITS[c] & up;
                let owner = near[e as usize];
                // A masked owner on the cell's level (at a refinement's edge, or on the body's
                // upper faces): the corner's rank is its bit.
                if owner.shape & (LIST | MASK | 31) == MASK | l
                    && let Some(r) = self.mask_rank(owner.shape, ranks[c])
                {
                    nodes[c] = owner.first + r;
                    continue;
                }
                // The corner's local coordinates in its owner: lo + off, less the owner's side
                // where the step crossed into the next owner (bit a of e, set only where off[a]
                // is 1 and lo[a] + 1 is the side). Arithmetic, not branches: which corners come
                // here changes from leaf to leaf.
                let off = CORNER_OFFSETS[c];
                let q = [0, 1, 2].map(|a| lo[a] + off[a] - ((e >> a & 1) << l));
                nodes[c] = if owner.shape & LIST == 0 {
                    self.in_record(owner, 0, q, l)
                } else {
                    let eb = [0, 1, 2].map(|a| b[a] + (e >> a & 1));
                    self.in_owner(eb, q, l)
                }
                .unwrap_or(0);
            }
            return nodes;
        }
        let mut nodes = [0; 8];
        for (node, off) in nodes.iter_mut().zip(CORNER_OFFSETS) {
            let c = [0, 1, 2].map(|a| lo[a] + off[a]);
            // A corner on the cell's upper face belongs to the next owner, at local 0.
            let e = c.map(|v| v >> l);
            let owner = [0, 1, 2].map(|a| b[a] + e[a]);
            let q = [0, 1, 2].map(|a| c[a] - (e[a] << l));
            *node = self.in_owner(owner, q, l).unwrap_or(0);
        }
        nodes
    }

    /// The numbering as [`OneLevel`] reads it, on a body of one level with dense owners.
    pub(super) fn one_level(&self) -> Option<OneLevel<'_>> {
        let Owners::Dense(owners) = &self.owners else {
            return None;
        };
        if self.finest != 0 {
            return None;
        }
        let [gx, gy, gz] = self.grid.map(|g| g as usize);
        let gxy = gx * gy;
        Some(OneLevel {
            grid: self.grid,
            owners: (self.count != gxy * gz).then_some(&owners[..]),
            offsets: [0, 1, gx + 1, gx, gxy, gxy + 1, gxy + gx + 1, gxy + gx],
        })
    }

    /// [`Nodes::corners`] of the cell at `ijk` on a body of one level, through [`OneLevel`] where
    /// the owners are dense.
    pub(super) fn unrefined_corners(&self, ijk: [u32; 3]) -> [u32; 8] {
        match self.one_level() {
            Some(one) => {
                let [gx, gy, _] = self.grid.map(|g| g as usize);
                let [i, j, k] = ijk.map(|v| v as usize);
                one.corners(i + gx * (j + gy * k))
            }
            None => self.corners(0, ijk),
        }
    }

    /// The finest-level coordinates of `node` (in range).
    pub(super) fn position(&self, node: u32) -> [u32; 3] {
        let (cell, owner) = match &self.owners {
            Owners::Dense(owners) => {
                let r = owners.partition_point(|o| o.first <= node) - 1;
                (r as u32, owners[r])
            }
            Owners::Sparse { cells, owners, .. } => {
                let r = owners.partition_point(|o| o.first <= node) - 1;
                (cells[r], owners[r])
            }
        };
        self.local_position(self.owner_cell(cell), owner, node)
    }

    /// The position of `node`, one of `owner`'s, whose owner cell has indices `b`.
    fn local_position(&self, b: [u32; 3], owner: Owner, node: u32) -> [u32; 3] {
        let i = node - owner.first;
        if owner.shape & LIST != 0 {
            let f = self.finest;
            let q = unpack(self.local.get(((owner.shape & !LIST) + i) as usize), f);
            return [0, 1, 2].map(|a| (b[a] << f) + q[a]);
        }
        // The point's rank on the level's lattice: i itself, or the i-th bit of the mask.
        let i = if owner.shape & MASK != 0 {
            self.mask_select(owner.shape, i)
        } else {
            i
        };
        self.point_position(b, owner.shape & 31, i)
    }

    /// The owner grid's indices of owner cell `cell`.
    fn owner_cell(&self, cell: u32) -> [u32; 3] {
        [
            cell % self.grid[0],
            (cell / self.grid[0]) % self.grid[1],
            cell / (self.grid[0] * self.grid[1]),
        ]
    }

    /// The finest-level coordinates of the point of rank `i` on level `level`'s lattice in the
    /// box of the owner cell of indices `b`.
    fn point_position(&self, b: [u32; 3], level: u32, i: u32) -> [u32; 3] {
        let f = self.finest;
        let m = (1 << level) - 1;
        let off = [i & m, (i >> level) & m, i >> (2 * level)];
        [0, 1, 2].map(|a| (b[a] << f) + (off[a] << (f - level)))
    }

    /// `f(node, its finest-level coordinates)` for every node, in node order, until `f` fails.
    ///
    /// Owner by owner, in plain loops: the owner cell's indices once per owner (three divisions),
    /// a masked owner's points in bit order, word by word, rather than a select per node. (An
    /// iterator of iterators over boxed owner records cost 181 instructions a node, these loops
    /// 87, `update_independent`'s work per node included: callgrind, on the seed's block refined
    /// twice.)
    pub(super) fn try_for_each_position<E>(
        &self,
        mut f: impl FnMut(u32, [u32; 3]) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut owner_nodes = |cell: u32, owner: Owner, next: u32| -> Result<(), E> {
            let b = self.owner_cell(cell);
            let level = owner.shape & 31;
            if owner.shape & (LIST | MASK) == MASK {
                let first = ((owner.shape & !MASK) >> 5) as usize;
                let (mut w, mut word) = (0, self.masks[first]);
                for node in owner.first..next {
                    while word == 0 {
                        w += 1;
                        word = self.masks[first + w];
                    }
                    let bit = (w * 64) as u32 + word.trailing_zeros();
                    word &= word - 1;
                    f(node, self.point_position(b, level, bit))?;
                }
            } else if owner.shape & LIST != 0 {
                for node in owner.first..next {
                    f(node, self.local_position(b, owner, node))?;
                }
            } else {
                for node in owner.first..next {
                    f(node, self.point_position(b, level, node - owner.first))?;
                }
            }
            Ok(())
        };
        match &self.owners {
            Owners::Dense(owners) => {
                for (c, w) in owners.windows(2).enumerate() {
                    owner_nodes(c as u32, w[0], w[1].first)?;
                }
            }
            Owners::Sparse { cells, owners, .. } => {
                for (w, &c) in owners.windows(2).zip(cells) {
                    owner_nodes(c, w[0], w[1].first)?;
                }
            }
        }
        Ok(())
    }

    /// Every node's finest-level coordinates, in node order.
    #[cfg(test)]
    pub(super) fn positions(&self) -> Vec<[u32; 3]> {
        let mut all = Vec::with_capacity(self.len());
        let Ok(()) = self.try_for_each_position(|_, p| {
            all.push(p);
            Ok::<(), std::convert::Infallible>(())
        });
        all
    }

    /// Bytes on the heap.
    pub(super) fn heap_bytes(&self) -> usize {
        self.local.heap_bytes()
            + self.masks.capacity() * size_of::<u64>()
            + match &self.owners {
                Owners::Dense(owners) => owners.capacity() * size_of::<Owner>(),
                Owners::Sparse { map, cells, owners } => {
                    map.heap_bytes()
                        + cells.capacity() * size_of::<u32>()
                        + owners.capacity() * size_of::<Owner>()
                }
            }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Positions of a small scene: a 3 × 2 × 2 base lattice refined 2 levels; cell (0, 0, 0)
    /// refined uniformly twice (full at level 2), cell (1, 0, 0) once, cell (2, 1, 1) not, and a
    /// few finest nodes sprinkled on faces (hanging-like): every shape of owner.
    fn scene() -> (Vec<[u32; 3]>, [u32; 3], u8) {
        let cells = [3, 2, 2];
        let mut p = Vec::new();
        let corners = |origin: [u32; 3], size: u32, p: &mut Vec<[u32; 3]>| {
            for c in 0..8u32 {
                p.push([0, 1, 2].map(|a| origin[a] + size * ((c >> a) & 1)));
            }
        };
        for k in 0..4 {
            for j in 0..4 {
                for i in 0..4 {
                    corners([i, j, k], 1, &mut p);
                }
            }
        }
        for k in 0..2 {
            for j in 0..2 {
                for i in 0..2 {
                    corners([4 + 2 * i, 2 * j, 2 * k], 2, &mut p);
                }
            }
        }
        corners([8, 4, 4], 4, &mut p);
        p.push([9, 4, 6]);
        p.push([8, 5, 5]);
        (p, cells, 2)
    }

    /// Every cell of every level whose corners are all nodes: `corners` gives `at` of each.
    /// Returns how many cells were checked on each level.
    fn corners_are_found(nodes: &Nodes, cells: [u32; 3], finest: u8) -> Vec<usize> {
        let finest = u32::from(finest);
        let mut checked = vec![0; finest as usize + 1];
        for l in 0..=finest {
            let s = finest - l;
            for k in 0..cells[2] << l {
                for j in 0..cells[1] << l {
                    for i in 0..cells[0] << l {
                        let at: Vec<Option<u32>> = CORNER_OFFSETS
                            .iter()
                            .map(|o| nodes.at([(i + o[0]) << s, (j + o[1]) << s, (k + o[2]) << s]))
                            .collect();
                        if at.iter().all(Option::is_some) {
                            let expected: Vec<u32> = at.into_iter().flatten().collect();
                            assert_eq!(nodes.corners(l, [i, j, k]).to_vec(), expected);
                            if finest == 0 {
                                let one = nodes.unrefined_corners([i, j, k]);
                                assert_eq!(one.to_vec(), expected, "one level at {i} {j} {k}");
                            }
                            checked[l as usize] += 1;
                        }
                    }
                }
            }
        }
        checked
    }

    #[test]
    fn every_position_is_numbered_once_and_found_again() {
        let (positions, cells, finest) = scene();
        let mut distinct = positions.clone();
        distinct.sort_unstable();
        distinct.dedup();
        let nodes = Nodes::new(cells, finest, positions.clone());
        assert_eq!(nodes.len(), distinct.len());
        let listed: Vec<[u32; 3]> = nodes.positions();
        assert_eq!(listed.len(), distinct.len());
        for (node, &p) in listed.iter().enumerate() {
            assert_eq!(nodes.at(p), Some(node as u32), "{p:?}");
            assert_eq!(nodes.position(node as u32), p);
        }
        let mut sorted = listed.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, distinct);
        // Every finest-level point, inside the grid and beyond it: a node exactly where one is.
        for z in 0..=9 {
            for y in 0..=9 {
                for x in 0..=13 {
                    let p = [x, y, z];
                    let node = distinct.binary_search(&p).is_ok();
                    assert_eq!(nodes.at(p).is_some(), node, "{p:?}");
                }
            }
        }
        assert_eq!(nodes.at([u32::MAX; 3]), None);
        let cells_checked: usize = corners_are_found(&nodes, cells, finest).iter().sum();
        assert!(cells_checked > 64 + 8 + 1, "{cells_checked}");
        // Full owners: cell (0, 0, 0) at level 2 owns its 64 nodes, first; masks exist.
        assert_eq!(nodes.at([0, 0, 0]), Some(0));
        assert_eq!(nodes.at([3, 3, 3]), Some(63));
        assert!(!nodes.masks.is_empty() && nodes.local.is_empty());
    }

    /// Owners holding some of the points of their level-3, 4 and 5 lattices: masks where they
    /// cost no more memory than lists (many points), lists where they would (few). Every node is
    /// numbered as a list numbers it (owner by owner, then z, y, x), found again at its position,
    /// and given by `corners` for every cell whose corners are nodes.
    #[test]
    fn deep_masks_number_as_lists_do() {
        let cells = [2, 2, 2];
        let finest = 5u32;
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut positions = Vec::new();
        // (owner, level, points drawn): 300 of 512, 2,000 of 4,096 and 3,000 of 32,768 points
        // (masks: 80, 640 and 5,120 bytes against lists of 1,200, 8,000 and 12,000); 10 of 512
        // and 100 of 4,096 (lists: 40 and 400 bytes against masks of 80 and 640).
        for (b, level, count) in [
            ([0, 0, 0], 3, 300),
            ([1, 0, 0], 4, 2_000),
            ([0, 1, 0], 5, 3_000),
            ([1, 1, 0], 3, 10),
            ([0, 0, 1], 4, 100),
        ] {
            let side = 1u64 << level;
            for _ in 0..count {
                let r = next();
                let q = [r % side, (r >> 20) % side, (r >> 40) % side];
                positions.push(
                    [0, 1, 2]
                        .map(|a: usize| (b[a] << finest) + ((q[a] as u32) << (finest - level))),
                );
            }
            // Its lowest corner, and one point a step of the level away (so that the level is
            // the one drawn); for the masks, every point of a block of 3³ cells at their level.
            positions.push(b.map(|v| v << finest));
            positions.push([0, 1, 2].map(|a| (b[a] << finest) + (1 << (finest - level))));
            for q in (0..64).filter(|_| count > 200) {
                let q = [q % 4, (q / 4) % 4, q / 16];
                positions.push([0, 1, 2].map(|a| (b[a] << finest) + (q[a] << (finest - level))));
            }
        }
        // Every base node, so that the owner grid is dense.
        for c in 0..27 {
            positions.push([c % 3, (c / 3) % 3, c / 9].map(|v| v << finest));
        }
        let nodes = Nodes::new(cells, finest as u8, positions.clone());
        let Owners::Dense(owners) = &nodes.owners else {
            panic!("a dense owner grid");
        };
        let shapes: Vec<Option<u32>> = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1]]
            .iter()
            .map(|b: &[usize; 3]| {
                let shape = owners[b[0] + 3 * (b[1] + 3 * b[2])].shape;
                assert!(shape & (MASK | LIST) != 0, "{b:?} is not full");
                (shape & MASK != 0).then_some(shape & 31)
            })
            .collect();
        assert_eq!(
            shapes,
            [Some(3), Some(4), Some(5), None, None],
            "the masks' levels, None for a list"
        );
        // The numbering of lists: by owner cell (x fastest), then (z, y, x) inside.
        let mut distinct = positions.clone();
        distinct.sort_unstable_by_key(|p| {
            let b = p.map(|v| v >> finest);
            (b[2], b[1], b[0], p[2], p[1], p[0])
        });
        distinct.dedup();
        let listed: Vec<[u32; 3]> = nodes.positions();
        assert_eq!(listed, distinct);
        for (node, &p) in listed.iter().enumerate() {
            assert_eq!(nodes.at(p), Some(node as u32), "{p:?}");
            assert_eq!(nodes.position(node as u32), p);
        }
        // Every point of the finest lattice in the grid: a node exactly where one is.
        let mut sorted = distinct.clone();
        sorted.sort_unstable();
        let side = 2 << finest;
        for z in 0..=side {
            for y in 0..=side {
                for x in 0..=side {
                    let p = [x, y, z];
                    assert_eq!(
                        nodes.at(p).is_some(),
                        sorted.binary_search(&p).is_ok(),
                        "{p:?}"
                    );
                }
            }
        }
        let checked = corners_are_found(&nodes, cells, finest as u8);
        assert!(checked[3..].iter().all(|&n| n >= 27), "{checked:?}");
    }

    #[test]
    fn sparse_and_dense_owners_number_alike() {
        // The same nodes on a lattice 40 times larger per axis: sparse owners.
        let (positions, cells, finest) = scene();
        let dense = Nodes::new(cells, finest, positions.clone());
        let sparse = Nodes::new(cells.map(|n| n * 40), finest, positions.clone());
        assert!(matches!(dense.owners, Owners::Dense(_)));
        assert!(matches!(sparse.owners, Owners::Sparse { .. }));
        // Owner cells are numbered differently (a wider grid) but in the same order.
        let a: Vec<_> = dense.positions();
        let b: Vec<_> = sparse.positions();
        assert_eq!(a, b);
        for (node, &p) in a.iter().enumerate() {
            assert_eq!(sparse.at(p), Some(node as u32));
            assert_eq!(sparse.position(node as u32), p);
        }
        // The same nodes 10 levels deeper, and one more on the finest lattice in cell (0, 0, 0):
        // local coordinates of 3 × 12 bits, and that owner lists its nodes.
        let mut deeper: Vec<[u32; 3]> = positions.iter().map(|p| p.map(|v| v << 10)).collect();
        deeper.push([1, 0, 0]);
        let deep = Nodes::new(cells, finest + 10, deeper.clone());
        assert!(matches!(deep.local, Local::Wide(_)) && !deep.local.is_empty());
        assert!(matches!(dense.local, Local::Narrow(_)));
        deeper.sort_unstable();
        deeper.dedup();
        let listed: Vec<[u32; 3]> = deep.positions();
        assert_eq!(listed.len(), deeper.len());
        for (node, &p) in listed.iter().enumerate() {
            assert_eq!(deep.at(p), Some(node as u32));
            assert_eq!(deep.position(node as u32), p);
            assert!(deeper.binary_search(&p).is_ok());
            assert_eq!(
                deep.at([p[0], p[1] + 1, p[2]]).is_some(),
                deeper.binary_search(&[p[0], p[1] + 1, p[2]]).is_ok()
            );
        }
    }

    #[test]
    fn one_level_numbers_in_lattice_order() {
        // Every base cell's 8 corners: one node per owner, in (z, y, x) order of the nodes.
        let cells = [3, 2, 4];
        let mut p = Vec::new();
        for k in 0..=4 {
            for j in 0..=2 {
                for i in 0..=3 {
                    p.push([i, j, k]);
                }
            }
        }
        let expected = p.clone();
        p.reverse();
        let nodes = Nodes::new(cells, 0, p.clone());
        assert_eq!(nodes.positions(), expected);
        assert!(nodes.local.is_empty());
        // Every lattice node: corners by their lattice index alone.
        assert!(nodes.one_level().is_some_and(|one| one.owners.is_none()));
        assert_eq!(corners_are_found(&nodes, cells, 0), vec![24]);
        // Without the cell (0, 0, 0)'s lowest corner and the cells (2, 1, 3)'s upper corners
        // (its last, and the lattice's): the corners through the owners' first nodes.
        p.retain(|&q| q != [0, 0, 0] && q != [3, 2, 4] && q != [3, 2, 3] && q != [2, 2, 4]);
        let holed = Nodes::new(cells, 0, p);
        assert!(holed.one_level().is_some_and(|one| one.owners.is_some()));
        assert_eq!(corners_are_found(&holed, cells, 0), vec![20]);
    }
}
