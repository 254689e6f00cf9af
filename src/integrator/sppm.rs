//! Stochastic progressive photon mapping (Hachisuka & Jensen 2009; pbrt-v4 `SPPMIntegrator`,
//! read as a specification): each iteration traces one camera path per pixel through specular
//! and glossy-only bounces to its first vertex with a diffuse lobe (the pixel's *visible
//! point*), adds the direct lighting there by next-event estimation, and then shoots photons
//! from the lights; the photons
//! landing within the pixel's radius of its visible point are its density estimate of the
//! indirect light. After every iteration each pixel shrinks its radius and rescales its flux
//! (Hachisuka et al. 2008, eqs. 6–7, with α = 2/3), so the estimate's bias and variance both go
//! to zero as iterations grow: the method is consistent, not unbiased.
//!
//! The pieces here are per path; the iteration loop and the determinism (photons stored by
//! photon index, a grid built in index order, a gather per pixel) are the driver's,
//! `render/photon.rs`.
//!
//! Depth counts bounces as the path tracer does: a visible point after `c` specular bounces
//! takes photons that bounced `k` times before reaching it only while `c + 1 + k ≤ max_depth`,
//! so a render at depth d estimates the same paths as the path tracer at depth d (pbrt-v4 bounds
//! the camera and photon paths separately). A photon's first hit is never stored: the direct
//! lighting it would estimate is the visible point's next-event estimate (as pbrt-v4).

use super::RayStats;
use super::direct::sample_ld;
use super::lighttracer::sample_emission;
use super::settings::PathSettings;
use super::vertex::Vertex;
use crate::geometry::Ray;
use crate::geometry::primitive::{NO_LIGHT, SurfaceHit};
use crate::material::bxdf::TransportMode;
use crate::math::Vec3;
use crate::sampling::SampleStream;
use crate::sampling::warp::power_heuristic;
use crate::world::World;

/// The photon integrators' own settings (`--photons-per-iteration`, `--photon-radius`; pbrt's
/// `photonsperiteration` and `radius`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotonSettings {
    /// Photon paths per iteration; `None`: one per pixel of the film window (pbrt-v4's default).
    pub photons_per_iteration: Option<u64>,
    /// The initial search radius in scene units; `None`: [`default_radius`].
    pub radius: Option<f32>,
    /// Vertex connection and merging without the merges (`--vcm-no-merge`): bidirectional path
    /// tracing with one light subpath per camera subpath, unbiased (`vcm.rs`).
    pub no_merge: bool,
}

/// The initial radius when none is given: 1/200 of the scene's bounding-box diagonal. pbrt-v4's
/// default is 1 scene unit, which suits scenes a few dozen units across only (a pbrt file's
/// `Integrator "sppm"` without `radius` still gets 1: the importer passes it on).
pub fn default_radius(world: &World) -> f32 {
    let d = world.bounds.diagonal().length();
    if d.is_finite() && d > 0.0 {
        d / 200.0
    } else {
        1.0
    }
}

/// The fraction α of the new photons a pixel keeps when its radius shrinks (Hachisuka et al.
/// 2008 §4.2; pbrt-v4's γ).
pub const ALPHA: f64 = 2.0 / 3.0;

/// A pixel's visible point of one iteration: the shaded vertex, the camera path's throughput to
/// it (zero: the pixel has none this iteration) and the specular bounces before it.
pub struct VisiblePoint {
    pub v: Vertex,
    pub beta: Vec3,
    pub bounces: u32,
    /// Spectral mode: the camera path met a dispersive surface and kept its hero wavelength
    /// alone (lane 0, × 3 in `beta`).
    pub hero_only: bool,
}

impl Default for VisiblePoint {
    fn default() -> Self {
        VisiblePoint {
            v: Vertex::unshaded(SurfaceHit::EMPTY),
            beta: Vec3::ZERO,
            bounces: 0,
            hero_only: false,
        }
    }
}

