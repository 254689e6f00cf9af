//! glTF files as exporters and optimisers write them ("files from the wild"):
//! `KHR_mesh_quantization`, `EXT_meshopt_compression` / `KHR_meshopt_compression` (with and
//! without filters), `EXT_texture_webp`, `KHR_texture_basisu`, `KHR_draco_mesh_compression` and
//! `KHR_materials_variants`. The compressed files in `scenes/gltf-files/` were made from the
//! Khronos samples in `../shared/scenes/gltf` by `scripts/make_gltf_files.sh` (gltfpack 1.3,
//! gltf-transform 4.5.1, basisu 1.15); each must load as the original does, within quantization
//! error.

mod common;

use std::path::{Path, PathBuf};

use trayecto::math::Vec3;
use trayecto::render::RenderSettings;
use trayecto::scene::{Scene, Shape};

fn repo_file(rel: &str) -> PathBuf {
    common::repo_dir().join("scenes/gltf-files").join(rel)
}

fn load(path: &Path) -> Result<Scene, String> {
    let bytes = std::fs::read(path).unwrap();
    // What loading a file does: parse, name, validate.
    trayecto::scene::load_bytes(&bytes, path.parent().unwrap(), &path.display().to_string())
        .map_err(|e| e.to_string())
}

fn load_str(json: &str, dir: &Path) -> Result<Scene, String> {
    trayecto::scene::load_bytes(json.as_bytes(), dir, "t.gltf").map_err(|e| e.to_string())
}

/// Geometry statistics that do not depend on vertex or triangle order: world bounds, surface
/// area, the area-weighted sum of interpolated shading normals (catches a wrong normal filter or
/// dequantization), and area per (metallic, roughness) pair (catches wrong material mapping).
struct Stats {
    min: Vec3,
    max: Vec3,
    area: f64,
    normal_sum: [f64; 3],
    area_by_material: std::collections::BTreeMap<(i32, i32), f64>,
}

fn stats(scene: &Scene) -> Stats {
    let b = scene.bounds();
    let mut s = Stats {
        min: b.min,
        max: b.max,
        area: 0.0,
        normal_sum: [0.0; 3],
        area_by_material: Default::default(),
    };
    for o in &scene.objects {
        let Shape::Mesh(m) = o.shape else { continue };
        let mesh = &scene.meshes[m];
        let normal_matrix = o.transform.inverse().transpose();
        let mat = &scene.materials[o.material];
        let key = (
            (mat.metallic * 100.0).round() as i32,
            (mat.roughness * 100.0).round() as i32,
        );
        for t in &mesh.indices {
            let p = t.map(|i| o.transform.transform_point3(mesh.positions[i as usize]));
            let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64;
            s.area += area;
            *s.area_by_material.entry(key).or_default() += area;
            if let Some(n) = &mesh.normals {
                let mut avg = Vec3::ZERO;
                for &i in t {
                    avg += normal_matrix
                        .transform_vector3(n[i as usize])
                        .normalize_or_zero();
                }
                let avg = avg.normalize_or_zero();
                for c in 0..3 {
                    s.normal_sum[c] += area * avg[c] as f64;
                }
            }
        }
    }
    s
}

#[test]
fn quantized_and_meshopt_spheres_match_the_original() {
    let original = load(&common::scene_file(
        "gltf/MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
    ))
    .unwrap();
    let reference = stats(&original);
    let extent = (reference.max - reference.min).max_element();
    for file in [
        "spheres_quantized.glb",
        "spheres_meshopt.glb",
        "spheres_meshopt_filters.glb",
        "spheres_meshopt_khr.glb",
    ] {
        let scene = load(&repo_file(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            !scene.warnings.iter().any(|w| w.contains("not supported")),
            "{file}: {:?}",
            scene.warnings
        );
        let s = stats(&scene);
        // 14-bit positions: a step of extent / 2^14.
        let step = extent / (1 << 14) as f32;
        for (a, b, what) in [(s.min, reference.min, "min"), (s.max, reference.max, "max")] {
            assert!(
                (a - b).abs().max_element() <= 4.0 * step,
                "{file}: bounds {what} {a} vs {b} (step {step})"
            );
        }
        let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-30);
        assert!(
            rel(s.area, reference.area) < 2e-3,
            "{file}: area {} vs {}",
            s.area,
            reference.area
        );
        // Area-weighted mean normal: 8-bit (octahedral) normals move it by well under 1 % of
        // the total area; a wrong filter or sign flips whole hemispheres.
        for c in 0..3 {
            let d = (s.normal_sum[c] - reference.normal_sum[c]).abs() / reference.area;
            assert!(
                d < 0.01,
                "{file}: normal sum [{c}] {} vs {} (area {})",
                s.normal_sum[c],
                reference.normal_sum[c],
                reference.area
            );
        }
        assert_eq!(
            s.area_by_material.len(),
            reference.area_by_material.len(),
            "{file}: material groups"
        );
        for (k, a) in &reference.area_by_material {
            let b = s.area_by_material.get(k).copied().unwrap_or(0.0);
            assert!(
                rel(b, *a) < 5e-3,
                "{file}: material (metallic, roughness) {k:?} covers {b} vs {a}"
            );
        }
    }
}

