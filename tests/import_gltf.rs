//! glTF import: node transforms, negative scale, texture-coordinate sets, sRGB vs linear textures,
//! missing textures, hostile files, punctual lights, and every Khronos sample model rendering.

mod common;

use std::path::{Path, PathBuf};

use base64::Engine;
use glam::Quat;
use trayecto::material::texture::srgb_to_linear;
use trayecto::math::{Mat4, Vec3};
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene::{LightDesc, Scene, gltf};
use trayecto::world::{World, WorldOptions};

/// A one-triangle glTF with POSITION, TEXCOORD_0, TEXCOORD_1 and u32 indices in a data URI.
/// `extra` is spliced into the top-level object (materials, textures, nodes, …).
fn triangle_gltf(positions: [[f32; 3]; 3], indices: [u32; 3], extra: &str) -> String {
    let mut buf = Vec::new();
    for p in positions {
        for c in p {
            buf.extend(c.to_le_bytes());
        }
    }
    for uv in [[0.0f32, 0.0], [1.0, 0.0], [0.0, 1.0]] {
        for c in uv {
            buf.extend(c.to_le_bytes());
        }
    }
    for uv in [[0.25f32, 0.25], [0.75, 0.25], [0.25, 0.75]] {
        for c in uv {
            buf.extend(c.to_le_bytes());
        }
    }
    for i in indices {
        buf.extend(i.to_le_bytes());
    }
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}},
   {{"buffer":0,"byteOffset":60,"byteLength":24}},{{"buffer":0,"byteOffset":84,"byteLength":12}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
   {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}},
   {{"bufferView":2,"componentType":5126,"count":3,"type":"VEC2"}},
   {{"bufferView":3,"componentType":5125,"count":3,"type":"SCALAR"}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1,"TEXCOORD_1":2}},"indices":3,"material":0}}]}}],
 {extra}}}"#,
        len = buf.len()
    )
}

const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
const PLAIN_MATERIAL: &str = r#""materials":[{"name":"m"}]"#;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto_import_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn load_str(json: &str, dir: &Path) -> Result<Scene, trayecto::scene::SceneError> {
    // Parsed and validated as a file on disk would be.
    trayecto::scene::load_bytes(json.as_bytes(), dir, "test.gltf")
}

fn render_small(scene: &Scene, size: u32, spp: u32, no_default_light: bool) -> Vec<Vec3> {
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            // (Else the uniform white sky these checks were written for, not the studio.)
            default_light: Some(if no_default_light {
                trayecto::light::default_light::DefaultLight::Off
            } else {
                trayecto::light::default_light::DefaultLight::Uniform
            }),
            ..Default::default()
        },
    )
    .unwrap();
    let settings = RenderSettings {
        width: size,
        height: size,
        spp,
        ..Default::default()
    };
    let cancel = std::sync::atomic::AtomicBool::new(false);
    render(&world, &settings, &NoObserver, &cancel)
        .unwrap()
        .image
        .data
}

#[test]
fn node_transforms_compose_parent_then_child() {
    let extra = format!(
        r#"{PLAIN_MATERIAL},
 "nodes":[{{"children":[1],"translation":[1,2,3]}},
          {{"mesh":0,"rotation":[0,0,0.70710678,0.70710678],"scale":[2,2,2]}}],
 "scenes":[{{"nodes":[0]}}],"scene":0"#
    );
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], &extra), Path::new(".")).unwrap();
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let expected = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))
        * Mat4::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
            Vec3::ZERO,
        );
    let t = &world.geometry.triangles[0];
    for (got, local) in [t.p0, t.p1, t.p2].into_iter().zip(TRI) {
        let want = expected.transform_point3(Vec3::from(local));
        assert!((got - want).length() < 1e-5, "{got} vs {want}");
    }
    // (1,0,0) rotated 90° about z, scaled 2, translated: (1, 4, 3).
    assert!((t.p1 - Vec3::new(1.0, 4.0, 3.0)).length() < 1e-5);
}

