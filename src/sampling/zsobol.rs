//! Morton-ordered, Owen-scrambled Sobol points over the whole image ("ZSobol"): Ahmed & Wonka 2020,
//! "Screen-space blue-noise diffusion of Monte Carlo sampling error via hierarchical ordering of
//! pixels" (ACM TOG 39(6)), in the form pbrt-v4 gives it (`ZSobolSampler`, Pharr, Jakob &
//! Humphreys, *Physically Based Rendering*, 4th ed., §8.7.7).
//!
//! One Sobol (0, 2)-sequence is shared by the image. Pixel p's samples are the indices
//! `(morton(p) << log2 spp) | sample`: pixels that are close on screen get consecutive blocks of
//! the sequence, so their samples are jointly well stratified and the error left in the image is
//! spread as blue noise rather than white noise. To decorrelate dimensions and pixels, the index
//! is scrambled per dimension by a random permutation of each base-4 digit chosen by a hash of the
//! more significant digits (a nested, Owen-style scramble of the quadtree order, which keeps every
//! aligned block of 4^k indices a block), and the Sobol coordinates are Owen-scrambled with a seed
//! of the dimension (Burley 2020). Each point is therefore uniformly distributed on its own: the
//! estimator stays unbiased.
//!
//! Only the low 32 bits of the scrambled index reach the Sobol generator matrices (as in pbrt-v4,
//! whose matrices are 32 bits wide): for images and sample counts with
//! `2·⌈log₂ max(w, h)⌉ + ⌈log₂ spp⌉ > 32` pixels far apart can share points (still unbiased,
//! their errors correlate).

use super::rng::mix64;

/// The 24 permutations of the 4 digits of a base-4 place.
const PERMUTATIONS: [[u8; 4]; 24] = {
    let mut out = [[0u8; 4]; 24];
    let mut n = 0;
    let mut a = 0;
    while a < 4 {
        let mut b = 0;
        while b < 4 {
            let mut c = 0;
            while c < 4 {
                if a != b && a != c && b != c {
                    out[n] = [a, b, c, 6 - a - b - c];
                    n += 1;
                }
                c += 1;
            }
            b += 1;
        }
        a += 1;
    }
    out
};

/// Interleaves the bits of x (even positions) and y (odd positions): the Morton (Z-order) code.
#[inline]
pub fn morton2(x: u32, y: u32) -> u64 {
    #[inline]
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        v = (v | (v << 1)) & 0x5555_5555_5555_5555;
        v
    }
    spread(x) | (spread(y) << 1)
}

/// ⌈log₂ n⌉ for n ≥ 1.
#[inline]
pub fn ceil_log2(n: u32) -> u32 {
    if n <= 1 {
        0
    } else {
        32 - (n - 1).leading_zeros()
    }
}

