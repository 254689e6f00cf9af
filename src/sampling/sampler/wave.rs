//! One bounce's numbers for a wave of paths at once: the stratified sampler's hashing and
//! permutations run across the wave's lanes (structure of arrays, one loop per number) instead of
//! path by path as the bounce draws them, so the compiler runs them several lanes wide: 4 (64-bit
//! hashing) and 8 (32-bit permutations) per AVX2 instruction, with AVX-512's 64-bit
//! multiplication at the `avx512` level, 2 to 4 in the SSE2 baseline (the copy is chosen at run
//! time, `crate::math::SimdLevel`).
//!
//! A bounce of the surface path tracer draws seven dimensions from its path's stream, from the
//! dimension `d` it has reached: the light sample's spare number (`d`, 1D) and point (`d + 1`,
//! 2D), the BSDF's lobe (`d + 3`, 1D) and direction (`d + 4`, 2D), and Russian roulette's number
//! (`d + 6`, 1D). [`WaveDraw`] computes all five draws for every lane of a wave in one pass;
//! the bounce then takes them through [`Drawn`], which hands out a precomputed number when the
//! stream asks for that dimension and otherwise draws from the stream itself, so a path that
//! skips or draws differently still gets its stream's numbers.
//!
//! Every lane computes exactly [`SampleStream::next_1d`] / [`SampleStream::next_2d`]: the same
//! 32- and 64-bit integer operations (exact at any width) and the same IEEE single-precision
//! additions, multiplications and minimum, each rounded once (Rust never contracts `a * b + c`
//! into an FMA, and none is written here), so every copy gives the scalar stream's bits (unit
//! tests below, per level; tests/simd.rs renders each level). Covered: the stratified and padded
//! samplers when the sample count and its 2D grid are powers of two (4, 16, 64, 256, … spp),
//! where every permutation is one pass of Kensler's hash without cycle walking; other samplers
//! and counts draw from the stream as before.

use super::{Numbers, SampleStream, SamplerSetup, UniformSource, permute_pow2};
use crate::math::{SimdLevel, Vec2};
use crate::sampling::ONE_MINUS_EPSILON;
use crate::sampling::rng::mix64;

/// The most lanes one [`WaveDraw::run`] covers: the wavefront path loop's wave.
pub const WAVE_LANES: usize = 32;
/// Lanes per step of the kernel's loops: AVX2's eight 32-bit lanes (LLVM widens the baseline
/// copy's loops to two or four).
const CHUNK: usize = 8;
const _: () = assert!(WAVE_LANES.is_multiple_of(CHUNK));

/// The dimensions one bounce draws (see the module's documentation), and where the five draws
/// start relative to the bounce's first dimension, with whether each is 2D.
const BOUNCE_DIMS: u32 = 7;
const DRAWS: [(usize, bool); 5] = [(0, false), (1, true), (3, false), (4, true), (6, false)];
/// The camera's draws from a stream's first dimension: film (2D), lens (2D).
const CAMERA_DRAWS: [(usize, bool); 2] = [(0, true), (2, true)];

/// A path's stream with its bounce's numbers, computed for the whole wave by [`WaveDraw`], in
/// front: the numbers the stream would give, the stream's position kept as if it had drawn them.
pub struct Drawn<'a> {
    s: &'a mut SampleStream,
    w: &'a WaveDraw,
    k: usize,
}

impl<'a> Drawn<'a> {
    /// The stream `s` of the wave's `k`-th lane ([`WaveDraw::push`] order) with the numbers of
    /// the wave's last [`WaveDraw::run`] (none since [`WaveDraw::begin`]: all from `s`).
    #[inline(always)]
    pub fn new(s: &'a mut SampleStream, w: &'a WaveDraw, k: usize) -> Drawn<'a> {
        Drawn {
            s,
            w,
            k: k % WAVE_LANES,
        }
    }

    /// Offset of the stream's next dimension from the lane's bounce's first.
    #[inline(always)]
    fn offset(&self) -> u32 {
        self.s.dim.wrapping_sub(self.w.lanes.dim[self.k])
    }
}

