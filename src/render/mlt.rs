//! Metropolis light transport over bidirectional path tracing, in primary sample space
//! (Kelemen et al. 2002; the mutations in [`crate::sampling::mlt`]) and multiplexed (Hachisuka
//! et al. 2014, "Multiplexed Metropolis Light Transport"): the state of a Markov chain is the
//! vector of uniform numbers one BDPT strategy (s, t) reads, and the strategy is itself chosen
//! by the state's first number, so the chain moves between strategies where one of them samples
//! a path better. pbrt-v4's `MLTIntegrator` is the specification read; the code is this
//! renderer's BDPT (`bdpt.rs`).
//!
//! * The target is the luminance of f(ū) = (number of strategies of the depth) · w_(s,t) ·
//!   C_(s,t)(ū): the MIS-weighted contribution of the chosen strategy over the probability of
//!   choosing it, so that summed over strategies it is BDPT's estimate. The depth is fixed per
//!   chain; every depth 0..=max_depth has its own chains, in proportion to its share of b.
//! * Bootstrap: `bootstrap_samples` independent states per depth (large steps) estimate the
//!   normalisation b = ∫ f* (the mean of their luminances times the number of depths) and make
//!   the distribution chain starts are drawn from, proportional to f*, which removes start-up
//!   bias (Veach 1997 §11.3.3).
//! * Expected-value splatting (Veach 1997 §11.3.2): each mutation splats the proposal with
//!   weight a and the current state with 1 − a, a the acceptance probability, both as f / f*.
//!   A pixel is then b / (mutations per pixel) times its splats: with `spp` the mutations per
//!   pixel, the film's sample count divides by it and each splat carries b.
//! * Reproducible: chain k's decisions come from its own generator, seeded by (seed, k), and
//!   bootstrap state i's numbers from one seeded by (seed, i); the chains splat into exact
//!   fixed-point buffers ([`crate::film::splat`]), so the image is the same for any number of
//!   threads. A chain is not split: a frame cannot be rendered in sample ranges or resumed.
//! * Previews: the chains run in batches, their depths interleaved, and after each batch the
//!   film so far, over the mutations per pixel done, goes to the observer (the web page's
//!   viewport; the image Ctrl-C writes) as a pass of the tiled driver does.

use crate::camera::Camera;
use crate::film::Film;
use crate::film::splat::SplatBuffer;
use crate::integrator::RayStats;
use crate::integrator::bdpt::{self, Context, MediaState, Scratch};
use crate::math::{Vec2, Vec3, luminance};
use crate::render::{Crop, FilmRender, RenderError, RenderObserver};
use crate::sampling::Distribution1D;
use crate::sampling::mlt::{MltSampler, MltSettings, UniformSource};
use crate::sampling::rng::{Pcg32, hash_words};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::time::Instant;

/// The primary-sample streams of a state: the camera subpath (and the strategy and film
/// point), the light subpath, and the connection's own numbers.
const CAMERA_STREAM: u32 = 0;
const LIGHT_STREAM: u32 = 1;
const CONNECTION_STREAM: u32 = 2;
const STREAMS: u32 = 3;

/// What evaluating a state needs besides its numbers.
struct Frame<'a> {
    ctx: Context<'a>,
    camera: &'a Camera,
    window: Crop,
    /// Where the film points of the t ≥ 2 strategies are drawn, uniformly: the window widened
    /// by the filter's reach (radius − ½ pixel per side), so that the window's edge pixels get
    /// the light their filter sees past the window as a path tracer's samples of them do
    /// (pbrt-v4 `MLTIntegrator` draws them over the film's `SampleBounds`): corner and size.
    film_min: Vec2,
    film_size: Vec2,
    /// Image pixels over the sampled film area: t = 1 strategies' importance is normalised over
    /// the whole image, the film points of the others are uniform over the sampled area.
    scale: f32,
    /// The sampled film area over the window's: the mutations are `spp` per window pixel, the
    /// states spread over the larger area.
    area_ratio: f64,
    max_depth: usize,
}

