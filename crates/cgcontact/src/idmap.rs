//! A small open-addressing hash map from `u32` ids (lattice nodes or cells) to `u32` values: the
//! storage of sparse bodies, whose memory must grow with their active cells, not their lattice.

use crate::{Error, memory};

/// Key of an empty entry: never a lattice id (a lattice has fewer than 2^32 − 1 nodes).
const EMPTY: u32 = u32::MAX;

/// Ids to values, at most half full, linear probing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct IdMap {
    keys: Vec<u32>,
    values: Vec<u32>,
    mask: usize,
}

impl IdMap {
    /// A map holding `pairs` (distinct keys, none equal to `u32::MAX`).
    pub(crate) fn new(pairs: impl ExactSizeIterator<Item = (u32, u32)>) -> Self {
        let capacity = Self::capacity(pairs.len());
        Self::holding(vec![EMPTY; capacity], vec![0; capacity], pairs)
    }

    /// [`IdMap::new`], or [`Error::OutOfMemory`] naming `what` when its tables cannot be allocated.
    pub(crate) fn try_new(
        pairs: impl ExactSizeIterator<Item = (u32, u32)>,
        what: &'static str,
    ) -> Result<Self, Error> {
        let capacity = Self::capacity(pairs.len());
        let keys = memory::filled(EMPTY, capacity, what)?;
        let values = memory::filled(0, capacity, what)?;
        Ok(Self::holding(keys, values, pairs))
    }

    /// Entries for `len` keys: at most half full.
    fn capacity(len: usize) -> usize {
        (2 * len).next_power_of_two().max(8)
    }

    /// The map of `pairs` in the empty tables `keys` (all `EMPTY`) and `values`, of one
    /// power-of-two length.
    fn holding(keys: Vec<u32>, values: Vec<u32>, pairs: impl Iterator<Item = (u32, u32)>) -> Self {
        let mask = keys.len() - 1;
        let mut map = Self { keys, values, mask };
        for (key, value) in pairs {
            debug_assert_ne!(key, EMPTY);
            let mut i = map.home(key);
            while map.keys[i] != EMPTY && map.keys[i] != key {
                i = (i + 1) & map.mask;
            }
            map.keys[i] = key;
            map.values[i] = value;
        }
        map
    }

    #[inline(always)]
    fn home(&self, key: u32) -> usize {
        // Fibonacci hashing: the high bits of the product spread consecutive ids.
        ((u64::from(key).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize) & self.mask
    }

    /// The value of `key`, if present.
    #[inline(always)]
    pub(crate) fn get(&self, key: u32) -> Option<u32> {
        let mut i = self.home(key);
        loop {
            let k = self.keys[i];
            if k == key {
                return Some(self.values[i]);
            }
            if k == EMPTY {
                return None;
            }
            i = (i + 1) & self.mask;
        }
    }

    /// Bytes on the heap.
    pub(crate) fn heap_bytes(&self) -> usize {
        (self.keys.capacity() + self.values.capacity()) * size_of::<u32>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a plain table: every key found with its value, every other id absent.
    #[test]
    fn answers_as_a_table() {
        let keys: Vec<u32> = (0..5000u32)
            .map(|i| i.wrapping_mul(2_654_435_761) % 1_000_003)
            .collect();
        let mut unique = keys.clone();
        unique.sort_unstable();
        unique.dedup();
        let map = IdMap::new(unique.iter().enumerate().map(|(v, &k)| (k, v as u32)));
        for (v, &k) in unique.iter().enumerate() {
            assert_eq!(map.get(k), Some(v as u32));
        }
        let present: std::collections::HashSet<u32> = unique.iter().copied().collect();
        for id in 0..1_000_003u32 {
            assert_eq!(map.get(id).is_some(), present.contains(&id), "{id}");
        }
        assert_eq!(IdMap::new(std::iter::empty()).get(3), None);
    }
}
