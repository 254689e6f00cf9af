//! What a client may ask for, checked field by field before any work starts (docs/DESIGN.md §7): the scene
//! is a built-in name or a file that canonicalises to a path inside the scenes folder, the output
//! name is a plain file name, and every number is inside both the renderer's limits
//! (`RenderSettings::validate`) and the server's own, tighter caps.

use super::folder::{MAX_SCENE_NAME, resolve_env, resolve_scene};
use crate::film::filter::{Filter, FilterKind};
use crate::film::tonemap::Tonemap;
use crate::integrator::{IntegratorKind, PathSettings};
use crate::light::default_light::DefaultLight;
use crate::render::{MAX_DEPTH, MAX_SECONDARY, RenderSettings};
use crate::sampling::SamplerKind;
use crate::scene::builtin;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::str::FromStr;

/// Integrator and tone-mapping names offered to the page; only those the library parses are
/// shown, so new modes appear by themselves when they land.
const INTEGRATOR_NAMES: &[&str] = &[
    "path",
    "whitted",
    "raycast",
    "lighttracer",
    "bdpt",
    "sppm",
    "vcm",
    "mlt",
];
const TONEMAP_NAMES: &[&str] = &["pbr-neutral", "agx", "clamp", "gamma2.2", "aces"];
pub const MAX_OUTPUT_NAME: usize = 64;

/// The server's caps, tighter than the renderer's (a public page should not accept a week of work).
#[derive(Clone, Debug)]
pub struct Limits {
    pub max_size: u32,
    pub max_spp: u32,
    pub max_secondary: u32,
    pub max_depth: u32,
    /// Upper bound on width × height × spp × secondary.
    pub max_samples: u64,
    pub max_jobs: usize,
    /// Renders that may wait for a slot.
    pub max_queue: usize,
    pub max_body: usize,
    pub upload: super::upload::UploadLimits,
    /// Memory all scene loads together may take (`--memory-total`), and one of them
    /// (`--memory-limit`), in bytes (`trayecto::limits`).
    pub memory_total: u64,
    pub memory_per_job: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_size: 4096,
            max_spp: 16384,
            max_secondary: 64.min(MAX_SECONDARY),
            max_depth: MAX_DEPTH,
            max_samples: 1 << 34,
            max_jobs: 2,
            max_queue: 16,
            max_body: 16 * 1024,
            upload: Default::default(),
            memory_total: crate::limits::default_limit(),
            memory_per_job: crate::limits::default_limit(),
        }
    }
}

pub fn integrator_names() -> Vec<&'static str> {
    INTEGRATOR_NAMES
        .iter()
        .copied()
        .filter(|n| IntegratorKind::from_str(n).is_ok())
        .collect()
}

pub fn tonemap_names() -> Vec<&'static str> {
    TONEMAP_NAMES
        .iter()
        .copied()
        .filter(|n| Tonemap::from_str(n).is_ok())
        .collect()
}

/// The `default_light` values a request may give (absent or null: as the scene file says).
pub const DEFAULT_LIGHT_NAMES: [&str; 4] = ["auto", "on", "off", "uniform"];

/// Where the scene comes from once resolved.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneSource {
    Builtin(String),
    /// A canonical path inside the scenes folder.
    File(PathBuf),
}

impl SceneSource {
    /// The argument for `scene::load`.
    pub fn load_spec(&self) -> String {
        match self {
            SceneSource::Builtin(n) => n.clone(),
            SceneSource::File(p) => p.to_string_lossy().into_owned(),
        }
    }
}

/// A checked render request.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    /// The scene as the client named it.
    pub scene: String,
    pub source: SceneSource,
    /// Base name of the output files (`<output>.png`, `<output>.exr`). When the request gave
    /// none ([`RenderRequest::output_given`]), the job queue picks a free `render-ID`.
    pub output: String,
    /// Whether the request named its output (else [`Defaults::OUTPUT`] is only a placeholder).
    pub output_given: bool,
    pub settings: RenderSettings,
    pub exposure: f32,
    pub tonemap: Tonemap,
    /// `None`: as the scene file says (else auto).
    pub default_light: Option<DefaultLight>,
    /// Also write the image denoised by Open Image Denoise (`<output>.denoised.png`/`.exr`).
    pub denoise: bool,
    /// Whether the request named a filter (else the scene file's, e.g. a pbrt PixelFilter).
    pub filter_given: bool,
    /// Whether the request said spectral or RGB (`spectral` true or false, `settings.path`);
    /// absent or null: the scene file's default (pbrt files spectral, as `--spectral`/`--rgb`
    /// left out on the command line).
    pub spectral_given: bool,
    /// Whether the request said `guiding` true or false (`settings.guiding`); absent or null:
    /// the scene file's (TOML `[render] guiding`), else off.
    pub guiding_given: bool,
    /// `crop`: fractions [x0, x1, y0, y1] of the image (pbrt's cropwindow).
    pub crop: Option<crate::pipeline::CropSpec>,
    /// glTF material variant (`KHR_materials_variants`); `None`: the file's default materials.
    pub variant: Option<String>,
    /// An environment map from the scenes folder lighting the scene (canonical path), and its
    /// name as the client gave it.
    pub environment: Option<(String, PathBuf)>,
    /// `env_rotation`: the environment map turned about +y, in degrees.
    pub env_rotation: f32,
    /// `camera`: render from this view (the viewport's) instead of the scene's camera.
    pub camera: Option<crate::camera::CameraSpec>,
    /// `aovs`: layers written into the EXR with the image (`albedo`, `normal`, which the page
    /// can show; `samples`, `variance`, the film's per-pixel statistics).
    pub aovs: Vec<crate::film::aov::AovKind>,
    /// The canonical scenes folder the request was checked against, which the job's log and
    /// errors never show ([`RenderRequest::relative_paths`]).
    pub scenes_dir: Option<PathBuf>,
    /// `time`, `frame`, `fps`, `shutter`: the moment rendered and the motion blur.
    pub time: crate::world::motion::TimeOptions,
    /// `frames`: a sequence, first and last frame (inclusive), written as `<output>_NNNN.png`
    /// and `.exr` (`pipeline::frame_path`).
    pub frames: Option<(u32, u32)>,
}

