//! A dielectric interface (glass, water, the thesis's `refractive`): exact Fresnel, Snell's law,
//! total internal reflection; smooth, or rough after Walter et al. 2007.
//!
//! Radiance transport across a refractive interface scales radiance by 1/η² (Veach 1997 §5.2;
//! PBRT-v4 §9.5.2): the transmitted `f` includes that factor and `BsdfSample::eta` reports the
//! relative IOR crossed so the integrator can undo it for Russian roulette.
//!
//! **Dispersion** (KHR_materials_dispersion): with [`Dielectric::dispersion`] set, each RGB
//! channel has its own IOR (the extension's Abbe-number law at one representative wavelength
//! per channel, [`dispersive_iors`]). The BSDF is then a different function per channel,
//! f_c = f(η_c), and is sampled as a one-sample mixture over channels: a channel c is picked
//! uniformly by `u_lobe`, the direction is sampled as for η_c, and the sample reports the
//! mixture pdf (1/3)·Σ_c pdf(η_c) with the full RGB value — an unbiased estimator of every
//! channel that MIS can weigh like any other BSDF. For the smooth interface the refracted
//! directions are distinct Dirac lobes: the chosen one carries only its own channel, weighted by
//! 3 (its discrete probability is a third of the transmission's); the shared reflection carries
//! all three with their own Fresnel terms.

use super::BsdfSample;
use super::{fresnel_reflection_sample, same_hemisphere};
use crate::material::microfacet::{Ggx, MIN_ALPHA, fresnel_dielectric, reflect, refract};
use crate::math::{Vec2, Vec3};

/// `eta` = IOR inside / outside; `tint` multiplies transmitted light. Smooth if `ggx` is `None`.
#[derive(Clone, Copy, Debug)]
pub struct Dielectric {
    pub eta: f32,
    pub ggx: Option<Ggx>,
    pub tint: Vec3,
    /// Per-channel IORs (KHR_materials_dispersion); `None` = `eta` for all channels.
    pub dispersion: Option<Vec3>,
    /// The id of an η spectrum varying with λ ([`crate::spectrum::BsdfSpectra`]: a named
    /// glass or a sampled η) that spectral rendering follows
    /// ([`crate::material::Bsdf::make_spectral`]); RGB rendering ignores it (`eta` is its index).
    pub eta_spectrum: Option<u16>,
}

/// Representative wavelengths (nm) of the linear-sRGB channels: the dominant wavelengths of the
/// sRGB red, green and blue primaries (against D65).
pub const CHANNEL_WAVELENGTHS: [f32; 3] = [611.3, 549.1, 464.3];

/// KHR_materials_dispersion: IOR at wavelength λ (nm) for base IOR `ior` (at the Fraunhofer d
/// line, 587.56 nm) and `dispersion` = 20 / Abbe number V_d. The extension's law (a Cauchy fit
/// through n_d with n_F − n_C = (n_d − 1)/V_d):
/// n(λ) = max(n_d + (n_d − 1)/V_d · (523655/λ² − 1.5168), 1).
#[inline]
pub fn dispersive_ior(ior: f32, dispersion: f32, lambda: f32) -> f32 {
    let inv_v = dispersion / 20.0;
    (ior + (ior - 1.0) * inv_v * (523_655.0 / (lambda * lambda) - 1.5168)).max(1.0)
}

