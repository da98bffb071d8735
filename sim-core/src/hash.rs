//! 64-bit FNV-1a (Fowler–Noll–Vo), the project's one non-cryptographic hash: the environment's
//! state hash and the images' pixel hash (determinism checks), the checkpoint manifest's file
//! hashes and the run directory's map hash. Changing it changes hashes on disk: old manifests
//! would no longer verify.

/// The FNV-1a 64 offset basis (the hash of no bytes).
const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// The FNV-1a 64 prime.
const PRIME: u64 = 0x0000_0100_0000_01b3;

/// 64-bit FNV-1a of `bytes`. Not cryptographic; it detects corruption: a change of any single
/// byte always changes the hash (each step is a bijection of the state).
#[must_use]
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv1a64::default();
    h.write(bytes);
    h.finish()
}

/// 64-bit FNV-1a fed piece by piece: the hash of the concatenated bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a64(u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self(OFFSET)
    }
}

impl Fnv1a64 {
    /// Feeds `bytes`.
    pub fn write(&mut self, bytes: &[u8]) {
        self.0 = bytes.iter().fold(self.0, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME));
    }

    /// Feeds `x` as its 8 little-endian bytes.
    pub fn write_u64(&mut self, x: u64) {
        self.write(&x.to_le_bytes());
    }

    /// The hash of everything fed so far.
    #[must_use]
    pub fn finish(self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_vectors() {
        // From the FNV reference (Landon Curt Noll's test vectors, FNV-1a 64).
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn feeding_in_pieces_hashes_the_concatenation() {
        let mut h = Fnv1a64::default();
        h.write(b"foo");
        h.write(b"bar");
        assert_eq!(h.finish(), fnv1a64(b"foobar"));
        let mut w = Fnv1a64::default();
        w.write_u64(0x0102_0304_0506_0708);
        assert_eq!(w.finish(), fnv1a64(&[8, 7, 6, 5, 4, 3, 2, 1]));
    }
}
