//! What the loaders read, value by value: small OBJ/MTL, PLY, glTF and EXR files are
//! written here with known contents, and every attribute must come back exactly as written (up
//! to each format's documented conventions: v flipped to glTF's v-down, 8-bit texels / 255).

use std::path::{Path, PathBuf};
use trayecto::material::{AlphaMode, MaterialModel, Texture};
use trayecto::math::{Vec2, Vec3, Vec4};
use trayecto::scene::{Mesh, Scene, Shape};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("trayecto-loaders-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 2×2 grey PNG with the given bytes (row-major, top row first).
fn grey_png(path: &Path, v: [u8; 4]) {
    let rgb: Vec<u8> = v.iter().flat_map(|&b| [b, b, b]).collect();
    image::save_buffer(path, &rgb, 2, 2, image::ExtendedColorType::Rgb8).unwrap();
}

/// Asserts that texture `t` holds `v` / 255 in channel `ch`, texel by texel.
fn assert_texels(t: &Texture, ch: usize, v: [u8; 4], what: &str) {
    assert_eq!((t.width, t.height), (2, 2), "{what}");
    for (i, &b) in v.iter().enumerate() {
        let got = t.texels.get(i)[ch];
        assert!(
            (got - b as f32 / 255.0).abs() < 1e-6,
            "{what}: texel {i} channel {ch} = {got}, written {b}/255"
        );
    }
}

fn close3(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-6
}

fn meshes(s: &Scene) -> Vec<(&Mesh, usize)> {
    s.objects
        .iter()
        .filter_map(|o| match o.shape {
            Shape::Mesh(m) => Some((&s.meshes[m], o.material)),
            _ => None,
        })
        .collect()
}

/// For each vertex of `mesh`, the index of the file position it equals (panics if none).
fn match_positions(mesh: &Mesh, file: &[Vec3]) -> Vec<usize> {
    mesh.positions
        .iter()
        .map(|p| {
            file.iter()
                .position(|q| close3(*p, *q))
                .unwrap_or_else(|| panic!("vertex {p} is not in the file"))
        })
        .collect()
}

const OBJ_V: [[f32; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.5, 1.5, 0.0],
    [0.0, 1.0, 0.0],
    [2.0, 0.0, 0.0],
    [3.0, 0.0, 0.0],
    [2.0, 1.0, 0.0],
];
const OBJ_VT: [[f32; 2]; 8] = [
    [0.1, 0.2],
    [0.3, 0.4],
    [0.5, 0.6],
    [0.7, 0.8],
    [0.9, 0.15],
    [0.25, 0.75],
    [0.5, 0.5],
    [0.75, 0.35],
];
const OBJ_VN: [[f32; 3]; 8] = [
    [0.0, 0.0, 1.0],
    [0.6, 0.0, 0.8],
    [0.0, 0.6, 0.8],
    [-0.6, 0.0, 0.8],
    [0.0, -0.6, 0.8],
    [0.0, 0.8, 0.6],
    [0.8, 0.0, 0.6],
    [0.0, 0.0, -1.0],
];

#[test]
fn obj_normals_uvs_negative_indices_fans_and_mtl_maps() {
    let dir = temp_dir("obj");
    let mut obj = String::from("mtllib m.mtl\n");
    for v in OBJ_V {
        obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    for t in OBJ_VT {
        obj += &format!("vt {} {}\n", t[0], t[1]);
    }
    for n in OBJ_VN {
        obj += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
    }
    // A convex pentagon (fan-triangulated), then a triangle through negative (relative) indices:
    // −3, −2, −1 are the last three v, vt and vn (v 6–8, vt 6–8, vn 6–8).
    obj += "o pentagon\nusemtl mirror3\nf 1/1/1 2/2/2 3/3/3 4/4/4 5/5/5\n";
    obj += "o relative\nusemtl pbr\nf -3/-3/-3 -2/-2/-2 -1/-1/-1\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl mirror3\nKd 0.1 0.1 0.1\nKs 0.9 0.8 0.7\nillum 3\n\
         newmtl mirror5\nKd 0.5 0.6 0.7\nillum 5\n\
         newmtl cutout\nKd 1 1 1\nmap_d alpha.png\n\
         newmtl bumpy\nKd 1 1 1\nbump -bm 1.0 bump.png\n\
         newmtl normy\nKd 1 1 1\nnorm nrm.png\n\
         newmtl pbr\nKd 1 1 1\nmap_Pr rough.png\nmap_Pm metal.png\n",
    )
    .unwrap();
    let (alpha, bump, nrm, rough, metal) = (
        [0u8, 64, 128, 255],
        [10u8, 20, 30, 40],
        [200u8, 150, 100, 50],
        [12u8, 99, 180, 240],
        [255u8, 0, 77, 140],
    );
    grey_png(&dir.join("alpha.png"), alpha);
    grey_png(&dir.join("bump.png"), bump);
    grey_png(&dir.join("nrm.png"), nrm);
    grey_png(&dir.join("rough.png"), rough);
    grey_png(&dir.join("metal.png"), metal);
    let s = trayecto::scene::load(dir.join("m.obj").to_str().unwrap()).unwrap();

    let file_v: Vec<Vec3> = OBJ_V.iter().map(|&v| Vec3::from(v)).collect();
    let ms = meshes(&s);
    assert_eq!(ms.len(), 2, "two objects");
    let mut tri_counts = Vec::new();
    for (mesh, _) in &ms {
        let idx = match_positions(mesh, &file_v);
        let normals = mesh.normals.as_ref().expect("normals read");
        let uv = mesh.uv0.as_ref().expect("UVs read");
        for (k, &i) in idx.iter().enumerate() {
            // Each position is used with the vt and vn of the same number (negative indices
            // resolved to the last three).
            assert!(
                close3(normals[k], Vec3::from(OBJ_VN[i])),
                "v {}: normal {} written {:?}",
                i + 1,
                normals[k],
                OBJ_VN[i]
            );
            let want = Vec2::new(OBJ_VT[i][0], 1.0 - OBJ_VT[i][1]);
            assert!(
                (uv[k] - want).abs().max_element() < 1e-6,
                "v {}: uv {} expected {want} (file {:?}, v flipped)",
                i + 1,
                uv[k],
                OBJ_VT[i]
            );
        }
        // The triangles, as sets of file vertex numbers.
        let tris: Vec<[usize; 3]> = mesh
            .indices
            .iter()
            .map(|t| [idx[t[0] as usize], idx[t[1] as usize], idx[t[2] as usize]])
            .collect();
        tri_counts.push(tris.len());
        if tris.len() == 3 {
            // The pentagon as a fan from its first vertex, winding kept (+z facing).
            assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        } else {
            assert_eq!(tris, vec![[5, 6, 7]]);
        }
    }
    tri_counts.sort();
    assert_eq!(tri_counts, vec![1, 3]);

    let mat = |name: &str| {
        s.materials
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no material {name}"))
    };
    let tex = |r: &Option<trayecto::material::TextureRef>, what: &str| {
        &s.textures[r
            .as_ref()
            .unwrap_or_else(|| panic!("{what}: no texture"))
            .texture]
    };
    // illum 3 and 5: mirrors, coloured by Ks (or Kd without Ks).
    let m3 = mat("mirror3");
    assert_eq!(m3.model, MaterialModel::Mirror);
    assert!(
        close3(m3.base_color, Vec3::new(0.9, 0.8, 0.7)),
        "{}",
        m3.base_color
    );
    let m5 = mat("mirror5");
    assert_eq!(m5.model, MaterialModel::Mirror);
    assert!(
        close3(m5.base_color, Vec3::new(0.5, 0.6, 0.7)),
        "{}",
        m5.base_color
    );
    // map_d: a linear opacity texture, rendered as stochastic transparency.
    let cut = mat("cutout");
    assert_eq!(cut.alpha_mode, AlphaMode::Blend);
    assert_texels(tex(&cut.alpha_texture, "map_d"), 0, alpha, "map_d");
    // bump (with an option before the file name) and norm: the normal map, linear.
    assert_texels(tex(&mat("bumpy").normal_texture, "bump"), 0, bump, "bump");
    assert_texels(tex(&mat("normy").normal_texture, "norm"), 0, nrm, "norm");
    // map_Pr / map_Pm: metallic-roughness model, factors 1, packed glTF-style (G rough, B metal).
    let pbr = mat("pbr");
    assert!(pbr.model.is_metallic_roughness());
    assert_eq!((pbr.roughness, pbr.metallic), (1.0, 1.0));
    let packed = tex(&pbr.metallic_roughness_texture, "map_Pr/map_Pm");
    assert_texels(packed, 1, rough, "map_Pr (G)");
    assert_texels(packed, 2, metal, "map_Pm (B)");
}

#[test]
fn ply_normals_and_uvs() {
    // ASCII PLY, a quad as two triangles with per-vertex normals and (s, t) coordinates.
    let verts: [([f32; 3], [f32; 3], [f32; 2]); 4] = [
        ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0]),
        ([1.0, 0.0, 0.0], [0.6, 0.0, 0.8], [1.0, 0.125]),
        ([1.0, 1.0, 0.0], [0.0, 0.6, 0.8], [0.875, 1.0]),
        ([0.0, 1.0, 0.0], [-0.6, 0.0, 0.8], [0.25, 0.75]),
    ];
    for (u_name, v_name) in [("s", "t"), ("u", "v"), ("texture_u", "texture_v")] {
        let mut ply = format!(
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             property float nx\nproperty float ny\nproperty float nz\nproperty float {u_name}\nproperty float {v_name}\n\
             element face 2\nproperty list uchar int vertex_indices\nend_header\n"
        );
        for (p, n, t) in verts {
            ply += &format!(
                "{} {} {} {} {} {} {} {}\n",
                p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1]
            );
        }
        ply += "3 0 1 2\n3 0 2 3\n";
        let s = trayecto::scene::ply::load_from_bytes(ply.as_bytes(), "t.ply").unwrap();
        let ms = meshes(&s);
        assert_eq!(ms.len(), 1);
        let mesh = ms[0].0;
        let file_v: Vec<Vec3> = verts.iter().map(|v| Vec3::from(v.0)).collect();
        let idx = match_positions(mesh, &file_v);
        let normals = mesh.normals.as_ref().expect("normals read");
        let uv = mesh.uv0.as_ref().expect("UVs read");
        for (k, &i) in idx.iter().enumerate() {
            assert!(
                close3(normals[k], Vec3::from(verts[i].1)),
                "{u_name}: normal {}",
                normals[k]
            );
            let want = Vec2::new(verts[i].2[0], 1.0 - verts[i].2[1]);
            assert!(
                (uv[k] - want).abs().max_element() < 1e-6,
                "{u_name}/{v_name}: vertex {i} uv {} expected {want}",
                uv[k]
            );
        }
        assert_eq!(mesh.indices.len(), 2);
    }
}

