//! The few collectives the distributed search needs, over plain `u64` words (an `f64` travels as
//! its bits, so that every value arrives bitwise), and what each rank sent.

use mpi::Count;
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition, PartitionMut};
use mpi::traits::*;

/// What one rank sent in a phase: point-to-point payload to other ranks (its own share, kept in
/// place, is not counted) and the collectives it joined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Ranks other than this one that it sent a non-empty payload to.
    pub messages: u64,
    /// Payload bytes sent to other ranks.
    pub bytes: u64,
    /// Collective calls (all-reduce, all-to-all of counts, broadcast) this rank took part in.
    pub collectives: u64,
}

impl Traffic {
    /// The sum of two phases' traffic.
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        Self {
            messages: self.messages + other.messages,
            bytes: self.bytes + other.bytes,
            collectives: self.collectives + other.collectives,
        }
    }
}

/// `send` in place reduced over every rank with `op`.
pub(crate) fn all_reduce<C: Communicator>(
    comm: &C,
    send: &[u64],
    op: SystemOperation,
    traffic: &mut Traffic,
) -> Vec<u64> {
    let mut out = vec![0u64; send.len()];
    comm.all_reduce_into(send, &mut out[..], op);
    traffic.collectives += 1;
    out
}

/// Sends `send`'s words to the ranks, `counts[r]` of them to rank r in rank order, and writes what
/// each rank sent here into `received` (resized), concatenated in rank order; returns the number
/// of words from each rank. Two collectives: the counts (all-to-all), then the words
/// (all-to-all-v).
pub(crate) fn exchange<C: Communicator>(
    comm: &C,
    send: &[u64],
    counts: &[usize],
    received: &mut Vec<u64>,
    traffic: &mut Traffic,
) -> Vec<usize> {
    debug_assert_eq!(counts.iter().sum::<usize>(), send.len());
    let send_counts = counts_of(counts);
    let recv_counts = exchange_counts(comm, &send_counts, traffic);
    let total: usize = recv_counts.iter().map(|&c| c as usize).sum();
    // Every word is overwritten by the exchange: only a length change writes.
    received.resize(total, 0);
    exchange_words(comm, send, &send_counts, received, &recv_counts, traffic);
    recv_counts.iter().map(|&c| c as usize).collect()
}

/// `counts` as MPI counts.
pub(crate) fn counts_of(counts: &[usize]) -> Vec<Count> {
    counts
        .iter()
        .map(|&n| Count::try_from(n).expect("under 2^31 words per rank pair"))
        .collect()
}

/// Collective: how many words each rank will send here, from what each rank will send to each
/// (an all-to-all of counts).
pub(crate) fn exchange_counts<C: Communicator>(
    comm: &C,
    send_counts: &[Count],
    traffic: &mut Traffic,
) -> Vec<Count> {
    let mut recv_counts: Vec<Count> = vec![0; send_counts.len()];
    comm.all_to_all_into(send_counts, &mut recv_counts[..]);
    traffic.collectives += 1;
    recv_counts
}

/// Collective: [`exchange_counts`] with this rank's `key` beside each count, so that every rank
/// receives every rank's key (one per rank, in rank order) and all reach the same verdict on
/// them, in the same all-to-all: a query's check costs no collective of its own.
pub(crate) fn exchange_keyed_counts<C: Communicator>(
    comm: &C,
    send_counts: &[Count],
    key: u64,
    traffic: &mut Traffic,
) -> (Vec<Count>, Vec<u64>) {
    // Each count, then the key's low and high halves (their bits as counts).
    let halves = [key as u32 as Count, (key >> 32) as u32 as Count];
    let send: Vec<Count> = send_counts
        .iter()
        .flat_map(|&n| [n, halves[0], halves[1]])
        .collect();
    let mut received: Vec<Count> = vec![0; send.len()];
    comm.all_to_all_into(&send[..], &mut received[..]);
    traffic.collectives += 1;
    received
        .chunks_exact(3)
        .map(|w| (w[0], u64::from(w[1] as u32) | u64::from(w[2] as u32) << 32))
        .unzip()
}

