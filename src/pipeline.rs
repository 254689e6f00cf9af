//! The render pipeline every front end runs: load → build the world → render → write
//! (docs/DESIGN.md §2). The command line and the web server only fill in a [`RenderJob`], watch it
//! through a [`PipelineObserver`] and read the returned [`RenderReport`]; nothing of the flow is
//! written twice.
//!
//! The stages are separate functions on purpose, so that a feature extends exactly one of them:
//! - scene-provided defaults (a pbrt `Film`, a TOML `[render]` table) resolve in
//!   [`RenderJob::settings_for`], after loading and before anything is sized;
//! - a partial render of a sample range, checkpoints and resuming are [`RenderJob::split`]
//!   ([`crate::split`]); an output named `*.trp` is a partial film, written by [`write_outputs`];
//! - AOVs ([`RenderJob::aovs`]) are traced after the beauty render by
//!   [`crate::render::render_aovs`] and handed to [`write_outputs`] as [`Layer`]s with the beauty
//!   image (one multi-layer EXR, or side files); the layers read from the film (sample counts,
//!   variance: [`AovKind::FILM`], [`crate::film::aov::film_layers`]) join the same list in
//!   [`RenderJob::run`];
//! - denoising ([`RenderJob::denoise`], [`crate::denoise`]) is the [`Stage::Denoise`] between
//!   rendering and [`write_outputs`]; the library is loaded before anything else, so a missing
//!   one fails before the render;
//! - checkpoint/resume hooks into the observer's `pass_done`, which already sees the film.

use crate::denoise::{DenoiseError, DenoiseOptions, Oidn};
use crate::film::Image;
use crate::film::aov::{AovKind, Layer, side_path};
use crate::film::output::{Format, OutputError, write_image};
use crate::film::tonemap::Tonemap;
use crate::integrator::RayStats;
use crate::phases::PhaseReport;
use crate::render::{RenderError, RenderObserver, RenderSettings};
use crate::scene::{Scene, SceneError};
use crate::split::partial::{Part, PartError};
use crate::split::{FrameId, SplitError, SplitOptions};
use crate::world::{World, WorldOptions};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The image height when only the camera's aspect ratio is known.
pub const DEFAULT_HEIGHT: u32 = 512;

/// A derived side in pixels: rounded, at least 1 and at most [`crate::render::MAX_DIMENSION`]
/// (an extreme aspect ratio then shows as a disagreement with the camera, which is reported).
fn clamp_side(v: f64) -> u32 {
    if v.is_finite() {
        v.round().clamp(1.0, crate::render::MAX_DIMENSION as f64) as u32
    } else {
        1
    }
}

/// One image file to write from the rendered film.
#[derive(Clone, Debug)]
pub struct OutputSpec {
    /// The format follows the extension (.png, .ppm, .exr, .hdr).
    pub path: PathBuf,
    /// Linear multiplier applied before tone mapping (display formats only).
    pub exposure: f32,
    pub tonemap: Tonemap,
}

/// Everything a render needs: what to load, how to compile it, how to render it and where to
/// write it. New options are new fields here (with defaults), not new parameters.
#[derive(Clone, Debug)]
pub struct RenderJob {
    /// A scene file, or a built-in scene's name (see [`crate::scene::load`]).
    pub scene: String,
    pub world: WorldOptions,
    pub settings: RenderSettings,
    /// Which of `settings`' size, samples and depth the user gave; the others come from the
    /// scene file when it has them (pbrt's Film, Sampler, Integrator: [`crate::scene::RenderHints`]).
    pub given: GivenSettings,
    /// Outputs named `*.trp` get the partial film (the exact sums, to merge or resume).
    pub outputs: Vec<OutputSpec>,
    /// Render a sample range only, save checkpoints, resume (default: the whole frame, no files).
    pub split: SplitOptions,
    /// AOV layers to write with the image (`--aov`; empty: none). Not with partial films.
    pub aovs: Vec<AovKind>,
    /// `--denoise`: also write each image output denoised by Open Image Denoise, beside it
    /// (`out.denoised.exr`); the raw image is written as always. Not with partial films.
    pub denoise: Option<DenoiseOptions>,
    /// Render only a window of the image (else the scene file's `cropwindow`/`pixelbounds`, if
    /// any); resolved into [`RenderSettings::crop`] once the image size is known.
    pub crop: Option<CropSpec>,
}

/// A crop window as the user gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CropSpec {
    /// Fractions [x0, x1, y0, y1] of the image (pbrt's `cropwindow`).
    Fractions([f32; 4]),
    /// Pixel bounds [x0, x1, y0, y1], columns `x0..x1` and rows `y0..y1` (pbrt's `pixelbounds`).
    Pixels([u32; 4]),
}

impl CropSpec {
    /// The pixel window in a `width`×`height` image.
    pub fn resolve(self, width: u32, height: u32) -> crate::render::Crop {
        match self {
            CropSpec::Fractions(f) => crate::render::Crop::from_fractions(f, width, height),
            CropSpec::Pixels([x0, x1, y0, y1]) => crate::render::Crop { x0, x1, y0, y1 },
        }
    }

    /// Parses `x0,x1,y0,y1` (four numbers; fractions or pixel bounds as `pixels` says).
    pub fn parse(s: &str, pixels: bool) -> Result<CropSpec, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 4 {
            return Err(format!(
                "'{s}' is not a window: write x0,x1,y0,y1 (four numbers)"
            ));
        }
        if pixels {
            let mut v = [0u32; 4];
            for (o, p) in v.iter_mut().zip(&parts) {
                *o = p
                    .parse()
                    .map_err(|_| format!("'{p}' is not a pixel coordinate (a whole number)"))?;
            }
            if !(v[0] < v[1] && v[2] < v[3]) {
                return Err(format!(
                    "pixel bounds {s} are empty: x0 < x1 and y0 < y1 are needed"
                ));
            }
            Ok(CropSpec::Pixels(v))
        } else {
            let mut v = [0f32; 4];
            for (o, p) in v.iter_mut().zip(&parts) {
                *o = p
                    .parse::<f32>()
                    .ok()
                    .filter(|x| (0.0..=1.0).contains(x))
                    .ok_or_else(|| format!("'{p}' is not a fraction of the image (0 to 1)"))?;
            }
            if !(v[0] < v[1] && v[2] < v[3]) {
                return Err(format!(
                    "crop window {s} is empty: x0 < x1 and y0 < y1 are needed"
                ));
            }
            Ok(CropSpec::Fractions(v))
        }
    }
}

/// The camera `--camera-from FILE` names: a TOML file's `[camera]` (or first `[[camera]]`) table,
/// or the first camera of any other scene file (glTF, pbrt, FBX, …), loaded as a render loads it.
pub fn camera_from_file(
    path: &std::path::Path,
) -> Result<crate::camera::CameraSpec, PipelineError> {
    use crate::camera::CameraSpec;
    let bad =
        |m: String| PipelineError::InvalidSetting(format!("--camera-from {}: {m}", path.display()));
    let is_toml = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_toml {
        // A camera snippet is a few lines; a scene file is read only up to its camera table.
        let meta = std::fs::metadata(path).map_err(|e| bad(e.to_string()))?;
        if meta.len() > 16 << 20 {
            return Err(bad("larger than 16 MiB: not a camera file".into()));
        }
        let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
        return CameraSpec::from_toml(&text).map_err(bad);
    }
    let scene = crate::scene::load_file(path)?;
    let desc = scene
        .cameras
        .first()
        .ok_or_else(|| bad("the scene has no camera".into()))?;
    let spec = CameraSpec::from_desc(desc);
    spec.validate().map_err(bad)?;
    Ok(spec)
}

/// Whether `path` names a partial film (`.trp`) rather than an image.
pub fn is_partial_film(path: &std::path::Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("trp"))
}

