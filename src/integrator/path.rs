//! The unidirectional path tracer of the thesis (§5.4), made unbiased: BSDF importance sampling
//! (§5.4.3), next-event estimation (§5.4.4) combined with BSDF sampling by multiple importance
//! sampling with the power heuristic (Veach 1997, ch. 9), and Russian roulette (§5.4.5) that divides
//! by the survival probability. Turning NEE or MIS off changes the variance, not the expectation:
//!
//! * NEE and MIS on: light samples and BSDF-sampled emitter hits are both kept, weighted by the
//!   power heuristic; the weights of the two strategies sum to one for every path.
//! * NEE on, MIS off: light samples carry weight 1, emitter hits after a non-specular bounce weight 0.
//! * NEE off: emitter hits carry weight 1. Delta lights (point, spot, directional) can never be hit,
//!   so they are always sampled explicitly.
//!
//! Depth counts bounces: `max_depth = 0` shows only emitters seen directly, 1 is direct lighting.

use super::RayStats;
use super::aov::AovPath;
use super::direct::sample_ld_mix;
use super::guiding::{self, Guiding, Pending, Record};
use super::vertex::{Vertex, sample_bsdf};
use crate::geometry::Ray;
use crate::geometry::primitive::{Intersection, NO_LIGHT, SurfaceHit};
use crate::math::{Vec3, luminance};
use crate::sampling::SampleStream;
use crate::sampling::warp::power_heuristic;
use crate::world::World;

// Where the settings always were, for library users.
pub use super::settings::PathSettings;

/// Radiance arriving at the camera along `ray`.
pub fn radiance(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
) -> Vec3 {
    radiance_impl(world, ray, world.candidate(ray), s, set, stats, None, None)
}

/// [`radiance`] with the camera ray's closest-hit candidate `first` (its [`World::candidate`])
/// already found, as the renderer's batched first hits do (`render.rs`, "batched first hits"):
/// the result, the rays counted and the numbers drawn from `s` are exactly those of
/// [`radiance`].
pub fn radiance_from(
    world: &World,
    ray: &Ray,
    first: Option<Intersection>,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
) -> Vec3 {
    radiance_impl(world, ray, first, s, set, stats, None, None)
}

/// [`radiance`], also recording the sample's AOVs (the first hit; the albedo and normal at the
/// first non-specular vertex) into `aov` from the vertices the path visits anyway, instead of
/// a second tracing of the camera ray. The radiance, the rays traced and the numbers drawn
/// from `s` are exactly those of [`radiance`]: the recorder only reads the path's vertices.
pub fn radiance_aov(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    aov: &mut AovPath,
) -> Vec3 {
    radiance_impl(
        world,
        ray,
        world.candidate(ray),
        s,
        set,
        stats,
        Some(aov),
        None,
    )
}

/// [`radiance_aov`] from the camera ray's precomputed candidate `first`, as [`radiance_from`].
pub fn radiance_aov_from(
    world: &World,
    ray: &Ray,
    first: Option<Intersection>,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    aov: &mut AovPath,
) -> Vec3 {
    radiance_impl(world, ray, first, s, set, stats, Some(aov), None)
}

/// [`radiance_from`] (with `aov`, [`radiance_aov_from`]) guided by `g` (docs/DESIGN.md, "Path
/// guiding"): at guided vertices directions come from the BSDF–guide mixture
/// ([`guiding::sample_mixture`]), and while training the path's vertices are recorded into
/// `g.records`. Draws the same sampler dimensions per bounce as the unguided path.
#[allow(clippy::too_many_arguments)]
pub fn radiance_guided_from(
    world: &World,
    ray: &Ray,
    first: Option<Intersection>,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    aov: Option<&mut AovPath>,
    g: &mut Guiding,
) -> Vec3 {
    radiance_impl(world, ray, first, s, set, stats, aov, Some(g))
}

