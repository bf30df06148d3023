//! The distributed body (setup) and its locator (queries).
//!
//! # How a point gets the serial answer
//! The lattice is cut into blocks of `block`³ cells. Setup makes each block's **home**: the rank
//! holding most of its active cells (the lowest such rank on a tie), or, for a block with no
//! active cell, the home of the first block near enough to hold its points' cells. A point goes to
//! the home of the block of the lattice cell it lies in (clamped into the lattice), and only there.
//!
//! The serial search of a point x reads and inverts only cells in the box x − [min(u, 0),
//! max(u, 0)] (per axis, u the displacements) widened by a cell or two: the cell holding x (for
//! the predicted displacement), the predicted cell, the cells of the refined guess and the ring
//! walk (`cgcontact`'s `locate/scalar.rs` and `locate/rings.rs`). So each home receives, besides its
//! blocks' cells, a **halo**: every active cell within that reach of its blocks, with its corner
//! displacements. It also receives the cells holding the global extremes of each displacement
//! component, so that its local body has the global displacement range, on which the search's
//! box, inside tolerance and admission test depend. On that local body the core's own search
//! visits exactly the cells it visits on the whole body, in the same order from the same
//! starting guess: the answer (cell, ξ, iterations, residual and inversions, bit for bit) is the
//! serial one, and so is the tie rule on a face shared by two ranks' cells, whatever the
//! partition. No order key needs comparing across ranks.
//!
//! Memory per rank: its home blocks' cells plus the halo (O(own cells) for a compact partition),
//! one `u32` per block for the home map, and the points routed to it.
//!
//! # Adaptive bodies
//! The same steps run on leaves ([`DistributedBody::new_adaptive`]): blocks are blocks of base
//! cells, a leaf belongs to the base cell it lies in, and a point goes to the home of its base
//! cell's block. The core's adaptive search reads only leaves meeting x − the displacement range,
//! in base lattice units, and the leaf holding x: the reach above, in base cells. It also depends
//! on two global quantities, which every local body gets: the displacement range (the leaves
//! holding its extremes) and the finest level (the inside tolerance scales with the finest
//! spacing: a leaf of that level). Its candidates are ordered by distance, then by leaf id: the
//! local body lists its leaves in ascending id in the whole body, so its ties break as the serial
//! body's do, and the answers name leaves by those ids.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use cgcontact::adaptive::MAX_LEVEL;
use cgcontact::glam::DVec2;
use cgcontact::glam::DVec3;
use cgcontact::{
    AdaptiveBody, AdaptiveLocator, Answer, Body, CellId, Contact, Face, GapAnswer, GapFinder, Hit,
    Lattice, LatticeLocator, Leaf, Locator, PointError, Settings,
};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::Error;
use crate::exchange::{
    Traffic, all_reduce, counts_of, displacements, exchange, exchange_keyed_counts, exchange_words,
    fingerprint, from_order_key, order_key,
};

/// The highest id a setup on this process gave a body: each setup agrees with the other ranks on
/// the next one, so that one body has one id on every rank whatever other communicators set up.
static LAST_BODY_ID: AtomicU64 = AtomicU64::new(0);

/// The key a rank whose own query check failed sends in place of its query's.
const FAILED_KEY: u64 = u64::MAX;

/// The kinds of query, in their keys.
const LOCATE_QUERY: u64 = 1;
const GAP_QUERY: u64 = 2;

/// No rank is home to this block: no active cell is near enough to hold a point there.
const NO_HOME: u32 = u32::MAX;

/// Cells added to each side of the reach: the cell holding x, the neighbours whose nodes its corner
/// displacements share, and the inside tolerance's widening.
const MARGIN: f64 = 3.0;

/// Words per cell record: the cell id, then 8 corners × 3 displacement components (f64 bits).
const CELL_WORDS: usize = 25;

/// Words per leaf record: the leaf's id, its level and position (two words), then its corners'
/// displacements as in a cell record.
const LEAF_WORDS: usize = 27;

/// A rank whose leaving points are at most one in this many of its points searches all of them
/// where they lie (see [`DistributedLocator::locate_all_into`]).
const IN_PLACE_SHARE: usize = 32;

/// Points searched at a time before their answers are encoded or merged: 4,096 answers (229 KB)
/// stay in the L2 cache until they are read.
const PIECE: usize = 4096;

/// Words per answer on the way back (see [`encode`]).
const ANSWER_WORDS: usize = 6;

/// Words per gap answer on the way back (see [`encode_gap`]).
const GAP_WORDS: usize = 10;

/// One active cell a rank holds: its lattice cell id and its corners' displacements (VTK order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OwnedCell {
    /// The lattice cell.
    pub cell: CellId,
    /// The displacements of its 8 corners, in VTK order (`Body::cell_displacements`' order).
    pub u: [DVec3; 8],
}

/// One leaf of an adaptive body a rank holds: its id in the whole body, where it lies, and its
/// corners' displacements. Each leaf is held by one rank; the leaves of one base cell may be
/// spread over several.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OwnedLeaf {
    /// The leaf's id in the whole body: its position in the leaves of the serial
    /// `AdaptiveBody`, the cell the answers name.
    pub id: CellId,
    /// Its level and position.
    pub leaf: Leaf,
    /// The displacements of its 8 corners, in VTK order (`AdaptiveBody::cell_displacements`'
    /// order).
    pub u: [DVec3; 8],
}

/// What the setup ships and checks of a cell or a leaf: the same steps build uniform and
/// adaptive local bodies.
trait Record: Copy + std::fmt::Debug {
    /// Words of its record on the wire.
    const WORDS: usize;
    /// Whether the caller names each record (a leaf's id in the whole body), so that the ranks
    /// must check that the names are the body's ids, each once; a lattice cell's name is where
    /// it lies, and a cell given twice meets itself at its block's home.
    const NAMED: bool;
    /// The cell errors and answers name.
    fn name(&self) -> CellId;
    /// Its corners' displacements, VTK order.
    fn u(&self) -> &[DVec3; 8];
    /// Its refinement level (0 for a lattice cell).
    fn level(&self) -> u8;
    /// The base lattice cell it lies in, or why it lies in none.
    fn base_cell(&self, lattice: &Lattice) -> Result<[u32; 3], Error>;
    fn write(&self, out: &mut [u64]);
    fn read(words: &[u64]) -> Self;
    /// The local body of the records kept and received, each with its base cell, and the
    /// extremes (added unless there).
    fn local<'c>(
        lattice: &Lattice,
        records: impl Iterator<Item = (&'c Self, [u32; 3])> + Clone,
        extremes: &[Self],
    ) -> Result<LocalBody, Error>
    where
        Self: 'c;
}

impl Record for OwnedCell {
    const WORDS: usize = CELL_WORDS;
    const NAMED: bool = false;

    fn name(&self) -> CellId {
        self.cell
    }

    fn u(&self) -> &[DVec3; 8] {
        &self.u
    }

    fn level(&self) -> u8 {
        0
    }

    fn base_cell(&self, lattice: &Lattice) -> Result<[u32; 3], Error> {
        lattice.cell_ijk(self.cell).ok_or(Error::CellOutOfRange {
            cell: self.cell,
            cells: lattice.cell_count(),
        })
    }

    fn write(&self, out: &mut [u64]) {
        out[0] = u64::from(self.cell.0);
        write_corners(&self.u, &mut out[1..]);
    }

    fn read(words: &[u64]) -> Self {
        Self {
            cell: CellId(words[0] as u32),
            u: read_corners(&words[1..]),
        }
    }

    fn local<'c>(
        lattice: &Lattice,
        records: impl Iterator<Item = (&'c Self, [u32; 3])> + Clone,
        extremes: &[Self],
    ) -> Result<LocalBody, Error> {
        local_body(lattice, records, extremes).map(LocalBody::Uniform)
    }
}

impl Record for OwnedLeaf {
    const WORDS: usize = LEAF_WORDS;
    const NAMED: bool = true;

    fn name(&self) -> CellId {
        self.id
    }

    fn u(&self) -> &[DVec3; 8] {
        &self.u
    }

    fn level(&self) -> u8 {
        self.leaf.level
    }

    fn base_cell(&self, lattice: &Lattice) -> Result<[u32; 3], Error> {
        let Leaf { level, ijk } = self.leaf;
        let cells = lattice.cells();
        if level > MAX_LEVEL || (0..3).any(|a| u64::from(ijk[a]) >= u64::from(cells[a]) << level) {
            return Err(Error::LeafOutOfRange {
                leaf: self.id,
                level,
                ijk,
            });
        }
        Ok(self.leaf.base())
    }

    fn write(&self, out: &mut [u64]) {
        let Leaf { level, ijk } = self.leaf;
        out[0] = u64::from(self.id.0);
        out[1] = u64::from(level) << 32 | u64::from(ijk[0]);
        out[2] = u64::from(ijk[1]) << 32 | u64::from(ijk[2]);
        write_corners(&self.u, &mut out[3..]);
    }

    fn read(words: &[u64]) -> Self {
        let low = |w: u64| (w & 0xffff_ffff) as u32;
        Self {
            id: CellId(words[0] as u32),
            leaf: Leaf::new(
                (words[1] >> 32) as u8,
                [low(words[1]), (words[2] >> 32) as u32, low(words[2])],
            ),
            u: read_corners(&words[3..]),
        }
    }

    fn local<'c>(
        lattice: &Lattice,
        records: impl Iterator<Item = (&'c Self, [u32; 3])> + Clone,
        extremes: &[Self],
    ) -> Result<LocalBody, Error> {
        local_adaptive_body(lattice, records.map(|(leaf, _)| *leaf).collect(), extremes)
    }
}

/// A rank's local body: lattice cells, or leaves with their ids in the whole body.
// One per setup, held in place: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum LocalBody {
    Uniform(Body),
    Adaptive {
        body: AdaptiveBody,
        /// Each local leaf's id in the whole body (ascending: the local ids keep the serial
        /// order, which breaks the search's ties).
        ids: Vec<CellId>,
    },
}

impl LocalBody {
    fn cell_count(&self) -> usize {
        match self {
            Self::Uniform(body) => body.active_count(),
            Self::Adaptive { body, .. } => body.cell_count(),
        }
    }

    fn heap_bytes(&self) -> usize {
        match self {
            Self::Uniform(body) => body.heap_bytes(),
            Self::Adaptive { body, ids } => body.heap_bytes() + size_of_val(ids.as_slice()),
        }
    }
}

/// The core's locator over a local body.
// The uniform locator is the larger by about 200 bytes; there is one such enum per distributed
// locator, built once and never moved in a loop, so boxing it would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum LocalLocator<'a> {
    Uniform(LatticeLocator<'a>),
    Adaptive {
        locator: AdaptiveLocator<'a>,
        ids: &'a [CellId],
    },
}

