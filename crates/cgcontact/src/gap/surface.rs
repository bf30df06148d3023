//! What the gap search asks of a body: its cells near a box, their faces and displacements. The
//! lattice locator's uniform body and the adaptive locator's leaves answer it.

use glam::DVec3;

use crate::adaptive::AdaptiveLocator;
use crate::lattice::{CellId, Lattice};
use crate::locate::{LatticeLocator, Locator};
use crate::reach::{self, Pyramid, Range};
use crate::schedule::Layout;
use crate::{Schedule, Settings};

/// A locator whose body has a boundary surface to measure gaps to: [`LatticeLocator`] and
/// [`AdaptiveLocator`]. Sealed: its methods are the crate's own.
pub trait Surface: Locator + sealed::Faces {}

impl Surface for LatticeLocator<'_> {}
impl Surface for AdaptiveLocator<'_> {}

pub(crate) use sealed::{Cell, Coverage};

pub(crate) mod sealed {
    use super::*;

    /// A cell the search visits: its id, level (0 on uniform bodies) and indices on its level's
    /// lattice.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct Cell {
        pub id: u32,
        pub level: u8,
        pub ijk: [u32; 3],
    }

    /// The displacement ranges of a body's blocks of base cells ([`Faces::block_ranges`]): the
    /// lattice locator's own, borrowed, or built for an adaptive body.
    #[derive(Clone, Debug)]
    pub struct Blocks<'a>(pub(crate) std::borrow::Cow<'a, Pyramid>);

    /// How much of a face is on the boundary surface.
    #[derive(Clone, Debug, PartialEq)]
    pub enum Coverage {
        /// All of it is covered from the other side: not on the surface.
        Covered,
        /// None of it is covered: all of it is on the surface.
        Open,
        /// The squares [s0, t0, s1, t1] (face coordinates) are on the surface, the rest covered.
        Partial(Box<[[f64; 4]]>),
    }

    /// The body's side of the gap search.
    pub trait Faces {
        /// The (base) lattice.
        fn lattice(&self) -> &Lattice;
        /// Every node's displacement.
        fn displacements(&self) -> &[DVec3];
        /// The locator's settings (its precision and inside tolerance decide the sign near the
        /// surface).
        fn locator_settings(&self) -> &Settings;
        /// The spacing of the finest cells (the lattice's on a uniform body).
        fn finest_spacing(&self) -> DVec3;
        /// The batched queries' schedule (the locator's) and the body as it sees it.
        fn schedule(&self) -> (Schedule, Layout<'_>);
        /// The cell of id `id`, if it is an active cell (a leaf).
        fn cell(&self, id: u32) -> Option<Cell>;
        /// The active cell nearest to lattice coordinates `t` (clamped into the lattice), if any.
        fn cell_near(&self, t: DVec3) -> Option<Cell>;
        /// The cell's undeformed lowest corner: the frame its faces are measured in.
        fn cell_origin(&self, cell: Cell) -> DVec3;
        /// The cell's edge lengths.
        fn size(&self, cell: Cell) -> DVec3;
        /// Every active cell whose closed undeformed box meets [`low`, `high`] (lattice
        /// coordinates), each once.
        fn cells_in_box(&self, low: DVec3, high: DVec3, visit: impl FnMut(Cell));
        /// The local faces of `cell` (bit f: face f) that may be on the boundary surface, from
        /// a cheap look at its neighbours; [`Faces::coverage`] settles the others.
        fn open_faces(&self, cell: Cell) -> u8;
        /// How much of local face `face` of `cell`, one of its [`Faces::open_faces`], is on the
        /// boundary surface.
        fn coverage(&self, cell: Cell, face: usize) -> Coverage;
        /// The corner displacements of `cell`, VTK order.
        fn corner_displacements(&self, cell: Cell) -> [DVec3; 8];
        /// The displacement ranges of the body's blocks of base cells (the lattice locator's
        /// octree, `reach.rs`), built only where the whole body's displacements spread (per
        /// axis, `spread`) over more than a few cells, as the locator builds its own: a large
        /// search box is then walked block by block, each block shifted by its own range.
        fn block_ranges(&self, spread: DVec3) -> Option<Blocks<'_>>;
        /// Every active cell of base cell `base` whose closed undeformed box meets [`low`,
        /// `high`] (lattice coordinates), in the order of [`Faces::cells_in_box`].
        fn cells_of_base(&self, base: [u32; 3], low: DVec3, high: DVec3, visit: impl FnMut(Cell));
        /// How far (per axis) the body's faces may be apart where they should meet (an adaptive
        /// body's [`crate::AdaptiveBody::seam`]): the locator's allowance grows by it.
        fn seam(&self) -> DVec3 {
            DVec3::ZERO
        }
        /// Whatever [`Faces::open_faces`] computes once per body, before the first search.
        fn prepare(&self) {}
        /// Whether [`Faces::open_faces`] is a table lookup (cheaper than any bound), so that the
        /// search asks it first.
        const OPEN_FACES_STORED: bool = false;
    }

    /// Cell index range along one axis of the cells (`n` of them) whose closed interval meets
    /// [`low`, `high`]: `None` when none does (or on NaN).
    #[inline]
    pub(in crate::gap) fn axis_range(low: f64, high: f64, n: u32) -> Option<(u32, u32)> {
        if !(high >= 0.0 && low <= f64::from(n)) {
            return None;
        }
        // The cell whose upper face is at `low` meets the closed box too: from ⌈low − 1⌉. No
        // `ceil`/`floor` (libm calls without SSE4.1): truncation is floor for values ≥ 0.
        let below = low - 1.0;
        let lo = if below > 0.0 {
            let t = below as u32;
            t + u32::from(f64::from(t) < below)
        } else {
            0
        };
        Some((lo.min(n - 1), (high as u32).min(n - 1)))
    }

    impl Faces for LatticeLocator<'_> {
        #[inline]
        fn cell_near(&self, t: DVec3) -> Option<Cell> {
            let lattice = self.body().lattice();
            let ijk = lattice.clamped_cell(t);
            let id = lattice.cell_id(ijk);
            self.body().is_active(id).then_some(Cell {
                id: id.0,
                level: 0,
                ijk,
            })
        }

        fn lattice(&self) -> &Lattice {
            self.body().lattice()
        }

        fn displacements(&self) -> &[DVec3] {
            self.body().displacements()
        }

        fn locator_settings(&self) -> &Settings {
            self.settings()
        }

        fn finest_spacing(&self) -> DVec3 {
            self.body().lattice().h()
        }

        fn schedule(&self) -> (Schedule, Layout<'_>) {
            (self.settings().schedule, self.layout())
        }

        fn cell(&self, id: u32) -> Option<Cell> {
            let body = self.body();
            let ijk = body.lattice().cell_ijk(CellId(id))?;
            body.is_active(CellId(id))
                .then_some(Cell { id, level: 0, ijk })
        }

        #[inline]
        fn cell_origin(&self, cell: Cell) -> DVec3 {
            self.body().lattice().node_position(cell.ijk)
        }

        #[inline]
        fn size(&self, _: Cell) -> DVec3 {
            self.body().lattice().h()
        }

        fn cells_in_box(&self, low: DVec3, high: DVec3, mut visit: impl FnMut(Cell)) {
            let lattice = self.body().lattice();
            let n = lattice.cells();
            let full = self.body().active_count() == lattice.cell_count();
            let active = self.body().active_set();
            let mut r = [(0, 0); 3];
            for a in 0..3 {
                match axis_range(low[a], high[a], n[a]) {
                    Some(range) => r[a] = range,
                    None => return,
                }
            }
            let box_cells: u64 = r.iter().map(|&(lo, hi)| u64::from(hi - lo + 1)).product();
            if !full && self.body().box_outnumbers_cells(box_cells) {
                // Far more lattice cells than the body has (a sparse body, a long distance): its
                // active cells in the box, in the same order (ascending id).
                let (low, high) = ([r[0].0, r[1].0, r[2].0], [r[0].1, r[1].1, r[2].1]);
                self.body().for_each_active_in(low, high, |ijk| {
                    visit(Cell {
                        id: lattice.cell_id(ijk).0,
                        level: 0,
                        ijk,
                    });
                });
                return;
            }
            for k in r[2].0..=r[2].1 {
                for j in r[1].0..=r[1].1 {
                    for i in r[0].0..=r[0].1 {
                        let id = lattice.cell_id([i, j, k]);
                        if full || active.contains(id) {
                            visit(Cell {
                                id: id.0,
                                level: 0,
                                ijk: [i, j, k],
                            });
                        }
                    }
                }
            }
        }

        fn block_ranges(&self, _: DVec3) -> Option<Blocks<'_>> {
            // The locator's own, built by the same rule from the same displacements (where they
            // spread, and not on a sparse body whose lattice dwarfs it): borrowed, not built twice.
            self.pyramid()
                .map(|p| Blocks(std::borrow::Cow::Borrowed(p)))
        }

        #[inline]
        fn cells_of_base(&self, ijk: [u32; 3], _: DVec3, _: DVec3, mut visit: impl FnMut(Cell)) {
            let id = self.body().lattice().cell_id(ijk);
            if self.body().is_active(id) {
                visit(Cell {
                    id: id.0,
                    level: 0,
                    ijk,
                });
            }
        }

        /// Exact: a face is open where the cell across is outside the lattice or inactive. On
        /// a body whose every lattice cell is active, only the lattice's own faces are.
        #[inline]
        fn open_faces(&self, cell: Cell) -> u8 {
            let body = self.body();
            let lattice = body.lattice();
            let n = lattice.cells();
            let full = body.active_count() == lattice.cell_count();
            // Decoded once for the 6 neighbours, not at each `is_active` call: on a body with
            // inactive cells (a rank's local body under MPI) the decodes dominated the search.
            let active = body.active_set();
            let mut open = 0;
            for face in 0..6 {
                let axis = face / 2;
                let mut across = cell.ijk;
                let border = if face % 2 == 1 {
                    across[axis] += 1;
                    across[axis] >= n[axis]
                } else {
                    let border = across[axis] == 0;
                    across[axis] = across[axis].wrapping_sub(1);
                    border
                };
                if border || (!full && !active.contains(lattice.cell_id(across))) {
                    open |= 1 << face;
                }
            }
            open
        }

        #[inline]
        fn coverage(&self, _: Cell, _: usize) -> Coverage {
            Coverage::Open
        }

        #[inline]
        fn corner_displacements(&self, cell: Cell) -> [DVec3; 8] {
            self.body().corner_displacements(cell.ijk)
        }
    }

    impl Faces for AdaptiveLocator<'_> {
        #[inline]
        fn cell_near(&self, t: DVec3) -> Option<Cell> {
            let (id, leaf) = self.body().leaf_near(t)?;
            Some(Cell {
                id,
                level: leaf.level,
                ijk: leaf.ijk,
            })
        }

        fn lattice(&self) -> &Lattice {
            self.body().lattice()
        }

        fn displacements(&self) -> &[DVec3] {
            self.body().displacements()
        }

        fn locator_settings(&self) -> &Settings {
            self.settings()
        }

        fn finest_spacing(&self) -> DVec3 {
            let body = self.body();
            body.spacing(body.finest_level())
        }

        fn schedule(&self) -> (Schedule, Layout<'_>) {
            (self.settings().schedule, self.layout())
        }

        fn cell(&self, id: u32) -> Option<Cell> {
            let leaf = self.body().leaves().get(id as usize)?;
            Some(Cell {
                id,
                level: leaf.level,
                ijk: leaf.ijk,
            })
        }

        #[inline]
        fn cell_origin(&self, cell: Cell) -> DVec3 {
            self.body()
                .leaf_origin(crate::Leaf::new(cell.level, cell.ijk))
        }

        #[inline]
        fn size(&self, cell: Cell) -> DVec3 {
            self.body().spacing(cell.level)
        }

        fn cells_in_box(&self, low: DVec3, high: DVec3, mut visit: impl FnMut(Cell)) {
            self.body()
                .for_each_surface_leaf_in_box(low, high, |id, leaf| {
                    visit(Cell {
                        id,
                        level: leaf.level,
                        ijk: leaf.ijk,
                    });
                });
        }

        fn block_ranges(&self, spread: DVec3) -> Option<Blocks<'_>> {
            // Per base cell, the range of its leaves' corner displacements (their hanging
            // corners' constrained values: what the leaves' maps take).
            let body = self.body();
            let lattice = body.lattice();
            let leaves = body.leaves();
            (reach::pyramid_pays(spread, lattice.h()) && lattice.cell_count() <= 64 * leaves.len())
                .then(|| {
                    Blocks(std::borrow::Cow::Owned(Pyramid::from_ranges(
                        lattice.cells(),
                        leaves.iter().enumerate().map(|(id, leaf)| {
                            (leaf.base(), Range::of(&body.leaf_displacements(id as u32)))
                        }),
                    )))
                })
        }

        fn cells_of_base(
            &self,
            base: [u32; 3],
            low: DVec3,
            high: DVec3,
            mut visit: impl FnMut(Cell),
        ) {
            // The box clamped into [b + δ, b + 1 − δ] per axis, δ a quarter of the finest
            // leaves' edge: the forest then looks at base cell b alone, and a leaf of b (its
            // bounds on the finest grid, b + k/2^L) meets the clamped box exactly when it meets
            // the box (`cells_in_box`'s order and leaves, restricted to b).
            let delta = 0.25 * 0.5f64.powi(i32::from(self.body().finest_level()));
            let b = DVec3::new(f64::from(base[0]), f64::from(base[1]), f64::from(base[2]));
            let (lo, hi) = (b + delta, b + (1.0 - delta));
            let (low, high) = (low.clamp(lo, hi), high.clamp(lo, hi));
            self.body()
                .for_each_surface_leaf_in_box(low, high, |id, leaf| {
                    debug_assert_eq!(leaf.base(), base);
                    visit(Cell {
                        id,
                        level: leaf.level,
                        ijk: leaf.ijk,
                    });
                });
        }

        #[inline]
        fn open_faces(&self, cell: Cell) -> u8 {
            self.body().open_faces(cell.id)
        }

        fn prepare(&self) {
            self.body().prepare_open_faces();
        }

        fn seam(&self) -> DVec3 {
            self.body().seam()
        }

        const OPEN_FACES_STORED: bool = true;

        fn coverage(&self, cell: Cell, face: usize) -> Coverage {
            self.body()
                .face_coverage(crate::Leaf::new(cell.level, cell.ijk), face)
        }

        #[inline]
        fn corner_displacements(&self, cell: Cell) -> [DVec3; 8] {
            self.body().leaf_displacements(cell.id)
        }
    }
}