/// Which render settings were given explicitly (and so win over the scene file's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GivenSettings {
    pub width: bool,
    pub height: bool,
    pub spp: bool,
    pub max_depth: bool,
    /// The reconstruction filter (else the scene file's, e.g. pbrt's `PixelFilter`).
    pub filter: bool,
    /// The integrator (else the scene file's, e.g. pbrt's `Integrator "lighttracer"`).
    pub integrator: bool,
    /// Spectral or RGB (`--spectral`/`--rgb`: `settings.path.spectral`); else the scene
    /// format's default ([`crate::scene::RenderHints::spectral`]: pbrt files spectral), RGB
    /// where the integrator has no spectral path ([`rgb_fallback`]).
    pub spectral: bool,
    /// Path guiding on or off (`--guiding`/`--no-guiding`: `settings.guiding`); else the scene
    /// file's ([`crate::scene::RenderHints::guiding`]), else off.
    pub guiding: bool,
}

impl GivenSettings {
    /// Every setting given: the scene file's hints are ignored.
    pub const ALL: GivenSettings = GivenSettings {
        width: true,
        height: true,
        spp: true,
        max_depth: true,
        filter: true,
        integrator: true,
        spectral: true,
        guiding: true,
    };
}

/// Falls back to RGB when spectral rendering came only from the scene file's default
/// ([`GivenSettings::spectral`] false) and the integrator `settings` resolve to in `world` has no
/// spectral path ([`crate::render::has_spectral_path`]), or `aovs` asks for BDPT's strategy
/// layers (RGB only); the line to log says why. An explicit `--spectral` is left for the render
/// to refuse by name.
pub fn rgb_fallback(
    given: &GivenSettings,
    world: &World,
    settings: &mut RenderSettings,
    aovs: &[AovKind],
) -> Option<String> {
    if given.spectral || !settings.path.spectral {
        return None;
    }
    let why = if !crate::render::has_spectral_path(world, settings) {
        let integrator = crate::integrator::Integrator::for_world(settings.integrator, world);
        format!("the {} has no spectral path yet", integrator.name())
    } else if let Some(k) = aovs.iter().find(|k| k.is_strategy()) {
        format!("the strategy layer --aov {} is RGB only", k.name())
    } else {
        return None;
    };
    settings.path.spectral = false;
    Some(format!(
        "the scene file renders spectrally by default, but {why}: rendering RGB"
    ))
}

/// The log's words for the colour mode and why it was chosen: `spectral` is the resolved
/// setting, `prefers` the scene file's default ([`crate::scene::RenderHints::spectral`]).
pub fn colour_mode(given: &GivenSettings, prefers: bool, spectral: bool) -> &'static str {
    match (spectral, given.spectral, prefers) {
        (true, false, _) => "spectral (3 wavelengths per sample; pbrt file; --rgb for RGB)",
        (true, true, _) => "spectral (3 wavelengths per sample)",
        (false, false, true) => "RGB (the file's spectral default does not apply: see above)",
        (false, true, true) => "RGB (--rgb)",
        (false, _, false) => "RGB",
    }
}

/// The stages of a render, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Load,
    Build,
    Render,
    /// Open Image Denoise (only with [`RenderJob::denoise`]).
    Denoise,
    Write,
}

/// A line of the render's log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LogLine {
    /// Something the user should know: unsupported data, a fallback, discarded samples.
    Warning(String),
    /// The summary lines and the phase report.
    Info(String),
}

impl std::fmt::Display for LogLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LogLine::Warning(w) => write!(f, "warning: {w}"),
            LogLine::Info(s) => f.write_str(s),
        }
    }
}

/// What a front end sees of a running pipeline. Every method has an empty default; the render
/// driver's progress (passes, tiles) comes through the [`RenderObserver`] supertrait.
pub trait PipelineObserver: RenderObserver {
    fn stage_started(&self, _stage: Stage) {}
    fn stage_finished(&self, _stage: Stage, _took: Duration) {}
    fn log(&self, _line: LogLine) {}
}

/// An observer that ignores everything.
pub struct Silent;
impl RenderObserver for Silent {}
impl PipelineObserver for Silent {}

