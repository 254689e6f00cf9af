//! Scattering functions, evaluated in the local shading frame where the shading normal is +z.
//! Each BSDF provides `eval` (f, without the cosine), `pdf` (solid angle) and `sample`, which must
//! agree: the chi-square tests in `tests/bsdf_chi2.rs` check every sampler against its pdf.
//!
//! Two-sided shading (SPEC §4): for opaque materials the integrator builds the frame around the
//! normal flipped to the side the ray arrived from, so `wo.z > 0` always and no `abs()` is taken.
//! Transmissive BSDFs keep the geometric orientation: `wo.z < 0` means the ray arrives from inside.
//!
//! Radiance transport across a refractive interface scales radiance by 1/η² (Veach 1997 §5.2;
//! PBRT-v4 §9.5.2): the transmitted `f` includes that factor and `BsdfSample::eta` reports the
//! relative IOR crossed so the integrator can undo it for Russian roulette.

use super::microfacet::{Ggx, MIN_ALPHA, fresnel_dielectric, reflect, refract, schlick};
use super::{Material, MaterialModel, Texture};
use crate::geometry::SurfaceHit;
use crate::math::{INV_PI, Vec2, Vec3, luminance};
use crate::sampling::warp;

#[derive(Clone, Copy, Debug)]
pub enum Bsdf {
    /// Lambertian reflection with the given albedo.
    Diffuse { albedo: Vec3 },
    /// The glTF 2.0 metallic-roughness BRDF (glTF spec, appendix B):
    /// `mix(fresnel_mix(diffuse, specular), conductor(specular, F0 = base), metallic)` with a GGX
    /// specular lobe, height-correlated Smith G2 and Schlick Fresnel.
    MetallicRoughness {
        base: Vec3,
        metallic: f32,
        ggx: Ggx,
        /// F0 of the dielectric layer: ((ior − 1)/(ior + 1))² × KHR specular colour, ≤ 1.
        f0_dielectric: Vec3,
        /// KHR_materials_specular strength (1 without the extension; 0 is pure Lambertian).
        specular: f32,
    },
    /// Perfect mirror with a tint.
    Mirror { color: Vec3 },
    /// A dielectric interface (glass, water, the thesis's `refractive`): exact Fresnel, Snell's
    /// law, total internal reflection. Smooth if `ggx` is `None`, else rough after Walter et al.
    /// 2007. `eta` = IOR inside / outside; `tint` multiplies transmitted light.
    Dielectric {
        eta: f32,
        ggx: Option<Ggx>,
        tint: Vec3,
    },
    /// An infinitely thin dielectric sheet (glTF transmission without a volume). Smooth (`ggx`
    /// `None`): light passes straight through, with the inter-reflections inside the sheet summed
    /// in closed form. Rough: the KHR_materials_transmission BTDF, the GGX reflection lobe mirrored
    /// through the sheet (transmission half vector H_T = normalize(V + L − 2(N·L)N)), so the
    /// transmitted image is blurred by the roughness but not displaced.
    ThinDielectric {
        eta: f32,
        tint: Vec3,
        ggx: Option<Ggx>,
    },
}

#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Incident direction in the local frame.
    pub wi: Vec3,
    /// BSDF value f(wo, wi) (no cosine).
    pub f: Vec3,
    /// Solid-angle pdf; for a specular (Dirac) lobe the discrete probability of the lobe.
    pub pdf: f32,
    /// True if `wi` was chosen from a Dirac delta lobe: light sampling cannot produce it.
    pub specular: bool,
    /// Relative IOR crossed (1 for reflection); radiance was scaled by 1/eta².
    pub eta: f32,
}

#[inline]
fn same_hemisphere(a: Vec3, b: Vec3) -> bool {
    a.z * b.z > 0.0
}