impl RenderRequest {
    /// `text` (a log line, an error) with the scene file named as the client named it and every
    /// other path inside the scenes folder relative to it: the page and the API never reveal
    /// where the server keeps its scenes.
    pub fn relative_paths(&self, text: &str) -> String {
        let mut t = text.to_string();
        if let SceneSource::File(p) = &self.source {
            t = t.replace(&*p.to_string_lossy(), &self.scene);
        }
        if let Some(root) = &self.scenes_dir {
            let root = root.to_string_lossy();
            t = t.replace(&format!("{root}{}", std::path::MAIN_SEPARATOR), "");
            t = t.replace(&*root, ".");
        }
        t
    }
}

/// AOV layers a request may ask for (albedo and normal: the page's view toggle).
pub const AOV_NAMES: [&str; 4] = ["albedo", "normal", "samples", "variance"];

/// The `camera` field: `{"eye": [x, y, z], "target": [x, y, z], "up": [x, y, z], "fov": degrees}`
/// (`up` defaults to +y, `fov` to 39.6), checked by [`crate::camera::CameraSpec::validate`].
pub fn camera_field(v: &Value) -> Result<crate::camera::CameraSpec, String> {
    use crate::camera::CameraSpec;
    let Value::Object(o) = v else {
        return Err("must be an object {eye, target, up, fov}".into());
    };
    if let Some(k) = o
        .keys()
        .find(|k| !["eye", "target", "up", "fov"].contains(&k.as_str()))
    {
        let shown: String = k.chars().take(40).collect();
        return Err(format!(
            "unknown key '{shown}' (known: eye, target, up, fov)"
        ));
    }
    let vec3 = |key: &str, default: Option<[f32; 3]>| -> Result<crate::math::Vec3, String> {
        match o.get(key) {
            None | Some(Value::Null) => default
                .map(crate::math::Vec3::from)
                .ok_or_else(|| format!("{key} is missing (three numbers)")),
            Some(Value::Array(a)) if a.len() == 3 => {
                let mut out = [0f32; 3];
                for (x, v) in out.iter_mut().zip(a) {
                    *x = v
                        .as_f64()
                        .ok_or_else(|| format!("{key} must be three numbers"))?
                        as f32;
                }
                Ok(out.into())
            }
            Some(_) => Err(format!("{key} must be three numbers")),
        }
    };
    let fov = match o.get("fov") {
        None | Some(Value::Null) => CameraSpec::DEFAULT_FOV,
        Some(v) => v
            .as_f64()
            .ok_or_else(|| "fov must be a number (degrees)".to_string())? as f32,
    };
    let spec = CameraSpec {
        eye: vec3("eye", None)?,
        target: vec3("target", None)?,
        up: vec3("up", Some([0.0, 1.0, 0.0]))?,
        fov,
    };
    spec.validate()?;
    Ok(spec)
}

/// Longest time limit a request may ask for, in seconds.
pub const MAX_TIME_LIMIT: f64 = 24.0 * 3600.0;

/// A switch: `true` or `false`, off when absent or null; anything else is an error naming `key`.
fn bool_field(v: Option<&Value>, key: &str, errors: &mut BTreeMap<String, String>) -> bool {
    match v {
        None | Some(Value::Null) => false,
        Some(Value::Bool(b)) => *b,
        Some(_) => {
            errors.insert(key.into(), "must be true or false".into());
            false
        }
    }
}

/// A true/false field whose absence (or null) means "the scene file's": `None` then.
fn optional_bool_field(
    v: Option<&Value>,
    key: &str,
    errors: &mut BTreeMap<String, String>,
) -> Option<bool> {
    match v {
        None | Some(Value::Null) => None,
        v => Some(bool_field(v, key, errors)),
    }
}

/// A positive number field at most `max` (`None` when absent or null).
fn positive_field(
    v: Option<&Value>,
    key: &str,
    max: f64,
    errors: &mut BTreeMap<String, String>,
) -> Option<f64> {
    match v {
        None | Some(Value::Null) => None,
        Some(Value::Number(n)) => match n.as_f64() {
            Some(x) if x.is_finite() && x > 0.0 && x <= max => Some(x),
            _ => {
                errors.insert(
                    key.into(),
                    format!("must be a number above 0 and at most {max}"),
                );
                None
            }
        },
        Some(_) => {
            errors.insert(
                key.into(),
                format!("must be a number above 0 and at most {max}"),
            );
            None
        }
    }
}

/// Why a request was refused: the body is not a JSON object, or some fields are wrong (field →
/// message, shown beside the field by the page).
#[derive(Debug, PartialEq)]
pub enum RequestError {
    Malformed(String),
    Fields(BTreeMap<String, String>),
}

/// Canonical scene and output folders plus the caps: everything requests are checked against.
#[derive(Clone, Debug)]
pub struct Policy {
    pub scenes_dir: Option<PathBuf>,
    pub output_dir: PathBuf,
    pub limits: Limits,
    pub threads: Option<usize>,
}

/// A plain output file name: letters, digits, '-', '_' and '.', not starting with '.', at most
/// [`MAX_OUTPUT_NAME`] characters. A trailing `.png`/`.exr` is dropped (both are written).
pub fn sanitize_output(name: &str) -> Result<String, String> {
    let mut n = name.trim();
    for ext in [".png", ".exr"] {
        if n.len() > ext.len() && n.to_ascii_lowercase().ends_with(ext) {
            n = &n[..n.len() - ext.len()];
        }
    }
    if n.is_empty() {
        return Err("give an output name".into());
    }
    if n.chars().count() > MAX_OUTPUT_NAME {
        return Err(format!("must be at most {MAX_OUTPUT_NAME} characters"));
    }
    if n.starts_with('.')
        || !n
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
    {
        return Err(
            "must be a plain file name: letters, digits, '-', '_' and '.', not starting with '.'"
                .into(),
        );
    }
    Ok(n.to_string())
}

