//! The volumetric path tracer: the path tracer of [`super::path`] extended to the
//! radiative transfer equation (thesis §2.10). It runs instead of `path` whenever the scene has a
//! participating medium or an interface surface; scenes without media keep the surface path
//! tracer untouched (bit-identical images).
//!
//! The estimator is the null-scattering path integral of Miller, Georgiev and Jarosz (2019) in the
//! form pbrt-v4 uses (§14.2–14.3), written here from those equations for RGB:
//!
//! * **Free-flight sampling** by delta tracking against a majorant σ_maj (σt for homogeneous media,
//!   σt·max density for grids), with distances drawn in one *hero channel* h chosen uniformly per
//!   camera sample. At a tentative collision the event is absorption, real scattering or a null
//!   collision with probabilities σa[h]/σ_maj[h], σs[h]/σ_maj[h], σn[h]/σ_maj[h].
//! * **Chromatic media without bias: spectral MIS.** Besides the throughput β (= f / p_h, the path's
//!   contribution over its pdf in the hero channel), two RGB ratios are tracked: r_u[c] = p_c / p_h,
//!   the pdf with which unidirectional sampling in channel c would have made the path, and
//!   r_l[c], the same for a path whose last vertex was made by light sampling. A contribution is
//!   β·L / mean_c(r_u[c] (+ r_l[c])): the balance heuristic over the three channels' sampling
//!   techniques (and, with r_l, over unidirectional and light sampling — MIS between phase/BSDF
//!   and light sampling at every vertex). No channel can give an unbounded weight where another
//!   has no extinction, and the estimate is unbiased for any hero-channel choice.
//! * **Transmittance on shadow rays** by ratio tracking (Novák et al. 2014) in the same null-
//!   scattering form, through index-matched interface surfaces (`MaterialModel::Interface`) and
//!   media; any other surface blocks.
//! * **Absorbing-only homogeneous media** (σs = 0: glTF `KHR_materials_volume`, coloured glass)
//!   need no sampling at all: every path, camera, bounce or shadow, is weighted by exp(−σa·d) along
//!   its real length (Beer–Lambert). This is consistent with MIS because both strategies treat the
//!   segment deterministically.
//!
//! * **Emissive media** (pbrt-v4's `Le`): σa·Le is added at every tentative collision with the
//!   same spectral-MIS weight (pbrt-v4 §14.2.2), and analytically for absorbing-only media.
//!   Medium emission is not sampled by next-event estimation (neither is it in pbrt-v4).
//!
//! Depth counts scattering events, at surfaces and in media alike: `max_depth = 0` shows only
//! emitters seen directly (through media), 1 is single scattering / direct lighting. Medium
//! emission counts as one more event, as in pbrt-v4 (`depth < max_depth`): it needs
//! `max_depth ≥ 1` to be seen directly. Crossing an
//! interface surface is not an event. Russian roulette uses β·η²/mean(r_u) (the path's throughput
//! under MIS) as the surface path tracer uses β·η². `secondary` splitting is not implemented here:
//! the pipeline refuses `--secondary` above 1 for scenes with media.

use super::RayStats;
use super::guiding::{self, Guiding, Mix, Pending, Record};
use super::settings::PathSettings;
use super::vertex::{Vertex, sample_bsdf};
use crate::geometry::Ray;
use crate::geometry::primitive::SurfaceHit;
use crate::material::Bsdf;
use crate::math::{Frame, Vec3};
use crate::medium::{HenyeyGreenstein, TrackStep};
use crate::sampling::SampleStream;
use crate::sampling::rng::{Pcg32, hash_words};
use crate::world::World;

/// Interface crossings allowed per ray segment before the walk gives up (a ray caught between
/// coincident interfaces must not loop for ever).
const MAX_CROSSINGS: u32 = 256;

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

