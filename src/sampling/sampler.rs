//! Per-sample random streams. A stream is a pure function of (seed, pixel, sample index,
//! dimension), so images are bit-identical whatever the number of threads or the tile order.
//!
//! * `independent`: every dimension hashed independently.
//! * `stratified`: every dimension (1D) or dimension pair (2D) is split into strata, one per sample
//!   of the pixel, and each sample index is sent to a stratum by a hashed permutation (Kensler 2013,
//!   "Correlated Multi-Jittered Sampling", §3, the permutation function) with a jitter inside it.
//!   2D requests are correlated multi-jittered (Kensler 2013, §4): a jittered grid whose x and y
//!   projections are also stratified, one sample per 1/spp strip when the grid has spp cells.
//!   Each sample is still marginally uniform, so the estimator stays unbiased.
//! * `sobol`: per-pixel Owen-scrambled Sobol points (Burley 2020), see [`super::sobol`].
//! * `zsobol`: one Owen-scrambled Sobol sequence over the image in Morton order (Ahmed & Wonka
//!   2020; pbrt-v4's `ZSobolSampler`), see [`super::zsobol`]: blue-noise error between pixels.

use super::ONE_MINUS_EPSILON;
use super::rng::{hash_words, mix64, u32_to_unit_f32};
use crate::math::Vec2;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SamplerKind {
    Independent,
    #[default]
    Stratified,
    /// Owen-scrambled Sobol (Burley 2020), see [`super::sobol`].
    Sobol,
    /// Poisson-disk points for 2D requests (§5.3.2), see [`super::poisson`]; 1D requests are
    /// stratified.
    PoissonDisk,
    /// Morton-ordered Owen-scrambled Sobol over the whole image, see [`super::zsobol`].
    ZSobol,
    /// `Stratified` for the first [`PADDED_DIMS`] dimensions (the camera and the first two
    /// bounces' light and BSDF numbers, where stratification lowers the error), then hashed independent
    /// numbers (one 64-bit mix per 1D or 2D request): deep bounces' numbers are decorrelated by
    /// the path's scattering anyway, so their stratification buys little and costs ~100–200
    /// instructions per number (pbrt-v4's `PaddedSobolSampler` pads in the same spirit).
    /// Opt-in: see BENCHMARKS.md (path vertex cost) for why it is not the default.
    Padded,
}

/// The dimensions a [`SamplerKind::Padded`] stream stratifies before it hands out independent
/// numbers: the camera's four (film jitter, lens) and the first two bounces' six each (light
/// spare and 2D number, BSDF lobe and direction), i.e. a path's first two vertices; later
/// vertices' numbers are hashed. Chosen by error per sample (16–24 seeds at 16, 64 and 256 spp)
/// and callgrind instructions on compare.py's scenes (BENCHMARKS.md (path vertex
/// cost)): padding from 10 (after the first vertex) saved 3–9 % of the instructions but added
/// up to 6 % to the Cornell box's error at 64–256 spp; from 4 (the camera's only) the error
/// rose by 25–100 %.
pub const PADDED_DIMS: u32 = 16;

impl SamplerKind {
    /// The name `--sampler` takes (what `FromStr` parses back; `poisson` is an alias).
    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified => "stratified",
            SamplerKind::Sobol => "sobol",
            SamplerKind::PoissonDisk => "poisson-disk",
            SamplerKind::ZSobol => "zsobol",
            SamplerKind::Padded => "padded",
        }
    }

    /// Every sampler, for front ends that list the choices.
    pub const ALL: [SamplerKind; 6] = [
        SamplerKind::Independent,
        SamplerKind::Stratified,
        SamplerKind::Padded,
        SamplerKind::Sobol,
        SamplerKind::ZSobol,
        SamplerKind::PoissonDisk,
    ];
}

impl std::str::FromStr for SamplerKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "independent" => Ok(SamplerKind::Independent),
            "stratified" => Ok(SamplerKind::Stratified),
            "sobol" => Ok(SamplerKind::Sobol),
            "poisson-disk" | "poisson" => Ok(SamplerKind::PoissonDisk),
            "zsobol" => Ok(SamplerKind::ZSobol),
            "padded" => Ok(SamplerKind::Padded),
            other => Err(format!(
                "unknown sampler '{other}' (expected independent, stratified, padded, sobol, \
                 zsobol or poisson-disk)"
            )),
        }
    }
}

mod wave;
pub use wave::{Drawn, WAVE_LANES, WaveDraw};

/// A source of uniform numbers in [0, 1), one or two at a time: a pixel sample's
/// [`SampleStream`], the stream with a wave's numbers computed ahead ([`Drawn`]), or the
/// primary-sample vector of a Metropolis chain (`super::mlt::MltSampler`).
pub trait UniformSource {
    fn next_1d(&mut self) -> f32;
    fn next_2d(&mut self) -> Vec2;
}

/// A [`UniformSource`] whose numbers are numbered dimensions, so that a routine can skip the
/// ones it does not use and keep the later ones' meaning: the stream, or the stream with a
/// wave's numbers in front ([`Drawn`]); either gives the same numbers for the same dimensions.
pub trait Numbers: UniformSource {
    /// Skips `n` dimensions (see [`SampleStream::skip`]).
    fn skip(&mut self, n: u32);
}

impl UniformSource for SampleStream {
    #[inline(always)]
    fn next_1d(&mut self) -> f32 {
        SampleStream::next_1d(self)
    }
    #[inline(always)]
    fn next_2d(&mut self) -> Vec2 {
        SampleStream::next_2d(self)
    }
}

impl Numbers for SampleStream {
    #[inline(always)]
    fn skip(&mut self, n: u32) {
        SampleStream::skip(self, n)
    }
}

