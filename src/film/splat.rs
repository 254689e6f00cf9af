//! Splats: contributions that land on a film point other than the pixel whose sample made them
//! (light tracing and the t = 1 strategies of bidirectional path tracing connect a light subpath
//! to the camera wherever it projects; docs/DESIGN.md, integrators).
//!
//! A [`SplatBuffer`] covers the whole film window, one per worker thread and pass. Its sums are
//! the film's exact fixed-point integers ([`super::to_fixed`]), so adding the buffers of every
//! worker, in any order and however the samples were shared out, gives the same film: the image
//! stays a pure function of the seed and the settings for any thread count, split into sample
//! ranges or resumed. The pixel's sample count is kept by the film as before ([`Film::add_counts`]:
//! every pixel owns `spp` paths), so a pixel's value is (its own samples' sum + the splats that
//! reached it) / spp, which is pbrt-v4's `rgbSum / weightSum + rgbSplat / spp` for the estimators
//! that weigh every camera sample by 1 (filter importance sampling).

use super::filter::{Filter, FilterKind};
use super::{Film, SAMPLE_LIMIT, to_fixed};
use crate::math::{Vec2, Vec3};

/// Per-pixel exact sums of one worker's splats over the film window.
#[derive(Clone, Debug)]
pub struct SplatBuffer {
    /// The film window: its corner in image pixels and its size.
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
    sum: Vec<[i128; 3]>,
    /// Non-finite or too large contributions, dropped.
    pub discarded: u64,
    filter: SplatFilter,
}

/// How a splat at a film point is shared among the pixels around it: the reconstruction filter
/// normalised to integrate to 1 (pbrt-v4 `RGBFilm::AddSplat` divides by the filter's integral
/// when the film is read), so a splat's expected share of a pixel is what filter importance
/// sampling gives a camera sample of it.
#[derive(Clone, Copy, Debug)]
struct SplatFilter {
    filter: Filter,
    /// 1 / ∫∫ f.
    inv_integral: f32,
    /// The default one-pixel box: the pixel containing the point takes the whole splat.
    pixel_box: bool,
}

impl SplatFilter {
    fn new(filter: &Filter) -> SplatFilter {
        let axis = |a: usize| -> f64 {
            let r = filter.radius[a];
            match filter.kind {
                FilterKind::Box => 2.0 * r as f64,
                FilterKind::Tent => (r * r) as f64,
                _ => {
                    // Midpoint rule on a fine grid: the filters are smooth on their support.
                    let n = 4096;
                    let dx = 2.0 * r as f64 / n as f64;
                    (0..n)
                        .map(|i| {
                            filter.eval_1d(a, (-(r as f64) + (i as f64 + 0.5) * dx) as f32) as f64
                        })
                        .sum::<f64>()
                        * dx
                }
            }
        };
        let integral = axis(0) * axis(1);
        SplatFilter {
            filter: *filter,
            inv_integral: if integral != 0.0 {
                (1.0 / integral) as f32
            } else {
                0.0
            },
            pixel_box: filter.is_default_box(),
        }
    }
}

impl SplatBuffer {
    /// An empty buffer over the film window `x0..x0+w` × `y0..y0+h` (image pixels), splatting
    /// through `filter`.
    pub fn new(x0: u32, y0: u32, w: u32, h: u32, filter: &Filter) -> SplatBuffer {
        SplatBuffer {
            x0,
            y0,
            w,
            h,
            sum: vec![[0; 3]; w as usize * h as usize],
            discarded: 0,
            filter: SplatFilter::new(filter),
        }
    }

    /// Empties the buffer for the next pass (keeps its memory).
    pub fn clear(&mut self) {
        self.sum.iter_mut().for_each(|s| *s = [0; 3]);
        self.discarded = 0;
    }

    /// Adds `v` to image pixel (x, y) as it is, if it is in the window (the camera-side
    /// contribution of a pixel's own sample, already weighted by its filter sample).
    #[inline]
    pub fn add_pixel(&mut self, x: u32, y: u32, v: Vec3) {
        if !(v.x.abs() < SAMPLE_LIMIT && v.y.abs() < SAMPLE_LIMIT && v.z.abs() < SAMPLE_LIMIT) {
            self.discarded += 1;
            return;
        }
        if v == Vec3::ZERO {
            return;
        }
        let (Some(fx), Some(fy)) = (x.checked_sub(self.x0), y.checked_sub(self.y0)) else {
            return;
        };
        if fx >= self.w || fy >= self.h {
            return;
        }
        let s = &mut self.sum[(fy * self.w + fx) as usize];
        s[0] += to_fixed(v.x);
        s[1] += to_fixed(v.y);
        s[2] += to_fixed(v.z);
    }