/// The scrambled sequence index of one request. `index` is `(morton << log2_spp) | sample`,
/// `digits` the number of base-4 digits it spans (`⌈log₂ res⌉ + ⌈log₂ spp / 2⌉`, at most 32:
/// images up to 65536 pixels a side at any `u32` sample count), `odd` whether log₂ spp is odd
/// (then the least significant place is a single bit, flipped by a hash), and `key` the hash of
/// (seed, dimension). Each digit is permuted by one of the 24 permutations, chosen by a hash of
/// the digits above it, as pbrt-v4's `ZSobolSampler::GetSampleIndex` does. Unlike pbrt, which
/// hashes the whole prefix again at every digit, the hash is carried down from digit to digit
/// (state ← rotl((state ⊕ (digit + 1)) · K, 29)): it is still a function of exactly the digits
/// above, so the scramble stays nested, at a fifth of the instructions (callgrind: the 64-bit
/// finaliser per digit made the sampler 2.7× the stratified one's cost).
///
/// The digits are read from the top of a register rotated by two bits per place and the
/// permuted ones shifted into the result from below, with the permutation a byte table indexed
/// by (permutation, digit): no shift by a variable amount (x86 takes those from `cl` only), 20
/// instructions per place where the loop indexing places by their shift took 25 (objdump). Same digits, same hash chain, so the same index.
#[inline]
pub fn scramble_index(index: u64, digits: u32, odd: bool, key: u64) -> u64 {
    debug_assert!(
        digits <= 32,
        "{digits} base-4 digits do not fit a u64 index"
    );
    let lowest = odd as u32;
    // The full base-4 places below the top; their 2·places bits at the top of x.
    let places = digits.saturating_sub(lowest).min(32);
    let mut x = if places == 0 {
        0
    } else {
        (index >> lowest) << (64 - 2 * places)
    };
    let mut out = 0u64;
    let mut h = key;
    for _ in 0..places {
        x = x.rotate_left(2);
        let digit = x & 3;
        // The state's high word mapped onto [0, 24) by a multiply (Lemire 2019), not `% 24`.
        let p = (((h >> 32) * 24) >> 32) as usize;
        out = (out << 2) | PERMUTATIONS_32[p][digit as usize] as u64;
        h = ((h ^ (digit + 1)).wrapping_mul(0x9E37_79B9_7F4A_7C15)).rotate_left(29);
    }
    if odd {
        let flip = mix64(h) & 1;
        out = (out << 1) | ((index & 1) ^ flip);
    }
    out
}

/// [`PERMUTATIONS`] padded to 32 rows: the row index `(hi · 24) >> 32` of a 32-bit `hi` is
/// below 32 by its bits alone, so the look-up needs no bounds check (rows 24..32 are never
/// chosen).
static PERMUTATIONS_32: [[u8; 4]; 32] = {
    let mut out = [[0u8; 4]; 32];
    let mut p = 0;
    while p < 24 {
        out[p] = PERMUTATIONS[p];
        p += 1;
    }
    out
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_permutation_table_holds_every_permutation_once() {
        let mut seen = std::collections::HashSet::new();
        for p in PERMUTATIONS {
            let mut s = p;
            s.sort();
            assert_eq!(s, [0, 1, 2, 3]);
            assert!(seen.insert(p));
        }
        assert_eq!(seen.len(), 24);
    }

    #[test]
    fn morton_interleaves() {
        assert_eq!(morton2(0, 0), 0);
        assert_eq!(morton2(1, 0), 1);
        assert_eq!(morton2(0, 1), 2);
        assert_eq!(morton2(3, 3), 15);
        assert_eq!(morton2(0xffff_ffff, 0), 0x5555_5555_5555_5555);
        assert_eq!(morton2(5, 9), 0b10_01_00_11);
    }

    #[test]
    fn ceil_log2_rounds_up() {
        let cases = [(1, 0), (2, 1), (3, 2), (4, 2), (5, 3), (64, 6), (65, 7)];
        for (n, l) in cases {
            assert_eq!(ceil_log2(n), l, "{n}");
        }
    }

    /// The scramble is a bijection on every aligned block of 2^bits indices, for even and odd
    /// bit counts, so a pixel's power-of-two samples are one block of the sequence.
    #[test]
    fn the_index_scramble_permutes_aligned_blocks() {
        for (bits, key) in [(6u32, 1u64), (7, 0xdead_beef), (10, 42), (5, 7)] {
            let odd = bits % 2 == 1;
            let digits = bits.div_ceil(2);
            let n = 1u64 << bits;
            let mut seen = vec![false; n as usize];
            for i in 0..n {
                let j = scramble_index(i, digits, odd, key);
                assert!(j < n && !std::mem::replace(&mut seen[j as usize], true));
            }
            // The block of the 4 (or 2) samples sharing all higher digits stays together.
            let low = if odd { 1 } else { 2 };
            for i in 0..n {
                let j = scramble_index(i, digits, odd, key);
                let base = scramble_index(i & !((1 << low) - 1), digits, odd, key);
                assert_eq!(j >> low, base >> low);
            }
        }
    }
}
