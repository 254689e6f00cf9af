//! The thesis's second stage: a Whitted ray tracer (§5.3.4) on top of the ray caster's local
//! shading (§5.1.10–5.1.12, §5.3.5).
//!
//! Local shading at a hit is `emission + ambient + Σ_lights f(wo, wi) · E_i`, where `E_i` is the
//! irradiance a light delivers (shadow-tested) and `f` is one of three BRDFs chosen by `--shading`:
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
//! tracer included. Two-sided shading flips the normal to the viewer's side instead of taking
//! `abs()` of cosines (SPEC §4).
//!
//! Lights: point, spot (with the glTF cone falloff) and directional lights give hard shadows with
//! one shadow ray each. Ambient lights (uniform radiance, incl. the default white environment) add
//! `k_d · L_ambient · occlusion` (eq. 5.95, occlusion from the material's occlusion texture, which only
//! these modes use). Area lights (emissive surfaces) are estimated with [`AREA_SAMPLES`] light
//! samples per shading point drawn by the path tracer's power-proportional light sampler, each
//! shadow-tested: shadows are soft and converge as `--spp` grows.
//!
//! Recursion (§5.3.4): perfect mirrors (`MaterialModel::Mirror`, and metals with metallic > 0.9 and
//! roughness < 0.05) reflect; dielectrics (`MaterialModel::Dielectric` or transmissive glTF
//! materials) split into a reflected and a refracted ray weighted by the exact unpolarised Fresnel
//! reflectance (eq. 5.79, not Schlick's approximation), with total internal reflection when
//! `sin θ_t > 1` (eq. 5.82). Refracted radiance is scaled by `(η_i/η_t)²` (radiance is not
//! invariant across an interface). Recursion stops at `--max-depth` (capped at
//! [`MAX_WHITTED_DEPTH`]) or when a branch's weight falls below [`MIN_BRANCH_WEIGHT`].

use super::RayStats;
use crate::geometry::Ray;
use crate::geometry::primitive::SurfaceHit;
use crate::light::{Light, spot_falloff};
use crate::material::bsdf::{base_color, emitted, sample_texture};
use crate::material::{Material, MaterialModel, Texture};
use crate::math::{INV_PI, Vec3};
use crate::sampling::SampleStream;
use crate::world::World;

/// Light samples per shading point for area lights.
pub const AREA_SAMPLES: u32 = 4;
/// Deepest recursion, whatever `--max-depth` says (keeps the stack bounded).
pub const MAX_WHITTED_DEPTH: u32 = 128;
/// Branches whose accumulated weight is below this are not traced.
pub const MIN_BRANCH_WEIGHT: f32 = 1e-3;

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
}

/// What the Whitted tracer does at a surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurfaceKind {
    Opaque,
    Mirror,
    Dielectric,
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
        let (mut metallic, mut roughness) = (m.metallic, m.roughness);
        if let Some(t) = &m.metallic_roughness_texture {
            let v = sample_texture(textures, t, hit);
            roughness *= v.y;
            metallic *= v.z;
        }
        let (metallic, roughness) = (metallic.clamp(0.0, 1.0), roughness.clamp(0.0, 1.0));
        let occlusion = match &m.occlusion_texture {
            Some(t) => {
                let ao = sample_texture(textures, t, hit).x;
                (1.0 + m.occlusion_strength * (ao - 1.0)).clamp(0.0, 1.0)
            }
            None => 1.0,
        };
        let glossy = m.model != MaterialModel::Diffuse || m.phong.is_some();
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

/// Classifies a material for the Whitted recursion.
pub fn surface_kind(m: &Material, s: &LocalSurface) -> SurfaceKind {
    match m.model {
        MaterialModel::Mirror => SurfaceKind::Mirror,
        // An interface (ior 1) refracts straight through: the medium boundary is invisible.
        MaterialModel::Dielectric | MaterialModel::Interface => SurfaceKind::Dielectric,
        _ if m.transmission > 0.5 => SurfaceKind::Dielectric,
        MaterialModel::MetallicRoughness if s.metallic > 0.9 && s.roughness < 0.05 => {
            SurfaceKind::Mirror
        }
        _ => SurfaceKind::Opaque,
    }
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
            let f0 = f0(s.base, s.metallic, m);
            let f = f0 + (Vec3::ONE - f0) * (1.0 - h.dot(wo).clamp(0.0, 1.0)).powi(5);
            let spec = f * (d * g / (4.0 * cos_i * cos_o));
            let kd = (Vec3::ONE - f) * (1.0 - s.metallic);
            kd * s.base * INV_PI + spec
        }
    }
}

