//! Objects that share a mesh render the same instanced (a two-level BVH over one object-space
//! copy, `geometry::instance`) as flattened into world-space triangles: every hit's bits, and so
//! every pixel's, under rotation, non-uniform scale, shear and mirroring, with shading normals,
//! tangents, uvs, vertex colours, alpha cut-outs, an area light and shadow rays.

mod common;

use glam::Quat;
use trayecto::film::Image;
use trayecto::geometry::Ray;
use trayecto::integrator::{Aov, IntegratorKind, ShadingModel};
use trayecto::material::{AlphaMode, Material};
use trayecto::math::{Mat4, Vec2, Vec3, Vec4};
use trayecto::render::RenderSettings;
use trayecto::scene::{CameraDesc, Scene, Shape, testscenes};
use trayecto::world::{Instancing, World, WorldOptions};

fn scene() -> Scene {
    let mut s = Scene::default();
    let mut mesh = testscenes::uv_sphere("ball", 8, 12);
    let n = mesh.positions.len();
    // Tangents and colours too, so every interpolated attribute is read; alpha varies so the
    // cut-out material has holes.
    mesh.tangents = Some(
        (0..n)
            .map(|i| {
                Vec4::new(
                    1.0,
                    0.1 * i as f32,
                    0.0,
                    if i % 3 == 0 { -1.0 } else { 1.0 },
                )
            })
            .collect(),
    );
    mesh.colors = Some(
        (0..n)
            .map(|i| Vec4::new(0.9, 0.5, 0.2, if i % 4 == 0 { 0.1 } else { 1.0 }))
            .collect(),
    );
    mesh.uv1 = mesh
        .uv0
        .as_ref()
        .map(|uv| uv.iter().map(|&u| u * 2.0 + Vec2::splat(0.1)).collect());
    let ball = s.add_mesh(mesh);
    let red = s.add_material(Material::diffuse("red", Vec3::new(0.8, 0.2, 0.1)));
    let blue = s.add_material(Material::diffuse("blue", Vec3::new(0.1, 0.3, 0.8)));
    let mut cut = Material::diffuse("cut", Vec3::splat(0.7));
    cut.alpha_mode = AlphaMode::Mask;
    let cut = s.add_material(cut);
    let mut lamp = Material::diffuse("lamp", Vec3::ZERO);
    lamp.emissive = Vec3::splat(6.0);
    let lamp = s.add_material(lamp);
    let placements = [
        // An emissive copy stays flat (it is an area light). First, so that its triangles are
        // numbered first in both worlds.
        (
            Mat4::from_translation(Vec3::new(0.0, 4.5, 1.0)) * Mat4::from_scale(Vec3::splat(0.4)),
            lamp,
        ),
        (Mat4::from_translation(Vec3::new(-2.0, 1.0, 0.0)), red),
        (
            Mat4::from_scale_rotation_translation(
                Vec3::new(1.5, 0.5, 0.8),
                Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.3),
                Vec3::new(0.0, 0.8, 0.5),
            ),
            blue,
        ),
        // A mirror: the winding and the bitangents flip.
        (
            Mat4::from_translation(Vec3::new(2.0, 1.0, -0.5))
                * Mat4::from_scale(Vec3::new(-1.0, 1.2, 1.0)),
            red,
        ),
        // A shear.
        (
            Mat4::from_translation(Vec3::new(0.0, 2.5, -1.0))
                * Mat4::from_cols(
                    Vec4::new(1.0, 0.0, 0.0, 0.0),
                    Vec4::new(0.6, 1.0, 0.0, 0.0),
                    Vec4::new(0.0, 0.3, 0.7, 0.0),
                    Vec4::W,
                ),
            cut,
        ),
    ];
    for (i, (m, material)) in placements.into_iter().enumerate() {
        s.add_object(&format!("ball{i}"), Shape::Mesh(ball), m, material);
    }
    common::add_floor(&mut s, 6.0, 0.5);
    s.cameras.push(CameraDesc::look_at(
        "cam",
        Vec3::new(0.5, 2.5, 8.0),
        Vec3::new(0.0, 1.2, 0.0),
        Vec3::Y,
        45.0,
    ));
    s.validate().unwrap();
    s
}

