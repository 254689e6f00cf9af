//! Smooth or rough dielectric (glass): the thesis's `refractive` material and pbrt-v4's
//! `dielectric`. Its IOR and glTF roughness are the material's `ior` and `roughness` (read by the
//! raycast/Whitted modes too); pbrt's roughness textures replace the roughness per hit.

use super::RoughnessTextures;
use crate::material::Bsdf;
use crate::material::eval::HitTextures;
use crate::math::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Dielectric {
    /// pbrt-v4 `roughness`/`uroughness`/`vroughness` given as float textures, evaluated per hit;
    /// `alpha` holds the GGX α of an axis without a texture (and the texture's mean, which only
    /// the raycast/Whitted local shading uses).
    pub alpha: Vec2,
    pub roughness: RoughnessTextures,
    /// The η spectrum varying with λ (a named glass `glass-BK7`, …, or a sampled η; an id of
    /// [`crate::spectrum::BsdfSpectra`]) the material's IOR was taken from: spectral rendering
    /// follows its η(λ) (dispersion); RGB uses the IOR.
    pub eta_spectrum: Option<u16>,
}

impl Dielectric {
    /// `eta` is the material's IOR; `roughness` gives its glTF roughness (factor × texture) when
    /// it has no roughness textures.
    #[inline]
    pub fn bsdf(&self, tx: &HitTextures, eta: f32, roughness: impl FnOnce() -> f32) -> Bsdf {
        if self.roughness.is_textured() {
            // pbrt-v4 `dielectric` with roughness textures: α per hit; Trayecto's rough
            // dielectric is isotropic (glTF roughness √α of α = √(αu·αv)).
            let alpha = self.roughness.alpha(self.alpha, tx);
            let a = (alpha.x * alpha.y).sqrt();
            return self.with_glass(Bsdf::dielectric(eta, a.sqrt().clamp(0.0, 1.0), Vec3::ONE));
        }
        self.with_glass(Bsdf::dielectric(eta, roughness(), Vec3::ONE))
    }

    #[inline]
    fn with_glass(&self, mut b: Bsdf) -> Bsdf {
        if let Bsdf::Dielectric(d) = &mut b {
            d.eta_spectrum = self.eta_spectrum;
        }
        b
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        if !(self.alpha.is_finite() && self.roughness.factor.is_finite()) {
            return Err("has a non-finite pbrt parameter".into());
        }
        if self.alpha.min_element() < 0.0 || self.roughness.factor.min_element() < 0.0 {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        Ok(())
    }
}
