//! The render driver of stochastic progressive photon mapping (`integrator/sppm.rs`;
//! docs/DESIGN.md, integrators): [`crate::render`] hands it the frame once the settings are
//! validated.
//!
//! An iteration is one sample index of every pixel: a camera pass (parallel over rows, each
//! pixel finding its visible point and its direct light with the stream of (seed, pixel,
//! iteration), as the tiled driver seeds a sample), a photon pass (parallel over fixed chunks of
//! photon indices; photon j of iteration i has a stream of its own, so it is the same path
//! whoever traces it, and the chunks' photons are concatenated in index order), a hashed grid
//! over the photons built in that order (`integrator/photon_grid.rs`), and a gather parallel over
//! pixels, each summing its own photons in grid order and updating its own radius and flux. No
//! sum is shared between threads, so the image is a pure function of the seed and the settings
//! for any thread count.
//!
//! A pixel's radius and count depend on every earlier iteration, so a frame cannot be split
//! into sample ranges (the farm, `--samples-range`) nor resumed from a checkpoint: both are
//! refused with the reason. The film is written from the pixels' estimates after every pass of
//! [`super::pass_schedule`] (the previews) and at the end.

use crate::camera::Camera;
use crate::film::Film;
use crate::film::filter::FilterSampler;
use crate::film::splat::SplatBuffer;
use crate::film::to_fixed;
use crate::geometry::primitive::SurfaceHit;
use crate::integrator::photon_grid::PointGrid;
use crate::integrator::sppm::{self, Photon, PixelState, VisiblePoint};
use crate::integrator::vcm::{self, LightVertex, Vcm};
use crate::integrator::vertex::Vertex;
use crate::integrator::{Integrator, RayStats};
use crate::math::Vec3;
use crate::render::{FilmRender, RangeStart, RenderError, RenderObserver, RenderSettings};
use crate::sampling::{SamplerKind, SamplerSetup};
use crate::world::World;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Photon paths traced by one task of the photon pass: a fixed split of the photon indices
/// (whatever the thread count), whose photons are concatenated in order.
const PHOTON_CHUNK: u64 = 4096;

/// Why SPPM cannot render `world` with `settings`, if it cannot.
pub fn check(world: &World, settings: &RenderSettings) -> Result<(), RenderError> {
    let bad = |m: &str| Err(RenderError::InvalidSetting(m.to_string()));
    if world.has_media() {
        return bad(
            "stochastic progressive photon mapping (--integrator sppm) does not render \
             participating media or medium interfaces (nor does pbrt-v4's SPPMIntegrator, which \
             ignores them): use --integrator path",
        );
    }
    if settings.noise_threshold.is_some() {
        return bad(
            "adaptive sampling (--noise-threshold) does not apply to SPPM: every pixel takes \
             part in every iteration's photon pass",
        );
    }
    if settings.guiding {
        return bad("path guiding (--guiding) guides the path tracer, not SPPM");
    }
    if settings.path.secondary > 1 {
        return bad(
            "secondary rays do not apply to SPPM: each iteration takes one visible point per \
             pixel; raise the iterations (--spp) instead",
        );
    }
    if let Some(r) = settings.photon.radius
        && !(r > 0.0 && r.is_finite())
    {
        return bad("the photon radius (--photon-radius) must be positive");
    }
    if settings.photon.photons_per_iteration == Some(0) {
        return bad("photons per iteration must be at least 1");
    }
    Ok(())
}

/// Why a sample range or a checkpoint cannot be rendered with SPPM.
fn check_range(start: &RangeStart) -> Result<(), RenderError> {
    if start.samples.start > 0 || start.resume.is_some() {
        return Err(RenderError::InvalidSetting(
            "SPPM cannot render a sample range that does not start at 0, nor resume from a \
             checkpoint: each pixel's photon radius and count depend on every earlier \
             iteration, so its iterations cannot be rendered apart and added"
                .into(),
        ));
    }
    Ok(())
}

