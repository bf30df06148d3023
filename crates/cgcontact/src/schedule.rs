//! The order in which the batched queries visit their points.
//!
//! On a body whose nodal data fits in the caches, any order is as fast as any other. On a large
//! one (a 4.2 M-cell block holds 100 MB of displacements) points in random order miss the caches
//! at every corner load, and the batched queries lose two thirds of their speed. So, above a
//! measured size, they first sort the points by the lattice cell (or block) they fall in (a radix
//! sort, most significant digit first: O(n), one piece per thread), answer them in that order, and
//! put the answers back in input order (or, for `locate_all_unordered_into` and
//! `gap_all_unordered_into`, leave them in that order beside the permutation). Each point's
//! answer depends on that point alone, so the answers are bitwise the same whatever the schedule;
//! only the order of the work changes.
//!
//! The sort's buffers (40 bytes per point, up to 56 when the points crowd into few blocks, and
//! two histograms per thread) live in a pool inside the locator and are reused by later calls.

use std::sync::{Mutex, TryLockError};

use glam::DVec3;
use rayon::prelude::*;

use crate::Lattice;

/// How the batched queries (`locate_all_into`, `locate_all_unordered_into`, `relocate_all`,
/// `gap_all_into`, `gap_all_unordered_into`, `regap_all`) order their work. The answers are
/// bitwise the same under every schedule, and returned in input order (by the two `unordered`
/// ones, in the order of the work, with the permutation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Schedule {
    /// [`Schedule::Blocked`] with [`Schedule::AUTO_LOG2_CELLS`] when the body's nodal data
    /// exceeds [`Schedule::AUTO_BYTES`] (for the adaptive locator's `locate_all_into` and
    /// `locate_all_unordered_into`, whatever its size: its batches reuse the leaves the previous
    /// points found, which pays only on sorted points), there are at least
    /// [`Schedule::AUTO_MIN_POINTS`] points, and they do not already come in an order the caches
    /// follow (a sample of pairs of consecutive points, [`Schedule::AUTO_FAR_SHARE`]); otherwise
    /// the input order.
    #[default]
    Auto,
    /// The points in the order given, in pieces of 256 across the threads.
    Input,
    /// The points grouped by lattice blocks of 2^`log2_cells` cells per axis (blocks of the base
    /// lattice on an adaptive body), blocks in lattice order, then answered block by block. The
    /// block is enlarged while the lattice has more than 2^32 blocks.
    Blocked {
        /// Base 2 logarithm of a block's edge, in cells.
        log2_cells: u8,
    },
}

impl Schedule {
    /// [`Schedule::Auto`] sorts above this many bytes of nodal data (displacements, and for an
    /// adaptive body its node numbering, corner table, bricks and octrees): where the sort pays on
    /// the machine of docs/benchmarks.md (it costs on the 128,000-cell block, 3 MB, and pays on
    /// the 1 M-cell block, 25 MB).
    pub const AUTO_BYTES: usize = 8 << 20;
    /// The block edge (log2, in cells) of [`Schedule::Auto`]: single cells, so the points come
    /// in lattice order, whose corner loads the hardware prefetches row by row. Blocks of 4³,
    /// 8³ and 16³ cells left the points in random order within a block and ran at less than
    /// half the speed of lattice order on the 4.2 M-cell block (docs/benchmarks.md).
    pub const AUTO_LOG2_CELLS: u8 = 0;
    /// Fewer points than this are answered in input order by [`Schedule::Auto`]: the sort's
    /// fixed costs (a histogram per pass and thread) would not pay.
    pub const AUTO_MIN_POINTS: usize = 16_384;
    /// Pairs of consecutive points [`Schedule::Auto`] samples, one in each of as many even
    /// strides of the input (where in the stride, a fixed hash decides), to
    /// tell whether the points already come in an order the caches follow.
    pub const AUTO_SAMPLES: usize = 1024;
    /// [`Schedule::Auto`] keeps the input order when at most this share of the sampled pairs of
    /// consecutive points jump further than a layer of cells (`far`): the sort then costs more
    /// than the cache misses it would save. On the 4.2 M-cell block of docs/benchmarks.md, input
    /// order is 1.45× the sorted speed with no far jumps, and breaks even at about a fifth.
    pub const AUTO_FAR_SHARE: f64 = 0.125;

    /// The block edge (log2, cells) to sort by for `points` points on a body of `layout`, or
    /// `None` for the input order.
    pub(crate) fn resolve(self, layout: &Layout<'_>, points: usize) -> Option<u8> {
        match self {
            Schedule::Auto => ((layout.remembers || layout.bytes > Self::AUTO_BYTES)
                && points >= Self::AUTO_MIN_POINTS)
                .then_some(Self::AUTO_LOG2_CELLS),
            Schedule::Input => None,
            Schedule::Blocked { log2_cells } => Some(log2_cells),
        }
    }
}

/// At most this many blocks: block indices fit in 32 bits.
const MAX_BLOCKS: u64 = 1 << 32;
/// Bits of the block index the first pass partitions by (the high ones): 2^10 buckets, whose
/// streams the partition writes at once. 2^8 and 2^11 buckets ran slower on the 4.2 M-cell block.
const BUCKET_BITS: u32 = 10;
/// Bits of the block index (below the bucket's) sorted per pass inside a bucket: 2^12 counts
/// (16 KB), so one pass suffices up to 2^22 blocks.
const LOCAL_BITS: u32 = 12;
/// At least this many points per thread.
const MIN_PIECE: usize = 1 << 14;
/// Points answered at a time (gathered, answered, scattered).
const CHUNK: usize = 256;