impl LocalLocator<'_> {
    /// The local answers of `points` into `out`, naming cells by their ids in the whole body.
    fn locate_all_into(&self, points: &[DVec3], out: &mut Vec<Answer>) {
        match self {
            Self::Uniform(locator) => locator.locate_all_into(points, out),
            Self::Adaptive { locator, ids } => {
                locator.locate_all_into(points, out);
                for answer in out.iter_mut() {
                    if let Ok(Some(hit)) = answer {
                        hit.cell = ids[hit.cell.index()];
                    }
                }
            }
        }
    }

    /// The inversions the local search of `x` tries.
    fn tried(&self, x: DVec3) -> u32 {
        match self {
            Self::Uniform(locator) => locator.locate_counted(x).1,
            Self::Adaptive { locator, .. } => locator.locate_counted(x).1,
        }
    }

    /// A gap finder over the local body.
    fn finder(&self, distance: f64) -> Result<LocalFinder<'_>, Error> {
        Ok(match self {
            Self::Uniform(locator) => LocalFinder::Uniform(GapFinder::new(locator, distance)?),
            Self::Adaptive { locator, ids } => LocalFinder::Adaptive {
                finder: GapFinder::new(locator, distance)?,
                ids,
            },
        })
    }
}

/// The core's gap finder over a local body.
enum LocalFinder<'l> {
    Uniform(GapFinder<'l, LatticeLocator<'l>>),
    Adaptive {
        finder: GapFinder<'l, AdaptiveLocator<'l>>,
        ids: &'l [CellId],
    },
}

impl LocalFinder<'_> {
    /// The local gap answers of `points` into `out`, naming cells by their ids in the whole body.
    fn gap_all_into(&self, points: &[DVec3], out: &mut Vec<GapAnswer>) {
        match self {
            Self::Uniform(finder) => finder.gap_all_into(points, out),
            Self::Adaptive { finder, ids } => {
                finder.gap_all_into(points, out);
                for answer in out.iter_mut() {
                    if let Ok(Some(contact)) = answer {
                        contact.face.cell = ids[contact.face.cell.index()];
                    }
                }
            }
        }
    }
}

/// The setup's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// The core locator's settings, the same on every rank.
    pub settings: Settings,
    /// Edge of the ownership map's blocks, in cells (default 8: 512 cells a block).
    pub block: u32,
    /// The largest search distance of [`DistributedLocator::gap_all_into`]: each home's halo
    /// widens by it, so that it holds every face within that distance of its points (default 0:
    /// the halo of point location only).
    pub gap_distance: f64,
    /// An adaptive body's seam (`AdaptiveBody::seam`: how far its hanging nodes may lie off the
    /// leaves they hang on, as a file's rounding leaves them), given to every rank's local body,
    /// so that the ranks hold the points the serial locator holds (default 0; a uniform body
    /// has none).
    pub seam: DVec3,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            settings: Settings::default(),
            block: 8,
            gap_distance: 0.0,
            seam: DVec3::ZERO,
        }
    }
}

/// What the setup cost this rank.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SetupStats {
    /// Wall time of [`DistributedBody::new`] on this rank, in seconds.
    pub seconds: f64,
    /// Its messages and bytes.
    pub traffic: Traffic,
    /// Cells (leaves, on an adaptive body) this rank was given.
    pub own_cells: usize,
    /// Cells (leaves) of its local body: its home blocks' cells, their halo and the extreme
    /// cells.
    pub local_cells: usize,
    /// Blocks of the ownership map (every rank keeps the whole map: one `u32` each).
    pub blocks: usize,
    /// Blocks this rank is home to.
    pub home_blocks: usize,
    /// Heap bytes of the local body (`Body::heap_bytes`).
    pub body_bytes: usize,
}

/// What one query cost this rank, phase by phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QueryStats {
    /// Points this rank asked about.
    pub points: usize,
    /// Points other ranks (and this one) routed here to search.
    pub searched: usize,
    /// Routing: each point's home, the points sorted by it and sent.
    pub routing_seconds: f64,
    /// The local search: this rank's own points and those received.
    pub search_seconds: f64,
    /// The answers encoded, sent back and put in input order.
    pub return_seconds: f64,
    /// Routing's messages and bytes.
    pub routing: Traffic,
    /// The return's messages and bytes.
    pub returned: Traffic,
}

/// The answers of a distributed query, in the input order of this rank's points.
#[derive(Clone, Debug, Default)]
pub struct Located {
    /// One answer per point, bitwise the serial `LatticeLocator::locate_all`'s on the whole body.
    pub answers: Vec<Answer>,
    /// The Newton inversions each point's search tried, failed ones included (the serial
    /// `Locator::locate_counted`'s count): what `cgcontact locate` writes for points not located.
    pub tried: Vec<u32>,
    /// What it cost this rank.
    pub stats: QueryStats,
    /// Buffers of the routing and the return, kept for the next query.
    scratch: Scratch,
}

/// The contact quantities of a distributed gap query, in the input order of this rank's points.
#[derive(Clone, Debug, Default)]
pub struct Gaps {
    /// One answer per point, bitwise the serial `GapFinder::gap_all_into`'s on the whole body.
    pub answers: Vec<GapAnswer>,
    /// What it cost this rank.
    pub stats: QueryStats,
    /// Buffers of the routing and the return, kept for the next query.
    scratch: Scratch,
    found: Vec<GapAnswer>,
}

/// The query's buffers, reused from one [`DistributedLocator::locate_all_into`] to the next.
#[derive(Clone, Debug, Default)]
struct Scratch {
    /// Each point's bucket: its home rank, or the rank count for a point with no home.
    homes: Vec<u32>,
    /// When the points are grouped, each point's place in the answers: the local search's batch
    /// (own points, then those received), then those coming back, then points with no home.
    /// When they are searched in place, the input index of each leaving point.
    slots: Vec<u32>,
    /// The points, grouped: those leaving (by home rank), this rank's own (when some leave),
    /// each group in input order, then those received (by sending rank). The last two are the
    /// local search's batch.
    work: Vec<DVec3>,
    /// The answers going back, as words.
    send: Vec<u64>,
    /// The answers coming back, as words.
    back: Vec<u64>,
    /// The local search's answers to the piece of points just searched (at most [`PIECE`]).
    found: Vec<Answer>,
}

/// The ownership map: blocks of the lattice and the home rank of each.
#[derive(Clone, Debug)]
struct Blocks {
    /// Edge of a block, in cells.
    size: u32,
    /// The lattice's cells per axis.
    cells: [u32; 3],
    /// Blocks per axis.
    counts: [u32; 3],
    /// The home rank of each block (x fastest), or [`NO_HOME`].
    home: Vec<u32>,
    /// Per axis, each lattice cell coordinate's share of its block's index: the block index of
    /// cell ijk is the sum of the three, with no division per cell.
    stride: [Vec<u32>; 3],
}

impl Blocks {
    /// The map of a lattice of `cells` per axis cut into blocks of `size`³ cells, no block with a
    /// home yet.
    fn new(cells: [u32; 3], size: u32) -> Self {
        let counts = cells.map(|n| n.div_ceil(size));
        let count = counts.iter().map(|&n| n as usize).product();
        let step = [1, counts[0], counts[0] * counts[1]];
        Self {
            size,
            cells,
            counts,
            home: vec![NO_HOME; count],
            stride: [0, 1, 2].map(|a| (0..cells[a]).map(|i| i / size * step[a]).collect()),
        }
    }

    /// Every block's coordinates, in index order (x fastest).
    fn all(&self) -> impl Iterator<Item = [u32; 3]> + '_ {
        let [nx, ny, nz] = self.counts;
        (0..nz).flat_map(move |z| (0..ny).flat_map(move |y| (0..nx).map(move |x| [x, y, z])))
    }

    /// The first and last cell of block `b`, per axis.
    fn cells_of(&self, b: [u32; 3]) -> ([u32; 3], [u32; 3]) {
        let first = b.map(|i| i * self.size);
        let last = [0, 1, 2].map(|a| ((b[a] + 1) * self.size).min(self.cells[a]) - 1);
        (first, last)
    }

    /// The indices of the blocks holding the cells `first − below ..= last + above` per axis,
    /// clamped into the lattice.
    fn around(
        &self,
        (first, last): ([u32; 3], [u32; 3]),
        below: [u32; 3],
        above: [u32; 3],
    ) -> impl Iterator<Item = usize> + '_ {
        let low = [0, 1, 2].map(|a| first[a].saturating_sub(below[a]) / self.size);
        let high =
            [0, 1, 2].map(|a| last[a].saturating_add(above[a]).min(self.cells[a] - 1) / self.size);
        (low[2]..=high[2]).flat_map(move |z| {
            (low[1]..=high[1])
                .flat_map(move |y| (low[0]..=high[0]).map(move |x| self.index([x, y, z])))
        })
    }

    /// The index of the block holding cell `ijk` (in the lattice).
    #[inline]
    fn of_cell_index(&self, ijk: [u32; 3]) -> usize {
        (self.stride[0][ijk[0] as usize]
            + self.stride[1][ijk[1] as usize]
            + self.stride[2][ijk[2] as usize]) as usize
    }

    fn index(&self, b: [u32; 3]) -> usize {
        let [nx, ny, _] = self.counts.map(|n| n as usize);
        b[0] as usize + nx * (b[1] as usize + ny * b[2] as usize)
    }
}

/// A body spread over the ranks of a communicator, ready to build locators: each rank's local body
/// holds what its points' serial searches read (see the module docs).
#[derive(Clone, Debug)]
pub struct DistributedBody {
    /// The same on every rank for one collective setup, and different for another: what the
    /// queries' keys compare.
    id: u64,
    /// This rank and the size of the setup's communicator: the homes name its ranks.
    rank: i32,
    size: i32,
    lattice: Lattice,
    settings: Settings,
    /// `Config::gap_distance`.
    gap_distance: f64,
    blocks: Blocks,
    /// Cells per axis that a point of a block may read below and above the block.
    before: [u32; 3],
    after: [u32; 3],
    /// The local body; `None` when this rank is home to no block with cells.
    body: Option<LocalBody>,
    stats: SetupStats,
}

impl DistributedBody {
    /// Collective: every rank of `comm` calls it, with the same `lattice` and `config` and its own
    /// cells (any subset of the body's active cells; each active cell on exactly one rank; none is
    /// fine). Fails on every rank when any rank's input is bad, naming the fault on that rank.
    pub fn new<C: Communicator>(
        comm: &C,
        lattice: Lattice,
        cells: &[OwnedCell],
        config: Config,
    ) -> Result<Self, Error> {
        Self::setup(comm, lattice, cells, config)
    }

