//! The render driver: splits the image into tiles, renders them in parallel passes (so front ends
//! can show a progressive preview), accumulates the film and reports statistics. Every sample is a
//! pure function of (seed, pixel, sample index), and the film adds each pass's tiles in a fixed
//! order, pass after pass, so the image is bit-identical for any thread count. Passes are
//! pipelined: workers start the next pass's tiles while the current one's last tiles finish
//! (see `render_in_pool`).

use crate::film::aov::{AovKind, Layer};
use crate::film::filter::{Filter, FilterSampler};
use crate::film::{Film, FilmBlock, Image};
use crate::integrator::aov::{self, AovPath, PixelAovs};
use crate::integrator::guiding::{Guide, Guiding, Learner, Record};
use crate::integrator::wavefront::{self, Wavefront};
use crate::integrator::{Integrator, IntegratorKind, PathSettings, RayStats, path};
use crate::sampling::sampler::{Drawn, WAVE_LANES, WaveDraw};
use crate::sampling::{Numbers, SampleStream, SamplerKind, SamplerSetup};
use crate::world::World;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, RwLock};
use std::time::{Duration, Instant};

pub mod light;
pub mod mlt;
pub mod photon;

pub const MAX_DIMENSION: u32 = 16384;
pub const MAX_PIXELS: u64 = 1 << 27;
pub const MAX_SPP: u32 = 1 << 20;
pub const MAX_DEPTH: u32 = 1024;
pub const MAX_SECONDARY: u32 = 1024;
const TILE: u32 = 16;
/// The samples per pixel every front end starts from (the command line, the web page, the
/// library).
pub const DEFAULT_SPP: u32 = 64;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u64,
    /// Worker threads; `None` uses every core.
    pub threads: Option<usize>,
    pub sampler: SamplerKind,
    pub integrator: IntegratorKind,
    pub path: PathSettings,
    /// Pixel reconstruction filter, by filter importance sampling ([`crate::film::filter`]).
    pub filter: Filter,
    /// Adaptive sampling: a pixel stops once the relative standard error of its mean luminance is
    /// below this (judged after each pass from the passes before it; see [`adaptive_mask`]).
    pub noise_threshold: Option<f32>,
    /// Progressive rendering: stop at the end of the last pass that finishes within this many
    /// seconds (the first pass always completes).
    pub time_limit: Option<f64>,
    /// Render and write only this window of the image (pixel bounds, see [`Crop`]).
    pub crop: Option<Crop>,
    /// Sum each pixel's squared sample luminance too ([`FilmBlock::tracked`]), for the
    /// `variance` AOV ([`Film::variance`]). Adaptive sampling tracks it whatever this says
    /// ([`RenderSettings::tracks_variance`]). The image is the same either way.
    pub track_variance: bool,
    /// Count each pixel's samples whose camera ray hit geometry ([`Film::track_coverage`]), for
    /// the `alpha` AOV; a `--transparent` render counts them whatever this says
    /// ([`RenderSettings::counts_coverage`]). The image is the same either way.
    pub track_coverage: bool,
    /// Path guiding (docs/DESIGN.md, "Path guiding"): the surface and volumetric path tracers
    /// learn the incident radiance in the render's first samples of each pixel
    /// ([`guide_training_passes`], kept in the image) and sample directions from a BSDF– (or
    /// phase-function–) guide mixture. The expectation is unchanged; whether it pays:
    /// BENCHMARKS.md, "Path guiding".
    pub guiding: bool,
    /// The photon integrators' photons per iteration and initial radius (`--integrator sppm`;
    /// [`crate::integrator::sppm::PhotonSettings`]); the other integrators ignore them.
    pub photon: crate::integrator::sppm::PhotonSettings,
    /// Metropolis light transport's bootstrap, chains and mutation sizes (`--integrator mlt`;
    /// [`crate::sampling::mlt::MltSettings`]); the other integrators ignore them.
    pub mlt: crate::sampling::mlt::MltSettings,
}

/// A window of the image in pixels: columns `x0..x1`, rows `y0..y1` (pbrt's `pixelbounds`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crop {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl Crop {
    /// pbrt-v4's rule for a `cropwindow` of fractions [x0, x1] × [y0, y1] of a `width`×`height`
    /// image: pixel bounds `ceil(width·x0)..ceil(width·x1)`, likewise for y (pbrt-v4
    /// `FilmBaseParameters`), each fraction clamped to [0, 1]. The window may come out empty (a
    /// sliver narrower than a pixel): [`RenderSettings::validate`] refuses it then.
    pub fn from_fractions(f: [f32; 4], width: u32, height: u32) -> Crop {
        let px = |v: f32, n: u32| {
            let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
            // In f32, as pbrt computes it: 20 · 0.2f is exactly 4 there, 4.0000000596 in f64.
            ((n as f32 * v).ceil() as u32).min(n)
        };
        Crop {
            x0: px(f[0], width),
            x1: px(f[1], width),
            y0: px(f[2], height),
            y1: px(f[3], height),
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
}

/// Samples every pixel gets before adaptive sampling may stop it (the variance estimate of fewer
/// samples is too unreliable: a pixel whose first samples all miss a small light would stop dark).
pub const ADAPTIVE_MIN_SAMPLES: u32 = 16;
/// Largest frame a `--time-limit` render plans when not given a sample count.
pub const TIME_LIMIT_SPP: u32 = 1 << 16;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            spp: DEFAULT_SPP,
            seed: 0,
            threads: None,
            sampler: SamplerKind::default(),
            integrator: IntegratorKind::default(),
            path: PathSettings::default(),
            filter: Filter::default(),
            noise_threshold: None,
            time_limit: None,
            crop: None,
            track_variance: false,
            track_coverage: false,
            guiding: false,
            photon: Default::default(),
            mlt: Default::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid setting: {0}")]
    InvalidSetting(String),
    #[error("render cancelled")]
    Cancelled,
    #[error("could not start {0} worker threads: {1}")]
    ThreadPool(usize, String),
    #[error("cannot resume: {0}")]
    Resume(String),
}

impl RenderSettings {
    /// Refuses absurd values before any work starts (docs/DESIGN.md §7).
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |m: String| Err(RenderError::InvalidSetting(m));
        if self.width == 0
            || self.height == 0
            || self.width > MAX_DIMENSION
            || self.height > MAX_DIMENSION
        {
            return bad(format!(
                "resolution {}x{} is out of range (each side must be 1 to {MAX_DIMENSION})",
                self.width, self.height
            ));
        }
        if self.width as u64 * self.height as u64 > MAX_PIXELS {
            return bad(format!(
                "resolution {}x{} has more than {MAX_PIXELS} pixels",
                self.width, self.height
            ));
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            return bad(format!(
                "samples per pixel must be 1 to {MAX_SPP} (got {})",
                self.spp
            ));
        }
        if self.path.max_depth > MAX_DEPTH {
            return bad(format!(
                "max depth must be at most {MAX_DEPTH} (got {})",
                self.path.max_depth
            ));
        }
        if self.path.secondary == 0 || self.path.secondary > MAX_SECONDARY {
            return bad(format!(
                "secondary rays must be 1 to {MAX_SECONDARY} (got {})",
                self.path.secondary
            ));
        }
        let rr = self.path.rr_scale;
        if !(rr > 0.0 && rr <= 1000.0) {
            return bad(format!(
                "Russian roulette scale must be above 0 and at most 1000 (got {rr})"
            ));
        }
        if let Some(t) = self.threads
            && (t == 0 || t > 1024)
        {
            return bad(format!("threads must be 1 to 1024 (got {t})"));
        }
        self.filter
            .validate()
            .map_err(RenderError::InvalidSetting)?;
        if let Some(t) = self.noise_threshold
            && !(t > 0.0 && t <= 100.0)
        {
            return bad(format!(
                "noise threshold must be a relative error above 0 and at most 100 (got {t})"
            ));
        }
        if let Some(t) = self.time_limit
            && !(t > 0.0 && t <= 1e7)
        {
            return bad(format!(
                "time limit must be above 0 and at most 10000000 seconds (got {t})"
            ));
        }
        if let Some(c) = self.crop
            && !(c.x0 < c.x1 && c.y0 < c.y1 && c.x1 <= self.width && c.y1 <= self.height)
        {
            return bad(format!(
                "crop window columns {}..{}, rows {}..{} is empty or outside the {}x{} image",
                c.x0, c.x1, c.y0, c.y1, self.width, self.height
            ));
        }
        Ok(())
    }

    /// The film's size and its offset in the image: the crop window, else the whole image.
    pub fn film_window(&self) -> Crop {
        self.crop.unwrap_or(Crop {
            x0: 0,
            x1: self.width,
            y0: 0,
            y1: self.height,
        })
    }

    /// Whether passes may stop early (adaptive sampling or a time limit), which makes the film
    /// depend on more than its sample range: such renders cannot be split or resumed.
    pub fn progressive(&self) -> bool {
        self.noise_threshold.is_some() || self.time_limit.is_some()
    }

    /// Whether the film sums squared luminance ([`Film::variance`]): when asked for
    /// ([`RenderSettings::track_variance`], the `variance` AOV) or when adaptive sampling needs
    /// it to judge pixels.
    pub fn tracks_variance(&self) -> bool {
        self.track_variance || self.noise_threshold.is_some()
    }

    /// Whether the film counts coverage (the alpha channel): when asked for
    /// ([`RenderSettings::track_coverage`], the `alpha` AOV) or for a transparent film.
    pub fn counts_coverage(&self) -> bool {
        self.track_coverage || self.path.transparent
    }
}

/// Which pixels of `film` get the next pass: those with fewer than [`ADAPTIVE_MIN_SAMPLES`]
/// samples or a relative error ([`Film::relative_error`]) above `threshold`, and their 8
/// neighbours (so a noisy region's edge is not left behind by a lucky pixel). A function of the
/// film only, so of the passes already done: the image stays a function of seed and settings.
/// Returns the number of pixels left active.
pub fn adaptive_mask(
    film: &Film,
    threshold: f32,
    active: &mut [bool],
    scratch: &mut [bool],
) -> usize {
    let (w, h) = (film.width as usize, film.height as usize);
    let counts = film.counts();
    for i in 0..w * h {
        scratch[i] = counts[i] < ADAPTIVE_MIN_SAMPLES || film.relative_error(i) > threshold as f64;
    }
    let mut n = 0;
    for y in 0..h {
        for x in 0..w {
            let mut a = false;
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    a |= scratch[yy * w + xx];
                }
            }
            active[y * w + x] = a;
            n += a as usize;
        }
    }
    n
}

/// Receives progress from the driver.
pub trait RenderObserver: Sync {
    /// After each pass: the film so far, samples per pixel done and planned. Called once per
    /// complete pass, in pass order and never concurrently with itself, from the worker thread
    /// that finished the pass (the other workers go on with the next pass meanwhile); the film
    /// holds exactly the passes done. Setting the cancel flag here stops the render with this
    /// film: no later pass is added.
    fn pass_done(&self, _film: &Film, _samples_done: u32, _spp: u32) {}
    /// After each tile (from worker threads): the work done and the total over the whole render,
    /// in pixel samples (a tile of `n` pixels rendered for `k` samples adds `n·k`), so that
    /// `done / total` is the fraction of the render's work whatever the passes' sizes (they
    /// double: by tiles alone, the 3 first passes of 7 are 4 of 64 samples). The total shrinks
    /// when adaptive sampling stops pixels, and a time-limited render reports the larger of
    /// its work and its time fractions.
    fn tile_done(&self, _done: u64, _total: u64) {}
    /// After each tile, right after [`RenderObserver::tile_done`]: the same work fractions with
    /// the render's time so far and the time left as [`remaining_time`] estimates it (the one
    /// estimate the CLI's bar, the web page and the farm's parts show).
    fn progress(&self, _progress: &Progress) {}
}

