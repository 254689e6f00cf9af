//! Wavefront OBJ/MTL loader (docs/DESIGN.md §3), on top of the `tobj` crate.
//!
//! MTL mapping: `Kd` → base colour, `Ks`/`Ns` → Phong parameters of the raycast/Whitted modes
//! (thesis §5.1.10), `Ke` → emitted radiance, `Ni` → IOR, `d` (or `Tr` = 1 − d) → opacity,
//! `illum` 3/5 → mirror, 4/6/7 with `d` < 1 or `Ni` → dielectric; `map_Kd`/`map_Ke` (sRGB),
//! `map_Ks` → specular colour texture, `map_d` → opacity texture, `bump`/`norm` → normal map;
//! the PBR extension `Pr`/`Pm` → roughness/metallic (metallic-roughness model) with `map_Pr` and
//! `map_Pm` packed into one glTF-layout texture; `Ka` above 1 without `Ke` is emission (a legacy
//! convention for lights). Other statements are named in warnings.
//! Faces are triangulated as fans; missing MTL files and textures are warnings.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use super::conventions::apply_material_conventions;
use super::image_io::{RefusedPath, is_missing_texture, load_texture_checked, resolve_in_dir};
use super::{Mesh, Scene, SceneError, Shape};
use crate::material::{AlphaMode, Material, MaterialModel, PhongParams, TextureRef};
use crate::math::{Mat4, Vec2, Vec3};

