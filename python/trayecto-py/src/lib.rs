//! The `trayecto` Python package's extension module (`trayecto._trayecto`): scenes loaded once
//! and rendered many times through the library's render stage (`trayecto::pipeline::trace`, the
//! one the command line runs), images handed to numpy without a copy.
//!
//! Settings arrive as the command line's option names (`max_depth`, `no_nee`, …); what is not
//! given keeps the library's defaults (`RenderSettings::default()`, `WorldOptions::default()`),
//! which the command line's own defaults equal (the package's tests render both ways and compare).

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use trayecto::accel::AccelKind;
use trayecto::camera::CameraSpec;
use trayecto::denoise::{DenoiseOptions, Oidn};
use trayecto::film::aov::{AovKind, Layer};
use trayecto::film::filter::{Filter, FilterKind};
use trayecto::film::tonemap::Tonemap;
use trayecto::integrator::{Aov, IntegratorKind, PathSettings, ShadingModel};
use trayecto::material::texture::TextureFilter;
use trayecto::math::Vec3;
use trayecto::pipeline::{
    CropSpec, GivenSettings, OutputSpec, PipelineError, RenderJob, finish_layers, trace,
};
use trayecto::render::{RenderObserver, RenderSettings};
use trayecto::sampling::SamplerKind;
use trayecto::scene::{LightDesc, SceneError as LibSceneError};
use trayecto::split::partial::Part;
use trayecto::split::{FrameId, SplitOptions};
use trayecto::world::{World, WorldOptions};

create_exception!(
    trayecto,
    SceneError,
    PyException,
    "A scene could not be loaded or changed; the message is the command line's."
);
create_exception!(
    trayecto,
    RenderError,
    PyException,
    "A render could not run: an invalid setting, or a failure while rendering."
);
create_exception!(
    trayecto,
    Cancelled,
    PyException,
    "The render was cancelled (the progress callback returned False)."
);

/// An error and its causes, as the command line prints them (`{:#}`).
fn message(e: &dyn std::error::Error) -> String {
    let mut m = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        m += &format!(": {s}");
        source = s.source();
    }
    m
}

fn scene_err(e: &LibSceneError) -> PyErr {
    SceneError::new_err(message(e))
}

fn pipeline_err(e: PipelineError) -> PyErr {
    match &e {
        PipelineError::Scene(s) => scene_err(s),
        PipelineError::InvalidSetting(_) => PyValueError::new_err(message(&e)),
        PipelineError::Cancelled | PipelineError::Interrupted { .. } => {
            Cancelled::new_err(message(&e))
        }
        _ => RenderError::new_err(message(&e)),
    }
}

fn bad(m: impl Into<String>) -> PyErr {
    PyValueError::new_err(m.into())
}

/// Every render keyword and its default: the command line's options by their Python names,
/// the values from the library's defaults. `None` means "the scene file's, else the built-in
/// default" (size, samples, depth, filter) or "not set".
#[pyfunction]
fn defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let s = RenderSettings::default();
    let p = PathSettings::default();
    let w = WorldOptions::default();
    let d = PyDict::new(py);
    let none = py.None();
    d.set_item("spp", &none)?;
    d.set_item("seed", s.seed)?;
    d.set_item("width", &none)?;
    d.set_item("height", &none)?;
    // None: the scene file's (pbrt `Integrator`), else the path tracer, as on the command line.
    d.set_item("integrator", &none)?;
    d.set_item("threads", s.threads)?;
    d.set_item("aovs", PyTuple::empty(py))?;
    d.set_item("secondary", p.secondary)?;
    d.set_item("max_depth", &none)?;
    d.set_item("exposure", 1.0f32)?;
    d.set_item("tonemap", Tonemap::default().name())?;
    d.set_item("shading", ShadingModel::default().name())?;
    d.set_item("accel", w.accel.name())?;
    d.set_item("sampler", s.sampler.name())?;
    d.set_item("no_nee", !p.nee)?;
    d.set_item("no_mis", !p.mis)?;
    d.set_item("rr_depth", p.rr_depth)?;
    d.set_item("rr_scale", p.rr_scale)?;
    d.set_item("camera", &none)?;
    d.set_item("default_light", &none)?;
    d.set_item("no_default_light", false)?;
    d.set_item("env", &none)?;
    d.set_item("env_rotation", &none)?;
    d.set_item("camera_from", &none)?;
    d.set_item("variant", &none)?;
    d.set_item("light_sampler", w.light_sampler.name())?;
    d.set_item("texture_filter", w.texture_filter.name())?;
    d.set_item("filter", &none)?;
    d.set_item("filter_radius", &none)?;
    d.set_item("filter_sigma", &none)?;
    d.set_item("noise_threshold", s.noise_threshold)?;
    d.set_item("time_limit", s.time_limit)?;
    d.set_item("crop", &none)?;
    d.set_item("pixel_bounds", &none)?;
    // None: the scene file's (TOML `[render] guiding`), else off; True/False: forced.
    d.set_item("guiding", &none)?;
    // The command line's `--no-guiding`: guiding=False.
    d.set_item("no_guiding", false)?;
    // SPPM and VCM: None is the scene file's, else the integrator's own default.
    d.set_item("photons_per_iteration", s.photon.photons_per_iteration)?;
    d.set_item("photon_radius", s.photon.radius)?;
    d.set_item("vcm_no_merge", s.photon.no_merge)?;
    // MLT: None is the scene file's, else pbrt-v4's default.
    d.set_item("mlt_bootstrap_samples", s.mlt.bootstrap_samples)?;
    d.set_item("mlt_chains", s.mlt.chains)?;
    d.set_item("mlt_large_step_probability", s.mlt.large_step_probability)?;
    d.set_item("mlt_sigma", s.mlt.sigma)?;
    // None: no clamp (infinite), as the command line's absent option.
    d.set_item("clamp_direct", &none)?;
    d.set_item("clamp_indirect", &none)?;
    d.set_item("transparent", p.transparent)?;
    // None: the scene file's default (pbrt files spectral, as pbrt-v4); True/False: forced.
    d.set_item("spectral", &none)?;
    // The command line's `--rgb`: spectral=False.
    d.set_item("rgb", false)?;
    // Animation and motion blur (`WorldOptions::time`): the file's rest pose, no blur.
    d.set_item("time", &none)?;
    d.set_item("frame", &none)?;
    d.set_item("fps", &none)?;
    d.set_item("shutter", &none)?;
    d.set_item("shutter_steps", &none)?;
    // Sample ranges, checkpoints and resuming (docs/DESIGN.md, "Splitting a frame").
    d.set_item("samples", &none)?;
    d.set_item("checkpoint", &none)?;
    d.set_item("checkpoint_interval", CHECKPOINT_INTERVAL)?;
    d.set_item("resume", &none)?;
    d.set_item("denoise", false)?;
    d.set_item("oidn", &none)?;
    // Read when the scene is loaded (`load_file`), as the command line reads them.
    d.set_item("memory_limit", &none)?;
    d.set_item("confine_paths", false)?;
    d.set_item("define", &none)?;
    Ok(d)
}

/// The command line's `--checkpoint-interval` default, in seconds.
const CHECKPOINT_INTERVAL: f64 = 60.0;