/// Renders iterations `start.samples` (from 0) of the frame with SPPM.
pub(crate) fn render(
    world: &World,
    settings: &RenderSettings,
    start: RangeStart,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    check(world, settings)?;
    check_range(&start)?;
    let t0 = Instant::now();
    let (w, h) = (settings.width, settings.height);
    let camera = Camera::new(&world.camera, w, h);
    let mut path = settings.path;
    if world.needs_footprint() {
        path.footprint = camera.footprint();
    }
    let win = settings.film_window();
    let (fw, fh) = (win.width(), win.height());
    let n_pix = fw as usize * fh as usize;
    let photons_per_iter = settings
        .photon
        .photons_per_iteration
        .unwrap_or(n_pix as u64)
        .max(1);
    let r0 = settings
        .photon
        .radius
        .unwrap_or_else(|| sppm::default_radius(world));
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h);
    // The photons' own streams: independent numbers keyed by (iteration, photon index), from a
    // seed of their own so they are not the camera samples' numbers.
    let photon_sampler = SamplerSetup::new(
        SamplerKind::Independent,
        settings.seed ^ 0x5370_706d_5068_6f74,
        1,
    );
    let filter = FilterSampler::new(&settings.filter);
    let iterations = start.samples.end;
    let previews: Vec<u32> = crate::render::pass_schedule(iterations)
        .into_iter()
        .map(|(_, b)| b)
        .collect();
    let deadline = settings.time_limit.map(|t| t0 + Duration::from_secs_f64(t));

    let mut vps: Vec<VisiblePoint> = (0..n_pix).map(|_| VisiblePoint::default()).collect();
    let mut pixels = vec![PixelState::new(r0); n_pix];
    let mut stats = RayStats::default();
    let mut done = 0u32;
    let mut cancelled = false;
    let mut stopped_early = false;
    let mut film = Film::new(fw, fh);
    for it in 0..iterations {
        if it > 0 && deadline.is_some_and(|d| Instant::now() >= d) {
            stopped_early = true;
            break;
        }
        // Spectral mode: the iteration's wavelengths, shared by its camera paths and photons.
        let path = for_iteration(path, settings.seed, it);
        // Motion blur: the iteration's moment, shared by its camera paths and photons.
        let (time, step, posed) = iteration_moment(world, &camera, settings.seed, it);
        let cam = posed.as_ref().unwrap_or(&camera);
        // Camera pass: each row's pixels write only their own visible points and sums.
        let cam_stats = vps
            .par_chunks_mut(fw as usize)
            .zip(pixels.par_chunks_mut(fw as usize))
            .enumerate()
            .map(|(fy, (vrow, prow))| {
                let mut st = RayStats::default();
                if cancel.load(Ordering::Relaxed) {
                    return st;
                }
                let y = fy as u32 + win.y0;
                for (fx, (vp, px)) in vrow.iter_mut().zip(prow.iter_mut()).enumerate() {
                    let x = fx as u32 + win.x0;
                    let mut stream = sampler.stream(sampler.pixel_key((x, y)), it);
                    let (ray, weight) = super::camera_ray(cam, &filter, &mut stream, x, y);
                    let ray = ray.with_time(time);
                    let l =
                        sppm::visible_point(step, &ray, weight, &mut stream, &path, &mut st, vp);
                    let l = path.to_film(l);
                    if l.is_finite() {
                        px.ld[0] += l.x as f64;
                        px.ld[1] += l.y as f64;
                        px.ld[2] += l.z as f64;
                    }
                }
                st
            })
            .reduce(RayStats::default, sum_stats);
        // Photon pass: chunks of photon indices, collected in index order.
        let chunks = photons_per_iter.div_ceil(PHOTON_CHUNK);
        let traced: Vec<(Vec<Vec3>, Vec<Photon>, RayStats)> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut st = RayStats::default();
                let (mut points, mut photons) = (Vec::new(), Vec::new());
                let mut v = Vertex::unshaded(SurfaceHit::EMPTY);
                let end = ((c + 1) * PHOTON_CHUNK).min(photons_per_iter);
                for j in c * PHOTON_CHUNK..end {
                    if cancel.load(Ordering::Relaxed) {
                        break;
                    }
                    let key = photon_sampler.pixel_key((j as u32, it));
                    let key = key ^ (j >> 32).wrapping_mul(0x9e37_79b9_7f4a_7c15);
                    let mut s = photon_sampler.stream(key, 0);
                    sppm::trace_photon(
                        step,
                        &mut s,
                        &path,
                        time,
                        &mut st,
                        &mut v,
                        &mut points,
                        &mut photons,
                    );
                }
                (points, photons, st)
            })
            .collect();
        if cancel.load(Ordering::Relaxed) {
            cancelled = true;
            break;
        }
        let total: usize = traced.iter().map(|t| t.0.len()).sum();
        let (mut points, mut photons) = (Vec::with_capacity(total), Vec::with_capacity(total));
        stats += cam_stats;
        for (p, ph, st) in traced {
            points.extend_from_slice(&p);
            photons.extend_from_slice(&ph);
            stats += st;
        }
        // The grid's cells are as large as the largest radius a visible point searches, so a
        // query visits at most two cells a side.
        let cell = vps
            .iter()
            .zip(&pixels)
            .filter(|(vp, _)| vp.beta != Vec3::ZERO)
            .map(|(_, px)| px.radius as f32)
            .fold(0.0f32, f32::max);
        if cell > 0.0 {
            let grid = PointGrid::build(&points, cell);
            let max_depth = path.max_depth;
            vps.par_iter()
                .zip(pixels.par_iter_mut())
                .for_each(|(vp, px)| {
                    if vp.beta == Vec3::ZERO {
                        return;
                    }
                    let (m, phi) =
                        sppm::gather(vp, px.radius as f32, max_depth, &grid, &points, &photons);
                    match &path.wavelengths {
                        None => px.update(m, phi, vp.beta),
                        // The point's throughput times the photons' flux, per wavelength,
                        // projected to RGB (pbrt-v4 `ToOutputRGB(vp.beta * Phi, lambda)`).
                        Some(w) => {
                            let lanes = Vec3::new(phi[0] as f32, phi[1] as f32, phi[2] as f32);
                            let rgb = w.to_rgb(vp.beta * lanes);
                            let rgb = [rgb.x as f64, rgb.y as f64, rgb.z as f64];
                            px.update(m, rgb, Vec3::ONE);
                        }
                    }
                });
        }
        done = it + 1;
        crate::render::report_work(observer, done as u64, iterations as u64, t0);
        if previews.contains(&done) && done < iterations {
            film = to_film(&pixels, fw, fh, done, photons_per_iter);
            observer.pass_done(&film, done, settings.spp);
        }
    }
    if done > 0 {
        film = to_film(&pixels, fw, fh, done, photons_per_iter);
        if !cancelled && done == iterations {
            observer.pass_done(&film, done, settings.spp);
        }
    }
    Ok(FilmRender {
        film,
        start: 0,
        done,
        cancelled,
        stopped_early,
        stats,
        render_time: t0.elapsed(),
        aovs: None,
    })
}

