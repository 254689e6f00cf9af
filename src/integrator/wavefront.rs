//! The wavefront (stream) form of the surface path tracer's bounce loop (docs/DESIGN.md §6,
//! "Wavefront path loop"): a batch of camera samples' paths advanced together, stage by
//! stage — shade and draw the light sample, trace the batch's shadow rays, finish NEE and sample
//! the BSDF, find the batch's closest hits, add emission and play Russian roulette — each stage a
//! loop over the live paths, compacted after every stage that ends paths (Laine, Karras and
//! Aila 2013, "Megakernels considered harmful"; pbrt-v4's wavefront integrator).
//!
//! Each path draws from its own sample stream exactly the numbers [`super::path::radiance_from`]
//! draws, in the same order, and does the same floating-point arithmetic (the same functions,
//! in the same order within a path; only the order *between* paths changes, and paths share no
//! state but the ray counts, integer sums): its radiance is bit-identical to the scalar
//! tracer's. What may change is the time: a stage runs one piece of code (traversal, a BSDF's
//! set-up, light sampling) over many paths in a row instead of the whole bounce per path, so the
//! instruction cache and the branch predictor see one stage's code at a time.
//!
//! Covered: RGB rendering, unguided, without in-loop AOVs, one continuation per camera sample
//! ([`supports`]); the rest (spectral, guided, AOVs, `--secondary` > 1, media: `volpath`) runs
//! the scalar tracer. `TRAYECTO_PATH_LOOP=scalar` selects the scalar loop everywhere
//! ([`enabled`]).

use super::RayStats;
use super::direct::{PendingLd, sample_ld_begin, sample_ld_finish};
use super::path::background;
use super::settings::PathSettings;
use super::vertex::{Vertex, sample_bsdf};
use crate::geometry::Ray;
use crate::geometry::primitive::{Intersection, NO_LIGHT, SurfaceHit};
use crate::math::Vec3;
use crate::sampling::sampler::{Drawn, WAVE_LANES, WaveDraw};
use crate::sampling::warp::power_heuristic;
use crate::sampling::{Numbers, SampleStream, UniformSource};
use crate::world::World;

/// Whether the renderer runs the surface path tracer's bounces in wavefront form where it
/// [`supports`] them: yes unless `TRAYECTO_PATH_LOOP=scalar` (`wavefront`: yes). Read once per
/// process; either way the image is the same, bit for bit.
pub fn enabled() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| match std::env::var("TRAYECTO_PATH_LOOP") {
        Ok(v) if v == "scalar" => false,
        Ok(v) if v == "wavefront" => true,
        Ok(v) => {
            eprintln!(
                "warning: TRAYECTO_PATH_LOOP={v:?} is not `scalar` or `wavefront`; using the default"
            );
            DEFAULT
        }
        Err(_) => DEFAULT,
    })
}

/// The path loop the renderer uses when `TRAYECTO_PATH_LOOP` is not set (BENCHMARKS.md,
/// "Wavefront path loop", for the measurements that chose it).
const DEFAULT: bool = true;

/// Whether [`Wavefront::trace`] renders samples with these settings: RGB, one continuation.
/// (Guiding and in-loop AOVs are the renderer's to route elsewhere.)
#[inline]
pub fn supports(set: &PathSettings) -> bool {
    !set.spectral && set.secondary <= 1
}

/// A camera sample as the batch sees it: its ray, the ray's closest-hit candidate (found by the
/// renderer's batched first hits) and its sample stream, positioned after the camera's numbers.
pub trait PathStart {
    fn ray(&self) -> &Ray;
    fn first(&self) -> Option<Intersection>;
    fn stream(&mut self) -> &mut SampleStream;
}