/// How the vertex that sends the NEE shadow ray scatters.
enum Scatterer<'a> {
    Surface {
        bsdf: &'a Bsdf,
        frame: &'a Frame,
        wo_local: Vec3,
        /// Geometric normal turned for scattering (see `oriented_normals`).
        ng: Vec3,
        /// The hit's material and its front-facing geometric normal, for the medium the shadow
        /// ray leaves into.
        material: u32,
        ng_front: Vec3,
        /// A guided vertex's BSDF–guide mixture, the density light samples are weighed against.
        mix: Option<&'a Mix<'a>>,
    },
    /// A point in a medium; `wo` points back along the path (towards the camera).
    Medium {
        phase: HenyeyGreenstein,
        wo: Vec3,
        mix: Option<&'a Mix<'a>>,
    },
}

struct PathState {
    beta: Vec3,
    r_u: Vec3,
    r_l: Vec3,
    channel: usize,
    /// The camera ray's shutter time, which every ray of the path inherits ([`Ray::time`]).
    time: f32,
}

/// Radiance arriving at the camera along `ray`.
pub fn radiance(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
) -> Vec3 {
    // Spectral mode, as the surface path tracer: the wavelengths ride on a copy of the settings
    // and the radiance at them reaches the film as RGB.
    match set.for_sample(s) {
        None => trace(world, ray, s, set, stats, None),
        Some(set) => {
            let l = trace(world, ray, s, &set, stats, None);
            set.to_film(l)
        }
    }
}

/// [`radiance`] guided by `g` (docs/DESIGN.md, "Path guiding"): surface vertices sample the
/// BSDF–guide mixture as the surface path tracer does, medium vertices the mixture of the phase
/// function and the guide of the medium tree (volume path guiding, Herholz et al. 2019, with
/// Müller's SD-tree as the guide), the mixture's choice drawn from the tracking generator; while
/// training, both kinds of vertex are recorded into `g.records`.
pub fn radiance_guided(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    g: &mut Guiding,
) -> Vec3 {
    // The records learn from the radiance in the path's own representation (at the sample's
    // wavelengths in spectral mode), as the surface path tracer's do.
    let (l, film) = match set.for_sample(s) {
        None => {
            let l = trace(world, ray, s, set, stats, Some(&mut *g));
            (l, l)
        }
        Some(set) => {
            let l = trace(world, ray, s, &set, stats, Some(&mut *g));
            (l, set.to_film(l))
        }
    };
    // A record's incident radiance is what the path gathered after it over the path's
    // MIS-weighted throughput there (an approximation: a learning signal only).
    g.finish(l);
    film
}

