//! OBJ/MTL, PLY and the native TOML format: the shared sample files load and render, the
//! repository's example is valid, and a glTF and its TOML twin give the same image.

mod common;

use std::path::Path;

use trayecto::math::Vec3;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::Scene;
use trayecto::world::{World, WorldOptions};

fn render_small(scene: &Scene, size: u32, spp: u32) -> Vec<Vec3> {
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let settings = RenderSettings {
        width: size,
        height: size,
        spp,
        seed: 7,
        ..Default::default()
    };
    let cancel = std::sync::atomic::AtomicBool::new(false);
    render(&world, &settings, &NoObserver, &cancel)
        .unwrap()
        .image
        .data
}

fn mean(img: &[Vec3]) -> Vec3 {
    img.iter().copied().sum::<Vec3>() / img.len() as f32
}

fn repo_file(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn obj_cornell_box_loads_with_its_materials_and_renders() {
    let p = common::scene_file("obj/cornell-box-original-data/cornell_box.obj");
    let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
    let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
    for n in ["white", "red", "green", "light"] {
        assert!(names.contains(&n), "{names:?}");
    }
    let red = scene.materials.iter().find(|m| m.name == "red").unwrap();
    assert_eq!(red.base_color, Vec3::new(1.0, 0.0, 0.0));
    assert!(scene.triangle_count() >= 30, "{}", scene.triangle_count());
    let b = scene.bounds();
    assert!(b.max.x > 500.0 && b.max.y > 500.0, "millimetres: {b:?}");
}

/// The light of cornell_box.mtl is `Ka 20 20 20` with no `Ke` (the legacy convention): it emits,
/// with a warning, and the box renders lit by it alone, seen through its open side (the automatic
/// camera turns to −z, where the front faces are): the ceiling light is the brightest thing in
/// view, the red wall on the left and the green wall on the right, as in the original photograph.
#[test]
fn obj_cornell_box_is_lit_by_its_own_light() {
    let p = common::scene_file("obj/cornell-box-original-data/cornell_box.obj");
    let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
    let light = scene.materials.iter().find(|m| m.name == "light").unwrap();
    assert_eq!(light.emissive, Vec3::splat(20.0));
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("Ka") && w.contains("emitted radiance")),
        "{:?}",
        scene.warnings
    );
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    // Lit by its own light: no default environment was added.
    assert!(
        world.area_light_count() >= 2,
        "{}",
        world.area_light_count()
    );
    assert!(
        !world.warnings.iter().any(|w| w.contains("no lights")),
        "{:?}",
        world.warnings
    );
    let n = 48usize;
    let settings = RenderSettings {
        width: n as u32,
        height: n as u32,
        spp: 16,
        seed: 7,
        ..Default::default()
    };
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let img = render(&world, &settings, &NoObserver, &cancel)
        .unwrap()
        .image;
    let px = |x: usize, y: usize| img.data[y * n + x];
    // The brightest pixel is the light (radiance 20), in the top third, near the middle.
    let (bi, bv) = img
        .data
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.x.total_cmp(&b.1.x))
        .unwrap();
    let (bx, by) = (bi % n, bi / n);
    assert!(bv.min_element() > 10.0, "brightest {bv}");
    assert!(
        by < n / 3 && bx.abs_diff(n / 2) < n / 6,
        "light seen at ({bx}, {by})"
    );
    // Walls at mid-height: the left strip is red, the right strip green.
    let strip = |x0: usize, x1: usize| {
        let mut s = Vec3::ZERO;
        for y in n / 3..2 * n / 3 {
            for x in x0..x1 {
                s += px(x, y);
            }
        }
        s / ((x1 - x0) * (n / 3)) as f32
    };
    // The box fills the middle of the frame (the camera fits its bounding sphere): its walls are
    // the outer 12 % of the lit span of the middle row.
    let lit: Vec<usize> = (0..n)
        .filter(|&x| px(x, n / 2).max_element() > 0.0)
        .collect();
    let (x0, x1) = (lit[0], lit[lit.len() - 1] + 1);
    let k = (x1 - x0) * 12 / 100;
    let (left, right) = (strip(x0, x0 + k), strip(x1 - k, x1));
    assert!(
        left.x > 3.0 * left.y && left.x > 3.0 * left.z,
        "left wall {left}"
    );
    assert!(
        right.y > 3.0 * right.x && right.y > 3.0 * right.z,
        "right wall {right}"
    );
    // Lit, but far from the light's radiance: the walls' level is set by the light alone.
    assert!(left.x > 0.05 && left.x < 10.0, "left wall {left}");
}

