//! Image environment lights (pbrt-v4 `ImageInfiniteLight`), equirectangular or equal-area
//! ([`EnvMap`] holds the image and its sampling densities).

use super::envmap::{EnvMap, EnvMapping, EnvPdf};
use super::{LeSample, LightSample, LightScene, disk_origin};
use crate::geometry::Ray;
use crate::geometry::primitive::SurfaceHit;
use crate::math::{PI, Vec2, Vec3};
use std::sync::Arc;

#[derive(Clone, Debug)]
pub struct EnvironmentLight {
    pub map: Arc<EnvMap>,
}

impl EnvironmentLight {
    /// A direction toward the map from the density `env` and the shadow ray along it from
    /// `hit`, offset along `n_offset`; `None` where the map is black.
    #[inline]
    pub fn sample_li(
        &self,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
        env: EnvPdf,
    ) -> Option<LightSample> {
        let (wi, li, pdf) = self.map.sample(u, env)?;
        if li == Vec3::ZERO {
            return None;
        }
        let shadow = Ray::spawn(hit.p, hit.p_error, n_offset, wi);
        Some(LightSample {
            wi,
            li,
            pdf,
            pmf: 1.0,
            delta: false,
            shadow,
            light: u32::MAX,
        })
    }

    /// Radiance arriving from the escaping direction `d` (pbrt-v4 `Le`).
    #[inline]
    pub fn le(&self, d: Vec3) -> Vec3 {
        self.map.eval(d)
    }

    /// [`EnvironmentLight::le`] and the solid-angle pdf of `d` under the density `env`.
    #[inline]
    pub fn le_pdf(&self, d: Vec3, env: EnvPdf) -> (Vec3, f32) {
        self.map.eval_pdf(d, env)
    }

    /// Emission sampling (pbrt-v4 `ImageInfiniteLight::SampleLe`): a direction toward the map
    /// from its full density with `u1`, the ray travelling the other way, from an origin on the
    /// scene's bounding disk facing it with `u2` (pdf 1/πr²).
    pub fn sample_le(&self, scene: &LightScene, u1: Vec2, u2: Vec2) -> Option<LeSample> {
        let (wi, le, pdf_dir) = self.map.sample(u1, EnvPdf::Full)?;
        let w = -wi;
        let (o, pdf_pos) = disk_origin(scene.center, scene.radius, w, u2);
        Some(LeSample {
            ray: Ray::new(o, w),
            le,
            n: w,
            pdf_pos,
            pdf_dir,
        })
    }

    /// Position and direction pdfs of [`EnvironmentLight::sample_le`] for a ray travelling in
    /// direction `w`.
    pub fn pdf_le(&self, scene: &LightScene, w: Vec3) -> (f32, f32) {
        (
            1.0 / (PI * scene.radius * scene.radius),
            self.map.pdf(-w, EnvPdf::Full),
        )
    }

    /// Power through the scene's bounding disk: π r² ∫ L dω, the integral tabulated over the
    /// texels (each texel's radiance times its solid angle: 4π / (w·h) on the equal-area
    /// square, 2π/w · (cos θ₀ − cos θ₁) on a latitude–longitude row). For a rigid light
    /// transform; the equirectangular map's bilinear filter moves it by a rounding-size amount.
    pub fn phi(&self, scene: &LightScene) -> Vec3 {
        let m = &*self.map;
        let (w, h) = (m.width as usize, m.height as usize);
        let mut sum = [0.0f64; 3];
        for y in 0..h {
            let omega = match m.mapping {
                EnvMapping::EqualArea => 4.0 * std::f64::consts::PI / (w * h) as f64,
                EnvMapping::Equirectangular => {
                    let t0 = std::f64::consts::PI * y as f64 / h as f64;
                    let t1 = std::f64::consts::PI * (y + 1) as f64 / h as f64;
                    2.0 * std::f64::consts::PI / w as f64 * (t0.cos() - t1.cos())
                }
            };
            for t in &m.texels[y * w..(y + 1) * w] {
                sum[0] += t.x as f64 * omega;
                sum[1] += t.y as f64 * omega;
                sum[2] += t.z as f64 * omega;
            }
        }
        let integral = Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32) * m.scale;
        integral * (PI * scene.radius * scene.radius)
    }

    /// Power for light selection: like a uniform environment of the map's mean radiance.
    pub fn selection_power(&self, scene_radius: f32) -> f32 {
        4.0 * PI * PI * scene_radius * scene_radius * self.map.mean_luminance
    }
}
