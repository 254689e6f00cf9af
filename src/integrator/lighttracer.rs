//! The light tracer (forward path tracing; Veach 1997 §10.2's s-strategies with t = 1, pbrt-v4
//! `LightPathIntegrator`, Mitsuba's particle tracer): paths start at the lights and every
//! vertex is joined to the camera, the contribution splatted where it lands on the film
//! ([`crate::film::splat`]). It converges on what a backward path tracer cannot: caustics seen
//! directly (a diffuse surface lit through glass or by a mirror), which it reaches by BSDF
//! sampling from the light.
//!
//! One light path per pixel sample: the pixel only seeds the path (its sample stream), so the
//! film's sample counts are the paths traced and a pixel's value is its splats over spp. The
//! camera's importance W_e is normalised over the whole image (`camera::CameraImportance`);
//! with a crop window only the window's pixels' paths are traced, so their splats are scaled by
//! the image's pixel count over the window's.
//!
//! What the camera sees directly of a light at infinity, and of point-like lights, is not
//! rendered (no light vertex can be joined to the lens for them; pbrt-v4's light tracer has the
//! same limits): the bidirectional path tracer has the strategies for it.
//!
//! Depth counts bounces as the path tracer does: the light seen directly is depth 0, a vertex
//! joined to the camera after k scatterings (counting the one joined) is depth k.
//!
//! Spectral mode (docs/DESIGN.md "Spectral rendering"): a light path carries the three
//! wavelengths of its sample, drawn before the light's numbers as the path tracer draws them
//! before the camera's; the light's emission is taken at them (its own spectrum when it has one),
//! each vertex's BSDF too, and every splat is projected to RGB through the CIE curves as a camera
//! sample is.

use super::RayStats;
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::camera::CameraImportance;
use crate::geometry::Ray;
use crate::geometry::primitive::SurfaceHit;
use crate::material::bxdf::TransportMode;
use crate::math::{Vec2, Vec3};
use crate::sampling::SampleStream;
use crate::sampling::mlt::UniformSource;
use crate::world::World;

/// Where a light path's contributions go: the film point and the value.
pub trait Splat {
    fn splat(&mut self, raster: Vec2, v: Vec3);
}

impl Splat for crate::film::splat::SplatBuffer {
    #[inline]
    fn splat(&mut self, raster: Vec2, v: Vec3) {
        crate::film::splat::SplatBuffer::splat(self, raster, v)
    }
}

/// A point on an emitter chosen for a light path: the light, its choice probability and, for
/// area lights, the surface point the ray leaves from.
pub struct Emission {
    pub index: usize,
    pub pmf: f32,
    pub le: crate::light::LeSample,
    pub point: Option<SurfaceHit>,
}

/// Chooses a light by power (a light path has no receiver to choose for) and samples a ray
/// leaving it, a moving light where it is at shutter time `time` (0 for a still): one 1D and
/// two 2D numbers, always drawn.
#[inline]
pub fn sample_emission(world: &World, s: &mut impl UniformSource, time: f32) -> Option<Emission> {
    let u_light = s.next_1d();
    let u1 = s.next_2d();
    let u2 = s.next_2d();
    if world.lights.is_empty() {
        return None;
    }
    let (index, pmf) = world.lights.distribution.sample_discrete(u_light);
    if !(pmf > 0.0) {
        return None;
    }
    let light = world.lights.posed(index, time);
    let scene = world.light_scene();
    let le = light.sample_le(&scene, u1, u2)?;
    if !(le.pdf_pos > 0.0 && le.pdf_dir > 0.0) || le.le == Vec3::ZERO {
        return None;
    }
    // The same point `sample_le` placed with `u1`, as a full hit (its error bounds and
    // texture coordinates), for joining it to the camera.
    let point = light.as_area().map(|a| a.sample_point(&world.geometry, u1));
    Some(Emission {
        index,
        pmf,
        le,
        point,
    })
}