#[test]
fn negative_scale_keeps_the_front_face() {
    let extra = format!(
        r#"{PLAIN_MATERIAL},"nodes":[{{"mesh":0,"scale":[-1,1,1]}}],"scenes":[{{"nodes":[0]}}]"#
    );
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], &extra), Path::new(".")).unwrap();
    let world = World::build(
        scene.clone(),
        &WorldOptions {
            default_light: Some(trayecto::scene::DefaultLight::Uniform),
            ..WorldOptions::default()
        },
    )
    .unwrap();
    let t = &world.geometry.triangles[0];
    let n = (t.p1 - t.p0).cross(t.p2 - t.p0);
    // The triangle faces +z; its mirror image in x still faces +z once the winding is flipped.
    assert!(n.z > 0.0, "mirrored triangle faces {n}");
    assert!(t.p0.x <= 0.0 && t.p1.x <= 0.0 && t.p2.x <= 0.0);
}

/// A PNG of one grey texel, value 128.
fn grey_png(dir: &Path, name: &str) {
    image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 128, 128, 255]))
        .save(dir.join(name))
        .unwrap();
}

#[test]
fn texcoord_sets_transforms_and_srgb_vs_linear() {
    let dir = temp_dir("texcoord");
    grey_png(&dir, "grey.png");
    let extra = r#""images":[{"uri":"grey.png"}],
 "samplers":[{"magFilter":9728,"wrapS":33071,"wrapT":33648}],
 "textures":[{"source":0,"sampler":0}],
 "extensionsUsed":["KHR_texture_transform"],
 "materials":[{"name":"m","pbrMetallicRoughness":{
    "baseColorTexture":{"index":0,"texCoord":1},
    "metallicRoughnessTexture":{"index":0,"extensions":{"KHR_texture_transform":
        {"offset":[0.5,0],"rotation":0.25,"scale":[2,3],"texCoord":1}}}}}],
 "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]"#;
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], extra), &dir).unwrap();
    let m = &scene.materials[0];
    let bc = m.base_color_texture.unwrap();
    assert_eq!(bc.texcoord, 1);
    let mr = m.metallic_roughness_texture.unwrap();
    assert_eq!(mr.texcoord, 1, "KHR_texture_transform texCoord overrides");
    let tf = mr.transform.unwrap();
    assert_eq!((tf.offset.x, tf.rotation, tf.scale.y), (0.5, 0.25, 3.0));
    // Both sets are kept per vertex.
    let mesh = &scene.meshes[0];
    assert_eq!(mesh.uv1.as_ref().unwrap()[1].x, 0.75);
    assert_eq!(mesh.uv0.as_ref().unwrap()[1].x, 1.0);
    // The same image decoded as colour (sRGB → linear) and as data (linear).
    let colour = &scene.textures[bc.texture];
    let data = &scene.textures[mr.texture];
    assert_ne!(bc.texture, mr.texture);
    assert!((colour.texels.get(0).x - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
    assert!((data.texels.get(0).x - 128.0 / 255.0).abs() < 1e-6);
    use trayecto::material::WrapMode;
    use trayecto::material::texture::FilterMode;
    assert_eq!(colour.wrap_s, WrapMode::ClampToEdge);
    assert_eq!(colour.wrap_t, WrapMode::MirroredRepeat);
    assert_eq!(colour.filter, FilterMode::Nearest);
}

#[test]
fn missing_texture_is_a_warning_and_magenta() {
    let extra = r#""images":[{"uri":"does_not_exist.png"}],"textures":[{"source":0}],
 "materials":[{"name":"m","pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
 "nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]"#;
    let dir = temp_dir("missing");
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], extra), &dir).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("does_not_exist.png") && w.contains("magenta")),
        "{:?}",
        scene.warnings
    );
    let t = &scene.textures[scene.materials[0].base_color_texture.unwrap().texture];
    assert_eq!(
        t.texels.get(0),
        trayecto::math::Vec4::new(1.0, 0.0, 1.0, 1.0)
    );
}