/// How far a render is ([`RenderObserver::progress`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// Work done and planned, in pixel samples (see [`RenderObserver::tile_done`]).
    pub done: u64,
    pub total: u64,
    /// Time since the render stage started.
    pub elapsed: Duration,
    /// Time left ([`remaining_time`]); `None` until a tile is done.
    pub remaining: Option<Duration>,
}

impl Progress {
    /// `done / total`, in [0, 1].
    pub fn fraction(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            (self.done as f64 / self.total as f64).min(1.0)
        }
    }
}

/// What the ETA knows of the complete passes ([`remaining_time`]): the first one's and the
/// latest one's cumulative work (pixel samples) and the time it was in, how many are in and how
/// many are still to come, and the sums of a least-squares fit of the passes after the first.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub first: (u64, Duration),
    pub last: (u64, Duration),
    pub committed: usize,
    pub left: usize,
    pub fit: PassFit,
}

impl PassTimes {
    /// What the ETA knows once pass number `committed` (counting from 1), of `work` pixel
    /// samples, is in at `at` since the render started, with `left` passes to come; `before` is
    /// what it knew after the pass before (`None` for the first).
    pub fn after(
        before: Option<PassTimes>,
        work: u64,
        at: Duration,
        committed: usize,
        left: usize,
    ) -> PassTimes {
        let last = (before.map_or(0, |b| b.last.0) + work, at);
        let mut fit = before.map_or(PassFit::default(), |b| b.fit);
        if let Some(b) = before {
            fit.add(work as f64, at.saturating_sub(b.last.1).as_secs_f64());
        }
        PassTimes {
            first: before.map_or(last, |b| b.first),
            last,
            committed,
            left,
            fit,
        }
    }
}

/// Sums for the least-squares line `duration = c + r·work` through the passes after the first
/// (the first carries the render's one-time costs: cold caches, lazily built tables, the first
/// preview): counted as a cost of every pass, they skewed both terms of the line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PassFit {
    pub n: u32,
    pub sum_w: f64,
    pub sum_d: f64,
    pub sum_ww: f64,
    pub sum_wd: f64,
}

impl PassFit {
    /// Adds a pass of `work` pixel samples that took `secs`.
    pub fn add(&mut self, work: f64, secs: f64) {
        self.n += 1;
        self.sum_w += work;
        self.sum_d += secs;
        self.sum_ww += work * work;
        self.sum_wd += work * secs;
    }

    /// The fixed cost per pass and the cost per pixel sample, once two passes of different sizes
    /// are in and the line is not negative (timing noise): `None` otherwise.
    fn line(&self) -> Option<(f64, f64)> {
        let n = f64::from(self.n);
        let det = n * self.sum_ww - self.sum_w * self.sum_w;
        if self.n < 2 || det <= 1e-9 * self.sum_ww * n {
            return None;
        }
        let r = (n * self.sum_wd - self.sum_w * self.sum_d) / det;
        let c = (self.sum_d - r * self.sum_w) / n;
        (r > 0.0 && c >= 0.0).then_some((c, r))
    }
}

/// The time left in a render (docs/DESIGN.md §5, "Progress and ETA"). A pass costs a fixed
/// amount (tiles set up, the film committed, the preview) plus an amount per pixel sample; the
/// two are fitted to the complete passes after the first by least squares (the first passes are
/// 1, 1, 2 samples: their fixed cost is most of their time, so a rate per sample alone predicted
/// renders 70 % too long at a tenth), or solved from the first pass and the latest while fewer
/// than two others are in; the time left is the passes to come times the one plus the work left
/// times the other, less the time already spent on the pass in flight. Tiles of one pass can
/// differ in cost by orders of magnitude (sky against glass or fog) and are rendered top to
/// bottom: the fraction of a pass's tiles done says little about its time, while whole passes,
/// each covering the frame, cost in proportion to their samples. Before two passes of different
/// sizes are in, the work fraction is all there is.
pub fn remaining_time(
    done: u64,
    total: u64,
    elapsed: Duration,
    passes: Option<PassTimes>,
) -> Option<Duration> {
    let left = total.saturating_sub(done);
    if left == 0 {
        return Some(Duration::ZERO);
    }
    let secs = match passes {
        Some(p) if p.last.0 > 0 => {
            let (w1, t1) = (p.first.0 as f64, p.first.1.as_secs_f64());
            let (wk, tk) = (p.last.0 as f64, p.last.1.as_secs_f64());
            let k = p.committed as f64;
            let det = wk - k * w1;
            // t1 = c + r·w1 and tk = k·c + r·wk; a solution that is not positive (timing noise)
            // falls back to a rate alone.
            let (mut c, mut r) = (0.0, tk / wk);
            if let Some(line) = p.fit.line() {
                (c, r) = line;
            } else if p.committed >= 2 && det.abs() > 1e-9 * wk {
                let rr = (tk - k * t1) / det;
                let cc = t1 - rr * w1;
                if rr > 0.0 && cc >= 0.0 {
                    (c, r) = (cc, rr);
                }
            }
            let in_flight = elapsed.saturating_sub(p.last.1).as_secs_f64();
            (p.left as f64 * c + total.saturating_sub(p.last.0) as f64 * r - in_flight).max(0.0)
        }
        _ if done > 0 => elapsed.as_secs_f64() * left as f64 / done as f64,
        _ => return None,
    };
    Some(Duration::from_secs_f64(secs))
}

/// Reports `done` of `total` units of work to `observer` ([`RenderObserver::tile_done`], then
/// [`RenderObserver::progress`] with the time left from the work fraction and the time since
/// `started`): for the drivers whose units (light-path passes, photon iterations) cost alike, so
/// that the fraction of them done is the fraction of the time.
pub fn report_work(observer: &dyn RenderObserver, done: u64, total: u64, started: Instant) {
    observer.tile_done(done, total);
    let elapsed = started.elapsed();
    observer.progress(&Progress {
        done,
        total,
        elapsed,
        remaining: remaining_time(done, total, elapsed, None),
    });
}

/// What the splatting drivers (the light tracer and BDPT, VCM, MLT) set up before tracing:
/// the camera and its importance W_e (on the film widened by the filter's reach,
/// [`crate::camera::CameraImportance::with_film_margin`]), the path settings with the camera's
/// footprint where textures or bumps need it, the film window, and W_e's scale from the whole
/// image to the window.
pub(crate) struct SplatSetup {
    pub camera: crate::camera::Camera,
    pub importance: crate::camera::CameraImportance,
    pub path: crate::integrator::PathSettings,
    pub win: crate::render::Crop,
    /// W_e integrates to 1 over the whole image; only the window's pixels start paths.
    pub scale: f32,
}

impl SplatSetup {
    pub(crate) fn new(world: &World, settings: &RenderSettings) -> Result<SplatSetup, RenderError> {
        let (w, h) = (settings.width, settings.height);
        let camera = crate::camera::Camera::new(&world.camera, w, h);
        // Light paths may land as far past the image as a camera sample of an edge pixel does.
        let [rx, ry] = settings.filter.radius;
        let importance = camera
            .importance()
            .map_err(|e| RenderError::InvalidSetting(e.to_string()))?
            .with_film_margin(crate::math::Vec2::new(rx - 0.5, ry - 0.5));
        let mut path = settings.path;
        if world.needs_footprint() {
            path.footprint = camera.footprint();
        }
        let win = settings.film_window();
        let scale = ((w as f64 * h as f64) / (win.width() as f64 * win.height() as f64)) as f32;
        Ok(SplatSetup {
            camera,
            importance,
            path,
            win,
            scale,
        })
    }
}

/// An observer that ignores everything.
pub struct NoObserver;
impl RenderObserver for NoObserver {}

#[derive(Clone, Debug)]
pub struct RenderOutput {
    pub image: Image,
    pub stats: RayStats,
    pub discarded_samples: u64,
    pub render_time: Duration,
}

impl RenderOutput {
    pub fn rays_per_second(&self) -> f64 {
        (self.stats.rays + self.stats.shadow_rays) as f64 / self.render_time.as_secs_f64().max(1e-9)
    }
}

/// The film of a render of a sample range, possibly stopped early.
#[derive(Clone, Debug)]
pub struct FilmRender {
    pub film: Film,
    /// Sample indices `start..done` of every pixel are in the film. When the render was
    /// cancelled, `done` is the end of the last complete pass (a cancelled pass adds nothing).
    pub start: u32,
    pub done: u32,
    pub cancelled: bool,
    /// Adaptive sampling found every pixel clean, or the time limit ended the render, before
    /// the last planned pass (pixels may then hold fewer samples than `done`).
    pub stopped_early: bool,
    pub stats: RayStats,
    pub render_time: Duration,
    /// The AOV accumulators of the film window's pixels (row-major), filled in the path loop
    /// when [`render_range_aovs`] was asked for them and could (see there); `None` otherwise.
    pub aovs: Option<Vec<PixelAovs>>,
}

/// Where a render of sample indices `samples` (of a `settings.spp` frame) starts: from nothing, or
/// from a film that holds `samples.start..resume_at` (a checkpoint).
pub struct RangeStart {
    pub samples: std::ops::Range<u32>,
    pub resume: Option<(Film, u32)>,
}

/// The sample-index ranges of the progressive passes: 1, 1, 2, 4, … samples, at most 64 per pass.
/// Depends only on `spp`, which keeps the accumulation order (and so the image) fixed.
pub fn pass_schedule(spp: u32) -> Vec<(u32, u32)> {
    let mut passes = Vec::new();
    let mut start = 0;
    let mut size = 1;
    while start < spp {
        let end = (start + size).min(spp);
        passes.push((start, end));
        start = end;
        if passes.len() > 1 {
            size = (size * 2).min(64);
        }
    }
    passes
}

/// The training iterations of a guided render of `pixels` film pixels, as sample ranges of
/// every pixel's own sample stream: the render's first samples, 1, 2, 4, … per pixel. Iteration
/// k samples with the guide learned from the iterations before it; every sample enters the
/// image with the same weight, so the image is the mean of `spp` unbiased samples.
///
/// Each iteration's tree is refined from the last (Müller et al. 2017 §3.4), so the guide grows
/// finer with every doubling for as long as each iteration brings more records than the one
/// before. The iterations go on until the first whose records fill the budget of one
/// ([`GUIDE_RECORD_BUDGET`]: an iteration after it, recording a fraction of its samples, would
/// learn from no more records, so its guide would be no better, and a training sample costs
/// more than another), but at least [`GUIDE_TRAINING_MIN_ITERATIONS`] of them, and at most a
/// quarter of `spp` in all (the last iteration then takes the rest). A `--time-limit` render,
/// whose sample count is not known in advance, also ends its training by time
/// ([`GUIDE_TRAINING_TIME_SHARE`]). Measured: BENCHMARKS.md, "Path guiding".
/// `TRAYECTO_GUIDING_TRAIN=n` trains on exactly n samples per pixel instead (a benchmarking
/// knob; 0: no training, no guide).
pub fn guide_training_passes(spp: u32, pixels: u64) -> Vec<(u32, u32)> {
    let knob = guide_training_knob();
    let per_pixel = knob.unwrap_or((spp / 4).max(1));
    // Doubling iterations; the last one takes the rest, so that the total is `per_pixel`,
    // unless the record budget ended them first.
    let mut passes: Vec<(u32, u32)> = Vec::new();
    let (mut s, mut n) = (0u32, 1u32);
    while s.saturating_add(n) <= per_pixel {
        passes.push((s, s + n));
        s += n;
        let full = pixels.saturating_mul(u64::from(n) * 4) >= GUIDE_RECORD_BUDGET;
        if knob.is_none() && full && passes.len() >= GUIDE_TRAINING_MIN_ITERATIONS {
            return passes;
        }
        n = n.saturating_mul(2);
    }
    match passes.last_mut() {
        Some(last) if s < per_pixel => last.1 = per_pixel,
        None if per_pixel > 0 => passes.push((0, per_pixel)),
        _ => {}
    }
    passes
}

