//! pbrt-v4 scene files (`.pbrt`), read the way pbrt-v4 reads them (its `parser.cpp`,
//! `scene.cpp`, `paramdict.cpp`; the file format reference at pbrt.org).
//!
//! * [`tokenizer`] splits the text, [`params`] reads typed parameter lists, this module runs the
//!   directives against pbrt's graphics state (current transform, material, area light, reverse
//!   orientation, `Attribute` defaults, named coordinate systems, object instances), [`shapes`]
//!   turns shapes into meshes or analytic shapes, [`materials`] maps materials and textures onto
//!   Trayecto's, [`spectra`] turns spectral values into RGB.
//! * Conventions: pbrt's camera space is left-handed (looks down +z, +y up, +x to the right of
//!   the image); Trayecto's looks down −z, so the camera-to-world matrix is pbrt's times
//!   diag(1, 1, −1). `fov` is the angle of the shorter image axis. `Transform`/`ConcatTransform`
//!   list the matrix column by column; `Rotate` takes degrees. Front faces follow pbrt: a mesh with
//!   normals faces its normals, one without faces its counter-clockwise side, and
//!   `ReverseOrientation` flips both (this matters for one-sided area lights).
//! * Everything a file uses that Trayecto cannot represent is a warning naming the directive and
//!   `file:line`; every parameter that is not read is reported the same way. Malformed files are
//!   errors naming the file and line.
//! * `Include`/`Import` and every file a scene names (PLY meshes, images) are resolved inside the
//!   main file's folder and refused outside it; include cycles and nesting deeper than
//!   [`MAX_INCLUDE_DEPTH`] are errors. PLY meshes are read, and images decoded, in parallel after
//!   parsing.

mod directives;
pub(crate) mod embed;
pub mod materials;
pub mod params;
pub mod shapes;
pub mod spectra;
pub mod tokenizer;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::material::Material;
use crate::math::{Mat3, Mat4, Vec3};
use crate::scene::{
    CameraDesc, LightDesc, MaterialId, Projection, Scene, SceneError, Shape, SphericalMapping,
};

use materials::{MatSpec, TexNode};
use params::{Param, ParamList, SpectrumValue, Values};
use tokenizer::{Token, TokenKind};

/// Deepest `Include` nesting accepted.
pub const MAX_INCLUDE_DEPTH: usize = 32;
/// Largest scene text accepted (one file), in bytes.
pub const MAX_FILE_BYTES: u64 = 1 << 31;
/// Most `Include`/`Import` files one scene may read, counting a file each time it is read: a
/// chain of files each including the next twice reads 2ⁿ files without a cycle or deep nesting.
pub const MAX_INCLUDES: u32 = 20_000;
/// Most bytes one scene may read through `Include`/`Import`, all files together.
pub const MAX_INCLUDED_BYTES: u64 = 1 << 32;
/// Deepest `AttributeBegin` nesting accepted.
const MAX_ATTRIBUTE_DEPTH: usize = 10_000;

/// Loads a `.pbrt` file and everything it includes.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    crate::scene::load_file(path)
}

/// The [`crate::scene::FORMATS`] entry: the main file's bytes, its folder (where includes and
/// every file the scene names must stay) and its name for messages.
pub fn load_from_file_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let dir = if dir.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        dir.to_path_buf()
    };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        SceneError::invalid(
            label,
            format!("the file is not UTF-8 text (byte {})", e.valid_up_to()),
        )
    })?;
    let mut l = Loader::new(Some(dir));
    if let Ok(c) = Path::new(label).canonicalize() {
        l.include_stack.push(c);
    }
    l.run_file(text, label, 0)?;
    l.finish()
}

/// Parses pbrt text held in memory (the fuzzing entry point). Nothing is read from disk:
/// `Include`, `Import` and file-backed shapes and textures are warnings.
pub fn load_from_str(text: &str, label: &str) -> Result<Scene, SceneError> {
    let mut l = Loader::new(None);
    l.run_file(text, label, 0)?;
    let mut scene = l.finish()?;
    scene.name = label.to_string();
    scene.source = Some(label.into());
    Ok(scene)
}

/// [`load_from_str`] for bytes that should be UTF-8 text.
pub fn load_from_bytes(bytes: &[u8], label: &str) -> Result<Scene, SceneError> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        SceneError::invalid(
            label,
            format!("the file is not UTF-8 text (byte {})", e.valid_up_to()),
        )
    })?;
    load_from_str(text, label)
}