#[inline(always)]
fn trace(
    world: &World,
    ray: &Ray,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
    mut g: Option<&mut Guiding>,
) -> Vec3 {
    let (guide, training) = match g.as_deref() {
        Some(g) => (g.guide, g.records.is_some()),
        None => (None, false),
    };
    let u_channel = s.next_1d();
    let lambda = set.wavelengths.map(|w| w.lambda);
    let channel = if lambda.is_some() {
        0
    } else {
        ((u_channel * 3.0) as usize).min(2)
    };
    // The tracking decisions use their own generator, seeded from the sample (so the image stays
    // a pure function of seed, pixel and sample index) — as pbrt-v4 seeds its per-ray RNG.
    let d = ray.d.normalize();
    let mut rng = Pcg32::new(
        hash_words(&[
            u64::from(u_channel.to_bits()),
            u64::from(ray.o.x.to_bits()) << 32 | u64::from(ray.o.y.to_bits()),
            u64::from(d.x.to_bits()) << 32 | u64::from(d.y.to_bits()),
            u64::from(d.z.to_bits()),
        ]),
        0x6d65_6469,
    );
    let mut st = PathState {
        beta: Vec3::ONE,
        r_u: Vec3::ONE,
        r_l: Vec3::ONE,
        channel,
        time: ray.time,
    };
    let mut ray = Ray::new(ray.o, d).with_time(ray.time);
    let mut medium = world.camera_medium();
    let mut l = Vec3::ZERO;
    let mut depth = 0u32;
    let mut specular_bounce = false;
    let mut eta_scale = 1.0f32;
    // The last scattering vertex, for the light-sampling pdf of emitters hit later.
    let mut prev_p = ray.o;
    // Its normal as given to the light sample there (zero in a medium): the light BVH's choice,
    // and so the pdf, depends on it.
    let mut prev_n = Vec3::ZERO;
    let mut crossings = 0u32;
    // Spectral mode: whether a dispersive surface has left only the hero wavelength (as in
    // `path.rs`, pbrt-v4 `TerminateSecondary`).
    let mut hero_only = false;
    loop {
        stats.rays += 1;
        let hit = world.intersect_filtered(&ray, &set.footprint);
        let t_max = hit.map_or(f32::INFINITY, |h| h.t);

        // --- The medium between the ray's origin and the surface (or infinity).
        if let Some(mi) = medium {
            let m = world.medium(mi);
            let c = m.coefficients(lambda);
            if m.is_analytic() {
                let tr = m.analytic_transmittance_in(&c, t_max);
                if c.le != Vec3::ZERO && depth < set.max_depth {
                    // ∫₀ᵈ e^(−σa·t)·σa·Le dt = Le·(1 − e^(−σa·d)), exact and noise-free; the
                    // segment is deterministic for every channel's technique, so the MIS
                    // weight is the path's own 1/mean(r_u).
                    l += set.clamp(st.beta * (Vec3::ONE - tr) * c.le / mean(st.r_u), depth);
                }
                st.beta *= tr;
            } else {
                let mut tracker = m.tracker_in(&c, &ray, t_max, channel);
                let mut scattered = false;
                loop {
                    match tracker.step(m, &mut rng) {
                        TrackStep::End { t_maj } => {
                            let th = t_maj[channel];
                            if !(th > 0.0) {
                                return l;
                            }
                            st.beta *= t_maj / th;
                            st.r_u *= t_maj / th;
                            st.r_l *= t_maj / th;
                            break;
                        }
                        TrackStep::Collision {
                            p,
                            props,
                            sigma_maj,
                            t_maj,
                        } => {
                            let sm = sigma_maj[channel];
                            if m.is_emissive() && depth < set.max_depth {
                                // Emission at every tentative collision (pbrt-v4 §14.2.2):
                                // β·T_maj/pdf · σa·Le, MIS-weighted over the channels by the
                                // rescaled probability r_e = r_u·σ_maj·T_maj/pdf of reaching
                                // this point.
                                let pdf = t_maj[channel] * sm;
                                let r_e = mean(st.r_u * sigma_maj * t_maj / pdf);
                                if r_e > 0.0 && pdf > 0.0 {
                                    l += set.clamp(
                                        st.beta * t_maj / pdf * props.sigma_a * m.le_in(&c, p)
                                            / r_e,
                                        depth,
                                    );
                                }
                            }
                            let p_absorb = props.sigma_a[channel] / sm;
                            let p_scatter = props.sigma_s[channel] / sm;
                            let u = rng.next_f32();
                            if u < p_absorb {
                                return l;
                            }
                            if u < p_absorb + p_scatter {
                                // Real scattering.
                                if depth >= set.max_depth {
                                    return l;
                                }
                                depth += 1;
                                let pdf = t_maj[channel] * props.sigma_s[channel];
                                st.beta *= t_maj * props.sigma_s / pdf;
                                st.r_u *= t_maj * props.sigma_s / pdf;
                                if !(st.beta.max_element() > 0.0
                                    && st.r_u.max_element() > 0.0
                                    && st.beta.is_finite())
                                {
                                    return l;
                                }
                                let wo = -ray.d;
                                let mix = guide
                                    .filter(|_| guiding::guides_bounce(depth - 1))
                                    .and_then(|gd| gd.mix_in(p, guiding::MEDIUM_BIN));
                                l += set.clamp(
                                    sample_ld(
                                        world,
                                        p,
                                        Vec3::ZERO,
                                        Vec3::ZERO,
                                        &Scatterer::Medium {
                                            phase: m.phase,
                                            wo,
                                            mix: mix.as_ref(),
                                        },
                                        medium,
                                        &st,
                                        &mut rng,
                                        s,
                                        set,
                                        stats,
                                    ),
                                    depth,
                                );
                                let u_dir = s.next_2d();
                                // (direction, its density, the phase function's, the guide's)
                                let (d_out, pdf, p_phase, p_guide) = match mix.as_ref() {
                                    None => {
                                        let ps = m.phase.sample(ray.d, u_dir);
                                        (ps.d_out, ps.pdf, ps.pdf, 0.0)
                                    }
                                    Some(mx) => guiding::sample_phase_mixture(
                                        &m.phase,
                                        ray.d,
                                        mx,
                                        rng.next_f32(),
                                        u_dir,
                                    ),
                                };
                                if !(pdf > 0.0) {
                                    return l;
                                }
                                // β·p/pdf = β for HG sampled alone (its own pdf); r_l = r_u / pdf.
                                if mix.is_some() {
                                    st.beta *= p_phase / pdf;
                                }
                                st.r_l = st.r_u / pdf;
                                if let Some(g) = g.as_deref_mut()
                                    && training
                                    && g.pending.len() < guiding::MAX_RECORDED_VERTICES
                                {
                                    g.pending.push(Pending {
                                        record: Record {
                                            p,
                                            bin: guiding::MEDIUM_BIN,
                                            wi: d_out,
                                            radiance: 0.0,
                                            f_cos: p_phase,
                                            pdf_bsdf: p_phase,
                                            pdf_guide: p_guide,
                                            pdf,
                                            alpha: mix.as_ref().map_or(1.0, |m| m.alpha),
                                        },
                                        l_before: l,
                                        beta_after: st.beta / mean(st.r_u),
                                        direct: Vec3::ZERO,
                                    });
                                }
                                prev_p = p;
                                prev_n = Vec3::ZERO;
                                specular_bounce = false;
                                ray = Ray::new(p, d_out).with_time(st.time);
                                scattered = true;
                                break;
                            }
                            // Null collision: continue with the null-scattering weight.
                            let sigma_n =
                                (sigma_maj - props.sigma_a - props.sigma_s).max(Vec3::ZERO);
                            let pdf = t_maj[channel] * sigma_n[channel];
                            if !(pdf > 0.0) {
                                return l;
                            }
                            st.beta *= t_maj * sigma_n / pdf;
                            st.r_u *= t_maj * sigma_n / pdf;
                            st.r_l *= t_maj * sigma_maj / pdf;
                            if !(st.beta.max_element() > 0.0 && st.r_u.max_element() > 0.0) {
                                return l;
                            }
                        }
                    }
                }
                if scattered {
                    crossings = 0;
                    if roulette(&mut st, depth, eta_scale, set, s).is_some() {
                        return l;
                    }
                    continue;
                }
            }
        }

        // --- Escaped: lights at infinity.
        let Some(hit) = hit else {
            // Each light at infinity weighed against its own NEE density.
            // Its NEE samples a uniform environment over the whole sphere (`sample_light`).
            // A transparent film leaves out the background the camera sees directly.
            if set.transparent && depth == 0 {
                return l;
            }
            let escaped = world.lights.escaped_mis_each(
                ray.d,
                set.env_pdf(),
                Vec3::ZERO,
                |i, le, pdf_light| {
                    emitter_contribution(
                        &st,
                        set.light_emission(&world.lights, i, le),
                        pdf_light,
                        depth,
                        specular_bounce,
                        set,
                    )
                },
            );
            l += set.clamp(escaped, depth);
            return l;
        };

        // --- The surface.
        let wo = -ray.d;
        let le = set.light_emission(&world.lights, hit.light, world.emitted(&hit, wo));
        if le != Vec3::ZERO {
            let pdf_light = world.emitter_pdf(prev_p, prev_n, &hit);
            l += set.clamp(
                emitter_contribution(&st, le, pdf_light, depth, specular_bounce, set),
                depth,
            );
        }
        if world.is_interface(hit.material) {
            // A boundary between media only: carry on in the same direction.
            medium = world.medium_after(hit.material, ray.d, hit.ng, medium);
            ray = Ray::spawn(hit.p, hit.p_error, hit.ng, ray.d).with_time(st.time);
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                return l;
            }
            continue;
        }
        crossings = 0;
        if depth >= set.max_depth {
            return l;
        }
        depth += 1;
        let mut v = Vertex::new(world, hit, wo);
        if let Some(l) = lambda {
            if !hero_only && v.bsdf.disperses() {
                hero_only = true;
                st.beta = Vec3::new(3.0 * st.beta.x, 0.0, 0.0);
            }
            v.bsdf.make_spectral(l, &world.bsdf_spectra);
        }
        let (bsdf, ng, frame, wo_local, hit) = (&v.bsdf, v.ng, &v.frame, v.wo_local, &v.hit);
        // A guided surface vertex: its tree by the normal faced toward the arriving path.
        let bin = g.is_some().then(|| guiding::normal_bin(hit.ng, wo));
        let mix = match (guide, bin) {
            (Some(gd), Some(b)) if guiding::guidable(bsdf) && guiding::guides_bounce(depth - 1) => {
                gd.mix_in(hit.p, b)
            }
            _ => None,
        };

        if !bsdf.is_specular() {
            l += set.clamp(
                sample_ld(
                    world,
                    hit.p,
                    hit.p_error,
                    ng,
                    &Scatterer::Surface {
                        bsdf,
                        frame,
                        wo_local,
                        ng,
                        material: hit.material,
                        ng_front: hit.ng,
                        mix: mix.as_ref(),
                    },
                    medium,
                    &st,
                    &mut rng,
                    s,
                    set,
                    stats,
                ),
                depth,
            );
        } else {
            s.skip(3);
        }

        // `densities`: the BSDF's and the guide's densities and the BSDF's share, for a
        // training record (as in the surface path tracer).
        let (bs, wi, densities) = if let Some(m) = mix.as_ref() {
            let u_pick = s.next_1d();
            let u_dir = s.next_2d();
            let Some(ms) = guiding::sample_mixture(bsdf, frame, wo_local, m, u_pick, u_dir) else {
                return l;
            };
            (ms.bs, ms.wi, Some((ms.pdf_bsdf, ms.pdf_guide, m.alpha)))
        } else {
            let Some(bs) = sample_bsdf(bsdf, wo_local, s) else {
                return l;
            };
            let wi = frame.to_world(bs.wi);
            let densities =
                (training && !bs.specular && guiding::guidable(bsdf)).then_some((bs.pdf, 0.0, 1.0));
            (bs, wi, densities)
        };
        if !bsdf.side_consistent(bs.wi, wi.dot(ng)) || !(bs.pdf > 0.0) {
            return l;
        }
        st.beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
        st.r_l = st.r_u / bs.pdf;
        if !(st.beta.max_element() > 0.0) || !st.beta.is_finite() {
            return l;
        }
        if let (Some(g), Some((pdf_bsdf, pdf_guide, alpha)), Some(bin)) =
            (g.as_deref_mut(), densities, bin)
            && training
            && !bs.specular
            && g.pending.len() < guiding::MAX_RECORDED_VERTICES
        {
            g.pending.push(Pending {
                record: Record {
                    p: hit.p,
                    bin,
                    wi,
                    radiance: 0.0,
                    f_cos: crate::math::luminance(bs.f) * bs.wi.z.abs(),
                    pdf_bsdf,
                    pdf_guide,
                    pdf: bs.pdf,
                    alpha,
                },
                l_before: l,
                beta_after: st.beta / mean(st.r_u),
                direct: Vec3::ZERO,
            });
        }
        specular_bounce = bs.specular;
        eta_scale *= bs.eta * bs.eta;
        prev_p = hit.p;
        prev_n = ng;
        medium = world.medium_after(hit.material, wi, hit.ng, medium);
        ray = Ray::spawn(hit.p, hit.p_error, ng, wi).with_time(st.time);
        if roulette(&mut st, depth, eta_scale, set, s).is_some() {
            return l;
        }
    }
}