/// One path of the batch: the scalar tracer's locals (`radiance_rgb`, `continue_path`), kept
/// between stages.
struct Lane {
    /// The path's vertex storage: each bounce's hit is intersected into it and shaded there.
    v: Vertex,
    /// Unit direction back along the ray that reached `v.hit`.
    wo: Vec3,
    /// What the camera ray's hit emits (or the background): `radiance_rgb`'s `l`.
    first: Vec3,
    /// Whether the path continued past its first hit (`continue_path` ran).
    continued: bool,
    /// `continue_path`'s radiance, throughput, η² product and bounces.
    l: Vec3,
    beta: Vec3,
    eta_scale: f32,
    depth: u32,
    /// The path's place in this bounce's [`WaveDraw`] (its sample numbers, drawn for the whole
    /// wave at once).
    slot: u32,
    /// The light sample waiting for its shadow ray, and whether that ray was blocked.
    pending: Option<PendingLd>,
    occluded: bool,
    /// The BSDF-sampled bounce: its ray and closest-hit candidate, its density and whether it
    /// was specular, the vertex it left (position, oriented geometric normal and the normal a
    /// uniform environment was sampled about) for MIS at what it hits.
    ray: Ray,
    candidate: Option<Intersection>,
    pdf: f32,
    specular: bool,
    wi: Vec3,
    p: Vec3,
    ng: Vec3,
    uniform_n: Vec3,
}

impl Lane {
    fn new() -> Lane {
        Lane {
            v: Vertex::unshaded(SurfaceHit::EMPTY),
            wo: Vec3::Z,
            first: Vec3::ZERO,
            continued: false,
            l: Vec3::ZERO,
            beta: Vec3::ONE,
            eta_scale: 1.0,
            depth: 0,
            slot: 0,
            pending: None,
            occluded: false,
            ray: Ray::new(Vec3::ZERO, Vec3::Z),
            candidate: None,
            pdf: 0.0,
            specular: false,
            wi: Vec3::Z,
            p: Vec3::ZERO,
            ng: Vec3::Z,
            uniform_n: Vec3::ZERO,
        }
    }
}

/// Paths advanced together. A lane holds the vertex with its hit and BSDF, the pending light
/// sample and the bounce ray, 704 bytes (`a_lane_stays_under_a_kilobyte`): with 64 lanes a wave the stages'
/// walks over them missed the L1 data cache 80 times per Cornell sample (callgrind's cache
/// simulation; 4 in the scalar loop), with 32 44 times, while the instruction-cache misses the
/// waves remove rose only from 11 to 15 (92 in the scalar loop); so the renderer's 64-sample
/// batch runs as two waves of 32 (BENCHMARKS.md, "Wavefront path loop").
const WAVE: usize = 32;
const _: () = assert!(WAVE <= WAVE_LANES);

/// A worker's wavefront state: one [`Lane`] per sample of the largest batch it has traced and
/// the lists of live paths, allocated when the worker's batch is made (never per ray or per
/// bounce).
pub struct Wavefront {
    lanes: Vec<Lane>,
    live: Vec<u32>,
    next: Vec<u32>,
    draw: Box<WaveDraw>,
}

impl Wavefront {
    /// State for batches of up to `capacity` samples (a larger batch grows it once).
    pub fn new(capacity: usize) -> Wavefront {
        Wavefront {
            lanes: (0..capacity).map(|_| Lane::new()).collect(),
            live: Vec::with_capacity(capacity),
            next: Vec::with_capacity(capacity),
            draw: Box::default(),
        }
    }

    /// The radiance of the path of sample `i` of the batch last [`Wavefront::trace`]d: bit for
    /// bit `path::radiance_from` of that sample.
    #[inline]
    pub fn radiance(&self, i: usize) -> Vec3 {
        let lane = &self.lanes[i];
        if !lane.continued {
            return lane.first;
        }
        // `radiance_rgb`'s sum over one continuation, with its exact arithmetic.
        let mut sum = Vec3::ZERO;
        sum += lane.l;
        lane.first + sum / 1.0
    }

    /// Traces the paths of `paths` (each from its camera ray's first hit) to their ends, stage by
    /// stage; their radiances are then [`Wavefront::radiance`]. Draws from each sample's stream
    /// and counts in `stats` exactly what `path::radiance_from` does. Requires [`supports`]`(set)`.
    pub fn trace<P: PathStart>(
        &mut self,
        world: &World,
        set: &PathSettings,
        paths: &mut [P],
        stats: &mut RayStats,
    ) {
        debug_assert!(supports(set));
        while self.lanes.len() < paths.len() {
            self.lanes.push(Lane::new());
        }
        for start in (0..paths.len()).step_by(WAVE) {
            let end = (start + WAVE).min(paths.len());
            self.trace_wave(world, set, paths, start..end, stats);
        }
    }

