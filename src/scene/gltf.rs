//! glTF 2.0 loader (`.gltf` and `.glb`), docs/DESIGN.md §3.
//!
//! The `gltf` crate parses and validates the JSON (references between objects are checked there);
//! everything that touches binary data is done here with checked arithmetic, so a hostile file
//! (accessors past the end of their buffer, absurd counts, strides smaller than an element) is a
//! clear error rather than a panic. Buffers and images are read only from beside the file, from
//! the GLB binary chunk, or from base64 `data:` URIs.
//!
//! Mapping: nodes are flattened with their world transforms (a negative determinant flips the
//! winding later, in `World::build`); each mesh primitive becomes one [`Mesh`], shared by every
//! node that instantiates it; perspective cameras keep their order (the first is the default);
//! `KHR_lights_punctual` intensities are divided by 683 lm/W (docs/DESIGN.md §4) to give W/sr (point, spot)
//! and W/m² (directional). Every feature the file uses that Trayecto ignores is named in a warning.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use base64::Engine;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::conventions::{ambient_light, apply_material_conventions, is_ambient_light_name};
use super::image_io::{
    RefusedPath, decode_texture, is_missing_texture, load_texture_checked, missing_texture,
    resolve_in_dir,
};
use super::{CameraDesc, LightDesc, MaterialId, Mesh, MeshId, Scene, SceneError, Shape};
use crate::material::texture::{FilterMode, UvTransform};
use crate::material::{AlphaMode, Material, MaterialModel, TextureRef, WrapMode};
use crate::math::{Mat4, Vec2, Vec3, Vec4};

/// Luminous efficacy used to turn photometric glTF light units into radiometric ones (docs/DESIGN.md §4,
/// Blender's convention).
pub const LUMENS_PER_WATT: f32 = 683.0;

/// Largest element count accepted for one accessor: far above any real model, low enough that a
/// forged count cannot exhaust memory.
const MAX_ACCESSOR_COUNT: usize = 1 << 27;

/// Extensions whose data Trayecto reads.
const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_materials_specular",
    "KHR_materials_clearcoat",
    "KHR_texture_transform",
];

/// Loads a glTF document from memory; external files are looked up in `dir`. `label` names the
/// file in messages. (Also the fuzzing entry point.)
pub fn load_from_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    // The `gltf` crate (1.4) can index out of bounds on malformed documents that pass its own
    // validation (found by tests/import_mutation.rs, both while validating meshes and in
    // `Image::source`). Contain any such panic as an error naming the file.
    super::contain_panics(
        label,
        "not a valid glTF 2.0 file: its structure is inconsistent",
        || load_from_bytes_unguarded(bytes, dir, label),
    )
}

fn load_from_bytes_unguarded(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let err = |m: String| SceneError::invalid(label, m);
    let gltf = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| err(format!("not a valid glTF 2.0 file: {e}")))?;
    validate(&gltf.document).map_err(err)?;
    let mut ld = Loader {
        doc: &gltf.document,
        dir,
        label,
        buffers: Vec::new(),
        scene: Scene {
            name: label.to_string(),
            source: Some(label.into()),
            ..Default::default()
        },
        textures: HashMap::new(),
        missing: HashSet::new(),
        meshes: HashMap::new(),
        default_material: None,
        warned: HashSet::new(),
    };
    ld.read_buffers(gltf.blob.as_deref())?;
    ld.report_extensions();
    for m in gltf.document.materials() {
        let mat = ld.material(&m)?;
        ld.scene.add_material(mat);
    }
    ld.nodes()?;
    let doc = ld.doc;
    if doc.animations().next().is_some() {
        let n = doc.animations().count();
        ld.warn_once(
            "animations",
            format!("{n} animation(s) are not supported: the static pose is rendered"),
        );
    }
    if doc.skins().next().is_some() {
        ld.warn_once(
            "skins",
            "skins are not supported: meshes are rendered in their bind pose".into(),
        );
    }
    let mut scene = ld.scene;
    apply_material_conventions(&mut scene);
    scene.validate()?;
    Ok(scene)
}