#[test]
fn hostile_uris_are_refused_with_the_file_name() {
    for uri in [
        "../secret.png",
        "/etc/passwd",
        "data:image/png,notbase64",
        "sub/../../x.png",
    ] {
        let extra = format!(
            r#""images":[{{"uri":"{uri}"}}],"textures":[{{"source":0}}],
 "materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}}}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]"#
        );
        let e = load_str(&triangle_gltf(TRI, [0, 1, 2], &extra), Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("test.gltf:"), "{e}");
    }
    // A buffer outside the folder too.
    let json = triangle_gltf(TRI, [0, 1, 2], &format!("{PLAIN_MATERIAL},\"nodes\":[]")).replacen(
        "data:application/octet-stream;base64,",
        "../../x.bin#",
        1,
    );
    assert!(load_str(&json, Path::new(".")).is_err());
}

#[test]
fn out_of_range_indices_are_errors_and_nan_positions_are_dropped() {
    let extra = format!(r#"{PLAIN_MATERIAL},"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]"#);
    let e = load_str(&triangle_gltf(TRI, [0, 1, 7], &extra), Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(e.contains("test.gltf") && e.contains("vertex"), "{e}");
    let mut bad = TRI;
    bad[1][1] = f32::NAN;
    // A NaN vertex cannot be bounded: its triangle is dropped with a warning naming the mesh.
    let s = load_str(&triangle_gltf(bad, [0, 1, 2], &extra), Path::new(".")).unwrap();
    assert_eq!(s.triangle_count(), 0);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("not finite") && w.contains("vertex 1")),
        "{:?}",
        s.warnings
    );
    // An accessor that runs past its buffer view.
    let json = triangle_gltf(TRI, [0, 1, 2], &extra).replace(
        r#""componentType":5126,"count":3,"type":"VEC3""#,
        r#""componentType":5126,"count":300,"type":"VEC3""#,
    );
    let e = load_str(&json, Path::new(".")).unwrap_err().to_string();
    assert!(e.contains("do not fit"), "{e}");
}

#[test]
fn truncated_glb_is_an_error_naming_the_file() {
    let path = common::scene_file("gltf/Box/glTF-Binary/Box.glb");
    let bytes = std::fs::read(&path).unwrap();
    for cut in [0, 11, 12, 20, 100, bytes.len() / 2, bytes.len() - 1] {
        let e = gltf::load_from_bytes(&bytes[..cut], path.parent().unwrap(), "Box.glb")
            .expect_err("truncated file must not load");
        assert!(e.to_string().starts_with("Box.glb:"), "{e}");
    }
    // Through the public entry point, with the real path in the message.
    let dir = temp_dir("truncated");
    let p = dir.join("cut.glb");
    std::fs::write(&p, &bytes[..bytes.len() - 40]).unwrap();
    let e = trayecto::scene::load(p.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("cut.glb"), "{e}");
}

#[test]
fn unsupported_features_are_named_in_warnings() {
    let extra = format!(
        r#"{PLAIN_MATERIAL},"extensionsUsed":["EXT_lights_image_based"],
 "cameras":[{{"type":"orthographic","orthographic":{{"xmag":1,"ymag":1,"znear":0.1,"zfar":10}}}},
            {{"name":"persp","type":"perspective","perspective":{{"yfov":0.5,"znear":0.1}}}}],
 "nodes":[{{"mesh":0}},{{"camera":0}},{{"camera":1,"translation":[0,0,5]}}],"scenes":[{{"nodes":[0,1,2]}}]"#
    );
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], &extra), Path::new(".")).unwrap();
    let all = scene.warnings.join("\n");
    assert!(all.contains("EXT_lights_image_based"), "{all}");
    assert!(!all.contains("orthographic"), "{all}");
    assert_eq!(scene.cameras.len(), 2);
    let persp = scene.cameras.iter().find(|c| c.name == "persp").unwrap();
    assert!((persp.vfov_deg - 0.5f32.to_degrees()).abs() < 1e-4);
    assert_eq!(
        persp.camera_to_world.w_axis.truncate(),
        Vec3::new(0.0, 0.0, 5.0)
    );
}

