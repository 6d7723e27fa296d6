//! FNV-1a hashes: the model fingerprint in the GUID (128 bit) and the checksum
//! of serialized FMU states (64 bit). Not cryptographic; they detect
//! accidental corruption and mix-ups, which is all an FMU needs. FNV-1a
//! detects every single-byte change: each step is a bijection of the state.

/// FNV-1a, 64 bit, of `bytes`.
pub fn fnv1a_64(bytes: &[u8]) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    bytes.iter().fold(OFFSET, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME))
}

/// Incremental FNV-1a, 128 bit.
#[derive(Debug, Clone, Copy)]
pub struct Fnv1a128(u128);

impl Default for Fnv1a128 {
    fn default() -> Self {
        Fnv1a128(0x6c62_272e_07bb_0142_62b8_2175_6295_c58d)
    }
}

impl Fnv1a128 {
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;

    /// Feeds `bytes`, then a length so that ("ab", "c") and ("a", "bc") differ.
    pub fn field(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes.iter().chain(&(bytes.len() as u64).to_le_bytes()) {
            self.0 = (self.0 ^ u128::from(b)).wrapping_mul(Self::PRIME);
        }
        self
    }

    /// The hash so far.
    pub fn finish(&self) -> u128 {
        self.0
    }
}
