//! The thesis's local shading models of the raycast and Whitted modes (§5.1.10–5.1.12, §5.3.5):
//! the parameters of a material at a hit ([`LocalSurface`]) and the BRDF `f` of the model chosen
//! by `--shading`:
//!
//! * `phong`: Lambert plus Phong's lobe `k_s (R·V)^n` (thesis eq. 5.66–5.68);
//! * `blinn-phong`: Lambert plus `k_s (N·H)^n` (eq. 5.69–5.71);
//! * `pbr`: the thesis's Cook-Torrance (eq. 5.83–5.94): GGX `D`, Smith/Schlick-GGX `G` with
//!   `k = (r + 1)² / 8`, Schlick `F` with `F0 = mix(0.04, base, metallic)`, `k_d = (1 − F)(1 −
//!   metallic)`. The thesis prints 0.4 in eq. 5.88; 0.04 is the usual dielectric reflectance
//!   (IOR 1.5) and what glTF specifies, so it is used here. `α = roughness²` as in glTF.
//!
//! Unlike the thesis, the Phong lobes are normalised (`(n+2)/2π` and `(n+8)/8π`, Lafortune &
//! Willems 1994; Akenine-Möller et al., *Real-Time Rendering* §9.8) and the Lambert term carries its
//! `1/π`, so a diffuse scene lit by a point light shows the same radiance in every mode, path
//! tracer included. The direct-lighting loop that uses them is `integrator::direct::shade_local`.

use super::eval::{base_color, roughness_metallic, sample_texture};
use super::microfacet::schlick;
use super::{Material, MaterialModel, Texture};
use crate::geometry::SurfaceHit;
use crate::math::{INV_PI, Vec3};

/// Direct-lighting model of the raycast and Whitted modes (`--shading`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ShadingModel {
    Phong,
    BlinnPhong,
    /// The thesis's Cook-Torrance (§5.3.5).
    #[default]
    Pbr,
}

impl std::str::FromStr for ShadingModel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "phong" => Ok(ShadingModel::Phong),
            "blinn-phong" | "blinn" => Ok(ShadingModel::BlinnPhong),
            "pbr" | "cook-torrance" => Ok(ShadingModel::Pbr),
            other => Err(format!(
                "unknown shading model '{other}' (expected phong, blinn-phong or pbr)"
            )),
        }
    }
}

impl ShadingModel {
    pub fn name(self) -> &'static str {
        match self {
            ShadingModel::Phong => "phong",
            ShadingModel::BlinnPhong => "blinn-phong",
            ShadingModel::Pbr => "pbr",
        }
    }

    /// Every model, for front ends that list the choices.
    pub const ALL: [ShadingModel; 3] = [
        ShadingModel::Phong,
        ShadingModel::BlinnPhong,
        ShadingModel::Pbr,
    ];
}

/// The local-shading parameters of a hit, with textures applied.
#[derive(Clone, Copy, Debug)]
pub struct LocalSurface {
    /// Base colour (factor × texture × vertex colour).
    pub base: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    /// Phong specular colour `k_s` and exponent `n`.
    pub spec: Vec3,
    pub shininess: f32,
    /// Ambient occlusion in [0, 1] (1 = unoccluded).
    pub occlusion: f32,
    /// False for purely Lambertian materials.
    pub glossy: bool,
}