/// Loads OBJ text from memory; MTL files and textures are looked up in `dir`. (Also the fuzzing
/// entry point.)
pub fn load_from_bytes(bytes: &[u8], dir: &Path, label: &str) -> Result<Scene, SceneError> {
    let err = |m: String| SceneError::invalid(label, m);
    let mut scene = Scene {
        name: label.to_string(),
        source: Some(label.into()),
        ..Default::default()
    };
    let refused: std::cell::RefCell<Option<String>> = Default::default();
    let mtl_warnings: std::cell::RefCell<Vec<String>> = Default::default();
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::Cursor::new(bytes);
    // tobj can panic on hostile input (an `unwrap` in its MTL parser): contained, as every
    // third-party parser is (docs/DESIGN.md §7).
    let parsed = super::contain_panics(
        label,
        "the OBJ or its material library is malformed",
        || {
            tobj::load_obj_buf(&mut reader, &options, |mtl: &Path| {
        let name = mtl.to_string_lossy().into_owned();
        let p = match resolve_in_dir(dir, &name) {
            Ok(p) => p,
            Err(why) => {
                *refused.borrow_mut() = Some(format!("material library {why}"));
                return Err(tobj::LoadError::OpenFileFailed);
            }
        };
        match crate::limits::read_file(&p) {
            Ok(bytes) => tobj::load_mtl_buf(&mut std::io::Cursor::new(bytes)),
            Err(e) => {
                mtl_warnings.borrow_mut().push(format!(
                    "material library '{name}' could not be read ({e}): default grey materials are used"
                ));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
        })
        .map_err(|e| err(format!("not a valid OBJ file: {e}")))
        },
    );
    let (models, materials) = parsed?;
    if let Some(why) = refused.into_inner() {
        return Err(err(why));
    }
    scene.warnings.extend(mtl_warnings.into_inner());
    let materials = match materials {
        Ok(m) => m,
        Err(tobj::LoadError::OpenFileFailed) => Vec::new(),
        Err(e) => {
            scene.warnings.push(format!(
                "material library is malformed ({e}): default grey materials are used"
            ));
            Vec::new()
        }
    };

    let mut warned = HashSet::new();
    for m in &materials {
        let mat = convert_material(m, dir, &mut scene, &mut warned)
            .map_err(|RefusedPath(why)| err(format!("material '{}': texture {why}", m.name)))?;
        scene.add_material(mat);
    }
    let mut default_material = None;
    for model in models {
        let tm = &model.mesh;
        let n = tm.positions.len() / 3;
        let positions: Vec<Vec3> = tm
            .positions
            .chunks_exact(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let normals = (tm.normals.len() == n * 3 && n > 0).then(|| {
            tm.normals
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect()
        });
        // OBJ's v runs up the image; Trayecto's textures have v = 0 at the top row (glTF).
        let uv0 = (tm.texcoords.len() == n * 2 && n > 0).then(|| {
            tm.texcoords
                .chunks_exact(2)
                .map(|t| Vec2::new(t[0], 1.0 - t[1]))
                .collect()
        });
        let indices: Vec<[u32; 3]> = tm
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        if indices.is_empty() {
            continue;
        }
        let material = match tm.material_id {
            Some(i) if i < scene.materials.len() => i,
            other => {
                if let Some(i) = other {
                    scene.warnings.push(format!(
                        "object '{}' uses material {i}, which is not defined: a grey default is used",
                        model.name
                    ));
                }
                *default_material.get_or_insert_with(|| {
                    scene
                        .materials
                        .push(Material::diffuse("OBJ default", Vec3::splat(0.8)));
                    scene.materials.len() - 1
                })
            }
        };
        let mesh = scene.add_mesh(Mesh {
            name: model.name.clone(),
            positions,
            indices,
            normals,
            uv0,
            ..Default::default()
        });
        scene.add_object(&model.name, Shape::Mesh(mesh), Mat4::IDENTITY, material);
    }
    apply_material_conventions(&mut scene);
    if scene.triangle_count() == 0 {
        // Plain text parses as an OBJ of unknown statements; a file without a single face is
        // not a scene, and saying so beats rendering an empty image.
        return Err(SceneError::invalid(
            label,
            "no faces found: this is not an OBJ mesh",
        ));
    }
    Ok(scene)
}

fn convert_material(
    m: &tobj::Material,
    dir: &Path,
    scene: &mut Scene,
    warned: &mut HashSet<String>,
) -> Result<Material, RefusedPath> {
    let v3 = |a: Option<[f32; 3]>| a.map(Vec3::from);
    let name = m.name.clone();
    let mut mat = Material::diffuse(&name, v3(m.diffuse).unwrap_or(Vec3::splat(0.8)));
    let unknown: &HashMap<String, String> = &m.unknown_param;
    let scalar = |k: &str| {
        unknown
            .get(k)
            .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
    };
    let specular = v3(m.specular).unwrap_or(Vec3::ZERO);
    let shininess = m.shininess.unwrap_or(0.0);
    if m.specular.is_some() || m.shininess.is_some() {
        mat.phong = Some(PhongParams {
            specular,
            shininess,
        });
    }
    if let Some(ke) = v3(m.emissive) {
        mat.emissive = ke;
    }
    if let Some(ni) = m.optical_density {
        mat.ior = ni;
    }
    mat.alpha = match (m.dissolve, scalar("Tr")) {
        (Some(d), _) => d,
        (None, Some(tr)) => 1.0 - tr,
        (None, None) => 1.0,
    };
    // Legacy convention (the Cornell box MTL files of Embree, tinyobjloader and many course
    // renderers): a light is marked by an ambient colour above 1 and no Ke. An ambient reflectance
    // cannot exceed 1, so such a Ka can only mean emitted radiance.
    if let Some(ka) = m.ambient
        && Vec3::from(ka).max_element() > 1.0
    {
        if m.emissive.is_none() && !unknown.contains_key("map_Ke") {
            mat.emissive = Vec3::from(ka);
            scene.warnings.push(format!(
                "material '{name}': ambient Ka {ka:?} is greater than 1 and there is no Ke, so it is \
                 taken as emitted radiance (a legacy MTL convention; write Ke to say so)"
            ));
        } else {
            scene.warnings.push(format!(
                "material '{name}': ambient Ka {ka:?} is ignored (the material has Ke)"
            ));
        }
    }
    // The PBR extension of MTL (Pr, Pm) selects the metallic-roughness model.
    let pr = scalar("Pr");
    let pm = scalar("Pm");
    let illum = m
        .illumination_model
        .unwrap_or(if specular.max_element() > 0.0 { 2 } else { 1 });
    if pr.is_some()
        || pm.is_some()
        || unknown.contains_key("map_Pr")
        || unknown.contains_key("map_Pm")
    {
        mat.model = MaterialModel::metallic_roughness();
        mat.roughness = pr.unwrap_or(1.0);
        mat.metallic = pm.unwrap_or(0.0);
    } else {
        match illum {
            3 | 5 => {
                mat.model = MaterialModel::Mirror;
                mat.base_color = if specular.max_element() > 0.0 {
                    specular
                } else {
                    mat.base_color
                };
            }
            4 | 6 | 7 if mat.alpha < 1.0 || m.optical_density.is_some_and(|n| n > 1.0) => {
                mat.model = MaterialModel::dielectric();
                mat.transmission = 1.0;
                mat.roughness = 0.0;
            }
            _ => {}
        }
    }

    let tex = |file: &str, srgb: bool, scene: &mut Scene| -> Result<Option<usize>, RefusedPath> {
        // Options such as `-bm 1.0` come before the file name; the name is the last word.
        let file = file.split_whitespace().last().unwrap_or("");
        let t = load_texture_checked(dir, file, srgb, &mut scene.warnings)?;
        let missing = is_missing_texture(&t);
        scene.textures.push(t);
        Ok(Some(scene.textures.len() - 1).filter(|_| srgb || !missing))
    };
    let tref = |i: Option<usize>| i.map(TextureRef::new);
    if let Some(f) = &m.diffuse_texture {
        mat.base_color_texture = tref(tex(f, true, scene)?);
    }
    if let Some(f) = unknown.get("map_Ke") {
        mat.emissive_texture = tref(tex(f, true, scene)?);
        if !mat.is_emissive() {
            mat.emissive = Vec3::ONE;
        }
    }
    if let Some(f) = &m.specular_texture {
        mat.specular_color_texture = tref(tex(f, true, scene)?);
    }
    if let Some(f) = &m.dissolve_texture {
        mat.alpha_texture = tref(tex(f, false, scene)?);
    }
    // Dissolve on a non-glass material is opacity: rendered as stochastic transparency.
    if !mat.model.is_dielectric() && (mat.alpha < 1.0 || mat.alpha_texture.is_some()) {
        mat.alpha_mode = AlphaMode::Blend;
    }
    if let Some(f) = m.normal_texture.as_ref().or(unknown.get("norm")) {
        mat.normal_texture = tref(tex(f, false, scene)?);
    }
    let rough = match unknown.get("map_Pr") {
        Some(f) => tex(f, false, scene)?,
        None => None,
    };
    let metal = match unknown.get("map_Pm") {
        Some(f) => tex(f, false, scene)?,
        None => None,
    };
    if rough.is_some() || metal.is_some() {
        let packed = super::image_io::pack_metallic_roughness(
            rough.and_then(|i| scene.textures.get(i)),
            metal.and_then(|i| scene.textures.get(i)),
        );
        if let Some(p) = packed {
            // The factors multiply the texture (glTF): a map replaces a missing scalar.
            if pr.is_none() && rough.is_some() {
                mat.roughness = 1.0;
            }
            if pm.is_none() && metal.is_some() {
                mat.metallic = 1.0;
            }
            scene.textures.push(p);
            mat.metallic_roughness_texture = Some(TextureRef::new(scene.textures.len() - 1));
        }
    }
    const HANDLED: &[&str] = &["Tr", "Pr", "Pm", "map_Pr", "map_Pm", "map_Ke", "norm", "Ke"];
    for k in unknown.keys() {
        if !HANDLED.contains(&k.as_str()) && warned.insert(k.clone()) {
            scene.warnings.push(format!(
                "MTL statement '{k}' is not supported and is ignored"
            ));
        }
    }
    if m.ambient_texture.is_some() && warned.insert("map_Ka".into()) {
        scene
            .warnings
            .push("MTL statement 'map_Ka' is not supported and is ignored".into());
    }
    if m.shininess_texture.is_some() && warned.insert("map_Ns".into()) {
        scene
            .warnings
            .push("MTL statement 'map_Ns' is not supported and is ignored".into());
    }
    Ok(mat)
}
