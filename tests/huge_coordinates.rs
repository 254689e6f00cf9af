//! Finite but huge and degenerate coordinates in every mesh format (OBJ, PLY, glTF) load, build
//! the world and the BVH, and render without a panic (docs/DESIGN.md §7, never a panic); vertices
//! that cannot be bounded (NaN, infinities, literals beyond the range of f32) are dropped with a
//! warning naming the mesh.

mod common;

use base64::Engine;
use std::path::Path;
use trayecto::geometry::Ray;
use trayecto::math::Vec3;
use trayecto::render::RenderSettings;
use trayecto::scene::{Scene, load_bytes};
use trayecto::world::{World, WorldOptions};

/// Triangles every format below carries: a small visible one, ones at 1e20 (the coordinates that
/// made the BVH traversal index an empty node, u32::MAX), one spanning ±3e38 (its box's surface
/// area and the scene's bounding sphere overflow), one whose three vertices coincide far away,
/// and a collinear one.
const TRIANGLES: [[[f32; 3]; 3]; 6] = [
    [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
    [[1e20, 0.0, 0.0], [1e20, 1e20, 0.0], [0.0, 1e20, 1e20]],
    [
        [-1e20, -1e20, -1e20],
        [-1e20, 1.0, -1e20],
        [1.0, -1e20, 1e20],
    ],
    [[-3e38, -3e38, 0.0], [3e38, -3e38, 0.0], [0.0, 3e38, 3e38]],
    [[1e20, 1e20, 1e20], [1e20, 1e20, 1e20], [1e20, 1e20, 1e20]],
    [[0.0, 0.0, 0.0], [1e19, 1e19, 1e19], [2e19, 2e19, 2e19]],
];

fn settings() -> RenderSettings {
    RenderSettings {
        width: 8,
        height: 8,
        spp: 2,
        ..RenderSettings::default()
    }
}

/// Builds the world (the BVH included) and renders it; also traces rays from the origin and from
/// huge points in many directions, so both traversals (closest hit and shadow) see the tree.
fn build_and_render(scene: &Scene) -> World {
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .expect("scene builds");
    let image = common::render_world(&world, &settings());
    assert_eq!(image.data.len(), 64);
    for o in [Vec3::ZERO, Vec3::splat(1e20), Vec3::new(-3e38, 0.0, 3e38)] {
        for i in 0..64 {
            let a = i as f32 * 0.7;
            let d = Vec3::new(a.cos(), (a * 0.37).sin(), a.sin() * 0.5 - 0.1);
            let ray = Ray::new(o, d);
            let _ = world.intersect(&ray);
            let _ = world.occluded(&ray);
        }
    }
    // Rays that are not finite hit nothing (they used to walk into the BVH's empty lanes).
    for ray in [
        Ray::new(Vec3::splat(f32::NAN), Vec3::X),
        Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0)),
        Ray::new(Vec3::splat(f32::INFINITY), Vec3::Z),
    ] {
        assert!(world.intersect(&ray).is_none());
        assert!(!world.occluded(&ray));
    }
    world
}

fn obj_text(extra_vertices: &str) -> String {
    let mut s = String::from("o huge\n");
    for tri in TRIANGLES {
        for v in tri {
            s += &format!("v {:e} {:e} {:e}\n", v[0], v[1], v[2]);
        }
    }
    for t in 0..TRIANGLES.len() {
        s += &format!("f {} {} {}\n", 3 * t + 1, 3 * t + 2, 3 * t + 3);
    }
    s + extra_vertices
}

#[test]
fn obj_with_huge_and_degenerate_coordinates_renders() {
    let s = load_bytes(obj_text("").as_bytes(), Path::new("."), "huge.obj").unwrap();
    assert_eq!(s.triangle_count(), TRIANGLES.len());
    build_and_render(&s);
}

#[test]
fn obj_vertices_beyond_f32_are_dropped_with_a_warning() {
    // `1e39` is a finite literal but no f32; `nan` and `inf` parse as themselves.
    let n = 3 * TRIANGLES.len();
    let extra = format!(
        "v 1e39 0 0\nv nan 0 0\nv 0 inf 0\nv 0 0 1\nf {} {} {}\nf {} {} {}\nf 1 2 {}\n",
        n + 1,
        n + 4,
        n + 2,
        n + 3,
        n + 4,
        1,
        n + 4
    );
    let s = load_bytes(obj_text(&extra).as_bytes(), Path::new("."), "huge.obj").unwrap();
    assert_eq!(s.triangle_count(), TRIANGLES.len() + 1);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("not finite") && w.contains("2 triangle(s)")),
        "{:?}",
        s.warnings
    );
    build_and_render(&s);
}

#[test]
fn ply_with_huge_and_degenerate_coordinates_renders() {
    let n = 3 * TRIANGLES.len();
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        n + 1,
        TRIANGLES.len() + 1
    );
    for tri in TRIANGLES {
        for v in tri {
            s += &format!("{:e} {:e} {:e}\n", v[0], v[1], v[2]);
        }
    }
    s += "nan 0 0\n";
    for t in 0..TRIANGLES.len() {
        s += &format!("3 {} {} {}\n", 3 * t, 3 * t + 1, 3 * t + 2);
    }
    s += &format!("3 0 1 {n}\n");
    let scene = load_bytes(s.as_bytes(), Path::new("."), "huge.ply").unwrap();
    assert_eq!(scene.triangle_count(), TRIANGLES.len());
    assert!(
        scene.warnings.iter().any(|w| w.contains("not finite")),
        "{:?}",
        scene.warnings
    );
    build_and_render(&scene);
}

/// A glTF file with the triangles above in one emissive mesh (so the area lights and the light
/// sampler see them too), placed by a node with `scale`.
fn gltf(scale: f32) -> String {
    let mut buf = Vec::new();
    for tri in TRIANGLES {
        for v in tri {
            for c in v {
                buf.extend(c.to_le_bytes());
            }
        }
    }
    let n = 3 * TRIANGLES.len();
    for i in 0..n as u32 {
        buf.extend(i.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{pos}}},{{"buffer":0,"byteOffset":{pos},"byteLength":{idx}}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-3e38,-3e38,-1e20],"max":[3e38,3e38,3e38]}},
   {{"bufferView":1,"componentType":5125,"count":{n},"type":"SCALAR"}}],
 "materials":[{{"emissiveFactor":[1,1,1]}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
 "nodes":[{{"mesh":0,"scale":[{scale:e},{scale:e},{scale:e}]}},{{"mesh":0}}],
 "scenes":[{{"nodes":[0,1]}}]}}"#,
        len = buf.len(),
        pos = 12 * n,
        idx = 4 * n,
    )
}

#[test]
fn gltf_with_huge_and_degenerate_coordinates_renders() {
    let s = load_bytes(gltf(1.0).as_bytes(), Path::new("."), "huge.gltf").unwrap();
    let world = build_and_render(&s);
    // The small triangle of each node is a light; triangles whose area overflows are not.
    assert!(
        world.area_light_count() >= 2,
        "{}",
        world.area_light_count()
    );
}

#[test]
fn gltf_transform_that_overflows_drops_triangles_with_a_warning() {
    // Scaled by 1e30, every vertex but the origin leaves the range of f32.
    let s = load_bytes(gltf(1e30).as_bytes(), Path::new("."), "huge.gltf").unwrap();
    let world = build_and_render(&s);
    assert!(
        world
            .warnings
            .iter()
            .any(|w| w.contains("dropped") && w.contains("range of 32-bit floats")),
        "{:?}",
        world.warnings
    );
}
