//! Ways a solver may split a body's cells over ranks: the library accepts any split; these three
//! are what the command line offers and what the tests run.

use cgcontact::{CellId, Lattice};

/// How cells are split over ranks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Partition {
    /// Slabs of whole layers across the lattice's longest axis, about equal in the cells given:
    /// a layer goes to rank ⌊(cells given in the layers before it) · P / (cells given)⌋. On a
    /// full block that is the layers [r·n/P, (r+1)·n/P) for rank r; given an adaptive body's
    /// leaves as their base cells, the slabs hold about equal numbers of leaves. With more ranks
    /// than layers, some ranks get none.
    Slabs,
    /// The active cells sorted along a Morton (Z-order) curve of their lattice indices, cut into P
    /// runs of equal count.
    Morton,
    /// Each cell to a rank drawn from a hash of its id: scattered, the worst case for locality.
    Random,
}

impl Partition {
    /// Every partition, in the order the tests run them.
    pub const ALL: [Self; 3] = [Self::Slabs, Self::Morton, Self::Random];

    /// The name the command line takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Slabs => "slabs",
            Self::Morton => "morton",
            Self::Random => "random",
        }
    }

    /// The rank of each of `cells` (cells of `lattice`, in range), for `ranks` ranks (at least
    /// 1). Morton needs every active cell (it cuts by count); the others decide cell by cell.
    #[must_use]
    pub fn owners(self, lattice: &Lattice, cells: &[CellId], ranks: usize) -> Vec<usize> {
        let ranks = ranks.max(1);
        let ijk = |cell: CellId| lattice.cell_ijk(cell).expect("cells of the lattice");
        match self {
            Self::Slabs => {
                let counts = lattice.cells();
                let axis = (0..3).max_by_key(|&a| (counts[a], 3 - a)).unwrap_or(0);
                let layer: Vec<usize> = cells.iter().map(|&c| ijk(c)[axis] as usize).collect();
                // Each layer's rank from the cells before it.
                let mut rank = vec![0usize; counts[axis] as usize];
                for &l in &layer {
                    rank[l] += 1;
                }
                let mut before = 0;
                for slot in &mut rank {
                    let here = *slot;
                    *slot = before * ranks / cells.len().max(1);
                    before += here;
                }
                layer.iter().map(|&l| rank[l]).collect()
            }
            Self::Morton => {
                let mut order: Vec<(u64, usize)> = cells
                    .iter()
                    .enumerate()
                    .map(|(at, &c)| (morton(ijk(c)), at))
                    .collect();
                order.sort_unstable();
                let mut owners = vec![0; cells.len()];
                for (position, &(_, at)) in order.iter().enumerate() {
                    owners[at] = position * ranks / cells.len().max(1);
                }
                owners
            }
            Self::Random => cells
                .iter()
                .map(|c| (mix(u64::from(c.0)) % ranks as u64) as usize)
                .collect(),
        }
    }
}

impl std::str::FromStr for Partition {
    type Err = String;

    fn from_str(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .ok_or_else(|| format!("unknown partition `{name}` (slabs, morton or random)"))
    }
}

/// The Morton code of lattice indices (21 bits per axis, enough for 2 million cells a side).
fn morton(ijk: [u32; 3]) -> u64 {
    let spread = |v: u32| {
        let mut x = u64::from(v) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    };
    spread(ijk[0]) | spread(ijk[1]) << 1 | spread(ijk[2]) << 2
}

/// A 64-bit mix (splitmix64's finaliser): a fixed, well-spread hash of a cell id.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cgcontact::glam::DVec3;

    #[test]
    fn morton_interleaves_the_axes() {
        assert_eq!(morton([1, 0, 0]), 1);
        assert_eq!(morton([0, 1, 0]), 2);
        assert_eq!(morton([0, 0, 1]), 4);
        assert_eq!(morton([3, 3, 3]), 63);
    }

    #[test]
    fn every_partition_gives_each_cell_one_rank_in_range() {
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [3, 7, 2]).unwrap();
        let cells: Vec<CellId> = (0..42).map(CellId).collect();
        for partition in Partition::ALL {
            for ranks in 1..6 {
                let owners = partition.owners(&lattice, &cells, ranks);
                assert_eq!(owners.len(), cells.len());
                assert!(owners.iter().all(|&r| r < ranks), "{partition:?} {ranks}");
            }
        }
        // Slabs across y, the longest axis: on the full lattice, layer l to rank ⌊l·P/7⌋.
        for ranks in 1..10 {
            let slabs = Partition::Slabs.owners(&lattice, &cells, ranks);
            for (&cell, &rank) in cells.iter().zip(&slabs) {
                let y = lattice.cell_ijk(cell).unwrap()[1] as usize;
                assert_eq!(rank, y * ranks / 7, "{ranks} ranks, {cell:?}");
            }
        }
    }

    #[test]
    fn slabs_balance_the_cells_given() {
        // Layer 0 given ten times (an adaptive base cell's leaves), layers 1 to 6 once each.
        let lattice = Lattice::new(DVec3::ZERO, DVec3::ONE, [1, 7, 1]).unwrap();
        let mut cells = vec![CellId(0); 10];
        cells.extend((1..7).map(CellId));
        let slabs = Partition::Slabs.owners(&lattice, &cells, 2);
        // 10 entries on rank 0, 6 on rank 1 (by layer count: layers 0 to 3, 13 against 3).
        assert!(slabs[..10].iter().all(|&r| r == 0), "{slabs:?}");
        assert!(slabs[10..].iter().all(|&r| r == 1), "{slabs:?}");
    }
}
