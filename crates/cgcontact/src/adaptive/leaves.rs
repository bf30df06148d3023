//! The leaves of an adaptive body, 8 bytes each: the level in 5 bits, then each index in as many
//! bits as the finest level's lattice needs along its axis. A body whose lattice is too wide for
//! 64 bits (more than about 2^19 finest cells along every axis) keeps 16-byte records instead.

use super::{Leaf, MAX_LEVEL};

/// Bits of the level.
const LEVEL_BITS: u32 = 5;
const _: () = assert!(MAX_LEVEL < 1 << LEVEL_BITS);

#[derive(Clone, Debug)]
pub(super) enum LeafStore {
    /// (level | i << 5 | j << (5 + bits[0]) | k << (5 + bits[0] + bits[1])) per leaf.
    Packed {
        bits: [u32; 3],
        data: Vec<u64>,
    },
    Wide(Vec<Leaf>),
}

impl LeafStore {
    /// The store of `leaves`, all of level at most `finest` and inside a base lattice of `cells`.
    pub(super) fn new(leaves: Vec<Leaf>, cells: [u32; 3], finest: u8) -> Self {
        let bits = cells.map(|n| {
            let top = (u64::from(n) << finest).saturating_sub(1);
            u64::BITS - top.leading_zeros()
        });
        if LEVEL_BITS + bits.iter().sum::<u32>() > u64::BITS {
            return Self::Wide(leaves);
        }
        let data = leaves
            .iter()
            .map(|leaf| {
                u64::from(leaf.level)
                    | u64::from(leaf.ijk[0]) << LEVEL_BITS
                    | u64::from(leaf.ijk[1]) << (LEVEL_BITS + bits[0])
                    | u64::from(leaf.ijk[2]) << (LEVEL_BITS + bits[0] + bits[1])
            })
            .collect();
        Self::Packed { bits, data }
    }

    pub(super) fn len(&self) -> usize {
        match self {
            Self::Packed { data, .. } => data.len(),
            Self::Wide(leaves) => leaves.len(),
        }
    }

    /// Leaf `id`.
    #[inline(always)]
    pub(super) fn get(&self, id: usize) -> Option<Leaf> {
        match self {
            Self::Packed { bits, data } => {
                let v = *data.get(id)?;
                let field = |shift: u32, width: u32| ((v >> shift) & ((1 << width) - 1)) as u32;
                Some(Leaf {
                    level: field(0, LEVEL_BITS) as u8,
                    ijk: [
                        field(LEVEL_BITS, bits[0]),
                        field(LEVEL_BITS + bits[0], bits[1]),
                        field(LEVEL_BITS + bits[0] + bits[1], bits[2]),
                    ],
                })
            }
            Self::Wide(leaves) => leaves.get(id).copied(),
        }
    }

    /// Leaf `id` of a store that has it.
    #[inline(always)]
    pub(super) fn at(&self, id: u32) -> Leaf {
        self.get(id as usize).expect("a leaf id of this body")
    }

    pub(super) fn heap_bytes(&self) -> usize {
        match self {
            Self::Packed { data, .. } => data.capacity() * size_of::<u64>(),
            Self::Wide(leaves) => leaves.capacity() * size_of::<Leaf>(),
        }
    }
}

/// The leaves of an [`super::AdaptiveBody`] in id order: a view that unpacks each leaf as it is
/// read.
#[derive(Clone, Copy)]
pub struct Leaves<'a>(pub(super) &'a LeafStore);

impl<'a> Leaves<'a> {
    /// Number of leaves.
    #[must_use]
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there is no leaf (never, for a body).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.0.len() == 0
    }

    /// Leaf `id`, `None` when out of range.
    #[must_use]
    pub fn get(&self, id: usize) -> Option<Leaf> {
        self.0.get(id)
    }

    /// The leaves in id order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Leaf> + 'a {
        let store = self.0;
        (0..store.len()).map(move |id| store.at(id as u32))
    }

    /// The leaves, copied out.
    #[must_use]
    pub fn to_vec(&self) -> Vec<Leaf> {
        self.iter().collect()
    }
}

impl<'a> IntoIterator for Leaves<'a> {
    type Item = Leaf;
    type IntoIter = Box<dyn ExactSizeIterator<Item = Leaf> + 'a>;

    fn into_iter(self) -> Self::IntoIter {
        Box::new(self.iter())
    }
}

impl PartialEq for Leaves<'_> {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

impl std::fmt::Debug for Leaves<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_come_back_as_stored() {
        let leaves = vec![
            Leaf::new(0, [2, 0, 1]),
            Leaf::new(3, [23, 7, 0]),
            Leaf::new(3, [0, 15, 15]),
            Leaf::new(1, [5, 3, 2]),
        ];
        let packed = LeafStore::new(leaves.clone(), [3, 2, 2], 3);
        assert!(matches!(packed, LeafStore::Packed { .. }));
        // 2^20 base cells per axis refined 20 levels: 3 × 40 bits do not fit.
        let wide = LeafStore::new(leaves.clone(), [1 << 20; 3], 20);
        assert!(matches!(wide, LeafStore::Wide(_)));
        for store in [&packed, &wide] {
            assert_eq!(Leaves(store).to_vec(), leaves);
            assert_eq!(store.get(4), None);
        }
        // Wide packed fields: a level-19 leaf at the far corner of a 2 × 1 × 1 lattice, indices
        // of 20, 19 and 19 bits: 5 + 20 + 19 + 19 = 63 bits.
        let far = vec![Leaf::new(19, [(1 << 20) - 1, (1 << 19) - 1, (1 << 19) - 1])];
        let store = LeafStore::new(far.clone(), [2, 1, 1], 19);
        assert!(matches!(store, LeafStore::Packed { .. }));
        assert_eq!(Leaves(&store).to_vec(), far);
    }
}