/// Why a pipeline stopped.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error("invalid setting: {0}")]
    InvalidSetting(String),
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Writing `path` failed (kept apart so a front end can name the file its own way).
    /// `error` already names the file; it is not also a `source()`, so `{:#}` says it once.
    #[error("{error}")]
    Write { path: PathBuf, error: OutputError },
    #[error("render cancelled")]
    Cancelled,
    /// Cancelled after some passes: what of them was kept (a checkpoint to resume from, the
    /// images of the completed passes), said in the message.
    #[error("{}", interrupted_message(*.done, *.spp, .checkpoint.as_deref(), *.checkpoint_fresh, .written, *.resumable))]
    Interrupted {
        /// Samples per pixel completed, of the frame's `spp`.
        done: u32,
        spp: u32,
        /// The checkpoint file that holds the render so far, if any.
        checkpoint: Option<PathBuf>,
        /// Whether `checkpoint` was written at the interruption (else it is an earlier one, from
        /// before the pass in flight, or the file resumed from).
        checkpoint_fresh: bool,
        /// The outputs written from the completed passes.
        written: Vec<PathBuf>,
        /// Whether a render of these settings can be continued from a checkpoint (not MLT's
        /// chains, which run over the whole frame).
        resumable: bool,
    },
    /// Writing an output failed; the film was saved as a partial film instead, which
    /// `trayecto merge` turns into the image.
    #[error("{error}; {}", rescue_message(.rescued, .samples, *.spp))]
    Rescued {
        error: Box<PipelineError>,
        /// Where the film went.
        rescued: PathBuf,
        /// The sample range it holds, of a frame of `spp` samples per pixel.
        samples: [u32; 2],
        spp: u32,
    },
    #[error(transparent)]
    Part(#[from] PartError),
    #[error(transparent)]
    Denoise(#[from] DenoiseError),
    #[error(transparent)]
    Split(SplitError),
}

fn interrupted_message(
    done: u32,
    spp: u32,
    checkpoint: Option<&std::path::Path>,
    fresh: bool,
    written: &[PathBuf],
    resumable: bool,
) -> String {
    let mut m = format!("interrupted after {done} of {spp} samples per pixel");
    if !written.is_empty() {
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        m += &format!(
            "; the image of the completed passes is in {}",
            names.join(" and ")
        );
    }
    match (checkpoint, fresh) {
        (Some(c), true) => {
            m += &format!(
                "; the render so far is saved in {0} (continue it with --resume {0})",
                c.display()
            )
        }
        (Some(c), false) => {
            m += &format!(
                "; the checkpoint {0} from before the pass in flight is kept (continue it with \
                 --resume {0})",
                c.display()
            )
        }
        (None, _) if resumable => m += " (give --checkpoint FILE to be able to resume a render)",
        (None, _) => {}
    }
    m
}

fn rescue_message(rescued: &std::path::Path, samples: &[u32; 2], spp: u32) -> String {
    let f = rescued.display();
    if samples[0] == 0 && samples[1] == spp {
        format!(
            "nothing is lost: the rendered film is saved in {f}; make the image from it with \
             `trayecto merge {f} -o image.exr` (any image name)"
        )
    } else {
        format!(
            "nothing is lost: the rendered film (samples {}..{} of {spp}) is saved in {f}, a \
             partial film to merge like the part it replaces (`trayecto merge {f} … -o image.exr`)",
            samples[0], samples[1]
        )
    }
}

impl From<SplitError> for PipelineError {
    fn from(e: SplitError) -> Self {
        match e {
            SplitError::Render(r) => r.into(),
            SplitError::Part(p) => p.into(),
            other => PipelineError::Split(other),
        }
    }
}

/// What a finished render reports.
#[derive(Clone, Debug)]
pub struct RenderReport {
    pub scene_name: String,
    /// The settings the render used (after scene defaults).
    pub settings: RenderSettings,
    /// The scene's and the world's warnings, and the render's own.
    pub warnings: Vec<String>,
    /// Phase timings, as the thesis's console log printed them.
    pub phases: PhaseReport,
    pub stats: RayStats,
    pub discarded_samples: u64,
    pub render_time: Duration,
    pub rays_per_second: f64,
    /// The files written, in the order of [`RenderJob::outputs`].
    pub written: Vec<PathBuf>,
    /// Samples per pixel of the last complete pass (less than `settings.spp` when adaptive
    /// sampling or the time limit stopped early, or the render covered a sample range).
    pub samples_done: u32,
    /// Mean samples per pixel actually taken (below `samples_done` under adaptive sampling).
    pub mean_samples: f64,
}

impl RenderJob {
    /// Refuses absurd settings and unwritable outputs before any work starts.
    pub fn check(&self) -> Result<(), PipelineError> {
        self.settings.validate()?;
        let bad = |m: String| Err(PipelineError::InvalidSetting(m));
        // The instruction set the BVHs will be built for: a name this build lacks, or a level
        // the CPU lacks, stops the render here rather than running other code than asked.
        if let Err(e) = crate::math::simd_setting() {
            return bad(e.to_string());
        }
        if let Some(c) = &self.world.camera_override {
            if let Err(e) = c.validate() {
                return bad(e);
            }
            if let Some(name) = &self.world.camera {
                return bad(format!(
                    "choose the scene's camera '{name}' or give a camera view (--camera-from), not both"
                ));
            }
        }
        if let Err(e) = self.world.time.validate() {
            return bad(e);
        }
        if !(self.world.env_rotation.is_finite() && self.world.env_rotation.abs() <= 1e6) {
            return bad(format!(
                "the environment rotation must be a number of degrees (got {})",
                self.world.env_rotation
            ));
        }
        for o in &self.outputs {
            if o.path.is_dir() {
                return Err(PipelineError::Output(OutputError::Write {
                    path: o.path.clone(),
                    message: "is a folder: name a file in it (e.g. -o folder/render.png)".into(),
                }));
            }
            if !(o.exposure.is_finite() && o.exposure > 0.0) {
                return bad(format!(
                    "exposure must be a positive number (got {})",
                    o.exposure
                ));
            }
            if !is_partial_film(&o.path) {
                Format::from_path(&o.path)?;
                if self.split.samples.is_some() {
                    return bad(format!(
                        "{}: a partial render (a sample range) writes a partial film: name the output FILE.trp, then merge the parts",
                        o.path.display()
                    ));
                }
            }
        }
        let partial =
            self.split.samples.is_some() || self.outputs.iter().any(|o| is_partial_film(&o.path));
        // Coverage (alpha) is counted by the film itself, so partial films keep it.
        if self.aovs.iter().any(|&k| k != AovKind::Alpha) && partial {
            let film = if self.aovs.iter().any(|&k| AovKind::FILM.contains(&k)) {
                " (samples and variance neither: a partial film keeps no squared sums, so the \
                 variance of merged parts could not be exact)"
            } else {
                ""
            };
            return bad(format!(
                "--aov: AOVs are written with the image of a whole render, not into partial films \
                 (.trp, --samples){film}; render the AOVs with the whole frame's settings and an \
                 image output, e.g. -o aovs.exr --aov albedo,normal"
            ));
        }
        if self.aovs.contains(&AovKind::Variance) && self.split.resume.is_some() {
            return bad(
                "--aov variance: a checkpoint keeps no squared sums, so the variance of a resumed \
                 render would leave out the samples before it; render the frame without --resume \
                 for the variance (samples works with --resume)"
                    .into(),
            );
        }
        if self.denoise.is_some() && partial {
            return bad(
                "--denoise: a partial film (.trp, --samples) holds raw sums; denoise the merged \
                 image of the whole frame instead (render it to an image with --denoise)"
                    .into(),
            );
        }
        let split = &self.split;
        if self.settings.progressive()
            && (split.samples.is_some()
                || split.checkpoint.is_some()
                || split.resume.is_some()
                || self.outputs.iter().any(|o| is_partial_film(&o.path)))
        {
            return bad(
                "--noise-threshold and --time-limit stop passes early, so the film depends \
                 on every pass before it: they cannot be combined with sample ranges (--samples, \
                 the farm), partial films (.trp), --checkpoint or --resume"
                    .into(),
            );
        }
        for path in self
            .outputs
            .iter()
            .map(|o| &o.path)
            .chain(&split.checkpoint)
        {
            if path.is_dir() {
                return Err(PipelineError::Output(OutputError::Write {
                    path: path.clone(),
                    message: "is a folder: name a file in it (e.g. -o folder/render.png)".into(),
                }));
            }
            if let Some(parent) = path.parent()
                && !parent.as_os_str().is_empty()
                && !parent.is_dir()
            {
                return Err(PipelineError::Output(OutputError::Write {
                    path: path.clone(),
                    message: "the output folder does not exist".into(),
                }));
            }
        }
        if let Some(r) = &split.samples
            // Without --spp the frame's count may come from the scene file: the render checks
            // the range against it then.
            && !(r.start < r.end && (!self.given.spp || r.end <= self.settings.spp))
        {
            return bad(format!(
                "sample range {}..{} must be non-empty and end at most at the frame's {} samples per pixel",
                r.start, r.end, self.settings.spp
            ));
        }
        if let Some(r) = &split.resume
            && !r.is_file()
        {
            return bad(format!("{}: no such checkpoint file", r.display()));
        }
        Ok(())
    }

    /// The AOVs to write for a scene with `hints`: the job's (`--aov`), else those the scene
    /// file asks for (Mitsuba's `aov` integrator), unless the render writes a partial film,
    /// which holds no AOVs.
    pub fn aovs_for(&self, hints: &crate::scene::RenderHints) -> Vec<AovKind> {
        let partial =
            self.split.samples.is_some() || self.outputs.iter().any(|o| is_partial_film(&o.path));
        if !self.aovs.is_empty() || partial {
            return self.aovs.clone();
        }
        hints.aovs.clone()
    }

    /// Whether the render must know its frame's identity (a scene digest): it writes or reads
    /// partial films.
    fn writes_parts(&self) -> bool {
        self.split.checkpoint.is_some()
            || self.split.resume.is_some()
            || self.outputs.iter().any(|o| is_partial_film(&o.path))
    }

    /// The settings to render `scene` with: the scene file's resolution, samples and depth
    /// ([`Scene::hints`]) under the options the job was explicitly given, and the image's shape
    /// from the camera (see [`RenderJob::resolve`]).
    pub fn settings_for(&self, scene: &Scene) -> RenderSettings {
        self.resolve(scene).0
    }

    /// [`RenderJob::settings_for`], with a line saying where the image size came from when it
    /// was not given in full or disagrees with the camera's shape.
    ///
    /// The size, in order of precedence: the sides the job was given; the file's own resolution
    /// ([`crate::scene::RenderHints`]: pbrt `Film`, TOML `[render]`), with one given side
    /// deriving the other from the file's aspect ratio; the selected camera's aspect ratio (glTF
    /// `aspectRatio`, FBX film aspect): [`DEFAULT_HEIGHT`] pixels high, or one given side
    /// deriving the other; else the job's defaults (square). When the final size disagrees with
    /// the camera's aspect ratio the view is fitted by the camera's
    /// [`crate::scene::SensorFit`] (Blender's sensor fit `AUTO`; pbrt files: the shorter side,
    /// as pbrt-v4; [`crate::scene::CameraDesc::fitted_tan_half_v`]) and the line says so.
    pub fn resolve(&self, scene: &Scene) -> (RenderSettings, Option<String>) {
        let mut s = self.settings.clone();
        let h = &scene.hints;
        let pick = |given: bool, hint: Option<u32>, current: u32| match hint {
            Some(v) if !given => v,
            _ => current,
        };
        s.spp = pick(self.given.spp, h.spp, s.spp);
        s.path.max_depth = pick(self.given.max_depth, h.max_depth, s.path.max_depth);
        if !self.given.filter
            && let Some(f) = h.filter
        {
            s.filter = f;
        }
        if !self.given.integrator
            && let Some(k) = h.integrator.as_deref().and_then(|n| n.parse().ok())
        {
            s.integrator = k;
        }
        if !self.given.spectral {
            s.path.spectral = h.spectral;
        }
        if !self.given.guiding
            && let Some(g) = h.guiding
        {
            s.guiding = g;
        }
        // The photon settings the job was not given, from the file.
        s.photon.photons_per_iteration = s.photon.photons_per_iteration.or(h.photons_per_iteration);
        s.photon.radius = s.photon.radius.or(h.photon_radius);
        if let Some(m) = h.mlt {
            s.mlt = s.mlt.or(m);
        }
        // pbrt's `mutationsperpixel` is MLT's samples per pixel, over the file's pixelsamples.
        if let Some(n) = h.mlt_mutations
            && !self.given.spp
            && s.integrator == crate::integrator::IntegratorKind::Mlt
        {
            s.spp = n;
        }

        // A camera override has no frame of its own: the image's shape is the job's.
        let camera = match self.world.camera_override {
            Some(_) => None,
            None => scene.camera_by(self.world.camera.as_deref()),
        };
        let cam_aspect = camera
            .and_then(|c| c.aspect)
            .filter(|a| a.is_finite() && *a > 0.0);
        let (gw, gh) = (self.given.width, self.given.height);
        // Derives one side from the other at aspect ratio `a` = width / height.
        let from_w = |w: u32, a: f32| clamp_side(w as f64 / a as f64);
        let from_h = |hh: u32, a: f32| clamp_side(hh as f64 * a as f64);
        let mut source = "";
        match (gw, gh, h.width, h.height) {
            (true, true, ..) => {}
            (false, false, Some(w), Some(hh)) => {
                (s.width, s.height) = (w, hh);
                source = "the scene file's resolution";
            }
            (true, false, Some(w), Some(hh)) => {
                s.height = from_w(s.width, w as f32 / hh as f32);
                source = "--width and the scene file's aspect ratio";
            }
            (false, true, Some(w), Some(hh)) => {
                s.width = from_h(s.height, w as f32 / hh as f32);
                source = "--height and the scene file's aspect ratio";
            }
            _ => match cam_aspect {
                Some(a) if !gw && !gh => {
                    s.height = DEFAULT_HEIGHT;
                    s.width = from_h(DEFAULT_HEIGHT, a);
                    source = "the camera's aspect ratio";
                }
                Some(a) if gw => {
                    s.height = from_w(s.width, a);
                    source = "--width and the camera's aspect ratio";
                }
                Some(a) => {
                    s.width = from_h(s.height, a);
                    source = "--height and the camera's aspect ratio";
                }
                // A camera without an aspect ratio of its own (glTF cameras without
                // `aspectRatio`, the built-in scenes) frames a square image: one given side
                // is the other too, as the default 512x512 is.
                None if gw && h.height.is_none() => {
                    s.height = s.width;
                    source = "--width (the camera has no aspect ratio: square)";
                }
                None if gh && h.width.is_none() => {
                    s.width = s.height;
                    source = "--height (the camera has no aspect ratio: square)";
                }
                None => {
                    s.width = pick(gw, h.width, s.width);
                    s.height = pick(gh, h.height, s.height);
                }
            },
        }
        let mut note = (!source.is_empty()).then(|| {
            format!(
                "image size {}x{} from {source} (give --width/--height to change it)",
                s.width, s.height
            )
        });
        if let (Some(c), Some(a)) = (camera, cam_aspect)
            && (s.width as f64 - s.height as f64 * a as f64).abs() > 1.0
        {
            let (larger, shorter) = if s.width >= s.height {
                ("width", "height")
            } else {
                ("height", "width")
            };
            let how = match c.fit {
                crate::scene::SensorFit::Auto => format!(
                    "the view is fitted as Blender does (sensor fit auto), the camera's wider \
                     field of view spans the image's {larger}"
                ),
                crate::scene::SensorFit::Shorter => format!(
                    "as in pbrt-v4, the field of view spans the image's shorter side ({shorter})"
                ),
                crate::scene::SensorFit::Width => {
                    "as in Mitsuba (fov_axis x), the horizontal field of view is kept".into()
                }
                crate::scene::SensorFit::Height => {
                    "as in Mitsuba (fov_axis y), the vertical field of view is kept".into()
                }
                crate::scene::SensorFit::Diagonal => {
                    "as in Mitsuba (fov_axis diagonal), the diagonal field of view is kept".into()
                }
            };
            note = Some(format!(
                "camera '{}' has aspect ratio {a:.3} but the image is {}x{} ({:.3}): {how}",
                c.name,
                s.width,
                s.height,
                s.width as f64 / s.height as f64
            ));
        }
        // The crop window needs the final size: the job's, else the file's pixel bounds, else
        // its crop window (pbrt-v4 uses `pixelbounds` only without `cropwindow`).
        let crop = self.crop.or(match (h.crop, h.pixel_bounds) {
            (Some(f), _) => Some(CropSpec::Fractions(f)),
            (None, Some(p)) => Some(CropSpec::Pixels(p)),
            _ => None,
        });
        s.crop = crop
            .map(|c| c.resolve(s.width, s.height))
            .filter(|c| (c.x0, c.x1, c.y0, c.y1) != (0, s.width, 0, s.height));
        // The variance AOV needs the film's squared-luminance sums.
        s.track_variance |= self.aovs.contains(&AovKind::Variance);
        s.track_coverage |= self.aovs.contains(&AovKind::Alpha);
        (s, note)
    }

    /// The Open Image Denoise library when `--denoise` asks for it.
    fn load_denoiser(&self) -> Result<Option<Oidn>, PipelineError> {
        self.denoise
            .as_ref()
            .map(|d| Oidn::load(d.library.as_deref()))
            .transpose()
            .map_err(Into::into)
    }

    /// Runs the whole pipeline. `cancel` is polled between stages and by the render driver.
    pub fn run(
        &self,
        observer: &dyn PipelineObserver,
        cancel: &AtomicBool,
    ) -> Result<RenderReport, PipelineError> {
        self.check()?;
        // The denoiser is loaded first: without it, fail before any work.
        let denoiser = self.load_denoiser()?;
        let mut run = Run {
            job: self,
            observer,
            cancel,
            warnings: Vec::new(),
        };
        // Loading and building run under the caller's memory budget and cancel flag
        // (crate::limits), else a fresh default budget; a load that fails because it was
        // cancelled is a cancellation, not an error.
        let built = crate::limits::scope_or_default(|| {
            let loaded = run.load()?;
            run.build(loaded)
        })
        .map_err(|e| cancelled_or(cancel, e))?;
        run.finish(built, denoiser.as_ref())
    }
}

/// A load or build that failed because it was cancelled is a cancellation, not an error.
fn cancelled_or(cancel: &AtomicBool, e: PipelineError) -> PipelineError {
    if cancel.load(Ordering::Relaxed) {
        PipelineError::Cancelled
    } else {
        e
    }
}

/// Output `path` of frame `frame` of a sequence: `out.exr` → `out_0001.exr`.
pub fn frame_path(path: &std::path::Path, frame: u32) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}_{frame:04}.{}", ext.to_string_lossy()),
        None => format!("{stem}_{frame:04}"),
    };
    path.with_file_name(name)
}