/// The settings of SPPM or VCM iteration `it`: in spectral mode `path` carrying
/// [`iteration_wavelengths`], else `path` as it is.
fn for_iteration(
    path: crate::integrator::PathSettings,
    seed: u64,
    it: u32,
) -> crate::integrator::PathSettings {
    if path.spectral {
        crate::integrator::PathSettings {
            wavelengths: Some(iteration_wavelengths(seed, it)),
            ..path
        }
    } else {
        path
    }
}

/// The wavelengths of SPPM or VCM iteration `it` in spectral mode: one set for all its camera
/// paths and photons (light subpaths), since each visible point (camera vertex) gathers photons
/// of the same iteration (pbrt-v4
/// `SPPMIntegrator::Render` draws them per iteration by the base-3 radical inverse), here
/// shifted by a number of the seed so that seeds differ in their wavelengths too.
fn iteration_wavelengths(seed: u64, it: u32) -> crate::spectrum::Wavelengths {
    let (mut x, mut f, mut n) = (0.0f64, 1.0 / 3.0, it);
    while n > 0 {
        x += (n % 3) as f64 * f;
        n /= 3;
        f /= 3.0;
    }
    let shift = (crate::sampling::rng::hash_words(&[seed, 0x7370_706d_6c61_6d62]) >> 11) as f64
        / (1u64 << 53) as f64;
    let u = ((x + shift).fract() as f32).min(1.0 - f32::EPSILON / 2.0);
    crate::spectrum::Wavelengths::sample(u)
}

