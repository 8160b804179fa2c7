//! Random numbers for the camera: session ids, SSRCs, first sequence
//! numbers and timestamp origins (RFC 3550 section 5.1 and 8.1 want the
//! last three unpredictable, and a guessable session id lets anyone on the
//! network tear a stream down).
//!
//! A ChaCha20 generator (`rand_chacha`, rust-random's) keyed with SHA-256
//! (`sha2`, RustCrypto's) of the entropy the caller gathers, and re-keyed
//! with each new sample ([`SessionRng::stir`]): what leaves on the wire is
//! ChaCha20 output, from which neither the key nor the samples can be
//! worked back (the xorshift this replaced gave its whole state away in
//! one session id). What the entropy is, and how weak, is the caller's
//! (docs/streaming.md, "Random numbers": on the board, a 200 MHz counter
//! read at events whose timing the network decides).

use rand_chacha::ChaCha20Rng;
use rand_core::{Rng, SeedableRng};
use sha2::{Digest, Sha256};

use super::rtsp::Random;

/// The camera's generator.
pub struct SessionRng {
    rng: ChaCha20Rng,
}

impl SessionRng {
    /// A generator keyed with SHA-256 of `entropy`.
    pub fn new(entropy: &[u8]) -> SessionRng {
        SessionRng { rng: ChaCha20Rng::from_seed(Sha256::digest(entropy).into()) }
    }

    /// Mix `entropy` in: the new key is SHA-256 of 32 bytes of output and
    /// the sample, so what was unpredictable stays so and a good sample
    /// makes the rest unpredictable too. Some thousand instructions: for
    /// events, not packets.
    pub fn stir(&mut self, entropy: &[u8]) {
        let mut old = [0u8; 32];
        self.rng.fill_bytes(&mut old);
        let mut h = Sha256::new();
        h.update(old);
        h.update(entropy);
        self.rng = ChaCha20Rng::from_seed(h.finalize().into());
    }
}

impl Random for SessionRng {
    fn next_u32(&mut self) -> u32 {
        self.rng.next_u32()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_entropy_gives_the_same_numbers_and_a_stir_changes_them() {
        let (mut a, mut b) = (SessionRng::new(b"boot 1234"), SessionRng::new(b"boot 1234"));
        let xs: std::vec::Vec<u32> = (0..4).map(|_| a.next_u32()).collect();
        assert_eq!(xs, (0..4).map(|_| b.next_u32()).collect::<std::vec::Vec<_>>());
        assert_ne!(SessionRng::new(b"boot 1235").next_u32(), SessionRng::new(b"boot 1234").next_u32());
        a.stir(b"connection at 99");
        b.stir(b"connection at 98");
        assert_ne!(a.next_u32(), b.next_u32(), "the sample counts");
    }

    #[test]
    fn the_output_is_not_the_key_stream_of_the_raw_entropy() {
        // A generator keyed with the entropy bytes themselves would be
        // ChaCha20 under a guessable key; the hash stands in between.
        let mut seed = [0u8; 32];
        seed[..9].copy_from_slice(b"boot 1234");
        let mut raw = ChaCha20Rng::from_seed(seed);
        assert_ne!(SessionRng::new(b"boot 1234").next_u32(), raw.next_u32());
    }
}