/// The IOR of each RGB channel at [`CHANNEL_WAVELENGTHS`].
pub fn dispersive_iors(ior: f32, dispersion: f32) -> Vec3 {
    let [r, g, b] = CHANNEL_WAVELENGTHS;
    Vec3::new(
        dispersive_ior(ior, dispersion, r),
        dispersive_ior(ior, dispersion, g),
        dispersive_ior(ior, dispersion, b),
    )
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
            dispersion: None,
            eta_spectrum: None,
        }
    }

    /// The same interface with per-channel IORs `iors` (see the module notes).
    pub fn with_dispersion(mut self, iors: Vec3) -> Dielectric {
        self.dispersion = Some(iors);
        self
    }

    /// Per channel, the relative IOR crossed from `wo` to `wi` ([`super::eta_crossed`]).
    #[inline]
    pub fn eta_crossed(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        super::eta_crossed(self.dispersion.unwrap_or(Vec3::splat(self.eta)), wo, wi)
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match (self.ggx, self.dispersion) {
            (None, _) => Vec3::ZERO,
            (Some(g), None) => rough_eval(g, self.eta, self.tint, wo, wi),
            (Some(g), Some(e)) => Vec3::new(
                rough_eval(g, e.x, self.tint, wo, wi).x,
                rough_eval(g, e.y, self.tint, wo, wi).y,
                rough_eval(g, e.z, self.tint, wo, wi).z,
            ),
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match (self.ggx, self.dispersion) {
            (None, _) => 0.0,
            (Some(g), None) => rough_pdf(g, self.eta, wo, wi),
            (Some(g), Some(e)) => {
                (rough_pdf(g, e.x, wo, wi) + rough_pdf(g, e.y, wo, wi) + rough_pdf(g, e.z, wo, wi))
                    / 3.0
            }
        }
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match (self.ggx, self.dispersion) {
            (None, None) => smooth_sample(self.eta, self.tint, wo, u_lobe),
            (Some(g), None) => rough_sample(g, self.eta, self.tint, wo, u_lobe, u),
            (None, Some(e)) => smooth_sample_dispersive(e, self.tint, wo, u_lobe),
            (Some(g), Some(e)) => {
                // Channel c with probability 1/3; the rest of `u_lobe` picks the lobe.
                let x = u_lobe * 3.0;
                let c = (x as usize).min(2);
                let u_lobe = (x - c as f32).clamp(0.0, 1.0 - f32::EPSILON);
                let eta_c = [e.x, e.y, e.z][c];
                let wi = rough_sample_dir(g, eta_c, wo, u_lobe, u)?;
                BsdfSample::glossy(wi, self.pdf(wo, wi), relative_eta(eta_c, wo, wi), || {
                    self.eval(wo, wi)
                })
            }
        }
    }
}

/// The relative IOR crossed from `wo` to `wi` (1 for reflection).
#[inline]
fn relative_eta(eta: f32, wo: Vec3, wi: Vec3) -> f32 {
    if same_hemisphere(wo, wi) {
        1.0
    } else if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    }
}

/// The smooth interface with per-channel IORs `etas`: reflection with probability mean_c R_c
/// (value R_c per channel), else channel c's refraction with probability (1 − mean R)/3 (value
/// T_c/η_c² in channel c only).
fn smooth_sample_dispersive(etas: Vec3, tint: Vec3, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let r = Vec3::new(
        fresnel_dielectric(wo.z, etas.x),
        fresnel_dielectric(wo.z, etas.y),
        fresnel_dielectric(wo.z, etas.z),
    );
    let p_r = (r.x + r.y + r.z) / 3.0;
    if u_lobe < p_r {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        return Some(BsdfSample {
            wi,
            f: r / wi.z.abs(),
            pdf: p_r,
            specular: true,
            eta: 1.0,
        });
    }
    let x = ((u_lobe - p_r) / (1.0 - p_r)).clamp(0.0, 1.0) * 3.0;
    let c = (x as usize).min(2);
    let eta_c = [etas.x, etas.y, etas.z][c];
    let t_c = 1.0 - [r.x, r.y, r.z][c];
    let (wi, etap) = refract(wo, Vec3::Z, eta_c)?;
    if wi.z == 0.0 || !(t_c > 0.0) {
        return None;
    }
    let mut f = Vec3::ZERO;
    f[c] = tint[c] * t_c / (wi.z.abs() * etap * etap);
    Some(BsdfSample {
        wi,
        f,
        pdf: (1.0 - p_r) / 3.0,
        specular: true,
        eta: etap,
    })
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

/// A direction sampled as [`rough_sample`] does: a visible normal, then reflection with
/// probability F or refraction.
#[inline]
fn rough_sample_dir(g: Ggx, eta: f32, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<Vec3> {
    if wo.z == 0.0 {
        return None;
    }
    let wm = g.sample_visible(wo, u);
    let r = fresnel_dielectric(wo.dot(wm), eta);
    if u_lobe < r {
        let wi = reflect(wo, wm);
        if !same_hemisphere(wo, wi) {
            return None;
        }
        Some(wi)
    } else {
        let (wi, _) = refract(wo, wm, eta)?;
        if same_hemisphere(wo, wi) || wi.z == 0.0 {
            return None;
        }
        Some(wi)
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
    let wi = rough_sample_dir(g, eta, wo, u_lobe, u)?;
    let pdf = rough_pdf(g, eta, wo, wi);
    BsdfSample::glossy(wi, pdf, relative_eta(eta, wo, wi), || {
        rough_eval(g, eta, tint, wo, wi)
    })
}