/// Reads an optional whole number in `lo..=hi`.
fn uint_field(
    v: Option<&Value>,
    key: &str,
    default: u64,
    lo: u64,
    hi: u64,
    errors: &mut BTreeMap<String, String>,
) -> u64 {
    let range = || format!("must be a whole number from {lo} to {hi}");
    match v {
        None | Some(Value::Null) => default,
        Some(Value::Number(n)) => match n.as_u64() {
            Some(v) if (lo..=hi).contains(&v) => v,
            _ => {
                errors.insert(key.into(), range());
                default
            }
        },
        Some(_) => {
            errors.insert(key.into(), range());
            default
        }
    }
}

fn string_field<'a>(
    v: Option<&'a Value>,
    key: &str,
    max_len: usize,
    errors: &mut BTreeMap<String, String>,
) -> Option<&'a str> {
    match v {
        None | Some(Value::Null) => None,
        Some(Value::String(s)) if s.len() <= max_len => Some(s.as_str()),
        Some(Value::String(_)) => {
            errors.insert(key.into(), format!("is too long (at most {max_len} bytes)"));
            None
        }
        Some(_) => {
            errors.insert(key.into(), "must be a string".into());
            None
        }
    }
}

/// The defaults the page starts with (and that apply to fields a client leaves out).
pub struct Defaults;
impl Defaults {
    /// The size when the scene gives none: the command line's (a request without a size gets
    /// the CLI's rule, [`default_size`]).
    pub const WIDTH: u64 = 512;
    pub const HEIGHT: u64 = 512;
    /// The command line's samples and bounce limit: the page and the CLI render alike.
    pub const SPP: u64 = crate::render::DEFAULT_SPP as u64;
    pub const SECONDARY: u64 = 1;
    pub const MAX_DEPTH: u64 = crate::integrator::settings::DEFAULT_MAX_DEPTH as u64;
    pub const EXPOSURE: f64 = 1.0;
    /// The prefix of the output name a request without one gets: `render-ID` (the job's id).
    pub const OUTPUT: &str = "render";
}

/// Resolves a scene name the page sent: a built-in or a file inside the scenes folder.
pub fn scene_source(name: &str, policy: &Policy) -> Result<SceneSource, String> {
    if builtin::NAMES.contains(&name) {
        return Ok(SceneSource::Builtin(name.to_string()));
    }
    match &policy.scenes_dir {
        None => Err(format!(
            "unknown scene (built-ins: {}; start the server with --scenes DIR for files)",
            builtin::NAMES.join(", ")
        )),
        Some(root) => resolve_scene(root, name).map(SceneSource::File),
    }
}

/// The settings a render of `scene` resolves to by the command line's rule
/// ([`crate::pipeline::RenderJob::resolve`]: the sides given, else the file's resolution,
/// else the camera's shape at [`crate::pipeline::DEFAULT_HEIGHT`] high, else
/// [`Defaults::WIDTH`]²), with the server's default samples and depth where the file has none,
/// and the note saying where the size came from.
fn resolved_settings(
    name: &str,
    scene: &crate::scene::Scene,
    width: Option<u32>,
    height: Option<u32>,
    camera: Option<crate::camera::CameraSpec>,
) -> (RenderSettings, Option<String>) {
    let job = crate::pipeline::RenderJob {
        scene: name.to_string(),
        world: crate::world::WorldOptions {
            camera_override: camera,
            ..crate::world::WorldOptions::default()
        },
        settings: RenderSettings {
            width: width.unwrap_or(Defaults::WIDTH as u32),
            height: height.unwrap_or(Defaults::HEIGHT as u32),
            spp: Defaults::SPP as u32,
            path: PathSettings {
                max_depth: Defaults::MAX_DEPTH as u32,
                ..PathSettings::default()
            },
            ..RenderSettings::default()
        },
        given: crate::pipeline::GivenSettings {
            width: width.is_some(),
            height: height.is_some(),
            spp: false,
            max_depth: false,
            filter: false,
            integrator: false,
            spectral: false,
            guiding: false,
        },
        split: Default::default(),
        aovs: Vec::new(),
        denoise: None,
        outputs: vec![],
        crop: None,
    };
    job.resolve(scene)
}

/// Loads the scene a request names, with the error message naming it as the client did.
fn load_scene(name: &str, source: &SceneSource) -> Result<crate::scene::Scene, String> {
    crate::scene::load(&source.load_spec()).map_err(|e| {
        let m = e.to_string();
        match source {
            SceneSource::File(p) => m.replace(&*p.to_string_lossy(), name),
            SceneSource::Builtin(_) => m,
        }
    })
}

/// Scales a size down (keeping its shape) to fit `max_size` on its longer side.
fn fit(w: u32, h: u32, max_size: u32) -> (u32, u32) {
    let (w, h) = (w as f64, h as f64);
    let scale = (max_size as f64 / w.max(h)).min(1.0);
    (
        (w * scale).round().max(1.0) as u32,
        (h * scale).round().max(1.0) as u32,
    )
}

/// The image size of a request that left out its width or height: the command line's rule
/// ([`resolved_settings`]) for the scene (loaded here), fitted to the server's `max_size` when
/// neither side was given. With one side given, the other follows the file's or the camera's
/// aspect ratio and must fit `max_size` itself (else the error names the side to give).
pub fn default_size(
    name: &str,
    source: &SceneSource,
    width: Option<u32>,
    height: Option<u32>,
    camera: Option<crate::camera::CameraSpec>,
    max_size: u32,
) -> Result<(u32, u32), (&'static str, String)> {
    let scene = load_scene(name, source).map_err(|m| ("scene", m))?;
    let (s, _) = resolved_settings(name, &scene, width, height, camera);
    match (width, height) {
        (None, None) => Ok(fit(s.width, s.height, max_size)),
        _ => {
            let (side, v) = if width.is_none() {
                ("width", s.width)
            } else {
                ("height", s.height)
            };
            if v > max_size {
                return Err((
                    side,
                    format!(
                        "the scene's aspect ratio makes it {v}, over this server's {max_size}: give it"
                    ),
                ));
            }
            Ok((s.width, s.height))
        }
    }
}

