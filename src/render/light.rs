//! The render driver of the integrators whose contributions land anywhere on the film (the light
//! tracer; docs/DESIGN.md, integrators): [`crate::render`] hands them the frame once it has
//! validated the settings and the sample range.
//!
//! Every pixel sample still starts one path, seeded by (seed, pixel, sample index) as in the
//! tiled driver, so a path is the same whoever traces it. Rows of the film window are shared
//! out to the workers from a counter; each worker splats into its own [`SplatBuffer`] over the
//! whole window, and at the end of a pass the buffers are added to the film. The sums are exact
//! integers, so neither the order of the additions nor which worker traced which row changes
//! the film: the image is a pure function of seed and settings for any thread count, and a
//! frame split into sample ranges (the farm, `--samples-range`) or resumed from a checkpoint
//! adds up to exactly the single run. Passes follow [`pass_schedule`], so previews and
//! cancelling behave as in the tiled driver (a cancelled pass adds nothing).

use crate::camera::Camera;
use crate::film::Film;
use crate::film::aov::{AovKind, Layer, Strategy};
use crate::film::filter::FilterSampler;
use crate::film::splat::SplatBuffer;
use crate::integrator::{Integrator, RayStats, bdpt, lighttracer};
use crate::math::{Vec2, Vec3};
use crate::render::{FilmRender, RangeStart, RenderError, RenderObserver, RenderSettings};
use crate::sampling::SamplerSetup;
use crate::world::World;
use rayon::prelude::*;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Why `integrator` cannot render `world` with `settings`, if it cannot: a camera without an
/// importance function, emissive media (neither subpath samples their emission), adaptive
/// sampling (a pixel's error is not its own samples' any more), and the settings of Metropolis
/// light transport and guiding that do not apply.
pub fn check(
    world: &World,
    integrator: Integrator,
    settings: &RenderSettings,
) -> Result<(), RenderError> {
    let bad = |m: String| Err(RenderError::InvalidSetting(m));
    let name = integrator.name();
    let camera = Camera::new(&world.camera, settings.width, settings.height);
    if let Err(e) = camera.importance() {
        return bad(format!("the {name} cannot render this camera: {e}"));
    }
    if (0..world.media.media.len()).any(|i| world.medium(i).is_emissive()) {
        return bad(format!(
            "the {name} does not render emissive media (their emission is not sampled from \
             either end of a path): use --integrator path"
        ));
    }
    if settings.noise_threshold.is_some() {
        return bad(format!(
            "adaptive sampling (--noise-threshold) does not apply to the {name}: its paths land \
             on other pixels than the one that started them"
        ));
    }
    if integrator == Integrator::Mlt {
        if settings.time_limit.is_some() {
            return bad(
                "a time limit (--time-limit) does not apply to Metropolis light transport: its \
                 image is normalised by the mutations of every chain, run to the end"
                    .into(),
            );
        }
        settings
            .mlt
            .validate()
            .map_err(RenderError::InvalidSetting)?;
    }
    if settings.guiding {
        return bad(format!(
            "path guiding (--guiding) guides the path tracer, not the {name}"
        ));
    }
    Ok(())
}

