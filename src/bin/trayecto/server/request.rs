//! What a client may ask for, checked field by field before any work starts (docs/DESIGN.md §7): the scene
//! is a built-in name or a file that canonicalises to a path inside the scenes folder, the output
//! name is a plain file name, and every number is inside both the renderer's limits
//! (`RenderSettings::validate`) and the server's own, tighter caps.

use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};
use std::str::FromStr;
use trayecto::film::tonemap::Tonemap;
use trayecto::integrator::{IntegratorKind, PathSettings};
use trayecto::light::default_light::DefaultLight;
use trayecto::render::{MAX_DEPTH, MAX_SECONDARY, RenderSettings};
use trayecto::sampling::SamplerKind;
use trayecto::scene::builtin;

/// Integrator and tone-mapping names offered to the page; only those the library parses are
/// shown, so new modes appear by themselves when they land.
const INTEGRATOR_NAMES: &[&str] = &["path", "whitted", "raycast"];
const TONEMAP_NAMES: &[&str] = &["clamp", "gamma2.2", "aces", "agx"];
pub const MAX_SCENE_NAME: usize = 512;
pub const MAX_OUTPUT_NAME: usize = 64;
/// How deep and how wide the scenes folder is listed, so a huge or looping tree cannot stall it.
const LIST_MAX_DEPTH: usize = 8;
const LIST_MAX_ENTRIES: usize = 5000;

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
    pub max_body: usize,
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
            max_body: 16 * 1024,
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
pub const DEFAULT_LIGHT_NAMES: [&str; 3] = ["auto", "on", "off"];

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
    /// Base name of the output files (`<output>.png`, `<output>.exr`).
    pub output: String,
    pub settings: RenderSettings,
    pub exposure: f32,
    pub tonemap: Tonemap,
    /// `None`: as the scene file says (else auto).
    pub default_light: Option<DefaultLight>,
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

fn has_scene_extension(p: &Path) -> bool {
    trayecto::scene::format_for(p).is_some()
}

/// Resolves a scene name relative to the (canonical) scenes folder. Refuses absolute paths, any
/// `..`/`.`/root component, backslashes and NULs before touching the file system, then
/// canonicalises (which resolves symlinks) and checks the result is still inside the folder.
pub fn resolve_scene(root: &Path, name: &str) -> Result<PathBuf, String> {
    if name.contains('\0') || name.contains('\\') {
        return Err("may not contain backslashes or NUL characters".into());
    }
    let rel = Path::new(name);
    if rel.is_absolute() {
        return Err("must be a path relative to the scenes folder, not an absolute path".into());
    }
    for c in rel.components() {
        if !matches!(c, Component::Normal(_)) {
            return Err("may not contain '..' or '.' components".into());
        }
    }
    let canon = root
        .join(rel)
        .canonicalize()
        .map_err(|_| format!("no scene '{name}' in the scenes folder"))?;
    if !canon.starts_with(root) {
        return Err("resolves outside the scenes folder".into());
    }
    if !canon.is_file() {
        return Err(format!("'{name}' is not a file"));
    }
    if !has_scene_extension(&canon) {
        return Err(format!(
            "'{name}' is not a scene file (expected {})",
            trayecto::scene::extension_list(false)
        ));
    }
    Ok(canon)
}

/// The page's scene list: scene files first (pbrt, glTF, FBX, TOML, OBJ, by path), then
/// standalone meshes (PLY); meshes that a pbrt or TOML file under the folder refers to only when
/// `all` (else they are counted in `hidden`).
pub fn scene_list(root: &Path, all: bool) -> (Vec<String>, usize) {
    let files = list_scenes(root);
    let referenced = referenced_files(root, &files);
    let rank = |f: &str| {
        let is_ref = referenced.contains(f);
        let mesh = trayecto::scene::format_for(Path::new(f)).is_some_and(|x| x.mesh_only);
        (is_ref as u8, mesh as u8)
    };
    let mut out: Vec<String> = files;
    let before = out.len();
    if !all {
        out.retain(|f| !referenced.contains(f));
    }
    let hidden = before - out.len();
    out.sort_by(|a, b| rank(a).cmp(&rank(b)).then_with(|| a.cmp(b)));
    (out, hidden)
}

