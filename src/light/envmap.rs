//! Environment maps, importance sampled with a 2D piecewise-constant distribution: a marginal
//! over rows and a conditional over each row's pixels (PBRT-v3 §14.2.4). Two parameterisations:
//!
//! * **Equirectangular** (`.hdr`, `.exr`; TOML and `--env`): texels weighted by luminance × sin θ
//!   so that the density is proportional to radiance per solid angle; a direction's solid-angle
//!   pdf is p(u, v) / (2π² sin θ), radiance is bilinearly filtered. Direction convention (Mitsuba
//!   3's `envmap`, so references agree): in the map's own frame +y is up, u = atan2(x, −z) / 2π
//!   (wrapped to [0, 1)), v = acos(y) / π with v = 0 the top row.
//! * **Equal-area square** (pbrt-v4's `infinite` light with a `filename`): Clarberg's octahedral
//!   mapping ([`crate::sampling::equal_area`]), every texel the same solid angle 4π / (w·h), so texels are
//!   weighted by luminance alone and the pdf is p(u, v) / 4π. Radiance is the nearest texel, as
//!   pbrt-v4's `ImageInfiniteLight::ImageLe` looks it up, so the sampling density is exactly
//!   proportional to the luminance of the function being integrated.

use crate::math::{Mat3, PI, Vec2, Vec3, floor_i64, luminance};
use crate::sampling::Distribution1D;
use crate::sampling::equal_area;
use std::path::Path;

/// Which density [`EnvMap::sample`] draws directions from and [`EnvMap::pdf`] reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum EnvPdf {
    /// In proportion to radiance: every direction the map lights is reachable.
    #[default]
    Full,
    /// MIS-compensated (radiance above the map's mean only): for next-event estimation that is
    /// combined by MIS with BSDF or phase-function sampling, never on its own.
    Compensated,
}

/// A piecewise-constant 2D distribution over the texels: a marginal over rows and a
/// conditional over each row's texels.
#[derive(Clone, Debug)]
struct TexelDistribution {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl TexelDistribution {
    /// From per-texel weights (row-major, `w` per row). A row's marginal weight is its true
    /// mean: `Distribution1D` would make an all-zero row uniform, and such a row must keep
    /// probability 0.
    fn new(w: usize, weights: &[f32]) -> TexelDistribution {
        let mut rows = Vec::with_capacity(weights.len() / w);
        let mut row_weights = Vec::with_capacity(weights.len() / w);
        for row in weights.chunks_exact(w) {
            let sum: f64 = row.iter().map(|&v| v as f64).sum();
            row_weights.push((sum / w as f64) as f32);
            rows.push(Distribution1D::new(row));
        }
        TexelDistribution {
            marginal: Distribution1D::new(&row_weights),
            rows,
        }
    }

    /// (uv, texel column, texel row, pdf in the unit square).
    #[inline]
    fn sample(&self, u: Vec2) -> (Vec2, usize, usize, f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (uu, pdf_u, col) = self.rows[row].sample_continuous(u.x);
        (Vec2::new(uu, v), col, row, pdf_u * pdf_v)
    }

    /// The density in the unit square on texel (x, y).
    #[inline]
    fn pdf(&self, x: usize, y: usize) -> f32 {
        let pm = self.marginal.func[y] / self.marginal.func_int;
        let row = &self.rows[y];
        pm * (row.func[x] / row.func_int)
    }
}

pub use crate::scene::EnvMapping;

#[derive(Clone, Debug)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    /// Linear RGB radiance, row-major from the top row.
    pub texels: Vec<Vec3>,
    pub scale: Vec3,
    pub mapping: EnvMapping,
    /// World-from-map rotation and its inverse.
    pub to_world: Mat3,
    pub to_local: Mat3,
    /// |det to_world|, for the solid-angle Jacobian of a non-rigid light transform.
    det: f32,
    /// Texels in proportion to their radiance (per solid angle): the density a light sample
    /// must have when it is the only strategy that can find a direction.
    full: TexelDistribution,
    /// The MIS-compensated density (Karlík et al. 2019, "MIS compensation: optimizing sampling
    /// techniques in multiple importance sampling"; pbrt-v4's `compensatedDistribution`):
    /// radiance minus the map's mean, clamped at 0. Directions dimmer than the mean are left to
    /// BSDF sampling, which finds them with MIS weight 1, and the light samples go to the
    /// bright parts. Only valid when combined by MIS with a strategy that covers every
    /// direction. `None` when nothing is brighter than the mean (a constant map).
    compensated: Option<TexelDistribution>,
    /// Mean luminance over the sphere (per steradian), for light selection by power.
    pub mean_luminance: f32,
}