/// Local shading at `hit` seen from `wo` (unit, away from the surface): ambient plus direct light
/// from every light, shadow-tested. Emission is not included.
pub fn shade_local(
    world: &World,
    hit: &SurfaceHit,
    wo: Vec3,
    model: ShadingModel,
    s: &mut SampleStream,
    stats: &mut RayStats,
) -> Vec3 {
    let m = &world.materials[hit.material as usize];
    let surf = LocalSurface::new(m, &world.textures, hit);
    // Two-sided shading: face the normals toward the viewer.
    let (ng, ns) = if hit.ng.dot(wo) < 0.0 {
        (-hit.ng, -hit.ns)
    } else {
        (hit.ng, hit.ns)
    };
    let mut l = Vec3::ZERO;
    let lights = &world.lights.lights;
    // World::build puts area lights first, so the analytic lights are the tail of the list.
    for light in lights.iter().rev() {
        let (wi, e_perp, shadow) = match light {
            Light::Area { .. } => break,
            Light::Uniform { radiance } => {
                l += surf.diffuse() * *radiance * surf.occlusion;
                continue;
            }
            // An environment map acts as an ambient term here, with the radiance the map has
            // along the shading normal (a cheap stand-in for its irradiance: Whitted mode has no
            // hemisphere integration).
            Light::Environment { map } => {
                l += surf.diffuse() * map.eval(ns) * surf.occlusion;
                continue;
            }
            Light::Point {
                position,
                intensity,
            } => {
                let to = *position - hit.p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    continue;
                }
                let wi = to / d2.sqrt();
                let shadow = Ray::spawn_to(hit.p, hit.p_error, ng, *position, Vec3::ZERO, wi);
                (wi, *intensity / d2, shadow)
            }
            Light::Spot {
                position,
                direction,
                intensity,
                cos_inner,
                cos_outer,
            } => {
                let to = *position - hit.p;
                let d2 = to.length_squared();
                if !(d2 > 0.0) {
                    continue;
                }
                let wi = to / d2.sqrt();
                let fall = spot_falloff(direction.dot(-wi), *cos_inner, *cos_outer);
                if fall <= 0.0 {
                    continue;
                }
                let shadow = Ray::spawn_to(hit.p, hit.p_error, ng, *position, Vec3::ZERO, wi);
                (wi, *intensity * (fall / d2), shadow)
            }
            Light::Directional {
                direction,
                irradiance,
            } => {
                let wi = -*direction;
                let mut shadow = Ray::spawn(hit.p, hit.p_error, ng, wi);
                shadow.t_max = f32::INFINITY;
                (wi, *irradiance, shadow)
            }
        };
        // The geometric normal must agree, or light would leak through the surface.
        if wi.dot(ng) <= 0.0 {
            continue;
        }
        let f = brdf(model, &surf, m, ns, wo, wi);
        if f == Vec3::ZERO {
            continue;
        }
        stats.shadow_rays += 1;
        if !world.occluded(&shadow) {
            l += f * e_perp * ns.dot(wi);
        }
    }
    if matches!(lights.first(), Some(Light::Area { .. })) {
        let mut sum = Vec3::ZERO;
        for _ in 0..AREA_SAMPLES {
            let u_light = s.next_1d();
            let u = s.next_2d();
            let Some(ls) = world.lights.sample(
                &world.geometry,
                &world.materials,
                &world.textures,
                hit,
                ng,
                u_light,
                u,
            ) else {
                continue;
            };
            // Only area-light samples count here (the others are evaluated exactly above): they
            // are the non-delta samples with a finite shadow segment. Dividing by the selection
            // probability keeps the estimate of the area lights' sum unbiased.
            if ls.delta || !ls.shadow.t_max.is_finite() || ls.wi.dot(ng) <= 0.0 {
                continue;
            }
            let f = brdf(model, &surf, m, ns, wo, ls.wi);
            if f == Vec3::ZERO {
                continue;
            }
            stats.shadow_rays += 1;
            if !world.occluded(&ls.shadow) {
                sum += f * ls.li * (ns.dot(ls.wi) / (ls.pmf * ls.pdf));
            }
        }
        l += sum / AREA_SAMPLES as f32;
    }
    l
}

/// Exact Fresnel reflectance of a dielectric interface for unpolarised light (thesis eq. 5.79;
/// PBRT eq. 8.2). `cos_i > 0` on the incident side, `eta = η_t / η_i`. Returns 1 under total
/// internal reflection (eq. 5.82).
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// Refracted direction (Snell, eq. 5.77–5.78) of `wo` (unit, away from the surface, on the side of
/// `n`) through an interface with relative index `eta = η_t / η_i`; `None` under total internal
/// reflection.
#[inline]
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = n.dot(wo);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / eta + (cos_i / eta - cos_t) * n).normalize())
}

#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    2.0 * n.dot(wo) * n - wo
}

/// Radiance arriving along `ray` in Whitted mode.
pub fn radiance(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    max_depth: u32,
    model: ShadingModel,
    stats: &mut RayStats,
) -> Vec3 {
    trace(
        world,
        ray,
        s,
        max_depth.min(MAX_WHITTED_DEPTH),
        1.0,
        model,
        stats,
    )
}