/// The blocks of a lattice: a point's block is the block of the cell its undeformed position
/// falls in, clamped into the lattice (NaN to block 0): any block would do, the key only orders
/// the work. Blocks smaller than a cell of the lattice (on a refined lattice, an adaptive
/// body's) are ordered cell by cell in lattice order, and in Morton order inside a cell, so
/// that the blocks of any cell of any level come one after the other: its points are answered
/// together, and the batched search finds that cell once for them all.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Blocks {
    origin: DVec3,
    /// 1 / (h · 2^log2).
    inv: DVec3,
    counts: [u32; 3],
    /// Bits per axis of a block's index inside its cell of the unrefined lattice (Morton order
    /// there), 0 when blocks are cells or larger.
    sub: u32,
}

impl Blocks {
    /// The blocks of 2^`log2` cells of `lattice` refined `level` times (enlarged while there
    /// are more than 2^32 blocks).
    pub(crate) fn new(lattice: &Lattice, level: u8, mut log2: u8) -> Self {
        let cells = lattice.cells().map(|n| u64::from(n) << level.min(32));
        let count = |log2: u8| cells.map(|n| n.div_ceil(1u64 << log2.min(63)).max(1));
        while count(log2).iter().fold(1u64, |p, &n| p.saturating_mul(n)) > MAX_BLOCKS {
            log2 += 1;
        }
        let size = lattice.h() * 2f64.powi(i32::from(log2) - i32::from(level));
        Self {
            origin: lattice.origin(),
            inv: size.recip(),
            // At most 2^32 blocks in all.
            counts: count(log2).map(|n| n as u32),
            // Below 32: with more bits, the blocks would be more than 2^32.
            sub: u32::from(level.min(32).saturating_sub(log2)),
        }
    }

    fn len(&self) -> usize {
        self.counts.iter().map(|&n| n as usize).product()
    }

    /// Whether the points already come in an order the caches follow: at most
    /// [`Schedule::AUTO_FAR_SHARE`] of [`Schedule::AUTO_SAMPLES`] pairs of consecutive points,
    /// one in each even stride of the input, lie more than a layer of blocks apart (their keys differ by
    /// more than a layer's blocks; a NaN point is clamped into block 0 as the sort does).
    fn coherent(&self, points: &[DVec3]) -> bool {
        let n = points.len();
        if n < 2 {
            return true;
        }
        let samples = Schedule::AUTO_SAMPLES.min(n - 1);
        let layer = self.counts[0] as usize * self.counts[1] as usize;
        let far = (0..samples)
            .filter(|&s| {
                // Pair (i, i + 1), i anywhere in the s-th of `samples` even strides of 0..n − 1:
                // a fixed hash of s picks where, so that inputs made of groups of a few points
                // are not sampled at the same place in every group (evenly spaced samples on a
                // power-of-two count took only the pairs inside pairs of points).
                let (low, high) = (s * (n - 1) / samples, (s + 1) * (n - 1) / samples);
                let hash = (s as u64 + 1).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32;
                let i = low + hash as usize % (high - low).max(1);
                self.key(points[i]).abs_diff(self.key(points[i + 1])) > layer
            })
            .count();
        far as f64 <= Schedule::AUTO_FAR_SHARE * samples as f64
    }

    #[inline(always)]
    pub(crate) fn key(&self, x: DVec3) -> usize {
        let t = (x - self.origin) * self.inv;
        // `max` maps negatives and NaN to 0, `as` saturates.
        // Axis by axis: `[0, 1, 2].map` compiled to an out-of-line call per point here, which
        // doubled the time of the keys' pass.
        let [nx, ny, nz] = self.counts;
        let i = (t.x.max(0.0) as u32).min(nx - 1) as usize;
        let j = (t.y.max(0.0) as u32).min(ny - 1) as usize;
        let k = (t.z.max(0.0) as u32).min(nz - 1) as usize;
        if self.sub == 0 {
            return i + nx as usize * (j + ny as usize * k);
        }
        // The cell's index in lattice order (the block counts are the cells' times 2^sub),
        // then the block's Morton index inside it.
        let sub = self.sub;
        let (cx, cy) = ((nx >> sub) as usize, (ny >> sub) as usize);
        let cell = (i >> sub) + cx * ((j >> sub) + cy * (k >> sub));
        let low = (1 << sub) - 1;
        let morton = spread(i & low) | spread(j & low) << 1 | spread(k & low) << 2;
        cell << (3 * sub) | morton
    }
}

/// The bits of `v` (below 2^16) spread to every third bit: bit b goes to bit 3b. Two lookups:
/// a block's index inside its cell has at most 10 bits per axis (3 · sub ≤ 32).
#[inline(always)]
fn spread(v: usize) -> usize {
    (SPREAD[v & 0xff] as usize) | (SPREAD[v >> 8 & 0xff] as usize) << 24
}

/// [`spread`] of each byte.
static SPREAD: [u32; 256] = {
    let mut table = [0; 256];
    let mut v = 0;
    while v < 256 {
        let mut bit = 0;
        while bit < 8 {
            table[v] |= ((v as u32 >> bit) & 1) << (3 * bit);
            bit += 1;
        }
        v += 1;
    }
    table
};

/// What the schedule needs to know of a body: its lattice, refined `level` times (an adaptive
/// body's finest level), and the bytes of nodal data its searches read.
#[derive(Clone, Copy, Debug)]
pub struct Layout<'a> {
    pub(crate) lattice: &'a Lattice,
    pub(crate) level: u8,
    pub(crate) bytes: usize,
    /// Whether the chunks, told that their points are sorted, reuse the cells found for one
    /// batch of points in the next (the adaptive locator's `locate_all_into`): the sort then
    /// pays on bodies of any size.
    pub(crate) remembers: bool,
}

/// A point partitioned into its bucket: its position, and its pair (block << 32 | input index
/// within its piece).
#[derive(Clone, Copy, Debug, Default)]
struct Record {
    x: DVec3,
    pair: u64,
}