/// A glTF orthographic camera renders a parallel view whose half extents are `xmag`, `ymag`: a
/// camera at (0.5, 0.5, 5) with xmag = ymag = 0.5 sees exactly the unit square, so an emissive
/// triangle (0,0)-(1,0)-(0,1) fills the pixels below the image's anti-diagonal and nothing else
/// (a perspective camera, or other magnitudes, would move that edge). Zero magnitudes cannot
/// frame a view: a warning, and the camera is skipped.
#[test]
fn orthographic_camera_frames_its_xmag_ymag_window() {
    let extra = r#""materials":[{"name":"glow","emissiveFactor":[1,1,1]}],
 "cameras":[{"name":"ortho","type":"orthographic","orthographic":{"xmag":0.5,"ymag":0.5,"znear":0.1,"zfar":10}},
            {"name":"flat","type":"orthographic","orthographic":{"xmag":0,"ymag":1,"znear":0.1,"zfar":10}}],
 "nodes":[{"mesh":0},{"camera":0,"translation":[0.5,0.5,5]},{"camera":1}],"scenes":[{"nodes":[0,1,2]}]"#;
    let scene = load_str(&triangle_gltf(TRI, [0, 1, 2], extra), Path::new(".")).unwrap();
    assert_eq!(scene.cameras.len(), 1, "{:?}", scene.warnings);
    assert_eq!(
        scene.cameras[0].projection,
        trayecto::scene::Projection::Orthographic { half_height: 0.5 }
    );
    assert_eq!(scene.cameras[0].aspect, Some(1.0));
    let all = scene.warnings.join("\n");
    assert!(all.contains("'flat'") && all.contains("xmag 0"), "{all}");
    let n = 16;
    let px = render_small(&scene, n, 4, true);
    let mut checked = 0;
    for y in 0..n {
        for x in 0..n {
            let (u, v) = (
                (x as f32 + 0.5) / n as f32,
                1.0 - (y as f32 + 0.5) / n as f32,
            );
            // Pixels the edge crosses are partly covered.
            if (u + v - 1.0).abs() < 1.5 / n as f32 {
                continue;
            }
            let lit = px[(y * n + x) as usize].y > 0.5;
            assert_eq!(
                lit,
                u + v < 1.0,
                "pixel ({x}, {y}): {:?}",
                px[(y * n + x) as usize]
            );
            checked += 1;
        }
    }
    assert!(checked > 150, "{checked}");
}

#[test]
fn lights_punctual_lamp_is_lit_by_its_own_lights() {
    let path = common::scene_file("gltf/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf");
    let scene = trayecto::scene::load(path.to_str().unwrap()).unwrap();
    let json: String = std::fs::read_to_string(&path).unwrap();
    assert!(json.contains("KHR_lights_punctual"));
    let punctual: Vec<&LightDesc> = scene
        .lights
        .iter()
        .filter(|l| matches!(l, LightDesc::Point { .. } | LightDesc::Spot { .. }))
        .collect();
    assert_eq!(punctual.len(), 5, "{:?}", scene.lights);
    // Candela / 683 = W/sr (docs/DESIGN.md §4): no light is brighter than the file's largest intensity.
    for l in &punctual {
        if let LightDesc::Point { intensity, .. } | LightDesc::Spot { intensity, .. } = l {
            assert!(intensity.max_element() > 0.0 && intensity.max_element() < 1000.0 / 683.0);
        }
    }
    let img = render_small(&scene, 32, 4, true);
    let mean: Vec3 = img.iter().copied().sum::<Vec3>() / img.len() as f32;
    assert!(mean.is_finite() && mean.max_element() > 1e-3, "mean {mean}");
}

/// The red Box seen from the automatic camera: red in the middle (its colour is linear
/// (0.8, 0, 0)), white environment at the corners, as the screenshot shows.
#[test]
fn box_is_red_in_the_middle() {
    let path = common::scene_file("gltf/Box/glTF/Box.gltf");
    let scene = trayecto::scene::load(path.to_str().unwrap()).unwrap();
    let n = 32usize;
    let img = render_small(&scene, n as u32, 8, false);
    let c = img[n / 2 * n + n / 2];
    assert!(c.x > 4.0 * c.y && c.x > 4.0 * c.z, "centre {c}");
    let corner = img[0];
    assert!((corner - Vec3::ONE).length() < 1e-3, "corner {corner}");
}