impl UniformSource for Drawn<'_> {
    #[inline(always)]
    fn next_1d(&mut self) -> f32 {
        let off = self.offset();
        if off < BOUNCE_DIMS && self.w.have_1d & (1 << off) != 0 {
            self.s.dim += 1;
            self.w.lanes.out[off as usize][self.k]
        } else {
            self.s.next_1d()
        }
    }

    #[inline(always)]
    fn next_2d(&mut self) -> Vec2 {
        let off = self.offset();
        if off < BOUNCE_DIMS - 1 && self.w.have_2d & (1 << off) != 0 {
            self.s.dim += 2;
            let o = off as usize;
            Vec2::new(self.w.lanes.out[o][self.k], self.w.lanes.out[o + 1][self.k])
        } else {
            self.s.next_2d()
        }
    }
}

impl Numbers for Drawn<'_> {
    #[inline(always)]
    fn skip(&mut self, n: u32) {
        self.s.skip(n);
    }
}

/// A wave's streams in structure-of-arrays form and their bounce numbers: the scratch of one
/// worker's wavefront loop, allocated with it (never per ray). [`Self::begin`], [`Self::push`]
/// each lane's stream, [`Self::run`], then [`Self::numbers`] per lane.
pub struct WaveDraw {
    level: SimdLevel,
    setup: Option<SamplerSetup>,
    n: usize,
    /// The offsets (bit `o`: dimension `bounce's first + o`) of the 1D and the 2D draws the
    /// last [`Self::run`] computed; zero since [`Self::begin`].
    have_1d: u32,
    have_2d: u32,
    lanes: Lanes,
}

/// The per-lane inputs and outputs, padded to [`WAVE_LANES`] so every loop has a fixed trip count.
#[derive(Clone)]
struct Lanes {
    key: [u64; WAVE_LANES],
    mix0: [u64; WAVE_LANES],
    mix1: [u64; WAVE_LANES],
    smod: [u32; WAVE_LANES],
    dim: [u32; WAVE_LANES],
    /// The stratified draws' 64-bit hashes between the kernel's two loops ([`strat_hashes`]).
    hashes: [[u32; WAVE_LANES]; 4],
    out: [[f32; WAVE_LANES]; BOUNCE_DIMS as usize],
}

impl Default for WaveDraw {
    fn default() -> Self {
        WaveDraw::new()
    }
}

impl WaveDraw {
    /// Scratch for one wave, using the process's SIMD level (`TRAYECTO_SIMD`).
    pub fn new() -> WaveDraw {
        WaveDraw::with_level(crate::math::simd_level())
    }

    /// Scratch for one wave whose kernel is `level`'s copy (portable if the CPU lacks it).
    pub fn with_level(level: SimdLevel) -> WaveDraw {
        WaveDraw {
            level: if level.available() {
                level
            } else {
                SimdLevel::Portable
            },
            setup: None,
            n: 0,
            have_1d: 0,
            have_2d: 0,
            lanes: Lanes {
                key: [0; WAVE_LANES],
                mix0: [0; WAVE_LANES],
                mix1: [0; WAVE_LANES],
                smod: [0; WAVE_LANES],
                dim: [0; WAVE_LANES],
                hashes: [[0; WAVE_LANES]; 4],
                out: [[0.0; WAVE_LANES]; BOUNCE_DIMS as usize],
            },
        }
    }

    /// Whether streams of this render can be drawn here: the stratified or padded sampler with a
    /// power-of-two sample count whose 2D grid has power-of-two sides above 1.
    #[inline]
    pub fn covers(s: &SampleStream) -> bool {
        let st = &s.setup;
        st.fast && st.pow2_1d && st.pow2_xy
    }

    /// Starts a wave's bounce: no lanes, no numbers.
    #[inline]
    pub fn begin(&mut self) {
        self.n = 0;
        self.have_1d = 0;
        self.have_2d = 0;
    }

    /// Adds the stream of the next lane, at the dimension its bounce starts from; the k-th lane
    /// pushed takes its numbers through [`Drawn::new`]`(stream, self, k)`. Requires
    /// [`Self::covers`], fewer than [`WAVE_LANES`] lanes, and the same render's streams in one
    /// wave.
    #[inline]
    pub fn push(&mut self, s: &SampleStream) {
        debug_assert!(Self::covers(s) && self.n < WAVE_LANES);
        let k = self.n;
        self.n += 1;
        if k == 0 {
            self.setup = Some(s.setup);
        }
        let l = &mut self.lanes;
        l.key[k] = s.pixel_key;
        l.mix0[k] = s.sample_mix[0];
        l.mix1[k] = s.sample_mix[1];
        l.smod[k] = s.sample_mod;
        l.dim[k] = s.dim;
    }