    /// Collective, as [`DistributedBody::new`], for an adaptive body: every rank calls it with
    /// the same base `lattice` and `config` and its own leaves (any subset of the body's leaves,
    /// each leaf on exactly one rank, each with its id in the whole body). Points are routed by
    /// the base cell they lie in; each home receives every leaf of the base cells within its
    /// points' reach, the leaves holding the displacement extremes and a leaf of the finest
    /// level (the search's tolerance depends on the finest spacing), so that the answers are
    /// bitwise those of the serial `AdaptiveLocator` on the whole body.
    ///
    /// `config.block` counts base cells. Where the points crowd into a refined patch, blocks of
    /// about 8 finest cells (8 >> finest level base cells, as `cgcontact-mpi locate` takes by
    /// default) spread them over several homes; blocks of 8 base cells may put the whole patch
    /// in one (docs/scaling.md).
    pub fn new_adaptive<C: Communicator>(
        comm: &C,
        lattice: Lattice,
        leaves: &[OwnedLeaf],
        config: Config,
    ) -> Result<Self, Error> {
        Self::setup(comm, lattice, leaves, config)
    }

    /// The setup of [`DistributedBody::new`] and [`DistributedBody::new_adaptive`]: lattice
    /// cells are leaves of level 0.
    fn setup<C: Communicator, R: Record>(
        comm: &C,
        lattice: Lattice,
        cells: &[R],
        config: Config,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        let mut traffic = Traffic::default();
        let rank = comm.rank();
        let size = comm.size() as usize;
        // 1. Check this rank's cells (one pass, which also finds each cell's lattice coordinates
        //    and the extremes of each displacement component); agree on failure, on a non-empty
        //    body and on the global extremes, all in one reduction (a minimum is the maximum of
        //    the complement of its order key).
        let scan = scan_cells(&lattice, cells, &config);
        let (low, high) = match &scan {
            Ok(scan) => (scan.low.map(|(key, _)| key), scan.high.map(|(key, _)| key)),
            Err(_) => ([u64::MAX; 3], [0; 3]),
        };
        let failed = if scan.is_err() {
            u64::MAX - rank as u64
        } else {
            0
        };
        let finest = scan.as_ref().map_or(0, |scan| scan.finest.0);
        let mut words = vec![failed, u64::from(!cells.is_empty())];
        words.extend(high);
        words.extend(low.map(|k| !k));
        words.push(u64::from(finest));
        // The lattice and the config, which must be the same on every rank (else the maps of
        // blocks differ, and the collectives sized by them): equal when the greatest key is the
        // least (the complement of the greatest complement).
        let key = setup_key(&lattice, &config);
        words.extend([key, !key, LAST_BODY_ID.load(Ordering::Relaxed)]);
        let agreed = all_reduce(comm, &words, SystemOperation::max(), &mut traffic);
        // Every rank takes the same id, and counts on from it.
        let id = agreed[11] + 1;
        LAST_BODY_ID.fetch_max(id, Ordering::Relaxed);
        if agreed[0] != 0 {
            scan?;
            return Err(Error::OnAnotherRank {
                rank: (u64::MAX - agreed[0]) as i32,
            });
        }
        if agreed[9] != !agreed[10] {
            return Err(Error::SetupMismatch);
        }
        if agreed[1] == 0 {
            return Err(Error::EmptyBody);
        }
        if R::NAMED {
            check_names(comm, cells, &mut traffic)?;
        }
        let scan = scan.expect("agreed: no rank failed");
        let high_key: [u64; 3] = [agreed[2], agreed[3], agreed[4]];
        let low_key: [u64; 3] = [!agreed[5], !agreed[6], !agreed[7]];
        let u_high = DVec3::from_array(high_key.map(from_order_key));
        let u_low = DVec3::from_array(low_key.map(from_order_key));
        // The finest level of any leaf (0 on a uniform body).
        let finest = agreed[8] as u8;

        // 2. The cells holding the six extremes (and, on an adaptive body, a leaf of the finest
        //    level: the seventh), sent to every rank: the lowest rank holding each names it, then
        //    one reduction carries them (only that rank's words are non-zero).
        let slots = if finest > 0 { 7 } else { 6 };
        let extremes: Vec<(usize, usize)> = (0..3)
            .filter(|_| !cells.is_empty())
            .flat_map(|a| {
                [
                    (high_key[a] == high[a]).then_some(scan.high[a].1),
                    (low_key[a] == low[a]).then_some(scan.low[a].1),
                ]
            })
            .chain(
                (slots == 7 && !cells.is_empty())
                    .then(|| (scan.finest.0 == finest).then_some(scan.finest.1)),
            )
            .enumerate()
            .filter_map(|(slot, at)| at.map(|at| (slot, at)))
            .collect();
        let mut holders = vec![u64::MAX; slots];
        for &(slot, _) in &extremes {
            holders[slot] = rank as u64;
        }
        let holders = all_reduce(comm, &holders, SystemOperation::min(), &mut traffic);
        let mut extreme_words = vec![0u64; slots * R::WORDS];
        for &(slot, at) in &extremes {
            if holders[slot] == rank as u64 {
                cells[at].write(&mut extreme_words[slot * R::WORDS..]);
            }
        }
        let extreme_words = all_reduce(comm, &extreme_words, SystemOperation::max(), &mut traffic);
        let extremes: Vec<R> = extreme_words.chunks_exact(R::WORDS).map(R::read).collect();

        // 3. The ownership map: one reduction over the blocks of (count of cells, rank) packed so
        //    that the maximum is the rank holding most, the lowest on a tie.
        let mut blocks = Blocks::new(lattice.cells(), config.block);
        let block_count = blocks.home.len();
        let block_of: Vec<u32> = scan
            .ijk
            .iter()
            .map(|&ijk| blocks.of_cell_index(ijk) as u32)
            .collect();
        let mut held = vec![0u64; block_count];
        for &b in &block_of {
            held[b as usize] += 1;
        }
        for words in &mut held {
            if *words > 0 {
                *words = *words << 32 | (u64::from(u32::MAX) - rank as u64);
            }
        }
        let held = all_reduce(comm, &held, SystemOperation::max(), &mut traffic);
        for (home, &words) in blocks.home.iter_mut().zip(&held) {
            if words != 0 {
                *home = u32::MAX - (words & 0xffff_ffff) as u32;
            }
        }
        drop(held);
        let h = lattice.h();
        let reach = |u: DVec3| -> [u32; 3] {
            let cells = ((u.max(DVec3::ZERO) + config.gap_distance) / h).ceil() + MARGIN;
            [0, 1, 2].map(|a| cells[a].min(f64::from(lattice.cells()[a])) as u32)
        };
        // A point at x reads cells near x − u: below x by up to max(u, 0), above by -min(u, 0);
        // its gap search, the faces of cells up to the gap distance D farther (`cgcontact`'s
        // `gap/mod.rs`), whose neighbours' presence the margin covers.
        let before = reach(u_high);
        let after = reach(-u_low);
        adopt_empty_blocks(&mut blocks, before, after);

        // 4. Each cell to every home whose blocks' reach holds it: the one home of its block's
        //    whole neighbourhood, mostly, or else those of the blocks its own reach meets.
        let sole = sole_homes(&blocks, before, after);
        let mut outgoing = vec![Vec::new(); size];
        let mut kept: Vec<u32> = Vec::new();
        let mut homes = Vec::with_capacity(8);
        for (at, (cell, &ijk)) in cells.iter().zip(&scan.ijk).enumerate() {
            homes.clear();
            match sole[block_of[at] as usize] {
                // The homes of the blocks whose points may read this cell.
                SEVERAL => {
                    for at in blocks.around((ijk, ijk), after, before) {
                        let home = blocks.home[at];
                        if home != NO_HOME && !homes.contains(&home) {
                            homes.push(home);
                        }
                    }
                }
                // Not met: the cell's own block has a cell, so a home.
                NO_HOME => {}
                home => homes.push(home),
            }
            for &home in &homes {
                if home == rank as u32 {
                    // This rank's own share stays here, unencoded.
                    kept.push(at as u32);
                    continue;
                }
                let out: &mut Vec<u64> = &mut outgoing[home as usize];
                let at = out.len();
                out.resize(at + R::WORDS, 0);
                cell.write(&mut out[at..]);
            }
        }
        drop(block_of);
        let counts: Vec<usize> = outgoing.iter().map(Vec::len).collect();
        let send = outgoing.concat();
        drop(outgoing);
        let mut received = Vec::new();
        exchange(comm, &send, &counts, &mut received, &mut traffic);
        drop(send);

        // 5. The local body: the cells kept and received and the extreme cells, checked for a
        //    cell held twice and a node given two displacements, then agreed on.
        let home_blocks = blocks.home.iter().filter(|&&h| h == rank as u32).count();
        let halo: Vec<(R, [u32; 3])> = received
            .chunks_exact(R::WORDS)
            .map(|words| {
                let cell = R::read(words);
                // Every rank checked its cells: in range.
                (cell, cell.base_cell(&lattice).unwrap_or([u32::MAX; 3]))
            })
            .collect();
        drop(received);
        // By reference: a cell record is 200 bytes, read twice.
        let local_cells = kept
            .iter()
            .map(|&at| (&cells[at as usize], scan.ijk[at as usize]))
            .chain(halo.iter().map(|(cell, ijk)| (cell, *ijk)));
        let built = if kept.is_empty() && halo.is_empty() {
            Ok(None)
        } else {
            R::local(&lattice, local_cells, &extremes).and_then(|mut body| {
                if let LocalBody::Adaptive { body, .. } = &mut body {
                    body.set_seam(config.seam)?;
                }
                Ok(Some(body))
            })
        };
        drop(halo);
        let failed = if built.is_err() {
            u64::MAX - rank as u64
        } else {
            0
        };
        let agreed = all_reduce(comm, &[failed], SystemOperation::max(), &mut traffic);
        if agreed[0] != 0 {
            built?;
            return Err(Error::OnAnotherRank {
                rank: (u64::MAX - agreed[0]) as i32,
            });
        }
        let body = built.expect("agreed: no rank failed");
        let stats = SetupStats {
            seconds: start.elapsed().as_secs_f64(),
            traffic,
            own_cells: cells.len(),
            local_cells: body.as_ref().map_or(0, LocalBody::cell_count),
            blocks: block_count,
            home_blocks,
            body_bytes: body.as_ref().map_or(0, LocalBody::heap_bytes),
        };
        Ok(Self {
            id,
            rank,
            size: size as i32,
            lattice,
            settings: config.settings,
            gap_distance: config.gap_distance,
            blocks,
            before,
            after,
            body,
            stats,
        })
    }

    /// The lattice.
    #[must_use]
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// This rank's local body (its home blocks' cells, their halo, the extreme cells), `None` when
    /// it is home to no block with cells or the body is adaptive.
    #[must_use]
    pub fn local_body(&self) -> Option<&Body> {
        match &self.body {
            Some(LocalBody::Uniform(body)) => Some(body),
            _ => None,
        }
    }

