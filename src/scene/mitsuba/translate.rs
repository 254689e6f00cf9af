//! Mitsuba 3 objects mapped onto the pbrt-v4 loader's directives ([`Builder`]).
//!
//! * Shapes: `obj`, `ply` and `serialized` are decoded here (Trayecto's OBJ and PLY readers,
//!   [`super::serialized`]) and become triangle meshes with Mitsuba's texture coordinates
//!   (Mitsuba flips an OBJ's v, not a PLY's); `rectangle` and `cube` are meshes with Mitsuba's
//!   parameterisation; `sphere`, `disk` and `cylinder` are pbrt's quadrics placed where Mitsuba
//!   puts them; `shapegroup` + `instance` are pbrt object instances. `flip_normals` is pbrt's
//!   `ReverseOrientation`; `face_normals` drops the vertex normals.
//! * BSDFs: `diffuse`; `dielectric`/`roughdielectric` → pbrt's dielectric (η = int_ior/ext_ior,
//!   α as roughness without remapping); `thindielectric`; `conductor`/`roughconductor` → pbrt's
//!   conductor with the named metal's (η, k) (`none` is a perfect mirror); `plastic` and
//!   `roughplastic` → pbrt's coated diffuse layer (approximation: Mitsuba's plastic is an
//!   analytic model of the same layer); `twosided` (Trayecto's BSDFs are two-sided already);
//!   `blendbsdf` → pbrt's mix; `mask` → the shape's alpha; `bumpmap` → displacement;
//!   `normalmap`; `null` → an interface; `principled`/`principledthin` → a coated diffuse or a
//!   conductor (approximation). Beckmann distributions are rendered with GGX of the same α
//!   (approximation).
//! * Textures: `bitmap` (filter, wrap, raw, `to_uv` scale and offset) → pbrt image maps;
//!   `checkerboard` → pbrt's checkerboard with Mitsuba's layout.
//! * Emitters: `area`, `point`, `spot` (pbrt's smoothstep falloff: approximation of Mitsuba's
//!   linear one), `directional`, `constant`, `envmap` (Trayecto's latitude–longitude map, which
//!   is Mitsuba's convention).
//! * Sensors: `perspective`, `thinlens`, `orthographic` (Mitsuba's camera space has x to the left
//!   of the image: the camera transform is mirrored into pbrt's); `hdrfilm` size and crop;
//!   `rfilter` box, tent, gaussian, mitchell, catmullrom (others: Gaussian); `sample_count`.
//! * Integrators: `path`, `volpath` (max_depth − 1 bounces), `direct` (one bounce), `ptracer`
//!   and `aov` (the path tracer, with a warning).
//! * Media: `homogeneous` (σt, albedo, scale, `hg` phase) and `heterogeneous` with `gridvolume`
//!   `.vol` densities.
//!
//! Everything else is a warning naming the plugin and `file:line`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use super::{Elem, resolve};
use crate::math::{Mat4, Vec3, Vec4};
use crate::scene::pbrt::embed::Builder;
use crate::scene::{LightDesc, MediumDesc, MediumKind, Scene, SceneError};

/// The pbrt integrator Mitsuba's `ptracer` (a particle tracer: paths from the emitters,
/// connected to the sensor) is rendered with: Trayecto's light tracer, the same method. Where the
/// light tracer cannot render the scene (media), the pipeline falls back to the path tracer as
/// for a pbrt file's `Integrator "lighttracer"`.
const PTRACER_INTEGRATOR: &str = "lighttracer";

/// Tags of property elements (everything else with a `type` is an object).
const VALUE_TAGS: &[&str] = &[
    "float",
    "integer",
    "boolean",
    "string",
    "rgb",
    "spectrum",
    "point",
    "vector",
    "transform",
    "ref",
];

/// pbrt's named metals (Mitsuba names them without the prefix).
const PBRT_METALS: &[&str] = &["Ag", "Al", "Au", "Cu", "CuZn", "MgO", "TiO2"];

/// Mitsuba's named indices of refraction (its `ior.h` table).
fn named_ior(name: &str) -> Option<f32> {
    Some(match name.to_ascii_lowercase().as_str() {
        "vacuum" => 1.0,
        "helium" => 1.000_036,
        "hydrogen" => 1.000_132,
        "air" => 1.000_277,
        "carbon dioxide" => 1.000_45,
        "water" => 1.333,
        "acetone" => 1.36,
        "ethanol" => 1.361,
        "carbon tetrachloride" => 1.461,
        "glycerol" => 1.4729,
        "benzene" => 1.501,
        "silicone oil" => 1.520_45,
        "bromine" => 1.661,
        "water ice" => 1.31,
        "fused quartz" => 1.458,
        "pyrex" => 1.47,
        "acrylic glass" => 1.49,
        "polypropylene" => 1.49,
        "bk7" => 1.5046,
        "sodium chloride" => 1.544,
        "amber" => 1.55,
        "pet" => 1.575,
        "diamond" => 2.419,
        _ => return None,
    })
}

/// A colour parameter in pbrt terms: the text after the parameter's type and name.
enum Col {
    Rgb(Vec3),
    Tex(String),
}

struct Tx<'a> {
    b: Builder,
    root: Option<PathBuf>,
    search: Vec<String>,
    ids: HashMap<String, &'a Elem>,
    /// pbrt names of the materials, textures, media and object instances made from elements.
    made: HashMap<(*const Elem, &'static str), String>,
    next: usize,
    used: BTreeMap<String, usize>,
    approx: BTreeSet<String>,
    /// Children of objects that were read (the rest are reported).
    read: std::cell::RefCell<std::collections::HashSet<*const Elem>>,
    /// Reading an emitter's properties: its sampled spectra are radiometric, not reflectances
    /// (Mitsuba's parser converts them without the D65 weighting and without clamping).
    emitting: bool,
    /// AOVs asked for by an `aov` integrator.
    aovs: Vec<crate::film::aov::AovKind>,
}

/// Translates the scene element into a [`Scene`].
pub(super) fn translate(
    scene: &Elem,
    root: Option<PathBuf>,
    search: Vec<String>,
    warnings: Vec<String>,
    label: &str,
) -> Result<Scene, SceneError> {
    let mut ids = HashMap::new();
    collect_ids(scene, &mut ids);
    let mut tx = Tx {
        b: Builder::new(root.clone()),
        root,
        search,
        ids,
        made: HashMap::new(),
        next: 0,
        used: BTreeMap::new(),
        approx: BTreeSet::new(),
        read: Default::default(),
        emitting: false,
        aovs: Vec::new(),
    };
    for w in warnings {
        tx.b.warn(w);
    }
    tx.scene(scene, label)?;
    let (used, approx) = (std::mem::take(&mut tx.used), std::mem::take(&mut tx.approx));
    let aovs = std::mem::take(&mut tx.aovs);
    let mut s = tx.b.finish()?;
    s.hints.aovs = aovs;
    let list = used
        .iter()
        .map(|(k, n)| {
            if *n > 1 {
                format!("{k} ×{n}")
            } else {
                k.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(", ");
    s.notes.push(format!("Mitsuba plugins used: {list}"));
    for a in approx {
        s.notes.push(format!("approximated: {a}"));
    }
    Ok(s)
}

fn collect_ids<'a>(e: &'a Elem, ids: &mut HashMap<String, &'a Elem>) {
    for c in &e.children {
        if !VALUE_TAGS.contains(&c.tag.as_str())
            && let Some(id) = c.attr("id")
        {
            ids.insert(id.to_string(), c);
        }
        if c.tag == "alias"
            && let (Some(id), Some(alias)) = (c.attr("id"), c.attr("as"))
            && let Some(t) = ids.get(id).copied()
        {
            ids.insert(alias.to_string(), t);
        }
        collect_ids(c, ids);
    }
}

fn q(s: &str) -> String {
    format!("\"{}\"", s.replace(['"', '\\'], "_"))
}

fn nums(v: &[f32]) -> String {
    let mut s = String::from("[");
    for x in v {
        s.push_str(&format!(" {x}"));
    }
    s.push_str(" ]");
    s
}

/// Linear sRGB of a Mitsuba `<spectrum value="λ:v, …">` as Mitsuba 3's RGB variants read it
/// (`spectrum_list_to_srgb`): the piecewise-linear spectrum, zero outside its first and last
/// wavelength, projected on the CIE 1931 matching functions over 360–830 nm and normalised by
/// ∫ȳ. A reflectance (`emitter` false) is seen under D65 (its XYZ is ∫ v·D65·x̄ / ∫ D65·ȳ, so a
/// flat spectrum is grey); an emitter's spectrum is taken as it is (equal energy is slightly
/// red in sRGB, as in Mitsuba). `None` when a value is not finite or there are no samples.
fn sampled_rgb(pairs: &[(f32, f32)], emitter: bool) -> Option<Vec3> {
    if pairs.is_empty() || pairs.iter().any(|(l, v)| !l.is_finite() || !v.is_finite()) {
        return None;
    }
    let mut s = pairs.to_vec();
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (first, last) = (s[0].0, s[s.len() - 1].0);
    let value = |l: f32| -> f32 {
        if l < first || l > last {
            return 0.0;
        }
        let i = s.partition_point(|p| p.0 <= l).clamp(1, s.len().max(2) - 1);
        if s.len() == 1 {
            return s[0].1;
        }
        let (a, b) = (s[i - 1], s[i]);
        if b.0 <= a.0 {
            return b.1;
        }
        a.1 + (b.1 - a.1) * ((l - a.0) / (b.0 - a.0)).clamp(0.0, 1.0)
    };
    let xyz = if emitter {
        crate::spectrum::spectrum_to_xyz(value)
    } else {
        crate::spectrum::spectrum_to_xyz(|l| value(l) * crate::spectrum::d65(l))
    };
    Some(crate::spectrum::xyz_to_linear_srgb(xyz))
}

fn parse_floats(s: &str) -> Vec<f32> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f32>().unwrap_or(f32::NAN))
        .collect()
}