/// Files of `files` that a pbrt or TOML scene among them names (as a quoted string, relative to
/// its own folder). Each scene file is read up to 16 MiB; a mention that is not a real reference
/// (a comment) only hides a mesh behind the "show all files" toggle.
fn referenced_files(root: &Path, files: &[String]) -> std::collections::HashSet<String> {
    const MAX_READ: u64 = 16 << 20;
    let listed: std::collections::HashSet<&str> = files.iter().map(|s| s.as_str()).collect();
    let mut out = std::collections::HashSet::new();
    for f in files {
        let ext = Path::new(f)
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        if !matches!(ext.as_deref(), Some("pbrt" | "toml")) {
            continue;
        }
        let path = root.join(f);
        if std::fs::metadata(&path).map_or(true, |m| m.len() > MAX_READ) {
            continue;
        }
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        let dir = Path::new(f).parent().unwrap_or(Path::new(""));
        for quoted in text.split('"').skip(1).step_by(2) {
            if quoted.is_empty() || quoted.len() > MAX_SCENE_NAME || quoted.contains('\\') {
                continue;
            }
            // Normalise "a/./b" and "a/../b" lexically; stay inside the folder.
            let mut parts: Vec<&str> = dir
                .to_str()
                .unwrap_or("")
                .split('/')
                .filter(|p| !p.is_empty())
                .collect();
            let mut inside = true;
            for c in quoted.split('/') {
                match c {
                    "" | "." => {}
                    ".." => inside &= parts.pop().is_some(),
                    c => parts.push(c),
                }
            }
            let rel = parts.join("/");
            if inside && &rel != f && listed.contains(rel.as_str()) {
                out.insert(rel);
            }
        }
    }
    out
}