/// Fewest training iterations (when a quarter of the samples allows): 1 + 2 + 4 + 8 samples
/// per pixel. A guide's structure comes from the iteration before it, so one iteration — which
/// a budget in camera samples alone gave frames of 2¹⁷ pixels or more — left a render a guide
/// of seven leaves whose quadtrees were their roots.
pub const GUIDE_TRAINING_MIN_ITERATIONS: usize = 4;

/// A guided `--time-limit` render trains while the next (doubled) iteration is predicted to
/// end within this share of the time limit, so its training ends between a sixth and a third
/// of it; the rest of the time samples with the last guide. The prediction is the last
/// iteration's time, rendering and learning, doubled. Measured against trainings of fixed
/// length at equal time (BENCHMARKS.md, "Path guiding").
pub const GUIDE_TRAINING_TIME_SHARE: f64 = 1.0 / 3.0;

/// [`GUIDE_TRAINING_TIME_SHARE`], unless `TRAYECTO_GUIDING_TRAIN_SHARE` sets another share of the
/// time limit (a benchmarking knob).
fn guide_training_time_share() -> f64 {
    static K: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *K.get_or_init(|| {
        std::env::var("TRAYECTO_GUIDING_TRAIN_SHARE")
            .ok()
            .and_then(|v| v.parse().ok())
            .filter(|f: &f64| *f > 0.0 && *f <= 1.0)
            .unwrap_or(GUIDE_TRAINING_TIME_SHARE)
    })
}

/// `TRAYECTO_GUIDING_TRAIN`: training samples per pixel instead of the budget (a benchmarking
/// knob).
fn guide_training_knob() -> Option<u32> {
    static K: std::sync::OnceLock<Option<u32>> = std::sync::OnceLock::new();
    *K.get_or_init(|| {
        std::env::var("TRAYECTO_GUIDING_TRAIN")
            .ok()
            .and_then(|v| v.parse().ok())
    })
}

/// Records a training pass keeps at most (52 bytes each; counted as four per camera sample): a
/// pass of more samples records every n-th sample of each pixel only.
pub const GUIDE_RECORD_BUDGET: u64 = 1 << 21;

/// Settings the volumetric path tracer cannot honour are refused rather than ignored: it has no
/// first-hit splitting (`secondary`; the first vertex may be in a medium), so a scene with media
/// and `secondary > 1` is an error that says what to use instead.
pub fn check_media_settings(world: &World, settings: &RenderSettings) -> Result<(), RenderError> {
    let integrator = Integrator::for_world(settings.integrator, world);
    match integrator {
        Integrator::Sppm => photon::check(world, settings)?,
        Integrator::Vcm => photon::check_vcm(world, settings)?,
        _ => {}
    }
    check_integrator_settings(integrator, settings)?;
    if integrator.capabilities().splats {
        light::check(world, integrator, settings)?;
    }
    Ok(())
}

/// Whether the integrator `settings` resolve to in `world` carries wavelengths
/// (docs/DESIGN.md "Spectral rendering"): the path tracers, the light tracer and BDPT (media
/// included), MLT on BDPT's paths, SPPM and VCM. The others refuse `--spectral`
/// ([`check_media_settings`]).
pub fn has_spectral_path(world: &World, settings: &RenderSettings) -> bool {
    // SPPM and VCM refuse media themselves (`photon::check`, `photon::check_vcm`).
    Integrator::for_world(settings.integrator, world).carries_wavelengths()
}

/// [`check_media_settings`] for the resolved integrator.
fn check_integrator_settings(
    integrator: Integrator,
    settings: &RenderSettings,
) -> Result<(), RenderError> {
    if integrator.capabilities().splats && settings.path.secondary > 1 {
        return Err(RenderError::InvalidSetting(format!(
            "secondary rays ({}) do not apply to the {}: its paths start at the lights",
            settings.path.secondary,
            integrator.name()
        )));
    }
    // Spectral transport is built into the path tracers (surface and volumetric), and the light
    // tracer, BDPT and MLT (media included), SPPM and VCM; the others (raycast,
    // Whitted) would silently render RGB (docs/DESIGN.md "Spectral rendering").
    if settings.path.spectral && !integrator.carries_wavelengths() {
        return Err(RenderError::InvalidSetting(format!(
            "spectral rendering is not available with the {} yet (the path tracers, the light \
             tracer, BDPT, MLT, SPPM and VCM carry wavelengths; this integrator's local shading \
             is RGB): render it with --rgb or use --integrator path",
            integrator.name()
        )));
    }
    if !integrator.capabilities().splitting && settings.path.secondary > 1 {
        return Err(RenderError::InvalidSetting(format!(
            "secondary rays ({}) are not supported in scenes with participating media or medium \
             interfaces (the volumetric path tracer renders them): use 1 and raise the samples \
             per pixel instead",
            settings.path.secondary
        )));
    }
    Ok(())
}

