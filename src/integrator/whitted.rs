//! The thesis's second stage: a Whitted ray tracer (§5.3.4) on top of the ray caster's local
//! shading (§5.1.10–5.1.12, §5.3.5).
//!
//! Local shading at a hit is `emission + ambient + Σ_lights f(wo, wi) · E_i`
//! ([`super::direct::shade_local`]), where `f` is one of the BRDFs of
//! [`crate::material::local_shading`] chosen by `--shading`.
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
use crate::material::local_shading::LocalSurface;
pub use crate::material::local_shading::ShadingModel;
use crate::material::microfacet::{fresnel_dielectric, reflect, refract};
use crate::material::{Material, MaterialModel};
use crate::math::Vec3;
use crate::sampling::SampleStream;
use crate::world::World;

pub use super::direct::AREA_SAMPLES;
/// Deepest recursion, whatever `--max-depth` says (keeps the stack bounded).
pub const MAX_WHITTED_DEPTH: u32 = 128;
/// Branches whose accumulated weight is below this are not traced.
pub const MIN_BRANCH_WEIGHT: f32 = 1e-3;

/// What the Whitted tracer does at a surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurfaceKind {
    Opaque,
    Mirror,
    Dielectric,
}

/// Classifies a material for the Whitted recursion.
pub fn surface_kind(m: &Material, s: &LocalSurface) -> SurfaceKind {
    match m.model {
        MaterialModel::Mirror => SurfaceKind::Mirror,
        // An interface (ior 1) refracts straight through: the medium boundary is invisible.
        MaterialModel::Dielectric(_) | MaterialModel::Interface => SurfaceKind::Dielectric,
        _ if m.transmission > 0.5 => SurfaceKind::Dielectric,
        MaterialModel::MetallicRoughness(_) | MaterialModel::Conductor(_)
            if s.metallic > 0.9 && s.roughness < 0.05 =>
        {
            SurfaceKind::Mirror
        }
        _ => SurfaceKind::Opaque,
    }
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
        return world.escaped(d);
    };
    let wo = -d;
    // The shading normal of every lobe below (local shading, mirror and refraction directions)
    // is the normal-mapped one, as in the path tracer.
    world.apply_normal_map(&mut hit);
    let m = world.surface_material(&hit);
    let mut l = world.emitted(&hit, wo);
    let surf = world.local_surface(&hit);
    match surface_kind(m, &surf) {
        SurfaceKind::Opaque => l += super::direct::shade_local(world, &hit, wo, model, s, stats),
        SurfaceKind::Mirror => {
            if depth_left > 0 {
                let (ng, ns) = if hit.ng.dot(wo) < 0.0 {
                    (-hit.ng, -hit.ns)
                } else {
                    (hit.ng, hit.ns)
                };
                let wr = reflect(wo, ns);
                if wr.dot(ng) > 0.0 {
                    let r = Ray::spawn(hit.p, hit.p_error, ng, wr).with_time(hit.time);
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
                // Exact Fresnel (thesis eq. 5.79) at the shading normal turned to the viewer; a
                // shading normal facing away counts as grazing incidence.
                let fr = fresnel_dielectric(ns.dot(wo).clamp(0.0, 1.0), eta);
                if fr * weight >= MIN_BRANCH_WEIGHT {
                    let wr = reflect(wo, ns);
                    if wr.dot(ng) > 0.0 {
                        let r = Ray::spawn(hit.p, hit.p_error, ng, wr).with_time(hit.time);
                        l += fr * trace(world, &r, s, depth_left - 1, weight * fr, model, stats);
                    }
                }
                let ft = 1.0 - fr;
                if ft * weight >= MIN_BRANCH_WEIGHT
                    && let Some(wt) = refract(wo, ns, eta).map(|(wt, _)| wt.normalize())
                    && wt.dot(ng) < 0.0
                {
                    let r = Ray::spawn(hit.p, hit.p_error, ng, wt).with_time(hit.time);
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

    /// The Fresnel term and refraction of `microfacet` as the Whitted tracer uses them (cosine
    /// on the incident side, `eta = η_t / η_i`).
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
        let (wt, _) = refract(wo, Vec3::Z, 1.33).unwrap();
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
