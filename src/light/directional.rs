//! Directional lights (pbrt-v4 `DistantLight`): irradiance `E` (W/m²) on a plane perpendicular to
//! the direction the light travels, from infinitely far away.

use super::{LeSample, LightSample, LightScene, disk_origin};
use crate::geometry::Ray;
use crate::math::{PI, Vec2, Vec3, luminance};

#[derive(Clone, Copy, Debug)]
pub struct DirectionalLight {
    /// Unit direction the light travels (it arrives from `-direction`).
    pub direction: Vec3,
    pub irradiance: Vec3,
}

impl DirectionalLight {
    /// The light seen from `p`: direction `-direction`, E, pdf 1 (a delta light) and a shadow
    /// ray to infinity.
    #[inline]
    pub fn sample_li(&self, p: Vec3, p_error: Vec3, n_offset: Vec3) -> Option<LightSample> {
        let wi = -self.direction;
        let mut shadow = Ray::spawn(p, p_error, n_offset, wi);
        shadow.t_max = f32::INFINITY;
        Some(LightSample {
            wi,
            li: self.irradiance,
            pdf: 1.0,
            pmf: 1.0,
            delta: true,
            shadow,
            light: u32::MAX,
        })
    }

    /// Emission sampling (pbrt-v4 `DistantLight::SampleLe`): the ray's direction is fixed (pdf
    /// 1, a delta in direction) and its origin uniform on the disk of the scene's bounding
    /// sphere facing it (pdf 1/πr²), carrying E.
    pub fn sample_le(&self, scene: &LightScene, u: Vec2) -> Option<LeSample> {
        let (o, pdf_pos) = disk_origin(scene.center, scene.radius, self.direction, u);
        Some(LeSample {
            ray: Ray::new(o, self.direction),
            le: self.irradiance,
            n: self.direction,
            pdf_pos,
            pdf_dir: 1.0,
        })
    }

    /// Position and direction pdfs of [`DirectionalLight::sample_le`]: 1/πr² and 0 (a delta
    /// in direction).
    pub fn pdf_le(&self, scene: &LightScene) -> (f32, f32) {
        (1.0 / (PI * scene.radius * scene.radius), 0.0)
    }

    /// Emitted power through the scene's bounding disk: π r² E.
    pub fn phi(&self, scene: &LightScene) -> Vec3 {
        self.irradiance * (PI * scene.radius * scene.radius)
    }

    /// Power for light selection (luminance of [`DirectionalLight::phi`]).
    pub fn selection_power(&self, scene_radius: f32) -> f32 {
        PI * scene_radius * scene_radius * luminance(self.irradiance)
    }
}
