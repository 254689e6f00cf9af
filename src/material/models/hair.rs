//! pbrt-v4 `hair` (`HairMaterial`): Chiang et al. 2016's fibre model ([`bxdf::Hair`]) with the
//! absorption given directly, as a colour to invert, or as melanin concentrations. The offset
//! across the fibre comes from the hit's v coordinate (h = 2v − 1, pbrt-v4
//! `HairMaterial::GetBxDF`), which curve hits set across the curve's width.

use crate::material::eval::{HitTextures, base_color_in};
use crate::material::{Bsdf, Material, bxdf};
use crate::math::Vec3;

/// Where the fibre's absorption coefficient comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HairAbsorption {
    /// σ_a as given (pbrt's `sigma_a`).
    SigmaA(Vec3),
    /// The material's base colour (pbrt's `reflectance`, possibly textured), inverted to σ_a
    /// per hit (paper eq. 9).
    Reflectance,
    /// Eumelanin and pheomelanin concentrations (paper §4.2).
    Melanin { eumelanin: f32, pheomelanin: f32 },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hair {
    pub absorption: HairAbsorption,
    /// Longitudinal and azimuthal roughness, in [0.01, 1] (pbrt-v4 clamps them so).
    pub beta_m: f32,
    pub beta_n: f32,
    /// Cuticle scale angle, degrees.
    pub alpha: f32,
    pub eta: f32,
}

impl Default for Hair {
    /// pbrt-v4's defaults: brown hair (eumelanin 1.3), β_m = β_n = 0.3, α = 2°, η = 1.55.
    fn default() -> Self {
        Hair {
            absorption: HairAbsorption::Melanin {
                eumelanin: 1.3,
                pheomelanin: 0.0,
            },
            beta_m: 0.3,
            beta_n: 0.3,
            alpha: 2.0,
            eta: 1.55,
        }
    }
}

impl Hair {
    #[inline]
    pub fn bsdf(&self, material: &Material, tx: &HitTextures) -> Bsdf {
        let beta_m = self.beta_m.clamp(0.01, 1.0);
        let beta_n = self.beta_n.clamp(0.01, 1.0);
        let sigma_a = match self.absorption {
            HairAbsorption::SigmaA(s) => s.max(Vec3::ZERO),
            HairAbsorption::Reflectance => bxdf::Hair::sigma_a_from_reflectance(
                base_color_in(material, tx).clamp(Vec3::ZERO, Vec3::ONE),
                beta_n,
            ),
            HairAbsorption::Melanin {
                eumelanin,
                pheomelanin,
            } => bxdf::Hair::sigma_a_from_concentration(eumelanin.max(0.0), pheomelanin.max(0.0)),
        };
        let h = -1.0 + 2.0 * tx.hit.uv[0].y;
        Bsdf::Hair(bxdf::Hair::new(
            h, self.eta, sigma_a, beta_m, beta_n, self.alpha,
        ))
    }

    pub(super) fn validate(&self) -> Result<(), String> {
        let finite = [self.beta_m, self.beta_n, self.alpha, self.eta]
            .iter()
            .all(|x| x.is_finite());
        let absorption_finite = match self.absorption {
            HairAbsorption::SigmaA(s) => s.is_finite(),
            HairAbsorption::Reflectance => true,
            HairAbsorption::Melanin {
                eumelanin,
                pheomelanin,
            } => eumelanin.is_finite() && pheomelanin.is_finite(),
        };
        if !finite || !absorption_finite {
            return Err("has a non-finite pbrt parameter".into());
        }
        if !(self.eta > 0.0) {
            return Err("has a non-positive eta".into());
        }
        Ok(())
    }
}