/// The names each option with a fixed set of values takes, as the command line spells them
/// (the library's `name()`, which its `FromStr` parses back).
#[pyfunction]
fn choices(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("sampler", SamplerKind::ALL.map(SamplerKind::name))?;
    d.set_item("accel", AccelKind::ALL.map(AccelKind::name))?;
    d.set_item("shading", ShadingModel::ALL.map(ShadingModel::name))?;
    d.set_item(
        "texture_filter",
        TextureFilter::ALL.map(TextureFilter::name),
    )?;
    d.set_item("light_sampler", trayecto::light::LightSamplerKind::NAMES)?;
    Ok(d)
}

/// A setting the scene file may give, as the command line's `--key`/`--off` pair: `key=True` or
/// `False` forces it, `off=True` is `key=False`, both true is refused; `None` leaves the file's.
fn forced_or_files(d: &Bound<'_, PyDict>, key: &str, off: &str) -> PyResult<Option<bool>> {
    match (opt::<bool>(d, key)?, opt::<bool>(d, off)?.unwrap_or(false)) {
        (Some(true), true) => Err(bad(format!(
            "invalid setting: give {key}=True or {off}=True, not both"
        ))),
        (_, true) => Ok(Some(false)),
        (v, false) => Ok(v),
    }
}

/// A keyword's value, `None` when it is absent or `None`.
fn opt<'py, T: FromPyObject<'py>>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<Option<T>> {
    match d.get_item(key)? {
        Some(v) if !v.is_none() => v
            .extract::<T>()
            .map(Some)
            .map_err(|e| PyTypeError::new_err(format!("{key}: {e}"))),
        _ => Ok(None),
    }
}

