//! pbrt-v4 `conductor` (pbrt-v4 `ConductorMaterial`): exact Fresnel of η + i k per channel, or
//! of the base colour as pbrt's `reflectance`, over a smooth or anisotropic GGX surface.

use super::RoughnessTextures;
use crate::material::TextureRef;
use crate::material::bxdf;
use crate::material::eval::HitTextures;
use crate::material::microfacet::conductor_from_reflectance;
use crate::math::{Vec2, Vec3};

/// A conductor's parameters. Roughness is GGX α already (x along the tangent, pbrt's
/// `uroughness`; y along the bitangent, `vroughness`); `roughness` textures, when set, replace
/// the constant α per hit ([`RoughnessTextures::alpha`]), and `eta_texture`/`k_texture`, when
/// set, scale η and k per hit by their RGB (pbrt-v4 evaluates a conductor's `eta` and `k` spectrum
/// textures at the hit, `ConductorMaterial::GetBxDF`). Defaults are pbrt-v4's (copper).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// η and k per linear-sRGB channel (default: pbrt's `metal-Cu-eta`/`metal-Cu-k` converted by
    /// [`crate::spectrum`]).
    pub eta: Vec3,
    pub k: Vec3,
    /// Textures of η and k (linear RGB), multiplying `eta` and `k` per hit.
    pub eta_texture: Option<TextureRef>,
    pub k_texture: Option<TextureRef>,
    /// Use the material's base colour (× texture) as pbrt's `reflectance` instead of η/k.
    pub reflectance: bool,
    pub alpha: Vec2,
    pub roughness: RoughnessTextures,
    /// `eta` and `k` as the named spectra they were projected from, for spectral rendering
    /// (`None`: upsampled from the RGB values, as pbrt-v4 does for an RGB η/k).
    pub spectra: Option<crate::spectrum::ConductorSpectra>,
}

impl Default for Conductor {
    fn default() -> Self {
        let (eta, k) =
            crate::spectrum::named_conductor_rgb("metal-Cu").unwrap_or((Vec3::ONE, Vec3::ZERO));
        Conductor {
            eta,
            k,
            eta_texture: None,
            k_texture: None,
            reflectance: false,
            alpha: Vec2::ZERO,
            roughness: RoughnessTextures::default(),
            spectra: None,
        }
    }
}

impl Conductor {
    /// η and k at the hit of `tx`, from the base colour `base` when the conductor is given by
    /// its reflectance.
    #[inline]
    pub fn eta_k(&self, tx: &HitTextures, base: impl FnOnce() -> Vec3) -> (Vec3, Vec3) {
        if self.reflectance {
            return conductor_from_reflectance(base());
        }
        let textured = |c: Vec3, t: &Option<TextureRef>| match t {
            // A texture's negative or non-finite texels would make the Fresnel term NaN.
            Some(t) => (c * tx.sample(t).truncate()).max(Vec3::ZERO),
            None => c,
        };
        (
            textured(self.eta, &self.eta_texture),
            textured(self.k, &self.k_texture),
        )
    }

    /// The conductor lobe at a hit. `outside_ior` is the IOR of the medium its surface faces:
    /// under a coat it is the coat's, and the Fresnel equations take η and k relative to it
    /// (pbrt-v4's `CoatedConductorMaterial` divides both by the interface IOR, also for the
    /// `reflectance` form).
    #[inline]
    pub fn lobe(
        &self,
        tx: &HitTextures,
        outside_ior: f32,
        base: impl FnOnce() -> Vec3,
    ) -> bxdf::Conductor {
        let alpha = self.roughness.alpha(self.alpha, tx);
        let (eta, k) = self.eta_k(tx, base);
        let mut c = bxdf::Conductor::new(eta / outside_ior, k / outside_ior, alpha.x, alpha.y);
        // Named spectra stand for constant η and k: a texture on either wins.
        if !self.reflectance && self.eta_texture.is_none() && self.k_texture.is_none() {
            c.spectra = self.spectra.map(|s| crate::spectrum::ConductorSpectra {
                outside_ior: s.outside_ior * outside_ior,
                ..s
            });
        }
        c
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        let finite = self.eta.is_finite()
            && self.k.is_finite()
            && self.alpha.is_finite()
            && self.roughness.factor.is_finite();
        if !finite {
            return Err("has a non-finite pbrt parameter".into());
        }
        if self.eta.min_element() < 0.0
            || self.k.min_element() < 0.0
            || self.alpha.min_element() < 0.0
            || self.roughness.factor.min_element() < 0.0
        {
            return Err("has a negative eta, k, albedo, transmittance or roughness".into());
        }
        Ok(())
    }
}