impl EnvMap {
    /// Reads an equirectangular map. Errors are one-line messages (the caller names the file).
    pub fn load(path: &Path, scale: Vec3, to_world: Mat3) -> Result<EnvMap, String> {
        Self::load_mapped(path, scale, to_world, EnvMapping::Equirectangular)
    }

    /// Reads a map with the given parameterisation. Equal-area maps must be square and finite
    /// (pbrt-v4 refuses others), and may also be `.pfm`, `.png`, `.tga` or `.jpg` (8-bit images
    /// are sRGB-encoded, as pbrt-v4 reads them).
    pub fn load_mapped(
        path: &Path,
        scale: Vec3,
        to_world: Mat3,
        mapping: EnvMapping,
    ) -> Result<EnvMap, String> {
        if mapping == EnvMapping::EqualArea {
            let det = to_world.determinant();
            if !(det.is_finite() && det.abs() > 1e-12 && to_world.is_finite()) {
                return Err("the light's transform is singular or not finite".into());
            }
            let (w, h, texels) = read_image(path)?;
            if w != h {
                return Err(format!(
                    "the image is {w}×{h}, not square: pbrt-v4 reads infinite-light images as equal-area square maps"
                ));
            }
            if texels.iter().any(|t| !t.is_finite()) {
                return Err(
                    "the image has infinite or not-a-number pixels, so it cannot be a light".into(),
                );
            }
            return Ok(EnvMap::from_texels_mapped(
                w, h, texels, scale, to_world, mapping,
            ));
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        let (w, h, texels) = match ext.as_str() {
            "exr" => {
                let img = crate::film::output::read_exr(path).map_err(|e| e.to_string())?;
                (img.width, img.height, img.data)
            }
            "hdr" | "pic" | "rgbe" => {
                let img = image::ImageReader::open(path)
                    .map_err(|e| format!("cannot open environment map: {e}"))?
                    .with_guessed_format()
                    .map_err(|e| format!("cannot read environment map: {e}"))?
                    .decode()
                    .map_err(|e| format!("cannot decode environment map: {e}"))?
                    .into_rgb32f();
                let (w, h) = img.dimensions();
                let texels = img.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
                (w, h, texels)
            }
            _ => {
                return Err(format!(
                    "environment map must be an equirectangular .hdr or .exr (got '{}')",
                    path.display()
                ));
            }
        };
        if w == 0 || h == 0 {
            return Err("environment map is empty".into());
        }
        Ok(EnvMap::from_texels(w, h, texels, scale, to_world))
    }

    /// Builds an equirectangular map and its sampling distributions. Non-finite or negative
    /// texels become 0.
    pub fn from_texels(w: u32, h: u32, texels: Vec<Vec3>, scale: Vec3, to_world: Mat3) -> EnvMap {
        Self::from_texels_mapped(w, h, texels, scale, to_world, EnvMapping::Equirectangular)
    }

    /// Builds a map of either parameterisation and its sampling distributions (one construction:
    /// only the texels' solid-angle weights differ). Non-finite or negative texels become 0.
    pub fn from_texels_mapped(
        w: u32,
        h: u32,
        texels: Vec<Vec3>,
        scale: Vec3,
        to_world: Mat3,
        mapping: EnvMapping,
    ) -> EnvMap {
        let texels: Vec<Vec3> = texels
            .into_iter()
            .map(|t| {
                if t.is_finite() {
                    t.max(Vec3::ZERO)
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        // Each texel's luminance, computed once: the integral and both densities read it.
        let lum: Vec<f32> = texels.iter().map(|&t| luminance(t * scale)).collect();
        // ∫ L dω with each row's exact solid angle Δφ·(cos θ0 − cos θ1) (the sampling weights
        // below use sin θ at the row centre, which only needs to be proportional).
        let mut integral = 0.0f64;
        // Each row's sampling factor for its texels' solid angle: sin θ at the row centre
        // (equirectangular), 1 (equal-area).
        let mut sin_theta = Vec::with_capacity(h as usize);
        for y in 0..h as usize {
            let (row_omega, st) = match mapping {
                EnvMapping::Equirectangular => {
                    let (t0, t1) = (PI * y as f32 / h as f32, PI * (y + 1) as f32 / h as f32);
                    (
                        (2.0 * PI / w as f32) as f64 * (t0.cos() - t1.cos()) as f64,
                        (PI * (y as f32 + 0.5) / h as f32).sin(),
                    )
                }
                EnvMapping::EqualArea => (4.0 * PI as f64 / (w as f64 * h as f64), 1.0),
            };
            let lum_sum: f64 = lum[y * w as usize..(y + 1) * w as usize]
                .iter()
                .map(|&l| l.max(0.0) as f64)
                .sum();
            integral += lum_sum * row_omega;
            sin_theta.push(st);
        }
        let mean_luminance = (integral / (4.0 * PI as f64)) as f32;
        // Both densities are per texel (luminance − offset)⁺ × the texel's solid-angle factor,
        // so that per solid angle they are proportional to (radiance − offset)⁺.
        let weights = |offset: f32| -> Vec<f32> {
            lum.iter()
                .enumerate()
                .map(|(i, &l)| (l - offset).max(0.0) * sin_theta[i / w as usize])
                .collect()
        };
        let full_weights = weights(0.0);
        let compensated_weights = weights(mean_luminance);
        // A map (nearly) constant to rounding has nothing above its mean but rounding noise,
        // which must not become the whole light-sampling density: then NEE keeps the full one.
        let sum = |v: &[f32]| v.iter().map(|&x| x as f64).sum::<f64>();
        let compensated = (sum(&compensated_weights) > 1e-3 * sum(&full_weights))
            .then(|| TexelDistribution::new(w as usize, &compensated_weights));
        let full = TexelDistribution::new(w as usize, &full_weights);
        let to_local = to_world.inverse();
        let det = to_world.determinant().abs();
        EnvMap {
            det,
            width: w,
            height: h,
            texels,
            scale,
            mapping,
            to_world,
            to_local,
            full,
            compensated,
            mean_luminance,
        }
    }

    #[inline]
    pub fn dir_to_uv(d: Vec3) -> Vec2 {
        let mut u = d.x.atan2(-d.z) * (0.5 / PI);
        if u < 0.0 {
            u += 1.0;
        }
        Vec2::new(u, d.y.clamp(-1.0, 1.0).acos() / PI)
    }

    #[inline]
    pub fn uv_to_dir(uv: Vec2) -> Vec3 {
        let (st, ct) = (uv.y * PI).sin_cos();
        Self::polar_to_dir(st, ct, uv.x)
    }

    /// [`EnvMap::uv_to_dir`] with θ's sine and cosine already known.
    #[inline]
    fn polar_to_dir(st: f32, ct: f32, u: f32) -> Vec3 {
        let (sp, cp) = (u * 2.0 * PI).sin_cos();
        Vec3::new(st * sp, ct, -st * cp)
    }

    /// The equal-area map's texel index of world direction `d` (unit), and the Jacobian
    /// dω_map / dω_world of the light's transform there. The map direction is w = M⁻¹d / |M⁻¹d|
    /// as pbrt-v4's `Le` has it; for a linear map M the solid angles relate by
    /// dω_world / dω_map = |det M| / |M w|³, and |M w| = 1 / |M⁻¹d|, so the Jacobian is
    /// 1 / (|det M| · |M⁻¹d|³) (1 for a rotation or reflection).
    #[inline]
    fn equal_area_texel(&self, d: Vec3) -> (usize, f32) {
        let local = self.to_local * d;
        let len = local.length();
        let uv = equal_area::sphere_to_square(if len > 0.0 { local / len } else { Vec3::Z });
        let (w, h) = (self.width as usize, self.height as usize);
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        (y * w + x, 1.0 / (self.det * len * len * len))
    }

    /// The unfiltered radiance of the texel world direction `d` falls in (what the sampling
    /// densities are built from).
    #[cfg(test)]
    fn texel_radiance(&self, d: Vec3) -> Vec3 {
        if self.mapping == EnvMapping::EqualArea {
            return self.texels[self.equal_area_texel(d).0] * self.scale;
        }
        let uv = Self::dir_to_uv(self.to_local * d);
        let (w, h) = (self.width as usize, self.height as usize);
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        self.texels[y * w + x] * self.scale
    }

    /// The world direction through texel (x, y)'s centre.
    #[cfg(test)]
    fn texel_direction(&self, x: usize, y: usize) -> Vec3 {
        let uv = Vec2::new(
            (x as f32 + 0.5) / self.width as f32,
            (y as f32 + 0.5) / self.height as f32,
        );
        let local = match self.mapping {
            EnvMapping::EqualArea => equal_area::square_to_sphere(uv),
            EnvMapping::Equirectangular => Self::uv_to_dir(uv),
        };
        (self.to_world * local).normalize()
    }

    /// Radiance arriving from world direction `d` (unit): bilinearly filtered (equirectangular)
    /// or the nearest texel (equal-area, as pbrt-v4).
    #[inline]
    pub fn eval(&self, d: Vec3) -> Vec3 {
        if self.mapping == EnvMapping::EqualArea {
            return self.texels[self.equal_area_texel(d).0] * self.scale;
        }
        self.eval_uv(Self::dir_to_uv(self.to_local * d))
    }

    /// [`EnvMap::eval`] and [`EnvMap::pdf`] of one direction, mapping it to the image once (an
    /// escaped BSDF sample needs both; the mapping's `atan2`/`acos` dominate each).
    #[inline]
    pub fn eval_pdf(&self, d: Vec3, which: EnvPdf) -> (Vec3, f32) {
        if self.mapping == EnvMapping::EqualArea {
            let (i, jacobian) = self.equal_area_texel(d);
            return (
                self.texels[i] * self.scale,
                self.equal_area_pdf(i, jacobian, which),
            );
        }
        let uv = Self::dir_to_uv(self.to_local * d);
        (self.eval_uv(uv), self.pdf_uv(uv, which))
    }

    /// The bilinearly filtered radiance at map coordinates `uv` (equirectangular).
    #[inline]
    fn eval_uv(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        let ((x0, fx0), (y0, fy0)) = (floor_i64(x), floor_i64(y));
        let (tx, ty) = (x - fx0, y - fy0);
        // Columns wrap around, rows clamp. A direction's columns are x0 ∈ [−1, w − 1] and
        // x0 + 1 ∈ [0, w]: one compare each instead of a division (`rem_euclid`), kept for
        // anything else (non-finite coordinates).
        let wrap = |xi: i64| {
            if xi < 0 && xi >= -w {
                (xi + w) as usize
            } else if xi >= 0 && xi < w {
                xi as usize
            } else {
                xi.rem_euclid(w) as usize
            }
        };
        let (c0, c1) = (wrap(x0), wrap(x0 + 1));
        let r0 = y0.clamp(0, h - 1) as usize * w as usize;
        let r1 = (y0 + 1).clamp(0, h - 1) as usize * w as usize;
        let t = &self.texels;
        let a = t[r0 + c0] * (1.0 - tx) + t[r0 + c1] * tx;
        let b = t[r1 + c0] * (1.0 - tx) + t[r1 + c1] * tx;
        (a * (1.0 - ty) + b * ty) * self.scale
    }

    /// The distribution `which` names (the full one for a map with no compensated one).
    #[inline]
    fn distribution(&self, which: EnvPdf) -> &TexelDistribution {
        match (which, &self.compensated) {
            (EnvPdf::Compensated, Some(c)) => c,
            _ => &self.full,
        }
    }

    /// Samples a world direction toward the map from the density `which`; returns (direction,
    /// radiance, solid-angle pdf).
    #[inline]
    pub fn sample(&self, u: Vec2, which: EnvPdf) -> Option<(Vec3, Vec3, f32)> {
        let (uv, col, row, pdf_uv) = self.distribution(which).sample(u);
        if self.mapping == EnvMapping::EqualArea {
            // Uniform Jacobian: dω = 4π du dv. The radiance is the sampled texel's, so the
            // estimate L / pdf is exact for the piecewise-constant map.
            if !(pdf_uv > 0.0) {
                return None;
            }
            let m = self.to_world * equal_area::square_to_sphere(uv);
            let len = m.length();
            if !(len > 0.0) {
                return None;
            }
            // The map-to-world Jacobian (see `equal_area_texel`): |M w| = len.
            let jacobian = len * len * len / self.det;
            let l = self.texels[row * self.width as usize + col] * self.scale;
            return Some((m / len, l, pdf_uv * jacobian / (4.0 * PI)));
        }
        // sin θ once, for the Jacobian and the direction (glibc's `sincosf` and `sinf` agree bit
        // for bit on [0, π], checked for every f32 there).
        let (sin_theta, cos_theta) = (uv.y * PI).sin_cos();
        if !(sin_theta > 0.0) || !(pdf_uv > 0.0) {
            return None;
        }
        let pdf = pdf_uv / (2.0 * PI * PI * sin_theta);
        let d = (self.to_world * Self::polar_to_dir(sin_theta, cos_theta, uv.x)).normalize();
        // The radiance at the sampled map coordinates themselves: `eval(d)` would map `d` back
        // to them (up to rounding) through the light transform, `atan2` and `acos`, the most
        // expensive part of a light sample. The direction is the same (M⁻¹d ∝ the map direction
        // for any invertible M), so the expected image is too; the bits move with the rounding
        // the round trip no longer adds.
        Some((d, self.eval_uv(uv), pdf))
    }

    /// Solid-angle pdf with which [`EnvMap::sample`] with `which` produces world direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3, which: EnvPdf) -> f32 {
        if self.mapping == EnvMapping::EqualArea {
            let (i, jacobian) = self.equal_area_texel(d);
            return self.equal_area_pdf(i, jacobian, which);
        }
        self.pdf_uv(Self::dir_to_uv(self.to_local * d), which)
    }

    /// The equal-area map's solid-angle pdf on texel `i` with the light transform's Jacobian.
    #[inline]
    fn equal_area_pdf(&self, i: usize, jacobian: f32, which: EnvPdf) -> f32 {
        let (y, x) = (i / self.width as usize, i % self.width as usize);
        self.distribution(which).pdf(x, y) * jacobian / (4.0 * PI)
    }

    /// The equirectangular map's solid-angle pdf at map coordinates `uv`.
    #[inline]
    fn pdf_uv(&self, uv: Vec2, which: EnvPdf) -> f32 {
        let (w, h) = (self.width as usize, self.height as usize);
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        let p = self.distribution(which).pdf(x, y);
        // Most texels have no compensated density: 0 without the sine (the same 0 it would
        // divide to; a texel's density is finite and non-negative).
        if p == 0.0 {
            return 0.0;
        }
        let sin_theta = (uv.y * PI).sin();
        if !(sin_theta > 0.0) {
            return 0.0;
        }
        p / (2.0 * PI * PI * sin_theta)
    }
}

/// Reads any image an environment may be (EXR, Radiance HDR, PFM; PNG, TGA, JPEG as sRGB) into
/// linear RGB texels, top row first ([`crate::image_io::read_rgb`]).
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<Vec3>), String> {
    crate::image_io::read_rgb(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_mapping_round_trips() {
        for &d in &[
            Vec3::new(0.3, 0.5, -0.8).normalize(),
            Vec3::new(-0.7, -0.2, 0.1).normalize(),
        ] {
            let back = EnvMap::uv_to_dir(EnvMap::dir_to_uv(d));
            assert!((back - d).length() < 1e-5, "{d:?} -> {back:?}");
        }
        // Mitsuba's convention: −z is the centre of the map, +y its top.
        assert!(
            (EnvMap::dir_to_uv(Vec3::new(0.0, 0.0, -1.0)) - Vec2::new(0.0, 0.5)).length() < 1e-6
        );
        assert!(EnvMap::dir_to_uv(Vec3::Y).y < 1e-6);
    }

    #[test]
    fn constant_map_has_uniform_pdf_and_mean() {
        let m = EnvMap::from_texels(8, 4, vec![Vec3::ONE; 32], Vec3::splat(2.0), Mat3::IDENTITY);
        // Rows weighted by their exact solid angle: the mean is exact.
        assert!(
            (m.mean_luminance - 2.0).abs() < 1e-5,
            "{}",
            m.mean_luminance
        );
        assert!((m.eval(Vec3::X) - Vec3::splat(2.0)).length() < 1e-5);
        // A constant map is sampled uniformly over the sphere: pdf 1/4π. Rows are weighted by
        // sin θ at their centre, so at the row centres the pdf is h / (2π² Σ sin θ_y), which is
        // 1/4π to 3·10⁻⁴ for 32 rows (the midpoint rule for ∫ sin θ dθ = 2).
        let (w, h) = (64u32, 32u32);
        let m = EnvMap::from_texels(
            w,
            h,
            vec![Vec3::ONE; (w * h) as usize],
            Vec3::splat(2.0),
            Mat3::IDENTITY,
        );
        assert!((m.mean_luminance - 2.0).abs() < 1e-5);
        let uniform = 1.0 / (4.0 * PI);
        for y in 0..h {
            for x in 0..w {
                let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
                let d = EnvMap::uv_to_dir(uv);
                let pdf = m.pdf(d, EnvPdf::Full);
                assert!(
                    (pdf / uniform - 1.0).abs() < 1e-3,
                    "pdf at texel ({x}, {y}) = {pdf}, 1/4π = {uniform}"
                );
                assert!((m.eval(d) - Vec3::splat(2.0)).abs().max_element() < 1e-5);
            }
        }
        // The pdf integrates to 1 over the sphere (midpoint rule in θ and φ, dω = sin θ dθ dφ;
        // pdf · sin θ is constant over each row, so the rule is exact up to rounding), and
        // `sample` reports the pdf that `pdf` gives for the direction it returns.
        let n = 256;
        let mut total = 0.0f64;
        for i in 0..n {
            let theta = PI * (i as f32 + 0.5) / n as f32;
            let (st, ct) = theta.sin_cos();
            for j in 0..2 * n {
                let phi = PI * (j as f32 + 0.5) / n as f32;
                let d = Vec3::new(st * phi.cos(), ct, st * phi.sin());
                total += (m.pdf(d, EnvPdf::Full) * st) as f64;
            }
        }
        total *= (PI as f64 / n as f64).powi(2);
        assert!((total - 1.0).abs() < 1e-4, "∫ pdf dω = {total}");
        for i in 0..16 {
            for j in 0..16 {
                let u = Vec2::new((i as f32 + 0.37) / 16.0, (j as f32 + 0.61) / 16.0);
                let (d, l, pdf) = m.sample(u, EnvPdf::Full).expect("a sample");
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert!((l - Vec3::splat(2.0)).abs().max_element() < 1e-5, "{l}");
                assert!(
                    (pdf / m.pdf(d, EnvPdf::Full) - 1.0).abs() < 1e-3,
                    "sample pdf {pdf} vs pdf(d) {}",
                    m.pdf(d, EnvPdf::Full)
                );
            }
        }
    }

    /// A constant equal-area map (the furnace case): every direction has radiance L and pdf
    /// 1/4π, so the estimate L / pdf of ∫ L dω is exact for every sample, and the mean radiance
    /// is L. Non-square or non-finite images are refused when loaded.
    #[test]
    fn constant_equal_area_map_is_uniform() {
        let n = 32u32;
        let rot = Mat3::from_axis_angle(Vec3::new(1.0, 0.2, -0.4).normalize(), 2.0);
        let m = EnvMap::from_texels_mapped(
            n,
            n,
            vec![Vec3::new(0.5, 1.0, 2.0); (n * n) as usize],
            Vec3::splat(3.0),
            rot,
            EnvMapping::EqualArea,
        );
        let l = Vec3::new(1.5, 3.0, 6.0);
        assert!((m.mean_luminance - luminance(l)).abs() < 1e-4 * luminance(l));
        let uniform = 1.0 / (4.0 * PI);
        for i in 0..64 {
            for j in 0..64 {
                let u = Vec2::new((i as f32 + 0.31) / 64.0, (j as f32 + 0.77) / 64.0);
                let (d, li, pdf) = m.sample(u, EnvPdf::Full).expect("a sample");
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert!((li - l).abs().max_element() < 1e-5);
                assert!((pdf / uniform - 1.0).abs() < 1e-4, "{pdf}");
                assert!((m.pdf(d, EnvPdf::Full) / uniform - 1.0).abs() < 1e-4);
                assert!((m.eval(d) - l).abs().max_element() < 1e-5);
            }
        }
        let dir = std::env::temp_dir().join(format!("trayecto-envmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let pfm = |w: u32, h: u32, v: f32| {
            let mut b = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
            for _ in 0..w * h * 3 {
                b.extend_from_slice(&v.to_le_bytes());
            }
            b
        };
        let path = dir.join("wide.pfm");
        std::fs::write(&path, pfm(8, 4, 1.0)).unwrap();
        let e = EnvMap::load_mapped(&path, Vec3::ONE, Mat3::IDENTITY, EnvMapping::EqualArea)
            .unwrap_err();
        assert!(e.contains("not square"), "{e}");
        let path = dir.join("square.pfm");
        std::fs::write(&path, pfm(4, 4, 2.0)).unwrap();
        let m =
            EnvMap::load_mapped(&path, Vec3::ONE, Mat3::IDENTITY, EnvMapping::EqualArea).unwrap();
        assert_eq!(m.eval(Vec3::X), Vec3::splat(2.0));
        let singular = Mat3::from_diagonal(Vec3::new(1.0, 0.0, 1.0));
        assert!(EnvMap::load_mapped(&path, Vec3::ONE, singular, EnvMapping::EqualArea).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The MIS-compensated density is a density (integrates to 1), is what `sample` reports
    /// for the directions it returns, is 0 wherever the radiance is at most the map's mean and
    /// elsewhere proportional to (radiance − mean); a constant map has none and falls back to
    /// the full density. Both mappings, a rotated map.
    #[test]
    fn compensated_density_is_radiance_above_the_mean() {
        let (w, h) = (32u32, 16u32);
        // A dim gradient, one bright "lamp" of 2×2 texels and a medium stripe.
        let texels: Vec<Vec3> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let v = if (10..12).contains(&x) && (4..6).contains(&y) {
                    500.0
                } else if y == 12 {
                    3.0
                } else {
                    0.05 + 0.02 * x as f32
                };
                Vec3::new(v, 0.9 * v, 0.8 * v)
            })
            .collect();
        let rot = Mat3::from_axis_angle(Vec3::new(0.3, 1.0, -0.2).normalize(), 0.7);
        for mapping in [EnvMapping::Equirectangular, EnvMapping::EqualArea] {
            let (w, h) = if mapping == EnvMapping::EqualArea {
                (16, 16)
            } else {
                (w, h)
            };
            let m = EnvMap::from_texels_mapped(
                w,
                h,
                texels[..(w * h) as usize].to_vec(),
                Vec3::ONE,
                rot,
                mapping,
            );
            assert!(m.compensated.is_some(), "{mapping:?}");
            // ∫ pdf dω = 1: the midpoint rule on a grid of the map's own parameterisation, 8
            // cells per texel side, so the densities are constant or ∝ 1/sin θ on each cell
            // (dω = sin θ dθ dφ, or 4π du dv for the equal-area square).
            let (nx, ny) = (8 * w as usize, 8 * h as usize);
            let mut total = [0.0f64; 2];
            for i in 0..ny {
                for j in 0..nx {
                    let uv = Vec2::new((j as f32 + 0.5) / nx as f32, (i as f32 + 0.5) / ny as f32);
                    let (local, dw) = match mapping {
                        EnvMapping::Equirectangular => (
                            EnvMap::uv_to_dir(uv),
                            2.0 * PI * PI * (uv.y * PI).sin() / (nx * ny) as f32,
                        ),
                        EnvMapping::EqualArea => (
                            equal_area::square_to_sphere(uv),
                            4.0 * PI / (nx * ny) as f32,
                        ),
                    };
                    let d = (rot * local).normalize();
                    total[0] += (m.pdf(d, EnvPdf::Full) * dw) as f64;
                    total[1] += (m.pdf(d, EnvPdf::Compensated) * dw) as f64;
                }
            }
            for t in total {
                assert!((t - 1.0).abs() < 1e-3, "{mapping:?}: ∫ pdf dω = {t}");
            }
            let mean = m.mean_luminance;
            let mut ratios = Vec::new();
            for i in 0..64 {
                for j in 0..64 {
                    let u = Vec2::new((i as f32 + 0.37) / 64.0, (j as f32 + 0.61) / 64.0);
                    let (d, _, pdf) = m.sample(u, EnvPdf::Compensated).expect("a sample");
                    assert!((pdf / m.pdf(d, EnvPdf::Compensated) - 1.0).abs() < 1e-3);
                    // Per solid angle the full density is ∝ L and the compensated one
                    // ∝ (L − mean)⁺ of the texel sampled (the texel's own radiance: `eval`
                    // filters, the densities do not).
                    let l = luminance(m.texel_radiance(d));
                    assert!(
                        l > mean,
                        "{mapping:?}: sampled a texel of L = {l} ≤ mean {mean}"
                    );
                    ratios.push(
                        m.pdf(d, EnvPdf::Full) / m.pdf(d, EnvPdf::Compensated) * (l - mean) / l,
                    );
                }
            }
            let (lo, hi) = ratios
                .iter()
                .fold((f32::MAX, 0.0f32), |(a, b), &r| (a.min(r), b.max(r)));
            assert!(
                hi / lo - 1.0 < 1e-3,
                "{mapping:?}: not ∝ (L − mean): {lo}..{hi}"
            );
            // Directions no brighter than the mean are left to BSDF sampling.
            for i in 0..(w * h) as usize {
                let (x, y) = (i % w as usize, i / w as usize);
                let d = m.texel_direction(x, y);
                let l = luminance(m.texel_radiance(d));
                assert_eq!(
                    m.pdf(d, EnvPdf::Compensated) == 0.0,
                    l <= mean,
                    "{mapping:?}: texel ({x}, {y}) L = {l}, mean {mean}"
                );
            }
        }
        let flat = EnvMap::from_texels(8, 4, vec![Vec3::splat(0.7); 32], Vec3::ONE, rot);
        assert!(flat.compensated.is_none());
        let d = Vec3::new(0.2, 0.9, -0.3).normalize();
        assert_eq!(flat.pdf(d, EnvPdf::Compensated), flat.pdf(d, EnvPdf::Full));
    }
}