fn parsed<T: std::str::FromStr>(d: &Bound<'_, PyDict>, key: &str) -> PyResult<Option<T>>
where
    T::Err: std::fmt::Display,
{
    match opt::<String>(d, key)? {
        Some(s) => s
            .trim()
            .parse::<T>()
            .map(Some)
            .map_err(|e| bad(format!("invalid setting: {key}: {e}"))),
        None => Ok(None),
    }
}

/// A window as four numbers or the command line's `x0,x1,y0,y1` text.
fn window(d: &Bound<'_, PyDict>, key: &str, pixels: bool) -> PyResult<Option<CropSpec>> {
    let Some(v) = d.get_item(key)?.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let text = if let Ok(s) = v.extract::<String>() {
        s
    } else {
        let nums: Vec<f64> = v
            .extract()
            .map_err(|_| PyTypeError::new_err(format!("{key}: four numbers x0, x1, y0, y1")))?;
        nums.iter()
            .map(|n| n.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    CropSpec::parse(&text, pixels)
        .map(Some)
        .map_err(|e| bad(format!("invalid setting: {key}: {e}")))
}

/// A render's options, as the command line turns its arguments into a job.
struct Options {
    settings: RenderSettings,
    world: WorldOptions,
    given: GivenSettings,
    crop: Option<CropSpec>,
    aovs: Vec<AovKind>,
    exposure: f32,
    tonemap: Tonemap,
    split: SplitOptions,
    denoise: Option<DenoiseOptions>,
    shading: ShadingModel,
}

/// `A..B` text, or two numbers (a tuple, a list, a `range`), as the command line's `A..B`.
fn range_text(d: &Bound<'_, PyDict>, key: &str) -> PyResult<Option<String>> {
    let Some(v) = d.get_item(key)?.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(s) = v.extract::<String>() {
        return Ok(Some(s));
    }
    if let (Ok(a), Ok(b)) = (v.getattr("start"), v.getattr("stop")) {
        return Ok(Some(format!(
            "{}..{}",
            a.extract::<u32>()?,
            b.extract::<u32>()?
        )));
    }
    let [a, b]: [u32; 2] = v
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{key}: 'A..B' or two numbers (A, B)")))?;
    Ok(Some(format!("{a}..{b}")))
}

/// `OPEN,CLOSE` text or two numbers.
fn shutter(d: &Bound<'_, PyDict>) -> PyResult<Option<[f64; 2]>> {
    let Some(v) = d.get_item("shutter")?.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(s) = v.extract::<String>() {
        let parsed = s
            .split_once(',')
            .and_then(|(a, b)| Some([a.trim().parse().ok()?, b.trim().parse().ok()?]));
        return parsed.map(Some).ok_or_else(|| {
            bad(format!(
                "invalid setting: shutter must be OPEN,CLOSE in seconds (got '{s}')"
            ))
        });
    }
    v.extract::<[f64; 2]>()
        .map(Some)
        .map_err(|_| PyTypeError::new_err("shutter: 'OPEN,CLOSE' or two numbers"))
}

fn options(d: &Bound<'_, PyDict>) -> PyResult<Options> {
    let known = defaults(d.py())?;
    for k in d.keys() {
        if !known.contains(&k)? {
            return Err(PyTypeError::new_err(format!(
                "render() got an unexpected keyword argument {k}"
            )));
        }
    }
    let mut s = RenderSettings::default();
    let time_limit: Option<f64> = opt(d, "time_limit")?;
    let width: Option<u32> = opt(d, "width")?;
    let height: Option<u32> = opt(d, "height")?;
    let spp: Option<u32> = opt(d, "spp")?;
    let max_depth: Option<u32> = opt(d, "max_depth")?;
    let filter_kind: Option<FilterKind> = parsed(d, "filter")?;
    s.width = width.unwrap_or(s.width);
    s.height = height.unwrap_or(s.height);
    s.time_limit = time_limit;
    s.noise_threshold = opt(d, "noise_threshold")?;
    // A time-limited render without a sample count runs until the time is up.
    s.spp = spp.unwrap_or(if s.time_limit.is_some() {
        trayecto::render::TIME_LIMIT_SPP
    } else {
        s.spp
    });
    s.seed = opt(d, "seed")?.unwrap_or(s.seed);
    // 0 means every core, as on the command line.
    s.threads = opt::<usize>(d, "threads")?.filter(|&t| t > 0);
    // `--guiding`/`--no-guiding`: None leaves the scene file's (GivenSettings::guiding).
    let guiding_given = forced_or_files(d, "guiding", "no_guiding")?;
    s.guiding = guiding_given.unwrap_or(false);
    s.photon.photons_per_iteration = opt(d, "photons_per_iteration")?;
    s.photon.radius = opt(d, "photon_radius")?;
    s.photon.no_merge = opt(d, "vcm_no_merge")?.unwrap_or(s.photon.no_merge);
    s.mlt.bootstrap_samples = opt(d, "mlt_bootstrap_samples")?;
    s.mlt.chains = opt(d, "mlt_chains")?;
    s.mlt.large_step_probability = opt(d, "mlt_large_step_probability")?;
    s.mlt.sigma = opt(d, "mlt_sigma")?;
    s.sampler = parsed(d, "sampler")?.unwrap_or(s.sampler);
    let p = &mut s.path;
    p.max_depth = max_depth.unwrap_or(p.max_depth);
    p.secondary = opt(d, "secondary")?.unwrap_or(p.secondary);
    p.rr_depth = opt(d, "rr_depth")?.unwrap_or(p.rr_depth);
    p.rr_scale = opt(d, "rr_scale")?.unwrap_or(p.rr_scale);
    p.nee &= !opt::<bool>(d, "no_nee")?.unwrap_or(false);
    p.mis &= !opt::<bool>(d, "no_mis")?.unwrap_or(false);
    for (key, clamp) in [
        ("clamp_direct", &mut p.clamp_direct),
        ("clamp_indirect", &mut p.clamp_indirect),
    ] {
        if let Some(x) = opt::<f32>(d, key)? {
            if !(x.is_finite() && x > 0.0) {
                return Err(bad(format!(
                    "invalid setting: {key} must be a positive number (got {x})"
                )));
            }
            *clamp = x;
        }
    }
    p.transparent = opt(d, "transparent")?.unwrap_or(p.transparent);
    // `--spectral`/`--rgb`: None leaves the scene file's default (GivenSettings::spectral).
    let spectral_given = forced_or_files(d, "spectral", "rgb")?;
    p.spectral = spectral_given.unwrap_or(false);
    // AOV names; with the raycast integrator a single view name picks what the image shows.
    let aov_names: Vec<String> = match d.get_item("aovs")?.filter(|v| !v.is_none()) {
        Some(v) if v.is_instance_of::<PyString>() => vec![v.extract()?],
        Some(v) => v
            .extract()
            .map_err(|_| PyTypeError::new_err("aovs: a list of AOV names"))?,
        None => Vec::new(),
    };
    let integrator_given: Option<IntegratorKind> = parsed(d, "integrator")?;
    let integrator = integrator_given.unwrap_or_default();
    let shading: ShadingModel = parsed(d, "shading")?.unwrap_or_default();
    let raycast = matches!(integrator, IntegratorKind::Raycast { .. });
    let shading_name = shading;
    let view = match aov_names.as_slice() {
        [one] if raycast => one.trim().parse::<Aov>().ok(),
        _ => None,
    };
    s.integrator = integrator.with_options(view.unwrap_or_default(), shading);
    let mut aovs = if view.is_some() || aov_names.is_empty() {
        Vec::new()
    } else {
        AovKind::parse_list(&aov_names.join(","))
            .map_err(|e| bad(format!("invalid setting: aovs: {e}")))?
    };
    if s.path.transparent {
        if integrator_given.is_some_and(|k| k != IntegratorKind::Path) {
            return Err(bad("invalid setting: transparent needs integrator='path'"));
        }
        // The coverage the image's alpha is, as the command line adds it.
        if !aovs.contains(&AovKind::Alpha) {
            aovs.push(AovKind::Alpha);
        }
    }
    let filter_radius: Option<f32> = opt(d, "filter_radius")?;
    let filter_sigma: Option<f32> = opt(d, "filter_sigma")?;
    if (filter_radius.is_some() || filter_sigma.is_some()) && filter_kind.is_none() {
        return Err(bad(
            "invalid setting: filter_radius and filter_sigma need filter=NAME",
        ));
    }
    if filter_sigma.is_some() && filter_kind != Some(FilterKind::Gaussian) {
        return Err(bad(
            "invalid setting: filter_sigma applies to filter='gaussian' only",
        ));
    }
    let mut f = Filter::new(filter_kind.unwrap_or_default());
    if let Some(r) = filter_radius {
        f.radius = [r, r];
    }
    if let Some(sg) = filter_sigma {
        f.sigma = sg;
    }
    s.filter = f;
    let crop = match window(d, "crop", false)? {
        Some(c) => Some(c),
        None => window(d, "pixel_bounds", true)?,
    };
    let mut w = WorldOptions::default();
    w.accel = parsed(d, "accel")?.unwrap_or(w.accel);
    w.camera = match d.get_item("camera")?.filter(|v| !v.is_none()) {
        Some(v) if v.is_instance_of::<PyInt>() => Some(v.extract::<u64>()?.to_string()),
        Some(v) => Some(v.extract::<String>()?),
        None => None,
    };
    w.default_light = if opt::<bool>(d, "no_default_light")?.unwrap_or(false) {
        Some(trayecto::light::default_light::DefaultLight::Off)
    } else {
        parsed(d, "default_light")?
    };
    w.env = opt::<PathBuf>(d, "env")?;
    let rotation: Option<f32> = opt(d, "env_rotation")?;
    if rotation.is_some() && w.env.is_none() {
        return Err(bad("invalid setting: env_rotation needs env"));
    }
    w.env_rotation = rotation.unwrap_or(0.0);
    w.variant = opt(d, "variant")?;
    w.light_sampler = parsed(d, "light_sampler")?.unwrap_or(w.light_sampler);
    w.texture_filter = parsed(d, "texture_filter")?.unwrap_or(w.texture_filter);
    w.time = trayecto::world::motion::TimeOptions {
        time: opt(d, "time")?,
        frame: opt(d, "frame")?,
        fps: opt(d, "fps")?,
        shutter: shutter(d)?,
        steps: opt(d, "shutter_steps")?.unwrap_or(0),
    };
    let samples = range_text(d, "samples")?
        .map(|r| trayecto::split::parse_range(&r))
        .transpose()
        .map_err(|e| bad(format!("invalid setting: samples: {e}")))?;
    let checkpoint_interval: f64 = opt(d, "checkpoint_interval")?.unwrap_or(CHECKPOINT_INTERVAL);
    if !(0.0..=1e9).contains(&checkpoint_interval) {
        return Err(bad(format!(
            "invalid setting: checkpoint_interval must be 0 or more seconds (got {checkpoint_interval})"
        )));
    }
    let checkpoint: Option<PathBuf> = opt(d, "checkpoint")?;
    let resume: Option<PathBuf> = opt(d, "resume")?;
    let split = SplitOptions {
        samples,
        // A resumed render goes on saving into its checkpoint.
        checkpoint: checkpoint.or_else(|| resume.clone()),
        checkpoint_interval: Duration::from_secs_f64(checkpoint_interval),
        resume,
        // A cancelled render raises; what it completed is in the checkpoint when one is named.
        write_on_interrupt: false,
    };
    let oidn: Option<PathBuf> = opt(d, "oidn")?;
    let denoise = match (opt::<bool>(d, "denoise")?.unwrap_or(false), oidn) {
        (true, library) => Some(DenoiseOptions { library }),
        (false, Some(_)) => return Err(bad("invalid setting: oidn needs denoise=True")),
        (false, None) => None,
    };
    if let Some(f) = opt::<PathBuf>(d, "camera_from")? {
        if w.camera.is_some() {
            return Err(bad("invalid setting: give camera or camera_from, not both"));
        }
        w.camera_override = Some(trayecto::pipeline::camera_from_file(&f).map_err(pipeline_err)?);
    }
    Ok(Options {
        settings: s,
        world: w,
        given: GivenSettings {
            width: width.is_some(),
            height: height.is_some(),
            spp: spp.is_some() || time_limit.is_some(),
            max_depth: max_depth.is_some(),
            filter: filter_kind.is_some(),
            integrator: integrator_given.is_some(),
            spectral: spectral_given.is_some(),
            guiding: guiding_given.is_some(),
        },
        crop,
        aovs,
        exposure: opt(d, "exposure")?.unwrap_or(1.0),
        tonemap: parsed(d, "tonemap")?.unwrap_or_default(),
        split,
        denoise,
        shading: shading_name,
    })
}

/// A vector of three numbers (a single number means grey).
fn vec3(v: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec3> {
    if let Ok(x) = v.extract::<f32>() {
        return Ok(Vec3::splat(x));
    }
    let a: [f32; 3] = v
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{what}: three numbers")))?;
    Ok(Vec3::from(a))
}

fn list3(v: Vec3) -> [f32; 3] {
    v.to_array()
}

/// The world built from a scene, and the options it was built with.
struct Built {
    world: World,
    /// The world options (camera override left out: the camera is changed in place).
    key: String,
    camera: Option<CameraSpec>,
    /// Scene warnings and the world's, as the command line prints them.
    warnings: Vec<String>,
}

/// A loaded scene. Change its camera, materials and lights, then render it again: the scene is
/// not read again, and the compiled world is rebuilt only when what changed needs it (a camera
/// or a non-emitting material changes in place; lights rebuild the world from memory).
#[pyclass(module = "trayecto", dict)]
struct Scene {
    scene: trayecto::scene::Scene,
    /// How the scene was named (the file, the built-in scene, `load_dict`).
    label: String,
    camera: Option<CameraSpec>,
    built: Option<Built>,
    /// How many times the world was built (the tests check that changes do not rebuild it).
    builds: u64,
    /// The memory limit and path rule the scene was loaded under, for building its world.
    load: LoadSettings,
}

/// The loading options of the command line (`--memory-limit`, `--confine-paths`).
#[derive(Clone, Copy, Default)]
struct LoadSettings {
    memory_limit: Option<u64>,
    confine_paths: bool,
}

impl LoadSettings {
    fn context(self) -> std::sync::Arc<trayecto::limits::LoadContext> {
        use trayecto::limits::{Budget, LoadContext, PathRule, default_limit};
        LoadContext::with_paths(
            Budget::new(self.memory_limit.unwrap_or_else(default_limit)),
            None,
            if self.confine_paths {
                PathRule::Confined
            } else {
                PathRule::Open
            },
        )
    }
}

fn key_of(w: &WorldOptions) -> String {
    let mut w = w.clone();
    w.camera_override = None;
    format!("{w:?}")
}

impl Scene {
    fn new(scene: trayecto::scene::Scene, label: String, load: LoadSettings) -> Scene {
        Scene {
            scene,
            label,
            camera: None,
            built: None,
            builds: 0,
            load,
        }
    }

    /// The compiled world when it can be changed in place: built, and a still (a motion-blurred
    /// world is several, each with its own copies).
    fn built_still(&mut self) -> Option<&mut Built> {
        self.built.as_mut().filter(|b| b.world.motion.is_empty())
    }

    fn material_index(&self, name: &Bound<'_, PyAny>) -> PyResult<usize> {
        if let Ok(i) = name.extract::<usize>() {
            return if i < self.scene.materials.len() {
                Ok(i)
            } else {
                Err(PyKeyError::new_err(format!(
                    "no material {i} (the scene has {})",
                    self.scene.materials.len()
                )))
            };
        }
        let n: String = name.extract()?;
        self.scene
            .materials
            .iter()
            .position(|m| m.name == n)
            .ok_or_else(|| {
                let names: Vec<&str> = self.scene.materials.iter().map(|m| &*m.name).collect();
                PyKeyError::new_err(format!(
                    "no material '{n}' (the scene has {})",
                    names.join(", ")
                ))
            })
    }

    /// The world for `opts`: the one built before when it was built with the same options (the
    /// camera set in place), else a new one from the scene in memory.
    fn world(&mut self, opts: &WorldOptions) -> PyResult<&World> {
        let key = key_of(opts);
        let reuse = matches!(&self.built, Some(b) if b.key == key
            && (b.camera == opts.camera_override
                || (opts.camera_override.is_some() && b.world.is_still())));
        if reuse {
            let b = self.built.as_mut().expect("checked");
            if b.camera != opts.camera_override
                && let Some(c) = &opts.camera_override
            {
                // What `World::build` makes of a camera override, without building the rest.
                c.validate().map_err(|e| bad(format!("camera: {e}")))?;
                b.world.camera = c.to_desc("view");
                b.camera = Some(*c);
            }
        } else {
            self.built = None;
            let mut scene = self.scene.clone();
            let world = trayecto::limits::scope(self.load.context(), || {
                if let Some(v) = &opts.variant {
                    scene.select_variant(v)?;
                }
                let warnings = scene.warnings.clone();
                // Posed at the moment `time`/`frame` ask for, one world per shutter step.
                World::build_posed(scene, opts).map(|w| (w, warnings))
            })
            .map_err(|e| scene_err(&e))?;
            let (world, mut warnings) = world;
            warnings.extend(world.warnings.iter().cloned());
            self.builds += 1;
            self.built = Some(Built {
                world,
                key,
                camera: opts.camera_override,
                warnings,
            });
        }
        Ok(&self.built.as_ref().expect("built").world)
    }
}

/// The camera a mapping or an object with `eye`, `target`, `up` and `fov` describes.
fn camera_spec(v: &Bound<'_, PyAny>) -> PyResult<CameraSpec> {
    let get = |k: &str| -> PyResult<Option<Bound<'_, PyAny>>> {
        if let Ok(d) = v.downcast::<PyDict>() {
            return d.get_item(k);
        }
        Ok(v.getattr(k).ok())
    };
    let need = |k: &str| {
        get(k)?
            .filter(|x| !x.is_none())
            .ok_or_else(|| PyTypeError::new_err(format!("camera: needs '{k}'")))
    };
    let up = match get("up")?.filter(|x| !x.is_none()) {
        Some(u) => vec3(&u, "up")?,
        None => Vec3::Y,
    };
    let fov = match get("fov")?.filter(|x| !x.is_none()) {
        Some(f) => f.extract()?,
        None => CameraSpec::DEFAULT_FOV,
    };
    let spec = CameraSpec {
        eye: vec3(&need("eye")?, "eye")?,
        target: vec3(&need("target")?, "target")?,
        up,
        fov,
    };
    spec.validate().map_err(|e| bad(format!("camera: {e}")))?;
    Ok(spec)
}

fn light_power(l: &mut LightDesc) -> (&'static str, &str, &mut Vec3) {
    match l {
        LightDesc::Point {
            name, intensity, ..
        } => ("point", name, intensity),
        LightDesc::Spot {
            name, intensity, ..
        } => ("spot", name, intensity),
        LightDesc::Directional {
            name, irradiance, ..
        } => ("directional", name, irradiance),
        LightDesc::Ambient { name, radiance } => ("ambient", name, radiance),
        LightDesc::Environment { name, scale, .. } => ("environment", name, scale),
    }
}

/// The material parameters that can be read and set by name.
const MATERIAL_KEYS: [&str; 12] = [
    "base_color",
    "metallic",
    "roughness",
    "emissive",
    "transmission",
    "ior",
    "specular",
    "specular_color",
    "alpha",
    "normal_scale",
    "thin_walled",
    "double_sided",
];

#[pymethods]
impl Scene {
    /// The scene's name.
    #[getter]
    fn name(&self) -> &str {
        &self.scene.name
    }

    /// Warnings about the scene: the loader's, and the compiled world's once it was rendered.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        match &self.built {
            Some(b) => b.warnings.clone(),
            None => self.scene.warnings.clone(),
        }
    }

    /// The scene's camera names, in order (`camera=` picks one by name or index).
    #[getter]
    fn cameras(&self) -> Vec<String> {
        self.scene.cameras.iter().map(|c| c.name.clone()).collect()
    }

    /// The material names, in order.
    #[getter]
    fn materials(&self) -> Vec<String> {
        self.scene
            .materials
            .iter()
            .map(|m| m.name.clone())
            .collect()
    }

    /// How many times the world was compiled for rendering (changes to the camera and to
    /// non-emitting materials do not compile it again).
    #[getter]
    fn builds(&self) -> u64 {
        self.builds
    }

    /// The view renders use: the one set with `scene.camera = …` (a dict with `eye`, `target`,
    /// `up`, `fov`), else the scene's first camera (`None` if it has none). Setting `None`
    /// goes back to the scene's own cameras.
    #[getter]
    fn get_camera<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let spec = match (&self.camera, self.scene.cameras.first()) {
            (Some(c), _) => *c,
            (None, Some(d)) => CameraSpec::from_desc(d),
            (None, None) => return Ok(None),
        };
        let d = PyDict::new(py);
        d.set_item("eye", list3(spec.eye))?;
        d.set_item("target", list3(spec.target))?;
        d.set_item("up", list3(spec.up))?;
        d.set_item("fov", spec.fov)?;
        Ok(Some(d))
    }

    #[setter]
    fn set_camera(&mut self, v: Option<Bound<'_, PyAny>>) -> PyResult<()> {
        self.camera = match v.filter(|v| !v.is_none()) {
            Some(v) => Some(camera_spec(&v)?),
            None => None,
        };
        Ok(())
    }

    /// A material's parameters by name (or index): base_color, metallic, roughness, emissive,
    /// transmission, ior, specular, specular_color, alpha, normal_scale, thin_walled,
    /// double_sided, and its model.
    fn material<'py>(
        &self,
        py: Python<'py>,
        name: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.scene.materials[self.material_index(name)?];
        let d = PyDict::new(py);
        d.set_item("name", &m.name)?;
        d.set_item("model", format!("{:?}", m.model).to_lowercase())?;
        d.set_item("base_color", list3(m.base_color))?;
        d.set_item("metallic", m.metallic)?;
        d.set_item("roughness", m.roughness)?;
        d.set_item("emissive", list3(m.emissive))?;
        d.set_item("transmission", m.transmission)?;
        d.set_item("ior", m.ior)?;
        d.set_item("specular", m.specular)?;
        d.set_item("specular_color", list3(m.specular_color))?;
        d.set_item("alpha", m.alpha)?;
        d.set_item("normal_scale", m.normal_scale)?;
        d.set_item("thin_walled", m.thin_walled)?;
        d.set_item("double_sided", m.double_sided)?;
        Ok(d)
    }

    /// Sets material parameters by name, e.g. `scene.set_material("red", roughness=0.2)`. A
    /// material that does not emit light before or after is changed in the compiled world in
    /// place; an emitter's change rebuilds the world (its area lights) from memory.
    #[pyo3(signature = (name, **params))]
    fn set_material(
        &mut self,
        name: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        let i = self.material_index(name)?;
        let before = self.scene.materials[i].clone();
        let mut m = before.clone();
        for (k, v) in params.into_iter().flatten() {
            let k: String = k.extract()?;
            let f = || -> PyResult<f32> {
                v.extract()
                    .map_err(|_| PyTypeError::new_err(format!("{k}: a number")))
            };
            match k.as_str() {
                "base_color" => m.base_color = vec3(&v, &k)?,
                "emissive" => m.emissive = vec3(&v, &k)?,
                "specular_color" => m.specular_color = vec3(&v, &k)?,
                "metallic" => m.metallic = f()?,
                "roughness" => m.roughness = f()?,
                "transmission" => m.transmission = f()?,
                "ior" => m.ior = f()?,
                "specular" => m.specular = f()?,
                "alpha" => m.alpha = f()?,
                "normal_scale" => m.normal_scale = f()?,
                "thin_walled" => m.thin_walled = v.extract()?,
                "double_sided" => m.double_sided = v.extract()?,
                _ => {
                    return Err(PyKeyError::new_err(format!(
                        "'{k}' is not a material parameter ({})",
                        MATERIAL_KEYS.join(", ")
                    )));
                }
            }
        }
        self.scene.materials[i] = m.clone();
        if let Err(e) = self.scene.validate() {
            self.scene.materials[i] = before;
            return Err(bad(format!("material '{}': {}", m.name, message(&e))));
        }
        let emits = |m: &trayecto::material::Material| {
            m.emissive != Vec3::ZERO || m.emissive_texture.is_some()
        };
        let count = self.scene.materials.len();
        match self.built_still() {
            // Media give bounding objects their own copies of materials: rebuild then.
            Some(b) if !emits(&before) && !emits(&m) && b.world.materials.len() == count => {
                b.world.materials[i] = m;
            }
            _ => self.built = None,
        }
        Ok(())
    }

    /// The lights (not emitting surfaces, which are materials): name, type and intensity (W/sr
    /// for point and spot lights, W/m² for directional, W/(m²·sr) for ambient, a scale for
    /// environment maps), RGB.
    #[getter]
    fn lights<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let mut out = Vec::new();
        for l in &self.scene.lights {
            let mut l = l.clone();
            let (kind, name, power) = light_power(&mut l);
            let d = PyDict::new(py);
            d.set_item("name", name)?;
            d.set_item("type", kind)?;
            d.set_item("intensity", list3(*power))?;
            out.push(d);
        }
        Ok(out)
    }

    /// Sets a light's intensity and colour, by name or index: `intensity` is a number or RGB
    /// in the units `lights` lists; `color` an RGB the intensity is multiplied by (given alone,
    /// it keeps the light's strength, its largest channel). Point, spot, directional and
    /// ambient lights change in the compiled world in place (the geometry and its BVH are
    /// kept; only the choice among lights is redone); an environment map's change rebuilds
    /// the world from memory at the next render.
    #[pyo3(signature = (name, intensity=None, color=None))]
    fn set_light(
        &mut self,
        name: &Bound<'_, PyAny>,
        intensity: Option<&Bound<'_, PyAny>>,
        color: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let count = self.scene.lights.len();
        let index = if let Ok(i) = name.extract::<usize>() {
            (i < count).then_some(i)
        } else {
            let n: String = name.extract()?;
            self.scene
                .lights
                .iter_mut()
                .position(|l| light_power(l).1 == n)
        };
        let i = index.ok_or_else(|| {
            PyKeyError::new_err(format!("no light {name} (the scene has {count})"))
        })?;
        let current = *light_power(&mut self.scene.lights[i]).2;
        let color = color.map(|c| vec3(c, "color")).transpose()?;
        let v = match (intensity, color) {
            (Some(x), None) => vec3(x, "intensity")?,
            (Some(x), Some(c)) => {
                let s: f32 = x.extract().map_err(|_| {
                    PyTypeError::new_err("intensity: one number when color is given")
                })?;
                c * s
            }
            (None, Some(c)) => c * current.max_element(),
            (None, None) => return Err(PyTypeError::new_err("set_light: give intensity or color")),
        };
        if !v.is_finite() || v.min_element() < 0.0 {
            return Err(bad("intensity: finite, non-negative numbers"));
        }
        *light_power(&mut self.scene.lights[i]).2 = v;
        let desc = self.scene.lights[i].clone();
        if let Some(b) = self.built_still()
            && !b.world.set_scene_light(i, &desc)
        {
            self.built = None;
        }
        Ok(())
    }

    fn __repr__(&self) -> String {
        format!(
            "<trayecto.Scene '{}': {} objects, {} materials, {} lights, {} cameras>",
            self.scene.name,
            self.scene.objects.len(),
            self.scene.materials.len(),
            self.scene.lights.len(),
            self.scene.cameras.len()
        )
    }
}