/// One state's value: f(ū) and the film point it lands on.
fn contribution(
    f: &Frame,
    u: &mut MltSampler,
    depth: usize,
    scratch: &mut Scratch,
    stats: &mut RayStats,
) -> (Vec3, Vec2) {
    let none = (Vec3::ZERO, Vec2::ZERO);
    u.start_stream(CAMERA_STREAM);
    // The strategy: depth + 2 of them make a path of `depth` bounces (s + t = depth + 2);
    // depth 0 has only the emitter seen from the camera (s = 0, t = 2), as (1, 1) is left out.
    let (s, t, strategies) = if depth == 0 {
        (0, 2, 1)
    } else {
        let n = depth + 2;
        let s = ((u.next_1d() * n as f32) as usize).min(n - 1);
        (s, n - s, n)
    };
    // Spectral mode: the state's wavelengths (one more number of its camera stream, none in RGB
    // mode) ride on a copy of the settings as in BDPT's `trace`; the contribution reaches the
    // film, and the target, as RGB through the CIE curves (pbrt-v4 `MLTIntegrator::L` samples
    // its wavelengths from the state and takes the luminance of the film's RGB).
    let spectral_set = f.ctx.set.for_sample(u);
    let spectral_ctx = spectral_set.as_ref().map(|set| f.ctx.with_set(set));
    let ctx = spectral_ctx.as_ref().unwrap_or(&f.ctx);
    let uf = u.next_2d();
    let film = Vec2::new(
        f.film_min.x + uf.x * f.film_size.x,
        f.film_min.y + uf.y * f.film_size.y,
    );
    let lens = u.next_2d();
    let mut ray = f.camera.generate_ray(film, lens);
    // Motion blur: the state's time is one more number of its camera stream (a still draws
    // none); the camera, both subpaths and the connection are at that moment.
    let world = ctx.world;
    let time = if world.is_still() { 0.0 } else { u.next_1d() };
    if let Some(m) = &world.camera_motion {
        let mut camera = f.camera.clone();
        camera.camera_to_world = m.at(time);
        ray = camera.generate_ray(film, lens);
    }
    let ray = ray.with_time(time);
    let posed = super::posed_importance(world, ctx.camera, time);
    let ctx = &super::at_time(ctx, &posed, time);
    let mut media = MediaState::new(ctx.world, u, ray.d);
    bdpt::camera_subpath(
        ctx,
        &ray,
        1.0,
        t - 1,
        u,
        stats,
        &mut scratch.camera,
        &mut media,
    );
    if scratch.camera.len() != t {
        return none;
    }
    u.start_stream(LIGHT_STREAM);
    scratch.light.clear();
    // s = 1 samples its own light point at the connection: no light subpath to make (a light
    // subpath that failed would otherwise zero a strategy that does not use it).
    if s >= 2 {
        bdpt::light_subpath(ctx, ray.o, u, stats, &mut scratch.light, &mut media, s - 1);
        if scratch.light.len() != s {
            return none;
        }
    }
    u.start_stream(CONNECTION_STREAM);
    let Some((l, raster)) = bdpt::connect_strategy(ctx, scratch, s, t, u, stats, &mut media) else {
        return none;
    };
    // A dispersive vertex kept the hero wavelength alone (as BDPT's `trace`).
    let l = if media.hero_only {
        Vec3::new(3.0 * l.x, 0.0, 0.0)
    } else {
        l
    };
    let l = ctx.set.to_film(l) * strategies as f32;
    if t == 1 {
        (l * f.scale, raster)
    } else {
        (l, film)
    }
}

/// The scalar target f* of a contribution: its luminance (negative values count as 0).
#[inline]
fn target(l: Vec3) -> f32 {
    let y = luminance(l);
    if y.is_finite() && y > 0.0 { y } else { 0.0 }
}

/// The generator of bootstrap state `i`'s numbers (and of the chain started from it, until the
/// chain takes its own).
fn bootstrap_rng(seed: u64, i: u64) -> Pcg32 {
    Pcg32::new(hash_words(&[seed, i, 0x6d6c_7462]), i)
}

