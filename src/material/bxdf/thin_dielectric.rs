//! An infinitely thin dielectric sheet (glTF transmission without a volume).

use super::BsdfSample;
use super::fresnel_reflection_sample;
use crate::material::microfacet::{Ggx, MIN_ALPHA, fresnel_dielectric, reflect};
use crate::math::{Vec2, Vec3};

/// Smooth (`ggx` `None`): light passes straight through, with the inter-reflections inside the
/// sheet summed in closed form. Rough: the KHR_materials_transmission BTDF, the GGX reflection
/// lobe mirrored through the sheet (transmission half vector H_T = normalize(V + L − 2(N·L)N)),
/// so the transmitted image is blurred by the roughness but not displaced.
#[derive(Clone, Copy, Debug)]
pub struct ThinDielectric {
    pub eta: f32,
    pub tint: Vec3,
    pub ggx: Option<Ggx>,
    /// The id of an η spectrum varying with λ ([`crate::spectrum::BsdfSpectra`]; pbrt's
    /// `thindielectric` with a named glass or a sampled η) that spectral rendering follows at
    /// the hero wavelength ([`crate::material::Bsdf::make_spectral`], as pbrt-v4's
    /// `ThinDielectricMaterial`); RGB rendering ignores it (`eta` is its index at 587.56 nm).
    pub eta_spectrum: Option<u16>,
}

impl ThinDielectric {
    /// A thin-walled sheet with glTF roughness `roughness`; smooth below the GGX floor.
    pub fn new(eta: f32, roughness: f32, tint: Vec3) -> ThinDielectric {
        let alpha = roughness * roughness;
        ThinDielectric {
            eta,
            tint,
            ggx: (alpha >= MIN_ALPHA).then(|| Ggx::new(alpha)),
            eta_spectrum: None,
        }
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self.ggx {
            None => Vec3::ZERO,
            Some(g) => rough_eval(g, self.eta, self.tint, wo, wi).0,
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self.ggx {
            None => 0.0,
            Some(g) => rough_eval(g, self.eta, self.tint, wo, wi).1,
        }
    }

    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let (eta, tint) = (self.eta, self.tint);
        if let Some(g) = self.ggx {
            return rough_sample(g, eta, tint, wo, u_lobe, u);
        }
        if wo.z == 0.0 {
            return None;
        }
        let (r, t) = thin_rt(eta, wo.z.abs());
        if u_lobe < r / (r + t) {
            Some(fresnel_reflection_sample(wo, r, r / (r + t)))
        } else {
            let wi = -wo;
            Some(BsdfSample {
                wi,
                f: tint * (t / wi.z.abs()),
                pdf: t / (r + t),
                specular: true,
                eta: 1.0,
            })
        }
    }
}

/// Reflectance and transmittance of a thin slab, summing the internal bounces:
/// R' = R + T²R / (1 − R²) (PBRT-v4 §9.5.3).
#[inline]
fn thin_rt(eta: f32, cos: f32) -> (f32, f32) {
    let mut r = fresnel_dielectric(cos, eta);
    let mut t = 1.0 - r;
    if r < 1.0 {
        r += t * t * r / (1.0 - r * r);
        t = 1.0 - r;
    }
    (r, t)
}

/// The rough thin sheet's f and pdf. The sheet is symmetric, so both directions are first moved
/// to the side `wo` is on; a transmitted `wi` is then mirrored back through the sheet, where the
/// GGX reflection lobe gives its value (KHR_materials_transmission, "Transmission BTDF"). The
/// lobe's energy is split by the thin-slab reflectance at the microfacet, R'(wo·h), as the smooth
/// sheet splits it at the normal, so roughness → 0 gives the smooth sheet.
#[inline]
fn rough_eval(g: Ggx, eta: f32, tint: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
    if wo.z == 0.0 || wi.z == 0.0 {
        return (Vec3::ZERO, 0.0);
    }
    let flip = if wo.z < 0.0 { -1.0 } else { 1.0 };
    let (wo, wi) = (wo * flip, wi * flip);
    let transmit = wi.z < 0.0;
    let wr = Vec3::new(wi.x, wi.y, wi.z.abs());
    let h = (wo + wr).normalize();
    let (woh, wrh) = (wo.dot(h), wr.dot(h));
    if !(woh > 0.0 && wrh > 0.0) {
        return (Vec3::ZERO, 0.0);
    }
    let (r, t) = thin_rt(eta, woh);
    let spec = g.d(h) * g.g2(wo, wr) / (4.0 * wo.z * wr.z);
    let lobe_pdf = g.d_visible(wo, h) / (4.0 * woh);
    if transmit {
        (tint * (t * spec), t * lobe_pdf)
    } else {
        (Vec3::splat(r * spec), r * lobe_pdf)
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
    let flip = if wo.z < 0.0 { -1.0 } else { 1.0 };
    let m = g.sample_visible(wo * flip, u);
    let mut wr = reflect(wo * flip, m);
    if wr.z <= 0.0 {
        return None;
    }
    let (r, _) = thin_rt(eta, (wo * flip).dot(m));
    if u_lobe >= r {
        wr.z = -wr.z;
    }
    let wi = wr * flip;
    let (f, pdf) = rough_eval(g, eta, tint, wo, wi);
    BsdfSample::glossy(wi, pdf, 1.0, || f)
}