/// glTF: a sparse POSITION accessor (one vertex replaced), a sparse TEXCOORD_0 accessor with no
/// buffer view (zeros but one entry), TANGENT with a negative bitangent sign, COLOR_0 as float
/// VEC4 on one primitive and as normalised unsigned-byte VEC4 on another.
#[test]
fn gltf_sparse_accessors_color_0_and_tangent() {
    use base64::Engine;
    let mut buf: Vec<u8> = Vec::new();
    let f32s = |buf: &mut Vec<u8>, v: &[f32]| {
        for x in v {
            buf.extend(x.to_le_bytes());
        }
    };
    let positions = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let tangents = [
        1.0f32, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 1.0, 0.6, 0.0, 0.8, -1.0,
    ];
    let colors = [
        0.1f32, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.25, 0.125, 1.0,
    ];
    let color_bytes = [0u8, 51, 102, 255, 17, 34, 68, 136, 255, 128, 1, 200];
    f32s(&mut buf, &positions); // 0..36
    f32s(&mut buf, &tangents); // 36..84
    f32s(&mut buf, &colors); // 84..132
    buf.extend(2u16.to_le_bytes()); // 132: sparse index of POSITION
    buf.extend([0, 0]);
    f32s(&mut buf, &[0.0, 2.0, 0.5]); // 136..148: its new value
    buf.extend(color_bytes); // 148..160
    buf.extend(1u16.to_le_bytes()); // 160: sparse index of TEXCOORD_0
    buf.extend([0, 0]);
    f32s(&mut buf, &[0.5, 0.25]); // 164..172
    assert_eq!(buf.len(), 172);
    let b64 = base64::engine::general_purpose::STANDARD.encode(&buf);
    let view =
        |off: usize, len: usize| format!(r#"{{"buffer":0,"byteOffset":{off},"byteLength":{len}}}"#);
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},
 "buffers":[{{"byteLength":172,"uri":"data:application/octet-stream;base64,{b64}"}}],
 "bufferViews":[{v0},{v1},{v2},{v3},{v4},{v5},{v6},{v7}],
 "accessors":[
  {{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,2,0.5],
    "sparse":{{"count":1,"indices":{{"bufferView":3,"componentType":5123}},"values":{{"bufferView":4}}}}}},
  {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC4"}},
  {{"bufferView":2,"componentType":5126,"count":3,"type":"VEC4"}},
  {{"bufferView":5,"componentType":5121,"normalized":true,"count":3,"type":"VEC4"}},
  {{"componentType":5126,"count":3,"type":"VEC2",
    "sparse":{{"count":1,"indices":{{"bufferView":6,"componentType":5123}},"values":{{"bufferView":7}}}}}}],
 "materials":[{{"pbrMetallicRoughness":{{"metallicFactor":0}}}}],
 "meshes":[{{"primitives":[
   {{"attributes":{{"POSITION":0,"TANGENT":1,"COLOR_0":2,"TEXCOORD_0":4}},"material":0}},
   {{"attributes":{{"POSITION":0,"COLOR_0":3}},"material":0}}]}}],
 "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        v0 = view(0, 36),
        v1 = view(36, 48),
        v2 = view(84, 48),
        v3 = view(132, 2),
        v4 = view(136, 12),
        v5 = view(148, 12),
        v6 = view(160, 2),
        v7 = view(164, 8),
    );
    let dir = temp_dir("gltf");
    let s = trayecto::scene::gltf::load_from_bytes(gltf.as_bytes(), &dir, "t.gltf")
        .unwrap_or_else(|e| panic!("{e}"));
    let ms = meshes(&s);
    assert_eq!(ms.len(), 2, "two primitives");
    // The sparse accessor replaced vertex 2.
    let file_v = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 0.5)];
    for (p, (mesh, _)) in ms.iter().enumerate() {
        let idx = match_positions(mesh, &file_v);
        let mut seen = idx.clone();
        seen.sort();
        assert_eq!(
            seen,
            vec![0, 1, 2],
            "primitive {p}: positions {:?}",
            mesh.positions
        );
        let read = mesh.colors.as_ref().expect("COLOR_0 read");
        for (k, &i) in idx.iter().enumerate() {
            let want = if p == 0 {
                Vec4::from_slice(&colors[4 * i..4 * i + 4])
            } else {
                Vec4::from_slice(
                    &color_bytes[4 * i..4 * i + 4]
                        .iter()
                        .map(|&b| b as f32 / 255.0)
                        .collect::<Vec<_>>(),
                )
            };
            assert!(
                (read[k] - want).abs().max_element() < 1e-6,
                "primitive {p} vertex {i}: COLOR_0 {} expected {want}",
                read[k]
            );
        }
        if p == 0 {
            let t = mesh.tangents.as_ref().expect("TANGENT read");
            let uv = mesh.uv0.as_ref().expect("TEXCOORD_0 read");
            for (k, &i) in idx.iter().enumerate() {
                let want = Vec4::from_slice(&tangents[4 * i..4 * i + 4]);
                assert!(
                    (t[k] - want).abs().max_element() < 1e-6,
                    "vertex {i}: TANGENT {} expected {want}",
                    t[k]
                );
                let want = if i == 1 {
                    Vec2::new(0.5, 0.25)
                } else {
                    Vec2::ZERO
                };
                assert!(
                    (uv[k] - want).abs().max_element() < 1e-6,
                    "vertex {i}: sparse TEXCOORD_0 {} expected {want}",
                    uv[k]
                );
            }
        }
    }
}