fn render_box(scene: &Scene) -> trayecto::film::Image {
    let settings = RenderSettings {
        width: 48,
        height: 48,
        spp: 16,
        ..Default::default()
    };
    common::render_scene(scene, &settings)
}

#[test]
fn compressed_and_webp_boxes_render_like_the_png_original() {
    let original = load(&common::scene_file(
        "gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
    ))
    .unwrap();
    let reference = render_box(&original);
    let mean = reference.mean();
    let scale = (mean[0] + mean[1] + mean[2]) as f64 / 3.0;
    // The same render of a box whose texture is replaced by a flat colour differs by far more;
    // the bound is what lossy WebP (quality 80) and 12-bit UVs leave.
    for (file, bound) in [
        ("box_meshopt_fallback.glb", 0.02),
        ("box_meshopt_filters.glb", 0.02),
        ("box_draco.glb", 0.02),
        ("box_draco_sequential.glb", 0.02),
        ("box_webp.glb", 0.06),
        ("box_ktx2_uastc.glb", 0.01),
        ("box_ktx2_etc1s.glb", 0.02),
    ] {
        let scene = load(&repo_file(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            !scene
                .warnings
                .iter()
                .any(|w| w.contains("magenta") || w.contains("not supported")),
            "{file}: {:?}",
            scene.warnings
        );
        assert_eq!(scene.textures.len(), 1, "{file}");
        let img = render_box(&scene);
        let e = common::rmse(&img, &reference) / scale;
        eprintln!("{file}: relative RMSE {e:.4}");
        assert!(e < bound, "{file}: relative RMSE {e:.4} ≥ {bound}");
    }
    // The bound bites: the box without its texture (white) is far from the original.
    let mut untextured = original.clone();
    untextured.materials[0].base_color_texture = None;
    let e = common::rmse(&render_box(&untextured), &reference) / scale;
    assert!(e > 0.2, "untextured box is only {e:.4} away");
}

/// Every vertex of `scene`'s only mesh, as (position, normal, uv) in world space.
fn box_vertices(scene: &Scene) -> Vec<(Vec3, Vec3, trayecto::math::Vec2)> {
    assert_eq!(scene.objects.len(), 1);
    let o = &scene.objects[0];
    let Shape::Mesh(m) = o.shape else {
        panic!("not a mesh")
    };
    let mesh = &scene.meshes[m];
    let normals = mesh.normals.as_ref().expect("normals");
    let uv = mesh.uv0.as_ref().expect("uv0");
    let nm = o.transform.inverse().transpose();
    (0..mesh.positions.len())
        .map(|i| {
            (
                o.transform.transform_point3(mesh.positions[i]),
                nm.transform_vector3(normals[i]).normalize(),
                uv[i],
            )
        })
        .collect()
}

#[test]
fn draco_boxes_decode_to_the_original_vertices() {
    let original = load(&common::scene_file(
        "gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
    ))
    .unwrap();
    let reference = box_vertices(&original);
    for file in ["box_draco.glb", "box_draco_sequential.glb"] {
        let scene = load(&repo_file(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(
            !scene.warnings.iter().any(|w| w.contains("not supported")),
            "{file}: {:?}",
            scene.warnings
        );
        let mesh = &scene.meshes[0];
        assert_eq!(mesh.indices.len(), 12, "{file}: triangles");
        let vertices = box_vertices(&scene);
        // Every decoded vertex is an original one (position, normal and UV together, so swapped
        // attribute ids or a wrong dequantization cannot pass) within gltf-transform's default
        // quantization: 14-bit positions over the unit box, 10-bit normals, 12-bit UVs.
        for (k, (p, n, uv)) in vertices.iter().enumerate() {
            let found = reference.iter().any(|(rp, rn, ruv)| {
                (*p - *rp).abs().max_element() < 4.0 / (1 << 14) as f32
                    && n.dot(*rn) > 0.999
                    && (*uv - *ruv).abs().max_element() < 4.0 / (1 << 12) as f32
            });
            assert!(
                found,
                "{file}: vertex {k} {p} {n} {uv} is not an original one"
            );
        }
        // Each triangle faces the way its normals do (the winding survived the decode).
        for (t, tri) in mesh.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            let geometric = (b.0 - a.0).cross(c.0 - a.0).normalize();
            assert!(geometric.dot(a.1) > 0.99, "{file}: triangle {t} is flipped");
        }
        // And every face of the box is there: the normals of the triangles cover all six sides.
        let mut sides: Vec<[i32; 3]> = mesh
            .indices
            .iter()
            .map(|t| {
                vertices[t[0] as usize]
                    .1
                    .round()
                    .to_array()
                    .map(|v| v as i32)
            })
            .collect();
        sides.sort();
        sides.dedup();
        assert_eq!(sides.len(), 6, "{file}: {sides:?}");
    }
}

#[test]
fn hostile_draco_streams_are_clear_errors() {
    let (json, bin, parse) = repacked("box_draco.glb");
    let ext = |j: &mut serde_json::Value| -> serde_json::Value {
        j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"].clone()
    };
    let view = ext(&mut json.clone())["bufferView"].as_u64().unwrap() as usize;
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut j = json.clone();
        f(&mut j);
        parse(&glb_join(&j, &bin))
            .expect_err("the hostile file was accepted")
            .to_string()
    };
    type JsonEdit<'a> = Box<dyn Fn(&mut serde_json::Value) + 'a>;
    let cases: Vec<(JsonEdit, &str)> = vec![
        (
            Box::new(|j| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"] =
                    99.into()
            }),
            "buffer view 99 does not exist",
        ),
        (
            Box::new(|j| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"] =
                    "x".into()
            }),
            "'bufferView'",
        ),
        (
            Box::new(|j| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]
                    ["POSITION"] = 9.into()
            }),
            "Draco attribute 9",
        ),
        (
            Box::new(|j| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"] =
                    3.into()
            }),
            "'attributes'",
        ),
        (
            // The stream cut short.
            Box::new(move |j| {
                let len = j["bufferViews"][view]["byteLength"].as_u64().unwrap();
                j["bufferViews"][view]["byteLength"] = (len / 2).into();
            }),
            "cannot be decoded",
        ),
        (
            // The stream read from the wrong place (the PNG's bytes).
            Box::new(move |j| {
                j["bufferViews"][view]["byteOffset"] = 0.into();
            }),
            "cannot be decoded",
        ),
        (
            // A TANGENT (4 components) said to be the 3-component NORMAL stream.
            Box::new(|j| {
                let p = &mut j["meshes"][0]["primitives"][0];
                p["attributes"]["TANGENT"] = 1.into();
                p["extensions"]["KHR_draco_mesh_compression"]["attributes"]["TANGENT"] =
                    p["extensions"]["KHR_draco_mesh_compression"]["attributes"]["NORMAL"].clone();
                j["accessors"][1]["type"] = "VEC4".into();
            }),
            "decodes to 3 components",
        ),
    ];
    for (k, (f, needle)) in cases.iter().enumerate() {
        let e = edit(f.as_ref());
        assert!(
            e.contains("KHR_draco_mesh_compression")
                && e.contains(needle)
                && e.contains("hostile.glb"),
            "case {k}: {e}"
        );
    }
    // Corrupt compressed bytes: every single-byte change of the Draco stream loads or is
    // refused, never panics, and some are refused.
    let v = &json["bufferViews"][view];
    let start = v["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = v["byteLength"].as_u64().unwrap() as usize;
    let mut refused = 0;
    for k in start..start + len {
        for flip in [0x5a, 0xff] {
            let mut b = bin.clone();
            b[k] ^= flip;
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                parse(&glb_join(&json, &b)).is_ok()
            }));
            refused += usize::from(!r.unwrap_or_else(|_| panic!("byte {k} ^ {flip:#x}: panic")));
        }
    }
    assert!(refused > 0, "no corrupted stream was refused");
}