    /// This rank's local adaptive body (its home blocks' leaves, their halo, the extreme and
    /// finest leaves) and each local leaf's id in the whole body, `None` when it is home to no
    /// block with leaves or the body is uniform.
    #[must_use]
    pub fn local_adaptive_body(&self) -> Option<(&AdaptiveBody, &[CellId])> {
        match &self.body {
            Some(LocalBody::Adaptive { body, ids }) => Some((body, ids)),
            _ => None,
        }
    }

    /// What the setup cost this rank.
    #[must_use]
    pub fn stats(&self) -> SetupStats {
        self.stats
    }

    /// Cells a point may read below and above its block, per axis (the halo's reach).
    #[must_use]
    pub fn reach(&self) -> ([u32; 3], [u32; 3]) {
        (self.before, self.after)
    }

    /// The rank a point is searched on, or `None` when it is not finite or no active cell is near
    /// enough to hold it. Pure index arithmetic on the ownership map.
    #[must_use]
    pub fn home_of(&self, x: DVec3) -> Option<u32> {
        match self.home_index(x) {
            NO_HOME => None,
            home => Some(home),
        }
    }

    /// [`DistributedBody::home_of`] with [`NO_HOME`] for `None`: the routing's per-point step.
    #[inline]
    fn home_index(&self, x: DVec3) -> u32 {
        if !x.is_finite() {
            return NO_HOME;
        }
        let ijk = self.lattice.clamped_cell(self.lattice.lattice_coords(x));
        self.blocks.home[self.blocks.of_cell_index(ijk)]
    }

    /// A locator over this rank's local body (local work: the core's O(nodes) build).
    pub fn locator(&self) -> Result<DistributedLocator<'_>, Error> {
        let local = match &self.body {
            Some(LocalBody::Uniform(body)) => Some(LocalLocator::Uniform(LatticeLocator::new(
                body,
                self.settings,
            )?)),
            Some(LocalBody::Adaptive { body, ids }) => Some(LocalLocator::Adaptive {
                locator: AdaptiveLocator::new(body, self.settings)?,
                ids,
            }),
            None => None,
        };
        Ok(DistributedLocator { body: self, local })
    }
}

/// Queries over a [`DistributedBody`].
#[derive(Clone, Debug)]
pub struct DistributedLocator<'a> {
    body: &'a DistributedBody,
    local: Option<LocalLocator<'a>>,
}