/// The random numbers of one camera sample of one pixel.
#[derive(Clone, Debug)]
pub struct SampleStream {
    /// The render's sampler, seed, sample count and everything derived from them (grid, masks,
    /// reciprocals), copied in once per camera sample so the generators read it from the stream.
    setup: SamplerSetup,
    /// Hash of (seed, pixel): fixed for the pixel.
    pixel_key: u64,
    sample: u32,
    dim: u32,
    /// `mix64(sample ^ salt << 32)` for salts 0 and 1: the sample's half of every `random` hash,
    /// the same for every dimension, so it is computed once per stream rather than per number.
    sample_mix: [u64; 2],
    /// `sample % spp`, the index the stratified permutations act on.
    sample_mod: u32,
    /// ZSobol only: the sample's index in the image's sequence, `(morton(pixel) << log2 spp) |
    /// (sample mod 2^log2 spp)`, its number of base-4 digits, whether log2 spp is odd, and the
    /// hash of (seed, sample ÷ 2^log2 spp) that keys every dimension's scrambles.
    z_index: u64,
    z_digits: u32,
    z_odd: bool,
    z_key: u64,
}

/// What every stream of a render shares: the sampler, the seed and the sample count's grid and
/// masks. Built once per render, so a camera sample does not redo the square root, the divisions
/// and the mask folding (callgrind: 1.9 % of the Cornell box's instructions went to building
/// streams sample by sample).
#[derive(Clone, Copy, Debug)]
pub struct SamplerSetup {
    kind: SamplerKind,
    /// `Stratified` or `Padded`: the stratified path is inlined into `next_1d`/`next_2d`.
    fast: bool,
    /// Dimensions below this are stratified on the fast path; from it on they are independent
    /// hashes (`u32::MAX` for `Stratified`: every dimension, its numbers unchanged).
    strat_dims: u32,
    seed: u64,
    spp: u32,
    /// The stratified 2D grid (`nx × ny ≥ spp` cells, `cells` of them).
    nx: u32,
    ny: u32,
    cells: u32,
    /// Power-of-two masks for `permute` over `spp` strata and over the `nx × ny` cells.
    /// `mask_1d` also bounds the Sobol index shuffle to the pixel's power-of-two block.
    mask_1d: u32,
    mask_2d: u32,
    /// The masks of `nx` and `ny` for the correlated multi-jitter permutations of `next_2d`.
    mask_x: u32,
    mask_y: u32,
    /// `spp` is a power of two (1 included): a stratified 1D number's permutation is one pass of
    /// Kensler's hash ([`permute_pow2`]) and its division by `spp` an exact multiplication.
    pow2_1d: bool,
    /// `nx` and `ny` are powers of two above 1 (so is `cells`): the 2D number's cell permutation
    /// is one pass, its two sub-cell permutations run side by side in one register
    /// ([`permute_pow2_pair`]), and its divisions are exact multiplications.
    pow2_xy: bool,
    /// log₂ nx when `pow2_xy`: the cell's row is `cell >> log2_nx`.
    log2_nx: u32,
    /// `spp`, `nx` and `ny` as floats, and their reciprocals (used only where exact: powers of
    /// two, for which x / n and x · (1/n) are the same float).
    spp_f: f32,
    nx_f: f32,
    ny_f: f32,
    inv_spp: f32,
    inv_nx: f32,
    inv_ny: f32,
    /// ZSobol: ⌈log₂ spp⌉ and ⌈log₂ max(width, height)⌉ (16 until [`Self::for_image`] sets it).
    log2_spp: u32,
    log2_res: u32,
}

impl SamplerSetup {
    pub fn new(kind: SamplerKind, seed: u64, spp: u32) -> SamplerSetup {
        let spp = spp.max(1);
        let nx = (spp as f32).sqrt().ceil() as u32;
        let ny = spp.div_ceil(nx);
        let pow2_xy = nx > 1 && ny > 1 && nx.is_power_of_two() && ny.is_power_of_two();
        SamplerSetup {
            kind,
            fast: matches!(kind, SamplerKind::Stratified | SamplerKind::Padded),
            strat_dims: if kind == SamplerKind::Padded {
                PADDED_DIMS
            } else {
                u32::MAX
            },
            seed,
            spp,
            nx,
            ny,
            cells: nx * ny,
            mask_1d: permute_mask(spp),
            mask_2d: permute_mask(nx * ny),
            mask_x: permute_mask(nx),
            mask_y: permute_mask(ny),
            pow2_1d: spp.is_power_of_two(),
            pow2_xy,
            log2_nx: nx.trailing_zeros(),
            spp_f: spp as f32,
            nx_f: nx as f32,
            ny_f: ny as f32,
            inv_spp: 1.0 / spp as f32,
            inv_nx: 1.0 / nx as f32,
            inv_ny: 1.0 / ny as f32,
            log2_spp: super::zsobol::ceil_log2(spp),
            log2_res: 16,
        }
    }

    /// The image size, which the ZSobol sampler's Morton indices span (the other samplers do not
    /// depend on it). A render sets it; a stream made on its own assumes 65536².
    pub fn for_image(mut self, width: u32, height: u32) -> SamplerSetup {
        self.log2_res = super::zsobol::ceil_log2(width.max(height).max(1));
        self
    }

    /// The hash of (seed, pixel) that [`Self::stream`] takes: once per pixel, not per sample.
    /// For ZSobol, the pixel's Morton code instead.
    #[inline]
    pub fn pixel_key(&self, pixel: (u32, u32)) -> u64 {
        if self.kind == SamplerKind::ZSobol {
            return super::zsobol::morton2(pixel.0, pixel.1);
        }
        hash_words(&[self.seed, pixel.0 as u64, pixel.1 as u64])
    }