/// A stored photon: the direction back toward where it came from, its flux and the bounces
/// before it arrived (its position is kept apart, for the grid).
#[derive(Clone, Copy, Debug)]
pub struct Photon {
    pub wi: Vec3,
    pub beta: Vec3,
    pub bounces: u32,
    /// Spectral mode: the photon path met a dispersive surface (lane 0 alone, × 3 in `beta`).
    pub hero_only: bool,
}

/// Traces the camera ray `ray` (filter weight `weight`) to its visible point, filling `vp`, and
/// returns the radiance the path gathers on the way. As pbrt-v4's `SPPMIntegrator`, the visible
/// point is the first vertex whose BSDF has a diffuse lobe ([`crate::material::Bsdf::has_diffuse_lobe`]),
/// or a glossy one where no photon could still reach it (the last bounce): the path continues
/// through specular vertices by sampling, and through glossy-only ones (rough conductors and
/// dielectrics) by sampling too, after a light sample weighted by MIS against that BSDF
/// sample's hit of the light (a narrow lobe's photon density estimate would be noisy and
/// blurred; pbrt-v4 does the same). Emitters are counted when the camera sees them directly or
/// through specular bounces, and with the MIS weight after a glossy bounce. At the visible
/// point the direct light is one light sample without MIS (BSDF-sampled hits of lights are
/// never followed from it, so the light sample carries the whole direct term). Draws 3
/// numbers at the visible point, 3 per specular bounce and 6 per glossy one.
pub fn visible_point(
    world: &World,
    ray: &Ray,
    weight: f32,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    vp: &mut VisiblePoint,
) -> Vec3 {
    vp.beta = Vec3::ZERO;
    vp.hero_only = false;
    let direct = PathSettings {
        nee: true,
        mis: false,
        ..*set
    };
    let glossy = PathSettings {
        nee: true,
        mis: true,
        ..*set
    };
    let env = glossy.env_pdf();
    let mut beta = Vec3::splat(weight);
    let mut l = Vec3::ZERO;
    let mut ray = *ray;
    let mut depth = 0u32;
    // The last non-specular bounce: its BSDF density, position, normal and the normal its
    // light sample took a uniform environment about (`None`: the path so far is specular).
    let mut prev: Option<(f32, Vec3, Vec3, Vec3)> = None;
    loop {
        stats.rays += 1;
        if !world.intersect_filtered_into(&ray, &set.footprint, &mut vp.v.hit) {
            let d = ray.d.normalize();
            match prev {
                None if depth > 0 || !set.transparent => l += beta * set.escaped(world, d),
                None => {}
                // Spectral mode: each light at infinity at the iteration's wavelengths.
                Some((p_b, _, _, uniform_n)) if set.wavelengths.is_some() => {
                    l += world
                        .lights
                        .escaped_mis_each(d, env, uniform_n, |i, le, p_l| {
                            beta * set.light_emission(&world.lights, i, le)
                                * power_heuristic(p_b, p_l)
                        });
                }
                Some((p_b, _, _, uniform_n)) => {
                    l += world.escaped_mis(d, env, uniform_n, |le, p_l| {
                        beta * le * power_heuristic(p_b, p_l)
                    });
                }
            }
            return l;
        }
        let wo = -ray.d.normalize();
        let le = world.emitted(&vp.v.hit, wo);
        if le != Vec3::ZERO {
            let le = set.light_emission(&world.lights, vp.v.hit.light, le);
            let w = match prev {
                Some((p_b, p, ng, _)) if vp.v.hit.light != NO_LIGHT => {
                    power_heuristic(p_b, world.emitter_pdf(p, ng, &vp.v.hit))
                }
                _ => 1.0,
            };
            l += beta * le * w;
        }
        if depth >= set.max_depth {
            return l;
        }
        vp.v.shade(world, wo);
        // Spectral mode: the BSDF at the iteration's wavelengths; a dispersive one keeps the hero
        // wavelength alone, weighted by the number of wavelengths (as the path tracer).
        if let Some(w) = &set.wavelengths {
            if !vp.hero_only && vp.v.bsdf.disperses() {
                vp.hero_only = true;
                beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
            }
            vp.v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
        }
        let specular = vp.v.bsdf.is_specular();
        if !specular {
            if vp.v.bsdf.has_diffuse_lobe() || depth + 1 >= set.max_depth {
                l += sample_ld(world, &vp.v, beta, s, &direct, stats);
                if !vp.v.bsdf.is_black() {
                    vp.beta = beta;
                    vp.bounces = depth;
                }
                return l;
            }
            l += sample_ld(world, &vp.v, beta, s, &glossy, stats);
        }
        let u_lobe = s.next_1d();
        let u_dir = s.next_2d();
        let v = &vp.v;
        let Some(bs) = v.bsdf.sample(v.wo_local, u_lobe, u_dir) else {
            return l;
        };
        let wi = v.frame.to_world(bs.wi);
        if !v.bsdf.side_consistent(bs.wi, wi.dot(v.ng)) {
            return l;
        }
        beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            return l;
        }
        prev = if bs.specular {
            None
        } else {
            Some((bs.pdf, v.hit.p, v.ng, v.uniform_env_normal(env)))
        };
        depth += 1;
        // The camera ray's time (an iteration's, under motion blur) carries on.
        ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(v.hit.time);
    }
}