/// The shutter time of SPPM or VCM iteration `it` of a motion-blurred frame, shared by all its
/// camera paths and photons (light subpaths): the base-2 radical inverse of `it` (van der
/// Corput), shifted by a number of the seed (a Cranley–Patterson rotation), so the first 2^k
/// iterations meet each 2^-k of the shutter once. One moment per iteration, not per path:
/// a visible point (camera vertex) gathers, and merges with, the photons of its iteration, and
/// photons traced at other moments would land where the surfaces were then (a density estimate
/// joining two times is not the scene at either). Each iteration is then an SPPM or VCM
/// iteration of the still at its time, consistent as the radius shrinks, and the image, their
/// average, converges to the shutter's average as the iterations sample the shutter: a
/// stratified estimate of a time integral, whose error for a few iterations is temporal
/// aliasing (the frame at a few moments), gone by a few hundred (docs/DESIGN.md).
fn iteration_time(seed: u64, it: u32) -> f32 {
    let x = it.reverse_bits() as f64 / 4_294_967_296.0;
    let shift = (crate::sampling::rng::hash_words(&[seed, 0x6d6f_7469_6f6e_7469]) >> 11) as f64
        / (1u64 << 53) as f64;
    ((x + shift).fract() as f32).min(1.0 - f32::EPSILON / 2.0)
}

/// The moment of SPPM or VCM iteration `it` ([`iteration_time`]): its time, the world to trace
/// then (a shutter step's where motion falls back to worlds per step, [`World::at_step`]) and
/// the camera placed where it is then (`None`: `camera` as it is). A still: time 0, `world`.
fn iteration_moment<'a>(
    world: &'a World,
    camera: &Camera,
    seed: u64,
    it: u32,
) -> (f32, &'a World, Option<Camera>) {
    if world.is_still() {
        return (0.0, world, None);
    }
    let t = iteration_time(seed, it);
    let step = world.at_step(crate::world::motion::step_of(t, world.time_steps()));
    let posed = world.camera_motion.as_ref().map(|m| {
        let mut c = camera.clone();
        c.camera_to_world = m.at(t);
        c
    });
    (t, step, posed)
}

fn sum_stats(mut a: RayStats, b: RayStats) -> RayStats {
    a += b;
    a
}

/// The film holding every pixel's estimate after `iterations`, as `iterations` samples of it
/// (the film's exact fixed point; a non-finite estimate is dropped and counted).
fn to_film(pixels: &[PixelState], fw: u32, fh: u32, iterations: u32, photons: u64) -> Film {
    let mut discarded = 0u64;
    let sum = pixels
        .iter()
        .map(|px| {
            let l = px.estimate(iterations, photons) * iterations as f32;
            if l.is_finite() && l.max_element() < crate::film::SAMPLE_LIMIT {
                [to_fixed(l.x), to_fixed(l.y), to_fixed(l.z)]
            } else {
                discarded += 1;
                [0; 3]
            }
        })
        .collect();
    Film::from_raw(fw, fh, sum, vec![iterations; pixels.len()], discarded)
        .expect("one state per pixel of the window")
}

/// Why vertex connection and merging cannot render `world` with `settings`, if it cannot: the
/// light tracer's reasons (`render/light.rs`: a camera without importance, media, adaptive
/// sampling, guiding) and its own settings'.
pub fn check_vcm(world: &World, settings: &RenderSettings) -> Result<(), RenderError> {
    super::light::check(world, Integrator::Vcm, settings)?;
    let bad = |m: &str| Err(RenderError::InvalidSetting(m.to_string()));
    if world.has_media() {
        // Its subpaths trace straight from surface to surface (no transmittance, no scattering
        // in a medium), so a medium would be silently ignored. Merging is a density estimate
        // on surfaces (Georgiev et al. 2012); in a medium it needs volume kernels and their
        // own MIS (points and beams: Křivánek et al. 2014's unified points, beams and paths).
        return bad(
            "vertex connection and merging (--integrator vcm) does not render participating \
             media or medium interfaces: its paths and merges are on surfaces only, so a medium \
             would be ignored; use --integrator bdpt or volpath",
        );
    }
    if settings.path.secondary > 1 {
        return bad("secondary rays do not apply to vertex connection and merging");
    }
    if let Some(r) = settings.photon.radius
        && !(r > 0.0 && r.is_finite())
    {
        return bad("the merge radius (--photon-radius) must be positive");
    }
    Ok(())
}

