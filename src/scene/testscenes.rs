//! Procedural scenes for the mode tests and the acceleration benchmark (they do not depend on any
//! loader): a textured multi-mesh scene in the spirit of the thesis's "wooden cube" (§5.3.6).

use super::{CameraDesc, LightDesc, Mesh, Scene, Shape};
use crate::material::texture::FilterMode;
use crate::material::{Material, MaterialModel, Texture, TextureRef, WrapMode};
use crate::math::{Mat4, Vec2, Vec3, Vec4};

/// A UV sphere of radius 1 with `rings × segments` quads, normals and texture coordinates.
pub fn uv_sphere(name: &str, rings: u32, segments: u32) -> Mesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let mut m = Mesh {
        name: name.to_string(),
        ..Default::default()
    };
    let (mut pos, mut nrm, mut uv) = (Vec::new(), Vec::new(), Vec::new());
    for r in 0..=rings {
        let v = r as f32 / rings as f32;
        let theta = v * std::f32::consts::PI;
        for s in 0..=segments {
            let u = s as f32 / segments as f32;
            let phi = u * std::f32::consts::TAU;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            );
            pos.push(n);
            nrm.push(n);
            uv.push(Vec2::new(u, v));
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let b = a + row;
            // Counter-clockwise seen from outside.
            if r != 0 {
                m.indices.push([a, b, a + 1]);
            }
            if r != rings - 1 {
                m.indices.push([a + 1, b, b + 1]);
            }
        }
    }
    m.positions = pos;
    m.normals = Some(nrm);
    m.uv0 = Some(uv);
    m
}

/// A `n × n` grid of quads (two triangles each) over [-1, 1]² in the xz plane, facing +y, with UVs.
pub fn grid_plane(name: &str, n: u32) -> Mesh {
    let n = n.max(1);
    let mut m = Mesh {
        name: name.to_string(),
        ..Default::default()
    };
    let mut uv = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            m.positions
                .push(Vec3::new(2.0 * u - 1.0, 0.0, 2.0 * v - 1.0));
            uv.push(Vec2::new(u, v));
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let b = a + n + 1;
            m.indices.push([a, b, a + 1]);
            m.indices.push([a + 1, b, b + 1]);
        }
    }
    m.normals = Some(vec![Vec3::Y; m.positions.len()]);
    m.uv0 = Some(uv);
    m
}

/// A checkerboard texture of `cells × cells` squares, `size` texels wide.
pub fn checker(name: &str, size: u32, cells: u32, a: Vec3, b: Vec3) -> Texture {
    let mut texels = Vec::with_capacity((size * size) as usize);
    for y in 0..size {
        for x in 0..size {
            let odd = (x * cells / size + y * cells / size) % 2 == 1;
            let c = if odd { a } else { b };
            texels.push(c.extend(1.0));
        }
    }
    Texture {
        name: name.to_string(),
        width: size,
        height: size,
        texels: texels.into(),
        wrap_s: WrapMode::Repeat,
        wrap_t: WrapMode::Repeat,
        filter: FilterMode::Bilinear,
        mipmap: true,
        mips: Vec::new(),
        procedural: None,
        layout: Default::default(),
    }
}

