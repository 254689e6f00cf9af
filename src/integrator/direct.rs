//! Direct lighting: next-event estimation at a path vertex ([`sample_ld`], one light sample
//! combined with BSDF sampling by MIS), and the local shading of the raycast and Whitted modes
//! ([`shade_local`], every analytic light plus [`AREA_SAMPLES`] area-light samples).

use super::RayStats;
use super::guiding::{Mix, mixture_pdf};
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::geometry::primitive::SurfaceHit;
use crate::light::{EnvPdf, LightSample, LocalLight};
use crate::material::local_shading::{ShadingModel, brdf};
use crate::math::Vec3;
use crate::sampling::warp::power_heuristic;
use crate::sampling::{Numbers, SampleStream};
use crate::world::World;

/// Light samples per shading point for area lights in [`shade_local`].
pub const AREA_SAMPLES: u32 = 4;

/// Next-event estimation at `v` (pbrt's `SampleLd`): one light sample, shadow-tested, weighted
/// by the power heuristic against BSDF sampling (Veach 1997, ch. 9) unless MIS is off or the
/// light is a delta light. Returns `beta` × the estimate. Always draws three numbers from `s`,
/// so the sample stream does not depend on what the vertex is: one 2D number chooses the light
/// and places the point on it (sample reuse, [`World::sample_light_reuse`]: the 2D point set's
/// stratification carries over to every light's points, which a separate choice number would
/// scatter), and a spare 1D number stands in for lights chosen too rarely to reuse it.
#[inline]
pub fn sample_ld(
    world: &World,
    v: &Vertex,
    beta: Vec3,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
) -> Vec3 {
    sample_ld_mix(world, v, beta, s, set, stats, None, None)
}

/// What a light sample saw, for a guide's training ([`sample_ld_mix`]): the direction, the
/// luminance of the incident radiance times the sample's MIS weight, and its density.
pub type NeeSeen = (Vec3, f32, f32);

/// [`sample_ld`] at a guided vertex: the light sample's MIS weight is against the density of
/// the direction sampling the path uses there, the BSDF–guide mixture
/// ([`super::guiding::mixture_pdf`]), so that the two strategies' weights still sum to one.
/// With `mix` = `None` it is [`sample_ld`]. With `seen`, an unoccluded non-delta light
/// sample is also reported there ([`NeeSeen`]): guide training records it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn sample_ld_mix(
    world: &World,
    v: &Vertex,
    beta: Vec3,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    mix: Option<&Mix>,
    seen: Option<&mut Option<NeeSeen>>,
) -> Vec3 {
    let Some(pending) = sample_ld_begin(world, v, s, set) else {
        return Vec3::ZERO;
    };
    stats.shadow_rays += 1;
    if world.occluded(&pending.ls.shadow) {
        return Vec3::ZERO;
    }
    sample_ld_finish(world, v, beta, set, &pending, mix, seen)
}

/// A light sample of [`sample_ld_begin`] whose contribution is not zero unless its shadow ray
/// (`ls.shadow`) is blocked: what [`sample_ld_finish`] needs once the ray has been traced.
#[derive(Clone, Copy)]
pub struct PendingLd {
    pub ls: LightSample,
    /// `ls.wi` in the vertex's shading frame.
    pub wi_local: Vec3,
    /// The BSDF's value for the sample (not zero).
    pub f: Vec3,
}