fn trace(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    depth_left: u32,
    weight: f32,
    model: ShadingModel,
    stats: &mut RayStats,
) -> Vec3 {
    stats.rays += 1;
    let d = ray.d.normalize();
    let Some(mut hit) = world.intersect(ray) else {
        return world.lights.escaped(d).0;
    };
    let wo = -d;
    let m = &world.materials[hit.material as usize];
    // The shading normal of every lobe below (local shading, mirror and refraction directions)
    // is the normal-mapped one, as in the path tracer.
    crate::material::normal_map::apply_normal_map(m, &world.textures, &mut hit);
    let mut l = emitted(m, &world.textures, &hit, wo);
    let surf = LocalSurface::new(m, &world.textures, &hit);
    match surface_kind(m, &surf) {
        SurfaceKind::Opaque => l += shade_local(world, &hit, wo, model, s, stats),
        SurfaceKind::Mirror => {
            if depth_left > 0 {
                let (ng, ns) = if hit.ng.dot(wo) < 0.0 {
                    (-hit.ng, -hit.ns)
                } else {
                    (hit.ng, hit.ns)
                };
                let wr = reflect(wo, ns);
                if wr.dot(ng) > 0.0 {
                    let r = Ray::spawn(hit.p, hit.p_error, ng, wr);
                    l += surf.base * trace(world, &r, s, depth_left - 1, weight, model, stats);
                }
            }
        }
        SurfaceKind::Dielectric => {
            if depth_left > 0 {
                // Entering when the ray arrives on the front side of the geometric normal.
                let entering = hit.ng.dot(wo) > 0.0;
                let (ng, ns) = if entering {
                    (hit.ng, hit.ns)
                } else {
                    (-hit.ng, -hit.ns)
                };
                let eta = if entering { m.ior } else { 1.0 / m.ior };
                let fr = fresnel_dielectric(ns.dot(wo), eta);
                if fr * weight >= MIN_BRANCH_WEIGHT {
                    let wr = reflect(wo, ns);
                    if wr.dot(ng) > 0.0 {
                        let r = Ray::spawn(hit.p, hit.p_error, ng, wr);
                        l += fr * trace(world, &r, s, depth_left - 1, weight * fr, model, stats);
                    }
                }
                let ft = 1.0 - fr;
                if ft * weight >= MIN_BRANCH_WEIGHT
                    && let Some(wt) = refract(wo, ns, eta)
                    && wt.dot(ng) < 0.0
                {
                    let r = Ray::spawn(hit.p, hit.p_error, ng, wt);
                    let li = trace(world, &r, s, depth_left - 1, weight * ft, model, stats);
                    l += surf.base * li * (ft / (eta * eta));
                }
            }
        }
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        // Normal incidence: ((η − 1)/(η + 1))².
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing incidence reflects everything.
        assert!(fresnel_dielectric(1e-6, 1.5) > 0.999);
        // Inside glass beyond the critical angle (sin θc = 1/1.5): total internal reflection.
        let cos_beyond = (1.0f32 - 0.7 * 0.7).sqrt();
        assert_eq!(fresnel_dielectric(cos_beyond, 1.0 / 1.5), 1.0);
        assert!(refract(Vec3::new(0.7, 0.0, cos_beyond), Vec3::Z, 1.0 / 1.5).is_none());
        // Brewster's angle: tan θB = η, parallel reflectance vanishes → R = r_perp² / 2.
        let tb = 1.5f32.atan();
        let r = fresnel_dielectric(tb.cos(), 1.5);
        let cos_t = (1.0 - (tb.sin() / 1.5).powi(2)).sqrt();
        let rp = (tb.cos() - 1.5 * cos_t) / (tb.cos() + 1.5 * cos_t);
        assert!((r - 0.5 * rp * rp).abs() < 1e-6);
    }

    #[test]
    fn refraction_obeys_snell() {
        let theta = 0.6f32;
        let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
        let wt = refract(wo, Vec3::Z, 1.33).unwrap();
        assert!(wt.z < 0.0);
        let sin_t = (wt.x * wt.x + wt.y * wt.y).sqrt();
        assert!((theta.sin() - 1.33 * sin_t).abs() < 1e-6);
        assert!(wt.x < 0.0, "the refracted ray continues across the normal");
    }

    #[test]
    fn shading_models_parse() {
        for (s, m) in [
            ("phong", ShadingModel::Phong),
            ("blinn-phong", ShadingModel::BlinnPhong),
            ("pbr", ShadingModel::Pbr),
        ] {
            assert_eq!(s.parse::<ShadingModel>().unwrap(), m);
            assert_eq!(m.name(), s);
        }
        assert!("gouraud".parse::<ShadingModel>().is_err());
    }
}