    /// Computes the bounce numbers of the lanes pushed since [`Self::begin`]: the draws `need`
    /// names (in the bounce's order: light spare, light point, lobe, direction, roulette); a
    /// draw no lane will ask for is left to the stream (which skips it).
    pub fn run(&mut self, need: [bool; 5]) {
        self.run_draws(&DRAWS, &need);
    }

    /// Computes the camera's numbers of the lanes pushed since [`Self::begin`] (streams at their
    /// first dimension): the film position's 2D number (dimensions 0–1) and, if `lens`, the
    /// lens position's (2–3), as [`crate::render`]'s `film_and_lens` draws them.
    pub fn run_camera(&mut self, lens: bool) {
        self.run_draws(&CAMERA_DRAWS, &[true, lens]);
    }

    /// The draws `draws` (offset from each lane's pushed dimension, and whether 2D) of which
    /// `need` says some lane will ask for.
    fn run_draws(&mut self, draws: &[(usize, bool)], need: &[bool]) {
        debug_assert!(draws.len() == need.len() && draws.len() <= DRAWS.len());
        self.have_1d = 0;
        self.have_2d = 0;
        let Some(st) = self.setup else { return };
        if self.n == 0 {
            return;
        }
        // Which draws are stratified for every lane, hashed (padded) for every lane, or mixed
        // (a padded stream whose lanes sit on both sides of its stratified dimensions).
        let mut kinds = [Kind::Skip; DRAWS.len()];
        let kinds = &mut kinds[..draws.len()];
        let dims = &self.lanes.dim[..self.n];
        let lo = dims.iter().fold(u32::MAX, |a, &d| a.min(d));
        let hi = dims.iter().fold(0, |a, &d| a.max(d));
        let uniform = lo == hi;
        for (j, &(o, two)) in draws.iter().enumerate() {
            let last = o as u32 + two as u32;
            kinds[j] = if hi.saturating_add(last) < st.strat_dims {
                Kind::Stratified
            } else if lo.saturating_add(o as u32) >= st.strat_dims {
                Kind::Padded
            } else {
                Kind::Mixed
            };
            if !need[j] {
                kinds[j] = Kind::Skip;
            } else if two {
                self.have_2d |= 1 << o;
            } else {
                self.have_1d |= 1 << o;
            }
        }
        let c = Consts::of(&st);
        match self.level {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `level` is only AVX-512 or AVX2 when the running CPU has those features
            // (`with_level` falls back to portable otherwise), which is what the
            // `#[target_feature]` copies require.
            SimdLevel::Avx512 => unsafe {
                kernel_avx512(&c, draws, kinds, uniform, self.n, &mut self.lanes)
            },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above, for AVX2.
            SimdLevel::Avx2 => unsafe {
                kernel_avx2(&c, draws, kinds, uniform, self.n, &mut self.lanes)
            },
            _ => kernel::<CHUNK, false>(&c, draws, kinds, uniform, self.n, &mut self.lanes),
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// No lane of the wave will ask for this draw.
    Skip,
    Stratified,
    Padded,
    Mixed,
}

/// The render's sampler constants the kernel reads (the fields of [`SamplerSetup`] for a
/// power-of-two count and grid).
struct Consts {
    strat_dims: u32,
    mask_1d: u32,
    mask_2d: u32,
    mask_x: u32,
    mask_y: u32,
    log2_nx: u32,
    inv_spp: f32,
    inv_nx: f32,
    inv_ny: f32,
}

impl Consts {
    fn of(st: &SamplerSetup) -> Consts {
        Consts {
            strat_dims: st.strat_dims,
            mask_1d: st.mask_1d,
            mask_2d: st.mask_2d,
            mask_x: st.mask_x,
            mask_y: st.mask_y,
            log2_nx: st.log2_nx,
            inv_spp: st.inv_spp,
            inv_nx: st.inv_nx,
            inv_ny: st.inv_ny,
        }
    }
}

/// `u32_to_unit_f32`: the top 24 bits as a float in [0, 1). `x >> 8` is below 2²⁴, so the
/// signed conversion (one instruction at every SIMD width) gives the same float as the unsigned.
#[inline(always)]
fn unit(x: u32) -> f32 {
    ((x >> 8) as i32 as f32) * (1.0 / (1u32 << 24) as f32)
}

/// The dimension's term of `SampleStream::dim_hash`: the same for every lane of a wave whose
/// paths are all at one dimension (they are, in the path tracer), so computed once then.
#[inline(always)]
fn dim_term(d: u32) -> u64 {
    (d as u64).wrapping_mul(0xA24BAED4963EE407)
}

/// `SampleStream::padding`.
#[inline(always)]
fn padding(key: u64, mix0: u64, d: u32) -> u64 {
    mix64((key ^ mix0).wrapping_add((d as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)))
}

/// The 64-bit half of a stratified number: the dimension's hash `h` and the jitter hash `j`,
/// as their low and high words `[h, h >> 32, j, j >> 32]`. Kept apart from the 32-bit half
/// ([`strat_1d_finish`], [`strat_2d_finish`]) so each runs in a loop of its own, at its own
/// vector width (four 64-bit or eight 32-bit lanes per AVX2 register).
#[inline(always)]
fn strat_hashes(key: u64, mix1: u64, dim_term: u64) -> [u32; 4] {
    let h = mix64(key ^ dim_term);
    let j = mix64(h ^ mix1);
    [h as u32, (h >> 32) as u32, j as u32, (j >> 32) as u32]
}

/// `SampleStream::stratified_1d` for a power-of-two count, from [`strat_hashes`].
#[inline(always)]
fn strat_1d_finish(c: &Consts, smod: u32, h: u32, j: u32) -> f32 {
    let jitter = unit(j);
    let stratum = permute_pow2(smod, h, c.mask_1d);
    ((stratum as i32 as f32 + jitter) * c.inv_spp).min(ONE_MINUS_EPSILON)
}

/// `SampleStream::stratified_2d` for a power-of-two grid (`permute_pow2_pair` is
/// `permute_pow2` twice), from [`strat_hashes`].
#[inline(always)]
fn strat_2d_finish(c: &Consts, smod: u32, [h, hp, jl, jh]: [u32; 4]) -> (f32, f32) {
    let (px, py) = (hp.wrapping_mul(0xa511_e9b3), hp.wrapping_mul(0x63d8_3595));
    let jx = unit(jl);
    let jy = unit(jh);
    let cell = permute_pow2(smod, h, c.mask_2d);
    let (cx, cy) = (cell & c.mask_x, cell >> c.log2_nx);
    let sub_x = permute_pow2(cy, px, c.mask_y);
    let sub_y = permute_pow2(cx, py, c.mask_x);
    let x = (cx as i32 as f32 + (sub_x as i32 as f32 + jx) * c.inv_ny) * c.inv_nx;
    let y = (cy as i32 as f32 + (sub_y as i32 as f32 + jy) * c.inv_nx) * c.inv_ny;
    (x.min(ONE_MINUS_EPSILON), y.min(ONE_MINUS_EPSILON))
}

/// `SampleStream::stratified_1d` for a power-of-two count.
#[inline(always)]
fn strat_1d(c: &Consts, key: u64, mix1: u64, smod: u32, d: u32) -> f32 {
    let [h, _, j, _] = strat_hashes(key, mix1, dim_term(d));
    strat_1d_finish(c, smod, h, j)
}

/// `SampleStream::stratified_2d` for a power-of-two grid.
#[inline(always)]
fn strat_2d(c: &Consts, key: u64, mix1: u64, smod: u32, d: u32) -> (f32, f32) {
    strat_2d_finish(c, smod, strat_hashes(key, mix1, dim_term(d)))
}

/// [`strat_hashes`] of the first `n` lanes at dimension `dim + off` into `hashes` (word by word),
/// with the dimension's term computed once when every lane is at one dimension (`uniform`).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn fill_hashes(
    n: usize,
    off: u32,
    uniform: bool,
    key: &[u64; WAVE_LANES],
    mix1: &[u64; WAVE_LANES],
    dim: &[u32; WAVE_LANES],
    hashes: &mut [[u32; WAVE_LANES]; 4],
) {
    let mut put = |k: usize, h: [u32; 4]| {
        for (w, x) in hashes.iter_mut().zip(h) {
            w[k] = x;
        }
    };
    if uniform {
        let t = dim_term(dim[0].wrapping_add(off));
        for k in 0..n {
            put(k, strat_hashes(key[k], mix1[k], t));
        }
    } else {
        for k in 0..n {
            put(
                k,
                strat_hashes(key[k], mix1[k], dim_term(dim[k].wrapping_add(off))),
            );
        }
    }
}

/// [`fill_hashes`] with AVX-512's 64-bit multiplication (`vpmullq`, DQ) on 256-bit registers
/// (VL): four lanes per instruction where AVX2 needs three `vpmuludq`, two shifts and two adds
/// per multiplication. It stays at 256 bits on purpose: the kernel compiled for 512-bit
/// registers (eight 64-bit, sixteen 32-bit lanes) rendered 7–8 % slower than the AVX2 copy on
/// this Xeon although the kernel alone ran faster, as the core slows down around bursts of
/// 512-bit multiplications (BENCHMARKS.md, "Wavefront path loop"). Written with intrinsics
/// because the loop vectorizer, given AVX-512, picks the 512-bit registers.
///
/// # Safety
/// The CPU must have AVX-512 F, DQ and VL (`SimdLevel::Avx512`). `n` must be a multiple of 4
/// and at most [`WAVE_LANES`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2")]
unsafe fn fill_hashes_vl(
    n: usize,
    off: u32,
    uniform: bool,
    key: &[u64; WAVE_LANES],
    mix1: &[u64; WAVE_LANES],
    dim: &[u32; WAVE_LANES],
    hashes: &mut [[u32; WAVE_LANES]; 4],
) {
    use std::arch::x86_64::*;
    debug_assert!(n.is_multiple_of(4) && n <= WAVE_LANES);
    let mix = |mut x: __m256i| {
        x = _mm256_xor_si256(x, _mm256_srli_epi64::<30>(x));
        x = _mm256_mullo_epi64(x, _mm256_set1_epi64x(0xbf58476d1ce4e5b9u64 as i64));
        x = _mm256_xor_si256(x, _mm256_srli_epi64::<27>(x));
        x = _mm256_mullo_epi64(x, _mm256_set1_epi64x(0x94d049bb133111ebu64 as i64));
        _mm256_xor_si256(x, _mm256_srli_epi64::<31>(x))
    };
    let words = |x: __m256i| {
        (
            _mm256_cvtepi64_epi32(x),
            _mm256_cvtepi64_epi32(_mm256_srli_epi64::<32>(x)),
        )
    };
    let t_all = _mm256_set1_epi64x(dim_term(dim[0].wrapping_add(off)) as i64);
    for k in (0..n.min(WAVE_LANES)).step_by(4) {
        // SAFETY: k + 4 ≤ n ≤ WAVE_LANES, so every load and store is inside its array (the
        // unaligned forms are used).
        unsafe {
            let t = if uniform {
                t_all
            } else {
                let d = _mm_add_epi32(
                    _mm_loadu_si128(dim.as_ptr().add(k).cast()),
                    _mm_set1_epi32(off as i32),
                );
                _mm256_mullo_epi64(
                    _mm256_cvtepu32_epi64(d),
                    _mm256_set1_epi64x(0xA24BAED4963EE407u64 as i64),
                )
            };
            let kv = _mm256_loadu_si256(key.as_ptr().add(k).cast());
            let h = mix(_mm256_xor_si256(kv, t));
            let m = _mm256_loadu_si256(mix1.as_ptr().add(k).cast());
            let j = mix(_mm256_xor_si256(h, m));
            let (hl, hh) = words(h);
            let (jl, jh) = words(j);
            for (w, v) in hashes.iter_mut().zip([hl, hh, jl, jh]) {
                _mm_storeu_si128(w.as_mut_ptr().add(k).cast(), v);
            }
        }
    }
}

/// [`fill_hashes`], or [`fill_hashes_vl`] in the `avx512` copy (`VL512`). A function rather than
/// a closure in [`kernel`]: a closure is not inlined into the `#[target_feature]` copies and is
/// compiled without their features (callgrind: +9 % instructions on the Cornell box).
#[inline(always)]
fn fill_hashes_at<const VL512: bool>(
    n: usize,
    off: u32,
    uniform: bool,
    key: &[u64; WAVE_LANES],
    mix1: &[u64; WAVE_LANES],
    dim: &[u32; WAVE_LANES],
    hashes: &mut [[u32; WAVE_LANES]; 4],
) {
    if VL512 {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `VL512` is only set by `kernel_avx512`, which runs only where the CPU has
        // AVX-512 F/DQ/VL; `n` is a multiple of `CHUNK` (8).
        unsafe {
            fill_hashes_vl(n, off, uniform, key, mix1, dim, hashes)
        };
    } else {
        fill_hashes(n, off, uniform, key, mix1, dim, hashes);
    }
}

/// The draws over the first `n` lanes, one loop per draw and kind (the kind is the same for
/// every lane of a loop, so its body is straight-line integer and float code over arrays: what
/// the loop vectorizer widens to the instruction set of the copy it is inlined into).
// Index loops over parallel arrays (rather than zipped iterators of six arrays): the form the
// loop vectorizer handles.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn kernel<const CH: usize, const VL512: bool>(
    c: &Consts,
    draws: &[(usize, bool)],
    kinds: &[Kind],
    uniform: bool,
    n: usize,
    l: &mut Lanes,
) {
    // Whole chunks of `CH` lanes, so each loop's trip count is a multiple of the vector width
    // and no scalar remainder runs (a bounce of a wave has ~10 live paths on average in the
    // Cornell box: a remainder loop would be most of the work). The lanes past `n` compute
    // numbers from earlier waves' inputs that nobody reads.
    let n = n.div_ceil(CH).min(WAVE_LANES / CH) * CH;
    let Lanes {
        key,
        mix0,
        mix1,
        smod,
        dim,
        hashes,
        out,
    } = l;
    for (&(o, two), &kind) in draws.iter().zip(kinds) {
        let off = o as u32;
        if two {
            let (xs, ys) = out.split_at_mut(o + 1);
            let (xs, ys) = (&mut xs[o], &mut ys[0]);
            let padded = |k: usize| {
                let h = padding(key[k], mix0[k], dim[k].wrapping_add(off));
                (unit(h as u32), unit((h >> 32) as u32))
            };
            match kind {
                Kind::Skip => {}
                Kind::Stratified => {
                    fill_hashes_at::<VL512>(n, off, uniform, key, mix1, dim, hashes);
                    for k in 0..n {
                        let h = [hashes[0][k], hashes[1][k], hashes[2][k], hashes[3][k]];
                        (xs[k], ys[k]) = strat_2d_finish(c, smod[k], h);
                    }
                }
                Kind::Padded => {
                    for k in 0..n {
                        (xs[k], ys[k]) = padded(k);
                    }
                }
                Kind::Mixed => {
                    for k in 0..n {
                        let d = dim[k].wrapping_add(off);
                        let s = strat_2d(c, key[k], mix1[k], smod[k], d);
                        let p = padded(k);
                        (xs[k], ys[k]) = if d < c.strat_dims { s } else { p };
                    }
                }
            }
        } else {
            let xs = &mut out[o];
            let padded = |k: usize| unit(padding(key[k], mix0[k], dim[k].wrapping_add(off)) as u32);
            match kind {
                Kind::Skip => {}
                Kind::Stratified => {
                    fill_hashes_at::<VL512>(n, off, uniform, key, mix1, dim, hashes);
                    for k in 0..n {
                        xs[k] = strat_1d_finish(c, smod[k], hashes[0][k], hashes[2][k]);
                    }
                }
                Kind::Padded => {
                    for k in 0..n {
                        xs[k] = padded(k);
                    }
                }
                Kind::Mixed => {
                    for k in 0..n {
                        let d = dim[k].wrapping_add(off);
                        let s = strat_1d(c, key[k], mix1[k], smod[k], d);
                        let p = padded(k);
                        xs[k] = if d < c.strat_dims { s } else { p };
                    }
                }
            }
        }
    }
}