/// The benchmark scene: a textured ground, `k × k` textured spheres of `detail` rings (mixed
/// diffuse, glossy, mirror and glass), a box mesh and a mirrored (negative-scale) instance, lit by
/// a point light, a rectangular area light and an ambient light. About `2·k²·detail²` triangles.
pub fn textured_spheres(k: u32, detail: u32) -> Scene {
    let mut s = Scene {
        name: format!("textured-spheres-{k}x{k}-{detail}"),
        ..Default::default()
    };
    s.textures.push(checker(
        "wood",
        64,
        8,
        Vec3::new(0.45, 0.25, 0.1),
        Vec3::new(0.7, 0.5, 0.3),
    ));
    s.textures
        .push(checker("marble", 32, 4, Vec3::splat(0.9), Vec3::splat(0.2)));
    s.textures.push(Texture::constant("ao", Vec4::splat(0.7)));
    let mut ground = Material::diffuse("ground", Vec3::ONE);
    ground.base_color_texture = Some(TextureRef::new(0));
    ground.occlusion_texture = Some(TextureRef::new(2));
    let ground = s.add_material(ground);
    let mut glossy = Material::diffuse("glossy", Vec3::ONE);
    glossy.model = MaterialModel::metallic_roughness();
    glossy.roughness = 0.3;
    glossy.base_color_texture = Some(TextureRef::new(1));
    let glossy = s.add_material(glossy);
    let mut metal = Material::diffuse("metal", Vec3::new(0.9, 0.7, 0.4));
    metal.model = MaterialModel::metallic_roughness();
    metal.metallic = 1.0;
    metal.roughness = 0.2;
    let metal = s.add_material(metal);
    let mut mirror = Material::diffuse("mirror", Vec3::splat(0.95));
    mirror.model = MaterialModel::Mirror;
    let mirror = s.add_material(mirror);
    let mut glass = Material::diffuse("refractive glass", Vec3::ONE);
    glass.model = MaterialModel::dielectric();
    glass.ior = 1.4;
    let glass = s.add_material(glass);
    let diffuse = s.add_material(Material::diffuse("red", Vec3::new(0.7, 0.1, 0.1)));
    let mut lamp = Material::diffuse("emissive lamp", Vec3::ZERO);
    lamp.emissive = Vec3::splat(8.0);
    let lamp = s.add_material(lamp);

    let plane = s.add_mesh(grid_plane("ground", 4));
    s.add_object(
        "ground",
        Shape::Mesh(plane),
        Mat4::from_scale(Vec3::new(6.0, 1.0, 6.0)),
        ground,
    );
    let sphere = s.add_mesh(uv_sphere("ball", detail, 2 * detail));
    let mats = [glossy, metal, mirror, glass, diffuse];
    let k = k.max(1);
    for j in 0..k {
        for i in 0..k {
            let x = (i as f32 + 0.5) / k as f32 * 8.0 - 4.0;
            let z = (j as f32 + 0.5) / k as f32 * 8.0 - 4.0;
            let r = 2.8 / k as f32;
            let m = mats[((i + j * k) as usize) % mats.len()];
            s.add_object(
                &format!("ball {i} {j}"),
                Shape::Mesh(sphere),
                Mat4::from_translation(Vec3::new(x, r, z)) * Mat4::from_scale(Vec3::splat(r)),
                m,
            );
        }
    }
    // A mirrored instance: negative scale flips the winding, which the world must undo.
    s.add_object(
        "mirrored ball",
        Shape::Mesh(sphere),
        Mat4::from_translation(Vec3::new(0.0, 2.5, -5.0))
            * Mat4::from_scale(Vec3::new(-0.8, 0.8, 0.8)),
        glossy,
    );
    s.add_object(
        "box",
        Shape::Cuboid {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        },
        Mat4::from_translation(Vec3::new(4.5, 0.5, 4.5)) * Mat4::from_rotation_y(0.5),
        diffuse,
    );
    s.add_object(
        "lamp",
        Shape::Quad {
            corner: Vec3::new(-1.0, 6.0, -1.0),
            e1: Vec3::new(2.0, 0.0, 0.0),
            e2: Vec3::new(0.0, 0.0, 2.0),
        },
        Mat4::IDENTITY,
        lamp,
    );
    s.lights.push(LightDesc::Point {
        name: "key".into(),
        position: Vec3::new(3.0, 7.0, 6.0),
        intensity: Vec3::splat(40.0),
    });
    s.lights.push(LightDesc::Ambient {
        name: "ambient".into(),
        radiance: Vec3::splat(0.1),
    });
    s.cameras.push(CameraDesc::look_at(
        "main",
        Vec3::new(0.0, 6.0, 12.0),
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::Y,
        45.0,
    ));
    s
}