/// Traces one photon path from the lights (the light tracer's emission sampling and adjoint
/// BSDF sampling, `lighttracer.rs`), pushing every photon it leaves on a non-specular surface
/// after its first bounce onto `points` and `photons`. `v` is vertex storage. `time` is the
/// shutter time of the iteration (0 for a still): the photon leaves its light where the light
/// is then, and every ray of its path is at that moment, the one its iteration's visible
/// points see.
#[allow(clippy::too_many_arguments)]
pub fn trace_photon(
    world: &World,
    s: &mut SampleStream,
    set: &PathSettings,
    time: f32,
    stats: &mut RayStats,
    v: &mut Vertex,
    points: &mut Vec<Vec3>,
    photons: &mut Vec<Photon>,
) {
    // A stored photon has bounced at least once and the visible point scatters it once more.
    if set.max_depth < 2 {
        return;
    }
    let Some(em) = sample_emission(world, s, time) else {
        return;
    };
    // The light's emission at the iteration's wavelengths in spectral mode.
    let le = set.light_emission(&world.lights, em.index as u32, em.le.le);
    let beta0 = le * (em.le.cos() / (em.pmf * em.le.pdf_pos * em.le.pdf_dir));
    if !(beta0.max_element() > 0.0) || !beta0.is_finite() {
        return;
    }
    let mut beta = beta0;
    // Russian roulette relative to what left the light, as the light tracer's.
    let inv_beta0 = 1.0 / beta0.max_element();
    let mut ray = em.le.ray.with_time(time);
    let mut bounces = 0u32;
    let mut hero_only = false;
    loop {
        stats.rays += 1;
        if !world.intersect_filtered_into(&ray, &set.footprint, &mut v.hit) {
            return;
        }
        let wo = -ray.d.normalize();
        v.shade(world, wo);
        if let Some(w) = &set.wavelengths {
            if !hero_only && v.bsdf.disperses() {
                hero_only = true;
                beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
            }
            v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
        }
        if bounces >= 1 && !v.bsdf.is_specular() {
            points.push(v.hit.p);
            photons.push(Photon {
                wi: wo,
                beta,
                bounces,
                hero_only,
            });
        }
        // The next hit would have bounced once more, and be scattered once more at a pixel.
        if bounces + 2 > set.max_depth {
            return;
        }
        let u_lobe = s.next_1d();
        let u_dir = s.next_2d();
        let Some((_, wi, weight)) = v.sample_scatter(TransportMode::Importance, u_lobe, u_dir)
        else {
            return;
        };
        beta *= weight;
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            return;
        }
        bounces += 1;
        if bounces >= set.rr_depth {
            let u_rr = s.next_1d();
            let q = (beta.max_element() * inv_beta0 * set.rr_scale).min(1.0);
            if q < 1.0 {
                if u_rr >= q {
                    return;
                }
                beta /= q;
            }
        }
        ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(time);
    }
}