/// The sort's buffers, reused across calls.
#[derive(Debug, Default)]
struct Workspace {
    /// Per point, its pair (block << 32 | input index within its piece), in input order.
    pairs: Vec<u64>,
    /// Per point, its record, the points of a piece partitioned by bucket.
    records: Vec<Record>,
    /// Per piece, the count (then the start) of each bucket, and the end of the last.
    buckets: Vec<u32>,
    /// Per piece, twice as many (block low bits << 32 | position in its bucket) pairs as the
    /// largest bucket holds: the local sort's source and destination.
    local: Vec<u64>,
    /// Per piece, the local sort's counts.
    counts: Vec<u32>,
}

impl Workspace {
    fn heap_bytes(&self) -> usize {
        size_of_val(self.pairs.as_slice())
            + size_of_val(self.records.as_slice())
            + size_of_val(self.buckets.as_slice())
            + size_of_val(self.local.as_slice())
            + size_of_val(self.counts.as_slice())
    }
}

/// A locator's schedule and the sort's buffers. Cloning gives an empty pool.
#[derive(Debug)]
pub(crate) struct Scheduler {
    schedule: Schedule,
    pool: Mutex<Workspace>,
}

impl Clone for Scheduler {
    fn clone(&self) -> Self {
        Self::new(self.schedule)
    }
}

impl Scheduler {
    pub(crate) fn new(schedule: Schedule) -> Self {
        Self {
            schedule,
            pool: Mutex::new(Workspace::default()),
        }
    }

    /// Bytes of the pooled buffers (0 while another call holds them).
    pub(crate) fn heap_bytes(&self) -> usize {
        match self.pool.try_lock() {
            Ok(ws) => ws.heap_bytes(),
            Err(TryLockError::Poisoned(p)) => p.into_inner().heap_bytes(),
            Err(TryLockError::WouldBlock) => 0,
        }
    }

    /// Answers `points` into `out` (same length) by `chunk`, which answers any run of points into
    /// a run of answers of the same length, on the current rayon pool: in input order in pieces
    /// of 256, or sorted by the blocks of the body's `layout`, as the schedule decides. With
    /// `warm`, `chunk` also reads each answer's previous value (the warm start's hint), which
    /// then travels with its point.
    pub(crate) fn run<T: Copy + Send + Sync>(
        &self,
        layout: Layout<'_>,
        points: &[DVec3],
        out: &mut [T],
        warm: bool,
        chunk: impl Fn(&[DVec3], &mut [T]) + Sync,
    ) {
        self.run_told(layout, points, out, warm, |p, o, _| chunk(p, o));
    }

    /// [`Self::run`] with `chunk` told whether its points come sorted by block (its third
    /// argument).
    pub(crate) fn run_told<T: Copy + Send + Sync>(
        &self,
        layout: Layout<'_>,
        points: &[DVec3],
        out: &mut [T],
        warm: bool,
        chunk: impl Fn(&[DVec3], &mut [T], bool) + Sync,
    ) {
        debug_assert_eq!(points.len(), out.len());
        let Some(blocks) = self.blocks(layout, points) else {
            out.par_chunks_mut(CHUNK)
                .zip(points.par_chunks(CHUNK))
                .for_each(|(out, points)| chunk(points, out, false));
            return;
        };
        let chunk = |p: &[DVec3], o: &mut [T]| chunk(p, o, true);
        let piece = piece_len(points.len());
        let pieces = out.par_chunks_mut(piece).map(|out| Scatter {
            answers: [out[0]; CHUNK],
            out,
            warm,
        });
        self.with_workspace(|ws| blocked(&blocks, points, piece, pieces, ws, &chunk));
    }

    /// [`Self::run`] without putting the answers back in input order: `out[k]` is the answer to
    /// `points[order[k]]`, in the order the points were answered (input order, or sorted by
    /// block), each index once. `order` and `out` are resized (`out` with `empty` when its length
    /// changes). Saves the scatter, a store to a random place per point. Never warm.
    pub(crate) fn run_unordered<T: Copy + Send + Sync>(
        &self,
        layout: Layout<'_>,
        points: &[DVec3],
        order: &mut Vec<usize>,
        out: &mut Vec<T>,
        empty: T,
        chunk: impl Fn(&[DVec3], &mut [T]) + Sync,
    ) {
        self.run_unordered_told(layout, points, order, out, empty, |p, o, _| chunk(p, o));
    }

    /// [`Self::run_unordered`] with `chunk` told whether its points come sorted by block (its
    /// third argument).
    pub(crate) fn run_unordered_told<T: Copy + Send + Sync>(
        &self,
        layout: Layout<'_>,
        points: &[DVec3],
        order: &mut Vec<usize>,
        out: &mut Vec<T>,
        empty: T,
        chunk: impl Fn(&[DVec3], &mut [T], bool) + Sync,
    ) {
        if out.len() != points.len() {
            out.clear();
            out.resize(points.len(), empty);
        }
        order.resize(points.len(), 0);
        let Some(blocks) = self.blocks(layout, points) else {
            order.par_iter_mut().enumerate().for_each(|(i, o)| *o = i);
            out.par_chunks_mut(CHUNK)
                .zip(points.par_chunks(CHUNK))
                .for_each(|(out, points)| chunk(points, out, false));
            return;
        };
        let chunk = |p: &[DVec3], o: &mut [T]| chunk(p, o, true);
        let piece = piece_len(points.len());
        let pieces = out
            .par_chunks_mut(piece)
            .zip(order.par_chunks_mut(piece))
            .enumerate()
            .map(|(p, (out, order))| Append {
                out,
                order,
                next: 0,
                start: p * piece,
            });
        self.with_workspace(|ws| blocked(&blocks, points, piece, pieces, ws, &chunk));
    }