impl RenderJob {
    /// Renders frames `frames` of an animated scene (docs/DESIGN.md §5, "Animation"): the scene
    /// is read once, then posed, compiled, rendered and written per frame, each output named by
    /// [`frame_path`]. Each frame is the image [`RenderJob::run`] gives with `--frame N`.
    ///
    /// With `--checkpoint FILE` each frame checkpoints into its own [`frame_path`] of FILE. With
    /// `--resume FILE` the sequence goes on where it stopped: a frame with a checkpoint newer
    /// than its outputs continues from it (exactly, as a resumed still), a frame whose outputs
    /// are all newer than its checkpoint (or have none) was finished and is skipped, and the
    /// others are rendered.
    pub fn run_frames(
        &self,
        frames: std::ops::RangeInclusive<u32>,
        observer: &dyn PipelineObserver,
        cancel: &AtomicBool,
    ) -> Result<Vec<RenderReport>, PipelineError> {
        let resume = self.split.resume.clone();
        // The checkpoints of a sequence are per frame: the one named is a pattern.
        let mut base = self.clone();
        base.split.resume = None;
        base.check()?;
        if self.world.time.time.is_some() {
            return Err(PipelineError::InvalidSetting(
                "--frames and --time both give the moment: use one".into(),
            ));
        }
        let denoiser = self.load_denoiser()?;
        let mut first = Run {
            job: self,
            observer,
            cancel,
            warnings: Vec::new(),
        };
        let loaded = crate::limits::scope_or_default(|| first.load())
            .map_err(|e| cancelled_or(cancel, e))?;
        let mut reports = Vec::new();
        let mut read_once = false;
        for frame in frames {
            let mut job = base.clone();
            job.world.time.frame = Some(frame);
            for o in &mut job.outputs {
                o.path = frame_path(&o.path, frame);
            }
            job.split.checkpoint = job.split.checkpoint.map(|c| frame_path(&c, frame));
            if let Some(r) = &resume {
                match frame_progress(&job, &frame_path(r, frame)) {
                    FrameProgress::Done => {
                        first.info(format!("frame {frame}: rendered before, skipped"));
                        continue;
                    }
                    FrameProgress::Resume(c) => {
                        job.split.resume = Some(c);
                        job.check()?;
                    }
                    FrameProgress::Start => {}
                }
            }
            let mut run = Run {
                job: &job,
                observer,
                cancel,
                warnings: first.warnings.clone(),
            };
            run.info(format!("frame {frame}"));
            let this = Loaded {
                scene: loaded.scene.clone(),
                settings: loaded.settings.clone(),
                digest: loaded.digest.clone(),
                // Read once, for the first frame rendered.
                time: if read_once {
                    Duration::ZERO
                } else {
                    loaded.time
                },
            };
            read_once = true;
            let built = crate::limits::scope_or_default(|| run.build(this))
                .map_err(|e| cancelled_or(cancel, e))?;
            reports.push(run.finish(built, denoiser.as_ref())?);
        }
        Ok(reports)
    }
}