    /// The stream of camera sample `sample` of the pixel whose [`Self::pixel_key`] is given.
    #[inline]
    pub fn stream(&self, pixel_key: u64, sample: u32) -> SampleStream {
        let (mut z_index, mut z_digits, mut z_key) = (0, 0, 0);
        if self.kind == SamplerKind::ZSobol {
            // Samples past 2^log2_spp (a render resumed beyond its count) start a new cycle of
            // the pixel's block with scrambles of their own.
            let cycle = (sample as u64) >> self.log2_spp;
            let low = (sample as u64) & ((1u64 << self.log2_spp) - 1);
            z_index = (pixel_key << self.log2_spp) | low;
            // A pixel outside the image size given (a stream made on its own) still gets all of
            // its Morton digits.
            let pixel_bits = 64 - pixel_key.leading_zeros();
            let res_bits = self.log2_res.max(pixel_bits.div_ceil(2));
            z_digits = res_bits + self.log2_spp.div_ceil(2);
            z_key = hash_words(&[self.seed, cycle, 0x07a5_0b01]);
        }
        SampleStream {
            setup: *self,
            pixel_key,
            sample,
            dim: 0,
            sample_mix: [mix64(sample as u64), mix64((sample as u64) ^ (1 << 32))],
            sample_mod: if sample < self.spp {
                sample
            } else {
                sample % self.spp
            },
            z_index,
            z_digits,
            z_odd: self.log2_spp % 2 == 1,
            z_key,
        }
    }
}

impl SampleStream {
    /// One stream on its own; a render builds a [`SamplerSetup`] once and asks it per sample.
    pub fn new(
        kind: SamplerKind,
        seed: u64,
        pixel: (u32, u32),
        sample: u32,
        spp: u32,
    ) -> SampleStream {
        let setup = SamplerSetup::new(kind, seed, spp);
        setup.stream(setup.pixel_key(pixel), sample)
    }

    /// ZSobol: the scrambled sequence index of dimension `dim` (its low 32 bits feed the Sobol
    /// matrices) and the dimension's Owen-scramble seed, shared by all pixels.
    #[inline]
    fn z_request(&self, dim: u32) -> (u32, u64) {
        let key = mix64(self.z_key ^ (dim as u64).wrapping_mul(0xA24BAED4963EE407));
        let i = super::zsobol::scramble_index(self.z_index, self.z_digits, self.z_odd, key);
        (i as u32, mix64(key))
    }

    #[inline]
    fn dim_hash(&self, dim: u32) -> u64 {
        mix64(self.pixel_key ^ (dim as u64).wrapping_mul(0xA24BAED4963EE407))
    }

    /// Hash of (pixel, dimension, sample, salt ∈ {0, 1}) mapped to [0, 1).
    #[inline]
    fn random(&self, dim: u32, salt: usize) -> f32 {
        self.random_h(self.dim_hash(dim), salt)
    }

    /// [`Self::random`] given the dimension's hash, so callers that also need it hash it once.
    #[inline]
    fn random_h(&self, dim_hash: u64, salt: usize) -> f32 {
        let h = mix64(dim_hash ^ self.sample_mix[salt]);
        u32_to_unit_f32(h as u32)
    }

