//! Uniform environment lights (pbrt-v4 `UniformInfiniteLight`; the thesis's ambient light and
//! the default white environment): radiance `L` from every direction.

use super::{LeSample, LightSample, LightScene, disk_origin};
use crate::geometry::Ray;
use crate::geometry::primitive::SurfaceHit;
use crate::math::{Frame, PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug)]
pub struct UniformLight {
    pub radiance: Vec3,
}

impl UniformLight {
    /// A direction toward the environment from `hit` ([`sample_uniform_env`] about
    /// `uniform_n`) and the shadow ray along it, offset along `n_offset`.
    #[inline]
    pub fn sample_li(
        &self,
        hit: &SurfaceHit,
        n_offset: Vec3,
        u: Vec2,
        uniform_n: Vec3,
    ) -> Option<LightSample> {
        let (wi, pdf) = sample_uniform_env(uniform_n, u)?;
        let shadow = Ray::spawn(hit.p, hit.p_error, n_offset, wi);
        Some(LightSample {
            wi,
            li: self.radiance,
            pdf,
            pmf: 1.0,
            delta: false,
            shadow,
            light: u32::MAX,
        })
    }

    /// Radiance along an escaping direction and the solid-angle pdf with which
    /// [`UniformLight::sample_li`] about `uniform_n` gives it.
    #[inline]
    pub fn le_pdf(&self, d: Vec3, uniform_n: Vec3) -> (Vec3, f32) {
        (self.radiance, uniform_env_pdf(uniform_n, d))
    }

    /// Emission sampling (pbrt-v4 `UniformInfiniteLight::SampleLe`): a direction uniform over
    /// the sphere (pdf 1/4π) and an origin on the scene's bounding disk facing it (pdf 1/πr²).
    pub fn sample_le(&self, scene: &LightScene, u1: Vec2, u2: Vec2) -> Option<LeSample> {
        let w = warp::uniform_sphere(u1);
        let (o, pdf_pos) = disk_origin(scene.center, scene.radius, w, u2);
        Some(LeSample {
            ray: Ray::new(o, w),
            le: self.radiance,
            n: w,
            pdf_pos,
            pdf_dir: warp::UNIFORM_SPHERE_PDF,
        })
    }

    /// Position and direction pdfs of [`UniformLight::sample_le`].
    pub fn pdf_le(&self, scene: &LightScene) -> (f32, f32) {
        (
            1.0 / (PI * scene.radius * scene.radius),
            warp::UNIFORM_SPHERE_PDF,
        )
    }

    /// Power through the scene's bounding disk from every direction: 4π · π r² · L (pbrt-v4
    /// `UniformInfiniteLight::Phi`).
    pub fn phi(&self, scene: &LightScene) -> Vec3 {
        self.radiance * (4.0 * PI * PI * scene.radius * scene.radius)
    }

    /// Power for light selection (luminance of [`UniformLight::phi`]).
    pub fn selection_power(&self, scene_radius: f32) -> f32 {
        4.0 * PI * PI * scene_radius * scene_radius * luminance(self.radiance)
    }
}

/// NEE's direction toward a uniform environment ([`UniformLight`]) from a receiver whose
/// integrand can only be non-zero in the hemisphere of the unit normal `n`, and its solid-angle
/// pdf: cosine-weighted about `n` (Malley's method, pdf cos θ / π, PBRT §13.6.3), so no sample
/// points below the surface. With `n` zero (a point in a medium, a BSDF that transmits, or NEE
/// not combined with BSDF sampling by MIS) it is uniform over the whole sphere, pdf 1 / 4π.
/// `None` for the rare sample whose direction rounds onto the horizon (pdf 0 there).
/// [`uniform_env_pdf`] is its density, which MIS of escaping BSDF samples must use.
#[inline]
pub fn sample_uniform_env(n: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
    if n == Vec3::ZERO {
        return Some((warp::uniform_sphere(u), warp::UNIFORM_SPHERE_PDF));
    }
    let wi = Frame::from_normal(n).to_world(warp::cosine_hemisphere(u));
    let pdf = uniform_env_pdf(n, wi);
    (pdf > 0.0).then_some((wi, pdf))
}

/// The density of [`sample_uniform_env`] about `n` at the unit direction `wi`: cos θ / π above
/// the plane of `n` and 0 below it (a direction the light sampler never produces, so a BSDF
/// sample there takes the whole MIS weight, Veach 1997 §9.2); 1 / 4π everywhere for `n` zero.
#[inline]
pub fn uniform_env_pdf(n: Vec3, wi: Vec3) -> f32 {
    if n == Vec3::ZERO {
        warp::UNIFORM_SPHERE_PDF
    } else {
        warp::cosine_hemisphere_pdf(n.dot(wi))
    }
}
