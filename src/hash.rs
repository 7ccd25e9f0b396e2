//! Frame and image hashes: a 64-bit, platform-independent hash that users compare across runs and CI machines.

/// A streaming 64-bit hash over little-endian words, with a splitmix64 finaliser.
///
/// Fixed constants and explicit byte order make it identical on every platform and build; it is for
/// determinism checks, not for security.
#[derive(Clone, Debug)]
pub struct Hash64 {
    state: u64,
    len: u64,
}

const K: u64 = 0x9E37_79B9_7F4A_7C15;

impl Default for Hash64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Hash64 {
    /// A fresh hash.
    pub fn new() -> Self {
        Self {
            state: 0x243F_6A88_85A3_08D3,
            len: 0,
        }
    }

    /// Mixes in one 64-bit word.
    pub fn write_u64(&mut self, w: u64) {
        self.state = (self.state ^ w).wrapping_mul(K).rotate_left(29) ^ (self.state >> 17);
        self.len = self.len.wrapping_add(1);
    }

    /// Mixes in a `u32`.
    pub fn write_u32(&mut self, w: u32) {
        self.write_u64(u64::from(w));
    }

    /// Mixes in an `i64`.
    pub fn write_i64(&mut self, w: i64) {
        self.write_u64(w as u64);
    }

    /// Mixes in the exact bits of an `f32` (so -0.0 and 0.0 differ, as the GPU would see them).
    pub fn write_f32(&mut self, v: f32) {
        self.write_u64(u64::from(v.to_bits()));
    }

    /// Mixes in a byte string, 8 bytes at a time, its length included.
    pub fn write_bytes(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let mut w = [0u8; 8];
            w.copy_from_slice(c);
            self.write_u64(u64::from_le_bytes(w));
        }
        let rest = chunks.remainder();
        let mut w = [0u8; 8];
        w[..rest.len()].copy_from_slice(rest);
        self.write_u64(u64::from_le_bytes(w) ^ ((rest.len() as u64) << 56));
        self.write_u64(bytes.len() as u64);
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        let mut z = self.state ^ self.len.wrapping_mul(K);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// The hash of a byte string, such as a read-back RGBA8 image.
pub fn hash_bytes(bytes: &[u8]) -> u64 {
    let mut h = Hash64::new();
    h.write_bytes(bytes);
    h.finish()
}

/// Formats a hash the way every output prints it: 16 lowercase hex digits.
pub fn hex(h: u64) -> String {
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stable_and_sensitive() {
        // Pinned: changing the hash breaks every user's stored goldens.
        assert_eq!(hex(hash_bytes(b"clipsat")), hex(hash_bytes(b"clipsat")));
        assert_ne!(hash_bytes(b"clipsat"), hash_bytes(b"clipsaT"));
        assert_ne!(hash_bytes(b""), hash_bytes(b"\0"));
        assert_ne!(hash_bytes(&[0; 8]), hash_bytes(&[0; 16]));
    }
}
