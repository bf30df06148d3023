//! Fallible allocation of a body's buffers, which grow with its input: a lattice of 10^9 nodes
//! asks for gigabytes, and an allocation that fails in a plain `Vec` aborts the process. A binding
//! (Python, C) turns [`Error::OutOfMemory`] into its own out-of-memory error instead. An estimate
//! asked for before the build (the bindings probe for 48 bytes a node) cannot do this alone: the
//! allocator's reuse of freed memory decides how much address space the build takes, and with a
//! little less room than that, a build that passed the probe aborted.

use bitvec::vec::BitVec;

use crate::Error;

/// The error for `len` values of `T` that cannot be allocated for `what`.
fn out_of_memory<T>(len: usize, what: &'static str) -> Error {
    Error::OutOfMemory {
        what,
        bytes: len.saturating_mul(size_of::<T>()),
    }
}

/// An empty vector with room for `len` values, or [`Error::OutOfMemory`] naming `what`.
pub(crate) fn with_capacity<T>(len: usize, what: &'static str) -> Result<Vec<T>, Error> {
    let mut out = Vec::new();
    out.try_reserve_exact(len)
        .map_err(|_| out_of_memory::<T>(len, what))?;
    Ok(out)
}

/// `len` copies of `value` (`vec![value; len]`), or [`Error::OutOfMemory`] naming `what`.
pub(crate) fn filled<T: Clone>(value: T, len: usize, what: &'static str) -> Result<Vec<T>, Error> {
    let mut out = with_capacity(len, what)?;
    out.resize(len, value);
    Ok(out)
}

/// The items of `items` in a vector (`collect`), grown as `Vec` grows itself, or
/// [`Error::OutOfMemory`] naming `what`.
pub(crate) fn collected<T>(
    items: impl IntoIterator<Item = T>,
    what: &'static str,
) -> Result<Vec<T>, Error> {
    let items = items.into_iter();
    let mut out = with_capacity(items.size_hint().0, what)?;
    for item in items {
        if out.len() == out.capacity() {
            // `try_reserve` doubles the capacity, as `push` would.
            out.try_reserve(1)
                .map_err(|_| out_of_memory::<T>(out.len().saturating_mul(2), what))?;
        }
        out.push(item);
    }
    Ok(out)
}

/// `len` bits of `bit` (`BitVec::repeat`), or [`Error::OutOfMemory`] naming `what`.
pub(crate) fn bits(bit: bool, len: usize, what: &'static str) -> Result<BitVec, Error> {
    let word = if bit { usize::MAX } else { 0 };
    let words = filled(word, len.div_ceil(usize::BITS as usize), what)?;
    let mut bits = BitVec::from_vec(words);
    bits.truncate(len);
    Ok(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_hold_what_the_infallible_forms_hold() {
        assert_eq!(filled(7u32, 5, "t").unwrap(), vec![7u32; 5]);
        let odd = (0..1000).filter(|k| k % 2 == 1);
        assert_eq!(
            collected(odd.clone(), "t").unwrap(),
            odd.collect::<Vec<_>>()
        );
        for len in [0, 1, 63, 64, 65, 200] {
            for bit in [false, true] {
                assert_eq!(
                    bits(bit, len, "t").unwrap(),
                    BitVec::<usize>::repeat(bit, len)
                );
            }
        }
    }

    #[test]
    fn an_allocation_too_large_is_an_error_naming_it() {
        let e = filled(0u64, usize::MAX / 4, "the test's buffer").unwrap_err();
        assert_eq!(
            e,
            Error::OutOfMemory {
                what: "the test's buffer",
                bytes: usize::MAX
            }
        );
        assert!(e.to_string().starts_with("the test's buffer: "), "{e}");
        assert!(bits(true, usize::MAX - 64, "mask").is_err());
    }
}