pub fn render(
    world: &World,
    settings: &RenderSettings,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<RenderOutput, RenderError> {
    let start = RangeStart {
        samples: 0..settings.spp,
        resume: None,
    };
    let r = render_range(world, settings, start, observer, cancel)?;
    if r.cancelled {
        return Err(RenderError::Cancelled);
    }
    Ok(RenderOutput {
        image: r.film.to_image(),
        stats: r.stats,
        discarded_samples: r.film.discarded,
        render_time: r.render_time,
    })
}

/// Renders sample indices `start.samples` of every pixel of a `settings.spp` frame (the sampler
/// is set up for the whole frame, so sample `i` is the same number whichever range it is rendered
/// in), continuing from `start.resume` if given. Cancelling returns the film of the passes done.
pub fn render_range(
    world: &World,
    settings: &RenderSettings,
    start: RangeStart,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    render_range_aovs(world, settings, start, false, observer, cancel)
}

/// Whether [`render_range_aovs`] records AOVs in the render's own paths for `settings` and
/// `start`: the surface path tracer (the volumetric one, raycast and Whitted keep the separate
/// pass of [`render_aovs_samples`]), from the first sample (a resumed film's earlier samples
/// have no AOVs).
pub fn aovs_in_loop(world: &World, settings: &RenderSettings, start: &RangeStart) -> bool {
    Integrator::for_world(settings.integrator, world)
        .capabilities()
        .in_loop_aovs
        && start.resume.is_none()
        && world.is_still()
}

/// [`render_range`]; with `aovs`, and when [`aovs_in_loop`] says the integrator can, the path
/// loop also records every sample's AOVs ([`path::radiance_aov`]) into
/// [`FilmRender::aovs`]: over exactly the samples in the film (a dropped pass's are dropped
/// too), each pixel's in sample order, so they do not depend on the thread count. The image is
/// bit-identical with and without them.
pub fn render_range_aovs(
    world: &World,
    settings: &RenderSettings,
    start: RangeStart,
    aovs: bool,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    settings.validate()?;
    // The one place the integrator is decided; everything below asks it what it can do.
    let integrator = Integrator::for_world(settings.integrator, world);
    match integrator {
        Integrator::Sppm => photon::check(world, settings)?,
        Integrator::Vcm => photon::check_vcm(world, settings)?,
        _ => {}
    }
    check_integrator_settings(integrator, settings)?;
    let range = start.samples.clone();
    if !(range.start < range.end && range.end <= settings.spp) {
        return Err(RenderError::InvalidSetting(format!(
            "sample range {}..{} must be non-empty and within 0..{} (the frame's samples per pixel)",
            range.start, range.end, settings.spp
        )));
    }
    if let Some((film, at)) = &start.resume {
        let win = settings.film_window();
        if (film.width, film.height) != (win.width(), win.height()) {
            return Err(RenderError::Resume(format!(
                "the checkpoint is {}x{}, the render {}x{}",
                film.width,
                film.height,
                win.width(),
                win.height()
            )));
        }
        if !(range.start <= *at && *at <= range.end) {
            return Err(RenderError::Resume(format!(
                "the checkpoint holds samples {}..{at}, outside the range {}..{}",
                range.start, range.start, range.end
            )));
        }
    }
    let aovs = aovs_in_loop(world, settings, &start) && aovs;
    let run = || {
        // Photon mapping's iterations share state between pixels: its own driver.
        match integrator {
            Integrator::Sppm => return photon::render(world, settings, start, observer, cancel),
            Integrator::Vcm => {
                return photon::render_vcm(world, settings, start, observer, cancel);
            }
            _ => {}
        }
        // Light paths splat anywhere on the film: their own driver (`render/light.rs`).
        if integrator.capabilities().splats {
            return light::render(world, integrator, settings, start, observer, cancel);
        }
        render_in_pool(world, integrator, settings, start, aovs, observer, cancel)
    };
    in_pool(settings.threads, "render", run)?
}

/// Runs `run` on a pool of `threads` workers named `name-0`, `name-1`, … (so profilers and
/// `bench/scaling.py`, which reads the render workers' scheduler statistics, can tell the
/// stages' workers apart), or on the global pool when `threads` is `None`.
pub(crate) fn in_pool<T: Send>(
    threads: Option<usize>,
    name: &'static str,
    run: impl FnOnce() -> T + Send,
) -> Result<T, RenderError> {
    match threads {
        Some(n) => Ok(rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .thread_name(move |i| format!("{name}-{i}"))
            .build()
            .map_err(|e| RenderError::ThreadPool(n, e.to_string()))?
            .install(run)),
        None => Ok(run()),
    }
}

/// A tile of the film: its corner and size, in film coordinates.
type TileRect = (u32, u32, u32, u32);
/// What a tile of a pass renders: its film block, ray counts, AOVs (in-loop AOVs only) and
/// guiding's training records (training passes only).
type Tile = (FilmBlock, RayStats, Vec<PixelAovs>, Vec<Record>);

fn render_in_pool(
    world: &World,
    integrator: Integrator,
    settings: &RenderSettings,
    range_start: RangeStart,
    record_aovs: bool,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    let start = Instant::now();
    let (w, h) = (settings.width, settings.height);
    let camera = crate::camera::Camera::new(&world.camera, w, h);
    // Filtered texture lookups and bump maps need this camera's pixel footprint at every hit.
    let filtered;
    let settings = if world.needs_footprint() {
        filtered = RenderSettings {
            path: crate::integrator::path::PathSettings {
                footprint: camera.footprint(),
                ..settings.path
            },
            ..settings.clone()
        };
        &filtered
    } else {
        settings
    };
    // The film covers the crop window (the whole image by default); tiles are in film
    // coordinates and samples in image coordinates, so a pixel is the same number whether or not
    // it is rendered as part of a crop.
    let win = settings.film_window();
    let (fw, fh) = (win.width(), win.height());
    let mut tiles = Vec::new();
    for y0 in (0..fh).step_by(TILE as usize) {
        for x0 in (0..fw).step_by(TILE as usize) {
            tiles.push((x0, y0, TILE.min(fw - x0), TILE.min(fh - y0)));
        }
    }
    let first = range_start.samples.start;
    let (film, from) = match range_start.resume {
        Some((film, at)) => (film, at),
        // `--transparent`: the film counts the samples whose camera ray hit geometry (alpha).
        None if settings.counts_coverage() => (Film::new(fw, fh).track_coverage(), first),
        None => (Film::new(fw, fh), first),
    };
    if settings.counts_coverage() != film.coverage().is_some() {
        return Err(RenderError::InvalidSetting(
            "the film resumed from has no coverage (alpha) but the render counts it \
             (--transparent, --aov alpha), or the other way round"
                .into(),
        ));
    }
    // Guiding: the surface and the volumetric path tracers are guided. The training
    // iterations are the first passes of every pixel's own samples (`guide_training_passes`);
    // each learns from the records of its samples and publishes the guide the next samples
    // use. A render of a sample range (or resumed) that does not own all of them still traces
    // them, to learn the same guide, and keeps only its own samples' radiance: the guide, and
    // so every sample, is the same whatever the range, the split or the thread count.
    let guided = settings.guiding && matches!(integrator, Integrator::Path | Integrator::VolPath);
    // A time-limited render does not know its sample count: its training ends by time
    // (`GUIDE_TRAINING_TIME_SHARE`), and the passes after it are planned once it has.
    let timed_training = guided && settings.time_limit.is_some();
    let end = range_start.samples.end;
    let mut passes: Vec<(u32, u32)> = Vec::new();
    // The samples of each pass that enter the film (empty: traced to learn only).
    let mut keep: Vec<(u32, u32)> = Vec::new();
    let mut trained_until = 0;
    // (A resumed film that already holds every sample needs no guide.)
    if guided && from < end {
        for (a, b) in guide_training_passes(settings.spp, fw as u64 * fh as u64) {
            if a >= end {
                break;
            }
            let b = b.min(end);
            passes.push((a, b));
            let lo = a.max(from);
            keep.push(if lo < b { (lo, b) } else { (b, b) });
            trained_until = b;
        }
    }
    let n_train = passes.len();
    // Passes over the samples still to do. The film's sums are exact (see `film`), so how the
    // samples are grouped into passes does not change the image.
    let rest = from.max(trained_until);
    if rest < end && !timed_training {
        for (a, b) in pass_schedule(end - rest) {
            passes.push((a + rest, b + rest));
            keep.push((a + rest, b + rest));
        }
    }
    // Adaptive sampling: which pixels the next pass renders (decided between passes).
    let adaptive = settings.noise_threshold.is_some();
    let pixels = (fw * fh) as usize;
    // In-loop AOVs: one accumulator per film pixel; each pass's tiles fill blocks of their own,
    // added once the pass is complete (like the film's blocks).
    let aov_film: Option<Vec<PixelAovs>> =
        record_aovs.then(|| vec![PixelAovs::default(); (fw * fh) as usize]);
    let (mut active, mut scratch) = if adaptive {
        (vec![true; pixels], vec![false; pixels])
    } else {
        (Vec::new(), Vec::new())
    };
    // A resumed film may already be clean everywhere: then no pass runs (unless training
    // passes are still to come: the adaptive mask is decided after them, as in the whole render).
    if let Some(t) = settings.noise_threshold
        && !passes.is_empty()
        && from >= trained_until
        && from >= ADAPTIVE_MIN_SAMPLES
        && adaptive_mask(&film, t, &mut active, &mut scratch) == 0
    {
        return Ok(FilmRender {
            film,
            start: first,
            done: from,
            cancelled: false,
            stopped_early: true,
            stats: RayStats::default(),
            render_time: start.elapsed(),
            aovs: aov_film,
        });
    }
    let learner = (n_train > 0).then(|| {
        let b = world.bounds;
        Learner::new(b.min, b.max)
    });
    let guide: RwLock<Option<Arc<Guide>>> = RwLock::new(None);
    let work = TileWork {
        world,
        integrator,
        settings,
        camera,
        filter: FilterSampler::new(&settings.filter),
        sampler: SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h),
        win,
        // Squared-luminance sums, for adaptive sampling and the variance AOV.
        track: settings.tracks_variance(),
        coverage: settings.counts_coverage(),
        record_aovs,
        guided: n_train > 0,
        // Training passes render every pixel, adaptive sampling or not.
        pixels: fw as u64 * fh as u64,
    };
    let deadline = settings
        .time_limit
        .map(|t| start + Duration::from_secs_f64(t));
    let schedule = PassSchedule {
        settings,
        passes: &passes,
        keep: &keep,
        tiles: &tiles,
        film_width: fw,
        deadline,
        n_train,
        guide: &guide,
        record_pixels: work.pixels,
        training_ends_by: settings
            .time_limit
            .filter(|_| timed_training)
            .map(|t| start + Duration::from_secs_f64(t * guide_training_time_share())),
    };
    let state = Commit {
        film,
        stats: RayStats::default(),
        aovs: aov_film,
        done: from,
        committed: 0,
        scratch,
        learner,
    };
    let mut c = schedule.run(
        state,
        active,
        observer,
        cancel,
        tile_job(&work, &guide, &keep, n_train),
    );
    let mut complete = c.committed == passes.len();
    // A time-limited guided render: the training above stopped by time (or ran its whole
    // chain); the rest of the time samples with the last guide.
    if timed_training
        && !cancel.load(Ordering::Relaxed)
        && deadline.is_some_and(|d| Instant::now() < d)
        && c.done < end
    {
        c.learner = None;
        c.committed = 0;
        let rest = c.done;
        let passes: Vec<(u32, u32)> = pass_schedule(end - rest)
            .into_iter()
            .map(|(a, b)| (a + rest, b + rest))
            .collect();
        let schedule = PassSchedule {
            passes: &passes,
            keep: &passes,
            n_train: 0,
            training_ends_by: None,
            ..schedule
        };
        let active = if adaptive {
            vec![true; pixels]
        } else {
            Vec::new()
        };
        c = schedule.run(
            c,
            active,
            observer,
            cancel,
            tile_job(&work, &guide, &passes, 0),
        );
        complete = c.committed == passes.len();
    }
    // An incomplete render with the flag set was cancelled (whichever check saw it first: a
    // worker before its tile or the commit before a pass), else it stopped early (time limit,
    // adaptive sampling's clean film).
    let cancelled = !complete && cancel.load(Ordering::Relaxed);
    if crate::integrator::guiding::diag_on() {
        let d = &crate::integrator::guiding::DIAG;
        eprintln!(
            "guiding diag: guide samples {} (f = 0: {}), record flux above/below the bin's normal {} / {}",
            d[0].load(Ordering::Relaxed),
            d[1].load(Ordering::Relaxed),
            d[2].load(Ordering::Relaxed),
            d[3].load(Ordering::Relaxed)
        );
    }
    Ok(FilmRender {
        film: c.film,
        start: first,
        done: c.done,
        cancelled,
        stopped_early: !complete && !cancelled,
        stats: c.stats,
        render_time: start.elapsed(),
        aovs: c.aovs,
    })
}

/// The per-tile work of a render: what one tile of one pass needs, shared read-only by the
/// workers of [`PassSchedule::run`].
struct TileWork<'a> {
    world: &'a World,
    integrator: Integrator,
    settings: &'a RenderSettings,
    camera: crate::camera::Camera,
    filter: FilterSampler,
    sampler: SamplerSetup,
    /// The film window in image coordinates.
    win: Crop,
    track: bool,
    /// Count coverage (`--transparent`): whether each sample's camera ray hits geometry.
    coverage: bool,
    record_aovs: bool,
    /// Guiding is on (the surface path tracer, at least one training pass).
    guided: bool,
    /// Film pixels (for the training passes' record stride), 0 with adaptive sampling, whose
    /// passes render fewer pixels: then every sample is recorded.
    pixels: u64,
}

impl TileWork<'_> {
    /// Samples `s0..s1` of every pixel of `tile` (those `mask` keeps, with adaptive sampling),
    /// of which those in `keep` enter the film (a guided training pass outside the render's
    /// range is traced for its records alone). With guiding, `guide` is the guide to sample
    /// with, and `train` says the pass records.
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        s0: u32,
        s1: u32,
        keep: (u32, u32),
        (x0, y0, tw, th): TileRect,
        mask: Option<&[bool]>,
        guide: Option<&Guide>,
        train: bool,
    ) -> Tile {
        let (world, settings, win) = (self.world, self.settings, self.win);
        let fw = win.width();
        let mut block = if self.track {
            FilmBlock::tracked(x0, y0, tw, th)
        } else {
            FilmBlock::new(x0, y0, tw, th)
        };
        if self.coverage {
            block = block.with_coverage();
        }
        let mut st = RayStats::default();
        let mut aov_block = Vec::new();
        if self.record_aovs {
            aov_block = vec![PixelAovs::default(); (tw * th) as usize];
        }
        // The surface path tracer's samples go through the batched first hits (`Batch`); the
        // other integrators trace sample by sample.
        // Motion blur traces each sample in the world of its time, sample by sample.
        let moving = !world.is_still();
        let batched = self.integrator.capabilities().batched_first_hits && !moving;
        // In-loop AOVs are only recorded by batching integrators (`aovs_in_loop`).
        debug_assert!(batched || !self.record_aovs);
        let mut batch = Batch::new(batched, wavefront::enabled());
        let mut records = Vec::new();
        // A training pass records every `stride`-th sample of each pixel, within the budget.
        let stride = (self.pixels * (s1 - s0) as u64 * 4)
            .div_ceil(GUIDE_RECORD_BUDGET)
            .max(1);
        let mut out = BatchOut {
            block: &mut block,
            stats: &mut st,
            aovs: self.record_aovs.then_some(&mut aov_block[..]),
            track: self.track,
            coverage: self.coverage,
            guiding: self.guided.then(|| Guiding {
                guide,
                records: train.then_some(&mut records),
                pending: Vec::new(),
            }),
        };
        for fy in y0..y0 + th {
            for fx in x0..x0 + tw {
                if let Some(m) = mask
                    && !m[(fy * fw + fx) as usize]
                {
                    continue;
                }
                let (x, y) = (fx + win.x0, fy + win.y0);
                let pixel_key = self.sampler.pixel_key((x, y));
                let slot = ((fy - y0) * tw + (fx - x0)) as usize;
                for s in s0..s1 {
                    let kept = keep.0 <= s && s < keep.1;
                    // Only a guided training pass traces samples it does not keep.
                    if !(kept || train && self.guided) {
                        continue;
                    }
                    if batched {
                        // The batch draws the camera numbers and rays of all its samples at
                        // once, when it is traced.
                        let p = batch.push(fx, fy, slot, self.sampler.stream(pixel_key, s));
                        p.pixel = (x, y);
                        p.record = train && records_sample(fx, fy, fw, s, stride);
                        p.keep = kept;
                        if batch.is_full() {
                            batch.trace(
                                world,
                                &self.camera,
                                &self.filter,
                                &settings.path,
                                &mut out,
                            );
                        }
                        continue;
                    }
                    let mut stream = self.sampler.stream(pixel_key, s);
                    // The camera ray the sample will draw, intersected on its own: these
                    // integrators do not report whether their first ray hit. A motion-blurred
                    // sample is judged at the shutter's opening.
                    let covered = kept && self.coverage && {
                        let (ray, _) =
                            camera_ray(&self.camera, &self.filter, &mut stream.clone(), x, y);
                        aov::covers(world, &ray)
                    };
                    if moving {
                        // Never recorded (moving scenes are not guided): kept samples only.
                        if kept {
                            let l = self.sample_moving(&mut stream, x, y, out.stats);
                            out.add(fx, fy, l, covered);
                        }
                        continue;
                    }
                    if self.integrator == Integrator::VolPath
                        && let Some(g) = out.guiding.as_mut()
                    {
                        let (ray, weight) =
                            camera_ray(&self.camera, &self.filter, &mut stream, x, y);
                        let record = train && records_sample(fx, fy, fw, s, stride);
                        let l = with_records(g, record, |g| {
                            crate::integrator::volpath::radiance_guided(
                                world,
                                &ray,
                                &mut stream,
                                &settings.path,
                                out.stats,
                                g,
                            )
                        });
                        if kept {
                            out.add(fx, fy, l * weight, covered);
                        }
                        continue;
                    }
                    if !kept {
                        continue;
                    }
                    let l = sample_pixel(
                        world,
                        self.integrator,
                        &self.camera,
                        &self.filter,
                        settings,
                        &mut stream,
                        x,
                        y,
                        out.stats,
                    );
                    out.add(fx, fy, l, covered);
                }
            }
        }
        batch.trace(world, &self.camera, &self.filter, &settings.path, &mut out);
        drop(out);
        (block, st, aov_block, records)
    }

    /// One motion-blurred camera sample: the film and lens numbers as [`camera_ray`] draws
    /// them, then the time (crate::world::motion): the fraction of the shutter that places a
    /// moving camera and picks the shutter step whose world the sample traces.
    fn sample_moving(
        &self,
        stream: &mut SampleStream,
        x: u32,
        y: u32,
        stats: &mut RayStats,
    ) -> crate::math::Vec3 {
        let (ray, weight) = moving_camera_ray(self.world, &self.camera, &self.filter, stream, x, y);
        let k = crate::world::motion::step_of(ray.time, self.world.time_steps());
        let l = self.integrator.radiance(
            self.world.at_step(k),
            &ray,
            stream,
            &self.settings.path,
            stats,
        );
        l * weight
    }
}