/// Where frame `job` of a resumed sequence stands ([`RenderJob::run_frames`]).
enum FrameProgress {
    /// Its outputs were all written after its last checkpoint (or it has none).
    Done,
    /// Continue from this checkpoint.
    Resume(PathBuf),
    /// Not begun.
    Start,
}

fn frame_progress(job: &RenderJob, checkpoint: &std::path::Path) -> FrameProgress {
    let modified = |p: &std::path::Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let saved = modified(checkpoint);
    let outputs: Option<Vec<_>> = job.outputs.iter().map(|o| modified(&o.path)).collect();
    match (saved, outputs) {
        (Some(c), Some(out)) if !out.is_empty() && out.iter().all(|&t| t >= c) => {
            FrameProgress::Done
        }
        (None, Some(out)) if !out.is_empty() => FrameProgress::Done,
        (Some(_), _) => FrameProgress::Resume(checkpoint.to_path_buf()),
        (None, _) => FrameProgress::Start,
    }
}

/// One run of a [`RenderJob`]: where its stages report, and the warnings so far. Each stage is
/// a method taking what the stage before it produced.
struct Run<'a> {
    job: &'a RenderJob,
    observer: &'a dyn PipelineObserver,
    cancel: &'a AtomicBool,
    warnings: Vec<String>,
}

/// The load stage's result: the scene, the settings resolved against it and its identity.
struct Loaded {
    scene: Scene,
    settings: RenderSettings,
    /// The frame's identity for partial films (empty when none is written or read).
    digest: String,
    time: Duration,
}

/// The build stage's result.
struct Built {
    world: World,
    frame: FrameId,
    settings: RenderSettings,
    /// The colour mode and why, for the plan's line ([`colour_mode`]).
    colour: &'static str,
    /// The AOVs to write: the job's, else the scene file's ([`RenderJob::aovs_for`]).
    aovs: Vec<AovKind>,
    scene_name: String,
    camera_count: usize,
    load_time: Duration,
    time: Duration,
}

/// The render stage's result: the beauty image, its film and the AOV layers (the world is gone).
struct Rendered {
    out: crate::render::RenderOutput,
    part: Part,
    layers: Vec<Layer>,
    /// The AOVs traced (the requested ones and the denoiser's guides).
    traced: Vec<AovKind>,
    /// The AOVs to write ([`Built::aovs`]).
    aovs: Vec<AovKind>,
    settings: RenderSettings,
    scene_name: String,
    samples_done: u32,
    mean_samples: f64,
    load_time: Duration,
    build_time: Duration,
    aov_time: Duration,
    accel_time: Duration,
    accel_description: String,
    /// The integrator that rendered ([`crate::integrator::Integrator::for_world`]).
    integrator_name: &'static str,
}