fn sampler(rng: Pcg32, set: &MltSettings) -> MltSampler {
    MltSampler::new(rng, set.small_sigma(), set.large_step(), STREAMS)
}

/// The bootstrap states' target values (index i: depth i mod (max_depth + 1)).
fn bootstrap(
    f: &Frame,
    set: &MltSettings,
    seed: u64,
    stats: &Mutex<RayStats>,
    cancel: &AtomicBool,
) -> Vec<f32> {
    use rayon::prelude::*;
    let depths = f.max_depth + 1;
    let n = set.bootstrap() as usize * depths;
    (0..n)
        .into_par_iter()
        .map_init(
            || (Scratch::default(), RayStats::default()),
            |(scratch, st), i| {
                if cancel.load(Ordering::Relaxed) {
                    return 0.0;
                }
                let mut u = sampler(bootstrap_rng(seed, i as u64), set);
                let (l, _) = contribution(f, &mut u, i % depths, scratch, st);
                if i % 4096 == 0 {
                    // Counted in blocks: the stats are a report, not part of the image.
                    let mut g = stats.lock().unwrap_or_else(|e| e.into_inner());
                    *g += std::mem::take(st);
                }
                target(l)
            },
        )
        .collect()
}

/// One chain of the plan: its depth, its mutations and what each of its splats carries.
struct Chain {
    depth: usize,
    mutations: u64,
    /// b_d · (total mutations) / (the depth's mutations): b when the depth's share of the
    /// mutations is exactly its share b_d / b of the brightness.
    weight: f32,
}

/// Shares the `total` mutations and the `chains` out among the depths in proportion to their
/// brightness b_d (mean bootstrap target of the depth): each depth is its own integral, so its
/// chains never leave it, and drawing every chain's depth at random (pbrt-v4) would add the
/// binomial noise of the chain counts to each depth's brightness (the light seen directly, at
/// depth 0, is a few pixels of large value: with a few dozen chains its brightness would be
/// tens of per cent off). The splat weight makes each depth's estimate exact whatever the
/// rounding of its share.
fn plan(b_d: &[f64], total: u64, chains: u64) -> Vec<Chain> {
    let b: f64 = b_d.iter().sum();
    let mut out = Vec::new();
    for (depth, &bd) in b_d.iter().enumerate() {
        if !(bd > 0.0) {
            continue;
        }
        let share = bd / b;
        let n = ((total as f64 * share).round() as u64).max(1);
        let k = ((chains as f64 * share).round() as u64).clamp(1, n);
        let weight = (bd * total as f64 / n as f64) as f32;
        for c in 0..k {
            out.push(Chain {
                depth,
                mutations: (c + 1) * n / k - c * n / k,
                weight,
            });
        }
    }
    out
}

/// The order the chains of `plan` run in: the i-th of a depth's k chains at (i + ½) / k of the
/// way, so that any prefix of the order holds about the same share of every depth's chains.
fn interleaved(chains: &[Chain]) -> Vec<usize> {
    let mut keyed = Vec::with_capacity(chains.len());
    let mut i = 0;
    while i < chains.len() {
        let d = chains[i].depth;
        let k = chains[i..].iter().take_while(|c| c.depth == d).count();
        keyed.extend((0..k).map(|j| ((j as f64 + 0.5) / k as f64, i + j)));
        i += k;
    }
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    keyed.into_iter().map(|(_, c)| c).collect()
}

/// The batches of `n` chains between previews: 1, 1, 2, 4, … chains, at most an eighth of
/// them per batch (a batch waits for its slowest chain, so not many more batches than that).
fn batches(n: usize) -> Vec<(usize, usize)> {
    let cap = (n / 8).max(1);
    let (mut out, mut a, mut size) = (Vec::new(), 0, 1);
    while a < n {
        let z = (a + size).min(n);
        out.push((a, z));
        a = z;
        if out.len() > 1 {
            size = (size * 2).min(cap);
        }
    }
    out
}