impl DistributedLocator<'_> {
    /// The core locator over this rank's local body, if it has one and it is uniform.
    #[must_use]
    pub fn local(&self) -> Option<&LatticeLocator<'_>> {
        match &self.local {
            Some(LocalLocator::Uniform(locator)) => Some(locator),
            _ => None,
        }
    }

    /// The core locator over this rank's local adaptive body, if it has one (its answers name
    /// local leaves: [`DistributedBody::local_adaptive_body`] maps them to the whole body's).
    #[must_use]
    pub fn local_adaptive(&self) -> Option<&AdaptiveLocator<'_>> {
        match &self.local {
            Some(LocalLocator::Adaptive { locator, .. }) => Some(locator),
            _ => None,
        }
    }

    /// Collective: every rank calls it with its own points (any number, none included), on a
    /// locator of the same [`DistributedBody`]. Each point is searched on its home rank and its
    /// answer comes back here, in input order, bitwise the serial locator's on the whole body.
    /// Runs the local search on the current rayon pool.
    ///
    /// # Errors
    /// [`Error::QueryMismatch`] on every rank when some rank queries another body, or makes
    /// another kind of query at the same time: found in the routing's first exchange, before any
    /// point travels. [`Error::Communicator`] on a rank whose `comm` is not the setup's
    /// ([`Error::OnAnotherRank`] on the others).
    pub fn locate_all<C: Communicator>(
        &self,
        comm: &C,
        points: &[DVec3],
    ) -> Result<Located, Error> {
        let mut located = Located::default();
        self.locate_all_into(comm, points, &mut located)?;
        Ok(located)
    }

    /// [`DistributedLocator::locate_all`] into `out`, whose buffers (answers, counts and the
    /// scratch of routing and return) are reused: a solver loop calling it again allocates
    /// little once the sizes settle.
    ///
    /// When at most one in 32 of this rank's points has another home (always on one rank, and
    /// for a solver asking about points in its own part), all of them are searched where they
    /// lie, with no copy, and the answers of the few that left are replaced by those that come
    /// back. Otherwise the points are grouped by home first.
    ///
    /// # Errors
    /// As [`DistributedLocator::locate_all`]; `out` is then left with no answers.
    pub fn locate_all_into<C: Communicator>(
        &self,
        comm: &C,
        points: &[DVec3],
        out: &mut Located,
    ) -> Result<(), Error> {
        let Located {
            answers,
            tried,
            stats,
            scratch,
        } = out;
        let key = self
            .check_communicator(comm)
            .map(|()| self.query_key(LOCATE_QUERY, 0.0));
        let route = match self.route(comm, points, scratch, stats, key) {
            Ok(route) => route,
            Err(e) => {
                answers.clear();
                tried.clear();
                return Err(e);
            }
        };
        let Scratch {
            slots,
            work,
            send,
            back,
            found,
            homes,
        } = scratch;
        let local = self.local.as_ref();
        let Route {
            own,
            leaving,
            recv,
            in_place,
            ..
        } = route;
        let own_here = route.own_here();
        let me = comm.rank() as usize;

        // Search and return. First the points received, a piece at a time, each piece's answers
        // encoded for the way back while they are in cache; the answers go back (each rank
        // knows how many it sends and gets back, so no counts are exchanged); then this rank's
        // own points, searched in place or, when grouped, a piece at a time, each piece's
        // answers merged into input order with those that came back while they are in cache.
        let start = Instant::now();
        let mut search = std::time::Duration::ZERO;
        let received = &work[leaving + own_here..];
        send.clear();
        send.reserve(ANSWER_WORDS * recv);
        if let Some(local) = local {
            for piece in received.chunks(PIECE) {
                let searching = Instant::now();
                local.locate_all_into(piece, found);
                search += searching.elapsed();
                for (answer, &x) in found.iter().zip(piece) {
                    send.extend_from_slice(&encode(answer, tried_count(local, answer, || x)));
                }
            }
        } else {
            // Only a rank home to some block is asked about points, and such a rank has a body.
            debug_assert!(received.is_empty());
        }
        route.send_back(comm, send, back, ANSWER_WORDS, &mut stats.returned);
        let searching = Instant::now();
        if in_place {
            match local {
                // A point with no home has no active cell within its search's reach, so the
                // local search answers it as the serial one does: refused if not finite, else
                // not found after no inversion. The answers of leaving points are replaced.
                Some(local) => {
                    local.locate_all_into(points, answers);
                    tried.clear();
                    tried.extend(answers.iter().zip(points).enumerate().map(
                        |(i, (answer, &x))| match answer {
                            Ok(Some(hit)) => hit.inversions,
                            // A point with no home tried none; a leaving point's count is
                            // replaced (a second search of a point this body does not hold
                            // would cost more than the first).
                            _ if homes[i] as usize != me => 0,
                            _ => local.tried(x),
                        },
                    ));
                }
                // Every point here has no home or leaves.
                None => {
                    answers.clear();
                    answers.extend(points.iter().map(|&x| no_home(x)));
                    tried.clear();
                    tried.resize(points.len(), 0);
                }
            }
            search += searching.elapsed();
            // The leaving points' answers, from what came back.
            for (&i, words) in slots.iter().zip(back.chunks_exact(ANSWER_WORDS)) {
                (answers[i as usize], tried[i as usize]) = decode(words);
            }
        } else {
            // Every answer is overwritten: only a length change writes.
            if answers.len() != points.len() {
                answers.clear();
                answers.resize(points.len(), Ok(None));
            }
            tried.resize(points.len(), 0);
            // The answers in input order, each from its slot: this rank's own from the piece
            // just searched, the others decoded from what came back, or a point with no home's.
            let returned = own + recv;
            let mut next = 0;
            let mut merge = |found: &[Answer], first: usize, end: usize| {
                while let Some(&slot) = slots.get(next) {
                    let (i, slot) = (next, slot as usize);
                    // Each branch writes in place: an (answer, count) pair built and then moved
                    // cost a store-forwarding stall per point.
                    if slot < own {
                        if slot >= end {
                            break;
                        }
                        answers[i] = found[slot - first];
                        // Searched here: the rank has a body.
                        tried[i] =
                            local.map_or(0, |local| tried_count(local, &answers[i], || points[i]));
                    } else if slot < returned + leaving {
                        let k = slot - returned;
                        (answers[i], tried[i]) =
                            decode(&back[k * ANSWER_WORDS..(k + 1) * ANSWER_WORDS]);
                    } else {
                        (answers[i], tried[i]) = (no_home(points[i]), 0);
                    }
                    next += 1;
                }
            };
            let mine = &work[leaving..leaving + own];
            if let Some(local) = local {
                for (p, piece) in mine.chunks(PIECE).enumerate() {
                    let searching = Instant::now();
                    local.locate_all_into(piece, found);
                    search += searching.elapsed();
                    merge(found, p * PIECE, p * PIECE + piece.len());
                }
            }
            merge(&[], own, own);
        }
        stats.search_seconds = search.as_secs_f64();
        stats.return_seconds = start.elapsed().as_secs_f64() - stats.search_seconds;
        Ok(())
    }

    /// Whether `comm` has the setup's ranks (a query on another communicator would read its
    /// homes as other ranks, or as none).
    fn check_communicator<C: Communicator>(&self, comm: &C) -> Result<(), Error> {
        let (rank, size) = (comm.rank(), comm.size());
        if (rank, size) == (self.body.rank, self.body.size) {
            Ok(())
        } else {
            Err(Error::Communicator {
                rank,
                size,
                setup_rank: self.body.rank,
                setup_size: self.body.size,
            })
        }
    }

    /// The key of a query of `kind` at `distance` on this body: every rank's must be the same.
    fn query_key(&self, kind: u64, distance: f64) -> u64 {
        match fingerprint([self.body.id, kind, distance.to_bits()]) {
            // Never the failed rank's key.
            FAILED_KEY => FAILED_KEY - 1,
            key => key,
        }
    }

    /// The local gap finder at `distance`, or why this rank refuses the query.
    fn finder(&self, distance: f64) -> Result<Option<LocalFinder<'_>>, Error> {
        if !(0.0..=cgcontact::MAX_DISPLACEMENT).contains(&distance) {
            return Err(Error::GapDistance(distance));
        }
        if distance > self.body.gap_distance {
            return Err(Error::GapBeyondSetup {
                asked: distance,
                set_up: self.body.gap_distance,
            });
        }
        self.local
            .as_ref()
            .map(|local| local.finder(distance))
            .transpose()
    }

    /// Collective: the signed gap, closest point and normal of each of this rank's points within
    /// `distance` (the same on every rank, at most the body's `Config::gap_distance`), each
    /// searched on its home by the core's [`GapFinder`], answers in input order, bitwise the
    /// serial `GapFinder::gap_all_into`'s on the whole body. The points travel as for
    /// [`DistributedLocator::locate_all_into`], whose buffers `out` keeps likewise.
    ///
    /// # Errors
    /// On every rank, with `out` left with no answers: [`Error::GapDistance`] or
    /// [`Error::GapBeyondSetup`] on a rank given such a distance ([`Error::OnAnotherRank`] on
    /// the others), and [`Error::QueryMismatch`] when the ranks ask for different distances,
    /// query different bodies or make different kinds of query at the same time;
    /// [`Error::Communicator`] as for [`DistributedLocator::locate_all`]. Each rank
    /// learns of the others' in the routing's first exchange, before any point travels.
    pub fn gap_all_into<C: Communicator>(
        &self,
        comm: &C,
        points: &[DVec3],
        distance: f64,
        out: &mut Gaps,
    ) -> Result<(), Error> {
        let finder = self.finder(distance);
        let key = match &finder {
            Ok(_) => self
                .check_communicator(comm)
                .map(|()| self.query_key(GAP_QUERY, distance)),
            Err(e) => Err(e.clone()),
        };
        let Gaps {
            answers,
            stats,
            scratch,
            found,
        } = out;
        let route = match self.route(comm, points, scratch, stats, key) {
            Ok(route) => route,
            Err(e) => {
                answers.clear();
                return Err(e);
            }
        };
        let finder = finder.expect("agreed: no rank refused the query");
        let (own, leaving, recv) = (route.own, route.leaving, route.recv);
        let Scratch {
            slots,
            work,
            send,
            back,
            ..
        } = scratch;

        // The points received first, their answers sent back; then this rank's own.
        let start = Instant::now();
        let mut search = std::time::Duration::ZERO;
        send.clear();
        found.clear();
        if let Some(finder) = &finder {
            let searching = Instant::now();
            finder.gap_all_into(&work[leaving + route.own_here()..], found);
            search += searching.elapsed();
        }
        for answer in found.iter() {
            send.extend_from_slice(&encode_gap(answer));
        }
        route.send_back(comm, send, back, GAP_WORDS, &mut stats.returned);
        let searching = Instant::now();
        if route.in_place {
            match &finder {
                Some(finder) => finder.gap_all_into(points, answers),
                // Every point here has no home or leaves.
                None => {
                    answers.clear();
                    answers.extend(points.iter().map(|&x| no_home(x)));
                }
            }
            search += searching.elapsed();
            // The leaving points' answers, from what came back.
            for (&i, words) in slots.iter().zip(back.chunks_exact(GAP_WORDS)) {
                answers[i as usize] = decode_gap(words);
            }
        } else {
            found.clear();
            if let Some(finder) = &finder {
                finder.gap_all_into(&work[leaving..leaving + own], found);
            }
            search += searching.elapsed();
            let returned = own + recv;
            answers.clear();
            answers.extend(slots.iter().enumerate().map(|(i, &slot)| {
                let slot = slot as usize;
                if slot < own {
                    found[slot]
                } else if slot < returned + leaving {
                    let k = slot - returned;
                    decode_gap(&back[k * GAP_WORDS..(k + 1) * GAP_WORDS])
                } else {
                    no_home(points[i])
                }
            }));
        }
        stats.search_seconds = search.as_secs_f64();
        stats.return_seconds = start.elapsed().as_secs_f64() - stats.search_seconds;
        Ok(())
    }

    /// Routing: each point's bucket (its home, or `size` for no home), counted; the counts
    /// exchanged; the points grouped by bucket in one branch-free pass (a stable counting sort)
    /// that notes where each one's answer will be; the groups sent as f64 words straight from,
    /// and received straight into, `work`, whose tail is the batch the local search reads. Starts
    /// `stats` afresh and fills its routing half.
    ///
    /// The count exchange also carries this rank's `key` (the query's, or its own refusal of
    /// it): every rank sees every rank's, and all stop before any point travels when a rank
    /// refused (its own error there, [`Error::OnAnotherRank`] elsewhere) or the keys differ.
    fn route<C: Communicator>(
        &self,
        comm: &C,
        points: &[DVec3],
        scratch: &mut Scratch,
        stats: &mut QueryStats,
        key: Result<u64, Error>,
    ) -> Result<Route, Error> {
        let start = Instant::now();
        *stats = QueryStats {
            points: points.len(),
            ..QueryStats::default()
        };
        let Scratch {
            homes, slots, work, ..
        } = scratch;
        let size = comm.size() as usize;
        let me = comm.rank() as usize;
        homes.clear();
        homes.extend(
            points
                .iter()
                .map(|&x| (self.body.home_index(x) as usize).min(size) as u32),
        );
        let mut per = vec![0usize; size + 1];
        for &bucket in homes.iter() {
            per[bucket as usize] += 1;
        }
        let (own, none) = (per[me], per[size]);
        let leaving = points.len() - own - none;
        let sent: Vec<usize> = (0..size)
            .map(|r| if r == me { 0 } else { per[r] })
            .collect();
        let send_counts = counts_of(&sent.iter().map(|&n| 3 * n).collect::<Vec<_>>());
        let (recv_counts, keys) = exchange_keyed_counts(
            comm,
            &send_counts,
            *key.as_ref().unwrap_or(&FAILED_KEY),
            &mut stats.routing,
        );
        if let Some(first) = keys.iter().position(|&k| k == FAILED_KEY) {
            key?;
            return Err(Error::OnAnotherRank { rank: first as i32 });
        }
        let key = key.expect("agreed: no rank refused the query");
        if keys.iter().any(|&k| k != key) {
            return Err(Error::QueryMismatch);
        }
        let from: Vec<usize> = recv_counts.iter().map(|&c| c as usize / 3).collect();
        let recv: usize = from.iter().sum();
        // When few points leave (none, on one rank or for a solver asking about its own part),
        // all of this rank's points are searched where they lie, and the answers of those that
        // left are then replaced by those that come back: the local search answers any point,
        // and a leaving point's local answer costs less than grouping every point.
        let in_place = leaving * IN_PLACE_SHARE <= points.len();
        // The own points in `work` (`Route::own_here`).
        let own_here = if in_place { 0 } else { own };
        assert!(
            u32::try_from(points.len() + recv).is_ok(),
            "under 2^32 points per rank, asked and received"
        );
        // Every place is overwritten below: only a length change writes.
        work.resize(leaving + own_here + recv, DVec3::ZERO);
        if in_place && leaving > 0 {
            // Only the leaving points, grouped by home rank, each remembering its input index.
            let mut place = vec![0usize; size];
            let mut at = 0;
            for r in (0..size).filter(|&r| r != me) {
                place[r] = at;
                at += per[r];
            }
            slots.clear();
            slots.resize(leaving, 0);
            for (i, (&x, &bucket)) in points.iter().zip(homes.iter()).enumerate() {
                let b = bucket as usize;
                if b != me && b != size {
                    work[place[b]] = x;
                    slots[place[b]] = i as u32;
                    place[b] += 1;
                }
            }
        } else if !in_place {
            // Each bucket's next place in `work` (points with no home are not searched) and in
            // the answers.
            let (mut place, mut slot) = (vec![0usize; size + 1], vec![0usize; size + 1]);
            let mut at = 0;
            for r in (0..size).filter(|&r| r != me) {
                (place[r], slot[r]) = (at, own + recv + at);
                at += per[r];
            }
            (place[me], slot[me]) = (leaving, 0);
            // A place past the points, written and never read.
            work.push(DVec3::ZERO);
            (place[size], slot[size]) = (work.len() - 1, own + recv + leaving);
            slots.clear();
            slots.extend(points.iter().zip(homes.iter()).map(|(&x, &bucket)| {
                let b = bucket as usize;
                work[place[b]] = x;
                // Points with no home all write the one place past the points.
                place[b] += usize::from(b != size);
                slot[b] += 1;
                (slot[b] - 1) as u32
            }));
            work.pop();
        }
        {
            let (grouped, received) = work.split_at_mut(leaving + own_here);
            exchange_words(
                comm,
                bytemuck::cast_slice::<DVec3, f64>(&grouped[..leaving]),
                &send_counts,
                bytemuck::cast_slice_mut::<DVec3, f64>(received),
                &recv_counts,
                &mut stats.routing,
            );
        }
        stats.searched = own + recv;
        stats.routing_seconds = start.elapsed().as_secs_f64();
        Ok(Route {
            own,
            leaving,
            recv,
            in_place,
            sent,
            from,
        })
    }
}

/// What routing found and did, for the search and the return.
struct Route {
    /// This rank's points whose home it is, those leaving and those received.
    own: usize,
    leaving: usize,
    recv: usize,
    /// All of this rank's points are searched where they lie (at most one in
    /// [`IN_PLACE_SHARE`] leaves); else they are grouped, own ones in `work`.
    in_place: bool,
    /// Points sent to each rank, and received from each.
    sent: Vec<usize>,
    from: Vec<usize>,
}

impl Route {
    /// The own points in `work`: all of them when grouped, none when searched in place.
    fn own_here(&self) -> usize {
        if self.in_place { 0 } else { self.own }
    }

    /// Collective: the answers of the points received (`send`, `words` words each, in the order
    /// received) back to the ranks that sent them; those of this rank's leaving points into
    /// `back`, in the order they left. Each rank knows how many answers it sends and gets back,
    /// so no counts are exchanged.
    fn send_back<C: Communicator>(
        &self,
        comm: &C,
        send: &[u64],
        back: &mut Vec<u64>,
        words: usize,
        traffic: &mut Traffic,
    ) {
        let counts = |n: &[usize]| counts_of(&n.iter().map(|&n| words * n).collect::<Vec<_>>());
        // Every word is overwritten by the exchange: only a length change writes.
        back.resize(words * self.leaving, 0);
        exchange_words(
            comm,
            send,
            &counts(&self.from),
            back,
            &counts(&self.sent),
            traffic,
        );
    }
}

/// The inversions the serial search tried for `x`, whose answer is `answer`: what `cgcontact
/// locate` writes (a hit's count, else the count of a search that found nothing).
#[inline]
fn tried_count(local: &LocalLocator<'_>, answer: &Answer, x: impl Fn() -> DVec3) -> u32 {
    match answer {
        Ok(Some(hit)) => hit.inversions,
        _ => local.tried(x()),
    }
}