    /// Whether [`Self::run`] would sort `points` on a body of `layout`: always under `Blocked`
    /// (two points or more), never under `Input`, and under `Auto` when the body and the batch
    /// are large enough and a sample of the points shows them out of order.
    pub(crate) fn would_sort(&self, layout: Layout<'_>, points: &[DVec3]) -> bool {
        self.blocks(layout, points).is_some()
    }

    /// The blocks to sort `points` by, or `None` to answer them in input order.
    fn blocks(&self, layout: Layout<'_>, points: &[DVec3]) -> Option<Blocks> {
        self.schedule
            .resolve(&layout, points.len())
            .filter(|_| points.len() > 1)
            .map(|log2| Blocks::new(layout.lattice, layout.level, log2))
            .filter(|blocks| self.schedule != Schedule::Auto || !blocks.coherent(points))
    }

    /// `f` on the pooled buffers, or on fresh ones when another call on this locator holds them.
    fn with_workspace(&self, f: impl FnOnce(&mut Workspace)) {
        let mut fresh = None;
        let mut guard = match self.pool.try_lock() {
            Ok(ws) => Some(ws),
            Err(TryLockError::Poisoned(p)) => Some(p.into_inner()),
            Err(TryLockError::WouldBlock) => None,
        };
        f(match guard.as_deref_mut() {
            Some(ws) => ws,
            None => fresh.insert(Workspace::default()),
        });
    }
}

/// The points of each piece of the blocked schedule: one piece per thread, at least
/// [`MIN_PIECE`] points each.
fn piece_len(n: usize) -> usize {
    let pieces = rayon::current_num_threads().clamp(1, n.div_ceil(MIN_PIECE));
    let piece = n.div_ceil(pieces);
    assert!(
        u32::try_from(piece).is_ok(),
        "at most 2^32 - 1 points per thread"
    );
    piece
}

/// How a piece of the blocked schedule answers its points, in runs of at most [`CHUNK`], and
/// where the answers go.
trait Answers<T>: Send {
    /// Answers `points` by `chunk`; `places` are their input places in the piece.
    fn answer(&mut self, points: &[DVec3], places: &[u32], chunk: &impl Fn(&[DVec3], &mut [T]));
}

/// Answers back in input order: each answered into a buffer (with its previous value when the run
/// is warm: the warm start's hint), then stored at its point's place in the piece's `out`.
struct Scatter<'a, T> {
    answers: [T; CHUNK],
    out: &'a mut [T],
    warm: bool,
}

impl<T: Copy + Send> Answers<T> for Scatter<'_, T> {
    #[inline(always)]
    fn answer(&mut self, points: &[DVec3], places: &[u32], chunk: &impl Fn(&[DVec3], &mut [T])) {
        let answers = &mut self.answers[..points.len()];
        if self.warm {
            for (a, &place) in answers.iter_mut().zip(places) {
                *a = self.out[place as usize];
            }
        } else {
            // The places the answers will be stored at, asked for while the chunk is answered:
            // on a large batch each is a cache miss, which the store would otherwise wait for.
            for &place in places {
                if let Some(slot) = self.out.get(place as usize) {
                    prefetch(slot);
                }
            }
        }
        chunk(points, answers);
        for (a, &place) in answers.iter().zip(places) {
            self.out[place as usize] = *a;
        }
    }
}

/// Asks the processor to bring the cache lines of `slot` (one or two: a value may straddle a
/// line's end) into its caches, ahead of a store there. A hint: nothing else changes.
///
/// Measured on the `scale` bench's 4,194,304-cell block, 1 M random points, one thread, against
/// the 16,000-cell block (`profile_locate 7 ratio`, the ratio's median; an Intel Xeon VM, two
/// runs of each build alternated): `locate_all_into` 0.458 and 0.454 without it, 0.534 and
/// 0.542 with it; in f32 0.944 against 1.108. `locate_all_unordered_into`, which stores in
/// order, moved within 2 % (0.697 and 0.688 against 0.700 and 0.707). Prefetching only the first
/// line of each value measured no gain (0.487).
#[inline(always)]
fn prefetch<T>(slot: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let first: *const i8 = std::ptr::from_ref(slot).cast();
        let last = first.wrapping_add(size_of::<T>().saturating_sub(1));
        // SAFETY: `_mm_prefetch` needs SSE, which every x86_64 processor has (it is in the
        // x86_64 target's baseline features, so this code only runs where it holds), and it is
        // a hint: it reads and writes nothing in Rust's memory model and never faults, whatever
        // the address. Both addresses here lie within `slot` anyway.
        #[allow(unsafe_code)]
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(first);
            _mm_prefetch::<_MM_HINT_T0>(last);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = slot;
}

/// Answers in the order they come: into the piece's `out` from `next` on, their points' indices
/// into `order` (`start` is the piece's first index).
struct Append<'a, T> {
    out: &'a mut [T],
    order: &'a mut [usize],
    next: usize,
    start: usize,
}

impl<T: Copy + Send> Answers<T> for Append<'_, T> {
    #[inline(always)]
    fn answer(&mut self, points: &[DVec3], places: &[u32], chunk: &impl Fn(&[DVec3], &mut [T])) {
        let run = self.next..self.next + points.len();
        chunk(points, &mut self.out[run.clone()]);
        for (o, &place) in self.order[run].iter_mut().zip(places) {
            *o = self.start + place as usize;
        }
        self.next += points.len();
    }
}

