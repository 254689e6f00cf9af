//! The render driver: splits the image into tiles, renders them in parallel passes (so front ends
//! can show a progressive preview), accumulates the film and reports statistics. Every sample is a
//! pure function of (seed, pixel, sample index), and the film adds tiles in a fixed order, so the
//! image is bit-identical for any thread count.

use crate::film::{Film, FilmBlock, Image};
use crate::integrator::{IntegratorKind, PathSettings, RayStats, path, raycast, whitted};
use crate::math::Vec2;
use crate::sampling::{SampleStream, SamplerKind, SamplerSetup};
use crate::world::World;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

pub const MAX_DIMENSION: u32 = 16384;
pub const MAX_PIXELS: u64 = 1 << 27;
pub const MAX_SPP: u32 = 1 << 20;
pub const MAX_DEPTH: u32 = 1024;
pub const MAX_SECONDARY: u32 = 1024;
const TILE: u32 = 16;

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
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 512,
            height: 512,
            spp: 64,
            seed: 0,
            threads: None,
            sampler: SamplerKind::default(),
            integrator: IntegratorKind::default(),
            path: PathSettings::default(),
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
        Ok(())
    }
}

/// Receives progress from the driver. Called from the driver's thread only.
pub trait RenderObserver: Sync {
    /// After each pass: the film so far, samples per pixel done and planned.
    fn pass_done(&self, _film: &Film, _samples_done: u32, _spp: u32) {}
    /// After each tile (from worker threads): tiles done and total over the whole render.
    fn tile_done(&self, _done: u64, _total: u64) {}
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
    pub stats: RayStats,
    pub render_time: Duration,
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
    settings.validate()?;
    let range = start.samples.clone();
    if !(range.start < range.end && range.end <= settings.spp) {
        return Err(RenderError::InvalidSetting(format!(
            "sample range {}..{} must be non-empty and within 0..{} (the frame's samples per pixel)",
            range.start, range.end, settings.spp
        )));
    }
    if let Some((film, at)) = &start.resume {
        if (film.width, film.height) != (settings.width, settings.height) {
            return Err(RenderError::Resume(format!(
                "the checkpoint is {}x{}, the render {}x{}",
                film.width, film.height, settings.width, settings.height
            )));
        }
        if !(range.start <= *at && *at <= range.end) {
            return Err(RenderError::Resume(format!(
                "the checkpoint holds samples {}..{at}, outside the range {}..{}",
                range.start, range.start, range.end
            )));
        }
    }
    let run = || render_in_pool(world, settings, start, observer, cancel);
    match settings.threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(|e| RenderError::ThreadPool(n, e.to_string()))?
            .install(run),
        None => run(),
    }
}

fn render_in_pool(
    world: &World,
    settings: &RenderSettings,
    range_start: RangeStart,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<FilmRender, RenderError> {
    let start = Instant::now();
    let (w, h) = (settings.width, settings.height);
    let camera = crate::camera::Camera::new(&world.camera, w, h);
    let mut tiles = Vec::new();
    for y0 in (0..h).step_by(TILE as usize) {
        for x0 in (0..w).step_by(TILE as usize) {
            tiles.push((x0, y0, TILE.min(w - x0), TILE.min(h - y0)));
        }
    }
    let first = range_start.samples.start;
    let (mut film, from) = match range_start.resume {
        Some((film, at)) => (film, at),
        None => (Film::new(w, h), first),
    };
    // Passes over the samples still to do. The film's sums are exact (see `film`), so how the
    // samples are grouped into passes does not change the image.
    let passes: Vec<(u32, u32)> = pass_schedule(range_start.samples.end - from)
        .into_iter()
        .map(|(a, b)| (a + from, b + from))
        .collect();
    let total_tiles = (tiles.len() * passes.len()) as u64;
    let tiles_done = AtomicU64::new(0);
    let mut stats = RayStats::default();
    let mut done = from;
    let sampler = SamplerSetup::new(settings.sampler, settings.seed, settings.spp);
    for &(s0, s1) in &passes {
        let blocks: Vec<(FilmBlock, RayStats)> = tiles
            .par_iter()
            .map(|&(x0, y0, tw, th)| {
                let mut block = FilmBlock::new(x0, y0, tw, th);
                let mut st = RayStats::default();
                if cancel.load(Ordering::Relaxed) {
                    return (block, st);
                }
                for y in y0..y0 + th {
                    for x in x0..x0 + tw {
                        let pixel_key = sampler.pixel_key((x, y));
                        for s in s0..s1 {
                            let mut stream = sampler.stream(pixel_key, s);
                            let l =
                                sample_pixel(world, &camera, settings, &mut stream, x, y, &mut st);
                            block.add(x, y, l);
                        }
                    }
                }
                let done = tiles_done.fetch_add(1, Ordering::Relaxed) + 1;
                observer.tile_done(done, total_tiles);
                (block, st)
            })
            .collect();
        if cancel.load(Ordering::Relaxed) {
            // Tiles skipped after the flag was set make this pass incomplete: drop all of it.
            return Ok(FilmRender {
                film,
                start: first,
                done,
                cancelled: true,
                stats,
                render_time: start.elapsed(),
            });
        }
        for (b, st) in &blocks {
            film.add_block(b);
            stats += *st;
        }
        done = s1;
        observer.pass_done(&film, s1, settings.spp);
    }
    Ok(FilmRender {
        film,
        start: first,
        done,
        cancelled: false,
        stats,
        render_time: start.elapsed(),
    })
}

/// One camera sample of pixel (x, y): a uniformly jittered film position (a box filter over the
/// pixel, as the reference images use) and a lens position.
#[inline]
fn sample_pixel(
    world: &World,
    camera: &crate::camera::Camera,
    settings: &RenderSettings,
    stream: &mut SampleStream,
    x: u32,
    y: u32,
    stats: &mut RayStats,
) -> crate::math::Vec3 {
    let jitter = stream.next_2d();
    let lens = stream.next_2d();
    let film = Vec2::new(x as f32 + jitter.x, y as f32 + jitter.y);
    let ray = camera.generate_ray(film, lens);
    match settings.integrator {
        IntegratorKind::Path => path::radiance(world, &ray, stream, &settings.path, stats),
        IntegratorKind::Raycast { aov, shading } => {
            raycast::radiance(world, &ray, stream, aov, shading, stats)
        }
        IntegratorKind::Whitted { shading } => {
            whitted::radiance(world, &ray, stream, settings.path.max_depth, shading, stats)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
