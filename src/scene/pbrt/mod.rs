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

pub mod materials;
pub mod params;
pub mod shapes;
pub mod spectra;
pub mod tokenizer;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::material::Material;
use crate::math::{Mat4, Vec3};
use crate::scene::{CameraDesc, LightDesc, MaterialId, Scene, SceneError, Shape};

use materials::{MatSpec, TexNode};
use params::{Param, ParamList, SpectrumValue, Values};
use tokenizer::{Token, TokenKind};

/// Deepest `Include` nesting accepted.
pub const MAX_INCLUDE_DEPTH: usize = 32;
/// Largest scene text accepted (one file), in bytes.
pub const MAX_FILE_BYTES: u64 = 1 << 31;
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
    let scene = l.finish()?;
    scene.validate()?;
    Ok(scene)
}

/// Parses pbrt text held in memory (the fuzzing entry point). Nothing is read from disk:
/// `Include`, `Import` and file-backed shapes and textures are warnings.
pub fn load_from_str(text: &str, label: &str) -> Result<Scene, SceneError> {
    let mut l = Loader::new(None);
    l.run_file(text, label, 0)?;
    let mut scene = l.finish()?;
    scene.name = label.to_string();
    scene.source = Some(label.into());
    scene.validate()?;
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
    let bytes = std::fs::read(path).map_err(|e| SceneError::Io {
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
    two_sided: bool,
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
    /// The end-time transform; only compared with `ctm` to warn about motion blur.
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
/// time, its material.
#[derive(Clone, Debug)]
struct InstancePart {
    shape: Shape,
    transform: Mat4,
    material: MaterialId,
    name: String,
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
    camera: Option<(Mat4, ParamList, String)>,
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
    material_cache: HashMap<String, MaterialId>,
    instances: HashMap<String, Vec<InstancePart>>,
    current_object: Option<(String, Vec<InstancePart>)>,
    include_stack: Vec<PathBuf>,
    settings: Settings,
    ply_jobs: Vec<PlyJob>,
    pub(crate) image_jobs: Vec<materials::ImageJob>,
    pub(crate) bake_jobs: Vec<materials::BakeJob>,
    world_begun: bool,
    warned_once: std::collections::HashSet<String>,
    /// Named media: `Some(id)` when mapped, `None` for a type Trayecto lacks (warned once).
    media: HashMap<String, Option<crate::scene::MediumId>>,
    /// The camera's medium name (pbrt's outside medium at `Camera`) and where it was set.
    camera_medium: Option<(String, String)>,
}

/// `file:line` of a token.
fn loc(file: &str, line: u32) -> String {
    format!("{file}:{line}")
}

impl Loader {
    fn new(root_dir: Option<PathBuf>) -> Loader {
        Loader {
            root_dir,
            scene: Scene::default(),
            gs: GraphicsState::default(),
            stack: Vec::new(),
            named_coord: HashMap::new(),
            named_materials: HashMap::new(),
            anonymous_materials: Vec::new(),
            float_textures: HashMap::new(),
            spectrum_textures: HashMap::new(),
            material_cache: HashMap::new(),
            instances: HashMap::new(),
            current_object: None,
            include_stack: Vec::new(),
            settings: Settings::default(),
            ply_jobs: Vec::new(),
            image_jobs: Vec::new(),
            bake_jobs: Vec::new(),
            world_begun: false,
            warned_once: Default::default(),
            media: HashMap::new(),
            camera_medium: None,
        }
    }

    pub(crate) fn warn(&mut self, w: String) {
        self.scene.warnings.push(w);
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
        let tokens = tokenizer::tokenize(text)
            .map_err(|(line, m)| SceneError::invalid(loc(file, line), m))?;
        let mut p = Cursor {
            tokens: &tokens,
            pos: 0,
            file,
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
        }
        Ok(())
    }

    fn transform_directive(&mut self, m: Mat4, set: bool) {
        // Transform directives change the transforms `ActiveTransform` selects; Trayecto renders
        // the start time (motion blur is not supported and is warned about at the shape).
        let apply = |cur: Mat4| if set { m } else { cur * m };
        if self.gs.active != Active::End {
            self.gs.ctm = apply(self.gs.ctm);
        }
        if self.gs.active != Active::Start {
            self.gs.ctm_end = apply(self.gs.ctm_end);
        }
    }

    fn directive(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
        depth: usize,
    ) -> Result<(), SceneError> {
        match name {
            "Identity" => self.transform_directive(Mat4::IDENTITY, true),
            "Translate" => {
                let v = p.numbers(3, at)?;
                self.transform_directive(
                    Mat4::from_translation(Vec3::new(v[0], v[1], v[2])),
                    false,
                );
            }
            "Scale" => {
                let v = p.numbers(3, at)?;
                self.transform_directive(Mat4::from_scale(Vec3::new(v[0], v[1], v[2])), false);
            }
            "Rotate" => {
                let v = p.numbers(4, at)?;
                let axis = Vec3::new(v[1], v[2], v[3]);
                if axis.length_squared() == 0.0 {
                    return Err(SceneError::invalid(at, "Rotate: the axis is zero"));
                }
                self.transform_directive(
                    Mat4::from_axis_angle(axis.normalize(), v[0].to_radians()),
                    false,
                );
            }
            "LookAt" => {
                let v = p.numbers(9, at)?;
                let m = look_at(
                    Vec3::new(v[0], v[1], v[2]),
                    Vec3::new(v[3], v[4], v[5]),
                    Vec3::new(v[6], v[7], v[8]),
                )
                .map_err(|e| SceneError::invalid(at, format!("LookAt: {e}")))?;
                self.transform_directive(m, false);
            }
            "Transform" | "ConcatTransform" => {
                let v = p.matrix(at)?;
                // pbrt lists the matrix column by column (it transposes the row-major array).
                let m = Mat4::from_cols_array(&v);
                if !crate::math::mat4_is_finite(&m) {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name}: non-finite matrix"),
                    ));
                }
                self.transform_directive(m, name == "Transform");
            }
            "CoordinateSystem" => {
                let n = p.string(at)?;
                self.named_coord.insert(n, self.gs.ctm);
            }
            "CoordSysTransform" => {
                let n = p.string(at)?;
                match self.named_coord.get(&n) {
                    Some(m) => {
                        let m = *m;
                        self.gs.ctm = m;
                        self.gs.ctm_end = m;
                    }
                    None => self.warn(format!(
                        "{at}: CoordSysTransform: no coordinate system named '{n}'"
                    )),
                }
            }
            "ActiveTransform" => {
                let w = p.word(at)?;
                self.gs.active = match w.as_str() {
                    "StartTime" => Active::Start,
                    "EndTime" => Active::End,
                    "All" => Active::All,
                    other => {
                        return Err(SceneError::invalid(
                            at,
                            format!(
                                "ActiveTransform: unknown '{other}' (StartTime, EndTime or All)"
                            ),
                        ));
                    }
                };
            }
            "TransformTimes" => {
                let v = p.numbers(2, at)?;
                if v[0] != v[1] {
                    self.warn_once(
                        "TransformTimes",
                        format!(
                            "{at}: TransformTimes {} {}: motion blur is not supported; the start-time transform is rendered",
                            v[0], v[1]
                        ),
                    );
                }
            }
            "ReverseOrientation" => self.gs.reverse = !self.gs.reverse,
            "AttributeBegin" | "TransformBegin" => {
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name}: nested too deeply"),
                    ));
                }
                let frame = if name == "AttributeBegin" {
                    Frame::Attribute
                } else {
                    if !self.warned_once.contains("TransformBegin") {
                        self.warn_once(
                            "TransformBegin",
                            format!("{at}: TransformBegin is deprecated in pbrt-v4 (read as in pbrt-v3: it saves only the transform)"),
                        );
                    }
                    Frame::Transform
                };
                self.stack.push((self.gs.clone(), frame, at.to_string()));
            }
            "AttributeEnd" | "TransformEnd" => {
                let want = if name == "AttributeEnd" {
                    Frame::Attribute
                } else {
                    Frame::Transform
                };
                let Some((saved, frame, opened)) = self.stack.pop() else {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name} without a matching begin"),
                    ));
                };
                if frame != want {
                    return Err(SceneError::invalid(
                        at,
                        format!(
                            "{name} closes the block opened at {opened}, which is of the other kind"
                        ),
                    ));
                }
                if frame == Frame::Attribute {
                    self.gs = saved;
                } else {
                    self.gs.ctm = saved.ctm;
                    self.gs.ctm_end = saved.ctm_end;
                    self.gs.active = saved.active;
                }
            }
            "Attribute" => {
                let target = p.string(at)?;
                let list = p.params(at)?;
                if !["shape", "light", "material", "medium", "texture"].contains(&target.as_str()) {
                    return Err(SceneError::invalid(
                        at,
                        format!("Attribute: unknown target '{target}'"),
                    ));
                }
                let entry = self.gs.attributes.entry(target).or_default();
                for prm in list.params {
                    entry.retain(|q| q.name != prm.name);
                    entry.push(prm);
                }
            }
            "Option" => {
                let list = p.params(at)?;
                for prm in &list.params {
                    self.warn(format!(
                        "{at}: Option \"{} {}\" does not change how Trayecto renders and was ignored",
                        prm.ty, prm.name
                    ));
                }
            }
            "ColorSpace" => {
                let n = p.string(at)?;
                if n != "srgb" {
                    self.warn(format!(
                        "{at}: ColorSpace \"{n}\": Trayecto renders in linear sRGB; the file's RGB values are read as sRGB"
                    ));
                }
            }
            "Camera" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                if self.world_begun {
                    return Err(SceneError::invalid(at, "Camera after WorldBegin"));
                }
                if ty != "perspective" {
                    self.warn(format!(
                        "{at}: Camera \"{ty}\" is not supported; a perspective camera with the same parameters is used"
                    ));
                }
                if self.gs.ctm != self.gs.ctm_end {
                    self.warn(format!(
                        "{at}: Camera: the moving camera is rendered at its start time"
                    ));
                }
                // pbrt names the camera's coordinate system "camera".
                if let Some(inv) = invert(&self.gs.ctm) {
                    self.named_coord.insert("camera".into(), inv);
                }
                self.settings.camera = Some((self.gs.ctm, list, at.to_string()));
                // pbrt-v4: the camera sits in the current outside medium.
                if !self.gs.medium_outside.is_empty() {
                    self.camera_medium = Some((self.gs.medium_outside.clone(), at.to_string()));
                }
            }
            "Film" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                if !matches!(ty.as_str(), "rgb" | "gbuffer" | "spectral") {
                    self.warn(format!("{at}: Film \"{ty}\" is unknown; read as \"rgb\""));
                }
                self.settings.film = Some((list, at.to_string()));
            }
            "Sampler" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let spp = list.int("pixelsamples", 16);
                if spp > 0 {
                    self.scene.hints.spp = Some(spp.min(1 << 20) as u32);
                }
                self.note_unused(&list, &format!("Sampler \"{ty}\""), at);
                self.warn_once(
                    "sampler",
                    format!("{at}: Sampler \"{ty}\": Trayecto uses its own sample generator (--sampler); pixelsamples is used"),
                );
            }
            "Integrator" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let depth_v = list.int("maxdepth", 5);
                if depth_v >= 0 {
                    self.scene.hints.max_depth = Some(depth_v.min(100_000) as u32);
                }
                if !matches!(ty.as_str(), "path" | "volpath") {
                    self.warn(format!(
                        "{at}: Integrator \"{ty}\": Trayecto renders with its path tracer; maxdepth is used"
                    ));
                }
                // Options of pbrt's path tracers that Trayecto's already does its own way.
                for k in ["regularize", "lightsampler"] {
                    if list.has(k) {
                        let _ = list.bool(k, false);
                        let _ = list.string(k);
                    }
                }
                self.note_unused(&list, &format!("Integrator \"{ty}\""), at);
            }
            "PixelFilter" => {
                let ty = p.string(at)?;
                let _ = p.params(at)?;
                self.warn_once(
                    "filter",
                    format!("{at}: PixelFilter \"{ty}\": Trayecto reconstructs with a box filter of one pixel (pbrt-v4's default is a 1.5-pixel Gaussian); edges are slightly sharper, means agree"),
                );
            }
            "Accelerator" => {
                let _ = p.string(at)?;
                let _ = p.params(at)?;
            }
            "WorldBegin" => {
                self.world_begun = true;
                self.gs.ctm = Mat4::IDENTITY;
                self.gs.ctm_end = Mat4::IDENTITY;
                self.named_coord.insert("world".into(), Mat4::IDENTITY);
            }
            "WorldEnd" => {
                // pbrt-v3; pbrt-v4 ends the world at the end of the file.
            }
            "MakeNamedMaterial" => {
                let n = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "material");
                let ty = list.string("type").unwrap_or_default();
                if ty.is_empty() {
                    return Err(SceneError::invalid(
                        at,
                        format!("MakeNamedMaterial \"{n}\": no \"string type\""),
                    ));
                }
                if self.named_materials.contains_key(&n) {
                    self.warn(format!(
                        "{at}: MakeNamedMaterial \"{n}\" redefines the material"
                    ));
                }
                self.named_materials.insert(
                    n.clone(),
                    MatSpec {
                        name: n,
                        ty,
                        params: list,
                        at: at.to_string(),
                    },
                );
            }
            "Material" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "material");
                self.anonymous_materials.push(MatSpec {
                    name: format!("{ty} ({at})"),
                    ty,
                    params: list,
                    at: at.to_string(),
                });
                self.gs.material = MatRef::Anonymous(self.anonymous_materials.len() - 1);
            }
            "NamedMaterial" => {
                let n = p.string(at)?;
                self.gs.material = MatRef::Named(n);
            }
            "Texture" => {
                let n = p.string(at)?;
                let ty = p.string(at)?;
                let class = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "texture");
                self.texture_directive(n, &ty, &class, list, at)?;
            }
            "LightSource" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "light");
                self.light_source(&ty, list, at)?;
            }
            "AreaLightSource" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "light");
                self.area_light_source(&ty, list, at);
            }
            "Shape" => {
                let ty = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "shape");
                self.shape(&ty, list, at)?;
            }
            "MakeNamedMedium" => {
                let n = p.string(at)?;
                let list = p.params(at)?;
                let list = self.with_attributes(list, "medium");
                self.make_named_medium(&n, &list, at)?;
            }
            "MediumInterface" => {
                let inside = p.string(at)?;
                // The second name is optional (one name sets both sides).
                let outside = p.optional_string().unwrap_or_else(|| inside.clone());
                self.gs.medium_inside = inside;
                self.gs.medium_outside = outside;
            }
            "ObjectBegin" => {
                let n = p.string(at)?;
                if self.current_object.is_some() {
                    return Err(SceneError::invalid(
                        at,
                        "ObjectBegin inside another ObjectBegin",
                    ));
                }
                if self.stack.len() >= MAX_ATTRIBUTE_DEPTH {
                    return Err(SceneError::invalid(at, "ObjectBegin: nested too deeply"));
                }
                // ObjectBegin implies AttributeBegin (pbrt-v4 scene.cpp).
                self.stack
                    .push((self.gs.clone(), Frame::Attribute, at.to_string()));
                self.current_object = Some((n, Vec::new()));
            }
            "ObjectEnd" => {
                let Some((n, parts)) = self.current_object.take() else {
                    return Err(SceneError::invalid(at, "ObjectEnd without ObjectBegin"));
                };
                if self.instances.contains_key(&n) {
                    self.warn(format!("{at}: ObjectBegin \"{n}\" redefines the object"));
                }
                self.instances.insert(n, parts);
                match self.stack.pop() {
                    Some((saved, Frame::Attribute, _)) => self.gs = saved,
                    _ => {
                        return Err(SceneError::invalid(
                            at,
                            "ObjectEnd does not match the ObjectBegin's attribute block",
                        ));
                    }
                }
            }
            "ObjectInstance" => {
                let n = p.string(at)?;
                if self.current_object.is_some() {
                    return Err(SceneError::invalid(at, "ObjectInstance inside ObjectBegin"));
                }
                let Some(parts) = self.instances.get(&n) else {
                    return Err(SceneError::invalid(
                        at,
                        format!("ObjectInstance: no object named '{n}'"),
                    ));
                };
                let ctm = self.gs.ctm;
                let parts = parts.clone();
                for part in parts {
                    self.scene.add_object(
                        &part.name,
                        part.shape,
                        ctm * part.transform,
                        part.material,
                    );
                }
            }
            "Include" | "Import" => {
                let f = p.string(at)?;
                self.include(&f, at, depth)?;
            }
            other => {
                return Err(SceneError::invalid(
                    at,
                    format!("unknown directive '{}'", short(other)),
                ));
            }
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
                self.warn_once(
                    "spotfalloff",
                    format!("{at}: spot light: Trayecto's cone falloff between the inner and outer angles may differ from pbrt-v4's smoothstep"),
                );
                self.scene.lights.push(LightDesc::Spot {
                    name,
                    position: ctm.transform_point3(from),
                    direction: dir.normalize(),
                    intensity: i * s,
                    inner_angle: (cone - delta).to_radians(),
                    outer_angle: cone.to_radians(),
                });
            }
            "distant" => {
                let l = spectrum(self, "L", Vec3::ONE);
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
                    if e > 0.0 {
                        self.warn(format!("{at}: infinite light: \"illuminance\" with an image is not supported; the image is used unscaled"));
                    }
                    let path = self.resolve(&f, at)?;
                    // pbrt-v4's image infinite lights use square equal-area (octahedral) maps,
                    // every texel subtending the same solid angle, so the plain texel mean is the
                    // mean radiance over the sphere. Until that parameterization lands, the light
                    // is that mean as uniform radiance: exact for the total power it sends into
                    // an open scene, not for its directions.
                    let job = materials::ImageJob {
                        texture: 0,
                        path,
                        name: f.clone(),
                        srgb: false,
                        gamma: None,
                        filter: crate::material::texture::FilterMode::Bilinear,
                        wrap: crate::material::WrapMode::Repeat,
                        at: at.to_string(),
                        size_hint: 0,
                    };
                    match materials::decode_image(&job) {
                        Ok(t) => {
                            let mean = t.average().truncate();
                            self.warn(format!(
                                "{at}: infinite light \"{f}\": equal-area environment images are not supported yet; its mean radiance {mean} is used as a uniform environment"
                            ));
                            self.scene.lights.push(LightDesc::Ambient {
                                name,
                                radiance: mean * s,
                            });
                        }
                        Err(e) => self.warn(format!(
                            "{at}: infinite light \"{f}\" could not be read ({e}) and was left out"
                        )),
                    }
                } else {
                    let rgb = match l {
                        Some(v) => self.illuminant_rgb(&v, at, "L").unwrap_or(Vec3::ONE),
                        None => Vec3::ONE,
                    };
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
        if list.has("power") {
            let _ = list.float("power", 0.0);
            // pbrt-v4 normalises `power` per shape it creates, and a triangle mesh makes one
            // light per triangle, so the radiance would differ per triangle: not representable by
            // one emissive material.
            self.warn(format!(
                "{at}: AreaLightSource \"diffuse\": \"power\" is not supported; L × scale is used"
            ));
        }
        if list.has("filename") {
            let _ = list.string("filename");
            self.warn(format!(
                "{at}: AreaLightSource \"diffuse\": image emission (\"filename\") is not supported; the constant L is used"
            ));
        }
        self.note_unused(&list, "AreaLightSource \"diffuse\"", at);
        self.gs.area_light = Some(AreaLight {
            radiance: l * scale,
            two_sided,
        });
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
            SpectrumValue::Named(n) => spectra::named_illuminant(n),
            SpectrumValue::Sampled(v) => spectra::sampled_rgb(v),
        };
        if r.is_none() {
            self.warn(format!(
                "{at}: \"{key}\": spectrum {s:?} is not supported; white is used"
            ));
        }
        r
    }

    /// The Trayecto material for the current graphics state (material plus area light).
    fn current_material(&mut self, at: &str) -> MaterialId {
        let (key, spec) = match self.gs.material.clone() {
            MatRef::Default => ("<default>".to_string(), None),
            MatRef::Anonymous(i) => (format!("#{i}"), self.anonymous_materials.get(i).cloned()),
            MatRef::Named(n) => match self.named_materials.get(&n) {
                Some(s) => (format!("named {n}"), Some(s.clone())),
                None => {
                    self.warn_once(
                        &format!("nomat {n}"),
                        format!("{at}: NamedMaterial \"{n}\" is not defined; the default diffuse material is used"),
                    );
                    ("<default>".to_string(), None)
                }
            },
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
            m.double_sided = l.two_sided;
        }
        let id = self.scene.add_material(m);
        self.material_cache.insert(full_key, id);
        id
    }

    /// Places a shape: in the world, or in the object being defined.
    fn place(&mut self, shape: Shape, name: String, at: &str) {
        let material = self.current_material(at);
        if self.gs.ctm != self.gs.ctm_end {
            self.warn_once(
                "motion",
                format!("{at}: Shape: an animated transform is rendered at its start time (motion blur is not supported)"),
            );
        }
        if let Some((_, parts)) = &mut self.current_object {
            parts.push(InstancePart {
                shape,
                transform: self.gs.ctm,
                material,
                name,
            });
        } else {
            self.scene.add_object(&name, shape, self.gs.ctm, material);
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
    /// given by the CTM); other types and emission are warnings.
    fn make_named_medium(&mut self, name: &str, p: &ParamList, at: &str) -> Result<(), SceneError> {
        use crate::scene::{MediumDesc, MediumKind};
        let ty = p.string("type").unwrap_or_default();
        let what = format!("MakeNamedMedium \"{name}\" (\"{ty}\")");
        if self.media.contains_key(name) {
            self.warn(format!(
                "{at}: {what}: redefines the medium; the new definition is used"
            ));
        }
        if !matches!(ty.as_str(), "homogeneous" | "uniformgrid") {
            self.warn(format!(
                "{at}: {what}: medium type \"{ty}\" is not supported; the medium is ignored (vacuum)"
            ));
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
        let scale = p.float("scale", 1.0);
        let g = p.float("g", 0.0);
        if p.has("Le") || p.has("Lescale") || p.has("temperature") || p.has("temperaturescale") {
            let _ = (
                p.spectrum("Le"),
                p.float("Lescale", 1.0),
                p.floats("temperature"),
                p.float("temperaturescale", 1.0),
            );
            self.warn(format!(
                "{at}: {what}: medium emission (Le/temperature) is not supported; it is ignored"
            ));
        }
        let kind = if ty == "uniformgrid" {
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
            MediumKind::Grid {
                nx: nx as usize,
                ny: ny as usize,
                nz: nz as usize,
                density,
                min: p.point3("p0", Vec3::ZERO),
                max: p.point3("p1", Vec3::ONE),
                transform: self.gs.ctm,
            }
        } else {
            MediumKind::Homogeneous
        };
        let _ = p.string("type");
        let desc = MediumDesc {
            name: name.to_string(),
            sigma_a,
            sigma_s,
            scale,
            g,
            kind,
        };
        desc.validate()
            .map_err(|e| SceneError::invalid(at, format!("{what}: {e}")))?;
        self.note_unused(p, &what, at);
        let id = self.scene.add_medium(desc);
        self.media.insert(name.to_string(), Some(id));
        Ok(())
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
        self.load_plys()?;
        self.run_image_jobs();
        self.run_bake_jobs();
        self.camera_and_film()?;
        Ok(self.scene)
    }

    fn camera_and_film(&mut self) -> Result<(), SceneError> {
        let (xres, yres, crop) = match self.settings.film.take() {
            Some((film, at)) => {
                let x = film.int("xresolution", 1280);
                let y = film.int("yresolution", 720);
                if !(1..=65536).contains(&x) || !(1..=65536).contains(&y) {
                    return Err(SceneError::invalid(
                        &at,
                        format!("Film: resolution {x}×{y} is out of range"),
                    ));
                }
                let crop = film.floats("cropwindow");
                if let Some(f) = film.string("filename") {
                    self.warn(format!(
                        "{at}: Film \"filename\" \"{f}\" is ignored: the output is what the command line names"
                    ));
                }
                self.note_unused(&film, "Film", &at);
                let crop = match crop {
                    Some(c) if c.len() == 4 => {
                        let c = [
                            c[0].clamp(0.0, 1.0),
                            c[1].clamp(0.0, 1.0),
                            c[2].clamp(0.0, 1.0),
                            c[3].clamp(0.0, 1.0),
                        ];
                        if c[0] < c[1] && c[2] < c[3] && c != [0.0, 1.0, 0.0, 1.0] {
                            Some(c)
                        } else {
                            None
                        }
                    }
                    Some(_) => {
                        return Err(SceneError::invalid(&at, "Film: cropwindow needs 4 values"));
                    }
                    None => None,
                };
                (x as u32, y as u32, crop)
            }
            None => (1280, 720, None),
        };
        self.scene.hints.width = Some(xres);
        self.scene.hints.height = Some(yres);
        self.scene.hints.crop = crop;
        if crop.is_some() {
            self.warn("Film \"cropwindow\": the whole image is rendered (the crop window is recorded in the render hints but not applied)".into());
        }
        let (camera_from_world, list, at) = match self.settings.camera.take() {
            Some(c) => c,
            None => {
                self.warn("no Camera directive: pbrt's default camera (at the origin looking down +z, fov 90) is used".into());
                (
                    Mat4::IDENTITY,
                    ParamList::default(),
                    "default camera".into(),
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
        let fov = list.float("fov", 90.0);
        if !(fov > 0.0 && fov < 180.0) {
            return Err(SceneError::invalid(
                &at,
                format!("Camera: fov {fov} is not in (0, 180)"),
            ));
        }
        // pbrt-v4 PerspectiveCamera: the screen window is [-aspect, aspect] × [-1, 1] for wide
        // images and [-1, 1] × [-1/aspect, 1/aspect] for tall ones, scaled by tan(fov/2): fov
        // spans the shorter axis.
        let t = (fov.to_radians() * 0.5).tan();
        let mut half_h = if aspect >= 1.0 { t } else { t / aspect };
        if let Some(sw) = list.floats("screenwindow") {
            if sw.len() == 4 && sw[1] > sw[0] && sw[3] > sw[2] {
                let centred = (sw[0] + sw[1]).abs() < 1e-6 && (sw[2] + sw[3]).abs() < 1e-6;
                if !centred {
                    self.warn(format!("{at}: Camera \"screenwindow\": an off-centre window is not supported; its height is used, centred"));
                }
                half_h = t * 0.5 * (sw[3] - sw[2]);
                let w_ratio = (sw[1] - sw[0]) / (sw[3] - sw[2]);
                if (w_ratio - aspect).abs() > 1e-3 * aspect {
                    self.warn(format!("{at}: Camera \"screenwindow\" has a different aspect ratio from the film; the film's is used"));
                }
            } else {
                return Err(SceneError::invalid(
                    &at,
                    "Camera: screenwindow needs 4 increasing values",
                ));
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
        for k in ["frameaspectratio", "shutteropen", "shutterclose"] {
            if list.has(k) {
                let _ = list.float(k, 0.0);
                if k == "frameaspectratio" {
                    self.warn(format!("{at}: Camera \"frameaspectratio\" is not supported; the film's aspect ratio is used"));
                }
            }
        }
        self.note_unused(&list, "Camera", &at);
        // pbrt camera space looks down +z; Trayecto's looks down −z with the same x and y.
        let flip = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        self.scene.cameras.push(CameraDesc {
            name: "pbrt camera".into(),
            camera_to_world: world_from_camera * flip,
            vfov_deg: vfov,
            aspect: Some(aspect),
            aperture_radius: lens,
            focus_distance: focus,
        });
        Ok(())
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