/// The first half of [`sample_ld_mix`], before the shadow ray: draws the light sample's three
/// numbers from `s` and evaluates the BSDF. `None` when the estimate is zero whatever the
/// shadow ray would find (no shadow ray is then traced). The wavefront path tracer
/// (`wavefront.rs`) runs it for a batch of vertices, traces their shadow rays together, then
/// finishes them: the same arithmetic as [`sample_ld_mix`], in stages.
#[inline(always)]
pub fn sample_ld_begin<S: Numbers>(
    world: &World,
    v: &Vertex,
    s: &mut S,
    set: &PathSettings,
) -> Option<PendingLd> {
    // A specular vertex takes no light sample, and a black BSDF would make `f` zero below: their
    // three numbers are skipped, not computed, so the later dimensions keep their meaning (the
    // estimate, the rays traced and the image are the same).
    if v.bsdf.is_specular() || v.bsdf.is_black() {
        s.skip(3);
        return None;
    }
    let u_spare = if world.light_count() > 1 {
        s.next_1d()
    } else {
        s.skip(1);
        0.0
    };
    let u_light = s.next_2d();
    let env = set.env_pdf();
    let uniform_n = v.uniform_env_normal(env);
    let ls = world.sample_light_reuse(&v.hit, v.ng, u_light, u_spare, env, uniform_n)?;
    if !(set.nee || ls.delta) {
        return None;
    }
    let wi_local = v.frame.to_local(ls.wi);
    // Shading and geometric normals must agree on the side of `wi`, or light would leak
    // through the surface (the BSDF knows which normal its lobes use).
    let consistent = v.bsdf.side_consistent(wi_local, ls.wi.dot(v.ng));
    let f = v.bsdf.eval(v.wo_local, wi_local);
    if !consistent || f == Vec3::ZERO {
        return None;
    }
    Some(PendingLd { ls, wi_local, f })
}

/// The second half of [`sample_ld_mix`], for a light sample whose shadow ray was not blocked:
/// `beta` × the estimate, MIS-weighted against `mix` (or the BSDF), reporting it to `seen`.
#[inline(always)]
pub fn sample_ld_finish(
    world: &World,
    v: &Vertex,
    beta: Vec3,
    set: &PathSettings,
    p: &PendingLd,
    mix: Option<&Mix>,
    seen: Option<&mut Option<NeeSeen>>,
) -> Vec3 {
    let (ls, wi_local, f) = (&p.ls, p.wi_local, p.f);
    let weight = if ls.delta || !set.mis {
        1.0
    } else {
        let p_dir = match mix {
            Some(m) => mixture_pdf(&v.bsdf, v.wo_local, wi_local, ls.wi, m),
            None => v.bsdf.pdf(v.wo_local, wi_local),
        };
        power_heuristic(ls.pmf * ls.pdf, p_dir)
    };
    if let Some(out) = seen
        && !ls.delta
    {
        *out = Some((
            ls.wi,
            crate::math::luminance(set.light_emission(&world.lights, ls.light, ls.li)) * weight,
            ls.pmf * ls.pdf,
        ));
    }
    beta * f
        * wi_local.z.abs()
        * set.light_emission(&world.lights, ls.light, ls.li)
        * (weight / (ls.pmf * ls.pdf))
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
    let m = world.surface_material(hit);
    let surf = world.local_surface(hit);
    // Two-sided shading: face the normals toward the viewer.
    let (ng, ns) = if hit.ng.dot(wo) < 0.0 {
        (-hit.ng, -hit.ns)
    } else {
        (hit.ng, hit.ns)
    };
    let mut l = Vec3::ZERO;
    // World::build puts area lights first, so the analytic lights are the tail of the list.
    for i in (0..world.light_count()).rev() {
        // A moving light where it is at the hit's moment.
        let light = world.lights.posed(i, hit.time);
        let (wi, e_perp, shadow) = match light.local_shading(hit, ng, ns) {
            LocalLight::Sampled => break,
            LocalLight::Ambient(radiance) => {
                l += surf.diffuse() * radiance * surf.occlusion;
                continue;
            }
            LocalLight::Direct(ls) => (ls.wi, ls.li, ls.shadow),
            LocalLight::None => continue,
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
        if !world.occluded(&shadow.with_time(hit.time)) {
            l += f * e_perp * ns.dot(wi);
        }
    }
    if world
        .lights()
        .first()
        .is_some_and(|l| l.as_area().is_some())
    {
        let mut sum = Vec3::ZERO;
        for _ in 0..AREA_SAMPLES {
            let u_light = s.next_1d();
            let u = s.next_2d();
            // Environment samples are skipped below, so their density does not matter.
            let Some(ls) = world.sample_light(hit, ng, u_light, u, EnvPdf::Full) else {
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