/// The serial answer of a point no active cell is near: refused if not finite, else not found
/// (after no inversion).
fn no_home<T>(x: DVec3) -> Result<Option<T>, PointError> {
    if x.is_finite() {
        Ok(None)
    } else {
        Err(PointError::NonFinite)
    }
}

/// Collective: the answers of every rank's points, concatenated in rank order, on `root`
/// (`None` elsewhere). What a command writing one results file needs.
pub fn gather_located<C: Communicator>(
    comm: &C,
    root: i32,
    located: &Located,
) -> Option<(Vec<Answer>, Vec<u32>)> {
    let mut words = Vec::with_capacity(ANSWER_WORDS * located.answers.len());
    for (answer, &tried) in located.answers.iter().zip(&located.tried) {
        words.extend_from_slice(&encode(answer, tried));
    }
    gather_words(comm, root, &words).map(|all| all.chunks_exact(ANSWER_WORDS).map(decode).unzip())
}

/// Collective: the gap answers of every rank's points, concatenated in rank order, on `root`
/// (`None` elsewhere).
pub fn gather_gaps<C: Communicator>(comm: &C, root: i32, gaps: &Gaps) -> Option<Vec<GapAnswer>> {
    let mut words = Vec::with_capacity(GAP_WORDS * gaps.answers.len());
    for answer in &gaps.answers {
        words.extend_from_slice(&encode_gap(answer));
    }
    gather_words(comm, root, &words)
        .map(|all| all.chunks_exact(GAP_WORDS).map(decode_gap).collect())
}

/// Collective: every rank's `words`, concatenated in rank order, on `root` (`None` elsewhere).
fn gather_words<C: Communicator>(comm: &C, root: i32, words: &[u64]) -> Option<Vec<u64>> {
    use mpi::datatype::PartitionMut;
    let process = comm.process_at_rank(root);
    let count = mpi::Count::try_from(words.len()).expect("under 2^31 words per rank");
    if comm.rank() == root {
        let mut counts = vec![0 as mpi::Count; comm.size() as usize];
        process.gather_into_root(&count, &mut counts[..]);
        let displs = displacements(&counts);
        let total: usize = counts.iter().map(|&c| c as usize).sum();
        let mut all = vec![0u64; total];
        {
            let mut into = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
            process.gather_varcount_into_root(words, &mut into);
        }
        Some(all)
    } else {
        process.gather_into(&count);
        process.gather_varcount_into(words);
        None
    }
}

/// Collective: whether the ranks' records are named 0, 1, …, n − 1 (n records in all), each
/// name once, as the leaves of the whole body are. The count, the greatest name and the sums of
/// the names' first three powers (wrapping) must be those of 0..n: a name out of range, every
/// rank numbering its own leaves from 0, or a name given twice (and so another missing) changes
/// them. Leaves named twice far apart never meet on one rank, where the local body would find
/// them: their answers would name one id for two leaves.
fn check_names<C: Communicator, R: Record>(
    comm: &C,
    records: &[R],
    traffic: &mut Traffic,
) -> Result<(), Error> {
    let mut sums = [records.len() as u64, 0, 0, 0];
    let mut greatest = 0u64;
    for record in records {
        let id = u64::from(record.name().0);
        greatest = greatest.max(id);
        let square = id.wrapping_mul(id);
        sums[1] = sums[1].wrapping_add(id);
        sums[2] = sums[2].wrapping_add(square);
        sums[3] = sums[3].wrapping_add(square.wrapping_mul(id));
    }
    let sums = all_reduce(comm, &sums, SystemOperation::sum(), traffic);
    let greatest = all_reduce(comm, &[greatest], SystemOperation::max(), traffic)[0];
    let n = u128::from(sums[0]);
    // Σ i, Σ i², Σ i³ over 0..n, exactly, then modulo 2^64 as the wrapping sums are.
    let expected = [
        n * n.saturating_sub(1) / 2,
        n.saturating_sub(1) * n * (2 * n).saturating_sub(1) / 6,
        (n * n.saturating_sub(1) / 2).pow(2),
    ]
    .map(|v| v as u64);
    if greatest + 1 != sums[0] || sums[1..] != expected {
        return Err(Error::LeafIds {
            leaves: sums[0],
            greatest,
        });
    }
    Ok(())
}

/// The fingerprint of what every rank must pass a setup alike: the lattice and the config.
fn setup_key(lattice: &Lattice, config: &Config) -> u64 {
    let vector = |v: DVec3| v.to_array().map(f64::to_bits);
    let settings = format!("{:?}", config.settings);
    fingerprint(
        vector(lattice.origin())
            .into_iter()
            .chain(vector(lattice.h()))
            .chain(lattice.cells().map(u64::from))
            .chain([u64::from(config.block), config.gap_distance.to_bits()])
            .chain(settings.bytes().map(u64::from)),
    )
}

/// One rank's cells, checked: each one's lattice coordinates, and the order keys of the lowest and
/// highest value of each displacement component with the index of a cell holding it.
#[derive(Debug)]
struct Scan {
    ijk: Vec<[u32; 3]>,
    low: [(u64, usize); 3],
    high: [(u64, usize); 3],
    /// The deepest level and the index of the first record at it.
    finest: (u8, usize),
}

/// Check one rank's cells (in the lattice, finite displacements) and the block size, in one pass
/// that also gathers what [`Scan`] holds.
fn scan_cells<R: Record>(lattice: &Lattice, cells: &[R], config: &Config) -> Result<Scan, Error> {
    if config.block == 0 || config.block > 1 << 20 {
        return Err(Error::BlockSize(config.block));
    }
    // The core's gap finder takes distances up to MAX_DISPLACEMENT: a body set up for more
    // would fail only at its first gap query, after a setup whose halos spanned the lattice.
    if !(0.0..=cgcontact::MAX_DISPLACEMENT).contains(&config.gap_distance) {
        return Err(Error::GapDistance(config.gap_distance));
    }
    config.settings.validate()?;
    let mut scan = Scan {
        ijk: Vec::with_capacity(cells.len()),
        low: [(u64::MAX, 0); 3],
        high: [(0, 0); 3],
        finest: (0, 0),
    };
    for (at, record) in cells.iter().enumerate() {
        scan.ijk.push(record.base_cell(lattice)?);
        if record.level() > scan.finest.0 {
            scan.finest = (record.level(), at);
        }
        let u = record.u();
        // A finite sum means finite terms; an infinite or NaN one is looked into (finite values
        // may overflow it).
        let sum = u.iter().fold(DVec3::ZERO, |s, &u| s + u);
        if !sum.is_finite()
            && let Some(corner) = u.iter().position(|u| !u.is_finite())
        {
            return Err(Error::NonFiniteDisplacement {
                cell: record.name(),
                corner,
            });
        }
        let (mut low, mut high) = (u[0], u[0]);
        for &u in &u[1..] {
            low = low.min(u);
            high = high.max(u);
        }
        for a in 0..3 {
            // The order keys rank -0 below +0, which a floating-point minimum does not.
            let zero = |v: f64, sign: bool| {
                if v == 0.0
                    && u.iter()
                        .any(|u| u[a] == 0.0 && u[a].is_sign_negative() == sign)
                {
                    if sign { -0.0 } else { 0.0 }
                } else {
                    v
                }
            };
            let key = order_key(zero(low[a], true));
            if key < scan.low[a].0 {
                scan.low[a] = (key, at);
            }
            let key = order_key(zero(high[a], false));
            if key > scan.high[a].0 {
                scan.high[a] = (key, at);
            }
        }
    }
    Ok(scan)
}

/// Give each block without cells the home of the first block (in index order) within its points'
/// reach that has cells, so that its points are searched where their cells are; a block with
/// none near keeps no home (its points are answered "not found" without a search).
fn adopt_empty_blocks(blocks: &mut Blocks, before: [u32; 3], after: [u32; 3]) {
    // A point of block b reads the cells below it by up to `before` and above it by `after`.
    let adopted = blocks
        .all()
        .zip(&blocks.home)
        .map(|(b, &home)| match home {
            NO_HOME => blocks
                .around(blocks.cells_of(b), before, after)
                .map(|at| blocks.home[at])
                .find(|&home| home != NO_HOME)
                .unwrap_or(NO_HOME),
            home => home,
        })
        .collect();
    blocks.home = adopted;
}

/// In [`sole_homes`]: the points reading this block's cells have several homes.
const SEVERAL: u32 = u32::MAX - 1;

/// For each block, the one home of every block whose points may read a cell of it ([`NO_HOME`]
/// when none, [`SEVERAL`] when they differ): the cells of most blocks go to that home alone, with
/// no look at their own reach.
fn sole_homes(blocks: &Blocks, before: [u32; 3], after: [u32; 3]) -> Vec<u32> {
    blocks
        .all()
        .map(|b| {
            // The blocks whose points may read a cell of b: its cells' reach, mirrored.
            let mut homes = blocks
                .around(blocks.cells_of(b), after, before)
                .map(|at| blocks.home[at])
                .filter(|&home| home != NO_HOME);
            match homes.next() {
                None => NO_HOME,
                Some(one) if homes.all(|home| home == one) => one,
                Some(_) => SEVERAL,
            }
        })
        .collect()
}