/// What a render of `name` gets when its size, samples and depth are not given: the file's own
/// resolution, else its camera's shape (the pipeline's rule, [`crate::pipeline::RenderJob::resolve`]),
/// scaled down to fit the server's `max_size`. Loads the scene.
pub fn scene_defaults(name: &str, policy: &Policy) -> Result<Value, String> {
    let source = scene_source(name, policy)?;
    let scene = load_scene(name, &source)?;
    let (s, note) = resolved_settings(name, &scene, None, None, None);
    let l = &policy.limits;
    let (w, h) = fit(s.width, s.height, l.max_size);
    Ok(serde_json::json!({
        "width": w,
        "height": h,
        "spp": s.spp.min(l.max_spp),
        "max_depth": s.path.max_depth.min(l.max_depth),
        "note": note,
        // glTF KHR_materials_variants (also of glTF files a TOML scene includes): the names the
        // request's `variant` field accepts; none is the file's default materials.
        "variants": scene.variants,
    }))
}

/// The fields a request may have, in the order the unknown-field message lists them.
const KNOWN_FIELDS: [&str; 30] = [
    "scene",
    "output",
    "width",
    "height",
    "spp",
    "secondary",
    "max_depth",
    "exposure",
    "integrator",
    "tonemap",
    "seed",
    "default_light",
    "filter",
    "noise_threshold",
    "time_limit",
    "crop",
    "denoise",
    "variant",
    "environment",
    "env_rotation",
    "camera",
    "aovs",
    "guiding",
    "transparent",
    "time",
    "spectral",
    "frame",
    "frames",
    "fps",
    "shutter",
];

/// A request body as sent. Every field is optional (absent and `null` alike) and kept as JSON,
/// not typed: a typed field would fail the whole body on serde's first error, and the page
/// shows a message per bad field. The checks below turn it into a [`RenderRequest`].
#[derive(Debug, Default, serde::Deserialize)]
#[serde(default)]
pub struct RequestBody {
    pub scene: Option<Value>,
    pub output: Option<Value>,
    pub width: Option<Value>,
    pub height: Option<Value>,
    pub spp: Option<Value>,
    pub secondary: Option<Value>,
    pub max_depth: Option<Value>,
    pub exposure: Option<Value>,
    pub integrator: Option<Value>,
    pub tonemap: Option<Value>,
    pub seed: Option<Value>,
    pub default_light: Option<Value>,
    pub filter: Option<Value>,
    pub noise_threshold: Option<Value>,
    pub time_limit: Option<Value>,
    pub crop: Option<Value>,
    pub denoise: Option<Value>,
    pub variant: Option<Value>,
    pub environment: Option<Value>,
    pub env_rotation: Option<Value>,
    pub camera: Option<Value>,
    pub aovs: Option<Value>,
    /// Path guiding (`--guiding`): true or false.
    pub guiding: Option<Value>,
    /// A transparent background (`--transparent`): true or false.
    pub transparent: Option<Value>,
    /// Spectral rendering: true (`--spectral`), false (`--rgb`) or null/absent (the scene
    /// file's default: pbrt files spectral).
    pub spectral: Option<Value>,
    /// The moment of an animated scene (`--time`): seconds.
    pub time: Option<Value>,
    /// The frame of an animated scene (`--frame`): a whole number, time `frame / fps`.
    pub frame: Option<Value>,
    /// A sequence (`--frames A..B`): `[A, B]`, inclusive; each frame's images are their own files.
    pub frames: Option<Value>,
    /// Frames per second for `frame`/`frames` (`--fps`); the file's rate, else 24.
    pub fps: Option<Value>,
    /// Motion blur (`--shutter OPEN,CLOSE`): `[open, close]` in seconds after the moment.
    pub shutter: Option<Value>,
    /// Anything else, refused by name.
    #[serde(flatten)]
    pub unknown: BTreeMap<String, Value>,
}

impl RequestBody {
    /// Parses a body that must be a JSON object.
    pub fn from_json(body: &[u8]) -> Result<RequestBody, RequestError> {
        let value: Value = serde_json::from_slice(body)
            .map_err(|e| RequestError::Malformed(format!("the body is not valid JSON: {e}")))?;
        if !value.is_object() {
            return Err(RequestError::Malformed(
                "the body must be a JSON object".into(),
            ));
        }
        // Every field is untyped JSON, so an object always fits.
        serde_json::from_value(value)
            .map_err(|e| RequestError::Malformed(format!("the body is not valid JSON: {e}")))
    }
}

/// Per-field messages, as the page shows them.
type Errors = BTreeMap<String, String>;

/// The numbers of a request: image size, samples, depth, seed.
struct Numbers {
    width: u32,
    height: u32,
    width_given: bool,
    height_given: bool,
    spp: u32,
    secondary: u32,
    max_depth: u32,
    seed: u64,
}

/// The image and integrator options of a request.
struct Options {
    exposure: f32,
    integrator: IntegratorKind,
    tonemap: Tonemap,
    default_light: Option<DefaultLight>,
    variant: Option<String>,
    filter: Option<Filter>,
    noise_threshold: Option<f32>,
    time_limit: Option<f64>,
    crop: Option<crate::pipeline::CropSpec>,
    denoise: bool,
    /// `None`: the scene file's setting.
    guiding: Option<bool>,
    transparent: bool,
    /// `None`: the scene file's default.
    spectral: Option<bool>,
}

