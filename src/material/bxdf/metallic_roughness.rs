//! The glTF 2.0 metallic-roughness BRDF (glTF spec, appendix B).

use crate::material::bsdf::BsdfSample;
use crate::material::clearcoat::Clearcoat;
use crate::material::microfacet::{Ggx, reflect, schlick};
use crate::math::{INV_PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

/// `mix(fresnel_mix(diffuse, specular), conductor(specular, F0 = base), metallic)` with a GGX
/// specular lobe, height-correlated Smith G2 and Schlick Fresnel.
#[derive(Clone, Copy, Debug)]
pub struct MetallicRoughness {
    pub base: Vec3,
    pub metallic: f32,
    pub ggx: Ggx,
    /// F0 of the dielectric layer: ((ior − 1)/(ior + 1))² × KHR specular colour, ≤ 1.
    pub f0_dielectric: Vec3,
    /// KHR_materials_specular strength (1 without the extension; 0 is pure Lambertian).
    pub specular: f32,
    /// KHR_materials_clearcoat layered on top (see [`Clearcoat`]): f = (1 − c·fr(V))·f_base +
    /// f_coat. Its normal is +z until [`crate::material::Bsdf::set_coat_normal`] places it.
    pub coat: Option<Clearcoat>,
}

impl MetallicRoughness {
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        self.eval_coated(wo, wi)
    }

    /// The base, scaled by what the coat leaves of it, plus the coat (both directions above).
    #[inline]
    fn eval_coated(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match &self.coat {
            None => self.eval_above(wo, wi),
            Some(c) => {
                self.eval_above(wo, wi) * (1.0 - c.layer_weight(wo)) + Vec3::splat(c.eval(wo, wi))
            }
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let p_spec = self.spec_probability(wo);
        let h = (wo + wi).normalize();
        let spec = self.ggx.d_visible(wo, h) / (4.0 * wo.dot(h));
        let base = p_spec * spec + (1.0 - p_spec) * warp::cosine_hemisphere_pdf(wi.z);
        match &self.coat {
            None => base,
            Some(c) => {
                let p_coat = coat_probability(c, wo);
                p_coat * c.pdf(wo, wi) + (1.0 - p_coat) * base
            }
        }
    }

    /// Picks the specular lobe (visible normals, Heitz 2018) or the diffuse one with `u_lobe`.
    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        // The coat first, with probability p_coat; the rest of `u_lobe`, rescaled to [0, 1),
        // chooses between the base's lobes.
        let mut u_lobe = u_lobe;
        let mut coat_wi = None;
        if let Some(c) = &self.coat {
            let p_coat = coat_probability(c, wo);
            if u_lobe < p_coat {
                coat_wi = Some(c.sample(wo, u)?);
            } else {
                u_lobe = ((u_lobe - p_coat) / (1.0 - p_coat)).min(1.0 - f32::EPSILON);
            }
        }
        let p_spec = self.spec_probability(wo);
        let wi = if let Some(wi) = coat_wi {
            wi
        } else if u_lobe < p_spec {
            let m = self.ggx.sample_visible(wo, u);
            reflect(wo, m)
        } else {
            warp::cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        // The sample's pdf and value are those of the whole mixture (one-sample MIS over
        // lobes), so either lobe can produce any direction consistently.
        let pdf = self.pdf(wo, wi);
        if !(pdf > 0.0) {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.eval_coated(wo, wi),
            pdf,
            specular: false,
            eta: 1.0,
        })
    }

    /// The BRDF for wo, wi both above the surface.
    #[inline]
    fn eval_above(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let h = h.normalize();
        let voh = wo.dot(h);
        let spec = self.ggx.d(h) * self.ggx.g2(wo, wi) / (4.0 * wo.z * wi.z);
        // glTF appendix B: fresnel_mix for the dielectric layer (with KHR_materials_specular's
        // weight), conductor Fresnel with F0 = base colour for the metal.
        let f_d = schlick(self.f0_dielectric, voh) * self.specular;
        let dielectric = self.base * (INV_PI * (1.0 - f_d.max_element())) + f_d * spec;
        let metal = schlick(self.base, voh) * spec;
        dielectric * (1.0 - self.metallic) + metal * self.metallic
    }

    /// Probability of sampling the specular lobe: its estimated share of the reflected energy,
    /// with Fresnel evaluated at the viewing angle.
    #[inline]
    fn spec_probability(&self, wo: Vec3) -> f32 {
        let (base, metallic) = (self.base, self.metallic);
        let f_d = schlick(self.f0_dielectric, wo.z) * self.specular;
        let w_spec = luminance(f_d * (1.0 - metallic) + schlick(base, wo.z) * metallic);
        let w_diff = (1.0 - metallic) * (1.0 - f_d.max_element()) * luminance(base);
        if !(w_diff > 0.0) {
            1.0
        } else if !(w_spec > 0.0) {
            0.0
        } else {
            // Keep both lobes reachable so the mixture pdf never under-covers f.
            (w_spec / (w_spec + w_diff)).clamp(0.05, 0.95)
        }
    }
}

/// Probability of sampling the clearcoat lobe: its Fresnel share c·fr(V) against what the base
/// keeps, (1 − c·fr)·½, clamped so both stay reachable (the mixture pdf must cover f).
#[inline]
fn coat_probability(c: &Clearcoat, wo: Vec3) -> f32 {
    let w = c.layer_weight(wo);
    (w / (w + 0.5 * (1.0 - w))).clamp(0.05, 0.95)
}