/// The loading keywords: `memory_limit` (bytes, or the command line's `4G`, `512M`),
/// `confine_paths`, and `define` (Mitsuba parameters: a dict, or `NAME=VALUE` strings).
fn load_settings(d: &Bound<'_, PyDict>) -> PyResult<(LoadSettings, Vec<(String, String)>)> {
    let memory_limit = match d.get_item("memory_limit")?.filter(|v| !v.is_none()) {
        Some(v) if v.is_instance_of::<PyString>() => Some(
            trayecto::limits::parse_size(&v.extract::<String>()?)
                .map_err(|e| bad(format!("invalid setting: memory_limit: {e}")))?,
        ),
        Some(v) => Some(v.extract::<u64>()?),
        None => None,
    };
    let mut define = Vec::new();
    match d.get_item("define")?.filter(|v| !v.is_none()) {
        Some(v) if v.is_instance_of::<PyDict>() => {
            for (k, x) in v.downcast::<PyDict>()? {
                let value = match x.extract::<String>() {
                    Ok(s) => s,
                    Err(_) => x.str()?.extract()?,
                };
                define.push((k.extract()?, value));
            }
        }
        Some(v) => {
            let items: Vec<String> = if v.is_instance_of::<PyString>() {
                vec![v.extract()?]
            } else {
                v.extract()?
            };
            for s in items {
                define.push(
                    trayecto::scene::mitsuba::parse_define(&s)
                        .map_err(|e| bad(format!("invalid setting: define: {e}")))?,
                );
            }
        }
        None => {}
    }
    let settings = LoadSettings {
        memory_limit,
        confine_paths: opt(d, "confine_paths")?.unwrap_or(false),
    };
    Ok((settings, define))
}