/// The bytes of image `index` embedded in a GLB.
fn glb_image(glb: &[u8], index: usize) -> Vec<u8> {
    let (json, bin) = glb_parts(glb);
    let view = &json["bufferViews"][json["images"][index]["bufferView"].as_u64().unwrap() as usize];
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    bin[start..start + view["byteLength"].as_u64().unwrap() as usize].to_vec()
}

#[test]
fn ktx2_basis_textures_decode_to_the_png_they_were_made_from() {
    use trayecto::scene::image_io::decode_image;
    let png = glb_image(
        &std::fs::read(common::scene_file(
            "gltf/BoxTextured/glTF-Binary/BoxTextured.glb",
        ))
        .unwrap(),
        0,
    );
    let png = decode_image("box.png", &png).unwrap().to_rgba8();
    // Mean absolute difference per 8-bit channel (alpha included).
    let mad = |a: &image::RgbaImage, b: &image::RgbaImage| -> f64 {
        assert_eq!(a.dimensions(), b.dimensions());
        let sum: u64 = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(&x, &y)| x.abs_diff(y) as u64)
            .sum();
        sum as f64 / a.as_raw().len() as f64
    };
    // UASTC is near-lossless, ETC1S (quality 255) coarser. The same image upside down (a wrong
    // orientation) or with red and blue swapped is far further away than either bound.
    for (file, bound) in [("box_ktx2_uastc.glb", 1.0), ("box_ktx2_etc1s.glb", 3.0)] {
        let ktx2 = glb_image(&std::fs::read(repo_file(file)).unwrap(), 0);
        assert!(ktx2.starts_with(b"\xABKTX 20\xBB"), "{file}");
        let img = decode_image(file, &ktx2)
            .unwrap_or_else(|e| panic!("{file}: {e}"))
            .to_rgba8();
        let d = mad(&img, &png);
        eprintln!("{file}: mean absolute difference {d:.2} / 255");
        assert!(d < bound, "{file}: {d:.2} ≥ {bound}");
        let flipped = image::imageops::flip_vertical(&img);
        assert!(
            mad(&flipped, &png) > 3.0 * bound,
            "{file}: the flip bound does not bite"
        );
        let mut swapped = img.clone();
        swapped.pixels_mut().for_each(|p| p.0.swap(0, 2));
        assert!(
            mad(&swapped, &png) > 3.0 * bound,
            "{file}: the swap bound does not bite"
        );
    }
}

