//! Split and resumable renders: render a sample range of a frame into a partial film,
//! save checkpoints while rendering, resume from one. The film's sums are exact (see
//! [`crate::film`]), so a frame assembled from parts, or a render stopped and resumed any number of
//! times, is bit-identical to one uninterrupted run.

pub mod partial;

use crate::film::Film;
use crate::render::{FilmRender, RangeStart, RenderError, RenderObserver, RenderSettings};
use crate::world::{World, WorldOptions};
use partial::{Part, PartError, PartFile, PartHeader};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// What identifies the frame being rendered: the scene (by content) and the settings.
#[derive(Clone, Debug)]
pub struct FrameId {
    /// The scene as named on the command line (messages only).
    pub scene: String,
    /// [`crate::scene::digest::digest`] of the scene.
    pub digest: String,
    pub settings: RenderSettings,
    pub world: WorldOptions,
    /// The light sampler the built world uses (never `auto`: [`crate::light::LightSet::sampler_kind`]).
    pub light_sampler: crate::light::LightSamplerKind,
}

impl FrameId {
    pub fn header(&self, samples: [u32; 2], discarded: u64) -> PartHeader {
        PartHeader::new(
            &self.scene,
            &self.digest,
            &self.settings,
            &self.world,
            self.light_sampler,
            samples,
            discarded,
        )
    }
}

/// How a render is split and saved.
#[derive(Clone, Debug, Default)]
pub struct SplitOptions {
    /// Sample indices to render (default: the whole frame).
    pub samples: Option<std::ops::Range<u32>>,
    /// Save the film here during the render and when it is interrupted.
    pub checkpoint: Option<PathBuf>,
    /// At least this long between checkpoints (one is written after every pass if zero).
    pub checkpoint_interval: Duration,
    /// Continue from this checkpoint.
    pub resume: Option<PathBuf>,
    /// When the render is interrupted (Ctrl-C) without a checkpoint file, still write the
    /// outputs from the passes completed so far (the command line's choice; a cancelled web
    /// render writes nothing).
    pub write_on_interrupt: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum SplitError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Part(#[from] PartError),
    #[error("cannot resume from {path}: {message}")]
    Resume { path: PathBuf, message: String },
    /// A checkpoint could not be written mid-render, so the render stopped (rendering on
    /// without the safety net asked for could lose hours); `part` holds the passes completed,
    /// for the caller to save elsewhere.
    #[error("{error}")]
    Checkpoint { error: PartError, part: Box<Part> },
}

/// The result of [`render_split`].
pub struct SplitOutcome {
    pub render: FilmRender,
    /// Sample indices the film holds (from the range's start, including a resumed checkpoint).
    pub header: PartHeader,
    /// Where the last checkpoint went, if one was written.
    pub checkpoint_written: Option<PathBuf>,
}

/// Forwards progress and writes checkpoints after passes.
struct Checkpointing<'a> {
    inner: &'a dyn RenderObserver,
    frame: &'a FrameId,
    start: u32,
    path: Option<&'a Path>,
    interval: Duration,
    last: Mutex<Instant>,
    error: Mutex<Option<PartError>>,
    cancel: &'a AtomicBool,
}

impl RenderObserver for Checkpointing<'_> {
    fn pass_done(&self, film: &Film, done: u32, spp: u32) {
        self.inner.pass_done(film, done, spp);
        let Some(path) = self.path else { return };
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if last.elapsed() < self.interval {
            return;
        }
        if let Err(e) = write_part(self.frame, film, [self.start, done], path) {
            // Stop rather than render on without the safety net the user asked for.
            *self.error.lock().unwrap_or_else(|e| e.into_inner()) = Some(e);
            self.cancel.store(true, Ordering::Relaxed);
        }
        *last = Instant::now();
    }

    fn tile_done(&self, done: u64, total: u64) {
        self.inner.tile_done(done, total);
    }

    fn progress(&self, progress: &crate::render::Progress) {
        self.inner.progress(progress);
    }
}

fn write_part(
    frame: &FrameId,
    film: &Film,
    samples: [u32; 2],
    path: &Path,
) -> Result<(), PartError> {
    Part {
        header: frame.header(samples, film.discarded),
        // The film is cloned so the render can go on while this one is written.
        film: film.clone(),
    }
    .write(path)
}