/// The blocked schedule: the points cut into pieces of `piece` points, one per thread; each piece
/// sorted by block and answered in that order 256 at a time (gathered into a buffer on the stack)
/// by its [`Answers`] in `pieces`: scattered back to their places, or appended in that order with
/// their indices. A piece owns its points' answers, so no answer is moved twice and no buffer
/// grows with the answers.
///
/// The sort is most significant digit first: a first pass reads the points in input order,
/// computes their blocks and counts the buckets (the high [`BUCKET_BITS`] of the block index); a
/// second reads them again and partitions them, carried whole, into their buckets; each bucket
/// is then sorted by the low bits of its blocks in the cache (one or two passes of
/// [`LOCAL_BITS`]) and answered. All passes are stable. Carrying the points saves gathering them
/// at random from the input, a cache miss per point: on the 4.2 M-cell block of
/// docs/benchmarks.md, 10 to 15 % faster than an LSD sort of (block, index) pairs whose points were
/// gathered by index.
fn blocked<T>(
    blocks: &Blocks,
    points: &[DVec3],
    piece: usize,
    pieces: impl IndexedParallelIterator<Item = impl Answers<T>>,
    ws: &mut Workspace,
    chunk: &(impl Fn(&[DVec3], &mut [T]) + Sync),
) {
    let n = points.len();
    let key_bits = u64::BITS - (blocks.len() as u64 - 1).leading_zeros();
    let low_bits = key_bits.saturating_sub(BUCKET_BITS);
    let buckets = (1usize << (key_bits - low_bits)) + 1;
    let pieces_count = n.div_ceil(piece);
    ws.pairs.resize(n, 0);
    ws.records.resize(n, Record::default());
    ws.buckets.resize(pieces_count * buckets, 0);
    // The keys, and each piece's buckets: counted, then turned into starts.
    ws.pairs
        .par_chunks_mut(piece)
        .zip(ws.buckets.par_chunks_mut(buckets))
        .zip(points.par_chunks(piece))
        .for_each(|((pairs, starts), points)| {
            starts.fill(0);
            for (pair, (j, &x)) in pairs.iter_mut().zip(points.iter().enumerate()) {
                let key = blocks.key(x) as u64;
                starts[(key >> low_bits) as usize] += 1;
                *pair = key << 32 | j as u64;
            }
            let mut next = 0;
            for slot in starts.iter_mut() {
                (*slot, next) = (next, next + *slot);
            }
        });
    // The local sort's buffers, as large as the largest bucket of any piece.
    let largest = ws
        .buckets
        .chunks(buckets)
        .flat_map(|starts| starts.windows(2).map(|w| w[1] - w[0]))
        .max()
        .unwrap_or(0) as usize;
    // (At least one of each per piece: the pieces are zipped with them.)
    let (local, digits) = if low_bits == 0 {
        (1, 1)
    } else {
        let passes = low_bits.div_ceil(LOCAL_BITS);
        (2 * largest.max(1), 1 << low_bits.div_ceil(passes))
    };
    ws.local.resize(pieces_count * local, 0);
    ws.counts.resize(pieces_count * digits, 0);
    ws.pairs
        .par_chunks(piece)
        .zip(ws.records.par_chunks_mut(piece))
        .zip(ws.buckets.par_chunks_mut(buckets))
        .zip(
            ws.local
                .par_chunks_mut(local)
                .zip(ws.counts.par_chunks_mut(digits)),
        )
        .zip(points.par_chunks(piece).zip(pieces))
        .for_each(
            |((((pairs, records), starts), (local, counts)), (points, mut answers))| {
                // Partition: each point carried whole into its bucket. `starts` ends up holding
                // each bucket's end, the next bucket's start.
                for (&pair, &x) in pairs.iter().zip(points) {
                    let slot = &mut starts[(pair >> (32 + low_bits)) as usize];
                    records[*slot as usize] = Record { x, pair };
                    *slot += 1;
                }
                let mut gathered = [DVec3::ZERO; CHUNK];
                let mut places = [0u32; CHUNK];
                let mut filled = 0;
                let mut begin = 0;
                let (from, to) = local.split_at_mut(local.len() / 2);
                for &end in &starts[..buckets - 1] {
                    let bucket = &records[begin as usize..end as usize];
                    begin = end;
                    // The bucket's order: by block when the buckets hold several blocks, else as
                    // partitioned.
                    let order = if low_bits == 0 {
                        None
                    } else {
                        let mask = (1 << low_bits) - 1;
                        let (f, t) = (&mut from[..bucket.len()], &mut to[..bucket.len()]);
                        for (l, (i, record)) in f.iter_mut().zip(bucket.iter().enumerate()) {
                            *l = (record.pair >> 32 & mask) << 32 | i as u64;
                        }
                        let (mut f, mut t) = (f, t);
                        let bits = low_bits.div_ceil(low_bits.div_ceil(LOCAL_BITS));
                        for shift in (0..low_bits).step_by(bits as usize) {
                            radix_pass(f, t, counts, 32 + shift);
                            std::mem::swap(&mut f, &mut t);
                        }
                        Some(&*f)
                    };
                    let len = bucket.len();
                    for k in 0..len {
                        let record = match order {
                            Some(order) => &bucket[order[k] as u32 as usize],
                            None => &bucket[k],
                        };
                        let place = record.pair as u32;
                        gathered[filled] = record.x;
                        places[filled] = place;
                        filled += 1;
                        if filled == CHUNK {
                            answers.answer(&gathered, &places, chunk);
                            filled = 0;
                        }
                    }
                }
                answers.answer(&gathered[..filled], &places[..filled], chunk);
            },
        );
}