/// What a camera ray that hits nothing sees: the lights at infinity, or nothing on a
/// transparent film.
#[inline]
pub(crate) fn background(world: &World, ray: &Ray, set: &PathSettings) -> Vec3 {
    if set.transparent {
        Vec3::ZERO
    } else {
        set.clamp(set.escaped(world, ray.d.normalize()), 0)
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn radiance_impl(
    world: &World,
    ray: &Ray,
    first: Option<Intersection>,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    aov: Option<&mut AovPath>,
    g: Option<&mut Guiding>,
) -> Vec3 {
    // Spectral mode: this sample's wavelengths ride on a copy of the settings, and its radiance
    // (one value per wavelength) reaches the film as RGB (docs/DESIGN.md "Spectral rendering").
    match set.for_sample(s) {
        None => radiance_rgb(world, ray, first, s, set, stats, aov, g),
        Some(set) => {
            let l = radiance_rgb(world, ray, first, s, &set, stats, aov, g);
            set.to_film(l)
        }
    }
}

/// [`radiance_impl`] in the path's own colour representation: linear sRGB, or in spectral mode
/// the radiance at `set.wavelengths`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn radiance_rgb(
    world: &World,
    ray: &Ray,
    first: Option<Intersection>,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    mut aov: Option<&mut AovPath>,
    mut g: Option<&mut Guiding>,
) -> Vec3 {
    stats.rays += 1;
    // The path's one vertex storage: each bounce's hit is intersected into it and shaded in
    // place (`Vertex::shade`), never moved. Set up only once the camera ray hits something.
    let Some(isect) = first else {
        return background(world, ray, set);
    };
    let mut v = Vertex::unshaded(SurfaceHit::EMPTY);
    if !world.complete_filtered_into(ray, isect, &set.footprint, &mut v.hit) {
        return background(world, ray, set);
    }
    let wo = -ray.d.normalize();
    let mut l = set.clamp(
        set.light_emission(&world.lights, v.hit.light, world.emitted(&v.hit, wo)),
        0,
    );
    if set.max_depth == 0 {
        if let Some(a) = aov {
            // No scattering vertex is built for the radiance: build one for the AOVs.
            let depth = v.hit.t * ray.d.length();
            v.shade(world, wo);
            a.first(world, &v, wo, depth);
            a.end_at(&v, wo);
        }
        return l;
    }
    let n = set.secondary.max(1);
    let mut sum = Vec3::ZERO;
    if let Some(a) = aov.as_deref_mut() {
        a.sample.first = None;
    }
    let depth0 = aov.is_some().then(|| v.hit.t * ray.d.length());
    for i in 1..=n {
        // The first continuation records the AOVs.
        let rec = aov.take().map(|a| (a, depth0.unwrap_or(0.0)));
        // Every continuation but the last starts from a copy of the hit; the last takes the
        // storage itself.
        sum += if i < n {
            let mut copy = Vertex::unshaded(v.hit);
            continue_path(world, &mut copy, wo, s, set, stats, rec, g.as_deref_mut())
        } else {
            continue_path(world, &mut v, wo, s, set, stats, rec, g.as_deref_mut())
        };
    }
    l += sum / n as f32;
    l
}

/// Scatters from `v.hit` (reached with direction `-wo`, not yet shaded) until the path ends;
/// returns the radiance it gathers, not counting the hit's own emission. `v` is the path's
/// vertex storage: each bounce's hit is intersected into `v.hit` and shaded there.
#[allow(clippy::too_many_arguments)]
fn continue_path(
    world: &World,
    v: &mut Vertex,
    mut wo: Vec3,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    mut aov: Option<(&mut AovPath, f32)>,
    mut g: Option<&mut Guiding>,
) -> Vec3 {
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    // Product of η² over refractions: undoes the 1/η² radiance scaling for Russian roulette,
    // whose survival should not depend on which medium the path is in (PBRT-v4 §14.1.2).
    let mut eta_scale = 1.0f32;
    // Product over guided bounces of q/p_bsdf (`guiding::rr_as_bsdf`); 1 unguided.
    let mut rr_ratio = 1.0f32;
    let mut depth = 0u32;
    // Spectral mode: whether the path has dropped all but its hero wavelength (at the first
    // dispersive surface, [`crate::material::Bsdf::disperses`]).
    let mut hero_only = false;
    // Sampler dimensions per bounce, taken whatever the vertex is: light (1D spare + 2D, see
    // `sample_ld`), BSDF lobe (1D) and direction (2D), and from `rr_depth` on Russian roulette
    // (1D).
    loop {
        v.shade(world, wo);
        if let Some((a, first_depth)) = aov.as_mut() {
            if depth == 0 {
                a.first(world, v, wo, *first_depth);
            }
            a.vertex(v, wo);
            if a.is_done() {
                aov = None;
            }
        }
        // The AOVs above saw the RGB BSDF; the path carries it at its wavelengths. A
        // dispersive surface keeps the hero wavelength alone, weighted by the number of
        // wavelengths (pbrt-v4 `TerminateSecondary`; docs/DESIGN.md "Spectral rendering").
        if let Some(w) = &set.wavelengths {
            if !hero_only && v.bsdf.disperses() {
                hero_only = true;
                beta = Vec3::new(3.0 * beta.x, 0.0, 0.0);
            }
            v.bsdf.make_spectral(w.lambda, &world.bsdf_spectra);
        }
        // A guided vertex samples the BSDF–guide mixture, and NEE weighs against it.
        let (guide, training) = match g.as_deref() {
            Some(g) => (g.guide, g.records.is_some()),
            None => (None, false),
        };
        // The vertex's tree: its normal faced toward the side the path arrived from.
        let bin = g.is_some().then(|| guiding::normal_bin(v.ng, wo));
        let mix = match (guide, bin) {
            (Some(gd), Some(b)) if guiding::guidable(&v.bsdf) && guiding::guides_bounce(depth) => {
                gd.mix_in(v.hit.p, b)
            }
            _ => None,
        };
        // While training, the light sample is a record too: the radiance NEE found along its
        // direction, weighted by its MIS weight, as the BSDF-sampled records carry theirs
        // (together they estimate the direct light arriving at the vertex, as in Müller 2019).
        let mut seen = None;
        let record_nee = training
            && guiding::records_nee()
            && guiding::learns_direct()
            && guiding::guidable(&v.bsdf);
        l += set.clamp(
            sample_ld_mix(
                world,
                v,
                beta,
                s,
                set,
                stats,
                mix.as_ref(),
                record_nee.then_some(&mut seen),
            ),
            depth + 1,
        );
        if let (Some((wi, radiance, pdf)), Some(out), Some(bin)) = (
            seen,
            g.as_deref_mut().and_then(|g| g.records.as_deref_mut()),
            bin,
        ) {
            out.push(Record {
                p: v.hit.p,
                bin,
                wi,
                radiance,
                f_cos: 0.0,
                pdf_bsdf: 0.0,
                pdf_guide: 0.0,
                pdf,
                alpha: 1.0,
            });
        }

        // BSDF sampling (or the mixture's): choose the next direction. The mixture takes the
        // lobe-choice number as its strategy choice, so the dimensions stay the same.
        // `densities`: the BSDF's and the guide's densities and the BSDF's share, for a
        // training record.
        let mut mix_densities = None;
        let (bs, wi, densities) = if let Some(m) = mix.as_ref() {
            let u_pick = s.next_1d();
            let u_dir = s.next_2d();
            let Some(ms) = guiding::sample_mixture(&v.bsdf, &v.frame, v.wo_local, m, u_pick, u_dir)
            else {
                break;
            };
            mix_densities = (!ms.bs.specular).then_some((ms.pdf_bsdf, ms.pdf_guide, m.alpha));
            (ms.bs, ms.wi, Some((ms.pdf_bsdf, ms.pdf_guide, m.alpha)))
        } else {
            let Some(bs) = sample_bsdf(&v.bsdf, v.wo_local, s) else {
                break;
            };
            let wi = v.frame.to_world(bs.wi);
            let densities = (training && !bs.specular && guiding::guidable(&v.bsdf))
                .then_some((bs.pdf, 0.0, 1.0));
            (bs, wi, densities)
        };
        if !v.bsdf.side_consistent(bs.wi, wi.dot(v.ng)) {
            break;
        }
        let w = bs.f * (bs.wi.z.abs() / bs.pdf);
        beta *= w;
        // Roulette's view of a guided bounce: the throughput BSDF sampling would have given.
        if let Some((pdf_bsdf, _, _)) = mix_densities
            && pdf_bsdf > 0.0
            && guiding::rr_as_bsdf()
        {
            rr_ratio *= bs.pdf / pdf_bsdf;
        }
        if let Some((a, _)) = aov.as_mut() {
            a.specular_bounce(w);
        }
        eta_scale *= bs.eta * bs.eta;
        if !(beta.max_element() > 0.0) || !beta.is_finite() {
            break;
        }
        let mut recorded = false;
        if let (Some(g), Some((pdf_bsdf, pdf_guide, alpha))) = (g.as_deref_mut(), densities)
            && training
            && !bs.specular
            && g.pending.len() < guiding::MAX_RECORDED_VERTICES
        {
            g.pending.push(Pending {
                record: Record {
                    p: v.hit.p,
                    bin: bin.unwrap_or(0),
                    wi,
                    radiance: 0.0,
                    f_cos: luminance(bs.f) * bs.wi.z.abs(),
                    pdf_bsdf,
                    pdf_guide,
                    pdf: bs.pdf,
                    alpha,
                },
                l_before: l,
                beta_after: beta,
                direct: Vec3::ZERO,
            });
            recorded = !guiding::learns_direct();
        }
        depth += 1;

        let ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(v.hit.time);
        stats.rays += 1;
        // The next hit overwrites this vertex's; MIS below still needs where it was (and the
        // normal its NEE sampled a uniform environment about).
        let (p, ng) = (v.hit.p, v.ng);
        let uniform_n = v.uniform_env_normal(set.env_pdf());
        if !world.intersect_filtered_into(&ray, &set.footprint, &mut v.hit) {
            // Each light at infinity weighed against its own NEE density.
            let escaped =
                world
                    .lights
                    .escaped_mis_each(wi, set.env_pdf(), uniform_n, |i, le, pdf_light| {
                        let weight = if bs.specular || !set.nee {
                            1.0
                        } else if !set.mis {
                            0.0
                        } else {
                            power_heuristic(bs.pdf, pdf_light)
                        };
                        beta * set.light_emission(&world.lights, i, le) * weight
                    });
            let escaped = set.clamp(escaped, depth);
            l += escaped;
            if recorded
                && set.nee
                && let Some(p) = g.as_deref_mut().and_then(|g| g.pending.last_mut())
            {
                p.direct = escaped;
            }
            break;
        }
        let next = &v.hit;
        let wo_next = -wi;
        let le = set.light_emission(&world.lights, next.light, world.emitted(next, wo_next));
        if le != Vec3::ZERO {
            let weight = if bs.specular || !set.nee || next.light == NO_LIGHT {
                1.0
            } else if !set.mis {
                0.0
            } else {
                let pdf_light = world.emitter_pdf(p, ng, next);
                power_heuristic(bs.pdf, pdf_light)
            };
            let hit = set.clamp(beta * le * weight, depth);
            l += hit;
            // An emitter NEE samples is direct light; one it does not is the guide's to learn.
            if recorded
                && set.nee
                && next.light != NO_LIGHT
                && let Some(p) = g.as_deref_mut().and_then(|g| g.pending.last_mut())
            {
                p.direct = hit;
            }
        }
        if depth >= set.max_depth {
            if let Some((a, _)) = aov {
                v.shade(world, wo_next);
                a.end_at(v, wo_next);
            }
            break;
        }
        // Russian roulette: survive with probability q, and divide by it to stay unbiased. The
        // dimension is taken whether or not it is needed (q = 1), so every bounce of every
        // sample takes the same sampler dimensions: a bounce's light and BSDF numbers then stay
        // stratified across the pixel's samples, which a draw made by some samples and not by
        // others would shift out of step. With q = 1 the number is skipped, not computed.
        if depth >= set.rr_depth {
            let q = (beta.max_element() * rr_ratio * eta_scale * set.rr_scale).min(1.0);
            if q < 1.0 {
                let u_rr = s.next_1d();
                if u_rr >= q {
                    if let Some((a, _)) = aov {
                        v.shade(world, wo_next);
                        a.end_at(v, wo_next);
                    }
                    break;
                }
                beta /= q;
            } else {
                s.skip(1);
            }
        }
        wo = wo_next;
    }
    if let Some(g) = g {
        g.finish(l);
    }
    l
}