/// A 64-bit FNV-1a hash of `words`: a fingerprint the ranks compare (the same on every rank for
/// the same words, whatever the build).
pub(crate) fn fingerprint(words: impl IntoIterator<Item = u64>) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for word in words {
        for byte in word.to_le_bytes() {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    hash
}

/// Collective: sends `send`, `send_counts[r]` words to rank r in rank order, and receives
/// `recv_counts[r]` words from rank r into `received` (exactly their sum), in rank order (an
/// all-to-all-v).
pub(crate) fn exchange_words<C: Communicator, T: Equivalence>(
    comm: &C,
    send: &[T],
    send_counts: &[Count],
    received: &mut [T],
    recv_counts: &[Count],
    traffic: &mut Traffic,
) {
    let me = comm.rank() as usize;
    for (rank, &n) in send_counts.iter().enumerate() {
        if rank != me && n > 0 {
            traffic.messages += 1;
            traffic.bytes += (size_of::<T>() * n as usize) as u64;
        }
    }
    traffic.collectives += 1;
    let send_displs = displacements(send_counts);
    let recv_displs = displacements(recv_counts);
    let partition = Partition::new(send, send_counts, &send_displs[..]);
    let mut into = PartitionMut::new(received, recv_counts, &recv_displs[..]);
    comm.all_to_all_varcount_into(&partition, &mut into);
}

/// Each partition's offset: the running sum of the counts before it.
/// MPI takes them as 32-bit counts: past 2^31 − 1 words before a partition, which a wrapping sum
/// would have turned into a negative or wrong offset (MPI then reading or writing outside the
/// buffer), it panics, as the counts do.
pub(crate) fn displacements(counts: &[Count]) -> Vec<Count> {
    counts
        .iter()
        .scan(0i64, |at, &c| {
            let here = Count::try_from(*at)
                .expect("under 2^31 words before any rank's share in one exchange");
            *at += i64::from(c);
            Some(here)
        })
        .collect()
}

/// An order-preserving key of an `f64` (IEEE total order), so that a max or min over ranks is an
/// integer max or min and the extreme arrives bitwise.
#[inline]
pub(crate) fn order_key(value: f64) -> u64 {
    let bits = value.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | (1 << 63)
    }
}

/// The inverse of [`order_key`].
#[inline]
pub(crate) fn from_order_key(key: u64) -> f64 {
    if key >> 63 == 1 {
        f64::from_bits(key & !(1 << 63))
    } else {
        f64::from_bits(!key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displacements_are_the_running_sums_up_to_the_largest_count() {
        assert_eq!(displacements(&[3, 0, 5, 2]), vec![0, 3, 3, 8]);
        // The last share may start at 2^31 − 1 (the buffer's end is no offset).
        assert_eq!(displacements(&[Count::MAX, 1]), vec![0, Count::MAX]);
    }

    /// Before, the running sum wrapped in a release build: a third share at −2^31.
    #[test]
    #[should_panic(expected = "under 2^31 words")]
    fn displacements_past_2_31_words_panic_rather_than_wrap() {
        let _ = displacements(&[Count::MAX, 1, 1]);
    }

    #[test]
    fn order_keys_sort_as_the_total_order_and_invert() {
        let values = [
            f64::NEG_INFINITY,
            -3.5,
            -1e-300,
            -0.0,
            0.0,
            1e-300,
            2.0,
            f64::INFINITY,
        ];
        for pair in values.windows(2) {
            assert!(order_key(pair[0]) < order_key(pair[1]), "{pair:?}");
        }
        for v in values {
            assert_eq!(from_order_key(order_key(v)).to_bits(), v.to_bits());
        }
    }
}