/// What the passes committed so far add up to.
struct Commit {
    film: Film,
    stats: RayStats,
    aovs: Option<Vec<PixelAovs>>,
    done: u32,
    committed: usize,
    scratch: Vec<bool>,
    /// Guiding's training state (while training passes remain).
    learner: Option<Learner>,
}

/// The work of one (pass, tile) job of a render whose passes keep `keep` and whose first
/// `n_train` passes train the guide: pass q samples with the guide of the training passes
/// before it (the schedule holds it back until they are committed). Training passes render
/// every pixel: the adaptive mask is decided after them.
fn tile_job<'a>(
    work: &'a TileWork<'a>,
    guide: &'a RwLock<Option<Arc<Guide>>>,
    keep: &'a [(u32, u32)],
    n_train: usize,
) -> impl Fn(usize, u32, u32, TileRect, Option<&[bool]>) -> Tile + Sync + 'a {
    move |q, s0, s1, tile, mask| {
        let g = work
            .guided
            .then(|| guide.read().unwrap_or_else(|e| e.into_inner()).clone())
            .flatten();
        let train = q < n_train;
        let mask = if train { None } else { mask };
        work.render(s0, s1, keep[q], tile, mask, g.as_deref(), train)
    }
}

/// The pass/tile scheduler: runs every (pass, tile) job on the pool's threads and commits the
/// passes in order, whatever renders a tile.
struct PassSchedule<'a> {
    settings: &'a RenderSettings,
    /// Sample ranges, in order.
    passes: &'a [(u32, u32)],
    /// The samples of each pass that enter the film: the whole pass, but for guided training
    /// passes outside the render's range (traced to learn the guide; empty when none).
    keep: &'a [(u32, u32)],
    tiles: &'a [TileRect],
    film_width: u32,
    deadline: Option<Instant>,
    /// Guiding: the first `n_train` passes train the guide, which the commit of each publishes
    /// in `guide` for the passes after it.
    n_train: usize,
    guide: &'a RwLock<Option<Arc<Guide>>>,
    /// [`TileWork::pixels`]: the training passes' record stride.
    record_pixels: u64,
    /// A time-limited guided render: the training stops after the iteration whose successor
    /// is predicted to end after this ([`GUIDE_TRAINING_TIME_SHARE`]). The samples after the
    /// training follow in a schedule of their own, so even the last pass here learns.
    training_ends_by: Option<Instant>,
}

impl PassSchedule<'_> {
    /// Renders the passes with `render_tile(pass, s0, s1, tile, mask)` from `state` on (`active`: the
    /// adaptive mask, empty without adaptive sampling) and returns what was committed.
    fn run<F>(
        &self,
        state: Commit,
        active: Vec<bool>,
        observer: &dyn RenderObserver,
        cancel: &AtomicBool,
        render_tile: F,
    ) -> Commit
    where
        F: Fn(usize, u32, u32, TileRect, Option<&[bool]>) -> Tile + Sync,
    {
        let (settings, passes, tiles, fw) =
            (self.settings, self.passes, self.tiles, self.film_width);
        let adaptive = settings.noise_threshold.is_some();
        // Progress in pixel samples (see `RenderObserver::tile_done`).
        let frame_pixels: u64 = tiles.iter().map(|t| u64::from(t.2) * u64::from(t.3)).sum();
        let samples_after =
            |p: usize| -> u64 { passes[p..].iter().map(|(a, b)| u64::from(b - a)).sum() };
        let work_done = AtomicU64::new(0);
        let work_total = AtomicU64::new(samples_after(0) * frame_pixels);
        let started = Instant::now();
        // The ETA's measurements: each pass's work, and the work of the committed passes with
        // the time the last of them was in (`remaining_time`).
        let pass_work: Vec<AtomicU64> = passes.iter().map(|_| AtomicU64::new(0)).collect();
        let committed_work = Mutex::new(None::<PassTimes>);

        // Pipelined passes. A barrier after every pass left all cores but one idle while
        // the pass's last tiles finished, and during the serial film update and `pass_done`. Instead
        // every worker takes (pass, tile) jobs from one counter in order, so it starts the next
        // pass's tiles while others finish the current one; the worker that completes a pass's last
        // tile commits it: its blocks go into the film in tile order, then `pass_done`. Passes are
        // committed strictly in order, so the film, the stats and the AOV sums (floats: their order
        // matters) see exactly the additions of the barrier version, and each `pass_done` sees the
        // film of complete passes only. Blocks of a finished but uncommitted pass wait in `slots`.
        //
        // A worker may run `lookahead` passes ahead of the oldest uncommitted one: 1 (which bounds
        // the blocks held to two passes' worth), 0 with adaptive sampling, whose next pass renders
        // the pixels chosen from the film of every pass before it (a barrier, as before).
        //
        // Guiding: a pass up to the first after the training passes waits for the commit of the
        // pass before it, which publishes the guide it samples with.
        let n_train = self.n_train;
        let lookahead_of = |q: usize| if adaptive || q <= n_train { 0 } else { 1 };
        let n_tiles = tiles.len();
        let ring = 2;
        let slots: Vec<Mutex<Option<Tile>>> =
            (0..n_tiles * ring).map(|_| Mutex::new(None)).collect();
        // Tiles still to render per pass.
        let left: Vec<AtomicUsize> = passes.iter().map(|_| AtomicUsize::new(n_tiles)).collect();
        let next_job = AtomicUsize::new(0);
        // Passes from this index on are neither rendered nor committed (cancel, time limit,
        // adaptive sampling found the film clean, a panic).
        let halt = AtomicUsize::new(passes.len());
        // Passes committed (mirrors `Commit::committed`, readable without the commit lock, which
        // is held during `pass_done`); `wake` tells waiting workers that it or `halt` changed.
        let committed = AtomicUsize::new(0);
        let wake = (Mutex::new(()), Condvar::new());
        let state = Mutex::new(state);
        let active = RwLock::new(active);
        let notify = || {
            let _g = lock(&wake.0);
            wake.1.notify_all();
        };
        let stop = |pass: usize| {
            halt.fetch_min(pass, Ordering::SeqCst);
            notify();
        };

        // Commits every complete pass at the head of the queue, in order.
        let commit = || {
            let mut c = lock(&state);
            loop {
                let p = c.committed;
                if p >= halt.load(Ordering::SeqCst) || left[p].load(Ordering::Acquire) != 0 {
                    break;
                }
                // A cancel (also one set by the previous `pass_done`) drops every pass not yet in.
                if cancel.load(Ordering::Relaxed) {
                    stop(p);
                    break;
                }
                let c = &mut *c;
                let train = p < n_train;
                let mut records = Vec::new();
                for slot in &slots[(p % ring) * n_tiles..][..n_tiles] {
                    let (b, st, ab, rec) =
                        lock(slot).take().expect("a complete pass has every tile");
                    if train {
                        // The tiles' records in tile order: the guide does not depend on which
                        // thread rendered what.
                        records.push(rec);
                    }
                    c.film.add_block(&b);
                    c.stats += st;
                    if let Some(af) = c.aovs.as_mut() {
                        for (k, px) in ab.iter().enumerate() {
                            let (fx, fy) = (b.x0 + k as u32 % b.w, b.y0 + k as u32 / b.w);
                            af[(fy * fw + fx) as usize].merge(px);
                        }
                    }
                }
                if train
                    && (p + 1 < passes.len() || self.training_ends_by.is_some())
                    && let Some(learner) = c.learner.as_mut()
                {
                    let (s0, s1) = passes[p];
                    // The spatial split threshold counts the samples the pass recorded.
                    let stride = (self.record_pixels * (s1 - s0) as u64 * 4)
                        .div_ceil(GUIDE_RECORD_BUDGET)
                        .max(1);
                    let spp = ((s1 - s0) as u64).div_ceil(stride) as u32;
                    let t0 = Instant::now();
                    learner.learn(records.iter().flatten(), spp);
                    *self.guide.write().unwrap_or_else(|e| e.into_inner()) = learner.guide();
                    if std::env::var_os("TRAYECTO_GUIDING_LOG").is_some() {
                        // Where the training time goes (`bench/guiding.py`): the pass ended
                        // at `t0` (render time so far), its learning took the rest.
                        eprintln!(
                            "guiding: training samples {s0}..{s1}: ended at {:.3} s, learning {:.3} s",
                            (t0 - started).as_secs_f64(),
                            t0.elapsed().as_secs_f64()
                        );
                    }
                    if p + 1 == n_train {
                        c.learner = None;
                    }
                    // By time: the next iteration, of `grow` times the samples, would take
                    // about `grow` times this one's rendering and learning (a training pass
                    // waits for the commit before it: it took the time since that commit).
                    if let Some(by) = self.training_ends_by
                        && let Some(&(n0, n1)) = passes.get(p + 1)
                    {
                        let now = started.elapsed();
                        let before = lock(&committed_work).map_or(Duration::ZERO, |t| t.last.1);
                        let grow = f64::from(n1 - n0) / f64::from((s1 - s0).max(1));
                        let took = now.saturating_sub(before);
                        if started + now + took.mul_f64(grow) > by {
                            halt.fetch_min(p + 1, Ordering::SeqCst);
                        }
                    }
                }
                drop(records);
                let kept = self.keep[p];
                let changed = kept.0 < kept.1;
                if changed {
                    c.done = kept.1;
                }
                {
                    let mut cw = lock(&committed_work);
                    *cw = Some(PassTimes::after(
                        *cw,
                        pass_work[p].load(Ordering::SeqCst),
                        started.elapsed(),
                        p + 1,
                        passes.len() - (p + 1),
                    ));
                }
                if changed {
                    observer.pass_done(&c.film, c.done, settings.spp);
                }
                c.committed = p + 1;
                // Training passes render every pixel: the mask is decided after them.
                if let Some(t) = settings.noise_threshold
                    && p + 1 < passes.len()
                    && p + 1 >= n_train
                    && c.done >= ADAPTIVE_MIN_SAMPLES
                {
                    let mut a = active.write().unwrap_or_else(|e| e.into_inner());
                    let left = adaptive_mask(&c.film, t, &mut a, &mut c.scratch);
                    if left == 0 {
                        halt.fetch_min(p + 1, Ordering::SeqCst);
                    }
                    // No tile of the next pass has started (lookahead 0): what is left is
                    // the remaining passes' samples of the pixels still active.
                    work_total.store(
                        work_done.load(Ordering::SeqCst) + samples_after(p + 1) * left as u64,
                        Ordering::SeqCst,
                    );
                }
                committed.store(p + 1, Ordering::SeqCst);
                notify();
            }
        };

        let n_workers = rayon::current_num_threads();
        let started_workers = AtomicUsize::new(0);
        let worker = || {
            started_workers.fetch_add(1, Ordering::SeqCst);
            // A panicking tile would leave its pass incomplete forever and the other workers
            // waiting for it: stop everything so the panic reaches the caller.
            let _unwind = OnUnwind(|| stop(0));
            loop {
                let j = next_job.fetch_add(1, Ordering::Relaxed);
                let (q, t) = (j / n_tiles, j % n_tiles);
                if q >= halt.load(Ordering::SeqCst) {
                    break;
                }
                let lookahead = lookahead_of(q);
                let waiting = || {
                    committed.load(Ordering::SeqCst) + lookahead < q
                        && q < halt.load(Ordering::SeqCst)
                };
                if waiting() {
                    // A pass waiting for a guide waits for the commit that learns it, whose
                    // learning runs in parallel on this pool (`Learner::learn`): meanwhile this
                    // worker takes the learning's jobs (once every worker has started, so that
                    // what it takes is never another worker's loop, which could wait on this
                    // one's tile), checking for the commit every millisecond.
                    while q <= n_train && waiting() {
                        let all = started_workers.load(Ordering::SeqCst) == n_workers;
                        if all && rayon::yield_now() == Some(rayon::Yield::Executed) {
                            continue;
                        }
                        let g = lock(&wake.0);
                        if waiting() {
                            drop(
                                wake.1
                                    .wait_timeout(g, Duration::from_millis(1))
                                    .unwrap_or_else(|e| e.into_inner()),
                            );
                        }
                    }
                    let mut g = lock(&wake.0);
                    while waiting() {
                        g = wake.1.wait(g).unwrap_or_else(|e| e.into_inner());
                    }
                    drop(g);
                    if q >= halt.load(Ordering::SeqCst) {
                        break;
                    }
                }
                if cancel.load(Ordering::Relaxed) {
                    stop(q);
                    break;
                }
                // The first pass always completes; later ones are abandoned whole when time runs
                // out (a pass with a tile skipped is never committed).
                if q > 0 && self.deadline.is_some_and(|d| Instant::now() >= d) {
                    stop(q);
                    break;
                }
                let (s0, s1) = passes[q];
                // Only adaptive renders take the lock; nothing writes it while a pass renders.
                let mask = adaptive.then(|| active.read().unwrap_or_else(|e| e.into_inner()));
                let tile = render_tile(q, s0, s1, tiles[t], mask.as_deref().map(|m| &m[..]));
                let (x0, y0, tw, th) = tiles[t];
                let pixels = match mask.as_deref() {
                    Some(m) => (y0..y0 + th)
                        .map(|y| {
                            let row = (y * fw) as usize;
                            m[row + x0 as usize..row + (x0 + tw) as usize]
                                .iter()
                                .filter(|a| **a)
                                .count() as u64
                        })
                        .sum(),
                    None => u64::from(tw) * u64::from(th),
                };
                drop(mask);
                *lock(&slots[(q % ring) * n_tiles + t]) = Some(tile);
                let units = pixels * u64::from(s1 - s0);
                pass_work[q].fetch_add(units, Ordering::SeqCst);
                let done = work_done.fetch_add(units, Ordering::SeqCst) + units;
                let total = work_total.load(Ordering::SeqCst).max(done);
                let elapsed = started.elapsed();
                let mut remaining = remaining_time(done, total, elapsed, *lock(&committed_work));
                // A time-limited render ends when its time is up, whatever work is left.
                let done = match settings.time_limit {
                    Some(limit) if limit > 0.0 => {
                        let by_time = elapsed.as_secs_f64() / limit;
                        let left =
                            Duration::from_secs_f64((limit - elapsed.as_secs_f64()).max(0.0));
                        remaining = Some(remaining.map_or(left, |r| r.min(left)));
                        done.max((by_time.min(1.0) * total as f64) as u64)
                    }
                    _ => done,
                };
                observer.tile_done(done, total);
                observer.progress(&Progress {
                    done,
                    total,
                    elapsed,
                    remaining,
                });
                if left[q].fetch_sub(1, Ordering::AcqRel) == 1 {
                    commit();
                }
            }
        };
        rayon::scope(|s| {
            for _ in 0..n_workers {
                s.spawn(|_| worker());
            }
        });
        state.into_inner().unwrap_or_else(|e| e.into_inner())
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Runs its closure when dropped during a panic.
struct OnUnwind<F: Fn()>(F);

impl<F: Fn()> Drop for OnUnwind<F> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            (self.0)()
        }
    }
}