#[test]
fn hostile_ktx2_images_are_clear_errors_never_panics() {
    use trayecto::scene::image_io::decode_image;
    let ktx2 = glb_image(&std::fs::read(repo_file("box_ktx2_uastc.glb")).unwrap(), 0);
    assert!(decode_image("t.ktx2", &ktx2).is_ok());
    let put32 =
        |d: &mut Vec<u8>, at: usize, v: u32| d[at..at + 4].copy_from_slice(&v.to_le_bytes());
    let put64 =
        |d: &mut Vec<u8>, at: usize, v: u64| d[at..at + 8].copy_from_slice(&v.to_le_bytes());
    type ByteEdit<'a> = Box<dyn Fn(&mut Vec<u8>) + 'a>;
    let cases: Vec<(ByteEdit, &str)> = vec![
        (Box::new(|d| put32(d, 20, 1 << 20)), "size"),
        (Box::new(|d| put32(d, 24, 0)), "size"),
        (Box::new(|d| put32(d, 36, 6)), "6 faces"),
        (Box::new(|d| put32(d, 12, 37)), "vkFormat 37"),
        (Box::new(|d| put64(d, 80, u64::MAX - 4)), "outside the file"),
        (Box::new(|d| put64(d, 88, 1 << 40)), "outside the file"),
        // A Zstandard level that claims to inflate to a terabyte.
        (Box::new(|d| put64(d, 96, 1 << 40)), "impossible"),
        (Box::new(|d| d.truncate(60)), "truncated"),
        (Box::new(|d| d.truncate(d.len() / 2)), "outside the file"),
    ];
    for (k, (f, needle)) in cases.iter().enumerate() {
        let mut d = ktx2.clone();
        f(&mut d);
        let e = decode_image("t.ktx2", &d)
            .err()
            .unwrap_or_else(|| panic!("case {k} accepted"));
        assert!(e.contains(needle), "case {k}: {e}");
    }
    // Every single-byte change of the file decodes or is refused, never panics.
    let mut refused = 0;
    for k in 0..ktx2.len().min(3000) {
        let mut d = ktx2.clone();
        d[k] ^= 0x5a;
        let r = std::panic::catch_unwind(|| decode_image("t.ktx2", &d).is_ok());
        refused += usize::from(!r.unwrap_or_else(|_| panic!("byte {k}: panic")));
    }
    assert!(refused > 0);
}