/// An environment map read from `.exr`: every texel exactly as written (row 0 at the top, the
/// map's +y), and the radiance at a texel's centre direction is that texel.
#[test]
fn environment_map_from_exr() {
    let dir = temp_dir("exr");
    let (w, h) = (8usize, 4usize);
    let texel = |x: usize, y: usize| {
        Vec3::new(
            x as f32 * 0.5 + 0.25,
            y as f32 * 2.0 + 1.0,
            (x * y) as f32 * 0.125 + 3.0,
        )
    };
    let path = dir.join("sky.exr");
    exr::prelude::write_rgb_file(&path, w, h, |x, y| {
        let c = texel(x, y);
        (c.x, c.y, c.z)
    })
    .unwrap();
    let map =
        trayecto::light::envmap::EnvMap::load(&path, Vec3::ONE, trayecto::math::Mat3::IDENTITY)
            .unwrap();
    assert_eq!((map.width, map.height), (w as u32, h as u32));
    for y in 0..h {
        for x in 0..w {
            assert_eq!(map.texels[y * w + x], texel(x, y), "texel ({x}, {y})");
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let d = trayecto::light::envmap::EnvMap::uv_to_dir(uv);
            let l = map.eval(d);
            assert!(
                ((l - texel(x, y)) / texel(x, y)).abs().max_element() < 1e-4,
                "radiance toward texel ({x}, {y}): {l}, texel {}",
                texel(x, y)
            );
        }
    }
    // The top row is up (+y), as in Mitsuba's envmap.
    assert!(trayecto::light::envmap::EnvMap::uv_to_dir(Vec2::new(0.5, 0.01)).y > 0.99);
}