/// The traced AOV layers among `kinds` ([`AovKind::is_traced`]; the film's own statistics come
/// from [`crate::film::aov::film_layers`]) of a film window `width` × `height` from the
/// accumulators [`render_range_aovs`] recorded.
pub fn aov_layers(kinds: &[AovKind], width: u32, height: u32, acc: &[PixelAovs]) -> Vec<Layer> {
    let kinds = &aov::traced(kinds)[..];
    let rows: Vec<Vec<f32>> = acc
        .chunks(width.max(1) as usize)
        .map(|row| {
            let mut out = Vec::new();
            for px in row {
                for &k in kinds {
                    px.push(k, &mut out);
                }
            }
            out
        })
        .collect();
    aov::layers(kinds, width, height, &rows)
}

/// The camera ray of one sample of pixel (x, y) and its filter weight: the stream's first two
/// numbers place the film position by the reconstruction filter (by default a uniform jitter over
/// the pixel, a box filter, as the reference images use; [`FilterSampler::film_point`]), the next
/// two place it on the lens. The AOV pass draws the same numbers, so it sees the same rays.
#[inline]
fn camera_ray<S: Numbers>(
    camera: &crate::camera::Camera,
    filter: &FilterSampler,
    stream: &mut S,
    x: u32,
    y: u32,
) -> (crate::geometry::Ray, f32) {
    let (film, lens, weight) = film_and_lens(camera, filter, stream, x, y);
    (camera.generate_ray(film, lens), weight)
}

/// [`camera_ray`]'s film point, lens point and filter weight, from the stream's first four
/// numbers.
#[inline]
fn film_and_lens<S: Numbers>(
    camera: &crate::camera::Camera,
    filter: &FilterSampler,
    stream: &mut S,
    x: u32,
    y: u32,
) -> (crate::math::Vec2, crate::math::Vec2, f32) {
    let jitter = stream.next_2d();
    // A pinhole camera ignores the lens numbers: skipping them keeps every later dimension where
    // it was (the image is bit-identical) without the cost of a 2D sample (callgrind, Cornell
    // box: a stratified 2D number is ~230 instructions, ~2 % of a sample).
    let lens = if camera.uses_lens() {
        stream.next_2d()
    } else {
        stream.skip(2);
        crate::math::Vec2::ZERO
    };
    let (film, weight) = filter.film_point(x, y, jitter);
    (film, lens, weight)
}

/// One motion-blurred camera sample of pixel (x, y): the film and lens numbers as
/// [`camera_ray`] draws them, then the time u ∈ [0, 1) (one more dimension; docs/DESIGN.md
/// "Motion blur"), the fraction of the shutter the sample sees. The camera is placed where
/// [`World::camera_motion`] has it at u, and the ray carries u ([`crate::geometry::Ray::time`]),
/// which every ray of its path inherits; the world to trace is [`World::at_step`] of the step
/// holding u.
pub(crate) fn moving_camera_ray(
    world: &World,
    camera: &crate::camera::Camera,
    filter: &FilterSampler,
    stream: &mut SampleStream,
    x: u32,
    y: u32,
) -> (crate::geometry::Ray, f32) {
    let (film, lens, weight) = film_and_lens(camera, filter, stream, x, y);
    let u = stream.next_1d();
    let ray = match &world.camera_motion {
        Some(m) => {
            let mut camera = camera.clone();
            camera.camera_to_world = m.at(u);
            camera.generate_ray(film, lens)
        }
        None => camera.generate_ray(film, lens),
    };
    (ray.with_time(u), weight)
}

/// The camera's importance at shutter time `time`: placed where [`World::camera_motion`] has
/// the camera then (pbrt-v4's `We`, `PDF_We` and `SampleWi` use the camera transform at the
/// ray's or the interaction's time), else unchanged.
#[inline]
pub(crate) fn posed_importance(
    world: &World,
    importance: &crate::camera::CameraImportance,
    time: f32,
) -> crate::camera::CameraImportance {
    match &world.camera_motion {
        Some(m) => importance.at(m.at(time)),
        None => *importance,
    }
}

/// A bidirectional sample's context at shutter time `time`: the world of the step holding it
/// ([`World::at_step`]; the one world when motion is continuous or there is none), the camera's
/// importance `posed` there, and the time both subpaths and every connection see. A still
/// (time 0, one step) gets a copy of `ctx`.
#[inline]
pub(crate) fn at_time<'a>(
    ctx: &crate::integrator::bdpt::Context<'a>,
    posed: &'a crate::camera::CameraImportance,
    time: f32,
) -> crate::integrator::bdpt::Context<'a> {
    crate::integrator::bdpt::Context {
        world: ctx
            .world
            .at_step(crate::world::motion::step_of(time, ctx.world.time_steps())),
        camera: posed,
        set: ctx.set,
        time,
    }
}

/// Traces the AOV layers `kinds` ([`crate::integrator::aov`]; only the traced ones,
/// [`AovKind::is_traced`]: samples and variance come from the film) over sample indices
/// `0..settings.spp` of every pixel of the film window (the crop, else the image), with the
/// camera rays of the beauty render's samples. See [`render_aovs_samples`].
pub fn render_aovs(
    world: &World,
    settings: &RenderSettings,
    kinds: &[AovKind],
    cancel: &AtomicBool,
) -> Result<Vec<Layer>, RenderError> {
    render_aovs_samples(world, settings, kinds, settings.spp, cancel)
}

/// [`render_aovs`] over sample indices `0..samples` only (a time-limited or adaptive render
/// traces its AOVs over the samples of its complete passes, not the planned frame). Each pixel
/// is accumulated by one thread in sample order, so the layers are the same for any thread count.
/// With a reconstruction filter the AOVs average their values at the filter's sample positions
/// without its weights (ids and normals must not be weighted; for the positive filters this is
/// the filtered value up to the sampler's table fit). Polls `cancel` between rows.
pub fn render_aovs_samples(
    world: &World,
    settings: &RenderSettings,
    kinds: &[AovKind],
    samples: u32,
    cancel: &AtomicBool,
) -> Result<Vec<Layer>, RenderError> {
    settings.validate()?;
    let kinds = &aov::traced(kinds)[..];
    let (w, h) = (settings.width, settings.height);
    let camera = crate::camera::Camera::new(&world.camera, w, h);
    // The beauty render's sampler, image size included (ZSobol's indices span it), so each AOV
    // sample replays its beauty sample's camera ray.
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp).for_image(w, h);
    let filter = FilterSampler::new(&settings.filter);
    let win = settings.film_window();
    let samples = samples.clamp(1, settings.spp);
    let run = || {
        (win.y0..win.y1)
            .into_par_iter()
            .map(|y| {
                let mut row = Vec::new();
                if cancel.load(Ordering::Relaxed) {
                    return row;
                }
                let mut acc = PixelAovs::default();
                for x in win.x0..win.x1 {
                    acc.clear();
                    let pixel_key = sampler.pixel_key((x, y));
                    for s in 0..samples {
                        let mut stream = sampler.stream(pixel_key, s);
                        let (ray, _) = camera_ray(&camera, &filter, &mut stream, x, y);
                        acc.add(&aov::trace(world, &ray, &mut stream));
                    }
                    for &k in kinds {
                        acc.push(k, &mut row);
                    }
                }
                row
            })
            .collect::<Vec<Vec<f32>>>()
    };
    let rows = in_pool(settings.threads, "aov", run)?;
    if cancel.load(Ordering::Relaxed) {
        return Err(RenderError::Cancelled);
    }
    Ok(aov::layers(kinds, win.width(), win.height(), &rows))
}