/// A one-triangle glTF (float positions in a data URI) with `extra` spliced into the root.
fn triangle(extra: &str, primitive_extra: &str) -> String {
    let mut buf = Vec::new();
    for c in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        buf.extend(c.to_le_bytes());
    }
    for c in [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0] {
        buf.extend(c.to_le_bytes());
    }
    use base64::Engine;
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}}],
 "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
   {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}}],
 "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"material":0{primitive_extra}}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0,
 {extra}}}"#,
        len = buf.len()
    )
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto_gltf_files_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 2×2 red PNG.
fn red_png() -> Vec<u8> {
    let img = image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

#[test]
fn ktx2_textures_are_preferred_and_bad_ones_are_named() {
    let dir = temp_dir("ktx2");
    // A KTX2 identifier and garbage.
    let mut ktx = b"\xABKTX 20\xBB\r\n\x1A\n".to_vec();
    ktx.extend([0u8; 64]);
    std::fs::write(dir.join("t.ktx2"), &ktx).unwrap();
    std::fs::write(dir.join("t.png"), red_png()).unwrap();
    // A real one (the UASTC box texture).
    let good = glb_image(&std::fs::read(repo_file("box_ktx2_uastc.glb")).unwrap(), 0);
    std::fs::write(dir.join("good.ktx2"), &good).unwrap();
    let materials = r#""materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}]"#;
    let gltf = |ktx2: &str, fallback: bool, required: bool| {
        let (images, source) = if fallback {
            (
                format!(r#"{{"uri":"t.png"}},{{"uri":"{ktx2}","name":"basis"}}"#),
                r#""source":0,"#,
            )
        } else {
            (format!(r#"{{"uri":"{ktx2}","name":"basis"}}"#), "")
        };
        let k = if fallback { 1 } else { 0 };
        let req = if required {
            r#","extensionsRequired":["KHR_texture_basisu"]"#
        } else {
            ""
        };
        triangle(
            &format!(
                r#"{materials},
 "extensionsUsed":["KHR_texture_basisu"]{req},
 "images":[{images}],
 "textures":[{{"name":"albedo",{source}"extensions":{{"KHR_texture_basisu":{{"source":{k}}}}}}}]"#
            ),
            "",
        )
    };
    for fallback in [false, true] {
        for required in [false, true] {
            let what = format!("fallback {fallback}, required {required}");
            // A good KTX2: used (not the red PNG), no warning.
            let scene = load_str(&gltf("good.ktx2", fallback, required), &dir)
                .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert!(
                !scene.warnings.iter().any(|w| w.contains("KTX2")
                    || w.contains("basisu")
                    || w.contains("not supported")
                    || w.contains("magenta")),
                "{what}: {:?}",
                scene.warnings
            );
            let t = &scene.textures[scene.materials[0].base_color_texture.unwrap().texture];
            assert_eq!(t.name, "good.ktx2", "{what}");
            // A broken one: the magenta fallback and a warning naming the file and the format.
            let scene = load_str(&gltf("t.ktx2", fallback, required), &dir)
                .unwrap_or_else(|e| panic!("{what}: {e}"));
            assert!(
                scene
                    .warnings
                    .iter()
                    .any(|w| w.contains("t.ktx2") && w.contains("KTX2") && w.contains("magenta")),
                "{what}: {:?}",
                scene.warnings
            );
        }
    }
    // WebP beside a PNG fallback: the WebP source is preferred (the extension's intent); an
    // undecodable WebP is a warning and the magenta fallback, not a silent PNG.
    std::fs::write(dir.join("bad.webp"), b"RIFF\0\0\0\0WEBPjunk").unwrap();
    let webp = triangle(
        &format!(
            r#"{materials},
 "extensionsUsed":["EXT_texture_webp"],
 "images":[{{"uri":"t.png"}},{{"uri":"bad.webp"}}],
 "textures":[{{"source":0,"extensions":{{"EXT_texture_webp":{{"source":1}}}}}}]"#
        ),
        "",
    );
    let scene = load_str(&webp, &dir).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("bad.webp") && w.contains("magenta")),
        "{:?}",
        scene.warnings
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Three materials (red, green, blue: the default) and two variants mapping red and green.
fn variants_gltf(root_variants: &str) -> String {
    triangle(
        &format!(
            r#""materials":[
   {{"name":"blue","pbrMetallicRoughness":{{"baseColorFactor":[0,0,1,1]}}}},
   {{"name":"red","pbrMetallicRoughness":{{"baseColorFactor":[1,0,0,1]}}}},
   {{"name":"green","pbrMetallicRoughness":{{"baseColorFactor":[0,1,0,1]}}}}],
 "extensionsUsed":["KHR_materials_variants"],
 "extensions":{{"KHR_materials_variants":{{"variants":{root_variants}}}}}"#
        ),
        r#","extensions":{"KHR_materials_variants":{"mappings":[
      {"material":1,"variants":[0]},{"material":2,"variants":[1]}]}}"#,
    )
}