    /// Splats `v` at the film point `raster` (image pixels, as [`crate::camera::Camera`]'s
    /// importance reports it) into the pixels the filter reaches, each weighted by the filter at
    /// its centre over the filter's integral. The point may lie outside the image (up to the
    /// filter's reach, where the camera's samples of edge pixels land too): its share of the
    /// pixels inside is kept.
    #[inline]
    pub fn splat(&mut self, raster: Vec2, v: Vec3) {
        if !(v.x.abs() < SAMPLE_LIMIT && v.y.abs() < SAMPLE_LIMIT && v.z.abs() < SAMPLE_LIMIT) {
            self.discarded += 1;
            return;
        }
        if v == Vec3::ZERO || !(raster.x.is_finite() && raster.y.is_finite()) {
            return;
        }
        let f = self.filter;
        if f.pixel_box {
            if raster.x >= 0.0 && raster.y >= 0.0 {
                self.add_pixel(raster.x as u32, raster.y as u32, v);
            }
            return;
        }
        let [rx, ry] = f.filter.radius;
        // Pixels whose centre (x + ½, y + ½) is within the radius of the point.
        let xa = (raster.x - 0.5 - rx).ceil().max(0.0) as u32;
        let xb = (raster.x - 0.5 + rx).floor().max(-1.0) as i64;
        let ya = (raster.y - 0.5 - ry).ceil().max(0.0) as u32;
        let yb = (raster.y - 0.5 + ry).floor().max(-1.0) as i64;
        for y in ya as i64..=yb {
            for x in xa as i64..=xb {
                let d = Vec2::new(x as f32 + 0.5 - raster.x, y as f32 + 0.5 - raster.y);
                let wt = f.filter.eval(d) * f.inv_integral;
                if wt != 0.0 {
                    self.add_pixel(x as u32, y as u32, v * wt);
                }
            }
        }
    }
}

impl Film {
    /// Adds a worker's splat sums (its window must be this film's). Exact: the order in which
    /// buffers are added does not change the film.
    pub fn add_splats(&mut self, buf: &SplatBuffer) {
        debug_assert_eq!((buf.w, buf.h), (self.width, self.height));
        for (s, b) in self.sum.iter_mut().zip(&buf.sum) {
            for c in 0..3 {
                s[c] += b[c];
            }
        }
        self.discarded = self.discarded.saturating_add(buf.discarded);
    }

    /// Counts `n` more samples in every pixel: each pixel owns the paths its samples started,
    /// wherever their contributions landed.
    pub fn add_counts(&mut self, n: u32) {
        for c in &mut self.count {
            *c += n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A splat's shares of the pixels sum to the splat, whatever the filter (so light reaching
    /// the film is neither lost nor created between pixels), and the box puts it in one pixel.
    #[test]
    fn splats_keep_their_total_across_pixels() {
        for kind in [
            FilterKind::Box,
            FilterKind::Tent,
            FilterKind::Gaussian,
            FilterKind::Mitchell,
            FilterKind::BlackmanHarris,
        ] {
            let filter = Filter::new(kind);
            let mut total = 0.0f64;
            let n = 64;
            for i in 0..n {
                let mut b = SplatBuffer::new(0, 0, 16, 16, &filter);
                let p = Vec2::new(
                    8.0 + (i as f32 * 0.618_034).fract(),
                    8.0 + (i as f32 * 0.414_214).fract(),
                );
                b.splat(p, Vec3::ONE);
                let mut f = Film::new(16, 16);
                f.add_splats(&b);
                f.add_counts(1);
                total += f.to_image().data.iter().map(|v| v.x as f64).sum::<f64>();
            }
            let mean = total / n as f64;
            assert!((mean - 1.0).abs() < 0.02, "{kind:?}: {mean}");
        }
        let mut b = SplatBuffer::new(2, 3, 4, 4, &Filter::default());
        b.splat(Vec2::new(3.99, 4.01), Vec3::splat(2.0));
        let mut f = Film::new(4, 4);
        f.add_splats(&b);
        f.add_counts(2);
        assert_eq!(f.pixel(1, 1), Vec3::ONE);
        assert_eq!(f.to_image().mean(), Vec3::splat(1.0 / 16.0));
    }
}