    /// [`Wavefront::trace`] for the samples `wave` of `paths`.
    fn trace_wave<P: PathStart>(
        &mut self,
        world: &World,
        set: &PathSettings,
        paths: &mut [P],
        wave: std::ops::Range<usize>,
        stats: &mut RayStats,
    ) {
        self.live.clear();
        // The camera rays' hits: `radiance_rgb` up to `continue_path`.
        for i in wave {
            let path = &paths[i];
            let lane = &mut self.lanes[i];
            stats.rays += 1;
            lane.continued = false;
            let ray = path.ray();
            let Some(isect) = path.first() else {
                lane.first = background(world, ray, set);
                continue;
            };
            if !world.complete_filtered_into(ray, isect, &set.footprint, &mut lane.v.hit) {
                lane.first = background(world, ray, set);
                continue;
            }
            let wo = -ray.d.normalize();
            let v = &lane.v;
            lane.first = set.clamp(
                set.light_emission(&world.lights, v.hit.light, world.emitted(&v.hit, wo)),
                0,
            );
            if set.max_depth == 0 {
                continue;
            }
            lane.continued = true;
            lane.wo = wo;
            lane.l = Vec3::ZERO;
            lane.beta = Vec3::ONE;
            lane.eta_scale = 1.0;
            lane.depth = 0;
            self.live.push(i as u32);
        }
        let lanes = &mut self.lanes[..];
        let draw = &mut *self.draw;
        let drawn = self
            .live
            .first()
            .is_some_and(|&i| WaveDraw::covers(paths[i as usize].stream()));
        while !self.live.is_empty() {
            // Shade each vertex.
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                lane.v.shade(world, lane.wo);
            }
            // The bounce's sample numbers for every live path at once, where the sampler
            // allows it (otherwise each path draws its own as it goes: the same numbers). Only
            // the draws some path will ask for: the light's spare number with more than one
            // light, the light's point unless every vertex is specular or black, the lobe
            // unless every BSDF has one, and roulette's number from its depth on (the wave's
            // paths are all at the same depth).
            draw.begin();
            if drawn {
                let mut need = [false, false, false, true, false];
                for (k, &i) in self.live.iter().enumerate() {
                    let lane = &mut lanes[i as usize];
                    lane.slot = k as u32;
                    draw.push(paths[i as usize].stream());
                    let b = &lane.v.bsdf;
                    need[1] |= !(b.is_specular() || b.is_black());
                    need[2] |= !b.has_one_lobe();
                    need[4] |= lane.depth + 1 >= set.rr_depth;
                }
                need[0] = need[1] && world.light_count() > 1;
                draw.run(need);
            }
            let draw = &*draw;
            // Draw each vertex's light sample (`sample_ld_begin`).
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                let mut s = Drawn::new(paths[i as usize].stream(), draw, lane.slot as usize);
                lane.pending = sample_ld_begin(world, &lane.v, &mut s, set);
            }
            // The batch's shadow rays.
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                if let Some(p) = &lane.pending {
                    stats.shadow_rays += 1;
                    lane.occluded = world.occluded(&p.ls.shadow);
                }
            }
            // Finish NEE, sample the BSDF and spawn the bounce ray (`continue_path`).
            self.next.clear();
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                let s = paths[i as usize].stream();
                if bounce(
                    world,
                    set,
                    lane,
                    &mut Drawn::new(s, draw, lane.slot as usize),
                    stats,
                ) {
                    self.next.push(i);
                }
            }
            std::mem::swap(&mut self.live, &mut self.next);
            // The batch's closest hits.
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                lane.candidate = world.candidate(&lane.ray);
            }
            // What each bounce found: emission (MIS-weighted), escape, the depth limit and
            // Russian roulette.
            self.next.clear();
            for &i in &self.live {
                let lane = &mut lanes[i as usize];
                let s = paths[i as usize].stream();
                if arrive(
                    world,
                    set,
                    lane,
                    &mut Drawn::new(s, draw, lane.slot as usize),
                ) {
                    self.next.push(i);
                }
            }
            std::mem::swap(&mut self.live, &mut self.next);
        }
    }
}

