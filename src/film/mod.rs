//! The film: linear radiance accumulated per pixel, the partial films of split and resumed renders
//! in [`partial`], and the image writers in [`output`].
//!
//! Sums are exact: every sample is converted to a fixed-point integer with [`FRAC_BITS`] fraction
//! bits and added as an `i128`. Integer addition is associative, so a pixel's sum does not depend
//! on how its samples were grouped (passes, tiles, a render split into sample ranges on several
//! machines, a render stopped and resumed): a merged or resumed film is bit-identical to a single
//! run. A floating-point sum would not be (`(a + b) + c != a + (b + c)` in general).

pub mod aov;
pub mod filter;
pub mod output;
pub mod splat;
pub mod tonemap;

use crate::math::Vec3;

/// Fraction bits of the fixed-point sums: a sample is truncated (towards zero) to a multiple of
/// 2⁻⁶⁰ ≈ 8.7·10⁻¹⁹, far below what an f32 image can show for any pixel value above ~10⁻¹¹.
pub const FRAC_BITS: u32 = 60;

/// Largest sample magnitude that is accumulated: 2⁴⁶ ≈ 7·10¹³. With at most 2²⁰ samples per pixel
/// ([`crate::render::MAX_SPP`]) a sum stays below 2⁴⁶⁺⁶⁰⁺²⁰ = 2¹²⁶, inside an `i128`. Larger (and
/// non-finite) samples are discarded and counted, like NaNs.
pub const SAMPLE_LIMIT: f32 = (1u64 << 46) as f32;

/// `v · 2^FRAC_BITS` truncated towards zero, exactly (from the float's bits: no rounding step
/// whose result could depend on anything but `v`). `|v|` must be below [`SAMPLE_LIMIT`].
#[inline]
pub fn to_fixed(v: f32) -> i128 {
    let bits = v.to_bits();
    let exp = ((bits >> 23) & 0xff) as i32;
    let frac = (bits & 0x7f_ffff) as i128;
    // v = mant · 2^e (IEEE 754 binary32; exponent 0 is subnormal).
    let (mant, e) = if exp == 0 {
        (frac, -149)
    } else {
        (frac | 0x80_0000, exp - 150)
    };
    let shift = e + FRAC_BITS as i32;
    let mag = if shift >= 0 {
        mant << shift
    } else if shift > -24 {
        mant >> -shift
    } else {
        0
    };
    if bits >> 31 == 1 { -mag } else { mag }
}

/// A fixed-point sum divided by a sample count, as an f32 mean.
#[inline]
fn fixed_mean(sum: i128, n: u32) -> f32 {
    // 2^-60 is exact in f64; `i128 as f64` rounds to nearest; both depend only on (sum, n).
    (sum as f64 * (1.0 / (1u64 << FRAC_BITS) as f64) / n as f64) as f32
}

/// Per-pixel exact fixed-point sums of radiance samples and their counts; samples that are not
/// finite or exceed [`SAMPLE_LIMIT`] are discarded and counted.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[i128; 3]>,
    count: Vec<u32>,
    /// Exact sums of the squared luminance of each sample (see [`FilmBlock::add_tracked`]), for
    /// the per-pixel variance that adaptive sampling and the `variance` layer use. All zero when
    /// the render does not track variance.
    sq: Vec<i128>,
    /// Per pixel, how many of its accepted samples' camera rays hit geometry (OpenEXR's alpha,
    /// `--transparent`): an exact count, so coverage merges across parts and checkpoints like
    /// the sums. `None` when the render does not track it ([`Film::track_coverage`]).
    cov: Option<Vec<u32>>,
    pub discarded: u64,
}

/// Rec. 709 luminance of a linear RGB value: what the variance and relative error are measured on.
#[inline]
pub fn luminance(l: Vec3) -> f32 {
    0.2126 * l.x + 0.7152 * l.y + 0.0722 * l.z
}

/// Largest squared luminance accumulated for the variance: with at most 2²⁰ samples the sums stay
/// below 2⁴⁵⁺⁶⁰⁺²⁰ < 2¹²⁷. A brighter sample still counts as very bright (the variance it shows
/// is large either way).
const SQ_LIMIT: f32 = (1u64 << 45) as f32;