fn world(instancing: Instancing) -> World {
    World::build(
        scene(),
        &WorldOptions {
            instancing,
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .unwrap()
}

fn render(w: &World, integrator: IntegratorKind) -> Image {
    common::render_world(
        w,
        &RenderSettings {
            width: 40,
            height: 32,
            spp: 4,
            integrator,
            ..RenderSettings::default()
        },
    )
}

fn bits(img: &Image) -> Vec<[u32; 3]> {
    img.data
        .iter()
        .map(|v| v.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn instanced_and_flattened_worlds_agree() {
    let flat = world(Instancing::Never);
    let inst = world(Instancing::Always);
    assert!(flat.geometry.instances.is_empty());
    // Four copies instanced; the emissive one flattened and lit.
    assert_eq!(inst.geometry.instances.instances.len(), 4);
    assert_eq!(inst.geometry.instances.meshes.len(), 1);
    assert_eq!(inst.area_light_count(), flat.area_light_count());
    assert!(inst.area_light_count() > 0);
    assert_eq!(flat.bounds, inst.bounds);

    // Every hit the same, field by field (the instanced triangles' indices follow the flat ones,
    // as the flattening numbers them here: the emissive copy is the first object).
    let mut hits = 0;
    for i in 0..4000 {
        let a = i as f32 * 0.618_034;
        let o = Vec3::new(3.0 * (a * 1.3).sin(), 1.0 + 2.0 * (a * 0.7).cos(), 7.0);
        let target = Vec3::new(3.0 * (a * 2.1).cos(), 1.5 + 1.5 * (a * 1.7).sin(), -1.0);
        let mut ray = Ray::new(o, target - o);
        if i % 5 == 0 {
            ray.t_max = 0.9;
        }
        let (f, n) = (flat.intersect(&ray), inst.intersect(&ray));
        assert_eq!(format!("{f:?}"), format!("{n:?}"), "ray {i}");
        assert_eq!(flat.occluded(&ray), inst.occluded(&ray), "ray {i}");
        hits += f.is_some() as usize;
    }
    assert!(hits > 1000, "{hits}");

    for integrator in [
        IntegratorKind::Path,
        IntegratorKind::Raycast {
            aov: Aov::Normals,
            shading: ShadingModel::default(),
        },
        IntegratorKind::Raycast {
            aov: Aov::Uv,
            shading: ShadingModel::default(),
        },
    ] {
        assert!(
            bits(&render(&flat, integrator)) == bits(&render(&inst, integrator)),
            "{integrator:?}: the images differ"
        );
    }
}

#[test]
fn auto_keeps_ordinary_scenes_flat() {
    assert!(world(Instancing::Auto).geometry.instances.is_empty());
}

/// A glTF triangle placed three times by `EXT_mesh_gpu_instancing` (translations and a rotation
/// accessor with one zero quaternion).
#[test]
fn gltf_gpu_instancing_places_one_shared_mesh_per_instance() {
    use base64::Engine;
    let mut buf: Vec<u8> = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        v.iter().for_each(|c| buf.extend(c.to_le_bytes()));
    }
    for t in [[0.0f32, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, -3.0]] {
        t.iter().for_each(|c| buf.extend(c.to_le_bytes()));
    }
    let half = std::f32::consts::FRAC_1_SQRT_2;
    for q in [[0.0f32, 0.0, 0.0, 1.0], [0.0, 0.0, half, half], [0.0; 4]] {
        q.iter().for_each(|c| buf.extend(c.to_le_bytes()));
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["EXT_mesh_gpu_instancing"],
 "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":36}},
   {{"buffer":0,"byteOffset":72,"byteLength":48}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
   {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3"}},
   {{"bufferView":2,"componentType":5126,"count":3,"type":"VEC4"}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
 "nodes":[{{"mesh":0,"translation":[0,1,0],
   "extensions":{{"EXT_mesh_gpu_instancing":{{"attributes":{{"TRANSLATION":1,"ROTATION":2}}}}}}}}],
 "scenes":[{{"nodes":[0]}}]}}"#,
        buf.len()
    );
    let s =
        trayecto::scene::load_bytes(json.as_bytes(), std::path::Path::new("."), "i.gltf").unwrap();
    assert_eq!(s.objects.len(), 3);
    assert!(s.objects.iter().all(|o| matches!(o.shape, Shape::Mesh(0))));
    let at = |i: usize| s.objects[i].transform.transform_point3(Vec3::X);
    assert!(
        (at(0) - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-6,
        "{}",
        at(0)
    );
    // Rotated a quarter turn about z, then moved by the instance and the node.
    assert!(
        (at(1) - Vec3::new(2.0, 2.0, 0.0)).length() < 1e-6,
        "{}",
        at(1)
    );
    assert!(
        (at(2) - Vec3::new(1.0, 1.0, -3.0)).length() < 1e-6,
        "{}",
        at(2)
    );
    assert!(
        s.warnings.iter().any(|w| w.contains("not quaternions")),
        "{:?}",
        s.warnings
    );
    let w = World::build(
        s,
        &WorldOptions {
            instancing: Instancing::Always,
            ..WorldOptions {
                default_light: Some(trayecto::scene::DefaultLight::Uniform),
                ..Default::default()
            }
        },
    )
    .unwrap();
    assert_eq!(w.geometry.instances.instances.len(), 3);
    assert_eq!(w.geometry.instances.meshes.len(), 1);
}
