//! glTF material extensions beyond the core (issue #17): each is read (no "not supported"
//! warning), files that require it load, malformed values are errors naming the file, and a
//! rendered check fails when the extension is ignored.

mod common;

use std::path::Path;
use trayecto::material::Material;
use trayecto::math::luminance;
use trayecto::render::RenderSettings;
use trayecto::scene::{Scene, gltf};
use trayecto::world::{World, WorldOptions};

/// A one-triangle glTF (positions only, in a data URI) with `materials` and `extra` spliced in.
fn triangle(materials: &str, extra: &str) -> String {
    use base64::Engine;
    let mut buf = Vec::new();
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        buf.extend(c.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteLength":36}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],
 "materials":[{materials}]{extra}}}"#
    )
}

fn load(json: &str) -> Result<Scene, trayecto::scene::SceneError> {
    gltf::load_from_bytes(json.as_bytes(), Path::new("."), "test.gltf")
}

fn unsupported(scene: &Scene) -> Vec<&String> {
    scene
        .warnings
        .iter()
        .filter(|w| w.contains("not supported"))
        .collect()
}

#[test]
fn clearcoat_is_read_and_files_requiring_it_load() {
    let json = triangle(
        r#"{"name":"varnish","extensions":{"KHR_materials_clearcoat":
            {"clearcoatFactor":0.7,"clearcoatRoughnessFactor":0.2}}}"#,
        r#","extensionsUsed":["KHR_materials_clearcoat"],"extensionsRequired":["KHR_materials_clearcoat"]"#,
    );
    let scene = load(&json).expect("a file requiring KHR_materials_clearcoat loads");
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let m: &Material = &scene.materials[0];
    assert_eq!((m.clearcoat, m.clearcoat_roughness), (0.7, 0.2));
    assert!(m.clearcoat_texture.is_none() && m.clearcoat_normal_texture.is_none());

    // A required extension that nothing reads blocks the file, by name.
    let json = triangle(
        r#"{"name":"m"}"#,
        r#","extensionsUsed":["EXT_made_up"],"extensionsRequired":["EXT_made_up"]"#,
    );
    let Err(err) = load(&json) else {
        panic!("EXT_made_up blocks the file");
    };
    let msg = err.to_string();
    assert!(
        msg.contains("test.gltf") && msg.contains("'EXT_made_up'") && msg.contains("requires"),
        "{msg}"
    );

    for (bad, what) in [
        (r#"{"clearcoatFactor":"much"}"#, "clearcoatFactor"),
        (
            r#"{"clearcoatRoughnessFactor":2.5}"#,
            "clearcoatRoughnessFactor",
        ),
        (
            r#"{"clearcoatFactor":1,"clearcoatTexture":{"index":7}}"#,
            "clearcoat texture",
        ),
        (
            r#"{"clearcoatFactor":1,"clearcoatNormalTexture":{}}"#,
            "clearcoatNormal texture",
        ),
    ] {
        let json = triangle(
            &format!(r#"{{"name":"m","extensions":{{"KHR_materials_clearcoat":{bad}}}}}"#),
            "",
        );
        let err = load(&json).err().unwrap_or_else(|| panic!("{bad} loads"));
        let msg = err.to_string();
        assert!(
            msg.contains("test.gltf") && msg.contains(what),
            "{bad}: {msg}"
        );
    }
}

/// Mean luminance over the pixels where the model is (the ray caster's depth view is 0 where a
/// camera ray escapes): the uniform background would dilute any difference.
fn model_luminance(scene: &Scene, n: u32, spp: u32) -> f32 {
    use trayecto::integrator::IntegratorKind;
    use trayecto::integrator::{Aov, ShadingModel};
    let world = World::build(scene.clone(), &WorldOptions::default()).unwrap();
    let settings = |spp, integrator| RenderSettings {
        width: n,
        height: n,
        spp,
        integrator,
        ..Default::default()
    };
    let depth = common::render_world(
        &world,
        &settings(
            1,
            IntegratorKind::Raycast {
                aov: Aov::Depth,
                shading: ShadingModel::Pbr,
            },
        ),
    );
    let img = common::render_world(&world, &settings(spp, IntegratorKind::default()));
    let on: Vec<usize> = (0..img.data.len())
        .filter(|&i| depth.data[i].x > 0.0)
        .collect();
    assert!(
        on.len() > img.data.len() / 10,
        "{} pixels on the model",
        on.len()
    );
    on.iter().map(|&i| luminance(img.data[i])).sum::<f32>() / on.len() as f32
}

/// ClearcoatWicker (README): "a wicker material covered with a wrinkled plastic clearcoat". The
/// coat, its roughness and its own normal map are read; under the default white environment the
/// coat reflects its Fresnel share c·fr of the sky where the brown wicker would have absorbed
/// most of it, so the sphere is measurably brighter than with the coat removed.
#[test]
fn clearcoat_wicker_is_coated() {
    let p = common::shared_scene("gltf-ext/ClearcoatWicker/glTF/ClearcoatWicker.gltf");
    let scene = trayecto::scene::load(p.to_str().unwrap()).unwrap();
    assert!(unsupported(&scene).is_empty(), "{:?}", scene.warnings);
    let m = &scene.materials[0];
    assert_eq!(m.clearcoat, 1.0);
    assert!((m.clearcoat_roughness - 0.1).abs() < 1e-6);
    assert!(m.clearcoat_normal_texture.is_some() && m.normal_texture.is_some());
    let mut bare = scene.clone();
    bare.materials[0].clearcoat = 0.0;
    let (with, without) = (
        model_luminance(&scene, 32, 16),
        model_luminance(&bare, 32, 16),
    );
    eprintln!("ClearcoatWicker mean luminance: coated {with}, coat removed {without}");
    assert!(
        with > 1.05 * without,
        "coated {with} is not brighter than without the coat {without}"
    );
}