/// Parses and checks a JSON render request ([`RequestBody`]). Every wrong field is reported, not
/// only the first ([`RequestError::Fields`]).
pub fn parse_request(body: &[u8], policy: &Policy) -> Result<RenderRequest, RequestError> {
    let b = RequestBody::from_json(body)?;
    let lim = &policy.limits;
    let mut errors = Errors::new();
    for k in b.unknown.keys() {
        let shown: String = k.chars().take(40).collect();
        errors.insert(
            "request".into(),
            format!(
                "unknown field '{shown}' (known: {})",
                KNOWN_FIELDS.join(", ")
            ),
        );
    }
    let scene_name = string_field(b.scene.as_ref(), "scene", MAX_SCENE_NAME, &mut errors);
    let source = check_scene(scene_name, policy, &mut errors);
    let output_given = !matches!(b.output, None | Some(Value::Null));
    let output = check_output(&b, &mut errors);
    let mut n = check_numbers(&b, lim, &mut errors);
    let o = check_options(&b, &mut errors);
    let (environment, env_rotation) = check_environment(&b, policy, &mut errors);
    let camera = match &b.camera {
        None | Some(Value::Null) => None,
        Some(v) => match camera_field(v) {
            Ok(c) => Some(c),
            Err(m) => {
                errors.insert("camera".into(), m);
                None
            }
        },
    };
    let (time, frames) = check_time(&b, &mut errors);
    let mut aovs = check_aovs(b.aovs.as_ref(), &mut errors);
    // As `--transparent`: the coverage is the alpha AOV, the path tracer leaves the
    // background out (docs/DESIGN.md §5, "Transparent film").
    // As `--spectral`: the path tracers, the light tracer, BDPT, MLT, SPPM and VCM carry
    // wavelengths, the other integrators (raycast, Whitted) refuse them.
    if o.spectral == Some(true) && !o.integrator.carries_wavelengths() {
        errors.insert(
            "spectral".into(),
            "needs the path integrator, the light tracer, BDPT, MLT or SPPM".into(),
        );
    }
    if o.transparent {
        if o.integrator != IntegratorKind::Path {
            errors.insert("transparent".into(), "needs the path integrator".into());
        }
        if !aovs.contains(&crate::film::aov::AovKind::Alpha) {
            aovs.push(crate::film::aov::AovKind::Alpha);
        }
    }

    // A size left out follows the command line's rule for the scene (its file's resolution or
    // its camera's shape), as /api/scene-defaults reports it; this loads the scene.
    if (!n.width_given || !n.height_given)
        && errors.is_empty()
        && let (Some(name), Some(src)) = (scene_name, &source)
    {
        match default_size(
            name,
            src,
            n.width_given.then_some(n.width),
            n.height_given.then_some(n.height),
            camera,
            lim.max_size,
        ) {
            Ok((w, h)) => (n.width, n.height) = (w, h),
            Err((field, m)) => {
                errors.insert(field.into(), m);
            }
        }
    }

    let samples = n.width as u64 * n.height as u64 * n.spp as u64 * n.secondary as u64;
    let frame_count = frames.map_or(1, |(a, b)| u64::from(b - a) + 1);
    if !errors.contains_key("spp") && samples > lim.max_samples {
        errors.insert(
            "spp".into(),
            format!(
                "width × height × samples × secondary rays = {samples} is over this server's budget of {}",
                lim.max_samples
            ),
        );
    } else if !errors.contains_key("frames")
        && samples.saturating_mul(frame_count) > lim.max_samples
    {
        errors.insert(
            "frames".into(),
            format!(
                "{frame_count} frames × {samples} samples each is over this server's budget of {}",
                lim.max_samples
            ),
        );
    }

    let settings = RenderSettings {
        width: n.width,
        height: n.height,
        spp: n.spp,
        seed: n.seed,
        threads: policy.threads,
        sampler: SamplerKind::default(),
        integrator: o.integrator,
        path: PathSettings {
            max_depth: n.max_depth,
            secondary: n.secondary,
            transparent: o.transparent,
            spectral: o.spectral.unwrap_or(false),
            ..PathSettings::default()
        },
        filter: o.filter.unwrap_or_default(),
        noise_threshold: o.noise_threshold,
        time_limit: o.time_limit,
        crop: None,
        // Set by the pipeline when the variance AOV is asked for.
        track_variance: false,
        // Set by the pipeline when the alpha AOV is asked for.
        track_coverage: false,
        guiding: o.guiding.unwrap_or(false),
        photon: Default::default(),
        mlt: Default::default(),
    };
    if errors.is_empty()
        && let Err(e) = settings.validate()
    {
        errors.insert("request".into(), e.to_string());
    }
    match (errors.is_empty(), source, output) {
        (true, Some(source), Some(output)) => Ok(RenderRequest {
            scene: scene_name.unwrap_or_default().to_string(),
            source,
            output,
            output_given,
            settings,
            exposure: o.exposure,
            tonemap: o.tonemap,
            default_light: o.default_light,
            filter_given: o.filter.is_some(),
            spectral_given: o.spectral.is_some(),
            guiding_given: o.guiding.is_some(),
            crop: o.crop,
            denoise: o.denoise,
            variant: o.variant,
            environment,
            env_rotation,
            camera,
            aovs,
            scenes_dir: policy.scenes_dir.clone(),
            time,
            frames,
        }),
        _ => Err(RequestError::Fields(errors)),
    }
}

/// The most frames one request may render (`frames`).
pub const MAX_FRAMES: u32 = 10_000;
/// The largest scene time, frame rate or shutter time a request may give, in seconds (or frames
/// per second).
const MAX_TIME: f64 = 1e6;

