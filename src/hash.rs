//! 64-bit FNV-1a: the one stable hash nephele keys files and caches by, and pins test outputs
//! with. Unlike [`std::hash::Hash`] its value is fixed by the bytes alone (not by the build,
//! the platform or the standard library's version), so it may go into file names and files.
//!
//! Numbers are hashed as their little-endian bytes ([`Fnv1a::write_u64`]), so a hash is the
//! same on every machine.

/// FNV-1a's 64-bit offset basis: the hash of no bytes.
pub const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a's 64-bit prime.
pub const PRIME: u64 = 0x0000_0100_0000_01b3;

/// A streaming 64-bit FNV-1a hasher: bytes written in pieces hash as if written at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fnv1a {
    state: u64,
}

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a::new()
    }
}

impl Fnv1a {
    /// A hasher that has seen nothing (its state is [`OFFSET_BASIS`]).
    pub const fn new() -> Fnv1a {
        Fnv1a {
            state: OFFSET_BASIS,
        }
    }

    /// Hash `bytes`, in order.
    #[inline]
    pub fn write(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.state = (self.state ^ u64::from(b)).wrapping_mul(PRIME);
        }
        self
    }

    /// Hash `v` as its 8 little-endian bytes.
    #[inline]
    pub fn write_u64(&mut self, v: u64) -> &mut Self {
        self.write(&v.to_le_bytes())
    }

    /// The hash of everything written so far (the hasher may go on).
    pub fn finish(&self) -> u64 {
        self.state
    }
}

/// The 64-bit FNV-1a hash of `bytes`.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    Fnv1a::new().write(bytes).finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_values() {
        // Test vectors of the FNV reference (draft-eastlake-fnv, FNV-1a 64).
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn streaming_equals_one_shot() {
        let mut h = Fnv1a::new();
        h.write(b"foo").write(b"").write(b"bar");
        assert_eq!(h.finish(), fnv1a(b"foobar"));
        let mut n = Fnv1a::default();
        n.write_u64(0x0102_0304_0506_0708);
        assert_eq!(n.finish(), fnv1a(&[8, 7, 6, 5, 4, 3, 2, 1]));
    }
}