/// Contribution of an emitter reached by unidirectional sampling, MIS-weighted against light
/// sampling (balance heuristic over channels and the two strategies).
#[inline]
fn emitter_contribution(
    st: &PathState,
    le: Vec3,
    pdf_light: f32,
    depth: u32,
    specular_bounce: bool,
    set: &PathSettings,
) -> Vec3 {
    if depth == 0 || specular_bounce || !set.nee || !(pdf_light > 0.0) {
        return st.beta * le / mean(st.r_u);
    }
    if !set.mis {
        return Vec3::ZERO;
    }
    let r_l = st.r_l * pdf_light;
    st.beta * le / mean(st.r_u + r_l)
}

/// Russian roulette on the MIS-weighted throughput; returns `Some(())` if the path ends.
#[inline]
fn roulette(
    st: &mut PathState,
    depth: u32,
    eta_scale: f32,
    set: &PathSettings,
    s: &mut SampleStream,
) -> Option<()> {
    if depth < set.rr_depth {
        return None;
    }
    let rr_beta = st.beta * eta_scale / mean(st.r_u);
    let q = (rr_beta.max_element() * set.rr_scale).min(1.0);
    if q < 1.0 {
        if !(q > 0.0) || s.next_1d() >= q {
            return Some(());
        }
        st.beta /= q;
    }
    None
}

