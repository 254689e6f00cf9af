//! The default-lighting rule (`--default-light auto|on|off`, `light::default_light`): model files
//! whose only emitters are self-lit decals get the default environment and render lit; scenes lit
//! by their own lamps (Cornell boxes in every format, the emissive-strength cubes, furnaces of
//! dim emissive walls) are left exactly as they were.

mod common;

use std::process::Command;
use trayecto::light::Light;
use trayecto::light::default_light::DefaultLight;
use trayecto::material::Material;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::RenderSettings;
use trayecto::scene::{Object, Scene, Shape, builtin};
use trayecto::world::{World, WorldOptions};

fn build(scene: &Scene, mode: Option<DefaultLight>) -> World {
    World::build(
        scene.clone(),
        &WorldOptions {
            default_light: mode,
            ..Default::default()
        },
    )
    .expect("scene builds")
}

/// The default environment is there: the studio (an environment map: these tests give no
/// `--env`) or, with `uniform`, the white sky of radiance 1.
fn has_default_light(world: &World) -> bool {
    world.lights.lights.iter().any(|l| match l {
        Light::Uniform(u) => u.radiance == Vec3::ONE,
        Light::Environment(e) => e.map.width == trayecto::light::studio::STUDIO_WIDTH,
        _ => false,
    })
}

fn load(rel: &str) -> Scene {
    let p = common::shared_scene(rel);
    trayecto::scene::load(p.to_str().unwrap()).expect("loads")
}

fn mean_luminance(world: &World, n: u32, spp: u32) -> f32 {
    let img = common::render_world(
        world,
        &RenderSettings {
            width: n,
            height: n,
            spp,
            ..Default::default()
        },
    );
    let m = img.mean();
    assert!(m.is_finite(), "{m}");
    trayecto::math::luminance(m)
}

/// The decal models render lit with no options, several times brighter than by their decals
/// alone (`off`); the warning says why the environment was added.
#[test]
fn decal_models_are_lit_with_no_options() {
    for rel in [
        "gltf/DamagedHelmet/glTF-Binary/DamagedHelmet.glb",
        "gltf-ext/ToyCar/glTF/ToyCar.gltf",
        "gltf/TransmissionTest/glTF-Binary/TransmissionTest.glb",
    ] {
        let scene = load(rel);
        let auto = build(&scene, None);
        assert!(has_default_light(&auto), "{rel}: {:?}", auto.warnings);
        assert!(
            auto.warnings.iter().any(|w| w.contains("self-lit")),
            "{rel}: {:?}",
            auto.warnings
        );
        let off = build(&scene, Some(DefaultLight::Off));
        assert!(!has_default_light(&off), "{rel}");
        let (lit, dark) = (mean_luminance(&auto, 24, 2), mean_luminance(&off, 24, 2));
        assert!(
            lit > 0.05 && lit > 4.0 * dark,
            "{rel}: mean luminance {lit} with the default light, {dark} without"
        );
    }
}

/// Scenes lit by their own lamps keep exactly their lights: no default environment in auto.
#[test]
fn scenes_with_lamps_are_unchanged() {
    let mut scenes = vec![("built-in cornell".to_string(), builtin::cornell())];
    for rel in [
        "obj/cornell-box-original-data/cornell_box.obj",
        "fbx/cornell_seed_conventions.glb",
        "fbx/cornell_seed_conventions.fbx",
        "gltf/EmissiveStrengthTest/glTF-Binary/EmissiveStrengthTest.glb",
        "gltf/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf",
    ] {
        scenes.push((rel.to_string(), load(rel)));
    }
    for (name, scene) in &scenes {
        let auto = build(scene, None);
        let off = build(scene, Some(DefaultLight::Off));
        assert!(!has_default_light(&auto), "{name}: {:?}", auto.warnings);
        assert_eq!(
            auto.lights.lights.len(),
            off.lights.lights.len(),
            "{name}: auto and off differ"
        );
    }
}

/// A camera inside a sphere of dim (radiance 1) emissive walls — the white furnace of
/// `tests/path_estimator.rs` — is lit by its walls: their power rivals the environment's, so
/// auto adds nothing (a sky outside a closed room would only add noise).
#[test]
fn a_furnace_of_dim_emitters_is_not_a_decal() {
    let mut scene = Scene::default();
    let mut wall = Material::diffuse("wall", Vec3::splat(0.5));
    wall.emissive = Vec3::ONE;
    wall.double_sided = true;
    let m = scene.add_material(wall);
    scene.objects.push(Object {
        name: "furnace".into(),
        shape: Shape::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        transform: Mat4::IDENTITY,
        material: m,
        medium: None,
    });
    let world = build(&scene, None);
    assert!(!has_default_light(&world), "{:?}", world.warnings);
    // The same wall shrunk to a small disc-sized decal beside a big grey model is a decal.
    let mut decal_scene = scene.clone();
    decal_scene.objects[0].transform = Mat4::from_scale(Vec3::splat(0.05));
    let grey = decal_scene.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    decal_scene.objects.push(Object {
        name: "model".into(),
        shape: Shape::Cuboid {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        },
        transform: Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0)),
        material: grey,
        medium: None,
    });
    assert!(has_default_light(&build(&decal_scene, None)));
}

