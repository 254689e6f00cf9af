//! A dielectric interface (glass, water, the thesis's `refractive`): exact Fresnel, Snell's law,
//! total internal reflection; smooth, or rough after Walter et al. 2007.
//!
//! Radiance transport across a refractive interface scales radiance by 1/η² (Veach 1997 §5.2;
//! PBRT-v4 §9.5.2): the transmitted `f` includes that factor and `BsdfSample::eta` reports the
//! relative IOR crossed so the integrator can undo it for Russian roulette.

use super::{fresnel_reflection_sample, same_hemisphere};
use crate::material::bsdf::BsdfSample;
use crate::material::microfacet::{Ggx, MIN_ALPHA, fresnel_dielectric, reflect, refract};
use crate::math::{Vec2, Vec3};

/// `eta` = IOR inside / outside; `tint` multiplies transmitted light. Smooth if `ggx` is `None`.
#[derive(Clone, Copy, Debug)]
pub struct Dielectric {
    pub eta: f32,
    pub ggx: Option<Ggx>,
    pub tint: Vec3,
}

impl Dielectric {
    /// A dielectric with glTF roughness `roughness` (α = roughness²); smooth below the GGX floor.
    pub fn new(eta: f32, roughness: f32, tint: Vec3) -> Dielectric {
        let alpha = roughness * roughness;
        Dielectric {
            eta,
            ggx: if alpha < MIN_ALPHA {
                None
            } else {
                Some(Ggx::new(alpha))
            },
            tint,
        }
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self.ggx {
            None => Vec3::ZERO,
            Some(g) => rough_eval(g, self.eta, self.tint, wo, wi),
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self.ggx {
            None => 0.0,
            Some(g) => rough_pdf(g, self.eta, wo, wi),
        }
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match self.ggx {
            None => smooth_sample(self.eta, self.tint, wo, u_lobe),
            Some(g) => rough_sample(g, self.eta, self.tint, wo, u_lobe, u),
        }
    }
}

fn smooth_sample(eta: f32, tint: Vec3, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let r = fresnel_dielectric(wo.z, eta);
    let t = 1.0 - r;
    if u_lobe < r / (r + t) {
        Some(fresnel_reflection_sample(wo, r, r / (r + t)))
    } else {
        let (wi, etap) = refract(wo, Vec3::Z, eta)?;
        if wi.z == 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: tint * (t / (wi.z.abs() * etap * etap)),
            pdf: t / (r + t),
            specular: true,
            eta: etap,
        })
    }
}

/// The generalised half vector of Walter et al. 2007 (eq. 16), oriented up; `None` for
/// configurations no microfacet can produce.
#[inline]
pub(super) fn half_vector(eta: f32, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
    if wo.z == 0.0 || wi.z == 0.0 {
        return None;
    }
    let reflect = wo.z * wi.z > 0.0;
    let etap = if reflect {
        1.0
    } else if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = wi * etap + wo;
    if wm.length_squared() == 0.0 {
        return None;
    }
    let mut wm = wm.normalize();
    if wm.z < 0.0 {
        wm = -wm;
    }
    // Discard back-facing microfacets.
    if wm.dot(wi) * wi.z < 0.0 || wm.dot(wo) * wo.z < 0.0 {
        return None;
    }
    Some((wm, etap, reflect))
}

fn rough_eval(g: Ggx, eta: f32, tint: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    let Some((wm, etap, is_reflect)) = half_vector(eta, wo, wi) else {
        return Vec3::ZERO;
    };
    let f = fresnel_dielectric(wo.dot(wm), eta);
    if is_reflect {
        Vec3::splat(g.d(wm) * g.g2(wo, wi) * f / (4.0 * wi.z * wo.z).abs())
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2) * wi.z * wo.z;
        let ft = g.d(wm) * g.g2(wo, wi) * (1.0 - f) * (wi.dot(wm) * wo.dot(wm) / denom).abs();
        tint * (ft / (etap * etap))
    }
}

fn rough_pdf(g: Ggx, eta: f32, wo: Vec3, wi: Vec3) -> f32 {
    let Some((wm, etap, is_reflect)) = half_vector(eta, wo, wi) else {
        return 0.0;
    };
    let r = fresnel_dielectric(wo.dot(wm), eta);
    let t = 1.0 - r;
    if is_reflect {
        g.d_visible(wo, wm) / (4.0 * wo.dot(wm).abs()) * r
    } else {
        let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
        // Jacobian of the refraction half-vector map, Walter et al. 2007 eq. 17.
        let dwm_dwi = wi.dot(wm).abs() / denom;
        g.d_visible(wo, wm) * dwm_dwi * t
    }
}

fn rough_sample(
    g: Ggx,
    eta: f32,
    tint: Vec3,
    wo: Vec3,
    u_lobe: f32,
    u: Vec2,
) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let wm = g.sample_visible(wo, u);
    let r = fresnel_dielectric(wo.dot(wm), eta);
    let wi = if u_lobe < r {
        let wi = reflect(wo, wm);
        if !same_hemisphere(wo, wi) {
            return None;
        }
        wi
    } else {
        let (wi, _) = refract(wo, wm, eta)?;
        if same_hemisphere(wo, wi) || wi.z == 0.0 {
            return None;
        }
        wi
    };
    let pdf = rough_pdf(g, eta, wo, wi);
    if !(pdf > 0.0) {
        return None;
    }
    let f = rough_eval(g, eta, tint, wo, wi);
    let etap = if same_hemisphere(wo, wi) {
        1.0
    } else if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    Some(BsdfSample {
        wi,
        f,
        pdf,
        specular: false,
        eta: etap,
    })
}