impl<'a> Tx<'a> {
    fn note(&mut self, what: String) {
        *self.used.entry(what).or_insert(0) += 1;
    }

    fn approx(&mut self, e: &Elem, what: &str) {
        self.approx.insert(format!(
            "{} '{}' ({}): {what}",
            e.tag,
            e.attr("type").unwrap_or(""),
            e.at()
        ));
    }

    fn warn(&mut self, e: &Elem, what: &str) {
        self.b.warn(format!(
            "{}: {} '{}': {what}",
            e.at(),
            e.tag,
            e.attr("type").unwrap_or("")
        ));
    }

    fn fresh(&mut self, base: &str) -> String {
        self.next += 1;
        format!("{base}#{}", self.next)
    }

    fn run(&mut self, e: &Elem, text: &str) -> Result<(), SceneError> {
        self.b.run(text, &e.file, e.line)
    }

    // ---- properties ----

    /// The child named `name` (a property, or a named nested object / ref).
    fn prop(&self, e: &'a Elem, name: &str) -> Option<&'a Elem> {
        let c = e.children.iter().find(|c| c.attr("name") == Some(name))?;
        self.read.borrow_mut().insert(c as *const Elem);
        Some(c)
    }

    /// The object a child stands for: itself, or the object its `ref` names.
    fn deref(&self, c: &'a Elem) -> Result<&'a Elem, SceneError> {
        if c.tag == "ref" {
            let id = c.attr("id").unwrap_or("");
            return self.ids.get(id).copied().ok_or_else(|| {
                SceneError::invalid(c.at(), format!("<ref id=\"{id}\">: no object has this id"))
            });
        }
        Ok(c)
    }

    /// Nested objects of kind `tag` (given inline or by `ref`), named or not.
    fn objects(
        &self,
        e: &'a Elem,
        tag: &str,
    ) -> Result<Vec<(&'a Elem, Option<&'a str>)>, SceneError> {
        let mut out = Vec::new();
        for c in &e.children {
            let obj = if c.tag == "ref" {
                self.deref(c)?
            } else if c.tag == tag {
                c
            } else {
                continue;
            };
            if obj.tag == tag {
                self.read.borrow_mut().insert(c as *const Elem);
                out.push((obj, c.attr("name")));
            }
        }
        Ok(out)
    }

    fn value(&self, e: &'a Elem, name: &str) -> Option<&'a str> {
        self.prop(e, name).and_then(|c| c.attr("value"))
    }

    fn float(&self, e: &'a Elem, name: &str, default: f32) -> Result<f32, SceneError> {
        let Some(c) = self.prop(e, name) else {
            return Ok(default);
        };
        let v = c.attr("value").unwrap_or("");
        v.trim()
            .parse::<f32>()
            .map_err(|_| SceneError::invalid(c.at(), format!("'{name}': '{v}' is not a number")))
    }

    fn boolean(&self, e: &'a Elem, name: &str, default: bool) -> bool {
        match self.value(e, name) {
            Some(v) => v.trim() == "true" || v.trim() == "1",
            None => default,
        }
    }

    fn string(&self, e: &'a Elem, name: &str) -> Option<String> {
        self.value(e, name).map(|s| s.to_string())
    }

    fn vec3(&self, c: &Elem) -> Result<Vec3, SceneError> {
        if let Some(v) = c.attr("value") {
            let f = parse_floats(v);
            return match f.as_slice() {
                [x] => Ok(Vec3::splat(*x)),
                [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
                _ => Err(SceneError::invalid(
                    c.at(),
                    format!("'{v}' is not 1 or 3 numbers"),
                )),
            };
        }
        let g = |k: &str| {
            c.attr(k)
                .and_then(|v| v.trim().parse::<f32>().ok())
                .unwrap_or(0.0)
        };
        Ok(Vec3::new(g("x"), g("y"), g("z")))
    }

    fn point(&self, e: &'a Elem, name: &str) -> Result<Option<Vec3>, SceneError> {
        match self.prop(e, name) {
            Some(c) => self.vec3(c).map(Some),
            None => Ok(None),
        }
    }

    /// A colour or texture property.
    fn color(
        &mut self,
        e: &'a Elem,
        name: &str,
        default: Option<f32>,
    ) -> Result<Option<Col>, SceneError> {
        let Some(c) = self.prop(e, name) else {
            return Ok(default.map(|d| Col::Rgb(Vec3::splat(d))));
        };
        self.color_of(c, false)
    }

    fn color_of(&mut self, c: &'a Elem, float: bool) -> Result<Option<Col>, SceneError> {
        match c.tag.as_str() {
            "rgb" | "float" => Ok(Some(Col::Rgb(self.vec3(c)?))),
            "spectrum" => {
                let v = c.attr("value").unwrap_or("");
                if v.contains(':') {
                    let mut pairs = Vec::new();
                    for p in v.split(',') {
                        let (l, x) = p.split_once(':').unwrap_or(("", ""));
                        match (l.trim().parse::<f32>(), x.trim().parse::<f32>()) {
                            (Ok(l), Ok(x)) => pairs.push((l, x)),
                            _ => {
                                return Err(SceneError::invalid(
                                    c.at(),
                                    format!("'{p}' is not wavelength:value"),
                                ));
                            }
                        }
                    }
                    self.approx.insert(format!(
                        "spectrum ({}): sampled spectra are converted to RGB",
                        c.at()
                    ));
                    // Converted here, not by pbrt's light path: pbrt-v4 normalises light spectra
                    // to luminance 1, Mitsuba keeps their magnitude.
                    let rgb = sampled_rgb(&pairs, self.emitting).ok_or_else(|| {
                        SceneError::invalid(c.at(), "the spectrum has no finite values")
                    })?;
                    if !self.emitting && (rgb.min_element() < 0.0 || rgb.max_element() > 1.0) {
                        self.warn(
                            c,
                            "the reflectance spectrum is outside the sRGB gamut; clamped to [0, 1] as Mitsuba does",
                        );
                    }
                    let rgb = if self.emitting {
                        rgb
                    } else {
                        rgb.clamp(Vec3::ZERO, Vec3::ONE)
                    };
                    Ok(Some(Col::Rgb(rgb)))
                } else if c.attr("filename").is_some() {
                    self.b.warn(format!(
                        "{}: spectrum files are not supported; grey 0.5 is used",
                        c.at()
                    ));
                    Ok(Some(Col::Rgb(Vec3::splat(0.5))))
                } else {
                    Ok(Some(Col::Rgb(self.vec3(c)?)))
                }
            }
            "ref" | "texture" => {
                let t = self.deref(c)?;
                if t.tag != "texture" {
                    return Err(SceneError::invalid(
                        c.at(),
                        format!("expected a texture, found <{}>", t.tag),
                    ));
                }
                Ok(self.texture(t, float)?.map(Col::Tex))
            }
            other => Err(SceneError::invalid(
                c.at(),
                format!("<{other}> is not a colour or texture"),
            )),
        }
    }

    /// A parameter's text: `"rgb name" [..]`, `"spectrum name" [..]` or `"texture name" "t"`.
    fn param(name: &str, c: &Col, float: bool) -> String {
        match c {
            Col::Rgb(v) if float => format!("\"float {name}\" [ {} ]", (v.x + v.y + v.z) / 3.0),
            Col::Rgb(v) => format!("\"rgb {name}\" {}", nums(&v.to_array())),
            Col::Tex(t) => format!("\"texture {name}\" {}", q(t)),
        }
    }

    /// A float-or-texture property as a parameter, or `None` when absent.
    fn float_param(
        &mut self,
        e: &'a Elem,
        name: &str,
        pbrt: &str,
    ) -> Result<Option<String>, SceneError> {
        let Some(c) = self.prop(e, name) else {
            return Ok(None);
        };
        Ok(self
            .color_of(c, true)?
            .map(|col| Self::param(pbrt, &col, true)))
    }

    fn transform(&self, e: &'a Elem, name: &str) -> Result<Mat4, SceneError> {
        let Some(t) = self.prop(e, name) else {
            return Ok(Mat4::IDENTITY);
        };
        let mut m = Mat4::IDENTITY;
        for op in &t.children {
            let f = |k: &str| op.attr(k).and_then(|v| v.trim().parse::<f32>().ok());
            let step = match op.tag.as_str() {
                "translate" => Mat4::from_translation(self.vec3(op)?),
                "scale" => {
                    let s = if op.attr("value").is_some() {
                        self.vec3(op)?
                    } else {
                        Vec3::new(
                            f("x").unwrap_or(1.0),
                            f("y").unwrap_or(1.0),
                            f("z").unwrap_or(1.0),
                        )
                    };
                    Mat4::from_scale(s)
                }
                "rotate" => {
                    let axis = self.vec3(op)?;
                    let angle = f("angle").unwrap_or(0.0);
                    if axis.length_squared() == 0.0 {
                        return Err(SceneError::invalid(op.at(), "rotate: the axis is zero"));
                    }
                    Mat4::from_axis_angle(axis.normalize(), angle.to_radians())
                }
                "matrix" => {
                    let v = parse_floats(op.attr("value").unwrap_or(""));
                    match v.len() {
                        16 => Mat4::from_cols_array(&v.try_into().unwrap_or([0.0; 16])).transpose(),
                        9 => {
                            let r = |i: usize, j: usize| v[i * 3 + j];
                            Mat4::from_cols(
                                Vec4::new(r(0, 0), r(1, 0), 0.0, r(2, 0)),
                                Vec4::new(r(0, 1), r(1, 1), 0.0, r(2, 1)),
                                Vec4::new(0.0, 0.0, 1.0, 0.0),
                                Vec4::new(r(0, 2), r(1, 2), 0.0, r(2, 2)),
                            )
                        }
                        n => {
                            return Err(SceneError::invalid(
                                op.at(),
                                format!("matrix: {n} numbers (16 or 9 expected)"),
                            ));
                        }
                    }
                }
                "lookat" => {
                    let p = |k: &str| -> Result<Vec3, SceneError> {
                        let v = parse_floats(op.attr(k).unwrap_or(""));
                        match v.as_slice() {
                            [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
                            _ => Err(SceneError::invalid(
                                op.at(),
                                format!("lookat: '{k}' needs 3 numbers"),
                            )),
                        }
                    };
                    let origin = p("origin")?;
                    let target = p("target")?;
                    let up = if op.attr("up").is_some() {
                        p("up")?
                    } else {
                        Vec3::Y
                    };
                    let dir = (target - origin).normalize_or_zero();
                    let left = up.cross(dir).normalize_or_zero();
                    if dir == Vec3::ZERO || left == Vec3::ZERO {
                        return Err(SceneError::invalid(
                            op.at(),
                            "lookat: origin equals target or up is parallel to the view",
                        ));
                    }
                    let new_up = dir.cross(left);
                    Mat4::from_cols(
                        left.extend(0.0),
                        new_up.extend(0.0),
                        dir.extend(0.0),
                        origin.extend(1.0),
                    )
                }
                other => {
                    return Err(SceneError::invalid(
                        op.at(),
                        format!("<{other}> is not a transform operation"),
                    ));
                }
            };
            m = step * m;
        }
        if !crate::math::mat4_is_finite(&m) {
            return Err(SceneError::invalid(t.at(), "the transform is not finite"));
        }
        Ok(m)
    }

    /// Reports the properties of `e` nobody read.
    fn unused(&mut self, e: &'a Elem) {
        let unread: Vec<String> = e
            .children
            .iter()
            .filter(|c| {
                c.attr("name").is_some() && !self.read.borrow().contains(&(*c as *const Elem))
            })
            .map(|c| c.attr("name").unwrap_or("").to_string())
            .collect();
        for n in unread {
            self.warn(
                e,
                &format!("parameter '{n}' is not supported and was ignored"),
            );
        }
    }

    // ---- the scene ----

    fn scene(&mut self, scene: &'a Elem, label: &str) -> Result<(), SceneError> {
        // pbrt wants the camera, film and integrator before the world.
        let sensors: Vec<&Elem> = scene
            .children
            .iter()
            .filter(|c| c.tag == "sensor")
            .collect();
        for extra in sensors.iter().skip(1) {
            self.warn(extra, "only the first sensor is rendered");
        }
        let integrator = scene.children.iter().find(|c| c.tag == "integrator");
        let has_media = scene.children.iter().any(|c| c.tag == "medium")
            || scene
                .children
                .iter()
                .any(|c| c.children.iter().any(|g| g.tag == "medium"));
        match integrator {
            Some(i) => self.integrator(i, has_media)?,
            None => self.run(scene, "Integrator \"path\" \"integer maxdepth\" [ 1024 ]")?,
        }
        match sensors.first() {
            Some(s) => self.sensor(s)?,
            None => {
                self.b.warn(format!(
                    "{label}: the scene has no <sensor>; Mitsuba's default (768 x 576, fov 45°) at the origin looking down +z is used"
                ));
                self.run(scene, "Film \"rgb\" \"integer xresolution\" [ 768 ] \"integer yresolution\" [ 576 ] Scale -1 1 1 Camera \"perspective\" \"float fov\" [ 34.5 ]")?;
            }
        }
        self.run(scene, "WorldBegin")?;
        for c in &scene.children {
            match c.tag.as_str() {
                "shape" => self.shape(c)?,
                "emitter" => self.emitter(c)?,
                "sensor" | "integrator" | "alias" => {}
                // Objects defined for later reference; made when used.
                "bsdf" | "texture" | "medium" | "phase" | "volume" | "spectrum" | "rfilter"
                | "sampler" | "film" => {
                    if c.attr("id").is_none() {
                        self.warn(c, "an unnamed object outside any other is not used");
                    }
                }
                other => {
                    let ty = c.attr("type").unwrap_or("");
                    self.b.warn(format!(
                        "{}: <{other}{}> is not supported and was ignored",
                        c.at(),
                        if ty.is_empty() {
                            String::new()
                        } else {
                            format!(" type=\"{ty}\"")
                        }
                    ));
                }
            }
        }
        Ok(())
    }

    fn integrator(&mut self, e: &'a Elem, has_media: bool) -> Result<(), SceneError> {
        let ty = e.attr("type").unwrap_or("");
        self.note(format!("integrator {ty}"));
        let depth = |tx: &Self, e: &'a Elem| -> Result<i64, SceneError> {
            let d = tx.float(e, "max_depth", -1.0)? as i64;
            let _ = tx.prop(e, "rr_depth");
            // Mitsuba counts path vertices (1: emitters seen directly); pbrt counts bounces.
            Ok(if d < 0 { 1024 } else { (d - 1).max(0) })
        };
        let (kind, maxdepth) = match ty {
            "path" | "volpath" | "volpathmis" => (
                if has_media || ty != "path" {
                    "volpath"
                } else {
                    "path"
                },
                depth(self, e)?,
            ),
            "direct" => {
                let _ = self.prop(e, "emitter_samples");
                let _ = self.prop(e, "bsdf_samples");
                self.approx(
                    e,
                    "rendered as the path tracer with one bounce (the same image, other noise)",
                );
                ("path", 1)
            }
            "ptracer" => {
                let _ = self.prop(e, "samples_per_pass");
                (PTRACER_INTEGRATOR, depth(self, e)?)
            }
            "aov" => {
                self.aov_list(e);
                match self.objects(e, "integrator")?.first() {
                    Some((inner, _)) => return self.integrator(inner, has_media),
                    None => ("path", 1024),
                }
            }
            other => {
                self.warn(
                    e,
                    &format!("integrator '{other}' is not supported; the path tracer renders"),
                );
                ("path", 1024)
            }
        };
        if self.boolean(e, "hide_emitters", false) {
            self.warn(e, "hide_emitters is not supported; emitters are visible");
        }
        self.unused(e);
        self.run(
            e,
            &format!("Integrator {} \"integer maxdepth\" [ {maxdepth} ]", q(kind)),
        )
    }

    /// The `aovs` string of Mitsuba's `aov` integrator ("name:type, …") as Trayecto's AOV
    /// layers. The layers keep Trayecto's channel names (`Z`, `P.X`, `N.X`, …), not the file's.
    fn aov_list(&mut self, e: &'a Elem) {
        use crate::film::aov::AovKind;
        let list = self.string(e, "aovs").unwrap_or_default();
        for item in list.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let ty = item.split_once(':').map_or(item, |(_, t)| t).trim();
            let kind = match ty {
                "albedo" => AovKind::Albedo,
                "depth" => AovKind::Depth,
                "position" => AovKind::Position,
                "sh_normal" => AovKind::ShadingNormal,
                "geo_normal" => {
                    self.approx(e, "the geo_normal AOV is the shading normal");
                    AovKind::ShadingNormal
                }
                "shape_index" => AovKind::ObjectId,
                other => {
                    self.warn(
                        e,
                        &format!("the AOV type '{other}' is not supported; it is not written"),
                    );
                    continue;
                }
            };
            if !self.aovs.contains(&kind) {
                self.aovs.push(kind);
            }
        }
        if !self.aovs.is_empty() {
            self.approx(
                e,
                "AOV layers are written under Trayecto's channel names (albedo.R, Z, P.X, N.X, IndexOB.X), not the file's",
            );
        }
    }

    fn sensor(&mut self, e: &'a Elem) -> Result<(), SceneError> {
        let ty = e.attr("type").unwrap_or("");
        self.note(format!("sensor {ty}"));
        // Film first: the field of view depends on its size.
        let film = self.objects(e, "film")?.first().map(|f| f.0);
        let (mut w, mut h) = (768u32, 576u32);
        let mut film_text = String::from("Film \"rgb\"");
        if let Some(f) = film {
            let fty = f.attr("type").unwrap_or("");
            self.note(format!("film {fty}"));
            if fty != "hdrfilm" {
                self.warn(f, "read as hdrfilm");
            }
            w = self.float(f, "width", 768.0)?.max(1.0) as u32;
            h = self.float(f, "height", 576.0)?.max(1.0) as u32;
            film_text.push_str(&format!(
                " \"integer xresolution\" [ {w} ] \"integer yresolution\" [ {h} ]"
            ));
            if self.prop(f, "crop_width").is_some() || self.prop(f, "crop_offset_x").is_some() {
                let cx = self.float(f, "crop_offset_x", 0.0)? as u32;
                let cy = self.float(f, "crop_offset_y", 0.0)? as u32;
                let cw = self.float(f, "crop_width", (w - cx.min(w)) as f32)? as u32;
                let ch = self.float(f, "crop_height", (h - cy.min(h)) as f32)? as u32;
                let _ = self.prop(f, "crop_offset_y");
                let _ = self.prop(f, "crop_height");
                film_text.push_str(&format!(
                    " \"integer pixelbounds\" [ {cx} {} {cy} {} ]",
                    (cx + cw).min(w),
                    (cy + ch).min(h)
                ));
            }
            for k in [
                "pixel_format",
                "component_format",
                "file_format",
                "sample_border",
                "compensate",
            ] {
                let _ = self.prop(f, k);
            }
            if let Some((rf, _)) = self.objects(f, "rfilter")?.first().copied() {
                self.filter(rf)?;
            } else {
                self.run(f, "PixelFilter \"gaussian\" \"float sigma\" [ 0.5 ] \"float xradius\" [ 2 ] \"float yradius\" [ 2 ]")?;
            }
            self.unused(f);
            self.run(f, &film_text)?;
        } else {
            film_text.push_str(" \"integer xresolution\" [ 768 ] \"integer yresolution\" [ 576 ]");
            self.run(e, &film_text)?;
        }
        if let Some((s, _)) = self.objects(e, "sampler")?.first().copied() {
            let sty = s.attr("type").unwrap_or("");
            self.note(format!("sampler {sty}"));
            let n = self.float(s, "sample_count", 4.0)?.max(1.0) as u32;
            let _ = self.prop(s, "seed");
            let _ = self.prop(s, "jitter");
            self.unused(s);
            self.approx(
                s,
                "Trayecto's own sample generator draws sample_count samples per pixel",
            );
            self.b.set_spp(n);
        }
        let to_world = self.transform(e, "to_world")?;
        // Mitsuba's camera space: +z forward, +y up, +x to the image's left; pbrt's x points right.
        let x = to_world.x_axis.truncate();
        let y = to_world.y_axis.truncate();
        let (sx, sy) = (x.length(), y.length());
        let z = to_world.z_axis.truncate().normalize_or_zero();
        let rigid = Mat4::from_cols(
            (-x / sx.max(1e-30)).extend(0.0),
            (y / sy.max(1e-30)).extend(0.0),
            z.extend(0.0),
            to_world.w_axis,
        );
        let Some(cam_from_world) = (rigid.determinant().is_normal()).then(|| rigid.inverse())
        else {
            return Err(SceneError::invalid(
                e.at(),
                "the sensor's to_world is singular",
            ));
        };
        let aspect = w as f32 / h as f32;
        let mut params = String::new();
        // How the view follows a film of another shape (a render at another --width/--height):
        // Mitsuba keeps the field of view across `fov_axis`, the orthographic window's width.
        let mut fit = crate::scene::SensorFit::Width;
        let proj = match ty {
            "perspective" | "thinlens" => {
                let mut axis = self.string(e, "fov_axis").unwrap_or_else(|| "x".into());
                let fov = if let Some(fl) = self.string(e, "focal_length") {
                    let mm: f32 = fl.trim().trim_end_matches("mm").parse().map_err(|_| {
                        SceneError::invalid(
                            e.at(),
                            format!("focal_length '{fl}' is not a length in mm"),
                        )
                    })?;
                    axis = "diagonal".into();
                    2.0 * (36f32.hypot(24.0) / (2.0 * mm)).atan().to_degrees()
                } else {
                    self.float(e, "fov", 39.3077)?
                };
                let t = (fov.to_radians() * 0.5).tan();
                let (wf, hf) = (w as f32, h as f32);
                let t_x = match axis.as_str() {
                    "x" => t,
                    "y" => t * wf / hf,
                    "diagonal" => t * wf / wf.hypot(hf),
                    "smaller" => {
                        if wf < hf {
                            t
                        } else {
                            t * wf / hf
                        }
                    }
                    "larger" => {
                        if wf > hf {
                            t
                        } else {
                            t * wf / hf
                        }
                    }
                    other => {
                        return Err(SceneError::invalid(
                            e.at(),
                            format!("fov_axis '{other}' is unknown"),
                        ));
                    }
                };
                fit = match axis.as_str() {
                    "y" => crate::scene::SensorFit::Height,
                    "diagonal" => crate::scene::SensorFit::Diagonal,
                    "smaller" => crate::scene::SensorFit::Shorter,
                    "larger" => crate::scene::SensorFit::Auto,
                    _ => crate::scene::SensorFit::Width,
                };
                let t_short = if wf < hf { t_x } else { t_x * hf / wf };
                params.push_str(&format!(
                    " \"float fov\" [ {} ]",
                    2.0 * t_short.atan().to_degrees()
                ));
                if ty == "thinlens" {
                    let r = self.float(e, "aperture_radius", 0.0)?;
                    let d = self.float(e, "focus_distance", 0.0)?;
                    params.push_str(&format!(
                        " \"float lensradius\" [ {r} ] \"float focaldistance\" [ {d} ]"
                    ));
                } else {
                    let _ = self.prop(e, "focus_distance");
                }
                "perspective"
            }
            "orthographic" => {
                // Mitsuba's window is x in [-1, 1] and y in [-1/aspect, 1/aspect], scaled by to_world.
                params.push_str(&format!(
                    " \"float screenwindow\" [ {} {} {} {} ]",
                    -sx,
                    sx,
                    -sy / aspect,
                    sy / aspect
                ));
                "orthographic"
            }
            other => {
                self.warn(
                    e,
                    &format!("sensor '{other}' is not supported; a perspective camera is used"),
                );
                params.push_str(" \"float fov\" [ 45 ]");
                fit = crate::scene::SensorFit::Shorter;
                "perspective"
            }
        };
        for k in [
            "near_clip",
            "far_clip",
            "shutter_open",
            "shutter_close",
            "principal_point_offset_x",
            "principal_point_offset_y",
        ] {
            let _ = self.prop(e, k);
        }
        let mut text = String::new();
        if let Some((m, _)) = self.objects(e, "medium")?.first().copied() {
            let name = self.medium(m)?;
            text.push_str(&format!("MediumInterface \"\" {} ", q(&name)));
        }
        text.push_str(&format!(
            "Transform {} Camera \"{proj}\"{params}",
            nums(&cam_from_world.to_cols_array())
        ));
        self.unused(e);
        self.run(e, &text)?;
        self.b.set_camera_fit(fit);
        Ok(())
    }

    fn filter(&mut self, f: &'a Elem) -> Result<(), SceneError> {
        let ty = f.attr("type").unwrap_or("");
        self.note(format!("rfilter {ty}"));
        let text = match ty {
            "box" => "PixelFilter \"box\" \"float xradius\" [ 0.5 ] \"float yradius\" [ 0.5 ]"
                .to_string(),
            "tent" => {
                let r = self.float(f, "radius", 1.0)?;
                format!(
                    "PixelFilter \"triangle\" \"float xradius\" [ {r} ] \"float yradius\" [ {r} ]"
                )
            }
            "gaussian" => {
                let s = self.float(f, "stddev", 0.5)?;
                format!(
                    "PixelFilter \"gaussian\" \"float sigma\" [ {s} ] \"float xradius\" [ {r} ] \"float yradius\" [ {r} ]",
                    r = 4.0 * s
                )
            }
            "mitchell" | "catmullrom" => {
                let (b, c) = if ty == "mitchell" {
                    (
                        self.float(f, "B", 1.0 / 3.0)?,
                        self.float(f, "C", 1.0 / 3.0)?,
                    )
                } else {
                    (0.0, 0.5)
                };
                format!(
                    "PixelFilter \"mitchell\" \"float B\" [ {b} ] \"float C\" [ {c} ] \"float xradius\" [ 2 ] \"float yradius\" [ 2 ]"
                )
            }
            other => {
                self.warn(
                    f,
                    &format!(
                        "filter '{other}' is not supported; Mitsuba's default Gaussian is used"
                    ),
                );
                "PixelFilter \"gaussian\" \"float sigma\" [ 0.5 ] \"float xradius\" [ 2 ] \"float yradius\" [ 2 ]".to_string()
            }
        };
        self.unused(f);
        self.run(f, &text)
    }

    // ---- textures and materials ----

    /// Defines the pbrt texture for `t` (as a float or spectrum texture) and returns its name.
    fn texture(&mut self, t: &'a Elem, float: bool) -> Result<Option<String>, SceneError> {
        let kind: &'static str = if float { "float" } else { "spectrum" };
        if let Some(n) = self.made.get(&(t as *const Elem, kind)) {
            return Ok(Some(n.clone()));
        }
        let ty = t.attr("type").unwrap_or("");
        self.note(format!("texture {ty}"));
        let name = self.fresh(t.attr("id").unwrap_or(ty));
        let m = self.transform(t, "to_uv")?;
        if m.x_axis.y != 0.0 || m.y_axis.x != 0.0 {
            self.approx(
                t,
                "to_uv with rotation or shear: only its scale and offset are used",
            );
        }
        let (su, sv, du, dv) = (m.x_axis.x, m.y_axis.y, m.w_axis.x, m.w_axis.y);
        let text = match ty {
            "bitmap" => {
                let Some(f) = self.string(t, "filename") else {
                    return Err(SceneError::invalid(t.at(), "bitmap without a filename"));
                };
                let Some(rel) = self.file(t, &f)? else {
                    return Ok(None);
                };
                let filter = match self.string(t, "filter_type").as_deref() {
                    Some("nearest") => "point",
                    _ => "bilinear",
                };
                let wrap = match self.string(t, "wrap_mode").as_deref() {
                    Some("clamp") => "clamp",
                    Some("mirror") => {
                        self.approx(t, "wrap_mode mirror is rendered as repeat");
                        "repeat"
                    }
                    _ => "repeat",
                };
                let raw = self.boolean(t, "raw", false);
                let _ = self.prop(t, "format");
                // Mitsuba looks images up at (u', v') = to_uv·(u, v) with v down; pbrt at
                // (su·u + du, sv·v + dv) with v up, and the mesh's v is stored as 1 − v.
                format!(
                    "Texture {} \"{kind}\" \"imagemap\" \"string filename\" {} \"string filter\" \"{filter}\" \"string wrap\" \"{wrap}\"{} \"float uscale\" [ {su} ] \"float vscale\" [ {sv} ] \"float udelta\" [ {du} ] \"float vdelta\" [ {} ]",
                    q(&name),
                    q(&rel),
                    if raw {
                        " \"string encoding\" \"linear\""
                    } else {
                        ""
                    },
                    1.0 - sv - dv
                )
            }
            "checkerboard" => {
                let c0 = self
                    .color(t, "color0", Some(0.4))?
                    .unwrap_or(Col::Rgb(Vec3::splat(0.4)));
                let c1 = self
                    .color(t, "color1", Some(0.2))?
                    .unwrap_or(Col::Rgb(Vec3::splat(0.2)));
                // Mitsuba: colour 0 where ⌊2u'⌋ + ⌊2v'⌋ is even; pbrt: tex1 where ⌊s⌋ + ⌊t⌋ is.
                format!(
                    "Texture {} \"{kind}\" \"checkerboard\" {} {} \"float uscale\" [ {} ] \"float vscale\" [ {} ] \"float udelta\" [ {} ] \"float vdelta\" [ {} ]",
                    q(&name),
                    Self::param("tex1", &c0, float),
                    Self::param("tex2", &c1, float),
                    2.0 * su,
                    -2.0 * sv,
                    2.0 * du,
                    2.0 * (sv + dv)
                )
            }
            other => {
                self.warn(
                    t,
                    &format!("texture '{other}' is not supported; grey 0.5 is used"),
                );
                format!(
                    "Texture {} \"{kind}\" \"constant\" \"{} value\" {}",
                    q(&name),
                    if float { "float" } else { "rgb" },
                    if float { "[ 0.5 ]" } else { "[ 0.5 0.5 0.5 ]" }
                )
            }
        };
        self.unused(t);
        self.run(t, &text)?;
        self.made.insert((t as *const Elem, kind), name.clone());
        Ok(Some(name))
    }

    /// Resolves a file an element names; `None` (warned) when parsing from memory.
    fn file(&mut self, e: &Elem, name: &str) -> Result<Option<String>, SceneError> {
        let Some(root) = &self.root else {
            self.warn(
                e,
                &format!("'{name}': files are not read when parsing text from memory"),
            );
            return Ok(None);
        };
        resolve(root, &e.dir, &self.search, name)
            .map(|(rel, _)| Some(rel))
            .map_err(|m| SceneError::invalid(e.at(), m))
    }

    fn ior(&self, e: &'a Elem, name: &str, default: f32) -> Result<f32, SceneError> {
        match self.value(e, name) {
            None => Ok(default),
            Some(v) => match v.trim().parse::<f32>() {
                Ok(x) => Ok(x),
                Err(_) => named_ior(v).ok_or_else(|| {
                    SceneError::invalid(
                        e.at(),
                        format!("{name}: '{v}' is not a number or a known material"),
                    )
                }),
            },
        }
    }

    /// Roughness parameters (`alpha` or `alpha_u`/`alpha_v`), unremapped.
    fn roughness(&mut self, e: &'a Elem, default: f32) -> Result<String, SceneError> {
        if self
            .string(e, "distribution")
            .as_deref()
            .unwrap_or("beckmann")
            == "beckmann"
        {
            self.approx(
                e,
                "the Beckmann distribution is rendered with GGX of the same alpha",
            );
        }
        let _ = self.prop(e, "sample_visible");
        let mut s = String::from(" \"bool remaproughness\" false");
        if self.prop(e, "alpha_u").is_some() {
            let u = self
                .float_param(e, "alpha_u", "uroughness")?
                .unwrap_or_default();
            let v = self
                .float_param(e, "alpha_v", "vroughness")?
                .unwrap_or_default();
            s.push_str(&format!(" {u} {v}"));
        } else {
            let a = self
                .float_param(e, "alpha", "roughness")?
                .unwrap_or_else(|| format!("\"float roughness\" [ {default} ]"));
            s.push_str(&format!(" {a}"));
        }
        Ok(s)
    }

    /// The pbrt material for a BSDF element: its name and the shape alpha a `mask` asks for.
    fn bsdf(&mut self, e: &'a Elem) -> Result<(String, Option<String>), SceneError> {
        if let Some(n) = self.made.get(&(e as *const Elem, "material")) {
            let alpha = self.made.get(&(e as *const Elem, "alpha")).cloned();
            return Ok((n.clone(), alpha));
        }
        let ty = e.attr("type").unwrap_or("");
        let spec = match self.bsdf_spec(e)? {
            Ok(spec) => spec,
            Err(done) => return Ok(done),
        };
        let name = self.fresh(e.attr("id").unwrap_or(ty));
        self.run(e, &format!("MakeNamedMaterial {} {spec}", q(&name)))?;
        self.made
            .insert((e as *const Elem, "material"), name.clone());
        Ok((name, None))
    }

    /// A BSDF's pbrt parameter text (`Ok`), or the material it stands for when it wraps
    /// another (`twosided`, `mask`: `Err`).
    #[allow(clippy::type_complexity)]
    fn bsdf_spec(
        &mut self,
        e: &'a Elem,
    ) -> Result<Result<String, (String, Option<String>)>, SceneError> {
        let ty = e.attr("type").unwrap_or("");
        self.note(format!("bsdf {ty}"));
        let child = |tx: &mut Self| -> Result<Option<&'a Elem>, SceneError> {
            Ok(tx.objects(e, "bsdf")?.first().map(|c| c.0))
        };
        let spec: String = match ty {
            "diffuse" => {
                let r = self
                    .color(e, "reflectance", Some(0.5))?
                    .unwrap_or(Col::Rgb(Vec3::splat(0.5)));
                format!(
                    "\"string type\" \"diffuse\" {}",
                    Self::param("reflectance", &r, false)
                )
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                let eta = self.ior(e, "int_ior", 1.5046)? / self.ior(e, "ext_ior", 1.000_277)?;
                for k in ["specular_reflectance", "specular_transmittance"] {
                    if self.prop(e, k).is_some() {
                        self.approx(e, &format!("{k} is not used (white)"));
                    }
                }
                if ty == "thindielectric" {
                    format!("\"string type\" \"thindielectric\" \"float eta\" [ {eta} ]")
                } else if ty == "roughdielectric" {
                    let r = self.roughness(e, 0.1)?;
                    format!("\"string type\" \"dielectric\" \"float eta\" [ {eta} ]{r}")
                } else {
                    format!("\"string type\" \"dielectric\" \"float eta\" [ {eta} ]")
                }
            }
            "conductor" | "roughconductor" => {
                let mat = self.string(e, "material").unwrap_or_else(|| "none".into());
                let mut s = String::from("\"string type\" \"conductor\"");
                if self.prop(e, "eta").is_some() || self.prop(e, "k").is_some() {
                    let eta = self
                        .color(e, "eta", Some(0.0))?
                        .unwrap_or(Col::Rgb(Vec3::ZERO));
                    let k = self
                        .color(e, "k", Some(1.0))?
                        .unwrap_or(Col::Rgb(Vec3::ONE));
                    s.push_str(&format!(
                        " {} {}",
                        Self::param("eta", &eta, false),
                        Self::param("k", &k, false)
                    ));
                } else if mat == "none" {
                    s.push_str(" \"rgb reflectance\" [ 1 1 1 ]");
                } else {
                    let m = if PBRT_METALS.contains(&mat.as_str()) {
                        mat.clone()
                    } else {
                        self.warn(
                            e,
                            &format!(
                                "material '{mat}' has no (eta, k) in Trayecto; aluminium is used"
                            ),
                        );
                        "Al".into()
                    };
                    s.push_str(&format!(
                        " \"spectrum eta\" \"metal-{m}-eta\" \"spectrum k\" \"metal-{m}-k\""
                    ));
                }
                if let Some(sr) = self.prop(e, "specular_reflectance") {
                    let _ = sr;
                    self.approx(e, "specular_reflectance is not used (white)");
                }
                if ty == "roughconductor" {
                    s.push_str(&self.roughness(e, 0.1)?);
                }
                s
            }
            "plastic" | "roughplastic" => {
                let eta = self.ior(e, "int_ior", 1.49)? / self.ior(e, "ext_ior", 1.000_277)?;
                let d = self
                    .color(e, "diffuse_reflectance", Some(0.5))?
                    .unwrap_or(Col::Rgb(Vec3::splat(0.5)));
                let _ = self.prop(e, "nonlinear");
                if self.prop(e, "specular_reflectance").is_some() {
                    self.approx(e, "specular_reflectance is not used (white)");
                }
                self.approx(e, "rendered as pbrt's coated diffuse layer (Mitsuba's plastic is an analytic model of it)");
                let r = if ty == "roughplastic" {
                    self.roughness(e, 0.1)?
                } else {
                    " \"float roughness\" [ 0 ]".into()
                };
                format!(
                    "\"string type\" \"coateddiffuse\" {} \"float eta\" [ {eta} ] \"float thickness\" [ 0.0001 ]{r}",
                    Self::param("reflectance", &d, false)
                )
            }
            "principled" | "principledthin" => {
                let base = self
                    .color(e, "base_color", Some(0.5))?
                    .unwrap_or(Col::Rgb(Vec3::splat(0.5)));
                let rough = self.float(e, "roughness", 0.5)?;
                let metallic = self.float(e, "metallic", 0.0)?;
                self.approx(e, "rendered as a coated diffuse (metallic < 0.5) or a conductor of the base colour");
                let a = rough * rough;
                if metallic >= 0.5 {
                    format!(
                        "\"string type\" \"conductor\" {} \"float roughness\" [ {a} ] \"bool remaproughness\" false",
                        Self::param("reflectance", &base, false)
                    )
                } else {
                    format!(
                        "\"string type\" \"coateddiffuse\" {} \"float roughness\" [ {a} ] \"bool remaproughness\" false \"float eta\" [ 1.5 ] \"float thickness\" [ 0.0001 ]",
                        Self::param("reflectance", &base, false)
                    )
                }
            }
            "twosided" => {
                let Some(c) = child(self)? else {
                    return Err(SceneError::invalid(
                        e.at(),
                        "twosided without a nested bsdf",
                    ));
                };
                if self.objects(e, "bsdf")?.len() > 1 {
                    self.warn(
                        e,
                        "a different BSDF on the back side is not supported: the front one is used on both sides",
                    );
                }
                let r = self.bsdf(c)?;
                self.made
                    .insert((e as *const Elem, "material"), r.0.clone());
                if let Some(a) = &r.1 {
                    self.made.insert((e as *const Elem, "alpha"), a.clone());
                }
                return Ok(Err(r));
            }
            "mask" => {
                let Some(c) = child(self)? else {
                    return Err(SceneError::invalid(e.at(), "mask without a nested bsdf"));
                };
                let r = self.bsdf(c)?;
                let a = match self.prop(e, "opacity") {
                    Some(o) => match self.color_of(o, true)? {
                        Some(Col::Tex(t)) => t,
                        Some(Col::Rgb(v)) => {
                            let n = self.fresh("opacity");
                            self.run(
                                e,
                                &format!(
                                    "Texture {} \"float\" \"constant\" \"float value\" [ {} ]",
                                    q(&n),
                                    (v.x + v.y + v.z) / 3.0
                                ),
                            )?;
                            n
                        }
                        _ => return Err(SceneError::invalid(e.at(), "mask: unsupported opacity")),
                    },
                    None => {
                        let n = self.fresh("opacity");
                        self.run(
                            e,
                            &format!(
                                "Texture {} \"float\" \"constant\" \"float value\" [ 0.5 ]",
                                q(&n)
                            ),
                        )?;
                        n
                    }
                };
                self.approx(
                    e,
                    "the mask is the shape's alpha (pbrt's stochastic alpha test)",
                );
                self.made
                    .insert((e as *const Elem, "material"), r.0.clone());
                self.made.insert((e as *const Elem, "alpha"), a.clone());
                self.unused(e);
                return Ok(Err((r.0, Some(a))));
            }
            "blendbsdf" => {
                let kids = self.objects(e, "bsdf")?;
                if kids.len() != 2 {
                    return Err(SceneError::invalid(
                        e.at(),
                        "blendbsdf needs two nested bsdfs",
                    ));
                }
                let a = self.bsdf(kids[0].0)?.0;
                let b = self.bsdf(kids[1].0)?.0;
                let w = self
                    .float_param(e, "weight", "amount")?
                    .unwrap_or_else(|| "\"float amount\" [ 0.5 ]".into());
                format!(
                    "\"string type\" \"mix\" \"string materials\" [ {} {} ] {w}",
                    q(&a),
                    q(&b)
                )
            }
            "bumpmap" | "normalmap" => {
                let Some(c) = child(self)? else {
                    return Err(SceneError::invalid(
                        e.at(),
                        format!("{ty} without a nested bsdf"),
                    ));
                };
                let inner = self.spec_of(c)?;
                let tex = self.objects(e, "texture")?.first().map(|t| t.0);
                let Some(tex) = tex else {
                    return Err(SceneError::invalid(
                        e.at(),
                        format!("{ty} without a nested texture"),
                    ));
                };
                if ty == "bumpmap" {
                    let scale = self.float(e, "scale", 1.0)?;
                    let Some(t) = self.texture(tex, true)? else {
                        return Ok(Err(self.bsdf(c)?));
                    };
                    let d = self.fresh("bump");
                    self.run(e, &format!("Texture {} \"float\" \"scale\" \"texture tex\" {} \"float scale\" [ {scale} ]", q(&d), q(&t)))?;
                    format!("{inner} \"texture displacement\" {}", q(&d))
                } else {
                    self.read.borrow_mut().insert(tex as *const Elem);
                    let Some(f) = self.string(tex, "filename") else {
                        return Err(SceneError::invalid(
                            tex.at(),
                            "normalmap: the texture needs a filename",
                        ));
                    };
                    let _ = self.prop(tex, "raw");
                    let Some(rel) = self.file(tex, &f)? else {
                        return Ok(Err(self.bsdf(c)?));
                    };
                    format!("{inner} \"string normalmap\" {}", q(&rel))
                }
            }
            "null" => "\"string type\" \"interface\"".to_string(),
            other => {
                self.warn(
                    e,
                    &format!("BSDF '{other}' is not supported; diffuse grey 0.5 is used"),
                );
                "\"string type\" \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]".to_string()
            }
        };
        self.unused(e);
        Ok(Ok(spec))
    }

    /// The pbrt parameter text of a BSDF, for wrappers that add to it (bump and normal maps);
    /// a wrapped wrapper (`twosided` inside `bumpmap`) gives its inner BSDF's.
    fn spec_of(&mut self, c: &'a Elem) -> Result<String, SceneError> {
        let mut c = c;
        loop {
            if c.attr("type") == Some("twosided")
                && let Some((inner, _)) = self.objects(c, "bsdf")?.first().copied()
            {
                self.note("bsdf twosided".into());
                c = inner;
                continue;
            }
            return match self.bsdf_spec(c)? {
                Ok(s) => Ok(s),
                Err((name, _)) => Ok(format!(
                    "\"string type\" \"mix\" \"string materials\" [ {n} {n} ] \"float amount\" [ 0 ]",
                    n = q(&name)
                )),
            };
        }
    }

    fn medium(&mut self, m: &'a Elem) -> Result<String, SceneError> {
        if let Some(n) = self.made.get(&(m as *const Elem, "medium")) {
            return Ok(n.clone());
        }
        let ty = m.attr("type").unwrap_or("");
        self.note(format!("medium {ty}"));
        let name = self.fresh(m.attr("id").unwrap_or(ty));
        let scale = self.float(m, "scale", 1.0)?;
        let mut g = 0.0;
        if let Some((p, _)) = self.objects(m, "phase")?.first().copied() {
            match p.attr("type").unwrap_or("") {
                "hg" => g = self.float(p, "g", 0.8)?,
                "isotropic" => {}
                other => self.warn(
                    p,
                    &format!("phase function '{other}' is not supported; isotropic is used"),
                ),
            }
            self.note(format!("phase {}", p.attr("type").unwrap_or("")));
            self.unused(p);
        }
        let _ = self.prop(m, "sample_emitters");
        let _ = self.prop(m, "has_spectral_extinction");
        let vec_of = |tx: &mut Self,
                      k: &str,
                      d: f32|
         -> Result<(Vec3, Option<&'a Elem>), SceneError> {
            match tx.prop(m, k) {
                None => Ok((Vec3::splat(d), None)),
                Some(c) => {
                    let obj = tx.deref(c)?;
                    if obj.tag == "volume" {
                        return Ok((Vec3::ONE, Some(obj)));
                    }
                    match tx.color_of(c, false)? {
                        Some(Col::Rgb(v)) => Ok((v, None)),
                        _ => {
                            tx.warn(m, &format!("'{k}': only constant values and volumes are supported; {d} is used"));
                            Ok((Vec3::splat(d), None))
                        }
                    }
                }
            }
        };
        let (sigma_t, st_vol) = vec_of(self, "sigma_t", 1.0)?;
        let (mut albedo, al_vol) = vec_of(self, "albedo", 0.75)?;
        if let Some(v) = al_vol {
            albedo = self.volume_constant(v, 0.75)?;
        }
        let mut desc = MediumDesc::homogeneous(
            &name,
            sigma_t * (Vec3::ONE - albedo),
            sigma_t * albedo,
            scale,
            g.clamp(-0.99, 0.99),
        );
        match (ty, st_vol) {
            ("homogeneous", None) => {}
            (_, Some(v)) => {
                let vty = v.attr("type").unwrap_or("");
                self.note(format!("volume {vty}"));
                if vty == "constvolume" {
                    let c = self.volume_constant(v, 1.0)?;
                    desc.sigma_a *= c;
                    desc.sigma_s *= c;
                } else if let Some(f) = self.string(v, "filename") {
                    let Some(root) = self.root.clone() else {
                        self.warn(v, "files are not read when parsing text from memory");
                        return Ok(name);
                    };
                    let (_, path) = resolve(&root, &v.dir, &self.search, &f)
                        .map_err(|e| SceneError::invalid(v.at(), e))?;
                    let bytes = crate::limits::read_file(&path).map_err(|e| SceneError::Io {
                        path: v.at(),
                        error: e,
                    })?;
                    let vol = crate::scene::vol::read_vol(&bytes)
                        .map_err(|e| SceneError::invalid(v.at(), format!("'{f}': {e}")))?;
                    let to_world = self.transform(v, "to_world")?;
                    for k in ["filter_type", "wrap_mode", "raw", "use_grid_bbox"] {
                        let _ = self.prop(v, k);
                    }
                    self.unused(v);
                    desc.kind = MediumKind::Grid {
                        nx: vol.nx,
                        ny: vol.ny,
                        nz: vol.nz,
                        density: vol.data,
                        min: Vec3::ZERO,
                        max: Vec3::ONE,
                        transform: to_world,
                        edge: crate::scene::GridEdge::Hold,
                        emission: None,
                    };
                } else {
                    self.warn(
                        v,
                        "volume without a filename; a constant density of 1 is used",
                    );
                }
            }
            ("heterogeneous", None) => {}
            (other, None) => {
                self.warn(
                    m,
                    &format!("medium '{other}' is not supported; homogeneous is used"),
                );
            }
        }
        self.unused(m);
        self.b.medium(&name, desc);
        self.made.insert((m as *const Elem, "medium"), name.clone());
        Ok(name)
    }

    fn volume_constant(&mut self, v: &'a Elem, d: f32) -> Result<Vec3, SceneError> {
        if v.attr("type") == Some("constvolume") {
            let c = self.color(v, "value", Some(d))?;
            if let Some(Col::Rgb(c)) = c {
                return Ok(c);
            }
        }
        self.warn(
            v,
            &format!("only constant volumes are supported here; {d} is used"),
        );
        Ok(Vec3::splat(d))
    }

    // ---- shapes ----

    fn shape(&mut self, e: &'a Elem) -> Result<(), SceneError> {
        let ty = e.attr("type").unwrap_or("");
        self.note(format!("shape {ty}"));
        if ty == "shapegroup" {
            let name = e.attr("id").unwrap_or("shapegroup").to_string();
            self.run(e, &format!("ObjectBegin {}", q(&name)))?;
            for c in self.objects(e, "shape")? {
                self.shape(c.0)?;
            }
            self.made.insert((e as *const Elem, "group"), name);
            return self.run(e, "ObjectEnd");
        }
        let to_world = self.transform(e, "to_world")?;
        if ty == "instance" {
            let Some((g, _)) = self.objects(e, "shape")?.first().copied() else {
                return Err(SceneError::invalid(e.at(), "instance without a shapegroup"));
            };
            let Some(name) = self.made.get(&(g as *const Elem, "group")).cloned() else {
                return Err(SceneError::invalid(
                    e.at(),
                    "instance: the shapegroup is not defined before it",
                ));
            };
            self.unused(e);
            return self.run(
                e,
                &format!(
                    "AttributeBegin Transform {} ObjectInstance {} AttributeEnd",
                    nums(&to_world.to_cols_array()),
                    q(&name)
                ),
            );
        }
        let mut head = String::from("AttributeBegin ");
        // Material (grey diffuse by default, as Mitsuba).
        let bsdfs = self.objects(e, "bsdf")?;
        let (mat, alpha) = match bsdfs.first() {
            Some((b, _)) => self.bsdf(b)?,
            None => {
                let n = "mitsuba-default".to_string();
                if !self.made.contains_key(&(std::ptr::null(), "material")) {
                    self.run(e, "MakeNamedMaterial \"mitsuba-default\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]")?;
                    self.made.insert((std::ptr::null(), "material"), n.clone());
                }
                (n, None)
            }
        };
        head.push_str(&format!("NamedMaterial {} ", q(&mat)));
        // Media.
        let mut interior = String::new();
        let mut exterior = String::new();
        for (m, role) in self.objects(e, "medium")? {
            let n = self.medium(m)?;
            match role {
                Some("interior") => interior = n,
                Some("exterior") => exterior = n,
                _ => self.warn(
                    e,
                    "a medium without name=\"interior\" or \"exterior\" is ignored",
                ),
            }
        }
        if !interior.is_empty() || !exterior.is_empty() {
            head.push_str(&format!(
                "MediumInterface {} {} ",
                q(&interior),
                q(&exterior)
            ));
        }
        // Area emitter.
        for (em, _) in self.objects(e, "emitter")? {
            let ety = em.attr("type").unwrap_or("");
            self.note(format!("emitter {ety}"));
            if ety != "area" {
                self.warn(em, "only area emitters can be attached to shapes");
                continue;
            }
            self.emitting = true;
            let r = self.color(em, "radiance", Some(1.0));
            self.emitting = false;
            let r = r?.unwrap_or(Col::Rgb(Vec3::ONE));
            let r = match r {
                Col::Tex(_) => {
                    self.warn(em, "textured radiance is not supported; 1 is used");
                    Col::Rgb(Vec3::ONE)
                }
                c => c,
            };
            self.unused(em);
            head.push_str(&format!(
                "AreaLightSource \"diffuse\" {} ",
                Self::param("L", &r, false)
            ));
        }
        if self.boolean(e, "flip_normals", false) {
            head.push_str("ReverseOrientation ");
        }
        let face_normals = self.boolean(e, "face_normals", false);
        let alpha_param = alpha
            .as_ref()
            .map(|a| format!(" \"texture alpha\" {}", q(a)))
            .unwrap_or_default();
        let place = |m: Mat4| format!("Transform {} ", nums(&m.to_cols_array()));
        match ty {
            "obj" | "ply" | "serialized" => {
                let Some(f) = self.string(e, "filename") else {
                    return Err(SceneError::invalid(
                        e.at(),
                        format!("{ty} without a filename"),
                    ));
                };
                let Some(root) = self.root.clone() else {
                    self.warn(
                        e,
                        &format!("'{f}': files are not read when parsing text from memory"),
                    );
                    return Ok(());
                };
                let (_, path) = resolve(&root, &e.dir, &self.search, &f)
                    .map_err(|m| SceneError::invalid(e.at(), m))?;
                let bytes = crate::limits::read_file(&path).map_err(|err| SceneError::Io {
                    path: format!("{}: {f}", e.at()),
                    error: err,
                })?;
                let label = path.display().to_string();
                let (p, idx, n, uv) = match ty {
                    "serialized" => {
                        let index = self.float(e, "shape_index", 0.0)? as usize;
                        let m = super::serialized::read(&bytes, index)
                            .map_err(|m| SceneError::invalid(&label, m))?;
                        let uv = m.uvs.map(|uv| {
                            uv.chunks_exact(2)
                                .flat_map(|c| [c[0], 1.0 - c[1]])
                                .collect::<Vec<_>>()
                        });
                        (m.positions, m.indices, m.normals, uv)
                    }
                    _ => {
                        let s = if ty == "obj" {
                            crate::scene::obj::load_from_bytes(
                                &bytes,
                                path.parent().unwrap_or(Path::new(".")),
                                &label,
                            )?
                        } else {
                            crate::scene::ply::load_from_bytes(&bytes, &label)?
                        };
                        merge_meshes(&s, ty == "obj")
                    }
                };
                let _ = self.prop(e, "flip_tex_coords");
                self.unused(e);
                head.push_str(&place(to_world));
                self.run(e, &head)?;
                let n = if face_normals { None } else { n };
                self.b.triangle_mesh(
                    &p,
                    &idx,
                    n.as_deref(),
                    uv.as_deref(),
                    alpha.as_deref(),
                    &e.at(),
                )?;
            }
            "rectangle" | "cube" => {
                let (p, idx, n, uv) = if ty == "rectangle" {
                    rectangle()
                } else {
                    cube()
                };
                self.unused(e);
                head.push_str(&place(to_world));
                self.run(e, &head)?;
                self.b
                    .triangle_mesh(&p, &idx, Some(&n), Some(&uv), alpha.as_deref(), &e.at())?;
            }
            "sphere" | "disk" | "cylinder" => {
                let (m, shape) = match ty {
                    "sphere" => {
                        let c = self.point(e, "center")?.unwrap_or(Vec3::ZERO);
                        let r = self.float(e, "radius", 1.0)?;
                        (
                            to_world * Mat4::from_translation(c),
                            format!("Shape \"sphere\" \"float radius\" [ {r} ]"),
                        )
                    }
                    "disk" => (
                        to_world,
                        "Shape \"disk\" \"float radius\" [ 1 ]".to_string(),
                    ),
                    _ => {
                        let p0 = self.point(e, "p0")?.unwrap_or(Vec3::ZERO);
                        let p1 = self.point(e, "p1")?.unwrap_or(Vec3::Z);
                        let r = self.float(e, "radius", 1.0)?;
                        let d = p1 - p0;
                        let len = d.length();
                        if !(len > 0.0) {
                            return Err(SceneError::invalid(e.at(), "cylinder: p0 equals p1"));
                        }
                        let z = d / len;
                        let (x, y) = z.any_orthonormal_pair();
                        let frame = Mat4::from_cols(
                            x.extend(0.0),
                            y.extend(0.0),
                            z.extend(0.0),
                            p0.extend(1.0),
                        );
                        (to_world * frame * Mat4::from_scale(Vec3::new(r, r, len)), "Shape \"cylinder\" \"float radius\" [ 1 ] \"float zmin\" [ 0 ] \"float zmax\" [ 1 ]".to_string())
                    }
                };
                if ty != "sphere" && !alpha_param.is_empty() {
                    self.approx(e, "the mask's opacity on a disk or cylinder is not used");
                }
                self.unused(e);
                let alpha_text = if ty == "sphere" {
                    alpha_param.clone()
                } else {
                    String::new()
                };
                self.run(e, &format!("{head}{}{shape}{alpha_text}", place(m)))?;
            }
            other => {
                self.warn(
                    e,
                    &format!("shape '{other}' is not supported and was left out"),
                );
                return Ok(());
            }
        }
        self.run(e, "AttributeEnd")
    }

    fn emitter(&mut self, e: &'a Elem) -> Result<(), SceneError> {
        let ty = e.attr("type").unwrap_or("");
        self.note(format!("emitter {ty}"));
        let to_world = self.transform(e, "to_world")?;
        let light_col = |tx: &mut Self, k: &str| -> Result<Col, SceneError> {
            tx.emitting = true;
            let c = tx.color(e, k, Some(1.0));
            tx.emitting = false;
            match c? {
                Some(Col::Tex(_)) | None => {
                    tx.warn(e, &format!("a textured '{k}' is not supported; 1 is used"));
                    Ok(Col::Rgb(Vec3::ONE))
                }
                Some(c) => Ok(c),
            }
        };
        let text = match ty {
            "point" => {
                let p = match self.point(e, "position")? {
                    Some(p) => p,
                    None => to_world.w_axis.truncate(),
                };
                let i = light_col(self, "intensity")?;
                format!(
                    "AttributeBegin LightSource \"point\" {} \"point3 from\" {} AttributeEnd",
                    Self::param("I", &i, false),
                    nums(&p.to_array())
                )
            }
            "spot" => {
                let i = light_col(self, "intensity")?;
                let cutoff = self.float(e, "cutoff_angle", 20.0)?;
                let beam = self.float(e, "beam_width", cutoff * 0.75)?;
                if self.prop(e, "texture").is_some() {
                    self.warn(e, "a projected texture is not supported; the spot is white");
                }
                self.approx(e, "the falloff between beam_width and cutoff_angle is pbrt's smoothstep (Mitsuba's is linear in angle)");
                format!(
                    "AttributeBegin Transform {} LightSource \"spot\" {} \"point3 from\" [ 0 0 0 ] \"point3 to\" [ 0 0 1 ] \"float coneangle\" [ {cutoff} ] \"float conedelta\" [ {} ] AttributeEnd",
                    nums(&to_world.to_cols_array()),
                    Self::param("I", &i, false),
                    (cutoff - beam).max(0.0)
                )
            }
            "directional" => {
                let d = match self.point(e, "direction")? {
                    Some(d) => d,
                    None => to_world.z_axis.truncate(),
                };
                let l = light_col(self, "irradiance")?;
                format!(
                    "AttributeBegin LightSource \"distant\" {} \"point3 from\" [ 0 0 0 ] \"point3 to\" {} AttributeEnd",
                    Self::param("L", &l, false),
                    nums(&d.to_array())
                )
            }
            "constant" => {
                let l = light_col(self, "radiance")?;
                format!(
                    "AttributeBegin LightSource \"infinite\" {} AttributeEnd",
                    Self::param("L", &l, false)
                )
            }
            "envmap" => {
                let Some(f) = self.string(e, "filename") else {
                    return Err(SceneError::invalid(e.at(), "envmap without a filename"));
                };
                let scale = self.float(e, "scale", 1.0)?;
                let Some(root) = self.root.clone() else {
                    self.warn(e, "files are not read when parsing text from memory");
                    return Ok(());
                };
                let (_, path) = resolve(&root, &e.dir, &self.search, &f)
                    .map_err(|m| SceneError::invalid(e.at(), m))?;
                self.unused(e);
                self.b.light(LightDesc::Environment {
                    name: format!("envmap ({})", e.at()),
                    path,
                    scale: Vec3::splat(scale),
                    mapping: crate::scene::EnvMapping::Equirectangular,
                    transform: to_world,
                });
                return Ok(());
            }
            other => {
                self.warn(
                    e,
                    &format!("emitter '{other}' is not supported and was left out"),
                );
                return Ok(());
            }
        };
        self.unused(e);
        self.run(e, &text)
    }
}

type MeshArrays = (Vec<f32>, Vec<u32>, Option<Vec<f32>>, Option<Vec<f32>>);

/// The meshes of a loaded OBJ or PLY as one set of arrays in pbrt's uv convention. Trayecto's
/// readers store v as 1 − v of the file; Mitsuba flips an OBJ's v (so pbrt's v is 1 − stored)
/// and keeps a PLY's (pbrt's v is the stored value).
fn merge_meshes(s: &Scene, obj: bool) -> MeshArrays {
    let mut p = Vec::new();
    let mut idx = Vec::new();
    let all_n = s.meshes.iter().all(|m| m.normals.is_some());
    let all_uv = s.meshes.iter().all(|m| m.uv0.is_some());
    let mut n = all_n.then(Vec::new);
    let mut uv = all_uv.then(Vec::new);
    for o in &s.objects {
        let crate::scene::Shape::Mesh(mi) = o.shape else {
            continue;
        };
        let Some(m) = s.meshes.get(mi) else { continue };
        let base = (p.len() / 3) as u32;
        for v in &m.positions {
            p.extend_from_slice(&o.transform.transform_point3(*v).to_array());
        }
        idx.extend(m.indices.iter().flat_map(|t| t.map(|i| i + base)));
        if let (Some(n), Some(mn)) = (&mut n, &m.normals) {
            for v in mn {
                n.extend_from_slice(&o.transform.transform_vector3(*v).to_array());
            }
        }
        if let (Some(uv), Some(mu)) = (&mut uv, &m.uv0) {
            for t in mu {
                uv.extend_from_slice(&[t.x, if obj { 1.0 - t.y } else { t.y }]);
            }
        }
    }
    (p, idx, n, uv)
}

/// Mitsuba's `rectangle`: [−1, 1]² in the z = 0 plane facing +z, uv = (x + 1, y + 1) / 2 (pbrt
/// convention: v up, stored flipped by the pbrt loader).
fn rectangle() -> (Vec<f32>, Vec<u32>, Vec<f32>, Vec<f32>) {
    let p = vec![
        -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
    ];
    let n = [0.0, 0.0, 1.0].repeat(4);
    // Mitsuba's (u, v) with v down is (x+1)/2, (y+1)/2; pbrt's v is 1 − that.
    let uv = vec![0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    (p, vec![0, 1, 2, 0, 2, 3], n, uv)
}

/// Mitsuba's `cube`: [−1, 1]³ with outward faces, each its own four vertices and normal.
fn cube() -> (Vec<f32>, Vec<u32>, Vec<f32>, Vec<f32>) {
    let (mut p, mut idx, mut n, mut uv) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut normal = Vec3::ZERO;
            normal[axis] = sign;
            let u_axis = if axis == 0 { Vec3::Y } else { Vec3::X };
            let mut v_axis = normal.cross(u_axis);
            if v_axis.length_squared() == 0.0 {
                v_axis = Vec3::Z;
            }
            let base = (p.len() / 3) as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let q = normal + u_axis * a + v_axis * b;
                p.extend_from_slice(&q.to_array());
                n.extend_from_slice(&normal.to_array());
                uv.extend_from_slice(&[(a + 1.0) * 0.5, 1.0 - (b + 1.0) * 0.5]);
            }
            // Counter-clockwise seen from outside: u × v is the normal.
            if u_axis.cross(v_axis).dot(normal) > 0.0 {
                idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
            } else {
                idx.extend_from_slice(&[base, base + 2, base + 1, base, base + 3, base + 2]);
            }
        }
    }
    (p, idx, n, uv)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: [f32; 3], tol: f32) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() <= tol * b[i].abs().max(0.05))
    }

    /// Values printed by Mitsuba 3.9.1 (`scalar_rgb`, `mi.spectrum_list_to_srgb`, which its XML
    /// parser calls with d65 = bounded = true for reflectances and false inside emitters).
    #[test]
    fn sampled_spectra_convert_as_mitsuba_does() {
        let flat = |v| vec![(400.0, v), (700.0, v)];
        let light = [(400.0, 0.0), (500.0, 8.0), (600.0, 15.6), (700.0, 18.4)];
        let cases: [(Vec3, [f32; 3]); 3] = [
            (
                sampled_rgb(&flat(0.5), false).unwrap(),
                [0.497671, 0.499878, 0.497455],
            ),
            (
                sampled_rgb(&flat(1.0), true).unwrap(),
                [1.19969, 0.949521, 0.903443],
            ),
            (
                sampled_rgb(&light, true).unwrap(),
                [20.7108, 10.8546, 2.77115],
            ),
        ];
        for (got, want) in cases {
            assert!(close(got, want, 0.01), "{got:?} vs Mitsuba {want:?}");
        }
        assert!(sampled_rgb(&[], false).is_none());
        assert!(sampled_rgb(&[(500.0, f32::NAN)], true).is_none());
        // One sample: a line of zero width, still a value.
        assert!(sampled_rgb(&[(550.0, 1.0)], false).is_some());
    }
}
