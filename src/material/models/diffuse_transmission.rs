//! pbrt-v4 `diffusetransmission` (`DiffuseTransmissionMaterial`): Lambertian reflection of the
//! material's base colour and Lambertian transmission.

use crate::material::Bsdf;
use crate::material::bxdf;
use crate::math::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseTransmission {
    /// Lambertian transmittance (pbrt's `transmittance` × `scale`).
    pub transmittance: Vec3,
}

impl Default for DiffuseTransmission {
    fn default() -> Self {
        DiffuseTransmission {
            transmittance: Vec3::splat(0.25),
        }
    }
}

impl DiffuseTransmission {
    #[inline]
    pub fn bsdf(&self, reflectance: Vec3) -> Bsdf {
        Bsdf::DiffuseTransmission(bxdf::DiffuseTransmission {
            reflectance,
            transmittance: self.transmittance,
        })
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        if !self.transmittance.is_finite() {
            return Err("has a non-finite pbrt parameter".into());
        }
        if self.transmittance.min_element() < 0.0 {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        Ok(())
    }
}