/// Mitsuba `-D` parameters are process-wide in the library: loads that set them take turns.
static DEFINES: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// `load` under the loading keywords, the GIL released.
fn load_with<T: Send>(
    py: Python<'_>,
    options: &Bound<'_, PyDict>,
    load: impl FnOnce() -> Result<T, LibSceneError> + Send,
) -> PyResult<(T, LoadSettings)> {
    let (settings, define) = load_settings(options)?;
    let loaded = py.allow_threads(|| {
        let _turn = DEFINES.lock().unwrap_or_else(|e| e.into_inner());
        trayecto::scene::mitsuba::set_defines(define);
        let r = trayecto::limits::scope(settings.context(), load);
        trayecto::scene::mitsuba::set_defines(Vec::new());
        r
    });
    Ok((loaded.map_err(|e| scene_err(&e))?, settings))
}

/// Loads a scene file (every format the command line reads) or a built-in scene by name, under
/// the loading keywords (`memory_limit`, `confine_paths`, `define`).
#[pyfunction]
fn load_file(py: Python<'_>, path: PathBuf, options: &Bound<'_, PyDict>) -> PyResult<Scene> {
    let spec = path.to_string_lossy().into_owned();
    let (scene, load) = load_with(py, options, || trayecto::scene::load(&spec))?;
    Ok(Scene::new(scene, spec, load))
}