/// Scene files under the (canonical) scenes folder, as '/'-separated relative paths, sorted.
/// Hidden entries are skipped; symlinks are listed only if they are files that resolve inside
/// the folder (symlinked folders are not followed, so loops cannot occur).
pub fn list_scenes(root: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut seen = 0usize;
    let mut stack: Vec<(PathBuf, usize)> = vec![(root.to_path_buf(), 0)];
    while let Some((dir, depth)) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            seen += 1;
            if seen > LIST_MAX_ENTRIES {
                break;
            }
            let name = e.file_name();
            let Some(name) = name.to_str() else { continue };
            if name.starts_with('.') {
                continue;
            }
            let path = e.path();
            let Ok(meta) = std::fs::symlink_metadata(&path) else {
                continue;
            };
            if meta.is_dir() {
                if depth + 1 < LIST_MAX_DEPTH {
                    stack.push((path, depth + 1));
                }
                continue;
            }
            let Ok(rel) = path.strip_prefix(root) else {
                continue;
            };
            let Some(rel) = rel.to_str() else { continue };
            if !has_scene_extension(&path) {
                continue;
            }
            if meta.file_type().is_symlink() {
                // Listed only if resolving it would be accepted.
                if resolve_scene(root, rel).is_err() {
                    continue;
                }
            } else if !meta.is_file() {
                continue;
            }
            out.push(rel.replace(std::path::MAIN_SEPARATOR, "/"));
        }
    }
    out.sort();
    out
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
    obj: &Map<String, Value>,
    key: &str,
    default: u64,
    lo: u64,
    hi: u64,
    errors: &mut BTreeMap<String, String>,
) -> u64 {
    let range = || format!("must be a whole number from {lo} to {hi}");
    match obj.get(key) {
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
    obj: &'a Map<String, Value>,
    key: &str,
    max_len: usize,
    errors: &mut BTreeMap<String, String>,
) -> Option<&'a str> {
    match obj.get(key) {
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
    pub const WIDTH: u64 = 256;
    pub const HEIGHT: u64 = 256;
    pub const SPP: u64 = 64;
    pub const SECONDARY: u64 = 1;
    pub const MAX_DEPTH: u64 = 16;
    pub const EXPOSURE: f64 = 1.0;
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

/// What a render of `name` gets when its size, samples and depth are not given: the file's own
/// resolution, else its camera's shape (the pipeline's rule, [`trayecto::pipeline::RenderJob::resolve`]),
/// scaled down to fit the server's `max_size`. Loads the scene.
pub fn scene_defaults(name: &str, policy: &Policy) -> Result<Value, String> {
    let source = scene_source(name, policy)?;
    let scene = trayecto::scene::load(&source.load_spec()).map_err(|e| {
        let m = e.to_string();
        match &source {
            SceneSource::File(p) => m.replace(&*p.to_string_lossy(), name),
            SceneSource::Builtin(_) => m,
        }
    })?;
    let job = trayecto::pipeline::RenderJob {
        scene: name.to_string(),
        world: trayecto::world::WorldOptions::default(),
        settings: RenderSettings {
            width: Defaults::WIDTH as u32,
            height: Defaults::HEIGHT as u32,
            spp: Defaults::SPP as u32,
            path: PathSettings {
                max_depth: Defaults::MAX_DEPTH as u32,
                ..PathSettings::default()
            },
            ..RenderSettings::default()
        },
        given: trayecto::pipeline::GivenSettings {
            width: false,
            height: false,
            spp: false,
            max_depth: false,
        },
        split: Default::default(),
        outputs: vec![],
    };
    let (s, note) = job.resolve(&scene);
    let l = &policy.limits;
    let (mut w, mut h) = (s.width as f64, s.height as f64);
    let scale = (l.max_size as f64 / w.max(h)).min(1.0);
    (w, h) = ((w * scale).round().max(1.0), (h * scale).round().max(1.0));
    Ok(serde_json::json!({
        "width": w as u32,
        "height": h as u32,
        "spp": s.spp.min(l.max_spp),
        "max_depth": s.path.max_depth.min(l.max_depth),
        "note": note,
    }))
}

/// Parses and checks a JSON render request. Every wrong field is reported, not only the first.
pub fn parse_request(body: &[u8], policy: &Policy) -> Result<RenderRequest, RequestError> {
    let value: Value = serde_json::from_slice(body)
        .map_err(|e| RequestError::Malformed(format!("the body is not valid JSON: {e}")))?;
    let Value::Object(obj) = value else {
        return Err(RequestError::Malformed(
            "the body must be a JSON object".into(),
        ));
    };
    let lim = &policy.limits;
    let mut errors = BTreeMap::new();
    let known = [
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
    ];
    for k in obj.keys() {
        if !known.contains(&k.as_str()) {
            let shown: String = k.chars().take(40).collect();
            errors.insert(
                "request".into(),
                format!("unknown field '{shown}' (known: {})", known.join(", ")),
            );
        }
    }

    let scene_name = string_field(&obj, "scene", MAX_SCENE_NAME, &mut errors);
    let mut source = None;
    match scene_name {
        None => {
            errors
                .entry("scene".into())
                .or_insert_with(|| "choose a scene".into());
        }
        Some(name) if builtin::NAMES.contains(&name) => {
            source = Some(SceneSource::Builtin(name.to_string()))
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
            }
            Some(root) => match resolve_scene(root, name) {
                Ok(p) => source = Some(SceneSource::File(p)),
                Err(m) => {
                    errors.insert("scene".into(), m);
                }
            },
        },
    }

    let output = match string_field(&obj, "output", 4 * MAX_OUTPUT_NAME, &mut errors) {
        None => Some(Defaults::OUTPUT.to_string()),
        Some(s) => match sanitize_output(s) {
            Ok(n) => Some(n),
            Err(m) => {
                errors.insert("output".into(), m);
                None
            }
        },
    };

    let size = lim.max_size as u64;
    let width = uint_field(&obj, "width", Defaults::WIDTH, 1, size, &mut errors) as u32;
    let height = uint_field(&obj, "height", Defaults::HEIGHT, 1, size, &mut errors) as u32;
    let spp = uint_field(
        &obj,
        "spp",
        Defaults::SPP,
        1,
        lim.max_spp as u64,
        &mut errors,
    ) as u32;
    let secondary = uint_field(
        &obj,
        "secondary",
        Defaults::SECONDARY,
        1,
        lim.max_secondary as u64,
        &mut errors,
    ) as u32;
    let max_depth = uint_field(
        &obj,
        "max_depth",
        Defaults::MAX_DEPTH,
        0,
        lim.max_depth as u64,
        &mut errors,
    ) as u32;
    let seed = uint_field(&obj, "seed", 0, 0, u64::MAX, &mut errors);

    let exposure = match obj.get("exposure") {
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

    let integrator = match string_field(&obj, "integrator", 32, &mut errors) {
        None => IntegratorKind::default(),
        Some(s) => IntegratorKind::from_str(s).unwrap_or_else(|_| {
            errors.insert(
                "integrator".into(),
                format!("must be one of: {}", integrator_names().join(", ")),
            );
            IntegratorKind::default()
        }),
    };
    let tonemap = match string_field(&obj, "tonemap", 32, &mut errors) {
        None => Tonemap::default(),
        Some(s) => Tonemap::from_str(s).unwrap_or_else(|_| {
            errors.insert(
                "tonemap".into(),
                format!("must be one of: {}", tonemap_names().join(", ")),
            );
            Tonemap::default()
        }),
    };
    let default_light = string_field(&obj, "default_light", 32, &mut errors).and_then(|s| {
        let parsed = DefaultLight::parse(s);
        if parsed.is_none() {
            errors.insert(
                "default_light".into(),
                format!("must be one of: {}", DEFAULT_LIGHT_NAMES.join(", ")),
            );
        }
        parsed
    });

    let samples = width as u64 * height as u64 * spp as u64 * secondary as u64;
    if !errors.contains_key("spp") && samples > lim.max_samples {
        errors.insert(
            "spp".into(),
            format!(
                "width × height × samples × secondary rays = {samples} is over this server's budget of {}",
                lim.max_samples
            ),
        );
    }

    let settings = RenderSettings {
        width,
        height,
        spp,
        seed,
        threads: policy.threads,
        sampler: SamplerKind::default(),
        integrator,
        path: PathSettings {
            max_depth,
            secondary,
            ..PathSettings::default()
        },
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
            settings,
            exposure,
            tonemap,
            default_light,
        }),
        _ => Err(RequestError::Fields(errors)),
    }
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

    #[test]
    fn defaults_fill_missing_fields() {
        let r = parse_request(br#"{"scene":"cornell"}"#, &policy()).unwrap();
        assert_eq!(r.source, SceneSource::Builtin("cornell".into()));
        assert_eq!(r.output, "render");
        assert_eq!((r.settings.width, r.settings.height), (256, 256));
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
        assert_eq!(tonemap_names().len(), 4);
    }
}