    /// The next number of the stream. The stratified and padded samplers' path is inlined into the caller;
    /// the others go through [`Self::other_1d`], so a stratified number costs no call, register
    /// saves or jump over the sampler kinds (callgrind, 64², 16 spp: −0.7 % of the Cornell box's
    /// instructions per sample, −0.6 % textured, −0.3 % veach; the same numbers).
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        let d = self.dim;
        self.dim += 1;
        if self.setup.fast {
            if d < self.setup.strat_dims {
                self.stratified_1d(d)
            } else {
                u32_to_unit_f32(self.padding(d) as u32)
            }
        } else {
            self.other_1d(d)
        }
    }

    /// Dimension `d` of a stratified stream: one stratum of `spp` per sample, by a hashed
    /// permutation, with a hashed jitter inside it.
    #[inline(always)]
    fn stratified_1d(&self, d: u32) -> f32 {
        let st = &self.setup;
        let h = self.dim_hash(d);
        let jitter = self.random_h(h, 1);
        let u = if st.pow2_1d {
            // A power-of-two spp is at most 2³¹, so the stratum is below 2³¹: `as i32 as f32`
            // is the same float as `as f32` from u32, in one conversion instead of a widening
            // and a 64-bit one.
            let stratum = permute_pow2(self.sample_mod, h as u32, st.mask_1d);
            (stratum as i32 as f32 + jitter) * st.inv_spp
        } else {
            let stratum = permute_masked(self.sample_mod, st.spp, h as u32, st.mask_1d);
            (stratum as f32 + jitter) / st.spp_f
        };
        u.min(ONE_MINUS_EPSILON)
    }

    /// A padded dimension's 64 hashed bits: one mix of (pixel, sample, dimension). The pixel
    /// and sample halves are the hashes the stratified numbers already use (`pixel_key`,
    /// `sample_mix[0]`), so the stream carries nothing new; the dimension is spread by the
    /// golden-ratio-like odd constant of [`Self::dim_hash`] and a different one, so a padded
    /// number is not any stratified number's jitter.
    #[inline(always)]
    fn padding(&self, d: u32) -> u64 {
        mix64(
            (self.pixel_key ^ self.sample_mix[0])
                .wrapping_add((d as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)),
        )
    }

    #[inline(never)]
    fn other_1d(&self, d: u32) -> f32 {
        match self.setup.kind {
            SamplerKind::Independent => self.random(d, 0),
            SamplerKind::Sobol => {
                let x =
                    super::sobol::scrambled_1d(self.sample, self.setup.mask_1d, self.dim_hash(d));
                u32_to_unit_f32(x)
            }
            SamplerKind::ZSobol => {
                let (i, seed) = self.z_request(d);
                // Sobol dimension 0 is the bit reversal of the index: its reversed form is i.
                u32_to_unit_f32(super::sobol::scramble_reversed(i, seed as u32))
            }
            SamplerKind::Stratified | SamplerKind::Padded | SamplerKind::PoissonDisk => {
                self.stratified_1d(d)
            }
        }
    }

    /// Skips `n` dimensions whose numbers the caller would not use (the light choice with one
    /// light, the lobe choice of a one-lobe BSDF), so later dimensions keep their meaning.
    #[inline]
    pub fn skip(&mut self, n: u32) {
        self.dim += n;
    }

    /// The next two numbers of the stream (one 2D point). Inlined for those samplers as
    /// [`Self::next_1d`] is.
    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        let d = self.dim;
        self.dim += 2;
        if self.setup.fast {
            if d < self.setup.strat_dims {
                self.stratified_2d(d)
            } else {
                let h = self.padding(d);
                Vec2::new(u32_to_unit_f32(h as u32), u32_to_unit_f32((h >> 32) as u32))
            }
        } else {
            self.other_2d(d)
        }
    }

    #[inline(never)]
    fn other_2d(&self, d: u32) -> Vec2 {
        match self.setup.kind {
            SamplerKind::Independent => Vec2::new(self.random(d, 0), self.random(d + 1, 0)),
            SamplerKind::Sobol => {
                let (x, y) =
                    super::sobol::scrambled_2d(self.sample, self.setup.mask_1d, self.dim_hash(d));
                Vec2::new(u32_to_unit_f32(x), u32_to_unit_f32(y))
            }
            SamplerKind::ZSobol => {
                let (i, seed) = self.z_request(d);
                let x = super::sobol::scramble_reversed(i, seed as u32);
                let y = super::sobol::scramble_reversed(
                    super::sobol::sobol_dim1_reversed(i),
                    (seed >> 32) as u32,
                );
                Vec2::new(u32_to_unit_f32(x), u32_to_unit_f32(y))
            }
            SamplerKind::PoissonDisk => {
                // The pixel's samples are the first spp points of the progressive pattern, handed
                // out in a per-dimension order; each repetition beyond the pattern's size gets its
                // own shift.
                let size = super::poisson::PATTERN_SIZE as u32;
                let cycle = self.sample / size;
                let n = self.setup.spp.min(size);
                let salt = self.dim_hash(d) ^ mix64(cycle as u64 + 1);
                let j = permute(self.sample % n, n, salt as u32);
                let shift = Vec2::new(
                    u32_to_unit_f32(mix64(salt ^ 0x51) as u32),
                    u32_to_unit_f32(mix64(salt ^ 0xa7) as u32),
                );
                super::poisson::shifted(j as usize, shift)
            }
            SamplerKind::Stratified | SamplerKind::Padded => self.stratified_2d(d),
        }
    }

    /// Dimensions `d`, `d + 1` of a stratified stream: correlated multi-jittered (below).
    #[inline(always)]
    fn stratified_2d(&self, d: u32) -> Vec2 {
        let st = &self.setup;
        let h = self.dim_hash(d);
        // Correlated multi-jittering (Kensler 2013, §4): an nx × ny grid with at least spp
        // cells, a hashed permutation spreading the samples over distinct cells; inside its
        // cell the sample takes the sub-column π₁(cy) of ny and the sub-row π₂(cx) of nx, with
        // π₁, π₂ hashed permutations shared by the dimension's cells. The samples of a column
        // then fill distinct sub-columns, so with nx·ny = spp the x (and y) projections are
        // stratified into spp strata as well as the 2D cells (N-rooks): a 1D decision taken
        // from x — NEE's light choice reusing its 2D number — is as stratified as a 1D
        // request. Every point stays uniform: the cell is uniform, and given it the sub-cell
        // is uniform over the permutations.
        let hp = (h >> 32) as u32;
        let (px, py) = (hp.wrapping_mul(0xa511_e9b3), hp.wrapping_mul(0x63d8_3595));
        // One 64-bit hash gives both jitters (24 bits each).
        let j = mix64(h ^ self.sample_mix[1]);
        let jx = u32_to_unit_f32(j as u32);
        let jy = u32_to_unit_f32((j >> 32) as u32);
        // The grid's sides are at most 2¹⁶ (nx = ⌈√spp⌉), so cells and sub-cells convert
        // through i32 exactly (one conversion each, as in `stratified_1d`).
        let (x, y) = if st.pow2_xy {
            // The usual square sample counts (4, 16, 64, 256): every permutation is one pass,
            // the row a shift, and dividing by nx or ny multiplying by its exact reciprocal.
            let cell = permute_pow2(self.sample_mod, h as u32, st.mask_2d);
            let (cx, cy) = (cell & st.mask_x, cell >> st.log2_nx);
            let (sub_x, sub_y) = permute_pow2_pair([cy, cx], [px, py], [st.mask_y, st.mask_x]);
            (
                (cx as i32 as f32 + (sub_x as i32 as f32 + jx) * st.inv_ny) * st.inv_nx,
                (cy as i32 as f32 + (sub_y as i32 as f32 + jy) * st.inv_nx) * st.inv_ny,
            )
        } else {
            let (nx, ny) = (st.nx, st.ny);
            let cell = permute_masked(self.sample_mod, st.cells, h as u32, st.mask_2d);
            let (cx, cy) = if nx.is_power_of_two() {
                (cell & (nx - 1), cell >> nx.trailing_zeros())
            } else {
                (cell % nx, cell / nx)
            };
            let sub_x = permute_masked(cy, ny, px, st.mask_y);
            let sub_y = permute_masked(cx, nx, py, st.mask_x);
            (
                (cx as i32 as f32 + (sub_x as i32 as f32 + jx) / st.ny_f) / st.nx_f,
                (cy as i32 as f32 + (sub_y as i32 as f32 + jy) / st.nx_f) / st.ny_f,
            )
        };
        Vec2::new(x.min(ONE_MINUS_EPSILON), y.min(ONE_MINUS_EPSILON))
    }
}