/// Camera samples whose first hits are found together, before any of their paths is shaded.
///
/// Why (the "wavefront" lever, measured: BENCHMARKS.md, "Tried, did not pay"): traced sample
/// by sample, every camera ray's traversal runs right after the previous path's shading, whose
/// code (tens of KB: the material evaluation, BSDF sampling, light sampling) has evicted the
/// traversal's from the instruction cache and retrained the branch predictor. A batch walks the
/// tree for `BATCH` coherent camera rays in a row, then runs each path from its precomputed
/// first hit. Everything a sample computes is unchanged: its stream is the one its camera ray
/// drew from, its path starts from the same `World::candidate` the path tracer would have found
/// ([`path::radiance_from`]), and the radiances reach the film (and the AOV block) in the
/// sample-by-sample order, so the image is bit-identical and the rays counted are the same.
const BATCH: usize = 64;

/// One camera sample of a [`Batch`]: its film pixel, image pixel and AOV slot, its stream (after
/// the camera numbers once the batch's rays are drawn), its ray and filter weight, and (once
/// traced) the ray's closest-hit candidate.
struct Primary {
    fx: u32,
    fy: u32,
    pixel: (u32, u32),
    slot: usize,
    stream: SampleStream,
    ray: crate::geometry::Ray,
    weight: f32,
    first: Option<crate::geometry::primitive::Intersection>,
    /// Guiding: this sample's path is recorded for training (in a training pass).
    record: bool,
    /// The sample enters the film (a guided training pass outside the render's range traces
    /// samples for their records alone).
    keep: bool,
}

/// The samples of one tile waiting for their camera rays and first hits, the wavefront path
/// loop's state (`integrator::wavefront`, when it runs the batch's paths) and the scratch in which
/// the batch's camera numbers are drawn across its samples; allocated once per tile job (never
/// per sample), empty when the integrator traces sample by sample.
struct Batch(Vec<Primary>, Option<Wavefront>, Box<WaveDraw>);

impl crate::integrator::wavefront::PathStart for Primary {
    #[inline]
    fn ray(&self) -> &crate::geometry::Ray {
        &self.ray
    }
    #[inline]
    fn first(&self) -> Option<crate::geometry::primitive::Intersection> {
        self.first
    }
    #[inline]
    fn stream(&mut self) -> &mut SampleStream {
        &mut self.stream
    }
}

/// Where a batch's radiances go: the tile's film block, its ray counts, its AOV block (when the
/// render records AOVs in the path loop).
struct BatchOut<'a> {
    block: &'a mut FilmBlock,
    stats: &'a mut RayStats,
    aovs: Option<&'a mut [PixelAovs]>,
    track: bool,
    /// Count the coverage of each sample's camera ray (`--transparent`).
    coverage: bool,
    /// Guided renders: the guide and the training records.
    guiding: Option<Guiding<'a>>,
}

impl BatchOut<'_> {
    #[inline]
    fn add(&mut self, fx: u32, fy: u32, l: crate::math::Vec3, covered: bool) {
        self.block.add_covered(fx, fy, l, self.track, covered);
    }
}

/// Whether a training pass records sample `s` of film pixel (`fx`, `fy`) (`fw` pixels a row):
/// every `stride`-th sample, counted along the film so that every pixel takes its turn.
#[inline]
fn records_sample(fx: u32, fy: u32, fw: u32, s: u32, stride: u64) -> bool {
    (fy as u64 * fw as u64 + fx as u64 + s as u64).is_multiple_of(stride)
}

/// Runs a guided sample's `trace` with `g`'s records hidden unless `record`: a sample left out
/// of training adds nothing to them.
#[inline]
fn with_records<T>(g: &mut Guiding, record: bool, trace: impl FnOnce(&mut Guiding) -> T) -> T {
    let held = if record { None } else { g.records.take() };
    let out = trace(g);
    if held.is_some() {
        g.records = held;
    }
    out
}

impl Batch {
    /// `wavefront`: run the paths' bounces in wavefront form where the settings allow it.
    fn new(batched: bool, wavefront: bool) -> Batch {
        Batch(
            Vec::with_capacity(if batched { BATCH } else { 0 }),
            (batched && wavefront).then(|| Wavefront::new(BATCH)),
            Box::default(),
        )
    }

    /// Appends a sample whose camera ray is still to be drawn from `stream`, and returns it.
    #[inline]
    fn push(&mut self, fx: u32, fy: u32, slot: usize, stream: SampleStream) -> &mut Primary {
        self.0.push(Primary {
            fx,
            fy,
            pixel: (0, 0),
            slot,
            stream,
            ray: crate::geometry::Ray::new(crate::math::Vec3::ZERO, crate::math::Vec3::Z),
            weight: 0.0,
            first: None,
            record: false,
            keep: true,
        });
        let last = self.0.len() - 1;
        &mut self.0[last]
    }

    #[inline]
    fn is_full(&self) -> bool {
        self.0.len() >= BATCH
    }

    /// Each sample's camera ray and filter weight ([`camera_ray`]), its film and lens numbers
    /// computed for up to [`WAVE_LANES`] samples at once where the sampler allows it
    /// ([`WaveDraw::run_camera`]; the same numbers as the streams draw one by one).
    fn camera_rays(&mut self, camera: &crate::camera::Camera, filter: &FilterSampler) {
        let Batch(samples, _, draw) = self;
        let drawn = samples.first().is_some_and(|p| WaveDraw::covers(&p.stream));
        for chunk in samples.chunks_mut(WAVE_LANES) {
            draw.begin();
            if drawn {
                for p in chunk.iter() {
                    draw.push(&p.stream);
                }
                draw.run_camera(camera.uses_lens());
            }
            for (k, p) in chunk.iter_mut().enumerate() {
                let (x, y) = p.pixel;
                let mut s = Drawn::new(&mut p.stream, draw, k);
                (p.ray, p.weight) = camera_ray(camera, filter, &mut s, x, y);
            }
        }
    }

    /// Draws every waiting sample's camera ray, finds its first hit, then runs their paths in
    /// order and adds them to `out`; leaves the batch empty.
    fn trace(
        &mut self,
        world: &World,
        camera: &crate::camera::Camera,
        filter: &FilterSampler,
        set: &PathSettings,
        out: &mut BatchOut,
    ) {
        self.camera_rays(camera, filter);
        for p in &mut self.0 {
            p.first = world.candidate(&p.ray);
        }
        // The wavefront loop covers unguided RGB paths without in-loop AOVs; its radiances are
        // bit for bit `path::radiance_from`'s, added to the film in the same order.
        if let Some(wf) = self.1.as_mut()
            && out.guiding.is_none()
            && out.aovs.is_none()
            && wavefront::supports(set)
        {
            wf.trace(world, set, &mut self.0, out.stats);
            for (i, p) in self.0.iter().enumerate() {
                if p.keep {
                    let covered = out.coverage && aov::covers(world, &p.ray);
                    out.add(p.fx, p.fy, wf.radiance(i) * p.weight, covered);
                }
            }
            self.0.clear();
            return;
        }
        for p in &mut self.0 {
            // The first hit found above may be a medium interface or a cut-out: coverage asks
            // for the first solid surface, as the alpha AOV always has.
            let covered = p.keep && out.coverage && aov::covers(world, &p.ray);
            if let Some(g) = out.guiding.as_mut() {
                let mut rec = (p.keep && out.aovs.is_some()).then(AovPath::new);
                let l = with_records(g, p.record, |g| {
                    path::radiance_guided_from(
                        world,
                        &p.ray,
                        p.first,
                        &mut p.stream,
                        set,
                        out.stats,
                        rec.as_mut(),
                        g,
                    )
                });
                if let (Some(aovs), Some(rec)) = (out.aovs.as_deref_mut(), rec) {
                    aovs[p.slot].add(&rec.sample);
                }
                if p.keep {
                    out.add(p.fx, p.fy, l * p.weight, covered);
                }
                continue;
            }
            let l = match out.aovs.as_deref_mut() {
                Some(aovs) => {
                    let mut rec = AovPath::new();
                    let l = path::radiance_aov_from(
                        world,
                        &p.ray,
                        p.first,
                        &mut p.stream,
                        set,
                        out.stats,
                        &mut rec,
                    );
                    aovs[p.slot].add(&rec.sample);
                    l
                }
                None => path::radiance_from(world, &p.ray, p.first, &mut p.stream, set, out.stats),
            };
            // As in `sample_pixel`: ×1 is exact for box and tent samples.
            out.add(p.fx, p.fy, l * p.weight, covered);
        }
        self.0.clear();
    }
}