/// Renders `start.samples` of every pixel of the film window with the splatting `integrator`.
pub(crate) fn render(
    world: &World,
    integrator: Integrator,
    settings: &RenderSettings,
    start: RangeStart,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    check(world, integrator, settings)?;
    if integrator == Integrator::Mlt {
        if start.samples != (0..settings.spp) || start.resume.is_some() {
            return Err(RenderError::InvalidSetting(
                "Metropolis light transport renders the whole frame at once: its chains are \
                 not split into sample ranges (--samples-range, the farm) nor resumed"
                    .into(),
            ));
        }
        return super::mlt::render(world, settings, observer, cancel);
    }
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
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h);
    let first = start.samples.start;
    let (mut film, from) = match start.resume {
        Some((film, at)) => (film, at),
        None => (Film::new(fw, fh), first),
    };
    let passes: Vec<(u32, u32)> = crate::render::pass_schedule(start.samples.end - from)
        .into_iter()
        .map(|(a, b)| (a + from, b + from))
        .collect();
    let deadline = settings.time_limit.map(|t| t0 + Duration::from_secs_f64(t));
    let threads = rayon::current_num_threads().max(1);
    let buffers: Vec<Mutex<(SplatBuffer, RayStats, bdpt::Scratch)>> = (0..threads)
        .map(|_| {
            Mutex::new((
                SplatBuffer::new(win.x0, win.y0, fw, fh, &settings.filter),
                RayStats::default(),
                bdpt::Scratch::default(),
            ))
        })
        .collect();
    let filter = FilterSampler::new(&settings.filter);
    let ctx = bdpt::Context {
        world,
        camera: &importance,
        set: &path,
        time: 0.0,
    };
    let moving = !world.is_still();
    let mut stats = RayStats::default();
    let mut done = from;
    let mut cancelled = false;
    let mut stopped_early = false;
    // Progress in pixel samples (passes double in size: rows alone would front-load it).
    let work_total: u64 =
        passes.iter().map(|&(a, b)| (b - a) as u64).sum::<u64>() * fw as u64 * fh as u64;
    let work_done = std::sync::atomic::AtomicU64::new(0);
    for (q, &(s0, s1)) in passes.iter().enumerate() {
        if q > 0 && deadline.is_some_and(|d| Instant::now() >= d) {
            stopped_early = true;
            break;
        }
        let next_row = AtomicUsize::new(0);
        let worker = |k: usize| {
            let mut guard = buffers[k].lock().unwrap_or_else(|e| e.into_inner());
            let (buf, st, scratch) = &mut *guard;
            buf.clear();
            *st = RayStats::default();
            loop {
                if cancel.load(Ordering::Relaxed) {
                    return;
                }
                let fy = next_row.fetch_add(1, Ordering::Relaxed) as u32;
                if fy >= fh {
                    return;
                }
                let y = fy + win.y0;
                for x in win.x0..win.x1 {
                    let key = sampler.pixel_key((x, y));
                    for s in s0..s1 {
                        let mut stream = sampler.stream(key, s);
                        match integrator {
                            Integrator::LightTracer => {
                                // A motion-blurred light path draws its time first.
                                let time = if moving { stream.next_1d() } else { 0.0 };
                                let posed = super::posed_importance(world, &importance, time);
                                let ctx = super::at_time(&ctx, &posed, time);
                                if world.has_media() {
                                    bdpt::trace_light(&ctx, &mut stream, scratch, st, scale, buf)
                                } else {
                                    lighttracer::trace(
                                        ctx.world,
                                        ctx.camera,
                                        &mut stream,
                                        &path,
                                        time,
                                        scale,
                                        st,
                                        buf,
                                    )
                                }
                            }
                            Integrator::Bdpt => {
                                let (ray, weight) =
                                    sample_camera_ray(world, &camera, &filter, &mut stream, x, y);
                                let posed = super::posed_importance(world, &importance, ray.time);
                                let l = bdpt::trace(
                                    &super::at_time(&ctx, &posed, ray.time),
                                    &ray,
                                    weight,
                                    &mut stream,
                                    scratch,
                                    st,
                                    scale,
                                    buf,
                                    &mut bdpt::NoStrategies,
                                );
                                buf.add_pixel(x, y, l);
                            }
                            _ => unreachable!("only splatting integrators come here"),
                        }
                    }
                }
                let row = (s1 - s0) as u64 * fw as u64;
                let n = work_done.fetch_add(row, Ordering::Relaxed) + row;
                super::report_work(observer, n, work_total, t0);
            }
        };
        rayon::scope(|sc| {
            for k in 0..threads {
                let worker = &worker;
                sc.spawn(move |_| worker(k));
            }
        });
        if cancel.load(Ordering::Relaxed) {
            cancelled = true;
            break;
        }
        // Exact integer sums: the buffers' order does not matter.
        for b in &buffers {
            let g = b.lock().unwrap_or_else(|e| e.into_inner());
            film.add_splats(&g.0);
            stats += g.1;
        }
        film.add_counts(s1 - s0);
        done = s1;
        observer.pass_done(&film, done, settings.spp);
        if cancel.load(Ordering::Relaxed) && q + 1 < passes.len() {
            cancelled = true;
            break;
        }
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

/// Why the strategy layers `kinds` ([`AovKind::Strategy`]) cannot be rendered with `settings`
/// in `world`, if they cannot: they are the bidirectional path tracer's, and a strategy deeper
/// than `--max-depth` makes no path.
pub fn check_strategies(
    world: &World,
    settings: &RenderSettings,
    kinds: &[AovKind],
) -> Result<(), RenderError> {
    let Some(first) = kinds.iter().find(|k| k.is_strategy()) else {
        return Ok(());
    };
    if settings.path.spectral {
        return Err(RenderError::InvalidSetting(format!(
            "--aov {}: the strategy layers are not available in spectral mode yet (a strategy's \
             contribution is not projected to RGB on its own): render it with --rgb",
            first.name()
        )));
    }
    if Integrator::for_world(settings.integrator, world) != Integrator::Bdpt {
        return Err(RenderError::InvalidSetting(format!(
            "--aov {}: the strategy layers are the bidirectional path tracer's: render with \
             --integrator bdpt",
            first.name()
        )));
    }
    for k in kinds {
        if let AovKind::Strategy(st) = k
            && st.depth() > settings.path.max_depth
        {
            return Err(RenderError::InvalidSetting(format!(
                "--aov {}: its paths have {} bounces, more than --max-depth {}: the layer would \
                 be black",
                k.name(),
                st.depth(),
                settings.path.max_depth
            )));
        }
    }
    Ok(())
}

/// Where each strategy's contributions go: `slots[s][t]` holds the buffer indices of its
/// weighted and unweighted layers (pbrt-v4 `BDPTIntegrator`'s `visualizeStrategies` and
/// `visualizeWeights` films). Contributions land as the beauty's do: on the sample's pixel, or
/// splatted where a t = 1 strategy joined the lens.
struct StrategyFilms<'a> {
    slots: &'a [[[Option<usize>; 2]; STRATEGY_T]],
    bufs: &'a mut [SplatBuffer],
    pixel: (u32, u32),
    scale: f32,
}