/// What a pixel carries from iteration to iteration (pbrt-v4's `SPPMPixel`): the sum of its
/// direct estimates, its radius, its photon count N and its flux τ.
#[derive(Clone, Copy, Debug)]
pub struct PixelState {
    pub ld: [f64; 3],
    pub radius: f64,
    pub n: f64,
    pub tau: [f64; 3],
}

impl PixelState {
    pub fn new(radius: f32) -> PixelState {
        PixelState {
            ld: [0.0; 3],
            radius: radius as f64,
            n: 0.0,
            tau: [0.0; 3],
        }
    }

    /// The progressive update after an iteration whose gather found `m` photons of total
    /// (BSDF-weighted) flux `phi` at a visible point of throughput `beta` (Hachisuka et al. 2008,
    /// eqs. 6–7): N' = N + αM, R' = R √(N'/(N + M)), τ' = (τ + βΦ) R'²/R².
    pub fn update(&mut self, m: u64, phi: [f64; 3], beta: Vec3) {
        if m == 0 {
            return;
        }
        let n_new = self.n + ALPHA * m as f64;
        let r_new = self.radius * (n_new / (self.n + m as f64)).sqrt();
        let shrink = (r_new / self.radius).powi(2);
        let b = [beta.x as f64, beta.y as f64, beta.z as f64];
        for c in 0..3 {
            self.tau[c] = (self.tau[c] + b[c] * phi[c]) * shrink;
        }
        self.n = n_new;
        self.radius = r_new;
    }

    /// The pixel's estimate after `iterations` iterations of `photons` photon paths each: the
    /// mean direct light plus τ / (N_emitted π R²).
    pub fn estimate(&self, iterations: u32, photons: u64) -> Vec3 {
        let it = iterations.max(1) as f64;
        let area = std::f64::consts::PI * self.radius * self.radius;
        let denom = it * photons.max(1) as f64 * area;
        let c = |i: usize| {
            let ind = if denom > 0.0 {
                self.tau[i] / denom
            } else {
                0.0
            };
            (self.ld[i] / it + ind) as f32
        };
        Vec3::new(c(0), c(1), c(2))
    }
}

/// The gather of one visible point: the photons within `radius` of it that it may scatter
/// (`bounces` before it plus their own within `max_depth`), their count (all photons within
/// the radius, as pbrt-v4 counts) and their flux weighted by the point's BSDF, summed in the
/// grid's order (a function of the photon list alone).
pub fn gather(
    vp: &VisiblePoint,
    radius: f32,
    max_depth: u32,
    grid: &super::photon_grid::PointGrid,
    points: &[Vec3],
    photons: &[Photon],
) -> (u64, [f64; 3]) {
    let v = &vp.v;
    let mut m = 0u64;
    let mut phi = [0.0f64; 3];
    grid.for_each_within(points, v.hit.p, radius, |i| {
        m += 1;
        let ph = &photons[i];
        if vp.bounces + 1 + ph.bounces > max_depth {
            return;
        }
        let wi_local = v.frame.to_local(ph.wi);
        if !v.bsdf.side_consistent(wi_local, ph.wi.dot(v.ng)) {
            return;
        }
        let mut f = v.bsdf.eval(v.wo_local, wi_local) * ph.beta;
        // Both ends kept the hero alone: its weight of 3 counts once (pbrt-v4 terminates the
        // one set of wavelengths they share).
        if vp.hero_only && ph.hero_only {
            f /= 3.0;
        }
        if f.is_finite() {
            phi[0] += f.x as f64;
            phi[1] += f.y as f64;
            phi[2] += f.z as f64;
        }
    });
    (m, phi)
}
