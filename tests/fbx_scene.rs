//! The FBX loader against the shared FBX scenes (made by `shared/scenes/fbx/make_fbx.py`): the
//! scene structure is checked numerically against the values in the script and against the
//! scene's `.glb` twin (exported from the same Blender scene; its JSON chunk parsed here).

mod common;

use common::shared_scene;
use glam::{Mat4, Quat, Vec3};
use serde_json::Value;
use std::collections::HashMap;
use trayecto::scene::{self, LightDesc, Scene, Shape};

fn load_fbx(name: &str) -> Scene {
    let p = shared_scene(&format!("fbx/{name}.fbx"));
    scene::load(p.to_str().unwrap()).unwrap_or_else(|e| panic!("{e}"))
}

/// The JSON chunk of a .glb.
fn glb_json(name: &str) -> Value {
    let bytes = std::fs::read(shared_scene(&format!("fbx/{name}.glb"))).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    serde_json::from_slice(&bytes[20..20 + len]).unwrap()
}

fn f(v: &Value) -> f32 {
    v.as_f64().unwrap() as f32
}

fn vec3(v: &Value) -> Vec3 {
    Vec3::new(f(&v[0]), f(&v[1]), f(&v[2]))
}

/// World matrices of every glTF node, by node name.
fn gltf_world(json: &Value) -> HashMap<String, (Mat4, Value)> {
    fn walk(json: &Value, i: usize, parent: Mat4, out: &mut HashMap<String, (Mat4, Value)>) {
        let n = &json["nodes"][i];
        let t = n.get("translation").map(vec3).unwrap_or(Vec3::ZERO);
        let r = n
            .get("rotation")
            .map(|r| Quat::from_xyzw(f(&r[0]), f(&r[1]), f(&r[2]), f(&r[3])))
            .unwrap_or(Quat::IDENTITY);
        let s = n.get("scale").map(vec3).unwrap_or(Vec3::ONE);
        let m = parent * Mat4::from_scale_rotation_translation(s, r, t);
        out.insert(n["name"].as_str().unwrap().to_string(), (m, n.clone()));
        for c in n
            .get("children")
            .and_then(|c| c.as_array())
            .into_iter()
            .flatten()
        {
            walk(json, c.as_u64().unwrap() as usize, m, out);
        }
    }
    let mut out = HashMap::new();
    for r in json["scenes"][0]["nodes"].as_array().unwrap() {
        walk(json, r.as_u64().unwrap() as usize, Mat4::IDENTITY, &mut out);
    }
    out
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

/// Checks the FBX scene against its glTF twin: objects, triangle counts, world bounds, materials
/// and camera.
fn check_against_gltf(name: &str) -> (Scene, Value) {
    let s = load_fbx(name);
    let json = glb_json(name);
    let world = gltf_world(&json);
    let gltf_meshes: Vec<(&String, &(Mat4, Value))> = world
        .iter()
        .filter(|(_, (_, n))| n.get("mesh").is_some())
        .collect();
    assert_eq!(s.objects.len(), gltf_meshes.len(), "object count");
    assert_eq!(s.objects.len(), 9);
    for (node_name, (m, node)) in gltf_meshes {
        let obj = s
            .objects
            .iter()
            .find(|o| &o.name == node_name)
            .unwrap_or_else(|| panic!("FBX has no object '{node_name}'"));
        let Shape::Mesh(mesh_id) = obj.shape else {
            panic!("'{node_name}' is not a mesh")
        };
        let mesh = &s.meshes[mesh_id];
        let prim = &json["meshes"][node["mesh"].as_u64().unwrap() as usize]["primitives"][0];
        let acc = |i: &Value| &json["accessors"][i.as_u64().unwrap() as usize];
        let gl_tris = acc(&prim["indices"])["count"].as_u64().unwrap() as usize / 3;
        assert_eq!(mesh.indices.len(), gl_tris, "triangles of '{node_name}'");
        // World bounds: the glTF accessor's box corners through the node's world matrix (exact
        // for these boxes, quads and the axis-aligned sphere).
        let pos = acc(&prim["attributes"]["POSITION"]);
        let (lo, hi) = (vec3(&pos["min"]), vec3(&pos["max"]));
        let (mut gmin, mut gmax) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for c in 0..8 {
            let p = Vec3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            );
            let w = m.transform_point3(p);
            gmin = gmin.min(w);
            gmax = gmax.max(w);
        }
        let (mut fmin, mut fmax) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for &p in &mesh.positions {
            let w = obj.transform.transform_point3(p);
            fmin = fmin.min(w);
            fmax = fmax.max(w);
        }
        assert!(
            close(fmin, gmin, 1e-4) && close(fmax, gmax, 1e-4),
            "bounds of '{node_name}': FBX {fmin}..{fmax}, glTF {gmin}..{gmax}"
        );
        // Material colour.
        let gm = &json["materials"][prim["material"].as_u64().unwrap() as usize];
        let mat = &s.materials[obj.material];
        assert_eq!(mat.name, gm["name"].as_str().unwrap());
        assert!(mat.double_sided, "FBX surfaces are double-sided");
        let base = gm["pbrMetallicRoughness"]
            .get("baseColorFactor")
            .map(vec3)
            .unwrap_or(Vec3::ONE);
        assert!(
            close(mat.base_color, base, 1e-6),
            "colour of '{}': {} vs {base}",
            mat.name,
            mat.base_color
        );
        if !mat.model.is_dielectric() {
            let pbr = &gm["pbrMetallicRoughness"];
            let metallic = pbr.get("metallicFactor").map(f).unwrap_or(1.0);
            let roughness = pbr.get("roughnessFactor").map(f).unwrap_or(1.0);
            assert!((mat.metallic - metallic).abs() < 1e-6, "{}", mat.name);
            assert!((mat.roughness - roughness).abs() < 1e-6, "{}", mat.name);
            assert!((mat.specular - 1.0).abs() < 1e-6, "{}", mat.name);
        }
    }
    // Camera: pose and vertical field of view.
    assert_eq!(s.cameras.len(), 1);
    let cam = &s.cameras[0];
    let (cm, cnode) = &world["camera"];
    let gcam = &json["cameras"][cnode["camera"].as_u64().unwrap() as usize]["perspective"];
    let yfov = f(&gcam["yfov"]).to_degrees();
    assert!(
        (cam.vfov_deg - yfov).abs() < 1e-3,
        "{} vs {yfov}",
        cam.vfov_deg
    );
    assert!((cam.vfov_deg - 39.3077).abs() < 1e-3);
    let c2w = cam.camera_to_world;
    assert!(close(c2w.w_axis.truncate(), cm.w_axis.truncate(), 1e-5));
    assert!(close(c2w.w_axis.truncate(), Vec3::new(0.0, 0.0, 3.9), 1e-5));
    let fwd = -c2w.z_axis.truncate().normalize();
    let gfwd = -cm.z_axis.truncate().normalize();
    assert!(
        close(fwd, gfwd, 1e-5) && close(fwd, Vec3::NEG_Z, 1e-5),
        "{fwd}"
    );
    assert!(close(c2w.y_axis.truncate().normalize(), Vec3::Y, 1e-5));
    (s, json)
}