/// Smallest mean luminance the relative error divides by: pixels darker than this are judged by
/// their absolute error over it (a black pixel with black samples is clean).
pub const REL_ERROR_FLOOR: f64 = 1e-4;

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sum: vec![[0; 3]; n],
            count: vec![0; n],
            sq: vec![0; n],
            cov: None,
            discarded: 0,
        }
    }

    /// This film, counting the coverage of its samples from now on (all zero so far).
    pub fn track_coverage(mut self) -> Film {
        self.cov = Some(vec![0; self.count.len()]);
        self
    }

    /// Per pixel, the accepted samples whose camera ray hit geometry, if tracked.
    pub fn coverage(&self) -> Option<&[u32]> {
        self.cov.as_deref()
    }

    /// The fraction of each pixel's samples that hit geometry (0 where a pixel has none), if
    /// coverage is tracked: the alpha channel of a `--transparent` render.
    pub fn alpha(&self) -> Option<Vec<f32>> {
        let cov = self.cov.as_ref()?;
        Some(
            cov.iter()
                .zip(&self.count)
                .map(|(&c, &n)| {
                    if n == 0 {
                        0.0
                    } else {
                        (c as f64 / n as f64) as f32
                    }
                })
                .collect(),
        )
    }

    /// A film read back with its coverage counts; `None` if their length does not match, or a
    /// pixel claims more covered samples than it has.
    pub fn with_coverage(mut self, cov: Vec<u32>) -> Option<Film> {
        if cov.len() != self.count.len() || cov.iter().zip(&self.count).any(|(c, n)| c > n) {
            return None;
        }
        self.cov = Some(cov);
        Some(self)
    }

    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    /// Adds a block of per-pixel sums (from one tile of one pass).
    pub fn add_block(&mut self, block: &FilmBlock) {
        for by in 0..block.h {
            for bx in 0..block.w {
                let i = self.index(block.x0 + bx, block.y0 + by);
                let j = (by * block.w + bx) as usize;
                for c in 0..3 {
                    self.sum[i][c] += block.sum[j][c];
                }
                self.count[i] += block.count[j];
                if let Some(sq) = &block.sq {
                    self.sq[i] += sq[j];
                }
                if let (Some(cov), Some(b)) = (&mut self.cov, &block.cov) {
                    cov[i] += b[j];
                }
            }
        }
        self.discarded = self.discarded.saturating_add(block.discarded);
    }

    /// Adds another film of the same size (another sample range of the same frame). Exact, so
    /// the order in which parts are added does not change the result. Fails on a size mismatch or
    /// if a sum or count would overflow (only possible for parts that do not belong together).
    pub fn add_film(&mut self, other: &Film) -> Result<(), String> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(format!(
                "film sizes differ: {}x{} and {}x{}",
                self.width, self.height, other.width, other.height
            ));
        }
        for (i, (s, o)) in self.sum.iter_mut().zip(&other.sum).enumerate() {
            for c in 0..3 {
                s[c] = s[c]
                    .checked_add(o[c])
                    .ok_or_else(|| format!("the sums of pixel {i} overflow"))?;
            }
        }
        for (i, (n, o)) in self.count.iter_mut().zip(&other.count).enumerate() {
            *n = n
                .checked_add(*o)
                .ok_or_else(|| format!("the sample count of pixel {i} overflows"))?;
        }
        for (s, o) in self.sq.iter_mut().zip(&other.sq) {
            *s = s.saturating_add(*o);
        }
        match (&mut self.cov, &other.cov) {
            (Some(c), Some(o)) => {
                for (c, o) in c.iter_mut().zip(o) {
                    // Never above the count, which was checked not to overflow.
                    *c += *o;
                }
            }
            (None, None) => {}
            _ => {
                return Err(
                    "one part has coverage (alpha, --transparent) and the other not".into(),
                );
            }
        }
        // Saturating: parts of one frame never come near it, and a forged count must not wrap.
        self.discarded = self.discarded.saturating_add(other.discarded);
        Ok(())
    }

    /// The raw accumulators (for writing a partial film): fixed-point sums and sample counts.
    pub fn raw(&self) -> (&[[i128; 3]], &[u32]) {
        (&self.sum, &self.count)
    }

    /// A film from raw accumulators (a partial film read back); `None` if the lengths do not
    /// match the size.
    pub fn from_raw(
        width: u32,
        height: u32,
        sum: Vec<[i128; 3]>,
        count: Vec<u32>,
        discarded: u64,
    ) -> Option<Film> {
        let n = width as usize * height as usize;
        (sum.len() == n && count.len() == n).then_some(Film {
            width,
            height,
            sum,
            count,
            sq: vec![0; n],
            cov: None,
            discarded,
        })
    }

    /// Samples accumulated in each pixel (row-major).
    pub fn counts(&self) -> &[u32] {
        &self.count
    }

    /// The unbiased sample variance of pixel `i`'s luminance samples (0 with fewer than two
    /// samples, or when the render did not track variance).
    pub fn variance(&self, i: usize) -> f64 {
        let n = self.count[i];
        if n < 2 {
            return 0.0;
        }
        let scale = 1.0 / (1u64 << FRAC_BITS) as f64;
        let s = self.sum[i];
        let mean_y =
            (0.2126 * s[0] as f64 + 0.7152 * s[1] as f64 + 0.0722 * s[2] as f64) * scale / n as f64;
        let mean_sq = self.sq[i] as f64 * scale / n as f64;
        ((mean_sq - mean_y * mean_y) * n as f64 / (n - 1) as f64).max(0.0)
    }

    /// The relative standard error of pixel `i`'s mean luminance: √(variance / n) / mean, the
    /// mean floored at [`REL_ERROR_FLOOR`]. Infinite with fewer than two samples.
    pub fn relative_error(&self, i: usize) -> f64 {
        let n = self.count[i];
        if n < 2 {
            return f64::INFINITY;
        }
        let scale = 1.0 / (1u64 << FRAC_BITS) as f64;
        let s = self.sum[i];
        let mean_y =
            (0.2126 * s[0] as f64 + 0.7152 * s[1] as f64 + 0.0722 * s[2] as f64) * scale / n as f64;
        (self.variance(i) / n as f64).sqrt() / mean_y.abs().max(REL_ERROR_FLOOR)
    }

    /// Mean radiance of a pixel (black if it has no samples yet).
    #[inline]
    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        let i = self.index(x, y);
        let n = self.count[i];
        if n == 0 {
            return Vec3::ZERO;
        }
        let s = self.sum[i];
        Vec3::new(
            fixed_mean(s[0], n),
            fixed_mean(s[1], n),
            fixed_mean(s[2], n),
        )
    }

    /// The current estimate as a row-major linear RGB image.
    pub fn to_image(&self) -> Image {
        let mut data = Vec::with_capacity(self.sum.len());
        for y in 0..self.height {
            for x in 0..self.width {
                data.push(self.pixel(x, y));
            }
        }
        Image {
            width: self.width,
            height: self.height,
            data,
        }
    }
}

