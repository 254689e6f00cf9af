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
//! Animations, skins and morph targets become the scene's [`crate::scene::animation::Animation`]
//! (`animation.rs`): skinned and morphed primitives get a mesh per node, posed at load in the
//! rest pose and by `Scene::pose` at any time.
//!
//! The loader is one [`Loader`] whose methods are split by concern: this file reads the document,
//! its buffers and extensions; `accessor.rs` decodes binary data; `material.rs` materials and
//! textures; `mesh.rs` primitives into meshes; `nodes.rs` the node hierarchy, cameras and lights.

mod accessor;
mod animation;
mod draco;
mod images;
mod material;
mod mesh;
mod meshopt;
mod nodes;
mod variants;

use std::collections::{HashMap, HashSet};
use std::path::Path;

use base64::Engine;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::conventions::{ambient_light, apply_material_conventions, is_ambient_light_name};
use super::image_io::{is_missing_texture, missing_texture, resolve_in_dir};
use super::{
    CameraDesc, LightDesc, MaterialId, Mesh, MeshId, Scene, SceneError, Shape, SpotFalloff,
};
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
    "KHR_materials_sheen",
    "KHR_materials_anisotropy",
    "KHR_materials_iridescence",
    "KHR_materials_dispersion",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_unlit",
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
    "EXT_texture_webp",
    "KHR_texture_basisu",
    "KHR_materials_variants",
    "EXT_mesh_gpu_instancing",
];

/// Extensions that carry only metadata (authorship, licence): nothing in them changes the image,
/// so they are not "unsupported".
const METADATA_EXTENSIONS: &[&str] = &["KHR_xmp", "KHR_xmp_json_ld"];

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
        decoded_views: HashMap::new(),
        images: HashMap::new(),
        variants: Vec::new(),
        variant_sets: Vec::new(),
        rig: Default::default(),
    };
    ld.read_buffers(gltf.blob.as_deref())?;
    ld.decode_meshopt_views()?;
    ld.report_extensions();
    ld.read_variants()?;
    ld.decode_images()?;
    for m in gltf.document.materials() {
        let mat = ld.material(&m)?;
        ld.scene.add_material(mat);
    }
    ld.nodes()?;
    ld.finish_animation()?;
    ld.images.clear();
    let variant_sets = std::mem::take(&mut ld.variant_sets);
    let mut scene = ld.scene;
    apply_material_conventions(&mut scene);
    let medium_of = super::volume::apply_volume_absorption(&mut scene);
    variants::finish(&mut scene, variant_sets, &medium_of);
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
        let unsupported_required =
            matches!(error, Error::Unsupported) && path.0.starts_with("extensionsRequired");
        // An accessor without a bufferView is all zeros (glTF 2.0 §3.6.2.1), which the crate
        // refuses; KHR_draco_mesh_compression's accessors are such, and are checked where the
        // primitive is read.
        let accessor_without_view = matches!(error, Error::Missing)
            && path.0.starts_with("accessors[")
            && path.0.ends_with("].bufferView");
        if !unsupported_required && !accessor_without_view {
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
    /// Buffer views decoded from EXT/KHR_meshopt_compression, by view index.
    decoded_views: HashMap<usize, Vec<u8>>,
    /// Images decoded ahead of the materials (in parallel), by image index.
    images: HashMap<usize, images::Decoded>,
    /// KHR_materials_variants: the variant names, in file order.
    variants: Vec<String>,
    /// Per object with variant mappings: its default material and the material of each variant.
    variant_sets: Vec<variants::ObjectVariantsDraft>,
    /// The node hierarchy, skins and deformed meshes, for posing (gltf/animation.rs).
    rig: crate::scene::animation::Rig,
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
            if meshopt::is_fallback_buffer(&b) {
                // Only the compressed views inside it are used; its bytes are never read.
                self.buffers.push(Vec::new());
                continue;
            }
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
        crate::limits::read_file(&path).map_err(|e| {
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
            if !SUPPORTED_EXTENSIONS.contains(&ext) && !METADATA_EXTENSIONS.contains(&ext) {
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
}