/// The `gltf` crate's validation, except that a required extension is judged by what Trayecto
/// reads (the crate refuses every `extensionsRequired` entry it does not parse itself, such as
/// KHR_materials_clearcoat, which is read here from the raw JSON). A required extension that
/// neither reads is an error naming it: the file cannot be rendered as its author meant.
fn validate(doc: &gltf::Document) -> Result<(), String> {
    use gltf::json::validation::{Error, Validate};
    let root = doc.as_json();
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        if !(matches!(error, Error::Unsupported) && path.0.starts_with("extensionsRequired")) {
            errors.push((path, error));
        }
    });
    if !errors.is_empty() {
        return Err(format!(
            "not a valid glTF 2.0 file: {}",
            gltf::Error::Validation(errors)
        ));
    }
    let blocking: Vec<&str> = root
        .extensions_required
        .iter()
        .map(String::as_str)
        .filter(|e| {
            !SUPPORTED_EXTENSIONS.contains(e)
                && !gltf::json::extensions::ENABLED_EXTENSIONS.contains(e)
        })
        .collect();
    if !blocking.is_empty() {
        return Err(format!(
            "the file requires glTF extension{} {} (extensionsRequired), which Trayecto does not support",
            if blocking.len() > 1 { "s" } else { "" },
            blocking
                .iter()
                .map(|e| format!("'{e}'"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(())
}

struct Loader<'a> {
    doc: &'a gltf::Document,
    dir: &'a Path,
    label: &'a str,
    buffers: Vec<Vec<u8>>,
    scene: Scene,
    /// (glTF texture index, sRGB) → scene texture.
    textures: HashMap<(usize, bool), usize>,
    /// Scene textures that are magenta fallbacks.
    missing: HashSet<usize>,
    /// (mesh, primitive) → scene mesh and material, or None if the primitive was skipped.
    meshes: HashMap<(usize, usize), Option<(MeshId, MaterialId)>>,
    default_material: Option<MaterialId>,
    warned: HashSet<String>,
}

impl<'a> Loader<'a> {
    fn err(&self, m: impl Into<String>) -> SceneError {
        SceneError::invalid(self.label, m)
    }

    fn warn_once(&mut self, key: &str, message: String) {
        if self.warned.insert(key.to_string()) {
            self.scene.warnings.push(message);
        }
    }

    fn read_buffers(&mut self, blob: Option<&[u8]>) -> Result<(), SceneError> {
        for b in self.doc.buffers() {
            let data = match b.source() {
                gltf::buffer::Source::Bin => blob
                    .ok_or_else(|| {
                        self.err(format!(
                            "buffer {} refers to the binary chunk, but the file has none",
                            b.index()
                        ))
                    })?
                    .to_vec(),
                gltf::buffer::Source::Uri(uri) => self.read_uri(uri, "buffer", b.index())?,
            };
            if data.len() < b.length() {
                return Err(self.err(format!(
                    "buffer {} has {} bytes but declares {} (truncated file?)",
                    b.index(),
                    data.len(),
                    b.length()
                )));
            }
            self.buffers.push(data);
        }
        Ok(())
    }

    /// Bytes of a buffer or image URI: base64 data URI, or a file beside the scene.
    fn read_uri(&self, uri: &str, what: &str, index: usize) -> Result<Vec<u8>, SceneError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((header, data)) = rest.split_once(',') else {
                return Err(self.err(format!("{what} {index}: malformed data URI")));
            };
            if !header.ends_with(";base64") {
                return Err(self.err(format!("{what} {index}: data URIs must be base64-encoded")));
            }
            return base64::engine::general_purpose::STANDARD
                .decode(data.trim())
                .map_err(|e| self.err(format!("{what} {index}: bad base64 data URI ({e})")));
        }
        let rel = super::image_io::percent_decode(uri);
        let path = resolve_in_dir(self.dir, &rel)
            .map_err(|why| self.err(format!("{what} {index}: {why}")))?;
        std::fs::read(&path).map_err(|e| {
            self.err(format!(
                "{what} {index}: cannot read '{}' ({e})",
                path.display()
            ))
        })
    }

    fn report_extensions(&mut self) {
        let required: HashSet<&str> = self.doc.extensions_required().collect();
        let used: Vec<&str> = self.doc.extensions_used().collect();
        for ext in used {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                let req = if required.contains(ext) {
                    " (the file marks it required; the render may be wrong)"
                } else {
                    ""
                };
                self.scene.warnings.push(format!(
                    "glTF extension '{ext}' is not supported and is ignored{req}"
                ));
            }
        }
    }

    // ---------------------------------------------------------------- textures and materials

    /// The scene texture for glTF texture `t` decoded as sRGB or linear.
    fn texture(&mut self, t: &gltf::Texture, srgb: bool) -> Result<usize, SceneError> {
        if let Some(&i) = self.textures.get(&(t.index(), srgb)) {
            return Ok(i);
        }
        let img = t.source();
        let name = img
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("image {}", img.index()));
        let mut tex = match img.source() {
            gltf::image::Source::View { view, .. } => {
                let bytes = self.view_bytes(&view)?;
                match decode_texture(&name, bytes, srgb) {
                    Ok(t) => t,
                    Err(e) => {
                        self.scene.warnings.push(format!(
                            "embedded image {} ('{name}') could not be decoded ({e}): using a magenta fallback",
                            img.index()
                        ));
                        missing_texture(&name)
                    }
                }
            }
            gltf::image::Source::Uri { uri, .. } => {
                if uri.starts_with("data:") {
                    let bytes = self.read_uri(uri, "image", img.index())?;
                    match decode_texture(&name, &bytes, srgb) {
                        Ok(t) => t,
                        Err(e) => {
                            self.scene.warnings.push(format!(
                                "image {} could not be decoded ({e}): using a magenta fallback",
                                img.index()
                            ));
                            missing_texture(&name)
                        }
                    }
                } else {
                    let rel = super::image_io::percent_decode(uri);
                    load_texture_checked(self.dir, &rel, srgb, &mut self.scene.warnings).map_err(
                        |RefusedPath(why)| self.err(format!("image {}: {why}", img.index())),
                    )?
                }
            }
        };
        let s = t.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => WrapMode::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => WrapMode::MirroredRepeat,
            gltf::texture::WrappingMode::Repeat => WrapMode::Repeat,
        };
        tex.wrap_s = wrap(s.wrap_s());
        tex.wrap_t = wrap(s.wrap_t());
        tex.filter = match s.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => FilterMode::Nearest,
            _ => FilterMode::Bilinear,
        };
        let missing = is_missing_texture(&tex);
        self.scene.textures.push(tex);
        let i = self.scene.textures.len() - 1;
        if missing {
            self.missing.insert(i);
        }
        self.textures.insert((t.index(), srgb), i);
        Ok(i)
    }

    fn texcoord_set(&mut self, set: u32, what: &str) -> u32 {
        if set > 1 {
            self.warn_once(
                &format!("texcoord{set}"),
                format!(
                    "texture-coordinate set {set} ({what}) is not supported (only 0 and 1): set 0 is used"
                ),
            );
            0
        } else {
            set
        }
    }

    /// A texture reference from a `textureInfo`; `colour` textures are decoded as sRGB. Missing
    /// data textures are dropped (the factor alone applies); missing colour textures stay magenta.
    fn tex_ref(
        &mut self,
        info: Option<gltf::texture::Info>,
        srgb: bool,
        keep_missing: bool,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        let texture = self.texture(&info.texture(), srgb)?;
        if self.missing.contains(&texture) && !keep_missing {
            return Ok(None);
        }
        let mut texcoord = info.tex_coord();
        let transform = info.texture_transform().map(|t| {
            if let Some(tc) = t.tex_coord() {
                texcoord = tc;
            }
            UvTransform {
                offset: Vec2::from(t.offset()),
                rotation: t.rotation(),
                scale: Vec2::from(t.scale()),
            }
        });
        let texcoord = self.texcoord_set(texcoord, what);
        Ok(Some(TextureRef {
            texture,
            texcoord,
            transform,
        }))
    }

    /// Normal and occlusion textures are not `textureInfo`s in the crate, so their
    /// KHR_texture_transform is read from the raw extension JSON.
    fn special_tex_ref(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        ext: Option<&gltf::json::Value>,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        let index = self.texture(&texture, false)?;
        if self.missing.contains(&index) {
            return Ok(None);
        }
        let mut texcoord = tex_coord;
        let transform = ext.map(|v| {
            let pair = |key: &str, default: f32| -> Vec2 {
                v.get(key)
                    .and_then(|a| a.as_array())
                    .map(|a| {
                        Vec2::new(
                            a.first().and_then(|x| x.as_f64()).unwrap_or(default as f64) as f32,
                            a.get(1).and_then(|x| x.as_f64()).unwrap_or(default as f64) as f32,
                        )
                    })
                    .unwrap_or(Vec2::splat(default))
            };
            if let Some(tc) = v.get("texCoord").and_then(|x| x.as_u64()) {
                texcoord = tc.min(u32::MAX as u64) as u32;
            }
            UvTransform {
                offset: pair("offset", 0.0),
                rotation: v.get("rotation").and_then(|x| x.as_f64()).unwrap_or(0.0) as f32,
                scale: pair("scale", 1.0),
            }
        });
        let texcoord = self.texcoord_set(texcoord, what);
        Ok(Some(TextureRef {
            texture: index,
            texcoord,
            transform,
        }))
    }

    fn material(&mut self, m: &gltf::Material) -> Result<Material, SceneError> {
        let name = m
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("material {}", m.index().unwrap_or(0)));
        let pbr = m.pbr_metallic_roughness();
        let bc = pbr.base_color_factor();
        let mut mat = Material {
            name: name.clone(),
            model: MaterialModel::MetallicRoughness,
            base_color: Vec3::new(bc[0], bc[1], bc[2]),
            alpha: bc[3],
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            double_sided: m.double_sided(),
            alpha_cutoff: m.alpha_cutoff().unwrap_or(0.5),
            alpha_mode: match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask,
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            },
            ..Default::default()
        };
        mat.base_color_texture = self.tex_ref(pbr.base_color_texture(), true, true, "baseColor")?;
        mat.metallic_roughness_texture = self.tex_ref(
            pbr.metallic_roughness_texture(),
            false,
            false,
            "metallicRoughness",
        )?;
        if let Some(n) = m.normal_texture() {
            mat.normal_scale = n.scale();
            mat.normal_texture = self.special_tex_ref(
                n.texture(),
                n.tex_coord(),
                n.extension_value("KHR_texture_transform"),
                "normal",
            )?;
        }
        if let Some(o) = m.occlusion_texture() {
            mat.occlusion_strength = o.strength();
            mat.occlusion_texture = self.special_tex_ref(
                o.texture(),
                o.tex_coord(),
                o.extension_value("KHR_texture_transform"),
                "occlusion",
            )?;
        }
        // Emission is radiance: factor × KHR_materials_emissive_strength (docs/DESIGN.md §4).
        let strength = m.emissive_strength().unwrap_or(1.0);
        mat.emissive = Vec3::from(m.emissive_factor()) * strength;
        // The emissive texture only matters when the factor is non-zero (glTF multiplies them).
        if mat.emissive.max_element() > 0.0 {
            mat.emissive_texture = self.tex_ref(m.emissive_texture(), true, false, "emissive")?;
        } else if m.emissive_texture().is_some() {
            self.scene.warnings.push(format!(
                "material '{name}': emissive texture with a zero emissive factor emits nothing"
            ));
        }
        if let Some(t) = m.transmission() {
            mat.transmission = t.transmission_factor();
            mat.transmission_texture =
                self.tex_ref(t.transmission_texture(), false, false, "transmission")?;
        }
        if let Some(ior) = m.ior() {
            mat.ior = ior;
        }
        match m.volume() {
            Some(v) => {
                mat.thin_walled = false;
                mat.thickness = v.thickness_factor();
                mat.attenuation_color = Vec3::from(v.attenuation_color());
                mat.attenuation_distance = v.attenuation_distance();
                if v.thickness_texture().is_some() {
                    self.warn_once(
                        "thickness_texture",
                        "KHR_materials_volume thickness textures are not supported (the factor is used)"
                            .into(),
                    );
                }
            }
            None => mat.thin_walled = mat.transmission > 0.0,
        }
        if let Some(s) = m.specular() {
            mat.specular = s.specular_factor();
            mat.specular_color = Vec3::from(s.specular_color_factor());
            mat.specular_texture = self.tex_ref(s.specular_texture(), false, false, "specular")?;
            mat.specular_color_texture =
                self.tex_ref(s.specular_color_texture(), true, false, "specularColor")?;
        }
        if let Some(cc) = m.extension_value("KHR_materials_clearcoat") {
            self.clearcoat(&mut mat, cc)?;
        }
        if m.unlit() {
            self.scene.warnings.push(format!(
                "material '{name}': KHR_materials_unlit is not supported; it is shaded as a lit material"
            ));
        }
        if m.pbr_specular_glossiness().is_some() {
            self.scene.warnings.push(format!(
                "material '{name}': KHR_materials_pbrSpecularGlossiness is not supported; the metallic-roughness fallback is used"
            ));
        }
        Ok(mat)
    }

    /// KHR_materials_clearcoat, read from the raw extension JSON (the `gltf` crate does not parse
    /// it): factors (default 0), the weight (R), roughness (G) and normal textures (all linear).
    fn clearcoat(&mut self, mat: &mut Material, v: &gltf::json::Value) -> Result<(), SceneError> {
        let num = |key: &str, default: f32| -> Result<f32, SceneError> {
            match v.get(key) {
                None => Ok(default),
                Some(x) => x
                    .as_f64()
                    .map(|x| x as f32)
                    .filter(|x| x.is_finite() && (0.0..=1.0).contains(x))
                    .ok_or_else(|| {
                        SceneError::invalid(
                            self.label,
                            format!(
                                "material '{}': KHR_materials_clearcoat {key} must be a number in [0, 1]",
                                mat.name
                            ),
                        )
                    }),
            }
        };
        mat.clearcoat = num("clearcoatFactor", 0.0)?;
        mat.clearcoat_roughness = num("clearcoatRoughnessFactor", 0.0)?;
        mat.clearcoat_texture = self.raw_tex_ref(v.get("clearcoatTexture"), "clearcoat")?;
        mat.clearcoat_roughness_texture =
            self.raw_tex_ref(v.get("clearcoatRoughnessTexture"), "clearcoatRoughness")?;
        if let Some(n) = v.get("clearcoatNormalTexture") {
            mat.clearcoat_normal_scale = n
                .get("scale")
                .and_then(|x| x.as_f64())
                .map(|x| x as f32)
                .filter(|x| x.is_finite())
                .unwrap_or(1.0);
            mat.clearcoat_normal_texture = self.raw_tex_ref(Some(n), "clearcoatNormal")?;
        }
        Ok(())
    }

    /// A `textureInfo` given as raw extension JSON (`index`, `texCoord`, KHR_texture_transform),
    /// decoded linearly. A missing or out-of-range index is an error naming the file.
    fn raw_tex_ref(
        &mut self,
        info: Option<&gltf::json::Value>,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        let texture = info
            .get("index")
            .and_then(|i| i.as_u64())
            .and_then(|i| self.doc.textures().nth(i.min(usize::MAX as u64) as usize))
            .ok_or_else(|| {
                SceneError::invalid(
                    self.label,
                    format!("{what} texture: 'index' is missing or names no texture"),
                )
            })?;
        let tex_coord = info
            .get("texCoord")
            .and_then(|t| t.as_u64())
            .unwrap_or(0)
            .min(u32::MAX as u64) as u32;
        let transform = info
            .get("extensions")
            .and_then(|e| e.get("KHR_texture_transform"));
        self.special_tex_ref(texture, tex_coord, transform, what)
    }

    fn default_material(&mut self) -> MaterialId {
        if let Some(m) = self.default_material {
            return m;
        }
        // The glTF default material: white, metallic 1, roughness 1.
        let m = Material {
            name: "glTF default".into(),
            model: MaterialModel::MetallicRoughness,
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            ..Default::default()
        };
        let id = self.scene.add_material(m);
        self.default_material = Some(id);
        id
    }

    // ---------------------------------------------------------------- binary data

    fn view_bytes(&self, view: &gltf::buffer::View) -> Result<&[u8], SceneError> {
        let buf = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| self.err(format!("buffer view {} has no buffer", view.index())))?;
        let start = view.offset();
        let end = start.checked_add(view.length());
        end.and_then(|end| buf.get(start..end)).ok_or_else(|| {
            self.err(format!(
                "buffer view {} (bytes {}..+{}) lies outside its buffer of {} bytes",
                view.index(),
                start,
                view.length(),
                buf.len()
            ))
        })
    }

    /// Reads `count` elements of `ncomp` components each from a view at `offset`, as f32
    /// (normalised integers per glTF §3.11) or raw integer values.
    #[allow(clippy::too_many_arguments)]
    fn read_elements(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        ty: DataType,
        ncomp: usize,
        normalized: bool,
        out: &mut Vec<[f64; 4]>,
        what: &str,
    ) -> Result<(), SceneError> {
        let data = self.view_bytes(view)?;
        let csize = ty.size();
        let esize = csize * ncomp;
        let stride = view.stride().unwrap_or(esize);
        if stride < esize {
            return Err(self.err(format!(
                "{what}: byte stride {stride} is smaller than an element ({esize} bytes)"
            )));
        }
        if count == 0 {
            return Ok(());
        }
        let needed = (count - 1)
            .checked_mul(stride)
            .and_then(|n| n.checked_add(esize))
            .and_then(|n| n.checked_add(offset));
        if needed.is_none_or(|n| n > data.len()) {
            return Err(self.err(format!(
                "{what}: {count} elements at offset {offset} with stride {stride} do not fit in buffer view {} ({} bytes)",
                view.index(),
                data.len()
            )));
        }
        out.reserve(count);
        for i in 0..count {
            let base = offset + i * stride;
            let mut e = [0.0f64; 4];
            for (c, v) in e.iter_mut().enumerate().take(ncomp) {
                let p = base + c * csize;
                *v = component(&data[p..p + csize], ty, normalized);
            }
            out.push(e);
        }
        Ok(())
    }

    /// Reads an accessor (with sparse substitution) as up to four f32 per element.
    fn read_accessor(
        &self,
        acc: &gltf::Accessor,
        what: &str,
    ) -> Result<(Vec<[f64; 4]>, usize), SceneError> {
        let ncomp = match acc.dimensions() {
            Dimensions::Scalar => 1,
            Dimensions::Vec2 => 2,
            Dimensions::Vec3 => 3,
            Dimensions::Vec4 => 4,
            other => {
                return Err(self.err(format!(
                    "{what}: accessor {} has type {other:?}, expected a scalar or vector",
                    acc.index()
                )));
            }
        };
        let count = acc.count();
        if count > MAX_ACCESSOR_COUNT {
            return Err(self.err(format!(
                "{what}: accessor {} has an absurd element count ({count})",
                acc.index()
            )));
        }
        let ty = acc.data_type();
        let mut out = Vec::new();
        match acc.view() {
            Some(view) => self.read_elements(
                &view,
                acc.offset(),
                count,
                ty,
                ncomp,
                acc.normalized(),
                &mut out,
                what,
            )?,
            None => out.resize(count, [0.0; 4]),
        }
        if let Some(sparse) = acc.sparse() {
            let n = sparse.count();
            if n > count {
                return Err(self.err(format!(
                    "{what}: accessor {} has more sparse entries ({n}) than elements ({count})",
                    acc.index()
                )));
            }
            let idx = sparse.indices();
            let ity = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let mut indices = Vec::new();
            self.read_elements(
                &idx.view(),
                idx.offset(),
                n,
                ity,
                1,
                false,
                &mut indices,
                what,
            )?;
            let vals = sparse.values();
            let mut values = Vec::new();
            self.read_elements(
                &vals.view(),
                vals.offset(),
                n,
                ty,
                ncomp,
                acc.normalized(),
                &mut values,
                what,
            )?;
            for (i, v) in indices.iter().zip(values) {
                let target = i[0] as usize;
                let slot = out.get_mut(target).ok_or_else(|| {
                    self.err(format!(
                        "{what}: sparse index {target} is out of range (count {count})"
                    ))
                })?;
                *slot = v;
            }
        }
        Ok((out, ncomp))
    }

    fn read_vec3(&self, acc: &gltf::Accessor, what: &str) -> Result<Vec<Vec3>, SceneError> {
        let (v, _) = self.read_accessor(acc, what)?;
        Ok(v.iter()
            .map(|e| Vec3::new(e[0] as f32, e[1] as f32, e[2] as f32))
            .collect())
    }

    fn read_vec2(&self, acc: &gltf::Accessor, what: &str) -> Result<Vec<Vec2>, SceneError> {
        let (v, _) = self.read_accessor(acc, what)?;
        Ok(v.iter()
            .map(|e| Vec2::new(e[0] as f32, e[1] as f32))
            .collect())
    }

    fn read_indices(&self, acc: &gltf::Accessor) -> Result<Vec<u32>, SceneError> {
        if !matches!(
            acc.data_type(),
            DataType::U8 | DataType::U16 | DataType::U32
        ) || acc.dimensions() != Dimensions::Scalar
        {
            return Err(self.err(format!(
                "index accessor {} must hold unsigned integer scalars",
                acc.index()
            )));
        }
        let (v, _) = self.read_accessor(acc, "indices")?;
        Ok(v.iter().map(|e| e[0] as u32).collect())
    }

    // ---------------------------------------------------------------- meshes

    fn primitive(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
    ) -> Result<Option<(MeshId, MaterialId)>, SceneError> {
        let key = (mesh.index(), prim.index());
        if let Some(r) = self.meshes.get(&key) {
            return Ok(*r);
        }
        let mesh_name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("mesh {}", mesh.index()));
        let r = self.build_primitive(&mesh_name, prim)?;
        self.meshes.insert(key, r);
        Ok(r)
    }

    fn build_primitive(
        &mut self,
        mesh_name: &str,
        prim: &gltf::Primitive,
    ) -> Result<Option<(MeshId, MaterialId)>, SceneError> {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warn_once(
                &format!("mode {mode:?}"),
                format!("primitives of mode {mode:?} are not supported and are skipped"),
            );
            return Ok(None);
        }
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            self.scene.warnings.push(format!(
                "mesh '{mesh_name}': a primitive without POSITION is skipped"
            ));
            return Ok(None);
        };
        let what = format!("mesh '{mesh_name}' POSITION");
        let positions = self.read_vec3(&pos_acc, &what)?;
        let n = positions.len();
        let mut m = Mesh {
            name: mesh_name.to_string(),
            positions,
            ..Default::default()
        };
        for (sem, acc) in prim.attributes() {
            use gltf::Semantic as S;
            match sem {
                S::Positions => {}
                S::Normals => m.normals = Some(self.read_vec3(&acc, "NORMAL")?),
                S::Tangents => {
                    let (v, _) = self.read_accessor(&acc, "TANGENT")?;
                    m.tangents = Some(
                        v.iter()
                            .map(|e| Vec4::new(e[0] as f32, e[1] as f32, e[2] as f32, e[3] as f32))
                            .collect(),
                    );
                }
                S::TexCoords(0) => m.uv0 = Some(self.read_vec2(&acc, "TEXCOORD_0")?),
                S::TexCoords(1) => m.uv1 = Some(self.read_vec2(&acc, "TEXCOORD_1")?),
                S::Colors(0) => {
                    let (v, nc) = self.read_accessor(&acc, "COLOR_0")?;
                    m.colors = Some(
                        v.iter()
                            .map(|e| {
                                let a = if nc == 4 { e[3] as f32 } else { 1.0 };
                                Vec4::new(e[0] as f32, e[1] as f32, e[2] as f32, a)
                            })
                            .collect(),
                    );
                }
                S::Joints(_) | S::Weights(_) => {}
                other => {
                    self.warn_once(
                        &format!("attr {other:?}"),
                        format!("vertex attribute {other:?} is not supported and is ignored"),
                    );
                }
            }
        }
        if prim.morph_targets().next().is_some() {
            self.warn_once(
                "morph",
                "morph targets are not supported: the base shape is rendered".into(),
            );
        }
        let idx: Vec<u32> = match prim.indices() {
            Some(acc) => self.read_indices(&acc)?,
            None => (0..n as u32).collect(),
        };
        let tri = |a: u32, b: u32, c: u32| [a, b, c];
        m.indices = match mode {
            Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
                .map(|i| {
                    // glTF §3.7.2.1: p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}} keeps the winding.
                    tri(idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2])
                })
                .collect(),
            Mode::TriangleFan => (0..idx.len().saturating_sub(2))
                .map(|i| tri(idx[i + 1], idx[i + 2], idx[0]))
                .collect(),
            _ => {
                if !idx.len().is_multiple_of(3) {
                    self.scene.warnings.push(format!(
                        "mesh '{mesh_name}': {} indices is not a multiple of 3; the extra ones are ignored",
                        idx.len()
                    ));
                }
                idx.chunks_exact(3).map(|c| tri(c[0], c[1], c[2])).collect()
            }
        };
        let material = match prim.material().index() {
            Some(i) if i < self.scene.materials.len() => i,
            Some(i) => {
                return Err(self.err(format!(
                    "mesh '{mesh_name}' references material {i}, which does not exist"
                )));
            }
            None => self.default_material(),
        };
        let id = self.scene.add_mesh(m);
        Ok(Some((id, material)))
    }

    // ---------------------------------------------------------------- node hierarchy

    fn nodes(&mut self) -> Result<(), SceneError> {
        let doc = self.doc;
        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                // No scene: render every node that is nobody's child.
                let children: HashSet<usize> = doc
                    .nodes()
                    .flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>())
                    .collect();
                doc.nodes()
                    .filter(|n| !children.contains(&n.index()))
                    .collect()
            }
        };
        if doc.scenes().count() > 1 {
            self.scene.warnings.push(format!(
                "the file has {} scenes; only the default one is rendered",
                doc.scenes().count()
            ));
        }
        let mut visited = HashSet::new();
        let mut stack: Vec<(gltf::Node, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = stack.pop() {
            if !visited.insert(node.index()) {
                // A node reached twice is a cycle or a shared child, both invalid glTF.
                self.warn_once(
                    "revisit",
                    format!(
                        "node {} is reached more than once (invalid hierarchy); later visits are ignored",
                        node.index()
                    ),
                );
                continue;
            }
            let local = Mat4::from_cols_array_2d(&node.transform().matrix());
            let world = parent * local;
            let node_name = node
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("node {}", node.index()));
            if let Some(mesh) = node.mesh() {
                for prim in mesh.primitives() {
                    if let Some((mesh_id, material)) = self.primitive(&mesh, &prim)? {
                        self.scene
                            .add_object(&node_name, Shape::Mesh(mesh_id), world, material);
                    }
                }
            }
            if let Some(cam) = node.camera() {
                self.camera(&cam, &node_name, world);
            }
            if let Some(light) = node.light() {
                self.light(&light, &node_name, world);
            }
            for c in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((c, world));
            }
        }
        Ok(())
    }

    fn camera(&mut self, cam: &gltf::Camera, node_name: &str, world: Mat4) {
        let name = cam.name().unwrap_or(node_name).to_string();
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                // Cameras ignore scale: keep the rotation and the position only.
                let rigid = Mat4::from_cols(
                    world.x_axis.truncate().normalize_or_zero().extend(0.0),
                    world.y_axis.truncate().normalize_or_zero().extend(0.0),
                    world.z_axis.truncate().normalize_or_zero().extend(0.0),
                    world.w_axis,
                );
                self.scene.cameras.push(CameraDesc {
                    name,
                    camera_to_world: rigid,
                    vfov_deg: p.yfov().to_degrees(),
                    aspect: p.aspect_ratio(),
                    aperture_radius: 0.0,
                    focus_distance: 1.0,
                });
            }
            gltf::camera::Projection::Orthographic(_) => {
                self.scene.warnings.push(format!(
                    "camera '{name}' is orthographic, which is not supported; it is skipped"
                ));
            }
        }
    }

    fn light(&mut self, light: &gltf::khr_lights_punctual::Light, node_name: &str, world: Mat4) {
        use gltf::khr_lights_punctual::Kind;
        let name = light.name().unwrap_or(node_name).to_string();
        let color = Vec3::from(light.color());
        if is_ambient_light_name(&name) || is_ambient_light_name(node_name) {
            // The thesis's convention (Annex B): an ambient light of that light's colour.
            self.scene.lights.push(ambient_light(&name, color));
            self.scene.warnings.push(format!(
                "convention: light '{name}' is an ambient light of its colour (name contains 'ambient')"
            ));
            return;
        }
        if light.range().is_some() {
            self.warn_once(
                "range",
                "KHR_lights_punctual 'range' is ignored: lights fall off with the inverse square of distance"
                    .into(),
            );
        }
        // docs/DESIGN.md §4: candela (lm/sr) and lux (lm/m²) / 683 lm/W → W/sr and W/m².
        let power = color * (light.intensity() / LUMENS_PER_WATT);
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let desc = match light.kind() {
            Kind::Point => LightDesc::Point {
                name,
                position,
                intensity: power,
            },
            Kind::Directional => LightDesc::Directional {
                name,
                direction,
                irradiance: power,
            },
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => LightDesc::Spot {
                name,
                position,
                direction,
                intensity: power,
                inner_angle: inner_cone_angle,
                outer_angle: outer_cone_angle,
            },
        };
        self.scene.lights.push(desc);
    }
}

