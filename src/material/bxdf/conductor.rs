//! pbrt-v4's conductor BSDF (`conductor` material; PBRT-v4 §9.3): a metal with a complex index of
//! refraction η + i k per RGB channel and the exact conductor Fresnel term, either perfectly
//! specular or rough with an anisotropic GGX microfacet distribution (Torrance–Sparrow with the
//! height-correlated Smith G2 and visible-normal sampling, Heitz 2018).
//!
//! Local shading frame: normal +z, x along the surface tangent (∂p/∂u), which orients the
//! anisotropy. The material is opaque and one-sided in the frame (the integrator flips the frame to
//! the side the ray arrives from), so `wo.z > 0` is required.

use super::BsdfSample;
use crate::material::microfacet::{Ggx, fresnel_conductor, reflect};
use crate::math::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// Real part of the relative IOR per channel.
    pub eta: Vec3,
    /// Imaginary part (absorption coefficient) per channel.
    pub k: Vec3,
    /// Microfacet distribution; a Dirac mirror when [`Ggx::effectively_smooth`].
    pub dist: Ggx,
    /// η and k as named spectra, which spectral rendering evaluates per wavelength
    /// ([`crate::material::Bsdf::make_spectral`]); `eta`/`k` are their RGB projections.
    pub spectra: Option<crate::spectrum::ConductorSpectra>,
}

impl Conductor {
    pub fn new(eta: Vec3, k: Vec3, alpha_x: f32, alpha_y: f32) -> Conductor {
        Conductor {
            eta,
            k,
            dist: Ggx::anisotropic(alpha_x, alpha_y),
            spectra: None,
        }
    }

    #[inline]
    pub fn is_specular(&self) -> bool {
        self.dist.effectively_smooth()
    }

    /// f(wo, wi) without the cosine: D(h) G2 F(wo·h) / (4 cos θo cos θi) (Walter et al. 2007 eq. 20).
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if self.is_specular() || wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let h = h.normalize();
        let f = fresnel_conductor(wo.dot(h).abs(), self.eta, self.k);
        f * (self.dist.d(h) * self.dist.g2(wo, wi) / (4.0 * wo.z * wi.z))
    }

    /// Solid-angle pdf of [`Conductor::sample`]: D_wo(h) / (4 wo·h) (Heitz 2018 eq. 17).
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_specular() || wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        self.dist.d_visible(wo, h) / (4.0 * wo.dot(h))
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        if self.is_specular() {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample {
                wi,
                f: fresnel_conductor(wi.z, self.eta, self.k) / wi.z,
                pdf: 1.0,
                specular: true,
                eta: 1.0,
            });
        }
        let m = self.dist.sample_visible(wo, u);
        let wi = reflect(wo, m);
        if wi.z <= 0.0 {
            return None;
        }
        BsdfSample::glossy(wi, self.pdf(wo, wi), 1.0, || self.eval(wo, wi))
    }

    /// Normal-incidence reflectance, the colour the raycast/Whitted modes show.
    pub fn albedo(&self) -> Vec3 {
        fresnel_conductor(1.0, self.eta, self.k)
    }
}
