//! Lambertian reflection.

use super::BsdfSample;
use super::same_hemisphere;
use crate::math::{INV_PI, Vec2, Vec3};
use crate::sampling::warp;

/// Lambertian reflection with the given albedo.
#[derive(Clone, Copy, Debug)]
pub struct Diffuse {
    pub albedo: Vec3,
}

impl Diffuse {
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if same_hemisphere(wo, wi) && wo.z > 0.0 {
            self.albedo * INV_PI
        } else {
            Vec3::ZERO
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if same_hemisphere(wo, wi) && wo.z > 0.0 {
            warp::cosine_hemisphere_pdf(wi.z)
        } else {
            0.0
        }
    }

    /// Cosine-weighted hemisphere sampling (Malley's method).
    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = warp::cosine_hemisphere(u);
        let pdf = warp::cosine_hemisphere_pdf(wi.z);
        if pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.albedo * INV_PI,
            pdf,
            specular: false,
            eta: 1.0,
        })
    }
}