/// One tile's contribution during one pass.
#[derive(Clone, Debug)]
pub struct FilmBlock {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
    pub sum: Vec<[i128; 3]>,
    pub count: Vec<u32>,
    /// Squared-luminance sums when the render tracks variance ([`FilmBlock::tracked`]).
    pub sq: Option<Vec<i128>>,
    /// Coverage counts when the render tracks them ([`Film::track_coverage`]).
    pub cov: Option<Vec<u32>>,
    pub discarded: u64,
}

impl FilmBlock {
    /// A block that also sums squared luminance (for adaptive sampling and the variance layer).
    pub fn tracked(x0: u32, y0: u32, w: u32, h: u32) -> FilmBlock {
        let mut b = FilmBlock::new(x0, y0, w, h);
        b.sq = Some(vec![0; (w * h) as usize]);
        b
    }

    pub fn new(x0: u32, y0: u32, w: u32, h: u32) -> FilmBlock {
        let n = (w * h) as usize;
        FilmBlock {
            x0,
            y0,
            w,
            h,
            sum: vec![[0; 3]; n],
            count: vec![0; n],
            sq: None,
            cov: None,
            discarded: 0,
        }
    }

    /// This block, counting coverage ([`FilmBlock::add_covered`]).
    pub fn with_coverage(mut self) -> FilmBlock {
        self.cov = Some(vec![0; self.count.len()]);
        self
    }

    /// [`FilmBlock::add_tracked`] (or [`FilmBlock::add`] when `track` is false), then, if the
    /// sample was accepted and its camera ray hit geometry, one more covered sample for the
    /// pixel. Coverage counts only accepted samples, so it never exceeds the count.
    #[inline]
    pub fn add_covered(&mut self, x: u32, y: u32, l: Vec3, track: bool, covered: bool) {
        let before = self.discarded;
        if track {
            self.add_tracked(x, y, l);
        } else {
            self.add(x, y, l);
        }
        if covered
            && before == self.discarded
            && let Some(cov) = &mut self.cov
        {
            cov[((y - self.y0) * self.w + (x - self.x0)) as usize] += 1;
        }
    }

    /// [`FilmBlock::add`], also summing the sample's squared luminance if the block is tracked.
    #[inline]
    pub fn add_tracked(&mut self, x: u32, y: u32, l: Vec3) {
        let before = self.discarded;
        self.add(x, y, l);
        if before == self.discarded
            && let Some(sq) = &mut self.sq
        {
            let j = ((y - self.y0) * self.w + (x - self.x0)) as usize;
            let yl = luminance(l);
            sq[j] += to_fixed((yl * yl).min(SQ_LIMIT));
        }
    }