/// Renders sample indices (iterations) `start.samples` of every pixel with vertex connection
/// and merging (`integrator/vcm.rs`). An iteration's radius depends on its index alone and its
/// light subpaths on (seed, pixel, index), so iterations are independent: light subpaths'
/// splats and camera subpaths' values go to per-thread fixed-point buffers
/// ([`SplatBuffer`]) whose exact sums make the film the same for any thread count and for a
/// frame split into sample ranges or resumed, as the light tracer's (`render/light.rs`).
pub(crate) fn render_vcm(
    world: &World,
    settings: &RenderSettings,
    start: RangeStart,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    check_vcm(world, settings)?;
    let t0 = Instant::now();
    let (w, h) = (settings.width, settings.height);
    let super::SplatSetup {
        camera,
        importance,
        path,
        win,
        scale,
    } = super::SplatSetup::new(world, settings)?;
    let (fw, fh) = (win.width(), win.height());
    let n_pix = fw as usize * fh as usize;
    let r0 = settings
        .photon
        .radius
        .unwrap_or_else(|| sppm::default_radius(world));
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h);
    // The light subpaths' streams: the same sampler, from a seed of their own.
    let light_sampler = SamplerSetup::new(
        settings.sampler,
        settings.seed ^ 0x7663_6d4c_6967_6874,
        settings.spp,
    )
    .for_image(w, h);
    let filter = FilterSampler::new(&settings.filter);
    let first = start.samples.start;
    let (mut film, from) = match start.resume {
        Some((film, at)) => (film, at),
        None => (Film::new(fw, fh), first),
    };
    let passes: Vec<(u32, u32)> = super::pass_schedule(start.samples.end - from)
        .into_iter()
        .map(|(a, b)| (a + from, b + from))
        .collect();
    let deadline = settings.time_limit.map(|t| t0 + Duration::from_secs_f64(t));
    let threads = rayon::current_num_threads().max(1);
    let buffers: Vec<std::sync::Mutex<SplatBuffer>> = (0..threads)
        .map(|_| std::sync::Mutex::new(SplatBuffer::new(win.x0, win.y0, fw, fh, &settings.filter)))
        .collect();
    let buffer = || {
        let k = rayon::current_thread_index().unwrap_or(0) % threads;
        buffers[k].lock().unwrap_or_else(|e| e.into_inner())
    };
    let mut stats = RayStats::default();
    let mut done = from;
    let mut cancelled = false;
    let mut stopped_early = false;
    let total_work = (start.samples.end - from) as u64;
    'passes: for (q, &(s0, s1)) in passes.iter().enumerate() {
        if q > 0 && deadline.is_some_and(|d| Instant::now() >= d) {
            stopped_early = true;
            break;
        }
        for b in &buffers {
            b.lock().unwrap_or_else(|e| e.into_inner()).clear();
        }
        for it in s0..s1 {
            // Spectral mode: the iteration's wavelengths, shared by its light and camera
            // subpaths since a camera vertex merges with other pixels' light vertices (as SPPM).
            let path = for_iteration(path, settings.seed, it);
            // Motion blur: the iteration's moment, shared by its light and camera subpaths
            // since a camera vertex merges with other pixels' light vertices (as SPPM).
            let (time, step, posed) = iteration_moment(world, &camera, settings.seed, it);
            let cam = posed.as_ref().unwrap_or(&camera);
            let importance = super::posed_importance(world, &importance, time);
            let vcm = Vcm::new(
                step,
                &importance,
                &path,
                scale,
                vcm::radius(r0, it),
                n_pix as u64,
                !settings.photon.no_merge,
                time,
            );
            // Light subpaths, one per pixel, stored row by row in pixel order.
            let mut rows: Vec<LightRow> = (0..fh)
                .into_par_iter()
                .map(|fy| {
                    let mut st = RayStats::default();
                    let (mut verts, mut points) = (Vec::new(), Vec::new());
                    let mut ends = Vec::with_capacity(fw as usize);
                    if !cancel.load(Ordering::Relaxed) {
                        let mut buf = buffer();
                        let y = fy + win.y0;
                        for x in win.x0..win.x1 {
                            let mut s = light_sampler.stream(light_sampler.pixel_key((x, y)), it);
                            vcm.light_path(&mut s, &mut st, &mut verts, &mut points, &mut *buf);
                            ends.push(verts.len() as u32);
                        }
                    }
                    LightRow {
                        verts,
                        points,
                        ends,
                        stats: st,
                    }
                })
                .collect();
            if cancel.load(Ordering::Relaxed) {
                cancelled = true;
                break 'passes;
            }
            let total: usize = rows.iter().map(|r| r.verts.len()).sum();
            let (mut all, mut points) = (Vec::with_capacity(total), Vec::with_capacity(total));
            let mut row_start = Vec::with_capacity(fh as usize);
            for row in &mut rows {
                row_start.push(all.len());
                all.append(&mut row.verts);
                points.append(&mut row.points);
                stats += row.stats;
            }
            let grid = if settings.photon.no_merge {
                PointGrid::default()
            } else {
                PointGrid::build(&points, vcm.radius)
            };
            let cam_stats = (0..fh)
                .into_par_iter()
                .map(|fy| {
                    let mut st = RayStats::default();
                    if cancel.load(Ordering::Relaxed) {
                        return st;
                    }
                    let ends = &rows[fy as usize].ends;
                    let base = row_start[fy as usize];
                    let y = fy + win.y0;
                    let mut values = Vec::with_capacity(fw as usize);
                    for (fx, x) in (win.x0..win.x1).enumerate() {
                        let a = base + if fx == 0 { 0 } else { ends[fx - 1] as usize };
                        let b = base + ends[fx] as usize;
                        let mut s = sampler.stream(sampler.pixel_key((x, y)), it);
                        let (ray, weight) = super::camera_ray(cam, &filter, &mut s, x, y);
                        let ray = ray.with_time(time);
                        let l = vcm.camera_path(
                            &ray,
                            weight,
                            &mut s,
                            &mut st,
                            &all[a..b],
                            &grid,
                            &all,
                            &points,
                        );
                        values.push(path.to_film(l));
                    }
                    let mut buf = buffer();
                    for (fx, l) in values.into_iter().enumerate() {
                        buf.add_pixel(win.x0 + fx as u32, y, l);
                    }
                    st
                })
                .reduce(RayStats::default, sum_stats);
            stats += cam_stats;
            crate::render::report_work(observer, (it + 1 - from) as u64, total_work, t0);
            if cancel.load(Ordering::Relaxed) {
                cancelled = true;
                break 'passes;
            }
        }
        // Exact integer sums: the buffers' order does not matter.
        for b in &buffers {
            film.add_splats(&b.lock().unwrap_or_else(|e| e.into_inner()));
        }
        film.add_counts(s1 - s0);
        done = s1;
        observer.pass_done(&film, done, settings.spp);
    }
    Ok(FilmRender {
        film,
        start: first,
        done,
        cancelled,
        stopped_early,
        stats,
        render_time: t0.elapsed(),
        aovs: None,
    })
}