/// A Python value as TOML: dicts are tables, lists and tuples arrays, numpy arrays and scalars
/// their `tolist()`, paths strings; `None` entries of a dict are left out.
fn to_toml(v: &Bound<'_, PyAny>, at: &str) -> PyResult<toml::Value> {
    use toml::Value;
    if v.is_instance_of::<PyBool>() {
        return Ok(Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(Value::String(v.extract()?));
    }
    if let Ok(d) = v.downcast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d {
            let k: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{at}: keys must be strings")))?;
            if x.is_none() {
                continue;
            }
            let here = if at.is_empty() {
                k.clone()
            } else {
                format!("{at}.{k}")
            };
            t.insert(k, to_toml(&x, &here)?);
        }
        return Ok(Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, x) in v.try_iter()?.enumerate() {
            a.push(to_toml(&x?, &format!("{at}[{i}]"))?);
        }
        return Ok(Value::Array(a));
    }
    if v.hasattr("tolist")? {
        return to_toml(&v.call_method0("tolist")?, at);
    }
    if v.hasattr("__fspath__")? {
        return to_toml(&v.call_method0("__fspath__")?, at);
    }
    Err(PyTypeError::new_err(format!(
        "{at}: a {} cannot be written in a scene",
        v.get_type().name()?
    )))
}

/// The TOML scene file a dict describes (the same text `load_dict` reads).
#[pyfunction]
fn to_toml_text(d: &Bound<'_, PyDict>) -> PyResult<String> {
    let v = to_toml(d.as_any(), "")?;
    toml::to_string(&v).map_err(|e| SceneError::new_err(format!("the scene dict: {e}")))
}

/// A scene from dicts and lists with the TOML scene file's schema; files it names are read
/// relative to `base_dir`.
#[pyfunction]
fn load_dict(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    base_dir: PathBuf,
    options: &Bound<'_, PyDict>,
) -> PyResult<Scene> {
    let text = to_toml_text(d)?;
    let label = "load_dict.toml";
    let (scene, load) = load_with(py, options, || {
        trayecto::scene::load_bytes(text.as_bytes(), &base_dir, label)
    })?;
    Ok(Scene::new(scene, label.into(), load))
}

/// Progress seen from the render's worker threads.
#[derive(Default)]
struct Progress {
    tiles: AtomicU64,
    total: AtomicU64,
}