/// The body of the `cells` kept and received, each with its lattice coordinates (each must come
/// once: a cell held by two ranks arrives twice), and the `extremes` (added unless there), checked
/// for a node given two displacements. Nodes are gathered in a dense table over the cells'
/// bounding box (a compact region; the extreme cells, anywhere, have their few nodes aside), so
/// the cost is linear in the cells, and read out in ascending lattice order: the body's own.
fn local_body<'c>(
    lattice: &Lattice,
    cells: impl Iterator<Item = (&'c OwnedCell, [u32; 3])> + Clone,
    extremes: &[OwnedCell],
) -> Result<Body, Error> {
    let (mut low, mut high, mut count) = ([u32::MAX; 3], [0u32; 3], 0usize);
    for (_, ijk) in cells.clone() {
        count += 1;
        for a in 0..3 {
            low[a] = low[a].min(ijk[a]);
            high[a] = high[a].max(ijk[a]);
        }
    }
    // Nodes of the box: one more than its cells per axis.
    let dims = [0, 1, 2].map(|a| (high[a] - low[a] + 2) as usize);
    let table_nodes = dims[0] * dims[1] * dims[2];
    if table_nodes > 64 * 8 * count.max(1) {
        // Scattered cells (a random partition's halo over a huge lattice): sort instead.
        return local_body_sorted(lattice, cells.map(|(cell, _)| *cell).collect(), extremes);
    }
    let slot = |ijk: [u32; 3]| -> Option<usize> {
        let d = [0, 1, 2].map(|a| ijk[a].checked_sub(low[a]).map(|v| v as usize));
        match d {
            [Some(x), Some(y), Some(z)] if x < dims[0] && y < dims[1] && z < dims[2] => {
                Some(x + dims[0] * (y + dims[1] * z))
            }
            _ => None,
        }
    };
    // Each corner's table entry from the cell's lowest one (VTK order).
    let corner = cgcontact::CORNER_OFFSETS
        .map(|o| o[0] as usize + dims[0] * (o[1] as usize + dims[1] * o[2] as usize));
    let mut table = vec![DVec3::NAN; table_nodes];
    let mut seen = vec![false; table_nodes];
    // One pass without a branch per corner: every corner written (the last writer wins), each
    // write compared with the value it replaces unless that was the NaN of a node not yet written
    // (the displacements are finite: every rank checked its cells). Consecutive writes all equal
    // is every write equal, so `differ` is zero exactly when no node was given two values.
    let mut differ = 0u64;
    for (cell, ijk) in cells.clone() {
        let at = slot(ijk).expect("in the box");
        if std::mem::replace(&mut seen[at], true) {
            return Err(Error::DuplicateCell { cell: cell.cell });
        }
        for (&offset, &u) in corner.iter().zip(&cell.u) {
            let kept = std::mem::replace(&mut table[at + offset], u);
            let bits = (kept.x.to_bits() ^ u.x.to_bits())
                | (kept.y.to_bits() ^ u.y.to_bits())
                | (kept.z.to_bits() ^ u.z.to_bits());
            differ |= if kept.x.is_nan() { 0 } else { bits };
        }
    }
    if differ != 0 {
        // Which node: the first cell, in the order given, one of whose corners differs from
        // the value that stayed.
        for (cell, ijk) in cells {
            let at = slot(ijk).expect("in the box");
            let differs = |(&offset, &u): (&usize, &DVec3)| {
                let kept: DVec3 = table[at + offset];
                kept.to_array().map(f64::to_bits) != u.to_array().map(f64::to_bits)
            };
            if let Some(c) = corner.iter().zip(&cell.u).position(differs) {
                let ijk = [0, 1, 2].map(|a| ijk[a] + cgcontact::CORNER_OFFSETS[c][a]);
                return Err(Error::InconsistentNode {
                    node: lattice.node_index(ijk),
                });
            }
        }
        unreachable!("a node given two values differs from the one that stayed");
    }
    // The cells in ascending id order: the box's rows are the lattice's, in its order.
    let [nx, ny, _] = lattice.cells().map(|n| n as usize);
    let cell_dims = [0, 1, 2].map(|a| dims[a] - 1);
    let mut ids: Vec<CellId> = Vec::with_capacity(count + extremes.len());
    for z in 0..cell_dims[2] {
        for y in 0..cell_dims[1] {
            let row = dims[0] * (y + dims[1] * z);
            let first = low[0] as usize + nx * (low[1] as usize + y + ny * (low[2] as usize + z));
            for x in 0..cell_dims[0] {
                if seen[row + x] {
                    ids.push(CellId((first + x) as u32));
                }
            }
        }
    }
    let mut aside: Vec<(usize, DVec3)> = Vec::new();
    for extreme in extremes {
        let ijk = lattice.cell_ijk(extreme.cell).expect("checked in range");
        // Kept in ascending order, so that the body's sort of the ids finds them sorted.
        let Err(place) = ids.binary_search(&extreme.cell) else {
            continue;
        };
        ids.insert(place, extreme.cell);
        for (c, node) in lattice.corner_nodes(ijk).into_iter().enumerate() {
            let node_ijk = lattice.node_ijk(node).expect("a node of the lattice");
            match slot(node_ijk) {
                Some(at) if table[at].x.is_nan() => table[at] = extreme.u[c],
                Some(_) => {}
                None => aside.push((node, extreme.u[c])),
            }
        }
    }
    drop(seen);
    aside.sort_unstable_by_key(|&(node, _)| node);
    aside.dedup_by_key(|&mut (node, _)| node);
    let mut body = Body::from_cells(*lattice, ids)?;
    // The displacements in ascending lattice node order: the box's, row by row (the lattice's own
    // order within the box), merged with those aside.
    let mut u = Vec::with_capacity(body.node_count());
    let mut aside = aside.into_iter().peekable();
    let [nx, ny, _] = lattice.cells().map(|n| n as usize + 1);
    let mut row = table.chunks_exact(dims[0]);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            let first = lattice.node_index([low[0], low[1] + y as u32, low[2] + z as u32]);
            debug_assert_eq!(
                first,
                low[0] as usize + nx * (low[1] as usize + y + ny * (low[2] as usize + z))
            );
            for (x, value) in row.next().expect("a row per (y, z)").iter().enumerate() {
                if value.x.is_nan() {
                    continue;
                }
                while let Some(&(node, v)) = aside.peek()
                    && node < first + x
                {
                    u.push(v);
                    aside.next();
                }
                u.push(*value);
            }
        }
    }
    u.extend(aside.map(|(_, v)| v));
    body.set_displacements(&u)?;
    Ok(body)
}

/// [`local_body`] by sorting, for cells too scattered for a table over their box.
fn local_body_sorted(
    lattice: &Lattice,
    mut received: Vec<OwnedCell>,
    extremes: &[OwnedCell],
) -> Result<Body, Error> {
    received.sort_unstable_by_key(|c| c.cell);
    if let Some(pair) = received.windows(2).find(|p| p[0].cell == p[1].cell) {
        return Err(Error::DuplicateCell { cell: pair[0].cell });
    }
    let mut cells = received;
    for extreme in extremes {
        if cells
            .binary_search_by_key(&extreme.cell, |c| c.cell)
            .is_err()
        {
            cells.push(*extreme);
        }
    }
    cells.sort_unstable_by_key(|c| c.cell);
    cells.dedup_by_key(|c| c.cell);
    let mut nodes: Vec<(usize, DVec3)> = Vec::with_capacity(8 * cells.len());
    for cell in &cells {
        let ijk = lattice.cell_ijk(cell.cell).expect("checked in range");
        nodes.extend(lattice.corner_nodes(ijk).into_iter().zip(cell.u));
    }
    nodes.sort_unstable_by_key(|&(node, _)| node);
    let bits = |u: DVec3| u.to_array().map(f64::to_bits);
    if let Some(pair) = nodes
        .windows(2)
        .find(|p| p[0].0 == p[1].0 && bits(p[0].1) != bits(p[1].1))
    {
        return Err(Error::InconsistentNode { node: pair[0].0 });
    }
    nodes.dedup_by_key(|&mut (node, _)| node);
    let mut body = Body::from_cells(*lattice, cells.iter().map(|c| c.cell))?;
    body.update_displacements(|node, _, u| {
        let at = nodes
            .binary_search_by_key(&node, |&(n, _)| n)
            .expect("every node of a local cell has its displacement");
        *u = nodes[at].1;
    })?;
    Ok(body)
}

/// The local adaptive body of the `leaves` kept and received (each must come once: a leaf held
/// by two ranks arrives twice) and the `extremes` (added unless there), in ascending id order,
/// so that local ids keep the serial order; checked for a node given two displacements.
fn local_adaptive_body(
    lattice: &Lattice,
    mut leaves: Vec<OwnedLeaf>,
    extremes: &[OwnedLeaf],
) -> Result<LocalBody, Error> {
    leaves.sort_unstable_by_key(|l| l.id);
    if let Some(pair) = leaves.windows(2).find(|p| p[0].id == p[1].id) {
        return Err(Error::DuplicateCell { cell: pair[0].id });
    }
    for extreme in extremes {
        if leaves.binary_search_by_key(&extreme.id, |l| l.id).is_err() {
            leaves.push(*extreme);
        }
    }
    leaves.sort_unstable_by_key(|l| l.id);
    leaves.dedup_by_key(|l| l.id);
    let ids: Vec<CellId> = leaves.iter().map(|l| l.id).collect();
    let global = |local: CellId| ids.get(local.index()).copied().unwrap_or(local);
    let mut body = AdaptiveBody::from_leaves(*lattice, leaves.iter().map(|l| l.leaf).collect())
        .map_err(|e| match e {
            cgcontact::Error::InvalidLeaf { cell, reason } => cgcontact::Error::InvalidLeaf {
                cell: global(cell),
                reason,
            },
            cgcontact::Error::OverlappingCells { cell, other } => {
                cgcontact::Error::OverlappingCells {
                    cell: global(cell),
                    other: global(other),
                }
            }
            e => e,
        })?;
    let mut u = vec![DVec3::NAN; body.node_count()];
    let bits = |u: DVec3| u.to_array().map(f64::to_bits);
    for (local, leaf) in leaves.iter().enumerate() {
        let nodes = body
            .cell_nodes(CellId(local as u32))
            .expect("a leaf of the body");
        for (corner, (&node, &value)) in nodes.iter().zip(&leaf.u).enumerate() {
            let kept = std::mem::replace(&mut u[node], value);
            if !kept.x.is_nan() && bits(kept) != bits(value) {
                return Err(Error::InconsistentCorner {
                    cell: leaf.id,
                    corner,
                });
            }
        }
    }
    body.set_displacements(&u)?;
    Ok(LocalBody::Adaptive { body, ids })
}

/// The 8 corners' displacements as 24 words (f64 bits).
fn write_corners(u: &[DVec3; 8], out: &mut [u64]) {
    for (c, u) in u.iter().enumerate() {
        for a in 0..3 {
            out[3 * c + a] = u[a].to_bits();
        }
    }
}

fn read_corners(words: &[u64]) -> [DVec3; 8] {
    std::array::from_fn(|c| {
        DVec3::new(
            f64::from_bits(words[3 * c]),
            f64::from_bits(words[3 * c + 1]),
            f64::from_bits(words[3 * c + 2]),
        )
    })
}

/// An answer and its tried count as 6 words: kind (0 none, 1 hit, 2 refused) and cell; ξ's bits;
/// iterations and inversions (or tried); the residual's bits.
fn encode(answer: &Answer, tried: u32) -> [u64; ANSWER_WORDS] {
    let mut out = [0; ANSWER_WORDS];
    match answer {
        Ok(Some(hit)) => {
            out[0] = 1 << 32 | u64::from(hit.cell.0);
            out[1] = hit.xi.x.to_bits();
            out[2] = hit.xi.y.to_bits();
            out[3] = hit.xi.z.to_bits();
            out[4] = u64::from(hit.iterations) << 32 | u64::from(hit.inversions);
            out[5] = hit.residual.to_bits();
        }
        Ok(None) => out[4] = u64::from(tried),
        Err(_) => {
            out[0] = 2 << 32;
            out[4] = u64::from(tried);
        }
    }
    out
}