/// Next-event estimation from a surface or medium point: one light sample, its transmittance
/// through interface surfaces and media by ratio tracking, MIS-weighted against phase/BSDF
/// sampling. Consumes three sample dimensions.
#[allow(clippy::too_many_arguments)]
fn sample_ld(
    world: &World,
    p: Vec3,
    p_error: Vec3,
    n_offset: Vec3,
    scatterer: &Scatterer,
    medium_in: Option<usize>,
    st: &PathState,
    rng: &mut Pcg32,
    s: &mut SampleStream,
    set: &PathSettings,
    stats: &mut RayStats,
) -> Vec3 {
    let u_light = s.next_1d();
    let u2 = s.next_2d();
    let n = if n_offset == Vec3::ZERO {
        Vec3::Z
    } else {
        n_offset
    };
    let here = SurfaceHit {
        p,
        p_error,
        ng: n,
        ns: n,
        time: st.time,
        ..SurfaceHit::EMPTY
    };
    let Some(ls) = world.sample_light(&here, n_offset, u_light, u2, set.env_pdf()) else {
        return Vec3::ZERO;
    };
    if !(set.nee || ls.delta) {
        return Vec3::ZERO;
    }
    let (f, scatter_pdf, medium_start) = match scatterer {
        Scatterer::Surface {
            bsdf,
            frame,
            wo_local,
            ng,
            material,
            ng_front,
            mix,
        } => {
            let wi_local = frame.to_local(ls.wi);
            // Shading and geometric normals must agree on the side of `wi`.
            if !bsdf.side_consistent(wi_local, ls.wi.dot(*ng)) {
                return Vec3::ZERO;
            }
            let f = bsdf.eval(*wo_local, wi_local) * wi_local.z.abs();
            // At a medium transition the shadow ray starts in the medium of the side `wi` is on.
            let start = world.medium_after(*material, ls.wi, *ng_front, medium_in);
            let pdf = match mix {
                Some(m) => guiding::mixture_pdf(bsdf, *wo_local, wi_local, ls.wi, m),
                None => bsdf.pdf(*wo_local, wi_local),
            };
            (f, pdf, start)
        }
        Scatterer::Medium { phase, wo, mix } => {
            // Light arrives travelling along −wi and leaves travelling along wo (towards the
            // camera).
            let pv = phase.eval(-ls.wi, *wo);
            let pdf = match mix {
                Some(m) => guiding::phase_mixture_pdf(phase, -*wo, ls.wi, m),
                None => pv,
            };
            (Vec3::splat(pv), pdf, medium_in)
        }
    };
    if f == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let Some((t_ray, r_l_tr, r_u_tr)) = world.transmittance_at(
        &ls.shadow,
        medium_start,
        st.channel,
        set.wavelengths.map(|w| w.lambda),
        rng,
        &mut stats.shadow_rays,
    ) else {
        return Vec3::ZERO;
    };
    let light_pdf = ls.pmf * ls.pdf;
    let r_l = st.r_u * r_l_tr * light_pdf;
    let r_u = st.r_u * r_u_tr * scatter_pdf;
    let denom = if ls.delta || !set.mis {
        mean(r_l)
    } else {
        mean(r_l + r_u)
    };
    if !(denom > 0.0) {
        return Vec3::ZERO;
    }
    st.beta * f * t_ray * set.light_emission(&world.lights, ls.light, ls.li) / denom
}