impl Run<'_> {
    fn warn(&mut self, w: String) {
        self.observer.log(LogLine::Warning(w.clone()));
        self.warnings.push(w);
    }

    fn info(&self, s: String) {
        self.observer.log(LogLine::Info(s));
    }

    fn check_cancel(&self) -> Result<(), PipelineError> {
        if self.cancel.load(Ordering::Relaxed) {
            return Err(PipelineError::Cancelled);
        }
        Ok(())
    }

    /// Load: the scene (its variant selected), the settings resolved against it.
    fn load(&mut self) -> Result<Loaded, PipelineError> {
        let job = self.job;
        self.observer.stage_started(Stage::Load);
        let t = Instant::now();
        let mut scene = crate::scene::load(&job.scene)?;
        if let Some(v) = &job.world.variant {
            scene.select_variant(v)?;
        }
        let time = t.elapsed();
        self.observer.stage_finished(Stage::Load, time);
        scene.warnings.iter().for_each(|w| self.warn(w.clone()));
        if let Some(a) = scene
            .animation
            .as_deref()
            .filter(|a| a.moves() && a.shutter.is_none())
            && job.world.time == Default::default()
        {
            let (t0, t1) = a.time_range().unwrap_or((0.0, 0.0));
            self.info(format!(
                "the scene is animated ({t0:.3} s – {t1:.3} s): its rest pose is rendered unless \
                 --time, --frame or --frames chooses a moment"
            ));
        }
        self.check_cancel()?;
        let (settings, size_note) = job.resolve(&scene);
        settings.validate()?;
        if let Some(n) = size_note {
            self.info(n);
        }
        // The frame's identity for partial films: hashing a big scene costs time, so only when
        // one is written or read.
        let digest = if job.writes_parts() {
            crate::scene::digest::digest(&job.scene, &scene, job.world.env.as_deref())?
        } else {
            String::new()
        };
        Ok(Loaded {
            scene,
            settings,
            digest,
            time,
        })
    }

    /// The stages after the build: the plan's log line, render, denoise, write, report.
    fn finish(
        mut self,
        built: Built,
        denoiser: Option<&Oidn>,
    ) -> Result<RenderReport, PipelineError> {
        self.log_plan(&built);
        self.check_cancel()?;
        let mut rendered = self.render(built, denoiser.is_some())?;
        let denoised = self.denoise(denoiser, &rendered)?;
        let written = self.write(&mut rendered, denoised.as_ref().map(|(d, _)| d))?;
        Ok(self.report(rendered, denoised.map(|(_, t)| t), written))
    }

    /// Build: the world from the scene.
    fn build(&mut self, loaded: Loaded) -> Result<Built, PipelineError> {
        let job = self.job;
        let Loaded {
            scene,
            mut settings,
            digest,
            time: load_time,
        } = loaded;
        let prefers_spectral = scene.hints.spectral;
        let scene_name = scene.name.clone();
        let camera_count = scene.cameras.len();
        let aovs = job.aovs_for(&scene.hints);
        if job.aovs.is_empty() && !aovs.is_empty() {
            let names: Vec<&str> = aovs.iter().map(|k| k.name()).collect();
            self.info(format!(
                "the scene file asks for AOVs: {} (--aov overrides)",
                names.join(", ")
            ));
        }
        self.observer.stage_started(Stage::Build);
        let t = Instant::now();
        // Posed at the job's moment, with one world per shutter step for motion blur.
        let world = World::build_posed(scene, &job.world)?;
        let time = t.elapsed();
        self.observer.stage_finished(Stage::Build, time);
        world.warnings.iter().for_each(|w| self.warn(w.clone()));
        // Before the frame's identity: partial films record the mode that renders.
        if let Some(line) = rgb_fallback(&job.given, &world, &mut settings, &aovs) {
            self.info(line);
        }
        let colour = colour_mode(&job.given, prefers_spectral, settings.path.spectral);
        // After the build: partial films record the light sampler `auto` resolved to.
        let frame = FrameId {
            scene: job.scene.clone(),
            digest,
            settings: settings.clone(),
            world: job.world.clone(),
            light_sampler: world.lights.sampler_kind(),
        };
        Ok(Built {
            world,
            frame,
            settings,
            colour,
            aovs,
            scene_name,
            camera_count,
            load_time,
            time,
        })
    }

    /// The scene summary and the render's plan, before it starts.
    fn log_plan(&self, built: &Built) {
        let (world, settings) = (&built.world, &built.settings);
        self.info(format!(
            "scene '{}': {} triangles, {} primitives, {} materials, {} lights ({} area), {} cameras",
            built.scene_name,
            world.triangle_count(),
            world.primitive_count(),
            world.materials.len(),
            world.lights.lights.len(),
            world.area_light_count(),
            built.camera_count
        ));
        let mut extras = String::new();
        if !settings.filter.is_default_box() {
            extras += &format!(", {} filter", settings.filter.describe());
        }
        if let Some(c) = settings.crop {
            extras += &format!(", crop columns {}..{} rows {}..{}", c.x0, c.x1, c.y0, c.y1);
        }
        if let Some(t) = settings.noise_threshold {
            extras += &format!(", noise threshold {t}");
        }
        if let Some(t) = settings.time_limit {
            extras += &format!(", time limit {t} s");
        }
        // Which colour representation renders and why (docs/DESIGN.md "Spectral rendering").
        extras += ", ";
        extras += built.colour;
        self.info(format!(
            "rendering {}x{} at {} spp, {} secondary, max depth {}, {} integrator, {} threads{extras}",
            settings.width,
            settings.height,
            settings.spp,
            settings.path.secondary,
            settings.path.max_depth,
            // The one that renders: `path` in a scene with media is the volumetric tracer.
            crate::integrator::Integrator::for_world(settings.integrator, world).name(),
            settings.threads.unwrap_or_else(rayon::current_num_threads)
        ));
    }

    /// Render: the beauty image (whole, or a sample range with checkpoints, [`crate::split`])
    /// and the AOVs, with the denoiser's guides when `guides`. The world is dropped at the end.
    fn render(&mut self, built: Built, guides: bool) -> Result<Rendered, PipelineError> {
        let job = self.job;
        let Built {
            world,
            frame,
            settings,
            aovs,
            scene_name,
            load_time,
            time: build_time,
            ..
        } = built;
        self.observer.stage_started(Stage::Render);
        // The denoiser's guides are traced too when they were not asked for (and not written).
        // Samples and variance are not traced: they are read from the film below.
        let mut traced = crate::integrator::aov::traced(&aovs);
        // BDPT's strategy layers are rendered by the render stage too ([`trace`]).
        traced.extend(aovs.iter().filter(|k| k.is_strategy()));
        if guides {
            for k in [AovKind::Albedo, AovKind::Normal] {
                if !traced.contains(&k) {
                    traced.push(k);
                }
            }
        }
        let t = match trace(
            &world,
            &frame,
            &job.split,
            &traced,
            self.observer,
            self.cancel,
        ) {
            Ok(Ok(t)) => t,
            Ok(Err(split)) => {
                let resumable = frame.settings.integrator != crate::integrator::IntegratorKind::Mlt;
                return Err(self.interrupted(*split, resumable));
            }
            // The checkpoint's folder failed mid-render: the completed passes go where a failed
            // output's film goes.
            Err(PipelineError::Split(crate::split::SplitError::Checkpoint { error, part })) => {
                return Err(rescue(PipelineError::Part(error), &part, &job.outputs));
            }
            Err(e) => return Err(e),
        };
        let samples_done = t.samples_done;
        let mean_samples = t.mean_samples;
        if t.stopped_early || settings.noise_threshold.is_some() {
            let counts = t.part.film.counts();
            let max = counts.iter().copied().max().unwrap_or(0);
            let min = counts.iter().copied().min().unwrap_or(0);
            let why = match (settings.noise_threshold, t.stopped_early) {
                (Some(th), true)
                    if samples_done < settings.spp && settings.time_limit.is_none() =>
                {
                    format!("every pixel reached relative error {th}")
                }
                (_, true) => "the time limit ended it".to_string(),
                (_, false) => format!("{} samples per pixel were reached", settings.spp),
            };
            self.info(format!(
                "progressive render stopped after sample {samples_done} of {} ({why}): {mean_samples:.1} samples per pixel on average (min {min}, max {max})",
                settings.spp
            ));
        }
        let Traced {
            out,
            part,
            layers,
            aov_time,
            ..
        } = t;
        self.observer
            .stage_finished(Stage::Render, out.render_time + aov_time);
        let accel_time = world.accel_build_time;
        let accel_description = world.accel.describe();
        let integrator_name =
            crate::integrator::Integrator::for_world(settings.integrator, &world).name();
        // The world (geometry, textures) is not needed to write the image.
        drop(world);
        Ok(Rendered {
            out,
            part,
            layers,
            traced,
            aovs,
            settings,
            scene_name,
            samples_done,
            mean_samples,
            load_time,
            build_time,
            aov_time,
            accel_time,
            accel_description,
            integrator_name,
        })
    }

    /// What an interrupted render keeps: the checkpoint (written at the interruption, or an
    /// earlier one), else, when the front end asks for it, the outputs written from the
    /// completed passes. Nothing kept is [`PipelineError::Cancelled`].
    fn interrupted(&mut self, split: crate::split::SplitOutcome, resumable: bool) -> PipelineError {
        let job = self.job;
        let (start, spp, done) = (split.header.samples[0], split.header.spp, split.render.done);
        let fresh = split.checkpoint_written.is_some();
        let checkpoint = split
            .checkpoint_written
            .or_else(|| job.split.checkpoint.clone().filter(|p| p.is_file()));
        let mut written = Vec::new();
        if done > start && checkpoint.is_none() && job.split.write_on_interrupt {
            let part = Part {
                header: split.header,
                film: split.render.film,
            };
            match write_outputs(&part.film.to_image(), Some(&part), &job.outputs, &[]) {
                Ok(w) => written = w,
                Err(e) => return rescue(e, &part, &job.outputs),
            }
        }
        if checkpoint.is_none() && written.is_empty() {
            return PipelineError::Cancelled;
        }
        PipelineError::Interrupted {
            done,
            spp,
            checkpoint,
            checkpoint_fresh: fresh,
            written,
            resumable,
        }
    }

    /// Denoise: the beauty image with the traced albedo and normal guides, and how long it took.
    fn denoise(
        &self,
        denoiser: Option<&Oidn>,
        r: &Rendered,
    ) -> Result<Option<(Image, Duration)>, PipelineError> {
        let Some(oidn) = denoiser else {
            return Ok(None);
        };
        self.observer.stage_started(Stage::Denoise);
        let t = Instant::now();
        let guide = |k: AovKind| {
            r.layers
                .iter()
                .find(|l| l.name == k.name())
                .and_then(Layer::to_image)
                .expect("the guides were traced")
        };
        let d = oidn.denoise(
            &r.out.image,
            &guide(AovKind::Albedo),
            &guide(AovKind::Normal),
            r.settings.threads,
        )?;
        let took = t.elapsed();
        self.observer.stage_finished(Stage::Denoise, t.elapsed());
        self.info(format!(
            "denoised with Open Image Denoise ({})",
            oidn.path().display()
        ));
        Ok(Some((d, took)))
    }

    /// Write: the image, the partial film, the requested AOV layers (the traced ones and the
    /// film's) and the denoised image; returns the files written and how long it took.
    fn write(
        &mut self,
        r: &mut Rendered,
        denoised: Option<&Image>,
    ) -> Result<(Vec<PathBuf>, Duration), PipelineError> {
        let job = self.job;
        finish_layers(&mut r.layers, &r.aovs, &r.settings, &r.part.film);

        self.observer.stage_started(Stage::Write);
        let t = Instant::now();
        // An adaptive render's sample counts and variances go into a multi-layer EXR unasked
        // (channels of the one file), but beside other formats only when `--aov` asks: side
        // files nobody asked for are clutter.
        let asked: Vec<Layer> = r
            .layers
            .iter()
            .filter(|l| {
                AovKind::FILM.iter().all(|k| k.name() != l.name)
                    || r.aovs.iter().any(|k| k.name() == l.name)
            })
            .cloned()
            .collect();
        let (exr, other): (Vec<OutputSpec>, Vec<OutputSpec>) = job
            .outputs
            .iter()
            .cloned()
            .partition(|o| Format::from_path(&o.path).ok() == Some(Format::Exr));
        let written =
            write_outputs(&r.out.image, Some(&r.part), &exr, &r.layers).and_then(|mut w| {
                w.extend(write_outputs(&r.out.image, Some(&r.part), &other, &asked)?);
                Ok(w)
            });
        let mut written = match written {
            Ok(w) => w,
            Err(e) => return Err(rescue(e, &r.part, &job.outputs)),
        };
        if let Some(d) = denoised {
            written.extend(write_denoised(d, &job.outputs)?);
        }
        let write_time = t.elapsed();
        self.observer.stage_finished(Stage::Write, write_time);
        if r.out.discarded_samples > 0 {
            self.warn(format!(
                "{} samples were NaN, infinite or beyond {:e} and were discarded",
                r.out.discarded_samples,
                crate::film::SAMPLE_LIMIT
            ));
        }
        Ok((written, write_time))
    }

    /// The thesis's console log (Fig. 5.44–5.46): phase durations and the time each ended, and
    /// the report the front end gets.
    fn report(
        self,
        r: Rendered,
        denoise_time: Option<Duration>,
        (written, write_time): (Vec<PathBuf>, Duration),
    ) -> RenderReport {
        let out = &r.out;
        let mut phases = PhaseReport::new();
        phases.phase("scene loaded", r.load_time);
        phases.phase("world compiled", r.build_time.saturating_sub(r.accel_time));
        phases.phase("acceleration structure built", r.accel_time);
        phases.phase(format!("rendered ({})", r.integrator_name), out.render_time);
        if !r.traced.is_empty() {
            phases.phase("AOVs traced", r.aov_time);
        }
        if let Some(t) = denoise_time {
            phases.phase("denoised", t);
        }
        phases.phase("image written", write_time);
        phases.note(format!("acceleration    {}", r.accel_description));
        phases.note(format!(
            "SIMD            {} (TRAYECTO_SIMD; the image is the same at every level)",
            crate::math::simd_level()
        ));
        phases.note(format!(
            "rays            {} ({} camera/bounce/reflection/refraction, {} shadow), {:.2} Mrays/s",
            out.stats.rays + out.stats.shadow_rays,
            out.stats.rays,
            out.stats.shadow_rays,
            out.rays_per_second() / 1e6
        ));
        phases.lines().into_iter().for_each(|l| self.info(l));
        let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        self.info(format!("wrote {}", names.join(" and ")));

        RenderReport {
            scene_name: r.scene_name,
            settings: r.settings,
            warnings: self.warnings,
            phases,
            stats: out.stats,
            discarded_samples: out.discarded_samples,
            render_time: out.render_time,
            rays_per_second: out.rays_per_second(),
            written,
            samples_done: r.samples_done,
            mean_samples: r.mean_samples,
        }
    }
}