fn read_text(path: &Path, label: &str) -> Result<String, SceneError> {
    let meta = std::fs::metadata(path).map_err(|e| SceneError::Io {
        path: label.to_string(),
        error: e,
    })?;
    if meta.len() > MAX_FILE_BYTES {
        return Err(SceneError::invalid(label, "the file is larger than 2 GiB"));
    }
    let bytes = crate::limits::read_file(path).map_err(|e| SceneError::Io {
        path: label.to_string(),
        error: e,
    })?;
    String::from_utf8(bytes).map_err(|e| {
        SceneError::invalid(
            label,
            format!(
                "the file is not UTF-8 text (byte {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Which of pbrt's two transforms the transform directives change (`ActiveTransform`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Active {
    Start,
    End,
    All,
}

/// An `AreaLightSource "diffuse"` in effect.
#[derive(Clone, Debug, PartialEq)]
struct AreaLight {
    radiance: Vec3,
    /// The spectrum `radiance` projects, when `L` was not RGB ([`Loader::light_spectrum`]).
    spectrum: Option<crate::spectrum::Illuminant>,
    two_sided: bool,
    /// pbrt-v4's `power` (W): radiance L·scale·power / (π · sides · area of each light's shape).
    power: Option<f32>,
}

/// The area pbrt-v4 normalises an area light's `power` by, for the shape being placed: each pbrt
/// shape is one light, and a triangle or bilinear mesh is one light per triangle or patch.
#[derive(Clone, Copy, Debug)]
pub(crate) enum LightArea {
    /// A quadric's own `Area()` (object space, as pbrt-v4 computes it).
    Quadric(f32),
    /// A mesh whose pbrt-v4 lights are groups of `n` of its triangles (1, or 2 for patches).
    Triangles(u32),
}

#[derive(Clone, Debug)]
enum MatRef {
    Default,
    Anonymous(usize),
    Named(String),
}

#[derive(Clone, Debug)]
struct GraphicsState {
    ctm: Mat4,
    /// The end-time transform (`ActiveTransform EndTime`), for motion blur.
    ctm_end: Mat4,
    active: Active,
    reverse: bool,
    material: MatRef,
    area_light: Option<AreaLight>,
    /// `Attribute "shape"|"light"|"material"|"medium"|"texture"` defaults.
    attributes: HashMap<String, Vec<Param>>,
    /// `MediumInterface` names (pbrt's current inside/outside media; "" is vacuum).
    medium_inside: String,
    medium_outside: String,
}

impl Default for GraphicsState {
    fn default() -> Self {
        GraphicsState {
            ctm: Mat4::IDENTITY,
            ctm_end: Mat4::IDENTITY,
            active: Active::All,
            reverse: false,
            material: MatRef::Default,
            area_light: None,
            attributes: HashMap::new(),
            medium_inside: String::new(),
            medium_outside: String::new(),
        }
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Frame {
    Attribute,
    Transform,
}

/// One shape of an object definition (`ObjectBegin`): its shape, the transform at definition
/// time, its material and its medium interface (pbrt-v4 records the `MediumInterface` in effect
/// inside the definition with each shape; the one at `ObjectInstance` does not apply).
#[derive(Clone, Debug)]
struct InstancePart {
    shape: Shape,
    transform: Mat4,
    material: MaterialId,
    name: String,
    medium: Option<crate::scene::MediumInterface>,
}

/// A `plymesh` to read after parsing (in parallel).
struct PlyJob {
    mesh: usize,
    path: PathBuf,
    name: String,
    location: String,
    reverse: bool,
}

/// Camera, film, sampler and integrator settings.
#[derive(Default)]
struct Settings {
    /// camera-from-world, parameters, where, type.
    camera: Option<(Mat4, ParamList, String, String)>,
    film: Option<(ParamList, String)>,
}

pub(crate) struct Loader {
    /// The main file's folder; None for in-memory text (no file access at all).
    root_dir: Option<PathBuf>,
    scene: Scene,
    gs: GraphicsState,
    stack: Vec<(GraphicsState, Frame, String)>,
    named_coord: HashMap<String, Mat4>,
    named_materials: HashMap<String, MatSpec>,
    anonymous_materials: Vec<MatSpec>,
    pub(crate) float_textures: HashMap<String, TexNode>,
    pub(crate) spectrum_textures: HashMap<String, TexNode>,
    /// Every texture node of the file ([`materials::TexArena`]).
    pub(crate) tex: materials::TexArena,
    material_cache: HashMap<String, MaterialId>,
    /// Materials placed by a `NamedMaterial` not (yet) defined: pbrt-v4 creates named materials
    /// at the end of the world block, so a later `MakeNamedMaterial` still applies. Resolved in
    /// [`Loader::finish`]: (material slot, name, area light, where it was used).
    pending_materials: Vec<(MaterialId, String, Option<AreaLight>, String)>,
    /// Set by `shape` for the shape it is about to place: the area its area light's `power`
    /// is normalised by.
    pub(crate) light_area: Option<LightArea>,
    instances: HashMap<String, Vec<InstancePart>>,
    current_object: Option<(String, Vec<InstancePart>)>,
    include_stack: Vec<PathBuf>,
    /// Files read through `Include`/`Import` so far, and their bytes ([`MAX_INCLUDES`]).
    included: (u32, u64),
    /// Image textures already made, by canonical path and decoding: a file named through
    /// different spellings (`a.png`, `./a.png`, `t/../a.png`) is decoded once.
    pub(crate) images_made: HashMap<materials::ImageKey, usize>,
    settings: Settings,
    ply_jobs: Vec<PlyJob>,
    pub(crate) image_jobs: Vec<materials::ImageJob>,
    world_begun: bool,
    warned_once: std::collections::HashSet<String>,
    /// Named media: `Some(id)` when mapped, `None` for a type Trayecto lacks (warned once).
    media: HashMap<String, Option<crate::scene::MediumId>>,
    /// The camera's medium name (pbrt's outside medium at `Camera`) and where it was set.
    camera_medium: Option<(String, String)>,
    /// `TransformTimes` (pbrt-v4's default 0 1).
    transform_times: [f64; 2],
    /// Objects placed with a moving transform (start ≠ end), and the camera's end transform
    /// when it moves: the scene's [`crate::scene::animation::Animation`].
    motion: Vec<crate::scene::animation::RigidMotion>,
    camera_end: Option<Mat4>,
    /// The camera's `shutteropen`/`shutterclose`.
    shutter: Option<(f64, f64)>,
    /// How the camera follows an image of another shape, when a translator (the Mitsuba
    /// loader) says so instead of pbrt-v4's rule.
    pub(crate) camera_fit: Option<crate::scene::SensorFit>,
}

/// `file:line` of a token.
fn loc(file: &str, line: u32) -> String {
    format!("{file}:{line}")
}

impl Loader {
    fn new(root_dir: Option<PathBuf>) -> Loader {
        Loader {
            root_dir,
            // pbrt-v4 renders every file spectrally: so does Trayecto unless told `--rgb`.
            scene: Scene {
                hints: crate::scene::RenderHints {
                    spectral: true,
                    ..Default::default()
                },
                ..Scene::default()
            },
            gs: GraphicsState::default(),
            stack: Vec::new(),
            named_coord: HashMap::new(),
            named_materials: HashMap::new(),
            anonymous_materials: Vec::new(),
            float_textures: HashMap::new(),
            spectrum_textures: HashMap::new(),
            material_cache: HashMap::new(),
            pending_materials: Vec::new(),
            light_area: None,
            instances: HashMap::new(),
            current_object: None,
            include_stack: Vec::new(),
            included: (0, 0),
            images_made: HashMap::new(),
            settings: Settings::default(),
            ply_jobs: Vec::new(),
            image_jobs: Vec::new(),
            tex: Default::default(),
            world_begun: false,
            warned_once: Default::default(),
            media: HashMap::new(),
            camera_medium: None,
            transform_times: [0.0, 1.0],
            motion: Vec::new(),
            camera_end: None,
            shutter: None,
            camera_fit: None,
        }
    }

    pub(crate) fn warn(&mut self, w: String) {
        self.scene.warnings.push(w);
    }

    /// The moving shapes and camera become the scene's animation, blurred over the camera's
    /// shutter.
    fn finish_motion(&mut self) {
        if self.motion.is_empty() {
            return;
        }
        self.scene.animation = Some(std::sync::Arc::new(crate::scene::animation::Animation {
            rigid: std::mem::take(&mut self.motion),
            shutter: Some(self.shutter.unwrap_or((0.0, 1.0))),
            ..Default::default()
        }));
        // The still (no --time, no shutter) shows the start transforms, as before.
        self.scene.pose(None);
    }

    /// A warning given once per distinct key (per-shape repeats would drown the rest).
    pub(crate) fn warn_once(&mut self, key: &str, w: String) {
        if self.warned_once.insert(key.to_string()) {
            self.scene.warnings.push(w);
        }
    }

    /// Resolves a file name written in the scene inside the main file's folder.
    pub(crate) fn resolve(&self, name: &str, at: &str) -> Result<PathBuf, SceneError> {
        let Some(dir) = &self.root_dir else {
            return Err(SceneError::invalid(
                at,
                format!("'{name}': files are not read when parsing text from memory"),
            ));
        };
        super::image_io::resolve_in_dir(dir, name).map_err(|m| SceneError::invalid(at, m))
    }

    fn run_file(&mut self, text: &str, file: &str, depth: usize) -> Result<(), SceneError> {
        let (tokens, _held) = tokenizer::tokenize(text)
            .map_err(|(line, m)| SceneError::invalid(loc(file, line), m))?;
        let mut p = Cursor {
            tokens: &tokens,
            pos: 0,
            file,
            warnings: Vec::new(),
        };
        while let Some(tok) = p.next() {
            let line = tok.line;
            let at = loc(file, line);
            let TokenKind::Word(name) = &tok.kind else {
                return Err(SceneError::invalid(
                    &at,
                    format!("expected a directive, found {}", describe(tok)),
                ));
            };
            self.directive(name, &mut p, &at, depth)?;
            self.scene.warnings.append(&mut p.warnings);
        }
        Ok(())
    }

    fn include(&mut self, f: &str, at: &str, depth: usize) -> Result<(), SceneError> {
        if self.root_dir.is_none() {
            self.warn(format!(
                "{at}: Include \"{f}\": files are not read when parsing text from memory"
            ));
            return Ok(());
        }
        if depth + 1 > MAX_INCLUDE_DEPTH {
            return Err(SceneError::invalid(
                at,
                format!("Include \"{f}\": includes nested more than {MAX_INCLUDE_DEPTH} deep"),
            ));
        }
        let path = self.resolve(f, at)?;
        let canon = path.canonicalize().map_err(|e| SceneError::Io {
            path: format!("{at}: Include \"{f}\""),
            error: e,
        })?;
        if self.include_stack.contains(&canon) {
            return Err(SceneError::invalid(
                at,
                format!("Include \"{f}\" includes itself (an include cycle)"),
            ));
        }
        let label = path.display().to_string();
        let size = std::fs::metadata(&path).map_or(0, |m| m.len());
        let (files, bytes) = (self.included.0 + 1, self.included.1.saturating_add(size));
        if files > MAX_INCLUDES || bytes > MAX_INCLUDED_BYTES {
            return Err(SceneError::invalid(
                at,
                format!(
                    "Include \"{f}\": the scene reads more than {MAX_INCLUDES} included files or {} through Include/Import (files included many times over?)",
                    crate::limits::bytes_text(MAX_INCLUDED_BYTES)
                ),
            ));
        }
        self.included = (files, bytes);
        let text = read_text(&path, &label)?;
        self.include_stack.push(canon);
        let r = self.run_file(&text, &label, depth + 1);
        self.include_stack.pop();
        r
    }

    /// Adds the `Attribute` defaults of `target` that the directive does not set itself. They
    /// come marked as used: an attribute that does not apply to one directive is not a warning
    /// there.
    fn with_attributes(&self, mut list: ParamList, target: &str) -> ParamList {
        if let Some(defaults) = self.gs.attributes.get(target) {
            for d in defaults {
                if !list.has(&d.name) {
                    let d = d.clone();
                    d.used.set(true);
                    list.params.push(d);
                }
            }
        }
        list
    }

    /// Warns about every parameter of `list` nobody read.
    pub(crate) fn note_unused(&mut self, list: &ParamList, what: &str, at: &str) {
        for u in list.unused() {
            self.warn(format!(
                "{at}: {what}: parameter {u} is not supported and was ignored"
            ));
        }
    }

    fn light_source(&mut self, ty: &str, list: ParamList, at: &str) -> Result<(), SceneError> {
        let ctm = self.gs.ctm;
        let scale = list.float("scale", 1.0);
        let name = format!("{ty} ({at})");
        let spectrum = |l: &mut Loader, key: &str, default: Vec3| -> Vec3 {
            match list.spectrum(key) {
                Some(s) => l.illuminant_rgb(&s, at, key).unwrap_or(default),
                None => default,
            }
        };
        match ty {
            "point" => {
                let i = spectrum(self, "I", Vec3::ONE);
                self.note_light_spectrum(&list, "I");
                let from = list.point3("from", Vec3::ZERO);
                let mut s = scale;
                let power = list.float("power", -1.0);
                if power > 0.0 {
                    s *= power / (4.0 * std::f32::consts::PI);
                }
                self.scene.lights.push(LightDesc::Point {
                    name,
                    position: ctm.transform_point3(from),
                    intensity: i * s,
                });
            }
            "spot" => {
                let i = spectrum(self, "I", Vec3::ONE);
                self.note_light_spectrum(&list, "I");
                let from = list.point3("from", Vec3::ZERO);
                let to = list.point3("to", Vec3::new(0.0, 0.0, 1.0));
                let cone = list.float("coneangle", 30.0).clamp(0.0, 90.0);
                let delta = list.float("conedeltaangle", 5.0).clamp(0.0, cone);
                let mut s = scale;
                let power = list.float("power", -1.0);
                if power > 0.0 {
                    // pbrt-v4 SpotLight::Create: k_e = 2π (1 − ½(cos start + cos total)).
                    let (c0, c1) = ((cone - delta).to_radians().cos(), cone.to_radians().cos());
                    s *= power / (2.0 * std::f32::consts::PI * (1.0 - 0.5 * (c0 + c1)));
                }
                let dir = ctm.transform_vector3(to - from);
                if !(dir.length_squared() > 0.0) {
                    return Err(SceneError::invalid(at, "spot light: 'from' equals 'to'"));
                }
                self.scene.lights.push(LightDesc::Spot {
                    name,
                    position: ctm.transform_point3(from),
                    direction: dir.normalize(),
                    intensity: i * s,
                    inner_angle: (cone - delta).to_radians(),
                    outer_angle: cone.to_radians(),
                    falloff: crate::scene::SpotFalloff::Smoothstep,
                });
            }
            "distant" => {
                let l = spectrum(self, "L", Vec3::ONE);
                self.note_light_spectrum(&list, "L");
                let from = list.point3("from", Vec3::ZERO);
                let to = list.point3("to", Vec3::new(0.0, 0.0, 1.0));
                let mut s = scale;
                let e = list.float("illuminance", -1.0);
                if e > 0.0 {
                    s *= e;
                }
                let dir = ctm.transform_vector3(to - from);
                if !(dir.length_squared() > 0.0) {
                    return Err(SceneError::invalid(at, "distant light: 'from' equals 'to'"));
                }
                self.scene.lights.push(LightDesc::Directional {
                    name,
                    direction: dir.normalize(),
                    irradiance: l * s,
                });
            }
            "infinite" => {
                let file = list.string("filename");
                let l = list.spectrum("L");
                let mut s = scale;
                let e = list.float("illuminance", -1.0);
                if let Some(f) = file {
                    if l.is_some() {
                        return Err(SceneError::invalid(
                            at,
                            "infinite light: both \"L\" and \"filename\" are given",
                        ));
                    }
                    let path = self.resolve(&f, at)?;
                    if !path.is_file() {
                        self.warn(format!(
                            "{at}: infinite light \"{f}\": the image does not exist; the light was left out"
                        ));
                        self.note_unused(&list, &format!("LightSource \"{ty}\""), at);
                        return Ok(());
                    }
                    if let Some(p) = list.point3s("portal") {
                        // pbrt-v4's PortalImageInfiniteLight samples only directions through
                        // the portal and is black behind the portal's plane; the whole map is
                        // the same radiance wherever the portal is visible.
                        self.warn(format!(
                            "{at}: infinite light \"{f}\": \"portal\" ({} points) is not supported; the map is sampled over the whole sphere (the same radiance through the portal; pbrt-v4 is black behind the portal's plane)",
                            p.len()
                        ));
                    }
                    // The light's frame is the CTM (pbrt-v4's `renderFromLight`); EnvMap takes
                    // its linear part and accounts for a non-rigid one's solid-angle Jacobian.
                    let to_world = Mat3::from_mat4(ctm);
                    if e > 0.0 {
                        let (w, h, texels) = crate::image_io::read_rgb(&path).map_err(|err| {
                            SceneError::invalid(at, format!("infinite light \"{f}\": {err}"))
                        })?;
                        let k = equal_area_illuminance(w, h, &texels);
                        if k > 0.0 && k.is_finite() {
                            s *= e / k;
                        } else {
                            self.warn(format!("{at}: infinite light \"{f}\": \"illuminance\" is given but the map sends no light to its upper hemisphere; the image is used unscaled"));
                        }
                    }
                    self.scene.lights.push(LightDesc::Environment {
                        name,
                        path,
                        scale: Vec3::splat(s),
                        mapping: crate::scene::EnvMapping::EqualArea,
                        transform: Mat4::from_mat3(to_world),
                    });
                } else {
                    let rgb = match l {
                        Some(v) => self.illuminant_rgb(&v, at, "L").unwrap_or(Vec3::ONE),
                        None => Vec3::ONE,
                    };
                    self.note_light_spectrum(&list, "L");
                    if e > 0.0 {
                        // Uniform radiance L gives illuminance π·L on an upward surface.
                        s *= e / std::f32::consts::PI;
                    }
                    self.scene.lights.push(LightDesc::Ambient {
                        name,
                        radiance: rgb * s,
                    });
                }
            }
            "goniometric" | "projection" => {
                self.warn(format!(
                    "{at}: LightSource \"{ty}\" is not supported and was left out"
                ));
                return Ok(());
            }
            other => {
                self.warn(format!(
                    "{at}: LightSource \"{other}\" is unknown and was left out"
                ));
                return Ok(());
            }
        }
        self.note_unused(&list, &format!("LightSource \"{ty}\""), at);
        Ok(())
    }

    fn area_light_source(&mut self, ty: &str, list: ParamList, at: &str) {
        if ty != "diffuse" {
            self.warn(format!(
                "{at}: AreaLightSource \"{ty}\" is unknown; the shapes do not emit"
            ));
            return;
        }
        let l = match list.spectrum("L") {
            Some(s) => self.illuminant_rgb(&s, at, "L").unwrap_or(Vec3::ONE),
            None => Vec3::ONE,
        };
        let scale = list.float("scale", 1.0);
        let two_sided = list.bool("twosided", false);
        // pbrt-v4 normalises `power` per light it creates, i.e. per shape (see `place`).
        let power = list.float("power", -1.0);
        let power = (power > 0.0 && power.is_finite()).then_some(power);
        if list.has("filename") {
            let _ = list.string("filename");
            self.warn(format!(
                "{at}: AreaLightSource \"diffuse\": image emission (\"filename\") is not supported; the constant L is used"
            ));
        }
        self.note_unused(&list, "AreaLightSource \"diffuse\"", at);
        let spectrum = self.light_spectrum(&list, "L");
        self.gs.area_light = Some(AreaLight {
            radiance: l * scale,
            spectrum,
            two_sided,
            power,
        });
    }

    /// The spectrum of a light's `key` (`L`, `I`) when it is not RGB: a `blackbody`, a named
    /// illuminant or file, a sampled list, kept for spectral rendering ([`crate::spectrum::Illuminant`]).
    /// None for RGB (upsampled as pbrt-v4's `RGBIlluminantSpectrum`) and for what
    /// [`Loader::illuminant_rgb`] could not read (it warns).
    fn light_spectrum(
        &mut self,
        list: &ParamList,
        key: &str,
    ) -> Option<crate::spectrum::Illuminant> {
        use crate::spectrum::Illuminant;
        match list.spectrum(key)? {
            SpectrumValue::Rgb(_) => None,
            SpectrumValue::Blackbody(t) => Illuminant::blackbody(t),
            SpectrumValue::Named(n) => Illuminant::named(&n).or_else(|| {
                let v = self.spectrum_file_quiet(&n)?;
                Illuminant::sampled(&v).map(|s| s.renamed(&n))
            }),
            SpectrumValue::Sampled(v) => Illuminant::sampled(&v),
        }
    }

    /// [`Loader::light_spectrum`] of the light about to be pushed to `scene.lights`, recorded in
    /// `scene.light_spectra`.
    fn note_light_spectrum(&mut self, list: &ParamList, key: &str) {
        if let Some(s) = self.light_spectrum(list, key) {
            let i = self.scene.lights.len();
            self.scene.light_spectra.push((i, s));
        }
    }

    /// RGB of a light spectrum (see [`spectra`]); None (with a warning) when it cannot be made.
    pub(crate) fn illuminant_rgb(
        &mut self,
        s: &SpectrumValue,
        at: &str,
        key: &str,
    ) -> Option<Vec3> {
        let r = match s {
            SpectrumValue::Rgb(c) => Some(*c),
            SpectrumValue::Blackbody(t) => spectra::blackbody_rgb(*t),
            SpectrumValue::Named(n) => match spectra::named_illuminant(n) {
                Some(c) => Some(c),
                None => self
                    .spectrum_file(n, at)
                    .and_then(|v| spectra::sampled_illuminant_rgb(&v)),
            },
            SpectrumValue::Sampled(v) => spectra::sampled_illuminant_rgb(v),
        };
        if r.is_none() {
            self.warn(format!(
                "{at}: \"{key}\": spectrum {s:?} is not supported; white is used"
            ));
        }
        r
    }

    /// A spectrum named by a file (pbrt-v4 reads a `"spectrum"` string that is not a built-in
    /// name as a file of (λ, value) pairs, relative to the scene), `None` when it is not one
    /// (the caller warns); a file that cannot be read or parsed is a warning naming it.
    pub(crate) fn spectrum_file(&mut self, name: &str, at: &str) -> Option<Vec<(f32, f32)>> {
        if self.in_memory() {
            return None;
        }
        let path = self.resolve(name, at).ok()?;
        if !path.is_file() {
            return None;
        }
        let parsed = std::fs::metadata(&path)
            .map_err(|e| e.to_string())
            .and_then(|m| {
                if m.len() > 1 << 24 {
                    Err("larger than 16 MiB".to_string())
                } else {
                    crate::limits::read_to_string(&path).map_err(|e| e.to_string())
                }
            })
            .and_then(|t| spectra::parse_spectrum_file(&t));
        match parsed {
            Ok(v) => Some(v),
            Err(e) => {
                self.warn(format!("{at}: spectrum file \"{name}\": {e}"));
                None
            }
        }
    }

    /// [`Loader::spectrum_file`] without its warning (the RGB conversion of the same spectrum
    /// has given it).
    fn spectrum_file_quiet(&mut self, name: &str) -> Option<Vec<(f32, f32)>> {
        let n = self.scene.warnings.len();
        let v = self.spectrum_file(name, "");
        self.scene.warnings.truncate(n);
        v
    }

    /// The Trayecto material for the current graphics state (material plus area light).
    fn current_material(&mut self, at: &str) -> MaterialId {
        let (key, spec) = match self.gs.material.clone() {
            MatRef::Default => ("<default>".to_string(), None),
            MatRef::Anonymous(i) => (format!("#{i}"), self.anonymous_materials.get(i).cloned()),
            MatRef::Named(n) => match self.named_materials.get(&n) {
                Some(s) => (format!("named {n}"), Some(s.clone())),
                // Defined later, or never (then warned at the end).
                None => (format!("pending {n}"), None),
            },
        };
        let pending = match &self.gs.material {
            MatRef::Named(n) if spec.is_none() => Some(n.clone()),
            _ => None,
        };
        let light = self.gs.area_light.clone();
        let full_key = format!("{key}|{light:?}");
        if let Some(id) = self.material_cache.get(&full_key) {
            return *id;
        }
        let mut m = match &spec {
            Some(s) => self.convert_material(s, 0),
            None => Material::diffuse("pbrt default", Vec3::splat(0.5)),
        };
        if let Some(l) = &light {
            m.emissive = l.radiance;
            m.emission_spectrum = l.spectrum.clone();
            m.double_sided = l.two_sided;
        }
        let id = self.scene.add_material(m);
        self.material_cache.insert(full_key, id);
        if let Some(n) = pending {
            self.pending_materials
                .push((id, n, light.clone(), at.to_string()));
        }
        id
    }

    /// The area pbrt-v4 divides an area light's `power` by for `shape` (see [`LightArea`]). A
    /// mesh whose triangles (or patches) differ in area gets one radiance for the mean area —
    /// the total power pbrt-v4 emits — with a warning, as pbrt-v4 gives each its own radiance.
    fn power_area(&mut self, shape: &Shape, area: Option<LightArea>, at: &str) -> Option<f32> {
        match (area?, shape) {
            (LightArea::Quadric(a), _) => Some(a),
            (LightArea::Triangles(n), Shape::Mesh(id)) => {
                let mesh = self.scene.meshes.get(*id)?;
                let ctm = self.gs.ctm;
                let areas: Vec<f32> = mesh
                    .indices
                    .chunks(n as usize)
                    .map(|group| {
                        group
                            .iter()
                            .map(|t| {
                                let p = |i: u32| ctm.transform_point3(mesh.positions[i as usize]);
                                0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length()
                            })
                            .sum::<f32>()
                    })
                    .collect();
                let (lo, hi) = areas.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), &a| {
                    (lo.min(a), hi.max(a))
                });
                if areas.is_empty() {
                    return None;
                }
                let mean = areas.iter().sum::<f32>() / areas.len() as f32;
                if hi > 1.01 * lo {
                    self.warn(format!(
                        "{at}: AreaLightSource \"diffuse\" \"power\": pbrt-v4 gives each of the mesh's {} triangles or patches its own radiance (their areas differ, {lo}..{hi}); Trayecto uses one radiance for the mean area, with the same total power",
                        areas.len()
                    ));
                }
                Some(mean)
            }
            _ => None,
        }
    }

    /// Fills the slots of materials used before their `MakeNamedMaterial` (pbrt-v4 resolves
    /// names at the end of the world block); names never defined keep the default material.
    fn resolve_pending_materials(&mut self) {
        for (id, n, light, at) in std::mem::take(&mut self.pending_materials) {
            match self.named_materials.get(&n).cloned() {
                Some(spec) => {
                    let mut m = self.convert_material(&spec, 0);
                    if let Some(l) = &light {
                        m.emissive = l.radiance;
                        m.emission_spectrum = l.spectrum.clone();
                        m.double_sided = l.two_sided;
                    }
                    self.scene.materials[id] = m;
                }
                None => self.warn_once(
                    &format!("nomat {n}"),
                    format!("{at}: NamedMaterial \"{n}\" is not defined; the default diffuse material is used"),
                ),
            }
        }
    }

    /// Places a shape: in the world, or in the object being defined.
    fn place(&mut self, shape: Shape, name: String, at: &str) {
        let light_area = self.light_area.take();
        let saved = self.gs.area_light.clone();
        if let Some(mut l) = self.gs.area_light.clone()
            && let Some(phi) = l.power.take()
        {
            match self.power_area(&shape, light_area, at) {
                Some(a) if a > 0.0 && a.is_finite() => {
                    let sides = if l.two_sided { 2.0 } else { 1.0 };
                    l.radiance *= phi / (std::f32::consts::PI * sides * a);
                }
                _ => self.warn(format!(
                    "{at}: AreaLightSource \"diffuse\": \"power\" is not supported for this shape; L × scale is used"
                )),
            }
            self.gs.area_light = Some(l);
        }
        let material = self.current_material(at);
        self.gs.area_light = saved;
        let moving = self.gs.ctm != self.gs.ctm_end;
        if moving && self.current_object.is_some() {
            self.warn_once(
                "motion",
                format!("{at}: Shape: a moving shape inside an object definition (ObjectBegin) is rendered at its start time (motion blur of instanced parts is not supported)"),
            );
        }
        if self.current_object.is_some() {
            let medium = self.shape_medium_interface(at);
            let transform = self.gs.ctm;
            if let Some((_, parts)) = &mut self.current_object {
                parts.push(InstancePart {
                    shape,
                    transform,
                    material,
                    name,
                    medium,
                });
            }
        } else {
            self.scene.add_object(&name, shape, self.gs.ctm, material);
            if moving {
                // pbrt-v4 `AnimatedTransform` between the two TransformTimes.
                self.motion
                    .push(crate::scene::animation::RigidMotion::Object {
                        object: self.scene.objects.len() - 1,
                        motion: crate::scene::animation::MovingTransform {
                            times: self.transform_times,
                            start: self.gs.ctm,
                            end: self.gs.ctm_end,
                        },
                    });
            }
            let mi = self.shape_medium_interface(at);
            if let Some(o) = self.scene.objects.last_mut() {
                o.medium = mi;
            }
        }
    }

    /// A named medium by name: `Ok(None)` for vacuum ("") or an unmapped type (warned where it
    /// was made); an undefined name is warned here and rendered as vacuum.
    fn medium_id(&mut self, name: &str, at: &str) -> Option<crate::scene::MediumId> {
        if name.is_empty() {
            return None;
        }
        match self.media.get(name) {
            Some(id) => *id,
            None => {
                self.warn(format!(
                    "{at}: medium \"{name}\" is not defined (MakeNamedMedium); vacuum is used"
                ));
                None
            }
        }
    }

    /// The shape's medium interface from the current `MediumInterface`. As in pbrt-v4's
    /// `GeometricPrimitive`, a shape whose two sides name the same medium is not a transition and
    /// leaves the ray's medium as it was (`None`).
    fn shape_medium_interface(&mut self, at: &str) -> Option<crate::scene::MediumInterface> {
        let (i, o) = (
            self.gs.medium_inside.clone(),
            self.gs.medium_outside.clone(),
        );
        if i == o {
            return None;
        }
        let inside = self.medium_id(&i, at);
        let outside = self.medium_id(&o, at);
        Some(crate::scene::MediumInterface { inside, outside })
    }

    /// `MakeNamedMedium`: `homogeneous` and `uniformgrid` map onto [`crate::scene::MediumDesc`]
    /// (pbrt-v4 defaults: σa = σs = 1, scale 1, g 0; the grid spans p0–p1 of the medium space
    /// given by the CTM, looked up with pbrt-v4's zero-outside-the-samples edge); both read
    /// emission (`Le`, `Lescale`; grids also `temperature`); other types are warnings.
    fn make_named_medium(&mut self, name: &str, p: &ParamList, at: &str) -> Result<(), SceneError> {
        use crate::scene::{MediumDesc, MediumKind};
        let ty = p.string("type").unwrap_or_default();
        let what = format!("MakeNamedMedium \"{name}\" (\"{ty}\")");
        if self.media.contains_key(name) {
            self.warn(format!(
                "{at}: {what}: redefines the medium; the new definition is used"
            ));
        }
        if ty == "nanovdb" {
            // pbrt-v4 reads NanoVDB files (.nvdb); no maintained Rust reader of that format
            // exists (the `vdb-rs` crate reads OpenVDB .vdb files, not NanoVDB).
            let file = p.string("filename").unwrap_or_default();
            self.warn(format!(
                "{at}: {what}: NanoVDB grid \"{file}\" is not supported (no Rust reader of the NanoVDB format is available; convert the grid to a \"uniformgrid\" medium); the medium is ignored (vacuum)"
            ));
        } else if !matches!(ty.as_str(), "homogeneous" | "uniformgrid") {
            self.warn(format!(
                "{at}: {what}: medium type \"{ty}\" is not supported; the medium is ignored (vacuum)"
            ));
        }
        if !matches!(ty.as_str(), "homogeneous" | "uniformgrid") {
            for q in &p.params {
                q.used.set(true);
            }
            self.media.insert(name.to_string(), None);
            return Ok(());
        }
        if let Some(pr) = p.string("preset") {
            self.warn(format!(
                "{at}: {what}: preset \"{pr}\" (measured scattering coefficients) is not supported; sigma_a/sigma_s are used"
            ));
        }
        let coef = |l: &mut Loader, key: &str| -> Vec3 {
            match p.spectrum(key) {
                Some(sv) => l.spectrum_as_rgb(&sv, at, key),
                None => Vec3::ONE,
            }
        };
        let sigma_a = coef(self, "sigma_a");
        let sigma_s = coef(self, "sigma_s");
        // Sampled σa/σs (inline or a file) stay spectra for spectral rendering.
        let mut sigma_spectra = [None, None];
        for (slot, key) in sigma_spectra.iter_mut().zip(["sigma_a", "sigma_s"]) {
            *slot = match p.spectrum(key) {
                Some(SpectrumValue::Sampled(v)) => crate::spectrum::SpectrumTable::sampled(&v),
                Some(SpectrumValue::Named(n)) => self
                    .spectrum_file_quiet(&n)
                    .and_then(|v| crate::spectrum::SpectrumTable::sampled(&v)),
                _ => None,
            };
        }
        // A kept σ spectrum is what spectral rendering takes; RGB takes its projection, which a
        // narrow band (its projection a spectral colour outside the sRGB gamut) makes negative in
        // a channel: RGB clamps that channel, with a warning, instead of refusing the medium.
        // The spectrum itself must be non-negative.
        let mut sigma = [sigma_a, sigma_s];
        for ((rgb, table), key) in sigma
            .iter_mut()
            .zip(&sigma_spectra)
            .zip(["sigma_a", "sigma_s"])
        {
            let Some(t) = table else { continue };
            if let Some(l) = (360..=830).find(|&l| !(t.value(l as f32) >= 0.0)) {
                return Err(SceneError::invalid(
                    at,
                    format!("{what}: \"{key}\" is negative at {l} nm"),
                ));
            }
            if rgb.min_element() < 0.0 {
                let c = rgb.max(Vec3::ZERO);
                self.warn(format!(
                    "{at}: {what}: the RGB projection {:?} of the spectrum \"{key}\" is outside the sRGB gamut; RGB rendering uses {:?}, --spectral the spectrum itself",
                    rgb.to_array(),
                    c.to_array()
                ));
                *rgb = c;
            }
        }
        let [sigma_a, sigma_s] = sigma;
        let scale = p.float("scale", 1.0);
        let g = p.float("g", 0.0);
        // Emission (pbrt-v4 `Le`, an illuminant spectrum, times `Lescale`; σa·Le per unit
        // length). A homogeneous medium's `Lescale` is one number; a uniformgrid's is a grid
        // (read below with the density).
        let mut le = Vec3::ZERO;
        if ty == "homogeneous" && p.has("Le") {
            let sv = p.spectrum("Le");
            let rgb = match &sv {
                Some(s) => self.illuminant_rgb(s, at, "Le").unwrap_or(Vec3::ONE),
                None => Vec3::ZERO,
            };
            le = rgb * p.float("Lescale", 1.0);
        } else if ty == "homogeneous" && p.has("Lescale") {
            let _ = p.float("Lescale", 1.0);
        }
        let mut kind = if ty == "uniformgrid" {
            let nx = p.int("nx", 1);
            let ny = p.int("ny", 1);
            let nz = p.int("nz", 1);
            let density = p.floats("density").unwrap_or_default();
            let n = (nx.max(0) as u128) * (ny.max(0) as u128) * (nz.max(0) as u128);
            if nx < 1 || ny < 1 || nz < 1 || n != density.len() as u128 {
                return Err(SceneError::invalid(
                    at,
                    format!(
                        "{what}: \"density\" has {} values, not nx·ny·nz = {nx}·{ny}·{nz}",
                        density.len()
                    ),
                ));
            }
            let emission =
                self.grid_emission(p, [nx as usize, ny as usize, nz as usize], at, &what)?;
            MediumKind::Grid {
                nx: nx as usize,
                ny: ny as usize,
                nz: nz as usize,
                density,
                min: p.point3("p0", Vec3::ZERO),
                max: p.point3("p1", Vec3::ONE),
                transform: self.gs.ctm,
                // pbrt-v4 `SampledGrid::Lookup` reads voxels outside the grid as 0.
                edge: crate::scene::GridEdge::Zero,
                emission,
            }
        } else {
            MediumKind::Homogeneous
        };
        let _ = p.string("type");
        // An `Le` given as a spectrum (not RGB) stays one for spectral rendering.
        let le_spectrum = if p.has("Le") && (ty == "homogeneous" || ty == "uniformgrid") {
            self.light_spectrum(p, "Le")
        } else {
            None
        };
        if le_spectrum.is_some() {
            le = self.emission_in_gamut(le, at, &what);
            if let MediumKind::Grid {
                emission: Some(crate::scene::GridEmission::Radiance { le, .. }),
                ..
            } = &mut kind
            {
                *le = self.emission_in_gamut(*le, at, &what);
            }
        }
        let desc = MediumDesc {
            name: name.to_string(),
            sigma_a,
            sigma_s,
            scale,
            g,
            le,
            kind,
            sigma_spectra,
            le_spectrum,
        };
        desc.validate()
            .map_err(|e| SceneError::invalid(at, format!("{what}: {e}")))?;
        self.note_unused(p, &what, at);
        let id = self.scene.add_medium(desc);
        self.media.insert(name.to_string(), Some(id));
        Ok(())
    }

    /// The RGB emission of a medium whose `Le` is a spectrum, for RGB rendering: a narrow band
    /// projects outside the sRGB gamut (a negative channel), which RGB cannot render; its
    /// negative channels are clamped and the result scaled back to the projection's luminance,
    /// which spectral rendering scales the spectrum by ([`crate::spectrum::Illuminant::at`]), so
    /// that spectral rendering stays exact. Warns when it clamps.
    fn emission_in_gamut(&mut self, rgb: Vec3, at: &str, what: &str) -> Vec3 {
        if !(rgb.min_element() < 0.0) {
            return rgb;
        }
        let y = |c: Vec3| 0.212_672_9 * c.x + 0.715_152_2 * c.y + 0.072_175 * c.z;
        let clamped = rgb.max(Vec3::ZERO);
        let c = if y(clamped) > 0.0 {
            clamped * (y(rgb) / y(clamped))
        } else {
            clamped
        };
        self.warn(format!(
            "{at}: {what}: the RGB projection {:?} of the spectrum \"Le\" is outside the sRGB gamut; RGB rendering uses {:?} (its luminance), --spectral the spectrum itself",
            rgb.to_array(),
            c.to_array()
        ));
        c
    }

    /// A `uniformgrid`'s emission as pbrt-v4's `GridMedium::Create` reads it (media.cpp): `Le`
    /// (an illuminant spectrum, normalised by 1/SpectrumToPhotometric) or a `temperature` grid
    /// (blackbody, `temperatureoffset` — alias `temperaturecutoff` — and `temperaturescale`), never
    /// both; either weighted by the `Lescale` grid (nx·ny·nz values), which is one sample of 1 at
    /// the box centre when absent. Counts that do not match nx·ny·nz are errors, as in pbrt-v4.
    fn grid_emission(
        &mut self,
        p: &ParamList,
        [nx, ny, nz]: [usize; 3],
        at: &str,
        what: &str,
    ) -> Result<Option<crate::scene::GridEmission>, SceneError> {
        use crate::scene::{GridEmission, VoxelGrid};
        let n = nx * ny * nz;
        let grid = |key: &str, data: Vec<f32>| -> Result<VoxelGrid, SceneError> {
            if data.len() != n {
                return Err(SceneError::invalid(
                    at,
                    format!(
                        "{what}: \"{key}\" has {} values, not nx·ny·nz = {nx}·{ny}·{nz}",
                        data.len()
                    ),
                ));
            }
            Ok(VoxelGrid { nx, ny, nz, data })
        };
        let temperature = p.floats("temperature").filter(|t| !t.is_empty());
        let le = if p.has("Le") { p.spectrum("Le") } else { None };
        let scale = match p.floats("Lescale") {
            Some(v) if !v.is_empty() => grid("Lescale", v)?,
            _ => VoxelGrid::single(1.0),
        };
        let t_offset = p.float("temperatureoffset", p.float("temperaturecutoff", 0.0));
        let t_scale = p.float("temperaturescale", 1.0);
        match (le, temperature) {
            (Some(_), Some(_)) => Err(SceneError::invalid(
                at,
                format!(
                    "{what}: both \"Le\" and \"temperature\" are given (pbrt-v4 refuses this too)"
                ),
            )),
            (Some(sv), None) => {
                let rgb = self.illuminant_rgb(&sv, at, "Le").unwrap_or(Vec3::ONE);
                Ok((rgb.max_element() > 0.0).then_some(GridEmission::Radiance { le: rgb, scale }))
            }
            (None, Some(t)) => Ok(Some(GridEmission::Blackbody {
                temperature: grid("temperature", t)?,
                scale,
                temperature_scale: t_scale,
                offset: t_offset,
            })),
            (None, None) => Ok(None),
        }
    }

    fn finish(mut self) -> Result<Scene, SceneError> {
        if let Some((n, at)) = self.camera_medium.take() {
            self.scene.camera_medium = self.medium_id(&n, &at);
        }
        if let Some((n, _)) = &self.current_object {
            return Err(SceneError::invalid(
                "end of file",
                format!("ObjectBegin \"{n}\" is never closed"),
            ));
        }
        if let Some((_, _, opened)) = self.stack.last() {
            self.warn(format!("{opened}: this block is never closed"));
        }
        self.resolve_pending_materials();
        self.load_plys()?;
        self.default_triangle_uvs();
        self.run_image_jobs();
        self.run_procedural_means();
        self.camera_and_film()?;
        self.finish_motion();
        Ok(self.scene)
    }

    /// Meshes without uvs under a material that reads texture coordinates get pbrt-v4's
    /// per-triangle (0, 0), (1, 0), (1, 1) ([`shapes::give_default_triangle_uvs`]).
    fn default_triangle_uvs(&mut self) {
        let mut done = vec![false; self.scene.meshes.len()];
        for i in 0..self.scene.objects.len() {
            let o = &self.scene.objects[i];
            let Shape::Mesh(id) = o.shape else { continue };
            if done.get(id).copied() != Some(false)
                || self.scene.meshes[id].uv0.is_some()
                || !shapes::material_uses_uv(&self.scene.materials, o.material)
            {
                continue;
            }
            done[id] = true;
            shapes::give_default_triangle_uvs(&mut self.scene.meshes[id]);
        }
    }

    /// pbrt-v4's `PixelFilter`: box, gaussian, mitchell and triangle with their parameters
    /// (`xradius`, `yradius`, `sigma`, `B`, `C`) become the scene's filter hint; `sinc` (Lanczos)
    /// is not built and falls back to pbrt's default Gaussian with a warning.
    fn pixel_filter(&mut self, ty: &str, list: &ParamList, at: &str) -> Result<(), SceneError> {
        use crate::film::filter::{Filter, FilterKind};
        let kind = match ty {
            "box" => FilterKind::Box,
            "gaussian" => FilterKind::Gaussian,
            "mitchell" => FilterKind::Mitchell,
            "triangle" => FilterKind::Tent,
            other => {
                for k in ["xradius", "yradius", "tau"] {
                    let _ = list.float(k, 0.0);
                }
                self.warn(format!(
                    "{at}: PixelFilter \"{other}\" is not supported: pbrt's default Gaussian (radius 1.5, sigma 0.5) is used"
                ));
                self.scene.hints.filter = Some(Filter::new(FilterKind::Gaussian));
                return Ok(());
            }
        };
        let mut f = Filter::new(kind);
        f.radius = [
            list.float("xradius", f.radius[0]),
            list.float("yradius", f.radius[1]),
        ];
        if kind == FilterKind::Gaussian {
            f.sigma = list.float("sigma", f.sigma);
        }
        if kind == FilterKind::Mitchell {
            f.b = list.float("B", f.b);
            f.c = list.float("C", f.c);
        }
        f.validate()
            .map_err(|e| SceneError::invalid(at, format!("PixelFilter \"{ty}\": {e}")))?;
        self.scene.hints.filter = Some(f);
        Ok(())
    }

    fn camera_and_film(&mut self) -> Result<(), SceneError> {
        let (xres, yres, crop, pixel_bounds, iso) = match self.settings.film.take() {
            Some((film, at)) => {
                // The sensor's ISO (pbrt-v4 `PixelSensor::Create`, default 100).
                let iso = film.float("iso", 100.0);
                if !(iso.is_finite() && iso > 0.0) {
                    return Err(SceneError::invalid(
                        &at,
                        format!("Film: iso must be a positive number (got {iso})"),
                    ));
                }
                let x = film.int("xresolution", 1280);
                let y = film.int("yresolution", 720);
                if !(1..=65536).contains(&x) || !(1..=65536).contains(&y) {
                    return Err(SceneError::invalid(
                        &at,
                        format!("Film: resolution {x}×{y} is out of range"),
                    ));
                }
                let crop = film.floats("cropwindow");
                let bounds = film.ints("pixelbounds");
                if let Some(f) = film.string("filename") {
                    self.warn(format!(
                        "{at}: Film \"filename\" \"{f}\" is ignored: the output is what the command line names"
                    ));
                }
                self.note_unused(&film, "Film", &at);
                let crop = match crop {
                    Some(c) if c.len() == 4 => {
                        // pbrt-v4: each pair is ordered and clamped to [0, 1].
                        let cl = |v: f32| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
                        let c = [
                            cl(c[0].min(c[1])),
                            cl(c[0].max(c[1])),
                            cl(c[2].min(c[3])),
                            cl(c[2].max(c[3])),
                        ];
                        if c == [0.0, 1.0, 0.0, 1.0] {
                            None
                        } else if c[0] < c[1] && c[2] < c[3] {
                            Some(c)
                        } else {
                            return Err(SceneError::invalid(
                                &at,
                                format!(
                                    "Film: cropwindow {} {} {} {} holds no pixel",
                                    c[0], c[1], c[2], c[3]
                                ),
                            ));
                        }
                    }
                    Some(_) => {
                        return Err(SceneError::invalid(&at, "Film: cropwindow needs 4 values"));
                    }
                    None => None,
                };
                // pbrt-v4: pixel bounds x0 x1 y0 y1 within the image, used when no crop window
                // is given (with both, pbrt uses the crop window and so does Trayecto).
                let pixel_bounds = match bounds {
                    Some(b) if b.len() == 4 => {
                        // pbrt-v4 clamps the bounds to the image, with a warning.
                        let c = [
                            b[0].clamp(0, x),
                            b[1].clamp(0, x),
                            b[2].clamp(0, y),
                            b[3].clamp(0, y),
                        ];
                        if c[..] != b[..] {
                            self.warn(format!("{at}: Film \"pixelbounds\" extend beyond the {x}×{y} image: clamped"));
                        }
                        if !(c[0] < c[1] && c[2] < c[3]) {
                            return Err(SceneError::invalid(
                                &at,
                                format!(
                                    "Film: pixelbounds {} {} {} {} holds no pixel of the {x}×{y} image",
                                    b[0], b[1], b[2], b[3]
                                ),
                            ));
                        }
                        let c = [c[0] as u32, c[1] as u32, c[2] as u32, c[3] as u32];
                        (c != [0, x as u32, 0, y as u32]).then_some(c)
                    }
                    Some(_) => {
                        return Err(SceneError::invalid(&at, "Film: pixelbounds needs 4 values"));
                    }
                    None => None,
                };
                if crop.is_some() && pixel_bounds.is_some() {
                    self.warn(format!("{at}: Film has both \"cropwindow\" and \"pixelbounds\": the crop window is used, as pbrt-v4 does"));
                }
                (x as u32, y as u32, crop, pixel_bounds, iso)
            }
            None => (1280, 720, None, None, 100.0),
        };
        self.scene.hints.width = Some(xres);
        self.scene.hints.height = Some(yres);
        self.scene.hints.crop = crop;
        self.scene.hints.pixel_bounds = pixel_bounds;
        // pbrt-v4 reconstructs with a Gaussian (radius 1.5, sigma 0.5) when the file names no
        // PixelFilter.
        if self.scene.hints.filter.is_none() {
            self.scene.hints.filter = Some(crate::film::filter::Filter::new(
                crate::film::filter::FilterKind::Gaussian,
            ));
        }
        let (camera_from_world, list, at, ty) = match self.settings.camera.take() {
            Some(c) => c,
            None => {
                self.warn("no Camera directive: pbrt's default camera (at the origin looking down +z, fov 90) is used".into());
                (
                    Mat4::IDENTITY,
                    ParamList::default(),
                    "default camera".into(),
                    "perspective".into(),
                )
            }
        };
        let Some(world_from_camera) = invert(&camera_from_world) else {
            return Err(SceneError::invalid(
                &at,
                "Camera: the camera transform is singular",
            ));
        };
        let aspect = xres as f32 / yres as f32;
        let mut projection = match ty.as_str() {
            "orthographic" => Projection::Orthographic { half_height: 1.0 },
            "spherical" => {
                let m = list.string("mapping").unwrap_or_else(|| "equalarea".into());
                Projection::Spherical(match m.as_str() {
                    "equalarea" => SphericalMapping::EqualArea,
                    "equirectangular" => SphericalMapping::Equirectangular,
                    _ => {
                        return Err(SceneError::invalid(
                            &at,
                            format!(
                                "Camera \"spherical\": unknown mapping \"{m}\" (must be \"equalarea\" or \"equirectangular\")"
                            ),
                        ));
                    }
                })
            }
            _ => Projection::Perspective,
        };
        // pbrt-v4's orthographic and spherical cameras have no field of view (a `fov` is left
        // unread, so it is reported as unused).
        let fov = match projection {
            Projection::Perspective => list.float("fov", 90.0),
            _ => 90.0,
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(SceneError::invalid(
                &at,
                format!("Camera: fov {fov} is not in (0, 180)"),
            ));
        }
        // pbrt-v4 PerspectiveCamera: the screen window is [-a, a] × [-1, 1] for wide frames and
        // [-1, 1] × [-1/a, 1/a] for tall ones (a = `frameaspectratio`, by default the film's),
        // scaled by tan(fov/2): fov spans the shorter axis. A `screenwindow` replaces it. The
        // OrthographicCamera has the same window, unscaled, in camera-space units (t = 1).
        let ortho = matches!(projection, Projection::Orthographic { .. });
        let t = if ortho {
            1.0
        } else {
            (fov.to_radians() * 0.5).tan()
        };
        let frame = list.float("frameaspectratio", aspect);
        if !(frame.is_finite() && frame > 0.0) {
            return Err(SceneError::invalid(
                &at,
                format!("Camera: frameaspectratio {frame} is not positive"),
            ));
        }
        let mut half_h = if aspect >= 1.0 { t } else { t / aspect };
        let default_window = if frame >= 1.0 {
            [-frame, frame, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / frame, 1.0 / frame]
        };
        let window = match list.floats("screenwindow") {
            Some(sw) if sw.len() == 4 && sw[1] > sw[0] && sw[3] > sw[2] => {
                Some([sw[0], sw[1], sw[2], sw[3]])
            }
            Some(_) => {
                return Err(SceneError::invalid(
                    &at,
                    "Camera: screenwindow needs 4 increasing values",
                ));
            }
            None => (frame != aspect).then_some(default_window),
        };
        // An off-centre window, or one whose aspect differs from the film's (pbrt stretches the
        // image), is the centred window of the same height seen through a shear of camera space:
        // S(X, Y, −1) = (sx·X + cx·t, Y + cy·t, −1) maps Trayecto's direction through film point
        // (nx, ny) ∈ [−1, 1]², (nx·hy·t·aspect, ny·hy·t, −1), to pbrt's, ((cx + hx·nx)·t,
        // (cy + hy·ny)·t, −1), with (cx, cy) the window's centre and (hx, hy) its half sizes.
        // The lens (z = 0) and the plane of focus (z = −focaldistance) keep their depths, so the
        // thin lens is unchanged; the centred, film-shaped window keeps the camera as it was.
        let mut shear = None;
        if let Some(sw) = window {
            let (cx, cy) = (0.5 * (sw[0] + sw[1]), 0.5 * (sw[2] + sw[3]));
            let (hx, hy) = (0.5 * (sw[1] - sw[0]), 0.5 * (sw[3] - sw[2]));
            half_h = t * hy;
            let sx = hx / (hy * aspect);
            let centred = cx.abs() < 1e-6 * hx && cy.abs() < 1e-6 * hy;
            if !(centred && (sx - 1.0).abs() < 1e-6) {
                // Orthographic rays are parallel: the window's centre is a translation of the
                // origins, (cx, cy, 0), instead of a shear of the directions.
                shear = Some(if ortho {
                    Mat4::from_cols(
                        crate::math::Vec4::new(sx, 0.0, 0.0, 0.0),
                        crate::math::Vec4::new(0.0, 1.0, 0.0, 0.0),
                        crate::math::Vec4::Z,
                        crate::math::Vec4::new(cx, cy, 0.0, 1.0),
                    )
                } else {
                    Mat4::from_cols(
                        crate::math::Vec4::new(sx, 0.0, 0.0, 0.0),
                        crate::math::Vec4::new(0.0, 1.0, 0.0, 0.0),
                        crate::math::Vec4::new(-cx * t, -cy * t, 1.0, 0.0),
                        crate::math::Vec4::W,
                    )
                });
                if ortho && list.float("lensradius", 0.0) > 0.0 {
                    self.warn(format!("{at}: Camera \"orthographic\": with a lens and an off-centre or stretched screen window the lens is centred on the window (pbrt-v4 centres it on the camera's axis)"));
                } else if (sx - 1.0).abs() >= 1e-6 && list.float("lensradius", 0.0) > 0.0 {
                    self.warn(format!("{at}: Camera: the screen window's aspect ratio differs from the film's: the image is stretched as in pbrt-v4, and so is the lens aperture (pbrt-v4's stays round)"));
                }
            }
        }
        let vfov = 2.0 * half_h.atan().to_degrees();
        let lens = list.float("lensradius", 0.0);
        let focus = list.float("focaldistance", 1e6);
        if !(lens >= 0.0 && lens.is_finite() && focus > 0.0 && focus.is_finite()) {
            return Err(SceneError::invalid(
                &at,
                "Camera: lensradius must be ≥ 0 and focaldistance > 0",
            ));
        }
        // pbrt-v4 cameras' shutter (default 0 to 1): the motion blur interval unless
        // `--shutter` says (crate::world::motion).
        let shutter = (
            list.float("shutteropen", 0.0) as f64,
            list.float("shutterclose", 1.0) as f64,
        );
        if !(shutter.0.is_finite() && shutter.1.is_finite() && shutter.0 <= shutter.1) {
            return Err(SceneError::invalid(
                &at,
                "Camera: shutteropen must be at most shutterclose",
            ));
        }
        self.shutter = Some(shutter);
        match &mut projection {
            Projection::Orthographic { half_height } => *half_height = half_h,
            Projection::Spherical(_) => {
                // pbrt-v4's SphericalCamera reads the window and the lens but uses neither.
                if lens > 0.0 {
                    self.warn(format!("{at}: Camera \"spherical\": \"lensradius\" is ignored, as pbrt-v4 ignores it"));
                }
                shear = None;
            }
            Projection::Perspective => {}
        }
        self.note_unused(&list, "Camera", &at);
        // pbrt camera space looks down +z; Trayecto's looks down −z with the same x and y.
        let flip = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        if let Some(end) = self.camera_end.take() {
            match invert(&end) {
                Some(world_from_end) => {
                    let to_world = |w: Mat4| match shear {
                        Some(shear) => w * flip * shear,
                        None => w * flip,
                    };
                    // pbrt-v4 interpolates the camera's world-from-camera transform.
                    self.motion
                        .push(crate::scene::animation::RigidMotion::Camera {
                            camera: self.scene.cameras.len(),
                            motion: crate::scene::animation::MovingTransform {
                                times: self.transform_times,
                                start: to_world(world_from_camera),
                                end: to_world(world_from_end),
                            },
                        });
                }
                None => self.warn(format!(
                    "{at}: Camera: the end-time camera transform is singular; the camera does not move"
                )),
            }
        }
        self.scene.cameras.push(CameraDesc {
            name: "pbrt camera".into(),
            camera_to_world: match shear {
                Some(shear) => world_from_camera * flip * shear,
                None => world_from_camera * flip,
            },
            vfov_deg: vfov,
            aspect: Some(aspect),
            // pbrt-v4's default window follows the film: at another resolution the field of
            // view still spans the shorter side. An explicit `screenwindow` or
            // `frameaspectratio` is fixed to the file's film instead, and fitted as any camera.
            fit: if let Some(fit) = self.camera_fit {
                fit
            } else if window.is_none() {
                crate::scene::SensorFit::Shorter
            } else {
                crate::scene::SensorFit::Auto
            },
            aperture_radius: if matches!(projection, Projection::Spherical(_)) {
                0.0
            } else {
                lens
            },
            focus_distance: focus,
            projection,
        });
        self.sensor_gain(shutter, iso, &at);
        Ok(())
    }

    /// pbrt-v4's film records `exposureTime · ISO / 100` times the radiance (`PixelSensor`'s
    /// imaging ratio), the exposure time being the camera's `shutterclose − shutteropen`
    /// (`Film::Create` reads it from the camera): a shutter open over [0.25, 1] gives an image
    /// three quarters as bright as over the default [0, 1]. Trayecto's film records radiance, so
    /// the ratio is folded into every emitter (the image is linear in them); at pbrt's defaults
    /// it is 1 and nothing is touched. `--shutter` changes the blur, not this gain, which is the
    /// file's.
    fn sensor_gain(&mut self, shutter: (f64, f64), iso: f32, at: &str) {
        let exposure = (shutter.1 - shutter.0) as f32;
        if exposure <= 0.0 {
            self.warn(format!(
                "{at}: Camera: the shutter never opens (shutteropen = shutterclose); pbrt-v4 refuses such a file, Trayecto renders it without the exposure time's gain"
            ));
        }
        let ratio = if exposure > 0.0 { exposure } else { 1.0 } * iso / 100.0;
        if ratio != 1.0 {
            scale_emission(&mut self.scene, ratio);
        }
    }
}

/// Multiplies everything that emits light in `scene` by `k`: lights, emissive materials and
/// emitting media.
fn scale_emission(scene: &mut Scene, k: f32) {
    for l in &mut scene.lights {
        match l {
            LightDesc::Point { intensity, .. } | LightDesc::Spot { intensity, .. } => {
                *intensity *= k
            }
            LightDesc::Directional { irradiance, .. } => *irradiance *= k,
            LightDesc::Ambient { radiance, .. } => *radiance *= k,
            LightDesc::Environment { scale, .. } => *scale *= k,
        }
    }
    for m in &mut scene.materials {
        m.emissive *= k;
    }
    for m in &mut scene.media {
        m.le *= k;
        if let crate::scene::MediumKind::Grid {
            emission: Some(e), ..
        } = &mut m.kind
        {
            let scale = match e {
                crate::scene::GridEmission::Radiance { scale, .. }
                | crate::scene::GridEmission::Blackbody { scale, .. } => scale,
            };
            scale.data.iter_mut().for_each(|v| *v *= k);
        }
    }
}

/// pbrt's LookAt: the camera-from-world transform of a left-handed frame whose +z looks from
/// `pos` towards `look`, +y along `up` (pbrt-v4 transform.cpp, `LookAt`).
fn look_at(pos: Vec3, look: Vec3, up: Vec3) -> Result<Mat4, String> {
    let dir = look - pos;
    if !(dir.length_squared() > 0.0) {
        return Err("the eye and the target are the same point".into());
    }
    let dir = dir.normalize();
    if !(up.length_squared() > 0.0) {
        return Err("the up vector is zero".into());
    }
    let right = up.normalize().cross(dir);
    if !(right.length_squared() > 1e-12) {
        return Err("the up vector and the viewing direction are parallel".into());
    }
    let right = right.normalize();
    let new_up = dir.cross(right);
    let world_from_camera = Mat4::from_cols(
        right.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        pos.extend(1.0),
    );
    Ok(world_from_camera.inverse())
}

fn invert(m: &Mat4) -> Option<Mat4> {
    let d = m.determinant();
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let inv = m.inverse();
    crate::math::mat4_is_finite(&inv).then_some(inv)
}

fn short(s: &str) -> String {
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.to_string()
    }
}

fn describe(t: &Token) -> String {
    match &t.kind {
        TokenKind::Str(s) => format!("the string \"{}\"", short(s)),
        TokenKind::Word(w) => format!("'{}'", short(w)),
        TokenKind::Open => "'['".into(),
        TokenKind::Close => "']'".into(),
    }
}

/// Reads directive arguments and parameter lists from the token stream.
struct Cursor<'a> {
    tokens: &'a [Token],
    pos: usize,
    file: &'a str,
    /// Warnings about parameter values, moved to the scene's after each directive.
    warnings: Vec<String>,
}

impl<'a> Cursor<'a> {
    fn next(&mut self) -> Option<&'a Token> {
        let t = self.tokens.get(self.pos)?;
        self.pos += 1;
        Some(t)
    }

    fn peek(&self) -> Option<&'a Token> {
        self.tokens.get(self.pos)
    }

    fn err(&self, at: &str, m: String) -> SceneError {
        let at = match self.tokens.get(self.pos.saturating_sub(1)) {
            Some(t) => loc(self.file, t.line),
            None => at.to_string(),
        };
        SceneError::invalid(at, m)
    }

    fn string(&mut self, at: &str) -> Result<String, SceneError> {
        match self.next() {
            Some(Token {
                kind: TokenKind::Str(s),
                ..
            }) => Ok(s.clone()),
            Some(t) => Err(self.err(
                at,
                format!("expected a quoted string, found {}", describe(t)),
            )),
            None => Err(SceneError::invalid(
                at,
                "the file ends where a quoted string was expected",
            )),
        }
    }

    fn optional_string(&mut self) -> Option<String> {
        if let Some(Token {
            kind: TokenKind::Str(s),
            ..
        }) = self.peek()
        {
            self.pos += 1;
            return Some(s.clone());
        }
        None
    }

    fn word(&mut self, at: &str) -> Result<String, SceneError> {
        match self.next() {
            Some(Token {
                kind: TokenKind::Word(s) | TokenKind::Str(s),
                ..
            }) => Ok(s.clone()),
            Some(t) => Err(self.err(at, format!("expected a word, found {}", describe(t)))),
            None => Err(SceneError::invalid(
                at,
                "the file ends where a word was expected",
            )),
        }
    }

    fn number(&mut self, at: &str) -> Result<f32, SceneError> {
        match self.next() {
            Some(Token {
                kind: TokenKind::Word(w),
                ..
            }) => {
                let v: f64 = w
                    .parse()
                    .map_err(|_| self.err(at, format!("'{}' is not a number", short(w))))?;
                let v = v as f32;
                if !v.is_finite() {
                    return Err(self.err(at, format!("'{}' is not a finite number", short(w))));
                }
                Ok(v)
            }
            Some(t) => Err(self.err(at, format!("expected a number, found {}", describe(t)))),
            None => Err(SceneError::invalid(
                at,
                "the file ends where a number was expected",
            )),
        }
    }

    fn numbers(&mut self, n: usize, at: &str) -> Result<Vec<f32>, SceneError> {
        (0..n).map(|_| self.number(at)).collect()
    }

    /// 16 numbers, bracketed or bare.
    fn matrix(&mut self, at: &str) -> Result<[f32; 16], SceneError> {
        let bracketed = matches!(self.peek().map(|t| &t.kind), Some(TokenKind::Open));
        if bracketed {
            self.pos += 1;
        }
        let v = self.numbers(16, at)?;
        if bracketed {
            match self.next() {
                Some(Token {
                    kind: TokenKind::Close,
                    ..
                }) => {}
                _ => return Err(self.err(at, "a matrix needs exactly 16 numbers and a ']'".into())),
            }
        }
        let mut m = [0.0; 16];
        m.copy_from_slice(&v);
        Ok(m)
    }

    /// A parameter list: `"type name" value` pairs until the next directive.
    fn params(&mut self, at: &str) -> Result<ParamList, SceneError> {
        let mut list = ParamList::default();
        while let Some(Token {
            kind: TokenKind::Str(decl),
            line,
        }) = self.peek()
        {
            self.pos += 1;
            let here = loc(self.file, *line);
            let values = self.values(&here)?;
            let p = Param::new(decl, values).map_err(|m| SceneError::invalid(&here, m))?;
            if let Some(w) = p.doubt() {
                self.warnings.push(format!("{here}: {w}"));
            }
            list.push(p).map_err(|m| SceneError::invalid(&here, m))?;
        }
        let _ = at;
        Ok(list)
    }

    fn values(&mut self, at: &str) -> Result<Values, SceneError> {
        let mut nums = Vec::new();
        let mut strs = Vec::new();
        let push = |t: &Token, nums: &mut Vec<f64>, strs: &mut Vec<String>| -> Result<(), String> {
            match &t.kind {
                TokenKind::Str(s) => strs.push(s.clone()),
                TokenKind::Word(w) if w == "true" || w == "false" => strs.push(w.clone()),
                TokenKind::Word(w) => {
                    let v: f64 = w
                        .parse()
                        .map_err(|_| format!("'{}' is not a number", short(w)))?;
                    nums.push(v);
                }
                _ => return Err("unexpected bracket".into()),
            }
            if !nums.is_empty() && !strs.is_empty() {
                return Err("a parameter mixes numbers and strings".into());
            }
            Ok(())
        };
        match self.next() {
            None => {
                return Err(SceneError::invalid(
                    at,
                    "the file ends where a parameter value was expected",
                ));
            }
            Some(Token {
                kind: TokenKind::Open,
                ..
            }) => loop {
                match self.next() {
                    None => {
                        return Err(SceneError::invalid(
                            at,
                            "unterminated '[': the file ends inside a parameter's values",
                        ));
                    }
                    Some(Token {
                        kind: TokenKind::Close,
                        ..
                    }) => break,
                    Some(Token {
                        kind: TokenKind::Open,
                        line,
                    }) => {
                        return Err(SceneError::invalid(
                            loc(self.file, *line),
                            "'[' inside a parameter's values (unterminated '[' before it?)",
                        ));
                    }
                    Some(t) => push(t, &mut nums, &mut strs)
                        .map_err(|m| SceneError::invalid(loc(self.file, t.line), m))?,
                }
            },
            Some(t) => push(t, &mut nums, &mut strs)
                .map_err(|m| SceneError::invalid(loc(self.file, t.line), m))?,
        }
        Ok(if nums.is_empty() {
            Values::Strs(strs)
        } else {
            Values::Nums(nums)
        })
    }
}

/// pbrt-v4's `illuminance` normalisation of an equal-area map (`Light::Create`, "infinite"): the
/// sum over texels in the map's upper hemisphere (+z, texel centres) of luminance × cos θ, times
/// 2π / texel count. Each texel subtends 4π / N, so with pbrt-v4's 2π / N the illuminance it
/// produces is twice the requested one; Trayecto follows pbrt-v4, the authority on the format.
fn equal_area_illuminance(w: u32, h: u32, texels: &[Vec3]) -> f32 {
    let mut sum = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let uv =
                crate::math::Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let d = crate::sampling::equal_area::square_to_sphere(uv);
            if d.z <= 0.0 {
                continue;
            }
            let t = texels[(y * w + x) as usize];
            sum += (crate::math::luminance(t) * d.z) as f64;
        }
    }
    (sum * 2.0 * std::f64::consts::PI / (w as f64 * h as f64)) as f32
}