/// Traces one light path from `s` and splats every contribution it makes to the film into
/// `out`, each multiplied by `scale`. `time` is the path's shutter time (0 for a still): every
/// ray of the path and every join to the lens is at that moment, `world` and `camera` being the
/// scene and the camera there (a motion-blurred frame's step world and posed importance).
#[allow(clippy::too_many_arguments)]
pub fn trace(
    world: &World,
    camera: &CameraImportance,
    s: &mut SampleStream,
    set: &PathSettings,
    time: f32,
    scale: f32,
    stats: &mut RayStats,
    out: &mut impl Splat,
) {
    let spectral = set.for_sample(s);
    let set = spectral.as_ref().unwrap_or(set);
    let Some(em) = sample_emission(world, s, time) else {
        return;
    };
    let scene = world.light_scene();
    let light = world.lights.posed(em.index, time);
    let light_index = em.index as u32;
    // The light seen directly (s = 1): only an area light has a point the lens can see.
    let u_cam = s.next_2d();
    if let (Some(area), Some(lp)) = (light.as_area(), &em.point)
        && let Some(cs) = camera.sample_wi(lp.p, u_cam)
        && area.pdf_le(&scene, lp.ng, cs.wi).1 > 0.0
    {
        let le = light.l(&scene, lp, cs.wi);
        if le != Vec3::ZERO {
            let le = set.light_emission(&world.lights, light_index, le);
            stats.shadow_rays += 1;
            let shadow = Ray::spawn_to(lp.p, lp.p_error, lp.ng, cs.p_lens, Vec3::ZERO, Vec3::ZERO)
                .with_time(time);
            if !world.occluded(&shadow) {
                let pdf = em.pmf * em.le.pdf_pos * cs.pdf;
                let v = le * (lp.ng.dot(cs.wi).abs() * cs.we / pdf);
                out.splat(cs.raster, set.to_film(v * scale));
            }
        }
    }
    if set.max_depth == 0 {
        return;
    }
    let beta0 = set.light_emission(&world.lights, light_index, em.le.le)
        * (em.le.cos() / (em.pmf * em.le.pdf_pos * em.le.pdf_dir));
    let mut beta = beta0;
    // Russian roulette judges the throughput relative to what left the light: β itself is in
    // the light's power units (its 1 / pdf_pos can be large or small), which pbrt-v4's max β
    // rule would read as "always survive" or "always die".
    let inv_beta0 = 1.0 / beta0.max_element();
    let mut ray = em.le.ray;
    let mut v = Vertex::unshaded(SurfaceHit::EMPTY);
    let mut depth = 0u32;
    // Spectral: set once a dispersive surface has kept the hero wavelength alone.
    let mut hero_only = false;
    loop {
        // The light ray and every ray spawned after it: the path's moment.
        ray.time = time;
        stats.rays += 1;
        if !world.intersect_filtered_into(&ray, &set.footprint, &mut v.hit) {
            break;
        }
        let wo = -ray.d.normalize();
        v.shade(world, wo);
        depth += 1;
        // As in the path tracer: the BSDF at the path's wavelengths; a dispersive one keeps the
        // hero wavelength alone, weighted by the number of wavelengths (pbrt-v4
        // `TerminateSecondary`).
        if let Some(w) = &set.wavelengths {
            if !hero_only && v.bsdf.disperses() {
                hero_only = true;
                beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
            }
            v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
        }
        // Join this vertex to the camera (t = 1): two numbers, always drawn.
        let u_cam = s.next_2d();
        if !v.bsdf.is_specular()
            && !v.bsdf.is_black()
            && let Some(cs) = camera.sample_wi(v.hit.p, u_cam)
        {
            let wi_local = v.frame.to_local(cs.wi);
            if v.bsdf.side_consistent(wi_local, cs.wi.dot(v.ng)) {
                let f = v
                    .bsdf
                    .eval_mode(v.wo_local, wi_local, TransportMode::Importance);
                let corr = TransportMode::Importance.shading_normal_correction(
                    v.wo_local,
                    wi_local,
                    Vec3::Z,
                    v.frame.to_local(v.ng),
                );
                let c = beta * f * (wi_local.z.abs() * corr * cs.we / cs.pdf);
                if c.max_element() > 0.0 {
                    stats.shadow_rays += 1;
                    let shadow = Ray::spawn_to(
                        v.hit.p,
                        v.hit.p_error,
                        v.ng,
                        cs.p_lens,
                        Vec3::ZERO,
                        Vec3::ZERO,
                    )
                    .with_time(time);
                    if !world.occluded(&shadow) {
                        out.splat(cs.raster, set.to_film(c * scale));
                    }
                }
            }
        }
        if depth >= set.max_depth {
            break;
        }
        // Continue by sampling the adjoint BSDF.
        let u_lobe = s.next_1d();
        let u_dir = s.next_2d();
        let Some((_, wi, weight)) = v.sample_scatter(TransportMode::Importance, u_lobe, u_dir)
        else {
            break;
        };
        beta *= weight;
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            break;
        }
        // Russian roulette, one number always drawn from `rr_depth` on (as the path tracer).
        if depth >= set.rr_depth {
            let u_rr = s.next_1d();
            let q = (beta.max_element() * inv_beta0 * set.rr_scale).min(1.0);
            if q < 1.0 {
                if u_rr >= q {
                    break;
                }
                beta /= q;
            }
        }
        ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi);
    }
}