/// What [`trace`] made of a render of a built world.
pub struct Traced {
    pub out: crate::render::RenderOutput,
    /// The film and its header (the frame's identity and sample range).
    pub part: Part,
    /// The traced AOV layers (see [`trace`]).
    pub layers: Vec<Layer>,
    /// Samples per pixel of the last complete pass.
    pub samples_done: u32,
    /// Mean samples per pixel actually taken.
    pub mean_samples: f64,
    /// Adaptive sampling or the time limit ended the render before its last planned pass.
    pub stopped_early: bool,
    pub aov_time: Duration,
}

/// The render stage on a built world: the beauty image (whole, or the sample range `split`
/// asks for, with its checkpoints, [`crate::split`]) and the `traced` AOV layers. AOVs are
/// recorded by the render's own paths where the integrator can (`render::aovs_in_loop`), else
/// traced in a pass of their own over the same camera samples; either way the beauty image is
/// the same. BDPT's strategy layers among `traced` ([`AovKind::Strategy`]) are rendered after
/// the image by `render::light::render_strategies`, over the same samples. An interrupted render
/// gives back what the split render kept (`Err` inside `Ok`).
pub fn trace(
    world: &World,
    frame: &FrameId,
    split: &SplitOptions,
    traced: &[AovKind],
    observer: &dyn RenderObserver,
    cancel: &AtomicBool,
) -> Result<Result<Traced, Box<crate::split::SplitOutcome>>, PipelineError> {
    let settings = &frame.settings;
    // BDPT's strategy layers come from a pass of their own after the render: checked first.
    let (strategies, traced): (Vec<AovKind>, Vec<AovKind>) =
        traced.iter().partition(|k| k.is_strategy());
    let traced = &traced[..];
    crate::render::light::check_strategies(world, settings, &strategies)?;
    let split =
        crate::split::render_split_aovs(world, frame, split, !traced.is_empty(), observer, cancel)?;
    if split.render.cancelled {
        return Ok(Err(Box::new(split)));
    }
    let samples_done = split.render.done;
    let counts = split.render.film.counts();
    let mean_samples = counts.iter().map(|&n| n as f64).sum::<f64>() / counts.len().max(1) as f64;
    let out = crate::render::RenderOutput {
        image: split.render.film.to_image(),
        stats: split.render.stats,
        discarded_samples: split.render.film.discarded,
        render_time: split.render.render_time,
    };
    let stopped_early = split.render.stopped_early;
    let part = Part {
        header: split.header,
        film: split.render.film,
    };
    let t = Instant::now();
    let win = settings.film_window();
    let in_loop = split.render.aovs;
    let mut layers = if traced.is_empty() {
        Vec::new()
    } else if let Some(acc) = &in_loop {
        crate::render::aov_layers(traced, win.width(), win.height(), acc)
    } else {
        match crate::render::render_aovs_samples(world, settings, traced, samples_done, cancel) {
            Ok(l) => l,
            Err(RenderError::Cancelled) => return Err(PipelineError::Cancelled),
            Err(e) => return Err(e.into()),
        }
    };
    if !strategies.is_empty() {
        let r = crate::render::light::render_strategies(
            world,
            settings,
            &strategies,
            samples_done,
            cancel,
        );
        match r {
            Ok(l) => layers.extend(l),
            Err(RenderError::Cancelled) => return Err(PipelineError::Cancelled),
            Err(e) => return Err(e.into()),
        }
    }
    Ok(Ok(Traced {
        out,
        part,
        layers,
        samples_done,
        mean_samples,
        stopped_early,
        aov_time: t.elapsed(),
    }))
}