impl RenderObserver for Progress {
    fn tile_done(&self, done: u64, total: u64) {
        self.tiles.fetch_max(done, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
    }
}

/// Renders `scene` with the command line's settings (`options`, by their Python names).
/// `progress(done, total)` is called from this thread every tenth of a second and at the end;
/// returning `False` cancels. Ctrl-C cancels too (signals are checked while the render runs
/// on other threads, the GIL released).
#[pyfunction]
#[pyo3(signature = (scene, options, progress=None))]
fn render(
    py: Python<'_>,
    scene: &Bound<'_, Scene>,
    options: &Bound<'_, PyDict>,
    progress: Option<PyObject>,
) -> PyResult<Image> {
    let o = self::options(options)?;
    let mut sc = scene.try_borrow_mut()?;
    let mut world_opts = o.world.clone();
    if world_opts.camera_override.is_none() && world_opts.camera.is_none() {
        world_opts.camera_override = sc.camera;
    }
    let job = RenderJob {
        scene: sc.label.clone(),
        world: world_opts.clone(),
        settings: o.settings.clone(),
        given: o.given,
        outputs: Vec::new(),
        split: o.split.clone(),
        aovs: o.aovs.clone(),
        denoise: o.denoise.clone(),
        crop: o.crop,
    };
    job.check().map_err(pipeline_err)?;
    let (mut settings, _) = job.resolve(&sc.scene);
    settings
        .validate()
        .map_err(|e| pipeline_err(PipelineError::Render(e)))?;
    // The denoiser is loaded first: without it, fail before any work (as the command line).
    let denoiser = o
        .denoise
        .as_ref()
        .map(|d| Oidn::load(d.library.as_deref()))
        .transpose()
        .map_err(|e| pipeline_err(e.into()))?;
    // Partial films carry the frame's identity, the digest of the scene as rendered (its
    // variant selected), so that parts from here and from the command line merge.
    let parts = o.split.samples.is_some() || o.split.checkpoint.is_some();
    let digest = if parts {
        let mut scene = sc.scene.clone();
        if let Some(v) = &world_opts.variant {
            scene.select_variant(v).map_err(|e| scene_err(&e))?;
        }
        trayecto::scene::digest::digest(&sc.label, &scene, world_opts.env.as_deref())
            .map_err(|e| scene_err(&e))?
    } else {
        String::new()
    };
    let world = sc.world(&world_opts)?;
    // As the command line: a file's spectral default gives way to RGB for an integrator
    // without a spectral path (the reason is in the command line's log).
    let _ = trayecto::pipeline::rgb_fallback(&o.given, world, &mut settings, &o.aovs);
    let frame = FrameId {
        scene: job.scene.clone(),
        digest,
        settings: settings.clone(),
        world: world_opts,
        light_sampler: world.lights.sampler_kind(),
    };
    let mut traced = trayecto::integrator::aov::traced(&o.aovs);
    // BDPT's strategy layers are rendered by the render stage too (`trace`).
    traced.extend(o.aovs.iter().filter(|k| k.is_strategy()));
    if denoiser.is_some() {
        // The denoiser's guides, traced when not asked for (and not kept).
        for k in [AovKind::Albedo, AovKind::Normal] {
            if !traced.contains(&k) {
                traced.push(k);
            }
        }
    }
    let split = &o.split;
    let observer = Progress::default();
    let cancel = AtomicBool::new(false);
    let mut interrupt: Option<PyErr> = None;
    // The render runs on a thread of its own; this thread waits with the GIL released and,
    // every tenth of a second, runs the signal handlers (Ctrl-C) and the progress callback.
    let done = (std::sync::Mutex::new(None), std::sync::Condvar::new());
    let result = std::thread::scope(|s| {
        let (observer, cancel, frame, traced, done) = (&observer, &cancel, &frame, &traced, &done);
        let handle = s.spawn(move || {
            let r = trace(world, frame, split, traced, observer, cancel);
            *done.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
            done.1.notify_all();
        });
        let report = |py: Python<'_>| -> PyResult<bool> {
            let Some(cb) = &progress else {
                return Ok(true);
            };
            let r = cb.call1(
                py,
                (
                    observer.tiles.load(Ordering::Relaxed),
                    observer.total.load(Ordering::Relaxed),
                ),
            )?;
            let r = r.bind(py);
            Ok(!r.is_instance_of::<PyBool>() || r.extract::<bool>()?)
        };
        loop {
            let got = py.allow_threads(|| {
                let guard = done.0.lock().unwrap_or_else(|e| e.into_inner());
                let (mut guard, _) = done
                    .1
                    .wait_timeout_while(guard, Duration::from_millis(100), |r| r.is_none())
                    .unwrap_or_else(|e| e.into_inner());
                guard.take()
            });
            if let Some(r) = got {
                if interrupt.is_none()
                    && let Err(e) = report(py)
                {
                    interrupt = Some(e);
                }
                return Some(r);
            }
            if handle.is_finished() {
                // It ended without a result: it panicked, which joining the scope re-raises.
                return None;
            }
            if interrupt.is_some() {
                continue;
            }
            match py.check_signals().and_then(|_| report(py)) {
                Ok(true) => {}
                Ok(false) => {
                    interrupt = Some(Cancelled::new_err("render cancelled"));
                    cancel.store(true, Ordering::Relaxed);
                }
                Err(e) => {
                    interrupt = Some(e);
                    cancel.store(true, Ordering::Relaxed);
                }
            }
        }
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    let result = result.ok_or_else(|| RenderError::new_err("the render failed"))?;
    let t = match result.map_err(pipeline_err)? {
        Ok(t) => t,
        Err(outcome) => {
            let kept = match &outcome.checkpoint_written {
                Some(p) => format!(
                    ": the film of {} samples per pixel is saved in {} (resume= it to go on)",
                    outcome.render.done,
                    p.display()
                ),
                None => String::new(),
            };
            return Err(Cancelled::new_err(format!("render cancelled{kept}")));
        }
    };
    let denoised = match &denoiser {
        Some(oidn) => {
            let guide = |k: AovKind| {
                t.layers
                    .iter()
                    .find(|l| l.name == k.name())
                    .and_then(Layer::to_image)
                    .ok_or_else(|| RenderError::new_err("the denoiser's guides were not traced"))
            };
            let (albedo, normal) = (guide(AovKind::Albedo)?, guide(AovKind::Normal)?);
            let threads = settings.threads;
            let image = &t.out.image;
            Some(
                py.allow_threads(|| oidn.denoise(image, &albedo, &normal, threads))
                    .map_err(|e| pipeline_err(e.into()))?,
            )
        }
        None => None,
    };
    let mut layers = t.layers;
    finish_layers(&mut layers, &o.aovs, &settings, &t.part.film);
    let stats = t.out.stats;
    let names = [
        ("integrator", settings.integrator.name()),
        ("sampler", settings.sampler.name()),
        ("shading", o.shading.name()),
        ("accel", o.world.accel.name()),
        ("texture_filter", o.world.texture_filter.name()),
        ("light_sampler", o.world.light_sampler.name()),
        ("filter", settings.filter.kind.name()),
        ("tonemap", o.tonemap.name()),
    ];
    Ok(Image {
        image: t.out.image,
        layers,
        exposure: o.exposure,
        tonemap: o.tonemap,
        samples_done: t.samples_done,
        mean_samples: t.mean_samples,
        render_time: t.out.render_time.as_secs_f64(),
        rays: stats.rays + stats.shadow_rays,
        part: parts.then_some(t.part),
        sample_range: o.split.samples.is_some(),
        denoised,
        names: names.map(|(k, v)| (k, v.to_string())).to_vec(),
        size: (settings.width, settings.height, settings.spp),
        spectral: settings.path.spectral,
    })
}

/// A rendered image: linear RGB (`numpy()`), its AOV layers (`aov(name)`), and the exposure and
/// tone mapping `write()` and Jupyter's display use for 8-bit formats.
#[pyclass(module = "trayecto", frozen)]
struct Image {
    image: trayecto::film::Image,
    layers: Vec<Layer>,
    exposure: f32,
    tonemap: Tonemap,
    samples_done: u32,
    mean_samples: f64,
    render_time: f64,
    rays: u64,
    /// The film and its header when the render wrote or read partial films (`samples`,
    /// `checkpoint`, `resume`): what `write("part.trp")` saves.
    part: Option<Part>,
    /// The render covered a sample range: its image is a partial film's.
    sample_range: bool,
    /// The image denoised by Open Image Denoise (`denoise=True`).
    denoised: Option<trayecto::film::Image>,
    /// The named settings the render used, as the command line spells them.
    names: Vec<(&'static str, String)>,
    /// Width, height and samples per pixel of the frame (after the scene file's own).
    size: (u32, u32, u32),
    /// Rendered spectrally (the keyword's, else the scene file's default where the integrator
    /// has a spectral path).
    spectral: bool,
}

/// numpy's view of memory an [`Image`] owns (`__array_interface__`, version 3): the array keeps
/// the view, and the view the image, alive; read-only, as the image does not change.
#[pyclass(module = "trayecto", frozen)]
struct ArrayView {
    _owner: Py<Image>,
    ptr: usize,
    shape: (usize, usize, usize),
}

#[pymethods]
impl ArrayView {
    #[getter(__array_interface__)]
    fn array_interface<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("version", 3)?;
        d.set_item("shape", self.shape)?;
        d.set_item("typestr", "<f4")?;
        d.set_item("data", (self.ptr, true))?;
        Ok(d)
    }
}

fn view<'py>(
    py: Python<'py>,
    owner: &Bound<'py, Image>,
    data: *const f32,
    shape: (usize, usize, usize),
) -> PyResult<Bound<'py, PyAny>> {
    let v = Bound::new(
        py,
        ArrayView {
            _owner: owner.clone().unbind(),
            ptr: data as usize,
            shape,
        },
    )?;
    py.import("numpy")?.call_method1("asarray", (v,))
}

