//! Owen-scrambled Sobol points (Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)).
//!
//! The first two Sobol dimensions (van der Corput and the Pascal-matrix dimension) give a 2D
//! (0, m, 2)-net for every power-of-two prefix. Each 1D or 2D request of a sample stream is
//! "padded" as Burley §4 describes: the sample index is shuffled by a nested uniform scramble with a
//! seed of its own, so different dimensions are decorrelated, and every coordinate is Owen-scrambled
//! with a hash-based nested uniform scramble (the Laine–Karras permutation applied to the reversed
//! bits, Burley §3). Scrambling keeps the net property and makes every point uniformly distributed,
//! so the estimator stays unbiased.
//!
//! Direction numbers: the generator matrices are built from the primitive polynomials and initial
//! values `m_k` of Joe & Kuo 2008 ("Constructing Sobol sequences with better two-dimensional
//! projections", the new-joe-kuo-6.21201 table), of which only the first rows are needed here.

/// (degree s, coefficients a, initial m_1..m_s) for Sobol dimensions 1.. (dimension 0 is the
/// identity matrix), from Joe & Kuo's table.
const JOE_KUO: [(u32, u32, [u32; 3]); 3] =
    [(1, 0, [1, 0, 0]), (2, 1, [1, 3, 0]), (3, 1, [1, 3, 1])];

/// Number of Sobol dimensions available.
pub const DIMENSIONS: usize = 1 + JOE_KUO.len();

/// Generator matrices as 32 direction numbers each (bit 31 is the most significant).
fn directions() -> &'static [[u32; 32]; DIMENSIONS] {
    static DIRS: std::sync::OnceLock<[[u32; 32]; DIMENSIONS]> = std::sync::OnceLock::new();
    DIRS.get_or_init(|| {
        let mut v = [[0u32; 32]; DIMENSIONS];
        for (k, d) in v[0].iter_mut().enumerate() {
            *d = 1u32 << (31 - k);
        }
        for (dim, &(s, a, m)) in JOE_KUO.iter().enumerate() {
            let s = s as usize;
            let dirs = &mut v[dim + 1];
            for k in 0..s {
                dirs[k] = m[k] << (31 - k);
            }
            // Bratley & Fox 1988, eq. for v_k from the primitive polynomial's coefficients.
            for k in s..32 {
                let mut x = dirs[k - s] ^ (dirs[k - s] >> s);
                for j in 1..s {
                    if (a >> (s - 1 - j)) & 1 == 1 {
                        x ^= dirs[k - j];
                    }
                }
                dirs[k] = x;
            }
        }
        v
    })
}

/// The `index`-th Sobol point's coordinate in dimension `dim` as 32 fixed-point bits. The two
/// dimensions the sampler uses need no table: 0 is the bit reversal, 1 the Pascal matrix.
#[inline]
pub fn sobol(index: u32, dim: usize) -> u32 {
    match dim {
        0 => index.reverse_bits(),
        1 => sobol_dim1(index),
        _ => sobol_from_table(index, dim),
    }
}

/// [`sobol`] from the generator matrix's direction numbers (any dimension).
fn sobol_from_table(index: u32, dim: usize) -> u32 {
    let dirs = &directions()[dim.min(DIMENSIONS - 1)];
    let mut x = 0u32;
    let mut i = index;
    let mut k = 0;
    while i != 0 {
        if i & 1 == 1 {
            x ^= dirs[k];
        }
        i >>= 1;
        k += 1;
    }
    x
}

/// Laine & Karras 2011's hash-based permutation, which only lets bits flip depending on less
/// significant bits (constants from Burley 2020, listing 2).
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50b47c);
    x ^= x.wrapping_mul(0xb82f1e52);
    x ^= x.wrapping_mul(0xc7afe638);
    x ^= x.wrapping_mul(0x8d22f6e6);
    x
}

/// Owen's nested uniform scramble of a 32-bit fixed-point number (Burley 2020, listing 3).
#[inline]
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// Dimension 1 of the Sobol sequence (the Pascal matrix: v₀ = 2³¹, v_k = v_{k−1} ⊕ v_{k−1} ≫ 1)
/// without the direction table.
#[inline]
const fn sobol_dim1(mut index: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut x = 0u32;
    while index != 0 {
        if index & 1 == 1 {
            x ^= v;
        }
        index >>= 1;
        v ^= v >> 1;
    }
    x
}