/// The AOV layers a render hands to [`write_outputs`]: of the traced `layers`, those in `aovs`
/// (the denoiser's guides are traced without being asked for), then the layers read from the
/// film: per-pixel sample counts and variances when asked for, and always from an adaptive
/// render (which tracks the variance anyway).
pub fn finish_layers(
    layers: &mut Vec<Layer>,
    aovs: &[AovKind],
    settings: &RenderSettings,
    film: &crate::film::Film,
) {
    layers.retain(|l| aovs.iter().any(|k| k.name() == l.name));
    let mut film_kinds: Vec<AovKind> = if settings.noise_threshold.is_some() {
        AovKind::FILM.to_vec()
    } else {
        aovs.to_vec()
    };
    if aovs.contains(&AovKind::Alpha) && !film_kinds.contains(&AovKind::Alpha) {
        film_kinds.push(AovKind::Alpha);
    }
    debug_assert!(
        !film_kinds.contains(&AovKind::Variance) || settings.tracks_variance(),
        "the variance layer needs a film that tracked it"
    );
    layers.extend(crate::film::aov::film_layers(film, &film_kinds));
}

/// The output stage: writes the image (or, for `*.trp` outputs, the partial film `part`) to every
/// requested file and returns their paths. `layers` (AOVs) go into an EXR output as extra
/// channels (one multi-layer file, [`crate::film::output::write_exr_layers`]); beside any other
/// format each is a side file `out.NAME.ext` ([`side_path`]) showing it for the eye
/// ([`Layer::display_image`]); the raw values (negative normals, infinite depth) need the EXR,
/// which RGBE (.hdr) cannot hold either.
pub fn write_outputs(
    image: &Image,
    part: Option<&Part>,
    outputs: &[OutputSpec],
    layers: &[Layer],
) -> Result<Vec<PathBuf>, PipelineError> {
    let werr = |path: &std::path::Path, error: OutputError| PipelineError::Write {
        path: path.to_path_buf(),
        error,
    };
    let mut written = Vec::with_capacity(outputs.len());
    for o in outputs {
        if is_partial_film(&o.path) {
            let part = part.ok_or_else(|| {
                PipelineError::InvalidSetting(format!(
                    "{}: no partial film to write",
                    o.path.display()
                ))
            })?;
            part.write(&o.path)?;
            written.push(o.path.clone());
            continue;
        }
        let format = Format::from_path(&o.path)?;
        if format == Format::Exr && !layers.is_empty() {
            crate::film::output::write_exr_layers(image, layers, &o.path)
                .map_err(|e| werr(&o.path, e))?;
            written.push(o.path.clone());
            continue;
        }
        // Coverage goes into a PNG's own alpha channel (premultiplied colours unassociated, as
        // PNG stores them), not beside it.
        let alpha = layers
            .iter()
            .find(|l| l.name == AovKind::Alpha.name() && l.depth() == 1)
            .filter(|_| format == Format::Png);
        match alpha {
            Some(a) => {
                crate::film::output::write_png_rgba(image, &a.data, &o.path, o.exposure, o.tonemap)
            }
            None => write_image(image, &o.path, o.exposure, o.tonemap),
        }
        .map_err(|e| werr(&o.path, e))?;
        written.push(o.path.clone());
        for l in layers
            .iter()
            .filter(|l| alpha.is_none_or(|a| a.name != l.name))
        {
            let side = side_path(&o.path, &l.name);
            write_image(&l.display_image(), &side, 1.0, Tonemap::Clamp)
                .map_err(|e| werr(&side, e))?;
            written.push(side);
        }
    }
    Ok(written)
}

/// After a failed write: saves the film as a partial film (`.trp`, exact) beside the output that
/// failed, else in the system's temporary folder, under a name no file has yet, and returns the
/// error saying where it went ([`PipelineError::Rescued`]); the original error when no place
/// would take it either. A film holding the frame from sample 0 is saved as a frame of the samples
/// it holds, so that `trayecto merge` makes its image alone (an interrupted or time-limited
/// render's).
fn rescue(error: PipelineError, part: &Part, outputs: &[OutputSpec]) -> PipelineError {
    let failed = match &error {
        PipelineError::Write { path, .. } => Some(path.clone()),
        PipelineError::Part(crate::split::partial::PartError::Io { path, .. }) => {
            Some(path.clone())
        }
        _ => None,
    }
    .or_else(|| outputs.first().map(|o| o.path.clone()))
    .unwrap_or_else(|| PathBuf::from("render"));
    let mut header = part.header.clone();
    if header.samples[0] == 0 {
        header.spp = header.samples[1];
    }
    let stem = failed
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "render".into());
    let beside = match failed.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    for dir in [beside, std::env::temp_dir()] {
        for i in 0..16 {
            let name = if i == 0 {
                format!("{stem}.trp")
            } else {
                format!("{stem}-{i}.trp")
            };
            let path = dir.join(name);
            // Never over an existing file (the one that failed, or anything else).
            if path == failed || std::fs::symlink_metadata(&path).is_ok() {
                continue;
            }
            if crate::split::partial::write_film(&header, &part.film, &path).is_ok() {
                return PipelineError::Rescued {
                    error: Box::new(error),
                    rescued: path,
                    samples: header.samples,
                    spp: header.spp,
                };
            }
            // The folder does not take files: try the next one.
            break;
        }
    }
    error
}

/// Writes the denoised image beside each image output (`out.png` → `out.denoised.png`, with the
/// output's exposure and tone mapping); returns the paths.
pub fn write_denoised(
    denoised: &Image,
    outputs: &[OutputSpec],
) -> Result<Vec<PathBuf>, PipelineError> {
    let mut written = Vec::new();
    for o in outputs.iter().filter(|o| !is_partial_film(&o.path)) {
        let path = side_path(&o.path, "denoised");
        write_image(denoised, &path, o.exposure, o.tonemap).map_err(|error| {
            PipelineError::Write {
                path: path.clone(),
                error,
            }
        })?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::interrupted_message;
    use std::path::PathBuf;

    /// An interrupted render without a checkpoint suggests one only where a checkpoint could be
    /// resumed: not for Metropolis light transport, whose chains run over the whole frame.
    #[test]
    fn the_checkpoint_hint_is_given_only_where_a_render_can_be_resumed() {
        let written = [PathBuf::from("out.png")];
        let path = interrupted_message(3, 16, None, false, &written, true);
        let mlt = interrupted_message(3, 16, None, false, &written, false);
        assert!(path.contains("--checkpoint"), "{path}");
        assert!(!mlt.contains("--checkpoint"), "{mlt}");
        assert!(mlt.contains("out.png"), "{mlt}");
    }
}