    /// Adds one radiance sample for pixel (x, y) (image coordinates), discarding NaN/∞ and
    /// samples beyond [`SAMPLE_LIMIT`].
    #[inline]
    pub fn add(&mut self, x: u32, y: u32, l: Vec3) {
        let j = ((y - self.y0) * self.w + (x - self.x0)) as usize;
        // `!(a < b)` also rejects NaN.
        if !(l.x.abs() < SAMPLE_LIMIT && l.y.abs() < SAMPLE_LIMIT && l.z.abs() < SAMPLE_LIMIT) {
            self.discarded += 1;
            return;
        }
        self.sum[j][0] += to_fixed(l.x);
        self.sum[j][1] += to_fixed(l.y);
        self.sum[j][2] += to_fixed(l.z);
        self.count[j] += 1;
    }
}

/// A linear RGB image (row-major, top row first).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<Vec3>,
}

impl Image {
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.data[(y * self.width + x) as usize]
    }

    /// Mean of each channel.
    pub fn mean(&self) -> Vec3 {
        let mut s = [0.0f64; 3];
        for p in &self.data {
            s[0] += p.x as f64;
            s[1] += p.y as f64;
            s[2] += p.z as f64;
        }
        let n = self.data.len().max(1) as f64;
        Vec3::new((s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_samples_are_discarded_and_counted() {
        let mut f = Film::new(2, 1);
        let mut b = FilmBlock::new(0, 0, 2, 1);
        b.add(0, 0, Vec3::ONE);
        b.add(0, 0, Vec3::new(f32::NAN, 0.0, 0.0));
        b.add(0, 0, Vec3::splat(3.0));
        b.add(1, 0, Vec3::new(f32::INFINITY, 0.0, 0.0));
        f.add_block(&b);
        assert_eq!(f.discarded, 2);
        assert_eq!(f.pixel(0, 0), Vec3::splat(2.0));
        assert_eq!(f.pixel(1, 0), Vec3::ZERO);
    }

    /// The conversion is exact truncation of v·2⁶⁰: checked against f64 arithmetic (exact for
    /// these magnitudes) on normal, subnormal, negative and tiny values.
    #[test]
    fn fixed_point_conversion_is_exact_truncation() {
        let scale = (1u64 << FRAC_BITS) as f64;
        for v in [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            0.1,
            -0.3,
            1.5e-7,
            3.0e9,
            -7.0e13,
            1e-18,
            1e-19,
            f32::MIN_POSITIVE,
            1e-45,
            0.999_999_94,
        ] {
            let want = (v as f64 * scale).trunc();
            assert_eq!(to_fixed(v) as f64, want, "{v:e}");
        }
        assert_eq!(to_fixed(1.0), 1i128 << FRAC_BITS);
        assert_eq!(to_fixed(0.75), 3i128 << (FRAC_BITS - 2));
    }

    /// Sums do not depend on how samples are grouped: any split of a sample sequence into blocks
    /// added in any order gives the same film (the property merge and resume rely on), while the
    /// same values summed in f64 in two groupings differ.
    #[test]
    fn sums_do_not_depend_on_grouping() {
        let values: Vec<f32> = (0..1000)
            .map(|i| ((i as f32 * 0.618_034).fract() - 0.2) * 10f32.powi(i % 9 - 4))
            .collect();
        let film_of = |cuts: &[usize]| {
            let mut f = Film::new(1, 1);
            for g in cuts.windows(2).rev() {
                let mut b = FilmBlock::new(0, 0, 1, 1);
                for &v in &values[g[0]..g[1]] {
                    b.add(0, 0, Vec3::splat(v));
                }
                let mut part = Film::new(1, 1);
                part.add_block(&b);
                f.add_film(&part).unwrap();
            }
            f
        };
        let one = film_of(&[0, 1000]);
        assert_eq!(one, film_of(&[0, 1, 500, 999, 1000]));
        assert_eq!(one, film_of(&[0, 333, 334, 1000]));
        let f64_sum =
            |order: &mut dyn Iterator<Item = &f32>| order.fold(0.0f64, |a, &v| a + v as f64);
        assert_ne!(
            f64_sum(&mut values.iter()),
            f64_sum(&mut values.iter().rev()),
            "the f64 sums should show the problem the fixed point solves"
        );
    }
}