#[test]
fn mtl_fields_map_to_the_material() {
    let dir = std::env::temp_dir().join(format!("trayecto_mtl_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl glow\nKd 0.5 0.5 0.5\nKe 2 1 0\n\
         newmtl glass\nKd 1 1 1\nNi 1.5\nd 0.2\nillum 7\n\
         newmtl metal\nKd 0.9 0.8 0.7\nPr 0.25\nPm 1\nKs 0.5 0.5 0.5\nNs 64\nmap_Kd missing.png\n\
         newmtl emissive_thing\nKd 0.2 0.4 0.6\n",
    )
    .unwrap();
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
               usemtl glow\nf 1 2 3\nusemtl glass\nf 2 4 3\nusemtl metal\nf 1 2 4\n\
               usemtl emissive_thing\nf 1 3 4\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let s = trayecto::scene::load(dir.join("m.obj").to_str().unwrap()).unwrap();
    let get = |n: &str| s.materials.iter().find(|m| m.name == n).unwrap();
    assert_eq!(get("glow").emissive, Vec3::new(2.0, 1.0, 0.0));
    assert!(get("glass").model.is_dielectric());
    assert_eq!(get("glass").ior, 1.5);
    assert!((get("glass").alpha - 0.2).abs() < 1e-6);
    let metal = get("metal");
    assert!(metal.model.is_metallic_roughness());
    assert_eq!((metal.roughness, metal.metallic), (0.25, 1.0));
    assert_eq!(metal.phong.unwrap().shininess, 64.0);
    assert!(metal.base_color_texture.is_some(), "magenta fallback kept");
    assert!(s.warnings.iter().any(|w| w.contains("missing.png")));
    // The thesis's convention: emits its diffuse colour × 5.
    assert_eq!(get("emissive_thing").emissive, Vec3::new(1.0, 2.0, 3.0));

    // A material library outside the folder is refused, naming the file.
    std::fs::write(
        dir.join("bad.obj"),
        "mtllib ../evil.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = trayecto::scene::load(dir.join("bad.obj").to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.obj") && e.contains(".."), "{e}");
    // Out-of-range face indices are an error, not a panic.
    std::fs::write(dir.join("idx.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let e = trayecto::scene::load(dir.join("idx.obj").to_str().unwrap()).unwrap_err();
    assert!(e.to_string().contains("idx.obj"), "{e}");
    // A NaN position cannot be bounded: its triangle is dropped with a warning naming the mesh
    // (docs/DESIGN.md §7), never a panic; the one beside it stays.
    std::fs::write(
        dir.join("nan.obj"),
        "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 1 0 0\nf 1 2 3\nf 1 4 3\n",
    )
    .unwrap();
    let s = trayecto::scene::load(dir.join("nan.obj").to_str().unwrap()).unwrap();
    assert_eq!(s.triangle_count(), 1);
    assert!(
        s.warnings.iter().any(|w| w.contains("not finite")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn ply_bunnies_load_and_render() {
    for (f, tris) in [
        ("bun_zipper_res4.ply", 948),
        ("bun_zipper_res3.ply", 3851),
        ("bun_zipper_res2.ply", 16301),
        ("bun_zipper.ply", 69451),
    ] {
        let p = common::scene_file(&format!("ply/stanford-bunny/{f}"));
        let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
        assert_eq!(scene.triangle_count(), tris, "{f}");
    }
    let p = common::scene_file("ply/stanford-bunny/bun_zipper_res2.ply");
    let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
    let img = render_small(&scene, 32, 2);
    // The auto camera frames the bunny: a good part of the frame is covered (not white sky).
    let covered = img
        .iter()
        .filter(|c| (**c - Vec3::ONE).length() > 0.05)
        .count();
    assert!(
        covered > img.len() / 5,
        "bunny covers {covered} of {} pixels",
        img.len()
    );
}

#[test]
fn example_toml_is_valid_and_uses_every_kind_of_object() {
    let scene = trayecto::scene::load(&repo_file("scenes/example.toml")).unwrap();
    use trayecto::scene::{LightDesc, Shape};
    let has = |f: &dyn Fn(&Shape) -> bool| scene.objects.iter().any(|o| f(&o.shape));
    assert!(has(&|s| matches!(s, Shape::Mesh(_))));
    assert!(has(&|s| matches!(s, Shape::Sphere { .. })));
    assert!(has(&|s| matches!(s, Shape::Cuboid { .. })));
    assert!(has(&|s| matches!(s, Shape::Quad { .. })));
    assert_eq!(scene.cameras.len(), 2);
    assert!(
        scene
            .lights
            .iter()
            .any(|l| matches!(l, LightDesc::Spot { .. }))
    );
    assert!(
        scene
            .lights
            .iter()
            .any(|l| matches!(l, LightDesc::Ambient { .. }))
    );
    let panel = scene
        .materials
        .iter()
        .find(|m| m.name == "emissive_panel")
        .unwrap();
    assert!(panel.is_emissive(), "naming convention applies to TOML");
    let img = render_small(&scene, 32, 2);
    assert!(mean(&img).max_element() > 1e-3);
}

#[test]
fn toml_errors_name_the_file_and_the_problem() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let cases = [
        (
            "[[object]]\ntype = \"sphere\"\ncenter = [0,0,0]\n",
            "radius",
        ),
        ("[[object]]\ntype = \"blob\"\n", "unknown type"),
        (
            "[[object]]\ntype = \"mesh\"\nfile = \"../../etc/passwd.ply\"\n",
            "..",
        ),
        ("[[material]]\nname = \"a\"\ncolour = [1,0,0]\n", "colour"),
        (
            "[[object]]\ntype = \"sphere\"\ncenter = [0,0,0]\nradius = -1\n",
            "invalid shape",
        ),
        (
            "[[object]]\ntype = \"quad\"\ncorner = [0,0,0]\ne1=[1,0,0]\ne2=[0,1,0]\nmaterial=\"x\"\n",
            "not defined",
        ),
        ("not toml at all [", ""),
    ];
    for (text, needle) in cases {
        let e = trayecto::scene::load_bytes(text.as_bytes(), &dir, "bad.toml")
            .expect_err(text)
            .to_string();
        assert!(e.starts_with("bad.toml:") && e.contains(needle), "{e}");
    }
}

/// docs/DESIGN.md §8: a glTF and a TOML description of the same scene produce the same image for the same
/// seed. The two differ only in how the camera matrix is computed (a node transform vs a
/// look-at), i.e. by rounding, so nearly every pixel must agree to 1e-4 relative.
#[test]
fn gltf_and_toml_twins_render_the_same_image() {
    let g = trayecto::scene::load(&repo_file("scenes/twin/twin.gltf")).unwrap();
    let t = trayecto::scene::load(&repo_file("scenes/twin/twin.toml")).unwrap();
    assert_eq!(g.triangle_count(), t.triangle_count());
    let (a, b) = (render_small(&g, 48, 4), render_small(&t, 48, 4));
    let ma = mean(&a);
    assert!(ma.max_element() > 1e-2, "lit by the point light: {ma}");
    let close = a
        .iter()
        .zip(&b)
        .filter(|(x, y)| (**x - **y).abs().max_element() <= 1e-4 * (1.0 + x.max_element()))
        .count();
    assert!(
        close * 100 >= a.len() * 99,
        "{close} of {} pixels agree",
        a.len()
    );
    let mb = mean(&b);
    assert!(
        (ma - mb).abs().max_element() <= 1e-3 * ma.max_element(),
        "{ma} vs {mb}"
    );
}

/// A TOML scene that includes a glTF gets the glTF's lights and cameras, moved by the object's
/// transform (rotation and translation; the scale moves positions only), with the TOML's own
/// cameras first and the included ones selectable by name or index.
#[test]
fn toml_includes_lights_and_cameras_of_mesh_files() {
    use base64::Engine;
    use trayecto::scene::{LightDesc, SpotFalloff};
    let dir = std::env::temp_dir().join(format!("trayecto_toml_incl_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // One white floor triangle (y = 0, facing +y), a camera 3 above it looking down, a point light 1
    // above it and a spot pointing down −y (its default direction, −z, turned by −90° about x).
    let mut buf = Vec::new();
    for c in [-2.0f32, 0.0, 2.0, 2.0, 0.0, 2.0, 0.0, 0.0, -2.0] {
        buf.extend(c.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_lights_punctual"],
 "extensions":{{"KHR_lights_punctual":{{"lights":[
   {{"type":"point","intensity":683,"name":"bulb"}},
   {{"type":"spot","intensity":683,"name":"spot","spot":{{"outerConeAngle":0.5}}}}]}}}},
 "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteLength":36}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-2,0,-2],"max":[2,0,2]}}],
 "materials":[{{"pbrMetallicRoughness":{{"metallicFactor":0}}}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}}],
 "cameras":[{{"type":"perspective","name":"top","perspective":{{"yfov":0.8,"znear":0.1}}}}],
 "nodes":[{{"mesh":0}},
   {{"name":"top","camera":0,"translation":[0,3,0],"rotation":[{n},0,0,{s}]}},
   {{"name":"bulb","translation":[0,1,0],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}},
   {{"name":"spot","translation":[0,1,0],"rotation":[{n},0,0,{s}],"extensions":{{"KHR_lights_punctual":{{"light":1}}}}}}],
 "scenes":[{{"nodes":[0,1,2,3]}}],"scene":0}}"#,
        n = -s
    );
    std::fs::write(dir.join("lamp.gltf"), gltf).unwrap();
    let toml = r#"