/// Renders the frame with Metropolis light transport: `settings.spp` mutations per pixel of the
/// film window over all chains.
pub(crate) fn render(
    world: &crate::world::World,
    settings: &crate::render::RenderSettings,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    let t0 = Instant::now();
    let set = settings.mlt;
    set.validate().map_err(RenderError::InvalidSetting)?;
    with_frame(world, settings, |frame| {
        render_frame(frame, settings, t0, observer, cancel)
    })
}

/// MLT's normalisation b (the image's mean luminance over the film window as the bootstrap
/// estimates it, light landing outside the window included) and its relative standard error:
/// the bootstrap's noise, which no number of mutations removes (every pixel of the image is
/// scaled by b).
pub fn normalisation(
    world: &crate::world::World,
    settings: &crate::render::RenderSettings,
) -> Result<(f64, f64), RenderError> {
    let set = settings.mlt;
    set.validate().map_err(RenderError::InvalidSetting)?;
    with_frame(world, settings, |f| {
        let stats = Mutex::new(RayStats::default());
        let weights = bootstrap(f, &set, settings.seed, &stats, &AtomicBool::new(false));
        let depths = f.max_depth + 1;
        let n = set.bootstrap() as f64;
        let (mut b, mut var) = (0.0, 0.0);
        for d in 0..depths {
            let ws = weights.iter().skip(d).step_by(depths).map(|&w| w as f64);
            let (s, s2) = ws.fold((0.0, 0.0), |(s, s2), w| (s + w, s2 + w * w));
            let mean = s / n;
            b += mean;
            var += (s2 / n - mean * mean).max(0.0) / (n - 1.0).max(1.0);
        }
        let b = b * f.area_ratio;
        Ok((
            b,
            if b > 0.0 {
                var.sqrt() * f.area_ratio / b
            } else {
                0.0
            },
        ))
    })
}

/// Calls `body` with the frame of `settings`.
fn with_frame<T>(
    world: &crate::world::World,
    settings: &crate::render::RenderSettings,
    body: impl FnOnce(&Frame) -> Result<T, RenderError>,
) -> Result<T, RenderError> {
    let super::SplatSetup {
        camera,
        importance,
        path,
        win,
        scale: _,
    } = super::SplatSetup::new(world, settings)?;
    let [rx, ry] = settings.filter.radius;
    let margin = Vec2::new(rx - 0.5, ry - 0.5).max(Vec2::ZERO);
    let film_min = Vec2::new(win.x0 as f32 - margin.x, win.y0 as f32 - margin.y);
    let film_size = Vec2::new(
        (win.x1 - win.x0) as f32 + 2.0 * margin.x,
        (win.y1 - win.y0) as f32 + 2.0 * margin.y,
    );
    let area = film_size.x as f64 * film_size.y as f64;
    let image = settings.width as f64 * settings.height as f64;
    let frame = Frame {
        ctx: Context {
            world,
            camera: &importance,
            set: &path,
            time: 0.0,
        },
        camera: &camera,
        window: win,
        film_min,
        film_size,
        scale: (image / area) as f32,
        area_ratio: area / (win.width() as f64 * win.height() as f64),
        max_depth: path.max_depth as usize,
    };
    body(&frame)
}