/// One pass of the LSD radix sort: `from` counted and scattered into `to` by the digit of
/// `counts.len()` values at `shift`, stably. Out of line: inlined into the schedule's closure it
/// ran slower.
#[inline(never)]
fn radix_pass(from: &[u64], to: &mut [u64], counts: &mut [u32], shift: u32) {
    let mask = counts.len() - 1;
    let digit = |pair: u64| (pair >> shift) as usize & mask;
    counts.fill(0);
    for &pair in from.iter() {
        counts[digit(pair)] += 1;
    }
    let mut next = 0;
    for slot in counts.iter_mut() {
        (*slot, next) = (next, next + *slot);
    }
    for &pair in from.iter() {
        let slot = &mut counts[digit(pair)];
        to[*slot as usize] = pair;
        *slot += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(lattice: &Lattice, level: u8, bytes: usize) -> Layout<'_> {
        Layout {
            lattice,
            level,
            bytes,
            remembers: false,
        }
    }

    fn lattice() -> Lattice {
        Lattice::new(
            DVec3::new(-1.0, 2.0, 0.5),
            DVec3::new(0.5, 0.25, 1.0),
            [16, 9, 5],
        )
        .unwrap()
    }

    /// Points anywhere, outside and NaN included; each answer a function of its point alone
    /// (its bits) and of the chunk's call, so that a point answered twice or out of place shows.
    fn points(n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let f = (i as f64 * 0.618_033_988_749_895).fract();
                let g = (i as f64 * 0.414_213_562_373_095).fract();
                match i % 97 {
                    0 => DVec3::NAN,
                    1 => DVec3::splat(-1e9),
                    _ => DVec3::new(-2.0 + 12.0 * f, 1.0 + 4.0 * g, 0.5 + 5.0 * (f * g)),
                }
            })
            .collect()
    }

    #[test]
    fn blocked_answers_are_the_input_orders() {
        let lattice = lattice();
        let points = points(40_000);
        let answer = |x: DVec3| (x.x.to_bits() ^ x.y.to_bits().rotate_left(7), x.z.to_bits());
        let chunk = |p: &[DVec3], o: &mut [(u64, u64)]| {
            for (o, &x) in o.iter_mut().zip(p) {
                *o = answer(x);
            }
        };
        let expected: Vec<_> = points.iter().map(|&x| answer(x)).collect();
        for schedule in [
            Schedule::Input,
            Schedule::Blocked { log2_cells: 0 },
            Schedule::Blocked { log2_cells: 2 },
            Schedule::Blocked { log2_cells: 30 },
        ] {
            let scheduler = Scheduler::new(schedule);
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                // Twice: the second call reuses the pool's buffers; then fewer points.
                for n in [points.len(), points.len(), 1_000] {
                    let mut out = vec![(0, 0); n];
                    pool.install(|| {
                        scheduler.run(
                            layout(&lattice, 0, usize::MAX),
                            &points[..n],
                            &mut out,
                            false,
                            chunk,
                        )
                    });
                    assert_eq!(out, expected[..n], "{schedule:?}, {threads} threads, {n}");
                }
            }
        }
    }

    /// On one thread the chunks see the points sorted by block, in input order within a block:
    /// on a lattice of few blocks (the partition alone sorts), of 2^22 (one local pass) and of
    /// 2^31 (two), points spread or all in one bucket.
    #[test]
    fn blocked_visits_points_by_block_stably() {
        let lattices = [
            lattice(),
            Lattice::new(DVec3::ZERO, DVec3::ONE, [128, 256, 128]).unwrap(),
            Lattice::new(DVec3::ZERO, DVec3::ONE, [2000, 1000, 1000]).unwrap(),
        ];
        for lattice in &lattices {
            let blocks = Blocks::new(lattice, 0, 0);
            let extent = lattice.h() * DVec3::from(lattice.cells().map(f64::from));
            for spread in [1.0, 1e-3] {
                // Distinct points (their index in x's low bits), many sharing a block.
                let points: Vec<DVec3> = points(40_000)
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        let t = (*p - DVec3::new(-2.0, 1.0, 0.5)) / DVec3::new(12.0, 4.0, 5.0);
                        let x = lattice.origin() + t * extent * spread;
                        DVec3::new(f64::from_bits(x.x.to_bits() & !0xffff | i as u64), x.y, x.z)
                    })
                    .collect();
                let seen = Mutex::new(Vec::new());
                let chunk = |p: &[DVec3], o: &mut [u8]| {
                    seen.lock().unwrap().extend_from_slice(p);
                    o.fill(1);
                };
                let mut out = vec![0u8; points.len()];
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .build()
                    .unwrap();
                let scheduler = Scheduler::new(Schedule::Blocked { log2_cells: 0 });
                pool.install(|| {
                    scheduler.run(layout(lattice, 0, 0), &points, &mut out, false, chunk)
                });
                assert!(out.iter().all(|&o| o == 1));
                let seen = seen.into_inner().unwrap();
                assert_eq!(seen.len(), points.len());
                let order: Vec<(usize, u64)> = seen
                    .iter()
                    .map(|x| (blocks.key(*x), x.x.to_bits() & 0xffff))
                    .collect();
                assert!(
                    order.windows(2).all(|w| w[0] < w[1]),
                    "{:?} blocks, spread {spread}",
                    lattice.cells()
                );
            }
        }
    }

    /// Unordered runs give each point's answer with its index, in the order the points were
    /// visited: sorted by block on any number of threads (each piece in order), input order
    /// under `Schedule::Input`.
    #[test]
    fn unordered_answers_come_in_the_visit_order() {
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [128, 256, 128]).unwrap();
        let blocks = Blocks::new(&lattice, 0, 0);
        let extent = DVec3::from(lattice.cells().map(f64::from));
        let points: Vec<DVec3> = points(50_000)
            .iter()
            .map(|p| (*p - DVec3::new(-2.0, 1.0, 0.5)) / DVec3::new(12.0, 4.0, 5.0) * extent)
            .collect();
        // The answer of a point: its bits, so that a wrong index shows.
        let chunk = |p: &[DVec3], o: &mut [[u64; 3]]| {
            for (o, x) in o.iter_mut().zip(p) {
                *o = x.to_array().map(f64::to_bits);
            }
        };
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for schedule in [Schedule::Input, Schedule::Blocked { log2_cells: 0 }] {
                let scheduler = Scheduler::new(schedule);
                let (mut order, mut out) = (Vec::new(), Vec::new());
                pool.install(|| {
                    let layout = layout(&lattice, 0, 0);
                    scheduler.run_unordered(layout, &points, &mut order, &mut out, [0; 3], chunk)
                });
                let mut seen = vec![false; points.len()];
                for (&i, a) in order.iter().zip(&out) {
                    assert!(!std::mem::replace(&mut seen[i], true), "index {i} twice");
                    assert_eq!(*a, points[i].to_array().map(f64::to_bits), "point {i}");
                }
                // Each thread's piece of the input, answered in the schedule's order.
                let piece = points
                    .len()
                    .div_ceil(threads.min(points.len().div_ceil(MIN_PIECE)));
                for (p, got) in order.chunks(piece).enumerate() {
                    let mut expected: Vec<usize> = (p * piece..(p * piece + got.len())).collect();
                    if schedule != Schedule::Input {
                        expected.sort_by_key(|&i| blocks.key(points[i]));
                    }
                    assert!(
                        got == expected,
                        "{schedule:?}, {threads} threads, piece {p}"
                    );
                }
            }
        }
    }

    #[test]
    fn warm_answers_travel_with_their_points() {
        let lattice = lattice();
        let points = points(20_000);
        // The chunk adds its point's bits to the previous answer.
        let chunk = |p: &[DVec3], o: &mut [u64]| {
            for (o, &x) in o.iter_mut().zip(p) {
                *o = o.wrapping_mul(31).wrapping_add(x.x.to_bits());
            }
        };
        let previous: Vec<u64> = (0..points.len() as u64).map(|i| i * 7 + 1).collect();
        let expected: Vec<u64> = previous
            .iter()
            .zip(&points)
            .map(|(&p, x)| p.wrapping_mul(31).wrapping_add(x.x.to_bits()))
            .collect();
        let scheduler = Scheduler::new(Schedule::Blocked { log2_cells: 1 });
        let mut out = previous.clone();
        scheduler.run(layout(&lattice, 1, 0), &points, &mut out, true, chunk);
        assert_eq!(out, expected);
    }

    #[test]
    fn blocks_sort_by_lattice_block() {
        let lattice = lattice();
        let blocks = Blocks::new(&lattice, 0, 2);
        assert_eq!(blocks.counts, [4, 3, 2]);
        // One level finer, blocks of 2^3 finer cells: the same blocks.
        let finer = Blocks::new(&lattice, 1, 3);
        assert_eq!((finer.counts, finer.inv), (blocks.counts, blocks.inv));
        // The cell (5, 4, 3) is in block (1, 1, 0); NaN and far points are clamped.
        let x = lattice.node_position([5, 4, 3]) + DVec3::splat(0.01);
        assert_eq!(blocks.key(x), 1 + 4);
        assert_eq!(blocks.key(DVec3::NAN), 0);
        assert_eq!(blocks.key(DVec3::splat(1e300)), blocks.len() - 1);
        // A huge lattice gets larger blocks, at most 2^32 of them.
        let huge = Lattice::new(DVec3::ZERO, DVec3::ONE, [2000, 1000, 1000]).unwrap();
        let big = Blocks::new(&huge, 0, 0);
        assert!(big.len() as u64 <= MAX_BLOCKS && big.len() as u64 > MAX_BLOCKS / 8);
        let deep = Blocks::new(&lattice, 20, 0);
        assert!(deep.len() as u64 <= MAX_BLOCKS && deep.len() as u64 > MAX_BLOCKS / 8);
    }

    /// On a lattice refined twice, the keys of the blocks inside any cell of level 0, 1 or 2
    /// are one run of consecutive keys, cells of level 0 in lattice order: a sort by key brings
    /// every leaf's points together.
    #[test]
    fn refined_blocks_keep_every_cell_together() {
        let lattice = lattice();
        let blocks = Blocks::new(&lattice, 2, 0);
        assert_eq!(blocks.sub, 2);
        let [nx, ny, nz] = lattice.cells();
        let quarter = lattice.h() / 4.0;
        let key = |ijk: [u32; 3]| {
            let centre = DVec3::from(ijk.map(|n| f64::from(n) + 0.5));
            blocks.key(lattice.origin() + centre * quarter)
        };
        let mut seen = vec![false; blocks.len()];
        for level in 0..=2u32 {
            let width = 1 << (2 - level);
            for (i, j, k) in (0..nz << level).flat_map(|k| {
                (0..ny << level).flat_map(move |j| (0..nx << level).map(move |i| (i, j, k)))
            }) {
                let mut keys: Vec<usize> = (0..width * width * width)
                    .map(|b| {
                        let (a, c, d) = (b % width, b / width % width, b / width / width);
                        key([i * width + a, j * width + c, k * width + d])
                    })
                    .collect();
                keys.sort_unstable();
                let first = keys[0];
                assert!(
                    keys.iter().enumerate().all(|(n, &key)| key == first + n),
                    "level {level} cell {:?}: {keys:?}",
                    (i, j, k)
                );
                if level == 0 {
                    let cell = i + nx * (j + ny * k);
                    assert_eq!(first, cell as usize * 64, "cell {:?}", (i, j, k));
                }
                if level == 2 {
                    assert!(
                        !std::mem::replace(&mut seen[first], true),
                        "key {first} twice"
                    );
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    /// Points in lattice order on a 64 × 64 × 64 lattice (one per cell, 2^18), then a share of
    /// them swapped with points anywhere (a fixed shuffle).
    fn lattice_ordered(swapped: f64) -> (Lattice, Vec<DVec3>) {
        let lattice = Lattice::new(DVec3::new(-3.0, 1.0, 2.0), DVec3::splat(0.5), [64; 3]).unwrap();
        let mut points: Vec<DVec3> = (0..64u32 * 64 * 64)
            .map(|c| {
                let ijk = [c % 64, c / 64 % 64, c / 4096];
                lattice.node_position(ijk) + DVec3::new(0.1, 0.2, 0.3)
            })
            .collect();
        let n = points.len();
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as usize % n
        };
        for _ in 0..(swapped * n as f64 / 2.0) as usize {
            let (i, j) = (next(), next());
            points.swap(i, j);
        }
        (lattice, points)
    }

    #[test]
    fn coherence_is_told_from_far_jumps() {
        let blocks = |lattice: &Lattice| Blocks::new(lattice, 0, 0);
        // Lattice order, and lattice order with a few far jumps: kept.
        for swapped in [0.0, 0.02] {
            let (lattice, points) = lattice_ordered(swapped);
            assert!(blocks(&lattice).coherent(&points), "{swapped}");
        }
        // Many far jumps, random order: sorted.
        for swapped in [0.2, 1.0] {
            let (lattice, points) = lattice_ordered(swapped);
            assert!(!blocks(&lattice).coherent(&points), "{swapped}");
        }
        // Points y-major, then x-major: consecutive points a layer or less apart but for the
        // ends of columns (one step in 64), whose next column reads the lines beside: kept;
        // alternating between the lower and the upper half of the layers: sorted.
        let (lattice, mut points) = lattice_ordered(0.0);
        let b = blocks(&lattice);
        points.sort_by(|p, q| (p.y, p.z, p.x).partial_cmp(&(q.y, q.z, q.x)).unwrap());
        assert!(b.coherent(&points));
        points.sort_by(|p, q| (p.x, p.y, p.z).partial_cmp(&(q.x, q.y, q.z)).unwrap());
        assert!(b.coherent(&points));
        let (_, points) = lattice_ordered(0.0);
        let (lo, hi) = points.split_at(points.len() / 2);
        let alternating: Vec<DVec3> = lo.iter().zip(hi).flat_map(|(a, b)| [*a, *b]).collect();
        assert!(!b.coherent(&alternating));
        // Groups of 2, 4 and 8 near points (a face's Gauss points) in random group order, on
        // input sizes that are powers of two, where evenly spaced samples could all fall inside
        // a group: 1/2 and 1/4 of the consecutive pairs jump far, sorted; 1/8, kept.
        let (lattice, shuffled) = lattice_ordered(1.0);
        let b = blocks(&lattice);
        for (group, kept) in [(2, false), (4, false), (8, true)] {
            for n in [1 << 16, 1 << 17, (1 << 17) + group] {
                let grouped: Vec<DVec3> = shuffled[..n / group]
                    .iter()
                    .flat_map(|&x| std::iter::repeat_n(x, group))
                    .collect();
                assert_eq!(b.coherent(&grouped), kept, "groups of {group}, {n} points");
            }
        }
        // NaN points fall in block 0, as the sort puts them; a single point is in order, two
        // far apart are not.
        assert!(b.coherent(&vec![DVec3::NAN; 40_000]));
        assert!(b.coherent(&points[..1]) && b.coherent(&points[..2]));
        assert!(!b.coherent(&[points[0], points[70_000]]));
    }

    /// Under `Auto` on a large body, points in lattice order are answered as given and points in
    /// random order are sorted first; an explicit `Blocked` sorts either.
    #[test]
    fn auto_keeps_an_order_the_caches_follow() {
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        for (swapped, schedule, sorts) in [
            (0.0, Schedule::Auto, false),
            (1.0, Schedule::Auto, true),
            (0.0, Schedule::Blocked { log2_cells: 4 }, true),
        ] {
            let (lattice, points) = lattice_ordered(swapped);
            let seen = Mutex::new(Vec::new());
            let chunk = |p: &[DVec3], o: &mut [u8]| {
                seen.lock().unwrap().extend_from_slice(p);
                o.fill(1);
            };
            let mut out = vec![0u8; points.len()];
            let scheduler = Scheduler::new(schedule);
            one.install(|| {
                scheduler.run(
                    layout(&lattice, 0, Schedule::AUTO_BYTES + 1),
                    &points,
                    &mut out,
                    false,
                    chunk,
                )
            });
            assert!(out.iter().all(|&o| o == 1));
            let seen = seen.into_inner().unwrap();
            assert_eq!(seen == points, !sorts, "{swapped} {schedule:?}");
        }
    }

    #[test]
    fn auto_sorts_only_large_bodies_and_batches() {
        let auto = Schedule::Auto;
        let lattice = lattice();
        let resolve = |schedule: Schedule, bytes, remembers, points| {
            let layout = Layout {
                remembers,
                ..layout(&lattice, 0, bytes)
            };
            schedule.resolve(&layout, points)
        };
        let (min, bytes) = (Schedule::AUTO_MIN_POINTS, Schedule::AUTO_BYTES);
        assert_eq!(resolve(auto, bytes, false, 1 << 20), None);
        assert_eq!(
            resolve(auto, bytes + 1, false, min),
            Some(Schedule::AUTO_LOG2_CELLS)
        );
        assert_eq!(resolve(auto, usize::MAX, false, min - 1), None);
        // A body whose chunks remember their cells: any size, still not a small batch.
        assert_eq!(resolve(auto, 0, true, min), Some(Schedule::AUTO_LOG2_CELLS));
        assert_eq!(resolve(auto, usize::MAX, true, min - 1), None);
        assert_eq!(resolve(Schedule::Input, usize::MAX, true, 1 << 20), None);
        assert_eq!(
            resolve(Schedule::Blocked { log2_cells: 4 }, 0, false, 2),
            Some(4)
        );
    }
}
