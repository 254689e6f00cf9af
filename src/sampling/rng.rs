//! PCG32 (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient Statistically Good Algorithms
//! for Random Number Generation") and integer hashes used to derive independent streams from
//! (seed, pixel, sample) without shared state, which keeps images identical for any thread count.

#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6364136223846793005;

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Pcg32 {
        let mut r = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        u32_to_unit_f32(self.next_u32())
    }
}

/// Maps 32 random bits to [0, 1) using the top 24 bits, so 1.0 is never returned.
#[inline]
pub fn u32_to_unit_f32(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// A strong 64-bit mixer (the SplitMix64 / MurmurHash3 finaliser family).
#[inline]
pub fn mix64(mut x: u64) -> u64 {
    x ^= x >> 30;
    x = x.wrapping_mul(0xbf58476d1ce4e5b9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94d049bb133111eb);
    x ^= x >> 31;
    x
}

/// Hashes several words into one 64-bit value.
#[inline]
pub fn hash_words(words: &[u64]) -> u64 {
    let mut h = 0x9E3779B97F4A7C15u64;
    for &w in words {
        h = mix64(h ^ w.wrapping_add(0x9E3779B97F4A7C15).wrapping_add(h << 6));
    }
    h
}

/// A uniform number in [0, 1) that is a pure function of up to eight floats (their bit patterns,
/// packed two per word): a reproducible coin for decisions that must not consume sampler
/// dimensions, such as stochastic transparency and stochastic material mixtures.
#[inline]
pub fn hash_floats_to_unit(values: &[f32]) -> f32 {
    debug_assert!(values.len() <= 8);
    let mut words = [0u64; 4];
    let n = values.len().div_ceil(2).min(4);
    for (w, pair) in words.iter_mut().zip(values.chunks(2)) {
        *w = match *pair {
            [a, b] => (a.to_bits() as u64) << 32 | b.to_bits() as u64,
            [a] => a.to_bits() as u64,
            _ => 0,
        };
    }
    u32_to_unit_f32((hash_words(&words[..n]) >> 32) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_floats_stay_in_range() {
        assert_eq!(u32_to_unit_f32(0), 0.0);
        assert!(u32_to_unit_f32(u32::MAX) < 1.0);
        let mut r = Pcg32::new(1, 2);
        let mean: f64 = (0..100_000).map(|_| r.next_f32() as f64).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
    }

    #[test]
    fn streams_differ() {
        let mut a = Pcg32::new(1, 1);
        let mut b = Pcg32::new(1, 2);
        let same = (0..100).filter(|_| a.next_u32() == b.next_u32()).count();
        assert!(same < 3);
        assert_ne!(hash_words(&[1, 2]), hash_words(&[2, 1]));
    }
}