/// One row's light subpaths: their stored vertices and positions in pixel order, where each
/// pixel's end, and the rays traced.
struct LightRow {
    verts: Vec<LightVertex>,
    points: Vec<Vec3>,
    ends: Vec<u32>,
    stats: RayStats,
}

#[cfg(test)]
mod tests {
    use super::iteration_time;

    /// The first 2^k iterations' times meet each 2^-k of the shutter once, for every k and seed
    /// (the stratification the convergence of a blurred SPPM or VCM render rests on), and the
    /// times lie in [0, 1) and differ between seeds.
    #[test]
    fn iteration_times_stratify_the_shutter() {
        for seed in [0u64, 1, 7, 0x5eed_5eed] {
            for k in 0..=9u32 {
                let n = 1u32 << k;
                let mut hit = vec![false; n as usize];
                for it in 0..n {
                    let t = iteration_time(seed, it);
                    assert!((0.0..1.0).contains(&t), "{t}");
                    let cell = ((t as f64 * n as f64) as usize).min(n as usize - 1);
                    assert!(
                        !hit[cell],
                        "seed {seed}, {n} iterations: stratum {cell} twice"
                    );
                    hit[cell] = true;
                }
            }
        }
        assert_ne!(iteration_time(1, 0), iteration_time(2, 0));
    }
}