/// `continue_path` from its light sample's result to the bounce ray: adds the light sample,
/// samples the BSDF and spawns the ray; `false` when the path ends here.
#[inline(always)]
fn bounce(
    world: &World,
    set: &PathSettings,
    lane: &mut Lane,
    s: &mut Drawn,
    stats: &mut RayStats,
) -> bool {
    let v = &lane.v;
    let ld = match &lane.pending {
        Some(p) if !lane.occluded => sample_ld_finish(world, v, lane.beta, set, p, None, None),
        _ => Vec3::ZERO,
    };
    lane.l += set.clamp(ld, lane.depth + 1);
    let Some(bs) = sample_bsdf(&v.bsdf, v.wo_local, s) else {
        return false;
    };
    let wi = v.frame.to_world(bs.wi);
    if !v.bsdf.side_consistent(bs.wi, wi.dot(v.ng)) {
        return false;
    }
    let w = bs.f * (bs.wi.z.abs() / bs.pdf);
    lane.beta *= w;
    lane.eta_scale *= bs.eta * bs.eta;
    if !(lane.beta.max_element() > 0.0) || !lane.beta.is_finite() {
        return false;
    }
    lane.depth += 1;
    lane.ray = Ray::spawn(v.hit.p, v.hit.p_error, v.ng, wi).with_time(v.hit.time);
    stats.rays += 1;
    lane.p = v.hit.p;
    lane.ng = v.ng;
    lane.uniform_n = v.uniform_env_normal(set.env_pdf());
    lane.pdf = bs.pdf;
    lane.specular = bs.specular;
    lane.wi = wi;
    true
}

/// `continue_path` after the bounce ray's closest hit: completes the hit into the vertex, adds
/// what it emits (or the lights at infinity if it escaped), then the depth limit and Russian
/// roulette; `false` when the path ends here.
#[inline(always)]
fn arrive(world: &World, set: &PathSettings, lane: &mut Lane, s: &mut Drawn) -> bool {
    let (beta, depth, wi) = (lane.beta, lane.depth, lane.wi);
    let hit = match lane.candidate {
        Some(isect) => {
            world.complete_filtered_into(&lane.ray, isect, &set.footprint, &mut lane.v.hit)
        }
        None => false,
    };
    if !hit {
        // Each light at infinity weighed against its own NEE density.
        let escaped =
            world
                .lights
                .escaped_mis_each(wi, set.env_pdf(), lane.uniform_n, |i, le, pdf_light| {
                    let weight = if lane.specular || !set.nee {
                        1.0
                    } else if !set.mis {
                        0.0
                    } else {
                        power_heuristic(lane.pdf, pdf_light)
                    };
                    beta * set.light_emission(&world.lights, i, le) * weight
                });
        lane.l += set.clamp(escaped, depth);
        return false;
    }
    let next = &lane.v.hit;
    let wo_next = -wi;
    let le = set.light_emission(&world.lights, next.light, world.emitted(next, wo_next));
    if le != Vec3::ZERO {
        let weight = if lane.specular || !set.nee || next.light == NO_LIGHT {
            1.0
        } else if !set.mis {
            0.0
        } else {
            let pdf_light = world.emitter_pdf(lane.p, lane.ng, next);
            power_heuristic(lane.pdf, pdf_light)
        };
        lane.l += set.clamp(beta * le * weight, depth);
    }
    if depth >= set.max_depth {
        return false;
    }
    // Russian roulette, as `continue_path` plays it (the unguided path's ratio is 1).
    if depth >= set.rr_depth {
        let rr_ratio = 1.0f32;
        let q = (beta.max_element() * rr_ratio * lane.eta_scale * set.rr_scale).min(1.0);
        if q < 1.0 {
            let u_rr = s.next_1d();
            if u_rr >= q {
                return false;
            }
            lane.beta /= q;
        } else {
            s.skip(1);
        }
    }
    lane.wo = wo_next;
    true
}

#[cfg(test)]
mod tests {
    /// The lanes of a wave are walked once per stage: their size is what the L1 data cache
    /// has to hold (see [`super::WAVE`]). A lane grown past 1 KB should make that choice again.
    #[test]
    fn a_lane_stays_under_a_kilobyte() {
        let size = std::mem::size_of::<super::Lane>();
        eprintln!("Lane: {size} bytes");
        assert!(size <= 1024, "Lane is {size} bytes");
    }
}
