//! Equirectangular environment maps (`.hdr`, `.exr`), importance sampled with a 2D
//! piecewise-constant distribution: a marginal over rows and a conditional over each row's pixels,
//! weighted by luminance × sin θ so that the density is proportional to radiance per solid angle
//! (PBRT-v3 §14.2.4). A direction's solid-angle pdf is p(u, v) / (2π² sin θ).
//!
//! Direction convention (Mitsuba 3's `envmap`, so references agree): in the map's own frame +y is
//! up, u = atan2(x, −z) / 2π (wrapped to [0, 1)), v = acos(y) / π with v = 0 the top row.

use crate::math::{Mat3, PI, Vec2, Vec3, luminance};
use crate::sampling::Distribution1D;
use std::path::Path;

#[derive(Clone, Debug)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    /// Linear RGB radiance, row-major from the top row.
    pub texels: Vec<Vec3>,
    pub scale: Vec3,
    /// World-from-map rotation and its inverse.
    pub to_world: Mat3,
    pub to_local: Mat3,
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
    /// Mean luminance over the sphere (per steradian), for light selection by power.
    pub mean_luminance: f32,
}

impl EnvMap {
    /// Reads an equirectangular map. Errors are one-line messages (the caller names the file).
    pub fn load(path: &Path, scale: Vec3, to_world: Mat3) -> Result<EnvMap, String> {
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

    /// Builds the map and its sampling distributions. Non-finite or negative texels become 0.
    pub fn from_texels(w: u32, h: u32, texels: Vec<Vec3>, scale: Vec3, to_world: Mat3) -> EnvMap {
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
        let mut rows = Vec::with_capacity(h as usize);
        let mut row_weights = Vec::with_capacity(h as usize);
        // ∫ L dω with each row's exact solid angle Δφ·(cos θ0 − cos θ1) (the sampling weights
        // below use sin θ at the row centre, which only needs to be proportional).
        let mut integral = 0.0f64;
        for y in 0..h as usize {
            let (t0, t1) = (PI * y as f32 / h as f32, PI * (y + 1) as f32 / h as f32);
            let row_omega = (2.0 * PI / w as f32) as f64 * (t0.cos() - t1.cos()) as f64;
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            let weights: Vec<f32> = (0..w as usize)
                .map(|x| luminance(texels[y * w as usize + x] * scale).max(0.0) * sin_theta)
                .collect();
            let sum: f64 = weights.iter().map(|&v| v as f64).sum();
            let lum_sum: f64 = (0..w as usize)
                .map(|x| luminance(texels[y * w as usize + x] * scale).max(0.0) as f64)
                .sum();
            integral += lum_sum * row_omega;
            // The marginal needs each row's true mean, which Distribution1D replaces by 1 for an
            // all-zero row; compute it here.
            row_weights.push((sum / w as f64) as f32);
            rows.push(Distribution1D::new(&weights));
        }
        let marginal = Distribution1D::new(&row_weights);
        let mean_luminance = (integral / (4.0 * PI as f64)) as f32;
        let to_local = to_world.inverse();
        EnvMap {
            width: w,
            height: h,
            texels,
            scale,
            to_world,
            to_local,
            rows,
            marginal,
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
        let (theta, phi) = (uv.y * PI, uv.x * 2.0 * PI);
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        Vec3::new(st * sp, ct, -st * cp)
    }

    /// Radiance arriving from world direction `d` (unit), bilinearly filtered.
    #[inline]
    pub fn eval(&self, d: Vec3) -> Vec3 {
        let uv = Self::dir_to_uv(self.to_local * d);
        let (w, h) = (self.width as i64, self.height as i64);
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let texel = |xi: i64, yi: i64| {
            let xi = xi.rem_euclid(w) as usize;
            let yi = yi.clamp(0, h - 1) as usize;
            self.texels[yi * w as usize + xi]
        };
        let a = texel(x0, y0) * (1.0 - tx) + texel(x0 + 1, y0) * tx;
        let b = texel(x0, y0 + 1) * (1.0 - tx) + texel(x0 + 1, y0 + 1) * tx;
        (a * (1.0 - ty) + b * ty) * self.scale
    }

    /// Samples a world direction toward the map; returns (direction, radiance, solid-angle pdf).
    #[inline]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (uu, pdf_u, _) = self.rows[row].sample_continuous(u.x);
        let uv = Vec2::new(uu, v);
        let sin_theta = (uv.y * PI).sin();
        if !(sin_theta > 0.0) || !(pdf_u * pdf_v > 0.0) {
            return None;
        }
        let pdf = pdf_u * pdf_v / (2.0 * PI * PI * sin_theta);
        let d = (self.to_world * Self::uv_to_dir(uv)).normalize();
        Some((d, self.eval(d), pdf))
    }

    /// Solid-angle pdf with which [`EnvMap::sample`] produces world direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        let uv = Self::dir_to_uv(self.to_local * d);
        let sin_theta = (uv.y * PI).sin();
        if !(sin_theta > 0.0) {
            return 0.0;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        let pm = self.marginal.func[y] / self.marginal.func_int;
        let row = &self.rows[y];
        let pc = row.func[x] / row.func_int;
        pm * pc / (2.0 * PI * PI * sin_theta)
    }
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
                let pdf = m.pdf(d);
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
                total += (m.pdf(d) * st) as f64;
            }
        }
        total *= (PI as f64 / n as f64).powi(2);
        assert!((total - 1.0).abs() < 1e-4, "∫ pdf dω = {total}");
        for i in 0..16 {
            for j in 0..16 {
                let u = Vec2::new((i as f32 + 0.37) / 16.0, (j as f32 + 0.61) / 16.0);
                let (d, l, pdf) = m.sample(u).expect("a sample");
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert!((l - Vec3::splat(2.0)).abs().max_element() < 1e-5, "{l}");
                assert!(
                    (pdf / m.pdf(d) - 1.0).abs() < 1e-3,
                    "sample pdf {pdf} vs pdf(d) {}",
                    m.pdf(d)
                );
            }
        }
    }
}