/// Strategies (s, t) with s, t < this have a slot ([`Strategy::MAX_DEPTH`] + 3).
const STRATEGY_T: usize = Strategy::MAX_DEPTH as usize + 3;

impl bdpt::StrategySink for StrategyFilms<'_> {
    #[inline]
    fn strategy(&mut self, s: usize, t: usize, l: Vec3, w: f32, raster: Vec2) {
        let Some(slot) = self.slots.get(s).and_then(|r| r.get(t)) else {
            return;
        };
        for (i, v) in slot.iter().zip([l * w, l]) {
            let Some(i) = *i else { continue };
            if t == 1 {
                self.bufs[i].splat(raster, v * self.scale);
            } else {
                self.bufs[i].add_pixel(self.pixel.0, self.pixel.1, v);
            }
        }
    }
}

/// The strategy layers among `kinds` ([`AovKind::Strategy`]; the others are skipped), rendered
/// over sample indices `0..samples` of the film window by the bidirectional path tracer: the
/// beauty render's paths again (the same sample streams; the strategies draw no numbers of
/// their own), each strategy's contribution kept apart, so the weighted layers of every
/// strategy up to `--max-depth` add up to the beauty image (to the rounding of the separate
/// sums). A pass of its own, as the other AOVs without an in-loop recording: it costs about
/// another render. Exact fixed-point sums like the beauty's, so the layers do not depend on
/// the thread count. Polls `cancel` between rows.
pub fn render_strategies(
    world: &World,
    settings: &RenderSettings,
    kinds: &[AovKind],
    samples: u32,
    cancel: &AtomicBool,
) -> Result<Vec<Layer>, RenderError> {
    let strategies: Vec<Strategy> = kinds
        .iter()
        .filter_map(|k| match k {
            AovKind::Strategy(s) => Some(*s),
            _ => None,
        })
        .collect();
    if strategies.is_empty() {
        return Ok(Vec::new());
    }
    settings.validate()?;
    check(world, Integrator::Bdpt, settings)?;
    check_strategies(world, settings, kinds)?;
    let (w, h) = (settings.width, settings.height);
    let super::SplatSetup {
        camera,
        importance,
        path,
        win,
        scale,
    } = super::SplatSetup::new(world, settings)?;
    let (fw, fh) = (win.width(), win.height());
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h);
    let filter = FilterSampler::new(&settings.filter);
    let samples = samples.clamp(1, settings.spp);
    let mut slots = [[[None; 2]; STRATEGY_T]; STRATEGY_T];
    for (i, st) in strategies.iter().enumerate() {
        slots[st.s as usize][st.t as usize][usize::from(!st.weighted)] = Some(i);
    }
    let ctx = bdpt::Context {
        world,
        camera: &importance,
        set: &path,
        time: 0.0,
    };
    let run = || {
        let threads = rayon::current_num_threads().max(1);
        let next_row = AtomicUsize::new(0);
        let worker = |_| {
            let mut bufs: Vec<SplatBuffer> = strategies
                .iter()
                .map(|_| SplatBuffer::new(win.x0, win.y0, fw, fh, &settings.filter))
                .collect();
            let mut scratch = bdpt::Scratch::default();
            let mut stats = RayStats::default();
            loop {
                let fy = next_row.fetch_add(1, Ordering::Relaxed) as u32;
                if fy >= fh || cancel.load(Ordering::Relaxed) {
                    return bufs;
                }
                let y = fy + win.y0;
                for x in win.x0..win.x1 {
                    let key = sampler.pixel_key((x, y));
                    for s in 0..samples {
                        let mut stream = sampler.stream(key, s);
                        let (ray, weight) =
                            sample_camera_ray(world, &camera, &filter, &mut stream, x, y);
                        let posed = super::posed_importance(world, &importance, ray.time);
                        let mut sink = StrategyFilms {
                            slots: &slots,
                            bufs: &mut bufs,
                            pixel: (x, y),
                            scale,
                        };
                        // The beauty's own sums are not kept: its film is the render's.
                        bdpt::trace(
                            &super::at_time(&ctx, &posed, ray.time),
                            &ray,
                            weight,
                            &mut stream,
                            &mut scratch,
                            &mut stats,
                            scale,
                            &mut NoSplats,
                            &mut sink,
                        );
                    }
                }
            }
        };
        let per_worker: Vec<Vec<SplatBuffer>> = (0..threads).into_par_iter().map(worker).collect();
        per_worker
    };
    let per_worker = super::in_pool(settings.threads, "strategies", run)?;
    if cancel.load(Ordering::Relaxed) {
        return Err(RenderError::Cancelled);
    }
    // Exact integer sums: the workers' order does not matter.
    Ok(strategies
        .iter()
        .enumerate()
        .map(|(i, &st)| {
            let mut film = Film::new(fw, fh);
            for bufs in &per_worker {
                film.add_splats(&bufs[i]);
            }
            film.add_counts(samples);
            let data = film
                .to_image()
                .data
                .iter()
                .flat_map(|p| [p.x, p.y, p.z])
                .collect();
            Layer::new(AovKind::Strategy(st), fw, fh, data)
        })
        .collect())
}

/// A camera sample's ray: as the tiled driver draws it ([`super::camera_ray`]), and in a
/// motion-blurred frame with its time drawn after the lens numbers and the camera placed there
/// ([`super::moving_camera_ray`]), so BDPT's camera subpaths are the path tracer's.
#[inline]
fn sample_camera_ray(
    world: &World,
    camera: &crate::camera::Camera,
    filter: &FilterSampler,
    stream: &mut crate::sampling::SampleStream,
    x: u32,
    y: u32,
) -> (crate::geometry::Ray, f32) {
    if world.is_still() {
        super::camera_ray(camera, filter, stream, x, y)
    } else {
        super::moving_camera_ray(world, camera, filter, stream, x, y)
    }
}

/// Splats dropped: the strategy pass keeps only the strategies' own sums.
struct NoSplats;
impl lighttracer::Splat for NoSplats {
    #[inline]
    fn splat(&mut self, _: Vec2, _: Vec3) {}
}