/// One component, exactly (f64 holds every u32 index). Normalised integers follow glTF 2.0
/// §3.11 (signed: max(c / MAX, −1)).
fn component(b: &[u8], ty: DataType, normalized: bool) -> f64 {
    let at = |i: usize| b.get(i).copied().unwrap_or(0);
    let (v, max) = match ty {
        DataType::I8 => (at(0) as i8 as f64, 127.0),
        DataType::U8 => (at(0) as f64, 255.0),
        DataType::I16 => (i16::from_le_bytes([at(0), at(1)]) as f64, 32767.0),
        DataType::U16 => (u16::from_le_bytes([at(0), at(1)]) as f64, 65535.0),
        DataType::U32 => (
            u32::from_le_bytes([at(0), at(1), at(2), at(3)]) as f64,
            u32::MAX as f64,
        ),
        DataType::F32 => return f32::from_le_bytes([at(0), at(1), at(2), at(3)]) as f64,
    };
    if normalized { (v / max).max(-1.0) } else { v }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalised_components() {
        assert_eq!(component(&[255], DataType::U8, true), 1.0);
        assert_eq!(component(&[0x80], DataType::I8, true), -1.0);
        assert_eq!(component(&[0xff, 0xff], DataType::U16, true), 1.0);
        assert_eq!(component(&[7, 0, 0, 0], DataType::U32, false), 7.0);
    }
}