fn render_frame(
    frame: &Frame,
    settings: &crate::render::RenderSettings,
    t0: Instant,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    let set = settings.mlt;
    let win = frame.window;
    let (fw, fh) = (win.x1 - win.x0, win.y1 - win.y0);
    let seed = settings.seed;
    let stats_boot = Mutex::new(RayStats::default());
    let weights = bootstrap(frame, &set, seed, &stats_boot, cancel);
    let depths = frame.max_depth + 1;
    let mut b_d = vec![0.0f64; depths];
    for (i, &w) in weights.iter().enumerate() {
        b_d[i % depths] += w as f64 / set.bootstrap() as f64;
    }
    for bd in &mut b_d {
        *bd *= frame.area_ratio;
    }
    let b: f64 = b_d.iter().sum();
    let mut stats = stats_boot.into_inner().unwrap_or_else(|e| e.into_inner());
    let mut film = Film::new(fw, fh);
    let spp = settings.spp;
    let finish = |film: Film, stats: RayStats, cancelled: bool| FilmRender {
        film,
        start: 0,
        done: if cancelled { 0 } else { spp },
        cancelled,
        stopped_early: false,
        stats,
        render_time: t0.elapsed(),
        aovs: None,
    };
    if cancel.load(Ordering::Relaxed) {
        return Ok(finish(film, stats, true));
    }
    if !(b > 0.0) {
        // Nothing reaches the camera: a black film of `spp` samples.
        film.add_counts(spp);
        observer.pass_done(&film, spp, spp);
        return Ok(finish(film, stats, false));
    }
    // Chain starts of each depth drawn by their target value (no start-up bias).
    let starts: Vec<Distribution1D> = (0..depths)
        .map(|d| {
            Distribution1D::new(
                &weights
                    .iter()
                    .skip(d)
                    .step_by(depths)
                    .copied()
                    .collect::<Vec<f32>>(),
            )
        })
        .collect();
    let total = spp as u64 * fw as u64 * fh as u64;
    let chains = plan(&b_d, total, set.chain_count() as u64);
    let n_chains = chains.len() as u64;
    let threads = rayon::current_num_threads().max(1);
    let buffers: Vec<Mutex<(SplatBuffer, RayStats, Scratch)>> = (0..threads)
        .map(|_| {
            Mutex::new((
                SplatBuffer::new(win.x0, win.y0, fw, fh, &settings.filter),
                RayStats::default(),
                Scratch::default(),
            ))
        })
        .collect();
    // The chains run in batches of growing size, in an order that interleaves the depths, so
    // that the chains done after each batch are a fair share of every depth's mutations: the
    // film so far, counted as the mutations per pixel done, is a preview of the image (pbrt-v4's
    // MLT writes such intermediate images too), for the web page and for Ctrl-C. The splats are
    // exact integer sums, so the batches leave the final film as it was.
    let order = interleaved(&chains);
    let chains_done = AtomicU64::new(0);
    let mut mutations_done = 0u64;
    let mut preview: Option<(Film, u32)> = None;
    let batches = batches(chains.len());
    for (q, &(a, z)) in batches.iter().enumerate() {
        let next = AtomicUsize::new(a);
        let worker = |k: usize| {
            let mut guard = buffers[k].lock().unwrap_or_else(|e| e.into_inner());
            let (buf, st, scratch) = &mut *guard;
            loop {
                let j = next.fetch_add(1, Ordering::Relaxed);
                if j >= z || cancel.load(Ordering::Relaxed) {
                    return;
                }
                let c = order[j];
                let run = Run {
                    frame,
                    set: &set,
                    seed,
                    depths,
                };
                run.chain(
                    c as u64,
                    &chains[c],
                    &starts[chains[c].depth],
                    scratch,
                    st,
                    buf,
                    cancel,
                );
                let n = chains_done.fetch_add(1, Ordering::Relaxed) + 1;
                crate::render::report_work(observer, n, n_chains, t0);
            }
        };
        rayon::scope(|sc| {
            for k in 0..threads {
                let worker = &worker;
                sc.spawn(move |_| worker(k));
            }
        });
        if cancel.load(Ordering::Relaxed) {
            // The chains of this batch are cut short: the last preview is what is kept.
            return Ok(match preview {
                Some((film, k)) => FilmRender {
                    done: k,
                    ..finish(film, stats, true)
                },
                None => finish(Film::new(fw, fh), stats, true),
            });
        }
        for buf in &buffers {
            let mut g = buf.lock().unwrap_or_else(|e| e.into_inner());
            film.add_splats(&g.0);
            g.0.clear();
            stats += std::mem::take(&mut g.1);
        }
        mutations_done += order[a..z]
            .iter()
            .map(|&c| chains[c].mutations)
            .sum::<u64>();
        if q + 1 < batches.len() {
            // The mutations per pixel done, rounded: the preview's brightness is off by at
            // most half a mutation per pixel in `k`.
            let t = total.max(1) as u128;
            let k = ((2 * spp as u128 * mutations_done as u128 + t) / (2 * t)) as u32;
            let k = k.max(1);
            let mut p = film.clone();
            p.add_counts(k);
            observer.pass_done(&p, k, spp);
            preview = Some((p, k));
        }
    }
    film.add_counts(spp);
    observer.pass_done(&film, spp, spp);
    Ok(finish(film, stats, false))
}