/// [`kernel`] compiled for AVX2: eight 32-bit or four 64-bit lanes per instruction.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn kernel_avx2(
    c: &Consts,
    draws: &[(usize, bool)],
    kinds: &[Kind],
    uniform: bool,
    n: usize,
    l: &mut Lanes,
) {
    kernel::<CHUNK, false>(c, draws, kinds, uniform, n, l)
}

/// [`kernel`] for the `avx512` level: the AVX2 copy, whose stratified draws hash their 64-bit
/// words with AVX-512's 256-bit `vpmullq` ([`fill_hashes_vl`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn kernel_avx512(
    c: &Consts,
    draws: &[(usize, bool)],
    kinds: &[Kind],
    uniform: bool,
    n: usize,
    l: &mut Lanes,
) {
    kernel::<CHUNK, true>(c, draws, kinds, uniform, n, l)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{SamplerKind, SamplerSetup};

    /// Every copy of the kernel computes, for every lane, the numbers the lane's own stream gives
    /// when asked for them one by one (compared with the kernel's output directly, so a wrong
    /// kernel cannot hide behind [`Drawn`]'s fallback): the stratified and padded samplers at
    /// every covered count; waves of one and of several dimensions, starting below, across and
    /// above the padded sampler's stratified dimensions; waves shorter than the kernel's
    /// width; and draws left out. Through [`Drawn`] every order of requests a bounce makes
    /// (each 1D number drawn or skipped) and one it does not (2D where a 1D number was planned)
    /// gives the stream's numbers and leaves the stream where the stream would be.
    #[test]
    fn every_level_draws_the_streams_numbers() {
        let mut checked = 0;
        for level in SimdLevel::ALL {
            if !level.available() {
                eprintln!("{level}: not on this CPU");
                continue;
            }
            for kind in [SamplerKind::Stratified, SamplerKind::Padded] {
                for spp in [4u32, 16, 64, 256, 1024, 65536] {
                    let setup = SamplerSetup::new(kind, 7 + spp as u64, spp).for_image(64, 64);
                    let waves = [
                        (32usize, 4u32, 1u32, [true; 5]),
                        (5, 10, 3, [true; 5]),
                        (32, 13, 3, [false, true, false, true, true]),
                        (17, 16, 1, [true, true, false, true, false]),
                        (32, 60, 2, [true; 5]),
                        (1, 9, 1, [false, false, true, true, true]),
                    ];
                    for (wave, start, spread, need) in waves {
                        let mut draw = WaveDraw::with_level(level);
                        let mut streams: Vec<SampleStream> = (0..wave)
                            .map(|k| {
                                let px = (k as u32 * 7 % 64, k as u32 * 13 % 64);
                                let sample = (k as u32).wrapping_mul(2_654_435_761) % (2 * spp);
                                let mut s = setup.stream(setup.pixel_key(px), sample);
                                // With `spread` > 1 the lanes sit a few dimensions apart, as
                                // the path tracer's never do, for waves whose lanes straddle
                                // the stratified dimensions.
                                s.skip(start + k as u32 % spread);
                                s
                            })
                            .collect();
                        assert!(WaveDraw::covers(&streams[0]));
                        draw.begin();
                        for s in &streams {
                            draw.push(s);
                        }
                        draw.run(need);
                        let what =
                            format!("{level} {kind:?} {spp} spp, wave of {wave} from {start}");
                        for (k, s) in streams.iter_mut().enumerate() {
                            // The kernel's numbers against the stream's, in the bounce's order.
                            let mut lazy = s.clone();
                            for (&(o, two), &needed) in DRAWS.iter().zip(&need) {
                                let (x, y) = if two {
                                    let p = lazy.next_2d();
                                    (p.x, Some(p.y))
                                } else {
                                    (lazy.next_1d(), None)
                                };
                                let have = if two { draw.have_2d } else { draw.have_1d };
                                assert_eq!(have & (1 << o) != 0, needed, "{what}");
                                if !needed {
                                    continue;
                                }
                                let out = &draw.lanes.out;
                                assert_eq!(
                                    out[o][k].to_bits(),
                                    x.to_bits(),
                                    "{what}, lane {k}, {o}"
                                );
                                if let Some(y) = y {
                                    assert_eq!(out[o + 1][k].to_bits(), y.to_bits(), "{what}, {k}");
                                }
                                checked += 1;
                            }
                            // Through `Drawn`: the eight ways a bounce asks (each 1D number
                            // drawn or skipped), then a 2D request where a 1D one was planned.
                            let mut orders: Vec<Vec<(bool, bool)>> = (0..8)
                                .map(|m| {
                                    (0..5)
                                        .map(|j| match j {
                                            1 | 3 => (true, true),
                                            _ => (false, m >> (j / 2) & 1 == 1),
                                        })
                                        .collect()
                                })
                                .collect();
                            orders.push(vec![(true, true); 3]);
                            for order in orders {
                                let mut own = s.clone();
                                let mut lazy = s.clone();
                                let mut d = Drawn::new(&mut own, &draw, k);
                                for (two, asked) in order {
                                    match (two, asked) {
                                        (true, _) => assert_eq!(
                                            d.next_2d().to_array().map(f32::to_bits),
                                            lazy.next_2d().to_array().map(f32::to_bits),
                                            "{what}, lane {k}"
                                        ),
                                        (false, true) => assert_eq!(
                                            d.next_1d().to_bits(),
                                            lazy.next_1d().to_bits(),
                                            "{what}, lane {k}"
                                        ),
                                        (false, false) => {
                                            d.skip(1);
                                            lazy.skip(1);
                                        }
                                    }
                                }
                                assert_eq!(own.dim, lazy.dim);
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }

    /// The camera's numbers ([`WaveDraw::run_camera`]): the film's and, with a lens, the lens's
    /// 2D numbers of each lane's stream from its first dimension, at every level; without a lens
    /// the lens's dimensions are left to the stream.
    #[test]
    fn every_level_draws_the_camera_numbers() {
        for level in SimdLevel::ALL.into_iter().filter(|l| l.available()) {
            for spp in [4u32, 64, 1024] {
                let setup = SamplerSetup::new(SamplerKind::Stratified, 11, spp);
                for (lanes, lens) in [(32usize, true), (9, false), (32, false)] {
                    let mut draw = WaveDraw::with_level(level);
                    let mut streams: Vec<SampleStream> = (0..lanes)
                        .map(|k| setup.stream(setup.pixel_key((k as u32, 3)), k as u32 * 5 % spp))
                        .collect();
                    draw.begin();
                    for s in &streams {
                        draw.push(s);
                    }
                    draw.run_camera(lens);
                    assert_eq!((draw.have_2d, draw.have_1d), (1 | (lens as u32) << 2, 0));
                    for (k, s) in streams.iter_mut().enumerate() {
                        let mut lazy = s.clone();
                        let (film, lens_point) = (lazy.next_2d(), lazy.next_2d());
                        let out = &draw.lanes.out;
                        assert_eq!(
                            [out[0][k], out[1][k]].map(f32::to_bits),
                            film.to_array().map(f32::to_bits),
                            "{level} {spp} spp, lane {k}"
                        );
                        if lens {
                            assert_eq!(
                                [out[2][k], out[3][k]].map(f32::to_bits),
                                lens_point.to_array().map(f32::to_bits),
                                "{level} {spp} spp, lane {k}"
                            );
                        }
                        let mut d = Drawn::new(s, &draw, k);
                        assert_eq!(d.next_2d().to_array(), film.to_array());
                        assert_eq!(d.next_2d().to_array(), lens_point.to_array());
                        assert_eq!(s.dim, lazy.dim);
                    }
                }
            }
        }
    }

    /// A wave's bounce without [`WaveDraw::run`] (a sampler the kernel does not cover) hands
    /// out nothing: every number comes from the stream.
    #[test]
    fn a_bounce_without_a_run_draws_from_the_stream() {
        let setup = SamplerSetup::new(SamplerKind::Stratified, 3, 16);
        let mut draw = WaveDraw::new();
        let mut s = setup.stream(setup.pixel_key((1, 2)), 5);
        s.skip(4);
        draw.begin();
        draw.push(&s);
        draw.run([true; 5]);
        // The next bounce starts, and this time nothing is drawn for the wave.
        draw.begin();
        let mut lazy = s.clone();
        let mut d = Drawn::new(&mut s, &draw, 0);
        assert_eq!(d.next_1d().to_bits(), lazy.next_1d().to_bits());
        assert_eq!(d.next_2d().x.to_bits(), lazy.next_2d().x.to_bits());
        assert_eq!(draw.have_1d | draw.have_2d, 0);
    }
}