impl Bsdf {
    /// Builds the BSDF of `material` at `hit`, reading its textures.
    pub fn from_material(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Bsdf {
        let base = base_color(material, textures, hit);
        let (mut roughness, mut metallic) = (material.roughness, material.metallic);
        if let Some(t) = &material.metallic_roughness_texture {
            // glTF: roughness in G, metalness in B (linear).
            let v = sample_texture(textures, t, hit);
            roughness *= v.y;
            metallic *= v.z;
        }
        let roughness = roughness.clamp(0.0, 1.0);
        let mut metallic = metallic.clamp(0.0, 1.0);
        let eta = if material.ior > 0.0 {
            material.ior
        } else {
            1.5
        };
        match material.model {
            MaterialModel::Diffuse => Bsdf::Diffuse { albedo: base },
            MaterialModel::Mirror => Bsdf::Mirror { color: base },
            MaterialModel::Dielectric => Bsdf::dielectric(eta, roughness, Vec3::ONE),
            MaterialModel::Interface => Bsdf::dielectric(1.0, 0.0, Vec3::ONE),
            MaterialModel::MetallicRoughness => {
                let mut transmission = material.transmission;
                if transmission > 0.0
                    && let Some(t) = &material.transmission_texture
                {
                    // KHR_materials_transmission: the factor is multiplied by the R channel.
                    transmission *= sample_texture(textures, t, hit).x;
                }
                // KHR_materials_transmission replaces the diffuse lobe of the dielectric part:
                //   mix(mix(dielectric(diffuse), transmissive, t), metal, metallic).
                // The transmissive component (a dielectric interface tinted by the base colour,
                // thin-walled without KHR_materials_volume) is chosen stochastically with
                // probability (1 − metallic)·t, an unbiased one-sample estimate of the mixture
                // (the coin is a hash of the hit, so NEE and BSDF sampling at this vertex see the
                // same component). The rest is the metallic-roughness BRDF with the metallic
                // weight renormalised: metallic' = metallic / (1 − (1 − metallic)·t).
                let p_transmit = transmission.clamp(0.0, 1.0) * (1.0 - metallic);
                if p_transmit > 0.0 {
                    if p_transmit >= 1.0 || hit_coin(hit) < p_transmit {
                        if material.thin_walled {
                            return Bsdf::thin_dielectric(eta, roughness, base);
                        }
                        return Bsdf::dielectric(eta, roughness, base);
                    }
                    metallic = (metallic / (1.0 - p_transmit)).min(1.0);
                }
                let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
                let f0_dielectric = (material.specular_color * r0).min(Vec3::ONE);
                let specular = material.specular.clamp(0.0, 1.0);
                if metallic == 0.0 && (specular == 0.0 || f0_dielectric == Vec3::ZERO) {
                    // No specular lobe at all (Blender's "Specular IOR Level" 0, exported as
                    // KHR_materials_specular 0): the mixture is exactly Lambertian, with the same
                    // value, pdf and samples, so skip the GGX terms.
                    return Bsdf::Diffuse { albedo: base };
                }
                Bsdf::MetallicRoughness {
                    base,
                    metallic,
                    ggx: Ggx::new(roughness * roughness),
                    f0_dielectric,
                    specular,
                }
            }
        }
    }

    /// A dielectric with glTF roughness `roughness` (α = roughness²); smooth below the GGX floor.
    pub fn dielectric(eta: f32, roughness: f32, tint: Vec3) -> Bsdf {
        let alpha = roughness * roughness;
        Bsdf::Dielectric {
            eta,
            ggx: if alpha < MIN_ALPHA {
                None
            } else {
                Some(Ggx::new(alpha))
            },
            tint,
        }
    }

    /// A thin-walled sheet with glTF roughness `roughness`; smooth below the GGX floor.
    pub fn thin_dielectric(eta: f32, roughness: f32, tint: Vec3) -> Bsdf {
        let alpha = roughness * roughness;
        Bsdf::ThinDielectric {
            eta,
            tint,
            ggx: (alpha >= MIN_ALPHA).then(|| Ggx::new(alpha)),
        }
    }

    /// True if every lobe is a Dirac delta (light sampling is pointless).
    #[inline]
    pub fn is_specular(&self) -> bool {
        match self {
            Bsdf::Diffuse { .. } | Bsdf::MetallicRoughness { .. } => false,
            Bsdf::Mirror { .. } => true,
            Bsdf::Dielectric { ggx, .. } | Bsdf::ThinDielectric { ggx, .. } => ggx.is_none(),
        }
    }

    /// True if `sample` ignores its lobe-choice number.
    #[inline]
    pub fn has_one_lobe(&self) -> bool {
        matches!(self, Bsdf::Diffuse { .. } | Bsdf::Mirror { .. })
    }

    /// True if the BSDF transmits: its frame must keep the geometric orientation.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        matches!(self, Bsdf::Dielectric { .. } | Bsdf::ThinDielectric { .. })
    }

    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match *self {
            Bsdf::Diffuse { albedo } => {
                if same_hemisphere(wo, wi) && wo.z > 0.0 {
                    albedo * INV_PI
                } else {
                    Vec3::ZERO
                }
            }
            Bsdf::MetallicRoughness { .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return Vec3::ZERO;
                }
                self.metal_rough_eval(wo, wi)
            }
            Bsdf::Mirror { .. } => Vec3::ZERO,
            Bsdf::Dielectric { eta, ggx, tint } => match ggx {
                None => Vec3::ZERO,
                Some(g) => rough_dielectric_eval(g, eta, tint, wo, wi),
            },
            Bsdf::ThinDielectric { eta, tint, ggx } => match ggx {
                None => Vec3::ZERO,
                Some(g) => rough_thin_eval(g, eta, tint, wo, wi).0,
            },
        }
    }

    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            Bsdf::Diffuse { .. } => {
                if same_hemisphere(wo, wi) && wo.z > 0.0 {
                    warp::cosine_hemisphere_pdf(wi.z)
                } else {
                    0.0
                }
            }
            Bsdf::MetallicRoughness { ggx, .. } => {
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    return 0.0;
                }
                let p_spec = self.metal_rough_spec_probability(wo);
                let h = (wo + wi).normalize();
                let spec = ggx.d_visible(wo, h) / (4.0 * wo.dot(h));
                p_spec * spec + (1.0 - p_spec) * warp::cosine_hemisphere_pdf(wi.z)
            }
            Bsdf::Mirror { .. } => 0.0,
            Bsdf::Dielectric { eta, ggx, .. } => match ggx {
                None => 0.0,
                Some(g) => rough_dielectric_pdf(g, eta, wo, wi),
            },
            Bsdf::ThinDielectric { eta, tint, ggx } => match ggx {
                None => 0.0,
                Some(g) => rough_thin_eval(g, eta, tint, wo, wi).1,
            },
        }
    }

    /// Samples an incident direction. `u_lobe` chooses among lobes, `u` the direction.
    #[inline]
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match *self {
            Bsdf::Diffuse { albedo } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = warp::cosine_hemisphere(u);
                let pdf = warp::cosine_hemisphere_pdf(wi.z);
                if pdf <= 0.0 {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    f: albedo * INV_PI,
                    pdf,
                    specular: false,
                    eta: 1.0,
                })
            }
            Bsdf::MetallicRoughness { ggx, .. } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let p_spec = self.metal_rough_spec_probability(wo);
                let wi = if u_lobe < p_spec {
                    let m = ggx.sample_visible(wo, u);
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
                    f: self.metal_rough_eval(wo, wi),
                    pdf,
                    specular: false,
                    eta: 1.0,
                })
            }
            Bsdf::Mirror { color } => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                Some(BsdfSample {
                    wi,
                    f: color / wi.z,
                    pdf: 1.0,
                    specular: true,
                    eta: 1.0,
                })
            }
            Bsdf::Dielectric { eta, ggx, tint } => match ggx {
                None => smooth_dielectric_sample(eta, tint, wo, u_lobe),
                Some(g) => rough_dielectric_sample(g, eta, tint, wo, u_lobe, u),
            },
            Bsdf::ThinDielectric {
                eta,
                tint,
                ggx: Some(g),
            } => rough_thin_sample(g, eta, tint, wo, u_lobe, u),
            Bsdf::ThinDielectric {
                eta,
                tint,
                ggx: None,
            } => {
                if wo.z == 0.0 {
                    return None;
                }
                let (r, t) = thin_dielectric_rt(eta, wo.z.abs());
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
    }

    /// Hemispherical albedo estimate used by the raycast `albedo` view and RR heuristics.
    pub fn albedo(&self) -> Vec3 {
        match *self {
            Bsdf::Diffuse { albedo } => albedo,
            Bsdf::MetallicRoughness { base, .. } => base,
            Bsdf::Mirror { color } => color,
            Bsdf::Dielectric { tint, .. } | Bsdf::ThinDielectric { tint, .. } => tint,
        }
    }

    /// The glTF BRDF for wo, wi both above the surface.
    #[inline]
    fn metal_rough_eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let Bsdf::MetallicRoughness {
            base,
            metallic,
            ggx,
            f0_dielectric,
            specular,
        } = *self
        else {
            return Vec3::ZERO;
        };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let h = h.normalize();
        let voh = wo.dot(h);
        let spec = ggx.d(h) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z);
        // glTF appendix B: fresnel_mix for the dielectric layer (with KHR_materials_specular's
        // weight), conductor Fresnel with F0 = base colour for the metal.
        let f_d = schlick(f0_dielectric, voh) * specular;
        let dielectric = base * (INV_PI * (1.0 - f_d.max_element())) + f_d * spec;
        let metal = schlick(base, voh) * spec;
        dielectric * (1.0 - metallic) + metal * metallic
    }

    /// Probability of sampling the specular lobe: its estimated share of the reflected energy,
    /// with Fresnel evaluated at the viewing angle.
    #[inline]
    fn metal_rough_spec_probability(&self, wo: Vec3) -> f32 {
        let Bsdf::MetallicRoughness {
            base,
            metallic,
            f0_dielectric,
            specular,
            ..
        } = *self
        else {
            return 0.0;
        };
        let f_d = schlick(f0_dielectric, wo.z) * specular;
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

/// Reflectance and transmittance of a thin slab, summing the internal bounces:
/// R' = R + T²R / (1 − R²) (PBRT-v4 §9.5.3).
#[inline]
fn thin_dielectric_rt(eta: f32, cos: f32) -> (f32, f32) {
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
fn rough_thin_eval(g: Ggx, eta: f32, tint: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
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
    let (r, t) = thin_dielectric_rt(eta, woh);
    let spec = g.d(h) * g.g2(wo, wr) / (4.0 * wo.z * wr.z);
    let lobe_pdf = g.d_visible(wo, h) / (4.0 * woh);
    if transmit {
        (tint * (t * spec), t * lobe_pdf)
    } else {
        (Vec3::splat(r * spec), r * lobe_pdf)
    }
}

fn rough_thin_sample(
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
    let (r, _) = thin_dielectric_rt(eta, (wo * flip).dot(m));
    if u_lobe >= r {
        wr.z = -wr.z;
    }
    let wi = wr * flip;
    let (f, pdf) = rough_thin_eval(g, eta, tint, wo, wi);
    if !(pdf > 0.0) {
        return None;
    }
    Some(BsdfSample {
        wi,
        f,
        pdf,
        specular: false,
        eta: 1.0,
    })
}

/// The Dirac reflection lobe of a smooth interface with reflectance `r`, chosen with
/// probability `pdf` (shared by the thick and the thin-walled dielectric).
#[inline]
fn fresnel_reflection_sample(wo: Vec3, r: f32, pdf: f32) -> BsdfSample {
    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
    BsdfSample {
        wi,
        f: Vec3::splat(r / wi.z.abs()),
        pdf,
        specular: true,
        eta: 1.0,
    }
}

fn smooth_dielectric_sample(eta: f32, tint: Vec3, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
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
fn dielectric_half_vector(eta: f32, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
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

fn rough_dielectric_eval(g: Ggx, eta: f32, tint: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    let Some((wm, etap, is_reflect)) = dielectric_half_vector(eta, wo, wi) else {
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

fn rough_dielectric_pdf(g: Ggx, eta: f32, wo: Vec3, wi: Vec3) -> f32 {
    let Some((wm, etap, is_reflect)) = dielectric_half_vector(eta, wo, wi) else {
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

fn rough_dielectric_sample(
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
    let pdf = rough_dielectric_pdf(g, eta, wo, wi);
    if !(pdf > 0.0) {
        return None;
    }
    let f = rough_dielectric_eval(g, eta, tint, wo, wi);
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

/// Base colour at a hit: factor × texture (sRGB-decoded) × vertex colour.
pub fn base_color(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> Vec3 {
    let mut c = material.base_color * hit.color.truncate();
    if let Some(t) = &material.base_color_texture {
        c *= sample_texture(textures, t, hit).truncate();
    }
    c
}

/// A uniform number in [0, 1) that is a pure function of the hit (its position and ray
/// distance): the coin that picks one component of a stochastic material mixture.
#[inline]
fn hit_coin(hit: &SurfaceHit) -> f32 {
    crate::sampling::rng::hash_floats_to_unit(&[hit.p.x, hit.p.y, hit.p.z, hit.t])
}

/// Opacity at a hit (glTF: base colour factor alpha × texture alpha × vertex colour alpha; OBJ
/// `d` × `map_d`), used by the alpha MASK and BLEND modes.
#[inline]
pub fn opacity(material: &Material, textures: &[Texture], hit: &SurfaceHit) -> f32 {
    let mut a = material.alpha * hit.color.w;
    if let Some(t) = &material.base_color_texture {
        a *= sample_texture(textures, t, hit).w;
    }
    if let Some(t) = &material.alpha_texture {
        a *= sample_texture(textures, t, hit).x;
    }
    a
}

/// Reads a texture reference at a hit, applying its UV set and transform.
#[inline]
pub fn sample_texture(
    textures: &[Texture],
    t: &super::TextureRef,
    hit: &SurfaceHit,
) -> crate::math::Vec4 {
    let mut uv = hit.uv[(t.texcoord as usize).min(1)];
    if let Some(tr) = &t.transform {
        uv = tr.apply(uv);
    }
    textures[t.texture].lookup(uv)
}

/// Emitted radiance of `material` at `hit` (front face only unless double-sided), toward `wo`.
#[inline]
pub fn emitted(material: &Material, textures: &[Texture], hit: &SurfaceHit, wo: Vec3) -> Vec3 {
    if !material.is_emissive() {
        return Vec3::ZERO;
    }
    if !material.double_sided && hit.ng.dot(wo) <= 0.0 {
        return Vec3::ZERO;
    }
    let mut e = material.emissive;
    if let Some(t) = &material.emissive_texture {
        e *= sample_texture(textures, t, hit).truncate();
    }
    e
}
