//! Point lights (pbrt-v4 `PointLight`): intensity `I` (W/sr) from one position, the same in every
//! direction.

use super::bvh::LightBounds;
use super::{LeSample, LightSample, toward};
use crate::geometry::{Bounds3, Ray};
use crate::math::{PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug)]
pub struct PointLight {
    pub position: Vec3,
    /// W/sr, RGB.
    pub intensity: Vec3,
}

impl PointLight {
    /// The light seen from `p` (error bound `p_error`, shadow ray offset along `n_offset`): the
    /// direction to it, I / d², pdf 1 (a delta light); `None` if `p` is the light's position.
    #[inline]
    pub fn sample_li(&self, p: Vec3, p_error: Vec3, n_offset: Vec3) -> Option<LightSample> {
        let (wi, d2) = toward(self.position, p)?;
        Some(LightSample {
            wi,
            li: self.intensity / d2,
            pdf: 1.0,
            pmf: 1.0,
            delta: true,
            shadow: Ray::spawn_to(p, p_error, n_offset, self.position, Vec3::ZERO, wi),
            light: u32::MAX,
        })
    }

    /// Emission sampling (pbrt-v4 `PointLight::SampleLe`): the position itself (pdf 1, a delta
    /// in position) and a direction uniform over the sphere (pdf 1/4π) carrying I.
    pub fn sample_le(&self, u: Vec2) -> Option<LeSample> {
        let w = warp::uniform_sphere(u);
        Some(LeSample {
            ray: Ray::new(self.position, w),
            le: self.intensity,
            n: Vec3::ZERO,
            pdf_pos: 1.0,
            pdf_dir: warp::UNIFORM_SPHERE_PDF,
        })
    }

    /// Position and direction pdfs of [`PointLight::sample_le`] (pbrt-v4 `PDF_Le`): position
    /// is a delta (0 as a density), direction 1/4π.
    pub fn pdf_le(&self) -> (f32, f32) {
        (0.0, warp::UNIFORM_SPHERE_PDF)
    }

    /// Emitted power 4π I.
    pub fn phi(&self) -> Vec3 {
        self.intensity * (4.0 * PI)
    }

    /// Power for light selection (luminance of [`PointLight::phi`]).
    pub fn selection_power(&self) -> f32 {
        4.0 * PI * luminance(self.intensity)
    }

    pub fn bounds(&self, phi: f32) -> LightBounds {
        LightBounds::all_around(Bounds3::from_point(self.position), phi)
    }
}