/// `time`, `frame`, `frames`, `fps` and `shutter`: the moment of an animated scene, a sequence
/// and the motion blur, checked as the command line's `--time`, `--frame`, `--frames`, `--fps`
/// and `--shutter` are (`TimeOptions::validate`).
fn check_time(
    b: &RequestBody,
    errors: &mut Errors,
) -> (crate::world::motion::TimeOptions, Option<(u32, u32)>) {
    let mut t = crate::world::motion::TimeOptions::default();
    let number = |v: &Value| v.as_f64().filter(|x| x.is_finite() && x.abs() <= MAX_TIME);
    let whole = |v: &Value| {
        v.as_u64()
            .filter(|&x| x <= u64::from(u32::MAX))
            .map(|x| x as u32)
    };
    match &b.time {
        None | Some(Value::Null) => {}
        Some(v) => match number(v) {
            Some(x) => t.time = Some(x),
            None => {
                errors.insert(
                    "time".into(),
                    format!("must be a number of seconds (at most {MAX_TIME} either way)"),
                );
            }
        },
    }
    match &b.frame {
        None | Some(Value::Null) => {}
        Some(v) => match whole(v) {
            Some(f) => t.frame = Some(f),
            None => {
                errors.insert("frame".into(), "must be a whole number from 0".into());
            }
        },
    }
    let frames = match &b.frames {
        None | Some(Value::Null) => None,
        Some(Value::Array(a)) if a.len() == 2 => match (whole(&a[0]), whole(&a[1])) {
            (Some(first), Some(last)) if first <= last && last - first < MAX_FRAMES => {
                Some((first, last))
            }
            _ => {
                errors.insert(
                    "frames".into(),
                    format!(
                        "must be [first, last]: whole numbers from 0, first <= last, at most \
                         {MAX_FRAMES} frames"
                    ),
                );
                None
            }
        },
        Some(_) => {
            errors.insert(
                "frames".into(),
                "must be [first, last] (two whole numbers)".into(),
            );
            None
        }
    };
    match &b.fps {
        None | Some(Value::Null) => {}
        Some(v) => match number(v).filter(|&x| x > 0.0) {
            Some(x) => t.fps = Some(x),
            None => {
                errors.insert(
                    "fps".into(),
                    format!("must be a positive number (at most {MAX_TIME})"),
                );
            }
        },
    }
    match &b.shutter {
        None | Some(Value::Null) => {}
        Some(Value::Array(a)) if a.len() == 2 => match (number(&a[0]), number(&a[1])) {
            (Some(open), Some(close)) if open <= close => t.shutter = Some([open, close]),
            _ => {
                errors.insert(
                    "shutter".into(),
                    "must be [open, close] in seconds with open <= close".into(),
                );
            }
        },
        Some(_) => {
            errors.insert(
                "shutter".into(),
                "must be [open, close] (two numbers of seconds)".into(),
            );
        }
    }
    // One moment: a time, a frame or a sequence.
    let given: Vec<&str> = [
        ("time", t.time.is_some()),
        ("frame", t.frame.is_some()),
        ("frames", frames.is_some()),
    ]
    .iter()
    .filter(|(_, g)| *g)
    .map(|(k, _)| *k)
    .collect();
    if given.len() > 1 {
        errors.insert(
            given[1].into(),
            format!("{} both give the moment: use one", given.join(" and ")),
        );
    }
    (t, frames)
}

/// `scene`: a built-in name, or a file inside the scenes folder.
fn check_scene(name: Option<&str>, policy: &Policy, errors: &mut Errors) -> Option<SceneSource> {
    match name {
        None => {
            errors
                .entry("scene".into())
                .or_insert_with(|| "choose a scene".into());
            None
        }
        Some(name) if builtin::NAMES.contains(&name) => {
            Some(SceneSource::Builtin(name.to_string()))
        }
        Some(name) => match &policy.scenes_dir {
            None => {
                errors.insert(
                    "scene".into(),
                    format!(
                        "unknown scene (built-ins: {}; start the server with --scenes DIR for files)",
                        builtin::NAMES.join(", ")
                    ),
                );
                None
            }
            Some(root) => match resolve_scene(root, name) {
                Ok(p) => Some(SceneSource::File(p)),
                Err(m) => {
                    errors.insert("scene".into(), m);
                    None
                }
            },
        },
    }
}

/// `output`: a plain file name (or the placeholder when absent).
fn check_output(b: &RequestBody, errors: &mut Errors) -> Option<String> {
    match string_field(b.output.as_ref(), "output", 4 * MAX_OUTPUT_NAME, errors) {
        None => Some(Defaults::OUTPUT.to_string()),
        Some(s) => match sanitize_output(s) {
            Ok(n) => Some(n),
            Err(m) => {
                errors.insert("output".into(), m);
                None
            }
        },
    }
}

/// `width`, `height`, `spp`, `secondary`, `max_depth`, `seed` within the server's limits.
fn check_numbers(b: &RequestBody, lim: &Limits, errors: &mut Errors) -> Numbers {
    let size = lim.max_size as u64;
    let given = |v: &Option<Value>| !matches!(v, None | Some(Value::Null));
    let uint = |v: &Option<Value>, key, default, lo, hi, errors: &mut Errors| {
        uint_field(v.as_ref(), key, default, lo, hi, errors)
    };
    Numbers {
        width_given: given(&b.width),
        height_given: given(&b.height),
        width: uint(&b.width, "width", Defaults::WIDTH, 1, size, errors) as u32,
        height: uint(&b.height, "height", Defaults::HEIGHT, 1, size, errors) as u32,
        spp: uint(&b.spp, "spp", Defaults::SPP, 1, lim.max_spp as u64, errors) as u32,
        secondary: uint(
            &b.secondary,
            "secondary",
            Defaults::SECONDARY,
            1,
            lim.max_secondary as u64,
            errors,
        ) as u32,
        max_depth: uint(
            &b.max_depth,
            "max_depth",
            Defaults::MAX_DEPTH,
            0,
            lim.max_depth as u64,
            errors,
        ) as u32,
        seed: uint(&b.seed, "seed", 0, 0, u64::MAX, errors),
    }
}