impl LocalSurface {
    pub fn new(m: &Material, textures: &[Texture], hit: &SurfaceHit) -> LocalSurface {
        let base = base_color(m, textures, hit);
        let (mut roughness, mut metallic) = roughness_metallic(m, textures, hit);
        let mut base = base;
        // The pbrt-v4 models in the local-shading vocabulary: a conductor is a metal of its
        // normal-incidence Fresnel colour, a coat a glossy dielectric over its base, and
        // diffuse transmission its reflection only. GGX α becomes glTF roughness √α.
        let rough_of = |a: crate::math::Vec2| (0.5 * (a.x + a.y)).max(0.0).sqrt().min(1.0);
        let conductor_f0 = |c: &crate::material::models::Conductor, base: Vec3| {
            let tx = crate::material::eval::HitTextures::new(textures, hit, None);
            let (eta, k) = c.eta_k(&tx, || base);
            crate::material::microfacet::fresnel_conductor(1.0, eta, k)
        };
        match &m.model {
            MaterialModel::Conductor(c) => {
                base = conductor_f0(c, base);
                metallic = 1.0;
                roughness = rough_of(c.alpha);
            }
            MaterialModel::CoatedConductor(c) => {
                base = conductor_f0(&c.conductor, base);
                metallic = 1.0;
                roughness = rough_of(c.coat.alpha).max(rough_of(c.conductor.alpha));
            }
            MaterialModel::CoatedDiffuse(c) => {
                metallic = 0.0;
                roughness = rough_of(c.coat.alpha);
            }
            MaterialModel::DiffuseTransmission(_) => {
                metallic = 0.0;
                roughness = 1.0;
            }
            _ => {}
        }
        let occlusion = match &m.occlusion_texture {
            Some(t) => {
                let ao = sample_texture(textures, t, hit).x;
                (1.0 + m.occlusion_strength * (ao - 1.0)).clamp(0.0, 1.0)
            }
            None => 1.0,
        };
        let glossy = !matches!(
            m.model,
            MaterialModel::Diffuse | MaterialModel::DiffuseTransmission(_)
        ) || m.phong.is_some();
        let (spec, shininess) = match (&m.phong, glossy) {
            (Some(p), _) => (p.specular, p.shininess.max(0.0)),
            (None, false) => (Vec3::ZERO, 1.0),
            (None, true) => {
                // Blinn-Phong exponent matching a GGX lobe of the same roughness (Walter et al.
                // 2007, §5.2: n = 2/α² − 2).
                let a = (roughness * roughness).max(1e-3);
                (f0(base, metallic, m), (2.0 / (a * a) - 2.0).clamp(0.0, 1e4))
            }
        };
        LocalSurface {
            base,
            metallic,
            roughness,
            spec,
            shininess,
            occlusion,
            glossy,
        }
    }

    /// The diffuse colour `k_d · c` that also receives the ambient term.
    #[inline]
    pub fn diffuse(&self) -> Vec3 {
        self.base * (1.0 - self.metallic)
    }
}

/// Normal-incidence reflectance: 0.04 (scaled by KHR_materials_specular) for dielectrics, the
/// base colour for metals (eq. 5.88 with the glTF constant).
#[inline]
fn f0(base: Vec3, metallic: f32, m: &Material) -> Vec3 {
    let dielectric = (Vec3::splat(0.04) * m.specular_color * m.specular).min(Vec3::ONE);
    dielectric.lerp(base, metallic)
}

/// BRDF value (no cosine) of the chosen model; `n` is the shading normal turned to the viewer's
/// side, `wo` and `wi` unit vectors away from the surface.
#[inline]
pub fn brdf(
    model: ShadingModel,
    s: &LocalSurface,
    m: &Material,
    n: Vec3,
    wo: Vec3,
    wi: Vec3,
) -> Vec3 {
    let cos_i = n.dot(wi);
    let cos_o = n.dot(wo);
    if !(cos_i > 0.0 && cos_o > 0.0) {
        return Vec3::ZERO;
    }
    if !s.glossy {
        return s.base * INV_PI;
    }
    match model {
        ShadingModel::Phong => {
            let r = 2.0 * cos_i * n - wi;
            let rv = r.dot(wo).max(0.0);
            let norm = (s.shininess + 2.0) * 0.5 * INV_PI;
            s.diffuse() * INV_PI + s.spec * (norm * rv.powf(s.shininess))
        }
        ShadingModel::BlinnPhong => {
            let h = (wo + wi).normalize_or_zero();
            let nh = n.dot(h).max(0.0);
            let norm = (s.shininess + 8.0) * 0.125 * INV_PI;
            s.diffuse() * INV_PI + s.spec * (norm * nh.powf(s.shininess))
        }
        ShadingModel::Pbr => {
            let h = (wo + wi).normalize_or_zero();
            let nh = n.dot(h).max(0.0);
            let a = (s.roughness * s.roughness).max(1e-3);
            let a2 = a * a;
            // Trowbridge-Reitz GGX (eq. 5.90).
            let t = nh * nh * (a2 - 1.0) + 1.0;
            let d = a2 * INV_PI / (t * t);
            // Smith with Schlick-GGX, k = (r + 1)² / 8 for analytic lights (eq. 5.91–5.93).
            let k = (s.roughness + 1.0) * (s.roughness + 1.0) / 8.0;
            let g1 = |c: f32| c / (c * (1.0 - k) + k);
            let g = g1(cos_i) * g1(cos_o);
            // Fresnel-Schlick (eq. 5.94).
            let f = schlick(f0(s.base, s.metallic, m), h.dot(wo).clamp(0.0, 1.0));
            let spec = f * (d * g / (4.0 * cos_i * cos_o));
            let kd = (Vec3::ONE - f) * (1.0 - s.metallic);
            kd * s.base * INV_PI + spec
        }
    }
}