/// [`sobol`] in dimension 1 with its bits reversed, by four byte tables (the generator matrix is
/// linear over GF(2): four look-ups and three XORs instead of a loop over the index's bits, which
/// span the whole image for ZSobol), of reversed entries because the Owen scramble works on
/// reversed bits and x86 has no single bit-reversal instruction.
#[inline]
pub fn sobol_dim1_reversed(i: u32) -> u32 {
    DIM1_BYTES_REV[0][(i & 0xff) as usize]
        ^ DIM1_BYTES_REV[1][((i >> 8) & 0xff) as usize]
        ^ DIM1_BYTES_REV[2][((i >> 16) & 0xff) as usize]
        ^ DIM1_BYTES_REV[3][(i >> 24) as usize]
}

static DIM1_BYTES_REV: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            t[k][b] = sobol_dim1((b as u32) << (8 * k)).reverse_bits();
            b += 1;
        }
        k += 1;
    }
    t
};

/// Owen-scrambles Sobol points given in reversed bit order: `nested_uniform_scramble(x, seed)`
/// for `x = reversed.reverse_bits()`, one bit reversal instead of two.
#[inline]
pub fn scramble_reversed(reversed: u32, seed: u32) -> u32 {
    laine_karras(reversed, seed).reverse_bits()
}

/// The index shuffle of a padded dimension. `mask` = 2^m − 1 with 2^m ≥ the pixel's sample count:
/// indices below 2^m are permuted among themselves (an Owen scramble is a bijection on every
/// aligned block), so a pixel's samples are exactly the first 2^m Sobol points, a (0, m, 2)-net,
/// and the generator loop runs over m bits instead of 32. Indices beyond the mask are scrambled
/// whole (still uniform, so still unbiased).
#[inline]
fn shuffle(index: u32, mask: u32, seed: u32) -> u32 {
    let i = nested_uniform_scramble(index, seed);
    if index <= mask { i & mask } else { i }
}

/// Shuffled, Owen-scrambled Sobol point `index` in dimensions (0, 1), as 32-bit fixed point.
/// `seed` is the padded dimension's 64-bit hash; see [`shuffle`] for `mask`.
#[inline]
pub fn scrambled_2d(index: u32, mask: u32, seed: u64) -> (u32, u32) {
    let i = shuffle(index, mask, seed as u32);
    let s = super::rng::mix64(seed);
    // `nested_uniform_scramble(sobol(i, d), ·)` with the scramble taking reversed bits: dimension
    // 0 reversed is i itself, dimension 1 reversed comes from the byte tables (four look-ups
    // instead of a loop over i's bits and two bit reversals; unit test below).
    (
        scramble_reversed(i, s as u32),
        scramble_reversed(sobol_dim1_reversed(i), (s >> 32) as u32),
    )
}