[[camera]]
name = "front"
eye = [0.0, 1.0, 8.0]
target = [0.0, 0.0, 0.0]
fov = 40.0

[[object]]
name = "lamp"
type = "mesh"
file = "lamp.gltf"
translate = [10.0, 0.0, 0.0]
rotate = [0.0, 0.0, 90.0]
scale = 2.0
"#;
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    let scene = trayecto::scene::load(dir.join("scene.toml").to_str().unwrap()).unwrap();
    assert!(
        !scene.warnings.iter().any(|w| w.contains("ignored")),
        "{:?}",
        scene.warnings
    );
    // Rotating by 90° about z sends +y to −x; scale 2 then translate (10, 0, 0):
    // the bulb at (0, 1, 0) ends at (8, 0, 0), and "down" (−y) becomes +x.
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-4;
    let bulb = scene.lights.iter().find(|l| l.name() == "bulb").unwrap();
    match bulb {
        LightDesc::Point {
            position,
            intensity,
            ..
        } => {
            assert!(close(*position, Vec3::new(8.0, 0.0, 0.0)), "{position}");
            // 683 cd / 683 lm/W; the scale does not change it.
            assert!(close(*intensity, Vec3::ONE), "{intensity}");
        }
        other => panic!("{other:?}"),
    }
    match scene.lights.iter().find(|l| l.name() == "spot").unwrap() {
        LightDesc::Spot {
            position,
            direction,
            ..
        } => {
            assert!(close(*position, Vec3::new(8.0, 0.0, 0.0)), "{position}");
            assert!(close(direction.normalize(), Vec3::X), "{direction}");
        }
        other => panic!("{other:?}"),
    }
    // Cameras: the TOML's first, then the glTF's, moved: at (4, 0, 0) after the transform,
    // looking along +x (its −y view turned by the rotation).
    let names: Vec<&str> = scene.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["front", "top"]);
    let top = &scene.cameras[1].camera_to_world;
    assert!(close(
        top.transform_point3(Vec3::ZERO),
        Vec3::new(4.0, 0.0, 0.0)
    ));
    assert!(close(top.transform_vector3(-Vec3::Z), Vec3::X));
    for sel in ["top", "1"] {
        let world = World::build(
            scene.clone(),
            &WorldOptions {
                camera: Some(sel.into()),
                default_light: Some(trayecto::light::default_light::DefaultLight::Off),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(world.camera.name, "top");
        // Lit by the included lights only (unlit, it would be black): the render must equal that
        // of the same scene with the two lights written out here by hand (from the glTF values
        // and the transform above), at the same seed. A light lost on the way from the file to
        // the world darkens the image (on axis, each gives the floor 1/4 W/m²; the spot's cone
        // covers less of the view).
        let settings = RenderSettings {
            width: 8,
            height: 8,
            spp: 64,
            ..Default::default()
        };
        let cancel = std::sync::atomic::AtomicBool::new(false);
        let mean = |scene: &trayecto::scene::Scene| {
            let world = World::build(
                scene.clone(),
                &WorldOptions {
                    camera: Some(sel.into()),
                    default_light: Some(trayecto::light::default_light::DefaultLight::Off),
                    ..Default::default()
                },
            )
            .unwrap();
            let img = render(&world, &settings, &NoObserver, &cancel)
                .unwrap()
                .image;
            img.data.iter().copied().sum::<Vec3>() / img.data.len() as f32
        };
        assert_eq!(world.camera.name, "top");
        let got = mean(&scene);
        let mut by_hand = scene.clone();
        let point = LightDesc::Point {
            name: "bulb".into(),
            position: Vec3::new(8.0, 0.0, 0.0),
            intensity: Vec3::ONE,
        };
        let spot = LightDesc::Spot {
            name: "spot".into(),
            position: Vec3::new(8.0, 0.0, 0.0),
            direction: Vec3::X,
            intensity: Vec3::ONE,
            inner_angle: 0.0,
            outer_angle: 0.5,
            falloff: SpotFalloff::SquaredRamp,
        };
        by_hand.lights = vec![point.clone(), spot.clone()];
        let expected = mean(&by_hand);
        by_hand.lights = vec![point];
        let bulb_only = mean(&by_hand);
        by_hand.lights = vec![spot];
        let spot_only = mean(&by_hand);
        println!(
            "included lights: image mean {got}, by hand {expected}; bulb only {bulb_only}, spot only {spot_only}"
        );
        // Same seed, same scene: only the rounding of the include's transform separates the two.
        let tolerance = 0.005;
        assert!(
            ((got - expected) / expected).abs().max_element() < tolerance,
            "camera {sel}: image mean {got}, with the lights written by hand {expected}"
        );
        // The test can tell a missing light: each one's share of the image is far above that.
        for alone in [bulb_only, spot_only] {
            assert!(
                (alone / expected).max_element() < 1.0 - 10.0 * tolerance,
                "one light {alone} vs both {expected}"
            );
        }
    }
}

/// A TOML scene that includes glTF files shifts every texture index of the included materials,
/// the KHR extensions' slots too (clearcoat, sheen, …): ClearcoatWicker included after a file with
/// a texture of its own must reference the same images as ClearcoatWicker loaded alone.
#[test]
fn included_gltf_extension_textures_keep_their_images() {
    let dir = std::env::temp_dir().join(format!("trayecto_include_tex_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for (from, to) in [
        ("gltf/BoxTextured/glTF", "box"),
        ("gltf-ext/ClearcoatWicker/glTF", "wicker"),
    ] {
        let src = common::shared_dir().join("scenes").join(from);
        std::fs::create_dir_all(dir.join(to)).unwrap();
        for e in std::fs::read_dir(&src).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dir.join(to).join(e.file_name())).unwrap();
        }
    }
    let toml = dir.join("both.toml");
    std::fs::write(
        &toml,
        "[[object]]\ntype = \"mesh\"\nfile = \"box/BoxTextured.gltf\"\n\n\
         [[object]]\ntype = \"mesh\"\nfile = \"wicker/ClearcoatWicker.gltf\"\n",
    )
    .unwrap();
    let alone = trayecto::scene::load_file(&dir.join("wicker/ClearcoatWicker.gltf")).unwrap();
    let both = trayecto::scene::load_file(&toml).unwrap();
    let texels = |s: &trayecto::scene::Scene, t: &trayecto::material::TextureRef| {
        let tex = &s.textures[t.texture];
        (tex.width, tex.height, tex.texels.get(tex.texels.len() / 3))
    };
    let mut checked = 0;
    for m in &alone.materials {
        let Some(inc) = both.materials.iter().find(|b| b.name == m.name) else {
            panic!("material '{}' missing from the TOML scene", m.name);
        };
        let (a, b): (Vec<_>, Vec<_>) = (m.texture_refs().collect(), inc.texture_refs().collect());
        assert_eq!(a.len(), b.len(), "{}", m.name);
        for (ta, tb) in a.iter().zip(&b) {
            assert_eq!(texels(&alone, ta), texels(&both, tb), "{}", m.name);
            checked += 1;
        }
        if m.metallic_roughness().clearcoat_normal_texture.is_some() {
            assert!(
                inc.metallic_roughness()
                    .clearcoat_normal_texture
                    .unwrap()
                    .texture
                    >= 1,
                "not shifted"
            );
        }
    }
    assert!(
        alone
            .materials
            .iter()
            .any(|m| m.metallic_roughness().clearcoat_normal_texture.is_some()),
        "ClearcoatWicker should have a clearcoat normal texture"
    );
    assert!(checked >= 4, "{checked}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A TOML scene opened by a relative path (`trayecto info d/x.toml`) finds its environment map
/// beside it: the loader resolves the file against the scene's folder and the world used to join
/// that folder again (`d/d/map.hdr`).
#[test]
fn environment_map_of_a_scene_opened_by_a_relative_path_is_found() {
    let rel = Path::new("target")
        .join("tmp")
        .join(format!("env_relative_{}", std::process::id()));
    let d = rel.join("d");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::copy(
        repo_file("../shared/scenes/hdr/studio_small_03_1k.hdr"),
        d.join("map.hdr"),
    )
    .unwrap();
    std::fs::write(
        d.join("x.toml"),
        r#"[[light]]
type = "environment"
file = "map.hdr"

[[object]]
type = "sphere"
center = [0, 0, -3]
radius = 1
"#,
    )
    .unwrap();
    assert!(d.is_relative());
    let scene = trayecto::scene::load_file(&d.join("x.toml")).unwrap();
    let world = World::build(
        scene,
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    );
    std::fs::remove_dir_all(&rel).unwrap();
    let world = world.unwrap();
    assert!(
        matches!(world.lights(), [trayecto::light::Light::Environment(_)]),
        "the environment map is the one light"
    );
}

/// Validation runs once, when a scene is loaded (docs/DESIGN.md §3), and `World::build` trusts a
/// loaded scene; `select_variant` may still move objects to a variant's material afterwards. So
/// `Scene::validate` must check the variants' materials and media too, not only the objects'.
/// (Checked to fail: with the variant loop removed from `Scene::validate`, both scenes validate.)
#[test]
fn material_variants_are_validated_with_the_scene() {
    use trayecto::scene::{MediumInterface, ObjectVariants};
    let base = trayecto::scene::load("cornell").unwrap();
    let n = base.materials.len();
    let variant = |material: usize, medium: Option<MediumInterface>| {
        let mut s = base.clone();
        s.variants = vec!["v".into()];
        s.variant_objects = vec![ObjectVariants {
            object: 0,
            default: (s.objects[0].material, None),
            by_variant: vec![(0, material, medium)],
        }];
        s
    };
    assert!(variant(n - 1, None).validate().is_ok());
    let e = variant(n, None).validate().unwrap_err().to_string();
    assert!(
        e.contains("variant") && e.contains(&format!("material {n}")),
        "{e}"
    );
    let missing = MediumInterface {
        inside: Some(7),
        outside: None,
    };
    assert!(variant(0, Some(missing)).validate().is_err());
}

/// A folder given as the scene is named as a folder, with the next step, whether or not its name
/// has an extension (it said "the file has no extension" for `/tmp`).
/// (Checked to fail: without the `is_dir` test in `scene::load`, the first case says "no extension".)
#[test]
fn a_folder_given_as_the_scene_is_called_a_folder() {
    let dir = std::env::temp_dir().join(format!("trayecto-folder-{}", std::process::id()));
    for d in [dir.join("plain"), dir.join("looks.gltf")] {
        std::fs::create_dir_all(&d).unwrap();
        let e = trayecto::scene::load(d.to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(d.to_str().unwrap())
                && e.contains("is a folder; give a scene file inside it"),
            "{e}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