/// Reads a checkpoint and checks that it is the start of this render's range of this frame.
pub fn load_checkpoint(
    path: &Path,
    frame: &FrameId,
    range: &std::ops::Range<u32>,
) -> Result<(Film, u32), SplitError> {
    // The header first: a checkpoint of another frame is refused before its pixels are read.
    let file = PartFile::open(path)?;
    let bad = |message: String| SplitError::Resume {
        path: path.to_path_buf(),
        message,
    };
    let want = frame.header([range.start, range.end], 0);
    if let Some(why) = want.mismatch(&file.header) {
        return Err(bad(format!("it is from another frame: {why}")));
    }
    let [a, b] = file.header.samples;
    if a != range.start || b > range.end {
        return Err(bad(format!(
            "it holds samples {a}..{b}, not the start of this render's range {}..{}",
            range.start, range.end
        )));
    }
    Ok((file.read()?.film, b))
}

/// Renders `opts.samples` (or the whole frame) of `frame`, resuming and checkpointing as asked.
/// When `cancel` is set (Ctrl-C), the passes done are saved to the checkpoint file (if any) and
/// the outcome says `cancelled`.
pub fn render_split(
    world: &World,
    frame: &FrameId,
    opts: &SplitOptions,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<SplitOutcome, SplitError> {
    render_split_aovs(world, frame, opts, false, observer, cancel)
}

/// [`render_split`], asking the render to record AOVs in its paths where it can
/// ([`crate::render::render_range_aovs`]; `render.aovs` is `None` where it could not).
pub fn render_split_aovs(
    world: &World,
    frame: &FrameId,
    opts: &SplitOptions,
    aovs: bool,
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<SplitOutcome, SplitError> {
    let s = &frame.settings;
    if s.integrator == crate::integrator::IntegratorKind::Mlt && opts.checkpoint.is_some() {
        // Its chains run over the whole frame and are not continued (render::light), so a
        // checkpoint could never be resumed; its previews still reach the observer.
        return Err(RenderError::InvalidSetting(
            "--checkpoint: Metropolis light transport cannot be resumed (its chains run over the \
             whole frame); Ctrl-C writes the image of the chains done so far"
                .into(),
        )
        .into());
    }
    let range = opts.samples.clone().unwrap_or(0..s.spp);
    let resume = match &opts.resume {
        Some(p) => Some(load_checkpoint(p, frame, &range)?),
        None => None,
    };
    // Resuming a finished render just returns its film.
    if let Some((film, at)) = &resume
        && *at == range.end
    {
        let header = frame.header([range.start, range.end], film.discarded);
        return Ok(SplitOutcome {
            render: FilmRender {
                film: film.clone(),
                start: range.start,
                done: range.end,
                cancelled: false,
                stopped_early: false,
                stats: Default::default(),
                render_time: Duration::ZERO,
                aovs: None,
            },
            header,
            checkpoint_written: None,
        });
    }
    let obs = Checkpointing {
        inner: observer,
        frame,
        start: range.start,
        path: opts.checkpoint.as_deref(),
        interval: opts.checkpoint_interval,
        last: Mutex::new(Instant::now()),
        error: Mutex::new(None),
        cancel,
    };
    let start = RangeStart {
        samples: range.clone(),
        resume,
    };
    let render = crate::render::render_range_aovs(world, s, start, aovs, &obs, cancel)?;
    if let Some(error) = obs.error.into_inner().unwrap_or_else(|e| e.into_inner()) {
        let header = frame.header([range.start, render.done], render.film.discarded);
        return Err(if render.done > range.start {
            SplitError::Checkpoint {
                error,
                part: Box::new(Part {
                    header,
                    film: render.film,
                }),
            }
        } else {
            error.into()
        });
    }
    let header = frame.header([range.start, render.done], render.film.discarded);
    let mut checkpoint_written = None;
    if let Some(path) = &opts.checkpoint
        && (render.cancelled || render.done == range.end)
        && render.done > range.start
    {
        write_part(frame, &render.film, [range.start, render.done], path)?;
        checkpoint_written = Some(path.clone());
    }
    Ok(SplitOutcome {
        render,
        header,
        checkpoint_written,
    })
}

/// Parses `A..B` (sample indices `A` to `B - 1`).
pub fn parse_range(s: &str) -> Result<std::ops::Range<u32>, String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("'{s}' is not a sample range: write A..B, e.g. 0..64"))?;
    let num = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}' is not a sample range: '{t}' is not a whole number"))
    };
    let (a, b) = (num(a)?, num(b)?);
    if a >= b {
        return Err(format!("sample range {a}..{b} is empty"));
    }
    Ok(a..b)
}