/// A pseudo-random permutation of `[0, l)` selected by `p`, evaluated at `i` without storing the
/// permutation (Kensler 2013, listing 3: cycle-walking over a hash restricted to the next power of two).
pub fn permute(i: u32, l: u32, p: u32) -> u32 {
    permute_masked(i, l, p, permute_mask(l))
}

/// The all-ones mask covering `[0, l)`: the next power of two minus one.
#[inline]
fn permute_mask(l: u32) -> u32 {
    let mut w = l.saturating_sub(1);
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    w
}

/// [`permute`] with the mask of `l` precomputed.
#[inline]
fn permute_masked(mut i: u32, l: u32, p: u32, w: u32) -> u32 {
    if l <= 1 {
        return 0;
    }
    loop {
        i = kensler_hash(i, p, w);
        if i < l {
            break;
        }
    }
    if w.wrapping_add(1) == l {
        // l is a power of two: Kensler's final offset (i + p) mod l is a mask.
        return i.wrapping_add(p) & w;
    }
    // Otherwise the same rotation of [0, l) by an offset derived from p, without Kensler's
    // `% l`: a 32-bit division took 11 % of the sampler's cycles at 32 spp (a 6×6 grid; perf), and most
    // sample counts that are not a power of 4 (32, 128, 512) or not a power of two (100) take
    // this path. The offset is the high word of p·l (Lemire 2019, "Fast random integer
    // generation in an interval"), which lies in [0, l).
    let offset = ((p as u64 * l as u64) >> 32) as u32;
    let j = i as u64 + offset as u64;
    (if j >= l as u64 { j - l as u64 } else { j }) as u32
}

/// One pass of Kensler's hash over `[0, w]` (2013, listing 3; the loop of [`permute_masked`]).
#[inline(always)]
fn kensler_hash(mut i: u32, p: u32, w: u32) -> u32 {
    i ^= p;
    i = i.wrapping_mul(0xe170893d);
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i = i.wrapping_mul(0x0929eb3f);
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i = i.wrapping_mul(1 | (p >> 27));
    i = i.wrapping_mul(0x6935fa69);
    i ^= (i & w) >> 11;
    i = i.wrapping_mul(0x74dcb303);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0x9e501cc3);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0xc860a3df);
    i &= w;
    i ^ (i >> 5)
}

/// [`permute_masked`]`(i, w + 1, p, w)` for `w + 1` a power of two (1 included): the hash then
/// ends inside the mask after one pass (`i & w` and `i ^ i >> 5` stay below w + 1), so no cycle
/// walking and no `l <= 1` test (for w = 0 the masked offset is 0, as `permute_masked` returns),
/// and Kensler's final `(i + p) mod l` is a mask.
#[inline(always)]
fn permute_pow2(i: u32, p: u32, w: u32) -> u32 {
    kensler_hash(i, p, w).wrapping_add(p) & w
}