/// What every chain shares.
struct Run<'a> {
    frame: &'a Frame<'a>,
    set: &'a MltSettings,
    seed: u64,
    depths: usize,
}

impl Run<'_> {
    /// Runs chain `c` of the plan from a bootstrap state of its depth drawn by f* (`starts`,
    /// over that depth's states), splatting into `out` (pbrt-v4 `MLTIntegrator::Render`'s
    /// chain loop).
    #[allow(clippy::too_many_arguments)]
    fn chain(
        &self,
        c: u64,
        chain: &Chain,
        starts: &Distribution1D,
        scratch: &mut Scratch,
        stats: &mut RayStats,
        out: &mut SplatBuffer,
        cancel: &AtomicBool,
    ) {
        let (f, set, seed) = (self.frame, self.set, self.seed);
        let depth = chain.depth;
        let b = chain.weight;
        let mut rng = Pcg32::new(hash_words(&[seed, c, 0x6d6c_7463]), c);
        let (k, _) = starts.sample_discrete(rng.next_f32());
        let i = k * self.depths + depth;
        // The bootstrap state again (its numbers come from the same generator), then the
        // chain's own proposals: chains started from the same state must not make the same
        // proposals.
        let mut u = sampler(bootstrap_rng(seed, i as u64), set);
        let (mut l_cur, mut p_cur) = contribution(f, &mut u, depth, scratch, stats);
        let mut c_cur = target(l_cur);
        u.reseed(Pcg32::new(hash_words(&[seed, c, 0x6d6c_7464]), c));
        for m in 0..chain.mutations {
            if m % 4096 == 4095 && cancel.load(Ordering::Relaxed) {
                return;
            }
            u.start_iteration();
            let (l_new, p_new) = contribution(f, &mut u, depth, scratch, stats);
            let c_new = target(l_new);
            let accept = if c_cur > 0.0 {
                (c_new / c_cur).min(1.0)
            } else {
                1.0
            };
            if accept > 0.0 && c_new > 0.0 {
                out.splat(p_new, l_new * (accept * b / c_new));
            }
            if accept < 1.0 {
                out.splat(p_cur, l_cur * ((1.0 - accept) * b / c_cur));
            }
            if rng.next_f32() < accept {
                (l_cur, p_cur, c_cur) = (l_new, p_new, c_new);
                u.accept();
            } else {
                u.reject();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// After every batch, the chains run hold each depth's share of its chains to within one
    /// chain (so a preview has every depth's light in proportion), and every chain runs once.
    #[test]
    fn every_batch_ends_with_each_depths_share_of_its_chains() {
        let chains = plan(&[0.05, 0.6, 0.25, 0.1], 1 << 20, 1000);
        let order = interleaved(&chains);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..chains.len()).collect::<Vec<_>>());
        let per_depth =
            |cs: &[usize], d: usize| cs.iter().filter(|&&c| chains[c].depth == d).count();
        let all: Vec<usize> = (0..chains.len()).collect();
        let b = batches(chains.len());
        assert!(b.len() >= 8 && b.last().unwrap().1 == chains.len());
        for &(_, z) in &b {
            let f = z as f64 / chains.len() as f64;
            for d in 0..4 {
                let (got, want) = (
                    per_depth(&order[..z], d) as f64,
                    per_depth(&all, d) as f64 * f,
                );
                assert!(
                    (got - want).abs() <= 1.0,
                    "depth {d} after {z} chains: {got}, not {want}"
                );
            }
        }
    }
}