#[test]
fn conventions_scene_matches_its_gltf_twin() {
    let (s, _) = check_against_gltf("cornell_seed_conventions");
    assert!(s.lights.is_empty(), "only the emissive-by-name area light");
    // The ceiling light emits its diffuse colour × 5 by name; the ball is glass of IOR 1.4.
    let light = s
        .materials
        .iter()
        .find(|m| m.name == "emissive_ceiling_light")
        .unwrap();
    assert!(close(
        light.emissive,
        Vec3::new(0.92, 0.70, 0.34) * 5.0,
        1e-5
    ));
    let glass = s
        .materials
        .iter()
        .find(|m| m.name == "refractive_glass")
        .unwrap();
    assert!(glass.model.is_dielectric());
    assert_eq!(glass.ior, 1.4);
    let others = s.materials.iter().filter(|m| m.is_emissive()).count();
    assert_eq!(others, 1, "only the light emits");
    // The sphere has smooth per-vertex normals and UVs; the box geometry matches docs/DESIGN.md §3.
    let ball = s.objects.iter().find(|o| o.name == "glass_ball").unwrap();
    let Shape::Mesh(b) = ball.shape else { panic!() };
    assert!(s.meshes[b].normals.is_some() && s.meshes[b].uv0.is_some());
    assert_eq!(s.meshes[b].indices.len(), 48 * 22 * 2 + 2 * 48);
    let large = s.objects.iter().find(|o| o.name == "large_box").unwrap();
    let expect = Mat4::from_cols_array_2d(&[
        [0.28491, 0.0, -0.0939491, 0.0],
        [0.0, 0.61, 0.0, 0.0],
        [0.0939491, 0.0, 0.28491, 0.0],
        [-0.33, -0.4, -0.28, 1.0],
    ]);
    assert!(
        large.transform.abs_diff_eq(expect, 2e-5),
        "{}",
        large.transform
    );
}