impl Image {
    fn write_to(
        &self,
        path: PathBuf,
        exposure: Option<f32>,
        tonemap: Option<&str>,
    ) -> PyResult<()> {
        let tonemap = match tonemap {
            Some(t) => t
                .parse::<Tonemap>()
                .map_err(|e| bad(format!("tonemap: {e}")))?,
            None => self.tonemap,
        };
        let partial = trayecto::pipeline::is_partial_film(&path);
        if partial && self.part.is_none() {
            return Err(bad(format!(
                "{}: a partial film is written from a render given samples= (e.g. samples=(0, \
                 spp)) or checkpoint=, which give it the frame's identity",
                path.display()
            )));
        }
        if !partial && self.sample_range {
            // The command line's rule (`RenderJob::check`): a sample range is a part to merge.
            return Err(bad(format!(
                "{}: a partial render (a sample range) writes a partial film: name the output \
                 FILE.trp, then merge the parts",
                path.display()
            )));
        }
        let out = OutputSpec {
            path,
            exposure: exposure.unwrap_or(self.exposure),
            tonemap,
        };
        let layers: &[Layer] = if partial { &[] } else { &self.layers };
        let err = |e: PipelineError| RenderError::new_err(message(&e));
        trayecto::pipeline::write_outputs(
            &self.image,
            self.part.as_ref(),
            std::slice::from_ref(&out),
            layers,
        )
        .map_err(err)?;
        if let Some(d) = &self.denoised {
            trayecto::pipeline::write_denoised(d, &[out]).map_err(err)?;
        }
        Ok(())
    }
}

#[pymethods]
impl Image {
    #[getter]
    fn width(&self) -> u32 {
        self.image.width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.image.height
    }

    /// The AOV layers rendered with the image (`aovs=`), by name.
    #[getter]
    fn aovs(&self) -> Vec<String> {
        self.layers.iter().map(|l| l.name.clone()).collect()
    }

    /// Render statistics: samples per pixel of the last pass, the mean taken, seconds, rays.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("samples_done", self.samples_done)?;
        d.set_item("mean_samples", self.mean_samples)?;
        d.set_item("render_time", self.render_time)?;
        d.set_item("rays", self.rays)?;
        Ok(d)
    }

    /// The linear RGB image as a float32 numpy array of shape (height, width, 3), sharing the
    /// image's memory (read-only: `.copy()` to change it).
    fn numpy<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let me = slf.get();
        let shape = (me.image.height as usize, me.image.width as usize, 3);
        // `Vec3` is three packed f32 (glam's `#[repr(C)]` layout), so the pixels are row-major
        // RGB floats.
        view(slf.py(), slf, me.image.data.as_ptr().cast(), shape)
    }

    /// The image denoised by Open Image Denoise (a render with `denoise=True`), as `numpy()`.
    fn denoised<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        let me = slf.get();
        let d = me.denoised.as_ref().ok_or_else(|| {
            PyKeyError::new_err("this image was not denoised: render with denoise=True")
        })?;
        let shape = (d.height as usize, d.width as usize, 3);
        view(slf.py(), slf, d.data.as_ptr().cast(), shape)
    }

    /// The settings the render used, by their keyword names: the named choices as the command
    /// line spells them (`sampler`, `accel`, `integrator`, ...) and the frame's `width`,
    /// `height` and `spp` (after the scene file's own).
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in &self.names {
            d.set_item(k, v)?;
        }
        d.set_item("width", self.size.0)?;
        d.set_item("height", self.size.1)?;
        d.set_item("spp", self.size.2)?;
        d.set_item("spectral", self.spectral)?;
        Ok(d)
    }

    /// An AOV layer as a float32 array (height, width, channels), sharing the image's memory.
    fn aov<'py>(slf: &Bound<'py, Self>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let me = slf.get();
        let l = me.layers.iter().find(|l| l.name == name).ok_or_else(|| {
            PyKeyError::new_err(format!(
                "no AOV '{name}' in this image (it has: {}); render with aovs=['{name}']",
                me.aovs().join(", ")
            ))
        })?;
        let (w, h) = (l.width as usize, l.height as usize);
        let c = l.data.len() / (w * h).max(1);
        view(slf.py(), slf, l.data.as_ptr(), (h, w, c))
    }

    /// Writes the image; the format follows the extension (.png, .ppm, .exr, .hdr), AOVs go
    /// into an .exr as layers, else beside it (`out.albedo.png`), as the command line writes
    /// them. `exposure` and `tonemap` default to the render's.
    #[pyo3(signature = (path, exposure=None, tonemap=None))]
    fn write(
        &self,
        py: Python<'_>,
        path: PathBuf,
        exposure: Option<f32>,
        tonemap: Option<&str>,
    ) -> PyResult<()> {
        py.allow_threads(|| self.write_to(path, exposure, tonemap))
    }

    /// PNG bytes for Jupyter, with the render's exposure and tone mapping.
    fn _repr_png_(&self) -> PyResult<Vec<u8>> {
        let dir = std::env::temp_dir().join(format!(
            "trayecto-png-{}-{:p}",
            std::process::id(),
            self as *const Self
        ));
        std::fs::create_dir_all(&dir).map_err(|e| RenderError::new_err(e.to_string()))?;
        let path = dir.join("image.png");
        let out = OutputSpec {
            path: path.clone(),
            exposure: self.exposure,
            tonemap: self.tonemap,
        };
        let r = trayecto::pipeline::write_outputs(&self.image, None, &[out], &[])
            .map_err(|e| RenderError::new_err(message(&e)))
            .and_then(|_| std::fs::read(&path).map_err(|e| RenderError::new_err(e.to_string())));
        let _ = std::fs::remove_dir_all(&dir);
        r
    }

    fn __repr__(&self) -> String {
        format!(
            "<trayecto.Image {}x{}, {} spp, AOVs [{}]>",
            self.image.width,
            self.image.height,
            self.samples_done,
            self.aovs().join(", ")
        )
    }
}

/// The built-in scene names `load_file` accepts.
#[pyfunction]
fn builtin_scenes() -> Vec<&'static str> {
    trayecto::scene::builtin::NAMES.to_vec()
}

#[pymodule]
fn _trayecto(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("RenderError", py.get_type::<RenderError>())?;
    m.add("Cancelled", py.get_type::<Cancelled>())?;
    m.add("RENDER_IDENTITY", trayecto::RENDER_IDENTITY)?;
    m.add_class::<Scene>()?;
    m.add_class::<Image>()?;
    m.add_function(wrap_pyfunction!(defaults, m)?)?;
    m.add_function(wrap_pyfunction!(choices, m)?)?;
    m.add_function(wrap_pyfunction!(load_file, m)?)?;
    m.add_function(wrap_pyfunction!(load_dict, m)?)?;
    m.add_function(wrap_pyfunction!(to_toml_text, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_scenes, m)?)?;
    Ok(())
}