/// `on` adds the environment to a lamp-lit scene; the TOML key is honoured and the command line
/// wins over it.
#[test]
fn on_off_and_the_scene_file_key() {
    let cornell = builtin::cornell();
    assert!(has_default_light(&build(&cornell, Some(DefaultLight::On))));
    let dir = std::env::temp_dir().join(format!("trayecto-default-light-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let toml = "default_light = \"off\"\n\
                [[material]]\nname = \"grey\"\n\
                [[object]]\nname = \"ball\"\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"grey\"\n";
    let scene =
        trayecto::scene::toml_scene::load_from_bytes(toml.as_bytes(), &dir, "t.toml").unwrap();
    assert_eq!(scene.default_light, Some(DefaultLight::Off));
    let world = build(&scene, None);
    assert!(!has_default_light(&world));
    assert!(
        world.warnings.iter().any(|w| w.contains("renders black")),
        "{:?}",
        world.warnings
    );
    assert!(has_default_light(&build(&scene, Some(DefaultLight::Auto))));
    let bad = "default_light = \"sometimes\"\n";
    let Err(err) = trayecto::scene::toml_scene::load_from_bytes(bad.as_bytes(), &dir, "t.toml")
    else {
        panic!("an unknown mode is an error");
    };
    assert!(err.to_string().contains("default_light"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The command line: `--default-light off` and its alias `--no-default-light` leave a model without
/// lights black; a bad value is refused with the allowed values.
#[test]
fn command_line_modes() {
    let dir = std::env::temp_dir().join(format!("trayecto-dl-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = common::shared_scene("gltf/Box/glTF/Box.gltf");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            model.to_str().unwrap(),
            "-o",
            "out.hdr",
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
        ];
        args.extend_from_slice(extra);
        Command::new(env!("CARGO_BIN_EXE_trayecto"))
            .args(&args)
            .current_dir(&dir)
            .output()
            .unwrap()
    };
    for (extra, black) in [
        (&[][..], false),
        (&["--default-light", "off"][..], true),
        (&["--no-default-light"][..], true),
        (&["--default-light", "on"][..], false),
    ] {
        let o = run(extra);
        assert!(
            o.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let img = image::open(dir.join("out.hdr")).unwrap().to_rgb32f();
        let sum: f32 = img.pixels().map(|p| p.0.iter().sum::<f32>()).sum();
        assert_eq!(sum == 0.0, black, "{extra:?}: image sum {sum}");
    }
    let o = run(&["--default-light", "sometimes"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("auto") && err.contains("off"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The studio environment (the default) shows a white model's form: a white diffuse sphere, the
/// furnace case of a uniform sky (every point reflects radiance 1: contrast 0), is brighter on
/// the upper left than on the lower right, no part of it is black, and its shading varies across
/// it; `uniform` keeps the earlier flat sky.
#[test]
fn the_studio_gives_a_white_model_form() {
    let mut scene = Scene::default();
    let m = scene.add_material(Material::diffuse("white", Vec3::ONE));
    scene.objects.push(Object {
        name: "ball".into(),
        shape: Shape::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        transform: Mat4::IDENTITY,
        material: m,
        medium: None,
    });
    let n = 32;
    let shade = |mode: Option<DefaultLight>| {
        let img = common::render_world(
            &build(&scene, mode),
            &RenderSettings {
                width: n,
                height: n,
                spp: 16,
                ..Default::default()
            },
        );
        // The pixels well inside the sphere's disc (the automatic camera frames it), as
        // (column, row, luminance).
        let mut px = Vec::new();
        for y in 0..n {
            for x in 0..n {
                let (dx, dy) = (
                    x as f32 + 0.5 - n as f32 / 2.0,
                    y as f32 + 0.5 - n as f32 / 2.0,
                );
                if dx.hypot(dy) < 0.25 * n as f32 {
                    px.push((dx, dy, trayecto::math::luminance(img.get(x, y))));
                }
            }
        }
        px
    };
    let contrast = |px: &[(f32, f32, f32)]| {
        let mean = px.iter().map(|p| p.2).sum::<f32>() / px.len() as f32;
        let var = px.iter().map(|p| (p.2 - mean).powi(2)).sum::<f32>() / px.len() as f32;
        var.sqrt() / mean
    };
    let studio = shade(None);
    let uniform = shade(Some(DefaultLight::Uniform));
    assert!(contrast(&uniform) < 0.05, "uniform: {}", contrast(&uniform));
    assert!(contrast(&studio) > 0.2, "studio: {}", contrast(&studio));
    let quadrant = |px: &[(f32, f32, f32)], sx: f32, sy: f32| {
        let q: Vec<f32> = px
            .iter()
            .filter(|p| p.0 * sx > 0.0 && p.1 * sy > 0.0)
            .map(|p| p.2)
            .collect();
        q.iter().sum::<f32>() / q.len() as f32
    };
    let (upper_left, lower_right) = (quadrant(&studio, -1.0, -1.0), quadrant(&studio, 1.0, 1.0));
    assert!(
        upper_left > 1.5 * lower_right,
        "upper left {upper_left}, lower right {lower_right}"
    );
    let darkest = studio.iter().map(|p| p.2).fold(f32::MAX, f32::min);
    assert!(darkest > 0.15, "darkest {darkest}");
}