fn decode(words: &[u64]) -> (Answer, u32) {
    let low = |w: u64| (w & 0xffff_ffff) as u32;
    match words[0] >> 32 {
        1 => {
            let hit = Hit {
                cell: CellId(low(words[0])),
                xi: DVec3::new(
                    f64::from_bits(words[1]),
                    f64::from_bits(words[2]),
                    f64::from_bits(words[3]),
                ),
                iterations: (words[4] >> 32) as u32,
                residual: f64::from_bits(words[5]),
                inversions: low(words[4]),
            };
            (Ok(Some(hit)), hit.inversions)
        }
        2 => (Err(PointError::NonFinite), low(words[4])),
        _ => (Ok(None), low(words[4])),
    }
}

/// A gap answer as 10 words: kind (0 none, 1 contact, 2 refused), whether the closest point is
/// inside its face, the local face and the cell; the gap, closest point, normal and (s, t) bits.
fn encode_gap(answer: &GapAnswer) -> [u64; GAP_WORDS] {
    let mut out = [0; GAP_WORDS];
    match answer {
        Ok(Some(c)) => {
            out[0] = 1 << 40
                | u64::from(c.interior) << 39
                | u64::from(c.face.local) << 32
                | u64::from(c.face.cell.0);
            out[1] = c.gap.to_bits();
            for a in 0..3 {
                out[2 + a] = c.point[a].to_bits();
                out[5 + a] = c.normal[a].to_bits();
            }
            out[8] = c.st.x.to_bits();
            out[9] = c.st.y.to_bits();
        }
        Ok(None) => {}
        Err(_) => out[0] = 2 << 40,
    }
    out
}

fn decode_gap(words: &[u64]) -> GapAnswer {
    let v = |a: usize| f64::from_bits(words[a]);
    match words[0] >> 40 {
        1 => Ok(Some(Contact {
            gap: v(1),
            point: DVec3::new(v(2), v(3), v(4)),
            normal: DVec3::new(v(5), v(6), v(7)),
            face: Face {
                cell: CellId((words[0] & 0xffff_ffff) as u32),
                local: (words[0] >> 32 & 0x7f) as u8,
            },
            st: DVec2::new(v(8), v(9)),
            interior: words[0] >> 39 & 1 == 1,
        })),
        2 => Err(PointError::NonFinite),
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_cross_the_wire_bitwise() {
        let hit = Hit {
            cell: CellId(77),
            xi: DVec3::new(-1.0, 0.1 + 0.2, -0.0),
            iterations: 3,
            residual: 1.5e-17,
            inversions: 2,
        };
        for (answer, tried) in [
            (Ok(Some(hit)), 2),
            (Ok(None), 5),
            (Err(PointError::NonFinite), 0),
        ] {
            let (back, count) = decode(&encode(&answer, tried));
            assert_eq!(count, tried);
            match (back, answer) {
                (Ok(Some(a)), Ok(Some(b))) => {
                    assert_eq!(
                        a.xi.to_array().map(f64::to_bits),
                        b.xi.to_array().map(f64::to_bits)
                    );
                    assert_eq!(a, b);
                }
                (a, b) => assert_eq!(a, b),
            }
        }
    }

    #[test]
    fn gap_answers_cross_the_wire_bitwise() {
        let contact = Contact {
            gap: -0.0,
            point: DVec3::new(1e300, -3.25, 0.1 + 0.2),
            normal: DVec3::new(0.0, -1.0, f64::MIN_POSITIVE),
            face: Face {
                cell: CellId(u32::MAX - 1),
                local: 5,
            },
            st: DVec2::new(-1.0, 0.7),
            interior: true,
        };
        let other = Contact {
            interior: false,
            face: Face {
                cell: CellId(0),
                local: 0,
            },
            ..contact
        };
        let bits = |a: &GapAnswer| {
            a.map(|c| {
                c.map(|c| {
                    let mut w = vec![c.gap.to_bits(), c.st.x.to_bits(), c.st.y.to_bits()];
                    w.extend(c.point.to_array().map(f64::to_bits));
                    w.extend(c.normal.to_array().map(f64::to_bits));
                    (w, c.face, c.interior)
                })
            })
        };
        for answer in [
            Ok(Some(contact)),
            Ok(Some(other)),
            Ok(None),
            Err(PointError::NonFinite),
        ] {
            assert_eq!(bits(&decode_gap(&encode_gap(&answer))), bits(&answer));
        }
    }

    #[test]
    fn block_strides_match_the_division() {
        for size in [1, 2, 3, 8] {
            let cells = [7, 5, 9];
            let blocks = Blocks::new(cells, size);
            for k in 0..cells[2] {
                for j in 0..cells[1] {
                    for i in 0..cells[0] {
                        let b = [i / size, j / size, k / size];
                        assert_eq!(blocks.of_cell_index([i, j, k]), blocks.index(b));
                    }
                }
            }
        }
    }

    #[test]
    fn the_scan_finds_the_extremes_and_refuses_what_is_not_finite() {
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [4, 3, 2]).expect("a lattice");
        let cell = |c: u32, u: [DVec3; 8]| OwnedCell { cell: CellId(c), u };
        let mut a = [DVec3::ZERO; 8];
        a[3] = DVec3::new(-0.0, 2.0, 1e308);
        a[5] = DVec3::new(0.0, -1.0, 1e308);
        let mut b = [DVec3::new(0.0, 0.5, -0.0); 8];
        b[6].x = -3.0;
        let cells = [cell(5, a), cell(17, b)];
        let scan = scan_cells(&lattice, &cells, &Config::default())
            .expect("finite: 1e308 + 1e308 overflows only the sum");
        assert_eq!(scan.ijk, vec![[1, 1, 0], [1, 1, 1]]);
        assert_eq!(scan.low[0], (order_key(-3.0), 1));
        assert_eq!(scan.high[0], (order_key(0.0), 0));
        assert_eq!(scan.low[1], (order_key(-1.0), 0));
        assert_eq!(scan.high[1], (order_key(2.0), 0));
        // -0 ranks below +0: the least z is b's -0, not a's +0.
        assert_eq!(scan.low[2], (order_key(-0.0), 1));
        assert_eq!(scan.high[2], (order_key(1e308), 0));
        // Zeros of both signs in one cell: the least is -0, the greatest +0, whatever their places.
        let mixed: [DVec3; 8] = std::array::from_fn(|c| {
            DVec3::new(
                if c == 4 { -0.0 } else { 0.0 },
                if c == 2 { 0.0 } else { -0.0 },
                0.0,
            )
        });
        let scan = scan_cells(&lattice, &[cell(0, mixed)], &Config::default()).expect("finite");
        for a in 0..2 {
            assert_eq!(scan.low[a].0, order_key(-0.0), "axis {a}");
            assert_eq!(scan.high[a].0, order_key(0.0), "axis {a}");
        }
        assert_eq!(scan.low[2].0, order_key(0.0));
        for (corner, bad) in [(2, f64::NAN), (7, f64::INFINITY)] {
            let mut u = a;
            u[corner].y = bad;
            match scan_cells(&lattice, &[cell(1, u)], &Config::default()) {
                Err(Error::NonFiniteDisplacement { cell, corner: c }) => {
                    assert_eq!((cell, c), (CellId(1), corner));
                }
                other => panic!("{other:?}"),
            }
        }
        assert!(matches!(
            scan_cells(&lattice, &[cell(24, a)], &Config::default()),
            Err(Error::CellOutOfRange { .. })
        ));
    }

    /// The local body of some cells and far extreme cells holds every node's displacement, in
    /// the body's order; a node given two displacements and a cell given twice are refused.
    #[test]
    fn the_local_body_gathers_every_node_and_refuses_conflicts() {
        let lattice = Lattice::new(DVec3::new(-3.0, 1.0, 0.5), DVec3::splat(0.5), [9, 8, 7])
            .expect("a lattice");
        // A field over the lattice's nodes: each node's own value.
        let field =
            |node: usize| DVec3::new(node as f64, -(node as f64) * 0.5, 1.0 / (1.0 + node as f64));
        let owned = |ijk: [u32; 3]| OwnedCell {
            cell: lattice.cell_id(ijk),
            u: lattice.corner_nodes(ijk).map(field),
        };
        // A block of cells in the middle (in scrambled order), and extremes: two beyond the
        // block's box in z, one beside it (its nodes fall between the box's in lattice order),
        // one inside it.
        let mut cells: Vec<([u32; 3], OwnedCell)> = Vec::new();
        for k in 2..5 {
            for j in 3..6 {
                for i in 1..4 {
                    cells.push(([i, j, k], owned([i, j, k])));
                }
            }
        }
        cells.reverse();
        cells.swap(3, 17);
        let extremes = [
            owned([8, 0, 6]),
            owned([0, 7, 0]),
            owned([6, 0, 3]),
            owned([2, 4, 3]),
        ];
        let local = |cells: &[([u32; 3], OwnedCell)]| {
            local_body(&lattice, cells.iter().map(|(ijk, c)| (c, *ijk)), &extremes)
        };
        let body = local(&cells).expect("consistent cells");
        assert_eq!(body.active_count(), cells.len() + 3);
        let nodes: Vec<usize> = body.nodes().collect();
        for (node, u) in nodes.iter().zip(body.displacements()) {
            assert_eq!(*u, field(*node), "node {node}");
        }
        assert_eq!(nodes.len(), 4 * 4 * 4 + 3 * 8);
        // A node given two displacements.
        let mut bad = cells.clone();
        bad[5].1.u[6].y += 1e-9;
        let node = lattice.corner_nodes(bad[5].0)[6];
        match local(&bad) {
            Err(Error::InconsistentNode { node: n }) => assert_eq!(n, node),
            other => panic!("{other:?}"),
        }
        // A cell given twice.
        let mut twice = cells.clone();
        twice.push(cells[7]);
        match local(&twice) {
            Err(Error::DuplicateCell { cell }) => assert_eq!(cell, cells[7].1.cell),
            other => panic!("{other:?}"),
        }
    }

    /// `record` written and read back, compared bit for bit.
    fn round_trip<R: Record>(record: R) -> R {
        let mut words = vec![0u64; R::WORDS];
        record.write(&mut words);
        let back = R::read(&words);
        assert_eq!(back.name(), record.name());
        for (a, b) in back.u().iter().zip(record.u()) {
            assert_eq!(
                a.to_array().map(f64::to_bits),
                b.to_array().map(f64::to_bits)
            );
        }
        back
    }

    #[test]
    fn cell_and_leaf_records_keep_every_bit() {
        let u = [0, 1, 2, 3, 4, 5, 6, 7].map(|c| DVec3::new(c as f64 * 0.1, -0.0, 1e-300));
        round_trip(OwnedCell {
            cell: CellId(12345),
            u,
        });
        // The largest level and indices a leaf may have.
        let leaf = Leaf::new(MAX_LEVEL, [u32::MAX, 7, (1 << 21) - 1]);
        let back = round_trip(OwnedLeaf {
            id: CellId(u32::MAX - 1),
            leaf,
            u,
        });
        assert_eq!(back.leaf, leaf);
    }
}