/// One camera sample of pixel (x, y) (see [`camera_ray`]); the radiance is weighted by the
/// filter's `f/pdf` (1 for box and tent).
#[inline]
#[allow(clippy::too_many_arguments)]
fn sample_pixel(
    world: &World,
    integrator: Integrator,
    camera: &crate::camera::Camera,
    filter: &FilterSampler,
    settings: &RenderSettings,
    stream: &mut SampleStream,
    x: u32,
    y: u32,
    stats: &mut RayStats,
) -> crate::math::Vec3 {
    let (ray, weight) = camera_ray(camera, filter, stream, x, y);
    let l = integrator.radiance(world, &ray, stream, &settings.path, stats);
    // ×1 is exact: box and tent samples are unchanged.
    l * weight
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The time left from passes that cost `c + r·work` each, the first with a one-time cost on
    /// top (cold caches, tables built on first use): once passes 2 and 3 are in, the estimate
    /// is exact however large that one-time cost. Solved from the first pass and the latest,
    /// as before the fit, a one-time cost of 0.5 s made the time left 71 % too long here.
    #[test]
    fn the_time_left_ignores_the_first_pass_one_time_cost() {
        let (c, r, once) = (0.02, 1e-4, 0.5);
        let sizes = [1u64, 1, 2, 4, 8, 16, 32].map(|s| s * 1000);
        let total: u64 = sizes.iter().sum();
        let mut times = Vec::new();
        let mut t = once;
        for w in sizes {
            t += c + r * w as f64;
            times.push(t);
        }
        let mut state: Option<PassTimes> = None;
        for (k, (&w, &t)) in sizes.iter().zip(&times).enumerate().take(4) {
            let at = Duration::from_secs_f64(t);
            state = Some(PassTimes::after(state, w, at, k + 1, sizes.len() - (k + 1)));
        }
        let p = state.unwrap();
        let (done, now) = (p.last.0, p.last.1);
        let predicted = remaining_time(done, total, now, Some(p))
            .unwrap()
            .as_secs_f64();
        let truth = times.last().unwrap() - now.as_secs_f64();
        assert!(
            (predicted - truth).abs() < 1e-6 * truth,
            "predicted {predicted} s left, {truth} s were"
        );
    }

    /// Progress counts pixel samples, not tiles: when the passes holding the first 4 of 64
    /// samples are in (3 of 7 passes, 43 % of the tiles), at most the next pass's 4 samples can
    /// be on top (one pass of lookahead), so the fraction reported is at most 8/64. Adaptive
    /// sampling shrinks the total as pixels stop, and the last report is the whole.
    #[test]
    fn progress_is_the_fraction_of_pixel_samples_done() {
        struct Record(Mutex<Vec<(u64, u64)>>, Mutex<Vec<(u32, f64)>>);
        impl RenderObserver for Record {
            fn pass_done(&self, _film: &Film, done: u32, _spp: u32) {
                let last = lock(&self.0).last().copied().unwrap_or((0, 1));
                lock(&self.1).push((done, last.0 as f64 / last.1 as f64));
            }
            fn tile_done(&self, done: u64, total: u64) {
                lock(&self.0).push((done, total));
            }
        }
        let scene = crate::scene::builtin::load("cornell").unwrap();
        let world = World::build(scene, &Default::default()).unwrap();
        for noise_threshold in [None, Some(0.5)] {
            let settings = RenderSettings {
                width: 32,
                height: 32,
                spp: 64,
                threads: Some(2),
                noise_threshold,
                ..Default::default()
            };
            let rec = Record(Mutex::new(Vec::new()), Mutex::new(Vec::new()));
            render(&world, &settings, &rec, &AtomicBool::new(false)).unwrap();
            // (Adaptive: the total shrinks once pixels stop, after 16 samples.)
            for &(done, fraction) in lock(&rec.1).iter().filter(|p| p.0 <= 16) {
                assert!(
                    fraction <= (2 * done).min(64) as f64 / 64.0 + 1e-9,
                    "{noise_threshold:?}: {fraction} reported when pass {done} of 64 was in"
                );
            }
            let reports = lock(&rec.0);
            let &(done, total) = reports.iter().max().unwrap();
            assert_eq!(done, total, "{noise_threshold:?}: the render ends at 100 %");
            if noise_threshold.is_none() {
                assert_eq!(total, 32 * 32 * 64);
            } else {
                assert!(total < 32 * 32 * 64, "adaptive sampling stopped pixels");
            }
        }
    }

    /// The wavefront loop (`integrator::wavefront`) gives every sample of a batch the radiance
    /// `path::radiance_from` gives it, bit for bit, leaves each sample's stream where the scalar
    /// loop leaves it and counts the same rays: with the default settings, at depth 1, and with
    /// roulette from the first bounce; a batch of 37 samples (not a multiple of anything) from a
    /// camera that also sees past the box, so some camera rays miss.
    #[test]
    fn the_wavefront_loop_traces_each_sample_as_the_scalar_loop_does() {
        let scene = crate::scene::builtin::load("cornell").unwrap();
        let mut world = World::build(scene, &Default::default()).unwrap();
        // Widen the view so the box's open front and outside show.
        world.camera.vfov_deg = (world.camera.vfov_deg * 2.5).min(150.0);
        let (w, h) = (7u32, 6u32);
        let camera = crate::camera::Camera::new(&world.camera, w, h);
        let sampler = SamplerSetup::new(SamplerKind::default(), 3, 4).for_image(w, h);
        let filter = FilterSampler::new(&Filter::default());
        let base = PathSettings::default();
        let shallow = PathSettings {
            max_depth: 1,
            ..base
        };
        let roulette = PathSettings {
            rr_depth: 0,
            max_depth: 40,
            ..base
        };
        let mut wf = Wavefront::new(8);
        let mut misses = 0;
        for set in [base, shallow, roulette] {
            let mut batch = Vec::new();
            for k in 0..37u32 {
                let (x, y, s) = (k % w, (k / w) % h, k / (w * h));
                let mut stream = sampler.stream(sampler.pixel_key((x, y)), s);
                let (ray, weight) = camera_ray(&camera, &filter, &mut stream, x, y);
                let first = world.candidate(&ray);
                misses += first.is_none() as u32;
                batch.push(Primary {
                    fx: x,
                    fy: y,
                    pixel: (x, y),
                    slot: 0,
                    stream,
                    ray,
                    weight,
                    first,
                    record: false,
                    keep: true,
                });
            }
            let mut scalar_stats = RayStats::default();
            let scalar: Vec<_> = batch
                .iter()
                .map(|p| {
                    let mut s = p.stream.clone();
                    let l = path::radiance_from(
                        &world,
                        &p.ray,
                        p.first,
                        &mut s,
                        &set,
                        &mut scalar_stats,
                    );
                    (l, s.next_1d())
                })
                .collect();
            let mut stats = RayStats::default();
            wf.trace(&world, &set, &mut batch, &mut stats);
            for (i, (l, after)) in scalar.iter().enumerate() {
                let got = wf.radiance(i);
                assert_eq!(
                    got.to_array().map(f32::to_bits),
                    l.to_array().map(f32::to_bits),
                    "sample {i}: {got} against {l}"
                );
                assert_eq!(
                    batch[i].stream.next_1d().to_bits(),
                    after.to_bits(),
                    "sample {i}"
                );
            }
            assert_eq!(
                (stats.rays, stats.shadow_rays),
                (scalar_stats.rays, scalar_stats.shadow_rays)
            );
            assert!(stats.rays > 37 && stats.shadow_rays > 0);
        }
        assert!(
            misses > 0,
            "no camera ray missed: the escape path is untested"
        );
    }

    /// The batched first hits (`Batch`) render exactly what tracing each sample on its own does:
    /// every pixel's film value, the rays counted and the in-loop AOVs (float sums, so their
    /// order counts) equal a reference that traces sample by sample with `path::radiance_aov`.
    /// The image (21 × 18) is not a multiple of the tile, nor a tile-pass of the batch, so
    /// partial tiles and partial batches are both exercised; two threads run the passes.
    #[test]
    fn batched_first_hits_render_what_sample_by_sample_tracing_does() {
        // 6 spp: each stream draws its own camera numbers; 16 spp: the batch draws them for its
        // samples at once (`Batch::camera_rays`), with a pinhole and with a thin lens.
        for (spp, aperture) in [(6u32, 0.0f32), (16, 0.0), (16, 0.05)] {
            batched_first_hits_case(spp, aperture);
        }
    }

    fn batched_first_hits_case(spp: u32, aperture: f32) {
        let mut scene = crate::scene::builtin::load("cornell").unwrap();
        for c in &mut scene.cameras {
            c.aperture_radius = aperture;
        }
        let world = World::build(scene, &Default::default()).unwrap();
        let (w, h) = (21u32, 18u32);
        let settings = RenderSettings {
            width: w,
            height: h,
            spp,
            threads: Some(2),
            ..Default::default()
        };
        // Reference: sample by sample, each pixel's samples in order.
        let camera = crate::camera::Camera::new(&world.camera, w, h);
        assert_eq!(camera.uses_lens(), aperture > 0.0);
        let sampler = SamplerSetup::new(settings.sampler, settings.seed, spp).for_image(w, h);
        let filter = FilterSampler::new(&settings.filter);
        let mut block = FilmBlock::new(0, 0, w, h);
        let mut stats = RayStats::default();
        let mut aovs = vec![PixelAovs::default(); (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                for s in 0..spp {
                    let mut stream = sampler.stream(sampler.pixel_key((x, y)), s);
                    let (ray, weight) = camera_ray(&camera, &filter, &mut stream, x, y);
                    let mut rec = AovPath::new();
                    let l = path::radiance_aov(
                        &world,
                        &ray,
                        &mut stream,
                        &settings.path,
                        &mut stats,
                        &mut rec,
                    );
                    aovs[(y * w + x) as usize].add(&rec.sample);
                    block.add(x, y, l * weight);
                }
            }
        }
        let mut film = Film::new(w, h);
        film.add_block(&block);
        assert!(stats.rays > (w * h * spp) as u64 && stats.shadow_rays > 0);

        for record_aovs in [false, true] {
            let r = render_range_aovs(
                &world,
                &settings,
                RangeStart {
                    samples: 0..spp,
                    resume: None,
                },
                record_aovs,
                &NoObserver,
                &AtomicBool::new(false),
            )
            .unwrap();
            assert_eq!(r.done, spp);
            assert_eq!(
                (r.stats.rays, r.stats.shadow_rays),
                (stats.rays, stats.shadow_rays)
            );
            for y in 0..h {
                for x in 0..w {
                    let (a, b) = (r.film.pixel(x, y), film.pixel(x, y));
                    assert_eq!(
                        a.to_array().map(f32::to_bits),
                        b.to_array().map(f32::to_bits),
                        "pixel ({x}, {y}), aovs {record_aovs}: {a} against {b}"
                    );
                }
            }
            if record_aovs {
                let got = r.aovs.expect("the path tracer records AOVs in the loop");
                assert_eq!(format!("{got:?}"), format!("{aovs:?}"));
            }
        }
    }

    #[test]
    fn pass_schedule_covers_every_sample_once() {
        for spp in [1u32, 2, 3, 7, 64, 1000] {
            let p = pass_schedule(spp);
            assert_eq!(p.first().unwrap().0, 0);
            assert_eq!(p.last().unwrap().1, spp);
            for w in p.windows(2) {
                assert_eq!(w[0].1, w[1].0);
            }
            assert!(p.iter().all(|(a, b)| b > a && b - a <= 64));
        }
    }

    /// The stopping rule: a pixel with 16 identical samples is clean, one with noisy samples is
    /// not and keeps its 8 neighbours active; fewer than 16 samples keep a pixel active.
    #[test]
    fn adaptive_mask_stops_clean_pixels_and_keeps_noisy_neighbourhoods() {
        use crate::math::Vec3;
        let (w, h) = (5u32, 3u32);
        let mut film = Film::new(w, h);
        let mut b = FilmBlock::tracked(0, 0, w, h);
        for y in 0..h {
            for x in 0..w {
                for k in 0..16 {
                    let v = if (x, y) == (0, 1) {
                        // Noisy: relative error ≈ 1/√16 · 1 = 0.25.
                        if k % 2 == 0 { 0.0 } else { 2.0 }
                    } else {
                        0.5
                    };
                    b.add_tracked(x, y, Vec3::splat(v));
                }
            }
        }
        // One pixel has too few samples to judge.
        b.add_tracked(4, 2, Vec3::ONE);
        film.add_block(&b);
        let mut tail = FilmBlock::tracked(0, 0, w, h);
        tail.add_tracked(4, 0, Vec3::ONE);
        let mut few = Film::new(w, h);
        few.add_block(&tail);
        let n = |f: &Film| {
            let mut a = vec![false; 15];
            let mut s = vec![false; 15];
            let c = adaptive_mask(f, 0.1, &mut a, &mut s);
            (a, c)
        };
        let (a, count) = n(&film);
        let active = |x: usize, y: usize| a[y * 5 + x];
        assert!(
            (film.relative_error(5) - 0.258).abs() < 0.01,
            "{}",
            film.relative_error(5)
        );
        assert!(film.relative_error(2) < 1e-3);
        // The noisy pixel (0, 1) and its neighbours x ≤ 1 stay; x ≥ 2 stop.
        for y in 0..3 {
            assert!(active(0, y) && active(1, y));
            assert!(!active(2, y) && !active(3, y));
        }
        assert_eq!(count, 6);
        // A pixel with under 16 samples is active, with its neighbours.
        let (a, _) = n(&few);
        assert!(a[4] && a[3] && a[9] && a[8]);
    }

    #[test]
    fn absurd_settings_are_refused() {
        let ok = RenderSettings::default();
        assert!(ok.validate().is_ok());
        for s in [
            RenderSettings {
                width: 0,
                ..ok.clone()
            },
            RenderSettings {
                height: 1_000_000,
                ..ok.clone()
            },
            RenderSettings {
                width: 16384,
                height: 16384,
                ..ok.clone()
            },
            RenderSettings {
                spp: 0,
                ..ok.clone()
            },
            RenderSettings {
                threads: Some(0),
                ..ok.clone()
            },
        ] {
            assert!(s.validate().is_err(), "{s:?}");
        }
    }
}