/// [`permute_masked`]`(i[k], w[k] + 1, p[k], w[k])` for k = 0, 1, where both `w[k] + 1` are
/// powers of two above 1: Kensler's hash then ends inside the mask after one pass (no cycle
/// walking) and the offset is a mask. On x86_64 the two permutations run in lanes 0 and 2 of one
/// SSE2 register (`pmuludq` multiplies those lanes; what it leaves in lanes 1 and 3 is never
/// read): the same 32-bit operations in the same order, so the same values (unit test below).
/// The stratified 2D number's two sub-cell permutations were ~80 of its ~230 instructions
/// (callgrind, Cornell box).
///
/// The multiplications are `pmuludq` written as inline assembly: given `_mm_mul_epu32`, LLVM
/// sees through its masking of lanes 1 and 3 and lowers four of the six products as full 64-bit
/// lane multiplications (three `pmuludq`, two shifts and an add each), 16 more instructions per
/// 2D number (objdump of `next_2d`); only the low 32 bits of lanes 0 and 2 are
/// read, which one `pmuludq` gives.
#[inline(always)]
fn permute_pow2_pair(i: [u32; 2], p: [u32; 2], w: [u32; 2]) -> (u32, u32) {
    debug_assert!(w.iter().all(|&w| w > 0 && (w + 1).is_power_of_two()));
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 intrinsics and one SSE2 instruction as inline assembly, which every x86_64
    // CPU has (the target's baseline); no memory is touched. `unsafe` because Rust asks it of
    // `#[target_feature]` functions called outside a function that lists the feature, and of
    // `asm!`.
    unsafe {
        use std::arch::x86_64::*;
        // Lanes 0 and 2 times lanes 0 and 2 of `k`, 64-bit products (`_mm_mul_epu32`), opaque
        // to LLVM's rewriting (above).
        let mul = |x: __m128i, k: __m128i| -> __m128i {
            let mut r = x;
            std::arch::asm!(
                "pmuludq {r}, {k}",
                r = inout(xmm_reg) r,
                k = in(xmm_reg) k,
                options(pure, nomem, nostack, preserves_flags)
            );
            r
        };
        let two = |a: u32, b: u32| _mm_setr_epi32(a as i32, 0, b as i32, 0);
        let c = |k: u32| _mm_set1_epi32(k as i32);
        let pv = two(p[0], p[1]);
        let wv = two(w[0], w[1]);
        // i ^= (i & w) >> s
        let fold = |x: __m128i, s: i32| -> __m128i {
            let m = _mm_and_si128(x, wv);
            let sh = match s {
                1 => _mm_srli_epi32::<1>(m),
                2 => _mm_srli_epi32::<2>(m),
                4 => _mm_srli_epi32::<4>(m),
                _ => _mm_srli_epi32::<11>(m),
            };
            _mm_xor_si128(x, sh)
        };
        // The two multiplications by (1 | p >> 27) and 0x6935fa69 folded (mod 2^32).
        let k = two(
            (1 | (p[0] >> 27)).wrapping_mul(0x6935fa69),
            (1 | (p[1] >> 27)).wrapping_mul(0x6935fa69),
        );
        let mut x = _mm_xor_si128(two(i[0], i[1]), pv);
        x = mul(x, c(0xe170893d));
        x = _mm_xor_si128(x, _mm_srli_epi32::<16>(pv));
        x = fold(x, 4);
        x = _mm_xor_si128(x, _mm_srli_epi32::<8>(pv));
        x = mul(x, c(0x0929eb3f));
        x = _mm_xor_si128(x, _mm_srli_epi32::<23>(pv));
        x = fold(x, 1);
        x = mul(x, k);
        x = fold(x, 11);
        x = mul(x, c(0x74dcb303));
        x = fold(x, 2);
        x = mul(x, c(0x9e501cc3));
        x = fold(x, 2);
        x = mul(x, c(0xc860a3df));
        x = _mm_and_si128(x, wv);
        x = _mm_xor_si128(x, _mm_srli_epi32::<5>(x));
        x = _mm_and_si128(_mm_add_epi32(x, pv), wv);
        (
            _mm_cvtsi128_si32(x) as u32,
            _mm_cvtsi128_si32(_mm_srli_si128::<8>(x)) as u32,
        )
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        (
            permute_masked(i[0], w[0] + 1, p[0], w[0]),
            permute_masked(i[1], w[1] + 1, p[1], w[1]),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paired power-of-two permutations are the scalar ones, value for value, over every
    /// index of sizes 2 to 1024 and hashed keys (including 0 and all ones).
    #[test]
    fn paired_pow2_permutations_are_the_scalar_ones() {
        let mut keys = vec![0u32, u32::MAX, 0x8000_0000, 1];
        let mut h = 17u64;
        for _ in 0..60 {
            h = mix64(h.wrapping_add(0x9E37_79B9_7F4A_7C15));
            keys.push(h as u32);
            keys.push((h >> 32) as u32);
        }
        for la in (1..=10).map(|b| 1u32 << b) {
            for lb in [2u32, 4, 8, 64, 1024] {
                for (n, &pa) in keys.iter().enumerate() {
                    let pb = keys[(n * 7 + 3) % keys.len()];
                    for i in 0..la.max(lb) {
                        let (ia, ib) = (i % la, (i * 5 + 1) % lb);
                        let got = permute_pow2_pair([ia, ib], [pa, pb], [la - 1, lb - 1]);
                        let want = (permute(ia, la, pa), permute(ib, lb, pb));
                        assert_eq!(got, want, "sizes {la} {lb}, keys {pa:#x} {pb:#x}, i {i}");
                    }
                }
            }
        }
    }

    /// The one-pass power-of-two permutation is the cycle-walking one, for every size from 1 to
    /// 4096 and hashed keys.
    #[test]
    fn one_pass_pow2_permutation_is_permute() {
        let mut h = 5u64;
        for b in 0..=12 {
            let l = 1u32 << b;
            for k in 0..40 {
                h = mix64(h.wrapping_add(k));
                let p = if k == 0 { u32::MAX } else { h as u32 };
                for i in 0..l.min(300) {
                    assert_eq!(
                        permute_pow2(i, p, l - 1),
                        permute(i, l, p),
                        "l {l} p {p:#x}"
                    );
                }
            }
        }
    }

    /// Samples past `spp` (a render resumed beyond its count) repeat the strata of sample
    /// `sample mod spp` with fresh jitter: the stream's index into the permutations wraps.
    #[test]
    fn samples_past_spp_reuse_the_strata() {
        for spp in [12u32, 64] {
            let setup = SamplerSetup::new(SamplerKind::Stratified, 9, spp);
            let key = setup.pixel_key((5, 3));
            for sample in 0..spp {
                let mut a = setup.stream(key, sample);
                let mut b = setup.stream(key, sample + 2 * spp);
                for _ in 0..6 {
                    let (x, y) = (a.next_1d(), b.next_1d());
                    assert_eq!((x * spp as f32) as u32, (y * spp as f32) as u32);
                    assert_ne!(x, y, "the jitter is the sample's own");
                }
            }
        }
    }

    #[test]
    fn permute_is_a_permutation() {
        for l in [1u32, 2, 3, 7, 16, 36, 100, 257] {
            for p in [0u32, 1, 0xdeadbeef, u32::MAX] {
                let mut seen = vec![false; l as usize];
                for i in 0..l {
                    let j = permute(i, l, p) as usize;
                    assert!(!seen[j], "l={l} p={p}");
                    seen[j] = true;
                }
            }
        }
    }

    #[test]
    fn stratified_1d_puts_one_sample_per_stratum() {
        // 16: power of two (mask); 12 and 100: the rotation without a division.
        for spp in [16u32, 12, 100] {
            for pixel in [(3, 4), (17, 2)] {
                let mut strata = vec![0; spp as usize];
                for s in 0..spp {
                    let mut st = SampleStream::new(SamplerKind::Stratified, 5, pixel, s, spp);
                    let u = st.next_1d();
                    strata[(u * spp as f32) as usize] += 1;
                }
                assert!(strata.iter().all(|&c| c == 1), "spp {spp}: {strata:?}");
            }
        }
    }

    #[test]
    fn stratified_2d_puts_at_most_one_sample_per_cell() {
        // 16 samples on a 4×4 grid (every cell once); 32 on 6×6 and 12 on 4×3 (the non-power-of-
        // two cell counts).
        for (spp, nx, ny) in [(16u32, 4usize, 4usize), (32, 6, 6), (12, 4, 3)] {
            let mut cells = vec![0; nx * ny];
            for s in 0..spp {
                let mut st = SampleStream::new(SamplerKind::Stratified, 5, (3, 4), s, spp);
                st.next_1d();
                let u = st.next_2d();
                cells[(u.y * ny as f32) as usize * nx + (u.x * nx as f32) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c <= 1), "spp {spp}: {cells:?}");
            assert_eq!(cells.iter().sum::<u32>(), spp);
        }
    }

    /// With a full grid (16 = 4×4, 12 = 4×3) the 2D points are also stratified along each
    /// axis: one sample in each of the spp strips of x and of y (multi-jittering), on top of one
    /// per cell; with a partial grid (32 on 6×6) at most one per strip.
    #[test]
    fn stratified_2d_projections_are_stratified() {
        for (spp, full) in [(16u32, true), (12, true), (32, false)] {
            for pixel in [(3, 4), (17, 2), (0, 0)] {
                let (mut xs, mut ys) = (vec![0; spp as usize], vec![0; spp as usize]);
                for s in 0..spp {
                    let mut st = SampleStream::new(SamplerKind::Stratified, 5, pixel, s, spp);
                    st.next_1d();
                    let u = st.next_2d();
                    xs[(u.x * spp as f32) as usize] += 1;
                    ys[(u.y * spp as f32) as usize] += 1;
                }
                if full {
                    assert!(xs.iter().all(|&c| c == 1), "spp {spp} x: {xs:?}");
                    assert!(ys.iter().all(|&c| c == 1), "spp {spp} y: {ys:?}");
                } else {
                    assert!(xs.iter().all(|&c| c <= 2), "spp {spp} x: {xs:?}");
                }
            }
        }
    }

    /// A few hundred numbers of every sampler kind, for power-of-two and other sample counts
    /// (full and partial 2D grids), samples past the count, 1D and 2D requests and skips: the
    /// sequence is part of the determinism contract (every image depends on it), so a faster
    /// generator must give the same bits. The expected digests and first numbers were recorded
    /// from the session-12 start code (main c1e0c37).
    fn pinned_numbers(kind: SamplerKind, requests: u32) -> Vec<f32> {
        let mut out = Vec::new();
        for spp in [1u32, 4, 12, 16, 32, 64] {
            let setup = SamplerSetup::new(kind, 11 + spp as u64, spp).for_image(40, 30);
            for pixel in [(0, 0), (5, 3), (39, 29)] {
                let key = setup.pixel_key(pixel);
                for s in [0, spp / 2, spp - 1, spp + 1] {
                    let mut st = setup.stream(key, s);
                    for d in 0..requests {
                        match d % 4 {
                            0 | 2 => {
                                let u = st.next_2d();
                                out.extend([u.x, u.y]);
                            }
                            1 => out.push(st.next_1d()),
                            _ => st.skip(1),
                        }
                    }
                }
            }
        }
        out
    }

    fn digest(values: &[f32]) -> u64 {
        values
            .iter()
            .fold(0, |h, v| mix64(h ^ v.to_bits() as u64).wrapping_add(1))
    }

    #[test]
    fn every_sampler_gives_the_pinned_numbers() {
        let pinned: [(SamplerKind, u64, [u32; 4]); 6] = [
            (
                SamplerKind::Independent,
                0x8c7aa098ef249299,
                [0x3f2362e6, 0x3eaf67b4, 0x3f3edcfb, 0x3f1e447f],
            ),
            (
                SamplerKind::Stratified,
                0x17114e5c30b8e7fc,
                [0x3ea747b4, 0x3e96e3fc, 0x3f57c612, 0x3f254804],
            ),
            (
                SamplerKind::Sobol,
                0x42ace6824d7d5cf0,
                [0x3f111f24, 0x3e766f34, 0x3f7638b6, 0x3ec305ce],
            ),
            (
                SamplerKind::PoissonDisk,
                0xc9a2dbb4b5efe840,
                [0x3f5a0d17, 0x3e88faa0, 0x3f57c612, 0x3ebfd600],
            ),
            (
                SamplerKind::ZSobol,
                0xa6e3df06703d0d06,
                [0x3ebf4b20, 0x3e9a1e74, 0x3f2acfee, 0x3f16869e],
            ),
            // Its first numbers are Stratified's; the digest differs from dimension 16 on.
            (
                SamplerKind::Padded,
                0xb108f605e2b5ce4e,
                [0x3ea747b4, 0x3e96e3fc, 0x3f57c612, 0x3f254804],
            ),
        ];
        for (kind, want, first) in pinned {
            // The padded sampler's requests reach past its stratified dimensions (18 + 18).
            let (requests, len) = if kind == SamplerKind::Padded {
                (24, 2160)
            } else {
                (12, 1080)
            };
            let v = pinned_numbers(kind, requests);
            assert_eq!(v.len(), len);
            let got: Vec<u32> = v[..4].iter().map(|x| x.to_bits()).collect();
            let hex: Vec<String> = got.iter().map(|b| format!("{b:#010x}")).collect();
            println!("{kind:?}: {:#018x}, [{}]", digest(&v), hex.join(", "));
            assert_eq!(got, first, "{kind:?}: the first numbers changed");
            assert_eq!(
                digest(&v),
                want,
                "{kind:?}: some of the pinned numbers changed"
            );
        }
    }

    /// The padded sampler is the stratified one, bit for bit, on its first `PADDED_DIMS`
    /// dimensions (1D and 2D requests, skips), and independent uniform numbers after them: each
    /// padded dimension's numbers over many pixels and samples fill 16 bins evenly (chi-square),
    /// the two halves of a padded 2D number and consecutive requests are uncorrelated, and a
    /// pixel's samples are not stratified there (they would be if the padding still permuted
    /// strata).
    #[test]
    fn padded_streams_stratify_only_the_first_dimensions() {
        let spp = 16;
        let strat = SamplerSetup::new(SamplerKind::Stratified, 7, spp).for_image(64, 64);
        let pad = SamplerSetup::new(SamplerKind::Padded, 7, spp).for_image(64, 64);
        // Requests as the pinned test makes them: 2D, 1D, 2D, skip, repeated. A 2D request
        // starting at PADDED_DIMS - 1 is stratified in both of its dimensions; from
        // PADDED_DIMS + 1 on every dimension is padded.
        let first_padded = PADDED_DIMS + 1;
        let dims = PADDED_DIMS + 13;
        let mut padded: Vec<Vec<f32>> = vec![Vec::new(); dims as usize];
        let mut full_strata = 0;
        let mut stratified_checked = 0;
        for px in 0..32u32 {
            for py in 0..32u32 {
                let mut strata = vec![0u32; spp as usize];
                let (ks, kp) = (strat.pixel_key((px, py)), pad.pixel_key((px, py)));
                for sample in 0..spp {
                    let (mut a, mut b) = (strat.stream(ks, sample), pad.stream(kp, sample));
                    let (mut d, mut j) = (0u32, 0u32);
                    while d + 1 < dims {
                        let (x, y) = match j % 4 {
                            0 | 2 => {
                                let (u, v) = (a.next_2d(), b.next_2d());
                                (vec![u.x, u.y], vec![v.x, v.y])
                            }
                            1 => (vec![a.next_1d()], vec![b.next_1d()]),
                            _ => {
                                a.skip(1);
                                b.skip(1);
                                (vec![0.0], vec![0.0])
                            }
                        };
                        for (i, (&xs, &ys)) in x.iter().zip(&y).enumerate() {
                            let di = d + i as u32;
                            assert!((0.0..1.0).contains(&ys), "dim {di}: {ys}");
                            if d < PADDED_DIMS {
                                assert_eq!(
                                    xs.to_bits(),
                                    ys.to_bits(),
                                    "dim {di} must be stratified"
                                );
                                stratified_checked += 1;
                            } else if j % 4 != 3 && di >= first_padded {
                                padded[di as usize].push(ys);
                                if di == first_padded + 1 {
                                    strata[(ys * spp as f32) as usize] += 1;
                                }
                            }
                        }
                        d += x.len() as u32;
                        j += 1;
                    }
                }
                full_strata += strata.iter().all(|&c| c == 1) as u32;
            }
        }
        assert!(stratified_checked >= 1024 * 16 * (PADDED_DIMS - 2));
        // With independent numbers a pixel fills all 16 strata with probability 16!/16^16.
        assert_eq!(
            full_strata, 0,
            "padded dimensions are still stratified per pixel"
        );
        let drawn: Vec<&Vec<f32>> = padded.iter().filter(|v| !v.is_empty()).collect();
        assert!(drawn.len() >= 8, "{} padded dimensions drawn", drawn.len());
        for (k, v) in drawn.iter().enumerate() {
            let n = v.len() as f64;
            let mut bins = [0f64; 16];
            for &x in v.iter() {
                bins[(x * 16.0) as usize] += 1.0;
            }
            let e = n / 16.0;
            let chi2: f64 = bins.iter().map(|&o| (o - e) * (o - e) / e).sum();
            // 15 degrees of freedom: P(chi2 > 45) < 1e-4.
            assert!(
                chi2 < 45.0,
                "padded dimension {k}: chi2 {chi2:.1}, bins {bins:?}"
            );
        }
        for w in drawn.windows(2) {
            let n = w[0].len() as f64;
            let cov = w[0]
                .iter()
                .zip(w[1].iter())
                .map(|(&x, &y)| (x as f64 - 0.5) * (y as f64 - 0.5))
                .sum::<f64>()
                / n;
            // Independent uniforms: the covariance is ~N(0, (1/12)²/n); 5 sigma.
            assert!(
                cov.abs() < 5.0 / 12.0 / n.sqrt(),
                "padded dimensions correlate: {cov}"
            );
        }
    }

    #[test]
    fn streams_are_deterministic_and_distinct() {
        for kind in [
            SamplerKind::Independent,
            SamplerKind::Stratified,
            SamplerKind::Sobol,
            SamplerKind::PoissonDisk,
            SamplerKind::ZSobol,
            SamplerKind::Padded,
        ] {
            let mut a = SampleStream::new(kind, 1, (0, 0), 3, 8);
            let mut b = SampleStream::new(kind, 1, (0, 0), 3, 8);
            let mut c = SampleStream::new(kind, 1, (1, 0), 3, 8);
            let va: Vec<f32> = (0..10).map(|_| a.next_1d()).collect();
            let vb: Vec<f32> = (0..10).map(|_| b.next_1d()).collect();
            let vc: Vec<f32> = (0..10).map(|_| c.next_1d()).collect();
            assert_eq!(va, vb);
            assert_ne!(va, vc);
            assert!(va.iter().all(|&x| (0.0..1.0).contains(&x)));
        }
    }
}