/// Exposure, integrator, tone mapping, default light, variant, filter, adaptive sampling, time
/// limit, crop and denoising.
fn check_options(b: &RequestBody, errors: &mut Errors) -> Options {
    let exposure = match &b.exposure {
        None | Some(Value::Null) => Defaults::EXPOSURE,
        Some(Value::Number(n)) => match n.as_f64() {
            Some(x) if x.is_finite() && x > 0.0 && x <= 1e6 => x,
            _ => {
                errors.insert(
                    "exposure".into(),
                    "must be a positive number (at most 1000000)".into(),
                );
                1.0
            }
        },
        Some(_) => {
            errors.insert("exposure".into(), "must be a positive number".into());
            1.0
        }
    } as f32;

    let integrator = match string_field(b.integrator.as_ref(), "integrator", 32, errors) {
        None => IntegratorKind::default(),
        Some(s) => IntegratorKind::from_str(s).unwrap_or_else(|_| {
            errors.insert(
                "integrator".into(),
                format!("must be one of: {}", integrator_names().join(", ")),
            );
            IntegratorKind::default()
        }),
    };
    let tonemap = match string_field(b.tonemap.as_ref(), "tonemap", 32, errors) {
        None => Tonemap::default(),
        Some(s) => Tonemap::from_str(s).unwrap_or_else(|_| {
            errors.insert(
                "tonemap".into(),
                format!("must be one of: {}", tonemap_names().join(", ")),
            );
            Tonemap::default()
        }),
    };
    let default_light = string_field(b.default_light.as_ref(), "default_light", 32, errors)
        .and_then(|s| {
            let parsed = DefaultLight::parse(s);
            if parsed.is_none() {
                errors.insert(
                    "default_light".into(),
                    format!("must be one of: {}", DEFAULT_LIGHT_NAMES.join(", ")),
                );
            }
            parsed
        });
    // Checked against the scene's variants when the job loads it (an unknown name fails the job
    // with the list of valid ones).
    let variant = string_field(b.variant.as_ref(), "variant", 256, errors).map(str::to_string);

    let filter = match string_field(b.filter.as_ref(), "filter", 32, errors) {
        None => None,
        Some(s) => match FilterKind::from_str(s) {
            Ok(k) => Some(Filter::new(k)),
            Err(_) => {
                errors.insert(
                    "filter".into(),
                    "must be one of: box, tent, gaussian, mitchell, blackman-harris".into(),
                );
                None
            }
        },
    };
    let noise_threshold =
        positive_field(b.noise_threshold.as_ref(), "noise_threshold", 100.0, errors)
            .map(|x| x as f32);
    let time_limit = positive_field(b.time_limit.as_ref(), "time_limit", MAX_TIME_LIMIT, errors);
    let crop = check_crop(b.crop.as_ref(), errors);
    let denoise = bool_field(b.denoise.as_ref(), "denoise", errors);
    let guiding = optional_bool_field(b.guiding.as_ref(), "guiding", errors);
    let transparent = bool_field(b.transparent.as_ref(), "transparent", errors);
    let spectral = optional_bool_field(b.spectral.as_ref(), "spectral", errors);
    Options {
        exposure,
        integrator,
        tonemap,
        default_light,
        variant,
        filter,
        noise_threshold,
        time_limit,
        crop,
        denoise,
        guiding,
        transparent,
        spectral,
    }
}

/// `crop`: four fractions of the image [x0, x1, y0, y1] (pbrt's cropwindow).
fn check_crop(v: Option<&Value>, errors: &mut Errors) -> Option<crate::pipeline::CropSpec> {
    match v {
        None | Some(Value::Null) => None,
        Some(Value::Array(a)) if a.len() == 4 => {
            let v: Vec<f32> = a
                .iter()
                .filter_map(|x| x.as_f64())
                .map(|x| x as f32)
                .collect();
            let text = v
                .iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(",");
            match (v.len(), crate::pipeline::CropSpec::parse(&text, false)) {
                (4, Ok(c)) => Some(c),
                (_, Err(m)) if v.len() == 4 => {
                    errors.insert("crop".into(), m);
                    None
                }
                _ => {
                    errors.insert(
                        "crop".into(),
                        "must be four numbers [x0, x1, y0, y1]".into(),
                    );
                    None
                }
            }
        }
        Some(_) => {
            errors.insert(
                "crop".into(),
                "must be four fractions of the image [x0, x1, y0, y1]".into(),
            );
            None
        }
    }
}

/// `environment` (a map inside the scenes folder) and `env_rotation` (degrees).
fn check_environment(
    b: &RequestBody,
    policy: &Policy,
    errors: &mut Errors,
) -> (Option<(String, PathBuf)>, f32) {
    let environment = match string_field(
        b.environment.as_ref(),
        "environment",
        MAX_SCENE_NAME,
        errors,
    ) {
        None | Some("") => None,
        Some(name) => match &policy.scenes_dir {
            None => {
                errors.insert(
                    "environment".into(),
                    "this server has no scenes folder to take environment maps from".into(),
                );
                None
            }
            Some(root) => match resolve_env(root, name) {
                Ok(p) => Some((name.to_string(), p)),
                Err(m) => {
                    errors.insert("environment".into(), m);
                    None
                }
            },
        },
    };

    let env_rotation = match &b.env_rotation {
        None | Some(Value::Null) => 0.0,
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() && x.abs() <= 36000.0 => x as f32,
            _ => {
                errors.insert(
                    "env_rotation".into(),
                    "must be a number of degrees (at most 36000 either way)".into(),
                );
                0.0
            }
        },
    };
    if env_rotation != 0.0 && environment.is_none() && !errors.contains_key("environment") {
        errors.insert(
            "env_rotation".into(),
            "turns the environment map: choose one (environment)".into(),
        );
    }
    (environment, env_rotation)
}

/// `aovs`: a list of layer names, each at most once.
fn check_aovs(v: Option<&Value>, errors: &mut Errors) -> Vec<crate::film::aov::AovKind> {
    let mut aovs = Vec::new();
    match v {
        None | Some(Value::Null) => {}
        Some(Value::Array(a)) if a.len() <= AOV_NAMES.len() => {
            for v in a {
                match v.as_str().filter(|n| AOV_NAMES.contains(n)) {
                    Some(n) => {
                        let k = crate::film::aov::AovKind::from_name(n)
                            .expect("the offered names parse");
                        if !aovs.contains(&k) {
                            aovs.push(k);
                        }
                    }
                    None => {
                        errors.insert(
                            "aovs".into(),
                            format!("must be a list of: {}", AOV_NAMES.join(", ")),
                        );
                    }
                }
            }
        }
        Some(_) => {
            errors.insert(
                "aovs".into(),
                format!("must be a list of: {}", AOV_NAMES.join(", ")),
            );
        }
    }
    aovs
}

