//! Lambertian reflection plus Lambertian transmission: pbrt-v4's `diffusetransmission` material
//! (PBRT-v4 §9.2 exercise / `DiffuseTransmissionBxDF`), reused by glTF's
//! `KHR_materials_diffuse_transmission`. f = R/π for `wi` on the side of `wo`, T/π on the other.
//!
//! The BSDF transmits, so the frame keeps the geometric orientation and `wo.z` may be negative.
//! Sampling picks reflection with probability max(R)/(max(R) + max(T)) (as pbrt-v4 does) and
//! draws a cosine-weighted direction on the chosen side.

use super::BsdfSample;
use crate::math::{INV_PI, Vec2, Vec3};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseTransmission {
    pub reflectance: Vec3,
    pub transmittance: Vec3,
}

impl DiffuseTransmission {
    #[inline]
    fn reflect_probability(&self) -> f32 {
        let pr = self.reflectance.max_element().max(0.0);
        let pt = self.transmittance.max_element().max(0.0);
        if pr + pt <= 0.0 { 0.0 } else { pr / (pr + pt) }
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z == 0.0 || wi.z == 0.0 {
            Vec3::ZERO
        } else if wo.z * wi.z > 0.0 {
            self.reflectance * INV_PI
        } else {
            self.transmittance * INV_PI
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let pr = self.reflect_probability();
        let p_side = if wo.z * wi.z > 0.0 { pr } else { 1.0 - pr };
        p_side * warp::cosine_hemisphere_pdf(wi.z.abs())
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let pr = self.reflect_probability();
        if pr == 0.0 && self.transmittance.max_element() <= 0.0 {
            return None;
        }
        let mut wi = warp::cosine_hemisphere(u);
        // Reflection stays on wo's side; transmission goes to the other one.
        let reflect = u_lobe < pr;
        let side = if reflect {
            wo.z.signum()
        } else {
            -wo.z.signum()
        };
        wi.z *= side;
        BsdfSample::glossy(wi, self.pdf(wo, wi), 1.0, || self.eval(wo, wi))
    }
}