/// Shuffled, Owen-scrambled 1D Sobol (van der Corput) point.
#[inline]
pub fn scrambled_1d(index: u32, mask: u32, seed: u64) -> u32 {
    let i = shuffle(index, mask, seed as u32);
    // Dimension 0 is the bit reversal of i: scrambling it reversed is scrambling i.
    scramble_reversed(i, (seed >> 32) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_points_match_the_sobol_sequence() {
        // Dimension 1 (x + 1, the Pascal matrix), in index (not Gray-code) order.
        let expect = [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875];
        for (i, e) in expect.iter().enumerate() {
            let x = sobol(i as u32, 1) as f64 / 4294967296.0;
            assert_eq!(x, *e, "index {i}");
        }
        // Dimension 2 (Joe–Kuo s=2, a=1, m=1,3): v = 1/2, 3/4, 3/8, … so x(i) = ⊕ v_k over i's bits.
        let expect = [0.0, 0.5, 0.75, 0.25, 0.375, 0.875, 0.625, 0.125];
        for (i, e) in expect.iter().enumerate() {
            let x = sobol(i as u32, 2) as f64 / 4294967296.0;
            assert_eq!(x, *e, "index {i}");
        }
    }

    #[test]
    fn dimension_one_without_the_table_matches_it() {
        for i in (0..5000u32).chain([u32::MAX, 0x8000_0000, 0x1234_5678]) {
            assert_eq!(sobol(i, 1), sobol_from_table(i, 1), "index {i}");
        }
    }

    #[test]
    fn dimension_one_by_bytes_matches_the_loop() {
        let mut x = 0x9e37_79b9u32;
        for i in (0..70000u32).chain([u32::MAX, 0x8000_0000, 0x00ff_ff00]) {
            assert_eq!(
                sobol_dim1_reversed(i),
                sobol_dim1(i).reverse_bits(),
                "index {i}"
            );
            x = x.wrapping_mul(0x0019_660d).wrapping_add(0x3c6e_f35f);
            assert_eq!(
                sobol_dim1_reversed(x),
                sobol_dim1(x).reverse_bits(),
                "index {x}"
            );
            assert_eq!(
                scramble_reversed(sobol_dim1_reversed(x), i),
                nested_uniform_scramble(sobol_dim1(x), i)
            );
        }
    }

    /// The scramblers' shortcuts (reversed dimension 0 is the index, reversed dimension 1 from
    /// the byte tables) give what the definitions give: Owen-scrambled `sobol(i, d)`.
    #[test]
    fn scrambled_points_are_the_scrambled_sobol_points() {
        let mut seed = 3u64;
        for n in 0..4000u32 {
            seed = super::super::rng::mix64(seed.wrapping_add(n as u64));
            let (index, mask) = match n % 3 {
                0 => (n % 64, 63),
                1 => (n, 1023),
                _ => (seed as u32 >> (n % 32), 15),
            };
            let i = shuffle(index, mask, seed as u32);
            let s = super::super::rng::mix64(seed);
            let want = (
                nested_uniform_scramble(sobol(i, 0), s as u32),
                nested_uniform_scramble(sobol(i, 1), (s >> 32) as u32),
            );
            assert_eq!(scrambled_2d(index, mask, seed), want, "index {index}");
            let want_1d = nested_uniform_scramble(sobol(i, 0), (seed >> 32) as u32);
            assert_eq!(scrambled_1d(index, mask, seed), want_1d, "index {index}");
        }
    }

    #[test]
    fn the_shuffle_permutes_each_power_of_two_prefix() {
        for seed in [0u32, 7, 0xdeadbeef] {
            for n in [1u32, 2, 8, 64, 1024] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let j = shuffle(i, n - 1, seed) as usize;
                    assert!(j < n as usize && !seen[j], "seed {seed} n {n}");
                    seen[j] = true;
                }
            }
        }
    }

    /// Every elementary interval of volume 1/n holds exactly one of the first n points.
    fn is_02_net(points: &[(u32, u32)]) -> bool {
        let n = points.len();
        let m = n.trailing_zeros();
        (0..=m).all(|bx| {
            let by = m - bx;
            let mut seen = vec![false; n];
            points.iter().all(|&(x, y)| {
                let cx = if bx == 0 {
                    0
                } else {
                    (x >> (32 - bx)) as usize
                };
                let cy = if by == 0 {
                    0
                } else {
                    (y >> (32 - by)) as usize
                };
                let c = (cy << bx) | cx;
                !std::mem::replace(&mut seen[c], true)
            })
        })
    }

    #[test]
    fn scrambled_points_form_02_nets() {
        for seed in [0u32, 1, 0xdeadbeef, 12345] {
            let seed = super::super::rng::mix64(seed as u64);
            for n in [4u32, 16, 64, 256] {
                let pts: Vec<(u32, u32)> = (0..n).map(|i| scrambled_2d(i, n - 1, seed)).collect();
                assert!(is_02_net(&pts), "seed {seed} n {n}");
                let xs: Vec<u32> = (0..n).map(|i| scrambled_1d(i, n - 1, seed)).collect();
                let mut strata = vec![0; n as usize];
                for x in xs {
                    strata[(x >> (32 - n.trailing_zeros())) as usize] += 1;
                }
                assert!(strata.iter().all(|&c| c == 1));
            }
        }
    }
}