/// A camera as the page and the job list show it: eye, target, up, vertical field of view.
pub fn camera_json(c: &crate::camera::CameraSpec) -> Value {
    serde_json::json!({
        "eye": c.eye.to_array(),
        "target": c.target.to_array(),
        "up": c.up.to_array(),
        "fov": c.fov,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy() -> Policy {
        Policy {
            scenes_dir: None,
            output_dir: PathBuf::from("."),
            limits: Limits::default(),
            threads: None,
        }
    }

    fn fields(body: &str) -> BTreeMap<String, String> {
        match parse_request(body.as_bytes(), &policy()) {
            Err(RequestError::Fields(f)) => f,
            other => panic!("expected field errors, got {other:?}"),
        }
    }

    /// `spectral` is three-way: absent or null leaves the scene file's default (pbrt files
    /// spectral), true and false force it; anything else, or true with an integrator without a
    /// spectral path, is refused by name.
    #[test]
    fn spectral_is_true_false_or_the_files_default() {
        let parse = |b: &str| parse_request(b.as_bytes(), &policy()).unwrap();
        for (body, given, spectral) in [
            (r#"{"scene":"cornell"}"#, false, false),
            (r#"{"scene":"cornell","spectral":null}"#, false, false),
            (r#"{"scene":"cornell","spectral":true}"#, true, true),
            (r#"{"scene":"cornell","spectral":false}"#, true, false),
        ] {
            let r = parse(body);
            assert_eq!(
                (r.spectral_given, r.settings.path.spectral),
                (given, spectral)
            );
        }
        assert!(fields(r#"{"scene":"cornell","spectral":"yes"}"#).contains_key("spectral"));
        assert!(
            fields(r#"{"scene":"cornell","spectral":true,"integrator":"whitted"}"#)
                .contains_key("spectral")
        );
        assert!(parse(r#"{"scene":"cornell","spectral":true,"integrator":"vcm"}"#).spectral_given);
        assert!(
            parse(r#"{"scene":"cornell","spectral":false,"integrator":"whitted"}"#).spectral_given
        );
    }

    /// `guiding` is three-way too: absent or null leaves the scene file's setting (TOML
    /// `[render] guiding`), true and false force it; anything else is refused by name.
    #[test]
    fn guiding_is_true_false_or_the_files() {
        let parse = |b: &str| parse_request(b.as_bytes(), &policy()).unwrap();
        for (body, given, guiding) in [
            (r#"{"scene":"cornell"}"#, false, false),
            (r#"{"scene":"cornell","guiding":null}"#, false, false),
            (r#"{"scene":"cornell","guiding":true}"#, true, true),
            (r#"{"scene":"cornell","guiding":false}"#, true, false),
        ] {
            let r = parse(body);
            assert_eq!((r.guiding_given, r.settings.guiding), (given, guiding));
        }
        assert!(fields(r#"{"scene":"cornell","guiding":"yes"}"#).contains_key("guiding"));
    }

    /// The #19 fields reach the settings, and absurd values are refused by name.
    #[test]
    fn filter_adaptive_time_limit_and_crop_fields() {
        let r = parse_request(
            br#"{"scene":"cornell","filter":"mitchell","noise_threshold":0.02,"time_limit":5,"crop":[0.25,0.75,0,0.5]}"#,
            &policy(),
        )
        .unwrap();
        assert_eq!(r.settings.filter, Filter::new(FilterKind::Mitchell));
        assert!(r.filter_given);
        assert_eq!(r.settings.noise_threshold, Some(0.02));
        assert_eq!(r.settings.time_limit, Some(5.0));
        assert_eq!(
            r.crop,
            Some(crate::pipeline::CropSpec::Fractions([0.25, 0.75, 0.0, 0.5]))
        );
        let plain = parse_request(br#"{"scene":"cornell"}"#, &policy()).unwrap();
        assert!(!plain.filter_given && plain.crop.is_none());
        let f = fields(
            r#"{"scene":"cornell","filter":"sinc","noise_threshold":-1,"time_limit":"x","crop":[0.5,0.1,0,1]}"#,
        );
        for k in ["filter", "noise_threshold", "time_limit", "crop"] {
            assert!(f.contains_key(k), "{k} not refused: {f:?}");
        }
        let f = fields(r#"{"scene":"cornell","time_limit":1e12,"crop":[0,1,0]}"#);
        assert!(
            f.contains_key("time_limit") && f.contains_key("crop"),
            "{f:?}"
        );
    }

    #[test]
    fn defaults_fill_missing_fields() {
        let r = parse_request(br#"{"scene":"cornell"}"#, &policy()).unwrap();
        assert_eq!(r.source, SceneSource::Builtin("cornell".into()));
        assert_eq!(r.output, "render");
        assert!(!r.output_given);
        // The command line's size for the Cornell box (its camera is square).
        assert_eq!((r.settings.width, r.settings.height), (512, 512));
        assert_eq!(r.settings.spp, 64);
        assert_eq!(r.exposure, 1.0);
    }

    #[test]
    fn every_bad_field_is_named() {
        let f = fields(
            r#"{"scene":"nope","output":"../x","width":0,"height":100000,"spp":-1,
                "secondary":1.5,"max_depth":"a","exposure":-2,"integrator":"magic","tonemap":7}"#,
        );
        for k in [
            "scene",
            "output",
            "width",
            "height",
            "spp",
            "secondary",
            "max_depth",
            "exposure",
            "integrator",
            "tonemap",
        ] {
            assert!(f.contains_key(k), "{k} missing from {f:?}");
        }
    }

    #[test]
    fn output_names_are_plain() {
        assert_eq!(sanitize_output("shot-1.png").unwrap(), "shot-1");
        assert_eq!(sanitize_output(" a_b.c ").unwrap(), "a_b.c");
        for bad in [
            "",
            ".png",
            "../x",
            "a/b",
            "a\\b",
            ".hidden",
            "/etc/passwd",
            "a b",
            "é",
        ] {
            assert!(sanitize_output(bad).is_err(), "{bad:?}");
        }
        assert!(sanitize_output(&"a".repeat(65)).is_err());
    }

    #[test]
    fn budget_refuses_absurd_work() {
        let f = fields(r#"{"scene":"cornell","width":4096,"height":4096,"spp":16384}"#);
        assert!(f["spp"].contains("budget"), "{f:?}");
    }

    #[test]
    fn integrators_offered_parse() {
        assert!(integrator_names().contains(&"path"));
        assert!(integrator_names().contains(&"bdpt"));
        assert_eq!(tonemap_names().len(), 5);
        assert_eq!(tonemap_names()[0], "pbr-neutral");
    }
}
