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

/// The arrival times of the frames the board receives, folded into one
/// word: each frame's cycle count at arrival is stirred in (a multiply and
/// a rotate, a few instructions a frame), and the camera's generator takes
/// the word at every new connection ([`SessionRng::stir`]). Where a frame
/// lands in the board's clock depends on the network and the peers, not on
/// the board: two boots of one image, even under QEMU's `-icount` (where
/// the board's own time is its instruction count), see their first frames
/// at other counts. Hand-written: it is a mixing step, not a generator
/// (SplitMix64's constants).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimingPool(u64);

impl TimingPool {
    /// A pool that starts from `seed` (the boot's own count).
    pub const fn new(seed: u64) -> TimingPool {
        TimingPool(seed)
    }

    /// Stir in one arrival's count.
    pub fn add(&mut self, count: u64) {
        let z = (self.0 ^ count).wrapping_add(0x9E37_79B9_7F4A_7C15);
        let z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        self.0 = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB).rotate_left(17);
    }

    /// What the pool holds now.
    pub const fn value(&self) -> u64 {
        self.0
    }
}

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

    #[test]
    fn arrival_times_change_the_pool_and_their_order_counts() {
        let fold = |counts: &[u64]| {
            let mut p = TimingPool::new(7);
            counts.iter().for_each(|&c| p.add(c));
            p.value()
        };
        assert_eq!(fold(&[100, 200]), fold(&[100, 200]), "the same arrivals, the same pool");
        assert_ne!(fold(&[100, 200]), fold(&[100, 201]), "one count apart");
        assert_ne!(fold(&[100, 200]), fold(&[200, 100]), "another order");
        assert_ne!(fold(&[]), fold(&[0]), "an arrival at count 0 still counts");
    }

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
