//! The film: linear radiance accumulated per pixel, and the image writers in [`output`].

pub mod output;
pub mod tonemap;

use crate::math::Vec3;

/// Per-pixel sums of radiance samples and their counts. Sums are f64 so long renders do not lose
/// precision; non-finite samples are discarded and counted.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[f64; 3]>,
    count: Vec<u32>,
    pub discarded: u64,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Film {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            count: vec![0; n],
            discarded: 0,
        }
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
            }
        }
        self.discarded += block.discarded;
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
            (s[0] / n as f64) as f32,
            (s[1] / n as f64) as f32,
            (s[2] / n as f64) as f32,
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
    pub sum: Vec<[f64; 3]>,
    pub count: Vec<u32>,
    pub discarded: u64,
}

impl FilmBlock {
    pub fn new(x0: u32, y0: u32, w: u32, h: u32) -> FilmBlock {
        let n = (w * h) as usize;
        FilmBlock {
            x0,
            y0,
            w,
            h,
            sum: vec![[0.0; 3]; n],
            count: vec![0; n],
            discarded: 0,
        }
    }

    /// Adds one radiance sample for pixel (x, y) (image coordinates), discarding NaN/∞.
    #[inline]
    pub fn add(&mut self, x: u32, y: u32, l: Vec3) {
        let j = ((y - self.y0) * self.w + (x - self.x0)) as usize;
        if !l.is_finite() {
            self.discarded += 1;
            return;
        }
        self.sum[j][0] += l.x as f64;
        self.sum[j][1] += l.y as f64;
        self.sum[j][2] += l.z as f64;
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
}