#[test]
fn material_variants_default_select_and_refuse() {
    let dir = temp_dir("variants");
    let json = variants_gltf(r#"[{"name":"Red"},{"name":"Green"},{"name":"Plain"}]"#);
    let mut scene = load_str(&json, &dir).unwrap();
    assert!(
        !scene.warnings.iter().any(|w| w.contains("variants")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(scene.variants, ["Red", "Green", "Plain"]);
    let colour = |s: &Scene| s.materials[s.objects[0].material].base_color;
    // Default: the primitive's own material.
    assert_eq!(colour(&scene), Vec3::new(0.0, 0.0, 1.0));
    scene.select_variant("Green").unwrap();
    assert_eq!(colour(&scene), Vec3::new(0.0, 1.0, 0.0));
    scene.select_variant("Red").unwrap();
    assert_eq!(colour(&scene), Vec3::new(1.0, 0.0, 0.0));
    // A variant that does not map this primitive: its default material.
    scene.select_variant("Plain").unwrap();
    assert_eq!(colour(&scene), Vec3::new(0.0, 0.0, 1.0));
    let e = scene.select_variant("Purple").unwrap_err().to_string();
    assert!(
        e.contains("'Purple'") && e.contains("'Red', 'Green', 'Plain'"),
        "{e}"
    );
    // The image changes with the variant (the choice reaches the renderer).
    let settings = RenderSettings {
        width: 16,
        height: 16,
        spp: 4,
        ..Default::default()
    };
    scene.select_variant("Red").unwrap();
    let red = common::render_scene(&scene, &settings).mean();
    scene.select_variant("Green").unwrap();
    let green = common::render_scene(&scene, &settings).mean();
    // (The white default environment fills most of the frame; the triangle tints it.)
    assert!(
        red[0] - red[1] > 0.03 && green[1] - green[0] > 0.03,
        "{red:?} {green:?}"
    );

    // A scene without variants refuses a variant by name.
    let mut plain = load(&common::scene_file("gltf/Box/glTF-Binary/Box.glb")).unwrap();
    let e = plain.select_variant("Red").unwrap_err().to_string();
    assert!(e.contains("no material variants"), "{e}");

    // Malformed mappings are errors naming the extension.
    for bad in [
        json.replace(r#""material":2"#, r#""material":7"#),
        json.replace(r#""variants":[1]"#, r#""variants":[9]"#),
        variants_gltf(r#"[{"name":"Red"},{"name":"Red"}]"#),
        variants_gltf(r#"[{"nom":"Red"}]"#),
        variants_gltf(r#"{}"#),
    ] {
        let e = load_str(&bad, &dir).unwrap_err();
        assert!(e.contains("KHR_materials_variants"), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn toml_includes_choose_a_variant() {
    let dir = temp_dir("variants_toml");
    std::fs::write(
        dir.join("v.gltf"),
        variants_gltf(r#"[{"name":"Red"},{"name":"Green"}]"#),
    )
    .unwrap();
    let toml =
        |variant: &str| format!("[[object]]\ntype = \"mesh\"\nfile = \"v.gltf\"\n{variant}\n");
    let load_toml = |text: String| {
        trayecto::scene::toml_scene::load_from_bytes(text.as_bytes(), &dir, "s.toml")
            .map_err(|e| e.to_string())
    };
    let colour = |s: &Scene| s.materials[s.objects[0].material].base_color;
    let scene = load_toml(toml("variant = \"Green\"")).unwrap();
    assert_eq!(colour(&scene), Vec3::new(0.0, 1.0, 0.0));
    let scene = load_toml(toml("")).unwrap();
    assert_eq!(colour(&scene), Vec3::new(0.0, 0.0, 1.0));
    let e = load_toml(toml("variant = \"Purple\"")).unwrap_err();
    assert!(
        e.contains("'Purple'") && e.contains("'Red', 'Green'"),
        "{e}"
    );
    let e = load_toml(
        "[[object]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 1\nvariant = \"Red\"\n".into(),
    )
    .unwrap_err();
    assert!(e.contains("variant"), "{e}");

    // The included file's variants are the TOML scene's: listed, and chosen afterwards (the
    // CLI's --variant, the server's field), merged by name across includes. An include's own
    // `variant =` is its default; a `material =` override has no variants.
    std::fs::write(
        dir.join("w.gltf"),
        variants_gltf(r#"[{"name":"Green"},{"name":"Plain"}]"#),
    )
    .unwrap();
    let two = |first: &str, second: &str| {
        format!(
            "[[object]]\ntype = \"mesh\"\nfile = \"v.gltf\"\n{first}\n\
             [[object]]\ntype = \"mesh\"\nfile = \"w.gltf\"\n{second}\n"
        )
    };
    let colours = |s: &Scene| [0, 1].map(|i| s.materials[s.objects[i].material].base_color);
    let (red, green, blue) = (
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
    );
    let mut scene = load_toml(two("", "")).unwrap();
    assert_eq!(scene.variants, ["Red", "Green", "Plain"]);
    assert_eq!(colours(&scene), [blue, blue]);
    scene.select_variant("Green").unwrap();
    // v.gltf maps Green (its 2nd variant) to green; w.gltf maps its 1st variant, Green, to red.
    assert_eq!(colours(&scene), [green, red]);
    scene.select_variant("Red").unwrap();
    assert_eq!(colours(&scene), [red, blue]);
    scene.select_variant("Plain").unwrap();
    assert_eq!(colours(&scene), [blue, green]);
    let e = scene.select_variant("Purple").unwrap_err().to_string();
    assert!(e.contains("'Red', 'Green', 'Plain'"), "{e}");
    // `variant = "Red"` on the first include: its default from then on.
    let mut scene = load_toml(two("variant = \"Red\"", "")).unwrap();
    assert_eq!(colours(&scene), [red, blue]);
    scene.select_variant("Plain").unwrap();
    assert_eq!(colours(&scene), [red, green]);
    // A material override: that include has no variants.
    let mut scene = load_toml(format!(
        "[[material]]\nname = \"grey\"\n\n{}material = \"grey\"\n",
        two("", "").replace("[[object]]\ntype = \"mesh\"\nfile = \"w.gltf\"\n\n", "")
    ))
    .unwrap();
    assert!(scene.variants.is_empty(), "{:?}", scene.variants);
    let e = scene.select_variant("Red").unwrap_err().to_string();
    assert!(e.contains("no material variants"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn cli_lists_and_selects_variants() {
    let dir = temp_dir("variants_cli");
    let file = dir.join("v.gltf");
    std::fs::write(&file, variants_gltf(r#"[{"name":"Red"},{"name":"Green"}]"#)).unwrap();
    let exe = env!("CARGO_BIN_EXE_trayecto");
    let out = std::process::Command::new(exe)
        .arg("info")
        .arg(&file)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("variants    2") && text.contains("'Red'") && text.contains("'Green'"),
        "{text}"
    );
    let png = dir.join("v.png");
    let run = |variant: &str| {
        std::process::Command::new(exe)
            .arg(&file)
            .args(["--width", "8", "--height", "8", "--spp", "1", "--quiet"])
            .args(["--variant", variant, "-o"])
            .arg(&png)
            .output()
            .unwrap()
    };
    let ok = run("Green");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let bad = run("Purple");
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success());
    assert!(
        err.contains("'Purple'") && err.contains("'Red', 'Green'"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Splits a GLB into its JSON and binary chunks, and joins them again.
fn glb_parts(glb: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin_start = 20 + json_len;
    let bin_len = u32::from_le_bytes(glb[bin_start..bin_start + 4].try_into().unwrap()) as usize;
    (json, glb[bin_start + 8..bin_start + 8 + bin_len].to_vec())
}

fn glb_join(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

/// A sample file split into its JSON and binary chunks, checked to load once joined again, and a
/// parser of hostile variants of it (named `hostile.glb`, resolved in the file's folder).
type GlbParser = Box<dyn Fn(&[u8]) -> Result<Scene, trayecto::scene::SceneError>>;
fn repacked(file: &str) -> (serde_json::Value, Vec<u8>, GlbParser) {
    let path = repo_file(file);
    let (json, bin) = glb_parts(&std::fs::read(&path).unwrap());
    let dir = path.parent().unwrap().to_path_buf();
    let parse: GlbParser =
        Box::new(move |bytes| trayecto::scene::load_bytes(bytes, &dir, "hostile.glb"));
    assert!(
        parse(&glb_join(&json, &bin)).is_ok(),
        "{file}: the repacked file loads"
    );
    (json, bin, parse)
}

#[test]
fn hostile_meshopt_streams_are_clear_errors() {
    let (json, bin, parse) = repacked("box_meshopt_filters.glb");
    let views = json["bufferViews"].as_array().unwrap().clone();
    let compressed: Vec<usize> = (0..views.len())
        .filter(|&i| views[i]["extensions"]["EXT_meshopt_compression"].is_object())
        .collect();
    assert!(compressed.len() >= 3, "{compressed:?}");
    let edit = |view: usize, key: &str, value: serde_json::Value| {
        let mut j = json.clone();
        j["bufferViews"][view]["extensions"]["EXT_meshopt_compression"][key] = value;
        parse(&glb_join(&j, &bin))
    };
    for &v in &compressed {
        let ext = &views[v]["extensions"]["EXT_meshopt_compression"];
        let count = ext["count"].as_u64().unwrap();
        let cases: Vec<(&str, serde_json::Value, &str)> = vec![
            ("count", (1u64 << 40).into(), "absurd"),
            ("count", (count * 5000).into(), "forged"),
            ("byteStride", 3.into(), "byteStride"),
            ("byteStride", 512.into(), "byteStride"),
            ("mode", "POINTS".into(), "mode"),
            ("filter", "COLOR".into(), "filter"),
            ("byteOffset", (1u64 << 62).into(), "outside"),
            ("byteLength", 5.into(), "corrupt"),
            ("buffer", 9.into(), "buffer 9"),
        ];
        for (key, value, needle) in cases {
            let e = edit(v, key, value.clone())
                .err()
                .unwrap_or_else(|| panic!("view {v}: {key} = {value} was accepted"))
                .to_string();
            assert!(
                e.contains("EXT_meshopt_compression") && e.contains(needle),
                "view {v}: {key} = {value}: {e}"
            );
        }
    }
    // Corrupt compressed bytes: every single-byte change loads or is refused, never panics.
    for k in 0..bin.len().min(2000) {
        let mut b = bin.clone();
        b[k] ^= 0x5a;
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            parse(&glb_join(&json, &b)).is_ok()
        }));
        assert!(r.is_ok(), "byte {k} flipped: panic");
    }
}

/// Hostile input for the pure-Rust meshopt decoder, beyond single edits: (i) each compressed
/// view of the EXT file and of the KHR file (vertex codec version 1) truncated to 0, 1, half and
/// all but one of its bytes, and given a count 1 or 16 too large, is an error naming the file
/// and the extension (or, for a count a little too large, decodes: the stream may hold it);
/// (ii) 4000 seeded random streams, each a random mode, filter, stride and count over random
/// bytes or a random prefix of a real stream, are decoded or refused, never a panic, and every
/// refusal names the file; the decoder refuses most of them itself (naming the extension).
#[test]
fn meshopt_decoder_survives_truncated_miscounted_and_random_streams() {
    for (file, ext) in [
        ("box_meshopt_filters.glb", "EXT_meshopt_compression"),
        ("spheres_meshopt_khr.glb", "KHR_meshopt_compression"),
    ] {
        let (json, bin, parse) = repacked(file);
        let views = json["bufferViews"].as_array().unwrap().clone();
        let compressed: Vec<usize> = (0..views.len())
            .filter(|&i| views[i]["extensions"][ext].is_object())
            .collect();
        assert!(!compressed.is_empty());
        for &v in &compressed {
            let e = &views[v]["extensions"][ext];
            let (len, count) = (
                e["byteLength"].as_u64().unwrap(),
                e["count"].as_u64().unwrap(),
            );
            let edit = |key: &str, value: u64| {
                let mut j = json.clone();
                j["bufferViews"][v]["extensions"][ext][key] = value.into();
                parse(&glb_join(&j, &bin))
            };
            for short in [0, 1, len / 2, len - 1] {
                let err = edit("byteLength", short)
                    .err()
                    .unwrap_or_else(|| panic!("{file} view {v}: {short} of {len} bytes accepted"))
                    .to_string();
                assert!(
                    err.contains("hostile.glb") && err.contains(ext),
                    "{file} view {v} truncated to {short}: {err}"
                );
            }
            for more in [1, 16] {
                if let Err(err) = edit("count", count + more) {
                    let err = err.to_string();
                    assert!(
                        err.contains("hostile.glb"),
                        "{file} view {v} count +{more}: {err}"
                    );
                }
            }
        }
    }
    let (json, bin, parse) = repacked("spheres_meshopt_khr.glb");
    let ext = "KHR_meshopt_compression";
    let mut rng = trayecto::sampling::rng::Pcg32::new(77, 3);
    let (mut refused_by_decoder, mut loaded) = (0, 0);
    let n = 4000;
    for k in 0..n {
        let mut b = bin.clone();
        let at = b.len();
        let real = &json["bufferViews"][(k % 3) as usize]["extensions"][ext];
        let len = 1 + (rng.next_u32() % 600) as usize;
        if k % 2 == 0 {
            b.extend((0..len).map(|_| rng.next_u32() as u8));
        } else {
            let (o, l) = (
                real["byteOffset"].as_u64().unwrap_or(0) as usize,
                real["byteLength"].as_u64().unwrap() as usize,
            );
            b.extend_from_slice(&bin[o..o + len.min(l)]);
        }
        let added = b.len() - at;
        while b.len() % 4 != 0 {
            b.push(0);
        }
        let mode = ["ATTRIBUTES", "TRIANGLES", "INDICES"][(rng.next_u32() % 3) as usize];
        let filter = ["NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR"]
            [(rng.next_u32() % 5) as usize];
        let stride = match mode {
            "ATTRIBUTES" => 4 * (1 + rng.next_u32() % 8),
            _ => 2 * (1 + rng.next_u32() % 2),
        };
        let count = match mode {
            "TRIANGLES" => 3 * (rng.next_u32() % 400),
            _ => rng.next_u32() % 1200,
        };
        let mut j = json.clone();
        j["buffers"][0]["byteLength"] = b.len().into();
        let e = &mut j["bufferViews"][0]["extensions"][ext];
        e["byteOffset"] = at.into();
        e["byteLength"] = added.into();
        e["mode"] = mode.into();
        e["filter"] = filter.into();
        e["byteStride"] = stride.into();
        e["count"] = count.into();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&glb_join(&j, &b))));
        match r {
            Err(_) => panic!("stream {k} ({mode} {filter} stride {stride} count {count}): panic"),
            Ok(Ok(_)) => loaded += 1,
            Ok(Err(err)) => {
                let err = err.to_string();
                assert!(err.contains("hostile.glb"), "stream {k}: {err}");
                if err.contains(ext) {
                    refused_by_decoder += 1;
                }
            }
        }
    }
    eprintln!(
        "random meshopt streams: {refused_by_decoder} of {n} refused by the decoder checks, {loaded} loaded"
    );
    assert!(refused_by_decoder > n / 2, "{refused_by_decoder} of {n}");
}

#[test]
fn metadata_extensions_are_not_unsupported_but_unknown_ones_are() {
    let dir = temp_dir("metadata");
    let mats = r#""materials":[{}]"#;
    let xmp = triangle(
        &format!(r#"{mats},"extensionsUsed":["KHR_xmp_json_ld","KHR_xmp"]"#),
        "",
    );
    let scene = load_str(&xmp, &dir).unwrap();
    assert!(
        !scene.warnings.iter().any(|w| w.contains("KHR_xmp")),
        "{:?}",
        scene.warnings
    );
    let unknown = triangle(&format!(r#"{mats},"extensionsUsed":["EXT_made_up"]"#), "");
    let scene = load_str(&unknown, &dir).unwrap();
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("'EXT_made_up' is not supported")),
        "{:?}",
        scene.warnings
    );
    std::fs::remove_dir_all(&dir).ok();
}