#[test]
fn lights_scene_loads_ambient_and_point_lights_in_radiometric_units() {
    let (s, json) = check_against_gltf("cornell_seed_conventions_lights");
    let world = gltf_world(&json);
    assert_eq!(s.lights.len(), 2);
    let gl_lights = json["extensions"]["KHR_lights_punctual"]["lights"]
        .as_array()
        .unwrap();
    // `ambient_fill` (a point light by type) is an ambient light of its colour by name.
    let amb = s
        .lights
        .iter()
        .find(|l| l.name() == "ambient_fill")
        .unwrap();
    let LightDesc::Ambient { radiance, .. } = amb else {
        panic!("{amb:?}")
    };
    let gl_amb = gl_lights
        .iter()
        .find(|l| l["name"] == "ambient_fill")
        .unwrap();
    assert!(close(*radiance, vec3(&gl_amb["color"]), 1e-7));
    assert!(close(*radiance, Vec3::splat(0.05), 1e-7));
    // `key_point`: Blender energy 20 W; FBX Intensity 2000 (watts × 100) → 20/(4π) W/sr; the glTF
    // twin's 1087.03 cd / 683 lm/W is the same radiant intensity (docs/DESIGN.md §4).
    let key = s.lights.iter().find(|l| l.name() == "key_point").unwrap();
    let LightDesc::Point {
        position,
        intensity,
        ..
    } = key
    else {
        panic!("{key:?}")
    };
    let expected = 20.0 / (4.0 * std::f32::consts::PI);
    assert!(
        close(*intensity, Vec3::splat(expected), 1e-5),
        "{intensity}"
    );
    let gl_key = gl_lights.iter().find(|l| l["name"] == "key_point").unwrap();
    let w_per_sr = f(&gl_key["intensity"]) / 683.0 * vec3(&gl_key["color"]);
    assert!(
        ((*intensity - w_per_sr) / w_per_sr).abs().max_element() < 1e-5,
        "FBX {intensity} W/sr vs glTF {w_per_sr} W/sr"
    );
    assert!(
        close(*position, Vec3::new(0.5, 0.6, 1.0), 1e-5),
        "{position}"
    );
    let (km, _) = &world["key_point"];
    assert!(close(*position, km.w_axis.truncate(), 1e-5));
}

#[test]
fn warnings_list_the_conventions_applied() {
    let s = load_fbx("cornell_seed_conventions_lights");
    let all = s.warnings.join("\n");
    for needle in [
        "'emissive_ceiling_light'",
        "'refractive_glass'",
        "'ambient_fill'",
    ] {
        assert!(all.contains(needle), "{all}");
    }
}
