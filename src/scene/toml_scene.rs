//! Trayecto's native scene file (TOML), for writing scenes by hand (docs/DESIGN.md §3). The complete,
//! commented reference is `scenes/example.toml` in the repository.
//!
//! Top level: `name`, `[[camera]]`, `[background]` (a uniform colour or an environment map),
//! `[[material]]`, `[[object]]` (a mesh file — OBJ, PLY, glTF — or an analytic sphere, box or
//! quad, §5.1.4–5.1.6) and `[[light]]` (point, spot, directional, ambient, environment). Light
//! units are radiometric: W/sr for point and spot intensities, W/m² for directional irradiance,
//! W/(m²·sr) for ambient radiance. Files are read only from the scene's folder; unknown keys are
//! errors (so typos do not pass silently).

use std::collections::HashMap;
use std::path::Path;

use serde::Deserialize;

use super::conventions::{ambient_light, apply_material_conventions, is_ambient_light_name};
use super::image_io::{RefusedPath, is_missing_texture, load_texture_checked, resolve_in_dir};
use super::{CameraDesc, LightDesc, MaterialId, Scene, SceneError, Shape, SpotFalloff};
use crate::material::models::{
    Coat, CoatedConductor, CoatedDiffuse, Conductor, DiffuseTransmission, Slab,
};
use crate::material::texture::UvTransform;
use crate::material::{AlphaMode, Material, MaterialModel, TextureRef};
use crate::math::{Mat4, Vec2, Vec3};

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct File {
    name: Option<String>,
    /// "auto", "on" or "off" (see `light::default_light`); `--default-light` overrides it.
    default_light: Option<super::DefaultLight>,
    #[serde(default)]
    camera: Vec<Camera>,
    background: Option<Background>,
    #[serde(default)]
    material: Vec<MaterialSpec>,
    #[serde(default)]
    object: Vec<ObjectSpec>,
    #[serde(default)]
    light: Vec<LightSpec>,
    #[serde(default)]
    medium: Vec<MediumSpec>,
    /// Name of the medium the camera is in: a global fog filling everything no object bounds.
    fog: Option<String>,
    /// Render settings the scene asks for; the command line overrides each.
    render: Option<RenderSpec>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderSpec {
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    max_depth: Option<u32>,
    /// Path guiding (`--guiding`): the scenes it pays on (interiors lit through a door or a
    /// window) can turn it on for every render of the file.
    guiding: Option<bool>,
}

/// A participating medium. `sigma_a`, `sigma_s` per unit length, times `scale`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MediumSpec {
    name: String,
    /// homogeneous (default) or grid.
    #[serde(rename = "type")]
    kind: Option<String>,
    #[serde(default)]
    sigma_a: [f32; 3],
    #[serde(default)]
    sigma_s: [f32; 3],
    #[serde(default = "one")]
    scale: f32,
    /// Henyey–Greenstein asymmetry in (−1, 1).
    #[serde(default)]
    g: f32,
    /// grid: a Mitsuba `.vol` density file (single channel, float32), placed at the bounding box
    /// the file gives (world units).
    file: Option<String>,
    /// Emitted radiance Le (RGB): the medium emits σa·Le per unit length (pbrt-v4's `Le`).
    #[serde(default)]
    emission: [f32; 3],
    /// grid: a `.vol` grid over the same box scaling `emission` point by point (pbrt-v4's
    /// `Lescale` grid); with `temperature_file`, the scale of the blackbody emission.
    emission_file: Option<String>,
    /// grid: a `.vol` grid of temperatures (K): blackbody emission normalised to peak 1 at
    /// T = (t − temperature_offset)·temperature_scale, none at T ≤ 100 K (pbrt-v4 `temperature`).
    temperature_file: Option<String>,
    #[serde(default = "one")]
    temperature_scale: f32,
    #[serde(default)]
    temperature_offset: f32,
    /// grid: "hold" (default; Mitsuba's `clamp`) holds the edge voxels up to the box faces,
    /// "zero" fades them to zero there (pbrt-v4's `uniformgrid`).
    edge: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Camera {
    name: Option<String>,
    eye: [f32; 3],
    target: [f32; 3],
    #[serde(default = "up")]
    up: [f32; 3],
    /// Vertical field of view in degrees.
    #[serde(default = "fov")]
    fov: f32,
    #[serde(default)]
    aperture: f32,
    focus_distance: Option<f32>,
}

fn up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn fov() -> f32 {
    39.6
}
fn one() -> f32 {
    1.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Background {
    color: Option<[f32; 3]>,
    map: Option<String>,
    #[serde(default = "one")]
    strength: f32,
    /// Rotation of the environment about +y, in degrees.
    #[serde(default)]
    rotation: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialSpec {
    name: String,
    /// diffuse, metallic-roughness, dielectric or mirror.
    model: Option<String>,
    base_color: Option<[f32; 3]>,
    base_color_texture: Option<String>,
    metallic: Option<f32>,
    roughness: Option<f32>,
    metallic_roughness_texture: Option<String>,
    normal_texture: Option<String>,
    emissive: Option<[f32; 3]>,
    #[serde(default = "one")]
    emissive_strength: f32,
    emissive_texture: Option<String>,
    ior: Option<f32>,
    transmission: Option<f32>,
    alpha: Option<f32>,
    specular: Option<f32>,
    #[serde(default)]
    double_sided: bool,
    /// `KHR_texture_transform` of every texture of the material: uv' = T · R · S · uv, with the
    /// rotation in degrees (counter-clockwise in glTF's v-down UV space).
    uv_scale: Option<[f32; 2]>,
    uv_offset: Option<[f32; 2]>,
    uv_rotation: Option<f32>,
    /// pbrt-v4 models (conductor, coated-diffuse, coated-conductor, diffuse-transmission).
    /// Roughnesses are GGX α (pbrt's `remaproughness false`); `roughness_v` makes them
    /// anisotropic.
    /// Conductor: a named metal ("metal-Cu", …) or `eta` + `k`, or `reflectance` = base_color.
    metal: Option<String>,
    eta: Option<[f32; 3]>,
    k: Option<[f32; 3]>,
    #[serde(default)]
    reflectance: bool,
    conductor_alpha: Option<f32>,
    conductor_alpha_v: Option<f32>,
    /// The coat: IOR (`ior`), GGX α, layer thickness, medium albedo and g, walk depth/samples.
    coat_alpha: Option<f32>,
    coat_alpha_v: Option<f32>,
    thickness: Option<f32>,
    albedo: Option<[f32; 3]>,
    g: Option<f32>,
    max_depth: Option<u32>,
    n_samples: Option<u32>,
    /// diffuse-transmission: transmittance (reflectance is base_color).
    transmittance: Option<[f32; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectSpec {
    name: Option<String>,
    /// mesh, sphere, box or quad.
    #[serde(rename = "type")]
    kind: String,
    /// Mesh file (OBJ, PLY, glTF) relative to the scene.
    file: Option<String>,
    /// A mesh given inline instead of `file`: vertex positions, triangles as three vertex
    /// indices each (default: consecutive vertices), and optional per-vertex normals and uvs.
    /// (The Python package's `load_dict` writes numpy arrays here.)
    positions: Option<Vec<[f32; 3]>>,
    indices: Option<Vec<[u32; 3]>>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    /// Material name; for meshes it replaces the file's own materials.
    material: Option<String>,
    /// glTF material variant of the included file (`KHR_materials_variants`); default: the
    /// file's default materials.
    variant: Option<String>,
    center: Option<[f32; 3]>,
    radius: Option<f32>,
    min: Option<[f32; 3]>,
    max: Option<[f32; 3]>,
    corner: Option<[f32; 3]>,
    e1: Option<[f32; 3]>,
    e2: Option<[f32; 3]>,
    /// Applied as scale, then rotation (degrees about x, then y, then z), then translation.
    translate: Option<[f32; 3]>,
    rotate: Option<[f32; 3]>,
    scale: Option<ScaleSpec>,
    /// A row-major 4×4 matrix (16 numbers), instead of translate/rotate/scale.
    matrix: Option<Vec<f32>>,
    /// Media on the two sides of the surface (names, or "none" for vacuum): inside is behind the
    /// surface's normal (inside a closed mesh, sphere or box). Giving either makes the surface a
    /// medium boundary; the other side defaults to the global `fog` (or vacuum).
    medium_inside: Option<String>,
    medium_outside: Option<String>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum ScaleSpec {
    Uniform(f32),
    Axes([f32; 3]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightSpec {
    name: Option<String>,
    /// point, spot, directional, ambient or environment.
    #[serde(rename = "type")]
    kind: String,
    position: Option<[f32; 3]>,
    direction: Option<[f32; 3]>,
    #[serde(default = "white")]
    color: [f32; 3],
    /// W/sr (point, spot), W/m² (directional), W/(m²·sr) (ambient) per unit colour.
    #[serde(default = "one")]
    intensity: f32,
    /// Spot cone half-angles in degrees.
    inner_angle: Option<f32>,
    outer_angle: Option<f32>,
    file: Option<String>,
    #[serde(default)]
    rotation: f32,
}

fn white() -> [f32; 3] {
    [1.0, 1.0, 1.0]
}

/// Parses a TOML scene from memory; referenced files are read from `dir`. (Also the fuzzing
/// entry point.)
pub fn load_from_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let err = |m: String| SceneError::invalid(label, m);
    let text = std::str::from_utf8(bytes).map_err(|_| err("the file is not UTF-8 text".into()))?;
    let file: File = toml::from_str(text).map_err(|e| err(format!("{e}")))?;
    let mut scene = Scene {
        name: file.name.clone().unwrap_or_else(|| label.to_string()),
        source: Some(label.into()),
        default_light: file.default_light,
        ..Default::default()
    };

    if let Some(r) = &file.render {
        for (key, v) in [("width", r.width), ("height", r.height), ("spp", r.spp)] {
            if v == Some(0) {
                return Err(err(format!("[render] {key} must be at least 1")));
            }
        }
        scene.hints.width = r.width;
        scene.hints.height = r.height;
        scene.hints.spp = r.spp;
        scene.hints.max_depth = r.max_depth;
        scene.hints.guiding = r.guiding;
    }

    let mut by_name: HashMap<String, MaterialId> = HashMap::new();
    for m in &file.material {
        let mat = material(m, dir, &mut scene)
            .map_err(|RefusedPath(why)| err(format!("material '{}': {why}", m.name)))?
            .map_err(|e| err(format!("material '{}': {e}", m.name)))?;
        if by_name
            .insert(m.name.clone(), scene.materials.len())
            .is_some()
        {
            return Err(err(format!("material '{}' is defined twice", m.name)));
        }
        scene.add_material(mat);
    }
    let mut media_by_name: HashMap<String, super::MediumId> = HashMap::new();
    for m in &file.medium {
        let desc = medium(m, dir).map_err(|e| err(format!("medium '{}': {e}", m.name)))?;
        if m.name == "none" {
            return Err(err(
                "a medium cannot be called 'none' (it means vacuum)".into()
            ));
        }
        if media_by_name
            .insert(m.name.clone(), scene.add_medium(desc))
            .is_some()
        {
            return Err(err(format!("medium '{}' is defined twice", m.name)));
        }
    }
    let lookup_medium = |n: &str, what: &str| -> Result<Option<super::MediumId>, SceneError> {
        if n == "none" {
            return Ok(None);
        }
        media_by_name
            .get(n)
            .copied()
            .map(Some)
            .ok_or_else(|| err(format!("{what} uses medium '{n}', which is not defined")))
    };
    if let Some(f) = &file.fog {
        scene.camera_medium = lookup_medium(f, "fog")?;
    }
    let fog = scene.camera_medium;
    let mut default_material = None;
    // Cameras of included files come after the TOML's own.
    let mut included_cameras = Vec::new();

    for (i, o) in file.object.iter().enumerate() {
        let name = o.name.clone().unwrap_or_else(|| format!("object {i}"));
        let transform = transform(o).map_err(|e| err(format!("object '{name}': {e}")))?;
        let mat = match &o.material {
            Some(n) => Some(*by_name.get(n).ok_or_else(|| {
                err(format!(
                    "object '{name}' uses material '{n}', which is not defined"
                ))
            })?),
            None => None,
        };
        let need = |v: Option<[f32; 3]>, key: &str| {
            v.map(Vec3::from)
                .ok_or_else(|| err(format!("object '{name}' ({}) needs '{key}'", o.kind)))
        };
        let what = format!("object '{name}'");
        let interface = if o.medium_inside.is_some() || o.medium_outside.is_some() {
            let side = |v: &Option<String>| match v {
                Some(n) => lookup_medium(n, &what),
                None => Ok(fog),
            };
            Some(super::MediumInterface {
                inside: side(&o.medium_inside)?,
                outside: side(&o.medium_outside)?,
            })
        } else {
            None
        };
        let shape = match o.kind.as_str() {
            "mesh" if o.file.is_none() && o.positions.is_some() => {
                let mesh =
                    inline_mesh(o, &name).map_err(|e| err(format!("object '{name}': {e}")))?;
                Shape::Mesh(scene.add_mesh(mesh))
            }
            _ if o.file.is_some() && o.positions.is_some() => {
                return Err(err(format!(
                    "object '{name}': give the mesh as 'file' or as 'positions', not both"
                )));
            }
            _ if o.kind != "mesh"
                && (o.positions.is_some()
                    || o.indices.is_some()
                    || o.normals.is_some()
                    || o.uvs.is_some()) =>
            {
                return Err(err(format!(
                    "object '{name}': positions, indices, normals and uvs describe an inline mesh (type = \"mesh\")"
                )));
            }
            "mesh" => {
                let f = o.file.as_deref().ok_or_else(|| {
                    err(format!(
                        "object '{name}' (mesh) needs 'file' (or inline 'positions')"
                    ))
                })?;
                add_mesh_file(
                    &mut scene,
                    dir,
                    f,
                    transform,
                    (mat, o.variant.as_deref()),
                    interface,
                    &mut included_cameras,
                )
                .map_err(|e| err(format!("object '{name}': {e}")))?;
                continue;
            }
            _ if o.variant.is_some() => {
                return Err(err(format!(
                    "object '{name}': 'variant' selects a glTF material variant of an included file (type = \"mesh\")"
                )));
            }
            "sphere" => Shape::Sphere {
                center: need(o.center, "center")?,
                radius: o
                    .radius
                    .ok_or_else(|| err(format!("object '{name}' (sphere) needs 'radius'")))?,
            },
            "box" => Shape::Cuboid {
                min: need(o.min, "min")?,
                max: need(o.max, "max")?,
            },
            "quad" => Shape::Quad {
                corner: need(o.corner, "corner")?,
                e1: need(o.e1, "e1")?,
                e2: need(o.e2, "e2")?,
            },
            other => {
                return Err(err(format!(
                    "object '{name}': unknown type '{other}' (mesh, sphere, box or quad)"
                )));
            }
        };
        let material = match mat {
            Some(m) => m,
            None => *default_material.get_or_insert_with(|| {
                scene.add_material(Material::diffuse("default", Vec3::splat(0.8)))
            }),
        };
        scene.add_object(&name, shape, transform, material);
        scene.objects.last_mut().expect("just added").medium = interface;
    }

    for (i, c) in file.camera.iter().enumerate() {
        let name = c.name.clone().unwrap_or_else(|| format!("camera {i}"));
        let (eye, target) = (Vec3::from(c.eye), Vec3::from(c.target));
        if (eye - target).length_squared() == 0.0 || !eye.is_finite() || !target.is_finite() {
            return Err(err(format!("camera '{name}': eye and target must differ")));
        }
        let mut cam = CameraDesc::look_at(&name, eye, target, Vec3::from(c.up), c.fov);
        cam.aperture_radius = c.aperture;
        if let Some(f) = c.focus_distance {
            cam.focus_distance = f;
        }
        scene.cameras.push(cam);
    }
    scene.cameras.extend(included_cameras);

    for (i, l) in file.light.iter().enumerate() {
        let name = l
            .name
            .clone()
            .unwrap_or_else(|| format!("{} light {i}", l.kind));
        let power = Vec3::from(l.color) * l.intensity;
        let shown = name.clone();
        let need = |v: Option<[f32; 3]>, key: &str| {
            v.map(Vec3::from)
                .ok_or_else(|| err(format!("light '{shown}' ({}) needs '{key}'", l.kind)))
        };
        if is_ambient_light_name(&name) && l.kind != "ambient" {
            scene.warnings.push(format!(
                "convention: light '{name}' is an ambient light of its colour (name contains 'ambient')"
            ));
            scene.lights.push(ambient_light(&name, Vec3::from(l.color)));
            continue;
        }
        let desc = match l.kind.as_str() {
            "point" => LightDesc::Point {
                name,
                position: need(l.position, "position")?,
                intensity: power,
            },
            "spot" => {
                let outer = l.outer_angle.unwrap_or(45.0);
                LightDesc::Spot {
                    position: need(l.position, "position")?,
                    direction: need(l.direction, "direction")?,
                    intensity: power,
                    inner_angle: l.inner_angle.unwrap_or(0.0).to_radians(),
                    outer_angle: outer.to_radians(),
                    falloff: SpotFalloff::SquaredRamp,
                    name,
                }
            }
            "directional" => LightDesc::Directional {
                direction: need(l.direction, "direction")?,
                irradiance: power,
                name,
            },
            "ambient" => LightDesc::Ambient {
                name,
                radiance: power,
            },
            "environment" => {
                let f = l
                    .file
                    .as_deref()
                    .ok_or_else(|| err(format!("light '{name}' (environment) needs 'file'")))?;
                let path =
                    resolve_in_dir(dir, f).map_err(|e| err(format!("light '{name}': {e}")))?;
                LightDesc::Environment {
                    name,
                    path,
                    scale: power,
                    mapping: Default::default(),
                    transform: Mat4::from_rotation_y(l.rotation.to_radians()),
                }
            }
            other => {
                return Err(err(format!(
                    "light '{name}': unknown type '{other}' (point, spot, directional, ambient or environment)"
                )));
            }
        };
        scene.lights.push(desc);
    }

    if let Some(bg) = &file.background {
        match (&bg.color, &bg.map) {
            (Some(c), None) => scene.lights.push(LightDesc::Ambient {
                name: "background".into(),
                radiance: Vec3::from(*c) * bg.strength,
            }),
            (None, Some(f)) => {
                let path = resolve_in_dir(dir, f).map_err(|e| err(format!("background: {e}")))?;
                scene.lights.push(LightDesc::Environment {
                    name: "background".into(),
                    path,
                    scale: Vec3::splat(bg.strength),
                    mapping: Default::default(),
                    transform: Mat4::from_rotation_y(bg.rotation.to_radians()),
                });
            }
            _ => {
                return Err(err(
                    "background needs exactly one of 'color' and 'map'".into()
                ));
            }
        }
    }

    apply_material_conventions(&mut scene);
    Ok(scene)
}

/// An inline mesh (`positions`, `indices`, `normals`, `uvs`): every index must name a vertex
/// and the per-vertex arrays must have one entry per position.
fn inline_mesh(o: &ObjectSpec, name: &str) -> Result<super::Mesh, String> {
    let positions: Vec<Vec3> = o
        .positions
        .iter()
        .flatten()
        .map(|&p| Vec3::from(p))
        .collect();
    let n = positions.len();
    let indices = match &o.indices {
        Some(i) => i.clone(),
        None if n.is_multiple_of(3) => (0..n as u32 / 3)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
        None => {
            return Err(format!(
                "{n} positions without 'indices' are not whole triangles (three vertices each)"
            ));
        }
    };
    if let Some(bad) = indices.iter().flatten().find(|&&i| i as usize >= n) {
        return Err(format!(
            "index {bad} names no vertex (there are {n} positions)"
        ));
    }
    let per_vertex = |len: usize, key: &str| {
        if len == n {
            Ok(())
        } else {
            Err(format!("'{key}' has {len} entries for {n} positions"))
        }
    };
    if let Some(v) = &o.normals {
        per_vertex(v.len(), "normals")?;
    }
    if let Some(v) = &o.uvs {
        per_vertex(v.len(), "uvs")?;
    }
    Ok(super::Mesh {
        name: name.to_string(),
        positions,
        indices,
        normals: o
            .normals
            .as_ref()
            .map(|v| v.iter().map(|&p| Vec3::from(p)).collect()),
        tangents: None,
        uv0: o
            .uvs
            .as_ref()
            .map(|v| v.iter().map(|&p| Vec2::from(p)).collect()),
        uv1: None,
        colors: None,
    })
}

fn transform(o: &ObjectSpec) -> Result<Mat4, String> {
    if let Some(m) = &o.matrix {
        if o.translate.is_some() || o.rotate.is_some() || o.scale.is_some() {
            return Err("'matrix' cannot be combined with translate/rotate/scale".into());
        }
        let a: [f32; 16] = m
            .as_slice()
            .try_into()
            .map_err(|_| format!("'matrix' needs 16 numbers, got {}", m.len()))?;
        // Row-major in the file, column-major in glam.
        return Ok(Mat4::from_cols_array(&a).transpose());
    }
    let s = match o.scale {
        None => Vec3::ONE,
        Some(ScaleSpec::Uniform(s)) => Vec3::splat(s),
        Some(ScaleSpec::Axes(a)) => Vec3::from(a),
    };
    let r = o.rotate.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let rot = Mat4::from_rotation_z(r.z.to_radians())
        * Mat4::from_rotation_y(r.y.to_radians())
        * Mat4::from_rotation_x(r.x.to_radians());
    let t = o.translate.map(Vec3::from).unwrap_or(Vec3::ZERO);
    Ok(Mat4::from_translation(t) * rot * Mat4::from_scale(s))
}

fn medium(m: &MediumSpec, dir: &Path) -> Result<super::MediumDesc, String> {
    let mut desc = super::MediumDesc::homogeneous(
        &m.name,
        Vec3::from(m.sigma_a),
        Vec3::from(m.sigma_s),
        m.scale,
        m.g,
    );
    desc.le = Vec3::from(m.emission);
    let read = |f: &str| -> Result<super::vol::VolFile, String> {
        let path = resolve_in_dir(dir, f)?;
        let bytes =
            crate::limits::read_file(&path).map_err(|e| format!("'{}': {e}", path.display()))?;
        super::vol::read_vol(&bytes).map_err(|e| format!("'{}': {e}", path.display()))
    };
    let voxels = |v: super::vol::VolFile| super::VoxelGrid {
        nx: v.nx,
        ny: v.ny,
        nz: v.nz,
        data: v.data,
    };
    match m.kind.as_deref() {
        None | Some("homogeneous") => {
            if m.file.is_some()
                || m.emission_file.is_some()
                || m.temperature_file.is_some()
                || m.edge.is_some()
            {
                return Err(
                    "'file', 'emission_file', 'temperature_file' and 'edge' are for grid media (type = \"grid\")"
                        .into(),
                );
            }
        }
        Some("grid") => {
            let f = m
                .file
                .as_deref()
                .ok_or("a grid medium needs 'file' (a .vol grid)")?;
            let v = read(f)?;
            let edge = match m.edge.as_deref() {
                None | Some("hold") => super::GridEdge::Hold,
                Some("zero") => super::GridEdge::Zero,
                Some(o) => return Err(format!("unknown edge '{o}' (hold or zero)")),
            };
            let scale = m
                .emission_file
                .as_deref()
                .map(read)
                .transpose()?
                .map(voxels);
            let emission = match m.temperature_file.as_deref() {
                Some(t) => {
                    if desc.le != Vec3::ZERO {
                        return Err("'emission' and 'temperature_file' exclude each other".into());
                    }
                    Some(super::GridEmission::Blackbody {
                        temperature: voxels(read(t)?),
                        scale: scale.unwrap_or(super::VoxelGrid::single(1.0)),
                        temperature_scale: m.temperature_scale,
                        offset: m.temperature_offset,
                    })
                }
                // The constant `emission` becomes the grid's radiance, scaled per voxel.
                None => scale.map(|scale| super::GridEmission::Radiance {
                    le: std::mem::take(&mut desc.le),
                    scale,
                }),
            };
            desc.kind = super::MediumKind::Grid {
                nx: v.nx,
                ny: v.ny,
                nz: v.nz,
                density: v.data,
                min: v.bbox_min,
                max: v.bbox_max,
                transform: Mat4::IDENTITY,
                edge,
                emission,
            };
        }
        Some(other) => return Err(format!("unknown type '{other}' (homogeneous or grid)")),
    }
    desc.validate()?;
    Ok(desc)
}

type MatResult = Result<Result<Material, String>, RefusedPath>;

fn material(m: &MaterialSpec, dir: &Path, scene: &mut Scene) -> MatResult {
    let model = match m.model.as_deref() {
        None | Some("diffuse") => MaterialModel::Diffuse,
        Some("metallic-roughness") => MaterialModel::metallic_roughness(),
        Some("dielectric") => MaterialModel::dielectric(),
        Some("mirror") => MaterialModel::Mirror,
        Some("conductor") => MaterialModel::Conductor(Default::default()),
        Some("coated-diffuse") => MaterialModel::CoatedDiffuse(Default::default()),
        Some("coated-conductor") => MaterialModel::CoatedConductor(Default::default()),
        Some("diffuse-transmission") => MaterialModel::DiffuseTransmission(Default::default()),
        Some("interface") => MaterialModel::Interface,
        Some(other) => {
            return Ok(Err(format!(
                "unknown model '{other}' (diffuse, metallic-roughness, dielectric, mirror, \
                 conductor, coated-diffuse, coated-conductor, diffuse-transmission or interface)"
            )));
        }
    };
    // The parameters of the pbrt-v4 models, each given to the models that read it.
    let mut conductor = Conductor::default();
    if let Some(metal) = &m.metal {
        let Some((eta, k)) = crate::spectrum::named_conductor_rgb(metal) else {
            return Ok(Err(format!(
                "unknown metal '{metal}' ({})",
                crate::spectrum::METALS.join(", ")
            )));
        };
        (conductor.eta, conductor.k) = (eta, k);
        conductor.spectra = crate::spectrum::ConductorSpectra::named(
            &format!("{metal}-eta"),
            &format!("{metal}-k"),
        );
    }
    match (m.eta, m.k) {
        (Some(e), Some(k)) if m.metal.is_none() => {
            (conductor.eta, conductor.k) = (Vec3::from(e), Vec3::from(k))
        }
        (None, None) => {}
        _ => return Ok(Err("'eta' and 'k' go together, and not with 'metal'".into())),
    }
    conductor.reflectance = m.reflectance;
    if let Some(a) = m.conductor_alpha {
        conductor.alpha = Vec2::new(a, m.conductor_alpha_v.unwrap_or(a));
    }
    let mut coat = Coat::default();
    if let Some(a) = m.coat_alpha {
        coat.alpha = Vec2::new(a, m.coat_alpha_v.unwrap_or(a));
    }
    if let Some(ior) = m.ior {
        coat.eta = ior;
    }
    let mut slab = Slab::default();
    if let Some(t) = m.thickness {
        slab.thickness = t;
    }
    if let Some(a) = m.albedo {
        slab.albedo = Vec3::from(a);
    }
    if let Some(g) = m.g {
        slab.g = g;
    }
    if let Some(d) = m.max_depth {
        slab.max_depth = d;
    }
    if let Some(n) = m.n_samples {
        slab.n_samples = n;
    }
    let mut sheet = DiffuseTransmission::default();
    if let Some(t) = m.transmittance {
        sheet.transmittance = Vec3::from(t);
    }
    let model = match model {
        MaterialModel::Conductor(_) => MaterialModel::Conductor(conductor),
        MaterialModel::CoatedDiffuse(_) => {
            MaterialModel::CoatedDiffuse(CoatedDiffuse { coat, slab })
        }
        MaterialModel::CoatedConductor(_) => MaterialModel::CoatedConductor(CoatedConductor {
            coat,
            conductor,
            slab,
        }),
        MaterialModel::DiffuseTransmission(_) => MaterialModel::DiffuseTransmission(sheet),
        other => other,
    };
    // A parameter of another model is read by none of this one: say so rather than drop it.
    let conductor_reads = matches!(
        model,
        MaterialModel::Conductor(_) | MaterialModel::CoatedConductor(_)
    );
    let coat_reads = matches!(
        model,
        MaterialModel::CoatedDiffuse(_) | MaterialModel::CoatedConductor(_)
    );
    let sheet_reads = matches!(model, MaterialModel::DiffuseTransmission(_));
    let unread: Vec<&str> = [
        ("metal", m.metal.is_some(), conductor_reads),
        ("eta", m.eta.is_some(), conductor_reads),
        ("k", m.k.is_some(), conductor_reads),
        ("reflectance", m.reflectance, conductor_reads),
        (
            "conductor_alpha",
            m.conductor_alpha.is_some(),
            conductor_reads,
        ),
        (
            "conductor_alpha_v",
            m.conductor_alpha_v.is_some(),
            conductor_reads,
        ),
        ("coat_alpha", m.coat_alpha.is_some(), coat_reads),
        ("coat_alpha_v", m.coat_alpha_v.is_some(), coat_reads),
        ("thickness", m.thickness.is_some(), coat_reads),
        ("albedo", m.albedo.is_some(), coat_reads),
        ("g", m.g.is_some(), coat_reads),
        ("max_depth", m.max_depth.is_some(), coat_reads),
        ("n_samples", m.n_samples.is_some(), coat_reads),
        ("transmittance", m.transmittance.is_some(), sheet_reads),
    ]
    .into_iter()
    .filter(|&(_, given, read)| given && !read)
    .map(|(name, _, _)| name)
    .collect();
    if !unread.is_empty() {
        scene.warnings.push(format!(
            "material '{}': model '{}' does not read {}; ignored",
            m.name,
            m.model.as_deref().unwrap_or("diffuse"),
            unread.join(", ")
        ));
    }
    let mut mat = Material {
        name: m.name.clone(),
        model,
        base_color: m.base_color.map(Vec3::from).unwrap_or(Vec3::splat(0.8)),
        metallic: m.metallic.unwrap_or(0.0),
        roughness: m.roughness.unwrap_or(if model == MaterialModel::Diffuse {
            1.0
        } else {
            0.5
        }),
        emissive: m.emissive.map(Vec3::from).unwrap_or(Vec3::ZERO) * m.emissive_strength,
        double_sided: m.double_sided,
        ..Default::default()
    };
    if let Some(ior) = m.ior {
        mat.ior = ior;
    }
    if model == MaterialModel::Interface {
        // No surface: index-matched, so every integrator sees straight through it.
        if m.ior.is_some_and(|i| i != 1.0) {
            return Ok(Err(
                "an interface material has no surface: its ior is 1 (use a dielectric to refract)"
                    .into(),
            ));
        }
        mat.ior = 1.0;
        mat.transmission = 1.0;
        mat.roughness = 0.0;
    }
    if model.is_dielectric() {
        mat.transmission = 1.0;
        mat.roughness = m.roughness.unwrap_or(0.0);
    }
    if let Some(t) = m.transmission {
        mat.transmission = t;
    }
    if let Some(a) = m.alpha {
        mat.alpha = a;
        if a < 1.0 {
            mat.alpha_mode = AlphaMode::Blend;
        }
    }
    if let Some(s) = m.specular {
        mat.specular = s;
    }
    let uv_transform = (m.uv_scale.is_some() || m.uv_offset.is_some() || m.uv_rotation.is_some())
        .then(|| UvTransform {
            offset: m.uv_offset.map(Vec2::from).unwrap_or(Vec2::ZERO),
            rotation: m.uv_rotation.unwrap_or(0.0).to_radians(),
            scale: m.uv_scale.map(Vec2::from).unwrap_or(Vec2::ONE),
        });
    if let Some(t) = &uv_transform
        && !(t.offset.is_finite() && t.rotation.is_finite() && t.scale.is_finite())
    {
        return Ok(Err(
            "uv_scale, uv_offset and uv_rotation must be finite".into()
        ));
    }
    let mut tex = |f: &Option<String>, srgb: bool| -> Result<Option<TextureRef>, RefusedPath> {
        let Some(f) = f else { return Ok(None) };
        let t = load_texture_checked(dir, f, srgb, &mut scene.warnings)?;
        let missing = is_missing_texture(&t);
        scene.textures.push(t);
        Ok((srgb || !missing).then(|| TextureRef {
            transform: uv_transform,
            ..TextureRef::new(scene.textures.len() - 1)
        }))
    };
    mat.base_color_texture = tex(&m.base_color_texture, true)?;
    mat.metallic_roughness_texture = tex(&m.metallic_roughness_texture, false)?;
    mat.normal_texture = tex(&m.normal_texture, false)?;
    mat.emissive_texture = tex(&m.emissive_texture, true)?;
    if mat.emissive_texture.is_some() && !mat.is_emissive() {
        mat.emissive = Vec3::splat(m.emissive_strength);
    }
    Ok(Ok(mat))
}

/// Merges the contents of a scene file (OBJ, PLY, glTF or FBX) into `scene`, under `transform`:
/// its objects and materials, its lights (moved by `transform`) and its cameras (moved by
/// `transform`, into `cameras`, which follow the TOML's own).
fn add_mesh_file(
    scene: &mut Scene,
    dir: &Path,
    file: &str,
    transform: Mat4,
    (material, variant): (Option<MaterialId>, Option<&str>),
    interface: Option<super::MediumInterface>,
    cameras: &mut Vec<CameraDesc>,
) -> Result<(), String> {
    let path = resolve_in_dir(dir, file)?;
    let sub = match super::format_for(&path) {
        Some(f) if f.includable => super::load_file(&path),
        _ => {
            let ext = path.extension().unwrap_or_default().to_string_lossy();
            return Err(format!(
                "'{file}': meshes are read from {}, not '.{ext}'",
                super::extension_list(true)
            ));
        }
    }
    .map_err(|e| e.to_string())?;
    let mut sub = sub;
    if let Some(v) = variant {
        sub.select_variant(v).map_err(|e| e.to_string())?;
    }
    let (m0, t0, mat0, med0) = (
        scene.meshes.len(),
        scene.textures.len(),
        scene.materials.len(),
        scene.media.len(),
    );
    let o0 = scene.objects.len();
    let sub_variants = std::mem::take(&mut sub.variants);
    let sub_variant_objects = std::mem::take(&mut sub.variant_objects);
    // The file's own media (glTF KHR_materials_volume absorption) belong to its own materials.
    if material.is_none() {
        scene.media.extend(sub.media);
    }
    scene
        .warnings
        .extend(sub.warnings.iter().map(|w| format!("{file}: {w}")));
    scene.meshes.extend(sub.meshes);
    if material.is_none() {
        for mut m in sub.materials {
            // Every slot, the KHR extensions' included (Material::texture_refs_mut).
            for t in m.texture_refs_mut() {
                t.texture += t0;
            }
            // A pbrt-v4 `mix` names two of the file's own materials.
            if let MaterialModel::Mix(mix) = &mut m.model {
                mix.materials = mix.materials.map(|j| j + mat0 as u32);
            }
            scene.materials.push(m);
        }
        // Image nodes of pbrt-v4 procedural textures name the file's own images.
        scene.textures.extend(sub.textures.into_iter().map(|mut t| {
            if let Some(p) = &mut t.procedural {
                p.shift_images(t0 as u32);
            }
            t
        }));
    }
    for o in sub.objects {
        let shape = match o.shape {
            Shape::Mesh(i) => Shape::Mesh(i + m0),
            s => s,
        };
        let mat = material.unwrap_or(o.material + mat0);
        scene.add_object(&o.name, shape, transform * o.transform, mat);
        let shift = |m: Option<usize>| m.map(|m| m + med0);
        scene.objects.last_mut().expect("just added").medium =
            interface.or(if material.is_none() {
                o.medium.map(|mi| super::MediumInterface {
                    inside: shift(mi.inside),
                    outside: shift(mi.outside),
                })
            } else {
                None
            });
    }
    // The included file's material variants become the scene's (`--variant`, the server's
    // `variant` field, `trayecto info`), merged by name with other includes'. Each object's default
    // is the material it has now: the file's default, or the variant this include chose with
    // `variant =`. A material override (`material =`) replaces the file's materials, variants too.
    if material.is_none() {
        for v in &sub_variants {
            if !scene.variants.contains(v) {
                scene.variants.push(v.clone());
            }
        }
        let shift_interface = |mi: Option<super::MediumInterface>| {
            interface.or(mi.map(|mi| super::MediumInterface {
                inside: mi.inside.map(|m| m + med0),
                outside: mi.outside.map(|m| m + med0),
            }))
        };
        for ov in sub_variant_objects {
            let object = ov.object + o0;
            let Some(o) = scene.objects.get(object) else {
                continue;
            };
            let default = (o.material, o.medium);
            let by_variant = ov
                .by_variant
                .iter()
                .filter_map(|&(v, m, mi)| {
                    let name = sub_variants.get(v)?;
                    let merged = scene.variants.iter().position(|n| n == name)?;
                    Some((merged, m + mat0, shift_interface(mi)))
                })
                .collect();
            scene.variant_objects.push(super::ObjectVariants {
                object,
                default,
                by_variant,
            });
        }
    }
    // Lights and cameras are rigid: they take the object's rotation and translation. A scale in
    // the transform moves their positions but does not change a light's intensity (as Blender
    // does when a light object is scaled) nor a camera's field of view.
    let (_, rotation, _) = transform.to_scale_rotation_translation();
    for l in sub.lights {
        scene.lights.push(match l {
            LightDesc::Point {
                name,
                position,
                intensity,
            } => LightDesc::Point {
                name,
                position: transform.transform_point3(position),
                intensity,
            },
            LightDesc::Spot {
                name,
                position,
                direction,
                intensity,
                inner_angle,
                outer_angle,
                falloff,
            } => LightDesc::Spot {
                name,
                position: transform.transform_point3(position),
                direction: (rotation * direction).normalize(),
                intensity,
                inner_angle,
                outer_angle,
                falloff,
            },
            LightDesc::Directional {
                name,
                direction,
                irradiance,
            } => LightDesc::Directional {
                name,
                direction: (rotation * direction).normalize(),
                irradiance,
            },
            a @ LightDesc::Ambient { .. } => a,
            LightDesc::Environment {
                name,
                path,
                scale,
                mapping,
                transform: t,
            } => LightDesc::Environment {
                mapping,
                name,
                // Already resolved against the included file's folder by its loader.
                path,
                scale,
                transform: Mat4::from_quat(rotation) * t,
            },
        });
    }
    for mut c in sub.cameras {
        let (_, r, t) = (transform * c.camera_to_world).to_scale_rotation_translation();
        c.camera_to_world = Mat4::from_rotation_translation(r, t);
        cameras.push(c);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pbrt_models_read_their_keys() {
        let text = br#"
[[material]]
name = "cu"
model = "conductor"
metal = "metal-Cu"
conductor_alpha = 0.1
conductor_alpha_v = 0.3

[[material]]
name = "coat"
model = "coated-conductor"
eta = [0.2, 0.9, 1.1]
k = [3.9, 2.4, 2.2]
ior = 1.3
coat_alpha = 0.2
thickness = 0.05
albedo = [0.5, 0.5, 0.5]
g = 0.2
max_depth = 20
n_samples = 4

[[material]]
name = "sheet"
model = "diffuse-transmission"
base_color = [0.3, 0.3, 0.3]
transmittance = [0.6, 0.5, 0.4]
"#;
        let scene = load_from_bytes(text, Path::new("."), "t.toml").unwrap();
        let [cu, coat, sheet] = &scene.materials[..] else {
            panic!("three materials")
        };
        let MaterialModel::Conductor(cu) = cu.model else {
            panic!("{:?}", cu.model)
        };
        let (eta, k) = crate::spectrum::named_conductor_rgb("metal-Cu").unwrap();
        assert_eq!((cu.eta, cu.k), (eta, k));
        assert_eq!(cu.alpha, Vec2::new(0.1, 0.3));
        let MaterialModel::CoatedConductor(coat) = coat.model else {
            panic!("{:?}", coat.model)
        };
        assert_eq!(coat.conductor.k, Vec3::new(3.9, 2.4, 2.2));
        assert_eq!(coat.coat.eta, 1.3);
        assert_eq!(coat.coat.alpha, Vec2::splat(0.2));
        assert_eq!((coat.slab.max_depth, coat.slab.n_samples), (20, 4));
        assert_eq!((coat.slab.thickness, coat.slab.g), (0.05, 0.2));
        let MaterialModel::DiffuseTransmission(sheet) = sheet.model else {
            panic!("{:?}", sheet.model)
        };
        assert_eq!(sheet.transmittance, Vec3::new(0.6, 0.5, 0.4));

        for (bad, why) in [
            (
                "model = \"conductor\"\nmetal = \"metal-Xx\"",
                "unknown metal",
            ),
            ("model = \"conductor\"\neta = [1, 1, 1]", "go together"),
            ("model = \"coated-diffuse\"\ng = 1.0", "g must be"),
            ("model = \"coated-diffuse\"\nthickness = 0.0", "thickness"),
            ("model = \"coated-diffuse\"\nn_samples = 0", "nsamples"),
            ("model = \"conductor\"\nconductor_alpha = -1.0", "negative"),
        ] {
            let text = format!("[[material]]\nname = \"m\"\n{bad}\n");
            let e = crate::scene::load_bytes(text.as_bytes(), Path::new("."), "t.toml")
                .err()
                .unwrap_or_else(|| panic!("{bad} accepted"))
                .to_string();
            assert!(e.contains(why), "{bad}: {e}");
        }

        // Another model's parameters are named in a warning, not dropped in silence.
        let text = b"[[material]]\nname = \"m\"\ng = 0.5\nmetal = \"metal-Cu\"\n";
        let scene = load_from_bytes(text, Path::new("."), "t.toml").unwrap();
        assert_eq!(
            scene.warnings,
            ["material 'm': model 'diffuse' does not read metal, g; ignored"]
        );
        let text = b"[[material]]\nname = \"m\"\nmodel = \"coated-diffuse\"\ng = 0.5\n";
        let scene = load_from_bytes(text, Path::new("."), "t.toml").unwrap();
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    }

    #[test]
    fn uv_transform_applies_to_the_material_textures() {
        let text = br#"
[[material]]
name = "floor"
base_color_texture = "missing.png"
uv_scale = [3.0, 2.0]
uv_rotation = 90.0
uv_offset = [0.1, 0.25]
"#;
        let scene = load_from_bytes(text, Path::new("."), "t.toml").unwrap();
        let t = scene.materials[0]
            .base_color_texture
            .unwrap()
            .transform
            .expect("transform");
        assert_eq!(t.scale, Vec2::new(3.0, 2.0));
        assert_eq!(t.offset, Vec2::new(0.1, 0.25));
        assert!((t.rotation - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        // KHR_texture_transform: u' = cos·sx·u + sin·sy·v + ox.
        let p = t.apply(Vec2::new(1.0, 0.0));
        assert!((p - Vec2::new(0.1, 0.25 - 3.0)).length() < 1e-5, "{p}");

        let plain = b"[[material]]\nname = \"m\"\nbase_color_texture = \"missing.png\"\n";
        let scene = load_from_bytes(plain, Path::new("."), "t.toml").unwrap();
        assert!(
            scene.materials[0]
                .base_color_texture
                .unwrap()
                .transform
                .is_none()
        );

        let bad = b"[[material]]\nname = \"m\"\nuv_scale = [nan, 1.0]\n";
        assert!(load_from_bytes(bad, Path::new("."), "t.toml").is_err());
    }
}
